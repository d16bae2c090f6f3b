/* One client conversation with a server: connect (with a timeout), send the
 * HELLO or LIST, then read the stream as it arrives and hand every frame to
 * an mts_stream_client, calling back after each event so a renderer can
 * follow. The socket never blocks past the I/O timeout; a server that dies
 * mid-stream leaves the client at its last whole batch and an error that
 * says so. */
#ifndef MTS_SESSION_H
#define MTS_SESSION_H

#include <stdint.h>

#include "error.h"
#include "stream.h"
#include "wire.h"

/* Zero-initialised means the defaults. */
typedef struct mts_session_options {
    const char *host;       /* NULL: 127.0.0.1 */
    const char *port;       /* NULL: 7447 */
    double connect_timeout; /* seconds; 0: 5 */
    double io_timeout;      /* seconds without a byte; 0: 30 */
    mts_wire_hello hello;   /* major/minor are filled in when zero */
    int list;               /* send LIST instead of HELLO */
    /* after each event; returning non-zero stops the session (MTS_ERR_ARG) */
    int (*on_event)(void *user, mts_stream_event ev, mts_stream_client *c);
    void *user;
} mts_session_options;

typedef struct mts_session_stats {
    uint64_t bytes;
    double ms_connect; /* connected */
    double ms_info;    /* MODEL_INFO taken */
    double ms_base;    /* base mesh in place (callbacks included, e.g. a first draw) */
    double ms_final;   /* END checked */
    double ms_apply;   /* time spent decoding and applying frames */
    uint32_t frames;
} mts_session_stats;

/* Runs to END (MTS_OK), an ERROR from the server (MTS_ERR_FORMAT with its
 * text; c->error_code says which), or a failure. */
mts_result mts_session_run(const mts_session_options *opts, mts_stream_client *c,
                           mts_session_stats *stats, mts_error *err);

#endif
