/* The parts of draco.h that need no Draco library: the quantization grid's
 * arithmetic and the bounds check of a buffer's head. The native build links
 * them beside draco.cpp, the browser build (web/) beside its shim over
 * Draco's own WebAssembly decoder, so both ends quantize and check alike. */
#include "draco.h"

#include <math.h>
#include <string.h>

/* Draco indexes points and corners with 32-bit ints; stay well inside. */
#define MAX_VERTICES (1u << 30)
#define MAX_TRIANGLES ((1u << 30) / 3)

static uint32_t max_quantized(int bits)
{
    return (1u << bits) - 1u;
}

static int finite3(const float *v)
{
    return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]);
}

int mts_draco_grid_valid(const mts_draco_grid *g)
{
    return g->bits >= 1 && g->bits <= MTS_DRACO_MAX_BITS && finite3(g->origin) &&
           isfinite(g->range) && g->range > 0.f;
}

mts_result mts_draco_grid_from_positions(const float *pos, uint32_t n, int bits,
                                         mts_draco_grid *g, mts_error *err)
{
    if (!g || (n && !pos))
        return mts_error_set(err, MTS_ERR_ARG, "draco grid: NULL argument");
    if (n == 0)
        return mts_error_set(err, MTS_ERR_ARG, "draco grid: no positions");
    if (bits == 0)
        bits = MTS_DRACO_DEFAULT_POSITION_BITS;
    if (bits < 1 || bits > MTS_DRACO_MAX_BITS)
        return mts_error_set(err, MTS_ERR_ARG, "draco grid: %d quantization bits (1..%d)", bits,
                             MTS_DRACO_MAX_BITS);
    float lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
    for (uint32_t i = 0; i < n; ++i) {
        const float *p = pos + 3 * (size_t)i;
        if (!finite3(p))
            return mts_error_set(err, MTS_ERR_RANGE, "draco grid: vertex %u is not finite", i);
        for (int c = 0; c < 3; ++c) {
            if (i == 0 || p[c] < lo[c])
                lo[c] = p[c];
            if (i == 0 || p[c] > hi[c])
                hi[c] = p[c];
        }
    }
    /* As AttributeQuantizationTransform::ComputeParameters: the largest side,
     * 1 when every position is the same. */
    float range = 0.f;
    for (int c = 0; c < 3; ++c) {
        float side = hi[c] - lo[c];
        if (range < side)
            range = side;
    }
    if (!isfinite(range))
        return mts_error_set(err, MTS_ERR_RANGE, "draco grid: box too large for float");
    if (range == 0.f)
        range = 1.f;
    g->bits = bits;
    memcpy(g->origin, lo, sizeof lo);
    g->range = range;
    return MTS_OK;
}

/* Draco: Quantizer::Init(range, maxq): inverse_delta = (float)maxq / range;
 * QuantizeFloat(v) = (int32) floor(v * inverse_delta + 0.5f), v = p - origin.
 * The volatile keeps the product rounded to float (no fused multiply-add,
 * whatever -ffp-contract the build uses), as Draco's amd64 build computes it. */
int mts_draco_quantize(const mts_draco_grid *g, const float p[3], uint32_t q[3])
{
    if (!g || !p || !q)
        return 0;
    if (!mts_draco_grid_valid(g)) {
        q[0] = q[1] = q[2] = 0;
        return 0;
    }
    const uint32_t maxq = max_quantized(g->bits);
    const float inv = (float)maxq / g->range;
    int inside = 1;
    for (int c = 0; c < 3; ++c) {
        const float v = p[c] - g->origin[c];
        volatile float scaled = v * inv;
        const float f = floorf(scaled + 0.5f);
        if (!(f >= 0.f)) { /* negative or NaN */
            q[c] = 0;
            inside = 0;
        } else if (f > (float)maxq) {
            q[c] = maxq;
            inside = 0;
        } else {
            q[c] = (uint32_t)f;
            if (q[c] > maxq) { /* f rounded up to 2^bits for bits > 24 */
                q[c] = maxq;
                inside = 0;
            }
        }
    }
    return inside;
}

/* Draco: Dequantizer::Init(range, maxq): delta = range / (float)maxq;
 * AttributeQuantizationTransform::InverseTransformAttribute:
 * p = (float)q * delta, then p = p + origin. */
void mts_draco_dequantize(const mts_draco_grid *g, const uint32_t q[3], float p[3])
{
    if (!g || !q || !p)
        return;
    if (!mts_draco_grid_valid(g)) {
        p[0] = p[1] = p[2] = 0.f;
        return;
    }
    const float delta = g->range / (float)max_quantized(g->bits);
    for (int c = 0; c < 3; ++c) {
        volatile float scaled = (float)(int32_t)q[c] * delta;
        p[c] = scaled + g->origin[c];
    }
}

