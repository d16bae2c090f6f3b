/* Growth cut at its key levels (see grow_tokens.h for the why): a mesh-only
 * grow, workers made from it, and the in-order fix-up of their records. */
#include "grow_tokens.h"

#include <stdlib.h>
#include <string.h>

#include "corner.h"
#include "greedy.h"
#include "grow_internal.h"
#include "model.h"
#include "words.h"

#define NONE MTS_GROW_NONE

/* ---- the mesh-only grow ---- */

mts_result mts_grow_create_mesh(const mts_strips *base, uint32_t nb, uint32_t n, mts_grow **out,
                                mts_error *err)
{
    *out = NULL;
    if (n > UINT32_MAX - 1 - nb)
        return mts_error_set(err, MTS_ERR_LIMIT, "grow: %u + %u vertices is too many", nb, n);
    for (uint32_t i = 0; i < base->index_count; i++) {
        if (base->indices[i] >= nb)
            return mts_error_set(err, MTS_ERR_FORMAT, "grow: base index %u is not a base vertex",
                                 base->indices[i]);
    }
    mts_grow *g = calloc(1, sizeof *g);
    if (!g)
        return mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
    g->nb = nb;
    g->n = n;
    g->stamp_now = 1;
    g->mesh_only = 1;
    mts_result rc = MTS_OK;
    if (!mts__corner_vhead_reserve(g, nb) || !mts__corner_tri_reserve(g, base->index_count + 1))
        rc = mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
    /* the triangles in the order mts_grow_create adds them: the same ids */
    for (uint32_t k = 0; rc == MTS_OK && k < base->strip_count; k++) {
        const uint32_t *str = base->indices + base->offsets[k];
        uint32_t len = base->offsets[k + 1] - base->offsets[k];
        for (uint32_t w = 0; rc == MTS_OK && w + 2 < len; w++) {
            uint32_t tri[3];
            if (mts_strip_window(str, w, tri) &&
                mts__corner_tri_add(g, tri[0], tri[1], tri[2], 1) < 0)
                rc = mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
        }
    }
    if (rc == MTS_OK)
        rc = mts__corner_twins_build(g, err);
    if (rc != MTS_OK) {
        mts_grow_free(g);
        return rc;
    }
    *out = g;
    return MTS_OK;
}

mts_result mts_grow_split_mesh(mts_grow *g, const mts_grow_split *sp, mts_error *err)
{
    if (!g->mesh_only)
        return mts_error_set(err, MTS_ERR_ARG, "grow: not a mesh-only grow");
    if (g->level >= g->n)
        return mts_error_set(err, MTS_ERR_ARG, "grow: every split is applied already");
    const uint32_t v = g->nb + g->level, u = sp->parent;
    if (u >= v || (sp->left != NONE && sp->left >= v) || (sp->right != NONE && sp->right >= v) ||
        sp->left == u || sp->right == u)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "grow: split %u (vertex %u, parent %u, %u, %u) names a vertex out "
                             "of range",
                             g->level, v, u, sp->left, sp->right);
    if (!mts__corner_vhead_reserve(g, v + 1))
        return mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
    mts_result rc = mts__corner_split_corners(g, sp, err);
    if (rc == MTS_OK)
        rc = mts__corner_split_apply(g, sp, err);
    if (rc == MTS_OK)
        g->level++;
    return rc;
}

/* ---- workers ---- */

