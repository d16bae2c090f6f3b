/* LOD policies (client/lodpolicy.c): monotone in distance and window size,
 * never above what is available, the budget controller converging under a
 * synthetic frame-time model without oscillating, names; and on cow, that
 * level_triangles rises with the level (what mts_model_level_for_triangles'
 * binary search and every policy rely on). */
#include <math.h>
#include <stdint.h>

#include "build.h"
#include "lodpolicy.h"
#include "mesh.h"
#include "model.h"
#include "test.h"

#define N_LEVELS 5000u

/* A model with only what the policies read: levels, triangles per level
 * (200 + 2 per split, as a closed mesh's splits give) and a unit box. */
static uint32_t tri_table[N_LEVELS + 1];

static mts_model fake_model(void)
{
    mts_model m;
    memset(&m, 0, sizeof m);
    m.level_count = N_LEVELS;
    m.base_vertex_count = 100;
    m.vertex_count = 100 + N_LEVELS;
    for (uint32_t l = 0; l <= N_LEVELS; l++)
        tri_table[l] = 200 + 2 * l;
    m.level_triangles = tri_table;
    for (int i = 0; i < 3; i++) {
        m.bbox_min[i] = -1;
        m.bbox_max[i] = 1;
    }
    return m;
}

static void test_parse(mts_test *t)
{
    mts_lod_policy_kind k = MTS_LOD_POLICY_BUDGET;
    CHECK(t, mts_lod_policy_parse("received", &k) && k == MTS_LOD_POLICY_RECEIVED);
    CHECK(t, mts_lod_policy_parse("distance", &k) && k == MTS_LOD_POLICY_DISTANCE);
    CHECK(t, mts_lod_policy_parse("area", &k) && k == MTS_LOD_POLICY_AREA);
    CHECK(t, mts_lod_policy_parse("budget", &k) && k == MTS_LOD_POLICY_BUDGET);
    CHECK(t, !mts_lod_policy_parse("Budget", &k));
    CHECK(t, !mts_lod_policy_parse("", &k));
    CHECK(t, !mts_lod_policy_parse(NULL, &k));
    for (int i = 0; i < 4; i++) {
        mts_lod_policy_kind back;
        CHECK(t, mts_lod_policy_parse(mts_lod_policy_name((mts_lod_policy_kind)i), &back) &&
                     back == (mts_lod_policy_kind)i);
    }
}

static void test_received(mts_test *t)
{
    mts_model m = fake_model();
    mts_lod_policy p;
    mts_lod_policy_init(&p, NULL, &m);
    CHECK(t, mts_lod_policy_choose(&p, 123, NULL, 0) == 123);
    CHECK(t, mts_lod_policy_choose(&p, N_LEVELS + 50, NULL, 5) == N_LEVELS);
}

static void test_distance_monotone(mts_test *t)
{
    mts_model m = fake_model();
    mts_lod_policy_options o = {0};
    o.kind = MTS_LOD_POLICY_DISTANCE;
    mts_lod_policy p;
    mts_lod_policy_init(&p, &o, &m);
    mts_lod_view v = {0, 35.0f * 3.14159265f / 180.0f, 512, 512};
    v.distance = 1;
    double d0 = mts_lod_policy_frame_distance(&p, &v);
    CHECK(t, d0 > sqrt(3.0)); /* the framing distance is outside the sphere */
    /* framed: everything; twice as far: a quarter of the triangles */
    v.distance = (float)d0;
    CHECK(t, mts_lod_policy_choose(&p, N_LEVELS, &v, 0) == N_LEVELS);
    v.distance = (float)(2 * d0);
    double q = mts_lod_policy_view_triangles(&p, &v);
    CHECKF(t, fabs(q - 0.25 * tri_table[N_LEVELS]) < 1, "%f", q);
    uint32_t l = mts_lod_policy_choose(&p, N_LEVELS, &v, 0);
    CHECK(t, tri_table[l] <= q && (l == N_LEVELS || tri_table[l + 1] > q));
    /* farther never more; never above available */
    uint32_t prev = UINT32_MAX;
    for (double d = 0.1; d < 100 * d0; d *= 1.05) {
        v.distance = (float)d;
        uint32_t lv = mts_lod_policy_choose(&p, N_LEVELS, &v, 0);
        CHECKF(t, lv <= prev, "distance %f: level %u after %u", d, lv, prev);
        prev = lv;
        uint32_t la = mts_lod_policy_choose(&p, 777, &v, 0);
        CHECK(t, la <= 777 && la == (lv < 777 ? lv : 777));
    }
    CHECK(t, prev == 0);
    /* the window's size does not matter to this policy, its shape does */
    v.distance = (float)(3 * d0);
    uint32_t a = mts_lod_policy_choose(&p, N_LEVELS, &v, 0);
    v.width = v.height = 2048;
    CHECK(t, mts_lod_policy_choose(&p, N_LEVELS, &v, 0) == a);
    /* no camera: what is available */
    CHECK(t, mts_lod_policy_choose(&p, 42, NULL, 0) == 42);
}

