/* Strip growth from vertex splits (see grow.h for the why, lodbuild.h for
 * the growth rules and the measurements behind key levels).
 *
 * State: the live triangles of the current level (ids in birth order; going
 * up, no triangle ever dies), a map from directed edges to the triangle
 * holding them, and the strips as paths on the dual graph, one per slot,
 * with each slot's indices as last derived. A split moves the fan of the
 * parent that the new vertex takes over, adds its new triangles, mends the
 * strip links the move broke, places the new triangles into strips, and
 * emits, per slot it touched, the smallest edit from the old indices to the
 * newly derived ones. A key level instead restripifies all live triangles
 * (the greedy stripifier, deterministic for the same triangle order). */
#include "grow.h"

#include <stdlib.h>
#include <string.h>

#include "stripify.h"
#include "words.h"


/* Directed edge (a, b) -> the triangle that holds it: linear probing that
 * doubles when half full. Deleting shifts the entries after a hole back
 * into it (Knuth's algorithm R) instead of leaving a tombstone: a split
 * deletes and inserts a dozen edges, and tombstones made the table rehash
 * itself every few thousand splits, 15% of a client's derivation time. */
typedef struct edge_map {
    uint64_t *key;
    int32_t *tri;
    uint32_t mask, live;
} edge_map;

#define EDGE_EMPTY UINT64_MAX

static uint32_t edge_hash(uint64_t k)
{
    k ^= k >> 33;
    k *= 0xff51afd7ed558ccdULL;
    k ^= k >> 33;
    return (uint32_t)k;
}

static int edge_map_alloc(edge_map *m, size_t entries)
{
    size_t cap = 64;
    while (cap < entries * 2)
        cap *= 2;
    if (cap > (size_t)1 << 31)
        return 0;
    m->key = malloc(cap * sizeof *m->key);
    m->tri = malloc(cap * sizeof *m->tri);
    if (!m->key || !m->tri) {
        free(m->key);
        free(m->tri);
        m->key = NULL;
        m->tri = NULL;
        return 0;
    }
    for (size_t i = 0; i < cap; i++)
        m->key[i] = EDGE_EMPTY;
    m->mask = (uint32_t)(cap - 1);
    m->live = 0;
    return 1;
}

static void edge_map_insert_new(edge_map *m, uint64_t k, int32_t t)
{
    uint32_t i = edge_hash(k) & m->mask;
    while (m->key[i] != EDGE_EMPTY)
        i = (i + 1) & m->mask;
    m->key[i] = k;
    m->tri[i] = t;
    m->live++;
}

/* Makes room for one more entry: doubles once half full. */
static int edge_map_room(edge_map *m)
{
    if ((size_t)(m->live + 1) * 2 <= (size_t)m->mask + 1)
        return 1;
    edge_map old = *m;
    if (!edge_map_alloc(m, (size_t)old.mask + 1)) {
        *m = old;
        return 0;
    }
    for (size_t i = 0; i <= old.mask; i++) {
        if (old.key[i] != EDGE_EMPTY)
            edge_map_insert_new(m, old.key[i], old.tri[i]);
    }
    free(old.key);
    free(old.tri);
    return 1;
}

static int edge_map_put(edge_map *m, uint32_t a, uint32_t b, int32_t t)
{
    if (!edge_map_room(m))
        return 0;
    uint64_t k = (uint64_t)a << 32 | b;
    uint32_t i = edge_hash(k) & m->mask;
    while (m->key[i] != EDGE_EMPTY) {
        if (m->key[i] == k) {
            m->tri[i] = t;
            return 1;
        }
        i = (i + 1) & m->mask;
    }
    m->key[i] = k;
    m->tri[i] = t;
    m->live++;
    return 1;
}

static int32_t edge_map_get(const edge_map *m, uint32_t a, uint32_t b)
{
    uint64_t k = (uint64_t)a << 32 | b;
    for (uint32_t i = edge_hash(k) & m->mask; m->key[i] != EDGE_EMPTY; i = (i + 1) & m->mask) {
        if (m->key[i] == k)
            return m->tri[i];
    }
    return -1;
}

/* Removes (a, b) only if t holds it: on a mesh that is not quite manifold
 * another triangle may have taken the edge over. */
static void edge_map_del(edge_map *m, uint32_t a, uint32_t b, int32_t t)
{
    uint64_t k = (uint64_t)a << 32 | b;
    uint32_t i = edge_hash(k) & m->mask;
    while (m->key[i] != k) {
        if (m->key[i] == EDGE_EMPTY)
            return;
        i = (i + 1) & m->mask;
    }
    if (m->tri[i] != t)
        return;
    /* close the hole: an entry further on moves into it unless its home
     * slot lies cyclically in (hole, entry], where a lookup still finds it */
    for (uint32_t j = (i + 1) & m->mask; m->key[j] != EDGE_EMPTY; j = (j + 1) & m->mask) {
        uint32_t home = edge_hash(m->key[j]) & m->mask;
        if (((j - home) & m->mask) >= ((j - i) & m->mask)) {
            m->key[i] = m->key[j];
            m->tri[i] = m->tri[j];
            i = j;
        }
    }
    m->key[i] = EDGE_EMPTY;
    m->live--;
}

struct mts_grow {
    uint32_t nb, n, level;
    /* triangles, all live */
    uint32_t tri_count, tri_cap;
    uint32_t (*img)[3];
    int32_t *next, *prev; /* strip paths on the dual graph */
    int32_t *tslot;       /* slot of each triangle's strip, -1 while unplaced */
    edge_map edges;
    int32_t *vtri; /* per vertex: a live triangle with that corner, or -1 */
    /* slots */
    uint32_t slot_count, slot_cap;
    mts_words *seq;    /* indices of each slot as last derived */
    int32_t *head; /* first triangle of each slot's path, -1 when empty */
    uint32_t *ntri;
    uint32_t *capacity;
    uint32_t *free_slots, free_count;
    uint32_t *stamp, stamp_now, *touched, touched_count;
    uint64_t total_indices;
    uint32_t nonempty;
    /* keys */
    const uint32_t *key_given;
    uint32_t key_given_count, key_given_at;
    double key_ratio, next_key;
    mts_words keys;
    /* the last record, and scratch */
    mts_words rec, scratch;
    mts_words affected;
    mts_words ring; /* scratch of the fan codes */
    uint32_t newest_born; /* the first triangle the last split brought back */
    mts_words around;     /* scratch of mts_grow_around_newest */
    mts_grow_figures fig;
};

static void tri_edges_del(mts_grow *g, uint32_t t)
{
    for (int c = 0; c < 3; c++)
        edge_map_del(&g->edges, g->img[t][c], g->img[t][(c + 1) % 3], (int32_t)t);
}

