/* One client conversation with a server: connect (with a timeout), send the
 * HELLO or LIST, then read the stream as it arrives and hand every frame to
 * an mts_stream_client, calling back after each event so a renderer can
 * follow. The socket never blocks past the I/O timeout; a server that dies
 * mid-stream leaves the client at its last whole batch and an error that
 * says so -- or, with `resume`, the session waits (exponential backoff with
 * jitter), connects again and asks for the stream from the first batch it
 * does not hold, a bounded number of times. */
#ifndef MTS_SESSION_H
#define MTS_SESSION_H

#include <stdint.h>

#include "error.h"
#include "stream.h"
#include "wire.h"

/* What on_retry is told: what broke, where the stream stands, what comes. */
typedef struct mts_session_retry {
    const char *reason; /* the error that ended the last try */
    int have_base;      /* the base is in: the stream resumes at batch `batches` */
    uint32_t batches;   /* batches applied */
    uint32_t attempt;   /* 1..max_tries: the try about to be made */
    uint32_t max_tries;
    double delay;       /* seconds it waits first */
} mts_session_retry;

/* Zero-initialised means the defaults. */
typedef struct mts_session_options {
    const char *host;       /* NULL: 127.0.0.1 */
    const char *port;       /* NULL: 7447 */
    double connect_timeout; /* seconds; 0: 5 */
    double io_timeout;      /* seconds without a byte; 0: 30 */
    double max_time;        /* seconds for the whole session, waits and resumes
                             * included, so that a server trickling a valid
                             * stream cannot hold a client forever; 0: 600 */
    mts_wire_hello hello;   /* major/minor are filled in when zero */
    int list;               /* send LIST instead of HELLO */
    /* When set, the stream comes from this stream file on a web server
     * instead (webfile.h; host, port and list unused): each conversation
     * is a range request, a resume asks for the batches not held, and the
     * file's checks stand for END. The caller's, kept across sessions so
     * that its index is read once; its own options hold the timeouts. */
    struct mts_webfile *file;
    /* When set, the TCP stream inside TLS (tls.h), as a TLS terminator in
     * front of mts-server offers it: the certificate verified against the
     * system's CAs or tls->cacert; a certificate that does not verify is
     * no connection error and is not retried. */
    const struct mts_tls_options *tls;
    /* after each event; returning non-zero stops the session (MTS_ERR_ARG) */
    int (*on_event)(void *user, mts_stream_event ev, mts_stream_client *c);
    void *user;
    /* Resume: on a connection error (connect refused or timed out, reset,
     * EOF before END, no byte for io_timeout) wait, reconnect and send HELLO
     * with resume_batch = the batches applied and the stream_id. Each try
     * counts, a failed connect included; a conversation that applied
     * something (base, batch, END) starts the count again. An ERROR from
     * the server (unknown model, stale stream, busy) is its answer, not a
     * broken connection, and a stream that fails its checks would fail
     * again: neither is retried. */
    int resume;
    uint32_t max_tries;     /* tries after a break before giving up; 0: 8 */
    double backoff_initial; /* seconds before the first try; 0: 0.1 */
    double backoff_max;     /* the wait doubles up to this; 0: 2 */
    /* before each wait (the library never prints); non-zero gives up */
    int (*on_retry)(void *user, const mts_session_retry *r);
} mts_session_options;

typedef struct mts_session_stats {
    uint64_t bytes;
    double ms_connect; /* connected */
    double ms_info;    /* MODEL_INFO taken */
    double ms_base;    /* base mesh in place (callbacks included, e.g. a first draw) */
    double ms_final;   /* END checked */
    double ms_apply;   /* time spent decoding and applying frames */
    uint32_t frames;
    uint32_t reconnects; /* connections made after a break (resume only) */
} mts_session_stats;

/* Runs to END (MTS_OK), an ERROR from the server (MTS_ERR_FORMAT with its
 * text; c->error_code says which), or a failure; with resume, a connection
 * error only after max_tries tries (the message names the last error).
 * Times in stats run from the first connect. */
mts_result mts_session_run(const mts_session_options *opts, mts_stream_client *c,
                           mts_session_stats *stats, mts_error *err);

/* The same session in steps, for a caller that must not block (a window
 * loop draws between steps): begin, then poll until it returns 0, then end.
 * mts_session_run is exactly this with an unbounded wait per poll.
 *
 * mts_session_poll waits at most timeout_ms for the network (0: not at all;
 * -1: until something happens or a timeout of the options runs out), then
 * does at most a few milliseconds of decoding and applying (whole frames;
 * on_event runs from here, on the caller's thread) and returns: 1 while the
 * session goes on, 0 once it has ended. Connecting and the resume backoff
 * are steps too (only resolving a host name may block: give an address).
 * mts_session_fd is the socket being waited on (-1 between connections),
 * for a caller that polls it with other descriptors.
 *
 * mts_session_end returns what mts_session_run would have (err filled on a
 * failure) and frees the session; before poll returned 0 it closes the
 * connection and returns MTS_ERR_ARG ("stopped by the caller"). The options
 * must stay valid until then. begin fails only when out of memory. */
typedef struct mts_session mts_session;

mts_result mts_session_begin(const mts_session_options *opts, mts_stream_client *c,
                             mts_session_stats *stats, mts_session **session, mts_error *err);
int mts_session_poll(mts_session *session, int timeout_ms);
int mts_session_fd(const mts_session *session);
mts_result mts_session_end(mts_session *session, mts_error *err);

#endif
