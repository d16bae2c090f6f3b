/* mts-client's own parts, shared by its headless run (mts_client.c) and its
 * window (mts_client_window.c). Program code: it prints; the library's
 * modules (session, view, render, ...) do not. */
#ifndef MTS_CLIENT_H
#define MTS_CLIENT_H

#include <stdint.h>

#include "cli.h"
#include "lodpolicy.h"
#include "render.h"
#include "session.h"
#include "stream.h"
#include "view.h"

typedef struct client_run {
    int render, quiet;
    const char *png, *model;
    uint32_t png_levels[64];
    int png_level_count;
    uint32_t next_png; /* index into png_levels, sorted ascending */
    mts_render_options ro;
    double morph_ms;  /* --morph-ms; negative: not given (the window's default) */
    mts_render_context *ctx;
    mts_view view;    /* made at the base mesh */
    int have_view;
    double ms_render;
    cli_bar bar;
    mts_error err;
    int failed;
    uint32_t pngs_written;
    char png_paths[8][512];
} client_run;

/* One triangle through a throw-away renderer with the run's options, so
 * the driver's first-draw work (llvmpipe compiles a shader variant) is done
 * before the model's first frame. */
int client_warm_up(client_run *rn);

/* The --json keys both runs write after the level's: the checksum (once
 * END came), reconnects, the session's times, the render time, and what
 * went to GL over the run beside the final buffers. */
void client_json_run(cli_json *j, const mts_stream_client *c, const mts_session_stats *st,
                     const client_run *rn);

/* --lod-policy distance or area before the stream: the triangles they want
 * at the camera's start, from the server's listing, set as the HELLO's
 * stop (mts_client.c says more). 1 when set. */
int client_policy_stop(mts_session_options *so, const client_run *rn,
                       const mts_lod_policy_options *po, double distance, uint32_t *asked,
                       uint64_t *list_bytes, uint64_t *full_bytes);

/* --window from start to exit status. */
int client_window_main(client_run *rn, mts_session_options *so, const char *script_path,
                       int json, const mts_lod_policy_options *po);

#endif
