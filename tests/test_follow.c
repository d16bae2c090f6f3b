/* The follower (client/follow.h) on the cow, streamed: at several levels,
 * up and down, its packed arrays are what the view's renderer uploads and
 * draws (its packed buffer read back from GL), the browser page's path
 * (web/mts_web.c, compiled natively here, fed the same bytes) hands its
 * WebGL2 side the same indices, per-strip ranges, colours and figures, and
 * each per-strip range holds that strip as the runtime has it. A small step
 * goes through the renderer's changed-strip path, not a full upload.
 *
 * Skips, naming the EGL error, where there is no EGL (MTS_TEST_REQUIRE_EGL=1
 * makes that a failure). */
#include <GLES3/gl3.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "build.h"
#include "camera.h"
#include "follow.h"
#include "mesh.h"
#include "render.h"
#include "render_internal.h"
#include "stream.h"
#include "test.h"
#include "test_gl.h"
#include "view.h"

/* the page's C, as emscripten builds it (without __EMSCRIPTEN__ its entry
 * points are plain functions) */
#include "../web/mts_web.c"

static mts_render_context *g_ctx;
static mts_error g_ctx_err;
static mts_stream g_stream;
static int g_cow_ok;

#define NEED_CONTEXT(t) MTS_TEST_NEED_GL(t, g_ctx, g_ctx_err, g_cow_ok)

/* What a connection asking for the full model is sent. */
static void connection_bytes(mts_buf *out)
{
    mts_error err = {0};
    uint32_t stop = mts_stream_stop_level(&g_stream, MTS_STOP_FULL, 0);
    mts_stream_put_model_info(&g_stream, stop, out);
    size_t off, len;
    if (mts_stream_range(&g_stream, 0, stop, &off, &len, &err) != MTS_OK)
        return;
    mts_buf_put(out, g_stream.bytes + off, len);
    mts_stream_put_end(&g_stream, stop, (uint32_t)out->size, out);
}

/* The renderer's packed buffer, read back from GL, widened to 32 bits. */
static uint32_t *read_packed(mts_test *t, mts_renderer *r, uint64_t *count)
{
    mts_error err = {0};
    mts__render_frame f;
    unsigned ibo = 0;
    int u16 = 0;
    *count = 0;
    if (mts__render_frame_begin(r, 0, 0, &f, &err) != MTS_OK) {
        CHECKF(t, 0, "frame: %s", err.msg);
        return NULL;
    }
    mts_result rc = mts__render_packed(r, 0, &ibo, count, &u16, &err);
    uint32_t *out = malloc((size_t)(*count ? *count : 1) * sizeof *out);
    if (rc == MTS_OK && out && *count) {
        size_t esize = u16 ? 2u : 4u;
        glBindBuffer(GL_COPY_READ_BUFFER, ibo);
        const void *p = glMapBufferRange(GL_COPY_READ_BUFFER, 0, (GLsizeiptr)(*count * esize),
                                         GL_MAP_READ_BIT);
        if (p) {
            for (uint64_t i = 0; i < *count; i++)
                out[i] = u16 ? ((const uint16_t *)p)[i] : ((const uint32_t *)p)[i];
            glUnmapBuffer(GL_COPY_READ_BUFFER);
        } else {
            rc = MTS_ERR_INTERNAL;
            mts_error_set(&err, rc, "glMapBufferRange: 0x%x", glGetError());
        }
        glBindBuffer(GL_COPY_READ_BUFFER, 0);
    }
    mts__render_frame_end(r, &f, 0, 0, 0, NULL);
    CHECKF(t, rc == MTS_OK && out, "packed buffer: %s", err.msg);
    if (rc != MTS_OK) {
        free(out);
        return NULL;
    }
    return out;
}

/* The follower's packed arrays against the runtime they came from. */
static void check_per_strip(mts_test *t, const mts_follow *f, uint32_t level)
{
    const mts_follow_packed *p = &f->packed;
    const uint32_t *idx = p->indices;
    uint32_t k = 0;
    for (uint32_t s = 0; s < f->lod->strip_count; s++) {
        uint32_t len;
        const uint32_t *strip = mts_lod_strip(f->lod, s, &len);
        if (len < 3)
            continue;
        float rgb[3];
        mts_camera_strip_color(s, rgb);
        int ok = k < p->strips && p->strip_length[k] == len &&
                 (uint64_t)p->strip_first[k] + len <= p->count && p->strip_first[k] % 2 == 0 &&
                 memcmp(idx + p->strip_first[k], strip, (size_t)len * 4) == 0 &&
                 memcmp(p->strip_rgb + 3 * (size_t)k, rgb, sizeof rgb) == 0;
        CHECKF(t, ok, "level %u: strip %u (drawn %u) is not where the packing says", level, s,
               k);
        if (!ok)
            return;
        k++;
    }
    CHECKF(t, k == p->strips, "level %u: %u strips drawn, packed %u", level, k, p->strips);
}

