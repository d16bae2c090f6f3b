/* mts-stress against mts-server over loopback, and the server under load and
 * abuse:
 *   - many applying clients all complete, each receiving the whole stream,
 *     also on two threads with two decoding at a time;
 *   - --no-apply --verify clients complete too;
 *   - over --max-clients, clients get ERROR busy, counted as such, while the
 *     others complete;
 *   - silent and byte-a-second clients are dropped at the handshake timeout
 *     without holding up well-behaved clients served at the same moment;
 *   - clients that reset or vanish mid-stream are cleaned up: the server
 *     stops cleanly afterwards (in the ASan build, LeakSanitizer checks that
 *     nothing leaked at its exit);
 *   - --workers 2 serves everyone; --rate-limit paces a stream; and
 *     --stats-interval writes stats lines. */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdint.h>

#include "clock.h"
#include "test.h"
#include "test_proc.h"
#include "wire.h"

static char bin_dir[512], tmp_dir[512], models_dir[600];

typedef struct server {
    pid_t pid;
    int port;
    char log[700];
} server;

/* Starts mts-server on a free port serving models_dir, plus extra options. */
static int server_start(server *sv, const char *name, const char *const *extra)
{
    char bin[600], listen[64];
    snprintf(bin, sizeof bin, "%s/mts-server", bin_dir);
    sv->port = mts_test_free_port();
    snprintf(listen, sizeof listen, "127.0.0.1:%d", sv->port);
    snprintf(sv->log, sizeof sv->log, "%s/stress_%s.log", tmp_dir, name);
    char *argv[32] = {bin, "--models", models_dir, "--listen", listen};
    int n = 5;
    for (; extra && *extra && n < 30; extra++)
        argv[n++] = (char *)*extra;
    argv[n] = NULL;
    sv->pid = mts_test_spawn(argv, sv->log);
    return mts_test_wait_port(sv->port, 30);
}

static int server_stop(server *sv)
{
    int st = mts_test_stop(sv->pid);
    sv->pid = 0;
    return st;
}

/* Runs mts-stress with args against sv; returns its exit status, output in out. */
static int stress(const server *sv, const char *args, char *out, size_t size)
{
    char cmd[2048];
    snprintf(cmd, sizeof cmd, "%s/mts-stress 127.0.0.1:%d %s", bin_dir, sv->port, args);
    return mts_test_run(cmd, out, size);
}

static long json_num(const char *json, const char *key)
{
    char pat[64];
    snprintf(pat, sizeof pat, "\"%s\":", key);
    const char *p = strstr(json, pat);
    return p ? strtol(p + strlen(pat), NULL, 10) : -1;
}

/* A HELLO for the whole stream of model, as any client sends it. */
static void put_hello(mts_buf *b, const char *model)
{
    mts_wire_hello h = {0};
    h.major = MTS_WIRE_MAJOR;
    h.minor = MTS_WIRE_MINOR;
    snprintf(h.model, sizeof h.model, "%s", model);
    mts_wire_put_hello(b, &h);
}

static int count_lines(const char *text, const char *needle)
{
    int n = 0;
    for (const char *p = text; (p = strstr(p, needle)); p += strlen(needle))
        n++;
    return n;
}

static void test_many_clients_apply(mts_test *t)
{
    server sv;
    CHECK(t, server_start(&sv, "apply", NULL));
    char one[4096], out[4096];
    CHECKF(t, stress(&sv, "cow --json", one, sizeof one) == 0, "%s", one);
    long stream_bytes = json_num(one, "bytes");
    CHECK(t, stream_bytes > 10000);
    int rc = stress(&sv, "cow --clients 100 --concurrency 50 --ramp 0.2 --json", out, sizeof out);
    CHECKF(t, rc == 0, "exit %d: %s", rc, out);
    CHECKF(t, json_num(out, "succeeded") == 100 && json_num(out, "failed") == 0, "%s", out);
    /* every client got the whole stream, no more, no less */
    CHECKF(t, json_num(out, "bytes") == 100 * stream_bytes, "%s vs %ld each", out, stream_bytes);
    CHECK(t, strstr(out, "\"failures\":{}") && strstr(out, "\"p99_ms_final\":"));
    CHECK(t, server_stop(&sv) == 0);
}

/* Two event loops sharing the clients, two clients decoding at a time:
 * every socket is still read as bytes come (the rest wait in their
 * readers, then decode in turn), so all complete and each got the whole
 * stream; and one thread alone as well. */
