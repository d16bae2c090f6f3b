/* Processes for end-to-end tests: start a program with its stderr in a log,
 * stop it, find a free loopback port, wait until a server answers, read a
 * log or a --json line back; and a stream client fed a connection's bytes,
 * as the programs' tests and the in-memory stream tests both do. Tests that
 * run the programs find them beside their own binary (build/bin for
 * build/tests, build/asan/bin for build/asan/tests), so the ASan build tests
 * the ASan programs. */
#ifndef MTS_TEST_PROC_H
#define MTS_TEST_PROC_H

#include <arpa/inet.h>
#include <libgen.h>
#include <netinet/in.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "stream.h"
#include "test.h"
#include "wire.h"

/* Runs fn(arg) in a child process limited to `bytes` of address space:
 * 1 when it returned nonzero there, 0 when it returned 0, ran out of
 * memory in a way that killed it, or could not be started. Memory checks
 * only: ASan's shadow needs terabytes of address space, so callers skip
 * them under it (__SANITIZE_ADDRESS__). */
static inline int mts_test_within_memory(int (*fn)(void *), void *arg, size_t bytes)
{
    pid_t pid = fork();
    if (pid == 0) {
        struct rlimit rl = {bytes, bytes};
        _exit(setrlimit(RLIMIT_AS, &rl) == 0 && fn(arg) ? 0 : 1);
    }
    int status = 0;
    if (pid < 0 || waitpid(pid, &status, 0) != pid)
        return 0;
    return WIFEXITED(status) && WEXITSTATUS(status) == 0;
}

/* bin_dir gets "<dir of argv0>/../bin". */
static inline void mts_test_bin_dir(const char *argv0, char *bin_dir, size_t size)
{
    char self[400];
    snprintf(self, sizeof self, "%s", argv0);
    snprintf(bin_dir, size, "%s/../bin", dirname(self));
}

/* Starts argv with stdout to /dev/null and stderr to log; returns its pid. */
static inline pid_t mts_test_spawn(char *const argv[], const char *log)
{
    pid_t pid = fork();
    if (pid == 0) {
        if (!freopen(log, "w", stderr) || !freopen("/dev/null", "w", stdout))
            _exit(126);
        execvp(argv[0], argv);
        _exit(127);
    }
    return pid;
}

/* SIGTERM, then waits; returns the exit status (-1 when killed by a signal). */
static inline int mts_test_stop(pid_t pid)
{
    if (pid <= 0)
        return -1;
    kill(pid, SIGTERM);
    int st = 0;
    waitpid(pid, &st, 0);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

static inline int mts_test_free_port(void)
{
    int fd = socket(AF_INET, SOCK_STREAM, 0), one = 1;
    struct sockaddr_in a = {0};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    int port = -1;
    socklen_t sl = sizeof a;
    if (bind(fd, (struct sockaddr *)&a, sizeof a) == 0 &&
        getsockname(fd, (struct sockaddr *)&a, &sl) == 0)
        port = ntohs(a.sin_port);
    close(fd);
    return port;
}

/* A listening loopback socket on a free port (*port), or -1. */
static inline int mts_test_listen_any(int *port)
{
    *port = -1;
    int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0), one = 1;
    struct sockaddr_in a = {0};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    socklen_t sl = sizeof a;
    if (fd < 0 || bind(fd, (struct sockaddr *)&a, sizeof a) != 0 || listen(fd, 16) != 0 ||
        getsockname(fd, (struct sockaddr *)&a, &sl) != 0) {
        if (fd >= 0)
            close(fd);
        return -1;
    }
    *port = ntohs(a.sin_port);
    return fd;
}

/* A connected loopback socket to port, or -1; with rcvbuf > 0 its receive
 * buffer is that small from the start (set before connecting, so the
 * window it offers is small too): a client that reads slowly or not at
 * all stalls its stream sooner. */
static inline int mts_test_connect_rcvbuf(int port, int rcvbuf)
{
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    if (fd >= 0 && rcvbuf > 0)
        setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf);
    struct sockaddr_in a = {0};
    a.sin_family = AF_INET;
    a.sin_port = htons((uint16_t)port);
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (fd >= 0 && connect(fd, (struct sockaddr *)&a, sizeof a) == 0)
        return fd;
    if (fd >= 0)
        close(fd);
    return -1;
}

