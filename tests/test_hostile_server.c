/* A hostile server against the client. The client's memory must follow what
 * arrived, never what a server claimed:
 *   - a MODEL_INFO whose counts (vertices, levels, base vertices, triangles,
 *     triangles at the stop, strips, strip capacities, key levels) are
 *     pumped up to 2^20, 2^24, 2^28 or 2^32-1, followed by cow's real BASE
 *     and batches, is refused at MODEL_INFO with an error that names the
 *     claim -- through the stream client API, and end to end by mts-client
 *     against a fake server, whose peak memory (the child's ru_maxrss, in
 *     the release build) stays under 256 MB;
 *   - a claim of a larger model that is consistent in itself is not
 *     refused at MODEL_INFO, but what the client allocates grows with the
 *     batches that come, not with the claim;
 *   - `mts-client --list` prints a MODELS frame's entries only once the
 *     whole frame checks out, and a listing that stalls or is cut says what
 *     happened to the model list.
 *
 * `test_hostile_server --serve FIELD VALUE PORT` serves one such stream on
 * 127.0.0.1:PORT until killed, for measuring a client by hand
 * (/usr/bin/time -v mts-client 127.0.0.1:PORT cow --no-render). */
#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <stdint.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <sys/wait.h>
#include <unistd.h>

#include "build.h"
#include "mesh.h"
#include "stream.h"
#include "test.h"
#include "test_proc.h"
#include "wire.h"

static char bin_dir[512], tmp_dir[512];

#define PEAK_LIMIT_KB (256L * 1024)

/* ASan's shadow and quarantine make RSS meaningless: the figures are
 * checked in the release build only, the refusals in both. */
#if defined(__SANITIZE_ADDRESS__)
#define MEASURE_RSS 0
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define MEASURE_RSS 0
#endif
#endif
#ifndef MEASURE_RSS
#define MEASURE_RSS 1
#endif

/* cow's stream (model name "cow"), as a server would send it. */
static int cow_stream(mts_stream *s, mts_error *err)
{
    mts_mesh mesh = {0};
    mts_model m;
    if (mts_mesh_load("tests/data/cow.off", NULL, &mesh, NULL, err) != MTS_OK)
        return 0;
    mts_result rc = mts_build_model(&mesh, "cow", NULL, &m, NULL, err);
    mts_mesh_free(&mesh);
    if (rc != MTS_OK)
        return 0;
    rc = mts_stream_build(&m, "cow", NULL, s, err);
    mts_model_free(&m);
    return rc == MTS_OK;
}

static const char *const FIELDS[] = {"vertices",       "levels",         "base_vertices",
                                     "triangles",      "stop_triangles", "strips",
                                     "capacity_total", "key_count"};
#define FIELD_COUNT (sizeof FIELDS / sizeof FIELDS[0])
static const uint32_t VALUES[] = {1u << 20, 1u << 24, 1u << 28, UINT32_MAX};
#define VALUE_COUNT (sizeof VALUES / sizeof VALUES[0])

/* MODEL_INFO as PROTOCOL.md lays it out, written here rather than with
 * mts_wire_put_model_info so that a key count with no key levels behind it
 * can be sent too. */
static void put_info(mts_buf *b, const mts_wire_model_info *mi)
{
    size_t f = mts_wire_frame_begin(b, MTS_MSG_MODEL_INFO);
    mts_buf_u16(b, mi->minor);
    mts_buf_u64(b, mi->stream_id);
    mts_buf_string(b, mi->model, strlen(mi->model));
    const uint32_t counts[] = {mi->vertices, mi->base_vertices, mi->levels, mi->triangles,
                               mi->strips,   mi->stop_level,    mi->stop_triangles};
    for (size_t i = 0; i < sizeof counts / sizeof counts[0]; i++)
        mts_buf_varint(b, counts[i]);
    for (int a = 0; a < 3; a++)
        mts_buf_f32(b, mi->bbox_min[a]);
    for (int a = 0; a < 3; a++)
        mts_buf_f32(b, mi->bbox_max[a]);
    mts_buf_u8(b, mi->quant_bits);
    mts_buf_u8(b, mi->flags);
    for (int a = 0; a < 3; a++)
        mts_buf_f32(b, mi->grid_origin[a]);
    mts_buf_f32(b, mi->grid_range);
    mts_buf_varint(b, mi->batch_count);
    mts_buf_varint(b, mi->batch_size);
    mts_buf_varint(b, mi->capacity_total);
    mts_buf_varint(b, mi->key_count);
    uint32_t prev = 0;
    for (uint32_t k = 0; mi->key_levels && k < mi->key_count; k++) {
        mts_buf_varint(b, mi->key_levels[k] - prev);
        prev = mi->key_levels[k];
    }
    mts_wire_frame_end(b, f);
}

