/* mts-client's shared run (run.h). */
#include "run.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "clock.h"
#include "modelfile.h"
#include "strips.h"
#include "webfile.h"

static void level_png_path(const mts_client_run *rn, uint32_t level, char *out, size_t size)
{
    char stem[400];
    if (rn->png) {
        snprintf(stem, sizeof stem, "%s", rn->png);
        char *dot = strrchr(stem, '.');
        char *slash = strrchr(stem, '/');
        if (dot && (!slash || dot > slash))
            *dot = 0;
    } else {
        snprintf(stem, sizeof stem, "%s", rn->model);
    }
    snprintf(out, size, "%s_L%u.png", stem, level);
}

/* Brings the view to `level` (MTS_VIEW_NEWEST: all that came) and draws a
 * frame. Headless, the view moves the stream client's own runtime. */
static int draw(mts_client_run *rn, mts_stream_client *c, uint32_t level)
{
    double t = 1e3 * mts_clock_seconds();
    mts_follow_source src = mts_follow_source_of_stream(c);
    if (mts_view_sync(&rn->view, &src, level, t, &rn->err) != MTS_OK ||
        mts_view_draw(&rn->view, &rn->err) != MTS_OK)
        return 0;
    rn->ms_render += 1e3 * mts_clock_seconds() - t;
    return 1;
}

static int write_png(mts_client_run *rn, const char *path)
{
    if (mts_render_write_png(rn->view.renderer, path, &rn->err) != MTS_OK)
        return 0;
    if (rn->pngs_written < 8)
        snprintf(rn->png_paths[rn->pngs_written], sizeof rn->png_paths[0], "%s", path);
    rn->pngs_written++;
    return 1;
}

/* PNGs for the listed levels the stream has now made available. */
static int level_pngs(mts_client_run *rn, mts_stream_client *c, int final)
{
    uint32_t reached = c->lod.level;
    while (rn->next_png < (uint32_t)rn->png_level_count &&
           (rn->png_levels[rn->next_png] <= reached ||
            (final && rn->png_levels[rn->next_png] > c->info.levels))) {
        uint32_t want = rn->png_levels[rn->next_png++];
        if (want > c->info.levels)
            want = c->info.levels;
        if (want > reached)
            continue;
        /* step down to the level, draw it, come back: only changed strips move */
        if (!draw(rn, c, want))
            return 0;
        char path[512];
        level_png_path(rn, want, path, sizeof path);
        if (!write_png(rn, path))
            return 0;
        mts_follow_source src = mts_follow_source_of_stream(c);
        if (mts_view_sync(&rn->view, &src, reached, 1e3 * mts_clock_seconds(), &rn->err) !=
            MTS_OK)
            return 0;
    }
    return 1;
}

int mts_client_run_warm_up(mts_client_run *rn)
{
    const uint32_t slot[2] = {0, 3};
    mts_render_layout layout = {3, 1, slot, {0, 0, 0}, {1, 1, 1}, 0, 0};
    mts_renderer *r = NULL;
    const float pos[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0}, nor[9] = {0, 0, 1, 0, 0, 1, 0, 0, 1};
    const uint32_t tri[3] = {0, 1, 2};
    int ok = mts_renderer_create(rn->ctx, &rn->ro, &layout, &r, &rn->err) == MTS_OK &&
             mts_render_append_vertices(r, 0, 3, pos, nor, NULL, &rn->err) == MTS_OK &&
             mts_render_set_strip(r, 0, tri, 3, &rn->err) == MTS_OK &&
             mts_render_draw(r, &rn->err) == MTS_OK;
    mts_renderer_destroy(r);
    return ok;
}

/* A MODELS listing's entry for one model: what the camera policies need to
 * ask for their stop point before the stream. */
typedef struct listed {
    const char *name;
    mts_wire_model_entry entry;
    int found;
} listed;

static void find_model(void *user, const mts_wire_model_entry *m)
{
    listed *l = user;
    if (!strcmp(m->name, l->name)) {
        l->entry = *m;
        l->found = 1;
    }
}

/* The stop a policy asks for, from the model's full triangle count. */
static int stop_from_triangles(mts_session_options *so, const mts_client_run *rn,
                               double distance, uint32_t full_triangles, uint64_t list_bytes,
                               uint64_t full_bytes, mts_client_run_stop *stop)
{
    const mts_lod_policy_options *po = &rn->po;
    /* budget cannot know its level before frames are timed: a first guess,
     * an eighth of the model, then more while frames stay in the budget */
    double t = po->kind == MTS_LOD_POLICY_BUDGET
                   ? full_triangles / 8.0
                   : mts_lod_policy_stop_triangles(po, distance,
                                                   rn->ro.camera.fov_y_deg * 3.14159265f / 180.0f,
                                                   (int)rn->ro.width, (int)rn->ro.height,
                                                   full_triangles);
    if (!(t >= 0) || t > UINT32_MAX)
        return 0;
    so->hello.stop_kind = MTS_STOP_TRIANGLES;
    so->hello.stop_value = (uint32_t)t;
    stop->asked = (uint32_t)t;
    stop->list_bytes = list_bytes;
    stop->full_bytes = full_bytes;
    return 1;
}

