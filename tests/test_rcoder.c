/* The range coder: bits, direct bits, integers and tree symbols round-trip,
 * alone and interleaved; skewed bits and geometric integers compress near
 * their entropy; a decoder uses exactly the bytes of a stream, refusing
 * every truncation and any trailing byte; garbage of any length decodes
 * without harm and is caught; the byte format is pinned. */
#include <math.h>
#include <stdint.h>

#include "rcoder.h"
#include "test.h"

/* xorshift64: the same sequence everywhere, so measured sizes are stable */
typedef struct rng {
    uint64_t s;
} rng;

static uint64_t next(rng *r)
{
    r->s ^= r->s << 13;
    r->s ^= r->s >> 7;
    r->s ^= r->s << 17;
    return r->s;
}

/* 1 with probability num / 65536 */
static unsigned coin(rng *r, uint32_t num)
{
    return (uint32_t)(next(r) >> 48) < num;
}

/* A geometric value: failures before a success of probability num / 65536. */
static uint32_t geometric(rng *r, uint32_t num)
{
    uint32_t v = 0;
    while (!coin(r, num))
        v++;
    return v;
}

/* Decoding from an exact-size heap copy, so a sanitizer build catches any
 * read past the end. */
static uint8_t *copy_of(const uint8_t *data, size_t size)
{
    uint8_t *c = malloc(size ? size : 1);
    if (size)
        memcpy(c, data, size);
    return c;
}

static void test_empty_stream(mts_test *t)
{
    mts_buf b = {0};
    mts_rc_encoder e;
    mts_rc_encoder_init(&e, &b);
    mts_rc_encoder_flush(&e);
    CHECK(t, !b.failed && b.size == 1);
    uint8_t *c = copy_of(b.data, b.size);
    mts_rc_decoder d;
    CHECK(t, mts_rc_decoder_init(&d, c, b.size));
    CHECK(t, mts_rc_decoder_finished(&d));
    /* nothing at all is not a stream */
    CHECK(t, !mts_rc_decoder_init(&d, c, 0) && !d.ok && !mts_rc_decoder_finished(&d));
    CHECK(t, !mts_rc_decoder_init(&d, NULL, 0) && !mts_rc_decoder_finished(&d));
    free(c);
    /* code >= range: no encoder writes this */
    static const uint8_t ff[4] = {0xFF, 0xFF, 0xFF, 0xFF};
    CHECK(t, !mts_rc_decoder_init(&d, ff, 4));
    mts_buf_free(&b);
}

static void test_bits_round_trip(mts_test *t)
{
    /* eight models, from nearly always 0 to nearly always 1 */
    static const uint32_t p1[8] = {300, 3000, 16384, 32768, 49152, 62000, 65236, 65535};
    enum { N = 200000 };
    uint8_t *bits = malloc(N), *which = malloc(N);
    rng r = {12345};
    mts_buf b = {0};
    mts_rc_encoder e;
    mts_rc_encoder_init(&e, &b);
    uint16_t probs[8];
    mts_rc_prob_init(probs, 8);
    for (int i = 0; i < N; i++) {
        which[i] = (uint8_t)(next(&r) & 7);
        bits[i] = (uint8_t)coin(&r, p1[which[i]]);
        mts_rc_encode_bit(&e, &probs[which[i]], bits[i]);
    }
    mts_rc_encoder_flush(&e);
    uint8_t *c = copy_of(b.data, b.size);
    mts_rc_decoder d;
    CHECK(t, mts_rc_decoder_init(&d, c, b.size));
    mts_rc_prob_init(probs, 8);
    int wrong = 0;
    for (int i = 0; i < N; i++)
        wrong += mts_rc_decode_bit(&d, &probs[which[i]]) != bits[i];
    CHECKF(t, wrong == 0, "%d of %d bits wrong", wrong, N);
    CHECK(t, mts_rc_decoder_finished(&d));
    free(c);
    free(bits);
    free(which);
    mts_buf_free(&b);
}

