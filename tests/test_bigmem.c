/* Large growing arrays (common/bigmem.h): contents kept as they grow, a
 * reservation grown in place, on a 2 MB boundary, backed only where
 * touched, and kept by a cache for the next client. */
#include <stdint.h>
#include <stdio.h>
#include <unistd.h>

#include "bigmem.h"
#include "test.h"

#if defined(__linux__) && UINTPTR_MAX > 0xffffffffu
#define RESERVES 1
#else
#define RESERVES 0
#endif

static void fill(uint8_t *p, size_t n, unsigned seed)
{
    for (size_t i = 0; i < n; i++)
        p[i] = (uint8_t)(i * 131u + seed);
}

static int same(const uint8_t *p, size_t n, unsigned seed)
{
    for (size_t i = 0; i < n; i++) {
        if (p[i] != (uint8_t)(i * 131u + seed))
            return 0;
    }
    return 1;
}

/* This process's resident pages, in bytes; 0 where it cannot be read. */
static size_t resident(void)
{
    FILE *f = fopen("/proc/self/statm", "r");
    unsigned long size = 0, rss = 0;
    if (!f)
        return 0;
    if (fscanf(f, "%lu %lu", &size, &rss) != 2)
        rss = 0;
    fclose(f);
    return (size_t)rss * (size_t)sysconf(_SC_PAGESIZE);
}

static void test_small_arrays_are_malloc_blocks(mts_test *t)
{
    mts_bigmem m = {0};
    m.align = 64;
    CHECK(t, mts_bigmem_room(&m, 1000, 0, 1 << 30));
    CHECK(t, m.p && m.room >= 1000 && m.reserved == 0);
    CHECK(t, (uintptr_t)m.p % 64 == 0);
    fill(m.p, 1000, 7);
    CHECK(t, mts_bigmem_room(&m, 200000, 1000, 1 << 30));
    CHECK(t, m.reserved == 0 && m.room >= 200000 && (uintptr_t)m.p % 64 == 0);
    CHECK(t, same(m.p, 1000, 7));
    CHECK(t, mts_bigmem_room(&m, 100, 0, 0)); /* less than it has: nothing moves */
    CHECK(t, m.room >= 200000);
    mts_bigmem_free(&m);
    CHECK(t, !m.p && !m.room && m.align == 64);

    mts_bigmem r = {0}; /* no alignment asked: realloc keeps what it had */
    CHECK(t, mts_bigmem_room(&r, 100, 0, 0));
    fill(r.p, 100, 3);
    CHECK(t, mts_bigmem_room(&r, 300000, 100, 0) && same(r.p, 100, 3));
    mts_bigmem_free(&r);
}

static void test_a_reservation_grows_in_place(mts_test *t)
{
    if (!RESERVES)
        SKIP(t, "no reservations on this platform");
    const size_t mb = (size_t)1 << 20;
    mts_bigmem m = {0};
    CHECK(t, mts_bigmem_room(&m, 64 * 1024, 0, 64 * mb)); /* small: malloc */
    CHECK(t, m.reserved == 0);
    fill(m.p, 64 * 1024, 11);
    CHECK(t, mts_bigmem_room(&m, 2 * mb, 64 * 1024, 64 * mb));
    CHECK(t, m.reserved >= 64 * mb && m.room == m.reserved);
    CHECK(t, (uintptr_t)m.p % (2 * mb) == 0);
    CHECK(t, same(m.p, 64 * 1024, 11));
    void *at = m.p;
    fill(m.p, 2 * mb, 5);
    CHECK(t, mts_bigmem_room(&m, 40 * mb, 2 * mb, 64 * mb));
    CHECK(t, m.p == at && same(m.p, 2 * mb, 5));
    /* past the bound it moves, keeping what it is told to */
    CHECK(t, mts_bigmem_room(&m, 100 * mb, 2 * mb, 64 * mb));
    CHECK(t, m.room >= 100 * mb && same(m.p, 2 * mb, 5));
    CHECK(t, (uintptr_t)m.p % (2 * mb) == 0);
    mts_bigmem_free(&m);
    CHECK(t, !m.p && !m.reserved);
}

static void test_memory_follows_what_is_touched(mts_test *t)
{
    if (!RESERVES)
        SKIP(t, "no reservations on this platform");
    const size_t mb = (size_t)1 << 20;
    const size_t before = resident();
    if (!before)
        SKIP(t, "no /proc/self/statm");
    mts_bigmem m = {0};
    /* a claimed bound of 4 GB is address space, not memory */
    CHECK(t, mts_bigmem_room(&m, 2 * mb, 0, 4096 * mb));
    CHECK(t, m.reserved >= 4096 * mb);
    fill(m.p, 3 * mb, 1);
    const size_t after = resident();
    /* far less than the bound (a sanitizer's shadow adds some for what is
     * touched) */
    CHECKF(t, after < before + 256 * mb, "%zu MB resident after touching 3 MB of 4 GB",
           (after - before) / mb);
    mts_bigmem_free(&m);
    /* a bound no mapping can hold: a malloc block of what is asked */
    mts_bigmem h = {0};
    CHECK(t, mts_bigmem_room(&h, 2 * mb, 0, SIZE_MAX / 2));
    CHECK(t, h.p && h.room >= 2 * mb);
    fill(h.p, 2 * mb, 9);
    CHECK(t, same(h.p, 2 * mb, 9));
    mts_bigmem_free(&h);
}

