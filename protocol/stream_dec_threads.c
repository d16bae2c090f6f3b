/* The client's decoder on more than one thread (stream_dec_threads.h):
 * growth cut at its keys (grow_tokens.h), the pool that grows each key
 * interval, the hand-over of splits and records, and the fix-up that puts
 * the records back in one grow's slots, in level order. */
#include "stream_dec_threads.h"

#include "grow_tokens.h"

#include <pthread.h>
#include <sched.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <stdio.h>
#include <time.h>
#ifdef __linux__
#include <fcntl.h>
#include <sys/syscall.h>
#include <unistd.h>
#endif

#include "bigmem.h"
#include "words.h"

/* The decode thread (the caller's) decodes the splits against a mesh-only
 * grow, which gives the fan codes, rings and the triangles round each new
 * vertex exactly as one grow does, and logs each split. Every key interval
 * has a worker, a full grow copied from the mesh-only one just before its
 * key split, which a pool thread grows through the logged splits, its
 * records in slot tokens. The decode thread fixes them up in level order
 * (mts_grow_fixup), keeps them and applies them at the batch's end, so the
 * records and the runtime are what one grow gives, and each batch is
 * applied before its frame returns. The full level's split reads the
 * batch's coder as it walks, so its worker runs on the decode thread.
 * With one pool thread (two threads in all) there is one worker, a grow
 * from the base that takes every split, and nothing to fix up (`pipe`):
 * it writes its records straight into the model's (own_data);
 * it takes each fan's ring from the log, as the decode thread walked it for
 * the fan code, in place of walking it again (mts_grow_take_ring). The
 * decode thread stripifies a key on its own mesh too where that pays (the
 * pool well behind), for the pool and for the ids it needs, walks the full
 * level's strips on its own mesh while the pool finishes, and the pool's
 * grow takes them once it is done. */

#define LOG_CHUNK 4096u /* splits a log chunk holds: freed once fixed up */
#define REC_BLOCK 65536u /* words of a worker's first record block */

#define PREFETCH_MIN_TRIANGLES (1u << 18) /* 8 MB of triangle records */

#define KEEP_CHUNK 4096u /* records kept at a time while waiting for the pool */

#define RING_MAX 14u /* corners of a ring the log carries: all but a few */

/* Pipe: a key's paths in the pool's grow's ids, made on the decode thread
 * where it gets there well ahead of the pool (par_key_paths); the pool
 * takes them, or makes its own where it got there first (KP_POOL). One
 * compare-and-swap on state decides, so the arrays are written before
 * KP_GIVEN and read only after it. */
typedef struct key_paths {
    atomic_int state;
    uint32_t *order, *starts, count, triangles;
} key_paths;

typedef struct logged_split {
    mts_grow_split sp;   /* as one grow takes it: explicit lists in its ids */
    uint32_t *lists;     /* what sp's explicit lists point into (owned) */
    const uint32_t *rec; /* the worker's record, in its tokens (in its blocks) */
    uint32_t rec_words;
    /* pipe: the parent's ring as the mesh-only grow walked it, in its ids
     * (mts_grow_take_ring); ring_n 0 where none is handed over */
    uint32_t ring_n, ring_closed;
    uint32_t ring[RING_MAX];
} logged_split;

/* Records are appended to blocks that never move, so the decode thread
 * reads one while the worker writes the next. Each block is twice the last
 * up to 2 MB, and those are huge pages (bigmem.h): a small mesh's records
 * stay in small blocks, a large one's cost a fault every 2 MB, not every
 * 4 KB. */
typedef struct rec_block {
    struct rec_block *next;
    mts_bigmem mem; /* where the block itself lives */
    size_t used, cap;
    uint32_t w[];
} rec_block;

#define REC_BLOCK_MOST ((((size_t)2 << 20) - sizeof(rec_block)) / 4)

static void rec_block_free(rec_block *b)
{
    mts_bigmem m = b->mem;
    mts_bigmem_free(&m);
}

typedef struct interval {
    mts_grow *w;         /* made on the decode thread, grown on a pool thread */
    uint32_t first, end; /* its splits; first is its key split but in interval 0 */
    atomic_uint made;    /* records made, first..made-1 */
    uint32_t seen;       /* made as the decode thread last read it (its own) */
    atomic_int done;     /* the worker has finished with w */
    atomic_uint want;    /* made, as the decode thread sleeps for it; UINT32_MAX: done */
    mts_result rc;       /* how (written before done) */
    mts_error err;
    /* oldest first: the worker appends at tail, the decode thread frees
     * from the head those whose records it has kept */
    rec_block *blocks, *tail;
    size_t block_words; /* the next block's words; 0: REC_BLOCK */
} interval;

struct mts__stream_par {
    pthread_mutex_t mu;
    pthread_cond_t work;     /* for pool threads: a split logged, a worker queued, stop */
    pthread_cond_t progress; /* for the decode thread: a record made, a worker done */
    pthread_t *thread;
    uint32_t thread_count;
    atomic_int stop;         /* set under mu, so that a sleeper sees it */
    atomic_uint logged;      /* splits 0..logged-1 are in the log */
    /* threads asleep on work for a split, on progress for a record: the
     * other side wakes them only then (par_sleep) */
    atomic_uint pool_sleeping, dec_sleeping;
    uint32_t queued, taken;  /* under mu: intervals with a worker, and taken by a thread */
    logged_split **chunk;    /* written by the decode thread before the split is logged */
    uint32_t chunk_count;
    interval *iv;            /* before the first key, one a key, the full level's */
    uint32_t iv_count;
    /* One pool thread (threads == 2): one grow from the base takes every
     * split but the full level's, on that thread, and its records are the
     * real ones. Intervals on one thread run one after another anyway, so
     * a worker a key would only add the mesh copies, the fresh memory and
     * the fix-up, all on the decode thread, which is the bound. Then iv[0]
     * is that grow's, iv[1] the full level's, and each key's renumbering
     * is kept in orders (for explicit splits' ids). */
    int pipe;
    uint32_t **orders, *order_n; /* written by the pool before the key's record is made */
    uint32_t *pool_ids, pool_ids_n; /* the pool's alone: mesh-only triangle -> its grow's */
    /* Pipe, where the model's records already hold the records form's
     * bound (they never move then): the pool writes its records straight
     * there, record_offsets too, and the decode thread, which used to copy
     * them over, only reads them below `made`. NULL: into blocks, kept by
     * the decode thread. */
    uint32_t *own_data, *own_offsets;
    size_t own_cap; /* words at own_data */
    /* the decode thread's alone */
    mts_grow_options go;
    mts_grow_fixup *fix;
    uint32_t dec_iv;           /* the interval of the split being decoded */
    uint32_t fix_iv, fixed;    /* records 0..fixed-1 kept; fix_iv: split fixed's interval */
    uint32_t composed;         /* the key orders of intervals 1..composed are in ids */
    uint32_t dec_keys;         /* pipe: the keys at or below the split being decoded */
    uint32_t *ids, *inv;       /* mesh-only triangle -> one grow's, and back */
    /* pipe: whether the pool thread has a core (mts__stream_par_batch_end) */
    atomic_int pool_tid;         /* its kernel id, once it runs (0 before) */
    int delay_fd;                /* its schedstat; -1 unopened, -2 none to read */
    uint64_t at_wall;            /* the batch's start */
    uint64_t win_wall, win_delay; /* the window: its batches' wall time, the delay before it */
    unsigned slow;               /* windows in a row past the line */
    uint64_t slow_idle;          /* the cores' idle ticks when that run began */
    uint32_t ids_n, ids_cap;
    mts_words mapped;          /* an explicit split's moved triangles in mesh-only ids */
    /* pipe: decoding ahead (stream_dec_threads.h) */
    uint32_t apply_cap;        /* the runtime goes no further before the frame returns */
    uint32_t ahead;            /* batches decoded ahead, not yet taken */
    int ahead_failed;          /* the one after them failed, so: */
    mts_result ahead_rc;
    mts_error ahead_err;
    int want_alone;            /* go on alone once nothing is decoded ahead */
    int ahead_held;            /* decode nothing ahead (mts__stream_par_ahead_hold) */
    /* pipe: the full level's record, made on the pool's grow (iv[0].w)
     * once it has grown every split before; kept in level order
     * (mts__stream_par_fixup) */
    const uint32_t *full_rec;
    uint32_t full_words;
    /* pipe: each key's paths where the decode thread made them; those
     * below kp_freed are freed (the pool is past them) */
    key_paths *kp;
    uint32_t kp_freed;
    uint32_t keys_below; /* the keys below the full level (which may be listed) */
    /* pipe: orders[0..orders_ready) are written (par_key_order, on the pool
     * thread, inside its key split); pool_key: the key it is at */
    atomic_uint orders_ready;
    uint32_t pool_key;
    int order_nomem;
    int hand;            /* mts_stream_client.threads_hand_key_paths */
};

