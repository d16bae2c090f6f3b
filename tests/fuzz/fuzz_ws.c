/* Fuzz target: the WebSocket layer (protocol/ws.c) as both ends meet it.
 * The input is a mode byte, then the bytes off a connection:
 *   mode bit 0 clear: what a browser sends mts-server's WebSocket port, read
 *     as server.c's ws_read does: the opening request into a buffer of
 *     MTS_WS_MAX_REQUEST, parsed after each read, then (after an upgrade)
 *     the frames that follow, through a server-side reader;
 *   mode bit 0 set: what a server answers a client: the 101 for a fixed
 *     key, then frames through a client-side reader.
 * Reads come in pieces of (mode >> 1) + 1 bytes. The promises checked:
 * the request parses to the same end whatever the pieces; a parsed upgrade
 * gets a 101 that our own client accepts; frames read the same in pieces as
 * in one go (the payload, how it ended); a reader that failed takes nothing
 * more; and the payload a reader gave, framed again with a Ping and a Close
 * around it, reads back to itself. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fuzz_util.h"
#include "ws.h"

#define MTS_FUZZ_WS_KEY "bXRzdHJlYW0gdGVzdCBrZQ=="

/* data[0..n) in a buffer of exactly n bytes (freed by the caller). */
static uint8_t *mts_fuzz_ws_exact(const uint8_t *data, size_t n)
{
    uint8_t *b = malloc(n ? n : 1);
    MTS_FUZZ_CHECK(b != NULL);
    if (n)
        memcpy(b, data, n);
    return b;
}

typedef struct mts_fuzz_ws_read {
    mts_buf payload;
    mts_result rc;
    int closed;
    uint16_t close_code;
    unsigned pings;
} mts_fuzz_ws_read;

/* data[0..size) through a reader of one side, piece bytes a call, each in
 * a buffer of its exact size so ASan sees any access past it. */
static void mts_fuzz_ws_frames(int client, uint64_t max_message, const uint8_t *data,
                               size_t size, size_t piece, mts_fuzz_ws_read *o)
{
    mts_ws_reader r = {0};
    r.client = client;
    r.max_message = max_message;
    o->rc = MTS_OK;
    for (size_t at = 0; at < size && o->rc == MTS_OK && !o->closed;) {
        size_t n = size - at < piece ? size - at : piece;
        uint8_t *chunk = mts_fuzz_ws_exact(data + at, n);
        mts_ws_control ctl = {0};
        mts_error err = {0};
        size_t p = 0;
        o->rc = mts_ws_reader_feed(&r, chunk, n, &p, &ctl, &err);
        MTS_FUZZ_CHECK(p <= n);
        mts_buf_put(&o->payload, chunk, p);
        free(chunk);
        if (o->rc != MTS_OK) {
            MTS_FUZZ_CHECK(err.msg[0] != 0 && r.failed);
            MTS_FUZZ_CHECK(ctl.fail_code >= 1000 && ctl.fail_code < 5000 &&
                           ctl.fail_code != MTS_WS_CLOSE_NONE);
            MTS_FUZZ_CHECK(o->rc == MTS_ERR_FORMAT || o->rc == MTS_ERR_LIMIT);
        }
        if (ctl.ping) {
            MTS_FUZZ_CHECK(ctl.pong_len <= sizeof ctl.pong);
            o->pings++;
        }
        if (ctl.close) {
            o->closed = 1;
            o->close_code = ctl.close_code;
        }
        at += n;
    }
    MTS_FUZZ_CHECK(!o->payload.failed && o->payload.size <= size);
    MTS_FUZZ_CHECK(r.payload_in == o->payload.size);
    if (o->rc != MTS_OK) { /* a failed reader takes nothing more */
        uint8_t more[4] = {0x82, 0x80, 0, 0};
        mts_ws_control ctl = {0};
        mts_error err = {0};
        size_t p = 1;
        MTS_FUZZ_CHECK(mts_ws_reader_feed(&r, more, sizeof more, &p, &ctl, &err) != MTS_OK &&
                       p == 0);
    }
}