/* Levels claimed: the vertices follow, and the batches so that their sizes
 * still add up (a server that lies does not also trip the first check). */
static void claim_levels(mts_wire_model_info *mi, uint64_t levels)
{
    if (levels > UINT32_MAX - mi->base_vertices)
        levels = UINT32_MAX - mi->base_vertices;
    mi->levels = (uint32_t)levels;
    mi->vertices = mi->base_vertices + mi->levels;
    mi->batch_count = (uint32_t)((levels + mi->batch_size - 1) / mi->batch_size);
}

/* cow's MODEL_INFO with `field` claiming `value` (the other counts as they
 * are, or raised as little as the wire format needs to take the claim),
 * then cow's real BASE and every batch: what a hostile server sends.
 * "model" claims a whole larger model, consistent in itself: `value`
 * vertices, twice the triangles, capacities of 5 indices a vertex. *want
 * gets the words a refusal must hold. */
static void hostile_answer(const mts_stream *s, const char *field, uint32_t value, mts_buf *out,
                           char *want, size_t want_size)
{
    mts_buf honest = {0};
    mts_stream_put_model_info(s, s->model.level_count, &honest);
    mts_wire_model_info mi;
    mts_error err = {0};
    if (mts_wire_parse_model_info(honest.data + MTS_WIRE_HEADER, honest.size - MTS_WIRE_HEADER,
                                  &mi, &err) != MTS_OK) {
        fprintf(stderr, "cow's own MODEL_INFO: %s\n", err.msg);
        abort();
    }
    mts_buf_free(&honest);
    uint32_t *keys = mi.key_levels;
    if (!strcmp(field, "vertices")) {
        claim_levels(&mi, (uint64_t)value - mi.base_vertices);
        snprintf(want, want_size, "claims %u vertices", mi.vertices);
    } else if (!strcmp(field, "levels")) {
        claim_levels(&mi, value);
        snprintf(want, want_size, "%u levels", mi.levels);
    } else if (!strcmp(field, "base_vertices")) {
        const uint32_t levels = mi.levels;
        mi.base_vertices = value - levels;
        mi.vertices = mi.base_vertices + levels;
        snprintf(want, want_size, "%u base", mi.base_vertices);
    } else if (!strcmp(field, "triangles")) {
        mi.triangles = value;
        snprintf(want, want_size, "claims %u triangles", value);
    } else if (!strcmp(field, "stop_triangles")) {
        mi.stop_triangles = value;
        snprintf(want, want_size, "claims %u triangles at the stop level", value);
    } else if (!strcmp(field, "strips")) {
        /* the wire format takes no more strips than capacity indices */
        mi.strips = value;
        if (mi.capacity_total < value)
            mi.capacity_total = value;
        snprintf(want, want_size, "claims %u strips", value);
    } else if (!strcmp(field, "capacity_total")) {
        mi.capacity_total = value;
        snprintf(want, want_size, "claims %u indices of strip capacity", value);
    } else if (!strcmp(field, "key_count")) {
        mi.key_count = value;
        mi.key_levels = NULL;
        snprintf(want, want_size, "%u key levels", value);
    } else if (!strcmp(field, "model")) {
        claim_levels(&mi, (uint64_t)value - mi.base_vertices);
        mi.triangles = mi.vertices > UINT32_MAX / 2 ? UINT32_MAX : 2 * mi.vertices;
        mi.capacity_total = mi.vertices > UINT32_MAX / 5 ? UINT32_MAX : 5 * mi.vertices;
        want[0] = 0;
    } else {
        fprintf(stderr, "no field %s\n", field);
        abort();
    }
    put_info(out, &mi);
    mi.key_levels = keys;
    mts_wire_model_info_free(&mi);
    mts_buf_put(out, s->bytes, s->size);
}

