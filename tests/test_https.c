/* Stream files from a real web server: nginx running docker/nginx-tls.conf
 * (only its marked lines replaced) with a throwaway CA made here by openssl,
 * mts-server beside it on the same models. mts-client reads the files over
 * http and https and must end where mts-server's TCP stream ends, with the
 * same checksum, at the full level, at stops inside batches and at their
 * ends, for triangle budgets and fractions; resume by range after nginx is
 * stopped mid-transfer and started again; and refuse, by name, a
 * certificate that does not verify, damaged and cut files, a file over the
 * cap, and a server that answers ranges wrongly or redirects in a loop or
 * to another scheme -- while a server that ignores ranges (a 200 with the
 * whole file) is used, bounded. */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "test.h"
#include "test_proc.h"

typedef struct env {
    char bin[400], dir[600], www[700], models[700];
    mts_test_tls_front front;
    mts_test_server sv;
    int have_bunny;
    int up;
} env;

static env E;

static void sleep_ms(int ms)
{
    struct timespec ts = {ms / 1000, (long)(ms % 1000) * 1000000L};
    nanosleep(&ts, NULL);
}

/* The CA, the server's certificate for 127.0.0.1, the models and their
 * stream files, mts-server and nginx; E.up once all are there (else a SKIP
 * or a failure says what is missing). */
static void setup(mts_test *t)
{
    const char *missing = mts_test_tls_front_missing(E.front.nginx, sizeof E.front.nginx);
    if (missing) {
        if (getenv("MTS_TEST_REQUIRE_NGINX"))
            CHECKF(t, 0, "%s (scripts/deps.sh installs it)", missing);
        else
            SKIP(t, "%s (scripts/deps.sh installs it)", missing);
        return;
    }
    char out[256];
    snprintf(E.dir, sizeof E.dir, "%s/https.%d", mts_test_tmpdir(), (int)getpid());
    snprintf(E.www, sizeof E.www, "%s/www", E.dir);
    snprintf(E.models, sizeof E.models, "%s/models", E.dir);
    mkdir(E.dir, 0755);
    mkdir(E.www, 0755);
    mkdir(E.models, 0755);
    /* a CA of its own and a certificate for 127.0.0.1 it signed: what a
     * private deployment has, and nothing the system trusts */
    snprintf(E.front.dir, sizeof E.front.dir, "%s", E.dir);
    snprintf(E.front.root, sizeof E.front.root, "%s", E.www);
    char said[4096];
    CHECKF(t, mts_test_tls_front_ca(&E.front, said, sizeof said), "openssl: %s", said);
    char cmd[4096];
    snprintf(cmd, sizeof cmd,
             "%s/mts-build tests/data/cow.off -o %s/cow.mtsm --stream %s/cow.mts -q", E.bin,
             E.models, E.www);
    CHECK(t, mts_test_sh(cmd));
    char bunny[1024];
    if (mts_test_model("bunny00.off", bunny, sizeof bunny)) {
        snprintf(cmd, sizeof cmd, "%s/mts-build %s -o %s/bunny00.mtsm --stream %s/bunny00.mts -q",
                 E.bin, bunny, E.models, E.www);
        E.have_bunny = mts_test_sh(cmd);
        CHECK(t, E.have_bunny);
    }
    if (t->case_failed)
        return;
    char log[800];
    snprintf(log, sizeof log, "%s/server.log", E.dir);
    CHECKF(t, mts_test_ws_server_start(&E.sv, E.bin, E.models, NULL, log, 20),
           "mts-server did not start (%s)", log);
    CHECK(t, mts_test_wait_models(E.bin, "", "cow", 1, out, sizeof out) || 1);
    E.front.ws_upstream = E.sv.ws_port;
    E.front.tcp_upstream = E.sv.port;
    E.front.limit_rate = "set $r 0; if ($arg_rate) { set $r $arg_rate; } limit_rate $r;";
    CHECKF(t, mts_test_tls_front_start(&E.front) > 0, "nginx did not start (%s/nginx.log)", E.dir);
    E.up = !t->case_failed;
}

static void test_setup(mts_test *t)
{
    setup(t);
}

typedef struct run {
    int status;
    long level, triangles, bytes, batches, reconnects;
    char checksum[32];
    char out[8192]; /* the JSON line: its "error" has commas, so it is searched whole */
} run;

