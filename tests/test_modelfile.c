/* The .mtsm file: round trip (capacities included), and every kind of damage
 * gets its own clear error and never a crash (truncation at every byte
 * offset, random byte flips, wrong magic and version, version-1 files, bad
 * checksums, out-of-range indices, capacities that do not hold the strips or
 * add up); a build on two threads writes the bytes one thread does. */
#include <math.h>
#include <stdint.h>

#include "build.h"
#include "color_field.h"
#include "crc32c.h"
#include "hand_model.h"
#include "lod.h"
#include "mesh.h"
#include "model.h"
#include "modelfile.h"
#include "verify.h"
#include "test.h"

/* A closed UV sphere, small enough to truncate at every byte. */
static void make_sphere(mts_mesh *m, uint32_t rings, uint32_t segments)
{
    uint32_t nv = 2 + (rings - 1) * segments;
    uint32_t nt = 2 * segments * (rings - 1);
    m->vertex_count = nv;
    m->triangle_count = nt;
    m->positions = malloc((size_t)nv * 12);
    m->normals = malloc((size_t)nv * 12);
    m->triangles = malloc((size_t)nt * 12);
    float *p = m->positions;
    *p++ = 0, *p++ = 0, *p++ = 1;
    for (uint32_t r = 1; r < rings; r++) {
        double th = M_PI * r / rings;
        for (uint32_t s = 0; s < segments; s++) {
            double ph = 2 * M_PI * s / segments;
            *p++ = (float)(sin(th) * cos(ph));
            *p++ = (float)(sin(th) * sin(ph));
            *p++ = (float)cos(th);
        }
    }
    *p++ = 0, *p++ = 0, *p++ = -1;
    uint32_t *t = m->triangles;
    uint32_t south = nv - 1;
    for (uint32_t s = 0; s < segments; s++) {
        uint32_t s1 = (s + 1) % segments;
        *t++ = 0, *t++ = 1 + s, *t++ = 1 + s1;
        for (uint32_t r = 1; r + 1 < rings; r++) {
            uint32_t a = 1 + (r - 1) * segments + s, b = 1 + (r - 1) * segments + s1;
            uint32_t c = 1 + r * segments + s, d = 1 + r * segments + s1;
            *t++ = a, *t++ = c, *t++ = d;
            *t++ = a, *t++ = d, *t++ = b;
        }
        uint32_t a = 1 + (rings - 2) * segments + s, b = 1 + (rings - 2) * segments + s1;
        *t++ = a, *t++ = south, *t++ = b;
    }
    mts_mesh_compute_normals(m);
}

static int small_model(mts_test *t, mts_model *model, uint8_t **file, size_t *size)
{
    mts_mesh mesh = {0};
    mts_error err = {0};
    make_sphere(&mesh, 8, 10);
    mesh.normals_given = 1; /* as if the file had them: the flag must survive */
    mts_result rc = mts_build_model(&mesh, "sphere", NULL, model, NULL, &err);
    mts_mesh_free(&mesh);
    CHECKF(t, rc == MTS_OK, "build: %s", err.msg);
    if (rc != MTS_OK)
        return 0;
    snprintf(model->build_key, sizeof model->build_key, "size 1, options 2: sphere");
    rc = mts_modelfile_encode(model, file, size, &err);
    CHECKF(t, rc == MTS_OK, "encode: %s", err.msg);
    return rc == MTS_OK;
}

static void test_crc32c_vector(mts_test *t)
{
    CHECK(t, mts_crc32c(0, "123456789", 9) == 0xE3069283u);
    CHECK(t, mts_crc32c(0, "", 0) == 0);
    /* continuing a CRC equals computing it in one go */
    uint32_t c = mts_crc32c(0, "1234", 4);
    CHECK(t, mts_crc32c(c, "56789", 5) == 0xE3069283u);
}

