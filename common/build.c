#include "build.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "clock.h"
#include "simplify.h"

typedef struct survivor {
    float p[3];
    uint32_t v;
} survivor;

static int cmp_survivor(const void *a, const void *b)
{
    const survivor *x = a, *y = b;
    for (int k = 0; k < 3; k++) {
        if (x->p[k] != y->p[k])
            return x->p[k] < y->p[k] ? -1 : 1;
    }
    return x->v < y->v ? -1 : x->v > y->v;
}

/* The base's ids in the order of its positions (x, then y, then z): a
 * stream numbers its base by grid point (PROTOCOL.md, BASE), so with these
 * ids the splits reorder.c sorts by parent stay sorted on the wire (the
 * grid ties a few neighbours that floats keep apart: those few move).
 * NULL when out of memory. */
static uint32_t *base_ids_by_position(const mts_mesh *mesh, const mts_simplify_result *simp)
{
    const uint32_t nv = mesh->vertex_count;
    uint32_t *ids = malloc(((size_t)nv + 1) * 4);
    survivor *sv = malloc(((size_t)nv + 1) * sizeof *sv);
    if (!ids || !sv) {
        free(ids);
        free(sv);
        return NULL;
    }
    for (uint32_t v = 0; v < nv; v++)
        ids[v] = 0;
    for (uint32_t c = 0; c < simp->collapse_count; c++) {
        if (simp->collapses[c].removed < nv)
            ids[simp->collapses[c].removed] = UINT32_MAX;
    }
    uint32_t k = 0;
    for (uint32_t v = 0; v < nv; v++) {
        if (ids[v] != UINT32_MAX) {
            memcpy(sv[k].p, mesh->positions + 3 * (size_t)v, 12);
            sv[k++].v = v;
        }
    }
    qsort(sv, k, sizeof *sv, cmp_survivor);
    for (uint32_t x = 0; x < k; x++)
        ids[sv[x].v] = x;
    free(sv);
    return ids;
}

mts_result mts_build_model(const mts_mesh *mesh, const char *source,
                           const mts_build_options *opts, mts_model *model,
                           mts_build_report *report, mts_error *err)
{
    static const mts_build_options defaults = {0};
    mts_build_report dummy;
    if (!opts)
        opts = &defaults;
    if (!report)
        report = &dummy;
    memset(report, 0, sizeof *report);
    memset(model, 0, sizeof *model);

    mts_strips strips = {0};
    mts_simplify_result simp = {0};
    uint32_t *base_ids = NULL;
    mts_result rc;

    double t0 = mts_clock_seconds();
    mts_progress_report(&opts->progress, "stripify", 0);
    rc = mts_stripify(mesh->triangles, mesh->triangle_count, mesh->vertex_count, &strips,
                      &report->stripify, err);
    if (rc != MTS_OK)
        goto done;
    mts_progress_report(&opts->progress, "stripify", 1);
    double t05 = mts_clock_seconds();

    /* Tunnelling on the greedy strips (and their order for the vertex
     * cache); the rest of the pipeline takes whatever strips come out. */
    if (opts->tunnel_length >= 0) {
        mts_tunnel_options to = {0};
        to.length = opts->tunnel_length ? opts->tunnel_length : MTS_TUNNEL_DEFAULT_LENGTH;
        to.anneal = opts->strip_effort;
        to.max_strip = opts->max_strip;
        to.progress = opts->progress;
        mts_strips tunnelled = {0};
        mts_progress_report(&opts->progress, "tunnel", 0);
        rc = mts_tunnel(&strips, mesh->vertex_count, &to, &tunnelled, &report->tunnel, err);
        if (rc != MTS_OK)
            goto done;
        mts_strips_free(&strips);
        strips = tunnelled;
        report->tunnel_length = to.length;
        mts_progress_report(&opts->progress, "tunnel", 1);
    } else {
        mts_strip_stats st;
        mts_strips_stats(&strips, &st);
        report->tunnel.strips_before = report->tunnel.strips_after = st.strips;
        report->tunnel.swaps_before = report->tunnel.swaps_after = st.degenerate;
        report->tunnel.draw_indices_before = report->tunnel.draw_indices_after =
            mts_strip_stats_draw_indices(&st);
        report->tunnel.triangles = (uint32_t)st.triangles;
    }
    double t1 = mts_clock_seconds();

    mts_simplify_options so = {0};
    so.base_vertices = opts->base_vertices;
    so.progress = opts->progress;
    rc = mts_simplify(mesh->positions, mesh->vertex_count, mesh->triangles, mesh->triangle_count,
                      &so, &simp, err);
    if (rc != MTS_OK)
        goto done;
    double t15 = mts_clock_seconds();
    if (!(base_ids = base_ids_by_position(mesh, &simp))) {
        rc = mts_error_set(err, MTS_ERR_NOMEM, "build: out of memory");
        goto done;
    }
    mts_reorder_options ro = {0};
    ro.window = opts->reorder_window;
    ro.base_ids = base_ids;
    rc = mts_reorder_collapses(mesh->triangles, mesh->triangle_count, mesh->vertex_count,
                               simp.collapses, simp.collapse_count, &ro, &report->reorder, err);
    if (rc != MTS_OK)
        goto done;
    double t2 = mts_clock_seconds();
    report->seconds_reorder = t2 - t15;

    mts_lodbuild_options lo = {0};
    lo.key_ratio = opts->key_ratio;
    lo.base_ids = base_ids;
    rc = mts_lodbuild(mesh, &strips, &simp, &lo, &opts->progress, model, &report->records, err);
    if (rc != MTS_OK)
        goto done;
    /* The same checks a loaded model passes (under 1% of the build): a
     * runtime started at the full level collapses records unchecked, and a
     * model that would not load must not be written. Failing here is a bug
     * in the builder, not bad input. */
    if ((rc = mts_model_validate(model, err)) != MTS_OK) {
        mts_error_prefix(err, "the built model is inconsistent");
        if (err)
            err->code = MTS_ERR_INTERNAL;
        rc = MTS_ERR_INTERNAL;
        mts_model_free(model);
        goto done;
    }
    double t3 = mts_clock_seconds();
    if (source)
        snprintf(model->source, sizeof model->source, "%s", source);

    report->seconds_stripify = t05 - t0;
    report->seconds_tunnel = t1 - t05;
    report->seconds_simplify = t2 - t1;
    report->seconds_records = t3 - t2;
done:
    mts_strips_free(&strips);
    mts_simplify_result_free(&simp);
    free(base_ids);
    return rc;
}
