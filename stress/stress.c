/* strcasestr */
#define _GNU_SOURCE
#include "stress.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "clock.h"
#include "crc32c.h"
#include "fetch.h"
#include "http.h"
#include "loop.h"
#include "net.h"
#include "stream.h"
#include "webfile.h"

#define HTTP_HEAD_MAX 1024

typedef enum sc_state { SC_WAITING = 0, SC_CONNECTING, SC_SENDING, SC_READING, SC_DONE } sc_state;

/* One simulated client. Small on purpose: with no_apply there is nothing
 * else per client but the frame reader's buffer (one frame at most). */
typedef struct sclient {
    int fd;
    sc_state state;
    mts_loop_io io; /* its socket in the shard's loop (user: the stress) */
    uint8_t got_info, got_base;
    uint32_t hello_sent;
    double t_start, t_last; /* seconds */
    float ms_base;
    uint64_t bytes_in;          /* read in this conversation (for the error messages) */
    /* no_apply with verify: frames are checked, not decoded, so there is no
     * stream client to cut them: this reader does */
    mts_wire_reader reader;
    /* apply mode: from its first bytes, which wait in it until its turn to
     * apply comes (at most max_appliers apply at once) */
    mts_stream_client *decoder;
    uint8_t eof;                /* apply mode: all its bytes are in, the socket closed */
    char *http_head;            /* http mode: the response head so far (then NULL) */
    uint32_t http_head_len;
    uint64_t http_body, http_length; /* body bytes received, and Content-Length */
    /* skim mode (no_apply without verify): frames are walked, not buffered;
     * only the small control frames are kept whole, to be parsed */
    uint8_t skim_hdr[MTS_WIRE_HEADER], skim_hdr_len, skim_type;
    uint32_t skim_left;  /* payload bytes of the current frame still to come */
    uint8_t *skim_keep;  /* the current control frame's payload, or NULL */
    uint32_t skim_kept;
    /* continuing (options.continue_kind): the second conversation's HELLO */
    uint8_t *hello2;
    uint32_t hello2_size;
    /* a stream file (options.url): its conversation, on the shard's pool;
     * bytes_in follows mts_webfile_bytes, eof says the stop's range is in */
    mts_webfile *wf;
    struct stress *owner; /* for the pool's on_end */
    uint8_t continued;
} sclient;

typedef struct stress {
    const mts_stress_options *o;
    mts_http_pool *pool; /* options.url: the shard's clients' transfers */
    mts_stress_report *rep;
    struct addrinfo *addr;
    mts_loop loop;
    sclient *c;
    uint8_t *hello;
    size_t hello_size;
    float *ms_final, *ms_base; /* per succeeded client */
    uint8_t *chunk;
    double t0;
    /* apply mode: bytes are read as they come, frames applied by at most
     * max_appliers clients at a time, the oldest first, a slice a round */
    uint32_t connected;  /* sockets open: what the concurrency limit counts */
    uint32_t oldest;     /* no client before it is still to apply */
    uint32_t max_appliers;
    /* apply mode: the reservations one client's decoder frees, kept for the
     * next (bigmem.h); NULL: none */
    mts_bigmem_cache *memory;
} stress;

const char *mts_stress_failure_name(mts_stress_failure f)
{
    static const char *names[MTS_STRESS_FAILURE_KINDS] = {
        "connect", "busy", "server_error", "closed", "timeout", "protocol", "verify", "local"};
    return (unsigned)f < MTS_STRESS_FAILURE_KINDS ? names[f] : "unknown";
}

static void sc_close_socket(stress *s, sclient *c)
{
    if (c->fd >= 0) {
        mts_loop_unwatch(&s->loop, &c->io);
        close(c->fd);
        c->fd = -1;
        s->connected--;
    }
}

static void sc_release(stress *s, sclient *c)
{
    sc_close_socket(s, c);
    mts_wire_reader_free(&c->reader);
    free(c->http_head);
    c->http_head = NULL;
    free(c->skim_keep);
    c->skim_keep = NULL;
    free(c->hello2);
    c->hello2 = NULL;
    if (c->wf) {
        mts_webfile_free(c->wf); /* its transfer and its connections with it */
        c->wf = NULL;
        s->connected--;
    }
    if (c->decoder) {
        mts_stream_client_free(c->decoder);
        free(c->decoder);
        c->decoder = NULL;
    }
    c->state = SC_DONE;
    s->rep->active--;
}

static void sc_fail(stress *s, sclient *c, mts_stress_failure why, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
static void sc_fail(stress *s, sclient *c, mts_stress_failure why, const char *fmt, ...)
{
    mts_stress_report *r = s->rep;
    if (r->failures[why]++ == 0) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(r->first_error[why], sizeof r->first_error[why], fmt, ap);
        va_end(ap);
    }
    r->failed++;
    sc_release(s, c);
}

/* Where an applying client ended, against the first client's end. */
static void sc_record_end(stress *s, sclient *c)
{
    struct mts_stress_end *r = &s->rep->end[c->hello2 || c->continued];
    const mts_stream_client *d = c->decoder;
    uint32_t level = d->have_lod ? d->lod.level : 0;
    uint64_t triangles = 0;
    if (d->have_lod) {
        mts_strip_stats ss;
        mts_lod_strip_stats(&d->lod, &ss);
        triangles = ss.triangles;
    }
    if (!r->ended++) {
        r->level = level;
        r->triangles = triangles;
        r->checksum = d->checksum;
    } else if (r->level != level || r->triangles != triangles || r->checksum != d->checksum) {
        r->disagree++;
    }
}

static void sc_succeed(stress *s, sclient *c, double now)
{
    mts_stress_report *r = s->rep;
    if (c->decoder)
        sc_record_end(s, c);
    s->ms_base[r->succeeded] = c->ms_base;
    s->ms_final[r->succeeded] = (float)((now - c->t_start) * 1e3);
    r->succeeded++;
    sc_release(s, c);
}