/* Feeds buf's frames to a fresh stream client until one fails: the index
 * of the frame that failed (-1: none did), its error in *err. */
static int feed_here(const mts_buf *buf, mts_error *err, uint64_t *checksum)
{
    mts_stream_client c;
    mts_stream_client_init(&c);
    mts_wire_reader r = {0};
    int failed = -1, k = 0;
    if (mts_wire_reader_feed(&r, buf->data, buf->size, err) != MTS_OK)
        failed = 0;
    uint8_t type;
    const uint8_t *p;
    size_t n;
    while (failed < 0 && mts_wire_reader_next(&r, &type, &p, &n, err) == 1) {
        mts_stream_event ev;
        if (mts_stream_client_frame(&c, type, p, n, &ev, err) != MTS_OK)
            failed = k;
        k++;
    }
    if (checksum)
        *checksum = c.have_lod ? mts_stream_checksum(&c.lod, c.quantized) : 0;
    mts_wire_reader_free(&r);
    mts_stream_client_free(&c);
    return failed;
}

/* The children here run with their address space capped (release build),
 * so that a client that follows a claim fails this test, not the machine. */
#define AS_LIMIT ((rlim_t)8 << 30)

static void cap_memory(void)
{
    if (MEASURE_RSS) {
        struct rlimit rl = {AS_LIMIT, AS_LIMIT};
        setrlimit(RLIMIT_AS, &rl);
    }
}

/* feed_here in a child process under cap_memory (its checksum is not
 * needed where this is used). */
static int feed(const mts_buf *buf, mts_error *err)
{
    int fds[2];
    if (pipe(fds) != 0)
        return -2;
    pid_t pid = fork();
    if (pid == 0) {
        close(fds[0]);
        cap_memory();
        mts_error e = {0};
        int failed = feed_here(buf, &e, NULL);
        (void)!write(fds[1], &failed, sizeof failed);
        (void)!write(fds[1], e.msg, sizeof e.msg);
        _exit(0);
    }
    close(fds[1]);
    int failed = -3;
    memset(err->msg, 0, sizeof err->msg);
    if (pid < 0 || read(fds[0], &failed, sizeof failed) != (ssize_t)sizeof failed ||
        read(fds[0], err->msg, sizeof err->msg) < 0)
        failed = -3;
    err->msg[sizeof err->msg - 1] = 0;
    close(fds[0]);
    if (pid > 0)
        waitpid(pid, NULL, 0);
    return failed;
}

/* ---- processes ---------------------------------------------------------- */

/* A server in a child process: every connection gets its request read and
 * then `answer` whole (mode 0) and a close; or only its first `cut` bytes
 * and then nothing until the client gives up (mode 1); or a byte every 50
 * ms (mode 2). It lives until killed (120 s at most). */
static pid_t fake_server(int lfd, const mts_buf *answer, int mode, size_t cut)
{
    pid_t pid = fork();
    if (pid != 0) {
        close(lfd);
        return pid;
    }
    alarm(120);
    signal(SIGPIPE, SIG_IGN);
    for (;;) {
        int fd = accept(lfd, NULL, NULL);
        if (fd < 0)
            continue;
        char req[256];
        (void)!recv(fd, req, sizeof req, 0);
        if (mode == 0) {
            (void)!send(fd, answer->data, answer->size, MSG_NOSIGNAL);
        } else if (mode == 1) {
            (void)!send(fd, answer->data, cut < answer->size ? cut : answer->size, MSG_NOSIGNAL);
            /* silent until the client hangs up */
            char x;
            while (recv(fd, &x, 1, 0) > 0)
                ;
        } else {
            for (size_t i = 0; i < answer->size && send(fd, answer->data + i, 1, MSG_NOSIGNAL) == 1;
                 i++)
                usleep(50000);
        }
        usleep(100000);
        close(fd);
    }
}

