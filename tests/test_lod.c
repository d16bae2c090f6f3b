/* The LOD builder and runtime on real meshes: DESIGN.md invariants 1 and 2 at
 * every level of cow and at 500 sampled levels of bunny00 and fandisk_large,
 * coherence (only the strips a record names change, and they are reported),
 * and random walks in both directions. */
#include <math.h>
#include <stdint.h>

#include "build.h"
#include "lod.h"
#include "mesh.h"
#include "model.h"
#include "modelfile.h"
#include "test.h"
#include "verify.h"

static int build_from(mts_test *t, const char *path, mts_model *m)
{
    mts_error err = {0};
    mts_mesh mesh = {0};
    if (mts_mesh_load(path, NULL, &mesh, NULL, &err) != MTS_OK) {
        CHECKF(t, 0, "load %s: %s", path, err.msg);
        return 0;
    }
    mts_result rc = mts_build_model(&mesh, path, NULL, m, NULL, &err);
    mts_mesh_free(&mesh);
    CHECKF(t, rc == MTS_OK, "build %s: %s", path, err.msg);
    return rc == MTS_OK;
}

/* The exact, from-scratch check of invariant 1 (sorted triangle lists) at
 * `exact` levels spread evenly, independent of the incremental walk that
 * mts_verify_model uses: the two methods check each other. */
static void exact_check_levels(mts_test *t, const mts_model *m, uint32_t exact)
{
    mts_error err = {0};
    mts_lod lod;
    CHECK(t, mts_lod_init(&lod, m, MTS_LOD_AT_BASE, &err) == MTS_OK);
    uint32_t n = m->level_count;
    if (exact > n + 1)
        exact = n + 1;
    for (uint32_t i = 0; i < exact && !t->case_failed; i++) {
        uint32_t l = exact > 1 ? (uint32_t)((uint64_t)i * n / (exact - 1)) : n;
        CHECK(t, mts_lod_set_level(&lod, l, &err) == MTS_OK);
        mts_verify_report rep;
        CHECKF(t, mts_verify_level(m, &lod, &rep, &err) == MTS_OK, "level %u: %s", l, err.msg);
    }
    mts_lod_free(&lod);
}

static void check_model_invariants(mts_test *t, mts_model *m, uint32_t samples)
{
    mts_error err = {0};
    CHECKF(t, mts_model_validate(m, &err) == MTS_OK, "validate: %s", err.msg);
    mts_verify_options vo = {0};
    vo.samples = samples;
    mts_verify_report rep;
    mts_result rc = mts_verify_model(m, &vo, &rep, &err);
    CHECKF(t, rc == MTS_OK, "verify: %s", err.msg);
    uint32_t want = samples ? samples : m->level_count + 1;
    CHECKF(t, rep.levels_checked == want, "checked %u levels, wanted %u", rep.levels_checked, want);
}

static void check_basic_shape(mts_test *t, const mts_model *m, uint32_t vertices,
                              uint32_t triangles)
{
    uint32_t n = m->level_count;
    CHECK(t, m->vertex_count == vertices);
    CHECK(t, m->level_triangles[n] == triangles);
    /* default stop: max(4, 1%) of the vertices, or no legal collapse left */
    uint32_t target = vertices / 100 > 4 ? vertices / 100 : 4;
    CHECKF(t, m->base_vertex_count >= target, "base %u below target %u", m->base_vertex_count, target);
    CHECKF(t, m->base_vertex_count <= target + vertices / 50, "base %u far above target %u",
           m->base_vertex_count, target);
    for (uint32_t l = 0; l < n; l++) {
        CHECK(t, m->level_triangles[l] < m->level_triangles[l + 1]);
        CHECK(t, m->parents[l] < m->base_vertex_count + l);
    }
}

static void test_cow_every_level(mts_test *t)
{
    mts_model m;
    if (!build_from(t, "tests/data/cow.off", &m))
        return;
    check_basic_shape(t, &m, 2904, 5804);
    check_model_invariants(t, &m, 0);
    exact_check_levels(t, &m, m.level_count + 1);
    mts_model_free(&m);
}

