#include "reccodec.h"

#include "varint.h"

size_t mts_reccodec_bound(const mts_model *m, uint32_t first, uint32_t count)
{
    size_t words = m->record_offsets[first + count] - m->record_offsets[first];
    return (words + count) * MTS_VARINT32_MAX_BYTES;
}

mts_result mts_reccodec_encode(const mts_model *m, uint32_t first, uint32_t count, uint8_t *out,
                               size_t capacity, size_t *written, mts_error *err)
{
    if (first > m->level_count || count > m->level_count - first)
        return mts_error_set(err, MTS_ERR_ARG, "reccodec: splits %u..%u of %u", first,
                             first + count, m->level_count);
    if (capacity < mts_reccodec_bound(m, first, count))
        return mts_error_set(err, MTS_ERR_ARG, "reccodec: output buffer too small");
    uint8_t *o = out;
    for (uint32_t j = first; j < first + count; j++) {
        const uint32_t v = m->base_vertex_count + j, parent = m->parents[j];
        const uint32_t *p = m->record_data + m->record_offsets[j];
        o += mts_varint_put(o, v - 1 - parent);
        uint32_t edits = *p++;
        o += mts_varint_put(o, edits);
        uint32_t prev_strip = 0;
        for (uint32_t e = 0; e < edits; e++) {
            uint32_t strip = p[0], erases = p[1], inserts = p[2], substs = p[3];
            p += 4;
            o += mts_varint_put(o, mts_zigzag_u32(strip - prev_strip));
            prev_strip = strip;
            o += mts_varint_put(o, erases);
            o += mts_varint_put(o, inserts);
            o += mts_varint_put(o, substs);
            /* erase runs, then insert runs: the same shape */
            for (uint32_t k = 0; k < erases + inserts; k++) {
                uint32_t run = p[1];
                o += mts_varint_put(o, p[0]);
                o += mts_varint_put(o, run);
                p += 2;
                for (uint32_t r = 0; r < run; r++)
                    o += mts_varint_put(o, mts_zigzag_u32(*p++ - parent));
            }
            uint32_t prev_pos = 0;
            for (uint32_t k = 0; k < substs; k++) {
                o += mts_varint_put(o, mts_zigzag_u32(*p - prev_pos));
                prev_pos = *p++;
            }
        }
    }
    *written = (size_t)(o - out);
    return MTS_OK;
}

#define GET(x)                                                                            \
    do {                                                                                  \
        if (!mts_varint_get(&p, end, &(x)))                                               \
            return mts_error_set(err, MTS_ERR_FORMAT,                                     \
                                 "split %u: record ends early or holds a bad number "     \
                                 "(byte %zu of %zu)",                                     \
                                 j, (size_t)(p - in), size);                              \
    } while (0)

#define PUT(x)                                                                            \
    do {                                                                                  \
        if (w >= out->word_capacity)                                                      \
            return mts_error_set(err, MTS_ERR_LIMIT, "split %u: more record words than "  \
                                 "the %zu expected", j, out->word_capacity);              \
        out->words[w++] = (x);                                                            \
    } while (0)

mts_result mts_reccodec_decode(const uint8_t *in, size_t size, uint32_t nb, uint32_t first,
                               uint32_t count, const mts_reccodec_out *out, size_t *consumed,
                               size_t *word_count, mts_error *err)
{
    const uint8_t *p = in, *end = in + size;
    size_t w = 0;
    for (uint32_t k = 0; k < count; k++) {
        const uint32_t j = first + k;
        const uint32_t v = nb + j;
        if ((uint64_t)out->word_base + w > UINT32_MAX)
            return mts_error_set(err, MTS_ERR_LIMIT, "split %u: records exceed 2^32 words", j);
        out->offsets[k] = out->word_base + (uint32_t)w;
        uint32_t back, edits;
        GET(back);
        if (back >= v)
            return mts_error_set(err, MTS_ERR_RANGE,
                                 "split %u: parent %u steps before vertex 0", j, back);
        const uint32_t parent = v - 1 - back;
        out->parents[k] = parent;
        GET(edits);
        PUT(edits);
        uint32_t strip = 0;
        for (uint32_t e = 0; e < edits; e++) {
            uint32_t ds, erases, inserts, substs;
            GET(ds);
            GET(erases);
            GET(inserts);
            GET(substs);
            strip += mts_unzigzag_u32(ds);
            PUT(strip);
            PUT(erases);
            PUT(inserts);
            PUT(substs);
            /* erase runs, then insert runs; 64-bit so a hostile pair of
             * counts cannot wrap (the input ends long before either) */
            for (uint64_t i = 0; i < (uint64_t)erases + inserts; i++) {
                uint32_t pos, run;
                GET(pos);
                GET(run);
                PUT(pos);
                PUT(run);
                for (uint32_t r = 0; r < run; r++) {
                    uint32_t d;
                    GET(d);
                    PUT(parent + mts_unzigzag_u32(d));
                }
            }
            uint32_t pos = 0;
            for (uint32_t i = 0; i < substs; i++) {
                uint32_t d;
                GET(d);
                pos += mts_unzigzag_u32(d);
                PUT(pos);
            }
        }
    }
    out->offsets[count] = out->word_base + (uint32_t)w;
    *consumed = (size_t)(p - in);
    *word_count = w;
    return MTS_OK;
}
