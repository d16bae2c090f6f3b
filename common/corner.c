/* The corner table (see corner.h for what it holds and why): built from the
 * base, split a split at a time, walked round a vertex and checked, and
 * grow.h's calls that only read it. */
#include "corner.h"

#include <stdlib.h>
#include <string.h>

#include "grow_internal.h"
#include "words.h"

/* the notation of grow_internal.h, short */
#define NONE MTS_GROW_NONE
#define NX mts__grow_nx
#define PV mts__grow_pv
#define TWIN MTS__GROW_TWIN

/* ---- triangles and vertices ---- */

/* The most triangles g may hold from here: a split adds at most two. It
 * only sizes the arrays' reservations (bigmem.h). */
static uint64_t tri_most(const mts_grow *g, uint32_t extra)
{
    return g->tri_count + (uint64_t)extra + (g->level < g->n ? 2ull * (g->n - g->level) : 0);
}

/* Room for the per-triangle arrays: cache-line aligned (two triangles a
 * line), and past 1 MB in a reservation on huge pages, grown in place
 * (bigmem.h): every walk round a vertex and along a strip lands somewhere
 * else in them, and a fresh client would otherwise fault in each doubling
 * anew. */
int mts__corner_tri_reserve(mts_grow *g, uint32_t extra)
{
    if (g->tri_count + (uint64_t)extra <= g->tri_cap)
        return 1;
    if (g->tri_count + (uint64_t)extra > (uint32_t)INT32_MAX / 2)
        return 0;
    uint32_t cap = g->tri_cap ? g->tri_cap : 64;
    while (cap < g->tri_count + extra)
        cap *= 2;
    const uint64_t most = tri_most(g, extra);
    g->tri_mem.align = 64;
    const int ok = mts_bigmem_room(&g->tri_mem, (size_t)cap * sizeof *g->tri,
                                   (size_t)g->tri_count * sizeof *g->tri,
                                   (size_t)most * sizeof *g->tri) &&
                   mts_bigmem_room(&g->prev_mem, (size_t)cap * 4, (size_t)g->tri_count * 4,
                                   (size_t)most * 4);
    g->tri = g->tri_mem.p;
    g->prev = g->prev_mem.p;
    if (!ok)
        return 0;
    const size_t room = g->tri_mem.room / sizeof *g->tri < g->prev_mem.room / 4
                            ? g->tri_mem.room / sizeof *g->tri
                            : g->prev_mem.room / 4;
    g->tri_cap = room < (uint32_t)INT32_MAX / 2 ? (uint32_t)room : (uint32_t)INT32_MAX / 2;
    return 1;
}

int32_t mts__corner_tri_add(mts_grow *g, uint32_t a, uint32_t b, uint32_t c, int list)
{
    if (!mts__corner_tri_reserve(g, 1))
        return -1;
    uint32_t t = g->tri_count++;
    g->tri[t].v[0] = a;
    g->tri[t].v[1] = b;
    g->tri[t].v[2] = c;
    g->tri[t].nx = g->prev[t] = g->tri[t].slot = -1;
    for (uint32_t k = 0; k < 3; k++) {
        TWIN(g, 3 * t + k) = NONE;
        if (list)
            g->vhead[g->tri[t].v[k]] = 3 * t + k;
    }
    return (int32_t)t;
}

int mts__corner_vhead_reserve(mts_grow *g, uint32_t count)
{
    if (count <= g->vhead_room)
        return 1;
    uint64_t room = 2ull * g->vhead_room;
    if (room < count)
        room = count;
    if (room > (uint64_t)g->nb + g->n)
        room = (uint64_t)g->nb + g->n;
    if (room < count)
        return 0;
    uint32_t *h = realloc(g->vhead, (size_t)room * sizeof *h);
    if (!h)
        return 0;
    for (uint64_t x = g->vhead_room; x < room; x++)
        h[x] = NONE;
    g->vhead = h;
    g->vhead_room = (uint32_t)room;
    return 1;
}

