/* Simplifier: Garland-Heckbert quadric half-edge collapses (Garland and
 * Heckbert, "Surface Simplification Using Quadric Error Metrics", SIGGRAPH
 * 1997) through OpenMesh's DecimaterT with ModQuadricT as the priority and
 * ModNormalFlippingT as a guard against folding faces over. Every collapse is
 * recorded in order as (removed vertex, kept vertex): the kept vertex keeps
 * its position, so a collapse is exactly "replace removed by kept everywhere
 * and drop the faces that now repeat a vertex" -- the property the strip
 * records rely on. */
#ifndef MTS_SIMPLIFY_H
#define MTS_SIMPLIFY_H

#include <stdint.h>

#include "error.h"
#include "progress.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct mts_collapse {
    uint32_t removed;       /* vertex merged away (OpenMesh's v0) */
    uint32_t kept;          /* vertex it merges into (v1) */
    uint32_t faces_removed; /* 2 inside the mesh, 1 on a boundary */
} mts_collapse;

/* Zero-initialised means the defaults. */
typedef struct mts_simplify_options {
    /* Stop once this many vertices remain (or no legal collapse is left).
     * 0: max(4, 1% of the vertices). */
    uint32_t base_vertices;
    /* Largest angle a face normal may turn in one collapse; 0: 90 degrees. */
    double max_normal_deviation_deg;
    /* 3 bytes of 8-bit sRGB a vertex, or NULL. With colors and
     * color_weight > 0 a collapse also costs the colour error it leaves
     * (simplify.cpp's ModQuadricColorT): a kept vertex stands for the
     * vertices merged into it, and the squared distance of their colours
     * (each channel over 255) from its own, weighted by their areas, adds
     * color_weight times the squared bounding-box diagonal times that to
     * the quadric's area-weighted squared distance -- a whole-range colour
     * mismatch costs as much as a displacement of sqrt(color_weight) of the
     * diagonal. Without colours or with color_weight <= 0 the collapses are
     * the quadric's alone. */
    const uint8_t *colors;
    double color_weight;
    mts_progress progress;
} mts_simplify_options;

typedef struct mts_simplify_result {
    uint32_t collapse_count;
    mts_collapse *collapses; /* in the order they were applied */
    uint32_t base_vertices;  /* vertices left */
    uint32_t base_triangles; /* faces left */
} mts_simplify_result;

/* positions: 3 floats per vertex; triangles: 3 indices per face, a manifold
 * consistently oriented mesh (see manifold.h): a face OpenMesh refuses here
 * is an error, since the caller was meant to filter it. */
mts_result mts_simplify(const float *positions, uint32_t vertex_count, const uint32_t *triangles,
                        uint32_t triangle_count, const mts_simplify_options *opts,
                        mts_simplify_result *result, mts_error *err);

void mts_simplify_result_free(mts_simplify_result *result);

#ifdef __cplusplus
}
#endif

#endif