static void test_round_trip(mts_test *t)
{
    mts_model m, back;
    uint8_t *file;
    size_t size;
    if (!small_model(t, &m, &file, &size))
        return;
    mts_error err = {0};
    CHECKF(t, mts_modelfile_decode(file, size, "sphere.mtsm", &back, &err) == MTS_OK, "%s", err.msg);
    CHECK(t, back.vertex_count == m.vertex_count && back.level_count == m.level_count);
    CHECK(t, back.strip_count == m.strip_count);
    CHECK(t, memcmp(back.capacity, m.capacity, (size_t)m.strip_count * 4) == 0);
    CHECK(t, memcmp(back.positions, m.positions, (size_t)m.vertex_count * 12) == 0);
    CHECK(t, memcmp(back.normals, m.normals, (size_t)m.vertex_count * 12) == 0);
    CHECK(t, memcmp(back.full.indices, m.full.indices, (size_t)m.full.index_count * 4) == 0);
    CHECK(t, memcmp(back.base.indices, m.base.indices, (size_t)m.base.index_count * 4) == 0);
    CHECK(t, memcmp(back.record_data, m.record_data, (size_t)m.record_word_count * 4) == 0);
    CHECK(t, memcmp(back.level_triangles, m.level_triangles, ((size_t)m.level_count + 1) * 4) == 0);
    CHECK(t, strcmp(back.source, "sphere") == 0);
    /* the build key is a section of its own, apart from the source */
    CHECK(t, strcmp(back.build_key, "size 1, options 2: sphere") == 0);
    CHECK(t, m.flags == MTS_MODEL_NORMALS_GIVEN && back.flags == m.flags);
    /* the split descriptions a stream sends, and the key levels */
    CHECK(t, back.key_count == m.key_count && back.growth_word_count == m.growth_word_count);
    CHECK(t, m.growth_word_count >= 3 * (size_t)m.level_count);
    CHECK(t, memcmp(back.key_levels, m.key_levels, (size_t)m.key_count * 4) == 0);
    CHECK(t, memcmp(back.growth_offsets, m.growth_offsets, ((size_t)m.level_count + 1) * 4) == 0);
    CHECK(t, memcmp(back.growth_data, m.growth_data, (size_t)m.growth_word_count * 4) == 0);
    mts_verify_report vr;
    CHECKF(t, mts_verify_growth(&back, &vr, &err) == MTS_OK, "%s", err.msg);
    /* encoding is deterministic */
    uint8_t *again;
    size_t again_size;
    CHECK(t, mts_modelfile_encode(&back, &again, &again_size, &err) == MTS_OK);
    CHECK(t, again_size == size && memcmp(again, file, size) == 0);
    /* and through a real file */
    char path[512];
    snprintf(path, sizeof path, "%s/mts_test_round_trip.mtsm", mts_test_tmpdir());
    uint64_t bytes = 0;
    CHECKF(t, mts_modelfile_save(&m, path, &bytes, &err) == MTS_OK, "%s", err.msg);
    CHECK(t, bytes == size);
    mts_model loaded;
    CHECKF(t, mts_modelfile_load(path, &loaded, &err) == MTS_OK, "%s", err.msg);
    mts_model_free(&loaded);
    remove(path);
    free(again);
    free(file);
    mts_model_free(&back);
    mts_model_free(&m);
}

/* A model whose strips are longer at a middle level than at either end and
 * whose records erase (tests/hand_model.h): through the file and back,
 * capacities and all, and the loaded model walks as the original does. */
static void test_round_trip_erase_model(mts_test *t)
{
    mts_model m, back;
    hand_state snap[3];
    hand_model_erases(&m, snap);
    snprintf(m.source, sizeof m.source, "by hand");
    uint8_t *file = NULL;
    size_t size = 0;
    mts_error err = {0};
    CHECKF(t, mts_modelfile_encode(&m, &file, &size, &err) == MTS_OK, "encode: %s", err.msg);
    CHECKF(t, mts_modelfile_decode(file, size, "hand.mtsm", &back, &err) == MTS_OK, "decode: %s",
           err.msg);
    if (t->case_failed) {
        free(file);
        mts_model_free(&m);
        return;
    }
    CHECK(t, back.strip_count == 2 && back.capacity[0] == 5 && back.capacity[1] == 3);
    CHECK(t, back.record_word_count == m.record_word_count &&
                 memcmp(back.record_data, m.record_data, (size_t)m.record_word_count * 4) == 0);
    CHECK(t, memcmp(back.record_offsets, m.record_offsets, 3 * 4) == 0);
    CHECK(t, back.full.offsets[1] == 2 && back.full.offsets[2] == 2);
    CHECK(t, strcmp(back.source, "by hand") == 0);
    mts_lod lod;
    CHECK(t, mts_lod_init(&lod, &back, MTS_LOD_AT_FULL, &err) == MTS_OK);
    for (uint32_t l = 3; l-- > 0;) {
        CHECK(t, mts_lod_set_level(&lod, l, &err) == MTS_OK);
        for (uint32_t s = 0; s < 2; s++) {
            uint32_t len;
            const uint32_t *x = mts_lod_strip(&lod, s, &len);
            CHECKF(t, len == snap[l].len[s] && memcmp(x, snap[l].d[s], (size_t)len * 4) == 0,
                   "level %u strip %u", l, s);
        }
    }
    mts_lod_free(&lod);
    /* every cut of it is refused too */
    for (size_t cut = 0; cut < size && !t->case_failed; cut++) {
        mts_model bad;
        uint8_t *copy = malloc(cut ? cut : 1);
        memcpy(copy, file, cut);
        mts_result rc = mts_modelfile_decode(copy, cut, "cut.mtsm", &bad, &err);
        free(copy);
        CHECKF(t, rc != MTS_OK, "cut at %zu of %zu was accepted", cut, size);
        if (rc == MTS_OK)
            mts_model_free(&bad);
    }
    free(file);
    mts_model_free(&back);
    mts_model_free(&m);
}

