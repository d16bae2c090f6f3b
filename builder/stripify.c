/* Greedy stripifier in the manner of STRIPE:
 *   F. Evans, S. Skiena, A. Varshney, "Optimizing Triangle Strips for Fast
 *   Rendering", IEEE Visualization 1996,
 * with NvTriStrip's trial of every start rotation, followed by a tunnelling
 * pass after
 *   A. J. Stewart, "Tunneling for Triangle Strips in Continuous
 *   Level-of-Detail Meshes", Graphics Interface 2001.
 *
 * The cost model. A strip is a path in the dual graph (triangles joined
 * across shared edges). Walking a path, a triangle is left across one of its
 * two edges other than the entry edge: the "free" one keeps the strip's
 * alternation and costs one index, the other needs a swap (one repeated
 * index) first. Seen without a direction: every interior triangle of a path
 * turns around its "pivot", the vertex its two path edges share, and a swap
 * is needed exactly where two consecutive triangles of a path have the same
 * pivot (the strip fans around one vertex), plus at most one at the start
 * (the second triangle's turn is fixed by parity; reading the path from the
 * other end may avoid it). A cover with S paths and W swaps therefore costs
 *   triangles + 2 S + W indices, plus S - 1 primitive restarts,
 * and all the heuristics below try to make 3 S + W small: a swap (1) is much
 * cheaper than a new strip (3).
 *
 * Phases:
 *  1. adjacency across manifold, consistently oriented edges only (two
 *     counting sorts of the half-edges, O(n + V)); every other edge counts
 *     as a border, so any input gives correct strips, only longer ones
 *     (striplinks.c, shared with tunnel.c);
 *  2. greedy paths: the seed is a free triangle with the fewest free
 *     neighbours; from each of its 3 rotations a path grows, and the one
 *     with the fewest indices per triangle wins. Growing prefers, STRIPE's
 *     way, the neighbour with fewer free neighbours of its own (taking the
 *     swap for it), so that no triangle is stranded as a strip of its own;
 *     on ties it goes on without a swap. Paths grow forwards only: growing
 *     them backwards from the seed as well did not pay (docs/strips.md);
 *  3. tunnelling: short alternating sequences of "link an end into a path,
 *     cut the path next to it" that end by joining two ends (one strip
 *     fewer) or that remove swaps, kept when 3 S + W drops; searched from
 *     every path end and from every swap (cut there first), depth 4, in
 *     passes until nothing changes. The search is tunnel.c's
 *     (mts__tunnel_search), the one the builder runs again after;
 *  4. encoding each path into indices with the winding of strips.h
 *     (striplinks.c).
 * The link structure of 3. (cover masks, labels, undo log, the moves and
 * their costs) is striplinks.h's.
 * Measured figures and the variants that lost: docs/strips.md.
 */
#include "stripify.h"

#include <stdlib.h>
#include <string.h>

#include "striplinks.h"
#include "words.h"

#define NONE MTS__NONE

/* The tunnelling search's depth (link/cut steps), from path ends and from
 * the two ends of a cut swap, and the most a partial tunnel may cost: fixed
 * by measurement (docs/strips.md, "The stripifier"); tunnel.c searches
 * shallower but wider after. Paths grow forwards from their seed only: growing them
 * backwards too gained nothing once tunnelling runs. */
enum { TUNNEL_DEPTH = 4, TUNNEL_CUT_DEPTH = 4, TUNNEL_BOUND = 2 };

typedef struct ctx {
    const uint32_t *tri;
    uint32_t n;
    uint32_t *nb;         /* 3n: neighbour across edge (v_i, v_i+1), NONE at a border */
    uint8_t *used;        /* already in a path */
    uint8_t *deg;         /* number of unused neighbours */
    uint32_t *mark;       /* == stamp: taken by the path being tried */
    uint32_t stamp;
    uint32_t *bucket[3];  /* seed candidates by degree 0..2 (stacks, lazily updated) */
    uint32_t bucket_len[3];
    uint32_t cursor;      /* lowest id that may still have degree 3 */
} ctx;

