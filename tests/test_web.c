/* The browser client against a loopback mts-server --ws-listen behind
 * nginx running web/nginx.conf (the page's files from build/web, the
 * stream proxied at /stream), as a user would run it (make demo-web):
 *   - the WebAssembly decoder, run by node (tests/web/decode.js), ends cow,
 *     bunny00 and fandisk_large at the same checksum as mts-client, at the
 *     full level and at partial stops (a level, a fraction);
 *   - the page in headless Chromium (driven over the DevTools protocol,
 *     tests/cdp.h) streams cow and bunny00 to the full level: the page's
 *     own state says the level and mts-client's checksum, and its picture
 *     is within a stated tolerance of mts-client --png of the same view;
 *   - a stop level from the page's query ends there with mts-client's
 *     checksum for that stop;
 *   - the level slider goes down and up through geomorphs, and the lower
 *     level's picture is mts-client's;
 *   - a model with vertex colours (tests/data/cow_colors.ply) is drawn in
 *     them: the page says so, its picture is mts-client's coloured one
 *     within the same tolerance, at the full level and slid down to level
 *     100 through a geomorph, and far from mts-client --no-colors' grey;
 *   - a server killed mid-stream shows an error on the page, not a frozen
 *     picture;
 *   - the page is cross-origin isolated (web/nginx.conf sends COOP/COEP),
 *     and with ?threads=2 decodes on two threads (mts_web_mt.wasm) to
 *     mts-client's level and checksum, cow, bunny00 (also to a stop) and
 *     fandisk_large, and a stream file of another origin too; a page that
 *     is not isolated (docker/nginx-tls.conf's) runs one thread;
 *   - the page reads stream files (?src=) cross-origin over https from
 *     nginx running docker/nginx-tls.conf (a throwaway CA whose server key
 *     Chromium is told to trust): cow and bunny00 to the full level, a
 *     stop inside a batch and a low one, and a continuation to a higher
 *     stop end at mts-client's level and checksum over TCP; nginx killed
 *     mid-transfer and started again, the page resumes from the first
 *     batch not held; a server that ignores Range is used, cut to the
 *     range; a wrong Content-Range, a 404 and a damaged file are errors
 *     the page shows by name.
 * build/web holds the page's files and nothing else (a web server hands
 * out all of it). Skips, saying why, without build/web (make web:
 * emscripten), node, chromium or nginx (fails instead with
 * MTS_TEST_REQUIRE_WEB=1, as in CI); the shared models' parts skip without
 * ../shared/models. */
#include <dirent.h>
#include <limits.h>
#include <signal.h>
#include <stdint.h>
#include <sys/prctl.h>

#include "cdp.h"
#include "test.h"
#include "test_proc.h"

static char bin_dir[512], tmp_dir[512], models_dir[600], web_dir[600], nginx[512];
/* the stream files (mts-build --stream), served by the TLS front */
static char www_dir[600];
static int have_node, have_chromium, have_shared;
/* the threaded build (mts_web_mt.js), which make web builds beside */
static int have_mt;

/* A picture may differ from mts-client's where SwiftShader and llvmpipe
 * rasterise an edge differently: at most this share of pixels by more
 * than PIXEL_TOLERANCE in a channel. */
#define PIXEL_TOLERANCE 48
#define PIXEL_SHARE 0.02

/* mts-server (pid; TCP on port, WebSocket on ws_port) and the nginx in
 * front of it (front; the page and /stream on web_port). */
typedef struct server {
    pid_t pid, front;
    int port, ws_port, web_port;
    char log[700];
} server;

static int server_start(server *sv, const char *name, const char *rate)
{
    snprintf(sv->log, sizeof sv->log, "%s/web_%s.log", tmp_dir, name);
    const char *extra[] = {rate ? "--rate-limit" : NULL, rate, NULL};
    mts_test_server ts;
    int up = mts_test_ws_server_start(&ts, bin_dir, models_dir, extra, sv->log, 60);
    sv->pid = ts.pid;
    sv->port = ts.port;
    sv->ws_port = ts.ws_port;
    sv->front = -1;
    char listen[64], out[4096], dir[700], log[800];
    snprintf(listen, sizeof listen, "127.0.0.1:%d", sv->port);
    up = up && mts_test_wait_models(bin_dir, listen, "cow", 600, out, sizeof out);
    snprintf(dir, sizeof dir, "%s/web_front_%s", tmp_dir, name);
    snprintf(log, sizeof log, "%s/web_nginx_%s.log", tmp_dir, name);
    if (up)
        sv->front = mts_test_front_start(nginx, dir, web_dir, sv->ws_port, &sv->web_port, log, 30);
    if (up && sv->front < 0) {
        mts_test_read_file(log, out, sizeof out);
        fprintf(stderr, "  nginx did not start: %s\n", out);
    }
    return up && sv->front > 0;
}

/* Stops nginx, then the server: the server's exit status (0 after a clean
 * stop; a sanitizer's report makes it non-zero). */
static int server_stop(server *sv)
{
    if (sv->front > 0)
        mts_test_stop(sv->front);
    sv->front = -1;
    int st = sv->pid > 0 ? mts_test_stop(sv->pid) : 0;
    sv->pid = 0;
    return st;
}

/* build/web holds only what a page loads: a web server hands out all of it. */
static void test_page_folder(mts_test *t)
{
    DIR *d = opendir(web_dir);
    CHECK(t, d != NULL);
    const char *page[] = {".html", ".js", ".css", ".wasm"};
    int files = 0;
    for (struct dirent *e; d && (e = readdir(d));) {
        if (e->d_name[0] == '.')
            continue;
        size_t n = strlen(e->d_name);
        int ok = 0;
        for (size_t k = 0; k < sizeof page / sizeof page[0]; k++) {
            size_t m = strlen(page[k]);
            ok |= n > m && strcmp(e->d_name + n - m, page[k]) == 0;
        }
        char path[900];
        struct stat st;
        snprintf(path, sizeof path, "%s/%s", web_dir, e->d_name);
        ok &= stat(path, &st) == 0 && S_ISREG(st.st_mode);
        CHECKF(t, ok, "%s is in the page's folder %s, which a web server hands out whole",
               e->d_name, web_dir);
        files++;
    }
    if (d)
        closedir(d);
    CHECKF(t, files >= 6, "%d files in %s", files, web_dir);
}

