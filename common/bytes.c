#include "bytes.h"

#include <stdlib.h>

int mts_buf_reserve(mts_buf *b, size_t extra)
{
    if (b->failed)
        return 0;
    if (extra <= b->cap - b->size)
        return 1;
    size_t cap = b->cap ? b->cap : 256;
    while (cap - b->size < extra) {
        if (cap > SIZE_MAX / 2) {
            b->failed = 1;
            return 0;
        }
        cap *= 2;
    }
    uint8_t *d = realloc(b->data, cap);
    if (!d) {
        b->failed = 1;
        return 0;
    }
    b->data = d;
    b->cap = cap;
    return 1;
}

void mts_buf_free(mts_buf *b)
{
    free(b->data);
    memset(b, 0, sizeof *b);
}

void mts_buf_put(mts_buf *b, const void *data, size_t size)
{
    if (size == 0 || !mts_buf_reserve(b, size))
        return;
    memcpy(b->data + b->size, data, size);
    b->size += size;
}

void mts_buf_u8(mts_buf *b, uint8_t x)
{
    mts_buf_put(b, &x, 1);
}

void mts_buf_u16(mts_buf *b, uint16_t x)
{
    uint8_t p[2] = {(uint8_t)x, (uint8_t)(x >> 8)};
    mts_buf_put(b, p, 2);
}

void mts_buf_u32(mts_buf *b, uint32_t x)
{
    uint8_t p[4];
    for (int i = 0; i < 4; i++)
        p[i] = (uint8_t)(x >> (8 * i));
    mts_buf_put(b, p, 4);
}

void mts_buf_u64(mts_buf *b, uint64_t x)
{
    mts_buf_u32(b, (uint32_t)x);
    mts_buf_u32(b, (uint32_t)(x >> 32));
}

void mts_buf_f32(mts_buf *b, float x)
{
    uint32_t bits;
    memcpy(&bits, &x, 4);
    mts_buf_u32(b, bits);
}

void mts_buf_varint(mts_buf *b, uint32_t x)
{
    uint8_t p[MTS_VARINT32_MAX_BYTES];
    mts_buf_put(b, p, mts_varint_put(p, x));
}

void mts_buf_string(mts_buf *b, const char *s, size_t len)
{
    mts_buf_varint(b, (uint32_t)len);
    mts_buf_put(b, s, len);
}

void mts_buf_patch_u32(mts_buf *b, size_t at, uint32_t x)
{
    if (b->failed || at + 4 > b->size)
        return;
    for (int i = 0; i < 4; i++)
        b->data[at + i] = (uint8_t)(x >> (8 * i));
}

const uint8_t *mts_cursor_bytes(mts_cursor *c, size_t n)
{
    if (!c->ok || (size_t)(c->end - c->p) < n) {
        c->ok = 0;
        return NULL;
    }
    const uint8_t *at = c->p;
    c->p += n;
    return at;
}

uint8_t mts_cursor_u8(mts_cursor *c)
{
    const uint8_t *p = mts_cursor_bytes(c, 1);
    return p ? p[0] : 0;
}

uint16_t mts_cursor_u16(mts_cursor *c)
{
    const uint8_t *p = mts_cursor_bytes(c, 2);
    return p ? (uint16_t)(p[0] | p[1] << 8) : 0;
}

uint32_t mts_cursor_u32(mts_cursor *c)
{
    const uint8_t *p = mts_cursor_bytes(c, 4);
    return p ? (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 |
                   (uint32_t)p[3] << 24
             : 0;
}

uint64_t mts_cursor_u64(mts_cursor *c)
{
    uint64_t lo = mts_cursor_u32(c);
    return lo | (uint64_t)mts_cursor_u32(c) << 32;
}

float mts_cursor_f32(mts_cursor *c)
{
    uint32_t bits = mts_cursor_u32(c);
    float x;
    memcpy(&x, &bits, 4);
    return x;
}

uint32_t mts_cursor_varint(mts_cursor *c)
{
    uint32_t x = 0;
    if (!c->ok || !mts_varint_get(&c->p, c->end, &x)) {
        c->ok = 0;
        return 0;
    }
    return x;
}

const char *mts_cursor_string(mts_cursor *c, size_t max, size_t *len)
{
    uint32_t n = mts_cursor_varint(c);
    if (!c->ok || n > max) {
        c->ok = 0;
        *len = 0;
        return NULL;
    }
    const uint8_t *p = mts_cursor_bytes(c, n);
    *len = p ? n : 0;
    return (const char *)p;
}
