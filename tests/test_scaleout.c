/* The scale-out topology of docker/ (compose.yaml), on loopback: two
 * mts-server processes serving one shared models folder, Debian's nginx as
 * the TCP balancer in front of them running the project's own
 * docker/nginx-stream.conf (only its two marked address lines replaced), and
 * mts-stress sending 1,000 clients through the balancer. Every client must
 * complete, and both servers must have served: their per-connection log lines
 * count the completed streams, which add up to the clients.
 *
 * No Docker engine runs where the tests run, so this is what checks the
 * topology; the Docker files themselves are not exercised here.
 *
 * Skips, saying why, when nginx or its stream module is not installed
 * (scripts/deps.sh installs both). Every process it starts is stopped on
 * every path, and dies with the test if the test itself is killed. */
#include <arpa/inet.h>
#include <errno.h>
#include <libgen.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "clock.h"
#include "test.h"
#include "test_proc.h"

#if defined(__SANITIZE_ADDRESS__)
#define MTS_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define MTS_ASAN 1
#endif
#endif

/* 1,000 clients, as compose's stress service sends (docker/README.md); the
 * sanitizer build runs the same number (every client decodes and applies
 * its batches, a few seconds of work even there) but gets more time for
 * everything to come up and finish. */
#define CLIENTS 1000
#ifdef MTS_ASAN
#define WAIT_S 60
#define STRESS_LIMIT_S 240
#else
#define WAIT_S 20
#define STRESS_LIMIT_S 90
#endif

#define SERVERS 2

static char bin_dir[512], tmp_dir[512];


/* Starts argv with stderr into log and stdout into out (or /dev/null). The
 * child gets SIGKILL when the test dies, so a crashed or timed-out test
 * leaves no server or nginx holding ports behind. */
static pid_t spawn(char *const argv[], const char *log, const char *out)
{
    pid_t parent = getpid();
    pid_t pid = fork();
    if (pid == 0) {
        prctl(PR_SET_PDEATHSIG, SIGKILL);
        if (getppid() != parent) /* the test died before prctl took hold */
            _exit(126);
        if (!freopen(log, "w", stderr) || !freopen(out ? out : "/dev/null", "w", stdout))
            _exit(126);
        execv(argv[0], argv);
        fprintf(stderr, "exec %s: %s\n", argv[0], strerror(errno));
        _exit(127);
    }
    return pid;
}

/* SIGTERM, then SIGKILL if it has not gone in 10 s: mts-server lets streams
 * finish for its --grace, which is short here as nothing is left running.
 * Returns the exit status, -1 when it did not exit by itself (or was not
 * running): mts-server exits 0 after a clean stop, and in the sanitizer build
 * a leak or error report makes that non-zero. */
static int stop(pid_t *pid)
{
    if (*pid <= 0)
        return -1;
    kill(*pid, SIGTERM);
    int st = 0;
    for (int i = 0; i < 1000; i++) {
        if (waitpid(*pid, &st, WNOHANG) == *pid) {
            *pid = 0;
            return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
        }
        usleep(10000);
    }
    kill(*pid, SIGKILL);
    waitpid(*pid, NULL, 0);
    *pid = 0;
    return -1;
}

/* Has pid exited? (reaps it; *pid becomes 0) */
static int gone(pid_t *pid)
{
    if (*pid > 0 && waitpid(*pid, NULL, WNOHANG) == *pid)
        *pid = 0;
    return *pid == 0;
}

/* The whole file, NUL-terminated, or NULL. */
static char *slurp(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *s = n >= 0 ? malloc((size_t)n + 1) : NULL;
    if (s) {
        size_t got = fread(s, 1, (size_t)n, f);
        s[got] = 0;
    }
    fclose(f);
    return s;
}

/* Prints the last part of a log to stderr, for a failure's context. */
static void show_tail(const char *what, const char *path)
{
    char *s = slurp(path);
    size_t n = s ? strlen(s) : 0;
    fprintf(stderr, "  --- %s (%s), last part:\n%s\n", what, path,
            s ? s + (n > 1500 ? n - 1500 : 0) : "(missing)");
    free(s);
}

/* Waits until the file exists and, when needle is given, holds it; fails
 * early when *pid exits. */