static run client(const char *source, const char *args)
{
    char cmd[3000], out[8192];
    run r;
    memset(&r, 0, sizeof r);
    snprintf(cmd, sizeof cmd,
             "%s/mts-client %s --no-render --json --timeout 10 --max-time 60 %s 2>/dev/null",
             E.bin, source, args);
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    r.status = mts_test_run(cmd, out, sizeof out);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    double s = (double)(t1.tv_sec - t0.tv_sec) + (t1.tv_nsec - t0.tv_nsec) / 1e9;
    if (s > 5)
        fprintf(stderr, "  (%s %s took %.1f s)\n", source, args, s);
    snprintf(r.out, sizeof r.out, "%s", out);
    r.level = mts_test_json_long(out, "level");
    r.triangles = mts_test_json_long(out, "triangles");
    r.bytes = mts_test_json_long(out, "bytes");
    r.batches = mts_test_json_long(out, "batches");
    r.reconnects = mts_test_json_long(out, "reconnects");
    mts_test_json(out, "checksum", r.checksum, sizeof r.checksum);
    return r;
}

static void test_stops_match_tcp(mts_test *t)
{
    const char *models[] = {"cow", "bunny00"};
    const char *stops[] = {"",          "--level 0",       "--level 123", "--level 2000",
                           "--level 64", "--triangles 900", "--fraction 0.37"};
    for (int m = 0; m < 2 && !t->case_failed; m++) {
        if (m == 1 && !E.have_bunny) {
            SKIP(t, "bunny00.off not found (../shared/models)");
            return;
        }
        char tcp[100], http[800], https[1600];
        snprintf(tcp, sizeof tcp, "127.0.0.1:%d %s", E.sv.port, models[m]);
        snprintf(http, sizeof http, "http://127.0.0.1:%d/%s.mts", E.front.http_port, models[m]);
        snprintf(https, sizeof https, "https://127.0.0.1:%d/%s.mts --cacert %s/ca.pem",
                 E.front.https_port, models[m], E.dir);
        for (size_t i = 0; i < sizeof stops / sizeof stops[0] && !t->case_failed; i++) {
            run a = client(tcp, stops[i]), b = client(http, stops[i]), c = client(https, stops[i]);
            CHECKF(t, a.status == 0 && b.status == 0 && c.status == 0,
                   "%s %s: exit %d/%d/%d (%s | %s)", models[m], stops[i], a.status, b.status,
                   c.status, b.out, c.out);
            CHECKF(t, a.checksum[0] && !strcmp(a.checksum, b.checksum) &&
                          !strcmp(a.checksum, c.checksum) && a.level == b.level &&
                          a.level == c.level && a.triangles == b.triangles,
                   "%s %s: TCP level %ld %s, http %ld %s, https %ld %s", models[m], stops[i],
                   a.level, a.checksum, b.level, b.checksum, c.level, c.checksum);
            /* the file's header, table and checks, less END: a few per cent
             * of a small stream, under one of bunny00's; a stop whose bytes
             * end inside the first request reads that request's 4 KB */
            /* HTTP/2 where the server offers it: nginx does over TLS (ALPN) */
            CHECKF(t, mts_test_json_long(b.out, "http_version") == 1 &&
                          mts_test_json_long(c.out, "http_version") == 2,
                   "%s %s: HTTP versions %ld (http) and %ld (https)", models[m], stops[i],
                   mts_test_json_long(b.out, "http_version"),
                   mts_test_json_long(c.out, "http_version"));
            CHECKF(t, b.bytes == c.bytes && b.bytes > a.bytes &&
                          (b.bytes - a.bytes < 1400 || (b.bytes == 4096 && a.bytes < 4096)),
                   "%s %s: TCP %ld bytes, http %ld, https %ld", models[m], stops[i], a.bytes,
                   b.bytes, c.bytes);
        }
    }
}

/* The TCP stream inside TLS, nginx's stream module terminating it in front
 * of mts-server: the same stream, so the same levels and checksums. */
