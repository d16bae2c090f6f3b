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
 *     as a border, so any input gives correct strips, only longer ones;
 *  2. greedy paths: the seed is a free triangle with the fewest free
 *     neighbours; from each of its 3 rotations a path grows, and the one
 *     with the fewest indices per triangle wins. Growing prefers, STRIPE's
 *     way, the neighbour with fewer free neighbours of its own (taking the
 *     swap for it), so that no triangle is stranded as a strip of its own;
 *     on ties it goes on without a swap. (Growing backwards from the seed as
 *     well is implemented but off: it did not pay, see the test file);
 *  3. tunnelling: short alternating sequences of "link an end into a path,
 *     cut the path next to it" that end by joining two ends (one strip
 *     fewer) or that remove swaps, kept when 3 S + W drops; searched from
 *     every path end and from every swap (cut there first), in passes
 *     until nothing changes;
 *  4. encoding each path into indices with the winding of strips.h.
 * Measured figures and the variants that lost are in tests/test_stripify.c.
 */
#include "stripify.h"

#include <stdlib.h>
#include <string.h>

#define NONE UINT32_MAX

/* Knobs fixed by measurement; a struct so that a benchmark can compare. */
struct stripify_opts {
    int stripe_turns; /* 1: prefer the neighbour with fewer free neighbours */
    int backward;     /* also grow each path backwards from its seed (measured:
                       * no gain once tunnelling runs, so off) */
    int depth;        /* tunnel search depth (link/cut steps), -1: no tunnelling */
    int bound;        /* cost increase a partial tunnel may carry */
    int cut_depth;    /* search depth from the two ends of a cut swap */
    int passes;       /* most tunnelling passes (the first over all triangles,
                       * the others near the last pass's changes) */
    uint32_t max_path; /* most triangles in one strip, >= 1 */
};

enum { TUNNEL_MAX_DEPTH = 8, UNDO_MAX = 2 * TUNNEL_MAX_DEPTH + 4 };

static const struct stripify_opts default_opts = {1, 0, 4, 2, 4, 16, MTS_STRIPIFY_MAX_STRIP};

typedef struct ctx {
    const uint32_t *tri;
    uint32_t n;
    struct stripify_opts opts;
    uint32_t *nb;         /* 3n: neighbour across edge (v_i, v_i+1), NONE at a border */
    uint8_t *used;        /* already in a path */
    uint8_t *deg;         /* number of unused neighbours */
    uint32_t *mark;       /* == stamp: taken by the path being tried */
    uint32_t stamp;
    uint32_t *bucket[3];  /* seed candidates by degree 0..2 (stacks, lazily updated) */
    uint32_t bucket_len[3];
    uint32_t cursor;      /* lowest id that may still have degree 3 */
} ctx;

/* ---- 1. adjacency ------------------------------------------------------- */

typedef struct edge_key {
    uint64_t key; /* low end << 32 | high end */
    uint32_t h;   /* half-edge id */
} edge_key;

static int edge_key_compare(const void *pa, const void *pb)
{
    const edge_key *a = pa, *b = pb;
    if (a->key != b->key)
        return a->key < b->key ? -1 : 1;
    return a->h < b->h ? -1 : a->h > b->h;
}

/* Half-edge h = 3t + i runs from tri[h] to tri[next_h(h)]. */
static inline uint32_t next_h(uint32_t h)
{
    return h % 3 == 2 ? h - 2 : h + 1;
}

static inline uint64_t key_of(const uint32_t *tri, uint32_t h)
{
    uint32_t a = tri[h], b = tri[next_h(h)];
    return a < b ? (uint64_t)a << 32 | b : (uint64_t)b << 32 | a;
}

/* Sorts the half-edges by (low end, high end) into order: two stable
 * counting sorts over the vertex range, O(n + V), when that range is not
 * much larger than the mesh; a comparison sort otherwise, so that a huge
 * vertex_count with few triangles cannot make us allocate for it. */
