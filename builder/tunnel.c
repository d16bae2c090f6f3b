/* Tunnelling on the dual graph, after
 *   M. B. Porcu, N. Sanna, R. Scateni, "Efficiently Keeping an Optimal
 *   Stripification over a CLOD Mesh", WSCG 2005 (paper 004 of
 *   docs/README.md, "References"), section 3, "The Tunnelling Algorithm",
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
 * mts__links_paths_ok in striplinks.h, shared with stripify.c), so every
 * tunnel the rules allow is still found.
 *
 * Strips are generalized, so a path of the dual graph costs, as strips.h
 * encodes it, triangles + 2 + its swaps indices, plus one restart between
 * strips: the cover costs T + 3 S + W - 1 with S strips and W swaps. A swap
 * sits where two consecutive triangles of a path turn around the same
 * vertex (their "pivot"), or at the start of a path whose two ends both
 * need one (even parity fixes the second triangle's turn; see start_delta):
 * both kinds are counted (the second kind is a few hundred of bunny00's
 * swaps where nothing avoids it); below, W counts both and "3 S + W"
 * is what every change is judged by. Complementing a tunnel changes the
 * pivots of the triangles on it, so a tunnel that saves a strip (-3) may
 * cost swaps; it is
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
 * already tunnel with d = 4: they sit in a local minimum. So after it, a
 * simulated annealing walks the same moves at random (Metropolis on
 * 3 S + W, fixed seed) and the exhaustive search runs again. K = 7 is the
 * default because past it the annealing's randomness is larger than the
 * gain; 96 moves a triangle because more pays slowly (mts-build
 * --strip-effort). The read-out orders the strips for a FIFO vertex cache
 * (cacheorder.c). The figures behind these
 * choices, and what was tried and not kept: docs/strips.md.
 */
#include "tunnel.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

#include "cacheorder.h"
#include "stripify.h"
#include "striplinks.h"
#include "words.h"

#define NONE MTS__NONE

enum {
    MAX_DEPTH = (MTS_TUNNEL_MAX_LENGTH - 1) / 2,
    VISIT_MAX = 2 * MAX_DEPTH + 4,
    /* a partial tunnel may cost this much (3 S + W) before it pays back:
     * more finds a little more for much more time */
    PARTIAL_BOUND = 3,
    MAX_PASSES = 64,
    DEFAULT_CACHE = 32,
    /* annealing moves per triangle: quality grows with it, slowly; 96
     * keeps the pass under 2 s on bunny00 (docs/strips.md) */
    DEFAULT_ANNEAL = MTS_TUNNEL_DEFAULT_ANNEAL,
};
/* Temperatures (in units of 3 S + W) from the first to the last of the
 * annealing's stages, geometric between: the best pair measured on bunny00
 * (docs/strips.md); hotter starts and colder ends lose. */
#define ANNEAL_T0 0.8
#define ANNEAL_T1 0.1
_Static_assert((int)MAX_DEPTH <= (int)MTS__LINKS_MAX_DEPTH, "the undo log must hold a search");
/* the pass is kept in a byte next to each triangle (striplinks.h) */
_Static_assert(MAX_PASSES <= 255, "a pass must fit mts__links.pass");

/* The cover, its labels, the undo log and the moves are striplinks.h's;
 * this file's own are the search (the best of all tunnels up to the bound,
 * which stripify.c runs too, mts__tunnel_search) and the annealing. */
typedef struct tun {
    mts__links L;
    int depth, cut_depth;
    int bound; /* the most a partial tunnel may cost (3 S + W) */
    uint32_t changes;
    /* the search in progress */
    int nvisit;
    uint32_t visit[VISIT_MAX];
    int best_d, nbest;
    mts__link_op best[MTS__LINKS_UNDO_MAX];
} tun;

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
    o->nbest = o->L.nundo;
    memcpy(o->best, o->L.undo, (size_t)o->L.nundo * sizeof *o->L.undo);
}

