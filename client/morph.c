/* Geomorphs between two levels (morph.h). */
#include "morph.h"

#include <stdlib.h>
#include <string.h>

void mts_morph_free(mts_morph *mo)
{
    if (!mo)
        return;
    free(mo->from);
    free(mo->from_colors);
    free(mo->ids);
    mo->from = NULL;
    mo->from_colors = NULL;
    mo->ids = NULL;
    mo->cap = 0;
    mo->active = 0;
    mo->count = 0;
}

/* The morph of vertex ids first .. first+count-1 towards (or from) the level
 * whose vertices end at first: each starts from its nearest ancestor below
 * first (a parent precedes its child in stream order, so walking up is one
 * look-up into the ids already resolved), in that ancestor's place, normal
 * and colour. */
static mts_result begin(mts_morph *mo, const mts_model *m, uint32_t first, uint32_t count,
                        mts_error *err)
{
    const uint8_t *colors = m->flags & MTS_MODEL_COLORS ? m->colors : NULL;
    if (count > mo->cap || (colors && !mo->from_colors)) {
        uint32_t cap = count > mo->cap ? count : mo->cap;
        float *f = realloc(mo->from, (size_t)cap * 6 * sizeof *f);
        if (f)
            mo->from = f;
        uint32_t *ids = realloc(mo->ids, (size_t)cap * sizeof *ids);
        if (ids)
            mo->ids = ids;
        uint8_t *c = mo->from_colors;
        if (colors && (c = realloc(mo->from_colors, (size_t)cap * 3)) != NULL)
            mo->from_colors = c;
        if (!f || !ids || (colors && !c))
            return mts_error_set(err, MTS_ERR_NOMEM, "morph: %u vertices", count);
        mo->cap = cap;
    }
    const uint32_t nb = m->base_vertex_count;
    for (uint32_t i = 0; i < count; i++) {
        uint32_t p = m->parents[first + i - nb];
        uint32_t a = p < first ? p : mo->ids[p - first];
        mo->ids[i] = a;
        memcpy(mo->from + 3 * (size_t)i, m->positions + 3 * (size_t)a, 12);
        memcpy(mo->from + 3 * ((size_t)count + i), m->normals + 3 * (size_t)a, 12);
        if (colors)
            memcpy(mo->from_colors + 3 * (size_t)i, colors + 3 * (size_t)a, 3);
    }
    mo->first = first;
    mo->count = count;
    mo->active = 1;
    return MTS_OK;
}

mts_result mts_morph_move(mts_morph *mo, mts_lod *lod, const mts_model *m, uint32_t target,
                          double now_ms, int *range_changed, mts_error *err)
{
    int changed = 0;
    mts_result rc = MTS_OK;
    if (mo->active) {
        double t = (now_ms - mo->t0) / mo->ms;
        if (t < 1) {
            mo->t = (float)(mo->down ? 1 - t : t);
            goto done;
        }
        /* it ends: the from-attributes go, a drop is taken now */
        mo->active = 0;
        mo->t = 1;
        mo->count = 0;
        changed = 1;
        if (mo->down && (rc = mts_lod_set_level(lod, mo->target, err)) != MTS_OK)
            goto done;
        mo->down = 0;
    }
    uint32_t from = lod->level;
    if (target == from)
        goto done;
    if (!(mo->ms > 0)) {
        rc = mts_lod_set_level(lod, target, err);
        goto done;
    }
    const uint32_t nb = m->base_vertex_count;
    mo->t0 = now_ms;
    changed = 1;
    if (target > from) {
        if ((rc = mts_lod_set_level(lod, target, err)) != MTS_OK)
            goto done;
        mo->t = 0;
        rc = begin(mo, m, nb + from, target - from, err);
    } else {
        mo->down = 1;
        mo->target = target;
        mo->t = 1;
        rc = begin(mo, m, nb + target, from - target, err);
    }
done:
    if (range_changed)
        *range_changed = changed;
    return rc;
}
