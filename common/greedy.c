/* Greedy strip paths in the manner of STRIPE:
 *   F. Evans, S. Skiena, A. Varshney, "Optimizing Triangle Strips for Fast
 *   Rendering", IEEE Visualization 1996,
 * (see greedy.h for why this exists beside stripify.c).
 *
 * A strip is walked as stripify.c walks it: at triangle t its last two
 * indices sit at corners q and r, the third corner is p; leaving across edge
 * (q, r) keeps the strip's alternation, leaving across (p, r) costs a swap.
 * The seed is a free triangle with the fewest free neighbours (the most
 * recently lowered first, so that strips lie side by side); the path leaves
 * it towards its neighbour with the fewest free neighbours and grows on,
 * preferring, STRIPE's way, the neighbour with fewer free neighbours of its
 * own (taking the swap for it). Everything is corner
 * and half-edge indices: crossing half-edge e of t into t' = twin / 3 lands
 * on edge e' = twin % 3 of t', whose corner e' is corner e + 1 of t. */
#include "greedy.h"

#include <stdlib.h>
#include <string.h>

#include "striplinks.h"

#define NONE MTS_GREEDY_NONE

static const uint8_t NX[3] = {1, 2, 0}, PV[3] = {2, 0, 1};

/* Per triangle one byte, so that looking at a neighbour costs one cache
 * line besides its twins: its free neighbours (bits 0-1), whether a path
 * holds it. */
enum { DEG = 3, USED = 4 };

typedef struct ctx {
    uint32_t n;
    const uint32_t *twin;
    size_t stride;
    uint8_t *flag;
    uint32_t *bucket[3]; /* seed candidates by degree 0..2 (stacks, lazily updated) */
    uint32_t bucket_len[3];
    uint32_t cursor; /* lowest id that may still have degree 3 */
} ctx;

static inline uint32_t twin_of(const ctx *c, uint32_t t, unsigned e)
{
    return c->twin[c->stride * t + e];
}

static inline uint32_t neighbour(const ctx *c, uint32_t t, unsigned e)
{
    uint32_t h = twin_of(c, t, e);
    return h == NONE ? NONE : h / 3;
}

static inline int avail(const ctx *c, uint32_t t)
{
    return t != NONE && !(c->flag[t] & USED);
}

/* Free neighbours of x other than `from`. */
static inline unsigned free_degree(const ctx *c, uint32_t x, uint32_t from)
{
    unsigned d = 0;
    for (unsigned e = 0; e < 3; e++) {
        uint32_t w = neighbour(c, x, e);
        if (w != from && avail(c, w))
            d++;
    }
    return d;
}

/* Crosses half-edge e of t, the strip's last index at corner lr of t (an end
 * of e): the neighbour, and in it that index's corner (*q) and the corner
 * the next index will be (*r). */
static inline uint32_t cross(const ctx *c, uint32_t t, unsigned e, unsigned lr, unsigned *q,
                             unsigned *r)
{
    uint32_t h = twin_of(c, t, e);
    unsigned e2 = h % 3;
    *q = lr == NX[e] ? e2 : NX[e2];
    *r = PV[e2];
    return h / 3;
}

/* Grows a path on from t, whose strip ends at corners (lq, lr): appends the
 * triangles it takes to out, at most limit, marks them used (commit counts
 * their neighbours down) and returns their number. */
static uint32_t grow(ctx *c, uint32_t t, unsigned lq, unsigned lr, uint32_t *out, uint32_t limit)
{
    uint32_t len = 0;
    while (len < limit) {
        unsigned lp = 3 - lq - lr, ef = mts__edge_of(lq, lr), es = mts__edge_of(lp, lr);
        uint32_t f = neighbour(c, t, ef), s = neighbour(c, t, es);
        int fa = avail(c, f), sa = avail(c, s) && s != f;
        if (!fa && !sa)
            break;
        /* go where fewer free neighbours remain, so that the other one is
         * not left stranded; the swap only when strictly better */
        int take_swap = !fa || (sa && free_degree(c, s, t) < free_degree(c, f, t));
        uint32_t u = cross(c, t, take_swap ? es : ef, lr, &lq, &lr);
        c->flag[u] |= USED;
        out[len++] = u;
        t = u;
    }
    return len;
}

/* Whether a strip read along a, b, c needs a swap at b, the first
 * triangle's rotation being the one that leaves it without one. Only this
 * swap depends on the way a path is read: inside it, a swap is where two
 * consecutive triangles turn round the same vertex, either way round
 * (stripify.c). */
static int start_swap(const ctx *c, uint32_t a, uint32_t b, uint32_t d)
{
    unsigned e = 0;
    while (neighbour(c, a, e) != b)
        e++;
    unsigned lq, lr;
    cross(c, a, e, NX[e], &lq, &lr);
    return neighbour(c, b, mts__edge_of(lq, lr)) != d;
}

