#include "build.h"

#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

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

/* The two sides of the build that need nothing of each other -- the
 * full-level strips (stripify, tunnel) and the collapse sequence
 * (simplify, reorder) -- run side by side where threads allow; records
 * need both. Their progress is merged into one bar: both stages' names,
 * the lesser fraction, one report at a time. */
typedef struct build_progress {
    pthread_mutex_t mu;
    int threaded;
    mts_progress user;
    const char *stage[2]; /* 0: the strips' side, 1: the simplifier's */
    double done[2];
    int finished[2];
} build_progress;

static void progress_side(build_progress *bp, int side, const char *stage, double done)
{
    if (!bp->threaded) {
        mts_progress_report(&bp->user, stage, done);
        return;
    }
    pthread_mutex_lock(&bp->mu);
    bp->stage[side] = stage;
    bp->done[side] = done;
    int other = !side;
    char label[48];
    double shown = done;
    if (bp->stage[other] && !bp->finished[other]) {
        snprintf(label, sizeof label, "%s+%s", bp->stage[0], bp->stage[1]);
        shown = bp->done[other] < done ? bp->done[other] : done;
    } else {
        snprintf(label, sizeof label, "%s", stage);
    }
    mts_progress_report(&bp->user, label, shown);
    pthread_mutex_unlock(&bp->mu);
}

static void progress_strips(void *user, const char *stage, double done)
{
    progress_side(user, 0, stage, done);
}

static void progress_simplify(void *user, const char *stage, double done)
{
    progress_side(user, 1, stage, done);
}

typedef struct strips_job {
    const mts_mesh *mesh;
    const mts_build_options *opts;
    build_progress *bp;
    mts_build_report *report; /* its stripify and tunnel fields only */
    mts_strips strips;
    mts_result rc;
    mts_error err;
} strips_job;

/* The full-level strips: greedy, then tunnelling (and their order for the
 * vertex cache); the rest of the pipeline takes whatever strips come out. */
static void *strips_job_run(void *arg)
{
    strips_job *j = arg;
    const mts_mesh *mesh = j->mesh;
    const mts_build_options *opts = j->opts;
    mts_build_report *report = j->report;
    mts_progress progress = {progress_strips, j->bp};
    double t0 = mts_clock_seconds();
    mts_progress_report(&progress, "stripify", 0);
    j->rc = mts_stripify(mesh->triangles, mesh->triangle_count, mesh->vertex_count, &j->strips,
                         &report->stripify, &j->err);
    if (j->rc != MTS_OK)
        goto done;
    mts_progress_report(&progress, "stripify", 1);
    double t05 = mts_clock_seconds();
    if (opts->tunnel_length >= 0) {
        mts_tunnel_options to = {0};
        to.length = opts->tunnel_length ? opts->tunnel_length : MTS_TUNNEL_DEFAULT_LENGTH;
        to.anneal = opts->strip_effort;
        to.max_strip = opts->max_strip;
        to.progress = progress;
        mts_strips tunnelled = {0};
        mts_progress_report(&progress, "tunnel", 0);
        j->rc = mts_tunnel(&j->strips, mesh->vertex_count, &to, &tunnelled, &report->tunnel,
                           &j->err);
        if (j->rc != MTS_OK)
            goto done;
        mts_strips_free(&j->strips);
        j->strips = tunnelled;
        report->tunnel_length = to.length;
        mts_progress_report(&progress, "tunnel", 1);
    } else {
        mts_strip_stats st;
        mts_strips_stats(&j->strips, &st);
        report->tunnel.strips_before = report->tunnel.strips_after = st.strips;
        report->tunnel.swaps_before = report->tunnel.swaps_after = st.degenerate;
        report->tunnel.draw_indices_before = report->tunnel.draw_indices_after =
            mts_strip_stats_draw_indices(&st);
        report->tunnel.triangles = (uint32_t)st.triangles;
    }
    double t1 = mts_clock_seconds();
    report->seconds_stripify = t05 - t0;
    report->seconds_tunnel = t1 - t05;
done:
    if (j->bp->threaded) {
        pthread_mutex_lock(&j->bp->mu);
        j->bp->finished[0] = 1;
        pthread_mutex_unlock(&j->bp->mu);
    }
    return NULL;
}