static void sc_connect(stress *s, sclient *c);
static int sc_decoder(stress *s, sclient *c);
static void sc_web_start(stress *s, sclient *c);

static void sc_start(stress *s, sclient *c, double now)
{
    s->rep->started++;
    s->rep->active++;
    c->t_start = c->t_last = now;
    if (s->o->url) {
        sc_web_start(s, c);
        return;
    }
    if (s->o->http_path) {
        c->http_head = malloc(HTTP_HEAD_MAX + 1);
        if (!c->http_head) {
            sc_fail(s, c, MTS_STRESS_LOCAL, "out of memory");
            return;
        }
    }
    sc_connect(s, c);
}

static void on_client(mts_loop *loop, mts_loop_io *io, unsigned events);

/* A connection for c's conversation: HELLO goes when it is up. */
static void sc_connect(stress *s, sclient *c)
{
    int e = 0, r = mts_net_connect_start(s->addr, &c->fd, &e);
    if (r < 0) {
        /* out of descriptors or local ports is this machine's limit, not the server's */
        sc_fail(s, c, e == EMFILE || e == ENFILE || e == EADDRNOTAVAIL || e == ENOBUFS ||
                              e == ENOMEM
                          ? MTS_STRESS_LOCAL
                          : MTS_STRESS_CONNECT,
                "connect: %s", strerror(e));
        return;
    }
    s->connected++;
    c->state = r > 0 ? SC_SENDING : SC_CONNECTING;
    if (mts_loop_watch(&s->loop, &c->io, c->fd, MTS_LOOP_OUT, on_client, s) != 0)
        sc_fail(s, c, MTS_STRESS_LOCAL, "epoll_ctl: %s", strerror(errno));
}

static void sc_send(stress *s, sclient *c, double now)
{
    if (c->state == SC_CONNECTING) {
        const int soerr = mts_net_connect_result(c->fd);
        if (soerr != 0) {
            sc_fail(s, c, MTS_STRESS_CONNECT, "connect: %s", strerror(soerr));
            return;
        }
        c->state = SC_SENDING;
    }
    const uint8_t *hello = c->hello2 ? c->hello2 : s->hello;
    const size_t size = c->hello2 ? c->hello2_size : s->hello_size;
    while (c->hello_sent < size) {
        ssize_t w = send(c->fd, hello + c->hello_sent, size - c->hello_sent,
                         MSG_NOSIGNAL | MSG_DONTWAIT);
        if (w < 0 && errno == EINTR)
            continue;
        if (w < 0 && (errno == EAGAIN || errno == EWOULDBLOCK))
            return; /* EPOLLOUT comes back */
        if (w < 0) {
            sc_fail(s, c, MTS_STRESS_CLOSED, "sending HELLO: %s", strerror(errno));
            return;
        }
        c->hello_sent += (uint32_t)w;
    }
    c->state = SC_READING;
    c->t_last = now;
    if (mts_loop_set(&s->loop, &c->io, MTS_LOOP_IN) != 0)
        sc_fail(s, c, MTS_STRESS_LOCAL, "epoll_ctl: %s", strerror(errno));
}

/* Frame checks without a decoder (no_apply): the conversation's order, the
 * messages that need no model state, and with verify each BATCH's CRC. */
static int sc_frame_light(stress *s, sclient *c, uint8_t type, const uint8_t *p, size_t n,
                          int *done)
{
    mts_error err = {0};
    switch (type) {
    case MTS_MSG_MODEL_INFO: {
        if (c->got_info) {
            sc_fail(s, c, MTS_STRESS_PROTOCOL, "a second MODEL_INFO");
            return 0;
        }
        mts_wire_model_info mi = {0};
        mts_result rc = mts_wire_parse_model_info(p, n, &mi, &err);
        mts_wire_model_info_free(&mi);
        if (rc != MTS_OK) {
            sc_fail(s, c, MTS_STRESS_PROTOCOL, "%s", err.msg);
            return 0;
        }
        c->got_info = 1;
        return 1;
    }
    case MTS_MSG_BASE:
        if (!c->got_info || c->got_base) {
            sc_fail(s, c, MTS_STRESS_PROTOCOL, "BASE out of order");
            return 0;
        }
        c->got_base = 1;
        c->ms_base = (float)((mts_clock_seconds() - c->t_start) * 1e3);
        return 1;
    case MTS_MSG_BATCH:
        if (!c->got_base) {
            sc_fail(s, c, MTS_STRESS_PROTOCOL, "BATCH before BASE");
            return 0;
        }
        if (n < 4) {
            sc_fail(s, c, MTS_STRESS_PROTOCOL, "BATCH of %zu bytes", n);
            return 0;
        }
        if (s->o->verify) {
            uint32_t want = (uint32_t)p[n - 4] | (uint32_t)p[n - 3] << 8 |
                            (uint32_t)p[n - 2] << 16 | (uint32_t)p[n - 1] << 24;
            if (mts_crc32c(0, p, n - 4) != want) {
                sc_fail(s, c, MTS_STRESS_PROTOCOL, "BATCH: CRC mismatch");
                return 0;
            }
        }
        s->rep->batches++;
        return 1;
    case MTS_MSG_END: {
        mts_wire_end e;
        if (!c->got_base || mts_wire_parse_end(p, n, &e, &err) != MTS_OK) {
            sc_fail(s, c, MTS_STRESS_PROTOCOL, "END: %s", c->got_base ? err.msg : "before BASE");
            return 0;
        }
        *done = 1;
        return 1;
    }
    case MTS_MSG_ERROR: {
        uint16_t code = 0;
        char text[128] = "";
        mts_wire_parse_error(p, n, &code, text, sizeof text, &err);
        sc_fail(s, c, code == MTS_WERR_BUSY ? MTS_STRESS_BUSY : MTS_STRESS_SERVER,
                "server: %s (%s)", text, mts_wire_error_name(code));
        return 0;
    }
    default:
        sc_fail(s, c, MTS_STRESS_PROTOCOL, "unexpected frame type %u", type);
        return 0;
    }
}

