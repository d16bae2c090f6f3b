/* mts-client: streams a model from an mts-server, applies every batch as it
 * arrives and renders headless (EGL) at the level received. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "cli.h"
#include "modelfile.h"
#include "render.h"
#include "session.h"
#include "stream.h"

static void usage(FILE *f)
{
    fputs("usage: mts-client [HOST[:PORT]] MODEL [--level L | --triangles N | --fraction F]\n"
          "                  [--png FILE] [--png-levels L1,L2,...] [--size WxH] [--color-strips]\n"
          "                  [--verify] [--model-file M.mtsm] [--no-render] [--resume]\n"
          "                  [--retries N] [--json] [--quiet]\n"
          "       mts-client [HOST[:PORT]] --list\n"
          "\n"
          "Streams MODEL from an mts-server (default 127.0.0.1:7447): a Draco base mesh,\n"
          "then batches of strip records applied as they arrive, rendered headless.\n"
          "\n"
          "  --level L / --triangles N / --fraction F   stop there (default: full)\n"
          "  --png FILE          write the final frame\n"
          "  --png-levels LIST   also write FILE-stem_L<level>.png at each listed level\n"
          "                      (MODEL_L<level>.png without --png)\n"
          "  --size WxH          frame size (default 512x512)\n"
          "  --color-strips      each strip in its own colour\n"
          "  --verify            check every batch's CRC and the final checksum (always\n"
          "                      done) and, with --model-file, that the final strips and\n"
          "                      positions equal that model's stream at the same level\n"
          "  --no-render         decode and apply only\n"
          "  --resume            when the connection breaks (or cannot be made), wait\n"
          "                      0.1 s doubling to 2 s (with jitter), reconnect and go on\n"
          "                      from the last batch applied; the final mesh is the same\n"
          "  --retries N         with --resume: give up after N tries in a row without\n"
          "                      progress (default 8)\n"
          "  --list              print the server's models\n"
          "  --json              one line of JSON with the figures\n"
          "  -q, --quiet         no progress, no summary\n"
          "\n"
          "Exit status: 0 complete, 1 failed (the last whole batch is still drawn;\n"
          "with --resume, after the last try), 2 bad usage.\n",
          f);
}

typedef struct run {
    int render, quiet;
    const char *png, *model;
    uint32_t png_levels[64];
    int png_level_count;
    uint32_t next_png; /* index into png_levels, sorted ascending */
    mts_render_options ro;
    mts_render_context *ctx;
    mts_renderer *r;
    uint32_t uploaded; /* vertices in the renderer */
    double ms_render;
    cli_bar bar;
    mts_error err;
    int failed;
    uint32_t pngs_written;
    char png_paths[8][512];
} run;

static double now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

static int cmp_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return x < y ? -1 : x > y;
}

static void level_png_path(const run *rn, uint32_t level, char *out, size_t size)
{
    char stem[400];
    if (rn->png) {
        snprintf(stem, sizeof stem, "%s", rn->png);
        char *dot = strrchr(stem, '.');
        char *slash = strrchr(stem, '/');
        if (dot && (!slash || dot > slash))
            *dot = 0;
    } else {
        snprintf(stem, sizeof stem, "%s", rn->model);
    }
    snprintf(out, size, "%s_L%u.png", stem, level);
}

/* Brings the renderer up to date with the runtime and draws a frame. */
static int draw(run *rn, mts_stream_client *c)
{
    double t = now_ms();
    uint32_t have = c->model.base_vertex_count + c->splits;
    if (have > rn->uploaded) {
        if (mts_render_append_vertices(rn->r, rn->uploaded, have - rn->uploaded,
                                       c->model.positions + 3 * (size_t)rn->uploaded,
                                       c->model.normals + 3 * (size_t)rn->uploaded,
                                       &rn->err) != MTS_OK)
            return 0;
        rn->uploaded = have;
    }
    if (mts_render_update_strips(rn->r, &c->lod, &rn->err) != MTS_OK)
        return 0;
    mts_lod_clear_changed(&c->lod);
    if (mts_render_draw(rn->r, &rn->err) != MTS_OK)
        return 0;
    rn->ms_render += now_ms() - t;
    return 1;
}

