/* mts-bench-stream: the streaming figures of `make bench` for each
 * mesh given: full-stream bytes beside Draco single-rate of the same full mesh
 * on the same grid (encoded here, in the same process), the raw file and the
 * .mtsm; bytes a client needs for 10%, 50% and 100% of the triangles; the
 * client's apply throughput (splits/s) decoding in memory, without GL upload
 * and, where EGL works, with it; and the draw-path table (every draw mode against the meshopt-optimized list at 100/50/25/10/5/1 % of
 * the vertices, under "draw_path" in the JSON). Time to first frame over
 * loopback is measured by bench/run.sh with the real server and client.
 * Options for the table alone: --draw-only, --fractions F1,F2,..., --rounds N,
 * --side PIXELS. --colors: only the colours' table (docs/colors.md). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include "drawmodes.h"
#include "bench_common.h"
#include "build.h"
#include "cli.h"
#include "draco.h"
#include "mesh.h"
#include "modelfile.h"
#include "render.h"
#include "stream.h"
#include "view.h"

#include <meshoptimizer.h>

#include "../tests/color_field.h"

/* Decodes and applies a whole connection's bytes; with a context, keeps a
 * view (the client's path to GL: client/view.h) in step at each batch, as
 * mts-client does, without drawing. Returns seconds (the view's creation at
 * the base mesh, a shader compile, left out), 0 on error. */
static double apply_all(const mts_buf *b, mts_render_context *ctx, mts_error *err)
{
    mts_stream_client c;
    mts_stream_client_init(&c);
    mts_view view;
    int have_view = 0;
    double t0 = cli_now(), t_create = 0;
    int ok = mts_stream_client_feed(&c, b->data, b->size, err) == MTS_OK, got;
    mts_stream_event ev;
    while (ok && (got = mts_stream_client_next(&c, &ev, err)) != 0) {
        ok = got > 0;
        if (!ok || !ctx || (ev != MTS_EV_BASE && ev != MTS_EV_BATCH))
            continue;
        mts_follow_source src = mts_follow_source_of_stream(&c);
        if (!have_view) {
            double tc = cli_now();
            mts_render_options ro;
            mts_render_options_default(&ro);
            ro.style.flat_shading = !(c.info.flags & MTS_INFO_NORMALS);
            ok = mts_view_create(&view, ctx, &ro, &src, NULL, err) == MTS_OK;
            have_view = ok;
            t_create = cli_now() - tc;
        }
        ok = ok && mts_view_sync(&view, &src, MTS_VIEW_NEWEST, 0, err) == MTS_OK;
    }
    double t = cli_now() - t0 - t_create;
    if (have_view)
        mts_view_free(&view);
    mts_stream_client_free(&c);
    return ok ? t : 0;
}

/* Medians of 5 runs of apply_all on a connection's bytes b, without GL
 * upload and (with a context) with it; *gl stays 0 without one. */
static void apply_median(const mts_buf *b, mts_render_context *ctx, double *no_gl, double *gl,
                         mts_error *err)
{
    double t[5] = {0}, tg[5] = {0};
    apply_all(b, NULL, err); /* warm-up: first-touch page faults are not decoding */
    for (int k = 0; k < 5; k++)
        t[k] = apply_all(b, NULL, err);
    if (t[0] == 0)
        printf("%-14s apply FAILED: %s\n", "", err->msg);
    qsort(t, 5, sizeof(double), bench_cmp_double);
    *no_gl = t[2];
    *gl = 0;
    if (!ctx)
        return;
    for (int k = 0; k < 5; k++)
        tg[k] = apply_all(b, ctx, err);
    qsort(tg, 5, sizeof(double), bench_cmp_double);
    *gl = tg[2];
}

/* Median frame time of n draws in a mode. */
static double frame_ms(mts_renderer *r, mts_drawmodes *dm, mts_drawmode mode, int n,
                       mts_error *err)
{
    double t[32];
    if (n > 32)
        n = 32;
    for (int i = 0; i < n; i++) {
        if (mts_drawmodes_draw(dm, r, mode, err) != MTS_OK)
            return 0;
        mts_render_stats st;
        mts_render_get_stats(r, &st);
        t[i] = st.last_draw_seconds * 1e3;
    }
    qsort(t, (size_t)n, sizeof(double), bench_cmp_double);
    return t[n / 2];
}

typedef struct draw_figures {
    double strips_ms, list_ms, list_opt_ms;
    uint64_t strip_index_bytes, list_index_bytes;
} draw_figures;

/* A renderer of side x side pixels holding m's vertices, shaded as
 * mts-client shades it (flat when the stream has no normals), timed (the
 * draw timings read last_draw_seconds), and lod at m's full level. */
