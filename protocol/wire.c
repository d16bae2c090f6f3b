#include "wire.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "utf8.h"

mts_result mts_wire_check_name(const char *name, size_t len, mts_error *err)
{
    if (!name || len == 0)
        return mts_error_set(err, MTS_ERR_ARG, "a model name cannot be empty");
    if (len > MTS_WIRE_MAX_NAME)
        return mts_error_set(err, MTS_ERR_ARG,
                             "model name \"%.64s...\" is too long (%zu characters, at most %d)",
                             name, len, MTS_WIRE_MAX_NAME);
    if (name[0] == '.')
        return mts_error_set(err, MTS_ERR_ARG,
                             "model name \"%.*s\" starts with '.' (not allowed)", (int)len, name);
    for (size_t i = 0; i < len; i++) {
        unsigned char c = (unsigned char)name[i];
        int ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                 c == '.' || c == '_' || c == '-';
        if (ok)
            continue;
        char shown[16];
        if (c >= 0x20 && c < 0x7f)
            snprintf(shown, sizeof shown, "'%c'", c);
        else
            snprintf(shown, sizeof shown, "byte 0x%02x", c);
        /* the name as shown: printable ASCII only */
        char printable[MTS_WIRE_MAX_NAME + 1];
        for (size_t k = 0; k < len; k++) {
            unsigned char b = (unsigned char)name[k];
            printable[k] = b >= 0x20 && b < 0x7f ? (char)b : '?';
        }
        printable[len] = 0;
        return mts_error_set(err, MTS_ERR_ARG,
                             "model name \"%s\" has %s at position %zu (allowed: A-Z a-z 0-9 . _ -)",
                             printable, shown, i + 1);
    }
    return MTS_OK;
}

int mts_wire_valid_name(const char *name, size_t len)
{
    return mts_wire_check_name(name, len, NULL) == MTS_OK;
}

size_t mts_wire_frame_begin(mts_buf *b, uint8_t type)
{
    size_t at = b->size;
    mts_buf_u32(b, 0);
    mts_buf_u8(b, type);
    return at;
}

void mts_wire_frame_end(mts_buf *b, size_t at)
{
    mts_buf_patch_u32(b, at, (uint32_t)(b->size - at - 4));
}

void mts_wire_put_hello(mts_buf *b, const mts_wire_hello *h)
{
    size_t f = mts_wire_frame_begin(b, MTS_MSG_HELLO);
    mts_buf_put(b, "MTSH", 4);
    mts_buf_u16(b, h->major);
    mts_buf_u16(b, h->minor);
    mts_buf_string(b, h->model, strnlen(h->model, MTS_WIRE_MAX_NAME));
    mts_buf_u8(b, h->stop_kind);
    mts_buf_varint(b, h->stop_value);
    mts_buf_varint(b, h->resume_batch);
    mts_buf_u64(b, h->stream_id);
    mts_buf_varint(b, h->flags);
    mts_wire_frame_end(b, f);
}

void mts_wire_put_list(mts_buf *b)
{
    mts_wire_frame_end(b, mts_wire_frame_begin(b, MTS_MSG_LIST));
}

void mts_wire_put_model_info_head(mts_buf *b, const mts_wire_model_info *mi, size_t tail_size)
{
    size_t f = mts_wire_frame_begin(b, MTS_MSG_MODEL_INFO);
    mts_buf_u16(b, mi->minor);
    mts_buf_u64(b, mi->stream_id);
    mts_buf_string(b, mi->model, strnlen(mi->model, MTS_WIRE_MAX_NAME));
    const uint32_t counts[] = {mi->vertices, mi->base_vertices, mi->levels, mi->triangles,
                               mi->strips, mi->stop_level, mi->stop_triangles};
    for (size_t i = 0; i < sizeof counts / sizeof counts[0]; i++)
        mts_buf_varint(b, counts[i]);
    mts_buf_patch_u32(b, f, (uint32_t)(b->size - f - 4 + tail_size));
}

