/* The stream client's decoder on threads (c->threads, docs/threads.md)
 * against one thread, on cow, bunny00 and fandisk_large:
 *  - at 2 threads and at 4 cut at their keys (threads_at_keys), fed whole
 *    and in small random pieces, and at 4 not cut (which decode as 2), every record
 *    (offsets, words, parents), every vertex and the strips are the
 *    one-thread decode's byte for byte; after each batch the runtime is at
 *    that batch's level with the server's checksum (a batch is applied
 *    before its frame returns, whatever the threads); the strips are
 *    compared at every level of cow and at the keys, the batches' ends and
 *    evenly spaced levels of the others; likewise cow with every fourth
 *    split explicit (triangle ids, mapped through the keys' renumberings);
 *  - a conversation broken after a batch resumes on the same threads, and
 *    a preview continued past its stop goes on with them;
 *  - a batch damaged after its CRC was taken fails the client at every
 *    thread count, and freeing it stops its threads;
 *  - mts-client --threads 1 and --threads 4 print the same checksum for
 *    cow over loopback, and --json reports the threads used (2 for 4)
 *    and asked; mts-stress's
 *    clients decode on two threads each (--decode-threads). */
#include <libgen.h>
#include <signal.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include "build.h"
#include "crc32c.h"
#include "grow.h"
#include "mesh.h"
#include "stream.h"
#include "test.h"
#include "test_proc.h"
#include "varint.h"
#include "wire.h"
#include "words.h"

static char bin_dir[512];

/* Rewrites m's split descriptions so that every `every`-th split but the
 * full level's names its triangles (one grow's ids, as a stream does), the
 * fans of the others coded again against a grow that took those, whose
 * records m then holds. No builder makes explicit splits yet, and with
 * threads the decoder maps their ids through the keys' renumberings. */
static int make_explicit(mts_test *t, mts_model *m, uint32_t every)
{
    mts_error err = {0};
    const uint32_t n = m->level_count, nb = m->base_vertex_count;
    const mts_grow_options go = {.key_levels = m->key_levels, .key_count = m->key_count};
    const mts_grow_full given = {.strips = &m->full, .slot_count = m->strip_count};
    mts_grow *fan = NULL, *g = NULL;
    uint32_t *off = calloc((size_t)n + 1, 4), *roff = calloc((size_t)n + 1, 4);
    mts_words data = {0}, rec = {0}, moved = {0};
    int ok = off && roff &&
             mts_grow_create(&m->base, nb, n, &go, &fan, &err) == MTS_OK &&
             mts_grow_create(&m->base, nb, n, &go, &g, &err) == MTS_OK;
    uint32_t explicit = 0;
    for (uint32_t j = 0; ok && j < n; j++) {
        mts_grow_split sp;
        const uint32_t *r;
        uint32_t rw;
        if (!mts_grow_model_split(fan, m, j, &sp)) {
            ok = 0;
            break;
        }
        const uint32_t u = sp.parent, v = nb + j;
        mts_grow_split xs = sp;
        uint32_t born[6], nborn = 0;
        off[j] = (uint32_t)data.n;
        if (j % every == every - 1 && j + 1 < n) {
            if (sp.left != MTS_GROW_NONE) {
                born[3 * nborn] = u, born[3 * nborn + 1] = v, born[3 * nborn + 2] = sp.left;
                nborn++;
            }
            if (sp.right != MTS_GROW_NONE) {
                born[3 * nborn] = v, born[3 * nborn + 1] = u, born[3 * nborn + 2] = sp.right;
                nborn++;
            }
            const int32_t k = mts_grow_fan(g, u, sp.left, sp.right, NULL, 0);
            moved.n = 0;
            ok = k > 0 && mts_words_reserve(&moved, (size_t)k) &&
                 mts_grow_fan(g, u, sp.left, sp.right, moved.w, (uint32_t)k) == k &&
                 mts_words_reserve(&data, 5 + (size_t)k + 3 * nborn);
            if (!ok)
                break;
            uint32_t *w = data.w + data.n;
            w[0] = w[1] = 0;
            w[2] = MTS_GROWTH_EXPLICIT;
            w[3] = (uint32_t)k;
            w[4] = nborn;
            memcpy(w + 5, moved.w, (size_t)k * 4);
            memcpy(w + 5 + k, born, (size_t)nborn * 12);
            data.n += 5 + (size_t)k + 3 * nborn;
            xs = (mts_grow_split){u, MTS_GROW_NONE, MTS_GROW_NONE, (uint32_t)k, moved.w, nborn,
                                  born};
            explicit++;
        } else {
            mts_grow_fan_code fc;
            ok = mts_grow_fan_encode(g, u, sp.left, sp.right, &fc) &&
                 mts_words_reserve(&data, 3);
            if (!ok)
                break;
            data.w[data.n++] = fc.start;
            data.w[data.n++] = fc.count;
            data.w[data.n++] = fc.sides;
        }
        ok = mts_grow_next(g, &xs, &given, &r, &rw, &err) == MTS_OK &&
             mts_words_reserve(&rec, rw);
        if (!ok)
            break;
        memcpy(rec.w + rec.n, r, (size_t)rw * 4);
        rec.n += rw;
        roff[j + 1] = (uint32_t)rec.n;
        ok = mts_grow_next(fan, &sp, &given, &r, &rw, &err) == MTS_OK;
    }
    CHECKF(t, ok && explicit > 0, "explicit splits: %u made: %s", explicit, err.msg);
    if (ok) {
        off[n] = (uint32_t)data.n;
        free(m->growth_offsets);
        free(m->growth_data);
        free(m->record_offsets);
        free(m->record_data);
        m->growth_offsets = off;
        m->growth_data = data.w;
        m->growth_word_count = (uint32_t)data.n;
        m->record_offsets = roff;
        m->record_data = rec.w;
        m->record_word_count = (uint32_t)rec.n;
    } else {
        free(off);
        free(roff);
        free(data.w);
        free(rec.w);
    }
    free(moved.w);
    mts_grow_free(fan);
    mts_grow_free(g);
    return ok;
}

