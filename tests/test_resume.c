/* Resuming a stream after a broken connection (PROTOCOL.md, HELLO):
 *   - in memory: a conversation cut anywhere, then the rest asked for from
 *     the client's resume point (mts_stream_range, as the server answers),
 *     ends with the unbroken stream's checksum -- also after several breaks
 *     and at a partial stop level; a resumed MODEL_INFO of another stream is
 *     refused, never mixed in;
 *   - over loopback: mts-server is killed mid-stream (the client's bytes go
 *     through a small proxy in this program that cuts the first connection
 *     inside batch 10, so "mid-stream" is exact) and started again on the
 *     same port: `mts-client --resume` completes with the unbroken run's
 *     checksum, triangles and verification; a server that never comes back
 *     makes it give up after its bounded tries, in the time the backoff
 *     allows; a server that comes back with another model under the same
 *     name answers `stale`, which is not retried. */
#include <fcntl.h>
#include <libgen.h>
#include <netinet/in.h>
#include <arpa/inet.h>
#include <poll.h>
#include <signal.h>
#include <stdint.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "clock.h"
#include "modelfile.h"
#include "build.h"
#include "mesh.h"
#include "stream.h"
#include "test.h"
#include "test_proc.h"
#include "wire.h"

static char bin_dir[512], tmp_dir[512];

/* ---- in memory ---- */

/* cow, built once (the simplifier is the slow part, under ASan most of all) */
static mts_model cow;
static int cow_state; /* 0: not yet, 1: built, -1: failed */

static int build_stream(mts_test *t, const mts_stream_options *o, mts_stream *s)
{
    mts_error err = {0};
    if (cow_state == 0) {
        mts_mesh mesh = {0};
        cow_state = -1;
        if (mts_mesh_load("tests/data/cow.off", NULL, &mesh, NULL, &err) == MTS_OK &&
            mts_build_model(&mesh, "cow", NULL, &cow, NULL, &err) == MTS_OK)
            cow_state = 1;
        mts_mesh_free(&mesh);
    }
    if (cow_state < 0) {
        CHECKF(t, 0, "building cow: %s", err.msg[0] ? err.msg : "failed before");
        return 0;
    }
    mts_result rc = mts_stream_build(&cow, "cow", o, s, &err);
    CHECKF(t, rc == MTS_OK, "stream: %s", err.msg);
    return rc == MTS_OK;
}

/* What the server sends for a HELLO (server.c: MODEL_INFO, the range, END),
 * including its refusal of a resume for another stream. */
static int conversation(const mts_stream *s, uint32_t stop, uint32_t resume_batch,
                        uint64_t stream_id, mts_buf *out)
{
    mts_error err = {0};
    if (resume_batch > 0 && stream_id != s->stream_id) {
        size_t f = mts_wire_frame_begin(out, MTS_MSG_ERROR);
        mts_buf_u16(out, MTS_WERR_STALE);
        mts_buf_varint(out, 5);
        mts_buf_put(out, "stale", 5);
        mts_wire_frame_end(out, f);
        return 0;
    }
    size_t off, len;
    if (mts_stream_range(s, resume_batch, stop, &off, &len, &err) != MTS_OK)
        return 0;
    mts_stream_put_model_info(s, stop, out);
    size_t head = out->size;
    mts_buf_put(out, s->bytes + off, len);
    mts_stream_put_end(s, stop, (uint32_t)(head + len), out);
    return 1;
}

typedef mts_test_events tally;

/* Feeds data in seeded pieces into the stream client, as one connection
 * does; a frame the cut leaves incomplete stays in the client until the
 * next connection's mts_stream_client_reconnected drops it. */
static mts_result feed(mts_stream_client *c, const uint8_t *data, size_t size, uint64_t seed,
                       tally *n, mts_error *err)
{
    return mts_test_feed(c, data, size, seed, 1500, n, err);
}

/* Streams to `stop` over connections that break at cuts[0], cuts[1], ...
 * (bytes into each connection; SIZE_MAX: no break), resuming each time;
 * checks that the end is the unbroken stream's. */
static void run_with_breaks(mts_test *t, const mts_stream *s, uint32_t stop, const size_t *cuts,
                            int ncuts, uint64_t seed, const char *what)
{
    mts_stream_client c;
    mts_stream_client_init(&c);
    mts_error err = {0};
    tally n = {0};
    int have_base_before = 0;
    for (int k = 0; k <= ncuts && !t->case_failed; k++) {
        uint32_t batch = 0;
        uint64_t id = 0;
        if (k > 0) {
            CHECKF(t, mts_stream_client_resume_point(&c, &batch, &id), "%s: break %d", what, k);
            CHECK(t, batch == (c.have_lod ? c.batches : 0));
            CHECK(t, batch == 0 ? id == 0 : id == s->stream_id);
            have_base_before = c.have_lod;
            CHECKF(t, mts_stream_client_reconnected(&c, &err) == MTS_OK, "%s: %s", what, err.msg);
        }
        mts_buf b = {0};
        CHECKF(t, conversation(s, stop, batch, id, &b), "%s: the server refused the resume", what);
        size_t len = k < ncuts && cuts[k] < b.size ? cuts[k] : b.size;
        int resumed = n.resumed;
        mts_result rc = feed(&c, b.data, len, seed + (uint64_t)k, &n, &err);
        CHECKF(t, rc == MTS_OK, "%s, connection %d (%zu of %zu bytes): %s", what, k, len, b.size,
               err.msg);
        /* once the base is in, a new conversation's whole MODEL_INFO is a
         * resume (MTS_EV_RESUMED); before, it starts over (MTS_EV_INFO) */
        size_t info_size = 4 + ((size_t)b.data[0] | (size_t)b.data[1] << 8 |
                                (size_t)b.data[2] << 16 | (size_t)b.data[3] << 24);
        if (k > 0 && have_base_before && rc == MTS_OK)
            CHECKF(t, n.resumed == resumed + (len >= info_size), "%s: MTS_EV_RESUMED %d, was %d",
                   what, n.resumed, resumed);
        int whole = len == b.size;
        mts_buf_free(&b);
        if (whole) /* a cut past the end: that conversation completed */
            break;
    }
    CHECKF(t, n.end == 1 && n.base == 1 && n.error == 0,
           "%s: %d END, %d BASE events (want 1 and 1)", what, n.end, n.base);
    CHECKF(t, (uint32_t)n.batch == c.batches, "%s: %d batch events for %u batches", what, n.batch,
           c.batches);
    CHECK(t, c.have_lod && c.lod.level == stop);
    CHECKF(t, c.records == s->records, "%s: the client took the %s form", what,
           c.records ? "records" : "splits");
    CHECKF(t, c.checksum == s->level_checksum[stop] && c.checksum == c.end_checksum,
           "%s: checksum %016llx, unbroken %016llx", what, (unsigned long long)c.checksum,
           (unsigned long long)s->level_checksum[stop]);
    if (c.have_lod) {
        size_t nv = (size_t)s->model.base_vertex_count + stop;
        CHECKF(t, memcmp(c.model.positions, s->model.positions, nv * 12) == 0 &&
                      memcmp(c.model.normals, s->model.normals, nv * 12) == 0,
               "%s: vertices differ", what);
    }
    uint32_t b2;
    uint64_t id2;
    CHECK(t, !mts_stream_client_resume_point(&c, &b2, &id2)); /* ended: nothing to resume */
    CHECK(t, mts_stream_client_reconnected(&c, &err) == MTS_ERR_ARG);
    mts_stream_client_free(&c);
}

