/* mts-bench: the figures bench/run.sh reports for a few meshes -- build time
 * per stage, strip quality at the full level against meshoptimizer and a
 * plain triangle list, strip quality at a few fractions of the full mesh,
 * the runtime's sweep time and memory, paper 000's Table 2 level walks (with
 * and without coherence) and Table 1's model sizes. Prints aligned tables on
 * stdout and, with --json FILE, writes the same figures as one line of JSON.
 *
 * Vertex-cache figures use a FIFO post-transform cache (the model
 * meshoptimizer's analyzer and the strip literature use): a hit does not
 * refresh an entry, a miss evicts the oldest. ACMR is misses per drawn
 * triangle, so degenerate windows cost only the index fetch, as on a GPU. */
#include <math.h>
#include <meshoptimizer.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "bench_common.h"
#include "build.h"
#include "cli.h"
#include "lod.h"
#include "mesh.h"
#include "model.h"
#include "modelfile.h"
#include "strips.h"

#define RESTART UINT32_MAX /* primitive restart marker, as GL's fixed index */
#define WALK_STEPS 100     /* paper 000, Table 2: 100 levels per walk */
#define WALK_SEED 20030101u /* fixed, so the random walk is the same every run */
#define MAX_RUNS 15

/* Fractions of the full vertex count the level table samples. */
static const double level_fractions[] = {1.0, 0.5, 0.25, 0.1, 0.05, 0.01};
#define LEVEL_ROWS (sizeof level_fractions / sizeof level_fractions[0])
/* Paper 004 Table 1: its model at 13, 27 and 52% ("LOD%"), with maximal
 * tunnel length 13, its best column: strips, isolated triangles, mean strip
 * length. The model is not among the shared ones, so only the shape of the
 * strips (mean length, isolated share) compares. */
static const double p4_fractions[3] = {0.13, 0.27, 0.52};
static const double p4_paper[3][3] = {{489, 46, 152.10}, {869, 52, 147.59}, {1489, 107, 199.70}};

enum { WALK_LINEAR, WALK_EXPONENTIAL, WALK_RANDOM, WALK_KINDS };
static const char *const walk_names[WALK_KINDS] = {"linear", "exponential", "random"};

/* Paper 000 (Belmonte et al., "Multiresolution triangle strips"), Tables 1
 * and 2, for the models we share with it. Their bunny is the 34834-vertex
 * Stanford one; bunny00 here has 37706 vertices, so sizes compare loosely.
 * Times are from a 550 MHz Pentium III. */
typedef struct paper_row {
    const char *stem;   /* our file's name without extension */
    const char *name;   /* theirs */
    uint32_t strips, triangles, vertices;
    double mts_mb, pm_mb, momfan_mb;
    /* Table 3, full level: thousands of vertices sent and of triangles
     * drawn (0: not given). Sent counts each strip's indices, swaps
     * included, one draw per strip: no restart markers. */
    double sent_k, drawn_k;
    double walk_ms[WALK_KINDS][2]; /* [kind][0 coherent, 1 without] */
} paper_row;

static const paper_row paper_rows[] = {
    {"cow", "Cow", 136, 5804, 2904, 0.253, 0.256, 0.202, 0, 0,
     {{0.469, 1.519}, {0.389, 1.713}, {1.560, 1.640}}},
    {"bunny00", "Bunny", 1229, 69451, 34834, 2.964, 2.993, 2.245, 83, 69.4,
     {{15.197, 27.120}, {13.052, 29.067}, {27.500, 27.965}}},
};

static const paper_row *paper_for(const char *stem)
{
    for (size_t i = 0; i < sizeof paper_rows / sizeof paper_rows[0]; i++)
        if (!strcmp(paper_rows[i].stem, stem))
            return &paper_rows[i];
    return NULL;
}

/* ---- FIFO vertex cache ------------------------------------------------ */

/* stamp[v] is the miss count right after v entered the cache (0: never); the
 * entries still cached are the last `size` misses, so v hits iff
 * stamp[v] + size > misses. O(1) per index, no queue to maintain. */
typedef struct fifo_cache {
    uint32_t size;
    uint32_t vertex_count;
    uint64_t misses;
    uint64_t *stamp;
} fifo_cache;

static int fifo_init(fifo_cache *c, uint32_t size, uint32_t vertex_count)
{
    c->size = size;
    c->vertex_count = vertex_count;
    c->misses = 0;
    c->stamp = calloc((size_t)vertex_count + 1, sizeof *c->stamp);
    return c->stamp != NULL;
}

static void fifo_reset(fifo_cache *c)
{
    c->misses = 0;
    memset(c->stamp, 0, ((size_t)c->vertex_count + 1) * sizeof *c->stamp);
}

static void fifo_free(fifo_cache *c)
{
    free(c->stamp);
    c->stamp = NULL;
}

/* Restart markers are not vertices: they neither hit nor miss. An index out
 * of range (a bug elsewhere) is counted as a miss rather than read past the
 * array. */
static void fifo_feed(fifo_cache *c, const uint32_t *idx, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        uint32_t v = idx[i];
        if (v == RESTART)
            continue;
        if (v >= c->vertex_count) {
            c->misses++;
            continue;
        }
        if (c->stamp[v] == 0 || c->stamp[v] + c->size <= c->misses)
            c->stamp[v] = ++c->misses;
    }
}

/* ---- results ---------------------------------------------------------- */

typedef struct build_times {
    double load, stripify, tunnel, simplify, records, write, total;
} build_times;

typedef struct level_row {
    double fraction;
    uint32_t level, vertices;
    int clamped; /* the fraction asks for fewer vertices than the base has */
    mts_strip_stats stats;
    double indices_per_triangle; /* with restarts, per drawn triangle */
    double degenerate_share;     /* degenerate windows / all windows */
    double acmr16;
} level_row;

typedef struct strip_figures {
    uint32_t strips;
    uint64_t swaps, restarts; /* degenerate windows; one restart between strips */
    uint64_t draw_indices; /* with restarts */
    double indices_per_triangle, acmr16, acmr32;
    /* as paper 000 counts: swaps in, no restart markers (one draw a strip) */
    double indices_per_triangle_no_restarts;
} strip_figures;

