/* A stream file: writing it from an encoded stream, reading its prefix, and
 * feeding its ranges to a stream client (stream_file.h, PROTOCOL.md "Stream
 * files"). */
#include "stream_file.h"

#include <stdlib.h>
#include <string.h>

#include "crc32c.h"

/* a frame's header: u32 length, u8 type */
#define FRAME_HEADER 5u
#define FRAME_MAX ((uint64_t)MTS_WIRE_MAX_FRAME + 4u)

static uint32_t zigzag(int64_t v)
{
    return (uint32_t)(((uint64_t)v << 1) ^ (uint64_t)(v >> 63));
}

static int64_t unzigzag(uint32_t z)
{
    return (int64_t)(z >> 1) ^ -(int64_t)(z & 1);
}

mts_result mts_stream_file_write(const mts_stream *s, mts_buf *out, mts_error *err)
{
    const mts_model *m = &s->model;
    const uint32_t levels = m->level_count;
    if (!m->level_triangles)
        return mts_error_set(err, MTS_ERR_ARG, "stream file: the model has no level triangles");
    const size_t base_size = s->batch_count ? s->batch_offset[0] : s->size;

    mts_buf info = {0}, table = {0};
    mts_stream_put_model_info(s, levels, &info);

    mts_buf_varint(&table, s->batch_count);
    if (base_size > UINT32_MAX || m->level_triangles[0] > UINT32_MAX)
        goto too_big;
    mts_buf_varint(&table, (uint32_t)base_size);
    mts_buf_varint(&table, m->level_triangles[0]);
    uint64_t prev = m->level_triangles[0];
    for (uint32_t k = 0; k < s->batch_count; k++) {
        const uint32_t first = s->batch_first[k], n = s->batch_first[k + 1] - first;
        const uint64_t size = s->batch_offset[k + 1] - s->batch_offset[k];
        const uint64_t t_first = m->level_triangles[first + 1];
        const uint64_t t_end = m->level_triangles[first + n];
        /* every split adds at least one triangle, an interior one two: the
         * deltas against that are a byte or two */
        const int64_t d_end = (int64_t)(t_end - t_first) - 2 * (int64_t)(n - 1);
        if (size > UINT32_MAX || t_first - prev > UINT32_MAX || d_end > INT32_MAX ||
            d_end < INT32_MIN)
            goto too_big;
        mts_buf_varint(&table, (uint32_t)size);
        mts_buf_varint(&table, (uint32_t)(t_first - prev));
        mts_buf_varint(&table, zigzag(d_end));
        prev = t_end;
    }
    /* one CRC over MODEL_INFO and the table: MODEL_INFO has none of its own
     * on the wire, and a client plans every request from these two */
    if (!info.failed && !table.failed)
        mts_buf_u32(&table, mts_crc32c(mts_crc32c(0, info.data, info.size), table.data,
                                       table.size));

    const uint64_t checks_size = 8ull * (s->batch_count + 1) + 4;
    const uint64_t file_size = MTS_SFILE_HEADER_SIZE + info.size + table.size + s->size +
                               checks_size;
    size_t h = out->size;
    mts_buf_put(out, MTS_SFILE_MAGIC, 4);
    mts_buf_u16(out, MTS_SFILE_MAJOR);
    mts_buf_u16(out, MTS_SFILE_MINOR);
    mts_buf_u32(out, (uint32_t)info.size);
    mts_buf_u32(out, (uint32_t)table.size);
    mts_buf_u64(out, file_size);
    mts_buf_u32(out, 0); /* flags: none yet; a reader refuses any it does not know */
    if (!out->failed)
        mts_buf_u32(out, mts_crc32c(0, out->data + h, 28));
    mts_buf_put(out, info.data, info.size);
    mts_buf_put(out, table.data, table.size);
    mts_buf_put(out, s->bytes, base_size);
    size_t c = out->size;
    mts_buf_u64(out, s->level_checksum[0]);
    for (uint32_t k = 0; k < s->batch_count; k++)
        mts_buf_u64(out, s->level_checksum[s->batch_first[k + 1]]);
    if (!out->failed)
        mts_buf_u32(out, mts_crc32c(0, out->data + c, out->size - c));
    mts_buf_put(out, s->bytes + base_size, s->size - base_size);
    mts_buf_free(&info);
    mts_buf_free(&table);
    if (out->failed)
        return mts_error_set(err, MTS_ERR_NOMEM, "stream file: out of memory");
    return MTS_OK;
too_big:
    mts_buf_free(&info);
    mts_buf_free(&table);
    return mts_error_set(err, MTS_ERR_RANGE, "stream file: a size or count does not fit");
}

