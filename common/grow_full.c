/* The full level's strips, which a client cannot afford to compute (they
 * are tunnelled) and a stream does not send as indices: each strip is
 * described by its first triangle, the corner it starts at and one swap bit
 * per inner triangle (grow.h, mts_grow_full), and both ends walk the same
 * description over the same mesh -- the builder's encoder to learn which
 * bits the walk forces (mts_grow_full_describe), a client to turn it into
 * the full level's paths (mts__grow_resolve_full, at the last split). */
#include <stdlib.h>
#include <string.h>

#include "grow.h"
#include "grow_internal.h"
#include "strips.h"
#include "words.h"

/* the notation of grow_internal.h, short */
#define NONE MTS_GROW_NONE
#define NX mts__grow_nx
#define PV mts__grow_pv
#define TWIN MTS__GROW_TWIN

/* ---- the walk ---- */

/* Walking a described strip: it entered triangle u across u's edge e
 * (corner e of u holds the end of the edge it crossed), its last two
 * indices are (a, c), and w = u's third corner is the index u adds. It
 * leaves across the edge that keeps c (no swap) or a (a swap): the
 * half-edge of u it crosses next. */
static inline uint32_t full_exit(const mts_grow *g, uint32_t u, uint32_t e, uint32_t keep)
{
    unsigned ck = g->tri[u].v[e] == keep ? e : NX[e];
    return 3 * u + (NX[ck] == PV[e] ? ck : PV[e]);
}

/* Which exits of u are open (bit 0: no swap, bit 1: a swap): a border or a
 * triangle an earlier strip (or this one) holds is closed, so where only one
 * is open the swap bit is forced and the stream does not carry it. */
static inline unsigned full_open(const mts_grow *g, uint32_t u, uint32_t e, uint32_t a, uint32_t c,
                                 const uint8_t *claimed)
{
    unsigned open = 0;
    for (unsigned k = 0; k < 2; k++) {
        uint32_t x = TWIN(g, full_exit(g, u, e, k ? a : c));
        if (x != NONE && !claimed[x / 3]) {
            open |= 1u << k;
            /* the walk goes on into one of them: a miss a triangle, in a
             * mesh whose ids do not follow its strips, otherwise waited
             * for after the bit is decoded */
            __builtin_prefetch(&g->tri[x / 3]);
        }
    }
    return open;
}

/* The triangles next to strip `prev` (given as its triangles in order) that
 * no strip holds yet: per triangle of it, across its edges 0, 1, 2, each
 * once. Where strips lie side by side, as tunnelled ones do, the next
 * strip often starts among them (grow.h, mts_grow_full_path.near). */
static int full_near(const mts_grow *g, const mts_words *prev, uint8_t *claimed, mts_words *out)
{
    out->n = 0;
    int ok = 1;
    for (size_t k = 0; k < prev->n && ok; k++) {
        const uint32_t *tw = g->tri[prev->w[k]].tw;
        for (unsigned e = 0; e < 3; e++) {
            const uint32_t x = tw[e] == NONE ? NONE : tw[e] / 3;
            if (x == NONE || claimed[x])
                continue;
            /* listed once: marked in the byte the walk reads anyway (a
             * separate array was a miss a neighbour on a large mesh),
             * unmarked below */
            if (!(ok = mts_words_reserve(out, 1)))
                break;
            claimed[x] = 2;
            out->w[out->n++] = x;
        }
    }
    for (size_t k = 0; k < out->n; k++)
        claimed[out->w[k]] = 0;
    return ok;
}

/* Walks the described full strips over g's mesh (at the full level), slot
 * by slot, the one walk both ends make. A strip's start comes from f->paths
 * or, with f->start, from the source, handed the triangles next to the
 * strip before (full_near). Each inner triangle's swap bit is forced where
 * full_open leaves one exit; else it comes from f (the array, or the
 * source, which is handed the bit before as context). With `describe`
 * (f->paths itself, for an encoder), each path's near fields are set and
 * each swap byte in f->swaps marked forced (bit 1); with `resolve` (g
 * itself), the paths become g's. */
