/* The server over loopback: a well-behaved client gets the whole stream and
 * the same mesh as the model, while at the same moment others send garbage, a
 * wrong version, an unknown model, or nothing at all -- each of those gets an
 * ERROR and a close, and the good client is served regardless. */
#include <arpa/inet.h>
#include <errno.h>
#include <netinet/in.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "build.h"
#include "mesh.h"
#include "server.h"
#include "stream.h"
#include "test.h"
#include "wire.h"

static atomic_int stop_flag;
/* > 0: the forked server runs with this few file descriptors */
static int fd_limit;

static void on_term(int sig)
{
    (void)sig;
    stop_flag = 1;
}

static int connect_to(int port)
{
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in a = {0};
    a.sin_family = AF_INET;
    a.sin_port = htons((uint16_t)port);
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (fd < 0 || connect(fd, (struct sockaddr *)&a, sizeof a) != 0) {
        if (fd >= 0)
            close(fd);
        return -1;
    }
    return fd;
}

/* Sends data, then reads until the server closes (at most `seconds`). */
static int exchange(int port, const void *data, size_t size, mts_buf *reply, double seconds)
{
    int fd = connect_to(port);
    if (fd < 0)
        return 0;
    if (size && send(fd, data, size, MSG_NOSIGNAL) != (ssize_t)size) {
        close(fd);
        return 0;
    }
    uint8_t buf[65536];
    struct timespec t0;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    for (;;) {
        struct pollfd pf = {fd, POLLIN, 0};
        if (poll(&pf, 1, 200) < 0)
            break;
        ssize_t r = recv(fd, buf, sizeof buf, 0);
        if (r > 0) {
            mts_buf_put(reply, buf, (size_t)r);
            continue;
        }
        if (r == 0 || (errno != EAGAIN && errno != EINTR))
            break;
        struct timespec t1;
        clock_gettime(CLOCK_MONOTONIC, &t1);
        if ((double)(t1.tv_sec - t0.tv_sec) + (t1.tv_nsec - t0.tv_nsec) * 1e-9 > seconds)
            break;
    }
    close(fd);
    return 1;
}

static uint16_t error_code_of(const mts_buf *reply)
{
    if (reply->size < 7 || reply->data[4] != MTS_MSG_ERROR)
        return 0;
    return (uint16_t)(reply->data[5] | reply->data[6] << 8);
}

static void hello_bytes(mts_buf *b, const char *model, uint16_t major)
{
    mts_wire_hello h = {0};
    h.major = major;
    snprintf(h.model, sizeof h.model, "%s", model);
    mts_wire_put_hello(b, &h);
}

typedef struct served {
    mts_stream stream;
    pid_t pid;
    int port;
} served;

/* sopts: how cow's stream is built (NULL: the defaults, no records form) */
static int start_server_with(mts_test *t, served *sv, const mts_server_options *opts,
                             const mts_stream_options *sopts)
{
    mts_error err = {0};
    mts_mesh mesh = {0};
    mts_model m;
    CHECK(t, mts_mesh_load("tests/data/cow.off", NULL, &mesh, NULL, &err) == MTS_OK);
    CHECK(t, mts_build_model(&mesh, "cow", NULL, &m, NULL, &err) == MTS_OK);
    mts_mesh_free(&mesh);
    CHECKF(t, mts_stream_build(&m, "cow", sopts, &sv->stream, &err) == MTS_OK, "%s", err.msg);
    mts_model_free(&m);
    const mts_stream *list[1] = {&sv->stream};
    mts_server *server = NULL;
    CHECKF(t, mts_server_create(opts, list, 1, &server, &err) == MTS_OK, "%s", err.msg);
    if (!server)
        return 0;
    sv->port = mts_server_port(server);
    sv->pid = fork();
    if (sv->pid == 0) {
        signal(SIGTERM, on_term);
        if (fd_limit > 0) {
            struct rlimit rl;
            getrlimit(RLIMIT_NOFILE, &rl);
            rl.rlim_cur = (rlim_t)fd_limit;
            setrlimit(RLIMIT_NOFILE, &rl);
        }
        mts_result rc = mts_server_run(server, &stop_flag, &err);
        mts_server_free(server);
        mts_stream_free(&sv->stream);
        _exit(rc == MTS_OK ? 0 : 3);
    }
    mts_server_free(server); /* the parent's copy of the listener */
    return sv->pid > 0;
}

static int start_server(mts_test *t, served *sv, const mts_server_options *opts)
{
    return start_server_with(t, sv, opts, NULL);
}

