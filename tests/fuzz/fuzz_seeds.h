/* The fuzz targets' seed corpora, made from real streams and files so the
 * fuzzer starts deep: a small torus model (fast to decode, every code path)
 * and tests/data/cow.off's model (the real thing), cut at a few stop levels,
 * each in both forms of a stream (splits, and records: PROTOCOL.md "Records
 * form"), and a torus whose normals travel (the one seed of that path).
 * `make fuzz` writes them with tests/fuzz/fuzz_seeds.c; the regression test
 * runs them through the targets in memory. Seeds stay small (the biggest are
 * cow's streams, under 10 KiB) so that each execution stays fast.
 *
 * The model-file seeds also hold a hand-made model (tests/hand_model.h) whose
 * records erase and whose strips are longer at a middle level than at the
 * full one, so the fuzzer starts from erase runs and capacities that the
 * full strips do not give.
 *
 * The stream-file seeds are whole stream files (mts_stream_file_write, as
 * mts-build --stream writes them) of the torus in both forms and of the
 * torus whose normals travel (and, for the regression test only, of cow's
 * splits form), behind a mode byte and four stop bytes.
 *
 * The glTF seeds are the small torus as .glb and .gltf files, each reaching
 * one more part of the reader (mts_fuzz_gltf_seeds says which).
 *
 * Targets: "stream_client", "request", "modelfile", "draco", "ws",
 * "stream_file", "gltf" (the fuzz_*.c files say what their input is; four
 * of them start with a mode byte). */
#ifndef MTS_FUZZ_SEEDS_H
#define MTS_FUZZ_SEEDS_H

#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../hand_model.h"
#include "draco.h"
#include "fuzz_util.h"
#include "mesh.h"
#include "modelfile.h"
#include "stream.h"
#include "stream_file.h"
#include "wire.h"
#include "ws.h"

typedef void (*mts_fuzz_emit_fn)(void *user, const char *target, const char *name,
                                 const uint8_t *data, size_t size);

typedef struct mts_fuzz_seeder {
    mts_fuzz_emit_fn emit;
    void *user;
    int failed; /* an allocation failed */
} mts_fuzz_seeder;

/* Emits data with a mode byte in front (the stream_client and modelfile inputs). */
static inline void mts_fuzz_emit_mode(mts_fuzz_seeder *sd, const char *target, const char *name,
                                      uint8_t mode, const uint8_t *data, size_t size)
{
    uint8_t *b = malloc(size + 1);
    if (!b) {
        sd->failed = 1;
        return;
    }
    b[0] = mode;
    if (size)
        memcpy(b + 1, data, size);
    sd->emit(sd->user, target, name, b, size + 1);
    free(b);
}

/* The Draco buffer inside a stream's BASE frame (its first frame). */
static inline const uint8_t *mts_fuzz_base_draco(const mts_stream *s, size_t *size)
{
    mts_cursor c = mts_cursor_make(s->bytes + MTS_WIRE_HEADER, s->size - MTS_WIRE_HEADER);
    uint32_t n = mts_cursor_varint(&c);
    *size = n;
    return mts_cursor_bytes(&c, n);
}

/* Stream seeds of one model: each stop level from the start, plus variants. */
static inline void mts_fuzz_stream_seeds(mts_fuzz_seeder *sd, const char *tag, const mts_stream *s,
                                         const uint32_t *stops, size_t nstops, int variants)
{
    char name[96];
    for (size_t i = 0; i < nstops; i++) {
        mts_buf b = {0};
        mts_fuzz_conversation(s, 0, stops[i], SIZE_MAX, &b);
        if (b.failed) {
            sd->failed = 1;
            mts_buf_free(&b);
            return;
        }
        snprintf(name, sizeof name, "%s-level%u", tag, stops[i]);
        mts_fuzz_emit_mode(sd, "stream_client", name, 0, b.data, b.size);
        if (variants && i + 1 == nstops) {
            /* the CRCs as sent (mode bit 0), split into small pieces, and cut short */
            snprintf(name, sizeof name, "%s-level%u-crc-kept", tag, stops[i]);
            mts_fuzz_emit_mode(sd, "stream_client", name, 1, b.data, b.size);
            snprintf(name, sizeof name, "%s-level%u-pieces", tag, stops[i]);
            mts_fuzz_emit_mode(sd, "stream_client", name, 2 * 5, b.data, b.size);
            snprintf(name, sizeof name, "%s-level%u-cut-half", tag, stops[i]);
            mts_fuzz_emit_mode(sd, "stream_client", name, 0, b.data, b.size / 2);
            snprintf(name, sizeof name, "%s-level%u-cut-before-end", tag, stops[i]);
            mts_fuzz_emit_mode(sd, "stream_client", name, 0, b.data, b.size - 3);
            /* two threads (mode bit 7), whole and in pieces: batches decoded ahead */
            snprintf(name, sizeof name, "%s-level%u-threads", tag, stops[i]);
            mts_fuzz_emit_mode(sd, "stream_client", name, 0x80, b.data, b.size);
            snprintf(name, sizeof name, "%s-level%u-threads-pieces", tag, stops[i]);
            mts_fuzz_emit_mode(sd, "stream_client", name, 0x80 | 2 * 9, b.data, b.size);
        }
        mts_buf_free(&b);
    }
}

/* Streams broken and resumed (MTS_FUZZ_CUT between the connections), named
 * tag-cut-...: s's form throughout, as a client resumes the stream_id it was
 * given. */