static void test_tcp_through_tls(mts_test *t)
{
    const char *models[] = {"cow", "cow", "cow", "bunny00"};
    const char *stops[] = {"", "--level 64", "--triangles 900", ""};
    for (size_t i = 0; i < sizeof stops / sizeof stops[0] && !t->case_failed; i++) {
        if (i == 3 && !E.have_bunny)
            break;
        char tcp[100], tls[1000];
        snprintf(tcp, sizeof tcp, "127.0.0.1:%d %s", E.sv.port, models[i]);
        snprintf(tls, sizeof tls, "127.0.0.1:%d %s --tls --cacert %s/ca.pem", E.front.tls_port,
                 models[i], E.dir);
        run a = client(tcp, stops[i]), b = client(tls, stops[i]);
        CHECKF(t, a.status == 0 && b.status == 0 && a.checksum[0] &&
                      !strcmp(a.checksum, b.checksum) && a.level == b.level &&
                      a.bytes == b.bytes,
               "%s: TCP exit %d level %ld %s %ld bytes; TLS exit %d level %ld %s %ld bytes (%s)",
               stops[i], a.status, a.level, a.checksum, a.bytes, b.status, b.level, b.checksum,
               b.bytes, b.out);
    }
    char cmd[2000], out[4096];
    snprintf(cmd, sizeof cmd, "%s/mts-client 127.0.0.1:%d --list --tls --cacert %s/ca.pem", E.bin,
             E.front.tls_port, E.dir);
    CHECKF(t, mts_test_run(cmd, out, sizeof out) == 0 && strstr(out, "cow"), "--list: %s", out);
    /* not verified without the CA; a port that does not speak TLS */
    char tls[1000];
    snprintf(tls, sizeof tls, "127.0.0.1:%d cow --tls --resume", E.front.tls_port);
    run r = client(tls, "");
    CHECKF(t, r.status == 1 && strstr(r.out, "certificate") && r.reconnects == 0,
           "no CA: exit %d: %s", r.status, r.out);
    snprintf(tls, sizeof tls, "127.0.0.1:%d cow --tls --cacert %s/ca.pem", E.sv.port, E.dir);
    r = client(tls, "");
    CHECKF(t, r.status == 1 && strstr(r.out, "TLS"), "plain port: exit %d: %s", r.status, r.out);
}

/* What docker/nginx-tls.conf sends with a stream file: ranges, an ETag,
 * CORS (and the preflight a Range request needs), the cache lifetime by
 * name, and no guessed type. */
static void test_headers(mts_test *t)
{
    char cmd[4000], out[8192], path[800];
    snprintf(cmd, sizeof cmd, "cp %s/cow.mts %s/cow-0123456789abcdef.mts", E.www, E.www);
    CHECK(t, mts_test_sh(cmd));
    struct {
        const char *name, *method, *range;
        const char *want[6];
    } cases[] = {
        {"cow.mts", "HEAD", "",
         {"HTTP/2 200", "accept-ranges: bytes", "etag: \"", "cache-control: public, max-age=3600",
          "access-control-allow-origin: *", "content-type: application/octet-stream"}},
        {"cow-0123456789abcdef.mts", "GET", "-r 0-99",
         {"HTTP/2 206", "cache-control: public, max-age=31536000, immutable",
          "access-control-expose-headers: content-range", NULL}},
        {"cow.mts", "OPTIONS", "",
         {"HTTP/2 204", "access-control-allow-headers: range", "access-control-allow-origin: *",
          NULL}},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        snprintf(path, sizeof path, "%s/headers.txt", E.dir);
        snprintf(cmd, sizeof cmd,
                 "curl -s --cacert %s/ca.pem %s %s -H 'Origin: https://elsewhere.example' "
                 "-H 'Access-Control-Request-Headers: range' -o /dev/null -D - "
                 "https://127.0.0.1:%d/%s | tr 'A-Z' 'a-z' | sed 's/^http/HTTP/'",
                 E.dir, cases[i].range,
                 !strcmp(cases[i].method, "HEAD") ? "-I" : !strcmp(cases[i].method, "OPTIONS")
                                                            ? "-X OPTIONS"
                                                            : "",
                 E.front.https_port, cases[i].name);
        CHECK(t, mts_test_run(cmd, out, sizeof out) == 0);
        for (int k = 0; k < 6 && cases[i].want[k]; k++) {
            char want[200];
            snprintf(want, sizeof want, "%s", cases[i].want[k]);
            if (strncmp(want, "HTTP", 4) != 0)
                for (char *p = want; *p; p++)
                    *p = (char)(*p >= 'A' && *p <= 'Z' ? *p - 'A' + 'a' : *p);
            CHECKF(t, strstr(out, want) != NULL, "%s %s: no '%s' in:\n%s", cases[i].method,
                   cases[i].name, want, out);
        }
    }
}

