/* The raw TCP transport: the conversation's bytes are the socket's, both
 * ways, with nothing around them. */
#include <stdint.h>
#include <sys/socket.h>

#include "clock.h"
#include "net.h"
#include "server_internal.h"

static void tcp_busy(mts_buf *b, const char *text)
{
    mts_wire_put_error(b, MTS_WERR_BUSY, text);
}

static int tcp_open(mts__conn *c)
{
    (void)c;
    return 0;
}

static void tcp_release(mts__conn *c)
{
    (void)c;
}

/* Reads what the client sent; its first frame is answered once all in. */
static void tcp_read(mts__conn *c)
{
    for (int rounds = 0;; rounds++) {
        if (c->phase != MTS__READING) { /* nothing more is expected: drain and ignore */
            /* a bounded drain per wake-up: a client that keeps sending cannot
             * hold the loop (the level-triggered event comes back) */
            if (rounds >= 16)
                return;
            uint8_t sink[4096];
            ssize_t r = mts_net_read(c->fd, sink, sizeof sink);
            if (r > 0)
                continue;
            if (r == 0 && c->linger_until > 0) {
                mts__conn_close(c, NULL); /* the refused client has read and closed */
            } else if (r == 0) {
                /* half-closed after its request (legal): the input event
                 * would fire forever, so stop watching it; writing goes on */
                c->rd_closed = 1;
                mts__conn_update_events(c);
            } else if (r == MTS_NET_FAILED) {
                mts__conn_close(c, "error: reset by peer");
            }
            return;
        }
        /* no more than the first frame's room: what follows it stays in the
         * socket, to be drained once it is answered */
        uint8_t buf[MTS__IN_MAX];
        ssize_t r = mts_net_read(c->fd, buf, sizeof c->in - c->in_len);
        if (r <= 0) {
            if (r == 0)
                mts__conn_close(c, "error: closed before hello");
            else if (r == MTS_NET_FAILED)
                mts__conn_close(c, "error: reset by peer");
            return;
        }
        c->last_progress = mts_clock_seconds();
        if (mts__conn_input(c, buf, (size_t)r))
            return;
    }
}

static int tcp_refuse(mts__conn *c, uint16_t code, const char *text)
{
    (void)c;
    (void)code;
    (void)text;
    return 0;
}

static int tcp_flush(mts__conn *c)
{
    (void)c;
    return 1;
}

static ssize_t tcp_send(mts__conn *c, struct iovec *iov, int n)
{
    struct msghdr msg = {0};
    msg.msg_iov = iov + 1;
    msg.msg_iovlen = (size_t)(n - 1);
    return sendmsg(c->fd, &msg, MSG_NOSIGNAL | MSG_DONTWAIT);
}

static mts__transport_end tcp_finish(mts__conn *c)
{
    (void)c;
    return MTS__END_CLOSE;
}

const mts__transport mts__tcp_transport = {
    .tag = "",
    .busy = tcp_busy,
    .open = tcp_open,
    .release = tcp_release,
    .read = tcp_read,
    .refuse = tcp_refuse,
    .flush = tcp_flush,
    .send = tcp_send,
    .finish = tcp_finish,
};
