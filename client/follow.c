/* The follower (follow.h): a LOD runtime kept in step with a source, and
 * its level packed for a draw. */
#include "follow.h"

#include <stdlib.h>
#include <string.h>

#include "camera.h"
#include "stream.h"
#include "strips.h"

mts_follow_source mts_follow_source_of_stream(struct mts_stream_client *c)
{
    /* the stream's runtime stops at the stop level; the last batch's splits
     * beyond it are decoded (its checks need them) but not shown */
    uint32_t levels = c->splits < c->stop_level ? c->splits : c->stop_level;
    mts_follow_source s = {&c->lod, &c->model, c->model.base_vertex_count + c->splits, levels,
                           c->announced};
    return s;
}

mts_follow_source mts_follow_source_of_model(mts_lod *lod, const mts_model *model)
{
    mts_follow_source s = {lod, model, model->vertex_count, model->level_count,
                           model->strip_count};
    return s;
}

mts_result mts_follow_init(mts_follow *f, const mts_follow_source *src,
                           const mts_follow_options *opts, mts_error *err)
{
    memset(f, 0, sizeof *f);
    f->morph.t = 1;
    if (!src || !src->lod || !src->model)
        return mts_error_set(err, MTS_ERR_ARG, "follow: NULL source");
    if (opts)
        f->opts = *opts;
    if (f->opts.morph_ms < 0 || f->opts.morph_ms > 1e6)
        return mts_error_set(err, MTS_ERR_ARG, "follow: morph time %g ms", f->opts.morph_ms);
    if (f->opts.morph_ms > 0 && !f->opts.own_runtime)
        return mts_error_set(err, MTS_ERR_ARG,
                             "follow: geomorphs need a runtime of the follower's own");
    f->lod = src->lod;
    if (f->opts.own_runtime) {
        mts_result rc = mts_lod_init(&f->own, src->model, MTS_LOD_AT_BASE, err);
        if (rc != MTS_OK)
            return rc;
        f->have_own = 1;
        f->lod = &f->own;
        f->announced = src->announced;
    }
    f->morph.ms = f->opts.morph_ms;
    return MTS_OK;
}

void mts_follow_free(mts_follow *f)
{
    if (!f)
        return;
    if (f->have_own)
        mts_lod_free(&f->own);
    mts_morph_free(&f->morph);
    mts_follow_packed_free(&f->packed);
    memset(f, 0, sizeof *f);
}

void mts_follow_touch(mts_follow *f)
{
    f->stale = 1;
}

void mts_follow_clear_changed(mts_follow *f)
{
    if (f->lod)
        mts_lod_clear_changed(f->lod);
}

mts_result mts_follow_sync(mts_follow *f, const mts_follow_source *src, uint32_t level,
                           double now_ms, mts_follow_changes *changes, mts_error *err)
{
    mts_follow_changes ch = {0};
    if (changes)
        *changes = ch;
    if (!f || !f->lod || !src || !src->lod || !src->model)
        return mts_error_set(err, MTS_ERR_ARG, "follow: sync without a follower or a source");
    const mts_model *m = src->model;
    mts_result rc;
    if (src->vertices > f->vertices) {
        ch.vertex_first = f->vertices;
        ch.vertex_count = src->vertices - f->vertices;
        f->vertices = src->vertices;
    }
    uint32_t available =
        src->vertices > m->base_vertex_count ? src->vertices - m->base_vertex_count : 0;
    if (available > src->levels)
        available = src->levels;
    if (f->have_own) {
        /* slots the source laid out since (their capacities are in the model
         * both share) are laid out before the follower may use them */
        if (src->announced > f->announced) {
            if ((rc = mts_lod_announce(&f->own, f->announced, err)) != MTS_OK)
                goto done;
            f->announced = src->announced;
        }
        mts_lod_set_available(&f->own, available);
    }
    uint32_t target = level < available ? level : available;
    if (!f->moved && f->opts.first_at_once) {
        /* nothing shown yet to slide from */
        rc = mts_lod_set_level(f->lod, target, err);
    } else {
        rc = mts_morph_move(&f->morph, f->lod, m, target, now_ms, &ch.morph_range, err);
        f->morph_serial += (uint32_t)ch.morph_range;
    }
    f->moved = 1;
    if (rc != MTS_OK)
        goto done;
    uint32_t changed;
    mts_lod_changed(f->lod, &changed);
    if (changed || f->lod->relayout_from != UINT32_MAX || !f->have_figures || f->stale) {
        ch.strips = 1;
        f->stale = 0;
        f->pack_stale = 1;
        mts_strip_stats ss;
        mts_lod_strip_stats(f->lod, &ss);
        f->shown.level = f->lod->level;
        f->shown.triangles = (uint32_t)ss.triangles;
        f->shown.strips = ss.strips;
        f->shown.indices = ss.indices;
        f->have_figures = 1;
    }
done:
    if (changes)
        *changes = ch;
    return rc;
}

