/* LOD runtime: the strips of a model at a current level, moved to any other
 * level by applying records (splits up, collapses down), touching only the
 * strips a record names and remembering which changed so a renderer can
 * re-upload just those (paper 001, algorithms 1 and 3).
 *
 * Each strip owns a fixed slot as long as its capacity (model->capacity: the
 * longest it is at any level; strip lengths are not monotone in the level,
 * so the full level's lengths will not do), and mts_lod_init reserves the
 * scratch for the longest record, so no move allocates. Splits are checked as they are applied, so a runtime can
 * follow records arriving from a socket: a record that does not fit the
 * current strips is an error naming the record and strip, and leaves the
 * runtime broken (every later move fails) since the record may have been
 * half applied; the caller drops it. A collapse is the exact inverse of its
 * split and checks nothing, so it must only undo records that were checked:
 * splits this runtime made, or, for MTS_LOD_AT_FULL, a model that passed
 * mts_model_validate (every loaded and every built model has). */
#ifndef MTS_LOD_H
#define MTS_LOD_H

#include <stdint.h>

#include "bigmem.h"
#include "error.h"
#include "model.h"
#include "strips.h"

typedef struct mts_lod {
    const mts_model *model;
    uint32_t level;
    /* levels up to here may be used: records of splits < available are present */
    uint32_t available;
    uint32_t strip_count;
    uint32_t *slot;   /* strip s lives at data + slot[s], capacity slot[s+1]-slot[s]
                         (== model->capacity[s]); slot[strip_count] is where the
                         slots end, room (data's size) at least that */
    uint32_t room;
    /* the first slot laid out anew since mts_lod_clear_changed (a renderer
     * moves its slots from there on), UINT32_MAX when none was */
    uint32_t relayout_from;
    uint32_t *length; /* current length of each strip */
    uint32_t *data;
    uint8_t *changed; /* per strip: changed since mts_lod_clear_changed */
    uint32_t *changed_list;
    uint32_t changed_count;
    /* scratch to walk a record backwards */
    const uint32_t **scratch;
    uint32_t scratch_size;
    /* where data and scratch live: reservations past a megabyte, from the
     * cache given to mts_lod_init_with (bigmem.h) */
    mts_bigmem data_mem, scratch_mem;
    int broken; /* a split record failed its checks */
} mts_lod;

typedef enum mts_lod_start {
    MTS_LOD_AT_BASE = 0,
    MTS_LOD_AT_FULL = 1 /* needs all records, validated (see above) */
} mts_lod_start;

/* Slots are laid out from model->capacity (which must be there when the model
 * has strips) and model->base (or ->full) is copied into them, each strip
 * checked to fit its slot; model must outlive lod. All strips start marked
 * changed (a renderer uploads everything once). */
mts_result mts_lod_init(mts_lod *lod, const mts_model *model, mts_lod_start start, mts_error *err);
/* The same, its slots' indices and its scratch in reservations from
 * `memory` (NULL: the kernel), for a caller that makes runtime after
 * runtime in one process (a stream client's, with its client's cache):
 * the next one then reuses pages the last one touched. */
mts_result mts_lod_init_with(mts_lod *lod, const mts_model *model, mts_lod_start start,
                             mts_bigmem_cache *memory, mts_error *err);
void mts_lod_free(mts_lod *lod);

/* Slots from..strip_count-1 laid out again from model->capacity, which has
 * grown for slots that had none: a stream client learns a slot's capacity
 * when the slot is first used. Those slots must be empty; the capacities
 * must fit the room reserved (MTS_ERR_RANGE). */
mts_result mts_lod_announce(mts_lod *lod, uint32_t from, mts_error *err);

/* Moves to the target level (clamped to [0, available]). Returns an error only
 * when a split record is inconsistent; lod->level then says where it stopped. */
mts_result mts_lod_set_level(mts_lod *lod, uint32_t target, mts_error *err);

/* A streaming client raises this as batches of records arrive (records of
 * splits below `available` must be in the model by then). */
static inline void mts_lod_set_available(mts_lod *lod, uint32_t available)
{
    lod->available = available < lod->model->level_count ? available : lod->model->level_count;
}

/* One split (level -> level + 1), checked: every erased run must be inside
 * its strip and hold exactly the indices the record lists, every inserted run
 * must fit the slot's capacity, every substituted position must hold the
 * parent. One collapse (level -> level - 1), its exact inverse, unchecked. */
mts_result mts_lod_split(mts_lod *lod, mts_error *err);
void mts_lod_collapse(mts_lod *lod);

static inline const uint32_t *mts_lod_strip(const mts_lod *lod, uint32_t s, uint32_t *length)
{
    *length = lod->length[s];
    return lod->data + lod->slot[s];
}

/* Strips changed since the last clear, each once, in the order first touched. */
static inline const uint32_t *mts_lod_changed(const mts_lod *lod, uint32_t *count)
{
    *count = lod->changed_count;
    return lod->changed_list;
}
void mts_lod_clear_changed(mts_lod *lod);

/* The figures of the strips at the current level (strips.h's counting). */
void mts_lod_strip_stats(const mts_lod *lod, mts_strip_stats *stats);

/* Bytes the runtime holds beyond the model. */
uint64_t mts_lod_memory_bytes(const mts_lod *lod);

#endif
