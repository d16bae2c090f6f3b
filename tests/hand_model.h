/* Models made by hand, for the tests of the runtime (test_lod), the record
 * codec (test_reccodec) and the model file (test_modelfile), which must not
 * depend on what the builder happens to emit: the strips are given at every
 * level, the records word by word in model.h's layout, and the base and full
 * strips, the level table and (unless given) the capacities follow from
 * them. Random models name a strip in several edits, erase and insert empty
 * runs, put back what an earlier edit erased and substitute inside inserted
 * runs, which a builder may never do but a runtime must get right. */
#ifndef MTS_HAND_MODEL_H
#define MTS_HAND_MODEL_H

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "model.h"

enum { HAND_STRIPS = 4, HAND_LEN = 64 };

/* Every strip at one level (or, for capacities, at one moment of a split). */
typedef struct hand_state {
    uint32_t len[HAND_STRIPS];
    uint32_t d[HAND_STRIPS][HAND_LEN];
} hand_state;

static inline uint32_t *hand_copy(const uint32_t *w, size_t n)
{
    uint32_t *c = malloc((n + 1) * sizeof *c);
    if (c && n)
        memcpy(c, w, n * sizeof *c);
    return c;
}

static inline uint32_t hand_triangles(const uint32_t *s, uint32_t n)
{
    uint32_t t = 0;
    for (uint32_t k = 0; k + 2 < n; k++)
        t += s[k] != s[k + 1] && s[k + 1] != s[k + 2] && s[k] != s[k + 2];
    return t;
}

/* Deterministic pseudo-random numbers. */
static inline uint32_t hand_rng(uint64_t *s)
{
    *s = *s * 6364136223846793005ull + 1442695040888963407ull;
    return (uint32_t)(*s >> 33);
}

/* Fills m (everything copied): nb base vertices, n splits with these parents
 * and records (roff: n + 1 offsets into rec), ns strips whose content at
 * level l is snap[l]. capacity NULL: each strip's longest over the levels.
 * Vertex i sits at 1 on axis i % 3, inside the box [0,1]^3. */
static inline void hand_model_from_states(mts_model *m, uint32_t nb, uint32_t n, uint32_t ns,
                                          const uint32_t *parents, const uint32_t *roff,
                                          const uint32_t *rec, const hand_state *snap,
                                          const uint32_t *capacity)
{
    memset(m, 0, sizeof *m);
    m->vertex_count = nb + n;
    m->base_vertex_count = nb;
    m->level_count = n;
    m->strip_count = ns;
    m->positions = calloc(3 * (size_t)m->vertex_count, sizeof(float));
    m->normals = calloc(3 * (size_t)m->vertex_count, sizeof(float));
    for (uint32_t i = 0; i < m->vertex_count; i++)
        m->positions[3 * i + i % 3] = 1.0f;
    m->bbox_max[0] = m->bbox_max[1] = m->bbox_max[2] = 1.0f;
    m->parents = hand_copy(parents, n);
    m->record_offsets = hand_copy(roff, (size_t)n + 1);
    m->record_data = hand_copy(rec, roff[n]);
    m->record_word_count = roff[n];
    m->capacity = malloc(((size_t)ns + 1) * 4);
    for (uint32_t s = 0; s < ns; s++) {
        uint32_t c = 0;
        for (uint32_t l = 0; l <= n; l++)
            c = snap[l].len[s] > c ? snap[l].len[s] : c;
        m->capacity[s] = capacity ? capacity[s] : c;
    }
    mts_strips *sets[2] = {&m->base, &m->full};
    const hand_state *ends[2] = {&snap[0], &snap[n]};
    for (int b = 0; b < 2; b++) {
        uint32_t total = 0, o = 0;
        for (uint32_t s = 0; s < ns; s++)
            total += ends[b]->len[s];
        mts_strips_alloc(sets[b], ns, total, NULL);
        for (uint32_t s = 0; s < ns; s++) {
            sets[b]->offsets[s] = o;
            memcpy(sets[b]->indices + o, ends[b]->d[s], ends[b]->len[s] * 4);
            o += ends[b]->len[s];
        }
        sets[b]->offsets[ns] = o;
    }
    m->level_triangles = malloc(((size_t)n + 1) * 4);
    m->level_strips = malloc(((size_t)n + 1) * 4);
    m->level_indices = malloc(((size_t)n + 1) * 4);
    for (uint32_t l = 0; l <= n; l++) {
        uint32_t tr = 0, st = 0, ix = 0;
        for (uint32_t s = 0; s < ns; s++) {
            tr += hand_triangles(snap[l].d[s], snap[l].len[s]);
            st += snap[l].len[s] > 0;
            ix += snap[l].len[s];
        }
        m->level_triangles[l] = tr;
        m->level_strips[l] = st;
        m->level_indices[l] = ix;
    }
}

