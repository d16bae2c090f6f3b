/* Private to the renderer (render.c, render_strips.c): its state, and the
 * calls between the two files. Not the public API (render.h), nor the
 * measurement seam (render_internal.h), through which drawmodes.c draws
 * without reaching these fields: mts__ names.
 *
 * render.c makes the renderer and its GL objects, takes the vertices and
 * the geomorphs' sources, draws the frame and reads it back; render_strips.c
 * keeps the index side: the strips in their slots (the slot buffer and its
 * host copy) as the level changes and new slots are laid out, the packed
 * buffer the default draw reads, and the wireframe's lines. What runs once a
 * strip (check_strip, put_strip) stays static beside its callers in
 * render_strips.c; only calls made once an update or a frame cross over. */
#ifndef MTS_RENDER_STATE_H
#define MTS_RENDER_STATE_H

#include <GLES3/gl32.h>
#include <GLES2/gl2ext.h>
#include <stdint.h>

#include "error.h"
#include "follow.h"
#include "render.h"

struct mts_renderer {
    mts_render_context *ctx;
    mts_render_options opts;
    /* The buffers hold what arrived, not what the source claims: the vertex
     * buffer grows (doubling) up to vertex_limit as vertices are appended,
     * the strip buffer up to index_limit as slots are laid out. */
    uint32_t vertex_capacity, vertex_limit;
    uint64_t index_limit;
    uint32_t strip_count;
    uint32_t *offset;   /* strip s at index offset[s], cap_s + 1 entries: slot[s] + s */
    uint32_t *capacity; /* cap_s: the longest length */
    uint32_t *length;   /* the length uploaded */
    uint32_t max_capacity;
    uint64_t index_count; /* offset[strip_count] */
    float bbox_min[3], bbox_max[3];

    /* two programs: [0] plain, [1] with the geomorph's mix, drawn only
     * while a morph runs, so a still frame pays nothing for it */
    struct render_program {
        GLuint id;
        GLint u_mvp, u_normal, u_color, u_light, u_ambient, u_flat, u_morph, u_morph_t;
        GLint u_vertex_color;
    } prog[2];
    GLuint vao, vbo, ibo, fbo, color_rb, depth_rb;
    /* layout.colors: the programs are built with COLORS 1 and the colours
     * (RGBA8, 4 bytes a vertex, by vertex id) have a buffer of their own,
     * so a model without them keeps the buffer, attributes and shader it
     * always had */
    int colors;
    GLuint color_vbo;
    GLuint wire_ibo; /* style.wireframe: GL_LINES over the triangles' edges */
    uint64_t wire_count;
    /* geomorphs: where vertices morph_first .. morph_end-1 come from
     * (positions for every vertex id, then normals), made at the first
     * mts_render_set_morph */
    GLuint morph_vbo;
    GLuint morph_color_vbo; /* with colours: the from-colours, RGBA8 by vertex id */
    uint32_t morph_first, morph_end;
    float morph_t;

    uint32_t *staging; /* max_capacity + 1 */
    /* the packed draws: a host copy of the slot buffer (the strips' current
     * indices at offset[s]), from which the packed buffer is rebuilt at the
     * first draw after the strips changed */
    uint32_t *host;
    GLuint packed_ibo;
    mts_follow_packed packed;  /* staging for the packed buffer */
    uint64_t packed_count;     /* entries in packed_ibo */
    int packed_kind;           /* the mode packed_ibo was built for; -1: stale */
    /* the slot buffer (ibo) lags the host copy: the packed modes never read
     * it, so it is filled only when a mode that does draws (upload_slots) */
    int slots_stale;
    int packed_u16;            /* GL_UNSIGNED_SHORT (every vertex id below 0xFFFF) */
    PFNGLMULTIDRAWELEMENTSEXTPROC multi_draw;

    float mvp[16], normal[9], eye[3], dir[3];
    mts_render_stats stats;
};

/* Returns MTS_OK when GL has no error pending; else names `what`. Drains
 * every pending error so the next check starts clean. */
mts_result mts__render_gl_check(mts_error *err, const char *what);

/* Fills the whole slot buffer from the host copy (each strip, then restarts
 * to its slot's end), for a mode that reads it after packed draws left it
 * behind (slots_stale). The index buffer is bound. Returns the bytes, 0
 * when out of memory. */
uint64_t mts__render_upload_slots(mts_renderer *r);

#endif
