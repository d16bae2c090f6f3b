/* The renderer, headless through EGL (Mesa's surfaceless platform, llvmpipe
 * on machines without a GPU): the cow drawn at the full level, at 10% and at
 * the base level (PNGs in mts_test_tmpdir()), the full level against the
 * source mesh's own triangles (a winding error in the strips would show as a
 * hole), back-face culling, restart runs drawing nothing, changed-strip
 * uploads touching only the changed strips, the draw modes, the camera, the
 * PNG writer and the errors.
 *
 * Where EGL cannot be initialised (no Mesa) every case that needs it skips,
 * naming the EGL error; with MTS_TEST_REQUIRE_EGL=1 (CI) it fails instead. */
#include <png.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "build.h"
#include "lod.h"
#include "mesh.h"
#include "model.h"
#include "pngwrite.h"
#include "render.h"
#include "strips.h"
#include "test.h"
#include "test_gl.h"
#include "drawmodes.h"

#define SIDE 256u

/* Set up once in main: one EGL context and one cow for every case. */
static mts_render_context *g_ctx;
static mts_error g_ctx_err;
static mts_mesh g_mesh;
static mts_model g_cow;
static int g_cow_ok;

/* the draw path draw_and_read takes: the renderer's own unless a case
 * compares others (client/drawmodes.h) */
static mts_drawmodes g_dm;
static mts_drawmode g_mode;

#define NEED_CONTEXT(t)                                                                \
    do {                                                                               \
        g_mode = MTS_DRAWMODE_JOINED;                                                  \
        MTS_TEST_NEED_GL(t, g_ctx, g_ctx_err, g_cow_ok);                               \
    } while (0)

static void png_path(char *buf, size_t size, const char *name)
{
    snprintf(buf, size, "%s/mts_render_%s.png", mts_test_tmpdir(), name);
}

/* ---- pictures --------------------------------------------------------- */

typedef struct frame {
    uint8_t px[SIDE * SIDE * 4];
} frame;

/* Pixels that are not the background (the top-left pixel: the camera keeps a
 * margin around the model). */
static uint32_t foreground(const frame *f)
{
    uint32_t n = 0;
    for (uint32_t i = 0; i < SIDE * SIDE; i++)
        n += (uint32_t)mts_test_pixel_differs(f->px + 4 * i, f->px, 2);
    return n;
}

static uint32_t pixels_differing(const frame *a, const frame *b, int tol)
{
    return mts_test_pixels_differing(a->px, b->px, SIDE * SIDE, tol);
}

/* Pixels of strong colour (the cow's surface is a light grey). */
static uint32_t saturated(const frame *f)
{
    uint32_t n = 0;
    for (uint32_t i = 0; i < SIDE * SIDE; i++) {
        const uint8_t *p = f->px + 4 * i;
        int mx = p[0], mn = p[0];
        for (int c = 1; c < 3; c++) {
            if (p[c] > mx)
                mx = p[c];
            if (p[c] < mn)
                mn = p[c];
        }
        n += (uint32_t)(mx - mn > 40);
    }
    return n;
}

static int draw_and_read(mts_test *t, mts_renderer *r, frame *f, const char *png)
{
    mts_error err = {0};
    mts_result rc = mts_drawmodes_draw(&g_dm, r, g_mode, &err);
    CHECKF(t, rc == MTS_OK, "draw: %s", err.msg);
    if (rc != MTS_OK)
        return 0;
    rc = mts_render_read_rgba(r, f->px, &err);
    CHECKF(t, rc == MTS_OK, "read: %s", err.msg);
    if (rc != MTS_OK)
        return 0;
    if (png) {
        char path[1024];
        png_path(path, sizeof path, png);
        rc = mts_render_write_png(r, path, &err);
        CHECKF(t, rc == MTS_OK, "png: %s", err.msg);
    }
    return rc == MTS_OK;
}

static void options(mts_render_options *o)
{
    mts_render_options_default(o);
    o->timed = 1; /* the cases print draw times */
    o->width = SIDE;
    o->height = SIDE;
}

/* A renderer for the runtime's model with every vertex uploaded (in two
 * appends: the base, then the rest) and the runtime's strips uploaded. */
static mts_renderer *renderer_for(mts_test *t, mts_lod *lod, const mts_render_options *o)
{
    mts_error err = {0};
    mts_render_layout layout;
    mts_render_layout_from_lod(lod, &layout);
    mts_renderer *r = NULL;
    mts_result rc = mts_renderer_create(g_ctx, o, &layout, &r, &err);
    CHECKF(t, rc == MTS_OK, "create: %s", err.msg);
    if (rc != MTS_OK)
        return NULL;
    const mts_model *m = lod->model;
    uint32_t nb = m->base_vertex_count;
    /* the model's colours where it has them (the layout says so then) */
    CHECK(t, mts_render_append_vertices(r, 0, nb, m->positions, m->normals, m->colors, &err) ==
                 MTS_OK);
    CHECK(t, mts_render_append_vertices(r, nb, m->vertex_count - nb, m->positions + 3u * nb,
                                        m->normals + 3u * nb,
                                        m->colors ? m->colors + 3u * nb : NULL, &err) == MTS_OK);
    CHECK(t, mts_render_vertex_count(r) == m->vertex_count);
    rc = mts_render_update_strips(r, lod, &err);
    CHECKF(t, rc == MTS_OK, "update: %s", err.msg);
    mts_lod_clear_changed(lod);
    return r;
}

/* A renderer drawing the given triangles, one 3-index strip each (with the
 * cow's bounding box, so the same camera). flip reverses each triangle. */