/* Cuts at the edges, then `rounds` rounds of random cuts (one break and
 * three, at the full level and a partial stop), in the form s is; label
 * names it in failures. */
static void cut_anywhere(mts_test *t, const mts_stream *s, int rounds, uint64_t seed,
                         const char *label)
{
    const uint32_t n = s->model.level_count;
    mts_buf info = {0};
    mts_stream_put_model_info(s, n, &info);
    const size_t hi = info.size;
    mts_buf_free(&info);
    /* the edges: in and right after MODEL_INFO (a fresh start), inside and
     * right after BASE (base in, no batch: the server sends BASE again and
     * the client skips it), on a batch boundary, inside the last batch, in END */
    size_t edges[] = {0, 1, 4, 5, hi - 1, hi, hi + 9, hi + s->batch_offset[0],
                      hi + s->batch_offset[1], hi + s->batch_offset[3], hi + s->batch_offset[3] + 1,
                      hi + s->batch_offset[s->batch_count] - 3, hi + s->size, hi + s->size + 3};
    char what[128];
    for (size_t i = 0; i < sizeof edges / sizeof edges[0] && !t->case_failed; i++) {
        snprintf(what, sizeof what, "%s, cut at %zu", label, edges[i]);
        run_with_breaks(t, s, n, &edges[i], 1, i, what);
    }
    size_t total = hi + s->size + 20;
    for (int round = 0; round < rounds && !t->case_failed; round++) {
        size_t cuts[3];
        int k = round % 2 ? 3 : 1;
        for (int j = 0; j < k; j++) {
            seed = seed * 6364136223846793005ull + 1442695040888963407ull;
            /* later conversations are shorter: cut within what is left */
            cuts[j] = (size_t)(seed >> 33) % (total / (size_t)(j + 1));
        }
        uint32_t stop = round % 4 < 2 ? n : n / 3;
        snprintf(what, sizeof what, "%s, round %d (stop %u, cut %zu...)", label, round, stop,
                 cuts[0]);
        run_with_breaks(t, s, stop, cuts, k, seed, what);
    }
}

static void test_cut_anywhere_then_resume(mts_test *t)
{
    mts_stream s;
    if (!build_stream(t, NULL, &s))
        return;
    cut_anywhere(t, &s, 40, 42, "splits");
    mts_stream_free(&s);
}

/* cow's stream and its records form (s->records_form); 0, with nothing
 * held and a check failed, without either. */
static int build_with_records(mts_test *t, mts_stream *s)
{
    mts_stream_options o = {0};
    o.with_records = 1;
    if (!build_stream(t, &o, s))
        return 0;
    CHECKF(t, s->records_form != NULL, "with_records = 1 built no records form");
    if (!s->records_form)
        mts_stream_free(s);
    return s->records_form != NULL;
}

/* Where batch k begins in a conversation to stop (after its MODEL_INFO). */
static size_t batch_at(const mts_stream *s, uint32_t stop, uint32_t k)
{
    mts_buf info = {0};
    mts_stream_put_model_info(s, stop, &info);
    size_t at = info.size + s->batch_offset[k];
    mts_buf_free(&info);
    return at;
}

/* A fresh client c, fed a's conversation `first` up to cut (inside batch 4)
 * and broken there: it holds 4 batches, would resume at batch 4 of a, and
 * takes the next conversation as a resume. */
static void break_in_batch_4(mts_test *t, const mts_stream *a, const mts_buf *first, size_t cut,
                             mts_stream_client *c, tally *k, mts_error *err)
{
    mts_stream_client_init(c);
    *k = (tally){0};
    CHECK(t, feed(c, first->data, cut, 1, k, err) == MTS_OK && c->batches == 4);
    uint32_t batch;
    uint64_t id;
    CHECK(t, mts_stream_client_resume_point(c, &batch, &id) && batch == 4 && id == a->stream_id);
    CHECK(t, mts_stream_client_reconnected(c, err) == MTS_OK);
}

