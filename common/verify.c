#include "verify.h"

#include <stdlib.h>
#include <string.h>

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

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

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
        qsort(s->keys, s->count, 8, cmp_u64);
    else
        qsort(s->wide, s->count, 12, mts_tri_compare);
}

static int set_contains(const tri_set *s, int packed, uint32_t t[3])
{
    mts_tri_canonical(t);
    if (packed) {
        uint64_t k = (uint64_t)t[0] << 42 | (uint64_t)t[1] << 21 | t[2];
        return bsearch(&k, s->keys, s->count, 8, cmp_u64) != NULL;
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
    size_t windows = 0;
    for (uint32_t s = 0; s < m->strip_count; s++) {
        uint32_t len = m->full.offsets[s + 1] - m->full.offsets[s];
        windows += len >= 3 ? len - 2 : 0;
    }
    /* a runtime strip never has more windows than at the full level */
    v->full_tris = malloc((windows + 1) * 12);
    v->rep = malloc(((size_t)m->vertex_count + 1) * 4);
    if (v->packed) {
        v->ref.keys = malloc((windows + 1) * 8);
        v->got.keys = malloc((windows + 1) * 8);
    } else {
        v->ref.wide = malloc((windows + 1) * 12);
        v->got.wide = malloc((windows + 1) * 12);
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

/* Two independent 64-bit hashes (FNV-1a and a multiply-xorshift mix) of the
 * whole strip state. */
static void state_hash(const mts_lod *lod, uint64_t h[2])
{
    uint64_t a = 0xcbf29ce484222325ull, b = 0x9e3779b97f4a7c15ull;
    for (uint32_t s = 0; s < lod->strip_count; s++) {
        uint32_t len;
        const uint32_t *str = mts_lod_strip(lod, s, &len);
        a = (a ^ (0x100000000ull | len)) * 0x100000001b3ull;
        b = (b ^ len ^ ((uint64_t)s << 32)) * 0xff51afd7ed558ccdull;
        b ^= b >> 29;
        for (uint32_t k = 0; k < len; k++) {
            a = (a ^ str[k]) * 0x100000001b3ull;
            b = (b ^ str[k]) * 0xc4ceb9fe1a85ec53ull;
            b ^= b >> 31;
        }
    }
    h[0] = a;
    h[1] = b;
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
    const uint32_t n = m->level_count;
    uint32_t samples = opts->samples == 0 || opts->samples > n + 1 ? n + 1 : opts->samples;
    if (samples < 2)
        samples = n > 0 ? 2 : 1;

    verifier v;
    mts_lod up = {0}, down = {0};
    uint64_t *hashes = malloc((size_t)samples * 16);
    mts_result rc = verifier_init(&v, m, err);
    if (rc != MTS_OK) {
        free(hashes);
        return rc;
    }
    if (!hashes) {
        rc = mts_error_set(err, MTS_ERR_NOMEM, "verify: out of memory");
        goto done;
    }
    if ((rc = mts_lod_init(&up, m, MTS_LOD_AT_BASE, err)) != MTS_OK ||
        (rc = mts_lod_init(&down, m, MTS_LOD_AT_FULL, err)) != MTS_OK)
        goto done;

    /* up from the base: invariant 1 at every sampled level, and its hash */
    for (uint32_t i = 0; i < samples; i++) {
        uint32_t l = sample_level(i, samples, n);
        if ((rc = mts_lod_set_level(&up, l, err)) != MTS_OK)
            goto done;
        if ((rc = check_level(&v, &up, report, err)) != MTS_OK)
            goto done;
        state_hash(&up, hashes + (size_t)2 * i);
        report->levels_checked++;
        mts_progress_report(&opts->progress, "verify", 0.5 * (i + 1) / samples);
    }
    /* down from the full level: the same strips at the same levels */
    for (uint32_t i = samples; i-- > 0;) {
        uint32_t l = sample_level(i, samples, n);
        mts_lod_set_level(&down, l, NULL);
        uint64_t h[2];
        state_hash(&down, h);
        if (h[0] != hashes[(size_t)2 * i] || h[1] != hashes[(size_t)2 * i + 1]) {
            /* find the strip: bring 'up' to the same level and compare */
            mts_lod_free(&up);
            if ((rc = mts_lod_init(&up, m, MTS_LOD_AT_BASE, err)) != MTS_OK ||
                (rc = mts_lod_set_level(&up, l, err)) != MTS_OK)
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
        mts_progress_report(&opts->progress, "verify", 0.5 + 0.5 * (samples - i) / samples);
    }
    rc = MTS_OK;
done:
    mts_lod_free(&up);
    mts_lod_free(&down);
    verifier_free(&v);
    free(hashes);
    return rc;
}
