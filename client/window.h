/* A native window and its input, for `mts-client --window`.
 *
 * Xlib, not GLFW: libX11 is already on every machine with Mesa's EGL (EGL's
 * X11 platform takes a Display* and a Window straight from it), and it lets
 * the client do all it needs -- a window, keys, pointer, close button -- with
 * no further library. GLFW would add a dependency and its own context
 * handling on top of the EGL context the renderer already makes.
 *
 * The window does no drawing: mts_render_context_create_window makes an EGL
 * window surface from mts_window_native_display/_window. Events are polled
 * without blocking; the raw X events are turned into the few the client
 * knows (a key of the list below, a left-button drag in pixels, wheel steps,
 * a new size, the close button), so a --script can feed the very same ones.
 *
 * Errors: create fails with MTS_ERR_IO when there is no X display ($DISPLAY
 * unset or unreachable). Nothing is printed. One thread. */
#ifndef MTS_WINDOW_H
#define MTS_WINDOW_H

#include <stdint.h>

#include "error.h"

typedef enum mts_key {
    MTS_KEY_NONE = 0,
    MTS_KEY_PLUS,      /* "+": one batch of levels up (also '=' and keypad +) */
    MTS_KEY_MINUS,     /* "-": one batch down (also keypad -) */
    MTS_KEY_PAGE_UP,   /* "PgUp": 10% of the levels up */
    MTS_KEY_PAGE_DOWN, /* "PgDn": 10% down */
    MTS_KEY_HOME,      /* "Home": the base mesh */
    MTS_KEY_END,       /* "End": the highest level received */
    MTS_KEY_W,         /* "w": wireframe on/off */
    MTS_KEY_C,         /* "c": colour per strip on/off */
    MTS_KEY_S,         /* "s": screenshot */
    MTS_KEY_Q,         /* "q": quit (also Escape) */
    MTS_KEY_COUNT
} mts_key;

/* "+", "-", "PgUp", "PgDn", "Home", "End", "w", "c", "s", "q" (the names
 * --script uses); NULL for MTS_KEY_NONE or out of range. */
const char *mts_key_name(mts_key key);
/* The key of a name above (exact match), MTS_KEY_NONE when none. */
mts_key mts_key_from_name(const char *name);

typedef enum mts_input_type {
    MTS_INPUT_NONE = 0,
    MTS_INPUT_KEY,    /* key */
    MTS_INPUT_DRAG,   /* dx, dy: pointer motion in pixels with the left button down */
    MTS_INPUT_SCROLL, /* steps: wheel, positive away from the user (zoom in) */
    MTS_INPUT_RESIZE, /* width, height */
    MTS_INPUT_CLOSE   /* the window manager's close button */
} mts_input_type;

typedef struct mts_input {
    mts_input_type type;
    mts_key key;
    int dx, dy;
    int steps;
    uint32_t width, height;
} mts_input;

typedef struct mts_window mts_window;

mts_result mts_window_create(const char *title, uint32_t width, uint32_t height,
                             mts_window **window, mts_error *err);
void mts_window_destroy(mts_window *window);

/* The next input event without waiting: 1 and *ev filled, 0 when none is
 * pending. Events the client has no use for are dropped here. */
int mts_window_poll(mts_window *window, mts_input *ev);

/* The X connection's descriptor, for poll() alongside the network. */
int mts_window_fd(const mts_window *window);

void mts_window_size(const mts_window *window, uint32_t *width, uint32_t *height);

/* For EGL's X11 platform: the Display* and the Window (an XID). */
void *mts_window_native_display(const mts_window *window);
unsigned long mts_window_native_window(const mts_window *window);

#endif