static void stop(pid_t pid)
{
    if (pid > 0) {
        kill(pid, SIGKILL);
        waitpid(pid, NULL, 0);
    }
}

/* Runs the shell-free argv with stdout and stderr into one file, and waits
 * for it with wait4: its exit status (-1: killed), peak RSS in KB, the
 * first size - 1 bytes of its output in out and the output's lines. */
typedef struct ran {
    int status;
    long maxrss_kb;
    size_t lines;
} ran;

static ran run_client(char *const argv[], char *out, size_t size)
{
    ran r = {-1, 0, 0};
    char path[700];
    snprintf(path, sizeof path, "%s/hostile_client_%d.out", tmp_dir, (int)getpid());
    pid_t pid = fork();
    if (pid == 0) {
        int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (fd < 0 || dup2(fd, 1) < 0 || dup2(fd, 2) < 0)
            _exit(126);
        close(fd);
        setenv("ASAN_OPTIONS", "detect_leaks=0", 1);
        cap_memory();
        alarm(60);
        execv(argv[0], argv);
        _exit(127);
    }
    int st = 0;
    struct rusage ru;
    memset(&ru, 0, sizeof ru);
    if (pid > 0 && wait4(pid, &st, 0, &ru) == pid) {
        r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
        r.maxrss_kb = ru.ru_maxrss;
    }
    out[0] = 0;
    FILE *f = fopen(path, "rb");
    if (f) {
        size_t got = fread(out, 1, size - 1, f);
        out[got] = 0;
        rewind(f);
        int ch;
        while ((ch = fgetc(f)) != EOF)
            r.lines += ch == '\n';
        fclose(f);
    }
    remove(path);
    return r;
}

/* ---- MODEL_INFO's claims ------------------------------------------------ */

/* The stream as it is decodes whole to the server's checksum: the harness
 * is sound, and the bounds below take a real model. */
static void test_honest_stream_accepted(mts_test *t)
{
    mts_stream s;
    mts_error err = {0};
    CHECKF(t, cow_stream(&s, &err), "%s", err.msg);
    if (t->case_failed)
        return;
    mts_buf b = {0};
    mts_stream_put_model_info(&s, s.model.level_count, &b);
    mts_buf_put(&b, s.bytes, s.size);
    uint64_t sum = 0;
    int failed = feed_here(&b, &err, &sum);
    CHECKF(t, failed < 0, "frame %d: %s", failed, err.msg);
    CHECKF(t, sum == s.level_checksum[s.model.level_count], "checksum %016llx, server %016llx",
           (unsigned long long)sum, (unsigned long long)s.level_checksum[s.model.level_count]);
    mts_buf_free(&b);
    mts_stream_free(&s);
}

/* Every pumped count is refused at MODEL_INFO (frame 0), by name. */
static void test_claims_refused_by_stream_client(mts_test *t)
{
    mts_stream s;
    mts_error err = {0};
    CHECKF(t, cow_stream(&s, &err), "%s", err.msg);
    if (t->case_failed)
        return;
    for (size_t f = 0; f < FIELD_COUNT; f++) {
        for (size_t v = 0; v < VALUE_COUNT; v++) {
            mts_buf b = {0};
            char want[160];
            hostile_answer(&s, FIELDS[f], VALUES[v], &b, want, sizeof want);
            memset(&err, 0, sizeof err);
            int failed = feed(&b, &err);
            CHECKF(t, failed == 0 && strstr(err.msg, "MODEL_INFO") && strstr(err.msg, want),
                   "%s = %u: frame %d failed (%s); want MODEL_INFO and '%s'", FIELDS[f],
                   VALUES[v], failed, err.msg, want);
            mts_buf_free(&b);
        }
    }
    mts_stream_free(&s);
}

/* mts-client against a fake server sending each hostile answer: exit 1,
 * the claim named, and (release build) a peak under 256 MB, headless
 * rendering included for one size of each claim. */
