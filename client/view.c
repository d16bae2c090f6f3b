/* The client's view (view.h): a renderer kept in step with a LOD runtime. */
#include "view.h"

#include <stdlib.h>
#include <string.h>

#include "stream.h"
#include "strips.h"

mts_view_source mts_view_source_of_stream(struct mts_stream_client *c)
{
    /* the stream's runtime stops at the stop level; the last batch's splits
     * beyond it are decoded (its checks need them) but not shown */
    uint32_t levels = c->splits < c->stop_level ? c->splits : c->stop_level;
    mts_view_source s = {&c->lod, &c->model, c->model.base_vertex_count + c->splits, levels,
                         c->announced};
    return s;
}

mts_view_source mts_view_source_of_model(mts_lod *lod, const mts_model *model)
{
    mts_view_source s = {lod, model, model->vertex_count, model->level_count,
                         model->strip_count};
    return s;
}

mts_result mts_view_create(mts_view *v, mts_render_context *ctx, const mts_render_options *ro,
                           const mts_view_source *src, const mts_view_options *opts,
                           mts_error *err)
{
    memset(v, 0, sizeof *v);
    if (!ctx || !ro || !src || !src->lod || !src->model)
        return mts_error_set(err, MTS_ERR_ARG, "view: NULL argument to mts_view_create");
    if (opts)
        v->opts = *opts;
    if (v->opts.morph_ms < 0 || v->opts.morph_ms > 1e6)
        return mts_error_set(err, MTS_ERR_ARG, "view: morph time %g ms", v->opts.morph_ms);
    if (v->opts.morph_ms > 0 && !v->opts.own_runtime)
        return mts_error_set(err, MTS_ERR_ARG,
                             "view: geomorphs need a runtime of the view's own");
    mts_render_layout layout;
    mts_render_layout_from_lod(src->lod, &layout);
    mts_result rc = mts_renderer_create(ctx, ro, &layout, &v->renderer, err);
    if (rc != MTS_OK)
        return rc;
    v->lod = src->lod;
    if (v->opts.own_runtime) {
        rc = mts_lod_init(&v->own, src->model, MTS_LOD_AT_BASE, err);
        if (rc != MTS_OK) {
            mts_view_free(v);
            return rc;
        }
        v->have_own = 1;
        v->lod = &v->own;
        v->announced = src->announced;
    }
    return MTS_OK;
}

void mts_view_free(mts_view *v)
{
    if (!v)
        return;
    mts_renderer_destroy(v->renderer);
    if (v->have_own)
        mts_lod_free(&v->own);
    free(v->morph_from);
    free(v->morph_ids);
    memset(v, 0, sizeof *v);
}

void mts_view_set_wireframe(mts_view *v, int on)
{
    v->wireframe = on;
    v->wire_stale = 1;
}

/* The morph of vertex ids first .. first+count-1 towards (or from) the level
 * whose vertices end at first: each starts from its nearest ancestor below
 * first (a parent precedes its child in stream order, so walking up is one
 * look-up into the ids already resolved). */
static mts_result morph_begin(mts_view *v, const mts_model *m, uint32_t first, uint32_t count,
                              mts_error *err)
{
    if (count > v->morph_cap) {
        float *f = realloc(v->morph_from, (size_t)count * 6 * sizeof *f);
        if (f)
            v->morph_from = f;
        uint32_t *ids = realloc(v->morph_ids, (size_t)count * sizeof *ids);
        if (ids)
            v->morph_ids = ids;
        if (!f || !ids)
            return mts_error_set(err, MTS_ERR_NOMEM, "view: a morph of %u vertices", count);
        v->morph_cap = count;
    }
    const uint32_t nb = m->base_vertex_count;
    for (uint32_t i = 0; i < count; i++) {
        uint32_t p = m->parents[first + i - nb];
        uint32_t a = p < first ? p : v->morph_ids[p - first];
        v->morph_ids[i] = a;
        memcpy(v->morph_from + 3 * (size_t)i, m->positions + 3 * (size_t)a, 12);
        memcpy(v->morph_from + 3 * ((size_t)count + i), m->normals + 3 * (size_t)a, 12);
    }
    mts_result rc = mts_render_set_morph(v->renderer, first, count, v->morph_from,
                                         v->morph_from + 3 * (size_t)count, err);
    if (rc != MTS_OK)
        return rc;
    v->morph_first = first;
    v->morph_count = count;
    v->morphing = 1;
    return MTS_OK;
}