static void test_area_monotone(mts_test *t)
{
    mts_model m = fake_model();
    mts_lod_policy_options o = {0};
    o.kind = MTS_LOD_POLICY_AREA;
    o.pixels_per_triangle = 8;
    mts_lod_policy p;
    mts_lod_policy_init(&p, &o, &m);
    const int sizes[][2] = {{64, 64}, {128, 64}, {128, 128}, {256, 128}, {256, 256},
                            {512, 256}, {512, 512}, {1024, 512}, {1024, 1024}};
    for (double d = 1.8; d < 400; d *= 1.3) {
        double prev_t = -1;
        for (size_t i = 0; i < sizeof sizes / sizeof sizes[0]; i++) {
            mts_lod_view v = {(float)d, 0.6f, sizes[i][0], sizes[i][1]};
            double tt = mts_lod_policy_view_triangles(&p, &v);
            CHECKF(t, tt >= prev_t, "distance %f, %dx%d: %f after %f", d, sizes[i][0],
                   sizes[i][1], tt, prev_t);
            CHECK(t, tt <= (double)sizes[i][0] * sizes[i][1] / 8 + 1e-6);
            prev_t = tt;
            uint32_t l = mts_lod_policy_choose(&p, 3000, &v, 0);
            CHECK(t, l <= 3000);
        }
    }
    uint32_t prev = UINT32_MAX;
    for (double d = 1.0; d < 1000; d *= 1.1) {
        mts_lod_view v = {(float)d, 0.6f, 800, 600};
        uint32_t l = mts_lod_policy_choose(&p, N_LEVELS, &v, 0);
        CHECKF(t, l <= prev, "distance %f: level %u after %u", d, l, prev);
        prev = l;
    }
    /* the disc's area: at distance 30 in a 1000-pixel-high window, fov 0.6 */
    mts_lod_view v = {30, 0.6f, 1000, 1000};
    double r = sqrt(3.0), rho = 500 * tan(asin(r / 30)) / tan(0.3);
    double want = 3.14159265358979 * rho * rho / 8;
    CHECKF(t, fabs(mts_lod_policy_view_triangles(&p, &v) - want) < 1e-3 * want, "%f vs %f",
           mts_lod_policy_view_triangles(&p, &v), want);
}

/* Frame time a + b * T (+ deterministic jitter of +-jit, relative). */
typedef struct synth {
    double a, b, jit;
    uint32_t seed;
} synth;

static double synth_ms(synth *s, uint32_t triangles)
{
    s->seed = s->seed * 1664525u + 1013904223u;
    double u = (double)(s->seed >> 8) / (double)(1u << 24) * 2 - 1;
    return (s->a + s->b * triangles) * (1 + s->jit * u);
}

static void run_budget(mts_test *t, double fps, synth s, uint32_t available, int expect_zero)
{
    mts_model m = fake_model();
    mts_lod_policy_options o = {0};
    o.kind = MTS_LOD_POLICY_BUDGET;
    o.fps = fps;
    mts_lod_policy p;
    mts_lod_policy_init(&p, &o, &m);
    double budget = 1000 / fps;
    uint32_t lo = UINT32_MAX, hi = 0;
    double last = 0;
    uint32_t l = 0;
    for (int f = 0; f < 300; f++) {
        l = mts_lod_policy_choose(&p, available, NULL, last);
        CHECK(t, l <= available);
        last = synth_ms(&s, tri_table[l]);
        if (f >= 60) { /* settled */
            lo = l < lo ? l : lo;
            hi = l > hi ? l : hi;
        }
    }
    if (expect_zero) {
        CHECKF(t, hi == 0, "levels %u..%u, expected 0 (budget cannot be met)", lo, hi);
        return;
    }
    double worst = s.a + s.b * tri_table[hi];
    CHECKF(t, worst <= budget, "fps %g: level %u predicts %f ms > %f", fps, hi, worst, budget);
    /* within a small band: the hysteresis (10%) plus the jitter */
    double band = (double)tri_table[hi] / tri_table[lo];
    CHECKF(t, band <= 1.1 + 2 * s.jit + 1e-9, "fps %g: levels %u..%u oscillate (x%.3f)", fps,
           lo, hi, band);
    /* and not far under the budget either, unless everything fits */
    if (hi < available)
        CHECKF(t, worst >= 0.7 * budget, "fps %g: level %u predicts only %f of %f ms", fps, hi,
               worst, budget);
    else
        CHECK(t, worst <= budget);
}

