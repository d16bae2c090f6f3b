/* A small event loop, after Redis's ae.c: descriptors watched for input or
 * output, each with a callback and a pointer of its own, and a tick the
 * owner runs between rounds (timers, scans, stopping). epoll underneath.
 * mts-server and mts-stress both run on it, one loop a thread.
 *
 * A watched descriptor is an mts_loop_io that the owner embeds in its own
 * record (a connection, a listener), so the loop allocates nothing per
 * descriptor and finds the callback from the event itself. The loop reads
 * an io only while dispatching its own event: a callback may stop watching
 * (or close) any io, but the memory of one closed in a round must stay
 * valid until the round is over (the owner frees such records from its
 * tick, as mts-server does with its list of dead connections). */
#ifndef MTS_LOOP_H
#define MTS_LOOP_H

#include <stdint.h>

#include "error.h"

/* What an io is watched for, and what a round found on it. */
enum {
    MTS_LOOP_IN = 1u,   /* readable, or the peer shut its side down */
    MTS_LOOP_OUT = 2u,  /* writable (a connect that finished, too) */
    MTS_LOOP_ERR = 4u   /* found only: an error or a hang-up on it */
};

typedef struct mts_loop mts_loop;
typedef struct mts_loop_io mts_loop_io;

/* Called once a round for an io with events found (MTS_LOOP_* bits). */
typedef void mts_loop_io_fn(mts_loop *loop, mts_loop_io *io, unsigned events);

/* Called before every wait with the time (mts_clock_seconds): returns the
 * longest the wait may sleep in milliseconds (0: poll), or < 0 to end
 * mts_loop_run. */
typedef int mts_loop_tick_fn(mts_loop *loop, void *user, double now);

struct mts_loop_io {
    int fd;
    unsigned events; /* what it is watched for now */
    mts_loop_io_fn *fn;
    void *user;
};

struct mts_loop {
    int epoll_fd;
    int max_events; /* per round; 0: 1024 */
};

/* An empty loop (loop->max_events may be set first). MTS_ERR_IO when the
 * kernel refuses one. */
mts_result mts_loop_init(mts_loop *loop, mts_error *err);
void mts_loop_close(mts_loop *loop);

/* Watches fd for `events` (MTS_LOOP_IN, MTS_LOOP_OUT, both, or none: kept
 * but quiet), fn(loop, io, found) to be called; io is the caller's and
 * must outlive the watch. 0, or -1 with errno (EMFILE, ENOMEM, ...). */
int mts_loop_watch(mts_loop *loop, mts_loop_io *io, int fd, unsigned events, mts_loop_io_fn *fn,
                   void *user);

/* Changes what io is watched for; nothing is asked of the kernel when it
 * is what it was. 0, or -1 with errno. */
int mts_loop_set(mts_loop *loop, mts_loop_io *io, unsigned events);

/* Stops watching io (its descriptor is the caller's to close). */
void mts_loop_unwatch(mts_loop *loop, mts_loop_io *io);

/* One round: waits up to timeout_ms (0: not at all, < 0: until something
 * comes) and calls each io's fn with what was found. The number of ios
 * called, 0 when interrupted by a signal, or -1 with err filled. */
int mts_loop_once(mts_loop *loop, int timeout_ms, mts_error *err);

/* Rounds until tick returns < 0: tick(loop, user, now), then a round of at
 * most what it returned. MTS_OK, or the error of a wait that failed. */
mts_result mts_loop_run(mts_loop *loop, mts_loop_tick_fn *tick, void *user, mts_error *err);

#endif
