/* Split reordering within windows (see reorder.h for why). Two passes:
 * replay the collapses on an indexed face set to learn each one's closed
 * 1-ring, then per window a topological sort of the splits (an edge where
 * two rings share a vertex, from the earlier split to the later) that
 * always takes the ready split with the smallest parent id at least the
 * last one taken, else starts a new ascending run. */
#include "reorder.h"

#include <stdlib.h>
#include <string.h>

#include "words.h"

#define NONE UINT32_MAX

/* ---- a min-heap of (key << 32 | split) ---- */

typedef struct heap {
    uint64_t *a;
    uint32_t n;
} heap;

static void heap_push(heap *h, uint64_t x)
{
    uint32_t i = h->n++;
    while (i > 0) {
        uint32_t p = (i - 1) / 2;
        if (h->a[p] <= x)
            break;
        h->a[i] = h->a[p];
        i = p;
    }
    h->a[i] = x;
}

static uint64_t heap_pop(heap *h)
{
    uint64_t top = h->a[0], x = h->a[--h->n];
    uint32_t i = 0;
    for (;;) {
        uint32_t c = 2 * i + 1;
        if (c >= h->n)
            break;
        if (c + 1 < h->n && h->a[c + 1] < h->a[c])
            c++;
        if (h->a[c] >= x)
            break;
        h->a[i] = h->a[c];
        i = c;
    }
    if (h->n)
        h->a[i] = x;
    return top;
}

/* ---- pass 1: each collapse's closed 1-ring ---- */

/* Every corner of the face set is on its vertex's list (cnext); a collapse
 * walks the removed vertex's list once, kills the faces that hold both
 * ends, relabels the rest and hands them to the kept vertex. A vertex's list
 * is walked only when it is removed, so each corner is walked once a
 * collapse in its chain. */
static mts_result rings(const uint32_t *triangles, uint32_t F, uint32_t nv,
                        const mts_collapse *col, uint32_t n, mts_words *set, uint32_t *off,
                        mts_error *err)
{
    mts_result rc = MTS_ERR_NOMEM;
    uint32_t *tri = malloc(((size_t)3 * F + 1) * 4), *cnext = malloc(((size_t)3 * F + 1) * 4);
    uint32_t *first = malloc(((size_t)nv + 1) * 4), *last = malloc(((size_t)nv + 1) * 4);
    uint32_t *seen = calloc((size_t)nv + 1, 4);
    uint8_t *dead = calloc((size_t)F + 1, 1), *gone = calloc((size_t)nv + 1, 1);
    if (!tri || !cnext || !first || !last || !seen || !dead || !gone)
        goto done;
    memcpy(tri, triangles, (size_t)3 * F * 4);
    for (uint32_t x = 0; x < nv; x++)
        first[x] = last[x] = NONE;
    for (uint32_t c = 3 * F; c-- > 0;) {
        const uint32_t x = tri[c];
        if (x >= nv) {
            rc = mts_error_set(err, MTS_ERR_RANGE, "reorder: triangle index %u out of range", x);
            goto done;
        }
        cnext[c] = first[x];
        if (first[x] == NONE)
            last[x] = c;
        first[x] = c;
    }
    set->n = 0;
    for (uint32_t i = 0; i < n; i++) {
        const uint32_t r = col[i].removed, k = col[i].kept, stamp = i + 1;
        if (r >= nv || k >= nv || r == k || gone[r] || gone[k]) {
            rc = mts_error_set(err, MTS_ERR_ARG,
                               "reorder: collapse %u (%u -> %u) names a vertex that is gone", i,
                               r, k);
            goto done;
        }
        off[i] = (uint32_t)set->n;
        if (!mts_words_reserve(set, 2))
            goto done;
        set->w[set->n++] = r;
        set->w[set->n++] = k;
        seen[r] = seen[k] = stamp;
        /* r's live corners: the ring, then relabelled onto k's list */
        uint32_t head = NONE, tail = NONE;
        for (uint32_t c = first[r]; c != NONE;) {
            const uint32_t next = cnext[c], f = c / 3;
            if (!dead[f]) {
                const uint32_t *t = tri + 3 * (size_t)f;
                for (int e = 0; e < 3; e++) {
                    if (seen[t[e]] != stamp) {
                        seen[t[e]] = stamp;
                        if (!mts_words_reserve(set, 1))
                            goto done;
                        set->w[set->n++] = t[e];
                    }
                }
                if (t[0] == k || t[1] == k || t[2] == k) {
                    dead[f] = 1; /* it repeats k now */
                } else {
                    tri[c] = k;
                    cnext[c] = NONE;
                    if (tail == NONE)
                        head = c;
                    else
                        cnext[tail] = c;
                    tail = c;
                }
            }
            c = next;
        }
        if (head != NONE) {
            if (first[k] == NONE)
                first[k] = head;
            else
                cnext[last[k]] = head;
            last[k] = tail;
        }
        first[r] = last[r] = NONE;
        gone[r] = 1;
    }
    off[n] = (uint32_t)set->n;
    rc = MTS_OK;
done:
    if (rc == MTS_ERR_NOMEM)
        mts_error_set(err, MTS_ERR_NOMEM, "reorder: out of memory");
    free(tri);
    free(cnext);
    free(first);
    free(last);
    free(seen);
    free(dead);
    free(gone);
    return rc;
}