static int build_stream(mts_test *t, const char *path, const char *name, uint32_t explicit_every,
                        mts_stream *s)
{
    mts_error err = {0};
    mts_mesh mesh = {0};
    mts_model m;
    if (mts_mesh_load(path, NULL, &mesh, NULL, &err) != MTS_OK) {
        CHECKF(t, 0, "load %s: %s", path, err.msg);
        return 0;
    }
    mts_result rc = mts_build_model(&mesh, path, NULL, &m, NULL, &err);
    mts_mesh_free(&mesh);
    CHECKF(t, rc == MTS_OK, "build %s: %s", path, err.msg);
    if (rc != MTS_OK)
        return 0;
    if (explicit_every && !make_explicit(t, &m, explicit_every)) {
        mts_model_free(&m);
        return 0;
    }
    rc = mts_stream_build(&m, name, NULL, s, &err);
    mts_model_free(&m);
    CHECKF(t, rc == MTS_OK, "stream %s: %s", name, err.msg);
    return rc == MTS_OK;
}

/* MODEL_INFO, the batches from `from` (BASE first when 0) to the full
 * level, END. */
static void conversation(const mts_stream *s, uint32_t from, mts_buf *out)
{
    mts_error err = {0};
    const uint32_t stop = s->model.level_count;
    size_t off, len;
    out->size = 0;
    mts_stream_put_model_info(s, stop, out);
    if (mts_stream_range(s, from, stop, &off, &len, &err) != MTS_OK)
        return;
    mts_buf_put(out, s->bytes + off, len);
    mts_stream_put_end(s, stop, (uint32_t)out->size, out);
}

typedef struct fed {
    uint32_t batches, bad_levels, bad_checksums;
    int ended;
} fed;

/* Takes every whole frame buffered; after each batch, the runtime must be
 * at the batch's level with the server's checksum there. */
