/* Fuzz target: a stream file as a client reads it from a web server
 * (protocol/stream_file.h, as client/webfile.c uses it). A stream file comes
 * from whoever runs the web server, so its header, table and checks are
 * input like any socket's bytes.
 *
 * Input: one mode byte, four stop bytes, then the file.
 *   mode bit 0     1: leave the CRCs as they are; 0: rewrite the header's,
 *                  the MODEL_INFO and table's, the checks' and every BASE and
 *                  BATCH frame's first, so that mutations reach the parsers
 *                  and decoders behind them
 *   mode bits 1-4  k: 0 hands a range over at once; else in pieces of
 *                  1 .. 2^k bytes from a generator seeded with the mode, as
 *                  libcurl's write callback does
 *   mode bit 5     cap the file at the input's own size (a header that
 *                  claims more is refused as over the cap); else no cap
 *   mode bit 6     the first conversation breaks part-way through its range
 *                  and resumes as a session does (resume_point,
 *                  reconnected, a new plan from the batches held)
 *   stop byte s    kind s & 3 (level, triangles, fraction, full) and a value
 *                  from s >> 2 scaled to the index's own counts, so that the
 *                  stops land on and next to its levels and batch bounds
 * The header goes through mts_stream_file_prefix_size and the prefix through
 * mts_stream_file_index_parse, capped. When the index parses, each stop is
 * planned (and once more from a batch past the plan, which must be refused)
 * and read on a fresh stream client from the file's bytes of its range; the
 * first one, when it ended, continues to the second stop as a preview that
 * zooms in does. What ended is moved down to level 0 and back, as in
 * fuzz_stream_client.c. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fuzz_util.h"
#include "stream.h"
#include "stream_file.h"
#include "wire.h"

#define MTS_FUZZ_SF_STOPS 4

typedef struct mts_fuzz_sf {
    const uint8_t *file;
    size_t size;
    size_t max_piece;
    uint64_t seed;
    int ends; /* conversations that ended with END at their first stop */
} mts_fuzz_sf;

/* The stop a stop byte names, on this index's counts. */
static void mts_fuzz_sf_stop(const mts_stream_file_index *idx, uint8_t s, uint8_t *kind,
                             uint32_t *value)
{
    static const uint8_t kinds[4] = {MTS_STOP_LEVEL, MTS_STOP_TRIANGLES, MTS_STOP_FRACTION,
                                     MTS_STOP_FULL};
    const uint32_t v = s >> 2; /* 0..63 */
    *kind = kinds[s & 3];
    *value = 0;
    switch (*kind) {
    case MTS_STOP_LEVEL:
        *value = v == 63 ? UINT32_MAX : (uint32_t)((uint64_t)idx->info.levels * v / 62);
        break;
    case MTS_STOP_TRIANGLES: {
        /* a batch's first split's count or the full level's, one below,
         * at, or one above it */
        const uint32_t n = idx->batch_count + 1;
        const uint32_t k = v % n;
        uint64_t t = k < idx->batch_count ? idx->level_triangles_first[k]
                                          : idx->boundary_triangles[idx->batch_count];
        t = t + (v / n) % 3;
        *value = t == 0 ? 0 : t - 1 > UINT32_MAX ? UINT32_MAX : (uint32_t)(t - 1);
        break;
    }
    case MTS_STOP_FRACTION:
        *value = v == 63 ? 2000000 : v * 1000000u / 62;
        break;
    default:
        break;
    }
}

/* The promises of a plan that was made. */
static void mts_fuzz_sf_check_plan(const mts_stream_file_index *idx,
                                   const mts_stream_file_plan *p, uint32_t first_batch)
{
    MTS_FUZZ_CHECK(p->batches <= idx->batch_count && first_batch <= p->batches);
    MTS_FUZZ_CHECK(p->stop_level <= idx->info.levels && p->boundary <= idx->info.levels);
    MTS_FUZZ_CHECK(p->by_triangles ? p->stop_level == p->boundary
                                   : p->stop_level <= p->boundary);
    MTS_FUZZ_CHECK(p->from <= p->to && p->to <= idx->file_size);
    MTS_FUZZ_CHECK(p->from >= idx->base_offset);
}

