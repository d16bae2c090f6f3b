/* The browser's decoder: the native client's stream decoder (protocol/,
 * common/: wire reader, stream client, growth, LOD runtime) behind a few
 * calls a page makes from JavaScript. The page moves bytes (WebSocket
 * messages in, HELLO and LIST out) and draws what mts_web_pack gives it;
 * everything else is the C the native client runs.
 *
 * A stream file (protocol/stream_file.h) is read the same way: the page
 * fetches byte ranges of it with HTTP Range requests and hands them to
 * the mts_web_file_* calls, which feed the same stream client.
 *
 * A view runtime of its own (as client/view.c's own_runtime) lets the page
 * show any level received while the stream goes on; mts_web_pack lays the
 * shown level's strips out as one joined strip (mts_strips_pack, the native
 * renderer's default draw) and says where each strip starts in it, for
 * colour by strip.
 *
 * Errors: the calls return an mts_result; mts_web_error says what went
 * wrong. Nothing is printed. The calls are made from one thread; built
 * with -pthread the decoder may run a pool thread beside it
 * (mts_web_set_threads). */
#ifndef MTS_WEB_H
#define MTS_WEB_H

#include <stddef.h>
#include <stdint.h>

#include "error.h"

typedef struct mts_web mts_web;

mts_web *mts_web_create(void);
void mts_web_destroy(mts_web *w);

/* The stream decoder's threads (mts_stream_client.threads), before the
 * first bytes: 2 runs a pool thread beside the caller's where the module
 * was built with -pthread (more are taken as 2; without -pthread, always
 * 1). Returns the count asked for. The decoder falls back to one thread
 * where the pool thread cannot start; mts_web_threads says the most that
 * decoded (mts_stream_client_threads_used; 1 before the base mesh). */
uint32_t mts_web_set_threads(mts_web *w, uint32_t n);
uint32_t mts_web_threads(const mts_web *w);

/* The first frame to send: a HELLO for model (stop_kind/stop_value as
 * PROTOCOL.md's HELLO, flags its flags), or a LIST. The bytes stay valid
 * until the next call; mts_web_out_size says how many. */
const uint8_t *mts_web_hello(mts_web *w, const char *model, uint32_t stop_kind,
                             uint32_t stop_value, uint32_t flags);
const uint8_t *mts_web_list(mts_web *w);
size_t mts_web_out_size(const mts_web *w);

/* Bytes from the server, in order, in any pieces. MTS_OK, or the error
 * that ended the stream (a server's ERROR frame too): nothing more is
 * taken after one. */
mts_result mts_web_feed(mts_web *w, const uint8_t *data, size_t size);

/* ---- a stream file (PROTOCOL.md, "Stream files") -------------------------
 * The conversation the native client has (client/webfile.c), the fetching
 * left to the page:
 *   1. fetch the file's first MTS_SFILE_FIRST_REQUEST (4096) bytes;
 *      mts_web_file_prefix_size says how many its prefix takes: fetch the
 *      rest of those when it is more, then mts_web_file_index;
 *   2. mts_web_file_plan for a stop, then mts_web_file_begin; fetch
 *      [mts_web_file_from, mts_web_file_to) and hand the bytes, in order,
 *      to mts_web_file_feed as they arrive (those of the prefix's request
 *      that fall in the range first); a server that ignored the range
 *      (a 200 with the whole file) is cut to it by the page: bytes past the
 *      range are refused;
 *   3. once mts_web_file_done: mts_web_file_end verifies the stop against
 *      the file's checks and ends the stream as END does (state 3).
 * A range that broke (a cut, a server down), or a higher stop once the
 * last ended, is step 2 again: the plan starts at the first batch not held
 * (mts_web_file_resume_point) and begin readies the client for it, the
 * index and the checks already read kept. Offsets are doubles: exact up to
 * 2^53, and what JavaScript's numbers hold. Errors are fatal to the
 * stream, as mts_web_feed's, and mts_web_error says what. */

/* From the file's first bytes (at least its 32-byte header): the size of
 * its prefix (header, MODEL_INFO, table); -1 when it is not a stream file
 * this reads, or is over 1 GiB. */
double mts_web_file_prefix_size(mts_web *w, const uint8_t *data, size_t size);
/* Parses the index from the file's first bytes (at least the prefix). */
mts_result mts_web_file_index(mts_web *w, const uint8_t *data, size_t size);
double mts_web_file_size(const mts_web *w); /* the file's, as its header says */
/* The first batch not held (0: from BASE, a fresh start); -1 when nothing
 * can resume (the stream failed). */
int mts_web_file_resume_point(const mts_web *w);
/* Plans a stop (stop_kind/stop_value as HELLO's) from the resume point:
 * the bytes to fetch are [mts_web_file_from, mts_web_file_to). */
mts_result mts_web_file_plan(mts_web *w, uint32_t stop_kind, uint32_t stop_value);
double mts_web_file_from(const mts_web *w);
double mts_web_file_to(const mts_web *w);
/* Starts the planned range: a fresh stream, a resume after a broken range
 * or, once the last ended, a continuation to the higher stop. */
