/* Strip growth from vertex splits (see grow.h for the why, lodbuild.h for
 * the growth rules and the measurements behind key levels).
 *
 * Every client runs this on every split it receives, so a split must cost
 * about what it changes, not what the strips it touches hold:
 *  - the mesh is a corner table in flat arrays (corner.h): a fan split
 *    relabels the fan's corners and links two new triangles in with O(1)
 *    twin updates, and walking round a vertex is a twin step.
 *  - the strips are paths on the dual graph (next/prev per triangle, one
 *    path per slot), and each slot keeps its indices as last derived. A
 *    split only changes a slot's indices in the stretch where the path runs
 *    past the parent u -- from the first triangle with corner u to the
 *    first one after the last -- so that stretch is found in the old indices
 *    (the first and last u), re-derived from the path, and spliced in
 *    (local_region). Whatever does not fit that pattern (a slot given new
 *    content, a key level) is derived whole; both give the same indices,
 *    which mts_grow_check verifies.
 *  - a key level restripifies every live triangle with greedy.c, which
 *    reads the twins directly; the full level's strips are walked from
 *    their description (grow_full.c).
 * The record of a split is, per slot it touched, the smallest edit from the
 * old indices to the new (emit_splice). */
#include "grow.h"

#include <stdlib.h>
#include <string.h>

#include "corner.h"
#include "greedy.h"
#include "grow_internal.h"
#include "strips.h"
#include "words.h"

/* the notation of grow_internal.h, short */
#define NONE MTS_GROW_NONE
#define NX mts__grow_nx
#define PV mts__grow_pv
#define TWIN MTS__GROW_TWIN

_Static_assert(MTS_GROW_NONE == MTS_GREEDY_NONE, "greedy.c reads growth's borders");

/* ---- deriving indices ---- */

/* Appends the indices of a path's triangles from t on (lodbuild.h): with
 * `first`, t starts the strip (its third vertex, then the edge it shares
 * with the next); otherwise (*a, *c) are the strip's last two indices, the
 * edge t is entered by, and t adds its third vertex, after a swap (a
 * repeated a) where the path turns the same way twice. Stops after `stop`
 * when it meets it (*met = 1), else at the path's end. (*a, *c) are the
 * last two indices after. */
static int derive_run(const mts_grow *g, int32_t t, int first, int32_t stop, uint32_t *a,
                      uint32_t *c, mts_words *out, int *met)
{
    *met = 0;
    if (t < 0)
        return 1;
    uint32_t hin = NONE; /* the half-edge t was entered by, once known */
    if (first) {
        if (!mts_words_reserve(out, 3))
            return 0;
        uint32_t *w = out->w + out->n;
        const mts__grow_tri *x = &g->tri[t];
        unsigned e = x->nx >= 0 ? (unsigned)(x->nx & 3) : 3;
        if (e == 3) {
            w[0] = x->v[0];
            w[1] = x->v[1];
            w[2] = x->v[2];
        } else {
            w[0] = x->v[PV[e]];
            w[1] = x->v[e];
            w[2] = x->v[NX[e]];
            hin = x->tw[e];
        }
        out->n += 3;
        *a = w[1];
        *c = w[2];
        if (t == stop) {
            *met = 1;
            return 1;
        }
        t = mts__grow_next_of(g, t);
        if (t < 0)
            return 1;
    }
    /* a triangle adds at most 2; room for the path's slot's triangles at
     * once, more only if that ran out */
    int32_t sl = g->tri[t].slot;
    if (!mts_words_reserve(out, 2 * (size_t)(sl >= 0 ? g->slot[sl].ntri + 1 : 8)))
        return 0;
    uint32_t *o = out->w;
    size_t n = out->n;
    uint32_t ca = *a, cc = *c;
    while (t >= 0) {
        if (n + 2 > out->cap) {
            out->n = n;
            if (!mts_words_reserve(out, 2 * n + 2))
                return 0;
            o = out->w;
        }
        const mts__grow_tri *x = &g->tri[t];
        /* its new index: the corner off the edge it was entered by */
        uint32_t w = hin != NONE && hin / 3 == (uint32_t)t
                         ? x->v[PV[hin % 3]]
                         : mts__corner_third(g, (uint32_t)t, ca, cc);
        int32_t nx = x->nx < 0 ? -1 : x->nx >> 2;
        unsigned e = x->nx < 0 ? 3 : (unsigned)(x->nx & 3);
        int swap = 0;
        hin = NONE;
        if (e < 3) {
            uint32_t p = x->v[e], q = x->v[NX[e]];
            swap = p != cc && q != cc;
            hin = x->tw[e];
        }
        if (swap)
            o[n++] = ca; /* the path turns the same way again: a swap keeps a */
        else
            ca = cc;
        o[n++] = w;
        cc = w;
        if (t == stop) {
            *met = 1;
            break;
        }
        t = nx;
    }
    out->n = n;
    *a = ca;
    *c = cc;
    return 1;
}

static int derive_whole(const mts_grow *g, int32_t head, mts_words *out)
{
    uint32_t a, c;
    int met;
    out->n = 0;
    return derive_run(g, head, 1, -1, &a, &c, out, &met);
}

/* ---- slots and paths ---- */

static void touch(mts_grow *g, int32_t slot)
{
    if (slot < 0)
        return;
    if (g->slot[slot].stamp != g->stamp_now) {
        g->slot[slot].stamp = g->stamp_now;
        g->touched[g->touched_count++] = (uint32_t)slot;
    }
}

/* Grows an array from old to cap elements of size elem, the new ones zero. */
static int grow_zeroed(void **p, size_t elem, uint32_t old, uint32_t cap)
{
    void *q = realloc(*p, (size_t)cap * elem);
    if (!q)
        return 0;
    memset((char *)q + (size_t)old * elem, 0, (size_t)(cap - old) * elem);
    *p = q;
    return 1;
}

/* A slot for new content: touched and fresh (derived whole). */
static int32_t slot_new(mts_grow *g)
{
    int32_t s;
    if (g->free_count) {
        s = (int32_t)g->free_slots[--g->free_count];
    } else {
        if (g->slot_count == g->slot_cap) {
            uint32_t old = g->slot_cap, cap = old ? old * 2 : 64;
            /* each array keeps its old block if its own growth fails */
            if (!grow_zeroed((void **)&g->slot, sizeof *g->slot, old, cap) ||
                !grow_zeroed((void **)&g->capacity, 4, old, cap) ||
                !grow_zeroed((void **)&g->free_slots, 4, old, cap) ||
                !grow_zeroed((void **)&g->touched, 4, old, cap))
                return -1;
            g->slot_cap = cap;
        }
        s = (int32_t)g->slot_count++;
    }
    g->slot[s].head = -1;
    g->slot[s].ntri = 0;
    g->slot[s].fresh = g->stamp_now;
    touch(g, s);
    return s;
}

