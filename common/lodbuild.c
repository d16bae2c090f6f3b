#include "lodbuild.h"

#include <stdlib.h>
#include <string.h>

/* A growable array of 32-bit words. */
typedef struct words {
    uint32_t *w;
    size_t n, cap;
} words;

static int words_reserve(words *v, size_t extra)
{
    if (v->n + extra <= v->cap)
        return 1;
    size_t cap = v->cap ? v->cap : 256;
    while (cap < v->n + extra)
        cap *= 2;
    uint32_t *w = realloc(v->w, cap * sizeof *w);
    if (!w)
        return 0;
    v->w = w;
    v->cap = cap;
    return 1;
}

static int words_push(words *v, uint32_t x)
{
    if (!words_reserve(v, 1))
        return 0;
    v->w[v->n++] = x;
    return 1;
}

static int window_degenerate(const uint32_t *s, uint32_t k)
{
    return s[k] == s[k + 1] || s[k + 1] == s[k + 2] || s[k] == s[k + 2];
}

/* Index k of the strip that deleting s[i..j) leaves. */
static inline uint32_t joined_at(const uint32_t *s, uint32_t i, uint32_t d, uint32_t k)
{
    return k < i ? s[k] : s[k + d];
}

/* Would deleting s[i..j) leave the multiset of oriented non-degenerate
 * triangles of the strip unchanged? Only windows touching the run and the
 * (at most two) windows spanning the join can differ; with an odd run the
 * windows after it change parity, which is harmless only if none of them
 * draws. last_drawn is the start of the last non-degenerate window, or -1. */
static int removal_keeps_surface(const uint32_t *s, uint32_t len, uint32_t i, uint32_t j,
                                 int64_t last_drawn)
{
    uint32_t d = j - i;
    if ((d & 1u) && last_drawn >= (int64_t)j)
        return 0;
    uint32_t before[2][3], after[2][3];
    int nb = 0, na = 0;
    int64_t k0 = (int64_t)i - 2 < 0 ? 0 : (int64_t)i - 2;
    int64_t k1 = (int64_t)j - 1 > (int64_t)len - 3 ? (int64_t)len - 3 : (int64_t)j - 1;
    for (int64_t k = k0; k <= k1; k++) {
        uint32_t t[3];
        if (mts_strip_window(s, (uint32_t)k, t)) {
            if (nb == 2)
                return 0; /* the join can bring back at most two triangles */
            mts_tri_canonical(t);
            memcpy(before[nb++], t, sizeof t);
        }
    }
    uint32_t joined_len = len - d;
    for (int64_t k = (int64_t)i - 2; k < (int64_t)i; k++) {
        if (k < 0 || k + 2 >= (int64_t)joined_len)
            continue;
        uint32_t w[3] = {joined_at(s, i, d, (uint32_t)k), joined_at(s, i, d, (uint32_t)k + 1),
                         joined_at(s, i, d, (uint32_t)k + 2)};
        uint32_t t[3];
        if (mts_strip_window(w, 0, t)) {
            if (k & 1) { /* window parity comes from its place in the strip */
                uint32_t x = t[0];
                t[0] = t[1];
                t[1] = x;
            }
            mts_tri_canonical(t);
            memcpy(after[na++], t, sizeof t);
        }
    }
    if (na != nb)
        return 0;
    if (nb == 0)
        return 1;
    if (nb == 1)
        return memcmp(before[0], after[0], sizeof before[0]) == 0;
    return (memcmp(before[0], after[0], 12) == 0 && memcmp(before[1], after[1], 12) == 0) ||
           (memcmp(before[0], after[1], 12) == 0 && memcmp(before[1], after[0], 12) == 0);
}

static int64_t last_drawn_window(const uint32_t *s, uint32_t len)
{
    for (int64_t k = (int64_t)len - 3; k >= 0; k--) {
        if (!window_degenerate(s, (uint32_t)k))
            return k;
    }
    return -1;
}

/* Finds the longest removable run around the maximal degenerate window run
 * [a, b] (window starts); ties go to the leftmost. */
