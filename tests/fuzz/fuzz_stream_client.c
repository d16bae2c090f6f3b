/* Fuzz target: the client's stream decoder. The input is what a server sends,
 * fed through the incremental wire reader into an mts_stream_client exactly as
 * client/session.c does, in pieces, over one or more connections.
 *
 * Input: one mode byte, then the server->client bytes.
 *   bit 0     1: leave the frames' CRCs as they are; 0: rewrite the CRC of
 *             every BASE and BATCH frame first, so that mutations reach the
 *             Draco, strip and record decoders behind it
 *   bits 1-5  k: 0 feeds all bytes at once; else pieces of 1 .. 2^(k % 17)
 *             bytes from a generator seeded with the mode, so frames arrive
 *             split anywhere, as from a socket
 *   bit 6     with bit 7: a connection that breaks leaves the whole frames
 *             it did not take in the reader (a session's backlog), some
 *             decoded ahead, for reconnected to deal with; without it every
 *             whole frame is taken before the break
 *   bit 7     1: the decoder on two threads, fed through its own reader
 *             (mts_stream_client_feed/next) so that it decodes whole
 *             batches ahead, taking 1 to 4 frames a piece as a session's
 *             time slice does
 * MTS_FUZZ_CUT (8 bytes) in the bytes is a broken connection: what follows is
 * the next connection's, which the client resumes as session.c does
 * (mts_stream_client_resume_point, then mts_stream_client_reconnected and a
 * new frame reader), so a frame cut by the break is dropped with it.
 * After the stream, a client that holds a runtime moves it to level 0 and back
 * up to what it received, as a viewer's level control does: collapses trust
 * the records the splits checked, so this checks that trust too. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fuzz_util.h"
#include "stream.h"
#include "wire.h"

static void mts_fuzz_on_model(void *user, const mts_wire_model_entry *m)
{
    size_t *count = user;
    MTS_FUZZ_CHECK(mts_wire_valid_name(m->name, strlen(m->name)));
    ++*count;
}

/* One event's checks; 1 when it ends the conversation. */
static int mts_fuzz_event(mts_stream_client *c, mts_stream_event ev, int *ended)
{
    if (ev == MTS_EV_BASE || ev == MTS_EV_BATCH) {
        MTS_FUZZ_CHECK(c->have_lod);
        MTS_FUZZ_CHECK(c->lod.level <= c->stop_level && c->lod.level <= c->splits);
    }
    if (ev == MTS_EV_END || ev == MTS_EV_MODELS)
        *ended = 1;
    return ev == MTS_EV_END || ev == MTS_EV_MODELS || ev == MTS_EV_ERROR;
}

/* One connection's bytes into the client's own reader (two threads): each
 * piece fed, then at most 1 to 4 frames taken, so whole frames wait in the
 * reader, some decoded ahead; at the end every whole frame is taken, but
 * for a `backlog` break. */
static int mts_fuzz_connection_fed(mts_stream_client *c, const uint8_t *bytes, size_t size,
                                   size_t max_piece, uint64_t *seed, int *ended, int backlog)
{
    mts_error err = {0};
    int done = 0, failed = 0;
    size_t at = 0;
    const int last = !backlog;
    while (!done && !failed && (at < size || last)) {
        *seed = *seed * 6364136223846793005ull + 1442695040888963407ull;
        size_t piece = 1 + (size_t)((*seed >> 33) % max_piece);
        if (piece > size - at)
            piece = size - at;
        if (piece && mts_stream_client_feed(c, bytes + at, piece, &err) != MTS_OK) {
            MTS_FUZZ_CHECK(err.msg[0] != 0);
            failed = 1;
            break;
        }
        at += piece;
        unsigned budget = at < size || !last ? 1 + (unsigned)((*seed >> 20) % 4) : ~0u;
        int got = 0;
        for (; budget && !done; budget--) {
            mts_stream_event ev;
            if ((got = mts_stream_client_next(c, &ev, &err)) <= 0)
                break;
            done = mts_fuzz_event(c, ev, ended);
        }
        if (got < 0) {
            MTS_FUZZ_CHECK(err.msg[0] != 0);
            failed = 1;
        }
        if (at == size && (got == 0 || !last))
            break;
    }
    return done || failed;
}

/* One connection's bytes through a new frame reader; returns 1 when the
 * conversation ended (END, MODELS, ERROR, or a refusal: nothing to resume). */