static void slot_release(mts_grow *g, int32_t s)
{
    g->slot[s].head = -1;
    g->slot[s].ntri = 0;
    g->slot[s].fresh = g->stamp_now;
    touch(g, s);
    g->free_slots[g->free_count++] = (uint32_t)s;
}

/* Gives the path starting at t (and everything after it) the slot s. */
static uint32_t path_claim(mts_grow *g, int32_t t, int32_t s)
{
    uint32_t count = 0;
    for (; t >= 0; t = mts__grow_next_of(g, t)) {
        g->tri[t].slot = s;
        count++;
    }
    return count;
}

/* Longest path growth may make by appending or joining; insertion into the
 * middle is never refused (the alternative is cutting the strip). */
#define GROW_MAX_PATH (2 * MTS_STRIPIFY_MAX_STRIP)

/* Mends one link a -> c that the split broke: a new triangle adjacent to
 * both goes between them (the strip crossed the edge it was born on), else
 * the path is cut and its tail gets a slot of its own. */
static int mend_link(mts_grow *g, int32_t a, int32_t c, uint32_t first_new)
{
    for (uint32_t f = first_new; f < g->tri_count; f++) {
        if (g->tri[f].slot >= 0 || !mts__grow_adjacent(g, a, (int32_t)f) ||
            !mts__grow_adjacent(g, (int32_t)f, c))
            continue;
        int32_t s = g->tri[a].slot;
        mts__grow_set_next(g, a, (int32_t)f);
        g->prev[f] = a;
        mts__grow_set_next(g, f, c);
        g->prev[c] = (int32_t)f;
        g->tri[f].slot = s;
        g->slot[s].ntri++;
        g->slot[s].relinked = g->stamp_now;
        g->fig.grown_inserted++;
        return 1;
    }
    int32_t s = g->tri[a].slot;
    int32_t ns = slot_new(g);
    if (ns < 0)
        return 0;
    mts__grow_set_next(g, a, -1);
    g->prev[c] = -1;
    g->slot[ns].head = c;
    g->slot[ns].ntri = path_claim(g, c, ns);
    g->slot[s].ntri -= g->slot[ns].ntri;
    g->slot[s].relinked = g->stamp_now;
    g->fig.strips_cut++;
    return 1;
}

/* Places a new triangle no strip crossed into: after a strip that ends next
 * to it, before one that starts next to it, both (joining them), or alone. */
static int place_newborn(mts_grow *g, int32_t f)
{
    int32_t nbr[3];
    for (int c = 0; c < 3; c++) {
        uint32_t h = TWIN(g, 3 * (size_t)f + c);
        int32_t x = h == NONE ? -1 : (int32_t)(h / 3);
        nbr[c] = x >= 0 && x != f && g->tri[x].slot >= 0 ? x : -1;
    }
    int32_t tail = -1, head = -1;
    for (int c = 0; c < 3 && tail < 0; c++) {
        int32_t h = nbr[c];
        if (h >= 0 && mts__grow_next_of(g, h) < 0 && g->slot[g->tri[h].slot].ntri < GROW_MAX_PATH)
            tail = h;
    }
    for (int c = 0; c < 3 && head < 0; c++) {
        int32_t h = nbr[c];
        if (h < 0 || h == tail || g->slot[g->tri[h].slot].head != h ||
            g->slot[g->tri[h].slot].ntri >= GROW_MAX_PATH)
            continue;
        if (tail >= 0 && (g->tri[h].slot == g->tri[tail].slot ||
                          g->slot[g->tri[h].slot].ntri + g->slot[g->tri[tail].slot].ntri >= GROW_MAX_PATH))
            continue; /* would close a loop, or make too long a strip */
        head = h;
    }
    if (tail >= 0 && head >= 0) {
        int32_t s = g->tri[tail].slot, gone = g->tri[head].slot;
        mts__grow_set_next(g, tail, f);
        g->prev[f] = tail;
        mts__grow_set_next(g, f, head);
        g->prev[head] = f;
        g->tri[f].slot = s;
        g->slot[s].ntri += 1 + path_claim(g, head, s);
        slot_release(g, gone);
        g->fig.grown_joined++;
    } else if (tail >= 0) {
        int32_t s = g->tri[tail].slot;
        mts__grow_set_next(g, tail, f);
        g->prev[f] = tail;
        g->tri[f].slot = s;
        g->slot[s].ntri++;
        g->fig.grown_appended++;
    } else if (head >= 0) {
        int32_t s = g->tri[head].slot;
        mts__grow_set_next(g, f, head);
        g->prev[head] = f;
        g->tri[f].slot = s;
        g->slot[s].head = f;
        g->slot[s].ntri++;
        g->fig.grown_appended++;
    } else {
        int32_t s = slot_new(g);
        if (s < 0)
            return 0;
        g->slot[s].head = f;
        g->slot[s].ntri = 1;
        g->tri[f].slot = s;
        g->fig.grown_alone++;
    }
    touch(g, g->tri[f].slot);
    g->slot[g->tri[f].slot].relinked = g->stamp_now;
    return 1;
}

/* Empties every path and slot: all of them touched and fresh, room for at
 * least `slots`. */
int mts__grow_paths_reset(mts_grow *g, uint32_t slots)
{
    while (g->slot_count < slots) {
        if (slot_new(g) < 0)
            return 0;
    }
    for (uint32_t s = 0; s < g->slot_count; s++) {
        g->slot[s].head = -1;
        g->slot[s].ntri = 0;
        g->slot[s].fresh = g->stamp_now;
        touch(g, (int32_t)s);
    }
    for (uint32_t t = 0; t < g->tri_count; t++) {
        g->tri[t].nx = g->prev[t] = -1;
        g->tri[t].slot = -1;
    }
    g->free_count = 0;
    return 1;
}

/* Frees the slots from `used` on and the empty ones below it. */
void mts__grow_slots_free_unused(mts_grow *g, uint32_t used)
{
    g->free_count = 0;
    for (uint32_t s = g->slot_count; s-- > 0;) {
        if (s >= used || g->slot[s].head < 0)
            g->free_slots[g->free_count++] = s;
    }
}

/* Turns strips over live triangles into paths. Lenient (the builder's full
 * level): paths go into slots 0.. in order, a strip whose windows do not
 * chain is split over several slots, and every other slot is left empty
 * and free. Strict (a base): slot s gets strip s, which must be one path. */
