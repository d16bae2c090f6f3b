/* Internal to the strip optimisers (stripify.c, tunnel.c): a set of strips
 * as links on the dual graph of its triangles, and the moves both optimisers
 * search over. Not part of the public API.
 *
 * The dual graph has a node per triangle and an edge per shared mesh edge
 * (manifold, consistently oriented edges only: a strip across any other edge
 * would draw a triangle with the wrong winding). A strip is a path in it; the
 * cover is a 3-bit mask per triangle, bit e set when its path goes through
 * edge e (to nb[3t + e]); at most two bits are set, fewer at a path end. The
 * moves are those of tunnelling after
 *   A. J. Stewart, "Tunneling for Triangle Strips in Continuous
 *   Level-of-Detail Meshes", Graphics Interface 2001,
 * and M. B. Porcu, N. Sanna, R. Scateni, "Efficiently Keeping an Optimal
 * Stripification over a CLOD Mesh", WSCG 2005 (paper 004), section 3:
 * link a path end into a path and cut that path next to it, join two ends,
 * cut a link. A search makes them through mts__links_link / _unlink, which
 * log the change so that it can be undone, and asks mts__links_paths_ok
 * whether the result is still a set of short paths.
 *
 * The cost model (see stripify.c): a path of m triangles costs m + 2 + its
 * swaps indices, a swap sitting where two consecutive triangles turn around
 * the same vertex (their "pivot"); a cover with S paths and W swaps costs
 * T + 3 S + W - 1 with the restarts. The moves return their change of 3 S + W.
 * (A path whose two ends both need a swap at the start, mts__links_bad_end,
 * costs one more; the moves leave that out, tunnel.c adds it.)
 *
 * The small, hot helpers are static inline here so that each search inlines
 * them as it did when they were its own; the rest is in striplinks.c. */
#ifndef MTS_STRIPLINKS_H
#define MTS_STRIPLINKS_H

#include <stdint.h>

#include "error.h"

#define MTS__NONE UINT32_MAX

enum {
    /* deepest search either optimiser runs, in link/cut steps (tunnel.c:
     * (MTS_TUNNEL_MAX_LENGTH - 1) / 2) */
    MTS__LINKS_MAX_DEPTH = 10,
    /* changes one search may log: two a step, one cut and one join */
    MTS__LINKS_UNDO_MAX = 2 * MTS__LINKS_MAX_DEPTH + 4,
};

typedef struct mts__link_op {
    uint32_t t, u; /* linked or unlinked across edge et of t, eu of u */
    uint8_t et, eu;
    uint8_t added; /* 1: the link was added, 0: removed */
} mts__link_op;

typedef struct mts__links {
    uint32_t n;
    const uint32_t *tri; /* 3n, oriented as drawn */
    const uint32_t *nb;  /* 3n: neighbour across edge (v_i, v_i+1), MTS__NONE at a border */
    uint8_t *mask;       /* bit e: linked across edge e */
    /* Labels, valid whenever a search starts (see mts__links_paths_ok): the
     * path of t is named by its first triangle pid[t], t lies at position
     * pos[t] on it, and plen[pid] is its length. lab[t] == lab_stamp:
     * labelled since the last accepted change. */
    uint32_t *pid, *pos, *plen, *lab;
    uint32_t *pend; /* pend[pid]: the path's other end; NULL: not kept */
    uint32_t lab_stamp;
    uint32_t max_path; /* most triangles in one path */
    uint8_t *touched;  /* the last pass that changed links near the triangle */
    uint8_t pass;      /* the current pass, from 1 */
    /* the search in progress */
    int nundo;
    mts__link_op undo[MTS__LINKS_UNDO_MAX];
} mts__links;

/* ---- the dual graph ------------------------------------------------------ */

/* The greedy seeds' buckets (stripify.c, greedy.c): triangles by their
 * number of free neighbours, pushed in id order and popped from the top,
 * turned round once filled so that the lowest ids come out first. */
