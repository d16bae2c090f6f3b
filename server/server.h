/* The streaming server: one non-blocking event loop (common/loop.h) that
 * accepts clients, reads each one's HELLO (or LIST), and writes it its
 * model's wire stream straight from the stream's immutable buffer with
 * sendmsg (a connection is a few offsets, never a copy), then END.
 *
 * Every connection is bounded: a handshake timeout for the first frame, an
 * idle timeout while its socket will not take bytes, a connection limit
 * (a client over it gets ERROR busy). A client that resets or vanishes is
 * closed and counted; everyone else is served on. Each connection ends with
 * one log line through the log callback (peer, model, bytes, level, time,
 * outcome); the library itself never prints. */
#ifndef MTS_SERVER_H
#define MTS_SERVER_H

#include <signal.h>
#include <stdatomic.h>
#include <stdint.h>

#include "error.h"
#include "stream.h"

/* Zero-initialised means the defaults. */
/* What a log line is about. */
typedef enum mts_server_log_kind {
    MTS_SERVER_LOG_CONNECTION, /* one line per connection as it ends (peer=... outcome=...) */
    MTS_SERVER_LOG_STATS,      /* the periodic "stats:" line (stats_interval) */
    MTS_SERVER_LOG_NOTICE      /* the server itself: accept failing, stopping */
} mts_server_log_kind;

typedef struct mts_server_options {
    const char *listen;       /* "ADDR:PORT"; NULL: 127.0.0.1:7447; port 0 picks one */
    const char *ws_listen;    /* "ADDR:PORT" for WebSocket clients (browsers); NULL: none */
    uint32_t max_clients;     /* 0: 1024 */
    double handshake_timeout; /* seconds for the first frame; 0: 10 */
    double idle_timeout;      /* seconds a connection may make no progress; 0: 30 */
    double grace;             /* seconds streams may finish after stop; 0: 5 */
    double prepare_wait;      /* seconds a HELLO waits for its model's stream, while that is
                                 still being encoded, before ERROR busy; 0: 60 */
    double rate_limit;        /* bytes/s per connection (previews at a realistic pace); 0: none */
    double stats_interval;    /* seconds between "stats:" log lines; 0: none */
    int reuse_port;           /* SO_REUSEPORT: several servers (workers) share the port */
    int sndbuf;               /* SO_SNDBUF of each connection, bytes; 0: the kernel's autotuning
                                 (Linux: up to tcp_wmem's max, 4 MiB, per connection) */
    /* every log line, with what it is about, so that a caller can drop the
     * per-connection ones (mts-server --quiet) and keep the rest */
    void (*log)(void *user, mts_server_log_kind kind, const char *line);
    void *log_user;
} mts_server_options;

typedef struct mts_server_stats {
    uint64_t accepted, completed, failed, busy, bytes;
    uint32_t peak; /* most connections open at once */
} mts_server_stats;

typedef struct mts_server mts_server;

/* A model a server serves, whose stream another thread may still be
 * encoding: the server listens at once and answers LIST with every model
 * (stream_bytes 0 while it is prepared); a HELLO for a model not yet ready
 * waits (up to prepare_wait) and is then served, or gets ERROR busy, or,
 * when the model failed, ERROR internal with the reason. Zero-initialised
 * but for the name and figures: preparing. */
typedef struct mts_server_model {
    char name[MTS_WIRE_MAX_NAME + 1];
    uint32_t vertices, triangles, levels; /* of the full level, for LIST */
    _Atomic(const mts_stream *) stream;   /* published once, then read-only */
    _Atomic(const mts_stream *) records;  /* its records form, may come later: a
                                             client asking for it before gets the
                                             splits form, as from a server without */
    atomic_int records_settled;           /* 1: records holds all it ever will */
    atomic_int failed;                    /* 1: it never will be; why says why */
    char why[200];
} mts_server_model;

/* Fills m for a model whose stream is still to come (published later). */
void mts_server_model_init_preparing(mts_server_model *m, const char *name,
                                     const mts_model *model);
/* Fills m for a stream that is ready now. */
void mts_server_model_init_ready(mts_server_model *m, const mts_stream *stream);
/* From the preparing thread: the stream is ready (it must then outlive the
 * servers), or it failed (why is copied). */
void mts_server_model_publish(mts_server_model *m, const mts_stream *stream);
/* The records form is ready, or (NULL) none will come. A client resuming a
 * records-form stream waits for it (up to prepare_wait) until then: the splits
 * form, with another stream_id, would send it back to the start. */
void mts_server_model_publish_records(mts_server_model *m, const mts_stream *records_form);
void mts_server_model_fail(mts_server_model *m, const char *why);

/* models (and every stream published into them) must outlive the server;
 * several servers (workers) may share one table. */
mts_result mts_server_create_models(const mts_server_options *opts, mts_server_model *models,
                                    uint32_t model_count, mts_server **out, mts_error *err);

/* The same for streams that are all ready (the server keeps its own table). */
mts_result mts_server_create(const mts_server_options *opts, const mts_stream *const *streams,
                             uint32_t stream_count, mts_server **out, mts_error *err);
void mts_server_free(mts_server *s);

/* The port actually bound (useful with port 0), and the WebSocket one (0:
 * none). */
int mts_server_port(const mts_server *s);
int mts_server_ws_port(const mts_server *s);

/* Serves until *stop becomes non-zero (a signal handler sets it, or another
 * thread: an atomic, lock-free, so both may), then stops accepting, lets
 * streams finish within the grace period and returns. */
mts_result mts_server_run(mts_server *s, const atomic_int *stop, mts_error *err);

void mts_server_get_stats(const mts_server *s, mts_server_stats *stats);

#endif