static int full_renderer(mts_render_context *ctx, const mts_model *m, uint32_t side,
                         mts_lod *lod, mts_renderer **r, mts_error *err)
{
    *r = NULL;
    if (mts_lod_init(lod, m, MTS_LOD_AT_FULL, err) != MTS_OK)
        return 0;
    mts_render_options ro;
    mts_render_options_default(&ro);
    ro.timed = 1;
    ro.width = ro.height = side;
    ro.style.flat_shading = !(m->flags & MTS_MODEL_NORMALS_GIVEN);
    mts_render_layout layout;
    mts_render_layout_from_lod(lod, &layout);
    if (mts_renderer_create(ctx, &ro, &layout, r, err) == MTS_OK &&
        mts_render_append_vertices(*r, 0, m->vertex_count, m->positions, m->normals,
                                   m->colors, err) ==
            MTS_OK)
        return 1;
    mts_renderer_destroy(*r);
    *r = NULL;
    mts_lod_free(lod);
    return 0;
}

/* The full level drawn as restart strips, as the plain triangle list of the
 * same triangles (in strip order) and as that list after
 * meshopt_optimizeVertexCache: same vertices, shader and camera. */
static int draw_compare(mts_render_context *ctx, const mts_model *m, draw_figures *f,
                        mts_error *err)
{
    mts_lod lod;
    mts_renderer *r = NULL;
    mts_drawmodes dm = {0};
    uint32_t *list = NULL, *opt = NULL;
    int ok = 0;
    if (!full_renderer(ctx, m, 1024, &lod, &r, err))
        return 0;
    if (mts_render_update_strips(r, &lod, err) != MTS_OK)
        goto done;
    f->strips_ms = frame_ms(r, &dm, MTS_DRAWMODE_JOINED, 21, err);
    mts_strip_stats ss = {0};
    list = malloc(((size_t)m->level_triangles[m->level_count] + 1) * 12);
    opt = malloc(((size_t)m->level_triangles[m->level_count] + 1) * 12);
    if (!list || !opt)
        goto done;
    size_t n = 0;
    for (uint32_t s = 0; s < lod.strip_count; s++) {
        uint32_t len;
        const uint32_t *str = mts_lod_strip(&lod, s, &len);
        mts_strip_stats_add(&ss, str, len);
        for (uint32_t k = 0; k + 2 < len; k++)
            n += 3 * (size_t)mts_strip_window(str, k, list + n);
    }
    f->strip_index_bytes = mts_strip_stats_draw_indices(&ss) * 4;
    f->list_index_bytes = (uint64_t)n * 4;
    if (mts_drawmodes_set_list(&dm, r, list, (uint32_t)n, err) != MTS_OK)
        goto done;
    f->list_ms = frame_ms(r, &dm, MTS_DRAWMODE_LIST, 21, err);
    meshopt_optimizeVertexCache(opt, list, n, m->vertex_count);
    if (mts_drawmodes_set_list(&dm, r, opt, (uint32_t)n, err) != MTS_OK)
        goto done;
    f->list_opt_ms = frame_ms(r, &dm, MTS_DRAWMODE_LIST, 21, err);
    ok = 1;
done:
    free(list);
    free(opt);
    if (r && mts_render_context_make_current(ctx, NULL) == MTS_OK)
        mts_drawmodes_free(&dm);
    mts_renderer_destroy(r);
    mts_lod_free(&lod);
    return ok;
}

/* ---- the draw path ------------------------------------
 * Every draw mode of the renderer and the meshopt-optimized triangle list of
 * the same triangles, at several levels: same renderer (1024x1024, shader,
 * camera, culling, depth), glFinish per frame (mts_render_draw). The modes
 * are measured in rounds, each round drawing every mode in turn (3 warm-up
 * frames, then the median of 11), so a slow spell of the shared machine hits
 * all modes alike; the figure is the median over the rounds and `noise` the
 * largest (max - min) / median of a mode over the rounds. */

#define DT_MAX_ROUNDS 31
static int dt_rounds = 7;
#define DT_FRAMES 11

enum { DT_RESTART, DT_MULTI, DT_PER_STRIP, DT_COMPACT, DT_JOINED, DT_LIST, DT_LIST_OPT, DT_MODES };
static const char *const dt_names[DT_MODES] = {"restart", "multi",  "per_strip", "compact",
                                               "joined",  "list", "list_opt"};
static const mts_drawmode dt_mode[DT_MODES] = {
    MTS_DRAWMODE_RESTART, MTS_DRAWMODE_MULTI, MTS_DRAWMODE_PER_STRIP, MTS_DRAWMODE_COMPACT,
    MTS_DRAWMODE_JOINED,  MTS_DRAWMODE_LIST,  MTS_DRAWMODE_LIST};

static double cpu_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* Median frame ms of DT_FRAMES draws after 3 warm-up draws; the process's
 * CPU ms per frame over them (llvmpipe's threads included: the work done,
 * which other load on a shared machine disturbs far less than the wall
 * time); index bytes read. */