/* ---- the index of every half-edge ---- */

static int cmp_key(const void *a, const void *b)
{
    const mts__corner_key *x = a, *y = b;
    if (x->key != y->key)
        return x->key < y->key ? -1 : 1;
    return x->h < y->h ? -1 : x->h > y->h;
}

/* Every half-edge sorted by (from, to): lookups of directed edges anywhere
 * in the mesh, for what is not a walk round one fan (pairing the base's
 * twins, adopting whole strips, checking).
 *
 * Sorted by a least-significant-digit radix sort, 16 bits a pass, stable
 * (so equal keys keep half-edge order) and skipping passes whose digit is
 * the same everywhere: the full level of a 1.2M-triangle mesh is 3.6M keys,
 * which qsort took seconds over. */
static mts__corner_key *he_index(const mts_grow *g)
{
    size_t m = 3 * (size_t)g->tri_count;
    mts__corner_key *k = malloc((m + 1) * sizeof *k), *tmp = malloc((m + 1) * sizeof *tmp);
    uint32_t *count = malloc(65537 * sizeof *count);
    if (!k || !tmp || !count) {
        free(k);
        free(tmp);
        free(count);
        return NULL;
    }
    uint64_t all_or = 0, all_and = ~(uint64_t)0;
    for (size_t h = 0; h < m; h++) {
        k[h].key =
            (uint64_t)mts__corner_from(g, (uint32_t)h) << 32 | mts__corner_to(g, (uint32_t)h);
        k[h].h = (uint32_t)h;
        all_or |= k[h].key;
        all_and &= k[h].key;
    }
    for (unsigned shift = 0; shift < 64; shift += 16) {
        if ((((all_or ^ all_and) >> shift) & 0xFFFF) == 0)
            continue; /* this digit never differs */
        memset(count, 0, 65537 * sizeof *count);
        for (size_t i = 0; i < m; i++)
            count[((k[i].key >> shift) & 0xFFFF) + 1]++;
        for (size_t d = 1; d <= 65536; d++)
            count[d] += count[d - 1];
        for (size_t i = 0; i < m; i++)
            tmp[count[(k[i].key >> shift) & 0xFFFF]++] = k[i];
        mts__corner_key *x = k;
        k = tmp;
        tmp = x;
    }
    free(tmp);
    free(count);
    return k;
}

/* The first entry of k (m of them) for a -> b, or m. */
static size_t he_index_find(const mts__corner_key *k, size_t m, uint32_t a, uint32_t b)
{
    uint64_t want = (uint64_t)a << 32 | b;
    size_t lo = 0, hi = m;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (k[mid].key < want)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo < m && k[lo].key == want ? lo : m;
}

mts_result mts__corner_twins_build(mts_grow *g, mts_error *err)
{
    size_t m = 3 * (size_t)g->tri_count;
    mts__corner_key *k = he_index(g);
    if (!k)
        return mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
    for (size_t i = 0; i + 1 < m; i++) {
        if (k[i].key == k[i + 1].key) {
            uint32_t a = (uint32_t)(k[i].key >> 32), b = (uint32_t)k[i].key;
            free(k);
            return mts_error_set(err, MTS_ERR_FORMAT,
                                 "grow: base edge (%u %u) is held by two triangles", a, b);
        }
    }
    for (size_t i = 0; i < m; i++) {
        size_t r = he_index_find(k, m, (uint32_t)k[i].key, (uint32_t)(k[i].key >> 32));
        TWIN(g, k[i].h) = r < m ? k[r].h : NONE;
    }
    free(k);
    return MTS_OK;
}

/* ---- finding ---- */

/* The half-edge a -> b in the fan of a's listed corner, or NONE: a vertex
 * of a manifold mesh has one fan, which is all growth makes. */