/* mts-client's checksum for a model at a stop ("" when it failed). */
static void native_checksum(const server *sv, const char *model, const char *stop, char *out,
                            size_t size)
{
    char cmd[1400], text[8192];
    snprintf(cmd, sizeof cmd, "%s/mts-client 127.0.0.1:%d %s %s --no-render --json --quiet",
             bin_dir, sv->port, model, stop);
    out[0] = 0;
    if (mts_test_run(cmd, text, sizeof text) == 0)
        mts_test_json(text, "checksum", out, size);
    /* "\"06b1...\"" -> 06b1... */
    size_t n = strlen(out);
    if (n >= 2 && out[0] == '"') {
        memmove(out, out + 1, n - 2);
        out[n - 2] = 0;
    }
}

static void test_node_decoder(mts_test *t)
{
    if (!have_node)
        SKIP(t, "no node (apt-get install nodejs): the WebAssembly decoder is not run");
    server sv;
    CHECK(t, server_start(&sv, "node", NULL));
    const char *models[] = {"cow", "bunny00", "fandisk_large"};
    struct {
        const char *native, *hello;
    } stops[] = {{"", "0:0"}, {"--level 500", "1:500"}, {"--fraction 0.25", "3:250000"}};
    for (int m = 0; m < 3; m++) {
        if (m > 0 && !have_shared) {
            fprintf(stderr, "  (bunny00, fandisk_large: no ../shared/models)\n");
            break;
        }
        for (int k = 0; k < 3; k++) {
            char native[64], cmd[1400], out[8192], ours[64], theirs[64];
            native_checksum(&sv, models[m], stops[k].native, native, sizeof native);
            snprintf(cmd, sizeof cmd, "node tests/web/decode.js %s tcp:127.0.0.1:%d:%s:%s",
                     web_dir, sv.port, models[m], stops[k].hello);
            int rc = mts_test_run(cmd, out, sizeof out);
            mts_test_json(out, "checksum", ours, sizeof ours);
            mts_test_json(out, "server_checksum", theirs, sizeof theirs);
            CHECKF(t, rc == 0 && native[0] && strstr(ours, native) && strstr(theirs, native),
                   "%s %s: native %s, WebAssembly %s", models[m], stops[k].hello, native, out);
        }
    }
    CHECK(t, server_stop(&sv) == 0);
}

static int page_settled(mts_cdp *c, const server *sv, const char *page_query, double seconds,
                        mts_buf *state);
static int page_drawn(mts_cdp *c, mts_buf *state);

/* Waits for the page's phase to be one of `phases` (space-separated);
 * its state's JSON into state. */
static int wait_phase(mts_cdp *c, const char *phases, double seconds, mts_buf *state)
{
    double until = mts_cdp_now() + seconds;
    while (mts_cdp_now() < until) {
        if (mts_cdp_eval(c, "JSON.stringify(window.mtsState || {})", state)) {
            char phase[64];
            mts_test_json((const char *)state->data, "phase", phase, sizeof phase);
            char want[80];
            for (const char *p = phases; *p;) {
                size_t n = strcspn(p, " ");
                snprintf(want, sizeof want, "\"%.*s\"", (int)n, p);
                if (strcmp(phase, want) == 0)
                    return 1;
                p += n + (p[n] == ' ');
            }
        }
        mts_cdp_sleep_ms(50);
    }
    return 0;
}

/* Headless Chromium for one test, its log named after it; 1 when up. */
static int browser_start(mts_cdp *c, const char *name, char *log, size_t log_size)
{
    snprintf(log, log_size, "%s/web_chromium_%s.log", tmp_dir, name);
    return mts_cdp_start(c, tmp_dir, log, 512, 512, 30);
}

/* The page's picture against mts-client --png of the same stop (the same
 * camera, 512 x 512): the share of pixels apart by more than
 * PIXEL_TOLERANCE, -1 when a picture failed. */
static double picture_share(const server *sv, mts_cdp *c, const char *model, const char *stop,
                            const char *name)
{
    char png_web[700], png_native[700], cmd[2000], out[4096];
    snprintf(png_web, sizeof png_web, "%s/web_%s.png", tmp_dir, name);
    snprintf(png_native, sizeof png_native, "%s/native_%s.png", tmp_dir, name);
    snprintf(cmd, sizeof cmd, "%s/mts-client 127.0.0.1:%d %s %s --png %s --quiet", bin_dir,
             sv->port, model, stop, png_native);
    if (!mts_cdp_screenshot(c, png_web) || mts_test_run(cmd, out, sizeof out) != 0)
        return -1;
    double share = mts_cdp_png_diff(png_web, png_native, PIXEL_TOLERANCE);
    fprintf(stderr, "  %s: %.2f%% of pixels differ by more than %d from mts-client's (%s)\n",
            name, 100 * share, PIXEL_TOLERANCE, png_web);
    return share;
}