static void test_certificate_verified(mts_test *t)
{
    char url[200];
    snprintf(url, sizeof url, "https://127.0.0.1:%d/cow.mts", E.front.https_port);
    run r = client(url, "");
    CHECKF(t, r.status == 1 && strstr(r.out, "certificate"), "exit %d: %s", r.status, r.out);
    char args[900];
    snprintf(args, sizeof args, "--cacert %s/missing.pem", E.dir);
    r = client(url, args);
    CHECKF(t, r.status == 1 || r.status == 2, "a missing CA file: exit %d", r.status);
}

/* nginx stopped in the middle of a slowed transfer and started again: the
 * client resumes with a range from the first batch it does not hold. The
 * rates make each transfer last about 5 s: nginx's limit_rate counts whole
 * seconds from a request's start, so a transfer may run up to a second
 * ahead, and the cut at 1.2 s must still fall in the middle. */
static void test_resume_after_restart(mts_test *t)
{
    const char *model = E.have_bunny ? "bunny00" : "cow";
    char cmd[2000], out[8192], tcp[100];
    snprintf(tcp, sizeof tcp, "127.0.0.1:%d %s", E.sv.port, model);
    run ref = client(tcp, "");
    snprintf(cmd, sizeof cmd,
             "%s/mts-client 'http://127.0.0.1:%d/%s.mts?rate=%s' --no-render --json --resume "
             "--retries 40 --timeout 5 > %s/resume.json 2>%s/resume.log",
             E.bin, E.front.http_port, model, E.have_bunny ? "30k" : "3k", E.dir, E.dir);
    pid_t pid = fork();
    if (pid == 0) {
        execl("/bin/sh", "sh", "-c", cmd, (char *)NULL);
        _exit(127);
    }
    sleep_ms(1200);
    mts_test_tls_front_stop(&E.front, 1); /* as a crash: every connection cut at once */
    sleep_ms(600);
    CHECKF(t, mts_test_tls_front_start(&E.front) > 0, "nginx did not start again");
    int st = 0;
    waitpid(pid, &st, 0);
    char path[800];
    snprintf(path, sizeof path, "%s/resume.json", E.dir);
    mts_test_read_file(path, out, sizeof out);
    char sum[32];
    mts_test_json(out, "checksum", sum, sizeof sum);
    CHECKF(t, WIFEXITED(st) && WEXITSTATUS(st) == 0 && !strcmp(sum, ref.checksum) &&
                  mts_test_json_long(out, "reconnects") >= 1,
           "after the restart: %s (TCP checksum %s)", out, ref.checksum);
}

/* The file rebuilt under the same name while a client was cut off: its
 * resume asks with If-Range and must refuse the new bytes by name rather
 * than mix two files. */
static void test_file_changed_between_ranges(mts_test *t)
{
    char src[800], dst[800], cmd[4000], out[8192];
    snprintf(src, sizeof src, "%s/cow.mts", E.www);
    snprintf(dst, sizeof dst, "%s/changing.mts", E.www);
    snprintf(cmd, sizeof cmd, "cp %s %s", src, dst);
    CHECK(t, mts_test_sh(cmd));
    snprintf(cmd, sizeof cmd,
             "%s/mts-client 'http://127.0.0.1:%d/changing.mts?rate=3k' --no-render --json "
             "--resume --retries 40 --timeout 5 > %s/changed.json 2>%s/changed.log",
             E.bin, E.front.http_port, E.dir, E.dir);
    pid_t pid = fork();
    if (pid == 0) {
        execl("/bin/sh", "sh", "-c", cmd, (char *)NULL);
        _exit(127);
    }
    sleep_ms(1500);
    mts_test_tls_front_stop(&E.front, 1);
    /* another build of the model: other bytes late in the file and a new
     * modification time, so nginx gives it a new ETag */
    snprintf(cmd, sizeof cmd,
             "printf 'XXXX' | dd of=%s bs=1 seek=$(($(stat -c %%s %s) - 100)) conv=notrunc "
             "2>/dev/null && touch -d '+1 minute' %s",
             dst, dst, dst);
    CHECK(t, mts_test_sh(cmd));
    CHECKF(t, mts_test_tls_front_start(&E.front) > 0, "nginx did not start again");
    int st = 0;
    waitpid(pid, &st, 0);
    char path[800];
    snprintf(path, sizeof path, "%s/changed.json", E.dir);
    mts_test_read_file(path, out, sizeof out);
    CHECKF(t, WIFEXITED(st) && WEXITSTATUS(st) == 1 && strstr(out, "changed on the server"),
           "exit %d: %s", WIFEXITED(st) ? WEXITSTATUS(st) : -1, out);
}