static uint32_t find_half_edge(const mts_grow *g, uint32_t a, uint32_t b)
{
    const uint32_t c0 = g->vhead[a];
    if (c0 == NONE)
        return NONE;
    uint32_t c = c0, steps = 0;
    do {
        if (mts__corner_to(g, c) == b)
            return c;
        c = mts__corner_fwd(g, c);
    } while (c != NONE && c != c0 && ++steps <= g->tri_count);
    if (c == c0)
        return NONE;
    for (c = mts__corner_back(g, c0), steps = 0; c != NONE && ++steps <= g->tri_count;
         c = mts__corner_back(g, c)) {
        if (mts__corner_to(g, c) == b)
            return c;
    }
    return NONE;
}

int32_t mts__corner_window_triangle(const mts_grow *g, int32_t prev, const uint32_t tri[3],
                                    mts__corner_key **ix)
{
    const size_t m = 3 * (size_t)g->tri_count;
    for (int e = 0; prev >= 0 && e < 3; e++) {
        uint32_t h = g->tri[prev].tw[e];
        if (h == NONE)
            continue;
        const uint32_t *v = g->tri[h / 3].v;
        int k = mts__corner_of(v, tri[0]);
        if (k >= 0 && v[NX[k]] == tri[1] && v[PV[k]] == tri[2])
            return (int32_t)(h / 3);
    }
    if (tri[0] < g->nb + g->level) {
        uint32_t h = find_half_edge(g, tri[0], tri[1]);
        if (h != NONE)
            return g->tri[h / 3].v[PV[h % 3]] == tri[2] ? (int32_t)(h / 3) : -1;
    }
    if (!*ix && !(*ix = he_index(g)))
        return -2;
    size_t i = he_index_find(*ix, m, tri[0], tri[1]);
    if (i == m)
        return -1;
    uint32_t t = (*ix)[i].h / 3;
    return mts__corner_third(g, t, tri[0], tri[1]) == tri[2] ? (int32_t)t : -1;
}

int32_t mts_grow_find(const mts_grow *g, uint32_t a, uint32_t b, uint32_t c)
{
    if (a >= g->nb + g->level)
        return -1;
    uint32_t h = find_half_edge(g, a, b);
    /* a vertex with more than one fan: the builder's rare explicit splits */
    for (uint32_t x = 0; h == NONE && x < 3 * g->tri_count; x++) {
        if (mts__corner_from(g, x) == a && mts__corner_to(g, x) == b)
            h = x;
    }
    if (h == NONE || g->tri[h / 3].v[PV[h % 3]] != c)
        return -1;
    return (int32_t)(h / 3);
}

void mts_grow_triangle(const mts_grow *g, uint32_t t, uint32_t out[3])
{
    memcpy(out, g->tri[t].v, 12);
}

/* ---- fans ---- */

int32_t mts_grow_fan(const mts_grow *g, uint32_t u, uint32_t left, uint32_t right, uint32_t *ids,
                     uint32_t cap)
{
    uint32_t count = 0;
    if (u >= g->nb + g->level)
        return -1;
    if (right != NONE) {
        /* forward from the corner whose out-edge is u -> right */
        uint32_t c = find_half_edge(g, u, right);
        if (c == NONE)
            return -1;
        for (;;) {
            if (count >= g->tri_count)
                return -1; /* went round without meeting left */
            if (count < cap)
                ids[count] = c / 3;
            count++;
            if (g->tri[c / 3].v[PV[c % 3]] == left)
                return (int32_t)count;
            c = mts__corner_fwd(g, c);
            if (c == NONE)
                return left == NONE ? (int32_t)count : -1;
        }
    }
    if (left == NONE)
        return -1;
    /* backward from the corner whose in-edge is left -> u, to the border */
    uint32_t h = find_half_edge(g, left, u);
    uint32_t c = h == NONE ? NONE : 3 * (h / 3) + NX[h % 3];
    while (c != NONE) {
        if (count >= g->tri_count)
            return -1;
        if (count < cap)
            ids[count] = c / 3;
        count++;
        c = mts__corner_back(g, c);
    }
    return count ? (int32_t)count : -1;
}

