/* Greedy stripifier: covers a manifold, consistently oriented triangle mesh
 * with generalized triangle strips, every triangle in exactly one strip, each
 * strip's winding equal to the mesh's (see strips.h for the convention).
 * Strips grow STRIPE/NvTriStrip style: seeds are taken from triangles with the
 * fewest free neighbours, a strip prefers to continue without a swap and looks
 * ahead before it turns. Deterministic for the same input. */
#ifndef MTS_STRIPIFY_H
#define MTS_STRIPIFY_H

#include <stdint.h>

#include "error.h"
#include "strips.h"

/* Counts from one run, for reports and benchmarks. */
typedef struct mts_stripify_stats {
    uint32_t strips;
    uint32_t swaps;      /* repeated indices inserted to turn */
    uint32_t singletons; /* strips of a single triangle */
} mts_stripify_stats;

/* triangles: 3 indices per triangle, each < vertex_count. out is allocated
 * (free with mts_strips_free). stats may be NULL.
 * - zero triangles: MTS_OK with an empty set (strip_count 0, offsets[0] 0);
 * - an index >= vertex_count: MTS_ERR_RANGE; a triangle that repeats a
 *   vertex: MTS_ERR_FORMAT (it cannot be a strip window); more than
 *   (2^32 - 2) / 3 triangles: MTS_ERR_LIMIT. On error out is left empty.
 * - edges that are not manifold and consistently oriented (3+ faces, two
 *   faces in the same direction) count as borders: the result is still
 *   exact, only with more strips.
 * Every strip draws at most MTS_STRIPIFY_MAX_STRIP triangles (strips.h). */
mts_result mts_stripify(const uint32_t *triangles, uint32_t triangle_count,
                        uint32_t vertex_count, mts_strips *out, mts_stripify_stats *stats,
                        mts_error *err);

/* A lower bound on what any cover of these triangles pays over one index
 * a triangle: 3 S + W (S strips, W swaps; strips.h's cost is triangles +
 * 3 S + W - 1 indices with restarts). Counted from vertex valences alone:
 * a strip passing a vertex without a swap holds 3 of its triangles, so a
 * vertex whose valence is not a multiple of 3 needs a strip end or a swap
 * next to it, and each end or swap serves at most two such vertices
 * (stripify.c says why). Vertices on a border or a non-manifold,
 * inconsistently oriented edge are left out, which only lowers it. For a
 * benchmark: how far a stripification is from what the mesh allows. */
mts_result mts_stripify_cost_bound(const uint32_t *triangles, uint32_t triangle_count,
                                   uint32_t vertex_count, uint64_t *bound, mts_error *err);

#endif