static void test_page(mts_test *t)
{
    if (!have_chromium)
        SKIP(t, "no chromium (scripts/deps.sh installs it): the page is not tested");
    server sv;
    CHECK(t, server_start(&sv, "page", NULL));
    mts_cdp c;
    char log[700];
    int up = browser_start(&c, "page", log, sizeof log);
    CHECKF(t, up, "chromium did not start (see %s)", log);
    struct {
        const char *model, *query, *native_stop;
        int shared;
    } runs[] = {
        {"cow", "", "", 0},
        {"bunny00", "", "", 1},
        {"bunny00", "&level=2000", "--level 2000", 1},
    };
    for (int i = 0; up && i < 3; i++) {
        if (runs[i].shared && !have_shared) {
            fprintf(stderr, "  (%s: no ../shared/models)\n", runs[i].model);
            continue;
        }
        char url[600], native[64];
        snprintf(url, sizeof url, "http://127.0.0.1:%d/?model=%s&bare=1%s", sv.web_port,
                 runs[i].model, runs[i].query);
        CHECK(t, mts_cdp_navigate(&c, url));
        mts_buf state = {0};
        int done = wait_phase(&c, "complete error", 120, &state);
        const char *st = state.data ? (const char *)state.data : "";
        CHECKF(t, done && strstr(st, "\"phase\":\"complete\""), "%s: %s", url, st);
        /* the stream's end is drawn at the next animation frame, after the
         * geomorph to it */
        double until = mts_cdp_now() + 20;
        while (done && mts_cdp_now() < until &&
               (mts_test_json_long((const char *)state.data, "level") !=
                    mts_test_json_long((const char *)state.data, "stop_level") ||
                !strstr((const char *)state.data, "\"morphing\":false"))) {
            mts_cdp_sleep_ms(50);
            mts_cdp_eval(&c, "JSON.stringify(window.mtsState)", &state);
        }
        st = (const char *)state.data;
        native_checksum(&sv, runs[i].model, runs[i].native_stop, native, sizeof native);
        char want[80];
        snprintf(want, sizeof want, "\"checksum\":\"%s\"", native);
        CHECKF(t, native[0] && strstr(st, want), "%s: mts-client says %s; the page %s", url,
               native, st);
        long level = mts_test_json_long(st, "level"), stop = mts_test_json_long(st, "stop_level");
        CHECKF(t, level > 0 && level == stop &&
                      (!runs[i].native_stop[0] || level == 2000),
               "%s: level %ld, stop %ld", url, level, stop);
        char name[64];
        snprintf(name, sizeof name, "%s_%d", runs[i].model, i);
        double share = picture_share(&sv, &c, runs[i].model, runs[i].native_stop, name);
        CHECKF(t, share >= 0 && share <= PIXEL_SHARE, "%s%s: %.4f", runs[i].model, runs[i].query,
               share);
        mts_buf_free(&state);
    }
    mts_cdp_stop(&c);
    CHECK(t, server_stop(&sv) == 0);
}

/* The threaded decoder (mts_web_mt.wasm, ?threads=2): web/nginx.conf
 * sends COOP/COEP, so the page is cross-origin isolated and runs two
 * threads, ending at mts-client's level and checksum as the one-thread
 * page does; the page's default is one thread. (A page that is not
 * isolated falls back to one: test_page_stream_file's page over https.) */
static void test_page_threads(mts_test *t)
{
    if (!have_chromium)
        SKIP(t, "no chromium (scripts/deps.sh installs it): the page is not tested");
    if (!have_mt) {
        if (getenv("MTS_TEST_REQUIRE_WEB")) {
            CHECKF(t, 0, "no %s/mts_web_mt.js (make web builds it)", web_dir);
            return;
        }
        SKIP(t, "no %s/mts_web_mt.js (make web builds it): the threaded page is not tested",
             web_dir);
    }
    server sv;
    CHECK(t, server_start(&sv, "threads", NULL));
    mts_cdp c;
    char log[700];
    int up = browser_start(&c, "threads", log, sizeof log);
    CHECKF(t, up, "chromium did not start (see %s)", log);
    struct {
        const char *model, *query, *native_stop;
        long threads;
        int shared;
    } runs[] = {
        {"cow", "&threads=2", "", 2, 0},
        {"cow", "", "", 1, 0},
        {"bunny00", "&threads=2", "", 2, 1},
        {"bunny00", "&threads=2&level=2000", "--level 2000", 2, 1},
        {"fandisk_large", "&threads=2", "", 2, 1},
    };
    mts_buf state = {0};
    for (size_t i = 0; up && i < sizeof runs / sizeof runs[0]; i++) {
        if (runs[i].shared && !have_shared) {
            fprintf(stderr, "  (%s: no ../shared/models)\n", runs[i].model);
            continue;
        }
        char q[300], native[64], want[96];
        snprintf(q, sizeof q, "model=%s&bare=1%s", runs[i].model, runs[i].query);
        int done = page_settled(&c, &sv, q, 120, &state) && page_drawn(&c, &state);
        const char *st = state.data ? (const char *)state.data : "";
        native_checksum(&sv, runs[i].model, runs[i].native_stop, native, sizeof native);
        snprintf(want, sizeof want, "\"checksum\":\"%s\"", native);
        CHECKF(t, done && native[0] && strstr(st, want) && strstr(st, "\"isolated\":true") &&
                      mts_test_json_long(st, "threads") == runs[i].threads &&
                      mts_test_json_long(st, "level") == mts_test_json_long(st, "stop_level"),
               "%s: mts-client says %s, on %ld threads the page %s", q, native, runs[i].threads,
               st);
        /* the pool thread grows the shared memory too: what the page's
         * thread reads of it (mts.js renews its views) draws the same */
        if (done && runs[i].threads == 2 && !runs[i].native_stop[0]) {
            char name[64];
            snprintf(name, sizeof name, "%s_threads", runs[i].model);
            double share = picture_share(&sv, &c, runs[i].model, "", name);
            CHECKF(t, share >= 0 && share <= PIXEL_SHARE, "%s: %.4f", q, share);
        }
        char ms[32];
        mts_test_json(st, "ms_final", ms, sizeof ms);
        fprintf(stderr, "  %s: %ld thread(s), level %ld at %.8s ms\n", q,
                mts_test_json_long(st, "threads"), mts_test_json_long(st, "level"), ms);
    }
    mts_buf_free(&state);
    mts_cdp_stop(&c);
    CHECK(t, server_stop(&sv) == 0);
}

/* The page's state, polled until it contains every one of `want` (NULL
 * ended), or `seconds` pass. */
static int wait_state(mts_cdp *c, const char *const *want, double seconds, mts_buf *state)
{
    double until = mts_cdp_now() + seconds;
    while (mts_cdp_now() < until) {
        if (mts_cdp_eval(c, "JSON.stringify(window.mtsState || {})", state)) {
            int all = 1;
            for (int k = 0; want[k] && all; k++)
                all = strstr((const char *)state->data, want[k]) != NULL;
            if (all)
                return 1;
        }
        mts_cdp_sleep_ms(20);
    }
    return 0;
}

/* The level slider down and up again, through geomorphs: going down the
 * level holds while the vertices slide back, then drops; going up it is
 * set at once and they slide out; the picture at the lower level is
 * mts-client's of that level. */