static mts_result adopt_strips(mts_grow *g, const mts_strips *strips, int strict, mts_error *err)
{
    mts__corner_key *ix = NULL;
    if (!mts__grow_paths_reset(g, strips->strip_count))
        return mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
    mts_result rc = MTS_OK;
    uint32_t used = 0;
    for (uint32_t k = 0; k < strips->strip_count; k++) {
        const uint32_t *str = strips->indices + strips->offsets[k];
        uint32_t len = strips->offsets[k + 1] - strips->offsets[k];
        int32_t prev = -1, s = strict ? (int32_t)k : -1;
        for (uint32_t w = 0; w + 2 < len; w++) {
            uint32_t tri[3];
            if (!mts_strip_window(str, w, tri))
                continue;
            int32_t t = mts__corner_window_triangle(g, prev, tri, &ix);
            if (t == -2) {
                rc = mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
                goto done;
            }
            if (t < 0) {
                rc = mts_error_set(err, MTS_ERR_FORMAT,
                                   "grow: strip %u draws (%u %u %u), not a triangle of level %u",
                                   k, tri[0], tri[1], tri[2], g->level);
                goto done;
            }
            if (g->tri[t].slot >= 0) {
                rc = mts_error_set(err, MTS_ERR_FORMAT,
                                   "grow: strip %u draws triangle (%u %u %u) a second time", k,
                                   tri[0], tri[1], tri[2]);
                goto done;
            }
            if (prev >= 0 && mts__grow_adjacent(g, prev, t)) {
                mts__grow_set_next(g, prev, t);
                g->prev[t] = prev;
            } else if (prev >= 0 && strict) {
                rc = mts_error_set(err, MTS_ERR_FORMAT,
                                   "grow: strip %u breaks at window %u (not one path)", k, w);
                goto done;
            } else {
                if (!strict) {
                    if (used == g->slot_count && slot_new(g) < 0) {
                        rc = mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
                        goto done;
                    }
                    s = (int32_t)used++;
                }
                g->slot[s].head = t;
                touch(g, s);
            }
            g->tri[t].slot = s;
            g->slot[s].ntri++;
            prev = t;
        }
    }
    mts__grow_slots_free_unused(g, strict ? strips->strip_count : used);
done:
    free(ix);
    return rc;
}

/* Sorts ids by key[id], largest first, ties by position: stable, so
 * deterministic. A counting sort while the keys are small (they are strip
 * lengths, every key level sorts every slot twice), else a merge sort. */
static int sort_desc(uint32_t *ids, uint32_t n, const uint32_t *key)
{
    uint32_t top = 0;
    for (uint32_t i = 0; i < n; i++)
        top = key[ids[i]] > top ? key[ids[i]] : top;
    uint32_t *tmp = malloc(((size_t)n + 1) * 4);
    if (!tmp)
        return 0;
    if (top < 4 * (n + 1024)) {
        uint32_t *at = calloc((size_t)top + 2, 4);
        if (!at) {
            free(tmp);
            return 0;
        }
        for (uint32_t i = 0; i < n; i++)
            at[top - key[ids[i]] + 1]++;
        for (uint32_t k = 1; k <= top + 1; k++)
            at[k] += at[k - 1];
        for (uint32_t i = 0; i < n; i++)
            tmp[at[top - key[ids[i]]]++] = ids[i];
        free(at);
        memcpy(ids, tmp, (size_t)n * 4);
        free(tmp);
        return 1;
    }
    for (uint32_t width = 1; width < n; width *= 2) {
        for (uint32_t lo = 0; lo < n; lo += 2 * width) {
            uint32_t mid = lo + width < n ? lo + width : n;
            uint32_t hi = lo + 2 * width < n ? lo + 2 * width : n;
            uint32_t i = lo, j = mid, o = lo;
            while (i < mid && j < hi)
                tmp[o++] = key[ids[i]] >= key[ids[j]] ? ids[i++] : ids[j++];
            while (i < mid)
                tmp[o++] = ids[i++];
            while (j < hi)
                tmp[o++] = ids[j++];
        }
        memcpy(ids, tmp, (size_t)n * 4);
    }
    free(tmp);
    return 1;
}

/* A runtime reserves each slot's longest length over all levels, so the
 * strips of a key level go into the slots by length, longest into the
 * roomiest: otherwise every slot soon holds a long strip at some key and
 * the room reserved grows to several times what any one level draws. */
static int fit_slots(mts_grow *g)
{
    uint32_t n = g->slot_count;
    uint32_t *paths = malloc(((size_t)n + 1) * 4), *slots = malloc(((size_t)n + 1) * 4);
    int32_t *head = malloc(((size_t)n + 1) * sizeof *head);
    uint32_t *ntri = malloc(((size_t)n + 1) * 4);
    int ok = paths && slots && head && ntri;
    if (ok) {
        for (uint32_t s = 0; s < n; s++) {
            paths[s] = s;
            slots[s] = s;
            head[s] = g->slot[s].head;
            ntri[s] = g->slot[s].ntri;
        }
        ok = sort_desc(paths, n, ntri) && sort_desc(slots, n, g->capacity);
    }
    if (ok) {
        for (uint32_t k = 0; k < n; k++) {
            uint32_t s = slots[k];
            g->slot[s].head = head[paths[k]];
            g->slot[s].ntri = ntri[paths[k]];
            path_claim(g, g->slot[s].head, (int32_t)s);
        }
        mts__grow_slots_free_unused(g, n);
    }
    free(paths);
    free(slots);
    free(head);
    free(ntri);
    return ok;
}

/* Restripifies every live triangle (greedy.c, in id order) into the slots,
 * renumbering the triangles in the order the paths were made: strips lie
 * side by side there, so the triangles round a vertex, which every later
 * split walks, come to sit in a few cache lines, not one each. */