static void test_truncated_everywhere(mts_test *t)
{
    mts_model m;
    uint8_t *file;
    size_t size;
    if (!small_model(t, &m, &file, &size))
        return;
    for (size_t cut = 0; cut < size; cut++) {
        mts_model back;
        mts_error err = {0};
        uint8_t *copy = malloc(cut ? cut : 1); /* exact size, so ASan sees any overread */
        memcpy(copy, file, cut);
        mts_result rc = mts_modelfile_decode(copy, cut, "cut.mtsm", &back, &err);
        free(copy);
        CHECKF(t, rc != MTS_OK, "truncated at %zu of %zu was accepted", cut, size);
        if (rc == MTS_OK) {
            mts_model_free(&back);
            break;
        }
        /* cut inside the padding after the last section still truncates a section or the table */
        CHECKF(t, strstr(err.msg, "truncated") || strstr(err.msg, "empty"),
               "cut at %zu: message does not say truncated: %s", cut, err.msg);
        CHECK(t, strstr(err.msg, "cut.mtsm") != NULL);
        if (t->case_failed)
            break;
    }
    free(file);
    mts_model_free(&m);
}

static void test_random_flips(mts_test *t)
{
    mts_model m;
    uint8_t *file;
    size_t size;
    if (!small_model(t, &m, &file, &size))
        return;
    uint64_t seed = 99;
    uint8_t *copy = malloc(size);
    for (int i = 0; i < 3000 && !t->case_failed; i++) {
        memcpy(copy, file, size);
        seed = seed * 6364136223846793005ull + 1442695040888963407ull;
        size_t at = (size_t)(seed >> 33) % size;
        uint8_t flip = (uint8_t)(1u << ((seed >> 20) & 7));
        copy[at] ^= flip;
        mts_model back;
        mts_error err = {0};
        mts_result rc = mts_modelfile_decode(copy, size, "flip.mtsm", &back, &err);
        if (rc == MTS_OK) {
            /* only a flip in alignment padding (not covered by any CRC) may pass */
            mts_model_free(&back);
            continue;
        }
        CHECKF(t, err.msg[0] != 0, "flip at %zu gave an empty message", at);
    }
    free(copy);
    free(file);
    mts_model_free(&m);
}

/* Recomputes every section CRC and the header CRC, so a deliberate edit
 * reaches the structural checks behind them. */
static void reseal(uint8_t *f)
{
    uint32_t count = f[8] | f[9] << 8 | f[10] << 16 | (uint32_t)f[11] << 24;
    for (uint32_t i = 0; i < count; i++) {
        uint8_t *e = f + 16 + 24 * i;
        uint64_t off = 0, len = 0;
        for (int b = 7; b >= 0; b--) {
            off = off << 8 | e[8 + b];
            len = len << 8 | e[16 + b];
        }
        uint32_t c = mts_crc32c(0, f + off, (size_t)len);
        for (int b = 0; b < 4; b++)
            e[4 + b] = (uint8_t)(c >> (8 * b));
    }
    uint32_t h = mts_crc32c(0, f, 12);
    h = mts_crc32c(h, f + 16, (size_t)24 * count);
    for (int b = 0; b < 4; b++)
        f[12 + b] = (uint8_t)(h >> (8 * b));
}

static uint64_t section_offset(const uint8_t *f, uint32_t id)
{
    uint32_t count = f[8] | f[9] << 8 | f[10] << 16 | (uint32_t)f[11] << 24;
    for (uint32_t i = 0; i < count; i++) {
        const uint8_t *e = f + 16 + 24 * i;
        if ((uint32_t)(e[0] | e[1] << 8 | e[2] << 16 | (uint32_t)e[3] << 24) == id) {
            uint64_t off = 0;
            for (int b = 7; b >= 0; b--)
                off = off << 8 | e[8 + b];
            return off;
        }
    }
    return 0;
}

