/* WebSocket (RFC 6455) for browsers, which cannot open a TCP stream: the
 * opening handshake and the framing, both sides. The conversation inside is
 * the TCP one, byte for byte (wire.h): binary messages carry each side's
 * bytes in order and their boundaries mean nothing, so the server sends its
 * shared stream buffers uncopied behind a frame header of 2 to 10 bytes.
 * No extensions (permessage-deflate: the stream is entropy-coded already),
 * no subprotocol. Every parser bounds what it reads and names what is wrong;
 * nothing here does I/O. */
#ifndef MTS_WS_H
#define MTS_WS_H

#include <stddef.h>
#include <stdint.h>

#include "bytes.h"
#include "error.h"

/* An opening request, its headers and all, must fit this (browsers send
 * about 500 bytes). */
#define MTS_WS_MAX_REQUEST 4096
/* The longest frame header: 2 bytes, an 8-byte length, a 4-byte mask. */
#define MTS_WS_MAX_HEADER 14
/* The longest message a reader takes by default: a client's are HELLO or
 * LIST, a few hundred bytes. */
#define MTS_WS_MAX_MESSAGE (64u << 10)
#define MTS_WS_MAX_PATH 256

typedef enum mts_ws_opcode {
    MTS_WS_CONTINUATION = 0,
    MTS_WS_TEXT = 1,
    MTS_WS_BINARY = 2,
    MTS_WS_CLOSE = 8,
    MTS_WS_PING = 9,
    MTS_WS_PONG = 10
} mts_ws_opcode;

/* Close codes (RFC 6455 7.4.1) a peer is sent. */
enum {
    MTS_WS_CLOSE_NORMAL = 1000,
    MTS_WS_CLOSE_GOING_AWAY = 1001,
    MTS_WS_CLOSE_PROTOCOL = 1002,
    MTS_WS_CLOSE_UNSUPPORTED = 1003, /* a text message: this protocol is binary */
    MTS_WS_CLOSE_NONE = 1005,        /* a Close without a code (never sent) */
    MTS_WS_CLOSE_INVALID_DATA = 1007, /* text that is not UTF-8 (a Close's reason) */
    MTS_WS_CLOSE_TOO_BIG = 1009,
    MTS_WS_CLOSE_INTERNAL = 1011
};

/* ---- the opening handshake ----------------------------------------------- */

typedef struct mts_ws_request {
    size_t size;   /* bytes of the request up to its blank line; 0: not all in yet */
    int upgrade;   /* 1: a WebSocket opening; 0: a plain GET (answered 426) */
    int status;    /* on an error: the HTTP status to answer (400, 405, 426, 431, 505) */
    char path[MTS_WS_MAX_PATH]; /* the request target, from '/', query included */
    char key[25];  /* Sec-WebSocket-Key: 24 base64 characters */
} mts_ws_request;

/* Parses the start of a connection, buf[0..len): MTS_OK with req->size > 0
 * once the whole request is in, MTS_OK with req->size == 0 while it may
 * still come (len < MTS_WS_MAX_REQUEST; garbage is refused as soon as it
 * shows), else MTS_ERR_FORMAT or MTS_ERR_LIMIT with the reason in err and
 * the HTTP status to answer in req->status. A GET that asks for no upgrade
 * is complete with upgrade 0 (its path is what it wants); one that asks
 * for one must have Host, Connection: Upgrade, Upgrade: websocket,
 * Sec-WebSocket-Version: 13 and a well-formed key. */
mts_result mts_ws_parse_request(const uint8_t *buf, size_t len, mts_ws_request *req,
                                mts_error *err);

/* Sec-WebSocket-Accept for a key: base64(SHA-1(key + the RFC's GUID)). */
void mts_ws_accept_key(const char *key, char out[29]);

/* The 101 answer to an opening request. */
void mts_ws_put_accept(mts_buf *b, const mts_ws_request *req);

/* An HTTP error answer (status 400, 403, 404, 405, 408, 426, 431, 503, 505)
 * with text as its plain-text body; Connection: close. */