mts_result mts_grow_create_worker(const mts_grow *mesh, const uint32_t *ids,
                                  const mts_grow_options *opts, mts_grow **out, mts_error *err)
{
    *out = NULL;
    const uint32_t L = mesh->level, nb = mesh->nb, n = mesh->n;
    if (!opts || !opts->key_levels)
        return mts_error_set(err, MTS_ERR_ARG, "grow: a worker needs the key levels");
    if (L >= n)
        return mts_error_set(err, MTS_ERR_ARG, "grow: every split is applied already");
    uint32_t at = 0;
    for (uint32_t k = 0; k < opts->key_count; k++) {
        if (opts->key_levels[k] == 0 || opts->key_levels[k] >= n ||
            (k && opts->key_levels[k] <= opts->key_levels[k - 1]))
            return mts_error_set(err, MTS_ERR_FORMAT,
                                 "grow: key level %u (%u of %u) is out of order or range",
                                 opts->key_levels[k], k, opts->key_count);
        at += opts->key_levels[k] <= L;
    }
    if (L + 1 < n && (at == opts->key_count || opts->key_levels[at] != L + 1))
        return mts_error_set(err, MTS_ERR_ARG, "grow: level %u is not a key", L + 1);
    mts_grow *g = calloc(1, sizeof *g);
    if (!g)
        return mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
    g->nb = nb;
    g->n = n;
    g->level = L;
    g->stamp_now = 1;
    g->keep_order = 1;
    mts_grow_use_memory(g, mesh->tri_mem.cache);
    g->key_given = opts->key_levels;
    g->key_given_count = opts->key_count;
    g->key_given_at = at;
    g->fig.key_count = 1;
    mts_result rc = MTS_OK;
    uint8_t *seen = NULL;
    if (!mts__corner_vhead_reserve(g, nb + L) || !mts__corner_tri_reserve(g, mesh->tri_count + 1))
        goto nomem;
    if (ids) {
        /* renumbering by anything but a permutation would corrupt the mesh */
        if (!(seen = calloc((size_t)mesh->tri_count + 1, 1)))
            goto nomem;
        for (uint32_t t = 0; t < mesh->tri_count && rc == MTS_OK; t++) {
            if (ids[t] >= mesh->tri_count || seen[ids[t]]++)
                rc = mts_error_set(err, MTS_ERR_ARG,
                                   "grow: the worker's ids are not a permutation (%u at %u)",
                                   ids[t], t);
        }
        if (rc != MTS_OK)
            goto fail;
    }
    /* copied and renumbered in one pass (mts__corner_renumber's mapping):
     * workers are made one after another, each from the one before's ids,
     * so this is on the sequential path */
    g->tri_count = mesh->tri_count;
    for (uint32_t t = 0; t < mesh->tri_count; t++) {
        const uint32_t x = ids ? ids[t] : t;
        mts__grow_tri *to = &g->tri[x];
        const mts__grow_tri *from = &mesh->tri[t];
        for (int e = 0; e < 3; e++) {
            const uint32_t h = from->tw[e];
            to->v[e] = from->v[e];
            to->tw[e] = h == NONE ? NONE : 3 * (ids ? ids[h / 3] : h / 3) + h % 3;
        }
        to->nx = to->slot = g->prev[x] = -1;
    }
    for (uint32_t x = 0; x < nb + L; x++) {
        const uint32_t c = mesh->vhead[x];
        g->vhead[x] = c == NONE ? NONE : 3 * (ids ? ids[c / 3] : c / 3) + c % 3;
    }
    g->key_triangles = g->tri_count;
    free(seen);
    *out = g;
    return MTS_OK;
nomem:
    rc = mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
fail:
    free(seen);
    mts_grow_free(g);
    return rc;
}

const uint32_t *mts_grow_key_order(const mts_grow *w, uint32_t *count)
{
    *count = (uint32_t)w->key_order.n;
    return w->key_order.n ? w->key_order.w : NULL;
}

void mts_grow_on_key_order(mts_grow *g, void (*fn)(void *user, const uint32_t *order,
                                                   uint32_t count),
                           void *user)
{
    g->on_key_order = fn;
    g->on_key_user = user;
}

/* ---- key paths handed across ---- */

mts_result mts_grow_key_paths(const mts_grow *g, const uint32_t *ids, const uint32_t *inv,
                              uint32_t *order, uint32_t *starts, uint32_t *path_count,
                              mts_error *err)
{
    const uint32_t n = g->tri_count;
    if (!ids)
        return mts_greedy_paths(n, g->tri[0].tw, sizeof *g->tri / 4, MTS_STRIPIFY_MAX_STRIP,
                                order, starts, path_count, err);
    /* the twins gathered in the other grow's ids first: greedy.c then reads
     * them in the order that grow keeps them (its strips of the key before,
     * side by side), where g's birth order would be a miss a triangle */
    uint32_t *tw = malloc((size_t)n * 12 + 12);
    if (!tw)
        return mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory for %u triangles", n);
    for (uint32_t i = 0; i < n; i++) {
        const uint32_t *x = g->tri[inv[i]].tw;
        for (unsigned e = 0; e < 3; e++)
            tw[3 * i + e] = x[e] == NONE ? NONE : 3 * ids[x[e] / 3] + x[e] % 3;
    }
    mts_result rc =
        mts_greedy_paths(n, tw, 3, MTS_STRIPIFY_MAX_STRIP, order, starts, path_count, err);
    free(tw);
    return rc;
}