/* The cost the pivots miss. A strip starts at even parity, so the first
 * triangle's winding fixes the second one's turn: about half of all path
 * ends need a swap there (mts__links_bad_end), and a path pays it (one
 * index) when both of its ends do. Left to chance that was 544 of bunny00's
 * 2361 strips; weighed in, 25. start_delta gives the change in such paths
 * the logged changes make (they must have passed mts__links_paths_ok),
 * from the labels alone: the cuts split the labelled paths into segments
 * whose end triangles are the cut links' or the paths' own ends (pid,
 * pend), the added links join segment ends, and following them from a free
 * end reaches the other end of each new path. */
static int start_delta(mts__links *L)
{
    enum { MAX_SEG = 3 * MTS__LINKS_UNDO_MAX };
    uint32_t cpid[MTS__LINKS_UNDO_MAX], cpos[MTS__LINKS_UNDO_MAX], clo[MTS__LINKS_UNDO_MAX],
        chi[MTS__LINKS_UNDO_MAX];
    uint32_t paths[2 * MTS__LINKS_UNDO_MAX];
    int ncut = 0, npath = 0;
    for (int i = 0; i < L->nundo; i++) {
        const mts__link_op *op = &L->undo[i];
        uint32_t ab[2] = {op->t, op->u};
        for (int e = 0; e < 2; e++) {
            uint32_t p = L->pid[ab[e]];
            int seen = 0;
            for (int j = 0; j < npath; j++)
                seen |= paths[j] == p;
            if (!seen)
                paths[npath++] = p;
        }
        if (!op->added) {
            /* a labelled link: its triangles lie next to each other */
            uint32_t a = L->pos[op->t] < L->pos[op->u] ? op->t : op->u;
            cpid[ncut] = L->pid[a];
            cpos[ncut] = L->pos[a];
            clo[ncut] = a;
            chi[ncut++] = a == op->t ? op->u : op->t;
        }
    }
    /* segment s: positions slo..shi of path sp; its end triangles are slot
     * 2 s (at slo) and 2 s + 1 (at shi), each joined to at most one other
     * slot by an added link */
    uint32_t sp[MAX_SEG], slo[MAX_SEG], shi[MAX_SEG], slot_tri[2 * MAX_SEG];
    int slot_link[2 * MAX_SEG];
    int nseg = 0;
    for (int j = 0; j < npath; j++) {
        uint32_t p = paths[j], lo = 0, lo_tri = p;
        for (;;) {
            int next = -1; /* the lowest cut of p at or above lo */
            for (int c = 0; c < ncut; c++) {
                if (cpid[c] == p && cpos[c] >= lo && (next < 0 || cpos[c] < cpos[next]))
                    next = c;
            }
            sp[nseg] = p;
            slo[nseg] = lo;
            slot_tri[2 * nseg] = lo_tri;
            slot_link[2 * nseg] = slot_link[2 * nseg + 1] = -1;
            if (next < 0) {
                shi[nseg] = L->plen[p] - 1;
                slot_tri[2 * nseg + 1] = L->pend[p];
                nseg++;
                break;
            }
            shi[nseg] = cpos[next];
            slot_tri[2 * nseg + 1] = clo[next];
            nseg++;
            lo = cpos[next] + 1;
            lo_tri = chi[next];
        }
    }
    for (int i = 0; i < L->nundo; i++) {
        const mts__link_op *op = &L->undo[i];
        if (!op->added)
            continue;
        int sl[2];
        uint32_t ab[2] = {op->t, op->u};
        for (int e = 0; e < 2; e++) {
            uint32_t p = L->pid[ab[e]], at = L->pos[ab[e]];
            int s = 0;
            while (s < nseg && !(sp[s] == p && slo[s] <= at && at <= shi[s]))
                s++;
            if (s == nseg)
                return 0; /* cannot happen: every link joins segment ends */
            sl[e] = at == slo[s] && slot_link[2 * s] < 0 ? 2 * s : 2 * s + 1;
        }
        slot_link[sl[0]] = sl[1];
        slot_link[sl[1]] = sl[0];
    }
    int after = 0;
    uint8_t done[2 * MAX_SEG] = {0};
    for (int k = 0; k < 2 * nseg; k++) {
        if (done[k] || slot_link[k] >= 0)
            continue;
        int cur = k;
        for (;;) {
            done[cur] = done[cur ^ 1] = 1;
            if (slot_link[cur ^ 1] < 0)
                break;
            cur = slot_link[cur ^ 1];
        }
        after += mts__links_bad_end(L, slot_tri[k]) && mts__links_bad_end(L, slot_tri[cur ^ 1]);
    }
    int before = 0;
    for (int i = L->nundo; i > 0; i--)
        mts__links_flip(L, &L->undo[i - 1]);
    for (int j = 0; j < npath; j++)
        before += mts__links_bad_end(L, paths[j]) && mts__links_bad_end(L, L->pend[paths[j]]);
    for (int i = 0; i < L->nundo; i++)
        mts__links_flip(L, &L->undo[i]);
    return after - before;
}