enum { KP_OPEN, KP_GIVEN, KP_POOL };

static logged_split *par_entry(struct mts__stream_par *p, uint32_t j)
{
    return &p->chunk[j / LOG_CHUNK][j % LOG_CHUNK];
}

static void par_free_chunk(struct mts__stream_par *p, uint32_t k)
{
    if (!p->chunk[k])
        return;
    for (uint32_t x = 0; x < LOG_CHUNK; x++)
        free(p->chunk[k][x].lists);
    free(p->chunk[k]);
    p->chunk[k] = NULL;
}

static void par_free_blocks(interval *v)
{
    while (v->blocks) {
        rec_block *b = v->blocks;
        v->blocks = b->next;
        rec_block_free(b);
    }
    v->tail = NULL;
}

/* Handing splits and records over: each is published as it is made (an
 * atomic store), and a side that finds nothing to take spins a while before
 * it sleeps. A split costs a couple of microseconds and a sleeping
 * thread's wake-up several, so waking the other side for each would cost
 * what threads gain, and publishing in runs made the worker lag a run
 * behind: at every batch's end the decode thread waited for that lag
 * (a quarter of bunny00's time on two threads). The spin is bounded, so a
 * thread that waits for longer (a network gap, a key's restripification)
 * sleeps on the lock, and only a sleeper is woken. */
#define SPIN_NS 50000

/* One turn of a spin. After the first few it yields the processor: where
 * the two threads share a core (a busy machine), a pure spin would hold it
 * for the whole spin while the thread it waits for cannot run, at every
 * hand-over; where a core is free, yielding returns at once. */
static void spin_turn(unsigned k)
{
    if (k >= 64) {
        sched_yield();
        return;
    }
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#elif defined(__aarch64__)
    __asm__ __volatile__("yield");
#endif
}

static uint64_t now_ns(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (uint64_t)t.tv_sec * 1000000000u + (uint64_t)t.tv_nsec;
}

/* A pool thread: the splits logged, once there are more than j (or the
 * decoder stops: then at most j). */
static uint32_t par_wait_logged(struct mts__stream_par *p, uint32_t j)
{
    uint32_t n = atomic_load(&p->logged);
    if (n > j)
        return n;
    const uint64_t until = now_ns() + SPIN_NS;
    for (unsigned k = 1;; k++) {
        spin_turn(k);
        if ((n = atomic_load(&p->logged)) > j || atomic_load(&p->stop))
            return n;
        if (k % 32 == 0 && now_ns() > until)
            break;
    }
    /* the decode thread stores logged, then reads pool_sleeping; this
     * thread counts itself, then reads logged: one of the two sees the
     * other (sequentially consistent), so no wake-up is lost */
    pthread_mutex_lock(&p->mu);
    atomic_fetch_add(&p->pool_sleeping, 1);
    while ((n = atomic_load(&p->logged)) <= j && !atomic_load(&p->stop))
        pthread_cond_wait(&p->work, &p->mu);
    atomic_fetch_sub(&p->pool_sleeping, 1);
    pthread_mutex_unlock(&p->mu);
    return n;
}

/* A pool thread: interval v's records below n are made. The decode thread
 * is woken only once it has what it sleeps for: woken at every record, it
 * would make the pool pay a futex call a record while the decode thread
 * waits for a key thousands of splits on (the last key's order, which the
 * full level's worker needs), a tenth of the pool's time on a large mesh.
 * A worker that ends wakes it anyway (par_grow). */
static void par_made(struct mts__stream_par *p, interval *v, uint32_t n)
{
    atomic_store(&v->made, n);
    if (atomic_load(&p->dec_sleeping) && n >= atomic_load(&v->want)) {
        pthread_mutex_lock(&p->mu);
        pthread_cond_broadcast(&p->progress);
        pthread_mutex_unlock(&p->mu);
    }
}

/* The pool thread (pipe): its grow renumbered its triangles at a key, t
 * becoming order[t] (count of them), so the ids the mesh-only grow's
 * triangles have in it are composed with that; those born since the last
 * key have the same id in both. 0 when out of memory. */
static int par_pool_ids(struct mts__stream_par *p, const uint32_t *order, uint32_t count)
{
    if (count > p->pool_ids_n) {
        uint32_t *a = realloc(p->pool_ids, (size_t)count * 4);
        if (!a)
            return 0;
        p->pool_ids = a;
        for (uint32_t x = p->pool_ids_n; x < count; x++)
            a[x] = x;
        p->pool_ids_n = count;
    }
    for (uint32_t x = 0; x < count; x++)
        p->pool_ids[x] = order[p->pool_ids[x]];
    return 1;
}

/* Pipe, on the pool thread inside its key split: the key's renumbering,
 * kept for the decode thread as soon as it is known (mts_grow_on_key_order),
 * about half the key split before the split returns. */
static void par_key_order(void *user, const uint32_t *order, uint32_t count)
{
    struct mts__stream_par *p = user;
    const uint32_t k = p->pool_key;
    if (k >= p->go.key_count || p->orders[k])
        return;
    if (!(p->orders[k] = malloc((size_t)count * 4 + 4))) {
        p->order_nomem = 1;
        return;
    }
    memcpy(p->orders[k], order, (size_t)count * 4);
    p->order_n[k] = count;
    atomic_store(&p->orders_ready, k + 1);
    if (atomic_load(&p->dec_sleeping)) {
        pthread_mutex_lock(&p->mu);
        pthread_cond_broadcast(&p->progress);
        pthread_mutex_unlock(&p->mu);
    }
}

/* A pool thread's interval: each logged split in turn, its record kept in
 * the interval's blocks and published. */