static int tri_edges_put(mts_grow *g, uint32_t t)
{
    for (int c = 0; c < 3; c++) {
        if (!edge_map_put(&g->edges, g->img[t][c], g->img[t][(c + 1) % 3], (int32_t)t))
            return 0;
    }
    return 1;
}

/* The edge x->y of triangle a whose reverse is in triangle b. */
static int shared_edge(const mts_grow *g, uint32_t ta, uint32_t tb, uint32_t *x, uint32_t *y)
{
    for (int c = 0; c < 3; c++) {
        uint32_t p = g->img[ta][c], q = g->img[ta][(c + 1) % 3];
        for (int d = 0; d < 3; d++) {
            if (g->img[tb][d] == q && g->img[tb][(d + 1) % 3] == p) {
                *x = p;
                *y = q;
                return 1;
            }
        }
    }
    return 0;
}

static int adjacent(const mts_grow *g, int32_t ta, int32_t tb)
{
    uint32_t x, y;
    return ta >= 0 && tb >= 0 && shared_edge(g, (uint32_t)ta, (uint32_t)tb, &x, &y);
}

static uint32_t third_vertex(const mts_grow *g, uint32_t t, uint32_t x, uint32_t y)
{
    for (int c = 0; c < 3; c++) {
        if (g->img[t][c] != x && g->img[t][c] != y)
            return g->img[t][c];
    }
    return g->img[t][0];
}

/* The indices of a path (lodbuild.h): the first triangle's third vertex and
 * the edge it shares with the second, then one index per triangle, plus a
 * swap where the path turns the same way twice. Links are always between
 * adjacent triangles (growth mends the ones a split breaks). */
static int derive_indices(const mts_grow *g, int32_t head, mts_words *out)
{
    out->n = 0;
    if (head < 0)
        return 1;
    uint32_t t = (uint32_t)head;
    if (!mts_words_reserve(out, 3))
        return 0;
    if (g->next[t] < 0) {
        memcpy(out->w, g->img[t], 12);
        out->n = 3;
        return 1;
    }
    uint32_t x = g->img[t][0], y = g->img[t][1];
    shared_edge(g, t, (uint32_t)g->next[t], &x, &y);
    out->w[0] = third_vertex(g, t, x, y);
    out->w[1] = x;
    out->w[2] = y;
    out->n = 3;
    uint32_t a = x, c = y; /* the last two indices, the edge into the next */
    for (int32_t s = g->next[t]; s >= 0; s = g->next[s]) {
        uint32_t w = third_vertex(g, (uint32_t)s, a, c);
        if (!mts_words_reserve(out, 2))
            return 0;
        if (g->next[s] >= 0) {
            uint32_t p = a, q = c;
            shared_edge(g, (uint32_t)s, (uint32_t)g->next[s], &p, &q);
            if (p != c && q != c) {
                /* the path turns the same way again: a swap keeps a */
                out->w[out->n++] = a;
                out->w[out->n++] = w;
                c = w;
                continue;
            }
        }
        out->w[out->n++] = w;
        a = c;
        c = w;
    }
    return 1;
}

static void touch(mts_grow *g, int32_t slot)
{
    if (slot < 0)
        return;
    if (g->stamp[slot] != g->stamp_now) {
        g->stamp[slot] = g->stamp_now;
        g->touched[g->touched_count++] = (uint32_t)slot;
    }
}

/* Grows an array from old to cap elements of size elem, the new ones zero. */
static int grow_zeroed(void **p, size_t elem, uint32_t old, uint32_t cap)
{
    void *q = realloc(*p, (size_t)cap * elem);
    if (!q)
        return 0;
    memset((char *)q + (size_t)old * elem, 0, (size_t)(cap - old) * elem);
    *p = q;
    return 1;
}

static int32_t slot_new(mts_grow *g)
{
    if (g->free_count)
        return (int32_t)g->free_slots[--g->free_count];
    if (g->slot_count == g->slot_cap) {
        uint32_t old = g->slot_cap, cap = old ? old * 2 : 64;
        /* each array keeps its old block if its own growth fails */
        if (!grow_zeroed((void **)&g->seq, sizeof *g->seq, old, cap) ||
            !grow_zeroed((void **)&g->head, sizeof *g->head, old, cap) ||
            !grow_zeroed((void **)&g->ntri, 4, old, cap) ||
            !grow_zeroed((void **)&g->capacity, 4, old, cap) ||
            !grow_zeroed((void **)&g->free_slots, 4, old, cap) ||
            !grow_zeroed((void **)&g->stamp, 4, old, cap) ||
            !grow_zeroed((void **)&g->touched, 4, old, cap))
            return -1;
        g->slot_cap = cap;
    }
    int32_t s = (int32_t)g->slot_count++;
    g->head[s] = -1;
    g->ntri[s] = 0;
    return s;
}

static void slot_release(mts_grow *g, int32_t s)
{
    g->head[s] = -1;
    g->ntri[s] = 0;
    g->free_slots[g->free_count++] = (uint32_t)s;
}

/* Gives the path starting at t (and everything after it) the slot s. */
static uint32_t path_claim(mts_grow *g, int32_t t, int32_t s)
{
    uint32_t count = 0;
    for (; t >= 0; t = g->next[t]) {
        g->tslot[t] = s;
        count++;
    }
    return count;
}

/* Longest path growth may make by appending or joining; insertion into the
 * middle is never refused (the alternative is cutting the strip). */
#define GROW_MAX_PATH (2 * MTS_STRIPIFY_MAX_STRIP)

/* Mends one link a -> c that the split broke: a new triangle adjacent to
 * both goes between them (the strip crossed the edge it was born on), else
 * the path is cut and its tail gets a slot of its own. */
static int mend_link(mts_grow *g, int32_t a, int32_t c, uint32_t first_new)
{
    for (uint32_t f = first_new; f < g->tri_count; f++) {
        if (g->tslot[f] >= 0 || !adjacent(g, a, (int32_t)f) || !adjacent(g, (int32_t)f, c))
            continue;
        int32_t s = g->tslot[a];
        g->next[a] = (int32_t)f;
        g->prev[f] = a;
        g->next[f] = c;
        g->prev[c] = (int32_t)f;
        g->tslot[f] = s;
        g->ntri[s]++;
        g->fig.grown_inserted++;
        return 1;
    }
    int32_t s = g->tslot[a];
    int32_t ns = slot_new(g);
    if (ns < 0)
        return 0;
    g->next[a] = -1;
    g->prev[c] = -1;
    g->head[ns] = c;
    g->ntri[ns] = path_claim(g, c, ns);
    g->ntri[s] -= g->ntri[ns];
    touch(g, ns);
    g->fig.strips_cut++;
    return 1;
}