static void sampled_model(mts_test *t, const char *name, uint32_t v, uint32_t tri)
{
    char buf[1024];
    const char *path = mts_test_model(name, buf, sizeof buf);
    if (!path)
        SKIP(t, "%s not found (set MTS_MODELS or put ../shared/models beside the project)", buf);
    mts_model m;
    if (!build_from(t, path, &m))
        return;
    check_basic_shape(t, &m, v, tri);
    check_model_invariants(t, &m, 500);      /* the dense sample */
    check_model_invariants(t, &m, 0);        /* and every level, which the walk makes cheap */
    exact_check_levels(t, &m, 100);
    mts_model_free(&m);
}

/* Verification must fail, and say where, when the strips are wrong. */
static void test_verify_detects_winding_flip(mts_test *t)
{
    mts_model m;
    if (!build_from(t, "tests/data/cow.off", &m))
        return;
    /* swap the first two indices of a base strip: its triangles turn over */
    uint32_t s = 0, tri[3];
    while (s < m.strip_count && (m.base.offsets[s + 1] - m.base.offsets[s] < 4 ||
                                 !mts_strip_window(m.base.indices + m.base.offsets[s], 0, tri)))
        s++;
    CHECK(t, s < m.strip_count);
    uint32_t *str = m.base.indices + m.base.offsets[s];
    uint32_t x = str[0];
    str[0] = str[1];
    str[1] = x;
    mts_error err = {0};
    mts_verify_report rep;
    CHECK(t, mts_verify_model(&m, NULL, &rep, &err) == MTS_ERR_INVARIANT);
    CHECKF(t, rep.failed_level == 0 && rep.failed_strip == s, "failed at level %u strip %u (%s)",
           rep.failed_level, rep.failed_strip, err.msg);
    CHECKF(t, strstr(err.msg, "level 0") != NULL, "%s", err.msg);
    mts_model_free(&m);
}

static void test_verify_detects_up_down_mismatch(mts_test *t)
{
    mts_model m;
    if (!build_from(t, "tests/data/cow.off", &m))
        return;
    /* one more (degenerate) index at the end of a full strip: the same
     * triangles, but coarsening down from it cannot match refining up */
    uint32_t target = m.strip_count / 2;
    mts_strips grown;
    mts_error err = {0};
    CHECK(t, mts_strips_alloc(&grown, m.strip_count, m.full.index_count + 1, &err) == MTS_OK);
    uint32_t o = 0;
    for (uint32_t s = 0; s < m.strip_count; s++) {
        grown.offsets[s] = o;
        uint32_t len = m.full.offsets[s + 1] - m.full.offsets[s];
        memcpy(grown.indices + o, m.full.indices + m.full.offsets[s], (size_t)len * 4);
        o += len;
        if (s == target) {
            grown.indices[o] = grown.indices[o - 1];
            o++;
        }
    }
    grown.offsets[m.strip_count] = o;
    mts_strips_free(&m.full);
    m.full = grown;
    mts_verify_report rep;
    CHECK(t, mts_verify_model(&m, NULL, &rep, &err) == MTS_ERR_INVARIANT);
    CHECKF(t, rep.failed_level == m.level_count && rep.failed_strip == target,
           "failed at level %u strip %u (%s)", rep.failed_level, rep.failed_strip, err.msg);
    mts_model_free(&m);
}

static void test_bunny_sampled(mts_test *t)
{
    sampled_model(t, "bunny00.off", 37706, 75408);
}

static void test_fandisk_sampled(mts_test *t)
{
    sampled_model(t, "fandisk_large.off", 15843, 31682);
}

/* Deterministic pseudo-random numbers for the walks. */
static uint32_t rng_next(uint64_t *s)
{
    *s = *s * 6364136223846793005ull + 1442695040888963407ull;
    return (uint32_t)(*s >> 33);
}

/* Moving between random levels: the strips at a level do not depend on the
 * path taken, every strip that differs is reported changed, and nothing is
 * reported that no record between the two levels names. */