void mts_wire_put_model_info_tail(mts_buf *b, const mts_wire_model_info *mi)
{
    for (int a = 0; a < 3; a++)
        mts_buf_f32(b, mi->bbox_min[a]);
    for (int a = 0; a < 3; a++)
        mts_buf_f32(b, mi->bbox_max[a]);
    mts_buf_u8(b, mi->quant_bits);
    mts_buf_u8(b, mi->flags);
    for (int a = 0; a < 3; a++)
        mts_buf_f32(b, mi->grid_origin[a]);
    mts_buf_f32(b, mi->grid_range);
    mts_buf_varint(b, mi->batch_count);
    mts_buf_varint(b, mi->batch_size);
    mts_buf_varint(b, mi->capacity_total);
    mts_buf_varint(b, mi->key_count);
    uint32_t prev = 0;
    for (uint32_t k = 0; k < mi->key_count; k++) {
        mts_buf_varint(b, mi->key_levels[k] - prev);
        prev = mi->key_levels[k];
    }
}

void mts_wire_put_model_info(mts_buf *b, const mts_wire_model_info *mi)
{
    size_t f = b->size;
    mts_wire_put_model_info_head(b, mi, 0);
    mts_wire_put_model_info_tail(b, mi);
    mts_wire_frame_end(b, f);
}

void mts_wire_put_end(mts_buf *b, const mts_wire_end *e)
{
    size_t f = mts_wire_frame_begin(b, MTS_MSG_END);
    mts_buf_varint(b, e->final_level);
    mts_buf_u64(b, e->checksum);
    mts_buf_varint(b, e->stream_bytes);
    mts_wire_frame_end(b, f);
}

void mts_wire_put_models(mts_buf *b, const mts_wire_model_entry *models, uint32_t count)
{
    size_t f = mts_wire_frame_begin(b, MTS_MSG_MODELS);
    mts_buf_varint(b, count);
    for (uint32_t i = 0; i < count; i++) {
        const mts_wire_model_entry *m = &models[i];
        mts_buf_string(b, m->name, strnlen(m->name, MTS_WIRE_MAX_NAME));
        mts_buf_varint(b, m->vertices);
        mts_buf_varint(b, m->triangles);
        mts_buf_varint(b, m->levels);
        mts_buf_varint(b, m->stream_bytes);
    }
    mts_wire_frame_end(b, f);
}

void mts_wire_put_error(mts_buf *b, uint16_t code, const char *text)
{
    size_t f = mts_wire_frame_begin(b, MTS_MSG_ERROR);
    mts_buf_u16(b, code);
    size_t len = strlen(text);
    mts_buf_string(b, text, len > 1024 ? 1024 : len);
    mts_wire_frame_end(b, f);
}

static mts_result parse_name(mts_cursor *c, char *out, const char *what, mts_error *err)
{
    size_t len = 0;
    const char *name = mts_cursor_string(c, MTS_WIRE_MAX_NAME, &len);
    if (!name)
        return mts_error_set(err, MTS_ERR_FORMAT, "%s: model name missing or over %d bytes",
                             what, MTS_WIRE_MAX_NAME);
    if (!mts_wire_valid_name(name, len))
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "%s: model name is not 1..%d characters of [A-Za-z0-9._-]", what,
                             MTS_WIRE_MAX_NAME);
    memcpy(out, name, len);
    out[len] = 0;
    return MTS_OK;
}

mts_result mts_wire_parse_hello(const uint8_t *payload, size_t size, mts_wire_hello *h,
                                mts_error *err)
{
    memset(h, 0, sizeof *h);
    mts_cursor c = mts_cursor_make(payload, size);
    const uint8_t *magic = mts_cursor_bytes(&c, 4);
    if (!magic || memcmp(magic, "MTSH", 4) != 0)
        return mts_error_set(err, MTS_ERR_FORMAT, "HELLO: bad magic (not an mtstream client)");
    h->major = mts_cursor_u16(&c);
    h->minor = mts_cursor_u16(&c);
    if (!c.ok)
        return mts_error_set(err, MTS_ERR_FORMAT, "HELLO: truncated before the version");
    if (h->major != MTS_WIRE_MAJOR)
        return mts_error_set(err, MTS_ERR_VERSION,
                             "HELLO: protocol version %u.%u; this server speaks %u.x%s", h->major,
                             h->minor, MTS_WIRE_MAJOR,
                             h->major < MTS_WIRE_MAJOR
                                 ? " (an older client: update it)"
                                 : "");
    mts_result rc = parse_name(&c, h->model, "HELLO", err);
    if (rc != MTS_OK)
        return rc;
    h->stop_kind = mts_cursor_u8(&c);
    h->stop_value = mts_cursor_varint(&c);
    h->resume_batch = mts_cursor_varint(&c);
    h->stream_id = mts_cursor_u64(&c);
    h->flags = mts_cursor_varint(&c);
    if (!c.ok)
        return mts_error_set(err, MTS_ERR_FORMAT, "HELLO: truncated (%zu bytes)", size);
    if (h->stop_kind > MTS_STOP_FRACTION)
        return mts_error_set(err, MTS_ERR_FORMAT, "HELLO: unknown stop kind %u", h->stop_kind);
    if (h->stop_kind == MTS_STOP_FRACTION && h->stop_value > 1000000)
        return mts_error_set(err, MTS_ERR_FORMAT, "HELLO: fraction %u is over 1,000,000 millionths",
                             h->stop_value);
    if (mts_cursor_left(&c) != 0)
        return mts_error_set(err, MTS_ERR_FORMAT, "HELLO: %zu bytes after the message",
                             mts_cursor_left(&c));
    return MTS_OK;
}

