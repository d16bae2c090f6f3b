/* The wire format: every message round-trips; malformed payloads (truncated
 * at every byte, bad magic, wrong version, bad names, huge counts) get clear
 * errors; the frame reader accepts bytes split anywhere, one at a time too,
 * and refuses an oversized frame from its header alone. */
#include <stdint.h>

#include "test.h"
#include "wire.h"

static mts_wire_hello sample_hello(void)
{
    mts_wire_hello h = {0};
    h.major = MTS_WIRE_MAJOR;
    h.minor = MTS_WIRE_MINOR;
    strcpy(h.model, "bunny00");
    h.stop_kind = MTS_STOP_FRACTION;
    h.stop_value = 250000;
    h.resume_batch = 7;
    h.stream_id = 0x0123456789abcdefull;
    return h;
}

/* The single frame in b: its type and payload. */
static int one_frame(mts_buf *b, uint8_t *type, const uint8_t **payload, size_t *size)
{
    if (b->size < 5)
        return 0;
    uint32_t len = b->data[0] | b->data[1] << 8 | b->data[2] << 16 | (uint32_t)b->data[3] << 24;
    if (len + 4 != b->size)
        return 0;
    *type = b->data[4];
    *payload = b->data + 5;
    *size = len - 1;
    return 1;
}

static void test_hello_round_trip_and_errors(mts_test *t)
{
    mts_buf b = {0};
    mts_wire_hello h = sample_hello(), back;
    mts_wire_put_hello(&b, &h);
    uint8_t type;
    const uint8_t *p;
    size_t n;
    mts_error err = {0};
    CHECK(t, one_frame(&b, &type, &p, &n) && type == MTS_MSG_HELLO);
    CHECKF(t, mts_wire_parse_hello(p, n, &back, &err) == MTS_OK, "%s", err.msg);
    CHECK(t, back.major == MTS_WIRE_MAJOR && strcmp(back.model, "bunny00") == 0);
    CHECK(t, back.stop_kind == MTS_STOP_FRACTION && back.stop_value == 250000);
    CHECK(t, back.resume_batch == 7 && back.stream_id == h.stream_id);
    /* every truncation is an error */
    for (size_t cut = 0; cut < n; cut++)
        CHECKF(t, mts_wire_parse_hello(p, cut, &back, &err) != MTS_OK, "cut %zu accepted", cut);
    /* trailing garbage */
    uint8_t *longer = malloc(n + 1);
    memcpy(longer, p, n);
    longer[n] = 0;
    CHECK(t, mts_wire_parse_hello(longer, n + 1, &back, &err) == MTS_ERR_FORMAT);
    free(longer);
    /* bad magic, other major version */
    uint8_t *copy = malloc(n);
    memcpy(copy, p, n);
    copy[0] = 'G';
    CHECK(t, mts_wire_parse_hello(copy, n, &back, &err) == MTS_ERR_FORMAT);
    CHECK(t, strstr(err.msg, "magic") != NULL);
    /* 1.0 and 2.0 peers (records on the wire), 3.0 (splits not
     * entropy-coded), 4.0 (other growth rules), 5.0 (parents coded alone),
     * 6.0 (every full-strip swap bit coded) and a future major */
    CHECK(t, MTS_WIRE_MAJOR == 7);
    for (uint8_t old = 1; old <= 6; old++) {
        memcpy(copy, p, n);
        copy[4] = old;
        copy[6] = copy[7] = 0; /* an X.0 peer (this one writes MTS_WIRE_MINOR) */
        char want[8];
        snprintf(want, sizeof want, "%u.0", old);
        CHECK(t, mts_wire_parse_hello(copy, n, &back, &err) == MTS_ERR_VERSION);
        CHECKF(t, strstr(err.msg, want) != NULL && strstr(err.msg, "speaks 7.x") != NULL, "%s",
               err.msg);
    }
    copy[4] = 8;
    copy[6] = copy[7] = 0;
    CHECK(t, mts_wire_parse_hello(copy, n, &back, &err) == MTS_ERR_VERSION);
    CHECKF(t, strstr(err.msg, "8.0") != NULL, "%s", err.msg);
    free(copy);
    /* names that could reach a file system are refused */
    const char *bad[] = {"../etc/passwd", "a/b", ".hidden", "", "sp ace",
                         "x2345678901234567890123456789012345678901234567890123456789012345"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        mts_buf bb = {0};
        mts_wire_hello hb = sample_hello();
        snprintf(hb.model, sizeof hb.model, "%s", bad[i]);
        /* write the name raw, bypassing the writer's own truncation */
        size_t f = mts_wire_frame_begin(&bb, MTS_MSG_HELLO);
        mts_buf_put(&bb, "MTSH", 4);
        mts_buf_u16(&bb, MTS_WIRE_MAJOR);
        mts_buf_u16(&bb, 0);
        mts_buf_string(&bb, bad[i], strlen(bad[i]));
        mts_buf_u8(&bb, 0);
        mts_buf_varint(&bb, 0);
        mts_buf_varint(&bb, 0);
        mts_buf_u64(&bb, 0);
        mts_buf_varint(&bb, 0);
        mts_wire_frame_end(&bb, f);
        CHECK(t, one_frame(&bb, &type, &p, &n));
        CHECKF(t, mts_wire_parse_hello(p, n, &back, &err) == MTS_ERR_FORMAT, "name '%s' accepted",
               bad[i]);
        mts_buf_free(&bb);
    }
    CHECK(t, mts_wire_valid_name("cow", 3) && mts_wire_valid_name("a.b-c_D9", 8));
    mts_buf_free(&b);
}