static inline void mts__buckets_lowest_first(uint32_t *bucket[3], const uint32_t len[3])
{
    for (int d = 0; d < 3; d++) {
        for (uint32_t i = 0, j = len[d]; i + 1 < j; i++, j--) {
            uint32_t x = bucket[d][i];
            bucket[d][i] = bucket[d][j - 1];
            bucket[d][j - 1] = x;
        }
    }
}

/* nb (3n) for the n triangles tri, indices < vertex_count: the neighbour
 * across each edge that exactly two faces run through in opposite
 * directions, MTS__NONE across any other. Deterministic, O(n + V) when V is
 * not much larger than the mesh. who prefixes the error message. */
mts_result mts__links_adjacency(const uint32_t *tri, uint32_t n, uint32_t vertex_count,
                                uint32_t *nb, const char *who, mts_error *err);

/* Local index of vertex v in triangle t. */
static inline unsigned mts__local_of(const uint32_t *tri, uint32_t t, uint32_t v)
{
    const uint32_t *tv = tri + 3 * (size_t)t;
    return tv[0] == v ? 0u : (unsigned)(tv[1] != v) + 1u; /* v is a corner of t */
}

/* Local edge index of the edge between local vertices i and j. */
static inline unsigned mts__edge_of(unsigned i, unsigned j)
{
    return (i + 1) % 3 == j ? i : j;
}

/* The edge of u = nb[3t + e] that is edge e of t, run the other way. */
static inline unsigned mts__twin_edge(const uint32_t *tri, const uint32_t *nb, uint32_t t,
                                      unsigned e)
{
    uint32_t u = nb[3 * (size_t)t + e];
    return mts__local_of(tri, u, tri[3 * (size_t)t + (e + 1) % 3]);
}

/* Writes the strip of path[0..m) to out (when not NULL) and returns its
 * length; *swaps gets its swaps. The first triangle is rotated so that the
 * strip leaves it without a swap, at even parity. Consecutive triangles must
 * be neighbours; 0 if not (a bug). */
uint32_t mts__links_encode(const uint32_t *tri, const uint32_t *nb, const uint32_t *path,
                           uint32_t m, uint32_t *out, uint32_t *swaps);

/* ---- the links ------------------------------------------------------------ */

/* By mask: the links, and for two links (an interior triangle) the vertex
 * their edges share (edges e and e+1 share vertex e+1) and the two edges
 * (0 where unused). Here rather than in striplinks.c so that they fold
 * into the inlined moves. */
static const uint8_t mts__link_count[8] = {0, 1, 1, 2, 1, 2, 2, 3};
static const uint8_t mts__pivot_local[8] = {0, 0, 0, 1, 0, 0, 2, 0};
static const uint8_t mts__mask_edge0[8] = {0, 0, 0, 0, 0, 0, 1, 0};
static const uint8_t mts__mask_edge1[8] = {0, 0, 0, 1, 0, 2, 2, 0};

static inline unsigned mts__links_count(const mts__links *L, uint32_t t)
{
    return mts__link_count[L->mask[t]];
}

/* The vertex an interior triangle turns around, MTS__NONE for a path end. */
static inline uint32_t mts__links_pivot(const mts__links *L, uint32_t t)
{
    uint8_t m = L->mask[t];
    return mts__link_count[m] == 2 ? L->tri[3 * (size_t)t + mts__pivot_local[m]] : MTS__NONE;
}

static inline int mts__links_linked(const mts__links *L, uint32_t t, uint32_t u)
{
    const uint32_t *n3 = L->nb + 3 * (size_t)t;
    uint8_t m = L->mask[t];
    return ((m & 1) && n3[0] == u) || ((m & 2) && n3[1] == u) || ((m & 4) && n3[2] == u);
}