static int wait_for(const char *path, const char *needle, pid_t *pid, double seconds)
{
    double end = mts_clock_seconds() + seconds;
    while (mts_clock_seconds() < end) {
        char *s = slurp(path);
        int ok = s && (!needle || strstr(s, needle));
        free(s);
        if (ok)
            return 1;
        if (gone(pid))
            return 0;
        usleep(20000);
    }
    return 0;
}

/* Completed streams in an mts-server log: one line per connection, and a
 * completed one reads "... model=cow ... outcome=ok". */
static int count_ok(const char *log)
{
    char *s = slurp(log);
    int n = 0;
    for (char *line = s; line && *line;) {
        char *end = strchr(line, '\n');
        if (end)
            *end = 0;
        if (strstr(line, " model=cow ") && strstr(line, " outcome=ok"))
            n++;
        line = end ? end + 1 : NULL;
    }
    free(s);
    return n;
}

/* How this nginx has the stream module: the load_module line to use ("" when
 * it is built in), or NULL with why filled in when it has none. */
static const char *stream_module(const char *nginx, char *line, size_t size, char *why,
                                 size_t why_size)
{
    char cmd[700], out[8192];
    snprintf(cmd, sizeof cmd, "%s -V", nginx);
    if (mts_test_run(cmd, out, sizeof out) != 0) {
        snprintf(why, why_size, "%.300s -V failed: %.200s", nginx, out);
        return NULL;
    }
    /* "--with-stream" alone is built in; "--with-stream=dynamic" a module
     * file (Debian's libnginx-mod-stream); neither, no stream at all. */
    for (const char *p = out; (p = strstr(p, "--with-stream")); p++) {
        char c = p[strlen("--with-stream")];
        if (c == ' ' || c == '\n' || c == 0) {
            line[0] = 0;
            return line;
        }
    }
    if (!strstr(out, "--with-stream=dynamic")) {
        snprintf(why, why_size, "%s is built without the stream module", nginx);
        return NULL;
    }
    char dir[512] = "/usr/lib/nginx/modules";
    const char *mp = strstr(out, "--modules-path=");
    if (mp) {
        mp += strlen("--modules-path=");
        size_t n = strcspn(mp, " \n");
        snprintf(dir, sizeof dir, "%.*s", (int)n, mp);
    }
    char so[600];
    snprintf(so, sizeof so, "%s/ngx_stream_module.so", dir);
    if (access(so, R_OK) != 0) {
        snprintf(why, why_size, "nginx's stream module %s is not installed (libnginx-mod-stream)",
                 so);
        return NULL;
    }
    snprintf(line, size, "load_module %s;\n", so);
    return line;
}

/* docker/nginx-stream.conf with the balancer's listen address and the
 * upstream servers put in for loopback, and the load_module line for this
 * nginx. Everything else (limits, timeouts, logging) is the file as compose
 * runs it. Returns 0 when a marked line is missing. */
static int write_nginx_conf(const char *path, const char *load_line, int lb_port,
                            const int *ports)
{
    char *src = slurp("docker/nginx-stream.conf");
    FILE *f = fopen(path, "w");
    int upstream = 0, listen_ = 0;
    for (char *line = src; f && line && *line;) {
        char *end = strchr(line, '\n');
        if (end)
            *end = 0;
        const char *t = line + strspn(line, " \t");
        if (*t == '#') { /* comments may name the markers too */
            fprintf(f, "%s\n", line);
        } else if (strncmp(t, "load_module ", 12) == 0) {
            fputs(load_line, f);
        } else if (strstr(line, "@UPSTREAM@")) {
            for (int i = 0; i < SERVERS; i++)
                fprintf(f, "        server 127.0.0.1:%d;\n", ports[i]);
            upstream = 1;
        } else if (strstr(line, "@LISTEN@")) {
            fprintf(f, "        listen 127.0.0.1:%d backlog=4096;\n", lb_port);
            listen_ = 1;
        } else {
            fprintf(f, "%s\n", line);
        }
        line = end ? end + 1 : NULL;
    }
    free(src);
    if (f)
        fclose(f);
    return f && upstream && listen_;
}

