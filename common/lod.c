#include "lod.h"

#include <stdlib.h>
#include <string.h>

static void lod_mark(mts_lod *lod, uint32_t s)
{
    if (!lod->changed[s]) {
        lod->changed[s] = 1;
        lod->changed_list[lod->changed_count++] = s;
    }
}

/* Records are laid out for the split; a collapse walks them backwards, so it
 * first notes where each edit of the record starts, then where each erase
 * and each insert of the edit being undone starts. An edit takes 4 words at
 * least (strip and three counts) and an erase or insert run 2 (position,
 * length), so for a record of w words 4 E + 2 (R + I) <= w - 1 and the
 * E + R + I entries never pass w / 2 + 1. The scratch holds nothing from
 * one record to the next, so growing it keeps nothing: past a megabyte of
 * pointers (a key level's record rewrites every strip) it takes a
 * reservation in place of a copy. */
static int lod_reserve_scratch(mts_lod *lod, uint32_t record_words)
{
    uint32_t need = record_words / 2 + 1;
    if (need <= lod->scratch_size)
        return 1;
    uint64_t size = lod->scratch_size ? lod->scratch_size : 64;
    while (size < need)
        size *= 2;
    if (size > UINT32_MAX || size > SIZE_MAX / sizeof *lod->scratch)
        return 0;
    if (!mts_bigmem_room(&lod->scratch_mem, (size_t)size * sizeof *lod->scratch, 0, 0))
        return 0;
    lod->scratch = lod->scratch_mem.p;
    lod->scratch_size = (uint32_t)size;
    return 1;
}

mts_result mts_lod_init(mts_lod *lod, const mts_model *model, mts_lod_start start, mts_error *err)
{
    return mts_lod_init_with(lod, model, start, NULL, err);
}

mts_result mts_lod_init_with(mts_lod *lod, const mts_model *model, mts_lod_start start,
                             mts_bigmem_cache *memory, mts_error *err)
{
    memset(lod, 0, sizeof *lod);
    lod->data_mem.cache = lod->scratch_mem.cache = memory;
    const mts_strips *from = start == MTS_LOD_AT_FULL ? &model->full : &model->base;
    uint32_t n = model->strip_count;
    if (model->full.strip_count != n || model->base.strip_count != n)
        return mts_error_set(err, MTS_ERR_INTERNAL, "lod: strip sets disagree on the strip count");
    if (n > 0 && !model->capacity)
        return mts_error_set(err, MTS_ERR_INTERNAL, "lod: the model has no strip capacities");
    /* slot offsets are 32-bit: the slots together must fit them */
    uint64_t total = 0;
    for (uint32_t s = 0; s < n; s++)
        total += model->capacity[s];
    const uint64_t room = model->capacity_room > total ? model->capacity_room : total;
    if (room >= UINT32_MAX)
        return mts_error_set(err, MTS_ERR_LIMIT, "lod: strip capacities add up to %llu indices",
                             (unsigned long long)room);
    lod->model = model;
    lod->strip_count = n;
    lod->available = model->level_count;
    lod->level = start == MTS_LOD_AT_FULL ? model->level_count : 0;
    lod->slot = malloc(((size_t)n + 1) * sizeof *lod->slot);
    lod->length = malloc(((size_t)n + 1) * sizeof *lod->length);
    /* no index is read past a strip's length, so pages another runtime
     * left in the cache need no clearing */
    if (mts_bigmem_room(&lod->data_mem, ((size_t)room + 1) * sizeof *lod->data, 0, 0))
        lod->data = lod->data_mem.p;
    lod->room = (uint32_t)room;
    lod->relayout_from = UINT32_MAX;
    lod->changed = calloc((size_t)n + 1, 1);
    lod->changed_list = malloc(((size_t)n + 1) * sizeof *lod->changed_list);
    if (!lod->slot || !lod->length || !lod->data || !lod->changed || !lod->changed_list) {
        mts_lod_free(lod);
        return mts_error_set(err, MTS_ERR_NOMEM, "lod: out of memory for %u strips", n);
    }
    lod->slot[0] = 0;
    for (uint32_t s = 0; s < n; s++)
        lod->slot[s + 1] = lod->slot[s] + model->capacity[s];
    for (uint32_t s = 0; s < n; s++) {
        uint32_t len = from->offsets[s + 1] - from->offsets[s];
        if (len > model->capacity[s]) {
            mts_lod_free(lod);
            return mts_error_set(err, MTS_ERR_RANGE,
                                 "lod: %s strip %u is longer (%u) than its capacity (%u)",
                                 start == MTS_LOD_AT_FULL ? "full" : "base", s, len,
                                 model->capacity[s]);
        }
        lod->length[s] = len;
        memcpy(lod->data + lod->slot[s], from->indices + from->offsets[s], (size_t)len * 4);
        lod_mark(lod, s);
    }
    /* Room to walk the longest record backwards, so that no later move
     * allocates. Offsets that go backwards are left for mts_lod_split to
     * report. A runtime that starts at the base collapses only what it
     * split, and each split reserves for its own record: it reads no
     * record here, which a stream client's model does not hold yet (its
     * offsets are sized by the levels the server claims). */
    uint32_t longest = 0;
    for (uint32_t j = 0; start == MTS_LOD_AT_FULL && j < lod->available; j++) {
        uint32_t a = model->record_offsets[j], b = model->record_offsets[j + 1];
        if (b > a && b - a > longest)
            longest = b - a;
    }
    if (!lod_reserve_scratch(lod, longest)) {
        mts_lod_free(lod);
        return mts_error_set(err, MTS_ERR_NOMEM, "lod: out of memory for a %u-word record",
                             longest);
    }
    return MTS_OK;
}

