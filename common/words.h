/* A growable array of 32-bit words, for builders that append records and
 * strip indices (grow.c, lodbuild.c). */
#ifndef MTS_WORDS_H
#define MTS_WORDS_H

#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

typedef struct mts_words {
    uint32_t *w;
    size_t n, cap;
} mts_words;

/* Room for `extra` more words; 0 when out of memory (v unchanged). */
static inline int mts_words_reserve(mts_words *v, size_t extra)
{
    if (v->n + extra <= v->cap)
        return 1;
    size_t cap = v->cap ? v->cap : 16;
    while (cap < v->n + extra)
        cap *= 2;
    uint32_t *w = (uint32_t *)realloc(v->w, cap * sizeof *w);
    if (!w)
        return 0;
    v->w = w;
    v->cap = cap;
    return 1;
}

/* qsort's comparison of two uint32_t, ascending. */
static inline int mts_words_cmp(const void *a, const void *b)
{
    const uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return x < y ? -1 : x > y;
}

/* The same for two uint64_t (keys packed from two words). */
static inline int mts_words_cmp64(const void *a, const void *b)
{
    const uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

#endif
