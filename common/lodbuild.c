/* LOD builder: strips grown upward from the base with key levels (see
 * lodbuild.h for the why).
 *
 * Measured on the shared models (indices per drawn triangle, restarts and
 * swaps counted, at 1/5/10/25/50% of the vertices): replaying collapses
 * downward from the full strips gave 4.1/3.7/3.4/2.6/1.8 on bunny00; growth
 * alone from a tunnelled base stays at 1.66-1.72 on every model; with key
 * levels every x1.41 / x1.7 / x2 of triangles the worst sampled level was
 * 1.50 / 1.48 / 1.60 (greedy strips at the keys; tunnelling them too gains
 * 0.02 and costs seconds). The default ratio, 1.5, keeps every level well
 * under 1.6 with about 12 keys on bunny00. */
#include "lodbuild.h"

#include <stdlib.h>
#include <string.h>

#include "stripify.h"
#include "tunnel.h"

/* A growable array of 32-bit words. */
typedef struct words {
    uint32_t *w;
    size_t n, cap;
} words;

static int words_reserve(words *v, size_t extra)
{
    if (v->n + extra <= v->cap)
        return 1;
    size_t cap = v->cap ? v->cap : 16;
    while (cap < v->n + extra)
        cap *= 2;
    uint32_t *w = realloc(v->w, cap * sizeof *w);
    if (!w)
        return 0;
    v->w = w;
    v->cap = cap;
    return 1;
}

static int words_push(words *v, uint32_t x)
{
    if (!words_reserve(v, 1))
        return 0;
    v->w[v->n++] = x;
    return 1;
}

/* Directed edge (a, b) -> the live triangle that holds it. */
typedef struct edge_map {
    uint64_t *key;
    int32_t *tri;
    uint32_t mask;
} edge_map;

#define EDGE_EMPTY UINT64_MAX
#define EDGE_GONE (UINT64_MAX - 1)

static uint32_t edge_hash(uint64_t k)
{
    k ^= k >> 33;
    k *= 0xff51afd7ed558ccdULL;
    k ^= k >> 33;
    return (uint32_t)k;
}

static int edge_map_init(edge_map *m, size_t entries)
{
    size_t cap = 16;
    while (cap < entries * 2)
        cap *= 2;
    m->key = malloc(cap * sizeof *m->key);
    m->tri = malloc(cap * sizeof *m->tri);
    if (!m->key || !m->tri)
        return 0;
    for (size_t i = 0; i < cap; i++)
        m->key[i] = EDGE_EMPTY;
    m->mask = (uint32_t)(cap - 1);
    return 1;
}

static void edge_map_put(edge_map *m, uint32_t a, uint32_t b, int32_t t)
{
    uint64_t k = (uint64_t)a << 32 | b;
    uint32_t i = edge_hash(k) & m->mask;
    int64_t gone = -1;
    while (m->key[i] != EDGE_EMPTY) {
        if (m->key[i] == k) {
            m->tri[i] = t;
            return;
        }
        if (m->key[i] == EDGE_GONE && gone < 0)
            gone = i;
        i = (i + 1) & m->mask;
    }
    if (gone >= 0)
        i = (uint32_t)gone;
    m->key[i] = k;
    m->tri[i] = t;
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
    for (uint32_t i = edge_hash(k) & m->mask; m->key[i] != EDGE_EMPTY; i = (i + 1) & m->mask) {
        if (m->key[i] == k) {
            if (m->tri[i] == t)
                m->key[i] = EDGE_GONE;
            return;
        }
    }
}

typedef struct builder {
    uint32_t nb, n, tri_count;
    const uint32_t *parent; /* n, stream ids */
    uint32_t (*corner)[3];  /* full-level vertices of each triangle */
    uint32_t (*img)[3];     /* its vertices at the current level */
    uint32_t *birth;        /* first level at which it is not degenerate */
    int32_t *next, *prev;   /* strip paths on the dual graph */
    int32_t *tslot;         /* slot of a live triangle's strip */
    uint8_t *alive;
    edge_map edges;
    /* per vertex v >= nb: the (triangle, corner) pairs whose vertex becomes
     * v when v is split off (every corner whose collapse chain passes v) */
    uint32_t *chain_off, *chain;
    uint32_t *born_off, *born;
    /* slots */
    uint32_t slot_count, slot_cap;
    words *seq;       /* indices of each slot at the current level */
    int32_t *head;    /* first triangle of each slot's path, -1 when empty */
    uint32_t *ntri;   /* triangles in each slot's path */
    uint32_t *capacity;
    uint32_t *free_slots;
    uint32_t free_count;
    uint32_t *stamp, stamp_now, *touched, touched_count;
    uint64_t total_indices; /* over all slots, for the level table */
    uint32_t nonempty;
    /* records, in split order, stream ids */
    words rec;
    uint32_t *rec_off;
    words scratch;
    int32_t *affected;
    uint32_t affected_cap;
} builder;

static uint32_t ancestor(const builder *b, uint32_t w, uint32_t level)
{
    while (w >= b->nb + level)
        w = b->parent[w - b->nb];
    return w;
}

