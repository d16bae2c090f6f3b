/* Large growing arrays in address space reserved once, on huge pages.
 *
 * The first touch of a fresh 4 KB page costs a fault and its zeroing. On
 * the virtual machines this project runs on a fault costs some 10 us, more
 * than decoding what fills the page, and a fresh client touches its whole
 * model that way (bunny00's took 7,400 faults for 170 ms to the full
 * picture; docs/threads.md, "A fresh client's pages"). A 2 MB huge page
 * costs one fault, some 0.1 ms with its zeroing. An array grown by
 * doubling with realloc also lands in fresh pages at each doubling, its
 * contents copied there.
 *
 * So an array that passes MTS_BIGMEM_FROM moves once into address space
 * reserved for the most it may ever hold (the caller's bound, which only
 * sizes the reservation: no page is backed before it is touched, so memory
 * still follows what arrived), 2 MB aligned and advised as huge pages
 * (madvise: a hint; where the kernel gives none, 4 KB pages as before).
 * From then on it grows in place: no copy, no page touched twice. Below
 * that size, where no reservation can be made (a 32-bit or WebAssembly
 * heap, a refused mapping) it is a malloc block: grown by realloc, or
 * where its owner asks for an alignment copied to a larger one.
 *
 * An mts_bigmem zeroed is empty. */
#ifndef MTS_BIGMEM_H
#define MTS_BIGMEM_H

#include <stddef.h>

/* from this size an array moves into a reservation */
#define MTS_BIGMEM_FROM ((size_t)1 << 20)

/* Reservations kept for the next client. A fresh reservation's pages are
 * zeroed at their first touch; a process that runs client after client (a
 * load generator, a bench) would pay that for every client, where malloc
 * used to hand each one the blocks the last one freed. Such a caller makes
 * one cache, sets it as each client's (mts_stream_client.memory), and frees
 * it after the last client and model made with it. A reservation freed
 * goes back to the cache with its pages as they are, up to
 * MTS_BIGMEM_CACHE_MAX of them (beyond, to the kernel); one asked for is
 * the smallest kept that holds the array's bound. Safe to share between
 * threads. */
typedef struct mts_bigmem_cache mts_bigmem_cache;
#define MTS_BIGMEM_CACHE_MAX 8

/* NULL when out of memory (then pass none: nothing else changes). */
mts_bigmem_cache *mts_bigmem_cache_create(void);
/* Gives every reservation kept back to the kernel. */
void mts_bigmem_cache_free(mts_bigmem_cache *cache);

typedef struct mts_bigmem {
    void *p;         /* the array; NULL when empty */
    size_t room;     /* bytes usable at p */
    size_t reserved; /* bytes of its reservation; 0: a malloc block */
    /* set by its owner, kept when it is freed: */
    size_t align;            /* a malloc block's alignment (a power of two);
                              * 0: malloc's own, grown by realloc */
    mts_bigmem_cache *cache; /* where reservations come from and go back to;
                              * NULL: the kernel */
} mts_bigmem;

/* Room for at least `bytes` at m->p, keeping its first `keep` bytes
 * (keep <= m->room); `most`: the most this array is expected to need, in
 * bytes (a reservation's size; 0: bytes). 1, or 0 when out of memory with
 * m unchanged. m->p may move. */
int mts_bigmem_room(mts_bigmem *m, size_t bytes, size_t keep, size_t most);

/* Frees what m holds and makes room for `bytes`, all of them zero, for an
 * array sized by a count it was told (a stream's claim) that only what
 * arrives fills. Past MTS_BIGMEM_FROM a reservation fresh from the kernel
 * (never from m->cache, whose pages hold an earlier array's bytes): its
 * pages stay untouched until written, so memory follows what is written,
 * not what was asked, whatever malloc would do (glibc's calloc clears a
 * block it carves from free heap memory, touching all of it). Below, or
 * where no reservation is made, a malloc block cleared. 1, or 0 when out
 * of memory (m then empty). */
int mts_bigmem_zeroed(mts_bigmem *m, size_t bytes);

/* For an array that is either m's or, where m is empty, a malloc block p
 * (an owner whose arrays come both ways): frees whichever it is. */
void mts_bigmem_release(mts_bigmem *m, void *p);

/* Exchanges two arrays (a renumbering writes into a second one). */
void mts_bigmem_swap(mts_bigmem *a, mts_bigmem *b);

void mts_bigmem_free(mts_bigmem *m);

#endif
