/* A coloured model end to end, as a user runs it: tests/data/cow_colors.ply
 * built by mts-build, streamed over loopback by mts-server, drawn by
 * mts-client headless:
 *   - --json says colors true, and the run sent GL 4 bytes a vertex more
 *     than the same run with --no-colors (which says colors false);
 *   - its PNG, at the full level and at level 300, is the picture this
 *     process draws of the same stream's model (mts_stream_build of the
 *     model file: the positions and colours the client decodes) through the
 *     same view: within 8 a channel in under 0.1% of the pixels;
 *   - the colours show: most of the cow is saturated, while --no-colors
 *     draws the grey, with none.
 * Skips, naming the EGL error, where there is no EGL (MTS_TEST_REQUIRE_EGL=1
 * makes that a failure). */
#include <png.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "clock.h"
#include "modelfile.h"
#include "stream.h"
#include "test.h"
#include "test_gl.h"
#include "test_proc.h"
#include "view.h"

#define SIDE 512u /* mts-client's default frame */

static char bin_dir[512], tmp_dir[512], models_dir[600], listen_addr[64];
static mts_render_context *g_ctx;
static mts_error g_ctx_err;
static mts_model g_model; /* the stream's model, as the client decodes it */
static int g_model_ok;

/* An RGBA8 picture of SIDE x SIDE, top row first. */
typedef struct picture {
    uint8_t px[SIDE * SIDE * 4];
} picture;

static int read_png(const char *path, picture *p)
{
    png_image im;
    memset(&im, 0, sizeof im);
    im.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&im, path))
        return 0;
    im.format = PNG_FORMAT_RGBA;
    int ok = im.width == SIDE && im.height == SIDE &&
             png_image_finish_read(&im, NULL, p->px, 0, NULL);
    png_image_free(&im);
    return ok;
}

/* Foreground pixels whose channels span more than 40 (the grey spans 23 at
 * full light), and all foreground pixels. */
static uint32_t saturated(const picture *p, uint32_t *foreground)
{
    uint32_t n = 0, fg = 0;
    for (uint32_t i = 0; i < SIDE * SIDE; i++) {
        const uint8_t *q = p->px + 4 * i;
        if (!mts_test_pixel_differs(q, p->px, 2))
            continue;
        fg++;
        int mx = q[0], mn = q[0];
        for (int c = 1; c < 3; c++) {
            mx = q[c] > mx ? q[c] : mx;
            mn = q[c] < mn ? q[c] : mn;
        }
        n += mx - mn > 40;
    }
    *foreground = fg;
    return n;
}

/* The stream's model at `level`, drawn here as mts-client draws it: the
 * default options, flat shading where the model has no normals, a view
 * with the model's colours. */
static int reference(mts_test *t, uint32_t level, picture *p)
{
    mts_error err = {0};
    mts_lod lod;
    if (mts_lod_init(&lod, &g_model, MTS_LOD_AT_FULL, &err) != MTS_OK) {
        CHECKF(t, 0, "lod: %s", err.msg);
        return 0;
    }
    mts_render_options ro;
    mts_render_options_default(&ro);
    ro.style.flat_shading = !(g_model.flags & MTS_MODEL_NORMALS_GIVEN);
    mts_follow_source src = mts_follow_source_of_model(&lod, &g_model);
    mts_view v;
    int ok = mts_view_create(&v, g_ctx, &ro, &src, NULL, &err) == MTS_OK;
    if (ok) {
        ok = v.colors && mts_view_sync(&v, &src, level, 0, &err) == MTS_OK &&
             mts_view_draw(&v, &err) == MTS_OK &&
             mts_render_read_rgba(v.renderer, p->px, &err) == MTS_OK;
        mts_view_free(&v);
    }
    CHECKF(t, ok, "reference at level %u: %s", level, err.msg);
    mts_lod_free(&lod);
    return ok;
}

/* mts-client's run of cow_colors with `args`: its --json line in json. */
static int client(mts_test *t, const char *args, char *json, size_t size)
{
    char cmd[2000];
    /* LeakSanitizer's exit-time scan crashes on llvmpipe's threads (see
     * test_e2e's PNG case): the client's leaks are checked elsewhere */
    snprintf(cmd, sizeof cmd,
             "ASAN_OPTIONS=detect_leaks=0 %s/mts-client %s cow_colors --json --quiet %s",
             bin_dir, listen_addr, args);
    int rc = mts_test_run(cmd, json, size);
    CHECKF(t, rc == 0, "%s: %s", cmd, json);
    return rc == 0;
}

