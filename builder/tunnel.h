/* Tunnelling (paper 004, after Stewart 2001): improves a set of strips on the
 * dual graph of the triangles they draw. An alternating tunnel from a strip
 * end (non-strip edge, strip edge, ..., non-strip edge) is complemented when
 * that makes the strips cheaper (fewer strips, fewer swaps) without closing
 * a loop or making a strip longer than the cap (a swap the start of a strip
 * needs counts like any other); the strips are then ordered, and each read
 * in the direction, that suits a FIFO vertex cache.
 * Strips are generalized (swaps, see strips.h). Deterministic for the same
 * input and options. */
#ifndef MTS_TUNNEL_H
#define MTS_TUNNEL_H

#include <stdint.h>

#include "error.h"
#include "progress.h"
#include "strips.h"

/* Longest tunnel searched by default, in dual-graph edges (odd): chosen by
 * measurement on bunny00 and fandisk_large (see tunnel.c). */
#define MTS_TUNNEL_DEFAULT_LENGTH 7
#define MTS_TUNNEL_DEFAULT_LENGTH_STR "7"
/* Simulated-annealing moves per triangle by default: keeps the pass under
 * 2 s on bunny00 (see tunnel.c for what more buys). */
#define MTS_TUNNEL_DEFAULT_ANNEAL 96
#define MTS_TUNNEL_DEFAULT_ANNEAL_STR "96"
/* Most moves per triangle accepted: bunny00 at 16384 takes minutes. */
#define MTS_TUNNEL_MAX_ANNEAL 1000000

/* Longest tunnel accepted at all: the search is exponential in it. */
#define MTS_TUNNEL_MAX_LENGTH 21
#define MTS_TUNNEL_MAX_LENGTH_STR "21"

/* Zero-initialised means the defaults. */
typedef struct mts_tunnel_options {
    int length;          /* longest tunnel in dual edges; 0: the default; < 0:
                          * no tunnelling, only the cache order; an even length
                          * counts as the odd one below it */
    uint32_t max_strip;  /* most triangles in one strip; 0: MTS_STRIPIFY_MAX_STRIP */
    uint32_t cache_size; /* FIFO the strip order is made for; 0: 32; 1: keep the
                          * order of the input */
    int anneal;          /* simulated-annealing moves per triangle after the
                          * exhaustive search (then searched again); 0: the
                          * default (MTS_TUNNEL_DEFAULT_ANNEAL); < 0: none;
                          * more than MTS_TUNNEL_MAX_ANNEAL: that many */
    mts_progress progress; /* "tunnel", through the annealing's stages */
} mts_tunnel_options;

/* Figures before (the input) and after, counted the way the benchmarks count:
 * swaps are degenerate windows, restarts one between consecutive strips,
 * draw indices every index plus the restarts. */
typedef struct mts_tunnel_stats {
    uint32_t strips_before, strips_after;
    uint64_t swaps_before, swaps_after;
    uint64_t draw_indices_before, draw_indices_after;
    uint32_t triangles;
    uint32_t changes; /* tunnels (and swap repairs) complemented */
    uint32_t passes;
    uint32_t anneal;  /* annealing moves per triangle made, 0: none */
    uint64_t cache_misses; /* misses of out, in order, through the FIFO of
                            * cache_size (empty at the start); 0 when the
                            * input's order is kept */
} mts_tunnel_stats;

/* in: strips over vertices < vertex_count. out gets strips drawing exactly
 * the same oriented triangles (every non-degenerate window of in, once
 * each), each at most max_strip triangles, never more draw indices than in
 * had when in's strips keep the cap (free with mts_strips_free). stats may
 * be NULL. An index >= vertex_count: MTS_ERR_RANGE; over (2^32 - 2) / 3
 * triangles: MTS_ERR_LIMIT. On error out is left empty. */
mts_result mts_tunnel(const mts_strips *in, uint32_t vertex_count,
                      const mts_tunnel_options *opts, mts_strips *out, mts_tunnel_stats *stats,
                      mts_error *err);

#endif