void mts_lod_free(mts_lod *lod)
{
    if (!lod)
        return;
    free(lod->slot);
    free(lod->length);
    mts_bigmem_free(&lod->data_mem);
    free(lod->changed);
    free(lod->changed_list);
    mts_bigmem_free(&lod->scratch_mem);
    memset(lod, 0, sizeof *lod);
}

void mts_lod_clear_changed(mts_lod *lod)
{
    for (uint32_t i = 0; i < lod->changed_count; i++)
        lod->changed[lod->changed_list[i]] = 0;
    lod->changed_count = 0;
    lod->relayout_from = UINT32_MAX;
}

mts_result mts_lod_announce(mts_lod *lod, uint32_t from, mts_error *err)
{
    if (from >= lod->strip_count)
        return MTS_OK;
    uint64_t at = lod->slot[from];
    for (uint32_t s = from; s < lod->strip_count; s++) {
        if (lod->length[s] != 0)
            return mts_error_set(err, MTS_ERR_INTERNAL,
                                 "lod: strip %u laid out anew while it holds indices", s);
        at += lod->model->capacity[s];
        if (at > lod->room)
            return mts_error_set(err, MTS_ERR_RANGE,
                                 "lod: strip capacities pass the %u indices reserved", lod->room);
    }
    for (uint32_t s = from; s < lod->strip_count; s++)
        lod->slot[s + 1] = lod->slot[s] + lod->model->capacity[s];
    if (from < lod->relayout_from)
        lod->relayout_from = from;
    return MTS_OK;
}

uint64_t mts_lod_memory_bytes(const mts_lod *lod)
{
    uint64_t n = lod->strip_count + 1;
    return n * (4 + 4 + 1 + 4) + (uint64_t)lod->room * 4 +
           (uint64_t)lod->scratch_size * sizeof *lod->scratch;
}

#define SPLIT_FAIL(...)                                                                    \
    do {                                                                                   \
        lod->broken = 1;                                                                   \
        return mts_error_set(err, MTS_ERR_RANGE, __VA_ARGS__);                             \
    } while (0)

