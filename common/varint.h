/* LEB128 variable-length integers (7 bits a byte, low bits first, high bit
 * set on every byte but the last) and zigzag for signed values: what the
 * model file and the wire use for counts, ids and deltas, which are mostly
 * small. Readers never run past the end they are given. */
#ifndef MTS_VARINT_H
#define MTS_VARINT_H

#include <stddef.h>
#include <stdint.h>

#define MTS_VARINT32_MAX_BYTES 5

/* Writes x at p (room for MTS_VARINT32_MAX_BYTES); returns the bytes written. */
static inline size_t mts_varint_put(uint8_t *p, uint32_t x)
{
    size_t n = 0;
    while (x >= 0x80) {
        p[n++] = (uint8_t)(x | 0x80);
        x >>= 7;
    }
    p[n++] = (uint8_t)x;
    return n;
}

/* Reads one value from [*p, end); advances *p. Returns 0 when the input ends
 * inside the value or the value does not fit 32 bits (or is not minimally
 * encoded in its fifth byte). */
static inline int mts_varint_get(const uint8_t **p, const uint8_t *end, uint32_t *x)
{
    const uint8_t *q = *p;
    if (q < end && *q < 0x80) { /* most values here take one byte */
        *x = *q;
        *p = q + 1;
        return 1;
    }
    uint32_t v = 0;
    for (int shift = 0; shift < 35; shift += 7) {
        if (q >= end)
            return 0;
        uint8_t b = *q++;
        if (shift == 28 && b > 0x0F)
            return 0;
        v |= (uint32_t)(b & 0x7F) << shift;
        if (!(b & 0x80)) {
            *x = v;
            *p = q;
            return 1;
        }
    }
    return 0;
}

/* Zigzag maps small signed deltas to small unsigned numbers (0, -1, 1, -2 ->
 * 0, 1, 2, 3). Deltas are taken between uint32 values modulo 2^32, so these
 * work on the bit patterns and never shift or overflow a signed value. */
static inline uint32_t mts_zigzag_u32(uint32_t delta)
{
    return (delta << 1) ^ (0u - (delta >> 31));
}

static inline uint32_t mts_unzigzag_u32(uint32_t x)
{
    return (x >> 1) ^ (0u - (x & 1u));
}

static inline uint32_t mts_zigzag(int32_t x)
{
    return mts_zigzag_u32((uint32_t)x);
}

static inline int32_t mts_unzigzag(uint32_t x)
{
    uint32_t u = mts_unzigzag_u32(x);
    /* two's complement back to signed without implementation-defined casts */
    return u <= INT32_MAX ? (int32_t)u : -(int32_t)(~u) - 1;
}

#endif
