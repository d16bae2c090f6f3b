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
    v->morph.ms = v->opts.morph_ms;
    v->morph.t = 1;
    return MTS_OK;
}

void mts_view_free(mts_view *v)
{
    if (!v)
        return;
    mts_renderer_destroy(v->renderer);
    if (v->have_own)
        mts_lod_free(&v->own);
    mts_morph_free(&v->morph);
    memset(v, 0, sizeof *v);
}

void mts_view_set_wireframe(mts_view *v, int on)
{
    v->wireframe = on;
    v->wire_stale = 1;
}

/* Moves the drawn runtime to target, through a geomorph where asked. */
static mts_result move_to(mts_view *v, const mts_view_source *src, uint32_t target, double now,
                          mts_error *err)
{
    int range_changed = 0;
    mts_result rc = mts_morph_move(&v->morph, v->lod, src->model, target, now, &range_changed, err);
    if (rc == MTS_OK && range_changed)
        rc = mts_render_set_morph(v->renderer, v->morph.first, v->morph.count, v->morph.from,
                                  v->morph.from + 3 * (size_t)v->morph.count, err);
    mts_render_set_morph_t(v->renderer, v->morph.t);
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
