/* mts-server and mts-client as a user runs them, over loopback:
 *   - a server that dies mid-stream leaves the client with a clear error, a
 *     non-zero exit and its last whole batch drawn (the PNG is written);
 *   - a model given as an http URL (served by python3 -m http.server on
 *     127.0.0.1) is fetched, built and streamed; ftp:// and file:// are
 *     refused, and so is a body over --max-download. */
#include <arpa/inet.h>
#include <libgen.h>
#include <netinet/in.h>
#include <signal.h>
#include <stdint.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include "build.h"
#include "clock.h"
#include "mesh.h"
#include "stream.h"
#include "test.h"
#include "test_proc.h"
#include "utf8.h"
#include "wire.h"

static char bin_dir[512], tmp_dir[512];

static int file_size(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return -1;
    fseek(f, 0, SEEK_END);
    int n = (int)ftell(f);
    fclose(f);
    return n;
}

/* cow's stream (model name "cow"), as a server would send it. */
static int cow_stream(mts_test *t, mts_stream *s)
{
    mts_error err = {0};
    mts_mesh mesh = {0};
    mts_model m;
    CHECKF(t, mts_mesh_load("tests/data/cow.off", NULL, &mesh, NULL, &err) == MTS_OK, "%s",
           err.msg);
    if (t->case_failed)
        return 0;
    CHECKF(t, mts_build_model(&mesh, "cow", NULL, &m, NULL, &err) == MTS_OK, "%s", err.msg);
    mts_mesh_free(&mesh);
    if (t->case_failed)
        return 0;
    CHECKF(t, mts_stream_build(&m, "cow", NULL, s, &err) == MTS_OK, "%s", err.msg);
    mts_model_free(&m);
    return !t->case_failed;
}

/* What a server sends for s's whole stream as a fresh client's answer:
 * MODEL_INFO, then BASE and every BATCH (no END: a fake server's own end). */
static void whole_answer(const mts_stream *s, mts_buf *b)
{
    mts_stream_put_model_info(s, s->model.level_count, b);
    mts_buf_put(b, s->bytes, s->size);
}

/* A server in a child process: each connection gets one HELLO read and
 * answers[k] (the last one again past the list) sent, `per_byte_us` apart
 * a byte when not 0; it lives until killed (60 s at most). */
static pid_t fake_server(int lfd, const mts_buf *const *answers, int count, unsigned per_byte_us)
{
    pid_t pid = fork();
    if (pid != 0) {
        close(lfd); /* the child's now */
        return pid;
    }
    alarm(60);
    for (int k = 0;; k++) {
        int fd = accept(lfd, NULL, NULL);
        char hello[256];
        (void)!recv(fd, hello, sizeof hello, 0);
        const mts_buf *b = answers[k < count ? k : count - 1];
        if (per_byte_us == 0) {
            (void)!send(fd, b->data, b->size, MSG_NOSIGNAL);
        } else {
            for (size_t i = 0; i < b->size && send(fd, b->data + i, 1, MSG_NOSIGNAL) == 1; i++)
                usleep(per_byte_us);
        }
        usleep(100000);
        close(fd);
    }
}

/* cow's stream (s, b: its whole answer) and a fake_server sending b to
 * each connection; its port in *port. */
static pid_t fake_cow_server(mts_test *t, mts_stream *s, mts_buf *b, unsigned per_byte_us,
                             int *port)
{
    int lfd = mts_test_listen_any(port);
    CHECK(t, lfd >= 0);
    whole_answer(s, b);
    const mts_buf *answer = b;
    return fake_server(lfd, &answer, 1, per_byte_us);
}

/* A server that sends a real stream for cow but dies after `cut` bytes:
 * after a pause, or at once, so that the close is read while frames sent
 * before it are still held and two threads decode (the client reads
 * between frames then): those frames are applied all the same; or it
 * resets the connection, and the message counts them too. */
