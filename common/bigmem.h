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

typedef struct mts_bigmem {
    void *p;         /* the array; NULL when empty */
    size_t room;     /* bytes usable at p */
    size_t reserved; /* bytes of its reservation; 0: a malloc block */
    size_t align;    /* set by its owner: a malloc block's alignment (a power
                      * of two); 0: malloc's own, grown by realloc */
} mts_bigmem;

/* Room for at least `bytes` at m->p, keeping its first `keep` bytes
 * (keep <= m->room); `most`: the most this array is expected to need, in
 * bytes (a reservation's size; 0: bytes). 1, or 0 when out of memory with
 * m unchanged. m->p may move. */
int mts_bigmem_room(mts_bigmem *m, size_t bytes, size_t keep, size_t most);

/* Exchanges two arrays (a renumbering writes into a second one). */
void mts_bigmem_swap(mts_bigmem *a, mts_bigmem *b);

void mts_bigmem_free(mts_bigmem *m);

#endif