static void test_model_info_round_trip_and_bounds(mts_test *t)
{
    mts_wire_model_info mi = {0}, back;
    mi.minor = 0;
    mi.stream_id = 42;
    strcpy(mi.model, "cow");
    mi.vertices = 40;
    mi.base_vertices = 5;
    mi.levels = 35;
    mi.triangles = 76;
    mi.strips = 4;
    mi.stop_level = 30;
    mi.stop_triangles = 60;
    mi.bbox_max[0] = mi.bbox_max[1] = mi.bbox_max[2] = 1;
    mi.quant_bits = 14;
    mi.flags = MTS_INFO_NORMALS;
    mi.grid_range = 1;
    mi.batch_count = 3; /* 15, 15 and the last 5 */
    mi.batch_size = 15;
    mi.capacity_total = 300;
    mts_buf b = {0};
    mts_wire_put_model_info(&b, &mi);
    uint8_t type;
    const uint8_t *p;
    size_t n;
    mts_error err = {0};
    CHECK(t, one_frame(&b, &type, &p, &n) && type == MTS_MSG_MODEL_INFO);
    CHECKF(t, mts_wire_parse_model_info(p, n, &back, &err) == MTS_OK, "%s", err.msg);
    CHECK(t, back.levels == 35 && back.batch_count == 3 && back.batch_size == 15);
    CHECK(t, mts_wire_batch_first(&back, 2) == 30 && mts_wire_batch_splits(&back, 1) == 15 &&
                 mts_wire_batch_splits(&back, 2) == 5);
    CHECK(t, back.capacity_total == 300 && back.stop_level == 30 && back.quant_bits == 14);
    CHECK(t, back.flags == MTS_INFO_NORMALS);
    mts_wire_model_info_free(&back);
    for (size_t cut = 0; cut < n; cut++) {
        CHECKF(t, mts_wire_parse_model_info(p, cut, &back, &err) != MTS_OK, "cut %zu", cut);
    }
    /* batch sizes that do not add up to the levels: too few batches, one
     * too many (the last would be empty), none of size 0 */
    const uint32_t bad[][2] = {{2, 15}, {4, 15}, {3, 11}, {3, 18}, {3, 0}, {0, 35}};
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; k++) {
        mts_wire_model_info x = mi;
        x.batch_count = bad[k][0];
        x.batch_size = bad[k][1];
        mts_buf c = {0};
        mts_wire_put_model_info(&c, &x);
        CHECK(t, one_frame(&c, &type, &p, &n));
        CHECKF(t, mts_wire_parse_model_info(p, n, &back, &err) == MTS_ERR_FORMAT,
               "%u batches of %u", x.batch_count, x.batch_size);
        CHECKF(t, strstr(err.msg, "do not make 35 levels") != NULL, "%s", err.msg);
        mts_buf_free(&c);
    }
    /* a flag this version does not know: the stream would not decode */
    mi.flags = 0x80;
    mts_buf g = {0};
    mts_wire_put_model_info(&g, &mi);
    CHECK(t, one_frame(&g, &type, &p, &n));
    CHECK(t, mts_wire_parse_model_info(p, n, &back, &err) == MTS_ERR_FORMAT);
    CHECKF(t, strstr(err.msg, "unknown flags 0x80") != NULL, "%s", err.msg);
    mts_buf_free(&g);
    mts_buf_free(&b);
    /* a count that promises more than the frame holds is refused before
     * allocating: written by hand, since the writer needs real arrays */
    mts_buf e = {0};
    size_t f = mts_wire_frame_begin(&e, MTS_MSG_MODEL_INFO);
    mts_buf_u16(&e, 0);
    mts_buf_u64(&e, 1);
    mts_buf_string(&e, "cow", 3);
    const uint32_t counts[] = {40, 5, 35, 76, 4000000000u, 30, 60};
    for (int i = 0; i < 7; i++)
        mts_buf_varint(&e, counts[i]);
    for (int i = 0; i < 6; i++)
        mts_buf_f32(&e, 0);
    mts_buf_u8(&e, 14);
    mts_buf_u8(&e, 0);
    for (int i = 0; i < 3; i++)
        mts_buf_f32(&e, 0);
    mts_buf_f32(&e, 1);
    mts_buf_varint(&e, 1);   /* one batch */
    mts_buf_varint(&e, 35);  /* of 35 splits */
    mts_buf_varint(&e, 100); /* the capacities' total */
    mts_buf_varint(&e, 0);   /* key levels */
    mts_wire_frame_end(&e, f);
    CHECK(t, one_frame(&e, &type, &p, &n));
    CHECK(t, mts_wire_parse_model_info(p, n, &back, &err) == MTS_ERR_FORMAT);
    CHECKF(t, strstr(err.msg, "cannot fit") != NULL, "%s", err.msg);
    mts_buf_free(&e);
}

