/* Strip growth: derives each split's strip record (model.h's format) from the
 * vertex split alone, the same way on the builder and on a client.
 *
 * Why a module of its own: the records are most of the bytes of a stream
 * that carries them (bunny00's records form is 25 times its splits form),
 * yet everything in them follows from
 * which triangles a split brings back and the rules that grow strips upward
 * (lodbuild.h). A client that runs these rules on the splits it receives
 * needs only the split itself on the wire: the parent, the two vertices the
 * new triangles open onto, and the new vertex's position. Builder and client
 * call the same code on the same inputs in the same order, so the records
 * agree by construction; lodbuild.c checks every split's triangles against
 * the full mesh's collapse chains and describes a split explicitly where the
 * fan rule below would not reproduce them.
 *
 * Everything here depends only on the order of the inputs and on equality of
 * vertex ids, never on their values, so renumbering vertices (as the stream
 * does to the base) renumbers the records and nothing else.
 *
 * Triangle ids: the base strips' non-degenerate windows in order, then per
 * split its new triangles in order. Keys (levels restripified afresh) are the
 * levels the caller lists, plus the full level, whose strips the caller
 * gives (typically tunnelled, which a client could not afford to redo). */
#ifndef MTS_GROW_H
#define MTS_GROW_H

#include <stdint.h>

#include "bigmem.h"
#include "bytes.h"
#include "error.h"
#include "model.h"
#include "strips.h"

#define MTS_GROW_NONE UINT32_MAX

/* Split j brings back vertex v = nb + j next to its parent u. By the fan rule
 * it brings back the triangles (u, v, left) and (v, u, right), either
 * MTS_GROW_NONE on a border, and v takes over the triangles around u from the
 * one holding the edge u->right round to the one holding left->u. A split
 * the rule does not describe lists its triangles instead: `moved` names the
 * triangles whose corner u becomes v, and `born` gives the new triangles (3
 * vertex ids each, as they are at level j + 1). */
typedef struct mts_grow_split {
    uint32_t parent;
    uint32_t left, right;
    uint32_t moved_count;
    const uint32_t *moved;
    uint32_t born_count;
    const uint32_t *born;
} mts_grow_split;

/* Zero-initialised means defaults. */
typedef struct mts_grow_options {
    /* Ascending levels in 1..n-1 that are restripified afresh. With
     * key_levels NULL, a level is a key once its triangles have grown by
     * key_ratio (> 1) since the last key, or, with key_quality > 0, once
     * they have grown by key_min_ratio and the strips draw more than
     * key_quality indices a triangle (restarts counted); mts_grow_keys()
     * lists the keys so chosen. */
    const uint32_t *key_levels;
    uint32_t key_count;
    double key_ratio;
    double key_quality, key_min_ratio;
    /* The builder's first pass: base strips in any form (a strip that does
     * not chain is split over slots, the longest go first); the form growth
     * derives is then what mts_grow_slot() gives at level 0. Otherwise slot s
     * holds base strip s, which must already be in that form. */
    int normalise_base;
    /* Where the large arrays' reservations come from (bigmem.h); NULL: the
     * kernel. The grows a client makes share its cache. */
    mts_bigmem_cache *memory;
} mts_grow_options;

typedef struct mts_grow mts_grow;

/* base: the strips at level 0 (slot s holds strip s; slots may be empty).
 * level_count: n, the number of splits; vertex ids run below nb + n. */
mts_result mts_grow_create(const mts_strips *base, uint32_t base_vertex_count,
                           uint32_t level_count, const mts_grow_options *opts, mts_grow **out,
                           mts_error *err);
void mts_grow_free(mts_grow *g);
/* Sets where g's large arrays take their reservations from (bigmem.h), for
 * a grow made without options. */
void mts_grow_use_memory(mts_grow *g, mts_bigmem_cache *memory);

/* The full level's strips, which a client cannot afford to compute (they
 * are tunnelled): the builder gives them as strips in any form, and the
 * strips growth derives from their paths become the full level; a client
 * gives their description (mts_grow_full_describe) instead. */
typedef struct mts_grow_full_path {
    uint32_t triangles; /* 0: an empty slot */
    uint32_t first;     /* the id of its first triangle at the full level */
    uint32_t rotation;  /* 0..2: the strip starts at this corner of it */
    /* set by mts_grow_full_describe: the triangles next to the strip before
     * it (the previous non-empty slot's) that no earlier strip holds, as the
     * walk lists them (mts_grow_full.start), and first's place among them
     * (MTS_GROW_NONE: not there) */
    uint32_t near_count, near;
} mts_grow_full_path;