static double dt_frames(mts_renderer *r, mts_drawmodes *dm, mts_drawmode mode, double *cpu_ms,
                        uint64_t *index_bytes, mts_error *err)
{
    double t[DT_FRAMES];
    mts_render_stats st;
    for (int i = 0; i < 3; i++)
        if (mts_drawmodes_draw(dm, r, mode, err) != MTS_OK)
            return -1;
    double c0 = cpu_s();
    for (int i = 0; i < DT_FRAMES; i++) {
        if (mts_drawmodes_draw(dm, r, mode, err) != MTS_OK)
            return -1;
        mts_render_get_stats(r, &st);
        t[i] = st.last_draw_seconds * 1e3;
    }
    *cpu_ms = (cpu_s() - c0) * 1e3 / DT_FRAMES;
    *index_bytes = st.last_draw_index_bytes;
    qsort(t, DT_FRAMES, sizeof(double), bench_cmp_double);
    return t[DT_FRAMES / 2];
}

static double dt_fractions[16] = {1.0, 0.5, 0.25, 0.1, 0.05, 0.01};
static int dt_nf = 6;
static uint32_t dt_side = 1024;

static int draw_table(mts_render_context *ctx, const mts_model *m, const char *name, FILE *jf,
                      int *first_json, mts_error *err)
{
    const double *fractions = dt_fractions;
    const int nf = dt_nf;
    mts_lod lod;
    mts_renderer *r = NULL;
    mts_drawmodes dm = {0};
    uint32_t *list = NULL, *opt = NULL;
    int ok = 0;
    if (!full_renderer(ctx, m, dt_side, &lod, &r, err))
        return 0;
    size_t cap = ((size_t)m->level_triangles[m->level_count] + 1) * 3;
    list = malloc(cap * sizeof *list);
    opt = malloc(cap * sizeof *opt);
    if (!list || !opt)
        goto done;
    printf("%-14s %5s %7s %8s", name, "vert%", "tris", "");
    for (int k = 0; k < DT_MODES; k++)
        printf(" %9s", dt_names[k]);
    printf("  %6s %7s %7s\n", "noise", "j/lopt", "j idx");
    for (int fi = 0; fi < nf; fi++) {
        uint32_t level = mts_model_level_for_fraction(m, fractions[fi]);
        if (mts_lod_set_level(&lod, level, err) != MTS_OK ||
            mts_render_update_strips(r, &lod, err) != MTS_OK)
            goto done;
        mts_lod_clear_changed(&lod);
        size_t n = 0;
        for (uint32_t s = 0; s < lod.strip_count; s++) {
            uint32_t len;
            const uint32_t *str = mts_lod_strip(&lod, s, &len);
            for (uint32_t k = 0; k + 2 < len; k++)
                n += 3 * (size_t)mts_strip_window(str, k, list + n);
        }
        uint32_t nv = m->base_vertex_count + level;
        meshopt_optimizeVertexCache(opt, list, n, nv);
        double ms[DT_MODES][DT_MAX_ROUNDS], cpu[DT_MODES][DT_MAX_ROUNDS];
        uint64_t bytes[DT_MODES] = {0};
        for (int round = 0; round < dt_rounds; round++)
            for (int k = 0; k < DT_MODES; k++) {
                if ((k == DT_LIST || k == DT_LIST_OPT) &&
                    mts_drawmodes_set_list(&dm, r, k == DT_LIST ? list : opt, (uint32_t)n,
                                           err) != MTS_OK)
                    goto done;
                ms[k][round] = dt_frames(r, &dm, dt_mode[k], &cpu[k][round], &bytes[k], err);
                if (ms[k][round] < 0)
                    goto done;
            }
        double med[DT_MODES], cmed[DT_MODES], noise = 0, cnoise = 0;
        for (int k = 0; k < DT_MODES; k++) {
            qsort(ms[k], dt_rounds, sizeof(double), bench_cmp_double);
            qsort(cpu[k], dt_rounds, sizeof(double), bench_cmp_double);
            med[k] = ms[k][dt_rounds / 2];
            cmed[k] = cpu[k][dt_rounds / 2];
            double cspread = cmed[k] > 0 ? (cpu[k][dt_rounds - 1] - cpu[k][0]) / cmed[k] : 0;
            if (cspread > cnoise)
                cnoise = cspread;
            double spread = med[k] > 0 ? (ms[k][dt_rounds - 1] - ms[k][0]) / med[k] : 0;
            if (spread > noise)
                noise = spread;
        }
        uint64_t tris = n / 3;
        printf("%-14s %5.0f %7llu %8s", "", fractions[fi] * 100, (unsigned long long)tris, "ms");
        for (int k = 0; k < DT_MODES; k++)
            printf(" %9.3f", med[k]);
        /* joined's index count against the list's (the same index type) */
        mts_render_stats st;
        mts_render_get_stats(r, &st);
        double jidx = (double)bytes[DT_JOINED] / (nv <= 0xFFFFu ? 2.0 : 4.0);
        printf("  %5.0f%% %7.3f %7.3f\n", noise * 100, med[DT_JOINED] / med[DT_LIST_OPT],
               tris ? jidx / (double)tris : 0);
        printf("%-14s %5s %7s %8s", "", "", "", "cpu ms");
        for (int k = 0; k < DT_MODES; k++)
            printf(" %9.3f", cmed[k]);
        printf("  %5.0f%% %7.3f\n", cnoise * 100, cmed[DT_JOINED] / cmed[DT_LIST_OPT]);
        printf("%-14s %5s %7s %8s", "", "", "", "idx B");
        for (int k = 0; k < DT_MODES; k++)
            printf(" %9llu", (unsigned long long)bytes[k]);
        printf("  %6s %7s %7.3f\n", "", "", n ? jidx / (double)n : 0);
        if (jf) {
            fprintf(jf, "%s\"%s@%g\":{\"level\":%u,\"triangles\":%llu,\"noise\":%.3f,"
                    "\"cpu_noise\":%.3f",
                    *first_json ? "" : ",", name, fractions[fi], level,
                    (unsigned long long)tris, noise, cnoise);
            for (int k = 0; k < DT_MODES; k++)
                fprintf(jf, ",\"%s_ms\":%.4f,\"%s_cpu_ms\":%.4f,\"%s_index_bytes\":%llu",
                        dt_names[k], med[k], dt_names[k], cmed[k], dt_names[k],
                        (unsigned long long)bytes[k]);
            fputs("}", jf);
            *first_json = 0;
        }
    }
    ok = 1;
done:
    free(list);
    free(opt);
    if (r && mts_render_context_make_current(ctx, NULL) == MTS_OK)
        mts_drawmodes_free(&dm);
    mts_renderer_destroy(r);
    mts_lod_free(&lod);
    return ok;
}