static inline void mts_fuzz_resume_seeds(mts_fuzz_seeder *sd, const char *tag, const mts_stream *s)
{
    const uint32_t n = s->model.level_count;
    if (s->batch_count < 5)
        return;
    /* bytes of a connection's stream up to a point in s->bytes: MODEL_INFO's
     * size, then the stream from its start */
    mts_buf info = {0};
    mts_stream_put_model_info(s, n, &info);
    const size_t head = info.size, base_end = s->batch_offset[0];
    mts_buf_free(&info);
    struct {
        const char *name;
        size_t keep[2];      /* what the first two connections got before the break */
        uint32_t resume[3];  /* the batch each connection resumes from */
    } cases[] = {
        /* cut inside BASE: nothing applied, the second connection starts over */
        {"cut-in-base", {head + base_end / 2, 0}, {0, 0, 0}},
        /* cut inside batch 0: the base is in, the server sends it again */
        {"cut-in-batch0", {head + s->batch_offset[0] + 9, 0}, {0, 0, 0}},
        /* cut inside batch 2: resumes from batch 2 */
        {"cut-in-batch2", {head + s->batch_offset[2] + 7, 0}, {0, 2, 0}},
        /* two breaks: inside batch 1, then inside batch 4 of the resumed stream */
        {"cut-twice",
         {head + s->batch_offset[1] + 3, head + s->batch_offset[4] - s->batch_offset[1] + 5},
         {0, 1, 4}},
    };
    char name[96];
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        mts_buf b = {0};
        int conns = cases[i].keep[1] ? 3 : 2;
        for (int k = 0; k < conns; k++) {
            if (k > 0)
                mts_buf_put(&b, MTS_FUZZ_CUT, MTS_FUZZ_CUT_SIZE);
            mts_fuzz_conversation(s, cases[i].resume[k], n, k + 1 < conns ? cases[i].keep[k] : SIZE_MAX,
                                  &b);
        }
        snprintf(name, sizeof name, "%s-%s", tag, cases[i].name);
        if (b.failed)
            sd->failed = 1;
        else
            mts_fuzz_emit_mode(sd, "stream_client", name, 0, b.data, b.size);
        /* on two threads, in pieces; and breaking with whole frames left
         * untaken, some decoded ahead (that one may resume elsewhere than
         * the recorded server does, and end refused) */
        snprintf(name, sizeof name, "%s-%s-threads", tag, cases[i].name);
        if (!b.failed)
            mts_fuzz_emit_mode(sd, "stream_client", name, 0x80 | 2 * 9, b.data, b.size);
        snprintf(name, sizeof name, "%s-%s-threads-backlog", tag, cases[i].name);
        if (!b.failed)
            mts_fuzz_emit_mode(sd, "stream_client", name, 0xc0 | 2 * 9, b.data, b.size);
        mts_buf_free(&b);
    }    /* continued past the stop (PROTOCOL.md, "Continuing"): to a stop inside
     * batch 2, then from the batches held to the full level */
    uint32_t stop = s->batch_first[2] + 3, held = 0;
    while (held < s->batch_count && s->batch_first[held] < stop)
        held++;
    mts_buf b = {0};
    mts_fuzz_conversation(s, 0, stop, SIZE_MAX, &b);
    mts_buf_put(&b, MTS_FUZZ_CUT, MTS_FUZZ_CUT_SIZE);
    mts_fuzz_conversation(s, held, n, SIZE_MAX, &b);
    snprintf(name, sizeof name, "%s-continued", tag);
    if (b.failed)
        sd->failed = 1;
    else
        mts_fuzz_emit_mode(sd, "stream_client", name, 0, b.data, b.size);
    mts_buf_free(&b);
}

/* A stream file of s behind a mode byte and four stop bytes (each stop
 * byte: a kind in bits 0-1 -- level, triangles, fraction, full -- and a
 * value in bits 2-7; fuzz_stream_file.c). */
static inline void mts_fuzz_stream_file_seed(mts_fuzz_seeder *sd, const char *name,
                                             const mts_stream *s, uint8_t mode,
                                             const uint8_t stops[4])
{
    mts_buf b = {0};
    mts_error err = {0};
    mts_buf_u8(&b, mode);
    mts_buf_put(&b, stops, 4);
    if (mts_stream_file_write(s, &b, &err) != MTS_OK || b.failed)
        sd->failed = 1;
    else
        sd->emit(sd->user, "stream_file", name, b.data, b.size);
    mts_buf_free(&b);
}

/* Stream-file seeds of one stream: half the levels, then a triangle budget
 * inside a batch, a fraction and the full level (each continued to the next);
 * with variants, the same in pieces with a break and resume, with the CRCs
 * as written, capped at the file's size, and by other stops. */
static inline void mts_fuzz_stream_file_seeds(mts_fuzz_seeder *sd, const char *tag,
                                              const mts_stream *s, int variants)
{
    static const uint8_t stops[4] = {31 << 2 | 0, 7 << 2 | 1, 20 << 2 | 2, 0 << 2 | 3};
    static const uint8_t others[4] = {63 << 2 | 0, 0 << 2 | 0, 62 << 2 | 2, 2 << 2 | 1};
    char name[96];
    snprintf(name, sizeof name, "%s-file", tag);
    mts_fuzz_stream_file_seed(sd, name, s, 0, stops);
    if (!variants)
        return;
    snprintf(name, sizeof name, "%s-file-pieces-break", tag);
    mts_fuzz_stream_file_seed(sd, name, s, 0x40 | 5 << 1, stops);
    snprintf(name, sizeof name, "%s-file-crc-kept", tag);
    mts_fuzz_stream_file_seed(sd, name, s, 1, stops);
    snprintf(name, sizeof name, "%s-file-capped-other-stops", tag);
    mts_fuzz_stream_file_seed(sd, name, s, 0x20 | 3 << 1, others);
}