/* One step of ring()'s walk, forward or back from *end into `to` (the
 * other way holding `other_n`): 1 when it meets the other way's end, the
 * ring closed; 0 otherwise (*done at a border); -1 when out of room or
 * past as many corners as there are triangles. */
static inline int ring_step(const mts_grow *g, int forward, uint32_t *end, uint32_t other_end,
                            mts_words *to, size_t other_n, int *done)
{
    const uint32_t c = forward ? mts__corner_fwd(g, *end) : mts__corner_back(g, *end);
    if (c == other_end)
        return 1;
    if (c == NONE) {
        *done = 1;
        return 0;
    }
    if (to->n + other_n >= g->tri_count || (to->n == to->cap && !mts_words_reserve(to, 1)))
        return -1;
    to->w[to->n++] = *end = c;
    return 0;
}

/* The parent's corners in ring order (grow.h: from the border when it is on
 * one, else from its listed corner, turning as the fan does), of the
 * fan its first corner lies in; cached until the next split. -1 when they
 * do not form a simple fan.
 *
 * Each step round is a load whose address the step before gave, and on a
 * mesh past the caches each is a miss, so the walk goes both ways from the
 * listed corner at once, forward into `out` and backward into scratch:
 * two chains whose misses overlap, meeting half way round an inner vertex
 * (twins pair both ways, so a step back undoes a step forward). */
static int32_t ring(mts_grow *g, uint32_t u)
{
    if (g->ring_level == g->level + 1 && g->ring_u == u)
        return (int32_t)g->ring_count;
    g->ring_level = 0;
    if (u >= g->nb + g->level || g->vhead[u] == NONE)
        return -1;
    mts_words *out = &g->ring, *back = &g->scratch; /* scratch: free between splits */
    const uint32_t c0 = g->vhead[u];
    out->n = back->n = 0;
    if (!mts_words_reserve(out, 16) || !mts_words_reserve(back, 16))
        return -1;
    out->w[out->n++] = c0;
    /* fe, be: the last corner each way (be is c0 until a step back) */
    uint32_t fe = c0, be = c0;
    int fdone = 0, bdone = 0, r = 0;
    while (!r && !(fdone && bdone)) {
        if (!fdone)
            r = ring_step(g, 1, &fe, be, out, back->n, &fdone);
        if (!r && !bdone)
            r = ring_step(g, 0, &be, fe, back, out->n, &bdone);
    }
    if (r < 0)
        return -1;
    const int closed = r;
    /* closed: c0 .. forward, then the corners behind c0 farthest first;
     * on a border: those behind c0 farthest first, then c0 .. the border */
    const size_t ahead = out->n, behind = back->n;
    if (behind) {
        if (!mts_words_reserve(out, behind))
            return -1;
        uint32_t *w = out->w;
        if (!closed)
            memmove(w + behind, w, ahead * 4);
        uint32_t *to = closed ? w + ahead : w;
        for (size_t i = 0; i < behind; i++)
            to[i] = back->w[behind - 1 - i];
        out->n = ahead + behind;
    }
    g->ring_u = u;
    g->ring_count = (uint32_t)out->n;
    g->ring_closed = closed;
    g->ring_level = g->level + 1;
    return (int32_t)out->n;
}

/* The fan from u -> right round to left -> u as a stretch of u's ring:
 * *start and *count. 0 when it is not one (or would give v all of a closed
 * ring, which leaves left == right and two triangles on one edge). */