static void stop_server(mts_test *t, served *sv)
{
    kill(sv->pid, SIGTERM);
    int st = 0;
    waitpid(sv->pid, &st, 0);
    CHECKF(t, WIFEXITED(st) && WEXITSTATUS(st) == 0, "server exit status %d", st);
    mts_stream_free(&sv->stream);
}

static void test_good_client_beside_bad_ones(mts_test *t)
{
    served sv;
    mts_server_options o = {0};
    o.listen = "127.0.0.1:0";
    o.handshake_timeout = 0.5;
    if (!start_server(t, &sv, &o))
        return;
    /* a silent client holds a connection open while the others run */
    int silent = connect_to(sv.port);
    CHECK(t, silent >= 0);

    mts_buf hello = {0}, reply = {0};
    hello_bytes(&hello, "cow", MTS_WIRE_MAJOR);
    CHECK(t, exchange(sv.port, hello.data, hello.size, &reply, 10));
    mts_stream_client c;
    mts_stream_client_init(&c);
    mts_wire_reader r = {0};
    mts_error err = {0};
    int ended = 0;
    CHECK(t, mts_wire_reader_feed(&r, reply.data, reply.size, &err) == MTS_OK);
    uint8_t type;
    const uint8_t *p;
    size_t n;
    while (mts_wire_reader_next(&r, &type, &p, &n, &err) == 1) {
        mts_stream_event ev;
        CHECKF(t, mts_stream_client_frame(&c, type, p, n, &ev, &err) == MTS_OK, "%s", err.msg);
        ended |= ev == MTS_EV_END;
    }
    CHECK(t, ended && c.lod.level == sv.stream.model.level_count);
    CHECK(t, c.checksum == sv.stream.level_checksum[sv.stream.model.level_count]);
    mts_stream_client_free(&c);
    mts_wire_reader_free(&r);

    /* unknown model, wrong major version (a 1.x client, whose records the
     * stream no longer matches, and a future one), garbage, a bad name */
    struct {
        const char *model;
        uint16_t major;
        uint16_t want;
    } cases[] = {{"nosuch", MTS_WIRE_MAJOR, MTS_WERR_UNKNOWN_MODEL},
                 {"cow", 1, MTS_WERR_VERSION},
                 {"cow", 9, MTS_WERR_VERSION}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        mts_buf h = {0}, rep = {0};
        hello_bytes(&h, cases[i].model, cases[i].major);
        CHECK(t, exchange(sv.port, h.data, h.size, &rep, 5));
        CHECKF(t, error_code_of(&rep) == cases[i].want, "case %zu: code %u", i, error_code_of(&rep));
        mts_buf_free(&h);
        mts_buf_free(&rep);
    }
    const char garbage[] = "GET / HTTP/1.1\r\nHost: x\r\n\r\n";
    mts_buf rep = {0};
    CHECK(t, exchange(sv.port, garbage, sizeof garbage - 1, &rep, 5));
    CHECK(t, error_code_of(&rep) == MTS_WERR_PROTOCOL);
    mts_buf_free(&rep);

    /* the silent one is timed out with an ERROR */
    mts_buf late = {0};
    uint8_t buf[256];
    struct pollfd pf = {silent, POLLIN, 0};
    CHECK(t, poll(&pf, 1, 3000) == 1);
    ssize_t got = recv(silent, buf, sizeof buf, 0);
    if (got > 0)
        mts_buf_put(&late, buf, (size_t)got);
    CHECK(t, error_code_of(&late) == MTS_WERR_TIMEOUT);
    close(silent);
    mts_buf_free(&late);

    /* LIST */
    mts_buf list = {0}, lrep = {0};
    mts_wire_put_list(&list);
    CHECK(t, exchange(sv.port, list.data, list.size, &lrep, 5));
    CHECK(t, lrep.size > 5 && lrep.data[4] == MTS_MSG_MODELS);
    mts_buf_free(&list);
    mts_buf_free(&lrep);

    mts_buf_free(&hello);
    mts_buf_free(&reply);
    stop_server(t, &sv);
}

static void test_busy(mts_test *t)
{
    served sv;
    mts_server_options o = {0};
    o.listen = "127.0.0.1:0";
    o.max_clients = 1;
    if (!start_server(t, &sv, &o))
        return;
    int first = connect_to(sv.port);
    CHECK(t, first >= 0);
    usleep(100000); /* let the server take it */
    mts_buf rep = {0};
    CHECK(t, exchange(sv.port, NULL, 0, &rep, 3));
    CHECK(t, error_code_of(&rep) == MTS_WERR_BUSY);
    mts_buf_free(&rep);
    close(first);
    stop_server(t, &sv);
}

