/* The client's view (client/view.h), headless on the cow: it draws what a
 * renderer given the same strips by hand draws, at every level it is asked
 * for, whether it moves the source's runtime or one of its own; it follows
 * a source that grows as a stream's does (vertices appended, levels made
 * available); and its geomorphs: the first frame of a morph is the old
 * level's picture, a frame half-way lies between the two levels' pictures,
 * the last is the new level's, going up and coming down.
 *
 * Skips, naming the EGL error, where there is no EGL (MTS_TEST_REQUIRE_EGL=1
 * makes that a failure). */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "build.h"
#include "lod.h"
#include "mesh.h"
#include "model.h"
#include "render.h"
#include "test.h"
#include "test_gl.h"
#include "view.h"

#define SIDE 256u

static mts_render_context *g_ctx;
static mts_error g_ctx_err;
static mts_model g_cow;
static int g_cow_ok;

#define NEED_CONTEXT(t) MTS_TEST_NEED_GL(t, g_ctx, g_ctx_err, g_cow_ok)

typedef struct frame {
    uint8_t px[SIDE * SIDE * 4];
} frame;

static void options(mts_render_options *o)
{
    memset(o, 0, sizeof *o); /* zeroed: the defaults, a front view */
    o->width = SIDE;
    o->height = SIDE;
    o->camera.yaw_deg = 30;
    o->camera.pitch_deg = 20;
}

/* Mean absolute difference per channel, over the frame. */
static double frame_diff(const frame *a, const frame *b)
{
    uint64_t sum = 0;
    for (size_t i = 0; i < sizeof a->px; i++)
        sum += (uint64_t)abs((int)a->px[i] - (int)b->px[i]);
    return (double)sum / (double)sizeof a->px;
}

static uint32_t pixels_differing(const frame *a, const frame *b, int tol)
{
    return mts_test_pixels_differing(a->px, b->px, SIDE * SIDE, tol);
}

static int view_frame(mts_test *t, mts_view *v, frame *f)
{
    mts_error err = {0};
    mts_result rc = mts_view_draw(v, &err);
    if (rc == MTS_OK)
        rc = mts_render_read_rgba(v->renderer, f->px, &err);
    CHECKF(t, rc == MTS_OK, "draw: %s", err.msg);
    return rc == MTS_OK;
}

/* The level drawn by a renderer given the runtime's strips by hand. */
static int reference_frame(mts_test *t, uint32_t level, frame *f)
{
    mts_error err = {0};
    mts_lod lod;
    if (mts_lod_init(&lod, &g_cow, MTS_LOD_AT_BASE, &err) != MTS_OK)
        return 0;
    mts_render_options o;
    options(&o);
    mts_render_layout layout;
    mts_render_layout_from_lod(&lod, &layout);
    mts_renderer *r = NULL;
    int ok = mts_lod_set_level(&lod, level, &err) == MTS_OK &&
             mts_renderer_create(g_ctx, &o, &layout, &r, &err) == MTS_OK &&
             mts_render_append_vertices(r, 0, g_cow.vertex_count, g_cow.positions,
                                        g_cow.normals, NULL, &err) == MTS_OK &&
             mts_render_update_strips(r, &lod, &err) == MTS_OK &&
             mts_render_draw(r, &err) == MTS_OK && mts_render_read_rgba(r, f->px, &err) == MTS_OK;
    CHECKF(t, ok, "reference at level %u: %s", level, err.msg);
    mts_renderer_destroy(r);
    mts_lod_free(&lod);
    return ok;
}

/* Both ways of holding the level draw the reference picture and report the
 * level's own figures; the own runtime leaves the source where it was. */
