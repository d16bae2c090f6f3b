/* Greedy strip paths over a half-edge dual graph, in time linear in the
 * triangles: the stripifier of the key levels that growth restripifies
 * (grow.c), which every streaming client runs, so it must cost a small
 * constant a triangle and need no adjacency built for it.
 *
 * It is the greedy phase of stripify.c (STRIPE's seeds and turns, see
 * there) with STRIPE's start in place of a trial of every way out of the
 * seed (fewer strips at the key levels, and faster), and without the
 * tunnelling that follows there, whose gain at the key levels is small
 * against what it would cost every client (docs/client-cost.md).
 * What it reads is only the twin of each half-edge, never a vertex id, so
 * the same mesh gives the same paths whatever its numbering. */
#ifndef MTS_GREEDY_H
#define MTS_GREEDY_H

#include <stddef.h>
#include <stdint.h>

#include "error.h"

#define MTS_GREEDY_NONE UINT32_MAX

/* n triangles; twin[stride * t + e]: for half-edge 3t + e (from corner e of
 * t to corner e + 1), the half-edge 3t' + e' that runs the other way in the
 * neighbour t', or MTS_GREEDY_NONE at a border (stride >= 3 lets the twins
 * sit in a caller's per-triangle records). Twins must pair up and never
 * join a triangle to itself: the caller's own state, which it keeps so
 * (mts_grow_check verifies grow.c's), not input, so it is not re-checked
 * at a cost of a fifth of the call.
 *
 * Writes the paths one after another: path k is order[starts[k] ..
 * starts[k + 1]), *path_count of them, every triangle in exactly one, each
 * at most max_path (>= 1) long, consecutive triangles neighbours. A path is
 * meant to be read from order[starts[k]]: the first triangle leaves towards
 * the second without a swap, as strips.h's derived form does. order holds
 * n entries, starts n + 1. Deterministic. MTS_ERR_NOMEM. */
mts_result mts_greedy_paths(uint32_t n, const uint32_t *twin, size_t stride, uint32_t max_path,
                            uint32_t *order, uint32_t *starts, uint32_t *path_count,
                            mts_error *err);

#endif
