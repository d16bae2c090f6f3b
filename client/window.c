/* The native window: Xlib (window.h says why). */
#include "window.h"

#include <X11/Xlib.h>
#include <X11/Xutil.h>
#include <X11/keysym.h>
#include <stdlib.h>
#include <string.h>

struct mts_window {
    Display *dpy;
    Window win;
    Atom wm_delete;
    uint32_t width, height;
    int dragging; /* left button down */
    int last_x, last_y;
};

static const char *const key_names[MTS_KEY_COUNT] = {
    NULL, "+", "-", "PgUp", "PgDn", "Home", "End", "w", "c", "s", "q",
};

const char *mts_key_name(mts_key key)
{
    return key > MTS_KEY_NONE && key < MTS_KEY_COUNT ? key_names[key] : NULL;
}

mts_key mts_key_from_name(const char *name)
{
    for (int k = 1; k < MTS_KEY_COUNT; k++)
        if (!strcmp(name, key_names[k]))
            return (mts_key)k;
    return MTS_KEY_NONE;
}

mts_result mts_window_create(const char *title, uint32_t width, uint32_t height,
                             mts_window **out, mts_error *err)
{
    *out = NULL;
    const char *name = getenv("DISPLAY");
    Display *dpy = XOpenDisplay(NULL);
    if (!dpy)
        return mts_error_set(err, MTS_ERR_IO, "cannot open the X display %s",
                             name && *name ? name : "(DISPLAY is not set)");
    mts_window *w = calloc(1, sizeof *w);
    if (!w) {
        XCloseDisplay(dpy);
        return mts_error_set(err, MTS_ERR_NOMEM, "window");
    }
    w->dpy = dpy;
    w->width = width;
    w->height = height;
    int screen = DefaultScreen(dpy);
    XSetWindowAttributes attr = {0};
    attr.background_pixel = BlackPixel(dpy, screen);
    attr.event_mask = KeyPressMask | ButtonPressMask | ButtonReleaseMask | PointerMotionMask |
                      StructureNotifyMask | ExposureMask;
    w->win = XCreateWindow(dpy, RootWindow(dpy, screen), 0, 0, width, height, 0,
                           CopyFromParent, InputOutput, CopyFromParent,
                           CWBackPixel | CWEventMask, &attr);
    XStoreName(dpy, w->win, title ? title : "mts-client");
    /* the close button sends a message instead of killing the connection */
    w->wm_delete = XInternAtom(dpy, "WM_DELETE_WINDOW", False);
    XSetWMProtocols(dpy, w->win, &w->wm_delete, 1);
    XMapWindow(dpy, w->win);
    XFlush(dpy);
    *out = w;
    return MTS_OK;
}

void mts_window_destroy(mts_window *w)
{
    if (!w)
        return;
    XDestroyWindow(w->dpy, w->win);
    XCloseDisplay(w->dpy);
    free(w);
}

static mts_key key_of(KeySym k)
{
    switch (k) {
    case XK_plus: case XK_equal: case XK_KP_Add: return MTS_KEY_PLUS;
    case XK_minus: case XK_KP_Subtract: return MTS_KEY_MINUS;
    case XK_Prior: case XK_KP_Prior: return MTS_KEY_PAGE_UP;
    case XK_Next: case XK_KP_Next: return MTS_KEY_PAGE_DOWN;
    case XK_Home: case XK_KP_Home: return MTS_KEY_HOME;
    case XK_End: case XK_KP_End: return MTS_KEY_END;
    case XK_w: case XK_W: return MTS_KEY_W;
    case XK_c: case XK_C: return MTS_KEY_C;
    case XK_s: case XK_S: return MTS_KEY_S;
    case XK_q: case XK_Q: case XK_Escape: return MTS_KEY_Q;
    }
    return MTS_KEY_NONE;
}

int mts_window_poll(mts_window *w, mts_input *ev)
{
    memset(ev, 0, sizeof *ev);
    while (XPending(w->dpy) > 0) {
        XEvent x;
        XNextEvent(w->dpy, &x);
        switch (x.type) {
        case KeyPress: {
            char text[8];
            KeySym sym = NoSymbol;
            /* with the modifiers applied: '+' is shift+'=' on most layouts */
            XLookupString(&x.xkey, text, sizeof text, &sym, NULL);
            ev->key = key_of(sym);
            if (ev->key == MTS_KEY_NONE)
                continue;
            ev->type = MTS_INPUT_KEY;
            return 1;
        }
        case ButtonPress:
            if (x.xbutton.button == Button1) {
                w->dragging = 1;
                w->last_x = x.xbutton.x;
                w->last_y = x.xbutton.y;
                continue;
            }
            if (x.xbutton.button == Button4 || x.xbutton.button == Button5) {
                ev->type = MTS_INPUT_SCROLL;
                ev->steps = x.xbutton.button == Button4 ? 1 : -1;
                return 1;
            }
            continue;
        case ButtonRelease:
            if (x.xbutton.button == Button1)
                w->dragging = 0;
            continue;
        case MotionNotify: {
            if (!w->dragging || !(x.xmotion.state & Button1Mask))
                continue;
            /* fold a burst of motion into one drag */
            while (XCheckTypedWindowEvent(w->dpy, w->win, MotionNotify, &x))
                ;
            ev->type = MTS_INPUT_DRAG;
            ev->dx = x.xmotion.x - w->last_x;
            ev->dy = x.xmotion.y - w->last_y;
            w->last_x = x.xmotion.x;
            w->last_y = x.xmotion.y;
            if (ev->dx == 0 && ev->dy == 0)
                continue;
            return 1;
        }
        case ConfigureNotify:
            if ((uint32_t)x.xconfigure.width == w->width &&
                (uint32_t)x.xconfigure.height == w->height)
                continue;
            w->width = (uint32_t)x.xconfigure.width;
            w->height = (uint32_t)x.xconfigure.height;
            ev->type = MTS_INPUT_RESIZE;
            ev->width = w->width;
            ev->height = w->height;
            return 1;
        case ClientMessage:
            if ((Atom)x.xclient.data.l[0] != w->wm_delete)
                continue;
            ev->type = MTS_INPUT_CLOSE;
            return 1;
        default:
            continue;
        }
    }
    return 0;
}

int mts_window_fd(const mts_window *w)
{
    return ConnectionNumber(w->dpy);
}

void mts_window_size(const mts_window *w, uint32_t *width, uint32_t *height)
{
    *width = w->width;
    *height = w->height;
}

void *mts_window_native_display(const mts_window *w)
{
    return w->dpy;
}

unsigned long mts_window_native_window(const mts_window *w)
{
    return (unsigned long)w->win;
}