static inline void mts_fuzz_request_seeds(mts_fuzz_seeder *sd, const mts_stream *s)
{
    struct {
        const char *name, *model;
        uint16_t major;
        uint8_t kind;
        uint32_t value, resume;
        int right_id; /* 1: the splits form's stream_id, 2: the records form's */
        uint32_t flags;
    } hellos[] = {
        {"hello-full", "fuzz", MTS_WIRE_MAJOR, MTS_STOP_FULL, 0, 0, 0, 0},
        {"hello-level", "fuzz", MTS_WIRE_MAJOR, MTS_STOP_LEVEL, 10, 0, 0, 0},
        {"hello-level-past", "fuzz", MTS_WIRE_MAJOR, MTS_STOP_LEVEL, 1000000, 0, 0, 0},
        {"hello-triangles", "fuzz", MTS_WIRE_MAJOR, MTS_STOP_TRIANGLES, 100, 0, 0, 0},
        {"hello-fraction", "fuzz", MTS_WIRE_MAJOR, MTS_STOP_FRACTION, 500000, 0, 0, 0},
        {"hello-resume", "fuzz", MTS_WIRE_MAJOR, MTS_STOP_LEVEL, 40, 2, 1, 0},
        {"hello-resume-stale", "fuzz", MTS_WIRE_MAJOR, MTS_STOP_FULL, 0, 1, 0, 0},
        {"hello-resume-past", "fuzz", MTS_WIRE_MAJOR, MTS_STOP_LEVEL, 10, 5, 1, 0},
        {"hello-unknown-model", "cow", MTS_WIRE_MAJOR, MTS_STOP_FULL, 0, 0, 0, 0},
        {"hello-version-1", "fuzz", 1, MTS_STOP_FULL, 0, 0, 0, 0}, /* an older peer */
        {"hello-version-next", "fuzz", MTS_WIRE_MAJOR + 1, MTS_STOP_FULL, 0, 0, 0, 0},
        /* 4.1: the records form asked for, resumed with its own stream_id or
         * (stale) the splits form's; unknown flag bits, ignored */
        {"hello-records", "fuzz", MTS_WIRE_MAJOR, MTS_STOP_FULL, 0, 0, 0, MTS_HELLO_RECORDS},
        {"hello-records-resume", "fuzz", MTS_WIRE_MAJOR, MTS_STOP_LEVEL, 40, 2, 2,
         MTS_HELLO_RECORDS},
        {"hello-records-resume-stale", "fuzz", MTS_WIRE_MAJOR, MTS_STOP_FULL, 0, 2, 1,
         MTS_HELLO_RECORDS},
        {"hello-unknown-flags", "fuzz", MTS_WIRE_MAJOR, MTS_STOP_FULL, 0, 0, 0, 0xfe},
    };
    for (size_t i = 0; i < sizeof hellos / sizeof hellos[0]; i++) {
        mts_wire_hello h = {0};
        h.major = hellos[i].major;
        h.minor = MTS_WIRE_MINOR;
        snprintf(h.model, sizeof h.model, "%s", hellos[i].model);
        h.stop_kind = hellos[i].kind;
        h.stop_value = hellos[i].value;
        h.resume_batch = hellos[i].resume;
        h.stream_id = hellos[i].right_id == 2 && s->records_form ? s->records_form->stream_id
                      : hellos[i].right_id                         ? s->stream_id
                                                                   : 12345;
        h.flags = hellos[i].flags;
        mts_buf b = {0};
        mts_wire_put_hello(&b, &h);
        if (b.failed)
            sd->failed = 1;
        else
            sd->emit(sd->user, "request", hellos[i].name, b.data, b.size);
        mts_buf_free(&b);
    }
    mts_buf b = {0};
    mts_wire_put_list(&b);
    if (b.failed)
        sd->failed = 1;
    else
        sd->emit(sd->user, "request", "list", b.data, b.size);
    mts_buf_free(&b);
}

/* ws: a browser's side (mode bit 0 clear) and a server's answers (set),
 * each read in pieces of (mode >> 1) + 1 bytes. */
static inline void mts_fuzz_ws_seeds(mts_fuzz_seeder *sd, const mts_stream *s)
{
    static const uint8_t mask[4] = {0x11, 0x5a, 0xc3, 0x7e};
    static const char key[] = "bXRzdHJlYW0gdGVzdCBrZQ==";
    mts_buf req = {0}, b = {0};
    mts_ws_put_request(&req, "127.0.0.1:7447", "/?model=fuzz", key);
    /* the opening, a Ping, a HELLO in two frames of one message, a Close */
    mts_wire_hello h = {0};
    h.major = MTS_WIRE_MAJOR;
    h.minor = MTS_WIRE_MINOR;
    snprintf(h.model, sizeof h.model, "fuzz");
    mts_buf hello = {0};
    mts_wire_put_hello(&hello, &h);
    mts_buf_put(&b, req.data, req.size);
    mts_ws_put_frame(&b, MTS_WS_PING, "p1", 2, mask);
    if (!hello.failed && hello.size > 3) {
        uint8_t hdr[MTS_WS_MAX_HEADER];
        size_t hn = mts_ws_header(hdr, MTS_WS_BINARY, 3, mask);
        hdr[0] &= 0x7f; /* not FIN */
        mts_buf_put(&b, hdr, hn);
        size_t at = b.size;
        mts_buf_put(&b, hello.data, 3);
        if (!b.failed)
            mts_ws_mask(b.data + at, 3, mask, 0);
        hn = mts_ws_header(hdr, MTS_WS_CONTINUATION, hello.size - 3, mask);
        mts_buf_put(&b, hdr, hn);
        at = b.size;
        mts_buf_put(&b, hello.data + 3, hello.size - 3);
        if (!b.failed)
            mts_ws_mask(b.data + at, hello.size - 3, mask, 0);
    }
    mts_ws_put_close(&b, MTS_WS_CLOSE_GOING_AWAY, "tab closed", mask);
    sd->failed |= b.failed || hello.failed;
    mts_fuzz_emit_mode(sd, "ws", "browser-hello", 0, b.data, b.size);
    mts_fuzz_emit_mode(sd, "ws", "browser-hello-pieces", 7 << 1, b.data, b.size);
    /* an upgrade, then a text message (refused: the protocol is binary) */
    b.size = 0;
    mts_buf_put(&b, req.data, req.size);
    mts_ws_put_frame(&b, MTS_WS_TEXT, "hello", 5, mask);
    mts_fuzz_emit_mode(sd, "ws", "browser-text", 0, b.data, b.size);
    static const char *plain[] = {
        "GET /index.html HTTP/1.1\r\nHost: x\r\n\r\n",
        ("GET / HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\nConnection: keep-alive, Upgrade\r\n"
         "Sec-WebSocket-Key: bXRzdHJlYW0gdGVzdCBrZQ==\r\nSec-WebSocket-Version: 8\r\n\r\n"),
        "POST / HTTP/1.1\r\nHost: x\r\nContent-Length: 0\r\n\r\n",
    };
    static const char *plain_names[] = {"plain-get", "version-8", "post"};
    for (int i = 0; i < 3; i++)
        mts_fuzz_emit_mode(sd, "ws", plain_names[i], 0, (const uint8_t *)plain[i],
                           strlen(plain[i]));
    /* a server's 101, the start of a stream in two messages (the second
     * with a 16-bit length), and its Close */
    mts_ws_request r;
    mts_error err = {0};
    b.size = 0;
    if (mts_ws_parse_request(req.data, req.size, &r, &err) == MTS_OK && r.size > 0) {
        mts_ws_put_accept(&b, &r);
        size_t first = s->size < 100 ? s->size : 100;
        size_t second = s->size - first < 900 ? s->size - first : 900;
        mts_ws_put_frame(&b, MTS_WS_BINARY, s->bytes, first, NULL);
        mts_ws_put_frame(&b, MTS_WS_BINARY, s->bytes + first, second, NULL);
        mts_ws_put_close(&b, MTS_WS_CLOSE_NORMAL, NULL, NULL);
        mts_fuzz_emit_mode(sd, "ws", "server-stream", 1, b.data, b.size);
        mts_fuzz_emit_mode(sd, "ws", "server-stream-pieces", 1 | 63 << 1, b.data, b.size);
    } else {
        sd->failed = 1;
    }
    b.size = 0;
    mts_ws_put_http_error(&b, 503, "server busy: try again later");
    mts_fuzz_emit_mode(sd, "ws", "server-busy", 1, b.data, b.size);
    sd->failed |= b.failed || req.failed;
    mts_buf_free(&hello);
    mts_buf_free(&req);
    mts_buf_free(&b);
}

