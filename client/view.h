/* The client's view: the one path from a LOD runtime to the screen.
 *
 * A view owns a renderer (render.h) and keeps it in step with a source --
 * a runtime that a stream client (or any caller) moves, and the vertices
 * and slots it has so far: mts_view_sync appends the vertices that came,
 * lays out the slots announced since, moves to the level asked for and
 * uploads the strips that changed (the renderer's changed-strip path), and
 * keeps the figures of the level shown. mts-client's headless run and its
 * window, the benchmarks and the tests all draw through it.
 *
 * Two ways to hold the level:
 *   - the source's own runtime (own_runtime 0): the view moves it, so a
 *     caller that steps below what came (a PNG of an earlier level) steps
 *     back up before the stream goes on. Headless, one runtime is enough.
 *   - a runtime of the view's own on the source's model (own_runtime 1): it
 *     may stand anywhere up to what came while the stream goes on, as the
 *     window's level keys need; only the strips that change between two
 *     levels are touched.
 *
 * Geomorphs (own runtime, morph_ms > 0): a level change does not pop; the
 * vertices a level adds slide from their ancestors' places (morph.h), which
 * the renderer draws by one id range and a factor (mts_render_set_morph).
 * While a morph runs the view holds its level, so a fast stream shows a
 * step every morph_ms instead of one a frame (which also bounds the packed
 * buffer's rebuilds).
 *
 * Errors: mts_result and mts_error, nothing printed. One thread. */
#ifndef MTS_VIEW_H
#define MTS_VIEW_H

#include <stdint.h>

#include "error.h"
#include "lod.h"
#include "model.h"
#include "morph.h"
#include "render.h"

struct mts_stream_client;

/* The level asked for by mts_view_sync: the newest the source has. */
#define MTS_VIEW_NEWEST UINT32_MAX

typedef struct mts_view_options {
    int own_runtime; /* see the top; 0 draws the source's runtime */
    double morph_ms; /* geomorph time; 0 (the default): levels change at once */
} mts_view_options;

/* What the view follows. */
typedef struct mts_view_source {
    mts_lod *lod;             /* the source's runtime */
    const mts_model *model;   /* its model (positions, normals, parents, capacities) */
    uint32_t vertices;        /* vertices present: base + the splits that came */
    uint32_t levels;          /* the highest level to show: a stream's stop level, where
                                 the last batch may bring splits past it */
    uint32_t announced;       /* slots laid out in lod (all of them for a whole model) */
} mts_view_source;

/* A stream client's runtime and what it has received. */
mts_view_source mts_view_source_of_stream(struct mts_stream_client *c);
/* A whole model's runtime (every level present). */
mts_view_source mts_view_source_of_model(mts_lod *lod, const mts_model *model);

typedef struct mts_view_figures {
    uint32_t level, triangles, strips;
    uint64_t indices; /* restarts not counted */
} mts_view_figures;

typedef struct mts_view {
    mts_renderer *renderer;
    mts_lod *lod;             /* the runtime drawn: the view's own or the source's */
    mts_view_figures shown;   /* of the level drawn */
    int have_figures;         /* shown is filled (after the first sync) */
    mts_morph morph;          /* .active: a geomorph runs, sync again next frame;
                                 .t: how far it is, 0..1 (towards the higher level) */
    /* the view's own */
    mts_view_options opts;
    mts_lod own;
    int have_own, wireframe, wire_stale;
    uint32_t uploaded, announced;
} mts_view;

/* Creates the renderer for the source's model (mts_render_layout_from_lod
 * of src->lod) on ctx with ro, and the own runtime where asked. The view
 * struct is the caller's; zero it or let this fill it. */
mts_result mts_view_create(mts_view *v, mts_render_context *ctx, const mts_render_options *ro,
                           const mts_view_source *src, const mts_view_options *opts,
                           mts_error *err);
void mts_view_free(mts_view *v);

/* Brings the view up to the source and towards `level` (at most what the
 * source has; MTS_VIEW_NEWEST for that), now_ms on a monotonic clock for the
 * geomorphs. Uploads what changed; draws nothing. */
mts_result mts_view_sync(mts_view *v, const mts_view_source *src, uint32_t level, double now_ms,
                         mts_error *err);

/* Draws the level shown (mts_render_draw). */
mts_result mts_view_draw(mts_view *v, mts_error *err);

/* The hidden-line edges drawn (style.wireframe in the renderer's style must
 * say so too); rebuilt at the next sync. */
void mts_view_set_wireframe(mts_view *v, int on);

#endif
