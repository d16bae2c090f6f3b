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
#include <math.h>
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

/* A renderer drawing the given triangles over the given vertices (colours
 * NULL: none), one 3-index strip each, with the cow's bounding box, so the
 * same camera. flip reverses each triangle. */
static mts_renderer *renderer_for_triangles_of(mts_test *t, const mts_render_options *o,
                                               uint32_t vertex_count, const float *positions,
                                               const float *normals, const uint8_t *colors,
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
    layout.vertex_capacity = vertex_count;
    layout.colors = colors != NULL;
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
    CHECK(t, mts_render_append_vertices(r, 0, vertex_count, positions, normals, colors, &err) ==
                 MTS_OK);
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

/* The source mesh's triangles, one 3-index strip each. */
static mts_renderer *renderer_for_triangles(mts_test *t, const mts_render_options *o,
                                            const uint32_t *tris, uint32_t count, int flip)
{
    return renderer_for_triangles_of(t, o, g_mesh.vertex_count, g_mesh.positions,
                                     g_mesh.normals, NULL, tris, count, flip);
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

/* ---- vertex colours --------------------------------------------------- */

/* A colour from a position in the cow's box: red grows and blue falls along
 * x, green along y, on the plane r + b = 295. Colours interpolate linearly
 * across a triangle, so every fragment of an unlit draw (ambient 1) keeps
 * r + b = 295 whatever the triangles are: a property of the picture that
 * needs no reference drawing. */
#define COLOR_RB 295
static void color_of(const float p[3], uint8_t rgb[3])
{
    float u[3];
    for (int k = 0; k < 3; k++) {
        float e = g_cow.bbox_max[k] - g_cow.bbox_min[k];
        u[k] = e > 0 ? (p[k] - g_cow.bbox_min[k]) / e : 0.5f;
        u[k] = u[k] < 0 ? 0 : u[k] > 1 ? 1 : u[k];
    }
    int r = 40 + (int)lrintf(215 * u[0]);
    rgb[0] = (uint8_t)r;
    rgb[1] = (uint8_t)(60 + lrintf(120 * u[1]));
    rgb[2] = (uint8_t)(COLOR_RB - r);
}

static uint8_t *colors_of(const float *positions, uint32_t n)
{
    uint8_t *c = malloc((size_t)n * 3 + 1);
    if (c)
        for (uint32_t i = 0; i < n; i++)
            color_of(positions + 3 * (size_t)i, c + 3 * (size_t)i);
    return c;
}

/* The cow with colours: g_cow's arrays (read only) and colours of its own. */
static int colored_cow(mts_model *m)
{
    *m = g_cow;
    m->colors = colors_of(g_cow.positions, g_cow.vertex_count);
    m->flags |= MTS_MODEL_COLORS;
    return m->colors != NULL;
}

/* The triangles of the runtime's current strips (swaps and collapsed
 * windows dropped), each in the winding the strip gives it. */
static uint32_t *level_triangles(const mts_lod *lod, uint32_t *count)
{
    uint64_t n = 0;
    for (uint32_t s = 0; s < lod->strip_count; s++)
        n += lod->length[s] >= 3 ? lod->length[s] - 2 : 0;
    uint32_t *tris = malloc((size_t)(n ? n : 1) * 3 * sizeof *tris);
    *count = 0;
    if (!tris)
        return NULL;
    for (uint32_t s = 0; s < lod->strip_count; s++) {
        uint32_t len;
        const uint32_t *idx = mts_lod_strip(lod, s, &len);
        for (uint32_t k = 0; k + 2 < len; k++) {
            uint32_t a = idx[k], b = idx[k + 1], c = idx[k + 2];
            if (a == b || b == c || a == c)
                continue;
            uint32_t *o = tris + 3 * (size_t)*count;
            o[0] = k % 2 ? b : a; /* odd windows: (s[k+1], s[k], s[k+2]) */
            o[1] = k % 2 ? a : b;
            o[2] = c;
            ++*count;
        }
    }
    return tris;
}

/* Foreground pixels: how many, the largest |r + b - COLOR_RB| among them,
 * and the mean of r - b over the left and the right third of the object's
 * extent on screen (x from the cow's min to max: the camera's right is
 * about +x, so red lies right, blue left). */
typedef struct hue_stats {
    uint32_t n;
    int rb_off;
    double left, right; /* mean r - b */
    uint32_t saturated;
} hue_stats;

static hue_stats hue_of(const frame *f)
{
    hue_stats h = {0};
    uint32_t x0 = SIDE, x1 = 0;
    for (uint32_t i = 0; i < SIDE * SIDE; i++)
        if (mts_test_pixel_differs(f->px + 4 * i, f->px, 2)) {
            uint32_t x = i % SIDE;
            x0 = x < x0 ? x : x0;
            x1 = x > x1 ? x : x1;
        }
    double sl = 0, sr = 0;
    uint32_t nl = 0, nr = 0;
    for (uint32_t i = 0; i < SIDE * SIDE; i++) {
        const uint8_t *p = f->px + 4 * i;
        if (!mts_test_pixel_differs(p, f->px, 2))
            continue;
        h.n++;
        int off = abs((int)p[0] + (int)p[2] - COLOR_RB);
        h.rb_off = off > h.rb_off ? off : h.rb_off;
        uint32_t x = i % SIDE;
        if (3 * (x - x0) < x1 - x0) {
            sl += (int)p[0] - (int)p[2];
            nl++;
        } else if (3 * (x1 - x) < x1 - x0) {
            sr += (int)p[0] - (int)p[2];
            nr++;
        }
    }
    h.left = nl ? sl / nl : 0;
    h.right = nr ? sr / nr : 0;
    h.saturated = saturated(f);
    return h;
}

/* The largest difference of a colour channel over the frame. */
static int max_channel_diff(const frame *a, const frame *b)
{
    int m = 0;
    for (uint32_t i = 0; i < SIDE * SIDE * 4; i++) {
        if (i % 4 == 3)
            continue;
        int d = abs((int)a->px[i] - (int)b->px[i]);
        m = d > m ? d : m;
    }
    return m;
}

/* The coloured cow drawn through its strips, at the full level and about
 * 10%, matches the same triangles drawn one by one with the same colours
 * (at the full level the source mesh's own triangles, coloured from their
 * positions), within 8 levels a channel in under 0.1% of the pixels, as
 * the grey comparison; unlit, every pixel keeps the colours' plane
 * r + b = 295 (within 3, rounding), so the colours reach the screen as
 * given; and against the grey picture the colours show: red right, blue
 * left, most of the cow saturated, where the grey has neither. */
static void test_colors_match_reference(mts_test *t)
{
    NEED_CONTEXT(t);
    mts_error err = {0};
    mts_model ccow;
    mts_lod lod = {0};
    int have_lod = 0;
    mts_renderer *r = NULL, *ref = NULL, *grey = NULL;
    uint8_t *mesh_colors = colors_of(g_mesh.positions, g_mesh.vertex_count);
    uint32_t *tris = NULL;
    frame *f = calloc(6, sizeof *f);
    if (!colored_cow(&ccow) || !mesh_colors || !f) {
        CHECK(t, 0);
        goto done;
    }
    mts_render_options o;
    options(&o);
    CHECKF(t, mts_lod_init(&lod, &ccow, MTS_LOD_AT_FULL, &err) == MTS_OK, "%s", err.msg);
    have_lod = !t->case_failed;
    if (!have_lod || !(r = renderer_for(t, &lod, &o)))
        goto done;
    mts_render_stats st;
    mts_render_get_stats(r, &st);
    CHECKF(t, st.colors && st.vertex_bytes_uploaded == 28ull * g_cow.vertex_count,
           "coloured: %llu vertex bytes for %u vertices",
           (unsigned long long)st.vertex_bytes_uploaded, g_cow.vertex_count);
    ref = renderer_for_triangles_of(t, &o, g_mesh.vertex_count, g_mesh.positions,
                                    g_mesh.normals, mesh_colors, g_mesh.triangles,
                                    g_mesh.triangle_count, 0);
    if (!ref || !draw_and_read(t, r, &f[0], "cow_colors_full") ||
        !draw_and_read(t, ref, &f[1], "cow_colors_mesh"))
        goto done;
    uint32_t d = pixels_differing(&f[0], &f[1], 8);
    fprintf(stderr, "  colours, full level against the mesh's triangles: %u pixels over 8, "
                    "largest difference %d\n", d, max_channel_diff(&f[0], &f[1]));
    CHECKF(t, d < SIDE * SIDE / 1000, "full level: strips and mesh differ in %u pixels", d);

    /* about 10%: the level's own triangles, one by one */
    uint32_t coarse = mts_model_level_for_fraction(&g_cow, 0.1), nt = 0;
    CHECK(t, mts_lod_set_level(&lod, coarse, &err) == MTS_OK);
    CHECKF(t, mts_render_update_strips(r, &lod, &err) == MTS_OK, "%s", err.msg);
    mts_lod_clear_changed(&lod);
    tris = level_triangles(&lod, &nt);
    mts_renderer_destroy(ref);
    ref = tris ? renderer_for_triangles_of(t, &o, g_cow.vertex_count, g_cow.positions,
                                           g_cow.normals, ccow.colors, tris, nt, 0)
               : NULL;
    if (!ref || !draw_and_read(t, r, &f[2], "cow_colors_10pct") ||
        !draw_and_read(t, ref, &f[3], NULL))
        goto done;
    d = pixels_differing(&f[2], &f[3], 8);
    fprintf(stderr, "  colours, level %u (%u triangles) against its triangles: %u pixels over "
                    "8, largest difference %d\n", coarse, nt, d, max_channel_diff(&f[2], &f[3]));
    CHECKF(t, d < SIDE * SIDE / 1000, "level %u: strips and triangles differ in %u pixels",
           coarse, d);
    CHECKF(t, pixels_differing(&f[0], &f[2], 8) > SIDE * SIDE / 200,
           "the full and the coarse level look alike");

    /* unlit: the colours as given, on their plane */
    mts_render_options unlit = o;
    unlit.style.ambient = 1;
    mts_render_set_style(r, &unlit.style);
    if (!draw_and_read(t, r, &f[4], "cow_colors_unlit"))
        goto done;
    hue_stats hu = hue_of(&f[4]);
    fprintf(stderr, "  unlit: %u pixels, r + b off %d from %d at most\n", hu.n, hu.rb_off,
            COLOR_RB);
    CHECKF(t, hu.n > SIDE * SIDE / 10 && hu.rb_off <= 3,
           "unlit colours off their plane by %d (%u pixels)", hu.rb_off, hu.n);
    mts_render_set_style(r, &o.style);

    /* against the grey: the same cow without colours */
    CHECK(t, mts_lod_set_level(&lod, g_cow.level_count, &err) == MTS_OK);
    mts_lod_clear_changed(&lod);
    mts_lod plain;
    if (mts_lod_init(&plain, &g_cow, MTS_LOD_AT_FULL, &err) != MTS_OK) {
        CHECKF(t, 0, "%s", err.msg);
        goto done;
    }
    grey = renderer_for(t, &plain, &o);
    mts_lod_free(&plain);
    if (!grey || !draw_and_read(t, grey, &f[5], NULL))
        goto done;
    hue_stats hc = hue_of(&f[0]), hg = hue_of(&f[5]);
    fprintf(stderr, "  mean r - b, left third / right third: coloured %.1f / %.1f, grey %.1f / "
                    "%.1f; saturated pixels: coloured %u, grey %u (of %u, %u)\n",
            hc.left, hc.right, hg.left, hg.right, hc.saturated, hg.saturated, hc.n, hg.n);
    CHECKF(t, hc.right - hc.left > 60 && hc.left < 0 && hc.right > 0,
           "coloured: r - b %.1f left, %.1f right", hc.left, hc.right);
    CHECKF(t, fabs(hg.right - hg.left) < 10, "grey: r - b %.1f left, %.1f right", hg.left,
           hg.right);
    CHECKF(t, hc.saturated > hc.n / 3 && hg.saturated < hg.n / 100,
           "saturated: coloured %u of %u, grey %u of %u", hc.saturated, hc.n, hg.saturated,
           hg.n);
    CHECKF(t, hc.n + SIDE > hg.n && hg.n + SIDE > hc.n, "silhouettes: %u and %u pixels", hc.n,
           hg.n);
done:
    mts_renderer_destroy(grey);
    mts_renderer_destroy(ref);
    mts_renderer_destroy(r);
    if (have_lod)
        mts_lod_free(&lod);
    free(ccow.colors);
    free(mesh_colors);
    free(tris);
    free(f);
}

/* The shading takes a colour as the grey is taken: every vertex in the
 * grey's 8-bit values draws the grey's picture (within 1 a channel: the
 * grey is not a whole number of 8-bit steps), lit and by strip; colour by
 * strip and the wireframe's edges keep their own colours. */
static void test_colors_shade_as_grey(mts_test *t)
{
    NEED_CONTEXT(t);
    mts_error err = {0};
    mts_model ccow = g_cow;
    mts_lod lod;
    mts_renderer *r = NULL, *grey = NULL;
    frame *f = calloc(4, sizeof *f);
    ccow.colors = malloc((size_t)g_cow.vertex_count * 3);
    ccow.flags |= MTS_MODEL_COLORS;
    mts_render_options o;
    options(&o);
    if (!f || !ccow.colors || mts_lod_init(&lod, &ccow, MTS_LOD_AT_FULL, &err) != MTS_OK) {
        CHECK(t, 0);
        free(f);
        free(ccow.colors);
        return;
    }
    for (uint32_t i = 0; i < g_cow.vertex_count; i++)
        for (int k = 0; k < 3; k++)
            ccow.colors[3 * (size_t)i + k] = (uint8_t)lrintf(o.style.color[k] * 255.0f);
    mts_lod plain;
    if (mts_lod_init(&plain, &g_cow, MTS_LOD_AT_FULL, &err) == MTS_OK) {
        grey = renderer_for(t, &plain, &o);
        mts_lod_free(&plain);
    }
    r = renderer_for(t, &lod, &o);
    if (!r || !grey || !draw_and_read(t, r, &f[0], NULL) || !draw_and_read(t, grey, &f[1], NULL))
        goto done;
    int m = max_channel_diff(&f[0], &f[1]);
    fprintf(stderr, "  colours equal to the grey: largest difference %d\n", m);
    CHECKF(t, m <= 1, "colours of the grey's values differ from the grey by %d", m);
    mts_render_options strips = o;
    strips.style.color_by_strip = 1;
    mts_render_set_style(r, &strips.style);
    mts_render_set_style(grey, &strips.style);
    if (!draw_and_read(t, r, &f[2], NULL) || !draw_and_read(t, grey, &f[3], NULL))
        goto done;
    CHECKF(t, pixels_differing(&f[2], &f[3], 0) == 0, "by strip: %u pixels differ",
           pixels_differing(&f[2], &f[3], 0));
    CHECK(t, saturated(&f[2]) > SIDE * SIDE / 20);
done:
    mts_renderer_destroy(grey);
    mts_renderer_destroy(r);
    mts_lod_free(&lod);
    free(ccow.colors);
    free(f);
}

/* What an uncoloured model sends to GL is what it always was -- 24 bytes a
 * vertex, a 24-byte-a-vertex buffer, 16 bytes a morphing vertex -- and a
 * coloured one adds 4 a vertex (and 4 a morphing vertex); colours are asked
 * for where the layout says there are some. */
static void test_colors_upload_bytes(mts_test *t)
{
    NEED_CONTEXT(t);
    mts_error err = {0};
    mts_render_options o;
    options(&o);
    mts_model ccow;
    if (!colored_cow(&ccow)) {
        CHECK(t, 0);
        return;
    }
    const uint32_t n = g_cow.vertex_count, nb = g_cow.base_vertex_count;
    const uint64_t cap = n < 65536 ? n : 65536; /* the buffer's first room */
    const mts_model *models[2] = {&g_cow, &ccow};
    for (int c = 0; c < 2; c++) {
        mts_lod lod;
        if (mts_lod_init(&lod, models[c], MTS_LOD_AT_FULL, &err) != MTS_OK) {
            CHECKF(t, 0, "%s", err.msg);
            continue;
        }
        mts_renderer *r = renderer_for(t, &lod, &o);
        if (r) {
            const uint64_t size = c ? 28 : 24;
            mts_render_stats st;
            mts_render_get_stats(r, &st);
            CHECKF(t, st.colors == c && st.vertex_bytes_uploaded == size * n &&
                          st.vertex_buffer_bytes == size * cap,
                   "%s: %llu bytes uploaded, buffer %llu, for %u vertices",
                   c ? "coloured" : "grey", (unsigned long long)st.vertex_bytes_uploaded,
                   (unsigned long long)st.vertex_buffer_bytes, n);
            CHECK(t, mts_render_set_morph(r, nb, 10, ccow.positions, ccow.normals, ccow.colors,
                                          &err) == MTS_OK);
            mts_render_get_stats(r, &st);
            CHECKF(t, st.morph_bytes_uploaded == (c ? 20u : 16u) * 10u, "%s morph: %llu bytes",
                   c ? "coloured" : "grey", (unsigned long long)st.morph_bytes_uploaded);
            if (c) { /* the colours may not be left out */
                CHECK(t, mts_render_append_vertices(r, 0, 1, ccow.positions, ccow.normals, NULL,
                                                    &err) == MTS_ERR_ARG);
                CHECK(t, mts_render_set_morph(r, nb, 1, ccow.positions, ccow.normals, NULL,
                                              &err) == MTS_ERR_ARG);
            }
        }
        mts_renderer_destroy(r);
        mts_lod_free(&lod);
    }
    free(ccow.colors);
}

/* Geomorph colours on the GPU: base vertices blue, every split's vertex
 * red, unlit. The morph from the base to the full level starts each new
 * vertex at its ancestor in the base, blue: the first frame has no red; at
 * t = 0.5 each morphing vertex is half red, half blue, so no pixel is
 * redder than that, and many are about that; at t = 1 the reds are full. */
static void test_colors_morph(mts_test *t)
{
    NEED_CONTEXT(t);
    mts_error err = {0};
    mts_model ccow = g_cow;
    const uint32_t n = g_cow.vertex_count, nb = g_cow.base_vertex_count;
    ccow.colors = malloc((size_t)n * 3);
    ccow.flags |= MTS_MODEL_COLORS;
    float *from = malloc((size_t)(n - nb) * 6 * sizeof *from);
    uint8_t *from_colors = malloc((size_t)(n - nb) * 3);
    frame *f = calloc(3, sizeof *f);
    mts_lod lod;
    int have_lod = 0;
    mts_renderer *r = NULL;
    if (!ccow.colors || !from || !from_colors || !f) {
        CHECK(t, 0);
        goto done;
    }
    for (uint32_t i = 0; i < n; i++) {
        uint8_t *c = ccow.colors + 3 * (size_t)i;
        c[0] = i < nb ? 0 : 255;
        c[1] = 0;
        c[2] = i < nb ? 255 : 0;
    }
    /* every new vertex from its nearest ancestor in the base, as morph.c does */
    uint32_t *anc = malloc((size_t)(n - nb) * sizeof *anc);
    if (!anc) {
        CHECK(t, 0);
        goto done;
    }
    for (uint32_t i = 0; i < n - nb; i++) {
        uint32_t p = g_cow.parents[i];
        anc[i] = p < nb ? p : anc[p - nb];
        memcpy(from + 3 * (size_t)i, g_cow.positions + 3 * (size_t)anc[i], 12);
        memcpy(from + 3 * ((size_t)(n - nb) + i), g_cow.normals + 3 * (size_t)anc[i], 12);
        memcpy(from_colors + 3 * (size_t)i, ccow.colors + 3 * (size_t)anc[i], 3);
    }
    free(anc);
    have_lod = mts_lod_init(&lod, &ccow, MTS_LOD_AT_FULL, &err) == MTS_OK;
    CHECKF(t, have_lod, "%s", err.msg);
    mts_render_options o;
    options(&o);
    o.style.ambient = 1;
    if (!have_lod || !(r = renderer_for(t, &lod, &o)))
        goto done;
    CHECKF(t, mts_render_set_morph(r, nb, n - nb, from, from + 3 * (size_t)(n - nb), from_colors,
                                   &err) == MTS_OK,
           "%s", err.msg);
    const float ts[3] = {0, 0.5f, 1};
    int max_r[3] = {0}, max_b_off[3] = {0};
    uint32_t near_half = 0, full_red = 0;
    for (int k = 0; k < 3; k++) {
        mts_render_set_morph_t(r, ts[k]);
        if (!draw_and_read(t, r, &f[k], k == 1 ? "cow_colors_morph50" : NULL))
            goto done;
        for (uint32_t i = 0; i < SIDE * SIDE; i++) {
            const uint8_t *p = f[k].px + 4 * i;
            if (!mts_test_pixel_differs(p, f[k].px, 2))
                continue;
            max_r[k] = p[0] > max_r[k] ? p[0] : max_r[k];
            int off = abs((int)p[0] + (int)p[2] - 255);
            max_b_off[k] = off > max_b_off[k] ? off : max_b_off[k];
            near_half += k == 1 && p[0] >= 100;
            full_red += k == 2 && p[0] >= 200;
        }
    }
    fprintf(stderr, "  morph colours: most red %d at t 0, %d at t 0.5 (%u pixels of 100 or "
                    "more), %d at t 1 (%u of 200 or more); r + b off 255 by %d, %d, %d\n",
            max_r[0], max_r[1], near_half, max_r[2], full_red, max_b_off[0], max_b_off[1],
            max_b_off[2]);
    CHECKF(t, max_r[0] <= 2, "t 0: red %d (the base is blue)", max_r[0]);
    CHECKF(t, max_r[1] >= 120 && max_r[1] <= 131 && near_half > SIDE * SIDE / 50,
           "t 0.5: red at most %d, %u pixels of 100 or more", max_r[1], near_half);
    CHECKF(t, max_r[2] >= 250 && full_red > SIDE * SIDE / 50, "t 1: red at most %d", max_r[2]);
    for (int k = 0; k < 3; k++)
        CHECKF(t, max_b_off[k] <= 3, "t %.1f: r + b off 255 by %d", ts[k], max_b_off[k]);
done:
    mts_renderer_destroy(r);
    if (have_lod)
        mts_lod_free(&lod);
    free(ccow.colors);
    free(from);
    free(from_colors);
    free(f);
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
    RUN(&t, test_colors_match_reference);
    RUN(&t, test_colors_shade_as_grey);
    RUN(&t, test_colors_upload_bytes);
    RUN(&t, test_colors_morph);

    if (g_ctx && mts_render_context_make_current(g_ctx, NULL) == MTS_OK)
        mts_drawmodes_free(&g_dm);
    mts_render_context_destroy(g_ctx);
    if (g_cow_ok)
        mts_model_free(&g_cow);
    mts_mesh_free(&g_mesh);
    return mts_test_end(&t);
}
