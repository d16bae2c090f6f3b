/* The renderer's seam for measurements (client/drawmodes.c, and the tests
 * that compare draw paths): a frame drawn by the caller's own draw calls,
 * with the renderer's state. Not the public API (render.h): mts__ names.
 *
 * mts__render_frame_begin makes the context current, clears the
 * framebuffer, sets the state, program and uniforms of mts_render_draw,
 * binds the vertex array (whose element buffer is the slot buffer: every
 * strip at its slot, padded with restarts) and, with `slots`, brings that
 * buffer up to date first (the default draw never reads it). The caller
 * draws; mts__render_frame_end binds the slot buffer back, adds the
 * wireframe where the style asks for it and `wireframe` was given to begin,
 * waits for the frame when options.timed, and records the stats from the
 * figures given (calls, indices, their bytes). */
#ifndef MTS_RENDER_INTERNAL_H
#define MTS_RENDER_INTERNAL_H

#include <stdint.h>

#include "error.h"
#include "render.h"

typedef struct mts__render_frame {
    uint32_t strip_count;
    const uint32_t *offset; /* strip s at index offset[s] of the slot buffer */
    const uint32_t *length; /* its length now */
    uint64_t slot_indices;  /* the whole slot buffer, restarts included */
    void (*multi_draw)(void); /* glMultiDrawElementsEXT, NULL without the extension */
    int u_color;            /* the surface colour's uniform in the bound program */
    /* the renderer's */
    double t0;
    int wire, program;
} mts__render_frame;

/* The context r draws in. */
mts_render_context *mts__render_context(const mts_renderer *r);

mts_result mts__render_frame_begin(mts_renderer *r, int wireframe, int slots,
                                   mts__render_frame *f, mts_error *err);

/* The packed buffer, rebuilt from the strips when stale or of the other
 * kind: joined (compact 0, what mts_render_draw draws) or one restart
 * between strips (compact 1); its buffer name, index count and whether the
 * indices are 16-bit. Counted in the stats' uploads. Between begin and end. */
mts_result mts__render_packed(mts_renderer *r, int compact, unsigned *ibo, uint64_t *count,
                              int *u16, mts_error *err);

/* mts__render_packed, then one draw of it: *calls, *indices and
 * *index_bytes what it drew. Between begin and end. */
mts_result mts__render_draw_packed(mts_renderer *r, int compact, uint32_t *calls,
                                   uint64_t *indices, uint64_t *index_bytes, mts_error *err);

mts_result mts__render_frame_end(mts_renderer *r, const mts__render_frame *f, uint32_t calls,
                                 uint64_t indices, uint64_t index_bytes, mts_error *err);

/* render_options.c's, for render.c: the style's zero fields given their
 * defaults (mts_render_options_default), and a layout checked before
 * mts_renderer_create makes anything (MTS_ERR_ARG, the fault named). */
void mts__render_style_defaults(mts_render_style *style);
mts_result mts__render_check_layout(const mts_render_layout *layout, mts_error *err);

#endif
