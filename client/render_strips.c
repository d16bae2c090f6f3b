/* The renderer's index side (render_state.h says how the renderer is
 * split): each strip in its slot of the slot buffer and of its host copy,
 * the slots laid out anew as a stream announces them, the packed buffer the
 * default draw reads, rebuilt from the host copy, and the wireframe's lines. */
#include "render.h"
#include "render_internal.h"
#include "render_state.h"

#include <GLES3/gl32.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "follow.h"

/* ---- the slot buffer -------------------------------------------------- */

/* Checks that strip s may hold these indices. */
static mts_result check_strip(const mts_renderer *r, uint32_t s, const uint32_t *idx,
                              uint32_t len, mts_error *err)
{
    if (s >= r->strip_count)
        return mts_error_set(err, MTS_ERR_RANGE, "render: strip %u of %u", s, r->strip_count);
    if (len > r->capacity[s])
        return mts_error_set(err, MTS_ERR_RANGE,
                             "render: strip %u has %u indices, its slot holds %u", s, len,
                             r->capacity[s]);
    uint32_t nv = r->stats.vertices;
    for (uint32_t i = 0; i < len; i++)
        if (idx[i] >= nv)
            return mts_error_set(err, MTS_ERR_RANGE,
                                 "render: strip %u position %u is vertex %u, but %u vertices "
                                 "are uploaded",
                                 s, i, idx[i], nv);
    return MTS_OK;
}

/* what the packed buffer holds (packed_kind; -1: stale) */
enum { PACK_JOINED = 0, PACK_COMPACT = 1 };

/* The packed buffer is drawn unless each strip is drawn in its colour. */
static int draws_packed(const mts_renderer *r)
{
    return !r->opts.style.color_by_strip;
}

/* Room for `need` indices in the strip buffer (at most index_limit), at
 * least doubled: the host copy grows, and the GPU's buffer is made anew,
 * to be filled whole at the next update (slots_stale). */
static mts_result grow_indices(mts_renderer *r, uint64_t need, mts_error *err)
{
    uint64_t cap = 2ull * r->index_count;
    if (cap < need)
        cap = need;
    if (cap > r->index_limit)
        cap = r->index_limit;
    uint32_t *host = realloc(r->host, (size_t)(cap ? cap : 1) * sizeof *host);
    if (!host)
        return mts_error_set(err, MTS_ERR_NOMEM, "render: %llu indices",
                             (unsigned long long)cap);
    r->host = host;
    mts_result rc = mts_render_context_make_current(r->ctx, err);
    if (rc != MTS_OK)
        return rc;
    glBindVertexArray(r->vao);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, r->ibo);
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)(cap * 4u), NULL, GL_DYNAMIC_DRAW);
    glBindVertexArray(0);
    r->stats.index_buffer_bytes = cap * 4u;
    r->index_count = cap;
    r->offset[r->strip_count] = (uint32_t)cap;
    r->slots_stale = 1;
    r->packed_kind = -1;
    return mts__render_gl_check(err, "growing the strip buffer");
}

uint64_t mts__render_upload_slots(mts_renderer *r)
{
    uint32_t *all = malloc((size_t)(r->index_count ? r->index_count : 1) * sizeof *all);
    if (!all)
        return 0;
    for (uint64_t i = 0; i < r->index_count; i++)
        all[i] = MTS_RENDER_RESTART_INDEX;
    for (uint32_t s = 0; s < r->strip_count; s++)
        memcpy(all + r->offset[s], r->host + r->offset[s], (size_t)r->length[s] * sizeof *all);
    glBufferSubData(GL_ELEMENT_ARRAY_BUFFER, 0, (GLsizeiptr)(r->index_count * 4u), all);
    free(all);
    r->slots_stale = 0;
    r->stats.full_uploads++;
    r->stats.index_bytes_uploaded += r->index_count * 4u;
    return r->index_count * 4u;
}

/* Strip s (checked) into the host copy and, unless the packed buffer is
 * what draws (then the slot buffer catches up when a mode reads it), into
 * the slot buffer over max(old, new) entries; the index buffer is bound. */