static mts_result restrip(mts_grow *g, mts_error *err)
{
    uint32_t n = g->tri_count, count = 0;
    const int given = g->given_order && g->given_level == g->level;
    uint32_t *order = given ? NULL : malloc(((size_t)n + 1) * 4);
    uint32_t *starts = given ? NULL : malloc(((size_t)n + 2) * 4);
    mts_result rc = given || (order && starts)
                        ? MTS_OK
                        : mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
    const uint32_t *po = order, *ps = starts;
    if (rc == MTS_OK && given) {
        /* another grow's greedy.c, on the same mesh (grow_tokens.h) */
        po = g->given_order;
        ps = g->given_starts;
        count = g->given_count;
        if (g->given_triangles != n || count > n || ps[0] != 0 || ps[count] != n)
            rc = mts_error_set(err, MTS_ERR_INTERNAL,
                               "grow: key paths of %u triangles in %u given for %u at level %u",
                               g->given_triangles, count, n, g->level);
        for (uint32_t k = 0; rc == MTS_OK && k < count; k++) {
            if (ps[k + 1] <= ps[k])
                rc = mts_error_set(err, MTS_ERR_INTERNAL, "grow: given key path %u is empty", k);
        }
    } else if (rc == MTS_OK) {
        rc = mts_greedy_paths(n, g->tri[0].tw, sizeof *g->tri / 4, MTS_STRIPIFY_MAX_STRIP, order,
                              starts, &count, err);
    }
    g->given_order = NULL;
    if (rc == MTS_OK) {
        uint32_t *perm = malloc(((size_t)n + 1) * 4);
        if (perm && given) {
            /* a permutation, or nothing is renumbered */
            memset(perm, 0xff, (size_t)n * 4);
            for (uint32_t i = 0; i < n && rc == MTS_OK; i++) {
                if (po[i] >= n || perm[po[i]] != UINT32_MAX)
                    rc = mts_error_set(err, MTS_ERR_INTERNAL,
                                       "grow: given key paths hold triangle %u twice or none "
                                       "such",
                                       po[i]);
                else
                    perm[po[i]] = i;
            }
        } else if (perm) {
            for (uint32_t i = 0; i < n; i++)
                perm[po[i]] = i;
        }
        /* known now; renumbering and the key's record take as long again */
        if (rc == MTS_OK && perm && g->on_key_order)
            g->on_key_order(g->on_key_user, perm, n);
        if (rc == MTS_OK &&
            (!perm || !mts__corner_renumber(g, perm) || !mts__grow_paths_reset(g, count)))
            rc = mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
        if (rc == MTS_OK && g->keep_order) {
            g->key_order.n = 0;
            if (!mts_words_reserve(&g->key_order, n))
                rc = mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
            else
                memcpy(g->key_order.w, perm, (size_t)n * 4);
            g->key_order.n = rc == MTS_OK ? n : 0;
        }
        free(perm);
    }
    for (uint32_t k = 0; rc == MTS_OK && k < count; k++) {
        for (uint32_t i = ps[k]; i < ps[k + 1]; i++) {
            g->tri[i].slot = (int32_t)k;
            g->prev[i] = i > ps[k] ? (int32_t)i - 1 : -1;
            mts__grow_set_next(g, i, i + 1 < ps[k + 1] ? (int32_t)i + 1 : -1);
        }
        g->slot[k].head = (int32_t)ps[k];
        g->slot[k].ntri = ps[k + 1] - ps[k];
    }
    if (rc == MTS_OK) {
        mts__grow_slots_free_unused(g, count);
        if (!fit_slots(g))
            rc = mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
    }
    free(order);
    free(starts);
    return rc;
}

/* ---- records ---- */

/* A slot's new indices: old[0..p0) + r + old[p1..) when `suffix`, else
 * old[0..p0) + r. */
typedef struct splice {
    uint32_t p0, p1;
    int suffix;
    const mts_words *r;
} splice;

/* Appends the edit that turns slot s's stored indices into the spliced ones
 * (in which the new vertex v appears; u is its parent), and stores them.
 * The runs carry u where the new indices have v, and the positions of v are
 * substitutions, so an inserted run never names a vertex that does not
 * exist yet. Outside the splice nothing changed and v cannot appear, so the
 * common prefix and suffix are sought from its edges. The new indices are
 * three pieces -- old[0..p0), r, old[p1..) -- each compared and copied as a
 * piece: a split emits a few edits, a key level one per slot, and this is
 * where a key level's indices all pass. */
static int emit_splice(mts_grow *g, uint32_t s, const splice *sp, uint32_t u, uint32_t v,
                       uint32_t *edits)
{
    mts_words *from = &g->slot[s].seq;
    const uint32_t *o = from->w, *r = sp->r->w;
    const size_t lo = from->n, rn = sp->r->n, keep = sp->suffix ? lo - sp->p1 : 0,
                 p0 = sp->p0, end = p0 + rn, ln = end + keep;
    /* new[end + i] = tail[i]; a slot never filled has no array at all */
    const uint32_t *tail = o ? o + (sp->suffix ? sp->p1 : lo) : o;
#define AS_BEFORE(x) ((x) == v ? u : (x))
    /* common prefix: new[0..p0) is old's own */
    size_t p = p0;
    while (p < end && p < lo && o[p] == AS_BEFORE(r[p - p0]))
        p++;
    if (p == end) {
        if (keep && end == sp->p1)
            p = lo; /* only substitutions: the kept tail is the same too */
        else
            while (p < lo && p < ln && o[p] == tail[p - end])
                p++;
    }
    /* common suffix, within what the prefix left: the kept tail is old's own */
    const size_t room = (lo < ln ? lo : ln) - p;
    size_t q = keep < room ? keep : room;
    while (q < room && ln - 1 - q >= end && o[lo - 1 - q] == tail[ln - 1 - q - end])
        q++;
    /* then r (the prefix reaches p0 at least, so the suffix stays in r) */
    while (q < room && o[lo - 1 - q] == AS_BEFORE(r[ln - 1 - q - p0]))
        q++;
    const size_t erase = lo - p - q, insert = ln - p - q;
    /* the record at most holds every position of r as a substitution */
    if (!mts_words_reserve(&g->rec, 4 + 2 + erase + 2 + insert + rn))
        return 0;
    uint32_t *w0 = g->rec.w + g->rec.n, *w = w0 + 4;
    if (erase) {
        *w++ = (uint32_t)p;
        *w++ = (uint32_t)erase;
        memcpy(w, o + p, erase * 4);
        w += erase;
    }
    if (insert) {
        *w++ = (uint32_t)p;
        *w++ = (uint32_t)insert;
        /* new[p..ln-q): its part in r mapped back to u, then the kept tail */
        size_t k = p, stop = ln - q;
        for (; k < stop && k < end; k++)
            *w++ = AS_BEFORE(r[k - p0]);
        if (k < stop) {
            memcpy(w, tail + (k - end), (stop - k) * 4);
            w += stop - k;
        }
    }
    uint32_t *subst = w;
    for (size_t k = 0; k < rn; k++) {
        *w = (uint32_t)(p0 + k);
        w += r[k] == v;
    }
#undef AS_BEFORE
    const size_t substs = (size_t)(w - subst);
    if (erase == 0 && insert == 0 && substs == 0)
        return 1;
    w0[0] = s;
    w0[1] = erase > 0;
    w0[2] = insert > 0;
    w0[3] = (uint32_t)substs;
    g->rec.n = (size_t)(w - g->rec.w);
    (*edits)++;
    g->fig.edits++;
    g->fig.erased_indices += erase;
    g->fig.inserted_indices += insert;
    g->fig.substitutions += substs;
    g->total_indices = g->total_indices - lo + ln;
    g->nonempty = g->nonempty - (lo > 0) + (ln > 0);
    /* the splice in place: the kept tail moves, the new run goes in */
    if (ln > lo && !mts_words_reserve(from, ln - lo))
        return 0;
    uint32_t *x = from->w;
    if (keep)
        memmove(x + end, x + sp->p1, keep * 4);
    if (rn)
        memcpy(x + p0, r, rn * 4);
    from->n = ln;
    if (ln > g->slot[s].capacity)
        g->slot[s].capacity = g->capacity[s] = (uint32_t)ln;
    return 1;
}

