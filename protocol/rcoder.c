#include "rcoder.h"

#include <math.h>

/* Significant bits of v: 0 for 0, else 1 + the index of the leading 1. */
static unsigned bit_length(uint32_t v)
{
#if defined(__GNUC__) || defined(__clang__)
    return v ? 32u - (unsigned)__builtin_clz(v) : 0u;
#else
    unsigned n = 0;
    while (v) {
        n++;
        v >>= 1;
    }
    return n;
#endif
}

/* mts_buf_u8 without the call while there is room: the encoder writes a
 * byte at a time. Once the buffer has failed every write goes the slow way,
 * which drops it. */
static void put_byte(mts_buf *b, uint8_t x)
{
    if (!b->failed && b->size < b->cap)
        b->data[b->size++] = x;
    else
        mts_buf_u8(b, x);
}

void mts_rc_encoder_init(mts_rc_encoder *e, mts_buf *out)
{
    e->low = 0;
    e->range = UINT32_MAX;
    e->cache = 0;
    /* LZMA starts with cache_size 1: a first byte that is always 0, since
     * low + range never exceeds 2^32 and so no carry can reach it. This
     * coder does not write that byte: it starts with no cache at all. */
    e->cache_size = 0;
    e->out = out;
    e->cost = NULL;
}

void mts_rc_encoder_account(mts_rc_encoder *e, uint32_t prob, unsigned bit)
{
    uint32_t p = bit ? MTS_RC_PROB_ONE - prob : prob;
    *e->cost -= log2((double)p / MTS_RC_PROB_ONE);
}

/* Moves low's top byte (bits 24..31) out. It cannot be written yet when it
 * is 0xFF and there was no carry: a later carry would turn it into 0x00 and
 * add one to the byte before. So it joins a run of pending 0xFF bytes behind
 * the cached byte, and the run is written, carry added, once a byte arrives
 * that can absorb any later carry (below 0xFF) or a carry arrives. */
void mts_rc_encoder_shift_low(mts_rc_encoder *e)
{
    if ((uint32_t)e->low < 0xFF000000u || (e->low >> 32) != 0) {
        uint8_t carry = (uint8_t)(e->low >> 32);
        /* With no cache yet (only at the start) there is nothing before this
         * byte, and no carry: see encoder_init. */
        if (e->cache_size) {
            put_byte(e->out, (uint8_t)(e->cache + carry));
            for (; e->cache_size > 1; e->cache_size--)
                put_byte(e->out, (uint8_t)(0xFF + carry));
        }
        e->cache = (uint8_t)(e->low >> 24);
        e->cache_size = 1;
    } else if (e->cache_size++ == 0) {
        /* a 0xFF first byte becomes the cache; no carry can reach it */
        e->cache = 0xFF;
    }
    e->low = (e->low & 0x00FFFFFFu) << 8;
}

/* LZMA writes all four bytes of low (and the pending ones) here. Any value
 * in [low, low + range) identifies the stream, and as range >= 2^24 that
 * interval holds a multiple of 2^24: ending on it leaves three zero bytes,
 * which the decoder supplies itself (MTS_RC_TAIL_BYTES). The first shift
 * moves its top byte into the cache, the second writes it (low is then 0). */
void mts_rc_encoder_flush(mts_rc_encoder *e)
{
    e->low = (e->low + (MTS_RC_TOP - 1)) & ~(uint64_t)(MTS_RC_TOP - 1);
    mts_rc_encoder_shift_low(e);
    mts_rc_encoder_shift_low(e);
}

void mts_rc_encode_direct(mts_rc_encoder *e, uint32_t value, unsigned nbits)
{
    if (nbits > 32)
        nbits = 32;
    if (e->cost)
        *e->cost += nbits;
    while (nbits--) {
        e->range >>= 1;
        e->low += e->range & (0u - ((value >> nbits) & 1u));
        if (e->range < MTS_RC_TOP) {
            e->range <<= 8;
            mts_rc_encoder_shift_low(e);
        }
    }
}