static void test_cow_random_walk_coherence(mts_test *t)
{
    mts_model m;
    if (!build_from(t, "tests/data/cow.off", &m))
        return;
    mts_error err = {0};
    mts_lod walk, fresh;
    CHECK(t, mts_lod_init(&walk, &m, MTS_LOD_AT_BASE, &err) == MTS_OK);
    uint32_t *snap = malloc(((size_t)m.full.index_count + 1) * 4);
    uint32_t *snap_len = malloc(((size_t)m.strip_count + 1) * 4);
    uint8_t *named = malloc((size_t)m.strip_count + 1);
    uint64_t seed = 12345;
    for (int step = 0; step < 60 && !t->case_failed; step++) {
        uint32_t target = rng_next(&seed) % (m.level_count + 1);
        memcpy(snap, walk.data, (size_t)m.full.index_count * 4);
        memcpy(snap_len, walk.length, (size_t)m.strip_count * 4);
        uint32_t from = walk.level;
        mts_lod_clear_changed(&walk);
        CHECK(t, mts_lod_set_level(&walk, target, &err) == MTS_OK);
        CHECK(t, walk.level == target);
        /* strips named by the records crossed */
        memset(named, 0, m.strip_count);
        uint32_t lo = from < target ? from : target, hi = from < target ? target : from;
        for (uint32_t j = lo; j < hi; j++) {
            const uint32_t *p = m.record_data + m.record_offsets[j];
            uint32_t edits = *p++;
            for (uint32_t e = 0; e < edits; e++) {
                named[p[0]] = 1;
                uint32_t ins = p[1], sub = p[2];
                p += 3;
                for (uint32_t k = 0; k < ins; k++)
                    p += 2 + p[1];
                p += sub;
            }
        }
        uint32_t nc;
        const uint32_t *changed = mts_lod_changed(&walk, &nc);
        uint8_t *is_changed = calloc((size_t)m.strip_count + 1, 1);
        for (uint32_t c = 0; c < nc; c++) {
            CHECKF(t, named[changed[c]], "strip %u reported changed but no record names it",
                   changed[c]);
            CHECKF(t, !is_changed[changed[c]], "strip %u reported twice", changed[c]);
            is_changed[changed[c]] = 1;
        }
        for (uint32_t s = 0; s < m.strip_count; s++) {
            uint32_t len;
            const uint32_t *now = mts_lod_strip(&walk, s, &len);
            int differs = len != snap_len[s] || memcmp(now, snap + walk.slot[s], (size_t)len * 4) != 0;
            if (differs)
                CHECKF(t, is_changed[s], "strip %u changed but was not reported", s);
        }
        free(is_changed);
        /* the same level reached straight from the base */
        CHECK(t, mts_lod_init(&fresh, &m, MTS_LOD_AT_BASE, &err) == MTS_OK);
        CHECK(t, mts_lod_set_level(&fresh, target, &err) == MTS_OK);
        for (uint32_t s = 0; s < m.strip_count; s++) {
            uint32_t la, lb;
            const uint32_t *a = mts_lod_strip(&walk, s, &la);
            const uint32_t *b = mts_lod_strip(&fresh, s, &lb);
            CHECKF(t, la == lb && memcmp(a, b, (size_t)la * 4) == 0,
                   "level %u strip %u depends on the path", target, s);
            if (t->case_failed)
                break;
        }
        mts_lod_free(&fresh);
    }
    free(snap);
    free(snap_len);
    free(named);
    mts_lod_free(&walk);
    mts_model_free(&m);
}

/* A record that does not fit the strips is refused with a message naming it,
 * and the runtime refuses to go on. */
static void test_runtime_rejects_bad_record(mts_test *t)
{
    mts_model m;
    if (!build_from(t, "tests/data/cow.off", &m))
        return;
    mts_error err = {0};
    mts_lod lod;
    CHECK(t, mts_lod_init(&lod, &m, MTS_LOD_AT_BASE, &err) == MTS_OK);
    /* find a record with a substitution and point it past its strip */
    uint32_t j = m.level_count / 2;
    uint32_t *p = m.record_data + m.record_offsets[j];
    uint32_t *sub = p + 1 + 3;
    for (uint32_t k = 0; k < p[2]; k++)
        sub += 2 + sub[1];
    /* layout: edit_count, then strip, insert_count, subst_count, ... */
    CHECK(t, p[0] >= 1);
    CHECK(t, p[3] >= 1);
    if (p[3] > 0) {
        uint32_t saved = *sub;
        *sub = 0xFFFFFFF0u;
        CHECK(t, mts_lod_set_level(&lod, m.level_count, &err) == MTS_ERR_RANGE);
        CHECKF(t, strstr(err.msg, "split") != NULL, "message: %s", err.msg);
        CHECK(t, lod.level == j);
        CHECK(t, lod.broken);
        CHECK(t, mts_lod_set_level(&lod, 0, &err) != MTS_OK);
        *sub = saved;
        CHECK(t, mts_model_validate(&m, &err) == MTS_OK);
    }
    mts_lod_free(&lod);
    mts_model_free(&m);
}

