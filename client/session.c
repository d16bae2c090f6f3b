#include "session.h"

#include <errno.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

static double now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

/* Non-blocking connect bounded by a timeout, over every address the name has. */
/* *transient: whether trying again later can help (a name that does not
 * resolve will not, unless the resolver itself failed for now). */
static int connect_bounded(const char *host, const char *port, double timeout, int *transient,
                           mts_error *err)
{
    struct addrinfo hints = {0}, *res = NULL;
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    int gai = getaddrinfo(host, port, &hints, &res);
    if (gai != 0) {
        *transient = gai == EAI_AGAIN;
        mts_error_set(err, MTS_ERR_IO, "%s:%s: %s", host, port, gai_strerror(gai));
        return -1;
    }
    *transient = 1;
    int fd = -1, last = 0;
    for (struct addrinfo *a = res; a; a = a->ai_next) {
        fd = socket(a->ai_family, a->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
        if (fd < 0) {
            last = errno;
            continue;
        }
        if (connect(fd, a->ai_addr, a->ai_addrlen) == 0)
            break;
        if (errno == EINPROGRESS) {
            struct pollfd pf = {fd, POLLOUT, 0};
            int soerr = 0;
            socklen_t sl = sizeof soerr;
            int pr;
            do
                pr = poll(&pf, 1, (int)(timeout * 1000));
            while (pr < 0 && errno == EINTR);
            if (pr == 1 && getsockopt(fd, SOL_SOCKET, SO_ERROR, &soerr, &sl) == 0 && soerr == 0)
                break;
            last = soerr ? soerr : ETIMEDOUT;
        } else {
            last = errno;
        }
        close(fd);
        fd = -1;
    }
    freeaddrinfo(res);
    if (fd < 0)
        mts_error_set(err, MTS_ERR_IO, "cannot connect to %s:%s: %s", host, port, strerror(last));
    return fd;
}

static mts_result send_all(int fd, const uint8_t *p, size_t n, double timeout, mts_error *err)
{
    while (n > 0) {
        ssize_t w = send(fd, p, n, MSG_NOSIGNAL);
        if (w > 0) {
            p += w;
            n -= (size_t)w;
            continue;
        }
        if (w < 0 && errno == EINTR)
            continue;
        if (w < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
            struct pollfd pf = {fd, POLLOUT, 0};
            if (poll(&pf, 1, (int)(timeout * 1000)) == 1)
                continue;
            return mts_error_set(err, MTS_ERR_IO, "sending the request timed out");
        }
        return mts_error_set(err, MTS_ERR_IO, "sending the request: %s", strerror(errno));
    }
    return MTS_OK;
}

/* Where a session stands between conversations. */
typedef struct session {
    const mts_session_options *o;
    const char *host, *port;
    double cto, ito;
    double t0;
    mts_stream_client *c;
    mts_session_stats *st;
    uint32_t connections; /* made so far */
} session;

/* One connection: connect, send the request, take frames until END, an
 * ERROR, or a failure. *transient says whether a failure is the
 * connection's (worth a new one); *progress whether anything was applied. */
static mts_result converse(session *s, const mts_wire_hello *hello, int *transient,
                           int *progress, mts_error *err)
{
    const mts_session_options *o = s->o;
    mts_stream_client *c = s->c;
    mts_session_stats *st = s->st;
    *transient = 0;
    *progress = 0;
    int fd = connect_bounded(s->host, s->port, s->cto, transient, err);
    if (fd < 0)
        return err->code;
    int one = 1;
    setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    if (s->connections++ == 0)
        st->ms_connect = now_ms() - s->t0;
    else
        st->reconnects++;

    mts_buf req = {0};
    if (o->list)
        mts_wire_put_list(&req);
    else
        mts_wire_put_hello(&req, hello);
    mts_result rc = req.failed ? mts_error_set(err, MTS_ERR_NOMEM, "out of memory")
                               : send_all(fd, req.data, req.size, s->ito, err);
    mts_buf_free(&req);
    *transient = rc == MTS_ERR_IO;
    /* a reader per connection: a frame cut by the break is dropped with it */
    mts_wire_reader r = {0};
    static const size_t chunk = 1 << 16;
    uint8_t *buf = rc == MTS_OK ? malloc(chunk) : NULL;
    if (rc == MTS_OK && !buf)
        rc = mts_error_set(err, MTS_ERR_NOMEM, "out of memory");
    int done = 0;
    while (rc == MTS_OK && !done) {
        struct pollfd pf = {fd, POLLIN, 0};
        int pr = poll(&pf, 1, (int)(s->ito * 1000));
        if (pr == 0) {
            rc = mts_error_set(err, MTS_ERR_IO, "no data from the server for %.0f s", s->ito);
            *transient = 1;
            break;
        }
        if (pr < 0) {
            if (errno == EINTR)
                continue;
            rc = mts_error_set(err, MTS_ERR_IO, "poll: %s", strerror(errno));
            break;
        }
        ssize_t got = recv(fd, buf, chunk, 0);
        if (got == 0) {
            rc = mts_error_set(err, MTS_ERR_IO,
                               "the server closed the connection mid-stream (after %llu bytes, "
                               "%u batches applied)",
                               (unsigned long long)st->bytes, c->batches);
            *transient = 1;
            break;
        }
        if (got < 0) {
            if (errno == EINTR || errno == EAGAIN || errno == EWOULDBLOCK)
                continue;
            rc = mts_error_set(err, MTS_ERR_IO, "connection lost after %llu bytes (%s)",
                               (unsigned long long)st->bytes, strerror(errno));
            *transient = 1;
            break;
        }
        st->bytes += (uint64_t)got;
        if ((rc = mts_wire_reader_feed(&r, buf, (size_t)got, err)) != MTS_OK)
            break;
        uint8_t type;
        const uint8_t *p;
        size_t n;
        int next;
        while (rc == MTS_OK && !done && (next = mts_wire_reader_next(&r, &type, &p, &n, err)) != 0) {
            if (next < 0) {
                rc = err->code;
                break;
            }
            double a = now_ms();
            mts_stream_event ev;
            rc = mts_stream_client_frame(c, type, p, n, &ev, err);
            st->ms_apply += now_ms() - a;
            st->frames++;
            if (rc != MTS_OK)
                break;
            if (ev == MTS_EV_BASE || ev == MTS_EV_BATCH || ev == MTS_EV_END)
                *progress = 1;
            if (o->on_event && o->on_event(o->user, ev, c)) {
                rc = mts_error_set(err, MTS_ERR_ARG, "stopped by the caller");
                break;
            }
            double t = now_ms() - s->t0;
            if (ev == MTS_EV_INFO)
                st->ms_info = t;
            else if (ev == MTS_EV_BASE)
                st->ms_base = t;
            else if (ev == MTS_EV_END || ev == MTS_EV_MODELS) {
                st->ms_final = t;
                done = 1;
            } else if (ev == MTS_EV_ERROR) {
                rc = mts_error_set(err, MTS_ERR_FORMAT, "the server said: %s (%s)", c->error_text,
                                   mts_wire_error_name(c->error_code));
                if (c->error_code == MTS_WERR_STALE)
                    mts_error_prefix(err, "cannot resume at batch %u: the server's stream "
                                          "changed since",
                                     c->batches);
                done = 1;
            }
        }
    }
    free(buf);
    mts_wire_reader_free(&r);
    close(fd);
    return rc;
}

/* A sleep that signals do not cut short. */
static void sleep_s(double seconds)
{
    struct timespec ts = {(time_t)seconds, (long)((seconds - (double)(time_t)seconds) * 1e9)};
    while (nanosleep(&ts, &ts) != 0 && errno == EINTR)
        ;
}

/* xorshift64*: jitter needs no quality, only clients that do not all come
 * back at the same moment after a server restart */
static double next_unit(uint64_t *state)
{
    uint64_t x = *state;
    x ^= x >> 12;
    x ^= x << 25;
    x ^= x >> 27;
    *state = x;
    return (double)((x * 0x2545f4914f6cdd1dull) >> 11) / 9007199254740992.0;
}

mts_result mts_session_run(const mts_session_options *o, mts_stream_client *c,
                           mts_session_stats *st, mts_error *err)
{
    mts_error local = {0};
    if (!err) /* the retry logic reads the message */
        err = &local;
    memset(st, 0, sizeof *st);
    session s = {o, o->host ? o->host : "127.0.0.1", o->port ? o->port : "7447",
                 o->connect_timeout > 0 ? o->connect_timeout : 5,
                 o->io_timeout > 0 ? o->io_timeout : 30, now_ms(), c, st, 0};
    const uint32_t max_tries = o->max_tries ? o->max_tries : 8;
    const double b0 = o->backoff_initial > 0 ? o->backoff_initial : 0.1;
    const double bmax = o->backoff_max > 0 ? o->backoff_max : 2;
    struct timespec seed_ts;
    clock_gettime(CLOCK_REALTIME, &seed_ts);
    uint64_t rng = ((uint64_t)seed_ts.tv_nsec << 20) ^ (uint64_t)seed_ts.tv_sec ^
                   ((uint64_t)getpid() << 40) ^ (uint64_t)(uintptr_t)c;
    if (rng == 0)
        rng = 1;

    mts_wire_hello hello = o->hello;
    if (hello.major == 0) {
        hello.major = MTS_WIRE_MAJOR;
        hello.minor = MTS_WIRE_MINOR;
    }
    uint32_t tries = 0; /* failed tries since the last progress */
    for (;;) {
        int transient, progress;
        mts_result rc = converse(&s, &hello, &transient, &progress, err);
        if (rc == MTS_OK || !o->resume || !transient)
            return rc;
        uint32_t batch;
        uint64_t id;
        if (!mts_stream_client_resume_point(c, &batch, &id))
            return rc;
        if (progress)
            tries = 0;
        if (tries >= max_tries)
            return mts_error_prefix(err, "gave up after %u %s (%u batches applied); the last "
                                         "error",
                                    max_tries, max_tries == 1 ? "try" : "tries", c->batches);
        tries++;
        double d = b0;
        for (uint32_t k = 1; k < tries && d < bmax; k++)
            d *= 2;
        if (d > bmax)
            d = bmax;
        /* "equal jitter": at least half the step, so the backoff still grows */
        d *= 0.5 + 0.5 * next_unit(&rng);
        mts_session_retry r = {err->msg, c->have_lod, c->batches, tries, max_tries, d};
        if (o->on_retry && o->on_retry(o->user, &r))
            return mts_error_prefix(err, "stopped by the caller while retrying");
        sleep_s(d);
        if ((rc = mts_stream_client_reconnected(c, err)) != MTS_OK)
            return rc;
        hello.resume_batch = batch;
        hello.stream_id = id;
    }
}
