/* mts-bench-phases: where a splits-form client's apply time goes, split the
 * way threading the decoder would split it (docs/threads.md). Per model, in
 * one process, memory warm, medians of N runs:
 *
 *  - the whole client: the splits form and the records form decoded and
 *    applied, as mts-bench-apply times them;
 *  - growth alone, replayed from the model's split descriptions
 *    (mts_grow_model_split + mts_grow_next, as verify.c derives records):
 *    per key interval, the key split (the split, the restripification and
 *    the key record) and the splits between keys, each timed;
 *  - what is left of the client (range decoding, position prediction,
 *    keeping records, the LOD runtime's apply) is the whole less growth.
 *
 * It then plays a schedule for N cores where the intervals' growth between
 * keys runs on workers once a sequential pass (everything else) has reached
 * their key, and prints the times that schedule gives: a bound on what
 * interval-level threads could reach, not a measurement of threads. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_common.h"
#include "cli.h"
#include "grow.h"
#include "modelfile.h"
#include "stream.h"

#define MAX_RUNS 99

/* Seconds to take every frame of b into a fresh client; 0 on an error. */
static double apply(const mts_buf *b, mts_error *err)
{
    mts_stream_client c;
    mts_stream_client_init(&c);
    double t0 = cli_now();
    int ok = mts_stream_client_feed(&c, b->data, b->size, err) == MTS_OK, got = 0;
    mts_stream_event ev;
    while (ok && (got = mts_stream_client_next(&c, &ev, err)) > 0)
        ;
    double t = cli_now() - t0;
    ok = ok && got == 0 && c.end_checksum != 0;
    mts_stream_client_free(&c);
    return ok ? t : 0;
}

/* One replay of growth over every split: per interval i (0: from the base;
 * i > 0: from key i - 1's split on) the key split's seconds in key[i] and
 * the others' in between[i], the fan lookups (connectivity only) in *fan. */