static void test_follow_view_and_page_agree(mts_test *t)
{
    NEED_CONTEXT(t);
    mts_error err = {0};
    mts_buf bytes = {0};
    connection_bytes(&bytes);

    /* native: a stream client fed the bytes, a view of its own runtime */
    mts_stream_client c;
    mts_stream_client_init(&c);
    int got = 0;
    mts_stream_event ev;
    CHECKF(t, mts_stream_client_feed(&c, bytes.data, bytes.size, &err) == MTS_OK, "%s", err.msg);
    while ((got = mts_stream_client_next(&c, &ev, &err)) > 0)
        ;
    CHECKF(t, got == 0 && c.have_lod, "native stream: %s", err.msg);

    /* the page: the same bytes through its own entry points */
    mts_web *w = mts_web_create();
    CHECK(t, w && mts_web_feed(w, bytes.data, bytes.size) == MTS_OK && mts_web_state(w) == 3);
    CHECKF(t, strcmp(mts_web_checksum(w), mts_web_server_checksum(w)) == 0,
           "page checksum %s, server %s", mts_web_checksum(w), mts_web_server_checksum(w));

    mts_render_options ro;
    memset(&ro, 0, sizeof ro);
    ro.width = ro.height = 128;
    mts_view v;
    mts_view_options vo = {1, 0, 0};
    mts_follow_source src = mts_follow_source_of_stream(&c);
    if (!w || !c.have_lod || mts_view_create(&v, g_ctx, &ro, &src, &vo, &err) != MTS_OK) {
        CHECKF(t, 0, "view: %s", err.msg);
        goto out;
    }
    const uint32_t n = c.lod.model->level_count;
    const uint32_t levels[] = {0, n / 8, n / 2, n, n / 3, n / 3 + 2, 1, n};
    for (size_t i = 0; i < sizeof levels / sizeof *levels; i++) {
        const uint32_t l = levels[i];
        src = mts_follow_source_of_stream(&c);
        mts_render_stats rs;
        if (mts_view_sync(&v, &src, l, 0, &err) != MTS_OK || mts_view_draw(&v, &err) != MTS_OK ||
            mts_follow_pack(&v.follow, &err) != MTS_OK) {
            CHECKF(t, 0, "level %u: %s", l, err.msg);
            break;
        }
        mts_render_get_stats(v.renderer, &rs);
        if (i == 5) /* two levels up: the changed strips only */
            CHECKF(t, !rs.last_update_full && rs.last_update_strips > 0 &&
                          rs.last_update_strips < v.follow.lod->strip_count,
                   "a step of 2 levels uploads %u strips (full %d) of %u",
                   rs.last_update_strips, rs.last_update_full, v.follow.lod->strip_count);
        const mts_follow_packed *p = &v.follow.packed;
        CHECKF(t, v.follow.lod->level == l && v.follow.shown.level == l, "at %u, asked %u",
               v.follow.lod->level, l);
        check_per_strip(t, &v.follow, l);

        /* what the view's renderer uploaded and drew */
        uint64_t gl_count = 0;
        uint32_t *gl = read_packed(t, v.renderer, &gl_count);
        CHECKF(t, gl && gl_count == p->count && rs.last_draw_indices == p->count &&
                      memcmp(gl, p->indices, (size_t)p->count * 4) == 0,
               "level %u: the renderer's packed buffer (%llu indices, drew %llu) is not the "
               "follower's (%llu)",
               l, (unsigned long long)gl_count, (unsigned long long)rs.last_draw_indices,
               (unsigned long long)p->count);
        free(gl);

        /* the page's arrays */
        if (mts_web_show(w, l, 0) != MTS_OK) {
            CHECKF(t, 0, "page at %u: %s", l, mts_web_error(w));
            break;
        }
        int same = mts_web_shown_level(w) == l && mts_web_index_count(w) == p->count &&
                   memcmp(mts_web_indices(w), p->indices, (size_t)p->count * 4) == 0 &&
                   mts_web_strip_count(w) == p->strips &&
                   memcmp(mts_web_strip_first(w), p->strip_first, (size_t)p->strips * 4) == 0 &&
                   memcmp(mts_web_strip_length(w), p->strip_length, (size_t)p->strips * 4) == 0 &&
                   memcmp(mts_web_strip_colors(w), p->strip_rgb, (size_t)p->strips * 12) == 0 &&
                   mts_web_shown_triangles(w) == v.follow.shown.triangles &&
                   mts_web_shown_strips(w) == v.follow.shown.strips;
        CHECKF(t, same,
               "level %u: the page (level %u, %u indices, %u strips drawn, %u triangles) is not "
               "the view (%llu indices, %u strips drawn, %u triangles)",
               l, mts_web_shown_level(w), mts_web_index_count(w), mts_web_strip_count(w),
               mts_web_shown_triangles(w), (unsigned long long)p->count, p->strips,
               v.follow.shown.triangles);
    }
    mts_view_free(&v);
out:
    mts_web_destroy(w);
    mts_stream_client_free(&c);
    mts_buf_free(&bytes);
}