/* The first and last position of x in a[0..n) (n when there is none). A
 * slot is mostly far longer than the stretch a split changes, so this scan
 * is most of what a split costs; in blocks of 16 the compiler makes it 4 or
 * 8 compares an instruction. */
enum { SCAN_BLOCK = 16 };

static uint32_t find_first(const uint32_t *a, uint32_t n, uint32_t x)
{
    uint32_t k = 0;
    for (; k + SCAN_BLOCK <= n; k += SCAN_BLOCK) {
        const uint32_t *b = a + k;
        unsigned any = 0;
        for (unsigned i = 0; i < SCAN_BLOCK; i++)
            any |= b[i] == x;
        if (any)
            break;
    }
    while (k < n && a[k] != x)
        k++;
    return k;
}

static uint32_t find_last(const uint32_t *a, uint32_t n, uint32_t x)
{
    uint32_t k = n;
    for (; k >= SCAN_BLOCK; k -= SCAN_BLOCK) {
        const uint32_t *b = a + k - SCAN_BLOCK;
        unsigned any = 0;
        for (unsigned i = 0; i < SCAN_BLOCK; i++)
            any |= b[i] == x;
        if (any)
            break;
    }
    while (k > 0 && a[k - 1] != x)
        k--;
    return k ? k - 1 : n;
}

/* The parent's triangle (before the split: g->cand) that window k of the
 * old indices o draws, u being one of its corners; its old next in *next.
 * -1 when none is (the slot is then derived whole). */
static int32_t cand_at(const mts_grow *g, const uint32_t *o, uint32_t k, uint32_t u,
                       int32_t *next)
{
    uint32_t tri[3];
    if (!mts_strip_window(o, k, tri))
        return -1;
    int j = mts__corner_of(tri, u);
    if (j < 0)
        return -1;
    uint32_t after = tri[NX[j]], before = tri[PV[j]];
    for (size_t i = 0; i < g->cand.n; i += 2) {
        uint32_t c = g->cand.w[i], t = c / 3;
        if (g->tri[t].v[NX[c % 3]] == after && g->tri[t].v[PV[c % 3]] == before) {
            *next = (int32_t)g->cand.w[i + 1];
            return (int32_t)t;
        }
    }
    return -1;
}

/* Where one pass of a strip past u ends and the next begins: a u 6 or more
 * indices after the last leaves three windows without u between them, and
 * a pass replaces at most 5 indices past its last u and 1 before its
 * first, so two passes never overlap. */
enum { PASS_GAP = 6 };

/* The new indices of slot s where its path runs past u: from the first
 * triangle with corner u (t_first) to the one after the last (t_n), the
 * only stretch a split changes. Before t_first the path is as it was (t_first
 * is entered by an edge without u, which nothing touches); t_n's own index
 * may change (its entering edge is read the other way round when the
 * stretch before it changed), but the strip leaves it as before. The
 * stretch is found in the old indices: t_first's window ends at the first
 * u (lo), t_last's starts at the last (hi).
 *
 * A strip often passes u twice, along two rows of the fan, with a row's
 * triangles between; none of those has corner u, and a split only changes
 * links between triangles that had it, so their indices stay and only each
 * pass is derived (half the triangles walked on real meshes). A pass ends
 * where the next u is PASS_GAP or more indices on. 1 done, 0 not such a
 * slot (it is then derived whole), -1 no memory. */
static int local_region(mts_grow *g, uint32_t s, uint32_t u, uint32_t lo, uint32_t hi,
                        splice *sp)
{
    const uint32_t *o = g->slot[s].seq.w;
    const uint32_t L = (uint32_t)g->slot[s].seq.n;
    mts_words *r = &g->scratch;
    r->n = 0;
    sp->r = r;
    uint32_t end = 0; /* where the pass before left the old indices; 0 before the first */
    for (uint32_t at = lo;;) {
        uint32_t last = at, next = hi + 1;
        for (uint32_t k = at + 1; k <= hi; k++) {
            if (o[k] != u)
                continue;
            if (k - last >= PASS_GAP) {
                next = k;
                break;
            }
            last = k;
        }
        int32_t t, unused;
        uint32_t a = 0, c = 0, p0 = 0;
        int first = at < 3;
        if (first) {
            t = g->slot[s].head;
        } else {
            p0 = at - (o[at - 1] == o[at - 3]); /* t_first's swap, if it has one */
            a = o[p0 - 2];
            c = o[p0 - 1];
            t = cand_at(g, o, at - 2, u, &unused);
            if (t < 0 || g->tri[t].slot != (int32_t)s)
                return 0;
        }
        if (end == 0) {
            sp->p0 = p0;
        } else {
            /* the stretch between two passes, as it was */
            if (p0 < end)
                return 0;
            if (!mts_words_reserve(r, p0 - end))
                return -1;
            memcpy(r->w + r->n, o + end, (size_t)(p0 - end) * 4);
            r->n += p0 - end;
        }
        int32_t tn = -1;
        uint32_t p1 = L;
        if (last + 3 < L) {
            if (cand_at(g, o, last, u, &tn) < 0 || tn < 0)
                return 0;
            p1 = last + 4 + (last + 4 < L && o[last + 3] == o[last + 1]);
        }
        int met;
        if (!derive_run(g, t, first, tn, &a, &c, r, &met))
            return -1;
        if (!met) { /* the path ends before t_n: derived to its end */
            sp->suffix = 0;
            sp->p1 = L;
            return 1;
        }
        /* the strip leaves t_n as it did, or the stretch is not what it seems */
        if (a != o[p1 - 2] || c != o[p1 - 1])
            return 0;
        if (next > hi) {
            sp->suffix = 1;
            sp->p1 = p1;
            return 1;
        }
        end = p1;
        at = next;
    }
}

/* A slot whose path kept every link, where every triangle with corner u
 * moved: its indices are the old ones with v for u (u first at lo, last at
 * hi), and the record only substitutes (no derivation). 1 done, 0 not such
 * a slot, -1 no memory. */