static void test_threads_and_appliers(mts_test *t)
{
    server sv;
    CHECK(t, server_start(&sv, "appliers", NULL));
    char one[4096], out[4096];
    CHECKF(t, stress(&sv, "cow --json", one, sizeof one) == 0, "%s", one);
    long stream_bytes = json_num(one, "bytes");
    const char *runs[] = {"cow --clients 120 --threads 2 --appliers 2 --json",
                          "cow --clients 40 --threads 1 --appliers 1 --json"};
    const long clients[] = {120, 40};
    for (int i = 0; i < 2; i++) {
        int rc = stress(&sv, runs[i], out, sizeof out);
        CHECKF(t, rc == 0 && json_num(out, "succeeded") == clients[i] &&
                      json_num(out, "failed") == 0,
               "%s: exit %d: %s", runs[i], rc, out);
        CHECKF(t, json_num(out, "bytes") == clients[i] * stream_bytes, "%s", out);
    }
    CHECK(t, stress(&sv, "cow --threads 0", out, sizeof out) == 2);
    CHECK(t, server_stop(&sv) == 0);
}

static void test_no_apply_verify(mts_test *t)
{
    server sv;
    CHECK(t, server_start(&sv, "noapply", NULL));
    char out[4096];
    int rc = stress(&sv, "cow --clients 300 --no-apply --verify --json", out, sizeof out);
    CHECKF(t, rc == 0 && json_num(out, "succeeded") == 300, "exit %d: %s", rc, out);
    CHECK(t, strstr(out, "\"apply\":false") != NULL);
    /* a partial stop: fewer bytes, still complete */
    rc = stress(&sv, "cow --clients 20 --fraction 0.3 --json", out, sizeof out);
    CHECKF(t, rc == 0 && json_num(out, "succeeded") == 20, "exit %d: %s", rc, out);
    CHECK(t, server_stop(&sv) == 0);
}

static void test_busy(mts_test *t)
{
    /* 4 slots, each stream paced to last about a second: the rest are refused */
    const char *extra[] = {"--max-clients", "4", "--rate-limit", "60000", NULL};
    server sv;
    CHECK(t, server_start(&sv, "busy", extra));
    char out[4096];
    int rc = stress(&sv, "cow --clients 40 --no-apply --json", out, sizeof out);
    long ok = json_num(out, "succeeded"), failed = json_num(out, "failed");
    CHECKF(t, rc == 1 && ok >= 4 && ok + failed == 40, "exit %d: %s", rc, out);
    long busy = -1;
    const char *b = strstr(out, "\"busy\":");
    if (b)
        busy = strtol(b + 7, NULL, 10);
    CHECKF(t, busy == failed && busy >= 30, "busy %ld of %ld failed: %s", busy, failed, out);
    CHECK(t, strstr(out, "server busy") != NULL); /* the reason, in words */
    CHECK(t, server_stop(&sv) == 0);
    char logtext[1 << 16];
    mts_test_read_file(sv.log, logtext, sizeof logtext);
    CHECKF(t, count_lines(logtext, "outcome=error: busy") == busy, "%s", logtext);
}

/* Silent clients and one that sends a byte at a time, all at once with
 * well-behaved ones: the bad ones are dropped at the handshake timeout, the
 * good ones finish as fast as alone. */
static void test_hostile_handshakes(mts_test *t)
{
    const char *extra[] = {"--handshake-timeout", "1", NULL};
    server sv;
    CHECK(t, server_start(&sv, "hostile", extra));
    int silent[20], drip = mts_test_connect(sv.port);
    for (int i = 0; i < 20; i++)
        silent[i] = mts_test_connect(sv.port);
    CHECK(t, drip >= 0 && silent[19] >= 0);
    const char hello_start[] = {40, 0, 0, 0, 1, 'M', 'T', 'S', 'H'};
    for (int i = 0; i < 3; i++) { /* a byte every 0.2 s */
        CHECK(t, send(drip, hello_start + i, 1, MSG_NOSIGNAL) == 1);
        struct timespec ts = {0, 200 * 1000 * 1000};
        nanosleep(&ts, NULL);
    }
    char out[4096];
    /* --no-apply: what is timed is the server, not 30 clients deriving
     * records in this one process */
    int rc = stress(&sv, "cow --clients 30 --no-apply --json", out, sizeof out);
    CHECKF(t, rc == 0 && json_num(out, "succeeded") == 30, "exit %d: %s", rc, out);
    /* the good clients were not held up behind the silent ones */
    CHECKF(t, json_num(out, "p99_ms_final") < 900, "%s", out);
    /* every bad one gets ERROR timeout and a close within about a second */
    int closed = 0;
    for (int i = 0; i <= 20; i++) {
        int fd = i < 20 ? silent[i] : drip;
        struct timeval tv = {3, 0};
        setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
        char buf[512];
        ssize_t n, total = 0;
        while ((n = recv(fd, buf, sizeof buf, 0)) > 0)
            total += n;
        if (n == 0 && total > 5 && buf[4] == 31) /* an ERROR frame, then EOF */
            closed++;
        close(fd);
    }
    CHECKF(t, closed == 21, "%d of 21 dropped with an ERROR", closed);
    CHECK(t, server_stop(&sv) == 0);
    char logtext[1 << 16];
    mts_test_read_file(sv.log, logtext, sizeof logtext);
    CHECKF(t, count_lines(logtext, "handshake timeout") == 21, "%s", logtext);
}

