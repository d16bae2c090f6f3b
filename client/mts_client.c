/* mts-client: streams a model from an mts-server, applies every batch as it
 * arrives and renders headless (EGL) at the level received -- or, with
 * --window (mts_client_window.c), shows it in an X11 window the user can
 * turn, zoom and move through the levels of, while the stream goes on. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "fetch.h"
#include "lodpolicy.h"
#include "mts_client.h"
#include "run.h"
#include "stream.h"
#include "webfile.h"
#include "wire.h"
#include "words.h"

static void usage(FILE *f)
{
    fputs("usage: mts-client [HOST[:PORT]] MODEL [--level L | --triangles N | --fraction F]\n"
          "       mts-client http(s)://HOST/PATH/NAME.mts [the same options]\n"
          "                  [--cacert FILE] [--max-file-bytes N]\n"
          "       mts-client HOST:PORT MODEL --tls [--cacert FILE] [the same options]\n"
          "                  [--png FILE] [--png-levels L1,L2,...] [--size WxH] [--color-strips]\n"
          "                  [--no-colors]\n"
          "                  [--verify] [--model-file M.mtsm] [--no-render] [--records]\n"
          "                  [--resume] [--retries N] [--connect-timeout S] [--timeout S]\n"
          "                  [--max-time S] [--lod-policy P [--fps N] [--distance D]]\n"
          "                  [--threads N] [--json] [--quiet]\n"
          "       mts-client [HOST[:PORT]] MODEL --window [--size WxH] [--script FILE]\n"
          "                  [--color-strips] [--no-colors] [--level L | ...] [--lod-policy P]\n"
          "                  [--resume]\n"
          "                  [--morph-ms MS] [--json]\n"
          "       mts-client [HOST[:PORT]] --list\n"
          "\n"
          "Streams MODEL from an mts-server (default 127.0.0.1:7447): a Draco base mesh,\n"
          "then batches of strip records applied as they arrive, rendered headless.\n"
          "Or reads a stream file (mts-build --stream) from any web server with HTTP\n"
          "range requests: the index, then the base and batches up to the stop, decoded\n"
          "as they arrive; --resume and the window's continuation ask for the batches\n"
          "not held. Or, with --tls, the TCP stream inside TLS, from a TLS terminator\n"
          "(nginx's stream module) in front of mts-server. TLS is verified against the\n"
          "system's CAs.\n"
          "\n"
          "  --level L / --triangles N / --fraction F   stop there (default: full)\n"
          "  --png FILE          write the final frame\n"
          "  --png-levels LIST   also write FILE-stem_L<level>.png at each listed level\n"
          "                      (MODEL_L<level>.png without --png)\n"
          "  --size WxH          frame size (default 512x512)\n"
          "  --color-strips      each strip in its own colour\n"
          "  --no-colors         grey even where the model has vertex colours (drawn by\n"
          "                      default; --json's colors says whether they were)\n"
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
          "  --tls               the server's port speaks TLS (a terminator in front of\n"
          "                      mts-server, as docker/nginx-tls.conf sets up)\n"
          "  --cacert FILE       for https and --tls: trust the CAs in FILE (PEM) instead of the\n"
          "                      system's (a private CA); verification is never skipped\n"
          "  --max-file-bytes N  refuse a stream file over N bytes (K, M, G; default 1G)\n"
          "  --threads N         threads that decode the stream (default 2 where 2 or more\n"
          "                      processors are online, else 1; more decode as 2, which is\n"
          "                      faster on any number of cores: docs/threads.md); the mesh\n"
          "                      is the same whatever N (--json: threads, threads_asked)\n"
          "  --list              print the server's models\n"
          "  --json              one line of JSON with the figures\n"
          "  -q, --quiet         no progress, no summary\n"
          "\n"
          "Exit status: 0 complete, 1 failed (the last whole batch is still drawn;\n"
          "with --resume, after the last try), 2 bad usage.\n",
          f);
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

/* The command line's options, one by one, into *o. Returns -1 to go on, or
 * the exit status: --help, or bad usage (said on stderr). */