static void test_direct_round_trip(mts_test *t)
{
    /* random widths 0..32; half a megabyte of uniform bits also makes 0xFF
     * runs and carries through them */
    enum { N = 150000 };
    rng r = {777};
    mts_buf b = {0};
    mts_rc_encoder e;
    mts_rc_encoder_init(&e, &b);
    for (int i = 0; i < N; i++) {
        unsigned n = (unsigned)(next(&r) % 33);
        mts_rc_encode_direct(&e, (uint32_t)next(&r), n);
    }
    mts_rc_encode_direct(&e, UINT32_MAX, 32);
    mts_rc_encode_direct(&e, 0, 32);
    mts_rc_encoder_flush(&e);
    size_t ff = 0;
    for (size_t i = 0; i < b.size; i++)
        ff += b.data[i] == 0xFF;
    CHECK(t, ff > 100);
    uint8_t *c = copy_of(b.data, b.size);
    mts_rc_decoder d;
    CHECK(t, mts_rc_decoder_init(&d, c, b.size));
    r.s = 777;
    int wrong = 0;
    for (int i = 0; i < N; i++) {
        unsigned n = (unsigned)(next(&r) % 33);
        uint32_t want = (uint32_t)next(&r);
        want = n == 32 ? want : want & ((1u << n) - 1);
        wrong += mts_rc_decode_direct(&d, n) != want;
    }
    CHECK(t, mts_rc_decode_direct(&d, 32) == UINT32_MAX);
    CHECK(t, mts_rc_decode_direct(&d, 32) == 0);
    CHECKF(t, wrong == 0, "%d values wrong", wrong);
    CHECK(t, mts_rc_decoder_finished(&d));
    free(c);
    mts_buf_free(&b);
}

/* 0, 1, 2^k - 1, 2^k, 2^k + 1 for every k, UINT32_MAX; then random values
 * of random magnitudes */
static uint32_t uint_case(rng *r, int i)
{
    static const int edges = 3 * 32 + 2;
    if (i < edges) {
        if (i == 0)
            return 0;
        if (i == 1)
            return UINT32_MAX;
        int k = (i - 2) / 3, d = (i - 2) % 3 - 1;
        return (uint32_t)((1ull << k) + (uint64_t)(int64_t)d);
    }
    uint32_t v = (uint32_t)next(r);
    return v >> (next(r) % 32);
}

static void test_uint_round_trip(mts_test *t)
{
    enum { N = 50000 };
    rng r = {99};
    mts_buf b = {0};
    mts_rc_encoder e;
    mts_rc_encoder_init(&e, &b);
    mts_rc_uint_model m;
    mts_rc_uint_model_init(&m);
    for (int i = 0; i < N; i++)
        mts_rc_encode_uint(&e, &m, uint_case(&r, i));
    mts_rc_encoder_flush(&e);
    uint8_t *c = copy_of(b.data, b.size);
    mts_rc_decoder d;
    CHECK(t, mts_rc_decoder_init(&d, c, b.size));
    mts_rc_uint_model_init(&m);
    r.s = 99;
    int wrong = 0;
    for (int i = 0; i < N; i++) {
        uint32_t want = uint_case(&r, i), got = mts_rc_decode_uint(&d, &m);
        if (got != want && wrong++ < 5)
            fprintf(stderr, "  value %d: %u, want %u\n", i, got, want);
    }
    CHECK(t, wrong == 0);
    CHECK(t, mts_rc_decoder_finished(&d));
    free(c);
    mts_buf_free(&b);
}

static int32_t sint_case(rng *r, int i)
{
    static const int32_t edges[] = {0, -1, 1, INT32_MIN, INT32_MAX, INT32_MIN + 1, INT32_MAX - 1,
                                    -2, 2, 1 << 30, -(1 << 30), 65535, -65536};
    if (i < (int)(sizeof edges / sizeof edges[0]))
        return edges[i];
    uint32_t u = (uint32_t)next(r);
    u >>= next(r) % 32;
    return (next(r) & 1) ? (int32_t)(u >> 1) : -(int32_t)(u >> 1) - 1;
}