/* One range of the file through the reader, the client's events taken
 * between pieces, as webfile.c's poll does. Stops after `stop_at` bytes
 * (a break); returns 0 when a refusal ended it. */
static int mts_fuzz_sf_range(mts_fuzz_sf *f, mts_stream_file_reader *r, mts_stream_client *c,
                             uint64_t stop_at)
{
    mts_error err = {0};
    uint64_t at = r->plan.from;
    uint64_t end = r->plan.to < f->size ? r->plan.to : f->size;
    if (stop_at < end - at)
        end = at + stop_at;
    while (at < end) {
        f->seed = f->seed * 6364136223846793005ull + 1442695040888963407ull;
        size_t piece = 1 + (size_t)((f->seed >> 33) % f->max_piece);
        if (piece > end - at)
            piece = (size_t)(end - at);
        mts_result rc = mts_stream_file_reader_feed(r, c, f->file + at, piece, &err);
        if (rc != MTS_OK) {
            MTS_FUZZ_CHECK(err.msg[0] != 0);
            return 0;
        }
        at += piece;
        mts_stream_event ev;
        int got;
        while ((got = mts_stream_client_next(c, &ev, &err)) > 0)
            if (ev == MTS_EV_BASE || ev == MTS_EV_BATCH)
                MTS_FUZZ_CHECK(c->have_lod && c->lod.level <= c->splits);
        if (got < 0) {
            MTS_FUZZ_CHECK(err.msg[0] != 0);
            return 0;
        }
    }
    MTS_FUZZ_CHECK(r->at == at);
    return 1;
}

/* Ends a range that came whole; 1 when the stream ended with END. */
static int mts_fuzz_sf_end(mts_fuzz_sf *f, mts_stream_file_reader *r, mts_stream_client *c)
{
    mts_error err = {0};
    mts_stream_event ev;
    if (!mts_stream_file_reader_done(r)) {
        /* the file is shorter than the range: end refuses */
        MTS_FUZZ_CHECK(mts_stream_file_reader_end(r, c, &ev, &err) != MTS_OK && err.msg[0]);
        return 0;
    }
    if (r->plan.to < f->size) {
        /* a server that sends past the range is refused, not followed */
        mts_error e2 = {0};
        MTS_FUZZ_CHECK(mts_stream_file_reader_feed(r, c, f->file + r->plan.to, 1, &e2) !=
                           MTS_OK &&
                       e2.msg[0]);
    }
    if (mts_stream_file_reader_end(r, c, &ev, &err) != MTS_OK) {
        MTS_FUZZ_CHECK(err.msg[0] != 0);
        return 0;
    }
    MTS_FUZZ_CHECK(ev == MTS_EV_END);
    MTS_FUZZ_CHECK(c->have_lod && c->lod.level == c->stop_level);
    MTS_FUZZ_CHECK(c->stop_level <= r->plan.boundary);
    if (!r->plan.by_triangles)
        MTS_FUZZ_CHECK(c->stop_level == r->plan.stop_level);
    return 1;
}

/* Down to the base and back up: everything held is a checked split. */
static void mts_fuzz_sf_walk(mts_stream_client *c)
{
    if (!c->have_lod || c->lod.broken)
        return;
    mts_error err = {0};
    uint32_t top = c->lod.level;
    uint64_t before = mts_stream_checksum(&c->lod, c->quantized);
    MTS_FUZZ_CHECK(mts_lod_set_level(&c->lod, 0, &err) == MTS_OK);
    MTS_FUZZ_CHECK(mts_lod_set_level(&c->lod, top, &err) == MTS_OK);
    MTS_FUZZ_CHECK(mts_stream_checksum(&c->lod, c->quantized) == before);
}

/* A conversation on a fresh client to stop i; the first may break and
 * resume, and continues to stop i + 1 when it ended. */
