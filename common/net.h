/* The sockets under the client, the load generator and the server: name
 * resolution, a non-blocking connect, a listener. A small layer apart from
 * their loops (Redis's anet.c is the model): each call reports failure as an
 * mts_result with the error named, or as the errno it hit, and never prints.
 * Every socket is close-on-exec; connected ones have TCP_NODELAY (a stream's
 * frames go out as they are made). */
#ifndef MTS_NET_H
#define MTS_NET_H

#include <netdb.h>
#include <sys/types.h>

#include "error.h"

/* getaddrinfo for a TCP stream to (or, `passive`, on) host:port. *transient
 * (may be NULL) says whether trying again later can help: a name that does
 * not resolve will not, unless the resolver itself failed for now. Free *out
 * with freeaddrinfo. */
mts_result mts_net_resolve(const char *host, const char *port, int passive,
                           struct addrinfo **out, int *transient, mts_error *err);

/* Starts a non-blocking connect to a: 1 connected already, 0 under way (poll
 * *fd for writing, then mts_net_connect_result), -1 failed with *errno_out
 * (*fd is then -1). */
int mts_net_connect_start(const struct addrinfo *a, int *fd, int *errno_out);

/* A connect under way on fd, once it is writable: 0 when it succeeded, else
 * the errno it failed with. */
int mts_net_connect_result(int fd);

/* TCP_NODELAY on a connected socket (an accepted one too). */
void mts_net_nodelay(int fd);

/* A non-blocking listening socket on spec, "ADDR:PORT" ("[::1]:7447" for
 * IPv6), with SO_REUSEADDR (and SO_REUSEPORT when reuse_port, so several
 * processes share the port) and an accept queue of `backlog`. */
mts_result mts_net_listen(const char *spec, int reuse_port, int backlog, int *fd,
                          mts_error *err);

/* What fd has now, at most cap bytes into buf, without blocking (an
 * interrupted read is retried): > 0 the bytes read, 0 the peer closed,
 * MTS_NET_AGAIN nothing yet, MTS_NET_FAILED an error left in errno. */
enum { MTS_NET_AGAIN = -1, MTS_NET_FAILED = -2 };
ssize_t mts_net_read(int fd, void *buf, size_t cap);

#endif
