/* The corner table: growth's mesh, private to growth (grow.c builds it and
 * splits it through these calls; not the public API, grow.h). corner.c
 * also holds grow.h's calls that only read the mesh: finding a triangle,
 * fans and their codes, the ring of the newest vertex, a model's split.
 *
 * Every client splits this mesh on every split it receives, so a split must
 * cost about what it changes: the mesh is a corner table in flat arrays,
 * per half-edge (3t + e, from corner e of triangle t to corner e + 1) its
 * twin, and per vertex one of its corners. A fan split relabels the fan's
 * corners and links two new triangles in with O(1) twin updates; walking
 * round a vertex is a twin step, never a lookup (hash maps cost a client far
 * more: docs/client-cost.md). Only what is not a walk round one fan -- the
 * base, whole strips adopted, the rare explicit split, the check -- sorts or
 * scans the half-edges.
 *
 * The arrays are mts_grow's (grow_internal.h), in the triangle records the
 * strips' paths share. The steps a walk takes a triangle at a time are
 * static inline here; what is called once a split or less is corner.c's. */
#ifndef MTS_CORNER_H
#define MTS_CORNER_H

#include <stddef.h>
#include <stdint.h>

#include "error.h"
#include "grow.h"
#include "grow_internal.h"

/* Where half-edge h starts, and where it ends. */
static inline uint32_t mts__corner_from(const mts_grow *g, uint32_t h)
{
    return g->tri[h / 3].v[h % 3];
}

static inline uint32_t mts__corner_to(const mts_grow *g, uint32_t h)
{
    return g->tri[h / 3].v[mts__grow_nx[h % 3]];
}

/* Which corner of triangle t (its vertex ids) is x, or -1. */
static inline int mts__corner_of(const uint32_t *t, uint32_t x)
{
    return t[0] == x ? 0 : t[1] == x ? 1 : t[2] == x ? 2 : -1;
}

/* Walking round a vertex: crossing a corner's out-edge (u -> a) backwards
 * lands on the corner of u in the triangle holding a -> u, crossing its
 * in-edge (b -> u) forwards on the one holding u -> b (a corner is also the
 * half-edge it starts). */
static inline uint32_t mts__corner_back(const mts_grow *g, uint32_t c)
{
    uint32_t h = MTS__GROW_TWIN(g, c);
    return h == MTS_GROW_NONE ? MTS_GROW_NONE : 3 * (h / 3) + mts__grow_nx[h % 3];
}

static inline uint32_t mts__corner_fwd(const mts_grow *g, uint32_t c)
{
    return MTS__GROW_TWIN(g, 3 * (c / 3) + mts__grow_pv[c % 3]);
}

/* The vertex of triangle t that is neither x nor y. */
static inline uint32_t mts__corner_third(const mts_grow *g, uint32_t t, uint32_t x, uint32_t y)
{
    const uint32_t *v = g->tri[t].v;
    return v[0] != x && v[0] != y ? v[0] : v[1] != x && v[1] != y ? v[1] : v[2];
}

/* Whether a split is a fan by the fan rule (grow.h), not listed. */
static inline int mts__corner_is_fan(const mts_grow_split *sp)
{
    return !sp->moved_count && !sp->born_count;
}

/* Room for `extra` more triangles; 0 when out of memory or too many. */
int mts__corner_tri_reserve(mts_grow *g, uint32_t extra);

/* Adds a live triangle, its edges borders for now, and (with `list`) makes
 * it the listed corner of each of its vertices; -1 when out of memory. */
int32_t mts__corner_tri_add(mts_grow *g, uint32_t a, uint32_t b, uint32_t c, int list);

/* Room in vhead for `count` vertices. It grows with the splits applied,
 * not with the levels announced: a client's growth starts before it knows
 * how many will really come. */
int mts__corner_vhead_reserve(mts_grow *g, uint32_t count);

/* A sorted index of every half-edge by (from, to), for what is not a walk
 * round one fan; what mts__corner_window_triangle keeps between calls. */
typedef struct mts__corner_key {
    uint64_t key;
    uint32_t h;
} mts__corner_key;

/* Pairs every half-edge with its reverse, all at once (the base). A
 * directed edge held twice is not a mesh growth can work on. */
mts_result mts__corner_twins_build(mts_grow *g, mts_error *err);

/* The live triangle a window (oriented as drawn) is: a neighbour of the
 * previous window's (a strip that chains), else found round its first
 * vertex, else (a vertex of several fans) in a sorted index of every
 * half-edge, made the first time one is needed (*ix, NULL at first; the
 * caller frees it). -1: none; -2: no memory. */
int32_t mts__corner_window_triangle(const mts_grow *g, int32_t prev, const uint32_t tri[3],
                                    mts__corner_key **ix);

/* Gives every triangle a new id, perm[old] (the paths are reset after: only
 * the mesh, the listed corners and the last split's triangles move). 0 when
 * out of memory. */
int mts__corner_renumber(mts_grow *g, const uint32_t *perm);

/* A split in two steps, so that growth can note the parent's ring and
 * paths between them (what it finds the changed stretch of a strip by).
 * First the corners the new vertex takes over, into g->affected;
 * MTS_ERR_FORMAT when the split names no fan or a triangle without a corner
 * at the parent. */
mts_result mts__corner_split_corners(mts_grow *g, const mts_grow_split *sp, mts_error *err);

/* Then the split itself: those corners become the new vertex's (g->affected
 * then holds their triangles), the new triangles are added (g->born) and
 * linked in. g->level is left to the caller. MTS_ERR_FORMAT when the split
 * contradicts the mesh. */
mts_result mts__corner_split_apply(mts_grow *g, const mts_grow_split *sp, mts_error *err);

/* Checks every twin against the directed edges and every listed corner
 * against its vertex (mts_grow_check's first half). MTS_ERR_INTERNAL names
 * the first difference. */
mts_result mts__corner_check(const mts_grow *g, mts_error *err);

#endif
