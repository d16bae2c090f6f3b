/* A model's wire stream end to end in memory: the client's mesh equals the
 * server's model at the level it asked for (strips exactly, positions bit for
 * bit on the grid), whatever the stop point and however the bytes are split;
 * a corrupted batch is rejected and not applied; a cut stream leaves the
 * client at its last whole batch with a consistent mesh; the client derives
 * every record from the splits' fan codes, word for word the model's, and
 * moves both ways with them. */
#include <stdint.h>

#include "build.h"
#include "crc32c.h"
#include "mesh.h"
#include "stream.h"
#include "test.h"
#include "verify.h"
#include "wire.h"

/* normals_given: treat the mesh's (computed) normals as the file's own, so
 * the stream carries them. */
static int build_stream_normals(mts_test *t, const char *path, int normals_given, mts_stream *s)
{
    mts_error err = {0};
    mts_mesh mesh = {0};
    mts_model m;
    if (mts_mesh_load(path, NULL, &mesh, NULL, &err) != MTS_OK) {
        CHECKF(t, 0, "%s", err.msg);
        return 0;
    }
    if (normals_given)
        mesh.normals_given = 1;
    mts_result rc = mts_build_model(&mesh, path, NULL, &m, NULL, &err);
    mts_mesh_free(&mesh);
    CHECKF(t, rc == MTS_OK, "%s", err.msg);
    if (rc != MTS_OK)
        return 0;
    rc = mts_stream_build(&m, "cow", NULL, s, &err);
    mts_model_free(&m);
    CHECKF(t, rc == MTS_OK, "stream: %s", err.msg);
    return rc == MTS_OK;
}

static int build_stream(mts_test *t, const char *path, mts_stream *s)
{
    return build_stream_normals(t, path, 0, s);
}

/* What a connection is sent for a HELLO: MODEL_INFO, the range, END. */
static void connection_bytes(const mts_stream *s, uint8_t kind, uint32_t value, mts_buf *out,
                             uint32_t *stop)
{
    mts_error err = {0};
    *stop = mts_stream_stop_level(s, kind, value);
    mts_stream_put_model_info(s, *stop, out);
    size_t off, len;
    if (mts_stream_range(s, 0, *stop, &off, &len, &err) != MTS_OK)
        return;
    mts_buf_put(out, s->bytes + off, len);
    mts_stream_put_end(s, *stop, (uint32_t)out->size, out);
}

/* Feeds bytes in pieces from a seeded generator; returns the last event. */
static mts_result feed(mts_stream_client *c, const uint8_t *data, size_t size, uint64_t seed,
                       int *saw_end, mts_error *err)
{
    mts_wire_reader r = {0};
    mts_result rc = MTS_OK;
    size_t at = 0;
    *saw_end = 0;
    while (at < size && rc == MTS_OK) {
        seed = seed * 6364136223846793005ull + 1442695040888963407ull;
        size_t piece = seed ? 1 + (size_t)((seed >> 33) % 977) : size;
        if (piece > size - at)
            piece = size - at;
        if ((rc = mts_wire_reader_feed(&r, data + at, piece, err)) != MTS_OK)
            break;
        at += piece;
        uint8_t type;
        const uint8_t *p;
        size_t n;
        int got;
        while (rc == MTS_OK && (got = mts_wire_reader_next(&r, &type, &p, &n, err)) == 1) {
            mts_stream_event ev;
            rc = mts_stream_client_frame(c, type, p, n, &ev, err);
            if (ev == MTS_EV_END)
                *saw_end = 1;
        }
    }
    mts_wire_reader_free(&r);
    return rc;
}

/* The client's state equals the stream model at the client's level. */
static void same_as_server(mts_test *t, const mts_stream *s, const mts_stream_client *c)
{
    mts_error err = {0};
    mts_lod ref;
    CHECK(t, mts_lod_init(&ref, &s->model, MTS_LOD_AT_BASE, &err) == MTS_OK);
    CHECK(t, mts_lod_set_level(&ref, c->lod.level, &err) == MTS_OK);
    for (uint32_t st = 0; st < s->model.strip_count; st++) {
        uint32_t la, lb;
        const uint32_t *a = mts_lod_strip(&ref, st, &la);
        const uint32_t *b = mts_lod_strip(&c->lod, st, &lb);
        CHECKF(t, la == lb && memcmp(a, b, (size_t)la * 4) == 0, "strip %u differs at level %u",
               st, c->lod.level);
        if (t->case_failed)
            break;
    }
    size_t nv = (size_t)s->model.base_vertex_count + c->lod.level;
    CHECK(t, memcmp(c->model.positions, s->model.positions, nv * 12) == 0);
    CHECK(t, memcmp(c->model.normals, s->model.normals, nv * 12) == 0);
    CHECK(t, memcmp(c->quantized, s->quantized, nv * 12) == 0);
    CHECK(t, mts_stream_checksum(&c->lod, c->quantized) == s->level_checksum[c->lod.level]);
    mts_lod_free(&ref);
}