static void test_view_levels(mts_test *t)
{
    NEED_CONTEXT(t);
    mts_error err = {0};
    mts_lod src_lod;
    CHECK(t, mts_lod_init(&src_lod, &g_cow, MTS_LOD_AT_FULL, &err) == MTS_OK);
    mts_follow_source src = mts_follow_source_of_model(&src_lod, &g_cow);
    mts_render_options o;
    options(&o);
    const uint32_t n = g_cow.level_count;
    const uint32_t levels[4] = {n, n / 10, 0, n / 2};
    for (int own = 0; own < 2; own++) {
        mts_view v;
        const mts_follow *vf = &v.follow; /* the level drawn, its figures, the morph */
        mts_view_options vo = {own, 0, 0};
        CHECKF(t, mts_view_create(&v, g_ctx, &o, &src, &vo, &err) == MTS_OK, "%s", err.msg);
        for (int i = 0; i < 4; i++) {
            uint32_t l = levels[i];
            CHECKF(t, mts_view_sync(&v, &src, l, 0, &err) == MTS_OK, "%s", err.msg);
            CHECKF(t, vf->shown.level == l && vf->lod->level == l, "own %d: at %u, asked %u", own,
                   vf->shown.level, l);
            CHECKF(t, vf->shown.triangles == g_cow.level_triangles[l] &&
                          vf->shown.strips == g_cow.level_strips[l] &&
                          vf->shown.indices == g_cow.level_indices[l],
                   "own %d level %u: %u triangles %u strips %llu indices, the model says %u %u "
                   "%u",
                   own, l, vf->shown.triangles, vf->shown.strips,
                   (unsigned long long)vf->shown.indices, g_cow.level_triangles[l],
                   g_cow.level_strips[l], g_cow.level_indices[l]);
            CHECKF(t, own ? src_lod.level == n : src_lod.level == l,
                   "own %d: the source is at %u", own, src_lod.level);
            frame got, want;
            if (view_frame(t, &v, &got) && reference_frame(t, l, &want))
                CHECKF(t, pixels_differing(&got, &want, 0) == 0,
                       "own %d level %u: %u pixels differ from the reference", own, l,
                       pixels_differing(&got, &want, 0));
        }
        /* asking past what is there shows what is there */
        CHECK(t, mts_view_sync(&v, &src, n + 100, 0, &err) == MTS_OK && vf->shown.level == n);
        CHECK(t, mts_view_sync(&v, &src, MTS_VIEW_NEWEST, 0, &err) == MTS_OK &&
                     vf->shown.level == n);
        mts_view_free(&v);
    }
    /* geomorphs need a runtime of the view's own */
    mts_view v;
    mts_view_options bad = {0, 100, 0};
    CHECK(t, mts_view_create(&v, g_ctx, &o, &src, &bad, &err) == MTS_ERR_ARG);
    mts_lod_free(&src_lod);
}

/* A source that grows as a stream does: vertices come in steps, and the
 * levels they make available; a view at NEWEST follows, drawing the
 * reference at each step, and uploads each vertex once. */
static void test_view_follows_growing_source(mts_test *t)
{
    NEED_CONTEXT(t);
    mts_error err = {0};
    mts_lod src_lod;
    CHECK(t, mts_lod_init(&src_lod, &g_cow, MTS_LOD_AT_BASE, &err) == MTS_OK);
    mts_follow_source src = mts_follow_source_of_model(&src_lod, &g_cow);
    const uint32_t nb = g_cow.base_vertex_count, n = g_cow.level_count;
    src.vertices = nb;
    mts_lod_set_available(&src_lod, 0);
    mts_render_options o;
    options(&o);
    mts_view v;
    const mts_follow *vf = &v.follow; /* the level drawn, its figures, the morph */
    mts_view_options vo = {1, 0, 0};
    CHECKF(t, mts_view_create(&v, g_ctx, &o, &src, &vo, &err) == MTS_OK, "%s", err.msg);
    for (uint32_t step = 0; step <= 4; step++) {
        uint32_t have = n * step / 4;
        src.vertices = nb + have;
        mts_lod_set_available(&src_lod, have);
        CHECK(t, mts_lod_set_level(&src_lod, have, &err) == MTS_OK);
        CHECKF(t, mts_view_sync(&v, &src, MTS_VIEW_NEWEST, 0, &err) == MTS_OK, "%s", err.msg);
        CHECKF(t, vf->shown.level == have, "step %u: view at %u, %u came", step, vf->shown.level,
               have);
        CHECK(t, mts_render_vertex_count(v.renderer) == nb + have);
        frame got, want;
        if (view_frame(t, &v, &got) && reference_frame(t, have, &want))
            CHECKF(t, pixels_differing(&got, &want, 0) == 0, "step %u: %u pixels differ", step,
                   pixels_differing(&got, &want, 0));
    }
    mts_render_stats rs;
    mts_render_get_stats(v.renderer, &rs);
    CHECKF(t, rs.vertex_bytes_uploaded == 24ull * g_cow.vertex_count,
           "%llu vertex bytes uploaded for %u vertices",
           (unsigned long long)rs.vertex_bytes_uploaded, g_cow.vertex_count);
    mts_view_free(&v);
    mts_lod_free(&src_lod);
}