/* ---- 2. greedy paths ---------------------------------------------------- */

/* The next seed: a triangle of the lowest degree, the most recently lowered
 * first (it lies next to the strip just made, which keeps strips side by
 * side and helps the vertex cache); degree-3 triangles by lowest id. Stale
 * entries (used since, or lowered again) are skipped: a triangle reaches
 * each degree at most once, so each bucket holds at most n entries. A
 * lowest-id heap for all degrees gave the same strips within 0.1% and took
 * twice as long (see the test file). */
static uint32_t next_seed(ctx *c)
{
    for (unsigned d = 0; d < 3; d++) {
        while (c->bucket_len[d] > 0) {
            uint32_t t = c->bucket[d][--c->bucket_len[d]];
            if (!c->used[t] && c->deg[t] == d)
                return t;
        }
    }
    while (c->cursor < c->n && (c->used[c->cursor] || c->deg[c->cursor] != 3))
        c->cursor++;
    return c->cursor < c->n ? c->cursor : NONE;
}

static void commit(ctx *c, uint32_t t)
{
    c->used[t] = 1;
    for (unsigned i = 0; i < 3; i++) {
        uint32_t u = c->nb[3 * (size_t)t + i];
        if (u != NONE && !c->used[u]) {
            uint8_t d = --c->deg[u];
            c->bucket[d][c->bucket_len[d]++] = u;
        }
    }
}

static inline int avail(const ctx *c, uint32_t t)
{
    return t != NONE && !c->used[t] && c->mark[t] != c->stamp;
}

/* Free neighbours of u other than `from`. */
static inline unsigned free_degree(const ctx *c, uint32_t u, uint32_t from)
{
    unsigned d = 0;
    for (unsigned i = 0; i < 3; i++) {
        uint32_t w = c->nb[3 * (size_t)u + i];
        if (w != from && avail(c, w))
            d++;
    }
    return d;
}

/* Grows a path from triangle t, whose strip so far ends with the local
 * vertices (p, q, r) = (3 - lq - lr, lq, lr): the free exit is edge (q, r),
 * the swap exit edge (p, r). Appends the triangles it takes to out (not t),
 * at most limit, marks them with the current stamp and returns their
 * number. */
static uint32_t grow(ctx *c, uint32_t t, unsigned lq, unsigned lr, uint32_t *out,
                     uint32_t limit)
{
    uint32_t len = 0;
    while (len < limit) {
        unsigned lp = 3 - lq - lr;
        uint32_t f = c->nb[3 * (size_t)t + mts__edge_of(lq, lr)];
        uint32_t s = c->nb[3 * (size_t)t + mts__edge_of(lp, lr)];
        int fa = avail(c, f), sa = avail(c, s) && s != f;
        int take_swap;
        if (!fa && !sa)
            break;
        if (!fa)
            take_swap = 1;
        else if (!sa)
            take_swap = 0;
        else
            /* Go where fewer free neighbours remain, so that the other one is
             * not left stranded; the swap only when strictly better. Against
             * "always free first" this halves the strips for twice the swaps,
             * a net gain (docs/strips.md). */
            take_swap = free_degree(c, s, t) < free_degree(c, f, t);
        uint32_t u = take_swap ? s : f;
        uint32_t va = c->tri[3 * (size_t)t + (take_swap ? lp : lq)];
        uint32_t vr = c->tri[3 * (size_t)t + lr];
        unsigned ur = mts__local_of(c->tri, u, vr), ua = mts__local_of(c->tri, u, va);
        c->mark[u] = c->stamp;
        out[len++] = u;
        /* the strip now ends (a, r, x): q := r, r := x */
        t = u;
        lq = ur;
        lr = 3 - ur - ua;
    }
    return len;
}

static void next_stamp(ctx *c)
{
    if (++c->stamp == 0) {
        /* wrapped: forget every old mark */
        memset(c->mark, 0, (size_t)c->n * sizeof *c->mark);
        c->stamp = 1;
    }
}

