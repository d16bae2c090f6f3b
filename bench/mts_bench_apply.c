/* mts-bench-apply: what a client pays to apply a stream, both
 * forms in the same process, memory warm: per model its splits, the
 * median time to decode and apply the whole splits form (deriving every
 * record) and the records form (records on the wire), their ratio, the cost
 * per split, and how long a server takes to encode the stream. Models are
 * .mtsm files, or meshes built first. Used by bench/client_cost.sh. With
 * --threads listing several counts, the splits form is timed at each,
 * alternated within each run, a row each; --json adds each count's time
 * over the first count's, run by run (its quartiles: over_first_paired). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "bench_common.h"
#include "build.h"
#include "cli.h"
#include "mesh.h"
#include "modelfile.h"
#include "stream.h"

/* The processor time of every thread of this process so far, seconds:
 * beside the wall time it says how much work a run's threads did together,
 * which bounds what any split of that work between them could reach. */
static double process_cpu(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

/* The processor time of the calling thread so far, seconds: the decode
 * thread's, since the client decodes on its caller's thread. */
static double thread_cpu(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

/* Seconds to take every frame of b into a fresh client; 0 on an error.
 * *cpu gets the processor seconds all threads spent on it, *dec the decode
 * thread's alone (the rest is the pool's: which of the two bounds a run).
 * *alone counts the runs whose two threads went on as one (stream.h,
 * threads_alone_from), so that a row's figure says what it measured. */
static double apply(const mts_buf *b, uint32_t threads, int at_keys, mts_bigmem_cache *memory,
                    uint64_t *checksum, double *cpu, double *dec, int *alone, mts_error *err)
{
    mts_stream_client c;
    mts_stream_client_init(&c);
    c.threads = threads;
    c.threads_at_keys = at_keys;
    c.memory = memory;
    double c0 = process_cpu(), d0 = thread_cpu(), t0 = cli_now();
    int ok = mts_stream_client_feed(&c, b->data, b->size, err) == MTS_OK, got = 0;
    mts_stream_event ev;
    while (ok && (got = mts_stream_client_next(&c, &ev, err)) > 0)
        ;
    double t = cli_now() - t0;
    *cpu = process_cpu() - c0;
    *dec = thread_cpu() - d0;
    ok = ok && got == 0 && c.end_checksum != 0;
    *checksum = c.checksum;
    *alone += c.threads_alone_from != 0;
    mts_stream_client_free(&c);
    return ok ? t : 0;
}

static int load(const char *path, mts_model *m, mts_error *err)
{
    size_t len = strlen(path);
    if (len > 5 && strcmp(path + len - 5, ".mtsm") == 0)
        return mts_modelfile_load(path, m, err) == MTS_OK;
    mts_mesh mesh = {0};
    if (mts_mesh_load(path, NULL, &mesh, NULL, err) != MTS_OK)
        return 0;
    int ok = mts_build_model(&mesh, path, NULL, m, NULL, err) == MTS_OK;
    mts_mesh_free(&mesh);
    return ok;
}

int main(int argc, char **argv)
{
    const char *paths[16], *json_path = NULL;
    int npaths = 0, runs = 7, nthreads = 1, at_keys[8] = {0};
    uint32_t threads[8] = {1};
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--threads") && i + 1 < argc) {
            /* a comma-separated list of counts, 1 to 64 each; "3k": three
             * cut at their keys (threads_at_keys), which "3" is not */
            const char *p = argv[++i];
            nthreads = 0;
            while (*p && nthreads < 8) {
                char *end;
                unsigned long v = strtoul(p, &end, 10);
                const int k = end != p && *end == 'k';
                end += k;
                if (end == p || v < 1 || v > 64 || (*end && *end != ','))
                    break;
                at_keys[nthreads] = k;
                threads[nthreads++] = (uint32_t)v;
                p = *end ? end + 1 : end;
            }
            if (*p || !nthreads) {
                fprintf(stderr, "mts-bench-apply: --threads needs counts from 1 to 64, "
                                "comma-separated (at most 8), each with a k to cut at keys\n");
                return CLI_EXIT_USAGE;
            }
        } else if (!strcmp(argv[i], "--json") && i + 1 < argc) {
            json_path = argv[++i];
        } else if (!strcmp(argv[i], "--runs")) {
            uint32_t u;
            if (!cli_option_u32(argc, argv, &i, "mts-bench-apply", 1, 99, &u))
                return CLI_EXIT_USAGE;
            runs = (int)u;
        } else if (!strcmp(argv[i], "-h") || !strcmp(argv[i], "--help")) {
            printf("usage: mts-bench-apply MODEL.mtsm|MESH... [--runs N] [--threads T1,T2,..]\n"
                   "                       [--json FILE]\n"
                   "Per model, both stream forms decoded and applied in this process (median\n"
                   "of N warm runs, default 7): ms, splits/s, their ratio, ns a split; and\n"
                   "the server's encoding time. --threads: the splits form's decoder threads\n"
                   "(stream.h; default 1), each count a row, alternated within each run; a\n"
                   "count with a k (3k) cuts growth at its keys (threads_at_keys), where more\n"
                   "than two without it decode as two.\n");
            return CLI_EXIT_OK;
        } else if (argv[i][0] == '-') {
            fprintf(stderr, "mts-bench-apply: unknown option %s\n", argv[i]);
            return CLI_EXIT_USAGE;
        } else if (npaths < 16) {
            paths[npaths++] = argv[i];
        } else {
            fprintf(stderr, "mts-bench-apply: at most 16 models\n");
            return CLI_EXIT_USAGE;
        }
    }
    if (!npaths) {
        fprintf(stderr, "mts-bench-apply: give models (see --help)\n");
        return CLI_EXIT_USAGE;
    }
    FILE *js = json_path ? fopen(json_path, "w") : NULL;
    if (json_path && !js) {
        fprintf(stderr, "mts-bench-apply: cannot write %s\n", json_path);
        return CLI_EXIT_FAIL;
    }
    if (js)
        fprintf(js, "{\"runs\":%d,\"models\":{", runs);
    printf("\nApplying a stream: both forms in one process, memory warm, median of %d\n",
           runs);
    printf("%-14s %9s %9s %10s %8s %8s %11s %10s %11s %7s %9s %9s %5s\n", "model", "triangles",
           "splits", "splits ms", "cpu ms", "dec ms", "splits M/s", "records ms", "records M/s",
           "ratio", "ns/split", "encode s", "alone");
    printf("%s\n", "----------------------------------------------------------------------------"
                   "------------------------------------");
    int status = CLI_EXIT_OK, first = 1;
    for (int k = 0; k < npaths; k++) {
        char name[128];
        cli_stem(paths[k], name, sizeof name);
        mts_error err = {0};
        mts_model m = {0};
        if (!load(paths[k], &m, &err)) {
            printf("%-14s skipped: %s\n", name, err.msg);
            status = CLI_EXIT_FAIL;
            continue;
        }
        mts_stream s;
        mts_stream_options so = {0};
        so.with_records = 1;
        double e0 = cli_now();
        if (mts_stream_build(&m, "bench", &so, &s, &err) != MTS_OK) {
            printf("%-14s FAILED to encode: %s\n", name, err.msg);
            mts_model_free(&m);
            status = CLI_EXIT_FAIL;
            continue;
        }
        double encode = cli_now() - e0;
        mts_buf a = {0}, r = {0};
        double ta[8][99], tr[99], cpu[8][99], dec[8][99], scratch = 0, scratch2 = 0;
        uint64_t ca[8] = {0}, cr = 0;
        int alone[8] = {0}, unused = 0;
        int ok = bench_connection_bytes(&s, s.model.level_count, &a) &&
                 bench_connection_bytes(s.records_form, s.records_form->model.level_count, &r);
        /* warm as in a process that runs client after client: the large
         * arrays' reservations kept from one to the next (bigmem.h) */
        mts_bigmem_cache *mem = mts_bigmem_cache_create();
        /* a first run of each: first-touch page faults are not decoding */
        ok = ok && apply(&r, 1, 0, mem, &cr, &scratch, &scratch2, &unused, &err) > 0;
        for (int x = 0; ok && x < nthreads; x++)
            ok = apply(&a, threads[x], at_keys[x], mem, &ca[x], &scratch, &scratch2, &unused,
                       &err) > 0;
        for (int i = 0; ok && i < runs; i++) { /* alternated, so drift hits all */
            for (int x = 0; ok && x < nthreads; x++)
                ok = (ta[x][i] = apply(&a, threads[x], at_keys[x], mem, &ca[x], &cpu[x][i],
                                         &dec[x][i], &alone[x], &err)) > 0;
            ok = ok && (tr[i] = apply(&r, 1, 0, mem, &cr, &scratch, &scratch2, &unused, &err)) > 0;
        }
        mts_bigmem_cache_free(mem);
        for (int x = 0; x < nthreads; x++)
            ok = ok && ca[x] == cr;
        if (!ok) {
            printf("%-14s FAILED: %s\n", name, ca[0] != cr ? "the forms end in other meshes" : err.msg);
            status = CLI_EXIT_FAIL;
        }
        /* each count's time over the first count's in the same run: the
         * machine's drift cancels in a run's pair, so their spread is the
         * noise the medians' ratio carries */
        double paired[8][99];
        for (int x = 0; ok && x < nthreads; x++) {
            for (int i = 0; i < runs; i++)
                paired[x][i] = ta[x][i] / ta[0][i];
            qsort(paired[x], (size_t)runs, sizeof paired[x][0], bench_cmp_double);
        }
        if (ok)
            qsort(tr, (size_t)runs, sizeof *tr, bench_cmp_double);
        for (int x = 0; ok && x < nthreads; x++) {
            double *tx = ta[x];
            char row[128];
            if (nthreads > 1 || threads[x] != 1)
                snprintf(row, sizeof row, "%.100s@t%u%s", name, threads[x], at_keys[x] ? "k" : "");
            else
                snprintf(row, sizeof row, "%s", name);
            qsort(tx, (size_t)runs, sizeof *tx, bench_cmp_double);
            qsort(cpu[x], (size_t)runs, sizeof cpu[x][0], bench_cmp_double);
            qsort(dec[x], (size_t)runs, sizeof dec[x][0], bench_cmp_double);
            const double cx = cpu[x][runs / 2], dx = dec[x][runs / 2];
            const double sa = tx[runs / 2], sr = tr[runs / 2], n = m.level_count;
            const uint32_t tris = m.level_triangles[m.level_count];
            printf("%-14s %9u %9u %10.2f %8.2f %8.2f %11.3f %10.2f %11.3f %7.2f %9.0f %9.2f %5d\n",
                   row, tris, m.level_count, sa * 1e3, cx * 1e3, dx * 1e3, n / sa / 1e6, sr * 1e3,
                   n / sr / 1e6, sa / sr, sa / n * 1e9, encode, alone[x]);
            if (js)
                fprintf(js,
                        "%s\"%s\":{\"triangles\":%u,\"splits\":%u,\"splits_bytes\":%zu,"
                        "\"records_bytes\":%zu,\"splits_ms\":%.3f,\"splits_per_s\":%.0f,"
                        "\"records_ms\":%.3f,\"records_per_s\":%.0f,\"ratio\":%.3f,"
                        "\"ns_per_split\":%.1f,\"splits_ms_min\":%.3f,\"records_ms_min\":%.3f,"
                        "\"encode_s\":%.3f,\"threads\":%u,\"at_keys\":%s,\"alone_runs\":%d,"
                        "\"cpu_ms\":%.3f,"
                        "\"decode_cpu_ms\":%.3f,\"over_first_paired\":[%.3f,%.3f,%.3f]}",
                        first ? "" : ",", row, tris, m.level_count, a.size, r.size, sa * 1e3,
                        n / sa, sr * 1e3, n / sr, sa / sr, sa / n * 1e9, tx[0] * 1e3,
                        tr[0] * 1e3, encode, threads[x], at_keys[x] ? "true" : "false", alone[x],
                        cx * 1e3, dx * 1e3,
                        paired[x][runs / 4], paired[x][runs / 2], paired[x][(3 * runs) / 4]);
            first = 0;
        }
        mts_buf_free(&a);
        mts_buf_free(&r);
        mts_stream_free(&s);
        mts_model_free(&m);
    }
    int any_k = 0;
    for (int x = 0; x < nthreads; x++)
        any_k |= at_keys[x];
    printf("(ratio: splits form / records form; ns/split: the splits form's; alone: the timed "
           "runs whose two threads went on as one, finding the pool thread without a core;\n%s"
           " cpu ms: the splits form's processor time, all threads together, median;\n"
           " dec ms: the decode thread's alone, the caller's: cpu ms less it is the pool's)\n",
           any_k ? " @tNk: N threads with growth cut at its keys (stream.h threads_at_keys);\n"
                 : "");
    if (js) {
        fprintf(js, "}}\n");
        fclose(js);
    }
    return status;
}