static int take_frames(mts_stream_client *c, const mts_stream *s, fed *f, mts_error *err)
{
    mts_stream_event ev;
    int got;
    while ((got = mts_stream_client_next(c, &ev, err)) > 0) {
        if (ev == MTS_EV_BATCH) {
            f->batches++;
            f->bad_levels += c->lod.level != c->splits;
            f->bad_checksums +=
                mts_stream_checksum_colors(&c->lod, c->quantized, c->model.colors) !=
                s->level_checksum[c->lod.level];
        }
        f->ended |= ev == MTS_EV_END;
    }
    return got;
}

/* Feeds b into c in pieces of 1..max_piece bytes from seed (max_piece 0:
 * whole). */
static mts_result feed(mts_stream_client *c, const mts_stream *s, const mts_buf *b,
                       uint64_t seed, size_t max_piece, fed *f, mts_error *err)
{
    size_t at = 0;
    while (at < b->size) {
        size_t piece = b->size - at;
        if (max_piece) {
            seed = seed * 6364136223846793005ull + 1442695040888963407ull;
            piece = 1 + (size_t)((seed >> 33) % max_piece);
            if (piece > b->size - at)
                piece = b->size - at;
        }
        mts_result rc = mts_stream_client_feed(c, b->data + at, piece, err);
        if (rc != MTS_OK)
            return rc;
        at += piece;
        if (take_frames(c, s, f, err) < 0)
            return err->code ? err->code : MTS_ERR_INTERNAL;
    }
    return MTS_OK;
}

/* Whether a and b draw the same strips now, slot by slot. */
static int same_strips(const mts_stream_client *a, const mts_stream_client *b)
{
    for (uint32_t st = 0; st < a->model.strip_count; st++) {
        uint32_t la, lb;
        const uint32_t *x = mts_lod_strip(&a->lod, st, &la), *y = mts_lod_strip(&b->lod, st, &lb);
        if (la != lb || (la && memcmp(x, y, (size_t)la * 4) != 0))
            return 0;
    }
    return 1;
}

static int is_key(const mts_stream_client *c, uint32_t level)
{
    for (uint32_t k = 0; k < c->info.key_count; k++) {
        if (c->info.key_levels[k] == level)
            return 1;
    }
    return 0;
}

/* c (threads) against one (one thread), both at the full level: records,
 * parents, vertices, and the strips at the levels compared (every one with
 * every_level); both end back at the full level. */
static void compare(mts_test *t, const char *what, const mts_stream *s, mts_stream_client *one,
                    mts_stream_client *c, int every_level)
{
    mts_error err = {0};
    const mts_model *a = &one->model, *b = &c->model;
    const uint32_t n = a->level_count, nv = a->base_vertex_count + n;
    /* the decoder may go on alone where the threads share a core (a busy
     * test machine): the records are the same either way */
    CHECKF(t, c->threads_ran > 1, "%s: the threads did not start", what);
    CHECKF(t,
           b->record_word_count == a->record_word_count &&
               memcmp(b->record_offsets, a->record_offsets, ((size_t)n + 1) * 4) == 0 &&
               memcmp(b->record_data, a->record_data, (size_t)a->record_word_count * 4) == 0,
           "%s: the records differ (%u words, one thread %u)", what, b->record_word_count,
           a->record_word_count);
    CHECKF(t, memcmp(b->parents, a->parents, (size_t)n * 4) == 0, "%s: the parents differ", what);
    CHECKF(t,
           memcmp(b->positions, a->positions, (size_t)nv * 12) == 0 &&
               memcmp(c->quantized, one->quantized, (size_t)nv * 12) == 0,
           "%s: the vertices differ", what);
    CHECKF(t, c->checksum == one->checksum && c->checksum == s->level_checksum[n],
           "%s: checksum %016llx, one thread %016llx", what, (unsigned long long)c->checksum,
           (unsigned long long)one->checksum);
    uint32_t compared = 0, bad = 0, at_batch = 0;
    for (uint32_t level = 0; level <= n && bad < 3; level++) {
        int here = every_level || level == n || is_key(one, level) || is_key(one, level + 1) ||
                   level % (n / 64 + 1) == 0;
        while (at_batch < s->batch_count && s->batch_first[at_batch + 1] < level)
            at_batch++;
        here |= at_batch < s->batch_count && s->batch_first[at_batch + 1] == level;
        if (!here)
            continue;
        if (mts_lod_set_level(&one->lod, level, &err) != MTS_OK ||
            mts_lod_set_level(&c->lod, level, &err) != MTS_OK) {
            CHECKF(t, 0, "%s: level %u: %s", what, level, err.msg);
            break;
        }
        compared++;
        if (!same_strips(one, c) ||
            mts_stream_checksum(&c->lod, c->quantized) != s->level_checksum[level]) {
            CHECKF(t, 0, "%s: the strips differ at level %u", what, level);
            bad++;
        }
    }
    CHECKF(t, bad == 0 && compared > 0, "%s: %u levels compared", what, compared);
}