static void par_grow(struct mts__stream_par *p, interval *v)
{
    uint32_t j = v->first, key = 0;
    mts_result rc = MTS_OK;
    par_made(p, v, j);
    while (rc == MTS_OK && j < v->end) {
        const uint32_t avail = par_wait_logged(p, j);
        if (avail <= j) {
            rc = mts_error_set(&v->err, MTS_ERR_ARG, "stream: the decoder stopped");
            break;
        }
        /* hints only past the caches: bunny00 (75K triangles, 32 bytes
         * each) took 1.05x to 1.15x the time with them */
        mts_grow_figures fig;
        mts_grow_get_figures(v->w, &fig);
        const uint32_t hints = p->pipe && fig.triangles >= PREFETCH_MIN_TRIANGLES ? 4 : 0;
        for (; j < avail && j < v->end; j++) {
            logged_split *ls = par_entry(p, j);
            const uint32_t *r;
            uint32_t rw;
            /* the splits logged after this one, each a link further on
             * (mts_grow_prefetch_ring) */
            for (uint32_t d = 1; d <= hints && j + d < avail && j + d < v->end; d++) {
                const logged_split *next = par_entry(p, j + d);
                if (next->ring_n)
                    mts_grow_prefetch_ring(v->w, d - 1, next->sp.parent, next->ring,
                                           next->ring_n, p->pool_ids, p->pool_ids_n);
            }
            if (ls->ring_n)
                mts_grow_take_ring(v->w, ls->sp.parent, ls->ring, ls->ring_n, ls->ring_closed,
                                   p->pool_ids, p->pool_ids_n);
            int expect = KP_OPEN;
            key_paths *kp = p->pipe && key < p->keys_below && p->go.key_levels[key] == j + 1
                                ? &p->kp[key]
                                : NULL;
            for (unsigned k = 1; kp && p->hand && atomic_load(&kp->state) == KP_OPEN &&
                                 !atomic_load(&p->stop);
                 k++)
                spin_turn(k); /* the test's word: the decode thread makes them */
            if (kp && !atomic_compare_exchange_strong(&kp->state, &expect, KP_POOL) &&
                expect == KP_GIVEN)
                mts_grow_give_key_paths(v->w, j + 1, kp->triangles, kp->order, kp->starts,
                                        kp->count);
            if (p->pipe) /* one pool thread: par_key_order's */
                p->pool_key = key;
            rc = mts_grow_next(v->w, &ls->sp, NULL, &r, &rw, &v->err);
            if (kp) /* read in that split only */
                mts_grow_give_key_paths(v->w, 0, 0, NULL, NULL, 0);
            if (rc != MTS_OK)
                break;
            if (p->pipe && key < p->go.key_count && p->go.key_levels[key] == j + 1) {
                /* the renumbering of the key just made (par_key_order), for
                 * the rings of the splits after it */
                if (p->order_nomem || !p->orders[key] ||
                    !par_pool_ids(p, p->orders[key], p->order_n[key])) {
                    rc = mts_error_set(&v->err, MTS_ERR_NOMEM, "out of memory for a key's order");
                    break;
                }
                key++;
            }
            if (p->own_data) {
                const size_t at = p->own_offsets[j];
                /* a records form of this model would bring no more */
                if (at >= p->own_cap || rw >= p->own_cap - at) {
                    rc = mts_error_set(&v->err, MTS_ERR_LIMIT,
                                       "stream: split %u's record passes the model's bound", j);
                    break;
                }
                memcpy(p->own_data + at, r, (size_t)rw * 4);
                p->own_offsets[j + 1] = (uint32_t)(at + rw);
                ls->rec = p->own_data + at;
                ls->rec_words = rw;
                par_made(p, v, j + 1);
                continue;
            }
            rec_block *b = v->tail;
            if (!b || b->cap - b->used < rw) {
                const size_t want = v->block_words ? v->block_words : REC_BLOCK,
                             cap = rw > want ? rw : want;
                v->block_words = 2 * want < REC_BLOCK_MOST ? 2 * want : REC_BLOCK_MOST;
                mts_bigmem m = {.cache = p->go.memory};
                if (!mts_bigmem_room(&m, sizeof *b + cap * 4, 0, 0)) {
                    rc = mts_error_set(&v->err, MTS_ERR_NOMEM, "out of memory for records");
                    break;
                }
                b = m.p;
                b->mem = m;
                b->next = NULL;
                b->used = 0;
                b->cap = cap;
                if (v->tail)
                    v->tail->next = b;
                else
                    v->blocks = b;
                v->tail = b;
            }
            uint32_t *to = b->w + b->used;
            memcpy(to, r, (size_t)rw * 4);
            b->used += rw;
            ls->rec = to;
            ls->rec_words = rw;
            par_made(p, v, j + 1);
        }
    }
    pthread_mutex_lock(&p->mu);
    v->rc = rc;
    atomic_store(&v->done, 1);
    pthread_cond_broadcast(&p->progress);
    pthread_mutex_unlock(&p->mu);
}

static void *par_thread(void *arg)
{
    struct mts__stream_par *p = arg;
#ifdef __linux__
    int expected = 0;
    atomic_compare_exchange_strong(&p->pool_tid, &expected, (int)syscall(SYS_gettid));
#endif
    pthread_mutex_lock(&p->mu);
    for (;;) {
        while (!atomic_load(&p->stop) && p->taken >= p->queued)
            pthread_cond_wait(&p->work, &p->mu);
        if (atomic_load(&p->stop))
            break;
        interval *v = &p->iv[p->taken++];
        pthread_mutex_unlock(&p->mu);
        par_grow(p, v);
        pthread_mutex_lock(&p->mu);
    }
    pthread_mutex_unlock(&p->mu);
    return NULL;
}

/* The decode thread: splits 0..n-1 are in the log. */
static void par_publish(struct mts__stream_par *p, uint32_t n)
{
    atomic_store(&p->logged, n);
    if (atomic_load(&p->pool_sleeping)) {
        pthread_mutex_lock(&p->mu);
        pthread_cond_broadcast(&p->work);
        pthread_mutex_unlock(&p->mu);
    }
}

/* Stops and joins the pool threads. */
static void par_stop(struct mts__stream_par *p)
{
    pthread_mutex_lock(&p->mu);
    atomic_store(&p->stop, 1);
    pthread_cond_broadcast(&p->work);
    pthread_mutex_unlock(&p->mu);
    for (uint32_t k = 0; k < p->thread_count; k++)
        pthread_join(p->thread[k], NULL);
    p->thread_count = 0;
}

void mts__stream_par_free(struct mts__stream_par *p)
{
    if (!p)
        return;
    par_stop(p);
#ifdef __linux__
    if (p->delay_fd >= 0)
        close(p->delay_fd);
#endif
    for (uint32_t k = 0; p->chunk && k < p->chunk_count; k++)
        par_free_chunk(p, k);
    for (uint32_t i = 0; p->iv && i < p->iv_count; i++) {
        mts_grow_free(p->iv[i].w);
        par_free_blocks(&p->iv[i]);
    }
    pthread_cond_destroy(&p->work);
    pthread_cond_destroy(&p->progress);
    pthread_mutex_destroy(&p->mu);
    mts_grow_fixup_free(p->fix);
    free(p->thread);
    free(p->chunk);
    free(p->iv);
    free(p->ids);
    free(p->inv);
    free(p->pool_ids);
    for (uint32_t k = 0; p->kp && k < p->keys_below; k++) {
        free(p->kp[k].order);
        free(p->kp[k].starts);
    }
    free(p->kp);
    free(p->mapped.w);
    for (uint32_t k = 0; p->orders && k < p->go.key_count; k++)
        free(p->orders[k]);
    free(p->orders);
    free(p->order_n);
    free(p);
}

/* What the decode thread waits for from interval v: its worker done, and
 * before that, with `orders`, the pool's first that many key orders
 * (par_key_order), else (but `whole`) its records below upto. */