static void test_two_servers_behind_nginx(mts_test *t)
{
    char nginx_buf[512], load_line[700], why[700];
    const char *nginx = mts_test_find_nginx(nginx_buf, sizeof nginx_buf);
    /* CI installs nginx (deps.sh) and sets MTS_TEST_REQUIRE_NGINX: a skip
     * there would hide a broken setup, so it fails instead */
    int required = getenv("MTS_TEST_REQUIRE_NGINX") != NULL;
    if (!nginx) {
        snprintf(why, sizeof why,
                 "nginx is not installed (scripts/deps.sh installs nginx and libnginx-mod-stream)");
        CHECKF(t, !required, "%s", why);
        if (!required)
            SKIP(t, "%s", why);
        return;
    }
    if (!stream_module(nginx, load_line, sizeof load_line, why, sizeof why)) {
        CHECKF(t, !required, "%s", why);
        if (!required)
            SKIP(t, "%s", why);
        return;
    }

    char dir[700], models[800], cmd[4096], out[16384];
    snprintf(dir, sizeof dir, "%s/scaleout.%ld", tmp_dir, (long)getpid());
    snprintf(models, sizeof models, "%s/models", dir);
    /* One models folder for both servers, as compose's shared volume; the
     * model is built once beforehand, as its one-shot `models` service does. */
    snprintf(cmd, sizeof cmd,
             "rm -rf '%s' && mkdir -p '%s' && '%s/mts-build' tests/data/cow.off -o '%s/cow.mtsm' "
             "--quiet",
             dir, models, bin_dir, models);
    int rc = mts_test_run(cmd, out, sizeof out);
    CHECKF(t, rc == 0, "mts-build: %s", out);
    if (rc != 0)
        return;

    pid_t srv[SERVERS] = {0}, lb = 0;
    int ports[SERVERS], lb_port = mts_test_free_port();
    char logs[SERVERS][800], listen[SERVERS][64], server_bin[600];
    char conf[800], pidfile[800], globals[1700], lb_err[800], lb_out[800], prefix[800];
    snprintf(server_bin, sizeof server_bin, "%s/mts-server", bin_dir);
    int up = 1;
    for (int i = 0; i < SERVERS && up; i++) {
        snprintf(logs[i], sizeof logs[i], "%s/server%d.log", dir, i + 1);
        /* A free port can be taken before the server binds it: a server that
         * exits at once gets another port. */
        for (int attempt = 0; attempt < 3; attempt++) {
            ports[i] = mts_test_free_port();
            snprintf(listen[i], sizeof listen[i], "127.0.0.1:%d", ports[i]);
            char *argv[] = {server_bin, "--models", models, "--listen", listen[i],
                            "--grace", "1", NULL};
            srv[i] = spawn(argv, logs[i], NULL);
            /* It logs "listening on" once its socket is open. */
            up = wait_for(logs[i], "listening on", &srv[i], WAIT_S);
            if (up || srv[i] > 0)
                break;
        }
        CHECKF(t, up, "server %d did not come up on %s", i + 1, listen[i]);
        if (!up)
            show_tail("server log", logs[i]);
    }

    if (up) {
        snprintf(conf, sizeof conf, "%s/nginx.conf", dir);
        snprintf(pidfile, sizeof pidfile, "%s/nginx.pid", dir);
        snprintf(lb_err, sizeof lb_err, "%s/nginx.err", dir);
        snprintf(lb_out, sizeof lb_out, "%s/nginx.access", dir);
        snprintf(prefix, sizeof prefix, "%s/", dir);
        /* One process (no master and workers), so stopping it is one kill and
         * PDEATHSIG covers it; the pid file in the test's folder, not /run. */
        snprintf(globals, sizeof globals, "master_process off; pid %s;", pidfile);
        int lb_up = 0, conf_ok = 1;
        /* As for the servers: another port when nginx exits at once. */
        for (int attempt = 0; attempt < 3 && !lb_up; attempt++) {
            lb_port = mts_test_free_port();
            conf_ok = write_nginx_conf(conf, load_line, lb_port, ports);
            CHECKF(t, conf_ok, "docker/nginx-stream.conf is missing or lost its marked lines");
            if (!conf_ok)
                break;
            /* -e stderr: errors from before the config is read go to the log
             * file too, not to /var/log/nginx, which another user may not
             * write. */
            char *argv[] = {(char *)nginx, "-e", "stderr", "-p", prefix,
                            "-c", conf, "-g", globals, NULL};
            lb = spawn(argv, lb_err, lb_out);
            /* nginx writes its pid file once its listening sockets are open. */
            lb_up = wait_for(pidfile, NULL, &lb, WAIT_S);
            if (!lb_up && lb > 0) /* running but not listening: no point retrying */
                break;
        }
        if (conf_ok && !lb_up) {
            CHECKF(t, lb_up, "nginx did not start");
            show_tail("nginx errors", lb_err);
        }
        up = lb_up;
    }

    if (up) {
        /* timeout(1): a stuck run still ends, and the processes get stopped. */
        snprintf(cmd, sizeof cmd,
                 "timeout -k 5 %d '%s/mts-stress' 127.0.0.1:%d cow --clients %d --json",
                 STRESS_LIMIT_S, bin_dir, lb_port, CLIENTS);
        double t0 = mts_clock_seconds();
        rc = mts_test_run(cmd, out, sizeof out);
        double secs = mts_clock_seconds() - t0;
        const char *json = strstr(out, "{\"");
        long clients = json ? mts_test_json_long(json, "clients") : -1;
        long ok = json ? mts_test_json_long(json, "succeeded") : -1;
        long failed = json ? mts_test_json_long(json, "failed") : -1;
        CHECKF(t, rc == 0, "mts-stress exit %d after %.1f s: %.3000s", rc, secs, out);
        CHECKF(t, clients == CLIENTS && ok == CLIENTS && failed == 0, "%.3000s", out);
        /* Stop the balancer and then the servers, so every connection is over
         * and logged before the logs are read. */
        stop(&lb);
        for (int i = 0; i < SERVERS; i++) {
            int st = stop(&srv[i]);
            CHECKF(t, st == 0, "server %d exited %d after SIGTERM", i + 1, st);
        }
        int served[SERVERS], sum = 0;
        for (int i = 0; i < SERVERS; i++) {
            served[i] = count_ok(logs[i]);
            sum += served[i];
        }
        if (getenv("MTS_TEST_VERBOSE"))
            fprintf(stderr,
                    "  %d clients in %.1f s through nginx: server 1 served %d, server 2 %d\n",
                    CLIENTS, secs, served[0], served[1]);
        for (int i = 0; i < SERVERS; i++)
            CHECKF(t, served[i] > 0, "server %d served no client (%d and %d)", i + 1, served[0],
                   served[1]);
        CHECKF(t, sum == CLIENTS, "the servers completed %d + %d streams, not %d", served[0],
               served[1], CLIENTS);
        if (t->case_failed) {
            show_tail("nginx errors", lb_err);
            for (int i = 0; i < SERVERS; i++)
                show_tail("server log", logs[i]);
        }
    }

    stop(&lb);
    for (int i = 0; i < SERVERS; i++)
        stop(&srv[i]);
    /* Keep the folder for a look after a failure. */
    if (!t->case_failed) {
        snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
        mts_test_run(cmd, out, sizeof out);
    }
}

