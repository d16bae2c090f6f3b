/* The render context: an EGL display and a GLES 3 context, headless on
 * Mesa's surfaceless platform or with a window surface on X11 (render.h,
 * at the top, says how the renderer uses it). Every call returns an
 * mts_result and fills mts_error (the EGL call and error named); nothing is
 * printed. A context belongs to one thread at a time. */
#ifndef MTS_EGL_H
#define MTS_EGL_H

#include <stdint.h>

#include "error.h"

typedef struct mts_render_context mts_render_context;

/* EGL on EGL_PLATFORM_SURFACELESS_MESA (eglGetPlatformDisplayEXT), a GLES 3
 * context current with no surface. Fails with MTS_ERR_IO (the EGL call and
 * error named) where there is no usable EGL, e.g. no Mesa: callers that can
 * run without pictures (tests) skip then. */
mts_result mts_render_context_create_headless(mts_render_context **ctx, mts_error *err);

/* Destroys the context (destroy its renderers first). The EGL display is
 * left initialised: an EGL display is one per platform per process, shared
 * by every context on it (Mesa 22 has no EGL_KHR_display_reference), so
 * eglTerminate here would pull it from under any other context in the
 * process; and on Mesa each terminate unloads the driver, whose static
 * allocations (112 bytes on llvmpipe) leak once per terminate + initialise
 * cycle. EGL finalises the display at exit. Creating and destroying contexts
 * repeatedly is fine and reuses the display. */
void mts_render_context_destroy(mts_render_context *ctx);

/* EGL on an X11 window (EGL_EXT_platform_x11): native_display is the
 * window's Display*, native_window its Window (window.h gives both). A GLES
 * 3 context current with a window surface; swaps wait for vertical blank
 * where the server has one (swap interval 1). MTS_ERR_IO (the EGL call
 * named) when EGL has no X11 platform or no matching config. */
mts_result mts_render_context_create_window(void *native_display, unsigned long native_window,
                                            mts_render_context **ctx, mts_error *err);

/* The window surface's size in pixels (0 x 0 when headless). */
void mts_render_context_surface_size(const mts_render_context *ctx, uint32_t *width,
                                     uint32_t *height);

/* Shows what was drawn to the window surface (eglSwapBuffers). MTS_ERR_ARG
 * for a headless context. */
mts_result mts_render_context_swap(mts_render_context *ctx, mts_error *err);

mts_result mts_render_context_make_current(mts_render_context *ctx, mts_error *err);

/* "GL_RENDERER | GL_VERSION", e.g. "llvmpipe (LLVM 15.0.6, 256 bits) |
 * OpenGL ES 3.2 Mesa 22.3.6". */
const char *mts_render_context_description(const mts_render_context *ctx);

/* Whether the context has a window surface (mts_render_context_create_window). */
int mts_render_context_has_window(const mts_render_context *ctx);

#endif