typedef struct par_want {
    interval *v;
    uint32_t upto, orders;
    int whole;
} par_want;

static int par_wanted(struct mts__stream_par *p, const par_want *w)
{
    if (atomic_load(&w->v->done))
        return 1;
    if (w->orders)
        return atomic_load(&p->orders_ready) >= w->orders;
    return !w->whole && atomic_load(&w->v->made) >= w->upto;
}

/* The decode thread: spins a while, then sleeps, until par_wanted. */
static void par_await(struct mts__stream_par *p, const par_want *w)
{
    if (par_wanted(p, w))
        return;
    const uint64_t until = now_ns() + SPIN_NS;
    for (unsigned k = 1;; k++) {
        spin_turn(k);
        if (par_wanted(p, w))
            return;
        if (k % 32 == 0 && now_ns() > until)
            break;
    }
    /* as par_wait_logged, the other way round; what it waits for is stored
     * before it counts itself, so a pool thread that sees the count sees
     * that too. A record count is woken for only once it is reached
     * (par_made); orders and the worker's end wake it as they come. */
    pthread_mutex_lock(&p->mu);
    atomic_store(&w->v->want, w->orders || w->whole ? UINT32_MAX : w->upto);
    atomic_fetch_add(&p->dec_sleeping, 1);
    while (!par_wanted(p, w))
        pthread_cond_wait(&p->progress, &p->mu);
    atomic_fetch_sub(&p->dec_sleeping, 1);
    atomic_store(&w->v->want, UINT32_MAX);
    pthread_mutex_unlock(&p->mu);
}

/* Until interval i has made its records below `upto` or its worker is
 * done: its error then, if it did not get there. */
static mts_result par_wait(struct mts__stream_par *p, uint32_t i, uint32_t upto, int whole,
                           mts_error *err)
{
    interval *v = &p->iv[i];
    if (!whole && v->seen >= upto)
        return MTS_OK;
    par_await(p, &(par_want){.v = v, .upto = upto, .whole = whole});
    /* records made are as good as made, but a worker that failed fails its
     * whole interval, as one grow would have stopped there (done is read
     * first: the worker stores its last count, then done) */
    const int done = atomic_load(&v->done);
    const uint32_t made = atomic_load(&v->made);
    const int ok = (!done || v->rc == MTS_OK) && (whole ? done : made >= upto);
    v->seen = made;
    if (ok)
        return MTS_OK;
    if (v->rc == MTS_OK) /* a worker done short of what was waited for */
        return mts_error_set(err, MTS_ERR_INTERNAL,
                             "stream: waited for %u records of an interval that made %u", upto,
                             made);
    if (err)
        *err = v->err;
    return v->rc;
}

/* Pipe: until the pool's key k - 1 order is written (par_key_order), or
 * its grow is done: its error then, if it did not get there. */
static mts_result par_wait_order(struct mts__stream_par *p, uint32_t k, mts_error *err)
{
    interval *v = &p->iv[0];
    if (atomic_load(&p->orders_ready) >= k)
        return MTS_OK;
    par_await(p, &(par_want){.v = v, .orders = k});
    if (atomic_load(&p->orders_ready) >= k)
        return MTS_OK;
    if (v->rc == MTS_OK)
        return mts_error_set(err, MTS_ERR_INTERNAL,
                             "stream: waited for key %u's order of a grow that made %u records",
                             k, atomic_load(&v->made));
    if (err)
        *err = v->err;
    return v->rc;
}

/* Sets the state up after BASE: the log, the intervals, the fix-up, the
 * first worker (a grow from the base, whose slots are the real ones) and
 * the pool. MTS_OK with c->par NULL where one thread it is. */
mts_result mts__stream_par_start(mts_stream_client *c, const mts_grow_options *go, mts_error *err)
{
    const mts_model *m = &c->model;
    const uint32_t n = m->level_count, kc = c->info.key_count;
    /* more than two decode as two (stream.h) unless cut at their keys */
    const uint32_t threads = c->threads > 2 && !c->threads_at_keys ? 2 : c->threads;
    if (threads < 2 || c->records || !c->info.key_levels || n == 0)
        return MTS_OK;
    struct mts__stream_par *p = calloc(1, sizeof *p);
    if (!p)
        return mts_error_set(err, MTS_ERR_NOMEM, "out of memory for the decoder's threads");
    if (pthread_mutex_init(&p->mu, NULL) != 0) {
        free(p);
        return mts_error_set(err, MTS_ERR_NOMEM, "cannot make the decoder's threads' lock");
    }
    pthread_cond_init(&p->work, NULL);
    pthread_cond_init(&p->progress, NULL);
    p->go = *go;
    p->delay_fd = -1;
    p->pipe = threads == 2;
    p->hand = c->threads_hand_key_paths;
    p->iv_count = p->pipe ? 2 : kc + 2;
    p->chunk_count = n / LOG_CHUNK + 1;
    mts_result rc = MTS_OK;
    if (!(p->iv = calloc(p->iv_count, sizeof *p->iv)) ||
        !(p->chunk = calloc(p->chunk_count, sizeof *p->chunk)) ||
        !(p->thread = calloc(threads, sizeof *p->thread)) ||
        (p->pipe && (!(p->orders = calloc(kc + 1, sizeof *p->orders)) ||
                     !(p->order_n = calloc(kc + 1, sizeof *p->order_n)))))
        rc = mts_error_set(err, MTS_ERR_NOMEM, "out of memory for the decoder's threads");
    /* interval i: the splits from key i's (none for i = 0) to the next
     * key's; the last one the full level's split alone */
    for (uint32_t i = 0; rc == MTS_OK && i < p->iv_count; i++)
        atomic_init(&p->iv[i].want, UINT32_MAX);
    for (uint32_t i = 0; rc == MTS_OK && i < kc + 2; i++) {
        const uint32_t first = i == 0 ? 0 : i <= kc ? c->info.key_levels[i - 1] - 1 : n - 1;
        const uint32_t end = i < kc ? c->info.key_levels[i] - 1 : i == kc ? n - 1 : n;
        if (end < first || (i > 0 && end == first))
            rc = mts_error_set(err, MTS_ERR_FORMAT, "MODEL_INFO: key levels out of order");
        else if (!p->pipe) {
            p->iv[i].first = first;
            p->iv[i].end = end;
        }
    }
    if (rc == MTS_OK && p->pipe) {
        p->iv[0].end = p->iv[1].first = n - 1;
        p->iv[1].end = n;
        while (p->keys_below < kc && c->info.key_levels[p->keys_below] < n)
            p->keys_below++;
        if (!(p->kp = calloc((size_t)p->keys_below + 1, sizeof *p->kp)))
            rc = mts_error_set(err, MTS_ERR_NOMEM, "out of memory for the decoder's threads");
        for (uint32_t k = 0; rc == MTS_OK && k < p->keys_below; k++)
            atomic_init(&p->kp[k].state, KP_OPEN);
    }
    if (rc == MTS_OK && !p->pipe) /* pipe: every record is the pool's grow's own */
        rc = mts_grow_fixup_create(&p->fix, err);
    /* pipe: room for the records form's bound now (past a megabyte a
     * reservation, address space only), so that the pool can write there */
    const size_t bound = c->record_word_limit;
    mts_error ignored; /* out of memory here: blocks, as before */
    if (rc == MTS_OK && p->pipe && bound && bound < UINT32_MAX &&
        mts__stream_reserve_records(c, 0, bound < MTS_BIGMEM_FROM / 4 ? bound : MTS_BIGMEM_FROM / 4,
                                    &ignored) == MTS_OK &&
        c->record_capacity >= bound + 1) {
        p->own_data = c->model.record_data;
        p->own_offsets = c->model.record_offsets;
        p->own_cap = bound + 1;
    }
    if (rc == MTS_OK)
        rc = mts_grow_create(&m->base, m->base_vertex_count, n, go, &p->iv[0].w, err);
    if (rc == MTS_OK && p->pipe)
        mts_grow_on_key_order(p->iv[0].w, par_key_order, p);
    if (rc == MTS_OK) {
        p->queued = 1;
        /* more threads than intervals would wait for nothing */
        const uint32_t want = threads - 1 < p->iv_count - 1 ? threads - 1 : p->iv_count - 1;
        for (uint32_t k = 0; k < want; k++) {
            if (pthread_create(&p->thread[p->thread_count], NULL, par_thread, p) != 0)
                break;
            p->thread_count++;
        }
    }
    /* no pool thread (a process at its thread limit, a browser without a
     * free worker): the caller's thread decodes alone, as with one */
    if (rc != MTS_OK || !p->thread_count) {
        mts__stream_par_free(p);
        return rc;
    }
    c->par = p;
    c->threads_ran = 1 + p->thread_count;
    return MTS_OK;
}

