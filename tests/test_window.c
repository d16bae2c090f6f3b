/* mts-client --window under Xvfb, driven by --script:
 *   - screenshots at three levels (Home, three batches up, End) exist, are
 *     not blank, and differ pairwise;
 *   - the HUD's figures for each screenshot (the --json "screenshots" array
 *     carries the HUD text of the frame it was taken from) agree with the
 *     level and triangles reported for it, and the last one -- End, the full
 *     stream -- with the client's own "level" and "triangles";
 *   - --json counts the frames shown while the stream came, and its seconds;
 *   - geomorphs: a shot mid-morph is named so and its HUD says morphing;
 *   - a model with vertex colours (tests/data/cow_colors.ply) is drawn in
 *     them, mid-morph too: --json says colors, the shots are saturated
 *     where the grey cow's are not;
 *   - more on demand: with --lod-policy distance the stream stops at the
 *     policy's level, zooming in continues it, and the end is an unbroken
 *     stream's checksum;
 *   - a malformed script line is refused with the file and line named.
 * Skips with the reason when Xvfb is not installed, unless
 * MTS_TEST_REQUIRE_EGL is set (CI: deps.sh installs it). */
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <png.h>
#include <stdint.h>
#include <stdlib.h>

#include "test.h"
#include "test_proc.h"

static char bin_dir[512], tmp_dir[600];

static int have_program(const char *name)
{
    char cmd[300], out[512];
    snprintf(cmd, sizeof cmd, "command -v %s", name);
    return mts_test_run(cmd, out, sizeof out) == 0;
}

/* An Xvfb on a display number nobody uses; 0 when it did not come up. */
static pid_t start_xvfb(int *display, const char *log)
{
    for (int n = 90 + (int)(getpid() % 400), tries = 0; tries < 50; n++, tries++) {
        char lock[64], sock[64];
        snprintf(lock, sizeof lock, "/tmp/.X%d-lock", n);
        snprintf(sock, sizeof sock, "/tmp/.X11-unix/X%d", n);
        if (access(lock, F_OK) == 0 || access(sock, F_OK) == 0)
            continue;
        char disp[16];
        snprintf(disp, sizeof disp, ":%d", n);
        char *argv[] = {"Xvfb", disp, "-screen", "0", "1024x768x24", "-nolisten", "tcp", NULL};
        pid_t pid = mts_test_spawn(argv, log);
        for (int i = 0; i < 100; i++) { /* up to 10 s for its socket */
            if (access(sock, F_OK) == 0) {
                *display = n;
                return pid;
            }
            int st;
            if (waitpid(pid, &st, WNOHANG) == pid)
                break; /* it died: the number was taken after all */
            struct timespec ts = {0, 100 * 1000 * 1000};
            nanosleep(&ts, NULL);
        }
        mts_test_stop(pid);
    }
    return 0;
}

/* Pixels that differ from the corner pixel (the background); -1 when the
 * file is not a PNG. */
static long foreground_pixels(const char *path)
{
    png_image im;
    memset(&im, 0, sizeof im);
    im.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&im, path))
        return -1;
    im.format = PNG_FORMAT_RGBA;
    size_t n = PNG_IMAGE_SIZE(im);
    uint8_t *px = malloc(n);
    if (!px || !png_image_finish_read(&im, NULL, px, 0, NULL)) {
        free(px);
        png_image_free(&im);
        return -1;
    }
    long fg = 0;
    for (size_t i = 0; i < n; i += 4)
        if (abs(px[i] - px[0]) + abs(px[i + 1] - px[1]) + abs(px[i + 2] - px[2]) > 24)
            fg++;
    free(px);
    return fg;
}

/* Pixels whose channels span more than 40 (the grey spans 23 at full light). */
static long saturated_pixels(const char *path)
{
    png_image im;
    memset(&im, 0, sizeof im);
    im.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&im, path))
        return -1;
    im.format = PNG_FORMAT_RGBA;
    size_t n = PNG_IMAGE_SIZE(im);
    uint8_t *px = malloc(n);
    if (!px || !png_image_finish_read(&im, NULL, px, 0, NULL)) {
        free(px);
        png_image_free(&im);
        return -1;
    }
    long sat = 0;
    for (size_t i = 0; i < n; i += 4) {
        int mx = px[i], mn = px[i];
        for (int c = 1; c < 3; c++) {
            mx = px[i + c] > mx ? px[i + c] : mx;
            mn = px[i + c] < mn ? px[i + c] : mn;
        }
        sat += mx - mn > 40;
    }
    free(px);
    return sat;
}