static inline void mts_fuzz_modelfile_seed(mts_fuzz_seeder *sd, const char *name, uint8_t mode,
                                           const mts_model *m)
{
    uint8_t *data = NULL;
    size_t size = 0;
    mts_error err = {0};
    if (mts_modelfile_encode(m, &data, &size, &err) != MTS_OK) {
        sd->failed = 1;
        return;
    }
    mts_fuzz_emit_mode(sd, "modelfile", name, mode, data, size);
    free(data);
}

static inline void mts_fuzz_draco_seed(mts_fuzz_seeder *sd, const char *name,
                                       const mts_stream *s, int method, int normals)
{
    /* the stream's own model at the full level, on the stream's grid */
    const mts_model *m = &s->model;
    uint32_t *tris = malloc(((size_t)m->full.index_count + 1) * 12);
    if (!tris) {
        sd->failed = 1;
        return;
    }
    uint32_t nt = 0;
    for (uint32_t st = 0; st < m->strip_count; st++) {
        const uint32_t *str = m->full.indices + m->full.offsets[st];
        uint32_t len = m->full.offsets[st + 1] - m->full.offsets[st];
        for (uint32_t k = 0; k + 2 < len; k++)
            nt += (uint32_t)mts_strip_window(str, k, tris + 3 * (size_t)nt);
    }
    mts_draco_mesh in = {m->vertex_count, nt, m->positions, normals ? m->normals : NULL, tris, NULL, NULL};
    mts_draco_options o = {0};
    o.grid = s->grid;
    o.method = method;
    o.normal_bits = normals ? 0 : -1;
    uint8_t *data = NULL;
    size_t size = 0;
    mts_error err = {0};
    if (mts_draco_encode(&in, &o, &data, &size, &err) == MTS_OK)
        sd->emit(sd->user, "draco", name, data, size);
    else
        sd->failed = 1;
    free(data);
    free(tris);
}

/* glTF seeds (the gltf target): the small torus (5 x 6, 30 vertices, 60
 * triangles, as tests/fuzz/fuzz_util.h writes it) as glTF 2.0, each seed
 * reaching one more part of builder/gltf_read.cpp: a GLB of positions and
 * uint16 indices, COLOR_0 as float VEC3 and as normalized ubyte VEC4 (that
 * one interleaved with the positions in one strided view), a .gltf whose
 * buffer is a base64 data: URI, node transforms (translation, rotation,
 * scale, a matrix, a child node, a mirroring scale that turns the winding
 * over), triangle strips, and sparse accessors (on a buffer view, and
 * without one). */