static void test_page_slider_morph(mts_test *t)
{
    if (!have_chromium)
        SKIP(t, "no chromium (scripts/deps.sh installs it): the page is not tested");
    server sv;
    CHECK(t, server_start(&sv, "slider", NULL));
    mts_cdp c;
    char log[700];
    int up = browser_start(&c, "slider", log, sizeof log);
    CHECKF(t, up, "chromium did not start (see %s)", log);
    char url[600];
    snprintf(url, sizeof url, "http://127.0.0.1:%d/?model=cow&bare=1&morph=1500", sv.web_port);
    mts_buf state = {0};
    const char *full[] = {"\"phase\":\"complete\"", "\"level\":2875,", "\"morphing\":false", NULL};
    CHECKF(t, up && mts_cdp_navigate(&c, url) && wait_state(&c, full, 60, &state), "%s",
           state.data ? (const char *)state.data : "");
    const char *slide_down = "(() => { document.getElementById('follow').checked = false; "
                             "const l = document.getElementById('level'); l.value = '100'; "
                             "l.dispatchEvent(new Event('input')); return 'ok'; })()";
    mts_buf ok = {0};
    CHECK(t, up && mts_cdp_eval(&c, slide_down, &ok));
    const char *sliding_down[] = {"\"morphing\":true", NULL};
    CHECK(t, up && wait_state(&c, sliding_down, 5, &state));
    CHECKF(t, up && mts_test_json_long((const char *)state.data, "level") == 2875,
           "going down, the level holds while the vertices slide back: %s",
           (const char *)state.data);
    const char *low[] = {"\"level\":100,", "\"morphing\":false", NULL};
    CHECKF(t, up && wait_state(&c, low, 10, &state), "%s", (const char *)state.data);
    double share = up ? picture_share(&sv, &c, "cow", "--level 100", "cow_slid_to_100") : -1;
    CHECKF(t, share >= 0 && share <= PIXEL_SHARE, "cow slid to 100: %.4f", share);
    const char *slide_up = "(() => { const l = document.getElementById('level'); "
                           "l.value = '2875'; l.dispatchEvent(new Event('input')); "
                           "return 'ok'; })()";
    CHECK(t, up && mts_cdp_eval(&c, slide_up, &ok));
    const char *sliding_up[] = {"\"morphing\":true", "\"level\":2875,", NULL};
    CHECKF(t, up && wait_state(&c, sliding_up, 5, &state),
           "going up, the level is set at once and the vertices slide: %s",
           (const char *)state.data);
    CHECK(t, up && wait_state(&c, full, 10, &state));
    mts_buf_free(&ok);
    mts_buf_free(&state);
    mts_cdp_stop(&c);
    CHECK(t, server_stop(&sv) == 0);
}

/* A coloured stream: the page draws its colours as mts-client does. */
static void test_page_colors(mts_test *t)
{
    if (!have_chromium)
        SKIP(t, "no chromium (scripts/deps.sh installs it): the page is not tested");
    server sv;
    CHECK(t, server_start(&sv, "colors", NULL));
    mts_cdp c;
    char log[700];
    int up = browser_start(&c, "colors", log, sizeof log);
    CHECKF(t, up, "chromium did not start (see %s)", log);
    char url[600];
    snprintf(url, sizeof url, "http://127.0.0.1:%d/?model=cow_colors&bare=1&morph=300",
             sv.web_port);
    mts_buf state = {0};
    const char *full[] = {"\"phase\":\"complete\"", "\"level\":2875,", "\"morphing\":false",
                          "\"colors\":true", NULL};
    CHECKF(t, up && mts_cdp_navigate(&c, url) && wait_state(&c, full, 60, &state), "%s",
           state.data ? (const char *)state.data : "");
    double share = up ? picture_share(&sv, &c, "cow_colors", "", "cow_colors") : -1;
    CHECKF(t, share >= 0 && share <= PIXEL_SHARE, "cow_colors: %.4f", share);
    /* against the grey: the colours are on the page, not only in the state */
    char png_web[700], png_grey[700], cmd[2000], out[4096];
    snprintf(png_web, sizeof png_web, "%s/web_cow_colors.png", tmp_dir);
    snprintf(png_grey, sizeof png_grey, "%s/native_cow_colors_grey.png", tmp_dir);
    snprintf(cmd, sizeof cmd, "%s/mts-client 127.0.0.1:%d cow_colors --no-colors --png %s --quiet",
             bin_dir, sv.port, png_grey);
    double grey = up && mts_test_run(cmd, out, sizeof out) == 0
                      ? mts_cdp_png_diff(png_web, png_grey, PIXEL_TOLERANCE)
                      : -1;
    fprintf(stderr, "  cow_colors: %.2f%% of pixels differ by more than %d from the grey\n",
            100 * grey, PIXEL_TOLERANCE);
    CHECKF(t, grey > 0.05, "the page's colours against the grey: %.4f", grey);
    /* down to level 100 through a geomorph (the from-colours too) */
    const char *slide_down = "(() => { document.getElementById('follow').checked = false; "
                             "const l = document.getElementById('level'); l.value = '100'; "
                             "l.dispatchEvent(new Event('input')); return 'ok'; })()";
    mts_buf ok = {0};
    CHECK(t, up && mts_cdp_eval(&c, slide_down, &ok));
    const char *low[] = {"\"level\":100,", "\"morphing\":false", NULL};
    CHECKF(t, up && wait_state(&c, low, 10, &state), "%s",
           state.data ? (const char *)state.data : "");
    CHECKF(t, up && !strstr((const char *)state.data, "\"phase\":\"error\""), "%s",
           (const char *)state.data);
    share = up ? picture_share(&sv, &c, "cow_colors", "--level 100", "cow_colors_100") : -1;
    CHECKF(t, share >= 0 && share <= PIXEL_SHARE, "cow_colors slid to 100: %.4f", share);
    mts_buf_free(&ok);
    mts_buf_free(&state);
    mts_cdp_stop(&c);
    CHECK(t, server_stop(&sv) == 0);
}