static uint16_t le16(const uint8_t *p)
{
    return (uint16_t)(p[0] | p[1] << 8);
}

static uint32_t le32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static uint64_t le64(const uint8_t *p)
{
    return (uint64_t)le32(p) | (uint64_t)le32(p + 4) << 32;
}

mts_result mts_stream_file_prefix_size(const uint8_t *header, size_t size, uint64_t max_bytes,
                                       uint64_t *prefix_size, mts_error *err)
{
    if (size < MTS_SFILE_HEADER_SIZE)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "stream file: %zu bytes, shorter than its %u-byte header", size,
                             MTS_SFILE_HEADER_SIZE);
    if (memcmp(header, MTS_SFILE_MAGIC, 4) != 0)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "not a stream file (it does not start with \"" MTS_SFILE_MAGIC
                             "\"; mts-build MESH --stream OUT.mts writes one)");
    if (mts_crc32c(0, header, 28) != le32(header + 28))
        return mts_error_set(err, MTS_ERR_CHECKSUM, "stream file: the header's CRC does not match");
    uint16_t major = le16(header + 4);
    if (major != MTS_SFILE_MAJOR)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "stream file version %u.%u; this client reads version %u", major,
                             le16(header + 6), MTS_SFILE_MAJOR);
    if (le32(header + 24) != 0)
        return mts_error_set(err, MTS_ERR_FORMAT, "stream file: unknown flags 0x%x",
                             le32(header + 24));
    const uint64_t info = le32(header + 8), table = le32(header + 12), file = le64(header + 16);
    if (max_bytes && file > max_bytes)
        return mts_error_set(err, MTS_ERR_RANGE,
                             "stream file: %llu bytes, over the size cap of %llu bytes",
                             (unsigned long long)file, (unsigned long long)max_bytes);
    if (info < FRAME_HEADER || info > FRAME_MAX || table < 4 ||
        MTS_SFILE_HEADER_SIZE + info + table > file)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "stream file: its header's sizes (MODEL_INFO %llu, table %llu, "
                             "file %llu bytes) do not fit together",
                             (unsigned long long)info, (unsigned long long)table,
                             (unsigned long long)file);
    *prefix_size = MTS_SFILE_HEADER_SIZE + info + table;
    return MTS_OK;
}

void mts_stream_file_index_free(mts_stream_file_index *idx)
{
    mts_wire_model_info_free(&idx->info);
    free(idx->batch_offset);
    free(idx->level_triangles_first);
    free(idx->boundary_triangles);
    memset(idx, 0, sizeof *idx);
}

static mts_result bad_table(mts_error *err, const char *what)
{
    return mts_error_set(err, MTS_ERR_FORMAT, "stream file: its table %s", what);
}