static void test_claims_refused_end_to_end(mts_test *t)
{
    mts_stream s;
    mts_error err = {0};
    CHECKF(t, cow_stream(&s, &err), "%s", err.msg);
    if (t->case_failed)
        return;
    char client[700];
    snprintf(client, sizeof client, "%s/mts-client", bin_dir);
    for (size_t f = 0; f < FIELD_COUNT; f++) {
        for (size_t v = 0; v < VALUE_COUNT; v++) {
            mts_buf b = {0};
            char want[160], addr[64], out[4096];
            hostile_answer(&s, FIELDS[f], VALUES[v], &b, want, sizeof want);
            int port, lfd = mts_test_listen_any(&port);
            CHECK(t, lfd >= 0);
            if (lfd < 0)
                break;
            pid_t pid = fake_server(lfd, &b, 0, 0);
            snprintf(addr, sizeof addr, "127.0.0.1:%d", port);
            const int render = v == 2;
            char *argv[] = {client, addr, "cow", "--timeout", "10", "--max-time", "30",
                            "--no-render", NULL, NULL};
            if (render) {
                argv[7] = "--size";
                argv[8] = "64x64";
            }
            ran r = run_client(argv, out, sizeof out);
            stop(pid);
            CHECKF(t, r.status == 1 && strstr(out, "MODEL_INFO") && strstr(out, want),
                   "%s = %u%s: exit %d, want '%s' in: %s", FIELDS[f], VALUES[v],
                   render ? " (rendering)" : "", r.status, want, out);
            if (MEASURE_RSS)
                CHECKF(t, r.maxrss_kb < PEAK_LIMIT_KB, "%s = %u%s: peak %ld KB", FIELDS[f],
                       VALUES[v], render ? " (rendering)" : "", r.maxrss_kb);
            if (getenv("MTS_TEST_VERBOSE"))
                fprintf(stderr, "  %-15s %10u%s: peak %6ld KB: %.*s\n", FIELDS[f], VALUES[v],
                        render ? " rendering" : "", r.maxrss_kb, (int)strcspn(out, "\n"), out);
            mts_buf_free(&b);
        }
    }
    mts_stream_free(&s);
}

/* A claim of a larger model that holds together (2^24 vertices, twice the
 * triangles): nothing at MODEL_INFO can refute it, so the client takes
 * cow's base and batches until the data contradicts the claim (cow's last
 * split is not the last of 2^24), and what it held meanwhile followed the
 * batches, not the claim: without drawing, a small part of the 64 MB that
 * one array of 4 bytes a claimed vertex would take; drawing, under 256 MB
 * (the renderer's buffers grow with the vertices and slots that came,
 * where sized by the claim they took 800 MB). */
static void test_consistent_claim_grows_with_data(mts_test *t)
{
    mts_stream s;
    mts_error err = {0};
    CHECKF(t, cow_stream(&s, &err), "%s", err.msg);
    if (t->case_failed)
        return;
    mts_buf b = {0};
    char want[160];
    hostile_answer(&s, "model", 1u << 24, &b, want, sizeof want);
    int failed = feed(&b, &err);
    /* MODEL_INFO, BASE, then cow's batches: the one with cow's last split
     * is where the data stops fitting the claim */
    CHECKF(t, failed > 1 && strstr(err.msg, "BATCH"), "frame %d failed: %s", failed, err.msg);
    for (int draw = 0; draw < 2; draw++) {
        int port, lfd = mts_test_listen_any(&port);
        CHECK(t, lfd >= 0);
        if (lfd < 0)
            break;
        pid_t pid = fake_server(lfd, &b, 0, 0);
        char client[700], addr[64], out[4096];
        snprintf(client, sizeof client, "%s/mts-client", bin_dir);
        snprintf(addr, sizeof addr, "127.0.0.1:%d", port);
        char *argv[] = {client, addr, "cow", draw ? "--size" : "--no-render",
                        draw ? "64x64" : "--timeout", draw ? "--timeout" : "10",
                        draw ? "10" : NULL, NULL};
        ran r = run_client(argv, out, sizeof out);
        stop(pid);
        CHECKF(t, r.status == 1 && strstr(out, "BATCH"), "%s: exit %d: %s",
               draw ? "drawing" : "headless", r.status, out);
        if (MEASURE_RSS)
            CHECKF(t, r.maxrss_kb < (draw ? PEAK_LIMIT_KB : 64 * 1024), "%s: peak %ld KB",
                   draw ? "drawing" : "headless", r.maxrss_kb);
        if (getenv("MTS_TEST_VERBOSE"))
            fprintf(stderr, "  consistent claim, %s: peak %6ld KB\n",
                    draw ? "drawing" : "headless", r.maxrss_kb);
    }
    mts_buf_free(&b);
    mts_stream_free(&s);
}