static int fan_segment(mts_grow *g, uint32_t u, uint32_t left, uint32_t right, uint32_t *start,
                       uint32_t *count)
{
    int32_t k = ring(g, u);
    if (k <= 0 || (left == NONE && right == NONE) || (left != NONE && left == right))
        return 0;
    const uint32_t K = (uint32_t)k, *r = g->ring.w;
    const int closed = g->ring_closed;
    uint32_t i = 0;
    if (right != NONE) {
        while (i < K && mts__corner_to(g, r[i]) != right)
            i++;
        if (i == K)
            return 0;
    } else if (closed) {
        return 0;
    }
    for (uint32_t j = 0; j < K; j++) {
        if (!closed && i + j >= K)
            break;
        if (left != NONE && g->tri[r[(i + j) % K] / 3].v[PV[r[(i + j) % K] % 3]] == left) {
            if (closed && j + 1 >= K)
                return 0;
            *start = i;
            *count = j + 1;
            return 1;
        }
    }
    if (left != NONE || closed)
        return 0;
    *start = i;
    *count = K - i;
    return 1;
}

int32_t mts_grow_ring_size(mts_grow *g, uint32_t u, int *closed)
{
    int32_t k = ring(g, u);
    *closed = k > 0 && g->ring_closed;
    return k;
}

int mts_grow_fan_encode(mts_grow *g, uint32_t u, uint32_t left, uint32_t right,
                        mts_grow_fan_code *code)
{
    uint32_t start, count;
    if (!fan_segment(g, u, left, right, &start, &count))
        return 0;
    code->start = start;
    code->count = count;
    code->sides = (right == NONE) | (left == NONE) << 1;
    uint32_t l2, r2;
    return mts_grow_fan_decode(g, u, code, &l2, &r2) && l2 == left && r2 == right;
}

int mts_grow_fan_decode(mts_grow *g, uint32_t u, const mts_grow_fan_code *code,
                        uint32_t *left, uint32_t *right)
{
    int32_t k = ring(g, u);
    if (k <= 0 || code->start >= (uint32_t)k || code->count == 0 ||
        code->count > (uint32_t)k || code->sides > 3)
        return 0;
    const uint32_t K = (uint32_t)k;
    const int closed = g->ring_closed;
    if (closed ? code->count >= K : code->start + code->count > K)
        return 0;
    /* a missing new triangle is a border the fan reaches */
    if ((code->sides & 1) && (closed || code->start != 0))
        return 0;
    if ((code->sides & 2) && (closed || code->start + code->count != K))
        return 0;
    uint32_t cf = g->ring.w[code->start], cl = g->ring.w[(code->start + code->count - 1) % K];
    *right = code->sides & 1 ? NONE : mts__corner_to(g, cf);
    *left = code->sides & 2 ? NONE : g->tri[cl / 3].v[PV[cl % 3]];
    return !(*left == NONE && *right == NONE) && !(*left != NONE && *left == *right);
}

/* ---- splits ---- */

/* Half-edge a's twin becomes b, and b's a (b may be NONE: a border). */
static inline void twin_pair(mts_grow *g, uint32_t a, uint32_t b)
{
    TWIN(g, a) = b;
    if (b != NONE)
        TWIN(g, b) = a;
}

/* An explicit split's twins: every half-edge of a moved or new triangle,
 * and those that were its twins, paired anew in one pass over the mesh
 * (explicit splits are the rare ones the fan rule misses, so O(triangles)
 * is fine), which also finds u a corner if it lost the one listed.
 * MTS_ERR_FORMAT when a directed edge ends up held twice. */
