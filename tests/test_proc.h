/* Processes for end-to-end tests: start a program with its stderr in a log,
 * stop it, find a free loopback port, wait until a server answers, read a
 * log back. Tests that run the programs find them beside their own binary
 * (build/bin for build/tests, build/asan/bin for build/asan/tests), so the
 * ASan build tests the ASan programs. */
#ifndef MTS_TEST_PROC_H
#define MTS_TEST_PROC_H

#include <arpa/inet.h>
#include <libgen.h>
#include <netinet/in.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

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

/* A connected loopback socket to port, or -1. */
static inline int mts_test_connect(int port)
{
    int fd = socket(AF_INET, SOCK_STREAM, 0);
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

#endif