void mts_ws_put_http_error(mts_buf *b, int status, const char *text);

/* The client's side, for tools and tests: an opening request for path on
 * host with key (24 base64 characters), and the check of the answer in
 * buf[0..len): MTS_OK with *size > 0 when a valid 101 for that key is in
 * (*size bytes of it; frames may follow), *size == 0 while it may come,
 * MTS_ERR_FORMAT naming what is wrong (an HTTP error's status line and body
 * are quoted). */
void mts_ws_put_request(mts_buf *b, const char *host, const char *path, const char *key);
mts_result mts_ws_parse_response(const uint8_t *buf, size_t len, const char *key, size_t *size,
                                 mts_error *err);

/* ---- frames ---------------------------------------------------------------- */

/* The header of one frame with len payload bytes into out, returning its
 * size: FIN set, unmasked when mask is NULL (the server's frames), else
 * masked with those 4 bytes (a client's; mask the payload with
 * mts_ws_mask). */
size_t mts_ws_header(uint8_t out[MTS_WS_MAX_HEADER], mts_ws_opcode op, uint64_t len,
                     const uint8_t *mask);

/* XORs data[0..len) with the mask, starting at byte `at` of the payload. */
void mts_ws_mask(uint8_t *data, size_t len, const uint8_t mask[4], uint64_t at);

/* A whole frame (header and payload, masked when mask is not NULL) onto b. */
void mts_ws_put_frame(mts_buf *b, mts_ws_opcode op, const void *data, size_t len,
                      const uint8_t *mask);

/* A Close frame with code and a short reason (at most 123 bytes kept). */
void mts_ws_put_close(mts_buf *b, uint16_t code, const char *reason, const uint8_t *mask);

/* What control frames a read brought. Cleared by the caller. */
typedef struct mts_ws_control {
    int ping;               /* a Ping came: answer with a Pong of pong[0..pong_len) */
    uint8_t pong[125];
    unsigned pong_len;
    int close;              /* a Close came, with close_code; nothing after it is read */
    uint16_t close_code;    /* MTS_WS_CLOSE_NONE when it had none */
    uint16_t fail_code;     /* after an error: the code to close with */
} mts_ws_control;

/* Reads a peer's frames. Zero-initialised: the server's side (frames must
 * be masked) with the default message limit. */
typedef struct mts_ws_reader {
    int client;             /* 1: the client's side (frames must not be masked) */
    int text;               /* 1: text messages are data too (tools talking to a browser's
                               DevTools); 0: refused, this protocol is binary */
    uint64_t max_message;   /* 0: MTS_WS_MAX_MESSAGE */
    uint64_t payload_in;    /* data bytes read so far */
    /* the frame in progress */
    uint8_t hdr[MTS_WS_MAX_HEADER];
    unsigned hdr_len;
    int in_frame, closed, failed;
    uint8_t opcode, fin, masked;
    uint8_t mask[4];
    uint64_t left, at;      /* payload bytes still to come, and read, of this frame */
    int in_message;         /* a fragmented data message is open */
    uint64_t message;       /* its bytes so far */
    uint8_t ctl[125];       /* a control frame's payload, gathered */
    unsigned ctl_len;
} mts_ws_reader;

/* Reads buf[0..len), bytes off the connection in order: the payload of
 * data frames, unmasked, is moved to buf[0..*payload) (it never overtakes
 * what is still to read); control frames are reported in ctl. After a
 * Close nothing more is read. A protocol error (an unmasked client frame,
 * reserved bits, an unknown opcode, a fragmented or long control frame, a
 * text message) is MTS_ERR_FORMAT, a message over the limit MTS_ERR_LIMIT,
 * both with ctl->fail_code; the reader then takes nothing more. */
mts_result mts_ws_reader_feed(mts_ws_reader *r, uint8_t *buf, size_t len, size_t *payload,
                              mts_ws_control *ctl, mts_error *err);

#endif
