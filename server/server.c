/* accept4 */
#define _GNU_SOURCE
#include "server.h"

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/uio.h>
#include <time.h>
#include <unistd.h>

#include "clock.h"
#include "loop.h"
#include "net.h"
#include "server_internal.h"
#include "wire.h"

/* The ERROR texts said in more than one place, worded once. */
#define TEXT_NOT_HELLO "the first message must be HELLO or LIST"
#define TEXT_BUSY "server busy: try again later"

struct mts_server {
    mts_server_options opts;
    double listen_paused_until; /* out of descriptors: the listener is not watched */
    mts_server_model *models;
    uint32_t model_count;
    mts_server_model *own_models; /* mts_server_create's table, freed with the server */
    uint32_t waiting;             /* connections in MTS__WAITING */
    /* the TCP listener, and the WebSocket one when asked for */
    struct listener {
        int fd, port;
        const mts__transport *tr; /* its connections' */
        mts_loop_io io;
        struct mts_server *server;
    } lis[2];
    mts_loop loop;
    const atomic_int *stop; /* mts_server_run's flag */
    double stop_at;              /* when the stop began: the grace counts from here */
    mts__conn *conns;
    mts__conn *dead; /* closed during this round of events; freed after it */
    mts__conn *paced; /* connections over their rate, waiting to resume */
    uint32_t conn_count, paced_count;
    double next_scan, next_stats;
    uint64_t bytes_out;      /* sent so far, live (stats.bytes counts closed connections) */
    uint64_t stats_bytes_at; /* bytes_out at the last stats line */
    mts_server_stats stats;
};

