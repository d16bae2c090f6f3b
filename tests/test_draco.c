/* Draco shim: round trips on real meshes with both methods (the triangles
 * come back after renumbering, positions on the grid bit for bit as the
 * quantize helper puts them), meshes with duplicate positions, sizes, and bad
 * input (every truncation of a small encoding, random byte flips) which must
 * give an error or a mesh inside its bounds, never a crash. */
#include <math.h>
#include <stdint.h>

#include "draco.h"
#include "mesh.h"
#include "test.h"

/* ------------------------------------------------------------------------ */
/* Helpers                                                                  */

static mts_draco_mesh view(const mts_mesh *m)
{
    mts_draco_mesh d = {m->vertex_count, m->triangle_count, m->positions, m->normals, m->triangles, NULL, NULL};
    return d;
}

/* The rotation of (a, b, c) that starts at its smallest index. */
static void canon(const uint32_t *t, uint32_t *out)
{
    int k = 0;
    if (t[1] < t[k])
        k = 1;
    if (t[2] < t[k])
        k = 2;
    for (int i = 0; i < 3; i++)
        out[i] = t[(k + i) % 3];
}

static int cmp_tri(const void *a, const void *b)
{
    const uint32_t *x = a, *y = b;
    for (int i = 0; i < 3; i++)
        if (x[i] != y[i])
            return x[i] < y[i] ? -1 : 1;
    return 0;
}

/* 1 when the oriented triangles a (renumbered by map, if any) and b are equal
 * as multisets, up to rotation of each triangle. */
static int same_triangles(const uint32_t *a, const uint32_t *map, const uint32_t *b, uint32_t n)
{
    uint32_t *x = malloc(sizeof(uint32_t) * 3 * (n ? n : 1));
    uint32_t *y = malloc(sizeof(uint32_t) * 3 * (n ? n : 1));
    if (!x || !y)
        abort();
    for (uint32_t f = 0; f < n; f++) {
        uint32_t t[3];
        for (int k = 0; k < 3; k++)
            t[k] = map ? map[a[3 * f + k]] : a[3 * f + k];
        canon(t, x + 3 * f);
        canon(b + 3 * f, y + 3 * f);
    }
    qsort(x, n, sizeof(uint32_t) * 3, cmp_tri);
    qsort(y, n, sizeof(uint32_t) * 3, cmp_tri);
    int same = memcmp(x, y, sizeof(uint32_t) * 3 * n) == 0;
    free(x);
    free(y);
    return same;
}

/* What a caller must be able to rely on after a successful decode. */
static int within_bounds(const mts_draco_mesh_out *m)
{
    if (m->vertex_count == 0 || m->triangle_count == 0 || !m->positions || !m->quantized || !m->triangles)
        return 0;
    if (m->grid.bits < 1 || m->grid.bits > MTS_DRACO_MAX_BITS || !(m->grid.range > 0) ||
        !isfinite(m->grid.range))
        return 0;
    uint32_t maxq = (1u << m->grid.bits) - 1;
    for (size_t i = 0; i < 3 * (size_t)m->vertex_count; i++) {
        if (m->quantized[i] > maxq || !isfinite(m->positions[i]))
            return 0;
        if (m->normals && !isfinite(m->normals[i]))
            return 0;
    }
    for (size_t i = 0; i < 3 * (size_t)m->triangle_count; i++)
        if (m->triangles[i] >= m->vertex_count)
            return 0;
    return 1;
}

static uint64_t rng_state = 0x853c49e6748fea9bull;
static uint32_t rnd(void)
{
    rng_state = rng_state * 6364136223846793005ull + 1442695040888963407ull;
    return (uint32_t)(rng_state >> 33);
}

/* A w x h grid of vertices in the z = 0 plane, two triangles per cell, CCW
 * seen from +z. When seam is set, the vertices of column w/2 are duplicated
 * (same position, new id at the end) and the cells right of the column use the
 * copies, so the mesh is two sheets that touch along a line. */
