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
static int connect_bounded(const char *host, const char *port, double timeout, mts_error *err)
{
    struct addrinfo hints = {0}, *res = NULL;
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    int gai = getaddrinfo(host, port, &hints, &res);
    if (gai != 0) {
        mts_error_set(err, MTS_ERR_IO, "%s:%s: %s", host, port, gai_strerror(gai));
        return -1;
    }
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

mts_result mts_session_run(const mts_session_options *o, mts_stream_client *c,
                           mts_session_stats *st, mts_error *err)
{
    memset(st, 0, sizeof *st);
    const char *host = o->host ? o->host : "127.0.0.1", *port = o->port ? o->port : "7447";
    double cto = o->connect_timeout > 0 ? o->connect_timeout : 5;
    double ito = o->io_timeout > 0 ? o->io_timeout : 30;
    double t0 = now_ms();
    int fd = connect_bounded(host, port, cto, err);
    if (fd < 0)
        return err ? err->code : MTS_ERR_IO;
    int one = 1;
    setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    st->ms_connect = now_ms() - t0;

    mts_buf req = {0};
    if (o->list) {
        mts_wire_put_list(&req);
    } else {
        mts_wire_hello h = o->hello;
        if (h.major == 0) {
            h.major = MTS_WIRE_MAJOR;
            h.minor = MTS_WIRE_MINOR;
        }
        mts_wire_put_hello(&req, &h);
    }
    mts_result rc = req.failed ? mts_error_set(err, MTS_ERR_NOMEM, "out of memory")
                               : send_all(fd, req.data, req.size, ito, err);
    mts_buf_free(&req);
    mts_wire_reader r = {0};
    static const size_t chunk = 1 << 16;
    uint8_t *buf = rc == MTS_OK ? malloc(chunk) : NULL;
    if (rc == MTS_OK && !buf)
        rc = mts_error_set(err, MTS_ERR_NOMEM, "out of memory");
    int done = 0;
    while (rc == MTS_OK && !done) {
        struct pollfd pf = {fd, POLLIN, 0};
        int pr = poll(&pf, 1, (int)(ito * 1000));
        if (pr == 0) {
            rc = mts_error_set(err, MTS_ERR_IO, "no data from the server for %.0f s", ito);
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
            break;
        }
        if (got < 0) {
            if (errno == EINTR || errno == EAGAIN || errno == EWOULDBLOCK)
                continue;
            rc = mts_error_set(err, MTS_ERR_IO, "connection lost after %llu bytes (%s)",
                               (unsigned long long)st->bytes, strerror(errno));
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
                rc = err ? err->code : MTS_ERR_FORMAT;
                break;
            }
            double a = now_ms();
            mts_stream_event ev;
            rc = mts_stream_client_frame(c, type, p, n, &ev, err);
            st->ms_apply += now_ms() - a;
            st->frames++;
            if (rc != MTS_OK)
                break;
            if (o->on_event && o->on_event(o->user, ev, c)) {
                rc = mts_error_set(err, MTS_ERR_ARG, "stopped by the caller");
                break;
            }
            double t = now_ms() - t0;
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
                done = 1;
            }
        }
    }
    free(buf);
    mts_wire_reader_free(&r);
    close(fd);
    return rc;
}
