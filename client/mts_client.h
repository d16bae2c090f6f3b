/* mts-client's command line, parsed by its main (mts_client.c), and its
 * window run (mts_client_window.c). Program code: it prints; what both runs
 * share is the library's (run.h), which does not. */
#ifndef MTS_CLIENT_H
#define MTS_CLIENT_H

#include "cli.h"
#include "run.h"
#include "session.h"
#include "tls.h"

typedef struct client_options {
    mts_client_run run;     /* the run's settings (and, once it runs, its state) */
    mts_session_options so; /* host and port point into this struct */
    int json, quiet, list, window, size_given;
    int stops;              /* --level, --triangles, --fraction given */
    const char *script;     /* --script */
    const char *pos[2];     /* [HOST[:PORT]] MODEL */
    int npos;
    char host[256], port[16];
    /* a stream file's URL instead of a server and a model */
    const char *url;
    char url_name[65];      /* the file's name without .mts: the run's model name */
    const char *cacert;     /* --cacert (a URL's, or --tls's) */
    int tls;                /* --tls: the TCP stream inside TLS */
    mts_tls_options tls_options;
    uint64_t max_file_bytes; /* --max-file-bytes; 0: the default */
    cli_bar bar;            /* headless: the stream's progress */
} client_options;

/* --window from start to exit status. */
int client_window_main(client_options *o);

#endif