static int best_removal(const uint32_t *s, uint32_t len, uint32_t a, uint32_t b,
                        int64_t last_drawn, uint32_t *ri, uint32_t *rj)
{
    uint32_t jmax = b + 3 < len ? b + 3 : len;
    for (uint32_t d = jmax - a; d >= 1; d--) {
        for (uint32_t i = a; i + d <= jmax && i <= b + 2; i++) {
            if (removal_keeps_surface(s, len, i, i + d, last_drawn)) {
                *ri = i;
                *rj = i + d;
                return 1;
            }
        }
    }
    return 0;
}

typedef struct removal {
    uint32_t pos, len, data_at; /* data_at: where the removed indices are kept */
} removal;

typedef struct builder {
    uint32_t *slot, *length, *data; /* working strips, shrinking from full */
    uint32_t strip_count;
    /* vertex -> strips that (may) hold it */
    uint32_t vertex_count;
    uint32_t **vs;
    uint32_t *vs_n, *vs_cap;
    uint32_t *stamp;
    uint32_t stamp_now;
    /* per collapse, in split form with original vertex ids */
    words rec;
    uint32_t *rec_off;
    /* scratch for one strip's edit */
    words subst, removed;
    removal *rm;
    size_t rm_n, rm_cap;
    uint32_t *touched;
} builder;

static int rm_push(builder *b, removal r)
{
    if (b->rm_n == b->rm_cap) {
        size_t cap = b->rm_cap ? b->rm_cap * 2 : 64;
        removal *p = realloc(b->rm, cap * sizeof *p);
        if (!p)
            return 0;
        b->rm = p;
        b->rm_cap = cap;
    }
    b->rm[b->rm_n++] = r;
    return 1;
}

static int vs_push(builder *b, uint32_t v, uint32_t s)
{
    if (b->vs_n[v] == b->vs_cap[v]) {
        uint32_t cap = b->vs_cap[v] ? b->vs_cap[v] * 2 : 4;
        uint32_t *p = realloc(b->vs[v], (size_t)cap * sizeof *p);
        if (!p)
            return 0;
        b->vs[v] = p;
        b->vs_cap[v] = cap;
    }
    b->vs[v][b->vs_n[v]++] = s;
    return 1;
}

/* Removes what the collapse left degenerate in one strip, around the window
 * starts [lo, hi] it changed; notes every removal in b->rm. Runs elsewhere in
 * the strip were already as short as they could be. */
static int cleanup_strip(builder *b, uint32_t *s, uint32_t *plen, int64_t lo, int64_t hi,
                         mts_lodbuild_stats *st)
{
    for (;;) {
        uint32_t len = *plen;
        if (len == 0)
            return 1;
        uint32_t ri = 0, rj = 0;
        int found = 0;
        if (len < 3) {
            ri = 0;
            rj = len;
            found = 1;
        } else {
            int64_t last_drawn = last_drawn_window(s, len);
            int64_t k = lo - 4 < 0 ? 0 : lo - 4;
            int64_t kend = hi + 4 > (int64_t)len - 3 ? (int64_t)len - 3 : hi + 4;
            while (k <= kend && !found) {
                if (!window_degenerate(s, (uint32_t)k)) {
                    k++;
                    continue;
                }
                uint32_t a = (uint32_t)k, e = (uint32_t)k;
                while (a > 0 && window_degenerate(s, a - 1))
                    a--;
                while (e + 3 < len && window_degenerate(s, e + 1))
                    e++;
                found = best_removal(s, len, a, e, last_drawn, &ri, &rj);
                k = (int64_t)e + 1;
            }
        }
        if (!found)
            return 1;
        uint32_t d = rj - ri;
        removal r = {ri, d, (uint32_t)b->removed.n};
        if (!rm_push(b, r) || !words_reserve(&b->removed, d))
            return 0;
        memcpy(b->removed.w + b->removed.n, s + ri, (size_t)d * 4);
        b->removed.n += d;
        memmove(s + ri, s + rj, (size_t)(len - rj) * 4);
        *plen = len - d;
        st->removed_runs++;
        st->removed_indices += d;
        /* the changed window starts, moved past the deletion, plus the two
         * windows that now span the join (ri - 2, ri - 1), which may lie to
         * the right of hi when the run found reached past it */
        lo = (int64_t)ri - 2 < lo ? (int64_t)ri - 2 : lo;
        hi = hi >= (int64_t)ri ? (hi - d > (int64_t)ri ? hi - d : (int64_t)ri) : hi;
        if (hi < (int64_t)ri - 1)
            hi = (int64_t)ri - 1;
    }
}