/* One model's stream: one thread, then 2 and 4 cut at their keys, whole
 * and in pieces, and 4 not cut, which decode as 2. */
static void model_threads(mts_test *t, const char *path, const char *name, size_t piece,
                          int every_level, uint32_t explicit_every)
{
    mts_stream s;
    if (!build_stream(t, path, name, explicit_every, &s))
        return;
    mts_buf b = {0};
    conversation(&s, 0, &b);
    mts_error err = {0};
    mts_stream_client one;
    mts_stream_client_init(&one);
    fed f1 = {0};
    CHECKF(t, feed(&one, &s, &b, 0, 0, &f1, &err) == MTS_OK && f1.ended, "%s: %s", name,
           err.msg);
    CHECKF(t, one.par == NULL && f1.bad_levels == 0 && f1.bad_checksums == 0 &&
                  f1.batches == s.batch_count,
           "%s: one thread: %u batches, %u at the wrong level, %u checksums", name, f1.batches,
           f1.bad_levels, f1.bad_checksums);
    CHECKF(t, one.info.key_count > 0, "%s: no key levels", name);
    CHECK(t, mts_stream_client_threads_used(&one) == 1);
    const uint32_t threads[3] = {2, 4, 4};
    const int at_keys[3] = {0, 1, 0};
    for (int k = 0; k < 3 && !t->case_failed; k++) {
        /* pieces 2: two threads, then one from a third of the batches on
         * (as where the threads turn out to share a core) */
        /* pieces 3: two threads, every key's paths made by the decode
         * thread and taken by the pool, as where the pool is well behind */
        for (int pieces = 0; pieces < (k == 0 ? 4 : 2 - (k == 2)) && !t->case_failed; pieces++) {
            char what[96];
            snprintf(what, sizeof what, "%s, %u threads%s, %s", name, threads[k],
                     at_keys[k] ? " at keys" : "",
                     pieces == 3   ? "whole, every key's paths handed across"
                     : pieces == 2 ? "whole, alone after a third"
                     : pieces      ? "small pieces"
                                   : "whole");
            mts_stream_client c;
            mts_stream_client_init(&c);
            c.threads = threads[k];
            c.threads_at_keys = at_keys[k];
            if (pieces == 2)
                c.threads_alone_after = s.batch_count / 3 + 1;
            c.threads_hand_key_paths = pieces == 3;
            fed f = {0};
            mts_result rc =
                feed(&c, &s, &b, 7 + (uint64_t)k, pieces == 1 ? piece : 0, &f, &err);
            CHECKF(t, rc == MTS_OK && f.ended, "%s: %s", what, err.msg);
            CHECKF(t, f.batches == s.batch_count && f.bad_levels == 0 && f.bad_checksums == 0,
                   "%s: %u batches, %u at the wrong level, %u checksums", what, f.batches,
                   f.bad_levels, f.bad_checksums);
            if (rc == MTS_OK)
                compare(t, what, &s, &one, &c, every_level && pieces != 1);
            const uint32_t used = at_keys[k] ? threads[k] : 2;
            CHECKF(t, mts_stream_client_threads_used(&c) == used, "%s: %u threads used, not %u",
                   what, mts_stream_client_threads_used(&c), used);
            if (pieces == 2)
                CHECKF(t,
                       c.par == NULL && c.threads_alone_from ==
                                            mts_wire_batch_first(&c.info, s.batch_count / 3 + 1),
                       "%s: alone from level %u", what, c.threads_alone_from);
            if (pieces == 3)
                CHECKF(t, c.threads_key_paths_handed, "%s: the pool made its own", what);
            mts_stream_client_free(&c);
        }
    }
    mts_stream_client_free(&one);
    mts_buf_free(&b);
    mts_stream_free(&s);
}