static mts_result twins_redo(mts_grow *g, uint32_t u, uint32_t first_new, mts_error *err)
{
    const size_t moved = g->affected.n, total = moved + (g->tri_count - first_new);
    mts__corner_key *k = malloc((3 * total + 1) * sizeof *k);
    if (!k)
        return mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
    size_t m = 0;
    for (size_t i = 0; i < total; i++) {
        uint32_t t = i < moved ? g->affected.w[i] : first_new + (uint32_t)(i - moved);
        for (uint32_t e = 0; e < 3; e++) {
            uint32_t h = 3 * t + e, o = TWIN(g, h);
            if (o != NONE && TWIN(g, o) == h)
                TWIN(g, o) = NONE;
            TWIN(g, h) = NONE;
            k[m].key = (uint64_t)mts__corner_from(g, h) << 32 | mts__corner_to(g, h);
            k[m++].h = h;
        }
    }
    qsort(k, m, sizeof *k, cmp_key);
    mts_result rc = MTS_OK;
    for (size_t i = 0; i + 1 < m && rc == MTS_OK; i++) {
        if (k[i].key == k[i + 1].key) /* two of them hold one directed edge */
            rc = MTS_ERR_FORMAT;
    }
    int lost_u = g->vhead[u] == NONE || mts__corner_from(g, g->vhead[u]) != u;
    if (lost_u)
        g->vhead[u] = NONE;
    for (uint32_t h = 0; h < 3 * g->tri_count && rc == MTS_OK; h++) {
        uint32_t a = mts__corner_from(g, h), b = mts__corner_to(g, h);
        if (lost_u && a == u) {
            g->vhead[u] = h;
            lost_u = 0;
        }
        size_t i = he_index_find(k, m, a, b);
        if (i < m && k[i].h != h) {
            rc = MTS_ERR_FORMAT; /* a moved or new edge that another triangle holds */
            break;
        }
        size_t r = he_index_find(k, m, b, a);
        if (r < m) {
            TWIN(g, h) = k[r].h;
            TWIN(g, k[r].h) = h;
        }
    }
    free(k);
    if (rc != MTS_OK)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "grow: split %u leaves a directed edge held by two triangles",
                             g->level);
    return MTS_OK;
}

mts_result mts__corner_split_corners(mts_grow *g, const mts_grow_split *sp, mts_error *err)
{
    const uint32_t u = sp->parent;
    g->affected.n = 0;
    uint32_t fs = 0, fc = 0;
    if (mts__corner_is_fan(sp)) {
        if (!fan_segment(g, u, sp->left, sp->right, &fs, &fc))
            return mts_error_set(err, MTS_ERR_FORMAT,
                                 "grow: split %u: no fan of %u from %u to %u", g->level, u,
                                 sp->right, sp->left);
        if (!mts_words_reserve(&g->affected, fc))
            goto nomem;
        for (uint32_t k = 0; k < fc; k++)
            g->affected.w[k] = g->ring.w[(fs + k) % g->ring_count]; /* corners for now */
        g->affected.n = fc;
    } else {
        if (!mts_words_reserve(&g->affected, sp->moved_count))
            goto nomem;
        for (uint32_t k = 0; k < sp->moved_count; k++) {
            uint32_t t = sp->moved[k];
            int c = t < g->tri_count ? mts__corner_of(g->tri[t].v, u) : -1;
            if (c < 0)
                return mts_error_set(err, MTS_ERR_FORMAT,
                                     "grow: split %u moves triangle %u, which has no corner %u",
                                     g->level, t, u);
            g->affected.w[k] = 3 * t + (uint32_t)c;
        }
        g->affected.n = sp->moved_count;
    }
    return MTS_OK;
nomem:
    return mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
}

