/* The renderer: draws a model's strips at the LOD runtime's current level
 * with OpenGL ES 3 (docs/architecture.md, "The client").
 *
 * Two parts, kept apart so that a windowed client reuses the same renderer:
 *
 *   mts_render_context  (egl.h) the EGL display + GLES 3 context (+ surface):
 *                       either headless, on Mesa's surfaceless platform,
 *                       current with no surface (EGL_KHR_surfaceless_context),
 *                       or on a native X11 window (EGL window surface), which
 *                       adds a present step: blit the renderer's frame to the
 *                       window, draw any overlay (a HUD) there, swap. Nothing
 *                       below changes: the frame is still drawn offscreen, so
 *                       a window's screenshot is the same picture as headless.
 *   mts_renderer        GL state only: buffers, shader, an offscreen
 *                       framebuffer (RGBA8 colour + 24-bit depth) of the
 *                       requested size. Every frame is drawn there, so it can
 *                       always be read back. Several renderers may share one
 *                       context; each call makes the context current first.
 *
 * Geometry, following the stream's shape:
 *   - One vertex buffer sized for the model's full vertex count up front:
 *     positions (3 floats) for all vertices, then normals (3 floats) for all
 *     vertices. It is filled by appending ranges, since a streaming client
 *     only ever appends vertices (stream order).
 *   - Where the layout says the model has colours (layout.colors), a second
 *     vertex buffer of 4 bytes a vertex: the colour as normalized RGBA8
 *     (8-bit sRGB red, green, blue as the model holds them, alpha 255: the
 *     4-byte stride every vertex fetch takes without conversion), appended
 *     with the positions. A model without colours has no such buffer, no
 *     such attribute and the program it always had: its bytes, uploads and
 *     draw are what they were.
 *   - One index buffer (GL_UNSIGNED_INT) holding every strip at a fixed place:
 *     strip s owns cap_s + 1 indices, cap_s being its length at the full
 *     level (the runtime's slot size). The strip's indices come first; the
 *     rest of its range is the restart index 0xFFFFFFFF, so the last entry is
 *     always a restart and a strip that shrank leaves no stale triangles (a
 *     run of restarts draws nothing: each one only ends the current
 *     primitive), and one glDrawElements(GL_TRIANGLE_STRIP) with
 *     GL_PRIMITIVE_RESTART_FIXED_INDEX would draw the whole model.
 *   - mts_render_update_strips keeps a host copy of the slots and, when a
 *     draw reads the slot buffer (colour by strip), re-uploads only the
 *     strips the runtime lists as changed, one glBufferSubData per strip
 *     covering max(old, new) length, or the whole buffer in one call when
 *     more than half the strips changed (the first upload after
 *     mts_lod_init, which marks every strip changed). The default draw never
 *     reads the slot buffer: it is left behind, and filled once when a draw
 *     that reads it comes; what the default draws goes up once a frame, at
 *     the first draw after a change (mts_render_stats counts every byte).
 *     The caller clears the runtime's changed list afterwards.
 *
 * The draw: a packed buffer of its own, rebuilt from the host copy of the
 * strips at the first draw after they changed (O(indices drawn), one
 * glBufferData). The packing is not the renderer's: it is follow.h's
 * (mts_follow_pack_strips over strips.h's mts_strips_pack, which
 * mts_follow_pack and so the browser page use too), so the page and the
 * native view draw the same arrays. It holds only the strips of 3 or more
 * indices, with 16-bit indices when vertex_capacity <= 65535, each strip
 * joined to the one before by repeating the previous strip's last index and
 * its own first, once more when that leaves it at an odd position: every
 * strip starts at an even position as after a restart, so keeps its winding,
 * and each window across a joint repeats an index, so draws nothing (2 or 3
 * indices a joint, no restart): one glDrawElements. Why (measured with
 * mts-bench-stream --draw-only on Mesa 22.3 llvmpipe): Mesa's draw module
 * runs its vertex pipeline once per restart-delimited piece (and once per
 * draw of a multi-draw), restarting its small vertex cache each time, and a
 * draw over the slots also walks their padding, which at coarse levels is
 * most of the buffer; one joined strip is one pipeline run whose cache spans
 * strips (figures: docs/strips.md, "Drawing them"). The draws it is measured
 * against -- the slot buffer with restarts, strip by strip, multi-draw, one
 * restart between packed strips, a triangle list -- are
 * client/drawmodes.h's, through the seam in render_internal.h. The stored
 * and streamed form stays the strips and their slots; the packed buffer is
 * the client's own.
 *
 * Colour by strip: a per-vertex attribute cannot carry a strip id (strips
 * share vertices), and gl_PrimitiveID (fragment shaders, GLES 3.2) numbers
 * the triangles of the whole draw call: on Mesa 22 it counts every window,
 * degenerate ones included, and a restart neither resets nor advances it.
 * Mapping it back to a strip would need a prefix sum of the current
 * max(0, length - 2) per strip in a texture, re-uploaded whenever a length
 * changes, and a binary search per fragment. Instead, with color_by_strip
 * the renderer draws strip by strip from the slot buffer with the strip's
 * colour in a uniform: slower, for inspection only.
 *
 * Shading: Lambert from a directional light above-left of the camera plus
 * ambient, per-vertex normals, the albedo the style's colour or, with
 * layout.colors, the vertex colour (interpolated across each triangle; both
 * taken as the sRGB values they are, unconverted: camera.h says why; colour
 * by strip and the wireframe's edges keep their uniform colours), back-face
 * culling of clockwise triangles
 * (counter-clockwise is front, as the strips' winding rule gives), depth test.
 * A winding error therefore shows as a hole.
 *
 * Camera: perspective, looking at the layout's bounding-box centre from the
 * direction given by yaw (about +Y, 0 = from +Z, positive turns towards +X)
 * and pitch (positive looks from above), at the distance where the box's
 * bounding sphere fits the narrower field of view with a 10% margin, divided
 * by zoom.
 *
 * Errors: every call returns an mts_result and fills mts_error (the EGL or GL
 * error named); nothing is printed. Not thread-safe: a context and its
 * renderers belong to one thread at a time. */
