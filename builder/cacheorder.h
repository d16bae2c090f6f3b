/* Cache order (cacheorder.c): strips ordered, and each read in one of its
 * directions, for a FIFO post-transform vertex cache. Internal to the
 * stripifier (tunnel.c): mts__ names. */
#ifndef MTS_CACHEORDER_H
#define MTS_CACHEORDER_H

#include <stdint.h>

/* A strip encoded both ways in a shared index buffer. */
typedef struct mts__order_path {
    uint32_t at[2], len[2]; /* [0] forward, [1] backward, in buf */
    uint32_t cold[2];       /* set by mts__order_paths: misses into an empty cache */
    uint8_t dirs;           /* bit d: direction d allowed (the shorter ones) */
} mts__order_path;

/* Orders paths[0 .. n) for a FIFO of csize (<= 1: the input's order, each
 * path the first way it allows): emit[i] is the i-th path drawn, emit_dir[i]
 * its direction (n entries each, the caller's); *misses the misses of that
 * order from an empty cache (0 with csize <= 1). Every index in buf is
 * below vertex_count, every len at most 2 max_path + 2. Returns 0 when out
 * of memory (emit then holds nothing useful). Deterministic. */
int mts__order_paths(mts__order_path *paths, uint32_t n, const uint32_t *buf,
                     uint32_t vertex_count, uint32_t csize, uint32_t max_path, uint32_t *emit,
                     uint8_t *emit_dir, uint64_t *misses);

#endif
