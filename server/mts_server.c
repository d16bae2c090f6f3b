/* mts-server: streams multiresolution strip models to many clients. */
#include <errno.h>
#include <stdatomic.h>
#include <unistd.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "catalog.h"
#include "cli.h"
#include "fetch.h"
#include "server.h"
#include "stream.h"

static void usage(FILE *f)
{
    fputs("usage: mts-server [--models DIR] [--model NAME=PATH|URL]... [--listen ADDR:PORT]\n"
          "                  [--ws-listen ADDR:PORT] [--max-clients N]\n"
          "                  [--idle-timeout S]\n"
          "                  [--handshake-timeout S] [--grace S] [--max-download BYTES]\n"
          "                  [--max-mesh-bytes N]\n"
          "                  [--fetch-timeout S] [--fetch-connect-timeout S] [--workers N]\n"
          "                  [--rate-limit BYTES/S] [--sndbuf BYTES] [--stats-interval S]\n"
          "                  [--prepare-threads N] [--prepare-wait S] [--no-records-form]\n"
          "                  [--quiet]\n"
          "\n"
          "Serves every .mtsm in DIR and every mesh there (built once and cached), each\n"
          "named by its file stem, plus models given one by one (a file, or an http(s)\n"
          "URL fetched and built). Clients get a Draco base mesh, then batches of strip\n"
          "records (docs/PROTOCOL.md): each batch's vertex splits, range-coded, from\n"
          "which the client derives the records, or where the client asks (mts-client\n"
          "--records) the records themselves. It listens as soon as the models are loaded\n"
          "and encodes their streams meanwhile: a client asking for one not ready yet\n"
          "waits for it.\n"
          "\n"
          "  --models DIR           a directory of models and meshes\n"
          "  --model NAME=SOURCE    one model: a .mtsm, a mesh file or an http(s) URL\n"
          "  --listen ADDR:PORT     default 127.0.0.1:7447\n"
          "  --ws-listen ADDR:PORT  also serve WebSocket clients (browsers) there: the same\n"
          "                         conversation in binary messages, the same limits\n"
          "                         (the page itself comes from a web server in front,\n"
          "                         which also proxies this port: web/nginx.conf)\n"
          "  --max-clients N        connections at once per worker (default 1024); more get\n"
          "                         ERROR busy\n"
          "  --idle-timeout S       drop a connection that takes no bytes for S s (default 30)\n"
          "  --handshake-timeout S  drop a client that sends no HELLO for S s (default 10)\n"
          "  --grace S              on SIGTERM/SIGINT, let streams finish for S s (default 5)\n"
          "  --max-download BYTES   size cap for URL models (default 268435456)\n"
          "  --max-mesh-bytes N     size cap of every mesh or model file read, and of a\n"
          "                         download too; a bigger one is skipped, by name, before\n"
          "                         it is read (bytes, or with K, M, G: 512M; default 4G)\n"
          "  --fetch-connect-timeout S  a URL model's connect may take S s (default 10)\n"
          "  --fetch-timeout S      a URL model's whole download may take S s (default 60)\n"
          "  --workers N            N event loops on N threads sharing the port through\n"
          "                         SO_REUSEPORT and the streams in memory (default 1)\n"
          "  --rate-limit BYTES/S   pace each connection (a realistic preview); default none\n"
          "  --sndbuf BYTES         each connection's kernel send buffer (default: autotuned,\n"
          "                         up to 4 MiB each on Linux); bounds kernel memory\n"
          "  --stats-interval S     a 'stats:' log line every S s per worker: connections,\n"
          "                         peak, outcomes, MB/s out, resident memory\n"
          "  --prepare-threads N    threads encoding the models' streams after start-up\n"
          "                         (default: one per core but one, at least 1)\n"
          "  --prepare-wait S       a client asking for a model still being encoded waits up\n"
          "                         to S s, then gets ERROR busy (default 60)\n"
          "  --no-records-form      keep only the splits form of each stream (a client that\n"
          "                         asks for records gets splits): saves memory, about 16x\n"
          "                         the splits form's bytes per model\n"
          "  -q, --quiet            no per-connection log lines, no progress bar, no line\n"
          "                         per model loaded or encoded (failures, warnings and the\n"
          "                         listening, stats and stopped lines stay)\n"
          "  -h, --help             this help\n"
          "\n"
          "Exit status: 0 after a clean stop, 1 when no model could be served, the\n"
          "address cannot be used or a stop came while the models were loading, 2 bad\n"
          "usage.\n",
          f);
}