static int substitute_only(mts_grow *g, uint32_t s, uint32_t u, uint32_t v, uint32_t lo,
                           uint32_t hi, uint32_t *edits)
{
    uint32_t *o = g->slot[s].seq.w;
    const uint32_t L = (uint32_t)g->slot[s].seq.n;
    uint32_t count = 0;
    mts_words *pos = &g->scratch;
    pos->n = 0;
    for (uint32_t k = lo; k <= hi; k++) {
        if (o[k] != u)
            continue;
        /* a triangle drawn over k (one has moved only if all of them have:
         * else a link across a u edge broke) */
        uint32_t w = k >= 2 ? k - 2 : 0, tri[3];
        while (w <= k && (w + 2 >= L || !mts_strip_window(o, w, tri)))
            w++;
        int32_t unused, t = w <= k ? cand_at(g, o, w, u, &unused) : -1;
        if (t < 0 || mts__corner_of(g->tri[t].v, v) < 0)
            return 0;
        if (!mts_words_reserve(pos, 1))
            return -1;
        pos->w[pos->n++] = k;
        count++;
    }
    if (!mts_words_reserve(&g->rec, 4 + count))
        return -1;
    uint32_t *r = g->rec.w + g->rec.n;
    *r++ = s;
    *r++ = 0;
    *r++ = 0;
    *r++ = count;
    for (uint32_t i = 0; i < count; i++) {
        *r++ = pos->w[i];
        o[pos->w[i]] = v;
    }
    g->rec.n = (size_t)(r - g->rec.w);
    (*edits)++;
    g->fig.edits++;
    g->fig.substitutions += count;
    return 1;
}

/* The record of the split to level g->level (u the parent, v the new
 * vertex): one edit per touched slot, in slot order. */
static int emit_record(mts_grow *g, uint32_t u, uint32_t v)
{
    g->rec.n = 0;
    if (!mts_words_reserve(&g->rec, 1))
        return 0;
    g->rec.n = 1;
    uint32_t edits = 0;
    /* slot order: a split touches two or three (insertion sort), a key
     * level every slot */
    if (g->touched_count == g->slot_count) { /* every slot: a key level */
        for (uint32_t k = 0; k < g->slot_count; k++)
            g->touched[k] = k;
    } else if (g->touched_count > 64) {
        qsort(g->touched, g->touched_count, 4, mts_words_cmp);
    } else {
        for (uint32_t i = 1; i < g->touched_count; i++) {
            uint32_t x = g->touched[i], j = i;
            for (; j > 0 && g->touched[j - 1] > x; j--)
                g->touched[j] = g->touched[j - 1];
            g->touched[j] = x;
        }
    }
    for (uint32_t k = 0; k < g->touched_count; k++) {
        uint32_t s = g->touched[k];
        splice sp = {0, (uint32_t)g->slot[s].seq.n, 0, &g->scratch};
        int local = 0;
        if (g->slot[s].fresh != g->stamp_now && g->slot[s].head >= 0 && g->slot[s].seq.n) {
            /* where u is in the old indices: the stretch both ways read */
            const uint32_t *o = g->slot[s].seq.w, L = (uint32_t)g->slot[s].seq.n;
            uint32_t lo = find_first(o, L, u), hi = lo < L ? find_last(o, L, u) : L;
            if (lo < L && g->slot[s].relinked != g->stamp_now) {
                int done = substitute_only(g, s, u, v, lo, hi, &edits);
                if (done < 0)
                    return 0;
                if (done)
                    continue;
            }
            local = lo < L ? local_region(g, s, u, lo, hi, &sp) : 0;
            if (local < 0)
                return 0;
        }
        if (!local) {
            sp.p0 = 0;
            sp.p1 = (uint32_t)g->slot[s].seq.n;
            sp.suffix = 0;
            if (!derive_whole(g, g->slot[s].head, &g->scratch))
                return 0;
        }
        if (!emit_splice(g, s, &sp, u, v, &edits))
            return 0;
    }
    g->rec.w[0] = edits;
    g->touched_count = 0;
    g->stamp_now++;
    return 1;
}

int mts__grow_splice_whole(mts_grow *g, uint32_t s, const mts_words *r, uint32_t u, uint32_t v,
                           uint32_t *edits)
{
    const splice sp = {0, (uint32_t)g->slot[s].seq.n, 0, r};
    return emit_splice(g, s, &sp, u, v, edits);
}

int mts__grow_slots_reserve(mts_grow *g, uint32_t count)
{
    if (count > g->slot_cap) {
        uint32_t old = g->slot_cap, cap = old ? old : 64;
        while (cap < count)
            cap *= 2;
        /* each array keeps its old block if its own growth fails */
        if (!grow_zeroed((void **)&g->slot, sizeof *g->slot, old, cap) ||
            !grow_zeroed((void **)&g->capacity, 4, old, cap) ||
            !grow_zeroed((void **)&g->free_slots, 4, old, cap) ||
            !grow_zeroed((void **)&g->touched, 4, old, cap))
            return 0;
        g->slot_cap = cap;
    }
    for (; g->slot_count < count; g->slot_count++) {
        g->slot[g->slot_count].head = -1;
        g->slot[g->slot_count].ntri = 0;
    }
    return 1;
}

/* Derives every touched slot's indices into seq without a record (the base). */
static int settle(mts_grow *g)
{
    for (uint32_t k = 0; k < g->touched_count; k++) {
        uint32_t s = g->touched[k];
        g->total_indices -= g->slot[s].seq.n;
        g->nonempty -= g->slot[s].seq.n > 0;
        if (!derive_whole(g, g->slot[s].head, &g->slot[s].seq))
            return 0;
        if (g->slot[s].seq.n > g->slot[s].capacity)
            g->slot[s].capacity = g->capacity[s] = (uint32_t)g->slot[s].seq.n;
        g->total_indices += g->slot[s].seq.n;
        g->nonempty += g->slot[s].seq.n > 0;
    }
    g->touched_count = 0;
    g->stamp_now++;
    return 1;
}

void mts_grow_use_memory(mts_grow *g, mts_bigmem_cache *memory)
{
    g->tri_mem.cache = g->prev_mem.cache = g->spare_mem.cache = memory;
}

void mts_grow_free(mts_grow *g)
{
    if (!g)
        return;
    mts_bigmem_free(&g->tri_mem);
    mts_bigmem_free(&g->prev_mem);
    mts_bigmem_free(&g->spare_mem);
    free(g->vhead);
    if (g->slot) {
        for (uint32_t s = 0; s < g->slot_cap; s++)
            free(g->slot[s].seq.w);
    }
    free(g->slot);
    free(g->capacity);
    free(g->free_slots);
    free(g->touched);
    free(g->keys.w);
    free(g->rec.w);
    free(g->scratch.w);
    free(g->affected.w);
    free(g->born.w);
    free(g->cand.w);
    free(g->ring.w);
    free(g->around.w);
    free(g->key_order.w);
    free(g);
}