/* Where the full stream's bytes go, each part in bytes
 * and in bits a vertex of the full mesh, beside Draco's single-rate total
 * on the same grid; and the first picture (the stream stopped at level 0). */
static void breakdown_table(const mts_stream_breakdown *bd, char (*names)[64], const size_t *draco,
                            const size_t *first, int n, FILE *jf, int *first_json)
{
    if (n == 0)
        return;
    printf("\nWhere the bytes go: the full splits-form stream, bytes and bits a vertex "
           "(of the full mesh)\n");
    static const char *const cols[] = {"capacities", "model info", "base draco", "base strips",
                                       "parent",    "fan code",  "position",   "normal",
                                       "full strips", "rc flush", "framing",  "total",
                                       "draco cl7", "level 0"};
    enum { NC = sizeof cols / sizeof cols[0] };
    printf("%-14s %5s", "model", "");
    for (int c = 0; c < NC; c++)
        printf(" %11s", cols[c]);
    printf("\n");
    if (jf)
        fprintf(jf, "%s\"bytes_breakdown\":{", *first_json ? "" : ",");
    for (int i = 0; i < n; i++) {
        const mts_stream_breakdown *b = &bd[i];
        const double fields = b->parent_bits + b->fan_bits + b->position_bits + b->normal_bits +
                              b->full_strips_bits + b->capacity_bits;
        const double total = (double)(b->info_bytes + b->base_bytes + b->batch_bytes + b->end_bytes);
        double v[NC] = {(double)b->capacity_bytes + b->capacity_bits / 8,
                        (double)b->info_bytes,
                        (double)b->base_draco_bytes,
                        (double)b->base_strip_bytes,
                        b->parent_bits / 8,
                        b->fan_bits / 8,
                        b->position_bits / 8,
                        b->normal_bits / 8,
                        b->full_strips_bits / 8,
                        (double)b->coded_bytes - fields / 8,
                        (double)(b->framing_bytes + b->end_bytes),
                        total,
                        (double)draco[i],
                        (double)first[i]};
        printf("%-14s %5s", names[i], "B");
        for (int c = 0; c < NC; c++)
            printf(" %11.0f", v[c]);
        printf("\n%-14s %5s", "", "b/v");
        for (int c = 0; c < NC; c++)
            printf(" %11.3f", b->vertices ? v[c] * 8 / b->vertices : 0);
        printf("\n");
        if (jf) {
            fprintf(jf, "%s\"%s\":{\"vertices\":%u,\"splits\":%u", i ? "," : "", names[i],
                    b->vertices, b->splits);
            static const char *const keys[NC] = {
                "capacity_bytes", "model_info_bytes", "base_draco_bytes",
                "base_strip_bytes", "parent_bytes", "fan_bytes", "position_bytes",
                "normal_bytes", "full_strips_bytes", "coder_flush_bytes", "framing_bytes",
                "total_bytes", "draco_cl7_bytes", "level0_bytes"};
            for (int c = 0; c < NC; c++)
                fprintf(jf, ",\"%s\":%.1f", keys[c], v[c]);
            fputs("}", jf);
        }
    }
    if (jf) {
        fputs("}", jf);
        *first_json = 0;
    }
    printf("(fields range-coded: the information coded for them, -log2 of each bit's "
           "probability; rc flush: the coded bytes beyond that; framing: frame and batch "
           "headers, CRCs, END; capacities: the slots', with BASE and the batch that first uses "
           "each; level 0: MODEL_INFO + BASE + END of a stream stopped there)\n");
}