typedef struct strips_wait {
    strips_job *job;
    pthread_t *thread;
    int *threaded;
    build_progress *bp;
    double waited; /* seconds the records waited for the strips */
} strips_wait;

/* The strips' side joined (once), its strips handed to the records. */
static mts_result join_strips(void *user, const mts_strips **strips, mts_error *err)
{
    strips_wait *w = user;
    if (*w->threaded) {
        double t0 = mts_clock_seconds();
        pthread_join(*w->thread, NULL);
        w->waited = mts_clock_seconds() - t0;
        *w->threaded = 0;
        pthread_mutex_destroy(&w->bp->mu);
        w->bp->threaded = 0;
    }
    if (w->job->rc != MTS_OK) {
        if (err)
            *err = w->job->err;
        return w->job->rc;
    }
    *strips = &w->job->strips;
    return MTS_OK;
}

static uint32_t build_threads(const mts_build_options *opts)
{
    if (opts->threads > 0)
        return opts->threads;
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    return n > 1 ? (uint32_t)n : 1;
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

    mts_simplify_result simp = {0};
    uint32_t *base_ids = NULL;
    mts_result rc;

    build_progress bp = {0};
    bp.user = opts->progress;
    strips_job job = {0};
    job.mesh = mesh;
    job.opts = opts;
    job.bp = &bp;
    job.report = report;
    pthread_t thread;
    int threaded = 0;
    report->threads = 1;
    if (build_threads(opts) > 1 && pthread_mutex_init(&bp.mu, NULL) == 0) {
        bp.threaded = 1;
        /* without threads (a WebAssembly build, a refused thread) the
         * strips are made first, as with --threads 1 */
        threaded = pthread_create(&thread, NULL, strips_job_run, &job) == 0;
        if (!threaded) {
            pthread_mutex_destroy(&bp.mu);
            bp.threaded = 0;
        }
    }
    if (!threaded) {
        strips_job_run(&job);
        if ((rc = job.rc) != MTS_OK) {
            if (err)
                *err = job.err;
            goto done;
        }
    } else {
        report->threads = 2;
    }

    double t1 = mts_clock_seconds();
    mts_simplify_options so = {0};
    so.base_vertices = opts->base_vertices;
    so.colors = mesh->colors;
    so.color_weight = opts->color_cost > 0 ? opts->color_cost
                      : opts->color_cost < 0 ? 0
                                             : MTS_BUILD_DEFAULT_COLOR_COST;
    so.progress = (mts_progress){progress_simplify, &bp};
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
    report->seconds_simplify = t2 - t1;
    double t25 = mts_clock_seconds();

    /* The records need the full strips only at the last split: with threads
     * they start now and wait for the strips' side there (join_strips). */
    strips_wait sw = {&job, &thread, &threaded, &bp, 0};
    mts_lodbuild_options lo = {0};
    lo.key_ratio = opts->key_ratio;
    lo.base_ids = base_ids;
    lo.full_strips = join_strips;
    lo.full_strips_user = &sw;
    mts_progress rp = {threaded ? progress_simplify : opts->progress.fn,
                       threaded ? (void *)&bp : opts->progress.user};
    rc = mts_lodbuild(mesh, threaded ? NULL : &job.strips, &simp, &lo, &rp, model,
                      &report->records, err);
    if (rc == MTS_OK && threaded) /* no last split (nothing to simplify) */
        rc = join_strips(&sw, &(const mts_strips *){NULL}, err);
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

    report->seconds_records = t3 - t25 - sw.waited;
done:
    if (threaded) { /* the simplifier failed: the strips' side ends first */
        pthread_join(thread, NULL);
        pthread_mutex_destroy(&bp.mu);
    }
    mts_strips_free(&job.strips);
    mts_simplify_result_free(&simp);
    free(base_ids);
    return rc;
}