/* One strip through one split (strip 0 only), as the state at two levels:
 * for the one-split models the tests write out. */
static inline void hand_model_one_split(mts_model *m, const uint32_t *base, uint32_t base_len,
                                        const uint32_t *full, uint32_t full_len,
                                        const uint32_t *rec, uint32_t rec_len)
{
    hand_state snap[2] = {0};
    snap[0].len[0] = base_len;
    memcpy(snap[0].d[0], base, base_len * 4);
    snap[1].len[0] = full_len;
    memcpy(snap[1].d[0], full, full_len * 4);
    const uint32_t parent = 0, roff[2] = {0, rec_len};
    hand_model_from_states(m, 3, 1, 1, &parent, roff, rec, snap, NULL);
}

/* A model whose strips are not monotone in the level (nb = 3, 2 splits):
 *   level 0  strip 0 = 0 1 2          strip 1 = 1 2 0
 *   split 0 (v 3, u 0): strip 0 gets (1 0) at 3, position 4 becomes 3
 *   level 1  strip 0 = 0 1 2 1 3      strip 1 = 1 2 0
 *   split 1 (v 4, u 1): strip 0 loses (2 1 3) at 2, position 1 becomes 4;
 *                       strip 1 loses all of (1 2 0) and gets an empty
 *                       run (an empty slot at the full level)
 *   level 2  strip 0 = 0 4            strip 1 = (empty)
 * so strip 0's capacity (5) is its length at level 1, longer than at either
 * end, and strip 1's (3) is its base length; snap gets the three levels. */
static inline void hand_model_erases(mts_model *m, hand_state snap[3])
{
    static const uint32_t rec[] = {
        /* split 0 */
        1,                   /* edits */
        0, 0, 1, 1,          /* strip 0: no erase, 1 insert, 1 subst */
        3, 2, 1, 0,          /*   insert (1 0) at 3 */
        4,                   /*   position 4: 0 -> 3 */
        /* split 1 */
        2,                   /* edits */
        0, 1, 0, 1,          /* strip 0: 1 erase, no insert, 1 subst */
        2, 3, 2, 1, 3,       /*   erase (2 1 3) at 2 */
        1,                   /*   position 1: 1 -> 4 */
        1, 1, 1, 0,          /* strip 1: 1 erase, 1 insert, no subst */
        0, 3, 1, 2, 0,       /*   erase (1 2 0) at 0 */
        0, 0,                /*   insert () at 0 */
    };
    static const uint32_t roff[3] = {0, 10, (uint32_t)(sizeof rec / sizeof rec[0])};
    static const uint32_t parents[2] = {0, 1};
    memset(snap, 0, 3 * sizeof *snap);
    const uint32_t l0s0[] = {0, 1, 2}, l0s1[] = {1, 2, 0}, l1s0[] = {0, 1, 2, 1, 3},
                   l2s0[] = {0, 4};
    snap[0].len[0] = 3, memcpy(snap[0].d[0], l0s0, sizeof l0s0);
    snap[0].len[1] = 3, memcpy(snap[0].d[1], l0s1, sizeof l0s1);
    snap[1].len[0] = 5, memcpy(snap[1].d[0], l1s0, sizeof l1s0);
    snap[1].len[1] = 3, memcpy(snap[1].d[1], l0s1, sizeof l0s1);
    snap[2].len[0] = 2, memcpy(snap[2].d[0], l2s0, sizeof l2s0);
    snap[2].len[1] = 0;
    hand_model_from_states(m, 3, 2, 2, parents, roff, rec, snap, NULL);
}

