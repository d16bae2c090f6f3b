#include "verify.h"

#include <stdlib.h>
#include <string.h>

#include "grow.h"
#include "words.h"

/* Triangles compare as 64-bit keys when ids fit 21 bits (2M vertices), else
 * as triples; either way sorted canonical triangles compare exactly. */
typedef struct tri_set {
    uint64_t *keys; /* packed, or 3 words per triangle in 'wide' mode */
    uint32_t *wide;
    size_t count;
} tri_set;

typedef struct verifier {
    const mts_model *m;
    int packed;
    uint32_t *full_tris; /* oriented triangles of the full strips */
    size_t full_count;
    uint32_t *rep; /* vertex -> its representative at the level */
    tri_set ref, got;
} verifier;

static void set_add(tri_set *s, int packed, uint32_t t[3])
{
    mts_tri_canonical(t);
    if (packed)
        s->keys[s->count++] = (uint64_t)t[0] << 42 | (uint64_t)t[1] << 21 | t[2];
    else
        memcpy(s->wide + 3 * s->count++, t, 12);
}

static void set_sort(tri_set *s, int packed)
{
    if (packed)
        qsort(s->keys, s->count, 8, mts_words_cmp64);
    else
        qsort(s->wide, s->count, 12, mts_tri_compare);
}

static int set_contains(const tri_set *s, int packed, uint32_t t[3])
{
    mts_tri_canonical(t);
    if (packed) {
        uint64_t k = (uint64_t)t[0] << 42 | (uint64_t)t[1] << 21 | t[2];
        return bsearch(&k, s->keys, s->count, 8, mts_words_cmp64) != NULL;
    }
    return bsearch(t, s->wide, s->count, 12, mts_tri_compare) != NULL;
}

static void verifier_free(verifier *v)
{
    free(v->full_tris);
    free(v->rep);
    free(v->ref.keys);
    free(v->ref.wide);
    free(v->got.keys);
    free(v->got.wide);
    memset(v, 0, sizeof *v); /* a second free is harmless */
}

static mts_result verifier_init(verifier *v, const mts_model *m, mts_error *err)
{
    memset(v, 0, sizeof *v);
    v->m = m;
    v->packed = m->vertex_count < (1u << 21);
    /* The reference holds at most the full strips' windows; the strips at a
     * level at most their slots' windows. Strip lengths are not monotone in
     * the level (model.h), so the latter are counted from the capacities (the
     * longest each slot is at any level), never from the full lengths. */
    size_t windows = 0, slot_windows = 0;
    for (uint32_t s = 0; s < m->strip_count; s++) {
        uint32_t len = m->full.offsets[s + 1] - m->full.offsets[s], cap = m->capacity[s];
        windows += len >= 3 ? len - 2 : 0;
        slot_windows += cap >= 3 ? cap - 2 : 0;
    }
    v->full_tris = malloc((windows + 1) * 12);
    v->rep = malloc(((size_t)m->vertex_count + 1) * 4);
    if (v->packed) {
        v->ref.keys = malloc((windows + 1) * 8);
        v->got.keys = malloc((slot_windows + 1) * 8);
    } else {
        v->ref.wide = malloc((windows + 1) * 12);
        v->got.wide = malloc((slot_windows + 1) * 12);
    }
    if (!v->full_tris || !v->rep || !(v->packed ? v->ref.keys && v->got.keys
                                                : v->ref.wide && v->got.wide)) {
        verifier_free(v);
        return mts_error_set(err, MTS_ERR_NOMEM, "verify: out of memory");
    }
    for (uint32_t s = 0; s < m->strip_count; s++) {
        const uint32_t *str = m->full.indices + m->full.offsets[s];
        uint32_t len = m->full.offsets[s + 1] - m->full.offsets[s];
        for (uint32_t k = 0; k + 2 < len; k++) {
            if (mts_strip_window(str, k, v->full_tris + 3 * v->full_count))
                v->full_count++;
        }
    }
    return MTS_OK;
}