static int parse_args(int argc, char **argv, client_options *o)
{
    memset(o, 0, sizeof *o);
    mts_client_run *rn = &o->run;
    rn->render = 1;
    rn->morph_ms = -1;
    rn->distance = 1;
    /* two decoding threads where two or more processors are online: on two
     * free cores they decode bunny00 and the 1.2M mesh in some 0.5x to
     * 0.7x one thread's time (docs/threads.md); the decoder takes no more
     * (stream.h, threads) */
    const long online = sysconf(_SC_NPROCESSORS_ONLN);
    rn->threads = online >= 2 ? 2 : 1;
    mts_render_options_default(&rn->ro);
    o->so.hello.stop_kind = MTS_STOP_FULL;
    int stop;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) {
            usage(stdout);
            return CLI_EXIT_OK;
        } else if (!strcmp(a, "--json")) {
            o->json = 1;
        } else if (!strcmp(a, "-q") || !strcmp(a, "--quiet")) {
            o->quiet = 1;
        } else if (!strcmp(a, "--verify")) {
            rn->verify = 1;
        } else if (!strcmp(a, "--list")) {
            o->list = 1;
        } else if (!strcmp(a, "--no-render")) {
            rn->render = 0;
        } else if (!strcmp(a, "--threads")) {
            if (!cli_option_u32(argc, argv, &i, "mts-client", 1, 64, &rn->threads))
                return CLI_EXIT_USAGE;
        } else if (!strcmp(a, "--records")) {
            o->so.hello.flags |= MTS_HELLO_RECORDS;
        } else if (!strcmp(a, "--window")) {
            o->window = 1;
        } else if (!strcmp(a, "--tls")) {
            o->tls = 1;
        } else if (!strcmp(a, "--cacert")) {
            if (!v) {
                fprintf(stderr, "mts-client: --cacert needs a PEM file\n");
                return CLI_EXIT_USAGE;
            }
            o->cacert = v;
            i++;
        } else if (!strcmp(a, "--max-file-bytes")) {
            if (!v || !cli_parse_bytes(v, &o->max_file_bytes) || o->max_file_bytes == 0) {
                fprintf(stderr, "mts-client: --max-file-bytes needs a size in bytes above 0 "
                                "(512M, 4G)\n");
                return CLI_EXIT_USAGE;
            }
            i++;
        } else if (!strcmp(a, "--script")) {
            if (!v) {
                fprintf(stderr, "mts-client: --script needs a file name\n");
                return CLI_EXIT_USAGE;
            }
            o->script = v;
            i++;
        } else if (!strcmp(a, "--connect-timeout") || !strcmp(a, "--timeout") ||
                   !strcmp(a, "--max-time")) {
            double *dst = !strcmp(a, "--connect-timeout") ? &o->so.connect_timeout
                          : !strcmp(a, "--timeout")       ? &o->so.io_timeout
                                                          : &o->so.max_time;
            if (!v || !cli_parse_double(v, dst) || !(*dst > 0) || *dst > 1e6) {
                fprintf(stderr, "mts-client: %s needs a number of seconds above 0\n", a);
                return CLI_EXIT_USAGE;
            }
            i++;
        } else if (!strcmp(a, "--morph-ms")) {
            if (!v || !cli_parse_double(v, &rn->morph_ms) || !(rn->morph_ms >= 0) ||
                rn->morph_ms > 60000) {
                fprintf(stderr, "mts-client: --morph-ms needs milliseconds from 0 to 60000\n");
                return CLI_EXIT_USAGE;
            }
            i++;
        } else if (!strcmp(a, "--resume")) {
            o->so.resume = 1;
        } else if (!strcmp(a, "--retries")) {
            if (!v || !cli_parse_u32(v, &o->so.max_tries) || o->so.max_tries < 1 ||
                o->so.max_tries > 1000) {
                fprintf(stderr, "mts-client: --retries needs a whole number from 1 to 1000\n");
                return CLI_EXIT_USAGE;
            }
            i++;
        } else if (!strcmp(a, "--color-strips")) {
            rn->ro.style.color_by_strip = 1;
        } else if (!strcmp(a, "--no-colors")) {
            rn->no_colors = 1;
        } else if (!strcmp(a, "--lod-policy")) {
            if (!v || !mts_lod_policy_parse(v, &rn->po.kind)) {
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
            *(!strcmp(a, "--fps") ? &rn->po.fps : &rn->distance) = x;
            i++;
        } else if ((stop = cli_option_stop(argc, argv, &i, "mts-client", &o->so.hello.stop_kind,
                                           &o->so.hello.stop_value))) {
            if (stop < 0)
                return CLI_EXIT_USAGE;
            o->stops++;
        } else if (!strcmp(a, "--png") || !strcmp(a, "--model-file")) {
            if (!v) {
                fprintf(stderr, "mts-client: %s needs a file name\n", a);
                return CLI_EXIT_USAGE;
            }
            if (!strcmp(a, "--png"))
                rn->png = v;
            else
                rn->model_file = v;
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
                if (!cli_parse_u32(tok, &l) || rn->png_level_count >= 64) {
                    fprintf(stderr, "mts-client: --png-levels: '%s' is not a level\n", tok);
                    return CLI_EXIT_USAGE;
                }
                rn->png_levels[rn->png_level_count++] = l;
            }
            qsort(rn->png_levels, (size_t)rn->png_level_count, 4, mts_words_cmp);
            i++;
        } else if (!strcmp(a, "--size")) {
            if (!v || !parse_size(v, &rn->ro.width, &rn->ro.height)) {
                fprintf(stderr, "mts-client: --size needs WxH, each 16..8192\n");
                return CLI_EXIT_USAGE;
            }
            o->size_given = 1;
            i++;
        } else if (a[0] == '-' && a[1]) {
            fprintf(stderr, "mts-client: unknown option %s (see --help)\n", a);
            return CLI_EXIT_USAGE;
        } else if (o->npos < 2) {
            o->pos[o->npos++] = a;
        } else {
            fprintf(stderr, "mts-client: too many arguments (see --help)\n");
            return CLI_EXIT_USAGE;
        }
    }
    return -1;
}