/* utime + stime of a process, in clock ticks. */
static long cpu_ticks(pid_t pid)
{
    char path[64], line[1024];
    snprintf(path, sizeof path, "/proc/%d/stat", (int)pid);
    FILE *f = fopen(path, "r");
    if (!f)
        return -1;
    size_t n = fread(line, 1, sizeof line - 1, f);
    fclose(f);
    line[n] = 0;
    const char *p = strrchr(line, ')');
    unsigned long ut = 0, st = 0;
    /* fields after the name: state ppid pgrp session tty tpgid flags minflt
     * cminflt majflt cmajflt utime stime */
    if (!p || sscanf(p + 2, "%*c %*d %*d %*d %*d %*d %*u %*u %*u %*u %*u %lu %lu", &ut, &st) != 2)
        return -1;
    return (long)(ut + st);
}

/* A client that sends its HELLO, shuts down its side (legal: it sends
 * nothing more) and reads slowly is served to the end, and the server does
 * not spin on the half-closed socket's input event while it waits. */
static void test_half_closed_slow_reader(mts_test *t)
{
    served sv;
    mts_server_options o = {0};
    o.listen = "127.0.0.1:0";
    if (!start_server(t, &sv, &o))
        return;
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    int small = 2048;
    setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
    struct sockaddr_in a = {0};
    a.sin_family = AF_INET;
    a.sin_port = htons((uint16_t)sv.port);
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    CHECK(t, connect(fd, (struct sockaddr *)&a, sizeof a) == 0);
    mts_buf hello = {0}, reply = {0};
    hello_bytes(&hello, "cow", MTS_WIRE_MAJOR);
    CHECK(t, send(fd, hello.data, hello.size, MSG_NOSIGNAL) == (ssize_t)hello.size);
    shutdown(fd, SHUT_WR);
    usleep(200000);
    long t0 = cpu_ticks(sv.pid);
    usleep(1000000); /* not reading: the server waits on a full socket */
    long t1 = cpu_ticks(sv.pid);
    CHECKF(t, t0 >= 0 && t1 - t0 < 30, "server used %ld ticks in 1 s while waiting", t1 - t0);
    uint8_t buf[65536];
    for (;;) {
        struct pollfd pf = {fd, POLLIN, 0};
        if (poll(&pf, 1, 5000) != 1)
            break;
        ssize_t r = recv(fd, buf, sizeof buf, 0);
        if (r <= 0)
            break;
        mts_buf_put(&reply, buf, (size_t)r);
    }
    close(fd);
    CHECKF(t, reply.size > sv.stream.size, /* MODEL_INFO + the whole stream + END */
           "got %zu bytes of a %zu-byte stream", reply.size, sv.stream.size);
    mts_buf_free(&hello);
    mts_buf_free(&reply);
    stop_server(t, &sv);
}

/* Out of file descriptors, the server must neither spin nor stop: it pauses
 * accepting and serves the queued client once descriptors free up. */
static void test_out_of_descriptors(mts_test *t)
{
    served sv;
    mts_server_options o = {0};
    o.listen = "127.0.0.1:0";
    o.handshake_timeout = 0.4;
    /* stdio, listener, epoll, and a few more: leaves room for about two clients */
    int highest = dup(0);
    close(highest);
    fd_limit = highest + 4;
    int started = start_server(t, &sv, &o);
    fd_limit = 0;
    if (!started)
        return;
    int silent[8];
    for (int i = 0; i < 8; i++)
        silent[i] = connect_to(sv.port); /* the kernel queues what the server cannot take */
    usleep(200000);
    long t0 = cpu_ticks(sv.pid);
    usleep(300000);
    long t1 = cpu_ticks(sv.pid);
    CHECKF(t, t1 - t0 < 15, "server used %ld ticks in 0.3 s while out of descriptors", t1 - t0);
    for (int i = 0; i < 8; i++)
        if (silent[i] >= 0)
            close(silent[i]);
    /* the queued ones time out and free their descriptors; then a good client is served */
    mts_buf hello = {0}, reply = {0};
    hello_bytes(&hello, "cow", MTS_WIRE_MAJOR);
    int served_ok = 0;
    for (int attempt = 0; attempt < 20 && !served_ok; attempt++) {
        reply.size = 0;
        exchange(sv.port, hello.data, hello.size, &reply, 3);
        served_ok = reply.size > 1000 && reply.data[4] == MTS_MSG_MODEL_INFO;
        if (!served_ok)
            usleep(200000);
    }
    CHECK(t, served_ok);
    mts_buf_free(&hello);
    mts_buf_free(&reply);
    stop_server(t, &sv);
}