mts_result mts__corner_split_apply(mts_grow *g, const mts_grow_split *sp, mts_error *err)
{
    const uint32_t v = g->nb + g->level, u = sp->parent;
    const int fan = mts__corner_is_fan(sp);
    /* the fan's two edges to the rest of u's ring, before they change */
    uint32_t hr = NONE, hl = NONE, opp_r = NONE, opp_l = NONE;
    if (fan) {
        uint32_t cr = g->affected.w[0], cl = g->affected.w[g->affected.n - 1];
        hr = cr;                        /* u -> right, becomes v -> right */
        hl = 3 * (cl / 3) + PV[cl % 3]; /* left -> u, becomes left -> v */
        opp_r = TWIN(g, hr);
        opp_l = TWIN(g, hl);
    }
    for (size_t k = 0; k < g->affected.n; k++) {
        uint32_t c = g->affected.w[k];
        if (g->tri[c / 3].v[c % 3] != u) /* an explicit split naming a triangle twice */
            return mts_error_set(err, MTS_ERR_FORMAT,
                                 "grow: split %u moves triangle %u twice", g->level, c / 3);
        g->tri[c / 3].v[c % 3] = v;
        g->affected.w[k] = c / 3;
        g->vhead[v] = c;
    }
    const uint32_t first_new = g->tri_count;
    if (fan) {
        int32_t nl = -1, nr = -1;
        if (sp->left != NONE && (nl = mts__corner_tri_add(g, u, v, sp->left, 0)) < 0)
            goto nomem;
        if (sp->right != NONE && (nr = mts__corner_tri_add(g, v, u, sp->right, 0)) < 0)
            goto nomem;
        /* u may have lent v its listed corner; left and right keep theirs */
        uint32_t nu = nr >= 0 ? 3 * (uint32_t)nr + 1 : 3 * (uint32_t)nl;
        g->vhead[u] = nu;
        g->vhead[v] = nr >= 0 ? 3 * (uint32_t)nr : 3 * (uint32_t)nl + 1;
        /* (u v left): v -> left meets the fan's left -> v, left -> u what
         * held u -> left; (v u right) likewise; u -> v meets v -> u */
        if (nl >= 0) {
            twin_pair(g, 3 * (uint32_t)nl + 1, hl);
            twin_pair(g, 3 * (uint32_t)nl + 2, opp_l);
        }
        if (nr >= 0) {
            twin_pair(g, 3 * (uint32_t)nr + 2, hr);
            twin_pair(g, 3 * (uint32_t)nr + 1, opp_r);
        }
        if (nl >= 0 && nr >= 0)
            twin_pair(g, 3 * (uint32_t)nl, 3 * (uint32_t)nr);
    } else {
        for (uint32_t k = 0; k < sp->born_count; k++) {
            const uint32_t *t = sp->born + 3 * (size_t)k;
            if (t[0] > v || t[1] > v || t[2] > v || t[0] == t[1] || t[1] == t[2] || t[0] == t[2])
                return mts_error_set(err, MTS_ERR_FORMAT,
                                     "grow: split %u brings back (%u %u %u), not a triangle of "
                                     "level %u",
                                     g->level, t[0], t[1], t[2], g->level + 1);
            if (mts__corner_tri_add(g, t[0], t[1], t[2], 1) < 0)
                goto nomem;
        }
        mts_result rc = twins_redo(g, u, first_new, err);
        if (rc != MTS_OK)
            return rc;
    }
    g->born.n = 0;
    if (!mts_words_reserve(&g->born, g->tri_count - first_new))
        goto nomem;
    for (uint32_t f = first_new; f < g->tri_count; f++)
        g->born.w[g->born.n++] = f;
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
    size_t want = 2 * (g->affected.n + g->born.n);
    if (!mts_words_reserve(&g->around, want))
        return mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
    uint32_t *out = g->around.w, n = 0;
    /* the moved triangles and, of the new ones, those with a corner v (an
     * explicit split may bring back others); each triangle's two other
     * corners in its own order after v, so (v, a, b) is the triangle as
     * drawn and its normal is (a - v) x (b - v) */
    for (size_t k = 0, total = g->affected.n + g->born.n; k < total; k++) {
        uint32_t t = k < g->affected.n ? g->affected.w[k] : g->born.w[k - g->affected.n];
        const uint32_t *c = g->tri[t].v;
        int at = mts__corner_of(c, v);
        if (at < 0)
            continue;
        out[n++] = c[NX[at]];
        out[n++] = c[PV[at]];
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
        sp->left = sp->right = NONE;
        sp->moved_count = w[3];
        sp->born_count = w[4];
        sp->moved = w + 5;
        sp->born = w + 5 + w[3];
        return sp->moved_count || sp->born_count;
    }
    mts_grow_fan_code code = {w[0], w[1], w[2]};
    return len == 3 && mts_grow_fan_decode(g, sp->parent, &code, &sp->left, &sp->right);
}