mts_result mts_web_file_begin(mts_web *w);
mts_result mts_web_file_feed(mts_web *w, const uint8_t *data, size_t size);
int mts_web_file_done(const mts_web *w); /* 1 once every byte of the range came */
mts_result mts_web_file_end(mts_web *w);

/* ---- what came ----------------------------------------------------------- */
const char *mts_web_error(const mts_web *w);   /* "" while all is well */
int mts_web_state(const mts_web *w);           /* 0 waiting, 1 info, 2 base in, 3 ended, 4 models */
uint32_t mts_web_received_level(const mts_web *w); /* levels decoded, up to the stop */
uint32_t mts_web_stop_level(const mts_web *w);
uint32_t mts_web_level_count(const mts_web *w);
uint32_t mts_web_vertices(const mts_web *w);   /* vertices present */
uint32_t mts_web_batches(const mts_web *w);
const char *mts_web_checksum(const mts_web *w);  /* ours, 16 hex digits ("" before END) */
const char *mts_web_server_checksum(const mts_web *w);
const float *mts_web_positions(const mts_web *w); /* 3 floats a vertex; moves as vertices come */
const float *mts_web_normals(const mts_web *w);
/* 1 when the model has a colour a vertex (MODEL_INFO's MTS_INFO_COLORS, the
 * colours come with the vertices). */
int mts_web_has_colors(const mts_web *w);
/* The colours of vertices first .. first+count-1 as RGBA8 (8-bit sRGB as the
 * stream holds them, alpha 255; 4 bytes a vertex, the native renderer's
 * layout), valid until the next call of this or
 * mts_web_morph_from_colors_rgba; NULL without colours or past the
 * vertices present. */
const uint8_t *mts_web_colors_rgba(mts_web *w, uint32_t first, uint32_t count);
const float *mts_web_bbox(const mts_web *w);      /* min xyz, max xyz of the full model */
const char *mts_web_models(const mts_web *w);     /* after a LIST: "name vertices triangles levels\n"... */

/* ---- what to draw ---------------------------------------------------------- */

/* Moves the view towards level (at most what came; through a geomorph
 * where mts_web_set_morph_ms asked for one, now_ms on a monotonic clock)
 * and packs it. */
mts_result mts_web_show(mts_web *w, uint32_t level, double now_ms);

/* Geomorphs (client/morph.h): ms a level change slides over (0, the
 * default: at once). While one runs (mts_web_morph_active), vertex ids
 * [first, first + count) are drawn between mts_web_morph_from's places
 * (count positions, then count normals, 3 floats each) and their own by
 * mts_web_morph_t; mts_web_morph_serial changes when the range does (its
 * from-places to upload again). */
void mts_web_set_morph_ms(mts_web *w, double ms);
int mts_web_morph_active(const mts_web *w);
float mts_web_morph_t(const mts_web *w);
uint32_t mts_web_morph_first(const mts_web *w);
uint32_t mts_web_morph_count(const mts_web *w);
const float *mts_web_morph_from(const mts_web *w);
/* The range's from-colours (each vertex's ancestor's), RGBA8 as
 * mts_web_colors_rgba's and valid as long; NULL without colours or a range. */
const uint8_t *mts_web_morph_from_colors_rgba(mts_web *w);
uint32_t mts_web_morph_serial(const mts_web *w);
uint32_t mts_web_shown_level(const mts_web *w);
uint32_t mts_web_shown_triangles(const mts_web *w);
uint32_t mts_web_shown_strips(const mts_web *w);
/* The packed strip: mts_web_index_count() 32-bit indices; strip k of the
 * mts_web_strip_count() drawn starts at strip_first[k], strip_length[k] long. */
const uint32_t *mts_web_indices(const mts_web *w);
uint32_t mts_web_index_count(const mts_web *w);
uint32_t mts_web_strip_count(const mts_web *w);
const uint32_t *mts_web_strip_first(const mts_web *w);
const uint32_t *mts_web_strip_length(const mts_web *w);
/* 3 floats a strip drawn: its colour when drawn by strip (as the native
 * renderer's). */
const float *mts_web_strip_colors(const mts_web *w);

/* The native renderer's camera (client/camera.h) for the model's box: 25
 * floats, the 4x4 mvp then the 3x3 normal matrix, column-major; the field
 * of view is the native default's (35 degrees). */
const float *mts_web_camera(mts_web *w, float yaw_deg, float pitch_deg, float zoom, float aspect);

/* The native renderer's look (client/camera.h): 11 floats, background
 * RGBA, surface RGB, ambient, the light's direction in view space. */
const float *mts_web_style(mts_web *w);
/* 1 when the stream carries no normals: shade by the faces (u_flat). */
int mts_web_flat(const mts_web *w);
/* The shaders' GLSL bodies (fragment 0: vertex), as the native renderer's:
 * to follow "#version 300 es", "#define MORPH 0|1" and "#define COLORS 0|1"
 * (client/camera.h). */
const char *mts_web_shader(int fragment);

#endif