mts_result mts_stream_file_index_parse(const uint8_t *data, size_t size, uint64_t max_bytes,
                                       mts_stream_file_index *idx, mts_error *err)
{
    memset(idx, 0, sizeof *idx);
    uint64_t prefix;
    mts_result rc = mts_stream_file_prefix_size(data, size, max_bytes, &prefix, err);
    if (rc != MTS_OK)
        return rc;
    if (size < prefix)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "stream file: %zu bytes of its %llu-byte prefix (header, "
                             "MODEL_INFO and table)",
                             size, (unsigned long long)prefix);
    idx->major = le16(data + 4);
    idx->minor = le16(data + 6);
    idx->file_size = le64(data + 16);
    idx->prefix_size = prefix;
    const uint32_t info_size = le32(data + 8), table_size = le32(data + 12);

    const uint8_t *f = data + MTS_SFILE_HEADER_SIZE;
    if (mts_crc32c(0, f, info_size + table_size - 4) != le32(f + info_size + table_size - 4))
        return mts_error_set(err, MTS_ERR_CHECKSUM,
                             "stream file: the CRC of its MODEL_INFO and table does not match");
    if (le32(f) != info_size - 4 || f[4] != MTS_MSG_MODEL_INFO)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "stream file: no MODEL_INFO frame of the header's size after it");
    if ((rc = mts_wire_parse_model_info(f + FRAME_HEADER, info_size - FRAME_HEADER, &idx->info,
                                        err)) != MTS_OK)
        return mts_error_prefix(err, "stream file");
    const mts_wire_model_info *mi = &idx->info;
    if (mi->stop_level != mi->levels)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "stream file: its MODEL_INFO stops at level %u of %u, not the full "
                             "level",
                             mi->stop_level, mi->levels);

    const uint8_t *t = f + info_size;
    mts_cursor cur = mts_cursor_make(t, table_size - 4);
    const uint32_t count = mts_cursor_varint(&cur);
    const uint32_t base_size = mts_cursor_varint(&cur);
    const uint32_t base_triangles = mts_cursor_varint(&cur);
    if (!cur.ok || count != mi->batch_count)
        return bad_table(err, "does not list MODEL_INFO's batches");
    /* three bytes an entry at least: the count is bounded by what came */
    if ((uint64_t)count * 3 > mts_cursor_left(&cur))
        return bad_table(err, "is shorter than its batches");
    if (base_size < FRAME_HEADER || base_size > FRAME_MAX)
        return bad_table(err, "gives BASE an impossible size");
    idx->batch_count = count;
    idx->batch_offset = malloc(((size_t)count + 1) * sizeof *idx->batch_offset);
    idx->level_triangles_first = malloc(((size_t)count + 1) * sizeof *idx->level_triangles_first);
    idx->boundary_triangles = malloc(((size_t)count + 1) * sizeof *idx->boundary_triangles);
    if (!idx->batch_offset || !idx->level_triangles_first || !idx->boundary_triangles)
        return mts_error_set(err, MTS_ERR_NOMEM, "stream file: out of memory");
    idx->base_offset = prefix;
    idx->base_size = base_size;
    idx->checks_offset = prefix + base_size;
    idx->checks_size = 8ull * (count + 1) + 4;
    uint64_t at = idx->checks_offset + idx->checks_size;
    uint64_t tri = base_triangles;
    idx->boundary_triangles[0] = tri;
    for (uint32_t k = 0; k < count; k++) {
        const uint32_t size_k = mts_cursor_varint(&cur);
        const uint32_t d_first = mts_cursor_varint(&cur);
        const int64_t d_end = unzigzag(mts_cursor_varint(&cur));
        const uint32_t n = mts_wire_batch_splits(mi, k);
        if (!cur.ok)
            return bad_table(err, "ends inside its batches");
        if (size_k < FRAME_HEADER || size_k > FRAME_MAX)
            return bad_table(err, "gives a BATCH an impossible size");
        /* a split adds at least one triangle */
        const int64_t added = d_end + 2 * (int64_t)(n - 1);
        if (d_first < 1 || added < (int64_t)(n - 1))
            return bad_table(err, "has triangle counts that do not rise with the level");
        idx->batch_offset[k] = at;
        at += size_k;
        idx->level_triangles_first[k] = tri + d_first;
        tri += d_first + (uint64_t)added;
        if (tri > mi->triangles)
            return bad_table(err, "counts more triangles than MODEL_INFO's full level");
        idx->boundary_triangles[k + 1] = tri;
    }
    idx->batch_offset[count] = at;
    if (mts_cursor_left(&cur) != 0)
        return bad_table(err, "has bytes after its batches");
    if (tri != mi->triangles)
        return bad_table(err, "does not end at MODEL_INFO's triangles");
    if (at != idx->file_size)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "stream file: its parts add up to %llu bytes, but the header says "
                             "%llu",
                             (unsigned long long)at, (unsigned long long)idx->file_size);
    return MTS_OK;
}

/* mts_model_level_for_fraction's rule, from MODEL_INFO's counts, so that a
 * fraction stops where mts-server would stop it */
static uint32_t level_for_fraction(const mts_wire_model_info *mi, double fraction)
{
    if (!(fraction > 0))
        return 0;
    if (fraction >= 1)
        return mi->levels;
    double vertices = fraction * mi->vertices + 0.5;
    if (vertices <= mi->base_vertices)
        return 0;
    uint64_t l = (uint64_t)vertices - mi->base_vertices;
    return l > mi->levels ? mi->levels : (uint32_t)l;
}