/* A resumed conversation that brings another stream is refused whole. */
static void test_other_stream_refused(mts_test *t)
{
    mts_stream a, b;
    if (!build_stream(t, NULL, &a))
        return;
    mts_stream_options o = {0};
    o.batch_splits = 50; /* same model, other batches: another stream_id */
    if (!build_stream(t, &o, &b)) {
        mts_stream_free(&a);
        return;
    }
    CHECK(t, a.stream_id != b.stream_id);
    const uint32_t n = a.model.level_count;
    mts_buf first = {0}, second = {0};
    conversation(&a, n, 0, 0, &first);
    size_t cut = batch_at(&a, n, 4) + 10; /* inside batch 4 */

    /* a server that does not check stream_id sends the other stream */
    mts_stream_client c;
    mts_error err = {0};
    tally k;
    break_in_batch_4(t, &a, &first, cut, &c, &k, &err);
    conversation(&b, n, 4, b.stream_id, &second);
    mts_result rc = feed(&c, second.data, second.size, 2, &k, &err);
    CHECKF(t, rc == MTS_ERR_FORMAT && strstr(err.msg, "not mixing"), "%d: %s", rc, err.msg);
    CHECK(t, c.batches == 4 && c.lod.level == a.batch_first[4]); /* untouched */
    uint32_t batch;
    uint64_t id;
    CHECK(t, !mts_stream_client_resume_point(&c, &batch, &id));
    mts_stream_client_free(&c);

    /* the server that checks answers ERROR stale: an event, not a mix */
    break_in_batch_4(t, &a, &first, cut, &c, &k, &err);
    mts_buf_free(&second);
    CHECK(t, !conversation(&b, n, 4, a.stream_id, &second));
    CHECK(t, feed(&c, second.data, second.size, 3, &k, &err) == MTS_OK);
    CHECK(t, k.error == 1 && c.error_code == MTS_WERR_STALE);
    CHECK(t, !mts_stream_client_resume_point(&c, &batch, &id));
    mts_stream_client_free(&c);

    /* a break before any batch with the base in, then another stream from
     * batch 0: the client holds a's base, so b must be refused too */
    mts_stream_client_init(&c);
    k = (tally){0};
    CHECK(t, feed(&c, first.data, cut - a.batch_offset[4] + a.batch_offset[0] + 2, 1, &k, &err) ==
             MTS_OK);
    CHECK(t, c.have_lod && c.batches == 0);
    CHECK(t, mts_stream_client_resume_point(&c, &batch, &id) && batch == 0 && id == 0);
    CHECK(t, mts_stream_client_reconnected(&c, &err) == MTS_OK);
    mts_buf_free(&second);
    conversation(&b, n, 0, 0, &second);
    rc = feed(&c, second.data, second.size, 4, &k, &err);
    CHECKF(t, rc == MTS_ERR_FORMAT && strstr(err.msg, "not mixing"), "%s", err.msg);
    mts_stream_client_free(&c);

    mts_buf_free(&first);
    mts_buf_free(&second);
    mts_stream_free(&a);
    mts_stream_free(&b);
}

/* The same cuts in the records form: the client resumes it with the records
 * form's own stream_id (run_with_breaks checks what resume_point gives
 * against the stream's) and ends on the splits form's checksum. */
static void test_cut_anywhere_then_resume_records(mts_test *t)
{
    mts_stream s;
    if (!build_with_records(t, &s))
        return;
    const mts_stream *r = s.records_form;
    CHECK(t, r != NULL && r->stream_id != s.stream_id && r->batch_count > 4);
    if (r && r->batch_count > 4)
        cut_anywhere(t, r, 16, 4242, "records");
    mts_stream_free(&s);
}

/* Continuing past the stop (a preview that zooms in asks for
 * more): a stream stopped at one level, then asked for a higher stop from
 * the batches it holds, ends with the checksum and vertices of an unbroken
 * stream to that level, at every step; a step that lies within the splits
 * already held (the last batch reaches past a stop inside it) needs no
 * batch; the bytes are the unbroken stream's plus each further
 * conversation's MODEL_INFO and END (and BASE again after a stop at level
 * 0, which holds no batch). A lower stop, or continuing a stream that did
 * not end, is refused. Both forms, and from every batch of cow to full. */
static void continue_steps(mts_test *t, const mts_stream *s, const uint32_t *stops, int nstops,
                           const char *label)
{
    mts_stream_client c;
    mts_stream_client_init(&c);
    mts_error err = {0};
    tally n = {0};
    size_t total = 0;
    for (int k = 0; k < nstops && !t->case_failed; k++) {
        uint32_t batch = 0;
        uint64_t id = 0;
        if (k > 0)
            CHECKF(t, mts_stream_client_continue(&c, &batch, &id, &err) == MTS_OK, "%s: %s",
                   label, err.msg);
        CHECK(t, batch == (k ? c.batches : 0));
        mts_buf b = {0};
        CHECKF(t, conversation(s, stops[k], batch, id, &b), "%s: no conversation to %u from %u",
               label, stops[k], batch);
        total += b.size;
        mts_result rc = feed(&c, b.data, b.size, (uint64_t)k, &n, &err);
        mts_buf_free(&b);
        CHECKF(t, rc == MTS_OK, "%s, step to %u: %s", label, stops[k], err.msg);
        CHECKF(t, c.have_lod && c.lod.level == stops[k] && c.end_checksum &&
                      c.checksum == s->level_checksum[stops[k]] && c.checksum == c.end_checksum,
               "%s, step to %u: level %u, checksum %016llx, unbroken %016llx", label, stops[k],
               c.lod.level, (unsigned long long)c.checksum,
               (unsigned long long)s->level_checksum[stops[k]]);
        size_t nv = (size_t)s->model.base_vertex_count + stops[k];
        CHECKF(t, memcmp(c.model.positions, s->model.positions, nv * 12) == 0,
               "%s, step to %u: vertices differ", label, stops[k]);
    }
    CHECKF(t, n.base == 1 && n.info == 1 && n.end == nstops && n.resumed == nstops - 1,
           "%s: %d BASE, %d INFO, %d END, %d RESUMED", label, n.base, n.info, n.end, n.resumed);
    /* the bytes: the unbroken stream to the last stop, plus MODEL_INFO and
     * END (and BASE after a stop with no batch) for every further step */
    mts_buf whole = {0};
    conversation(s, stops[nstops - 1], 0, 0, &whole);
    mts_buf info = {0};
    mts_stream_put_model_info(s, stops[nstops - 1], &info);
    size_t extra = 0;
    for (int k = 1; k < nstops; k++)
        extra += info.size + 32 + (stops[k - 1] < s->batch_first[0] + 1 ? s->batch_offset[0] : 0);
    CHECKF(t, total >= whole.size && total <= whole.size + extra,
           "%s: %zu bytes in all, the unbroken stream %zu (+%zu allowed)", label, total,
           whole.size, extra);
    mts_buf_free(&whole);
    mts_buf_free(&info);
    /* lower than the level held: refused */
    if (c.lod.level > 0 && !t->case_failed) {
        uint32_t batch;
        uint64_t id;
        CHECK(t, mts_stream_client_continue(&c, &batch, &id, &err) == MTS_OK);
        mts_buf b = {0};
        conversation(s, c.lod.level - 1, batch > 0 ? batch - 1 : 0, id, &b);
        mts_result rc = feed(&c, b.data, b.size, 7, &n, &err);
        CHECKF(t, rc == MTS_ERR_FORMAT && strstr(err.msg, "may only rise"), "%s: %s", label,
               err.msg);
        mts_buf_free(&b);
    }
    mts_stream_client_free(&c);
}