static int replay(const mts_model *m, const uint32_t *interval_of, double *key, double *between,
                  double *fan, mts_error *err)
{
    const uint32_t n = m->level_count;
    mts_grow_options go = {0};
    go.key_levels = m->key_levels;
    go.key_count = m->key_count;
    mts_grow *g = NULL;
    if (mts_grow_create(&m->base, m->base_vertex_count, n, &go, &g, err) != MTS_OK)
        return 0;
    mts_grow_full given = {.strips = &m->full};
    *fan = 0;
    uint32_t next_key = 0;
    int ok = 1;
    for (uint32_t j = 0; j < n && ok; j++) {
        mts_grow_split sp;
        const uint32_t *r;
        uint32_t words;
        double t0 = cli_now();
        ok = mts_grow_model_split(g, m, j, &sp);
        double t1 = cli_now();
        ok = ok && mts_grow_next(g, &sp, &given, &r, &words, err) == MTS_OK;
        double t2 = cli_now();
        *fan += t1 - t0;
        /* split j takes level j to j + 1: a key split when j + 1 is a key */
        const int is_key = j + 1 == n ||
                           (next_key < m->key_count && m->key_levels[next_key] == j + 1);
        if (is_key) {
            key[interval_of[j]] += t2 - t1;
            next_key++;
        } else {
            between[interval_of[j]] += t2 - t1;
        }
    }
    mts_grow_free(g);
    return ok;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double median(double *x, int n)
{
    qsort(x, (size_t)n, sizeof *x, cmp_double);
    return x[n / 2];
}

/* The schedule's finishing time on `cores`: a sequential pass of `seq`
 * seconds, spread over the splits evenly, holds one core; interval i's
 * growth between keys (work[i]) may start once that pass has reached its
 * first split (start[i] of n) and goes, in order, to the first core free. */
static double schedule(uint32_t intervals, const uint32_t *start, uint32_t n, const double *work,
                       double seq, int cores)
{
    double freeat[64];
    for (int c = 0; c < cores; c++)
        freeat[c] = c == 0 ? seq : 0; /* core 0 runs the sequential pass */
    double end = seq;
    for (uint32_t i = 0; i < intervals; i++) {
        const double ready = seq * start[i] / (n ? n : 1);
        int best = 0;
        for (int c = 1; c < cores; c++) {
            if ((freeat[c] > ready ? freeat[c] : ready) < (freeat[best] > ready ? freeat[best] : ready))
                best = c;
        }
        /* with one core the pass and the growth interleave as today */
        double at = cores == 1 ? 0 : (freeat[best] > ready ? freeat[best] : ready);
        freeat[best] = (cores == 1 ? freeat[best] : at) + work[i];
        if (freeat[best] > end)
            end = freeat[best];
    }
    return end;
}

int main(int argc, char **argv)
{
    const char *paths[16];
    int npaths = 0, runs = 5;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--runs")) {
            uint32_t u;
            if (!cli_option_u32(argc, argv, &i, "mts-bench-phases", 1, MAX_RUNS, &u))
                return CLI_EXIT_USAGE;
            runs = (int)u;
        } else if (!strcmp(argv[i], "-h") || !strcmp(argv[i], "--help")) {
            printf("usage: mts-bench-phases MODEL.mtsm... [--runs N]\n"
                   "Per model: the client's whole apply (both forms), growth alone per key\n"
                   "interval (key split and the splits between), medians of N warm runs\n"
                   "(default 5), and what a schedule with interval growth on workers gives.\n");
            return CLI_EXIT_OK;
        } else if (argv[i][0] == '-') {
            fprintf(stderr, "mts-bench-phases: unknown option %s\n", argv[i]);
            return CLI_EXIT_USAGE;
        } else if (npaths < 16) {
            paths[npaths++] = argv[i];
        } else {
            fprintf(stderr, "mts-bench-phases: at most 16 models\n");
            return CLI_EXIT_USAGE;
        }
    }
    if (!npaths) {
        fprintf(stderr, "mts-bench-phases: give models (see --help)\n");
        return CLI_EXIT_USAGE;
    }
    int status = CLI_EXIT_OK;
    for (int k = 0; k < npaths; k++) {
        char name[128];
        cli_stem(paths[k], name, sizeof name);
        mts_error err = {0};
        mts_model m = {0};
        if (mts_modelfile_load(paths[k], &m, &err) != MTS_OK) {
            printf("%s: skipped: %s\n", name, err.msg);
            status = CLI_EXIT_FAIL;
            continue;
        }
        const uint32_t n = m.level_count, intervals = m.key_count + 2;
        /* interval 0 runs from the base; interval i > 0 from the split that
         * makes key i - 1 (the full level's key is the last interval) */
        uint32_t *interval_of = malloc(((size_t)n + 1) * 4), *start = calloc(intervals, 4);
        double *key = calloc((size_t)intervals * MAX_RUNS, sizeof *key),
               *between = calloc((size_t)intervals * MAX_RUNS, sizeof *between);
        double fan[MAX_RUNS], whole[MAX_RUNS], recs[MAX_RUNS], grow[MAX_RUNS];
        mts_stream s;
        mts_stream_options so = {0};
        so.with_records = 1;
        mts_buf a = {0}, r = {0};
        const int built = interval_of && start && key && between &&
                          mts_stream_build(&m, "bench", &so, &s, &err) == MTS_OK;
        int ok = built;
        if (ok) {
            uint32_t iv = 0;
            for (uint32_t j = 0; j < n; j++) {
                if ((iv < m.key_count && m.key_levels[iv] == j + 1) || j + 1 == n)
                    start[++iv] = j;
                interval_of[j] = iv;
            }
            ok = bench_connection_bytes(&s, n, &a) &&
                 bench_connection_bytes(s.records_form, s.records_form->model.level_count, &r);
            /* first runs of each: first-touch page faults are not decoding */
            ok = ok && apply(&a, &err) > 0 && apply(&r, &err) > 0 &&
                 replay(&m, interval_of, key, between, &fan[0], &err);
            memset(key, 0, (size_t)intervals * sizeof *key);
            memset(between, 0, (size_t)intervals * sizeof *between);
        }
        for (int i = 0; ok && i < runs; i++) { /* alternated, so drift hits all three */
            ok = (whole[i] = apply(&a, &err)) > 0 && (recs[i] = apply(&r, &err)) > 0 &&
                 replay(&m, interval_of, key + (size_t)i * intervals,
                        between + (size_t)i * intervals, &fan[i], &err);
            grow[i] = fan[i];
            for (uint32_t v = 0; ok && v < intervals; v++)
                grow[i] += key[(size_t)i * intervals + v] + between[(size_t)i * intervals + v];
        }
        if (!ok) {
            printf("%s: FAILED: %s\n", name, err.msg);
            status = CLI_EXIT_FAIL;
        } else {
            /* per interval, the median over runs of each part */
            double *km = calloc(intervals, sizeof *km), *bm = calloc(intervals, sizeof *bm),
                   col[MAX_RUNS], keys_total = 0, between_total = 0, big = 0;
            for (uint32_t v = 0; km && bm && v < intervals; v++) {
                for (int i = 0; i < runs; i++)
                    col[i] = key[(size_t)i * intervals + v];
                km[v] = median(col, runs);
                for (int i = 0; i < runs; i++)
                    col[i] = between[(size_t)i * intervals + v];
                bm[v] = median(col, runs);
                keys_total += km[v];
                between_total += bm[v];
                if (bm[v] > big)
                    big = bm[v];
            }
            const double w = median(whole, runs), rf = median(recs, runs),
                         g = median(grow, runs), f = median(fan, runs);
            /* explicit splits name triangle ids, which each key renumbers:
             * the one place the decoder needs a key's greedy order */
            uint32_t explicit_count = 0;
            for (uint32_t j = 0; j < n; j++) {
                const uint32_t len = m.growth_offsets[j + 1] - m.growth_offsets[j];
                explicit_count +=
                    len >= 3 && m.growth_data[m.growth_offsets[j] + 2] == MTS_GROWTH_EXPLICIT;
            }
            printf("\n%s: %u splits (%u explicit), %u key levels below the full level, median "
                   "of %d warm runs\n",
                   name, n, explicit_count, m.key_count, runs);
            printf("  client, splits form       %9.2f ms\n", w * 1e3);
            printf("  client, records form      %9.2f ms\n", rf * 1e3);
            printf("  growth replayed, all      %9.2f ms (%.0f %% of the client)\n", g * 1e3,
                   100 * g / w);
            printf("    fan lookups             %9.2f ms\n", f * 1e3);
            printf("    key splits              %9.2f ms (%u, restripification and key "
                   "records)\n",
                   keys_total * 1e3, m.key_count + 1);
            printf("    splits between keys     %9.2f ms\n", between_total * 1e3);
            printf("  client less growth        %9.2f ms (decoding, prediction, records kept, "
                   "LOD apply)\n",
                   (w - g) * 1e3);
            printf("  %-8s %9s %9s %7s %11s %11s\n", "interval", "first", "splits", "share",
                   "key ms", "between ms");
            for (uint32_t v = 0; v < intervals; v++) {
                uint32_t end = v + 1 < intervals ? start[v + 1] : n;
                printf("  %-8u %9u %9u %6.1f%% %11.3f %11.3f\n", v, start[v], end - start[v],
                       100.0 * (end - start[v]) / n, km[v] * 1e3, bm[v] * 1e3);
            }
            /* the sequential pass: all but the growth between keys */
            const double seq = w - between_total;
            printf("  largest interval's growth between keys: %.1f %% of it all\n",
                   100 * big / (between_total ? between_total : 1));
            printf("  schedule (sequential pass %.2f ms = the client less the growth between "
                   "keys; that growth on workers by interval):\n",
                   seq * 1e3);
            /* B: the key splits' restripification and records on the
             * workers too; the corner table's updates, which the decoder
             * needs as well, are inside the growth timed here, so the
             * sequential pass is at least this: a lower bound */
            double *kb = calloc(intervals, sizeof *kb);
            for (uint32_t v = 0; kb && v < intervals; v++)
                kb[v] = km[v] + bm[v];
            const double seq_b = w - between_total - keys_total;
            const int cores[] = {1, 2, 4, 8, 16};
            for (int c = 0; c < 5; c++) {
                double t = schedule(intervals, start, n, bm, seq, cores[c]);
                printf("    %2d cores: %9.2f ms, %.2fx of one\n", cores[c], t * 1e3,
                       t / schedule(intervals, start, n, bm, seq, 1));
            }
            printf("  schedule B (sequential pass %.2f ms = the client less all growth but the fan "
                   "lookups; key splits on workers too; a lower bound):\n",
                   seq_b * 1e3);
            for (int c = 0; kb && c < 5; c++) {
                double t = schedule(intervals, start, n, kb, seq_b, cores[c]);
                printf("    %2d cores: %9.2f ms, %.2fx of one\n", cores[c], t * 1e3,
                       t / schedule(intervals, start, n, kb, seq_b, 1));
            }
            free(kb);
            free(km);
            free(bm);
        }
        mts_buf_free(&a);
        mts_buf_free(&r);
        if (built)
            mts_stream_free(&s);
        free(interval_of);
        free(start);
        free(key);
        free(between);
        mts_model_free(&m);
    }
    return status;
}