/* The model's name from a stream file's URL: its last path segment without
 * ".mts" (for the PNGs' names and the summary), "stream" when that is no
 * model name. */
static void name_of_url(const char *url, char *out, size_t size)
{
    const char *end = url + strcspn(url, "?#");
    const char *start = end;
    while (start > url && start[-1] != '/')
        start--;
    size_t n = (size_t)(end - start);
    if (n > 4 && !memcmp(end - 4, ".mts", 4))
        n -= 4;
    if (n == 0 || n >= size || !mts_wire_valid_name(start, n))
        snprintf(out, size, "stream");
    else
        snprintf(out, size, "%.*s", (int)n, start);
}

/* mts-client URL: the stream file's options. */
static int check_url(client_options *o)
{
    if (o->list || o->npos != 1) {
        fprintf(stderr, "mts-client: a stream file's URL is the only argument (no --list, no "
                        "HOST)\n");
        return CLI_EXIT_USAGE;
    }
    if (o->so.hello.flags & MTS_HELLO_RECORDS) {
        fprintf(stderr, "mts-client: --records asks mts-server for a form; a stream file holds "
                        "the one it was written in (mts-build --stream FILE --records)\n");
        return CLI_EXIT_USAGE;
    }
    o->url = o->pos[0];
    name_of_url(o->url, o->url_name, sizeof o->url_name);
    o->run.model = o->url_name;
    snprintf(o->so.hello.model, sizeof o->so.hello.model, "%s", o->url_name);
    return -1;
}

/* What the options mean together: the combinations refused, the settings
 * they imply, the model and the server. Returns -1 to go on, or the exit
 * status of bad usage (said on stderr). */
