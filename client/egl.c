/* The render context: EGL on Mesa's surfaceless platform or on an X11
 * window (egl.h). */
#include "egl.h"

#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <GLES3/gl3.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifndef EGL_PLATFORM_SURFACELESS_MESA
#define EGL_PLATFORM_SURFACELESS_MESA 0x31DD
#endif
#ifndef EGL_PLATFORM_X11_EXT
#define EGL_PLATFORM_X11_EXT 0x31D5
#endif

struct mts_render_context {
    EGLDisplay display;
    EGLContext context;
    EGLSurface surface; /* EGL_NO_SURFACE when headless */
    char description[256];
};

static const char *egl_error_name(EGLint e)
{
    switch (e) {
    case EGL_SUCCESS: return "EGL_SUCCESS";
    case EGL_NOT_INITIALIZED: return "EGL_NOT_INITIALIZED";
    case EGL_BAD_ACCESS: return "EGL_BAD_ACCESS";
    case EGL_BAD_ALLOC: return "EGL_BAD_ALLOC";
    case EGL_BAD_ATTRIBUTE: return "EGL_BAD_ATTRIBUTE";
    case EGL_BAD_CONFIG: return "EGL_BAD_CONFIG";
    case EGL_BAD_CONTEXT: return "EGL_BAD_CONTEXT";
    case EGL_BAD_CURRENT_SURFACE: return "EGL_BAD_CURRENT_SURFACE";
    case EGL_BAD_DISPLAY: return "EGL_BAD_DISPLAY";
    case EGL_BAD_MATCH: return "EGL_BAD_MATCH";
    case EGL_BAD_NATIVE_PIXMAP: return "EGL_BAD_NATIVE_PIXMAP";
    case EGL_BAD_NATIVE_WINDOW: return "EGL_BAD_NATIVE_WINDOW";
    case EGL_BAD_PARAMETER: return "EGL_BAD_PARAMETER";
    case EGL_BAD_SURFACE: return "EGL_BAD_SURFACE";
    case EGL_CONTEXT_LOST: return "EGL_CONTEXT_LOST";
    }
    return "unknown EGL error";
}

static mts_result egl_fail(mts_error *err, const char *what)
{
    EGLint e = eglGetError();
    return mts_error_set(err, MTS_ERR_IO, "EGL: %s failed: %s (0x%04x)", what,
                         egl_error_name(e), (unsigned)e);
}

/* Whole-word search in a space-separated extension list. */
static int has_extension(const char *list, const char *name)
{
    if (!list)
        return 0;
    size_t n = strlen(name);
    for (const char *p = list; (p = strstr(p, name)) != NULL; p += n) {
        if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == 0))
            return 1;
    }
    return 0;
}

/* The display of an EGL platform (its client extension checked first), in a
 * new context struct with neither surface nor context yet. */
static mts_result open_display(const char *extension, EGLenum platform, void *native,
                               const char *name, mts_render_context **out, mts_error *err)
{
    const char *client_ext = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    if (!client_ext)
        return egl_fail(err, "eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS)");
    if (!has_extension(client_ext, extension))
        return mts_error_set(err, MTS_ERR_IO,
                             "EGL: no %s (is Mesa's libEGL installed? client extensions: "
                             "%.300s)",
                             extension, *client_ext ? client_ext : "none");
    PFNEGLGETPLATFORMDISPLAYEXTPROC get_platform_display =
        (PFNEGLGETPLATFORMDISPLAYEXTPROC)eglGetProcAddress("eglGetPlatformDisplayEXT");
    if (!get_platform_display)
        return mts_error_set(err, MTS_ERR_IO, "EGL: no eglGetPlatformDisplayEXT");
    mts_render_context *c = calloc(1, sizeof *c);
    if (!c)
        return mts_error_set(err, MTS_ERR_NOMEM, "render: context");
    c->surface = EGL_NO_SURFACE;
    c->context = EGL_NO_CONTEXT;
    char what[120];
    c->display = get_platform_display(platform, native, NULL);
    if (c->display == EGL_NO_DISPLAY) {
        snprintf(what, sizeof what, "eglGetPlatformDisplayEXT (%s platform)", name);
        mts_result rc = egl_fail(err, what);
        free(c);
        return rc;
    }
    EGLint major = 0, minor = 0;
    if (!eglInitialize(c->display, &major, &minor)) {
        snprintf(what, sizeof what, "eglInitialize (%s platform)", name);
        mts_result rc = egl_fail(err, what);
        free(c);
        return rc;
    }
    *out = c;
    return MTS_OK;
}

