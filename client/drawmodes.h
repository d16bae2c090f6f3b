/* Draw paths kept for measuring the renderer's own against (make bench,
 * "Draw path"; test_render checks they all draw the same picture). The
 * renderer (client/render.h) draws one way -- the live strips joined into
 * one packed strip -- and these the others, through its measurement seam
 * (client/render_internal.h):
 *
 *   RESTART    one glDrawElements over the slot buffer, restarts between
 *              strips and as padding (the stored layout as it is)
 *   PER_STRIP  a glDrawElements per live strip, its current length
 *   MULTI      glMultiDrawElementsEXT over the same (GL_EXT_multi_draw_arrays,
 *              which Mesa has; PER_STRIP's loop where it is missing)
 *   COMPACT    the live strips packed end to end, one restart between two
 *   JOINED     what mts_render_draw draws
 *   LIST       an indexed triangle list given to mts_drawmodes_set_list, on
 *              the same vertices: strips against lists
 *
 * Why JOINED is the renderer's: docs/strips.md, "Drawing them". */
#ifndef MTS_DRAWMODES_H
#define MTS_DRAWMODES_H

#include <stdint.h>

#include "error.h"
#include "render.h"

typedef enum mts_drawmode {
    MTS_DRAWMODE_JOINED = 0,
    MTS_DRAWMODE_RESTART,
    MTS_DRAWMODE_PER_STRIP,
    MTS_DRAWMODE_MULTI,
    MTS_DRAWMODE_COMPACT,
    MTS_DRAWMODE_LIST
} mts_drawmode;

/* What the modes need beside a renderer: the triangle list's buffer and the
 * multi-draw arrays. Zero it; free with mts_drawmodes_free (its renderer's
 * context current, or gone with it). */
typedef struct mts_drawmodes {
    unsigned list_ibo;
    uint32_t list_count;
    int32_t *multi_count;
    const void **multi_offset;
    uint32_t multi_cap;
} mts_drawmodes;

/* An indexed triangle list (3 indices a triangle, each below the vertices
 * uploaded to r) for LIST. */
mts_result mts_drawmodes_set_list(mts_drawmodes *d, mts_renderer *r, const uint32_t *indices,
                                  uint32_t count, mts_error *err);

/* One frame of r in mode (the renderer's stats count it as its own draws:
 * last_draw_seconds with options.timed, calls, indices and their bytes). */
mts_result mts_drawmodes_draw(mts_drawmodes *d, mts_renderer *r, mts_drawmode mode,
                              mts_error *err);

void mts_drawmodes_free(mts_drawmodes *d);

#endif