mts_result mts_grow_create(const mts_strips *base, uint32_t nb, uint32_t n,
                           const mts_grow_options *opts, mts_grow **out, mts_error *err)
{
    *out = NULL;
    if (n > UINT32_MAX - 1 - nb)
        return mts_error_set(err, MTS_ERR_LIMIT, "grow: %u + %u vertices is too many", nb, n);
    mts_grow *g = calloc(1, sizeof *g);
    if (!g)
        return mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
    g->nb = nb;
    g->n = n;
    g->stamp_now = 1;
    if (opts)
        mts_grow_use_memory(g, opts->memory);
    mts_result rc;
    if (opts && opts->key_levels) {
        for (uint32_t k = 0; k < opts->key_count; k++) {
            if (opts->key_levels[k] == 0 || opts->key_levels[k] >= n ||
                (k && opts->key_levels[k] <= opts->key_levels[k - 1])) {
                rc = mts_error_set(err, MTS_ERR_FORMAT,
                                   "grow: key level %u (%u of %u) is out of order or range",
                                   opts->key_levels[k], k, opts->key_count);
                goto fail;
            }
        }
        g->key_given = opts->key_levels;
        g->key_given_count = opts->key_count;
    } else {
        g->key_ratio = opts && opts->key_ratio > 1 ? opts->key_ratio : -1;
        g->key_quality = opts && opts->key_quality > 0 ? opts->key_quality : -1;
        g->key_min_ratio = opts && opts->key_min_ratio > 1 ? opts->key_min_ratio : 1;
    }
    for (uint32_t i = 0; i < base->index_count; i++) {
        if (base->indices[i] >= nb) {
            rc = mts_error_set(err, MTS_ERR_FORMAT, "grow: base index %u is not a base vertex",
                               base->indices[i]);
            goto fail;
        }
    }
    if (!mts__corner_vhead_reserve(g, nb) || !mts__corner_tri_reserve(g, base->index_count + 1))
        goto nomem;
    for (uint32_t k = 0; k < base->strip_count; k++) {
        const uint32_t *str = base->indices + base->offsets[k];
        uint32_t len = base->offsets[k + 1] - base->offsets[k];
        for (uint32_t w = 0; w + 2 < len; w++) {
            uint32_t tri[3];
            if (mts_strip_window(str, w, tri) &&
                mts__corner_tri_add(g, tri[0], tri[1], tri[2], 1) < 0)
                goto nomem;
        }
    }
    if ((rc = mts__corner_twins_build(g, err)) != MTS_OK)
        goto fail;
    int strict = !(opts && opts->normalise_base);
    if ((rc = adopt_strips(g, base, strict, err)) != MTS_OK)
        goto fail;
    if (!strict && !fit_slots(g))
        goto nomem;
    if (!settle(g))
        goto nomem;
    for (uint32_t s = 0; strict && s < base->strip_count; s++) {
        uint32_t len = base->offsets[s + 1] - base->offsets[s];
        if (len != g->slot[s].seq.n ||
            (len && memcmp(g->slot[s].seq.w, base->indices + base->offsets[s], (size_t)len * 4) != 0)) {
            rc = mts_error_set(err, MTS_ERR_FORMAT,
                               "grow: base strip %u is not in the form growth derives", s);
            goto fail;
        }
    }
    g->fig.key_count = 1;
    g->key_triangles = g->tri_count;
    *out = g;
    return MTS_OK;
nomem:
    rc = mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
fail:
    mts_grow_free(g);
    return rc;
}

/* The full level's strips walked already (mts_grow_full.derived): slot s
 * takes strip s whole, as emit_record would after the walk (every slot
 * fresh, in slot order), and the record is made here. Their paths are not
 * set: nothing grows past the full level, so the grow keeps its mesh and
 * its slots' indices only. */
static mts_result take_derived(mts_grow *g, const mts_strips *d, uint32_t u, uint32_t v,
                               mts_error *err)
{
    const uint32_t vertices = g->nb + g->level;
    if (d->offsets[0] != 0 || d->offsets[d->strip_count] != d->index_count)
        return mts_error_set(err, MTS_ERR_ARG, "grow: the full strips given are malformed");
    for (uint32_t s = 0; s < d->strip_count; s++) {
        if (d->offsets[s + 1] < d->offsets[s])
            return mts_error_set(err, MTS_ERR_ARG, "grow: full strip %u given is malformed", s);
    }
    for (uint32_t i = 0; i < d->index_count; i++) {
        if (d->indices[i] >= vertices)
            return mts_error_set(err, MTS_ERR_ARG,
                                 "grow: a full strip given names vertex %u of %u", d->indices[i],
                                 vertices);
    }
    g->rec.n = 0;
    if (!mts__grow_slots_reserve(g, d->strip_count) || !mts_words_reserve(&g->rec, 1))
        return mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
    g->rec.n = 1;
    uint32_t edits = 0;
    for (uint32_t s = 0; s < g->slot_count; s++) {
        const uint32_t at = s < d->strip_count ? d->offsets[s] : 0;
        const mts_words r = {d->indices + at, s < d->strip_count ? d->offsets[s + 1] - at : 0, 0};
        if (!mts__grow_splice_whole(g, s, &r, u, v, &edits))
            return mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
        g->slot[s].head = -1;
        g->slot[s].ntri = 0;
    }
    g->rec.w[0] = edits;
    g->touched_count = 0;
    g->free_count = 0;
    g->stamp_now++;
    g->mesh_only = 1;
    return MTS_OK;
}

static int is_key(mts_grow *g)
{
    if (g->level == g->n)
        return 1;
    if (g->key_given) {
        if (g->key_given_at < g->key_given_count && g->key_given[g->key_given_at] == g->level) {
            g->key_given_at++;
            return 1;
        }
        return 0;
    }
    const double grown = g->key_triangles ? (double)g->tri_count / g->key_triangles : 0;
    if (g->key_ratio > 1 && grown >= g->key_ratio)
        return 1;
    /* the strips as the last split left them, drawn joined */
    const mts_strip_stats now = {.strips = g->nonempty, .indices = g->total_indices};
    return g->key_quality > 0 && grown >= g->key_min_ratio && g->tri_count &&
           (double)mts_strip_stats_draw_indices(&now) / g->tri_count > g->key_quality;
}

/* Notes the parent's corners before a fan split, with each one's triangle's
 * next on its path (g->cand: what local_region finds the changed stretch
 * by): its ring, all the corners it has in a manifold mesh. */
static int note_candidates(mts_grow *g)
{
    g->cand.n = 0;
    if (!mts_words_reserve(&g->cand, 2 * (size_t)g->ring_count))
        return 0;
    for (uint32_t k = 0; k < g->ring_count; k++) {
        uint32_t c = g->ring.w[k];
        g->cand.w[g->cand.n++] = c;
        g->cand.w[g->cand.n++] = (uint32_t)mts__grow_next_of(g, c / 3);
    }
    return 1;
}