/* 4.1's HELLO flag: a client asking for the records form says so in HELLO's
 * flags, which come back as sent (other bits too: a server ignores the ones
 * it does not know, so a later client's wishes cost it nothing); a peer
 * that asks for nothing (flags 0) still parses. */
static void test_hello_records_flag(mts_test *t)
{
    CHECK(t, MTS_HELLO_RECORDS == 1u);
    const uint32_t flags[] = {MTS_HELLO_RECORDS, 0, MTS_HELLO_RECORDS | 0x40u, 0x80u, 1u << 31};
    for (size_t i = 0; i < sizeof flags / sizeof flags[0]; i++) {
        mts_buf b = {0};
        mts_wire_hello h = sample_hello(), back;
        h.flags = flags[i];
        mts_wire_put_hello(&b, &h);
        uint8_t type;
        const uint8_t *p;
        size_t n;
        mts_error err = {0};
        CHECK(t, one_frame(&b, &type, &p, &n) && type == MTS_MSG_HELLO);
        CHECKF(t, mts_wire_parse_hello(p, n, &back, &err) == MTS_OK, "flags 0x%x: %s", flags[i],
               err.msg);
        CHECKF(t, back.flags == flags[i], "flags 0x%x came back 0x%x", flags[i], back.flags);
        CHECK(t, back.minor == MTS_WIRE_MINOR && back.resume_batch == 7 &&
                 back.stream_id == h.stream_id && strcmp(back.model, "bunny00") == 0);
        CHECK(t, !!(back.flags & MTS_HELLO_RECORDS) == !!(flags[i] & MTS_HELLO_RECORDS));
        /* cut anywhere, the flags included: refused */
        for (size_t cut = 0; cut < n; cut++)
            CHECKF(t, mts_wire_parse_hello(p, cut, &back, &err) != MTS_OK, "cut %zu accepted", cut);
        mts_buf_free(&b);
    }
    /* a 4.0 client's HELLO: minor 0, no flags */
    mts_buf b = {0};
    mts_wire_hello h = sample_hello(), back;
    h.minor = 0;
    mts_wire_put_hello(&b, &h);
    uint8_t type;
    const uint8_t *p;
    size_t n;
    mts_error err = {0};
    CHECK(t, one_frame(&b, &type, &p, &n));
    CHECKF(t, mts_wire_parse_hello(p, n, &back, &err) == MTS_OK, "%s", err.msg);
    CHECK(t, back.minor == 0 && back.flags == 0);
    mts_buf_free(&b);
}