static int read_whole(const char *path, unsigned char **data, long *size)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return 0;
    fseek(f, 0, SEEK_END);
    *size = ftell(f);
    fseek(f, 0, SEEK_SET);
    *data = malloc((size_t)(*size > 0 ? *size : 1));
    int ok = *data && fread(*data, 1, (size_t)*size, f) == (size_t)*size;
    fclose(f);
    return ok;
}

/* Copies the string value of "key" in s (escapes kept as written). */
static void json_s(const char *s, const char *key, char *out, size_t size)
{
    char k[64];
    snprintf(k, sizeof k, "\"%s\":\"", key);
    out[0] = 0;
    const char *p = strstr(s, k);
    if (!p)
        return;
    p += strlen(k);
    size_t i = 0;
    while (*p && i + 1 < size && !(*p == '"' && p[-1] != '\\'))
        out[i++] = *p++;
    out[i] = 0;
}

/* The --json screenshot entries in out, up to max of them into e: how many. */
static int screenshots(const char *out, const char **e, int max)
{
    int n = 0;
    for (const char *p = out; n < max && (p = strstr(p, "{\"file\":")) != NULL; p++)
        e[n++] = p;
    return n;
}

/* Where the windowed client runs: its folder (screenshots land there), the
 * Xvfb display and where the stream comes from ("HOST:PORT cow", or a
 * stream file's URL). */
typedef struct window_env {
    const char *dir, *source;
    int display;
} window_env;

/* Runs the windowed client with `lines` as its script (dir/name.txt), stderr
 * in dir/name.log and `opts` added; its exit status, its output in out. */
static int run_window(mts_test *t, const window_env *w, const char *name, const char *lines,
                      const char *opts, char *out, size_t size)
{
    char script[800], cmd[8192];
    snprintf(script, sizeof script, "%s/%s.txt", w->dir, name);
    FILE *f = fopen(script, "w");
    CHECK(t, f != NULL);
    if (f) {
        fputs(lines, f);
        fclose(f);
    }
    /* detect_leaks=0: llvmpipe's threads upset LeakSanitizer (see test_e2e) */
    snprintf(cmd, sizeof cmd,
             "cd %s && DISPLAY=:%d ASAN_OPTIONS=detect_leaks=0 timeout 120 %s/mts-client %s "
             "--window --size 640x480 --script %s --json %s 2>%s.log",
             w->dir, w->display, bin_dir, w->source, script, opts, name);
    return mts_test_run(cmd, out, size);
}

/* run_window, which must complete with two screenshots (into e): 1 when
 * it did. */
static int run_window_two_shots(mts_test *t, const window_env *w, const char *name,
                                const char *lines, const char *opts, char *out, size_t size,
                                const char **e)
{
    int rc = run_window(t, w, name, lines, opts, out, size);
    CHECKF(t, rc == 0 && strstr(out, "\"complete\":true"), "exit %d: %s", rc, out);
    int n = screenshots(out, e, 2);
    CHECKF(t, n == 2, "two screenshots wanted: %s", out);
    return n == 2;
}