void mts_wire_model_info_free(mts_wire_model_info *mi)
{
    free(mi->key_levels);
    mi->key_levels = NULL;
}

mts_result mts_wire_parse_model_info(const uint8_t *payload, size_t size,
                                     mts_wire_model_info *mi, mts_error *err)
{
    memset(mi, 0, sizeof *mi);
    mts_cursor c = mts_cursor_make(payload, size);
    mi->minor = mts_cursor_u16(&c);
    mi->stream_id = mts_cursor_u64(&c);
    mts_result rc = parse_name(&c, mi->model, "MODEL_INFO", err);
    if (rc != MTS_OK)
        return rc;
    uint32_t *counts[] = {&mi->vertices, &mi->base_vertices, &mi->levels, &mi->triangles,
                          &mi->strips, &mi->stop_level, &mi->stop_triangles};
    for (size_t i = 0; i < sizeof counts / sizeof counts[0]; i++)
        *counts[i] = mts_cursor_varint(&c);
    for (int a = 0; a < 3; a++)
        mi->bbox_min[a] = mts_cursor_f32(&c);
    for (int a = 0; a < 3; a++)
        mi->bbox_max[a] = mts_cursor_f32(&c);
    mi->quant_bits = mts_cursor_u8(&c);
    mi->flags = mts_cursor_u8(&c);
    for (int a = 0; a < 3; a++)
        mi->grid_origin[a] = mts_cursor_f32(&c);
    mi->grid_range = mts_cursor_f32(&c);
    mi->batch_count = mts_cursor_varint(&c);
    if (!c.ok)
        return mts_error_set(err, MTS_ERR_FORMAT, "MODEL_INFO: truncated (%zu bytes)", size);
    if (mi->vertices == 0 || mi->levels >= mi->vertices ||
        mi->base_vertices != mi->vertices - mi->levels || mi->stop_level > mi->levels)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "MODEL_INFO: %u vertices, %u base, %u levels, stop at %u do not add up",
                             mi->vertices, mi->base_vertices, mi->levels, mi->stop_level);
    if (mi->quant_bits < 1 || mi->quant_bits > 30 || !(mi->grid_range > 0))
        return mts_error_set(err, MTS_ERR_FORMAT, "MODEL_INFO: bad position grid (%u bits)",
                             mi->quant_bits);
    if (mi->flags & ~MTS_INFO_KNOWN_FLAGS)
        return mts_error_set(err, MTS_ERR_FORMAT, "MODEL_INFO: unknown flags 0x%02x",
                             mi->flags);
    mi->batch_size = mts_cursor_varint(&c);
    /* every batch but the last holds batch_size splits, the last 1 to
     * batch_size: together exactly the levels */
    const uint64_t whole = (uint64_t)mi->batch_size * mi->batch_count;
    if (c.ok && (mi->levels == 0 ? mi->batch_count != 0
                                 : mi->batch_size == 0 || whole < mi->levels ||
                                       whole - mi->batch_size >= mi->levels))
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "MODEL_INFO: %u batches of %u splits do not make %u levels",
                             mi->batch_count, mi->batch_size, mi->levels);
    mi->capacity_total = mts_cursor_varint(&c);
    /* every slot is used at some level, so it has room for an index: the
     * strips are bounded by the capacities' total before anything is sized
     * by them */
    if (c.ok && mi->strips > mi->capacity_total) {
        const uint32_t strips = mi->strips, total = mi->capacity_total;
        mts_wire_model_info_free(mi);
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "MODEL_INFO: %u strips cannot fit slots of %u indices", strips,
                             total);
    }
    mi->key_count = mts_cursor_varint(&c);
    if (mi->key_count > MTS_WIRE_MAX_KEYS || mi->key_count > mts_cursor_left(&c)) {
        uint32_t kc = mi->key_count;
        mts_wire_model_info_free(mi);
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "MODEL_INFO: %u key levels (at most %u, and what fits the message)",
                             kc, MTS_WIRE_MAX_KEYS);
    }
    mi->key_levels = malloc(((size_t)mi->key_count + 1) * 4);
    if (!mi->key_levels) {
        mts_wire_model_info_free(mi);
        return mts_error_set(err, MTS_ERR_NOMEM, "MODEL_INFO: out of memory");
    }
    uint64_t key = 0;
    for (uint32_t k = 0; k < mi->key_count; k++) {
        uint32_t d = mts_cursor_varint(&c);
        key += d;
        if (d == 0 || key >= mi->levels) {
            mts_wire_model_info_free(mi);
            return mts_error_set(err, MTS_ERR_FORMAT,
                                 "MODEL_INFO: key level %llu (the %u-th) is not ascending below "
                                 "the %u levels",
                                 (unsigned long long)key, k + 1, mi->levels);
        }
        mi->key_levels[k] = (uint32_t)key;
    }
    if (!c.ok || mts_cursor_left(&c) != 0) {
        mts_wire_model_info_free(mi);
        return mts_error_set(err, MTS_ERR_FORMAT, "MODEL_INFO: truncated, or %zu bytes too many",
                             c.ok ? mts_cursor_left(&c) : 0);
    }
    return MTS_OK;
}