/* MODEL_INFO's flag for the records form parses alone and with the normals
 * flag; a bit this version does not know is refused beside it. */
static void test_model_info_records_flag(mts_test *t)
{
    mts_wire_model_info mi = {0};
    mi.minor = MTS_WIRE_MINOR;
    mi.stream_id = 0x1122334455667788ull;
    strcpy(mi.model, "cow");
    mi.vertices = 40;
    mi.base_vertices = 5;
    mi.levels = 35;
    mi.triangles = 76;
    mi.strips = 2;
    mi.stop_level = 35;
    mi.stop_triangles = 76;
    mi.bbox_max[0] = mi.bbox_max[1] = mi.bbox_max[2] = 1;
    mi.quant_bits = 14;
    mi.grid_range = 1;
    mi.batch_count = 2; /* 20 and 15 */
    mi.batch_size = 20;
    mi.capacity_total = 60;
    /* colours (7.1) are known; a 7.0 client refused them as unknown, the
     * way this one refuses 8 and up */
    CHECK(t, MTS_INFO_RECORDS == 2u && MTS_INFO_COLORS == 4u &&
             MTS_INFO_KNOWN_FLAGS == (MTS_INFO_NORMALS | MTS_INFO_RECORDS | MTS_INFO_COLORS));
    CHECK(t, MTS_WIRE_MAJOR == 7 && MTS_WIRE_MINOR == 1);
    const struct {
        uint8_t flags;
        int ok;
    } cases[] = {{MTS_INFO_RECORDS, 1},
                 {MTS_INFO_RECORDS | MTS_INFO_NORMALS, 1},
                 {0, 1},
                 {MTS_INFO_COLORS, 1},
                 {MTS_INFO_RECORDS | MTS_INFO_NORMALS | MTS_INFO_COLORS, 1},
                 {8, 0},
                 {MTS_INFO_RECORDS | 8, 0},
                 {MTS_INFO_COLORS | 0x10, 0},
                 {MTS_INFO_RECORDS | MTS_INFO_NORMALS | 0x40, 0}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        mi.flags = cases[i].flags;
        mts_buf b = {0};
        mts_wire_put_model_info(&b, &mi);
        uint8_t type;
        const uint8_t *p;
        size_t n;
        mts_error err = {0};
        mts_wire_model_info back;
        CHECK(t, one_frame(&b, &type, &p, &n) && type == MTS_MSG_MODEL_INFO);
        mts_result rc = mts_wire_parse_model_info(p, n, &back, &err);
        if (cases[i].ok) {
            CHECKF(t, rc == MTS_OK, "flags 0x%02x: %s", cases[i].flags, err.msg);
            CHECK(t, rc != MTS_OK || (back.flags == cases[i].flags && back.minor == MTS_WIRE_MINOR &&
                                      back.stream_id == mi.stream_id && back.batch_count == 2 &&
                                      mts_wire_batch_splits(&back, 1) == 15 && back.capacity_total == 60));
            if (rc == MTS_OK)
                mts_wire_model_info_free(&back);
        } else {
            char want[40];
            snprintf(want, sizeof want, "unknown flags 0x%02x", cases[i].flags);
            CHECKF(t, rc == MTS_ERR_FORMAT && strstr(err.msg, want), "flags 0x%02x: %d %s",
                   cases[i].flags, rc, err.msg);
        }
        mts_buf_free(&b);
    }
}