/* printf onto the end of a buffer (failure: b->failed) */
static inline void mts_fuzz_printf(mts_buf *b, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
static inline void mts_fuzz_printf(mts_buf *b, const char *fmt, ...)
{
    char small[256];
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(small, sizeof small, fmt, ap);
    va_end(ap);
    if (n < 0) {
        b->failed = 1;
        return;
    }
    if ((size_t)n < sizeof small) {
        mts_buf_put(b, small, (size_t)n);
        return;
    }
    char *big = malloc((size_t)n + 1);
    if (!big) {
        b->failed = 1;
        return;
    }
    va_start(ap, fmt);
    vsnprintf(big, (size_t)n + 1, fmt, ap);
    va_end(ap);
    mts_buf_put(b, big, (size_t)n);
    free(big);
}

static inline void mts_fuzz_base64(mts_buf *b, const uint8_t *p, size_t n)
{
    static const char abc[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    for (size_t i = 0; i < n; i += 3) {
        uint32_t v = (uint32_t)p[i] << 16 | (i + 1 < n ? (uint32_t)p[i + 1] << 8 : 0) |
                     (i + 2 < n ? p[i + 2] : 0);
        char q[4] = {abc[v >> 18 & 63], abc[v >> 12 & 63], i + 1 < n ? abc[v >> 6 & 63] : '=',
                     i + 2 < n ? abc[v & 63] : '='};
        mts_buf_put(b, q, 4);
    }
}

/* Emits a glTF of the JSON in json (an object without its closing brace
 * and without "buffers") and one buffer, bin: as GLB (its BIN chunk) or as
 * .gltf with bin as a data: URI. */
static inline void mts_fuzz_gltf_emit(mts_fuzz_seeder *sd, const char *name, const mts_buf *json,
                                      const mts_buf *bin, int glb)
{
    mts_buf j = {0}, b = {0};
    mts_buf_put(&j, json->data, json->size);
    mts_fuzz_printf(&j, ",\"buffers\":[{\"byteLength\":%zu", bin->size);
    if (!glb) {
        mts_fuzz_printf(&j, ",\"uri\":\"data:application/octet-stream;base64,");
        mts_fuzz_base64(&j, bin->data, bin->size);
        mts_buf_u8(&j, '"');
    }
    mts_fuzz_printf(&j, "}]}");
    if (glb) {
        /* header, JSON chunk (padded with spaces), BIN chunk (with zeros) */
        size_t jl = (j.size + 3) & ~(size_t)3, bl = (bin->size + 3) & ~(size_t)3;
        mts_buf_put(&b, "glTF", 4);
        mts_buf_u32(&b, 2);
        mts_buf_u32(&b, (uint32_t)(12 + 8 + jl + 8 + bl));
        mts_buf_u32(&b, (uint32_t)jl);
        mts_buf_u32(&b, 0x4E4F534Au); /* "JSON" */
        mts_buf_put(&b, j.data, j.size);
        for (size_t k = j.size; k < jl; k++)
            mts_buf_u8(&b, ' ');
        mts_buf_u32(&b, (uint32_t)bl);
        mts_buf_u32(&b, 0x004E4942u); /* "BIN\0" */
        mts_buf_put(&b, bin->data, bin->size);
        for (size_t k = bin->size; k < bl; k++)
            mts_buf_u8(&b, 0);
    } else {
        mts_buf_put(&b, j.data, j.size);
    }
    if (j.failed || b.failed || json->failed || bin->failed)
        sd->failed = 1;
    else
        sd->emit(sd->user, "gltf", name, b.data, b.size);
    mts_buf_free(&j);
    mts_buf_free(&b);
}

/* The JSON every torus seed starts with: asset, one scene of the root
 * nodes listed in roots. */
static inline void mts_fuzz_gltf_head(mts_buf *j, const char *roots)
{
    mts_fuzz_printf(j, "{\"asset\":{\"version\":\"2.0\",\"generator\":\"mtstream fuzz seeds\"},"
                       "\"scene\":0,\"scenes\":[{\"nodes\":[%s]}]", roots);
}

/* A POSITION accessor of the torus's vertex count, its bounds as glTF
 * wants them, more members (more: "" or ",\"name\":...") at its end. */
static inline void mts_fuzz_gltf_position_accessor(mts_buf *j, const mts_mesh *m, int view,
                                                   const char *more)
{
    float lo[3], hi[3];
    for (int a = 0; a < 3; a++) {
        lo[a] = hi[a] = m->positions[a];
        for (uint32_t v = 1; v < m->vertex_count; v++) {
            float x = m->positions[3 * (size_t)v + a];
            lo[a] = x < lo[a] ? x : lo[a];
            hi[a] = x > hi[a] ? x : hi[a];
        }
    }
    mts_fuzz_printf(j,
                    "{\"bufferView\":%d,\"componentType\":5126,\"count\":%u,\"type\":\"VEC3\","
                    "\"min\":[%.9g,%.9g,%.9g],\"max\":[%.9g,%.9g,%.9g]%s}",
                    view, m->vertex_count, lo[0], lo[1], lo[2], hi[0], hi[1], hi[2], more);
}

static inline void mts_fuzz_gltf_put_positions(mts_buf *bin, const mts_mesh *m)
{
    for (size_t k = 0; k < 3 * (size_t)m->vertex_count; k++)
        mts_buf_f32(bin, m->positions[k]);
}

static inline void mts_fuzz_gltf_put_indices16(mts_buf *bin, const mts_mesh *m)
{
    for (size_t k = 0; k < 3 * (size_t)m->triangle_count; k++)
        mts_buf_u16(bin, (uint16_t)m->triangles[k]);
}

/* A vertex's colour from its position, as the other coloured seeds make
 * theirs, in 0..1. */
static inline float mts_fuzz_gltf_color(const mts_mesh *m, uint32_t v, int a)
{
    return (128.0f + 100.0f * m->positions[3 * (size_t)v + a]) / 255.0f;
}

static inline mts_result mts_fuzz_gltf_seeds(mts_fuzz_seeder *sd, mts_error *err)
{
    const int nu = 5, nv = 6;
    size_t size = 0;
    char *off = mts_fuzz_torus_off(nu, nv, &size);
    mts_mesh m;
    mts_result rc = off ? mts_mesh_load_memory("torus.off", off, size, NULL, &m, NULL, err)
                        : mts_error_set(err, MTS_ERR_NOMEM, "out of memory");
    free(off);
    if (rc != MTS_OK)
        return rc;
    const size_t pos_bytes = 12 * (size_t)m.vertex_count;
    const size_t idx_bytes = 6 * (size_t)m.triangle_count;
    const uint32_t nidx = 3 * m.triangle_count;
    mts_buf j = {0}, bin = {0};

    /* positions and uint16 indices, as GLB and as .gltf with a data: URI */
    mts_fuzz_gltf_head(&j, "0");
    mts_fuzz_printf(&j, ",\"nodes\":[{\"mesh\":0}],\"meshes\":[{\"primitives\":[{\"attributes\":"
                        "{\"POSITION\":0},\"indices\":1,\"mode\":4}]}],\"accessors\":[");
    mts_fuzz_gltf_position_accessor(&j, &m, 0, "");
    mts_fuzz_printf(&j, ",{\"bufferView\":1,\"componentType\":5123,\"count\":%u,"
                        "\"type\":\"SCALAR\"}],\"bufferViews\":["
                        "{\"buffer\":0,\"byteLength\":%zu,\"target\":34962},"
                        "{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu,\"target\":34963}]",
                    nidx, pos_bytes, pos_bytes, idx_bytes);
    mts_fuzz_gltf_put_positions(&bin, &m);
    mts_fuzz_gltf_put_indices16(&bin, &m);
    mts_fuzz_gltf_emit(sd, "torus.glb", &j, &bin, 1);
    mts_fuzz_gltf_emit(sd, "torus-data-uri.gltf", &j, &bin, 0);

    /* node transforms: node 0 (translation, rotation, scale) over node 1 (a
     * matrix) with the mesh, and node 2 mirrored (its winding turned over) */
    j.size = 0;
    mts_fuzz_gltf_head(&j, "0,2");
    mts_fuzz_printf(&j, ",\"nodes\":["
                        "{\"translation\":[1,2,3],\"rotation\":[0,0,0.382683432,0.923879533],"
                        "\"scale\":[2,2,2],\"children\":[1]},"
                        "{\"mesh\":0,\"matrix\":[1,0,0,0,0,0.5,0,0,0,0,1,0,0,0,-4,1]},"
                        "{\"mesh\":0,\"translation\":[10,0,0],\"scale\":[-1,1,1]}],"
                        "\"meshes\":[{\"primitives\":[{\"attributes\":"
                        "{\"POSITION\":0},\"indices\":1}]}],\"accessors\":[");
    mts_fuzz_gltf_position_accessor(&j, &m, 0, "");
    mts_fuzz_printf(&j, ",{\"bufferView\":1,\"componentType\":5123,\"count\":%u,"
                        "\"type\":\"SCALAR\"}],\"bufferViews\":["
                        "{\"buffer\":0,\"byteLength\":%zu},"
                        "{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu}]",
                    nidx, pos_bytes, pos_bytes, idx_bytes);
    mts_fuzz_gltf_emit(sd, "torus-nodes.glb", &j, &bin, 1);

    /* COLOR_0 as float VEC3 in a view of its own */
    j.size = 0;
    mts_fuzz_gltf_head(&j, "0");
    mts_fuzz_printf(&j, ",\"nodes\":[{\"mesh\":0}],\"meshes\":[{\"primitives\":[{\"attributes\":"
                        "{\"POSITION\":0,\"COLOR_0\":2},\"indices\":1}]}],\"accessors\":[");
    mts_fuzz_gltf_position_accessor(&j, &m, 0, "");
    mts_fuzz_printf(&j, ",{\"bufferView\":1,\"componentType\":5123,\"count\":%u,"
                        "\"type\":\"SCALAR\"},"
                        "{\"bufferView\":2,\"componentType\":5126,\"count\":%u,\"type\":\"VEC3\"}],"
                        "\"bufferViews\":[{\"buffer\":0,\"byteLength\":%zu},"
                        "{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu},"
                        "{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu}]",
                    nidx, m.vertex_count, pos_bytes, pos_bytes, idx_bytes, pos_bytes + idx_bytes,
                    pos_bytes);
    for (uint32_t v = 0; v < m.vertex_count; v++)
        for (int a = 0; a < 3; a++)
            mts_buf_f32(&bin, mts_fuzz_gltf_color(&m, v, a));
    mts_fuzz_gltf_emit(sd, "torus-colors-float.glb", &j, &bin, 1);

    /* COLOR_0 as normalized ubyte VEC4 (some alpha below opaque),
     * interleaved with the positions in one view of stride 16 */
    j.size = 0;
    bin.size = 0;
    mts_fuzz_gltf_head(&j, "0");
    mts_fuzz_printf(&j, ",\"nodes\":[{\"mesh\":0}],\"meshes\":[{\"primitives\":[{\"attributes\":"
                        "{\"POSITION\":0,\"COLOR_0\":2},\"indices\":1}]}],\"accessors\":[");
    mts_fuzz_gltf_position_accessor(&j, &m, 0, "");
    mts_fuzz_printf(&j, ",{\"bufferView\":1,\"componentType\":5123,\"count\":%u,"
                        "\"type\":\"SCALAR\"},"
                        "{\"bufferView\":0,\"byteOffset\":12,\"componentType\":5121,"
                        "\"normalized\":true,\"count\":%u,\"type\":\"VEC4\"}],"
                        "\"bufferViews\":[{\"buffer\":0,\"byteLength\":%zu,\"byteStride\":16},"
                        "{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu}]",
                    nidx, m.vertex_count, 16 * (size_t)m.vertex_count,
                    16 * (size_t)m.vertex_count, idx_bytes);
    for (uint32_t v = 0; v < m.vertex_count; v++) {
        for (int a = 0; a < 3; a++)
            mts_buf_f32(&bin, m.positions[3 * (size_t)v + a]);
        for (int a = 0; a < 3; a++)
            mts_buf_u8(&bin, (uint8_t)lrintf(255.0f * mts_fuzz_gltf_color(&m, v, a)));
        mts_buf_u8(&bin, v % 4 ? 255 : 128);
    }
    mts_fuzz_gltf_put_indices16(&bin, &m);
    mts_fuzz_gltf_emit(sd, "torus-colors-ubyte.glb", &j, &bin, 1);

    /* triangle strips: a strip a ring of the torus, vertices (i, j) and
     * (i + 1, j) in turn around it, the rings joined into one strip by
     * repeating the last index of one and the first of the next (an even
     * number of indices each, so that every ring starts on an even
     * triangle and keeps its winding); the joins' triangles are degenerate
     * and dropped */
    j.size = 0;
    bin.size = 0;
    const int ring_len = 2 * (nv + 1), strip_len = nu * ring_len + 2 * (nu - 1);
    mts_fuzz_gltf_head(&j, "0");
    mts_fuzz_printf(&j, ",\"nodes\":[{\"mesh\":0}],\"meshes\":[{\"primitives\":[{\"attributes\":"
                        "{\"POSITION\":0},\"indices\":1,\"mode\":5}]}],\"accessors\":[");
    mts_fuzz_gltf_position_accessor(&j, &m, 0, "");
    mts_fuzz_printf(&j, ",{\"bufferView\":1,\"componentType\":5123,\"count\":%d,"
                        "\"type\":\"SCALAR\"}],\"bufferViews\":[{\"buffer\":0,\"byteLength\":%zu},"
                        "{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%d}]",
                    strip_len, pos_bytes, pos_bytes, 2 * strip_len);
    mts_fuzz_gltf_put_positions(&bin, &m);
    for (int i = 0; i < nu; i++) {
        if (i > 0) {
            mts_buf_u16(&bin, (uint16_t)(i * nv)); /* the last of ring i - 1 */
            mts_buf_u16(&bin, (uint16_t)(i * nv)); /* the first of ring i */
        }
        for (int k = 0; k <= nv; k++) {
            mts_buf_u16(&bin, (uint16_t)(i * nv + k % nv));
            mts_buf_u16(&bin, (uint16_t)((i + 1) % nu * nv + k % nv));
        }
    }
    mts_fuzz_gltf_emit(sd, "torus-strips.glb", &j, &bin, 1);

    /* sparse: three positions moved out (uint8 indices), on the positions'
     * view; COLOR_0 without a view, zero but for four vertices (uint16
     * indices) */
    j.size = 0;
    bin.size = 0;
    static const uint8_t moved[3] = {0, 7, 20};
    static const uint16_t lit[4] = {1, 9, 17, 29};
    const size_t sparse_at = pos_bytes + idx_bytes;
    mts_fuzz_gltf_head(&j, "0");
    mts_fuzz_printf(&j, ",\"nodes\":[{\"mesh\":0}],\"meshes\":[{\"primitives\":[{\"attributes\":"
                        "{\"POSITION\":0,\"COLOR_0\":2},\"indices\":1}]}],\"accessors\":[");
    mts_fuzz_gltf_position_accessor(&j, &m, 0,
                                    ",\"sparse\":{\"count\":3,\"indices\":{\"bufferView\":2,"
                                    "\"componentType\":5121},\"values\":{\"bufferView\":3}}");
    mts_fuzz_printf(&j, ",{\"bufferView\":1,\"componentType\":5123,\"count\":%u,"
                        "\"type\":\"SCALAR\"},"
                        "{\"componentType\":5126,\"count\":%u,\"type\":\"VEC3\","
                        "\"sparse\":{\"count\":4,\"indices\":{\"bufferView\":4,"
                        "\"componentType\":5123},\"values\":{\"bufferView\":5}}}],"
                        "\"bufferViews\":[{\"buffer\":0,\"byteLength\":%zu},"
                        "{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu},"
                        "{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":3},"
                        "{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":36},"
                        "{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":8},"
                        "{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":48}]",
                    nidx, m.vertex_count, pos_bytes, pos_bytes, idx_bytes, sparse_at,
                    sparse_at + 4, sparse_at + 40, sparse_at + 48);
    mts_fuzz_gltf_put_positions(&bin, &m);
    mts_fuzz_gltf_put_indices16(&bin, &m);
    mts_buf_put(&bin, moved, 3);
    mts_buf_u8(&bin, 0); /* the values' view starts 4-aligned */
    for (int k = 0; k < 3; k++)
        for (int a = 0; a < 3; a++)
            mts_buf_f32(&bin, 1.1f * m.positions[3 * (size_t)moved[k] + a]);
    for (int k = 0; k < 4; k++)
        mts_buf_u16(&bin, lit[k]);
    for (int k = 0; k < 4; k++)
        for (int a = 0; a < 3; a++)
            mts_buf_f32(&bin, mts_fuzz_gltf_color(&m, lit[k], a));
    mts_fuzz_gltf_emit(sd, "torus-sparse.glb", &j, &bin, 1);

    mts_buf_free(&j);
    mts_buf_free(&bin);
    mts_mesh_free(&m);
    return MTS_OK;
}

