/* Strip growth from vertex splits (see grow.h for the why, lodbuild.h for
 * the growth rules and the measurements behind key levels).
 *
 * Every client runs this on every split it receives, so a split must cost
 * about what it changes, not what the strips it touches hold:
 *  - the mesh is a corner table in flat arrays: per half-edge (3t + e, from
 *    corner e of triangle t to corner e + 1) its twin, and per vertex one of
 *    its corners. A fan split relabels the fan's corners and links two new
 *    triangles in with O(1) twin updates; walking round a vertex is a twin
 *    step, never a lookup (hash maps cost a client far more:
 *    docs/client-cost.md). Only what is not a walk round one fan -- the
 *    base, whole strips adopted, the rare explicit split -- sorts or scans
 *    the half-edges.
 *  - the strips are paths on the dual graph (next/prev per triangle, one
 *    path per slot), and each slot keeps its indices as last derived. A
 *    split only changes a slot's indices in the stretch where the path runs
 *    past the parent u -- from the first triangle with corner u to the
 *    first one after the last -- so that stretch is found in the old indices
 *    (the first and last u), re-derived from the path, and spliced in
 *    (local_region). Whatever does not fit that pattern (a slot given new
 *    content, a key level) is derived whole; both give the same indices,
 *    which mts_grow_check verifies.
 *  - a key level restripifies every live triangle with greedy.c, which
 *    reads the twins directly.
 * The record of a split is, per slot it touched, the smallest edit from the
 * old indices to the new (emit_splice). */
#include "grow.h"

#include <stdlib.h>
#include <string.h>

#include "greedy.h"
#include "strips.h"
#include "words.h"

#define NONE MTS_GROW_NONE

static const uint8_t NX[3] = {1, 2, 0}, PV[3] = {2, 0, 1};

/* What a split and a derivation read of a triangle, in one place: a walk
 * along a path or round a vertex is a cache miss a triangle, not three. */
typedef struct grow_tri {
    uint32_t v[3];
    uint32_t tw[3]; /* per edge e: the twin half-edge, NONE at a border */
    int32_t nx;     /* the next on its strip's path, times 4, plus the edge
                     * to it (3: none found); -1 at the path's end */
    int32_t slot;   /* of its strip, -1 while unplaced */
} grow_tri;
/* two to a cache line; greedy.c reads tw straight from these records */
_Static_assert(sizeof(grow_tri) == 32, "grow_tri is half a cache line");
_Static_assert(MTS_GROW_NONE == MTS_GREEDY_NONE, "greedy.c reads grow.c's borders");

typedef struct grow_slot {
    mts_words seq;     /* indices as last derived */
    int32_t head;      /* first triangle of the path, -1 when empty */
    uint32_t ntri;     /* triangles on it */
    uint32_t stamp;    /* == stamp_now: touched by this split */
    uint32_t fresh;    /* == stamp_now: given other content (derived whole) */
    uint32_t relinked; /* == stamp_now: a link of its path changed */
    uint32_t capacity; /* longest it has been (g->capacity[s] too, for the figures;
                        * here a split reads it in the slot's cache line) */
} grow_slot;

/* The twin of half-edge h (3t + e, from corner e of t to corner e + 1). */
#define TWIN(g, h) ((g)->tri[(h) / 3].tw[(h) % 3])

struct mts_grow {
    uint32_t nb, n, level;
    /* triangles, all live */
    uint32_t tri_count, tri_cap;
    grow_tri *tri;   /* 64-byte aligned: two to a cache line */
    int32_t *prev;   /* each triangle's previous on its path (read far less) */
    uint32_t *vhead; /* per vertex: a corner of it, NONE when it has none */
    uint32_t vhead_room; /* vertices vhead holds: grown as splits bring them */
    /* slots */
    uint32_t slot_count, slot_cap;
    grow_slot *slot;
    uint32_t *capacity; /* the slots' capacities again, as figures give them */
    uint32_t *free_slots, free_count;
    uint32_t stamp_now, *touched, touched_count;
    uint64_t total_indices;
    uint32_t nonempty;
    /* keys */
    const uint32_t *key_given;
    uint32_t key_given_count, key_given_at;
    double key_ratio, key_quality, key_min_ratio;
    uint32_t key_triangles; /* at the last key */
    mts_words keys;
    /* the last record, and scratch */
    mts_words rec, scratch;
    mts_words affected; /* the triangles the last split moved */
    mts_words cand;     /* pairs: the parent's corners before the split, the old next */
    mts_words ring;     /* corners of ring_u in ring order, valid at ring_level */
    uint32_t ring_u, ring_level, ring_count;
    int ring_closed;
    mts_words born;       /* the triangles the last split brought back */
    mts_words around;     /* scratch of mts_grow_around_newest */
    mts_grow_figures fig;
};

/* ---- the corner table ---- */

static inline uint32_t he_from(const mts_grow *g, uint32_t h)
{
    return g->tri[h / 3].v[h % 3];
}

static inline uint32_t he_to(const mts_grow *g, uint32_t h)
{
    return g->tri[h / 3].v[NX[h % 3]];
}

static inline int corner_of(const uint32_t *t, uint32_t x)
{
    return t[0] == x ? 0 : t[1] == x ? 1 : t[2] == x ? 2 : -1;
}

/* Walking round a vertex: crossing a corner's out-edge (u -> a) backwards
 * lands on the corner of u in the triangle holding a -> u, crossing its
 * in-edge (b -> u) forwards on the one holding u -> b (a corner is also the
 * half-edge it starts). */
static inline uint32_t corner_back(const mts_grow *g, uint32_t c)
{
    uint32_t h = TWIN(g, c);
    return h == NONE ? NONE : 3 * (h / 3) + NX[h % 3];
}

static inline uint32_t corner_fwd(const mts_grow *g, uint32_t c)
{
    return TWIN(g, 3 * (c / 3) + PV[c % 3]);
}

/* The half-edge a -> b in the fan of a's listed corner, or NONE: a vertex
 * of a manifold mesh has one fan, which is all growth makes. */
static uint32_t find_half_edge(const mts_grow *g, uint32_t a, uint32_t b)
{
    const uint32_t c0 = g->vhead[a];
    if (c0 == NONE)
        return NONE;
    uint32_t c = c0, steps = 0;
    do {
        if (he_to(g, c) == b)
            return c;
        c = corner_fwd(g, c);
    } while (c != NONE && c != c0 && ++steps <= g->tri_count);
    if (c == c0)
        return NONE;
    for (c = corner_back(g, c0), steps = 0; c != NONE && ++steps <= g->tri_count;
         c = corner_back(g, c)) {
        if (he_to(g, c) == b)
            return c;
    }
    return NONE;
}

static inline int adjacent(const mts_grow *g, int32_t ta, int32_t tb)
{
    if (ta < 0 || tb < 0)
        return 0;
    const uint32_t *h = g->tri[ta].tw;
    uint32_t b = (uint32_t)tb;
    return (h[0] != NONE && h[0] / 3 == b) || (h[1] != NONE && h[1] / 3 == b) ||
           (h[2] != NONE && h[2] / 3 == b);
}

/* The edge of t that leads to its neighbour b (0..2), or 3. */
static inline unsigned edge_to(const mts_grow *g, uint32_t t, uint32_t b)
{
    const uint32_t *h = g->tri[t].tw;
    for (unsigned e = 0; e < 3; e++) {
        if (h[e] != NONE && h[e] / 3 == b)
            return e;
    }
    return 3;
}

/* Half-edge a's twin becomes b, and b's a (b may be NONE: a border). */
static inline void twin_pair(mts_grow *g, uint32_t a, uint32_t b)
{
    TWIN(g, a) = b;
    if (b != NONE)
        TWIN(g, b) = a;
}

static inline int32_t next_of(const mts_grow *g, int32_t t)
{
    return g->tri[t].nx < 0 ? -1 : g->tri[t].nx >> 2;
}

/* Links t to n (-1: t ends its path), noting the edge between them. */
static inline void set_next(mts_grow *g, int32_t t, int32_t n)
{
    g->tri[t].nx = n < 0 ? -1 : (int32_t)((uint32_t)n << 2 | edge_to(g, (uint32_t)t, (uint32_t)n));
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
    void *p;
    if (posix_memalign(&p, 64, (size_t)cap * sizeof *g->tri) != 0)
        return 0;
    if (g->tri_count)
        memcpy(p, g->tri, (size_t)g->tri_count * sizeof *g->tri);
    free(g->tri);
    g->tri = p;
    if (!(p = realloc(g->prev, (size_t)cap * 4)))
        return 0;
    g->prev = p;
    g->tri_cap = cap;
    return 1;
}