typedef struct mts_grow_full {
    const mts_strips *strips;
    /* or per slot its path, and one byte per inner triangle of every strip
     * in slot order: bit 0 whether the strip swaps there */
    const mts_grow_full_path *paths;
    const uint8_t *swaps;
    uint64_t swap_count;
    uint32_t slot_count; /* with paths: the model's slots */
    /* or, with paths and no swaps, where the bits come from as the paths
     * are walked: only the bits the walk does not force (a strip that goes
     * on and finds one way on open, the other a border or a triangle a strip
     * before it holds, has no choice). `previous` is the bit before,
     * forced or not (0 for the first): a context for a coder. Returns the
     * bit, 0 or 1. */
    unsigned (*swap_bit)(void *user, unsigned previous);
    /* and, optionally, where each strip's start comes from as the walk gets
     * there (paths' first and rotation are then not read): handed the
     * triangles next to the strip before that no strip holds yet, in a
     * fixed order (a strip of tunnelled strips often starts among them).
     * Sets *near_at to the start's place among them, or leaves it
     * MTS_GROW_NONE and sets *first to the start's id; and *rotation.
     * Returns 0 when the source is broken. */
    int (*start)(void *user, const uint32_t *near, uint32_t near_count, uint32_t *near_at,
                 uint32_t *first, uint32_t *rotation);
    void *user;
    /* A start's id from `start` names a triangle of another grow of this
     * mesh: the walked grow's triangle first_ids[first] (first itself from
     * first_id_count on). NULL: the walked grow's own ids. */
    const uint32_t *first_ids;
    uint32_t first_id_count;
    /* or the strips already walked, as growth derives them, one a slot
     * (mts_grow_full_strips, on another grow of this mesh): the slots take
     * them as they are, and the grow keeps no paths past the full level
     * (mts_grow_check then checks its mesh only). */
    const mts_strips *derived;
} mts_grow_full;

/* Walks a description of the full strips (paths and swap bits as above, as
 * a client receives them) over g's mesh at the full level -- a mesh-only
 * grow's too (grow_tokens.h) -- into the strips growth derives from it, one
 * a slot (f->slot_count, an empty slot empty): what mts_grow_next makes the
 * slots at the full level, for a grow of the same mesh to take as
 * mts_grow_full.derived. They name vertices only, so a mesh in other
 * triangle ids gives the same. out's arrays are allocated (mts_strips_free).
 * MTS_ERR_FORMAT as the last split gives it on a broken description;
 * MTS_ERR_ARG when g is not at the full level. */
mts_result mts_grow_full_strips(const mts_grow *g, const mts_grow_full *f, mts_strips *out,
                                mts_error *err);

/* Describes the full strips (in the form growth derives, as the builder
 * left them in the model) as a client can resolve them on its own mesh:
 * g must be at the full level. paths holds full->strip_count entries,
 * swaps room for full->index_count bytes; *swap_count is set, and each
 * swap byte is the bit (bit 0) and whether the walk forces it (bit 1), so
 * an encoder sends only the others (mts_grow_full's swap_bit). About 2
 * bytes a strip and under half a bit a triangle once entropy-coded, where
 * the strips' indices would take 1.3 to 2 bytes each. MTS_ERR_ARG when g
 * is not at the full level, a strip is not in that form or does not start
 * on a triangle of g's mesh; MTS_ERR_FORMAT when the strips overlap. */
mts_result mts_grow_full_describe(const mts_grow *g, const mts_strips *full,
                                  mts_grow_full_path *paths, uint8_t *swaps, uint64_t *swap_count,
                                  mts_error *err);

/* Applies the next split (level l to l + 1) and gives its record in
 * model.h's format: *record points at *word_count words owned by g, valid
 * until the next call. The last split needs `full`; elsewhere it is
 * ignored. A split that names no live triangle or contradicts the mesh
 * gives MTS_ERR_FORMAT and leaves g unusable; a mesh-only grow
 * (grow_tokens.h) gives MTS_ERR_ARG. */
mts_result mts_grow_next(mts_grow *g, const mts_grow_split *split, const mts_grow_full *full,
                         const uint32_t **record, uint32_t *word_count, mts_error *err);

