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
 * (free with mts_strips_free). stats may be NULL. */
mts_result mts_stripify(const uint32_t *triangles, uint32_t triangle_count,
                        uint32_t vertex_count, mts_strips *out, mts_stripify_stats *stats,
                        mts_error *err);

#endif