static int check_options(client_options *o)
{
    mts_client_run *rn = &o->run;
    if (rn->po.kind != MTS_LOD_POLICY_RECEIVED && !rn->render) {
        fprintf(stderr, "mts-client: --lod-policy draws: it cannot go with --no-render\n");
        return CLI_EXIT_USAGE;
    }
    rn->ro.camera.zoom = (float)(1 / rn->distance);
    /* budget reads frame times: frames that are waited for */
    rn->ro.timed = rn->po.kind == MTS_LOD_POLICY_BUDGET;
    if (o->stops > 1) {
        fprintf(stderr, "mts-client: give one of --level, --triangles, --fraction\n");
        return CLI_EXIT_USAGE;
    }
    if (o->script && !o->window) {
        fprintf(stderr, "mts-client: --script drives the window: it needs --window\n");
        return CLI_EXIT_USAGE;
    }
    if (o->window && (o->list || !rn->render || rn->png || rn->png_level_count || rn->verify)) {
        fprintf(stderr, "mts-client: --window does not go with --list, --no-render, --png, "
                        "--png-levels or --verify (press s in the window for a picture)\n");
        return CLI_EXIT_USAGE;
    }
    if (rn->morph_ms >= 0 && !o->window) {
        fprintf(stderr, "mts-client: --morph-ms is the window's (headless frames are drawn at "
                        "whole levels)\n");
        return CLI_EXIT_USAGE;
    }
    if (o->window && !o->size_given) {
        rn->ro.width = 800;
        rn->ro.height = 600;
    }
    const char *server = NULL;
    if (o->npos >= 1 && mts_fetch_is_url(o->pos[o->npos - 1])) {
        if (o->tls) {
            fprintf(stderr, "mts-client: --tls is for HOST:PORT (a URL says https itself)\n");
            return CLI_EXIT_USAGE;
        }
        return check_url(o);
    }
    if (o->max_file_bytes || (o->cacert && !o->tls)) {
        fprintf(stderr, "mts-client: --max-file-bytes is for a stream file's URL, --cacert for "
                        "one or for --tls\n");
        return CLI_EXIT_USAGE;
    }
    if (o->tls) {
        o->tls_options.cacert = o->cacert;
        o->tls_options.connect_timeout = o->so.connect_timeout;
        o->so.tls = &o->tls_options;
    }
    if (o->list) {
        if (o->npos > 1) {
            fprintf(stderr, "mts-client: --list takes only HOST[:PORT]\n");
            return CLI_EXIT_USAGE;
        }
        server = o->npos ? o->pos[0] : NULL;
    } else {
        if (o->npos == 0) {
            usage(stderr);
            return CLI_EXIT_USAGE;
        }
        server = o->npos == 2 ? o->pos[0] : NULL;
        rn->model = o->pos[o->npos - 1];
        if (!mts_wire_valid_name(rn->model, strlen(rn->model))) {
            fprintf(stderr, "mts-client: '%s' is not a model name ([A-Za-z0-9._-], 1..64)\n",
                    rn->model);
            return CLI_EXIT_USAGE;
        }
        snprintf(o->so.hello.model, sizeof o->so.hello.model, "%s", rn->model);
    }
    snprintf(o->host, sizeof o->host, "127.0.0.1");
    snprintf(o->port, sizeof o->port, "7447");
    if (server && !cli_parse_server(server, o->host, sizeof o->host, o->port, sizeof o->port)) {
        fprintf(stderr, "mts-client: bad address %s (HOST[:PORT])\n", server);
        return CLI_EXIT_USAGE;
    }
    o->so.host = o->host;
    o->so.port = o->port;
    o->so.list = o->list;
    return -1;
}

/* The session's events: the progress bar and a resumed stream said on
 * stderr, then the run's frames and PNGs (run.h). */
static int on_event(void *user, mts_stream_event ev, mts_stream_client *c)
{
    client_options *o = user;
    if (ev == MTS_EV_RESUMED && !o->quiet && !c->continuing) {
        cli_bar_done(&o->bar);
        fprintf(stderr, "mts-client: reconnected; resuming at batch %u of %u\n", c->batches,
                c->info.batch_count);
    }
    if (ev == MTS_EV_INFO)
        cli_bar_update(&o->bar, "stream", 0);
    else if (ev == MTS_EV_BATCH)
        cli_bar_update(&o->bar, "stream",
                       c->stop_level ? (double)c->lod.level / c->stop_level : 1.0);
    return mts_client_run_on_event(&o->run, ev, c);
}

