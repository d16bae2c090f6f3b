/* The browser client's figures for `make bench`: the page (build/web) in
 * headless Chromium, driven over the DevTools protocol (tests/cdp.h),
 * against mts-servers of this build on loopback, each behind nginx running
 * web/nginx.conf as a user would serve the page:
 *   - time to connect, to the first frame and to the full level, the
 *     decoder's time in the page, and the checksum (median of --runs);
 *   - frames drawn while the model streams slowly enough to watch
 *     (mts-server --rate-limit), every animation frame drawn (&redraw=1),
 *     and the script's time in a frame;
 *   - pictures of the page at three levels, one coloured by strip and the
 *     whole page with its panel, into --png-dir.
 * The WebAssembly decoder's splits/s beside the native one's are
 * bench/web.sh's (node, mts-bench-apply). */
#include <limits.h>
#include <math.h>
#include <signal.h>
#include <sys/stat.h>

#include "../tests/cdp.h"
#include "cli.h"

#define MAX_RUNS 15
#define NPICS 5 /* three levels, one by strip, the page with its panel */

/* mts-server and the nginx in front of it (web/nginx.conf: the page and
 * the stream at /stream on web_port), as a user runs the page. */
typedef struct server {
    mts_test_server s;
    pid_t front;
    int web_port;
} server;

static int server_start(const char *bin_dir, const char *models, const char *web_dir,
                        const char *rate, const char *log, server *sv)
{
    const char *extra[] = {"--quiet", rate ? "--rate-limit" : NULL, rate, NULL};
    char listen[64], out[4096], nginx[512], root[PATH_MAX], dir[800], nlog[800];
    sv->front = -1;
    int up = mts_test_ws_server_start(&sv->s, bin_dir, models, extra, log, 60);
    snprintf(listen, sizeof listen, "127.0.0.1:%d", sv->s.port);
    if (!up || !mts_test_wait_models(bin_dir, listen, "cow", 600, out, sizeof out))
        return 0;
    if (!mts_test_find_nginx(nginx, sizeof nginx) || !realpath(web_dir, root)) {
        fprintf(stderr, "mts-bench-web: no nginx (scripts/deps.sh), or no %s\n", web_dir);
        return 0;
    }
    snprintf(dir, sizeof dir, "%s.front", log);
    snprintf(nlog, sizeof nlog, "%s.nginx", log);
    sv->front = mts_test_front_start(nginx, dir, root, sv->s.ws_port, &sv->web_port, nlog, 30);
    return sv->front > 0;
}

static double json_double(const char *json, const char *key)
{
    char v[64];
    mts_test_json(json, key, v, sizeof v);
    return v[0] ? strtod(v, NULL) : NAN;
}

/* Loads url and waits for the stream's end to be drawn (or an error):
 * the page's state into state. */
static int page_run(mts_cdp *c, const char *url, double seconds, mts_buf *state)
{
    if (!mts_cdp_navigate(c, url))
        return 0;
    double until = mts_cdp_now() + seconds;
    while (mts_cdp_now() < until) {
        if (mts_cdp_eval(c, "JSON.stringify(window.mtsState || {})", state)) {
            const char *st = (const char *)state->data;
            if (strstr(st, "\"phase\":\"error\""))
                return 0;
            if (strstr(st, "\"phase\":\"complete\"") && strstr(st, "\"morphing\":false") &&
                mts_test_json_long(st, "level") == mts_test_json_long(st, "stop_level"))
                return 1;
        }
        mts_cdp_sleep_ms(20);
    }
    return 0;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median(double *v, int n)
{
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    return n ? (n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2])) : NAN;
}

/* The decoder on one thread against two, where the page is cross-origin
 * isolated (web/nginx.conf sends COOP/COEP): each model loaded `runs`
 * times with &threads=1 (the one-thread build) and with &threads=2 (the
 * threaded build), alternated, the order swapped every other pair, so
 * that drift on a shared machine falls on both alike. Every load must end
 * at the same checksum. */
#define THREAD_MODELS 8
typedef struct thread_cmp {
    char model[64], checksum[64];
    double final[2], decode[2];
    long level, threads, isolated;
    int match;
} thread_cmp;

