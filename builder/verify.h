/* Model verification against an independent reference (docs/architecture.md, invariants
 * 1 and 2):
 *   1. at a level l, the oriented non-degenerate triangles of the runtime's
 *      strips equal, as a multiset, the full mesh's triangles (taken from the
 *      full strips) with the collapses down to l replayed on a plain triangle
 *      list -- exact comparison of sorted canonical triangles;
 *   2. the strips at l reached by splitting up from the base equal those
 *      reached by collapsing down from the full level (compared through two
 *      independent 64-bit hashes of every strip's id, length and indices).
 * mts_verify_model walks every level once each way and keeps both sides of
 * invariant 1 as a multiset difference updated by what each split changes, so
 * checking all 37,330 levels of bunny00 takes a fraction of a second; at a
 * failing level the exact sorted comparison names the strip.
 * The first failure is returned with the level and strip it was found at. */
#ifndef MTS_VERIFY_H
#define MTS_VERIFY_H

#include <stdint.h>

#include "error.h"
#include "lod.h"
#include "model.h"
#include "progress.h"

/* Zero-initialised means: every level. */
typedef struct mts_verify_options {
    uint32_t samples; /* check this many levels spread evenly (always 0 and n); 0: all */
    mts_progress progress;
} mts_verify_options;

typedef struct mts_verify_report {
    uint32_t levels_checked;
    uint32_t failed_level; /* valid when the call failed with MTS_ERR_INVARIANT */
    uint32_t failed_strip; /* UINT32_MAX when no single strip is to blame */
} mts_verify_report;

mts_result mts_verify_model(const mts_model *model, const mts_verify_options *opts,
                            mts_verify_report *report, mts_error *err);

/* Invariant 1 at lod's current level alone (for tests that move a runtime
 * around themselves). */
mts_result mts_verify_level(const mts_model *model, const mts_lod *lod,
                            mts_verify_report *report, mts_error *err);

/* What a client that derives records does (grow.h), done here: growth from
 * the base strips, driven by the model's key levels and split descriptions
 * (the full strips at the last split), must give every record of the model
 * word for word. On failure, report->failed_level is the split that
 * differs. */
mts_result mts_verify_growth(const mts_model *model, mts_verify_report *report, mts_error *err);

#endif