static void test_the_cache_keeps_reservations(mts_test *t)
{
    if (!RESERVES)
        SKIP(t, "no reservations on this platform");
    const size_t mb = (size_t)1 << 20;
    mts_bigmem_cache *cache = mts_bigmem_cache_create();
    CHECK(t, cache != NULL);
    if (!cache)
        return;
    mts_bigmem a = {0};
    a.cache = cache;
    CHECK(t, mts_bigmem_room(&a, 2 * mb, 0, 8 * mb));
    void *first = a.p;
    fill(a.p, 2 * mb, 2);
    mts_bigmem_free(&a);
    CHECK(t, !a.p && a.cache == cache);
    /* the next array of that bound takes it back, pages and all */
    CHECK(t, mts_bigmem_room(&a, 4 * mb, 0, 8 * mb));
    CHECK(t, a.p == first && a.reserved >= 8 * mb);
    /* a larger bound than any kept: a reservation of its own */
    mts_bigmem b = {0};
    b.cache = cache;
    CHECK(t, mts_bigmem_room(&b, 2 * mb, 0, 32 * mb));
    CHECK(t, b.p != first && b.reserved >= 32 * mb);
    /* a smaller bound takes the smallest kept that holds it */
    mts_bigmem_free(&b);
    mts_bigmem_free(&a);
    mts_bigmem c = {0};
    c.cache = cache;
    CHECK(t, mts_bigmem_room(&c, 2 * mb, 0, 4 * mb));
    CHECK(t, c.p == first);
    mts_bigmem_free(&c);
    /* no more than MTS_BIGMEM_CACHE_MAX are kept; the rest go back */
    mts_bigmem many[MTS_BIGMEM_CACHE_MAX + 4];
    int ok = 1;
    for (int i = 0; i < MTS_BIGMEM_CACHE_MAX + 4; i++) {
        many[i] = (mts_bigmem){.cache = cache};
        ok &= mts_bigmem_room(&many[i], 2 * mb, 0, 2 * mb);
    }
    CHECK(t, ok);
    for (int i = 0; i < MTS_BIGMEM_CACHE_MAX + 4; i++)
        mts_bigmem_free(&many[i]);
    mts_bigmem_cache_free(cache);
}

/* An array sized by a claim: zero throughout, only what is written
 * resident (even in a process whose heap would clear a calloc block, and
 * with a cache holding a reservation full of an earlier array's bytes), and
 * a small one a zeroed malloc block. */
static void test_zeroed_follows_what_is_written(mts_test *t)
{
    const size_t mb = (size_t)1 << 20;
    mts_bigmem s = {0};
    CHECK(t, mts_bigmem_zeroed(&s, 1000) && s.p && s.room >= 1000 && !s.reserved);
    int zero = 1;
    for (size_t i = 0; s.p && i < 1000; i++)
        zero &= ((uint8_t *)s.p)[i] == 0;
    CHECK(t, zero);
    mts_bigmem_free(&s);
    if (!RESERVES)
        SKIP(t, "no reservations on this platform");
    mts_bigmem_cache *cache = mts_bigmem_cache_create();
    CHECK(t, cache != NULL);
    if (!cache)
        return;
    mts_bigmem dirty = {.cache = cache};
    CHECK(t, mts_bigmem_room(&dirty, 64 * mb, 0, 64 * mb));
    fill(dirty.p, 64 * mb, 5);
    mts_bigmem_free(&dirty); /* kept by the cache, bytes and all */
    const size_t before = resident();
    if (!before)
        SKIP(t, "no /proc/self/statm");
    mts_bigmem z = {.cache = cache};
    CHECK(t, mts_bigmem_zeroed(&z, 64 * mb) && z.reserved >= 64 * mb);
    if (!z.p)
        return;
    uint8_t *p = z.p;
    p[0] = 1;
    const size_t after = resident();
    CHECKF(t, after < before + 16 * mb, "%zu MB resident after writing one byte of 64 MB",
           (after - before) / mb);
    /* and none of the cached array's bytes (read after the count: a read
     * may map a page, where the kernel has no shared zero page for huge
     * pages) */
    zero = p[0] == 1;
    for (size_t i = 1; i < 64 * mb; i += mb + 4097)
        zero &= p[i] == 0;
    CHECK(t, zero && p[64 * mb - 1] == 0);
    mts_bigmem_free(&z); /* to the cache too */
    mts_bigmem_cache_free(cache);
}

static void test_swap(mts_test *t)
{
    mts_bigmem a = {0}, b = {0};
    CHECK(t, mts_bigmem_room(&a, 100, 0, 0) && mts_bigmem_room(&b, 200, 0, 0));
    void *pa = a.p, *pb = b.p;
    mts_bigmem_swap(&a, &b);
    CHECK(t, a.p == pb && b.p == pa && a.room >= 200 && b.room >= 100);
    mts_bigmem_free(&a);
    mts_bigmem_free(&b);
}

int main(void)
{
    mts_test t = {0};
    RUN(&t, test_small_arrays_are_malloc_blocks);
    RUN(&t, test_a_reservation_grows_in_place);
    RUN(&t, test_memory_follows_what_is_touched);
    RUN(&t, test_the_cache_keeps_reservations);
    RUN(&t, test_zeroed_follows_what_is_written);
    RUN(&t, test_swap);
    return mts_test_end(&t);
}