static int write_file(const char *path, const uint8_t *data, size_t size)
{
    FILE *f = fopen(path, "wb");
    int ok = f && fwrite(data, 1, size, f) == size;
    if (f)
        ok = fclose(f) == 0 && ok;
    return ok;
}

/* Damaged copies of cow.mts, served by nginx: each refused by name. */
static void test_damaged_files(mts_test *t)
{
    char path[800];
    snprintf(path, sizeof path, "%s/cow.mts", E.www);
    FILE *f = fopen(path, "rb");
    static uint8_t file[1 << 20];
    size_t size = f ? fread(file, 1, sizeof file, f) : 0;
    if (f)
        fclose(f);
    CHECK(t, size > 4096);
    if (t->case_failed)
        return;
    uint32_t info = (uint32_t)file[8] | (uint32_t)file[9] << 8;
    struct {
        const char *name;
        size_t at; /* byte flipped, or the size cut to (cut) */
        int cut;
        const char *says;
    } cases[] = {
        {"cut", 20, 1, "header"},
        {"cutmid", 0, 1, "the file ends"},
        {"info", 32 + 9, 0, "MODEL_INFO and table"},
        {"table", 32 + info + 3, 0, "MODEL_INFO and table"},
        {"frame", 0, 0, "checksum"},
    };
    cases[1].at = size * 2 / 3;
    cases[4].at = size - 300; /* inside the last batches */
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        static uint8_t copy[1 << 20];
        memcpy(copy, file, size);
        size_t n = cases[i].cut ? cases[i].at : size;
        if (!cases[i].cut)
            copy[cases[i].at] ^= 0x55;
        snprintf(path, sizeof path, "%s/%s.mts", E.www, cases[i].name);
        CHECK(t, write_file(path, copy, n));
        char url[200];
        snprintf(url, sizeof url, "http://127.0.0.1:%d/%s.mts", E.front.http_port, cases[i].name);
        run r = client(url, "");
        CHECKF(t, r.status == 1 && strstr(r.out, cases[i].says), "%s: exit %d: %s",
               cases[i].name, r.status, r.out);
    }
    /* over the cap */
    char url[200];
    snprintf(url, sizeof url, "http://127.0.0.1:%d/cow.mts", E.front.http_port);
    run r = client(url, "--max-file-bytes 4K");
    CHECKF(t, r.status == 1 && strstr(r.out, "size cap"), "cap: exit %d: %s", r.status,
           r.out);
    /* not there */
    snprintf(url, sizeof url, "http://127.0.0.1:%d/nothing.mts", E.front.http_port);
    r = client(url, "--resume");
    CHECKF(t, r.status == 1 && strstr(r.out, "404"), "404: exit %d: %s", r.status, r.out);
}

/* ---- a web server that answers wrongly ------------------------------------ */

/* Serves cow.mts's bytes, answering by path: /whole (a 200 with all of it,
 * whatever the range), /wrongrange (a 206 for other bytes), /unsat (416),
 * /loop (a redirect to itself), /ftp (a redirect to ftp://). */