/* --resume: the session waits and tries again; say so on stderr. */
static int on_retry(void *user, const mts_session_retry *r)
{
    client_options *o = user;
    if (o->quiet)
        return 0;
    cli_bar_done(&o->bar);
    if (r->have_base)
        fprintf(stderr, "mts-client: connection lost at batch %u (%s); retrying in %.2f s "
                        "(try %u/%u)\n",
                r->batches, r->reason, r->delay, r->attempt, r->max_tries);
    else
        fprintf(stderr, "mts-client: %s; retrying in %.2f s (try %u/%u)\n", r->reason, r->delay,
                r->attempt, r->max_tries);
    return 0;
}

static void print_model(void *user, const mts_wire_model_entry *m)
{
    (void)user;
    printf("%-24s %9u vertices %9u triangles %9u levels %10u stream bytes\n", m->name,
           m->vertices, m->triangles, m->levels, m->stream_bytes);
}

/* The headless run's summary on stdout: --json's line, or a few lines of
 * text unless quiet. */
static void print_summary(const client_options *o, const mts_stream_client *c,
                          const mts_session_stats *st, const mts_client_run_result *res,
                          mts_result rc, const mts_error *err)
{
    const mts_client_run *rn = &o->run;
    const mts_lod_policy_options *po = &rn->po;
    if (o->json) {
        cli_json j;
        cli_json_begin(&j, stdout);
        mts_client_run_json_head(&j, rn, c, rc == MTS_OK, st->bytes);
        if (po->kind != MTS_LOD_POLICY_RECEIVED) {
            cli_json_str(&j, "lod_policy", mts_lod_policy_name(po->kind));
            cli_json_u64(&j, "level_received", res->received);
            /* the stop it asked for, the listing that told it the model's
             * size, and what the whole stream would have cost */
            cli_json_bool(&j, "stop_asked", res->stop_asked);
            if (res->stop_asked) {
                cli_json_u64(&j, "triangles_asked", res->stop.asked);
                cli_json_u64(&j, "continuations", res->continuations);
                cli_json_u64(&j, "list_bytes", res->stop.list_bytes);
                cli_json_u64(&j, "full_stream_bytes", res->stop.full_bytes);
            }
        }
        mts_client_run_json(&j, c, st, rn);
        if (o->so.file && mts_webfile_http_version(o->so.file) > 0)
            cli_json_u64(&j, "http_version", (uint64_t)mts_webfile_http_version(o->so.file));
        if (res->verified >= 0)
            cli_json_bool(&j, "verified", res->verified);
        if (rc != MTS_OK)
            cli_json_str(&j, "error", err->msg);
        cli_json_end(&j);
    } else if (!o->quiet && c->have_lod) {
        printf("%s: level %u of %u, %u triangles, %u batches, %llu bytes in %.1f ms "
               "(base drawn at %.1f ms; decode+apply %.1f ms, render %.1f ms)\n",
               rn->model, c->have_lod ? c->lod.level : 0, c->info.levels,
               mts_client_run_triangles(c), c->batches, (unsigned long long)st->bytes,
               st->ms_final ? st->ms_final : 0, st->ms_base, st->ms_apply, rn->ms_render);
        if (po->kind != MTS_LOD_POLICY_RECEIVED && res->stop_asked)
            printf("  lod policy %s: asked for %u triangles, %llu of the whole stream's %llu "
                   "bytes\n",
                   mts_lod_policy_name(po->kind), res->stop.asked, (unsigned long long)st->bytes,
                   (unsigned long long)res->stop.full_bytes);
        else if (po->kind != MTS_LOD_POLICY_RECEIVED)
            printf("  lod policy %s: level %u of %u received\n", mts_lod_policy_name(po->kind),
                   c->lod.level, res->received);
        for (uint32_t i = 0; i < rn->pngs_written && i < 8; i++)
            printf("  wrote %s\n", rn->png_paths[i]);
        if (res->verified == 1)
            printf("  verified: checksum%s match\n",
                   rn->model_file ? ", strips and positions" : "");
    }
}