int mts_rc_decoder_init(mts_rc_decoder *d, const uint8_t *data, size_t size)
{
    d->p = data;
    d->end = data ? data + size : data;
    d->range = UINT32_MAX;
    d->code = 0;
    d->past_end = 0;
    d->ok = 1;
    for (int i = 0; i < 4; i++)
        d->code = (d->code << 8) | (d->p < d->end ? *d->p++ : mts_rc_decoder_past_end(d));
    /* every stream has at least one byte; and code < range always */
    if (d->p == data || d->code >= d->range)
        d->ok = 0;
    return d->ok;
}

uint8_t mts_rc_decoder_past_end(mts_rc_decoder *d)
{
    if (d->past_end < UINT32_MAX)
        d->past_end++;
    if (d->past_end > MTS_RC_TAIL_BYTES)
        d->ok = 0;
    return 0;
}

int mts_rc_decoder_finished(const mts_rc_decoder *d)
{
    return d->ok && d->p == d->end && d->past_end == MTS_RC_TAIL_BYTES;
}

/* The decoders below keep the coder's state in locals while they work (a
 * value is a dozen decisions, and through d the compiler would reload and
 * store range and code at each, as other stores may alias d) and put it
 * back at the end; rc_bit is mts_rc_decode_bit on that state. */
typedef struct rc_state {
    uint32_t range, code;
    const uint8_t *p;
} rc_state;

static inline rc_state rc_load(const mts_rc_decoder *d)
{
    rc_state r = {d->range, d->code, d->p};
    return r;
}

static inline void rc_store(mts_rc_decoder *d, rc_state r)
{
    d->range = r.range;
    d->code = r.code;
    d->p = r.p;
}

static inline void rc_norm(mts_rc_decoder *d, rc_state *r)
{
    if (r->range < MTS_RC_TOP) {
        r->range <<= 8;
        r->code = (r->code << 8) | (r->p < d->end ? *r->p++ : mts_rc_decoder_past_end(d));
    }
}

static inline unsigned rc_bit(mts_rc_decoder *d, rc_state *r, uint16_t *prob)
{
    uint32_t p = *prob, bound = (r->range >> MTS_RC_PROB_BITS) * p;
    unsigned bit = r->code >= bound;
    if (!bit) {
        r->range = bound;
        *prob = (uint16_t)(p + ((MTS_RC_PROB_ONE - p) >> MTS_RC_ADAPT_SHIFT));
    } else {
        r->code -= bound;
        r->range -= bound;
        *prob = (uint16_t)(p - (p >> MTS_RC_ADAPT_SHIFT));
    }
    rc_norm(d, r);
    return bit;
}

static inline uint32_t rc_direct(mts_rc_decoder *d, rc_state *r, unsigned nbits)
{
    uint32_t v = 0, bad = 0;
    while (nbits--) {
        r->range >>= 1;
        uint32_t bit = r->code >= r->range;
        r->code -= r->range & (0u - bit);
        /* halving an odd range drops its last value, which no encoder
         * reaches: code landing there means the input is not a stream */
        bad |= r->code >= r->range;
        v = (v << 1) | bit;
        rc_norm(d, r);
    }
    if (bad)
        d->ok = 0;
    return v;
}

uint32_t mts_rc_decode_direct(mts_rc_decoder *d, unsigned nbits)
{
    rc_state r = rc_load(d);
    uint32_t v = rc_direct(d, &r, nbits > 32 ? 32 : nbits);
    rc_store(d, r);
    return v;
}

void mts_rc_uint_model_init(mts_rc_uint_model *m)
{
    mts_rc_prob_init(m->bucket, sizeof m->bucket / sizeof m->bucket[0]);
    mts_rc_prob_init(&m->mantissa[0][0], sizeof m->mantissa / sizeof m->mantissa[0][0]);
}