/* Two threads pay only where each has a core. Sharing one, they take
 * longer than one thread alone (each hand-over waits for the other to be
 * scheduled, and both keep the mesh), so the decoder watches the pool
 * thread's run delay: the time it was ready to run and waited for a core
 * (Linux's schedstat; elsewhere nothing is measured and two stay two).
 * With a core each it is near nothing; sharing one with another busy
 * process, a third of the batch's time or more. CPU time against wall time
 * would not tell these apart from the batches where one thread sleeps
 * while the other restripifies a key. A window is at least WINDOW_NS of
 * batches, and it takes three in a row: on an idle machine about one window
 * in a hundred reads 15% or more, at times two in a row (another process
 * woken for some 8 ms), and the switch is for the rest of the stream; a
 * busy machine reads 45% to 85% in every window. */
#define WINDOW_NS 4000000u
#define SLOW_PERCENT 15u /* of the window's wall time */
#define SLOW_WINDOWS 3u  /* in a row */

/* The pool thread's run delay so far, in ns; 0 where none can be read. */
static int par_delay(struct mts__stream_par *p, uint64_t *ns)
{
#ifdef __linux__
    if (p->delay_fd == -1) {
        const int tid = atomic_load(&p->pool_tid);
        if (!tid)
            return 0;
        char path[64];
        snprintf(path, sizeof path, "/proc/self/task/%d/schedstat", tid);
        p->delay_fd = open(path, O_RDONLY | O_CLOEXEC);
        if (p->delay_fd < 0)
            p->delay_fd = -2;
    }
    char buf[96];
    ssize_t n;
    if (p->delay_fd < 0 || (n = pread(p->delay_fd, buf, sizeof buf - 1, 0)) <= 0)
        return 0;
    buf[n] = 0;
    /* "run time, run delay, time slices", in ns */
    unsigned long long run, delay;
    if (sscanf(buf, "%llu %llu", &run, &delay) != 2)
        return 0;
    *ns = delay;
    return 1;
#else
    (void)p;
    (void)ns;
    return 0;
#endif
}

/* The idle time so far of the processors this thread may run on, in
 * /proc/stat's ticks (USER_HZ, 10 ms on Linux), idle and iowait; 0 where
 * none can be read. The pool thread's run delay says it waited for a core,
 * not that none was free: the scheduler may keep both threads on one
 * processor for tens of milliseconds while another idles (seen on a
 * virtual machine, each thread woken onto the other's processor), and a
 * fresh process often starts so. Going alone is for a machine with no core
 * free. */
static int cores_idle(uint64_t *ticks)
{
#ifdef __linux__
    unsigned long mask[16] = {0}; /* 1024 processors */
    long got = syscall(SYS_sched_getaffinity, 0, sizeof mask, mask);
    FILE *f = fopen("/proc/stat", "re");
    if (got <= 0 || !f) {
        if (f)
            fclose(f);
        return 0;
    }
    char line[256];
    uint64_t sum = 0;
    int any = 0;
    const unsigned bits = 8 * sizeof mask[0];
    while (fgets(line, sizeof line, f)) {
        unsigned cpu;
        unsigned long long user, nice, sys, idle, iowait;
        if (strncmp(line, "cpu", 3) != 0)
            break; /* the per-processor lines come first */
        if (line[3] < '0' || line[3] > '9')
            continue; /* the machine's total */
        if (sscanf(line, "cpu%u %llu %llu %llu %llu %llu", &cpu, &user, &nice, &sys, &idle,
                   &iowait) != 6 ||
            cpu >= 8 * (unsigned)sizeof mask || !(mask[cpu / bits] >> (cpu % bits) & 1))
            continue;
        sum += idle + iowait;
        any = 1;
    }
    fclose(f);
    *ticks = sum;
    return any;
#else
    (void)ticks;
    return 0;
#endif
}

void mts__stream_par_batch_start(mts_stream_client *c)
{
    struct mts__stream_par *p = c->par;
    if (p->pipe && !p->win_wall && !par_delay(p, &p->win_delay))
        p->win_delay = UINT64_MAX;
    p->at_wall = now_ns();
}

uint32_t mts_stream_client_threads_used(const mts_stream_client *c)
{
    return c->threads_ran ? c->threads_ran : 1;
}

/* Room for n triangle ids and their inverse, grown by doubling. */
static mts_result ids_reserve(struct mts__stream_par *p, uint32_t n, mts_error *err)
{
    if (n <= p->ids_cap)
        return MTS_OK;
    uint32_t cap = n > 2 * p->ids_cap ? n : 2 * p->ids_cap;
    uint32_t *a = realloc(p->ids, (size_t)cap * 4), *b;
    if (a)
        p->ids = a;
    if (!a || !(b = realloc(p->inv, (size_t)cap * 4)))
        return mts_error_set(err, MTS_ERR_NOMEM, "out of memory for triangle ids");
    p->inv = b;
    p->ids_cap = cap;
    return MTS_OK;
}

/* Composes the key orders of the intervals up to i into ids (waiting for
 * each worker's key split): what an explicit split's triangle ids, and the
 * next worker, need. */
static mts_result par_chain(mts_stream_client *c, uint32_t i, mts_error *err)
{
    struct mts__stream_par *p = c->par;
    for (; p->composed < i; p->composed++) {
        const uint32_t k = p->composed + 1;
        /* the key split of interval k, split key_levels[k - 1] - 1, made
         * (pipe: its order known, half way through that split) */
        mts_result rc = p->pipe ? par_wait_order(p, k, err)
                                : par_wait(p, k, p->iv[k].first + 1, 0, err);
        if (rc != MTS_OK)
            return rc;
        uint32_t count = 0;
        const uint32_t *order = NULL;
        if (p->pipe) {
            order = p->orders[k - 1];
            count = p->order_n[k - 1];
        } else {
            order = mts_grow_key_order(p->iv[k].w, &count);
        }
        if ((rc = ids_reserve(p, count, err)) != MTS_OK)
            return rc;
        /* the triangles born since the last key have the same id in both */
        for (; p->ids_n < count; p->ids_n++)
            p->ids[p->ids_n] = p->ids_n;
        for (uint32_t x = 0; order && x < count; x++) {
            p->ids[x] = order[p->ids[x]];
            p->inv[p->ids[x]] = x;
        }
    }
    return MTS_OK;
}