static int write_png(run *rn, const char *path)
{
    if (mts_render_write_png(rn->r, path, &rn->err) != MTS_OK)
        return 0;
    if (rn->pngs_written < 8)
        snprintf(rn->png_paths[rn->pngs_written], sizeof rn->png_paths[0], "%s", path);
    rn->pngs_written++;
    return 1;
}

/* PNGs for the listed levels the stream has now made available. */
static int level_pngs(run *rn, mts_stream_client *c, int final)
{
    uint32_t reached = c->lod.level;
    while (rn->next_png < (uint32_t)rn->png_level_count &&
           (rn->png_levels[rn->next_png] <= reached ||
            (final && rn->png_levels[rn->next_png] > c->info.levels))) {
        uint32_t want = rn->png_levels[rn->next_png++];
        if (want > c->info.levels)
            want = c->info.levels;
        if (want > reached)
            continue;
        /* step down to the level, draw it, come back: only changed strips move */
        if (mts_lod_set_level(&c->lod, want, &rn->err) != MTS_OK || !draw(rn, c))
            return 0;
        char path[512];
        level_png_path(rn, want, path, sizeof path);
        if (!write_png(rn, path))
            return 0;
        if (mts_lod_set_level(&c->lod, reached, &rn->err) != MTS_OK)
            return 0;
    }
    return 1;
}

static int on_event(void *user, mts_stream_event ev, mts_stream_client *c)
{
    run *rn = user;
    if (ev == MTS_EV_RESUMED && !rn->quiet) {
        cli_bar_done(&rn->bar);
        fprintf(stderr, "mts-client: reconnected; resuming at batch %u of %u\n", c->batches,
                c->info.batch_count);
    }
    if (ev == MTS_EV_INFO) {
        cli_bar_update(&rn->bar, "stream", 0);
    } else if (ev == MTS_EV_BASE && rn->render) {
        mts_render_layout layout;
        mts_render_layout_from_lod(&c->lod, &layout);
        if (mts_renderer_create(rn->ctx, &rn->ro, &layout, &rn->r, &rn->err) != MTS_OK ||
            !draw(rn, c) || !level_pngs(rn, c, 0)) {
            rn->failed = 1;
            return 1;
        }
    } else if (ev == MTS_EV_BATCH) {
        cli_bar_update(&rn->bar, "stream",
                       c->stop_level ? (double)c->lod.level / c->stop_level : 1.0);
        if (rn->render && rn->next_png < (uint32_t)rn->png_level_count && !level_pngs(rn, c, 0)) {
            rn->failed = 1;
            return 1;
        }
    }
    return 0;
}

/* --resume: the session waits and tries again; say so on stderr. */
static int on_retry(void *user, const mts_session_retry *r)
{
    run *rn = user;
    if (rn->quiet)
        return 0;
    cli_bar_done(&rn->bar);
    if (r->have_base)
        fprintf(stderr, "mts-client: connection lost at batch %u (%s); retrying in %.2f s "
                        "(try %u/%u)\n",
                r->batches, r->reason, r->delay, r->attempt, r->max_tries);
    else
        fprintf(stderr, "mts-client: %s; retrying in %.2f s (try %u/%u)\n", r->reason, r->delay,
                r->attempt, r->max_tries);
    return 0;
}

/* One triangle through a throw-away renderer with the real options. */
static int warm_up(run *rn)
{
    const uint32_t slot[2] = {0, 3};
    mts_render_layout layout = {3, 1, slot, {0, 0, 0}, {1, 1, 1}};
    mts_renderer *r = NULL;
    const float pos[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0}, nor[9] = {0, 0, 1, 0, 0, 1, 0, 0, 1};
    const uint32_t tri[3] = {0, 1, 2};
    int ok = mts_renderer_create(rn->ctx, &rn->ro, &layout, &r, &rn->err) == MTS_OK &&
             mts_render_append_vertices(r, 0, 3, pos, nor, &rn->err) == MTS_OK &&
             mts_render_set_strip(r, 0, tri, 3, &rn->err) == MTS_OK &&
             mts_render_draw(r, &rn->err) == MTS_OK;
    mts_renderer_destroy(r);
    return ok;
}

