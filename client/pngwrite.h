/* PNG output for rendered frames (libpng's simplified API). Named pngwrite.h,
 * not png.h, so that it never shadows libpng's <png.h> on an -Iclient path.
 * Pixels are RGBA8, 4 bytes a pixel, rows packed (width * 4 bytes each).
 * OpenGL reads rows bottom-up (its first row is the bottom of the picture):
 * pass bottom_up = 1 for such a buffer and the PNG comes out the right way
 * up. Errors come back in mts_error (libpng's own message included);
 * nothing is printed. */
#ifndef MTS_PNGWRITE_H
#define MTS_PNGWRITE_H

#include <stddef.h>
#include <stdint.h>

#include "error.h"

/* Largest width or height accepted (PNG allows 2^31-1; this keeps
 * width * height * 4 far inside size_t and libpng's own limits). */
#define MTS_PNG_MAX_SIDE 16384u

/* Encodes into a new buffer (free with free()). */
mts_result mts_png_encode_rgba(uint32_t width, uint32_t height, const uint8_t *pixels,
                               int bottom_up, uint8_t **png, size_t *size, mts_error *err);

/* Writes a PNG file atomically (a temporary file beside it, renamed into place). */
mts_result mts_png_write_rgba(const char *path, uint32_t width, uint32_t height,
                              const uint8_t *pixels, int bottom_up, mts_error *err);

#endif