/* Places a new triangle no strip crossed into: after a strip that ends next
 * to it, before one that starts next to it, both (joining them), or alone. */
static int place_newborn(mts_grow *g, int32_t f)
{
    int32_t nbr[3];
    for (int c = 0; c < 3; c++) {
        int32_t h = edge_map_get(&g->edges, g->img[f][(c + 1) % 3], g->img[f][c]);
        nbr[c] = (h >= 0 && h != f && g->tslot[h] >= 0) ? h : -1;
    }
    int32_t tail = -1, head = -1;
    for (int c = 0; c < 3 && tail < 0; c++) {
        int32_t h = nbr[c];
        if (h >= 0 && g->next[h] < 0 && g->ntri[g->tslot[h]] < GROW_MAX_PATH)
            tail = h;
    }
    for (int c = 0; c < 3 && head < 0; c++) {
        int32_t h = nbr[c];
        if (h < 0 || h == tail || g->prev[h] >= 0 || g->ntri[g->tslot[h]] >= GROW_MAX_PATH)
            continue;
        if (tail >= 0 && (g->tslot[h] == g->tslot[tail] ||
                          g->ntri[g->tslot[h]] + g->ntri[g->tslot[tail]] >= GROW_MAX_PATH))
            continue; /* would close a loop, or make too long a strip */
        head = h;
    }
    if (tail >= 0 && head >= 0) {
        int32_t s = g->tslot[tail], gone = g->tslot[head];
        g->next[tail] = f;
        g->prev[f] = tail;
        g->next[f] = head;
        g->prev[head] = f;
        g->tslot[f] = s;
        g->ntri[s] += 1 + path_claim(g, head, s);
        touch(g, gone);
        slot_release(g, gone);
        g->fig.grown_joined++;
    } else if (tail >= 0) {
        int32_t s = g->tslot[tail];
        g->next[tail] = f;
        g->prev[f] = tail;
        g->tslot[f] = s;
        g->ntri[s]++;
        g->fig.grown_appended++;
    } else if (head >= 0) {
        int32_t s = g->tslot[head];
        g->next[f] = head;
        g->prev[head] = f;
        g->tslot[f] = s;
        g->head[s] = f;
        g->ntri[s]++;
        g->fig.grown_appended++;
    } else {
        int32_t s = slot_new(g);
        if (s < 0)
            return 0;
        g->head[s] = f;
        g->ntri[s] = 1;
        g->tslot[f] = s;
        g->fig.grown_alone++;
    }
    touch(g, g->tslot[f]);
    return 1;
}

/* Turns strips over live triangles into paths. Lenient (a key level's
 * fresh strips): paths go into slots 0.. in order, a strip whose windows do
 * not chain is split over several slots, and every other slot is left empty
 * and free. Strict (a client's base and full level): slot s gets strip s,
 * which must be one path. Every slot is touched. */
static mts_result adopt_strips(mts_grow *g, const mts_strips *strips, int strict, mts_error *err)
{
    while (g->slot_count < strips->strip_count) {
        if (slot_new(g) < 0)
            return mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
    }
    for (uint32_t s = 0; s < g->slot_count; s++) {
        g->head[s] = -1;
        g->ntri[s] = 0;
        touch(g, (int32_t)s);
    }
    for (uint32_t t = 0; t < g->tri_count; t++) {
        g->next[t] = g->prev[t] = -1;
        g->tslot[t] = -1;
    }
    g->free_count = 0;
    uint32_t used = 0;
    for (uint32_t k = 0; k < strips->strip_count; k++) {
        const uint32_t *str = strips->indices + strips->offsets[k];
        uint32_t len = strips->offsets[k + 1] - strips->offsets[k];
        int32_t prev = -1, s = strict ? (int32_t)k : -1;
        for (uint32_t w = 0; w + 2 < len; w++) {
            uint32_t tri[3];
            if (!mts_strip_window(str, w, tri))
                continue;
            int32_t t = edge_map_get(&g->edges, tri[0], tri[1]);
            if (t < 0 || third_vertex(g, (uint32_t)t, tri[0], tri[1]) != tri[2])
                return mts_error_set(err, MTS_ERR_FORMAT,
                                     "grow: strip %u draws (%u %u %u), not a triangle of level %u",
                                     k, tri[0], tri[1], tri[2], g->level);
            if (g->tslot[t] >= 0)
                return mts_error_set(err, MTS_ERR_FORMAT,
                                     "grow: strip %u draws triangle (%u %u %u) a second time", k,
                                     tri[0], tri[1], tri[2]);
            if (prev >= 0 && adjacent(g, prev, t)) {
                g->next[prev] = t;
                g->prev[t] = prev;
            } else if (prev >= 0 && strict) {
                return mts_error_set(err, MTS_ERR_FORMAT,
                                     "grow: strip %u breaks at window %u (not one path)", k, w);
            } else {
                if (!strict) {
                    if (used == g->slot_count && slot_new(g) < 0)
                        return mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
                    s = (int32_t)used++;
                }
                g->head[s] = t;
                touch(g, s);
            }
            g->tslot[t] = s;
            g->ntri[s]++;
            prev = t;
        }
    }
    if (strict)
        used = strips->strip_count;
    for (uint32_t s = g->slot_count; s-- > 0;) {
        if (s >= used || g->head[s] < 0)
            g->free_slots[g->free_count++] = s;
    }
    return MTS_OK;
}

/* Sorts ids by key[id], largest first, ties by position (a stable merge
 * sort: deterministic, and insertion sort is too slow for 10^4 slots). */
static int sort_desc(uint32_t *ids, uint32_t n, const uint32_t *key)
{
    uint32_t *tmp = malloc(((size_t)n + 1) * 4);
    if (!tmp)
        return 0;
    for (uint32_t width = 1; width < n; width *= 2) {
        for (uint32_t lo = 0; lo < n; lo += 2 * width) {
            uint32_t mid = lo + width < n ? lo + width : n;
            uint32_t hi = lo + 2 * width < n ? lo + 2 * width : n;
            uint32_t i = lo, j = mid, o = lo;
            while (i < mid && j < hi)
                tmp[o++] = key[ids[i]] >= key[ids[j]] ? ids[i++] : ids[j++];
            while (i < mid)
                tmp[o++] = ids[i++];
            while (j < hi)
                tmp[o++] = ids[j++];
        }
        memcpy(ids, tmp, (size_t)n * 4);
    }
    free(tmp);
    return 1;
}

/* A runtime reserves each slot's longest length over all levels, so the
 * strips of a key level go into the slots by length, longest into the
 * roomiest: otherwise every slot soon holds a long strip at some key and
 * the room reserved grows to several times what any one level draws. */
