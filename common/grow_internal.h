/* Private to strip growth (grow.c, grow_full.c, grow_tokens.c, and the
 * corner table, corner.c): the state they share, and the small helpers each
 * of them calls a triangle at a time. Not the public API (grow.h): mts__
 * names.
 *
 * One object holds it all, and the mesh and the strips' paths share each
 * triangle's record, so a walk along a path or round a vertex reads one
 * record a triangle. The hot helpers are static inline here so that every
 * file inlines them as it did when growth was one file: a call a triangle
 * would cost every client's every split. */
#ifndef MTS_GROW_INTERNAL_H
#define MTS_GROW_INTERNAL_H

#include <stdint.h>

#include "bigmem.h"
#include "error.h"
#include "grow.h"
#include "words.h"

/* The corner after corner e of a triangle, and the one before it. */
static const uint8_t mts__grow_nx[3] = {1, 2, 0}, mts__grow_pv[3] = {2, 0, 1};

/* What a split and a derivation read of a triangle, in one place: a walk
 * along a path or round a vertex is a cache miss a triangle, not three. */
typedef struct mts__grow_tri {
    uint32_t v[3];
    uint32_t tw[3]; /* per edge e: the twin half-edge, MTS_GROW_NONE at a border */
    int32_t nx;     /* the next on its strip's path, times 4, plus the edge
                     * to it (3: none found); -1 at the path's end */
    int32_t slot;   /* of its strip, -1 while unplaced */
} mts__grow_tri;
/* two to a cache line; greedy.c reads tw straight from these records */
_Static_assert(sizeof(mts__grow_tri) == 32, "mts__grow_tri is half a cache line");

typedef struct mts__grow_slot {
    mts_words seq;     /* indices as last derived */
    int32_t head;      /* first triangle of the path, -1 when empty */
    uint32_t ntri;     /* triangles on it */
    uint32_t stamp;    /* == stamp_now: touched by this split */
    uint32_t fresh;    /* == stamp_now: given other content (derived whole) */
    uint32_t relinked; /* == stamp_now: a link of its path changed */
    uint32_t capacity; /* longest it has been (g->capacity[s] too, for the figures;
                        * here a split reads it in the slot's cache line) */
} mts__grow_slot;

/* The twin of half-edge h (3t + e, from corner e of t to corner e + 1). */
#define MTS__GROW_TWIN(g, h) ((g)->tri[(h) / 3].tw[(h) % 3])

struct mts_grow {
    uint32_t nb, n, level;
    /* triangles, all live */
    uint32_t tri_count, tri_cap;
    mts__grow_tri *tri; /* 64-byte aligned: two to a cache line (tri_mem.p) */
    int32_t *prev;      /* each triangle's previous on its path, read far less (prev_mem.p) */
    /* where they live, and the array a key's renumbering writes into */
    mts_bigmem tri_mem, prev_mem, spare_mem;
    uint32_t *vhead;    /* per vertex: a corner of it, MTS_GROW_NONE when it has none */
    uint32_t vhead_room; /* vertices vhead holds: grown as splits bring them */
    /* slots */
    uint32_t slot_count, slot_cap;
    mts__grow_slot *slot;
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
    /* grow_tokens.h: a mesh-only grow has no slots or paths, and a worker
     * keeps each key's renumbering (old id -> new) for the next worker */
    int mesh_only, keep_order;
    mts_words key_order;
    /* paths for the restripification at given_level, greedy.c's on another
     * grow of this mesh (mts_grow_give_key_paths), the caller's memory */
    const uint32_t *given_order, *given_starts;
    uint32_t given_level, given_triangles, given_count;
    /* told each key's renumbering once it is known (mts_grow_on_key_order) */
    void (*on_key_order)(void *user, const uint32_t *order, uint32_t count);
    void *on_key_user;
};

/* ---- paths on the dual graph ---- */

/* Whether triangles ta and tb are neighbours (either -1: no). */
static inline int mts__grow_adjacent(const mts_grow *g, int32_t ta, int32_t tb)
{
    if (ta < 0 || tb < 0)
        return 0;
    const uint32_t *h = g->tri[ta].tw;
    uint32_t b = (uint32_t)tb;
    return (h[0] != MTS_GROW_NONE && h[0] / 3 == b) || (h[1] != MTS_GROW_NONE && h[1] / 3 == b) ||
           (h[2] != MTS_GROW_NONE && h[2] / 3 == b);
}

/* The edge of t that leads to its neighbour b (0..2), or 3. */
static inline unsigned mts__grow_edge_to(const mts_grow *g, uint32_t t, uint32_t b)
{
    const uint32_t *h = g->tri[t].tw;
    for (unsigned e = 0; e < 3; e++) {
        if (h[e] != MTS_GROW_NONE && h[e] / 3 == b)
            return e;
    }
    return 3;
}

/* The next triangle on t's path, -1 at its end. */
static inline int32_t mts__grow_next_of(const mts_grow *g, int32_t t)
{
    return g->tri[t].nx < 0 ? -1 : g->tri[t].nx >> 2;
}

/* Links t to n (-1: t ends its path), noting the edge between them. */
static inline void mts__grow_set_next(mts_grow *g, int32_t t, int32_t n)
{
    g->tri[t].nx =
        n < 0 ? -1 : (int32_t)((uint32_t)n << 2 | mts__grow_edge_to(g, (uint32_t)t, (uint32_t)n));
}

/* Empties every path and slot: all of them touched and fresh, room for at
 * least `slots` (grow.c). */
int mts__grow_paths_reset(mts_grow *g, uint32_t slots);

/* Frees the slots from `used` on and the empty ones below it (grow.c). */
void mts__grow_slots_free_unused(mts_grow *g, uint32_t used);

/* Room for `count` slots, the new ones empty; slot_count becomes at least
 * `count` (grow.c). 0 when out of memory. */
int mts__grow_slots_reserve(mts_grow *g, uint32_t count);

/* Appends to g->rec the edit that turns slot s's indices into r whole (u
 * the parent of the split to the level r is of, v its vertex), as a key
 * level's record does for every slot, and stores r as the slot's indices
 * (grow.c). 0 when out of memory. */
int mts__grow_splice_whole(mts_grow *g, uint32_t s, const mts_words *r, uint32_t u, uint32_t v,
                           uint32_t *edits);

/* The full level's paths from a description of its strips (grow_full.c):
 * the walk a client makes at the last split. */
mts_result mts__grow_resolve_full(mts_grow *g, const mts_grow_full *f, mts_error *err);

#endif