/* ---- pass 2: the windows ---- */

/* The default window where split w0 starts: a quarter of the vertices
 * there are then (16 at least, 65536 at most). Early splits matter most to
 * a level's look and come in small windows, near the decimation's order;
 * later ones in large windows, where the parents' gaps shrink to a few
 * whatever the mesh's size. On bunny00 against windows of a fixed 2 % of
 * the splits: 3 % fewer bytes, and the error at equal bytes within 0.3 %
 * up to 30 KB and 2-7 % lower beyond (docs/bytes.md). */
static uint32_t window_at(uint32_t nb, uint32_t w0, uint32_t n)
{
    const uint64_t w = ((uint64_t)nb + (w0 < n ? w0 : n)) / 4;
    return w < 16 ? 16 : w > 65536 ? 65536 : (uint32_t)w;
}

mts_result mts_reorder_collapses(const uint32_t *triangles, uint32_t triangle_count,
                                 uint32_t vertex_count, mts_collapse *collapses, uint32_t count,
                                 const mts_reorder_options *opts, mts_reorder_stats *stats,
                                 mts_error *err)
{
    static const mts_reorder_options defaults = {0};
    mts_reorder_stats dummy;
    if (!opts)
        opts = &defaults;
    if (!stats)
        stats = &dummy;
    memset(stats, 0, sizeof *stats);
    const uint32_t n = count, nv = vertex_count;
    if (n >= nv)
        return mts_error_set(err, MTS_ERR_ARG, "reorder: %u collapses for %u vertices", n, nv);
    /* windows: opts->window splits each, or by default window_at's */
    const uint32_t fixed = opts->window;
    stats->window = fixed;
    if (fixed == 1 || n < 2)
        return MTS_OK;
    const uint32_t nb = nv - n;
    /* the largest window there is, for the scratch */
    uint32_t W = fixed ? fixed : window_at(nb, n, n);
    if (W > n)
        W = n;

    mts_result rc = MTS_ERR_NOMEM;
    mts_words set = {0}, ea = {0};
    uint32_t *off = malloc(((size_t)n + 1) * 4);
    uint32_t *id = malloc(((size_t)nv + 1) * 4); /* final ids, as they become known */
    uint32_t *lastw = calloc((size_t)nv + 1, 4), *lasti = malloc(((size_t)nv + 1) * 4);
    uint32_t *indeg = malloc(((size_t)W + 1) * 4), *aoff = malloc(((size_t)W + 2) * 4);
    uint32_t *adj = NULL, *order = malloc(((size_t)n + 1) * 4);
    uint8_t *removed = calloc((size_t)nv + 1, 1);
    heap cur = {malloc(((size_t)W + 1) * 8), 0}, nxt = {malloc(((size_t)W + 1) * 8), 0};
    mts_collapse *out = malloc(((size_t)n + 1) * sizeof *out);
    if (!off || !id || !lastw || !lasti || !indeg || !aoff || !order || !removed || !cur.a ||
        !nxt.a || !out)
        goto nomem;
    if ((rc = rings(triangles, triangle_count, nv, collapses, n, &set, off, err)) != MTS_OK)
        goto fail;
    rc = MTS_ERR_NOMEM;
    /* survivors: 0..nb-1 as lodbuild numbers them */
    for (uint32_t c = 0; c < n; c++)
        removed[collapses[c].removed] = 1;
    for (uint32_t x = 0, next = 0; x < nv; x++)
        id[x] = removed[x] ? NONE : opts->base_ids ? opts->base_ids[x] : next++;
    uint64_t prev = 0;
    uint32_t placed = 0;
    for (uint32_t w0 = 0, stamp = 1, ws; w0 < n; w0 += ws, stamp++) {
        ws = fixed ? fixed : window_at(nb, w0, n);
        ws = ws < n - w0 ? ws : n - w0;
        stats->windows++;
        /* split w0 + i is collapse n - 1 - (w0 + i); an edge wherever two
         * rings share a vertex, from the last split to touch it */
        ea.n = 0;
        for (uint32_t i = 0; i < ws; i++) {
            const uint32_t c = n - 1 - (w0 + i);
            for (uint32_t q = off[c]; q < off[c + 1]; q++) {
                const uint32_t x = set.w[q];
                if (lastw[x] == stamp && lasti[x] != i) {
                    if (!mts_words_reserve(&ea, 2))
                        goto nomem;
                    ea.w[ea.n++] = lasti[x];
                    ea.w[ea.n++] = i;
                }
                lastw[x] = stamp;
                lasti[x] = i;
            }
        }
        const size_t ne = ea.n / 2;
        stats->conflicts += ne;
        uint32_t *grown = realloc(adj, (ne + 1) * 4);
        if (!grown)
            goto nomem;
        adj = grown;
        memset(indeg, 0, (size_t)ws * 4);
        memset(aoff, 0, ((size_t)ws + 2) * 4);
        for (size_t e = 0; e < ne; e++) {
            indeg[ea.w[2 * e + 1]]++;
            aoff[ea.w[2 * e] + 2]++;
        }
        for (uint32_t i = 0; i < ws; i++)
            aoff[i + 2] += aoff[i + 1];
        for (size_t e = 0; e < ne; e++)
            adj[aoff[ea.w[2 * e] + 1]++] = ea.w[2 * e + 1];
        /* aoff[i + 1] is now the end of i's successors, aoff[i] their start */
#define KEY(i) ((uint64_t)id[collapses[n - 1 - (w0 + (i))].kept])
#define READY(i)                                                                                   \
    do {                                                                                           \
        uint64_t key_ = KEY(i);                                                                    \
        heap_push(key_ >= prev ? &cur : &nxt, key_ << 32 | (i));                                   \
    } while (0)
        for (uint32_t i = 0; i < ws; i++) {
            if (!indeg[i])
                READY(i);
        }
        for (uint32_t done = 0; done < ws; done++) {
            if (cur.n == 0) { /* a new ascending run */
                heap t = cur;
                cur = nxt;
                nxt = t;
                stats->runs++;
            }
            const uint32_t i = (uint32_t)(heap_pop(&cur) & 0xFFFFFFFFu);
            const uint32_t c = n - 1 - (w0 + i);
            prev = KEY(i);
            id[collapses[c].removed] = nb + placed;
            order[placed++] = c;
            for (uint32_t q = aoff[i]; q < aoff[i + 1]; q++) {
                if (--indeg[adj[q]] == 0)
                    READY(adj[q]);
            }
        }
#undef READY
#undef KEY
    }
    /* split p is collapse order[p]: back to collapse order */
    for (uint32_t p = 0; p < n; p++)
        out[n - 1 - p] = collapses[order[p]];
    memcpy(collapses, out, (size_t)n * sizeof *out);
    rc = MTS_OK;
    goto fail;
nomem:
    rc = mts_error_set(err, MTS_ERR_NOMEM, "reorder: out of memory");
fail:
    free(set.w);
    free(ea.w);
    free(off);
    free(id);
    free(lastw);
    free(lasti);
    free(indeg);
    free(aoff);
    free(adj);
    free(order);
    free(removed);
    free(cur.a);
    free(nxt.a);
    free(out);
    return rc;
}
