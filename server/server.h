/* The streaming server's event loop: one non-blocking epoll loop that
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
#include <stdint.h>

#include "error.h"
#include "stream.h"

/* Zero-initialised means the defaults. */
typedef struct mts_server_options {
    const char *listen;       /* "ADDR:PORT"; NULL: 127.0.0.1:7447; port 0 picks one */
    uint32_t max_clients;     /* 0: 1024 */
    double handshake_timeout; /* seconds for the first frame; 0: 10 */
    double idle_timeout;      /* seconds a connection may make no progress; 0: 30 */
    double grace;             /* seconds streams may finish after stop; 0: 5 */
    double rate_limit;        /* bytes/s per connection (previews at a realistic pace); 0: none */
    double stats_interval;    /* seconds between "stats:" log lines; 0: none */
    int reuse_port;           /* SO_REUSEPORT: several servers (workers) share the port */
    int sndbuf;               /* SO_SNDBUF of each connection, bytes; 0: the kernel's autotuning
                                 (Linux: up to tcp_wmem's max, 4 MiB, per connection) */
    void (*log)(void *user, const char *line);
    void *log_user;
} mts_server_options;

typedef struct mts_server_stats {
    uint64_t accepted, completed, failed, busy, bytes;
    uint32_t peak; /* most connections open at once */
} mts_server_stats;

typedef struct mts_server mts_server;

/* streams must outlive the server. */
mts_result mts_server_create(const mts_server_options *opts, const mts_stream *const *streams,
                             uint32_t stream_count, mts_server **out, mts_error *err);
void mts_server_free(mts_server *s);

/* The port actually bound (useful with port 0). */
int mts_server_port(const mts_server *s);

/* Serves until *stop becomes non-zero (a signal handler sets it), then stops
 * accepting, lets streams finish within the grace period and returns. */
mts_result mts_server_run(mts_server *s, volatile sig_atomic_t *stop, mts_error *err);

void mts_server_get_stats(const mts_server *s, mts_server_stats *stats);

#endif
