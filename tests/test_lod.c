/* The LOD builder and runtime on real meshes: the invariants 1 and 2 of docs/architecture.md at
 * every level of cow and at 500 sampled levels of bunny00 and fandisk_large,
 * coherence (only the strips a record names change, and they are reported),
 * and random walks in both directions; and the runtime on hand-made records
 * (tests/hand_model.h): erase runs, capacities, and every check a split
 * makes. */
#include <math.h>
#include <stdint.h>

#include "build.h"
#include "hand_model.h"
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
    check_model_invariants(t, &m, 500);      /* 500 sampled levels, as mts-inspect --sample */
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
     * triangles, but coarsening down from it cannot match refining up (a
     * strip with room for it in its slot, so that it is this that fails) */
    uint32_t target = m.strip_count / 2;
    while (target < m.strip_count &&
           m.full.offsets[target + 1] - m.full.offsets[target] >= m.capacity[target])
        target++;
    CHECK(t, target < m.strip_count);
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
    /* the slots, as long as the capacities (not the full strips) */
    const uint32_t slots = walk.slot[m.strip_count];
    uint32_t *snap = malloc(((size_t)slots + 1) * 4);
    uint32_t *snap_len = malloc(((size_t)m.strip_count + 1) * 4);
    uint8_t *named = malloc((size_t)m.strip_count + 1);
    uint64_t seed = 12345;
    for (int step = 0; step < 60 && !t->case_failed; step++) {
        uint32_t target = rng_next(&seed) % (m.level_count + 1);
        memcpy(snap, walk.data, (size_t)slots * 4);
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
                uint32_t runs = p[1] + p[2], sub = p[3];
                p += 4;
                for (uint32_t k = 0; k < runs; k++)
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
    /* find a record from the middle on with a substitution, and point it
     * past its strip (layout: edit_count, then strip, erase_count,
     * insert_count, subst_count, the runs, the positions) */
    uint32_t j = m.level_count / 2, *sub = NULL;
    for (; j < m.level_count && !sub; j++) {
        uint32_t *p = m.record_data + m.record_offsets[j];
        uint32_t edits = *p++;
        for (uint32_t e = 0; e < edits && !sub; e++) {
            uint32_t runs = p[1] + p[2], substs = p[3];
            p += 4;
            for (uint32_t k = 0; k < runs; k++)
                p += 2 + p[1];
            if (substs > 0)
                sub = p;
            p += substs;
        }
    }
    CHECK(t, sub != NULL);
    if (sub) {
        j--;
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

/* A record may name one strip in two edits: the second edit's positions are
 * in the strip as the first left it, so a collapse must undo the edits last
 * to first. (Undone first to last, the second run was removed from the
 * wrong place and, here, from past the strip's end: a wild memmove.) */
static void test_collapse_undoes_edits_in_reverse(mts_test *t)
{
    const uint32_t base[] = {0, 1, 2};
    const uint32_t full[] = {0, 1, 2, 1, 2, 0, 1};
    const uint32_t rec[] = {2,                         /* edits */
                            0, 0, 1, 0, 3, 2, 1, 2,    /* strip 0: insert (1 2) at 3 */
                            0, 0, 1, 0, 5, 2, 0, 1};   /* strip 0: insert (0 1) at 5 */
    mts_model m;
    hand_model_one_split(&m, base, 3, full, 7, rec, 17);
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

/* A runtime's slots and scratch past a megabyte live in reservations
 * (bigmem.h); one made from a cache after another takes the pages the
 * last one left, which still hold its indices, and its splits and
 * collapses must give the same strips. The record is padded with empty
 * edits (a runtime takes them) so that its scratch passes a megabyte. */
static void test_runtime_reuses_reservations(mts_test *t)
{
    enum { PAD = 1 << 16 };
    const uint32_t base[] = {0, 1, 2}, full[] = {0, 1, 2, 1, 3};
    const uint32_t head[] = {1 + PAD, 0, 0, 1, 1, 3, 2, 1, 0, 4}; /* insert (1 0) at 3, 4 -> v */
    const uint32_t words = 10 + 4 * PAD;
    uint32_t *rec = calloc(words, 4);
    CHECK(t, rec != NULL);
    if (!rec)
        return;
    memcpy(rec, head, sizeof head); /* then PAD edits of strip 0 that change nothing */
    mts_model m;
    hand_model_one_split(&m, base, 3, full, 5, rec, words);
    free(rec);
    m.capacity[0] = 1u << 18; /* a megabyte of slot */
    mts_bigmem_cache *cache = mts_bigmem_cache_create();
    CHECK(t, cache != NULL);
    void *left[2] = {NULL, NULL};
    for (int round = 0; round < 2; round++) {
        mts_lod lod;
        mts_error err = {0};
        CHECKF(t, mts_lod_init_with(&lod, &m, MTS_LOD_AT_BASE, cache, &err) == MTS_OK, "init: %s",
               err.msg);
        for (int k = 0; k < 3; k++) {
            CHECKF(t, mts_lod_set_level(&lod, 1, &err) == MTS_OK, "split: %s", err.msg);
            uint32_t len;
            const uint32_t *s = mts_lod_strip(&lod, 0, &len);
            CHECK(t, len == 5 && memcmp(s, full, sizeof full) == 0);
            CHECK(t, mts_lod_set_level(&lod, 0, &err) == MTS_OK);
            s = mts_lod_strip(&lod, 0, &len);
            CHECK(t, len == 3 && memcmp(s, base, sizeof base) == 0);
        }
#if defined(__linux__) && UINTPTR_MAX > 0xffffffffu
        CHECK(t, lod.data_mem.reserved > 0 && lod.scratch_mem.reserved > 0);
        if (round == 0) {
            left[0] = lod.data_mem.p;
            left[1] = lod.scratch_mem.p;
        } else {
            CHECK(t, lod.data_mem.p == left[0] || lod.data_mem.p == left[1]);
            CHECK(t, lod.scratch_mem.p == left[0] || lod.scratch_mem.p == left[1]);
        }
#endif
        mts_lod_free(&lod);
    }
    mts_bigmem_cache_free(cache);
    mts_model_free(&m);
}

/* The bounding box travels in the file and sets the quantization grid, so a
 * model whose box is not finite or does not hold its positions is refused. */
static void test_validate_checks_bbox(mts_test *t)
{
    const uint32_t base[] = {0, 1, 2};
    const uint32_t full[] = {0, 1, 2, 3};
    /* strip 0: insert (0) at 3, then position 3 becomes vertex 3 */
    const uint32_t rec[] = {1, 0, 0, 1, 1, 3, 1, 0, 3};
    mts_model m;
    hand_model_one_split(&m, base, 3, full, 4, rec, 9);
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

/* Walks the runtime over a model whose strips at every level are known, from
 * either end, to random levels and back, comparing every strip each time;
 * and checks the slots are the capacities. */
static void walk_against_states(mts_test *t, const mts_model *m, const hand_state *snap,
                                uint64_t *seed, int steps, const char *what)
{
    mts_error err = {0};
    for (int start = 0; start < 2 && !t->case_failed; start++) {
        mts_lod lod;
        CHECKF(t, mts_lod_init(&lod, m, start ? MTS_LOD_AT_FULL : MTS_LOD_AT_BASE, &err) == MTS_OK,
               "%s: init: %s", what, err.msg);
        if (t->case_failed)
            return;
        for (uint32_t s = 0; s < m->strip_count; s++)
            CHECK(t, lod.slot[s + 1] - lod.slot[s] == m->capacity[s]);
        for (int step = 0; step < steps && !t->case_failed; step++) {
            /* every other step to an end, so each end is reached often */
            uint32_t target = step % 2 ? hand_rng(seed) % (m->level_count + 1)
                                       : (step / 2) % 2 ? m->level_count : 0;
            CHECKF(t, mts_lod_set_level(&lod, target, &err) == MTS_OK, "%s: %s", what, err.msg);
            for (uint32_t s = 0; s < m->strip_count && !t->case_failed; s++) {
                uint32_t len;
                const uint32_t *x = mts_lod_strip(&lod, s, &len);
                CHECKF(t, len == snap[target].len[s] &&
                              memcmp(x, snap[target].d[s], (size_t)len * 4) == 0,
                       "%s, level %u, strip %u differs (from the %s)", what, target, s,
                       start ? "full level" : "base");
            }
        }
        mts_lod_free(&lod);
    }
}

/* Any record set that mts_model_validate accepts, the runtime must walk both
 * ways: small random models (tests/hand_model.h: records applied by a naive
 * reference, which also gives the strips at every level), then random walks
 * from either end compared with the reference at every level reached. */
static void test_random_records_walk_both_ways(mts_test *t)
{
    uint64_t seed = 99;
    for (int it = 0; it < 3000 && !t->case_failed; it++) {
        mts_model m;
        hand_state *snap = hand_random_model(&seed, 0, &m);
        mts_error err = {0};
        char what[32];
        snprintf(what, sizeof what, "model %d", it);
        CHECKF(t, mts_model_validate(&m, &err) == MTS_OK, "%s: validate: %s", what, err.msg);
        walk_against_states(t, &m, snap, &seed, 12, what);
        mts_model_free(&m);
        free(snap);
    }
}

/* One split that erases a run, inserts one and substitutes: the split gives
 * exactly the new strip and the collapse exactly the old one, again and
 * again, from either end. */
static void test_erase_insert_subst(mts_test *t)
{
    const uint32_t base[] = {1, 0, 2, 1};
    const uint32_t full[] = {1, 0, 2, 3, 1};
    const uint32_t rec[] = {1,             /* edits */
                            0, 1, 1, 1,    /* strip 0: 1 erase, 1 insert, 1 subst */
                            1, 2, 0, 2,    /*   erase (0 2) at 1: 1 1 */
                            1, 3, 0, 2, 0, /*   insert (0 2 0) at 1: 1 0 2 0 1 */
                            3};            /*   position 3: 0 -> 3 */
    mts_model m;
    hand_model_one_split(&m, base, 4, full, 5, rec, 15);
    mts_error err = {0};
    CHECKF(t, mts_model_validate(&m, &err) == MTS_OK, "validate: %s", err.msg);
    hand_state snap[2] = {0};
    snap[0].len[0] = 4;
    memcpy(snap[0].d[0], base, sizeof base);
    snap[1].len[0] = 5;
    memcpy(snap[1].d[0], full, sizeof full);
    uint64_t seed = 5;
    walk_against_states(t, &m, snap, &seed, 8, "erase-insert-subst");
    /* the collapse reports the strip changed, like the split */
    mts_lod lod;
    CHECK(t, mts_lod_init(&lod, &m, MTS_LOD_AT_FULL, &err) == MTS_OK);
    mts_lod_clear_changed(&lod);
    mts_lod_collapse(&lod);
    uint32_t nc;
    const uint32_t *changed = mts_lod_changed(&lod, &nc);
    CHECK(t, nc == 1 && changed[0] == 0 && lod.level == 0);
    mts_lod_free(&lod);
    mts_model_free(&m);
}

/* A split whose erased run is not what the strip holds is refused, naming
 * the split, the strip and the position; the runtime is then broken. */
static void test_erase_wrong_content_rejected(mts_test *t)
{
    mts_model m;
    hand_state snap[3];
    hand_model_erases(&m, snap);
    mts_error err = {0};
    CHECKF(t, mts_model_validate(&m, &err) == MTS_OK, "validate: %s", err.msg);
    /* split 1's erase from strip 0 says (2 1 3) at 2; make it (2 0 3) */
    uint32_t *erased = m.record_data + m.record_offsets[1] + 1 + 4 + 2;
    CHECK(t, erased[0] == 2 && erased[1] == 1 && erased[2] == 3);
    erased[1] = 0;
    CHECK(t, mts_model_validate(&m, &err) == MTS_ERR_RANGE);
    CHECKF(t, strstr(err.msg, "split 1: strip 0 position 3 holds 1, the record erases 0"),
           "message: %s", err.msg);
    mts_lod lod;
    CHECK(t, mts_lod_init(&lod, &m, MTS_LOD_AT_BASE, &err) == MTS_OK);
    CHECK(t, mts_lod_set_level(&lod, 2, &err) == MTS_ERR_RANGE);
    CHECK(t, lod.level == 1 && lod.broken);
    CHECKF(t, strstr(err.msg, "split 1") && strstr(err.msg, "strip 0") &&
                  strstr(err.msg, "position 3"),
           "message: %s", err.msg);
    CHECK(t, mts_lod_set_level(&lod, 0, &err) != MTS_OK);
    mts_lod_free(&lod);
    mts_model_free(&m);
}

/* Erases that reach past the strip, or past the record, are refused before
 * anything is read there (ASan watches). */
static void test_erase_out_of_bounds_rejected(mts_test *t)
{
    const struct {
        uint32_t pos, run;
        const char *needle;
    } cases[] = {
        {2, 2, "split 0: erase of 2 at 2 does not fit strip 0 (length 3)"},
        {4, 0, "split 0: erase of 0 at 4 does not fit strip 0 (length 3)"},
        {1, 0xFFFFFFFFu, "does not fit strip 0"},
        {0xFFFFFFFFu, 1, "does not fit strip 0"},
        {0, 3, "record ends inside an erase from strip 0"},
    };
    const uint32_t base[] = {0, 1, 2}, full[] = {0, 1, 2};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        /* strip 0: one erase, nothing else; for the last case the record
         * holds only 2 of the 3 indices it erases */
        const uint32_t rec[] = {1, 0, 1, 0, 0, cases[i].pos, cases[i].run, 0, 1};
        mts_model m;
        hand_model_one_split(&m, base, 3, full, 3, rec, 9);
        mts_error err = {0};
        CHECK(t, mts_model_validate(&m, &err) == MTS_ERR_RANGE);
        CHECKF(t, strstr(err.msg, cases[i].needle) != NULL, "case %zu: message: %s", i, err.msg);
        mts_model_free(&m);
    }
    /* a record that ends inside the erase header */
    const uint32_t rec[] = {1, 0, 1, 0, 0, 0};
    mts_model m;
    hand_model_one_split(&m, base, 3, full, 3, rec, 6);
    mts_error err = {0};
    CHECK(t, mts_model_validate(&m, &err) == MTS_ERR_RANGE);
    CHECKF(t, strstr(err.msg, "record ends inside an erase from strip 0"), "message: %s",
           err.msg);
    mts_model_free(&m);
}

/* Strip lengths are not monotone in the level: a slot longer at a middle
 * level than at either end, and one empty at the full level, work within
 * their capacities, which set the slots (not the full strips). */
static void test_capacity_longer_than_full(mts_test *t)
{
    mts_model m;
    hand_state snap[3];
    hand_model_erases(&m, snap);
    CHECK(t, m.capacity[0] == 5 && m.capacity[1] == 3);
    CHECK(t, m.full.offsets[1] == 2 && m.full.offsets[2] == 2);
    mts_error err = {0};
    CHECKF(t, mts_model_validate(&m, &err) == MTS_OK, "validate: %s", err.msg);
    uint64_t seed = 17;
    walk_against_states(t, &m, snap, &seed, 20, "erases model");
    mts_lod lod;
    CHECK(t, mts_lod_init(&lod, &m, MTS_LOD_AT_BASE, &err) == MTS_OK);
    CHECK(t, lod.slot[2] == 8);
    /* counts the capacities: slot, length, changed flag and list per strip */
    CHECK(t, mts_lod_memory_bytes(&lod) ==
                 3 * 13 + 8 * 4 + (uint64_t)lod.scratch_size * sizeof *lod.scratch);
    mts_lod_free(&lod);
    mts_model_free(&m);
}

/* A capacity smaller than a strip ever gets is refused: at the base or full
 * level by mts_model_validate (and at the start by mts_lod_init), in
 * between by the split that would overflow the slot; so is a model without
 * capacities, or with more than records could ever fill. */
static void test_capacity_exceeded_rejected(mts_test *t)
{
    mts_model m;
    hand_state snap[3];
    hand_model_erases(&m, snap);
    mts_error err = {0};
    mts_lod lod;

    m.capacity[0] = 4; /* level 1's strip 0 is 5 long */
    CHECK(t, mts_model_validate(&m, &err) == MTS_ERR_RANGE);
    CHECKF(t, strstr(err.msg, "split 0: insert of 2 at 3 does not fit strip 0 (length 3 of "
                              "capacity 4)"),
           "message: %s", err.msg);
    CHECK(t, mts_lod_init(&lod, &m, MTS_LOD_AT_BASE, &err) == MTS_OK);
    CHECK(t, mts_lod_set_level(&lod, 2, &err) == MTS_ERR_RANGE);
    CHECK(t, lod.level == 0 && lod.broken);
    mts_lod_free(&lod);

    m.capacity[0] = 2; /* the base strip is 3 long */
    CHECK(t, mts_model_validate(&m, &err) == MTS_ERR_RANGE);
    CHECKF(t, strstr(err.msg, "strip 0 is 3 long at the base and 2 at the full level, past its "
                              "capacity 2"),
           "message: %s", err.msg);
    CHECK(t, mts_lod_init(&lod, &m, MTS_LOD_AT_BASE, &err) == MTS_ERR_RANGE);
    CHECKF(t, strstr(err.msg, "base strip 0 is longer (3) than its capacity (2)"), "message: %s",
           err.msg);
    CHECK(t, mts_lod_init(&lod, &m, MTS_LOD_AT_FULL, &err) == MTS_OK);
    mts_lod_free(&lod);

    m.capacity[0] = 1; /* the full strip is 2 long */
    CHECK(t, mts_lod_init(&lod, &m, MTS_LOD_AT_FULL, &err) == MTS_ERR_RANGE);
    CHECKF(t, strstr(err.msg, "full strip 0 is longer (2) than its capacity (1)"), "message: %s",
           err.msg);

    m.capacity[0] = 1u << 20; /* far more than records could fill */
    CHECK(t, mts_model_validate(&m, &err) == MTS_ERR_RANGE);
    CHECKF(t, strstr(err.msg, "could ever fill"), "message: %s", err.msg);
    m.capacity[0] = UINT32_MAX;
    m.capacity[1] = 2;
    CHECK(t, mts_lod_init(&lod, &m, MTS_LOD_AT_BASE, &err) == MTS_ERR_LIMIT);

    m.capacity[0] = 5;
    m.capacity[1] = 3;
    CHECK(t, mts_model_validate(&m, &err) == MTS_OK);
    uint32_t *cap = m.capacity;
    m.capacity = NULL;
    CHECK(t, mts_model_validate(&m, &err) == MTS_ERR_FORMAT);
    CHECKF(t, strstr(err.msg, "capacities are missing"), "message: %s", err.msg);
    CHECK(t, mts_lod_init(&lod, &m, MTS_LOD_AT_BASE, &err) != MTS_OK);
    m.capacity = cap;
    mts_model_free(&m);
}

/* Two edits of one split on one strip: the first inserts, the second erases
 * part of what the first inserted and of what was there. The slot must hold
 * the longest moment inside the split, and the collapse must put back the
 * erased indices where they were. */
static void test_erase_after_insert_same_strip(mts_test *t)
{
    const uint32_t base[] = {1, 2, 0}, full[] = {1};
    const uint32_t rec[] = {2,                   /* edits */
                            0, 0, 1, 0,          /* strip 0: 1 insert */
                            3, 2, 0, 0,          /*   insert (0 0) at 3: 1 2 0 0 0 */
                            0, 1, 0, 0,          /* strip 0: 1 erase */
                            1, 4, 2, 0, 0, 0};   /*   erase (2 0 0 0) at 1: 1 */
    mts_model m;
    hand_model_one_split(&m, base, 3, full, 1, rec, 19);
    mts_error err = {0};
    /* the longest moment (5) is past the longest level (3) */
    CHECK(t, m.capacity[0] == 3);
    CHECK(t, mts_model_validate(&m, &err) == MTS_ERR_RANGE);
    CHECKF(t, strstr(err.msg, "insert of 2 at 3 does not fit strip 0 (length 3 of capacity 3)"),
           "message: %s", err.msg);
    m.capacity[0] = 5;
    CHECKF(t, mts_model_validate(&m, &err) == MTS_OK, "validate: %s", err.msg);
    hand_state snap[2] = {0};
    snap[0].len[0] = 3;
    memcpy(snap[0].d[0], base, sizeof base);
    snap[1].len[0] = 1;
    snap[1].d[0][0] = 1;
    uint64_t seed = 3;
    walk_against_states(t, &m, snap, &seed, 8, "insert then erase");
    mts_model_free(&m);
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
    RUN(&t, test_runtime_reuses_reservations);
    RUN(&t, test_validate_checks_bbox);
    RUN(&t, test_random_records_walk_both_ways);
    RUN(&t, test_erase_insert_subst);
    RUN(&t, test_erase_wrong_content_rejected);
    RUN(&t, test_erase_out_of_bounds_rejected);
    RUN(&t, test_capacity_longer_than_full);
    RUN(&t, test_capacity_exceeded_rejected);
    RUN(&t, test_erase_after_insert_same_strip);
    RUN(&t, test_verify_detects_winding_flip);
    RUN(&t, test_verify_detects_up_down_mismatch);
    RUN(&t, test_bunny_sampled);
    RUN(&t, test_fandisk_sampled);
    return mts_test_end(&t);
}