void mts_grow_give_key_paths(mts_grow *g, uint32_t level, uint32_t triangles,
                             const uint32_t *order, const uint32_t *starts, uint32_t path_count)
{
    g->given_order = order;
    g->given_starts = starts;
    g->given_level = level;
    g->given_triangles = triangles;
    g->given_count = path_count;
}

/* ---- rings handed across ---- */

const uint32_t *mts_grow_ring_at_hand(const mts_grow *g, uint32_t u, uint32_t *count,
                                      int *closed)
{
    /* corner.c's ring cache: valid for the split about to be made */
    if (g->ring_level != g->level + 1 || g->ring_u != u || !g->ring_count)
        return NULL;
    *count = g->ring_count;
    *closed = g->ring_closed;
    return g->ring.w;
}

uint32_t mts_grow_ring_vertices(const mts_grow *g, uint32_t u, uint32_t *out, uint32_t cap)
{
    uint32_t count, n = 0;
    int closed;
    const uint32_t *r = mts_grow_ring_at_hand(g, u, &count, &closed);
    for (uint32_t k = 0; r && k < count && n < cap; k++) {
        const uint32_t c = r[k];
        out[n++] = g->tri[c / 3].v[mts__grow_nx[c % 3]];
    }
    if (r && !closed && n < cap) {
        const uint32_t c = r[count - 1];
        out[n++] = g->tri[c / 3].v[mts__grow_pv[c % 3]];
    }
    return n;
}

int mts_grow_take_ring(mts_grow *g, uint32_t u, const uint32_t *corners, uint32_t count,
                       int closed, const uint32_t *ids, uint32_t ids_count)
{
    const uint32_t tris = g->tri_count;
    g->ring_level = 0; /* whatever it held is overwritten */
    g->ring.n = 0;
    if (!count || count > tris || u >= g->nb + g->level || g->vhead[u] == NONE ||
        !mts_words_reserve(&g->ring, count))
        return 0;
    uint32_t *r = g->ring.w;
    for (uint32_t k = 0; k < count; k++) {
        const uint32_t t = corners[k] / 3;
        const uint32_t x = ids && t < ids_count ? ids[t] : t;
        if (x >= tris)
            return 0;
        r[k] = 3 * x + corners[k] % 3;
    }
    /* what ring() in corner.c would give: each corner's next round u is
     * the one after it, the two ends are where its walk starts and stops,
     * and u's listed corner is on it (a vertex where two fans meet has a
     * ring for each). Every load below has its address from r, so the
     * misses overlap where the walk takes them one after another. */
    const uint32_t head = g->vhead[u];
    int listed = 0;
    for (uint32_t k = 0; k < count; k++) {
        if (g->tri[r[k] / 3].v[r[k] % 3] != u)
            return 0;
        const uint32_t next = mts__corner_fwd(g, r[k]);
        if (next != (k + 1 < count ? r[k + 1] : closed ? r[0] : NONE))
            return 0;
        listed |= r[k] == head;
    }
    if (!listed || (closed ? r[0] != head : mts__corner_back(g, r[0]) != NONE))
        return 0;
    g->ring.n = count;
    g->ring_u = u;
    g->ring_count = count;
    g->ring_closed = closed;
    g->ring_level = g->level + 1;
    return 1;
}

