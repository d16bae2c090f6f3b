/* The builder pipeline, mesh in, model out: stripify the full mesh,
 * simplify it (recording collapses), replay the collapses over the strips
 * into records. Shared by mts-build and, later, the server's model catalog. */
#ifndef MTS_BUILD_H
#define MTS_BUILD_H

#include <stdint.h>

#include "error.h"
#include "lodbuild.h"
#include "mesh.h"
#include "model.h"
#include "progress.h"
#include "reorder.h"
#include "stripify.h"
#include "tunnel.h"

/* The colour term's weight a coloured mesh gets by default
 * (mts_build_options.color_cost): a whole-range colour mismatch weighs as a
 * displacement of 0.1% of the bounding-box diagonal. Small enough to leave
 * the geometry of smoothly coloured curved meshes as it was, enough to
 * decide where the quadric is indifferent (flat regions, where it is 0)
 * and to keep sharp colour boundaries; docs/colors.md has the
 * measurements. */
#define MTS_BUILD_DEFAULT_COLOR_COST 1e-6
#define MTS_BUILD_DEFAULT_COLOR_COST_STR "1e-6"

/* Zero-initialised means the defaults. */
typedef struct mts_build_options {
    uint32_t base_vertices; /* 0: max(4, 1% of the vertices) */
    int tunnel_length;      /* longest tunnel (tunnel.h) run on the full strips:
                             * 0: MTS_TUNNEL_DEFAULT_LENGTH; < 0: no tunnelling
                             * pass (nor its cache order) */
    double key_ratio;       /* key levels (lodbuild.h): 0: the default; < 0: only
                             * the base and the full level */
    int strip_effort;       /* annealing moves per triangle in the tunnelling
                             * pass (tunnel.h's anneal): 0: the default; < 0:
                             * none */
    uint32_t max_strip;     /* most triangles in one full-level strip, set by
                             * the tunnelling pass (none without it): 0:
                             * MTS_STRIPIFY_MAX_STRIP */
    uint32_t reorder_window; /* splits sorted by parent within windows of this
                              * many (reorder.h): 0: the default; 1: none */
    /* A coloured mesh's collapses also weigh the colour error they leave
     * (simplify.h's color_weight): 0: MTS_BUILD_DEFAULT_COLOR_COST; < 0:
     * none, the quadric alone. A mesh without colours ignores it. */
    double color_cost;
    /* The full-level strips and the simplification need nothing of each
     * other: with more than one thread they run side by side (the model is
     * the same byte for byte). 0: the processors online; 1: one after the
     * other. */
    uint32_t threads;
    /* Called from both sides when threaded, one call at a time. */
    mts_progress progress;
} mts_build_options;

typedef struct mts_build_report {
    /* each stage's own time; with threads, stripify + tunnel ran beside
     * simplify, so they add up to more than the wall time */
    double seconds_stripify, seconds_tunnel, seconds_simplify, seconds_records;
    uint32_t threads;            /* 2 when the two sides ran side by side */
    double seconds_reorder;      /* of seconds_simplify */
    mts_reorder_stats reorder;
    mts_stripify_stats stripify; /* the greedy stripifier's own figures */
    int tunnel_length;           /* the length used, 0 when the pass was off */
    mts_tunnel_stats tunnel;     /* strips/swaps/draw indices before and after
                                  * (after == before when the pass is off) */
    mts_lodbuild_stats records;
} mts_build_report;

mts_result mts_build_model(const mts_mesh *mesh, const char *source,
                           const mts_build_options *opts, mts_model *model,
                           mts_build_report *report, mts_error *err);

#endif