static uint32_t next_seed(ctx *c)
{
    for (unsigned d = 0; d < 3; d++) {
        while (c->bucket_len[d] > 0) {
            uint32_t t = c->bucket[d][--c->bucket_len[d]];
            if (c->flag[t] == d) /* not used, degree d */
                return t;
        }
    }
    while (c->cursor < c->n && c->flag[c->cursor] != 3)
        c->cursor++;
    return c->cursor < c->n ? c->cursor : NONE;
}

/* t joins a path: its free neighbours have one free neighbour fewer. */
static void commit(ctx *c, uint32_t t)
{
    c->flag[t] = USED;
    for (unsigned e = 0; e < 3; e++) {
        uint32_t u = neighbour(c, t, e);
        if (u != NONE && !(c->flag[u] & USED)) {
            unsigned d = (c->flag[u] & DEG) - 1u;
            c->flag[u] = (uint8_t)((c->flag[u] & ~DEG) | d);
            c->bucket[d][c->bucket_len[d]++] = u;
        }
    }
}

mts_result mts_greedy_paths(uint32_t n, const uint32_t *twin, size_t stride, uint32_t max_path,
                            uint32_t *order, uint32_t *starts, uint32_t *path_count,
                            mts_error *err)
{
    *path_count = 0;
    starts[0] = 0;
    if (n == 0)
        return MTS_OK;
    if (n > (UINT32_MAX - 1) / 3)
        return mts_error_set(err, MTS_ERR_LIMIT, "greedy: %u triangles is too many", n);
    if (stride < 3)
        return mts_error_set(err, MTS_ERR_ARG, "greedy: twins %zu apart", stride);
    if (max_path < 1)
        max_path = 1;
    if (max_path > n)
        max_path = n;
    mts_result rc = MTS_OK;
    ctx c = {0};
    c.n = n;
    c.twin = twin;
    c.stride = stride;
    c.flag = malloc(n);
    for (int d = 0; d < 3; d++)
        c.bucket[d] = malloc((size_t)n * sizeof *c.bucket[d]);
    uint32_t *best = malloc((size_t)max_path * sizeof *best);
    if (!c.flag || !c.bucket[0] || !c.bucket[1] || !c.bucket[2] || !best) {
        rc = mts_error_set(err, MTS_ERR_NOMEM, "greedy: out of memory for %u triangles", n);
        goto done;
    }
    for (uint32_t t = 0; t < n; t++) {
        unsigned d = 0;
        for (unsigned e = 0; e < 3; e++)
            d += twin_of(&c, t, e) != NONE;
        c.flag[t] = (uint8_t)d;
        if (d < 3)
            c.bucket[d][c.bucket_len[d]++] = t;
    }
    mts__buckets_lowest_first(c.bucket, c.bucket_len);

    uint32_t placed = 0, paths = 0;
    for (;;) {
        uint32_t seed = next_seed(&c);
        if (seed == NONE)
            break;
        /* out of the seed towards its neighbour with the fewest free
         * neighbours of its own (STRIPE's start; trying every way out, as
         * NvTriStrip does, made more strips here, and slower) */
        uint32_t best_m = 1, way = 3;
        unsigned fewest = 4;
        for (unsigned e = 0; e < 3 && max_path > 1; e++) {
            uint32_t u = neighbour(&c, seed, e);
            unsigned d = avail(&c, u) ? free_degree(&c, u, seed) : 4;
            if (d < fewest) {
                fewest = d;
                way = e;
            }
        }
        best[0] = seed;
        if (way < 3) {
            unsigned lq, lr;
            best[1] = cross(&c, seed, way, NX[way], &lq, &lr);
            c.flag[seed] |= USED;
            c.flag[best[1]] |= USED;
            best_m = 2 + grow(&c, best[1], lq, lr, best + 2, max_path - 2);
        }
        /* read from the end that does not start with a swap, if one does */
        if (best_m >= 3 && start_swap(&c, best[0], best[1], best[2]) &&
            !start_swap(&c, best[best_m - 1], best[best_m - 2], best[best_m - 3])) {
            for (uint32_t i = 0, j = best_m - 1; i < j; i++, j--) {
                uint32_t x = best[i];
                best[i] = best[j];
                best[j] = x;
            }
        }
        for (uint32_t k = 0; k < best_m; k++) {
            commit(&c, best[k]);
            order[placed++] = best[k];
        }
        starts[++paths] = placed;
    }
    if (placed != n)
        rc = mts_error_set(err, MTS_ERR_INTERNAL, "greedy: paths hold %u of %u triangles", placed,
                           n);
    *path_count = paths;
done:
    free(c.flag);
    for (int d = 0; d < 3; d++)
        free(c.bucket[d]);
    free(best);
    return rc;
}