/* Geomorphs between level a and level b, both ways. */
static void test_view_morph(mts_test *t)
{
    NEED_CONTEXT(t);
    mts_error err = {0};
    mts_lod src_lod;
    CHECK(t, mts_lod_init(&src_lod, &g_cow, MTS_LOD_AT_FULL, &err) == MTS_OK);
    mts_follow_source src = mts_follow_source_of_model(&src_lod, &g_cow);
    const uint32_t a = g_cow.level_count / 20, b = g_cow.level_count / 4;
    frame ref_a, ref_b;
    if (!reference_frame(t, a, &ref_a) || !reference_frame(t, b, &ref_b))
        return;
    const double d_ab = frame_diff(&ref_a, &ref_b);
    CHECKF(t, d_ab > 0.5, "levels %u and %u look alike (%.3f)", a, b, d_ab);

    mts_render_options o;
    options(&o);
    mts_view v;
    const mts_follow *vf = &v.follow; /* the level drawn, its figures, the morph */
    mts_view_options vo = {1, 100, 0};
    CHECKF(t, mts_view_create(&v, g_ctx, &o, &src, &vo, &err) == MTS_OK, "%s", err.msg);
    /* base -> a, to its end */
    CHECK(t, mts_view_sync(&v, &src, a, 0, &err) == MTS_OK && vf->morph.active &&
                 vf->lod->level == a);
    CHECK(t, mts_view_sync(&v, &src, a, 1000, &err) == MTS_OK && !vf->morph.active);
    frame f;
    if (view_frame(t, &v, &f))
        CHECKF(t, pixels_differing(&f, &ref_a, 0) == 0, "after the morph to %u: %u pixels",
               a, pixels_differing(&f, &ref_a, 0));

    /* up: the level is set at once, its new vertices start at their
     * ancestors' places; the first frame is level a's surface */
    CHECK(t, mts_view_sync(&v, &src, b, 2000, &err) == MTS_OK);
    CHECKF(t, vf->morph.active && vf->lod->level == b && vf->shown.level == b && vf->morph.t == 0,
           "morphing %d at %u, t %.2f", vf->morph.active, vf->lod->level, vf->morph.t);
    frame m0, m50, m_down;
    if (view_frame(t, &v, &m0)) {
        uint32_t d = pixels_differing(&m0, &ref_a, 8);
        CHECKF(t, d < SIDE * SIDE / 500, "the morph's first frame differs from level %u's in "
                                         "%u pixels", a, d);
        fprintf(stderr, "  morph %u -> %u: first frame against a: %u pixels over 8 (of %u)\n",
                a, b, d, SIDE * SIDE);
    }
    /* a request meanwhile waits for the morph to end */
    CHECK(t, mts_view_sync(&v, &src, g_cow.level_count, 2050, &err) == MTS_OK);
    CHECKF(t, vf->morph.active && vf->lod->level == b && vf->morph.t > 0.45f && vf->morph.t < 0.55f,
           "half-way: morphing %d at %u, t %.2f", vf->morph.active, vf->lod->level, vf->morph.t);
    if (view_frame(t, &v, &m50)) {
        double da = frame_diff(&m50, &ref_a), db = frame_diff(&m50, &ref_b);
        fprintf(stderr, "  half-way: %.3f from level %u, %.3f from level %u (they are %.3f "
                        "apart)\n", da, a, db, b, d_ab);
        CHECKF(t, da > 0 && db > 0 && da < d_ab && db < d_ab,
               "half-way frame not between: %.3f from a, %.3f from b, a to b %.3f", da, db,
               d_ab);
    }
    CHECK(t, mts_view_sync(&v, &src, b, 3000, &err) == MTS_OK && !vf->morph.active);
    if (view_frame(t, &v, &f))
        CHECKF(t, pixels_differing(&f, &ref_b, 0) == 0, "after the morph to %u: %u pixels",
               b, pixels_differing(&f, &ref_b, 0));

    /* down: the vertices slide back first, the level drops at the end */
    CHECK(t, mts_view_sync(&v, &src, a, 4000, &err) == MTS_OK);
    CHECKF(t, vf->morph.active && vf->lod->level == b && vf->morph.t == 1, "down: at %u, t %.2f",
           vf->lod->level, vf->morph.t);
    if (view_frame(t, &v, &f))
        CHECKF(t, pixels_differing(&f, &ref_b, 0) == 0,
               "the first frame down differs from level %u's in %u pixels", b,
               pixels_differing(&f, &ref_b, 0));
    CHECK(t, mts_view_sync(&v, &src, a, 4050, &err) == MTS_OK && vf->morph.active);
    if (view_frame(t, &v, &m_down)) {
        double da = frame_diff(&m_down, &ref_a), db = frame_diff(&m_down, &ref_b);
        CHECKF(t, da < d_ab && db < d_ab && pixels_differing(&m_down, &m50, 8) < SIDE * SIDE / 500,
               "half-way down: %.3f from a, %.3f from b; half-way up and down differ in %u "
               "pixels", da, db, pixels_differing(&m_down, &m50, 8));
    }
    CHECK(t, mts_view_sync(&v, &src, a, 5000, &err) == MTS_OK && !vf->morph.active &&
                 vf->lod->level == a && vf->shown.level == a);
    if (view_frame(t, &v, &f))
        CHECKF(t, pixels_differing(&f, &ref_a, 0) == 0, "back at %u: %u pixels", a,
               pixels_differing(&f, &ref_a, 0));
    mts_render_stats rs;
    mts_render_get_stats(v.renderer, &rs);
    /* each morph sends its range's sources once: 0->a, a->b, b->a */
    uint64_t want = 16ull * (a + (b - a) + (b - a));
    CHECKF(t, rs.morph_bytes_uploaded == want, "%llu morph bytes, want %llu",
           (unsigned long long)rs.morph_bytes_uploaded, (unsigned long long)want);
    mts_view_free(&v);
    mts_lod_free(&src_lod);
}

