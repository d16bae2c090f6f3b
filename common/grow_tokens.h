/* Growth cut at its key levels, so that the key intervals can be derived
 * apart (by workers, docs/threads.md) and still give, word for word, the
 * records one grow gives (grow.h).
 *
 * Why it can be cut there: after a key, the strips' paths follow from the
 * mesh at the key alone (greedy.c, in the triangle ids the key before left),
 * and growth compares slots only for equality and path lengths. The records
 * are what depends on the past, through the slot ids: which slot a key's
 * strip goes into (the capacities so far), which free slot a split opens,
 * the order of a record's edits, and a key record erases what the interval
 * before left. So a worker grows its interval in slot tokens of its own,
 * and the in-order fix-up (mts_grow_fixup) turns its records into the real
 * ones once the interval before is known; that is a mapping and a sort a
 * record, and one splice a slot a key.
 *
 * The pieces, in the order a decoder uses them:
 *  - a mesh-only grow (the sequential pass): the corner table and nothing
 *    else, never renumbered, so triangle ids are birth order. Rings, fan
 *    codes and the triangles round a new vertex are what grow.h's calls give
 *    on a full grow (they read vertex ids and corners, not triangle ids).
 *  - a worker: a copy of the mesh-only grow at the level before a key, its
 *    triangles renumbered to the ids one grow has there; mts_grow_next then
 *    applies the key split and the splits up to the next key, its slots
 *    being tokens (token k at a restripified key: its k-th longest path;
 *    later tokens: the slots it opens, in order).
 *  - the fix-up, fed every worker's records in level order.
 *
 * Explicit splits name triangles by the ids of one grow: a mesh-only grow
 * takes them in its own ids (the caller maps them, mts_grow_key_order). */
#ifndef MTS_GROW_TOKENS_H
#define MTS_GROW_TOKENS_H

#include <stdint.h>

#include "error.h"
#include "grow.h"
#include "strips.h"

/* A grow that keeps the mesh only: mts_grow_split_mesh applies splits,
 * mts_grow_next refuses it (MTS_ERR_ARG), and the calls that read the mesh
 * (rings, fan codes, mts_grow_around_newest, mts_grow_model_split,
 * mts_grow_check) work as on a full grow. The base strips are read as
 * triangles only. Freed with mts_grow_free. */
mts_result mts_grow_create_mesh(const mts_strips *base, uint32_t base_vertex_count,
                                uint32_t level_count, mts_grow **out, mts_error *err);

/* Applies the next split to a mesh-only grow. MTS_ERR_ARG on a full grow
 * or after the last split; MTS_ERR_FORMAT as mts_grow_next gives it. */
mts_result mts_grow_split_mesh(mts_grow *g, const mts_grow_split *split, mts_error *err);

/* A worker for the key interval that starts at level mesh->level + 1 (a key
 * of opts->key_levels, or the full level): a full grow at mesh's level
 * holding its mesh, triangle t of mesh being triangle ids[t] of the worker
 * (ids: the renumbering one grow made at the keys so far, a permutation of
 * mesh's triangles; NULL: none, before the first key). Its first
 * mts_grow_next is the key split; it stops being of use at the next key.
 * opts must list the key levels (MTS_ERR_ARG otherwise, or when the next
 * level is not a key). */
mts_result mts_grow_create_worker(const mts_grow *mesh, const uint32_t *ids,
                                  const mts_grow_options *opts, mts_grow **out, mts_error *err);

/* A worker's renumbering at its key (restripified, not the full level):
 * triangle t before it became order[t]; *count triangles. NULL before. The
 * ids of the next worker are ids[t] -> order[ids[t]] for the triangles this
 * worker started with, and the same id for those its key split brought. */
const uint32_t *mts_grow_key_order(const mts_grow *worker, uint32_t *count);

/* Tells fn each renumbering g makes at a restripified key (old id t
 * becomes order[t], count of them) as soon as it is known, before g
 * renumbers: a decoder on another thread maps its own mesh's ids through
 * it, and the rest of the key split (the renumbering, the key's record)
 * takes about as long again. Called on the thread that grows g, inside
 * mts_grow_next; order is valid during the call only. */
void mts_grow_on_key_order(mts_grow *g, void (*fn)(void *user, const uint32_t *order,
                                                   uint32_t count),
                           void *user);

/* Key paths handed across: a key's restripification (greedy.c) reads the
 * mesh at the key only, which a decoder's mesh-only grow reaches long before
 * the grow that derives the records does, and greedy.c is a sixth of that
 * grow's time on a large mesh. The grow that gets there first stripifies
 * for the other.
 *
 * greedy.c's paths of g's mesh as it is now, as another grow of the same
 * mesh would make them in its restripification here: g's triangle t is
 * that grow's ids[t], and its triangle i g's inv[i] (a permutation and its
 * inverse; both NULL: the same ids). order, in that grow's ids: a triangle
 * count's entries; starts one more (mts_grow_get_figures). MTS_ERR_NOMEM. */