/* set by the signal handler, read by the workers and the thread that
 * prepares the models: atomics, which a handler may store to (lock-free) */
static atomic_int stop_requested, serving;
_Static_assert(ATOMIC_INT_LOCK_FREE == 2, "a signal handler stores to an atomic_int");

/* Serving, a stop lets streams finish (the workers poll the flag). Before
 * that nothing is served and a model's build cannot stop part-way, so a
 * stop while models load ends the process at once, with status 1 and a
 * line that says so, not killed by the signal (a cache being written is a
 * temporary file until it is whole: fileio.c). */
static void on_signal(int sig)
{
    (void)sig;
    if (!serving) {
        static const char msg[] = "mts-server: stopped while loading models; nothing served\n";
        ssize_t w = write(STDERR_FILENO, msg, sizeof msg - 1);
        (void)w;
        _exit(CLI_EXIT_FAIL);
    }
    stop_requested = 1;
}

/* --quiet drops the per-connection lines only: stats, notices and the
 * listening and stopped lines are what an operator watches. */
static void log_line(void *user, mts_server_log_kind kind, const char *line)
{
    if (*(int *)user && kind == MTS_SERVER_LOG_CONNECTION)
        return;
    char stamp[32];
    time_t now = time(NULL);
    struct tm tm;
    strftime(stamp, sizeof stamp, "%Y-%m-%dT%H:%M:%S", gmtime_r(&now, &tm));
    fprintf(stderr, "%s %s\n", stamp, line);
}

static void report(void *user, mts_catalog_report_kind kind, const char *file, const char *msg)
{
    if (kind == MTS_CATALOG_ADDED && *(int *)user)
        return;
    const char *what = kind == MTS_CATALOG_FAILED    ? "failed"
                       : kind == MTS_CATALOG_SKIPPED ? "skipped"
                       : kind == MTS_CATALOG_NOTE    ? "note"
                                                     : "added";
    fprintf(stderr, "mts-server: %s: %s: %s\n", what, file, msg);
}

static int parse_seconds(const char *s, double *out)
{
    return cli_parse_double(s, out) && *out > 0;
}

/* Every connection is a descriptor: raise the soft limit toward what the
 * connection limits need, and say so when the hard limit is too low. */
static void raise_nofile(uint64_t need, int quiet)
{
    uint64_t now, hard;
    need += 64; /* listeners, epoll, logs, model files */
    if (cli_raise_nofile(need, &now, &hard) && !quiet)
        fprintf(stderr, "mts-server: open-file limit raised to %llu\n", (unsigned long long)now);
    if (now < need)
        fprintf(stderr,
                "mts-server: warning: the open-file limit (hard %llu) is below the %llu "
                "descriptors --max-clients needs; clients over it wait in the accept queue "
                "(raise it with ulimit -Hn or LimitNOFILE=)\n",
                (unsigned long long)hard, (unsigned long long)need);
}

typedef struct worker {
    mts_server *server;
    mts_error err;
    mts_result rc;
    pthread_t thread;
} worker;

static void *worker_main(void *arg)
{
    worker *w = arg;
    w->rc = mts_server_run(w->server, &stop_requested, &w->err);
    return NULL;
}

/* The threads that encode the models' streams while the servers listen:
 * each takes the next model, publishes its stream (or why it failed) into
 * the table the servers read, and lets the catalog's copy of the model go. */