static void test_cow(mts_test *t)
{
    model_threads(t, "tests/data/cow.off", "cow", 97, 1, 0);
}

static void test_bunny(mts_test *t)
{
    char buf[1024];
    const char *path = mts_test_model("bunny00.off", buf, sizeof buf);
    if (!path)
        SKIP(t, "%s not found", buf);
    model_threads(t, path, "bunny00", 977, 0, 0);
}

static void test_fandisk(mts_test *t)
{
    char buf[1024];
    const char *path = mts_test_model("fandisk_large.off", buf, sizeof buf);
    if (!path)
        SKIP(t, "%s not found", buf);
    model_threads(t, path, "fandisk_large", 977, 0, 0);
}

/* cow with every fourth split explicit: the ids a split names are one
 * grow's, which the decode thread's mesh-only grow maps through every
 * key's renumbering so far (from the workers, or from the one grow on two
 * threads) */
static void test_explicit(mts_test *t)
{
    model_threads(t, "tests/data/cow.off", "cow-explicit", 97, 1, 4);
}

/* A conversation cut after a third of the batches, resumed: the threads
 * go on where they were. */
static void test_resume(mts_test *t)
{
    mts_stream s;
    if (!build_stream(t, "tests/data/cow.off", "cow", 0, &s))
        return;
    mts_error err = {0};
    mts_buf whole = {0}, first = {0}, rest = {0};
    conversation(&s, 0, &whole);
    mts_stream_client one, c;
    mts_stream_client_init(&one);
    fed f1 = {0}, f = {0};
    CHECK(t, feed(&one, &s, &whole, 0, 0, &f1, &err) == MTS_OK && f1.ended);
    uint32_t batch;
    uint64_t id;
    /* MODEL_INFO, BASE and the first third of the batches, and half a batch */
    mts_stream_put_model_info(&s, s.model.level_count, &first);
    const uint32_t cut = s.batch_count / 3;
    mts_buf_put(&first, s.bytes, s.batch_offset[cut] + 9);
    /* on three threads cut at their keys; on two gone on alone before the
     * cut; on two going on alone after the resume */
    const uint32_t threads[3] = {3, 2, 2}, alone[3] = {0, cut / 2 + 1, cut + 2};
    for (int k = 0; k < 3; k++) {
        char what[64];
        snprintf(what, sizeof what, "cow resumed, %u threads, alone after %u", threads[k],
                 alone[k]);
        mts_stream_client_init(&c);
        c.threads = threads[k];
        c.threads_at_keys = threads[k] > 2;
        c.threads_alone_after = alone[k];
        f = (fed){0};
        CHECKF(t, feed(&c, &s, &first, 5, 61, &f, &err) == MTS_OK && !f.ended, "%s: %s", what,
               err.msg);
        CHECK(t, mts_stream_client_resume_point(&c, &batch, &id) && batch == cut);
        CHECK(t, mts_stream_client_reconnected(&c, &err) == MTS_OK && c.threads == threads[k] &&
                     c.threads_at_keys == (threads[k] > 2) && c.threads_alone_after == alone[k]);
        conversation(&s, batch, &rest);
        CHECKF(t, feed(&c, &s, &rest, 6, 61, &f, &err) == MTS_OK && f.ended, "%s: %s", what,
               err.msg);
        CHECKF(t, f.batches == s.batch_count && f.bad_levels == 0 && f.bad_checksums == 0,
               "%s: %u batches, %u at the wrong level, %u checksums", what, f.batches,
               f.bad_levels, f.bad_checksums);
        CHECKF(t, !alone[k] || c.threads_alone_from == mts_wire_batch_first(&c.info, alone[k]),
               "%s: alone from level %u", what, c.threads_alone_from);
        if (f.ended)
            compare(t, what, &s, &one, &c, 0);
        mts_stream_client_free(&c);
    }
    /* two threads cut while batches decoded ahead wait in the reader,
     * untaken: the resume goes on after them (no switch to one thread, so
     * that decoding ahead is not turned off by a measure) */
    mts_stream_client_init(&c);
    c.threads = 2;
    c.threads_alone_after = UINT32_MAX;
    f = (fed){0};
    CHECK(t, mts_stream_client_feed(&c, first.data, first.size, &err) == MTS_OK);
    mts_stream_event ev;
    while (f.batches < cut / 2 && mts_stream_client_next(&c, &ev, &err) > 0)
        f.batches += ev == MTS_EV_BATCH;
    CHECKF(t, f.batches == cut / 2 && c.batches == cut / 2, "cut ahead: %u batches: %s",
           f.batches, err.msg);
    /* the resume point is the same before the reconnection as after it */
    uint32_t before = 0;
    CHECK(t, mts_stream_client_resume_point(&c, &before, &id));
    CHECKF(t, mts_stream_client_reconnected(&c, &err) == MTS_OK, "cut ahead: %s", err.msg);
    CHECK(t, mts_stream_client_resume_point(&c, &batch, &id) && batch == before);
    CHECKF(t, batch > cut / 2 && batch <= cut && c.lod.level == c.splits &&
                  mts_stream_checksum_colors(&c.lod, c.quantized, c.model.colors) ==
                      s.level_checksum[c.lod.level],
           "cut ahead: resumes at batch %u of %u taken, level %u", batch, cut / 2, c.lod.level);
    conversation(&s, batch, &rest);
    f = (fed){0};
    CHECKF(t, feed(&c, &s, &rest, 0, 0, &f, &err) == MTS_OK && f.ended, "cut ahead: %s",
           err.msg);
    CHECKF(t, f.bad_levels == 0 && f.bad_checksums == 0, "cut ahead: %u levels, %u checksums",
           f.bad_levels, f.bad_checksums);
    if (f.ended)
        compare(t, "cow cut with batches decoded ahead, 2 threads", &s, &one, &c, 0);
    mts_stream_client_free(&c);
    /* a preview to a third of the levels, continued to the full level */
    const uint32_t stop = s.model.level_count / 3;
    size_t off, len;
    first.size = 0;
    mts_stream_put_model_info(&s, stop, &first);
    CHECK(t, mts_stream_range(&s, 0, stop, &off, &len, &err) == MTS_OK);
    mts_buf_put(&first, s.bytes + off, len);
    mts_stream_put_end(&s, stop, (uint32_t)first.size, &first);
    mts_stream_client_init(&c);
    c.threads = 2;
    f = (fed){0};
    CHECKF(t, feed(&c, &s, &first, 8, 0, &f, &err) == MTS_OK && f.ended && c.lod.level == stop,
           "preview: %s", err.msg);
    CHECKF(t, mts_stream_client_continue(&c, &batch, &id, &err) == MTS_OK, "%s", err.msg);
    conversation(&s, batch, &rest);
    f.ended = 0;
    CHECKF(t, feed(&c, &s, &rest, 0, 0, &f, &err) == MTS_OK && f.ended, "continued: %s", err.msg);
    if (f.ended)
        compare(t, "cow continued, 2 threads", &s, &one, &c, 0);
    mts_stream_client_free(&c);
    mts_stream_client_free(&one);
    mts_buf_free(&whole);
    mts_buf_free(&first);
    mts_buf_free(&rest);
    mts_stream_free(&s);
}