/* A refused client that sent more than its HELLO reads the ERROR and then a
 * clean end of stream: the server shuts its side and lets the client close,
 * instead of closing with unread bytes, which resets the connection (on a
 * real network the reset can destroy the ERROR in flight; on loopback it
 * shows as ECONNRESET after the data). */
static void test_refusal_survives_extra_bytes(mts_test *t)
{
    served sv;
    mts_server_options o = {0};
    o.listen = "127.0.0.1:0";
    if (!start_server(t, &sv, &o))
        return;
    int got_error = 0;
    for (int round = 0; round < 20; round++) {
        int fd = connect_to(sv.port);
        if (fd < 0)
            break;
        mts_buf req = {0};
        hello_bytes(&req, "nosuch", MTS_WIRE_MAJOR);
        uint8_t junk[2048];
        memset(junk, 0x5a, sizeof junk);
        mts_buf_put(&req, junk, sizeof junk); /* more than the server reads before refusing */
        (void)!send(fd, req.data, req.size, MSG_NOSIGNAL);
        usleep(20000); /* let the refusal and its close happen before we read */
        mts_buf reply = {0};
        uint8_t buf[4096];
        ssize_t r = -1;
        for (;;) {
            struct pollfd pf = {fd, POLLIN, 0};
            if (poll(&pf, 1, 2000) != 1)
                break;
            r = recv(fd, buf, sizeof buf, 0);
            if (r <= 0)
                break;
            mts_buf_put(&reply, buf, (size_t)r);
        }
        got_error += error_code_of(&reply) == MTS_WERR_UNKNOWN_MODEL && r == 0;
        mts_buf_free(&reply);
        mts_buf_free(&req);
        close(fd);
    }
    CHECKF(t, got_error == 20, "%d of 20 refused clients read their ERROR and a clean end",
           got_error);
    stop_server(t, &sv);
}

/* ---- the records form (PROTOCOL.md, "Records form") ---- */

static void hello_for(mts_buf *b, uint32_t flags, uint32_t resume_batch, uint64_t stream_id)
{
    mts_wire_hello h = {0};
    h.major = MTS_WIRE_MAJOR;
    h.minor = MTS_WIRE_MINOR;
    snprintf(h.model, sizeof h.model, "cow");
    h.resume_batch = resume_batch;
    h.stream_id = stream_id;
    h.flags = flags;
    mts_wire_put_hello(b, &h);
}

/* Feeds the first `size` bytes of a reply into c through a new frame reader,
 * as one connection; returns the first error (MTS_OK when none) and sets
 * *ended when END came. */
static mts_result take_reply(mts_stream_client *c, const uint8_t *data, size_t size, int *ended,
                             mts_error *err)
{
    mts_wire_reader r = {0};
    mts_result rc = mts_wire_reader_feed(&r, data, size, err);
    uint8_t type;
    const uint8_t *p;
    size_t n;
    *ended = 0;
    while (rc == MTS_OK && mts_wire_reader_next(&r, &type, &p, &n, err) == 1) {
        mts_stream_event ev;
        rc = mts_stream_client_frame(c, type, p, n, &ev, err);
        *ended |= ev == MTS_EV_END;
    }
    mts_wire_reader_free(&r);
    return rc;
}

/* The whole stream for a HELLO with these flags, into a fresh client. */
static int fetch(mts_test *t, int port, uint32_t flags, mts_stream_client *c, mts_buf *reply)
{
    mts_buf h = {0};
    hello_for(&h, flags, 0, 0);
    CHECK(t, exchange(port, h.data, h.size, reply, 10));
    mts_buf_free(&h);
    mts_stream_client_init(c);
    mts_error err = {0};
    int ended = 0;
    CHECKF(t, take_reply(c, reply->data, reply->size, &ended, &err) == MTS_OK && ended,
           "flags 0x%x: %s", flags, err.msg);
    return ended;
}

/* A server that keeps the records form: a HELLO without the flag gets the
 * splits form, one with it the records form (MODEL_INFO flags and its own
 * stream_id), and both end on the same checksum. A records-form client cut
 * inside batch 5 resumes with the records form's stream_id and ends the same;
 * a resume naming the other form's stream_id is answered `stale`. */