typedef struct preparer {
    mts_catalog *cat;
    mts_server_model *models;
    mts_stream *streams; /* zeroed: mts_stream_free is safe on any of them */
    uint32_t count;
    atomic_uint next, done, ok;
    int no_records, quiet;
    atomic_int failed_all;
} preparer;

static void *prepare_main(void *arg)
{
    preparer *p = arg;
    for (;;) {
        uint32_t i = atomic_fetch_add(&p->next, 1);
        if (i >= p->count || stop_requested)
            return NULL;
        const mts_catalog_entry *e = mts_catalog_at(p->cat, i);
        mts_stream_options sto = {0};
        sto.cancel = &stop_requested; /* the records form follows, once this is served */
        mts_error err = {0};
        const double t0 = cli_now();
        int ok = mts_stream_build(&e->model, e->name, &sto, &p->streams[i], &err) == MTS_OK;
        if (!ok) {
            if (!stop_requested)
                fprintf(stderr, "mts-server: %s: cannot encode its stream: %s\n", e->name,
                        err.msg);
            mts_server_model_fail(&p->models[i], err.msg);
        } else {
            mts_stream *st = &p->streams[i];
            mts_server_model_publish(&p->models[i], st);
            const double t1 = cli_now();
            if (!p->quiet)
                fprintf(stderr,
                        "mts-server: serving %s: %u vertices, %u levels, %zu stream bytes, "
                        "encoded in %.2f s\n",
                        e->name, e->model.vertex_count, e->model.level_count, st->size,
                        t1 - t0);
            if (p->no_records || stop_requested) {
                mts_server_model_publish_records(&p->models[i], NULL);
            } else {
                if (mts_stream_add_records_form(st, &err) != MTS_OK) {
                    fprintf(stderr, "mts-server: %s: no records form (%s); splits form only\n",
                            e->name, err.msg);
                    mts_server_model_publish_records(&p->models[i], NULL);
                } else {
                    mts_server_model_publish_records(&p->models[i], st->records_form);
                    if (!p->quiet)
                        fprintf(stderr, "mts-server: %s: records form ready, %zu bytes\n",
                                e->name, st->records_form->size);
                }
            }
        }
        /* the stream holds its own copy of the model */
        mts_catalog_release_model(p->cat, i);
        /* ok counts before done does, so whoever ends the count sees them all */
        if (ok)
            atomic_fetch_add(&p->ok, 1);
        if (atomic_fetch_add(&p->done, 1) + 1 == p->count && atomic_load(&p->ok) == 0 &&
            !stop_requested) {
            fprintf(stderr, "mts-server: no model could be encoded; stopping\n");
            atomic_store(&p->failed_all, 1);
            stop_requested = 1;
        }
    }
}