/* A model written out by hand: 4 vertices (3 base), one strip, one split
 * whose record is given; the level table is filled from the strips. */
static uint32_t *copy_words(const uint32_t *w, size_t n)
{
    uint32_t *c = malloc((n + 1) * sizeof *c);
    if (c && n)
        memcpy(c, w, n * sizeof *c);
    return c;
}

static uint32_t count_triangles(const uint32_t *s, uint32_t n)
{
    uint32_t t = 0;
    for (uint32_t k = 0; k + 2 < n; k++)
        t += s[k] != s[k + 1] && s[k + 1] != s[k + 2] && s[k] != s[k + 2];
    return t;
}

static void hand_model(mts_model *m, const uint32_t *base, uint32_t base_len,
                       const uint32_t *full, uint32_t full_len, const uint32_t *rec,
                       uint32_t rec_len)
{
    memset(m, 0, sizeof *m);
    m->vertex_count = 4;
    m->base_vertex_count = 3;
    m->level_count = 1;
    m->strip_count = 1;
    m->positions = calloc(12, sizeof(float));
    m->normals = calloc(12, sizeof(float));
    for (int i = 0; i < 4; i++)
        m->positions[3 * i + (i % 3)] = 1.0f;
    const uint32_t parent = 0;
    m->parents = copy_words(&parent, 1);
    mts_strips_alloc(&m->base, 1, base_len, NULL);
    m->base.offsets[1] = base_len;
    memcpy(m->base.indices, base, base_len * 4);
    mts_strips_alloc(&m->full, 1, full_len, NULL);
    m->full.offsets[1] = full_len;
    memcpy(m->full.indices, full, full_len * 4);
    const uint32_t offsets[2] = {0, rec_len};
    m->record_offsets = copy_words(offsets, 2);
    m->record_data = copy_words(rec, rec_len);
    m->record_word_count = rec_len;
    const uint32_t tris[2] = {count_triangles(base, base_len), count_triangles(full, full_len)};
    const uint32_t strips[2] = {base_len > 0, full_len > 0};
    const uint32_t indices[2] = {base_len, full_len};
    m->level_triangles = copy_words(tris, 2);
    m->level_strips = copy_words(strips, 2);
    m->level_indices = copy_words(indices, 2);
    m->bbox_max[0] = m->bbox_max[1] = m->bbox_max[2] = 1.0f;
}

/* A record may name one strip in two edits: the second edit's positions are
 * in the strip as the first left it, so a collapse must undo the edits last
 * to first. (Undone first to last, the second run was removed from the
 * wrong place and, here, from past the strip's end: a wild memmove.) */
static void test_collapse_undoes_edits_in_reverse(mts_test *t)
{
    const uint32_t base[] = {0, 1, 2};
    const uint32_t full[] = {0, 1, 2, 1, 2, 0, 1};
    const uint32_t rec[] = {2,                      /* edits */
                            0, 1, 0, 3, 2, 1, 2,    /* strip 0: insert (1 2) at 3 */
                            0, 1, 0, 5, 2, 0, 1};   /* strip 0: insert (0 1) at 5 */
    mts_model m;
    hand_model(&m, base, 3, full, 7, rec, 15);
    mts_error err = {0};
    CHECKF(t, mts_model_validate(&m, &err) == MTS_OK, "validate: %s", err.msg);
    for (int start = 0; start < 2; start++) {
        mts_lod lod;
        CHECK(t, mts_lod_init(&lod, &m, start ? MTS_LOD_AT_FULL : MTS_LOD_AT_BASE, &err) == MTS_OK);
        for (int round = 0; round < 2; round++) {
            CHECK(t, mts_lod_set_level(&lod, 1, &err) == MTS_OK);
            uint32_t len;
            const uint32_t *s = mts_lod_strip(&lod, 0, &len);
            CHECK(t, len == 7 && memcmp(s, full, sizeof full) == 0);
            CHECK(t, mts_lod_set_level(&lod, 0, &err) == MTS_OK);
            s = mts_lod_strip(&lod, 0, &len);
            CHECKF(t, len == 3 && memcmp(s, base, sizeof base) == 0,
                   "collapse left length %u", len);
        }
        mts_lod_free(&lod);
    }
    mts_model_free(&m);
}