/* --lod-policy distance or area: the level they choose is known from the
 * view and the model's full triangle count (the server's MODELS listing,
 * a few dozen bytes), so the stream is asked to stop there instead of
 * coming whole: HELLO's triangle stop, which the server resolves with the
 * model's own per-level counts to the highest level within the budget --
 * the policy's choice, counted exactly. Returns 1 when the stop was set. */
int mts_client_run_policy_stop(mts_session_options *so, const mts_client_run *rn,
                               double distance, mts_client_run_stop *stop)
{
    if (so->file) {
        /* a stream file: its index has the counts, and the session that
         * follows reuses it, so the stream is still one more request */
        mts_error ferr = {0};
        if (mts_webfile_read_index(so->file, &ferr) != MTS_OK)
            return 0; /* the session will say what is wrong */
        const mts_stream_file_index *idx = mts_webfile_index(so->file);
        return stop_from_triangles(so, rn, distance, idx->info.triangles,
                                   mts_webfile_bytes(so->file), idx->file_size, stop);
    }
    mts_session_options lo = *so;
    lo.list = 1;
    lo.on_event = NULL;
    lo.resume = 0;
    mts_stream_client lc;
    mts_stream_client_init(&lc);
    listed l;
    memset(&l, 0, sizeof l);
    l.name = rn->model;
    lc.on_model = find_model;
    lc.user = &l;
    mts_session_stats st;
    mts_error err = {0};
    mts_result rc = mts_session_run(&lo, &lc, &st, &err);
    mts_stream_client_free(&lc);
    if (rc != MTS_OK || !l.found)
        return 0; /* the stream comes whole and the policy picks after it */
    return stop_from_triangles(so, rn, distance, l.entry.triangles, st.bytes,
                               l.entry.stream_bytes, stop);
}

int mts_client_run_make_view(mts_client_run *rn, mts_stream_client *c,
                             const mts_view_options *vo)
{
    /* a stream without normals is shaded from the faces each level has */
    rn->ro.style.flat_shading = !(c->info.flags & MTS_INFO_NORMALS);
    mts_view_options o = {0};
    if (vo)
        o = *vo;
    o.no_colors = o.no_colors || rn->no_colors;
    mts_follow_source src = mts_follow_source_of_stream(c);
    if (mts_view_create(&rn->view, rn->ctx, &rn->ro, &src, &o, &rn->err) != MTS_OK) {
        rn->failed = 1;
        return 0;
    }
    rn->have_view = 1;
    return 1;
}

int mts_client_run_on_event(mts_client_run *rn, mts_stream_event ev, mts_stream_client *c)
{
    if (ev == MTS_EV_BASE && rn->render && !rn->have_view) {
        if (!mts_client_run_make_view(rn, c, NULL) || !draw(rn, c, MTS_VIEW_NEWEST) ||
            !level_pngs(rn, c, 0)) {
            rn->failed = 1;
            return 1;
        }
    } else if (ev == MTS_EV_BATCH) {
        if (rn->render && rn->next_png < (uint32_t)rn->png_level_count && !level_pngs(rn, c, 0)) {
            rn->failed = 1;
            return 1;
        }
    }
    return 0;
}

/* --model-file: the same model's stream built here must hold, at the final
 * level, exactly the strips and positions the client received. */