typedef struct model_result {
    char path[1024], name[256];
    int missing, failed;
    char error[MTS_ERROR_MSG_SIZE + 64];
    uint64_t input_bytes;

    uint32_t vertices, triangles, base_vertices, base_triangles, levels;
    int runs;
    build_times build; /* medians */
    mts_stripify_stats stripify;

    strip_figures ours, meshopt;
    strip_figures greedy;   /* mts_stripify alone, before tunnelling */
    int tunnel_length;      /* the build's (0: off) */
    double meshopt_seconds;         /* optimizeVertexCache + stripify */
    double list_acmr16, list_acmr32; /* meshopt-optimized triangle list */
    double list_acmr16_analyzer;     /* meshopt_analyzeVertexCache, to check our FIFO */
    uint64_t cost_bound;             /* mts_stripify_cost_bound: 3 S + W no cover goes under */

    level_row level[LEVEL_ROWS];
    /* over every level, from the model's level table */
    uint32_t worst_level, key_levels, worst_triangles, worst_strips;
    /* paper 004 Table 1's LOD fractions of the triangles: strips, isolated
     * triangles, mean strip length */
    uint32_t p4_level[3], p4_strips[3], p4_isolated[3];
    double p4_mean[3];
    double worst_ipt, worst_degenerate_share;

    double sweep_ms, up_ms, down_ms; /* medians */
    int sweep_reps;
    uint64_t lod_bytes, model_bytes, indexed_bytes;

    double walk_ms[WALK_KINDS][2]; /* mean per extraction; [0] coherent, [1] without */
    int walk_reps;

    uint64_t file_bytes;
    const paper_row *paper;
} model_result;

typedef struct bench_options {
    int runs;      /* builds per model; the median is reported */
    int reps;      /* repetitions of each sweep and walk; the median is reported */
    double budget; /* seconds a walk cell may take before it stops repeating */
} bench_options;

/* ---- helpers ---------------------------------------------------------- */

