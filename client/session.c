#include "session.h"

#include <errno.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "clock.h"
#include "net.h"
#include "tls.h"
#include "webfile.h"

/* Connecting runs as steps so that a window loop never waits on it: the
 * name is resolved (getaddrinfo blocks, but a numeric address or
 * /etc/hosts answers at once), then each address gets a non-blocking
 * connect that poll watches, bounded by the connect timeout. */
typedef struct connector {
    struct addrinfo *res, *cur;
    int fd;           /* the socket connecting now, or -1 */
    double deadline;  /* ms: when this address gives up */
    int last;         /* errno of the last failed address */
} connector;

static void connector_close(connector *k)
{
    if (k->fd >= 0)
        close(k->fd);
    k->fd = -1;
    if (k->res)
        freeaddrinfo(k->res);
    k->res = k->cur = NULL;
}

/* *transient: whether trying again later can help (a name that does not
 * resolve will not, unless the resolver itself failed for now). */
static mts_result connector_start(connector *k, const char *host, const char *port,
                                  int *transient, mts_error *err)
{
    k->fd = -1;
    k->last = 0;
    k->res = k->cur = NULL;
    mts_result rc = mts_net_resolve(host, port, 0, &k->res, transient, err);
    k->cur = k->res;
    return rc;
}

/* Moves the connect on: 1 connected (k->fd is the socket, owned by the
 * caller from then on), 0 still connecting, -1 every address failed (err
 * set). Waits at most timeout_ms (-1: until this address is decided). */