static void test_continue_past_the_stop(mts_test *t)
{
    mts_stream s;
    if (!build_with_records(t, &s))
        return;
    const mts_stream *forms[2] = {&s, s.records_form};
    for (int f = 0; f < 2 && forms[f]; f++) {
        const mts_stream *x = forms[f];
        const uint32_t n = x->model.level_count;
        /* a stop inside the second batch, one within the splits that batch
         * brought, then on to a third and the full level */
        uint32_t inside = x->batch_first[1] + 3, held = inside + 2;
        const uint32_t a[] = {inside, held, n / 3, n};
        const uint32_t b[] = {0, n / 7, n / 7, n};
        const uint32_t c[] = {n / 2, n};
        char label[64];
        snprintf(label, sizeof label, "%s, inside/held/third/full", f ? "records" : "splits");
        continue_steps(t, x, a, 4, label);
        snprintf(label, sizeof label, "%s, base/seventh/again/full", f ? "records" : "splits");
        continue_steps(t, x, b, 4, label);
        snprintf(label, sizeof label, "%s, half/full", f ? "records" : "splits");
        continue_steps(t, x, c, 2, label);
    }
    /* from every batch boundary of cow (and one split into each batch) on
     * to the full level, both forms */
    for (int f = 0; f < 2 && forms[f] && !t->case_failed; f++) {
        const mts_stream *x = forms[f];
        for (uint32_t k = 0; k < x->batch_count && !t->case_failed; k++) {
            for (uint32_t d = 0; d < 2; d++) {
                uint32_t stop = x->batch_first[k] + d;
                if (stop >= x->model.level_count)
                    continue;
                const uint32_t st[2] = {stop, x->model.level_count};
                char label[80];
                snprintf(label, sizeof label, "%s, from %u to full", f ? "records" : "splits",
                         stop);
                continue_steps(t, x, st, 2, label);
            }
        }
    }
    /* a stream still going does not continue */
    mts_stream_client cl;
    mts_stream_client_init(&cl);
    mts_error err = {0};
    uint32_t batch;
    uint64_t id;
    CHECK(t, mts_stream_client_continue(&cl, &batch, &id, &err) == MTS_ERR_ARG);
    mts_stream_client_free(&cl);
    mts_stream_free(&s);
}

/* A client that began in one form cannot go on in the other: the forms are
 * two streams (two stream_ids). A server that checks answers `stale`; one
 * that does not sends the other form, which is refused whole. */
static void test_other_form_refused(mts_test *t)
{
    mts_stream s;
    if (!build_with_records(t, &s))
        return;
    const mts_stream *r = s.records_form;
    const uint32_t n = s.model.level_count;
    const mts_stream *began[2] = {r, &s}, *then[2] = {&s, r};
    for (int i = 0; i < 2; i++) {
        const mts_stream *a = began[i], *b = then[i];
        mts_buf first = {0}, second = {0};
        conversation(a, n, 0, 0, &first);
        size_t cut = batch_at(a, n, 4) + 10; /* inside batch 4 */
        mts_stream_client c;
        mts_error err = {0};
        tally k;
        break_in_batch_4(t, a, &first, cut, &c, &k, &err);
        CHECK(t, c.records == a->records);
        /* the server that checks: the other form's stream_id is not this one */
        CHECK(t, !conversation(b, n, 4, a->stream_id, &second));
        mts_stream_client d;
        mts_stream_client_init(&d);
        tally kd = {0};
        CHECK(t, feed(&d, second.data, second.size, 2, &kd, &err) == MTS_OK);
        CHECK(t, kd.error == 1 && d.error_code == MTS_WERR_STALE);
        mts_stream_client_free(&d);
        /* the server that does not: sends the other form from batch 4 */
        mts_buf_free(&second);
        conversation(b, n, 4, b->stream_id, &second);
        mts_result rc = feed(&c, second.data, second.size, 3, &k, &err);
        CHECKF(t, rc == MTS_ERR_FORMAT && strstr(err.msg, "not mixing"), "began %s: %d %s",
               a->records ? "records" : "splits", rc, err.msg);
        CHECK(t, c.batches == 4 && c.lod.level == a->batch_first[4] && !c.lod.broken);
        uint32_t batch;
        uint64_t id;
        CHECK(t, !mts_stream_client_resume_point(&c, &batch, &id));
        mts_stream_client_free(&c);
        mts_buf_free(&first);
        mts_buf_free(&second);
    }
    mts_stream_free(&s);
}

