#include "strips.h"

#include <stdlib.h>
#include <string.h>

void mts_strips_free(mts_strips *strips)
{
    if (!strips)
        return;
    mts_bigmem_release(&strips->offsets_mem, strips->offsets);
    free(strips->indices);
    strips->offsets = NULL;
    strips->indices = NULL;
    strips->strip_count = 0;
    strips->index_count = 0;
}

mts_result mts_strips_alloc(mts_strips *strips, uint32_t strip_count, uint32_t index_count,
                            mts_error *err)
{
    strips->strip_count = strip_count;
    strips->index_count = index_count;
    strips->offsets_mem = (mts_bigmem){0};
    strips->offsets = mts_bigmem_zeroed(&strips->offsets_mem,
                                        ((size_t)strip_count + 1) * sizeof *strips->offsets)
                          ? strips->offsets_mem.p
                          : NULL;
    /* +1 so that an empty set still owns a buffer and callers never see NULL */
    strips->indices = malloc(((size_t)index_count + 1) * sizeof *strips->indices);
    if (!strips->offsets || !strips->indices) {
        mts_strips_free(strips);
        return mts_error_set(err, MTS_ERR_NOMEM, "out of memory for %u strips / %u indices",
                             strip_count, index_count);
    }
    return MTS_OK;
}

int mts_tri_compare(const void *pa, const void *pb)
{
    const uint32_t *a = pa, *b = pb;
    for (int i = 0; i < 3; i++) {
        if (a[i] != b[i])
            return a[i] < b[i] ? -1 : 1;
    }
    return 0;
}

void mts_strip_stats_add(mts_strip_stats *stats, const uint32_t *s, uint32_t n)
{
    if (n == 0)
        return;
    stats->strips++;
    stats->indices += n;
    for (uint32_t k = 0; k + 2 < n; k++) {
        uint32_t tri[3];
        if (mts_strip_window(s, k, tri))
            stats->triangles++;
        else
            stats->degenerate++;
    }
}

void mts_strips_stats(const mts_strips *strips, mts_strip_stats *stats)
{
    *stats = (mts_strip_stats){0};
    for (uint32_t i = 0; i < strips->strip_count; i++)
        mts_strip_stats_add(stats, strips->indices + strips->offsets[i],
                            strips->offsets[i + 1] - strips->offsets[i]);
}

uint64_t mts_strip_stats_draw_indices(const mts_strip_stats *stats)
{
    return stats->indices + (stats->strips > 0 ? stats->strips - 1 : 0);
}

uint64_t mts_strips_pack_bound(const uint32_t *length, uint32_t count, int joined)
{
    uint64_t need = 0;
    for (uint32_t s = 0; s < count; s++)
        if (length[s] >= 3)
            need += length[s] + (joined ? 3u : 1u);
    return need;
}

uint64_t mts_strips_pack(const uint32_t *data, const uint32_t *offset, const uint32_t *length,
                         uint32_t count, uint32_t restart, int u16, void *out, uint32_t *first)
{
    uint32_t drawn = 0;
    uint32_t *o32 = out;
    uint16_t *o16 = out;
    uint64_t n = 0;
#define PUT(v) (u16 ? (void)(o16[n++] = (uint16_t)(v)) : (void)(o32[n++] = (v)))
    for (uint32_t s = 0; s < count; s++) {
        uint32_t len = length[s];
        if (len < 3)
            continue;
        const uint32_t *src = data + offset[s];
        if (n > 0) {
            if (!restart) {
                uint32_t q = u16 ? (uint32_t)o16[n - 1] : o32[n - 1];
                PUT(q);
                PUT(src[0]);
                if (n & 1u)
                    PUT(src[0]);
            } else {
                PUT(restart);
            }
        }
        if (first)
            first[drawn++] = (uint32_t)n;
        if (u16)
            for (uint32_t i = 0; i < len; i++)
                o16[n + i] = (uint16_t)src[i];
        else
            memcpy(o32 + n, src, (size_t)len * sizeof *src);
        n += len;
    }
#undef PUT
    return n;
}
