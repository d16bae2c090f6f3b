/* Ranged HTTP(S) GETs of one file, without blocking (libcurl's multi
 * interface), the bytes handed on as they arrive: how a client reads a
 * stream file from any web server or CDN.
 *
 * One mts_http is one URL and one libcurl handle, reused from range to
 * range so that the connection (and TLS session, and HTTP/2 where the server
 * offers it) is kept. Only http and https, for the URL and every redirect;
 * redirects bounded; TLS verified against the system's CA store, or the
 * file given (never turned off); connect, no-byte and total timeouts; the
 * file's size capped by what the server says (Content-Range's total or the
 * length of a 200).
 *
 * A server that answers a range with the whole file (200) is used anyway:
 * the bytes before the range are skipped, the transfer ends where the range
 * ends. A 206 whose Content-Range is not the range asked for, a 416, any
 * other status of 300 or more, and a body longer than its range are errors
 * that name what came. Nothing is buffered here: each piece goes to the
 * callback as libcurl hands it over.
 *
 * Every range after the first is of the same file: it is asked for with
 * If-Range and the first answer's ETag, and an answer of another ETag or
 * another size (a file rebuilt under the same name between a cut and its
 * resume) is an error that says so, never bytes mixed from two files.
 *
 * The program calls mts_fetch_global_init() once first (fetch.h). */
#ifndef MTS_HTTP_H
#define MTS_HTTP_H

#include <stddef.h>
#include <stdint.h>

#include "error.h"
#include "loop.h"

typedef struct mts_http mts_http;
typedef struct mts_http_pool mts_http_pool;

/* Zero-initialised means the defaults. */
typedef struct mts_http_options {
    const char *cacert;       /* PEM file of the CAs to trust instead of the system's */
    double connect_timeout;   /* seconds; 0: 10 */
    double io_timeout;        /* seconds without a byte; 0: 30 */
    double max_time;          /* seconds a range may take; 0: no limit here */
    uint32_t max_redirects;   /* 0: 5 */
    uint64_t max_bytes;       /* the file's size cap; 0: 1 GiB */
    /* NULL: the handle has a multi handle of its own, moved by mts_http_poll.
     * Else the pool's (see mts_http_pool below), and on_end(end_user, http)
     * is called from the pool's loop each time a range ends. */
    mts_http_pool *pool;
    void (*on_end)(void *end_user, mts_http *http);
    void *end_user;
} mts_http_options;

/* A piece of the range: its offset in the file. Returning non-zero stops
 * the transfer (mts_http_result then gives MTS_ERR_ARG, "stopped"). */
typedef int (*mts_http_on_data)(void *user, uint64_t offset, const uint8_t *data, size_t size);

/* Checks the URL (http or https only; no I/O yet). */
mts_result mts_http_create(mts_http **http, const char *url, const mts_http_options *opts,
                           mts_error *err);
void mts_http_free(mts_http *http);

/* Starts a GET of bytes [from, to) of the file. With MTS_HTTP_UP_TO a file
 * that ends before `to` is no error: the range ends with it (a client's
 * first request asks for more than small files have). */
#define MTS_HTTP_UP_TO 1
mts_result mts_http_get(mts_http *http, uint64_t from, uint64_t to, int flags,
                        mts_http_on_data fn, void *user, mts_error *err);

/* Waits at most timeout_ms (-1: until something happens) and moves the
 * transfer on; the callback runs from here. 1: still going; 0: it ended
 * (mts_http_result says how). A pooled handle is moved by its pool's loop:
 * this only says whether its range is still going, never waits. */
int mts_http_poll(mts_http *http, int timeout_ms);

/* After poll returned 0: MTS_OK when every byte of the range came, else an
 * error naming the URL (password removed) and what went wrong. */
mts_result mts_http_result(mts_http *http, mts_error *err);

/* Stops a transfer under way (the connection is closed). */
void mts_http_cancel(mts_http *http);

/* What the last response said: the file's size (0 when not told), the
 * status, the bytes received in the body (all of them: for a 200, those
 * skipped before the range too), and the HTTP version (2 for HTTP/2). */
typedef struct mts_http_info {
    uint64_t file_size;
    long status;
    uint64_t body_bytes;
    int http_version;
    int whole_file; /* the server ignored the range */
    /* how the last transfer ended, for callers that count failures by
     * kind: no byte or no connection in time; no connection at all (refused,
     * unreachable, no TLS handshake) */
    int timed_out, no_connection;
} mts_http_info;
mts_http_info mts_http_last(const mts_http *http);

/* The URL as it may be shown (no password). */
const char *mts_http_url(const mts_http *http);

/* ---- many transfers on one event loop ----------------------------------
 *
 * A pool is one libcurl multi handle whose sockets and timer are watched by
 * an mts_loop (common/loop.h): a thousand handles on one thread cost one
 * epoll, not a thousand multi handles each polled. libcurl multi handles
 * are not shared between threads: one pool a loop, one loop a thread.
 *
 * Each handle in a pool still has connections of its own: its own
 * connection cache (a libcurl share of its own), so the ranges of one
 * handle reuse its keep-alive connection (and HTTP/2 where offered), and
 * no two handles ever share a connection or multiplex over one -- a pool of
 * simulated users loads a server as that many users do. What they do share
 * is the multi handle's DNS cache and the CA store libcurl caches per multi
 * handle (not per connection, so a thousand TLS handshakes do not parse the
 * CA file a thousand times).
 *
 * The loop's owner calls mts_http_pool_tick before each round (libcurl's
 * timeouts, retries and connection timers are run from it) and sleeps at
 * most what it returns. A handle's on_end runs from the tick or from a
 * socket's event, never from inside libcurl: it may start the handle's
 * next range, or free it. Free the pool after every handle in it. */
mts_result mts_http_pool_create(mts_http_pool **pool, mts_loop *loop, mts_error *err);
void mts_http_pool_free(mts_http_pool *pool);

/* Runs libcurl's timer when it is due; the milliseconds until it is due
 * next, or -1 when none is set. */
int mts_http_pool_tick(mts_http_pool *pool);

#endif