static void server_dies_mid_stream(mts_test *t, int pause_us, int reset, const char *threads)
{
    mts_stream s;
    if (!cow_stream(t, &s))
        return;
    int port, lfd = mts_test_listen_any(&port);
    CHECK(t, lfd >= 0);
    mts_buf b = {0};
    mts_stream_put_model_info(&s, s.model.level_count, &b);
    size_t cut = b.size + s.batch_offset[10] + 7; /* inside batch 10 */
    mts_buf_put(&b, s.bytes, s.size);
    pid_t pid = fork();
    if (pid == 0) {
        int fd = accept(lfd, NULL, NULL);
        char hello[256];
        (void)!recv(fd, hello, sizeof hello, 0);
        (void)!send(fd, b.data, cut, MSG_NOSIGNAL);
        usleep((useconds_t)pause_us);
        if (reset) { /* a reset, not a close: linger 0 */
            struct linger l = {1, 0};
            setsockopt(fd, SOL_SOCKET, SO_LINGER, &l, sizeof l);
        }
        close(fd);
        _exit(0);
    }
    close(lfd);
    char cmd[4096], out[8192], png[1024];
    snprintf(png, sizeof png, "%s/e2e_cut.png", tmp_dir);
    remove(png);
    /* detect_leaks=0: see test_pngs_at_three_levels */
    snprintf(cmd, sizeof cmd,
             "ASAN_OPTIONS=detect_leaks=0 %s/mts-client 127.0.0.1:%d cow --png %s --json%s",
             bin_dir, port, png, threads);
    int rc = mts_test_run(cmd, out, sizeof out);
    waitpid(pid, NULL, 0);
    CHECKF(t, rc == 1, "exit %d: %s", rc, out);
    CHECKF(t, strstr(out, reset ? "connection lost" : "mid-stream") &&
                  strstr(out, "10 batches applied"),
           "%s", out);
    CHECKF(t, strstr(out, "\"batches\":10,") != NULL, "%s", out);
    char level[64];
    snprintf(level, sizeof level, "\"level\":%u,", s.batch_first[10]);
    CHECKF(t, strstr(out, level) != NULL, "want %s in %s", level, out);
    CHECKF(t, file_size(png) > 1000, "no picture of the last whole batch at %s", png);
    mts_buf_free(&b);
    mts_stream_free(&s);
}

static void test_server_dies_mid_stream(mts_test *t)
{
    server_dies_mid_stream(t, 100000, 0, "");
    server_dies_mid_stream(t, 0, 0, " --threads 2");
    server_dies_mid_stream(t, 0, 0, " --threads 1");
    /* a reset once the bytes are in (sooner, it would drop bytes unsent) */
    server_dies_mid_stream(t, 100000, 1, "");
}

/* A server that answers HELLO for "horse" with cow's stream: the client
 * refuses it by name instead of drawing the wrong model. */
static void test_info_for_another_model(mts_test *t)
{
    mts_stream s;
    if (!cow_stream(t, &s))
        return;
    int port;
    mts_buf b = {0};
    pid_t pid = fake_cow_server(t, &s, &b, 0, &port);
    char cmd[2048], out[8192];
    snprintf(cmd, sizeof cmd, "%s/mts-client 127.0.0.1:%d horse --no-render --json", bin_dir,
             port);
    int rc = mts_test_run(cmd, out, sizeof out);
    kill(pid, SIGKILL);
    waitpid(pid, NULL, 0);
    CHECKF(t, rc == 1 && strstr(out, "MODEL_INFO is for model 'cow', not the 'horse' asked for") &&
                  strstr(out, "\"complete\":false"),
           "exit %d: %s", rc, out);
    mts_buf_free(&b);
    mts_stream_free(&s);
}

/* A server that trickles a valid stream (a byte every 100 ms, never idle
 * for --timeout) holds a client no longer than --max-time. */
static void test_trickle_bounded(mts_test *t)
{
    mts_stream s;
    if (!cow_stream(t, &s))
        return;
    int port;
    mts_buf b = {0};
    pid_t pid = fake_cow_server(t, &s, &b, 100000, &port);
    char cmd[2048], out[8192];
    snprintf(cmd, sizeof cmd,
             "%s/mts-client 127.0.0.1:%d cow --no-render --json --timeout 5 --max-time 1.5",
             bin_dir, port);
    const double t0 = mts_clock_seconds();
    int rc = mts_test_run(cmd, out, sizeof out);
    const double took = mts_clock_seconds() - t0;
    kill(pid, SIGKILL);
    waitpid(pid, NULL, 0);
    CHECKF(t, rc == 1 && strstr(out, "no END after 1.5 s") && strstr(out, "time limit"),
           "exit %d: %s", rc, out);
    CHECKF(t, took < 5, "the client took %.1f s", took);
    /* the options are checked */
    snprintf(cmd, sizeof cmd, "%s/mts-client 127.0.0.1:%d cow --max-time 0", bin_dir, port);
    CHECK(t, mts_test_run(cmd, out, sizeof out) == 2 && strstr(out, "--max-time"));
    mts_buf_free(&b);
    mts_stream_free(&s);
}

