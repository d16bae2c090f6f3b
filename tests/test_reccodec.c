/* Varints and the compact split encoding: exact round trips (whole model and
 * arbitrary batches, records with erase runs), the exact bytes of one
 * record, and truncated or random input ends in an error, never an
 * overrun. */
#include <stdint.h>

#include "build.h"
#include "hand_model.h"
#include "mesh.h"
#include "model.h"
#include "reccodec.h"
#include "test.h"
#include "varint.h"

static void test_varint(mts_test *t)
{
    const uint32_t values[] = {0, 1, 127, 128, 255, 16383, 16384, 1u << 21, (1u << 28) - 1,
                               1u << 28, UINT32_MAX - 1, UINT32_MAX};
    uint8_t buf[MTS_VARINT32_MAX_BYTES];
    for (size_t i = 0; i < sizeof values / sizeof values[0]; i++) {
        size_t n = mts_varint_put(buf, values[i]);
        CHECK(t, n >= 1 && n <= MTS_VARINT32_MAX_BYTES);
        const uint8_t *p = buf;
        uint32_t x = 0;
        CHECK(t, mts_varint_get(&p, buf + n, &x) == 1 && x == values[i] && p == buf + n);
        /* every shorter read fails and does not move */
        for (size_t cut = 0; cut < n; cut++) {
            p = buf;
            CHECK(t, mts_varint_get(&p, buf + cut, &x) == 0 && p == buf);
        }
    }
    /* more than 32 bits, and six-byte encodings, are refused */
    const uint8_t too_big[] = {0xFF, 0xFF, 0xFF, 0xFF, 0x1F};
    const uint8_t too_long[] = {0x80, 0x80, 0x80, 0x80, 0x80, 0x00};
    const uint8_t *p = too_big;
    uint32_t x;
    CHECK(t, mts_varint_get(&p, too_big + 5, &x) == 0);
    p = too_long;
    CHECK(t, mts_varint_get(&p, too_long + 6, &x) == 0);
    const int32_t signed_values[] = {0, -1, 1, -2, 2, INT32_MAX, INT32_MIN};
    for (size_t i = 0; i < sizeof signed_values / sizeof signed_values[0]; i++)
        CHECK(t, mts_unzigzag(mts_zigzag(signed_values[i])) == signed_values[i]);
    CHECK(t, mts_zigzag(-1) == 1 && mts_zigzag(1) == 2);
    const uint32_t raw[] = {0, 1, 0x7FFFFFFFu, 0x80000000u, 0xFFFFFFFFu};
    for (size_t i = 0; i < sizeof raw / sizeof raw[0]; i++)
        CHECK(t, mts_unzigzag_u32(mts_zigzag_u32(raw[i])) == raw[i]);
}

static int cow_model(mts_test *t, mts_model *m)
{
    mts_error err = {0};
    mts_mesh mesh = {0};
    if (mts_mesh_load("tests/data/cow.off", NULL, &mesh, NULL, &err) != MTS_OK) {
        CHECKF(t, 0, "%s", err.msg);
        return 0;
    }
    mts_result rc = mts_build_model(&mesh, "cow", NULL, m, NULL, &err);
    mts_mesh_free(&mesh);
    CHECKF(t, rc == MTS_OK, "%s", err.msg);
    return rc == MTS_OK;
}

/* Decodes [first, first+count) and compares with the model. */
static void round_trip(mts_test *t, const mts_model *m, uint32_t first, uint32_t count,
                       size_t *encoded_bytes)
{
    mts_error err = {0};
    size_t cap = mts_reccodec_bound(m, first, count), written = 0;
    uint8_t *buf = malloc(cap + 1);
    CHECKF(t, mts_reccodec_encode(m, first, count, buf, cap, &written, &err) == MTS_OK, "%s",
           err.msg);
    uint32_t *parents = malloc(((size_t)count + 1) * 4);
    uint32_t *offsets = malloc(((size_t)count + 1) * 4);
    uint32_t *words = malloc((written + 1) * 4);
    mts_reccodec_out out = {parents, offsets, words, written, m->record_offsets[first]};
    size_t consumed = 0, nwords = 0;
    CHECKF(t, mts_reccodec_decode(buf, written, m->base_vertex_count, first, count, &out,
                                  &consumed, &nwords, &err) == MTS_OK,
           "%s", err.msg);
    CHECK(t, consumed == written);
    CHECK(t, nwords == m->record_offsets[first + count] - m->record_offsets[first]);
    CHECK(t, memcmp(parents, m->parents + first, (size_t)count * 4) == 0);
    CHECK(t, memcmp(offsets, m->record_offsets + first, ((size_t)count + 1) * 4) == 0);
    CHECK(t, memcmp(words, m->record_data + m->record_offsets[first], nwords * 4) == 0);
    if (encoded_bytes)
        *encoded_bytes = written;
    free(buf);
    free(parents);
    free(offsets);
    free(words);
}

static void test_round_trip_cow(mts_test *t)
{
    mts_model m;
    if (!cow_model(t, &m))
        return;
    size_t bytes = 0;
    round_trip(t, &m, 0, m.level_count, &bytes);
    size_t raw = ((size_t)m.record_word_count + m.level_count) * 4;
    if (getenv("MTS_TEST_VERBOSE"))
        fprintf(stderr, "  cow: %zu bytes of splits as words, %zu encoded (%.2fx)\n", raw, bytes,
                (double)raw / bytes);
    CHECKF(t, bytes * 2 < raw, "encoding saves less than half: %zu of %zu", bytes, raw);
    /* in uneven batches, as a stream would send them */
    uint32_t at = 0, step = 1;
    while (at < m.level_count && !t->case_failed) {
        uint32_t count = step < m.level_count - at ? step : m.level_count - at;
        round_trip(t, &m, at, count, NULL);
        at += count;
        step = step * 3 + 1;
    }
    mts_model_free(&m);
}