static mts_result sort_half_edges(const ctx *c, uint32_t vertex_count, uint32_t *order,
                                  mts_error *err)
{
    mts_result rc = MTS_OK;
    uint32_t n3 = 3 * c->n;
    uint32_t *count = NULL, *tmp = NULL;
    edge_key *keys = NULL;
    if ((uint64_t)vertex_count <= 4 * (uint64_t)n3 + 1024) {
        count = calloc((size_t)vertex_count + 1, sizeof *count);
        tmp = malloc((size_t)n3 * sizeof *tmp);
        if (!count || !tmp)
            goto nomem;
        for (uint32_t h = 0; h < n3; h++)
            count[(uint32_t)key_of(c->tri, h) + 1]++;
        for (uint32_t v = 0; v < vertex_count; v++)
            count[v + 1] += count[v];
        for (uint32_t h = 0; h < n3; h++)
            tmp[count[(uint32_t)key_of(c->tri, h)]++] = h;
        memset(count, 0, ((size_t)vertex_count + 1) * sizeof *count);
        for (uint32_t h = 0; h < n3; h++)
            count[(key_of(c->tri, h) >> 32) + 1]++;
        for (uint32_t v = 0; v < vertex_count; v++)
            count[v + 1] += count[v];
        for (uint32_t k = 0; k < n3; k++)
            order[count[key_of(c->tri, tmp[k]) >> 32]++] = tmp[k];
    } else {
        keys = malloc((size_t)n3 * sizeof *keys);
        if (!keys)
            goto nomem;
        for (uint32_t h = 0; h < n3; h++)
            keys[h] = (edge_key){key_of(c->tri, h), h};
        qsort(keys, n3, sizeof *keys, edge_key_compare);
        for (uint32_t k = 0; k < n3; k++)
            order[k] = keys[k].h;
    }
    goto cleanup;
nomem:
    rc = mts_error_set(err, MTS_ERR_NOMEM,
                       "stripify: out of memory for the adjacency of %u triangles", c->n);
cleanup:
    free(count);
    free(tmp);
    free(keys);
    return rc;
}

static mts_result build_adjacency(ctx *c, uint32_t vertex_count, mts_error *err)
{
    uint32_t n3 = 3 * c->n;
    uint32_t *order = malloc((size_t)n3 * sizeof *order);
    if (!order)
        return mts_error_set(err, MTS_ERR_NOMEM,
                             "stripify: out of memory for the adjacency of %u triangles", c->n);
    mts_result rc = sort_half_edges(c, vertex_count, order, err);
    if (rc != MTS_OK)
        goto cleanup;
    for (uint32_t h = 0; h < n3; h++)
        c->nb[h] = NONE;
    for (uint32_t k = 0; k < n3;) {
        uint64_t key = key_of(c->tri, order[k]);
        uint32_t e = k + 1;
        while (e < n3 && key_of(c->tri, order[e]) == key)
            e++;
        /* Only an edge with exactly two faces that run through it in
         * opposite directions joins them: a strip across any other edge
         * would draw one of them with the wrong winding. */
        uint32_t h0 = order[k], h1 = order[k + 1 < n3 ? k + 1 : k];
        if (e - k == 2 && c->tri[h0] != c->tri[h1]) {
            c->nb[h0] = h1 / 3;
            c->nb[h1] = h0 / 3;
        }
        k = e;
    }
cleanup:
    free(order);
    return rc;
}

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