static int fit_slots(mts_grow *g)
{
    uint32_t n = g->slot_count;
    uint32_t *paths = malloc(((size_t)n + 1) * 4), *slots = malloc(((size_t)n + 1) * 4);
    int32_t *head = malloc(((size_t)n + 1) * sizeof *head);
    uint32_t *ntri = malloc(((size_t)n + 1) * 4);
    int ok = paths && slots && head && ntri;
    if (ok) {
        for (uint32_t s = 0; s < n; s++) {
            paths[s] = s;
            slots[s] = s;
            head[s] = g->head[s];
            ntri[s] = g->ntri[s];
        }
        ok = sort_desc(paths, n, g->ntri) && sort_desc(slots, n, g->capacity);
    }
    if (ok) {
        for (uint32_t k = 0; k < n; k++) {
            uint32_t s = slots[k];
            g->head[s] = head[paths[k]];
            g->ntri[s] = ntri[paths[k]];
            path_claim(g, g->head[s], (int32_t)s);
        }
        g->free_count = 0;
        for (uint32_t k = n; k-- > 0;) {
            if (g->head[k] < 0)
                g->free_slots[g->free_count++] = k;
        }
    }
    free(paths);
    free(slots);
    free(head);
    free(ntri);
    return ok;
}

/* Restripifies every live triangle, in id order, into the slots. */
static mts_result restrip(mts_grow *g, mts_error *err)
{
    mts_strips strips = {0};
    mts_result rc = mts_stripify(&g->img[0][0], g->tri_count, g->nb + g->level, &strips, NULL,
                                 err);
    if (rc == MTS_OK)
        rc = adopt_strips(g, &strips, 0, err);
    mts_strips_free(&strips);
    if (rc == MTS_OK && !fit_slots(g))
        rc = mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
    return rc;
}

/* Appends the edit that turns slot s's stored indices into `to` (in which
 * the new vertex v appears; u is its parent), and stores `to`. The runs
 * carry u where `to` has v, and the positions of v are substitutions, so an
 * inserted run never names a vertex that does not exist yet. */
static int emit_edit(mts_grow *g, uint32_t s, const mts_words *to, uint32_t u, uint32_t v,
                     uint32_t *edits)
{
    mts_words *from = &g->seq[s];
    const uint32_t *o = from->w, *nw = to->w;
    size_t lo = from->n, ln = to->n;
#define AS_BEFORE(x) ((x) == v ? u : (x))
    size_t p = 0;
    while (p < lo && p < ln && o[p] == AS_BEFORE(nw[p]))
        p++;
    size_t q = 0;
    while (q < lo - p && q < ln - p && o[lo - 1 - q] == AS_BEFORE(nw[ln - 1 - q]))
        q++;
    size_t erase = lo - p - q, insert = ln - p - q, substs = 0;
    for (size_t k = 0; k < ln; k++)
        substs += nw[k] == v;
    if (erase == 0 && insert == 0 && substs == 0)
        return 1;
    if (!mts_words_reserve(&g->rec, 4 + 2 + erase + 2 + insert + substs))
        return 0;
    uint32_t *w = g->rec.w + g->rec.n;
    *w++ = s;
    *w++ = erase > 0;
    *w++ = insert > 0;
    *w++ = (uint32_t)substs;
    if (erase) {
        *w++ = (uint32_t)p;
        *w++ = (uint32_t)erase;
        memcpy(w, o + p, erase * 4);
        w += erase;
    }
    if (insert) {
        *w++ = (uint32_t)p;
        *w++ = (uint32_t)insert;
        for (size_t k = 0; k < insert; k++)
            *w++ = AS_BEFORE(nw[p + k]);
    }
    for (size_t k = 0; k < ln; k++) {
        if (nw[k] == v)
            *w++ = (uint32_t)k;
    }
#undef AS_BEFORE
    g->rec.n = (size_t)(w - g->rec.w);
    (*edits)++;
    g->fig.edits++;
    g->fig.erased_indices += erase;
    g->fig.inserted_indices += insert;
    g->fig.substitutions += substs;
    g->total_indices = g->total_indices - lo + ln;
    g->nonempty = g->nonempty - (lo > 0) + (ln > 0);
    from->n = 0;
    if (!mts_words_reserve(from, ln))
        return 0;
    if (ln) /* an emptied slot's new indices may have no buffer at all */
        memcpy(from->w, nw, ln * 4);
    from->n = ln;
    if (ln > g->capacity[s])
        g->capacity[s] = (uint32_t)ln;
    return 1;
}

static int cmp_u32(const void *a, const void *c)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)c;
    return x < y ? -1 : x > y;
}

/* The record of the split to level g->level: one edit per touched slot, in
 * slot order. */
static int emit_record(mts_grow *g, uint32_t u, uint32_t v)
{
    g->rec.n = 0;
    if (!mts_words_reserve(&g->rec, 1))
        return 0;
    g->rec.n = 1;
    uint32_t edits = 0;
    qsort(g->touched, g->touched_count, 4, cmp_u32);
    for (uint32_t k = 0; k < g->touched_count; k++) {
        uint32_t s = g->touched[k];
        if (!derive_indices(g, g->head[s], &g->scratch) ||
            !emit_edit(g, s, &g->scratch, u, v, &edits))
            return 0;
    }
    g->rec.w[0] = edits;
    g->touched_count = 0;
    g->stamp_now++;
    return 1;
}

/* ---- the full level's strips as swap bits ---- */

/* Reads a strip in derived form: its triangle count and, per inner
 * triangle, whether it swaps (one byte each, appended at swaps + *count).
 * Returns 0 when the strip is not in that form. */
static int parse_derived(const uint32_t *s, uint32_t len, uint32_t *ntri, uint8_t *swaps,
                         uint64_t *count_swaps)
{
    if (len == 0) {
        *ntri = 0;
        return 1;
    }
    if (len < 3 || s[0] == s[1] || s[1] == s[2] || s[0] == s[2])
        return 0;
    uint32_t a = s[1], c = s[2], k = 3, count = 1;
    while (k < len) {
        int swap = 0;
        if (s[k] == a && k + 1 < len) {
            swap = 1;
            k++;
        }
        uint32_t w = s[k++];
        if (w == a || w == c)
            return 0;
        count++;
        if (k < len) /* an inner triangle */
            swaps[(*count_swaps)++] = (uint8_t)swap;
        else if (swap)
            return 0; /* the last triangle never swaps */
        if (swap) {
            c = w;
        } else {
            a = c;
            c = w;
        }
    }
    *ntri = count;
    return 1;
}

