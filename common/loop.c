/* The event loop (loop.h) on epoll. */
#include "loop.h"

#include <errno.h>
#include <string.h>
#include <sys/epoll.h>
#include <unistd.h>

#include "clock.h"

/* Input is watched with EPOLLRDHUP too: a peer that shut its side is
 * readable (the read says 0), not a silent descriptor. */
static uint32_t to_epoll(unsigned events)
{
    return (events & MTS_LOOP_IN ? EPOLLIN | EPOLLRDHUP : 0) | (events & MTS_LOOP_OUT ? EPOLLOUT : 0);
}

mts_result mts_loop_init(mts_loop *loop, mts_error *err)
{
    loop->epoll_fd = epoll_create1(EPOLL_CLOEXEC);
    if (loop->epoll_fd < 0)
        return mts_error_set(err, MTS_ERR_IO, "epoll: %s", strerror(errno));
    return MTS_OK;
}

void mts_loop_close(mts_loop *loop)
{
    if (loop->epoll_fd >= 0)
        close(loop->epoll_fd);
    loop->epoll_fd = -1;
}

int mts_loop_watch(mts_loop *loop, mts_loop_io *io, int fd, unsigned events, mts_loop_io_fn *fn,
                   void *user)
{
    io->fd = fd;
    io->events = events;
    io->fn = fn;
    io->user = user;
    struct epoll_event ev = {.events = to_epoll(events), .data.ptr = io};
    return epoll_ctl(loop->epoll_fd, EPOLL_CTL_ADD, fd, &ev);
}

int mts_loop_set(mts_loop *loop, mts_loop_io *io, unsigned events)
{
    if (events == io->events)
        return 0;
    struct epoll_event ev = {.events = to_epoll(events), .data.ptr = io};
    if (epoll_ctl(loop->epoll_fd, EPOLL_CTL_MOD, io->fd, &ev) != 0)
        return -1;
    io->events = events;
    return 0;
}

void mts_loop_unwatch(mts_loop *loop, mts_loop_io *io)
{
    epoll_ctl(loop->epoll_fd, EPOLL_CTL_DEL, io->fd, NULL);
}

int mts_loop_once(mts_loop *loop, int timeout_ms, mts_error *err)
{
    struct epoll_event events[1024];
    int max = loop->max_events > 0 && loop->max_events < 1024 ? loop->max_events : 1024;
    int n = epoll_wait(loop->epoll_fd, events, max, timeout_ms);
    if (n < 0) {
        if (errno == EINTR)
            return 0;
        mts_error_set(err, MTS_ERR_IO, "epoll_wait: %s", strerror(errno));
        return -1;
    }
    for (int i = 0; i < n; i++) {
        mts_loop_io *io = events[i].data.ptr;
        uint32_t e = events[i].events;
        unsigned found = (e & (EPOLLIN | EPOLLRDHUP) ? MTS_LOOP_IN : 0) |
                         (e & EPOLLOUT ? MTS_LOOP_OUT : 0) |
                         (e & (EPOLLERR | EPOLLHUP) ? MTS_LOOP_ERR : 0);
        io->fn(loop, io, found);
    }
    return n;
}

mts_result mts_loop_run(mts_loop *loop, mts_loop_tick_fn *tick, void *user, mts_error *err)
{
    for (;;) {
        int timeout = tick(loop, user, mts_clock_seconds());
        if (timeout < 0)
            return MTS_OK;
        if (mts_loop_once(loop, timeout, err) < 0)
            return err ? err->code : MTS_ERR_IO;
    }
}
