/* The LOD builder and runtime on real meshes: DESIGN.md invariants 1 and 2 at
 * every level of cow and at 500 sampled levels of bunny00 and fandisk_large,
 * coherence (only the strips a record names change, and they are reported),
 * and random walks in both directions. */
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
    check_model_invariants(t, &m, 500);
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
    RUN(&t, test_bunny_sampled);
    RUN(&t, test_fandisk_sampled);
    return mts_test_end(&t);
}