/* A batch that fails its CRC is rejected whole; with --resume the client
 * asks for it again (PROTOCOL.md, "Split coding") and ends with the mesh of
 * an unbroken run; without, it stops at the batch before. The server's first answer has a byte of batch 3 flipped. */
static void test_crc_mismatch_resumed(mts_test *t)
{
    mts_stream s;
    if (!cow_stream(t, &s))
        return;
    mts_error err = {0};
    const uint32_t stop = s.model.level_count;
    mts_buf whole = {0}, resumed = {0};
    size_t off, len;
    mts_stream_put_model_info(&s, stop, &whole);
    CHECK(t, mts_stream_range(&s, 0, stop, &off, &len, &err) == MTS_OK);
    const size_t flip = whole.size + (s.batch_offset[3] - off) + 9; /* inside batch 3 */
    mts_buf_put(&whole, s.bytes + off, len);
    mts_stream_put_end(&s, stop, (uint32_t)whole.size, &whole);
    whole.data[flip] ^= 0x40;
    mts_stream_put_model_info(&s, stop, &resumed);
    CHECK(t, mts_stream_range(&s, 3, stop, &off, &len, &err) == MTS_OK);
    mts_buf_put(&resumed, s.bytes + off, len);
    mts_stream_put_end(&s, stop, (uint32_t)resumed.size, &resumed);
    for (int with_resume = 1; with_resume >= 0; with_resume--) {
        int port, lfd = mts_test_listen_any(&port);
        CHECK(t, lfd >= 0);
        const mts_buf *answers[2] = {&whole, &resumed};
        pid_t pid = fake_server(lfd, answers, 2, 0);
        char cmd[2048], out[8192];
        snprintf(cmd, sizeof cmd, "%s/mts-client 127.0.0.1:%d cow --no-render --json %s", bin_dir,
                 port, with_resume ? "--resume" : "");
        int rc = mts_test_run(cmd, out, sizeof out);
        kill(pid, SIGKILL);
        waitpid(pid, NULL, 0);
        if (with_resume) {
            char want[64];
            snprintf(want, sizeof want, "\"checksum\":\"%016llx\"",
                     (unsigned long long)s.level_checksum[stop]);
            CHECKF(t, rc == 0 && strstr(out, "\"complete\":true") && strstr(out, want) &&
                          strstr(out, "\"reconnects\":1"),
                   "exit %d: %s", rc, out);
        } else {
            CHECKF(t, rc == 1 && strstr(out, "BATCH 3: checksum mismatch") &&
                          strstr(out, "\"batches\":3,"),
                   "exit %d: %s", rc, out);
        }
    }
    mts_buf_free(&whole);
    mts_buf_free(&resumed);
    mts_stream_free(&s);
}

/* Whether out holds only well-formed UTF-8 (what a JSON parser takes). */
static int all_utf8(const char *out)
{
    const unsigned char *u = (const unsigned char *)out;
    size_t n = strlen(out);
    for (size_t i = 0; i < n;) {
        size_t k = mts_utf8_seq_len(u + i, n - i);
        if (k == 0)
            return 0;
        i += k;
    }
    return 1;
}

/* A server whose ERROR text is not UTF-8 (and holds control bytes): what
 * mts-client and mts-stress print of it, --json line and messages alike,
 * is still UTF-8, the bad bytes replaced. */