static uint64_t put_strip(mts_renderer *r, uint32_t s, const uint32_t *idx, uint32_t len)
{
    uint32_t old = r->length[s];
    uint32_t n = len > old ? len : old;
    if (n == 0)
        return 0;
    if (r->slots_stale || draws_packed(r)) {
        memcpy(r->host + r->offset[s], idx, (size_t)len * sizeof *idx);
        r->packed_kind = -1;
        r->length[s] = len;
        r->slots_stale = 1;
        return 0;
    }
    memcpy(r->staging, idx, (size_t)len * sizeof *idx);
    for (uint32_t i = len; i < n; i++)
        r->staging[i] = MTS_RENDER_RESTART_INDEX;
    memcpy(r->host + r->offset[s], idx, (size_t)len * sizeof *idx);
    r->packed_kind = -1;
    glBufferSubData(GL_ELEMENT_ARRAY_BUFFER, (GLintptr)((uint64_t)r->offset[s] * 4u),
                    (GLsizeiptr)((uint64_t)n * 4u), r->staging);
    r->length[s] = len;
    r->stats.strip_uploads++;
    return (uint64_t)n * 4u;
}

mts_result mts_render_set_strip(mts_renderer *r, uint32_t s, const uint32_t *indices,
                                uint32_t length, mts_error *err)
{
    if (!r || (length && !indices))
        return mts_error_set(err, MTS_ERR_ARG, "render: NULL argument to set_strip");
    mts_result rc = check_strip(r, s, indices, length, err);
    if (rc != MTS_OK)
        return rc;
    rc = mts_render_context_make_current(r->ctx, err);
    if (rc != MTS_OK)
        return rc;
    glBindVertexArray(r->vao);
    uint64_t bytes = put_strip(r, s, indices, length);
    glBindVertexArray(0);
    rc = mts__render_gl_check(err, "uploading a strip");
    if (rc != MTS_OK)
        return rc;
    r->stats.last_update_strips = 1;
    r->stats.last_update_bytes = bytes;
    r->stats.last_update_full = 0;
    r->stats.index_bytes_uploaded += bytes;
    return MTS_OK;
}

/* Slots from lod->relayout_from on, as lod now lays them out: they were
 * empty (a stream announces a slot before it is used), so nothing moves in
 * the buffer, and what lies there is restarts still. */
static mts_result relayout(mts_renderer *r, const mts_lod *lod, mts_error *err)
{
    const uint32_t from = lod->relayout_from, n = r->strip_count;
    if ((uint64_t)lod->slot[n] + n > r->index_limit)
        return mts_error_set(err, MTS_ERR_RANGE,
                             "render: the slots grow to %u indices, past the buffer's %llu",
                             lod->slot[n], (unsigned long long)r->index_limit - n);
    if ((uint64_t)lod->slot[n] + n > r->index_count) {
        mts_result rc = grow_indices(r, (uint64_t)lod->slot[n] + n, err);
        if (rc != MTS_OK)
            return rc;
    }
    uint32_t longest = r->max_capacity;
    for (uint32_t s = from; s < n; s++) {
        if (r->length[s] != 0)
            return mts_error_set(err, MTS_ERR_INTERNAL,
                                 "render: strip %u laid out anew while it is drawn", s);
        const uint32_t cap = lod->slot[s + 1] - lod->slot[s];
        longest = cap > longest ? cap : longest;
    }
    if (longest > r->max_capacity) {
        uint32_t *st = realloc(r->staging, ((size_t)longest + 1) * sizeof *st);
        if (!st)
            return mts_error_set(err, MTS_ERR_NOMEM, "render: staging for %u indices", longest);
        r->staging = st;
        r->max_capacity = longest;
    }
    for (uint32_t s = from; s < n; s++) {
        r->offset[s] = lod->slot[s] + s;
        r->capacity[s] = lod->slot[s + 1] - lod->slot[s];
    }
    r->packed_kind = -1; /* any packed copy was laid out from the old offsets */
    return MTS_OK;
}