static void mts_fuzz_sf_conversation(mts_fuzz_sf *f, const mts_stream_file_index *idx,
                                     const uint8_t *stops, int i, uint8_t mode)
{
    uint8_t kind;
    uint32_t value;
    mts_fuzz_sf_stop(idx, stops[i], &kind, &value);
    mts_error err = {0};
    mts_stream_file_plan plan;
    MTS_FUZZ_CHECK(mts_stream_file_plan_stop(idx, kind, value, 0, &plan, &err) == MTS_OK);
    mts_fuzz_sf_check_plan(idx, &plan, 0);
    mts_stream_file_plan past;
    MTS_FUZZ_CHECK(mts_stream_file_plan_stop(idx, kind, value, plan.batches + 1, &past, &err) ==
                   MTS_ERR_RANGE);

    mts_stream_client c;
    mts_stream_client_init(&c);
    mts_stream_file_reader r;
    memset(&r, 0, sizeof r);
    int going = mts_stream_file_reader_begin(&r, idx, &plan, &c, &err) == MTS_OK;
    if (going && i == 0 && (mode & 0x40)) {
        /* a break somewhere in the range, then a resume from what is held */
        const uint64_t len = plan.to - plan.from;
        const uint64_t cut = len ? (f->seed >> 17) % len : 0;
        going = mts_fuzz_sf_range(f, &r, &c, cut);
        uint32_t batch;
        uint64_t id;
        if (going && mts_stream_client_resume_point(&c, &batch, &id) &&
            mts_stream_client_reconnected(&c, &err) == MTS_OK) {
            going = mts_stream_file_plan_stop(idx, kind, value, c.have_lod ? c.batches : 0,
                                              &plan, &err) == MTS_OK;
            if (going) {
                mts_fuzz_sf_check_plan(idx, &plan, c.have_lod ? c.batches : 0);
                going = mts_stream_file_reader_begin(&r, idx, &plan, &c, &err) == MTS_OK;
            }
        } else {
            going = 0;
        }
    }
    if (going)
        going = mts_fuzz_sf_range(f, &r, &c, UINT64_MAX) && mts_fuzz_sf_end(f, &r, &c);
    f->ends += going;
    if (going && i + 1 < MTS_FUZZ_SF_STOPS) {
        /* a preview asking for more: from the batches held to the next stop
         * (refused as a range when that stop is lower) */
        uint32_t batch;
        uint64_t id;
        mts_fuzz_sf_stop(idx, stops[i + 1], &kind, &value);
        if (mts_stream_client_continue(&c, &batch, &id, &err) != MTS_OK) {
            MTS_FUZZ_CHECK(err.msg[0] != 0);
        } else {
            MTS_FUZZ_CHECK(batch == c.batches && id == c.info.stream_id);
            if (mts_stream_file_plan_stop(idx, kind, value, batch, &plan, &err) == MTS_OK) {
                mts_fuzz_sf_check_plan(idx, &plan, batch);
                if (mts_stream_file_reader_begin(&r, idx, &plan, &c, &err) == MTS_OK &&
                    mts_fuzz_sf_range(f, &r, &c, UINT64_MAX))
                    mts_fuzz_sf_end(f, &r, &c);
            } else {
                MTS_FUZZ_CHECK(err.code == MTS_ERR_RANGE && batch > 0);
            }
        }
    }
    mts_fuzz_sf_walk(&c);
    mts_stream_file_reader_free(&r);
    mts_stream_client_free(&c);
}

/* The CRCs a mutation would break, made right again where their bounds lie
 * inside the file. */
static void mts_fuzz_sf_fix_crcs(uint8_t *file, size_t size)
{
    if (size < MTS_SFILE_HEADER_SIZE)
        return;
    mts_fuzz_put_u32(file + 28, mts_crc32c(0, file, 28));
    const uint64_t info = mts_fuzz_get_u32(file + 8), table = mts_fuzz_get_u32(file + 12);
    if (info + table >= 4 && MTS_SFILE_HEADER_SIZE + info + table <= size) {
        uint8_t *f = file + MTS_SFILE_HEADER_SIZE;
        mts_fuzz_put_u32(f + info + table - 4, mts_crc32c(0, f, (size_t)(info + table - 4)));
    }
    mts_stream_file_index idx;
    mts_error err = {0};
    if (mts_stream_file_index_parse(file, size, 0, &idx, &err) == MTS_OK) {
        if (idx.base_offset < size)
            mts_fuzz_fix_stream_crcs(file + idx.base_offset,
                                     (size_t)(idx.base_size < size - idx.base_offset
                                                  ? idx.base_size
                                                  : size - idx.base_offset));
        if (idx.checks_offset + idx.checks_size <= size) {
            uint8_t *ck = file + idx.checks_offset;
            const size_t body = (size_t)idx.checks_size - 4;
            mts_fuzz_put_u32(ck + body, mts_crc32c(0, ck, body));
        }
        if (idx.batch_offset[0] < size)
            mts_fuzz_fix_stream_crcs(file + idx.batch_offset[0],
                                     size - (size_t)idx.batch_offset[0]);
    }
    mts_stream_file_index_free(&idx);
}