void mts_rc_encode_uint(mts_rc_encoder *e, mts_rc_uint_model *m, uint32_t v)
{
    unsigned b = bit_length(v);
    unsigned node = 1;
    for (int i = MTS_RC_BUCKET_BITS - 1; i >= 0; i--) {
        unsigned bit = (b >> i) & 1u;
        mts_rc_encode_bit(e, &m->bucket[node], bit);
        node = 2 * node + bit;
    }
    if (b < 2)
        return; /* 0 and 1 are their bucket */
    unsigned below = b - 1; /* bits under the leading 1 */
    unsigned modelled = below < MTS_RC_CONTEXT_BITS ? below : MTS_RC_CONTEXT_BITS;
    uint16_t *probs = m->mantissa[b];
    node = 1;
    for (unsigned i = 1; i <= modelled; i++) {
        unsigned bit = (v >> (below - i)) & 1u;
        mts_rc_encode_bit(e, &probs[node], bit);
        node = 2 * node + bit;
    }
    mts_rc_encode_direct(e, v, below - modelled);
}

uint32_t mts_rc_decode_uint(mts_rc_decoder *d, mts_rc_uint_model *m)
{
    rc_state r = rc_load(d);
    unsigned node = 1;
    for (int i = 0; i < MTS_RC_BUCKET_BITS; i++)
        node = 2 * node + rc_bit(d, &r, &m->bucket[node]);
    unsigned b = node - (1u << MTS_RC_BUCKET_BITS);
    uint32_t v = b;
    if (b >= MTS_RC_BUCKETS) {
        d->ok = 0;
        v = 0;
    } else if (b >= 2) {
        unsigned below = b - 1;
        unsigned modelled = below < MTS_RC_CONTEXT_BITS ? below : MTS_RC_CONTEXT_BITS;
        uint16_t *probs = m->mantissa[b];
        node = 1;
        for (unsigned i = 0; i < modelled; i++)
            node = 2 * node + rc_bit(d, &r, &probs[node]);
        uint32_t top = node - (1u << modelled);
        unsigned rest = below - modelled;
        v = (1u << below) | (top << rest) | rc_direct(d, &r, rest);
    }
    rc_store(d, r);
    return v;
}

void mts_rc_encode_sint(mts_rc_encoder *e, mts_rc_uint_model *m, int32_t v)
{
    mts_rc_encode_uint(e, m, mts_zigzag(v));
}

int32_t mts_rc_decode_sint(mts_rc_decoder *d, mts_rc_uint_model *m)
{
    return mts_unzigzag(mts_rc_decode_uint(d, m));
}

void mts_rc_tree_model_init(mts_rc_tree_model *m, unsigned nbits)
{
    mts_rc_prob_init(m->probs, sizeof m->probs / sizeof m->probs[0]);
    m->nbits = nbits < MTS_RC_TREE_MAX_BITS ? nbits : MTS_RC_TREE_MAX_BITS;
}

/* nbits as init left it, re-clamped: the tree's size is what keeps the
 * node indices inside probs. */
static unsigned tree_bits(const mts_rc_tree_model *m)
{
    return m->nbits < MTS_RC_TREE_MAX_BITS ? m->nbits : MTS_RC_TREE_MAX_BITS;
}

void mts_rc_encode_tree(mts_rc_encoder *e, mts_rc_tree_model *m, unsigned symbol)
{
    unsigned n = tree_bits(m), node = 1;
    while (n--) {
        unsigned bit = (symbol >> n) & 1u;
        mts_rc_encode_bit(e, &m->probs[node], bit);
        node = 2 * node + bit;
    }
}

unsigned mts_rc_decode_tree(mts_rc_decoder *d, mts_rc_tree_model *m)
{
    rc_state r = rc_load(d);
    unsigned n = tree_bits(m), node = 1;
    for (unsigned i = 0; i < n; i++)
        node = 2 * node + rc_bit(d, &r, &m->probs[node]);
    rc_store(d, r);
    return node - (1u << n);
}