static int compare_threads(mts_cdp *c, int port, const char *list, uint32_t runs,
                           thread_cmp *out, int *count, mts_buf *state)
{
    char names[512];
    snprintf(names, sizeof names, "%s", list);
    *count = 0;
    for (char *save = NULL, *m = strtok_r(names, ",", &save); m && *count < THREAD_MODELS;
         m = strtok_r(NULL, ",", &save)) {
        thread_cmp *t = &out[(*count)++];
        memset(t, 0, sizeof *t);
        snprintf(t->model, sizeof t->model, "%s", m);
        double final[2][MAX_RUNS], decode[2][MAX_RUNS];
        char url[2][400];
        for (int k = 0; k < 2; k++)
            snprintf(url[k], sizeof url[k], "http://127.0.0.1:%d/?model=%s&bare=1%s", port, m,
                     k ? "&threads=2" : "&threads=1");
        t->match = 1;
        /* one load of each first: scripts and WebAssembly into the cache */
        for (int k = 0; k < 2; k++)
            if (!page_run(c, url[k], 60, state))
                goto failed;
        for (uint32_t r = 0; r < runs; r++) {
            for (int j = 0; j < 2; j++) {
                const int k = (int)(r & 1) ^ j;
                if (!page_run(c, url[k], 60, state))
                    goto failed;
                const char *st = (const char *)state->data;
                final[k][r] = json_double(st, "ms_final");
                decode[k][r] = json_double(st, "decode_ms");
                char sum[64];
                mts_test_json(st, "checksum", sum, sizeof sum);
                if (!t->checksum[0])
                    snprintf(t->checksum, sizeof t->checksum, "%s", sum);
                t->match &= sum[0] && strcmp(sum, t->checksum) == 0;
                if (k == 1) {
                    t->threads = mts_test_json_long(st, "threads");
                    t->isolated = strstr(st, "\"isolated\":true") != NULL;
                }
                t->level = mts_test_json_long(st, "level");
            }
        }
        for (int k = 0; k < 2; k++) {
            t->final[k] = median(final[k], (int)runs);
            t->decode[k] = median(decode[k], (int)runs);
        }
        continue;
    failed:
        fprintf(stderr, "mts-bench-web: %s did not stream: %s\n", m,
                state->data ? (const char *)state->data : "");
        return 0;
    }
    return 1;
}

/* The 1-minute load average (what else the machine ran meanwhile), -1
 * where /proc has none. */
static double load_average(void)
{
    FILE *f = fopen("/proc/loadavg", "r");
    double v = -1;
    if (f) {
        if (fscanf(f, "%lf", &v) != 1)
            v = -1;
        fclose(f);
    }
    return v;
}

static void threads_json(FILE *f, const thread_cmp *t, int count, uint32_t runs,
                         const char *rate, const double load[2])
{
    fprintf(f, "\"threads\":{\"runs\":%u,\"rate_limit\":%s,\"load_before\":%.2f,"
               "\"load_after\":%.2f,\"models\":{",
            runs, rate && *rate ? rate : "0", load[0], load[1]);
    for (int i = 0; i < count; i++, t++)
        fprintf(f,
                "%s\"%s\":{\"level\":%ld,\"ms_final_1\":%.2f,\"ms_final_2\":%.2f,"
                "\"ratio\":%.3f,\"decode_ms_1\":%.2f,\"decode_ms_2\":%.2f,\"threads\":%ld,"
                "\"isolated\":%s,\"checksum\":%s,\"checksum_match\":%s}",
                i ? "," : "", t->model, t->level, t->final[0], t->final[1],
                t->final[1] / t->final[0], t->decode[0], t->decode[1], t->threads,
                t->isolated ? "true" : "false", t->checksum[0] ? t->checksum : "\"\"",
                t->match ? "true" : "false");
    fprintf(f, "}}");
}

static void usage(FILE *f)
{
    fprintf(f,
            "usage: mts-bench-web MODELS_DIR [--model NAME] [--runs N] [--rate-limit B/s]\n"
            "                     [--levels A,B] [--png-dir DIR] [--web-dir DIR] [--json FILE]\n"
            "                     [--threads-models A,B,... [--threads-rate-limit B/s]\n"
            "                     [--threads-only]]\n"
            "The browser client in headless Chromium against mts-servers of this build\n"
            "serving MODELS_DIR (with cow in it) on loopback: connect, first frame and\n"
            "full level (median of --runs, default 5), frames while the model streams at\n"
            "--rate-limit (default 40000 B/s), pictures at levels A, B and the full\n"
            "level (default 1000,8000) into --png-dir (default bench/plots).\n"
            "--threads-models: the full level of each model with the one-thread decoder\n"
            "and the threaded one (two threads), --runs loads each, alternated, medians,\n"
            "from a server paced at --threads-rate-limit (default: not paced);\n"
            "--threads-only: that alone.\n"
            "Exit status 1 when a figure could not be measured.\n");
}

