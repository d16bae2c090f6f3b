/* The WebSocket transport (--ws-listen, for browsers): the opening request
 * while it comes (answered with the 101, or an HTTP error), then frames
 * both ways around the same conversation. The client's data frames are
 * unmasked into the conversation's input, a Ping is answered, a Close or a
 * broken frame ends the conversation with a Close frame; the conversation's
 * bytes, the shared stream buffer among them, go out uncopied in binary
 * messages behind a small header. protocol/ws.h does the parsing and the
 * framing; this file does the I/O and the rules around it. */
#include <errno.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>

#include "clock.h"
#include "net.h"
#include "server_internal.h"
#include "ws.h"

typedef struct ws_state {
    int open;                 /* the 101 is queued: frames from here */
    uint8_t req[MTS_WS_MAX_REQUEST];
    size_t req_len;
    mts_ws_reader rd;
    /* raw bytes sent between data frames: the HTTP answer, pongs, the close */
    mts_buf raw;
    size_t raw_off;
    int close_queued;
    /* the binary frame being sent: its header, and its payload still to go */
    uint8_t hdr[MTS_WS_MAX_HEADER];
    size_t hdr_len, hdr_off;
    uint64_t left;
} ws_state;

/* A server message carries at most this much of the stream: a browser sees
 * a message only once all of it is in, so a large one would hold the
 * picture back (at 10 bytes of header a message, 0.03 % more bytes). */
#define WS_MESSAGE_MAX (32u << 10)

static void ws_busy(mts_buf *b, const char *text)
{
    mts_ws_put_http_error(b, 503, text); /* before its upgrade: HTTP */
}

static int ws_open_state(mts__conn *c)
{
    c->tstate = calloc(1, sizeof(ws_state));
    return c->tstate ? 0 : -1;
}

static void ws_release(mts__conn *c)
{
    ws_state *w = c->tstate;
    if (!w)
        return;
    mts_buf_free(&w->raw);
    free(w);
    c->tstate = NULL;
}

/* Ends the connection before its upgrade with an HTTP answer (status,
 * text) once it is flushed. */
static void ws_refuse_http(mts__conn *c, int status, const char *text, const char *outcome)
{
    ws_state *w = c->tstate;
    w->raw.size = w->raw_off = 0;
    mts_ws_put_http_error(&w->raw, status, text);
    w->close_queued = 1; /* not upgraded: no Close frame */
    mts__conn_stop(c, outcome);
}

/* Before the upgrade the client is sent HTTP, and a handshake timeout is
 * its opening request's (the conversation has not begun). */
static int ws_refuse(mts__conn *c, uint16_t code, const char *text)
{
    ws_state *w = c->tstate;
    if (w->open)
        return 0;
    int timeout = code == MTS_WERR_TIMEOUT;
    w->raw.size = w->raw_off = 0;
    mts_ws_put_http_error(&w->raw, timeout ? 408 : 400,
                          timeout ? "no WebSocket opening request in time" : text);
    w->close_queued = 1;
    return 1;
}

/* Ends the conversation with a Close frame (then the usual close): for a
 * broken frame, or a Close from the client. */
static void ws_end(mts__conn *c, uint16_t code, const char *reason, const char *outcome)
{
    ws_state *w = c->tstate;
    if (!w->close_queued)
        mts_ws_put_close(&w->raw, code, reason, NULL);
    w->close_queued = 1;
    mts__conn_stop(c, outcome);
}

/* Frames from the client, buf[0..n): their payload is the conversation
 * (only its first frame matters, as over TCP); a Ping is answered, a Close
 * ends it. 0: the connection is ending. */
static int ws_frames(mts__conn *c, uint8_t *buf, size_t n)
{
    ws_state *w = c->tstate;
    mts_ws_control ctl = {0};
    mts_error err = {0};
    size_t p = 0;
    mts_result rc = mts_ws_reader_feed(&w->rd, buf, n, &p, &ctl, &err);
    if (p > 0)
        mts__conn_input(c, buf, p);
    if (rc != MTS_OK) {
        ws_end(c, ctl.fail_code, err.msg + strlen("websocket: "), "error: bad websocket frame");
        return 0;
    }
    if (ctl.ping && !w->close_queued) {
        if (w->raw.size - w->raw_off > 4096) {
            ws_end(c, MTS_WS_CLOSE_PROTOCOL, "too many pings", "error: ping flood");
            return 0;
        }
        mts_ws_put_frame(&w->raw, MTS_WS_PONG, ctl.pong, ctl.pong_len, NULL);
    }
    if (ctl.close) {
        if (!mts__conn_all_sent(c) && c->end != MTS__REFUSED)
            ws_end(c, MTS_WS_CLOSE_NORMAL, NULL,
                   c->phase == MTS__WRITING ? "error: closed by client"
                                            : "error: closed before hello");
        else if (!w->close_queued) { /* all sent already: answer the Close, end as served */
            mts_ws_put_close(&w->raw, MTS_WS_CLOSE_NORMAL, NULL, NULL);
            w->close_queued = 1;
        }
        return 0;
    }
    return 1;
}

/* The opening request is in: upgrade, or answer a plain GET with 426 (the
 * page comes from a web server, never from here). 1: upgraded (frames may
 * follow in w->req past req->size). */
static int ws_upgrade(mts__conn *c, const mts_ws_request *req)
{
    ws_state *w = c->tstate;
    if (!req->upgrade) {
        ws_refuse_http(c, 426,
                       "this port streams models over WebSocket to the page, which a web "
                       "server hands out (docs: web/nginx.conf)",
                       "error: not a websocket request");
        return 0;
    }
    mts_ws_put_accept(&w->raw, req);
    w->open = 1;
    return 1;
}