static inline int mts_test_connect(int port)
{
    return mts_test_connect_rcvbuf(port, 0);
}

/* Waits up to `seconds` until something accepts connections on port. */
static inline int mts_test_wait_port(int port, double seconds)
{
    for (int i = 0; i < (int)(seconds * 20); i++) {
        int fd = mts_test_connect(port);
        if (fd >= 0) {
            close(fd);
            return 1;
        }
        struct timespec ts = {0, 50 * 1000 * 1000};
        nanosleep(&ts, NULL);
    }
    return 0;
}

/* Lists the models of the mts-server at listen (bin_dir's mts-client
 * --list) every 0.1 s, `tries` times at most, until the listing names
 * `model` (any listing when NULL): 1 when it did. The last output in out. */
static inline int mts_test_wait_models(const char *bin_dir, const char *listen, const char *model,
                                       int tries, char *out, size_t size)
{
    char cmd[1200];
    snprintf(cmd, sizeof cmd, "%s/mts-client %s --list", bin_dir, listen);
    for (int i = 0; i < tries; i++) {
        if (mts_test_run(cmd, out, size) == 0 && (!model || strstr(out, model)))
            return 1;
        struct timespec ts = {0, 100 * 1000 * 1000};
        nanosleep(&ts, NULL);
    }
    return 0;
}

/* An mts-server of bin_dir serving models_dir on two free loopback ports,
 * TCP (port) and WebSocket (ws_port), with the extra arguments (NULL-ended,
 * or NULL), its output into log. 1 once the TCP port listens within
 * `seconds`. Stop it with mts_test_stop(pid). */
typedef struct mts_test_server {
    pid_t pid;
    int port, ws_port;
} mts_test_server;

static inline int mts_test_ws_server_start(mts_test_server *sv, const char *bin_dir,
                                           const char *models_dir, const char *const *extra,
                                           const char *log, double seconds)
{
    char bin[600], listen[64], ws_listen[64];
    snprintf(bin, sizeof bin, "%s/mts-server", bin_dir);
    sv->port = mts_test_free_port();
    sv->ws_port = mts_test_free_port();
    snprintf(listen, sizeof listen, "127.0.0.1:%d", sv->port);
    snprintf(ws_listen, sizeof ws_listen, "127.0.0.1:%d", sv->ws_port);
    char *argv[32] = {bin, "--models", (char *)models_dir, "--listen", listen, "--ws-listen",
                      ws_listen};
    int n = 7;
    for (; extra && *extra && n < 30; extra++)
        argv[n++] = (char *)*extra;
    argv[n] = NULL;
    sv->pid = mts_test_spawn(argv, log);
    return sv->pid > 0 && mts_test_wait_port(sv->port, seconds);
}

/* ---- nginx in front of mts-server (web/nginx.conf) ------------------------ */

/* The nginx to run, or NULL: sbin is often not on a user's PATH. */
static inline const char *mts_test_find_nginx(char *buf, size_t size)
{
    const char *fixed[] = {"/usr/sbin/nginx", "/usr/local/sbin/nginx",
                           "/usr/local/nginx/sbin/nginx"};
    for (size_t i = 0; i < sizeof fixed / sizeof fixed[0]; i++) {
        if (access(fixed[i], X_OK) == 0) {
            snprintf(buf, size, "%s", fixed[i]);
            return buf;
        }
    }
    char out[1024];
    if (mts_test_run("command -v nginx", out, sizeof out) == 0 && out[0] == '/') {
        out[strcspn(out, "\n")] = 0;
        snprintf(buf, size, "%.400s", out);
        return buf;
    }
    return NULL;
}

/* Copies the config src to dst with each line that holds marks[i]
 * replaced by lines[i] (comment lines are kept as they are). 0 when a file
 * could not be read or written, or a mark was not found. */
static inline int mts_test_conf_from(const char *src, const char *dst, const char *const *marks,
                                     const char *const *lines, int n)
{
    FILE *in = fopen(src, "r"), *out = in ? fopen(dst, "w") : NULL;
    int found[16] = {0}, ok = in && out && n <= 16;
    char line[1024];
    while (ok && fgets(line, sizeof line, in)) {
        const char *t = line + strspn(line, " \t");
        int k = -1;
        for (int i = 0; *t != '#' && i < n && k < 0; i++)
            k = strstr(line, marks[i]) ? i : -1;
        if (k >= 0) {
            fprintf(out, "%s\n", lines[k]);
            found[k] = 1;
        } else {
            fputs(line, out);
        }
    }
    for (int i = 0; ok && i < n; i++)
        ok = found[i];
    if (in)
        fclose(in);
    if (out && fclose(out) != 0)
        ok = 0;
    return ok;
}