static void test_sint_round_trip(mts_test *t)
{
    enum { N = 30000 };
    rng r = {4242};
    mts_buf b = {0};
    mts_rc_encoder e;
    mts_rc_encoder_init(&e, &b);
    mts_rc_uint_model m;
    mts_rc_uint_model_init(&m);
    for (int i = 0; i < N; i++)
        mts_rc_encode_sint(&e, &m, sint_case(&r, i));
    mts_rc_encoder_flush(&e);
    uint8_t *c = copy_of(b.data, b.size);
    mts_rc_decoder d;
    CHECK(t, mts_rc_decoder_init(&d, c, b.size));
    mts_rc_uint_model_init(&m);
    r.s = 4242;
    int wrong = 0;
    for (int i = 0; i < N; i++)
        wrong += mts_rc_decode_sint(&d, &m) != sint_case(&r, i);
    CHECKF(t, wrong == 0, "%d values wrong", wrong);
    CHECK(t, mts_rc_decoder_finished(&d));
    free(c);
    mts_buf_free(&b);
}

static void test_tree_round_trip(mts_test *t)
{
    /* every width 0..8, skewed symbols (geometric, so the tree has something
     * to learn) and uniform ones; and a width above 8 is taken as 8 */
    for (unsigned nbits = 0; nbits <= 9; nbits++) {
        enum { N = 20000 };
        unsigned n = nbits > 8 ? 8 : nbits, mask = (1u << n) - 1;
        rng r = {1000 + nbits};
        mts_buf b = {0};
        mts_rc_encoder e;
        mts_rc_encoder_init(&e, &b);
        mts_rc_tree_model m;
        mts_rc_tree_model_init(&m, nbits);
        CHECK(t, m.nbits == n);
        for (int i = 0; i < N; i++) {
            unsigned s = (i & 1) ? (unsigned)next(&r) : geometric(&r, 20000);
            mts_rc_encode_tree(&e, &m, s & mask);
        }
        mts_rc_encoder_flush(&e);
        if (nbits == 0)
            CHECK(t, b.size == 1); /* zero-bit symbols cost nothing */
        uint8_t *c = copy_of(b.data, b.size);
        mts_rc_decoder d;
        CHECK(t, mts_rc_decoder_init(&d, c, b.size));
        mts_rc_tree_model_init(&m, nbits);
        r.s = 1000 + nbits;
        int wrong = 0;
        for (int i = 0; i < N; i++) {
            unsigned s = (i & 1) ? (unsigned)next(&r) : geometric(&r, 20000);
            wrong += mts_rc_decode_tree(&d, &m) != (s & mask);
        }
        CHECKF(t, wrong == 0, "nbits %u: %d symbols wrong", nbits, wrong);
        CHECKF(t, mts_rc_decoder_finished(&d), "nbits %u", nbits);
        free(c);
        mts_buf_free(&b);
    }
}

/* A mixture: per step a random kind of symbol, each kind with models of its
 * own, as a stream interleaves its fields. Both sides draw the same script
 * from the seed. */
typedef struct mix_models {
    uint16_t flag[4];
    mts_rc_uint_model delta, residual;
    mts_rc_tree_model code3, code8;
} mix_models;

static void mix_init(mix_models *mm)
{
    mts_rc_prob_init(mm->flag, 4);
    mts_rc_uint_model_init(&mm->delta);
    mts_rc_uint_model_init(&mm->residual);
    mts_rc_tree_model_init(&mm->code3, 3);
    mts_rc_tree_model_init(&mm->code8, 8);
}

typedef struct mix_step {
    unsigned kind;
    uint32_t value;
} mix_step;

static mix_step mix_next(rng *r)
{
    mix_step s;
    s.kind = (unsigned)(next(r) % 6);
    switch (s.kind) {
    case 0: s.value = coin(r, 6000); break;
    case 1: s.value = geometric(r, 8000); break;
    case 2: s.value = (uint32_t)(int32_t)(geometric(r, 3000) * ((next(r) & 1) ? 1 : -1)); break;
    case 3: s.value = geometric(r, 30000) & 7; break;
    case 4: s.value = (uint32_t)next(r) & 0xFF; break;
    default: s.value = (uint32_t)next(r) & 0x3FF; break;
    }
    return s;
}

static void mix_encode(mts_rc_encoder *e, mix_models *mm, mix_step s, unsigned i)
{
    switch (s.kind) {
    case 0: mts_rc_encode_bit(e, &mm->flag[i & 3], s.value); break;
    case 1: mts_rc_encode_uint(e, &mm->delta, s.value); break;
    case 2: mts_rc_encode_sint(e, &mm->residual, (int32_t)s.value); break;
    case 3: mts_rc_encode_tree(e, &mm->code3, s.value); break;
    case 4: mts_rc_encode_tree(e, &mm->code8, s.value); break;
    default: mts_rc_encode_direct(e, s.value, 10); break;
    }
}