static mts_result full_walk(const mts_grow *g, mts_grow *resolve, const mts_grow_full *f,
                            mts_grow_full_path *describe, mts_words *derived, uint32_t *offsets,
                            mts_error *err)
{
    uint8_t *claimed = calloc((size_t)g->tri_count + 1, 1);
    mts_words prev = {0}, cur = {0}, near = {0};
    mts_result rc = claimed ? MTS_OK
                                    : mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
    uint8_t *mark = describe ? (uint8_t *)f->swaps : NULL;
    uint64_t bit = 0;
    unsigned last = 0;
    for (uint32_t s = 0; s < f->slot_count && rc == MTS_OK; s++) {
        const mts_grow_full_path *p = &f->paths[s];
        if (offsets)
            offsets[s] = (uint32_t)derived->n;
        if (!p->triangles)
            continue;
        if ((f->start || describe) && !full_near(g, &prev, claimed, &near)) {
            rc = mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
            break;
        }
        uint32_t t = p->first, r = p->rotation, at = NONE;
        if (f->start && (!f->start(f->user, near.w, (uint32_t)near.n, &at, &t, &r) ||
                         (at != NONE && at >= near.n))) {
            rc = mts_error_set(err, MTS_ERR_FORMAT, "full strips: strip %u's start is malformed",
                               s);
            break;
        }
        /* the messages name no id of g's: a grow of the same mesh in other
         * ids must fail the same way */
        const uint32_t named = t;
        if (at != NONE)
            t = near.w[at];
        else if (f->first_ids && t < f->first_id_count)
            t = f->first_ids[t];
        if (r > 2) {
            rc = mts_error_set(err, MTS_ERR_FORMAT, "full strips: strip %u starts at corner %u",
                               s, r);
            break;
        }
        if (t >= g->tri_count || claimed[t]) {
            rc = mts_error_set(err, MTS_ERR_FORMAT,
                               "full strips: strip %u starts on triangle %u, which is none of "
                               "the %u or one a strip holds",
                               s, named, g->tri_count);
            break;
        }
        if (describe) {
            describe[s].near = NONE;
            describe[s].near_count = (uint32_t)near.n;
            for (uint32_t k = 0; k < near.n && describe[s].near == NONE; k++)
                describe[s].near = near.w[k] == t ? k : NONE;
        }
        claimed[t] = 1;
        cur.n = 0;
        /* a strip's derived indices: three, then at most two a triangle */
        if (!mts_words_reserve(&cur, p->triangles) ||
            (derived && !mts_words_reserve(derived, 2 * (size_t)p->triangles + 1))) {
            rc = mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
            break;
        }
        cur.w[cur.n++] = t;
        if (resolve) {
            resolve->slot[s].head = (int32_t)t;
            resolve->tri[t].slot = (int32_t)s;
            resolve->slot[s].ntri = 1;
        }
        /* the strip's last two indices (a, c) and the half-edge between them */
        uint32_t a = g->tri[t].v[NX[r]], c = g->tri[t].v[PV[r]], h = 3 * t + NX[r];
        if (derived) {
            /* as grow.c derives a path: a lone triangle as its corners
             * stand, else from the corner its exit edge is opposite */
            uint32_t *o = derived->w + derived->n;
            const unsigned r0 = p->triangles == 1 ? 0 : r;
            o[0] = g->tri[t].v[r0];
            o[1] = g->tri[t].v[NX[r0]];
            o[2] = g->tri[t].v[PV[r0]];
            derived->n += 3;
        }
        for (uint32_t i = 1; i < p->triangles; i++) {
            uint32_t o = TWIN(g, h);
            if (o == NONE) {
                rc = mts_error_set(err, MTS_ERR_FORMAT,
                                   "full strips: strip %u runs off the mesh at triangle %u", s, i);
                break;
            }
            uint32_t u = o / 3, e = o % 3;
            if (claimed[u]) {
                rc = mts_error_set(err, MTS_ERR_FORMAT,
                                   "full strips: strip %u crosses, at its triangle %u, into one a "
                                   "strip holds",
                                   s, i);
                break;
            }
            claimed[u] = 1;
            cur.w[cur.n++] = u;
            if (resolve) {
                mts__grow_set_next(resolve, t, (int32_t)u);
                resolve->prev[u] = (int32_t)t;
                resolve->tri[u].slot = (int32_t)s;
                resolve->slot[s].ntri++;
            }
            uint32_t w = g->tri[u].v[PV[e]];
            int swap = 0;
            if (i + 1 < p->triangles) {
                const unsigned open = full_open(g, u, e, a, c, claimed);
                if (open == 0) {
                    rc = mts_error_set(err, MTS_ERR_FORMAT,
                                       "full strips: strip %u ends at triangle %u of %u, every "
                                       "way on closed",
                                       s, i, p->triangles);
                    break;
                }
                if (f->swaps && bit >= f->swap_count) {
                    rc = mts_error_set(err, MTS_ERR_FORMAT,
                                       "full strips: more inner triangles than %llu swap bits",
                                       (unsigned long long)f->swap_count);
                    break;
                }
                if (open != 3)
                    swap = open == 2;
                else
                    swap = f->swaps ? (f->swaps[bit] & 1) != 0 : f->swap_bit(f->user, last) != 0;
                if (mark)
                    mark[bit] = (uint8_t)((mark[bit] & 1) | (open != 3) << 1);
                bit++;
                last = (unsigned)swap;
            }
            h = full_exit(g, u, e, swap ? a : c);
            if (derived) {
                /* a swap repeats a, as grow.c's derivation writes it */
                if (swap)
                    derived->w[derived->n++] = a;
                derived->w[derived->n++] = w;
            }
            if (swap) {
                c = w;
            } else {
                a = c;
                c = w;
            }
            t = u;
        }
        mts_words x = prev;
        prev = cur;
        cur = x;
    }
    if (rc == MTS_OK && f->swaps && bit != f->swap_count)
        rc = mts_error_set(err, MTS_ERR_FORMAT, "full strips: %llu swap bits for %llu",
                           (unsigned long long)f->swap_count, (unsigned long long)bit);
    if (rc == MTS_OK && offsets)
        offsets[f->slot_count] = (uint32_t)derived->n;
    free(claimed);
    free(prev.w);
    free(cur.w);
    free(near.w);
    return rc;
}