/* Clients that reset or vanish mid-stream; then everyone else is still
 * served and the server stops cleanly with nothing leaked. */
static void test_resets_mid_stream(mts_test *t)
{
    /* cow's stream (19 KB) takes 0.4 s at this rate: every broken client
     * is still mid-stream when it goes */
    const char *extra[] = {"--rate-limit", "50000", NULL};
    server sv;
    CHECK(t, server_start(&sv, "resets", extra));
    mts_buf hello = {0};
    put_hello(&hello, "cow");
    const uint8_t *hp = hello.data;
    size_t hn = hello.size;
    for (int i = 0; i < 40; i++) {
        int fd = mts_test_connect(sv.port);
        CHECK(t, fd >= 0 && send(fd, hp, hn, MSG_NOSIGNAL) == (ssize_t)hn);
        char buf[2048];
        CHECK(t, recv(fd, buf, sizeof buf, MSG_WAITALL) > 0);
        if (i % 2 == 0) { /* reset: linger 0 makes close send RST */
            struct linger lg = {1, 0};
            setsockopt(fd, SOL_SOCKET, SO_LINGER, &lg, sizeof lg);
        }
        close(fd);
    }
    mts_buf_free(&hello);
    char out[4096];
    int rc = stress(&sv, "cow --clients 20 --no-apply --json", out, sizeof out);
    CHECKF(t, rc == 0 && json_num(out, "succeeded") == 20, "exit %d: %s", rc, out);
    CHECK(t, server_stop(&sv) == 0);
    char logtext[1 << 16];
    mts_test_read_file(sv.log, logtext, sizeof logtext);
    int gone = count_lines(logtext, "outcome=error: reset by peer") +
               count_lines(logtext, "outcome=error: peer went away");
    CHECKF(t, gone == 40, "%d of 40 broken clients logged as such", gone);
    CHECKF(t, !strstr(logtext, "Sanitizer"), "%s", logtext);
    CHECK(t, strstr(logtext, "mts-server: stopped:") != NULL);
}

/* A height field of n x n vertices as an OFF file: a stream bigger than the
 * kernel's socket buffers (cow's fits in them), so a reader can stall it. */
static int write_grid(const char *path, int n)
{
    FILE *f = fopen(path, "w");
    if (!f)
        return 0;
    fprintf(f, "OFF\n%d %d 0\n", n * n, 2 * (n - 1) * (n - 1));
    for (int y = 0; y < n; y++)
        for (int x = 0; x < n; x++)
            fprintf(f, "%d %d %.4f\n", x, y, 3.0 * sin(x * 0.21) * cos(y * 0.17));
    for (int y = 0; y + 1 < n; y++)
        for (int x = 0; x + 1 < n; x++) {
            int a = y * n + x;
            fprintf(f, "3 %d %d %d\n3 %d %d %d\n", a, a + 1, a + n + 1, a, a + n + 1, a + n);
        }
    return fclose(f) == 0;
}

/* A client that asks for a stream and never reads: the server keeps serving
 * everyone else at full speed and drops it at the idle timeout. */