static mts_renderer *renderer_for_triangles(mts_test *t, const mts_render_options *o,
                                            const uint32_t *tris, uint32_t count, int flip)
{
    mts_error err = {0};
    uint32_t *slot = malloc(((size_t)count + 1) * sizeof *slot);
    if (!slot) {
        CHECK(t, slot != NULL);
        return NULL;
    }
    for (uint32_t i = 0; i <= count; i++)
        slot[i] = 3u * i;
    mts_render_layout layout = {0};
    layout.vertex_capacity = g_mesh.vertex_count;
    layout.strip_count = count;
    layout.slot = slot;
    memcpy(layout.bbox_min, g_cow.bbox_min, sizeof layout.bbox_min);
    memcpy(layout.bbox_max, g_cow.bbox_max, sizeof layout.bbox_max);
    mts_renderer *r = NULL;
    mts_result rc = mts_renderer_create(g_ctx, o, &layout, &r, &err);
    free(slot);
    CHECKF(t, rc == MTS_OK, "create: %s", err.msg);
    if (rc != MTS_OK)
        return NULL;
    CHECK(t, mts_render_append_vertices(r, 0, g_mesh.vertex_count, g_mesh.positions,
                                        g_mesh.normals, NULL, &err) == MTS_OK);
    for (uint32_t i = 0; i < count && !t->case_failed; i++) {
        uint32_t tri[3] = {tris[3 * i], tris[3 * i + 1], tris[3 * i + 2]};
        if (flip) {
            uint32_t x = tri[1];
            tri[1] = tri[2];
            tri[2] = x;
        }
        rc = mts_render_set_strip(r, i, tri, 3, &err);
        CHECKF(t, rc == MTS_OK, "triangle %u: %s", i, err.msg);
    }
    return r;
}

/* What most cases start from: the cow's runtime started `at` and moved to
 * `level`, the default options, a renderer for them and `frames` frames. */
typedef struct cow_case {
    mts_lod lod;
    mts_render_options o;
    mts_renderer *r;
    frame *f;
} cow_case;

/* 1 when all of it is there and no check failed; cow_case_free either way. */
static int cow_case_init(mts_test *t, cow_case *c, mts_lod_start at, uint32_t level,
                         size_t frames)
{
    mts_error err = {0};
    memset(c, 0, sizeof *c);
    options(&c->o);
    mts_result rc = mts_lod_init(&c->lod, &g_cow, at, &err);
    CHECKF(t, rc == MTS_OK, "lod: %s", err.msg);
    if (rc != MTS_OK)
        return 0;
    CHECK(t, mts_lod_set_level(&c->lod, level, &err) == MTS_OK);
    c->r = renderer_for(t, &c->lod, &c->o);
    c->f = calloc(frames, sizeof *c->f);
    CHECK(t, c->f != NULL);
    return c->r && c->f && !t->case_failed;
}

static void cow_case_free(cow_case *c)
{
    free(c->f);
    mts_renderer_destroy(c->r);
    mts_lod_free(&c->lod);
}

/* ---- cases ------------------------------------------------------------ */

static void test_context(mts_test *t)
{
    NEED_CONTEXT(t);
    const char *d = mts_render_context_description(g_ctx);
    CHECK(t, d && strstr(d, "OpenGL ES 3") != NULL);
    if (getenv("MTS_TEST_VERBOSE"))
        fprintf(stderr, "  GL: %s\n", d);
}

/* Full level, ~10% and the base: lit pictures, each different. */
static void test_cow_levels(mts_test *t)
{
    NEED_CONTEXT(t);
    mts_error err = {0};
    cow_case c;
    if (!cow_case_init(t, &c, MTS_LOD_AT_FULL, g_cow.level_count, 3))
        goto done;
    mts_render_stats st;
    mts_render_get_stats(c.r, &st);
    /* the default draws the packed buffer, built at the first frame: until
     * then no index went to GL, and the slot buffer waits for a mode that
     * reads it */
    CHECK(t, st.full_uploads == 0 && st.index_bytes_uploaded == 0 && st.packed_builds == 0);
    /* every slot's capacity (the longest it is at any level) and a separator */
    CHECK(t, st.index_buffer_bytes == 4ull * (c.lod.slot[g_cow.strip_count] + g_cow.strip_count));

    uint32_t levels[3] = {g_cow.level_count, mts_model_level_for_fraction(&g_cow, 0.1), 0};
    const char *names[3] = {"cow_full", "cow_10pct", "cow_base"};
    uint32_t fg[3];
    for (int i = 0; i < 3; i++) {
        CHECK(t, mts_lod_set_level(&c.lod, levels[i], &err) == MTS_OK);
        CHECKF(t, mts_render_update_strips(c.r, &c.lod, &err) == MTS_OK, "%s", err.msg);
        mts_lod_clear_changed(&c.lod);
        if (!draw_and_read(t, c.r, &c.f[i], names[i]))
            goto done;
        fg[i] = foreground(&c.f[i]);
        /* the background is the requested colour: 0.12, 0.14, 0.18 */
        CHECKF(t, c.f[i].px[0] == 31 && c.f[i].px[1] == 36 && c.f[i].px[2] == 46,
               "background %u %u %u", c.f[i].px[0], c.f[i].px[1], c.f[i].px[2]);
        CHECKF(t, fg[i] > SIDE * SIDE / 10, "%s: only %u of %u pixels drawn", names[i], fg[i],
               SIDE * SIDE);
        CHECKF(t, fg[i] < SIDE * SIDE * 7 / 10, "%s: %u of %u pixels drawn", names[i], fg[i],
               SIDE * SIDE);
    }
    for (int i = 0; i < 3; i++)
        for (int j = i + 1; j < 3; j++) {
            uint32_t d = pixels_differing(&c.f[i], &c.f[j], 8);
            CHECKF(t, d > SIDE * SIDE / 200, "%s and %s differ in %u pixels only", names[i],
                   names[j], d);
        }
    /* the silhouette stays much the same while the shading coarsens */
    CHECKF(t, fg[2] > fg[0] / 2 && fg[2] < fg[0] * 2, "full %u, base %u pixels", fg[0], fg[2]);

    if (getenv("MTS_TEST_VERBOSE")) {
        mts_render_get_stats(c.r, &st);
        fprintf(stderr, "  cow base level %ux%u: %.3f ms, %llu indices\n", SIDE, SIDE,
                st.last_draw_seconds * 1e3, (unsigned long long)st.last_draw_indices);
    }
done:
    cow_case_free(&c);
}

/* The strips at the full level draw the same picture as the mesh they were
 * built from, drawn triangle by triangle: same surface, same winding (a
 * flipped strip would be culled and leave a hole). */
static void test_full_level_matches_mesh(mts_test *t)
{
    NEED_CONTEXT(t);
    cow_case c;
    int ok = cow_case_init(t, &c, MTS_LOD_AT_FULL, g_cow.level_count, 2);
    mts_renderer *tris =
        renderer_for_triangles(t, &c.o, g_mesh.triangles, g_mesh.triangle_count, 0);
    if (ok && tris && !t->case_failed && draw_and_read(t, c.r, &c.f[0], NULL) &&
        draw_and_read(t, tris, &c.f[1], "cow_mesh_triangles")) {
        uint32_t d = pixels_differing(&c.f[0], &c.f[1], 8);
        CHECKF(t, d < SIDE * SIDE / 1000, "strips and mesh differ in %u pixels", d);
        CHECK(t, foreground(&c.f[1]) > SIDE * SIDE / 10);
    }
    mts_renderer_destroy(tris);
    cow_case_free(&c);
}

