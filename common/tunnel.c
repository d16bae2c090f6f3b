/* Tunnelling on the dual graph, after
 *   M. B. Porcu, N. Sanna, R. Scateni, "Efficiently Keeping an Optimal
 *   Stripification over a CLOD Mesh", WSCG 2005 (paper 004 in
 *   ../shared/papers), section 3, "The Tunnelling Algorithm",
 * which builds on A. J. Stewart, "Tunneling for Triangle Strips in
 * Continuous Level-of-Detail Meshes", Graphics Interface 2001.
 *
 * The dual graph has a node per triangle and an edge per shared mesh edge
 * (manifold, consistently oriented edges only: a strip across any other edge
 * would draw a triangle with the wrong winding). A set of strips colours its
 * edges: "solid" (links) joins consecutive triangles of a strip, the others
 * are "dashed". A tunnel is an alternating path dashed, solid, ..., dashed
 * between two strip ends (terminal nodes); complementing it turns every
 * dashed edge into a link and every solid one into a plain edge, which joins
 * two strips into one. The no-loop rules of the paper (the last edge must
 * not join a strip to itself; a dashed edge inside one strip must be
 * followed by the solid edge back towards where it came from) are what keep
 * the result a set of paths; here they are checked, not steered by: the
 * search may take any step, and a candidate is kept only when the links
 * after the change still form paths (no cycle, none longer than the cap),
 * which a union-find over the cut pieces of the paths answers exactly (see
 * paths_ok), so every tunnel the rules allow is still found.
 *
 * Strips are generalized, so a path of the dual graph costs, as strips.h
 * encodes it, triangles + 2 + its swaps indices, plus one restart between
 * strips: the cover costs T + 3 S + W - 1 with S strips and W swaps. A swap
 * sits where two consecutive triangles of a path turn around the same
 * vertex (their "pivot"). Complementing a tunnel changes the pivots of the
 * triangles on it, so a tunnel that saves a strip (-3) may cost swaps; it is
 * taken only when 3 S + W drops, and of all the tunnels up to the length
 * bound from one end, the cheapest is taken (paper: any tunnel; with swaps
 * counted, the cheapest one is worth the exhaustive search). Besides tunnels
 * between two ends, the search keeps
 *  - an even-length alternating path that ends by cutting a link (the strip
 *    end moves, no strip is saved) when it removes swaps;
 *  - from every swap, a cut there (+3 for the new strip) followed by a tunnel
 *    from either new end that rejoins the pieces for less.
 * Passes repeat, near the last pass's changes only, until no tunnel up to the
 * bound is left.
 *
 * The length bound K counts dual edges: K = 2 d + 1 allows d solid edges.
 * The exhaustive search alone finds little on mts_stripify's strips, which
 * already tunnel with d = 4 (bunny00: 1.2430 -> 1.2421 idx/tri at K = 9,
 * 1.2389 at K = 21): they sit in a local minimum. So after it, a simulated
 * annealing walks the same moves at random (Metropolis on 3 S + W, fixed
 * seed) and the exhaustive search runs again. Measured (gcc -O2, shared
 * 2-core VM; idx/tri with restarts; seconds of this pass, one run):
 *   K      bunny00 (75408 tris)           fandisk_large (31682 tris)
 *          strips swaps idx/tri  s         strips swaps idx/tri  s
 *   off    2209  11701  1.2430  0.02       860   4499  1.2234  0.01 (cache order only)
 *   1      2282  10970  1.2362  0.30       864   4238  1.2155  0.12
 *   3      2393   9749  1.2245  0.64       936   3687  1.2050  0.23
 *   5      2364   9675  1.2223  0.67       926   3622  1.2020  0.28
 *   7      2361   9606  1.2213  0.78       926   3597  1.2012  0.30  <- the default
 *   9      2394   9469  1.2208  0.77       904   3660  1.2011  0.31
 *   11     2361   9565  1.2208  0.80       921   3618  1.2014  0.32
 *   13     2351   9620  1.2211  0.83       903   3665  1.2012  0.32
 * Past 7 the annealing's randomness is larger than the gain. On bunny00
 * Loop-subdivided twice (1.2 M triangles): 1.0893 -> 1.0716 in 11 s.
 *
 * The read-out orders the strips for a FIFO vertex cache: after each strip,
 * of the strips sharing a vertex with the cache, the one (and the direction)
 * that the cache saves the most misses on comes next; else the next strip in
 * the input's order. A direction costs no extra index: of the two, the
 * shorter encoding (a swap at the start) is the only one tried.
 */
#include "tunnel.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "stripify.h"

#define NONE UINT32_MAX

enum {
    MAX_DEPTH = (MTS_TUNNEL_MAX_LENGTH - 1) / 2,
    UNDO_MAX = 2 * MAX_DEPTH + 4,
    VISIT_MAX = 2 * MAX_DEPTH + 4,
    /* a partial tunnel may cost this much (3 S + W) before it pays back:
     * more finds a little more for much more time */
    PARTIAL_BOUND = 3,
    MAX_PASSES = 64,
    DEFAULT_CACHE = 32,
    /* annealing moves per triangle: quality grows with it, slowly (bunny00,
     * idx/tri after: 20 -> 1.228, 60 -> 1.222, 100 -> 1.219, 0.35 / 0.9 /
     * 1.75 s); 64 keeps the pass near a second on bunny00 */
    DEFAULT_ANNEAL = 64,
};
/* Temperatures (in units of 3 S + W) from the first to the last of the
 * annealing's stages, geometric between: measured on bunny00 at 60 moves a
 * triangle, 1.0 -> 0.1 and 0.8 -> 0.1 are best (1.2218 / 1.2224), hotter
 * starts (2.0, 1.5) lose (1.238 / 1.236), a colder end (0.05) too (1.2229). */
#define ANNEAL_T0 0.8
#define ANNEAL_T1 0.1

typedef struct undo_op {
    uint32_t t, u; /* linked or unlinked across edge et of t, eu of u */
    uint8_t et, eu;
    uint8_t added; /* 1: the link was added, 0: removed */
} undo_op;