/* A batch past the first whose coded splits are damaged, its CRC resealed:
 * refused at every thread count, and the client frees its threads. */
static void test_damaged_batch(mts_test *t)
{
    mts_stream s;
    if (!build_stream(t, "tests/data/cow.off", "cow", 0, &s))
        return;
    mts_buf b = {0};
    conversation(&s, 0, &b);
    /* the frame of batch batch_count / 2 */
    size_t at = 0;
    uint32_t seen = 0;
    const uint32_t target = s.batch_count / 2;
    while (at + 5 < b.size) {
        size_t flen = b.data[at] | b.data[at + 1] << 8 | b.data[at + 2] << 16 |
                      (size_t)b.data[at + 3] << 24;
        if (b.data[at + 4] == MTS_MSG_BATCH && seen++ == target)
            break;
        at += 4 + flen;
    }
    size_t flen = b.data[at] | b.data[at + 1] << 8 | b.data[at + 2] << 16 |
                  (size_t)b.data[at + 3] << 24;
    uint8_t *pl = b.data + at + 5;
    CHECK(t, flen > 40);
    for (size_t k = flen / 3; k < flen / 3 + 8; k++)
        pl[k] ^= 0x5a;
    uint32_t crc = mts_crc32c(0, pl, flen - 1 - 4);
    for (int k = 0; k < 4; k++)
        pl[flen - 1 - 4 + k] = (uint8_t)(crc >> (8 * k));
    const uint32_t threads[3] = {1, 2, 4};
    mts_result first_rc = MTS_OK;
    char first_msg[sizeof(((mts_error *)0)->msg)] = "";
    for (int k = 0; k < 3; k++) {
        mts_stream_client c;
        mts_stream_client_init(&c);
        c.threads = threads[k];
        c.threads_at_keys = threads[k] > 2;
        mts_error err = {0};
        fed f = {0};
        mts_result rc = feed(&c, &s, &b, 3, 0, &f, &err);
        CHECKF(t, rc != MTS_OK && !f.ended && f.batches == target &&
                      strncmp(err.msg, "BATCH ", 6) == 0,
               "%u threads: %s after %u batches", threads[k], err.msg, f.batches);
        if (k == 0) {
            first_rc = rc;
            snprintf(first_msg, sizeof first_msg, "%s", err.msg);
        }
        CHECKF(t, rc == first_rc && strcmp(err.msg, first_msg) == 0,
               "%u threads: result %d (%s), one thread %d (%s)", threads[k], rc, err.msg,
               first_rc, first_msg);
        mts_stream_client_free(&c);
    }
    mts_buf_free(&b);
    mts_stream_free(&s);
}