static void test_cow_every_stop(mts_test *t)
{
    mts_stream s;
    if (!build_stream(t, "tests/data/cow.off", &s))
        return;
    const uint32_t n = s.model.level_count;
    struct {
        uint8_t kind;
        uint32_t value;
    } stops[] = {{MTS_STOP_FULL, 0},         {MTS_STOP_LEVEL, n / 3},
                 {MTS_STOP_LEVEL, 0},        {MTS_STOP_TRIANGLES, 1000},
                 {MTS_STOP_FRACTION, 500000}, {MTS_STOP_LEVEL, 999999}};
    for (size_t i = 0; i < sizeof stops / sizeof stops[0] && !t->case_failed; i++) {
        for (uint64_t seed = 0; seed < 4; seed++) {
            mts_buf b = {0};
            uint32_t stop;
            connection_bytes(&s, stops[i].kind, stops[i].value, &b, &stop);
            mts_stream_client c;
            mts_stream_client_init(&c);
            mts_error err = {0};
            int saw_end;
            mts_result rc = feed(&c, b.data, b.size, seed, &saw_end, &err);
            CHECKF(t, rc == MTS_OK && saw_end, "stop %zu seed %llu: %s", i,
                   (unsigned long long)seed, err.msg);
            CHECK(t, c.lod.level == stop);
            CHECK(t, c.checksum == c.end_checksum);
            same_as_server(t, &s, &c);
            mts_stream_client_free(&c);
            mts_buf_free(&b);
        }
    }
    mts_stream_free(&s);
}

/* Normals travel exactly when the source had its own: then the client
 * holds the server's (octahedral-coded, bit for bit); without, neither end
 * has any and the stream is smaller by them. */
static void test_normals_travel_when_given(mts_test *t)
{
    mts_stream with, without;
    if (!build_stream_normals(t, "tests/data/cow.off", 1, &with))
        return;
    if (!build_stream(t, "tests/data/cow.off", &without)) {
        mts_stream_free(&with);
        return;
    }
    mts_stream *both[2] = {&with, &without};
    size_t sizes[2] = {0, 0};
    for (int k = 0; k < 2; k++) {
        mts_stream *s = both[k];
        const size_t nv = s->model.vertex_count;
        mts_buf b = {0};
        uint32_t stop;
        connection_bytes(s, MTS_STOP_FULL, 0, &b, &stop);
        sizes[k] = b.size;
        mts_stream_client c;
        mts_stream_client_init(&c);
        mts_error err = {0};
        int saw_end;
        mts_result rc = feed(&c, b.data, b.size, 7, &saw_end, &err);
        CHECKF(t, rc == MTS_OK && saw_end, "%s", err.msg);
        CHECK(t, !!(c.info.flags & MTS_INFO_NORMALS) == (k == 0));
        same_as_server(t, s, &c); /* normals included, bit for bit */
        size_t unit = 0;
        for (size_t x = 0; x < nv; x++) {
            const float *q = c.model.normals + 3 * x;
            float l = q[0] * q[0] + q[1] * q[1] + q[2] * q[2];
            unit += l > 0.999f && l < 1.001f;
        }
        CHECKF(t, k == 0 ? unit == nv : unit == 0, "%zu of %zu unit normals", unit, nv);
        mts_stream_client_free(&c);
        mts_buf_free(&b);
    }
    /* 2 x 16 bits a vertex, coded: at least a byte a vertex saved */
    CHECKF(t, sizes[1] + with.model.vertex_count < sizes[0], "%zu with normals, %zu without",
           sizes[0], sizes[1]);
    mts_stream_free(&with);
    mts_stream_free(&without);
}

/* A MODEL_INFO whose triangle count the strip slots cannot hold (a hostile
 * server's way to make later counts huge) is refused before any batch. */