static int compare_with_file(const char *path, mts_stream_client *c, mts_error *err)
{
    mts_model m;
    mts_stream s;
    if (mts_modelfile_load(path, &m, err) != MTS_OK)
        return 0;
    /* the form the server sent: a records-form stream has its own stream_id */
    mts_stream_options so = {0};
    so.with_records = c->records;
    mts_result rc = mts_stream_build(&m, c->info.model, &so, &s, err);
    mts_model_free(&m);
    if (rc != MTS_OK)
        return 0;
    int same = mts_stream_for_hello(&s, c->records ? MTS_HELLO_RECORDS : 0)->stream_id ==
               c->info.stream_id;
    if (!same)
        mts_error_set(err, MTS_ERR_INVARIANT, "%s encodes to another stream than the server's",
                      path);
    mts_lod ref;
    if (same && mts_lod_init(&ref, &s.model, MTS_LOD_AT_BASE, err) == MTS_OK) {
        mts_lod_set_level(&ref, c->lod.level, err);
        for (uint32_t st = 0; st < ref.strip_count && same; st++) {
            uint32_t la, lb;
            const uint32_t *a = mts_lod_strip(&ref, st, &la);
            const uint32_t *b = mts_lod_strip(&c->lod, st, &lb);
            if (la != lb || memcmp(a, b, (size_t)la * 4) != 0) {
                same = 0;
                mts_error_set(err, MTS_ERR_INVARIANT, "strip %u differs from %s at level %u", st,
                              path, c->lod.level);
            }
        }
        size_t nv = (size_t)s.model.base_vertex_count + c->lod.level;
        if (same && memcmp(s.model.positions, c->model.positions, nv * 12) != 0) {
            same = 0;
            mts_error_set(err, MTS_ERR_INVARIANT, "positions differ from %s", path);
        }
        mts_lod_free(&ref);
    }
    mts_stream_free(&s);
    return same;
}

/* --lod-policy: the policy's level (at most the level received) for the
 * final frame, in *level. budget draws frames, each timed from the level
 * change to glFinish, until the level has held for 10 frames (at most 120).
 * Only changed strips are re-uploaded (the coherent runtime). */
static int apply_policy(mts_client_run *rn, mts_stream_client *c, const mts_lod_policy_options *po,
                        double distance, uint32_t *level, double *want_more)
{
    *want_more = 0;
    mts_lod_policy p;
    mts_lod_policy_init(&p, po, &c->model);
    mts_strip_stats base = {0};
    mts_strips_stats(&c->model.base, &base);
    mts_lod_policy_set_counts(&p, (uint32_t)base.triangles, c->info.triangles);
    uint32_t received = c->lod.level;
    mts_lod_view view = {1, rn->ro.camera.fov_y_deg * 3.14159265f / 180.0f, (int)rn->ro.width,
                         (int)rn->ro.height};
    view.distance = (float)(distance * mts_lod_policy_frame_distance(&p, &view));
    double last_ms = 0;
    for (int frame = 0, held = 0; frame < 120 && held < 10; frame++) {
        uint32_t l = mts_lod_policy_choose(&p, received, &view, last_ms);
        held = l == c->lod.level ? held + 1 : 0;
        *level = l;
        if (po->kind != MTS_LOD_POLICY_BUDGET)
            return 1;
        double t = (1e3 * mts_clock_seconds());
        if (!draw(rn, c, l))
            return 0;
        last_ms = (1e3 * mts_clock_seconds()) - t;
    }
    /* all that came fits the budget: the triangles it would take */
    if (*level == received && p.ms_per_triangle > 0)
        *want_more = p.opt.headroom * (1000.0 / p.opt.fps) / p.ms_per_triangle;
    return 1;
}

mts_result mts_client_run_finish(mts_client_run *rn, mts_session_options *so,
                                 mts_stream_client *c, mts_session_stats *st, mts_result rc,
                                 mts_client_run_result *res, mts_error *err)
{
    const mts_lod_policy_options *po = &rn->po;
    if (rn->failed) {
        rc = rn->err.code ? rn->err.code : MTS_ERR_INTERNAL;
        *err = rn->err;
    }
    res->verified = -1;
    res->continuations = 0;
    /* whatever happened, the last whole batch is drawn and written -- unless a
     * record failed while a batch was being applied: the runtime is then
     * broken part-way through a split and there is no whole level to draw */
    res->received = c->have_lod ? c->lod.level : 0;
    if (rn->have_view && c->have_lod && !c->lod.broken) {
        if (rc == MTS_OK)
            level_pngs(rn, c, 1);
        uint32_t final_level = MTS_VIEW_NEWEST;
        /* a stop distance or area asked for is their level already (the
         * server resolved it with the real counts, where the client has a
         * linear estimate): drawn as it came. budget times frames, and while
         * all that came fits, asks for what would (up to 8 times) */
        int pick = po->kind != MTS_LOD_POLICY_RECEIVED &&
                   (!res->stop_asked || po->kind == MTS_LOD_POLICY_BUDGET);
        for (int more = 0; pick && rc == MTS_OK; more++) {
            double want = 0;
            if (!apply_policy(rn, c, po, rn->distance, &final_level, &want)) {
                rc = rn->err.code ? rn->err.code : MTS_ERR_INTERNAL;
                *err = rn->err;
                break;
            }
            if (!res->stop_asked || more == 8 || c->stop_level >= c->info.levels ||
                !(want > 1.1 * c->info.stop_triangles))
                break;
            uint32_t batch;
            uint64_t id;
            if ((rc = mts_stream_client_continue(c, &batch, &id, err)) != MTS_OK)
                break;
            so->hello.stop_kind = MTS_STOP_TRIANGLES;
            so->hello.stop_value = want > UINT32_MAX ? UINT32_MAX : (uint32_t)want;
            so->hello.resume_batch = batch;
            so->hello.stream_id = id;
            uint64_t before = st->bytes;
            rc = mts_session_run(so, c, st, err);
            st->bytes += before;
            res->continuations++;
            res->received = c->lod.level;
            final_level = MTS_VIEW_NEWEST;
        }
        if (draw(rn, c, final_level) && rn->png)
            write_png(rn, rn->png);
    }
    if (rc == MTS_OK && rn->verify && rn->model_file) {
        mts_error verr = {0};
        res->verified = compare_with_file(rn->model_file, c, &verr);
        if (!res->verified) {
            rc = verr.code ? verr.code : MTS_ERR_INVARIANT;
            *err = verr;
        }
    } else if (rc == MTS_OK && rn->verify) {
        res->verified = c->checksum == c->end_checksum;
    }
    return rc;
}