/* The neighbour along the path from cur that is not prev (MTS__NONE: an end). */
static inline uint32_t mts__links_step(const mts__links *L, uint32_t prev, uint32_t cur)
{
    /* the labels walk whole paths after every kept change: the linked
     * edges come from tables rather than a loop of unpredictable branches
     * (the first linked edge that does not lead back to prev, as a loop
     * over e would find it) */
    static const uint8_t first[8] = {0, 0, 1, 0, 2, 0, 1, 0}, second[8] = {0, 0, 1, 1, 2, 2, 2, 0};
    const uint32_t *n3 = L->nb + 3 * (size_t)cur;
    uint8_t m = L->mask[cur];
    if (m == 0)
        return MTS__NONE; /* an isolated triangle */
    if (m == 7) {         /* three links: a bug; the first that does not lead back */
        for (int e = 0; e < 3; e++) {
            if (n3[e] != prev)
                return n3[e];
        }
        return MTS__NONE;
    }
    uint32_t a = n3[first[m]], b = n3[second[m]];
    uint32_t r = a != prev ? a : b;
    return r != prev ? r : MTS__NONE;
}

/* u = nb[3t + e] when t, of pivot pt, is linked to it across edge e and
 * the link is a swap (u turns around pt as well) with u > t, else
 * MTS__NONE: each swap once, where a search may cut it. */
static inline uint32_t mts__links_swap_at(const mts__links *L, uint32_t t, unsigned e,
                                          uint32_t pt)
{
    uint32_t u = L->nb[3 * (size_t)t + e];
    if (!(L->mask[t] >> e & 1) || u < t || mts__links_pivot(L, u) != pt)
        return MTS__NONE;
    return u;
}

/* The free edge of x (not linked yet) to its neighbour y, 3 if none: where a
 * driver links the consecutive triangles of an input path. */
static inline unsigned mts__links_free_edge(const mts__links *L, uint32_t x, uint32_t y)
{
    unsigned e = 0;
    while (e < 3 && (L->nb[3 * (size_t)x + e] != y || (L->mask[x] >> e & 1)))
        e++;
    return e;
}

/* Links t across edge e, not logged (building the cover). */
static inline void mts__links_set(mts__links *L, uint32_t t, unsigned e)
{
    uint32_t u = L->nb[3 * (size_t)t + e];
    L->mask[t] |= (uint8_t)(1u << e);
    L->mask[u] |= (uint8_t)(1u << mts__twin_edge(L->tri, L->nb, t, e));
}

/* ---- changes with undo ---------------------------------------------------- */

static inline void mts__links_link(mts__links *L, uint32_t t, unsigned et)
{
    uint32_t u = L->nb[3 * (size_t)t + et];
    unsigned eu = mts__twin_edge(L->tri, L->nb, t, et);
    L->mask[t] |= (uint8_t)(1u << et);
    L->mask[u] |= (uint8_t)(1u << eu);
    L->undo[L->nundo++] = (mts__link_op){t, u, (uint8_t)et, (uint8_t)eu, 1};
}

static inline void mts__links_unlink(mts__links *L, uint32_t t, unsigned et)
{
    uint32_t u = L->nb[3 * (size_t)t + et];
    unsigned eu = mts__twin_edge(L->tri, L->nb, t, et);
    L->mask[t] &= (uint8_t)~(1u << et);
    L->mask[u] &= (uint8_t)~(1u << eu);
    L->undo[L->nundo++] = (mts__link_op){t, u, (uint8_t)et, (uint8_t)eu, 0};
}

/* Makes op again or takes it back: the ops are made and taken back in
 * order, so its link always stands the other way, and flipping both bits
 * does either (no branch on which way). */
static inline void mts__links_flip(mts__links *L, const mts__link_op *op)
{
    L->mask[op->t] ^= (uint8_t)(1u << op->et);
    L->mask[op->u] ^= (uint8_t)(1u << op->eu);
}