/* A random model: random base strips, then n random records applied by a
 * naive reference, which gives the strips at every level (returned,
 * n + 1 states; free() it) and each strip's capacity, the longest it is at
 * any moment of any split. wide: vertex ids up to 10^6 (multi-byte varints
 * and negative deltas for the codec), else a few (parents hit often). */
static inline hand_state *hand_random_model(uint64_t *seed, int wide, mts_model *m)
{
    uint32_t nb = wide ? 1000 + hand_rng(seed) % 1000000 : 2 + hand_rng(seed) % 3;
    uint32_t n = 1 + hand_rng(seed) % 6, ns = 1 + hand_rng(seed) % HAND_STRIPS;
    hand_state *snap = calloc((size_t)n + 1, sizeof *snap);
    uint32_t *parents = malloc((size_t)n * 4), *roff = malloc(((size_t)n + 1) * 4);
    uint32_t *rec = malloc(8192 * 4), w = 0;
    uint32_t cap[HAND_STRIPS] = {0};
    hand_state cur = {0};
    for (uint32_t s = 0; s < ns; s++) {
        cur.len[s] = hand_rng(seed) % 5;
        for (uint32_t k = 0; k < cur.len[s]; k++)
            cur.d[s][k] = hand_rng(seed) % nb;
        cap[s] = cur.len[s];
    }
    snap[0] = cur;
    for (uint32_t j = 0; j < n; j++) {
        uint32_t v = nb + j, u = hand_rng(seed) % v;
        if (!wide && hand_rng(seed) % 2 && cur.len[0])
            u = cur.d[0][0] < v ? cur.d[0][0] : u; /* a parent that is there to substitute */
        parents[j] = u;
        roff[j] = w;
        uint32_t edits = hand_rng(seed) % 4;
        rec[w++] = edits;
        for (uint32_t e = 0; e < edits; e++) {
            uint32_t s = hand_rng(seed) % ns, at = w, sub = 0;
            uint32_t era = hand_rng(seed) % 3, ins = hand_rng(seed) % 3;
            w += 4;
            for (uint32_t k = 0; k < era; k++) {
                uint32_t pos = hand_rng(seed) % (cur.len[s] + 1), room = cur.len[s] - pos;
                uint32_t run = hand_rng(seed) % ((room < 4 ? room : 4) + 1);
                rec[w++] = pos;
                rec[w++] = run;
                memcpy(rec + w, cur.d[s] + pos, run * 4);
                w += run;
                memmove(cur.d[s] + pos, cur.d[s] + pos + run, (cur.len[s] - pos - run) * 4);
                cur.len[s] -= run;
            }
            for (uint32_t k = 0; k < ins; k++) {
                uint32_t run = hand_rng(seed) % 4, pos = hand_rng(seed) % (cur.len[s] + 1);
                if (cur.len[s] + run > HAND_LEN)
                    run = 0;
                rec[w++] = pos;
                rec[w++] = run;
                memmove(cur.d[s] + pos + run, cur.d[s] + pos, (cur.len[s] - pos) * 4);
                for (uint32_t r = 0; r < run; r++) {
                    uint32_t x = hand_rng(seed) % 4 ? u : hand_rng(seed) % v;
                    cur.d[s][pos + r] = rec[w++] = x;
                }
                cur.len[s] += run;
                if (cur.len[s] > cap[s])
                    cap[s] = cur.len[s];
            }
            for (uint32_t k = 0; k < cur.len[s]; k++) {
                if (cur.d[s][k] == u && hand_rng(seed) % 2) {
                    cur.d[s][k] = v;
                    rec[w++] = k;
                    sub++;
                }
            }
            rec[at] = s;
            rec[at + 1] = era;
            rec[at + 2] = ins;
            rec[at + 3] = sub;
        }
        snap[j + 1] = cur;
    }
    roff[n] = w;
    hand_model_from_states(m, nb, n, ns, parents, roff, rec, snap, cap);
    free(parents);
    free(roff);
    free(rec);
    return snap;
}

#endif