static void test_page_broken_connection(mts_test *t)
{
    if (!have_chromium)
        SKIP(t, "no chromium (scripts/deps.sh installs it): the page is not tested");
    if (!have_shared)
        SKIP(t, "no ../shared/models (bunny00 streams long enough to be cut)");
    server sv; /* bunny00's 150 KB at 30 KB/s: five seconds to cut it in */
    CHECK(t, server_start(&sv, "broken", "30000"));
    mts_cdp c;
    char log[700];
    int up = browser_start(&c, "broken", log, sizeof log);
    CHECKF(t, up, "chromium did not start (see %s)", log);
    char url[600];
    snprintf(url, sizeof url, "http://127.0.0.1:%d/?model=bunny00&bare=1", sv.web_port);
    mts_buf state = {0};
    if (up && mts_cdp_navigate(&c, url) && wait_phase(&c, "streaming", 30, &state)) {
        /* some levels in, then the server dies */
        double until = mts_cdp_now() + 10;
        while (mts_cdp_now() < until && mts_test_json_long((const char *)state.data, "received") <= 0) {
            mts_cdp_sleep_ms(50);
            mts_cdp_eval(&c, "JSON.stringify(window.mtsState)", &state);
        }
        kill(sv.pid, SIGKILL);
        waitpid(sv.pid, NULL, 0);
        sv.pid = 0;
        int ended = wait_phase(&c, "error complete", 20, &state);
        const char *st = (const char *)state.data;
        CHECKF(t, ended && strstr(st, "\"phase\":\"error\"") &&
                      strstr(st, "the connection closed at level"),
               "%s", st);
        /* the error is on the page, for the user */
        mts_buf shown = {0};
        CHECK(t, mts_cdp_eval(&c, "document.getElementById('error').hidden ? '' : "
                                  "document.getElementById('error').textContent",
                              &shown) &&
                     strstr((const char *)shown.data, "closed"));
        mts_buf_free(&shown);
    } else {
        CHECKF(t, 0, "the page did not start streaming: %s",
               state.data ? (const char *)state.data : "");
    }
    mts_buf_free(&state);
    mts_cdp_stop(&c);
    server_stop(&sv);
}

/* ---- stream files (?src=) ------------------------------------------------- */

/* A web server the page may read from (CORS) that answers wrongly, by path:
 * /whole.mts a 200 with all of cow.mts whatever the range, /wrongrange.mts
 * a 206 for other bytes than those asked for. One process per connection:
 * Chromium opens connections it may never use. */
static void hostile_serve(int lfd, const uint8_t *file, size_t size)
{
    signal(SIGCHLD, SIG_IGN);
    for (;;) {
        int fd = accept(lfd, NULL, NULL);
        if (fd < 0)
            continue;
        pid_t pid = fork();
        if (pid != 0) {
            close(fd);
            continue;
        }
        char req[4096];
        mts_test_read_request(fd, req, sizeof req);
        unsigned long a = 0, b = size - 1;
        const char *rg = strstr(req, "ange: bytes=");
        if (rg)
            sscanf(rg + 12, "%lu-%lu", &a, &b);
        if (b >= size)
            b = size - 1;
        const char *cors = "Access-Control-Allow-Origin: *\r\n"
                           "Access-Control-Expose-Headers: Content-Range, Content-Length\r\n";
        char head[1024];
        int hn;
        const uint8_t *body = file;
        size_t body_size = 0;
        if (strncmp(req, "OPTIONS ", 8) == 0) {
            hn = snprintf(head, sizeof head,
                          "HTTP/1.1 204 No Content\r\n%sAccess-Control-Allow-Methods: GET\r\n"
                          "Access-Control-Allow-Headers: Range\r\nConnection: close\r\n\r\n",
                          cors);
        } else if (strstr(req, "GET /whole")) {
            body_size = size;
            hn = snprintf(head, sizeof head,
                          "HTTP/1.1 200 OK\r\n%sContent-Length: %zu\r\nConnection: close\r\n\r\n",
                          cors, size);
        } else {
            unsigned long from = a + 7 <= b ? a + 7 : a;
            body = file + from;
            body_size = b - from + 1;
            hn = snprintf(head, sizeof head,
                          "HTTP/1.1 206 Partial Content\r\n%sContent-Range: bytes %lu-%lu/%zu\r\n"
                          "Content-Length: %zu\r\nConnection: close\r\n\r\n",
                          cors, from, b, size, body_size);
        }
        if (write(fd, head, (size_t)hn) == hn) {
            for (size_t at = 0; at < body_size;) {
                ssize_t w = write(fd, body + at, body_size - at);
                if (w <= 0)
                    break;
                at += (size_t)w;
            }
        }
        shutdown(fd, SHUT_WR);
        char drain[256];
        while (read(fd, drain, sizeof drain) > 0) {
        }
        _exit(0);
    }
}

/* The page at page_query (after "?"), run until it completes or fails and,
 * once complete, until the end is drawn (level at the stop, no geomorph
 * under way); its state into state. 1 when it completed. */
static int page_settled(mts_cdp *c, const server *sv, const char *page_query, double seconds,
                        mts_buf *state)
{
    char url[900];
    snprintf(url, sizeof url, "http://127.0.0.1:%d/?%.800s", sv->web_port, page_query);
    if (!mts_cdp_navigate(c, url))
        return 0;
    return wait_phase(c, "complete error", seconds, state) &&
           strstr((const char *)state->data, "\"phase\":\"complete\"");
}

/* After a stream completed: waits for its end to be drawn. */
static int page_drawn(mts_cdp *c, mts_buf *state)
{
    double until = mts_cdp_now() + 20;
    while (mts_cdp_now() < until) {
        const char *st = (const char *)state->data;
        if (mts_test_json_long(st, "level") == mts_test_json_long(st, "stop_level") &&
            strstr(st, "\"morphing\":false"))
            return 1;
        mts_cdp_sleep_ms(50);
        mts_cdp_eval(c, "JSON.stringify(window.mtsState)", state);
    }
    return 0;
}

/* The page's state ends at mts-client's level and checksum for the stop. */
static int same_as_native(const server *sv, const char *model, const char *stop, long level,
                          const char *st)
{
    char native[64], want[96];
    native_checksum(sv, model, stop, native, sizeof native);
    snprintf(want, sizeof want, "\"checksum\":\"%s\"", native);
    return native[0] && strstr(st, want) && mts_test_json_long(st, "level") == level &&
           mts_test_json_long(st, "stop_level") == level;
}