static void test_info_triangles_bounded(mts_test *t)
{
    mts_stream s;
    if (!build_stream(t, "tests/data/cow.off", &s))
        return;
    mts_buf b = {0};
    mts_stream_put_model_info(&s, s.model.level_count, &b);
    mts_wire_model_info mi = {0};
    mts_error err = {0};
    CHECKF(t, mts_wire_parse_model_info(b.data + MTS_WIRE_HEADER, b.size - MTS_WIRE_HEADER, &mi,
                                        &err) == MTS_OK,
           "%s", err.msg);
    uint64_t cap = 0;
    for (uint32_t i = 0; i < mi.strips; i++)
        cap += mi.capacities[i];
    mi.triangles = (uint32_t)cap + 1;
    mts_buf bad = {0};
    mts_wire_put_model_info(&bad, &mi);
    mts_stream_client c;
    mts_stream_client_init(&c);
    int saw_end;
    mts_result rc = feed(&c, bad.data, bad.size, 0, &saw_end, &err);
    CHECKF(t, rc == MTS_ERR_FORMAT && strstr(err.msg, "cannot fit strip slots"), "%s", err.msg);
    mts_stream_client_free(&c);
    mts_wire_model_info_free(&mi);
    mts_buf_free(&bad);
    mts_buf_free(&b);
    mts_stream_free(&s);
}

static void test_corrupt_batch_rejected(mts_test *t)
{
    mts_stream s;
    if (!build_stream(t, "tests/data/cow.off", &s))
        return;
    mts_buf b = {0};
    uint32_t stop;
    connection_bytes(&s, MTS_STOP_FULL, 0, &b, &stop);
    /* flip a byte inside the third batch's payload (MODEL_INFO comes first) */
    uint32_t len = b.data[0] | b.data[1] << 8 | b.data[2] << 16 | (uint32_t)b.data[3] << 24;
    size_t info_size = 4 + (size_t)len;
    size_t at = info_size + s.batch_offset[2] + 12;
    b.data[at] ^= 0x10;
    mts_stream_client c;
    mts_stream_client_init(&c);
    mts_error err = {0};
    int saw_end;
    mts_result rc = feed(&c, b.data, b.size, 1, &saw_end, &err);
    CHECK(t, rc == MTS_ERR_CHECKSUM);
    CHECKF(t, strstr(err.msg, "BATCH 2") && strstr(err.msg, "not applied"), "%s", err.msg);
    CHECK(t, c.batches == 2 && c.lod.level == s.batch_first[2]);
    same_as_server(t, &s, &c); /* still exactly the model at the last whole batch */
    mts_stream_client_free(&c);
    mts_buf_free(&b);
    mts_stream_free(&s);
}

static void test_cut_stream_keeps_last_batch(mts_test *t)
{
    mts_stream s;
    if (!build_stream(t, "tests/data/cow.off", &s))
        return;
    mts_buf b = {0};
    uint32_t stop;
    connection_bytes(&s, MTS_STOP_FULL, 0, &b, &stop);
    uint64_t seed = 5;
    for (int round = 0; round < 25; round++) {
        seed = seed * 6364136223846793005ull + 1442695040888963407ull;
        size_t cut = (size_t)(seed >> 33) % b.size;
        mts_stream_client c;
        mts_stream_client_init(&c);
        mts_error err = {0};
        int saw_end;
        CHECK(t, feed(&c, b.data, cut, seed, &saw_end, &err) == MTS_OK);
        CHECK(t, !saw_end);
        if (c.have_lod)
            same_as_server(t, &s, &c);
        mts_stream_client_free(&c);
    }
    mts_buf_free(&b);
    mts_stream_free(&s);
}

static void test_garbage_frames(mts_test *t)
{
    uint64_t seed = 11;
    for (int round = 0; round < 2000; round++) {
        uint8_t junk[96];
        for (size_t i = 0; i < sizeof junk; i++) {
            seed = seed * 6364136223846793005ull + 1442695040888963407ull;
            junk[i] = (uint8_t)(seed >> 56);
        }
        mts_stream_client c;
        mts_stream_client_init(&c);
        mts_error err = {0};
        mts_stream_event ev;
        uint8_t type = (uint8_t)(16 + round % 5);
        (void)mts_stream_client_frame(&c, type, junk, (size_t)(round % 96), &ev, &err);
        mts_stream_client_free(&c);
    }
    CHECK(t, 1); /* reaching here under ASan is the assertion: no crash, no leak */
}

