/* Large growing arrays in address space reserved once (bigmem.h). */
#include "bigmem.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* A reservation wants a 64-bit address space (the bounds run to gigabytes)
 * and mmap; WebAssembly's heap and 32-bit builds keep realloc. */
#if defined(__linux__) && !defined(__EMSCRIPTEN__) && UINTPTR_MAX > 0xffffffffu
#include <pthread.h>
#include <sys/mman.h>
#define BIGMEM_RESERVE 1
#else
#define BIGMEM_RESERVE 0
#endif

#define HUGE_PAGE ((size_t)2 << 20)

struct mts_bigmem_cache {
#if BIGMEM_RESERVE
    pthread_mutex_t mu;
    uint32_t count;
    void *p[MTS_BIGMEM_CACHE_MAX];
    size_t reserved[MTS_BIGMEM_CACHE_MAX];
#else
    int unused; /* nothing is reserved: nothing to keep */
#endif
};

mts_bigmem_cache *mts_bigmem_cache_create(void)
{
    mts_bigmem_cache *c = calloc(1, sizeof *c);
#if BIGMEM_RESERVE
    if (c && pthread_mutex_init(&c->mu, NULL) != 0) {
        free(c);
        return NULL;
    }
#endif
    return c;
}

void mts_bigmem_cache_free(mts_bigmem_cache *c)
{
    if (!c)
        return;
#if BIGMEM_RESERVE
    for (uint32_t i = 0; i < c->count; i++)
        munmap(c->p[i], c->reserved[i]);
    pthread_mutex_destroy(&c->mu);
#endif
    free(c);
}

#if BIGMEM_RESERVE
/* The smallest kept reservation of at least `bytes`, taken out; NULL when
 * none is. */
static void *cache_take(mts_bigmem_cache *c, size_t bytes, size_t *reserved)
{
    void *p = NULL;
    pthread_mutex_lock(&c->mu);
    uint32_t best = c->count;
    for (uint32_t i = 0; i < c->count; i++) {
        if (c->reserved[i] >= bytes && (best == c->count || c->reserved[i] < c->reserved[best]))
            best = i;
    }
    if (best < c->count) {
        p = c->p[best];
        *reserved = c->reserved[best];
        c->count--;
        c->p[best] = c->p[c->count];
        c->reserved[best] = c->reserved[c->count];
    }
    pthread_mutex_unlock(&c->mu);
    return p;
}

/* 1 when the cache kept the reservation. */
static int cache_put(mts_bigmem_cache *c, void *p, size_t reserved)
{
    int kept = 0;
    pthread_mutex_lock(&c->mu);
    if (c->count < MTS_BIGMEM_CACHE_MAX) {
        c->p[c->count] = p;
        c->reserved[c->count] = reserved;
        c->count++;
        kept = 1;
    }
    pthread_mutex_unlock(&c->mu);
    return kept;
}

/* `bytes` of address space on a 2 MB boundary, backed only where touched;
 * NULL where refused. */
static void *reserve(size_t bytes)
{
    const size_t span = bytes + HUGE_PAGE;
    if (span < bytes)
        return NULL;
    uint8_t *p = mmap(NULL, span, PROT_READ | PROT_WRITE,
                      MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
    if (p == MAP_FAILED)
        return NULL;
    /* trim to the boundary: what is cut off either side is given back */
    uint8_t *q = (uint8_t *)(((uintptr_t)p + HUGE_PAGE - 1) & ~(uintptr_t)(HUGE_PAGE - 1));
    if (q > p)
        munmap(p, (size_t)(q - p));
    if (p + span > q + bytes)
        munmap(q + bytes, (size_t)(p + span - (q + bytes)));
#ifdef MADV_HUGEPAGE
    madvise(q, bytes, MADV_HUGEPAGE);
#endif
    return q;
}
#endif

int mts_bigmem_room(mts_bigmem *m, size_t bytes, size_t keep, size_t most)
{
    if (bytes <= m->room)
        return 1;
    if (keep > m->room)
        keep = m->room;
#if BIGMEM_RESERVE
    if (bytes >= MTS_BIGMEM_FROM) {
        size_t want = most > bytes ? most : bytes;
        if (m->reserved) /* past the bound: twice over, or what is asked */
            want = bytes > 2 * m->reserved ? bytes : 2 * m->reserved;
        want = (want + HUGE_PAGE - 1) & ~(HUGE_PAGE - 1);
        void *q = NULL;
        if (want >= bytes && m->cache)
            q = cache_take(m->cache, want, &want);
        if (want >= bytes && !q)
            q = reserve(want);
        if (q) {
            if (keep)
                memcpy(q, m->p, keep);
            mts_bigmem_free(m);
            m->p = q;
            m->room = m->reserved = want;
            return 1;
        }
        if (m->reserved) /* cannot move a reservation into realloc */
            return 0;
    }
#endif
    (void)most;
    void *q;
    if (!m->align) {
        if (!(q = realloc(m->p, bytes)))
            return 0;
    } else {
        if (posix_memalign(&q, m->align, bytes) != 0)
            return 0;
        if (keep)
            memcpy(q, m->p, keep);
        free(m->p);
    }
    m->p = q;
    m->room = bytes;
    return 1;
}

int mts_bigmem_zeroed(mts_bigmem *m, size_t bytes)
{
    mts_bigmem_free(m);
    /* never the cache: what it keeps holds earlier arrays' bytes */
    mts_bigmem_cache *cache = m->cache;
    m->cache = NULL;
    const int ok = mts_bigmem_room(m, bytes ? bytes : 1, 0, 0);
    m->cache = cache;
    if (ok && !m->reserved) /* a malloc block; a fresh reservation is zero */
        memset(m->p, 0, m->room);
    return ok;
}

void mts_bigmem_release(mts_bigmem *m, void *p)
{
    if (m->p)
        mts_bigmem_free(m);
    else
        free(p);
}

void mts_bigmem_swap(mts_bigmem *a, mts_bigmem *b)
{
    const mts_bigmem t = *a;
    *a = *b;
    *b = t;
}

void mts_bigmem_free(mts_bigmem *m)
{
#if BIGMEM_RESERVE
    if (m->reserved) {
        if (!m->cache || !cache_put(m->cache, m->p, m->reserved))
            munmap(m->p, m->reserved);
    } else
#endif
        free(m->p);
    m->p = NULL;
    m->room = m->reserved = 0; /* align and cache stay: the owner's */
}