void mts_grow_prefetch_ring(const mts_grow *g, unsigned ahead, uint32_t u,
                            const uint32_t *corners, uint32_t count, const uint32_t *ids,
                            uint32_t ids_count)
{
    const uint32_t tris = g->tri_count;
    if (ahead == 3) {
        for (uint32_t k = 0; k < count; k++) {
            const uint32_t t = corners[k] / 3;
            if (ids && t < ids_count)
                __builtin_prefetch(ids + t);
        }
        if (u < g->nb + g->level)
            __builtin_prefetch(g->vhead + u);
        return;
    }
    int32_t last = -1;
    for (uint32_t k = 0; k < count; k++) {
        const uint32_t t = corners[k] / 3;
        const uint32_t x = ids && t < ids_count ? ids[t] : t;
        if (x >= tris)
            continue;
        if (ahead == 2) {
            /* and where each comes from on its path: the fan's ends check
             * that link */
            __builtin_prefetch(g->tri + x);
            __builtin_prefetch(g->prev + x);
            continue;
        }
        /* the triangles round u mostly lie on one or two strips */
        const int32_t s = g->tri[x].slot;
        if (s < 0 || (uint32_t)s >= g->slot_count || s == last)
            continue;
        last = s;
        if (ahead == 1) {
            __builtin_prefetch(g->slot + s);
            continue;
        }
        /* a split scans the slot for u from both ends: four lines at each
         * end, all of a short one (the ends alone left the pool 1.06x
         * slower on the 1.2M mesh) */
        const uint32_t *w = g->slot[s].seq.w;
        const size_t n = g->slot[s].seq.n;
        for (size_t i = 0; i < n && i < 64; i += 16) {
            __builtin_prefetch(w + i);
            if (n > 64)
                __builtin_prefetch(w + n - 1 - i);
        }
    }
    if (ahead == 2 && u < g->nb + g->level && g->vhead[u] != MTS_GROW_NONE &&
        g->vhead[u] / 3 < tris)
        __builtin_prefetch(g->tri + g->vhead[u] / 3);
}

/* ---- the in-order fix-up ---- */

struct mts_grow_fixup {
    mts_grow *g; /* slots only: each one's indices and capacity, no mesh */
    int keyed;   /* a key was given: tokens map through map and spare */
    uint32_t tokens, slots; /* tokens at the key (paths), slots then */
    mts_words map;          /* token k < tokens -> its slot */
    mts_words spare;        /* the slots the key left empty, ascending */
    mts_words content, at;  /* scratch: the key's strip per token, where each starts */
    mts_words out;          /* the record as the fix-up gives it */
    uint64_t *order;        /* scratch: (slot, edit) pairs of a record */
    size_t order_cap;
};

mts_result mts_grow_fixup_create(mts_grow_fixup **out, mts_error *err)
{
    *out = NULL;
    mts_grow_fixup *f = calloc(1, sizeof *f);
    if (f && !(f->g = calloc(1, sizeof *f->g))) {
        free(f);
        f = NULL;
    }
    if (!f)
        return mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
    f->g->stamp_now = 1;
    *out = f;
    return MTS_OK;
}

void mts_grow_fixup_free(mts_grow_fixup *f)
{
    if (!f)
        return;
    mts_grow_free(f->g);
    free(f->map.w);
    free(f->spare.w);
    free(f->content.w);
    free(f->at.w);
    free(f->out.w);
    free(f->order);
    free(f);
}

/* The slot of token t. One grow pops its free slots lowest first (the key
 * pushes them highest first) and opens new ones only when none is free; a
 * worker, which knows no free slot of the past, opens a new token wherever
 * one grow pops or opens: its new tokens are those, in order. */
static uint64_t token_slot(const mts_grow_fixup *f, uint32_t t)
{
    if (!f->keyed)
        return t;
    if (t < f->tokens)
        return f->map.w[t];
    uint64_t i = t - f->tokens;
    return i < f->spare.n ? f->spare.w[i] : (uint64_t)f->slots + (i - f->spare.n);
}

mts_result mts_grow_fixup_end(mts_grow_fixup *f, const mts_grow *w, mts_error *err)
{
    mts_grow *g = f->g;
    for (uint32_t t = 0; t < w->slot_count; t++) {
        const uint64_t s = token_slot(f, t);
        if (s >= INT32_MAX)
            return mts_error_set(err, MTS_ERR_LIMIT, "grow: slot %llu", (unsigned long long)s);
        if (!mts__grow_slots_reserve(g, (uint32_t)s + 1))
            return mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
        mts_words *to = &g->slot[s].seq;
        const mts_words *from = &w->slot[t].seq;
        g->total_indices = g->total_indices - to->n + from->n;
        g->nonempty = g->nonempty - (to->n > 0) + (from->n > 0);
        to->n = 0;
        if (!mts_words_reserve(to, from->n))
            return mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
        if (from->n)
            memcpy(to->w, from->w, from->n * 4);
        to->n = from->n;
        if (w->capacity[t] > g->capacity[s])
            g->slot[s].capacity = g->capacity[s] = w->capacity[t];
    }
    return MTS_OK;
}