/* Makes every seed; cow_path is tests/data/cow.off (NULL: torus seeds only).
 * slow: also cow's whole model file (160 KiB), which takes a fuzz target some
 * 100 ms an execution (it is validated, walked and written again): the
 * regression test runs it, the fuzzer's corpus does without (it would spend
 * its time there, and the torus files reach the same code).
 * Returns MTS_OK, or the first error (err says what). */
static inline mts_result mts_fuzz_make_seeds(const char *cow_path, int slow, mts_fuzz_emit_fn emit,
                                             void *user, mts_error *err)
{
    mts_fuzz_seeder sd = {emit, user, 0};
    mts_stream torus, small, seq, normals;
    mts_result rc;
    if ((rc = mts_fuzz_torus_stream(8, 10, 8, 1, &torus, err)) != MTS_OK)
        return mts_error_prefix(err, "torus");
    if ((rc = mts_fuzz_torus_stream(5, 6, 4, 1, &small, err)) != MTS_OK) {
        mts_stream_free(&torus);
        return mts_error_prefix(err, "small torus");
    }
    /* the small torus again, its (computed) normals taken as the source's
     * own, so that they travel (MODEL_INFO flags bit 0), in both forms */
    {
        size_t size = 0;
        char *off = mts_fuzz_torus_off(5, 6, &size);
        mts_model m;
        rc = off ? mts_fuzz_build_model("torus.off", off, size, 0, &m, err)
                 : mts_error_set(err, MTS_ERR_NOMEM, "out of memory");
        free(off);
        if (rc == MTS_OK) {
            m.flags |= MTS_MODEL_NORMALS_GIVEN;
            mts_stream_options o = {0};
            o.batch_splits = 4;
            o.with_records = 1;
            rc = mts_stream_build(&m, "fuzz", &o, &normals, err);
            mts_model_free(&m);
        }
        if (rc != MTS_OK) {
            mts_stream_free(&torus);
            mts_stream_free(&small);
            return mts_error_prefix(err, "torus with normals");
        }
    }
    /* the same small torus, its base mesh Draco-encoded with the sequential method */
    {
        size_t size = 0;
        char *off = mts_fuzz_torus_off(5, 6, &size);
        mts_model m;
        rc = off ? mts_fuzz_build_model("torus.off", off, size, 0, &m, err)
                 : mts_error_set(err, MTS_ERR_NOMEM, "out of memory");
        free(off);
        if (rc == MTS_OK) {
            mts_stream_options o = {0};
            o.batch_splits = 4;
            o.draco_method = MTS_DRACO_SEQUENTIAL;
            rc = mts_stream_build(&m, "fuzz", &o, &seq, err);
            mts_model_free(&m);
        }
        if (rc != MTS_OK) {
            mts_stream_free(&torus);
            mts_stream_free(&small);
            mts_stream_free(&normals);
            return mts_error_prefix(err, "sequential torus");
        }
    }

    /* the small torus with a colour per vertex from its position, so
     * that colours travel (MODEL_INFO flags bit 2), in both forms; none
     * when building it fails (out of memory: sd.failed) */
    mts_stream colored = {0};
    int have_colored = 0;
    {
        size_t size = 0;
        char *off = mts_fuzz_torus_off(5, 6, &size);
        mts_model m;
        rc = off ? mts_fuzz_build_model("torus.off", off, size, 0, &m, err)
                 : mts_error_set(err, MTS_ERR_NOMEM, "out of memory");
        free(off);
        if (rc == MTS_OK) {
            free(m.colors);
            m.colors = malloc(3 * (size_t)m.vertex_count + 1);
            for (uint32_t x = 0; m.colors && x < m.vertex_count; x++)
                for (int a = 0; a < 3; a++)
                    m.colors[3 * (size_t)x + a] =
                        (uint8_t)(128 + (int)(100.0f * m.positions[3 * (size_t)x + a]));
            m.flags |= m.colors ? MTS_MODEL_COLORS : 0;
            mts_stream_options o = {0};
            o.batch_splits = 4;
            o.with_records = 1;
            have_colored = m.colors && mts_stream_build(&m, "fuzz", &o, &colored, err) == MTS_OK;
            mts_model_free(&m);
        }
        sd.failed |= !have_colored;
    }

    /* stream_client */
    const uint32_t n = torus.model.level_count;
    const uint32_t torus_stops[] = {0, 9, n / 2, n};
    mts_fuzz_stream_seeds(&sd, "torus", &torus, torus_stops, 4, 1);
    mts_fuzz_resume_seeds(&sd, "torus", &torus);
    const uint32_t small_stops[] = {small.model.level_count};
    mts_fuzz_stream_seeds(&sd, "small", &small, small_stops, 1, 0);
    mts_fuzz_stream_seeds(&sd, "sequential", &seq, small_stops, 1, 0);
    /* the records form: the same stops, variants and breaks */
    if (torus.records_form && small.records_form && normals.records_form) {
        mts_fuzz_stream_seeds(&sd, "torus-records", torus.records_form, torus_stops, 4, 1);
        mts_fuzz_resume_seeds(&sd, "torus-records", torus.records_form);
        mts_fuzz_stream_seeds(&sd, "small-records", small.records_form, small_stops, 1, 0);
        const uint32_t normals_stops[] = {normals.model.level_count / 2,
                                          normals.model.level_count};
        mts_fuzz_stream_seeds(&sd, "small-normals", &normals, normals_stops, 2, 0);
        mts_fuzz_stream_seeds(&sd, "small-normals-records", normals.records_form, normals_stops,
                              2, 0);
    } else {
        sd.failed = 1; /* with_records = 1 gave none: out of memory */
    }
    if (have_colored && colored.records_form) {
        const uint32_t colored_stops[] = {colored.model.level_count / 2,
                                          colored.model.level_count};
        mts_fuzz_stream_seeds(&sd, "small-colors", &colored, colored_stops, 2, 0);
        mts_fuzz_stream_seeds(&sd, "small-colors-records", colored.records_form, colored_stops,
                              2, 0);
    }
    {
        mts_buf b = {0};
        mts_wire_model_entry e[2] = {{"fuzz", 80, 160, 76, 4000}, {"cow.v2", 2904, 5804, 2875, 90000}};
        mts_wire_put_models(&b, e, 2);
        mts_wire_put_error(&b, MTS_WERR_BUSY, "never read: MODELS ends the conversation");
        if (!b.failed)
            mts_fuzz_emit_mode(&sd, "stream_client", "models", 0, b.data, b.size);
        b.size = 0;
        mts_wire_put_error(&b, MTS_WERR_UNKNOWN_MODEL, "no model named 'x' (LIST shows the models)");
        if (!b.failed)
            mts_fuzz_emit_mode(&sd, "stream_client", "error", 0, b.data, b.size);
        sd.failed |= b.failed;
        mts_buf_free(&b);
    }

    /* stream_file: whole files of the torus in both forms and of the torus
     * whose normals travel */
    mts_fuzz_stream_file_seeds(&sd, "torus", &torus, 1);
    if (torus.records_form)
        mts_fuzz_stream_file_seeds(&sd, "torus-records", torus.records_form, 0);
    mts_fuzz_stream_file_seeds(&sd, "small-normals", &normals, 0);
    if (have_colored)
        mts_fuzz_stream_file_seeds(&sd, "small-colors", &colored, 0);

    /* request */
    mts_fuzz_request_seeds(&sd, &torus);

    /* ws */
    mts_fuzz_ws_seeds(&sd, &torus);

    /* modelfile: the models as mts-build would write them (the streams'
     * models are snapped to the grid, which a model file does not mind) */
    mts_fuzz_modelfile_seed(&sd, "torus", 0, &torus.model);
    mts_fuzz_modelfile_seed(&sd, "torus-crc-kept", 1, &torus.model);
    mts_fuzz_modelfile_seed(&sd, "small", 0, &small.model);
    {
        /* the small torus with a colour per vertex: the COLORS section */
        mts_model colored = small.model;
        uint8_t *c = malloc(3 * (size_t)colored.vertex_count + 1);
        if (c) {
            for (size_t i = 0; i < 3 * (size_t)colored.vertex_count; i++)
                c[i] = (uint8_t)(i * 37u);
            colored.colors = c;
            colored.flags |= MTS_MODEL_COLORS;
            mts_fuzz_modelfile_seed(&sd, "small-colors", 0, &colored);
            mts_fuzz_modelfile_seed(&sd, "small-colors-crc-kept", 1, &colored);
            free(c);
        }
    }
    {
        mts_model hm;
        hand_state hs[3];
        hand_model_erases(&hm, hs);
        mts_fuzz_modelfile_seed(&sd, "hand-erases", 0, &hm);
        mts_model_free(&hm);
        /* random records: several edits on a strip, empty runs (few
         * vertices: a wide model's positions would make a big seed) */
        uint64_t seed = 2024;
        hand_state *states = hand_random_model(&seed, 0, &hm);
        mts_fuzz_modelfile_seed(&sd, "hand-random", 0, &hm);
        mts_model_free(&hm);
        free(states);
    }

    /* draco: what BASE frames carry, and whole meshes with and without normals */
    size_t dsize = 0;
    const uint8_t *d = mts_fuzz_base_draco(&torus, &dsize);
    if (d)
        sd.emit(sd.user, "draco", "torus-base-edgebreaker", d, dsize);
    if ((d = mts_fuzz_base_draco(&seq, &dsize)) != NULL)
        sd.emit(sd.user, "draco", "small-base-sequential", d, dsize);
    mts_fuzz_draco_seed(&sd, "torus-edgebreaker", &torus, MTS_DRACO_EDGEBREAKER, 1);
    mts_fuzz_draco_seed(&sd, "torus-sequential", &torus, MTS_DRACO_SEQUENTIAL, 1);
    mts_fuzz_draco_seed(&sd, "small-edgebreaker-no-normals", &small, MTS_DRACO_EDGEBREAKER, 0);
    mts_fuzz_draco_seed(&sd, "small-sequential-no-normals", &small, MTS_DRACO_SEQUENTIAL, 0);
    mts_stream_free(&torus);
    mts_stream_free(&small);
    mts_stream_free(&seq);
    mts_stream_free(&normals);
    if (have_colored)
        mts_stream_free(&colored);

    /* gltf: the small torus as glTF */
    if ((rc = mts_fuzz_gltf_seeds(&sd, err)) != MTS_OK)
        return mts_error_prefix(err, "glTF seeds");

    /* cow: the real model, cut at its first batches (its full stream and
     * file are a few hundred KiB: too slow an input to mutate) */
    if (cow_path) {
        mts_model m;
        if ((rc = mts_fuzz_build_model(cow_path, NULL, 0, 0, &m, err)) != MTS_OK)
            return rc;
        mts_stream cow;
        mts_stream_options o = {0};
        o.with_records = 1;
        rc = mts_stream_build(&m, "cow", &o, &cow, err);
        if (rc == MTS_OK) {
            uint32_t cow_stops[3] = {0, 0, 0};
            size_t nstops = 1;
            for (uint32_t k = 1; k <= 3 && k < cow.batch_count; k += 2)
                cow_stops[nstops++] = cow.batch_first[k];
            mts_fuzz_stream_seeds(&sd, "cow", &cow, cow_stops, nstops, 0);
            /* its records form to the first batch's end only: some 5 KiB a
             * batch, 16 times the splits form's */
            if (cow.records_form)
                mts_fuzz_stream_seeds(&sd, "cow-records", cow.records_form, cow_stops,
                                      nstops > 2 ? 2 : nstops, 0);
            else
                sd.failed = 1;
            if ((d = mts_fuzz_base_draco(&cow, &dsize)) != NULL)
                sd.emit(sd.user, "draco", "cow-base-edgebreaker", d, dsize);
            /* the whole splits form as a file, for the regression test only:
             * a stream file is the whole stream, too slow an input to mutate */
            if (slow)
                mts_fuzz_stream_file_seeds(&sd, "cow", &cow, 0);
            mts_stream_free(&cow);
        }
        if (slow)
            mts_fuzz_modelfile_seed(&sd, "cow", 0, &m);
        mts_model_free(&m);
        if (rc != MTS_OK)
            return rc;
    }
    if (sd.failed)
        return mts_error_set(err, MTS_ERR_NOMEM, "fuzz seeds: out of memory");
    return MTS_OK;
}

#endif