static void test_small_messages(mts_test *t)
{
    mts_buf b = {0};
    mts_error err = {0};
    uint8_t type;
    const uint8_t *p;
    size_t n;
    mts_wire_end e = {1234, 0xfeedfacecafebeefull, 99999}, eb;
    mts_wire_put_end(&b, &e);
    CHECK(t, one_frame(&b, &type, &p, &n) && type == MTS_MSG_END);
    CHECK(t, mts_wire_parse_end(p, n, &eb, &err) == MTS_OK);
    CHECK(t, eb.final_level == 1234 && eb.checksum == e.checksum && eb.stream_bytes == 99999);
    b.size = 0;
    mts_wire_put_error(&b, MTS_WERR_UNKNOWN_MODEL, "no model 'x'\n\x01");
    CHECK(t, one_frame(&b, &type, &p, &n) && type == MTS_MSG_ERROR);
    uint16_t code;
    char text[64];
    CHECK(t, mts_wire_parse_error(p, n, &code, text, sizeof text, &err) == MTS_OK);
    CHECK(t, code == MTS_WERR_UNKNOWN_MODEL && strcmp(text, "no model 'x'??") == 0);
    CHECK(t, strcmp(mts_wire_error_name(code), "unknown_model") == 0);
    b.size = 0;
    mts_wire_put_list(&b);
    CHECK(t, one_frame(&b, &type, &p, &n) && type == MTS_MSG_LIST && n == 0);
    mts_buf_free(&b);
}

/* A peer's text comes out as UTF-8: well-formed characters kept whole,
 * every byte of anything else and every control byte '?', never a
 * character cut by the room left. */
static void test_clean_text(mts_test *t)
{
    char out[64];
    const char ok[] = "caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80";
    CHECK(t, mts_wire_clean_text(out, sizeof out, ok, strlen(ok)) == strlen(ok) &&
                 strcmp(out, ok) == 0);
    const struct {
        const char *in, *want;
    } cases[] = {
        {"\xff\xfe", "??"},
        {"a\xc0\xaf" "b", "a??b"},         /* overlong "/" */
        {"\xed\xa0\x80", "???"},            /* a surrogate */
        {"\xf4\x90\x80\x80", "????"},       /* past U+10FFFF */
        {"x\xe2\x82", "x??"},                /* cut short */
        {"\x80z", "?z"},                    /* a stray continuation */
        {"tab\there\x7f", "tab?here?"},      /* control bytes */
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        mts_wire_clean_text(out, sizeof out, cases[i].in, strlen(cases[i].in));
        CHECKF(t, strcmp(out, cases[i].want) == 0, "case %zu: %s", i, out);
    }
    /* room for "caf" and half of the e-acute: the character is left out */
    CHECK(t, mts_wire_clean_text(out, 5, ok, strlen(ok)) == 3 && strcmp(out, "caf") == 0);
}

