#include "strips.h"

#include <stdlib.h>

void mts_strips_free(mts_strips *strips)
{
    if (!strips)
        return;
    free(strips->offsets);
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
    strips->offsets = calloc((size_t)strip_count + 1, sizeof *strips->offsets);
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