mts_result mts_grow_full_describe(const mts_grow *g, const mts_strips *full,
                                  mts_grow_full_path *paths, uint8_t *swaps, uint64_t *swap_count,
                                  mts_error *err)
{
    *swap_count = 0;
    if (g->level != g->n)
        return mts_error_set(err, MTS_ERR_ARG,
                             "grow: the full strips described at level %u of %u", g->level, g->n);
    for (uint32_t st = 0; st < full->strip_count; st++) {
        const uint32_t *s = full->indices + full->offsets[st];
        uint32_t len = full->offsets[st + 1] - full->offsets[st];
        mts_grow_full_path *p = &paths[st];
        memset(p, 0, sizeof *p);
        if (!parse_derived(s, len, &p->triangles, swaps, swap_count))
            return mts_error_set(err, MTS_ERR_ARG,
                                 "grow: full strip %u is not in the form growth derives", st);
        if (!p->triangles)
            continue;
        int32_t t = mts_grow_find(g, s[0], s[1], s[2]);
        if (t < 0)
            return mts_error_set(err, MTS_ERR_ARG,
                                 "grow: full strip %u starts on (%u %u %u), not a triangle of "
                                 "level %u",
                                 st, s[0], s[1], s[2], g->level);
        p->first = (uint32_t)t;
        while (g->img[t][p->rotation] != s[0])
            p->rotation++;
    }
    return MTS_OK;
}

/* The triangle across the edge {a, c} from t, or -1. */
static int32_t across(const mts_grow *g, int32_t t, uint32_t a, uint32_t c)
{
    int32_t x = edge_map_get(&g->edges, a, c);
    if (x >= 0 && x != t)
        return x;
    x = edge_map_get(&g->edges, c, a);
    return x != t ? x : -1;
}

/* Resolves a description of the full strips (mts_grow_full_describe) on
 * the current (full) mesh into strips, slot by slot. */
static mts_result resolve_full(mts_grow *g, const mts_grow_full *f, mts_strips *out,
                               mts_error *err)
{
    uint64_t tris = 0, inner = 0;
    for (uint32_t s = 0; s < f->slot_count; s++) {
        const mts_grow_full_path *p = &f->paths[s];
        tris += p->triangles;
        inner += p->triangles >= 2 ? p->triangles - 2 : 0;
        if (p->triangles && (p->first >= g->tri_count || p->rotation > 2))
            return mts_error_set(err, MTS_ERR_FORMAT,
                                 "full strips: strip %u starts at corner %u of triangle %u (of "
                                 "%u)",
                                 s, p->rotation, p->first, g->tri_count);
    }
    if (tris > g->tri_count || inner != f->swap_count)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "full strips: %llu triangles of %u, %llu swap bits for %llu",
                             (unsigned long long)tris, g->tri_count,
                             (unsigned long long)f->swap_count, (unsigned long long)inner);
    /* each triangle costs at most 2 indices past the first 3 of a strip */
    mts_result rc = mts_strips_alloc(out, f->slot_count, (uint32_t)(2 * tris + 3ull * f->slot_count),
                                     err);
    if (rc != MTS_OK)
        return rc;
    uint64_t bit = 0;
    uint32_t o = 0;
    for (uint32_t s = 0; s < f->slot_count; s++) {
        const mts_grow_full_path *p = &f->paths[s];
        out->offsets[s] = o;
        if (!p->triangles)
            continue;
        int32_t t = (int32_t)p->first;
        const uint32_t *v = g->img[t];
        uint32_t r = p->rotation;
        out->indices[o++] = v[r];
        out->indices[o++] = v[(r + 1) % 3];
        out->indices[o++] = v[(r + 2) % 3];
        uint32_t a = v[(r + 1) % 3], c = v[(r + 2) % 3];
        for (uint32_t i = 1; i < p->triangles; i++) {
            t = across(g, t, a, c);
            if (t < 0)
                return mts_error_set(err, MTS_ERR_FORMAT,
                                     "full strips: strip %u runs off the mesh at triangle %u", s,
                                     i);
            uint32_t w = third_vertex(g, (uint32_t)t, a, c);
            int swap = i + 1 < p->triangles ? f->swaps[bit++] != 0 : 0;
            if (swap)
                out->indices[o++] = a;
            out->indices[o++] = w;
            if (swap) {
                c = w;
            } else {
                a = c;
                c = w;
            }
        }
    }
    out->offsets[f->slot_count] = o;
    out->index_count = o;
    return MTS_OK;
}

static int tri_reserve(mts_grow *g, uint32_t extra)
{
    if (g->tri_count + (uint64_t)extra <= g->tri_cap)
        return 1;
    if (g->tri_count + (uint64_t)extra > (uint32_t)INT32_MAX / 2)
        return 0;
    uint32_t cap = g->tri_cap ? g->tri_cap : 64;
    while (cap < g->tri_count + extra)
        cap *= 2;
    void *img = realloc(g->img, (size_t)cap * 12);
    if (!img)
        return 0;
    g->img = img;
    int32_t *nx = realloc(g->next, (size_t)cap * 4);
    if (!nx)
        return 0;
    g->next = nx;
    int32_t *pv = realloc(g->prev, (size_t)cap * 4);
    if (!pv)
        return 0;
    g->prev = pv;
    int32_t *ts = realloc(g->tslot, (size_t)cap * 4);
    if (!ts)
        return 0;
    g->tslot = ts;
    g->tri_cap = cap;
    return 1;
}

/* Adds a live triangle; 0 when out of memory. */
static int tri_add(mts_grow *g, uint32_t a, uint32_t b, uint32_t c)
{
    if (!tri_reserve(g, 1))
        return 0;
    uint32_t t = g->tri_count++;
    g->img[t][0] = a;
    g->img[t][1] = b;
    g->img[t][2] = c;
    g->next[t] = g->prev[t] = g->tslot[t] = -1;
    g->vtri[a] = g->vtri[b] = g->vtri[c] = (int32_t)t;
    return tri_edges_put(g, t);
}

void mts_grow_free(mts_grow *g)
{
    if (!g)
        return;
    free(g->img);
    free(g->next);
    free(g->prev);
    free(g->tslot);
    free(g->edges.key);
    free(g->edges.tri);
    free(g->vtri);
    if (g->seq) {
        for (uint32_t s = 0; s < g->slot_cap; s++)
            free(g->seq[s].w);
    }
    free(g->seq);
    free(g->head);
    free(g->ntri);
    free(g->capacity);
    free(g->free_slots);
    free(g->stamp);
    free(g->touched);
    free(g->keys.w);
    free(g->rec.w);
    free(g->scratch.w);
    free(g->affected.w);
    free(g->ring.w);
    free(g->around.w);
    free(g);
}

