/* Colour fields for tests and benches of coloured meshes, without a
 * coloured file: each vertex's colour a function of its position in the
 * box, scaled by the box's longest side.
 *   smooth   three sines of different directions and periods (one to two
 *            periods across the model), the kind of field a scan's or a
 *            painted mesh's colours are locally: no edge of the mesh sees
 *            more than a few steps of 255;
 *   patches  a 4x4x4 grid of cells over the box, each a flat colour of six
 *            saturated ones: sharp colour boundaries along planes that cut
 *            the mesh (a painted part's or a segmentation's boundaries), where
 *            a collapse across one moves the boundary. */
#ifndef MTS_TEST_COLOR_FIELD_H
#define MTS_TEST_COLOR_FIELD_H

#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#include "mesh.h"
#include "model.h"

enum { MTS_TEST_FIELD_SMOOTH, MTS_TEST_FIELD_PATCHES };

/* The colour at p in a box from lo with longest side side. */
static inline void mts_test_color_at(const float *p, const float *lo, float side, int kind,
                                     uint8_t *o)
{
    const float u = (p[0] - lo[0]) / side, v = (p[1] - lo[1]) / side, w = (p[2] - lo[2]) / side;
    if (kind == MTS_TEST_FIELD_PATCHES) {
        static const uint8_t palette[6][3] = {{220, 40, 40},  {40, 180, 60},  {50, 80, 220},
                                              {240, 200, 40}, {200, 60, 200}, {40, 200, 210}};
        int a = (int)floorf(4 * u), b = (int)floorf(4 * v), c = (int)floorf(4 * w);
        int k = ((a + 2 * b + 5 * c) % 6 + 6) % 6;
        o[0] = palette[k][0];
        o[1] = palette[k][1];
        o[2] = palette[k][2];
        return;
    }
    o[0] = (uint8_t)lrintf(127.5f + 127.5f * sinf(6.2831853f * (1.5f * u + 0.3f * w)));
    o[1] = (uint8_t)lrintf(127.5f + 127.5f * sinf(6.2831853f * (1.1f * v + 0.7f * u) + 1.f));
    o[2] = (uint8_t)lrintf(127.5f + 127.5f * cosf(6.2831853f * (0.8f * w + 0.5f * v)));
}

/* Colours for n points from lo with box extent ext; NULL when out of memory. */
static inline uint8_t *mts_test_color_points(const float *pos, uint32_t n, const float *lo,
                                             const float *hi, int kind)
{
    uint8_t *c = malloc((size_t)n * 3 + 1);
    if (!c)
        return NULL;
    float side = 0;
    for (int a = 0; a < 3; a++)
        if (hi[a] - lo[a] > side)
            side = hi[a] - lo[a];
    if (!(side > 0))
        side = 1;
    for (uint32_t x = 0; x < n; x++)
        mts_test_color_at(pos + 3 * (size_t)x, lo, side, kind, c + 3 * (size_t)x);
    return c;
}

/* Gives m the smooth field (replacing any colours) and MTS_MODEL_COLORS; 0
 * when out of memory. */
static inline int mts_test_color_field(mts_model *m)
{
    uint8_t *c = mts_test_color_points(m->positions, m->vertex_count, m->bbox_min, m->bbox_max,
                                       MTS_TEST_FIELD_SMOOTH);
    if (!c)
        return 0;
    free(m->colors);
    m->colors = c;
    m->flags |= MTS_MODEL_COLORS;
    return 1;
}

/* Gives a mesh a field before it is built (replacing any colours), so that
 * the builder sees them; 0 when out of memory. */
static inline int mts_test_mesh_color_field(mts_mesh *mesh, int kind)
{
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t v = 0; v < mesh->vertex_count; v++)
        for (int a = 0; a < 3; a++) {
            lo[a] = fminf(lo[a], mesh->positions[3 * (size_t)v + a]);
            hi[a] = fmaxf(hi[a], mesh->positions[3 * (size_t)v + a]);
        }
    uint8_t *c = mts_test_color_points(mesh->positions, mesh->vertex_count, lo, hi, kind);
    if (!c)
        return 0;
    free(mesh->colors);
    mesh->colors = c;
    return 1;
}

#endif
