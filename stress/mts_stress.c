/* mts-stress: many simulated clients against one mts-server (or a balancer
 * in front of several), with latency percentiles and throughput. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <unistd.h>

#include "cli.h"
#include "fetch.h"
#include "stress.h"

static void usage(FILE *f)
{
    fputs("usage: mts-stress [HOST[:PORT]] MODEL --clients N [--concurrency C] [--ramp S]\n"
          "                  [--level L | --triangles N | --fraction F] [--no-apply] [--verify]\n"
          "                  [--records] [--threads T] [--appliers A] [--decode-threads D]\n"
          "                  [--continue-level L | --continue-triangles N |\n"
          "                   --continue-fraction F [--continue-share S]]\n"
          "                  [--connect-timeout S] [--io-timeout S] [--json] [--quiet]\n"
          "       mts-stress HOST:PORT --http PATH --clients N ...   (a static file server)\n"
          "       mts-stress http[s]://HOST/NAME.mts --clients N [--cacert FILE]\n"
          "                  [--max-file-bytes N] [the stops, --continue-*, --concurrency,\n"
          "                   --ramp, --threads, --appliers, timeouts, --verify, --json]\n"
          "\n"
          "Runs N simulated clients against an mts-server (default 127.0.0.1:7447) from\n"
          "one process, each speaking the whole protocol, and reports how they fared:\n"
          "failures by reason, bytes, time to the base mesh and to the final level\n"
          "(p50/p90/p99/max), MB/s and batches/s, and its own CPU time.\n"
          "\n"
          "  --clients N          clients in all (default 1)\n"
          "  --concurrency C      at most C connected at once (default: all N)\n"
          "  --ramp S             start the clients evenly over S seconds (default 0)\n"
          "  --level L / --triangles N / --fraction F   where each client stops (default: full)\n"
          "  --continue-level L / --continue-triangles N / --continue-fraction F\n"
          "                       previews that ask for more: after END at its stop, a\n"
          "                       client connects again and continues from the batches it\n"
          "                       holds to this stop (PROTOCOL.md, \"Continuing\"), checked\n"
          "                       at its END; applying clients only\n"
          "  --continue-share S   only this share of the clients continues (0..1, default 1)\n"
          "  --no-apply           only read and frame the stream; do not decode or apply\n"
          "                       (loads the server, not this process)\n"
          "  --records            ask for the records form (PROTOCOL.md): far more bytes,\n"
          "                       far less work for an applying client\n"
          "  --verify             with --no-apply, still check every batch's CRC (applying\n"
          "                       clients always check CRCs and the final checksum)\n"
          "  --threads T          event loops, each with its share of the clients\n"
          "                       (default: one per core)\n"
          "  --appliers A         applying clients decode at most A at once, the oldest\n"
          "                       first, while every socket is read as bytes come (default\n"
          "                       8 a thread); bounds memory, not the work\n"
          "  --decode-threads D   threads each applying client's decoder uses (default 1:\n"
          "                       a load generator's many clients already fill the cores;\n"
          "                       mts-client's --threads: more than 2 decode as 2)\n"
          "  --http PATH          not mtstream: GET PATH over HTTP/1.0 from each client, to\n"
          "                       measure a web server (nginx) on the same bytes\n"
          "  URL                  a stream file (PROTOCOL.md, \"Stream files\") on any web\n"
          "                       server: each client reads it as mts-client does (its\n"
          "                       prefix, then one range to its stop, checked against the\n"
          "                       file's checksums) and applies it, over connections of\n"
          "                       its own (no two clients share or multiplex one)\n"
          "  --cacert FILE        for an https URL: trust the CAs in FILE (PEM)\n"
          "  --max-file-bytes N   for a URL: refuse a file over N bytes (K, M, G; default 1G)\n"
          "  --connect-timeout S  default 10 (a full listen queue costs SYN retries)\n"
          "  --io-timeout S       give up on a client after S s without a byte (default 30)\n"
          "  --json               one line of JSON with the figures\n"
          "  -q, --quiet          no live line, no summary\n"
          "  -h, --help           this help\n"
          "\n"
          "A URL's clients always apply (no --no-apply, --records or --http: the file\n"
          "holds one form, and its bytes are the web server's to send).\n"
          "\n"
          "Each client holds a socket; N or C above the open-file limit is raised to the\n"
          "hard limit. An applying client holds its stream's bytes until it is decoded,\n"
          "and a decoded model while it is (--appliers of them at a time).\n"
          "\n"
          "Exit status: 0 every client completed, 1 some failed (see the reasons),\n"
          "2 bad usage.\n",
          f);
}

static void live(void *user, const mts_stress_report *r)
{
    (void)user;
    fprintf(stderr, "\r\033[K  %.1f s  %u/%u done, %u active, %u failed, %.1f MB, %.1f MB/s", r->seconds,
            r->succeeded + r->failed, r->clients, r->active, r->failed, (double)r->bytes / 1e6,
            r->seconds > 0 ? (double)r->bytes / 1e6 / r->seconds : 0.0);
    fflush(stderr);
}

static double cpu_seconds(void)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return (double)ru.ru_utime.tv_sec + ru.ru_utime.tv_usec * 1e-6 + (double)ru.ru_stime.tv_sec +
           ru.ru_stime.tv_usec * 1e-6;
}

/* Each client needs a descriptor: raise the soft limit as far as the hard
 * one allows, and say so when that is still too low. */