/* Derives every touched slot's indices into seq without a record (the base). */
static int settle(mts_grow *g)
{
    for (uint32_t k = 0; k < g->touched_count; k++) {
        uint32_t s = g->touched[k];
        g->total_indices -= g->seq[s].n;
        g->nonempty -= g->seq[s].n > 0;
        if (!derive_indices(g, g->head[s], &g->seq[s]))
            return 0;
        if (g->seq[s].n > g->capacity[s])
            g->capacity[s] = (uint32_t)g->seq[s].n;
        g->total_indices += g->seq[s].n;
        g->nonempty += g->seq[s].n > 0;
    }
    g->touched_count = 0;
    g->stamp_now++;
    return 1;
}

mts_result mts_grow_create(const mts_strips *base, uint32_t nb, uint32_t n,
                           const mts_grow_options *opts, mts_grow **out, mts_error *err)
{
    *out = NULL;
    if (n > UINT32_MAX - 1 - nb)
        return mts_error_set(err, MTS_ERR_LIMIT, "grow: %u + %u vertices is too many", nb, n);
    mts_grow *g = calloc(1, sizeof *g);
    if (!g)
        return mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
    g->nb = nb;
    g->n = n;
    g->stamp_now = 1;
    mts_result rc;
    if (opts && opts->key_levels) {
        for (uint32_t k = 0; k < opts->key_count; k++) {
            if (opts->key_levels[k] == 0 || opts->key_levels[k] >= n ||
                (k && opts->key_levels[k] <= opts->key_levels[k - 1])) {
                rc = mts_error_set(err, MTS_ERR_FORMAT,
                                   "grow: key level %u (%u of %u) is out of order or range",
                                   opts->key_levels[k], k, opts->key_count);
                goto fail;
            }
        }
        g->key_given = opts->key_levels;
        g->key_given_count = opts->key_count;
    } else {
        g->key_ratio = opts && opts->key_ratio > 1 ? opts->key_ratio : -1;
    }
    for (uint32_t i = 0; i < base->index_count; i++) {
        if (base->indices[i] >= nb) {
            rc = mts_error_set(err, MTS_ERR_FORMAT, "grow: base index %u is not a base vertex",
                               base->indices[i]);
            goto fail;
        }
    }
    uint32_t windows = base->index_count;
    g->vtri = malloc(((size_t)nb + n + 1) * sizeof *g->vtri);
    if (!g->vtri)
        goto nomem;
    for (size_t i = 0; i < (size_t)nb + n; i++)
        g->vtri[i] = -1;
    if (!edge_map_alloc(&g->edges, 3 * (size_t)windows + 64) || !tri_reserve(g, windows + 1))
        goto nomem;
    for (uint32_t k = 0; k < base->strip_count; k++) {
        const uint32_t *str = base->indices + base->offsets[k];
        uint32_t len = base->offsets[k + 1] - base->offsets[k];
        for (uint32_t w = 0; w + 2 < len; w++) {
            uint32_t tri[3];
            if (!mts_strip_window(str, w, tri))
                continue;
            if (edge_map_get(&g->edges, tri[0], tri[1]) >= 0 ||
                edge_map_get(&g->edges, tri[1], tri[2]) >= 0 ||
                edge_map_get(&g->edges, tri[2], tri[0]) >= 0) {
                rc = mts_error_set(err, MTS_ERR_FORMAT,
                                   "grow: base strip %u window %u (%u %u %u) repeats an edge "
                                   "another triangle holds",
                                   k, w, tri[0], tri[1], tri[2]);
                goto fail;
            }
            if (!tri_add(g, tri[0], tri[1], tri[2]))
                goto nomem;
        }
    }
    int strict = !(opts && opts->normalise_base);
    if ((rc = adopt_strips(g, base, strict, err)) != MTS_OK)
        goto fail;
    if (!strict && !fit_slots(g))
        goto nomem;
    if (!settle(g))
        goto nomem;
    for (uint32_t s = 0; strict && s < base->strip_count; s++) {
        uint32_t len = base->offsets[s + 1] - base->offsets[s];
        if (len != g->seq[s].n ||
            (len && memcmp(g->seq[s].w, base->indices + base->offsets[s], (size_t)len * 4) != 0)) {
            rc = mts_error_set(err, MTS_ERR_FORMAT,
                               "grow: base strip %u is not in the form growth derives", s);
            goto fail;
        }
    }
    g->fig.key_count = 1;
    g->next_key = g->key_ratio > 1 ? g->tri_count * g->key_ratio : -1;
    *out = g;
    return MTS_OK;
nomem:
    rc = mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
fail:
    mts_grow_free(g);
    return rc;
}

int32_t mts_grow_find(const mts_grow *g, uint32_t a, uint32_t b, uint32_t c)
{
    int32_t t = edge_map_get(&g->edges, a, b);
    if (t < 0 || third_vertex(g, (uint32_t)t, a, b) != c)
        return -1;
    return t;
}

void mts_grow_triangle(const mts_grow *g, uint32_t t, uint32_t out[3])
{
    memcpy(out, g->img[t], 12);
}

/* The corner of t after u, or NONE when t has no corner u. */
static uint32_t after(const mts_grow *g, uint32_t t, uint32_t u)
{
    for (int c = 0; c < 3; c++) {
        if (g->img[t][c] == u)
            return g->img[t][(c + 1) % 3];
    }
    return MTS_GROW_NONE;
}

static uint32_t before(const mts_grow *g, uint32_t t, uint32_t u)
{
    for (int c = 0; c < 3; c++) {
        if (g->img[t][c] == u)
            return g->img[t][(c + 2) % 3];
    }
    return MTS_GROW_NONE;
}

int32_t mts_grow_fan(const mts_grow *g, uint32_t u, uint32_t left, uint32_t right, uint32_t *ids,
                     uint32_t cap)
{
    uint32_t count = 0;
    if (right != MTS_GROW_NONE) {
        /* forward from the triangle holding u->right: (u, x, y) -> (u, y, .) */
        int32_t t = edge_map_get(&g->edges, u, right);
        if (t < 0)
            return -1;
        for (;;) {
            if (count >= g->tri_count)
                return -1; /* went round without meeting left */
            if (count < cap)
                ids[count] = (uint32_t)t;
            count++;
            uint32_t y = before(g, (uint32_t)t, u);
            if (y == left)
                return (int32_t)count;
            t = edge_map_get(&g->edges, u, y);
            if (t < 0)
                return left == MTS_GROW_NONE ? (int32_t)count : -1;
        }
    }
    if (left == MTS_GROW_NONE)
        return -1;
    /* backward from the triangle holding left->u to the border */
    int32_t t = edge_map_get(&g->edges, left, u);
    while (t >= 0) {
        if (count >= g->tri_count)
            return -1;
        if (count < cap)
            ids[count] = (uint32_t)t;
        count++;
        t = edge_map_get(&g->edges, after(g, (uint32_t)t, u), u);
    }
    return count ? (int32_t)count : -1;
}

