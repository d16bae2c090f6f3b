/* Compact encoding of splits (a parent and a record each, see model.h) for
 * the model file and the wire. Every value is a LEB128 varint; values that
 * sit near another are stored as zigzag deltas:
 *
 *   split j (its vertex v = nb + j):
 *     v - 1 - parent
 *     edit_count
 *     per edit: zigzag(strip - previous edit's strip), erase_count,
 *               insert_count, subst_count,
 *               per erase:  position, length, zigzag(index - parent) per index
 *               per insert: position, length, zigzag(index - parent) per index
 *               per position: zigzag(position - previous position)
 *
 * Runs, erased or inserted, are mostly the parent and its neighbours (the
 * triangles around the split edge), strips in a record are near each other
 * and substituted positions ascend, so most values take one byte: about 2.5x
 * smaller than 32-bit words. Every record word is one varint, and a split
 * adds one (its parent), so a split's words never outnumber its bytes.
 * Decoding checks only what it must to stay in bounds (the end of the input,
 * the room for words); the records' meaning is checked where they are applied
 * (mts_lod_split). */
#ifndef MTS_RECCODEC_H
#define MTS_RECCODEC_H

#include <stddef.h>
#include <stdint.h>

#include "error.h"
#include "model.h"

/* Bytes enough to encode splits [first, first + count) of the model. */
size_t mts_reccodec_bound(const mts_model *model, uint32_t first, uint32_t count);

mts_result mts_reccodec_encode(const mts_model *model, uint32_t first, uint32_t count,
                               uint8_t *out, size_t capacity, size_t *written, mts_error *err);

/* Where decoded splits go: parents[k] and the record words of split
 * first + k; offsets[k] is where its words start, counted from word_base
 * (offsets[count] is the end). At most word_capacity words are written; a
 * split's words never outnumber its bytes, so size words always suffice. */
typedef struct mts_reccodec_out {
    uint32_t *parents;  /* count entries */
    uint32_t *offsets;  /* count + 1 entries */
    uint32_t *words;
    size_t word_capacity;
    uint32_t word_base;
} mts_reccodec_out;

/* Decodes exactly count splits from in[0..size); *consumed gets the bytes
 * read and *word_count the words written. */
mts_result mts_reccodec_decode(const uint8_t *in, size_t size, uint32_t base_vertex_count,
                               uint32_t first, uint32_t count, const mts_reccodec_out *out,
                               size_t *consumed, size_t *word_count, mts_error *err);

#endif