/* Takes back the logged changes after the first `mark`. */
static inline void mts__links_undo_to(mts__links *L, int mark)
{
    while (L->nundo > mark)
        mts__links_flip(L, &L->undo[--L->nundo]);
}

/* The no-loop rules of paper 004, checked: do the links as the search has
 * changed them still form paths of at most max_path triangles? Answered
 * without walking: the labels pid/pos/plen were valid when the search
 * started; the links it removed cut those paths into segments and the links
 * it added join segment ends, so a union-find over a handful of segments,
 * with their lengths, answers both. A link between two ends of one piece
 * closes a loop (rule 1; rule 2 is the same loop seen one step earlier). */
static inline int mts__links_paths_ok(const mts__links *L)
{
    uint32_t cut_pid[MTS__LINKS_UNDO_MAX], cut_at[MTS__LINKS_UNDO_MAX];
    uint32_t seg_pid[2 * MTS__LINKS_UNDO_MAX], seg_k[2 * MTS__LINKS_UNDO_MAX],
        size[2 * MTS__LINKS_UNDO_MAX];
    int parent[2 * MTS__LINKS_UNDO_MAX];
    int ncut = 0, nseg = 0;
    for (int i = 0; i < L->nundo; i++) {
        if (!L->undo[i].added) {
            uint32_t a = L->undo[i].t, b = L->undo[i].u;
            cut_pid[ncut] = L->pid[a];
            /* the cut lies between positions cut_at and cut_at + 1 */
            cut_at[ncut++] = L->pos[a] < L->pos[b] ? L->pos[a] : L->pos[b];
        }
    }
    for (int i = 0; i < L->nundo; i++) {
        if (!L->undo[i].added)
            continue;
        int r[2];
        for (int e = 0; e < 2; e++) {
            uint32_t x = e ? L->undo[i].u : L->undo[i].t;
            uint32_t px = L->pid[x], k = 0;
            /* x's segment: the k-th piece of its path, between the nearest
             * cuts below and above it */
            uint32_t lo = 0, hi = L->plen[px];
            for (int j = 0; j < ncut; j++) {
                if (cut_pid[j] != px)
                    continue;
                if (cut_at[j] < L->pos[x]) {
                    k++;
                    if (cut_at[j] + 1 > lo)
                        lo = cut_at[j] + 1;
                } else if (cut_at[j] + 1 < hi) {
                    hi = cut_at[j] + 1;
                }
            }
            int s = 0;
            while (s < nseg && !(seg_pid[s] == px && seg_k[s] == k))
                s++;
            if (s == nseg) {
                seg_pid[s] = px;
                seg_k[s] = k;
                size[s] = hi - lo;
                parent[s] = s;
                nseg++;
            }
            while (parent[s] != s)
                s = parent[s];
            r[e] = s;
        }
        if (r[0] == r[1] || size[r[0]] + size[r[1]] > L->max_path)
            return 0;
        parent[r[0]] = r[1];
        size[r[1]] += size[r[0]];
    }
    return 1;
}

/* ---- the start of a strip ------------------------------------------------ */

/* 1 when a strip read from the end t (one link, to u) needs a swap at u: a
 * strip starts at even parity, so t is drawn (v_e+2, v_e, v_e+1) with e
 * its linked edge, and u goes on without a swap only when it turns around
 * v_e+1. A path with both ends bad costs one swap more than its pivots say
 * (about a quarter of the strips, unsteered). */
static inline int mts__links_bad_end(const mts__links *L, uint32_t t)
{
    uint8_t m = L->mask[t];
    if (m != 1 && m != 2 && m != 4)
        return 0;
    unsigned e = m >> 1 & 3u; /* 1, 2, 4 -> 0, 1, 2 */
    uint32_t u = L->nb[3 * (size_t)t + e];
    return mts__links_pivot(L, u) == L->tri[3 * (size_t)t + e];
}

/* ---- the moves, logged, each returning its change of 3 S + W ------------- */