static int parse_size(const char *s, uint32_t *w, uint32_t *h)
{
    char *x;
    unsigned long a = strtoul(s, &x, 10), b;
    if (x == s || (*x != 'x' && *x != 'X'))
        return 0;
    char *end;
    b = strtoul(x + 1, &end, 10);
    if (*end || a < 16 || b < 16 || a > 8192 || b > 8192)
        return 0;
    *w = (uint32_t)a;
    *h = (uint32_t)b;
    return 1;
}

static void print_model(void *user, const mts_wire_model_entry *m)
{
    (void)user;
    printf("%-24s %9u vertices %9u triangles %9u levels %10u stream bytes\n", m->name,
           m->vertices, m->triangles, m->levels, m->stream_bytes);
}

/* --model-file: the same model's stream built here must hold, at the final
 * level, exactly the strips and positions the client received. */
static int compare_with_file(const char *path, mts_stream_client *c, mts_error *err)
{
    mts_model m;
    mts_stream s;
    if (mts_modelfile_load(path, &m, err) != MTS_OK)
        return 0;
    mts_result rc = mts_stream_build(&m, c->info.model, NULL, &s, err);
    mts_model_free(&m);
    if (rc != MTS_OK)
        return 0;
    int same = s.stream_id == c->info.stream_id;
    if (!same)
        mts_error_set(err, MTS_ERR_INVARIANT, "%s encodes to another stream than the server's",
                      path);
    mts_lod ref;
    if (same && mts_lod_init(&ref, &s.model, MTS_LOD_AT_BASE, err) == MTS_OK) {
        mts_lod_set_level(&ref, c->lod.level, err);
        for (uint32_t st = 0; st < ref.strip_count && same; st++) {
            uint32_t la, lb;
            const uint32_t *a = mts_lod_strip(&ref, st, &la);
            const uint32_t *b = mts_lod_strip(&c->lod, st, &lb);
            if (la != lb || memcmp(a, b, (size_t)la * 4) != 0) {
                same = 0;
                mts_error_set(err, MTS_ERR_INVARIANT, "strip %u differs from %s at level %u", st,
                              path, c->lod.level);
            }
        }
        size_t nv = (size_t)s.model.base_vertex_count + c->lod.level;
        if (same && memcmp(s.model.positions, c->model.positions, nv * 12) != 0) {
            same = 0;
            mts_error_set(err, MTS_ERR_INVARIANT, "positions differ from %s", path);
        }
        mts_lod_free(&ref);
    }
    mts_stream_free(&s);
    return same;
}

