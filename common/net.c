#include "net.h"

#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

/* getaddrinfo for a TCP stream: its result code (0 for success). */
static int net__gai(const char *host, const char *port, int passive, struct addrinfo **out)
{
    struct addrinfo hints = {0};
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    if (passive)
        hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
    *out = NULL;
    int gai = getaddrinfo(host, port, &hints, out);
    if (gai != 0)
        *out = NULL;
    return gai;
}

mts_result mts_net_resolve(const char *host, const char *port, int passive,
                           struct addrinfo **out, int *transient, mts_error *err)
{
    int gai = net__gai(host, port, passive, out);
    if (transient)
        *transient = gai == 0 || gai == EAI_AGAIN;
    if (gai != 0)
        return mts_error_set(err, MTS_ERR_IO, "%s:%s: %s", host, port, gai_strerror(gai));
    return MTS_OK;
}

void mts_net_nodelay(int fd)
{
    int one = 1;
    setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
}

int mts_net_connect_start(const struct addrinfo *a, int *fd, int *errno_out)
{
    *fd = socket(a->ai_family, a->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (*fd < 0) {
        *errno_out = errno;
        return -1;
    }
    mts_net_nodelay(*fd);
    if (connect(*fd, a->ai_addr, a->ai_addrlen) == 0)
        return 1;
    if (errno == EINPROGRESS)
        return 0;
    *errno_out = errno;
    close(*fd);
    *fd = -1;
    return -1;
}

int mts_net_connect_result(int fd)
{
    int soerr = 0;
    socklen_t sl = sizeof soerr;
    if (getsockopt(fd, SOL_SOCKET, SO_ERROR, &soerr, &sl) != 0)
        return errno ? errno : EIO;
    return soerr;
}

mts_result mts_net_listen(const char *spec, int reuse_port, int backlog, int *out,
                          mts_error *err)
{
    *out = -1;
    char host[256];
    const char *colon = strrchr(spec, ':');
    if (!colon || colon == spec || (size_t)(colon - spec) >= sizeof host)
        return mts_error_set(err, MTS_ERR_ARG, "listen address '%s' is not ADDR:PORT", spec);
    size_t hl = (size_t)(colon - spec);
    const char *h = spec;
    if (spec[0] == '[' && hl >= 2 && spec[hl - 1] == ']') { /* [::1]:7447 */
        h++;
        hl -= 2;
    }
    memcpy(host, h, hl);
    host[hl] = 0;
    struct addrinfo *res = NULL;
    int gai = net__gai(host, colon + 1, 1, &res);
    if (gai != 0)
        return mts_error_set(err, MTS_ERR_ARG, "listen address '%s': %s", spec, gai_strerror(gai));
    int fd = socket(res->ai_family, res->ai_socktype | SOCK_CLOEXEC, 0);
    int one = 1, flags = 0;
    if (fd < 0 || setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one) != 0 ||
        (reuse_port && setsockopt(fd, SOL_SOCKET, SO_REUSEPORT, &one, sizeof one) != 0) ||
        bind(fd, res->ai_addr, res->ai_addrlen) != 0 || listen(fd, backlog) != 0 ||
        (flags = fcntl(fd, F_GETFL, 0)) < 0 || fcntl(fd, F_SETFL, flags | O_NONBLOCK) != 0) {
        mts_result rc =
            mts_error_set(err, MTS_ERR_IO, "cannot listen on %s: %s", spec, strerror(errno));
        if (fd >= 0)
            close(fd);
        freeaddrinfo(res);
        return rc;
    }
    freeaddrinfo(res);
    *out = fd;
    return MTS_OK;
}

ssize_t mts_net_read(int fd, void *buf, size_t cap)
{
    for (;;) {
        ssize_t got = recv(fd, buf, cap, MSG_DONTWAIT);
        if (got >= 0)
            return got;
        if (errno == EINTR)
            continue;
        return errno == EAGAIN || errno == EWOULDBLOCK ? MTS_NET_AGAIN : MTS_NET_FAILED;
    }
}