/* The full change of a candidate whose pivots and strips change by d: the
 * start swaps are worth looking up only where they can make it pay (they
 * change by a few at most). */
static inline int full_cost(mts__links *L, int d, int limit)
{
    return d <= limit ? d + start_delta(L) : d;
}

/* Depth-first search of the alternating paths from the end z: dashed edge
 * z-y, then either y is an end (the tunnel closes: one strip fewer) or a
 * solid edge y-yi is cut and yi is the new end to go on from (depth more
 * times). cum is the change of 3 S + W so far, the start swaps left out
 * (they are looked up per candidate, full_cost); every state cheaper than
 * o->best_d, start swaps in, that keeps paths is recorded. A tunnel visits
 * each triangle once (so a solid edge is always one of the labelled paths,
 * never a link the search added). At most 2 x 2 choices a step; partial
 * costs over o->bound (PARTIAL_BOUND here, stripify.c's own) are not
 * followed. */
static void search(tun *o, uint32_t z, int depth, int cum)
{
    mts__links *L = &o->L;
    for (unsigned i = 0; i < 3; i++) {
        uint32_t y = L->nb[3 * (size_t)z + i];
        if (y == NONE || (L->mask[z] >> i & 1) || visited(o, y))
            continue;
        int here = L->nundo;
        if (mts__links_count(L, y) < 2) {
            int d = cum + mts__move_join(L, z, i);
            if (d <= o->best_d + 1 && mts__links_paths_ok(L)) {
                d = full_cost(L, d, o->best_d + 1);
                if (d < o->best_d)
                    record(o, d);
            }
            mts__links_undo_to(L, here);
            continue;
        }
        if (depth == 0)
            continue;
        o->visit[o->nvisit++] = y;
        for (unsigned e = 0; e < 3; e++) {
            if (!(L->mask[y] >> e & 1))
                continue;
            uint32_t yi = L->nb[3 * (size_t)y + e];
            if (visited(o, yi))
                continue;
            int d = cum + mts__move_shift(L, z, i, e);
            if (d <= o->best_d + 1 && mts__links_paths_ok(L)) {
                int full = full_cost(L, d, o->best_d + 1);
                if (full < o->best_d)
                    record(o, full);
            }
            if (d <= o->bound) {
                o->visit[o->nvisit++] = yi;
                search(o, yi, depth - 1, d);
                o->nvisit--;
            }
            mts__links_undo_to(L, here);
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
        mts__links_flip(&o->L, &o->best[i]);
    mts__links_relabel(&o->L, o->best, o->nbest);
    o->changes++;
}

static uint32_t improve(tun *o)
{
    mts__links *L = &o->L;
    uint32_t n = L->n, pass;
    mts__links_label_all(L);
    for (pass = 1; pass <= MAX_PASSES; pass++) {
        int changed = 0;
        L->pass = (uint8_t)pass;
        for (uint32_t t = 0; t < n; t++) {
            /* after the first pass, only near the last pass's changes:
             * elsewhere every search would fail again */
            if (pass > 1 && L->touched[t] + 1u < pass)
                continue;
            if (mts__links_count(L, t) < 2) {
                L->nundo = 0;
                o->nvisit = 1;
                o->visit[0] = t;
                o->best_d = 0;
                o->nbest = 0;
                search(o, t, o->depth, 0);
                if (o->nbest > 0) {
                    accept_best(o);
                    changed = 1;
                    if (mts__links_count(L, t) < 2)
                        t--; /* still an end: it may tunnel again */
                }
                continue;
            }
            if (o->cut_depth < 0)
                continue;
            /* A swap between t and a later neighbour u: cut it (+3 for the
             * new strip, -1 swap, and whatever the new ends lose) and look
             * for a tunnel from either new end that rejoins for less. */
            uint32_t pt = mts__links_pivot(L, t);
            for (unsigned e = 0; e < 3; e++) {
                uint32_t u = mts__links_swap_at(L, t, e, pt);
                if (u == NONE)
                    continue;
                L->nundo = 0;
                int d = mts__move_cut(L, t, e);
                o->best_d = 0;
                o->nbest = 0;
                o->nvisit = 2;
                o->visit[0] = t;
                o->visit[1] = u;
                search(o, t, o->cut_depth, d);
                search(o, u, o->cut_depth, d);
                mts__links_undo_to(L, 0);
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

/* The search on a cover a caller built (stripify.c's greedy paths): see
 * striplinks.h. */
uint32_t mts__tunnel_search(mts__links *L, int depth, int cut_depth, int bound,
                            uint32_t *changes)
{
    tun o;
    memset(&o, 0, sizeof o);
    o.L = *L;
    o.depth = depth < 0 ? 0 : depth > MAX_DEPTH ? MAX_DEPTH : depth;
    o.cut_depth = cut_depth > MAX_DEPTH ? MAX_DEPTH : cut_depth;
    o.bound = bound;
    uint32_t passes = improve(&o);
    *L = o.L;
    if (changes)
        *changes += o.changes;
    return passes;
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

/* Whether t is among the first `width` triangles of the visit list, which
 * holds MTS__NONE past nvisit: a fixed count of compares, no early exit (the
 * walk's picks are random, so an exit branch would be mispredicted). */
static inline int visited_fixed(const tun *o, uint32_t t, int width)
{
#ifdef __SSE2__
    if (width == 8) {
        __m128i k = _mm_set1_epi32((int)t);
        __m128i a = _mm_cmpeq_epi32(_mm_loadu_si128((const __m128i *)o->visit), k);
        __m128i b = _mm_cmpeq_epi32(_mm_loadu_si128((const __m128i *)(o->visit + 4)), k);
        return _mm_movemask_epi8(_mm_or_si128(a, b)) != 0;
    }
#endif
    int v = 0;
    for (int i = 0; i < width; i++)
        v |= o->visit[i] == t;
    return v;
}

/* A random alternating walk from the end z of up to depth link/cut steps,
 * stopping at a join or, with probability 1/2 a step, as an end move; the
 * changes stay in the undo log; returns the change of 3 S + W, or INT32_MIN
 * when the walk found no step. The visit list must hold MTS__NONE past
 * nvisit up to `width` (at least nvisit + 2 depth). */
static inline int random_walk_w(tun *o, uint32_t z, int depth, int cum, uint64_t *rs, int width)
{
    mts__links *L = &o->L;
    for (;;) {
        unsigned cand[3], nc = 0;
        const uint32_t *n3 = L->nb + 3 * (size_t)z;
        uint8_t m = L->mask[z];
        for (unsigned i = 0; i < 3; i++) {
            uint32_t y = n3[i];
            cand[nc] = i;
            nc += (y != NONE) & !(m >> i & 1) & !visited_fixed(o, y, width);
        }
        if (nc == 0)
            return INT32_MIN;
        uint64_t r = rnd_next(rs);
        /* r % nc for nc of 1 to 3 without a 64-bit division (a tenth of
         * the step's time), the same pick */
        unsigned i = cand[nc == 3 ? (unsigned)(r % 3u) : (unsigned)r & (nc - 1)];
        uint32_t y = n3[i];
        uint8_t my = L->mask[y];
        if (mts__link_count[my] < 2)
            return cum + mts__move_join(L, z, i);
        if (depth == 0)
            return INT32_MIN;
        const uint32_t *y3 = L->nb + 3 * (size_t)y;
        unsigned ce[3], ne = 0;
        for (unsigned e = 0; e < 3; e++) {
            ce[ne] = e;
            ne += (my >> e & 1) & !visited_fixed(o, y3[e], width);
        }
        if (ne == 0)
            return INT32_MIN;
        unsigned e = ce[(unsigned)(r >> 8) & (ne - 1)]; /* (r >> 8) % ne, ne 1 or 2 */
        uint32_t yi = y3[e];
        cum += mts__move_shift(L, z, i, e);
        o->visit[o->nvisit++] = y;
        o->visit[o->nvisit++] = yi;
        if ((r >> 16) & 1)
            return cum; /* the end moves to yi */
        z = yi;
        depth--;
    }
}

/* The walk at the default depth (3: 8 visits at most) with its compares
 * unrolled, any other through the whole list. */
static int random_walk(tun *o, uint32_t z, int depth, int cum, uint64_t *rs)
{
    if (o->nvisit + 2 * depth <= 8)
        return random_walk_w(o, z, depth, cum, rs, 8);
    for (int v = o->nvisit; v < VISIT_MAX; v++)
        o->visit[v] = NONE;
    return random_walk_w(o, z, depth, cum, rs, VISIT_MAX);
}

/* Simulated annealing over the same moves as the search, picked at random
 * and kept by the Metropolis rule on 3 S + W: the exhaustive search stops
 * in a local minimum, a walk through slightly worse states gets out of it. */
static void anneal(tun *o, uint64_t moves, double t0, double t1, int depth,
                   const mts_progress *progress)
{
    mts__links *L = &o->L;
    uint64_t rs = 0x6d74732d74756eull; /* "mts-tun" */
    uint32_t n = L->n;
    enum { STAGES = 64 };
    uint32_t thresh[8]; /* accept a cost of +d when a 32-bit draw is below thresh[d] */
    L->pass = 1;
    for (int stage = 0; stage < STAGES; stage++) {
        mts_progress_report(progress, "tunnel", (double)stage / STAGES);
        double temp = t0 * pow(t1 / t0, (double)stage / (STAGES - 1));
        for (int d = 0; d < 8; d++)
            thresh[d] = (uint32_t)(exp(-(double)d / temp) * 4294967295.0);
        uint32_t t = n - 1;
        for (uint64_t k = 0; k < moves / STAGES; k++) {
            uint64_t r = rnd_next(&rs);
            /* a sweep in triangle order rather than a random pick: the same
             * quality, and on a mesh much larger than the CPU caches
             * several times faster (the ids are roughly spatial) */
            t = t + 1 == n ? 0 : t + 1; /* k % n, without the division */
            L->nundo = 0;
            for (int v = 0; v < 8; v++) /* the default walk's; a deeper one pads its own */
                o->visit[v] = NONE;
            o->nvisit = 1;
            o->visit[0] = t;
            int d;
            if (mts__links_count(L, t) < 2) {
                d = random_walk(o, t, depth, 0, &rs);
            } else {
                unsigned ce[2], ne = 0;
                for (unsigned e = 0; e < 3; e++) {
                    if (L->mask[t] >> e & 1)
                        ce[ne++] = e;
                }
                unsigned e = ce[(r >> 4) & 1];
                uint32_t u = L->nb[3 * (size_t)t + e];
                d = mts__move_cut(L, t, e);
                o->visit[o->nvisit++] = u;
                if ((r >> 5) & 3) /* mostly: rejoin somewhere */
                    d = random_walk(o, (r >> 7) & 1 ? t : u, depth, d, &rs);
            }
            int ok = 0;
            if (d != INT32_MIN && d <= 1) {
                /* the start swaps may tip it: paths first, they need them.
                 * Over 1 they are not looked up (half the time, for the
                 * same quality): such a move is seldom kept anyway */
                ok = mts__links_paths_ok(L);
                if (ok)
                    d = full_cost(L, d, 1);
                ok = ok && (d <= 0 || (d < 8 && (uint32_t)(r & 0xffffffffu) < thresh[d]));
            } else if (d != INT32_MIN && d < 8) {
                ok = (uint32_t)(r & 0xffffffffu) < thresh[d] && mts__links_paths_ok(L);
            }
            if (!ok) {
                mts__links_undo_to(L, 0);
                continue;
            }
            /* kept as it stands: only the labels need the change */
            mts__links_relabel(L, L->undo, L->nundo);
            o->changes++;
        }
    }
}

/* ---- driver -------------------------------------------------------------- */

static mts_result tunnel_dense(const mts_strips *in, uint32_t vertex_count,
                               const mts_tunnel_options *opts, mts_strips *out,
                               mts_tunnel_stats *stats, mts_error *err)
{
    static const mts_tunnel_options defaults = {0};
    mts_result rc = MTS_OK;
    tun o = {0};
    uint32_t *tri = NULL, *nb = NULL, *prev = NULL, *order = NULL, *starts = NULL, *rev = NULL, *buf = NULL;
    uint32_t *emit = NULL;
    uint8_t *used = NULL, *emit_dir = NULL;
    mts__order_path *encs = NULL;

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
    o.L.max_path = opts->max_strip ? opts->max_strip : MTS_STRIPIFY_MAX_STRIP;
    uint32_t csize = opts->cache_size ? opts->cache_size : DEFAULT_CACHE;
    int effort = opts->anneal == 0                     ? DEFAULT_ANNEAL
                 : opts->anneal > MTS_TUNNEL_MAX_ANNEAL ? MTS_TUNNEL_MAX_ANNEAL
                                                        : opts->anneal;

    /* The drawn triangles, numbered in drawing order, and which one each
     * follows in its strip. */
    tri = malloc((size_t)n * 3 * sizeof *tri + 1);
    nb = malloc((size_t)n * 3 * sizeof *nb + 1);
    o.L.n = n;
    o.L.tri = tri;
    o.L.nb = nb;
    o.L.mask = calloc((size_t)n + 1, 1);
    prev = malloc((size_t)n * sizeof *prev + 1);
    if (!tri || !nb || !o.L.mask || !prev)
        goto nomem;
    uint32_t t = 0;
    for (uint32_t s = 0; s < in->strip_count; s++) {
        const uint32_t *p = in->indices + in->offsets[s];
        uint32_t len = in->offsets[s + 1] - in->offsets[s], last = NONE;
        for (uint32_t w = 0; w + 2 < len; w++) {
            if (!mts_strip_window(p, w, tri + 3 * (size_t)t))
                continue;
            prev[t] = last;
            last = t++;
        }
    }
    rc = mts__links_adjacency(tri, n, vertex_count, nb, "tunnel", err);
    if (rc != MTS_OK)
        goto cleanup;
    /* Links from the input: consecutive drawn triangles of a strip that are
     * neighbours, within the cap (a longer input strip is cut). */
    {
        uint32_t run = 0;
        for (t = 0; t < n; t++) {
            uint32_t p = prev[t];
            unsigned e = 3;
            if (p != NONE && run < o.L.max_path && mts__links_count(&o.L, p) < 2)
                e = mts__links_free_edge(&o.L, p, t);
            if (e < 3) {
                mts__links_set(&o.L, p, e);
                run++;
            } else {
                run = 1;
            }
        }
    }

    if (length >= 1 && n > 0) {
        o.depth = (length - 1) / 2;
        o.cut_depth = o.depth;
        o.bound = PARTIAL_BOUND;
        o.L.pid = malloc((size_t)n * sizeof *o.L.pid);
        o.L.pos = malloc((size_t)n * sizeof *o.L.pos);
        o.L.plen = malloc((size_t)n * sizeof *o.L.plen);
        o.L.pend = malloc((size_t)n * sizeof *o.L.pend);
        o.L.lab = calloc(n, sizeof *o.L.lab);
        o.L.touched = calloc(n, sizeof *o.L.touched);
        if (!o.L.pid || !o.L.pos || !o.L.plen || !o.L.pend || !o.L.lab || !o.L.touched)
            goto nomem;
        st.passes = improve(&o);
        if (effort > 0) {
            st.anneal = (uint32_t)effort;
            anneal(&o, (uint64_t)effort * n, ANNEAL_T0, ANNEAL_T1, o.depth, &opts->progress);
            /* and down to a local minimum again, exhaustively */
            memset(o.L.touched, 0, (size_t)n * sizeof *o.L.touched);
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
        uint32_t e0 = mts__links_path_end(&o.L, t);
        if (e0 == NONE) {
            rc = mts_error_set(err, MTS_ERR_INTERNAL, "tunnel: triangle %u is on a cycle", t);
            goto cleanup;
        }
        uint32_t pv = NONE, cur = e0, run = 0;
        starts[paths++] = placed;
        while (cur != NONE && placed < n) {
            if (run == o.L.max_path) {
                starts[paths++] = placed;
                run = 0;
            }
            used[cur] = 1;
            order[placed++] = cur;
            run++;
            uint32_t nx = mts__links_step(&o.L, pv, cur);
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
    rev = malloc((size_t)o.L.max_path * sizeof *rev + 1);
    if (!encs || !rev)
        goto nomem;
    uint64_t total = 0;
    for (uint32_t p = 0; p < paths; p++) {
        uint32_t m = starts[p + 1] - starts[p], sw;
        for (uint32_t k = 0; k < m; k++)
            rev[k] = order[starts[p] + m - 1 - k];
        encs[p].len[0] = mts__links_encode(tri, nb, order + starts[p], m, NULL, &sw);
        encs[p].len[1] = mts__links_encode(tri, nb, rev, m, NULL, &sw);
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
        mts__links_encode(tri, nb, order + starts[p], m, buf + encs[p].at[0], &sw);
        mts__links_encode(tri, nb, rev, m, buf + encs[p].at[1], &sw);
    }

    /* The order: for the cache (cacheorder.h). */
    emit = malloc((size_t)paths * sizeof *emit + 1);
    emit_dir = malloc((size_t)paths + 1);
    if (!emit || !emit_dir ||
        !mts__order_paths(encs, paths, buf, vertex_count, csize, o.L.max_path, emit, emit_dir,
                          &st.cache_misses))
        goto nomem;
    const uint32_t emitted = paths;
    uint64_t out_total = 0;
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
            over = one.triangles > o.L.max_path;
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
            st.cache_misses = 0; /* the input's order, not the one counted */
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
        const mts__order_path *e = &encs[emit[i]];
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
    free(tri);
    free(nb);
    free(o.L.mask);
    free(o.L.pid);
    free(o.L.pos);
    free(o.L.plen);
    free(o.L.pend);
    free(o.L.lab);
    free(o.L.touched);
    free(prev);
    free(order);
    free(starts);
    free(used);
    free(rev);
    free(buf);
    free(encs);
    free(emit);
    free(emit_dir);
    return rc;
}

/* The cache order keeps arrays per vertex id; ids far sparser than the
 * strips' indices (a caller's vertex_count up to 2^32 - 1) are renumbered
 * in order first, so that memory follows the strips. */
mts_result mts_tunnel(const mts_strips *in, uint32_t vertex_count,
                      const mts_tunnel_options *opts, mts_strips *out, mts_tunnel_stats *stats,
                      mts_error *err)
{
    if (!out || !in || (uint64_t)vertex_count <= 2 * (uint64_t)in->index_count + 1024)
        return tunnel_dense(in, vertex_count, opts, out, stats, err);
    *out = (mts_strips){0};
    for (uint32_t k = 0; k < in->index_count; k++) {
        if (in->indices[k] >= vertex_count)
            return mts_error_set(err, MTS_ERR_RANGE, "tunnel: index %u at %u is past %u vertices",
                                 in->indices[k], k, vertex_count);
    }
    uint32_t n = in->index_count, used = 0;
    uint32_t *ids = malloc(((size_t)n + 1) * sizeof *ids);
    uint32_t *local = malloc(((size_t)n + 1) * sizeof *local);
    if (!ids || !local) {
        free(ids);
        free(local);
        return mts_error_set(err, MTS_ERR_NOMEM, "tunnel: out of memory for %u indices", n);
    }
    memcpy(ids, in->indices, (size_t)n * sizeof *ids);
    qsort(ids, n, sizeof *ids, mts_words_cmp);
    for (uint32_t k = 0; k < n; k++) {
        if (used == 0 || ids[k] != ids[used - 1])
            ids[used++] = ids[k];
    }
    for (uint32_t k = 0; k < n; k++) {
        const uint32_t *at = bsearch(&in->indices[k], ids, used, sizeof *ids, mts_words_cmp);
        local[k] = (uint32_t)(at - ids);
    }
    mts_strips renamed = {.strip_count = in->strip_count, .index_count = n, .offsets = in->offsets, .indices = local};
    mts_result rc = tunnel_dense(&renamed, used, opts, out, stats, err);
    for (uint32_t k = 0; rc == MTS_OK && k < out->index_count; k++)
        out->indices[k] = ids[out->indices[k]];
    free(ids);
    free(local);
    return rc;
}