typedef struct tun {
    uint32_t n;
    uint32_t *tri;  /* 3n, oriented as drawn */
    uint32_t *nb;   /* 3n: neighbour across edge (v_i, v_i+1), NONE at a border */
    uint8_t *mask;  /* bit e: linked across edge e */
    /* Labels valid whenever a search starts: the path of t is named by its
     * first triangle pid[t]; t lies at pos[t]; plen[pid] is its length. */
    uint32_t *pid, *pos, *plen, *lab;
    uint32_t lab_stamp;
    uint32_t *touched; /* the last pass that changed links near t */
    uint32_t pass;
    uint32_t max_path;
    int depth, cut_depth;
    uint32_t changes;
    /* the search in progress */
    int nundo;
    undo_op undo[UNDO_MAX];
    int nvisit;
    uint32_t visit[VISIT_MAX];
    int best_d, nbest;
    undo_op best[UNDO_MAX];
} tun;

static const uint8_t link_count[8] = {0, 1, 1, 2, 1, 2, 2, 3};
/* the vertex the two edges of a 2-bit mask share: edges e and e+1 share
 * vertex e+1 */
static const uint8_t pivot_local[8] = {0, 0, 0, 1, 0, 0, 2, 0};

static inline unsigned nlinks(const tun *o, uint32_t t)
{
    return link_count[o->mask[t]];
}

static inline uint32_t pivot(const tun *o, uint32_t t)
{
    uint8_t m = o->mask[t];
    return link_count[m] == 2 ? o->tri[3 * (size_t)t + pivot_local[m]] : NONE;
}

static inline unsigned local_of(const tun *o, uint32_t t, uint32_t v)
{
    const uint32_t *tv = o->tri + 3 * (size_t)t;
    return tv[0] == v ? 0u : tv[1] == v ? 1u : 2u;
}

/* Local edge index of the edge between local vertices i and j. */
static inline unsigned edge_of(unsigned i, unsigned j)
{
    return (i + 1) % 3 == j ? i : j;
}

/* The edge of u = nb[3t + e] that is edge e of t, run the other way. */
static inline unsigned twin_edge(const tun *o, uint32_t t, unsigned e)
{
    uint32_t u = o->nb[3 * (size_t)t + e];
    return local_of(o, u, o->tri[3 * (size_t)t + (e + 1) % 3]);
}

/* The neighbour along the path from cur that is not prev (NONE: an end). */
static inline uint32_t step(const tun *o, uint32_t prev, uint32_t cur)
{
    const uint32_t *n3 = o->nb + 3 * (size_t)cur;
    uint8_t m = o->mask[cur];
    for (int e = 0; e < 3; e++) {
        if ((m >> e & 1) && n3[e] != prev)
            return n3[e];
    }
    return NONE;
}

/* ---- adjacency ---------------------------------------------------------- */

static inline uint32_t next_h(uint32_t h)
{
    return h % 3 == 2 ? h - 2 : h + 1;
}

/* Half-edges bucketed by their lower end (a counting sort over the vertex
 * range, which the caller bounds), each bucket sorted by the higher end:
 * runs of equal edges are then adjacent. O(n + V), deterministic. */
static mts_result build_adjacency(tun *o, uint32_t vertex_count, mts_error *err)
{
    uint32_t n3 = 3 * o->n;
    uint32_t *start = calloc((size_t)vertex_count + 1, sizeof *start);
    uint32_t *order = malloc((size_t)n3 * sizeof *order + 1);
    if (!start || !order) {
        free(start);
        free(order);
        return mts_error_set(err, MTS_ERR_NOMEM,
                             "tunnel: out of memory for the adjacency of %u triangles", o->n);
    }
    const uint32_t *tri = o->tri;
    for (uint32_t h = 0; h < n3; h++) {
        uint32_t a = tri[h], b = tri[next_h(h)];
        start[(a < b ? a : b) + 1]++;
    }
    for (uint32_t v = 0; v < vertex_count; v++)
        start[v + 1] += start[v];
    for (uint32_t h = 0; h < n3; h++) {
        uint32_t a = tri[h], b = tri[next_h(h)];
        order[start[a < b ? a : b]++] = h;
    }
    /* start[v] is now the end of bucket v, the start of bucket v + 1 */
    for (uint32_t h = 0; h < n3; h++)
        o->nb[h] = NONE;
    uint32_t lo = 0;
    for (uint32_t v = 0; v < vertex_count; v++) {
        uint32_t hi = start[v];
        /* insertion sort by (higher end, half-edge id): buckets hold a
         * vertex's valence or so */
        for (uint32_t i = lo + 1; i < hi; i++) {
            uint32_t h = order[i], j = i;
            uint32_t kh = tri[h] > tri[next_h(h)] ? tri[h] : tri[next_h(h)];
            while (j > lo) {
                uint32_t g = order[j - 1];
                uint32_t kg = tri[g] > tri[next_h(g)] ? tri[g] : tri[next_h(g)];
                if (kg < kh || (kg == kh && g < h))
                    break;
                order[j] = g;
                j--;
            }
            order[j] = h;
        }
        for (uint32_t i = lo; i < hi;) {
            uint32_t h = order[i];
            uint32_t kh = tri[h] > tri[next_h(h)] ? tri[h] : tri[next_h(h)];
            uint32_t e = i + 1;
            while (e < hi) {
                uint32_t g = order[e];
                uint32_t kg = tri[g] > tri[next_h(g)] ? tri[g] : tri[next_h(g)];
                if (kg != kh)
                    break;
                e++;
            }
            /* exactly two faces, through the edge in opposite directions */
            if (e - i == 2 && tri[order[i]] != tri[order[i + 1]]) {
                o->nb[order[i]] = order[i + 1] / 3;
                o->nb[order[i + 1]] = order[i] / 3;
            }
            i = e;
        }
        lo = hi;
    }
    free(start);
    free(order);
    return MTS_OK;
}

