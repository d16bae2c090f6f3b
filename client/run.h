/* What mts-client's two runs share, headless (mts_client.c) and in a window
 * (mts_client_window.c): the run's settings and what it has drawn, the
 * warm-up draw, a camera policy's stop asked before the stream, the view
 * made at the base mesh, the headless run's frames, PNGs and verification
 * once the stream ended, and the --json keys both write.
 *
 * Library code: nothing is printed. A failure fills the run's err (or the
 * mts_error given) and the program says what the user sees; the --json
 * writers add keys to an object the program began (cli_json), on the file
 * it chose. */
#ifndef MTS_RUN_H
#define MTS_RUN_H

#include <stdint.h>

#include "cli.h"
#include "lodpolicy.h"
#include "render.h"
#include "session.h"
#include "stream.h"
#include "view.h"

typedef struct mts_client_run {
    /* settings, from the command line */
    int render;           /* 0: --no-render, decode and apply only */
    const char *model;
    const char *png;      /* --png: the final frame's file, or NULL */
    uint32_t png_levels[64]; /* --png-levels, sorted ascending */
    int png_level_count;
    mts_render_options ro;
    double morph_ms;      /* --morph-ms; negative: not given (the window's default) */
    mts_lod_policy_options po;
    double distance;      /* --distance: the camera at this times the framing distance */
    int verify;           /* --verify */
    const char *model_file; /* --model-file: what --verify compares with */
    int no_colors;        /* --no-colors: grey where the stream has colours */
    uint32_t threads;     /* --threads: the stream decoder's (stream.h) */
    /* the run's */
    uint32_t next_png;    /* index into png_levels */
    mts_render_context *ctx;
    mts_view view;        /* made at the base mesh */
    int have_view;
    double ms_render;
    mts_error err;
    int failed;
    uint32_t pngs_written;
    char png_paths[8][512];
} mts_client_run;

/* One triangle through a throw-away renderer with the run's options, so
 * the driver's first-draw work (llvmpipe compiles a shader variant) is done
 * before the model's first frame. 0 on failure (rn->err). */
int mts_client_run_warm_up(mts_client_run *rn);

/* A camera policy's stop, asked for before the stream. */
typedef struct mts_client_run_stop {
    uint32_t asked;      /* the triangles asked for */
    uint64_t list_bytes; /* the listing that told the model's size */
    uint64_t full_bytes; /* what the whole stream would have cost */
} mts_client_run_stop;

/* --lod-policy distance or area (or budget's first guess) before the
 * stream: the triangles they want at the camera's start (the camera at
 * `distance` times the framing distance), from the server's listing, set as
 * the HELLO's stop (run.c says more). 1 when set, and *stop filled. */
int mts_client_run_policy_stop(mts_session_options *so, const mts_client_run *rn,
                               double distance, mts_client_run_stop *stop);

/* The view of c's model at its base mesh (rn->view, rn->have_view) with
 * the run's options; vo NULL for the view's defaults. Flat shading where the
 * stream has no normals; the stream's colours unless --no-colors. 0 on
 * failure (rn->err, rn->failed). */
int mts_client_run_make_view(mts_client_run *rn, mts_stream_client *c,
                             const mts_view_options *vo);

/* The headless run's part of a session's on_event: the view and a first
 * frame at the base, the --png-levels frames as their levels come.
 * Non-zero stops the session (rn->failed, rn->err say why). */
int mts_client_run_on_event(mts_client_run *rn, mts_stream_event ev, mts_stream_client *c);

/* What the headless run ends with, for its summary. */
typedef struct mts_client_run_result {
    int stop_asked;          /* a camera policy's stop was asked before the stream */
    mts_client_run_stop stop;
    uint32_t received;       /* the level received (a policy may draw another) */
    uint32_t continuations;  /* conversations that went on past the stop (budget) */
    int verified;            /* -1: not checked */
} mts_client_run_result;

/* After the headless stream ended with rc (err filled when not MTS_OK):
 * whatever happened, the last whole batch is drawn and --png written; the
 * listed levels left, the policy's level (budget times frames, and asks for
 * more while all that came fits: so's stop is moved on and the session run
 * again, with so's hooks), then --verify. res->stop_asked and res->stop are
 * the caller's (mts_client_run_policy_stop); the rest is filled here.
 * Returns the run's result, err filled when it is not MTS_OK. */
mts_result mts_client_run_finish(mts_client_run *rn, mts_session_options *so,
                                 mts_stream_client *c, mts_session_stats *st, mts_result rc,
                                 mts_client_run_result *res, mts_error *err);

/* The triangles of c's runtime at its level (0 before the base). */
uint32_t mts_client_run_triangles(const mts_stream_client *c);

/* The --json keys both runs write first: model, complete, bytes, batches,
 * form, level, levels. */
void mts_client_run_json_head(cli_json *j, const mts_client_run *rn,
                              const mts_stream_client *c, int complete, uint64_t bytes);

/* The --json keys both runs write after those of their own: the triangles,
 * the checksum (once END came), whether the model's colours were drawn
 * (colors: the stream carried them and --no-colors did not turn them off),
 * reconnects, the session's times, the render time, and what went to GL
 * over the run beside the final buffers. */
void mts_client_run_json(cli_json *j, const mts_stream_client *c, const mts_session_stats *st,
                         const mts_client_run *rn);

/* The view and the render context (the run's GL). */
void mts_client_run_free(mts_client_run *rn);

#endif