/* What an applied frame brought: splits_before is the decoder's count
 * before it. 0 once c failed (released). */
static int sc_event(stress *s, sclient *c, mts_stream_event ev, uint32_t splits_before,
                    int *done)
{
    switch (ev) {
    case MTS_EV_BASE:
        c->ms_base = (float)((mts_clock_seconds() - c->t_start) * 1e3);
        break;
    case MTS_EV_BATCH:
        s->rep->batches++;
        s->rep->splits += c->decoder->splits - splits_before;
        break;
    case MTS_EV_END:
        *done = 1;
        break;
    case MTS_EV_ERROR:
        sc_fail(s, c, c->decoder->error_code == MTS_WERR_BUSY ? MTS_STRESS_BUSY : MTS_STRESS_SERVER,
                "server: %s (%s)", c->decoder->error_text,
                mts_wire_error_name(c->decoder->error_code));
        return 0;
    case MTS_EV_MODELS:
        sc_fail(s, c, MTS_STRESS_PROTOCOL, "MODELS in answer to a HELLO");
        return 0;
    default:
        break;
    }
    return 1;
}

/* http mode: the head is kept until its blank line, then only the body is
 * counted; the response must be a 200 with exactly Content-Length bytes. */
static void sc_read_http(stress *s, sclient *c, const uint8_t *p, size_t n)
{
    if (c->http_head) {
        size_t take = n < HTTP_HEAD_MAX - c->http_head_len ? n : HTTP_HEAD_MAX - c->http_head_len;
        memcpy(c->http_head + c->http_head_len, p, take);
        c->http_head_len += (uint32_t)take;
        c->http_head[c->http_head_len] = 0;
        char *end = strstr(c->http_head, "\r\n\r\n");
        if (!end) {
            if (c->http_head_len == HTTP_HEAD_MAX)
                sc_fail(s, c, MTS_STRESS_PROTOCOL, "HTTP response head over %d bytes",
                        HTTP_HEAD_MAX);
            return;
        }
        if (strncmp(c->http_head, "HTTP/1.", 7) != 0 || strncmp(c->http_head + 8, " 200", 4) != 0) {
            char *eol = strstr(c->http_head, "\r\n");
            *eol = 0;
            sc_fail(s, c, MTS_STRESS_SERVER, "%s", c->http_head);
            return;
        }
        const char *cl = strcasestr(c->http_head, "\r\ncontent-length:");
        c->http_length = cl ? strtoull(cl + 17, NULL, 10) : UINT64_MAX;
        size_t head = (size_t)(end + 4 - c->http_head);
        c->http_body = (uint64_t)(c->http_head_len - head) + (n - take);
        free(c->http_head);
        c->http_head = NULL;
        c->got_base = 1;
        c->ms_base = (float)((mts_clock_seconds() - c->t_start) * 1e3);
        return;
    }
    c->http_body += n;
}

/* Skim mode: walks the frames in p without copying the bulk of them, so the
 * client costs about what a plain file download costs (the figures are the
 * server's). Returns 0 once the client has ended (failed or done). */
static int sc_skim(stress *s, sclient *c, const uint8_t *p, size_t n)
{
    const uint8_t *end = p + n;
    while (p < end) {
        if (c->skim_hdr_len < MTS_WIRE_HEADER) {
            c->skim_hdr[c->skim_hdr_len++] = *p++;
            if (c->skim_hdr_len < MTS_WIRE_HEADER)
                continue;
            const uint8_t *h = c->skim_hdr;
            uint32_t len = (uint32_t)h[0] | (uint32_t)h[1] << 8 | (uint32_t)h[2] << 16 |
                           (uint32_t)h[3] << 24;
            if (len == 0 || len > MTS_WIRE_MAX_FRAME) {
                sc_fail(s, c, MTS_STRESS_PROTOCOL, "frame of %u bytes (1..%u allowed)", len,
                        MTS_WIRE_MAX_FRAME);
                return 0;
            }
            c->skim_type = h[4];
            c->skim_left = len - 1;
            c->skim_kept = 0;
            if (c->skim_type != MTS_MSG_BASE && c->skim_type != MTS_MSG_BATCH) {
                c->skim_keep = malloc(c->skim_left + 1);
                if (!c->skim_keep) {
                    sc_fail(s, c, MTS_STRESS_LOCAL, "out of memory");
                    return 0;
                }
            }
        } else {
            size_t take = (size_t)(end - p) < c->skim_left ? (size_t)(end - p) : c->skim_left;
            if (c->skim_keep)
                memcpy(c->skim_keep + c->skim_kept, p, take);
            c->skim_kept += (uint32_t)take;
            c->skim_left -= (uint32_t)take;
            p += take;
        }
        if (c->skim_hdr_len == MTS_WIRE_HEADER && c->skim_left == 0) {
            /* a whole frame: BASE and BATCH are checked for order and size
             * only (a BATCH ends in its 4-byte CRC) */
            int done = 0, ok;
            static const uint8_t four[4] = {0};
            if (c->skim_type == MTS_MSG_BASE || c->skim_type == MTS_MSG_BATCH)
                ok = sc_frame_light(s, c, c->skim_type, four, c->skim_kept >= 4 ? 4 : 0, &done);
            else
                ok = sc_frame_light(s, c, c->skim_type, c->skim_keep, c->skim_kept, &done);
            free(c->skim_keep);
            c->skim_keep = NULL;
            c->skim_hdr_len = 0;
            if (!ok)
                return 0;
            if (done) {
                sc_succeed(s, c, mts_clock_seconds());
                return 0;
            }
        }
    }
    return 1;
}

/* ---- a stream file (options.url) ---------------------------------------- */