/* An nginx running web/nginx.conf in folder dir (its prefix: pid file,
 * temporary folders, the config as written), serving the page folder root
 * (an absolute path) on a free loopback port (*port) and proxying /stream
 * to ws_port; its stderr into log. One process (master_process off), so
 * stopping it is one signal, and it dies with the test. The pid, or -1
 * when it did not listen within `seconds` (log says why). */
static inline pid_t mts_test_front_start(const char *nginx, const char *dir, const char *root,
                                         int ws_port, int *port, const char *log, double seconds)
{
    char conf[1200], prefix[1200], listen[80], upstream[80], rootline[4200];
    snprintf(conf, sizeof conf, "%.1000s/nginx.conf", dir);
    snprintf(prefix, sizeof prefix, "%.1000s/", dir);
    snprintf(upstream, sizeof upstream, "        server 127.0.0.1:%d;", ws_port);
    snprintf(rootline, sizeof rootline, "        root %.4096s;", root);
    const char *marks[] = {"@LISTEN@", "@UPSTREAM@", "@ROOT@"};
    mkdir(dir, 0755);
    /* a free port can be taken before nginx binds it: another one then */
    for (int attempt = 0; attempt < 3; attempt++) {
        *port = mts_test_free_port();
        snprintf(listen, sizeof listen, "        listen 127.0.0.1:%d;", *port);
        const char *lines[] = {listen, upstream, rootline};
        if (!mts_test_conf_from("web/nginx.conf", conf, marks, lines, 3))
            return -1;
        pid_t parent = getpid();
        pid_t pid = fork();
        if (pid == 0) {
            prctl(PR_SET_PDEATHSIG, SIGKILL);
            if (getppid() != parent || !freopen(log, "w", stderr) ||
                !freopen("/dev/null", "w", stdout))
                _exit(126);
            execl(nginx, nginx, "-e", "stderr", "-p", prefix, "-c", conf, "-g",
                  "master_process off;", (char *)NULL);
            _exit(127);
        }
        if (pid < 0)
            return -1;
        for (int i = 0; i < (int)(seconds * 20); i++) {
            int st;
            if (waitpid(pid, &st, WNOHANG) == pid) {
                pid = -1; /* exited: the port, or a config error (see log) */
                break;
            }
            int fd = mts_test_connect(*port);
            if (fd >= 0) {
                close(fd);
                return pid;
            }
            struct timespec ts = {0, 50 * 1000 * 1000};
            nanosleep(&ts, NULL);
        }
        if (pid > 0) {
            kill(pid, SIGKILL);
            waitpid(pid, NULL, 0);
            return -1;
        }
    }
    return -1;
}

/* docker/nginx-tls.conf run as is, with its marked lines replaced: a
 * throwaway CA of its own (dir/ca.pem, made by mts_test_tls_front_ca) and a
 * certificate for 127.0.0.1 it signed, root served over http and https
 * (HTTP/2), /stream proxied to ws_upstream and TLS on tls_port proxied to
 * tcp_upstream. limit_rate, when set, replaces the stream files' rate line
 * (the tests slow a transfer down with ?rate=). */
typedef struct mts_test_tls_front {
    char dir[600];  /* absolute: the CA, the config, nginx's prefix and log */
    char root[700]; /* absolute: what it serves */
    char nginx[512];
    int ws_upstream, tcp_upstream;
    const char *limit_rate;
    int http_port, https_port, tls_port; /* chosen at the first start, kept on restarts */
    pid_t pid;
} mts_test_tls_front;

/* Runs a shell command; 1 when it exited 0, else it and what it printed
 * go to stderr and 0. */
static inline int mts_test_sh(const char *cmd)
{
    char out[4096];
    int rc = mts_test_run(cmd, out, sizeof out);
    if (rc != 0)
        fprintf(stderr, "  `%s` failed: %s\n", cmd, out);
    return rc == 0;
}

/* NULL when the TLS front can run here (nginx, written into nginx, with
 * its stream module, and openssl), else what is missing. */
