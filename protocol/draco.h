/* Draco shim for the stream's base mesh (docs/architecture.md, "The stream").
 *
 * The base mesh travels Draco-compressed. Positions are quantized on ONE grid
 * for the whole model (Draco's explicit quantization: origin = min corner of
 * the FULL mesh's box, range = its largest side), so base vertices (quantized
 * by Draco) and refinement vertices (quantized by mts_draco_quantize) lie on
 * the same lattice and meet without cracks.
 *
 * What Draco 1.5.5 does (checked by tests/test_draco.c on cow and bunny00):
 *  - Sequential keeps vertex order, face order and corner order exactly.
 *  - Edgebreaker renumbers vertices (2 of bunny00's 37,706 keep their id),
 *    reorders faces and rotates the corners of a face (about a third each
 *    way) but keeps every face's orientation. It also splits non-manifold
 *    vertices and edges and the vertices between faces of opposite
 *    orientation, and drops degenerate faces and unreferenced vertices.
 *  The server therefore encodes, decodes its own output with mts_draco_decode
 *  and calls mts_draco_renumber for original id -> decoded id; the stream's
 *  base vertex ids follow from the decoded ones (stream_coding.c sorts them by grid
 *  point), which every client gets too. When
 *  renumbering fails the caller encodes again with MTS_DRACO_SEQUENTIAL.
 *  The mesh is built as a draco::Mesh directly, one point per vertex (no
 *  TriangleSoupMeshBuilder, which would deduplicate); with positions only the
 *  output is byte for byte what `draco_encoder -qp 14 -cl N` writes.
 *
 * Quantization, exactly as Draco 1.5.5 does it (AttributeQuantizationTransform
 * with draco::Quantizer / Dequantizer, all in float):
 *     maxq  = 2^bits - 1
 *     q     = (int32) floor((p - origin) * ((float)maxq / range) + 0.5f)
 *     p'    = (float)q * (range / (float)maxq) + origin
 * each product and sum rounded to float (no fused multiply-add). Two rules make
 * the integers and floats the same on every machine, whatever Draco's own
 * build does with floats:
 *  - mts_draco_encode hands Draco each position already snapped to its grid
 *    point p', which Draco's formula maps back to q with almost half a step
 *    to spare (a build of Draco with fused multiply-add could otherwise move
 *    values lying near a half step);
 *  - mts_draco_decode asks Draco for the integer positions and dequantizes
 *    them with mts_draco_dequantize; base and refinement vertices go through
 *    the same code. (On amd64 Draco's own dequantized floats are the same, bit
 *    for bit.) Normals are Draco's octahedral ones, dequantized by Draco.
 *
 * Colours (mts_draco_mesh.colors) go in as a COLOR attribute of 3 unsigned
 * bytes, one value per point like the positions. Draco 1.5.5 quantizes
 * only float attributes, so an integer one takes its integer attribute
 * coder: predicted (parallelogram at -cl 3..8, constrained
 * multi-parallelogram above, a plain difference at -cl 0..2), then
 * entropy-coded, and decoded bit for bit (tests/test_stream_colors.c checks
 * it on cow and on the stream's base). Their prediction follows Edgebreaker's
 * traversal, so they do not change the connectivity or its renumbering.
 *
 * Every function catches all C++ exceptions, prints nothing and keeps no
 * global state; results are malloc'ed and freed with the functions below. */
#ifndef MTS_DRACO_H
#define MTS_DRACO_H

#include <stddef.h>
#include <stdint.h>

#include "error.h"