static void tri_edges_put(builder *b, uint32_t t)
{
    for (int c = 0; c < 3; c++)
        edge_map_put(&b->edges, b->img[t][c], b->img[t][(c + 1) % 3], (int32_t)t);
}

static void tri_edges_del(builder *b, uint32_t t)
{
    for (int c = 0; c < 3; c++)
        edge_map_del(&b->edges, b->img[t][c], b->img[t][(c + 1) % 3], (int32_t)t);
}

/* The edge x->y of triangle a whose reverse is in triangle b. */
static int shared_edge(const builder *b, uint32_t ta, uint32_t tb, uint32_t *x, uint32_t *y)
{
    for (int c = 0; c < 3; c++) {
        uint32_t p = b->img[ta][c], q = b->img[ta][(c + 1) % 3];
        for (int d = 0; d < 3; d++) {
            if (b->img[tb][d] == q && b->img[tb][(d + 1) % 3] == p) {
                *x = p;
                *y = q;
                return 1;
            }
        }
    }
    return 0;
}

static int adjacent(const builder *b, int32_t ta, int32_t tb)
{
    uint32_t x, y;
    return ta >= 0 && tb >= 0 && shared_edge(b, (uint32_t)ta, (uint32_t)tb, &x, &y);
}

static uint32_t third_vertex(const builder *b, uint32_t t, uint32_t x, uint32_t y)
{
    for (int c = 0; c < 3; c++) {
        if (b->img[t][c] != x && b->img[t][c] != y)
            return b->img[t][c];
    }
    return b->img[t][0];
}

/* The indices of a path (see lodbuild.h): at most 3 + 2 per further
 * triangle. */
