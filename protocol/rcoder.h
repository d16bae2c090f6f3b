/* An adaptive binary range coder and the integer models the stream codes its
 * per-split fields with (vertex-id deltas, small codes, quantized position
 * residuals: mostly small, roughly geometric or Laplacian).
 *
 * What it is: the range coder of LZMA (Igor Pavlov's, after G. N. N. Martin,
 * "Range encoding: an algorithm for removing redundancy from a digitised
 * message", 1979): a 32-bit range, a 64-bit low with carry propagation
 * through a cached byte and a run of pending 0xFF bytes, and 11-bit
 * probabilities that each coded bit nudges towards itself. Every value is
 * coded as a sequence of such binary decisions (a bit-tree for a small
 * symbol, bucket + mantissa for an integer), each with its own probability.
 *
 * Why adaptive binary models: each BATCH is its own coded stream (a client
 * applies a batch only once it is whole), too short to pay for frequency
 * tables on the wire. Binary models need no tables: they start flat and
 * learn from what they code, the decoder mirroring the encoder step by step
 * (the stream keeps them from batch to batch, stream_coding.h). They adapt faster
 * than LZMA's (MTS_RC_ADAPT_SHIFT 4, not 5): on geometric integers that
 * costs 5.5% over the entropy after 1000 symbols where 5 costs 6.7%, and
 * wins more on fewer (33% against 50% after 50). On whole streams the two
 * are within 0.5% (bunny00 209,005 bytes with 4, 208,719 with 5; cow
 * 17,199 and 17,287).
 *
 * Determinism: integers only -- no floating point, no platform-dependent
 * widths -- so an encoder and a decoder on any platform agree bit for bit.
 *
 * Ends, exactly: unlike LZMA the encoder writes neither LZMA's leading zero
 * byte (it carries no information) nor the whole of `low` at the end; it
 * ends on a value whose last MTS_RC_TAIL_BYTES bytes are zero and leaves
 * those out. A decoder reads four bytes ahead and is fed zeros past the end
 * of its input, so after decoding what was encoded it has used every byte
 * of the input and exactly MTS_RC_TAIL_BYTES zeros beyond it:
 * mts_rc_decoder_finished() checks that, which catches truncated input and
 * trailing bytes alike. Needing any more than that means the input was
 * truncated (or is not a stream): `ok` drops to 0 and stays there, and the
 * decoder goes on returning values without reading anything -- a caller
 * decodes a whole message and checks once. Decoding never reads outside its
 * input, and every call does a bounded amount of work on any input.
 *
 * An empty stream (init, flush) is one byte. The coder itself costs about
 * one byte a stream over the information coded. */
#ifndef MTS_RCODER_H
#define MTS_RCODER_H

#include <stddef.h>
#include <stdint.h>

#include "bytes.h"

#define MTS_RC_PROB_BITS 11
#define MTS_RC_PROB_ONE (1u << MTS_RC_PROB_BITS)
#define MTS_RC_PROB_INIT (MTS_RC_PROB_ONE / 2) /* flat: p(0) = 1/2 */
/* Each coded bit moves its probability 1/16 of the way towards itself. With
 * 11-bit probabilities that keeps every probability in [15, 2033]: never 0,
 * so any bit stays codable, and at most about 0.01 bit for a certain one. */
#define MTS_RC_ADAPT_SHIFT 4
/* The coder keeps range >= 2^24 between calls, so one decision shrinks it by
 * at most 2^8 and one byte shifted in restores it. */
#define MTS_RC_TOP (1u << 24)
/* Zero bytes a finished stream leaves for the decoder to supply. */
#define MTS_RC_TAIL_BYTES 3u
/* Mantissa bits under an integer's leading 1 that are modelled (per bucket);
 * the rest are coded as they are, nearly uniform in practice. */
#define MTS_RC_CONTEXT_BITS 2
/* Buckets of a uint model: 0 for the value 0, else the number of
 * significant bits (1..32), coded by a 6-bit bit-tree. */
#define MTS_RC_BUCKETS 33
#define MTS_RC_BUCKET_BITS 6
#define MTS_RC_TREE_MAX_BITS 8

typedef struct mts_rc_encoder {
    uint64_t low;        /* bit 32 is a carry into the bytes not yet written */
    uint32_t range;
    uint8_t cache;       /* the last byte shifted out, still open to a carry */
    uint64_t cache_size; /* bytes held back: the cache and cache_size - 1
                            0xFF after it (0 at the start: none yet) */
    mts_buf *out;
    /* when not NULL, the information each coded bit carries (-log2 of its
     * probability, in bits) is added here: where a stream's bytes go
     * (stream_enc.c's breakdown), without changing a byte of it */
    double *cost;
} mts_rc_encoder;

typedef struct mts_rc_decoder {
    const uint8_t *p, *end;
    uint32_t range, code; /* code: the input's value less low, < range */
    uint32_t past_end;    /* zero bytes fed past the end (saturating) */
    int ok;               /* 0 once the input proved truncated or malformed */
} mts_rc_decoder;

/* Appends the stream to out (out->failed is set, sticky, when memory runs
 * out). Nothing is written before the flush; after it the encoder is spent,
 * and init starts another stream. */
void mts_rc_encoder_init(mts_rc_encoder *e, mts_buf *out);
void mts_rc_encoder_flush(mts_rc_encoder *e);
/* Moves low's top byte out; encode_bit's slow path. */
void mts_rc_encoder_shift_low(mts_rc_encoder *e);
/* Adds a bit's information to *e->cost; encode_bit's accounting path. */
void mts_rc_encoder_account(mts_rc_encoder *e, uint32_t prob, unsigned bit);