/* Geomorph colours through the view (morph.c's from-colours, the view's
 * upload, the shader's mix), on a cow whose level-a vertices are blue and
 * whose later ones are red, unlit: going up from a to b, each vertex a
 * split adds starts in its nearest ancestor's colour (one present at a:
 * blue) -- checked in the follower's from_colors against a walk up the
 * parents -- so the first frame has no red; half-way every added vertex is
 * half red (no pixel redder than 128 + rounding, many near it), at the end
 * full red; coming down they fade back. With no_colors the same view draws
 * grey and uploads no colour. */
static void test_view_morph_colors(mts_test *t)
{
    NEED_CONTEXT(t);
    mts_error err = {0};
    const uint32_t n = g_cow.vertex_count, nb = g_cow.base_vertex_count;
    const uint32_t a = g_cow.level_count / 20, b = g_cow.level_count;
    mts_model ccow = g_cow;
    ccow.colors = malloc((size_t)n * 3);
    ccow.flags |= MTS_MODEL_COLORS;
    if (!ccow.colors) {
        CHECK(t, 0);
        return;
    }
    for (uint32_t i = 0; i < n; i++) {
        uint8_t red = i >= nb + a ? 255 : 0;
        ccow.colors[3 * (size_t)i] = red;
        ccow.colors[3 * (size_t)i + 1] = 0;
        ccow.colors[3 * (size_t)i + 2] = (uint8_t)(255 - red);
    }
    mts_lod src_lod;
    CHECK(t, mts_lod_init(&src_lod, &ccow, MTS_LOD_AT_FULL, &err) == MTS_OK);
    mts_follow_source src = mts_follow_source_of_model(&src_lod, &ccow);
    mts_render_options o;
    options(&o);
    o.style.ambient = 1;
    for (int grey = 0; grey < 2; grey++) {
        mts_view v;
        const mts_follow *vf = &v.follow;
        mts_view_options vo = {1, 100, grey};
        CHECKF(t, mts_view_create(&v, g_ctx, &o, &src, &vo, &err) == MTS_OK, "%s", err.msg);
        CHECK(t, v.colors == !grey);
        CHECK(t, mts_view_sync(&v, &src, a, 0, &err) == MTS_OK);
        CHECK(t, mts_view_sync(&v, &src, a, 1000, &err) == MTS_OK && !vf->morph.active);
        CHECK(t, mts_view_sync(&v, &src, b, 2000, &err) == MTS_OK && vf->morph.active &&
                     vf->morph.first == nb + a && vf->morph.count == b - a);
        /* the from-colours: each vertex's ancestor present at level a */
        uint32_t wrong = 0;
        for (uint32_t i = 0; i < vf->morph.count && vf->morph.from_colors; i++) {
            uint32_t anc = nb + a + i;
            while (anc >= nb + a)
                anc = g_cow.parents[anc - nb];
            wrong += memcmp(vf->morph.from_colors + 3 * (size_t)i, ccow.colors + 3 * (size_t)anc,
                            3) != 0;
        }
        CHECKF(t, vf->morph.from_colors && wrong == 0, "%u from-colours are not the ancestor's",
               wrong);
        const double at[4] = {2000, 2050, 3000, 0};
        int max_r[3] = {0}, off[3] = {0};
        uint32_t many[3] = {0};
        for (int k = 0; k < 3; k++) {
            if (k)
                CHECK(t, mts_view_sync(&v, &src, b, at[k], &err) == MTS_OK);
            frame f;
            if (!view_frame(t, &v, &f))
                break;
            for (uint32_t i = 0; i < SIDE * SIDE; i++) {
                const uint8_t *p = f.px + 4 * i;
                if (!mts_test_pixel_differs(p, f.px, 2))
                    continue;
                max_r[k] = p[0] > max_r[k] ? p[0] : max_r[k];
                int d = abs((int)p[0] + (int)p[2] - 255);
                off[k] = d > off[k] ? d : off[k];
                many[k] += p[0] >= (k == 1 ? 100 : 200);
            }
        }
        if (!grey) {
            fprintf(stderr, "  view morph colours %u -> %u: most red %d, %d (%u pixels of 100 or "
                            "more), %d; r + b off 255 by %d %d %d\n",
                    a, b, max_r[0], max_r[1], many[1], max_r[2], off[0], off[1], off[2]);
            CHECKF(t, max_r[0] <= 2, "first frame: red %d", max_r[0]);
            CHECKF(t, max_r[1] >= 110 && max_r[1] <= 131 && many[1] > SIDE * SIDE / 100,
                   "half-way: red at most %d, %u pixels of 100 or more", max_r[1], many[1]);
            CHECKF(t, max_r[2] >= 250 && many[2] > SIDE * SIDE / 100, "the end: red %d",
                   max_r[2]);
            CHECKF(t, off[0] <= 3 && off[1] <= 3 && off[2] <= 3, "off the colours' line by %d %d %d",
                   off[0], off[1], off[2]);
        } else {
            /* the grey, unlit: 0.85 0.82 0.76 everywhere */
            CHECKF(t, max_r[0] == max_r[1] && max_r[1] == max_r[2] && max_r[0] >= 216 &&
                          max_r[0] <= 218,
                   "no_colors: red %d %d %d", max_r[0], max_r[1], max_r[2]);
        }
        mts_render_stats rs;
        mts_render_get_stats(v.renderer, &rs);
        CHECKF(t, rs.colors == !grey && rs.vertex_bytes_uploaded ==
                                            (grey ? 24ull : 28ull) * n + rs.morph_bytes_uploaded,
               "%s: %llu vertex bytes", grey ? "grey" : "colours",
               (unsigned long long)rs.vertex_bytes_uploaded);
        mts_view_free(&v);
    }
    mts_lod_free(&src_lod);
    free(ccow.colors);
}

int main(void)
{
    mts_test t = {0};
    mts_error err = {0};
    mts_mesh mesh;
    if (mts_mesh_load("tests/data/cow.off", NULL, &mesh, NULL, &err) == MTS_OK) {
        if (mts_build_model(&mesh, "tests/data/cow.off", NULL, &g_cow, NULL, &err) == MTS_OK)
            g_cow_ok = 1;
        mts_mesh_free(&mesh);
    }
    if (!g_cow_ok)
        fprintf(stderr, "  cow: %s\n", err.msg);
    if (mts_render_context_create_headless(&g_ctx, &g_ctx_err) != MTS_OK)
        g_ctx = NULL;
    RUN(&t, test_view_levels);
    RUN(&t, test_view_follows_growing_source);
    RUN(&t, test_view_morph);
    RUN(&t, test_view_morph_colors);
    mts_render_context_destroy(g_ctx);
    if (g_cow_ok)
        mts_model_free(&g_cow);
    return mts_test_end(&t);
}