static void test_peer_text_not_utf8(mts_test *t)
{
    int port, lfd = mts_test_listen_any(&port);
    CHECK(t, lfd >= 0);
    if (lfd < 0)
        return;
    mts_buf b = {0};
    mts_wire_put_error(&b, MTS_WERR_UNKNOWN_MODEL,
                       "bad \xff\xfe bytes \xc0\xaf \xed\xa0\x80 \x1b[31m cut \xe2\x82");
    const mts_buf *answer = &b; /* to mts-client, then to mts-stress's two */
    pid_t pid = fake_server(lfd, &answer, 1, 0);
    char cmd[2048], out[8192];
    snprintf(cmd, sizeof cmd, "%s/mts-client 127.0.0.1:%d cow --no-render --json", bin_dir, port);
    int rc = mts_test_run(cmd, out, sizeof out);
    CHECKF(t, rc == 1 && strstr(out, "\"error\"") && strstr(out, "bad ?? bytes ?? ???"), "exit %d: %s",
           rc, out);
    CHECKF(t, all_utf8(out), "not UTF-8: %s", out);
    snprintf(cmd, sizeof cmd, "%s/mts-stress 127.0.0.1:%d cow --clients 2 --no-apply --json",
             bin_dir, port);
    rc = mts_test_run(cmd, out, sizeof out);
    CHECKF(t, rc == 1 && all_utf8(out), "exit %d: %s", rc, out);
    kill(pid, SIGKILL);
    waitpid(pid, NULL, 0);
    mts_buf_free(&b);
}

static void test_url_models(mts_test *t)
{
    char out[8192], cmd[4096];
    if (mts_test_run("python3 -c 'import http.server'", out, sizeof out) != 0)
        SKIP(t, "python3 with http.server is not available");
    int web = mts_test_free_port(), mts = mts_test_free_port();
    char webport[16], listen[64], log_web[600], log_srv[600], url_ok[256], url_big[256];
    snprintf(webport, sizeof webport, "%d", web);
    snprintf(listen, sizeof listen, "127.0.0.1:%d", mts);
    snprintf(log_web, sizeof log_web, "%s/e2e_web.log", tmp_dir);
    snprintf(log_srv, sizeof log_srv, "%s/e2e_srv.log", tmp_dir);
    char *web_argv[] = {"python3", "-m", "http.server", webport, "--bind", "127.0.0.1",
                        "--directory", "tests/data", NULL};
    pid_t wpid = mts_test_spawn(web_argv, log_web);
    /* until the web server answers */
    snprintf(cmd, sizeof cmd,
             "for i in $(seq 1 50); do python3 -c 'import urllib.request,sys; "
             "urllib.request.urlopen(\"http://127.0.0.1:%d/cow.off\")' && exit 0; sleep 0.1; "
             "done; exit 1",
             web);
    CHECK(t, mts_test_run(cmd, out, sizeof out) == 0);
    snprintf(url_ok, sizeof url_ok, "cowweb=http://127.0.0.1:%d/cow.off", web);
    snprintf(url_big, sizeof url_big, "cowbig=http://127.0.0.1:%d/cow.off", web);
    char server_bin[600];
    snprintf(server_bin, sizeof server_bin, "%s/mts-server", bin_dir);
    /* two good-or-refused URL models and two refused schemes, with a small cap
     * on one of them: the server serves what it can and says why not the rest */
    char *srv_argv[] = {server_bin, "--listen", listen, "--model", url_ok,
                        "--model", "ftpmodel=ftp://127.0.0.1/cow.off",
                        "--model", "filemodel=file:///etc/passwd", "--quiet", NULL};
    pid_t spid = mts_test_spawn(srv_argv, log_srv);
    CHECKF(t, mts_test_wait_models(bin_dir, listen, NULL, 100, out, sizeof out),
           "server did not come up: %s", out);
    CHECKF(t, strstr(out, "cowweb") && !strstr(out, "ftpmodel") && !strstr(out, "filemodel"),
           "%s", out);
    snprintf(cmd, sizeof cmd, "%s/mts-client 127.0.0.1:%d cowweb --no-render --json --verify",
             bin_dir, mts);
    CHECKF(t, mts_test_run(cmd, out, sizeof out) == 0, "%s", out);
    CHECK(t, strstr(out, "\"complete\":true") && strstr(out, "\"triangles\":5804"));
    mts_test_stop(spid);
    char logtext[8192];
    mts_test_read_file(log_srv, logtext, sizeof logtext);
    CHECKF(t, strstr(logtext, "ftp://") && strstr(logtext, "file://"),
           "refusals not reported: %s", logtext);

    /* over the size cap: nothing to serve, exit 1, the cap named */
    snprintf(cmd, sizeof cmd, "%s/mts-server --listen %s --model %s --max-download 1000",
             bin_dir, listen, url_big);
    CHECK(t, mts_test_run(cmd, out, sizeof out) == 1);
    CHECKF(t, strstr(out, "1000") != NULL, "%s", out);
    mts_test_stop(wpid);
}