/* A GLES 3 config with these attributes, and the GLES API bound. */
static mts_result choose_config(mts_render_context *c, const EGLint *attribs, const char *kind,
                                EGLConfig *config, mts_error *err)
{
    EGLint configs = 0;
    if (!eglChooseConfig(c->display, attribs, config, 1, &configs))
        return egl_fail(err, "eglChooseConfig");
    if (configs < 1)
        return mts_error_set(err, MTS_ERR_IO, "EGL: no %s config with EGL_OPENGL_ES3_BIT", kind);
    if (!eglBindAPI(EGL_OPENGL_ES_API))
        return egl_fail(err, "eglBindAPI(EGL_OPENGL_ES_API)");
    return MTS_OK;
}

/* A GLES 3.0 context on config, current on c's surface (or none). */
static mts_result make_context(mts_render_context *c, EGLConfig config, mts_error *err)
{
    const EGLint context_attribs[] = {EGL_CONTEXT_MAJOR_VERSION, 3, EGL_CONTEXT_MINOR_VERSION,
                                      0, EGL_NONE};
    c->context = eglCreateContext(c->display, config, EGL_NO_CONTEXT, context_attribs);
    if (c->context == EGL_NO_CONTEXT)
        return egl_fail(err, "eglCreateContext (GLES 3.0)");
    if (!eglMakeCurrent(c->display, c->surface, c->surface, c->context))
        return egl_fail(err, c->surface == EGL_NO_SURFACE ? "eglMakeCurrent (no surface)"
                                                          : "eglMakeCurrent (window)");
    const char *renderer = (const char *)glGetString(GL_RENDERER);
    const char *version = (const char *)glGetString(GL_VERSION);
    snprintf(c->description, sizeof c->description, "%s | %s", renderer ? renderer : "?",
             version ? version : "?");
    return MTS_OK;
}

mts_result mts_render_context_create_headless(mts_render_context **out, mts_error *err)
{
    if (!out)
        return mts_error_set(err, MTS_ERR_ARG, "render: NULL context pointer");
    *out = NULL;
    mts_render_context *c = NULL;
    mts_result rc = open_display("EGL_MESA_platform_surfaceless", EGL_PLATFORM_SURFACELESS_MESA,
                                 EGL_DEFAULT_DISPLAY, "surfaceless", &c, err);
    if (rc != MTS_OK)
        return rc;
    if (!has_extension(eglQueryString(c->display, EGL_EXTENSIONS),
                       "EGL_KHR_surfaceless_context")) {
        rc = mts_error_set(err, MTS_ERR_IO, "EGL: display has no EGL_KHR_surfaceless_context");
        goto fail;
    }
    /* EGL_SURFACE_TYPE 0: no surface needed (the default asks for windows). */
    const EGLint config_attribs[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_ES3_BIT,
                                     EGL_SURFACE_TYPE, 0, EGL_NONE};
    EGLConfig config;
    if ((rc = choose_config(c, config_attribs, "surfaceless", &config, err)) != MTS_OK ||
        (rc = make_context(c, config, err)) != MTS_OK)
        goto fail;
    *out = c;
    return MTS_OK;
fail:
    mts_render_context_destroy(c);
    return rc;
}