/* Resolves a description of the full strips (mts_grow_full_describe) on
 * the current (full) mesh straight into paths, slot by slot: each strip
 * leaves a triangle across the edge of its last two indices, and a swap
 * bit says which of them stays. */
/* What every walk of a description checks first: *triangles, its sum. */
static mts_result full_check(const mts_grow *g, const mts_grow_full *f, uint64_t *triangles,
                             mts_error *err)
{
    uint64_t tris = 0;
    for (uint32_t s = 0; s < f->slot_count; s++)
        tris += f->paths[s].triangles;
    *triangles = tris;
    if (tris > g->tri_count)
        return mts_error_set(err, MTS_ERR_FORMAT, "full strips: %llu triangles of %u",
                             (unsigned long long)tris, g->tri_count);
    if (!f->swaps && !f->swap_bit)
        return mts_error_set(err, MTS_ERR_ARG, "full strips: no swap bits");
    return MTS_OK;
}

mts_result mts__grow_resolve_full(mts_grow *g, const mts_grow_full *f, mts_error *err)
{
    uint64_t tris;
    mts_result rc = full_check(g, f, &tris, err);
    if (rc != MTS_OK)
        return rc;
    if (!mts__grow_paths_reset(g, f->slot_count))
        return mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
    rc = full_walk(g, g, f, NULL, NULL, NULL, err);
    if (rc == MTS_OK)
        mts__grow_slots_free_unused(g, f->slot_count);
    return rc;
}