/* Adds a live triangle, its edges borders for now, and (with `list`) makes
 * it the listed corner of each of its vertices; -1 when out of memory. */
static int32_t tri_add(mts_grow *g, uint32_t a, uint32_t b, uint32_t c, int list)
{
    if (!tri_reserve(g, 1))
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

/* Room in vhead for `count` vertices. It grows with the splits applied,
 * not with the levels announced: a client's growth starts before it knows
 * how many will really come. */
static int vhead_reserve(mts_grow *g, uint32_t count)
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

/* Every half-edge sorted by (from, to): lookups of directed edges anywhere
 * in the mesh, for what is not a walk round one fan (pairing the base's
 * twins, adopting whole strips, checking). */
typedef struct he_key {
    uint64_t key;
    uint32_t h;
} he_key;

static int cmp_he_key(const void *a, const void *b)
{
    const he_key *x = a, *y = b;
    if (x->key != y->key)
        return x->key < y->key ? -1 : 1;
    return x->h < y->h ? -1 : x->h > y->h;
}

/* Sorted by a least-significant-digit radix sort, 16 bits a pass, stable
 * (so equal keys keep half-edge order) and skipping passes whose digit is
 * the same everywhere: the full level of a 1.2M-triangle mesh is 3.6M keys,
 * which qsort took seconds over. */
static he_key *he_index(const mts_grow *g)
{
    size_t m = 3 * (size_t)g->tri_count;
    he_key *k = malloc((m + 1) * sizeof *k), *tmp = malloc((m + 1) * sizeof *tmp);
    uint32_t *count = malloc(65537 * sizeof *count);
    if (!k || !tmp || !count) {
        free(k);
        free(tmp);
        free(count);
        return NULL;
    }
    uint64_t all_or = 0, all_and = ~(uint64_t)0;
    for (size_t h = 0; h < m; h++) {
        k[h].key = (uint64_t)he_from(g, (uint32_t)h) << 32 | he_to(g, (uint32_t)h);
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
        he_key *x = k;
        k = tmp;
        tmp = x;
    }
    free(tmp);
    free(count);
    return k;
}

/* The first entry of k (m of them) for a -> b, or m. */
static size_t he_index_find(const he_key *k, size_t m, uint32_t a, uint32_t b)
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

/* Pairs every half-edge with its reverse, all at once (the base). A
 * directed edge held twice is not a mesh growth can work on. */
static mts_result twins_build(mts_grow *g, mts_error *err)
{
    size_t m = 3 * (size_t)g->tri_count;
    he_key *k = he_index(g);
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

/* ---- deriving indices ---- */

static uint32_t third_vertex(const mts_grow *g, uint32_t t, uint32_t x, uint32_t y)
{
    const uint32_t *v = g->tri[t].v;
    return v[0] != x && v[0] != y ? v[0] : v[1] != x && v[1] != y ? v[1] : v[2];
}

/* Appends the indices of a path's triangles from t on (lodbuild.h): with
 * `first`, t starts the strip (its third vertex, then the edge it shares
 * with the next); otherwise (*a, *c) are the strip's last two indices, the
 * edge t is entered by, and t adds its third vertex, after a swap (a
 * repeated a) where the path turns the same way twice. Stops after `stop`
 * when it meets it (*met = 1), else at the path's end. (*a, *c) are the
 * last two indices after. */
static int derive_run(const mts_grow *g, int32_t t, int first, int32_t stop, uint32_t *a,
                      uint32_t *c, mts_words *out, int *met)
{
    *met = 0;
    if (t < 0)
        return 1;
    uint32_t hin = NONE; /* the half-edge t was entered by, once known */
    if (first) {
        if (!mts_words_reserve(out, 3))
            return 0;
        uint32_t *w = out->w + out->n;
        const grow_tri *x = &g->tri[t];
        unsigned e = x->nx >= 0 ? (unsigned)(x->nx & 3) : 3;
        if (e == 3) {
            w[0] = x->v[0];
            w[1] = x->v[1];
            w[2] = x->v[2];
        } else {
            w[0] = x->v[PV[e]];
            w[1] = x->v[e];
            w[2] = x->v[NX[e]];
            hin = x->tw[e];
        }
        out->n += 3;
        *a = w[1];
        *c = w[2];
        if (t == stop) {
            *met = 1;
            return 1;
        }
        t = next_of(g, t);
        if (t < 0)
            return 1;
    }
    /* a triangle adds at most 2; room for the path's slot's triangles at
     * once, more only if that ran out */
    int32_t sl = g->tri[t].slot;
    if (!mts_words_reserve(out, 2 * (size_t)(sl >= 0 ? g->slot[sl].ntri + 1 : 8)))
        return 0;
    uint32_t *o = out->w;
    size_t n = out->n;
    uint32_t ca = *a, cc = *c;
    while (t >= 0) {
        if (n + 2 > out->cap) {
            out->n = n;
            if (!mts_words_reserve(out, 2 * n + 2))
                return 0;
            o = out->w;
        }
        const grow_tri *x = &g->tri[t];
        /* its new index: the corner off the edge it was entered by */
        uint32_t w = hin != NONE && hin / 3 == (uint32_t)t ? x->v[PV[hin % 3]]
                                                            : third_vertex(g, (uint32_t)t, ca, cc);
        int32_t nx = x->nx < 0 ? -1 : x->nx >> 2;
        unsigned e = x->nx < 0 ? 3 : (unsigned)(x->nx & 3);
        int swap = 0;
        hin = NONE;
        if (e < 3) {
            uint32_t p = x->v[e], q = x->v[NX[e]];
            swap = p != cc && q != cc;
            hin = x->tw[e];
        }
        if (swap)
            o[n++] = ca; /* the path turns the same way again: a swap keeps a */
        else
            ca = cc;
        o[n++] = w;
        cc = w;
        if (t == stop) {
            *met = 1;
            break;
        }
        t = nx;
    }
    out->n = n;
    *a = ca;
    *c = cc;
    return 1;
}

static int derive_whole(const mts_grow *g, int32_t head, mts_words *out)
{
    uint32_t a, c;
    int met;
    out->n = 0;
    return derive_run(g, head, 1, -1, &a, &c, out, &met);
}

/* ---- slots and paths ---- */

static void touch(mts_grow *g, int32_t slot)
{
    if (slot < 0)
        return;
    if (g->slot[slot].stamp != g->stamp_now) {
        g->slot[slot].stamp = g->stamp_now;
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

/* A slot for new content: touched and fresh (derived whole). */
static int32_t slot_new(mts_grow *g)
{
    int32_t s;
    if (g->free_count) {
        s = (int32_t)g->free_slots[--g->free_count];
    } else {
        if (g->slot_count == g->slot_cap) {
            uint32_t old = g->slot_cap, cap = old ? old * 2 : 64;
            /* each array keeps its old block if its own growth fails */
            if (!grow_zeroed((void **)&g->slot, sizeof *g->slot, old, cap) ||
                !grow_zeroed((void **)&g->capacity, 4, old, cap) ||
                !grow_zeroed((void **)&g->free_slots, 4, old, cap) ||
                !grow_zeroed((void **)&g->touched, 4, old, cap))
                return -1;
            g->slot_cap = cap;
        }
        s = (int32_t)g->slot_count++;
    }
    g->slot[s].head = -1;
    g->slot[s].ntri = 0;
    g->slot[s].fresh = g->stamp_now;
    touch(g, s);
    return s;
}

static void slot_release(mts_grow *g, int32_t s)
{
    g->slot[s].head = -1;
    g->slot[s].ntri = 0;
    g->slot[s].fresh = g->stamp_now;
    touch(g, s);
    g->free_slots[g->free_count++] = (uint32_t)s;
}

/* Gives the path starting at t (and everything after it) the slot s. */
static uint32_t path_claim(mts_grow *g, int32_t t, int32_t s)
{
    uint32_t count = 0;
    for (; t >= 0; t = next_of(g, t)) {
        g->tri[t].slot = s;
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
        if (g->tri[f].slot >= 0 || !adjacent(g, a, (int32_t)f) || !adjacent(g, (int32_t)f, c))
            continue;
        int32_t s = g->tri[a].slot;
        set_next(g, a, (int32_t)f);
        g->prev[f] = a;
        set_next(g, f, c);
        g->prev[c] = (int32_t)f;
        g->tri[f].slot = s;
        g->slot[s].ntri++;
        g->slot[s].relinked = g->stamp_now;
        g->fig.grown_inserted++;
        return 1;
    }
    int32_t s = g->tri[a].slot;
    int32_t ns = slot_new(g);
    if (ns < 0)
        return 0;
    set_next(g, a, -1);
    g->prev[c] = -1;
    g->slot[ns].head = c;
    g->slot[ns].ntri = path_claim(g, c, ns);
    g->slot[s].ntri -= g->slot[ns].ntri;
    g->slot[s].relinked = g->stamp_now;
    g->fig.strips_cut++;
    return 1;
}

/* Places a new triangle no strip crossed into: after a strip that ends next
 * to it, before one that starts next to it, both (joining them), or alone. */
static int place_newborn(mts_grow *g, int32_t f)
{
    int32_t nbr[3];
    for (int c = 0; c < 3; c++) {
        uint32_t h = TWIN(g, 3 * (size_t)f + c);
        int32_t x = h == NONE ? -1 : (int32_t)(h / 3);
        nbr[c] = x >= 0 && x != f && g->tri[x].slot >= 0 ? x : -1;
    }
    int32_t tail = -1, head = -1;
    for (int c = 0; c < 3 && tail < 0; c++) {
        int32_t h = nbr[c];
        if (h >= 0 && next_of(g, h) < 0 && g->slot[g->tri[h].slot].ntri < GROW_MAX_PATH)
            tail = h;
    }
    for (int c = 0; c < 3 && head < 0; c++) {
        int32_t h = nbr[c];
        if (h < 0 || h == tail || g->slot[g->tri[h].slot].head != h ||
            g->slot[g->tri[h].slot].ntri >= GROW_MAX_PATH)
            continue;
        if (tail >= 0 && (g->tri[h].slot == g->tri[tail].slot ||
                          g->slot[g->tri[h].slot].ntri + g->slot[g->tri[tail].slot].ntri >= GROW_MAX_PATH))
            continue; /* would close a loop, or make too long a strip */
        head = h;
    }
    if (tail >= 0 && head >= 0) {
        int32_t s = g->tri[tail].slot, gone = g->tri[head].slot;
        set_next(g, tail, f);
        g->prev[f] = tail;
        set_next(g, f, head);
        g->prev[head] = f;
        g->tri[f].slot = s;
        g->slot[s].ntri += 1 + path_claim(g, head, s);
        slot_release(g, gone);
        g->fig.grown_joined++;
    } else if (tail >= 0) {
        int32_t s = g->tri[tail].slot;
        set_next(g, tail, f);
        g->prev[f] = tail;
        g->tri[f].slot = s;
        g->slot[s].ntri++;
        g->fig.grown_appended++;
    } else if (head >= 0) {
        int32_t s = g->tri[head].slot;
        set_next(g, f, head);
        g->prev[head] = f;
        g->tri[f].slot = s;
        g->slot[s].head = f;
        g->slot[s].ntri++;
        g->fig.grown_appended++;
    } else {
        int32_t s = slot_new(g);
        if (s < 0)
            return 0;
        g->slot[s].head = f;
        g->slot[s].ntri = 1;
        g->tri[f].slot = s;
        g->fig.grown_alone++;
    }
    touch(g, g->tri[f].slot);
    g->slot[g->tri[f].slot].relinked = g->stamp_now;
    return 1;
}

/* Empties every path and slot: all of them touched and fresh, room for at
 * least `slots`. */
static int paths_reset(mts_grow *g, uint32_t slots)
{
    while (g->slot_count < slots) {
        if (slot_new(g) < 0)
            return 0;
    }
    for (uint32_t s = 0; s < g->slot_count; s++) {
        g->slot[s].head = -1;
        g->slot[s].ntri = 0;
        g->slot[s].fresh = g->stamp_now;
        touch(g, (int32_t)s);
    }
    for (uint32_t t = 0; t < g->tri_count; t++) {
        g->tri[t].nx = g->prev[t] = -1;
        g->tri[t].slot = -1;
    }
    g->free_count = 0;
    return 1;
}

/* Frees the slots from `used` on and the empty ones below it. */
static void slots_free_unused(mts_grow *g, uint32_t used)
{
    g->free_count = 0;
    for (uint32_t s = g->slot_count; s-- > 0;) {
        if (s >= used || g->slot[s].head < 0)
            g->free_slots[g->free_count++] = s;
    }
}

/* Turns strips over live triangles into paths. Lenient (the builder's full
 * level): paths go into slots 0.. in order, a strip whose windows do not
 * chain is split over several slots, and every other slot is left empty
 * and free. Strict (a base): slot s gets strip s, which must be one path. */
/* The live triangle a window (oriented as drawn) is: a neighbour of the
 * previous window's (a strip that chains), else found round its first
 * vertex, else (a vertex of several fans) in a sorted index of every
 * half-edge, made the first time one is needed. -1: none; -2: no memory. */
static int32_t window_triangle(const mts_grow *g, int32_t prev, const uint32_t tri[3],
                               he_key **ix)
{
    const size_t m = 3 * (size_t)g->tri_count;
    for (int e = 0; prev >= 0 && e < 3; e++) {
        uint32_t h = g->tri[prev].tw[e];
        if (h == NONE)
            continue;
        const uint32_t *v = g->tri[h / 3].v;
        int k = corner_of(v, tri[0]);
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
    return third_vertex(g, t, tri[0], tri[1]) == tri[2] ? (int32_t)t : -1;
}

static mts_result adopt_strips(mts_grow *g, const mts_strips *strips, int strict, mts_error *err)
{
    he_key *ix = NULL;
    if (!paths_reset(g, strips->strip_count))
        return mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
    mts_result rc = MTS_OK;
    uint32_t used = 0;
    for (uint32_t k = 0; k < strips->strip_count; k++) {
        const uint32_t *str = strips->indices + strips->offsets[k];
        uint32_t len = strips->offsets[k + 1] - strips->offsets[k];
        int32_t prev = -1, s = strict ? (int32_t)k : -1;
        for (uint32_t w = 0; w + 2 < len; w++) {
            uint32_t tri[3];
            if (!mts_strip_window(str, w, tri))
                continue;
            int32_t t = window_triangle(g, prev, tri, &ix);
            if (t == -2) {
                rc = mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
                goto done;
            }
            if (t < 0) {
                rc = mts_error_set(err, MTS_ERR_FORMAT,
                                   "grow: strip %u draws (%u %u %u), not a triangle of level %u",
                                   k, tri[0], tri[1], tri[2], g->level);
                goto done;
            }
            if (g->tri[t].slot >= 0) {
                rc = mts_error_set(err, MTS_ERR_FORMAT,
                                   "grow: strip %u draws triangle (%u %u %u) a second time", k,
                                   tri[0], tri[1], tri[2]);
                goto done;
            }
            if (prev >= 0 && adjacent(g, prev, t)) {
                set_next(g, prev, t);
                g->prev[t] = prev;
            } else if (prev >= 0 && strict) {
                rc = mts_error_set(err, MTS_ERR_FORMAT,
                                   "grow: strip %u breaks at window %u (not one path)", k, w);
                goto done;
            } else {
                if (!strict) {
                    if (used == g->slot_count && slot_new(g) < 0) {
                        rc = mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
                        goto done;
                    }
                    s = (int32_t)used++;
                }
                g->slot[s].head = t;
                touch(g, s);
            }
            g->tri[t].slot = s;
            g->slot[s].ntri++;
            prev = t;
        }
    }
    slots_free_unused(g, strict ? strips->strip_count : used);
done:
    free(ix);
    return rc;
}

/* Sorts ids by key[id], largest first, ties by position: stable, so
 * deterministic. A counting sort while the keys are small (they are strip
 * lengths, every key level sorts every slot twice), else a merge sort. */
static int sort_desc(uint32_t *ids, uint32_t n, const uint32_t *key)
{
    uint32_t top = 0;
    for (uint32_t i = 0; i < n; i++)
        top = key[ids[i]] > top ? key[ids[i]] : top;
    uint32_t *tmp = malloc(((size_t)n + 1) * 4);
    if (!tmp)
        return 0;
    if (top < 4 * (n + 1024)) {
        uint32_t *at = calloc((size_t)top + 2, 4);
        if (!at) {
            free(tmp);
            return 0;
        }
        for (uint32_t i = 0; i < n; i++)
            at[top - key[ids[i]] + 1]++;
        for (uint32_t k = 1; k <= top + 1; k++)
            at[k] += at[k - 1];
        for (uint32_t i = 0; i < n; i++)
            tmp[at[top - key[ids[i]]]++] = ids[i];
        free(at);
        memcpy(ids, tmp, (size_t)n * 4);
        free(tmp);
        return 1;
    }
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
            head[s] = g->slot[s].head;
            ntri[s] = g->slot[s].ntri;
        }
        ok = sort_desc(paths, n, ntri) && sort_desc(slots, n, g->capacity);
    }
    if (ok) {
        for (uint32_t k = 0; k < n; k++) {
            uint32_t s = slots[k];
            g->slot[s].head = head[paths[k]];
            g->slot[s].ntri = ntri[paths[k]];
            path_claim(g, g->slot[s].head, (int32_t)s);
        }
        slots_free_unused(g, n);
    }
    free(paths);
    free(slots);
    free(head);
    free(ntri);
    return ok;
}

/* Gives every triangle a new id, perm[old] (the paths are reset after: only
 * the mesh, the listed corners and the last split's triangles move). */
static int renumber(mts_grow *g, const uint32_t *perm)
{
    void *p;
    if (posix_memalign(&p, 64, (size_t)g->tri_cap * sizeof *g->tri) != 0)
        return 0;
    grow_tri *nt = p;
    for (uint32_t t = 0; t < g->tri_count; t++) {
        grow_tri *x = &nt[perm[t]];
        const grow_tri *o = &g->tri[t];
        for (int e = 0; e < 3; e++) {
            uint32_t h = o->tw[e];
            x->v[e] = o->v[e];
            x->tw[e] = h == NONE ? NONE : 3 * perm[h / 3] + h % 3;
        }
        x->nx = x->slot = -1;
    }
    free(g->tri);
    g->tri = nt;
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

/* Restripifies every live triangle (greedy.c, in id order) into the slots,
 * renumbering the triangles in the order the paths were made: strips lie
 * side by side there, so the triangles round a vertex, which every later
 * split walks, come to sit in a few cache lines, not one each. */
static mts_result restrip(mts_grow *g, mts_error *err)
{
    uint32_t n = g->tri_count, count = 0;
    uint32_t *order = malloc(((size_t)n + 1) * 4), *starts = malloc(((size_t)n + 2) * 4);
    mts_result rc = order && starts ? MTS_OK
                                    : mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
    if (rc == MTS_OK)
        rc = mts_greedy_paths(n, g->tri[0].tw, sizeof *g->tri / 4, MTS_STRIPIFY_MAX_STRIP, order,
                              starts, &count, err);
    if (rc == MTS_OK) {
        uint32_t *perm = malloc(((size_t)n + 1) * 4);
        if (perm) {
            for (uint32_t i = 0; i < n; i++)
                perm[order[i]] = i;
        }
        if (!perm || !renumber(g, perm) || !paths_reset(g, count))
            rc = mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
        free(perm);
    }
    for (uint32_t k = 0; rc == MTS_OK && k < count; k++) {
        for (uint32_t i = starts[k]; i < starts[k + 1]; i++) {
            g->tri[i].slot = (int32_t)k;
            g->prev[i] = i > starts[k] ? (int32_t)i - 1 : -1;
            set_next(g, i, i + 1 < starts[k + 1] ? (int32_t)i + 1 : -1);
        }
        g->slot[k].head = (int32_t)starts[k];
        g->slot[k].ntri = starts[k + 1] - starts[k];
    }
    if (rc == MTS_OK) {
        slots_free_unused(g, count);
        if (!fit_slots(g))
            rc = mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
    }
    free(order);
    free(starts);
    return rc;
}

/* Walking a described strip: it entered triangle u across u's edge e
 * (corner e of u holds he_to of the edge it crossed), its last two indices
 * are (a, c), and w = u's third corner is the index u adds. It leaves
 * across the edge that keeps c (no swap) or a (a swap): the half-edge of u
 * it crosses next. */
static inline uint32_t full_exit(const mts_grow *g, uint32_t u, uint32_t e, uint32_t keep)
{
    unsigned ck = g->tri[u].v[e] == keep ? e : NX[e];
    return 3 * u + (NX[ck] == PV[e] ? ck : PV[e]);
}

/* Which exits of u are open (bit 0: no swap, bit 1: a swap): a border or a
 * triangle an earlier strip (or this one) holds is closed, so where only one
 * is open the swap bit is forced and the stream does not carry it. */
static inline unsigned full_open(const mts_grow *g, uint32_t u, uint32_t e, uint32_t a, uint32_t c,
                                 const uint8_t *claimed)
{
    unsigned open = 0;
    for (unsigned k = 0; k < 2; k++) {
        uint32_t x = TWIN(g, full_exit(g, u, e, k ? a : c));
        if (x != NONE && !claimed[x / 3])
            open |= 1u << k;
    }
    return open;
}

/* The triangles next to strip `prev` (given as its triangles in order) that
 * no strip holds yet: per triangle of it, across its edges 0, 1, 2, each
 * once. Where strips lie side by side, as tunnelled ones do, the next
 * strip often starts among them (grow.h, mts_grow_full_path.near). */
static int full_near(const mts_grow *g, const mts_words *prev, const uint8_t *claimed,
                     uint32_t *seen, uint32_t stamp, mts_words *out)
{
    out->n = 0;
    for (size_t k = 0; k < prev->n; k++) {
        const uint32_t *tw = g->tri[prev->w[k]].tw;
        for (unsigned e = 0; e < 3; e++) {
            const uint32_t x = tw[e] == NONE ? NONE : tw[e] / 3;
            if (x == NONE || claimed[x] || seen[x] == stamp)
                continue;
            seen[x] = stamp;
            if (!mts_words_reserve(out, 1))
                return 0;
            out->w[out->n++] = x;
        }
    }
    return 1;
}

/* Walks the described full strips over g's mesh (at the full level), slot
 * by slot, the one walk both ends make. A strip's start comes from f->paths
 * or, with f->start, from the source, handed the triangles next to the
 * strip before (full_near). Each inner triangle's swap bit is forced where
 * full_open leaves one exit; else it comes from f (the array, or the
 * source, which is handed the bit before as context). With `describe`
 * (f->paths itself, for an encoder), each path's near fields are set and
 * each swap byte in f->swaps marked forced (bit 1); with `resolve` (g
 * itself), the paths become g's. */
static mts_result full_walk(const mts_grow *g, mts_grow *resolve, const mts_grow_full *f,
                            mts_grow_full_path *describe, mts_error *err)
{
    uint8_t *claimed = calloc((size_t)g->tri_count + 1, 1);
    uint32_t *seen = calloc((size_t)g->tri_count + 1, 4);
    mts_words prev = {0}, cur = {0}, near = {0};
    mts_result rc = claimed && seen ? MTS_OK
                                    : mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
    uint8_t *mark = describe ? (uint8_t *)f->swaps : NULL;
    uint64_t bit = 0;
    unsigned last = 0;
    for (uint32_t s = 0, stamp = 1; s < f->slot_count && rc == MTS_OK; s++) {
        const mts_grow_full_path *p = &f->paths[s];
        if (!p->triangles)
            continue;
        if ((f->start || describe) && !full_near(g, &prev, claimed, seen, stamp++, &near)) {
            rc = mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
            break;
        }
        uint32_t t = p->first, r = p->rotation;
        if (f->start && !f->start(f->user, near.w, (uint32_t)near.n, &t, &r)) {
            rc = mts_error_set(err, MTS_ERR_FORMAT, "full strips: strip %u's start is malformed",
                               s);
            break;
        }
        if (t >= g->tri_count || r > 2 || claimed[t]) {
            rc = mts_error_set(err, MTS_ERR_FORMAT,
                               "full strips: strip %u starts at corner %u of triangle %u, which "
                               "is none of the %u or one a strip holds",
                               s, r, t, g->tri_count);
            break;
        }
        if (describe) {
            describe[s].near = NONE;
            describe[s].near_count = (uint32_t)near.n;
            for (uint32_t k = 0; k < near.n && describe[s].near == NONE; k++)
                describe[s].near = near.w[k] == t ? k : NONE;
        }
        claimed[t] = 1;
        cur.n = 0;
        if (!mts_words_reserve(&cur, p->triangles)) {
            rc = mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
            break;
        }
        cur.w[cur.n++] = t;
        if (resolve) {
            resolve->slot[s].head = (int32_t)t;
            resolve->tri[t].slot = (int32_t)s;
            resolve->slot[s].ntri = 1;
        }
        /* the strip's last two indices (a, c) and the half-edge between them */
        uint32_t a = g->tri[t].v[NX[r]], c = g->tri[t].v[PV[r]], h = 3 * t + NX[r];
        for (uint32_t i = 1; i < p->triangles; i++) {
            uint32_t o = TWIN(g, h);
            if (o == NONE) {
                rc = mts_error_set(err, MTS_ERR_FORMAT,
                                   "full strips: strip %u runs off the mesh at triangle %u", s, i);
                break;
            }
            uint32_t u = o / 3, e = o % 3;
            if (claimed[u]) {
                rc = mts_error_set(err, MTS_ERR_FORMAT,
                                   "full strips: strip %u crosses into triangle %u, which a strip "
                                   "holds",
                                   s, u);
                break;
            }
            claimed[u] = 1;
            cur.w[cur.n++] = u;
            if (resolve) {
                set_next(resolve, t, (int32_t)u);
                resolve->prev[u] = (int32_t)t;
                resolve->tri[u].slot = (int32_t)s;
                resolve->slot[s].ntri++;
            }
            uint32_t w = g->tri[u].v[PV[e]];
            int swap = 0;
            if (i + 1 < p->triangles) {
                const unsigned open = full_open(g, u, e, a, c, claimed);
                if (open == 0) {
                    rc = mts_error_set(err, MTS_ERR_FORMAT,
                                       "full strips: strip %u ends at triangle %u of %u, every "
                                       "way on closed",
                                       s, i, p->triangles);
                    break;
                }
                if (f->swaps && bit >= f->swap_count) {
                    rc = mts_error_set(err, MTS_ERR_FORMAT,
                                       "full strips: more inner triangles than %llu swap bits",
                                       (unsigned long long)f->swap_count);
                    break;
                }
                if (open != 3)
                    swap = open == 2;
                else
                    swap = f->swaps ? (f->swaps[bit] & 1) != 0 : f->swap_bit(f->user, last) != 0;
                if (mark)
                    mark[bit] = (uint8_t)((mark[bit] & 1) | (open != 3) << 1);
                bit++;
                last = (unsigned)swap;
            }
            h = full_exit(g, u, e, swap ? a : c);
            if (swap) {
                c = w;
            } else {
                a = c;
                c = w;
            }
            t = u;
        }
        mts_words x = prev;
        prev = cur;
        cur = x;
    }
    if (rc == MTS_OK && f->swaps && bit != f->swap_count)
        rc = mts_error_set(err, MTS_ERR_FORMAT, "full strips: %llu swap bits for %llu",
                           (unsigned long long)f->swap_count, (unsigned long long)bit);
    free(claimed);
    free(seen);
    free(prev.w);
    free(cur.w);
    free(near.w);
    return rc;
}

/* Resolves a description of the full strips (mts_grow_full_describe) on
 * the current (full) mesh straight into paths, slot by slot: each strip
 * leaves a triangle across the edge of its last two indices, and a swap
 * bit says which of them stays. */
static mts_result resolve_full(mts_grow *g, const mts_grow_full *f, mts_error *err)
{
    uint64_t tris = 0;
    for (uint32_t s = 0; s < f->slot_count; s++)
        tris += f->paths[s].triangles;
    if (tris > g->tri_count)
        return mts_error_set(err, MTS_ERR_FORMAT, "full strips: %llu triangles of %u",
                             (unsigned long long)tris, g->tri_count);
    if (!f->swaps && !f->swap_bit)
        return mts_error_set(err, MTS_ERR_ARG, "full strips: no swap bits");
    if (!paths_reset(g, f->slot_count))
        return mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
    mts_result rc = full_walk(g, g, f, NULL, err);
    if (rc == MTS_OK)
        slots_free_unused(g, f->slot_count);
    return rc;
}

/* ---- records ---- */

/* A slot's new indices: old[0..p0) + r + old[p1..) when `suffix`, else
 * old[0..p0) + r. */
typedef struct splice {
    uint32_t p0, p1;
    int suffix;
    const mts_words *r;
} splice;

/* Appends the edit that turns slot s's stored indices into the spliced ones
 * (in which the new vertex v appears; u is its parent), and stores them.
 * The runs carry u where the new indices have v, and the positions of v are
 * substitutions, so an inserted run never names a vertex that does not
 * exist yet. Outside the splice nothing changed and v cannot appear, so the
 * common prefix and suffix are sought from its edges. The new indices are
 * three pieces -- old[0..p0), r, old[p1..) -- each compared and copied as a
 * piece: a split emits a few edits, a key level one per slot, and this is
 * where a key level's indices all pass. */
static int emit_splice(mts_grow *g, uint32_t s, const splice *sp, uint32_t u, uint32_t v,
                       uint32_t *edits)
{
    mts_words *from = &g->slot[s].seq;
    const uint32_t *o = from->w, *r = sp->r->w;
    const size_t lo = from->n, rn = sp->r->n, keep = sp->suffix ? lo - sp->p1 : 0,
                 p0 = sp->p0, end = p0 + rn, ln = end + keep;
    /* new[end + i] = tail[i]; a slot never filled has no array at all */
    const uint32_t *tail = o ? o + (sp->suffix ? sp->p1 : lo) : o;
#define AS_BEFORE(x) ((x) == v ? u : (x))
    /* common prefix: new[0..p0) is old's own */
    size_t p = p0;
    while (p < end && p < lo && o[p] == AS_BEFORE(r[p - p0]))
        p++;
    if (p == end) {
        if (keep && end == sp->p1)
            p = lo; /* only substitutions: the kept tail is the same too */
        else
            while (p < lo && p < ln && o[p] == tail[p - end])
                p++;
    }
    /* common suffix, within what the prefix left: the kept tail is old's own */
    const size_t room = (lo < ln ? lo : ln) - p;
    size_t q = keep < room ? keep : room;
    while (q < room && ln - 1 - q >= end && o[lo - 1 - q] == tail[ln - 1 - q - end])
        q++;
    /* then r (the prefix reaches p0 at least, so the suffix stays in r) */
    while (q < room && o[lo - 1 - q] == AS_BEFORE(r[ln - 1 - q - p0]))
        q++;
    const size_t erase = lo - p - q, insert = ln - p - q;
    /* the record at most holds every position of r as a substitution */
    if (!mts_words_reserve(&g->rec, 4 + 2 + erase + 2 + insert + rn))
        return 0;
    uint32_t *w0 = g->rec.w + g->rec.n, *w = w0 + 4;
    if (erase) {
        *w++ = (uint32_t)p;
        *w++ = (uint32_t)erase;
        memcpy(w, o + p, erase * 4);
        w += erase;
    }
    if (insert) {
        *w++ = (uint32_t)p;
        *w++ = (uint32_t)insert;
        /* new[p..ln-q): its part in r mapped back to u, then the kept tail */
        size_t k = p, stop = ln - q;
        for (; k < stop && k < end; k++)
            *w++ = AS_BEFORE(r[k - p0]);
        if (k < stop) {
            memcpy(w, tail + (k - end), (stop - k) * 4);
            w += stop - k;
        }
    }
    uint32_t *subst = w;
    for (size_t k = 0; k < rn; k++) {
        *w = (uint32_t)(p0 + k);
        w += r[k] == v;
    }
#undef AS_BEFORE
    const size_t substs = (size_t)(w - subst);
    if (erase == 0 && insert == 0 && substs == 0)
        return 1;
    w0[0] = s;
    w0[1] = erase > 0;
    w0[2] = insert > 0;
    w0[3] = (uint32_t)substs;
    g->rec.n = (size_t)(w - g->rec.w);
    (*edits)++;
    g->fig.edits++;
    g->fig.erased_indices += erase;
    g->fig.inserted_indices += insert;
    g->fig.substitutions += substs;
    g->total_indices = g->total_indices - lo + ln;
    g->nonempty = g->nonempty - (lo > 0) + (ln > 0);
    /* the splice in place: the kept tail moves, the new run goes in */
    if (ln > lo && !mts_words_reserve(from, ln - lo))
        return 0;
    uint32_t *x = from->w;
    if (keep)
        memmove(x + end, x + sp->p1, keep * 4);
    if (rn)
        memcpy(x + p0, r, rn * 4);
    from->n = ln;
    if (ln > g->slot[s].capacity)
        g->slot[s].capacity = g->capacity[s] = (uint32_t)ln;
    return 1;
}

/* The first and last position of x in a[0..n) (n when there is none). A
 * slot is mostly far longer than the stretch a split changes, so this scan
 * is most of what a split costs; in blocks of 16 the compiler makes it 4 or
 * 8 compares an instruction. */
enum { SCAN_BLOCK = 16 };

static uint32_t find_first(const uint32_t *a, uint32_t n, uint32_t x)
{
    uint32_t k = 0;
    for (; k + SCAN_BLOCK <= n; k += SCAN_BLOCK) {
        const uint32_t *b = a + k;
        unsigned any = 0;
        for (unsigned i = 0; i < SCAN_BLOCK; i++)
            any |= b[i] == x;
        if (any)
            break;
    }
    while (k < n && a[k] != x)
        k++;
    return k;
}

static uint32_t find_last(const uint32_t *a, uint32_t n, uint32_t x)
{
    uint32_t k = n;
    for (; k >= SCAN_BLOCK; k -= SCAN_BLOCK) {
        const uint32_t *b = a + k - SCAN_BLOCK;
        unsigned any = 0;
        for (unsigned i = 0; i < SCAN_BLOCK; i++)
            any |= b[i] == x;
        if (any)
            break;
    }
    while (k > 0 && a[k - 1] != x)
        k--;
    return k ? k - 1 : n;
}

/* The parent's triangle (before the split: g->cand) that window k of the
 * old indices o draws, u being one of its corners; its old next in *next.
 * -1 when none is (the slot is then derived whole). */
static int32_t cand_at(const mts_grow *g, const uint32_t *o, uint32_t k, uint32_t u,
                       int32_t *next)
{
    uint32_t tri[3];
    if (!mts_strip_window(o, k, tri))
        return -1;
    int j = corner_of(tri, u);
    if (j < 0)
        return -1;
    uint32_t after = tri[NX[j]], before = tri[PV[j]];
    for (size_t i = 0; i < g->cand.n; i += 2) {
        uint32_t c = g->cand.w[i], t = c / 3;
        if (g->tri[t].v[NX[c % 3]] == after && g->tri[t].v[PV[c % 3]] == before) {
            *next = (int32_t)g->cand.w[i + 1];
            return (int32_t)t;
        }
    }
    return -1;
}

/* The new indices of slot s where its path runs past u: from the first
 * triangle with corner u (t_first) to the one after the last (t_n), the
 * only stretch a split changes. Before t_first the path is as it was (t_first
 * is entered by an edge without u, which nothing touches); t_n's own index
 * may change (its entering edge is read the other way round when the
 * stretch before it changed), but the strip leaves it as before. The
 * stretch is found in the old indices: t_first's window ends at the first
 * u (lo), t_last's starts at the last (hi). 0 when the slot does not look
 * like that (it is then derived whole). */
static int local_region(mts_grow *g, uint32_t s, uint32_t u, uint32_t lo, uint32_t hi,
                        splice *sp)
{
    const uint32_t *o = g->slot[s].seq.w;
    const uint32_t L = (uint32_t)g->slot[s].seq.n;
    int32_t t, unused;
    uint32_t a = 0, c = 0;
    int first = lo < 3;
    if (first) {
        sp->p0 = 0;
        t = g->slot[s].head;
    } else {
        sp->p0 = lo - (o[lo - 1] == o[lo - 3]); /* t_first's swap, if it has one */
        a = o[sp->p0 - 2];
        c = o[sp->p0 - 1];
        t = cand_at(g, o, lo - 2, u, &unused);
        if (t < 0 || g->tri[t].slot != (int32_t)s)
            return 0;
    }
    int32_t tn = -1;
    sp->p1 = L;
    if (hi + 3 < L) {
        if (cand_at(g, o, hi, u, &tn) < 0 || tn < 0)
            return 0;
        sp->p1 = hi + 4 + (hi + 4 < L && o[hi + 3] == o[hi + 1]);
    }
    mts_words *r = &g->scratch;
    r->n = 0;
    int met;
    if (!derive_run(g, t, first, tn, &a, &c, r, &met))
        return -1;
    sp->suffix = met;
    sp->r = r;
    /* the strip leaves t_n as it did, or the stretch is not what it seems */
    return !met || (a == o[sp->p1 - 2] && c == o[sp->p1 - 1]);
}

/* A slot whose path kept every link, where every triangle with corner u
 * moved: its indices are the old ones with v for u (u first at lo, last at
 * hi), and the record only substitutes (no derivation). 1 done, 0 not such
 * a slot, -1 no memory. */
static int substitute_only(mts_grow *g, uint32_t s, uint32_t u, uint32_t v, uint32_t lo,
                           uint32_t hi, uint32_t *edits)
{
    uint32_t *o = g->slot[s].seq.w;
    const uint32_t L = (uint32_t)g->slot[s].seq.n;
    uint32_t count = 0;
    mts_words *pos = &g->scratch;
    pos->n = 0;
    for (uint32_t k = lo; k <= hi; k++) {
        if (o[k] != u)
            continue;
        /* a triangle drawn over k (one has moved only if all of them have:
         * else a link across a u edge broke) */
        uint32_t w = k >= 2 ? k - 2 : 0, tri[3];
        while (w <= k && (w + 2 >= L || !mts_strip_window(o, w, tri)))
            w++;
        int32_t unused, t = w <= k ? cand_at(g, o, w, u, &unused) : -1;
        if (t < 0 || corner_of(g->tri[t].v, v) < 0)
            return 0;
        if (!mts_words_reserve(pos, 1))
            return -1;
        pos->w[pos->n++] = k;
        count++;
    }
    if (!mts_words_reserve(&g->rec, 4 + count))
        return -1;
    uint32_t *r = g->rec.w + g->rec.n;
    *r++ = s;
    *r++ = 0;
    *r++ = 0;
    *r++ = count;
    for (uint32_t i = 0; i < count; i++) {
        *r++ = pos->w[i];
        o[pos->w[i]] = v;
    }
    g->rec.n = (size_t)(r - g->rec.w);
    (*edits)++;
    g->fig.edits++;
    g->fig.substitutions += count;
    return 1;
}

/* The record of the split to level g->level (u the parent, v the new
 * vertex): one edit per touched slot, in slot order. */
static int emit_record(mts_grow *g, uint32_t u, uint32_t v)
{
    g->rec.n = 0;
    if (!mts_words_reserve(&g->rec, 1))
        return 0;
    g->rec.n = 1;
    uint32_t edits = 0;
    /* slot order: a split touches two or three (insertion sort), a key
     * level every slot */
    if (g->touched_count == g->slot_count) { /* every slot: a key level */
        for (uint32_t k = 0; k < g->slot_count; k++)
            g->touched[k] = k;
    } else if (g->touched_count > 64) {
        qsort(g->touched, g->touched_count, 4, mts_words_cmp);
    } else {
        for (uint32_t i = 1; i < g->touched_count; i++) {
            uint32_t x = g->touched[i], j = i;
            for (; j > 0 && g->touched[j - 1] > x; j--)
                g->touched[j] = g->touched[j - 1];
            g->touched[j] = x;
        }
    }
    for (uint32_t k = 0; k < g->touched_count; k++) {
        uint32_t s = g->touched[k];
        splice sp = {0, (uint32_t)g->slot[s].seq.n, 0, &g->scratch};
        int local = 0;
        if (g->slot[s].fresh != g->stamp_now && g->slot[s].head >= 0 && g->slot[s].seq.n) {
            /* where u is in the old indices: the stretch both ways read */
            const uint32_t *o = g->slot[s].seq.w, L = (uint32_t)g->slot[s].seq.n;
            uint32_t lo = find_first(o, L, u), hi = lo < L ? find_last(o, L, u) : L;
            if (lo < L && g->slot[s].relinked != g->stamp_now) {
                int done = substitute_only(g, s, u, v, lo, hi, &edits);
                if (done < 0)
                    return 0;
                if (done)
                    continue;
            }
            local = lo < L ? local_region(g, s, u, lo, hi, &sp) : 0;
            if (local < 0)
                return 0;
        }
        if (!local) {
            sp.p0 = 0;
            sp.p1 = (uint32_t)g->slot[s].seq.n;
            sp.suffix = 0;
            if (!derive_whole(g, g->slot[s].head, &g->scratch))
                return 0;
        }
        if (!emit_splice(g, s, &sp, u, v, &edits))
            return 0;
    }
    g->rec.w[0] = edits;
    g->touched_count = 0;
    g->stamp_now++;
    return 1;
}

/* Derives every touched slot's indices into seq without a record (the base). */
static int settle(mts_grow *g)
{
    for (uint32_t k = 0; k < g->touched_count; k++) {
        uint32_t s = g->touched[k];
        g->total_indices -= g->slot[s].seq.n;
        g->nonempty -= g->slot[s].seq.n > 0;
        if (!derive_whole(g, g->slot[s].head, &g->slot[s].seq))
            return 0;
        if (g->slot[s].seq.n > g->slot[s].capacity)
            g->slot[s].capacity = g->capacity[s] = (uint32_t)g->slot[s].seq.n;
        g->total_indices += g->slot[s].seq.n;
        g->nonempty += g->slot[s].seq.n > 0;
    }
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
        while (g->tri[t].v[p->rotation] != s[0])
            p->rotation++;
    }
    /* which bits the walk forces: the walk a client makes */
    const mts_grow_full f = {.paths = paths,
                             .swaps = swaps,
                             .swap_count = *swap_count,
                             .slot_count = full->strip_count};
    return full_walk(g, NULL, &f, paths, err);
}

void mts_grow_free(mts_grow *g)
{
    if (!g)
        return;
    free(g->tri);
    free(g->vhead);
    free(g->prev);
    if (g->slot) {
        for (uint32_t s = 0; s < g->slot_cap; s++)
            free(g->slot[s].seq.w);
    }
    free(g->slot);
    free(g->capacity);
    free(g->free_slots);
    free(g->touched);
    free(g->keys.w);
    free(g->rec.w);
    free(g->scratch.w);
    free(g->affected.w);
    free(g->born.w);
    free(g->cand.w);
    free(g->ring.w);
    free(g->around.w);
    free(g);
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
        g->key_quality = opts && opts->key_quality > 0 ? opts->key_quality : -1;
        g->key_min_ratio = opts && opts->key_min_ratio > 1 ? opts->key_min_ratio : 1;
    }
    for (uint32_t i = 0; i < base->index_count; i++) {
        if (base->indices[i] >= nb) {
            rc = mts_error_set(err, MTS_ERR_FORMAT, "grow: base index %u is not a base vertex",
                               base->indices[i]);
            goto fail;
        }
    }
    if (!vhead_reserve(g, nb) || !tri_reserve(g, base->index_count + 1))
        goto nomem;
    for (uint32_t k = 0; k < base->strip_count; k++) {
        const uint32_t *str = base->indices + base->offsets[k];
        uint32_t len = base->offsets[k + 1] - base->offsets[k];
        for (uint32_t w = 0; w + 2 < len; w++) {
            uint32_t tri[3];
            if (mts_strip_window(str, w, tri) && tri_add(g, tri[0], tri[1], tri[2], 1) < 0)
                goto nomem;
        }
    }
    if ((rc = twins_build(g, err)) != MTS_OK)
        goto fail;
    int strict = !(opts && opts->normalise_base);
    if ((rc = adopt_strips(g, base, strict, err)) != MTS_OK)
        goto fail;
    if (!strict && !fit_slots(g))
        goto nomem;
    if (!settle(g))
        goto nomem;
    for (uint32_t s = 0; strict && s < base->strip_count; s++) {
        uint32_t len = base->offsets[s + 1] - base->offsets[s];
        if (len != g->slot[s].seq.n ||
            (len && memcmp(g->slot[s].seq.w, base->indices + base->offsets[s], (size_t)len * 4) != 0)) {
            rc = mts_error_set(err, MTS_ERR_FORMAT,
                               "grow: base strip %u is not in the form growth derives", s);
            goto fail;
        }
    }
    g->fig.key_count = 1;
    g->key_triangles = g->tri_count;
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
    if (a >= g->nb + g->level)
        return -1;
    uint32_t h = find_half_edge(g, a, b);
    /* a vertex with more than one fan: the builder's rare explicit splits */
    for (uint32_t x = 0; h == NONE && x < 3 * g->tri_count; x++) {
        if (he_from(g, x) == a && he_to(g, x) == b)
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
            c = corner_fwd(g, c);
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
        c = corner_back(g, c);
    }
    return count ? (int32_t)count : -1;
}

/* The parent's corners in ring order (grow.h: from the border when it is on
 * one, else from its listed corner, turning as the fan does), of the
 * fan its first corner lies in; cached until the next split. -1 when they
 * do not form a simple fan. */
static int32_t ring(mts_grow *g, uint32_t u)
{
    if (g->ring_level == g->level + 1 && g->ring_u == u)
        return (int32_t)g->ring_count;
    g->ring_level = 0;
    if (u >= g->nb + g->level || g->vhead[u] == NONE)
        return -1;
    mts_words *out = &g->ring;
    const uint32_t c0 = g->vhead[u];
    if (!mts_words_reserve(out, 16))
        return -1;
    /* forward from the listed corner: round to it (an inner vertex, the
     * ring starts there), or to a border */
    uint32_t c = c0;
    out->n = 0;
    for (;;) {
        if (out->n >= g->tri_count || (out->n == out->cap && !mts_words_reserve(out, 1)))
            return -1;
        out->w[out->n++] = c;
        c = corner_fwd(g, c);
        if (c == NONE || c == c0)
            break;
    }
    int closed = c == c0;
    if (!closed) {
        /* on a border: the ring starts at the other one, behind c0 */
        size_t ahead = out->n;
        for (c = corner_back(g, c0); c != NONE; c = corner_back(g, c)) {
            if (out->n >= g->tri_count || (out->n == out->cap && !mts_words_reserve(out, 1)))
                return -1;
            out->w[out->n++] = c;
        }
        /* out: c0 .. border, then the corners behind c0 nearest first */
        size_t behind = out->n - ahead;
        if (behind) {
            mts_words *t = &g->scratch; /* free between splits */
            t->n = 0;
            if (!mts_words_reserve(t, out->n))
                return -1;
            for (size_t i = 0; i < behind; i++)
                t->w[i] = out->w[out->n - 1 - i];
            memcpy(t->w + behind, out->w, ahead * 4);
            memcpy(out->w, t->w, out->n * 4);
        }
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
        while (i < K && he_to(g, r[i]) != right)
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
    *right = code->sides & 1 ? NONE : he_to(g, cf);
    *left = code->sides & 2 ? NONE : g->tri[cl / 3].v[PV[cl % 3]];
    return !(*left == NONE && *right == NONE) && !(*left != NONE && *left == *right);
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
    const double grown = g->key_triangles ? (double)g->tri_count / g->key_triangles : 0;
    if (g->key_ratio > 1 && grown >= g->key_ratio)
        return 1;
    /* the strips as the last split left them, drawn joined */
    const mts_strip_stats now = {.strips = g->nonempty, .indices = g->total_indices};
    return g->key_quality > 0 && grown >= g->key_min_ratio && g->tri_count &&
           (double)mts_strip_stats_draw_indices(&now) / g->tri_count > g->key_quality;
}

/* Notes the parent's corners before a fan split, with each one's triangle's
 * next on its path (g->cand: what local_region finds the changed stretch
 * by): its ring, all the corners it has in a manifold mesh. */
static int note_candidates(mts_grow *g)
{
    g->cand.n = 0;
    if (!mts_words_reserve(&g->cand, 2 * (size_t)g->ring_count))
        return 0;
    for (uint32_t k = 0; k < g->ring_count; k++) {
        uint32_t c = g->ring.w[k];
        g->cand.w[g->cand.n++] = c;
        g->cand.w[g->cand.n++] = (uint32_t)next_of(g, c / 3);
    }
    return 1;
}

/* An explicit split's twins: every half-edge of a moved or new triangle,
 * and those that were its twins, paired anew in one pass over the mesh
 * (explicit splits are the rare ones the fan rule misses, so O(triangles)
 * is fine), which also finds u a corner if it lost the one listed.
 * MTS_ERR_FORMAT when a directed edge ends up held twice. */
static mts_result twins_redo(mts_grow *g, uint32_t u, uint32_t first_new, mts_error *err)
{
    const size_t moved = g->affected.n, total = moved + (g->tri_count - first_new);
    he_key *k = malloc((3 * total + 1) * sizeof *k);
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
            k[m].key = (uint64_t)he_from(g, h) << 32 | he_to(g, h);
            k[m++].h = h;
        }
    }
    qsort(k, m, sizeof *k, cmp_he_key);
    mts_result rc = MTS_OK;
    for (size_t i = 0; i + 1 < m && rc == MTS_OK; i++) {
        if (k[i].key == k[i + 1].key) /* two of them hold one directed edge */
            rc = MTS_ERR_FORMAT;
    }
    int lost_u = g->vhead[u] == NONE || he_from(g, g->vhead[u]) != u;
    if (lost_u)
        g->vhead[u] = NONE;
    for (uint32_t h = 0; h < 3 * g->tri_count && rc == MTS_OK; h++) {
        uint32_t a = he_from(g, h), b = he_to(g, h);
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

mts_result mts_grow_next(mts_grow *g, const mts_grow_split *sp, const mts_grow_full *full,
                         const uint32_t **record, uint32_t *word_count, mts_error *err)
{
    if (g->level >= g->n)
        return mts_error_set(err, MTS_ERR_ARG, "grow: every split is applied already");
    const uint32_t v = g->nb + g->level, u = sp->parent;
    if (u >= v || (sp->left != NONE && sp->left >= v) || (sp->right != NONE && sp->right >= v) ||
        sp->left == u || sp->right == u)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "grow: split %u (vertex %u, parent %u, %u, %u) names a vertex out "
                             "of range",
                             g->level, v, u, sp->left, sp->right);
    if (g->level + 1 == g->n && (!full || (!full->strips && !full->paths)))
        return mts_error_set(err, MTS_ERR_ARG, "grow: the last split needs the full strips");
    if (!vhead_reserve(g, v + 1))
        goto nomem;
    const int fan = !sp->moved_count && !sp->born_count;

    /* the corners v takes over */
    g->affected.n = 0;
    uint32_t fs = 0, fc = 0;
    if (fan) {
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
            int c = t < g->tri_count ? corner_of(g->tri[t].v, u) : -1;
            if (c < 0)
                return mts_error_set(err, MTS_ERR_FORMAT,
                                     "grow: split %u moves triangle %u, which has no corner %u",
                                     g->level, t, u);
            g->affected.w[k] = 3 * t + (uint32_t)c;
        }
        g->affected.n = sp->moved_count;
    }
    g->cand.n = 0;
    if (fan && !note_candidates(g))
        goto nomem;
    /* the fan's two edges to the rest of u's ring, before they change */
    uint32_t hr = NONE, hl = NONE, opp_r = NONE, opp_l = NONE;
    if (fan) {
        uint32_t cr = g->affected.w[0], cl = g->affected.w[fc - 1];
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
        if (sp->left != NONE && (nl = tri_add(g, u, v, sp->left, 0)) < 0)
            goto nomem;
        if (sp->right != NONE && (nr = tri_add(g, v, u, sp->right, 0)) < 0)
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
            if (tri_add(g, t[0], t[1], t[2], 1) < 0)
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
    g->level++;

    if (is_key(g)) {
        mts_result rc;
        if (g->level < g->n)
            rc = restrip(g, err);
        else if (full->strips)
            rc = adopt_strips(g, full->strips, 0, err);
        else
            rc = resolve_full(g, full, err);
        if (rc != MTS_OK)
            return rc;
        if (!mts_words_reserve(&g->keys, 1))
            goto nomem;
        g->keys.w[g->keys.n++] = g->level;
        g->fig.key_count++;
        g->key_triangles = g->tri_count;
    } else {
        /* links the split broke: only next to a moved triangle */
        for (size_t k = 0; k < g->affected.n; k++) {
            int32_t t = (int32_t)g->affected.w[k];
            touch(g, g->tri[t].slot);
            /* a fan's inner triangles keep every neighbour: only its ends
             * can have lost a link, across u -> right and left -> u */
            if (fan && k != 0 && k + 1 != g->affected.n)
                continue;
            if (g->prev[t] >= 0 && !adjacent(g, g->prev[t], t) &&
                !mend_link(g, g->prev[t], t, first_new))
                goto nomem;
            if (next_of(g, t) >= 0 && !adjacent(g, t, next_of(g, t)) &&
                !mend_link(g, t, next_of(g, t), first_new))
                goto nomem;
        }
        for (uint32_t f = first_new; f < g->tri_count; f++) {
            if (g->tri[f].slot < 0 && !place_newborn(g, (int32_t)f))
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
        int at = corner_of(c, v);
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
    *length = (uint32_t)g->slot[s].seq.n;
    return g->slot[s].seq.w;
}

mts_result mts_grow_check(const mts_grow *g, mts_error *err)
{
    const uint32_t nv = g->nb + g->level, nh = 3 * g->tri_count;
    mts_result rc = MTS_OK;
    mts_words d = {0};
    he_key *ix = he_index(g);
    uint8_t *has = calloc((size_t)nv + 1, 1);
    if (!ix || !has) {
        free(ix);
        free(has);
        return mts_error_set(err, MTS_ERR_NOMEM, "grow check: out of memory");
    }
    for (uint32_t h = 0; h < nh && rc == MTS_OK; h++) {
        uint32_t a = he_from(g, h), b = he_to(g, h), o = TWIN(g, h);
        size_t i = he_index_find(ix, nh, a, b), r = he_index_find(ix, nh, b, a);
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
        if (c == NONE ? has[x] : c >= nh || he_from(g, c) != x)
            rc = mts_error_set(err, MTS_ERR_INTERNAL, "grow check: vertex %u lists corner %u", x,
                               c);
    }
    uint64_t indices = 0;
    uint32_t nonempty = 0, placed = 0;
    for (uint32_t s = 0; s < g->slot_count && rc == MTS_OK; s++) {
        uint32_t count = 0;
        for (int32_t t = g->slot[s].head, p = -1; t >= 0 && rc == MTS_OK; p = t, t = next_of(g, t)) {
            if (g->tri[t].slot != (int32_t)s || g->prev[t] != p || (p >= 0 && !adjacent(g, p, t)) ||
                (p >= 0 && (g->tri[p].nx & 3) != (int32_t)edge_to(g, (uint32_t)p, (uint32_t)t)) ||
                ++count > g->tri_count)
                rc = mts_error_set(err, MTS_ERR_INTERNAL,
                                   "grow check: slot %u's path is broken at triangle %d", s, t);
        }
        if (rc != MTS_OK)
            break;
        if (count != g->slot[s].ntri)
            rc = mts_error_set(err, MTS_ERR_INTERNAL,
                               "grow check: slot %u holds %u triangles, counted %u", s, count,
                               g->slot[s].ntri);
        else if (!derive_whole(g, g->slot[s].head, &d))
            rc = mts_error_set(err, MTS_ERR_NOMEM, "grow check: out of memory");
        else if (d.n != g->slot[s].seq.n || (d.n && memcmp(d.w, g->slot[s].seq.w, d.n * 4) != 0))
            rc = mts_error_set(err, MTS_ERR_INTERNAL,
                               "grow check: slot %u holds %zu indices where its path gives %zu "
                               "(or others)",
                               s, g->slot[s].seq.n, d.n);
        placed += count;
        indices += g->slot[s].seq.n;
        nonempty += g->slot[s].seq.n > 0;
    }
    if (rc == MTS_OK && (placed != g->tri_count || indices != g->total_indices ||
                         nonempty != g->nonempty))
        rc = mts_error_set(err, MTS_ERR_INTERNAL,
                           "grow check: %u of %u triangles placed, %llu indices (kept %llu), %u "
                           "strips (kept %u)",
                           placed, g->tri_count, (unsigned long long)indices,
                           (unsigned long long)g->total_indices, nonempty, g->nonempty);
    free(ix);
    free(has);
    free(d.w);
    return rc;
}