mts_result mts_grow_next(mts_grow *g, const mts_grow_split *sp, const mts_grow_full *full,
                         const uint32_t **record, uint32_t *word_count, mts_error *err)
{
    if (g->mesh_only)
        return mts_error_set(err, MTS_ERR_ARG, "grow: a mesh-only grow derives no records");
    if (g->level >= g->n)
        return mts_error_set(err, MTS_ERR_ARG, "grow: every split is applied already");
    const uint32_t v = g->nb + g->level, u = sp->parent;
    if (u >= v || (sp->left != NONE && sp->left >= v) || (sp->right != NONE && sp->right >= v) ||
        sp->left == u || sp->right == u)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "grow: split %u (vertex %u, parent %u, %u, %u) names a vertex out "
                             "of range",
                             g->level, v, u, sp->left, sp->right);
    if (g->level + 1 == g->n && (!full || (!full->strips && !full->paths && !full->derived)))
        return mts_error_set(err, MTS_ERR_ARG, "grow: the last split needs the full strips");
    if (!mts__corner_vhead_reserve(g, v + 1))
        goto nomem;
    const int fan = mts__corner_is_fan(sp);
    /* the corners v takes over, the parent's corners and their paths noted
     * while they are as they were, then the split itself */
    mts_result rc = mts__corner_split_corners(g, sp, err);
    if (rc != MTS_OK)
        return rc;
    g->cand.n = 0;
    if (fan && !note_candidates(g))
        goto nomem;
    const uint32_t first_new = g->tri_count;
    if ((rc = mts__corner_split_apply(g, sp, err)) != MTS_OK)
        return rc;
    g->level++;

    int emitted = 0;
    if (is_key(g)) {
        if (g->level < g->n)
            rc = restrip(g, err);
        else if ((emitted = full->derived != NULL))
            rc = take_derived(g, full->derived, u, v, err);
        else if (full->strips)
            rc = adopt_strips(g, full->strips, 0, err);
        else
            rc = mts__grow_resolve_full(g, full, err);
        if (rc != MTS_OK)
            return rc;
        if (!mts_words_reserve(&g->keys, 1))
            goto nomem;
        g->keys.w[g->keys.n++] = g->level;
        g->fig.key_count++;
        g->key_triangles = g->tri_count;
    } else {
        /* links the split broke: only next to a moved triangle */
        for (size_t k = 0; k < g->affected.n; k++) {
            int32_t t = (int32_t)g->affected.w[k];
            touch(g, g->tri[t].slot);
            /* a fan's inner triangles keep every neighbour: only its ends
             * can have lost a link, across u -> right and left -> u */
            if (fan && k != 0 && k + 1 != g->affected.n)
                continue;
            if (g->prev[t] >= 0 && !mts__grow_adjacent(g, g->prev[t], t) &&
                !mend_link(g, g->prev[t], t, first_new))
                goto nomem;
            if (mts__grow_next_of(g, t) >= 0 &&
                !mts__grow_adjacent(g, t, mts__grow_next_of(g, t)) &&
                !mend_link(g, t, mts__grow_next_of(g, t), first_new))
                goto nomem;
        }
        for (uint32_t f = first_new; f < g->tri_count; f++) {
            if (g->tri[f].slot < 0 && !place_newborn(g, (int32_t)f))
                goto nomem;
        }
    }
    if (!emitted && !emit_record(g, u, v))
        goto nomem;
    if (g->rec.n > UINT32_MAX)
        return mts_error_set(err, MTS_ERR_LIMIT, "grow: a record of %zu words", g->rec.n);
    *record = g->rec.w;
    *word_count = (uint32_t)g->rec.n;
    return MTS_OK;
nomem:
    return mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
}

void mts_grow_get_figures(const mts_grow *g, mts_grow_figures *out)
{
    *out = g->fig;
    out->level = g->level;
    out->triangles = g->tri_count;
    out->strips = g->nonempty;
    out->indices = g->total_indices;
    out->slot_count = g->slot_count;
    out->capacity = g->capacity;
}

const uint32_t *mts_grow_keys(const mts_grow *g, uint32_t *count)
{
    *count = (uint32_t)g->keys.n;
    return g->keys.w;
}

const uint32_t *mts_grow_slot(const mts_grow *g, uint32_t s, uint32_t *length)
{
    if (s >= g->slot_count) {
        *length = 0;
        return NULL;
    }
    *length = (uint32_t)g->slot[s].seq.n;
    return g->slot[s].seq.w;
}

mts_result mts_grow_check(const mts_grow *g, mts_error *err)
{
    mts_result rc = mts__corner_check(g, err);
    if (g->mesh_only || rc != MTS_OK)
        return rc;
    mts_words d = {0};
    uint64_t indices = 0;
    uint32_t nonempty = 0, placed = 0;
    for (uint32_t s = 0; s < g->slot_count && rc == MTS_OK; s++) {
        uint32_t count = 0;
        for (int32_t t = g->slot[s].head, p = -1; t >= 0 && rc == MTS_OK;
             p = t, t = mts__grow_next_of(g, t)) {
            if (g->tri[t].slot != (int32_t)s || g->prev[t] != p ||
                (p >= 0 && !mts__grow_adjacent(g, p, t)) ||
                (p >= 0 &&
                 (g->tri[p].nx & 3) != (int32_t)mts__grow_edge_to(g, (uint32_t)p, (uint32_t)t)) ||
                ++count > g->tri_count)
                rc = mts_error_set(err, MTS_ERR_INTERNAL,
                                   "grow check: slot %u's path is broken at triangle %d", s, t);
        }
        if (rc != MTS_OK)
            break;
        if (count != g->slot[s].ntri)
            rc = mts_error_set(err, MTS_ERR_INTERNAL,
                               "grow check: slot %u holds %u triangles, counted %u", s, count,
                               g->slot[s].ntri);
        else if (!derive_whole(g, g->slot[s].head, &d))
            rc = mts_error_set(err, MTS_ERR_NOMEM, "grow check: out of memory");
        else if (d.n != g->slot[s].seq.n || (d.n && memcmp(d.w, g->slot[s].seq.w, d.n * 4) != 0))
            rc = mts_error_set(err, MTS_ERR_INTERNAL,
                               "grow check: slot %u holds %zu indices where its path gives %zu "
                               "(or others)",
                               s, g->slot[s].seq.n, d.n);
        placed += count;
        indices += g->slot[s].seq.n;
        nonempty += g->slot[s].seq.n > 0;
    }
    if (rc == MTS_OK && (placed != g->tri_count || indices != g->total_indices ||
                         nonempty != g->nonempty))
        rc = mts_error_set(err, MTS_ERR_INTERNAL,
                           "grow check: %u of %u triangles placed, %llu indices (kept %llu), %u "
                           "strips (kept %u)",
                           placed, g->tri_count, (unsigned long long)indices,
                           (unsigned long long)g->total_indices, nonempty, g->nonempty);
    free(d.w);
    return rc;
}