/* The ids a new worker starts in: those composed, and for the triangles
 * born since, their own. */
static mts_result par_ids(mts_stream_client *c, mts_error *err)
{
    struct mts__stream_par *p = c->par;
    mts_grow_figures fig;
    mts_grow_get_figures(c->grow, &fig);
    mts_result rc = ids_reserve(p, fig.triangles, err);
    if (rc != MTS_OK)
        return rc;
    for (; p->ids_n < fig.triangles; p->ids_n++)
        p->ids[p->ids_n] = p->inv[p->ids_n] = p->ids_n;
    return MTS_OK;
}

/* Interval k's worker is done: its slots become the fix-up's state. */
static mts_result par_retire(struct mts__stream_par *p, uint32_t k, mts_error *err)
{
    mts_result rc = par_wait(p, k, 0, 1, err);
    if (rc == MTS_OK)
        rc = mts_grow_fixup_end(p->fix, p->iv[k].w, err);
    mts_grow_free(p->iv[k].w);
    p->iv[k].w = NULL;
    par_free_blocks(&p->iv[k]);
    return rc;
}

/* Fixes up and keeps the records below `upto`, in level order, as their
 * workers make them. */
/* The records kept so far, applied to the runtime (up to the stop). */
static mts_result par_apply(mts_stream_client *c, mts_error *err)
{
    const uint32_t cap = c->par->apply_cap;
    const uint32_t fixed = c->par->fixed < cap ? c->par->fixed : cap;
    const uint32_t to = fixed < c->stop_level ? fixed : c->stop_level;
    if (c->lod.level >= to)
        return MTS_OK;
    mts_lod_set_available(&c->lod, fixed);
    return mts_lod_set_level(&c->lod, to, err);
}

/* Pipe, every record below the full level kept: the full level's, made
 * on the pool's grow, whose slots are the real ones, is kept as it is. */
static mts_result par_full(mts_stream_client *c, mts_error *err)
{
    struct mts__stream_par *p = c->par;
    const uint32_t j = p->iv[1].first;
    mts_result rc = MTS_OK;
    if (!p->full_rec)
        return mts_error_set(err, MTS_ERR_INTERNAL, "stream: the full level's split is not made");
    if ((rc = par_apply(c, err)) != MTS_OK ||
        (rc = mts__stream_keep_record(c, j, p->full_rec, p->full_words, err)) != MTS_OK)
        return rc;
    p->fixed = j + 1;
    p->full_rec = NULL;
    return MTS_OK;
}

mts_result mts__stream_par_fixup(mts_stream_client *c, uint32_t upto, mts_error *err)
{
    struct mts__stream_par *p = c->par;
    const uint32_t nb = c->model.base_vertex_count;
    while (p->fixed < upto) {
        const uint32_t j = p->fixed;
        while (j >= p->iv[p->fix_iv].end)
            p->fix_iv++;
        const uint32_t i = p->fix_iv;
        mts_result rc = MTS_OK;
        if (p->pipe && i == 1)
            return par_full(c, err);
        /* about to wait: what is kept is applied meanwhile, so that the
         * batch's end is left only with what the pool makes last */
        if (p->iv[i].seen <= j && atomic_load(&p->iv[i].made) <= j &&
            (rc = par_apply(c, err)) != MTS_OK)
            return rc;
        rc = par_wait(p, i, j + 1, 0, err);
        if (rc != MTS_OK)
            return rc;
        const logged_split *ls = par_entry(p, j);
        const uint32_t *o = ls->rec;
        uint32_t ow = ls->rec_words;
        if (i > 0 && j == p->iv[i].first) {
            if ((rc = par_retire(p, i - 1, err)) != MTS_OK ||
                (rc = mts_grow_fixup_key(p->fix, ls->rec, ls->rec_words, ls->sp.parent, nb + j,
                                         0, &o, &ow, err)) != MTS_OK)
                return rc;
        } else if (i > 0 &&
                   (rc = mts_grow_fixup_record(p->fix, ls->rec, ls->rec_words, &o, &ow, err)) !=
                       MTS_OK) {
            return rc;
        }
        if (p->own_data) /* the pool wrote it in place, and its end */
            c->model.record_word_count = c->model.record_offsets[j + 1];
        else if ((rc = mts__stream_keep_record(c, j, o, ow, err)) != MTS_OK)
            return rc;
        p->fixed = j + 1;
        /* the blocks before the one this record lies in are all kept (the
         * worker linked the next block before making a record there) */
        interval *v = &p->iv[i];
        const uintptr_t at = (uintptr_t)ls->rec;
        while (v->blocks && (at < (uintptr_t)v->blocks->w ||
                             at > (uintptr_t)(v->blocks->w + v->blocks->cap))) {
            rec_block *b = v->blocks;
            v->blocks = b->next;
            rec_block_free(b);
        }
        if (p->fixed % LOG_CHUNK == 0)
            par_free_chunk(p, p->fixed / LOG_CHUNK - 1);
    }
    return MTS_OK;
}

/* Between splits: the records the workers have made so far, below upto,
 * fixed up, kept and applied to the runtime without waiting, so that the
 * batch's end waits only for what the workers lag behind (the caller sees
 * the runtime only once the batch is in). */
mts_result mts__stream_par_catch_up(mts_stream_client *c, uint32_t upto, mts_error *err)
{
    struct mts__stream_par *p = c->par;
    uint32_t ready = p->fixed;
    /* the successor's key needs the interval's worker done, not only its
     * records made (par_grow stores made, then done): done is read first */
    for (uint32_t k = p->fix_iv; k < p->queued && ready < upto; k++) {
        interval *v = &p->iv[k];
        const int done = atomic_load(&v->done);
        const uint32_t made = atomic_load(&v->made);
        v->seen = made;
        if ((done && v->rc != MTS_OK) || made < v->first)
            break;
        ready = made < upto ? made : upto;
        if (made < v->end || !done)
            break;
    }
    if (ready <= p->fixed)
        return MTS_OK;
    mts_result rc = mts__stream_par_fixup(c, ready, err);
    return rc == MTS_OK ? par_apply(c, err) : rc;
}

/* Pipe: waits for the pool's grow to be done, keeping (and applying, as
 * far as the batch being taken allows) its records as they come, which the
 * batch's end would otherwise do after the full split: on the 1.2M mesh
 * the pool makes 30K to 95K of them while the decode thread waits here. */
static mts_result par_keep_until_done(mts_stream_client *c, mts_error *err)
{
    struct mts__stream_par *p = c->par;
    for (;;) {
        const int done = atomic_load(&p->iv[0].done);
        const uint32_t made = atomic_load(&p->iv[0].made);
        mts_result rc = made > p->fixed ? mts__stream_par_catch_up(c, made, err) : MTS_OK;
        if (rc != MTS_OK || done)
            return rc == MTS_OK ? par_wait(p, 0, 0, 1, err) : rc;
        const uint32_t end = p->iv[0].end;
        if ((rc = par_wait(p, 0, end - made > KEEP_CHUNK ? made + KEEP_CHUNK : end, 0, err)) !=
            MTS_OK)
            return rc;
    }
}