/* A conversation's failure, by kind: what the transfer said (no
 * connection, a timeout, a 5xx), else what the bytes were. */
static void sc_web_fail(stress *s, sclient *c, mts_result rc, const mts_error *err)
{
    const mts_http_info hi = mts_webfile_http_last(c->wf);
    mts_stress_failure why = MTS_STRESS_PROTOCOL;
    if (rc == MTS_ERR_NOMEM)
        why = MTS_STRESS_LOCAL;
    else if (rc == MTS_ERR_CHECKSUM)
        why = MTS_STRESS_VERIFY;
    else if (hi.no_connection)
        why = MTS_STRESS_CONNECT;
    else if (hi.timed_out)
        why = MTS_STRESS_TIMEOUT;
    else if (hi.status == 503 || hi.status == 429)
        why = MTS_STRESS_BUSY;
    else if (hi.status >= 400)
        why = MTS_STRESS_SERVER;
    else if (rc == MTS_ERR_IO)
        why = MTS_STRESS_CLOSED;
    sc_fail(s, c, why, "%s", err->msg);
}

static void sc_web_bytes(stress *s, sclient *c)
{
    const uint64_t b = mts_webfile_bytes(c->wf);
    s->rep->bytes += b - c->bytes_in;
    c->bytes_in = b;
}

/* A range ended, or a conversation began: the next range is asked for, or
 * every byte of the stop is in (applied, then ended by sc_apply), or the
 * conversation failed. */
static void sc_web_step(stress *s, sclient *c)
{
    sc_web_bytes(s, c);
    c->t_last = mts_clock_seconds();
    if (mts_webfile_poll(c->wf, c->decoder, 0))
        return; /* a range under way */
    mts_error err = {0};
    mts_result rc = mts_webfile_result(c->wf, &err);
    if (rc != MTS_OK)
        sc_web_fail(s, c, rc, &err);
    else
        c->eof = 1;
}

/* The pool's word that one of c's ranges ended (from the shard's loop). */
static void sc_web_end(void *user, mts_http *http)
{
    (void)http;
    sclient *c = user;
    if (c->state != SC_DONE && c->wf)
        sc_web_step(c->owner, c);
}

/* A client of a stream file: its own mts_webfile (its own connections) on
 * the shard's pool, towards the hello's stop; the prefix is its own first
 * request, as a real client's is. */
static void sc_web_start(stress *s, sclient *c)
{
    const mts_stress_options *o = s->o;
    if (!sc_decoder(s, c))
        return;
    mts_http_options ho = {0};
    ho.cacert = o->cacert;
    ho.connect_timeout = o->connect_timeout;
    ho.io_timeout = o->io_timeout;
    ho.max_bytes = o->max_file_bytes;
    ho.pool = s->pool;
    ho.on_end = sc_web_end;
    ho.end_user = c;
    c->owner = s;
    mts_error err = {0};
    mts_result rc = mts_webfile_create(&c->wf, o->url, &ho, &err);
    if (rc != MTS_OK) {
        sc_fail(s, c, MTS_STRESS_LOCAL, "%s", err.msg);
        return;
    }
    s->connected++; /* counted as a socket is: released with the webfile */
    c->state = SC_READING;
    rc = mts_webfile_begin(c->wf, c->decoder, o->hello.stop_kind, o->hello.stop_value, &err);
    if (rc != MTS_OK) {
        sc_web_fail(s, c, rc, &err);
        return;
    }
    sc_web_step(s, c);
}

/* After END: a client chosen to ask for more connects again and continues
 * to options.continue_kind/value from the batches it holds. 1 when it does
 * (or failed trying, released), 0 when it is done. */
static int sc_continues(stress *s, sclient *c)
{
    const mts_stress_options *o = s->o;
    if (!o->continue_kind || c->hello2 || c->continued)
        return 0; /* no continuation asked, or this was it */
    double share = o->continue_share > 0 && o->continue_share < 1 ? o->continue_share : 1;
    uint64_t i = (uint64_t)(c - s->c);
    if ((uint64_t)((double)(i + 1) * share) == (uint64_t)((double)i * share))
        return 0; /* not one of the share */
    uint32_t batch;
    uint64_t id;
    mts_error err = {0};
    if (mts_stream_client_continue(c->decoder, &batch, &id, &err) != MTS_OK) {
        sc_fail(s, c, MTS_STRESS_LOCAL, "continue: %s", err.msg);
        return 1;
    }
    if (c->wf) {
        /* the index is held: one range, from the first batch not held, on
         * the client's own connection when the server kept it open */
        c->continued = 1;
        c->eof = 0;
        s->rep->continuations++;
        mts_result rc = mts_webfile_begin(c->wf, c->decoder, o->continue_kind,
                                          o->continue_value, &err);
        if (rc != MTS_OK)
            sc_web_fail(s, c, rc, &err);
        else
            sc_web_step(s, c);
        return 1;
    }
    mts_wire_hello h = o->hello;
    if (h.major == 0) {
        h.major = MTS_WIRE_MAJOR;
        h.minor = MTS_WIRE_MINOR;
    }
    h.stop_kind = o->continue_kind;
    h.stop_value = o->continue_value;
    h.resume_batch = batch;
    h.stream_id = id;
    /* the form held, whatever was asked (PROTOCOL.md, "Resuming") */
    h.flags = c->decoder->records ? (uint8_t)(h.flags | MTS_HELLO_RECORDS)
                                  : (uint8_t)(h.flags & ~MTS_HELLO_RECORDS);
    mts_buf b = {0};
    mts_wire_put_hello(&b, &h);
    if (b.failed) {
        mts_buf_free(&b);
        sc_fail(s, c, MTS_STRESS_LOCAL, "out of memory");
        return 1;
    }
    c->hello2 = b.data;
    c->hello2_size = (uint32_t)b.size;
    sc_close_socket(s, c);
    c->bytes_in = 0;
    c->eof = 0;
    c->hello_sent = 0;
    c->got_info = c->got_base = 0;
    s->rep->continuations++;
    c->t_last = mts_clock_seconds(); /* the I/O timeout counts from here */
    sc_connect(s, c);
    return 1;
}