mts_result mts_grow_full_strips(const mts_grow *g, const mts_grow_full *f, mts_strips *out,
                                mts_error *err)
{
    memset(out, 0, sizeof *out);
    if (g->level != g->n)
        return mts_error_set(err, MTS_ERR_ARG,
                             "grow: the full strips walked at level %u of %u", g->level, g->n);
    if (!f->paths)
        return mts_error_set(err, MTS_ERR_ARG, "full strips: no description");
    uint64_t tris;
    mts_result rc = full_check(g, f, &tris, err);
    if (rc != MTS_OK)
        return rc;
    /* the indices: three a strip, then at most two a triangle */
    mts_words idx = {0};
    uint32_t *offsets = malloc(((size_t)f->slot_count + 1) * 4);
    if (!offsets || !mts_words_reserve(&idx, 2 * (size_t)tris + f->slot_count + 1))
        rc = mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
    if (rc == MTS_OK)
        rc = full_walk(g, NULL, f, NULL, &idx, offsets, err);
    if (rc == MTS_OK && idx.n > UINT32_MAX)
        rc = mts_error_set(err, MTS_ERR_LIMIT, "full strips: %zu indices", idx.n);
    if (rc != MTS_OK) {
        free(offsets);
        free(idx.w);
        return rc;
    }
    out->strip_count = f->slot_count;
    out->index_count = (uint32_t)idx.n;
    out->offsets = offsets;
    out->indices = idx.w;
    return MTS_OK;
}

/* ---- describing ---- */

/* Reads a strip in derived form: its triangle count and, per inner
 * triangle, whether it swaps (one byte each, appended at swaps + *count).
 * Returns 0 when the strip is not in that form. */
static int parse_derived(const uint32_t *s, uint32_t len, uint32_t *ntri, uint8_t *swaps,
                         uint64_t *count_swaps)
{
    if (len == 0) {
        *ntri = 0;
        return 1;
    }
    if (len < 3 || s[0] == s[1] || s[1] == s[2] || s[0] == s[2])
        return 0;
    uint32_t a = s[1], c = s[2], k = 3, count = 1;
    while (k < len) {
        int swap = 0;
        if (s[k] == a && k + 1 < len) {
            swap = 1;
            k++;
        }
        uint32_t w = s[k++];
        if (w == a || w == c)
            return 0;
        count++;
        if (k < len) /* an inner triangle */
            swaps[(*count_swaps)++] = (uint8_t)swap;
        else if (swap)
            return 0; /* the last triangle never swaps */
        if (swap) {
            c = w;
        } else {
            a = c;
            c = w;
        }
    }
    *ntri = count;
    return 1;
}

mts_result mts_grow_full_describe(const mts_grow *g, const mts_strips *full,
                                  mts_grow_full_path *paths, uint8_t *swaps, uint64_t *swap_count,
                                  mts_error *err)
{
    *swap_count = 0;
    if (g->level != g->n)
        return mts_error_set(err, MTS_ERR_ARG,
                             "grow: the full strips described at level %u of %u", g->level, g->n);
    for (uint32_t st = 0; st < full->strip_count; st++) {
        const uint32_t *s = full->indices + full->offsets[st];
        uint32_t len = full->offsets[st + 1] - full->offsets[st];
        mts_grow_full_path *p = &paths[st];
        memset(p, 0, sizeof *p);
        if (!parse_derived(s, len, &p->triangles, swaps, swap_count))
            return mts_error_set(err, MTS_ERR_ARG,
                                 "grow: full strip %u is not in the form growth derives", st);
        if (!p->triangles)
            continue;
        int32_t t = mts_grow_find(g, s[0], s[1], s[2]);
        if (t < 0)
            return mts_error_set(err, MTS_ERR_ARG,
                                 "grow: full strip %u starts on (%u %u %u), not a triangle of "
                                 "level %u",
                                 st, s[0], s[1], s[2], g->level);
        p->first = (uint32_t)t;
        while (g->tri[t].v[p->rotation] != s[0])
            p->rotation++;
    }
    /* which bits the walk forces: the walk a client makes */
    const mts_grow_full f = {.paths = paths,
                             .swaps = swaps,
                             .swap_count = *swap_count,
                             .slot_count = full->strip_count};
    return full_walk(g, NULL, &f, paths, NULL, NULL, err);
}