uint32_t mts_client_run_triangles(const mts_stream_client *c)
{
    uint32_t triangles = 0;
    if (c->have_lod) {
        mts_strip_stats ss;
        mts_lod_strip_stats(&c->lod, &ss);
        triangles = (uint32_t)ss.triangles;
    }
    return triangles;
}

/* What went to GL (the whole run) beside what the last frame drew from: the
 * vertices and the index buffer of the draw path (the packed one by
 * default), so a run's uploads read as a multiple of its final buffers. */
static void json_uploads(cli_json *j, const mts_renderer *r)
{
    if (!r)
        return;
    mts_render_stats rs;
    mts_render_get_stats(r, &rs);
    cli_json_u64(j, "gl_upload_bytes", rs.vertex_bytes_uploaded + rs.index_bytes_uploaded);
    cli_json_u64(j, "gl_final_bytes",
                 (uint64_t)rs.vertices * (rs.colors ? 28u : 24u) +
                     (rs.packed_bytes ? rs.packed_bytes : rs.last_draw_index_bytes));
    if (rs.morph_bytes_uploaded)
        cli_json_u64(j, "gl_morph_bytes", rs.morph_bytes_uploaded);
}

void mts_client_run_json_head(cli_json *j, const mts_client_run *rn,
                              const mts_stream_client *c, int complete, uint64_t bytes)
{
    cli_json_str(j, "model", rn->model);
    cli_json_bool(j, "complete", complete);
    cli_json_u64(j, "bytes", bytes);
    cli_json_u64(j, "batches", c->batches);
    cli_json_str(j, "form", c->records ? "records" : "splits");
    cli_json_u64(j, "level", c->have_lod ? c->lod.level : 0);
    cli_json_u64(j, "levels", c->info.levels);
}

void mts_client_run_json(cli_json *j, const mts_stream_client *c, const mts_session_stats *st,
                         const mts_client_run *rn)
{
    cli_json_u64(j, "triangles", mts_client_run_triangles(c));
    /* what decoded, not what was asked: the records form decodes on one */
    cli_json_u64(j, "threads", mts_stream_client_threads_used(c));
    cli_json_u64(j, "threads_asked", rn->threads);
    if (c->threads_alone_from) /* the threads shared a core: one decoded from here on */
        cli_json_u64(j, "threads_alone_from", c->threads_alone_from);
    if (c->end_checksum) { /* END came: the mesh checksum at the final level */
        char hex[17];
        snprintf(hex, sizeof hex, "%016llx", (unsigned long long)c->checksum);
        cli_json_str(j, "checksum", hex);
    }
    cli_json_bool(j, "colors", rn->have_view ? rn->view.colors
                                             : (c->model.flags & MTS_MODEL_COLORS) && c->model.colors &&
                                                   !rn->no_colors);
    cli_json_u64(j, "reconnects", st->reconnects);
    cli_json_num(j, "ms_connect", st->ms_connect, 3);
    cli_json_num(j, "ms_base", st->ms_base, 3);
    cli_json_num(j, "ms_final", st->ms_final, 3);
    cli_json_num(j, "ms_apply", st->ms_apply, 3);
    cli_json_num(j, "ms_render", rn->ms_render, 3);
    json_uploads(j, rn->have_view ? rn->view.renderer : NULL);
}

void mts_client_run_free(mts_client_run *rn)
{
    mts_view_free(&rn->view);
    mts_render_context_destroy(rn->ctx);
}