/* Apply mode: c's decoder, made the first time. 0 when out of memory (c
 * failed and released). */
static int sc_decoder(stress *s, sclient *c)
{
    if (!c->decoder) {
        c->decoder = malloc(sizeof *c->decoder);
        if (!c->decoder) {
            sc_fail(s, c, MTS_STRESS_LOCAL, "out of memory");
            return 0;
        }
        mts_stream_client_init(c->decoder);
        c->decoder->threads = s->o->decode_threads;
        c->decoder->memory = s->memory;
    }
    return 1;
}

/* Apply mode: applies c's whole frames until the deadline. 0 once c has
 * ended (succeeded or failed and released), 2 when the deadline stopped it,
 * 1 when it waits for bytes. */
static int sc_apply(stress *s, sclient *c, double deadline)
{
    if (!sc_decoder(s, c))
        return 0;
    if (c->wf)
        sc_web_bytes(s, c);
    mts_error err = {0};
    mts_stream_event ev;
    int next, done = 0;
    uint32_t splits_before = c->decoder->splits;
    while ((next = mts_stream_client_next(c->decoder, &ev, &err)) > 0) {
        if (!sc_event(s, c, ev, splits_before, &done))
            return 0; /* failed and released */
        splits_before = c->decoder->splits;
        if (done) {
            if (sc_continues(s, c))
                return 0; /* connecting again, or failed and released */
            /* the clock again, not the round's: a round of many applying
             * clients can take long enough to blur the percentiles */
            sc_succeed(s, c, mts_clock_seconds());
            return 0;
        }
        if (mts_clock_seconds() >= deadline)
            return 2;
    }
    if (next < 0) {
        mts_stress_failure why = MTS_STRESS_PROTOCOL;
        if (err.code == MTS_ERR_NOMEM)
            why = MTS_STRESS_LOCAL;
        else if (err.code == MTS_ERR_CHECKSUM && !c->decoder->rejected)
            why = MTS_STRESS_VERIFY; /* END's checksum: the mesh is not the server's */
        sc_fail(s, c, why, "%s", err.msg);
        return 0;
    }
    if (c->wf) {
        if (!c->eof)
            return 1; /* the range is still coming */
        /* every frame of the stop is applied: the file's checks stand in
         * for END's */
        mts_stream_event ev = MTS_EV_NONE;
        mts_result rc = mts_webfile_end(c->wf, c->decoder, &ev, &err);
        if (rc != MTS_OK || ev != MTS_EV_END) {
            sc_fail(s, c,
                    rc == MTS_ERR_CHECKSUM ? MTS_STRESS_VERIFY
                    : rc == MTS_ERR_NOMEM  ? MTS_STRESS_LOCAL
                                           : MTS_STRESS_PROTOCOL,
                    "%s", rc != MTS_OK ? err.msg : "the stream file's range ended without END");
            return 0;
        }
        if (sc_continues(s, c))
            return 0;
        sc_succeed(s, c, mts_clock_seconds());
        return 0;
    }
    if (c->eof) {
        sc_fail(s, c, MTS_STRESS_CLOSED, "closed before END (after %llu bytes)",
                (unsigned long long)c->bytes_in);
        return 0;
    }
    return 1;
}

/* One round of applying: the oldest unfinished clients, at most
 * max_appliers of them, each in turn until the round's time is up. 1 when
 * there is decoding left that needs no more bytes (the loop should not
 * sleep on the sockets then). */
static int apply_round(stress *s, uint32_t started, double budget)
{
    while (s->oldest < started && s->c[s->oldest].state == SC_DONE)
        s->oldest++;
    double deadline = mts_clock_seconds() + budget;
    uint32_t busy = 0;
    int left = 0;
    for (uint32_t i = s->oldest; i < started && busy < s->max_appliers; i++) {
        sclient *c = &s->c[i];
        if (c->state == SC_DONE || c->state == SC_WAITING)
            continue;
        busy++;
        if (!c->wf && c->bytes_in == 0 && !c->eof)
            continue; /* (a stream file's bytes are in its decoder: it is asked) */
        double share = (deadline - mts_clock_seconds()) / (double)(s->max_appliers - busy + 1);
        if (share <= 0)
            return 1;
        /* an ended client makes room for a waiting one, which may have
         * all its bytes already */
        int r = sc_apply(s, c, mts_clock_seconds() + share);
        left |= r != 1;
    }
    return left;
}

