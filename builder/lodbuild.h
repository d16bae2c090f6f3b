/* LOD builder: turns a collapse sequence and the full-resolution strips into
 * the per-split strip records of a model (see model.h), building the strips
 * from the base upward.
 *
 * Replaying collapses downward over the full-level strips (paper 001's
 * hStrips) leaves them fragmented and full of degenerate triangles as the
 * mesh coarsens: 1.8 indices per drawn triangle at half the vertices and 4
 * at the base on bunny00. Upward, a split only ever opens the two edges it
 * brings back triangles on, and a strip that crossed such an edge still runs
 * on through the new triangle: each new triangle is inserted into the strip
 * that crossed its edge, appended to a strip that ends next to it (joining
 * two strips when it sits between two ends), or starts a strip of its own.
 * Strips so grown stay long, but every inserted triangle usually costs a
 * swap, so at key levels -- where the triangle count has grown by the key
 * ratio since the last -- the mesh is stripified afresh (the greedy
 * stripifier; at the base also tunnelling, and at the full level the
 * caller's strips, typically tunnelled). A key level is a record like any
 * other: it erases the old strips and inserts the new ones, so the same
 * records still move both ways.
 *
 * The growth itself is common/grow.c, which a streaming client runs too: the
 * builder here works out each split's description from the collapse chains
 * (checking the fan rule against them), drives grow.c with it, and keeps
 * both the records and the descriptions in the model.
 *
 * A strip is kept as a path of triangles on the dual graph; its indices are
 * derived from the path alone (the first triangle's third vertex and the
 * edge it shares with the second, then one index per triangle, plus a swap
 * where the path turns the same way twice), and a split's record for a slot
 * is the smallest erase + insert that turns the old indices into the new,
 * with the new vertex brought in by substitution (so inserted runs only name
 * vertices that exist before the split). */
#ifndef MTS_LODBUILD_H
#define MTS_LODBUILD_H

#include <stdint.h>

#include "error.h"
#include "mesh.h"
#include "model.h"
#include "progress.h"
#include "simplify.h"
#include "strips.h"

/* Key levels: one once the strips draw more than MTS_LODBUILD_KEY_QUALITY
 * indices a triangle (restarts counted) and the triangles have grown by
 * MTS_LODBUILD_KEY_MIN_RATIO since the last key, or once they have grown by
 * the key ratio. Chosen by measurement on cow, bunny00 and fandisk_large
 * (docs/client-cost.md). */
#define MTS_LODBUILD_DEFAULT_KEY_RATIO 1.7
#define MTS_LODBUILD_DEFAULT_KEY_RATIO_STR "1.7"
#define MTS_LODBUILD_KEY_QUALITY 1.55
#define MTS_LODBUILD_KEY_QUALITY_STR "1.55"
#define MTS_LODBUILD_KEY_MIN_RATIO 1.2

/* Zero-initialised means the defaults. */
typedef struct mts_lodbuild_options {
    double key_ratio; /* 0: the default; > 1: a key level at the latest each
                       * time the triangles grow by this factor; < 0 (or in
                       * (0, 1]): only the base and the full level are keys */
    /* per vertex of the mesh, its id when it survives into the base (0..nb-1,
     * each once; MTS_ERR_ARG otherwise); NULL: survivors in vertex order */
    const uint32_t *base_ids;
    /* The full strips may come late: they are needed only at the last split
     * (the full level adopts them), so a builder that makes them beside the
     * records passes strips NULL and this, called once before the last split
     * (it may wait), to hand them over. */
    mts_result (*full_strips)(void *user, const mts_strips **strips, mts_error *err);
    void *full_strips_user;
} mts_lodbuild_options;

typedef struct mts_lodbuild_stats {
    uint64_t edits;            /* (record, strip) pairs */
    uint64_t substitutions;    /* positions where the parent becomes the new vertex */
    uint64_t erased_indices;   /* over all records */
    uint64_t inserted_indices; /* over all records */
    uint32_t key_levels;       /* restripified levels, the base and the full level included */
    uint64_t grown_inserted;   /* new triangles inserted into a strip crossing their edge */
    uint64_t grown_appended;   /* ... appended at a strip's end */
    uint64_t grown_joined;     /* ... joining two strips */
    uint64_t grown_alone;      /* ... starting a strip of their own */
    uint64_t strips_cut;       /* strips a split broke without a triangle to mend them */
    uint64_t explicit_splits;  /* splits the fan rule does not describe (grow.h) */
} mts_lodbuild_stats;

/* mesh: the full mesh the strips and collapses refer to (original ids);
 * strips: its full-resolution strips; simp: its collapse sequence. The model
 * gets stream-ordered copies of everything; opts, stats and progress may be
 * NULL. */
mts_result mts_lodbuild(const mts_mesh *mesh, const mts_strips *strips,
                        const mts_simplify_result *simp, const mts_lodbuild_options *opts,
                        const mts_progress *progress, mts_model *model,
                        mts_lodbuild_stats *stats, mts_error *err);

#endif