mts_result mts_stream_file_plan_stop(const mts_stream_file_index *idx, uint8_t stop_kind,
                                     uint32_t stop_value, uint32_t first_batch,
                                     mts_stream_file_plan *plan, mts_error *err)
{
    const mts_wire_model_info *mi = &idx->info;
    memset(plan, 0, sizeof *plan);
    uint32_t batches = 0;
    switch (stop_kind) {
    case MTS_STOP_TRIANGLES:
        /* batch k is needed when the level goes past its first split, that
         * is when one split more still fits the budget */
        plan->by_triangles = 1;
        plan->max_triangles = stop_value;
        while (batches < idx->batch_count &&
               idx->level_triangles_first[batches] <= stop_value)
            batches++;
        plan->stop_level = batches ? mts_wire_batch_first(mi, batches - 1) +
                                         mts_wire_batch_splits(mi, batches - 1)
                                   : 0;
        break;
    case MTS_STOP_LEVEL:
    case MTS_STOP_FRACTION:
    default: {
        uint32_t level = mi->levels;
        if (stop_kind == MTS_STOP_LEVEL)
            level = stop_value < mi->levels ? stop_value : mi->levels;
        else if (stop_kind == MTS_STOP_FRACTION)
            level = level_for_fraction(mi, stop_value / 1e6);
        plan->stop_level = level;
        while (batches < idx->batch_count && mts_wire_batch_first(mi, batches) < level)
            batches++;
        break;
    }
    }
    plan->batches = batches;
    plan->boundary = batches ? mts_wire_batch_first(mi, batches - 1) +
                                   mts_wire_batch_splits(mi, batches - 1)
                             : 0;
    if (first_batch > batches)
        return mts_error_set(err, MTS_ERR_RANGE,
                             "resume from batch %u, but the stream to level %u has %u batches",
                             first_batch, plan->stop_level, batches);
    plan->from = first_batch == 0 ? idx->base_offset : idx->batch_offset[first_batch];
    plan->to = batches ? idx->batch_offset[batches] : idx->checks_offset + idx->checks_size;
    if (plan->to < plan->from)
        plan->to = plan->from;
    return MTS_OK;
}

mts_result mts_stream_file_reader_begin(mts_stream_file_reader *r,
                                        const mts_stream_file_index *idx,
                                        const mts_stream_file_plan *plan, mts_stream_client *c,
                                        mts_error *err)
{
    if (r->idx && r->idx != idx) /* the checks kept belong to another file */
        mts_stream_file_reader_free(r);
    r->idx = idx;
    r->plan = *plan;
    r->at = plan->from;
    /* MODEL_INFO as mts-server would send it for this stop; until the
     * batches are in, the triangles at the stop are bounded by those at the
     * boundary (the exact count is set when the stream ends) */
    mts_wire_model_info mi = idx->info;
    mi.stop_level = plan->stop_level;
    mi.stop_triangles = (uint32_t)idx->boundary_triangles[plan->batches];
    mts_buf b = {0};
    mts_wire_put_model_info(&b, &mi);
    mts_result rc = b.failed ? mts_error_set(err, MTS_ERR_NOMEM, "stream file: out of memory")
                             : mts_stream_client_feed(c, b.data, b.size, err);
    mts_buf_free(&b);
    return rc;
}

mts_result mts_stream_file_reader_feed(mts_stream_file_reader *r, mts_stream_client *c,
                                       const uint8_t *data, size_t size, mts_error *err)
{
    const mts_stream_file_index *idx = r->idx;
    if (size > r->plan.to - r->at)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "stream file: %zu bytes past the range asked for (bytes %llu-%llu)",
                             size - (size_t)(r->plan.to - r->at),
                             (unsigned long long)r->plan.from,
                             (unsigned long long)r->plan.to - 1);
    const uint64_t c0 = idx->checks_offset, c1 = c0 + idx->checks_size;
    while (size > 0) {
        size_t n = size;
        if (r->at >= c0 && r->at < c1) {
            if (n > c1 - r->at)
                n = (size_t)(c1 - r->at);
            if (!r->checks && !(r->checks = malloc(idx->checks_size)))
                return mts_error_set(err, MTS_ERR_NOMEM, "stream file: out of memory");
            memcpy(r->checks + (r->at - c0), data, n);
            if (r->at + n == c1) {
                const size_t body = (size_t)idx->checks_size - 4;
                if (mts_crc32c(0, r->checks, body) != le32(r->checks + body))
                    return mts_error_set(err, MTS_ERR_CHECKSUM,
                                         "stream file: the checks' CRC does not match");
                r->checks_ok = 1;
            }
        } else {
            if (r->at < c0 && n > c0 - r->at)
                n = (size_t)(c0 - r->at);
            mts_result rc = mts_stream_client_feed(c, data, n, err);
            if (rc != MTS_OK)
                return rc;
        }
        r->at += n;
        data += n;
        size -= n;
    }
    return MTS_OK;
}