/* ---- mts-client ---- */

/* A server in a child process: each connection gets one HELLO read and b
 * sent; it lives until killed (60 s at most). */
/* The records form brings its records whole: asked for four threads, the
 * client decodes it on one, says so, and ends at every batch's checksum. */
static void test_records_form(mts_test *t)
{
    mts_error err = {0};
    mts_mesh mesh = {0};
    mts_model m;
    mts_stream s;
    CHECKF(t, mts_mesh_load("tests/data/cow.off", NULL, &mesh, NULL, &err) == MTS_OK, "%s",
           err.msg);
    if (t->case_failed)
        return;
    mts_result rc = mts_build_model(&mesh, "cow", NULL, &m, NULL, &err);
    mts_mesh_free(&mesh);
    CHECKF(t, rc == MTS_OK, "build: %s", err.msg);
    if (rc != MTS_OK)
        return;
    mts_stream_options o = {0};
    o.with_records = 1;
    rc = mts_stream_build(&m, "cow", &o, &s, &err);
    mts_model_free(&m);
    CHECKF(t, rc == MTS_OK && s.records_form, "stream: %s", err.msg);
    if (rc != MTS_OK)
        return;
    if (s.records_form) {
        mts_buf b = {0};
        conversation(s.records_form, 0, &b);
        mts_stream_client c;
        mts_stream_client_init(&c);
        c.threads = 4;
        fed f = {0};
        rc = feed(&c, s.records_form, &b, 3, 0, &f, &err);
        CHECKF(t, rc == MTS_OK && f.ended && c.records, "records form: %s", err.msg);
        CHECKF(t, f.batches == s.batch_count && f.bad_levels == 0 && f.bad_checksums == 0,
               "records form: %u batches, %u at the wrong level, %u checksums", f.batches,
               f.bad_levels, f.bad_checksums);
        CHECKF(t, c.par == NULL && mts_stream_client_threads_used(&c) == 1,
               "records form: %u threads used", mts_stream_client_threads_used(&c));
        mts_stream_client_free(&c);
        mts_buf_free(&b);
    }
    mts_stream_free(&s);
}