/* The bounding box travels in the file and sets the quantization grid, so a
 * model whose box is not finite or does not hold its positions is refused. */
static void test_validate_checks_bbox(mts_test *t)
{
    const uint32_t base[] = {0, 1, 2};
    const uint32_t full[] = {0, 1, 2, 3};
    /* strip 0: insert (0) at 3, then position 3 becomes vertex 3 */
    const uint32_t rec[] = {1, 0, 1, 1, 3, 1, 0, 3};
    mts_model m;
    hand_model(&m, base, 3, full, 4, rec, 8);
    mts_error err = {0};
    CHECKF(t, mts_model_validate(&m, &err) == MTS_OK, "validate: %s", err.msg);
    m.bbox_max[1] = 0.5f;
    CHECK(t, mts_model_validate(&m, &err) == MTS_ERR_FORMAT);
    CHECKF(t, strstr(err.msg, "outside the bounding box") != NULL, "message: %s", err.msg);
    m.bbox_max[1] = 1.0f;
    m.bbox_min[2] = NAN;
    CHECK(t, mts_model_validate(&m, &err) == MTS_ERR_FORMAT);
    CHECKF(t, strstr(err.msg, "bounding box is not finite") != NULL, "message: %s", err.msg);
    mts_model_free(&m);
}

/* Any record set that mts_model_validate accepts, the runtime must walk both
 * ways: small random models (random base strips, random records applied by a
 * naive reference, which also gives the full strips and the level table),
 * then random walks from either end compared with the reference at every
 * level reached. Records here name a strip in several edits, insert empty
 * runs and substitute inside inserted runs, which the builder never does. */
enum { PROP_STRIPS = 4, PROP_LEN = 64 };
typedef struct prop_state {
    uint32_t len[PROP_STRIPS];
    uint32_t d[PROP_STRIPS][PROP_LEN];
} prop_state;