/* mts-server + mts-client with pictures at three levels: they exist, are not
 * blank (a blank frame compresses to a few hundred bytes) and differ. */
/* An mts-server on a free loopback port over a folder of cow.off, up once
 * it lists its models; listen gets its address. flag: an extra option or
 * NULL. Returns the pid, or -1 (a failed check says why). */
static pid_t cow_server(mts_test *t, const char *name, const char *flag, char *listen,
                        size_t listen_size)
{
    char out[4096], cmd[2048], dir[600], log[700], server_bin[600];
    snprintf(dir, sizeof dir, "%s/e2e_%s_models", tmp_dir, name);
    snprintf(cmd, sizeof cmd, "rm -rf %s && mkdir -p %s && cp tests/data/cow.off %s/", dir, dir,
             dir);
    CHECK(t, mts_test_run(cmd, out, sizeof out) == 0);
    snprintf(listen, listen_size, "127.0.0.1:%d", mts_test_free_port());
    snprintf(server_bin, sizeof server_bin, "%s/mts-server", bin_dir);
    snprintf(log, sizeof log, "%s/e2e_%s_srv.log", tmp_dir, name);
    char *argv[] = {server_bin, "--models", dir, "--listen", listen,
                    (char *)(flag ? flag : "--quiet"), NULL};
    pid_t spid = mts_test_spawn(argv, log);
    CHECKF(t, mts_test_wait_models(bin_dir, listen, NULL, 100, out, sizeof out),
           "server did not come up (%s)", log);
    return spid;
}

static void test_pngs_at_three_levels(mts_test *t)
{
    char out[8192], cmd[4096], listen[64];
    pid_t spid = cow_server(t, "png", NULL, listen, sizeof listen);
    char png[700];
    snprintf(png, sizeof png, "%s/e2e_cow.png", tmp_dir);
    /* In the sanitizer build LeakSanitizer's exit-time scan crashes while it
     * stops llvmpipe's worker threads ("Tracer caught signal 11"), so this one
     * run skips the leak scan; the renderer's leaks are checked in
     * test_render, where the threads are gone first. */
    snprintf(cmd, sizeof cmd,
             "ASAN_OPTIONS=detect_leaks=0 %s/mts-client %s cow --png %s --png-levels 0,300,1500 "
             "--size 256x256",
             bin_dir, listen, png);
    int rc = mts_test_run(cmd, out, sizeof out);
    mts_test_stop(spid);
    if (rc != 0 && strstr(out, "EGL") && !getenv("MTS_TEST_REQUIRE_EGL"))
        SKIP(t, "no EGL here: %s", out);
    CHECKF(t, rc == 0, "%s", out);
    const char *levels[3] = {"0", "300", "1500"};
    unsigned char *data[3] = {0};
    int sizes[3];
    for (int i = 0; i < 3; i++) {
        char path[800];
        snprintf(path, sizeof path, "%s/e2e_cow_L%s.png", tmp_dir, levels[i]);
        sizes[i] = file_size(path);
        /* a blank 256x256 frame compresses to a few hundred bytes; the
         * flat-shaded base mesh to about 2.7 KB */
        CHECKF(t, sizes[i] > 1500, "%s: %d bytes", path, sizes[i]);
        FILE *f = fopen(path, "rb");
        if (f && sizes[i] > 0) {
            data[i] = malloc((size_t)sizes[i]);
            if (fread(data[i], 1, (size_t)sizes[i], f) != (size_t)sizes[i])
                CHECK(t, 0);
        }
        if (f)
            fclose(f);
    }
    for (int i = 0; i < 3; i++) {
        for (int j = i + 1; j < 3; j++) {
            int same = data[i] && data[j] && sizes[i] == sizes[j] &&
                       memcmp(data[i], data[j], (size_t)sizes[i]) == 0;
            CHECKF(t, !same, "levels %s and %s look the same", levels[i], levels[j]);
        }
    }
    for (int i = 0; i < 3; i++)
        free(data[i]);
}

