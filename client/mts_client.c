/* mts-client: streams a model from an mts-server, applies every batch as it
 * arrives and renders headless (EGL) at the level received -- or, with
 * --window (mts_client_window.c), shows it in an X11 window the user can
 * turn, zoom and move through the levels of, while the stream goes on. */
#include <errno.h>
#include <math.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "clock.h"
#include "modelfile.h"
#include "mts_client.h"
#include "stream.h"
#include "strips.h"
#include "words.h"

static void usage(FILE *f)
{
    fputs("usage: mts-client [HOST[:PORT]] MODEL [--level L | --triangles N | --fraction F]\n"
          "                  [--png FILE] [--png-levels L1,L2,...] [--size WxH] [--color-strips]\n"
          "                  [--verify] [--model-file M.mtsm] [--no-render] [--records]\n"
          "                  [--resume] [--retries N] [--connect-timeout S] [--timeout S]\n"
          "                  [--max-time S] [--lod-policy P [--fps N] [--distance D]]\n"
          "                  [--json] [--quiet]\n"
          "       mts-client [HOST[:PORT]] MODEL --window [--size WxH] [--script FILE]\n"
          "                  [--color-strips] [--level L | ...] [--lod-policy P] [--resume]\n"
          "                  [--morph-ms MS] [--json]\n"
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
          "  --lod-policy P      the level drawn at the end: received (default: all that\n"
          "                      came), distance or area (from the camera: the stream is\n"
          "                      asked to stop at their level), budget (the largest\n"
          "                      level that draws within 1000/--fps ms: an eighth of the\n"
          "                      model first, then more while frames fit)\n"
          "  --fps N             budget's target frames per second (default 60)\n"
          "  --distance D        camera at D times the framing distance (default 1)\n"
          "  --verify            check every batch's CRC and the final checksum (always\n"
          "                      done) and, with --model-file, that the final strips and\n"
          "                      positions equal that model's stream at the same level\n"
          "  --no-render         decode and apply only\n"
          "  --records           ask for the records form: about 16x the bytes, but nothing\n"
          "                      to derive, so far less work to apply; for fast links\n"
          "  --resume            when the connection breaks (or cannot be made), wait\n"
          "                      0.1 s doubling to 2 s (with jitter), reconnect and go on\n"
          "                      from the last batch applied; the final mesh is the same\n"
          "  --retries N         with --resume: give up after N tries in a row without\n"
          "                      progress (default 8)\n"
          "  --connect-timeout S give up a connect after S s (default 5)\n"
          "  --timeout S         give up a connection that brings no byte for S s\n"
          "                      (default 30; with --resume, that try)\n"
          "  --max-time S        give up when the stream has not ended after S s in all,\n"
          "                      waits and resumes included (default 600)\n"
          "  --window            show the model in a window (X11, $DISPLAY) as it streams:\n"
          "                      left-drag turns it, the wheel zooms; keys: + / - one\n"
          "                      batch of levels, PgUp / PgDn 10%, Home the base, End the\n"
          "                      newest level (and follow the stream, or --lod-policy,\n"
          "                      again), w wireframe,\n"
          "                      c colour per strip, s screenshot (MODEL_L<level>.png here),\n"
          "                      q or Escape quit. A HUD shows level, triangles, strips,\n"
          "                      indices per triangle, frames/s, bytes and MB/s\n"
          "  --morph-ms MS       with --window: geomorphs; a level change slides the\n"
          "                      vertices it adds (or removes) from (or to) their\n"
          "                      ancestors' places over MS ms, so levels do not pop\n"
          "                      (default 250; 0 switches levels at once)\n"
          "  --script FILE       with --window: input from FILE, one event a line, seconds\n"
          "                      after the first frame first: '0.5 key End', '1.2 drag 40\n"
          "                      -10', '1.4 scroll -2', '2.0 key q'\n"
          "  --list              print the server's models\n"
          "  --json              one line of JSON with the figures\n"
          "  -q, --quiet         no progress, no summary\n"
          "\n"
          "Exit status: 0 complete, 1 failed (the last whole batch is still drawn;\n"
          "with --resume, after the last try), 2 bad usage.\n",
          f);
}