static void sc_read(stress *s, sclient *c, double now)
{
    /* a few reads per wake-up, then the others get their turn */
    for (int round = 0; round < 4; round++) {
        ssize_t got = mts_net_read(c->fd, s->chunk, 1 << 16);
        if (got == MTS_NET_AGAIN)
            return;
        if (got == 0 && s->o->http_path && !c->http_head && c->http_body == c->http_length) {
            sc_succeed(s, c, mts_clock_seconds());
            return;
        }
        if (got == 0 && !s->o->no_apply && !s->o->http_path) {
            /* all of it is in: applied later, END or not */
            c->eof = 1;
            sc_close_socket(s, c);
            return;
        }
        if (got == 0) {
            sc_fail(s, c, MTS_STRESS_CLOSED, "closed before END (after %llu bytes)",
                    (unsigned long long)c->bytes_in);
            return;
        }
        if (got < 0) {
            sc_fail(s, c, MTS_STRESS_CLOSED, "after %llu bytes: %s",
                    (unsigned long long)c->bytes_in, strerror(errno));
            return;
        }
        s->rep->bytes += (uint64_t)got;
        c->bytes_in += (uint64_t)got;
        c->t_last = now;
        if (s->o->no_apply && !s->o->verify && !s->o->http_path) {
            if (!sc_skim(s, c, s->chunk, (size_t)got))
                return;
            continue;
        }
        if (s->o->http_path) {
            sc_read_http(s, c, s->chunk, (size_t)got);
            if (c->state == SC_DONE)
                return;
            continue;
        }
        mts_error err = {0};
        if (!s->o->no_apply) {
            /* applied in apply_round, the oldest clients first */
            if (!sc_decoder(s, c))
                return; /* failed and released */
            if (mts_stream_client_feed(c->decoder, s->chunk, (size_t)got, &err) != MTS_OK) {
                sc_fail(s, c, err.code == MTS_ERR_NOMEM ? MTS_STRESS_LOCAL : MTS_STRESS_PROTOCOL,
                        "%s", err.msg);
                return;
            }
        } else { /* with verify: checked as it comes, cheaply */
            if (mts_wire_reader_feed(&c->reader, s->chunk, (size_t)got, &err) != MTS_OK) {
                sc_fail(s, c, err.code == MTS_ERR_NOMEM ? MTS_STRESS_LOCAL : MTS_STRESS_PROTOCOL,
                        "%s", err.msg);
                return;
            }
            uint8_t type;
            const uint8_t *p;
            size_t n;
            int next, done = 0;
            while ((next = mts_wire_reader_next(&c->reader, &type, &p, &n, &err)) > 0) {
                if (!sc_frame_light(s, c, type, p, n, &done))
                    return; /* failed and released */
                if (done) {
                    sc_succeed(s, c, mts_clock_seconds());
                    return;
                }
            }
            if (next < 0) {
                sc_fail(s, c, MTS_STRESS_PROTOCOL, "%s", err.msg);
                return;
            }
        }
        if ((size_t)got < (1u << 16))
            return; /* the socket is drained */
    }
}

static void check_timeouts(stress *s, uint32_t started, double now)
{
    double cto = s->o->connect_timeout > 0 ? s->o->connect_timeout : 10;
    double ito = s->o->io_timeout > 0 ? s->o->io_timeout : 30;
    for (uint32_t i = 0; i < started; i++) {
        sclient *c = &s->c[i];
        if (c->state == SC_CONNECTING && now - c->t_start > cto)
            sc_fail(s, c, MTS_STRESS_CONNECT, "no connection within %.0f s", cto);
        else if ((c->state == SC_SENDING || c->state == SC_READING) && c->fd >= 0 &&
                 now - c->t_last > ito)
            sc_fail(s, c, MTS_STRESS_TIMEOUT, "no data for %.0f s", ito);
    }
}

static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

/* Nearest-rank percentiles of the sorted values: p50, p90, p99, max. */
static void percentiles(float *v, uint32_t n, double out[4])
{
    memset(out, 0, 4 * sizeof *out);
    if (n == 0)
        return;
    qsort(v, n, sizeof *v, cmp_float);
    static const double q[3] = {0.50, 0.90, 0.99};
    for (int k = 0; k < 3; k++) {
        uint32_t rank = (uint32_t)ceil(q[k] * n);
        out[k] = v[(rank ? rank : 1) - 1];
    }
    out[3] = v[n - 1];
}

/* One thread's share of the clients: a loop of its own over clients
 * k, k + T, k + 2T, ... (T threads), reporting into its own report, which
 * it copies into `snap` under the lock for the caller's progress line. */
typedef struct shard {
    stress s;
    mts_stress_report rep, snap;
    uint32_t n, conc, index, count; /* its clients; this is shard index of count */
    double ramp, t0;
    pthread_mutex_t lock;
    int finished;      /* under lock: the shard's loop has ended */
    atomic_int *stop;  /* the watcher's: give up on the clients still running */
    mts_result rc;
    mts_error err;
    /* the loop's tick: the next client to start, when the last scan and
     * report were, and whether decoding is left that needs no bytes */
    uint32_t next;
    double last_progress, last_scan;
    int pending;
} shard;

static void shard_publish(shard *h, int finished)
{
    pthread_mutex_lock(&h->lock);
    h->rep.seconds = mts_clock_seconds() - h->t0;
    h->snap = h->rep;
    h->finished = finished;
    pthread_mutex_unlock(&h->lock);
}

/* A client's socket has events: the HELLO goes out while it connects and
 * sends, then bytes are read (data, or the EOF or reset a read reports). */
static void on_client(mts_loop *loop, mts_loop_io *io, unsigned events)
{
    (void)loop;
    (void)events;
    stress *s = io->user;
    sclient *c = (sclient *)(void *)((char *)io - offsetof(sclient, io));
    if (c->state == SC_DONE)
        return;
    double now = mts_clock_seconds();
    if (c->state == SC_CONNECTING || c->state == SC_SENDING)
        sc_send(s, c, now);
    else
        sc_read(s, c, now);
}

/* Between rounds: decoding, timeouts and the shard's report for what the
 * last round brought, then the clients due (the ramp spaces all the
 * threads' clients as one) under the concurrency limit. The next round's
 * longest sleep, or -1 once every client has ended or the watcher stops
 * the run. */