/* Local edge index of the edge between local vertices i and j. */
static inline unsigned edge_of(unsigned i, unsigned j)
{
    return (i + 1) % 3 == j ? i : j;
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

/* Local index of vertex v in triangle t. */
static inline unsigned local_of(const ctx *c, uint32_t t, uint32_t v)
{
    const uint32_t *tv = c->tri + 3 * (size_t)t;
    return tv[0] == v ? 0u : tv[1] == v ? 1u : 2u;
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
        uint32_t f = c->nb[3 * (size_t)t + edge_of(lq, lr)];
        uint32_t s = c->nb[3 * (size_t)t + edge_of(lp, lr)];
        int fa = avail(c, f), sa = avail(c, s) && s != f;
        int take_swap;
        if (!fa && !sa)
            break;
        if (!fa)
            take_swap = 1;
        else if (!sa)
            take_swap = 0;
        else if (c->opts.stripe_turns)
            /* Go where fewer free neighbours remain, so that the other one is
             * not left stranded; the swap only when strictly better. Against
             * "always free first" this halves the strips for twice the swaps,
             * a net gain (test file). */
            take_swap = free_degree(c, s, t) < free_degree(c, f, t);
        else
            take_swap = 0;
        uint32_t u = take_swap ? s : f;
        uint32_t va = c->tri[3 * (size_t)t + (take_swap ? lp : lq)];
        uint32_t vr = c->tri[3 * (size_t)t + lr];
        unsigned ur = local_of(c, u, vr), ua = local_of(c, u, va);
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

/* ---- 4. encoding -------------------------------------------------------- */

/* Writes the strip of path[0..m) to out (when not NULL) and returns its
 * length, 0 if two consecutive triangles are not neighbours (a bug); *swaps
 * gets the swaps. The first triangle is rotated so that the strip leaves it
 * without a swap, at even parity. */
static uint32_t encode(const ctx *c, const uint32_t *path, uint32_t m, uint32_t *out,
                       uint32_t *swaps)
{
    const uint32_t *tri = c->tri;
    uint32_t t = path[0];
    *swaps = 0;
    if (m == 1) {
        if (out)
            memcpy(out, tri + 3 * (size_t)t, 3 * sizeof *out);
        return 3;
    }
    unsigned e = 0;
    while (e < 3 && c->nb[3 * (size_t)t + e] != path[1])
        e++;
    if (e == 3)
        return 0;
    /* window 0 = (v_e+2, v_e, v_e+1), a rotation of t; leaves by (v_e, v_e+1) */
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
        if (c->nb[3 * (size_t)t + edge_of(lq, lr)] == u) {
            la = lq;
        } else if (c->nb[3 * (size_t)t + edge_of(lp, lr)] == u) {
            /* "... p q r" becomes "... p q p r": window (q p r) at the next
             * parity is still t with its winding, and (p r x) is u's */
            la = lp;
            if (out) {
                out[len] = out[len - 1]; /* r, the last index so far */
                out[len - 1] = tri[3 * (size_t)t + lp];
            }
            len++;
            (*swaps)++;
        } else {
            return 0;
        }
        uint32_t va = tri[3 * (size_t)t + la], vr = tri[3 * (size_t)t + lr];
        unsigned ur = local_of(c, u, vr), ua = local_of(c, u, va);
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

/* ---- 3. tunnelling ------------------------------------------------------ */

/* The cover as a 3-bit mask per triangle: bit e set when its path goes
 * through edge e (to nb[3t + e]); at most two bits are set, fewer at a path
 * end. A search changes links through op_link / op_unlink, which log the
 * change so that it can be undone. */

typedef struct undo_op {
    uint32_t t, u;   /* linked or unlinked across edge et of t, eu of u */
    uint8_t et, eu;
    uint8_t added;   /* 1: the link was added, 0: removed */
} undo_op;

typedef struct opt {
    const ctx *c;
    uint8_t *mask;
    /* Labels, valid whenever a search starts (see paths_ok): the path of t
     * is named by its first triangle pid[t], t lies at position pos[t] on
     * it, and plen[pid] is its length. lab[t] == lab_stamp: labelled since
     * the last accepted change. */
    uint32_t *pid, *pos, *plen, *lab;
    uint32_t lab_stamp;
    uint32_t max_path;
    uint8_t *touched; /* the last pass that changed links near the triangle */
    uint8_t pass;     /* the current pass, from 1 */
    int depth, cut_depth, bound;
    int nundo;
    undo_op undo[UNDO_MAX];
} opt;

static const uint8_t link_count[8] = {0, 1, 1, 2, 1, 2, 2, 3};
/* the vertex that the two edges of a 2-bit mask share: edges e and e+1
 * share vertex e+1 */
static const uint8_t pivot_local[8] = {0, 0, 0, 1, 0, 0, 2, 0};

static inline unsigned nlinks(const opt *o, uint32_t t)
{
    return link_count[o->mask[t]];
}

/* The vertex an interior triangle turns around, NONE for a path end. */
static inline uint32_t pivot(const opt *o, uint32_t t)
{
    uint8_t m = o->mask[t];
    return link_count[m] == 2 ? o->c->tri[3 * (size_t)t + pivot_local[m]] : NONE;
}

/* The edge of u = nb[3t + e] that is edge e of t, run the other way. */
static inline unsigned twin_edge(const ctx *c, uint32_t t, unsigned e)
{
    uint32_t u = c->nb[3 * (size_t)t + e];
    return local_of(c, u, c->tri[3 * (size_t)t + (e + 1) % 3]);
}

static inline int linked(const opt *o, uint32_t t, uint32_t u)
{
    const uint32_t *n3 = o->c->nb + 3 * (size_t)t;
    uint8_t m = o->mask[t];
    return ((m & 1) && n3[0] == u) || ((m & 2) && n3[1] == u) || ((m & 4) && n3[2] == u);
}

/* The neighbour along the path from cur that is not prev (NONE: an end). */
static inline uint32_t step(const opt *o, uint32_t prev, uint32_t cur)
{
    const uint32_t *n3 = o->c->nb + 3 * (size_t)cur;
    uint8_t m = o->mask[cur];
    for (int e = 0; e < 3; e++) {
        if ((m >> e & 1) && n3[e] != prev)
            return n3[e];
    }
    return NONE;
}

static void op_link(opt *o, uint32_t t, unsigned et)
{
    uint32_t u = o->c->nb[3 * (size_t)t + et];
    unsigned eu = twin_edge(o->c, t, et);
    o->mask[t] |= (uint8_t)(1u << et);
    o->mask[u] |= (uint8_t)(1u << eu);
    o->undo[o->nundo++] = (undo_op){t, u, (uint8_t)et, (uint8_t)eu, 1};
}

static void op_unlink(opt *o, uint32_t t, unsigned et)
{
    uint32_t u = o->c->nb[3 * (size_t)t + et];
    unsigned eu = twin_edge(o->c, t, et);
    o->mask[t] &= (uint8_t)~(1u << et);
    o->mask[u] &= (uint8_t)~(1u << eu);
    o->undo[o->nundo++] = (undo_op){t, u, (uint8_t)et, (uint8_t)eu, 0};
}

static void undo_to(opt *o, int mark)
{
    while (o->nundo > mark) {
        const undo_op *op = &o->undo[--o->nundo];
        if (op->added) {
            o->mask[op->t] &= (uint8_t)~(1u << op->et);
            o->mask[op->u] &= (uint8_t)~(1u << op->eu);
        } else {
            o->mask[op->t] |= (uint8_t)(1u << op->et);
            o->mask[op->u] |= (uint8_t)(1u << op->eu);
        }
    }
}

/* Swaps on the path edges that touch the k distinct triangles T. */
static int local_swaps(const opt *o, const uint32_t *T, int k)
{
    int w = 0;
    for (int i = 0; i < k; i++) {
        uint32_t t = T[i], pt = pivot(o, t);
        if (pt == NONE)
            continue;
        for (unsigned e = 0; e < 3; e++) {
            if (!(o->mask[t] >> e & 1))
                continue;
            uint32_t u = o->c->nb[3 * (size_t)t + e];
            int seen = 0;
            for (int j = 0; j < i; j++)
                seen |= T[j] == u;
            w += !seen && pivot(o, u) == pt;
        }
    }
    return w;
}

/* Whether the links as changed by the search in progress still form short
 * paths: no cycle and no path longer than max_path. Checked without
 * walking: the labels pid/pos/plen were valid when the search started; the
 * links it removed cut those paths into segments and the links it added
 * join segment ends, so union-find over a handful of segments, with their
 * lengths, answers both. */
static int paths_ok(const opt *o)
{
    uint32_t cut_pid[UNDO_MAX], cut_at[UNDO_MAX];
    uint32_t seg_pid[2 * UNDO_MAX], seg_k[2 * UNDO_MAX], size[2 * UNDO_MAX];
    int parent[2 * UNDO_MAX];
    int ncut = 0, nseg = 0;
    for (int i = 0; i < o->nundo; i++) {
        if (!o->undo[i].added) {
            uint32_t a = o->undo[i].t, b = o->undo[i].u;
            cut_pid[ncut] = o->pid[a];
            /* the cut lies between positions cut_at and cut_at + 1 */
            cut_at[ncut++] = o->pos[a] < o->pos[b] ? o->pos[a] : o->pos[b];
        }
    }
    for (int i = 0; i < o->nundo; i++) {
        if (!o->undo[i].added)
            continue;
        int r[2];
        for (int e = 0; e < 2; e++) {
            uint32_t x = e ? o->undo[i].u : o->undo[i].t;
            uint32_t px = o->pid[x], k = 0;
            /* x's segment: the k-th piece of its path, between the nearest
             * cuts below and above it */
            uint32_t lo = 0, hi = o->plen[px];
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

/* Was the link across edge e of t added by the search in progress? Such a
 * link is not in the labelled paths, so the search must not cut it
 * (paths_ok could not place the cut). */
static int added_now(const opt *o, uint32_t t, unsigned e)
{
    for (int i = 0; i < o->nundo; i++) {
        const undo_op *op = &o->undo[i];
        if (op->added && ((op->t == t && op->et == e) || (op->u == t && op->eu == e)))
            return 1;
    }
    return 0;
}

/* One end of the path through t; NONE if t lies on a cycle (a bug: the
 * caller reports it rather than loop for ever). */
static uint32_t path_end(const opt *o, uint32_t t)
{
    uint32_t prev = NONE, cur = t;
    for (uint32_t k = 0; k <= o->c->n; k++) {
        uint32_t nx = step(o, prev, cur);
        if (nx == NONE)
            return cur;
        prev = cur;
        cur = nx;
    }
    return NONE;
}

/* Labels the path through t. */
static void label_path(opt *o, uint32_t t)
{
    uint32_t first = path_end(o, t), k = 0;
    if (first == NONE)
        return; /* a cycle: cannot happen; the read-out reports it */
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

/* Keeps the search's changes, relabels every path they touched and marks
 * the triangles around them for the next pass. */
static void accept(opt *o)
{
    if (++o->lab_stamp == 0) {
        /* wrapped (only on meshes of over 800 million triangles): forget
         * every old stamp; the labels themselves stay valid */
        memset(o->lab, 0, (size_t)o->c->n * sizeof *o->lab);
        o->lab_stamp = 1;
    }
    for (int i = 0; i < o->nundo; i++) {
        uint32_t ends[2] = {o->undo[i].t, o->undo[i].u};
        for (int e = 0; e < 2; e++) {
            o->touched[ends[e]] = o->pass;
            for (unsigned k = 0; k < 3; k++) {
                uint32_t w = o->c->nb[3 * (size_t)ends[e] + k];
                if (w != NONE)
                    o->touched[w] = o->pass;
            }
        }
        if (o->lab[o->undo[i].t] != o->lab_stamp)
            label_path(o, o->undo[i].t);
        if (o->lab[o->undo[i].u] != o->lab_stamp)
            label_path(o, o->undo[i].u);
    }
    o->nundo = 0;
}

/* Depth-first search for a tunnel from the path end z; cum is the change of
 * 3 S + W so far. Stops at the first state that costs less than at the
 * start and has no cycle (returns 1, changes kept in the undo log); else
 * restores the links and returns 0. A step has at most 3 x 2 choices, so a
 * search visits at most 6^depth states; the bound on cum prunes most. (Marks
 * that let a search go through each edge once were tried: same strips, same
 * time, so the search stays exhaustive.) */
static int tunnel(opt *o, uint32_t z, int depth, int cum)
{
    const ctx *c = o->c;
    for (unsigned i = 0; i < 3; i++) {
        uint32_t y = c->nb[3 * (size_t)z + i];
        if (y == NONE || (o->mask[z] >> i & 1) || linked(o, z, y))
            continue;
        int here = o->nundo;
        if (nlinks(o, y) < 2) {
            /* y is an end too: join the two paths, one strip fewer */
            uint32_t T[2] = {z, y};
            int before = local_swaps(o, T, 2);
            op_link(o, z, i);
            int d = local_swaps(o, T, 2) - before - 3;
            if (cum + d < 0 && paths_ok(o))
                return 1;
            undo_to(o, here);
            continue;
        }
        if (depth == 0)
            continue;
        for (unsigned e = 0; e < 3; e++) {
            /* link z to y and cut y from yi: the end moves to yi */
            if (!(o->mask[y] >> e & 1) || added_now(o, y, e))
                continue;
            uint32_t yi = c->nb[3 * (size_t)y + e];
            uint32_t T[3] = {z, y, yi};
            int before = local_swaps(o, T, 3);
            op_unlink(o, y, e);
            op_link(o, z, i);
            int d = local_swaps(o, T, 3) - before;
            if (cum + d < 0 && paths_ok(o))
                return 1;
            if (cum + d <= o->bound && tunnel(o, yi, depth - 1, cum + d))
                return 1;
            undo_to(o, here);
        }
    }
    return 0;
}

static void improve(opt *o, int passes)
{
    uint32_t n = o->c->n;
    o->lab_stamp = 1;
    for (uint32_t t = 0; t < n; t++) {
        if (o->lab[t] != 1)
            label_path(o, t);
    }
    if (passes > 254)
        passes = 254;
    for (int pass = 1; pass <= passes; pass++) {
        int changed = 0;
        o->pass = (uint8_t)pass;
        for (uint32_t t = 0; t < n; t++) {
            /* after the first pass, only where the last one changed
             * something: elsewhere every search would fail again */
            if (pass > 1 && o->touched[t] < pass - 1)
                continue;
            o->nundo = 0;
            if (nlinks(o, t) < 2) {
                if (tunnel(o, t, o->depth, 0)) {
                    accept(o);
                    changed = 1;
                    t--; /* t may still be an end: try it again */
                }
                continue;
            }
            /* Interior triangle with a swap towards a later neighbour u: cut
             * there (+3 for the new path, -1 swap and whatever the new ends
             * lose) and look for a tunnel from either new end that rejoins
             * the pieces more cheaply. */
            uint32_t pt = pivot(o, t);
            for (unsigned e = 0; e < 3; e++) {
                uint32_t u = o->c->nb[3 * (size_t)t + e];
                if (!(o->mask[t] >> e & 1) || u < t || pivot(o, u) != pt)
                    continue;
                uint32_t T[2] = {t, u};
                int before = local_swaps(o, T, 2);
                op_unlink(o, t, e);
                int d = local_swaps(o, T, 2) - before + 3;
                if (tunnel(o, t, o->cut_depth, d) || tunnel(o, u, o->cut_depth, d)) {
                    accept(o);
                    changed = 1;
                    break;
                }
                undo_to(o, 0);
            }
        }
        if (!changed)
            break;
    }
}

/* 1 when a strip read from the end triangle a needs a swap at its second
 * triangle b: b, at odd parity, goes on without a swap only if it turns
 * around the first vertex of its entry edge from a in b's own orientation. */
static int start_swap(const opt *o, uint32_t a)
{
    uint32_t b = step(o, NONE, a);
    if (b == NONE || nlinks(o, b) < 2)
        return 0;
    unsigned e = 0;
    while (e < 3 && !((o->mask[b] >> e & 1) && o->c->nb[3 * (size_t)b + e] == a))
        e++;
    return pivot(o, b) != o->c->tri[3 * (size_t)b + e % 3];
}

/* ---- driver ------------------------------------------------------------- */

static mts_result stripify_impl(const uint32_t *triangles, uint32_t triangle_count,
                                uint32_t vertex_count, mts_strips *out, mts_stripify_stats *stats,
                                const struct stripify_opts *opts, mts_error *err)
{
    mts_result rc = MTS_OK;
    ctx c = {0};
    opt o = {0};
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
    c.opts = *opts;
    if (c.opts.depth > TUNNEL_MAX_DEPTH)
        c.opts.depth = TUNNEL_MAX_DEPTH;
    if (c.opts.max_path < 1)
        c.opts.max_path = 1;
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
    o.mask = calloc(n, 1);
    if (!c.nb || !c.used || !c.deg || !c.mark || !c.bucket[0] || !c.bucket[1] || !c.bucket[2] ||
        !order || !starts || !trial || !best || !fwd || !bwd || !o.mask) {
        rc = mts_error_set(err, MTS_ERR_NOMEM, "stripify: out of memory for %u triangles", n);
        goto cleanup;
    }
    rc = build_adjacency(&c, vertex_count, err);
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
    /* the buckets pop from the top: lowest ids first among the initial ones */
    for (int d = 0; d < 3; d++) {
        for (uint32_t i = 0, j = c.bucket_len[d]; i + 1 < j; i++, j--) {
            uint32_t x = c.bucket[d][i];
            c.bucket[d][i] = c.bucket[d][j - 1];
            c.bucket[d][j - 1] = x;
        }
    }

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
            unsigned a = j, b = (j + 1) % 3, cc = (j + 2) % 3;
            uint32_t nf = grow(&c, seed, b, cc, fwd, c.opts.max_path - 1);
            /* Backwards: the strip read in reverse ends with the seed as
             * (c b a), so it goes on from last vertex a after b. Parity is
             * settled when the joined path is encoded from its far end. */
            uint32_t nbk =
                c.opts.backward ? grow(&c, seed, b, a, bwd, c.opts.max_path - 1 - nf) : 0;
            uint32_t m = 0;
            for (uint32_t k = nbk; k > 0; k--)
                trial[m++] = bwd[k - 1];
            trial[m++] = seed;
            memcpy(trial + m, fwd, (size_t)nf * sizeof *fwd);
            m += nf;
            uint32_t sw, len = encode(&c, trial, m, NULL, &sw);
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
    o.c = &c;
    for (uint32_t s = 0; s < strip_count; s++) {
        for (uint32_t k = starts[s]; k + 1 < starts[s + 1]; k++) {
            uint32_t x = order[k], y = order[k + 1];
            unsigned e = 0;
            while (e < 3 && (c.nb[3 * (size_t)x + e] != y || (o.mask[x] >> e & 1)))
                e++;
            if (e == 3) {
                rc = mts_error_set(err, MTS_ERR_INTERNAL, "stripify: path %u is broken", s);
                goto cleanup;
            }
            o.mask[x] |= (uint8_t)(1u << e);
            o.mask[y] |= (uint8_t)(1u << twin_edge(&c, x, e));
        }
    }
    if (c.opts.depth >= 0) {
        o.pid = fwd;
        o.pos = bwd;
        o.touched = calloc(n, 1);
        o.plen = malloc((size_t)n * sizeof *o.plen);
        o.lab = calloc(n, sizeof *o.lab);
        o.max_path = c.opts.max_path;
        if (!o.touched || !o.plen || !o.lab) {
            rc = mts_error_set(err, MTS_ERR_NOMEM, "stripify: out of memory for %u triangles", n);
            goto cleanup;
        }
        o.depth = c.opts.depth;
        o.cut_depth = c.opts.cut_depth < c.opts.depth ? c.opts.cut_depth : c.opts.depth;
        o.bound = c.opts.bound;
        improve(&o, c.opts.passes);
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
        uint32_t e0 = path_end(&o, t), start = e0;
        if (e0 == NONE) {
            rc = mts_error_set(err, MTS_ERR_INTERNAL, "stripify: triangle %u is on a cycle", t);
            goto cleanup;
        }
        if (o.mask[e0]) {
            uint32_t e1 = path_end(&o, e0);
            int f0 = start_swap(&o, e0), f1 = start_swap(&o, e1);
            if ((f0 && !f1) || (f0 == f1 && e1 < e0))
                start = e1;
        }
        starts[strip_count++] = placed;
        uint32_t prev = NONE, cur = start;
        while (cur != NONE && placed < n) {
            c.used[cur] = 1;
            order[placed++] = cur;
            uint32_t nx = step(&o, prev, cur);
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
        uint32_t len = encode(&c, order + starts[s], m, NULL, &sw);
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
        at += encode(&c, order + starts[s], starts[s + 1] - starts[s], out->indices + at, &sw);
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
    free(o.mask);
    free(o.touched);
    free(o.plen);
    free(o.lab);
    return rc;
}

mts_result mts_stripify(const uint32_t *triangles, uint32_t triangle_count, uint32_t vertex_count,
                        mts_strips *out, mts_stripify_stats *stats, mts_error *err)
{
    return stripify_impl(triangles, triangle_count, vertex_count, out, stats, &default_opts, err);
}
