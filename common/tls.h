/* A TLS client connection for the stream protocol, for a server behind a
 * TLS terminator (nginx's `stream` module with ssl, docker/nginx-tls.conf):
 * the bytes are the same as over plain TCP, only wrapped.
 *
 * It is libcurl's connect-only mode: libcurl resolves, connects and does the
 * TLS handshake without blocking (its multi interface), verifies the
 * server's certificate and name exactly as for the stream files over
 * https (the system's CA store, or the file given; never turned off), and
 * then hands over a channel to send and receive raw bytes. So the client has
 * one TLS policy and one TLS library for both ways of reaching a server, and
 * no TLS code of its own.
 *
 * The program calls mts_fetch_global_init() once first (fetch.h). */
#ifndef MTS_TLS_H
#define MTS_TLS_H

#include <stddef.h>
#include <sys/types.h>

#include "error.h"

/* Zero-initialised means the defaults. */
typedef struct mts_tls_options {
    const char *cacert;     /* PEM file of the CAs to trust instead of the system's */
    double connect_timeout; /* seconds for the connect and the handshake; 0: 10 */
} mts_tls_options;

typedef struct mts_tls mts_tls;

/* Starts connecting to host:port (a name or a numeric address; IPv6 as is,
 * without brackets). No I/O yet beyond what libcurl starts at once. */
mts_result mts_tls_start(mts_tls **tls, const char *host, const char *port,
                         const mts_tls_options *opts, mts_error *err);
void mts_tls_free(mts_tls *tls);

/* Moves the connect and handshake on, waiting at most timeout_ms (-1: up
 * to a second). 1: ready to send and receive; 0: not yet; -1: failed (err
 * names the host and why: refused, timed out, the certificate). A failure
 * of the network (refused, timed out, reset) is MTS_ERR_IO, one of the
 * certificate or of the TLS handshake is MTS_ERR_ARG: trying again cannot
 * cure it. */
int mts_tls_step(mts_tls *tls, int timeout_ms, mts_error *err);

/* The socket to wait on once ready (-1 before). Wait on it only after
 * mts_tls_read said MTS_NET_AGAIN: TLS may hold bytes already decrypted. */
int mts_tls_fd(const mts_tls *tls);

/* Sends all of it, waiting at most timeout seconds for room. */
mts_result mts_tls_send_all(mts_tls *tls, const void *data, size_t size, double timeout,
                            mts_error *err);

/* As mts_net_read: bytes read, 0 when the server closed the connection,
 * MTS_NET_AGAIN when nothing is there yet, MTS_NET_FAILED on an error (err
 * says which). */
ssize_t mts_tls_read(mts_tls *tls, void *buf, size_t cap, mts_error *err);

#endif