static void put32(uint8_t *p, uint32_t x)
{
    for (int b = 0; b < 4; b++)
        p[b] = (uint8_t)(x >> (8 * b));
}

static void expect_error(mts_test *t, uint8_t *f, size_t size, mts_result code, const char *needle)
{
    mts_model back;
    mts_error err = {0};
    mts_result rc = mts_modelfile_decode(f, size, "bad.mtsm", &back, &err);
    CHECKF(t, rc == code, "got %s (%s), expected %s", mts_result_name(rc), err.msg,
           mts_result_name(code));
    CHECKF(t, strstr(err.msg, needle) != NULL, "message '%s' lacks '%s'", err.msg, needle);
    if (rc == MTS_OK)
        mts_model_free(&back);
}

static void test_specific_errors(mts_test *t)
{
    mts_model m;
    uint8_t *file;
    size_t size;
    if (!small_model(t, &m, &file, &size))
        return;
    uint8_t *f = malloc(size);

    memcpy(f, file, size);
    f[0] = 'X';
    expect_error(t, f, size, MTS_ERR_FORMAT, "magic");

    memcpy(f, file, size);
    f[4] = 6;
    expect_error(t, f, size, MTS_ERR_VERSION, "version 6.");

    /* versions 1 to 4 (no erase runs, no capacities; no split
     * descriptions; no flags; other growth rules): rebuild */
    memcpy(f, file, size);
    f[4] = 1;
    reseal(f);
    expect_error(t, f, size, MTS_ERR_VERSION,
                 "model file version 1 is from an older mtstream; rebuild it with mts-build");
    memcpy(f, file, size);
    f[4] = 2;
    reseal(f);
    expect_error(t, f, size, MTS_ERR_VERSION,
                 "model file version 2 is from an older mtstream; rebuild it with mts-build");
    memcpy(f, file, size);
    f[4] = 3;
    reseal(f);
    expect_error(t, f, size, MTS_ERR_VERSION,
                 "model file version 3 is from an older mtstream; rebuild it with mts-build");
    memcpy(f, file, size);
    f[4] = 4;
    reseal(f);
    expect_error(t, f, size, MTS_ERR_VERSION,
                 "model file version 4 is from an older mtstream; rebuild it with mts-build");

    memcpy(f, file, size);
    f[section_offset(f, 2) + 5] ^= 0x40; /* inside the positions */
    expect_error(t, f, size, MTS_ERR_CHECKSUM, "checksum mismatch in section 'positions'");

    memcpy(f, file, size);
    f[13] ^= 1;
    expect_error(t, f, size, MTS_ERR_CHECKSUM, "header checksum");

    /* a base strip index past the base vertices, with valid checksums */
    memcpy(f, file, size);
    uint64_t base = section_offset(f, 5);
    put32(f + base + 4 * (uint64_t)m.strip_count, m.vertex_count + 7);
    reseal(f);
    expect_error(t, f, size, MTS_ERR_RANGE, "out of range");

    /* a model flag this version does not know (INFO's flags, resealed) */
    memcpy(f, file, size);
    put32(f + section_offset(f, 1) + 56, 0x80);
    reseal(f);
    expect_error(t, f, size, MTS_ERR_FORMAT, "unknown model flags 0x80");

    /* a parent before vertex 0: the first split's first varint */
    memcpy(f, file, size);
    f[section_offset(f, 6)] = 0x7F;
    reseal(f);
    expect_error(t, f, size, MTS_ERR_RANGE, "parent");

    /* a record naming a strip that does not exist, in an otherwise sound file */
    {
        uint32_t saved = m.record_data[1];
        m.record_data[1] = 1u << 30; /* split 0's first edit's strip */
        uint8_t *bad;
        size_t bad_size;
        mts_error e2 = {0};
        CHECK(t, mts_modelfile_encode(&m, &bad, &bad_size, &e2) == MTS_OK);
        expect_error(t, bad, bad_size, MTS_ERR_RANGE, "strip 1073741824 out of range");
        free(bad);
        m.record_data[1] = saved;
    }

    /* capacities (section 9, one u32 per strip; their sum is word 7 of
     * 'info'): one that a strip does not fit, even when the sum agrees */
    {
        uint32_t s = 0;
        while (s < m.strip_count && m.full.offsets[s + 1] == m.full.offsets[s])
            s++;
        CHECK(t, s < m.strip_count);
        uint32_t total = 0;
        for (uint32_t k = 0; k < m.strip_count; k++)
            total += m.capacity[k];
        memcpy(f, file, size);
        put32(f + section_offset(f, 9) + 4 * (uint64_t)s, 0);
        put32(f + section_offset(f, 1) + 28, total - m.capacity[s]);
        reseal(f);
        expect_error(t, f, size, MTS_ERR_RANGE, "past its capacity");

        /* one that breaks the sum 'info' declares */
        memcpy(f, file, size);
        put32(f + section_offset(f, 9) + 4 * (uint64_t)s, m.capacity[s] + 1);
        reseal(f);
        expect_error(t, f, size, MTS_ERR_FORMAT, "strip capacities add up to");

        /* more than base indices and record words could ever fill, even
         * when the capacities add up to it */
        memcpy(f, file, size);
        uint32_t huge = 0x7FFFFFF0u;
        put32(f + section_offset(f, 9) + 4 * (uint64_t)s, huge);
        put32(f + section_offset(f, 1) + 28, total - m.capacity[s] + huge);
        reseal(f);
        expect_error(t, f, size, MTS_ERR_FORMAT, "could ever fill");
    }

    /* counts that promise more than the file holds */
    memcpy(f, file, size);
    put32(f + section_offset(f, 1), 0x7FFFFFFF);
    reseal(f);
    expect_error(t, f, size, MTS_ERR_FORMAT, "bytes");

    expect_error(t, f, 0, MTS_ERR_FORMAT, "empty");

    mts_error err = {0};
    mts_model back;
    CHECK(t, mts_modelfile_load("/nonexistent/x.mtsm", &back, &err) == MTS_ERR_IO);
    CHECK(t, strstr(err.msg, "/nonexistent/x.mtsm") != NULL);

    free(f);
    free(file);
    mts_model_free(&m);
}

