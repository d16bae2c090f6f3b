/* What the headless-GL tests share (test_render, test_view): the skip where
 * there is no EGL context (a failure with MTS_TEST_REQUIRE_EGL=1, as in CI)
 * or the cow did not build, and frames compared pixel by pixel. */
#ifndef MTS_TEST_GL_H
#define MTS_TEST_GL_H

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "test.h"

#define MTS_TEST_NEED_GL(t, ctx, ctx_err, cow_ok)                                       \
    do {                                                                               \
        if (!(ctx)) {                                                                  \
            const char *req_ = getenv("MTS_TEST_REQUIRE_EGL");                         \
            if (req_ && *req_ && strcmp(req_, "0") != 0) {                             \
                CHECKF(t, 0, "no EGL context: %s", (ctx_err).msg);                     \
                return;                                                                \
            }                                                                          \
            SKIP(t, "no EGL context: %s", (ctx_err).msg);                              \
        }                                                                              \
        if (!(cow_ok)) {                                                               \
            CHECKF(t, 0, "the cow did not build");                                     \
            return;                                                                    \
        }                                                                              \
    } while (0)

/* Does RGBA pixel a differ from b by more than tol in a colour channel? */
static inline int mts_test_pixel_differs(const uint8_t *a, const uint8_t *b, int tol)
{
    for (int c = 0; c < 3; c++) {
        int d = (int)a[c] - (int)b[c];
        if (d > tol || d < -tol)
            return 1;
    }
    return 0;
}

/* RGBA pixels of two frames of `pixels` pixels that differ by more than tol. */
static inline uint32_t mts_test_pixels_differing(const uint8_t *a, const uint8_t *b,
                                                 size_t pixels, int tol)
{
    uint32_t n = 0;
    for (size_t i = 0; i < pixels; i++)
        n += (uint32_t)mts_test_pixel_differs(a + 4 * i, b + 4 * i, tol);
    return n;
}

#endif
