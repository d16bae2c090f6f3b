/* A set of triangle strips in flat arrays: strip s is
 * indices[offsets[s] .. offsets[s+1]). Strip winding (docs/architecture.md, invariant 1):
 * window k of a strip is (s[k], s[k+1], s[k+2]) for even k and
 * (s[k+1], s[k], s[k+2]) for odd k; a window with a repeated index is a
 * degenerate triangle and draws nothing. Strips are generalized: a swap is a
 * repeated index, and every strip starts at even parity (as it does after a
 * primitive restart). */
#ifndef MTS_STRIPS_H
#define MTS_STRIPS_H

#include <stdint.h>

#include "bigmem.h"
#include "error.h"

/* The most triangles a strip draws, at every level: it bounds the
 * stripifier's work per change and what a per-strip update re-sends, and
 * the runtime's growth and key-level restripification keep to it too. */
#define MTS_STRIPIFY_MAX_STRIP 256u
#define MTS_STRIPIFY_MAX_STRIP_STR "256"

typedef struct mts_strips {
    uint32_t strip_count;
    uint32_t index_count; /* == offsets[strip_count] */
    uint32_t *offsets;    /* strip_count + 1 entries */
    uint32_t *indices;
    /* where mts_strips_alloc put offsets (zero until written, so a count
     * a stream claims costs no memory before strips arrive); empty where
     * offsets is a malloc block */
    mts_bigmem offsets_mem;
} mts_strips;

/* Figures a stripifier or a level is judged by. */
typedef struct mts_strip_stats {
    uint32_t strips;        /* non-empty strips */
    uint64_t indices;       /* sum of strip lengths (no restart markers) */
    uint64_t triangles;     /* non-degenerate windows */
    uint64_t degenerate;    /* degenerate windows (swaps and collapse leftovers) */
} mts_strip_stats;

void mts_strips_free(mts_strips *strips);

/* Allocates offsets for strip_count strips and room for index_count indices. */
mts_result mts_strips_alloc(mts_strips *strips, uint32_t strip_count, uint32_t index_count,
                            mts_error *err);

/* The oriented triangle of window k of strip s (length n >= k + 3); returns 0
 * when the window is degenerate. */
static inline int mts_strip_window(const uint32_t *s, uint32_t k, uint32_t tri[3])
{
    uint32_t a = s[k], b = s[k + 1], c = s[k + 2];
    if (a == b || b == c || a == c)
        return 0;
    if (k & 1u) {
        tri[0] = b; tri[1] = a; tri[2] = c;
    } else {
        tri[0] = a; tri[1] = b; tri[2] = c;
    }
    return 1;
}

/* Rotates an oriented triangle so that its smallest index comes first: two
 * triangles are the same oriented triangle iff their canonical forms are equal. */
static inline void mts_tri_canonical(uint32_t t[3])
{
    uint32_t a = t[0], b = t[1], c = t[2];
    if (b < a && b < c) {
        t[0] = b; t[1] = c; t[2] = a;
    } else if (c < a && c < b) {
        t[0] = c; t[1] = a; t[2] = b;
    }
}

/* qsort comparator over canonical triangles (3 x uint32_t). */
int mts_tri_compare(const void *a, const void *b);

/* Adds one strip's figures to stats. */
void mts_strip_stats_add(mts_strip_stats *stats, const uint32_t *s, uint32_t n);

void mts_strips_stats(const mts_strips *strips, mts_strip_stats *stats);

/* Indices a renderer sends for these strips joined by primitive restart:
 * every index plus one restart marker between consecutive non-empty strips. */
uint64_t mts_strip_stats_draw_indices(const mts_strip_stats *stats);

/* One draw for a set of strips (strip s at data + offset[s], length[s]
 * long; strips shorter than 3 draw nothing and are left out), packed one
 * after another: joined (restart 0), strip b follows the strip before it
 * (ending in q) after q b0, and once more b0 when that leaves b0 at an odd
 * position, so every strip starts at an even position (keeps its winding)
 * and each window across a joint repeats an index (draws nothing); or with
 * the index `restart` between strips. 16-bit output (u16) when every index
 * fits. out holds mts_strips_pack_bound() entries; returns the count.
 * first, when not NULL, gets where each strip drawn begins in out (one
 * entry a strip of 3 or more, in order). */
uint64_t mts_strips_pack_bound(const uint32_t *length, uint32_t count, int joined);
uint64_t mts_strips_pack(const uint32_t *data, const uint32_t *offset, const uint32_t *length,
                         uint32_t count, uint32_t restart, int u16, void *out, uint32_t *first);

#endif