/* The build's two sides on two threads give the model one thread gives,
 * byte for byte, and the progress callback is never entered twice at once. */
/* ------------------------------------------------------------------------ */
/* Vertex colours                                                           */

/* What the builder wrote for tests/data/cow.off (source "tests/data/cow.off",
 * default options) before the model file could hold colours, computed with
 * the code of commit 1d93558: an uncoloured model's file must stay byte
 * for byte what it was. A change to what the builder makes (strips,
 * records, options) changes these, and then they are remade, with that
 * change's reason, by the printout of this test. */
#define COW_FILE_BYTES 334664u
#define COW_FILE_CRC32C 0xfdf6307eu

static int build_file_with(mts_test *t, const char *mesh_path, const mts_mesh_options *mo,
                           const mts_build_options *bo, const char *source, mts_model *model,
                           uint8_t **file, size_t *size)
{
    mts_mesh mesh = {0};
    mts_error err = {0};
    mts_result rc = mts_mesh_load(mesh_path, mo, &mesh, NULL, &err);
    CHECKF(t, rc == MTS_OK, "%s: %s", mesh_path, err.msg);
    if (rc == MTS_OK) {
        rc = mts_build_model(&mesh, source, bo, model, NULL, &err);
        CHECKF(t, rc == MTS_OK, "build: %s", err.msg);
    }
    if (rc == MTS_OK) {
        rc = mts_modelfile_encode(model, file, size, &err);
        CHECKF(t, rc == MTS_OK, "encode: %s", err.msg);
        if (rc != MTS_OK)
            mts_model_free(model);
    }
    mts_mesh_free(&mesh);
    return rc == MTS_OK;
}

static int build_file(mts_test *t, const char *mesh_path, const mts_mesh_options *mo,
                      const char *source, mts_model *model, uint8_t **file, size_t *size)
{
    return build_file_with(t, mesh_path, mo, NULL, source, model, file, size);
}

static void test_uncolored_file_unchanged(mts_test *t)
{
    mts_model m;
    uint8_t *f;
    size_t n;
    if (!build_file(t, "tests/data/cow.off", NULL, "tests/data/cow.off", &m, &f, &n))
        return;
    uint32_t crc = mts_crc32c(0, f, n);
    CHECKF(t, n == COW_FILE_BYTES && crc == COW_FILE_CRC32C,
           "cow.off's model file: %zu bytes, CRC-32C 0x%08x; before colours it was %u bytes, "
           "0x%08x", n, crc, COW_FILE_BYTES, COW_FILE_CRC32C);
    CHECK(t, m.colors == NULL && !(m.flags & MTS_MODEL_COLORS));
    CHECK(t, f[6] == 1 && f[7] == 0); /* still version 5.1 */
    free(f);
    mts_model_free(&m);

    /* the coloured cow without its colours is that same model */
    uint8_t *g;
    size_t gn;
    mts_mesh_options mo = {.no_colors = 1};
    if (!build_file(t, "tests/data/cow_colors.ply", &mo, "tests/data/cow.off", &m, &g, &gn))
        return;
    CHECKF(t, gn == COW_FILE_BYTES && mts_crc32c(0, g, gn) == COW_FILE_CRC32C,
           "cow_colors.ply without colours: %zu bytes, 0x%08x", gn, mts_crc32c(0, g, gn));
    free(g);
    mts_model_free(&m);
}