static void test_page_stream_file(mts_test *t)
{
    if (!have_chromium)
        SKIP(t, "no chromium (scripts/deps.sh installs it): the page is not tested");
    char out[8192], found[512];
    const char *missing = mts_test_tls_front_missing(found, sizeof found);
    if (missing) {
        if (getenv("MTS_TEST_REQUIRE_WEB"))
            CHECKF(t, 0, "%s (scripts/deps.sh installs it)", missing);
        else
            SKIP(t, "%s: docker/nginx-tls.conf does not run", missing);
        return;
    }
    server sv;
    CHECK(t, server_start(&sv, "file", NULL));
    /* the stream files' own origin, over https with a throwaway CA */
    mts_test_tls_front front;
    memset(&front, 0, sizeof front);
    snprintf(front.dir, sizeof front.dir, "%s/web_tls", tmp_dir);
    snprintf(front.root, sizeof front.root, "%s", www_dir);
    snprintf(front.nginx, sizeof front.nginx, "%s", nginx);
    front.ws_upstream = sv.ws_port;
    front.tcp_upstream = sv.port;
    front.limit_rate = "set $r 0; if ($arg_rate) { set $r $arg_rate; } limit_rate $r;";
    CHECKF(t, mts_test_tls_front_ca(&front, out, sizeof out), "openssl: %s", out);
    CHECKF(t, mts_test_tls_front_start(&front) > 0, "nginx did not start (%s/nginx.log)",
           front.dir);
    /* Chromium trusts the server's key, by its SPKI's SHA-256, and nothing else */
    char cmd[2000], spki[200], spki_arg[300];
    snprintf(cmd, sizeof cmd,
             "openssl x509 -in %s/cert.pem -pubkey -noout | openssl pkey -pubin -outform der | "
             "openssl dgst -sha256 -binary | base64",
             front.dir);
    CHECK(t, mts_test_run(cmd, spki, sizeof spki) == 0 && spki[0]);
    spki[strcspn(spki, "\n")] = 0;
    snprintf(spki_arg, sizeof spki_arg, "--ignore-certificate-errors-spki-list=%s", spki);
    /* the damaged copy: a byte of the last batches flipped */
    char path[800];
    snprintf(path, sizeof path, "%s/cow.mts", www_dir);
    static uint8_t file[1 << 20];
    FILE *f = fopen(path, "rb");
    size_t size = f ? fread(file, 1, sizeof file, f) : 0;
    if (f)
        fclose(f);
    CHECK(t, size > 400);
    snprintf(path, sizeof path, "%s/damaged.mts", www_dir);
    f = fopen(path, "wb");
    file[size - 300] ^= 0x55;
    CHECK(t, f && fwrite(file, 1, size, f) == size && fclose(f) == 0);
    file[size - 300] ^= 0x55;
    int hport;
    int lfd = mts_test_listen_any(&hport);
    CHECK(t, lfd >= 0);
    if (t->case_failed) {
        mts_test_tls_front_stop(&front, 0);
        server_stop(&sv);
        return;
    }
    pid_t hostile = fork();
    if (hostile == 0) {
        prctl(PR_SET_PDEATHSIG, SIGKILL);
        hostile_serve(lfd, file, size);
        _exit(0);
    }
    close(lfd);

    mts_cdp c;
    char log[700];
    const char *extra[] = {spki_arg, NULL};
    snprintf(log, sizeof log, "%s/web_chromium_file.log", tmp_dir);
    int up = mts_cdp_start_with(&c, tmp_dir, log, 512, 512, 30, extra);
    CHECKF(t, up, "chromium did not start (see %s)", log);
    char https[100], q[700];
    snprintf(https, sizeof https, "https://127.0.0.1:%d", front.https_port);
    mts_buf state = {0}, ok = {0};
    const char *st = "";

    /* the full level, cross-origin over https; its picture is mts-client's */
    snprintf(q, sizeof q, "src=%s/cow.mts&bare=1", https);
    int done = up && page_settled(&c, &sv, q, 60, &state) && page_drawn(&c, &state);
    st = state.data ? (const char *)state.data : "";
    CHECKF(t, done && same_as_native(&sv, "cow", "", 2875, st), "cow full: %s", st);
    double share = done ? picture_share(&sv, &c, "cow", "", "cow_file") : -1;
    CHECKF(t, share >= 0 && share <= PIXEL_SHARE, "cow from the file: %.4f", share);
    long full_bytes = mts_test_json_long(st, "bytes");
    CHECKF(t, full_bytes > 0 && (size_t)full_bytes <= size, "cow full: %ld bytes of %zu",
           full_bytes, size);

    /* a low stop, and a stop inside a batch continued to a higher one:
     * the continuation is one request, from the first batch not held */
    snprintf(q, sizeof q, "src=%s/cow.mts&bare=1&level=10", https);
    done = up && page_settled(&c, &sv, q, 60, &state) && page_drawn(&c, &state);
    st = state.data ? (const char *)state.data : "";
    CHECKF(t, done && same_as_native(&sv, "cow", "--level 10", 10, st), "cow to 10: %s", st);
    snprintf(q, sizeof q, "src=%s/cow.mts&bare=1&level=1000", https);
    done = up && page_settled(&c, &sv, q, 60, &state) && page_drawn(&c, &state);
    st = state.data ? (const char *)state.data : "";
    CHECKF(t, done && same_as_native(&sv, "cow", "--level 1000", 1000, st), "cow to 1000: %s",
           st);
    long bytes_1000 = mts_test_json_long(st, "bytes"), requests = mts_test_json_long(st, "requests");
    const char *more = "(() => { document.getElementById('stop').value = '2000'; "
                       "document.getElementById('more').click(); return 'ok'; })()";
    const char *at_2000[] = {"\"phase\":\"complete\"", "\"level\":2000,", "\"morphing\":false",
                             NULL};
    done = done && mts_cdp_eval(&c, more, &ok) && wait_state(&c, at_2000, 30, &state);
    st = state.data ? (const char *)state.data : "";
    CHECKF(t, done && same_as_native(&sv, "cow", "--level 2000", 2000, st) &&
                  mts_test_json_long(st, "requests") == requests + 1 &&
                  mts_test_json_long(st, "first_batch") > 0 &&
                  mts_test_json_long(st, "bytes") + bytes_1000 < full_bytes * 2,
           "cow continued from 1000 (%ld bytes, %ld requests) to 2000: %s", bytes_1000,
           requests, st);
    fprintf(stderr, "  cow from the file: %ld bytes to the full level; %ld to level 1000, "
                    "%ld more to 2000\n",
            full_bytes, bytes_1000, mts_test_json_long(st, "bytes") - bytes_1000);

    /* bunny00 over the file and over the WebSocket: the same end */
    if (have_shared) {
        /* the page is cross-origin isolated (web/nginx.conf's COEP): the
         * file of another origin still comes, by its CORS headers, and
         * the threaded decoder reads it */
        snprintf(q, sizeof q, "src=%s/bunny00.mts&bare=1&threads=2", https);
        done = up && page_settled(&c, &sv, q, 120, &state) && page_drawn(&c, &state);
        st = state.data ? (const char *)state.data : "";
        long levels = mts_test_json_long(st, "levels");
        CHECKF(t, done && levels > 0 && same_as_native(&sv, "bunny00", "", levels, st) &&
                      strstr(st, "\"isolated\":true") &&
                      mts_test_json_long(st, "threads") == (have_mt ? 2 : 1),
               "bunny00 full: %s", st);
        long file_bytes = mts_test_json_long(st, "bytes");
        char file_ms[32], ws_ms[32];
        mts_test_json(st, "ms_final", file_ms, sizeof file_ms);
        done = up && page_settled(&c, &sv, "model=bunny00&bare=1", 120, &state);
        st = state.data ? (const char *)state.data : "";
        mts_test_json(st, "ms_final", ws_ms, sizeof ws_ms);
        fprintf(stderr, "  bunny00 to the full level: %ld bytes in %s ms from the file over "
                        "https; %ld bytes in %s ms over the WebSocket\n",
                file_bytes, file_ms, mts_test_json_long(st, "bytes"), ws_ms);
    }

    /* the page itself from the same nginx over https, reading the file
     * beside it (same origin, a relative src): what a deployment of
     * docker/nginx-tls.conf serves */
    {
        const char *same = have_shared ? "bunny00" : "cow";
        snprintf(cmd, sizeof cmd, "cp -r %s/. %s/", web_dir, www_dir);
        CHECK(t, mts_test_run(cmd, out, sizeof out) == 0);
        char page[300];
        /* no COOP/COEP there: not isolated, so ?threads=2 runs one */
        snprintf(page, sizeof page, "%s/?src=%s.mts&bare=1&threads=2", https, same);
        done = up && mts_cdp_navigate(&c, page) &&
               wait_phase(&c, "complete error", 120, &state) &&
               strstr((const char *)state.data, "\"phase\":\"complete\"") &&
               page_drawn(&c, &state);
        st = state.data ? (const char *)state.data : "";
        long levels = mts_test_json_long(st, "levels");
        CHECKF(t, done && levels > 0 && same_as_native(&sv, same, "", levels, st) &&
                      strstr(st, "\"isolated\":false") && mts_test_json_long(st, "threads") == 1,
               "the page over https, %s beside it: %s", same, st);
    }

    /* nginx killed mid-transfer and started again: the page asks for the
     * batches it does not hold, and ends where TCP does */
    const char *model = have_shared ? "bunny00" : "cow";
    snprintf(q, sizeof q, "src=%s/%s.mts%%3Frate%%3D%s&bare=1", https, model,
             have_shared ? "100k" : "10k");
    char url[900];
    snprintf(url, sizeof url, "http://127.0.0.1:%d/?%s", sv.web_port, q);
    const char *streaming[] = {"\"phase\":\"streaming\"", "\"batches\":", NULL};
    done = up && mts_cdp_navigate(&c, url) && wait_state(&c, streaming, 30, &state);
    double until = mts_cdp_now() + 10;
    while (done && mts_cdp_now() < until &&
           mts_test_json_long((const char *)state.data, "batches") < 2) {
        mts_cdp_sleep_ms(20);
        mts_cdp_eval(&c, "JSON.stringify(window.mtsState)", &state);
    }
    long held = done ? mts_test_json_long((const char *)state.data, "batches") : -1;
    mts_test_tls_front_stop(&front, 1); /* as a crash: every connection cut at once */
    mts_cdp_sleep_ms(600);
    CHECK(t, mts_test_tls_front_start(&front) > 0);
    done = done && wait_phase(&c, "complete error", 60, &state) && page_drawn(&c, &state);
    st = state.data ? (const char *)state.data : "";
    long levels = mts_test_json_long(st, "levels");
    CHECKF(t, done && held >= 2 && levels > 0 && same_as_native(&sv, model, "", levels, st) &&
                  mts_test_json_long(st, "reconnects") >= 1 &&
                  mts_test_json_long(st, "first_batch") >= held,
           "%s resumed after nginx restarted (%ld batches held at the cut): %s", model, held, st);
    fprintf(stderr, "  %s resumed from batch %ld after %ld failed tries: %ld bytes in all\n", model,
            mts_test_json_long(st, "first_batch"), mts_test_json_long(st, "reconnects"),
            mts_test_json_long(st, "bytes"));

    /* the file rebuilt while the page was cut off: its resume asks with
     * If-Range and is refused by name, never fed bytes of two files */
    snprintf(cmd, sizeof cmd, "cp %s/cow.mts %s/changing.mts", www_dir, www_dir);
    CHECK(t, mts_test_run(cmd, out, sizeof out) == 0);
    snprintf(url, sizeof url, "http://127.0.0.1:%d/?src=%s/changing.mts%%3Frate%%3D4k&bare=1",
             sv.web_port, https);
    done = up && mts_cdp_navigate(&c, url) && wait_state(&c, streaming, 30, &state);
    until = mts_cdp_now() + 10;
    while (done && mts_cdp_now() < until &&
           mts_test_json_long((const char *)state.data, "batches") < 2) {
        mts_cdp_sleep_ms(20);
        mts_cdp_eval(&c, "JSON.stringify(window.mtsState)", &state);
    }
    mts_test_tls_front_stop(&front, 1);
    snprintf(cmd, sizeof cmd,
             "f=%s/changing.mts; printf 'XXXX' | dd of=$f bs=1 seek=$(($(stat -c %%s $f) - 100)) "
             "conv=notrunc 2>/dev/null && touch -d '+1 minute' $f",
             www_dir);
    CHECK(t, mts_test_run(cmd, out, sizeof out) == 0);
    CHECK(t, mts_test_tls_front_start(&front) > 0);
    done = done && wait_phase(&c, "complete error", 60, &state);
    st = state.data ? (const char *)state.data : "";
    CHECKF(t, done && strstr(st, "\"phase\":\"error\"") && strstr(st, "changed on the server"),
           "a file rebuilt during a cut: %s", st);

    /* a server that ignores Range: used, cut to the range */
    snprintf(q, sizeof q, "src=http://127.0.0.1:%d/whole.mts&bare=1&level=1000", hport);
    done = up && page_settled(&c, &sv, q, 60, &state) && page_drawn(&c, &state);
    st = state.data ? (const char *)state.data : "";
    CHECKF(t, done && same_as_native(&sv, "cow", "--level 1000", 1000, st),
           "a server that ignores Range: %s", st);

    /* errors, by name, on the page */
    struct {
        const char *src, *says;
    } bad[] = {
        {"http://127.0.0.1:%d/wrongrange.mts", "Content-Range"},
        {"https://127.0.0.1:%d/nothing.mts", "404"},
        {"https://127.0.0.1:%d/damaged.mts", "checksum"},
    };
    for (size_t i = 0; up && i < sizeof bad / sizeof bad[0]; i++) {
        char s[300];
        snprintf(s, sizeof s, bad[i].src, i == 0 ? hport : front.https_port);
        snprintf(q, sizeof q, "src=%s&bare=1", s);
        done = page_settled(&c, &sv, q, 30, &state);
        st = state.data ? (const char *)state.data : "";
        mts_buf shown = {0};
        int on_page = mts_cdp_eval(&c, "document.getElementById('error').hidden ? '' : "
                                       "document.getElementById('error').textContent",
                                   &shown) &&
                      shown.data && strstr((const char *)shown.data, bad[i].says);
        CHECKF(t, !done && strstr(st, "\"phase\":\"error\"") && on_page, "%s: %s (shown: %s)", s,
               st, shown.data ? (const char *)shown.data : "");
        fprintf(stderr, "  %s: %s\n", s, shown.data ? (const char *)shown.data : "");
        mts_buf_free(&shown);
    }
    mts_buf_free(&ok);
    mts_buf_free(&state);
    mts_cdp_stop(&c);
    kill(hostile, SIGKILL);
    waitpid(hostile, NULL, 0);
    mts_test_tls_front_stop(&front, 0);
    CHECK(t, server_stop(&sv) == 0);
}