/* ---- over loopback ---- */

static int send_all(int fd, const uint8_t *p, size_t n)
{
    while (n > 0) {
        ssize_t w = send(fd, p, n, MSG_NOSIGNAL);
        if (w <= 0)
            return 0;
        p += w;
        n -= (size_t)w;
    }
    return 1;
}

/* Copies both ways until either side closes or `limit` bytes went from the
 * server to the client. */
static void pump(int cfd, int ufd, size_t limit)
{
    uint8_t buf[1 << 15];
    size_t down = 0;
    while (down < limit) {
        struct pollfd pf[2] = {{cfd, POLLIN, 0}, {ufd, POLLIN, 0}};
        if (poll(pf, 2, 30000) <= 0)
            return;
        if (pf[0].revents) {
            ssize_t r = recv(cfd, buf, sizeof buf, 0);
            if (r <= 0 || !send_all(ufd, buf, (size_t)r))
                return;
        }
        if (pf[1].revents) {
            size_t want = limit - down < sizeof buf ? limit - down : sizeof buf;
            ssize_t r = recv(ufd, buf, want, 0);
            if (r <= 0 || !send_all(cfd, buf, (size_t)r))
                return;
            down += (size_t)r;
        }
    }
}

/* The proxy (a child process): the first connection is cut after `cut`
 * bytes from the server; it then tells the parent ('c' on `tell`) and waits
 * for the server to be dead (a byte on `wait`) before closing the client's
 * side, so the client sees what a killed server leaves: the stream ending
 * mid-frame. Later connections are forwarded whole while the server is up;
 * while it is down the client's connection is reset at once, as a refused
 * connect would be. With `vanish` the proxy stops listening after the cut:
 * every try is refused. */
static void proxy_main(int lfd, int upstream, size_t cut, int tell, int wait, int vanish)
{
    signal(SIGPIPE, SIG_IGN);
    for (int first = 1;; first = 0) {
        int cfd = accept(lfd, NULL, NULL);
        if (cfd < 0)
            _exit(1);
        int ufd = mts_test_connect(upstream);
        if (ufd < 0) {
            struct linger lg = {1, 0};
            setsockopt(cfd, SOL_SOCKET, SO_LINGER, &lg, sizeof lg);
            close(cfd);
            continue;
        }
        pump(cfd, ufd, first ? cut : SIZE_MAX);
        if (first) {
            char b = 'c';
            if (write(tell, &b, 1) != 1 || read(wait, &b, 1) != 1)
                _exit(1);
        }
        close(ufd);
        close(cfd);
        if (first && vanish)
            _exit(0);
    }
}

/* flag: one more option for mts-server, or NULL */
static pid_t spawn_server_with(const char *models, int port, const char *log, const char *flag)
{
    char bin[600], listen[64];
    snprintf(bin, sizeof bin, "%s/mts-server", bin_dir);
    snprintf(listen, sizeof listen, "127.0.0.1:%d", port);
    pid_t pid = fork();
    if (pid == 0) {
        if (!freopen(log, "a", stderr) || !freopen("/dev/null", "w", stdout))
            _exit(126);
        execl(bin, bin, "--models", models, "--listen", listen, flag, (char *)NULL);
        _exit(127);
    }
    return pid;
}

static pid_t spawn_server(const char *models, int port, const char *log)
{
    return spawn_server_with(models, port, log, NULL);
}

static int server_up(int port)
{
    char cmd[1024], out[4096];
    snprintf(cmd, sizeof cmd,
             "for i in $(seq 1 200); do %s/mts-client 127.0.0.1:%d --list >/dev/null && exit 0; "
             "sleep 0.05; done; exit 1",
             bin_dir, port);
    return mts_test_run(cmd, out, sizeof out) == 0;
}

static void stop_pid(pid_t pid, int sig)
{
    if (pid <= 0)
        return;
    kill(pid, sig);
    waitpid(pid, NULL, 0);
}


typedef struct fixture {
    char models[600], other[600], model_file[700], log[700];
    const char *render; /* "" or "--no-render" */
    int port;
    size_t cut;  /* into the first connection: inside batch 10 */
    size_t cut_records; /* the same in the records form (mts-client --records) */
    size_t records_size; /* the records form's bytes */
    uint32_t cut_batch;
    char unbroken[8192];
} fixture;

static int have_programs(mts_test *t)
{
    const char *need[] = {"mts-build", "mts-server", "mts-client"};
    for (int i = 0; i < 3; i++) {
        char path[700];
        snprintf(path, sizeof path, "%s/%s", bin_dir, need[i]);
        if (access(path, X_OK) != 0) {
            fprintf(stderr, "  SKIP %s: %s is not built\n", t->case_name, path);
            t->case_skipped = 1;
            return 0;
        }
    }
    return 1;
}

/* Builds cow.mtsm (and, in `other`, an octahedron named cow: another stream
 * under the same name), starts a server, runs the unbroken client. */