int main(int argc, char **argv)
{
    const char *dirs[64], *models[64];
    int ndirs = 0, nmodels = 0, quiet = 0, no_records = 0;
    uint32_t nworkers = 1, nprepare = 0;
    mts_server_options so = {0};
    mts_catalog_options co = {0};
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) {
            usage(stdout);
            return CLI_EXIT_OK;
        } else if (!strcmp(a, "-q") || !strcmp(a, "--quiet")) {
            quiet = 1;
            continue;
        } else if (!strcmp(a, "--no-records-form")) {
            no_records = 1;
            continue;
        }
        if (!v) {
            fprintf(stderr, "mts-server: %s needs a value (see --help)\n", a);
            return CLI_EXIT_USAGE;
        }
        i++;
        if (!strcmp(a, "--models") && ndirs < 64) {
            dirs[ndirs++] = v;
        } else if (!strcmp(a, "--model") && nmodels < 64) {
            models[nmodels++] = v;
        } else if (!strcmp(a, "--listen")) {
            so.listen = v;
        } else if (!strcmp(a, "--ws-listen")) {
            so.ws_listen = v;
        } else if (!strcmp(a, "--web-root")) {
            /* files are a web server's job (confined paths, sendfile, ranges,
             * caching): say where that went rather than "unknown option" */
            fprintf(stderr, "mts-server: --web-root is gone: serve the page (%s) with a web "
                            "server in front of --ws-listen, as web/nginx.conf does "
                            "(make demo-web)\n", v);
            return CLI_EXIT_USAGE;
        } else if (!strcmp(a, "--max-clients")) {
            if (!cli_parse_u32(v, &so.max_clients) || so.max_clients == 0) {
                fprintf(stderr, "mts-server: --max-clients needs a positive number\n");
                return CLI_EXIT_USAGE;
            }
        } else if (!strcmp(a, "--prepare-threads")) {
            if (!cli_parse_u32(v, &nprepare) || nprepare == 0 || nprepare > 256) {
                fprintf(stderr, "mts-server: --prepare-threads needs a number from 1 to 256\n");
                return CLI_EXIT_USAGE;
            }
        } else if (!strcmp(a, "--idle-timeout") || !strcmp(a, "--handshake-timeout") ||
                   !strcmp(a, "--grace") || !strcmp(a, "--prepare-wait")) {
            double *s = !strcmp(a, "--idle-timeout")    ? &so.idle_timeout
                        : !strcmp(a, "--prepare-wait")  ? &so.prepare_wait
                        : !strcmp(a, "--handshake-timeout") ? &so.handshake_timeout
                                                            : &so.grace;
            if (!parse_seconds(v, s)) {
                fprintf(stderr, "mts-server: %s needs a positive number of seconds\n", a);
                return CLI_EXIT_USAGE;
            }
        } else if (!strcmp(a, "--workers")) {
            if (!cli_parse_u32(v, &nworkers) || nworkers == 0 || nworkers > 256) {
                fprintf(stderr, "mts-server: --workers needs a number from 1 to 256\n");
                return CLI_EXIT_USAGE;
            }
        } else if (!strcmp(a, "--rate-limit")) {
            if (!cli_parse_double(v, &so.rate_limit) || so.rate_limit < 1) {
                fprintf(stderr, "mts-server: --rate-limit needs bytes per second (>= 1)\n");
                return CLI_EXIT_USAGE;
            }
        } else if (!strcmp(a, "--sndbuf")) {
            uint32_t b;
            if (!cli_parse_u32(v, &b) || b < 4096 || b > (1u << 30)) {
                fprintf(stderr, "mts-server: --sndbuf needs bytes from 4096 to 2^30\n");
                return CLI_EXIT_USAGE;
            }
            so.sndbuf = (int)b;
        } else if (!strcmp(a, "--stats-interval")) {
            if (!parse_seconds(v, &so.stats_interval)) {
                fprintf(stderr, "mts-server: --stats-interval needs a positive number of seconds\n");
                return CLI_EXIT_USAGE;
            }
        } else if (!strcmp(a, "--max-download")) {
            double bytes;
            if (!cli_parse_double(v, &bytes) || bytes < 1) {
                fprintf(stderr, "mts-server: --max-download needs a size in bytes\n");
                return CLI_EXIT_USAGE;
            }
            co.fetch.max_bytes = (uint64_t)bytes;
        } else if (!strcmp(a, "--max-mesh-bytes")) {
            if (!cli_parse_bytes(v, &co.max_mesh_bytes) || co.max_mesh_bytes == 0) {
                fprintf(stderr, "mts-server: --max-mesh-bytes needs a size in bytes above 0 "
                                "(512M, 4G)\n");
                return CLI_EXIT_USAGE;
            }
        } else if (!strcmp(a, "--fetch-connect-timeout") || !strcmp(a, "--fetch-timeout")) {
            double secs;
            if (!parse_seconds(v, &secs) || secs > 86400) {
                fprintf(stderr, "mts-server: %s needs a number of seconds above 0\n", a);
                return CLI_EXIT_USAGE;
            }
            uint32_t ms = (uint32_t)(secs * 1000 + 0.5) ? (uint32_t)(secs * 1000 + 0.5) : 1;
            if (!strcmp(a, "--fetch-timeout"))
                co.fetch.timeout_ms = ms;
            else
                co.fetch.connect_timeout_ms = ms;
        } else {
            fprintf(stderr, "mts-server: unknown option %s (see --help)\n", a);
            return CLI_EXIT_USAGE;
        }
    }
    if (ndirs == 0 && nmodels == 0) {
        fprintf(stderr, "mts-server: give --models DIR or --model NAME=SOURCE (see --help)\n");
        return CLI_EXIT_USAGE;
    }

    signal(SIGPIPE, SIG_IGN);
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGINT, &sa, NULL);
    mts_error err = {0};
    mts_catalog *cat = NULL;
    mts_stream *streams = NULL;
    mts_server_model *table = NULL;
    worker *workers = NULL;
    pthread_t *preparers = NULL;
    preparer prep = {0};
    uint32_t created = 0, prepared = 0, count = 0;
    int status = CLI_EXIT_FAIL;
    cli_bar bar;
    cli_bar_init(&bar, quiet);
    co.progress = cli_bar_progress(&bar);
    if (mts_fetch_global_init(&err) != MTS_OK || mts_catalog_create(&co, &cat, &err) != MTS_OK)
        goto fail;
    mts_catalog_report rep = {report, &quiet};
    for (int i = 0; i < ndirs; i++) {
        unsigned failed = 0;
        if (mts_catalog_add_dir(cat, dirs[i], &rep, &failed, &err) != MTS_OK)
            goto fail;
    }
    for (int i = 0; i < nmodels; i++) {
        if (mts_catalog_add_spec(cat, models[i], &rep, &err) != MTS_OK) {
            cli_bar_done(&bar);
            fprintf(stderr, "mts-server: %s: %s\n", models[i], err.msg);
        }
    }
    cli_bar_done(&bar);
    count = (uint32_t)mts_catalog_count(cat);
    if (count == 0) {
        mts_error_set(&err, MTS_ERR_ARG, "no model to serve");
        goto fail;
    }
    streams = calloc(count, sizeof *streams);
    table = calloc(count, sizeof *table);
    if (!streams || !table) {
        mts_error_set(&err, MTS_ERR_NOMEM, "out of memory");
        goto fail;
    }
    for (uint32_t i = 0; i < count; i++) {
        const mts_catalog_entry *e = mts_catalog_at(cat, i);
        mts_server_model_init_preparing(&table[i], e->name, &e->model);
    }
    so.log = log_line;
    so.log_user = &quiet;
    so.reuse_port = nworkers > 1;
    raise_nofile((uint64_t)(so.max_clients ? so.max_clients : 1024) * nworkers, quiet);
    workers = calloc(nworkers, sizeof *workers);
    if (!workers) {
        mts_error_set(&err, MTS_ERR_NOMEM, "out of memory");
        goto fail;
    }
    /* the first worker binds (port 0 picks one); the others join its port */
    char listen_spec[300], ws_spec[300];
    const char *ws_asked = so.ws_listen;
    for (; created < nworkers; created++) {
        if (created == 1) {
            const char *spec = so.listen ? so.listen : "127.0.0.1:7447";
            const char *colon = strrchr(spec, ':');
            snprintf(listen_spec, sizeof listen_spec, "%.*s:%d", (int)(colon - spec), spec,
                     mts_server_port(workers[0].server));
            so.listen = listen_spec;
            if (so.ws_listen && (colon = strrchr(so.ws_listen, ':')) != NULL) {
                snprintf(ws_spec, sizeof ws_spec, "%.*s:%d", (int)(colon - so.ws_listen),
                         so.ws_listen, mts_server_ws_port(workers[0].server));
                so.ws_listen = ws_spec;
            }
        }
        if (mts_server_create_models(&so, table, count, &workers[created].server, &err) !=
            MTS_OK)
            goto fail;
    }
    /* the streams are encoded while the servers listen */
    if (!nprepare) {
        long cores = sysconf(_SC_NPROCESSORS_ONLN);
        nprepare = cores > 2 ? (uint32_t)cores - 1 : 1;
    }
    if (nprepare > count)
        nprepare = count;
    prep.cat = cat;
    prep.models = table;
    prep.streams = streams;
    prep.count = count;
    atomic_init(&prep.next, 0);
    atomic_init(&prep.done, 0);
    atomic_init(&prep.ok, 0);
    atomic_init(&prep.failed_all, 0);
    prep.no_records = no_records;
    prep.quiet = quiet;
    preparers = calloc(nprepare, sizeof *preparers);
    if (!preparers) {
        mts_error_set(&err, MTS_ERR_NOMEM, "out of memory");
        goto fail;
    }
    for (; prepared < nprepare; prepared++) {
        if (pthread_create(&preparers[prepared], NULL, prepare_main, &prep) != 0)
            break;
    }
    if (prepared == 0) {
        /* encoding here would leave the bound sockets unanswered meanwhile */
        mts_error_set(&err, MTS_ERR_IO, "cannot start a thread to encode the streams");
        goto fail;
    }
    serving = 1;
    fprintf(stderr,
                "mts-server: listening on %s (port %d), %u models (streams being encoded), %u "
                "worker%s\n",
                so.listen ? so.listen : "127.0.0.1:7447", mts_server_port(workers[0].server),
                count, nworkers, nworkers == 1 ? "" : "s");
    if (ws_asked)
        fprintf(stderr, "mts-server: WebSocket clients on %s (port %d)\n", ws_asked,
                mts_server_ws_port(workers[0].server));
    /* worker 0 runs on this thread; signals may land on any thread, and
     * every loop polls the one flag */
    uint32_t started = 1;
    for (; started < nworkers; started++) {
        if (pthread_create(&workers[started].thread, NULL, worker_main, &workers[started]) != 0) {
            stop_requested = 1;
            fprintf(stderr, "mts-server: cannot start worker %u; stopping\n", started);
            break;
        }
    }
    worker_main(&workers[0]);
    mts_server_stats st = {0};
    mts_result rc = workers[0].rc;
    if (rc != MTS_OK)
        err = workers[0].err;
    for (uint32_t i = 0; i < nworkers; i++) {
        if (i > 0 && i < started) {
            pthread_join(workers[i].thread, NULL);
            if (workers[i].rc != MTS_OK && rc == MTS_OK) {
                rc = workers[i].rc;
                err = workers[i].err;
            }
        }
        mts_server_stats ws;
        mts_server_get_stats(workers[i].server, &ws);
        st.accepted += ws.accepted;
        st.completed += ws.completed;
        st.failed += ws.failed;
        st.busy += ws.busy;
        st.bytes += ws.bytes;
        st.peak += ws.peak;
    }
    /* a preparer still encoding stops at its next check of the flag */
    stop_requested = 1;
    for (uint32_t i = 0; i < prepared; i++)
        pthread_join(preparers[i], NULL);
    prepared = 0;
    if (rc != MTS_OK)
        goto fail;
    if (atomic_load(&prep.failed_all))
        goto done; /* said why; exit 1 */
    fprintf(stderr, "mts-server: stopped: %llu connections, %llu completed, %llu failed, "
                        "%llu busy, %llu bytes, peak %u at once\n",
                (unsigned long long)st.accepted, (unsigned long long)st.completed,
                (unsigned long long)st.failed, (unsigned long long)st.busy,
                (unsigned long long)st.bytes, st.peak);
    status = CLI_EXIT_OK;
    goto done;
fail:
    cli_bar_done(&bar);
    fprintf(stderr, "mts-server: %s\n", err.msg);
done:
    /* a preparer still encoding stops at its next check of the flag */
    stop_requested = 1;
    for (uint32_t i = 0; i < prepared; i++)
        pthread_join(preparers[i], NULL);
    free(preparers);
    for (uint32_t i = 0; i < created && workers; i++)
        mts_server_free(workers[i].server);
    free(workers);
    for (uint32_t i = 0; streams && i < count; i++)
        mts_stream_free(&streams[i]);
    free(streams);
    free(table);
    mts_catalog_free(cat);
    mts_fetch_global_cleanup();
    return status;
}