static double median(double *v, int n)
{
    qsort(v, (size_t)n, sizeof *v, bench_cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* splitmix64: a tiny, well-mixed generator whose state the caller owns. */
static uint64_t splitmix64(uint64_t *state)
{
    uint64_t z = (*state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

static void fail(model_result *r, const char *what, const mts_error *err)
{
    r->failed = 1;
    snprintf(r->error, sizeof r->error, "%s: %s", what, err->msg);
}

/* ---- the measurements --------------------------------------------------- */

/* Loads and builds `runs` times; keeps the last mesh and model. */
static int bench_build(model_result *r, const bench_options *o, mts_mesh *mesh,
                       mts_model *model)
{
    double t[7][MAX_RUNS];
    mts_error err = {0};
    for (int i = 0; i < o->runs; i++) {
        mts_mesh_free(mesh);
        mts_model_free(model);
        double t0 = cli_now();
        if (mts_mesh_load(r->path, NULL, mesh, NULL, &err) != MTS_OK) {
            fail(r, "load", &err);
            return 0;
        }
        double t1 = cli_now();
        mts_build_report rep;
        if (mts_build_model(mesh, r->path, NULL, model, &rep, &err) != MTS_OK) {
            fail(r, "build", &err);
            return 0;
        }
        double t2 = cli_now();
        uint8_t *data = NULL;
        size_t size = 0;
        if (mts_modelfile_encode(model, &data, &size, &err) != MTS_OK) {
            fail(r, "encode", &err);
            return 0;
        }
        double t3 = cli_now();
        free(data);
        t[0][i] = t1 - t0;
        t[1][i] = rep.seconds_stripify;
        t[2][i] = rep.seconds_simplify;
        t[3][i] = rep.seconds_records;
        t[4][i] = t3 - t2;
        /* the stages plus what build does between them (copies, frees) */
        t[5][i] = t3 - t0;
        t[6][i] = rep.seconds_tunnel;
        r->stripify = rep.stripify;
        r->tunnel_length = rep.tunnel_length;
        r->key_levels = rep.records.key_levels;
        r->file_bytes = size;
    }
    r->runs = o->runs;
    r->build.load = median(t[0], o->runs);
    r->build.stripify = median(t[1], o->runs);
    r->build.simplify = median(t[2], o->runs);
    r->build.records = median(t[3], o->runs);
    r->build.write = median(t[4], o->runs);
    r->build.total = median(t[5], o->runs);
    r->build.tunnel = median(t[6], o->runs);

    /* Validation is untimed: it tells a broken library from slow figures. */
    if (mts_model_validate(model, &err) != MTS_OK) {
        fail(r, "validate", &err);
        return 0;
    }
    uint32_t n = model->level_count;
    r->vertices = model->vertex_count;
    r->triangles = model->level_triangles[n];
    r->base_vertices = model->base_vertex_count;
    r->base_triangles = model->level_triangles[0];
    r->levels = n;
    return 1;
}

static double ratio(uint64_t num, uint64_t den)
{
    return den ? (double)num / (double)den : NAN;
}

/* Figures of strips joined by restarts, per triangle of the mesh. */
static void strips_figures(const mts_strips *full, uint32_t triangle_count, fifo_cache *c16,
                           fifo_cache *c32, strip_figures *f)
{
    mts_strip_stats st;
    mts_strips_stats(full, &st);
    const uint32_t restart = RESTART;
    int first = 1;
    fifo_reset(c16);
    fifo_reset(c32);
    for (uint32_t s = 0; s < full->strip_count; s++) {
        uint32_t len = full->offsets[s + 1] - full->offsets[s];
        if (!len)
            continue;
        if (!first) { /* a restart between strips matters to nothing but the count */
            fifo_feed(c16, &restart, 1);
            fifo_feed(c32, &restart, 1);
        }
        first = 0;
        fifo_feed(c16, full->indices + full->offsets[s], len);
        fifo_feed(c32, full->indices + full->offsets[s], len);
    }
    /* per triangle of the mesh: were the strips to draw extra (bad)
     * triangles, they would not make the figures look better */
    f->strips = st.strips;
    f->swaps = st.degenerate;
    f->restarts = st.strips ? st.strips - 1 : 0;
    f->draw_indices = mts_strip_stats_draw_indices(&st);
    f->indices_per_triangle = ratio(f->draw_indices, triangle_count);
    f->indices_per_triangle_no_restarts = ratio(f->draw_indices - f->restarts, triangle_count);
    f->acmr16 = ratio(c16->misses, triangle_count);
    f->acmr32 = ratio(c32->misses, triangle_count);
}

/* Our full strips, joined by restarts, against the greedy stripifier's
 * alone (before tunnelling), meshoptimizer's strips and its cache-optimized
 * triangle list. */
static int bench_full(model_result *r, const mts_mesh *mesh, const mts_model *model)
{
    int ok = 0;
    size_t list_n = (size_t)mesh->triangle_count * 3;
    uint32_t *opt = malloc(list_n * sizeof *opt);
    uint32_t *strip = malloc(meshopt_stripifyBound(list_n) * sizeof *strip);
    fifo_cache c16 = {0}, c32 = {0};
    if (!opt || !strip || !fifo_init(&c16, 16, model->vertex_count) ||
        !fifo_init(&c32, 32, model->vertex_count)) {
        snprintf(r->error, sizeof r->error, "out of memory for the cache figures");
        r->failed = 1;
        goto done;
    }

    strips_figures(&model->full, mesh->triangle_count, &c16, &c32, &r->ours);
    {
        mts_strips greedy = {0};
        mts_error err = {0};
        if (mts_stripify(mesh->triangles, mesh->triangle_count, mesh->vertex_count, &greedy, NULL,
                         &err) != MTS_OK) {
            fail(r, "stripify", &err);
            goto done;
        }
        strips_figures(&greedy, mesh->triangle_count, &c16, &c32, &r->greedy);
        mts_strips_free(&greedy);
        if (mts_stripify_cost_bound(mesh->triangles, mesh->triangle_count, mesh->vertex_count,
                                    &r->cost_bound, &err) != MTS_OK) {
            fail(r, "stripify bound", &err);
            goto done;
        }
    }

    /* meshoptimizer: its stripifier wants a cache-optimized list first */
    double t0 = cli_now();
    meshopt_optimizeVertexCache(opt, mesh->triangles, list_n, mesh->vertex_count);
    size_t sn = meshopt_stripify(strip, opt, list_n, mesh->vertex_count, RESTART);
    r->meshopt_seconds = cli_now() - t0;
    uint32_t restarts = 0;
    for (size_t i = 0; i < sn; i++)
        restarts += strip[i] == RESTART;
    fifo_reset(&c16);
    fifo_reset(&c32);
    fifo_feed(&c16, strip, sn);
    fifo_feed(&c32, strip, sn);
    r->meshopt.strips = sn ? restarts + 1 : 0;
    r->meshopt.restarts = restarts;
    r->meshopt.draw_indices = sn;
    r->meshopt.indices_per_triangle = ratio(sn, mesh->triangle_count);
    r->meshopt.indices_per_triangle_no_restarts = ratio(sn - restarts, mesh->triangle_count);
    r->meshopt.acmr16 = ratio(c16.misses, mesh->triangle_count);
    r->meshopt.acmr32 = ratio(c32.misses, mesh->triangle_count);

    fifo_reset(&c16);
    fifo_reset(&c32);
    fifo_feed(&c16, opt, list_n);
    fifo_feed(&c32, opt, list_n);
    r->list_acmr16 = ratio(c16.misses, mesh->triangle_count);
    r->list_acmr32 = ratio(c32.misses, mesh->triangle_count);
    r->list_acmr16_analyzer =
        meshopt_analyzeVertexCache(opt, list_n, mesh->vertex_count, 16, 0, 0).acmr;
    ok = 1;
done:
    fifo_free(&c16);
    fifo_free(&c32);
    free(opt);
    free(strip);
    return ok;
}

/* Figures of the runtime's strips as they are now. */
static void lod_figures(const mts_lod *lod, fifo_cache *c16, level_row *row)
{
    mts_strip_stats st = {0};
    const uint32_t restart = RESTART;
    fifo_reset(c16);
    for (uint32_t s = 0; s < lod->strip_count; s++) {
        uint32_t len;
        const uint32_t *p = mts_lod_strip(lod, s, &len);
        if (!len)
            continue;
        if (st.strips)
            fifo_feed(c16, &restart, 1);
        mts_strip_stats_add(&st, p, len);
        fifo_feed(c16, p, len);
    }
    row->stats = st;
    row->indices_per_triangle = ratio(mts_strip_stats_draw_indices(&st), st.triangles);
    row->degenerate_share = ratio(st.degenerate, st.triangles + st.degenerate);
    row->acmr16 = ratio(c16->misses, st.triangles);
}

static int bench_levels(model_result *r, const mts_model *model)
{
    mts_error err = {0};
    mts_lod lod;
    fifo_cache c16 = {0};
    if (!fifo_init(&c16, 16, model->vertex_count)) {
        snprintf(r->error, sizeof r->error, "out of memory for the level figures");
        r->failed = 1;
        return 0;
    }
    if (mts_lod_init(&lod, model, MTS_LOD_AT_BASE, &err) != MTS_OK) {
        fail(r, "lod init", &err);
        fifo_free(&c16);
        return 0;
    }
    /* The worst level of all, where a client drawing it pays most per
     * triangle: every strip's indices plus one restart between strips;
     * degenerate windows = indices - 2 per strip - drawn triangles. */
    r->worst_ipt = 0;
    for (uint32_t l = 0; l <= model->level_count; l++) {
        uint32_t tris = model->level_triangles[l], strips = model->level_strips[l];
        uint64_t idx = model->level_indices[l];
        if (!tris || !strips)
            continue;
        double ipt = (double)(idx + strips - 1) / tris;
        if (ipt > r->worst_ipt) {
            r->worst_ipt = ipt;
            r->worst_level = l;
            r->worst_triangles = tris;
            r->worst_strips = strips;
            r->worst_degenerate_share =
                ratio(idx - 2 * (uint64_t)strips - tris, idx - 2 * (uint64_t)strips);
        }
    }
    int ok = 1;
    for (size_t i = 0; i < LEVEL_ROWS && ok; i++) {
        level_row *row = &r->level[i];
        row->fraction = level_fractions[i];
        row->level = mts_model_level_for_fraction(model, row->fraction);
        row->vertices = model->base_vertex_count + row->level;
        /* level_for_fraction rounds to the nearest vertex count and stops at
         * the base; say so only when the rounded request is below it */
        row->clamped = (uint64_t)(row->fraction * model->vertex_count + 0.5) <
                       model->base_vertex_count;
        if (mts_lod_set_level(&lod, row->level, &err) != MTS_OK) {
            fail(r, "set level", &err);
            ok = 0;
            break;
        }
        lod_figures(&lod, &c16, row);
        if (row->stats.triangles != model->level_triangles[row->level] ||
            row->stats.strips != model->level_strips[row->level]) {
            snprintf(r->error, sizeof r->error,
                     "level %u: the runtime's strips draw %llu triangles in %u strips, the "
                     "model says %u in %u",
                     row->level, (unsigned long long)row->stats.triangles, row->stats.strips,
                     model->level_triangles[row->level], model->level_strips[row->level]);
            r->failed = 1;
            ok = 0;
        }
    }
    for (int i = 0; i < 3 && ok; i++) {
        uint32_t level = mts_model_level_for_triangles(
            model, (uint64_t)(p4_fractions[i] * model->level_triangles[model->level_count]));
        if (mts_lod_set_level(&lod, level, &err) != MTS_OK) {
            fail(r, "set level", &err);
            ok = 0;
            break;
        }
        uint32_t strips = 0, isolated = 0;
        uint64_t tris = 0;
        for (uint32_t s = 0; s < lod.strip_count; s++) {
            uint32_t len;
            const uint32_t *p = mts_lod_strip(&lod, s, &len);
            mts_strip_stats one = {0};
            mts_strip_stats_add(&one, p, len);
            if (!one.triangles)
                continue;
            strips++;
            isolated += one.triangles == 1;
            tris += one.triangles;
        }
        r->p4_level[i] = level;
        r->p4_strips[i] = strips;
        r->p4_isolated[i] = isolated;
        r->p4_mean[i] = ratio(tris, strips);
    }
    mts_lod_free(&lod);
    fifo_free(&c16);
    return ok;
}

/* base -> full -> base, the whole record set both ways. */
static int bench_sweep(model_result *r, const bench_options *o, const mts_model *model)
{
    mts_error err = {0};
    mts_lod lod;
    if (mts_lod_init(&lod, model, MTS_LOD_AT_BASE, &err) != MTS_OK) {
        fail(r, "lod init", &err);
        return 0;
    }
    double up[MAX_RUNS], down[MAX_RUNS], both[MAX_RUNS];
    int ok = 1;
    for (int i = 0; i < o->reps; i++) {
        mts_lod_clear_changed(&lod);
        double t0 = cli_now();
        if (mts_lod_set_level(&lod, model->level_count, &err) != MTS_OK) {
            fail(r, "sweep up", &err);
            ok = 0;
            break;
        }
        double t1 = cli_now();
        mts_lod_set_level(&lod, 0, &err); /* collapses cannot fail */
        double t2 = cli_now();
        up[i] = (t1 - t0) * 1e3;
        down[i] = (t2 - t1) * 1e3;
        both[i] = (t2 - t0) * 1e3;
    }
    if (ok) {
        r->sweep_reps = o->reps;
        r->up_ms = median(up, o->reps);
        r->down_ms = median(down, o->reps);
        r->sweep_ms = median(both, o->reps);
        /* after a sweep, so the collapse scratch is counted at its largest */
        r->lod_bytes = mts_lod_memory_bytes(&lod);
        r->model_bytes = mts_model_memory_bytes(model);
        /* float positions + normals, 32-bit triangle indices */
        r->indexed_bytes = (uint64_t)model->vertex_count * 24 + (uint64_t)r->triangles * 12;
    }
    mts_lod_free(&lod);
    return ok;
}

/* The 100 target levels of a walk (paper 000, section 5.2). */
static void walk_levels(const mts_model *model, int kind, uint32_t *out)
{
    uint32_t n = model->level_count;
    uint64_t rng = WALK_SEED;
    /* exponential: the vertex (so, about the triangle) count shrinks by a
     * constant factor per step, from the full mesh at k = 0 to the base at
     * k = 99 */
    double span = log2((double)model->vertex_count / model->base_vertex_count);
    for (uint32_t k = 0; k < WALK_STEPS; k++) {
        switch (kind) {
        case WALK_LINEAR:
            out[k] = (uint32_t)llround((double)n * (WALK_STEPS - 1 - k) / (WALK_STEPS - 1));
            break;
        case WALK_EXPONENTIAL:
            out[k] = mts_model_level_for_fraction(model, exp2(-(double)k * span / (WALK_STEPS - 1)));
            break;
        default:
            out[k] = (uint32_t)(splitmix64(&rng) % ((uint64_t)n + 1));
            break;
        }
    }
}

/* One walk; returns the mean milliseconds per extraction, or -1 on error.
 * Coherent: one runtime moves from each level to the next; it starts at the
 * walk's first level (untimed), as if the previous frame had left it there,
 * so the first extraction is free -- otherwise a walk that starts at the full
 * level would pay a whole base -> full climb up front. Without coherence:
 * every extraction is a fresh runtime at the base (mts_lod_init, which
 * allocates and copies the base strips) moved up to the target. */
static double walk_once(const mts_model *model, const uint32_t *target, int coherent,
                        mts_error *err)
{
    double total = 0;
    mts_lod lod;
    if (coherent) {
        if (mts_lod_init(&lod, model, MTS_LOD_AT_BASE, err) != MTS_OK)
            return -1;
        if (mts_lod_set_level(&lod, target[0], err) != MTS_OK) {
            mts_lod_free(&lod);
            return -1;
        }
        for (uint32_t k = 0; k < WALK_STEPS; k++) {
            mts_lod_clear_changed(&lod); /* the renderer's upload, not timed */
            double t0 = cli_now();
            mts_result rc = mts_lod_set_level(&lod, target[k], err);
            total += cli_now() - t0;
            if (rc != MTS_OK) {
                mts_lod_free(&lod);
                return -1;
            }
        }
        mts_lod_free(&lod);
    } else {
        for (uint32_t k = 0; k < WALK_STEPS; k++) {
            double t0 = cli_now();
            if (mts_lod_init(&lod, model, MTS_LOD_AT_BASE, err) != MTS_OK)
                return -1;
            mts_result rc = mts_lod_set_level(&lod, target[k], err);
            total += cli_now() - t0;
            mts_lod_free(&lod);
            if (rc != MTS_OK)
                return -1;
        }
    }
    return total * 1e3 / WALK_STEPS;
}

static int bench_walks(model_result *r, const bench_options *o, const mts_model *model)
{
    uint32_t target[WALK_STEPS];
    mts_error err = {0};
    int reps_done = o->reps;
    for (int kind = 0; kind < WALK_KINDS; kind++) {
        walk_levels(model, kind, target);
        for (int without = 0; without < 2; without++) {
            double ms[MAX_RUNS];
            int reps = 0;
            double t0 = cli_now();
            /* repeat for a stable median, but stop a slow cell early */
            while (reps < o->reps && (reps == 0 || cli_now() - t0 < o->budget)) {
                ms[reps] = walk_once(model, target, !without, &err);
                if (ms[reps] < 0) {
                    fail(r, "walk", &err);
                    return 0;
                }
                reps++;
            }
            if (reps < reps_done)
                reps_done = reps;
            r->walk_ms[kind][without] = median(ms, reps);
        }
    }
    r->walk_reps = reps_done;
    return 1;
}

static void bench_model(model_result *r, const bench_options *o)
{
    struct stat sb;
    if (stat(r->path, &sb) != 0) {
        r->missing = 1;
        snprintf(r->error, sizeof r->error, "not found");
        return;
    }
    r->input_bytes = (uint64_t)sb.st_size;
    r->paper = paper_for(r->name);
    mts_mesh mesh = {0};
    mts_model model = {0};
    if (bench_build(r, o, &mesh, &model) && bench_full(r, &mesh, &model) &&
        bench_levels(r, &model) && bench_sweep(r, o, &model))
        bench_walks(r, o, &model);
    mts_model_free(&model);
    mts_mesh_free(&mesh);
}

/* ---- output ------------------------------------------------------------- */

static void rule(int width)
{
    for (int i = 0; i < width; i++)
        putchar('-');
    putchar('\n');
}

static double mb(uint64_t bytes)
{
    return bytes / 1e6;
}

static void print_tables(const model_result *res, int count, const bench_options *o)
{
    int any = 0;
    for (int i = 0; i < count; i++) {
        if (res[i].missing)
            printf("%s: skipped, %s (%s)\n", res[i].name, res[i].error, res[i].path);
        else if (res[i].failed)
            printf("%s: FAILED, %s\n", res[i].name, res[i].error);
        else
            any = 1;
    }
    if (!any)
        return;

    printf("\nBuild, seconds per stage (median of %d runs; write = encode to memory)\n",
           o->runs);
    printf("%-14s %9s %9s %8s %8s %8s %8s %8s %8s %8s %8s\n", "model", "vertices", "triangles",
           "load s", "strip s", "tunnel s", "simpl s", "recs s", "write s", "total s", "levels");
    rule(14 + 10 * 2 + 9 * 8);
    for (int i = 0; i < count; i++) {
        const model_result *r = &res[i];
        if (r->missing || r->failed)
            continue;
        printf("%-14s %9u %9u %8.3f %8.3f %8.3f %8.3f %8.3f %8.3f %8.3f %8u\n", r->name,
               r->vertices, r->triangles, r->build.load, r->build.stripify, r->build.tunnel,
               r->build.simplify,
               r->build.records, r->build.write, r->build.total, r->levels);
    }

    printf("\nFull level: indices per triangle (restarts counted) and FIFO-cache ACMR "
           "(misses per triangle)\n");
    printf("%-14s %-22s %7s %7s %9s %8s %8s %9s\n", "model", "method", "strips", "swaps",
           "idx/tri", "ACMR-16", "ACMR-32", "time ms");
    rule(14 + 23 + 8 * 2 + 10 + 9 * 2 + 10);
    for (int i = 0; i < count; i++) {
        const model_result *r = &res[i];
        if (r->missing || r->failed)
            continue;
        printf("%-14s %-22s %7u %7llu %9.3f %8.3f %8.3f %9.2f\n", r->name, "mts greedy",
               r->greedy.strips, (unsigned long long)r->greedy.swaps,
               r->greedy.indices_per_triangle, r->greedy.acmr16, r->greedy.acmr32,
               r->build.stripify * 1e3);
        char label[32];
        snprintf(label, sizeof label, "mts tunnel K=%d", r->tunnel_length);
        printf("%-14s %-22s %7u %7llu %9.3f %8.3f %8.3f %9.2f\n", "",
               r->tunnel_length > 0 ? label : "mts (tunnel off)", r->ours.strips,
               (unsigned long long)r->ours.swaps, r->ours.indices_per_triangle, r->ours.acmr16,
               r->ours.acmr32, r->build.tunnel * 1e3);
        printf("%-14s %-22s %7u %7s %9.3f %8.3f %8.3f %9.2f\n", "", "meshopt strips",
               r->meshopt.strips, "-", r->meshopt.indices_per_triangle, r->meshopt.acmr16,
               r->meshopt.acmr32, r->meshopt_seconds * 1e3);
        printf("%-14s %-22s %7s %7s %9.3f %8.3f %8.3f %9s\n", "", "meshopt optimized list", "-",
               "-", 3.0, r->list_acmr16, r->list_acmr32, "-");
        printf("%-14s %-22s %7s %7s %9.3f %8s %8s %9s\n", "", "bound (valences)", "-", "-",
               r->triangles ? 1.0 + ((double)r->cost_bound - 1.0) / r->triangles : 0, "-", "-",
               "-");
    }
    printf("(restarts = strips - 1, counted in idx/tri; mts greedy time: our stripify; tunnel "
           "time: the tunnelling pass on top, median; meshopt time: optimizeVertexCache + "
           "stripify, one run; bound: no strips can do better, from the vertices whose valence "
           "is not a multiple of 3, mts_stripify_cost_bound)\n");

    printf("\nFull level counted as paper 000 counts it (Table 3: vertices sent, swaps in, "
           "one draw per strip, so no restart markers)\n");
    printf("%-14s %-22s %9s %14s %12s\n", "model", "method", "idx/tri", "w/o restarts",
           "paper 000");
    rule(14 + 23 + 10 + 15 + 13);
    for (int i = 0; i < count; i++) {
        const model_result *r = &res[i];
        if (r->missing || r->failed)
            continue;
        char p[48] = "-";
        if (r->paper && r->paper->drawn_k > 0)
            snprintf(p, sizeof p, "%.3f", r->paper->sent_k / r->paper->drawn_k);
        printf("%-14s %-22s %9.3f %14.3f %12s\n", r->name, "mts tunnel",
               r->ours.indices_per_triangle, r->ours.indices_per_triangle_no_restarts, p);
        printf("%-14s %-22s %9.3f %14.3f %12s\n", "", "meshopt strips",
               r->meshopt.indices_per_triangle, r->meshopt.indices_per_triangle_no_restarts, "-");
    }
    printf("(paper 000: MTS on the 69,451-triangle Stanford bunny, 83K vertices for 69.4K "
           "triangles; bunny00 here has 75,408)\n");

    printf("\nLevels by fraction of the full vertex count (runtime strips)\n");
    printf("%-14s %7s %8s %9s %9s %7s %13s %8s %8s  %s\n", "model", "target", "level",
           "vertices", "triangles", "strips", "idx/drawn tri", "degen %", "ACMR-16", "note");
    rule(14 + 8 + 9 + 10 * 2 + 8 + 14 + 9 * 2 + 8);
    for (int i = 0; i < count; i++) {
        const model_result *r = &res[i];
        if (r->missing || r->failed)
            continue;
        for (size_t k = 0; k < LEVEL_ROWS; k++) {
            const level_row *l = &r->level[k];
            const char *note = l->clamped ? "clamped to the base"
                               : l->level == 0 ? "= base"
                               : l->level == r->levels ? "= full"
                                                       : "";
            printf("%-14s %6.0f%% %8u %9u %9llu %7u %13.3f %8.2f %8.3f  %s\n", k ? "" : r->name,
                   l->fraction * 100, l->level, l->vertices,
                   (unsigned long long)l->stats.triangles, l->stats.strips,
                   l->indices_per_triangle, l->degenerate_share * 100, l->acmr16, note);
        }
        printf("%-14s %7s %8u %9u %9u %7u %13.3f %8.2f %8s  worst of all %u levels (%u key)\n",
               "", "worst", r->worst_level, r->base_vertices + r->worst_level,
               r->worst_triangles, r->worst_strips, r->worst_ipt, r->worst_degenerate_share * 100, "-", r->levels + 1,
               r->key_levels);
    }

    printf("\nRuntime: sweep base -> full -> base (median of %d) and memory against the "
           "indexed mesh\n",
           o->reps);
    printf("%-14s %9s %9s %9s %11s %11s %12s %8s %8s\n", "model", "up ms", "down ms", "sweep ms",
           "lod bytes", "model bytes", "indexed B", "lod/idx", "mdl/idx");
    rule(14 + 10 * 3 + 12 * 2 + 13 + 9 * 2);
    for (int i = 0; i < count; i++) {
        const model_result *r = &res[i];
        if (r->missing || r->failed)
            continue;
        printf("%-14s %9.3f %9.3f %9.3f %11llu %11llu %12llu %8.2f %8.2f\n", r->name, r->up_ms,
               r->down_ms, r->sweep_ms, (unsigned long long)r->lod_bytes,
               (unsigned long long)r->model_bytes, (unsigned long long)r->indexed_bytes,
               ratio(r->lod_bytes, r->indexed_bytes), ratio(r->model_bytes, r->indexed_bytes));
    }
    printf("(indexed mesh: 24 B per vertex for float positions + normals, 12 B per triangle)\n");

    printf("\nLevel walks, paper 000 Table 2: mean ms per extraction over %d levels "
           "(median of up to %d walks)\n",
           WALK_STEPS, o->reps);
    printf("%-14s %-12s %11s %11s %7s  %11s %11s\n", "model", "walk", "coherent ms", "without ms",
           "speedup", "paper coh.", "paper w/o");
    rule(14 + 13 + 12 * 2 + 8 + 2 + 11 + 12);
    for (int i = 0; i < count; i++) {
        const model_result *r = &res[i];
        if (r->missing || r->failed)
            continue;
        for (int k = 0; k < WALK_KINDS; k++) {
            char pc[32] = "-", pw[32] = "-";
            if (r->paper) {
                snprintf(pc, sizeof pc, "%.3f", r->paper->walk_ms[k][0]);
                snprintf(pw, sizeof pw, "%.3f", r->paper->walk_ms[k][1]);
            }
            printf("%-14s %-12s %11.4f %11.4f %6.1fx  %11s %11s\n", k ? "" : r->name,
                   walk_names[k], r->walk_ms[k][0], r->walk_ms[k][1],
                   r->walk_ms[k][1] / r->walk_ms[k][0], pc, pw);
        }
    }
    printf("(paper: a 550 MHz Pentium III; coherent walks start at their first level, "
           "untimed)\n");

    printf("\nStrips at paper 004 Table 1's levels (fraction of the full triangles; paper: "
           "its own model, tunnel length 13)\n");
    printf("%-14s %6s %8s %8s %9s %11s %8s %9s %11s\n", "model", "LOD%", "level", "strips",
           "isolated", "mean tris", "paper", "p.isol.", "p.mean");
    rule(14 + 7 + 9 * 2 + 10 + 12 + 9 + 10 + 12);
    for (int i = 0; i < count; i++) {
        const model_result *r = &res[i];
        if (r->missing || r->failed)
            continue;
        for (int k = 0; k < 3; k++)
            printf("%-14s %5.0f%% %8u %8u %9u %11.2f %8.0f %9.0f %11.2f\n", k ? "" : r->name,
                   p4_fractions[k] * 100, r->p4_level[k], r->p4_strips[k], r->p4_isolated[k],
                   r->p4_mean[k], p4_paper[k][0], p4_paper[k][1], p4_paper[k][2]);
    }

    printf("\nModel size, paper 000 Table 1 (MB = 10^6 bytes)\n");
    printf("%-14s %11s %11s %8s %7s %9s %9s %9s %9s %9s\n", "model", "input B", "mtsm B",
           "mtsm MB", "strips", "paper MB", "PM MB", "MOM-Fan", "p.strips", "p.verts");
    rule(14 + 12 * 2 + 9 + 8 + 10 * 5);
    for (int i = 0; i < count; i++) {
        const model_result *r = &res[i];
        if (r->missing || r->failed)
            continue;
        char a[32] = "-", b[32] = "-", c[32] = "-", d[32] = "-", e[32] = "-";
        if (r->paper) {
            snprintf(a, sizeof a, "%.3f", r->paper->mts_mb);
            snprintf(b, sizeof b, "%.3f", r->paper->pm_mb);
            snprintf(c, sizeof c, "%.3f", r->paper->momfan_mb);
            snprintf(d, sizeof d, "%u", r->paper->strips);
            snprintf(e, sizeof e, "%u", r->paper->vertices);
        }
        printf("%-14s %11llu %11llu %8.3f %7u %9s %9s %9s %9s %9s\n", r->name,
               (unsigned long long)r->input_bytes, (unsigned long long)r->file_bytes,
               mb(r->file_bytes), r->ours.strips, a, b, c, d, e);
    }
}

static void json_strip_figures(cli_json *j, const char *key, const strip_figures *f)
{
    cli_json_object_begin(j, key);
    cli_json_u64(j, "strips", f->strips);
    cli_json_u64(j, "swaps", f->swaps);
    cli_json_u64(j, "restarts", f->restarts);
    cli_json_u64(j, "draw_indices", f->draw_indices);
    cli_json_num(j, "indices_per_triangle", f->indices_per_triangle, 4);
    cli_json_num(j, "indices_per_triangle_no_restarts", f->indices_per_triangle_no_restarts, 4);
    cli_json_num(j, "acmr16", f->acmr16, 4);
    cli_json_num(j, "acmr32", f->acmr32, 4);
    cli_json_object_end(j);
}

static void json_model(cli_json *j, const model_result *r)
{
    cli_json_object_begin(j, r->name);
    cli_json_str(j, "path", r->path);
    if (r->missing || r->failed) {
        cli_json_str(j, "status", r->missing ? "missing" : "failed");
        cli_json_str(j, "error", r->error);
        cli_json_object_end(j);
        return;
    }
    cli_json_str(j, "status", "ok");
    cli_json_u64(j, "input_bytes", r->input_bytes);
    cli_json_u64(j, "vertices", r->vertices);
    cli_json_u64(j, "triangles", r->triangles);
    cli_json_u64(j, "base_vertices", r->base_vertices);
    cli_json_u64(j, "base_triangles", r->base_triangles);
    cli_json_u64(j, "levels", r->levels);

    cli_json_object_begin(j, "build_seconds");
    cli_json_u64(j, "runs", (uint64_t)r->runs);
    cli_json_num(j, "load", r->build.load, 5);
    cli_json_num(j, "stripify", r->build.stripify, 5);
    cli_json_num(j, "tunnel", r->build.tunnel, 5);
    cli_json_num(j, "simplify", r->build.simplify, 5);
    cli_json_num(j, "records", r->build.records, 5);
    cli_json_num(j, "write", r->build.write, 5);
    cli_json_num(j, "total", r->build.total, 5);
    cli_json_object_end(j);

    cli_json_object_begin(j, "full");
    cli_json_u64(j, "swaps", r->ours.swaps);
    cli_json_u64(j, "singletons", r->stripify.singletons); /* the greedy strips' */
    cli_json_u64(j, "tunnel_length", (uint64_t)r->tunnel_length);
    cli_json_num(j, "tunnel_seconds", r->build.tunnel, 5);
    json_strip_figures(j, "mts", &r->ours);
    json_strip_figures(j, "greedy", &r->greedy);
    json_strip_figures(j, "meshopt", &r->meshopt);
    cli_json_num(j, "meshopt_seconds", r->meshopt_seconds, 5);
    cli_json_object_begin(j, "list");
    cli_json_num(j, "indices_per_triangle", 3.0, 1);
    cli_json_num(j, "acmr16", r->list_acmr16, 4);
    cli_json_num(j, "acmr32", r->list_acmr32, 4);
    cli_json_num(j, "acmr16_meshopt_analyzer", r->list_acmr16_analyzer, 4);
    cli_json_object_end(j);
    cli_json_u64(j, "cost_bound", r->cost_bound);
    cli_json_num(j, "indices_per_triangle_bound",
                 r->triangles ? 1.0 + ((double)r->cost_bound - 1.0) / r->triangles : 0, 4);
    if (r->paper && r->paper->drawn_k > 0)
        cli_json_num(j, "paper000_table3_sent_per_triangle",
                     r->paper->sent_k / r->paper->drawn_k, 4);
    cli_json_object_end(j);

    cli_json_object_begin(j, "paper004_table1");
    for (int k = 0; k < 3; k++) {
        char key[16];
        snprintf(key, sizeof key, "%g", p4_fractions[k]);
        cli_json_object_begin(j, key);
        cli_json_u64(j, "level", r->p4_level[k]);
        cli_json_u64(j, "strips", r->p4_strips[k]);
        cli_json_u64(j, "isolated", r->p4_isolated[k]);
        cli_json_num(j, "mean_strip_triangles", r->p4_mean[k], 3);
        cli_json_u64(j, "paper_strips", (uint64_t)p4_paper[k][0]);
        cli_json_u64(j, "paper_isolated", (uint64_t)p4_paper[k][1]);
        cli_json_num(j, "paper_mean_strip_triangles", p4_paper[k][2], 2);
        cli_json_object_end(j);
    }
    cli_json_object_end(j);
    cli_json_object_begin(j, "worst_level");
    cli_json_u64(j, "level", r->worst_level);
    cli_json_u64(j, "levels", (uint64_t)r->levels + 1);
    cli_json_u64(j, "key_levels", r->key_levels);
    cli_json_num(j, "indices_per_drawn_triangle", r->worst_ipt, 4);
    cli_json_num(j, "degenerate_share", r->worst_degenerate_share, 4);
    cli_json_object_end(j);
    cli_json_object_begin(j, "levels_by_fraction");
    for (size_t k = 0; k < LEVEL_ROWS; k++) {
        const level_row *l = &r->level[k];
        char key[32];
        snprintf(key, sizeof key, "%g", l->fraction);
        cli_json_object_begin(j, key);
        cli_json_u64(j, "level", l->level);
        cli_json_bool(j, "clamped", l->clamped);
        cli_json_u64(j, "vertices", l->vertices);
        cli_json_u64(j, "triangles", l->stats.triangles);
        cli_json_u64(j, "strips", l->stats.strips);
        cli_json_u64(j, "draw_indices", mts_strip_stats_draw_indices(&l->stats));
        cli_json_u64(j, "degenerate_windows", l->stats.degenerate);
        cli_json_num(j, "indices_per_drawn_triangle", l->indices_per_triangle, 4);
        cli_json_num(j, "degenerate_share", l->degenerate_share, 4);
        cli_json_num(j, "acmr16", l->acmr16, 4);
        cli_json_object_end(j);
    }
    cli_json_object_end(j);

    cli_json_object_begin(j, "runtime");
    cli_json_u64(j, "reps", (uint64_t)r->sweep_reps);
    cli_json_num(j, "up_ms", r->up_ms, 4);
    cli_json_num(j, "down_ms", r->down_ms, 4);
    cli_json_num(j, "sweep_ms", r->sweep_ms, 4);
    cli_json_u64(j, "lod_bytes", r->lod_bytes);
    cli_json_u64(j, "model_bytes", r->model_bytes);
    cli_json_u64(j, "indexed_mesh_bytes", r->indexed_bytes);
    cli_json_num(j, "lod_to_indexed", ratio(r->lod_bytes, r->indexed_bytes), 4);
    cli_json_num(j, "model_to_indexed", ratio(r->model_bytes, r->indexed_bytes), 4);
    cli_json_object_end(j);

    cli_json_object_begin(j, "walks_ms_per_extraction");
    cli_json_u64(j, "steps", WALK_STEPS);
    cli_json_u64(j, "reps", (uint64_t)r->walk_reps);
    for (int k = 0; k < WALK_KINDS; k++) {
        cli_json_object_begin(j, walk_names[k]);
        cli_json_num(j, "coherent", r->walk_ms[k][0], 5);
        cli_json_num(j, "without", r->walk_ms[k][1], 5);
        if (r->paper) {
            cli_json_num(j, "paper_coherent", r->paper->walk_ms[k][0], 3);
            cli_json_num(j, "paper_without", r->paper->walk_ms[k][1], 3);
        }
        cli_json_object_end(j);
    }
    cli_json_object_end(j);

    cli_json_object_begin(j, "size");
    cli_json_u64(j, "model_file_bytes", r->file_bytes);
    cli_json_num(j, "model_file_mb", mb(r->file_bytes), 4);
    cli_json_u64(j, "input_bytes", r->input_bytes);
    if (r->paper) {
        cli_json_num(j, "paper_mts_mb", r->paper->mts_mb, 3);
        cli_json_num(j, "paper_pm_mb", r->paper->pm_mb, 3);
        cli_json_num(j, "paper_momfan_mb", r->paper->momfan_mb, 3);
        cli_json_u64(j, "paper_strips", r->paper->strips);
        cli_json_u64(j, "paper_vertices", r->paper->vertices);
        cli_json_u64(j, "paper_triangles", r->paper->triangles);
    }
    cli_json_object_end(j);
    cli_json_object_end(j);
}

static int write_json(const char *path, const model_result *res, int count,
                      const bench_options *o)
{
    FILE *f = fopen(path, "w");
    if (!f) {
        perror(path);
        return 0;
    }
    cli_json j;
    cli_json_begin(&j, f);
    cli_json_u64(&j, "build_runs", (uint64_t)o->runs);
    cli_json_u64(&j, "reps", (uint64_t)o->reps);
    cli_json_object_begin(&j, "models");
    for (int i = 0; i < count; i++)
        json_model(&j, &res[i]);
    cli_json_object_end(&j);
    cli_json_end(&j);
    int ok = !ferror(f);
    if (fclose(f) != 0)
        ok = 0;
    if (!ok)
        fprintf(stderr, "mts-bench: writing %s failed\n", path);
    return ok;
}

static void usage(FILE *f)
{
    fputs("usage: mts-bench MESH... [--json FILE] [--runs N] [--reps N]\n"
          "\n"
          "Builds each mesh and prints build times, strip quality against meshoptimizer,\n"
          "strip quality by level, runtime sweep time and memory, paper 000's level walks\n"
          "and model sizes. A missing mesh is skipped with a note.\n"
          "\n"
          "  --json FILE   also write the figures as one line of JSON\n"
          "  --runs N      builds per mesh, median reported (default 3, at most 15)\n"
          "  --reps N      sweeps and walks per mesh, median reported (default 5, at most 15)\n"
          "  -h, --help    this help\n"
          "\n"
          "Exit status: 0 all present meshes measured, 1 one failed, 2 bad usage.\n",
          f);
}

int main(int argc, char **argv)
{
    bench_options o = {3, 5, 2.0};
    const char *json = NULL;
    const char **paths = malloc((size_t)argc * sizeof *paths);
    int count = 0;
    if (!paths) {
        fputs("mts-bench: out of memory\n", stderr);
        return CLI_EXIT_FAIL;
    }
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        uint32_t v;
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) {
            usage(stdout);
            free(paths);
            return CLI_EXIT_OK;
        } else if (!strcmp(a, "--json")) {
            if (++i >= argc) {
                fputs("mts-bench: --json needs a file name\n", stderr);
                free(paths);
                return CLI_EXIT_USAGE;
            }
            json = argv[i];
        } else if (!strcmp(a, "--runs") || !strcmp(a, "--reps")) {
            if (++i >= argc || !cli_parse_u32(argv[i], &v) || v == 0 || v > MAX_RUNS) {
                fprintf(stderr, "mts-bench: %s needs a number from 1 to %d\n", a, MAX_RUNS);
                free(paths);
                return CLI_EXIT_USAGE;
            }
            if (a[3] == 'u')
                o.runs = (int)v;
            else
                o.reps = (int)v;
        } else if (a[0] == '-' && a[1]) {
            fprintf(stderr, "mts-bench: unknown option %s (see --help)\n", a);
            free(paths);
            return CLI_EXIT_USAGE;
        } else {
            paths[count++] = a;
        }
    }
    if (!count) {
        usage(stderr);
        free(paths);
        return CLI_EXIT_USAGE;
    }

    model_result *res = calloc((size_t)count, sizeof *res);
    if (!res) {
        fputs("mts-bench: out of memory\n", stderr);
        free(paths);
        return CLI_EXIT_FAIL;
    }
    int status = CLI_EXIT_OK;
    for (int i = 0; i < count; i++) {
        model_result *r = &res[i];
        snprintf(r->path, sizeof r->path, "%s", paths[i]);
        cli_stem(paths[i], r->name, sizeof r->name);
        fprintf(stderr, "mts-bench: %s ...\n", r->name);
        double t0 = cli_now();
        bench_model(r, &o);
        if (r->failed)
            status = CLI_EXIT_FAIL;
        else if (!r->missing)
            fprintf(stderr, "mts-bench: %s done in %.1f s\n", r->name, cli_now() - t0);
    }
    print_tables(res, count, &o);
    if (json && !write_json(json, res, count, &o))
        status = CLI_EXIT_FAIL;
    free(res);
    free(paths);
    return status;
}
