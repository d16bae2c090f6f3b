/* PNG output through libpng's simplified write API: it reports failures in
 * png_image.message instead of printing or longjmp-ing out, and a negative
 * row stride reads a bottom-up buffer, so no copy is needed to flip. */
#include "pngwrite.h"

#include "fileio.h"

#include <errno.h>
#include <png.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

mts_result mts_png_encode_rgba(uint32_t width, uint32_t height, const uint8_t *pixels,
                               int bottom_up, uint8_t **png, size_t *size, mts_error *err)
{
    if (!png || !size || !pixels)
        return mts_error_set(err, MTS_ERR_ARG, "png: NULL argument");
    *png = NULL;
    *size = 0;
    if (width == 0 || height == 0 || width > MTS_PNG_MAX_SIDE || height > MTS_PNG_MAX_SIDE)
        return mts_error_set(err, MTS_ERR_ARG, "png: size %ux%u out of range 1..%u", width,
                             height, MTS_PNG_MAX_SIDE);

    png_image image;
    memset(&image, 0, sizeof image);
    image.version = PNG_IMAGE_VERSION;
    image.width = width;
    image.height = height;
    image.format = PNG_FORMAT_RGBA;

    png_int_32 stride = (png_int_32)(width * 4u);
    if (bottom_up)
        stride = -stride;
    /* The worst case (stored, not compressed) bounds what libpng writes. */
    png_alloc_size_t cap = PNG_IMAGE_PNG_SIZE_MAX(image);
    uint8_t *buf = malloc(cap);
    if (!buf)
        return mts_error_set(err, MTS_ERR_NOMEM, "png: %zu bytes for %ux%u", (size_t)cap,
                             width, height);
    png_alloc_size_t n = cap;
    if (!png_image_write_to_memory(&image, buf, &n, 0, pixels, stride, NULL)) {
        mts_result rc = mts_error_set(err, MTS_ERR_INTERNAL, "png: libpng: %s",
                                      image.message[0] ? image.message : "write failed");
        png_image_free(&image);
        free(buf);
        return rc;
    }
    png_image_free(&image);
    *png = buf;
    *size = n;
    return MTS_OK;
}

mts_result mts_png_write_rgba(const char *path, uint32_t width, uint32_t height,
                              const uint8_t *pixels, int bottom_up, mts_error *err)
{
    if (!path)
        return mts_error_set(err, MTS_ERR_ARG, "png: NULL path");
    uint8_t *buf = NULL;
    size_t size = 0;
    mts_result rc = mts_png_encode_rgba(width, height, pixels, bottom_up, &buf, &size, err);
    if (rc != MTS_OK) {
        if (err)
            mts_error_prefix(err, "%s", path);
        return rc;
    }

    rc = mts_file_write_atomic(path, buf, size, err);
    free(buf);
    return rc;
}