static uint32_t mix_decode(mts_rc_decoder *d, mix_models *mm, unsigned kind, unsigned i)
{
    switch (kind) {
    case 0: return mts_rc_decode_bit(d, &mm->flag[i & 3]);
    case 1: return mts_rc_decode_uint(d, &mm->delta);
    case 2: return (uint32_t)mts_rc_decode_sint(d, &mm->residual);
    case 3: return mts_rc_decode_tree(d, &mm->code3);
    case 4: return mts_rc_decode_tree(d, &mm->code8);
    default: return mts_rc_decode_direct(d, 10);
    }
}

static void mix_encode_stream(mts_buf *b, uint64_t seed, int n)
{
    rng r = {seed};
    mix_models mm;
    mix_init(&mm);
    mts_rc_encoder e;
    mts_rc_encoder_init(&e, b);
    for (int i = 0; i < n; i++)
        mix_encode(&e, &mm, mix_next(&r), (unsigned)i);
    mts_rc_encoder_flush(&e);
}

/* Decodes the mixture from data; returns the number of wrong values. */
static int mix_decode_stream(mts_rc_decoder *d, const uint8_t *data, size_t size, uint64_t seed,
                             int n)
{
    rng r = {seed};
    mix_models mm;
    mix_init(&mm);
    mts_rc_decoder_init(d, data, size);
    int wrong = 0;
    for (int i = 0; i < n; i++) {
        mix_step s = mix_next(&r);
        wrong += mix_decode(d, &mm, s.kind, (unsigned)i) != s.value;
    }
    return wrong;
}

static void test_mixture_round_trip(mts_test *t)
{
    for (int n = 0; n <= 3000; n = n ? n * 3 : 1) {
        mts_buf b = {0};
        mix_encode_stream(&b, 555 + (uint64_t)n, n);
        uint8_t *c = copy_of(b.data, b.size);
        mts_rc_decoder d;
        int wrong = mix_decode_stream(&d, c, b.size, 555 + (uint64_t)n, n);
        CHECKF(t, wrong == 0, "n %d: %d wrong", n, wrong);
        CHECKF(t, mts_rc_decoder_finished(&d), "n %d", n);
        free(c);
        mts_buf_free(&b);
    }
}

/* Every cut of a stream is refused (not finished, and ok = 0: the decoder
 * needed zeros past the tail), so is every stream with bytes after it, and
 * neither reads outside the input. */
static void test_exact_end(mts_test *t)
{
    for (int n = 0; n <= 60; n += 3) {
        uint64_t seed = 31 + (uint64_t)n;
        mts_buf b = {0};
        mix_encode_stream(&b, seed, n);
        mts_rc_decoder d;
        for (size_t cut = 0; cut < b.size; cut++) {
            uint8_t *c = copy_of(b.data, cut);
            mix_decode_stream(&d, c, cut, seed, n);
            CHECKF(t, !mts_rc_decoder_finished(&d) && !d.ok, "n %d: cut %zu of %zu accepted", n,
                   cut, b.size);
            free(c);
        }
        static const uint8_t tails[] = {0x00, 0xFF, 0x5A};
        for (size_t extra = 1; extra <= 6; extra++) {
            for (size_t k = 0; k < sizeof tails; k++) {
                uint8_t *c = malloc(b.size + extra);
                memcpy(c, b.data, b.size);
                memset(c + b.size, tails[k], extra);
                int wrong = mix_decode_stream(&d, c, b.size + extra, seed, n);
                /* the bytes after it do not change what it decodes to */
                CHECK(t, wrong == 0);
                CHECKF(t, !mts_rc_decoder_finished(&d), "n %d: %zu bytes 0x%02x after it accepted",
                       n, extra, tails[k]);
                free(c);
            }
        }
        /* and the stream itself, exactly */
        uint8_t *c = copy_of(b.data, b.size);
        CHECK(t, mix_decode_stream(&d, c, b.size, seed, n) == 0);
        CHECK(t, mts_rc_decoder_finished(&d) && d.p == d.end && d.past_end == MTS_RC_TAIL_BYTES);
        free(c);
        mts_buf_free(&b);
    }
}