typedef struct sheet {
    uint32_t vertex_count, triangle_count;
    float positions[3 * 200];
    uint32_t triangles[3 * 200];
} sheet;

static void make_sheet(sheet *s, uint32_t w, uint32_t h, int seam)
{
    uint32_t copy[64];
    s->vertex_count = 0;
    for (uint32_t y = 0; y < h; y++)
        for (uint32_t x = 0; x < w; x++) {
            float *p = s->positions + 3 * s->vertex_count++;
            p[0] = (float)x * 0.25f;
            p[1] = (float)y * 0.25f + 0.01f * (float)(x * x); /* not flat in y: no symmetry */
            p[2] = 0.05f * (float)((x * 7 + y * 3) % 5);
        }
    for (uint32_t y = 0; y < h; y++) {
        copy[y] = y * w + w / 2;
        if (seam) {
            memcpy(s->positions + 3 * s->vertex_count, s->positions + 3 * copy[y], sizeof(float) * 3);
            copy[y] = s->vertex_count++;
        }
    }
    s->triangle_count = 0;
    for (uint32_t y = 0; y + 1 < h; y++)
        for (uint32_t x = 0; x + 1 < w; x++) {
            uint32_t v00 = y * w + x, v10 = v00 + 1, v01 = v00 + w, v11 = v01 + 1;
            if (x == w / 2) { /* the right side uses the copies */
                v00 = copy[y];
                v01 = copy[y + 1];
            }
            uint32_t *t = s->triangles + 3 * s->triangle_count;
            t[0] = v00, t[1] = v10, t[2] = v11;
            t[3] = v00, t[4] = v11, t[5] = v01;
            s->triangle_count += 2;
        }
}

/* ------------------------------------------------------------------------ */
/* Quantization helper                                                      */

static void test_quantize_helper(mts_test *t)
{
    mts_draco_grid g = {14, {-1.f, 2.f, 0.5f}, 3.f};
    uint32_t maxq = (1u << 14) - 1;
    float p[3] = {-1.f, 2.f, 0.5f}, r[3];
    uint32_t q[3];
    CHECK(t, mts_draco_quantize(&g, p, q) == 1 && q[0] == 0 && q[1] == 0 && q[2] == 0);
    float top[3] = {2.f, 5.f, 3.5f};
    CHECK(t, mts_draco_quantize(&g, top, q) == 1 && q[0] == maxq && q[1] == maxq && q[2] == maxq);
    mts_draco_dequantize(&g, q, r);
    CHECK(t, fabsf(r[0] - 2.f) < 1e-6f && fabsf(r[1] - 5.f) < 1e-6f && fabsf(r[2] - 3.5f) < 1e-6f);
    float out[3] = {-1.1f, 2.f, 3.6f};
    CHECK(t, mts_draco_quantize(&g, out, q) == 0 && q[0] == 0 && q[2] == maxq);
    float nan3[3] = {NAN, 2.f, 2.f};
    CHECK(t, mts_draco_quantize(&g, nan3, q) == 0 && q[0] == 0);
    /* Draco's formula: floor((p - origin) * ((float)maxq / range) + 0.5f). */
    const float inv = (float)maxq / g.range;
    for (int i = 0; i < 1000; i++) {
        float v[3];
        for (int c = 0; c < 3; c++)
            v[c] = g.origin[c] + g.range * (float)rnd() / 4294967296.0f;
        CHECK(t, mts_draco_quantize(&g, v, q) == 1);
        for (int c = 0; c < 3; c++) {
            volatile float s = (v[c] - g.origin[c]) * inv;
            CHECK(t, q[c] == (uint32_t)floorf(s + 0.5f));
        }
        /* a grid point quantizes back to itself */
        uint32_t q2[3];
        mts_draco_dequantize(&g, q, r);
        CHECK(t, mts_draco_quantize(&g, r, q2) == 1 && !memcmp(q, q2, sizeof q));
    }
    mts_draco_grid bad = {0, {0, 0, 0}, 1.f};
    CHECK(t, mts_draco_quantize(&bad, p, q) == 0);

    float pts[6] = {1, 2, 3, 4, 0, 3.5f};
    mts_draco_grid gg;
    mts_error err;
    CHECK(t, mts_draco_grid_from_positions(pts, 2, 0, &gg, &err) == MTS_OK);
    CHECK(t, gg.bits == 14 && gg.origin[0] == 1 && gg.origin[1] == 0 && gg.origin[2] == 3 && gg.range == 3);
    CHECK(t, mts_draco_grid_from_positions(pts, 1, 10, &gg, &err) == MTS_OK && gg.range == 1.f);
    CHECK(t, mts_draco_grid_from_positions(pts, 0, 10, &gg, &err) == MTS_ERR_ARG);
    CHECK(t, mts_draco_grid_from_positions(pts, 2, 31, &gg, &err) == MTS_ERR_ARG);
}