static void shared_model_stops(mts_test *t, const char *file)
{
    char buf[1024];
    const char *path = mts_test_model(file, buf, sizeof buf);
    if (!path)
        SKIP(t, "%s not found", buf);
    mts_stream s;
    if (!build_stream(t, path, &s))
        return;
    if (getenv("MTS_TEST_VERBOSE"))
        fprintf(stderr, "  %s: stream %zu bytes (base frame %zu), %u batches, draco %s\n", file,
                s.size, s.batch_offset[0], s.batch_count,
                s.draco_method == MTS_DRACO_SEQUENTIAL ? "sequential" : "edgebreaker");
    /* the full level and two partial stops */
    const uint8_t kinds[3] = {MTS_STOP_FULL, MTS_STOP_FRACTION, MTS_STOP_TRIANGLES};
    const uint32_t values[3] = {0, 250000, 40000};
    for (int i = 0; i < 3; i++) {
        mts_buf b = {0};
        uint32_t stop;
        connection_bytes(&s, kinds[i], values[i], &b, &stop);
        mts_stream_client c;
        mts_stream_client_init(&c);
        mts_error err = {0};
        int saw_end;
        CHECKF(t, feed(&c, b.data, b.size, 3 + (uint64_t)i, &saw_end, &err) == MTS_OK && saw_end,
               "%s", err.msg);
        CHECK(t, c.lod.level == stop);
        same_as_server(t, &s, &c);
        if (getenv("MTS_TEST_VERBOSE"))
            fprintf(stderr, "  %s stop %d: level %u, %zu bytes\n", file, i, stop, b.size);
        mts_stream_client_free(&c);
        mts_buf_free(&b);
    }
    mts_stream_free(&s);
}

/* fandisk's box has an origin Draco cannot store exactly (-4.7e-15 becomes
 * -0): the stream must use Draco's grid for every vertex */
static void test_bunny_stops(mts_test *t)
{
    shared_model_stops(t, "bunny00.off");
}

static void test_fandisk_stops(mts_test *t)
{
    shared_model_stops(t, "fandisk_large.off");
}

/* ---- records the client derives --------------------------------------
 *
 * The stream carries no records (PROTOCOL.md, BATCH): the client derives
 * each from the split's fan code (common/grow.h). On cow, whose base Draco's
 * Edgebreaker renumbers, the client's records equal the stream model's word
 * for word (the derivation looks at vertex ids only for equality), key
 * levels included, and they move the client both ways. */