mts_result mts_wire_parse_end(const uint8_t *payload, size_t size, mts_wire_end *e,
                              mts_error *err)
{
    mts_cursor c = mts_cursor_make(payload, size);
    e->final_level = mts_cursor_varint(&c);
    e->checksum = mts_cursor_u64(&c);
    e->stream_bytes = mts_cursor_varint(&c);
    if (!c.ok || mts_cursor_left(&c) != 0)
        return mts_error_set(err, MTS_ERR_FORMAT, "END: malformed (%zu bytes)", size);
    return MTS_OK;
}

mts_result mts_wire_parse_models(const uint8_t *payload, size_t size,
                                 void (*fn)(void *user, const mts_wire_model_entry *m),
                                 void *user, mts_error *err)
{
    mts_cursor c = mts_cursor_make(payload, size);
    uint32_t count = mts_cursor_varint(&c);
    if (!c.ok || count > mts_cursor_left(&c))
        return mts_error_set(err, MTS_ERR_FORMAT, "MODELS: bad count");
    for (uint32_t i = 0; i < count; i++) {
        mts_wire_model_entry m;
        mts_result rc = parse_name(&c, m.name, "MODELS", err);
        if (rc != MTS_OK)
            return rc;
        m.vertices = mts_cursor_varint(&c);
        m.triangles = mts_cursor_varint(&c);
        m.levels = mts_cursor_varint(&c);
        m.stream_bytes = mts_cursor_varint(&c);
        if (!c.ok)
            return mts_error_set(err, MTS_ERR_FORMAT, "MODELS: truncated at model %u", i);
        fn(user, &m);
    }
    if (mts_cursor_left(&c) != 0)
        return mts_error_set(err, MTS_ERR_FORMAT, "MODELS: bytes after the last model");
    return MTS_OK;
}

size_t mts_wire_clean_text(char *out, size_t out_size, const char *in, size_t len)
{
    if (out_size == 0)
        return 0;
    const unsigned char *s = (const unsigned char *)in;
    size_t o = 0;
    for (size_t i = 0; i < len;) {
        const size_t k = mts_utf8_seq_len(s + i, len - i);
        const int bad = k == 0 || s[i] < 0x20 || s[i] == 0x7f;
        const size_t w = bad ? 1 : k;
        if (o + w > out_size - 1)
            break; /* never a character cut in two */
        if (bad)
            out[o++] = '?';
        else
            for (size_t q = 0; q < k; q++)
                out[o++] = (char)s[i + q];
        i += bad ? 1 : k;
    }
    out[o] = 0;
    return o;
}