static int derive_indices(const builder *b, int32_t head, words *out)
{
    out->n = 0;
    if (head < 0)
        return 1;
    uint32_t t = (uint32_t)head;
    if (b->next[t] < 0) {
        if (!words_reserve(out, 3))
            return 0;
        memcpy(out->w, b->img[t], 12);
        out->n = 3;
        return 1;
    }
    uint32_t x, y;
    shared_edge(b, t, (uint32_t)b->next[t], &x, &y);
    if (!words_reserve(out, 3))
        return 0;
    out->w[0] = third_vertex(b, t, x, y);
    out->w[1] = x;
    out->w[2] = y;
    out->n = 3;
    uint32_t a = x, c = y; /* the last two indices, the edge into the next */
    for (int32_t s = b->next[t]; s >= 0; s = b->next[s]) {
        uint32_t w = third_vertex(b, (uint32_t)s, a, c);
        if (!words_reserve(out, 2))
            return 0;
        if (b->next[s] >= 0) {
            uint32_t p, q;
            shared_edge(b, (uint32_t)s, (uint32_t)b->next[s], &p, &q);
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

static void touch(builder *b, int32_t slot)
{
    if (slot < 0)
        return;
    if (b->stamp[slot] != b->stamp_now) {
        b->stamp[slot] = b->stamp_now;
        b->touched[b->touched_count++] = (uint32_t)slot;
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

static int32_t slot_new(builder *b)
{
    if (b->free_count)
        return (int32_t)b->free_slots[--b->free_count];
    if (b->slot_count == b->slot_cap) {
        uint32_t old = b->slot_cap, cap = old * 2;
        /* each array keeps its old block if its own growth fails */
        if (!grow_zeroed((void **)&b->seq, sizeof *b->seq, old, cap) ||
            !grow_zeroed((void **)&b->head, sizeof *b->head, old, cap) ||
            !grow_zeroed((void **)&b->ntri, 4, old, cap) ||
            !grow_zeroed((void **)&b->capacity, 4, old, cap) ||
            !grow_zeroed((void **)&b->free_slots, 4, old, cap) ||
            !grow_zeroed((void **)&b->stamp, 4, old, cap) ||
            !grow_zeroed((void **)&b->touched, 4, old, cap))
            return -1;
        b->slot_cap = cap;
    }
    int32_t s = (int32_t)b->slot_count++;
    b->head[s] = -1;
    b->ntri[s] = 0;
    return s;
}

static void slot_release(builder *b, int32_t s)
{
    b->head[s] = -1;
    b->ntri[s] = 0;
    b->free_slots[b->free_count++] = (uint32_t)s;
}

/* Gives the path starting at t (and everything after it) the slot s. */
static uint32_t path_claim(builder *b, int32_t t, int32_t s)
{
    uint32_t count = 0;
    for (; t >= 0; t = b->next[t]) {
        b->tslot[t] = s;
        count++;
    }
    return count;
}

/* Longest path growth may make by appending or joining; insertion into the
 * middle is never refused (the alternative is cutting the strip). */
#define GROW_MAX_PATH (2 * MTS_STRIPIFY_MAX_STRIP)

/* Mends one link a -> c that the split broke: a newborn triangle adjacent to
 * both goes between them (the strip crossed the edge it was born on), else
 * the path is cut and its tail gets a slot of its own. */
static int mend_link(builder *b, int32_t a, int32_t c, const int32_t *newborn, uint32_t nnew,
                     mts_lodbuild_stats *st)
{
    for (uint32_t q = 0; q < nnew; q++) {
        int32_t f = newborn[q];
        if (b->tslot[f] >= 0 || !adjacent(b, a, f) || !adjacent(b, f, c))
            continue;
        int32_t s = b->tslot[a];
        b->next[a] = f;
        b->prev[f] = a;
        b->next[f] = c;
        b->prev[c] = f;
        b->tslot[f] = s;
        b->ntri[s]++;
        st->grown_inserted++;
        return 1;
    }
    int32_t s = b->tslot[a];
    int32_t ns = slot_new(b);
    if (ns < 0)
        return 0;
    b->next[a] = -1;
    b->prev[c] = -1;
    b->head[ns] = c;
    b->ntri[ns] = path_claim(b, c, ns);
    b->ntri[s] -= b->ntri[ns];
    touch(b, ns);
    st->strips_cut++;
    return 1;
}

/* Places a newborn triangle no strip crossed into: after a strip that ends
 * next to it, before one that starts next to it, both (joining them), or
 * alone. */
static int place_newborn(builder *b, int32_t f, mts_lodbuild_stats *st)
{
    int32_t nbr[3];
    for (int c = 0; c < 3; c++) {
        int32_t g = edge_map_get(&b->edges, b->img[f][(c + 1) % 3], b->img[f][c]);
        nbr[c] = (g >= 0 && g != f && b->alive[g] && b->tslot[g] >= 0) ? g : -1;
    }
    int32_t tail = -1, head = -1;
    for (int c = 0; c < 3 && tail < 0; c++) {
        int32_t g = nbr[c];
        if (g >= 0 && b->next[g] < 0 && b->ntri[b->tslot[g]] < GROW_MAX_PATH)
            tail = g;
    }
    for (int c = 0; c < 3 && head < 0; c++) {
        int32_t g = nbr[c];
        if (g < 0 || g == tail || b->prev[g] >= 0 || b->ntri[b->tslot[g]] >= GROW_MAX_PATH)
            continue;
        if (tail >= 0 && (b->tslot[g] == b->tslot[tail] ||
                          b->ntri[b->tslot[g]] + b->ntri[b->tslot[tail]] >= GROW_MAX_PATH))
            continue; /* would close a loop, or make too long a strip */
        head = g;
    }
    if (tail >= 0 && head >= 0) {
        int32_t s = b->tslot[tail], gone = b->tslot[head];
        b->next[tail] = f;
        b->prev[f] = tail;
        b->next[f] = head;
        b->prev[head] = f;
        b->tslot[f] = s;
        b->ntri[s] += 1 + path_claim(b, head, s);
        touch(b, gone);
        slot_release(b, gone);
        st->grown_joined++;
    } else if (tail >= 0) {
        int32_t s = b->tslot[tail];
        b->next[tail] = f;
        b->prev[f] = tail;
        b->tslot[f] = s;
        b->ntri[s]++;
        st->grown_appended++;
    } else if (head >= 0) {
        int32_t s = b->tslot[head];
        b->next[f] = head;
        b->prev[head] = f;
        b->tslot[f] = s;
        b->head[s] = f;
        b->ntri[s]++;
        st->grown_appended++;
    } else {
        int32_t s = slot_new(b);
        if (s < 0)
            return 0;
        b->head[s] = f;
        b->ntri[s] = 1;
        b->tslot[f] = s;
        st->grown_alone++;
    }
    touch(b, b->tslot[f]);
    return 1;
}

/* Turns strips (from the stripifier, over live triangles) into paths in
 * slots 0.., every other slot left empty; every slot is touched. A window
 * that names no live triangle is a bug. */
static mts_result adopt_strips(builder *b, const mts_strips *strips, mts_error *err)
{
    for (uint32_t s = 0; s < b->slot_count; s++) {
        b->head[s] = -1;
        b->ntri[s] = 0;
        touch(b, (int32_t)s);
    }
    for (uint32_t t = 0; t < b->tri_count; t++) {
        b->next[t] = b->prev[t] = -1;
        b->tslot[t] = -1;
    }
    b->free_count = 0;
    uint32_t used = 0;
    for (uint32_t k = 0; k < strips->strip_count; k++) {
        const uint32_t *str = strips->indices + strips->offsets[k];
        uint32_t len = strips->offsets[k + 1] - strips->offsets[k];
        int32_t prev = -1, s = -1;
        for (uint32_t w = 0; w + 2 < len; w++) {
            uint32_t tri[3];
            if (!mts_strip_window(str, w, tri))
                continue;
            int32_t t = edge_map_get(&b->edges, tri[0], tri[1]);
            if (t < 0 || !b->alive[t] || third_vertex(b, (uint32_t)t, tri[0], tri[1]) != tri[2])
                return mts_error_set(err, MTS_ERR_INTERNAL,
                                     "lodbuild: strip %u draws (%u %u %u), not a live triangle",
                                     k, tri[0], tri[1], tri[2]);
            if (prev >= 0 && adjacent(b, prev, t)) {
                b->next[prev] = t;
                b->prev[t] = prev;
            } else {
                if (used == b->slot_count && slot_new(b) < 0)
                    return mts_error_set(err, MTS_ERR_NOMEM, "lodbuild: out of memory");
                s = (int32_t)used++;
                b->head[s] = t;
                touch(b, s);
            }
            b->tslot[t] = s;
            b->ntri[s]++;
            prev = t;
        }
    }
    for (uint32_t s = b->slot_count; s-- > used;)
        b->free_slots[b->free_count++] = s;
    return MTS_OK;
}

/* A runtime reserves each slot's longest length over all levels, so strips
 * of a key level go into the slots by length, longest into the roomiest:
 * otherwise every slot soon holds a long strip at some key and the room
 * reserved grows to several times what any one level draws. */
/* Sorts ids by key[id], largest first, ties by id (a stable, deterministic
 * order; insertion sort over runs is too slow for 10^4 slots, so merge). */
static void sort_desc(uint32_t *ids, uint32_t n, const uint32_t *key)
{
    uint32_t *tmp = malloc(((size_t)n + 1) * 4);
    if (!tmp)
        return; /* leaves the order as is: still correct, only roomier */
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
}

static int fit_slots(builder *b)
{
    uint32_t n = b->slot_count;
    uint32_t *paths = malloc(((size_t)n + 1) * 4), *slots = malloc(((size_t)n + 1) * 4);
    int32_t *head = malloc(((size_t)n + 1) * sizeof *head);
    uint32_t *ntri = malloc(((size_t)n + 1) * 4);
    if (!paths || !slots || !head || !ntri) {
        free(paths);
        free(slots);
        free(head);
        free(ntri);
        return 0;
    }
    for (uint32_t s = 0; s < n; s++) {
        paths[s] = s;
        slots[s] = s;
        head[s] = b->head[s];
        ntri[s] = b->ntri[s];
    }
    sort_desc(paths, n, b->ntri);
    sort_desc(slots, n, b->capacity);
    for (uint32_t k = 0; k < n; k++) {
        uint32_t s = slots[k];
        b->head[s] = head[paths[k]];
        b->ntri[s] = ntri[paths[k]];
        path_claim(b, b->head[s], (int32_t)s);
    }
    b->free_count = 0;
    for (uint32_t k = n; k-- > 0;) {
        if (b->head[k] < 0)
            b->free_slots[b->free_count++] = k;
    }
    free(paths);
    free(slots);
    free(head);
    free(ntri);
    return 1;
}

/* Restripifies the live triangles (the level's mesh) into the slots. */
static mts_result restrip(builder *b, uint32_t level, int tunnel_length, mts_error *err)
{
    uint32_t live = 0;
    for (uint32_t t = 0; t < b->tri_count; t++)
        live += b->alive[t];
    uint32_t *tris = malloc(((size_t)live + 1) * 12);
    if (!tris)
        return mts_error_set(err, MTS_ERR_NOMEM, "lodbuild: out of memory");
    live = 0;
    for (uint32_t t = 0; t < b->tri_count; t++) {
        if (b->alive[t])
            memcpy(tris + 3 * (size_t)live++, b->img[t], 12);
    }
    mts_strips strips = {0};
    mts_result rc = mts_stripify(tris, live, b->nb + level, &strips, NULL, err);
    free(tris);
    if (rc == MTS_OK && tunnel_length > 0) {
        mts_tunnel_options to = {0};
        to.length = tunnel_length;
        mts_strips tunnelled = {0};
        rc = mts_tunnel(&strips, b->nb + level, &to, &tunnelled, NULL, err);
        mts_strips_free(&strips);
        strips = tunnelled;
    }
    if (rc == MTS_OK)
        rc = adopt_strips(b, &strips, err);
    mts_strips_free(&strips);
    if (rc == MTS_OK && !fit_slots(b))
        rc = mts_error_set(err, MTS_ERR_NOMEM, "lodbuild: out of memory");
    return rc;
}

/* Appends the edit that turns slot s's stored indices into `to` (in which
 * the new vertex v appears; u is its parent), and stores `to`. The runs
 * carry u where `to` has v, and the positions of v are substitutions, so an
 * inserted run never names a vertex that does not exist yet. */
static int emit_edit(builder *b, uint32_t s, const words *to, uint32_t u, uint32_t v,
                     uint32_t *edits, mts_lodbuild_stats *st)
{
    words *from = &b->seq[s];
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
    if (!words_reserve(&b->rec, 4 + 2 + erase + 2 + insert + substs))
        return 0;
    uint32_t *w = b->rec.w + b->rec.n;
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
    b->rec.n = (size_t)(w - b->rec.w);
    (*edits)++;
    st->edits++;
    st->erased_indices += erase;
    st->inserted_indices += insert;
    st->substitutions += substs;
    b->total_indices = b->total_indices - lo + ln;
    b->nonempty = b->nonempty - (lo > 0) + (ln > 0);
    from->n = 0;
    if (!words_reserve(from, ln))
        return 0;
    memcpy(from->w, nw, ln * 4);
    from->n = ln;
    if (ln > b->capacity[s])
        b->capacity[s] = (uint32_t)ln;
    return 1;
}

static int cmp_u32(const void *a, const void *c)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)c;
    return x < y ? -1 : x > y;
}

/* The record of split j: one edit per touched slot, in slot order. `given`
 * (the caller's full strips, at the last split) replaces derivation. */
static int emit_record(builder *b, uint32_t j, const mts_strips *given, mts_lodbuild_stats *st)
{
    uint32_t u = j < b->n ? b->parent[j] : 0, v = b->nb + j;
    size_t count_at = b->rec.n;
    if (!words_push(&b->rec, 0))
        return 0;
    uint32_t edits = 0;
    qsort(b->touched, b->touched_count, 4, cmp_u32);
    for (uint32_t k = 0; k < b->touched_count; k++) {
        uint32_t s = b->touched[k];
        if (given) {
            b->scratch.n = 0;
            if (s < given->strip_count) {
                uint32_t len = given->offsets[s + 1] - given->offsets[s];
                if (!words_reserve(&b->scratch, len))
                    return 0;
                memcpy(b->scratch.w, given->indices + given->offsets[s], (size_t)len * 4);
                b->scratch.n = len;
            }
        } else if (!derive_indices(b, b->head[s], &b->scratch)) {
            return 0;
        }
        if (!emit_edit(b, s, &b->scratch, u, v, &edits, st))
            return 0;
    }
    b->rec.w[count_at] = edits;
    b->touched_count = 0;
    b->stamp_now++;
    return 1;
}

static mts_result level_figures(const builder *b, uint32_t live, mts_model *m, uint32_t level,
                                mts_error *err)
{
    if (b->total_indices > UINT32_MAX)
        return mts_error_set(err, MTS_ERR_LIMIT, "lodbuild: level %u has %llu strip indices",
                             level, (unsigned long long)b->total_indices);
    m->level_triangles[level] = live;
    m->level_strips[level] = b->nonempty;
    m->level_indices[level] = (uint32_t)b->total_indices;
    return MTS_OK;
}

static void builder_free(builder *b)
{
    free(b->corner);
    free(b->img);
    free(b->birth);
    free(b->next);
    free(b->prev);
    free(b->tslot);
    free(b->alive);
    free(b->edges.key);
    free(b->edges.tri);
    free(b->chain_off);
    free(b->chain);
    free(b->born_off);
    free(b->born);
    if (b->seq) {
        for (uint32_t s = 0; s < b->slot_cap; s++)
            free(b->seq[s].w);
    }
    free(b->seq);
    free(b->head);
    free(b->ntri);
    free(b->capacity);
    free(b->free_slots);
    free(b->stamp);
    free(b->touched);
    free(b->rec.w);
    free(b->rec_off);
    free(b->scratch.w);
    free(b->affected);
}

static mts_result copy_slots(const builder *b, mts_strips *out, mts_error *err)
{
    uint64_t total = 0;
    for (uint32_t s = 0; s < b->slot_count; s++)
        total += b->seq[s].n;
    if (total > UINT32_MAX - 1)
        return mts_error_set(err, MTS_ERR_LIMIT, "lodbuild: %llu strip indices at one level",
                             (unsigned long long)total);
    mts_result rc = mts_strips_alloc(out, b->slot_count, (uint32_t)total, err);
    if (rc != MTS_OK)
        return rc;
    uint32_t o = 0;
    for (uint32_t s = 0; s < b->slot_count; s++) {
        out->offsets[s] = o;
        memcpy(out->indices + o, b->seq[s].w, b->seq[s].n * 4);
        o += (uint32_t)b->seq[s].n;
    }
    out->offsets[b->slot_count] = o;
    return MTS_OK;
}

mts_result mts_lodbuild(const mts_mesh *mesh, const mts_strips *strips,
                        const mts_simplify_result *simp, const mts_lodbuild_options *opts,
                        const mts_progress *progress, mts_model *model,
                        mts_lodbuild_stats *stats_out, mts_error *err)
{
    mts_result rc = MTS_ERR_NOMEM;
    builder b = {0};
    mts_lodbuild_stats st = {0};
    uint32_t *new_id = NULL, *parents = NULL;
    mts_strips given = {0};
    const uint32_t nv = mesh->vertex_count;
    const uint32_t n = simp->collapse_count;
    const uint32_t F = mesh->triangle_count;
    double ratio = opts && opts->key_ratio != 0 ? opts->key_ratio : MTS_LODBUILD_DEFAULT_KEY_RATIO;
    memset(model, 0, sizeof *model);

    if (n >= nv)
        return mts_error_set(err, MTS_ERR_ARG, "lodbuild: %u collapses for %u vertices", n, nv);
    if (F > (UINT32_MAX - 2) / 3 || F > INT32_MAX / 2)
        return mts_error_set(err, MTS_ERR_LIMIT, "lodbuild: %u triangles is too many", F);
    for (uint32_t i = 0; i < strips->index_count; i++) {
        if (strips->indices[i] >= nv)
            return mts_error_set(err, MTS_ERR_RANGE, "lodbuild: strip index %u out of range",
                                 strips->indices[i]);
    }
    for (size_t i = 0; i < 3 * (size_t)F; i++) {
        if (mesh->triangles[i] >= nv)
            return mts_error_set(err, MTS_ERR_RANGE, "lodbuild: triangle index %u out of range",
                                 mesh->triangles[i]);
    }

    /* Stream order: survivors keep their relative order, then the collapsed
     * vertices, last collapsed first. */
    const uint32_t nb = nv - n;
    new_id = malloc(((size_t)nv + 1) * 4);
    parents = malloc(((size_t)n + 1) * 4);
    if (!new_id || !parents)
        goto nomem;
    for (uint32_t v = 0; v < nv; v++)
        new_id[v] = UINT32_MAX;
    for (uint32_t c = 0; c < n; c++) {
        const uint32_t v = simp->collapses[c].removed, u = simp->collapses[c].kept;
        if (v >= nv || u >= nv || v == u) {
            rc = mts_error_set(err, MTS_ERR_RANGE, "lodbuild: collapse %u (%u -> %u) is invalid",
                               c, v, u);
            goto fail;
        }
        if (new_id[v] != UINT32_MAX) {
            rc = mts_error_set(err, MTS_ERR_ARG, "lodbuild: vertex %u collapses twice", v);
            goto fail;
        }
        new_id[v] = nb + (n - 1 - c);
    }
    uint32_t next_id = 0;
    for (uint32_t v = 0; v < nv; v++) {
        if (new_id[v] == UINT32_MAX)
            new_id[v] = next_id++;
    }
    for (uint32_t c = 0; c < n; c++) {
        uint32_t kept = new_id[simp->collapses[c].kept], j = n - 1 - c;
        if (kept >= nb + j) {
            rc = mts_error_set(err, MTS_ERR_ARG,
                               "lodbuild: collapse %u keeps vertex %u after it was removed", c,
                               simp->collapses[c].kept);
            goto fail;
        }
        parents[j] = kept;
    }

    b.nb = nb;
    b.n = n;
    b.tri_count = F;
    b.parent = parents;
    b.corner = malloc(((size_t)F + 1) * 12);
    b.img = malloc(((size_t)F + 1) * 12);
    b.birth = malloc(((size_t)F + 1) * 4);
    b.next = malloc(((size_t)F + 1) * 4);
    b.prev = malloc(((size_t)F + 1) * 4);
    b.tslot = malloc(((size_t)F + 1) * 4);
    b.alive = calloc((size_t)F + 1, 1);
    b.chain_off = calloc((size_t)nv + 2, 4);
    b.born_off = calloc((size_t)n + 3, 4);
    b.born = malloc(((size_t)F + 1) * 4);
    b.rec_off = malloc(((size_t)n + 1) * 4);
    b.slot_cap = 64;
    b.seq = calloc(b.slot_cap, sizeof *b.seq);
    b.head = malloc(b.slot_cap * sizeof *b.head);
    b.ntri = malloc(b.slot_cap * 4);
    b.capacity = calloc(b.slot_cap, 4);
    b.free_slots = malloc(b.slot_cap * 4);
    b.stamp = calloc(b.slot_cap, 4);
    b.touched = malloc(b.slot_cap * 4);
    b.stamp_now = 1;
    model->level_triangles = malloc(((size_t)n + 1) * 4);
    model->level_strips = malloc(((size_t)n + 1) * 4);
    model->level_indices = malloc(((size_t)n + 1) * 4);
    if (!b.corner || !b.img || !b.birth || !b.next || !b.prev || !b.tslot || !b.alive ||
        !b.chain_off || !b.born_off || !b.born || !b.rec_off || !b.seq || !b.head || !b.ntri ||
        !b.capacity || !b.free_slots || !b.stamp || !b.touched || !model->level_triangles ||
        !model->level_strips || !model->level_indices || !edge_map_init(&b.edges, 3 * (size_t)F))
        goto nomem;

    /* Each triangle's first level: the lowest at which its corners' images
     * are three vertices (images only merge going down). */
    for (uint32_t t = 0; t < F; t++) {
        for (int c = 0; c < 3; c++)
            b.corner[t][c] = new_id[mesh->triangles[3 * (size_t)t + c]];
        uint32_t lo = 0, hi = n + 1;
        while (lo < hi) {
            uint32_t mid = lo + (hi - lo) / 2;
            uint32_t x = ancestor(&b, b.corner[t][0], mid), y = ancestor(&b, b.corner[t][1], mid),
                     z = ancestor(&b, b.corner[t][2], mid);
            if (x != y && y != z && x != z)
                hi = mid;
            else
                lo = mid + 1;
        }
        if (lo > n) {
            rc = mts_error_set(err, MTS_ERR_ARG, "lodbuild: triangle %u repeats a vertex", t);
            goto fail;
        }
        b.birth[t] = lo;
        b.born_off[lo + 1]++;
        b.next[t] = b.prev[t] = b.tslot[t] = -1;
    }
    for (uint32_t l = 0; l <= n; l++)
        b.born_off[l + 1] += b.born_off[l];
    {
        uint32_t *fill = calloc((size_t)n + 2, 4);
        if (!fill)
            goto nomem;
        for (uint32_t t = 0; t < F; t++)
            b.born[b.born_off[b.birth[t]] + fill[b.birth[t]]++] = t;
        free(fill);
    }
    /* Corner chains: the corners whose vertex becomes v when v splits off. */
    uint64_t chain_total = 0;
    for (uint32_t t = 0; t < F; t++) {
        for (int c = 0; c < 3; c++) {
            for (uint32_t w = b.corner[t][c]; w >= nb; w = parents[w - nb]) {
                b.chain_off[w + 1]++;
                chain_total++;
            }
        }
    }
    if (chain_total > UINT32_MAX - 1) {
        rc = mts_error_set(err, MTS_ERR_LIMIT, "lodbuild: collapse chains too deep (%llu links)",
                           (unsigned long long)chain_total);
        goto fail;
    }
    for (uint32_t v = 0; v < nv; v++)
        b.chain_off[v + 1] += b.chain_off[v];
    b.chain = malloc((chain_total + 1) * 4);
    {
        uint32_t *fill = calloc((size_t)nv + 1, 4);
        if (!b.chain || !fill) {
            free(fill);
            goto nomem;
        }
        for (uint32_t t = 0; t < F; t++) {
            for (uint32_t c = 0; c < 3; c++) {
                for (uint32_t w = b.corner[t][c]; w >= nb; w = parents[w - nb])
                    b.chain[b.chain_off[w] + fill[w]++] = 3 * t + c;
            }
        }
        free(fill);
    }
    uint32_t most_affected = 1;
    for (uint32_t v = nb; v < nv; v++) {
        uint32_t k = b.chain_off[v + 1] - b.chain_off[v];
        if (k > most_affected)
            most_affected = k;
    }
    b.affected = malloc((size_t)most_affected * sizeof *b.affected);
    if (!b.affected)
        goto nomem;

    /* The caller's full strips in stream ids: the last key level. */
    if (mts_strips_alloc(&given, strips->strip_count, strips->index_count, err) != MTS_OK)
        goto fail_keep;
    memcpy(given.offsets, strips->offsets, ((size_t)strips->strip_count + 1) * 4);
    for (uint32_t i = 0; i < strips->index_count; i++)
        given.indices[i] = new_id[strips->indices[i]];

    /* Level 0: the base mesh, stripified and tunnelled. */
    uint32_t live = 0;
    for (uint32_t k = b.born_off[0]; k < b.born_off[1]; k++) {
        uint32_t t = b.born[k];
        b.alive[t] = 1;
        for (int c = 0; c < 3; c++)
            b.img[t][c] = ancestor(&b, b.corner[t][c], 0);
        tri_edges_put(&b, t);
        live++;
    }
    while (n == 0 && b.slot_count < given.strip_count) {
        if (slot_new(&b) < 0)
            goto nomem;
    }
    if (n == 0) {
        if ((rc = adopt_strips(&b, &given, err)) != MTS_OK)
            goto fail;
        st.key_levels++;
        if (!emit_record(&b, 0, &given, &st))
            goto nomem;
        b.rec.n = 0;
    } else {
        if ((rc = restrip(&b, 0, MTS_TUNNEL_DEFAULT_LENGTH, err)) != MTS_OK)
            goto fail;
        st.key_levels++;
        for (uint32_t k = 0; k < b.touched_count; k++) {
            uint32_t s = b.touched[k];
            if (!derive_indices(&b, b.head[s], &b.seq[s]))
                goto nomem;
            if (b.seq[s].n > b.capacity[s])
                b.capacity[s] = (uint32_t)b.seq[s].n;
            b.total_indices += b.seq[s].n;
            b.nonempty += b.seq[s].n > 0;
        }
        b.touched_count = 0;
        b.stamp_now++;
    }
    if ((rc = level_figures(&b, live, model, 0, err)) != MTS_OK)
        goto fail;
    if ((rc = copy_slots(&b, &model->base, err)) != MTS_OK)
        goto fail;

    double next_key = ratio > 1 ? live * ratio : -1;
    for (uint32_t j = 0; j < n; j++) {
        const uint32_t v = nb + j, level = j + 1;
        b.rec_off[j] = (uint32_t)b.rec.n;
        /* the corners that become v */
        uint32_t na = 0;
        for (uint32_t k = b.chain_off[v]; k < b.chain_off[v + 1]; k++) {
            uint32_t t = b.chain[k] / 3, c = b.chain[k] % 3;
            if (!b.alive[t])
                continue;
            if (na == 0 || b.affected[na - 1] != (int32_t)t) {
                tri_edges_del(&b, t);
                b.affected[na++] = (int32_t)t;
            }
            b.img[t][c] = v;
        }
        for (uint32_t k = 0; k < na; k++)
            tri_edges_put(&b, (uint32_t)b.affected[k]);
        int32_t newborn[8];
        uint32_t nnew = 0;
        for (uint32_t k = b.born_off[level]; k < b.born_off[level + 1]; k++) {
            uint32_t t = b.born[k];
            b.alive[t] = 1;
            for (int c = 0; c < 3; c++)
                b.img[t][c] = ancestor(&b, b.corner[t][c], level);
            tri_edges_put(&b, t);
            live++;
            if (nnew < 8)
                newborn[nnew++] = (int32_t)t;
        }
        int is_key = level == n || (next_key > 0 && live >= next_key);
        if (is_key) {
            if (level == n) {
                /* slot s gets the caller's strip s */
                while (b.slot_count < given.strip_count) {
                    if (slot_new(&b) < 0)
                        goto nomem;
                }
                if ((rc = adopt_strips(&b, &given, err)) != MTS_OK)
                    goto fail;
            } else if ((rc = restrip(&b, level, 0, err)) != MTS_OK) {
                goto fail;
            }
            st.key_levels++;
            next_key = ratio > 1 ? live * ratio : -1;
            if (!emit_record(&b, j, level == n ? &given : NULL, &st))
                goto nomem;
        } else {
            /* Links the split broke: only next to a relabelled triangle. */
            for (uint32_t k = 0; k < na; k++) {
                int32_t t = b.affected[k];
                touch(&b, b.tslot[t]);
                if (b.prev[t] >= 0 && !adjacent(&b, b.prev[t], t) &&
                    !mend_link(&b, b.prev[t], t, newborn, nnew, &st))
                    goto nomem;
                if (b.next[t] >= 0 && !adjacent(&b, t, b.next[t]) &&
                    !mend_link(&b, t, b.next[t], newborn, nnew, &st))
                    goto nomem;
            }
            for (uint32_t k = 0; k < nnew; k++) {
                if (b.tslot[newborn[k]] < 0 && !place_newborn(&b, newborn[k], &st))
                    goto nomem;
            }
            /* more than 8 newborns cannot happen on a manifold (2 per split);
             * place any others alone all the same */
            for (uint32_t k = b.born_off[level] + nnew; k < b.born_off[level + 1]; k++) {
                if (!place_newborn(&b, (int32_t)b.born[k], &st))
                    goto nomem;
            }
            if (!emit_record(&b, j, NULL, &st))
                goto nomem;
        }
        if ((rc = level_figures(&b, live, model, level, err)) != MTS_OK)
            goto fail;
        if ((j & 1023) == 0)
            mts_progress_report(progress, "records", (double)j / n);
    }
    if (b.rec.n > UINT32_MAX - 1) {
        rc = mts_error_set(err, MTS_ERR_LIMIT,
                           "lodbuild: the records take %zu words, more than 32-bit offsets reach",
                           b.rec.n);
        goto fail;
    }
    b.rec_off[n] = (uint32_t)b.rec.n;

    model->vertex_count = nv;
    model->base_vertex_count = nb;
    model->level_count = n;
    model->strip_count = b.slot_count;
    model->positions = malloc((size_t)nv * 12 + 1);
    model->normals = malloc((size_t)nv * 12 + 1);
    model->capacity = malloc(((size_t)b.slot_count + 1) * 4);
    if (!model->positions || !model->normals || !model->capacity)
        goto nomem;
    memcpy(model->capacity, b.capacity, (size_t)b.slot_count * 4);
    for (int a = 0; a < 3; a++) {
        model->bbox_min[a] = nv ? mesh->positions[a] : 0;
        model->bbox_max[a] = nv ? mesh->positions[a] : 0;
    }
    for (uint32_t v = 0; v < nv; v++) {
        memcpy(model->positions + 3 * (size_t)new_id[v], mesh->positions + 3 * (size_t)v, 12);
        memcpy(model->normals + 3 * (size_t)new_id[v], mesh->normals + 3 * (size_t)v, 12);
        for (int a = 0; a < 3; a++) {
            float x = mesh->positions[3 * (size_t)v + a];
            if (x < model->bbox_min[a])
                model->bbox_min[a] = x;
            if (x > model->bbox_max[a])
                model->bbox_max[a] = x;
        }
    }
    model->parents = parents;
    parents = NULL;
    model->record_offsets = b.rec_off;
    b.rec_off = NULL;
    model->record_word_count = (uint32_t)b.rec.n;
    model->record_data = b.rec.w;
    b.rec.w = NULL;
    if (!model->record_data && !(model->record_data = malloc(4)))
        goto nomem;
    /* the base was copied before the first split; grow it to every slot */
    if (model->base.strip_count < b.slot_count) {
        mts_strips base = {0};
        if ((rc = mts_strips_alloc(&base, b.slot_count, model->base.index_count, err)) != MTS_OK)
            goto fail;
        memcpy(base.offsets, model->base.offsets, ((size_t)model->base.strip_count + 1) * 4);
        for (uint32_t s = model->base.strip_count + 1; s <= b.slot_count; s++)
            base.offsets[s] = model->base.index_count;
        memcpy(base.indices, model->base.indices, (size_t)model->base.index_count * 4);
        mts_strips_free(&model->base);
        model->base = base;
    }
    if ((rc = copy_slots(&b, &model->full, err)) != MTS_OK)
        goto fail;

    mts_progress_report(progress, "records", 1.0);
    if (stats_out)
        *stats_out = st;
    builder_free(&b);
    mts_strips_free(&given);
    free(new_id);
    return MTS_OK;

nomem:
    rc = mts_error_set(err, MTS_ERR_NOMEM, "lodbuild: out of memory");
    goto fail;
fail_keep:
    rc = err ? err->code : MTS_ERR_NOMEM;
fail:
    builder_free(&b);
    mts_strips_free(&given);
    free(new_id);
    free(parents);
    mts_model_free(model);
    return rc;
}