/* The parent's triangles in ring order (grow.h); -1 when the ring is not a
 * simple fan. *closed says whether it goes all the way round. */
static int32_t ring(const mts_grow *g, uint32_t u, mts_words *out, int *closed)
{
    out->n = 0;
    *closed = 0;
    if (u >= g->nb + g->level || g->vtri[u] < 0)
        return -1;
    int32_t t0 = g->vtri[u], t = t0, first = t0, lowest = t0;
    uint32_t steps = 0;
    /* back to the border, or round to t0 */
    for (;;) {
        int32_t p = edge_map_get(&g->edges, after(g, (uint32_t)t, u), u);
        if (p < 0) {
            first = t;
            break;
        }
        if (p == t0) {
            *closed = 1;
            first = lowest;
            break;
        }
        if (++steps > g->tri_count)
            return -1;
        t = p;
        if (t < lowest)
            lowest = t;
    }
    t = first;
    for (;;) {
        if (out->n >= g->tri_count)
            return -1;
        if (!mts_words_reserve(out, 1))
            return -1;
        out->w[out->n++] = (uint32_t)t;
        t = edge_map_get(&g->edges, u, before(g, (uint32_t)t, u));
        if (t < 0 || t == first)
            break;
    }
    if (*closed && t != first)
        return -1;
    return (int32_t)out->n;
}

int mts_grow_fan_encode(mts_grow *g, uint32_t u, uint32_t left, uint32_t right,
                        mts_grow_fan_code *code)
{
    mts_grow *mg = g;
    int closed;
    int32_t k = ring(g, u, &mg->ring, &closed);
    int32_t m = mts_grow_fan(g, u, left, right, NULL, 0);
    if (k <= 0 || m <= 0 || m > k)
        return 0;
    uint32_t first;
    if (mts_grow_fan(g, u, left, right, &first, 1) != m)
        return 0;
    /* the fan runs forward from `first` (mts_grow_fan walks backward only
     * when right is absent, so then its first is the fan's far end) */
    if (right == MTS_GROW_NONE) {
        first = mg->ring.w[0];
        if (closed)
            return 0;
    }
    for (int32_t i = 0; i < k; i++) {
        if (mg->ring.w[i] == first) {
            code->start = (uint32_t)i;
            code->count = (uint32_t)m;
            code->sides = (right == MTS_GROW_NONE) | (left == MTS_GROW_NONE) << 1;
            uint32_t l2, r2;
            return mts_grow_fan_decode(g, u, code, &l2, &r2) && l2 == left && r2 == right;
        }
    }
    return 0;
}

int mts_grow_fan_decode(mts_grow *g, uint32_t u, const mts_grow_fan_code *code,
                        uint32_t *left, uint32_t *right)
{
    mts_grow *mg = g;
    int closed;
    int32_t k = ring(g, u, &mg->ring, &closed);
    if (k <= 0 || code->start >= (uint32_t)k || code->count == 0 || code->count > (uint32_t)k ||
        code->sides > 3)
        return 0;
    if (!closed && code->start + code->count > (uint32_t)k)
        return 0;
    uint32_t t_first = mg->ring.w[code->start];
    uint32_t t_last = mg->ring.w[(code->start + code->count - 1) % (uint32_t)k];
    *right = code->sides & 1 ? MTS_GROW_NONE : after(g, t_first, u);
    *left = code->sides & 2 ? MTS_GROW_NONE : before(g, t_last, u);
    if (*left == MTS_GROW_NONE && *right == MTS_GROW_NONE)
        return 0;
    /* the fan rule must give back exactly these triangles */
    return mts_grow_fan(g, u, *left, *right, NULL, 0) == (int32_t)code->count;
}

static int is_key(mts_grow *g)
{
    if (g->level == g->n)
        return 1;
    if (g->key_given) {
        if (g->key_given_at < g->key_given_count && g->key_given[g->key_given_at] == g->level) {
            g->key_given_at++;
            return 1;
        }
        return 0;
    }
    return g->next_key > 0 && g->tri_count >= g->next_key;
}