/* mts-client --records against mts-server: the records form by default
 * ("form":"records", many more bytes, the splits client's checksum and
 * triangles); against mts-server --no-records-form the same request gets the
 * splits form and completes all the same. */
static void test_records_form_programs(mts_test *t)
{
    char out[8192], cmd[4096];
    char splits[3][32] = {{0}}, split_bytes[32] = {0};
    for (int without = 0; without < 2; without++) {
        char listen[64];
        pid_t spid = cow_server(t, without ? "records_without" : "records",
                                without ? "--no-records-form" : NULL, listen, sizeof listen);
        const char *keys[3] = {"checksum", "triangles", "level"};
        for (int records = 0; records < 2; records++) {
            snprintf(cmd, sizeof cmd,
                     "ASAN_OPTIONS=detect_leaks=0 %s/mts-client %s cow --no-render --json "
                     "--verify%s",
                     bin_dir, listen, records ? " --records" : "");
            int rc = mts_test_run(cmd, out, sizeof out);
            CHECKF(t, rc == 0 && strstr(out, "\"complete\":true") &&
                          strstr(out, "\"verified\":true"),
                   "exit %d: %s", rc, out);
            const char *want = records && !without ? "\"form\":\"records\"" : "\"form\":\"splits\"";
            CHECKF(t, strstr(out, want) != NULL, "%s%s: want %s in %s",
                   without ? "--no-records-form, " : "", records ? "--records" : "splits", want,
                   out);
            char v[64], bytes[32];
            mts_test_json(out, "bytes", bytes, sizeof bytes);
            if (!without && !records) {
                for (int k = 0; k < 3; k++)
                    mts_test_json(out, keys[k], splits[k], sizeof splits[k]);
                snprintf(split_bytes, sizeof split_bytes, "%s", bytes);
                CHECKF(t, splits[0][0] != 0, "no checksum: %s", out);
                continue;
            }
            for (int k = 0; k < 3; k++) {
                mts_test_json(out, keys[k], v, sizeof v);
                CHECKF(t, strcmp(v, splits[k]) == 0, "%s: %s, the splits client's %s", keys[k], v,
                       splits[k]);
            }
            if (without) /* the splits form, byte for byte as many */
                CHECKF(t, strcmp(bytes, split_bytes) == 0, "bytes %s, splits %s", bytes,
                       split_bytes);
            else /* the records form: many times the bytes */
                CHECKF(t, atol(bytes) > 4 * atol(split_bytes), "bytes %s, splits %s", bytes,
                       split_bytes);
        }
        mts_test_stop(spid);
    }
}

/* --lod-policy distance and area ask for their stop point: the
 * bytes received are those of the stream stopped at the level they chose,
 * exactly -- the same bytes, level and checksum as --triangles with the
 * triangles they asked for -- far fewer than the whole stream's; and the
 * level drawn is the level received, also at a stop level inside a batch
 * (--level 300: the last batch brings splits past it); budget asks for a
 * first guess and continues while frames fit. */