/* ---- colours ----------------------------------------------------------
 * --colors MESH... [--json FILE]: what vertex colours cost on the wire. A
 * mesh without its own colours gets the tests' smooth field
 * (tests/color_field.h) before it is built, as a coloured file's would be
 * seen by the builder; the stream without colours is the mesh's built
 * without them. */

/* The full level's triangles, from the strips' drawn windows. */
static uint32_t *full_triangles(const mts_model *m, uint32_t *count)
{
    uint32_t *t = malloc((size_t)m->full.index_count * 12 + 12), n = 0;
    for (uint32_t st = 0; t && st < m->strip_count; st++) {
        const uint32_t *str = m->full.indices + m->full.offsets[st];
        for (uint32_t k = 0; k + 2 < m->full.offsets[st + 1] - m->full.offsets[st]; k++)
            n += (uint32_t)mts_strip_window(str, k, t + 3 * (size_t)n);
    }
    *count = n;
    return t;
}

static int colors_table(const char *const *paths, int np, const char *json_path)
{
    FILE *jf = json_path ? fopen(json_path, "w") : NULL;
    if (json_path && !jf) {
        fprintf(stderr, "mts-bench-stream: cannot write %s\n", json_path);
        return 1;
    }
    if (jf)
        fputs("{\"grid_bits\":14,\"models\":{", jf);
    int status = 0, first = 1;
    printf("\nColours: the full stream (MODEL_INFO + BASE + every BATCH + END) beside Draco "
           "single-rate\nof the full mesh on the same 14-bit grid, with byte colours (COLOR "
           "attribute, lossless)\n");
    printf("%-14s %6s %9s %9s %7s %8s %9s %8s %9s %9s %7s %8s %8s\n", "model", "source",
           "plain B", "color B", "+B", "+b/vert", "col b/spl", "base col", "draco7", "draco7+c",
           "x d7+c", "d10+c", "records");
    printf("%s\n", "----------------------------------------------------------------------------"
                   "----------------------------------------------");
    for (int i = 0; i < np; i++) {
        char name[64];
        cli_stem(paths[i], name, sizeof name);
        mts_error err = {0};
        mts_mesh mesh = {0};
        mts_model m, mp;
        int have_m = 0, have_mp = 0;
        if (mts_mesh_load(paths[i], NULL, &mesh, NULL, &err) != MTS_OK) {
            printf("%-14s FAILED: %s\n", name, err.msg);
            status = 1;
            continue;
        }
        /* the field goes on the mesh, so that the builder sees the colours
         * as it sees a coloured file's */
        const int own = mesh.colors != NULL;
        if (!own && !mts_test_mesh_color_field(&mesh, MTS_TEST_FIELD_SMOOTH)) {
            mts_mesh_free(&mesh);
            return 1;
        }
        uint8_t *colors = mesh.colors;
        mts_result rc = mts_build_model(&mesh, paths[i], NULL, &m, NULL, &err);
        have_m = rc == MTS_OK;
        /* the same mesh without colours: the stream a 7.0 server sent */
        mesh.colors = NULL;
        if (rc == MTS_OK)
            rc = mts_build_model(&mesh, paths[i], NULL, &mp, NULL, &err);
        have_mp = have_m && rc == MTS_OK;
        mesh.colors = colors;
        mts_mesh_free(&mesh);
        mts_stream plain, col;
        mts_stream_breakdown bp, bc;
        mts_stream_options o = {0};
        o.with_records = 1;
        o.breakdown = &bp;
        if (rc == MTS_OK)
            rc = mts_stream_build(&mp, name, &o, &plain, &err);
        o.breakdown = &bc;
        if (rc == MTS_OK && (rc = mts_stream_build(&m, name, &o, &col, &err)) != MTS_OK)
            mts_stream_free(&plain);
        if (rc != MTS_OK) {
            printf("%-14s FAILED: %s\n", name, err.msg);
            if (have_m)
                mts_model_free(&m);
            if (have_mp)
                mts_model_free(&mp);
            status = 1;
            continue;
        }
        mts_buf b = {0};
        const size_t full_plain = bench_connection_bytes(&plain, mp.level_count, &b),
                     full_col = bench_connection_bytes(&col, m.level_count, &b),
                     rec_col = bench_connection_bytes(col.records_form, m.level_count, &b);
        mts_buf_free(&b);
        uint32_t nt = 0;
        uint32_t *tris = full_triangles(&col.model, &nt);
        size_t draco[3] = {0};
        for (int k = 0; tris && k < 3; k++) {
            mts_draco_mesh dm = {m.vertex_count, nt, col.model.positions, NULL, tris,
                                 k ? col.model.colors : NULL, NULL};
            mts_draco_options dopt = {0};
            dopt.grid = col.grid;
            dopt.compression_level = k == 2 ? 10 : 7;
            uint8_t *out = NULL;
            if (mts_draco_encode(&dm, &dopt, &out, &draco[k], &err) != MTS_OK)
                draco[k] = 0;
            free(out);
        }
        free(tris);
        const double added = (double)full_col - (double)full_plain,
                     bits_vertex = 8 * added / m.vertex_count,
                     bits_split = bc.color_bits / (bc.splits ? bc.splits : 1),
                     ratio = draco[1] ? (double)full_col / draco[1] : 0;
        const size_t base_col = bc.base_draco_bytes - bp.base_draco_bytes;
        printf("%-14s %6s %9zu %9zu %7.0f %8.2f %9.2f %8zu %9zu %9zu %7.2f %8zu %8zu\n", name,
               own ? "file" : "field", full_plain, full_col, added, bits_vertex, bits_split,
               base_col, draco[0], draco[1], ratio, draco[2], rec_col);
        if (jf)
            fprintf(jf,
                    "%s\"%s\":{\"colors\":\"%s\",\"vertices\":%u,\"stream_bytes_without\":%zu,"
                    "\"stream_bytes_with\":%zu,\"added_bytes\":%.0f,\"added_bits_per_vertex\":%.3f,"
                    "\"color_bits_per_split\":%.3f,\"base_color_bytes\":%zu,"
                    "\"draco_cl7_positions\":%zu,\"draco_cl7_with_colors\":%zu,"
                    "\"stream_over_draco_cl7_with_colors\":%.4f,\"draco_cl10_with_colors\":%zu,"
                    "\"records_form_bytes_with\":%zu}",
                    first ? "" : ",", name, own ? "file" : "smooth field", m.vertex_count,
                    full_plain, full_col, added, bits_vertex, bits_split, base_col, draco[0],
                    draco[1], ratio, draco[2], rec_col);
        first = 0;
        mts_stream_free(&plain);
        mts_stream_free(&col);
        mts_model_free(&m);
        mts_model_free(&mp);
    }
    printf("(plain B: the stream of the mesh without colours, byte for byte a 7.0 server's; "
           "+B: what the colours add,\n the collapses they change included; +b/vert: that in "
           "bits a vertex; col b/spl: coded colour bits a split;\n base col: what they add to "
           "BASE's Draco mesh; draco7(+c): Draco edgebreaker cl 7 of the full mesh,\n positions "
           "(and colours); x d7+c: colour B / draco7+c; d10+c: cl 10 with colours; records: "
           "the\n records form with colours)\n");
    if (jf) {
        fputs("}}\n", jf);
        fclose(jf);
    }
    return status;
}