#ifndef MTS_RENDER_H
#define MTS_RENDER_H

#include <stdint.h>

#include "camera.h"
#include "egl.h"
#include "error.h"
#include "lod.h"

#define MTS_RENDER_RESTART_INDEX 0xFFFFFFFFu

/* ---- renderer --------------------------------------------------------- */

/* What the buffers are sized for: fixed for the renderer's life. */
typedef struct mts_render_layout {
    uint32_t vertex_capacity; /* full vertex count */
    uint32_t strip_count;
    const uint32_t *slot;     /* strip_count + 1 entries, slot[s+1]-slot[s] = strip s's
                                 longest length; copied at create */
    float bbox_min[3], bbox_max[3]; /* what the camera frames */
    uint32_t room; /* indices the slots may come to (they grow as a stream
                      announces them): 0 = slot[strip_count] */
    int colors;    /* a colour a vertex comes with the positions (see the top) */
} mts_render_layout;

/* The layout a runtime's model needs (its vertex count, bbox and slots, and
 * colours where the model has them: MTS_MODEL_COLORS). */
void mts_render_layout_from_lod(const mts_lod *lod, mts_render_layout *layout);


typedef struct mts_render_options {
    uint32_t width, height; /* framebuffer size, 1..GL_MAX_RENDERBUFFER_SIZE */
    mts_render_camera camera;
    mts_render_style style;
    /* Each draw waits for the frame (glFinish) and fills
     * stats.last_draw_seconds: for measurements (benchmarks, the budget LOD
     * policy). Off, a draw returns once GL has the commands; reading the
     * frame back waits for it anyway. */
    int timed;
} mts_render_options;

/* 512x512, yaw 30, pitch 20, zoom 1, fov 35, dark blue-grey background,
 * light grey surface, ambient 0.25, culling on, no wireframe
 * (dark edges when turned on), untimed.
 *
 * A zeroed options struct means the same but for the view's direction (yaw
 * and pitch 0: from +Z, level): where 0 is no usable value -- a size, zoom,
 * field of view, an all-zero colour -- the renderer takes the default, and
 * the zero flags are the defaults (culling on). ambient 0
 * is taken as the default too; a negative ambient means none. */
void mts_render_options_default(mts_render_options *opts);

typedef struct mts_renderer mts_renderer;

/* Creates the buffers (index buffer all restarts, vertex buffer unfilled), the
 * shader and the framebuffer. MTS_ERR_LIMIT when the layout exceeds what GL
 * can address (GLsizei index count, GL_MAX_ELEMENT_INDEX, buffer size). */
mts_result mts_renderer_create(mts_render_context *ctx, const mts_render_options *opts,
                               const mts_render_layout *layout, mts_renderer **r,
                               mts_error *err);
void mts_renderer_destroy(mts_renderer *r);

/* Uploads vertices first .. first+count-1 (3 floats each in positions and
 * normals; with layout.colors 3 bytes each in colors, 8-bit sRGB r, g, b as
 * mts_model.colors holds them, MTS_ERR_ARG when NULL; without, colors is
 * not read and may be NULL). Appending: first may not be beyond the
 * vertices already there (a range may be sent again, as after a resumed
 * stream) and first+count may not pass vertex_capacity (MTS_ERR_RANGE). */
mts_result mts_render_append_vertices(mts_renderer *r, uint32_t first, uint32_t count,
                                      const float *positions, const float *normals,
                                      const uint8_t *colors, mts_error *err);
uint32_t mts_render_vertex_count(const mts_renderer *r);

/* Sets strip s to the given indices (length <= its capacity; every index below
 * the vertices uploaded, else MTS_ERR_RANGE and nothing changes). One
 * glBufferSubData of max(old, new) length when the draw reads the slot
 * buffer (else the host copy only; see the top). The building block of
 * mts_render_update_strips, for callers without a runtime. */
mts_result mts_render_set_strip(mts_renderer *r, uint32_t s, const uint32_t *indices,
                                uint32_t length, mts_error *err);