static void test_records_form_on_request(mts_test *t)
{
    served sv;
    mts_server_options o = {0};
    o.listen = "127.0.0.1:0";
    mts_stream_options so = {0};
    so.with_records = 1;
    if (!start_server_with(t, &sv, &o, &so))
        return;
    const mts_stream *s = &sv.stream, *r = s->records_form;
    const uint32_t n = s->model.level_count;
    CHECK(t, r != NULL && r->stream_id != s->stream_id && s->batch_count > 6);
    if (!r || s->batch_count <= 6) {
        stop_server(t, &sv);
        return;
    }
    mts_stream_client a, b;
    mts_buf ra = {0}, rb = {0};
    fetch(t, sv.port, 0, &a, &ra);
    CHECK(t, !a.records && !(a.info.flags & MTS_INFO_RECORDS) && a.info.stream_id == s->stream_id);
    CHECK(t, a.lod.level == n && a.checksum == s->level_checksum[n]);
    fetch(t, sv.port, MTS_HELLO_RECORDS, &b, &rb);
    CHECK(t, b.records && (b.info.flags & MTS_INFO_RECORDS) && b.info.stream_id == r->stream_id);
    CHECK(t, b.lod.level == n);
    CHECKF(t, b.checksum == a.checksum && b.end_checksum == a.end_checksum,
           "records %016llx, splits %016llx", (unsigned long long)b.checksum,
           (unsigned long long)a.checksum);
    /* each connection got its form whole: MODEL_INFO, the form's bytes, END */
    CHECKF(t, ra.size > s->size && ra.size < s->size + 4096 && rb.size > r->size &&
                  rb.size < r->size + 4096,
           "splits %zu bytes (stream %zu), records %zu (stream %zu)", ra.size, s->size, rb.size,
           r->size);
    mts_stream_client_free(&a);
    mts_stream_client_free(&b);

    /* cut inside batch 5 of the records form, then resumed */
    size_t info_size = 4 + ((size_t)rb.data[0] | (size_t)rb.data[1] << 8 |
                            (size_t)rb.data[2] << 16 | (size_t)rb.data[3] << 24);
    size_t cut = info_size + r->batch_offset[5] + 7;
    mts_stream_client c;
    mts_stream_client_init(&c);
    mts_error err = {0};
    int ended;
    CHECKF(t, take_reply(&c, rb.data, cut, &ended, &err) == MTS_OK && !ended, "%s", err.msg);
    CHECK(t, c.records && c.batches == 5 && c.lod.level == s->batch_first[5]);
    uint32_t batch;
    uint64_t id;
    CHECK(t, mts_stream_client_resume_point(&c, &batch, &id) && batch == 5 && id == r->stream_id);
    CHECK(t, mts_stream_client_reconnected(&c, &err) == MTS_OK);
    mts_buf h = {0}, rest = {0};
    hello_for(&h, MTS_HELLO_RECORDS, batch, id);
    CHECK(t, exchange(sv.port, h.data, h.size, &rest, 10));
    CHECKF(t, rest.size > 5 && rest.data[4] == MTS_MSG_MODEL_INFO, "code %u",
           error_code_of(&rest));
    /* from batch 5 on: no BASE, no batch sent twice */
    CHECKF(t, rest.size < rb.size - r->batch_offset[5] + 16, "resumed reply %zu bytes of %zu",
           rest.size, rb.size);
    CHECKF(t, take_reply(&c, rest.data, rest.size, &ended, &err) == MTS_OK && ended, "%s",
           err.msg);
    CHECK(t, c.resumes == 1 && c.lod.level == n && c.checksum == s->level_checksum[n]);
    mts_stream_client_free(&c);

    /* a resume with one form's stream_id asking for the other form: stale */
    const struct {
        uint32_t flags;
        uint64_t id;
    } stale[] = {{MTS_HELLO_RECORDS, s->stream_id}, {0, r->stream_id}};
    for (int i = 0; i < 2; i++) {
        mts_buf hs = {0}, rep = {0};
        hello_for(&hs, stale[i].flags, 5, stale[i].id);
        CHECK(t, exchange(sv.port, hs.data, hs.size, &rep, 5));
        CHECKF(t, error_code_of(&rep) == MTS_WERR_STALE, "case %d: code %u", i,
               error_code_of(&rep));
        mts_buf_free(&hs);
        mts_buf_free(&rep);
    }
    mts_buf_free(&h);
    mts_buf_free(&rest);
    mts_buf_free(&ra);
    mts_buf_free(&rb);
    stop_server(t, &sv);
}

/* A server without the records form answers a HELLO asking for records with
 * the splits form, which the client takes and completes; a resume asking
 * for records goes on in the splits form it was given. */