static int connector_step(connector *k, const char *host, const char *port, double cto,
                          int timeout_ms, mts_error *err)
{
    for (;;) {
        if (k->fd < 0) {
            if (!k->cur) {
                mts_error_set(err, MTS_ERR_IO, "cannot connect to %s:%s: %s", host, port,
                              strerror(k->last));
                connector_close(k);
                return -1;
            }
            struct addrinfo *a = k->cur;
            k->cur = a->ai_next;
            int started = mts_net_connect_start(a, &k->fd, &k->last);
            if (started < 0)
                continue;
            if (started > 0)
                goto connected;
            k->deadline = (1e3 * mts_clock_seconds()) + cto * 1000;
        }
        double left = k->deadline - (1e3 * mts_clock_seconds());
        int wait = left > 0 ? (int)left + 1 : 0;
        if (timeout_ms >= 0 && timeout_ms < wait)
            wait = timeout_ms;
        struct pollfd pf = {k->fd, POLLOUT, 0};
        int pr = poll(&pf, 1, wait);
        if (pr < 0 && errno == EINTR)
            return 0;
        if (pr == 1) {
            int soerr = mts_net_connect_result(k->fd);
            if (soerr == 0)
                goto connected;
            k->last = soerr;
        } else if ((1e3 * mts_clock_seconds()) < k->deadline) {
            return 0; /* the caller's wait ran out first */
        } else {
            k->last = ETIMEDOUT;
        }
        close(k->fd);
        k->fd = -1;
    }
connected:;
    int fd = k->fd;
    k->fd = -1;
    connector_close(k);
    k->fd = fd;
    return 1;
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

/* Where a session stands: one conversation at a time, or the wait before
 * the next one. Every step below returns to the caller within the poll's
 * timeout plus one bounded slice of work, so a window loop can draw between
 * steps; mts_session_run simply polls until the end. */
typedef enum phase {
    PH_CONNECT,    /* resolve and start connecting */
    PH_CONNECTING, /* a non-blocking connect under way */
    PH_STREAM,     /* connected, request sent: frames coming */
    PH_WAIT,       /* resume: backing off before the next try */
    PH_DONE
} phase;

struct mts_session {
    const mts_session_options *o;
    const char *host, *port;
    double cto, ito, max_ms;
    double t0;
    mts_stream_client *c;
    mts_session_stats *st;
    uint32_t connections; /* made so far */
    mts_wire_hello hello;
    uint32_t max_tries, tries; /* tries: failed tries since the last progress */
    double b0, bmax;
    uint64_t rng;
    phase ph;
    connector k;
    int fd;               /* the connection in PH_STREAM */
    mts_tls *tls;         /* its TLS (owns fd), when the options ask for TLS */
    int tls_pending;      /* TLS may hold decrypted bytes: read before waiting */
    uint8_t *buf;
    double last_data;     /* ms: the last byte (or the connect), for io_timeout */
    int progress;         /* this conversation applied something */
    int backlog;          /* the client may hold whole frames not yet taken */
    /* a read between frames found the connection closed (1) or broken (2,
     * held_why): the conversation ends so once the frames held before it
     * are taken */
    int held;
    char held_why[sizeof(((mts_error *)0)->msg)];
    double retry_at;      /* ms, PH_WAIT */
    mts_result result;    /* PH_DONE */
    mts_error err;
};

#define SESSION_CHUNK (1 << 16)
/* bytes held ahead of the frame being taken, where two threads decode */
#define SESSION_AHEAD (1 << 18)
/* ms of decoding and applying per poll before the caller gets control back */
#define SESSION_SLICE_MS 8.0

static void close_conversation(mts_session *s)
{
    if (s->o->file)
        mts_webfile_cancel(s->o->file);
    connector_close(&s->k);
    if (s->tls)
        mts_tls_free(s->tls); /* and its socket */
    else if (s->fd >= 0)
        close(s->fd);
    s->tls = NULL;
    s->tls_pending = 0;
    s->held = 0;
    s->fd = -1;
    free(s->buf);
    s->buf = NULL;
}

static void finish(mts_session *s, mts_result rc)
{
    close_conversation(s);
    s->result = rc;
    s->ph = PH_DONE;
}

/* A conversation ended with rc (not MTS_OK): give up, or wait and resume.
 * transient says whether the failure is the connection's (worth a new one). */
static void conversation_failed(mts_session *s, mts_result rc, int transient)
{
    const mts_session_options *o = s->o;
    mts_stream_client *c = s->c;
    mts_error *err = &s->err;
    close_conversation(s);
    if (!o->resume || !transient) {
        finish(s, rc);
        return;
    }
    uint32_t batch;
    uint64_t id;
    if (!mts_stream_client_resume_point(c, &batch, &id)) {
        finish(s, rc);
        return;
    }
    if (s->progress)
        s->tries = 0;
    if (s->tries >= s->max_tries) {
        finish(s, mts_error_prefix(err, "gave up after %u %s (%u batches applied); the last "
                                        "error",
                                   s->max_tries, s->max_tries == 1 ? "try" : "tries",
                                   c->batches));
        return;
    }
    s->tries++;
    double d = s->b0;
    for (uint32_t k = 1; k < s->tries && d < s->bmax; k++)
        d *= 2;
    if (d > s->bmax)
        d = s->bmax;
    /* "equal jitter": at least half the step, so the backoff still grows */
    d *= 0.5 + 0.5 * next_unit(&s->rng);
    mts_session_retry r = {err->msg, c->have_lod, c->batches, s->tries, s->max_tries, d};
    if (o->on_retry && o->on_retry(o->user, &r)) {
        finish(s, mts_error_prefix(err, "stopped by the caller while retrying"));
        return;
    }
    s->retry_at = (1e3 * mts_clock_seconds()) + d * 1000;
    s->ph = PH_WAIT;
}

/* Connected: send the request, get ready for frames. */
static void connected(mts_session *s, int fd)
{
    const mts_session_options *o = s->o;
    mts_error *err = &s->err;
    s->fd = fd;
    s->k.fd = -1;
    if (s->connections++ == 0)
        s->st->ms_connect = (1e3 * mts_clock_seconds()) - s->t0;
    else
        s->st->reconnects++;
    mts_buf req = {0};
    if (o->list)
        mts_wire_put_list(&req);
    else
        mts_wire_put_hello(&req, &s->hello);
    /* a request is a few hundred bytes: the socket buffer takes it at once */
    mts_result rc = req.failed ? mts_error_set(err, MTS_ERR_NOMEM, "out of memory")
                     : s->tls  ? mts_tls_send_all(s->tls, req.data, req.size, s->ito, err)
                               : send_all(fd, req.data, req.size, s->ito, err);
    mts_buf_free(&req);
    if (rc == MTS_OK && !(s->buf = malloc(SESSION_CHUNK)))
        rc = mts_error_set(err, MTS_ERR_NOMEM, "out of memory");
    if (rc != MTS_OK) {
        conversation_failed(s, rc, rc == MTS_ERR_IO);
        return;
    }
    s->last_data = (1e3 * mts_clock_seconds());
    s->ph = PH_STREAM;
}

/* One event of the stream client: the caller's callback, the times, and
 * the end of the conversation on END, MODELS or ERROR. 1: go on, 0: the
 * conversation ended (s->ph moved on). */
static int take_event(mts_session *s, mts_stream_event ev)
{
    const mts_session_options *o = s->o;
    mts_stream_client *c = s->c;
    mts_session_stats *st = s->st;
    mts_error *err = &s->err;
    if (ev == MTS_EV_BASE || ev == MTS_EV_BATCH || ev == MTS_EV_END)
        s->progress = 1;
    if (o->on_event && o->on_event(o->user, ev, c)) {
        conversation_failed(s, mts_error_set(err, MTS_ERR_ARG, "stopped by the caller"), 0);
        return 0;
    }
    double t = (1e3 * mts_clock_seconds()) - s->t0;
    if (ev == MTS_EV_INFO && !o->file && strcmp(c->info.model, s->hello.model) != 0) {
        /* a stream of another model is no answer to this HELLO (names
         * are checked as [A-Za-z0-9._-] when parsed); a stream file is
         * named by its URL, not by the model in it */
        mts_result rc = mts_error_set(err, MTS_ERR_FORMAT,
                                      "MODEL_INFO is for model '%s', not the '%s' asked for",
                                      c->info.model, s->hello.model);
        conversation_failed(s, rc, 0);
        return 0;
    }
    if (ev == MTS_EV_INFO) {
        st->ms_info = t;
    } else if (ev == MTS_EV_BASE) {
        st->ms_base = t;
    } else if (ev == MTS_EV_END || ev == MTS_EV_MODELS) {
        st->ms_final = t;
        finish(s, MTS_OK);
        return 0;
    } else if (ev == MTS_EV_ERROR) {
        mts_result rc = mts_error_set(err, MTS_ERR_FORMAT, "the server said: %s (%s)",
                                      c->error_text, mts_wire_error_name(c->error_code));
        if (c->error_code == MTS_WERR_STALE)
            mts_error_prefix(err, "cannot resume at batch %u: the server's stream "
                                  "changed since",
                             c->batches);
        conversation_failed(s, rc, 0);
        return 0;
    }
    return 1;
}

/* The conversation's end where the connection closed (closed) or broke
 * (why), in s->err: what came and what was applied by then. */
static mts_result broken(mts_session *s, int closed, const char *why)
{
    const unsigned long long bytes = (unsigned long long)s->st->bytes;
    if (!closed && s->o->list)
        return mts_error_set(&s->err, MTS_ERR_IO, "connection lost after %llu bytes (%s)", bytes,
                             why);
    if (!closed)
        return mts_error_set(&s->err, MTS_ERR_IO,
                             "connection lost after %llu bytes, %u batches applied (%s)", bytes,
                             s->c->batches, why);
    if (s->o->list)
        return mts_error_set(&s->err, MTS_ERR_IO,
                             "the server closed the connection before the model list was whole "
                             "(after %llu bytes)",
                             bytes);
    return mts_error_set(&s->err, MTS_ERR_IO,
                         "the server closed the connection mid-stream (after %llu bytes, %u "
                         "batches applied)",
                         bytes, s->c->batches);
}

/* One read of what the socket (or TLS) holds, fed to the stream client.
 * 1: bytes fed; 0: none there yet; -1: the conversation ended (s->ph moved
 * on). Between frames (between) a closed or broken connection ends it only
 * once the frames held are taken (s->held): those came before. */
static int read_some(mts_session *s, int between)
{
    mts_error e = {0};
    ssize_t got = s->tls ? mts_tls_read(s->tls, s->buf, SESSION_CHUNK, &e)
                         : mts_net_read(s->fd, s->buf, SESSION_CHUNK);
    s->tls_pending = s->tls && got > 0;
    if (got == MTS_NET_AGAIN)
        return 0;
    if (got <= 0) {
        char why[sizeof e.msg];
        snprintf(why, sizeof why, "%s", got == 0 ? "" : s->tls ? e.msg : strerror(errno));
        if (between) {
            s->held = got == 0 ? 1 : 2;
            snprintf(s->held_why, sizeof s->held_why, "%s", why);
            return 0;
        }
        conversation_failed(s, broken(s, got == 0, why), 1);
        return -1;
    }
    s->last_data = (1e3 * mts_clock_seconds());
    s->st->bytes += (uint64_t)got;
    mts_result rc = mts_stream_client_feed(s->c, s->buf, (size_t)got, &s->err);
    if (rc != MTS_OK) {
        conversation_failed(s, rc, 0);
        return -1;
    }
    return 1;
}

/* Two threads decode the batches held whole while a batch's records are
 * made, and a batch returns only once they are; with the last whole frame
 * in hand that wait is idle, and the bytes that came meanwhile sit in the
 * socket (or libcurl) until the frames are taken. So where two threads
 * decode, the bytes that are there come in before each frame, up to
 * SESSION_AHEAD held. 0: the conversation ended (s->ph moved on). */
static int top_up(mts_session *s)
{
    mts_stream_client *c = s->c;
    mts_webfile *wf = s->o->file;
    while (!s->held && mts_stream_client_threads_used(c) > 1 && !c->threads_alone_from &&
           mts_stream_client_buffered(c) < SESSION_AHEAD) {
        if (wf) { /* a failure here is the file's result, read after the frames */
            const uint64_t before = mts_webfile_bytes(wf);
            const int going = mts_webfile_poll(wf, c, 0);
            s->st->bytes += mts_webfile_bytes(wf) - before;
            if (!going || mts_webfile_bytes(wf) == before)
                break;
            continue;
        }
        int r = read_some(s, 1);
        if (r <= 0)
            return r == 0;
    }
    return 1;
}

/* Takes the whole frames the stream client holds until the deadline (ms;
 * the rest wait in it: s->backlog). A new conversation starts with
 * mts_stream_client_reconnected, which drops a frame cut by the break.
 * 1: go on, 0: the conversation ended (s->ph moved on). */
static int take_frames(mts_session *s, double deadline)
{
    mts_stream_client *c = s->c;
    mts_session_stats *st = s->st;
    mts_error *err = &s->err;
    s->backlog = 0;
    for (;;) {
        if (!top_up(s))
            return 0;
        size_t before = mts_stream_client_buffered(c);
        double a = (1e3 * mts_clock_seconds());
        mts_stream_event ev;
        int next = mts_stream_client_next(c, &ev, err);
        if (next == 0)
            break;
        st->ms_apply += (1e3 * mts_clock_seconds()) - a;
        /* a frame was taken unless its header was refused */
        st->frames += mts_stream_client_buffered(c) < before;
        if (next < 0) {
            /* a frame that failed its CRC was rejected whole: a resume asks
             * for it again; anything else would fail again */
            conversation_failed(s, err->code, c->rejected);
            return 0;
        }
        if (!take_event(s, ev))
            return 0;
        if ((1e3 * mts_clock_seconds()) >= deadline) {
            s->backlog = 1; /* more frames may be whole already: the next poll */
            break;
        }
    }
    return 1;
}

/* Ends the conversation with the break a read between frames found, once
 * the frames held before it are taken (no backlog). 1: ended. */
static int held_end(mts_session *s)
{
    if (!s->held || s->backlog)
        return 0;
    conversation_failed(s, broken(s, s->held == 1, s->held_why), 1);
    return 1;
}

/* Waits up to timeout_ms for bytes (never past io_timeout), then reads and
 * applies what is there for at most one slice. */
static void stream_step(mts_session *s, int timeout_ms)
{
    mts_error *err = &s->err;
    const double deadline = (1e3 * mts_clock_seconds()) + SESSION_SLICE_MS;
    if (s->backlog) {
        /* frames already here come first, and there is no waiting then */
        if (!take_frames(s, deadline) || s->backlog)
            return;
        timeout_ms = 0;
    }
    if (held_end(s))
        return;
    double idle_left = s->last_data + s->ito * 1000 - (1e3 * mts_clock_seconds());
    int wait = idle_left > 0 ? (int)idle_left + 1 : 0;
    if (timeout_ms >= 0 && timeout_ms < wait)
        wait = timeout_ms;
    struct pollfd pf = {s->fd, POLLIN, 0};
    /* bytes TLS already decrypted wake no poll */
    int pr = s->tls_pending ? 1 : poll(&pf, 1, wait);
    if (pr < 0) {
        if (errno != EINTR)
            conversation_failed(s, mts_error_set(err, MTS_ERR_IO, "poll: %s", strerror(errno)),
                                0);
        return;
    }
    if (pr == 0) {
        /* a listing has no END nor batches: its messages speak of the list */
        if ((1e3 * mts_clock_seconds()) - s->last_data >= s->ito * 1000)
            conversation_failed(s,
                                s->o->list
                                    ? mts_error_set(err, MTS_ERR_IO,
                                                    "the server stopped sending the model list "
                                                    "(no data for %g s)",
                                                    s->ito)
                                    : mts_error_set(err, MTS_ERR_IO,
                                                    "no data from the server for %.0f s", s->ito),
                                1);
        return;
    }
    do {
        if (held_end(s) || read_some(s, 0) <= 0 || !take_frames(s, deadline))
            return;
    } while ((1e3 * mts_clock_seconds()) < deadline && !s->backlog);
}

/* A conversation with a stream file: what came is handed on as in
 * stream_step, and once the range is in and its frames are taken the file's
 * checks end the stream as END would. */
static void file_step(mts_session *s, int timeout_ms)
{
    mts_webfile *wf = s->o->file;
    mts_error *err = &s->err;
    const double deadline = (1e3 * mts_clock_seconds()) + SESSION_SLICE_MS;
    if (s->backlog) {
        if (!take_frames(s, deadline) || s->backlog)
            return;
        timeout_ms = 0;
    }
    const uint64_t before = mts_webfile_bytes(wf);
    int going = mts_webfile_poll(wf, s->c, timeout_ms);
    s->st->bytes += mts_webfile_bytes(wf) - before;
    if (!take_frames(s, deadline) || s->backlog)
        return;
    if (going)
        return;
    mts_result rc = mts_webfile_result(wf, err);
    if (rc != MTS_OK) {
        /* a cut, a timeout or a server down is worth a new conversation; a
         * 404, a damaged file or a refused certificate is not */
        conversation_failed(s, rc, rc == MTS_ERR_IO || s->c->rejected);
        return;
    }
    mts_stream_event ev;
    if ((rc = mts_webfile_end(wf, s->c, &ev, err)) != MTS_OK) {
        conversation_failed(s, rc, 0);
        return;
    }
    take_event(s, ev);
}

mts_result mts_session_begin(const mts_session_options *o, mts_stream_client *c,
                             mts_session_stats *st, mts_session **out, mts_error *err)
{
    *out = NULL;
    mts_session *s = calloc(1, sizeof *s);
    if (!s)
        return mts_error_set(err, MTS_ERR_NOMEM, "out of memory");
    memset(st, 0, sizeof *st);
    s->o = o;
    s->host = o->host ? o->host : "127.0.0.1";
    s->port = o->port ? o->port : "7447";
    s->cto = o->connect_timeout > 0 ? o->connect_timeout : 5;
    s->ito = o->io_timeout > 0 ? o->io_timeout : 30;
    s->max_ms = (o->max_time > 0 ? o->max_time : 600) * 1000;
    s->t0 = (1e3 * mts_clock_seconds());
    s->c = c;
    s->st = st;
    s->max_tries = o->max_tries ? o->max_tries : 8;
    s->b0 = o->backoff_initial > 0 ? o->backoff_initial : 0.1;
    s->bmax = o->backoff_max > 0 ? o->backoff_max : 2;
    struct timespec seed_ts;
    clock_gettime(CLOCK_REALTIME, &seed_ts);
    s->rng = ((uint64_t)seed_ts.tv_nsec << 20) ^ (uint64_t)seed_ts.tv_sec ^
             ((uint64_t)getpid() << 40) ^ (uint64_t)(uintptr_t)c;
    if (s->rng == 0)
        s->rng = 1;
    s->hello = o->hello;
    if (s->hello.major == 0) {
        s->hello.major = MTS_WIRE_MAJOR;
        s->hello.minor = MTS_WIRE_MINOR;
    }
    s->fd = -1;
    s->k.fd = -1;
    s->ph = PH_CONNECT;
    *out = s;
    return MTS_OK;
}

int mts_session_poll(mts_session *s, int timeout_ms)
{
    const double time_left = s->t0 + s->max_ms - (1e3 * mts_clock_seconds());
    if (s->ph != PH_DONE && time_left <= 0 && s->o->list)
        finish(s, mts_error_set(&s->err, MTS_ERR_IO,
                                "the model list did not come whole within %g s (the session's "
                                "time limit)",
                                s->max_ms / 1000));
    else if (s->ph != PH_DONE && time_left <= 0)
        finish(s, mts_error_set(&s->err, MTS_ERR_IO,
                                "no END after %g s (%u batches applied): the session's time "
                                "limit",
                                s->max_ms / 1000, s->c->batches));
    else if (timeout_ms < 0 || timeout_ms > time_left) /* no wait past the limit */
        timeout_ms = (int)time_left + 1;
    if (s->ph == PH_CONNECT && s->o->file) {
        s->progress = 0;
        if (s->connections++ == 0)
            s->st->ms_connect = (1e3 * mts_clock_seconds()) - s->t0;
        else
            s->st->reconnects++;
        mts_result rc = mts_webfile_begin(s->o->file, s->c, s->hello.stop_kind,
                                          s->hello.stop_value, &s->err);
        if (rc != MTS_OK)
            conversation_failed(s, rc, rc == MTS_ERR_IO);
        else
            s->ph = PH_STREAM;
    }
    if (s->ph == PH_CONNECT && s->o->tls) {
        s->progress = 0;
        mts_result rc = mts_tls_start(&s->tls, s->host, s->port, s->o->tls, &s->err);
        if (rc != MTS_OK)
            conversation_failed(s, rc, rc == MTS_ERR_IO);
        else
            s->ph = PH_CONNECTING;
    }
    if (s->ph == PH_CONNECT) { /* then on to connecting at once */
        int transient;
        s->progress = 0;
        mts_result rc = connector_start(&s->k, s->host, s->port, &transient, &s->err);
        if (rc != MTS_OK)
            conversation_failed(s, rc, transient);
        else
            s->ph = PH_CONNECTING;
    }
    switch (s->ph) {
    case PH_CONNECT:
        break;
    case PH_CONNECTING: {
        if (s->tls) {
            int k = mts_tls_step(s->tls, timeout_ms, &s->err);
            if (k > 0)
                connected(s, mts_tls_fd(s->tls));
            else if (k < 0)
                conversation_failed(s, s->err.code, s->err.code == MTS_ERR_IO);
            break;
        }
        int k = connector_step(&s->k, s->host, s->port, s->cto, timeout_ms, &s->err);
        if (k > 0)
            connected(s, s->k.fd);
        else if (k < 0)
            conversation_failed(s, s->err.code, 1);
        break;
    }
    case PH_STREAM:
        if (s->o->file)
            file_step(s, timeout_ms);
        else
            stream_step(s, timeout_ms);
        break;
    case PH_WAIT: {
        double left = s->retry_at - (1e3 * mts_clock_seconds());
        if (left > 0) {
            int wait = (int)left + 1;
            if (timeout_ms >= 0 && timeout_ms < wait)
                wait = timeout_ms;
            poll(NULL, 0, wait);
            if ((1e3 * mts_clock_seconds()) < s->retry_at)
                break;
        }
        mts_result rc = mts_stream_client_reconnected(s->c, &s->err);
        if (rc != MTS_OK) {
            finish(s, rc);
            break;
        }
        uint32_t batch;
        uint64_t id;
        /* resume_point held when the wait began and nothing changed since */
        mts_stream_client_resume_point(s->c, &batch, &id);
        s->hello.resume_batch = batch;
        s->hello.stream_id = id;
        /* a resume asks for the form it holds, which MODEL_INFO said, not
         * the one first asked for: a server without the records form sent
         * splits, and the next server may have both */
        if (batch > 0)
            s->hello.flags = (s->hello.flags & ~MTS_HELLO_RECORDS) |
                             (s->c->records ? MTS_HELLO_RECORDS : 0);
        s->ph = PH_CONNECT;
        break;
    }
    case PH_DONE:
        break;
    }
    return s->ph != PH_DONE;
}

int mts_session_fd(const mts_session *s)
{
    if (s->tls)
        return s->ph == PH_STREAM ? s->fd : -1;
    return s->ph == PH_STREAM ? s->fd : s->ph == PH_CONNECTING ? s->k.fd : -1;
}

mts_result mts_session_end(mts_session *s, mts_error *err)
{
    if (!s)
        return MTS_OK;
    mts_result rc;
    if (s->ph == PH_DONE) {
        rc = s->result;
    } else {
        close_conversation(s);
        rc = mts_error_set(&s->err, MTS_ERR_ARG, "stopped by the caller");
    }
    if (err && rc != MTS_OK)
        *err = s->err;
    free(s);
    return rc;
}

mts_result mts_session_run(const mts_session_options *o, mts_stream_client *c,
                           mts_session_stats *st, mts_error *err)
{
    mts_session *s;
    mts_result rc = mts_session_begin(o, c, st, &s, err);
    if (rc != MTS_OK)
        return rc;
    while (mts_session_poll(s, -1))
        ;
    return mts_session_end(s, err);
}