static mts_result morph_end(mts_view *v, mts_error *err)
{
    v->morphing = 0;
    v->morph_t = 1;
    mts_result rc = mts_render_set_morph(v->renderer, 0, 0, NULL, NULL, err);
    if (rc == MTS_OK && v->morph_down)
        rc = mts_lod_set_level(v->lod, v->morph_target, err);
    v->morph_down = 0;
    return rc;
}

/* Moves the drawn runtime to target, through a geomorph where asked. */
static mts_result move_to(mts_view *v, const mts_view_source *src, uint32_t target, double now,
                          mts_error *err)
{
    mts_result rc;
    if (v->morphing) {
        double t = (now - v->morph_t0) / v->opts.morph_ms;
        if (t < 1) {
            v->morph_t = (float)(v->morph_down ? 1 - t : t);
            mts_render_set_morph_t(v->renderer, v->morph_t);
            return MTS_OK;
        }
        if ((rc = morph_end(v, err)) != MTS_OK)
            return rc;
    }
    uint32_t from = v->lod->level;
    if (target == from)
        return MTS_OK;
    if (!(v->opts.morph_ms > 0))
        return mts_lod_set_level(v->lod, target, err);
    const uint32_t nb = src->model->base_vertex_count;
    v->morph_t0 = now;
    if (target > from) {
        if ((rc = mts_lod_set_level(v->lod, target, err)) != MTS_OK)
            return rc;
        v->morph_t = 0;
        rc = morph_begin(v, src->model, nb + from, target - from, err);
    } else {
        v->morph_down = 1;
        v->morph_target = target;
        v->morph_t = 1;
        rc = morph_begin(v, src->model, nb + target, from - target, err);
    }
    mts_render_set_morph_t(v->renderer, v->morph_t);
    return rc;
}

mts_result mts_view_sync(mts_view *v, const mts_view_source *src, uint32_t level, double now_ms,
                         mts_error *err)
{
    if (!v || !v->renderer || !src || !src->lod || !src->model)
        return mts_error_set(err, MTS_ERR_ARG, "view: sync without a view or a source");
    const mts_model *m = src->model;
    mts_result rc;
    if (src->vertices > v->uploaded) {
        rc = mts_render_append_vertices(v->renderer, v->uploaded, src->vertices - v->uploaded,
                                        m->positions + 3 * (size_t)v->uploaded,
                                        m->normals + 3 * (size_t)v->uploaded, err);
        if (rc != MTS_OK)
            return rc;
        v->uploaded = src->vertices;
    }
    uint32_t available =
        src->vertices > m->base_vertex_count ? src->vertices - m->base_vertex_count : 0;
    if (available > src->levels)
        available = src->levels;
    if (v->have_own) {
        /* slots the source laid out since (their capacities are in the model
         * both share) are laid out before the view may use them */
        if (src->announced > v->announced) {
            if ((rc = mts_lod_announce(&v->own, v->announced, err)) != MTS_OK)
                return rc;
            v->announced = src->announced;
        }
        mts_lod_set_available(&v->own, available);
    }
    uint32_t target = level < available ? level : available;
    if ((rc = move_to(v, src, target, now_ms, err)) != MTS_OK)
        return rc;
    uint32_t changed;
    mts_lod_changed(v->lod, &changed);
    if (changed || v->lod->relayout_from != UINT32_MAX || !v->have_figures || v->wire_stale) {
        if ((rc = mts_render_update_strips(v->renderer, v->lod, err)) != MTS_OK)
            return rc;
        mts_lod_clear_changed(v->lod);
        if (v->wireframe && (rc = mts_render_update_wireframe(v->renderer, v->lod, err)) != MTS_OK)
            return rc;
        v->wire_stale = 0;
        mts_strip_stats ss;
        mts_lod_strip_stats(v->lod, &ss);
        v->shown.level = v->lod->level;
        v->shown.triangles = (uint32_t)ss.triangles;
        v->shown.strips = ss.strips;
        v->shown.indices = ss.indices;
        v->have_figures = 1;
    }
    return MTS_OK;
}

mts_result mts_view_draw(mts_view *v, mts_error *err)
{
    if (!v || !v->renderer)
        return mts_error_set(err, MTS_ERR_ARG, "view: draw without a renderer");
    return mts_render_draw(v->renderer, err);
}
