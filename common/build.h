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
#include "stripify.h"

/* Zero-initialised means the defaults. */
typedef struct mts_build_options {
    uint32_t base_vertices; /* 0: max(4, 1% of the vertices) */
    mts_progress progress;
} mts_build_options;

typedef struct mts_build_report {
    double seconds_stripify, seconds_simplify, seconds_records;
    mts_stripify_stats stripify;
    mts_lodbuild_stats records;
} mts_build_report;

mts_result mts_build_model(const mts_mesh *mesh, const char *source,
                           const mts_build_options *opts, mts_model *model,
                           mts_build_report *report, mts_error *err);

#endif