static void logf_(mts_server *s, mts_server_log_kind kind, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
static void logf_(mts_server *s, mts_server_log_kind kind, const char *fmt, ...)
{
    if (!s->opts.log)
        return;
    char line[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    s->opts.log(s->opts.log_user, kind, line);
}

static mts_result open_listener(mts_server *s, struct listener *l, const char *spec,
                                mts_error *err)
{
    /* a deep accept queue: thousands of clients may connect in one burst, and
     * a full queue costs each of them a SYN retry (a second or more) */
    int fd;
    mts_result rc = mts_net_listen(spec, s->opts.reuse_port, 4096, &fd, err);
    if (rc != MTS_OK)
        return rc;
    struct sockaddr_storage ss;
    socklen_t sl = sizeof ss;
    getsockname(fd, (struct sockaddr *)&ss, &sl);
    l->port = ss.ss_family == AF_INET6 ? ntohs(((struct sockaddr_in6 *)&ss)->sin6_port)
                                       : ntohs(((struct sockaddr_in *)&ss)->sin_port);
    l->fd = fd;
    return MTS_OK;
}

static void accept_all(mts_server *s, struct listener *l);
static void on_conn(mts_loop *loop, mts_loop_io *io, unsigned events);

static void on_listener(mts_loop *loop, mts_loop_io *io, unsigned events)
{
    (void)loop;
    (void)events;
    struct listener *l = io->user;
    if (l->fd >= 0)
        accept_all(l->server, l);
}

/* Watches a listener for connections: 0, or -1 with errno. */
static int watch_listener(mts_server *s, struct listener *l)
{
    l->server = s;
    return mts_loop_watch(&s->loop, &l->io, l->fd, MTS_LOOP_IN, on_listener, l);
}

mts_result mts_server_create_models(const mts_server_options *opts, mts_server_model *models,
                                    uint32_t model_count, mts_server **out, mts_error *err)
{
    static const mts_server_options defaults = {0};
    *out = NULL;
    mts_server *s = calloc(1, sizeof *s);
    if (!s)
        return mts_error_set(err, MTS_ERR_NOMEM, "server: out of memory");
    s->opts = opts ? *opts : defaults;
    if (!s->opts.listen)
        s->opts.listen = "127.0.0.1:7447";
    if (!s->opts.max_clients)
        s->opts.max_clients = 1024;
    if (!(s->opts.handshake_timeout > 0))
        s->opts.handshake_timeout = 10;
    if (!(s->opts.idle_timeout > 0))
        s->opts.idle_timeout = 30;
    if (!(s->opts.grace > 0))
        s->opts.grace = 5;
    if (!(s->opts.prepare_wait > 0))
        s->opts.prepare_wait = 60;
    s->models = models;
    s->model_count = model_count;
    s->next_stats = mts_clock_seconds() + s->opts.stats_interval;
    s->lis[0].fd = s->lis[1].fd = s->loop.epoll_fd = -1;
    s->lis[0].tr = &mts__tcp_transport;
    s->lis[1].tr = &mts__ws_transport;
    mts_result rc = open_listener(s, &s->lis[0], s->opts.listen, err);
    if (rc == MTS_OK && s->opts.ws_listen)
        rc = open_listener(s, &s->lis[1], s->opts.ws_listen, err);
    if (rc != MTS_OK) {
        mts_server_free(s);
        return rc;
    }
    rc = mts_loop_init(&s->loop, err);
    for (int k = 0; k < 2 && rc == MTS_OK; k++) {
        if (s->lis[k].fd >= 0 && watch_listener(s, &s->lis[k]) != 0)
            rc = mts_error_set(err, MTS_ERR_IO, "epoll: %s", strerror(errno));
    }
    if (rc != MTS_OK) {
        mts_server_free(s);
        return rc;
    }
    *out = s;
    return MTS_OK;
}

void mts_server_model_init_preparing(mts_server_model *m, const char *name,
                                     const mts_model *model)
{
    memset(m, 0, sizeof *m);
    snprintf(m->name, sizeof m->name, "%s", name);
    m->vertices = model->vertex_count;
    m->triangles = model->level_triangles[model->level_count];
    m->levels = model->level_count;
    atomic_init(&m->stream, NULL);
    atomic_init(&m->records, NULL);
    atomic_init(&m->records_settled, 0);
    atomic_init(&m->failed, 0);
}

void mts_server_model_init_ready(mts_server_model *m, const mts_stream *stream)
{
    mts_server_model_init_preparing(m, stream->name, &stream->model);
    atomic_init(&m->stream, stream);
    atomic_init(&m->records, stream->records_form);
    atomic_init(&m->records_settled, 1);
}

void mts_server_model_publish_records(mts_server_model *m, const mts_stream *records_form)
{
    atomic_store_explicit(&m->records, records_form, memory_order_release);
    atomic_store_explicit(&m->records_settled, 1, memory_order_release);
}

void mts_server_model_publish(mts_server_model *m, const mts_stream *stream)
{
    atomic_store_explicit(&m->stream, stream, memory_order_release);
}

void mts_server_model_fail(mts_server_model *m, const char *why)
{
    snprintf(m->why, sizeof m->why, "%s", why);
    atomic_store_explicit(&m->failed, 1, memory_order_release);
}

mts_result mts_server_create(const mts_server_options *opts, const mts_stream *const *streams,
                             uint32_t stream_count, mts_server **out, mts_error *err)
{
    mts_server_model *models = calloc((size_t)stream_count + 1, sizeof *models);
    if (!models)
        return mts_error_set(err, MTS_ERR_NOMEM, "server: out of memory");
    for (uint32_t i = 0; i < stream_count; i++)
        mts_server_model_init_ready(&models[i], streams[i]);
    mts_result rc = mts_server_create_models(opts, models, stream_count, out, err);
    if (rc != MTS_OK) {
        free(models);
        return rc;
    }
    (*out)->own_models = models;
    return MTS_OK;
}

int mts_server_port(const mts_server *s)
{
    return s->lis[0].port;
}

int mts_server_ws_port(const mts_server *s)
{
    return s->lis[1].fd >= 0 ? s->lis[1].port : 0;
}

void mts_server_get_stats(const mts_server *s, mts_server_stats *stats)
{
    *stats = s->stats;
}

static void paced_add(mts_server *s, mts__conn *c, double until)
{
    if (c->paced_until == 0) {
        c->pprev = NULL;
        c->pnext = s->paced;
        if (s->paced)
            s->paced->pprev = c;
        s->paced = c;
        s->paced_count++;
    }
    c->paced_until = until;
}

static void paced_remove(mts_server *s, mts__conn *c)
{
    if (c->paced_until == 0)
        return;
    if (c->pprev)
        c->pprev->pnext = c->pnext;
    else
        s->paced = c->pnext;
    if (c->pnext)
        c->pnext->pprev = c->pprev;
    c->pprev = c->pnext = NULL;
    c->paced_until = 0;
    s->paced_count--;
}

/* A failure may also be the server stopping. */
void mts__conn_close(mts__conn *c, const char *failure)
{
    mts_server *s = c->server;
    const int ok = !failure && c->end == MTS__SERVED;
    const char *outcome = failure ? failure : c->outcome ? c->outcome : "closed";
    if (ok)
        s->stats.completed++;
    else
        s->stats.failed++;
    s->stats.bytes += c->sent;
    paced_remove(s, c);
    if (c->phase == MTS__WAITING)
        s->waiting--;
    logf_(s, MTS_SERVER_LOG_CONNECTION, "peer=%s model=%s bytes=%llu level=%u ms=%.1f outcome=%s",
          c->peer,
          c->model[0] ? c->model : "-", (unsigned long long)c->sent, c->stop_level,
          (mts_clock_seconds() - c->started) * 1e3, outcome);
    mts_loop_unwatch(&s->loop, &c->io);
    close(c->fd);
    c->fd = -1;
    mts_buf_free(&c->head);
    mts_buf_free(&c->tail);
    c->tr->release(c);
    if (c->prev)
        c->prev->next = c->next;
    else
        s->conns = c->next;
    if (c->next)
        c->next->prev = c->prev;
    s->conn_count--;
    /* later events of this round may still point at c: free it after them */
    c->prev = NULL;
    c->next = s->dead;
    s->dead = c;
}

static void free_dead(mts_server *s)
{
    while (s->dead) {
        mts__conn *c = s->dead;
        s->dead = c->next;
        free(c);
    }
}

void mts_server_free(mts_server *s)
{
    if (!s)
        return;
    while (s->conns)
        mts__conn_close(s->conns, "shutdown");
    free_dead(s);
    for (int k = 0; k < 2; k++) {
        if (s->lis[k].fd >= 0)
            close(s->lis[k].fd);
    }
    mts_loop_close(&s->loop);
    free(s->own_models);
    free(s);
}

static mts_server_model *find_model(mts_server *s, const char *name)
{
    for (uint32_t i = 0; i < s->model_count; i++) {
        if (strcmp(s->models[i].name, name) == 0)
            return &s->models[i];
    }
    return NULL;
}

static const mts_stream *model_stream(mts_server_model *m)
{
    return atomic_load_explicit(&m->stream, memory_order_acquire);
}

/* Drops what the conversation still had to send: it ends refused, with
 * `outcome`, once what is queued is flushed. */
static void conn_drop(mts__conn *c, const char *outcome)
{
    c->head.size = c->head_off = 0;
    c->body_off = c->body_end = 0;
    c->info_size = c->info_off = 0;
    c->tail.size = c->tail_off = 0;
    c->phase = MTS__WRITING;
    c->end = MTS__REFUSED;
    c->outcome = outcome;
}

/* Ends the conversation with an ERROR frame once it is flushed (or with
 * the transport's own answer, before its handshake is through). Nothing of
 * the conversation has gone out yet. */
static void conn_refuse(mts__conn *c, uint16_t code, const char *text, const char *outcome)
{
    conn_drop(c, outcome);
    if (!c->tr->refuse(c, code, text))
        mts_wire_put_error(&c->head, code, text);
}

void mts__conn_stop(mts__conn *c, const char *outcome)
{
    if (c->phase == MTS__WAITING)
        c->server->waiting--;
    conn_drop(c, outcome);
}

int mts__conn_all_sent(const mts__conn *c)
{
    return c->phase == MTS__WRITING && c->end == MTS__SERVED && c->body_off == c->body_end &&
           c->tail_off == c->tail.size;
}

static void conn_serve(mts_server *s, mts__conn *c, double now);

static void conn_answer(mts_server *s, mts__conn *c, uint8_t type, const uint8_t *p, size_t n)
{
    mts_error err = {0};
    if (type == MTS_MSG_LIST) {
        mts_wire_model_entry *list = calloc(s->model_count + 1, sizeof *list);
        if (!list) {
            conn_refuse(c, MTS_WERR_INTERNAL, "out of memory", "error: out of memory");
            return;
        }
        for (uint32_t i = 0; i < s->model_count; i++) {
            mts_server_model *m = &s->models[i];
            const mts_stream *st = model_stream(m);
            snprintf(list[i].name, sizeof list[i].name, "%s", m->name);
            list[i].vertices = m->vertices;
            list[i].triangles = m->triangles;
            list[i].levels = m->levels;
            list[i].stream_bytes = st ? (uint32_t)st->size : 0; /* 0: being prepared */
        }
        mts_wire_put_models(&c->head, list, s->model_count);
        free(list);
        if (c->head.failed) {
            conn_refuse(c, MTS_WERR_INTERNAL, "out of memory", "error: out of memory");
            return;
        }
        snprintf(c->model, sizeof c->model, "(list)");
        c->phase = MTS__WRITING;
        c->end = MTS__SERVED;
        c->outcome = "ok";
        return;
    }
    if (type != MTS_MSG_HELLO) {
        conn_refuse(c, MTS_WERR_PROTOCOL, TEXT_NOT_HELLO,
                    "error: no hello");
        return;
    }
    mts_wire_hello h;
    mts_result rc = mts_wire_parse_hello(p, n, &h, &err);
    if (rc != MTS_OK) {
        conn_refuse(c, rc == MTS_ERR_VERSION ? MTS_WERR_VERSION : MTS_WERR_PROTOCOL, err.msg,
                    rc == MTS_ERR_VERSION ? "error: version" : "error: bad hello");
        return;
    }
    snprintf(c->model, sizeof c->model, "%s", h.model);
    mts_server_model *m = find_model(s, h.model);
    if (!m) {
        char text[128];
        snprintf(text, sizeof text, "no model named '%s' (LIST shows the models)", h.model);
        conn_refuse(c, MTS_WERR_UNKNOWN_MODEL, text, "error: unknown model");
        return;
    }
    c->waits_for = m;
    c->hello = h;
    c->phase = MTS__WAITING;
    s->waiting++;
    conn_serve(s, c, mts_clock_seconds());
}

/* Answers a HELLO whose model is ready, has failed, or has been waited for
 * long enough; leaves it waiting otherwise. */
static void conn_serve(mts_server *s, mts__conn *c, double now)
{
    mts_error err = {0};
    mts_server_model *m = c->waits_for;
    const mts_stream *st = model_stream(m);
    const mts_wire_hello *h = &c->hello;
    if (!st) {
        char text[300];
        if (atomic_load_explicit(&m->failed, memory_order_acquire)) {
            s->waiting--;
            snprintf(text, sizeof text, "model '%s' cannot be served: %s", m->name, m->why);
            conn_refuse(c, MTS_WERR_INTERNAL, text, "error: model failed");
        } else if (now - c->started > s->opts.prepare_wait) {
            s->waiting--;
            snprintf(text, sizeof text,
                     "model '%s' is still being prepared (its stream is encoding); try again "
                     "shortly",
                     m->name);
            conn_refuse(c, MTS_WERR_BUSY, text, "error: preparing");
        }
        return;
    }
    if (h->flags & MTS_HELLO_RECORDS) { /* the form it asked for, where this server has it */
        /* settled is read first: once it reads 1, records holds the last word */
        const int settled = atomic_load_explicit(&m->records_settled, memory_order_acquire);
        const mts_stream *r = atomic_load_explicit(&m->records, memory_order_acquire);
        if (r)
            st = r;
        else if (!settled && h->resume_batch > 0 && h->stream_id != st->stream_id &&
                 now - c->started <= s->opts.prepare_wait)
            return; /* resuming the records form, which is still being encoded */
    }
    s->waiting--;
    if (h->resume_batch > 0 && h->stream_id != st->stream_id) {
        conn_refuse(c, MTS_WERR_STALE, "the model changed since; start over", "error: stale");
        return;
    }
    c->stream = st;
    c->answered = now;
    c->stop_level = mts_stream_stop_level(st, h->stop_kind, h->stop_value);
    size_t off, len;
    if (mts_stream_range(st, h->resume_batch, c->stop_level, &off, &len, &err) != MTS_OK) {
        conn_refuse(c, MTS_WERR_PROTOCOL, err.msg, "error: bad resume");
        return;
    }
    mts_stream_put_model_info_head(st, c->stop_level, &c->head);
    c->info_size = st->info_tail_size;
    c->body_off = off;
    c->body_end = off + len;
    mts_stream_put_end(st, c->stop_level, (uint32_t)(c->head.size + c->info_size + len),
                       &c->tail);
    if (c->head.failed || c->tail.failed) {
        conn_refuse(c, MTS_WERR_INTERNAL, "out of memory", "error: out of memory");
        return;
    }
    c->phase = MTS__WRITING;
    c->end = MTS__SERVED;
    c->outcome = "ok";
}

void mts__conn_update_events(mts__conn *c)
{
    mts_loop_set(&c->server->loop, &c->io,
                 (c->rd_closed ? 0 : MTS_LOOP_IN) | (c->watching_out ? MTS_LOOP_OUT : 0));
}

void mts__conn_watch_out(mts__conn *c, int on)
{
    c->watching_out = on;
    mts__conn_update_events(c);
}

/* Gathers the first frame in c->in and answers it once complete, or
 * refuses a frame that cannot be a HELLO or LIST. The longest frame taken
 * fits c->in, so bytes past its room are never needed. */
int mts__conn_input(mts__conn *c, const uint8_t *buf, size_t n)
{
    if (c->phase != MTS__READING || n == 0)
        return 0;
    size_t room = sizeof c->in - c->in_len, k = n < room ? n : room;
    memcpy(c->in + c->in_len, buf, k);
    c->in_len += k;
    if (c->in_len < MTS_WIRE_HEADER)
        return 0;
    uint32_t len = (uint32_t)c->in[0] | (uint32_t)c->in[1] << 8 | (uint32_t)c->in[2] << 16 |
                   (uint32_t)c->in[3] << 24;
    if (len == 0 || len > sizeof c->in - 4) {
        conn_refuse(c, MTS_WERR_PROTOCOL, TEXT_NOT_HELLO, "error: garbage");
        return 1;
    }
    if (c->in_len < 4 + (size_t)len)
        return 0;
    conn_answer(c->server, c, c->in[4], c->in + 5, len - 1);
    return 1;
}

/* A paced connection is a preview of a link at the rate: bytes leave at the
 * rate from the first one, a tick's worth at a time (the loop ticks every
 * 5 ms while any connection is paced), at least 4 KiB so writes are not
 * tiny. A larger head start would let a small stream arrive all at once:
 * a tenth of a second at 10 Mbit/s is 125 KB, most of a mesh's stream. */
#define PACE_TICK 0.005
static double pace_quantum(double rate)
{
    return rate * PACE_TICK > 4096 ? rate * PACE_TICK : 4096;
}

/* Bytes a paced connection may send now: its rate since it was answered,
 * plus one quantum. */
static size_t pace_allowance(const mts__conn *c, double rate, double quantum, double now)
{
    double allowed = rate * (now - c->answered) + quantum - (double)c->sent;
    return allowed > 0 ? (size_t)allowed : 0;
}

/* Writes as much as the socket (and the rate limit) takes: the head frame,
 * MODEL_INFO's shared tail, the shared stream range, the END frame -- one
 * sendmsg through the transport, no copies (a header of its own may go
 * first in the same sendmsg). */
void mts__conn_write(mts__conn *c)
{
    mts_server *s = c->server;
    for (;;) {
        if (!c->tr->flush(c))
            return;
        if (c->phase != MTS__WRITING) {
            if (c->watching_out) /* the transport's bytes are out; the rest waits for input */
                mts__conn_watch_out(c, 0);
            return;
        }
        struct iovec iov[5];
        int n = 1; /* iov[0]: the transport's, for a header of its own */
        if (c->head_off < c->head.size)
            iov[n++] = (struct iovec){c->head.data + c->head_off, c->head.size - c->head_off};
        if (c->info_off < c->info_size)
            iov[n++] = (struct iovec){c->stream->info_tail + c->info_off,
                                      c->info_size - c->info_off};
        if (c->body_off < c->body_end)
            iov[n++] = (struct iovec){(void *)(c->stream->bytes + c->body_off),
                                      c->body_end - c->body_off};
        if (c->tail_off < c->tail.size)
            iov[n++] = (struct iovec){c->tail.data + c->tail_off, c->tail.size - c->tail_off};
        if (n == 1) {
            mts__transport_end how = c->tr->finish(c);
            if (how == MTS__END_MORE)
                continue;
            if ((c->end == MTS__REFUSED || how == MTS__END_LINGER) && !c->rd_closed) {
                /* Closing now, with client bytes still unread (or the
                 * transport's peer still to answer its end), would send a
                 * reset that can destroy what is in flight: shut our side
                 * and let the client close first (briefly). */
                shutdown(c->fd, SHUT_WR);
                c->linger_until = mts_clock_seconds() + 1.0;
                c->watching_out = 0;
                mts__conn_update_events(c);
                return;
            }
            mts__conn_close(c, NULL);
            return;
        }
        if (s->opts.rate_limit > 0 && c->stream) {
            const double now = mts_clock_seconds(), rate = s->opts.rate_limit,
                         quantum = pace_quantum(rate);
            size_t allow = pace_allowance(c, rate, quantum, now), left = 0;
            for (int k = 1; k < n; k++)
                left += iov[k].iov_len;
            if (allow < left && allow < (size_t)quantum) {
                /* over its rate, or nearly: stop watching output until a
                 * quantum is due. Writing what a few microseconds allow
                 * would send the rest in thousands of writes of a few bytes
                 * (over WebSocket, each its own message, which a page then
                 * takes one event at a time). */
                paced_add(s, c, now + (quantum - (double)allow) / rate);
                c->last_progress = now; /* pacing is not stalling */
                mts__conn_watch_out(c, 0);
                return;
            }
            for (int k = 1; k < n; k++) {
                if (iov[k].iov_len >= allow) {
                    iov[k].iov_len = allow;
                    n = k + 1;
                    break;
                }
                allow -= iov[k].iov_len;
            }
        }
        ssize_t wr = c->tr->send(c, iov, n);
        if (wr < 0) {
            if (errno == EINTR)
                continue;
            if (errno == EAGAIN || errno == EWOULDBLOCK) {
                mts__conn_watch_out(c, 1);
                return;
            }
            mts__conn_close(c, errno == EPIPE ? "error: peer went away" : "error: reset by peer");
            return;
        }
        size_t left = (size_t)wr;
        c->last_progress = mts_clock_seconds(); /* a header's bytes too */
        c->sent += left;
        s->bytes_out += left;
        size_t k = c->head.size - c->head_off < left ? c->head.size - c->head_off : left;
        c->head_off += k;
        left -= k;
        k = c->info_size - c->info_off < left ? c->info_size - c->info_off : left;
        c->info_off += k;
        left -= k;
        k = c->body_end - c->body_off < left ? c->body_end - c->body_off : left;
        c->body_off += k;
        left -= k;
        c->tail_off += left;
        if (c->head_off == c->head.size && c->head.data && c->end == MTS__SERVED) {
            /* sent: a long stream should not keep its head frame around */
            mts_buf_free(&c->head);
            c->head_off = 0;
        }
    }
}

static void accept_all(mts_server *s, struct listener *l)
{
    for (;;) {
        struct sockaddr_storage ss;
        socklen_t sl = sizeof ss;
        int fd = accept4(l->fd, (struct sockaddr *)&ss, &sl, SOCK_NONBLOCK | SOCK_CLOEXEC);
        if (fd < 0) {
            if (errno == EMFILE || errno == ENFILE || errno == ENOBUFS || errno == ENOMEM) {
                /* the pending connection stays queued and the listeners stay
                 * readable: stop watching them for a moment instead of spinning */
                for (int k = 0; k < 2; k++) {
                    if (s->lis[k].fd >= 0)
                        mts_loop_unwatch(&s->loop, &s->lis[k].io);
                }
                s->listen_paused_until = mts_clock_seconds() + 0.1;
                logf_(s, MTS_SERVER_LOG_NOTICE, "accept: %s; not accepting for 100 ms",
                      strerror(errno));
            }
            return;
        }
        char peer[64] = "?";
        char host[INET6_ADDRSTRLEN] = "?";
        int port = 0;
        if (ss.ss_family == AF_INET) {
            inet_ntop(AF_INET, &((struct sockaddr_in *)&ss)->sin_addr, host, sizeof host);
            port = ntohs(((struct sockaddr_in *)&ss)->sin_port);
        } else if (ss.ss_family == AF_INET6) {
            inet_ntop(AF_INET6, &((struct sockaddr_in6 *)&ss)->sin6_addr, host, sizeof host);
            port = ntohs(((struct sockaddr_in6 *)&ss)->sin6_port);
        }
        /* the log says which transport a peer came by ("ws/" for WebSocket) */
        snprintf(peer, sizeof peer, "%s%s:%d", l->tr->tag, host, port);
        s->stats.accepted++;
        if (s->conn_count >= s->opts.max_clients) {
            mts_buf b = {0};
            l->tr->busy(&b, TEXT_BUSY);
            if (!b.failed)
                (void)!send(fd, b.data, b.size, MSG_NOSIGNAL | MSG_DONTWAIT);
            mts_buf_free(&b);
            /* read what the client already sent (its HELLO) and shut our
             * side first, so the close is a FIN the client reads after the
             * ERROR, not a reset that can overtake it */
            uint8_t sink[512];
            while (recv(fd, sink, sizeof sink, MSG_DONTWAIT) > 0) {
            }
            shutdown(fd, SHUT_WR);
            close(fd);
            s->stats.busy++;
            logf_(s, MTS_SERVER_LOG_CONNECTION,
                  "peer=%s model=- bytes=0 level=0 ms=0.0 outcome=error: busy", peer);
            continue;
        }
        mts__conn *c = calloc(1, sizeof *c);
        if (c)
            c->tr = l->tr;
        if (c && c->tr->open(c) != 0) {
            free(c);
            c = NULL;
        }
        if (!c) {
            close(fd);
            continue;
        }
        mts_net_nodelay(fd);
        if (s->opts.sndbuf > 0) /* fixed, not autotuned: bounds kernel memory per client */
            setsockopt(fd, SOL_SOCKET, SO_SNDBUF, &s->opts.sndbuf, sizeof s->opts.sndbuf);
        c->fd = fd;
        c->server = s;
        c->started = c->last_progress = mts_clock_seconds();
        snprintf(c->peer, sizeof c->peer, "%s", peer);
        if (mts_loop_watch(&s->loop, &c->io, fd, MTS_LOOP_IN, on_conn, c) != 0) {
            close(fd);
            c->tr->release(c);
            free(c);
            continue;
        }
        c->next = s->conns;
        if (s->conns)
            s->conns->prev = c;
        s->conns = c;
        s->conn_count++;
        if (s->conn_count > s->stats.peak)
            s->stats.peak = s->conn_count;
    }
}

/* Resident memory of the whole process, from /proc (0 where unreadable). */
static double rss_mb(void)
{
    FILE *f = fopen("/proc/self/statm", "r");
    unsigned long pages = 0, resident = 0;
    if (!f)
        return 0;
    if (fscanf(f, "%lu %lu", &pages, &resident) != 2)
        resident = 0;
    fclose(f);
    return (double)resident * (double)sysconf(_SC_PAGESIZE) / 1048576.0;
}

static void stats_line(mts_server *s, double now)
{
    double dt = s->opts.stats_interval;
    logf_(s, MTS_SERVER_LOG_STATS,
          "stats: connections=%u peak=%u accepted=%llu completed=%llu failed=%llu busy=%llu "
          "out_mb_s=%.2f rss_mb=%.1f",
          s->conn_count, s->stats.peak, (unsigned long long)s->stats.accepted,
          (unsigned long long)s->stats.completed, (unsigned long long)s->stats.failed,
          (unsigned long long)s->stats.busy, (double)(s->bytes_out - s->stats_bytes_at) / 1e6 / dt,
          rss_mb());
    s->stats_bytes_at = s->bytes_out;
    s->next_stats = now + dt;
}

/* Paced connections whose time has come send their allowance. */
static void resume_paced(mts_server *s, double now)
{
    mts__conn *c = s->paced;
    while (c) {
        mts__conn *next = c->pnext;
        if (now >= c->paced_until) {
            paced_remove(s, c);
            c->last_progress = now;
            mts__conn_write(c); /* sends; paces again, waits for room, or closes */
        }
        c = next;
    }
}

/* HELLOs whose model was being prepared: served once it is ready. */
static void serve_waiting(mts_server *s, double now)
{
    for (mts__conn *c = s->conns, *next; c && s->waiting; c = next) {
        next = c->next;
        if (c->phase != MTS__WAITING)
            continue;
        conn_serve(s, c, now);
        if (c->phase == MTS__WRITING)
            mts__conn_write(c);
    }
}

static void check_timeouts(mts_server *s, double now)
{
    mts__conn *c = s->conns;
    while (c) {
        mts__conn *next = c->next;
        if (c->linger_until > 0) {
            if (now > c->linger_until)
                mts__conn_close(c, NULL);
        } else if (c->phase == MTS__READING && now - c->started > s->opts.handshake_timeout) {
            conn_refuse(c, MTS_WERR_TIMEOUT, "no HELLO or LIST in time",
                        "error: handshake timeout");
            mts__conn_write(c); /* best effort; closes once flushed or on error */
        } else if (c->paced_until > 0) {
            /* resumed by resume_paced */
        } else if (c->phase == MTS__WRITING && now - c->last_progress > s->opts.idle_timeout) {
            mts__conn_close(c, "error: idle timeout");
        }
        c = next;
    }
}

/* A connection's events of a round: an error or hang-up closes it, input
 * is read (a first frame answered starts the writing at once), output is
 * written. */
static void on_conn(mts_loop *loop, mts_loop_io *io, unsigned events)
{
    (void)loop;
    mts__conn *c = io->user;
    if (c->fd < 0) /* closed earlier in this round */
        return;
    if (events & MTS_LOOP_ERR) {
        /* a refused client closing after its ERROR is the expected end:
         * keep the refusal's outcome in the log */
        mts__conn_close(c, c->linger_until > 0 ? NULL
                           : c->phase == MTS__READING ? "error: closed before hello"
                                                      : "error: reset by peer");
        return;
    }
    if (events & MTS_LOOP_IN) {
        mts__phase before = c->phase;
        c->tr->read(c);
        if (c->fd < 0)
            return;
        if (before == MTS__READING && c->phase == MTS__WRITING) {
            mts__conn_write(c);
            return;
        }
    }
    if ((events & MTS_LOOP_OUT) && c->fd >= 0)
        mts__conn_write(c);
}

/* What the loop does between rounds: what the last round left (paced
 * connections due, prepared models' waiting clients, timeouts, stats, the
 * connections it closed), then the listeners (back after running out of
 * descriptors; closed on a stop, the streams given their grace). The next
 * round's longest sleep, or -1 once stopped and every stream has ended. */
static int server_tick(mts_loop *loop, void *user, double now)
{
    (void)loop;
    mts_server *s = user;
    if (s->paced_count)
        resume_paced(s, now);
    if (s->waiting)
        serve_waiting(s, now);
    /* the timeout scan is over every connection: a few times a second */
    if (now >= s->next_scan) {
        check_timeouts(s, now);
        s->next_scan = now + 0.05;
    }
    if (s->opts.stats_interval > 0 && now >= s->next_stats)
        stats_line(s, now);
    free_dead(s);
    if (s->listen_paused_until > 0 && now >= s->listen_paused_until && s->lis[0].fd >= 0) {
        s->listen_paused_until = 0;
        for (int k = 0; k < 2; k++) {
            if (s->lis[k].fd >= 0 && watch_listener(s, &s->lis[k]) != 0)
                s->listen_paused_until = now + 0.1; /* try again */
        }
    }
    if (*s->stop && s->lis[0].fd >= 0) {
        for (int k = 0; k < 2; k++) {
            if (s->lis[k].fd < 0)
                continue;
            mts_loop_unwatch(&s->loop, &s->lis[k].io);
            close(s->lis[k].fd);
            s->lis[k].fd = -1;
        }
        s->stop_at = now;
        logf_(s, MTS_SERVER_LOG_NOTICE, "stopping: %u streams to finish within %.1f s",
              s->conn_count, s->opts.grace);
    }
    if (s->lis[0].fd < 0 && (s->conn_count == 0 || now - s->stop_at > s->opts.grace)) {
        while (s->conns)
            mts__conn_close(s->conns, "error: server stopped");
        free_dead(s);
        return -1;
    }
    /* paced connections resume from the tick, and waiting ones are
     * answered from it: tick often then */
    return s->paced_count ? 5 : s->waiting ? 20 : 100;
}

mts_result mts_server_run(mts_server *s, const atomic_int *stop, mts_error *err)
{
    s->stop = stop;
    s->stop_at = 0;
    return mts_loop_run(&s->loop, server_tick, s, err);
}