/* *ends, *tried (when not NULL): conversations that ended with END, and
 * those started (the regression test checks that intact seeds end every
 * one). */
int mts_fuzz_stream_file_ends(const uint8_t *data, size_t size, int *ends, int *tried)
{
    if (ends)
        *ends = 0;
    if (tried)
        *tried = 0;
    if (size < 1 + MTS_FUZZ_SF_STOPS)
        return 0;
    const uint8_t mode = data[0];
    const uint8_t *stops = data + 1;
    size -= 1 + MTS_FUZZ_SF_STOPS;
    /* an exact-size copy, so ASan sees any read past the input */
    uint8_t *file = malloc(size ? size : 1);
    MTS_FUZZ_CHECK(file != NULL);
    memcpy(file, data + 1 + MTS_FUZZ_SF_STOPS, size);
    if (!(mode & 1))
        mts_fuzz_sf_fix_crcs(file, size);
    const unsigned split = (mode >> 1) & 15;
    mts_fuzz_sf f = {file, size, split ? (size_t)1 << split : (size ? size : 1),
                     mode * 0x9e3779b97f4a7c15ull + 1, 0};
    const uint64_t cap = (mode & 0x20) ? size : 0;

    /* the first request's bytes, then the whole prefix: both say the same */
    mts_error err = {0};
    uint64_t prefix = 0;
    mts_result prc = mts_stream_file_prefix_size(file, size < MTS_SFILE_FIRST_REQUEST
                                                           ? size
                                                           : MTS_SFILE_FIRST_REQUEST,
                                                 cap, &prefix, &err);
    MTS_FUZZ_CHECK(prc == MTS_OK ? prefix > MTS_SFILE_HEADER_SIZE : err.msg[0] != 0);
    mts_stream_file_index idx;
    err = (mts_error){0};
    mts_result rc = mts_stream_file_index_parse(file, size, cap, &idx, &err);
    int tries = 0;
    if (rc != MTS_OK) {
        MTS_FUZZ_CHECK(err.msg[0] != 0 && err.code == rc);
    } else {
        MTS_FUZZ_CHECK(prc == MTS_OK && idx.prefix_size == prefix && prefix <= size);
        MTS_FUZZ_CHECK(!cap || idx.file_size <= cap);
        MTS_FUZZ_CHECK(idx.batch_count == idx.info.batch_count);
        MTS_FUZZ_CHECK(idx.base_offset == prefix &&
                       idx.checks_offset == idx.base_offset + idx.base_size);
        uint64_t prev = idx.checks_offset + idx.checks_size;
        for (uint32_t k = 0; k <= idx.batch_count; k++) {
            MTS_FUZZ_CHECK(idx.batch_offset[k] >= prev);
            prev = idx.batch_offset[k];
        }
        MTS_FUZZ_CHECK(idx.batch_offset[idx.batch_count] == idx.file_size);
        for (int i = 0; i < MTS_FUZZ_SF_STOPS; i++) {
            mts_fuzz_sf_conversation(&f, &idx, stops, i, mode);
            tries++;
        }
    }
    mts_stream_file_index_free(&idx);
    free(file);
    if (ends)
        *ends = f.ends;
    if (tried)
        *tried = tries;
    return 0;
}

int mts_fuzz_stream_file(const uint8_t *data, size_t size)
{
    return mts_fuzz_stream_file_ends(data, size, NULL, NULL);
}

#ifndef MTS_FUZZ_NO_ENTRY
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return mts_fuzz_stream_file(data, size);
}
#endif