/* Draco's DecodeVarint<uint32_t>: at most 5 bytes, low bits first, wrapping
 * to 32 bits as Draco's does, so that this reads the value Draco will read. */
static int head_varint(const uint8_t **p, const uint8_t *end, uint64_t *v)
{
    uint32_t x = 0;
    for (int i = 0; i < 5 && *p < end; ++i) {
        const uint8_t b = *(*p)++;
        x |= (uint32_t)(b & 0x7f) << (7 * i);
        if (!(b & 0x80)) {
            *v = x;
            return 1;
        }
    }
    return 0;
}

/* Draco trusts the counts at the head of a buffer: its Edgebreaker decoder
 * reserves and fills arrays for the declared faces and vertices before it
 * reads a single symbol, and the sequential one sizes its attributes by the
 * declared points. A 100-byte buffer declaring a billion faces made it ask
 * for 5 GB (found by tests/fuzz/fuzz_draco.c; the input is kept in
 * tests/fuzz/regressions/draco/). So the head is read here first and the
 * counts bounded before Draco sees them (docs/architecture.md, invariant 4).
 *
 * What is accepted is what mts_draco_encode writes: the bitstream version
 * Draco 1.5 writes (2.2; the head's layout below is 2.2's), a triangle mesh,
 * sequential or Edgebreaker, no metadata. The bound: at most DECLARED_PER_BYTE
 * faces (and as many vertices) per byte of the buffer, never less than
 * DECLARED_FLOOR. Real encodings hold far fewer: a 300 x 300 perfectly
 * regular grid, the most compressible mesh there is, is 12 faces a byte
 * (sequential; Edgebreaker under 1). */
#define DECLARED_PER_BYTE 256u
#define DECLARED_FLOOR (1u << 16)

mts_result mts_draco_check_head(const uint8_t *data, size_t size, mts_error *err)
{
    const uint8_t *p = data, *end = data + size;
    /* "DRACO", major, minor, geometry type, method, u16 flags */
    if (size < 11 || memcmp(p, "DRACO", 5) != 0)
        return mts_error_set(err, MTS_ERR_FORMAT, "draco decode: not a Draco buffer");
    if (p[5] != MTS_DRACO_BITSTREAM_MAJOR || p[6] != MTS_DRACO_BITSTREAM_MINOR)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "draco decode: bitstream version %u.%u (this reads %u.%u)", p[5], p[6],
                             MTS_DRACO_BITSTREAM_MAJOR, MTS_DRACO_BITSTREAM_MINOR);
    if (p[7] != MTS_DRACO_TRIANGULAR_MESH)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "draco decode: not a triangle mesh (geometry type %u)", p[7]);
    const uint16_t flags = (uint16_t)(p[9] | p[10] << 8);
    if (flags != 0)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "draco decode: header flags %#x (metadata is not read)",
                             (unsigned)flags);
    const uint8_t method = p[8];
    p += 11;
    uint64_t faces = 0, vertices = 0, split = 0, unused;
    int ok;
    if (method == MTS_DRACO_SEQUENTIAL_BITSTREAM) {
        ok = head_varint(&p, end, &faces) && head_varint(&p, end, &vertices);
    } else if (method == MTS_DRACO_EDGEBREAKER_BITSTREAM) {
        /* traversal decoder type, encoded vertices, faces, attribute data
         * count, symbols, split symbols (each split symbol may add a vertex) */
        ok = p++ < end && head_varint(&p, end, &vertices) && head_varint(&p, end, &faces) &&
             p++ < end && head_varint(&p, end, &unused) && head_varint(&p, end, &split);
    } else {
        return mts_error_set(err, MTS_ERR_FORMAT, "draco decode: unknown mesh method %u", method);
    }
    if (!ok)
        return mts_error_set(err, MTS_ERR_FORMAT, "draco decode: buffer ends inside its header");
    uint64_t limit = (uint64_t)DECLARED_PER_BYTE * size;
    if (limit < DECLARED_FLOOR)
        limit = DECLARED_FLOOR;
    const uint64_t max_faces = limit < MAX_TRIANGLES ? limit : MAX_TRIANGLES;
    const uint64_t max_vertices = limit < MAX_VERTICES ? limit : MAX_VERTICES;
    if (faces > max_faces || vertices + split > max_vertices)
        return mts_error_set(err, MTS_ERR_LIMIT,
                             "draco decode: %llu faces and %llu vertices declared in %zu bytes "
                             "(at most %llu of each)",
                             (unsigned long long)faces, (unsigned long long)(vertices + split), size,
                             (unsigned long long)max_vertices);
    return MTS_OK;
}