static void test_slow_reader(mts_test *t)
{
    char grid[700], cmd[4096], out[8192];
    snprintf(grid, sizeof grid, "%s/grid.off", models_dir);
    CHECK(t, write_grid(grid, 190));
    snprintf(cmd, sizeof cmd, "%s/mts-build %s -o %s/grid.mtsm --quiet && rm %s", bin_dir, grid,
             models_dir, grid);
    CHECKF(t, mts_test_run(cmd, out, sizeof out) == 0, "%s", out);
    /* a small fixed send buffer: with the kernel's autotuning (up to 4 MiB)
     * the whole stream would fit in it and nothing could stall */
    const char *extra[] = {"--idle-timeout", "1", "--sndbuf", "16384", NULL};
    server sv;
    CHECK(t, server_start(&sv, "slow", extra));
    int fd = socket(AF_INET, SOCK_STREAM, 0), small = 4096;
    setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
    struct sockaddr_in a = {0};
    a.sin_family = AF_INET;
    a.sin_port = htons((uint16_t)sv.port);
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    CHECK(t, connect(fd, (struct sockaddr *)&a, sizeof a) == 0);
    mts_buf hello = {0};
    put_hello(&hello, "grid");
    CHECK(t, send(fd, hello.data, hello.size, MSG_NOSIGNAL) == (ssize_t)hello.size);
    mts_buf_free(&hello);
    int rc = stress(&sv, "grid --clients 20 --no-apply --json", out, sizeof out);
    CHECKF(t, rc == 0 && json_num(out, "succeeded") == 20, "exit %d: %s", rc, out);
    /* each stream is many times the stalled reader's 20 KB of socket buffers */
    CHECKF(t, json_num(out, "bytes") > 20 * 100000L, "the grid stream is too small: %s", out);
    struct timespec ts = {2, 0};
    nanosleep(&ts, NULL);
    CHECK(t, server_stop(&sv) == 0);
    close(fd);
    char logtext[1 << 16];
    mts_test_read_file(sv.log, logtext, sizeof logtext);
    CHECKF(t, count_lines(logtext, "model=grid") == 21 &&
                  count_lines(logtext, "outcome=error: idle timeout") == 1,
           "%s", logtext);
    snprintf(cmd, sizeof cmd, "rm -f %s/grid.mtsm", models_dir);
    mts_test_run(cmd, out, sizeof out);
}

static void test_workers_rate_stats(mts_test *t)
{
    const char *extra[] = {"--workers", "2", "--stats-interval", "0.2", NULL};
    server sv;
    CHECK(t, server_start(&sv, "workers", extra));
    char out[4096];
    int rc = stress(&sv, "cow --clients 200 --no-apply --json", out, sizeof out);
    CHECKF(t, rc == 0 && json_num(out, "succeeded") == 200, "exit %d: %s", rc, out);
    struct timespec ts = {0, 300 * 1000 * 1000};
    nanosleep(&ts, NULL);
    CHECK(t, server_stop(&sv) == 0);
    char logtext[1 << 17];
    mts_test_read_file(sv.log, logtext, sizeof logtext);
    CHECK(t, strstr(logtext, "2 workers") != NULL);
    CHECKF(t, count_lines(logtext, "stats: connections=") >= 2, "no stats lines");
    CHECK(t, strstr(logtext, "200 completed") != NULL);

    /* --rate-limit: a stream of B bytes takes about (B - 4 KiB) / rate, as
     * on a link (4 KiB: the first write) */
    const char *paced[] = {"--rate-limit", "100000", NULL};
    CHECK(t, server_start(&sv, "paced", paced));
    rc = stress(&sv, "cow --clients 3 --json", out, sizeof out);
    long bytes = json_num(out, "bytes") / 3, ms = json_num(out, "p50_ms_final");
    long want = (bytes - 4096) * 1000 / 100000;
    CHECKF(t, rc == 0 && ms >= want * 9 / 10 && ms < want * 3 + 500,
           "%ld bytes in %ld ms, about %ld expected: %s", bytes, ms, want, out);
    CHECK(t, server_stop(&sv) == 0);
}

/* --quiet drops the per-connection lines and nothing an operator watches:
 * the listening, stats and stopped lines stay. */
static void test_quiet_keeps_stats(mts_test *t)
{
    const char *extra[] = {"--quiet", "--stats-interval", "0.2", NULL};
    server sv;
    CHECK(t, server_start(&sv, "quiet", extra));
    char out[4096];
    int rc = stress(&sv, "cow --clients 5 --no-apply --json", out, sizeof out);
    CHECKF(t, rc == 0 && json_num(out, "succeeded") == 5, "exit %d: %s", rc, out);
    struct timespec ts = {0, 500 * 1000 * 1000};
    nanosleep(&ts, NULL);
    CHECK(t, server_stop(&sv) == 0);
    char logtext[1 << 16];
    mts_test_read_file(sv.log, logtext, sizeof logtext);
    CHECKF(t, strstr(logtext, "mts-server: listening on") && strstr(logtext, "stats: connections=") &&
                  strstr(logtext, "mts-server: stopped: ") && strstr(logtext, ", 5 completed"),
           "%s", logtext);
    CHECKF(t, !strstr(logtext, "peer=") && !strstr(logtext, "added:"), "%s", logtext);
}

