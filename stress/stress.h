/* Many simulated clients from one process, for load-testing a server: a
 * non-blocking event loop (common/loop.h) per thread (one per core) drives its share of N
 * conversations (no GL), each speaking the whole protocol. By default every client decodes and applies its batches
 * through the same mts_stream_client and LOD runtime as mts-client, so the
 * figures include a real client's work; with no_apply a client only reads
 * and frames what arrives (and checks each BATCH's CRC when verify is set),
 * which loads the server alone.
 *
 * Clients start evenly over `ramp` seconds, at most `concurrency` connected
 * at once; a client whose stream is all in makes room for the next. Sockets
 * are read as bytes come, whatever the decoding has reached: a thousand
 * applying clients cost a thousand clients' decoding, which takes its time,
 * but none looks stalled to the server. Each failure is counted by reason;
 * one failing client never stops the others. */
#ifndef MTS_STRESS_H
#define MTS_STRESS_H

#include <stdint.h>

#include "error.h"
#include "wire.h"

typedef enum mts_stress_failure {
    MTS_STRESS_CONNECT = 0, /* refused, unreachable, or no connection in time */
    MTS_STRESS_BUSY,        /* the server answered ERROR busy */
    MTS_STRESS_SERVER,      /* any other ERROR from the server */
    MTS_STRESS_CLOSED,      /* reset, or closed before END */
    MTS_STRESS_TIMEOUT,     /* no byte for io_timeout seconds */
    MTS_STRESS_PROTOCOL,    /* a bad frame, CRC or record */
    MTS_STRESS_VERIFY,      /* the final mesh's checksum differs from END's */
    MTS_STRESS_LOCAL,       /* out of memory or descriptors here, not the server's fault */
    MTS_STRESS_FAILURE_KINDS
} mts_stress_failure;

/* "connect", "busy", "server_error", "closed", "timeout", "protocol",
 * "verify", "local": stable names for reports and JSON. */
const char *mts_stress_failure_name(mts_stress_failure f);

typedef struct mts_stress_report {
    uint32_t clients, started, active, succeeded, failed;
    uint32_t failures[MTS_STRESS_FAILURE_KINDS];
    char first_error[MTS_STRESS_FAILURE_KINDS][160]; /* the first message of each kind */
    uint64_t bytes, batches, splits;
    uint32_t continuations; /* conversations that went on past a client's first stop */
    double seconds; /* since the first connection attempt */
    /* Filled at the end, over the clients that succeeded (0 when none): */
    double ms_base[4];  /* p50, p90, p99, max: connect started -> base mesh in */
    double ms_final[4]; /* connect started -> END checked */
    double mb_per_s, batches_per_s;
    /* Where the applying clients that succeeded ended: [0] those that
     * stopped at the hello's stop, [1] those that continued past it. Each
     * holds the first one's level, triangles and mesh checksum (END's), and
     * how many ended elsewhere -- they all asked for the same stop, so 0
     * unless a server or file is wrong in a way no CRC caught. */
    struct mts_stress_end {
        uint32_t ended; /* clients with an end recorded */
        uint32_t level;
        uint64_t triangles, checksum;
        uint32_t disagree;
    } end[2];
} mts_stress_report;

/* Zero-initialised means the defaults. */
typedef struct mts_stress_options {
    const char *host;       /* NULL: 127.0.0.1 */
    const char *port;       /* NULL: 7447 */
    mts_wire_hello hello;   /* model and stop point; major/minor filled in when zero */
    uint32_t clients;       /* 0: 1 */
    uint32_t concurrency;   /* clients connected at once; 0: all of them */
    double ramp;            /* seconds over which the clients start; 0: at once */
    uint32_t threads;       /* event loops, each with its share of the clients (and of
                             * the concurrency); 0: one per core */
    int no_apply;           /* frame only, do not decode or apply */
    uint32_t appliers;      /* applying clients decode at most this many at once, the
                             * oldest first (the others' bytes wait, read as they
                             * come, so the server sees every client keep up); 0: 8 */
    int verify;             /* with no_apply: still check every BATCH's CRC */
    uint32_t decode_threads; /* each applying client's decoder's (stream.h's threads);
                              * 0: 1, as the clients already share the cores */
    /* Previews that ask for more (PROTOCOL.md, "Continuing"; applying
     * clients only): after END at the hello's stop, a share of the clients
     * (continue_share in (0, 1]; 0: all) connects again and continues to
     * this stop (MTS_STOP_FRACTION etc.; continue_kind 0: none), checked at
     * its END as the first was. */
    uint8_t continue_kind;
    uint32_t continue_value;
    double continue_share;
    /* Not mtstream at all: GET this path over HTTP/1.0 (one response per
     * connection) and count the body, so a static file server (nginx) can be
     * measured by the same clients on the same bytes. NULL: mtstream. */
    const char *http_path;
    /* A stream file (PROTOCOL.md, "Stream files") at an http:// or https://
     * URL: each client reads it as mts-client does (client/webfile.h: the
     * prefix, then one range to its stop, END's check from the file's
     * checks), applying, over connections of its own -- every client is
     * its own user: its own keep-alive connection (or HTTP/2 connection),
     * never one shared or multiplexed with another client's. The clients
     * of a thread share one libcurl multi handle on the thread's loop
     * (http.h, mts_http_pool). NULL: mtstream over TCP to host:port.
     * The program calls mts_fetch_global_init() (fetch.h) first. */
    const char *url;
    const char *cacert;      /* with url: the CAs to trust instead of the system's */
    uint64_t max_file_bytes; /* with url: the file's size cap; 0: http.h's */
    double connect_timeout; /* 0: 10 s (a full listen queue costs SYN retries) */
    double io_timeout;      /* 0: 30 s without a byte */
    double progress_interval; /* seconds between on_progress calls; 0: 0.5 */
    void (*on_progress)(void *user, const mts_stress_report *so_far);
    void *user;
} mts_stress_options;

/* Runs every client to its end. Returns an error only when the run itself
 * cannot go on (bad options, the host does not resolve, a URL that is not
 * http or https, a CA file that cannot be read, epoll fails); client
 * failures are counted in the report, which is filled either way. */
mts_result mts_stress_run(const mts_stress_options *opts, mts_stress_report *report,
                          mts_error *err);

#endif