/* ---- changes with undo -------------------------------------------------- */

static void op_link(tun *o, uint32_t t, unsigned et)
{
    uint32_t u = o->nb[3 * (size_t)t + et];
    unsigned eu = twin_edge(o, t, et);
    o->mask[t] |= (uint8_t)(1u << et);
    o->mask[u] |= (uint8_t)(1u << eu);
    o->undo[o->nundo++] = (undo_op){t, u, (uint8_t)et, (uint8_t)eu, 1};
}

static void op_unlink(tun *o, uint32_t t, unsigned et)
{
    uint32_t u = o->nb[3 * (size_t)t + et];
    unsigned eu = twin_edge(o, t, et);
    o->mask[t] &= (uint8_t)~(1u << et);
    o->mask[u] &= (uint8_t)~(1u << eu);
    o->undo[o->nundo++] = (undo_op){t, u, (uint8_t)et, (uint8_t)eu, 0};
}

static void apply_op(tun *o, const undo_op *op, int forward)
{
    int set = forward ? op->added : !op->added;
    if (set) {
        o->mask[op->t] |= (uint8_t)(1u << op->et);
        o->mask[op->u] |= (uint8_t)(1u << op->eu);
    } else {
        o->mask[op->t] &= (uint8_t)~(1u << op->et);
        o->mask[op->u] &= (uint8_t)~(1u << op->eu);
    }
}

static void undo_to(tun *o, int mark)
{
    while (o->nundo > mark)
        apply_op(o, &o->undo[--o->nundo], 0);
}

/* Swaps on the links that touch the k distinct triangles T. */
static int local_swaps(const tun *o, const uint32_t *T, int k)
{
    int w = 0;
    for (int i = 0; i < k; i++) {
        uint32_t t = T[i], pt = pivot(o, t);
        if (pt == NONE)
            continue;
        for (unsigned e = 0; e < 3; e++) {
            if (!(o->mask[t] >> e & 1))
                continue;
            uint32_t u = o->nb[3 * (size_t)t + e];
            int seen = 0;
            for (int j = 0; j < i; j++)
                seen |= T[j] == u;
            w += !seen && pivot(o, u) == pt;
        }
    }
    return w;
}

/* The no-loop rules, checked: do the links as the search has changed them
 * still form paths of at most max_path triangles? The labels were valid when
 * the search started; the links it removed cut those paths into pieces and
 * the links it added join piece ends, so a union-find over the pieces (with
 * their lengths) answers it without walking: a link between two ends of one
 * piece closes a loop (rule 1; rule 2 is the same loop seen one step
 * earlier). */