/* Culling: the triangles facing the camera draw the whole visible surface;
 * the same triangles reversed draw nothing (all culled), but do draw with
 * culling off. (The whole cow reversed would not draw background: it is
 * closed, and its far half, reversed, faces the camera from inside.) */
static void test_back_faces_culled(mts_test *t)
{
    NEED_CONTEXT(t);
    mts_render_options o;
    options(&o);
    uint32_t *front = malloc((size_t)g_mesh.triangle_count * 3 * sizeof *front);
    frame *f = calloc(4, sizeof *f);
    mts_renderer *all = NULL, *fr = NULL, *flipped = NULL;
    if (!front || !f) {
        CHECK(t, 0);
        goto done;
    }
    all = renderer_for_triangles(t, &o, g_mesh.triangles, g_mesh.triangle_count, 0);
    if (!all)
        goto done;
    float eye[3], dir[3];
    mts_render_eye(all, eye, dir);
    uint32_t nf = 0;
    for (uint32_t i = 0; i < g_mesh.triangle_count; i++) {
        const uint32_t *tr = g_mesh.triangles + 3 * i;
        const float *a = g_mesh.positions + 3 * tr[0], *b = g_mesh.positions + 3 * tr[1],
                    *c = g_mesh.positions + 3 * tr[2];
        float u[3], v[3], n[3], e[3];
        for (int k = 0; k < 3; k++) {
            u[k] = b[k] - a[k];
            v[k] = c[k] - a[k];
            e[k] = eye[k] - (a[k] + b[k] + c[k]) / 3.0f;
        }
        n[0] = u[1] * v[2] - u[2] * v[1];
        n[1] = u[2] * v[0] - u[0] * v[2];
        n[2] = u[0] * v[1] - u[1] * v[0];
        if (n[0] * e[0] + n[1] * e[1] + n[2] * e[2] > 0)
            memcpy(front + 3 * nf++, tr, 3 * sizeof *tr);
    }
    CHECKF(t, nf > g_mesh.triangle_count / 4 && nf < g_mesh.triangle_count * 3 / 4,
           "%u of %u triangles face the camera", nf, g_mesh.triangle_count);
    fr = renderer_for_triangles(t, &o, front, nf, 0);
    flipped = renderer_for_triangles(t, &o, front, nf, 1);
    if (!fr || !flipped || t->case_failed)
        goto done;
    if (!draw_and_read(t, all, &f[0], NULL) || !draw_and_read(t, fr, &f[1], NULL) ||
        !draw_and_read(t, flipped, &f[2], "cow_front_reversed"))
        goto done;
    uint32_t d = pixels_differing(&f[0], &f[1], 8);
    CHECKF(t, d < SIDE * SIDE / 1000, "front-facing half differs from the cow in %u pixels", d);
    uint32_t fg = foreground(&f[2]);
    CHECKF(t, fg < 20, "%u pixels drawn by reversed triangles", fg);
    /* the whole cow reversed: its far half, seen from inside, faces the camera */
    mts_renderer *inside =
        renderer_for_triangles(t, &o, g_mesh.triangles, g_mesh.triangle_count, 1);
    if (!inside || !draw_and_read(t, inside, &f[3], "cow_all_reversed")) {
        mts_renderer_destroy(inside);
        goto done;
    }
    mts_renderer_destroy(inside);
    fg = foreground(&f[3]);
    CHECKF(t, fg > foreground(&f[0]) / 2, "whole cow reversed: %u pixels, cow %u", fg,
           foreground(&f[0]));
    mts_render_options off = o;
    off.style.show_back_faces = 1;
    mts_render_set_style(flipped, &off.style);
    if (!draw_and_read(t, flipped, &f[3], NULL))
        goto done;
    fg = foreground(&f[3]);
    CHECKF(t, fg > SIDE * SIDE / 10, "culling off: only %u pixels", fg);
done:
    mts_renderer_destroy(all);
    mts_renderer_destroy(fr);
    mts_renderer_destroy(flipped);
    free(front);
    free(f);
}

/* Flat shading (a stream without normals) lights each triangle by its own
 * plane and ignores the vertex normals: the same silhouette as smooth
 * shading, similar light overall, varied across the surface; zero normals
 * change nothing, where smooth shading would give them one flat half-light. */
static void test_flat_shading(mts_test *t)
{
    NEED_CONTEXT(t);
    mts_render_options o;
    options(&o);
    frame *f = calloc(4, sizeof *f);
    float *zero = calloc((size_t)g_mesh.vertex_count * 3, sizeof *zero);
    mts_renderer *r = NULL;
    mts_error err = {0};
    if (!f || !zero) {
        CHECK(t, 0);
        goto done;
    }
    r = renderer_for_triangles(t, &o, g_mesh.triangles, g_mesh.triangle_count, 0);
    if (!r || !draw_and_read(t, r, &f[0], NULL))
        goto done;
    mts_render_options flat = o;
    flat.style.flat_shading = 1;
    mts_render_set_style(r, &flat.style);
    if (!draw_and_read(t, r, &f[1], "cow_flat"))
        goto done;
    CHECK(t, mts_render_append_vertices(r, 0, g_mesh.vertex_count, g_mesh.positions, zero, NULL,
                                        &err) == MTS_OK);
    if (!draw_and_read(t, r, &f[2], NULL))
        goto done;
    mts_render_set_style(r, &o.style);
    if (!draw_and_read(t, r, &f[3], NULL))
        goto done;
    uint32_t fg0 = foreground(&f[0]), fg1 = foreground(&f[1]);
    CHECKF(t, fg1 + SIDE > fg0 && fg0 + SIDE > fg1, "silhouettes: smooth %u, flat %u pixels",
           fg0, fg1);
    CHECKF(t, pixels_differing(&f[0], &f[1], 8) > fg0 / 20, "flat shading looks smooth");
    CHECKF(t, pixels_differing(&f[1], &f[2], 0) == 0, "flat shading read the normals");
    /* light over the surface: mean and spread of the red channel */
    double sum[4] = {0};
    int lo[4] = {255, 255, 255, 255}, hi[4] = {0};
    for (int k = 0; k < 4; k++) {
        uint32_t n = 0;
        for (uint32_t i = 0; i < SIDE * SIDE; i++) {
            const uint8_t *p = f[k].px + 4 * i;
            if (!mts_test_pixel_differs(p, f[k].px, 2))
                continue;
            n++;
            sum[k] += p[0];
            lo[k] = p[0] < lo[k] ? p[0] : lo[k];
            hi[k] = p[0] > hi[k] ? p[0] : hi[k];
        }
        sum[k] /= n ? n : 1;
    }
    CHECKF(t, sum[1] > 0.8 * sum[0] && sum[1] < 1.25 * sum[0], "mean light: smooth %.1f, flat %.1f",
           sum[0], sum[1]);
    CHECKF(t, hi[1] - lo[1] > 60, "flat shading spans %d..%d", lo[1], hi[1]);
    CHECKF(t, hi[3] - lo[3] <= 2, "zero normals, smooth: %d..%d (half light everywhere)", lo[3],
           hi[3]);
done:
    mts_renderer_destroy(r);
    free(zero);
    free(f);
}