mts_result mts_render_update_strips(mts_renderer *r, const mts_lod *lod, mts_error *err)
{
    if (!r || !lod)
        return mts_error_set(err, MTS_ERR_ARG, "render: NULL argument to update_strips");
    if (lod->strip_count != r->strip_count)
        return mts_error_set(err, MTS_ERR_ARG, "render: runtime has %u strips, renderer %u",
                             lod->strip_count, r->strip_count);
    if (lod->relayout_from < r->strip_count) {
        mts_result rc = relayout(r, lod, err);
        if (rc != MTS_OK)
            return rc;
    }
    uint32_t count = 0;
    const uint32_t *changed = mts_lod_changed(lod, &count);
    r->stats.last_update_strips = 0;
    r->stats.last_update_bytes = 0;
    r->stats.last_update_full = 0;
    if (count == 0)
        return MTS_OK;
    for (uint32_t i = 0; i < count; i++) {
        uint32_t len;
        const uint32_t *idx = mts_lod_strip(lod, changed[i], &len);
        mts_result rc = check_strip(r, changed[i], idx, len, err);
        if (rc != MTS_OK)
            return mts_error_prefix(err, "update at level %u", lod->level);
    }
    mts_result rc = mts_render_context_make_current(r->ctx, err);
    if (rc != MTS_OK)
        return rc;
    glBindVertexArray(r->vao);
    uint64_t bytes = 0;
    /* drawing the slot buffer: many strips, or a buffer left behind by
     * packed draws, go up whole; the packed path leaves it behind */
    int full = ((uint64_t)count * 2u > r->strip_count || r->slots_stale) && !draws_packed(r);
    if (full) {
        /* one upload of the whole buffer beats thousands of small ones */
        uint32_t *all = malloc((size_t)r->index_count * sizeof *all);
        if (!all) {
            glBindVertexArray(0);
            return mts_error_set(err, MTS_ERR_NOMEM, "render: %llu indices",
                                 (unsigned long long)r->index_count);
        }
        uint64_t end = 0;
        for (uint32_t s = 0; s < r->strip_count; s++) {
            uint32_t len;
            const uint32_t *idx = mts_lod_strip(lod, s, &len);
            uint32_t *dst = all + r->offset[s];
            memcpy(dst, idx, (size_t)len * sizeof *idx);
            for (uint32_t i = len; i <= r->capacity[s]; i++)
                dst[i] = MTS_RENDER_RESTART_INDEX;
            r->length[s] = len;
            end = (uint64_t)r->offset[s] + r->capacity[s] + 1;
        }
        /* room past the slots laid out so far holds restarts too */
        for (uint64_t i = end; i < r->index_count; i++)
            all[i] = MTS_RENDER_RESTART_INDEX;
        bytes = r->index_count * 4u;
        glBufferSubData(GL_ELEMENT_ARRAY_BUFFER, 0, (GLsizeiptr)bytes, all);
        memcpy(r->host, all, (size_t)r->index_count * sizeof *all);
        r->packed_kind = -1;
        r->slots_stale = 0;
        free(all);
    } else {
        for (uint32_t i = 0; i < count; i++) {
            uint32_t len;
            const uint32_t *idx = mts_lod_strip(lod, changed[i], &len);
            bytes += put_strip(r, changed[i], idx, len);
        }
    }
    glBindVertexArray(0);
    rc = mts__render_gl_check(err, "uploading strips");
    if (rc != MTS_OK)
        return rc;
    r->stats.last_update_strips = full ? r->strip_count : count;
    r->stats.last_update_bytes = bytes;
    r->stats.last_update_full = full;
    if (full)
        r->stats.full_uploads++;
    r->stats.index_bytes_uploaded += bytes;
    return MTS_OK;
}

/* ---- the packed buffer ------------------------------------------------ */

/* Rebuilds the packed buffer for COMPACT or JOINED from the host copy of
 * the strips (follow.h's packing, the page's too). */
