/* Cache order: the order of a set of strips, and the direction each is
 * read in, for a FIFO post-transform vertex cache (the benchmarks' model:
 * ACMR-32). Two greedy orders -- strip by strip, and over chains of strips
 * joined where they share most (chain_links) -- the one with fewer misses
 * kept, then refined by or-opt moves of single strips (order_refine). Used
 * by the tunnelling's read-out (tunnel.c); the figures behind the choices:
 * docs/strips.md. */
#include "cacheorder.h"

#include <stdlib.h>
#include <string.h>

#include "striplinks.h"

#define NONE MTS__NONE

typedef mts__order_path enc;


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
    /* the ring slot, misses % size, kept rather than divided per miss */
    uint32_t slot = (uint32_t)(f->misses % f->size);
    for (uint32_t i = 0; i < n; i++) {
        uint32_t v = idx[i];
        if (!fifo_hit(f, v)) {
            f->ring[slot] = v;
            slot = slot + 1 == f->size ? 0 : slot + 1;
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

/* Both directions of a path, encoded. */

/* What the orders below read: the encoded paths and, per vertex, the paths
 * that use it (vpaths[vstart[v] .. vstart[v + 1])). */
typedef struct order_ctx {
    uint32_t paths;
    const enc *encs;
    const uint32_t *buf, *vstart, *vpaths;
    fifo *f;
    uint64_t *save; /* fifo_trial's room: 2 max_path + 3 each */
    uint32_t *savev;
    uint8_t *used;  /* paths + 1 */
    uint32_t *cand; /* paths + 1 */
} order_ctx;

/* Empties the cache: every stamp reads as a miss, and the ring fills from
 * slot 0 again (the greedy reads its first slots as the contents). */
static void fifo_clear(fifo *f)
{
    f->misses += 2 * (uint64_t)f->size - f->misses % f->size;
}

/* The greedy order (see the top of the file): after each strip, of the
 * strips sharing a vertex with the cache, the one and the direction that
 * save the most misses against an empty cache; else the next one by id.
 * With chains (succ != NULL), only a chain's first strip is picked, in the
 * direction the chain fixed (cdir < 2), and the whole chain follows it.
 * Returns the misses of the whole order. */
static uint64_t order_greedy(const order_ctx *c, const uint32_t *succ, const uint32_t *pred,
                             const uint8_t *cdir, uint32_t *emit, uint8_t *emit_dir)
{
    fifo *f = c->f;
    const enc *encs = c->encs;
    fifo_clear(f);
    uint64_t base = f->misses;
    memset(c->used, 0, (size_t)c->paths + 1);
    for (uint32_t p = 0; p < c->paths; p++)
        c->cand[p] = NONE;
    uint32_t emitted = 0, next_fallback = 0;
    while (emitted < c->paths) {
        uint32_t best = NONE;
        int best_dir = 0;
        int64_t best_gain = 0;
        uint64_t filled = f->misses - base;
        uint32_t slots = filled < f->size ? (uint32_t)filled : f->size;
        for (uint32_t r = 0; r < slots; r++) {
            uint32_t v = f->ring[r];
            for (uint32_t k = c->vstart[v]; k < c->vstart[v + 1]; k++) {
                uint32_t p = c->vpaths[k];
                if (c->used[p] || c->cand[p] == emitted || (succ && pred[p] != NONE))
                    continue;
                c->cand[p] = emitted;
                for (int d = 0; d < 2; d++) {
                    if (!(encs[p].dirs >> d & 1) || (succ && cdir[p] < 2 && cdir[p] != d))
                        continue;
                    uint32_t miss = fifo_trial(f, c->buf + encs[p].at[d], encs[p].len[d],
                                               c->save, c->savev);
                    int64_t gain = (int64_t)encs[p].cold[d] - (int64_t)miss;
                    if (gain > best_gain || (gain == best_gain && best != NONE && p < best)) {
                        best_gain = gain;
                        best = p;
                        best_dir = d;
                    }
                }
            }
        }
        if (best == NONE) {
            while (c->used[next_fallback] || (succ && pred[next_fallback] != NONE))
                next_fallback++;
            best = next_fallback;
            best_dir = succ && cdir[best] < 2 ? cdir[best] : encs[best].dirs & 1 ? 0 : 1;
        }
        for (;;) {
            c->used[best] = 1;
            emit[emitted] = best;
            emit_dir[emitted++] = (uint8_t)best_dir;
            fifo_feed(f, c->buf + encs[best].at[best_dir], encs[best].len[best_dir]);
            if (!succ || succ[best] == NONE)
                break;
            best = succ[best];
            best_dir = cdir[best];
        }
    }
    return f->misses - base;
}

typedef struct pair_gain {
    uint32_t p, q;  /* p, then q */
    uint8_t dp, dq; /* in these directions */
    int32_t gain;   /* misses q saves after p, against q into an empty cache */
} pair_gain;

static int pair_gain_compare(const void *pa, const void *pb)
{
    const pair_gain *a = pa, *b = pb;
    if (a->gain != b->gain)
        return a->gain > b->gain ? -1 : 1;
    if (a->p != b->p)
        return a->p < b->p ? -1 : 1;
    if (a->q != b->q)
        return a->q < b->q ? -1 : 1;
    if (a->dp != b->dp)
        return a->dp < b->dp ? -1 : 1;
    return (a->dq > b->dq) - (a->dq < b->dq);
}

static uint32_t chain_root(uint32_t *parent, uint32_t x)
{
    while (parent[x] != x) {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    return x;
}

/* Chains for order_greedy, as the greedy edge heuristic of the travelling
 * salesman builds tours: every pair of strips that share a vertex is scored
 * by the misses the second saves right after the first (both ways, all
 * allowed directions), and the pairs are taken best first where both ends
 * are still free, the directions agree and no loop closes. The greedy order
 * looks one strip ahead and often strands a strip that only its neighbours
 * could have shared with; the chains settle the best pairs first (bunny00,
 * ACMR-32 0.836 -> 0.812 on the same strips). Returns 0 when out of memory. */
static int chain_links(const order_ctx *c, uint32_t *succ, uint32_t *pred, uint8_t *cdir)
{
    const enc *encs = c->encs;
    fifo *f = c->f;
    size_t cap = 4 * (size_t)c->paths + 16, np = 0;
    pair_gain *pg = malloc(cap * sizeof *pg);
    uint32_t *parent = malloc(((size_t)c->paths + 1) * sizeof *parent);
    uint32_t *qs = malloc(((size_t)c->paths + 1) * sizeof *qs);
    int ok = pg && parent && qs;
    for (uint32_t p = 0; ok && p < c->paths; p++)
        c->cand[p] = NONE;
    for (uint32_t p = 0; ok && p < c->paths; p++) {
        /* the strips that share a vertex with p, each once */
        const uint32_t *s = c->buf + encs[p].at[0];
        uint32_t nq = 0;
        for (uint32_t k = 0; k < encs[p].len[0]; k++) {
            uint32_t v = s[k];
            for (uint32_t j = c->vstart[v]; j < c->vstart[v + 1]; j++) {
                uint32_t q = c->vpaths[j];
                if (q == p || c->cand[q] == p)
                    continue;
                c->cand[q] = p;
                qs[nq++] = q;
            }
        }
        /* p fed once per direction: a trial leaves the cache as it was */
        for (int dp = 0; ok && dp < 2; dp++) {
            if (!(encs[p].dirs >> dp & 1))
                continue;
            fifo_clear(f);
            fifo_feed(f, c->buf + encs[p].at[dp], encs[p].len[dp]);
            for (uint32_t i = 0; ok && i < nq; i++) {
                uint32_t q = qs[i];
                for (int dq = 0; dq < 2; dq++) {
                    if (!(encs[q].dirs >> dq & 1))
                        continue;
                    uint32_t miss = fifo_trial(f, c->buf + encs[q].at[dq], encs[q].len[dq],
                                               c->save, c->savev);
                    int32_t gain = (int32_t)encs[q].cold[dq] - (int32_t)miss;
                    if (gain <= 0)
                        continue;
                    if (np == cap) {
                        pair_gain *grown = realloc(pg, 2 * cap * sizeof *pg);
                        if (!grown) {
                            ok = 0;
                            break;
                        }
                        pg = grown;
                        cap *= 2;
                    }
                    pg[np++] = (pair_gain){p, q, (uint8_t)dp, (uint8_t)dq, gain};
                }
            }
        }
    }
    if (ok) {
        qsort(pg, np, sizeof *pg, pair_gain_compare);
        for (uint32_t p = 0; p < c->paths; p++) {
            succ[p] = pred[p] = NONE;
            cdir[p] = 2; /* not fixed yet */
            parent[p] = p;
        }
        for (size_t i = 0; i < np; i++) {
            const pair_gain *e = &pg[i];
            if (succ[e->p] != NONE || pred[e->q] != NONE ||
                (cdir[e->p] < 2 && cdir[e->p] != e->dp) || (cdir[e->q] < 2 && cdir[e->q] != e->dq))
                continue;
            uint32_t a = chain_root(parent, e->p), b = chain_root(parent, e->q);
            if (a == b)
                continue;
            parent[a] = b;
            succ[e->p] = e->q;
            pred[e->q] = e->p;
            cdir[e->p] = e->dp;
            cdir[e->q] = e->dq;
        }
    }
    free(pg);
    free(parent);
    free(qs);
    return ok;
}

/* ---- order refinement ---------------------------------------------------- */

/* The greedy orders look one strip ahead. Or-opt then moves single strips:
 * each strip is tried at every place next to a strip it shares a vertex
 * with, up to about REFINE_SPAN indices away, in each allowed direction, and the
 * best move that saves misses is made. A move is judged by replaying the
 * cache over the strips between the two places and REFINE_TAIL after, from
 * the cache contents kept for every position; after it, the replay goes on
 * until the cache holds what it held before, so every figure stays exact
 * (and a move whose cost lay past the tail is taken back).
 * (bunny00: ACMR-32 0.814 -> 0.801; capped at 48, 0.770 -> 0.754; a strip
 * set's best order cannot go under what each strip saves after its best
 * neighbour alone, 0.780 here, so little more is to be had from the order.) */
enum { REFINE_SPAN = 4096, REFINE_TAIL = 3, REFINE_SWEEPS = 4, REFINE_MAX_CONTENTS = 1 << 25 };

typedef struct refine {
    const order_ctx *c;
    uint32_t *emit;   /* the order being refined */
    uint8_t *dir;     /* each one's direction */
    uint32_t *posof;  /* path -> position */
    uint32_t *snap;   /* (paths + 1) x size: cache contents before each position,
                       * oldest first; the last, at `paths`, is the replay's scratch */
    uint32_t *snap_n; /* how many of them */
    uint64_t *cm;     /* misses before each position (paths + 1) */
    uint32_t *seq;    /* a trial's strips: range + REFINE_TAIL + 2 */
    uint8_t *seq_dir;
    uint32_t range;   /* farthest move, in places */
} refine;

/* The cache's contents, oldest first: stamp s sits in slot (s - 1) % size
 * and still counts when the vertex there carries it. */
static uint32_t fifo_contents(const fifo *f, uint32_t *out)
{
    uint32_t k = 0;
    for (uint32_t j = 0; j < f->size; j++) {
        uint64_t s = f->misses - f->size + j + 1;
        uint32_t v = f->ring[(s - 1) % f->size];
        if (f->stamp[v] == s)
            out[k++] = v;
    }
    return k;
}

static void fifo_restore(fifo *f, const uint32_t *v, uint32_t k)
{
    fifo_clear(f);
    for (uint32_t i = 0; i < k; i++) {
        f->ring[f->misses % f->size] = v[i];
        f->stamp[v[i]] = ++f->misses;
    }
}

static void refine_feed(const refine *r, uint32_t p, int d)
{
    const enc *e = &r->c->encs[p];
    fifo_feed(r->c->f, r->c->buf + e->at[d], e->len[d]);
}

/* Replays from position lo: contents and misses of every later position,
 * until one past `settled` holds what it held before (then the misses after
 * it move by the same amount) or the end. */
static void refine_replay(refine *r, uint32_t lo, uint32_t settled)
{
    const order_ctx *c = r->c;
    fifo *f = c->f;
    uint32_t size = f->size, paths = c->paths;
    uint32_t *tmp = r->snap + (size_t)paths * size; /* position `paths` is never compared */
    fifo_restore(f, r->snap + (size_t)lo * size, r->snap_n[lo]);
    uint64_t base = f->misses, at = r->cm[lo];
    for (uint32_t x = lo; x < paths; x++) {
        uint64_t now = at + (f->misses - base);
        if (x > lo) {
            uint32_t k = fifo_contents(f, tmp);
            if (x > settled && k == r->snap_n[x] &&
                memcmp(tmp, r->snap + (size_t)x * size, k * sizeof *tmp) == 0) {
                uint64_t old = r->cm[x];
                for (uint32_t y = x; y <= paths; y++)
                    r->cm[y] = r->cm[y] - old + now;
                return;
            }
            memcpy(r->snap + (size_t)x * size, tmp, k * sizeof *tmp);
            r->snap_n[x] = k;
        }
        r->cm[x] = now;
        refine_feed(r, r->emit[x], r->dir[x]);
        r->posof[r->emit[x]] = x;
    }
    r->cm[paths] = at + (f->misses - base);
}

/* The misses of the strips from lo to end (exclusive, old positions) with p
 * taken from position i and put before position j, read in direction d. */
static int64_t refine_trial(refine *r, uint32_t i, uint32_t j, int d, uint32_t *lo_out,
                            uint32_t *end_out)
{
    const order_ctx *c = r->c;
    uint32_t paths = c->paths, p = r->emit[i], lo, end, n = 0;
    if (j > i) {
        lo = i;
        end = j + REFINE_TAIL < paths ? j + REFINE_TAIL : paths;
        for (uint32_t x = i + 1; x < end; x++) {
            if (x == j) {
                r->seq[n] = p;
                r->seq_dir[n++] = (uint8_t)d;
            }
            r->seq[n] = r->emit[x];
            r->seq_dir[n++] = r->dir[x];
        }
        if (j >= end) {
            r->seq[n] = p;
            r->seq_dir[n++] = (uint8_t)d;
        }
    } else {
        lo = j;
        end = i + 1 + REFINE_TAIL < paths ? i + 1 + REFINE_TAIL : paths;
        r->seq[n] = p;
        r->seq_dir[n++] = (uint8_t)d;
        for (uint32_t x = j; x < end; x++) {
            if (x != i) {
                r->seq[n] = r->emit[x];
                r->seq_dir[n++] = r->dir[x];
            }
        }
    }
    fifo *f = c->f;
    fifo_restore(f, r->snap + (size_t)lo * f->size, r->snap_n[lo]);
    uint64_t m0 = f->misses;
    for (uint32_t k = 0; k < n; k++)
        refine_feed(r, r->seq[k], r->seq_dir[k]);
    *lo_out = lo;
    *end_out = end;
    return (int64_t)(f->misses - m0) - (int64_t)(r->cm[end] - r->cm[lo]);
}

static void refine_move(refine *r, uint32_t i, uint32_t j, int d)
{
    uint32_t p = r->emit[i];
    if (j > i) {
        memmove(r->emit + i, r->emit + i + 1, (size_t)(j - i - 1) * sizeof *r->emit);
        memmove(r->dir + i, r->dir + i + 1, (size_t)(j - i - 1));
        r->emit[j - 1] = p;
        r->dir[j - 1] = (uint8_t)d;
    } else {
        memmove(r->emit + j + 1, r->emit + j, (size_t)(i - j) * sizeof *r->emit);
        memmove(r->dir + j + 1, r->dir + j, (size_t)(i - j));
        r->emit[j] = p;
        r->dir[j] = (uint8_t)d;
    }
}

/* Refines emit/emit_dir in place and returns the misses of the result,
 * never more than `misses`, those of the order it was given. Out of memory
 * it leaves the order as it was: the refinement is a bonus. */
static uint64_t order_refine(const order_ctx *c, uint32_t *emit, uint8_t *emit_dir,
                             uint64_t misses)
{
    uint32_t paths = c->paths, size = c->f->size;
    refine r = {c, NULL, NULL, NULL, NULL, NULL, NULL, NULL, NULL, 0};
    uint64_t result = misses;
    /* the contents kept per position: past 2^25 entries (a cache far larger
     * than a GPU's, or over a million strips at 32) the greedy order stays
     * rather than ask for gigabytes */
    if (((uint64_t)paths + 1) * size > REFINE_MAX_CONTENTS)
        return misses;
    /* a move is judged by replaying what lies between: bound that work by
     * indices, not places (a 1.2 M-triangle mesh has strips twice as long) */
    uint64_t total = 0;
    for (uint32_t p = 0; p < paths; p++)
        total += c->encs[p].len[0];
    uint64_t avg = paths ? total / paths + 1 : 1;
    r.range = REFINE_SPAN / avg < 8 ? 8 : REFINE_SPAN / avg > 256 ? 256 : (uint32_t)(REFINE_SPAN / avg);
    r.emit = malloc(((size_t)paths + 1) * sizeof *r.emit);
    r.dir = malloc((size_t)paths + 1);
    r.posof = malloc(((size_t)paths + 1) * sizeof *r.posof);
    r.snap = malloc(((size_t)paths + 1) * size * sizeof *r.snap);
    r.snap_n = malloc(((size_t)paths + 1) * sizeof *r.snap_n);
    r.cm = malloc(((size_t)paths + 1) * sizeof *r.cm);
    r.seq = malloc(((size_t)r.range + REFINE_TAIL + 2) * sizeof *r.seq);
    r.seq_dir = malloc((size_t)r.range + REFINE_TAIL + 2);
    if (!r.emit || !r.dir || !r.posof || !r.snap || !r.snap_n || !r.cm || !r.seq || !r.seq_dir)
        goto done;
    memcpy(r.emit, emit, (size_t)paths * sizeof *emit);
    memcpy(r.dir, emit_dir, (size_t)paths);
    fifo_clear(c->f);
    r.snap_n[0] = 0;
    r.cm[0] = 0;
    refine_replay(&r, 0, paths);
    for (uint32_t p = 0; p < paths; p++)
        c->cand[p] = NONE;
    uint32_t stamp = 0;
    for (int sweep = 0; sweep < REFINE_SWEEPS; sweep++) {
        uint32_t moved = 0;
        for (uint32_t i = 0; i < paths; i++) {
            uint32_t p = r.emit[i], best_j = NONE;
            int best_d = 0;
            int64_t best = 0;
            const enc *e = &c->encs[p];
            const uint32_t *s = c->buf + e->at[0];
            stamp++;
            if (e->dirs == 3) { /* read the other way, where it is */
                uint32_t lo, end;
                int64_t delta = refine_trial(&r, i, i, !r.dir[i], &lo, &end);
                if (delta < best) {
                    best = delta;
                    best_j = i;
                    best_d = !r.dir[i];
                }
            }
            for (uint32_t k = 0; k < e->len[0]; k++) {
                uint32_t v = s[k];
                for (uint32_t a = c->vstart[v]; a < c->vstart[v + 1]; a++) {
                    uint32_t q = c->vpaths[a];
                    if (q == p || c->cand[q] == stamp)
                        continue;
                    c->cand[q] = stamp;
                    uint32_t pq = r.posof[q];
                    for (uint32_t j = pq; j <= pq + 1; j++) {
                        if (j == i || j == i + 1 || (j > i ? j - i : i - j) > r.range)
                            continue;
                        for (int d = 0; d < 2; d++) {
                            if (!(e->dirs >> d & 1))
                                continue;
                            uint32_t lo, end;
                            int64_t delta = refine_trial(&r, i, j, d, &lo, &end);
                            if (delta < best) {
                                best = delta;
                                best_j = j;
                                best_d = d;
                            }
                        }
                    }
                }
            }
            if (best_j == NONE)
                continue;
            /* the trial saw REFINE_TAIL strips past the move; the replay
             * sees them all: a move that costs more there is taken back */
            uint64_t before = r.cm[paths];
            int old_d = r.dir[i];
            uint32_t lo = i < best_j ? i : best_j, hi = i > best_j ? i : best_j;
            refine_move(&r, i, best_j, best_d);
            refine_replay(&r, lo, hi);
            if (r.cm[paths] >= before) {
                uint32_t at = best_j > i ? best_j - 1 : best_j;
                refine_move(&r, at, best_j > i ? i : i + 1, old_d);
                refine_replay(&r, lo, hi);
                continue;
            }
            moved++;
        }
        if (!moved)
            break;
    }
    if (r.cm[paths] < misses) {
        result = r.cm[paths];
        memcpy(emit, r.emit, (size_t)paths * sizeof *emit);
        memcpy(emit_dir, r.dir, (size_t)paths);
    }
done:
    free(r.emit);
    free(r.dir);
    free(r.posof);
    free(r.snap);
    free(r.snap_n);
    free(r.cm);
    free(r.seq);
    free(r.seq_dir);
    return result;
}

int mts__order_paths(mts__order_path *encs, uint32_t paths, const uint32_t *buf,
                     uint32_t vertex_count, uint32_t csize, uint32_t max_path, uint32_t *emit,
                     uint8_t *emit_dir, uint64_t *misses_out)
{
    *misses_out = 0;
    if (csize <= 1) { /* the input's order, each path its allowed way */
        for (uint32_t p = 0; p < paths; p++) {
            emit[p] = p;
            emit_dir[p] = encs[p].dirs & 1 ? 0 : 1;
        }
        return 1;
    }
    int ok = 0;
    uint32_t *vstart = NULL, *vpaths = NULL, *vlast = NULL, *cand = NULL, *savev = NULL;
    uint32_t *succ = NULL, *pred = NULL, *emit2 = NULL;
    uint8_t *used = NULL, *cdir = NULL, *emit_dir2 = NULL;
    uint64_t *save = NULL;
    fifo f = {0};
    used = calloc((size_t)paths + 1, 1);
    if (!used)
        goto done;
    /* vertex -> paths that use it */
    vstart = calloc((size_t)vertex_count + 1, sizeof *vstart);
    vlast = malloc((size_t)vertex_count * sizeof *vlast + 1);
    f.size = csize;
    f.stamp = calloc((size_t)vertex_count + 1, sizeof *f.stamp);
    f.ring = calloc(csize, sizeof *f.ring);
    cand = malloc((size_t)paths * sizeof *cand + 1);
    save = malloc(((size_t)max_path * 2 + 3) * sizeof *save);
    savev = malloc(((size_t)max_path * 2 + 3) * sizeof *savev);
    if (!vstart || !vlast || !f.stamp || !f.ring || !cand || !save || !savev)
        goto done;
    /* the paths through each vertex (CSR): counted, then filled */
    for (int fill = 0; fill < 2; fill++) {
        if (fill) {
            for (uint32_t v = 0; v < vertex_count; v++)
                vstart[v + 1] += vstart[v];
            vpaths = malloc((size_t)vstart[vertex_count] * sizeof *vpaths + 1);
            if (!vpaths)
                goto done;
        }
        for (uint32_t v = 0; v < vertex_count; v++)
            vlast[v] = NONE;
        for (uint32_t p = 0; p < paths; p++) {
            const uint32_t *s = buf + encs[p].at[0];
            for (uint32_t k = 0; k < encs[p].len[0]; k++) {
                if (vlast[s[k]] == p)
                    continue;
                vlast[s[k]] = p;
                if (fill)
                    vpaths[vstart[s[k]]++] = p;
                else
                    vstart[s[k] + 1]++;
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
    /* Two orders, the greedy one and the greedy one over chains; the
     * one with fewer misses is kept (the chains lose where the strips
     * are short: bunny00 capped at 32, 0.737 against 0.745). */
    order_ctx oc = {paths, encs, buf, vstart, vpaths, &f, save, savev, used, cand};
    uint64_t misses = order_greedy(&oc, NULL, NULL, NULL, emit, emit_dir);
    succ = malloc(((size_t)paths + 1) * sizeof *succ);
    pred = malloc(((size_t)paths + 1) * sizeof *pred);
    cdir = malloc((size_t)paths + 1);
    emit2 = malloc(((size_t)paths + 1) * sizeof *emit2);
    emit_dir2 = malloc((size_t)paths + 1);
    if (!succ || !pred || !cdir || !emit2 || !emit_dir2 || !chain_links(&oc, succ, pred, cdir))
        goto done;
    uint64_t chained = order_greedy(&oc, succ, pred, cdir, emit2, emit_dir2);
    if (chained < misses) {
        memcpy(emit, emit2, (size_t)paths * sizeof *emit);
        memcpy(emit_dir, emit_dir2, (size_t)paths);
        misses = chained;
    }
    *misses_out = order_refine(&oc, emit, emit_dir, misses);
    ok = 1;
done:
    free(used);
    free(vstart);
    free(vpaths);
    free(vlast);
    free(cand);
    free(save);
    free(savev);
    free(succ);
    free(pred);
    free(cdir);
    free(emit2);
    free(emit_dir2);
    free(f.stamp);
    free(f.ring);
    return ok;
}