static void level_png_path(const client_run *rn, uint32_t level, char *out, size_t size)
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

/* Brings the view to `level` (MTS_VIEW_NEWEST: all that came) and draws a
 * frame. Headless, the view moves the stream client's own runtime. */
static int draw(client_run *rn, mts_stream_client *c, uint32_t level)
{
    double t = 1e3 * mts_clock_seconds();
    mts_view_source src = mts_view_source_of_stream(c);
    if (mts_view_sync(&rn->view, &src, level, t, &rn->err) != MTS_OK ||
        mts_view_draw(&rn->view, &rn->err) != MTS_OK)
        return 0;
    rn->ms_render += 1e3 * mts_clock_seconds() - t;
    return 1;
}

/* What went to GL (the whole run) beside what the last frame drew from: the
 * vertices and the index buffer of the draw path (the packed one by
 * default), so a run's uploads read as a multiple of its final buffers. */
static void json_uploads(cli_json *j, const mts_renderer *r)
{
    if (!r)
        return;
    mts_render_stats rs;
    mts_render_get_stats(r, &rs);
    cli_json_u64(j, "gl_upload_bytes", rs.vertex_bytes_uploaded + rs.index_bytes_uploaded);
    cli_json_u64(j, "gl_final_bytes",
                 (uint64_t)rs.vertices * 24u +
                     (rs.packed_bytes ? rs.packed_bytes : rs.last_draw_index_bytes));
    if (rs.morph_bytes_uploaded)
        cli_json_u64(j, "gl_morph_bytes", rs.morph_bytes_uploaded);
}

void client_json_run(cli_json *j, const mts_stream_client *c, const mts_session_stats *st,
                     const client_run *rn)
{
    if (c->end_checksum) { /* END came: the mesh checksum at the final level */
        char hex[17];
        snprintf(hex, sizeof hex, "%016llx", (unsigned long long)c->checksum);
        cli_json_str(j, "checksum", hex);
    }
    cli_json_u64(j, "reconnects", st->reconnects);
    cli_json_num(j, "ms_connect", st->ms_connect, 3);
    cli_json_num(j, "ms_base", st->ms_base, 3);
    cli_json_num(j, "ms_final", st->ms_final, 3);
    cli_json_num(j, "ms_apply", st->ms_apply, 3);
    cli_json_num(j, "ms_render", rn->ms_render, 3);
    json_uploads(j, rn->have_view ? rn->view.renderer : NULL);
}

static int write_png(client_run *rn, const char *path)
{
    if (mts_render_write_png(rn->view.renderer, path, &rn->err) != MTS_OK)
        return 0;
    if (rn->pngs_written < 8)
        snprintf(rn->png_paths[rn->pngs_written], sizeof rn->png_paths[0], "%s", path);
    rn->pngs_written++;
    return 1;
}

/* PNGs for the listed levels the stream has now made available. */
static int level_pngs(client_run *rn, mts_stream_client *c, int final)
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
        if (!draw(rn, c, want))
            return 0;
        char path[512];
        level_png_path(rn, want, path, sizeof path);
        if (!write_png(rn, path))
            return 0;
        mts_view_source src = mts_view_source_of_stream(c);
        if (mts_view_sync(&rn->view, &src, reached, 1e3 * mts_clock_seconds(), &rn->err) !=
            MTS_OK)
            return 0;
    }
    return 1;
}