static void test_window_screenshots(mts_test *t)
{
    if (!have_program("Xvfb")) {
        CHECKF(t, !getenv("MTS_TEST_REQUIRE_EGL"),
               "Xvfb is not installed (scripts/deps.sh installs xvfb)");
        SKIP(t, "Xvfb is not installed (Debian: xvfb)");
    }
    char dir[700], cmd[8192], out[16384], log[800];
    snprintf(dir, sizeof dir, "%s/window_%d", tmp_dir, (int)getpid());
    snprintf(cmd, sizeof cmd,
             "rm -rf %s && mkdir -p %s/models && cp tests/data/cow.off tests/data/cow_colors.ply "
             "%s/models/",
             dir, dir, dir);
    CHECK(t, mts_test_run(cmd, out, sizeof out) == 0);

    int display = 0;
    snprintf(log, sizeof log, "%s/xvfb.log", dir);
    pid_t xpid = start_xvfb(&display, log);
    CHECKF(t, xpid > 0, "Xvfb did not start (log %s)", log);
    if (xpid <= 0)
        return;

    int port = mts_test_free_port();
    char listen[64], server_bin[600], models[800], slog[800];
    snprintf(listen, sizeof listen, "127.0.0.1:%d", port);
    snprintf(server_bin, sizeof server_bin, "%s/mts-server", bin_dir);
    snprintf(models, sizeof models, "%s/models", dir);
    snprintf(slog, sizeof slog, "%s/server.log", dir);
    char *sargv[] = {server_bin, "--models", models, "--listen", listen, "--quiet", NULL};
    pid_t spid = mts_test_spawn(sargv, slog);
    /* the server builds cow first (slow under ASan): wait until it lists it */
    CHECKF(t, mts_test_wait_models(bin_dir, listen, "cow", 300, out, sizeof out),
           "server did not come up: %s", out);

    /* times count from the first frame of the model; by 1.5 s a loopback
     * stream of cow has long ended, so End is the full level */
    char source[100];
    snprintf(source, sizeof source, "%s cow", listen);
    const window_env w = {dir, source, display};
    int rc = run_window(t, &w, "client",
                        "# three levels, the keys between them\n"
                        "0.2 key Home\n"
                        "0.4 key s\n"
                        "0.5 key +\n0.6 key +\n0.7 key +\n"
                        "0.8 key PgUp\n0.9 key PgDn\n"
                        "1.0 key s\n"
                        "1.1 key w\n1.2 key c\n1.3 key w\n1.3 key c\n"
                        "1.5 key End\n"
                        "1.6 drag 40 -10\n"
                        "1.7 scroll -2\n"
                        "2.0 key s\n"
                        "2.3 key q\n",
                        "--morph-ms 0", out, sizeof out);

    /* geomorphs (the window's default, here 400 ms): End from the base
     * starts a morph to the full level; a shot 0.1 s into it is a frame
     * between the levels, named so, and the HUD says it is morphing */
    char mout[8192];
    const char *m[2];
    if (run_window_two_shots(t, &w, "morph",
                             "0.5 key Home\n1.2 key End\n1.3 key s\n2.0 key s\n2.2 key q\n",
                             "--morph-ms 400", mout, sizeof mout, m)) {
        const char *m1 = m[0], *m2 = m[1];
        char file1[300], hud1[1024], file2[300], hud2[1024];
        json_s(m1, "file", file1, sizeof file1);
        json_s(m1, "hud", hud1, sizeof hud1);
        json_s(m2, "file", file2, sizeof file2);
        json_s(m2, "hud", hud2, sizeof hud2);
        CHECKF(t, strstr(file1, "_morph") && strstr(hud1, "morphing 400 ms"),
               "the shot 0.1 s after End: %s, HUD '%s'", file1, hud1);
        CHECKF(t, !strstr(file2, "_morph") && strstr(hud2, "morph 400 ms") &&
                      !strstr(hud2, "morphing"),
               "the shot after the morph: %s, HUD '%s'", file2, hud2);
        CHECKF(t, mts_test_json_long(m1, "level") == mts_test_json_long(m2, "level") &&
                      mts_test_json_long(m2, "level") == mts_test_json_long(mout, "levels"),
               "a morph up shows the level it goes to: %s", mout);
        char p1[1100], p2[1100];
        unsigned char *d1 = NULL, *d2 = NULL;
        long s1 = 0, s2 = 0;
        snprintf(p1, sizeof p1, "%s/%s", dir, file1);
        snprintf(p2, sizeof p2, "%s/%s", dir, file2);
        CHECKF(t, read_whole(p1, &d1, &s1) && read_whole(p2, &d2, &s2), "%s or %s missing", p1,
               p2);
        CHECKF(t, !(d1 && d2 && s1 == s2 && !memcmp(d1, d2, (size_t)s1)),
               "the mid-morph frame is the final frame");
        free(d1);
        free(d2);
    }

    /* vertex colours, in the window and through its geomorphs: the same
     * morph of the coloured cow; its shots are mostly saturated, where the
     * grey cow's above have none */
    char csource[100], cout[8192];
    CHECKF(t, mts_test_wait_models(bin_dir, listen, "cow_colors", 300, cout, sizeof cout),
           "the server does not list cow_colors: %s", cout);
    snprintf(csource, sizeof csource, "%s cow_colors", listen);
    const window_env wc = {dir, csource, display};
    const char *cs[2];
    if (run_window_two_shots(t, &wc, "colors",
                             "0.5 key Home\n1.2 key End\n1.3 key s\n2.0 key s\n2.2 key q\n",
                             "--morph-ms 400", cout, sizeof cout, cs)) {
        CHECKF(t, strstr(cout, "\"colors\":true") != NULL, "%s", cout);
        CHECKF(t, strstr(mout, "\"colors\":false") != NULL, "the grey cow: %s", mout);
        char m1[300];
        json_s(m[0], "file", m1, sizeof m1);
        for (int i = 0; i < 2; i++) {
            char file[300], path[1100], grey[1100];
            json_s(cs[i], "file", file, sizeof file);
            snprintf(path, sizeof path, "%s/%s", dir, file);
            snprintf(grey, sizeof grey, "%s/%s", dir, m1);
            long fg = foreground_pixels(path), sat = saturated_pixels(path),
                 grey_sat = saturated_pixels(grey);
            fprintf(stderr, "  window, cow_colors %s: %ld of %ld pixels saturated (grey mid-morph: "
                            "%ld)\n", file, sat, fg, grey_sat);
            CHECKF(t, fg > 640 * 480 / 50 && sat > fg / 3 && grey_sat >= 0 && grey_sat < fg / 100,
                   "%s: %ld of %ld saturated, the grey %ld", file, sat, fg, grey_sat);
        }
    }

    /* more on demand: the distance policy asks for its level's stop, and
     * zooming in continues the stream from the batches held; the end is the
     * checksum of an unbroken stream to the level reached */
    char zout[8192], ref[4096];
    const char *z[2];
    int zshots = run_window_two_shots(t, &w, "zoom",
                                      "0.8 key s\n1.0 scroll 8\n2.5 key s\n2.8 key q\n",
                                      "--lod-policy distance --distance 4", zout, sizeof zout, z);
    long zl = mts_test_json_long(zout, "level");
    if (zshots) {
        const char *z1 = z[0], *z2 = z[1];
        char hud1[1024];
        json_s(z1, "hud", hud1, sizeof hud1);
        long l1 = mts_test_json_long(z1, "level"), l2 = mts_test_json_long(z2, "level");
        CHECKF(t, l1 < l2 && l2 == zl && zl < mts_test_json_long(zout, "levels") &&
                      mts_test_json_long(zout, "continuations") >= 1,
               "zooming in did not fetch more: %s", zout);
        CHECKF(t, strstr(hud1, "zoom in for more") != NULL, "HUD before the zoom: '%s'", hud1);
    }
    char zsum[40] = "", rsum[40] = "";
    json_s(zout, "checksum", zsum, sizeof zsum);
    snprintf(cmd, sizeof cmd,
             "ASAN_OPTIONS=detect_leaks=0 %s/mts-client %s cow --level %ld --no-render --json",
             bin_dir, listen, zl);
    CHECK(t, mts_test_run(cmd, ref, sizeof ref) == 0);
    json_s(ref, "checksum", rsum, sizeof rsum);
    CHECKF(t, zsum[0] && !strcmp(zsum, rsum), "checksum %s after the zoom, %s unbroken to %ld",
           zsum, rsum, zl);

    /* the same from a stream file on a web server: the policy's stop is one
     * range, zooming in asks nginx for the next */
    mts_test_tls_front front = {0};
    char said[4096];
    if (mts_test_find_nginx(front.nginx, sizeof front.nginx)) {
        snprintf(front.dir, sizeof front.dir, "%.580s/front", dir);
        snprintf(front.root, sizeof front.root, "%.580s/www", dir);
        snprintf(cmd, sizeof cmd, "mkdir -p %s && ASAN_OPTIONS=detect_leaks=0 %s/mts-build "
                 "tests/data/cow.off --stream %s/cow.mts -q", front.root, bin_dir, front.root);
        CHECK(t, mts_test_run(cmd, said, sizeof said) == 0);
        CHECKF(t, mts_test_tls_front_ca(&front, said, sizeof said), "openssl: %s", said);
        CHECKF(t, mts_test_tls_front_start(&front) > 0, "nginx did not start (%s)", front.dir);
        char url[200], uout[8192], usum[40] = "";
        snprintf(url, sizeof url, "http://127.0.0.1:%d/cow.mts", front.http_port);
        const window_env wu = {dir, url, display};
        const char *u[2];
        if (front.pid > 0 &&
            run_window_two_shots(t, &wu, "zoomurl", "0.8 key s\n1.0 scroll 8\n2.5 key s\n2.8 key q\n",
                                 "--lod-policy distance --distance 4", uout, sizeof uout, u)) {
            long ul = mts_test_json_long(uout, "level");
            CHECKF(t, mts_test_json_long(u[0], "level") < ul &&
                          mts_test_json_long(u[1], "level") == ul &&
                          mts_test_json_long(uout, "continuations") >= 1,
                   "zooming in did not fetch more from the file: %s", uout);
            json_s(uout, "checksum", usum, sizeof usum);
            snprintf(cmd, sizeof cmd,
                     "ASAN_OPTIONS=detect_leaks=0 %s/mts-client %s cow --level %ld --no-render "
                     "--json",
                     bin_dir, listen, ul);
            CHECK(t, mts_test_run(cmd, ref, sizeof ref) == 0);
            json_s(ref, "checksum", rsum, sizeof rsum);
            CHECKF(t, usum[0] && !strcmp(usum, rsum),
                   "checksum %s after the zoom over http, %s over TCP to %ld", usum, rsum, ul);
        }
        mts_test_tls_front_stop(&front, 0);
    } else {
        CHECKF(t, !getenv("MTS_TEST_REQUIRE_NGINX"), "nginx is not installed (scripts/deps.sh)");
        printf("  (no nginx: the window's continuation over a stream file is not tried)\n");
    }
    char clog[800], logtext[4096];
    snprintf(clog, sizeof clog, "%s/client.log", dir);
    mts_test_read_file(clog, logtext, sizeof logtext);
    mts_test_stop(spid);
    mts_test_stop(xpid);
    CHECKF(t, rc == 0, "exit %d: %s %s", rc, out, logtext);
    CHECKF(t, strstr(out, "\"complete\":true") != NULL, "%s", out);

    long level = mts_test_json_long(out, "level"), levels = mts_test_json_long(out, "levels"),
         triangles = mts_test_json_long(out, "triangles");
    /* frames while the stream came, and for how long: frames/s then */
    long frames = mts_test_json_long(out, "frames"),
         streaming = mts_test_json_long(out, "frames_streaming");
    const char *secs = strstr(out, "\"seconds_streaming\":");
    double seconds = secs ? strtod(secs + strlen("\"seconds_streaming\":"), NULL) : -1;
    const char *fps_at = strstr(out, "\"fps_streaming\":");
    double fps = fps_at ? strtod(fps_at + strlen("\"fps_streaming\":"), NULL) : -1;
    /* fps_streaming is the other two's quotient (seconds rounded to 1 ms as
     * printed, fps to 0.1) */
    CHECKF(t, streaming >= 1 && streaming <= frames && seconds > 0 &&
                  fabs(fps - (double)streaming / seconds) <= 0.06 + fps * 0.0006 / seconds,
           "frames %ld, %ld while streaming for %.3f s at %.1f/s: %s", frames, streaming,
           seconds, fps, out);
    const char *shots = strstr(out, "\"screenshots\":[");
    CHECKF(t, shots != NULL, "no screenshots in %s", out);
    if (!shots)
        return;
    /* the three entries */
    const char *e[3];
    int n = screenshots(shots, e, 3);
    CHECKF(t, n == 3, "%d screenshots: %s", n, shots);
    if (n != 3)
        return;
    CHECKF(t, strstr(e[2], "{\"file\":") == e[2] && !strstr(e[2] + 1, "{\"file\":"),
           "more than three screenshots: %s", shots);
    long lv[3], tri[3];
    unsigned char *data[3] = {0};
    long size[3] = {0};
    for (int i = 0; i < 3; i++) {
        char file[300], hud[1024], path[1100], want[80];
        json_s(e[i], "file", file, sizeof file);
        json_s(e[i], "hud", hud, sizeof hud);
        lv[i] = mts_test_json_long(e[i], "level");
        tri[i] = mts_test_json_long(e[i], "triangles");
        char name[64];
        snprintf(name, sizeof name, "cow_L%ld.png", lv[i]);
        CHECKF(t, !strcmp(file, name), "screenshot %d is %s, want %s", i, file, name);
        /* the HUD of that frame showed these very figures */
        snprintf(want, sizeof want, "level %ld of %ld", lv[i], levels);
        CHECKF(t, strstr(hud, want) != NULL, "HUD '%s' lacks '%s'", hud, want);
        snprintf(want, sizeof want, "triangles %ld ", tri[i]);
        CHECKF(t, strstr(hud, want) != NULL, "HUD '%s' lacks '%s'", hud, want);
        snprintf(path, sizeof path, "%s/%s", dir, file);
        CHECKF(t, read_whole(path, &data[i], &size[i]), "%s is missing", path);
        long fg = foreground_pixels(path);
        /* the cow covers a good part of a 640x480 frame; blank would be 0 */
        CHECKF(t, fg > 640 * 480 / 50, "%s looks blank: %ld foreground pixels", path, fg);
    }
    CHECKF(t, lv[0] == 0 && lv[0] < lv[1] && lv[1] < lv[2], "levels %ld %ld %ld", lv[0], lv[1],
           lv[2]);
    CHECKF(t, tri[0] < tri[1] && tri[1] < tri[2], "triangles %ld %ld %ld", tri[0], tri[1],
           tri[2]);
    /* End: the HUD agrees with what the client reports for the stream */
    CHECKF(t, lv[2] == level && level == levels, "last screenshot at %ld, client at %ld of %ld",
           lv[2], level, levels);
    CHECKF(t, tri[2] == triangles, "last screenshot %ld triangles, client %ld", tri[2],
           triangles);
    for (int i = 0; i < 3; i++)
        for (int j = i + 1; j < 3; j++)
            CHECKF(t, !(data[i] && data[j] && size[i] == size[j] &&
                        !memcmp(data[i], data[j], (size_t)size[i])),
                   "screenshots %d and %d are the same", i, j);
    for (int i = 0; i < 3; i++)
        free(data[i]);
}