/* The base level drawn from slots sized for the full level (long runs of
 * restart indices, left by strips that shrank) and from tight slots (one
 * restart between strips) is the same picture, pixel for pixel. */
static void test_restart_runs_draw_nothing(mts_test *t)
{
    NEED_CONTEXT(t);
    mts_error err = {0};
    cow_case c;
    mts_renderer *tight = NULL;
    if (!cow_case_init(t, &c, MTS_LOD_AT_FULL, g_cow.level_count, 2))
        goto done;
    mts_renderer *wide = c.r;
    /* full -> base: every strip shrinks in place */
    CHECK(t, mts_lod_set_level(&c.lod, 0, &err) == MTS_OK);
    CHECK(t, mts_render_update_strips(wide, &c.lod, &err) == MTS_OK);
    mts_lod_clear_changed(&c.lod);

    mts_render_layout layout;
    mts_render_layout_from_lod(&c.lod, &layout);
    layout.slot = g_cow.base.offsets; /* capacity = base length */
    layout.room = 0;
    CHECKF(t, mts_renderer_create(g_ctx, &c.o, &layout, &tight, &err) == MTS_OK, "%s", err.msg);
    if (!tight)
        goto done;
    CHECK(t, mts_render_append_vertices(tight, 0, g_cow.vertex_count, g_cow.positions,
                                        g_cow.normals, NULL, &err) == MTS_OK);
    for (uint32_t s = 0; s < g_cow.strip_count; s++) {
        uint32_t len;
        const uint32_t *idx = mts_lod_strip(&c.lod, s, &len);
        CHECKF(t, mts_render_set_strip(tight, s, idx, len, &err) == MTS_OK, "%s", err.msg);
    }
    mts_render_stats ws, ts;
    mts_render_get_stats(wide, &ws);
    mts_render_get_stats(tight, &ts);
    CHECK(t, ws.index_buffer_bytes > 2 * ts.index_buffer_bytes);
    if (!draw_and_read(t, wide, &c.f[0], NULL) || !draw_and_read(t, tight, &c.f[1], NULL))
        goto done;
    uint32_t d = pixels_differing(&c.f[0], &c.f[1], 0);
    CHECKF(t, d == 0, "restart runs change %u pixels", d);
    CHECK(t, foreground(&c.f[0]) > SIDE * SIDE / 10);
done:
    mts_renderer_destroy(tight);
    cow_case_free(&c);
}

/* Drawing the slot buffer (RESTART), a small move re-uploads exactly the
 * strips the runtime lists, each over max(old, new) indices, and the picture
 * equals a fresh upload's. */
static void test_small_move_uploads_changed_strips(mts_test *t)
{
    NEED_CONTEXT(t);
    mts_error err = {0};
    mts_lod lod, fresh_lod;
    CHECK(t, mts_lod_init(&lod, &g_cow, MTS_LOD_AT_BASE, &err) == MTS_OK);
    CHECK(t, mts_lod_init(&fresh_lod, &g_cow, MTS_LOD_AT_BASE, &err) == MTS_OK);
    uint32_t mid = g_cow.level_count / 2;
    CHECK(t, mts_lod_set_level(&lod, mid, &err) == MTS_OK);
    mts_render_options o;
    options(&o);
    o.style.color_by_strip = 1; /* the renderer's own draw that reads the slot buffer */
    mts_renderer *r = renderer_for(t, &lod, &o), *fresh = NULL;
    uint32_t *old_len = malloc(((size_t)g_cow.strip_count + 1) * sizeof *old_len);
    frame *f = calloc(2, sizeof *f);
    if (!r || !old_len || !f || t->case_failed)
        goto done;

    /* nothing changed: nothing uploaded */
    CHECK(t, mts_render_update_strips(r, &lod, &err) == MTS_OK);
    mts_render_stats st;
    mts_render_get_stats(r, &st);
    CHECK(t, st.last_update_strips == 0 && st.last_update_bytes == 0);

    for (int dirn = 0; dirn < 2; dirn++) {
        memcpy(old_len, lod.length, (size_t)g_cow.strip_count * sizeof *old_len);
        mts_render_reset_counters(r);
        uint32_t target = dirn == 0 ? mid + 3 : mid - 2;
        CHECK(t, mts_lod_set_level(&lod, target, &err) == MTS_OK);
        uint32_t nc;
        const uint32_t *changed = mts_lod_changed(&lod, &nc);
        CHECK(t, nc > 0 && nc < g_cow.strip_count / 10);
        uint64_t want = 0;
        for (uint32_t i = 0; i < nc; i++) {
            uint32_t s = changed[i];
            want += 4ull * (lod.length[s] > old_len[s] ? lod.length[s] : old_len[s]);
        }
        CHECKF(t, mts_render_update_strips(r, &lod, &err) == MTS_OK, "%s", err.msg);
        mts_lod_clear_changed(&lod);
        mts_render_get_stats(r, &st);
        CHECKF(t, st.last_update_strips == nc && !st.last_update_full,
               "%u strips changed, %u uploaded (full %d)", nc, st.last_update_strips,
               st.last_update_full);
        CHECK(t, st.strip_uploads == nc && st.full_uploads == 0);
        CHECKF(t, st.last_update_bytes == want && st.index_bytes_uploaded == want,
               "uploaded %llu bytes, expected %llu", (unsigned long long)st.last_update_bytes,
               (unsigned long long)want);
        CHECK(t, st.last_update_bytes * 5 < st.index_buffer_bytes);
        if (getenv("MTS_TEST_VERBOSE"))
            fprintf(stderr, "  level %u -> %u: %u of %u strips, %llu of %llu bytes\n",
                    dirn ? mid + 3 : mid, target, nc, g_cow.strip_count,
                    (unsigned long long)st.last_update_bytes,
                    (unsigned long long)st.index_buffer_bytes);
    }
    /* the same level uploaded whole draws the same */
    CHECK(t, mts_lod_set_level(&fresh_lod, lod.level, &err) == MTS_OK);
    fresh = renderer_for(t, &fresh_lod, &o);
    if (!fresh || t->case_failed)
        goto done;
    if (draw_and_read(t, r, &f[0], NULL) && draw_and_read(t, fresh, &f[1], NULL))
        CHECK(t, pixels_differing(&f[0], &f[1], 0) == 0);
done:
    free(old_len);
    free(f);
    mts_renderer_destroy(r);
    mts_renderer_destroy(fresh);
    mts_lod_free(&lod);
    mts_lod_free(&fresh_lod);
}