static int on_event(void *user, mts_stream_event ev, mts_stream_client *c)
{
    client_run *rn = user;
    if (ev == MTS_EV_RESUMED && !rn->quiet && !c->continuing) {
        cli_bar_done(&rn->bar);
        fprintf(stderr, "mts-client: reconnected; resuming at batch %u of %u\n", c->batches,
                c->info.batch_count);
    }
    if (ev == MTS_EV_INFO) {
        cli_bar_update(&rn->bar, "stream", 0);
    } else if (ev == MTS_EV_BASE && rn->render && !rn->have_view) {
        /* a stream without normals is shaded from the faces each level has */
        rn->ro.style.flat_shading = !(c->info.flags & MTS_INFO_NORMALS);
        mts_view_source src = mts_view_source_of_stream(c);
        if (mts_view_create(&rn->view, rn->ctx, &rn->ro, &src, NULL, &rn->err) != MTS_OK) {
            rn->failed = 1;
            return 1;
        }
        rn->have_view = 1;
        if (!draw(rn, c, MTS_VIEW_NEWEST) || !level_pngs(rn, c, 0)) {
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
    client_run *rn = user;
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

int client_warm_up(client_run *rn)
{
    const uint32_t slot[2] = {0, 3};
    mts_render_layout layout = {3, 1, slot, {0, 0, 0}, {1, 1, 1}, 0};
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

/* A MODELS listing's entry for one model: what the camera policies need to
 * ask for their stop point before the stream. */
typedef struct listed {
    const char *name;
    mts_wire_model_entry entry;
    int found;
} listed;

static void find_model(void *user, const mts_wire_model_entry *m)
{
    listed *l = user;
    if (!strcmp(m->name, l->name)) {
        l->entry = *m;
        l->found = 1;
    }
}

/* --lod-policy distance or area: the level they choose is known from the
 * view and the model's full triangle count (the server's MODELS listing,
 * a few dozen bytes), so the stream is asked to stop there instead of
 * coming whole: HELLO's triangle stop, which the server resolves with the
 * model's own per-level counts to the highest level within the budget --
 * the policy's choice, counted exactly. Returns 1 when the stop was set
 * (*asked the triangles, *list_bytes and *full_bytes the listing's figures). */
int client_policy_stop(mts_session_options *so, const client_run *rn,
                       const mts_lod_policy_options *po, double distance, uint32_t *asked,
                       uint64_t *list_bytes, uint64_t *full_bytes)
{
    mts_session_options lo = *so;
    lo.list = 1;
    lo.on_event = NULL;
    lo.resume = 0;
    mts_stream_client lc;
    mts_stream_client_init(&lc);
    listed l;
    memset(&l, 0, sizeof l);
    l.name = rn->model;
    lc.on_model = find_model;
    lc.user = &l;
    mts_session_stats st;
    mts_error err = {0};
    mts_result rc = mts_session_run(&lo, &lc, &st, &err);
    mts_stream_client_free(&lc);
    if (rc != MTS_OK || !l.found)
        return 0; /* the stream comes whole and the policy picks after it */
    /* budget cannot know its level before frames are timed: a first guess,
     * an eighth of the model, then more while frames stay in the budget */
    double t = po->kind == MTS_LOD_POLICY_BUDGET
                   ? l.entry.triangles / 8.0
                   : mts_lod_policy_stop_triangles(po, distance,
                                                   rn->ro.camera.fov_y_deg * 3.14159265f / 180.0f,
                                                   (int)rn->ro.width, (int)rn->ro.height,
                                                   l.entry.triangles);
    if (!(t >= 0) || t > UINT32_MAX)
        return 0;
    so->hello.stop_kind = MTS_STOP_TRIANGLES;
    so->hello.stop_value = (uint32_t)t;
    *asked = (uint32_t)t;
    *list_bytes = st.bytes;
    *full_bytes = l.entry.stream_bytes;
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
    /* the form the server sent: a records-form stream has its own stream_id */
    mts_stream_options so = {0};
    so.with_records = c->records;
    mts_result rc = mts_stream_build(&m, c->info.model, &so, &s, err);
    mts_model_free(&m);
    if (rc != MTS_OK)
        return 0;
    int same = mts_stream_for_hello(&s, c->records ? MTS_HELLO_RECORDS : 0)->stream_id ==
               c->info.stream_id;
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

/* --lod-policy: the policy's level (at most the level received) for the
 * final frame, in *level. budget draws frames, each timed from the level
 * change to glFinish, until the level has held for 10 frames (at most 120).
 * Only changed strips are re-uploaded (the coherent runtime). */
static int apply_policy(client_run *rn, mts_stream_client *c, const mts_lod_policy_options *po,
                        double distance, uint32_t *level, double *want_more)
{
    *want_more = 0;
    mts_lod_policy p;
    mts_lod_policy_init(&p, po, &c->model);
    mts_strip_stats base = {0};
    mts_strips_stats(&c->model.base, &base);
    mts_lod_policy_set_counts(&p, (uint32_t)base.triangles, c->info.triangles);
    uint32_t received = c->lod.level;
    mts_lod_view view = {1, rn->ro.camera.fov_y_deg * 3.14159265f / 180.0f, (int)rn->ro.width,
                         (int)rn->ro.height};
    view.distance = (float)(distance * mts_lod_policy_frame_distance(&p, &view));
    double last_ms = 0;
    for (int frame = 0, held = 0; frame < 120 && held < 10; frame++) {
        uint32_t l = mts_lod_policy_choose(&p, received, &view, last_ms);
        held = l == c->lod.level ? held + 1 : 0;
        *level = l;
        if (po->kind != MTS_LOD_POLICY_BUDGET)
            return 1;
        double t = (1e3 * mts_clock_seconds());
        if (!draw(rn, c, l))
            return 0;
        last_ms = (1e3 * mts_clock_seconds()) - t;
    }
    /* all that came fits the budget: the triangles it would take */
    if (*level == received && p.ms_per_triangle > 0)
        *want_more = p.opt.headroom * (1000.0 / p.opt.fps) / p.ms_per_triangle;
    return 1;
}

int main(int argc, char **argv)
{
    const char *pos[2];
    int npos = 0, json = 0, verify = 0, list = 0, window = 0, size_given = 0;
    const char *model_file = NULL, *script = NULL;
    client_run rn;
    memset(&rn, 0, sizeof rn);
    rn.render = 1;
    rn.morph_ms = -1;
    mts_render_options_default(&rn.ro);
    mts_session_options so = {0};
    so.hello.stop_kind = MTS_STOP_FULL;
    int stops = 0, stop;
    mts_lod_policy_options po = {0};
    double distance = 1;
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
        } else if (!strcmp(a, "--records")) {
            so.hello.flags |= MTS_HELLO_RECORDS;
        } else if (!strcmp(a, "--window")) {
            window = 1;
        } else if (!strcmp(a, "--script")) {
            if (!v) {
                fprintf(stderr, "mts-client: --script needs a file name\n");
                return CLI_EXIT_USAGE;
            }
            script = v;
            i++;
        } else if (!strcmp(a, "--connect-timeout") || !strcmp(a, "--timeout") ||
                   !strcmp(a, "--max-time")) {
            double *dst = !strcmp(a, "--connect-timeout") ? &so.connect_timeout
                          : !strcmp(a, "--timeout")       ? &so.io_timeout
                                                          : &so.max_time;
            if (!v || !cli_parse_double(v, dst) || !(*dst > 0) || *dst > 1e6) {
                fprintf(stderr, "mts-client: %s needs a number of seconds above 0\n", a);
                return CLI_EXIT_USAGE;
            }
            i++;
        } else if (!strcmp(a, "--morph-ms")) {
            if (!v || !cli_parse_double(v, &rn.morph_ms) || !(rn.morph_ms >= 0) ||
                rn.morph_ms > 60000) {
                fprintf(stderr, "mts-client: --morph-ms needs milliseconds from 0 to 60000\n");
                return CLI_EXIT_USAGE;
            }
            i++;
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
        } else if (!strcmp(a, "--lod-policy")) {
            if (!v || !mts_lod_policy_parse(v, &po.kind)) {
                fprintf(stderr, "mts-client: --lod-policy needs received, distance, area or "
                                "budget\n");
                return CLI_EXIT_USAGE;
            }
            i++;
        } else if (!strcmp(a, "--fps") || !strcmp(a, "--distance")) {
            char *end;
            double x = v ? strtod(v, &end) : 0;
            if (!v || *end || !(x > 0) || x > 1e6) {
                fprintf(stderr, "mts-client: %s needs a positive number\n", a);
                return CLI_EXIT_USAGE;
            }
            *(!strcmp(a, "--fps") ? &po.fps : &distance) = x;
            i++;
        } else if ((stop = cli_option_stop(argc, argv, &i, "mts-client", &so.hello.stop_kind,
                                           &so.hello.stop_value))) {
            if (stop < 0)
                return CLI_EXIT_USAGE;
            stops++;
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
            qsort(rn.png_levels, (size_t)rn.png_level_count, 4, mts_words_cmp);
            i++;
        } else if (!strcmp(a, "--size")) {
            if (!v || !parse_size(v, &rn.ro.width, &rn.ro.height)) {
                fprintf(stderr, "mts-client: --size needs WxH, each 16..8192\n");
                return CLI_EXIT_USAGE;
            }
            size_given = 1;
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
    if (po.kind != MTS_LOD_POLICY_RECEIVED && !rn.render) {
        fprintf(stderr, "mts-client: --lod-policy draws: it cannot go with --no-render\n");
        return CLI_EXIT_USAGE;
    }
    rn.ro.camera.zoom = (float)(1 / distance);
    /* budget reads frame times: frames that are waited for */
    rn.ro.timed = po.kind == MTS_LOD_POLICY_BUDGET;
    if (stops > 1) {
        fprintf(stderr, "mts-client: give one of --level, --triangles, --fraction\n");
        return CLI_EXIT_USAGE;
    }
    if (script && !window) {
        fprintf(stderr, "mts-client: --script drives the window: it needs --window\n");
        return CLI_EXIT_USAGE;
    }
    if (window && (list || !rn.render || rn.png || rn.png_level_count || verify)) {
        fprintf(stderr, "mts-client: --window does not go with --list, --no-render, --png, "
                        "--png-levels or --verify (press s in the window for a picture)\n");
        return CLI_EXIT_USAGE;
    }
    if (rn.morph_ms >= 0 && !window) {
        fprintf(stderr, "mts-client: --morph-ms is the window's (headless frames are drawn at "
                        "whole levels)\n");
        return CLI_EXIT_USAGE;
    }
    if (window && !size_given) {
        rn.ro.width = 800;
        rn.ro.height = 600;
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
    if (window)
        return client_window_main(&rn, &so, script, json, &po);

    /* EGL comes up, and draws once, before connecting: the first frame of
     * the model should wait for the network, not for the driver (llvmpipe
     * compiles a shader variant at its first draw) */
    if (rn.render && !list &&
        (mts_render_context_create_headless(&rn.ctx, &rn.err) != MTS_OK ||
         !client_warm_up(&rn))) {
        fprintf(stderr, "mts-client: %s\n", rn.err.msg);
        mts_render_context_destroy(rn.ctx);
        return CLI_EXIT_FAIL;
    }
    uint32_t asked = 0, continuations = 0;
    uint64_t list_bytes = 0, full_bytes = 0;
    int stop_asked = !list && stops == 0 && po.kind != MTS_LOD_POLICY_RECEIVED &&
                     client_policy_stop(&so, &rn, &po, distance, &asked, &list_bytes, &full_bytes);
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
    uint32_t received = c.have_lod ? c.lod.level : 0;
    if (rn.have_view && c.have_lod && !c.lod.broken) {
        if (rc == MTS_OK)
            level_pngs(&rn, &c, 1);
        uint32_t final_level = MTS_VIEW_NEWEST;
        /* a stop distance or area asked for is their level already (the
         * server resolved it with the real counts, where the client has a
         * linear estimate): drawn as it came. budget times frames, and while
         * all that came fits, asks for what would (up to 8 times) */
        int pick = po.kind != MTS_LOD_POLICY_RECEIVED &&
                   (!stop_asked || po.kind == MTS_LOD_POLICY_BUDGET);
        for (int more = 0; pick && rc == MTS_OK; more++) {
            double want = 0;
            if (!apply_policy(&rn, &c, &po, distance, &final_level, &want)) {
                rc = rn.err.code ? rn.err.code : MTS_ERR_INTERNAL;
                err = rn.err;
                break;
            }
            if (!stop_asked || more == 8 || c.stop_level >= c.info.levels ||
                !(want > 1.1 * c.info.stop_triangles))
                break;
            uint32_t batch;
            uint64_t id;
            if ((rc = mts_stream_client_continue(&c, &batch, &id, &err)) != MTS_OK)
                break;
            so.hello.stop_kind = MTS_STOP_TRIANGLES;
            so.hello.stop_value = want > UINT32_MAX ? UINT32_MAX : (uint32_t)want;
            so.hello.resume_batch = batch;
            so.hello.stream_id = id;
            uint64_t before = st.bytes;
            rc = mts_session_run(&so, &c, &st, &err);
            st.bytes += before;
            continuations++;
            received = c.lod.level;
            final_level = MTS_VIEW_NEWEST;
        }
        if (draw(&rn, &c, final_level) && rn.png)
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
        mts_strip_stats ss;
        mts_lod_strip_stats(&c.lod, &ss);
        triangles = (uint32_t)ss.triangles;
    }
    if (json) {
        cli_json j;
        cli_json_begin(&j, stdout);
        cli_json_str(&j, "model", rn.model);
        cli_json_bool(&j, "complete", rc == MTS_OK);
        cli_json_u64(&j, "bytes", st.bytes);
        cli_json_u64(&j, "batches", c.batches);
        cli_json_str(&j, "form", c.records ? "records" : "splits");
        cli_json_u64(&j, "level", c.have_lod ? c.lod.level : 0);
        cli_json_u64(&j, "levels", c.info.levels);
        if (po.kind != MTS_LOD_POLICY_RECEIVED) {
            cli_json_str(&j, "lod_policy", mts_lod_policy_name(po.kind));
            cli_json_u64(&j, "level_received", received);
            /* the stop it asked for, the listing that told it the model's
             * size, and what the whole stream would have cost */
            cli_json_bool(&j, "stop_asked", stop_asked);
            if (stop_asked) {
                cli_json_u64(&j, "triangles_asked", asked);
                cli_json_u64(&j, "continuations", continuations);
                cli_json_u64(&j, "list_bytes", list_bytes);
                cli_json_u64(&j, "full_stream_bytes", full_bytes);
            }
        }
        cli_json_u64(&j, "triangles", triangles);
        client_json_run(&j, &c, &st, &rn);
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
        if (po.kind != MTS_LOD_POLICY_RECEIVED && stop_asked)
            printf("  lod policy %s: asked for %u triangles, %llu of the whole stream's %llu "
                   "bytes\n",
                   mts_lod_policy_name(po.kind), asked, (unsigned long long)st.bytes,
                   (unsigned long long)full_bytes);
        else if (po.kind != MTS_LOD_POLICY_RECEIVED)
            printf("  lod policy %s: level %u of %u received\n", mts_lod_policy_name(po.kind),
                   c.lod.level, received);
        for (uint32_t i = 0; i < rn.pngs_written && i < 8; i++)
            printf("  wrote %s\n", rn.png_paths[i]);
        if (verified == 1)
            printf("  verified: checksum%s match\n", model_file ? ", strips and positions" : "");
    }
    if (rc != MTS_OK)
        fprintf(stderr, "mts-client: %s\n", err.msg);
    mts_view_free(&rn.view);
    mts_render_context_destroy(rn.ctx);
    mts_stream_client_free(&c);
    return rc == MTS_OK ? CLI_EXIT_OK : CLI_EXIT_FAIL;
}