/* Sorts slot ids by cap[id], largest first, as one grow's fit_slots does:
 * stable over ascending ids, so equal capacities keep id order (a merge
 * sort; a key comes once in thousands of splits). */
static int sort_by_capacity(uint32_t *ids, uint32_t n, const uint32_t *cap)
{
    uint32_t *tmp = malloc(((size_t)n + 1) * 4);
    if (!tmp)
        return 0;
    for (uint32_t width = 1; width < n; width *= 2) {
        for (uint32_t lo = 0; lo < n; lo += 2 * width) {
            uint32_t mid = lo + width < n ? lo + width : n;
            uint32_t hi = lo + 2 * width < n ? lo + 2 * width : n;
            uint32_t i = lo, j = mid, o = lo;
            while (i < mid && j < hi)
                tmp[o++] = cap[ids[i]] >= cap[ids[j]] ? ids[i++] : ids[j++];
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

mts_result mts_grow_fixup_key(mts_grow_fixup *f, const uint32_t *rec, uint32_t words, uint32_t u,
                              uint32_t v, int full, const uint32_t **out, uint32_t *out_words,
                              mts_error *err)
{
    mts_grow *g = f->g;
    const uint32_t *p = rec, *end = rec + words;
    /* the key's strips per token: the worker's record inserts each whole
     * into an empty slot, u where v is, v at the substitutions */
    f->content.n = f->at.n = 0;
    uint32_t edits = words ? *p++ : 0, top = 0;
    if (!words)
        goto malformed;
    for (uint32_t k = 0; k < edits; k++) {
        uint32_t t;
        const uint32_t *next = mts_record_skip_edit(p, end, &t);
        if (!next || p[1] != 0 || p[2] > 1 || (k && t <= top) || t >= INT32_MAX)
            goto malformed;
        top = t;
        while (f->at.n <= t) {
            if (!mts_words_reserve(&f->at, 2))
                goto nomem;
            f->at.w[f->at.n++] = (uint32_t)f->content.n; /* tokens with no edit: empty */
        }
        const uint32_t len = p[2] ? p[5] : 0, *ins = p + 6;
        if (p[2] && p[4] != 0)
            goto malformed;
        if (!mts_words_reserve(&f->content, len))
            goto nomem;
        uint32_t *c = f->content.w + f->content.n;
        memcpy(c, ins, (size_t)len * 4);
        for (const uint32_t *q = p + 4 + (p[2] ? 2 + len : 0); q < next; q++) {
            if (*q >= len)
                goto malformed;
            c[*q] = v;
        }
        f->content.n += len;
        p = next;
    }
    if (p != end)
        goto malformed;
    if (!mts_words_reserve(&f->at, 1))
        goto nomem;
    f->at.w[f->at.n] = (uint32_t)f->content.n; /* the end of the last */
    const uint32_t tokens = (uint32_t)f->at.n;
    /* a restripified key's tokens are its paths, none empty */
    if (!full && tokens != edits)
        goto malformed;
    const uint32_t slots = g->slot_count > tokens ? g->slot_count : tokens;
    if (!mts__grow_slots_reserve(g, slots) || !mts_words_reserve(&f->map, slots) ||
        !mts_words_reserve(&f->spare, slots))
        goto nomem;
    /* token k goes into the k-th roomiest slot (grow.c's fit_slots; the
     * worker's tokens are its paths longest first); the full level's
     * strips keep the model's slots */
    uint32_t *by = f->spare.w; /* every slot, then the empty ones only */
    for (uint32_t s = 0; s < slots; s++)
        by[s] = s;
    if (!full && !sort_by_capacity(by, slots, g->capacity))
        goto nomem;
    memcpy(f->map.w, by, (size_t)tokens * 4);
    f->map.n = tokens;
    /* the rest are the key's empty slots: ascending, as they are popped */
    uint32_t spare = 0;
    for (uint32_t k = tokens; k < slots; k++)
        by[spare++] = by[k];
    qsort(by, spare, 4, mts_words_cmp);
    f->spare.n = spare;
    f->tokens = tokens;
    f->slots = slots;
    f->keyed = 1;
    /* the record: every slot in order, from what the interval before left
     * to its token's strip (an empty one: erased) */
    if (f->order_cap < slots) {
        uint64_t *o = realloc(f->order, ((size_t)slots + 1) * sizeof *o);
        if (!o)
            goto nomem;
        f->order = o;
        f->order_cap = slots;
    }
    for (uint32_t s = 0; s < slots; s++)
        f->order[s] = NONE;
    for (uint32_t t = 0; t < tokens; t++)
        f->order[f->map.w[t]] = t;
    g->rec.n = 0;
    if (!mts_words_reserve(&g->rec, 1))
        goto nomem;
    g->rec.n = 1;
    uint32_t made = 0;
    for (uint32_t s = 0; s < slots; s++) {
        const uint64_t t = f->order[s];
        mts_words r = {NULL, 0, 0};
        if (t != NONE) {
            r.w = f->content.w + f->at.w[t];
            r.n = f->at.w[t + 1] - f->at.w[t];
        }
        if (!mts__grow_splice_whole(g, s, &r, u, v, &made))
            goto nomem;
    }
    g->rec.w[0] = made;
    if (g->rec.n > UINT32_MAX)
        return mts_error_set(err, MTS_ERR_LIMIT, "grow: a record of %zu words", g->rec.n);
    *out = g->rec.w;
    *out_words = (uint32_t)g->rec.n;
    return MTS_OK;
malformed:
    return mts_error_set(err, MTS_ERR_FORMAT, "grow: not a worker's key record");
nomem:
    return mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
}

mts_result mts_grow_fixup_record(mts_grow_fixup *f, const uint32_t *rec, uint32_t words,
                                 const uint32_t **out, uint32_t *out_words, mts_error *err)
{
    if (!words)
        return mts_error_set(err, MTS_ERR_FORMAT, "grow: an empty record");
    const uint32_t edits = rec[0], *p = rec + 1, *end = rec + words;
    if (edits > words)
        return mts_error_set(err, MTS_ERR_FORMAT, "grow: a record of %u edits in %u words",
                             edits, words);
    if (f->order_cap < edits) {
        uint64_t *o = realloc(f->order, ((size_t)edits + 1) * sizeof *o);
        if (!o)
            return mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
        f->order = o;
        f->order_cap = edits;
    }
    /* each edit's slot and where it starts (its offset in rec, under 2^32) */
    for (uint32_t k = 0; k < edits; k++) {
        uint32_t t;
        const uint32_t *next = mts_record_skip_edit(p, end, &t);
        uint64_t s = next ? token_slot(f, t) : 0;
        if (!next || s >= INT32_MAX)
            return mts_error_set(err, MTS_ERR_FORMAT, "grow: edit %u of a record is malformed",
                                 k);
        f->order[k] = s << 32 | (uint32_t)(p - rec);
        p = next;
    }
    if (p != end)
        return mts_error_set(err, MTS_ERR_FORMAT, "grow: a record runs past its edits");
    /* a split edits two or three slots: an insertion sort, as emit_record */
    if (edits > 64) {
        qsort(f->order, edits, sizeof *f->order, mts_words_cmp64);
    } else {
        for (uint32_t i = 1; i < edits; i++) {
            uint64_t x = f->order[i];
            uint32_t j = i;
            for (; j > 0 && f->order[j - 1] > x; j--)
                f->order[j] = f->order[j - 1];
            f->order[j] = x;
        }
    }
    f->out.n = 0;
    if (!mts_words_reserve(&f->out, words))
        return mts_error_set(err, MTS_ERR_NOMEM, "grow: out of memory");
    uint32_t *o = f->out.w;
    *o++ = edits;
    for (uint32_t k = 0; k < edits; k++) {
        const uint32_t *e = rec + (uint32_t)f->order[k], *stop;
        uint32_t t;
        stop = mts_record_skip_edit(e, end, &t);
        *o++ = (uint32_t)(f->order[k] >> 32);
        memcpy(o, e + 1, (size_t)(stop - e - 1) * 4);
        o += stop - e - 1;
    }
    f->out.n = words;
    *out = f->out.w;
    *out_words = words;
    return MTS_OK;
}