static double entropy_bits(double p)
{
    return -(p * log2(p) + (1 - p) * log2(1 - p));
}

static void test_compression_skewed_bits(mts_test *t)
{
    enum { N = 100000 };
    rng r = {2024};
    mts_buf b = {0};
    mts_rc_encoder e;
    mts_rc_encoder_init(&e, &b);
    uint16_t prob = MTS_RC_PROB_INIT;
    int ones = 0;
    for (int i = 0; i < N; i++) {
        unsigned bit = coin(&r, 3277); /* p(1) = 0.05 */
        ones += bit;
        mts_rc_encode_bit(&e, &prob, bit);
    }
    mts_rc_encoder_flush(&e);
    double bound = N * entropy_bits((double)ones / N) / 8;
    /* Measured 1.083 times the bound (3897 bytes for 3599). The cost over
     * the bound is the price of adapting by 1/16 a bit -- a noisy estimate
     * of p -- which short batches need; by 1/32 this would be about 1.04. */
    CHECKF(t, b.size < 1.10 * bound, "%zu bytes, entropy %.0f", b.size, bound);
    CHECKF(t, b.size > 0.99 * bound, "%zu bytes, entropy %.0f", b.size, bound);
    mts_buf_free(&b);
}

static size_t varint_size(uint32_t v)
{
    uint8_t p[MTS_VARINT32_MAX_BYTES];
    return mts_varint_put(p, v);
}

static void test_compression_geometric(mts_test *t)
{
    /* mean 4 and mean 99: bytes, against the entropy and against varints.
     * Measured: 4692 (entropy 4512, varints 10000) and 10272 (entropy
     * 10099, varints 12652). */
    static const double p[2] = {0.2, 0.01};
    static const double slack[2] = {1.07, 1.05};
    for (int k = 0; k < 2; k++) {
        enum { N = 10000 };
        rng r = {88172645463325252ull};
        mts_buf b = {0};
        mts_rc_encoder e;
        mts_rc_encoder_init(&e, &b);
        mts_rc_uint_model m;
        mts_rc_uint_model_init(&m);
        size_t varints = 0;
        for (int i = 0; i < N; i++) {
            uint32_t v = geometric(&r, (uint32_t)(p[k] * 65536));
            varints += varint_size(v);
            mts_rc_encode_uint(&e, &m, v);
        }
        mts_rc_encoder_flush(&e);
        double bound = N * entropy_bits(p[k]) / p[k] / 8;
        CHECKF(t, b.size < slack[k] * bound, "p %.2f: %zu bytes, entropy %.0f", p[k], b.size,
               bound);
        CHECKF(t, b.size < (k == 0 ? 0.5 : 0.85) * varints, "p %.2f: %zu bytes, varints %zu",
               p[k], b.size, varints);
        mts_buf_free(&b);
    }
}

/* Random bytes of every length up to 300 and some longer: whatever they
 * decode to, no symbol is out of range, nothing is read outside them, and
 * once a decoder needs more bytes than they hold it says so. */
static void test_garbage_input(mts_test *t)
{
    rng r = {0xDEADBEEF};
    int caught = 0, lengths = 0;
    for (size_t len = 0; len <= 4096; len = len < 300 ? len + 1 : len * 2) {
        for (int pattern = 0; pattern < 3; pattern++) {
            uint8_t *c = malloc(len ? len : 1);
            for (size_t i = 0; i < len; i++)
                c[i] = pattern == 0 ? (uint8_t)next(&r) : pattern == 1 ? 0xFF : 0x00;
            mts_rc_decoder d;
            mts_rc_decoder_init(&d, c, len);
            mix_models mm;
            mix_init(&mm);
            int bad = 0;
            for (int i = 0; i < 3000; i++) {
                unsigned kind = (unsigned)(next(&r) % 6);
                uint32_t v = mix_decode(&d, &mm, kind, (unsigned)i);
                bad += (kind == 0 && v > 1) || (kind == 3 && v > 7) || (kind == 4 && v > 255) ||
                       (kind == 5 && v > 1023);
            }
            CHECK(t, bad == 0);
            CHECK(t, d.p >= c && d.p <= c + len);
            /* 8 direct bits take a byte: this is more than there is */
            for (size_t i = 0; i < len + MTS_RC_TAIL_BYTES + 1; i++)
                mts_rc_decode_direct(&d, 8);
            CHECKF(t, !d.ok && !mts_rc_decoder_finished(&d), "len %zu pattern %d", len, pattern);
            caught += !d.ok;
            lengths++;
            free(c);
        }
    }
    CHECK(t, caught == lengths);
}