static pid_t serve(int lfd, const mts_buf *b)
{
    pid_t pid = fork();
    if (pid != 0) {
        close(lfd);
        return pid;
    }
    alarm(60);
    for (;;) {
        int fd = accept(lfd, NULL, NULL);
        char hello[256];
        (void)!recv(fd, hello, sizeof hello, 0);
        (void)!send(fd, b->data, b->size, MSG_NOSIGNAL);
        usleep(100000);
        close(fd);
    }
}

static void test_client_program(mts_test *t)
{
    mts_stream s;
    if (!build_stream(t, "tests/data/cow.off", "cow", 0, &s))
        return;
    mts_buf b = {0};
    conversation(&s, 0, &b);
    int port, lfd = mts_test_listen_any(&port);
    CHECK(t, lfd >= 0);
    if (lfd < 0)
        return;
    pid_t pid = serve(lfd, &b);
    char cmd[2048], out[2][8192], want[64];
    snprintf(want, sizeof want, "\"checksum\":\"%016llx\"",
             (unsigned long long)s.level_checksum[s.model.level_count]);
    const int threads[2] = {1, 4};
    for (int k = 0; k < 2; k++) {
        snprintf(cmd, sizeof cmd,
                 "ASAN_OPTIONS=detect_leaks=0 %s/mts-client 127.0.0.1:%d cow --no-render --json "
                 "--threads %d",
                 bin_dir, port, threads[k]);
        int rc = mts_test_run(cmd, out[k], sizeof out[k]);
        char th[64]; /* more than two decode as two */
        snprintf(th, sizeof th, "\"threads\":%d,\"threads_asked\":%d",
                 threads[k] > 2 ? 2 : threads[k], threads[k]);
        CHECKF(t, rc == 0 && strstr(out[k], want) && strstr(out[k], th), "--threads %d: exit %d: %s",
               threads[k], rc, out[k]);
    }
    snprintf(cmd, sizeof cmd, "%s/mts-client 127.0.0.1:%d cow --threads 0", bin_dir, port);
    CHECK(t, mts_test_run(cmd, out[0], sizeof out[0]) == 2 && strstr(out[0], "--threads"));
    snprintf(cmd, sizeof cmd, "%s/mts-client --help", bin_dir);
    CHECK(t, mts_test_run(cmd, out[0], sizeof out[0]) == 0 && strstr(out[0], "--threads"));
    snprintf(cmd, sizeof cmd, "%s/mts-stress --help", bin_dir);
    CHECK(t, mts_test_run(cmd, out[0], sizeof out[0]) == 0 && strstr(out[0], "--decode-threads"));
    /* a stress client decoding on two threads ends with the same mesh */
    snprintf(cmd, sizeof cmd,
             "ASAN_OPTIONS=detect_leaks=0 %s/mts-stress 127.0.0.1:%d cow --clients 2 "
             "--decode-threads 2 --json",
             bin_dir, port);
    CHECKF(t, mts_test_run(cmd, out[0], sizeof out[0]) == 0, "mts-stress: %s", out[0]);
    kill(pid, SIGKILL);
    waitpid(pid, NULL, 0);
    mts_buf_free(&b);
    mts_stream_free(&s);
}

int main(int argc, char **argv)
{
    (void)argc;
    mts_test_bin_dir(argv[0], bin_dir, sizeof bin_dir);
    signal(SIGPIPE, SIG_IGN);
    mts_test t = {0};
    RUN(&t, test_cow);
    RUN(&t, test_resume);
    RUN(&t, test_damaged_batch);
    RUN(&t, test_bunny);
    RUN(&t, test_fandisk);
    RUN(&t, test_explicit);
    RUN(&t, test_records_form);
    RUN(&t, test_client_program);
    return mts_test_end(&t);
}