mts_result mts_lod_split(mts_lod *lod, mts_error *err)
{
    const mts_model *m = lod->model;
    if (lod->broken)
        return mts_error_set(err, MTS_ERR_ARG, "lod: an earlier record failed; reload the model");
    uint32_t j = lod->level;
    if (j >= lod->available)
        return mts_error_set(err, MTS_ERR_ARG, "lod: split %u is not available", j);
    const uint32_t *p = m->record_data + m->record_offsets[j];
    const uint32_t *end = m->record_data + m->record_offsets[j + 1];
    const uint32_t v = m->base_vertex_count + j;
    const uint32_t u = m->parents[j];
    if (u >= v)
        SPLIT_FAIL("split %u: parent %u is not older than vertex %u", j, u, v);
    /* the collapse that undoes this split must find its scratch; a no-op
     * unless records came after mts_lod_init (available raised since) */
    if (end > p && !lod_reserve_scratch(lod, (uint32_t)(end - p)))
        return mts_error_set(err, MTS_ERR_NOMEM, "split %u: out of memory for its record", j);

    if (p >= end)
        SPLIT_FAIL("split %u: empty record", j);
    uint32_t edits = *p++;
    for (uint32_t e = 0; e < edits; e++) {
        if (end - p < 4)
            SPLIT_FAIL("split %u: record ends inside edit %u", j, e);
        uint32_t s = p[0], erases = p[1], inserts = p[2], substs = p[3];
        p += 4;
        if (s >= lod->strip_count)
            SPLIT_FAIL("split %u: strip %u out of range (%u strips)", j, s, lod->strip_count);
        uint32_t *str = lod->data + lod->slot[s];
        uint32_t cap = lod->slot[s + 1] - lod->slot[s];
        uint32_t len = lod->length[s];
        /* Erased runs are kept in the record so the collapse can put them
         * back: they must be what the strip holds, or the collapse would
         * restore other indices than the split removed. */
        for (uint32_t k = 0; k < erases; k++) {
            if (end - p < 2)
                SPLIT_FAIL("split %u: record ends inside an erase from strip %u", j, s);
            uint32_t pos = p[0], run = p[1];
            p += 2;
            if (pos > len || run > len - pos)
                SPLIT_FAIL("split %u: erase of %u at %u does not fit strip %u (length %u)", j,
                           run, pos, s, len);
            if ((uint32_t)(end - p) < run)
                SPLIT_FAIL("split %u: record ends inside an erase from strip %u", j, s);
            for (uint32_t r = 0; r < run; r++) {
                if (str[pos + r] != p[r])
                    SPLIT_FAIL("split %u: strip %u position %u holds %u, the record erases %u", j,
                               s, pos + r, str[pos + r], p[r]);
            }
            memmove(str + pos, str + pos + run, (size_t)(len - pos - run) * 4);
            len -= run;
            p += run;
        }
        for (uint32_t k = 0; k < inserts; k++) {
            if (end - p < 2)
                SPLIT_FAIL("split %u: record ends inside an insert into strip %u", j, s);
            uint32_t pos = p[0], run = p[1];
            p += 2;
            if (pos > len || run > cap - len)
                SPLIT_FAIL("split %u: insert of %u at %u does not fit strip %u (length %u of "
                           "capacity %u)",
                           j, run, pos, s, len, cap);
            if ((uint32_t)(end - p) < run)
                SPLIT_FAIL("split %u: record ends inside an insert into strip %u", j, s);
            for (uint32_t r = 0; r < run; r++) {
                if (p[r] >= v)
                    SPLIT_FAIL("split %u: strip %u gets vertex %u, not yet split (%u exist)", j, s,
                               p[r], v);
            }
            memmove(str + pos + run, str + pos, (size_t)(len - pos) * 4);
            memcpy(str + pos, p, (size_t)run * 4);
            len += run;
            p += run;
        }
        if ((uint32_t)(end - p) < substs)
            SPLIT_FAIL("split %u: record ends inside the positions of strip %u", j, s);
        for (uint32_t k = 0; k < substs; k++) {
            uint32_t pos = p[k];
            if (pos >= len || str[pos] != u)
                SPLIT_FAIL("split %u: strip %u position %u does not hold the parent %u", j, s, pos,
                           u);
            str[pos] = v;
        }
        p += substs;
        lod->length[s] = len;
        lod_mark(lod, s);
    }
    if (p != end)
        SPLIT_FAIL("split %u: %td words left over after %u edits", j, end - p, edits);
    lod->level = j + 1;
    return MTS_OK;
}