static inline const char *mts_test_tls_front_missing(char *nginx, size_t size)
{
    char out[256];
    if (!mts_test_find_nginx(nginx, size))
        return "nginx is not installed";
    if (access("/usr/lib/nginx/modules/ngx_stream_module.so", R_OK) != 0)
        return "nginx's stream module is not installed";
    if (mts_test_run("command -v openssl", out, sizeof out) != 0)
        return "openssl is not installed";
    return NULL;
}

/* The CA (ca.pem, ca.key) and nginx's certificate (cert.pem, key.pem) for
 * 127.0.0.1 and localhost, made by openssl in f->dir. 1 on success; else
 * out says what openssl said. */
static inline int mts_test_tls_front_ca(const mts_test_tls_front *f, char *out, size_t size)
{
    char cmd[4096];
    mkdir(f->dir, 0755);
    snprintf(cmd, sizeof cmd,
             "cd %s && openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes "
             "-keyout ca.key -out ca.pem -days 2 -subj '/CN=mtstream test CA' && "
             "openssl req -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -keyout key.pem "
             "-out srv.csr -subj /CN=127.0.0.1 && "
             "printf 'subjectAltName=IP:127.0.0.1,DNS:localhost\\n' > ext.cnf && "
             "openssl x509 -req -in srv.csr -CA ca.pem -CAkey ca.key -CAcreateserial "
             "-out cert.pem -days 2 -extfile ext.cnf 2>&1",
             f->dir);
    return mts_test_run(cmd, out, size) == 0;
}

/* Starts (or starts again) nginx on f's ports. The pid (also in f->pid),
 * or -1 when it did not listen (dir/nginx.log says why). */
static inline pid_t mts_test_tls_front_start(mts_test_tls_front *f)
{
    char conf[800], prefix[800], log[800];
    snprintf(conf, sizeof conf, "%s/nginx.conf", f->dir);
    snprintf(prefix, sizeof prefix, "%s/nginx/", f->dir);
    snprintf(log, sizeof log, "%s/nginx.log", f->dir);
    mkdir(prefix, 0755);
    f->pid = -1;
    if (!f->http_port) {
        f->http_port = mts_test_free_port();
        f->https_port = mts_test_free_port();
        f->tls_port = mts_test_free_port();
    }
    char l[11][900];
    snprintf(l[0], sizeof l[0], "listen 127.0.0.1:%d;", f->http_port);
    snprintf(l[1], sizeof l[1], "listen 127.0.0.1:%d ssl http2;", f->https_port);
    snprintf(l[2], sizeof l[2], "ssl_certificate %s/cert.pem;", f->dir);
    snprintf(l[3], sizeof l[3], "ssl_certificate_key %s/key.pem;", f->dir);
    snprintf(l[4], sizeof l[4], "root %s;", f->root);
    snprintf(l[5], sizeof l[5], "server 127.0.0.1:%d;", f->ws_upstream ? f->ws_upstream : 9);
    snprintf(l[6], sizeof l[6], "server 127.0.0.1:%d;", f->tcp_upstream ? f->tcp_upstream : 9);
    snprintf(l[7], sizeof l[7], "listen 127.0.0.1:%d ssl;", f->tls_port);
    snprintf(l[8], sizeof l[8], "%s", f->limit_rate ? f->limit_rate : "limit_rate 0;");
    const char *marks[] = {"@HTTP_LISTEN@", "@HTTPS_LISTEN@", "@CERT@",        "@KEY@",
                           "@ROOT@",        "@WS_UPSTREAM@",  "@TCP_UPSTREAM@", "@TLS_LISTEN@",
                           "@LIMIT_RATE@",  "@STREAM_CERT@",  "@STREAM_KEY@"};
    const char *lines[] = {l[0], l[1], l[2], l[3], l[4], l[5], l[6], l[7], l[8], l[2], l[3]};
    if (!mts_test_conf_from("docker/nginx-tls.conf", conf, marks, lines, 11))
        return -1;
    pid_t parent = getpid();
    pid_t pid = fork();
    if (pid == 0) {
        prctl(PR_SET_PDEATHSIG, SIGKILL);
        if (getppid() != parent || !freopen(log, "a", stderr) || !freopen("/dev/null", "w", stdout))
            _exit(126);
        execl(f->nginx, f->nginx, "-e", "stderr", "-p", prefix, "-c", conf, "-g",
              "master_process off; pid nginx.pid;", (char *)NULL);
        _exit(127);
    }
    if (pid < 0)
        return -1;
    for (int i = 0; i < 100; i++) {
        int st;
        if (waitpid(pid, &st, WNOHANG) == pid)
            return -1;
        if (mts_test_wait_port(f->https_port, 0.05) && mts_test_wait_port(f->http_port, 0.05) &&
            mts_test_wait_port(f->tls_port, 0.05))
            return f->pid = pid;
    }
    kill(pid, SIGKILL);
    waitpid(pid, NULL, 0);
    return -1;
}

