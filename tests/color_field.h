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
 *            a collapse across one moves the boundary;
 *   curvature (a mesh's, mts_test_mesh_color_field only) the mean curvature
 *            baked into a ramp, blue where concave, light grey where flat,
 *            red where convex, smoothed over the mesh: a field that follows
 *            the shape, as a baked curvature or ambient-occlusion map does,
 *            with its detail where the geometry's is. */
#ifndef MTS_TEST_COLOR_FIELD_H
#define MTS_TEST_COLOR_FIELD_H

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "mesh.h"
#include "model.h"

enum { MTS_TEST_FIELD_SMOOTH, MTS_TEST_FIELD_PATCHES, MTS_TEST_FIELD_CURVATURE };

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

static inline int mts_test_cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

/* The curvature field's colours: per vertex the umbrella Laplacian (the
 * mean of the neighbours of each incident triangle, minus the vertex) along
 * the normal over the mean incident edge length -- about half the edge
 * length times the mean curvature, signed -- averaged 24 times with the
 * neighbours, then mapped through the ramp with the 90th percentile of its
 * size at the ends. NULL when out of memory. */
static inline uint8_t *mts_test_curvature_colors(const mts_mesh *mesh)
{
    const uint32_t n = mesh->vertex_count;
    float *k = calloc((size_t)n + 1, sizeof(float)), *acc = calloc((size_t)n * 4 + 4, sizeof(float)),
          *sz = malloc(((size_t)n + 1) * sizeof(float));
    uint8_t *c = malloc((size_t)n * 3 + 1);
    if (!k || !acc || !sz || !c) {
        free(k), free(acc), free(sz), free(c);
        return NULL;
    }
    const float *p = mesh->positions;
    for (uint32_t t = 0; t < mesh->triangle_count; t++) /* neighbour sums, edge lengths */
        for (int j = 0; j < 3; j++) {
            uint32_t v = mesh->triangles[3 * (size_t)t + j];
            for (int o = 1; o < 3; o++) {
                uint32_t w = mesh->triangles[3 * (size_t)t + (j + o) % 3];
                float e2 = 0;
                for (int a = 0; a < 3; a++) {
                    acc[4 * (size_t)v + a] += p[3 * (size_t)w + a] - p[3 * (size_t)v + a];
                    e2 += (p[3 * (size_t)w + a] - p[3 * (size_t)v + a]) *
                          (p[3 * (size_t)w + a] - p[3 * (size_t)v + a]);
                }
                acc[4 * (size_t)v + 3] += sqrtf(e2);
            }
        }
    for (uint32_t v = 0; v < n; v++) {
        const float *a = acc + 4 * (size_t)v, *nv = mesh->normals + 3 * (size_t)v;
        /* the sums count each neighbour twice over a closed fan: the means
         * divide both by the same count, which cancels */
        k[v] = a[3] > 0 ? (a[0] * nv[0] + a[1] * nv[1] + a[2] * nv[2]) / a[3] : 0;
    }
    for (int it = 0; it < 24; it++) {
        memset(acc, 0, (size_t)n * 2 * sizeof(float));
        for (uint32_t t = 0; t < mesh->triangle_count; t++)
            for (int j = 0; j < 3; j++) {
                uint32_t v = mesh->triangles[3 * (size_t)t + j];
                acc[2 * (size_t)v] += k[mesh->triangles[3 * (size_t)t + (j + 1) % 3]] +
                                      k[mesh->triangles[3 * (size_t)t + (j + 2) % 3]];
                acc[2 * (size_t)v + 1] += 2;
            }
        for (uint32_t v = 0; v < n; v++)
            k[v] = 0.5f * k[v] + 0.5f * (acc[2 * (size_t)v + 1] > 0
                                             ? acc[2 * (size_t)v] / acc[2 * (size_t)v + 1]
                                             : k[v]);
    }
    for (uint32_t v = 0; v < n; v++)
        sz[v] = fabsf(k[v]);
    qsort(sz, n, sizeof(float), mts_test_cmp_float);
    float scale = n ? sz[(size_t)n * 9 / 10] : 0;
    if (!(scale > 0))
        scale = 1;
    static const float ramp[3][3] = {{40, 70, 200}, {225, 225, 220}, {205, 45, 35}};
    for (uint32_t v = 0; v < n; v++) {
        /* the Laplacian points inwards where convex: minus along the normal */
        float s = -k[v] / scale;
        s = s < -1 ? -1 : s > 1 ? 1 : s;
        const float *from = ramp[1], *to = s < 0 ? ramp[0] : ramp[2];
        float u = fabsf(s);
        for (int a = 0; a < 3; a++)
            c[3 * (size_t)v + a] = (uint8_t)lrintf(from[a] + u * (to[a] - from[a]));
    }
    free(k), free(acc), free(sz);
    return c;
}

/* Gives a mesh a field before it is built (replacing any colours), so that
 * the builder sees them; 0 when out of memory. */
static inline int mts_test_mesh_color_field(mts_mesh *mesh, int kind)
{
    if (kind == MTS_TEST_FIELD_CURVATURE) {
        uint8_t *c = mts_test_curvature_colors(mesh);
        if (!c)
            return 0;
        free(mesh->colors);
        mesh->colors = c;
        return 1;
    }
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