mts_result mts_follow_pack_strips(mts_follow_packed *p, const uint32_t *data,
                                  const uint32_t *offset, const uint32_t *length,
                                  uint32_t strip_count, uint32_t restart, int u16, int per_strip,
                                  mts_error *err)
{
    uint64_t need = mts_strips_pack_bound(length, strip_count, restart == 0);
    /* GL's and WebGL's draw counts are GLsizei */
    if (need > (uint64_t)INT32_MAX)
        return mts_error_set(err, MTS_ERR_LIMIT, "pack: %llu packed indices",
                             (unsigned long long)need);
    size_t bytes = (size_t)(need ? need : 1) * (u16 ? 2u : 4u);
    if (bytes > p->cap || !p->indices) {
        void *q = realloc(p->indices, bytes);
        if (!q)
            return mts_error_set(err, MTS_ERR_NOMEM, "pack: %llu packed indices",
                                 (unsigned long long)need);
        p->indices = q;
        p->cap = bytes;
    }
    p->u16 = u16;
    if (per_strip && strip_count > p->strip_cap) {
        uint32_t *fi = realloc(p->strip_first, (size_t)strip_count * sizeof *fi);
        if (fi)
            p->strip_first = fi;
        uint32_t *n = realloc(p->strip_length, (size_t)strip_count * sizeof *n);
        if (n)
            p->strip_length = n;
        float *rgb = realloc(p->strip_rgb, (size_t)strip_count * 3 * sizeof *rgb);
        if (rgb)
            p->strip_rgb = rgb;
        if (!fi || !n || !rgb)
            return mts_error_set(err, MTS_ERR_NOMEM, "pack: %u strips", strip_count);
        p->strip_cap = strip_count;
    }
    p->count = mts_strips_pack(data, offset, length, strip_count, restart, u16, p->indices,
                               per_strip ? p->strip_first : NULL);
    p->strips = 0;
    if (per_strip) {
        uint32_t k = 0;
        for (uint32_t s = 0; s < strip_count; s++)
            if (length[s] >= 3) {
                mts_camera_strip_color(s, p->strip_rgb + 3 * (size_t)k);
                p->strip_length[k++] = length[s];
            }
        p->strips = k;
    }
    return MTS_OK;
}

void mts_follow_packed_free(mts_follow_packed *p)
{
    if (!p)
        return;
    free(p->indices);
    free(p->strip_first);
    free(p->strip_length);
    free(p->strip_rgb);
    memset(p, 0, sizeof *p);
}

mts_result mts_follow_pack(mts_follow *f, mts_error *err)
{
    if (!f || !f->lod)
        return mts_error_set(err, MTS_ERR_ARG, "follow: pack without a runtime");
    if (!f->pack_stale && f->packed.indices)
        return MTS_OK;
    const mts_lod *l = f->lod;
    mts_result rc =
        mts_follow_pack_strips(&f->packed, l->data, l->slot, l->length, l->strip_count, 0, 0, 1,
                               err);
    if (rc == MTS_OK)
        f->pack_stale = 0;
    return rc;
}
