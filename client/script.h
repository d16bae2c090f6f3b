/* Scripted input for `mts-client --window --script FILE`: the same events a
 * user makes, at set times, so a test (or a demo) drives the window with no
 * one at the keyboard. One event a line, seconds since the model's first
 * frame first (the base mesh on screen: keys before it would have nothing
 * to act on):
 *
 *   0.5 key End        a key, named as in window.h: + - PgUp PgDn Home End w c s q
 *   1.2 drag 40 -10    a left-button drag by (dx, dy) pixels
 *   1.4 scroll -2      wheel steps (positive zooms in)
 *
 * Blank lines and lines starting with '#' are skipped. Times may not go
 * backwards. A malformed line is an error naming the file, the line number
 * and the line. */
#ifndef MTS_SCRIPT_H
#define MTS_SCRIPT_H

#include <stddef.h>

#include "error.h"
#include "window.h"

typedef struct mts_script_event {
    double t; /* seconds */
    mts_input input;
    unsigned line;
} mts_script_event;

typedef struct mts_script {
    mts_script_event *events;
    size_t count, next;
} mts_script;

/* name is what errors call the text (the file name). */
mts_result mts_script_parse(const char *text, const char *name, mts_script *script,
                            mts_error *err);
mts_result mts_script_load(const char *path, mts_script *script, mts_error *err);
void mts_script_free(mts_script *script);

/* The next event due by time t: 1 and *ev filled (in file order), 0 when
 * none is due yet. */
int mts_script_next(mts_script *script, double t, mts_input *ev);
/* All events given out. */
int mts_script_done(const mts_script *script);

#endif