mts_result mts_grow_key_paths(const mts_grow *g, const uint32_t *ids, const uint32_t *inv,
                              uint32_t *order, uint32_t *starts, uint32_t *path_count,
                              mts_error *err);

/* Hands g the paths of its restripification at `level` (its next split's
 * key), in g's ids, for `triangles` triangles: that split renumbers by them
 * in place of stripifying. They stay the caller's, read during that split.
 * Paths that are not a partition of g's triangles there fail that split
 * with MTS_ERR_INTERNAL (and leave g unusable, as any failed split does). */
void mts_grow_give_key_paths(mts_grow *g, uint32_t level, uint32_t triangles,
                             const uint32_t *order, const uint32_t *starts, uint32_t path_count);

/* Rings handed across: two grows of one mesh (a mesh-only grow and the
 * grow whose records are derived on another thread) both walk round the
 * parent of every fan split, a chase of one cache miss a triangle, and the
 * walk is a fifth of a client's time on a large mesh. The grow that walks
 * first hands its ring to the other, which checks it with loads that do not
 * wait on each other in place of walking.
 *
 * The ring of u that g's next split's fan was found in (mts_grow_fan_decode
 * or mts_grow_fan_encode at this level), as corners of g's triangles (3t +
 * corner); NULL when g has no ring of u at hand. Valid until g changes. */
const uint32_t *mts_grow_ring_at_hand(const mts_grow *g, uint32_t u, uint32_t *count,
                                      int *closed);

/* The vertices round u on that ring (each triangle's corner after u, and
 * the last one's before u where the ring is open), at most cap of them into
 * out: the vertices a split of u reads the positions of, known before its
 * fan code is, so that a decoder can ask for those positions early. 0 when
 * g has no ring of u at hand. */
uint32_t mts_grow_ring_vertices(const mts_grow *g, uint32_t u, uint32_t *out, uint32_t cap);

/* Hands g the ring of u for its next split, as another grow of the same mesh
 * found it (mts_grow_ring_at_hand), that grow's triangle t being g's ids[t]
 * (t itself from ids_count on; the renumbering g made at its keys). It is
 * taken only where it is, corner for corner and in order, the ring g's own
 * walk would give (every corner u's, each one's next round u the one after,
 * a closed ring from u's listed corner, an open one from border to border):
 * 1 then, and the split does not walk; 0 otherwise, and it walks as ever. */
int mts_grow_take_ring(mts_grow *g, uint32_t u, const uint32_t *corners, uint32_t count,
                       int closed, const uint32_t *ids, uint32_t ids_count);

/* The grow that takes the rings knows them splits before it grows them, and
 * what a split reads (the ring's triangles, their strips' slots, the slots'
 * indices) is a chain of misses it would take one after another. Each call
 * asks for one link of that chain for the split `ahead` splits on (3: the
 * ids, 2: the triangles, 1: the slots, 0: the slots' indices, as each link
 * needs the one before it in cache), so that by its turn its data is near.
 * Only hints: it reads what g holds now, in bounds, and changes nothing.
 * A mesh that stays in the caches gains nothing and pays for them: the
 * caller asks only past that. */
void mts_grow_prefetch_ring(const mts_grow *g, unsigned ahead, uint32_t u,
                            const uint32_t *corners, uint32_t count, const uint32_t *ids,
                            uint32_t ids_count);

/* The in-order state: each slot's indices and capacity as the intervals
 * derived so far leave them, and the current worker's tokens. The free
 * slots are not part of it: a key empties them and refills them with its
 * empty slots. An error leaves f unusable. */
typedef struct mts_grow_fixup mts_grow_fixup;

mts_result mts_grow_fixup_create(mts_grow_fixup **out, mts_error *err);
void mts_grow_fixup_free(mts_grow_fixup *f);

/* The end of an interval: w's slots (the tokens of the last key given, or
 * before any, a grow from the base, whose slots are the real ones) become
 * the state the next key starts from. w is only read. */
mts_result mts_grow_fixup_end(mts_grow_fixup *f, const mts_grow *w, mts_error *err);

/* A key split's record: rec (words) as the worker gave it for the split to
 * the key (u its parent, v its vertex), from empty slots in its tokens.
 * `full`: the key is the full level, whose slots are the model's (tokens
 * are slots). Maps the tokens to slots as one grow would (by capacity) and
 * gives the real record in *out (owned by f, valid until the next call).
 * MTS_ERR_FORMAT when rec is not such a record. */
mts_result mts_grow_fixup_key(mts_grow_fixup *f, const uint32_t *rec, uint32_t words, uint32_t u,
                              uint32_t v, int full, const uint32_t **out, uint32_t *out_words,
                              mts_error *err);

/* A record between keys, in the tokens of the last key given: the real one
 * in *out (owned by f, valid until the next call). */
mts_result mts_grow_fixup_record(mts_grow_fixup *f, const uint32_t *rec, uint32_t words,
                                 const uint32_t **out, uint32_t *out_words, mts_error *err);

#endif