static void builder_free(builder *b)
{
    free(b->slot);
    free(b->length);
    free(b->data);
    if (b->vs) {
        for (uint32_t v = 0; v < b->vertex_count; v++)
            free(b->vs[v]);
        free(b->vs);
    }
    free(b->vs_n);
    free(b->vs_cap);
    free(b->stamp);
    free(b->rec.w);
    free(b->rec_off);
    free(b->subst.w);
    free(b->removed.w);
    free(b->rm);
    free(b->touched);
}

static int cmp_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return x < y ? -1 : x > y;
}

mts_result mts_lodbuild(const mts_mesh *mesh, const mts_strips *strips,
                        const mts_simplify_result *simp, const mts_progress *progress,
                        mts_model *model, mts_lodbuild_stats *stats_out, mts_error *err)
{
    mts_result rc = MTS_ERR_NOMEM;
    builder b = {0};
    mts_lodbuild_stats st = {0};
    uint32_t *new_id = NULL;
    const uint32_t nv = mesh->vertex_count;
    const uint32_t n = simp->collapse_count;
    const uint32_t ns = strips->strip_count;
    memset(model, 0, sizeof *model);

    if (n >= nv)
        return mts_error_set(err, MTS_ERR_ARG, "lodbuild: %u collapses for %u vertices", n, nv);
    for (uint32_t i = 0; i < strips->index_count; i++) {
        if (strips->indices[i] >= nv)
            return mts_error_set(err, MTS_ERR_RANGE, "lodbuild: strip index %u out of range",
                                 strips->indices[i]);
    }

    b.strip_count = ns;
    b.vertex_count = nv;
    b.slot = malloc(((size_t)ns + 1) * 4);
    b.length = malloc(((size_t)ns + 1) * 4);
    b.data = malloc(((size_t)strips->index_count + 1) * 4);
    b.vs = calloc(nv, sizeof *b.vs);
    b.vs_n = calloc(nv, 4);
    b.vs_cap = calloc(nv, 4);
    b.stamp = calloc((size_t)ns + 1, 4);
    b.rec_off = malloc(((size_t)n + 1) * 4);
    b.touched = malloc(((size_t)ns + 1) * 4);
    new_id = malloc((size_t)nv * 4);
    model->level_triangles = malloc(((size_t)n + 1) * 4);
    model->level_strips = malloc(((size_t)n + 1) * 4);
    model->level_indices = malloc(((size_t)n + 1) * 4);
    if (!b.slot || !b.length || !b.data || !b.vs || !b.vs_n || !b.vs_cap || !b.stamp ||
        !b.rec_off || !b.touched || !new_id || !model->level_triangles || !model->level_strips ||
        !model->level_indices)
        goto nomem;
    memcpy(b.slot, strips->offsets, ((size_t)ns + 1) * 4);
    memcpy(b.data, strips->indices, (size_t)strips->index_count * 4);
    uint32_t nonempty = 0;
    uint64_t total = strips->index_count;
    for (uint32_t s = 0; s < ns; s++) {
        b.length[s] = b.slot[s + 1] - b.slot[s];
        nonempty += b.length[s] > 0;
        const uint32_t *str = b.data + b.slot[s];
        for (uint32_t k = 0; k < b.length[s]; k++) {
            uint32_t v = str[k];
            if ((b.vs_n[v] == 0 || b.vs[v][b.vs_n[v] - 1] != s) && !vs_push(&b, v, s))
                goto nomem;
        }
    }
    uint32_t triangles = mesh->triangle_count;
    model->level_triangles[n] = triangles;
    model->level_strips[n] = nonempty;
    model->level_indices[n] = (uint32_t)total;

    for (uint32_t c = 0; c < n; c++) {
        const uint32_t v = simp->collapses[c].removed, u = simp->collapses[c].kept;
        if (v >= nv || u >= nv || v == u) {
            rc = mts_error_set(err, MTS_ERR_RANGE, "lodbuild: collapse %u (%u -> %u) is invalid",
                               c, v, u);
            goto fail;
        }
        b.rec_off[c] = (uint32_t)b.rec.n;
        size_t edit_count_at = b.rec.n;
        if (!words_push(&b.rec, 0))
            goto nomem;
        uint32_t nt = 0;
        b.stamp_now++;
        for (uint32_t k = 0; k < b.vs_n[v]; k++) {
            uint32_t s = b.vs[v][k];
            if (b.stamp[s] != b.stamp_now) {
                b.stamp[s] = b.stamp_now;
                b.touched[nt++] = s;
            }
        }
        qsort(b.touched, nt, 4, cmp_u32);
        uint32_t edits = 0;
        for (uint32_t t = 0; t < nt; t++) {
            uint32_t s = b.touched[t];
            uint32_t *str = b.data + b.slot[s];
            uint32_t len = b.length[s];
            b.subst.n = 0;
            b.removed.n = 0;
            b.rm_n = 0;
            for (uint32_t k = 0; k < len; k++) {
                if (str[k] == v) {
                    str[k] = u;
                    if (!words_push(&b.subst, k))
                        goto nomem;
                }
            }
            if (b.subst.n == 0)
                continue; /* v left this strip in an earlier run removal */
            int64_t lo = (int64_t)b.subst.w[0] - 2, hi = b.subst.w[b.subst.n - 1];
            if (!cleanup_strip(&b, str, &b.length[s], lo, hi, &st))
                goto nomem;
            /* split form: inserts last-removed first, then the positions */
            size_t need = 3 + 2 * b.rm_n + b.removed.n + b.subst.n;
            if (!words_reserve(&b.rec, need))
                goto nomem;
            uint32_t *w = b.rec.w + b.rec.n;
            *w++ = s;
            *w++ = (uint32_t)b.rm_n;
            *w++ = (uint32_t)b.subst.n;
            for (size_t r = b.rm_n; r-- > 0;) {
                *w++ = b.rm[r].pos;
                *w++ = b.rm[r].len;
                memcpy(w, b.removed.w + b.rm[r].data_at, (size_t)b.rm[r].len * 4);
                w += b.rm[r].len;
            }
            memcpy(w, b.subst.w, b.subst.n * 4);
            w += b.subst.n;
            b.rec.n = (size_t)(w - b.rec.w);
            edits++;
            st.edits++;
            st.substitutions += b.subst.n;
            total -= len - b.length[s];
            if (b.length[s] == 0) {
                nonempty--;
                st.emptied_strips++;
            } else {
                /* u now lives in s: let the next collapse of u find it */
                int known = 0;
                for (uint32_t k = 0; k < b.vs_n[u] && !known; k++)
                    known = b.vs[u][k] == s;
                if (!known && !vs_push(&b, u, s))
                    goto nomem;
            }
        }
        b.rec.w[edit_count_at] = edits;
        free(b.vs[v]);
        b.vs[v] = NULL;
        b.vs_n[v] = b.vs_cap[v] = 0;
        triangles -= simp->collapses[c].faces_removed;
        model->level_triangles[n - 1 - c] = triangles;
        model->level_strips[n - 1 - c] = nonempty;
        model->level_indices[n - 1 - c] = (uint32_t)total;
        if ((c & 1023) == 0)
            mts_progress_report(progress, "records", (double)c / n);
    }
    /* offsets are 32-bit words in the model and the file */
    if (b.rec.n > UINT32_MAX - 1) {
        rc = mts_error_set(err, MTS_ERR_LIMIT,
                           "lodbuild: the records take %zu words, more than 32-bit offsets reach",
                           b.rec.n);
        goto fail;
    }
    b.rec_off[n] = (uint32_t)b.rec.n;

    /* Stream order: survivors keep their relative order, then the collapsed
     * vertices, last collapsed first. */
    const uint32_t nb = nv - n;
    for (uint32_t v = 0; v < nv; v++)
        new_id[v] = UINT32_MAX;
    for (uint32_t c = 0; c < n; c++) {
        uint32_t v = simp->collapses[c].removed;
        if (new_id[v] != UINT32_MAX) {
            rc = mts_error_set(err, MTS_ERR_ARG, "lodbuild: vertex %u collapses twice", v);
            goto fail;
        }
        new_id[v] = nb + (n - 1 - c);
    }
    uint32_t next = 0;
    for (uint32_t v = 0; v < nv; v++) {
        if (new_id[v] == UINT32_MAX)
            new_id[v] = next++;
    }

    model->vertex_count = nv;
    model->base_vertex_count = nb;
    model->level_count = n;
    model->strip_count = ns;
    model->positions = malloc((size_t)nv * 12);
    model->normals = malloc((size_t)nv * 12);
    model->parents = malloc(((size_t)n + 1) * 4);
    model->record_offsets = malloc(((size_t)n + 1) * 4);
    model->record_data = malloc((b.rec.n + 1) * 4);
    if (!model->positions || !model->normals || !model->parents || !model->record_offsets ||
        !model->record_data)
        goto nomem;
    for (int a = 0; a < 3; a++) {
        model->bbox_min[a] = nv ? mesh->positions[a] : 0;
        model->bbox_max[a] = nv ? mesh->positions[a] : 0;
    }
    for (uint32_t v = 0; v < nv; v++) {
        memcpy(model->positions + 3 * (size_t)new_id[v], mesh->positions + 3 * (size_t)v, 12);
        memcpy(model->normals + 3 * (size_t)new_id[v], mesh->normals + 3 * (size_t)v, 12);
        for (int a = 0; a < 3; a++) {
            float x = mesh->positions[3 * (size_t)v + a];
            if (x < model->bbox_min[a])
                model->bbox_min[a] = x;
            if (x > model->bbox_max[a])
                model->bbox_max[a] = x;
        }
    }
    for (uint32_t c = 0; c < n; c++)
        model->parents[n - 1 - c] = new_id[simp->collapses[c].kept];

    /* records in split order, vertex ids renumbered */
    uint32_t at = 0;
    for (uint32_t j = 0; j < n; j++) {
        uint32_t c = n - 1 - j;
        const uint32_t *p = b.rec.w + b.rec_off[c];
        const uint32_t *end = b.rec.w + b.rec_off[c + 1];
        model->record_offsets[j] = at;
        uint32_t *out = model->record_data + at;
        uint32_t edits = *p;
        *out++ = *p++;
        for (uint32_t e = 0; e < edits; e++) {
            uint32_t inserts = p[1], substs = p[2];
            memcpy(out, p, 12);
            out += 3;
            p += 3;
            for (uint32_t k = 0; k < inserts; k++) {
                uint32_t run = p[1];
                *out++ = p[0];
                *out++ = run;
                p += 2;
                for (uint32_t r = 0; r < run; r++)
                    *out++ = new_id[*p++];
            }
            memcpy(out, p, (size_t)substs * 4);
            out += substs;
            p += substs;
        }
        if (p != end) {
            rc = mts_error_set(err, MTS_ERR_INTERNAL, "lodbuild: record %u is malformed", c);
            goto fail;
        }
        at = (uint32_t)(out - model->record_data);
    }
    model->record_offsets[n] = at;
    model->record_word_count = at;

    /* full and base strips in stream ids */
    if (mts_strips_alloc(&model->full, ns, strips->index_count, err) != MTS_OK)
        goto fail_keep;
    memcpy(model->full.offsets, strips->offsets, ((size_t)ns + 1) * 4);
    for (uint32_t i = 0; i < strips->index_count; i++)
        model->full.indices[i] = new_id[strips->indices[i]];
    if (mts_strips_alloc(&model->base, ns, (uint32_t)total, err) != MTS_OK)
        goto fail_keep;
    uint32_t o = 0;
    for (uint32_t s = 0; s < ns; s++) {
        model->base.offsets[s] = o;
        const uint32_t *str = b.data + b.slot[s];
        for (uint32_t k = 0; k < b.length[s]; k++)
            model->base.indices[o++] = new_id[str[k]];
    }
    model->base.offsets[ns] = o;

    mts_progress_report(progress, "records", 1.0);
    if (stats_out)
        *stats_out = st;
    builder_free(&b);
    free(new_id);
    return MTS_OK;

nomem:
    rc = mts_error_set(err, MTS_ERR_NOMEM, "lodbuild: out of memory");
    goto fail;
fail_keep:
    rc = err ? err->code : MTS_ERR_NOMEM;
fail:
    builder_free(&b);
    free(new_id);
    mts_model_free(model);
    return rc;
}