/* Previews that ask for more: half the clients stop at a tenth,
 * the other half continue to a half from the batches they hold, in both
 * forms; every client completes with its END checked, and the batches are
 * exactly those of the two stops (none sent twice). */
static void test_continuing_clients(mts_test *t)
{
    server sv;
    CHECK(t, server_start(&sv, "continue", NULL));
    char out[4096], ref_lo[4096], ref_hi[4096];
    CHECK(t, stress(&sv, "cow --clients 1 --fraction 0.1 --json", ref_lo, sizeof ref_lo) == 0);
    CHECK(t, stress(&sv, "cow --clients 1 --fraction 0.5 --json", ref_hi, sizeof ref_hi) == 0);
    long lo = json_num(ref_lo, "batches"), hi = json_num(ref_hi, "batches");
    for (int records = 0; records < 2; records++) {
        int rc = stress(&sv,
                        records ? "cow --clients 8 --fraction 0.1 --continue-fraction 0.5 "
                                  "--continue-share 0.5 --records --json"
                                : "cow --clients 8 --fraction 0.1 --continue-fraction 0.5 "
                                  "--continue-share 0.5 --json",
                        out, sizeof out);
        CHECKF(t, rc == 0 && json_num(out, "succeeded") == 8 && json_num(out, "failed") == 0 &&
                      json_num(out, "continuations") == 4,
               "records %d: exit %d: %s", records, rc, out);
        if (!records)
            CHECKF(t, json_num(out, "batches") == 4 * lo + 4 * hi,
                   "%ld batches, want 4 x %ld + 4 x %ld", json_num(out, "batches"), lo, hi);
    }
    CHECK(t, stress(&sv, "cow --clients 2 --no-apply --continue-fraction 0.5 --json", out,
                    sizeof out) == 2);
    CHECK(t, server_stop(&sv) == 0);
}

/* A stop (SIGTERM) while the models still load ends mts-server with status
 * 1 and a line saying so, not killed by the signal (exit 143). A
 * grid mesh of 180,000 triangles takes seconds to build; the stop comes
 * half a second in. */
static void test_stop_while_loading(mts_test *t)
{
    char dir[700], path[760], bin[600], listen[64], log[760];
    snprintf(dir, sizeof dir, "%s/stress_loading", tmp_dir);
    snprintf(path, sizeof path, "%s/grid.off", dir);
    snprintf(log, sizeof log, "%s/stress_loading.log", tmp_dir);
    mkdir(dir, 0755);
    FILE *f = fopen(path, "w");
    CHECK(t, f != NULL);
    if (!f)
        return;
    const int n = 300; /* n x n vertices, 2 (n - 1)^2 triangles */
    fprintf(f, "OFF\n%d %d 0\n", n * n, 2 * (n - 1) * (n - 1));
    for (int y = 0; y < n; y++)
        for (int x = 0; x < n; x++)
            fprintf(f, "%d %d %g\n", x, y, 0.001 * ((x * 7 + y * 13) % 17));
    for (int y = 0; y + 1 < n; y++)
        for (int x = 0; x + 1 < n; x++) {
            int v = y * n + x;
            fprintf(f, "3 %d %d %d\n3 %d %d %d\n", v, v + 1, v + n + 1, v, v + n + 1, v + n);
        }
    fclose(f);
    snprintf(bin, sizeof bin, "%s/mts-server", bin_dir);
    snprintf(listen, sizeof listen, "127.0.0.1:%d", mts_test_free_port());
    char *argv[] = {bin, "--models", dir, "--listen", listen, NULL};
    pid_t pid = mts_test_spawn(argv, log);
    struct timespec ts = {0, 500 * 1000 * 1000};
    nanosleep(&ts, NULL);
    kill(pid, SIGTERM);
    int st = 0;
    waitpid(pid, &st, 0);
    char logtext[1 << 14];
    mts_test_read_file(log, logtext, sizeof logtext);
    CHECKF(t, WIFEXITED(st) && WEXITSTATUS(st) == 1,
           "exit %d, signal %d: %s", WIFEXITED(st) ? WEXITSTATUS(st) : -1,
           WIFSIGNALED(st) ? WTERMSIG(st) : 0, logtext);
    CHECKF(t, strstr(logtext, "stopped while loading models") && !strstr(logtext, "listening"),
           "%s", logtext);
}