/* The triangles the fan rule gives split's vertex (ids, ascending walk
 * order), without applying anything: at most cap are written, the count is
 * returned, or -1 when the rule does not apply (no fan from right to left). */
int32_t mts_grow_fan(const mts_grow *g, uint32_t parent, uint32_t left, uint32_t right,
                     uint32_t *ids, uint32_t cap);

/* The live triangle holding the directed edge a->b and the third vertex c
 * (in that rotation), or -1. */
int32_t mts_grow_find(const mts_grow *g, uint32_t a, uint32_t b, uint32_t c);

/* The compact form of a fan-rule split, what a stream carries: the
 * parent's triangles in ring order (from the border when the parent is on
 * one, else from the triangle of its listed corner, turning as the fan
 * does), `start`
 * the ring position of the first triangle v takes over, `count` how many it
 * takes, and `sides` bit 0 set when there is no `right` new triangle, bit 1
 * when there is no `left` one. Encoding fails (returns 0) when the split is
 * not a fan of the current mesh; decoding fails on a code that names no
 * fan. Only ring order matters, never vertex values. Both use g's
 * scratch, hence the non-const g. */
typedef struct mts_grow_fan_code {
    uint32_t start, count, sides;
} mts_grow_fan_code;

int mts_grow_fan_encode(mts_grow *g, uint32_t parent, uint32_t left, uint32_t right,
                        mts_grow_fan_code *code);
/* The triangles round u at g's level (its ring, as fan codes count it) and
 * whether it closes; -1 when u has none. What a fan code is coded against:
 * both ends know it before the code. */
int32_t mts_grow_ring_size(mts_grow *g, uint32_t u, int *closed);
int mts_grow_fan_decode(mts_grow *g, uint32_t parent, const mts_grow_fan_code *code,
                        uint32_t *left, uint32_t *right);

/* After a split: the two other corners (a, b) of every triangle around its
 * new vertex v, in the triangle's order after v (so it is (v, a, b) as
 * drawn), pair by pair. Each ring vertex of an interior v comes twice, so
 * their mean is the ring's centroid -- what a stream predicts v's position
 * from, since both ends know the ring before they know v -- and the pairs
 * give the faces' normals, which predict v's. *ids points into g's scratch
 * (valid until the next call). MTS_ERR_ARG before any split. */
mts_result mts_grow_around_newest(mts_grow *g, const uint32_t **ids, uint32_t *count,
                                  mts_error *err);

/* Split j of a model as mts_grow_next takes it, from the model's split
 * description (model.h: a fan code decoded against g, now at level j, or
 * the explicit lists, which sp then points into). 0 when the description
 * is malformed or names no fan of g's mesh. */
int mts_grow_model_split(mts_grow *g, const mts_model *m, uint32_t j, mts_grow_split *sp);

/* Checks g's whole state against what it stands for, for tests: every
 * twin against the directed edges, every corner in its vertex's list, the
 * paths (links between neighbours, slots, counts, every triangle placed)
 * and every slot's indices against a derivation of its path from scratch
 * (which a split does only where the path changed). MTS_ERR_INTERNAL names
 * the first difference. O(triangles x valence). */
mts_result mts_grow_check(const mts_grow *g, mts_error *err);

/* Vertex ids of triangle t, as they are now. */
void mts_grow_triangle(const mts_grow *g, uint32_t t, uint32_t out[3]);

typedef struct mts_grow_figures {
    uint32_t level;
    uint32_t triangles;    /* live */
    uint32_t strips;       /* non-empty slots */
    uint64_t indices;      /* over all slots */
    uint32_t slot_count;   /* slots so far */
    const uint32_t *capacity; /* slot_count: longest each slot has been */
    uint64_t edits, substitutions, erased_indices, inserted_indices;
    uint64_t grown_inserted, grown_appended, grown_joined, grown_alone, strips_cut;
    uint32_t key_count;    /* keys so far, the base included */
} mts_grow_figures;

void mts_grow_get_figures(const mts_grow *g, mts_grow_figures *out);

/* The keys so far (levels in 1..n), ascending; the full level included once
 * reached. */
const uint32_t *mts_grow_keys(const mts_grow *g, uint32_t *count);

/* The indices of slot s now. */
const uint32_t *mts_grow_slot(const mts_grow *g, uint32_t s, uint32_t *length);

#endif