/* Takes the strips lod lists as changed (see the top of this file), after
 * moving the slots lod has laid out anew (lod->relayout_from) within the
 * layout's room. Checks
 * first that lod has the layout's strip count, every changed strip fits its
 * slot and every index is below the vertices uploaded; on failure nothing is
 * uploaded. Leaves lod's changed list alone: the caller clears it. */
mts_result mts_render_update_strips(mts_renderer *r, const mts_lod *lod, mts_error *err);

void mts_render_set_camera(mts_renderer *r, const mts_render_camera *camera);
void mts_render_set_style(mts_renderer *r, const mts_render_style *style);

/* The camera's position (world space) and the view direction (unit, from the
 * eye towards the box centre), for callers that need the view (tests). */
void mts_render_eye(const mts_renderer *r, float eye[3], float dir[3]);

/* Draws a frame into the framebuffer. With options.timed it waits for it
 * (glFinish) and stats.last_draw_seconds is the frame's time, clear to
 * finish. */
mts_result mts_render_draw(mts_renderer *r, mts_error *err);

/* Windowed contexts: copies the last frame to the window surface (scaled
 * when the sizes differ) and leaves the window's framebuffer bound with a
 * viewport over all of it, for an overlay; then mts_render_context_swap.
 * MTS_ERR_ARG for a headless context. */
mts_result mts_render_blit(mts_renderer *r, mts_error *err);

/* blit + swap, for callers with no overlay. */
mts_result mts_render_present(mts_renderer *r, mts_error *err);

/* New framebuffer size (a window was resized): the renderbuffers are
 * reallocated and the camera's aspect follows; geometry stays. */
mts_result mts_render_resize(mts_renderer *r, uint32_t width, uint32_t height, mts_error *err);

/* Geomorphs: vertices first .. first+count-1 are drawn at
 * mix(from, their own, t) -- positions and normals, and colours with
 * layout.colors -- where from is given here (3 floats a vertex each, the
 * same count; from_colors 3 bytes a vertex, required with layout.colors,
 * else not read), t by mts_render_set_morph_t (0 until then). One range at
 * a time: a new call replaces it; count 0 turns morphing off. The vertex
 * shader picks the range by gl_VertexID (the index fetched), so strips and
 * the packed buffer are untouched: a morph costs one upload of its range's
 * 16 bytes a vertex (positions as given, normals in 10 bits a component;
 * 20 with colours, RGBA8), then a uniform a frame. The buffers for it are
 * made at the first call. */
mts_result mts_render_set_morph(mts_renderer *r, uint32_t first, uint32_t count,
                                const float *from_positions, const float *from_normals,
                                const uint8_t *from_colors, mts_error *err);
void mts_render_set_morph_t(mts_renderer *r, float t);

/* Rebuilds the wireframe's edges from the runtime's current strips: three
 * edges per non-degenerate triangle (shared edges twice: simpler than a
 * hash, and GL_LINES draws a repeat at the same depth). Call after the
 * strips changed while style.wireframe is on. */
mts_result mts_render_update_wireframe(mts_renderer *r, const mts_lod *lod, mts_error *err);

/* Reads the last frame, RGBA8, width*height*4 bytes, top row first. */
mts_result mts_render_read_rgba(mts_renderer *r, uint8_t *rgba, mts_error *err);

/* Reads the last frame and writes it as a PNG. */
mts_result mts_render_write_png(mts_renderer *r, const char *path, mts_error *err);

typedef struct mts_render_stats {
    uint32_t width, height;
    uint64_t vertex_buffer_bytes, index_buffer_bytes; /* GPU buffer sizes */
    uint32_t vertices;                                /* uploaded so far */
    /* totals since create or mts_render_reset_counters */
    uint64_t vertex_bytes_uploaded;
    uint64_t index_bytes_uploaded;
    uint64_t strip_uploads;   /* strips uploaded one by one */
    uint64_t full_uploads;    /* whole index buffer uploads */
    uint64_t packed_builds;   /* packed buffers rebuilt (their bytes are in
                               * index_bytes_uploaded too) */
    uint64_t packed_bytes;    /* the packed buffer now */
    uint64_t morph_bytes_uploaded; /* geomorph sources (in vertex_bytes_uploaded too) */
    int colors;               /* layout.colors: 28 bytes a vertex instead of 24 */
    /* the last mts_render_update_strips */
    uint32_t last_update_strips; /* strips it covered (all of them for a full upload) */
    uint64_t last_update_bytes;
    int last_update_full;
    /* the last mts_render_draw */
    double last_draw_seconds; /* options.timed: CPU time clear .. glFinish (monotonic) */
    uint32_t last_draw_calls;
    uint64_t last_draw_indices; /* indices submitted, restarts included */
    uint64_t last_draw_index_bytes; /* their bytes (the packed buffer may use 16 bits) */
    int multi_draw_available;   /* GL_EXT_multi_draw_arrays */
} mts_render_stats;

void mts_render_get_stats(const mts_renderer *r, mts_render_stats *stats);
void mts_render_reset_counters(mts_renderer *r);

#endif
