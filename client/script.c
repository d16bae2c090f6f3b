/* --script parsing (script.h has the format). */
#include "script.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>


static int parse_int(const char *s, int *out)
{
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (end == s || *end || errno || v < -100000 || v > 100000)
        return 0;
    *out = (int)v;
    return 1;
}

/* One line, already cut at '\n', comments and blanks dealt with. */
static mts_result parse_line(char line[256], const char *name, unsigned n, mts_script_event *ev,
                             mts_error *err)
{
    char shown[256]; /* the line as written, for errors (strtok_r cuts it up) */
    memcpy(shown, line, strlen(line) + 1);
    char *tok[5];
    int nt = 0;
    for (char *save = NULL, *t = strtok_r(line, " \t\r", &save); t;
         t = strtok_r(NULL, " \t\r", &save)) {
        if (nt == 5)
            return mts_error_set(err, MTS_ERR_FORMAT, "%s:%u: too many words in '%s'", name, n,
                                 shown);
        tok[nt++] = t;
    }
    char *end;
    double t = nt ? strtod(tok[0], &end) : 0;
    if (nt < 2 || end == tok[0] || *end || !isfinite(t) || t < 0 || t > 86400)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "%s:%u: '%s' does not start with a time in seconds and an event "
                             "(key NAME, drag DX DY, scroll STEPS)",
                             name, n, shown);
    memset(ev, 0, sizeof *ev);
    ev->t = t;
    ev->line = n;
    if (!strcmp(tok[1], "key") && nt == 3) {
        ev->input.type = MTS_INPUT_KEY;
        ev->input.key = mts_key_from_name(tok[2]);
        if (ev->input.key == MTS_KEY_NONE)
            return mts_error_set(err, MTS_ERR_FORMAT,
                                 "%s:%u: unknown key '%s' in '%s' (keys: + - PgUp PgDn Home End "
                                 "w c s q)",
                                 name, n, tok[2], shown);
    } else if (!strcmp(tok[1], "drag") && nt == 4) {
        ev->input.type = MTS_INPUT_DRAG;
        if (!parse_int(tok[2], &ev->input.dx) || !parse_int(tok[3], &ev->input.dy))
            return mts_error_set(err, MTS_ERR_FORMAT,
                                 "%s:%u: drag needs two whole numbers of pixels: '%s'", name, n,
                                 shown);
    } else if (!strcmp(tok[1], "scroll") && nt == 3) {
        ev->input.type = MTS_INPUT_SCROLL;
        if (!parse_int(tok[2], &ev->input.steps))
            return mts_error_set(err, MTS_ERR_FORMAT,
                                 "%s:%u: scroll needs a whole number of steps: '%s'", name, n,
                                 shown);
    } else {
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "%s:%u: '%s' is not an event (key NAME, drag DX DY, scroll STEPS)",
                             name, n, shown);
    }
    return MTS_OK;
}

mts_result mts_script_parse(const char *text, const char *name, mts_script *s, mts_error *err)
{
    memset(s, 0, sizeof *s);
    size_t cap = 0;
    unsigned n = 0;
    const char *p = text;
    while (*p) {
        const char *nl = strchr(p, '\n');
        size_t len = nl ? (size_t)(nl - p) : strlen(p);
        n++;
        char line[256];
        if (len >= sizeof line) {
            mts_script_free(s);
            return mts_error_set(err, MTS_ERR_FORMAT, "%s:%u: line longer than %zu bytes", name,
                                 n, sizeof line - 1);
        }
        memcpy(line, p, len);
        line[len] = 0;
        p += len + (nl ? 1 : 0);
        const char *q = line + strspn(line, " \t\r");
        if (!*q || *q == '#')
            continue;
        if (s->count == cap) {
            size_t nc = cap ? cap * 2 : 16;
            mts_script_event *e = realloc(s->events, nc * sizeof *e);
            if (!e) {
                mts_script_free(s);
                return mts_error_set(err, MTS_ERR_NOMEM, "%s: out of memory", name);
            }
            s->events = e;
            cap = nc;
        }
        mts_result rc = parse_line(line, name, n, &s->events[s->count], err);
        if (rc == MTS_OK && s->count && s->events[s->count].t < s->events[s->count - 1].t)
            rc = mts_error_set(err, MTS_ERR_FORMAT,
                               "%s:%u: time %g comes before the previous line's %g", name, n,
                               s->events[s->count].t, s->events[s->count - 1].t);
        if (rc != MTS_OK) {
            mts_script_free(s);
            return rc;
        }
        s->count++;
    }
    return MTS_OK;
}

mts_result mts_script_load(const char *path, mts_script *s, mts_error *err)
{
    memset(s, 0, sizeof *s);
    FILE *f = fopen(path, "rb");
    if (!f)
        return mts_error_set(err, MTS_ERR_IO, "%s: %s", path, strerror(errno));
    /* a script is a few lines; 1 MiB is far beyond any */
    static const size_t max = 1 << 20;
    char *text = malloc(max + 1);
    if (!text) {
        fclose(f);
        return mts_error_set(err, MTS_ERR_NOMEM, "%s: out of memory", path);
    }
    size_t n = fread(text, 1, max + 1, f);
    int bad = ferror(f);
    fclose(f);
    mts_result rc;
    if (bad)
        rc = mts_error_set(err, MTS_ERR_IO, "%s: read error", path);
    else if (n > max)
        rc = mts_error_set(err, MTS_ERR_LIMIT, "%s: over %zu bytes", path, max);
    else if (memchr(text, 0, n))
        rc = mts_error_set(err, MTS_ERR_FORMAT, "%s: not a text file (a NUL byte)", path);
    else {
        text[n] = 0;
        rc = mts_script_parse(text, path, s, err);
    }
    free(text);
    return rc;
}

void mts_script_free(mts_script *s)
{
    free(s->events);
    memset(s, 0, sizeof *s);
}

int mts_script_next(mts_script *s, double t, mts_input *ev)
{
    if (s->next >= s->count || s->events[s->next].t > t)
        return 0;
    *ev = s->events[s->next++].input;
    return 1;
}

int mts_script_done(const mts_script *s)
{
    return s->next >= s->count;
}