/* Frames fed in pieces of every size come out whole and in order. */
static void test_reader_any_split(mts_test *t)
{
    mts_buf b = {0};
    mts_wire_hello h = sample_hello();
    mts_wire_put_hello(&b, &h);
    mts_wire_put_list(&b);
    mts_wire_put_error(&b, 1, "bye");
    for (size_t piece = 1; piece <= b.size && !t->case_failed; piece++) {
        mts_wire_reader r = {0};
        mts_error err = {0};
        int frames = 0;
        uint8_t types[3] = {0};
        for (size_t at = 0; at < b.size; at += piece) {
            size_t k = b.size - at < piece ? b.size - at : piece;
            CHECK(t, mts_wire_reader_feed(&r, b.data + at, k, &err) == MTS_OK);
            uint8_t type;
            const uint8_t *p;
            size_t n;
            int got;
            while ((got = mts_wire_reader_next(&r, &type, &p, &n, &err)) == 1) {
                if (frames < 3)
                    types[frames] = type;
                frames++;
                if (type == MTS_MSG_HELLO) {
                    mts_wire_hello back;
                    CHECK(t, mts_wire_parse_hello(p, n, &back, &err) == MTS_OK);
                }
            }
            CHECK(t, got == 0);
        }
        CHECKF(t, frames == 3 && types[0] == MTS_MSG_HELLO && types[1] == MTS_MSG_LIST &&
                      types[2] == MTS_MSG_ERROR,
               "piece %zu: %d frames", piece, frames);
        mts_wire_reader_free(&r);
    }
    mts_buf_free(&b);
}

/* Peeking: the frame `skip` frames on, only once it is whole, left for
 * next; a bad length on the way gives 0 (next then refuses it). */
static void test_reader_peek(mts_test *t)
{
    mts_buf b = {0};
    mts_wire_hello h = sample_hello();
    mts_wire_put_hello(&b, &h);
    mts_wire_put_list(&b);
    mts_wire_put_error(&b, 1, "bye");
    mts_wire_reader r = {0};
    mts_error err = {0};
    uint8_t type = 0;
    const uint8_t *p;
    size_t n;
    /* all but the last byte: the first two frames whole, the third not */
    CHECK(t, mts_wire_reader_feed(&r, b.data, b.size - 1, &err) == MTS_OK);
    CHECK(t, mts_wire_reader_peek(&r, 0, &type, &p, &n) == 1 && type == MTS_MSG_HELLO);
    CHECK(t, mts_wire_reader_peek(&r, 1, &type, &p, &n) == 1 && type == MTS_MSG_LIST);
    CHECK(t, mts_wire_reader_peek(&r, 2, &type, &p, &n) == 0);
    CHECK(t, mts_wire_reader_feed(&r, b.data + b.size - 1, 1, &err) == MTS_OK);
    CHECK(t, mts_wire_reader_peek(&r, 2, &type, &p, &n) == 1 && type == MTS_MSG_ERROR);
    const uint8_t *peeked = p;
    size_t peeked_n = n;
    /* next takes them in order, the same bytes as peeked */
    CHECK(t, mts_wire_reader_next(&r, &type, &p, &n, &err) == 1 && type == MTS_MSG_HELLO);
    CHECK(t, mts_wire_reader_peek(&r, 1, &type, &p, &n) == 1 && p == peeked && n == peeked_n);
    CHECK(t, mts_wire_reader_peek(&r, 2, &type, &p, &n) == 0);
    mts_wire_reader_free(&r);
    /* a zero length after the first frame: peeking past it finds nothing */
    const uint8_t zero[5] = {0, 0, 0, 0, 1};
    CHECK(t, mts_wire_reader_feed(&r, b.data, 4 + (size_t)b.data[0], &err) == MTS_OK);
    CHECK(t, mts_wire_reader_feed(&r, zero, 5, &err) == MTS_OK);
    CHECK(t, mts_wire_reader_peek(&r, 0, &type, &p, &n) == 1);
    CHECK(t, mts_wire_reader_peek(&r, 1, &type, &p, &n) == 0);
    mts_wire_reader_free(&r);
    mts_buf_free(&b);
}