/* Stops it: SIGKILL as a crash (every connection cut at once), else SIGTERM. */
static inline void mts_test_tls_front_stop(mts_test_tls_front *f, int crash)
{
    if (f->pid > 0) {
        kill(f->pid, crash ? SIGKILL : SIGTERM);
        waitpid(f->pid, NULL, 0);
    }
    f->pid = -1;
}

/* An HTTP request's head from fd, NUL-terminated into req (size at least
 * 2): read until the blank line, the peer's end, or req is full. For the
 * tests' small hostile web servers. */
static inline void mts_test_read_request(int fd, char *req, size_t size)
{
    size_t got = 0;
    req[0] = 0;
    while (got < size - 1) {
        ssize_t n = read(fd, req + got, size - 1 - got);
        if (n <= 0)
            break;
        got += (size_t)n;
        req[got] = 0;
        if (strstr(req, "\r\n\r\n"))
            break;
    }
}

/* The first size-1 bytes of a file, NUL-terminated ("" when unreadable). */
static inline void mts_test_read_file(const char *path, char *out, size_t size)
{
    out[0] = 0;
    FILE *f = fopen(path, "r");
    if (!f)
        return;
    size_t n = fread(out, 1, size - 1, f);
    out[n] = 0;
    fclose(f);
}

/* The value of "key": in a JSON line, as text up to the next ',', '}' or
 * line end ("" when absent). */
static inline void mts_test_json(const char *json, const char *key, char *out, size_t size)
{
    char k[64];
    snprintf(k, sizeof k, "\"%s\":", key);
    const char *p = strstr(json, k);
    out[0] = 0;
    if (!p)
        return;
    p += strlen(k);
    size_t n = strcspn(p, ",}\n");
    if (n >= size)
        n = size - 1;
    memcpy(out, p, n);
    out[n] = 0;
}

/* The number after "key": in a JSON line, or -1. */
static inline long mts_test_json_long(const char *json, const char *key)
{
    char k[64];
    snprintf(k, sizeof k, "\"%s\":", key);
    const char *p = strstr(json, k);
    return p ? strtol(p + strlen(k), NULL, 10) : -1;
}

/* Events a stream client gave, by kind. */
typedef struct mts_test_events {
    int info, base, batch, end, resumed, error;
} mts_test_events;

/* Feeds data to c as one connection does: in pieces of 1 to max_piece bytes
 * drawn from seed, up to the end or the first error, the client's or its
 * frames'; adds the events to *n. A frame left incomplete stays in c until a
 * new conversation (mts_stream_client_reconnected or _continue) drops it. */
static inline mts_result mts_test_feed(mts_stream_client *c, const uint8_t *data, size_t size,
                                       uint64_t seed, size_t max_piece, mts_test_events *n,
                                       mts_error *err)
{
    size_t at = 0;
    while (at < size) {
        seed = seed * 6364136223846793005ull + 1442695040888963407ull;
        size_t piece = 1 + (size_t)((seed >> 33) % max_piece);
        if (piece > size - at)
            piece = size - at;
        mts_result rc = mts_stream_client_feed(c, data + at, piece, err);
        if (rc != MTS_OK)
            return rc;
        at += piece;
        mts_stream_event ev;
        int got;
        while ((got = mts_stream_client_next(c, &ev, err)) > 0) {
            n->info += ev == MTS_EV_INFO;
            n->base += ev == MTS_EV_BASE;
            n->batch += ev == MTS_EV_BATCH;
            n->end += ev == MTS_EV_END;
            n->resumed += ev == MTS_EV_RESUMED;
            n->error += ev == MTS_EV_ERROR;
        }
        if (got < 0)
            return err->code;
    }
    return MTS_OK;
}

#endif