static int by_position(const void *a, const void *b)
{
    return memcmp(a, b, 12);
}

static void test_colors_round_trip(mts_test *t)
{
    mts_model m;
    uint8_t *f;
    size_t n;
    if (!build_file(t, "tests/data/cow_colors.ply", NULL, "cow_colors", &m, &f, &n))
        return;
    CHECK(t, m.colors != NULL && (m.flags & MTS_MODEL_COLORS));
    CHECK(t, f[6] == 2); /* version 5.2 */
    {
        /* what the colours cost: their bytes, a table entry, alignment --
         * with the collapses of the uncoloured mesh (the colour term in the
         * collapse cost, which changes them, off) */
        mts_model plain, held;
        uint8_t *pf, *hf;
        size_t pn, hn;
        mts_mesh_options mo = {.no_colors = 1};
        mts_build_options bo = {.color_cost = -1};
        if (build_file(t, "tests/data/cow_colors.ply", &mo, "cow_colors", &plain, &pf, &pn)) {
            if (build_file_with(t, "tests/data/cow_colors.ply", NULL, &bo, "cow_colors", &held,
                                &hf, &hn)) {
                CHECKF(t, hn >= pn + 3 * 2904 + 24 && hn < pn + 3 * 2904 + 24 + 8,
                       "%zu bytes with colours, %zu without", hn, pn);
                free(hf);
                mts_model_free(&held);
            }
            free(pf);
            mts_model_free(&plain);
        }
    }

    /* Every vertex of the model has the colour of the source vertex at its
     * position: the colours followed the vertices through cleaning,
     * simplification's ids and the stream order. (The field is a function
     * of position, so where the cow has two vertices at one position they
     * have one colour too.) */
    mts_mesh src = {0};
    mts_error err = {0};
    CHECK(t, mts_mesh_load("tests/data/cow_colors.ply", NULL, &src, NULL, &err) == MTS_OK);
    CHECK(t, src.colors && src.vertex_count == m.vertex_count);
    if (src.colors && src.vertex_count == m.vertex_count) {
        typedef struct {
            float p[3];
            uint8_t c[3];
        } pc;
        pc *table = malloc(src.vertex_count * sizeof *table);
        for (uint32_t v = 0; table && v < src.vertex_count; v++) {
            memcpy(table[v].p, src.positions + 3 * (size_t)v, 12);
            memcpy(table[v].c, src.colors + 3 * (size_t)v, 3);
        }
        if (table) {
            qsort(table, src.vertex_count, sizeof *table, by_position);
            uint32_t wrong = 0;
            for (uint32_t v = 0; v < m.vertex_count; v++) {
                const pc *hit = bsearch(m.positions + 3 * (size_t)v, table, src.vertex_count,
                                        sizeof *table, by_position);
                wrong += !hit || memcmp(hit->c, m.colors + 3 * (size_t)v, 3) != 0;
            }
            CHECKF(t, wrong == 0, "%u of %u vertices with another colour than the source's",
                   wrong, m.vertex_count);
            /* and the colours are the field, not one colour everywhere */
            uint32_t differ = 0;
            for (uint32_t v = 1; v < m.vertex_count; v++)
                differ += memcmp(m.colors, m.colors + 3 * (size_t)v, 3) != 0;
            CHECK(t, differ > m.vertex_count / 2);
        }
        free(table);
    }
    mts_mesh_free(&src);

    /* the file gives them back */
    mts_model back;
    mts_result rc = mts_modelfile_decode(f, n, "cow_colors.mtsm", &back, &err);
    CHECKF(t, rc == MTS_OK, "%s", err.msg);
    if (rc == MTS_OK) {
        CHECK(t, back.flags == m.flags && back.colors != NULL);
        CHECK(t, back.colors && !memcmp(back.colors, m.colors, 3 * (size_t)m.vertex_count));
        uint8_t *again;
        size_t again_n;
        CHECK(t, mts_modelfile_encode(&back, &again, &again_n, &err) == MTS_OK);
        CHECK(t, again_n == n && !memcmp(again, f, n));
        free(again);
        mts_model_free(&back);
    }
    free(f);
    mts_model_free(&m);
}