static void test_random_records_walk_both_ways(mts_test *t)
{
    uint64_t seed = 99;
    for (int it = 0; it < 3000 && !t->case_failed; it++) {
        uint32_t nb = 2 + rng_next(&seed) % 3, n = 1 + rng_next(&seed) % 6;
        uint32_t ns = 1 + rng_next(&seed) % PROP_STRIPS;
        prop_state *snap = calloc(n + 1, sizeof *snap);
        uint32_t *parents = malloc(n * 4), *roff = malloc((n + 1) * 4);
        uint32_t *rec = malloc(4096 * 4), w = 0;
        prop_state cur = {0};
        for (uint32_t s = 0; s < ns; s++) {
            cur.len[s] = rng_next(&seed) % 5;
            for (uint32_t k = 0; k < cur.len[s]; k++)
                cur.d[s][k] = rng_next(&seed) % nb;
        }
        snap[0] = cur;
        for (uint32_t j = 0; j < n; j++) {
            uint32_t v = nb + j, u = rng_next(&seed) % v;
            parents[j] = u;
            roff[j] = w;
            uint32_t edits = rng_next(&seed) % 4;
            rec[w++] = edits;
            for (uint32_t e = 0; e < edits; e++) {
                uint32_t s = rng_next(&seed) % ns, at = w, ins = rng_next(&seed) % 3, sub = 0;
                w += 3;
                for (uint32_t k = 0; k < ins; k++) {
                    uint32_t run = rng_next(&seed) % 4, pos = rng_next(&seed) % (cur.len[s] + 1);
                    if (cur.len[s] + run > PROP_LEN)
                        run = 0;
                    rec[w++] = pos;
                    rec[w++] = run;
                    memmove(cur.d[s] + pos + run, cur.d[s] + pos, (cur.len[s] - pos) * 4);
                    for (uint32_t r = 0; r < run; r++) {
                        uint32_t x = rng_next(&seed) % 4 ? u : rng_next(&seed) % v;
                        cur.d[s][pos + r] = rec[w++] = x;
                    }
                    cur.len[s] += run;
                }
                for (uint32_t k = 0; k < cur.len[s]; k++) {
                    if (cur.d[s][k] == u && rng_next(&seed) % 2) {
                        cur.d[s][k] = v;
                        rec[w++] = k;
                        sub++;
                    }
                }
                rec[at] = s;
                rec[at + 1] = ins;
                rec[at + 2] = sub;
            }
            snap[j + 1] = cur;
        }
        roff[n] = w;

        mts_model m = {0};
        m.vertex_count = nb + n;
        m.base_vertex_count = nb;
        m.level_count = n;
        m.strip_count = ns;
        m.positions = calloc(3 * (size_t)m.vertex_count, sizeof(float));
        m.normals = calloc(3 * (size_t)m.vertex_count, sizeof(float));
        m.parents = parents;
        m.record_offsets = roff;
        m.record_data = rec;
        m.record_word_count = w;
        mts_strips *sets[2] = {&m.base, &m.full};
        const prop_state *ends[2] = {&snap[0], &snap[n]};
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
        m.level_triangles = malloc((n + 1) * 4);
        m.level_strips = malloc((n + 1) * 4);
        m.level_indices = malloc((n + 1) * 4);
        for (uint32_t l = 0; l <= n; l++) {
            uint32_t tr = 0, st = 0, ix = 0;
            for (uint32_t s = 0; s < ns; s++) {
                tr += count_triangles(snap[l].d[s], snap[l].len[s]);
                st += snap[l].len[s] > 0;
                ix += snap[l].len[s];
            }
            m.level_triangles[l] = tr;
            m.level_strips[l] = st;
            m.level_indices[l] = ix;
        }

        mts_error err = {0};
        CHECKF(t, mts_model_validate(&m, &err) == MTS_OK, "model %d: validate: %s", it, err.msg);
        for (int start = 0; start < 2 && !t->case_failed; start++) {
            mts_lod lod;
            CHECK(t, mts_lod_init(&lod, &m, start ? MTS_LOD_AT_FULL : MTS_LOD_AT_BASE, &err) ==
                         MTS_OK);
            for (int step = 0; step < 12 && !t->case_failed; step++) {
                uint32_t target = rng_next(&seed) % (n + 1);
                CHECKF(t, mts_lod_set_level(&lod, target, &err) == MTS_OK, "model %d: %s", it,
                       err.msg);
                for (uint32_t s = 0; s < ns && !t->case_failed; s++) {
                    uint32_t len;
                    const uint32_t *x = mts_lod_strip(&lod, s, &len);
                    CHECKF(t, len == snap[target].len[s] &&
                                  memcmp(x, snap[target].d[s], (size_t)len * 4) == 0,
                           "model %d, level %u, strip %u differs (from the %s)", it, target, s,
                           start ? "full level" : "base");
                }
            }
            mts_lod_free(&lod);
        }
        mts_model_free(&m);
        free(snap);
    }
}

static void test_level_lookup(mts_test *t)
{
    mts_model m;
    if (!build_from(t, "tests/data/cow.off", &m))
        return;
    uint32_t n = m.level_count;
    CHECK(t, mts_model_level_for_fraction(&m, 1.0) == n);
    CHECK(t, mts_model_level_for_fraction(&m, 0.0) == 0);
    uint32_t half = mts_model_level_for_fraction(&m, 0.5);
    CHECK(t, m.base_vertex_count + half == (m.vertex_count + 1) / 2);
    CHECK(t, mts_model_level_for_triangles(&m, m.level_triangles[n]) == n);
    CHECK(t, mts_model_level_for_triangles(&m, 0) == 0);
    uint32_t l = mts_model_level_for_triangles(&m, 1000);
    CHECK(t, m.level_triangles[l] <= 1000 && (l == n || m.level_triangles[l + 1] > 1000));
    mts_model_free(&m);
}

int main(void)
{
    mts_test t = {0};
    RUN(&t, test_cow_every_level);
    RUN(&t, test_cow_random_walk_coherence);
    RUN(&t, test_runtime_rejects_bad_record);
    RUN(&t, test_level_lookup);
    RUN(&t, test_collapse_undoes_edits_in_reverse);
    RUN(&t, test_validate_checks_bbox);
    RUN(&t, test_random_records_walk_both_ways);
    RUN(&t, test_verify_detects_winding_flip);
    RUN(&t, test_verify_detects_up_down_mismatch);
    RUN(&t, test_bunny_sampled);
    RUN(&t, test_fandisk_sampled);
    return mts_test_end(&t);
}