/* The page's geomorphs: the follower with the page's options moves as the
 * page does, range for range. */
static void test_follow_page_morphs(mts_test *t)
{
    if (!g_cow_ok) {
        CHECKF(t, 0, "the cow did not build");
        return;
    }
    mts_error err = {0};
    mts_buf bytes = {0};
    connection_bytes(&bytes);
    mts_stream_client c;
    mts_stream_client_init(&c);
    mts_stream_event ev;
    int got = 0;
    CHECK(t, mts_stream_client_feed(&c, bytes.data, bytes.size, &err) == MTS_OK);
    while ((got = mts_stream_client_next(&c, &ev, &err)) > 0)
        ;
    mts_web *w = mts_web_create();
    CHECK(t, w && mts_web_feed(w, bytes.data, bytes.size) == MTS_OK);
    mts_web_set_morph_ms(w, 100);
    mts_follow f;
    mts_follow_source src = mts_follow_source_of_stream(&c);
    mts_follow_options fo = {1, 100, 1};
    if (got != 0 || !w || mts_follow_init(&f, &src, &fo, &err) != MTS_OK) {
        CHECKF(t, 0, "%s", err.msg);
        goto out;
    }
    const uint32_t n = c.lod.model->level_count;
    /* the first level at once, then up, half-way, down */
    const struct {
        uint32_t level;
        double ms;
    } steps[] = {{n / 4, 0}, {n / 2, 10}, {n / 2, 60}, {n / 2, 120}, {n / 5, 130}, {n / 5, 180},
                 {n / 5, 240}};
    for (size_t i = 0; i < sizeof steps / sizeof *steps; i++) {
        if (mts_follow_sync(&f, &src, steps[i].level, steps[i].ms, NULL, &err) != MTS_OK ||
            mts_follow_pack(&f, &err) != MTS_OK || mts_web_show(w, steps[i].level, steps[i].ms)) {
            CHECKF(t, 0, "step %zu: %s %s", i, err.msg, mts_web_error(w));
            break;
        }
        mts_follow_clear_changed(&f);
        int same = mts_web_shown_level(w) == f.lod->level &&
                   mts_web_morph_active(w) == f.morph.active && mts_web_morph_t(w) == f.morph.t &&
                   mts_web_morph_first(w) == f.morph.first &&
                   mts_web_morph_count(w) == f.morph.count &&
                   mts_web_morph_serial(w) == f.morph_serial &&
                   (!f.morph.count || memcmp(mts_web_morph_from(w), f.morph.from,
                                             (size_t)f.morph.count * 24) == 0) &&
                   mts_web_index_count(w) == f.packed.count &&
                   memcmp(mts_web_indices(w), f.packed.indices, (size_t)f.packed.count * 4) == 0;
        CHECKF(t, same, "step %zu (level %u at %.0f ms): the page at %u (t %.2f), the follower "
               "at %u (t %.2f)", i, steps[i].level, steps[i].ms, mts_web_shown_level(w),
               mts_web_morph_t(w), f.lod->level, f.morph.t);
    }
    CHECK(t, f.morph_serial > 0 && !f.morph.active && f.lod->level == n / 5);
    mts_follow_free(&f);
out:
    mts_web_destroy(w);
    mts_stream_client_free(&c);
    mts_buf_free(&bytes);
}

int main(void)
{
    mts_test t = {0};
    mts_error err = {0};
    mts_mesh mesh;
    if (mts_mesh_load("tests/data/cow.off", NULL, &mesh, NULL, &err) == MTS_OK) {
        mts_model m;
        if (mts_build_model(&mesh, "tests/data/cow.off", NULL, &m, NULL, &err) == MTS_OK) {
            g_cow_ok = mts_stream_build(&m, "cow", NULL, &g_stream, &err) == MTS_OK;
            mts_model_free(&m);
        }
        mts_mesh_free(&mesh);
    }
    if (!g_cow_ok)
        fprintf(stderr, "  cow: %s\n", err.msg);
    if (mts_render_context_create_headless(&g_ctx, &g_ctx_err) != MTS_OK)
        g_ctx = NULL;
    RUN(&t, test_follow_view_and_page_agree);
    RUN(&t, test_follow_page_morphs);
    mts_render_context_destroy(g_ctx);
    if (g_cow_ok)
        mts_stream_free(&g_stream);
    return mts_test_end(&t);
}