/* ---- 3. tunnelling: tunnel.c's search (mts__tunnel_search) ---------- */

/* 1 when a strip read from the end triangle a needs a swap at its second
 * triangle b: b, at odd parity, goes on without a swap only if it turns
 * around the first vertex of its entry edge from a in b's own orientation. */
static int start_swap(const mts__links *L, uint32_t a)
{
    uint32_t b = mts__links_step(L, NONE, a);
    if (b == NONE || mts__links_count(L, b) < 2)
        return 0;
    unsigned e = 0;
    while (e < 3 && !((L->mask[b] >> e & 1) && L->nb[3 * (size_t)b + e] == a))
        e++;
    return mts__links_pivot(L, b) != L->tri[3 * (size_t)b + e % 3];
}

/* ---- driver ------------------------------------------------------------- */

static mts_result stripify_impl(const uint32_t *triangles, uint32_t triangle_count,
                                uint32_t vertex_count, mts_strips *out, mts_stripify_stats *stats,
                                mts_error *err)
{
    mts_result rc = MTS_OK;
    ctx c = {0};
    mts__links L = {0};
    uint32_t *order = NULL, *starts = NULL, *trial = NULL, *best = NULL, *fwd = NULL,
             *bwd = NULL;

    if (!out)
        return mts_error_set(err, MTS_ERR_ARG, "stripify: no output");
    *out = (mts_strips){0};
    if (stats)
        *stats = (mts_stripify_stats){0};
    if (triangle_count > 0 && !triangles)
        return mts_error_set(err, MTS_ERR_ARG, "stripify: no triangle array for %u triangles",
                             triangle_count);
    /* A cover never needs more than 3 indices per triangle, and half-edge
     * ids are 3n: keep both within 32 bits. */
    if (triangle_count > (UINT32_MAX - 1) / 3)
        return mts_error_set(err, MTS_ERR_LIMIT, "stripify: %u triangles exceed the limit of %u",
                             triangle_count, (UINT32_MAX - 1) / 3);
    for (uint32_t t = 0; t < triangle_count; t++) {
        const uint32_t *v = triangles + 3 * (size_t)t;
        for (int i = 0; i < 3; i++) {
            if (v[i] >= vertex_count)
                return mts_error_set(err, MTS_ERR_RANGE,
                                     "stripify: triangle %u uses vertex %u of only %u", t, v[i],
                                     vertex_count);
        }
        if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2])
            return mts_error_set(err, MTS_ERR_FORMAT,
                                 "stripify: triangle %u (%u %u %u) repeats a vertex", t, v[0],
                                 v[1], v[2]);
    }
    if (triangle_count == 0)
        return mts_strips_alloc(out, 0, 0, err);

    uint32_t n = triangle_count;
    c.tri = triangles;
    c.n = n;
    c.nb = malloc((size_t)n * 3 * sizeof *c.nb);
    c.used = calloc(n, 1);
    c.deg = malloc(n);
    c.mark = calloc(n, sizeof *c.mark);
    for (int d = 0; d < 3; d++)
        c.bucket[d] = malloc((size_t)n * sizeof *c.bucket[d]);
    order = malloc((size_t)n * sizeof *order);
    starts = malloc(((size_t)n + 1) * sizeof *starts);
    trial = malloc((size_t)n * sizeof *trial);
    best = malloc((size_t)n * sizeof *best);
    fwd = malloc((size_t)n * sizeof *fwd);
    bwd = malloc((size_t)n * sizeof *bwd);
    L.mask = calloc(n, 1);
    if (!c.nb || !c.used || !c.deg || !c.mark || !c.bucket[0] || !c.bucket[1] || !c.bucket[2] ||
        !order || !starts || !trial || !best || !fwd || !bwd || !L.mask) {
        rc = mts_error_set(err, MTS_ERR_NOMEM, "stripify: out of memory for %u triangles", n);
        goto cleanup;
    }
    rc = mts__links_adjacency(c.tri, n, vertex_count, c.nb, "stripify", err);
    if (rc != MTS_OK)
        goto cleanup;
    for (uint32_t t = 0; t < n; t++) {
        unsigned d = 0;
        for (unsigned i = 0; i < 3; i++)
            d += c.nb[3 * (size_t)t + i] != NONE;
        c.deg[t] = (uint8_t)d;
        if (d < 3)
            c.bucket[d][c.bucket_len[d]++] = t;
    }
    mts__buckets_lowest_first(c.bucket, c.bucket_len);

    /* Greedy paths, one after the other in order[]: path i is
     * order[starts[i] .. starts[i+1]). */
    uint32_t placed = 0, strip_count = 0;
    for (;;) {
        uint32_t seed = next_seed(&c);
        if (seed == NONE)
            break;
        uint32_t best_m = 0, best_cost = 0;
        for (unsigned j = 0; j < 3; j++) {
            next_stamp(&c);
            c.mark[seed] = c.stamp;
            /* the strip starts (v_j, v_j+1, v_j+2) */
            unsigned b = (j + 1) % 3, cc = (j + 2) % 3;
            uint32_t nf = grow(&c, seed, b, cc, fwd, MTS_STRIPIFY_MAX_STRIP - 1);
            uint32_t m = 0;
            trial[m++] = seed;
            memcpy(trial + m, fwd, (size_t)nf * sizeof *fwd);
            m += nf;
            uint32_t sw, len = mts__links_encode(c.tri, c.nb, trial, m, NULL, &sw);
            if (len == 0) {
                rc = mts_error_set(err, MTS_ERR_INTERNAL, "stripify: a trial path is broken");
                goto cleanup;
            }
            /* fewest indices per triangle, restart included: (len + 1) / m */
            uint64_t lhs = (uint64_t)(len + 1) * best_m, rhs = (uint64_t)best_cost * m;
            if (best_m == 0 || lhs < rhs || (lhs == rhs && m > best_m)) {
                best_m = m;
                best_cost = len + 1;
                memcpy(best, trial, (size_t)m * sizeof *trial);
            }
        }
        starts[strip_count++] = placed;
        for (uint32_t k = 0; k < best_m; k++) {
            commit(&c, best[k]);
            order[placed++] = best[k];
        }
    }
    starts[strip_count] = placed;
    if (placed != n) {
        rc = mts_error_set(err, MTS_ERR_INTERNAL, "stripify: paths hold %u of %u triangles",
                           placed, n);
        goto cleanup;
    }

    /* Paths as links, then tunnelling. */
    L.n = n;
    L.tri = c.tri;
    L.nb = c.nb;
    for (uint32_t s = 0; s < strip_count; s++) {
        for (uint32_t k = starts[s]; k + 1 < starts[s + 1]; k++) {
            uint32_t x = order[k], y = order[k + 1];
            unsigned e = mts__links_free_edge(&L, x, y);
            if (e == 3) {
                rc = mts_error_set(err, MTS_ERR_INTERNAL, "stripify: path %u is broken", s);
                goto cleanup;
            }
            mts__links_set(&L, x, e);
        }
    }
    {
        L.pid = fwd;
        L.pos = bwd;
        L.touched = calloc(n, 1);
        L.plen = malloc((size_t)n * sizeof *L.plen);
        L.pend = malloc((size_t)n * sizeof *L.pend);
        L.lab = calloc(n, sizeof *L.lab);
        L.max_path = MTS_STRIPIFY_MAX_STRIP;
        if (!L.touched || !L.plen || !L.pend || !L.lab) {
            rc = mts_error_set(err, MTS_ERR_NOMEM, "stripify: out of memory for %u triangles", n);
            goto cleanup;
        }
        mts__tunnel_search(&L, TUNNEL_DEPTH, TUNNEL_CUT_DEPTH, TUNNEL_BOUND, NULL);
    }

    /* Read the paths out in the order the greedy pass placed their first
     * triangle, which keeps neighbouring strips close for the vertex cache;
     * each from the end that needs no swap at its start, if one does. */
    memcpy(trial, order, (size_t)n * sizeof *order);
    memset(c.used, 0, n);
    placed = 0;
    strip_count = 0;
    for (uint32_t s = 0; s < n; s++) {
        uint32_t t = trial[s];
        if (c.used[t])
            continue;
        uint32_t e0 = mts__links_path_end(&L, t), start = e0;
        if (e0 == NONE) {
            rc = mts_error_set(err, MTS_ERR_INTERNAL, "stripify: triangle %u is on a cycle", t);
            goto cleanup;
        }
        if (L.mask[e0]) {
            uint32_t e1 = mts__links_path_end(&L, e0);
            int f0 = start_swap(&L, e0), f1 = start_swap(&L, e1);
            if ((f0 && !f1) || (f0 == f1 && e1 < e0))
                start = e1;
        }
        starts[strip_count++] = placed;
        uint32_t prev = NONE, cur = start;
        while (cur != NONE && placed < n) {
            c.used[cur] = 1;
            order[placed++] = cur;
            uint32_t nx = mts__links_step(&L, prev, cur);
            prev = cur;
            cur = nx;
        }
    }
    starts[strip_count] = placed;
    if (placed != n) {
        rc = mts_error_set(err, MTS_ERR_INTERNAL, "stripify: paths hold %u of %u triangles",
                           placed, n);
        goto cleanup;
    }

    /* Encode: the total length first, then the indices. */
    uint64_t total = 0;
    uint32_t swaps = 0, singletons = 0;
    for (uint32_t s = 0; s < strip_count; s++) {
        uint32_t sw, m = starts[s + 1] - starts[s];
        uint32_t len = mts__links_encode(c.tri, c.nb, order + starts[s], m, NULL, &sw);
        if (len == 0) {
            rc = mts_error_set(err, MTS_ERR_INTERNAL, "stripify: strip %u is not a path", s);
            goto cleanup;
        }
        total += len;
        swaps += sw;
        singletons += m == 1;
    }
    if (total > UINT32_MAX - 1) {
        rc = mts_error_set(err, MTS_ERR_LIMIT, "stripify: %llu indices exceed 32 bits",
                           (unsigned long long)total);
        goto cleanup;
    }
    rc = mts_strips_alloc(out, strip_count, (uint32_t)total, err);
    if (rc != MTS_OK)
        goto cleanup;
    uint32_t at = 0;
    for (uint32_t s = 0; s < strip_count; s++) {
        uint32_t sw;
        out->offsets[s] = at;
        at += mts__links_encode(c.tri, c.nb, order + starts[s], starts[s + 1] - starts[s], out->indices + at, &sw);
    }
    out->offsets[strip_count] = at;
    if (stats) {
        stats->strips = strip_count;
        stats->swaps = swaps;
        stats->singletons = singletons;
    }