/* A section's table entry in file f. */
static uint8_t *section_entry(uint8_t *f, uint32_t id)
{
    uint32_t count = f[8] | f[9] << 8 | f[10] << 16 | (uint32_t)f[11] << 24;
    for (uint32_t i = 0; i < count; i++) {
        uint8_t *e = f + 16 + 24 * i;
        if ((uint32_t)(e[0] | e[1] << 8 | e[2] << 16 | (uint32_t)e[3] << 24) == id)
            return e;
    }
    return NULL;
}

static void test_colors_damaged(mts_test *t)
{
    mts_model m;
    uint8_t *f;
    size_t n;
    mts_mesh_options mo = {0};
    if (!build_file(t, "tests/data/cow_colors.ply", &mo, "cow_colors", &m, &f, &n))
        return;
    mts_model_free(&m);
    const uint32_t SEC_COLORS = 12, SEC_INFO = 1;
    uint8_t *e = section_entry(f, SEC_COLORS);
    CHECK(t, e != NULL);
    if (!e) {
        free(f);
        return;
    }
    uint64_t at = section_offset(f, SEC_COLORS);
    uint8_t *bad = malloc(n);

    /* a flipped byte: the section's checksum, by name */
    memcpy(bad, f, n);
    bad[at + 100] ^= 0x40;
    expect_error(t, bad, n, MTS_ERR_CHECKSUM, "checksum mismatch in section 'colors'");

    /* shorter than INFO's vertices need */
    memcpy(bad, f, n);
    put32(section_entry(bad, SEC_COLORS) + 16, 3 * 2904 - 3);
    reseal(bad);
    expect_error(t, bad, n, MTS_ERR_FORMAT, "section 'colors' is 8709 bytes; the counts in 'info' "
                                            "need 8712");

    /* the flag without the section (its id made unknown: skipped) */
    memcpy(bad, f, n);
    put32(section_entry(bad, SEC_COLORS), 99);
    reseal(bad);
    expect_error(t, bad, n, MTS_ERR_FORMAT, "section 'colors' is missing");

    /* the section without the flag */
    memcpy(bad, f, n);
    uint64_t info = section_offset(bad, SEC_INFO);
    bad[info + 56] &= (uint8_t)~MTS_MODEL_COLORS;
    reseal(bad);
    expect_error(t, bad, n, MTS_ERR_FORMAT, "section 'colors' in a model whose 'info' flags");

    /* cut inside it (the last section) */
    expect_error(t, f, (size_t)at + 10, MTS_ERR_FORMAT, "truncated: section 'colors'");
    free(bad);
    free(f);
}

typedef struct progress_probe {
    volatile int inside, overlapped, calls;
} progress_probe;

static void probe_progress(void *user, const char *stage, double done)
{
    progress_probe *p = user;
    (void)stage;
    (void)done;
    if (__atomic_fetch_add(&p->inside, 1, __ATOMIC_SEQ_CST) != 0)
        p->overlapped = 1;
    p->calls++;
    for (volatile int i = 0; i < 2000; i++) {
    } /* a window for an overlap to show */
    __atomic_fetch_sub(&p->inside, 1, __ATOMIC_SEQ_CST);
}

static void test_threads_same_model(mts_test *t)
{
    mts_mesh mesh = {0};
    mts_error err = {0};
    CHECKF(t, mts_mesh_load("tests/data/cow.off", NULL, &mesh, NULL, &err) == MTS_OK, "%s",
           err.msg);
    uint8_t *file[2] = {NULL, NULL};
    size_t size[2] = {0, 0};
    uint32_t used[2] = {0, 0};
    progress_probe probe = {0};
    for (int k = 0; k < 2; k++) {
        mts_build_options bo = {0};
        bo.threads = k ? 2 : 1;
        bo.progress.fn = probe_progress;
        bo.progress.user = &probe;
        mts_build_report rep;
        mts_model model;
        CHECKF(t, mts_build_model(&mesh, "cow", &bo, &model, &rep, &err) == MTS_OK, "%s",
               err.msg);
        used[k] = rep.threads;
        CHECK(t, mts_modelfile_encode(&model, &file[k], &size[k], &err) == MTS_OK);
        mts_model_free(&model);
    }
    CHECKF(t, used[0] == 1 && used[1] == 2, "threads used: %u and %u", used[0], used[1]);
    CHECKF(t, size[0] == size[1] && memcmp(file[0], file[1], size[0]) == 0,
           "one thread: %zu bytes; two: %zu bytes, or other bytes", size[0], size[1]);
    CHECKF(t, probe.calls > 0 && !probe.overlapped, "%d progress calls, overlapped %d",
           probe.calls, probe.overlapped);
    free(file[0]);
    free(file[1]);
    mts_mesh_free(&mesh);
}