/* Headless (and --list): EGL up and warmed before connecting, a camera
 * policy's stop asked, the stream, then what the run draws and writes after
 * it (run.h), the summary and the exit status. */
static int run_headless(client_options *o)
{
    mts_client_run *rn = &o->run;
    o->so.on_event = on_event;
    o->so.on_retry = on_retry;
    o->so.user = o;
    cli_bar_init(&o->bar, o->quiet || o->json || o->list);
    /* EGL comes up, and draws once, before connecting: the first frame of
     * the model should wait for the network, not for the driver (llvmpipe
     * compiles a shader variant at its first draw) */
    if (rn->render && !o->list &&
        (mts_render_context_create_headless(&rn->ctx, &rn->err) != MTS_OK ||
         !mts_client_run_warm_up(rn))) {
        fprintf(stderr, "mts-client: %s\n", rn->err.msg);
        mts_render_context_destroy(rn->ctx);
        return CLI_EXIT_FAIL;
    }
    mts_client_run_result res = {0};
    res.stop_asked = !o->list && o->stops == 0 && rn->po.kind != MTS_LOD_POLICY_RECEIVED &&
                     mts_client_run_policy_stop(&o->so, rn, rn->distance, &res.stop);
    mts_stream_client c;
    mts_stream_client_init(&c);
    c.threads = rn->threads;
    c.on_model = print_model;
    mts_session_stats st;
    mts_error err = {0};
    mts_result rc = mts_session_run(&o->so, &c, &st, &err);
    cli_bar_done(&o->bar);
    if (o->list) {
        if (rc != MTS_OK)
            fprintf(stderr, "mts-client: %s\n", err.msg);
        mts_stream_client_free(&c);
        return rc == MTS_OK ? CLI_EXIT_OK : CLI_EXIT_FAIL;
    }
    rc = mts_client_run_finish(rn, &o->so, &c, &st, rc, &res, &err);
    print_summary(o, &c, &st, &res, rc, &err);
    if (rc != MTS_OK)
        fprintf(stderr, "mts-client: %s\n", err.msg);
    mts_client_run_free(rn);
    mts_stream_client_free(&c);
    return rc == MTS_OK ? CLI_EXIT_OK : CLI_EXIT_FAIL;
}

/* A stream file's URL: libcurl, and the file the sessions read from. */
static int open_url(client_options *o)
{
    mts_error err = {0};
    mts_http_options ho = {0};
    ho.cacert = o->cacert;
    ho.connect_timeout = o->so.connect_timeout > 0 ? o->so.connect_timeout : 5;
    ho.io_timeout = o->so.io_timeout;
    ho.max_bytes = o->max_file_bytes;
    if (mts_fetch_global_init(&err) != MTS_OK ||
        mts_webfile_create(&o->so.file, o->url, &ho, &err) != MTS_OK) {
        fprintf(stderr, "mts-client: %s\n", err.msg);
        return 0;
    }
    return 1;
}

int main(int argc, char **argv)
{
    client_options o;
    int status = parse_args(argc, argv, &o);
    if (status < 0)
        status = check_options(&o);
    if (status >= 0)
        return status;
    /* A fresh client touches its whole model once, so its heap goes on huge
     * pages (cli.h). 256 MB of address space holds the heap of a 1.2M-
     * triangle model (its large arrays live in reservations of their own);
     * past it the heap grows in 4 KB pages as before. */
    cli_heap_on_huge_pages((size_t)256 << 20);
    if (o.url && !open_url(&o))
        return CLI_EXIT_FAIL;
    if (o.tls) {
        mts_error err = {0};
        if (mts_fetch_global_init(&err) != MTS_OK) {
            fprintf(stderr, "mts-client: %s\n", err.msg);
            return CLI_EXIT_FAIL;
        }
    }
    status = o.window ? client_window_main(&o) : run_headless(&o);
    if (o.url || o.tls) {
        mts_webfile_free(o.so.file);
        mts_fetch_global_cleanup();
    }
    return status;
}
