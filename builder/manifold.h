/* Which faces of a triangle soup OpenMesh accepts into a manifold
 * half-edge mesh, added in order: a face is refused when adding it would make
 * an edge with more than two faces, a vertex whose fan is not a disc, or an
 * edge used twice in the same direction (inconsistent orientation). The
 * simplifier runs on exactly the accepted faces, so the strips do too. */
#ifndef MTS_MANIFOLD_H
#define MTS_MANIFOLD_H

#include <stdint.h>

#include "error.h"

#ifdef __cplusplus
extern "C" {
#endif

/* accepted[i] is set to 1 when triangle i was accepted, 0 when refused;
 * *refused_count (may be NULL) gets the number refused. */
mts_result mts_manifold_filter(uint32_t vertex_count, const uint32_t *triangles,
                               uint32_t triangle_count, uint8_t *accepted,
                               uint32_t *refused_count, mts_error *err);

#ifdef __cplusplus
}
#endif

#endif