/* The default (packed) path uploads to GL only what a frame draws from: a
 * move between frames rebuilds the packed buffer once at the next frame and
 * sends nothing to the slot buffer; a mode that reads the slot buffer brings
 * it up to date once, and draws what the packed buffer drew. */
static void test_packed_path_uploads(mts_test *t)
{
    NEED_CONTEXT(t);
    mts_error err = {0};
    cow_case c;
    if (!cow_case_init(t, &c, MTS_LOD_AT_BASE, 0, 2))
        goto done;
    mts_render_stats st;
    const uint32_t mid = g_cow.level_count / 2;
    for (uint32_t target = mid; target <= mid + 40; target += 20) {
        mts_render_reset_counters(c.r);
        CHECK(t, mts_lod_set_level(&c.lod, target, &err) == MTS_OK);
        for (int k = 0; k < 2; k++) { /* two updates before the frame: one rebuild */
            CHECKF(t, mts_render_update_strips(c.r, &c.lod, &err) == MTS_OK, "%s", err.msg);
            mts_lod_clear_changed(&c.lod);
        }
        mts_render_get_stats(c.r, &st);
        CHECK(t, st.index_bytes_uploaded == 0 && st.strip_uploads == 0 && st.full_uploads == 0);
        if (!draw_and_read(t, c.r, &c.f[0], NULL))
            goto done;
        mts_render_get_stats(c.r, &st);
        CHECKF(t, st.packed_builds == 1 && st.index_bytes_uploaded == st.packed_bytes &&
                      st.packed_bytes == st.last_draw_index_bytes,
               "%llu builds, %llu bytes uploaded, packed %llu", (unsigned long long)st.packed_builds,
               (unsigned long long)st.index_bytes_uploaded, (unsigned long long)st.packed_bytes);
        /* a frame with nothing changed uploads nothing */
        mts_render_reset_counters(c.r);
        if (!draw_and_read(t, c.r, &c.f[0], NULL))
            goto done;
        mts_render_get_stats(c.r, &st);
        CHECK(t, st.index_bytes_uploaded == 0 && st.packed_builds == 0);
    }
    /* the slot buffer, read at last: filled once, the same picture */
    mts_render_reset_counters(c.r);
    mts_render_style rs = c.o.style;
    g_mode = MTS_DRAWMODE_RESTART;
    mts_render_set_style(c.r, &rs);
    if (!draw_and_read(t, c.r, &c.f[1], NULL))
        goto done;
    mts_render_get_stats(c.r, &st);
    CHECK(t, st.full_uploads == 1 && st.index_bytes_uploaded == st.index_buffer_bytes);
    CHECK(t, pixels_differing(&c.f[0], &c.f[1], 0) == 0);
    mts_render_reset_counters(c.r);
    if (!draw_and_read(t, c.r, &c.f[1], NULL))
        goto done;
    mts_render_get_stats(c.r, &st);
    CHECK(t, st.index_bytes_uploaded == 0);
done:
    cow_case_free(&c);
}

/* Strip by strip (glDrawElements each, glMultiDrawElementsEXT) draws what one
 * restart-joined call draws; colour by strip paints strips apart. */
static void test_draw_modes(mts_test *t)
{
    NEED_CONTEXT(t);
    cow_case c;
    if (!cow_case_init(t, &c, MTS_LOD_AT_FULL, g_cow.level_count / 3, 4))
        goto done;
    mts_render_stats st;
    mts_drawmode modes[3] = {MTS_DRAWMODE_RESTART, MTS_DRAWMODE_PER_STRIP,
                                     MTS_DRAWMODE_MULTI};
    for (int i = 0; i < 3; i++) {
        mts_render_style s = c.o.style;
        g_mode = modes[i];
        mts_render_set_style(c.r, &s);
        if (!draw_and_read(t, c.r, &c.f[i], NULL))
            goto done;
        mts_render_get_stats(c.r, &st);
        if (i == 0)
            CHECK(t, st.last_draw_calls == 1 &&
                         st.last_draw_indices * 4 == st.index_buffer_bytes);
        if (i == 1) {
            uint32_t drawn = 0;
            for (uint32_t k = 0; k < c.lod.strip_count; k++)
                drawn += c.lod.length[k] >= 3;
            CHECK(t, st.last_draw_calls == drawn);
        }
        if (i == 2 && st.multi_draw_available)
            CHECK(t, st.last_draw_calls == 1);
        if (i > 0) {
            CHECK(t, st.last_draw_indices <= g_cow.level_indices[c.lod.level]);
            uint32_t d = pixels_differing(&c.f[0], &c.f[i], 0);
            CHECKF(t, d == 0, "mode %d differs from restart in %u pixels", i, d);
        }
    }
    mts_render_style s = c.o.style;
    s.color_by_strip = 1; /* the renderer's own draw, strip by strip */
    mts_render_set_style(c.r, &s);
    g_mode = MTS_DRAWMODE_JOINED;
    if (!draw_and_read(t, c.r, &c.f[3], "cow_strips"))
        goto done;
    CHECK(t, saturated(&c.f[0]) < SIDE * SIDE / 100);
    CHECKF(t, saturated(&c.f[3]) > foreground(&c.f[3]) / 2, "%u saturated of %u",
           saturated(&c.f[3]), foreground(&c.f[3]));
    CHECK(t, pixels_differing(&c.f[0], &c.f[3], 2) < foreground(&c.f[0]) + 10);
done:
    cow_case_free(&c);
}

