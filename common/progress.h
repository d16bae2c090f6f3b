/* Progress reporting from long library calls. The library only calls the
 * callback; a program decides whether and how to draw a bar. */
#ifndef MTS_PROGRESS_H
#define MTS_PROGRESS_H

typedef struct mts_progress {
    /* done in [0, 1] for the named stage; may be NULL. */
    void (*fn)(void *user, const char *stage, double done);
    void *user;
} mts_progress;

static inline void mts_progress_report(const mts_progress *p, const char *stage, double done)
{
    if (p && p->fn)
        p->fn(p->user, stage, done);
}

#endif
