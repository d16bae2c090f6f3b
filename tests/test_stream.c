/* A model's wire stream end to end in memory: the client's mesh equals the
 * server's model at the level it asked for (strips exactly, positions bit for
 * bit on the grid), whatever the stop point and however the bytes are split;
 * a corrupted batch is rejected and not applied; a cut stream leaves the
 * client at its last whole batch with a consistent mesh; the client derives
 * every record from the splits' fan codes, word for word the model's, and
 * moves both ways with them. */
#include <math.h>
#include <stdint.h>

#include "build.h"
#include "crc32c.h"
#include "reccodec.h"
#include "mesh.h"
#include "stream.h"
#include "test.h"
#include "test_proc.h"
#include "verify.h"
#include "wire.h"

/* normals_given: treat the mesh's (computed) normals as the file's own, so
 * the stream carries them; opts may be NULL. */
static int build_model(mts_test *t, const char *path, int normals_given, mts_model *m)
{
    mts_error err = {0};
    mts_mesh mesh = {0};
    if (mts_mesh_load(path, NULL, &mesh, NULL, &err) != MTS_OK) {
        CHECKF(t, 0, "%s", err.msg);
        return 0;
    }
    if (normals_given)
        mesh.normals_given = 1;
    mts_result rc = mts_build_model(&mesh, path, NULL, m, NULL, &err);
    mts_mesh_free(&mesh);
    CHECKF(t, rc == MTS_OK, "%s", err.msg);
    return rc == MTS_OK;
}

static int build_stream_opts(mts_test *t, const char *path, int normals_given,
                             const mts_stream_options *opts, mts_stream *s)
{
    mts_error err = {0};
    mts_model m;
    if (!build_model(t, path, normals_given, &m))
        return 0;
    mts_result rc = mts_stream_build(&m, "cow", opts, s, &err);
    mts_model_free(&m);
    CHECKF(t, rc == MTS_OK, "stream: %s", err.msg);
    return rc == MTS_OK;
}