static int paths_ok(const tun *o)
{
    uint32_t cut_pid[UNDO_MAX], cut_at[UNDO_MAX];
    uint32_t seg_pid[2 * UNDO_MAX], seg_k[2 * UNDO_MAX], size[2 * UNDO_MAX];
    int parent[2 * UNDO_MAX];
    int ncut = 0, nseg = 0;
    for (int i = 0; i < o->nundo; i++) {
        if (!o->undo[i].added) {
            uint32_t a = o->undo[i].t, b = o->undo[i].u;
            cut_pid[ncut] = o->pid[a];
            cut_at[ncut++] = o->pos[a] < o->pos[b] ? o->pos[a] : o->pos[b];
        }
    }
    for (int i = 0; i < o->nundo; i++) {
        if (!o->undo[i].added)
            continue;
        int r[2];
        for (int e = 0; e < 2; e++) {
            uint32_t x = e ? o->undo[i].u : o->undo[i].t;
            uint32_t px = o->pid[x], k = 0, lo = 0, hi = o->plen[px];
            for (int j = 0; j < ncut; j++) {
                if (cut_pid[j] != px)
                    continue;
                if (cut_at[j] < o->pos[x]) {
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
        if (r[0] == r[1] || size[r[0]] + size[r[1]] > o->max_path)
            return 0;
        parent[r[0]] = r[1];
        size[r[1]] += size[r[0]];
    }
    return 1;
}

/* One end of the path through t; NONE on a cycle (cannot happen: every
 * change passed paths_ok; the read-out reports it rather than loop). */
static uint32_t path_end(const tun *o, uint32_t t)
{
    uint32_t prev = NONE, cur = t;
    for (uint32_t k = 0; k <= o->n; k++) {
        uint32_t nx = step(o, prev, cur);
        if (nx == NONE)
            return cur;
        prev = cur;
        cur = nx;
    }
    return NONE;
}

static void label_path(tun *o, uint32_t t)
{
    uint32_t first = path_end(o, t), k = 0;
    if (first == NONE)
        return;
    uint32_t prev = NONE, cur = first;
    while (cur != NONE) {
        o->pid[cur] = first;
        o->pos[cur] = k++;
        o->lab[cur] = o->lab_stamp;
        uint32_t nx = step(o, prev, cur);
        prev = cur;
        cur = nx;
    }
    o->plen[first] = k;
}

/* ---- the search ---------------------------------------------------------- */

static inline int visited(const tun *o, uint32_t t)
{
    for (int i = 0; i < o->nvisit; i++) {
        if (o->visit[i] == t)
            return 1;
    }
    return 0;
}

static void record(tun *o, int d)
{
    o->best_d = d;
    o->nbest = o->nundo;
    memcpy(o->best, o->undo, (size_t)o->nundo * sizeof *o->undo);
}

/* Depth-first search of the alternating paths from the end z: dashed edge
 * z-y, then either y is an end (the tunnel closes: one strip fewer) or a
 * solid edge y-yi is cut and yi is the new end to go on from (depth more
 * times). cum is the change of 3 S + W so far; every state cheaper than
 * o->best_d that keeps paths is recorded. A tunnel visits each triangle once
 * (so a solid edge is always one of the labelled paths, never a link the
 * search added). At most 2 x 2 choices a step; partial costs over
 * PARTIAL_BOUND are not followed. */
static void search(tun *o, uint32_t z, int depth, int cum)
{
    for (unsigned i = 0; i < 3; i++) {
        uint32_t y = o->nb[3 * (size_t)z + i];
        if (y == NONE || (o->mask[z] >> i & 1) || visited(o, y))
            continue;
        int here = o->nundo;
        if (nlinks(o, y) < 2) {
            uint32_t T[2] = {z, y};
            int before = local_swaps(o, T, 2);
            op_link(o, z, i);
            int d = cum + local_swaps(o, T, 2) - before - 3;
            if (d < o->best_d && paths_ok(o))
                record(o, d);
            undo_to(o, here);
            continue;
        }
        if (depth == 0)
            continue;
        o->visit[o->nvisit++] = y;
        for (unsigned e = 0; e < 3; e++) {
            if (!(o->mask[y] >> e & 1))
                continue;
            uint32_t yi = o->nb[3 * (size_t)y + e];
            if (visited(o, yi))
                continue;
            uint32_t T[3] = {z, y, yi};
            int before = local_swaps(o, T, 3);
            op_unlink(o, y, e);
            op_link(o, z, i);
            int d = cum + local_swaps(o, T, 3) - before;
            if (d < o->best_d && paths_ok(o))
                record(o, d);
            if (d <= PARTIAL_BOUND) {
                o->visit[o->nvisit++] = yi;
                search(o, yi, depth - 1, d);
                o->nvisit--;
            }
            undo_to(o, here);
        }
        o->nvisit--;
    }
}

/* Keeps the best change found (the search has undone everything), relabels
 * the paths it touched and marks the triangles around it for the next
 * pass. */
static void accept_best(tun *o)
{
    for (int i = 0; i < o->nbest; i++)
        apply_op(o, &o->best[i], 1);
    if (++o->lab_stamp == 0) {
        memset(o->lab, 0, (size_t)o->n * sizeof *o->lab);
        o->lab_stamp = 1;
    }
    for (int i = 0; i < o->nbest; i++) {
        uint32_t ends[2] = {o->best[i].t, o->best[i].u};
        for (int e = 0; e < 2; e++) {
            o->touched[ends[e]] = o->pass;
            for (unsigned k = 0; k < 3; k++) {
                uint32_t w = o->nb[3 * (size_t)ends[e] + k];
                if (w != NONE)
                    o->touched[w] = o->pass;
            }
        }
    }
    for (int i = 0; i < o->nbest; i++) {
        if (o->lab[o->best[i].t] != o->lab_stamp)
            label_path(o, o->best[i].t);
        if (o->lab[o->best[i].u] != o->lab_stamp)
            label_path(o, o->best[i].u);
    }
    o->changes++;
}

static uint32_t improve(tun *o)
{
    uint32_t n = o->n, pass;
    o->lab_stamp = 1;
    for (uint32_t t = 0; t < n; t++) {
        if (o->lab[t] != 1)
            label_path(o, t);
    }
    for (pass = 1; pass <= MAX_PASSES; pass++) {
        int changed = 0;
        o->pass = pass;
        for (uint32_t t = 0; t < n; t++) {
            /* after the first pass, only near the last pass's changes:
             * elsewhere every search would fail again */
            if (pass > 1 && o->touched[t] + 1 < pass)
                continue;
            if (nlinks(o, t) < 2) {
                o->nundo = 0;
                o->nvisit = 1;
                o->visit[0] = t;
                o->best_d = 0;
                o->nbest = 0;
                search(o, t, o->depth, 0);
                if (o->nbest > 0) {
                    accept_best(o);
                    changed = 1;
                    if (nlinks(o, t) < 2)
                        t--; /* still an end: it may tunnel again */
                }
                continue;
            }
            if (o->cut_depth < 0)
                continue;
            /* A swap between t and a later neighbour u: cut it (+3 for the
             * new strip, -1 swap, and whatever the new ends lose) and look
             * for a tunnel from either new end that rejoins for less. */
            uint32_t pt = pivot(o, t);
            for (unsigned e = 0; e < 3; e++) {
                uint32_t u = o->nb[3 * (size_t)t + e];
                if (!(o->mask[t] >> e & 1) || u < t || pivot(o, u) != pt)
                    continue;
                uint32_t T[2] = {t, u};
                o->nundo = 0;
                int before = local_swaps(o, T, 2);
                op_unlink(o, t, e);
                int d = local_swaps(o, T, 2) - before + 3;
                o->best_d = 0;
                o->nbest = 0;
                o->nvisit = 2;
                o->visit[0] = t;
                o->visit[1] = u;
                search(o, t, o->cut_depth, d);
                search(o, u, o->cut_depth, d);
                undo_to(o, 0);
                if (o->nbest > 0) {
                    accept_best(o);
                    changed = 1;
                    break;
                }
            }
        }
        if (!changed)
            break;
    }
    return pass > MAX_PASSES ? MAX_PASSES : pass;
}

/* ---- annealing ----------------------------------------------------------- */

/* splitmix64: a fixed seed keeps the output deterministic */
static inline uint64_t rnd_next(uint64_t *state)
{
    uint64_t z = (*state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

/* A random alternating walk from the end z of up to depth link/cut steps,
 * stopping at a join or, with probability 1/2 a step, as an end move; the
 * changes stay in the undo log; returns the change of 3 S + W, or INT32_MIN
 * when the walk found no step. */
static int random_walk(tun *o, uint32_t z, int depth, int cum, uint64_t *rs)
{
    for (;;) {
        unsigned cand[3], nc = 0;
        for (unsigned i = 0; i < 3; i++) {
            uint32_t y = o->nb[3 * (size_t)z + i];
            if (y != NONE && !(o->mask[z] >> i & 1) && !visited(o, y))
                cand[nc++] = i;
        }
        if (nc == 0)
            return INT32_MIN;
        uint64_t r = rnd_next(rs);
        unsigned i = cand[r % nc];
        uint32_t y = o->nb[3 * (size_t)z + i];
        if (nlinks(o, y) < 2) {
            uint32_t T[2] = {z, y};
            int before = local_swaps(o, T, 2);
            op_link(o, z, i);
            return cum + local_swaps(o, T, 2) - before - 3;
        }
        if (depth == 0)
            return INT32_MIN;
        unsigned ce[2], ne = 0;
        for (unsigned e = 0; e < 3; e++) {
            if ((o->mask[y] >> e & 1) && !visited(o, o->nb[3 * (size_t)y + e]))
                ce[ne++] = e;
        }
        if (ne == 0)
            return INT32_MIN;
        unsigned e = ce[(r >> 8) % ne];
        uint32_t yi = o->nb[3 * (size_t)y + e];
        uint32_t T[3] = {z, y, yi};
        int before = local_swaps(o, T, 3);
        op_unlink(o, y, e);
        op_link(o, z, i);
        cum += local_swaps(o, T, 3) - before;
        o->visit[o->nvisit++] = y;
        o->visit[o->nvisit++] = yi;
        if ((r >> 16) & 1)
            return cum; /* the end moves to yi */
        z = yi;
        depth--;
    }
}

/* Simulated annealing over the same moves as the search, picked at random
 * and kept by the Metropolis rule on 3 S + W: the exhaustive search stops
 * in a local minimum, a walk through slightly worse states gets out of it. */
static void anneal(tun *o, uint64_t moves, double t0, double t1, int depth)
{
    uint64_t rs = 0x6d74732d74756eull; /* "mts-tun" */
    uint32_t n = o->n;
    enum { STAGES = 64 };
    uint32_t thresh[8]; /* accept a cost of +d when a 32-bit draw is below thresh[d] */
    o->pass = 1;
    for (int stage = 0; stage < STAGES; stage++) {
        double temp = t0 * pow(t1 / t0, (double)stage / (STAGES - 1));
        for (int d = 0; d < 8; d++)
            thresh[d] = (uint32_t)(exp(-(double)d / temp) * 4294967295.0);
        for (uint64_t k = 0; k < moves / STAGES; k++) {
            uint64_t r = rnd_next(&rs);
            /* a sweep in triangle order rather than a random pick: the same
             * quality, and on a mesh much larger than the CPU caches
             * several times faster (the ids are roughly spatial) */
            uint32_t t = (uint32_t)(k % n);
            o->nundo = 0;
            o->nvisit = 1;
            o->visit[0] = t;
            int d;
            if (nlinks(o, t) < 2) {
                d = random_walk(o, t, depth, 0, &rs);
            } else {
                unsigned ce[2], ne = 0;
                for (unsigned e = 0; e < 3; e++) {
                    if (o->mask[t] >> e & 1)
                        ce[ne++] = e;
                }
                unsigned e = ce[(r >> 4) & 1];
                uint32_t u = o->nb[3 * (size_t)t + e];

                uint32_t T[2] = {t, u};
                int before = local_swaps(o, T, 2);
                op_unlink(o, t, e);
                d = local_swaps(o, T, 2) - before + 3;
                o->visit[o->nvisit++] = u;
                if ((r >> 5) & 3) /* mostly: rejoin somewhere */
                    d = random_walk(o, (r >> 7) & 1 ? t : u, depth, d, &rs);
            }
            int ok = d != INT32_MIN &&
                     (d <= 0 || (d < 8 && (uint32_t)(r & 0xffffffffu) < thresh[d])) &&
                     paths_ok(o);
            if (!ok) {
                undo_to(o, 0);
                continue;
            }
            o->nbest = o->nundo;
            memcpy(o->best, o->undo, (size_t)o->nundo * sizeof *o->undo);
            undo_to(o, 0);
            accept_best(o);
        }
    }
}

/* ---- encoding ------------------------------------------------------------ */

/* Writes the strip of path[0..m) to out (when not NULL) and returns its
 * length; *swaps gets its swaps. The first triangle is rotated so that the
 * strip leaves it without a swap. Consecutive triangles are neighbours (the
 * links say so); 0 if not (a bug). */
static uint32_t encode(const tun *o, const uint32_t *path, uint32_t m, uint32_t *out,
                       uint32_t *swaps)
{
    const uint32_t *tri = o->tri;
    uint32_t t = path[0];
    *swaps = 0;
    if (m == 1) {
        if (out)
            memcpy(out, tri + 3 * (size_t)t, 3 * sizeof *out);
        return 3;
    }
    unsigned e = 0;
    while (e < 3 && o->nb[3 * (size_t)t + e] != path[1])
        e++;
    if (e == 3)
        return 0;
    /* window 0 = (v_e+2, v_e, v_e+1), a rotation of t, leaving by (v_e, v_e+1) */
    unsigned lq = e, lr = (e + 1) % 3;
    if (out) {
        out[0] = tri[3 * (size_t)t + (e + 2) % 3];
        out[1] = tri[3 * (size_t)t + lq];
        out[2] = tri[3 * (size_t)t + lr];
    }
    uint32_t len = 3;
    for (uint32_t k = 1; k < m; k++) {
        uint32_t u = path[k];
        unsigned lp = 3 - lq - lr, la;
        if (o->nb[3 * (size_t)t + edge_of(lq, lr)] == u) {
            la = lq;
        } else if (o->nb[3 * (size_t)t + edge_of(lp, lr)] == u) {
            /* "... p q r" becomes "... p q p r": (q p r) at the next parity
             * is still t, and (p r x) is u */
            la = lp;
            if (out) {
                out[len] = out[len - 1];
                out[len - 1] = tri[3 * (size_t)t + lp];
            }
            len++;
            (*swaps)++;
        } else {
            return 0;
        }
        uint32_t va = tri[3 * (size_t)t + la], vr = tri[3 * (size_t)t + lr];
        unsigned ur = local_of(o, u, vr), ua = local_of(o, u, va);
        unsigned ux = 3 - ur - ua;
        if (out)
            out[len] = tri[3 * (size_t)u + ux];
        len++;
        t = u;
        lq = ur;
        lr = ux;
    }
    return len;
}

/* ---- cache order --------------------------------------------------------- */

/* A FIFO post-transform cache as the benchmarks model it: v is cached iff
 * stamp[v] + size > misses (stamp: the miss count when v went in). */
typedef struct fifo {
    uint32_t size;
    uint64_t misses;
    uint64_t *stamp;
    uint32_t *ring; /* the last `size` vertices that missed: the contents */
} fifo;

static inline int fifo_hit(const fifo *f, uint32_t v)
{
    return f->stamp[v] != 0 && f->stamp[v] + f->size > f->misses;
}

static void fifo_feed(fifo *f, const uint32_t *idx, uint32_t n)
{
    for (uint32_t i = 0; i < n; i++) {
        uint32_t v = idx[i];
        if (!fifo_hit(f, v)) {
            f->ring[f->misses % f->size] = v;
            f->stamp[v] = ++f->misses;
        }
    }
}

/* Misses feeding idx would cost now; the cache is left as it was (the
 * strip's own misses are stamped and then restored from save). */
static uint32_t fifo_trial(fifo *f, const uint32_t *idx, uint32_t n, uint64_t *save,
                           uint32_t *savev)
{
    uint64_t m0 = f->misses;
    uint32_t k = 0;
    for (uint32_t i = 0; i < n; i++) {
        uint32_t v = idx[i];
        if (!fifo_hit(f, v)) {
            savev[k] = v;
            save[k++] = f->stamp[v];
            f->stamp[v] = ++f->misses;
        }
    }
    uint32_t missed = (uint32_t)(f->misses - m0);
    while (k > 0) {
        k--;
        f->stamp[savev[k]] = save[k];
    }
    f->misses = m0;
    return missed;
}

/* ---- driver -------------------------------------------------------------- */

typedef struct enc {
    uint32_t at[2], len[2]; /* [0] forward, [1] backward, in buf */
    uint32_t cold[2];       /* misses into an empty cache */
    uint8_t dirs;           /* bit d: direction d allowed (the shorter ones) */
} enc;

mts_result mts_tunnel(const mts_strips *in, uint32_t vertex_count,
                      const mts_tunnel_options *opts, mts_strips *out, mts_tunnel_stats *stats,
                      mts_error *err)
{
    static const mts_tunnel_options defaults = {0};
    mts_result rc = MTS_OK;
    tun o = {0};
    uint32_t *prev = NULL, *order = NULL, *starts = NULL, *rev = NULL, *buf = NULL;
    uint32_t *vstart = NULL, *vpaths = NULL, *vlast = NULL, *cand = NULL, *savev = NULL;
    uint32_t *emit = NULL;
    uint8_t *used = NULL, *emit_dir = NULL;
    uint64_t *save = NULL;
    enc *encs = NULL;
    fifo f = {0};

    if (!opts)
        opts = &defaults;
    if (!out || !in)
        return mts_error_set(err, MTS_ERR_ARG, "tunnel: no input or output");
    *out = (mts_strips){0};
    mts_tunnel_stats st = {0};
    for (uint32_t k = 0; k < in->index_count; k++) {
        if (in->indices[k] >= vertex_count)
            return mts_error_set(err, MTS_ERR_RANGE, "tunnel: index %u at %u is past %u vertices",
                                 in->indices[k], k, vertex_count);
    }
    mts_strip_stats before;
    mts_strips_stats(in, &before);
    st.strips_before = before.strips;
    st.swaps_before = before.degenerate;
    st.draw_indices_before = mts_strip_stats_draw_indices(&before);
    if (before.triangles > (UINT32_MAX - 1) / 3)
        return mts_error_set(err, MTS_ERR_LIMIT, "tunnel: %llu triangles exceed the limit of %u",
                             (unsigned long long)before.triangles, (UINT32_MAX - 1) / 3);
    uint32_t n = (uint32_t)before.triangles;
    st.triangles = n;
    int length = opts->length == 0 ? MTS_TUNNEL_DEFAULT_LENGTH : opts->length;
    if (length > MTS_TUNNEL_MAX_LENGTH)
        length = MTS_TUNNEL_MAX_LENGTH;
    o.max_path = opts->max_strip ? opts->max_strip : MTS_STRIPIFY_MAX_STRIP;
    uint32_t csize = opts->cache_size ? opts->cache_size : DEFAULT_CACHE;
    int effort = opts->anneal == 0 ? DEFAULT_ANNEAL : opts->anneal;

    /* The drawn triangles, numbered in drawing order, and which one each
     * follows in its strip. */
    o.n = n;
    o.tri = malloc((size_t)n * 3 * sizeof *o.tri + 1);
    o.nb = malloc((size_t)n * 3 * sizeof *o.nb + 1);
    o.mask = calloc((size_t)n + 1, 1);
    prev = malloc((size_t)n * sizeof *prev + 1);
    if (!o.tri || !o.nb || !o.mask || !prev)
        goto nomem;
    uint32_t t = 0;
    for (uint32_t s = 0; s < in->strip_count; s++) {
        const uint32_t *p = in->indices + in->offsets[s];
        uint32_t len = in->offsets[s + 1] - in->offsets[s], last = NONE;
        for (uint32_t w = 0; w + 2 < len; w++) {
            if (!mts_strip_window(p, w, o.tri + 3 * (size_t)t))
                continue;
            prev[t] = last;
            last = t++;
        }
    }
    rc = build_adjacency(&o, vertex_count, err);
    if (rc != MTS_OK)
        goto cleanup;
    /* Links from the input: consecutive drawn triangles of a strip that are
     * neighbours, within the cap (a longer input strip is cut). */
    {
        uint32_t run = 0;
        for (t = 0; t < n; t++) {
            uint32_t p = prev[t];
            unsigned e = 3;
            if (p != NONE && run < o.max_path && nlinks(&o, p) < 2) {
                e = 0;
                while (e < 3 && (o.nb[3 * (size_t)p + e] != t || (o.mask[p] >> e & 1)))
                    e++;
            }
            if (e < 3) {
                o.mask[p] |= (uint8_t)(1u << e);
                o.mask[t] |= (uint8_t)(1u << twin_edge(&o, p, e));
                run++;
            } else {
                run = 1;
            }
        }
    }

    if (length >= 1 && n > 0) {
        o.depth = (length - 1) / 2;
        o.cut_depth = o.depth;
        o.pid = malloc((size_t)n * sizeof *o.pid);
        o.pos = malloc((size_t)n * sizeof *o.pos);
        o.plen = malloc((size_t)n * sizeof *o.plen);
        o.lab = calloc(n, sizeof *o.lab);
        o.touched = calloc(n, sizeof *o.touched);
        if (!o.pid || !o.pos || !o.plen || !o.lab || !o.touched)
            goto nomem;
        st.passes = improve(&o);
        if (effort > 0) {
            anneal(&o, (uint64_t)effort * n, ANNEAL_T0, ANNEAL_T1, o.depth);
            /* and down to a local minimum again, exhaustively */
            memset(o.touched, 0, (size_t)n * sizeof *o.touched);
            st.passes += improve(&o);
        }
        st.changes = o.changes;
    }

    /* Read the paths out in the order of their lowest triangle (the input's
     * order), cutting any over the cap (only an input strip could be). */
    order = malloc((size_t)n * sizeof *order + 1);
    starts = malloc(((size_t)n + 2) * sizeof *starts);
    used = calloc((size_t)n + 1, 1);
    if (!order || !starts || !used)
        goto nomem;
    uint32_t placed = 0, paths = 0;
    for (t = 0; t < n; t++) {
        if (used[t])
            continue;
        uint32_t e0 = path_end(&o, t);
        if (e0 == NONE) {
            rc = mts_error_set(err, MTS_ERR_INTERNAL, "tunnel: triangle %u is on a cycle", t);
            goto cleanup;
        }
        uint32_t pv = NONE, cur = e0, run = 0;
        starts[paths++] = placed;
        while (cur != NONE && placed < n) {
            if (run == o.max_path) {
                starts[paths++] = placed;
                run = 0;
            }
            used[cur] = 1;
            order[placed++] = cur;
            run++;
            uint32_t nx = step(&o, pv, cur);
            pv = cur;
            cur = nx;
        }
    }
    starts[paths] = placed;
    if (placed != n) {
        rc = mts_error_set(err, MTS_ERR_INTERNAL, "tunnel: paths hold %u of %u triangles", placed,
                           n);
        goto cleanup;
    }

    /* Both directions of every path, encoded. */
    encs = calloc((size_t)paths + 1, sizeof *encs);
    rev = malloc((size_t)o.max_path * sizeof *rev + 1);
    if (!encs || !rev)
        goto nomem;
    uint64_t total = 0;
    for (uint32_t p = 0; p < paths; p++) {
        uint32_t m = starts[p + 1] - starts[p], sw;
        for (uint32_t k = 0; k < m; k++)
            rev[k] = order[starts[p] + m - 1 - k];
        encs[p].len[0] = encode(&o, order + starts[p], m, NULL, &sw);
        encs[p].len[1] = encode(&o, rev, m, NULL, &sw);
        if (encs[p].len[0] == 0 || encs[p].len[1] == 0) {
            rc = mts_error_set(err, MTS_ERR_INTERNAL, "tunnel: path %u is broken", p);
            goto cleanup;
        }
        encs[p].at[0] = (uint32_t)total;
        total += encs[p].len[0];
        encs[p].at[1] = (uint32_t)total;
        total += encs[p].len[1];
        if (total > UINT32_MAX - 1) {
            rc = mts_error_set(err, MTS_ERR_LIMIT, "tunnel: %llu indices exceed 32 bits",
                               (unsigned long long)total);
            goto cleanup;
        }
        encs[p].dirs = encs[p].len[0] < encs[p].len[1]   ? 1
                       : encs[p].len[1] < encs[p].len[0] ? 2
                                                         : 3;
    }
    buf = malloc((size_t)total * sizeof *buf + 1);
    if (!buf)
        goto nomem;
    for (uint32_t p = 0; p < paths; p++) {
        uint32_t m = starts[p + 1] - starts[p], sw;
        for (uint32_t k = 0; k < m; k++)
            rev[k] = order[starts[p] + m - 1 - k];
        encode(&o, order + starts[p], m, buf + encs[p].at[0], &sw);
        encode(&o, rev, m, buf + encs[p].at[1], &sw);
    }

    /* The order: greedy for the cache (see the top of the file). */
    emit = malloc((size_t)paths * sizeof *emit + 1);
    emit_dir = malloc((size_t)paths + 1);
    if (!emit || !emit_dir)
        goto nomem;
    memset(used, 0, (size_t)paths + 1);
    uint32_t emitted = 0;
    uint64_t out_total = 0;
    if (csize <= 1) {
        for (uint32_t p = 0; p < paths; p++) {
            emit[emitted] = p;
            emit_dir[emitted++] = encs[p].dirs & 1 ? 0 : 1;
        }
    } else {
        /* vertex -> paths that use it */
        vstart = calloc((size_t)vertex_count + 1, sizeof *vstart);
        vlast = malloc((size_t)vertex_count * sizeof *vlast + 1);
        f.size = csize;
        f.stamp = calloc((size_t)vertex_count + 1, sizeof *f.stamp);
        f.ring = calloc(csize, sizeof *f.ring);
        cand = malloc((size_t)paths * sizeof *cand + 1);
        save = malloc(((size_t)o.max_path * 2 + 3) * sizeof *save);
        savev = malloc(((size_t)o.max_path * 2 + 3) * sizeof *savev);
        if (!vstart || !vlast || !f.stamp || !f.ring || !cand || !save || !savev)
            goto nomem;
        for (uint32_t v = 0; v < vertex_count; v++)
            vlast[v] = NONE;
        for (uint32_t p = 0; p < paths; p++) {
            const uint32_t *s = buf + encs[p].at[0];
            for (uint32_t k = 0; k < encs[p].len[0]; k++) {
                if (vlast[s[k]] != p) {
                    vlast[s[k]] = p;
                    vstart[s[k] + 1]++;
                }
            }
        }
        for (uint32_t v = 0; v < vertex_count; v++)
            vstart[v + 1] += vstart[v];
        vpaths = malloc((size_t)vstart[vertex_count] * sizeof *vpaths + 1);
        if (!vpaths)
            goto nomem;
        for (uint32_t v = 0; v < vertex_count; v++)
            vlast[v] = NONE;
        for (uint32_t p = 0; p < paths; p++) {
            const uint32_t *s = buf + encs[p].at[0];
            for (uint32_t k = 0; k < encs[p].len[0]; k++) {
                if (vlast[s[k]] != p) {
                    vlast[s[k]] = p;
                    vpaths[vstart[s[k]]++] = p;
                }
            }
        }
        for (uint32_t v = vertex_count; v > 0; v--)
            vstart[v] = vstart[v - 1];
        vstart[0] = 0;
        /* misses of each direction into an empty cache, the baseline a
         * placement saves against */
        for (uint32_t p = 0; p < paths; p++) {
            for (int d = 0; d < 2; d++) {
                f.misses = (uint64_t)csize + 1; /* every stamp 0 reads as a miss */
                encs[p].cold[d] = fifo_trial(&f, buf + encs[p].at[d], encs[p].len[d], save, savev);
            }
        }
        f.misses = 0;
        for (uint32_t p = 0; p < paths; p++)
            cand[p] = NONE;
        uint32_t next_fallback = 0;
        while (emitted < paths) {
            uint32_t best = NONE;
            int best_dir = 0;
            int64_t best_gain = 0;
            uint32_t slots = f.misses < csize ? (uint32_t)f.misses : csize;
            for (uint32_t r = 0; r < slots; r++) {
                uint32_t v = f.ring[r];
                for (uint32_t k = vstart[v]; k < vstart[v + 1]; k++) {
                    uint32_t p = vpaths[k];
                    if (used[p] || cand[p] == emitted)
                        continue;
                    cand[p] = emitted;
                    for (int d = 0; d < 2; d++) {
                        if (!(encs[p].dirs >> d & 1))
                            continue;
                        uint32_t miss =
                            fifo_trial(&f, buf + encs[p].at[d], encs[p].len[d], save, savev);
                        int64_t gain = (int64_t)encs[p].cold[d] - (int64_t)miss;
                        if (gain > best_gain ||
                            (gain == best_gain && best != NONE && p < best)) {
                            best_gain = gain;
                            best = p;
                            best_dir = d;
                        }
                    }
                }
            }
            if (best == NONE) {
                while (used[next_fallback])
                    next_fallback++;
                best = next_fallback;
                best_dir = encs[best].dirs & 1 ? 0 : 1;
            }
            used[best] = 1;
            emit[emitted] = best;
            emit_dir[emitted++] = (uint8_t)best_dir;
            fifo_feed(&f, buf + encs[best].at[best_dir], encs[best].len[best_dir]);
        }
    }
    for (uint32_t i = 0; i < emitted; i++)
        out_total += encs[emit[i]].len[emit_dir[i]];

    uint64_t draw_after = out_total + (paths ? paths - 1 : 0);
    if (draw_after > st.draw_indices_before && before.strips > 0) {
        /* Cannot happen with in's strips within the cap (every change lowers
         * 3 S + W and each path takes its shorter direction), but never hand
         * back worse strips than we were given: copy them (empty strips and
         * all). Only a strip over the cap could be longer, as cut. */
        int over = 0;
        for (uint32_t s = 0; s < in->strip_count && !over; s++) {
            mts_strip_stats one = {0};
            mts_strip_stats_add(&one, in->indices + in->offsets[s],
                                in->offsets[s + 1] - in->offsets[s]);
            over = one.triangles > o.max_path;
        }
        if (!over) {
            rc = mts_strips_alloc(out, in->strip_count, in->index_count, err);
            if (rc != MTS_OK)
                goto cleanup;
            memcpy(out->offsets, in->offsets, ((size_t)in->strip_count + 1) * sizeof *out->offsets);
            memcpy(out->indices, in->indices, (size_t)in->index_count * sizeof *out->indices);
            st.strips_after = st.strips_before;
            st.swaps_after = st.swaps_before;
            st.draw_indices_after = st.draw_indices_before;
            if (stats)
                *stats = st;
            goto cleanup;
        }
    }
    rc = mts_strips_alloc(out, paths, (uint32_t)out_total, err);
    if (rc != MTS_OK)
        goto cleanup;
    uint32_t at = 0;
    for (uint32_t i = 0; i < emitted; i++) {
        const enc *e = &encs[emit[i]];
        int d = emit_dir[i];
        out->offsets[i] = at;
        memcpy(out->indices + at, buf + e->at[d], (size_t)e->len[d] * sizeof *buf);
        at += e->len[d];
    }
    out->offsets[paths] = at;
    mts_strip_stats after;
    mts_strips_stats(out, &after);
    st.strips_after = after.strips;
    st.swaps_after = after.degenerate;
    st.draw_indices_after = mts_strip_stats_draw_indices(&after);
    if (stats)
        *stats = st;
    goto cleanup;

nomem:
    rc = mts_error_set(err, MTS_ERR_NOMEM, "tunnel: out of memory for %u triangles", n);
cleanup:
    free(o.tri);
    free(o.nb);
    free(o.mask);
    free(o.pid);
    free(o.pos);
    free(o.plen);
    free(o.lab);
    free(o.touched);
    free(prev);
    free(order);
    free(starts);
    free(used);
    free(rev);
    free(buf);
    free(encs);
    free(vstart);
    free(vpaths);
    free(vlast);
    free(cand);
    free(save);
    free(savev);
    free(emit);
    free(emit_dir);
    free(f.stamp);
    free(f.ring);
    return rc;
}