static mts_result check_level(verifier *v, const mts_lod *lod, mts_verify_report *rep,
                              mts_error *err)
{
    const mts_model *m = v->m;
    const uint32_t l = lod->level, nb = m->base_vertex_count;
    /* parents are older than their children, so one pass resolves chains */
    for (uint32_t x = 0; x < m->vertex_count; x++)
        v->rep[x] = x < nb + l ? x : v->rep[m->parents[x - nb]];
    v->ref.count = 0;
    for (size_t i = 0; i < v->full_count; i++) {
        const uint32_t *f = v->full_tris + 3 * i;
        uint32_t t[3] = {v->rep[f[0]], v->rep[f[1]], v->rep[f[2]]};
        if (t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
            set_add(&v->ref, v->packed, t);
    }
    v->got.count = 0;
    for (uint32_t s = 0; s < lod->strip_count; s++) {
        uint32_t len;
        const uint32_t *str = mts_lod_strip(lod, s, &len);
        for (uint32_t k = 0; k + 2 < len; k++) {
            uint32_t t[3];
            if (mts_strip_window(str, k, t))
                set_add(&v->got, v->packed, t);
        }
    }
    set_sort(&v->ref, v->packed);
    set_sort(&v->got, v->packed);
    int same = v->ref.count == v->got.count &&
               (v->packed ? memcmp(v->ref.keys, v->got.keys, v->ref.count * 8) == 0
                          : memcmp(v->ref.wide, v->got.wide, v->ref.count * 12) == 0);
    if (same)
        return MTS_OK;

    rep->failed_level = l;
    rep->failed_strip = UINT32_MAX;
    /* name the first strip drawing a triangle the mesh does not have here */
    for (uint32_t s = 0; s < lod->strip_count; s++) {
        uint32_t len;
        const uint32_t *str = mts_lod_strip(lod, s, &len);
        for (uint32_t k = 0; k + 2 < len; k++) {
            uint32_t t[3], shown[3];
            if (!mts_strip_window(str, k, t))
                continue;
            memcpy(shown, t, sizeof t);
            if (!set_contains(&v->ref, v->packed, t)) {
                rep->failed_strip = s;
                return mts_error_set(err, MTS_ERR_INVARIANT,
                                     "level %u, strip %u, window %u: triangle (%u, %u, %u) is not "
                                     "a triangle of the mesh at this level (with this winding)",
                                     l, s, k, shown[0], shown[1], shown[2]);
            }
        }
    }
    return mts_error_set(err, MTS_ERR_INVARIANT,
                         "level %u: the strips draw %zu triangles, the mesh has %zu (a triangle "
                         "is missing or drawn twice)",
                         l, v->got.count, v->ref.count);
}

mts_result mts_verify_level(const mts_model *model, const mts_lod *lod,
                            mts_verify_report *report, mts_error *err)
{
    verifier v;
    mts_verify_report dummy;
    if (!report)
        report = &dummy;
    mts_result rc = verifier_init(&v, model, err);
    if (rc != MTS_OK)
        return rc;
    rc = check_level(&v, lod, report, err);
    verifier_free(&v);
    return rc;
}

/* ---- the walk over every level ----------------------------------------
 *
 * Checking each level from scratch costs a sort of the whole mesh per level,
 * which is quadratic over all levels (minutes for bunny00). The walk instead
 * keeps D = (triangles the strips draw) - (triangles of the reference mesh)
 * as a multiset of canonical oriented triangles, updated by what one split
 * changes on each side; invariant 1 holds at a level exactly when D is
 * empty, which a count of non-zero entries tells at once.
 *   - strip side: the strips a record names lose their old windows and gain
 *     their new ones;
 *   - reference side: split j gives back vertex v = nb + j, and every full
 *     vertex that was merged into v (its subtree in the collapse forest; all
 *     of them have ids above v) maps to v instead of to v's parent, so only
 *     the full triangles touching that subtree move.
 * When D is not empty the exact sorted comparison above names the strip. */

typedef struct tri_entry {
    uint32_t a, b, c;
    int32_t count; /* 0 marks a free slot only when a == UINT32_MAX */
} tri_entry;

typedef struct tri_map {
    tri_entry *slots;
    size_t cap, used; /* cap is a power of two */
    size_t nonzero;
} tri_map;

static uint64_t tri_hash(uint32_t a, uint32_t b, uint32_t c)
{
    uint64_t h = ((uint64_t)a << 32 | b) * 0x9e3779b97f4a7c15ull;
    h ^= (h >> 29) ^ ((uint64_t)c * 0xc2b2ae3d27d4eb4full);
    h *= 0xff51afd7ed558ccdull;
    return h ^ (h >> 32);
}

static int tri_map_init(tri_map *m, size_t expected)
{
    size_t cap = 1024;
    while (cap < expected * 2)
        cap *= 2;
    m->slots = malloc(cap * sizeof *m->slots);
    if (!m->slots)
        return 0;
    for (size_t i = 0; i < cap; i++)
        m->slots[i].a = UINT32_MAX;
    m->cap = cap;
    m->used = 0;
    m->nonzero = 0;
    return 1;
}

static int tri_map_grow(tri_map *m)
{
    tri_map bigger;
    if (!tri_map_init(&bigger, m->cap))
        return 0;
    for (size_t i = 0; i < m->cap; i++) {
        const tri_entry *e = &m->slots[i];
        if (e->a == UINT32_MAX)
            continue;
        size_t at = tri_hash(e->a, e->b, e->c) & (bigger.cap - 1);
        while (bigger.slots[at].a != UINT32_MAX)
            at = (at + 1) & (bigger.cap - 1);
        bigger.slots[at] = *e;
    }
    bigger.used = m->used;
    bigger.nonzero = m->nonzero;
    free(m->slots);
    *m = bigger;
    return 1;
}

/* Adds delta to the count of an oriented triangle (skipped if degenerate). */
static int tri_map_add(tri_map *m, uint32_t a, uint32_t b, uint32_t c, int32_t delta)
{
    if (a == b || b == c || a == c)
        return 1;
    uint32_t t[3] = {a, b, c};
    mts_tri_canonical(t);
    if (m->used * 10 >= m->cap * 7 && !tri_map_grow(m))
        return 0;
    size_t at = tri_hash(t[0], t[1], t[2]) & (m->cap - 1);
    for (;;) {
        tri_entry *e = &m->slots[at];
        if (e->a == UINT32_MAX) {
            e->a = t[0];
            e->b = t[1];
            e->c = t[2];
            e->count = delta;
            m->used++;
            m->nonzero += delta != 0;
            return 1;
        }
        if (e->a == t[0] && e->b == t[1] && e->c == t[2]) {
            int was = e->count != 0;
            e->count += delta;
            m->nonzero = m->nonzero - (size_t)was + (e->count != 0);
            return 1;
        }
        at = (at + 1) & (m->cap - 1);
    }
}

/* Adds sign x every window of a strip. */
static int strip_windows_add(tri_map *m, const uint32_t *s, uint32_t len, int32_t sign)
{
    for (uint32_t k = 0; k + 2 < len; k++) {
        int ok = (k & 1u) ? tri_map_add(m, s[k + 1], s[k], s[k + 2], sign)
                          : tri_map_add(m, s[k], s[k + 1], s[k + 2], sign);
        if (!ok)
            return 0;
    }
    return 1;
}

/* Two independent 64-bit hashes of one strip (its id, length and indices);
 * the state of all strips is their sum, so a changed strip updates it. */
static void strip_hash(uint32_t id, const uint32_t *s, uint32_t len, uint64_t h[2])
{
    uint64_t a = 0xcbf29ce484222325ull ^ id, b = 0x9e3779b97f4a7c15ull + ((uint64_t)id << 32);
    a = (a ^ len) * 0x100000001b3ull;
    for (uint32_t k = 0; k < len; k++) {
        a = (a ^ s[k]) * 0x100000001b3ull;
        b = (b ^ s[k]) * 0xc4ceb9fe1a85ec53ull;
        b ^= b >> 31;
    }
    a ^= a >> 33;
    a *= 0xff51afd7ed558ccdull;
    a ^= a >> 33;
    b ^= len;
    b *= 0x94d049bb133111ebull;
    b ^= b >> 29;
    h[0] = a;
    h[1] = b;
}

typedef struct walk {
    const mts_model *m;
    tri_map diff;
    uint32_t *tri_start, *tri_list; /* full vertex -> full triangles (CSR) */
    uint32_t *child_start, *child_list; /* vertex -> vertices merged into it */
    uint32_t *stack, *moved;
    uint32_t *stamp;      /* per full triangle */
    uint32_t *strip_stamp;
    uint32_t *named;      /* strips a record names */
    uint64_t (*strip_h)[2];
    uint64_t sum[2];
    uint32_t now;
} walk;

static void walk_free(walk *w)
{
    free(w->diff.slots);
    free(w->tri_start);
    free(w->tri_list);
    free(w->child_start);
    free(w->child_list);
    free(w->stack);
    free(w->moved);
    free(w->stamp);
    free(w->strip_stamp);
    free(w->named);
    free(w->strip_h);
    memset(w, 0, sizeof *w);
}

static mts_result walk_init(walk *w, const verifier *v, mts_error *err)
{
    const mts_model *m = v->m;
    const uint32_t nv = m->vertex_count, nb = m->base_vertex_count, n = m->level_count;
    memset(w, 0, sizeof *w);
    w->m = m;
    w->tri_start = calloc((size_t)nv + 1, 4);
    w->tri_list = malloc((v->full_count * 3 + 1) * 4);
    w->child_start = calloc((size_t)nv + 1, 4);
    w->child_list = malloc(((size_t)n + 1) * 4);
    w->stack = malloc(((size_t)nv + 1) * 4);
    w->moved = malloc((v->full_count + 1) * 4);
    w->stamp = calloc(v->full_count + 1, 4);
    w->strip_stamp = calloc((size_t)m->strip_count + 1, 4);
    w->named = malloc(((size_t)m->strip_count + 1) * 4);
    w->strip_h = calloc((size_t)m->strip_count + 1, sizeof *w->strip_h);
    if (!w->tri_start || !w->tri_list || !w->child_start || !w->child_list || !w->stack ||
        !w->moved || !w->stamp || !w->strip_stamp || !w->named || !w->strip_h ||
        !tri_map_init(&w->diff, v->full_count)) {
        walk_free(w);
        return mts_error_set(err, MTS_ERR_NOMEM, "verify: out of memory");
    }
    /* counting sort into compressed rows: vertex -> triangles, parent -> children */
    for (size_t i = 0; i < v->full_count * 3; i++)
        w->tri_start[v->full_tris[i] + 1]++;
    for (uint32_t x = 0; x < nv; x++)
        w->tri_start[x + 1] += w->tri_start[x];
    for (size_t i = 0; i < v->full_count * 3; i++)
        w->tri_list[w->tri_start[v->full_tris[i]]++] = (uint32_t)(i / 3);
    for (uint32_t x = nv; x > 0; x--)
        w->tri_start[x] = w->tri_start[x - 1];
    w->tri_start[0] = 0;
    for (uint32_t j = 0; j < n; j++)
        w->child_start[m->parents[j] + 1]++;
    for (uint32_t x = 0; x < nv; x++)
        w->child_start[x + 1] += w->child_start[x];
    for (uint32_t j = 0; j < n; j++)
        w->child_list[w->child_start[m->parents[j]]++] = nb + j;
    for (uint32_t x = nv; x > 0; x--)
        w->child_start[x] = w->child_start[x - 1];
    w->child_start[0] = 0;
    return MTS_OK;
}

static int add_strip(walk *w, const mts_lod *lod, uint32_t s, int32_t sign)
{
    uint32_t len;
    const uint32_t *str = mts_lod_strip(lod, s, &len);
    uint64_t h[2];
    strip_hash(s, str, len, h);
    if (sign > 0) {
        w->sum[0] += h[0];
        w->sum[1] += h[1];
    } else {
        w->sum[0] -= h[0];
        w->sum[1] -= h[1];
    }
    return strip_windows_add(&w->diff, str, len, sign);
}

/* Moves the reference side from level l to l + 1 (v = nb + l appears). */
static int reference_split(walk *w, verifier *v, uint32_t l)
{
    const mts_model *m = w->m;
    const uint32_t vnew = m->base_vertex_count + l;
    uint32_t sp = 0, nmoved = 0;
    w->now++;
    w->stack[sp++] = vnew;
    while (sp) { /* the subtree of v, depth first */
        uint32_t x = w->stack[--sp];
        v->rep[x] = UINT32_MAX; /* marked: rewritten below */
        for (uint32_t k = w->tri_start[x]; k < w->tri_start[x + 1]; k++) {
            uint32_t t = w->tri_list[k];
            if (w->stamp[t] != w->now) {
                w->stamp[t] = w->now;
                w->moved[nmoved++] = t;
            }
        }
        for (uint32_t c = w->child_start[x]; c < w->child_start[x + 1]; c++)
            w->stack[sp++] = w->child_list[c];
    }
    const uint32_t parent = m->parents[l];
    for (int pass = 0; pass < 2; pass++) {
        /* pass 0: the triangles as they were (subtree -> parent) leave the
         * reference, so D gains them back; pass 1: they come in mapped to v */
        uint32_t to = pass == 0 ? parent : vnew;
        for (uint32_t i = 0; i < nmoved; i++) {
            const uint32_t *f = v->full_tris + 3 * (size_t)w->moved[i];
            uint32_t t[3];
            for (int c = 0; c < 3; c++)
                t[c] = v->rep[f[c]] == UINT32_MAX ? to : v->rep[f[c]];
            if (!tri_map_add(&w->diff, t[0], t[1], t[2], pass == 0 ? 1 : -1))
                return 0;
        }
    }
    /* the marked vertices are the subtree: they now map to v */
    w->stack[0] = vnew;
    sp = 1;
    while (sp) {
        uint32_t x = w->stack[--sp];
        v->rep[x] = vnew;
        for (uint32_t c = w->child_start[x]; c < w->child_start[x + 1]; c++)
            w->stack[sp++] = w->child_list[c];
    }
    return 1;
}

static uint32_t sample_level(uint32_t i, uint32_t samples, uint32_t n)
{
    return samples <= 1 ? n : (uint32_t)(((uint64_t)i * n + (samples - 1) / 2) / (samples - 1));
}

mts_result mts_verify_model(const mts_model *m, const mts_verify_options *opts,
                            mts_verify_report *report, mts_error *err)
{
    static const mts_verify_options defaults = {0};
    mts_verify_report dummy;
    if (!opts)
        opts = &defaults;
    if (!report)
        report = &dummy;
    memset(report, 0, sizeof *report);
    report->failed_strip = UINT32_MAX;
    const uint32_t n = m->level_count, nb = m->base_vertex_count;
    uint32_t samples = opts->samples == 0 || opts->samples > n + 1 ? n + 1 : opts->samples;
    if (samples < 2)
        samples = n > 0 ? 2 : 1;

    verifier v;
    walk w;
    mts_lod up = {0}, down = {0};
    uint64_t(*sums)[2] = malloc(((size_t)n + 1) * sizeof *sums);
    uint8_t *sampled = calloc((size_t)n + 1, 1);
    mts_result rc = verifier_init(&v, m, err);
    if (rc != MTS_OK) {
        free(sums);
        free(sampled);
        return rc;
    }
    if ((rc = walk_init(&w, &v, err)) != MTS_OK) {
        verifier_free(&v);
        free(sums);
        free(sampled);
        return rc;
    }
    if (!sums || !sampled) {
        rc = mts_error_set(err, MTS_ERR_NOMEM, "verify: out of memory");
        goto done;
    }
    for (uint32_t i = 0; i < samples; i++)
        sampled[sample_level(i, samples, n)] = 1;
    if ((rc = mts_lod_init(&up, m, MTS_LOD_AT_BASE, err)) != MTS_OK ||
        (rc = mts_lod_init(&down, m, MTS_LOD_AT_FULL, err)) != MTS_OK)
        goto done;

    /* level 0: every strip window in, every reference triangle out */
    for (uint32_t x = 0; x < m->vertex_count; x++)
        v.rep[x] = x < nb ? x : v.rep[m->parents[x - nb]];
    for (size_t i = 0; i < v.full_count; i++) {
        const uint32_t *f = v.full_tris + 3 * i;
        if (!tri_map_add(&w.diff, v.rep[f[0]], v.rep[f[1]], v.rep[f[2]], -1))
            goto nomem;
    }
    for (uint32_t s = 0; s < m->strip_count; s++) {
        if (!add_strip(&w, &up, s, 1))
            goto nomem;
    }

    /* up from the base: invariant 1 at every sampled level; state sums kept */
    for (uint32_t l = 0;; l++) {
        sums[l][0] = w.sum[0];
        sums[l][1] = w.sum[1];
        if (sampled[l]) {
            if (w.diff.nonzero != 0) {
                rc = check_level(&v, &up, report, err);
                if (rc == MTS_OK) /* cannot happen: the exact check agrees */
                    rc = mts_error_set(err, MTS_ERR_INTERNAL,
                                       "verify: level %u: incremental and exact checks disagree", l);
                goto done;
            }
            report->levels_checked++;
        }
        if (l == n)
            break;
        /* the strips this record names leave D before it applies, and come back after */
        const uint32_t *p = m->record_data + m->record_offsets[l],
                       *end = m->record_data + m->record_offsets[l + 1];
        uint32_t edits = *p++, named = 0;
        w.now++;
        for (uint32_t e = 0; e < edits && p; e++) {
            uint32_t s;
            p = mts_record_skip_edit(p, end, &s);
            if (p && s < m->strip_count && w.strip_stamp[s] != w.now) {
                w.strip_stamp[s] = w.now;
                w.named[named++] = s;
            }
        }
        for (uint32_t k = 0; k < named; k++) {
            if (!add_strip(&w, &up, w.named[k], -1))
                goto nomem;
        }
        if ((rc = mts_lod_split(&up, err)) != MTS_OK)
            goto done;
        for (uint32_t k = 0; k < named; k++) {
            if (!add_strip(&w, &up, w.named[k], 1))
                goto nomem;
        }
        mts_lod_clear_changed(&up);
        if (!reference_split(&w, &v, l))
            goto nomem;
        if ((l & 255) == 0)
            mts_progress_report(&opts->progress, "verify", 0.7 * l / (n ? n : 1));
    }

    /* down from the full level: the same strips at every sampled level */
    uint64_t total[2] = {0, 0};
    for (uint32_t s = 0; s < m->strip_count; s++) {
        uint32_t len;
        const uint32_t *str = mts_lod_strip(&down, s, &len);
        strip_hash(s, str, len, w.strip_h[s]);
        total[0] += w.strip_h[s][0];
        total[1] += w.strip_h[s][1];
    }
    mts_lod_clear_changed(&down);
    for (uint32_t l = n;; l--) {
        if (sampled[l] && (total[0] != sums[l][0] || total[1] != sums[l][1])) {
            /* find the strip: bring 'up' to the same level and compare */
            if ((rc = mts_lod_set_level(&up, l, err)) != MTS_OK)
                goto done;
            report->failed_level = l;
            for (uint32_t s = 0; s < m->strip_count; s++) {
                uint32_t la, lb;
                const uint32_t *a = mts_lod_strip(&up, s, &la);
                const uint32_t *b = mts_lod_strip(&down, s, &lb);
                if (la != lb || memcmp(a, b, (size_t)la * 4) != 0) {
                    report->failed_strip = s;
                    break;
                }
            }
            rc = mts_error_set(err, MTS_ERR_INVARIANT,
                               "level %u, strip %u: refining up from the base and coarsening "
                               "down from the full level give different strips",
                               l, report->failed_strip);
            goto done;
        }
        if (l == 0)
            break;
        mts_lod_collapse(&down);
        uint32_t nc;
        const uint32_t *changed = mts_lod_changed(&down, &nc);
        for (uint32_t c = 0; c < nc; c++) {
            uint32_t s = changed[c], len;
            const uint32_t *str = mts_lod_strip(&down, s, &len);
            total[0] -= w.strip_h[s][0];
            total[1] -= w.strip_h[s][1];
            strip_hash(s, str, len, w.strip_h[s]);
            total[0] += w.strip_h[s][0];
            total[1] += w.strip_h[s][1];
        }
        mts_lod_clear_changed(&down);
        if ((l & 255) == 0)
            mts_progress_report(&opts->progress, "verify", 0.7 + 0.3 * (n - l) / (n ? n : 1));
    }
    mts_progress_report(&opts->progress, "verify", 1.0);
    rc = MTS_OK;
    goto done;
nomem:
    rc = mts_error_set(err, MTS_ERR_NOMEM, "verify: out of memory");
done:
    mts_lod_free(&up);
    mts_lod_free(&down);
    walk_free(&w);
    verifier_free(&v);
    free(sums);
    free(sampled);
    return rc;
}

/* Derives every record from the descriptions with the full strips given as
 * gf, comparing each with the model's; leaves g at the full level. */
static mts_result derive_all(const mts_model *m, const mts_grow_full *gf, mts_grow **gout,
                             mts_verify_report *rep, mts_error *err)
{
    const uint32_t n = m->level_count;
    mts_grow_options go = {0};
    go.key_levels = m->key_levels;
    go.key_count = m->key_count;
    mts_grow *g = NULL;
    mts_result rc = mts_grow_create(&m->base, m->base_vertex_count, n, &go, &g, err);
    if (rc != MTS_OK)
        return rc;
    rep->levels_checked = 0;
    for (uint32_t j = 0; j < n && rc == MTS_OK; j++) {
        mts_grow_split sp;
        const uint32_t *r;
        uint32_t words;
        rep->failed_level = j;
        if (!mts_grow_model_split(g, m, j, &sp)) {
            rc = mts_error_set(err, MTS_ERR_INVARIANT, "growth: split %u's description names no "
                               "fan of the mesh", j);
            break;
        }
        if ((rc = mts_grow_next(g, &sp, gf, &r, &words, err)) != MTS_OK) {
            mts_error_prefix(err, "growth");
            break;
        }
        uint32_t want = m->record_offsets[j + 1] - m->record_offsets[j];
        if (words != want ||
            memcmp(r, m->record_data + m->record_offsets[j], (size_t)words * 4) != 0)
            rc = mts_error_set(err, MTS_ERR_INVARIANT,
                               "growth: split %u derives a record of %u words that differs from "
                               "the model's %u",
                               j, words, want);
        rep->levels_checked++;
    }
    if (rc == MTS_OK)
        rep->failed_level = UINT32_MAX;
    *gout = g;
    return rc;
}

mts_result mts_verify_growth(const mts_model *m, mts_verify_report *report, mts_error *err)
{
    mts_verify_report rep = {0, 0, UINT32_MAX};
    if (!m->growth_offsets || !m->growth_data)
        return mts_error_set(err, MTS_ERR_ARG, "the model has no split descriptions");
    /* As the builder: the full strips given whole. Then as a client, which
     * gets them described on the full level's triangles (mts_grow_full_
     * describe, which needs a grow at the full level: the first pass's). */
    mts_grow_full given = {.strips = &m->full, .slot_count = 0};
    mts_grow *g = NULL, *again = NULL;
    mts_grow_full_path *paths = malloc(((size_t)m->strip_count + 1) * sizeof *paths);
    uint8_t *swaps = malloc((size_t)m->full.index_count + 1);
    mts_result rc = paths && swaps ? derive_all(m, &given, &g, &rep, err)
                                   : mts_error_set(err, MTS_ERR_NOMEM, "verify: out of memory");
    uint64_t swap_count = 0;
    if (rc == MTS_OK && m->level_count > 0 &&
        mts_grow_full_describe(g, &m->full, paths, swaps, &swap_count, err) != MTS_OK) {
        /* not the model a stream could send: an invariant, not bad input */
        mts_error_prefix(err, "growth");
        rc = MTS_ERR_INVARIANT;
        if (err)
            err->code = rc;
    }
    if (rc == MTS_OK && m->level_count > 0) {
        mts_grow_full described = {.paths = paths, .swaps = swaps, .swap_count = swap_count, .slot_count = m->strip_count};
        rc = derive_all(m, &described, &again, &rep, err);
    }
    mts_grow_free(g);
    mts_grow_free(again);
    free(paths);
    free(swaps);
    if (report)
        *report = rep;
    return rc;
}