static int build_stream_normals(mts_test *t, const char *path, int normals_given, mts_stream *s)
{
    return build_stream_opts(t, path, normals_given, NULL, s);
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

/* Feeds bytes in pieces from a seeded generator; *saw_end: END came. */
static mts_result feed(mts_stream_client *c, const uint8_t *data, size_t size, uint64_t seed,
                       int *saw_end, mts_error *err)
{
    mts_test_events n = {0};
    mts_result rc = mts_test_feed(c, data, size, seed, 977, &n, err);
    *saw_end = n.end > 0;
    return rc;
}

/* A fresh client c fed what a connection to s for (kind, value) is sent, in
 * pieces from seed: 1 when it ended (END) without an error (else in err).
 * The level it stops at in *stop, the bytes in *bytes (may be NULL). */
static int receive(const mts_stream *s, uint8_t kind, uint32_t value, uint64_t seed,
                   mts_stream_client *c, uint32_t *stop, size_t *bytes, mts_error *err)
{
    mts_buf b = {0};
    connection_bytes(s, kind, value, &b, stop);
    if (bytes)
        *bytes = b.size;
    mts_stream_client_init(c);
    int saw_end;
    mts_result rc = feed(c, b.data, b.size, seed, &saw_end, err);
    mts_buf_free(&b);
    return rc == MTS_OK && saw_end;
}

/* How many of the first count normals are of unit length. */
static size_t unit_normals(const float *normals, size_t count)
{
    size_t unit = 0;
    for (size_t x = 0; x < count; x++) {
        const float *q = normals + 3 * x;
        float l = q[0] * q[0] + q[1] * q[1] + q[2] * q[2];
        unit += l > 0.999f && l < 1.001f;
    }
    return unit;
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
    /* built without the records form: a HELLO asking for records gets this */
    CHECK(t, s.records_form == NULL && !s.records);
    CHECK(t, mts_stream_for_hello(&s, MTS_HELLO_RECORDS) == &s);
    const uint32_t n = s.model.level_count;
    struct {
        uint8_t kind;
        uint32_t value;
    } stops[] = {{MTS_STOP_FULL, 0},         {MTS_STOP_LEVEL, n / 3},
                 {MTS_STOP_LEVEL, 0},        {MTS_STOP_TRIANGLES, 1000},
                 {MTS_STOP_FRACTION, 500000}, {MTS_STOP_LEVEL, 999999}};
    for (size_t i = 0; i < sizeof stops / sizeof stops[0] && !t->case_failed; i++) {
        for (uint64_t seed = 0; seed < 4; seed++) {
            uint32_t stop;
            mts_stream_client c;
            mts_error err = {0};
            CHECKF(t, receive(&s, stops[i].kind, stops[i].value, seed, &c, &stop, NULL, &err),
                   "stop %zu seed %llu: %s", i, (unsigned long long)seed, err.msg);
            CHECK(t, c.lod.level == stop);
            CHECK(t, c.checksum == c.end_checksum);
            same_as_server(t, &s, &c);
            mts_stream_client_free(&c);
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
        uint32_t stop;
        mts_stream_client c;
        mts_error err = {0};
        CHECKF(t, receive(s, MTS_STOP_FULL, 0, 7, &c, &stop, &sizes[k], &err), "%s", err.msg);
        CHECK(t, !!(c.info.flags & MTS_INFO_NORMALS) == (k == 0));
        same_as_server(t, s, &c); /* normals included, bit for bit */
        size_t unit = unit_normals(c.model.normals, nv);
        CHECKF(t, k == 0 ? unit == nv : unit == 0, "%zu of %zu unit normals", unit, nv);
        mts_stream_client_free(&c);
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
    mi.triangles = mi.capacity_total + 1;
    mts_buf bad = {0};
    mts_wire_put_model_info(&bad, &mi);
    mts_stream_client c;
    mts_stream_client_init(&c);
    int saw_end;
    mts_result rc = feed(&c, bad.data, bad.size, 0, &saw_end, &err);
    CHECKF(t, rc == MTS_ERR_FORMAT && strstr(err.msg, "triangles, more than strip capacities"),
           "%s", err.msg);
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

/* What a client made of a stream: its events in order, where it ended. */
typedef struct fed {
    uint8_t events[4096];
    size_t count;
    int failed; /* next returned -1 */
    uint64_t checksum, end_checksum;
    uint32_t level, batches;
} fed;

static void fed_event(fed *f, mts_stream_event ev)
{
    if (f->count < sizeof f->events)
        f->events[f->count] = (uint8_t)ev;
    f->count++;
}

static void fed_end(fed *f, const mts_stream_client *c)
{
    f->checksum = c->checksum;
    f->end_checksum = c->end_checksum;
    f->level = c->have_lod ? c->lod.level : 0;
    f->batches = c->batches;
}

/* The reference: the connection's frames cut out here and handed to
 * mts_stream_client_frame whole, one by one. */
static void feed_whole_frames(const mts_buf *b, fed *f)
{
    mts_stream_client c;
    mts_stream_client_init(&c);
    mts_error err = {0};
    size_t at = 0;
    while (at + MTS_WIRE_HEADER <= b->size && !f->failed) {
        const uint8_t *h = b->data + at;
        size_t len = (size_t)h[0] | (size_t)h[1] << 8 | (size_t)h[2] << 16 | (size_t)h[3] << 24;
        mts_stream_event ev;
        f->failed = mts_stream_client_frame(&c, h[4], h + MTS_WIRE_HEADER, len - 1, &ev, &err) !=
                    MTS_OK;
        if (!f->failed)
            fed_event(f, ev);
        at += 4 + len;
    }
    fed_end(f, &c);
    mts_stream_client_free(&c);
}

/* b through feed and next, in pieces of 1..max_piece bytes from seed. */
static void feed_pieces(mts_test *t, const mts_buf *b, uint64_t seed, size_t max_piece, fed *f)
{
    mts_stream_client c;
    mts_stream_client_init(&c);
    mts_error err = {0};
    size_t at = 0;
    while (at < b->size && !f->failed) {
        seed = seed * 6364136223846793005ull + 1442695040888963407ull;
        size_t piece = 1 + (size_t)((seed >> 33) % max_piece);
        if (piece > b->size - at)
            piece = b->size - at;
        CHECKF(t, mts_stream_client_feed(&c, b->data + at, piece, &err) == MTS_OK, "%s", err.msg);
        at += piece;
        mts_stream_event ev;
        int got;
        while ((got = mts_stream_client_next(&c, &ev, &err)) > 0)
            fed_event(f, ev);
        f->failed = got < 0;
    }
    CHECKF(t, !f->failed, "%s", err.msg);
    CHECK(t, mts_stream_client_buffered(&c) == 0);
    fed_end(f, &c);
    mts_stream_client_free(&c);
}

static int fed_same(const fed *a, const fed *b)
{
    size_t kept = a->count < sizeof a->events ? a->count : sizeof a->events;
    return a->count == b->count && a->failed == b->failed &&
           memcmp(a->events, b->events, kept) == 0 && a->checksum == b->checksum &&
           a->end_checksum == b->end_checksum && a->level == b->level &&
           a->batches == b->batches;
}

/* Bytes split anywhere give what whole frames give: the same events in the
 * same order, the same mesh. */
static void test_feed_any_split(mts_test *t)
{
    mts_stream s;
    if (!build_stream(t, "tests/data/cow.off", &s))
        return;
    const uint32_t stops[2] = {s.model.level_count, s.model.level_count / 3};
    for (int k = 0; k < 2 && !t->case_failed; k++) {
        mts_buf b = {0};
        uint32_t stop;
        connection_bytes(&s, MTS_STOP_LEVEL, stops[k], &b, &stop);
        fed whole = {0};
        feed_whole_frames(&b, &whole);
        /* MODEL_INFO, BASE, the batches, END */
        CHECK(t, !whole.failed && whole.count == (size_t)whole.batches + 3 && whole.level == stop);
        CHECK(t, whole.checksum == s.level_checksum[stop] && whole.end_checksum == whole.checksum);
        fed one = {0};
        feed_pieces(t, &b, 0, 1, &one);
        CHECKF(t, fed_same(&whole, &one), "stop %u, a byte at a time: %zu events, checksum %016llx",
               stop, one.count, (unsigned long long)one.checksum);
        for (uint64_t seed = 1; seed <= 20 && !t->case_failed; seed++) {
            fed some = {0};
            size_t max_piece = seed % 4 == 0 ? b.size : seed % 4 == 1 ? 7 : 3000;
            feed_pieces(t, &b, seed, max_piece, &some);
            CHECKF(t, fed_same(&whole, &some), "stop %u, seed %llu, pieces up to %zu", stop,
                   (unsigned long long)seed, max_piece);
        }
        mts_buf_free(&b);
    }
    mts_stream_free(&s);
}

/* A connection that breaks inside a frame leaves its start in the client;
 * the new conversation drops it, so the resumed stream ends as the
 * unbroken one. The same after END for a continuation. */
static void test_feed_reconnect_drops_cut_frame(mts_test *t)
{
    mts_stream s;
    if (!build_stream(t, "tests/data/cow.off", &s))
        return;
    const uint32_t n = s.model.level_count;
    mts_error err = {0};
    mts_buf first = {0};
    uint32_t stop;
    connection_bytes(&s, MTS_STOP_FULL, 0, &first, &stop);
    mts_buf info = {0};
    mts_stream_put_model_info(&s, n, &info);
    size_t cut = info.size + s.batch_offset[4] + 10; /* inside batch 4 */
    mts_stream_client c;
    mts_stream_client_init(&c);
    mts_test_events ev = {0};
    CHECKF(t, mts_test_feed(&c, first.data, cut, 1, 977, &ev, &err) == MTS_OK, "%s", err.msg);
    CHECK(t, c.batches == 4 && ev.batch == 4 && mts_stream_client_buffered(&c) == 10);
    uint32_t batch;
    uint64_t id;
    CHECK(t, mts_stream_client_resume_point(&c, &batch, &id) && batch == 4);
    CHECK(t, mts_stream_client_reconnected(&c, &err) == MTS_OK);
    CHECK(t, mts_stream_client_buffered(&c) == 0);
    /* what the server sends for the resume: MODEL_INFO, batches 4.., END */
    mts_buf second = {0};
    size_t off, len;
    CHECK(t, mts_stream_range(&s, batch, n, &off, &len, &err) == MTS_OK);
    mts_stream_put_model_info(&s, n, &second);
    size_t head = second.size;
    mts_buf_put(&second, s.bytes + off, len);
    mts_stream_put_end(&s, n, (uint32_t)(head + len), &second);
    CHECKF(t, mts_test_feed(&c, second.data, second.size, 2, 977, &ev, &err) == MTS_OK, "%s",
           err.msg);
    CHECK(t, ev.resumed == 1 && ev.end == 1 && (uint32_t)ev.batch == s.batch_count);
    CHECK(t, c.checksum == s.level_checksum[n] && c.end_checksum == c.checksum);
    CHECK(t, mts_stream_client_buffered(&c) == 0);

    /* after END: the start of a frame that never came whole, dropped by
     * continue */
    CHECK(t, mts_stream_client_feed(&c, first.data, 3, &err) == MTS_OK);
    mts_stream_event e;
    CHECK(t, mts_stream_client_next(&c, &e, &err) == 0 && mts_stream_client_buffered(&c) == 3);
    CHECK(t, mts_stream_client_continue(&c, &batch, &id, &err) == MTS_OK);
    CHECK(t, mts_stream_client_buffered(&c) == 0);
    mts_stream_client_free(&c);

    /* before the base: a fresh start, the partial MODEL_INFO dropped */
    mts_stream_client_init(&c);
    ev = (mts_test_events){0};
    CHECK(t, mts_test_feed(&c, first.data, info.size - 1, 3, 977, &ev, &err) == MTS_OK);
    CHECK(t, ev.info == 0 && mts_stream_client_buffered(&c) == info.size - 1);
    CHECK(t, mts_stream_client_reconnected(&c, &err) == MTS_OK);
    CHECK(t, mts_stream_client_buffered(&c) == 0);
    CHECK(t, mts_test_feed(&c, first.data, first.size, 4, 977, &ev, &err) == MTS_OK);
    CHECK(t, ev.info == 1 && ev.end == 1 && c.checksum == s.level_checksum[n]);
    mts_stream_client_free(&c);

    mts_buf_free(&info);
    mts_buf_free(&first);
    mts_buf_free(&second);
    mts_stream_free(&s);
}

/* Bytes that are not this protocol's frames give -1 and an error that
 * names what is wrong, and end the client; a frame that only failed its CRC
 * is said so by c->rejected. */
static void test_feed_garbage_named(mts_test *t)
{
    static const struct {
        const char *bytes;
        size_t size;
        mts_result code;
        const char *says;
    } bad[] = {
        {"GET / HTTP/1.1\r\n\r\n", 18, MTS_ERR_FORMAT, "frame of 542393671 bytes"},
        {"\0\0\0\0\x10", 5, MTS_ERR_FORMAT, "frame of 0 bytes"},
        {"\x03\0\0\0\x7f\1\2", 7, MTS_ERR_FORMAT, "unexpected message type 127"},
        {"\x03\0\0\0\x12\1\2", 7, MTS_ERR_FORMAT, "unexpected message type 18"},
        {"\x03\0\0\0\x10\1\2", 7, MTS_ERR_FORMAT, "MODEL_INFO"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        mts_stream_client c;
        mts_stream_client_init(&c);
        mts_error err = {0};
        mts_stream_event ev;
        CHECK(t, mts_stream_client_feed(&c, bad[i].bytes, bad[i].size, &err) == MTS_OK);
        CHECK(t, mts_stream_client_next(&c, &ev, &err) == -1);
        CHECKF(t, err.code == bad[i].code && strstr(err.msg, bad[i].says), "case %zu: %s (%s)", i,
               err.msg, mts_result_name(err.code));
        CHECK(t, !c.rejected);
        uint32_t batch;
        uint64_t id;
        CHECK(t, !mts_stream_client_resume_point(&c, &batch, &id)); /* nothing to resume */
        CHECK(t, mts_stream_client_next(&c, &ev, &err) != 1);
        mts_stream_client_free(&c);
    }

    /* random bytes: an error or a wait for more, never a crash */
    uint64_t seed = 29;
    for (int round = 0; round < 500; round++) {
        uint8_t junk[64];
        for (size_t i = 0; i < sizeof junk; i++) {
            seed = seed * 6364136223846793005ull + 1442695040888963407ull;
            junk[i] = (uint8_t)(seed >> 56);
        }
        if (round % 2) { /* a length that fits, so the type and payload are read */
            junk[0] = (uint8_t)(round % 59 + 1);
            junk[1] = junk[2] = junk[3] = 0;
        }
        mts_stream_client c;
        mts_stream_client_init(&c);
        mts_error err = {0};
        mts_stream_event ev;
        CHECK(t, mts_stream_client_feed(&c, junk, sizeof junk, &err) == MTS_OK);
        int got;
        while ((got = mts_stream_client_next(&c, &ev, &err)) > 0)
            ;
        CHECKF(t, got == 0 || err.msg[0], "round %d", round);
        mts_stream_client_free(&c);
    }

    /* a batch that fails its CRC: rejected, and said so */
    mts_stream s;
    if (!build_stream(t, "tests/data/cow.off", &s))
        return;
    mts_buf b = {0};
    uint32_t stop;
    connection_bytes(&s, MTS_STOP_FULL, 0, &b, &stop);
    size_t info_size = 4 + ((size_t)b.data[0] | (size_t)b.data[1] << 8 |
                            (size_t)b.data[2] << 16 | (size_t)b.data[3] << 24);
    b.data[info_size + s.batch_offset[1] + 12] ^= 0x10;
    mts_stream_client c;
    mts_stream_client_init(&c);
    mts_error err = {0};
    mts_stream_event ev;
    CHECK(t, mts_stream_client_feed(&c, b.data, b.size, &err) == MTS_OK);
    int got;
    while ((got = mts_stream_client_next(&c, &ev, &err)) > 0)
        ;
    CHECKF(t, got == -1 && err.code == MTS_ERR_CHECKSUM && c.rejected && c.batches == 1 &&
                  strstr(err.msg, "BATCH 1"),
           "%d %s", got, err.msg);
    mts_stream_client_free(&c);
    mts_buf_free(&b);
    mts_stream_free(&s);
}

/* records: also build the records form, and check it at the full level
 * (the build is the slow part: one build serves both forms) */
static void shared_model_stops(mts_test *t, const char *file, int records)
{
    char buf[1024];
    const char *path = mts_test_model(file, buf, sizeof buf);
    if (!path)
        SKIP(t, "%s not found", buf);
    mts_stream s;
    mts_stream_options o = {0};
    o.with_records = records;
    if (!build_stream_opts(t, path, 0, &o, &s))
        return;
    if (getenv("MTS_TEST_VERBOSE"))
        fprintf(stderr, "  %s: stream %zu bytes (base frame %zu), %u batches, draco %s\n", file,
                s.size, s.batch_offset[0], s.batch_count,
                s.draco_method == MTS_DRACO_SEQUENTIAL ? "sequential" : "edgebreaker");
    /* the full level and two partial stops */
    const uint8_t kinds[3] = {MTS_STOP_FULL, MTS_STOP_FRACTION, MTS_STOP_TRIANGLES};
    const uint32_t values[3] = {0, 250000, 40000};
    for (int i = 0; i < 3; i++) {
        uint32_t stop;
        size_t bytes;
        mts_stream_client c;
        mts_error err = {0};
        CHECKF(t, receive(&s, kinds[i], values[i], 3 + (uint64_t)i, &c, &stop, &bytes, &err),
               "%s", err.msg);
        CHECK(t, c.lod.level == stop);
        same_as_server(t, &s, &c);
        if (getenv("MTS_TEST_VERBOSE"))
            fprintf(stderr, "  %s stop %d: level %u, %zu bytes\n", file, i, stop, bytes);
        mts_stream_client_free(&c);
    }
    if (records && s.records_form) {
        /* the records form at the full level: the same mesh, and the
         * model's records word for word */
        const mts_stream *r = s.records_form;
        uint32_t stop;
        mts_stream_client c;
        mts_error err = {0};
        CHECKF(t, receive(r, MTS_STOP_FULL, 0, 9, &c, &stop, NULL, &err), "records: %s", err.msg);
        CHECK(t, c.records == 1 && c.grow == NULL && c.info.stream_id == r->stream_id);
        CHECK(t, stop == s.model.level_count && c.lod.level == stop);
        CHECK(t, c.checksum == s.level_checksum[stop]);
        same_as_server(t, &s, &c);
        CHECK(t, c.model.record_word_count == s.model.record_word_count &&
                     memcmp(c.model.record_data, s.model.record_data,
                            (size_t)s.model.record_word_count * 4) == 0);
        if (getenv("MTS_TEST_VERBOSE"))
            fprintf(stderr, "  %s records form: %zu bytes (splits form %zu)\n", file, r->size,
                    s.size);
        mts_stream_client_free(&c);
    } else if (records) {
        CHECK(t, s.records_form != NULL);
    }
    mts_stream_free(&s);
}

/* fandisk's box has an origin Draco cannot store exactly (-4.7e-15 becomes
 * -0): the stream must use Draco's grid for every vertex */
static void test_bunny_stops(mts_test *t)
{
    shared_model_stops(t, "bunny00.off", 1);
}

static void test_fandisk_stops(mts_test *t)
{
    shared_model_stops(t, "fandisk_large.off", 0);
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
    for (int k = 0; k < 2; k++) /* index, new slots */
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

/* ---- the records form ---------------------------------------------------
 *
 * The same model, BASE and batching, but each batch carries its splits'
 * records (reccodec.h) and each new vertex against its parent (PROTOCOL.md,
 * "Records form"): the client derives nothing and must end exactly where the
 * splits form does, at every stop; a damaged or padded batch is refused. */

/* cow with its records form, built once for the cases below */
static mts_stream cow_rec;
static int cow_rec_state; /* 0: not yet, 1: built, -1: failed */

static const mts_stream *cow_with_records(mts_test *t)
{
    if (cow_rec_state == 0) {
        mts_stream_options o = {0};
        o.with_records = 1;
        cow_rec_state = build_stream_opts(t, "tests/data/cow.off", 0, &o, &cow_rec) ? 1 : -1;
        if (cow_rec_state > 0 && !cow_rec.records_form) {
            CHECKF(t, 0, "with_records = 1 built no records form");
            mts_stream_free(&cow_rec);
            cow_rec_state = -1;
        }
    } else if (cow_rec_state < 0) {
        CHECKF(t, 0, "building cow with its records form failed before");
    }
    return cow_rec_state > 0 ? &cow_rec : NULL;
}

/* cow (*s), its records form (*r) and what a connection to the records form
 * for the full level is sent (b, stopping at *stop); 0 when cow did not
 * build. */
static int cow_records_full(mts_test *t, const mts_stream **s, const mts_stream **r, mts_buf *b,
                            uint32_t *stop)
{
    *s = cow_with_records(t);
    if (!*s)
        return 0;
    *r = (*s)->records_form;
    connection_bytes(*r, MTS_STOP_FULL, 0, b, stop);
    return 1;
}

static uint32_t get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* Recomputes the CRC of the frame at f (its length field first). */
static void reseal(uint8_t *f)
{
    size_t n = get_u32(f) - 1; /* payload, CRC included */
    uint8_t *pl = f + MTS_WIRE_HEADER;
    uint32_t crc = mts_crc32c(0, pl, n - 4);
    for (int k = 0; k < 4; k++)
        pl[n - 4 + k] = (uint8_t)(crc >> (8 * k));
}

/* Where batch k's frame lies in connection bytes b of stream r (MODEL_INFO
 * first), and where its body starts after the header. */
static void batch_frame(const mts_stream *r, const mts_buf *b, uint32_t k, size_t *at,
                        size_t *end, size_t *body)
{
    size_t info_size = 4 + (size_t)get_u32(b->data);
    *at = info_size + r->batch_offset[k];
    *end = info_size + r->batch_offset[k + 1];
    const uint8_t *pl = b->data + *at + MTS_WIRE_HEADER;
    mts_cursor cur = mts_cursor_make(pl, *end - *at - MTS_WIRE_HEADER - 4);
    mts_cursor_varint(&cur); /* index */
    mts_cursor_varint(&cur); /* slots announced, then (records form) their capacities */
    for (uint32_t st = r->announced[k]; r->records && st < r->announced[k + 1]; st++)
        mts_cursor_varint(&cur);
    *body = (size_t)(cur.p - b->data);
}

/* Ends the batch frame begun at f in x with a fresh CRC, appends what
 * follows the original batch in b (from end), feeds it all and frees x. */
static mts_result seal_and_feed(mts_stream_client *c, mts_buf *x, size_t f, const mts_buf *b,
                                size_t end, uint64_t seed, int *saw_end, mts_error *err)
{
    mts_buf_u32(x, 0); /* the CRC, resealed below */
    mts_wire_frame_end(x, f);
    reseal(x->data + f);
    mts_buf_put(x, b->data + end, b->size - end);
    mts_result rc = feed(c, x->data, x->size, seed, saw_end, err);
    mts_buf_free(x);
    return rc;
}

/* Feeds b with batch k's body replaced by body[0..size) (CRC recomputed). */
static mts_result feed_with_batch(mts_stream_client *c, const mts_stream *r, const mts_buf *b,
                                  uint32_t k, const uint8_t *body, size_t size, uint64_t seed,
                                  int *saw_end, mts_error *err)
{
    size_t at, end, bstart;
    batch_frame(r, b, k, &at, &end, &bstart);
    mts_buf x = {0};
    mts_buf_put(&x, b->data, at);
    size_t f = mts_wire_frame_begin(&x, MTS_MSG_BATCH);
    mts_buf_put(&x, b->data + at + MTS_WIRE_HEADER, bstart - at - MTS_WIRE_HEADER);
    mts_buf_put(&x, body, size);
    return seal_and_feed(c, &x, f, b, end, seed, saw_end, err);
}

/* Feeds b with batch k's header announcing `more` slots (in the records
 * form with the model's capacities; the splits form codes them in its body,
 * left as it was), CRC recomputed. */
static mts_result feed_with_announced(mts_stream_client *c, const mts_stream *r,
                                      const mts_buf *b, uint32_t k, uint32_t more,
                                      int *saw_end, mts_error *err)
{
    const uint32_t upto = r->announced[k] + more;
    size_t at, end, bstart;
    batch_frame(r, b, k, &at, &end, &bstart);
    mts_buf x = {0};
    mts_buf_put(&x, b->data, at);
    size_t f = mts_wire_frame_begin(&x, MTS_MSG_BATCH);
    mts_buf_varint(&x, k);
    mts_buf_varint(&x, more);
    for (uint32_t st = r->announced[k]; r->records && st < upto && st < r->model.strip_count;
         st++)
        mts_buf_varint(&x, r->model.capacity[st]);
    mts_buf_put(&x, b->data + bstart, end - 4 - bstart);
    return seal_and_feed(c, &x, f, b, end, 0, saw_end, err);
}

/* Capacities come with the frame that first uses a slot: a batch that
 * announces more than there are, leaves out a slot its records use, or
 * whose capacities pass MODEL_INFO's total is refused by name, and
 * the client stays at its last whole batch. Both forms. */
static void test_capacities_announced(mts_test *t)
{
    const mts_stream *s = cow_with_records(t);
    if (!s)
        return;
    for (int form = 0; form < 2 && !t->case_failed; form++) {
        const mts_stream *r = form ? s->records_form : s;
        mts_buf b = {0};
        uint32_t stop;
        connection_bytes(r, MTS_STOP_FULL, 0, &b, &stop);
        /* the first batch that brings new slots, after one that brought some */
        uint32_t k = 1;
        while (k < r->batch_count && r->announced[k + 1] == r->announced[k])
            k++;
        CHECK(t, k < r->batch_count && r->announced[k] > 0);
        if (t->case_failed) {
            mts_buf_free(&b);
            break;
        }
        const uint32_t left = r->model.strip_count - r->announced[k];
        const struct {
            uint32_t more;
            const char *want;
        } cases[] = {
            {left + 1, "past the"},   /* more than there are */
            {UINT32_MAX, "past the"}, /* more than a count can add */
            /* a used slot left out (the splits form's body then codes
             * capacities where splits should be: refused, for some reason) */
            {0, form ? "capacity" : ""},
        };
        for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
            mts_stream_client c;
            mts_stream_client_init(&c);
            mts_error err = {0};
            int saw_end = 0;
            mts_result rc = feed_with_announced(&c, r, &b, k, cases[i].more, &saw_end, &err);
            CHECKF(t, rc != MTS_OK && !saw_end && strstr(err.msg, cases[i].want),
                   "form %d case %zu: %d %s", form, i, rc, err.msg);
            /* refused before anything of the batch is applied, or (a record
             * that does not fit) part-way through it, the runtime broken */
            CHECKF(t, c.lod.level <= r->batch_first[k] ||
                          (c.lod.broken && c.lod.level < r->batch_first[k + 1]),
                   "form %d case %zu: level %u", form, i, c.lod.level);
            mts_stream_client_free(&c);
        }
        /* a total below what the slots take: found where it runs out, in the
         * last batch to announce slots */
        mts_wire_model_info mi = {0};
        mts_error err = {0};
        const size_t info_size = 4 + (size_t)get_u32(b.data);
        CHECK(t, mts_wire_parse_model_info(b.data + MTS_WIRE_HEADER, info_size - MTS_WIRE_HEADER,
                                           &mi, &err) == MTS_OK);
        uint32_t last = r->batch_count - 1;
        while (last > 0 && r->announced[last + 1] == r->announced[last])
            last--;
        mi.capacity_total--;
        mts_buf x = {0};
        mts_wire_put_model_info(&x, &mi);
        mts_buf_put(&x, b.data + info_size, b.size - info_size);
        mts_stream_client c;
        mts_stream_client_init(&c);
        int saw_end = 0;
        mts_result rc = feed(&c, x.data, x.size, 3, &saw_end, &err);
        CHECKF(t, rc == MTS_ERR_FORMAT && strstr(err.msg, "past MODEL_INFO's") &&
                      c.batches == last && c.lod.level == r->batch_first[last],
               "form %d: %d %s (%u batches, level %u; batch %u)", form, rc, err.msg, c.batches,
               c.lod.level, last);
        mts_stream_client_free(&c);
        mts_wire_model_info_free(&mi);
        mts_buf_free(&x);
        mts_buf_free(&b);
    }
}

/* The records form from the start at the splits form's stops, in random
 * pieces: at every stop the client equals the model, ends with the splits
 * form's END checksum, and holds the model's records word for word; the
 * form is its own stream (flags, stream_id) over the same BASE and batches. */
static void test_records_form_every_stop(mts_test *t)
{
    const mts_stream *s = cow_with_records(t);
    if (!s)
        return;
    const mts_stream *r = s->records_form;
    const uint32_t n = s->model.level_count;
    /* what a HELLO picks */
    CHECK(t, mts_stream_for_hello(s, 0) == s && mts_stream_for_hello(s, MTS_HELLO_RECORDS) == r);
    CHECK(t, !s->records && r->records && r->borrowed && !r->records_form);
    /* the same model, grid and batching; the BASE frame byte for byte */
    CHECK(t, r->model.positions == s->model.positions && r->quantized == s->quantized &&
             r->level_checksum == s->level_checksum);
    CHECK(t, r->batch_count == s->batch_count && s->batch_count > 3 &&
             memcmp(r->batch_first, s->batch_first, ((size_t)s->batch_count + 1) * 4) == 0);
    CHECK(t, r->batch_offset[0] == s->batch_offset[0] &&
             memcmp(r->bytes, s->bytes, s->batch_offset[0]) == 0);
    CHECK(t, r->batch_offset[r->batch_count] == r->size && r->size > 4 * s->size);
    CHECKF(t, r->stream_id != s->stream_id, "both forms are stream %016llx",
           (unsigned long long)r->stream_id);
    /* MODEL_INFO: equal but for the stream_id and the records flag */
    mts_buf ia = {0}, ib = {0};
    mts_stream_put_model_info(s, n, &ia);
    mts_stream_put_model_info(r, n, &ib);
    mts_wire_model_info a = {0}, b = {0};
    mts_error err = {0};
    CHECKF(t, mts_wire_parse_model_info(ia.data + MTS_WIRE_HEADER, ia.size - MTS_WIRE_HEADER, &a,
                                        &err) == MTS_OK &&
                  mts_wire_parse_model_info(ib.data + MTS_WIRE_HEADER,
                                            ib.size - MTS_WIRE_HEADER, &b, &err) == MTS_OK,
           "%s", err.msg);
    CHECK(t, a.flags == 0 && b.flags == MTS_INFO_RECORDS);
    CHECK(t, a.stream_id == s->stream_id && b.stream_id == r->stream_id);
    CHECK(t, b.minor == MTS_WIRE_MINOR);
    CHECK(t, a.levels == b.levels && a.vertices == b.vertices && a.triangles == b.triangles &&
             a.batch_count == b.batch_count && a.key_count == b.key_count && a.strips == b.strips);
    CHECK(t, ia.size == ib.size); /* the same fields, so the same size */
    mts_wire_model_info_free(&a);
    mts_wire_model_info_free(&b);
    mts_buf_free(&ia);
    mts_buf_free(&ib);

    struct {
        uint8_t kind;
        uint32_t value;
    } stops[] = {{MTS_STOP_FULL, 0},         {MTS_STOP_LEVEL, n / 3},
                 {MTS_STOP_LEVEL, 0},        {MTS_STOP_TRIANGLES, 1000},
                 {MTS_STOP_FRACTION, 500000}, {MTS_STOP_LEVEL, 999999}};
    for (size_t i = 0; i < sizeof stops / sizeof stops[0] && !t->case_failed; i++) {
        /* the splits form at this stop, for its END checksum */
        uint32_t sstop;
        mts_stream_client sc;
        CHECKF(t, receive(s, stops[i].kind, stops[i].value, 0, &sc, &sstop, NULL, &err),
               "splits, stop %zu: %s", i, err.msg);
        for (uint64_t seed = 0; seed < 4; seed++) {
            uint32_t stop;
            mts_stream_client c;
            CHECKF(t, receive(r, stops[i].kind, stops[i].value, seed, &c, &stop, NULL, &err),
                   "records, stop %zu seed %llu: %s", i, (unsigned long long)seed, err.msg);
            CHECK(t, stop == sstop);
            CHECK(t, c.records == 1 && c.grow == NULL);
            CHECK(t, (c.info.flags & MTS_INFO_RECORDS) && c.info.stream_id == r->stream_id);
            CHECK(t, c.lod.level == stop && !c.lod.broken);
            CHECKF(t, c.checksum == c.end_checksum && c.end_checksum == sc.end_checksum &&
                          c.checksum == s->level_checksum[stop],
                   "stop %zu: records %016llx, splits %016llx", i,
                   (unsigned long long)c.checksum, (unsigned long long)sc.end_checksum);
            same_as_server(t, s, &c);
            /* the records it was sent (whole batches up to the stop) are the
             * model's, parents included */
            const uint32_t got = c.splits;
            CHECK(t, got >= stop && got <= n && c.batches <= s->batch_count &&
                     got == s->batch_first[c.batches]);
            CHECK(t, memcmp(c.model.parents, s->model.parents, (size_t)got * 4) == 0);
            CHECK(t, memcmp(c.model.record_offsets, s->model.record_offsets,
                            ((size_t)got + 1) * 4) == 0);
            CHECK(t, got == 0 || memcmp(c.model.record_data, s->model.record_data,
                                        (size_t)s->model.record_offsets[got] * 4) == 0);
            mts_stream_client_free(&c);
        }
        mts_stream_client_free(&sc);
    }
}

/* Each records-form batch is the model's records in reccodec's encoding,
 * then per split three grid deltas against the parent, then the CRC. */
static void test_records_form_batch_layout(mts_test *t)
{
    const mts_stream *s, *r;
    mts_buf b = {0};
    uint32_t stop;
    if (!cow_records_full(t, &s, &r, &b, &stop))
        return;
    const uint32_t nb = s->model.base_vertex_count;
    for (uint32_t k = 0; k < r->batch_count && !t->case_failed; k++) {
        const uint32_t first = s->batch_first[k], count = s->batch_first[k + 1] - first;
        size_t at, end, body;
        batch_frame(r, &b, k, &at, &end, &body);
        CHECK(t, b.data[at + 4] == MTS_MSG_BATCH && get_u32(b.data + at) + 4 == end - at);
        size_t bound = mts_reccodec_bound(&s->model, first, count), written = 0;
        uint8_t *rec = malloc(bound ? bound : 1);
        mts_error err = {0};
        CHECKF(t, rec && mts_reccodec_encode(&s->model, first, count, rec, bound, &written,
                                             &err) == MTS_OK,
               "%s", err.msg);
        CHECKF(t, body + written <= end - 4 && memcmp(b.data + body, rec, written) == 0,
               "batch %u: its records are not reccodec's encoding of splits %u+%u", k, first,
               count);
        free(rec);
        mts_cursor cur = mts_cursor_make(b.data + body + written, end - 4 - body - written);
        for (uint32_t i = 0; i < count && cur.ok; i++) {
            const uint32_t v = nb + first + i, u = s->model.parents[first + i];
            for (int a = 0; a < 3; a++) {
                int32_t d = (int32_t)mts_unzigzag_u32(mts_cursor_varint(&cur));
                CHECKF(t, cur.ok && (int64_t)s->quantized[3 * (size_t)u + a] + d ==
                                        (int64_t)s->quantized[3 * (size_t)v + a],
                       "batch %u: vertex %u axis %d", k, v, a);
            }
        }
        CHECKF(t, cur.ok && mts_cursor_left(&cur) == 0, "batch %u: %zu bytes before its CRC", k,
               mts_cursor_left(&cur));
    }
    mts_buf_free(&b);
}

/* Normals the source had travel in the records form too, bit for bit. */
static void test_records_form_normals(mts_test *t)
{
    mts_stream s;
    mts_stream_options o = {0};
    o.with_records = 1;
    if (!build_stream_opts(t, "tests/data/cow.off", 1, &o, &s))
        return;
    const mts_stream *r = s.records_form;
    CHECK(t, r != NULL);
    if (!r) {
        mts_stream_free(&s);
        return;
    }
    const uint32_t n = s.model.level_count;
    const uint32_t stops[2] = {n, n / 2};
    for (int i = 0; i < 2; i++) {
        uint32_t stop;
        mts_stream_client c;
        mts_error err = {0};
        CHECKF(t, receive(r, MTS_STOP_LEVEL, stops[i], 13 + (uint64_t)i, &c, &stop, NULL, &err),
               "%s", err.msg);
        CHECK(t, c.info.flags == (MTS_INFO_NORMALS | MTS_INFO_RECORDS) && c.records);
        CHECK(t, c.lod.level == stop && c.checksum == s.level_checksum[stop]);
        same_as_server(t, &s, &c); /* normals included, bit for bit */
        size_t nv = (size_t)s.model.base_vertex_count + stop;
        size_t unit = unit_normals(c.model.normals, nv);
        CHECKF(t, unit == nv, "%zu of %zu unit normals", unit, nv);
        mts_stream_client_free(&c);
    }
    mts_stream_free(&s);
}

/* One byte of a records-form batch's records damaged and the CRC resealed
 * (a broken server): stream.h promises the batch is applied only once its
 * encoding checks out and each record is checked against the strips as it
 * is applied. So each damage is refused at that batch, the client left at
 * its last whole batch (the encoding failed) or its runtime marked broken
 * part-way through the batch (a record failed) -- or, where the damaged
 * record happens to fit the strips, caught by a later record or END's
 * checksum. No damaged stream ends accepted with another mesh, and a
 * refused client has nothing to resume. */
static void test_records_form_damaged_record(mts_test *t)
{
    const mts_stream *s, *r;
    mts_buf b = {0};
    uint32_t stop;
    if (!cow_records_full(t, &s, &r, &b, &stop))
        return;
    const uint32_t k = 2, first = s->batch_first[k], next = s->batch_first[k + 1];
    size_t at, end, body;
    batch_frame(r, &b, k, &at, &end, &body);
    size_t bound = mts_reccodec_bound(&s->model, first, next - first), written = 0;
    uint8_t *rec = malloc(bound ? bound : 1);
    mts_error err = {0};
    CHECK(t, rec && mts_reccodec_encode(&s->model, first, next - first, rec, bound, &written,
                                        &err) == MTS_OK);
    free(rec);
    uint8_t *copy = malloc(b.size);
    if (!copy) {
        CHECK(t, 0);
        mts_buf_free(&b);
        return;
    }
    const size_t step = written / 300 + 1;
    unsigned refused = 0, broken = 0, later = 0, harmless = 0;
    for (size_t pos = body; pos < body + written && !t->case_failed; pos += step) {
        memcpy(copy, b.data, b.size);
        copy[pos] ^= pos == body ? 0x5a : (uint8_t)(1u << (pos % 7));
        reseal(copy + at);
        mts_stream_client c;
        mts_stream_client_init(&c);
        int saw_end;
        /* up to the damaged batch */
        mts_result rc = feed(&c, copy, end, pos, &saw_end, &err);
        if (rc != MTS_OK) {
            refused++;
            CHECKF(t, strncmp(err.msg, "BATCH 2", 7) == 0, "byte %zu: %s", pos - body, err.msg);
            if (c.lod.broken) {
                broken++;
                CHECKF(t, c.lod.level >= first && c.lod.level < next,
                       "byte %zu: broken at level %u, batch 2 is %u..%u", pos - body, c.lod.level,
                       first, next);
            } else {
                CHECKF(t, c.batches == k && c.splits == first && c.lod.level == first,
                       "byte %zu: %u batches, level %u after a refused batch (%s)", pos - body,
                       c.batches, c.lod.level, err.msg);
                same_as_server(t, s, &c); /* the last whole batch, untouched */
            }
            uint32_t rb;
            uint64_t id;
            CHECK(t, !mts_stream_client_resume_point(&c, &rb, &id));
            mts_stream_event ev;
            CHECK(t, mts_stream_client_frame(&c, MTS_MSG_BATCH, copy + end + 5, 8, &ev, &err) ==
                         MTS_ERR_ARG); /* not fed again */
        } else {
            /* a damaged record that fits the strips: the rest must catch it,
             * or it changed nothing the mesh shows */
            rc = feed(&c, copy + end, b.size - end, pos + 1, &saw_end, &err);
            if (rc != MTS_OK) {
                later++;
                if (getenv("MTS_TEST_VERBOSE"))
                    fprintf(stderr, "  byte %zu caught later: %s\n", pos - body, err.msg);
            } else {
                CHECKF(t, saw_end, "byte %zu", pos - body);
                same_as_server(t, s, &c);
                harmless++;
            }
        }
        mts_stream_client_free(&c);
    }
    if (getenv("MTS_TEST_VERBOSE"))
        fprintf(stderr,
                "  %zu record bytes, every %zu damaged: %u refused at the batch (%u with the "
                "runtime broken), %u caught later, %u harmless\n",
                written, step, refused, broken, later, harmless);
    CHECK(t, refused > later + harmless); /* most are caught at the batch itself */

    /* the first split's parent step damaged: refused at that batch */
    memcpy(copy, b.data, b.size);
    copy[body] ^= 0x5a;
    reseal(copy + at);
    mts_stream_client c;
    mts_stream_client_init(&c);
    int saw_end;
    mts_result rc = feed(&c, copy, b.size, 3, &saw_end, &err);
    CHECKF(t, rc != MTS_OK && !saw_end && strncmp(err.msg, "BATCH 2", 7) == 0, "%s", err.msg);
    CHECK(t, c.lod.broken ? c.lod.level >= first && c.lod.level < next
                          : c.batches == k && c.lod.level == first);
    mts_stream_client_free(&c);
    free(copy);
    mts_buf_free(&b);
}

/* A records-form batch with bytes after its vertices, or cut inside its
 * last vertex (CRC resealed either way), is refused whole: the client stays
 * at its last whole batch. */
static void test_records_form_trailing_bytes(mts_test *t)
{
    const mts_stream *s, *r;
    mts_buf b = {0};
    uint32_t stop;
    if (!cow_records_full(t, &s, &r, &b, &stop))
        return;
    const uint32_t k = 2;
    size_t at, end, body;
    batch_frame(r, &b, k, &at, &end, &body);
    const size_t size = end - 4 - body; /* records and vertices */
    uint8_t *longer = malloc(size + 3);
    if (!longer) {
        CHECK(t, 0);
        mts_buf_free(&b);
        return;
    }
    memcpy(longer, b.data + body, size);
    struct {
        size_t size;
        mts_result want;
        const char *says;
    } cases[] = {{size + 1, MTS_ERR_FORMAT, "1 bytes after its records"},
                 {size + 3, MTS_ERR_FORMAT, "3 bytes after its records"},
                 {size - 1, MTS_ERR_RANGE, "cut short"}};
    longer[size] = 0;
    longer[size + 1] = 1;
    longer[size + 2] = 0;
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        mts_stream_client c;
        mts_stream_client_init(&c);
        mts_error err = {0};
        int saw_end;
        mts_result rc = feed_with_batch(&c, r, &b, k, longer, cases[i].size, i, &saw_end, &err);
        CHECKF(t, rc == cases[i].want && strncmp(err.msg, "BATCH 2", 7) == 0 &&
                      strstr(err.msg, cases[i].says),
               "case %zu: %d %s", i, rc, err.msg);
        CHECK(t, !saw_end && !c.lod.broken);
        CHECK(t, c.batches == k && c.lod.level == s->batch_first[k]);
        same_as_server(t, s, &c);
        mts_stream_client_free(&c);
    }
    /* the same batch as sent, through the same rebuilding: accepted */
    mts_stream_client c;
    mts_stream_client_init(&c);
    mts_error err = {0};
    int saw_end;
    CHECKF(t, feed_with_batch(&c, r, &b, k, longer, size, 7, &saw_end, &err) == MTS_OK && saw_end,
           "%s", err.msg);
    CHECK(t, c.lod.level == stop);
    mts_stream_client_free(&c);
    free(longer);
    mts_buf_free(&b);
}

/* Records that pass every check of mts_lod_split can still be padded with
 * edits that change nothing (the record format allows them). A records-form
 * client keeps at most MODEL_INFO's bound of record words
 * (c->record_word_limit, stream_dec.c take_info): a little padding still fits
 * and ends on the right checksum, padding past the bound is refused with
 * MTS_ERR_LIMIT and the memory held stays within it. */
static mts_result feed_padded(const mts_stream *r, const mts_buf *b, uint32_t pad,
                              mts_stream_client *c, int *saw_end, mts_error *err)
{
    size_t at, end, body;
    batch_frame(r, b, 0, &at, &end, &body);
    /* split 0 opens the body: its parent (back) and edit count; no-op edits
     * on strip 0 go first, so the original edits' strip deltas still hold */
    mts_cursor cur = mts_cursor_make(b->data + body, end - 4 - body);
    uint32_t back = mts_cursor_varint(&cur), edits = mts_cursor_varint(&cur);
    mts_buf x = {0};
    mts_buf_varint(&x, back);
    mts_buf_varint(&x, edits + pad);
    for (uint32_t i = 0; i < pad; i++)
        mts_buf_u32(&x, 0); /* strip delta 0, no erase, no insert, no substitution */
    mts_buf_put(&x, cur.p, mts_cursor_left(&cur));
    mts_result rc = feed_with_batch(c, r, b, 0, x.data, x.size, 0, saw_end, err);
    mts_buf_free(&x);
    return rc;
}

static void test_records_form_padding_bounded(mts_test *t)
{
    const mts_stream *s, *r;
    mts_buf b = {0};
    uint32_t stop;
    if (!cow_records_full(t, &s, &r, &b, &stop))
        return;
    mts_stream_client c;
    mts_error err = {0};
    int saw_end;

    mts_stream_client_init(&c);
    CHECKF(t, feed_padded(r, &b, 1000, &c, &saw_end, &err) == MTS_OK && saw_end, "%s",
           err.msg);
    CHECK(t, c.lod.level == stop && c.checksum == s->level_checksum[stop]);
    /* the bound: 256 words a split and a full rewrite a key level */
    uint64_t limit = c.record_word_limit, cap = 0;
    for (uint32_t st = 0; st < s->model.strip_count; st++)
        cap += s->model.capacity[st];
    uint64_t want = 256ull * s->model.level_count +
                    (s->model.key_count + 1ull) * (2 * cap + 5ull * s->model.strip_count);
    CHECKF(t, limit == want, "bound %llu, MODEL_INFO gives %llu", (unsigned long long)limit,
           (unsigned long long)want);
    CHECKF(t, limit > 4ull * s->model.record_word_count, "bound %llu, model %u words",
           (unsigned long long)limit, s->model.record_word_count);
    mts_stream_client_free(&c);

    /* 4 words an edit: enough of them go past the bound */
    uint32_t pad = (uint32_t)(limit / 4) + 1000;
    mts_stream_client_init(&c);
    mts_result rc = feed_padded(r, &b, pad, &c, &saw_end, &err);
    CHECKF(t, rc == MTS_ERR_LIMIT && strncmp(err.msg, "BATCH 0", 7) == 0, "%d: %s", rc, err.msg);
    CHECK(t, !saw_end && c.batches == 0 && c.lod.level == 0);
    CHECKF(t, c.record_capacity <= limit + 1, "holds room for %zu words, bound %llu",
           c.record_capacity, (unsigned long long)limit);
    mts_stream_client_free(&c);
    mts_buf_free(&b);
}

/* A model whose records are not what its split descriptions grow would make
 * the two forms give different meshes: mts_stream_build refuses it, naming
 * the split. (This record no longer applies, so the level replay would refuse
 * the model too, with another error; test_records_must_match_growth_same_mesh
 * has a record that applies.) */
static void test_records_must_match_growth(mts_test *t)
{
    mts_error err = {0};
    mts_model m;
    if (!build_model(t, "tests/data/cow.off", 0, &m))
        return;
    mts_result rc;
    /* split j's first edit names another strip */
    const uint32_t j = m.level_count / 2;
    uint32_t *rec = m.record_data + m.record_offsets[j];
    CHECK(t, rec[0] >= 1);
    rec[1] = (rec[1] + 1) % m.strip_count;
    mts_stream s;
    mts_stream_options o = {0};
    o.with_records = 1;
    rc = mts_stream_build(&m, "cow", &o, &s, &err);
    char want[64];
    snprintf(want, sizeof want, "split %u's record", j);
    CHECKF(t, rc == MTS_ERR_INVARIANT && strstr(err.msg, want), "%d: %s", rc, err.msg);
    if (rc == MTS_OK)
        mts_stream_free(&s);
    mts_model_free(&m);
}

/* The substituted positions of the first edit at or after split `from`
 * that sets two or more (its split in *split), or NULL: walks the records as
 * model.h lays them out. */
static uint32_t *two_substitutions(const mts_model *m, uint32_t from, uint32_t *split)
{
    for (uint32_t j = from; j < m->level_count; j++) {
        uint32_t *p = m->record_data + m->record_offsets[j];
        uint32_t edits = *p++;
        for (uint32_t e = 0; e < edits; e++) {
            uint32_t erases = p[1], inserts = p[2], substs = p[3];
            p += 4;
            for (uint32_t k = 0; k < erases + inserts; k++)
                p += 2 + p[1]; /* position, length, the run */
            if (substs >= 2) {
                *split = j;
                return p;
            }
            p += substs;
        }
    }
    return NULL;
}

/* A record that still gives the same mesh as what its description grows
 * but is not word for word what it grows (two substituted positions
 * swapped: v lands on the same slots): the model stays valid and every
 * level's mesh is the same, so nothing but the comparison in predict_all
 * sees it; the records form would send other records than a splits-form
 * client derives, and mts_stream_build refuses it, in either form. */
static void test_records_must_match_growth_same_mesh(mts_test *t)
{
    mts_error err = {0};
    mts_model m;
    if (!build_model(t, "tests/data/cow.off", 0, &m))
        return;
    mts_result rc;
    uint32_t j = 0;
    uint32_t *pos = two_substitutions(&m, m.level_count / 2, &j);
    CHECKF(t, pos != NULL, "no edit of splits %u.. substitutes twice", m.level_count / 2);
    if (pos) {
        CHECK(t, pos[0] != pos[1]);
        uint32_t x = pos[0];
        pos[0] = pos[1];
        pos[1] = x;
        /* still a model: every record applies, the replay ends on the full strips */
        CHECKF(t, mts_model_validate(&m, &err) == MTS_OK, "%s", err.msg);
        char want[96];
        snprintf(want, sizeof want, "split %u's record is not what its description grows", j);
        for (int with_records = 0; with_records < 2; with_records++) {
            mts_stream s;
            mts_stream_options o = {0};
            o.with_records = with_records;
            rc = mts_stream_build(&m, "cow", &o, &s, &err);
            CHECKF(t, rc == MTS_ERR_INVARIANT && strstr(err.msg, want),
                   "with_records %d: %d: %s", with_records, rc, rc ? err.msg : "built");
            if (rc == MTS_OK)
                mts_stream_free(&s);
        }
    }
    mts_model_free(&m);
}

/* MODEL_INFO says one form, the batches are the other's (a broken server):
 * refused at the first batch, never applied as the other. */
static void test_records_form_flag_mismatch(mts_test *t)
{
    const mts_stream *s = cow_with_records(t);
    if (!s)
        return;
    const mts_stream *r = s->records_form;
    const uint32_t n = s->model.level_count;
    const mts_stream *info_of[2] = {s, r}, *bytes_of[2] = {r, s};
    for (int i = 0; i < 2; i++) {
        mts_buf b = {0};
        mts_stream_put_model_info(info_of[i], n, &b);
        mts_buf_put(&b, bytes_of[i]->bytes, bytes_of[i]->size);
        mts_stream_put_end(s, n, (uint32_t)b.size, &b);
        mts_stream_client c;
        mts_stream_client_init(&c);
        mts_error err = {0};
        int saw_end;
        mts_result rc = feed(&c, b.data, b.size, 5, &saw_end, &err);
        CHECKF(t, rc != MTS_OK && strncmp(err.msg, "BATCH 0", 7) == 0, "%s info: %d %s",
               i ? "records" : "splits", rc, err.msg);
        CHECK(t, c.records == i && !saw_end);
        CHECK(t, c.lod.broken ? c.lod.level < s->batch_first[1] : c.lod.level == 0);
        mts_stream_client_free(&c);
        mts_buf_free(&b);
    }
}

/* A records-form client moves down to the base and back up with the records
 * it was sent (collapses undo what the splits checked), at every step the
 * model; the splits form's derived records are the same words. */
static void test_records_form_moves_both_ways(mts_test *t)
{
    const mts_stream *s = cow_with_records(t);
    if (!s)
        return;
    const mts_model *sm = &s->model;
    uint32_t stop;
    mts_stream_client c;
    mts_error err = {0};
    CHECKF(t, receive(s->records_form, MTS_STOP_FULL, 0, 17, &c, &stop, NULL, &err), "%s",
           err.msg);
    CHECK(t, c.lod.level == sm->level_count && c.lod.available == sm->level_count);
    CHECK(t, sm->key_count >= 3);
    const uint32_t path[] = {0, sm->key_levels[1], sm->level_count / 2, 1, sm->level_count,
                             sm->key_levels[sm->key_count - 1] - 1, sm->level_count};
    for (size_t i = 0; i < sizeof path / sizeof path[0] && !t->case_failed; i++) {
        CHECKF(t, mts_lod_set_level(&c.lod, path[i], &err) == MTS_OK, "to %u: %s", path[i],
               err.msg);
        CHECK(t, c.lod.level == path[i]);
        same_as_server(t, s, &c);
    }
    CHECK(t, mts_stream_checksum(&c.lod, c.quantized) == s->level_checksum[sm->level_count]);
    mts_stream_client_free(&c);
}

/* A model without split descriptions (one made by hand, or by an older
 * build) cannot be streamed, and says why. */
/* The breakdown only counts: the stream is byte for byte the one built
 * without it; its parts add up to a connection's bytes; the fields'
 * information is what the coded bodies hold, less a few flush bytes a
 * batch (the range coder's overhead is that small). With normals. */
static void test_breakdown_adds_up(mts_test *t)
{
    mts_error err = {0};
    mts_model m;
    if (!build_model(t, "tests/data/cow.off", 1, &m))
        return;
    mts_stream plain, counted;
    mts_stream_breakdown bd;
    mts_stream_options o = {0};
    o.breakdown = &bd;
    CHECKF(t, mts_stream_build(&m, "cow", NULL, &plain, &err) == MTS_OK, "%s", err.msg);
    CHECKF(t, mts_stream_build(&m, "cow", &o, &counted, &err) == MTS_OK, "%s", err.msg);
    mts_model_free(&m);
    if (t->case_failed)
        return;
    CHECK(t, plain.size == counted.size && memcmp(plain.bytes, counted.bytes, plain.size) == 0);
    mts_buf b = {0};
    uint32_t stop;
    connection_bytes(&counted, MTS_STOP_LEVEL, UINT32_MAX, &b, &stop);
    CHECK(t, stop == counted.model.level_count);
    CHECKF(t, bd.info_bytes + bd.base_bytes + bd.batch_bytes + bd.end_bytes == b.size,
           "parts %zu + %zu + %zu + %zu, connection %zu", bd.info_bytes, bd.base_bytes,
           bd.batch_bytes, bd.end_bytes, b.size);
    CHECK(t, bd.base_bytes == counted.batch_offset[0]);
    /* every slot's capacity travels once, with BASE (a varint) or coded in
     * the batch that first uses it */
    CHECK(t, bd.capacity_bytes >= counted.announced[0] && bd.capacity_bits > 0 &&
                 counted.announced[counted.batch_count] == counted.model.strip_count &&
                 bd.info_batch_bytes < bd.info_bytes);
    CHECK(t, bd.base_draco_bytes > 0 && bd.base_strip_bytes > 0 &&
                 bd.base_draco_bytes + bd.base_strip_bytes < bd.base_bytes);
    const double fields = (bd.parent_bits + bd.fan_bits + bd.position_bits + bd.normal_bits +
                           bd.full_strips_bits + bd.capacity_bits) /
                          8;
    CHECK(t, bd.parent_bits > 0 && bd.fan_bits > 0 && bd.position_bits > 0 && bd.normal_bits > 0 &&
                 bd.full_strips_bits > 0);
    CHECKF(t, fields <= (double)bd.coded_bytes + 1 &&
                  (double)bd.coded_bytes - fields < 4.0 * counted.batch_count,
           "fields %.1f B, coded %zu B over %u batches", fields, bd.coded_bytes,
           counted.batch_count);
    CHECK(t, bd.framing_bytes + bd.coded_bytes + bd.capacity_bytes ==
                 bd.base_bytes - bd.base_draco_bytes - bd.base_strip_bytes + bd.batch_bytes);
    CHECK(t, bd.vertices == counted.model.vertex_count && bd.splits == counted.model.level_count);
    mts_buf_free(&b);
    mts_stream_free(&plain);
    mts_stream_free(&counted);
}

/* The stream's base ids are the decoded base in grid order (PROTOCOL.md,
 * BASE), and a built model numbers its base by position, so the stream
 * renames almost nothing: what the builder sorted by parent stays sorted. */
static void test_base_in_grid_order(mts_test *t)
{
    mts_error err = {0};
    mts_model m;
    if (!build_model(t, "tests/data/cow.off", 1, &m))
        return;
    mts_stream s;
    CHECKF(t, mts_stream_build(&m, "cow", NULL, &s, &err) == MTS_OK, "%s", err.msg);
    if (t->case_failed) {
        mts_model_free(&m);
        return;
    }
    const uint32_t nb = m.base_vertex_count;
    uint32_t unsorted = 0, kept = 0;
    const float step = s.grid.range / (float)((1u << s.grid.bits) - 1);
    for (uint32_t x = 0; x < nb; x++) {
        const uint32_t *q = s.quantized + 3 * (size_t)x;
        if (x > 0 && memcmp(q - 3, q, 12) != 0) {
            int a = 0;
            while (q[a - 3] == q[a])
                a++;
            unsorted += q[a - 3] > q[a];
        }
        int same = 1;
        for (int a = 0; a < 3; a++)
            same &= fabsf(s.model.positions[3 * (size_t)x + a] - m.positions[3 * (size_t)x + a]) <=
                    step;
        kept += same;
    }
    CHECKF(t, unsorted == 0, "%u base vertices out of grid order", unsorted);
    CHECKF(t, kept >= nb - nb / 20, "%u of %u base vertices keep the builder's id", kept, nb);
    mts_stream_free(&s);
    mts_model_free(&m);
}

static void test_model_without_descriptions_refused(mts_test *t)
{
    mts_stream s;
    mts_error err = {0};
    mts_model m;
    if (!build_model(t, "tests/data/cow.off", 0, &m))
        return;
    mts_result rc;
    free(m.growth_data);
    m.growth_data = NULL;
    rc = mts_stream_build(&m, "cow", NULL, &s, &err);
    CHECKF(t, rc == MTS_ERR_ARG && strstr(err.msg, "no split descriptions") &&
                  strstr(err.msg, "rebuild"),
           "%s", err.msg);
    mts_model_free(&m);
}

/* A small model in its units: cow shrunk to a box of about 8 mm at 9 cm
 * from the origin (a small part in metres). Draco keeps an explicit grid's
 * origin and range to six decimals, a step or more of this grid, so the
 * base's grid points came back off by one (one of them -1) and the stream
 * could not be built, or a client's checksum would differ. Every stop ends
 * at the server's checksum, in both methods' fallbacks, for several
 * offsets. */
static void test_small_model_in_metres(mts_test *t)
{
    static const float offset[][3] = {{0.0418548f, 0.961535f, 0.0939126f},
                                      {-0.0123457f, 0.f, 1.2345678f},
                                      {0.f, 0.f, 0.f}};
    for (size_t k = 0; k < sizeof offset / sizeof offset[0] && !t->case_failed; k++) {
        mts_error err = {0};
        mts_mesh mesh = {0};
        CHECKF(t, mts_mesh_load("tests/data/cow.off", NULL, &mesh, NULL, &err) == MTS_OK, "%s",
               err.msg);
        if (t->case_failed)
            return;
        float lo[3] = {mesh.positions[0], mesh.positions[1], mesh.positions[2]}, side = 0;
        for (uint32_t v = 0; v < mesh.vertex_count; v++)
            for (int c = 0; c < 3; c++)
                lo[c] = mesh.positions[3 * v + c] < lo[c] ? mesh.positions[3 * v + c] : lo[c];
        for (uint32_t v = 0; v < mesh.vertex_count; v++)
            for (int c = 0; c < 3; c++) {
                float d = mesh.positions[3 * v + c] - lo[c];
                side = d > side ? d : side;
            }
        for (uint32_t v = 0; v < mesh.vertex_count; v++)
            for (int c = 0; c < 3; c++)
                mesh.positions[3 * v + c] =
                    offset[k][c] + (mesh.positions[3 * v + c] - lo[c]) * (0.008f / side);
        mts_model m;
        mts_result rc = mts_build_model(&mesh, "cow", NULL, &m, NULL, &err);
        mts_mesh_free(&mesh);
        CHECKF(t, rc == MTS_OK, "offset %zu: %s", k, err.msg);
        if (rc != MTS_OK)
            return;
        mts_stream s;
        rc = mts_stream_build(&m, "cow", NULL, &s, &err);
        mts_model_free(&m);
        CHECKF(t, rc == MTS_OK, "offset %zu: stream: %s", k, err.msg);
        if (rc != MTS_OK)
            return;
        const uint32_t n = s.model.level_count;
        const uint32_t stops[] = {0, n / 2, n};
        for (size_t i = 0; i < 3; i++) {
            uint32_t stop;
            mts_stream_client c;
            CHECKF(t, receive(&s, MTS_STOP_LEVEL, stops[i], k, &c, &stop, NULL, &err),
                   "offset %zu, level %u: %s", k, stops[i], err.msg);
            CHECK(t, c.lod.level == stop && c.checksum == s.level_checksum[stop] &&
                         c.checksum == c.end_checksum);
            same_as_server(t, &s, &c);
            mts_stream_client_free(&c);
        }
        mts_stream_free(&s);
    }
}

int main(void)
{
    mts_test t = {0};
    RUN(&t, test_cow_every_stop);
    RUN(&t, test_small_model_in_metres);
    RUN(&t, test_normals_travel_when_given);
    RUN(&t, test_info_triangles_bounded);
    RUN(&t, test_corrupt_batch_rejected);
    RUN(&t, test_cut_stream_keeps_last_batch);
    RUN(&t, test_garbage_frames);
    RUN(&t, test_feed_any_split);
    RUN(&t, test_feed_reconnect_drops_cut_frame);
    RUN(&t, test_feed_garbage_named);
    RUN(&t, test_client_derives_every_record);
    RUN(&t, test_model_without_descriptions_refused);
    RUN(&t, test_breakdown_adds_up);
    RUN(&t, test_base_in_grid_order);
    RUN(&t, test_capacities_announced);
    RUN(&t, test_records_form_every_stop);
    RUN(&t, test_records_form_batch_layout);
    RUN(&t, test_records_form_normals);
    RUN(&t, test_records_form_damaged_record);
    RUN(&t, test_records_form_trailing_bytes);
    RUN(&t, test_records_form_flag_mismatch);
    RUN(&t, test_records_form_moves_both_ways);
    RUN(&t, test_records_form_padding_bounded);
    RUN(&t, test_records_must_match_growth);
    RUN(&t, test_records_must_match_growth_same_mesh);
    if (cow_rec_state > 0)
        mts_stream_free(&cow_rec);
    RUN(&t, test_bunny_stops);
    RUN(&t, test_fandisk_stops);
    return mts_test_end(&t);
}