/* The Docker and Kubernetes files cannot run here (no engine, no cluster),
 * but they can be linted: yamllint (deps.sh installs it) on both YAML files,
 * strict, so a warning fails too. */
static void test_docker_files_lint(mts_test *t)
{
    char out[8192];
    if (mts_test_run("command -v yamllint", out, sizeof out) != 0) {
        CHECKF(t, !getenv("MTS_TEST_REQUIRE_NGINX"), "yamllint is not installed");
        SKIP(t, "yamllint is not installed (scripts/deps.sh installs it)");
    }
    int rc = mts_test_run("yamllint -s docker/compose.yaml docker/k8s.yaml", out, sizeof out);
    CHECKF(t, rc == 0, "yamllint: %s", out);
}

int main(int argc, char **argv)
{
    (void)argc;
    mts_test_bin_dir(argv[0], bin_dir, sizeof bin_dir);
    snprintf(tmp_dir, sizeof tmp_dir, "%s", mts_test_tmpdir());
    signal(SIGPIPE, SIG_IGN);
    /* 1,000 clients hold 1,000 descriptors in mts-stress, 2,000 in nginx
     * (client and upstream side) and about 500 in each server: every child
     * inherits the soft limit raised to the hard one (often only 1,024 soft). */
    struct rlimit rl;
    if (getrlimit(RLIMIT_NOFILE, &rl) == 0 && rl.rlim_cur < 65536 && rl.rlim_cur < rl.rlim_max) {
        rl.rlim_cur = rl.rlim_max < 65536 ? rl.rlim_max : 65536;
        setrlimit(RLIMIT_NOFILE, &rl);
    }
    mts_test t = {0};
    RUN(&t, test_two_servers_behind_nginx);
    RUN(&t, test_docker_files_lint);
    return mts_test_end(&t);
}
