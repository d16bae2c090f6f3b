/* LOD builder: replays a collapse sequence over the full-resolution strips
 * and records, for every collapse, which strips change, where the removed
 * vertex becomes the kept one, and which runs of indices it leaves
 * degenerate and removes -- in the hStrips/LodStrips style of paper 001
 * (Ramos, Gumbau, Chover, "An efficient approach to render 3D meshes by
 * managing multiresolution triangle strips"), stored inverted as splits in
 * stream order (see model.h).
 *
 * Run removal keeps every triangle and its winding (DESIGN.md invariant 1): a
 * run is removed only when the strip's oriented non-degenerate triangles are
 * the same multiset before and after, which an exact local test decides
 * (the windows the run touches against the windows that span the join, and
 * no parity flip of non-degenerate triangles after it). Paper 001's aa(a)+ and
 * ab(ab)+ patterns are special cases; its aaa -> aa would flip the winding of
 * the rest of the strip, so it is not done. */
#ifndef MTS_LODBUILD_H
#define MTS_LODBUILD_H

#include <stdint.h>

#include "error.h"
#include "mesh.h"
#include "model.h"
#include "progress.h"
#include "simplify.h"
#include "strips.h"

typedef struct mts_lodbuild_stats {
    uint64_t edits;           /* (record, strip) pairs */
    uint64_t substitutions;   /* positions where a vertex changes */
    uint64_t removed_runs;    /* degenerate runs removed over all collapses */
    uint64_t removed_indices; /* indices in those runs */
    uint64_t emptied_strips;  /* strips that vanish on the way to the base */
} mts_lodbuild_stats;

/* mesh: the full mesh the strips and collapses refer to (original ids);
 * strips: its full-resolution strips; simp: its collapse sequence. The model
 * gets stream-ordered copies of everything; stats and progress may be NULL. */
mts_result mts_lodbuild(const mts_mesh *mesh, const mts_strips *strips,
                        const mts_simplify_result *simp, const mts_progress *progress,
                        mts_model *model, mts_lodbuild_stats *stats, mts_error *err);

#endif