/* Whether the decode thread, at key k with the pool at `made` (of n
 * levels), makes the key's paths. In units of the pool's splits, measured on
 * bunny00 and the 1.2M mesh alike: greedy.c here costs some 8% of the key's
 * splits, the pool's whole key split some 11%. So the pool takes the paths
 * where it is a tenth behind: it is the bound then, and the decode thread
 * has time to spare. At the last key, too, where the decode thread, going
 * on to the full level (its splits past the key), would wait there for the
 * pool's key, it waits less making them itself (it then knows the ids
 * through the key). Elsewhere (the pool close behind) it goes on. */
static int par_key_paths_pay(const struct mts__stream_par *p, uint32_t k, uint32_t made,
                             uint32_t n)
{
    const uint32_t level = p->go.key_levels[k];
    const uint64_t behind = level - (made < level ? made : level);
    return p->hand || behind > level / 10 ||
           (k + 1 == p->keys_below && behind + level / 32 > n - level);
}

/* The paths of the keys the pool is past are freed. */
static void par_free_key_paths(struct mts__stream_par *p)
{
    const uint32_t made = atomic_load(&p->iv[0].made);
    for (; p->kp_freed < p->keys_below && made >= p->go.key_levels[p->kp_freed]; p->kp_freed++) {
        key_paths *kp = &p->kp[p->kp_freed];
        free(kp->order);
        free(kp->starts);
        kp->order = kp->starts = NULL;
    }
}

/* Pipe, the mesh-only grow at key k: its restripification, which the pool's
 * grow makes there, made here too where it pays (par_key_paths_pay), in
 * the pool's ids (those of the key before). Below the last key only where
 * those are known without waiting (the decode thread made the key before's
 * paths too, or the pool is past it); at the last key waited for where the
 * pool is not past it yet, as the batch's end would wait for its records.
 * The pool takes the paths if it gets there after them, and the decode
 * thread then knows the ids through the key, which explicit splits, the
 * next key's paths and the full level's walk need; else it takes them from
 * the pool's order. */
static mts_result par_key_paths(mts_stream_client *c, uint32_t k, mts_error *err)
{
    struct mts__stream_par *p = c->par;
    const uint32_t levels = c->model.level_count;
    const int last = k + 1 == p->keys_below;
    par_free_key_paths(p);
    if (p->composed > k || k < p->kp_freed ||
        !par_key_paths_pay(p, k, atomic_load(&p->iv[0].made), levels) ||
        (!last && !p->hand && p->composed < k && atomic_load(&p->orders_ready) < k))
        return MTS_OK;
    mts_result rc = par_chain(c, k, err);
    if (rc != MTS_OK || !par_key_paths_pay(p, k, atomic_load(&p->iv[0].made), levels))
        return rc;
    if ((rc = par_ids(c, err)) != MTS_OK)
        return rc;
    /* in the pool's ids; mine: the same in the mesh-only grow's */
    key_paths *kp = &p->kp[k];
    const uint32_t n = p->ids_n;
    uint32_t *mine = malloc((size_t)n * 4 + 4), count = 0;
    kp->order = malloc((size_t)n * 4 + 4);
    kp->starts = malloc((size_t)n * 4 + 8);
    if (!mine || !kp->order || !kp->starts)
        rc = mts_error_set(err, MTS_ERR_NOMEM, "out of memory for a key's paths");
    if (rc == MTS_OK)
        rc = mts_grow_key_paths(c->grow, p->ids, p->inv, kp->order, kp->starts, &count, err);
    if (rc == MTS_OK) {
        for (uint32_t i = 0; i < n; i++)
            mine[i] = p->inv[kp->order[i]];
        kp->count = count;
        kp->triangles = n;
        int expect = KP_OPEN;
        atomic_compare_exchange_strong(&kp->state, &expect, KP_GIVEN);
        /* the key's renumbering, composed: what the pool's order would add */
        for (uint32_t i = 0; i < n; i++) {
            p->ids[mine[i]] = i;
            p->inv[i] = mine[i];
        }
        p->composed = k + 1;
    }
    free(mine);
    return rc;
}

/* Pipe, the full level's split: its walk reads this batch's coder, so it
 * runs here, on the mesh-only grow (the start ids it reads mapped through
 * the keys), while the pool finishes; the pool's grow then takes the
 * strips walked, once it is done. An error of the pool's, at an earlier
 * split, is the one to give. */
static mts_result par_full_split(mts_stream_client *c, const mts_grow_split *sp,
                                 const mts_grow_split *ms, const mts_grow_full *full,
                                 mts_error *err)
{
    struct mts__stream_par *p = c->par;
    mts_error werr = {0};
    mts_strips walked = {0};
    mts_result wrc = par_chain(c, p->keys_below, err);
    if (wrc != MTS_OK)
        return wrc;
    if ((wrc = mts_grow_split_mesh(c->grow, ms, &werr)) == MTS_OK &&
        (wrc = par_ids(c, &werr)) == MTS_OK) {
        mts_grow_full f = *full;
        f.first_ids = p->inv;
        f.first_id_count = p->ids_n;
        wrc = mts_grow_full_strips(c->grow, &f, &walked, &werr);
    }
    mts_result rc = par_keep_until_done(c, err);
    /* the pool, done, reached the last key: it took the paths or made its own */
    c->threads_key_paths_handed =
        p->keys_below && atomic_load(&p->kp[p->keys_below - 1].state) == KP_GIVEN;
    if (rc == MTS_OK && wrc != MTS_OK) {
        rc = wrc;
        if (err)
            *err = werr;
    }
    par_free_key_paths(p);
    if (rc == MTS_OK) {
        const mts_grow_full taken = {.derived = &walked};
        rc = mts_grow_next(p->iv[0].w, sp, &taken, &p->full_rec, &p->full_words, err);
    }
    mts_strips_free(&walked);
    return rc;
}

/* Split j on the decode thread: a worker made where a key interval starts,
 * the split logged for it (or, the full level's, derived here), and the
 * mesh-only grow split. *lists (an explicit split's) passes to the log. */
