/* The client's view (view.h): a follower and a renderer uploading what it
 * says changed. */
#include "view.h"

#include <string.h>

mts_result mts_view_create(mts_view *v, mts_render_context *ctx, const mts_render_options *ro,
                           const mts_follow_source *src, const mts_view_options *opts,
                           mts_error *err)
{
    memset(v, 0, sizeof *v);
    if (!ctx || !ro || !src || !src->lod || !src->model)
        return mts_error_set(err, MTS_ERR_ARG, "view: NULL argument to mts_view_create");
    mts_follow_options fo = {0};
    if (opts) {
        fo.own_runtime = opts->own_runtime;
        fo.morph_ms = opts->morph_ms;
    }
    mts_result rc = mts_follow_init(&v->follow, src, &fo, err);
    if (rc != MTS_OK)
        return rc;
    mts_render_layout layout;
    mts_render_layout_from_lod(src->lod, &layout);
    if (opts && opts->no_colors)
        layout.colors = 0;
    if ((rc = mts_renderer_create(ctx, ro, &layout, &v->renderer, err)) != MTS_OK)
        mts_view_free(v);
    else
        v->colors = layout.colors;
    return rc;
}

void mts_view_free(mts_view *v)
{
    if (!v)
        return;
    mts_renderer_destroy(v->renderer);
    mts_follow_free(&v->follow);
    memset(v, 0, sizeof *v);
}

void mts_view_set_wireframe(mts_view *v, int on)
{
    v->wireframe = on;
    mts_follow_touch(&v->follow);
}

mts_result mts_view_sync(mts_view *v, const mts_follow_source *src, uint32_t level, double now_ms,
                         mts_error *err)
{
    if (!v || !v->renderer || !src || !src->lod || !src->model)
        return mts_error_set(err, MTS_ERR_ARG, "view: sync without a view or a source");
    mts_follow *f = &v->follow;
    mts_follow_changes ch;
    mts_result rc = mts_follow_sync(f, src, level, now_ms, &ch, err);
    /* the vertices go up first: the strips and the morph's range use them */
    if (ch.vertex_count) {
        const mts_model *m = src->model;
        /* a model that says it has colours and holds none is refused by
         * the renderer rather than drawn from an unfilled buffer */
        const uint8_t *colors =
            v->colors && m->colors ? m->colors + 3 * (size_t)ch.vertex_first : NULL;
        mts_result vrc = mts_render_append_vertices(
            v->renderer, ch.vertex_first, ch.vertex_count,
            m->positions + 3 * (size_t)ch.vertex_first, m->normals + 3 * (size_t)ch.vertex_first,
            colors, err);
        if (vrc != MTS_OK)
            return vrc;
    }
    if (ch.morph_range && rc == MTS_OK)
        rc = mts_render_set_morph(v->renderer, f->morph.first, f->morph.count, f->morph.from,
                                  f->morph.from + 3 * (size_t)f->morph.count,
                                  v->colors ? f->morph.from_colors : NULL, err);
    mts_render_set_morph_t(v->renderer, f->morph.t);
    if (rc != MTS_OK || !ch.strips)
        return rc;
    if ((rc = mts_render_update_strips(v->renderer, f->lod, err)) != MTS_OK)
        return rc;
    mts_follow_clear_changed(f);
    if (v->wireframe)
        rc = mts_render_update_wireframe(v->renderer, f->lod, err);
    return rc;
}

mts_result mts_view_draw(mts_view *v, mts_error *err)
{
    if (!v || !v->renderer)
        return mts_error_set(err, MTS_ERR_ARG, "view: draw without a renderer");
    return mts_render_draw(v->renderer, err);
}