/* Each move below knows which of its triangles are path ends before and
 * after it, and a link at an end is never a swap (an end has no pivot): so
 * each counts only the interior triangles' links, on one side of the move.
 * Swaps on the links of t, less any to x (counted already). */
static inline int mts__links_swaps_at(const mts__links *L, uint32_t t, uint32_t x)
{
    uint32_t pt = mts__links_pivot(L, t);
    if (pt == MTS__NONE)
        return 0;
    uint8_t m = L->mask[t];
    const uint32_t *n3 = L->nb + 3 * (size_t)t;
    uint32_t ua = n3[mts__mask_edge0[m]], ub = n3[mts__mask_edge1[m]];
    return ((ua != x) & (mts__links_pivot(L, ua) == pt)) + ((ub != x) & (mts__links_pivot(L, ub) == pt));
}

/* Links the path end z to the path end across its edge i: one strip fewer
 * (-3), and whatever the two ends' turns gain or lose (before, both are
 * ends: no swaps). */
static inline int mts__move_join(mts__links *L, uint32_t z, unsigned i)
{
    uint32_t y = L->nb[3 * (size_t)z + i];
    mts__links_link(L, z, i);
    return mts__links_swaps_at(L, z, MTS__NONE) + mts__links_swaps_at(L, y, z) - 3;
}

/* Links the path end z to y across its edge i and cuts y from yi, y's
 * neighbour across its edge e: the end moves from z to yi, no strip is
 * saved (one alternating step of a tunnel). z is an end before, yi after. */
static inline int mts__move_shift(mts__links *L, uint32_t z, unsigned i, unsigned e)
{
    uint32_t y = L->nb[3 * (size_t)z + i];
    uint32_t yi = L->nb[3 * (size_t)y + e];
    int before = mts__links_swaps_at(L, y, MTS__NONE) + mts__links_swaps_at(L, yi, y);
    mts__links_unlink(L, y, e);
    mts__links_link(L, z, i);
    return mts__links_swaps_at(L, z, MTS__NONE) + mts__links_swaps_at(L, y, z) - before;
}

/* Cuts the link across edge e of t: a new strip (+3), and whatever the two
 * new ends' turns gain or lose (after, both are ends: no swaps). */
static inline int mts__move_cut(mts__links *L, uint32_t t, unsigned e)
{
    uint32_t u = L->nb[3 * (size_t)t + e];
    int before = mts__links_swaps_at(L, t, MTS__NONE) + mts__links_swaps_at(L, u, t);
    mts__links_unlink(L, t, e);
    return 3 - before;
}

/* ---- labels ---------------------------------------------------------------- */

/* One end of the path through t; MTS__NONE if t lies on a cycle (cannot
 * happen: every change passed paths_ok; the read-out reports it rather than
 * loop for ever). */
uint32_t mts__links_path_end(const mts__links *L, uint32_t t);

/* Labels every path (lab must be zeroed): lab_stamp starts at 1. */
void mts__links_label_all(mts__links *L);

/* After the changes ops[0..nops) were made: relabels every path they
 * touched and marks the triangles around them with the current pass. */
void mts__links_relabel(mts__links *L, const mts__link_op *ops, int nops);

/* ---- the search (tunnel.c) ---------------------------------------------- */

/* Tunnels the cover L in passes until no change up to depth link/cut steps
 * (at most MTS__LINKS_MAX_DEPTH) from any path end, or cut_depth from the
 * two ends of a cut swap (< 0: none), makes 3 S + W smaller, start swaps
 * included; the best change from each start is kept, and partial tunnels
 * that cost more than bound are not followed. L must have every
 * array (pid, pos, plen, pend, lab, touched) allocated for L->n triangles,
 * lab zeroed; its labels are made here. Returns the passes run; *changes
 * (when not NULL) grows by the changes kept. */
uint32_t mts__tunnel_search(mts__links *L, int depth, int cut_depth, int bound,
                            uint32_t *changes);

#endif