/* A bad line is named before any window or connection is needed. */
static void test_script_errors(mts_test *t)
{
    char path[700], cmd[4096], out[4096];
    snprintf(path, sizeof path, "%s/window_bad_%d.txt", tmp_dir, (int)getpid());
    const char *bad[] = {"0.5 key Foo\n", "abc key s\n", "1 drag 4\n", "2 key s\n1 key q\n",
                         "0.5 jump 3\n"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        FILE *f = fopen(path, "w");
        CHECK(t, f != NULL);
        if (!f)
            return;
        fprintf(f, "# a comment\n\n%s", bad[i]);
        fclose(f);
        snprintf(cmd, sizeof cmd,
                 "DISPLAY=:9999 ASAN_OPTIONS=detect_leaks=0 %s/mts-client 127.0.0.1:1 cow "
                 "--window --script %s",
                 bin_dir, path);
        int rc = mts_test_run(cmd, out, sizeof out);
        char want[800];
        snprintf(want, sizeof want, "%s:%d:", path, strchr(bad[i], '\n')[1] ? 4 : 3);
        CHECKF(t, rc == 1 && strstr(out, want), "'%s': exit %d, want '%s' in: %s", bad[i], rc,
               want, out);
    }
    remove(path);
    snprintf(cmd, sizeof cmd, "%s/mts-client cow --script x.txt", bin_dir);
    CHECK(t, mts_test_run(cmd, out, sizeof out) == 2 && strstr(out, "--window"));
}

int main(int argc, char **argv)
{
    (void)argc;
    char rel[512], abs_dir[PATH_MAX];
    mts_test_bin_dir(argv[0], rel, sizeof rel);
    /* absolute: the client runs in a scratch directory (screenshots go to the cwd) */
    snprintf(bin_dir, sizeof bin_dir, "%.500s", realpath(rel, abs_dir) ? abs_dir : rel);
    snprintf(tmp_dir, sizeof tmp_dir, "%s", mts_test_tmpdir());
    signal(SIGPIPE, SIG_IGN);
    mts_test t = {0};
    RUN(&t, test_script_errors);
    RUN(&t, test_window_screenshots);
    return mts_test_end(&t);
}