/* ---- renumbering ---- */

int mts__corner_renumber(mts_grow *g, const uint32_t *perm)
{
    /* into the array the last key's renumbering left behind where that is a
     * reservation, which keeps its pages */
    g->spare_mem.align = 64;
    if (!mts_bigmem_room(&g->spare_mem, (size_t)g->tri_cap * sizeof *g->tri, 0,
                         (size_t)tri_most(g, 0) * sizeof *g->tri))
        return 0;
    mts__grow_tri *nt = g->spare_mem.p;
    for (uint32_t t = 0; t < g->tri_count; t++) {
        mts__grow_tri *x = &nt[perm[t]];
        const mts__grow_tri *o = &g->tri[t];
        for (int e = 0; e < 3; e++) {
            uint32_t h = o->tw[e];
            x->v[e] = o->v[e];
            x->tw[e] = h == NONE ? NONE : 3 * perm[h / 3] + h % 3;
        }
        x->nx = x->slot = -1;
    }
    mts_bigmem_swap(&g->tri_mem, &g->spare_mem);
    g->tri = nt;
    /* a small array goes back to malloc, which hands its lines to the next
     * one; a reservation stays for the next key */
    if (!g->spare_mem.reserved)
        mts_bigmem_free(&g->spare_mem);
    for (size_t x = 0; x < (size_t)g->nb + g->level; x++) {
        uint32_t c = g->vhead[x];
        if (c != NONE)
            g->vhead[x] = 3 * perm[c / 3] + c % 3;
    }
    for (size_t k = 0; k < g->affected.n; k++)
        g->affected.w[k] = perm[g->affected.w[k]];
    for (size_t k = 0; k < g->born.n; k++)
        g->born.w[k] = perm[g->born.w[k]];
    g->ring_level = 0;
    return 1;
}

/* ---- checking ---- */

mts_result mts__corner_check(const mts_grow *g, mts_error *err)
{
    const uint32_t nv = g->nb + g->level, nh = 3 * g->tri_count;
    mts_result rc = MTS_OK;
    mts__corner_key *ix = he_index(g);
    uint8_t *has = calloc((size_t)nv + 1, 1);
    if (!ix || !has) {
        free(ix);
        free(has);
        return mts_error_set(err, MTS_ERR_NOMEM, "grow check: out of memory");
    }
    for (uint32_t h = 0; h < nh && rc == MTS_OK; h++) {
        uint32_t a = mts__corner_from(g, h), b = mts__corner_to(g, h), o = TWIN(g, h);
        size_t i = he_index_find(ix, nh, a, b);
        size_t r = he_index_find(ix, nh, b, a);
        uint32_t want = r < nh ? ix[r].h : NONE;
        if (a >= nv)
            rc = mts_error_set(err, MTS_ERR_INTERNAL, "grow check: vertex %u at level %u", a,
                               g->level);
        else if (i + 1 < nh && ix[i + 1].key == ix[i].key)
            rc = mts_error_set(err, MTS_ERR_INTERNAL, "grow check: edge (%u %u) held twice", a,
                               b);
        else if (o != want)
            rc = mts_error_set(err, MTS_ERR_INTERNAL,
                               "grow check: half-edge %u (%u %u) has twin %u, not %u", h, a, b, o,
                               want);
        else
            has[a] = 1;
    }
    for (uint32_t x = 0; x < nv && rc == MTS_OK; x++) {
        uint32_t c = g->vhead[x];
        if (c == NONE ? has[x] : c >= nh || mts__corner_from(g, c) != x)
            rc = mts_error_set(err, MTS_ERR_INTERNAL, "grow check: vertex %u lists corner %u", x,
                               c);
    }
    free(ix);
    free(has);
    return rc;
}