/* A bucket of 33..63 is no value: the bucket tree is a 6-bit tree, so
 * coding 40 with a fresh 6-bit tree model makes one. */
static void test_bad_bucket(mts_test *t)
{
    mts_buf b = {0};
    mts_rc_encoder e;
    mts_rc_encoder_init(&e, &b);
    mts_rc_tree_model tm;
    mts_rc_tree_model_init(&tm, MTS_RC_BUCKET_BITS);
    mts_rc_encode_tree(&e, &tm, 40);
    mts_rc_encoder_flush(&e);
    mts_rc_decoder d;
    mts_rc_uint_model m;
    mts_rc_uint_model_init(&m);
    CHECK(t, mts_rc_decoder_init(&d, b.data, b.size));
    CHECK(t, mts_rc_decode_uint(&d, &m) == 0);
    CHECK(t, !d.ok && !mts_rc_decoder_finished(&d));
    mts_buf_free(&b);
}

/* An out-of-memory buffer stays failed and takes nothing. */
static void test_failed_buffer(mts_test *t)
{
    mts_buf b = {0};
    b.failed = 1;
    mts_rc_encoder e;
    mts_rc_encoder_init(&e, &b);
    mts_rc_uint_model m;
    mts_rc_uint_model_init(&m);
    for (uint32_t i = 0; i < 1000; i++)
        mts_rc_encode_uint(&e, &m, i * 7919);
    mts_rc_encoder_flush(&e);
    CHECK(t, b.failed && b.size == 0 && b.data == NULL);
}

/* The bytes of a fixed mixture: the format is the wire's, so a change to
 * the coder or the models that moves one byte must be deliberate (and is a
 * wire version). Integers only, so these are the bytes on every platform. */
static void test_format_pinned(mts_test *t)
{
    static const uint8_t want[] = {
        0x66, 0x31, 0xd2, 0xf5, 0xd7, 0xc8, 0x2a, 0x18, 0x8f, 0x51, 0xd2, 0x1a,
        0xdc, 0xbd, 0x1e, 0xae, 0x35, 0xd8, 0x48, 0xc5, 0x85, 0x20, 0xf0, 0x15,
        0xe2, 0x62, 0x82, 0x4e, 0xeb, 0xb8, 0xd2, 0x60, 0xcb, 0xa1,
    };
    mts_buf b = {0};
    mix_encode_stream(&b, 20240601, 40);
    int same = b.size == sizeof want && memcmp(b.data, want, b.size) == 0;
    if (!same || getenv("MTS_RC_PRINT_GOLDEN")) {
        fprintf(stderr, "  %zu bytes:", b.size);
        for (size_t i = 0; i < b.size; i++)
            fprintf(stderr, "%s0x%02x,", i % 12 ? " " : "\n  ", b.data[i]);
        fputc('\n', stderr);
    }
    CHECK(t, same);
    mts_buf_free(&b);
}

int main(void)
{
    mts_test t = {0};
    RUN(&t, test_empty_stream);
    RUN(&t, test_bits_round_trip);
    RUN(&t, test_direct_round_trip);
    RUN(&t, test_uint_round_trip);
    RUN(&t, test_sint_round_trip);
    RUN(&t, test_tree_round_trip);
    RUN(&t, test_mixture_round_trip);
    RUN(&t, test_exact_end);
    RUN(&t, test_compression_skewed_bits);
    RUN(&t, test_compression_geometric);
    RUN(&t, test_garbage_input);
    RUN(&t, test_bad_bucket);
    RUN(&t, test_failed_buffer);
    RUN(&t, test_format_pinned);
    return mts_test_end(&t);
}
