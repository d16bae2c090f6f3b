/* Geomorphs between two levels of a runtime, GL-free: the state the native
 * view (view.c) and the browser page (web/mts_web.c) keep alike.
 *
 * Going up, the level is set at once and the vertices it adds are drawn
 * first at their ancestors' places (the nearest ancestor present at the old
 * level: the position, normal and colour that vertex had there, so the
 * first frame is the old level's surface in its colours) and slide to their own over ms; going down,
 * they slide back and the level drops when they arrive. Vertices of one
 * level range are contiguous ids (stream order), so a renderer morphs them
 * by one id range [first, first + count), the from-attributes of that range
 * and a factor t. While a morph runs the level holds; a request that comes
 * meanwhile is taken when it ends, so a fast stream shows a step every ms
 * instead of one a frame.
 *
 * Errors: mts_result and mts_error, nothing printed. One thread. */
#ifndef MTS_MORPH_H
#define MTS_MORPH_H

#include <stdint.h>

#include "error.h"
#include "lod.h"
#include "model.h"

typedef struct mts_morph {
    double ms;              /* the morph's time; 0: levels change at once */
    int active;             /* a morph runs: move again next frame */
    float t;                /* how far it is, 0..1 (towards the higher level) */
    uint32_t first, count;  /* the vertex ids morphing (count 0: none) */
    float *from;            /* 6 floats a vertex of the range: positions, then normals */
    uint8_t *from_colors;   /* 3 bytes a vertex of the range (the ancestors' r, g, b)
                               where the model has colours (MTS_MODEL_COLORS); else NULL */
    /* internal */
    int down;
    uint32_t target; /* going down: the level set when the morph ends */
    double t0;
    uint32_t *ids;
    uint32_t cap;
} mts_morph;

void mts_morph_free(mts_morph *mo);

/* Moves lod towards target at now_ms (a monotonic clock): sets t, and the
 * level where a morph ends or starts. *range_changed (may be NULL) is set
 * to 1 when first, count or from (and from_colors) changed (the renderer's
 * from-attributes to upload again), else 0. */
mts_result mts_morph_move(mts_morph *mo, mts_lod *lod, const mts_model *m, uint32_t target,
                          double now_ms, int *range_changed, mts_error *err);

#endif