static void hostile_serve(int lfd, const uint8_t *file, size_t size)
{
    for (;;) {
        int fd = accept(lfd, NULL, NULL);
        if (fd < 0)
            continue;
        char req[4096];
        mts_test_read_request(fd, req, sizeof req);
        unsigned long a = 0, b = 0;
        const char *rg = strstr(req, "Range: bytes=");
        if (rg)
            sscanf(rg + 13, "%lu-%lu", &a, &b);
        if (b >= size)
            b = size - 1;
        char head[512];
        int hn;
        if (strstr(req, "GET /whole")) {
            hn = snprintf(head, sizeof head,
                          "HTTP/1.1 200 OK\r\nContent-Length: %zu\r\nConnection: close\r\n\r\n",
                          size);
            if (write(fd, head, (size_t)hn) == hn) {
                for (size_t at = 0; at < size;) {
                    ssize_t w = write(fd, file + at, size - at);
                    if (w <= 0)
                        break;
                    at += (size_t)w;
                }
            }
        } else if (strstr(req, "GET /wrongrange")) {
            unsigned long from = a + 7;
            hn = snprintf(head, sizeof head,
                          "HTTP/1.1 206 Partial Content\r\nContent-Range: bytes %lu-%lu/%zu\r\n"
                          "Content-Length: %lu\r\nConnection: close\r\n\r\n",
                          from, b, size, b - from + 1);
            if (write(fd, head, (size_t)hn) == hn)
                (void)!write(fd, file + from, b - from + 1);
        } else if (strstr(req, "GET /unsat")) {
            hn = snprintf(head, sizeof head,
                          "HTTP/1.1 416 Range Not Satisfiable\r\nContent-Range: bytes */%zu\r\n"
                          "Content-Length: 0\r\nConnection: close\r\n\r\n",
                          size);
            (void)!write(fd, head, (size_t)hn);
        } else {
            const char *to = strstr(req, "GET /ftp") ? "ftp://127.0.0.1/cow.mts" : "/loop.mts";
            hn = snprintf(head, sizeof head,
                          "HTTP/1.1 302 Found\r\nLocation: %s\r\nContent-Length: 0\r\n"
                          "Connection: close\r\n\r\n",
                          to);
            (void)!write(fd, head, (size_t)hn);
        }
        close(fd);
    }
}

static void test_hostile_web_server(mts_test *t)
{
    char path[800];
    snprintf(path, sizeof path, "%s/cow.mts", E.www);
    static uint8_t file[1 << 20];
    FILE *f = fopen(path, "rb");
    size_t size = f ? fread(file, 1, sizeof file, f) : 0;
    if (f)
        fclose(f);
    int port;
    int lfd = mts_test_listen_any(&port);
    CHECK(t, size > 0 && lfd >= 0);
    if (t->case_failed)
        return;
    pid_t pid = fork();
    if (pid == 0) {
        prctl(PR_SET_PDEATHSIG, SIGKILL);
        hostile_serve(lfd, file, size);
        _exit(0);
    }
    close(lfd);
    char tcp[100];
    snprintf(tcp, sizeof tcp, "127.0.0.1:%d cow", E.sv.port);
    run ref = client(tcp, "--level 500");
    struct {
        const char *path;
        int ok;
        const char *says;
    } cases[] = {
        {"whole.mts", 1, ""},
        {"wrongrange.mts", 0, "for the range"},
        {"unsat.mts", 0, "416"},
        {"loop.mts", 0, "redirect"},
        {"ftp.mts", 0, "http and https"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char url[200];
        snprintf(url, sizeof url, "http://127.0.0.1:%d/%s", port, cases[i].path);
        run r = client(url, "--level 500");
        if (cases[i].ok)
            CHECKF(t, r.status == 0 && !strcmp(r.checksum, ref.checksum),
                   "%s: exit %d %s (%s), TCP %s", cases[i].path, r.status, r.checksum, r.out,
                   ref.checksum);
        else
            CHECKF(t, r.status == 1 && strstr(r.out, cases[i].says), "%s: exit %d: %s",
                   cases[i].path, r.status, r.out);
    }
    kill(pid, SIGKILL);
    waitpid(pid, NULL, 0);
}

int main(int argc, char **argv)
{
    (void)argc;
    mts_test t = {0};
    mts_test_bin_dir(argv[0], E.bin, sizeof E.bin);
    signal(SIGPIPE, SIG_IGN);
    RUN(&t, test_setup);
    if (E.up) {
        RUN(&t, test_stops_match_tcp);
        RUN(&t, test_headers);
        RUN(&t, test_certificate_verified);
        RUN(&t, test_tcp_through_tls);
        RUN(&t, test_damaged_files);
        RUN(&t, test_hostile_web_server);
        RUN(&t, test_resume_after_restart);
        RUN(&t, test_file_changed_between_ranges);
    }
    mts_test_tls_front_stop(&E.front, 0);
    if (E.sv.pid > 0)
        mts_test_stop(E.sv.pid);
    return mts_test_end(&t);
}
