/* mts-stress against a stream file on a real nginx (docker/nginx-tls.conf
 * with a throwaway CA), beside mts-server on the same model: 200 applying
 * clients over http and over https must all complete, and end at the level
 * and checksum that mts-server's stream ends at for the same stop (the
 * file's checks stand in for END's, so a wrong byte anywhere fails them).
 * Continuing clients read one more range each; a certificate that does not
 * verify and a missing file fail every client by kind, and what makes no
 * sense for a file (--no-apply, --records, a model name) is refused. */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "test.h"
#include "test_proc.h"

typedef struct env {
    char bin[400], dir[600], www[700], models[700];
    mts_test_tls_front front;
    mts_test_server sv;
    int up;
} env;

static env E;

static void test_setup(mts_test *t)
{
    const char *missing = mts_test_tls_front_missing(E.front.nginx, sizeof E.front.nginx);
    if (missing) {
        if (getenv("MTS_TEST_REQUIRE_NGINX"))
            CHECKF(t, 0, "%s (scripts/deps.sh installs it)", missing);
        else
            SKIP(t, "%s (scripts/deps.sh installs it)", missing);
        return;
    }
    char out[4096];
    snprintf(E.dir, sizeof E.dir, "%s/stress_web.%d", mts_test_tmpdir(), (int)getpid());
    snprintf(E.www, sizeof E.www, "%s/www", E.dir);
    snprintf(E.models, sizeof E.models, "%s/models", E.dir);
    mkdir(E.dir, 0755);
    mkdir(E.www, 0755);
    mkdir(E.models, 0755);
    snprintf(E.front.dir, sizeof E.front.dir, "%s", E.dir);
    snprintf(E.front.root, sizeof E.front.root, "%s", E.www);
    CHECKF(t, mts_test_tls_front_ca(&E.front, out, sizeof out), "openssl: %s", out);
    char cmd[4096];
    snprintf(cmd, sizeof cmd,
             "%s/mts-build tests/data/cow.off -o %s/cow.mtsm --stream %s/cow.mts -q", E.bin,
             E.models, E.www);
    CHECK(t, mts_test_sh(cmd));
    if (t->case_failed)
        return;
    char log[800];
    snprintf(log, sizeof log, "%s/server.log", E.dir);
    CHECKF(t, mts_test_ws_server_start(&E.sv, E.bin, E.models, NULL, log, 20),
           "mts-server did not start (%s)", log);
    E.front.ws_upstream = E.sv.ws_port;
    E.front.tcp_upstream = E.sv.port;
    CHECKF(t, mts_test_tls_front_start(&E.front) > 0, "nginx did not start (%s/nginx.log)", E.dir);
    E.up = !t->case_failed;
}

typedef struct run {
    int status;
    long clients, succeeded, failed, level, triangles, elsewhere, continuations, cont_level;
    char checksum[32], cont_checksum[32];
    char out[8192];
} run;

/* mts-stress SOURCE ARGS --json, its figures and all it said. */
static run stress(const char *source, const char *args)
{
    char cmd[3000];
    run r;
    memset(&r, 0, sizeof r);
    snprintf(cmd, sizeof cmd, "%s/mts-stress %s --json --connect-timeout 10 --io-timeout 20 %s",
             E.bin, source, args);
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    r.status = mts_test_run(cmd, r.out, sizeof r.out);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    double s = (double)(t1.tv_sec - t0.tv_sec) + (t1.tv_nsec - t0.tv_nsec) / 1e9;
    if (s > (getenv("MTS_TEST_VERBOSE") ? 0 : 5))
        fprintf(stderr, "  (mts-stress %s %s took %.1f s)\n", source, args, s);
    r.clients = mts_test_json_long(r.out, "clients");
    r.succeeded = mts_test_json_long(r.out, "succeeded");
    r.failed = mts_test_json_long(r.out, "failed");
    r.level = mts_test_json_long(r.out, "level");
    r.triangles = mts_test_json_long(r.out, "triangles");
    r.elsewhere = mts_test_json_long(r.out, "ended_elsewhere");
    r.continuations = mts_test_json_long(r.out, "continuations");
    mts_test_json(r.out, "checksum", r.checksum, sizeof r.checksum);
    r.cont_level = mts_test_json_long(r.out, "continued_level");
    mts_test_json(r.out, "continued_checksum", r.cont_checksum, sizeof r.cont_checksum);
    return r;
}

/* mts-client's own TCP run: the reference level and checksum. */
static void client_tcp(const char *args, long *level, char *checksum, size_t size)
{
    char cmd[2000], out[8192];
    snprintf(cmd, sizeof cmd,
             "%s/mts-client 127.0.0.1:%d cow --no-render --json --timeout 10 %s 2>/dev/null",
             E.bin, E.sv.port, args);
    int st = mts_test_run(cmd, out, sizeof out);
    *level = st == 0 ? mts_test_json_long(out, "level") : -2;
    mts_test_json(out, "checksum", checksum, size);
}