mts_result mts_wire_parse_error(const uint8_t *payload, size_t size, uint16_t *code, char *text,
                                size_t text_size, mts_error *err)
{
    mts_cursor c = mts_cursor_make(payload, size);
    *code = mts_cursor_u16(&c);
    size_t len = 0;
    const char *s = mts_cursor_string(&c, size, &len);
    if (!c.ok || !s || text_size == 0)
        return mts_error_set(err, MTS_ERR_FORMAT, "ERROR: malformed (%zu bytes)", size);
    mts_wire_clean_text(text, text_size, s, len);
    return MTS_OK;
}

const char *mts_wire_error_name(uint16_t code)
{
    switch (code) {
    case MTS_WERR_PROTOCOL: return "protocol";
    case MTS_WERR_VERSION: return "version";
    case MTS_WERR_UNKNOWN_MODEL: return "unknown_model";
    case MTS_WERR_BUSY: return "busy";
    case MTS_WERR_STALE: return "stale";
    case MTS_WERR_TIMEOUT: return "timeout";
    case MTS_WERR_INTERNAL: return "internal";
    }
    return "unknown";
}

void mts_wire_reader_free(mts_wire_reader *r)
{
    free(r->buf);
    memset(r, 0, sizeof *r);
}

mts_result mts_wire_reader_feed(mts_wire_reader *r, const void *data, size_t size,
                                mts_error *err)
{
    if (r->start > 0 &&
        (r->start >= r->len || r->start > r->cap / 2 || size > r->cap - r->len)) {
        /* drop consumed frames before growing: whenever the new bytes would
         * not fit otherwise, so the buffer holds only what is still unread */
        memmove(r->buf, r->buf + r->start, r->len - r->start);
        r->len -= r->start;
        r->start = 0;
    }
    if (size > r->cap - r->len) {
        /* a drained reader holds less than one frame; one that is fed without
         * being drained is allowed one more, then refused */
        if (r->len > 2 * ((size_t)MTS_WIRE_MAX_FRAME + MTS_WIRE_HEADER) ||
            size > SIZE_MAX / 2 - r->len)
            return mts_error_set(err, MTS_ERR_LIMIT, "reader: more than a frame buffered");
        size_t need = r->len + size;
        size_t cap = r->cap ? r->cap : 4096;
        while (cap < need)
            cap *= 2;
        uint8_t *b = realloc(r->buf, cap);
        if (!b)
            return mts_error_set(err, MTS_ERR_NOMEM, "reader: out of memory");
        r->buf = b;
        r->cap = cap;
    }
    if (size)
        memcpy(r->buf + r->len, data, size);
    r->len += size;
    r->bytes_in += size;
    return MTS_OK;
}

/* The frame at r->buf + at: 1 whole (*len its length field: type and
 * payload), 0 not all there, -1 a length that cannot be. */
static int frame_at(const mts_wire_reader *r, size_t at, uint32_t *len)
{
    if (r->len - at < 4)
        return 0;
    const uint8_t *p = r->buf + at;
    *len = (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
    if (*len == 0 || *len > MTS_WIRE_MAX_FRAME)
        return -1;
    return r->len - at - 4 >= *len;
}

int mts_wire_reader_next(mts_wire_reader *r, uint8_t *type, const uint8_t **payload,
                         size_t *size, mts_error *err)
{
    uint32_t len = 0;
    const int got = frame_at(r, r->start, &len);
    if (got < 0)
        mts_error_set(err, MTS_ERR_FORMAT, "frame of %u bytes (1..%u allowed)", len,
                      MTS_WIRE_MAX_FRAME);
    if (got <= 0)
        return got;
    const uint8_t *p = r->buf + r->start;
    *type = p[4];
    *payload = p + 5;
    *size = len - 1;
    r->start += 4 + (size_t)len;
    return 1;
}

int mts_wire_reader_peek(const mts_wire_reader *r, uint32_t skip, uint8_t *type,
                         const uint8_t **payload, size_t *size)
{
    size_t at = r->start;
    uint32_t len = 0;
    for (uint32_t k = 0; frame_at(r, at, &len) > 0; k++, at += 4 + (size_t)len) {
        if (k == skip) {
            *type = r->buf[at + 4];
            *payload = r->buf + at + 5;
            *size = len - 1;
            return 1;
        }
    }
    return 0;
}