void mts_lod_collapse(mts_lod *lod)
{
    const mts_model *m = lod->model;
    if (lod->level == 0 || lod->broken)
        return;
    uint32_t j = lod->level - 1;
    const uint32_t *p = m->record_data + m->record_offsets[j];
    const uint32_t u = m->parents[j];
    /* Undo the edits last to first: two edits may name the same strip, and
     * then the later one's positions are in the strip as the earlier one
     * left it. Within an edit likewise: positions back to u, the inserted
     * runs out last to first, then the erased runs back in last to first,
     * each at the position it had when the split took it out. The record
     * was checked when it was split (or by mts_model_validate), so every
     * length stays within the slot (the split passed through the same
     * lengths), and mts_lod_init or that split reserved the scratch, so
     * this walk cannot fail. */
    const uint32_t **edit_at = lod->scratch;
    uint32_t edits = *p++;
    for (uint32_t e = 0; e < edits; e++) {
        edit_at[e] = p;
        uint32_t runs = p[1] + p[2], substs = p[3];
        p += 4;
        for (uint32_t k = 0; k < runs; k++)
            p += 2 + p[1];
        p += substs;
    }
    for (uint32_t e = edits; e-- > 0;) {
        const uint32_t *q = edit_at[e];
        uint32_t s = q[0], erases = q[1], inserts = q[2], substs = q[3];
        q += 4;
        /* erase runs, then insert runs, in record order */
        const uint32_t **run_at = lod->scratch + edits;
        for (uint32_t k = 0; k < erases + inserts; k++) {
            run_at[k] = q;
            q += 2 + q[1];
        }
        uint32_t *str = lod->data + lod->slot[s];
        uint32_t len = lod->length[s];
        for (uint32_t k = 0; k < substs; k++)
            str[q[k]] = u;
        for (uint32_t k = erases + inserts; k-- > erases;) {
            uint32_t pos = run_at[k][0], run = run_at[k][1];
            memmove(str + pos, str + pos + run, (size_t)(len - pos - run) * 4);
            len -= run;
        }
        for (uint32_t k = erases; k-- > 0;) {
            uint32_t pos = run_at[k][0], run = run_at[k][1];
            memmove(str + pos + run, str + pos, (size_t)(len - pos) * 4);
            memcpy(str + pos, run_at[k] + 2, (size_t)run * 4);
            len += run;
        }
        lod->length[s] = len;
        lod_mark(lod, s);
    }
    lod->level = j;
}

mts_result mts_lod_set_level(mts_lod *lod, uint32_t target, mts_error *err)
{
    if (lod->broken)
        return mts_error_set(err, MTS_ERR_ARG, "lod: an earlier record failed; reload the model");
    if (target > lod->available)
        target = lod->available;
    while (lod->level > target)
        mts_lod_collapse(lod);
    while (lod->level < target) {
        mts_result r = mts_lod_split(lod, err);
        if (r != MTS_OK)
            return r;
    }
    return MTS_OK;
}

void mts_lod_strip_stats(const mts_lod *lod, mts_strip_stats *stats)
{
    memset(stats, 0, sizeof *stats);
    for (uint32_t s = 0; s < lod->strip_count; s++)
        mts_strip_stats_add(stats, lod->data + lod->slot[s], lod->length[s]);
}