mts_result mts_render_context_create_window(void *native_display, unsigned long native_window,
                                            mts_render_context **out, mts_error *err)
{
    if (!out || !native_display)
        return mts_error_set(err, MTS_ERR_ARG, "render: NULL argument to create_window");
    *out = NULL;
    PFNEGLCREATEPLATFORMWINDOWSURFACEEXTPROC create_window_surface =
        (PFNEGLCREATEPLATFORMWINDOWSURFACEEXTPROC)eglGetProcAddress(
            "eglCreatePlatformWindowSurfaceEXT");
    if (!create_window_surface)
        return mts_error_set(err, MTS_ERR_IO, "EGL: no eglCreatePlatformWindowSurfaceEXT");
    mts_render_context *c = NULL;
    mts_result rc = open_display("EGL_EXT_platform_x11", EGL_PLATFORM_X11_EXT, native_display,
                                 "X11", &c, err);
    if (rc != MTS_OK)
        return rc;
    /* 8-bit RGB: the window shows the renderer's RGBA8 frame as it is; no
     * depth here, the renderer's framebuffer has its own */
    const EGLint config_attribs[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_ES3_BIT,
                                     EGL_SURFACE_TYPE, EGL_WINDOW_BIT,
                                     EGL_RED_SIZE, 8, EGL_GREEN_SIZE, 8, EGL_BLUE_SIZE, 8,
                                     EGL_NONE};
    EGLConfig config;
    if ((rc = choose_config(c, config_attribs, "window", &config, err)) != MTS_OK)
        goto fail;
    /* EGL_EXT_platform_x11: the native window is passed as a Window* */
    unsigned long xid = native_window;
    c->surface = create_window_surface(c->display, config, &xid, NULL);
    if (c->surface == EGL_NO_SURFACE) {
        rc = egl_fail(err, "eglCreatePlatformWindowSurfaceEXT");
        goto fail;
    }
    if ((rc = make_context(c, config, err)) != MTS_OK)
        goto fail;
    eglSwapInterval(c->display, 1); /* a hint: servers without vblank ignore it */
    *out = c;
    return MTS_OK;
fail:
    mts_render_context_destroy(c);
    return rc;
}

void mts_render_context_surface_size(const mts_render_context *c, uint32_t *width,
                                     uint32_t *height)
{
    EGLint w = 0, h = 0;
    if (c && c->surface != EGL_NO_SURFACE) {
        eglQuerySurface(c->display, c->surface, EGL_WIDTH, &w);
        eglQuerySurface(c->display, c->surface, EGL_HEIGHT, &h);
    }
    *width = w > 0 ? (uint32_t)w : 0;
    *height = h > 0 ? (uint32_t)h : 0;
}

mts_result mts_render_context_swap(mts_render_context *c, mts_error *err)
{
    if (!c || c->surface == EGL_NO_SURFACE)
        return mts_error_set(err, MTS_ERR_ARG, "render: swap on a context without a window");
    mts_result rc = mts_render_context_make_current(c, err);
    if (rc != MTS_OK)
        return rc;
    if (!eglSwapBuffers(c->display, c->surface))
        return egl_fail(err, "eglSwapBuffers");
    return MTS_OK;
}

void mts_render_context_destroy(mts_render_context *c)
{
    if (!c)
        return;
    if (c->display != EGL_NO_DISPLAY) {
        /* unbind only our own context: another may be current */
        if (c->context != EGL_NO_CONTEXT && eglGetCurrentContext() == c->context)
            eglMakeCurrent(c->display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
        if (c->surface != EGL_NO_SURFACE)
            eglDestroySurface(c->display, c->surface);
        if (c->context != EGL_NO_CONTEXT)
            eglDestroyContext(c->display, c->context);
        /* no eglTerminate: the display is the process's (egl.h) */
    }
    /* frees this thread's EGL state (bound API, last error) unless some
     * other context is still current on it */
    if (eglGetCurrentContext() == EGL_NO_CONTEXT)
        eglReleaseThread();
    free(c);
}

mts_result mts_render_context_make_current(mts_render_context *c, mts_error *err)
{
    if (!c)
        return mts_error_set(err, MTS_ERR_ARG, "render: NULL context");
    if (eglGetCurrentContext() == c->context)
        return MTS_OK;
    if (!eglMakeCurrent(c->display, c->surface, c->surface, c->context))
        return egl_fail(err, "eglMakeCurrent");
    return MTS_OK;
}

const char *mts_render_context_description(const mts_render_context *c)
{
    return c ? c->description : "";
}

int mts_render_context_has_window(const mts_render_context *c)
{
    return c && c->surface != EGL_NO_SURFACE;
}