static int have(const char *cmd)
{
    char out[256];
    return mts_test_run(cmd, out, sizeof out) == 0;
}

int main(int argc, char **argv)
{
    (void)argc;
    signal(SIGPIPE, SIG_IGN);
    alarm(600); /* a browser that stops answering ends the test, not the run */
    mts_test_bin_dir(argv[0], bin_dir, sizeof bin_dir);
    snprintf(tmp_dir, sizeof tmp_dir, "%s", mts_test_tmpdir());
    snprintf(models_dir, sizeof models_dir, "%s/web_models", tmp_dir);
    snprintf(www_dir, sizeof www_dir, "%s/web_www", tmp_dir);
    const char *wd = getenv("MTS_WEB_DIR");
    /* nginx's root: an absolute path (a relative one is nginx's prefix's) */
    char real[PATH_MAX];
    snprintf(web_dir, sizeof web_dir, "%.590s",
             realpath(wd && *wd ? wd : "build/web", real) ? real : wd && *wd ? wd : "build/web");
    mts_test t = {0};
    char path[700];
    snprintf(path, sizeof path, "%s/mts_web.js", web_dir);
    struct stat st;
    /* CI installs emscripten and chromium (deps.sh) and sets
     * MTS_TEST_REQUIRE_WEB: there a skip is a failure */
    int required = getenv("MTS_TEST_REQUIRE_WEB") != NULL;
    if (stat(path, &st) != 0) {
        printf("  %s: no %s: `make web` builds the browser client (needs emscripten; "
               "scripts/deps.sh installs it)\n",
               required ? "FAIL" : "SKIP", path);
        if (required)
            t.failed = 1;
        else
            t.skipped = 8;
        return mts_test_end(&t);
    }
    snprintf(path, sizeof path, "%s/mts_web_mt.js", web_dir);
    have_mt = stat(path, &st) == 0;
    have_node = have("node --version");
    have_chromium = have("chromium --version");
    int have_nginx = mts_test_find_nginx(nginx, sizeof nginx) != NULL;
    if (required && (!have_node || !have_chromium || !have_nginx)) {
        printf("  FAIL: MTS_TEST_REQUIRE_WEB is set, and there is no %s\n",
               !have_node ? "node" : !have_chromium ? "chromium" : "nginx");
        t.failed = 1;
        return mts_test_end(&t);
    }
    if (!have_nginx) {
        printf("  SKIP: no nginx (scripts/deps.sh installs it): it serves the page\n");
        t.skipped = 8;
        return mts_test_end(&t);
    }
    char m[600];
    have_shared = mts_test_model("bunny00.off", m, sizeof m) != NULL &&
                  mts_test_model("fandisk_large.off", m, sizeof m) != NULL;
    /* the models, built once */
    char cmd[6000], out[8192];
    snprintf(cmd, sizeof cmd,
             "mkdir -p %s %s && %s/mts-build tests/data/cow.off -o %s/cow.mtsm --stream "
             "%s/cow.mts --quiet && %s/mts-build tests/data/cow_colors.ply -o "
             "%s/cow_colors.mtsm --quiet",
             models_dir, www_dir, bin_dir, models_dir, www_dir, bin_dir, models_dir);
    if (mts_test_run(cmd, out, sizeof out) != 0) {
        fprintf(stderr, "cannot build cow: %s\n", out);
        return 1;
    }
    if (have_shared) {
        char bunny[600], fandisk[600];
        mts_test_model("bunny00.off", bunny, sizeof bunny);
        mts_test_model("fandisk_large.off", fandisk, sizeof fandisk);
        snprintf(cmd, sizeof cmd,
                 "%s/mts-build %s -o %s/bunny00.mtsm --stream %s/bunny00.mts --quiet && "
                 "%s/mts-build %s -o %s/fandisk_large.mtsm --quiet",
                 bin_dir, bunny, models_dir, www_dir, bin_dir, fandisk, models_dir);
        if (mts_test_run(cmd, out, sizeof out) != 0) {
            fprintf(stderr, "cannot build the shared models: %s\n", out);
            return 1;
        }
    }
    RUN(&t, test_page_folder);
    RUN(&t, test_node_decoder);
    RUN(&t, test_page);
    RUN(&t, test_page_threads);
    RUN(&t, test_page_slider_morph);
    RUN(&t, test_page_colors);
    RUN(&t, test_page_broken_connection);
    RUN(&t, test_page_stream_file);
    return mts_test_end(&t);
}