int mts_stream_file_reader_done(const mts_stream_file_reader *r)
{
    return r->idx && r->at == r->plan.to;
}

static mts_result triangles_at(mts_stream_client *c, uint32_t level, uint64_t *triangles,
                               mts_error *err)
{
    mts_result rc = mts_lod_set_level(&c->lod, level, err);
    if (rc != MTS_OK)
        return rc;
    mts_strip_stats ss;
    mts_lod_strip_stats(&c->lod, &ss);
    *triangles = ss.triangles;
    return MTS_OK;
}

mts_result mts_stream_file_reader_end(mts_stream_file_reader *r, mts_stream_client *c,
                                      mts_stream_event *event, mts_error *err)
{
    *event = MTS_EV_NONE;
    const mts_stream_file_plan *p = &r->plan;
    if (!mts_stream_file_reader_done(r))
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "stream file: the range ended at byte %llu of %llu",
                             (unsigned long long)r->at, (unsigned long long)p->to);
    if (!c->have_lod || c->batches != p->batches || c->splits < p->boundary)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "stream file: %u of the %u batches to level %u were taken",
                             c->batches, p->batches, p->boundary);
    if (!r->checks_ok)
        return mts_error_set(err, MTS_ERR_FORMAT, "stream file: the checks never came");
    const uint64_t want = le64(r->checks + 8ull * p->batches);
    mts_result rc = mts_lod_set_level(&c->lod, p->boundary, err);
    if (rc != MTS_OK)
        return rc;
    const uint64_t got = mts_stream_checksum_colors(&c->lod, c->quantized, c->model.colors);
    if (got != want)
        return mts_error_set(err, MTS_ERR_CHECKSUM,
                             "stream file: the mesh at level %u differs from the file's "
                             "(checksum %016llx, file %016llx)",
                             p->boundary, (unsigned long long)got, (unsigned long long)want);
    /* The state at a level is a function of the level alone, so the level
     * asked for, reached from the checked boundary, is checked too. */
    uint32_t level = c->stop_level;
    uint64_t triangles = 0;
    if (p->by_triangles) {
        /* the largest level with at most max_triangles: the plan took the
         * last batch only if its first split fits */
        uint32_t lo = 0, hi = 0;
        if (p->batches > 0) {
            hi = p->boundary;
            lo = hi - mts_wire_batch_splits(&c->info, p->batches - 1) + 1;
        }
        while (lo < hi) {
            uint32_t mid = lo + (hi - lo + 1) / 2;
            if ((rc = triangles_at(c, mid, &triangles, err)) != MTS_OK)
                return rc;
            if (triangles <= p->max_triangles)
                lo = mid;
            else
                hi = mid - 1;
        }
        level = lo;
    }
    if ((rc = triangles_at(c, level, &triangles, err)) != MTS_OK)
        return rc;
    /* The plan took the last batch because the table said its first split
     * fits the budget; the checks vouch for the mesh, not for the table's
     * counts, so a table that lied shows here. */
    if (p->by_triangles && p->batches > 0 && triangles > p->max_triangles)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "stream file: the table's triangle counts disagree with the mesh "
                             "(level %u has %llu triangles, over the %llu asked for)",
                             level, (unsigned long long)triangles,
                             (unsigned long long)p->max_triangles);
    c->stop_level = level;
    c->info.stop_level = level;
    c->info.stop_triangles = (uint32_t)triangles;
    mts_wire_end e = {level, mts_stream_checksum_colors(&c->lod, c->quantized, c->model.colors),
                      (uint32_t)(p->to - p->from)};
    mts_buf b = {0};
    mts_wire_put_end(&b, &e);
    if (b.failed) {
        mts_buf_free(&b);
        return mts_error_set(err, MTS_ERR_NOMEM, "stream file: out of memory");
    }
    rc = mts_stream_client_frame(c, MTS_MSG_END, b.data + FRAME_HEADER, b.size - FRAME_HEADER,
                                 event, err);
    mts_buf_free(&b);
    return rc;
}

void mts_stream_file_reader_free(mts_stream_file_reader *r)
{
    free(r->checks);
    memset(r, 0, sizeof *r);
}