int main(int argc, char **argv)
{
    const char *json_path = NULL;
    const char *paths[16];
    int np = 0, draw_only = 0, colors_only = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--json") && i + 1 < argc)
            json_path = argv[++i];
        else if (!strcmp(argv[i], "--draw-only")) /* the draw-path table alone */
            draw_only = 1;
        else if (!strcmp(argv[i], "--colors")) /* the colours' table alone */
            colors_only = 1;
        else if (!strcmp(argv[i], "--fractions") && i + 1 < argc) { /* its levels, e.g. 1,0.1 */
            char *p = argv[++i];
            for (dt_nf = 0; dt_nf < 16 && *p; dt_nf++) {
                dt_fractions[dt_nf] = strtod(p, &p);
                if (*p == ',')
                    p++;
            }
        } else if (!strcmp(argv[i], "--rounds") && i + 1 < argc) { /* its rounds, 1..31 */
            dt_rounds = atoi(argv[++i]);
            dt_rounds = dt_rounds < 1 ? 1 : dt_rounds > DT_MAX_ROUNDS ? DT_MAX_ROUNDS : dt_rounds;
        } else if (!strcmp(argv[i], "--side") && i + 1 < argc) /* its framebuffer side */
            dt_side = (uint32_t)strtoul(argv[++i], NULL, 10);
        else if (np < 16)
            paths[np++] = argv[i];
    }
    if (colors_only)
        return colors_table(paths, np, json_path);
    FILE *jf = json_path ? fopen(json_path, "w") : NULL;
    if (jf)
        fputs("{", jf);
    mts_render_context *ctx = NULL;
    mts_error cerr = {0};
    int have_gl = mts_render_context_create_headless(&ctx, &cerr) == MTS_OK;
    /* the draw-path table's JSON, written under "draw_path" at the end */
    char *dj_text = NULL;
    size_t dj_size = 0;
    FILE *dj = jf ? open_memstream(&dj_text, &dj_size) : NULL;
    int first_dj = 1, first_json = 1;
    /* where each model's bytes go, printed after the streaming table */
    mts_stream_breakdown bds[16];
    size_t bd_draco[16], bd_first[16];
    char bd_name[16][64];
    int nbd = 0;
    if (draw_only)
        goto draw_path;

    printf("\nStreaming: bytes on the wire beside Draco single-rate on the same 14-bit grid\n");
    printf("%-14s %10s %10s %10s %10s %10s %10s %8s %10s %10s %10s\n", "model", "stream B",
           "base B", "draco cl7", "draco cl10", "+normals", "mtsm B", "x draco7", "10% tri B",
           "50% tri B", "100% B");
    printf("%s\n", "---------------------------------------------------------------------------"
                   "-------------------------------------------");
    for (int i = 0; i < np; i++) {
        struct stat st;
        char name[64];
        cli_stem(paths[i], name, sizeof name);
        if (stat(paths[i], &st) != 0) {
            printf("%-14s skipped: %s not found\n", name, paths[i]);
            continue;
        }
        mts_error err = {0};
        mts_mesh mesh = {0};
        mts_model m;
        mts_stream s;
        if (mts_mesh_load(paths[i], NULL, &mesh, NULL, &err) != MTS_OK ||
            mts_build_model(&mesh, paths[i], NULL, &m, NULL, &err) != MTS_OK) {
            printf("%-14s FAILED: %s\n", name, err.msg);
            continue;
        }
        mts_stream_options sto = {0};
        sto.with_records = 1;
        sto.breakdown = &bds[nbd];
        if (mts_stream_build(&m, name, &sto, &s, &err) != MTS_OK) {
            printf("%-14s FAILED: %s\n", name, err.msg);
            mts_model_free(&m);
            mts_mesh_free(&mesh);
            continue;
        }
        /* Draco single-rate of the full mesh on the stream's grid */
        size_t draco[3] = {0};
        for (int k = 0; k < 3; k++) {
            mts_draco_mesh dm = {mesh.vertex_count, mesh.triangle_count, mesh.positions,
                                 k == 2 ? mesh.normals : NULL, mesh.triangles, NULL, NULL};
            mts_draco_options o = {0};
            o.grid = s.grid;
            o.normal_bits = k == 2 ? 10 : -1;
            o.compression_level = k == 0 ? 7 : 10;
            uint8_t *out = NULL;
            if (mts_draco_encode(&dm, &o, &out, &draco[k], &err) != MTS_OK)
                draco[k] = 0;
            free(out);
        }
        uint8_t *file = NULL;
        size_t file_size = 0;
        mts_modelfile_encode(&m, &file, &file_size, &err);
        free(file);
        mts_buf b = {0};
        size_t at[3];
        const double fr[3] = {0.1, 0.5, 1.0};
        for (int k = 0; k < 3; k++) {
            uint64_t tri = (uint64_t)(fr[k] * m.level_triangles[m.level_count] + 0.5);
            at[k] = bench_connection_bytes(&s, mts_model_level_for_triangles(&m, tri), &b);
        }
        bd_draco[nbd] = draco[0];
        bd_first[nbd] = bench_connection_bytes(&s, 0, &b);
        /* b holds the full stream from here on: it is applied below */
        size_t full = bench_connection_bytes(&s, m.level_count, &b);
        snprintf(bd_name[nbd], sizeof bd_name[nbd], "%s", name);
        nbd++;
        printf("%-14s %10zu %10zu %10zu %10zu %10zu %10zu %8.2f %10zu %10zu %10zu\n", name, full,
               s.batch_offset[0], draco[0], draco[1], draco[2], file_size,
               draco[0] ? (double)full / draco[0] : 0, at[0], at[1], at[2]);

        /* apply throughput, median of 5, of each form */
        double no_gl = 0, gl_med = 0, rec_no_gl = 0, rec_gl = 0;
        apply_median(&b, have_gl ? ctx : NULL, &no_gl, &gl_med, &err);
        mts_buf rb = {0};
        size_t rec_full = bench_connection_bytes(s.records_form, m.level_count, &rb);
        apply_median(&rb, have_gl ? ctx : NULL, &rec_no_gl, &rec_gl, &err);
        mts_buf_free(&rb);
        double splits = m.level_count;
        printf("%-14s apply %u splits: %.2f ms decode+apply (%.2f M splits/s)", "", m.level_count,
               no_gl * 1e3, no_gl > 0 ? splits / no_gl / 1e6 : 0);
        if (have_gl)
            printf(", %.2f ms with GL upload (%.2f M splits/s)", gl_med * 1e3,
                   gl_med > 0 ? splits / gl_med / 1e6 : 0);
        printf("\n%-14s records form (--records): %zu B (%.1fx), apply %.2f ms (%.2f M splits/s)",
               "", rec_full, full ? (double)rec_full / full : 0, rec_no_gl * 1e3,
               rec_no_gl > 0 ? splits / rec_no_gl / 1e6 : 0);
        if (have_gl)
            printf(", %.2f ms with GL upload (%.2f M splits/s)", rec_gl * 1e3,
                   rec_gl > 0 ? splits / rec_gl / 1e6 : 0);
        printf("\n");
        draw_figures df = {0};
        if (have_gl && draw_compare(ctx, &s.model, &df, &err))
            printf("%-14s full level at 1024x1024 on %s: strips %.2f ms (%llu index bytes), "
                   "triangle list %.2f ms, meshopt-optimized list %.2f ms (%llu index bytes, "
                   "strips %.2fx)\n",
                   "", mts_render_context_description(ctx), df.strips_ms,
                   (unsigned long long)df.strip_index_bytes, df.list_ms, df.list_opt_ms,
                   (unsigned long long)df.list_index_bytes,
                   df.list_index_bytes ? (double)df.strip_index_bytes / df.list_index_bytes : 0);
        if (jf) {
            fprintf(jf,
                    "%s\"%s\":{\"stream_bytes\":%zu,\"base_frame_bytes\":%zu,\"batches\":%u,"
                    "\"draco_cl7_bytes\":%zu,\"draco_cl10_bytes\":%zu,\"draco_cl10_normals_bytes\":%zu,"
                    "\"stream_over_draco_cl7\":%.3f,\"input_bytes\":%lld,\"mtsm_bytes\":%zu,"
                    "\"bytes_10pct_triangles\":%zu,\"bytes_50pct_triangles\":%zu,"
                    "\"bytes_100pct_triangles\":%zu,\"apply_ms\":%.3f,\"splits_per_s\":%.0f,"
                    "\"apply_gl_ms\":%.3f,\"splits_per_s_gl\":%.0f,\"frame_ms_strips\":%.3f,"
                    "\"frame_ms_list\":%.3f,\"frame_ms_list_meshopt\":%.3f,"
                    "\"strip_index_bytes\":%llu,\"list_index_bytes\":%llu,"
                    "\"records_stream_bytes\":%zu,\"records_apply_ms\":%.3f,"
                    "\"records_splits_per_s\":%.0f,\"records_apply_gl_ms\":%.3f,"
                    "\"records_splits_per_s_gl\":%.0f}",
                    first_json ? "" : ",", name, full, s.batch_offset[0], s.batch_count, draco[0],
                    draco[1], draco[2], draco[0] ? (double)full / draco[0] : 0,
                    (long long)st.st_size, file_size, at[0], at[1], at[2], no_gl * 1e3,
                    no_gl > 0 ? splits / no_gl : 0, gl_med * 1e3,
                    gl_med > 0 ? splits / gl_med : 0, df.strips_ms, df.list_ms, df.list_opt_ms,
                    (unsigned long long)df.strip_index_bytes,
                    (unsigned long long)df.list_index_bytes, rec_full, rec_no_gl * 1e3,
                    rec_no_gl > 0 ? splits / rec_no_gl : 0, rec_gl * 1e3,
                    rec_gl > 0 ? splits / rec_gl : 0);
            first_json = 0;
        }
        mts_buf_free(&b);
        mts_stream_free(&s);
        mts_model_free(&m);
        mts_mesh_free(&mesh);
    }
    if (!have_gl)
        printf("(no EGL here: %s; GL upload not measured)\n", cerr.msg);
    printf("(stream B: MODEL_INFO + BASE + every BATCH + END for the full level; x draco7: stream / "
           "Draco edgebreaker cl 7, positions only)\n");
    breakdown_table(bds, bd_name, bd_draco, bd_first, nbd, jf, &first_json);