#ifdef __cplusplus
extern "C" {
#endif

#define MTS_DRACO_DEFAULT_POSITION_BITS 14
#define MTS_DRACO_DEFAULT_NORMAL_BITS 10
#define MTS_DRACO_MAX_BITS 30 /* Draco's limit for quantization bits */

/* The quantization grid of positions. */
typedef struct mts_draco_grid {
    int bits;         /* 1..30 */
    float origin[3];  /* min corner of the full model's box */
    float range;      /* largest side of that box (> 0) */
} mts_draco_grid;

/* A mesh to encode (not owned). */
typedef struct mts_draco_mesh {
    uint32_t vertex_count;
    uint32_t triangle_count;
    const float *positions;    /* 3 per vertex */
    const float *normals;      /* 3 per vertex, or NULL */
    const uint32_t *triangles; /* 3 per triangle */
    /* 3 per vertex (8-bit r, g, b), or NULL: a COLOR attribute of unsigned
     * bytes, which Draco codes losslessly (see the top) */
    const uint8_t *colors;
    /* 3 per vertex, or NULL: the grid points the positions were quantized
     * to, which mts_draco_renumber matches the decoded ones against. Draco
     * keeps the grid's origin and range to six decimals, so on a small model
     * the positions quantized again on the decoded grid can land a step
     * away; NULL quantizes them on it all the same. Not read by encode. */
    const uint32_t *quantized;
} mts_draco_mesh;

typedef enum mts_draco_method {
    MTS_DRACO_EDGEBREAKER = 0, /* default: best compression, reorders vertices */
    MTS_DRACO_SEQUENTIAL = 1   /* keeps vertex and face order */
} mts_draco_method;

/* Encoding options; a zero-initialised struct means the defaults. */
typedef struct mts_draco_options {
    /* Position grid. grid.bits 0 = 14. grid.range 0 = the box of this mesh
     * (mts_draco_grid_from_positions); the server passes the FULL model's grid. */
    mts_draco_grid grid;
    int normal_bits;         /* 0 = 10; -1 = leave normals out; else 1..30 */
    int method;              /* an mts_draco_method; 0 = edgebreaker */
    /* draco_encoder's -cl: 1..10 (Draco speed 10 - cl); 0 = default 10 (best);
     * -1 = -cl 0 (fastest, worst). */
    int compression_level;
} mts_draco_options;

/* A decoded mesh (owned; free with mts_draco_mesh_out_free). */
typedef struct mts_draco_mesh_out {
    uint32_t vertex_count;
    uint32_t triangle_count;
    float *positions;    /* 3 per vertex: mts_draco_dequantize(grid, quantized) */
    uint32_t *quantized; /* 3 per vertex, each in [0, 2^bits - 1] */
    float *normals;      /* 3 per vertex, or NULL when the stream has none */
    uint32_t *triangles; /* 3 per triangle, each < vertex_count */
    uint8_t *colors;     /* 3 per vertex, or NULL when the stream has none */
    mts_draco_grid grid; /* the grid read from the stream */
} mts_draco_mesh_out;

/* Compresses `in`. On success *out is a malloc'ed buffer of *size bytes (free()
 * it). Errors: MTS_ERR_ARG (bad options, index out of range, NULL arrays),
 * MTS_ERR_RANGE (a position outside the grid or not finite), MTS_ERR_NOMEM,
 * MTS_ERR_INTERNAL (Draco refused). */
mts_result mts_draco_encode(const mts_draco_mesh *in, const mts_draco_options *opts,
                            uint8_t **out, size_t *size, mts_error *err);

/* Decodes a buffer made by mts_draco_encode. Nothing in it is trusted: a
 * truncated or corrupt buffer gives MTS_ERR_FORMAT (Draco refused it) or
 * MTS_ERR_RANGE (counts, indices or quantized values out of bounds), never a
 * crash. Since Draco allocates for the counts a buffer declares before it
 * reads them, the head is checked first: another bitstream version, geometry
 * or metadata is MTS_ERR_FORMAT, more faces or vertices than 256 a byte of
 * the buffer (65,536 at least) MTS_ERR_LIMIT. *out is zeroed first and left
 * empty on failure. */
mts_result mts_draco_decode(const uint8_t *data, size_t size, mts_draco_mesh_out *out,
                            mts_error *err);

void mts_draco_mesh_out_free(mts_draco_mesh_out *mesh);

/* Given the mesh the server encoded and what mts_draco_decode made of it,
 * computes vertex_map[original id] = decoded id (a bijection) and, when
 * face_map is not NULL, face_map[original face] = decoded face.
 *
 * Approach: when the decoded mesh is the original in the same order (the
 * sequential method), the identity. Otherwise each original position is
 * quantized on decoded->grid (or original->quantized taken); a vertex
 * whose quantized position is unique on both sides is matched directly.
 * Vertices sharing a quantized position are matched through connectivity:
 * for an original face (a, b, c) with a and b matched, the decoded face
 * holding the directed edge map(a) -> map(b) gives map(c), which must have the
 * same quantized position (orientation is thus required to be kept). This
 * propagates until nothing changes. Nothing is guessed: when a vertex stays
 * ambiguous (e.g. a component made only of duplicated positions), or the
 * counts differ, or the final check (every oriented original face maps to a
 * decoded face, as a multiset, up to rotation) fails, it returns
 * MTS_ERR_INVARIANT and the caller falls back to MTS_DRACO_SEQUENTIAL. */
mts_result mts_draco_renumber(const mts_draco_mesh *original, const mts_draco_mesh_out *decoded,
                              uint32_t *vertex_map, uint32_t *face_map, mts_error *err);

/* The grid Draco would compute for these positions: origin = per-axis min,
 * range = largest side (1 when all positions are equal). bits 0 = 14.
 * MTS_ERR_ARG for no positions, bad bits; MTS_ERR_RANGE for NaN/inf. */
mts_result mts_draco_grid_from_positions(const float *positions, uint32_t count, int bits,
                                         mts_draco_grid *grid, mts_error *err);

/* Quantizes one position exactly as Draco's encoder does (see the top).
 * Returns 1 when all three values lie on the grid ([0, 2^bits - 1]), else 0
 * with the out-of-range values clamped (NaN gives 0). */
int mts_draco_quantize(const mts_draco_grid *grid, const float p[3], uint32_t q[3]);

/* The inverse: p = q * (range / maxq) + origin, in float, not fused. */
void mts_draco_dequantize(const mts_draco_grid *grid, const uint32_t q[3], float p[3]);

/* 1 when the grid can be used: 1..30 bits, a finite origin, range > 0. */
int mts_draco_grid_valid(const mts_draco_grid *grid);

/* What the head of a Draco buffer must say before Draco reads it (see
 * mts_draco_decode): this bitstream version, a triangle mesh, no metadata,
 * and counts a buffer of that size can hold. */
#define MTS_DRACO_BITSTREAM_MAJOR 2
#define MTS_DRACO_BITSTREAM_MINOR 2
#define MTS_DRACO_TRIANGULAR_MESH 1
/* the head's method byte */
#define MTS_DRACO_SEQUENTIAL_BITSTREAM 0
#define MTS_DRACO_EDGEBREAKER_BITSTREAM 1
mts_result mts_draco_check_head(const uint8_t *data, size_t size, mts_error *err);

#ifdef __cplusplus
}
#endif

#endif
