/* The multiresolution strip model, in memory: what a .mtsm file holds and
 * what the server streams. Vertex ids are in stream order (docs/architecture.md, "Levels
 * and vertex order"): base vertices 0..nb-1, then vertex nb+j is the one split
 * j brings back next to its parent parents[j] (< nb+j).
 *
 * Strip slots are stable ids: slot s exists at every level, possibly empty.
 * capacity[s] is the longest slot s is at any level, the room a runtime
 * reserves for it (so no split ever moves a strip).
 *
 * Strips are built upward (see lodbuild.h): key levels are stripified
 * afresh, and between them each split grows the strips by the triangles it
 * brings back. Records, one per split j, live in record_data[record_offsets[j]
 * .. record_offsets[j+1]) as 32-bit words, in the order a split applies them:
 *
 *   edit_count
 *   edit_count times:
 *     strip, erase_count, insert_count, subst_count,
 *     erase_count  times: position, length, length indices  -- runs to erase
 *     insert_count times: position, length, length indices  -- runs to insert
 *     subst_count  times: position                          -- u becomes v here
 *
 * A split applies the edits in order; in each it erases each run (its
 * position is in the strip as it is at that moment, and the strip must hold
 * exactly those indices there), then inserts each run (positions likewise),
 * then sets the listed positions (which hold the parent u) to the new vertex
 * v = nb + j. The collapse back reverses it, edit by edit from the last (a
 * record may name a strip in more than one edit): positions become u, the
 * inserted runs are erased last to first, then the erased runs are put back
 * last to first. Keeping the erased indices in the record is what lets a
 * collapse restore them, so the same records move both ways (paper 001's
 * hRecordsLOD + hInterLeavedData, generalised from "runs a collapse drops" to
 * "any change a level makes"). */
#ifndef MTS_MODEL_H
#define MTS_MODEL_H

#include <stdint.h>

#include "bigmem.h"
#include "error.h"
#include "strips.h"

#define MTS_GROWTH_EXPLICIT 4u

/* The normals are the source mesh's own; without this flag they were
 * computed from its faces, and a stream leaves them out. */
#define MTS_MODEL_NORMALS_GIVEN 1u
/* The source mesh had a colour per vertex: colors holds them. */
#define MTS_MODEL_COLORS 2u

typedef struct mts_model {
    uint32_t vertex_count;      /* full level */
    uint32_t base_vertex_count; /* nb */
    uint32_t level_count;       /* n = vertex_count - nb; levels are 0..n */
    uint32_t strip_count;       /* slots, same at every level */
    uint32_t *capacity;         /* strip_count: longest length of each slot at any level */
    /* what a runtime reserves for all the slots: 0 for the capacities' sum.
     * A stream client learns the sum first and each slot's capacity when
     * the slot is first used (capacity 0 until then; mts_lod_announce). */
    uint64_t capacity_room;

    float *positions; /* 3 per vertex, stream order */
    float *normals;   /* 3 per vertex, stream order */
    uint8_t *colors;  /* 3 per vertex (8-bit sRGB red, green, blue), stream order, with
                         MTS_MODEL_COLORS; else NULL */
    float bbox_min[3], bbox_max[3];
    uint32_t flags; /* MTS_MODEL_* */

    uint32_t *parents; /* n */

    mts_strips full; /* strips at level n */
    mts_strips base; /* strips at level 0 */

    uint32_t *record_offsets; /* n + 1 */
    uint32_t *record_data;
    uint32_t record_word_count; /* == record_offsets[n] */
    /* where record_data lives when a stream client grew it as records came
     * (bigmem.h); else empty, and record_data a malloc block */
    mts_bigmem record_mem;
    /* where a stream client put parents, record_offsets and capacity, sized
     * by what MODEL_INFO claims and filled as levels and slots arrive
     * (mts_bigmem_zeroed); else empty, and each a malloc block */
    mts_bigmem parents_mem, offsets_mem, capacity_mem;
    /* where a stream client grew positions, normals and colors as vertices
     * came (bigmem.h); else empty, and each a malloc block */
    mts_bigmem positions_mem, normals_mem, colors_mem;

    /* What a stream sends in place of the records (grow.h): the key levels
     * (ascending, in 1..n-1; the full level is always a key), and per split j
     * growth_data[growth_offsets[j] .. growth_offsets[j+1]): the fan code
     * start, count, sides, or for a split the fan rule does not describe
     * sides = MTS_GROWTH_EXPLICIT, moved_count, born_count, the moved
     * triangle ids, and 3 vertex ids per new triangle. */
    uint32_t key_count;
    uint32_t *key_levels;
    uint32_t *growth_offsets; /* n + 1 */
    uint32_t *growth_data;
    uint32_t growth_word_count;

    /* Per level l in 0..n (vertices at l are nb + l). */
    uint32_t *level_triangles;
    uint32_t *level_strips;  /* non-empty strips */
    uint32_t *level_indices; /* sum of strip lengths, restarts not counted */

    char source[256]; /* where the model came from (file name), informational */
    /* What a cached model was built from and how: a server's cache
     * (server/catalog.c) is used only while this equals the key it makes
     * from the mesh file and its build options. Empty for other models. */
    char build_key[256];
} mts_model;

void mts_model_free(mts_model *model);

/* Checks every count, index and record of a model against the others: record
 * offsets in order, each record parses exactly, every strip id, position and
 * vertex id in range at the level it is used, every erased run holds what the
 * record says, every substituted position holds the parent, no slot ever
 * grows past its capacity, replaying all splits from the base strips gives
 * exactly the full strips, and the per-level counts match the replay. After this, a
 * runtime may apply the records without checks. */
mts_result mts_model_validate(const mts_model *model, mts_error *err);

/* One edit of a record in the format above, from p (at its strip) within
 * [p, end): the strip it edits in *strip; returns where the next edit
 * starts, or NULL when the edit runs past end. */
static inline const uint32_t *mts_record_skip_edit(const uint32_t *p, const uint32_t *end,
                                                   uint32_t *strip)
{
    if (end - p < 4)
        return NULL;
    const uint32_t runs = p[1] + p[2], substs = p[3];
    *strip = p[0];
    size_t k = 4, n = (size_t)(end - p);
    for (uint32_t r = 0; r < runs; r++) {
        if (n - k < 2 || n - k - 2 < p[k + 1])
            return NULL;
        k += 2 + (size_t)p[k + 1];
    }
    return n - k < substs ? NULL : p + k + substs;
}

/* Level holding the number of triangles closest to (not above) the given
 * count, and the level for a fraction in [0,1] of the full vertex count. */
uint32_t mts_model_level_for_triangles(const mts_model *model, uint64_t triangles);
uint32_t mts_model_level_for_fraction(const mts_model *model, double fraction);

/* Bytes of the in-memory model (arrays only), for reports. */
uint64_t mts_model_memory_bytes(const mts_model *model);

#endif