/* Every draw mode draws the same picture, pixel for pixel, at several levels
 * of the cow reached by incremental updates (down, then back up to the full
 * level, so a packed buffer left stale by an update would show): restart,
 * per strip, multi-draw, the packed modes (COMPACT, JOINED) with 16-bit
 * indices and, in a renderer whose layout claims more than 65535 vertices,
 * with 32-bit ones; and the strips' own triangles as a list. A faster mode
 * cannot be a wrong one. */
static void test_all_modes_same_picture(mts_test *t)
{
    NEED_CONTEXT(t);
    mts_error err = {0};
    cow_case c;
    int ok = cow_case_init(t, &c, MTS_LOD_AT_FULL, g_cow.level_count, 2);
    mts_renderer *r[2] = {c.r, NULL};
    mts_render_layout layout;
    mts_render_layout_from_lod(&c.lod, &layout);
    layout.vertex_capacity = 70000; /* 32-bit packed indices */
    CHECKF(t, mts_renderer_create(g_ctx, &c.o, &layout, &r[1], &err) == MTS_OK, "%s", err.msg);
    uint32_t *list = malloc(((size_t)g_cow.level_triangles[g_cow.level_count] + 1) * 12);
    if (!ok || !r[1] || !list || t->case_failed)
        goto done;
    CHECK(t, mts_render_append_vertices(r[1], 0, g_cow.vertex_count, g_cow.positions,
                                        g_cow.normals, NULL, &err) == MTS_OK);
    for (uint32_t s = 0; s < c.lod.strip_count; s++) { /* renderer_for cleared the changes */
        uint32_t len;
        const uint32_t *str = mts_lod_strip(&c.lod, s, &len);
        CHECK(t, mts_render_set_strip(r[1], s, str, len, &err) == MTS_OK);
    }
    const uint32_t n = g_cow.level_count;
    const uint32_t levels[] = {n, n / 2, n / 10, n / 50, 0, n / 3, n};
    const mts_drawmode modes[] = {MTS_DRAWMODE_PER_STRIP, MTS_DRAWMODE_MULTI,
                                          MTS_DRAWMODE_COMPACT, MTS_DRAWMODE_JOINED,
                                          MTS_DRAWMODE_LIST};
    for (size_t li = 0; li < sizeof levels / sizeof levels[0]; li++) {
        CHECK(t, mts_lod_set_level(&c.lod, levels[li], &err) == MTS_OK);
        for (int k = 0; k < 2; k++)
            CHECKF(t, mts_render_update_strips(r[k], &c.lod, &err) == MTS_OK, "%s", err.msg);
        mts_lod_clear_changed(&c.lod);
        size_t nl = 0;
        for (uint32_t s = 0; s < c.lod.strip_count; s++) {
            uint32_t len;
            const uint32_t *str = mts_lod_strip(&c.lod, s, &len);
            for (uint32_t k = 0; k + 2 < len; k++)
                nl += 3 * (size_t)mts_strip_window(str, k, list + nl);
        }
        CHECK(t, mts_drawmodes_set_list(&g_dm, r[0], list, (uint32_t)nl, &err) == MTS_OK);
        mts_render_style s = c.o.style;
        g_mode = MTS_DRAWMODE_RESTART;
        mts_render_set_style(r[0], &s);
        if (!draw_and_read(t, r[0], &c.f[0], NULL))
            goto done;
        CHECK(t, foreground(&c.f[0]) > 100);
        for (int k = 0; k < 2; k++)
            for (size_t mi = 0; mi < sizeof modes / sizeof modes[0]; mi++) {
                if (k == 1 && modes[mi] != MTS_DRAWMODE_COMPACT &&
                    modes[mi] != MTS_DRAWMODE_JOINED)
                    continue;
                g_mode = modes[mi];
                mts_render_set_style(r[k], &s);
                if (!draw_and_read(t, r[k], &c.f[1], NULL))
                    goto done;
                mts_render_stats st;
                mts_render_get_stats(r[k], &st);
                uint32_t d = pixels_differing(&c.f[0], &c.f[1], 0);
                CHECKF(t, d == 0, "level %u, mode %d (%u-bit): %u pixels differ from restart",
                       levels[li], (int)modes[mi], k ? 32 : 16, d);
                if (modes[mi] == MTS_DRAWMODE_COMPACT || modes[mi] == MTS_DRAWMODE_JOINED) {
                    CHECK(t, st.last_draw_calls == 1);
                    CHECK(t, st.last_draw_index_bytes == st.last_draw_indices * (k ? 4u : 2u));
                    /* no slot padding: at most 3 joining indices a strip */
                    CHECK(t, st.last_draw_indices <=
                                 g_cow.level_indices[c.lod.level] + 3ull * c.lod.strip_count);
                }
            }
    }
done:
    free(list);
    mts_renderer_destroy(r[1]);
    cow_case_free(&c);
}

/* Orbiting and zooming move the picture. */
/* Slots whose capacities come later, as a stream announces them
 * (mts_lod_announce): the renderer sizes its buffer for the runtime's room,
 * moves the slots laid out anew, and draws the full level as a renderer
 * laid out whole from the start does, in every draw mode. */