int main(int argc, char **argv)
{
    const char *pos[2];
    int npos = 0, json = 0, verify = 0, list = 0;
    const char *model_file = NULL;
    run rn;
    memset(&rn, 0, sizeof rn);
    rn.render = 1;
    mts_render_options_default(&rn.ro);
    mts_session_options so = {0};
    so.hello.stop_kind = MTS_STOP_FULL;
    int stops = 0, stop;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) {
            usage(stdout);
            return CLI_EXIT_OK;
        } else if (!strcmp(a, "--json")) {
            json = 1;
        } else if (!strcmp(a, "-q") || !strcmp(a, "--quiet")) {
            rn.quiet = 1;
        } else if (!strcmp(a, "--verify")) {
            verify = 1;
        } else if (!strcmp(a, "--list")) {
            list = 1;
        } else if (!strcmp(a, "--no-render")) {
            rn.render = 0;
        } else if (!strcmp(a, "--resume")) {
            so.resume = 1;
        } else if (!strcmp(a, "--retries")) {
            if (!v || !cli_parse_u32(v, &so.max_tries) || so.max_tries < 1 ||
                so.max_tries > 1000) {
                fprintf(stderr, "mts-client: --retries needs a whole number from 1 to 1000\n");
                return CLI_EXIT_USAGE;
            }
            i++;
        } else if (!strcmp(a, "--color-strips")) {
            rn.ro.style.color_by_strip = 1;
        } else if ((stop = cli_parse_stop(a, v, &so.hello.stop_kind, &so.hello.stop_value))) {
            if (stop < 0) {
                fprintf(stderr, "mts-client: %s needs %s\n", a,
                        strcmp(a, "--fraction") ? "a whole number" : "a number from 0 to 1");
                return CLI_EXIT_USAGE;
            }
            stops++;
            i++;
        } else if (!strcmp(a, "--png") || !strcmp(a, "--model-file")) {
            if (!v) {
                fprintf(stderr, "mts-client: %s needs a file name\n", a);
                return CLI_EXIT_USAGE;
            }
            if (!strcmp(a, "--png"))
                rn.png = v;
            else
                model_file = v;
            i++;
        } else if (!strcmp(a, "--png-levels")) {
            if (!v) {
                fprintf(stderr, "mts-client: --png-levels needs a list like 0,100,1000\n");
                return CLI_EXIT_USAGE;
            }
            char tmp[1024];
            snprintf(tmp, sizeof tmp, "%s", v);
            for (char *tok = strtok(tmp, ","); tok; tok = strtok(NULL, ",")) {
                uint32_t l;
                if (!cli_parse_u32(tok, &l) || rn.png_level_count >= 64) {
                    fprintf(stderr, "mts-client: --png-levels: '%s' is not a level\n", tok);
                    return CLI_EXIT_USAGE;
                }
                rn.png_levels[rn.png_level_count++] = l;
            }
            qsort(rn.png_levels, (size_t)rn.png_level_count, 4, cmp_u32);
            i++;
        } else if (!strcmp(a, "--size")) {
            if (!v || !parse_size(v, &rn.ro.width, &rn.ro.height)) {
                fprintf(stderr, "mts-client: --size needs WxH, each 16..8192\n");
                return CLI_EXIT_USAGE;
            }
            i++;
        } else if (a[0] == '-' && a[1]) {
            fprintf(stderr, "mts-client: unknown option %s (see --help)\n", a);
            return CLI_EXIT_USAGE;
        } else if (npos < 2) {
            pos[npos++] = a;
        } else {
            fprintf(stderr, "mts-client: too many arguments (see --help)\n");
            return CLI_EXIT_USAGE;
        }
    }
    if (stops > 1) {
        fprintf(stderr, "mts-client: give one of --level, --triangles, --fraction\n");
        return CLI_EXIT_USAGE;
    }
    const char *server = NULL;
    if (list) {
        if (npos > 1) {
            fprintf(stderr, "mts-client: --list takes only HOST[:PORT]\n");
            return CLI_EXIT_USAGE;
        }
        server = npos ? pos[0] : NULL;
    } else {
        if (npos == 0) {
            usage(stderr);
            return CLI_EXIT_USAGE;
        }
        server = npos == 2 ? pos[0] : NULL;
        rn.model = pos[npos - 1];
        if (!mts_wire_valid_name(rn.model, strlen(rn.model))) {
            fprintf(stderr, "mts-client: '%s' is not a model name ([A-Za-z0-9._-], 1..64)\n",
                    rn.model);
            return CLI_EXIT_USAGE;
        }
        snprintf(so.hello.model, sizeof so.hello.model, "%s", rn.model);
    }
    char host[256] = "127.0.0.1", port[16] = "7447";
    if (server && !cli_parse_server(server, host, sizeof host, port, sizeof port)) {
        fprintf(stderr, "mts-client: bad address %s (HOST[:PORT])\n", server);
        return CLI_EXIT_USAGE;
    }
    so.host = host;
    so.port = port;
    so.list = list;
    so.on_event = on_event;
    so.on_retry = on_retry;
    so.user = &rn;
    cli_bar_init(&rn.bar, rn.quiet || json || list);

    /* EGL comes up, and draws once, before connecting: the first frame of
     * the model should wait for the network, not for the driver (llvmpipe
     * compiles a shader variant at its first draw) */
    if (rn.render && !list &&
        (mts_render_context_create_headless(&rn.ctx, &rn.err) != MTS_OK ||
         !warm_up(&rn))) {
        fprintf(stderr, "mts-client: %s\n", rn.err.msg);
        mts_render_context_destroy(rn.ctx);
        return CLI_EXIT_FAIL;
    }
    mts_stream_client c;
    mts_stream_client_init(&c);
    c.on_model = print_model;
    mts_session_stats st;
    mts_error err = {0};
    mts_result rc = mts_session_run(&so, &c, &st, &err);
    cli_bar_done(&rn.bar);
    if (list) {
        if (rc != MTS_OK)
            fprintf(stderr, "mts-client: %s\n", err.msg);
        mts_stream_client_free(&c);
        return rc == MTS_OK ? CLI_EXIT_OK : CLI_EXIT_FAIL;
    }
    if (rn.failed) {
        rc = rn.err.code ? rn.err.code : MTS_ERR_INTERNAL;
        err = rn.err;
    }
    int verified = -1;
    /* whatever happened, the last whole batch is drawn and written -- unless a
     * record failed while a batch was being applied: the runtime is then
     * broken part-way through a split and there is no whole level to draw */
    if (rn.r && c.have_lod && !c.lod.broken) {
        if (rc == MTS_OK)
            level_pngs(&rn, &c, 1);
        if (draw(&rn, &c) && rn.png)
            write_png(&rn, rn.png);
    }
    if (rc == MTS_OK && verify && model_file) {
        mts_error verr = {0};
        verified = compare_with_file(model_file, &c, &verr);
        if (!verified) {
            rc = verr.code ? verr.code : MTS_ERR_INVARIANT;
            err = verr;
        }
    } else if (rc == MTS_OK && verify) {
        verified = c.checksum == c.end_checksum;
    }
    uint32_t triangles = 0;
    if (c.have_lod) {
        mts_strip_stats ss = {0};
        for (uint32_t s = 0; s < c.lod.strip_count; s++) {
            uint32_t len;
            const uint32_t *str = mts_lod_strip(&c.lod, s, &len);
            mts_strip_stats_add(&ss, str, len);
        }
        triangles = (uint32_t)ss.triangles;
    }
    if (json) {
        cli_json j;
        cli_json_begin(&j, stdout);
        cli_json_str(&j, "model", rn.model);
        cli_json_bool(&j, "complete", rc == MTS_OK);
        cli_json_u64(&j, "bytes", st.bytes);
        cli_json_u64(&j, "batches", c.batches);
        cli_json_u64(&j, "level", c.have_lod ? c.lod.level : 0);
        cli_json_u64(&j, "levels", c.info.levels);
        cli_json_u64(&j, "triangles", triangles);
        if (c.end_checksum) { /* END came: the mesh checksum at the final level */
            char hex[17];
            snprintf(hex, sizeof hex, "%016llx", (unsigned long long)c.checksum);
            cli_json_str(&j, "checksum", hex);
        }
        cli_json_u64(&j, "reconnects", st.reconnects);
        cli_json_num(&j, "ms_connect", st.ms_connect, 3);
        cli_json_num(&j, "ms_base", st.ms_base, 3);
        cli_json_num(&j, "ms_final", st.ms_final, 3);
        cli_json_num(&j, "ms_apply", st.ms_apply, 3);
        cli_json_num(&j, "ms_render", rn.ms_render, 3);
        if (verified >= 0)
            cli_json_bool(&j, "verified", verified);
        if (rc != MTS_OK)
            cli_json_str(&j, "error", err.msg);
        cli_json_end(&j);
    } else if (!rn.quiet && c.have_lod) {
        printf("%s: level %u of %u, %u triangles, %u batches, %llu bytes in %.1f ms "
               "(base drawn at %.1f ms; decode+apply %.1f ms, render %.1f ms)\n",
               rn.model, c.have_lod ? c.lod.level : 0, c.info.levels, triangles, c.batches,
               (unsigned long long)st.bytes, st.ms_final ? st.ms_final : 0, st.ms_base,
               st.ms_apply, rn.ms_render);
        for (uint32_t i = 0; i < rn.pngs_written && i < 8; i++)
            printf("  wrote %s\n", rn.png_paths[i]);
        if (verified == 1)
            printf("  verified: checksum%s match\n", model_file ? ", strips and positions" : "");
    }
    if (rc != MTS_OK)
        fprintf(stderr, "mts-client: %s\n", err.msg);
    mts_renderer_destroy(rn.r);
    mts_render_context_destroy(rn.ctx);
    mts_stream_client_free(&c);
    return rc == MTS_OK ? CLI_EXIT_OK : CLI_EXIT_FAIL;
}