static int setup(mts_test *t, fixture *f, pid_t *server)
{
    char cmd[8192], out[8192];
    snprintf(f->models, sizeof f->models, "%s/resume_models", tmp_dir);
    snprintf(f->other, sizeof f->other, "%s/resume_other", tmp_dir);
    snprintf(f->model_file, sizeof f->model_file, "%s/cow.mtsm", f->models);
    snprintf(f->log, sizeof f->log, "%s/resume_server.log", tmp_dir);
    snprintf(cmd, sizeof cmd,
             "rm -rf %s %s && mkdir -p %s %s && %s/mts-build tests/data/cow.off -o %s --quiet && "
             "printf 'OFF\\n6 8 0\\n1 0 0\\n-1 0 0\\n0 1 0\\n0 -1 0\\n0 0 1\\n0 0 -1\\n"
             "3 0 2 4\\n3 2 1 4\\n3 1 3 4\\n3 3 0 4\\n3 2 0 5\\n3 1 2 5\\n3 3 1 5\\n"
             "3 0 3 5\\n' > %s/resume_octa.off && %s/mts-build %s/resume_octa.off -o %s/cow.mtsm "
             "--quiet",
             f->models, f->other, f->models, f->other, bin_dir, f->model_file, tmp_dir, bin_dir,
             tmp_dir, f->other);
    if (mts_test_run(cmd, out, sizeof out) != 0) {
        CHECKF(t, 0, "building the models: %s", out);
        return 0;
    }
    /* where batch 10 is in the server's stream, in both forms: the same
     * model file, encoded the way the server does */
    mts_error err = {0};
    mts_model m;
    mts_stream s;
    if (mts_modelfile_load(f->model_file, &m, &err) != MTS_OK) {
        CHECKF(t, 0, "%s", err.msg);
        return 0;
    }
    mts_stream_options so = {0};
    so.with_records = 1;
    mts_result rc = mts_stream_build(&m, "cow", &so, &s, &err);
    mts_model_free(&m);
    if (rc != MTS_OK) {
        CHECKF(t, 0, "%s", err.msg);
        return 0;
    }
    f->cut_batch = 10;
    f->cut = batch_at(&s, s.model.level_count, f->cut_batch) + 7;
    CHECK(t, s.batch_count > 20 && s.records_form);
    if (s.records_form) {
        f->cut_records = batch_at(s.records_form, s.model.level_count, f->cut_batch) + 7;
        f->records_size = s.records_form->size;
    }
    mts_stream_free(&s);

    f->port = mts_test_free_port();
    *server = spawn_server(f->models, f->port, f->log);
    if (!server_up(f->port)) {
        CHECKF(t, 0, "the server did not come up (log: %s)", f->log);
        return 0;
    }
    /* the unbroken run; rendering as a user would, unless there is no EGL */
    f->render = "";
    for (int attempt = 0; attempt < 2; attempt++) {
        snprintf(cmd, sizeof cmd,
                 "ASAN_OPTIONS=detect_leaks=0 timeout 60 %s/mts-client 127.0.0.1:%d cow --json "
                 "--verify --model-file %s %s",
                 bin_dir, f->port, f->model_file, f->render);
        rc = mts_test_run(cmd, f->unbroken, sizeof f->unbroken);
        if (rc != 0 && attempt == 0 && strstr(f->unbroken, "EGL") &&
            !getenv("MTS_TEST_REQUIRE_EGL")) {
            fprintf(stderr, "  (%s: no EGL here, the clients run --no-render)\n", t->case_name);
            f->render = "--no-render";
            continue;
        }
        break;
    }
    CHECKF(t, rc == 0 && strstr(f->unbroken, "\"complete\":true") &&
                  strstr(f->unbroken, "\"verified\":true") && strstr(f->unbroken, "\"checksum\""),
           "unbroken run: %s", f->unbroken);
    return !t->case_failed;
}

/* The models, the cut and the unbroken run are the same for every case:
 * set up once; each case then gets a running server. */
static fixture fx;
static int fx_state; /* 0: not yet, 1: ready, -1: failed */
static pid_t fx_server = -1;

static fixture *get_fixture(mts_test *t, pid_t *server)
{
    if (fx_state == 0)
        fx_state = setup(t, &fx, &fx_server) ? 1 : -1;
    if (fx_state < 0) {
        CHECKF(t, 0, "the set-up failed (see above)");
        *server = fx_server;
        fx_server = -1;
        return NULL;
    }
    if (fx_server > 0) { /* the one the unbroken run used */
        *server = fx_server;
        fx_server = -1;
        return &fx;
    }
    *server = spawn_server(fx.models, fx.port, fx.log);
    if (!server_up(fx.port)) {
        CHECKF(t, 0, "the server did not come up (log: %s)", fx.log);
        return NULL;
    }
    return &fx;
}

/* The fixture and its server for a case that runs the programs; NULL (no
 * server left running) when they are not built (the case skips) or the
 * set-up failed. */
static fixture *start_fixture(mts_test *t, pid_t *server)
{
    *server = -1;
    if (!have_programs(t))
        return NULL;
    fixture *f = get_fixture(t, server);
    if (!f) {
        stop_pid(*server, SIGTERM);
        *server = -1;
    }
    return f;
}

enum { AFTER_CUT_RESTART, AFTER_CUT_NOTHING, AFTER_CUT_OTHER_MODEL };

/* Starts the proxy and the client (--resume), cuts, kills the server, then
 * does `after`; returns the client's exit status, its output in out and
 * the seconds from the cut to its end. */