/* --fetch-timeout bounds a URL model's download: a server that accepts and
 * never answers costs a second, named, not the default minute. */
static void test_fetch_timeout_option(mts_test *t)
{
    int port, lfd = mts_test_listen_any(&port);
    CHECK(t, lfd >= 0);
    if (lfd < 0)
        return;
    pid_t mute = fork();
    if (mute == 0) { /* accepts, reads, never answers */
        alarm(30);
        for (;;) {
            int fd = accept(lfd, NULL, NULL);
            (void)fd;
        }
    }
    close(lfd);
    char cmd[1024], out[8192];
    snprintf(cmd, sizeof cmd,
             "%s/mts-server --model slow=http://127.0.0.1:%d/slow.off --fetch-timeout 1 "
             "--listen 127.0.0.1:%d",
             bin_dir, port, mts_test_free_port());
    const double t0 = mts_clock_seconds();
    int rc = mts_test_run(cmd, out, sizeof out);
    const double took = mts_clock_seconds() - t0;
    kill(mute, SIGKILL);
    waitpid(mute, NULL, 0);
    CHECKF(t, rc == 1 && strstr(out, "total timeout 1000 ms") && took < 10,
           "exit %d after %.1f s: %s", rc, took, out);
    snprintf(cmd, sizeof cmd, "%s/mts-server --models . --fetch-connect-timeout -1", bin_dir);
    CHECK(t, mts_test_run(cmd, out, sizeof out) == 2 && strstr(out, "--fetch-connect-timeout"));
}

static void test_usage(mts_test *t)
{
    char cmd[1024], out[8192];
    snprintf(cmd, sizeof cmd, "%s/mts-stress --help", bin_dir);
    CHECK(t, mts_test_run(cmd, out, sizeof out) == 0 && strstr(out, "--concurrency"));
    snprintf(cmd, sizeof cmd, "%s/mts-stress cow --clients 0", bin_dir);
    CHECK(t, mts_test_run(cmd, out, sizeof out) == 2);
    snprintf(cmd, sizeof cmd, "%s/mts-stress cow --level 3 --fraction 0.5", bin_dir);
    CHECK(t, mts_test_run(cmd, out, sizeof out) == 2);
    /* nobody listening: every client fails to connect, named as such */
    snprintf(cmd, sizeof cmd, "%s/mts-stress 127.0.0.1:%d cow --clients 5 --json", bin_dir,
             mts_test_free_port());
    CHECKF(t, mts_test_run(cmd, out, sizeof out) == 1 && strstr(out, "\"connect\":5"), "%s", out);
}

int main(int argc, char **argv)
{
    (void)argc;
    mts_test_bin_dir(argv[0], bin_dir, sizeof bin_dir);
    snprintf(tmp_dir, sizeof tmp_dir, "%s", mts_test_tmpdir());
    snprintf(models_dir, sizeof models_dir, "%s/stress_models", tmp_dir);
    signal(SIGPIPE, SIG_IGN);
    mts_test t = {0};
    char cmd[2048], out[8192];
    snprintf(cmd, sizeof cmd, "mkdir -p %s && %s/mts-build tests/data/cow.off -o %s/cow.mtsm --quiet",
             models_dir, bin_dir, models_dir);
    if (mts_test_run(cmd, out, sizeof out) != 0) {
        fprintf(stderr, "cannot build cow: %s\n", out);
        return 1;
    }
    RUN(&t, test_usage);
    RUN(&t, test_many_clients_apply);
    RUN(&t, test_threads_and_appliers);
    RUN(&t, test_no_apply_verify);
    RUN(&t, test_busy);
    RUN(&t, test_hostile_handshakes);
    RUN(&t, test_resets_mid_stream);
    RUN(&t, test_slow_reader);
    RUN(&t, test_workers_rate_stats);
    RUN(&t, test_quiet_keeps_stats);
    RUN(&t, test_continuing_clients);
    RUN(&t, test_stop_while_loading);
    RUN(&t, test_fetch_timeout_option);
    return mts_test_end(&t);
}