draw_path:
    if (have_gl) {
        printf("\nDraw path: frame ms at %ux%u on %s, median of %d rounds "
               "(each the median of %d frames); index bytes read per frame\n",
               dt_side, dt_side, mts_render_context_description(ctx), dt_rounds, DT_FRAMES);
        printf("(list: the strips' triangles in strip order; list_opt: after "
               "meshopt_optimizeVertexCache; noise: the largest (max-min)/median over rounds; "
               "j/lopt: joined ms / list_opt ms; j idx: joined's indices per triangle, then per "
               "list index)\n");
        for (int i = 0; i < np; i++) {
            char name[64];
            cli_stem(paths[i], name, sizeof name);
            mts_error err = {0};
            mts_mesh mesh = {0};
            mts_model m;
            if (mts_mesh_load(paths[i], NULL, &mesh, NULL, &err) != MTS_OK ||
                mts_build_model(&mesh, paths[i], NULL, &m, NULL, &err) != MTS_OK) {
                printf("%-14s skipped: %s\n", name, err.msg);
                mts_mesh_free(&mesh);
                continue;
            }
            if (!draw_table(ctx, &m, name, dj, &first_dj, &err))
                printf("%-14s draw table FAILED: %s\n", name, err.msg);
            mts_model_free(&m);
            mts_mesh_free(&mesh);
        }
    }
    if (dj) {
        fclose(dj);
        fprintf(jf, "%s\"draw_path\":{%s}", first_json ? "" : ",", dj_text ? dj_text : "");
        free(dj_text);
    }
    if (jf) {
        fputs("}\n", jf);
        fclose(jf);
    }
    mts_render_context_destroy(ctx);
    return 0;
}