mts_result mts_grow_next(mts_grow *g, const mts_grow_split *sp, const mts_grow_full *full,
                         const uint32_t **record, uint32_t *word_count, mts_error *err)
{
    if (g->level >= g->n)
        return mts_error_set(err, MTS_ERR_ARG, "grow: every split is applied already");
    const uint32_t v = g->nb + g->level, u = sp->parent;
    if (u >= v || (sp->left != MTS_GROW_NONE && sp->left >= v) ||
        (sp->right != MTS_GROW_NONE && sp->right >= v) || sp->left == u || sp->right == u)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "grow: split %u (vertex %u, parent %u, %u, %u) names a vertex out "
                             "of range",
                             g->level, v, u, sp->left, sp->right);
    if (g->level + 1 == g->n && (!full || (!full->strips && !full->paths)))
        return mts_error_set(err, MTS_ERR_ARG, "grow: the last split needs the full strips");

    /* the triangles v takes over */
    g->affected.n = 0;
    if (sp->moved_count || sp->born_count) {
        if (!mts_words_reserve(&g->affected, sp->moved_count))
            goto nomem;
        for (uint32_t k = 0; k < sp->moved_count; k++) {
            uint32_t t = sp->moved[k];
            if (t >= g->tri_count || after(g, t, u) == MTS_GROW_NONE)
                return mts_error_set(err, MTS_ERR_FORMAT,
                                     "grow: split %u moves triangle %u, which has no corner %u",
                                     g->level, t, u);
            g->affected.w[g->affected.n++] = t;
        }
    } else {
        /* one walk of the fan while the scratch is big enough (nearly
         * always); a second only after growing it */
        uint32_t cap = g->affected.cap > UINT32_MAX ? UINT32_MAX : (uint32_t)g->affected.cap;
        int32_t k = mts_grow_fan(g, u, sp->left, sp->right, g->affected.w, cap);
        if (k < 0)
            return mts_error_set(err, MTS_ERR_FORMAT,
                                 "grow: split %u: no fan of %u from %u to %u", g->level, u,
                                 sp->right, sp->left);
        if ((uint32_t)k > cap) {
            if (!mts_words_reserve(&g->affected, (uint32_t)k))
                goto nomem;
            k = mts_grow_fan(g, u, sp->left, sp->right, g->affected.w, (uint32_t)k);
        }
        g->affected.n = (size_t)k;
    }
    for (size_t k = 0; k < g->affected.n; k++) {
        uint32_t t = g->affected.w[k];
        tri_edges_del(g, t);
        for (int c = 0; c < 3; c++) {
            if (g->img[t][c] == u)
                g->img[t][c] = v;
        }
    }
    for (size_t k = 0; k < g->affected.n; k++) {
        if (!tri_edges_put(g, g->affected.w[k]))
            goto nomem;
    }
    const uint32_t first_new = g->tri_count;
    g->newest_born = first_new;
    if (sp->moved_count || sp->born_count) {
        for (uint32_t k = 0; k < sp->born_count; k++) {
            const uint32_t *t = sp->born + 3 * (size_t)k;
            if (t[0] > v || t[1] > v || t[2] > v || t[0] == t[1] || t[1] == t[2] || t[0] == t[2])
                return mts_error_set(err, MTS_ERR_FORMAT,
                                     "grow: split %u brings back (%u %u %u), not a triangle of "
                                     "level %u",
                                     g->level, t[0], t[1], t[2], g->level + 1);
            if (!tri_add(g, t[0], t[1], t[2]))
                goto nomem;
        }
    } else {
        if (sp->left != MTS_GROW_NONE && !tri_add(g, u, v, sp->left))
            goto nomem;
        if (sp->right != MTS_GROW_NONE && !tri_add(g, v, u, sp->right))
            goto nomem;
    }
    if (g->affected.n)
        g->vtri[v] = (int32_t)g->affected.w[0];
    if (g->vtri[u] >= 0 && after(g, (uint32_t)g->vtri[u], u) == MTS_GROW_NONE) {
        /* u's triangle moved to v and no new one has u: find another */
        g->vtri[u] = -1;
        for (uint32_t t = 0; t < g->tri_count && g->vtri[u] < 0; t++) {
            if (after(g, t, u) != MTS_GROW_NONE)
                g->vtri[u] = (int32_t)t;
        }
    }
    g->level++;

    if (is_key(g)) {
        mts_result rc;
        if (g->level < g->n) {
            rc = restrip(g, err);
        } else if (full->strips) {
            rc = adopt_strips(g, full->strips, 0, err);
        } else {
            mts_strips decoded = {0};
            rc = resolve_full(g, full, &decoded, err);
            if (rc == MTS_OK)
                rc = adopt_strips(g, &decoded, 1, err);
            mts_strips_free(&decoded);
        }
        if (rc != MTS_OK)
            return rc;
        if (!mts_words_reserve(&g->keys, 1))
            goto nomem;
        g->keys.w[g->keys.n++] = g->level;
        g->fig.key_count++;
        g->next_key = g->key_ratio > 1 ? g->tri_count * g->key_ratio : -1;
    } else {
        /* links the split broke: only next to a moved triangle */
        for (size_t k = 0; k < g->affected.n; k++) {
            int32_t t = (int32_t)g->affected.w[k];
            touch(g, g->tslot[t]);
            if (g->prev[t] >= 0 && !adjacent(g, g->prev[t], t) &&
                !mend_link(g, g->prev[t], t, first_new))
                goto nomem;
            if (g->next[t] >= 0 && !adjacent(g, t, g->next[t]) &&
                !mend_link(g, t, g->next[t], first_new))
                goto nomem;
        }
        for (uint32_t f = first_new; f < g->tri_count; f++) {
            if (g->tslot[f] < 0 && !place_newborn(g, (int32_t)f))
                goto nomem;
        }
    }
    if (!emit_record(g, u, v))
        goto nomem;
    if (g->rec.n > UINT32_MAX)
        return mts_error_set(err, MTS_ERR_LIMIT, "grow: a record of %zu words", g->rec.n);
    *record = g->rec.w;
    *word_count = (uint32_t)g->rec.n;
    return MTS_OK;
nomem:
    return mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
}

mts_result mts_grow_around_newest(mts_grow *g, const uint32_t **ids, uint32_t *count,
                                  mts_error *err)
{
    *ids = NULL;
    *count = 0;
    if (g->level == 0)
        return mts_error_set(err, MTS_ERR_ARG, "grow: no split applied yet");
    const uint32_t v = g->nb + g->level - 1;
    size_t want = 2 * (g->affected.n + (size_t)(g->tri_count - g->newest_born));
    if (!mts_words_reserve(&g->around, want))
        return mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
    uint32_t *out = g->around.w, n = 0;
    /* the moved triangles and, of the new ones, those with a corner v (an
     * explicit split may bring back others); each triangle's two other
     * corners in its own order after v, so (v, a, b) is the triangle as
     * drawn and its normal is (a - v) x (b - v) */
    for (size_t k = 0, total = g->affected.n + (g->tri_count - g->newest_born); k < total; k++) {
        uint32_t t = k < g->affected.n ? g->affected.w[k]
                                       : g->newest_born + (uint32_t)(k - g->affected.n);
        const uint32_t *c = g->img[t];
        int at = c[0] == v ? 0 : c[1] == v ? 1 : c[2] == v ? 2 : -1;
        if (at < 0)
            continue;
        out[n++] = c[(at + 1) % 3];
        out[n++] = c[(at + 2) % 3];
    }
    *ids = out;
    *count = n;
    return MTS_OK;
}

int mts_grow_model_split(mts_grow *g, const mts_model *m, uint32_t j, mts_grow_split *sp)
{
    const uint32_t *w = m->growth_data + m->growth_offsets[j];
    uint32_t len = m->growth_offsets[j + 1] - m->growth_offsets[j];
    memset(sp, 0, sizeof *sp);
    sp->parent = m->parents[j];
    if (len < 3)
        return 0;
    if (w[2] == MTS_GROWTH_EXPLICIT) {
        if (len < 5 || (uint64_t)w[3] + 3ull * w[4] != len - 5)
            return 0;
        sp->left = sp->right = MTS_GROW_NONE;
        sp->moved_count = w[3];
        sp->born_count = w[4];
        sp->moved = w + 5;
        sp->born = w + 5 + w[3];
        return sp->moved_count || sp->born_count;
    }
    mts_grow_fan_code code = {w[0], w[1], w[2]};
    return len == 3 && mts_grow_fan_decode(g, sp->parent, &code, &sp->left, &sp->right);
}

void mts_grow_get_figures(const mts_grow *g, mts_grow_figures *out)
{
    *out = g->fig;
    out->level = g->level;
    out->triangles = g->tri_count;
    out->strips = g->nonempty;
    out->indices = g->total_indices;
    out->slot_count = g->slot_count;
    out->capacity = g->capacity;
}

const uint32_t *mts_grow_keys(const mts_grow *g, uint32_t *count)
{
    *count = (uint32_t)g->keys.n;
    return g->keys.w;
}

const uint32_t *mts_grow_slot(const mts_grow *g, uint32_t s, uint32_t *length)
{
    if (s >= g->slot_count) {
        *length = 0;
        return NULL;
    }
    *length = (uint32_t)g->seq[s].n;
    return g->seq[s].w;
}