static void test_records_request_without_records_form(mts_test *t)
{
    served sv;
    mts_server_options o = {0};
    o.listen = "127.0.0.1:0";
    if (!start_server(t, &sv, &o))
        return;
    const mts_stream *s = &sv.stream;
    const uint32_t n = s->model.level_count;
    CHECK(t, s->records_form == NULL);
    mts_stream_client a;
    mts_buf ra = {0};
    fetch(t, sv.port, MTS_HELLO_RECORDS, &a, &ra);
    CHECK(t, !a.records && !(a.info.flags & MTS_INFO_RECORDS) && a.info.stream_id == s->stream_id);
    CHECK(t, a.lod.level == n && a.checksum == s->level_checksum[n]);
    mts_stream_client_free(&a);

    size_t info_size = 4 + ((size_t)ra.data[0] | (size_t)ra.data[1] << 8 |
                            (size_t)ra.data[2] << 16 | (size_t)ra.data[3] << 24);
    mts_stream_client c;
    mts_stream_client_init(&c);
    mts_error err = {0};
    int ended;
    CHECK(t, take_reply(&c, ra.data, info_size + s->batch_offset[5] + 7, &ended, &err) == MTS_OK);
    uint32_t batch;
    uint64_t id;
    CHECK(t, mts_stream_client_resume_point(&c, &batch, &id) && batch == 5 && id == s->stream_id);
    CHECK(t, mts_stream_client_reconnected(&c, &err) == MTS_OK);
    mts_buf h = {0}, rest = {0};
    hello_for(&h, MTS_HELLO_RECORDS, batch, id);
    CHECK(t, exchange(sv.port, h.data, h.size, &rest, 10));
    CHECKF(t, take_reply(&c, rest.data, rest.size, &ended, &err) == MTS_OK && ended, "code %u: %s",
           error_code_of(&rest), err.msg);
    CHECK(t, !c.records && c.resumes == 1 && c.lod.level == n &&
             c.checksum == s->level_checksum[n]);
    mts_stream_client_free(&c);
    mts_buf_free(&h);
    mts_buf_free(&rest);
    mts_buf_free(&ra);
    stop_server(t, &sv);
}

/* The server listens before its streams are encoded (mts-server does, so
 * that it is ready in seconds with large models): LIST names every model,
 * stream_bytes 0 for one being prepared; a HELLO for it waits and gets the
 * whole stream once a thread publishes it; one for a model that failed gets
 * ERROR internal with the reason; one for a model never ready in time gets
 * ERROR busy. Everyone else is served meanwhile. */
typedef struct publisher {
    mts_server_model *m;
    mts_stream *stream;
    double delay;
} publisher;

static void *publish_later(void *arg)
{
    publisher *p = arg;
    struct timespec d = {(time_t)p->delay, (long)((p->delay - (time_t)p->delay) * 1e9)};
    nanosleep(&d, NULL);
    mts_server_model_publish(p->m, p->stream);
    return NULL;
}

static void models_listed(void *user, const mts_wire_model_entry *e)
{
    mts_wire_model_entry *out = user;
    for (int i = 0; i < 3; i++) {
        if (!out[i].name[0]) {
            out[i] = *e;
            return;
        }
    }
}