/* Reads what the client sent: its opening request, then frames. */
static void ws_read(mts__conn *c)
{
    ws_state *w = c->tstate;
    uint8_t buf[4096];
    for (int rounds = 0; rounds < 16; rounds++) {
        int opening = !w->open;
        uint8_t *dst = opening ? w->req + w->req_len : buf;
        size_t cap = opening ? sizeof w->req - w->req_len : sizeof buf;
        ssize_t r = mts_net_read(c->fd, dst, cap);
        if (r == 0) {
            if (c->linger_until > 0)
                mts__conn_close(c, NULL); /* the client has read and closed */
            else if (c->phase == MTS__READING || c->phase == MTS__WAITING)
                mts__conn_close(c, "error: closed before hello");
            else {
                c->rd_closed = 1; /* half-closed: writing goes on */
                mts__conn_update_events(c);
            }
            return;
        }
        if (r == MTS_NET_FAILED) {
            mts__conn_close(c, "error: reset by peer");
            return;
        }
        if (r < 0)
            break; /* all read: what it asked for goes out below */
        /* ending (refused, or answered without an upgrade): what it sends
         * is read and dropped, never parsed as a request again */
        if (c->linger_until > 0 || (w->close_queued && (c->end == MTS__REFUSED || !w->open)))
            continue;
        /* what a client sends is never progress (only what it takes from
         * us is): one that trickles bytes and reads nothing is idle */
        if (opening) {
            w->req_len += (size_t)r;
            mts_ws_request req;
            mts_error err = {0};
            if (mts_ws_parse_request(w->req, w->req_len, &req, &err) != MTS_OK) {
                ws_refuse_http(c, req.status, err.msg + strlen("websocket: "),
                               "error: bad websocket request");
                break;
            }
            if (req.size == 0)
                continue; /* more to come */
            if (!ws_upgrade(c, &req))
                break;
            size_t extra = w->req_len - req.size;
            memcpy(buf, w->req + req.size, extra);
            w->req_len = 0;
            if (extra > 0 && !ws_frames(c, buf, extra))
                break;
            continue;
        }
        if (!ws_frames(c, buf, (size_t)r))
            break;
    }
    if (c->fd >= 0 && (w->raw.size > w->raw_off || c->phase == MTS__WRITING))
        mts__conn_write(c);
}

/* The raw bytes (the HTTP answer, pongs, the Close), sent only between data
 * frames. */
static int ws_flush(mts__conn *c)
{
    ws_state *w = c->tstate;
    if (w->hdr_off < w->hdr_len || w->left > 0)
        return 1; /* inside a data frame: after it */
    while (w->raw_off < w->raw.size) {
        if (w->raw.failed) {
            mts__conn_close(c, "error: out of memory");
            return 0;
        }
        ssize_t k = send(c->fd, w->raw.data + w->raw_off, w->raw.size - w->raw_off,
                         MSG_NOSIGNAL | MSG_DONTWAIT);
        if (k < 0 && errno == EINTR)
            continue;
        if (k < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
            mts__conn_watch_out(c, 1);
            return 0;
        }
        if (k < 0) {
            mts__conn_close(c, errno == EPIPE ? "error: peer went away" : "error: reset by peer");
            return 0;
        }
        w->raw_off += (size_t)k;
        c->last_progress = mts_clock_seconds();
    }
    w->raw.size = w->raw_off = 0;
    return 1;
}

/* The conversation's bytes inside binary messages of at most
 * WS_MESSAGE_MAX, whose header goes first in the same sendmsg. */
static ssize_t ws_send(mts__conn *c, struct iovec *iov, int n)
{
    ws_state *w = c->tstate;
    if (w->hdr_off == w->hdr_len && w->left == 0) { /* a new message */
        uint64_t total = 0;
        for (int k = 1; k < n; k++)
            total += iov[k].iov_len;
        w->left = total < WS_MESSAGE_MAX ? total : WS_MESSAGE_MAX;
        w->hdr_len = mts_ws_header(w->hdr, MTS_WS_BINARY, w->left, NULL);
        w->hdr_off = 0;
    }
    uint64_t room = w->left;
    for (int k = 1; k < n; k++) {
        if (iov[k].iov_len >= room) {
            iov[k].iov_len = (size_t)room;
            n = k + 1;
            break;
        }
        room -= iov[k].iov_len;
    }
    int first = 1;
    if (w->hdr_off < w->hdr_len) {
        iov[0] = (struct iovec){w->hdr + w->hdr_off, w->hdr_len - w->hdr_off};
        first = 0;
    }
    struct msghdr msg = {0};
    msg.msg_iov = iov + first;
    msg.msg_iovlen = (size_t)(n - first);
    ssize_t wr = sendmsg(c->fd, &msg, MSG_NOSIGNAL | MSG_DONTWAIT);
    if (wr < 0)
        return -1;
    size_t left = (size_t)wr;
    size_t k = w->hdr_len - w->hdr_off < left ? w->hdr_len - w->hdr_off : left;
    w->hdr_off += k;
    left -= k;
    w->left -= left;
    return (ssize_t)left;
}

/* The conversation is out: the Close that ends it, and the client's
 * answering Close to wait for. */
static mts__transport_end ws_finish(mts__conn *c)
{
    ws_state *w = c->tstate;
    if (w->close_queued)
        return MTS__END_LINGER;
    mts_ws_put_close(&w->raw, MTS_WS_CLOSE_NORMAL, NULL, NULL);
    w->close_queued = 1;
    return MTS__END_MORE;
}

const mts__transport mts__ws_transport = {
    .tag = "ws/",
    .busy = ws_busy,
    .open = ws_open_state,
    .release = ws_release,
    .read = ws_read,
    .refuse = ws_refuse,
    .flush = ws_flush,
    .send = ws_send,
    .finish = ws_finish,
};
