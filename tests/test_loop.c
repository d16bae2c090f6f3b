/* The event loop (common/loop.h) on socket pairs: input and output are
 * reported to the io they belong to, with its own pointer; what an io is
 * watched for can change and stop; a peer that closes is input, and a
 * reset an error; the tick bounds each round's sleep and ends the run. */
#include <errno.h>
#include <sys/socket.h>
#include <unistd.h>

#include "clock.h"
#include "loop.h"
#include "test.h"

typedef struct seen {
    mts_loop_io io;
    int calls;
    unsigned last;
} seen;

static void record(mts_loop *loop, mts_loop_io *io, unsigned events)
{
    (void)loop;
    seen *s = io->user;
    s->calls++;
    s->last = events;
}

static void test_in_out_and_changes(mts_test *t)
{
    mts_loop loop = {0};
    mts_error err = {0};
    CHECK(t, mts_loop_init(&loop, &err) == MTS_OK);
    int sv[2];
    CHECK(t, socketpair(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK, 0, sv) == 0);
    seen a = {0}, b = {0};
    CHECK(t, mts_loop_watch(&loop, &a.io, sv[0], MTS_LOOP_IN, record, &a) == 0);
    CHECK(t, mts_loop_watch(&loop, &b.io, sv[1], MTS_LOOP_OUT, record, &b) == 0);
    /* only b is ready: writable */
    CHECK(t, mts_loop_once(&loop, 0, &err) == 1);
    CHECK(t, a.calls == 0 && b.calls == 1 && b.last == MTS_LOOP_OUT);
    /* b stops asking for output: nothing at all */
    CHECK(t, mts_loop_set(&loop, &b.io, 0) == 0 && b.io.events == 0);
    CHECK(t, mts_loop_once(&loop, 0, &err) == 0);
    /* a byte for a: input, to a's own pointer */
    CHECK(t, write(sv[1], "x", 1) == 1);
    CHECK(t, mts_loop_once(&loop, 1000, &err) == 1);
    CHECK(t, a.calls == 1 && a.last == MTS_LOOP_IN && b.calls == 1);
    /* unwatched, a is not reported though the byte is still there */
    mts_loop_unwatch(&loop, &a.io);
    CHECK(t, mts_loop_once(&loop, 0, &err) == 0 && a.calls == 1);
    /* watched again for input and output at once */
    CHECK(t, mts_loop_watch(&loop, &a.io, sv[0], MTS_LOOP_IN | MTS_LOOP_OUT, record, &a) == 0);
    CHECK(t, mts_loop_once(&loop, 0, &err) == 1 && a.last == (MTS_LOOP_IN | MTS_LOOP_OUT));
    /* the peer goes: a's input says so (a read would return 0) */
    close(sv[1]);
    CHECK(t, mts_loop_set(&loop, &a.io, MTS_LOOP_IN) == 0);
    a.calls = 0;
    CHECK(t, mts_loop_once(&loop, 1000, &err) == 1 && a.calls == 1 && (a.last & MTS_LOOP_IN));
    close(sv[0]);
    mts_loop_close(&loop);
    CHECK(t, loop.epoll_fd == -1);
    /* a descriptor the kernel will not watch is refused, with errno */
    CHECK(t, mts_loop_init(&loop, &err) == MTS_OK);
    seen c = {0};
    errno = 0;
    CHECK(t, mts_loop_watch(&loop, &c.io, -1, MTS_LOOP_IN, record, &c) == -1 && errno == EBADF);
    mts_loop_close(&loop);
}

/* A reset (the peer closed with bytes it never read) is an error. */
static void test_reset_is_an_error(mts_test *t)
{
    mts_loop loop = {0};
    mts_error err = {0};
    CHECK(t, mts_loop_init(&loop, &err) == MTS_OK);
    int sv[2];
    CHECK(t, socketpair(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK, 0, sv) == 0);
    seen a = {0};
    CHECK(t, mts_loop_watch(&loop, &a.io, sv[0], MTS_LOOP_IN, record, &a) == 0);
    shutdown(sv[0], SHUT_RDWR); /* both ways closed: a hang-up */
    CHECK(t, mts_loop_once(&loop, 1000, &err) == 1 && (a.last & MTS_LOOP_ERR));
    close(sv[0]);
    close(sv[1]);
    mts_loop_close(&loop);
}

typedef struct ticker {
    int ticks;
    double first, last;
} ticker;

static int tick(mts_loop *loop, void *user, double now)
{
    (void)loop;
    ticker *k = user;
    if (k->ticks++ == 0)
        k->first = now;
    k->last = now;
    return k->ticks > 5 ? -1 : 20; /* five rounds of 20 ms, then stop */
}

static void test_run_until_the_tick_stops(mts_test *t)
{
    mts_loop loop = {0};
    mts_error err = {0};
    CHECK(t, mts_loop_init(&loop, &err) == MTS_OK);
    ticker k = {0};
    CHECK(t, mts_loop_run(&loop, tick, &k, &err) == MTS_OK);
    /* five rounds slept their 20 ms each, nothing waking them */
    CHECKF(t, k.ticks == 6 && k.last - k.first >= 0.09, "%d ticks over %.3f s", k.ticks,
           k.last - k.first);
    mts_loop_close(&loop);
}

int main(void)
{
    mts_test t = {0};
    RUN(&t, test_in_out_and_changes);
    RUN(&t, test_reset_is_an_error);
    RUN(&t, test_run_until_the_tick_stops);
    return mts_test_end(&t);
}