/* ---- the model list ----------------------------------------------------- */

/* A MODELS frame of `count` entries named m0, m1, ...; `broken`: one more
 * entry announced than there are, so the frame fails at its end. */
static void models_frame(mts_buf *b, uint32_t count, int broken)
{
    size_t f = mts_wire_frame_begin(b, MTS_MSG_MODELS);
    mts_buf_varint(b, count + (broken ? 1 : 0));
    for (uint32_t i = 0; i < count; i++) {
        char name[16];
        int len = snprintf(name, sizeof name, "m%u", i);
        mts_buf_string(b, name, (size_t)len);
        mts_buf_varint(b, 1000);
        mts_buf_varint(b, 2000);
        mts_buf_varint(b, 900);
        mts_buf_varint(b, 50000);
    }
    if (broken)
        mts_buf_u8(b, 0xff); /* the announced entry's name runs past the frame */
    mts_wire_frame_end(b, f);
}

static void count_model(void *user, const mts_wire_model_entry *m)
{
    (void)m;
    (*(uint32_t *)user)++;
}

/* A MODELS frame that fails at its end prints none of its 200,000 entries,
 * only the error; through the API too, not one entry is handed out. A good
 * frame prints each entry. */
static void test_list_checked_before_printing(mts_test *t)
{
    mts_buf bad = {0}, good = {0};
    models_frame(&bad, 200000, 1);
    models_frame(&good, 3, 0);
    /* API: the callback sees nothing of a bad frame, all of a good one */
    uint32_t seen = 0;
    for (int k = 0; k < 2; k++) {
        const mts_buf *b = k ? &good : &bad;
        mts_stream_client c;
        mts_stream_client_init(&c);
        c.user = &seen;
        c.on_model = count_model;
        seen = 0;
        mts_stream_event ev;
        mts_error err = {0};
        mts_result rc = mts_stream_client_frame(&c, MTS_MSG_MODELS, b->data + MTS_WIRE_HEADER,
                                                b->size - MTS_WIRE_HEADER, &ev, &err);
        if (k == 0)
            CHECKF(t, rc != MTS_OK && seen == 0, "bad frame: rc %d, %u entries handed out",
                   (int)rc, seen);
        else
            CHECKF(t, rc == MTS_OK && ev == MTS_EV_MODELS && seen == 3, "rc %d (%s), %u entries",
                   (int)rc, err.msg, seen);
        mts_stream_client_free(&c);
    }
    int port, lfd = mts_test_listen_any(&port);
    CHECK(t, lfd >= 0);
    if (lfd >= 0) {
        pid_t pid = fake_server(lfd, &bad, 0, 0);
        char client[700], addr[64], out[4096];
        snprintf(client, sizeof client, "%s/mts-client", bin_dir);
        snprintf(addr, sizeof addr, "127.0.0.1:%d", port);
        char *argv[] = {client, addr, "--list", "--timeout", "10", NULL};
        ran r = run_client(argv, out, sizeof out);
        stop(pid);
        CHECKF(t, r.status == 1 && r.lines == 1 && strstr(out, "MODELS"),
               "exit %d, %zu lines: %.300s", r.status, r.lines, out);
    }
    if ((lfd = mts_test_listen_any(&port)) >= 0) {
        pid_t pid = fake_server(lfd, &good, 0, 0);
        char client[700], addr[64], out[4096];
        snprintf(client, sizeof client, "%s/mts-client", bin_dir);
        snprintf(addr, sizeof addr, "127.0.0.1:%d", port);
        char *argv[] = {client, addr, "--list", NULL};
        ran r = run_client(argv, out, sizeof out);
        stop(pid);
        CHECKF(t, r.status == 0 && r.lines == 3 && strstr(out, "m2 "), "exit %d, %zu lines: %s",
               r.status, r.lines, out);
    }
    mts_buf_free(&bad);
    mts_buf_free(&good);
}

