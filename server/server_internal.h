/* Private to the server: a connection as the conversation (server.c) and
 * its transport share it. Not the public API (server.h): mts__ names.
 *
 * The conversation (HELLO or LIST in; MODEL_INFO, the stream's range and
 * END out) is the same bytes whatever carries them. A transport carries
 * them: raw TCP (tcp_conn.c), or WebSocket for browsers (ws_conn.c), which
 * has a handshake of its own, frames both ways and control frames. The
 * conversation calls its connection's transport only through the table
 * below, and a transport calls the conversation back only through the
 * mts__conn_ calls after it, so neither knows how the other works. */
#ifndef MTS_SERVER_INTERNAL_H
#define MTS_SERVER_INTERNAL_H

#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>
#include <sys/uio.h>

#include "bytes.h"
#include "loop.h"
#include "server.h"
#include "wire.h"

/* MTS__WAITING: a HELLO for a model whose stream is still being encoded */
typedef enum mts__phase { MTS__READING = 0, MTS__WAITING, MTS__WRITING } mts__phase;

/* How a conversation ends, as the stats count it (the log says more). */
typedef enum mts__conn_end { MTS__OPEN = 0, MTS__SERVED, MTS__REFUSED } mts__conn_end;

/* What a transport does once the conversation's bytes are all out. */
typedef enum mts__transport_end {
    MTS__END_CLOSE = 0, /* nothing: the conversation closes as it would anyway */
    MTS__END_MORE,      /* it queued closing bytes of its own: write on */
    MTS__END_LINGER     /* its peer answers the end: shut our side and wait for it */
} mts__transport_end;

typedef struct mts__conn mts__conn;

/* A transport: how a listener's connections carry the conversation. */
typedef struct mts__transport {
    const char *tag; /* before the peer's address in the log */
    /* the answer to a client over the connection limit, sent before anything
     * of it is read */
    void (*busy)(mts_buf *b, const char *text);
    /* its state for a new connection (c->tstate): 0, or -1 out of memory */
    int (*open)(mts__conn *c);
    /* frees that state; the conversation closes the socket */
    void (*release)(mts__conn *c);
    /* the socket is readable: reads what it has, handing the conversation
     * its bytes (mts__conn_input), and closes on EOF or an error */
    void (*read)(mts__conn *c);
    /* the conversation refuses the client (code, text): 1 when the transport
     * has answered it in its own terms (its handshake is not through, so an
     * ERROR frame would mean nothing to the client), 0 for the ERROR frame */
    int (*refuse)(mts__conn *c, uint16_t code, const char *text);
    /* sends bytes of its own that go before the conversation's: 1 none left,
     * 0 the socket is full (output is watched) or the connection closed */
    int (*flush)(mts__conn *c);
    /* sends what it can of the conversation's bytes iov[1..n), iov[0] being
     * free for a header of its own: how many of the conversation's bytes
     * went, or -1 with errno */
    ssize_t (*send)(mts__conn *c, struct iovec *iov, int n);
    /* the conversation's bytes are all out */
    mts__transport_end (*finish)(mts__conn *c);
} mts__transport;

extern const mts__transport mts__tcp_transport, mts__ws_transport;

/* A client's first frame is a HELLO or LIST: small, so it fits here. */
#define MTS__IN_MAX 512

struct mts__conn {
    int fd;
    mts__phase phase;
    const mts__transport *tr;
    void *tstate;               /* the transport's own (NULL for TCP) */
    uint8_t in[MTS__IN_MAX];
    size_t in_len;
    const mts_stream *stream;
    mts_server_model *waits_for; /* WAITING: the model, and the HELLO to answer */
    mts_wire_hello hello;
    mts_buf head, tail;         /* per-connection frames around the shared body */
    size_t head_off, tail_off;
    size_t info_off, info_size; /* MODEL_INFO's shared tail, sent right after head */
    size_t body_off, body_end;  /* range of stream->bytes still to send */
    uint64_t sent;
    double started, last_progress;
    double answered;            /* when the HELLO was answered: pacing counts from here */
    double paced_until;         /* > 0: over its rate; output resumes then */
    uint32_t stop_level;
    int watching_out;
    int rd_closed;              /* the peer shut down its side: stop watching for input */
    double linger_until;        /* > 0: a refusal is sent and our side shut; wait for the
                                   peer's close so it reads the ERROR instead of a reset */
    mts_loop_io io;             /* its descriptor in the server's loop */
    struct mts_server *server;
    /* set when the conversation has an end in sight: whether it counts as
     * served, and the log's words for it */
    mts__conn_end end;
    const char *outcome;
    char peer[64];
    char model[MTS_WIRE_MAX_NAME + 1];
    mts__conn *prev, *next;
    mts__conn *pprev, *pnext; /* on the paced list while paced_until > 0 */
};

/* ---- the conversation's calls for transports (server.c) ------------------- */

/* The client's bytes of the conversation, buf[0..n): taken while its first
 * frame is read, which is then answered (or refused); ignored after it.
 * 1: answered or refused. */
int mts__conn_input(mts__conn *c, const uint8_t *buf, size_t n);

/* Writes what is due: the transport's own bytes, then the conversation's. */
void mts__conn_write(mts__conn *c);

/* Closes c: with `failure`, it failed so (a reset, a timeout); else it ends
 * as it was set to (served, refused, or closed before either). */
void mts__conn_close(mts__conn *c, const char *failure);

/* The transport ends the conversation (a broken frame, the client closing):
 * nothing more of it is sent, and it ends as refused with `outcome`. */
void mts__conn_stop(mts__conn *c, const char *outcome);

/* 1: the conversation was served and every byte of it is out. */
int mts__conn_all_sent(const mts__conn *c);

/* The loop's watch on c, after c->rd_closed changed; output on or off. */
void mts__conn_update_events(mts__conn *c);
void mts__conn_watch_out(mts__conn *c, int on);

#endif