int main(int argc, char **argv)
{
    signal(SIGPIPE, SIG_IGN);
    const char *models = NULL, *model = "bunny00", *json = NULL, *png_dir = "bench/plots";
    const char *web_dir = "build/web", *rate = "40000";
    const char *thread_models = NULL, *thread_rate = NULL;
    int threads_only = 0;
    uint32_t runs = 5, levels[2] = {1000, 8000};
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
            usage(stdout);
            return 0;
        } else if (!strcmp(a, "--runs")) {
            if (!cli_option_u32(argc, argv, &i, "mts-bench-web", 1, MAX_RUNS, &runs))
                return 2;
        } else if (!strcmp(a, "--levels") && i + 1 < argc) {
            if (sscanf(argv[++i], "%u,%u", &levels[0], &levels[1]) != 2) {
                fprintf(stderr, "mts-bench-web: --levels wants A,B, not %s\n", argv[i]);
                return 2;
            }
        } else if (!strcmp(a, "--model") && i + 1 < argc) {
            model = argv[++i];
        } else if (!strcmp(a, "--rate-limit") && i + 1 < argc) {
            rate = argv[++i];
        } else if (!strcmp(a, "--png-dir") && i + 1 < argc) {
            png_dir = argv[++i];
        } else if (!strcmp(a, "--web-dir") && i + 1 < argc) {
            web_dir = argv[++i];
        } else if (!strcmp(a, "--threads-models") && i + 1 < argc) {
            thread_models = argv[++i];
        } else if (!strcmp(a, "--threads-rate-limit") && i + 1 < argc) {
            thread_rate = argv[++i];
        } else if (!strcmp(a, "--threads-only")) {
            threads_only = 1;
        } else if (!strcmp(a, "--json") && i + 1 < argc) {
            json = argv[++i];
        } else if (a[0] == '-' || models) {
            fprintf(stderr, "mts-bench-web: unexpected %s\n", a);
            usage(stderr);
            return 2;
        } else {
            models = a;
        }
    }
    if (!models) {
        usage(stderr);
        return 2;
    }
    char bin_dir[512], path[700];
    mts_test_bin_dir(argv[0], bin_dir, sizeof bin_dir);
    snprintf(path, sizeof path, "%s/mts_web.js", web_dir);
    struct stat sb;
    if (stat(path, &sb) != 0) {
        fprintf(stderr, "mts-bench-web: no %s (make web)\n", path);
        return 1;
    }
    const char *tmp = mts_test_tmpdir();
    char log_fast[700], log_slow[700], log_browser[700];
    snprintf(log_fast, sizeof log_fast, "%s/bench_web_server.log", tmp);
    snprintf(log_slow, sizeof log_slow, "%s/bench_web_server_slow.log", tmp);
    snprintf(log_browser, sizeof log_browser, "%s/bench_web_chromium.log", tmp);
    server fast = {0}, slow = {0}, paced = {0};
    mts_cdp c;
    int ok = server_start(bin_dir, models, web_dir, NULL, log_fast, &fast) &&
             (threads_only || server_start(bin_dir, models, web_dir, rate, log_slow, &slow));
    char log_paced[700];
    snprintf(log_paced, sizeof log_paced, "%s/bench_web_server_paced.log", tmp);
    ok = ok && (!thread_models || !thread_rate ||
                server_start(bin_dir, models, web_dir, thread_rate, log_paced, &paced));
    if (!ok) {
        fprintf(stderr, "mts-bench-web: the servers did not start (%s, %s)\n", log_fast, log_slow);
        goto done_servers;
    }
    /* the window client's bench size */
    if (!mts_cdp_start(&c, tmp, log_browser, 800, 600, 30)) {
        fprintf(stderr, "mts-bench-web: chromium did not start (%s)\n", log_browser);
        ok = 0;
        goto done;
    }
    mts_buf state = {0};
    thread_cmp tc[THREAD_MODELS];
    int tc_count = 0;
    double load[2] = {-1, -1};
    if (thread_models) {
        load[0] = load_average();
        const int port = thread_rate ? paced.web_port : fast.web_port;
        if (!(ok = compare_threads(&c, port, thread_models, runs, tc, &tc_count, &state)))
            goto done_state;
        load[1] = load_average();
        printf("Browser client, the decoder on one thread and on two (headless Chromium, "
               "the page cross-origin isolated, loopback%s%s%s, median of %u alternated loads; "
               "load average %.2f before, %.2f after):\n",
               thread_rate ? " at " : "", thread_rate ? thread_rate : "",
               thread_rate ? " B/s" : "", runs, load[0], load[1]);
        for (int i = 0; i < tc_count; i++)
            printf("  %s: full level %ld at %.1f ms on one thread, %.1f ms on %ld (%.3fx); "
                   "decode %.1f / %.1f ms; checksum %s%s\n",
                   tc[i].model, tc[i].level, tc[i].final[0], tc[i].final[1], tc[i].threads,
                   tc[i].final[1] / tc[i].final[0], tc[i].decode[0], tc[i].decode[1],
                   tc[i].checksum, tc[i].match ? " (the same)" : " (DIFFERENT)");
        for (int i = 0; i < tc_count; i++)
            ok &= tc[i].match && tc[i].threads == 2 && tc[i].isolated;
        if (threads_only) {
            FILE *f = json ? fopen(json, "w") : NULL;
            if (f) {
                fprintf(f, "{");
                threads_json(f, tc, tc_count, runs, thread_rate, load);
                fprintf(f, "}\n");
                ok = fclose(f) == 0 && ok;
            } else if (json) {
                fprintf(stderr, "mts-bench-web: cannot write %s\n", json);
                ok = 0;
            }
            goto done_state;
        }
    }
    char url[800], checksum[64] = "";
    double connect[MAX_RUNS], base[MAX_RUNS], first[MAX_RUNS], final[MAX_RUNS], decode[MAX_RUNS];
    long level = 0, bytes = 0;
    /* one load first: the page, its scripts and WebAssembly into the cache,
     * as for a user who has opened it before */
    snprintf(url, sizeof url, "http://127.0.0.1:%d/?model=%s&bare=1", fast.web_port, model);
    ok = page_run(&c, url, 60, &state);
    for (uint32_t r = 0; ok && r < runs; r++) {
        ok = page_run(&c, url, 60, &state);
        const char *st = (const char *)state.data;
        connect[r] = json_double(st, "ms_connect");
        base[r] = json_double(st, "ms_base");
        first[r] = json_double(st, "ms_first_frame");
        final[r] = json_double(st, "ms_final");
        decode[r] = json_double(st, "decode_ms");
        level = mts_test_json_long(st, "level");
        bytes = mts_test_json_long(st, "bytes");
        mts_test_json(st, "checksum", checksum, sizeof checksum);
    }
    if (!ok) {
        fprintf(stderr, "mts-bench-web: %s did not stream: %s\n", url,
                state.data ? (const char *)state.data : "");
        goto done_state;
    }
    /* while it streams slowly: frames drawn as batches come */
    snprintf(url, sizeof url, "http://127.0.0.1:%d/?model=%s&bare=1&redraw=1", slow.web_port,
             model);
    double t0 = mts_cdp_now();
    ok = page_run(&c, url, 120, &state);
    const char *st = (const char *)state.data;
    double wall = mts_cdp_now() - t0;
    double frames = json_double(st, "frames_streaming");
    double span = (json_double(st, "ms_final") - json_double(st, "ms_first_frame")) / 1000;
    double fps = span > 0 ? (frames - 1) / span : NAN;
    double all_frames = json_double(st, "frames");
    double draw_mean = all_frames > 0 ? json_double(st, "draw_ms_total") / all_frames : NAN;
    double draw_max = json_double(st, "draw_ms_max");
    if (!ok) {
        fprintf(stderr, "mts-bench-web: %s did not stream: %s\n", url, st ? st : "");
        goto done_state;
    }
    /* pictures */
    mkdir(png_dir, 0755);
    struct {
        long level;
        int strips;
        char path[700];
        long triangles;
    } pics[NPICS] = {{levels[0], 0, "", 0}, {levels[1], 0, "", 0}, {0, 0, "", 0},
                     {levels[1], 1, "", 0}, {0, 2, "", 0}};
    for (int k = 0; ok && k < NPICS; k++) {
        char lv[40] = "";
        if (pics[k].level)
            snprintf(lv, sizeof lv, "&level=%ld", pics[k].level);
        /* strips 2: the whole page, its panel and HUD (the README's picture) */
        snprintf(url, sizeof url, "http://127.0.0.1:%d/?model=%s%s%s%s", fast.web_port, model,
                 pics[k].strips == 2 ? "" : "&bare=1", lv, pics[k].strips == 1 ? "&strips=1" : "");
        ok = page_run(&c, url, 60, &state);
        pics[k].level = mts_test_json_long((const char *)state.data, "level");
        pics[k].triangles = mts_test_json_long((const char *)state.data, "triangles");
        if (pics[k].strips == 2)
            snprintf(pics[k].path, sizeof pics[k].path, "%s/web_page_%s.png", png_dir, model);
        else
            snprintf(pics[k].path, sizeof pics[k].path, "%s/web_%s_%s%ld.png", png_dir, model,
                     pics[k].strips ? "strips_" : "", pics[k].level);
        ok = ok && mts_cdp_screenshot(&c, pics[k].path);
    }
    if (!ok) {
        fprintf(stderr, "mts-bench-web: a picture failed: %s\n",
                state.data ? (const char *)state.data : "");
        goto done_state;
    }
    double first_max = 0;
    for (uint32_t r = 0; r < runs; r++)
        first_max = first[r] > first_max ? first[r] : first_max;
    double m_connect = median(connect, (int)runs), m_first = median(first, (int)runs);
    double m_base = median(base, (int)runs);
    double m_final = median(final, (int)runs), m_decode = median(decode, (int)runs);
    printf("Browser client (%s, headless Chromium, SwiftShader, 800x600, loopback, "
           "median of %u):\n",
           model, runs);
    printf("  connect %.1f ms, base mesh in %.1f ms, first frame %.1f ms (at most %.1f), full "
           "level %ld at %.1f ms (decode %.1f ms in the page), %ld B, checksum %s\n",
           m_connect, m_base, m_first, first_max, level, m_final, m_decode, bytes, checksum);
    printf("  streaming at %s B/s: %.0f frames in %.2f s while it came (%.1f fps); the "
           "script's share of a frame %.2f ms mean, %.2f ms at most\n",
           rate, frames, span, fps, draw_mean, draw_max);
    for (int k = 0; k < NPICS; k++)
        printf("  picture: level %ld (%ld triangles)%s: %s\n", pics[k].level, pics[k].triangles,
               pics[k].strips == 1 ? ", by strip" : pics[k].strips == 2 ? ", the page" : "",
               pics[k].path);
    if (json) {
        FILE *f = fopen(json, "w");
        if (!f) {
            fprintf(stderr, "mts-bench-web: cannot write %s\n", json);
            ok = 0;
            goto done_state;
        }
        fprintf(f,
                "{\"model\":\"%s\",\"runs\":%u,\"width\":800,\"height\":600,\"ms_connect\":%.2f,"
                "\"ms_base\":%.2f,\"ms_first_frame\":%.2f,\"ms_first_frame_max\":%.2f,\"ms_final\":%.2f,\"decode_ms\":%.2f,\"level\":%ld,"
                "\"bytes\":%ld,\"checksum\":%s,\"streaming\":{\"rate_limit\":%s,\"seconds\":%.3f,"
                "\"wall_s\":%.3f,\"frames\":%.0f,\"fps\":%.2f,\"script_ms_mean\":%.3f,"
                "\"script_ms_max\":%.3f},\"pictures\":[",
                model, runs, m_connect, m_base, m_first, first_max, m_final, m_decode, level, bytes,
                checksum[0] ? checksum : "\"\"", rate, span, wall, frames, fps, draw_mean,
                draw_max);
        for (int k = 0; k < NPICS; k++)
            fprintf(f, "%s{\"level\":%ld,\"triangles\":%ld,\"strips\":%d,\"path\":\"%s\"}",
                    k ? "," : "", pics[k].level, pics[k].triangles, pics[k].strips,
                    pics[k].path);
        fprintf(f, "]");
        if (tc_count) {
            fprintf(f, ",");
            threads_json(f, tc, tc_count, runs, thread_rate, load);
        }
        fprintf(f, "}\n");
        ok = fclose(f) == 0 && ok;
    }
done_state:
    mts_buf_free(&state);
done:
    mts_cdp_stop(&c);
done_servers:
    for (server *sv = &fast; sv; sv = sv == &fast ? &slow : sv == &slow ? &paced : NULL) {
        if (sv->front > 0)
            mts_test_stop(sv->front);
        if (sv->s.pid > 0)
            mts_test_stop(sv->s.pid);
    }
    return ok ? 0 : 1;
}