cleanup:
    free(c.nb);
    free(c.used);
    free(c.deg);
    free(c.mark);
    for (int d = 0; d < 3; d++)
        free(c.bucket[d]);
    free(order);
    free(starts);
    free(trial);
    free(best);
    free(fwd);
    free(bwd);
    free(L.mask);
    free(L.touched);
    free(L.plen);
    free(L.pend);
    free(L.lab);
    return rc;
}

mts_result mts_stripify(const uint32_t *triangles, uint32_t triangle_count, uint32_t vertex_count,
                        mts_strips *out, mts_stripify_stats *stats, mts_error *err)
{
    return stripify_impl(triangles, triangle_count, vertex_count, out, stats, err);
}

/* ---- the lower bound -------------------------------------------------- */

/* Why it holds. Along a strip, let a "visit" of vertex v be a maximal run of
 * consecutive triangles of the strip that contain v; the triangles around v
 * split into visits. Inside a visit every triangle but the first and last
 * turns around v (its entry and exit edges both hold v), so a visit of L
 * triangles away from the strip's ends has L - 3 swaps pivoting on v when L
 * >= 3; L = 2 means its two triangles turn around one neighbour x, which is
 * a swap on x, and L = 1 cannot happen. So a vertex whose visits are all of
 * 3 triangles has a valence that is a multiple of 3, and any other vertex
 * has a visit of 1 or 2 triangles or of 4 or more: it is served by a strip
 * end or by a swap. A swap serves two vertices at most (its pivot, and the
 * neighbour whose 2-triangle visit it makes); an end at most two (the first
 * triangle's vertex off its exit edge, and one on it). With N such vertices,
 * W swaps and S strips, N <= 2 (W + 2 S) <= 2 (3 S + W).
 *
 * Exactly: call an edge at v a spoke, open unless two consecutive triangles
 * of a strip cross it, and let j count the linked spokes between two
 * consecutive open ones around v (a border fan is a line, both ends open).
 * A run of j spokes is a visit of j + 1 triangles, j - 2 swaps on v when j
 * >= 2; adding 3 per triangle, less 3 per link (at both its ends) and the
 * swaps, vertex by vertex, gives
 *     2 (3 S + W - W0) = sum over vertices and runs of |j - 2|,
 * W0 the swaps a strip's second triangle takes at its start, which pivot on
 * nothing. A vertex whose valence is not a multiple of 3 has a run other
 * than 2, so it pays at least 1/2; and a strip's first vertex (j = 0) pays
 * 1 on its own. tests/test_stripify.c checks the identity on every cover it
 * makes; tunnel.c reads where the excess of its strips lies from it. */