static int shard_tick(mts_loop *loop, void *user, double now)
{
    (void)loop;
    shard *h = user;
    stress *sp = &h->s;
    const mts_stress_options *o = sp->o;
    mts_stress_report *rep = &h->rep;
    const uint32_t n = h->n, conc = h->conc;
    if (!o->no_apply && !o->http_path)
        h->pending = apply_round(sp, h->next, 0.02);
    now = mts_clock_seconds();
    if (now - h->last_scan >= 0.1) {
        check_timeouts(sp, h->next, now);
        h->last_scan = now;
    }
    if (now - h->last_progress >= 0.1) {
        shard_publish(h, 0);
        h->last_progress = now;
    }
    if (rep->succeeded + rep->failed >= n || atomic_load_explicit(h->stop, memory_order_relaxed))
        return -1;
    while (h->next < n && sp->connected < conc &&
           (h->ramp == 0 || now - sp->t0 >= h->ramp * (double)(h->next * h->count + h->index) /
                                               (double)(n * h->count))) {
        sc_start(sp, &sp->c[h->next], now);
        h->next++;
    }
    /* decoding left that needs no bytes: do not sleep on the sockets */
    int timeout_ms = h->pending ? 0 : 100;
    if (sp->pool) {
        /* libcurl's timer, last: the clients just started are due at once */
        int ms = mts_http_pool_tick(sp->pool);
        if (ms >= 0 && ms < timeout_ms)
            timeout_ms = ms;
    }
    if (h->next < n && sp->connected < conc && h->ramp > 0) {
        double due = sp->t0 +
                     h->ramp * (double)(h->next * h->count + h->index) / (double)(n * h->count) -
                     now;
        int ms = (int)(due * 1e3) + 1;
        timeout_ms = ms < timeout_ms ? (ms > 0 ? ms : 0) : timeout_ms;
    }
    return timeout_ms;
}

static void *shard_main(void *arg)
{
    shard *h = arg;
    h->s.t0 = h->t0;
    h->last_progress = h->last_scan = h->t0;
    h->rc = mts_loop_run(&h->s.loop, shard_tick, h, &h->err);
    shard_publish(h, 1);
    return NULL;
}

static void report_add(mts_stress_report *to, const mts_stress_report *r)
{
    to->started += r->started;
    to->active += r->active;
    to->succeeded += r->succeeded;
    to->failed += r->failed;
    for (int k = 0; k < MTS_STRESS_FAILURE_KINDS; k++) {
        if (r->failures[k] && !to->failures[k])
            memcpy(to->first_error[k], r->first_error[k], sizeof to->first_error[k]);
        to->failures[k] += r->failures[k];
    }
    to->bytes += r->bytes;
    to->batches += r->batches;
    to->splits += r->splits;
    to->continuations += r->continuations;
    for (int k = 0; k < 2; k++) {
        /* every client's end against the first's: a shard whose first ended
         * elsewhere counts all its clients */
        const struct mts_stress_end *e = &r->end[k];
        struct mts_stress_end *t = &to->end[k];
        if (!e->ended)
            continue;
        if (!t->ended) {
            *t = *e;
            continue;
        }
        t->disagree += t->level != e->level || t->triangles != e->triangles ||
                               t->checksum != e->checksum
                           ? e->ended
                           : e->disagree;
        t->ended += e->ended;
    }
    if (r->seconds > to->seconds)
        to->seconds = r->seconds;
}