static void raise_nofile(uint64_t need, int quiet)
{
    uint64_t now, hard;
    need += 64;
    cli_raise_nofile(need, &now, &hard);
    if (now < need && !quiet)
        fprintf(stderr,
                "mts-stress: the open-file limit (hard %llu) is below the %llu descriptors "
                "wanted: clients over it fail as 'local'; raise it (ulimit -Hn) or use "
                "--concurrency\n",
                (unsigned long long)hard, (unsigned long long)need);
}

int main(int argc, char **argv)
{
    mts_stress_options so = {0};
    const char *pos[2];
    int npos = 0, json = 0, quiet = 0, stops = 0, stop;
    const char *cacert = NULL;
    uint64_t max_file_bytes = 0;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) {
            usage(stdout);
            return CLI_EXIT_OK;
        } else if (!strcmp(a, "--json")) {
            json = 1;
        } else if (!strcmp(a, "-q") || !strcmp(a, "--quiet")) {
            quiet = 1;
        } else if (!strcmp(a, "--no-apply")) {
            so.no_apply = 1;
        } else if (!strcmp(a, "--verify")) {
            so.verify = 1;
        } else if (!strcmp(a, "--records")) {
            so.hello.flags |= MTS_HELLO_RECORDS;
        } else if (!strcmp(a, "--clients") || !strcmp(a, "--concurrency") ||
                   !strcmp(a, "--threads") || !strcmp(a, "--appliers") ||
                   !strcmp(a, "--decode-threads")) {
            uint32_t *x = !strcmp(a, "--clients")       ? &so.clients
                          : !strcmp(a, "--concurrency") ? &so.concurrency
                          : !strcmp(a, "--threads")     ? &so.threads
                          : !strcmp(a, "--appliers")    ? &so.appliers
                                                        : &so.decode_threads;
            if (!cli_option_u32(argc, argv, &i, "mts-stress", 1,
                                x == &so.decode_threads ? 64 : UINT32_MAX, x))
                return CLI_EXIT_USAGE;
        } else if (!strncmp(a, "--continue-", 11) && strcmp(a, "--continue-share") != 0) {
            char base[40];
            snprintf(base, sizeof base, "--%s", a + 11);
            if (cli_parse_stop(base, v, &so.continue_kind, &so.continue_value) <= 0) {
                fprintf(stderr, "mts-stress: %s needs %s\n", a, cli_stop_value_kind(a));
                return CLI_EXIT_USAGE;
            }
            i++;
        } else if (!strcmp(a, "--continue-share")) {
            if (!v || !cli_parse_double(v, &so.continue_share) || !(so.continue_share > 0) ||
                so.continue_share > 1) {
                fprintf(stderr, "mts-stress: --continue-share needs a number above 0, at most "
                                "1\n");
                return CLI_EXIT_USAGE;
            }
            i++;
        } else if ((stop = cli_option_stop(argc, argv, &i, "mts-stress", &so.hello.stop_kind,
                                           &so.hello.stop_value))) {
            if (stop < 0)
                return CLI_EXIT_USAGE;
            stops++;
        } else if (!strcmp(a, "--http")) {
            if (!v) {
                fprintf(stderr, "mts-stress: --http needs a path\n");
                return CLI_EXIT_USAGE;
            }
            so.http_path = v;
            i++;
        } else if (!strcmp(a, "--cacert")) {
            if (!v) {
                fprintf(stderr, "mts-stress: --cacert needs a PEM file\n");
                return CLI_EXIT_USAGE;
            }
            cacert = v;
            i++;
        } else if (!strcmp(a, "--max-file-bytes")) {
            if (!v || !cli_parse_bytes(v, &max_file_bytes) || max_file_bytes == 0) {
                fprintf(stderr, "mts-stress: --max-file-bytes needs a size in bytes above 0 "
                                "(512M, 4G)\n");
                return CLI_EXIT_USAGE;
            }
            i++;
        } else if (!strcmp(a, "--ramp") || !strcmp(a, "--connect-timeout") ||
                   !strcmp(a, "--io-timeout")) {
            double s;
            int ramp = !strcmp(a, "--ramp");
            if (!v || !cli_parse_double(v, &s) || s < 0 || (!ramp && s == 0)) {
                fprintf(stderr, "mts-stress: %s needs a %s number of seconds\n", a,
                        ramp ? "non-negative" : "positive");
                return CLI_EXIT_USAGE;
            }
            if (ramp)
                so.ramp = s;
            else if (!strcmp(a, "--connect-timeout"))
                so.connect_timeout = s;
            else
                so.io_timeout = s;
            i++;
        } else if (a[0] == '-' && a[1]) {
            fprintf(stderr, "mts-stress: unknown option %s (see --help)\n", a);
            return CLI_EXIT_USAGE;
        } else if (npos < 2) {
            pos[npos++] = a;
        } else {
            fprintf(stderr, "mts-stress: too many arguments (see --help)\n");
            return CLI_EXIT_USAGE;
        }
    }
    const int url = npos >= 1 && mts_fetch_is_url(pos[0]);
    if (url) {
        /* what a file cannot do is said, not ignored */
        const char *no = npos > 1            ? "a model name (the URL names the file)"
                         : so.no_apply       ? "--no-apply (a stream file's clients apply)"
                         : so.hello.flags    ? "--records (the file holds the form it was built in)"
                         : so.http_path      ? "--http (the URL is what is fetched)"
                                             : NULL;
        if (no) {
            fprintf(stderr, "mts-stress: a stream file's URL takes no %s\n", no);
            return CLI_EXIT_USAGE;
        }
    } else if (cacert || max_file_bytes) {
        fprintf(stderr, "mts-stress: --cacert and --max-file-bytes are for a stream file's "
                        "URL (http[s]://HOST/NAME.mts)\n");
        return CLI_EXIT_USAGE;
    }
    if (so.http_path && npos == 1) /* no model: the path names what to fetch */
        pos[npos++] = "http";
    if (npos == 0) {
        usage(stderr);
        return CLI_EXIT_USAGE;
    }
    if (stops > 1) {
        fprintf(stderr, "mts-stress: give one of --level, --triangles, --fraction\n");
        return CLI_EXIT_USAGE;
    }
    if (so.continue_kind && (so.no_apply || so.http_path)) {
        fprintf(stderr, "mts-stress: --continue-* needs applying clients (not --no-apply or "
                        "--http)\n");
        return CLI_EXIT_USAGE;
    }
    const char *model = pos[npos - 1];
    char shown[256] = "";
    mts_error err = {0};
    if (url) {
        so.url = pos[0];
        so.cacert = cacert;
        so.max_file_bytes = max_file_bytes;
        mts_fetch_display_url(so.url, shown, sizeof shown);
        model = shown;
        if (mts_fetch_global_init(&err) != MTS_OK) {
            fprintf(stderr, "mts-stress: %s\n", err.msg);
            return CLI_EXIT_FAIL;
        }
    } else if (!mts_wire_valid_name(model, strlen(model))) {
        fprintf(stderr, "mts-stress: '%s' is not a model name ([A-Za-z0-9._-], 1..64)\n", model);
        return CLI_EXIT_USAGE;
    }
    /* a file is named by its URL; the name is only shown */
    snprintf(so.hello.model, sizeof so.hello.model, "%.64s", model);
    char host[256] = "127.0.0.1", port[16] = "7447";
    if (!url && npos == 2 && !cli_parse_server(pos[0], host, sizeof host, port, sizeof port)) {
        fprintf(stderr, "mts-stress: bad address %s (HOST[:PORT])\n", pos[0]);
        return CLI_EXIT_USAGE;
    }
    so.host = host;
    so.port = port;
    if (!so.clients)
        so.clients = 1;
    raise_nofile(so.concurrency && so.concurrency < so.clients ? so.concurrency : so.clients,
                 quiet);
    if (!quiet && !json && isatty(STDERR_FILENO))
        so.on_progress = live;

    mts_stress_report r;
    double cpu0 = cpu_seconds();
    mts_result rc = mts_stress_run(&so, &r, &err);
    double cpu = cpu_seconds() - cpu0;
    if (so.on_progress)
        fputs("\r\033[K", stderr);
    if (url)
        mts_fetch_global_cleanup();
    if (rc != MTS_OK) {
        fprintf(stderr, "mts-stress: %s\n", err.msg);
        return rc == MTS_ERR_ARG ? CLI_EXIT_USAGE : CLI_EXIT_FAIL;
    }
    if (json) {
        cli_json j;
        cli_json_begin(&j, stdout);
        if (url)
            cli_json_str(&j, "url", shown);
        else
            cli_json_str(&j, "model", model);
        cli_json_u64(&j, "clients", r.clients);
        cli_json_u64(&j, "succeeded", r.succeeded);
        cli_json_u64(&j, "failed", r.failed);
        cli_json_object_begin(&j, "failures");
        for (int k = 0; k < MTS_STRESS_FAILURE_KINDS; k++) {
            if (r.failures[k])
                cli_json_u64(&j, mts_stress_failure_name((mts_stress_failure)k), r.failures[k]);
        }
        cli_json_object_end(&j);
        cli_json_bool(&j, "apply", !so.no_apply);
        cli_json_u64(&j, "concurrency", so.concurrency ? so.concurrency : so.clients);
        cli_json_u64(&j, "bytes", r.bytes);
        cli_json_u64(&j, "batches", r.batches);
        cli_json_u64(&j, "continuations", r.continuations);
        /* where the clients ended (the first's; those that continued
         * apart), and how many ended elsewhere */
        static const char *end_key[2][3] = {{"level", "triangles", "checksum"},
                                        {"continued_level", "continued_triangles",
                                         "continued_checksum"}};
        for (int k = 0; k < 2; k++) {
            const struct mts_stress_end *e = &r.end[k];
            if (!e->ended)
                continue;
            char hex[17];
            snprintf(hex, sizeof hex, "%016llx", (unsigned long long)e->checksum);
            cli_json_u64(&j, end_key[k][0], e->level);
            cli_json_u64(&j, end_key[k][1], e->triangles);
            cli_json_str(&j, end_key[k][2], hex);
        }
        if (r.end[0].ended || r.end[1].ended)
            cli_json_u64(&j, "ended_elsewhere", r.end[0].disagree + r.end[1].disagree);
        cli_json_num(&j, "seconds", r.seconds, 3);
        cli_json_num(&j, "mb_per_s", r.mb_per_s, 2);
        cli_json_num(&j, "batches_per_s", r.batches_per_s, 1);
        static const char *pct[4] = {"p50", "p90", "p99", "max"};
        char key[32];
        for (int k = 0; k < 4; k++) {
            snprintf(key, sizeof key, "%s_ms_base", pct[k]);
            cli_json_num(&j, key, r.ms_base[k], 2);
        }
        for (int k = 0; k < 4; k++) {
            snprintf(key, sizeof key, "%s_ms_final", pct[k]);
            cli_json_num(&j, key, r.ms_final[k], 2);
        }
        cli_json_num(&j, "cpu_s", cpu, 3);
        /* the process's peak resident memory: what N clients cost here */
        struct rusage ru;
        getrusage(RUSAGE_SELF, &ru);
        cli_json_u64(&j, "max_rss_kb", (uint64_t)ru.ru_maxrss);
        cli_json_end(&j);
    }
    if (!quiet && !json) {
        if (url)
            printf("%u clients of %s: %u succeeded, %u failed in %.2f s\n", r.clients, shown,
                   r.succeeded, r.failed, r.seconds);
        else
            printf("%u clients of %s at %s:%s%s: %u succeeded, %u failed in %.2f s\n",
                   r.clients, model, host, port, so.no_apply ? " (not applied)" : "",
                   r.succeeded, r.failed, r.seconds);
        printf("  %.1f MB, %.1f MB/s, %.0f batches/s; this process used %.2f s of CPU\n",
               (double)r.bytes / 1e6, r.mb_per_s, r.batches_per_s, cpu);
        if (r.continuations)
            printf("  %u clients continued past their first stop\n", r.continuations);
        for (int k = 0; k < 2; k++) {
            const struct mts_stress_end *e = &r.end[k];
            if (e->ended)
                printf("  %u %s at level %u, %llu triangles, checksum %016llx%s\n", e->ended,
                       k ? "continued and ended" : "ended", e->level,
                       (unsigned long long)e->triangles, (unsigned long long)e->checksum,
                       e->disagree ? " (some ended elsewhere!)" : "");
        }
        if (r.succeeded)
            printf("  ms to base   p50 %.1f  p90 %.1f  p99 %.1f  max %.1f\n"
                   "  ms to final  p50 %.1f  p90 %.1f  p99 %.1f  max %.1f\n",
                   r.ms_base[0], r.ms_base[1], r.ms_base[2], r.ms_base[3], r.ms_final[0],
                   r.ms_final[1], r.ms_final[2], r.ms_final[3]);
    }
    if (!quiet) {
        for (int k = 0; k < MTS_STRESS_FAILURE_KINDS; k++) {
            if (r.failures[k])
                fprintf(stderr, "mts-stress: %u failed (%s), first: %s\n", r.failures[k],
                        mts_stress_failure_name((mts_stress_failure)k), r.first_error[k]);
        }
    }
    /* clients that asked for one stop and ended at two are a failure too */
    return r.failed || r.end[0].disagree || r.end[1].disagree ? CLI_EXIT_FAIL : CLI_EXIT_OK;
}