static void test_policy_asks_stop(mts_test *t)
{
    char out[8192], ref[8192], cmd[4096], listen[64];
    pid_t spid = cow_server(t, "policy", NULL, listen, sizeof listen);
    const char *policies[2] = {"distance --distance 4", "area --distance 3"};
    for (int i = 0; i < 2; i++) {
        snprintf(cmd, sizeof cmd,
                 "ASAN_OPTIONS=detect_leaks=0 %s/mts-client %s cow --size 128x128 --json "
                 "--lod-policy %s",
                 bin_dir, listen, policies[i]);
        int rc = mts_test_run(cmd, out, sizeof out);
        if (rc != 0 && strstr(out, "EGL") && !getenv("MTS_TEST_REQUIRE_EGL")) {
            mts_test_stop(spid);
            SKIP(t, "no EGL here: %s", out);
        }
        CHECKF(t, rc == 0 && strstr(out, "\"complete\":true") &&
                      strstr(out, "\"stop_asked\":true"),
               "%s: exit %d: %s", policies[i], rc, out);
        char asked[32], bytes[32], full[32], level[32], received[32], sum[40];
        mts_test_json(out, "triangles_asked", asked, sizeof asked);
        mts_test_json(out, "bytes", bytes, sizeof bytes);
        mts_test_json(out, "full_stream_bytes", full, sizeof full);
        mts_test_json(out, "level", level, sizeof level);
        mts_test_json(out, "level_received", received, sizeof received);
        mts_test_json(out, "checksum", sum, sizeof sum);
        CHECKF(t, atol(asked) > 0 && atol(bytes) > 0 && atol(bytes) * 3 < atol(full),
               "%s: %s triangles asked, %s bytes of %s", policies[i], asked, bytes, full);
        CHECKF(t, !strcmp(level, received), "%s: drew %s, received %s", policies[i], level,
               received);
        snprintf(cmd, sizeof cmd,
                 "ASAN_OPTIONS=detect_leaks=0 %s/mts-client %s cow --no-render --json "
                 "--triangles %s",
                 bin_dir, listen, asked);
        rc = mts_test_run(cmd, ref, sizeof ref);
        char rbytes[32], rlevel[32], rsum[40];
        mts_test_json(ref, "bytes", rbytes, sizeof rbytes);
        mts_test_json(ref, "level", rlevel, sizeof rlevel);
        mts_test_json(ref, "checksum", rsum, sizeof rsum);
        CHECKF(t, rc == 0 && !strcmp(bytes, rbytes) && !strcmp(level, rlevel) &&
                      !strcmp(sum, rsum) && sum[0],
               "%s: %s bytes, level %s, checksum %s; --triangles %s: %s, %s, %s", policies[i],
               bytes, level, sum, asked, rbytes, rlevel, rsum);
    }
    /* budget: a first guess, then more while frames fit; with a budget no
     * frame can miss (--fps 0.01: 100 s a frame) it continues to the full
     * level, the unbroken stream's checksum */
    snprintf(cmd, sizeof cmd,
             "ASAN_OPTIONS=detect_leaks=0 %s/mts-client %s cow --size 64x64 --json "
             "--lod-policy budget --fps 0.01",
             bin_dir, listen);
    int brc = mts_test_run(cmd, out, sizeof out);
    snprintf(cmd, sizeof cmd, "ASAN_OPTIONS=detect_leaks=0 %s/mts-client %s cow --no-render --json",
             bin_dir, listen);
    CHECK(t, mts_test_run(cmd, ref, sizeof ref) == 0);
    char bl[32], bls[32], bc[32], bsum[40], fsum[40];
    mts_test_json(out, "level", bl, sizeof bl);
    mts_test_json(out, "levels", bls, sizeof bls);
    mts_test_json(out, "continuations", bc, sizeof bc);
    mts_test_json(out, "checksum", bsum, sizeof bsum);
    mts_test_json(ref, "checksum", fsum, sizeof fsum);
    CHECKF(t, brc == 0 && !strcmp(bl, bls) && atol(bc) >= 1 && bsum[0] && !strcmp(bsum, fsum),
           "budget: exit %d, level %s of %s, %s continuations, checksum %s (full %s): %s", brc,
           bl, bls, bc, bsum, fsum, out);
    /* a stop inside a batch is drawn at the stop level */
    snprintf(cmd, sizeof cmd,
             "ASAN_OPTIONS=detect_leaks=0 %s/mts-client %s cow --size 64x64 --json --level 300",
             bin_dir, listen);
    int rc = mts_test_run(cmd, out, sizeof out);
    char level[32];
    mts_test_json(out, "level", level, sizeof level);
    CHECKF(t, rc == 0 && !strcmp(level, "300"), "--level 300 drew level %s: %s", level, out);
    mts_test_stop(spid);
}

int main(int argc, char **argv)
{
    (void)argc;
    mts_test_bin_dir(argv[0], bin_dir, sizeof bin_dir);
    snprintf(tmp_dir, sizeof tmp_dir, "%s", mts_test_tmpdir());
    signal(SIGPIPE, SIG_IGN);
    mts_test t = {0};
    RUN(&t, test_server_dies_mid_stream);
    RUN(&t, test_peer_text_not_utf8);
    RUN(&t, test_info_for_another_model);
    RUN(&t, test_trickle_bounded);
    RUN(&t, test_crc_mismatch_resumed);
    RUN(&t, test_url_models);
    RUN(&t, test_pngs_at_three_levels);
    RUN(&t, test_records_form_programs);
    RUN(&t, test_policy_asks_stop);
    return mts_test_end(&t);
}
