/* A model's wire stream end to end in memory: the client's mesh equals the
 * server's model at the level it asked for (strips exactly, positions bit for
 * bit on the grid), whatever the stop point and however the bytes are split;
 * a corrupted batch is rejected and not applied; a cut stream leaves the
 * client at its last whole batch with a consistent mesh; records that erase
 * runs are renumbered with the base, streamed and applied both ways, and the
 * slots are MODEL_INFO's capacities (the longest at any level). */
#include <stdint.h>

#include "build.h"
#include "mesh.h"
#include "stream.h"
#include "test.h"
#include "verify.h"
#include "wire.h"

static int build_stream(mts_test *t, const char *path, mts_stream *s)
{
    mts_error err = {0};
    mts_mesh mesh = {0};
    mts_model m;
    if (mts_mesh_load(path, NULL, &mesh, NULL, &err) != MTS_OK) {
        CHECKF(t, 0, "%s", err.msg);
        return 0;
    }
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

/* ---- a hand-made model whose splits erase runs ------------------------
 *
 * Six base vertices in a 2 x 3 grid, one strip; split 0 brings back vertex 6
 * (parent 4) by erasing the strip's tail [4 5] and inserting [4 5 4], whose
 * last 4 becomes 6; split 1 brings back 7 (parent 5) by erasing all of strip 0
 * in two runs and building strip 1 afresh, as at a key level. So slot 0 is
 * longest (7) at level 1 and empty at the full level, and both erased runs
 * hold base vertices that Draco's renumbering must rename. */
static const float hand_pos[8][3] = {{0, 0, 0}, {0, 1, 0}, {1, 0, 0}, {1, 1, 0},
                                     {2, 0, 0}, {2, 1, 0}, {3, 0, 0}, {3, 1, 0}};
static const uint32_t hand_base0[6] = {0, 1, 2, 3, 4, 5};
static const uint32_t hand_level1_strip0[7] = {0, 1, 2, 3, 4, 5, 6};
static const uint32_t hand_full1[8] = {0, 1, 2, 3, 4, 5, 6, 7};
static const uint32_t hand_records[] = {
    /* split 0: one edit on strip 0: erase (4, 2: 4 5), insert (4, 3: 4 5 4), subst 6 */
    1, 0, 1, 1, 1, 4, 2, 4, 5, 4, 3, 4, 5, 4, 6,
    /* split 1: strip 0 erases (4, 3: 4 5 6) then (0, 4: 0 1 2 3); strip 1
     * inserts (0, 8: 0 1 2 3 4 5 6 5) and turns position 7 into 7 */
    2, 0, 2, 0, 0, 4, 3, 4, 5, 6, 0, 4, 0, 1, 2, 3,
    1, 0, 1, 1, 0, 8, 0, 1, 2, 3, 4, 5, 6, 5, 7};

static uint32_t *hand_words(const uint32_t *w, size_t n)
{
    uint32_t *c = malloc(n * 4 + 4);
    if (c)
        memcpy(c, w, n * 4);
    return c;
}

static void hand_model(mts_model *m)
{
    memset(m, 0, sizeof *m);
    m->vertex_count = 8;
    m->base_vertex_count = 6;
    m->level_count = 2;
    m->strip_count = 2;
    m->positions = malloc(sizeof hand_pos);
    memcpy(m->positions, hand_pos, sizeof hand_pos);
    m->normals = calloc(24, sizeof(float));
    for (int x = 0; x < 8; x++)
        m->normals[3 * x + 2] = -1.0f;
    m->bbox_max[0] = 3;
    m->bbox_max[1] = 1;
    const uint32_t parents[2] = {4, 5}, capacity[2] = {7, 8};
    m->parents = hand_words(parents, 2);
    m->capacity = hand_words(capacity, 2);
    mts_strips_alloc(&m->base, 2, 6, NULL);
    m->base.offsets[1] = m->base.offsets[2] = 6;
    memcpy(m->base.indices, hand_base0, sizeof hand_base0);
    mts_strips_alloc(&m->full, 2, 8, NULL);
    m->full.offsets[1] = 0;
    m->full.offsets[2] = 8;
    memcpy(m->full.indices, hand_full1, sizeof hand_full1);
    const uint32_t offsets[3] = {0, 15, (uint32_t)(sizeof hand_records / 4)};
    m->record_offsets = hand_words(offsets, 3);
    m->record_data = hand_words(hand_records, sizeof hand_records / 4);
    m->record_word_count = offsets[2];
    const uint32_t tris[3] = {4, 5, 6}, strips[3] = {1, 1, 1}, indices[3] = {6, 7, 8};
    m->level_triangles = hand_words(tris, 3);
    m->level_strips = hand_words(strips, 3);
    m->level_indices = hand_words(indices, 3);
    snprintf(m->source, sizeof m->source, "hand");
}

/* strip s of the runtime is want[] with base vertices renamed by map */
static int strip_is(const mts_lod *lod, uint32_t s, const uint32_t *want, uint32_t n,
                    const uint32_t *map)
{
    uint32_t len;
    const uint32_t *str = mts_lod_strip(lod, s, &len);
    if (len != n)
        return 0;
    for (uint32_t k = 0; k < n; k++) {
        if (str[k] != (want[k] < 6 ? map[want[k]] : want[k]))
            return 0;
    }
    return 1;
}

static void test_erased_runs_renumbered_and_streamed(mts_test *t)
{
    mts_model m;
    mts_error err = {0};
    hand_model(&m);
    CHECKF(t, mts_model_validate(&m, &err) == MTS_OK, "the hand model: %s", err.msg);
    mts_stream_options o = {0};
    o.batch_splits = 1;
    mts_stream s;
    mts_result rc = mts_stream_build(&m, "hand", &o, &s, &err);
    CHECKF(t, rc == MTS_OK, "stream: %s", err.msg);
    if (rc != MTS_OK) {
        mts_model_free(&m);
        return;
    }
    /* Draco's renaming, read back from the positions (each base vertex is
     * the one of the stream's nearest to it); Edgebreaker reverses this base
     * (map 5 4 3 2 1 0), so every erased run is renamed */
    uint32_t map[6];
    for (uint32_t x = 0; x < 6; x++) {
        float best = 1e30f;
        for (uint32_t y = 0; y < 6; y++) {
            float d = 0;
            for (int a = 0; a < 3; a++) {
                float e = s.model.positions[3 * y + a] - hand_pos[x][a];
                d += e * e;
            }
            if (d < best) {
                best = d;
                map[x] = y;
            }
        }
    }
    if (getenv("MTS_TEST_VERBOSE"))
        fprintf(stderr, "  hand model: Draco %s, base renamed %u %u %u %u %u %u\n",
                s.draco_method == MTS_DRACO_SEQUENTIAL ? "sequential" : "edgebreaker", map[0],
                map[1], map[2], map[3], map[4], map[5]);
    /* the stream's model: capacities copied, records renamed, erased runs too */
    CHECK(t, s.model.capacity != m.capacity && s.model.capacity[0] == 7 &&
             s.model.capacity[1] == 8);
    const uint32_t *w = s.model.record_data;
    CHECK(t, w[5] == 4 && w[6] == 2 && w[7] == map[4] && w[8] == map[5]);   /* erased */
    CHECK(t, w[9] == 4 && w[10] == 3 && w[11] == map[4] && w[13] == map[4]); /* inserted */
    CHECK(t, w[15 + 7] == map[4] && w[15 + 8] == map[5] && w[15 + 9] == 6);
    CHECK(t, w[15 + 12] == map[0] && w[15 + 15] == map[3]);
    CHECK(t, w[15 + 22] == map[0] && w[15 + 27] == map[5] && w[15 + 28] == 6 &&
             w[15 + 29] == map[5] && w[15 + 30] == 7);
    mts_verify_report vr;
    CHECKF(t, mts_verify_model(&s.model, NULL, &vr, &err) == MTS_OK, "verify: %s", err.msg);
    CHECK(t, vr.levels_checked == 3);

    for (uint32_t stop = 0; stop <= 2 && !t->case_failed; stop++) {
        mts_buf b = {0};
        uint32_t got_stop;
        connection_bytes(&s, MTS_STOP_LEVEL, stop, &b, &got_stop);
        CHECK(t, got_stop == stop);
        mts_stream_client c;
        mts_stream_client_init(&c);
        int saw_end;
        rc = feed(&c, b.data, b.size, 7 + stop, &saw_end, &err);
        CHECKF(t, rc == MTS_OK && saw_end, "stop %u: %s", stop, err.msg);
        CHECK(t, c.lod.level == stop && c.checksum == c.end_checksum);
        /* the slots' room is MODEL_INFO's capacities, not the full lengths */
        CHECK(t, c.info.capacities[0] == 7 && c.info.capacities[1] == 8);
        CHECK(t, c.model.capacity && c.model.capacity[0] == 7 && c.model.capacity[1] == 8);
        same_as_server(t, &s, &c);
        if (stop == 1)
            CHECK(t, strip_is(&c.lod, 0, hand_level1_strip0, 7, map) &&
                         strip_is(&c.lod, 1, NULL, 0, map));
        if (stop == 2) {
            CHECK(t, strip_is(&c.lod, 0, NULL, 0, map) && strip_is(&c.lod, 1, hand_full1, 8, map));
            /* down to the base (the erased runs come back) and up again */
            CHECK(t, mts_lod_set_level(&c.lod, 0, &err) == MTS_OK);
            CHECK(t, strip_is(&c.lod, 0, hand_base0, 6, map) && strip_is(&c.lod, 1, NULL, 0, map));
            CHECK(t, mts_lod_set_level(&c.lod, 1, &err) == MTS_OK);
            CHECK(t, strip_is(&c.lod, 0, hand_level1_strip0, 7, map));
            CHECKF(t, mts_lod_set_level(&c.lod, 2, &err) == MTS_OK, "%s", err.msg);
            same_as_server(t, &s, &c);
        }
        mts_stream_client_free(&c);
        mts_buf_free(&b);
    }

    /* a MODEL_INFO whose capacity is below the base strip: BASE is refused */
    mts_buf b = {0};
    uint32_t stop;
    connection_bytes(&s, MTS_STOP_FULL, 0, &b, &stop);
    uint32_t len = b.data[0] | b.data[1] << 8 | b.data[2] << 16 | (uint32_t)b.data[3] << 24;
    mts_wire_model_info mi = {0};
    CHECK(t, mts_wire_parse_model_info(b.data + 5, len - 1, &mi, &err) == MTS_OK);
    if (mi.capacities) {
        mi.capacities[0] = 5;
        mts_buf bad = {0};
        mts_wire_put_model_info(&bad, &mi);
        mts_buf_put(&bad, b.data + 4 + len, b.size - 4 - len);
        mts_stream_client c;
        mts_stream_client_init(&c);
        int saw_end;
        rc = feed(&c, bad.data, bad.size, 0, &saw_end, &err);
        CHECKF(t, rc == MTS_ERR_RANGE && strstr(err.msg, "capacity"), "%s", err.msg);
        mts_stream_client_free(&c);
        mts_buf_free(&bad);
    }
    mts_wire_model_info_free(&mi);
    mts_buf_free(&b);
    mts_stream_free(&s);
    mts_model_free(&m);
}

int main(void)
{
    mts_test t = {0};
    RUN(&t, test_cow_every_stop);
    RUN(&t, test_corrupt_batch_rejected);
    RUN(&t, test_cut_stream_keeps_last_batch);
    RUN(&t, test_garbage_frames);
    RUN(&t, test_erased_runs_renumbered_and_streamed);
    RUN(&t, test_bunny_stops);
    RUN(&t, test_fandisk_stops);
    return mts_test_end(&t);
}
