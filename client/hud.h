/* The heads-up display of `mts-client --window`: lines of text drawn over
 * the window's frame with GLES 3, in a built-in 5x7 bitmap font (ASCII 32 to
 * 126; other bytes show as '?'), on a translucent box so it reads over any
 * model. The font is baked into a byte array and uploaded once as a small
 * texture; each frame the text becomes one buffer of textured quads drawn in
 * one call. No font library, no files.
 *
 * Drawn into whatever framebuffer is bound (mts_render_blit leaves the
 * window's bound), so screenshots of the renderer's own frame do not carry
 * it. Errors name the GL call; nothing is printed. Not thread-safe. */
#ifndef MTS_HUD_H
#define MTS_HUD_H

#include <stdint.h>

#include "error.h"
#include "render.h"

typedef struct mts_hud mts_hud;

/* Makes ctx current and creates the shader, the font texture and buffers. */
mts_result mts_hud_create(mts_render_context *ctx, mts_hud **hud, mts_error *err);
void mts_hud_destroy(mts_hud *hud);

/* Draws text ('\n' between lines) at the top left of the bound framebuffer,
 * which is fb_width x fb_height pixels, each font pixel scale x scale
 * (1..8). Leaves blending off and depth testing off. */
mts_result mts_hud_draw(mts_hud *hud, const char *text, uint32_t fb_width, uint32_t fb_height,
                        int scale, mts_error *err);

/* Clears the bound framebuffer (fb_width x fb_height) to rgb: a window
 * with nothing to show yet (before the base mesh) still gets a clean frame. */
mts_result mts_hud_clear(mts_hud *hud, const float rgb[3], uint32_t fb_width, uint32_t fb_height,
                         mts_error *err);

/* The 5x7 glyph of an ASCII byte: 5 columns, bit r of column c set when
 * row r (0 = top) is lit; '?' for bytes outside 32..126. For tests. */
const uint8_t *mts_hud_glyph(unsigned char c);

#endif