static void test_slots_announced_later(mts_test *t)
{
    NEED_CONTEXT(t);
    mts_error err = {0};
    const uint32_t n = g_cow.strip_count;
    mts_model m = g_cow; /* shallow: only the capacities are its own */
    uint32_t *caps = calloc((size_t)n + 1, 4), k0 = 0;
    uint64_t total = 0;
    for (uint32_t s = 0; s < n; s++) {
        total += g_cow.capacity[s];
        if (g_cow.base.offsets[s + 1] > g_cow.base.offsets[s])
            k0 = s + 1;
    }
    for (uint32_t s = 0; s < k0; s++)
        caps[s] = g_cow.capacity[s];
    m.capacity = caps;
    m.capacity_room = total;
    mts_lod late, whole;
    CHECK(t, mts_lod_init(&late, &m, MTS_LOD_AT_BASE, &err) == MTS_OK);
    CHECK(t, mts_lod_init(&whole, &g_cow, MTS_LOD_AT_FULL, &err) == MTS_OK);
    CHECK(t, late.room == total && late.slot[n] < total && k0 < n);
    mts_render_options o;
    options(&o);
    mts_renderer *r[2] = {renderer_for(t, &late, &o), renderer_for(t, &whole, &o)};
    frame *f = calloc(2, sizeof *f);
    if (!r[0] || !r[1] || !f || t->case_failed)
        goto done;
    /* a slot used before its capacity came does not fit */
    CHECK(t, mts_lod_set_level(&late, g_cow.level_count, &err) != MTS_OK);
    mts_lod_free(&late);
    CHECK(t, mts_lod_init(&late, &m, MTS_LOD_AT_BASE, &err) == MTS_OK);
    CHECK(t, mts_render_update_strips(r[0], &late, &err) == MTS_OK);
    mts_lod_clear_changed(&late);
    /* the rest announced; more than the room is refused */
    for (uint32_t s = k0; s < n; s++)
        caps[s] = g_cow.capacity[s];
    caps[n - 1]++;
    CHECK(t, mts_lod_announce(&late, k0, &err) == MTS_ERR_RANGE);
    caps[n - 1]--;
    CHECKF(t, mts_lod_announce(&late, k0, &err) == MTS_OK, "%s", err.msg);
    CHECK(t, late.relayout_from == k0 && late.slot[n] == total);
    CHECKF(t, mts_lod_set_level(&late, g_cow.level_count, &err) == MTS_OK, "%s", err.msg);
    CHECKF(t, mts_render_update_strips(r[0], &late, &err) == MTS_OK, "%s", err.msg);
    mts_lod_clear_changed(&late);
    CHECK(t, late.relayout_from == UINT32_MAX);
    static const mts_drawmode modes[] = {MTS_DRAWMODE_JOINED, MTS_DRAWMODE_RESTART,
                                                 MTS_DRAWMODE_PER_STRIP,
                                                 MTS_DRAWMODE_MULTI,
                                                 MTS_DRAWMODE_COMPACT};
    for (size_t i = 0; i < sizeof modes / sizeof modes[0] && !t->case_failed; i++) {
        g_mode = modes[i];
        mts_render_set_style(r[0], &o.style);
        mts_render_set_style(r[1], &o.style);
        if (!draw_and_read(t, r[0], &f[0], NULL) || !draw_and_read(t, r[1], &f[1], NULL))
            break;
        uint32_t d = pixels_differing(&f[0], &f[1], 0);
        CHECKF(t, d == 0, "mode %d: %u pixels differ", (int)modes[i], d);
    }
done:
    for (int i = 0; i < 2; i++)
        mts_renderer_destroy(r[i]);
    free(f);
    mts_lod_free(&late);
    mts_lod_free(&whole);
    free(caps);
}

static void test_camera(mts_test *t)
{
    NEED_CONTEXT(t);
    cow_case c;
    if (!cow_case_init(t, &c, MTS_LOD_AT_FULL, g_cow.level_count, 3))
        goto done;
    if (!draw_and_read(t, c.r, &c.f[0], NULL))
        goto done;
    mts_render_camera cam = c.o.camera;
    cam.yaw_deg += 180;
    mts_render_set_camera(c.r, &cam);
    if (!draw_and_read(t, c.r, &c.f[1], "cow_yaw210"))
        goto done;
    cam = c.o.camera;
    cam.zoom = 2;
    mts_render_set_camera(c.r, &cam);
    if (!draw_and_read(t, c.r, &c.f[2], "cow_zoom2"))
        goto done;
    CHECK(t, pixels_differing(&c.f[0], &c.f[1], 8) > SIDE * SIDE / 20);
    uint32_t a = foreground(&c.f[0]), b = foreground(&c.f[2]);
    CHECKF(t, b > 2 * a, "zoom 2: %u pixels, zoom 1: %u", b, a);
    float eye[3], dir[3];
    mts_render_eye(c.r, eye, dir);
    CHECK(t, dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2] > 0.99f);
done:
    cow_case_free(&c);
}

/* Bad calls are refused with a message, and change nothing. */
static void test_errors(mts_test *t)
{
    NEED_CONTEXT(t);
    mts_error err = {0};
    mts_lod lod;
    CHECK(t, mts_lod_init(&lod, &g_cow, MTS_LOD_AT_BASE, &err) == MTS_OK);
    mts_render_options o;
    options(&o);
    mts_render_layout layout;
    mts_render_layout_from_lod(&lod, &layout);
    mts_renderer *r = NULL;

    mts_render_options bad = o;
    bad.width = 0;
    CHECK(t, mts_renderer_create(g_ctx, &bad, &layout, &r, &err) == MTS_ERR_ARG && !r);
    bad = o;
    bad.width = 1u << 30;
    CHECK(t, mts_renderer_create(g_ctx, &bad, &layout, &r, &err) == MTS_ERR_LIMIT && !r);
    mts_render_layout bl = layout;
    bl.vertex_capacity = UINT32_MAX;
    CHECK(t, mts_renderer_create(g_ctx, &o, &bl, &r, &err) == MTS_ERR_LIMIT && !r);
    uint32_t slots[3] = {0, 5, 2};
    bl = layout;
    bl.strip_count = 2;
    bl.slot = slots;
    CHECK(t, mts_renderer_create(g_ctx, &o, &bl, &r, &err) == MTS_ERR_ARG && !r);

    CHECKF(t, mts_renderer_create(g_ctx, &o, &layout, &r, &err) == MTS_OK, "%s", err.msg);
    if (!r)
        goto done;
    uint32_t nb = g_cow.base_vertex_count;
    /* a gap, then past the capacity */
    CHECK(t, mts_render_append_vertices(r, 1, 1, g_cow.positions, g_cow.normals, NULL, &err) ==
                 MTS_ERR_RANGE);
    CHECK(t, mts_render_append_vertices(r, 0, g_cow.vertex_count + 1, g_cow.positions,
                                        g_cow.normals, NULL, &err) == MTS_ERR_RANGE);
    CHECK(t, mts_render_vertex_count(r) == 0);
    CHECK(t, mts_render_append_vertices(r, 0, nb, g_cow.positions, g_cow.normals, NULL, &err) ==
                 MTS_OK);
    /* sending a range again is fine */
    CHECK(t, mts_render_append_vertices(r, nb / 2, nb - nb / 2, g_cow.positions + 3 * (nb / 2),
                                        g_cow.normals + 3 * (nb / 2), NULL, &err) == MTS_OK);
    CHECK(t, mts_render_vertex_count(r) == nb);

    CHECKF(t, mts_render_update_strips(r, &lod, &err) == MTS_OK, "%s", err.msg);
    mts_lod_clear_changed(&lod);
    /* the runtime ahead of the vertices: refused, nothing uploaded */
    CHECK(t, mts_lod_set_level(&lod, 10, &err) == MTS_OK);
    mts_render_reset_counters(r);
    CHECK(t, mts_render_update_strips(r, &lod, &err) == MTS_ERR_RANGE);
    CHECKF(t, strstr(err.msg, "vertex") != NULL && strstr(err.msg, "level 10") != NULL, "%s",
           err.msg);
    mts_render_stats st;
    mts_render_get_stats(r, &st);
    CHECK(t, st.index_bytes_uploaded == 0 && st.strip_uploads == 0);
    /* once the vertices are there it goes through */
    CHECK(t, mts_render_append_vertices(r, nb, 10, g_cow.positions + 3 * nb,
                                        g_cow.normals + 3 * nb, NULL, &err) == MTS_OK);
    CHECKF(t, mts_render_update_strips(r, &lod, &err) == MTS_OK, "%s", err.msg);

    uint32_t idx[4] = {0, 1, 2, nb + 10};
    CHECK(t, mts_render_set_strip(r, 0, idx, 4, &err) == MTS_ERR_RANGE);
    CHECK(t, mts_render_set_strip(r, g_cow.strip_count, idx, 3, &err) == MTS_ERR_RANGE);
    uint32_t cap = lod.slot[1] - lod.slot[0];
    uint32_t *longer = calloc((size_t)cap + 1, sizeof *longer);
    if (longer)
        CHECK(t, mts_render_set_strip(r, 0, longer, cap + 1, &err) == MTS_ERR_RANGE);
    free(longer);

    mts_lod other = lod;
    other.strip_count = lod.strip_count - 1;
    CHECK(t, mts_render_update_strips(r, &other, &err) == MTS_ERR_ARG);

    char path[1024];
    snprintf(path, sizeof path, "%s/no/such/dir/x.png", mts_test_tmpdir());
    CHECK(t, mts_render_draw(r, &err) == MTS_OK);
    CHECK(t, mts_render_write_png(r, path, &err) == MTS_ERR_IO);
    CHECKF(t, strstr(err.msg, "x.png") != NULL, "%s", err.msg);
done:
    mts_renderer_destroy(r);
    mts_lod_free(&lod);
}