/* The layout of reccodec.h, byte by byte, on split 1 of the hand-made model
 * with erase runs (tests/hand_model.h). */
static void test_erase_record_bytes(mts_test *t)
{
    mts_model m;
    hand_state snap[3];
    hand_model_erases(&m, snap);
    const uint8_t want[] = {
        2,             /* v - 1 - parent: 4 - 1 - 1 */
        2,             /* edits */
        0, 1, 0, 1,    /* strip 0 (delta 0), 1 erase, no insert, 1 subst */
        2, 3, 2, 0, 4, /*   erase at 2, 3 long: 2 1 3 as zigzag(index - 1) */
        2,             /*   position 1 (delta from 0) */
        2, 1, 1, 0,    /* strip 1 (delta +1), 1 erase, 1 insert, no subst */
        0, 3, 0, 2, 1, /*   erase at 0, 3 long: 1 2 0 */
        0, 0,          /*   insert at 0, empty */
    };
    uint8_t buf[(22 + 1) * MTS_VARINT32_MAX_BYTES]; /* the bound: 22 words and a parent */
    size_t written = 0;
    mts_error err = {0};
    CHECK(t, mts_reccodec_bound(&m, 1, 1) == sizeof buf);
    CHECKF(t, mts_reccodec_encode(&m, 1, 1, buf, sizeof buf, &written, &err) == MTS_OK, "%s",
           err.msg);
    CHECKF(t, written == sizeof want && memcmp(buf, want, sizeof want) == 0,
           "split 1 encodes to %zu bytes, not the %zu expected", written, sizeof want);
    mts_model_free(&m);
}

/* Records with erase runs, round trip: the hand-made model, then random
 * models (erases, empty runs, several edits on one strip) with vertex ids
 * from a few up to a million (multi-byte varints, negative deltas). A
 * split's words never outnumber its bytes: round_trip gives the decoder no
 * more room than that. */
static void test_round_trip_erase_runs(mts_test *t)
{
    mts_model m;
    hand_state snap[3];
    hand_model_erases(&m, snap);
    round_trip(t, &m, 0, 2, NULL);
    round_trip(t, &m, 1, 1, NULL);
    mts_model_free(&m);
    uint64_t seed = 4242;
    for (int it = 0; it < 600 && !t->case_failed; it++) {
        hand_state *states = hand_random_model(&seed, it % 2, &m);
        round_trip(t, &m, 0, m.level_count, NULL);
        for (uint32_t j = 0; j < m.level_count && !t->case_failed; j++)
            round_trip(t, &m, j, 1, NULL);
        mts_model_free(&m);
        free(states);
    }
}

static void test_truncated_and_garbage(mts_test *t)
{
    mts_model m;
    if (!cow_model(t, &m))
        return;
    mts_error err = {0};
    const uint32_t first = 100, count = 40;
    size_t cap = mts_reccodec_bound(&m, first, count), written = 0;
    uint8_t *buf = malloc(cap);
    CHECK(t, mts_reccodec_encode(&m, first, count, buf, cap, &written, &err) == MTS_OK);
    uint32_t parents[41], offsets[42];
    uint32_t *words = malloc((written + 1) * 4);
    mts_reccodec_out out = {parents, offsets, words, written, 0};
    for (size_t cut = 0; cut < written; cut++) {
        uint8_t *copy = malloc(cut + 1);
        memcpy(copy, buf, cut);
        size_t consumed, nw;
        mts_result rc = mts_reccodec_decode(copy, cut, m.base_vertex_count, first, count, &out,
                                            &consumed, &nw, &err);
        CHECKF(t, rc != MTS_OK, "cut at %zu of %zu decoded", cut, written);
        free(copy);
    }
    /* random bytes: an error or some splits, never an overrun (ASan watches) */
    uint64_t seed = 7;
    for (int round = 0; round < 2000; round++) {
        size_t n = 1 + (size_t)(round % 64);
        uint8_t *junk = malloc(n);
        for (size_t i = 0; i < n; i++) {
            seed = seed * 6364136223846793005ull + 1442695040888963407ull;
            junk[i] = (uint8_t)(seed >> 56);
        }
        uint32_t jp[8], jo[9], jw[64];
        mts_reccodec_out jout = {jp, jo, jw, n < 64 ? n : 64, 0};
        size_t consumed, nw;
        mts_result rc = mts_reccodec_decode(junk, n, 50, 0, 8, &jout, &consumed, &nw, &err);
        if (rc == MTS_OK)
            CHECK(t, consumed <= n && nw <= n);
        free(junk);
    }
    free(words);
    free(buf);
    mts_model_free(&m);
}

int main(void)
{
    mts_test t = {0};
    RUN(&t, test_varint);
    RUN(&t, test_round_trip_cow);
    RUN(&t, test_erase_record_bytes);
    RUN(&t, test_round_trip_erase_runs);
    RUN(&t, test_truncated_and_garbage);
    return mts_test_end(&t);
}