static int broken_run(mts_test *t, fixture *f, pid_t *server, int after, size_t cut_at,
                      const char *extra, char *out, size_t size, double *seconds_after_cut)
{
    int pport, lfd = mts_test_listen_any(&pport);
    int to_parent[2], to_proxy[2];
    if (lfd < 0 || pipe(to_parent) != 0 || pipe(to_proxy) != 0) {
        CHECK(t, 0);
        return -1;
    }
    /* the client and the servers started later need none of these */
    for (int i = 0; i < 2; i++) {
        fcntl(to_parent[i], F_SETFD, FD_CLOEXEC);
        fcntl(to_proxy[i], F_SETFD, FD_CLOEXEC);
    }
    pid_t proxy = fork();
    if (proxy == 0) {
        close(to_parent[0]);
        close(to_proxy[1]);
        proxy_main(lfd, f->port, cut_at, to_parent[1], to_proxy[0], after == AFTER_CUT_NOTHING);
        _exit(0);
    }
    close(lfd);
    close(to_parent[1]);
    close(to_proxy[0]);
    char cmd[8192];
    snprintf(cmd, sizeof cmd,
             "(ASAN_OPTIONS=detect_leaks=0 timeout 60 %s/mts-client 127.0.0.1:%d cow --resume "
             "--json --verify --model-file %s %s %s) 2>&1",
             bin_dir, pport, f->model_file, f->render, extra);
    FILE *p = popen(cmd, "r");
    double t_cut = mts_clock_seconds();
    struct pollfd pf = {to_parent[0], POLLIN, 0};
    char b = 0;
    int cut = poll(&pf, 1, 20000) == 1 && read(to_parent[0], &b, 1) == 1 && b == 'c';
    CHECKF(t, cut, "the proxy never cut the stream");
    if (cut) {
        t_cut = mts_clock_seconds();
        /* the server dies with the client's stream cut short, then the
         * proxy lets the client see it */
        stop_pid(*server, SIGKILL);
        *server = -1;
        b = 'k';
        CHECK(t, write(to_proxy[1], &b, 1) == 1);
        if (after != AFTER_CUT_NOTHING) {
            struct timespec ts = {0, 300 * 1000 * 1000};
            nanosleep(&ts, NULL); /* the client's first tries find it down */
            *server = spawn_server(after == AFTER_CUT_OTHER_MODEL ? f->other : f->models, f->port,
                                   f->log);
        }
    }
    size_t n = p ? fread(out, 1, size - 1, p) : 0;
    out[n] = 0;
    int st = p ? pclose(p) : -1;
    *seconds_after_cut = mts_clock_seconds() - t_cut;
    close(to_parent[0]);
    close(to_proxy[1]);
    stop_pid(proxy, SIGKILL);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

/* A client's broken run, as broken_case gives it. */
typedef struct client_run {
    int rc;      /* its exit status */
    double secs; /* from the cut to its end */
    char out[16384];
} client_run;

/* The fixture and a broken run against its server (started with flag, or
 * none; the cut is into the records form with `records`), the server
 * stopped after; NULL when there is no fixture (the case skips or failed). */
static fixture *broken_case(mts_test *t, const char *flag, int after, int records,
                            const char *extra, client_run *r)
{
    pid_t server;
    fixture *f = start_fixture(t, &server);
    if (!f)
        return NULL;
    if (flag) {
        stop_pid(server, SIGTERM);
        server = spawn_server_with(f->models, f->port, f->log, flag);
        CHECK(t, server_up(f->port));
    }
    r->rc = broken_run(t, f, &server, after, records ? f->cut_records : f->cut, extra, r->out,
                       sizeof r->out, &r->secs);
    stop_pid(server, SIGTERM);
    return f;
}

/* The first `count` of checksum, triangles, level, batches and levels in a
 * resumed run's --json output are the unbroken run's. */
static void same_as_unbroken(mts_test *t, const fixture *f, const char *out, int count)
{
    const char *keys[] = {"checksum", "triangles", "level", "batches", "levels"};
    for (int i = 0; i < count; i++) {
        char a[128], b[128];
        mts_test_json(f->unbroken, keys[i], a, sizeof a);
        mts_test_json(out, keys[i], b, sizeof b);
        CHECKF(t, a[0] && strcmp(a, b) == 0, "%s: %s unbroken, %s resumed", keys[i], a, b);
    }
}

static void test_server_killed_and_restarted(mts_test *t)
{
    client_run r;
    fixture *f = broken_case(t, NULL, AFTER_CUT_RESTART, 0, "", &r);
    if (!f)
        return;
    CHECKF(t, r.rc == 0, "exit %d: %s", r.rc, r.out);
    char want[64];
    snprintf(want, sizeof want, "connection lost at batch %u", f->cut_batch);
    CHECKF(t, strstr(r.out, want) && strstr(r.out, "retrying in") && strstr(r.out, "(try 1/8)"),
           "no retry reported: %s", r.out);
    snprintf(want, sizeof want, "resuming at batch %u", f->cut_batch);
    CHECKF(t, strstr(r.out, want) != NULL, "no resume reported: %s", r.out);
    CHECKF(t, strstr(r.out, "\"complete\":true") && strstr(r.out, "\"verified\":true"), "%s",
           r.out);
    /* the same mesh as the unbroken run */
    same_as_unbroken(t, f, r.out, 5);
    char rec[32];
    mts_test_json(r.out, "reconnects", rec, sizeof rec);
    CHECKF(t, atoi(rec) >= 1, "reconnects: '%s'", rec);
    mts_test_json(f->unbroken, "reconnects", rec, sizeof rec);
    CHECK(t, strcmp(rec, "0") == 0);
    /* fewer bytes than twice the stream: the second connection did not
     * start over */
    char b1[32], b2[32];
    mts_test_json(f->unbroken, "bytes", b1, sizeof b1);
    mts_test_json(r.out, "bytes", b2, sizeof b2);
    CHECKF(t, atol(b2) < atol(b1) + (long)f->cut / 2, "bytes %s, unbroken %s", b2, b1);
    if (getenv("MTS_TEST_VERBOSE"))
        fprintf(stderr, "  resumed %.2f s after the cut:\n%s", r.secs, r.out);
}

/* The same in the records form (mts-client --records; mts-server keeps it by
 * default): the client resumes at batch 10 with the records form's
 * stream_id, and ends on the unbroken splits-form run's mesh, verified
 * against the model file. */
static void test_server_killed_and_restarted_records(mts_test *t)
{
    client_run r;
    fixture *f = broken_case(t, NULL, AFTER_CUT_RESTART, 1, "--records", &r);
    if (!f)
        return;
    CHECKF(t, r.rc == 0, "exit %d: %s", r.rc, r.out);
    char want[64];
    snprintf(want, sizeof want, "connection lost at batch %u", f->cut_batch);
    CHECKF(t, strstr(r.out, want) != NULL, "no break reported: %s", r.out);
    snprintf(want, sizeof want, "resuming at batch %u", f->cut_batch);
    CHECKF(t, strstr(r.out, want) != NULL, "no resume reported: %s", r.out);
    CHECKF(t, strstr(r.out, "\"complete\":true") && strstr(r.out, "\"verified\":true") &&
                  strstr(r.out, "\"form\":\"records\""),
           "%s", r.out);
    /* the same mesh as the unbroken splits-form run */
    same_as_unbroken(t, f, r.out, 5);
    char form[32], rec[32], bytes[32];
    mts_test_json(f->unbroken, "form", form, sizeof form);
    CHECK(t, strcmp(form, "\"splits\"") == 0);
    mts_test_json(r.out, "reconnects", rec, sizeof rec);
    CHECKF(t, atoi(rec) >= 1, "reconnects: '%s'", rec);
    /* the records form, and not twice: the second connection went on from
     * batch 10 */
    mts_test_json(r.out, "bytes", bytes, sizeof bytes);
    CHECKF(t, (size_t)atol(bytes) > f->records_size &&
                  (size_t)atol(bytes) < f->records_size + f->cut_records / 2,
           "bytes %s, records form %zu, cut at %zu", bytes, f->records_size, f->cut_records);
    if (getenv("MTS_TEST_VERBOSE"))
        fprintf(stderr, "  resumed (records form) %.2f s after the cut:\n%s", r.secs, r.out);
}

/* A --records client first served by a server without the records form
 * (mts-server --no-records-form) holds the splits form; after the break it
 * resumes against a server that has both, and must ask for the form it
 * holds, not the one it first asked for (else that server would answer
 * stale). It ends complete, in the splits form, on the unbroken mesh. */
static void test_resume_asks_for_the_form_held(mts_test *t)
{
    client_run r;
    fixture *f = broken_case(t, "--no-records-form", AFTER_CUT_RESTART, 0, "--records", &r);
    if (!f)
        return;
    CHECKF(t, r.rc == 0, "exit %d: %s", r.rc, r.out);
    char want[64];
    snprintf(want, sizeof want, "resuming at batch %u", f->cut_batch);
    CHECKF(t, strstr(r.out, want) != NULL, "no resume reported: %s", r.out);
    CHECKF(t, strstr(r.out, "\"complete\":true") && strstr(r.out, "\"verified\":true") &&
                  strstr(r.out, "\"form\":\"splits\"") && !strstr(r.out, "stale"),
           "%s", r.out);
    same_as_unbroken(t, f, r.out, 1);
}

static void test_server_never_back(mts_test *t)
{
    /* 3 tries: waits of 0.1, 0.2, 0.4 s, each at least half that (jitter) */
    client_run r;
    if (!broken_case(t, NULL, AFTER_CUT_NOTHING, 0, "--retries 3", &r))
        return;
    CHECKF(t, r.rc == 1, "exit %d: %s", r.rc, r.out);
    CHECKF(t, strstr(r.out, "gave up after 3 tries") && strstr(r.out, "refused") &&
                  strstr(r.out, "(try 3/3)") && !strstr(r.out, "(try 4/"),
           "%s", r.out);
    CHECKF(t, strstr(r.out, "\"complete\":false") && strstr(r.out, "\"batches\":10,"), "%s", r.out);
    if (getenv("MTS_TEST_VERBOSE"))
        fprintf(stderr, "  gave up %.2f s after the cut:\n%s", r.secs, r.out);
    CHECKF(t, r.secs >= 0.35 && r.secs < 5,
           "gave up %.2f s after the cut (want 0.35 .. 0.7 s and the client's own start and exit)",
           r.secs);
}

static void test_stale_stream_not_retried(mts_test *t)
{
    client_run r;
    if (!broken_case(t, NULL, AFTER_CUT_OTHER_MODEL, 0, "", &r))
        return;
    CHECKF(t, r.rc == 1, "exit %d: %s", r.rc, r.out);
    CHECKF(t, strstr(r.out, "stale") && strstr(r.out, "cannot resume at batch 10"), "%s", r.out);
    CHECKF(t, strstr(r.out, "\"complete\":false") && strstr(r.out, "\"batches\":10,"), "%s", r.out);
    /* the answer ends it: no try after the one that got ERROR stale */
    const char *stale = strstr(r.out, "stale");
    CHECKF(t, stale && !strstr(stale, "retrying in"), "%s", r.out);
    CHECKF(t, r.secs < 5, "ended %.2f s after the cut", r.secs);
    if (getenv("MTS_TEST_VERBOSE"))
        fprintf(stderr, "  ended %.2f s after the cut:\n%s", r.secs, r.out);
}

int main(int argc, char **argv)
{
    (void)argc;
    mts_test_bin_dir(argv[0], bin_dir, sizeof bin_dir);
    snprintf(tmp_dir, sizeof tmp_dir, "%s", mts_test_tmpdir());
    signal(SIGPIPE, SIG_IGN);
    mts_test t = {0};
    RUN(&t, test_cut_anywhere_then_resume);
    RUN(&t, test_other_stream_refused);
    RUN(&t, test_cut_anywhere_then_resume_records);
    RUN(&t, test_continue_past_the_stop);
    RUN(&t, test_other_form_refused);
    RUN(&t, test_server_killed_and_restarted);
    RUN(&t, test_server_killed_and_restarted_records);
    RUN(&t, test_resume_asks_for_the_form_held);
    RUN(&t, test_server_never_back);
    RUN(&t, test_stale_stream_not_retried);
    if (cow_state > 0)
        mts_model_free(&cow);
    return mts_test_end(&t);
}