static void test_reader_refuses_bad_lengths(mts_test *t)
{
    mts_wire_reader r = {0};
    mts_error err = {0};
    const uint8_t huge[5] = {0x01, 0x00, 0x00, 0x02, MTS_MSG_BATCH}; /* 32 MiB + 1 */
    CHECK(t, mts_wire_reader_feed(&r, huge, 4, &err) == MTS_OK);
    uint8_t type;
    const uint8_t *p;
    size_t n;
    CHECK(t, mts_wire_reader_next(&r, &type, &p, &n, &err) == -1);
    CHECKF(t, strstr(err.msg, "allowed") != NULL, "%s", err.msg);
    mts_wire_reader_free(&r);
    const uint8_t zero[5] = {0, 0, 0, 0, 1};
    CHECK(t, mts_wire_reader_feed(&r, zero, 5, &err) == MTS_OK);
    CHECK(t, mts_wire_reader_next(&r, &type, &p, &n, &err) == -1);
    mts_wire_reader_free(&r);
}

/* Two near-maximal frames back to back, fed in pieces and drained after each
 * feed as a client does: consumed bytes are dropped before the buffer grows,
 * so a legal stream is never refused as "more than a frame buffered". */
static void test_reader_two_big_frames(mts_test *t)
{
    const size_t a_len = (16u << 20) - 4, b_len = MTS_WIRE_MAX_FRAME; /* type + payload */
    const size_t total = 4 + a_len + 4 + b_len;
    uint8_t *data = calloc(total, 1);
    CHECK(t, data != NULL);
    if (!data)
        return;
    data[0] = (uint8_t)a_len;
    data[1] = (uint8_t)(a_len >> 8);
    data[2] = (uint8_t)(a_len >> 16);
    data[3] = (uint8_t)(a_len >> 24);
    data[4] = MTS_MSG_BASE;
    uint8_t *bh = data + 4 + a_len;
    bh[0] = (uint8_t)b_len;
    bh[1] = (uint8_t)(b_len >> 8);
    bh[2] = (uint8_t)(b_len >> 16);
    bh[3] = (uint8_t)(b_len >> 24);
    bh[4] = MTS_MSG_BATCH;
    mts_wire_reader r = {0};
    mts_error err = {0};
    int frames = 0, ok = 1;
    for (size_t at = 0; at < total && ok; at += 100000) {
        size_t k = total - at < 100000 ? total - at : 100000;
        ok = mts_wire_reader_feed(&r, data + at, k, &err) == MTS_OK;
        CHECKF(t, ok, "at %zu: %s", at, err.msg);
        uint8_t type;
        const uint8_t *p;
        size_t n;
        while (ok && mts_wire_reader_next(&r, &type, &p, &n, &err) == 1) {
            CHECK(t, n == (frames == 0 ? a_len : b_len) - 1);
            frames++;
        }
    }
    CHECK(t, frames == 2);
    CHECK(t, r.cap <= 2 * ((size_t)MTS_WIRE_MAX_FRAME + MTS_WIRE_HEADER) + 100000);
    mts_wire_reader_free(&r);
    free(data);
}

int main(void)
{
    mts_test t = {0};
    RUN(&t, test_clean_text);
    RUN(&t, test_hello_round_trip_and_errors);
    RUN(&t, test_model_info_round_trip_and_bounds);
    RUN(&t, test_hello_records_flag);
    RUN(&t, test_model_info_records_flag);
    RUN(&t, test_small_messages);
    RUN(&t, test_reader_any_split);
    RUN(&t, test_reader_peek);
    RUN(&t, test_reader_refuses_bad_lengths);
    RUN(&t, test_reader_two_big_frames);
    return mts_test_end(&t);
}