/* Mean squared colour distance (sRGB units, summed over channels) between
 * each vertex's colour and the colour its place takes at level L: its
 * ancestor's there, the vertex it was collapsed into. */
static double ancestor_color_error(const mts_model *m, uint32_t level)
{
    const uint32_t nb = m->base_vertex_count, present = nb + level;
    double sum = 0;
    for (uint32_t v = 0; v < m->vertex_count; v++) {
        uint32_t a = v;
        while (a >= present)
            a = m->parents[a - nb];
        for (int k = 0; k < 3; k++) {
            double d = (double)m->colors[3 * (size_t)v + k] - m->colors[3 * (size_t)a + k];
            sum += d * d;
        }
    }
    return sum / m->vertex_count;
}

/* The colour term in the collapse cost (build.h's color_cost): on the cow
 * with sharp colour patches (tests/color_field.h), the default weight keeps
 * the patches' boundaries, so the colours the coarse levels draw are nearer
 * the input's than the quadric alone leaves them, at every level measured;
 * an uncoloured mesh ignores the weight (its model is the same byte for
 * byte, whatever the weight). */
static void test_color_cost(mts_test *t)
{
    mts_mesh mesh = {0};
    mts_error err = {0};
    CHECKF(t, mts_mesh_load("tests/data/cow.off", NULL, &mesh, NULL, &err) == MTS_OK, "%s",
           err.msg);
    if (!mesh.vertex_count)
        return;
    mts_model m[2];
    uint8_t *file[2] = {NULL, NULL};
    size_t size[2] = {0, 0};
    for (int k = 0; k < 2; k++) { /* uncoloured: the quadric alone, then a heavy colour weight */
        mts_build_options bo = {0};
        bo.color_cost = k ? 1e-2 : -1;
        CHECKF(t, mts_build_model(&mesh, "cow", &bo, &m[k], NULL, &err) == MTS_OK, "%s", err.msg);
        CHECK(t, mts_modelfile_encode(&m[k], &file[k], &size[k], &err) == MTS_OK);
        mts_model_free(&m[k]);
    }
    CHECKF(t, size[0] == size[1] && size[0] && memcmp(file[0], file[1], size[0]) == 0,
           "an uncoloured cow built with a colour weight: %zu bytes against %zu", size[1], size[0]);
    free(file[0]);
    free(file[1]);

    CHECK(t, mts_test_mesh_color_field(&mesh, MTS_TEST_FIELD_PATCHES));
    for (int k = 0; k < 2; k++) { /* the quadric alone, then a colour weight */
        mts_build_options bo = {0};
        bo.color_cost = k ? 1e-4 : -1;
        CHECKF(t, mts_build_model(&mesh, "cow", &bo, &m[k], NULL, &err) == MTS_OK, "%s", err.msg);
        CHECK(t, m[k].colors != NULL);
    }
    if (m[0].colors && m[1].colors) {
        CHECK(t, m[0].level_count == m[1].level_count);
        for (int pct = 5; pct <= 50; pct *= 2) { /* 5, 10, 20, 40 % of the splits */
            uint32_t level = m[0].level_count * (uint32_t)pct / 100;
            double plain = ancestor_color_error(&m[0], level),
                   colored = ancestor_color_error(&m[1], level);
            CHECKF(t, colored < 0.9 * plain,
                   "level %u (%d%%): colour error %.1f with the colour term, %.1f without", level,
                   pct, colored, plain);
        }
    }
    mts_model_free(&m[0]);
    mts_model_free(&m[1]);
    mts_mesh_free(&mesh);
}

int main(void)
{
    mts_test t = {0};
    RUN(&t, test_crc32c_vector);
    RUN(&t, test_round_trip);
    RUN(&t, test_round_trip_erase_model);
    RUN(&t, test_truncated_everywhere);
    RUN(&t, test_random_flips);
    RUN(&t, test_specific_errors);
    RUN(&t, test_threads_same_model);
    RUN(&t, test_uncolored_file_unchanged);
    RUN(&t, test_colors_round_trip);
    RUN(&t, test_colors_damaged);
    RUN(&t, test_color_cost);
    return mts_test_end(&t);
}