static mts_result build_packed(mts_renderer *r, int kind, mts_error *err)
{
    uint32_t restart = kind == PACK_JOINED ? 0
                       : r->packed_u16     ? 0xFFFFu
                                           : MTS_RENDER_RESTART_INDEX;
    mts_result rc = mts_follow_pack_strips(&r->packed, r->host, r->offset, r->length,
                                           r->strip_count, restart, r->packed_u16, 0, err);
    if (rc != MTS_OK)
        return rc;
    uint64_t n = r->packed.count;
    size_t esize = r->packed_u16 ? 2u : 4u;
    if (!r->packed_ibo)
        glGenBuffers(1, &r->packed_ibo);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, r->packed_ibo);
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)(n ? n * esize : esize),
                 n ? r->packed.indices : NULL, GL_DYNAMIC_DRAW);
    r->packed_count = n;
    r->packed_kind = kind;
    r->stats.packed_builds++;
    r->stats.packed_bytes = n * esize;
    r->stats.index_bytes_uploaded += n * esize;
    return MTS_OK;
}

mts_result mts__render_packed(mts_renderer *r, int compact, unsigned *ibo, uint64_t *count,
                              int *u16, mts_error *err)
{
    int kind = compact ? PACK_COMPACT : PACK_JOINED;
    if (r->packed_kind != kind) {
        mts_result rc = build_packed(r, kind, err);
        if (rc != MTS_OK)
            return rc;
    }
    *ibo = r->packed_ibo;
    *count = r->packed_count;
    *u16 = r->packed_u16;
    return MTS_OK;
}

/* ---- the wireframe ---------------------------------------------------- */

mts_result mts_render_update_wireframe(mts_renderer *r, const mts_lod *lod, mts_error *err)
{
    if (!r || !lod)
        return mts_error_set(err, MTS_ERR_ARG, "render: NULL argument to update_wireframe");
    if (lod->strip_count != r->strip_count)
        return mts_error_set(err, MTS_ERR_ARG, "render: runtime has %u strips, renderer %u",
                             lod->strip_count, r->strip_count);
    uint64_t windows = 0;
    for (uint32_t s = 0; s < lod->strip_count; s++)
        windows += lod->length[s] >= 3 ? lod->length[s] - 2 : 0;
    if (windows * 6u > (uint64_t)INT32_MAX)
        return mts_error_set(err, MTS_ERR_LIMIT, "render: %llu wireframe indices",
                             (unsigned long long)windows * 6u);
    uint32_t *lines = malloc((size_t)(windows ? windows : 1) * 6u * sizeof *lines);
    if (!lines)
        return mts_error_set(err, MTS_ERR_NOMEM, "render: %llu wireframe indices",
                             (unsigned long long)windows * 6u);
    uint64_t n = 0;
    uint32_t nv = r->stats.vertices;
    for (uint32_t s = 0; s < lod->strip_count; s++) {
        uint32_t len;
        const uint32_t *idx = mts_lod_strip(lod, s, &len);
        for (uint32_t k = 0; k + 2 < len; k++) {
            uint32_t a = idx[k], b = idx[k + 1], c = idx[k + 2];
            if (a == b || b == c || a == c) /* a swap or a collapse leftover */
                continue;
            if (a >= nv || b >= nv || c >= nv) {
                free(lines);
                return mts_error_set(err, MTS_ERR_RANGE,
                                     "render: strip %u uses vertex %u of %u uploaded", s,
                                     a >= nv ? a : b >= nv ? b : c, nv);
            }
            uint32_t *o = lines + n;
            o[0] = a, o[1] = b, o[2] = b, o[3] = c, o[4] = c, o[5] = a;
            n += 6;
        }
    }
    mts_result rc = mts_render_context_make_current(r->ctx, err);
    if (rc == MTS_OK) {
        if (!r->wire_ibo)
            glGenBuffers(1, &r->wire_ibo);
        glBindVertexArray(0);
        glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, r->wire_ibo);
        glBufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)(n * 4u), n ? lines : NULL,
                     GL_DYNAMIC_DRAW);
        glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, 0);
        r->wire_count = n;
        rc = mts__render_gl_check(err, "uploading the wireframe");
    }
    free(lines);
    return rc;
}