/* A listing that stops half-way (nothing more for --timeout), trickles
 * past --max-time, or is cut by a close says what happened to the model
 * list, in the list's words: no END, no batches, which a listing has not. */
static void test_list_stalled_says_so(mts_test *t)
{
    mts_buf list = {0};
    models_frame(&list, 500, 0);
    const struct {
        int mode;
        const char *opt, *val, *want;
    } cases[] = {
        {1, "--timeout", "1", "the server stopped sending the model list (no data for 1 s)"},
        {2, "--max-time", "1.5", "the model list did not come whole within 1.5 s"},
        {0, NULL, NULL, "the server closed the connection before the model list was whole"},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        int port, lfd = mts_test_listen_any(&port);
        CHECK(t, lfd >= 0);
        if (lfd < 0)
            break;
        mts_buf cut = {0};
        const mts_buf *answer = &list;
        if (cases[k].mode == 0) { /* a close half-way through the frame */
            mts_buf_put(&cut, list.data, list.size / 2);
            answer = &cut;
        }
        pid_t pid = fake_server(lfd, answer, cases[k].mode, list.size / 2);
        char client[700], addr[64], out[4096];
        snprintf(client, sizeof client, "%s/mts-client", bin_dir);
        snprintf(addr, sizeof addr, "127.0.0.1:%d", port);
        char *argv[] = {client, addr, "--list", (char *)cases[k].opt, (char *)cases[k].val, NULL};
        ran r = run_client(argv, out, sizeof out);
        stop(pid);
        CHECKF(t, r.status == 1 && strstr(out, cases[k].want) && !strstr(out, "END") &&
                      !strstr(out, "batches"),
               "exit %d, want '%s' in: %s", r.status, cases[k].want, out);
        mts_buf_free(&cut);
    }
    mts_buf_free(&list);
}

/* --serve FIELD VALUE PORT: one hostile stream on 127.0.0.1:PORT. */
static int serve(const char *field, const char *value, const char *port_text)
{
    mts_stream s;
    mts_error err = {0};
    if (!cow_stream(&s, &err)) {
        fprintf(stderr, "cow: %s\n", err.msg);
        return 1;
    }
    mts_buf b = {0};
    char want[160];
    hostile_answer(&s, field, (uint32_t)strtoul(value, NULL, 0), &b, want, sizeof want);
    int fd = socket(AF_INET, SOCK_STREAM, 0), one = 1;
    struct sockaddr_in a = {0};
    a.sin_family = AF_INET;
    a.sin_port = htons((uint16_t)atoi(port_text));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    if (bind(fd, (struct sockaddr *)&a, sizeof a) != 0 || listen(fd, 16) != 0) {
        fprintf(stderr, "listen on %s: %s\n", port_text, strerror(errno));
        return 1;
    }
    fprintf(stderr, "serving cow with %s = %s on 127.0.0.1:%s\n", field, value, port_text);
    signal(SIGPIPE, SIG_IGN);
    for (;;) {
        int c = accept(fd, NULL, NULL);
        if (c < 0)
            continue;
        char req[256];
        (void)!recv(c, req, sizeof req, 0);
        (void)!send(c, b.data, b.size, MSG_NOSIGNAL);
        usleep(100000);
        close(c);
    }
}

int main(int argc, char **argv)
{
    if (argc == 5 && !strcmp(argv[1], "--serve"))
        return serve(argv[2], argv[3], argv[4]);
    mts_test_bin_dir(argv[0], bin_dir, sizeof bin_dir);
    snprintf(tmp_dir, sizeof tmp_dir, "%s", mts_test_tmpdir());
    signal(SIGPIPE, SIG_IGN);
    mts_test t = {0};
    RUN(&t, test_honest_stream_accepted);
    RUN(&t, test_claims_refused_by_stream_client);
    RUN(&t, test_claims_refused_end_to_end);
    RUN(&t, test_consistent_claim_grows_with_data);
    RUN(&t, test_list_checked_before_printing);
    RUN(&t, test_list_stalled_says_so);
    return mts_test_end(&t);
}