static void test_many_clients_match_tcp(mts_test *t)
{
    const char *stops[] = {"", "--level 500", "--triangles 900"};
    char tcp[100], http[300], https[1200];
    snprintf(tcp, sizeof tcp, "127.0.0.1:%d cow", E.sv.port);
    snprintf(http, sizeof http, "http://127.0.0.1:%d/cow.mts", E.front.http_port);
    snprintf(https, sizeof https, "https://127.0.0.1:%d/cow.mts --cacert %s/ca.pem",
             E.front.https_port, E.dir);
    for (size_t i = 0; i < sizeof stops / sizeof stops[0] && !t->case_failed; i++) {
        char args[200], ref[32];
        long ref_level;
        client_tcp(stops[i], &ref_level, ref, sizeof ref);
        snprintf(args, sizeof args, "--clients 200 --verify %s", stops[i]);
        run a = stress(tcp, args), b = stress(http, args), c = stress(https, args);
        const run *r[3] = {&a, &b, &c};
        const char *name[3] = {"TCP", "http", "https"};
        for (int k = 0; k < 3; k++)
            CHECKF(t, r[k]->status == 0 && r[k]->clients == 200 && r[k]->succeeded == 200 &&
                          r[k]->failed == 0 && r[k]->elsewhere == 0,
                   "%s %s: exit %d: %s", name[k], stops[i], r[k]->status, r[k]->out);
        CHECKF(t, ref[0] && !strcmp(a.checksum, ref) && !strcmp(b.checksum, ref) &&
                      !strcmp(c.checksum, ref) && a.level == ref_level && b.level == ref_level &&
                      c.level == ref_level && a.triangles == b.triangles &&
                      a.triangles == c.triangles,
               "%s: mts-client level %ld %s; mts-stress TCP %ld %s, http %ld %s, https %ld %s",
               stops[i], ref_level, ref, a.level, a.checksum, b.level, b.checksum, c.level,
               c.checksum);
    }
}

/* Previews that ask for more: each continuing client reads one more range
 * (the index is held) and ends where a full stream does. */
static void test_continue(mts_test *t)
{
    char https[1200], ref[32];
    long ref_level;
    client_tcp("", &ref_level, ref, sizeof ref);
    snprintf(https, sizeof https, "https://127.0.0.1:%d/cow.mts --cacert %s/ca.pem",
             E.front.https_port, E.dir);
    run r = stress(https, "--clients 50 --level 100 --continue-fraction 1 --ramp 0.2");
    CHECKF(t, r.status == 0 && r.succeeded == 50 && r.continuations == 50 && r.elsewhere == 0 &&
                  r.cont_level == ref_level && !strcmp(r.cont_checksum, ref),
           "exit %d, full level %ld %s: %s", r.status, ref_level, ref, r.out);
}

/* Every client fails, each counted by kind, and the run says why. */
static void test_failures_by_kind(mts_test *t)
{
    char url[300];
    snprintf(url, sizeof url, "https://127.0.0.1:%d/cow.mts", E.front.https_port);
    run r = stress(url, "--clients 20");
    CHECKF(t, r.status == 1 && r.failed == 20 && mts_test_json_long(r.out, "connect") == 20 &&
                  strstr(r.out, "certificate"),
           "an unverified certificate: exit %d: %s", r.status, r.out);
    snprintf(url, sizeof url, "http://127.0.0.1:%d/none.mts", E.front.http_port);
    r = stress(url, "--clients 20");
    CHECKF(t, r.status == 1 && r.failed == 20 &&
                  mts_test_json_long(r.out, "server_error") == 20 && strstr(r.out, "404"),
           "a missing file: exit %d: %s", r.status, r.out);
    snprintf(url, sizeof url, "http://127.0.0.1:%d/cow.mts", E.front.http_port);
    r = stress(url, "--clients 5 --max-file-bytes 1K");
    CHECKF(t, r.status == 1 && r.failed == 5 && strstr(r.out, "cap"),
           "over the size cap: exit %d: %s", r.status, r.out);
}

/* What makes no sense for a file is refused before any client starts. */
static void test_refusals(mts_test *t)
{
    char url[300], tcp[100];
    snprintf(url, sizeof url, "http://127.0.0.1:%d/cow.mts", E.front.http_port);
    snprintf(tcp, sizeof tcp, "127.0.0.1:%d cow", E.sv.port);
    const struct {
        const char *source, *args, *says;
    } cases[] = {
        {url, "--no-apply", "--no-apply"},
        {url, "--records", "--records"},
        {url, "--http /cow.mts", "--http"},
        {"http://127.0.0.1:1/cow.mts cow", "", "model name"},
        {tcp, "--cacert /dev/null", "URL"},
        {tcp, "--max-file-bytes 1M", "URL"},
        {url, "--cacert /nonexistent/ca.pem", "CA certificates"},
        {"ftp://127.0.0.1/cow.mts", "", "http"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        run r = stress(cases[i].source, cases[i].args);
        CHECKF(t, r.status == 2 && strstr(r.out, cases[i].says) && !strstr(r.out, "succeeded"),
               "%s %s: exit %d: %s", cases[i].source, cases[i].args, r.status, r.out);
    }
}

int main(int argc, char **argv)
{
    (void)argc;
    mts_test t = {0};
    mts_test_bin_dir(argv[0], E.bin, sizeof E.bin);
    signal(SIGPIPE, SIG_IGN);
    RUN(&t, test_setup);
    if (E.up) {
        RUN(&t, test_many_clients_match_tcp);
        RUN(&t, test_continue);
        RUN(&t, test_failures_by_kind);
        RUN(&t, test_refusals);
    }
    mts_test_tls_front_stop(&E.front, 0);
    if (E.sv.pid > 0)
        mts_test_stop(E.sv.pid);
    return mts_test_end(&t);
}