static void test_budget_converges(mts_test *t)
{
    synth s = {2.0, 0.001, 0, 1}; /* 2 ms + 1 ms per 1000 triangles */
    run_budget(t, 60, s, N_LEVELS, 0);   /* 16.7 ms: about 13,000 triangles */
    run_budget(t, 120, s, N_LEVELS, 0);  /* 8.3 ms */
    run_budget(t, 30, s, N_LEVELS, 0);   /* everything fits: 10.2k triangles, 12.2 ms */
    run_budget(t, 60, s, 1000, 0);       /* limited by what arrived */
    s.jit = 0.05;
    run_budget(t, 100, s, N_LEVELS, 0);  /* noisy frames */
    synth slow = {20.0, 0.001, 0, 7};    /* fixed cost over the budget */
    run_budget(t, 60, slow, N_LEVELS, 1);
    synth steep = {0.5, 0.004, 0.02, 3};
    run_budget(t, 90, steep, N_LEVELS, 0);
}

static void test_budget_first_and_unmeasured(mts_test *t)
{
    mts_model m = fake_model();
    mts_lod_policy_options o = {0};
    o.kind = MTS_LOD_POLICY_BUDGET;
    mts_lod_policy p;
    mts_lod_policy_init(&p, &o, &m);
    CHECK(t, mts_lod_policy_choose(&p, 900, NULL, 0) == 900); /* nothing measured yet */
    CHECK(t, mts_lod_policy_choose(&p, 900, NULL, -1) == 900);
    CHECK(t, mts_lod_policy_choose(&p, 400, NULL, 0) == 400); /* clamped to available */
    /* a very slow frame moves down at once */
    uint32_t l = mts_lod_policy_choose(&p, 900, NULL, 1000);
    CHECK(t, l < 400);
}

/* A streaming client's model has no level_triangles: counted linearly
 * between the ends given, which for the fake model is exact. */
static void test_without_table(mts_test *t)
{
    mts_model with = fake_model(), without = fake_model();
    without.level_triangles = NULL;
    mts_lod_policy_options o = {0};
    for (int k = MTS_LOD_POLICY_DISTANCE; k <= MTS_LOD_POLICY_AREA; k++) {
        o.kind = (mts_lod_policy_kind)k;
        mts_lod_policy a, b;
        mts_lod_policy_init(&a, &o, &with);
        mts_lod_policy_init(&b, &o, &without);
        CHECK(t, mts_lod_policy_level_triangles(&b, N_LEVELS) == 2.0 * N_LEVELS);
        mts_lod_policy_set_counts(&b, 200, 200 + 2 * N_LEVELS);
        for (double d = 1; d < 300; d *= 1.2) {
            mts_lod_view v = {(float)d, 0.6f, 640, 480};
            uint32_t la = mts_lod_policy_choose(&a, N_LEVELS, &v, 0);
            uint32_t lb = mts_lod_policy_choose(&b, N_LEVELS, &v, 0);
            CHECKF(t, la == lb || la == lb + 1 || lb == la + 1, "%s at %f: %u vs %u",
                   mts_lod_policy_name(o.kind), d, la, lb);
            CHECK(t, mts_lod_policy_choose(&b, 100, &v, 0) <= 100);
        }
    }
}

static void test_cow_levels_monotone(mts_test *t)
{
    mts_error err = {0};
    mts_mesh mesh = {0};
    mts_model m;
    if (mts_mesh_load("tests/data/cow.off", NULL, &mesh, NULL, &err) != MTS_OK)
        SKIP(t, "tests/data/cow.off: %s", err.msg);
    mts_result rc = mts_build_model(&mesh, "cow", NULL, &m, NULL, &err);
    mts_mesh_free(&mesh);
    CHECKF(t, rc == MTS_OK, "%s", err.msg);
    if (rc != MTS_OK)
        return;
    for (uint32_t l = 0; l < m.level_count; l++)
        CHECKF(t, m.level_triangles[l + 1] > m.level_triangles[l], "level %u: %u -> %u", l,
               m.level_triangles[l], m.level_triangles[l + 1]);
    mts_lod_policy_options o = {0};
    o.kind = MTS_LOD_POLICY_DISTANCE;
    mts_lod_policy p;
    mts_lod_policy_init(&p, &o, &m);
    mts_lod_view v = {1, 0.61f, 512, 512};
    double d0 = mts_lod_policy_frame_distance(&p, &v);
    v.distance = (float)d0;
    CHECK(t, mts_lod_policy_choose(&p, m.level_count, &v, 0) == m.level_count);
    v.distance = (float)(1e3 * d0);
    CHECK(t, mts_lod_policy_choose(&p, m.level_count, &v, 0) == 0);
    mts_model_free(&m);
}

int main(void)
{
    mts_test t = {0};
    RUN(&t, test_parse);
    RUN(&t, test_received);
    RUN(&t, test_distance_monotone);
    RUN(&t, test_area_monotone);
    RUN(&t, test_budget_converges);
    RUN(&t, test_budget_first_and_unmeasured);
    RUN(&t, test_without_table);
    RUN(&t, test_cow_levels_monotone);
    return mts_test_end(&t);
}