mts_result mts_stripify_cost_bound(const uint32_t *tri, uint32_t n, uint32_t vertex_count,
                                   uint64_t *bound, mts_error *err)
{
    *bound = 0;
    if (n > (UINT32_MAX - 2) / 3)
        return mts_error_set(err, MTS_ERR_LIMIT, "stripify bound: %u triangles", n);
    for (size_t k = 0; k < (size_t)3 * n; k++)
        if (tri[k] >= vertex_count)
            return mts_error_set(err, MTS_ERR_RANGE,
                                 "stripify bound: triangle %zu names vertex %u of %u", k / 3,
                                 tri[k], vertex_count);
    /* Per vertex, its valence and whether a border touches it, gathered by
     * sorting (vertex << 2 | counts toward the valence << 1 | on a border)
     * entries rather than in arrays of vertex_count: the ids may be sparse
     * up to 2^32 - 1, and memory must follow the triangles. */
    size_t nh = (size_t)3 * n;
    uint32_t *nb = malloc((nh + 1) * sizeof *nb);
    uint64_t *ent = malloc((2 * nh + 1) * sizeof *ent);
    mts_result rc = MTS_OK;
    if (!nb || !ent)
        rc = mts_error_set(err, MTS_ERR_NOMEM, "stripify bound: out of memory");
    else
        rc = mts__links_adjacency(tri, n, vertex_count, nb, "stripify bound", err);
    if (rc == MTS_OK) {
        /* the strips' own adjacency: an edge no strip may cross is a border */
        size_t ne = 0;
        for (size_t h = 0; h < nh; h++) {
            uint32_t a = tri[h], b = tri[h - h % 3 + (h + 1) % 3];
            uint64_t border = nb[h] == NONE;
            ent[ne++] = (uint64_t)a << 2 | 2u | border;
            if (border)
                ent[ne++] = (uint64_t)b << 2 | 1u;
        }
        qsort(ent, ne, sizeof *ent, mts_words_cmp64);
        uint64_t defects = 0;
        for (size_t i = 0; i < ne;) {
            uint64_t v = ent[i] >> 2, valence = 0;
            int off = 0;
            for (; i < ne && ent[i] >> 2 == v; i++) {
                valence += ent[i] >> 1 & 1;
                off |= (int)(ent[i] & 1);
            }
            defects += !off && valence % 3 != 0;
        }
        *bound = (defects + 1) / 2;
    }
    free(nb);
    free(ent);
    return rc;
}
