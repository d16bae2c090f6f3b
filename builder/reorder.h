/* Reorders a collapse sequence so that a stream codes its splits' parents
 * cheaply, without changing the full mesh or the base.
 *
 * A stream names each split's parent u. In the decimation's order parents
 * are anywhere in the mesh (the cheapest collapse next), so coding u costs
 * about log2 of the vertices there are: 13.6 bits a split on bunny00, more
 * than a quarter of the stream. Compressed Progressive Meshes (Pajarola and
 * Rossignac 2000) and valence-driven coders (Alliez and Desbrun 2001) pay a
 * bit or two a vertex for the same thing because they refine in batches of
 * independent splits, visited in an order both ends know. This does the
 * same within windows of the split order: two splits whose closed 1-rings
 * (the removed vertex and every vertex round it, at its collapse) share no
 * vertex commute -- either order gives the same mesh after both, and each
 * is as legal as before -- so within a window the splits are sorted by
 * their parent's final id, as far as the splits that do share vertices
 * allow (they keep their order). A parent then mostly lies a short way
 * above the one before it (stream.c codes that gap).
 *
 * The levels inside a window change (the same splits, in another order);
 * the window is a small fraction of the splits, so the level of detail a
 * level stands for hardly does. */
#ifndef MTS_REORDER_H
#define MTS_REORDER_H

#include <stdint.h>

#include "error.h"
#include "simplify.h"

/* Zero-initialised means the defaults. */
typedef struct mts_reorder_options {
    /* splits a window; 0: a quarter of the vertices present where the
     * window starts (16..65536); 1: no reordering */
    uint32_t window;
    /* per vertex, the id it has in the model when it survives (0..nb-1,
     * each once; mts_lodbuild_options.base_ids); NULL: survivors in vertex
     * order */
    const uint32_t *base_ids;
} mts_reorder_options;

typedef struct mts_reorder_stats {
    uint32_t window;   /* the fixed one asked for, 0 for the default */
    uint32_t windows;  /* windows there were */
    uint32_t runs;     /* ascending runs of parents, over all windows */
    uint64_t conflicts; /* pairs of splits in one window that had to keep their order */
} mts_reorder_stats;

/* Permutes collapses[0..count) in place (mesh: vertex_count vertices,
 * triangle_count triangles, 3 indices each, the mesh the collapses were
 * made on). The final id of a vertex is as lodbuild gives it: survivors
 * 0..nb-1 in their order, then the removed vertices, last collapsed first.
 * MTS_ERR_ARG when a collapse names a vertex that is gone or out of range
 * (not looked for with window 1 or fewer than two collapses, which leave
 * the sequence as it is); MTS_ERR_NOMEM. stats may be NULL. */
mts_result mts_reorder_collapses(const uint32_t *triangles, uint32_t triangle_count,
                                 uint32_t vertex_count, mts_collapse *collapses, uint32_t count,
                                 const mts_reorder_options *opts, mts_reorder_stats *stats,
                                 mts_error *err);

#endif