static int mts_fuzz_connection(mts_stream_client *c, const uint8_t *bytes, size_t size,
                               size_t max_piece, uint64_t *seed, int *ended)
{
    mts_wire_reader r = {0};
    mts_error err = {0};
    mts_result rc = MTS_OK;
    int done = 0;
    size_t at = 0;
    while (at < size && rc == MTS_OK && !done) {
        *seed = *seed * 6364136223846793005ull + 1442695040888963407ull;
        size_t piece = 1 + (size_t)((*seed >> 33) % max_piece);
        if (piece > size - at)
            piece = size - at;
        if ((rc = mts_wire_reader_feed(&r, bytes + at, piece, &err)) != MTS_OK)
            break;
        at += piece;
        uint8_t type;
        const uint8_t *p;
        size_t n;
        int next;
        while (rc == MTS_OK && !done && (next = mts_wire_reader_next(&r, &type, &p, &n, &err)) != 0) {
            if (next < 0) {
                rc = MTS_ERR_FORMAT;
                MTS_FUZZ_CHECK(err.msg[0] != 0);
                break;
            }
            mts_stream_event ev;
            rc = mts_stream_client_frame(c, type, p, n, &ev, &err);
            if (rc != MTS_OK) {
                /* every refusal names its reason */
                MTS_FUZZ_CHECK(err.msg[0] != 0 && err.code == rc);
                break;
            }
            done = mts_fuzz_event(c, ev, ended);
        }
    }
    mts_wire_reader_free(&r);
    /* session.c resumes only after a broken connection, never after a refusal */
    return done || rc != MTS_OK;
}

/* *ended (when not NULL): whether the stream reached END (or a listing its
 * end), for the regression test's check that intact seeds do. */
int mts_fuzz_stream_client_ended(const uint8_t *data, size_t size, int *ended)
{
    int end_seen = 0;
    if (ended)
        *ended = 0;
    if (size < 1)
        return 0;
    const uint8_t mode = data[0];
    size--;
    /* an exact-size copy, so ASan sees any read past the input */
    uint8_t *bytes = malloc(size ? size : 1);
    MTS_FUZZ_CHECK(bytes != NULL);
    memcpy(bytes, data + 1, size);
    const unsigned split = (mode >> 1) & 31;
    const size_t max_piece = split ? (size_t)1 << (split % 17) : (size ? size : 1);
    uint64_t seed = mode * 0x9e3779b97f4a7c15ull + 1;

    mts_stream_client c;
    mts_stream_client_init(&c);
    c.threads = mode & 0x80 ? 2 : 1;
    size_t listed = 0;
    c.on_model = mts_fuzz_on_model;
    c.user = &listed;
    mts_error err = {0};
    size_t at = 0;
    int cont = 0; /* the last connection ended with END: the next one continues it */
    for (int first = 1;; first = 0) {
        const uint8_t *cut = at < size ? mts_fuzz_find_cut(bytes + at, size - at) : NULL;
        size_t len = cut ? (size_t)(cut - (bytes + at)) : size - at;
        if (!first && cont) {
            /* a preview asking for more (PROTOCOL.md, "Continuing") */
            uint32_t batch;
            uint64_t id;
            if (mts_stream_client_continue(&c, &batch, &id, &err) != MTS_OK) {
                MTS_FUZZ_CHECK(err.msg[0] != 0);
                break;
            }
            MTS_FUZZ_CHECK(batch == c.batches && id == c.info.stream_id);
        } else if (!first) {
            uint32_t batch;
            uint64_t id;
            if (!mts_stream_client_resume_point(&c, &batch, &id))
                break;
            /* two threads also count the batches they decoded ahead */
            MTS_FUZZ_CHECK(batch == 0 || (c.have_lod && batch >= c.batches && id == c.info.stream_id));
            if (mts_stream_client_reconnected(&c, &err) != MTS_OK) {
                MTS_FUZZ_CHECK(err.msg[0] != 0);
                break;
            }
            /* ... which reconnected applied */
            MTS_FUZZ_CHECK(batch == 0 || !c.have_lod || c.batches == batch);
        }
        if (!(mode & 1))
            mts_fuzz_fix_stream_crcs(bytes + at, len);
        int stopped = c.threads > 1 ? mts_fuzz_connection_fed(&c, bytes + at, len, max_piece,
                                                              &seed, &end_seen,
                                                              cut && (mode & 0x40))
                                    : mts_fuzz_connection(&c, bytes + at, len, max_piece, &seed,
                                                          &end_seen);
        if (!cut)
            break;
        /* after END more bytes are a continuation; after a refusal, nothing */
        cont = stopped && c.have_lod && c.end_checksum && c.checksum == c.end_checksum &&
               !c.lod.broken;
        if (stopped && !cont)
            break;
        at += len + MTS_FUZZ_CUT_SIZE;
    }
    if (c.have_lod && !c.lod.broken) {
        /* everything a runtime holds is a checked split: down and up again
         * must work and land on the same strips */
        uint32_t top = c.lod.level;
        uint64_t before = mts_stream_checksum(&c.lod, c.quantized);
        MTS_FUZZ_CHECK(mts_lod_set_level(&c.lod, 0, &err) == MTS_OK);
        MTS_FUZZ_CHECK(mts_lod_set_level(&c.lod, top, &err) == MTS_OK);
        MTS_FUZZ_CHECK(c.lod.level == top);
        MTS_FUZZ_CHECK(mts_stream_checksum(&c.lod, c.quantized) == before);
    }
    mts_stream_client_free(&c);
    free(bytes);
    if (ended)
        *ended = end_seen;
    return 0;
}

int mts_fuzz_stream_client(const uint8_t *data, size_t size)
{
    return mts_fuzz_stream_client_ended(data, size, NULL);
}

#ifndef MTS_FUZZ_NO_ENTRY
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return mts_fuzz_stream_client(data, size);
}
#endif