static void test_client_draws_colors(mts_test *t)
{
    MTS_TEST_NEED_GL(t, g_ctx, g_ctx_err, g_model_ok);
    picture *p = calloc(3, sizeof *p);
    if (!p) {
        CHECK(t, 0);
        return;
    }
    const uint32_t levels[2] = {g_model.level_count, 300};
    char json[2][8192], args[1000], png[2][700];
    for (int k = 0; k < 2; k++) {
        snprintf(png[k], sizeof png[k], "%s/client_colors_L%u.png", tmp_dir, levels[k]);
        snprintf(args, sizeof args, "--level %u --png %s", levels[k], png[k]);
        if (!client(t, args, json[k], sizeof json[k]))
            goto done;
        CHECKF(t, strstr(json[k], "\"colors\":true") && strstr(json[k], "\"complete\":true"),
               "%s", json[k]);
        if (!read_png(png[k], &p[0]) || !reference(t, levels[k], &p[1])) {
            CHECKF(t, 0, "level %u: no picture (%s)", levels[k], png[k]);
            goto done;
        }
        uint32_t d = mts_test_pixels_differing(p[0].px, p[1].px, SIDE * SIDE, 8);
        int most = 0;
        for (uint32_t i = 0; i < SIDE * SIDE * 4; i++)
            if (i % 4 != 3 && abs((int)p[0].px[i] - (int)p[1].px[i]) > most)
                most = abs((int)p[0].px[i] - (int)p[1].px[i]);
        uint32_t fg, sat = saturated(&p[0], &fg);
        fprintf(stderr, "  level %u: mts-client's PNG against the model drawn here: %u pixels "
                        "over 8, largest difference %d; %u of %u foreground pixels saturated\n",
                levels[k], d, most, sat, fg);
        CHECKF(t, d < SIDE * SIDE / 1000, "level %u: %u pixels differ", levels[k], d);
        CHECKF(t, fg > SIDE * SIDE / 20 && sat > fg / 3, "level %u: %u of %u saturated",
               levels[k], sat, fg);
    }
    /* grey on request: the same run less the colours' 4 bytes a vertex */
    char grey_png[700], grey_json[8192];
    snprintf(grey_png, sizeof grey_png, "%s/client_colors_grey.png", tmp_dir);
    snprintf(args, sizeof args, "--no-colors --png %s", grey_png);
    if (!client(t, args, grey_json, sizeof grey_json))
        goto done;
    CHECKF(t, strstr(grey_json, "\"colors\":false"), "%s", grey_json);
    long up = mts_test_json_long(json[0], "gl_upload_bytes"),
         grey_up = mts_test_json_long(grey_json, "gl_upload_bytes");
    long fin = mts_test_json_long(json[0], "gl_final_bytes"),
         grey_fin = mts_test_json_long(grey_json, "gl_final_bytes");
    fprintf(stderr, "  GL uploads: %ld bytes with colours, %ld grey (%u vertices)\n", up, grey_up,
            g_model.vertex_count);
    CHECKF(t, up - grey_up == 4l * g_model.vertex_count &&
                  fin - grey_fin == 4l * g_model.vertex_count,
           "uploads %ld and %ld, final %ld and %ld, for %u vertices", up, grey_up, fin, grey_fin,
           g_model.vertex_count);
    uint32_t fg;
    if (read_png(grey_png, &p[2]))
        CHECKF(t, saturated(&p[2], &fg) < fg / 100 && fg > SIDE * SIDE / 20,
               "--no-colors: %u of %u pixels saturated", saturated(&p[2], &fg), fg);
    else
        CHECKF(t, 0, "no picture %s", grey_png);
done:
    free(p);
}

int main(int argc, char **argv)
{
    (void)argc;
    mts_test t = {0};
    mts_test_bin_dir(argv[0], bin_dir, sizeof bin_dir);
    snprintf(tmp_dir, sizeof tmp_dir, "%s", mts_test_tmpdir());
    snprintf(models_dir, sizeof models_dir, "%s/client_colors_models", tmp_dir);
    char cmd[2000], out[8192];
    snprintf(cmd, sizeof cmd,
             "mkdir -p %s && %s/mts-build tests/data/cow_colors.ply -o %s/cow_colors.mtsm "
             "--quiet",
             models_dir, bin_dir, models_dir);
    if (mts_test_run(cmd, out, sizeof out) != 0) {
        fprintf(stderr, "cannot build cow_colors: %s\n", out);
        return 1;
    }
    /* the stream the server sends, built here from the same file */
    mts_error err = {0};
    mts_model m;
    char path[700];
    snprintf(path, sizeof path, "%s/cow_colors.mtsm", models_dir);
    if (mts_modelfile_load(path, &m, &err) == MTS_OK) {
        mts_stream s;
        mts_stream_options so = {0};
        if (mts_stream_build(&m, "cow_colors", &so, &s, &err) == MTS_OK) {
            g_model = s.model; /* taken over: the rest of the stream goes */
            memset(&s.model, 0, sizeof s.model);
            mts_stream_free(&s);
            g_model_ok = (g_model.flags & MTS_MODEL_COLORS) && g_model.colors;
            if (!g_model_ok)
                snprintf(err.msg, sizeof err.msg, "the stream's model has no colours");
        }
        mts_model_free(&m);
    }
    if (!g_model_ok)
        fprintf(stderr, "  cow_colors: %s\n", err.msg);
    if (mts_render_context_create_headless(&g_ctx, &g_ctx_err) != MTS_OK)
        g_ctx = NULL;

    char log[700];
    snprintf(log, sizeof log, "%s/client_colors_server.log", tmp_dir);
    mts_test_server sv = {0};
    int up = mts_test_ws_server_start(&sv, bin_dir, models_dir, NULL, log, 60);
    snprintf(listen_addr, sizeof listen_addr, "127.0.0.1:%d", sv.port);
    up = up && mts_test_wait_models(bin_dir, listen_addr, "cow_colors", 600, out, sizeof out);
    if (!up) {
        mts_test_read_file(log, out, sizeof out);
        fprintf(stderr, "the server did not come up: %s\n", out);
        t.failed = 1;
    } else {
        RUN(&t, test_client_draws_colors);
    }
    /* a clean stop exits 0; a sanitizer's report would not */
    if (sv.pid > 0 && mts_test_stop(sv.pid) != 0) {
        fprintf(stderr, "  FAIL: mts-server did not exit cleanly (%s)\n", log);
        t.failed++;
    }
    mts_render_context_destroy(g_ctx);
    if (g_model_ok || g_model.positions)
        mts_model_free(&g_model);
    return mts_test_end(&t);
}