static void test_client_derives_every_record(mts_test *t)
{
    mts_stream s;
    if (!build_stream(t, "tests/data/cow.off", &s))
        return;
    mts_error err = {0};
    const mts_model *sm = &s.model;
    CHECKF(t, sm->key_count >= 5, "%u key levels", sm->key_count);
    /* the renumbered model still derives its own records */
    mts_verify_report vr;
    CHECKF(t, mts_verify_growth(sm, &vr, &err) == MTS_OK, "renumbered: %s", err.msg);
    mts_buf b = {0};
    uint32_t stop;
    connection_bytes(&s, MTS_STOP_FULL, 0, &b, &stop);
    mts_stream_client c;
    mts_stream_client_init(&c);
    int saw_end;
    mts_result rc = feed(&c, b.data, b.size, 11, &saw_end, &err);
    CHECKF(t, rc == MTS_OK && saw_end, "%s", err.msg);
    CHECK(t, c.info.key_count == sm->key_count &&
             memcmp(c.info.key_levels, sm->key_levels, (size_t)sm->key_count * 4) == 0);
    CHECK(t, c.model.record_word_count == sm->record_word_count);
    CHECK(t, memcmp(c.model.record_offsets, sm->record_offsets,
                    ((size_t)sm->level_count + 1) * 4) == 0);
    CHECK(t, memcmp(c.model.record_data, sm->record_data, (size_t)sm->record_word_count * 4) ==
                 0);
    CHECK(t, memcmp(c.model.parents, sm->parents, (size_t)sm->level_count * 4) == 0);
    /* a key level's record erases runs; down to the base and back up */
    uint64_t erased = 0;
    for (uint32_t j = 0; j < sm->level_count; j++) {
        const uint32_t *w = sm->record_data + sm->record_offsets[j];
        for (uint32_t e = 0, edits = *w++; e < edits; e++) {
            erased += w[1];
            uint32_t runs = w[1] + w[2], substs = w[3];
            w += 4;
            for (uint32_t r = 0; r < runs; r++)
                w += 2 + w[1];
            w += substs;
        }
    }
    CHECK(t, erased > 0);
    CHECK(t, mts_lod_set_level(&c.lod, 0, &err) == MTS_OK);
    same_as_server(t, &s, &c);
    CHECK(t, mts_lod_set_level(&c.lod, sm->key_levels[1], &err) == MTS_OK);
    same_as_server(t, &s, &c);
    CHECK(t, mts_lod_set_level(&c.lod, sm->level_count, &err) == MTS_OK);
    same_as_server(t, &s, &c);
    mts_stream_client_free(&c);

    /* a batch whose coded splits are damaged after the CRC was taken (a
     * byte of the first batch's range-coded body flipped, CRC resealed):
     * what decodes no longer names fans of the mesh or ends where the
     * message does, and the batch is refused whole */
    size_t at = 0;
    while (at + 5 < b.size && b.data[at + 4] != MTS_MSG_BATCH)
        at += 4 + (b.data[at] | b.data[at + 1] << 8 | b.data[at + 2] << 16 |
                   (size_t)b.data[at + 3] << 24);
    size_t flen = b.data[at] | b.data[at + 1] << 8 | b.data[at + 2] << 16 |
                  (size_t)b.data[at + 3] << 24;
    uint8_t *pl = b.data + at + 5;
    mts_cursor cur = mts_cursor_make(pl, flen - 1);
    for (int k = 0; k < 3; k++) /* index, first, count */
        mts_cursor_varint(&cur);
    size_t body = (size_t)(cur.p - pl);
    CHECK(t, cur.ok && body + 8 < flen - 1 - 4);
    pl[body + 2] ^= 0x5a;
    uint32_t crc = mts_crc32c(0, pl, flen - 1 - 4);
    for (int k = 0; k < 4; k++)
        pl[flen - 1 - 4 + k] = (uint8_t)(crc >> (8 * k));
    mts_stream_client_init(&c);
    rc = feed(&c, b.data, b.size, 0, &saw_end, &err);
    CHECKF(t, (rc == MTS_ERR_FORMAT || rc == MTS_ERR_RANGE) && strncmp(err.msg, "BATCH 0: ", 9) == 0,
           "%s", err.msg);
    CHECK(t, c.batches == 0 && c.lod.level == 0);
    mts_stream_client_free(&c);
    mts_buf_free(&b);
    mts_stream_free(&s);
}

/* A model without split descriptions (one made by hand, or by an older
 * build) cannot be streamed, and says why. */
static void test_model_without_descriptions_refused(mts_test *t)
{
    mts_stream s;
    mts_error err = {0};
    mts_model m;
    mts_mesh mesh = {0};
    if (mts_mesh_load("tests/data/cow.off", NULL, &mesh, NULL, &err) != MTS_OK) {
        CHECKF(t, 0, "%s", err.msg);
        return;
    }
    mts_result rc = mts_build_model(&mesh, "cow", NULL, &m, NULL, &err);
    mts_mesh_free(&mesh);
    CHECKF(t, rc == MTS_OK, "%s", err.msg);
    if (rc != MTS_OK)
        return;
    free(m.growth_data);
    m.growth_data = NULL;
    rc = mts_stream_build(&m, "cow", NULL, &s, &err);
    CHECKF(t, rc == MTS_ERR_ARG && strstr(err.msg, "no split descriptions") &&
                  strstr(err.msg, "rebuild"),
           "%s", err.msg);
    mts_model_free(&m);
}

int main(void)
{
    mts_test t = {0};
    RUN(&t, test_cow_every_stop);
    RUN(&t, test_normals_travel_when_given);
    RUN(&t, test_info_triangles_bounded);
    RUN(&t, test_corrupt_batch_rejected);
    RUN(&t, test_cut_stream_keeps_last_batch);
    RUN(&t, test_garbage_frames);
    RUN(&t, test_client_derives_every_record);
    RUN(&t, test_model_without_descriptions_refused);
    RUN(&t, test_bunny_stops);
    RUN(&t, test_fandisk_stops);
    return mts_test_end(&t);
}