/* Returns 0 (and ok = 0) when the input is empty or cannot start a stream. */
int mts_rc_decoder_init(mts_rc_decoder *d, const uint8_t *data, size_t size);
/* 1 when the decoder has used exactly the bytes of a stream, no more, no
 * fewer: call it after decoding everything the message holds. */
int mts_rc_decoder_finished(const mts_rc_decoder *d);
/* The next byte once the input is used up: 0, counted. decode_bit's slow
 * path. */
uint8_t mts_rc_decoder_past_end(mts_rc_decoder *d);

static inline void mts_rc_prob_init(uint16_t *probs, size_t count)
{
    for (size_t i = 0; i < count; i++)
        probs[i] = MTS_RC_PROB_INIT;
}

/* One bit with probability *prob (of a 0, in 1/2048ths), which it then
 * adapts. Hot: inline. */
static inline void mts_rc_encode_bit(mts_rc_encoder *e, uint16_t *prob, unsigned bit)
{
    uint32_t p = *prob;
    uint32_t bound = (e->range >> MTS_RC_PROB_BITS) * p;
    if (e->cost)
        mts_rc_encoder_account(e, p, bit);
    if (!bit) {
        e->range = bound;
        *prob = (uint16_t)(p + ((MTS_RC_PROB_ONE - p) >> MTS_RC_ADAPT_SHIFT));
    } else {
        e->low += bound;
        e->range -= bound;
        *prob = (uint16_t)(p - (p >> MTS_RC_ADAPT_SHIFT));
    }
    if (e->range < MTS_RC_TOP) {
        e->range <<= 8;
        mts_rc_encoder_shift_low(e);
    }
}

static inline void mts_rc_decoder_normalize(mts_rc_decoder *d)
{
    if (d->range < MTS_RC_TOP) {
        d->range <<= 8;
        d->code = (d->code << 8) | (d->p < d->end ? *d->p++ : mts_rc_decoder_past_end(d));
    }
}

static inline unsigned mts_rc_decode_bit(mts_rc_decoder *d, uint16_t *prob)
{
    uint32_t p = *prob;
    uint32_t bound = (d->range >> MTS_RC_PROB_BITS) * p;
    unsigned bit;
    if (d->code < bound) {
        d->range = bound;
        *prob = (uint16_t)(p + ((MTS_RC_PROB_ONE - p) >> MTS_RC_ADAPT_SHIFT));
        bit = 0;
    } else {
        d->code -= bound;
        d->range -= bound;
        *prob = (uint16_t)(p - (p >> MTS_RC_ADAPT_SHIFT));
        bit = 1;
    }
    mts_rc_decoder_normalize(d);
    return bit;
}

/* The low nbits (0..32) of value, high bit first, each with probability 1/2
 * and no model: for bits nothing predicts. */
void mts_rc_encode_direct(mts_rc_encoder *e, uint32_t value, unsigned nbits);
uint32_t mts_rc_decode_direct(mts_rc_decoder *d, unsigned nbits);

/* Unsigned 32-bit integers, small ones cheap: the bucket (significant bits,
 * 0..32) by a bit-tree, then the bits under the leading 1 -- the top
 * MTS_RC_CONTEXT_BITS modelled per bucket (they carry the slope of a
 * geometric distribution within its bucket), the rest direct. A value of b
 * significant bits costs its bucket plus b - 1 bits. */
typedef struct mts_rc_uint_model {
    uint16_t bucket[1 << MTS_RC_BUCKET_BITS]; /* bit-tree, node 1 the root */
    uint16_t mantissa[MTS_RC_BUCKETS][1 << MTS_RC_CONTEXT_BITS];
} mts_rc_uint_model;

void mts_rc_uint_model_init(mts_rc_uint_model *m);
void mts_rc_encode_uint(mts_rc_encoder *e, mts_rc_uint_model *m, uint32_t v);
/* A bucket the encoder cannot write (33..63) sets ok = 0 and gives 0. */
uint32_t mts_rc_decode_uint(mts_rc_decoder *d, mts_rc_uint_model *m);

/* Signed values through zigzag (0, -1, 1, -2 -> 0, 1, 2, 3), so small
 * magnitudes of either sign are cheap. */
void mts_rc_encode_sint(mts_rc_encoder *e, mts_rc_uint_model *m, int32_t v);
int32_t mts_rc_decode_sint(mts_rc_decoder *d, mts_rc_uint_model *m);

/* Symbols in [0, 2^nbits), nbits 0..8, by a bit-tree: each symbol's bits
 * high first, each bit's probability chosen by the bits above it, so the
 * model learns any distribution over the 2^nbits symbols. */
typedef struct mts_rc_tree_model {
    uint16_t probs[1 << MTS_RC_TREE_MAX_BITS]; /* node 1 the root */
    unsigned nbits;
} mts_rc_tree_model;

/* nbits above MTS_RC_TREE_MAX_BITS is taken as MTS_RC_TREE_MAX_BITS. */
void mts_rc_tree_model_init(mts_rc_tree_model *m, unsigned nbits);
/* Codes the low nbits of symbol. */
void mts_rc_encode_tree(mts_rc_encoder *e, mts_rc_tree_model *m, unsigned symbol);
unsigned mts_rc_decode_tree(mts_rc_decoder *d, mts_rc_tree_model *m);

#endif