/* The PNG writer flips bottom-up buffers, and reads back what it wrote. */
static void test_png(mts_test *t)
{
    mts_error err = {0};
    /* 3x2: bottom row red, green, blue; top row white, black, grey (GL order) */
    const uint8_t px[24] = {255, 0, 0, 255,     0, 255, 0, 255,  0, 0, 255, 255,
                            255, 255, 255, 255, 0, 0, 0, 255,    128, 128, 128, 128};
    for (int bottom_up = 0; bottom_up < 2; bottom_up++) {
        uint8_t *png = NULL;
        size_t size = 0;
        CHECKF(t, mts_png_encode_rgba(3, 2, px, bottom_up, &png, &size, &err) == MTS_OK, "%s",
               err.msg);
        if (!png)
            return;
        CHECK(t, size > 8 && memcmp(png, "\x89PNG\r\n\x1a\n", 8) == 0);
        png_image im;
        memset(&im, 0, sizeof im);
        im.version = PNG_IMAGE_VERSION;
        uint8_t back[24] = {0};
        CHECK(t, png_image_begin_read_from_memory(&im, png, size));
        im.format = PNG_FORMAT_RGBA;
        CHECK(t, im.width == 3 && im.height == 2);
        CHECK(t, png_image_finish_read(&im, NULL, back, 0, NULL));
        png_image_free(&im);
        free(png);
        for (int row = 0; row < 2; row++) {
            int src = bottom_up ? 1 - row : row;
            CHECKF(t, memcmp(back + 12 * row, px + 12 * src, 12) == 0,
                   "bottom_up %d: row %d", bottom_up, row);
        }
    }
    char path[1024];
    snprintf(path, sizeof path, "%s/mts_render_png_test.png", mts_test_tmpdir());
    CHECKF(t, mts_png_write_rgba(path, 3, 2, px, 1, &err) == MTS_OK, "%s", err.msg);
    FILE *fp = fopen(path, "rb");
    CHECK(t, fp != NULL);
    if (fp)
        fclose(fp);
    remove(path);
    uint8_t *png = NULL;
    size_t size = 0;
    CHECK(t, mts_png_encode_rgba(0, 2, px, 0, &png, &size, &err) == MTS_ERR_ARG && !png);
    CHECK(t, mts_png_encode_rgba(MTS_PNG_MAX_SIDE + 1, 1, px, 0, &png, &size, &err) ==
                 MTS_ERR_ARG);
    snprintf(path, sizeof path, "%s/no/such/dir/x.png", mts_test_tmpdir());
    CHECK(t, mts_png_write_rgba(path, 3, 2, px, 1, &err) == MTS_ERR_IO);
}

int main(void)
{
    mts_test t = {0};
    mts_error err = {0};
    if (mts_mesh_load("tests/data/cow.off", NULL, &g_mesh, NULL, &err) == MTS_OK &&
        mts_build_model(&g_mesh, "tests/data/cow.off", NULL, &g_cow, NULL, &err) == MTS_OK)
        g_cow_ok = 1;
    else
        fprintf(stderr, "  cow: %s\n", err.msg);
    if (mts_render_context_create_headless(&g_ctx, &g_ctx_err) != MTS_OK)
        g_ctx = NULL;

    RUN(&t, test_png);
    RUN(&t, test_context);
    RUN(&t, test_cow_levels);
    RUN(&t, test_full_level_matches_mesh);
    RUN(&t, test_back_faces_culled);
    RUN(&t, test_flat_shading);
    RUN(&t, test_restart_runs_draw_nothing);
    RUN(&t, test_small_move_uploads_changed_strips);
    RUN(&t, test_packed_path_uploads);
    RUN(&t, test_draw_modes);
    RUN(&t, test_all_modes_same_picture);
    RUN(&t, test_slots_announced_later);
    RUN(&t, test_camera);
    RUN(&t, test_errors);

    if (g_ctx && mts_render_context_make_current(g_ctx, NULL) == MTS_OK)
        mts_drawmodes_free(&g_dm);
    mts_render_context_destroy(g_ctx);
    if (g_cow_ok)
        mts_model_free(&g_cow);
    mts_mesh_free(&g_mesh);
    return mts_test_end(&t);
}