/* Both reads, in pieces and in one go, end the same way. */
static void mts_fuzz_ws_compare(int client, const uint8_t *data, size_t size, size_t piece)
{
    mts_fuzz_ws_read a = {0}, b = {0};
    mts_fuzz_ws_frames(client, 0, data, size, piece, &a);
    mts_fuzz_ws_frames(client, 0, data, size, size ? size : 1, &b);
    MTS_FUZZ_CHECK(a.rc == b.rc && a.closed == b.closed && a.close_code == b.close_code);
    MTS_FUZZ_CHECK(a.payload.size == b.payload.size &&
                   (a.payload.size == 0 ||
                    memcmp(a.payload.data, b.payload.data, a.payload.size) == 0));
    /* what was read, framed again as the other side would send it */
    if (a.payload.size > 0 && a.payload.size <= (32u << 10)) {
        static const uint8_t mask[4] = {0x37, 0x00, 0xfe, 0x81};
        const uint8_t *m = client ? NULL : mask; /* a client's frames are masked */
        mts_buf again = {0};
        size_t half = a.payload.size / 2;
        mts_ws_put_frame(&again, MTS_WS_PING, a.payload.data, half < 125 ? half : 125, m);
        mts_ws_put_frame(&again, MTS_WS_BINARY, a.payload.data, a.payload.size, m);
        mts_ws_put_close(&again, MTS_WS_CLOSE_NORMAL, "done", m);
        MTS_FUZZ_CHECK(!again.failed);
        mts_fuzz_ws_read c = {0};
        mts_fuzz_ws_frames(client, 0, again.data, again.size, piece, &c);
        MTS_FUZZ_CHECK(c.rc == MTS_OK && c.closed && c.close_code == MTS_WS_CLOSE_NORMAL);
        MTS_FUZZ_CHECK(c.pings == 1);
        MTS_FUZZ_CHECK(c.payload.size == a.payload.size &&
                       memcmp(c.payload.data, a.payload.data, a.payload.size) == 0);
        mts_buf_free(&c.payload);
        mts_buf_free(&again);
    }
    mts_buf_free(&a.payload);
    mts_buf_free(&b.payload);
}

/* The server's side: the opening request as ws_read gathers it. */
static void mts_fuzz_ws_server(const uint8_t *data, size_t size, size_t piece)
{
    size_t have = 0;
    mts_ws_request req;
    mts_error err = {0};
    mts_result rc = MTS_OK;
    req.size = 0;
    while (have < size && have < MTS_WS_MAX_REQUEST) {
        size_t n = size - have < piece ? size - have : piece;
        if (n > MTS_WS_MAX_REQUEST - have)
            n = MTS_WS_MAX_REQUEST - have;
        have += n;
        uint8_t *prefix = mts_fuzz_ws_exact(data, have);
        rc = mts_ws_parse_request(prefix, have, &req, &err);
        free(prefix);
        if (rc != MTS_OK || req.size > 0)
            break;
    }
    if (rc != MTS_OK) {
        MTS_FUZZ_CHECK(err.msg[0] != 0 && (rc == MTS_ERR_FORMAT || rc == MTS_ERR_LIMIT));
        MTS_FUZZ_CHECK(req.status == 400 || req.status == 405 || req.status == 426 ||
                       req.status == 431 || req.status == 505);
        return;
    }
    if (req.size == 0) { /* still coming: only while the buffer has room */
        MTS_FUZZ_CHECK(have < MTS_WS_MAX_REQUEST);
        return;
    }
    MTS_FUZZ_CHECK(req.size <= have);
    /* the same end when all of it is parsed at once */
    mts_ws_request again;
    size_t whole = size < MTS_WS_MAX_REQUEST ? size : MTS_WS_MAX_REQUEST;
    MTS_FUZZ_CHECK(mts_ws_parse_request(data, whole, &again, &err) == MTS_OK &&
                   again.size == req.size && again.upgrade == req.upgrade &&
                   strcmp(again.path, req.path) == 0 && strcmp(again.key, req.key) == 0);
    MTS_FUZZ_CHECK(req.path[0] == '/' && strlen(req.path) < sizeof req.path);
    if (!req.upgrade)
        return; /* 426: nothing more is read */
    MTS_FUZZ_CHECK(strlen(req.key) == 24);
    /* our 101 is what our client accepts */
    mts_buf answer = {0};
    mts_ws_put_accept(&answer, &req);
    size_t got = 0;
    MTS_FUZZ_CHECK(!answer.failed && mts_ws_parse_response(answer.data, answer.size, req.key,
                                                           &got, &err) == MTS_OK &&
                   got == answer.size);
    mts_buf_free(&answer);
    mts_fuzz_ws_compare(0, data + req.size, size - req.size, piece);
}

/* The client's side: a server's answer, then its frames. */
static void mts_fuzz_ws_client(const uint8_t *data, size_t size, size_t piece)
{
    size_t have = 0, got = 0;
    mts_error err = {0};
    mts_result rc = MTS_OK;
    while (have < size) {
        have += size - have < piece ? size - have : piece;
        uint8_t *prefix = mts_fuzz_ws_exact(data, have);
        rc = mts_ws_parse_response(prefix, have, MTS_FUZZ_WS_KEY, &got, &err);
        free(prefix);
        if (rc != MTS_OK || got > 0)
            break;
    }
    if (rc != MTS_OK) {
        MTS_FUZZ_CHECK(err.msg[0] != 0);
        return;
    }
    if (got == 0)
        return;
    MTS_FUZZ_CHECK(got <= have);
    mts_fuzz_ws_compare(1, data + got, size - got, piece);
}

int mts_fuzz_ws(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    size_t piece = (size_t)(data[0] >> 1) + 1;
    if (data[0] & 1)
        mts_fuzz_ws_client(data + 1, size - 1, piece);
    else
        mts_fuzz_ws_server(data + 1, size - 1, piece);
    return 0;
}

#ifndef MTS_FUZZ_NO_ENTRY
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return mts_fuzz_ws(data, size);
}
#endif