/* ------------------------------------------------------------------------ */
/* Round trips                                                              */

/* Encodes m with opts, decodes, renumbers and checks everything the server
 * and the clients rely on. Returns the encoded size (0 on failure). */
static size_t round_trip(mts_test *t, const mts_draco_mesh *m, const mts_draco_options *opts,
                         int expect_identity)
{
    mts_error err = {0};
    uint8_t *data = NULL;
    size_t size = 0;
    mts_result r = mts_draco_encode(m, opts, &data, &size, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    if (r != MTS_OK)
        return 0;
    mts_draco_mesh_out d;
    r = mts_draco_decode(data, size, &d, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    free(data);
    if (r != MTS_OK)
        return 0;
    CHECK(t, within_bounds(&d));
    CHECK(t, d.vertex_count == m->vertex_count && d.triangle_count == m->triangle_count);
    CHECK(t, !m->normals || (opts && opts->normal_bits == -1) ? d.normals == NULL : d.normals != NULL);
    if (opts && opts->grid.range > 0)
        CHECK(t, !memcmp(&d.grid, &opts->grid, sizeof d.grid));

    uint32_t *vmap = malloc(sizeof(uint32_t) * m->vertex_count);
    uint32_t *fmap = malloc(sizeof(uint32_t) * m->triangle_count);
    if (!vmap || !fmap)
        abort();
    r = mts_draco_renumber(m, &d, vmap, fmap, &err);
    CHECKF(t, r == MTS_OK, "%u vertices, %s: %s", m->vertex_count,
           opts && opts->method == MTS_DRACO_SEQUENTIAL ? "sequential" : "edgebreaker", err.msg);
    if (r == MTS_OK && d.vertex_count == m->vertex_count && d.triangle_count == m->triangle_count) {
        /* a bijection */
        uint8_t *seen = calloc(m->vertex_count, 1);
        int bij = 1, identity = 1;
        for (uint32_t i = 0; i < m->vertex_count; i++) {
            if (vmap[i] >= m->vertex_count || seen[vmap[i]])
                bij = 0;
            else
                seen[vmap[i]] = 1;
            if (vmap[i] != i)
                identity = 0;
        }
        free(seen);
        CHECK(t, bij);
        if (expect_identity) {
            CHECK(t, identity);
            CHECK(t, !memcmp(m->triangles, d.triangles, sizeof(uint32_t) * 3 * m->triangle_count));
        }
        /* oriented triangles, as a multiset */
        CHECK(t, same_triangles(m->triangles, vmap, d.triangles, m->triangle_count));
        /* and the face map names a rotation of the same triangle */
        int fm_ok = 1;
        for (uint32_t f = 0; f < m->triangle_count && bij; f++) {
            uint32_t a[3], b[3], x[3];
            for (int k = 0; k < 3; k++)
                x[k] = vmap[m->triangles[3 * f + k]];
            canon(x, a);
            canon(d.triangles + 3 * (size_t)fmap[f], b);
            if (fmap[f] >= d.triangle_count || memcmp(a, b, sizeof a))
                fm_ok = 0;
        }
        CHECK(t, fm_ok);
        /* positions: on the grid as the helper puts them, bit for bit, and
         * within half a step of the original */
        const mts_draco_grid *g = &d.grid;
        const double step = (double)g->range / (double)((1u << g->bits) - 1);
        int bits_ok = 1, half_ok = 1, normals_ok = 1;
        double worst = 0;
        for (uint32_t i = 0; i < m->vertex_count && bij; i++) {
            const float *p = m->positions + 3 * (size_t)i;
            uint32_t q[3];
            float p2[3];
            mts_draco_quantize(g, p, q);
            mts_draco_dequantize(g, q, p2);
            const uint32_t j = vmap[i];
            if (memcmp(q, d.quantized + 3 * (size_t)j, sizeof q) || memcmp(p2, d.positions + 3 * (size_t)j, sizeof p2))
                bits_ok = 0;
            for (int c = 0; c < 3; c++) {
                double e = fabs(((double)p[c] - (double)g->origin[c]) / step - (double)d.quantized[3 * (size_t)j + c]);
                if (e > worst)
                    worst = e;
                if (e > 0.5 + 1e-3)
                    half_ok = 0;
            }
            if (d.normals && m->normals) {
                const float *n = m->normals + 3 * (size_t)i, *n2 = d.normals + 3 * (size_t)j;
                double len = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
                double dot = (double)n[0] * n2[0] + (double)n[1] * n2[1] + (double)n[2] * n2[2];
                if (len > 0.5 && dot < 0.999 * len)
                    normals_ok = 0;
            }
        }
        CHECK(t, bits_ok);
        CHECKF(t, half_ok, "worst %.4f steps", worst);
        CHECK(t, normals_ok);
    }
    free(vmap);
    free(fmap);
    mts_draco_mesh_out_free(&d);
    CHECK(t, d.positions == NULL && d.vertex_count == 0);
    return size;
}

static int load_cow(mts_test *t, mts_mesh *m)
{
    mts_error err;
    mts_result r = mts_mesh_load("tests/data/cow.off", NULL, m, NULL, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    return r == MTS_OK;
}

static void test_cow_edgebreaker(mts_test *t)
{
    mts_mesh m;
    if (!load_cow(t, &m))
        return;
    mts_draco_mesh v = view(&m);
    mts_draco_options o = {0};
    mts_error err;
    CHECK(t, mts_draco_grid_from_positions(m.positions, m.vertex_count, 14, &o.grid, &err) == MTS_OK);
    CHECK(t, round_trip(t, &v, &o, 0) > 0);
    /* the defaults (grid from this mesh, 14 bits) give the same grid */
    CHECK(t, round_trip(t, &v, NULL, 0) > 0);
    /* a grid larger than the mesh (the full model's box around a base mesh) */
    mts_draco_options big = o;
    big.grid.origin[0] -= 1.f;
    big.grid.range *= 2.f;
    big.normal_bits = -1;
    CHECK(t, round_trip(t, &v, &big, 0) > 0);
    mts_mesh_free(&m);
}

static void test_cow_sequential(mts_test *t)
{
    mts_mesh m;
    if (!load_cow(t, &m))
        return;
    mts_draco_mesh v = view(&m);
    mts_draco_options o = {0};
    o.method = MTS_DRACO_SEQUENTIAL;
    CHECK(t, round_trip(t, &v, &o, 1) > 0);
    o.compression_level = 1;
    o.grid.bits = 11;
    CHECK(t, round_trip(t, &v, &o, 1) > 0);
    mts_mesh_free(&m);
}

/* Duplicate positions: a seam of coincident vertices is told apart through
 * the faces; two coincident copies of a whole sheet cannot be, which is an
 * error for edgebreaker and the identity for sequential. */
static void test_duplicates(mts_test *t)
{
    static sheet s;
    make_sheet(&s, 7, 6, 1);
    mts_draco_mesh v = {s.vertex_count, s.triangle_count, s.positions, NULL, s.triangles, NULL, NULL};
    mts_draco_options o = {0};
    CHECK(t, round_trip(t, &v, &o, 0) > 0);
    o.method = MTS_DRACO_SEQUENTIAL;
    CHECK(t, round_trip(t, &v, &o, 1) > 0);

    /* two sheets on top of each other, the same orientation */
    static sheet twice;
    make_sheet(&twice, 5, 5, 0);
    uint32_t nv = twice.vertex_count, nt = twice.triangle_count;
    memcpy(twice.positions + 3 * nv, twice.positions, sizeof(float) * 3 * nv);
    for (uint32_t i = 0; i < 3 * nt; i++)
        twice.triangles[3 * nt + i] = twice.triangles[i] + nv;
    twice.vertex_count = 2 * nv;
    twice.triangle_count = 2 * nt;
    mts_draco_mesh w = {twice.vertex_count, twice.triangle_count, twice.positions, NULL, twice.triangles, NULL, NULL};
    mts_draco_options eb = {0};
    uint8_t *data = NULL;
    size_t size = 0;
    mts_error err;
    CHECKF(t, mts_draco_encode(&w, &eb, &data, &size, &err) == MTS_OK, "%s", err.msg);
    mts_draco_mesh_out d;
    CHECKF(t, mts_draco_decode(data, size, &d, &err) == MTS_OK, "%s", err.msg);
    free(data);
    uint32_t vmap[200];
    mts_result r = mts_draco_renumber(&w, &d, vmap, NULL, &err);
    /* edgebreaker renumbers; unless it happened to keep the order, the copies
     * cannot be told apart */
    if (r != MTS_OK)
        CHECKF(t, r == MTS_ERR_INVARIANT && strstr(err.msg, "cannot be told apart"), "%s", err.msg);
    else
        CHECK(t, same_triangles(w.triangles, vmap, d.triangles, w.triangle_count));
    mts_draco_mesh_out_free(&d);
    mts_draco_options seq = {0};
    seq.method = MTS_DRACO_SEQUENTIAL;
    CHECK(t, round_trip(t, &w, &seq, 1) > 0);
}

/* What edgebreaker changes beyond the order: it splits non-manifold vertices
 * and edges (and the vertices of faces with the other orientation), drops
 * degenerate faces and unreferenced vertices. Renumbering must then fail
 * cleanly, and the sequential method keep everything as it is. */
static void test_edgebreaker_limits(mts_test *t)
{
    static const float p[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, -1, 0, 0, 0, -1, 0, 5, 5, 5};
    static const struct {
        const char *what;
        uint32_t vertices, triangles;
        uint32_t tri[9];
    } cases[] = {
        {"bowtie", 5, 2, {0, 1, 2, 0, 3, 4}},
        {"unreferenced vertex", 6, 2, {0, 1, 2, 0, 3, 4}},
        {"degenerate face", 5, 3, {0, 1, 2, 0, 0, 3, 0, 2, 3}},
        {"edge in three faces", 5, 3, {0, 1, 2, 1, 0, 3, 0, 1, 4}},
        {"neighbour flipped", 4, 2, {0, 1, 2, 0, 1, 3}},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        mts_draco_mesh m = {cases[i].vertices, cases[i].triangles, p, NULL, cases[i].tri, NULL, NULL};
        mts_draco_options o = {0};
        uint8_t *data = NULL;
        size_t size = 0;
        mts_error err;
        CHECKF(t, mts_draco_encode(&m, &o, &data, &size, &err) == MTS_OK, "%s: %s", cases[i].what, err.msg);
        mts_draco_mesh_out d;
        mts_result r = mts_draco_decode(data, size, &d, &err);
        CHECKF(t, r == MTS_OK, "%s: %s", cases[i].what, err.msg);
        free(data);
        if (r != MTS_OK)
            continue;
        uint32_t vmap[8];
        r = mts_draco_renumber(&m, &d, vmap, NULL, &err);
        if (r == MTS_OK)
            CHECK(t, d.triangle_count == m.triangle_count &&
                         same_triangles(m.triangles, vmap, d.triangles, m.triangle_count));
        else
            CHECKF(t, r == MTS_ERR_INVARIANT, "%s: %s", cases[i].what, err.msg);
        if (getenv("MTS_TEST_VERBOSE"))
            fprintf(stderr, "  %s: edgebreaker gives %u vertices, %u triangles: %s\n", cases[i].what,
                    d.vertex_count, d.triangle_count, r == MTS_OK ? "renumbered" : err.msg);
        mts_draco_mesh_out_free(&d);
        o.method = MTS_DRACO_SEQUENTIAL;
        CHECK(t, round_trip(t, &m, &o, 1) > 0);
    }
}

/* ------------------------------------------------------------------------ */
/* Arguments                                                                */

static void test_bad_arguments(mts_test *t)
{
    static sheet s;
    make_sheet(&s, 4, 4, 0);
    mts_draco_mesh v = {s.vertex_count, s.triangle_count, s.positions, NULL, s.triangles, NULL, NULL};
    uint8_t *data = NULL;
    size_t size = 0;
    mts_error err;
    mts_draco_options o = {0};
    CHECK(t, mts_draco_encode(NULL, &o, &data, &size, &err) == MTS_ERR_ARG);
    CHECK(t, mts_draco_encode(&v, &o, NULL, &size, &err) == MTS_ERR_ARG);
    o.grid.bits = 31;
    CHECK(t, mts_draco_encode(&v, &o, &data, &size, &err) == MTS_ERR_ARG);
    o.grid.bits = 0;
    o.normal_bits = 40;
    mts_draco_mesh vn = v;
    vn.normals = s.positions;
    CHECK(t, mts_draco_encode(&vn, &o, &data, &size, &err) == MTS_ERR_ARG);
    o.normal_bits = 0;
    o.compression_level = 11;
    CHECK(t, mts_draco_encode(&v, &o, &data, &size, &err) == MTS_ERR_ARG);
    o.compression_level = 0;
    o.method = 7;
    CHECK(t, mts_draco_encode(&v, &o, &data, &size, &err) == MTS_ERR_ARG);
    o.method = MTS_DRACO_EDGEBREAKER;
    /* a grid that does not hold the mesh */
    o.grid = (mts_draco_grid){14, {0.1f, 0.f, 0.f}, 0.5f};
    CHECK(t, mts_draco_encode(&v, &o, &data, &size, &err) == MTS_ERR_RANGE);
    CHECK(t, strstr(err.msg, "outside the grid") != NULL);
    /* an index out of range */
    o.grid.range = 0;
    s.triangles[5] = s.vertex_count;
    CHECK(t, mts_draco_encode(&v, &o, &data, &size, &err) == MTS_ERR_ARG);
    s.triangles[5] = 0;
    v.triangle_count = 0;
    CHECK(t, mts_draco_encode(&v, &o, &data, &size, &err) == MTS_ERR_ARG);
    CHECK(t, data == NULL && size == 0);

    mts_draco_mesh_out d;
    CHECK(t, mts_draco_decode(NULL, 0, &d, &err) == MTS_ERR_FORMAT);
    CHECK(t, mts_draco_decode((const uint8_t *)"DRACO", 5, &d, &err) == MTS_ERR_FORMAT);
    CHECK(t, mts_draco_decode((const uint8_t *)"x", 1, NULL, &err) == MTS_ERR_ARG);
    mts_draco_mesh_out_free(NULL);
}

/* ------------------------------------------------------------------------ */
/* Bad input                                                                */

/* Decodes data; a success must be within bounds. Returns 1 on success. An
 * out-of-memory answer counts as bad too: a few bytes must not make Draco
 * allocate without bound. */
static int decode_checked(mts_test *t, const uint8_t *data, size_t size, size_t *bad)
{
    mts_draco_mesh_out d;
    mts_error err = {0};
    mts_result r = mts_draco_decode(data, size, &d, &err);
    if (r != MTS_OK) {
        if (!err.msg[0] || d.positions || d.vertex_count || r == MTS_ERR_NOMEM) {
            if (getenv("MTS_TEST_VERBOSE"))
                fprintf(stderr, "  bad answer (%s): %s\n", mts_result_name(r), err.msg);
            ++*bad;
        }
        return 0;
    }
    if (!within_bounds(&d))
        ++*bad;
    mts_draco_mesh_out_free(&d);
    (void)t;
    return 1;
}

static void fuzz_buffer(mts_test *t, const char *what, const uint8_t *data, size_t size, int flips)
{
    size_t bad = 0, ok_prefix = 0, ok_flip = 0;
    uint8_t *copy = malloc(size);
    if (!copy)
        abort();
    for (size_t n = 0; n < size; n++) {
        memcpy(copy, data, n); /* exact-size copy: ASan sees any overread */
        ok_prefix += decode_checked(t, copy, n, &bad);
    }
    /* every byte set to values that make large or odd counts */
    static const int values[] = {0x00, 0xff, 0x7f, 0x80, 0x01, -1, -2};
    size_t ok_set = 0;
    for (size_t at = 0; at < size; at++)
        for (size_t k = 0; k < sizeof values / sizeof values[0]; k++) {
            memcpy(copy, data, size);
            copy[at] = values[k] >= 0 ? (uint8_t)values[k] : (uint8_t)(copy[at] ^ (uint8_t)-values[k]);
            ok_set += decode_checked(t, copy, size, &bad);
        }
    /* a 5-byte varint of 2^32 - 1 in place of the bytes at each header offset */
    for (size_t at = 0; at + 5 <= size && at < 64; at++) {
        memcpy(copy, data, size);
        memcpy(copy + at, "\xff\xff\xff\xff\x0f", 5);
        ok_set += decode_checked(t, copy, size, &bad);
    }
    for (int i = 0; i < flips; i++) {
        memcpy(copy, data, size);
        int k = 1 + (int)(rnd() % 3);
        for (int j = 0; j < k; j++) {
            size_t at = rnd() % size;
            if (rnd() & 1)
                copy[at] ^= (uint8_t)(1u << (rnd() % 8));
            else
                copy[at] = (uint8_t)rnd();
        }
        ok_flip += decode_checked(t, copy, size, &bad);
    }
    free(copy);
    CHECKF(t, bad == 0, "%s: %zu decodes broke their bounds or error contract", what, bad);
    printf("  %s: %zu bytes; %zu of %zu truncations, %zu of %zu set bytes and %zu of %d random corruptions "
           "still decode (within bounds)\n",
           what, size, ok_prefix, size, ok_set, size * 7 + (size < 68 ? size - 4 : 64), ok_flip, flips);
}

static void test_bad_input(mts_test *t)
{
    static sheet s;
    make_sheet(&s, 6, 5, 1);
    float normals[3 * 200];
    for (uint32_t i = 0; i < s.vertex_count; i++) {
        normals[3 * i] = 0.1f * (float)(i % 3);
        normals[3 * i + 1] = 0.2f;
        normals[3 * i + 2] = 1.f;
    }
    mts_draco_mesh v = {s.vertex_count, s.triangle_count, s.positions, normals, s.triangles, NULL, NULL};
    for (int method = 0; method < 2; method++) {
        mts_draco_options o = {0};
        o.method = method;
        uint8_t *data = NULL;
        size_t size = 0;
        mts_error err;
        CHECKF(t, mts_draco_encode(&v, &o, &data, &size, &err) == MTS_OK, "%s", err.msg);
        if (!data)
            continue;
        fuzz_buffer(t, method ? "sheet, sequential" : "sheet, edgebreaker", data, size, 3000);
        free(data);
    }
    mts_mesh m;
    if (!load_cow(t, &m))
        return;
    mts_draco_mesh cv = view(&m);
    for (int method = 0; method < 2; method++) {
        mts_draco_options o = {0};
        o.method = method;
        uint8_t *data = NULL;
        size_t size = 0;
        mts_error err;
        CHECKF(t, mts_draco_encode(&cv, &o, &data, &size, &err) == MTS_OK, "%s", err.msg);
        if (!data)
            continue;
        size_t bad = 0;
        uint8_t *copy = malloc(size);
        if (!copy)
            abort();
        for (int i = 0; i < 300; i++) {
            memcpy(copy, data, size);
            copy[rnd() % size] ^= (uint8_t)(1u << (rnd() % 8));
            decode_checked(t, copy, size, &bad);
            size_t n = rnd() % size;
            decode_checked(t, data, n, &bad);
        }
        /* random garbage, with and without a Draco header */
        for (int i = 0; i < 300; i++) {
            size_t n = 1 + rnd() % 2000;
            uint8_t *g = malloc(n);
            if (!g)
                abort();
            for (size_t j = 0; j < n; j++)
                g[j] = (uint8_t)rnd();
            if (i & 1)
                memcpy(g, data, n < 16 ? n : 16);
            decode_checked(t, g, n, &bad);
            free(g);
        }
        free(copy);
        free(data);
        CHECKF(t, bad == 0, "cow: %zu decodes broke their bounds or error contract", bad);
    }
    mts_mesh_free(&m);
}

/* ------------------------------------------------------------------------ */
/* Sizes                                                                    */

static void sizes_of(mts_test *t, const char *name, const mts_mesh *m)
{
    mts_draco_mesh v = view(m);
    static const struct {
        const char *what;
        mts_draco_method method;
        int level;
    } runs[] = {{"edgebreaker cl 7", MTS_DRACO_EDGEBREAKER, 7},
                {"edgebreaker cl 10", MTS_DRACO_EDGEBREAKER, 10},
                {"sequential cl 10", MTS_DRACO_SEQUENTIAL, 10}};
    size_t sz[2][3];
    for (int nrm = 0; nrm < 2; nrm++)
        for (int i = 0; i < 3; i++) {
            mts_draco_options o = {0};
            o.method = runs[i].method;
            o.compression_level = runs[i].level;
            o.normal_bits = nrm ? 0 : -1;
            sz[nrm][i] = round_trip(t, &v, &o, runs[i].method == MTS_DRACO_SEQUENTIAL);
            printf("  %s (%u vertices, %u triangles), 14 bits, %s, %s: %zu bytes (%.2f bytes/triangle)\n", name,
                   m->vertex_count, m->triangle_count, runs[i].what, nrm ? "10-bit normals" : "no normals",
                   sz[nrm][i], (double)sz[nrm][i] / m->triangle_count);
        }
    for (int nrm = 0; nrm < 2; nrm++) {
        CHECK(t, sz[nrm][1] <= sz[nrm][0]);
        CHECK(t, sz[nrm][0] < sz[nrm][2]);
    }
}

static void test_sizes(mts_test *t)
{
    mts_mesh m;
    if (!load_cow(t, &m))
        return;
    sizes_of(t, "cow", &m);
    mts_mesh_free(&m);

    char path[4096];
    if (!mts_test_model("bunny00.off", path, sizeof path))
        SKIP(t, "no bunny00.off under %s", getenv("MTS_MODELS") ? getenv("MTS_MODELS") : "../shared/models");
    mts_error err;
    mts_result r = mts_mesh_load(path, NULL, &m, NULL, &err);
    CHECKF(t, r == MTS_OK, "%s", err.msg);
    if (r != MTS_OK)
        return;
    /* Debian's `draco_encoder -i bunny00.obj -qp 14 -cl 7` (positions only)
     * makes 115,183 bytes, -cl 10 110,650 */
    sizes_of(t, "bunny00", &m);
    mts_mesh_free(&m);
}

int main(void)
{
    mts_test t = {0};
    RUN(&t, test_quantize_helper);
    RUN(&t, test_cow_edgebreaker);
    RUN(&t, test_cow_sequential);
    RUN(&t, test_duplicates);
    RUN(&t, test_edgebreaker_limits);
    RUN(&t, test_bad_arguments);
    RUN(&t, test_bad_input);
    RUN(&t, test_sizes);
    return mts_test_end(&t);
}