static void test_models_being_prepared(mts_test *t)
{
    mts_error err = {0};
    mts_mesh mesh = {0};
    mts_model m;
    mts_stream st;
    CHECK(t, mts_mesh_load("tests/data/cow.off", NULL, &mesh, NULL, &err) == MTS_OK);
    CHECK(t, mts_build_model(&mesh, "cow", NULL, &m, NULL, &err) == MTS_OK);
    mts_mesh_free(&mesh);
    CHECK(t, mts_stream_build(&m, "cow", NULL, &st, &err) == MTS_OK);
    mts_server_model table[3];
    const char *names[3] = {"cow", "broken", "slow"};
    for (int i = 0; i < 3; i++)
        mts_server_model_init_preparing(&table[i], names[i], &m);
    mts_server_model_fail(&table[1], "its model file is damaged");
    mts_server_options o = {0};
    o.listen = "127.0.0.1:0";
    o.prepare_wait = 1.5;
    mts_server *server = NULL;
    CHECKF(t, mts_server_create_models(&o, table, 3, &server, &err) == MTS_OK, "%s", err.msg);
    if (!server)
        return;
    int port = mts_server_port(server);
    pid_t pid = fork();
    if (pid == 0) {
        signal(SIGTERM, on_term);
        publisher p = {&table[0], &st, 0.6};
        pthread_t th;
        pthread_create(&th, NULL, publish_later, &p);
        mts_result rc = mts_server_run(server, &stop_flag, &err);
        pthread_join(th, NULL);
        mts_server_free(server);
        _exit(rc == MTS_OK ? 0 : 3);
    }
    mts_server_free(server);

    /* LIST at once: all three, cow's stream not ready */
    mts_buf lb = {0}, lr = {0};
    mts_wire_put_list(&lb);
    CHECK(t, exchange(port, lb.data, lb.size, &lr, 5));
    mts_wire_model_entry listed[3];
    memset(listed, 0, sizeof listed);
    CHECKF(t, lr.size > 5 && lr.data[4] == MTS_MSG_MODELS &&
                  mts_wire_parse_models(lr.data + 5, lr.size - 5, models_listed, listed, &err) ==
                      MTS_OK,
           "%s", err.msg);
    CHECK(t, !strcmp(listed[0].name, "cow") && !strcmp(listed[1].name, "broken") &&
                 !strcmp(listed[2].name, "slow"));
    CHECK(t, listed[0].stream_bytes == 0 && listed[0].levels == m.level_count);

    /* cow: waits, then the whole stream */
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    mts_stream_client c;
    mts_buf reply = {0};
    mts_buf h = {0};
    hello_for(&h, 0, 0, 0);
    CHECK(t, exchange(port, h.data, h.size, &reply, 10));
    clock_gettime(CLOCK_MONOTONIC, &t1);
    double waited = (double)(t1.tv_sec - t0.tv_sec) + (t1.tv_nsec - t0.tv_nsec) * 1e-9;
    mts_stream_client_init(&c);
    int ended = 0;
    CHECKF(t, take_reply(&c, reply.data, reply.size, &ended, &err) == MTS_OK && ended, "%s",
           err.msg);
    CHECK(t, c.lod.level == m.level_count && c.checksum == st.level_checksum[m.level_count]);
    CHECKF(t, waited > 0.3 && waited < 5, "waited %.2f s", waited);
    mts_stream_client_free(&c);

    /* broken: the reason; slow: busy after prepare_wait */
    const struct {
        const char *model;
        uint16_t code;
        const char *needle;
    } refused[] = {{"broken", MTS_WERR_INTERNAL, "damaged"},
                   {"slow", MTS_WERR_BUSY, "still being prepared"}};
    for (int i = 0; i < 2; i++) {
        mts_buf hb = {0}, rb = {0};
        hello_bytes(&hb, refused[i].model, MTS_WIRE_MAJOR);
        CHECK(t, exchange(port, hb.data, hb.size, &rb, 10));
        CHECKF(t, error_code_of(&rb) == refused[i].code, "%s: code %u", refused[i].model,
               error_code_of(&rb));
        uint16_t code;
        char text[256] = "";
        if (rb.size > 5)
            mts_wire_parse_error(rb.data + 5, rb.size - 5, &code, text, sizeof text, &err);
        CHECKF(t, strstr(text, refused[i].needle) != NULL, "%s: '%s'", refused[i].model, text);
        mts_buf_free(&hb);
        mts_buf_free(&rb);
    }
    kill(pid, SIGTERM);
    int status = 0;
    waitpid(pid, &status, 0);
    CHECKF(t, WIFEXITED(status) && WEXITSTATUS(status) == 0, "server exit status %d", status);
    mts_buf_free(&lb);
    mts_buf_free(&lr);
    mts_buf_free(&h);
    mts_buf_free(&reply);
    mts_stream_free(&st);
    mts_model_free(&m);
}

typedef struct records_publisher {
    mts_server_model *m;
    const mts_stream *records; /* NULL: none will come */
    double delay;
} records_publisher;

static void *publish_records_later(void *arg)
{
    records_publisher *p = arg;
    struct timespec d = {(time_t)p->delay, (long)((p->delay - (time_t)p->delay) * 1e9)};
    nanosleep(&d, NULL);
    mts_server_model_publish_records(p->m, p->records);
    return NULL;
}

/* mts-server publishes a model's splits form first and its records form when
 * that is encoded. A client that resumes the records form (a server killed
 * and restarted under it) waits for it: the splits form, another stream, would
 * send it back to the start. A fresh request for records takes the splits
 * form at once; where no records form comes, the resume is stale. */
