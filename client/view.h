/* The client's view: the one path from a LOD runtime to the screen.
 *
 * A view is a follower (follow.h: a runtime kept in step with a source, the
 * level asked for, the geomorphs, GL-free) plus a renderer (render.h) that
 * uploads what the follower says changed: the vertices that came, the
 * strips that changed (the renderer's changed-strip path) and a morph's
 * range, which the renderer draws by one id range and a factor
 * (mts_render_set_morph). mts-client's headless run and its window, the
 * benchmarks and the tests all draw through it; the browser page follows
 * with the same follower and draws with WebGL2.
 *
 * Errors: mts_result and mts_error, nothing printed. One thread. */
#ifndef MTS_VIEW_H
#define MTS_VIEW_H

#include <stdint.h>

#include "error.h"
#include "follow.h"
#include "render.h"

/* The level asked for by mts_view_sync: the newest the source has. */
#define MTS_VIEW_NEWEST MTS_FOLLOW_NEWEST

typedef struct mts_view_options {
    int own_runtime; /* follow.h's; 0 draws the source's runtime */
    double morph_ms; /* geomorph time; 0 (the default): levels change at once */
    int no_colors;   /* grey even where the model has colours */
} mts_view_options;

typedef struct mts_view {
    mts_renderer *renderer;
    mts_follow follow; /* .lod the runtime drawn, .shown its figures, .morph */
    int wireframe;
    int colors; /* the renderer draws the model's colours (MTS_MODEL_COLORS) */
} mts_view;

/* Creates the renderer for the source's model (mts_render_layout_from_lod
 * of src->lod: with the model's colours where it has them and
 * opts->no_colors does not say otherwise) on ctx with ro, and the follower
 * (mts_follow_init). The view struct is the caller's; zero it or let this
 * fill it. */
mts_result mts_view_create(mts_view *v, mts_render_context *ctx, const mts_render_options *ro,
                           const mts_follow_source *src, const mts_view_options *opts,
                           mts_error *err);
void mts_view_free(mts_view *v);

/* Brings the view up to the source and towards `level` (at most what the
 * source has; MTS_VIEW_NEWEST for that), now_ms on a monotonic clock for the
 * geomorphs. Uploads what changed; draws nothing. */
mts_result mts_view_sync(mts_view *v, const mts_follow_source *src, uint32_t level, double now_ms,
                         mts_error *err);

/* Draws the level shown (mts_render_draw). */
mts_result mts_view_draw(mts_view *v, mts_error *err);

/* The hidden-line edges drawn (style.wireframe in the renderer's style must
 * say so too); rebuilt at the next sync. */
void mts_view_set_wireframe(mts_view *v, int on);

#endif