mts_result mts__stream_par_split(mts_stream_client *c, uint32_t j, const mts_grow_split *sp,
                                 uint32_t **lists, const mts_grow_full *full, mts_error *err)
{
    struct mts__stream_par *p = c->par;
    while (p->dec_iv + 1 < p->iv_count && j >= p->iv[p->dec_iv + 1].first)
        p->dec_iv++;
    const uint32_t i = p->dec_iv;
    const int starts = i > 0 && j == p->iv[i].first, last = i + 1 == p->iv_count;
    /* an explicit split names triangles by one grow's ids at level j: the
     * keys before j renumbered them; a new worker starts in the ids before
     * its key. Only those wait for the chain: any other split goes on
     * decoding while its interval's worker restripifies at the key. */
    uint32_t keys = starts ? i - 1 : i;
    if (p->pipe) {
        while (p->dec_keys < p->go.key_count && p->go.key_levels[p->dec_keys] <= j)
            p->dec_keys++;
        keys = p->dec_keys;
    }
    mts_result rc =
        (starts && !p->pipe) || sp->moved_count ? par_chain(c, keys, err) : MTS_OK;
    if (rc != MTS_OK)
        return rc;
    mts_grow_split ms = *sp;
    if (sp->moved_count) {
        p->mapped.n = 0;
        if (!mts_words_reserve(&p->mapped, sp->moved_count))
            return mts_error_set(err, MTS_ERR_NOMEM, "out of memory");
        for (uint32_t k = 0; k < sp->moved_count; k++) {
            const uint32_t x = sp->moved[k];
            p->mapped.w[k] = x < p->ids_n && p->composed ? p->inv[x] : x;
        }
        ms.moved = p->mapped.w;
    }
    if (starts && p->pipe) {
        return par_full_split(c, sp, &ms, full, err);
    } else if (starts) {
        mts_grow *w = NULL;
        if ((rc = par_ids(c, err)) != MTS_OK ||
            (rc = mts_grow_create_worker(c->grow, p->composed ? p->ids : NULL, &p->go, &w,
                                         err)) != MTS_OK)
            return rc;
        if (last) {
            /* the full level: the fix-up must have every record before */
            const uint32_t *r, *o;
            uint32_t rw, ow;
            if ((rc = mts__stream_par_fixup(c, j, err)) == MTS_OK &&
                (rc = mts_grow_next(w, sp, full, &r, &rw, err)) == MTS_OK &&
                (rc = par_retire(p, i - 1, err)) == MTS_OK &&
                (rc = mts_grow_fixup_key(p->fix, r, rw, sp->parent, c->model.base_vertex_count + j,
                                         1, &o, &ow, err)) == MTS_OK &&
                (rc = mts__stream_keep_record(c, j, o, ow, err)) == MTS_OK)
                p->fixed = j + 1;
            mts_grow_free(w);
            if (rc != MTS_OK)
                return rc;
        } else {
            p->iv[i].w = w;
            pthread_mutex_lock(&p->mu);
            p->queued = i + 1;
            pthread_cond_broadcast(&p->work);
            pthread_mutex_unlock(&p->mu);
        }
    }
    if (!last) {
        logged_split **ch = &p->chunk[j / LOG_CHUNK];
        if (!*ch && !(*ch = calloc(LOG_CHUNK, sizeof **ch)))
            return mts_error_set(err, MTS_ERR_NOMEM, "out of memory for the split log");
        logged_split *ls = &(*ch)[j % LOG_CHUNK];
        ls->sp = *sp;
        ls->lists = *lists;
        *lists = NULL;
        /* the ring the fan code was decoded in, for the pool not to walk */
        uint32_t rn = 0;
        int closed = 0;
        const uint32_t *ring =
            p->pipe && !sp->moved_count ? mts_grow_ring_at_hand(c->grow, sp->parent, &rn, &closed)
                                        : NULL;
        ls->ring_n = ring && rn <= RING_MAX ? rn : 0;
        ls->ring_closed = (uint32_t)closed;
        if (ls->ring_n)
            memcpy(ls->ring, ring, (size_t)rn * 4);
        par_publish(p, j + 1);
    }
    rc = mts_grow_split_mesh(c->grow, &ms, err);
    if (rc == MTS_OK && p->pipe && p->dec_keys < p->keys_below &&
        j + 1 == p->go.key_levels[p->dec_keys])
        rc = par_key_paths(c, p->dec_keys, err);
    return rc;
}


void mts__stream_par_apply_upto(mts_stream_client *c, uint32_t upto)
{
    c->par->apply_cap = upto;
}

int mts__stream_par_ahead_wanted(mts_stream_client *c, uint32_t upto, uint32_t *ahead)
{
    struct mts__stream_par *p = c->par;
    *ahead = p->ahead;
    /* the test's switch comes after the batch it names, none decoded past it */
    const uint32_t next = c->batches + 1 + p->ahead;
    if (!p->pipe || p->ahead_failed || p->want_alone || p->ahead_held ||
        (c->threads_alone_after && next >= c->threads_alone_after))
        return 0;
    return p->ahead == 0 || atomic_load(&p->iv[0].made) < upto;
}

void mts__stream_par_ahead_done(mts_stream_client *c, mts_result rc, const mts_error *e)
{
    struct mts__stream_par *p = c->par;
    if (rc == MTS_OK) {
        p->ahead++;
        return;
    }
    p->ahead_failed = 1;
    p->ahead_rc = rc;
    p->ahead_err = *e;
}

int mts__stream_par_ahead_take(mts_stream_client *c, mts_result *rc, mts_error *err)
{
    struct mts__stream_par *p = c->par;
    *rc = MTS_OK;
    if (p->ahead) {
        p->ahead--;
        return 1;
    }
    if (!p->ahead_failed)
        return 0;
    p->ahead_failed = 0;
    *rc = p->ahead_rc;
    if (err)
        *err = p->ahead_err;
    return 1;
}

void mts__stream_par_ahead_hold(mts_stream_client *c, int hold)
{
    if (c->par)
        c->par->ahead_held = hold;
}

uint32_t mts__stream_par_ahead_batches(const mts_stream_client *c)
{
    return c->par ? c->par->ahead : 0;
}

/* Pipe, every record below `level` kept: the pool thread waits for a split
 * that will not come. Stopped, its grow is one grow's at `level`, so it
 * becomes the decoder's (in place of the mesh-only grow) and the rest of
 * the stream decodes as with one thread. */
static void par_alone(mts_stream_client *c, uint32_t level)
{
    struct mts__stream_par *p = c->par;
    interval *v = &p->iv[0];
    if (atomic_load(&v->made) != level || atomic_load(&v->done) || !v->w)
        return; /* not where the records are (the fix-up saw to it): stay on two */
    par_stop(p);
    mts_grow_free(c->grow);
    c->grow = v->w;
    v->w = NULL;
    mts_grow_on_key_order(c->grow, NULL, NULL); /* p is freed below */
    mts__stream_par_free(p);
    c->par = NULL;
    c->threads_alone_from = level;
}

/* Pipe, after a batch: whether the pool thread waited for a core for
 * SLOW_PERCENT of SLOW_WINDOWS windows in a row while no core idled. */
static int par_crowded(struct mts__stream_par *p)
{
    int crowded = 0;
    p->win_wall += now_ns() - p->at_wall;
    uint64_t delay;
    if (p->win_wall >= WINDOW_NS && p->win_delay != UINT64_MAX &&
        par_delay(p, &delay) && delay >= p->win_delay) {
        const uint64_t d = delay - p->win_delay;
        p->slow = d * 100 >= p->win_wall * SLOW_PERCENT ? p->slow + 1 : 0;
        uint64_t idle = 0;
        if (p->slow == 1 && !cores_idle(&p->slow_idle))
            p->slow_idle = UINT64_MAX;
        if (p->slow >= SLOW_WINDOWS) {
            /* a core idled for a tick or more of those windows (12 ms at
             * least): the threads were placed badly, not crowded out */
            if (p->slow_idle != UINT64_MAX && cores_idle(&idle) && idle > p->slow_idle)
                p->slow = 0;
            else
                crowded = 1;
        }
    }
    if (p->win_wall >= WINDOW_NS)
        p->win_wall = 0;
    return crowded;
}

void mts__stream_par_batch_end(mts_stream_client *c, uint32_t index)
{
    struct mts__stream_par *p = c->par;
    const uint32_t level = p->fixed;
    /* after the last batch nothing is left to go on with */
    if (!p->pipe || level + 1 >= c->model.level_count)
        return;
    if (c->threads_alone_after) { /* the test's word, not a measure */
        if (index + 1 >= c->threads_alone_after)
            p->want_alone = 1;
    } else if (!p->want_alone && !p->hand && par_crowded(p)) {
        p->want_alone = 1;
    }
    /* once the batches decoded ahead are taken: the pool's grow is then
     * where the records are, and no split waits in the log */
    if (p->want_alone && !p->ahead && !p->ahead_failed)
        par_alone(c, level);
}
