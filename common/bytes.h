/* Byte buffers for writing and cursors for reading little-endian fixed-width
 * numbers, varints and strings. A cursor's error is sticky: once a read runs
 * past the end every later read returns zero and `ok` stays 0, so a parser
 * reads a whole structure and checks once -- but it must check a count
 * against mts_cursor_left() before it allocates or loops on it. */
#ifndef MTS_BYTES_H
#define MTS_BYTES_H

#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "varint.h"

typedef struct mts_buf {
    uint8_t *data;
    size_t size, cap;
    int failed; /* an allocation failed; every later write is dropped */
} mts_buf;

int mts_buf_reserve(mts_buf *b, size_t extra);
void mts_buf_free(mts_buf *b);
void mts_buf_put(mts_buf *b, const void *data, size_t size);
void mts_buf_u8(mts_buf *b, uint8_t x);
void mts_buf_u16(mts_buf *b, uint16_t x);
void mts_buf_u32(mts_buf *b, uint32_t x);
void mts_buf_u64(mts_buf *b, uint64_t x);
void mts_buf_f32(mts_buf *b, float x);
void mts_buf_varint(mts_buf *b, uint32_t x);
void mts_buf_string(mts_buf *b, const char *s, size_t len);
/* Overwrites 4 bytes at an offset already written (a length or a checksum). */
void mts_buf_patch_u32(mts_buf *b, size_t at, uint32_t x);

typedef struct mts_cursor {
    const uint8_t *p, *end;
    int ok;
} mts_cursor;

static inline mts_cursor mts_cursor_make(const void *data, size_t size)
{
    mts_cursor c = {(const uint8_t *)data, (const uint8_t *)data + size, 1};
    return c;
}

static inline size_t mts_cursor_left(const mts_cursor *c)
{
    return c->ok ? (size_t)(c->end - c->p) : 0;
}

const uint8_t *mts_cursor_bytes(mts_cursor *c, size_t n); /* NULL past the end */
uint8_t mts_cursor_u8(mts_cursor *c);
uint16_t mts_cursor_u16(mts_cursor *c);
uint32_t mts_cursor_u32(mts_cursor *c);
uint64_t mts_cursor_u64(mts_cursor *c);
float mts_cursor_f32(mts_cursor *c);
uint32_t mts_cursor_varint(mts_cursor *c);
/* A string of at most max bytes; returns its bytes (not terminated) or NULL. */
const char *mts_cursor_string(mts_cursor *c, size_t max, size_t *len);

#endif