mts_result mts_stress_run(const mts_stress_options *o, mts_stress_report *rep, mts_error *err)
{
    memset(rep, 0, sizeof *rep);
    uint32_t n = o->clients ? o->clients : 1;
    uint32_t conc = o->concurrency && o->concurrency < n ? o->concurrency : n;
    double ramp = o->ramp > 0 ? o->ramp : 0;
    double interval = o->progress_interval > 0 ? o->progress_interval : 0.5;
    uint32_t T = o->threads;
    if (T == 0) {
        long cores = sysconf(_SC_NPROCESSORS_ONLN);
        T = cores > 0 ? (uint32_t)cores : 1;
    }
    /* each loop has at least one client, one connection and one decoder of
     * its own, so the limits asked for hold across the loops */
    if (T > conc)
        T = conc;
    if (o->appliers && T > o->appliers)
        T = o->appliers;
    if (T > 64)
        T = 64;
    rep->clients = n;
    atomic_int stop;
    atomic_init(&stop, 0);
    mts_result rc = MTS_OK;
    mts_buf hello = {0};
    struct addrinfo *addr = NULL;
    shard *hs = calloc(T, sizeof *hs);
    pthread_t *th = calloc(T, sizeof *th);
    uint32_t running = 0, made = 0;
    float *ms_final = malloc((size_t)n * sizeof *ms_final);
    float *ms_base = malloc((size_t)n * sizeof *ms_base);
    if (!hs || !th || !ms_final || !ms_base) {
        rc = mts_error_set(err, MTS_ERR_NOMEM, "out of memory for %u clients", n);
        goto done;
    }

    const char *host = o->host ? o->host : "127.0.0.1", *port = o->port ? o->port : "7447";
    if (o->url) {
        if (o->no_apply || o->http_path || (o->hello.flags & MTS_HELLO_RECORDS)) {
            rc = mts_error_set(err, MTS_ERR_ARG,
                               "a stream file's clients apply what they read, in the file's "
                               "form: no no_apply, http_path or records");
            goto done;
        }
        /* the URL and the CA file, checked once here rather than failing
         * every client (a handle costs no I/O until its first range) */
        mts_http_options ho = {0};
        ho.cacert = o->cacert;
        mts_http *probe = NULL;
        if ((rc = mts_http_create(&probe, o->url, &ho, err)) != MTS_OK) {
            if (err)
                err->code = MTS_ERR_ARG;
            rc = MTS_ERR_ARG;
            goto done;
        }
        mts_http_free(probe);
    } else if ((rc = mts_net_resolve(host, port, 0, &addr, NULL, err)) != MTS_OK) {
        rc = MTS_ERR_ARG; /* the address given does not resolve: bad usage */
        if (err)
            err->code = MTS_ERR_ARG;
        goto done;
    }
    if (o->url) {
        /* no HELLO: each client's requests are its webfile's */
    } else if (o->http_path) {
        /* HTTP/1.0: one response per connection, ended by the server's close */
        char req[1200];
        int len = snprintf(req, sizeof req, "GET /%s HTTP/1.0\r\nHost: %s\r\n\r\n",
                           o->http_path[0] == '/' ? o->http_path + 1 : o->http_path, host);
        if (len < 0 || (size_t)len >= sizeof req) {
            rc = mts_error_set(err, MTS_ERR_ARG, "HTTP path too long");
            goto done;
        }
        mts_buf_put(&hello, req, (size_t)len);
    } else {
        mts_wire_hello h = o->hello;
        if (h.major == 0) {
            h.major = MTS_WIRE_MAJOR;
            h.minor = MTS_WIRE_MINOR;
        }
        mts_wire_put_hello(&hello, &h);
    }
    if (!o->url && hello.failed) {
        rc = mts_error_set(err, MTS_ERR_NOMEM, "out of memory");
        goto done;
    }
    const double t0 = mts_clock_seconds();
    for (uint32_t k = 0; k < T; k++, made++) {
        shard *h = &hs[k];
        stress *sp = &h->s;
        h->index = k;
        h->count = T;
        h->n = n / T + (k < n % T);
        h->conc = conc / T + (k < conc % T);
        h->stop = &stop;
        h->ramp = ramp;
        h->t0 = t0;
        h->rep.clients = h->n;
        pthread_mutex_init(&h->lock, NULL);
        sp->o = o;
        sp->rep = &h->rep;
        sp->addr = addr;
        sp->hello = hello.data;
        sp->hello_size = hello.size;
        sp->max_appliers = o->appliers ? o->appliers / T + (k < o->appliers % T) : 8;
        sp->c = calloc(h->n + 1, sizeof *sp->c);
        sp->ms_final = malloc(((size_t)h->n + 1) * sizeof *sp->ms_final);
        sp->ms_base = malloc(((size_t)h->n + 1) * sizeof *sp->ms_base);
        sp->chunk = malloc(1 << 16);
        /* out of memory for it, the decoders reserve from the kernel */
        sp->memory = o->no_apply ? NULL : mts_bigmem_cache_create();
        sp->loop.epoll_fd = -1;
        sp->loop.max_events = 512;
        if (!sp->c || !sp->ms_final || !sp->ms_base || !sp->chunk) {
            rc = mts_error_set(err, MTS_ERR_NOMEM, "out of memory for %u clients", n);
            made++;
            goto done;
        }
        if ((rc = mts_loop_init(&sp->loop, err)) != MTS_OK) {
            made++;
            goto done;
        }
        if (o->url && (rc = mts_http_pool_create(&sp->pool, &sp->loop, err)) != MTS_OK) {
            made++;
            goto done;
        }
        for (uint32_t i = 0; i < h->n; i++)
            sp->c[i].fd = -1;
    }
    /* every share on a thread of its own; this one watches and reports */
    for (uint32_t k = 0; k < T; k++, running++) {
        if (pthread_create(&th[k], NULL, shard_main, &hs[k]) != 0) {
            rc = mts_error_set(err, MTS_ERR_IO, "cannot start thread %u of %u", k + 1, T);
            break;
        }
    }
    /* the watcher looks often, so the run ends when its clients do, and
     * reports at the interval asked for */
    double last_report = t0;
    for (;;) {
        mts_stress_report now_rep = {0};
        now_rep.clients = n;
        uint32_t finished = 0;
        int broken = rc != MTS_OK;
        for (uint32_t k = 0; k < running; k++) {
            pthread_mutex_lock(&hs[k].lock);
            report_add(&now_rep, &hs[k].snap);
            finished += (uint32_t)hs[k].finished;
            broken |= hs[k].finished && hs[k].rc != MTS_OK; /* its loop failed */
            pthread_mutex_unlock(&hs[k].lock);
        }
        if (finished == running || broken)
            break;
        if (o->on_progress && mts_clock_seconds() - last_report >= interval) {
            o->on_progress(o->user, &now_rep);
            last_report = mts_clock_seconds();
        }
        struct timespec d = {0, 10 * 1000 * 1000};
        nanosleep(&d, NULL);
    }
    /* after a failure the other loops give up too; their clients still
     * running are released below */
    atomic_store(&stop, 1);
    for (uint32_t k = 0; k < running; k++)
        pthread_join(th[k], NULL);
    uint32_t ok = 0;
    for (uint32_t k = 0; k < running; k++) {
        report_add(rep, &hs[k].rep);
        memcpy(ms_final + ok, hs[k].s.ms_final, (size_t)hs[k].rep.succeeded * sizeof *ms_final);
        memcpy(ms_base + ok, hs[k].s.ms_base, (size_t)hs[k].rep.succeeded * sizeof *ms_base);
        ok += hs[k].rep.succeeded;
        if (hs[k].rc != MTS_OK && rc == MTS_OK) {
            rc = hs[k].rc;
            if (err)
                *err = hs[k].err;
        }
    }
    /* report_add kept the last shard's end: the watcher's wake-up is no
     * part of the run */
    percentiles(ms_base, rep->succeeded, rep->ms_base);
    percentiles(ms_final, rep->succeeded, rep->ms_final);
    if (rep->seconds > 0) {
        rep->mb_per_s = (double)rep->bytes / 1e6 / rep->seconds;
        rep->batches_per_s = (double)rep->batches / rep->seconds;
    }
done:
    for (uint32_t k = 0; hs && k < made; k++) {
        stress *sp = &hs[k].s;
        if (sp->c) {
            for (uint32_t i = 0; i < hs[k].n; i++) {
                if (sp->c[i].state != SC_DONE && sp->c[i].state != SC_WAITING) {
                    sp->rep->active++; /* sc_release counts it down */
                    sc_release(sp, &sp->c[i]);
                }
            }
        }
        mts_http_pool_free(sp->pool); /* after its clients' handles */
        mts_loop_close(&sp->loop);
        free(sp->c);
        free(sp->ms_final);
        free(sp->ms_base);
        free(sp->chunk);
        mts_bigmem_cache_free(sp->memory); /* after every decoder of its clients */
        pthread_mutex_destroy(&hs[k].lock);
    }
    if (addr)
        freeaddrinfo(addr);
    mts_buf_free(&hello);
    free(hs);
    free(th);
    free(ms_final);
    free(ms_base);
    return rc;
}