static void test_records_form_published_later(mts_test *t)
{
    mts_error err = {0};
    mts_mesh mesh = {0};
    mts_model m;
    mts_stream st;
    mts_stream_options so = {0};
    so.with_records = 1;
    CHECK(t, mts_mesh_load("tests/data/cow.off", NULL, &mesh, NULL, &err) == MTS_OK);
    CHECK(t, mts_build_model(&mesh, "cow", NULL, &m, NULL, &err) == MTS_OK);
    mts_mesh_free(&mesh);
    CHECK(t, mts_stream_build(&m, "cow", &so, &st, &err) == MTS_OK);
    const mts_stream *r = st.records_form;
    CHECK(t, r != NULL && st.batch_count > 6);
    if (!r || st.batch_count <= 6) {
        mts_stream_free(&st);
        mts_model_free(&m);
        return;
    }
    mts_server_model table[2];
    mts_server_model_init_preparing(&table[0], "cow", &m);
    mts_server_model_init_preparing(&table[1], "none", &m);
    mts_server_model_publish(&table[0], &st);
    mts_server_model_publish(&table[1], &st);
    mts_server_options o = {0};
    o.listen = "127.0.0.1:0";
    o.prepare_wait = 5;
    mts_server *server = NULL;
    CHECKF(t, mts_server_create_models(&o, table, 2, &server, &err) == MTS_OK, "%s", err.msg);
    if (!server)
        return;
    int port = mts_server_port(server);
    pid_t pid = fork();
    if (pid == 0) {
        signal(SIGTERM, on_term);
        records_publisher p[2] = {{&table[0], r, 1.0}, {&table[1], NULL, 1.0}};
        pthread_t th[2];
        for (int i = 0; i < 2; i++)
            pthread_create(&th[i], NULL, publish_records_later, &p[i]);
        mts_result rc = mts_server_run(server, &stop_flag, &err);
        for (int i = 0; i < 2; i++)
            pthread_join(th[i], NULL);
        mts_server_free(server);
        _exit(rc == MTS_OK ? 0 : 3);
    }
    mts_server_free(server);

    /* a fresh request for records, before they are ready: the splits form */
    mts_stream_client a;
    mts_buf ra = {0};
    fetch(t, port, MTS_HELLO_RECORDS, &a, &ra);
    CHECK(t, !a.records && a.info.stream_id == st.stream_id);
    CHECK(t, a.lod.level == m.level_count && a.checksum == st.level_checksum[m.level_count]);
    mts_stream_client_free(&a);

    /* resumes of the records form at batch 5, asked for at once: cow's waits
     * for its records form and goes on in it; none's is stale once the server
     * knows that no records form will come */
    const char *models[2] = {"cow", "none"};
    for (int i = 0; i < 2; i++) {
        mts_wire_hello h = {0};
        h.major = MTS_WIRE_MAJOR;
        h.minor = MTS_WIRE_MINOR;
        snprintf(h.model, sizeof h.model, "%s", models[i]);
        h.resume_batch = 5;
        h.stream_id = r->stream_id;
        h.flags = MTS_HELLO_RECORDS;
        mts_buf hb = {0}, rep = {0};
        mts_wire_put_hello(&hb, &h);
        CHECK(t, exchange(port, hb.data, hb.size, &rep, 10));
        if (i == 0) {
            mts_wire_model_info mi = {0};
            CHECKF(t, rep.size > 5 && rep.data[4] == MTS_MSG_MODEL_INFO, "cow: code %u",
                   error_code_of(&rep));
            size_t n = rep.size > 5 ? (size_t)(rep.data[0] | rep.data[1] << 8 |
                                               rep.data[2] << 16 | (size_t)rep.data[3] << 24)
                                    : 0;
            CHECKF(t, n >= 1 && n + 4 <= rep.size &&
                          mts_wire_parse_model_info(rep.data + 5, n - 1, &mi, &err) == MTS_OK &&
                          mi.stream_id == r->stream_id && (mi.flags & MTS_INFO_RECORDS),
                   "cow: not resumed in the records form: %s", err.msg);
            mts_wire_model_info_free(&mi);
            /* from batch 5 on: no BASE, no batch sent twice */
            CHECKF(t, rep.size < r->size - r->batch_offset[5] + 4096, "resumed reply %zu bytes",
                   rep.size);
        } else {
            CHECKF(t, error_code_of(&rep) == MTS_WERR_STALE, "none: code %u",
                   error_code_of(&rep));
        }
        mts_buf_free(&hb);
        mts_buf_free(&rep);
    }
    kill(pid, SIGTERM);
    int status = 0;
    waitpid(pid, &status, 0);
    CHECKF(t, WIFEXITED(status) && WEXITSTATUS(status) == 0, "server exit status %d", status);
    mts_buf_free(&ra);
    mts_stream_free(&st);
    mts_model_free(&m);
}

int main(void)
{
    signal(SIGPIPE, SIG_IGN);
    mts_test t = {0};
    RUN(&t, test_good_client_beside_bad_ones);
    RUN(&t, test_busy);
    RUN(&t, test_half_closed_slow_reader);
    RUN(&t, test_out_of_descriptors);
    RUN(&t, test_refusal_survives_extra_bytes);
    RUN(&t, test_records_form_on_request);
    RUN(&t, test_records_request_without_records_form);
    RUN(&t, test_models_being_prepared);
    RUN(&t, test_records_form_published_later);
    return mts_test_end(&t);
}
