/* Vertex colours on the wire: Draco keeps the base's byte colours exactly;
 * a coloured model streamed (splits and records forms) leaves the client,
 * after every batch, with the model's colours for every vertex present, bit
 * for bit, and END's checksum counts them; a resumed client keeps those it
 * has; a damaged colour is refused by name (CRC, a residual off the 0..255
 * range, END's checksum, a base without colours); and a model without
 * colours streams byte for byte as before colours existed. */
#include <stdint.h>

#include "build.h"
#include "color_field.h"
#include "crc32c.h"
#include "draco.h"
#include "mesh.h"
#include "stream.h"
#include "test.h"
#include "test_proc.h"
#include "varint.h"
#include "wire.h"

static int build_model(mts_test *t, const char *path, mts_model *m)
{
    mts_error err = {0};
    mts_mesh mesh = {0};
    if (mts_mesh_load(path, NULL, &mesh, NULL, &err) != MTS_OK) {
        CHECKF(t, 0, "%s: %s", path, err.msg);
        return 0;
    }
    mts_result rc = mts_build_model(&mesh, path, NULL, m, NULL, &err);
    mts_mesh_free(&mesh);
    CHECKF(t, rc == MTS_OK, "%s: %s", path, err.msg);
    return rc == MTS_OK;
}

/* which 0: cow.off with the smooth field; 1: cow_colors.ply, the builder's
 * reading of a coloured file */
static int colored_model(mts_test *t, int which, mts_model *m)
{
    if (!build_model(t, which ? "tests/data/cow_colors.ply" : "tests/data/cow.off", m))
        return 0;
    if (which == 0 && !mts_test_color_field(m)) {
        mts_model_free(m);
        CHECK(t, 0);
        return 0;
    }
    CHECKF(t, (m->flags & MTS_MODEL_COLORS) && m->colors, "model %d has no colours", which);
    if (!m->colors) {
        mts_model_free(m);
        return 0;
    }
    return 1;
}

static int colored_stream(mts_test *t, int which, uint32_t batch_splits, mts_stream *s)
{
    mts_model m;
    if (!colored_model(t, which, &m))
        return 0;
    mts_error err = {0};
    mts_stream_options o = {0};
    o.with_records = 1;
    o.batch_splits = batch_splits;
    mts_result rc = mts_stream_build(&m, "cow", &o, s, &err);
    /* the stream's copy stands for the model: a split vertex keeps its id
     * (only the base is renumbered, to grid order) and its colour */
    if (rc == MTS_OK) {
        const size_t nb = m.base_vertex_count, nv = m.vertex_count;
        CHECK(t, s->model.colors && s->model.colors != m.colors &&
                     memcmp(s->model.colors + 3 * nb, m.colors + 3 * nb, (nv - nb) * 3) == 0);
        /* base colours: the same, each with its vertex's grid point */
        size_t found = 0;
        for (size_t x = 0; x < nb; x++) {
            uint32_t q[3];
            mts_draco_quantize(&s->grid, m.positions + 3 * x, q);
            for (size_t y = 0; y < nb; y++)
                if (memcmp(s->quantized + 3 * y, q, 12) == 0 &&
                    memcmp(s->model.colors + 3 * y, m.colors + 3 * x, 3) == 0) {
                    found++;
                    break;
                }
        }
        CHECKF(t, found == nb, "%zu of %zu base colours found", found, nb);
    }
    mts_model_free(&m);
    CHECKF(t, rc == MTS_OK, "stream: %s", err.msg);
    return rc == MTS_OK;
}

/* What a connection is sent: MODEL_INFO, the range from resume_batch, END. */
static void connection(const mts_stream *s, uint32_t stop, uint32_t resume_batch, mts_buf *out)
{
    mts_error err = {0};
    mts_stream_put_model_info(s, stop, out);
    size_t off, len;
    if (mts_stream_range(s, resume_batch, stop, &off, &len, &err) != MTS_OK)
        return;
    mts_buf_put(out, s->bytes + off, len);
    mts_stream_put_end(s, stop, (uint32_t)out->size, out);
}

/* The client's colours are the stream model's for every vertex it has
 * decoded (the vertices of every split it holds, past its level too). */
static int same_colors(const mts_stream *s, const mts_stream_client *c)
{
    const size_t nv = (size_t)s->model.base_vertex_count + c->splits;
    return (c->model.flags & MTS_MODEL_COLORS) && c->model.colors && c->vertex_room >= nv &&
           memcmp(c->model.colors, s->model.colors, nv * 3) == 0;
}

/* Draco 1.5.5 keeps an unsigned-byte COLOR attribute exactly, with either
 * method and at every compression level we use; none goes in, none comes
 * out. */
static void test_draco_colors_lossless(mts_test *t)
{
    mts_model m;
    if (!colored_model(t, 1, &m))
        return;
    uint32_t nt = 0;
    uint32_t *tris = malloc((size_t)m.full.index_count * 12 + 12);
    for (uint32_t st = 0; tris && st < m.strip_count; st++)
        for (uint32_t k = m.full.offsets[st]; k + 2 < m.full.offsets[st + 1]; k++)
            nt += (uint32_t)mts_strip_window(m.full.indices + m.full.offsets[st],
                                             k - m.full.offsets[st], tris + 3 * (size_t)nt);
    uint32_t *map = malloc((size_t)m.vertex_count * 4);
    CHECK(t, tris && map && nt > 0);
    const int levels[3] = {-1, 7, 10};
    for (int method = 0; method < 2 && tris && map; method++)
        for (int l = 0; l < 3; l++)
            for (int with = 0; with < 2; with++) {
                mts_draco_mesh in = {m.vertex_count, nt, m.positions, NULL, tris,
                                     with ? m.colors : NULL, NULL};
                mts_draco_options o = {0};
                o.method = method;
                o.compression_level = levels[l];
                mts_error err = {0};
                uint8_t *bytes = NULL;
                size_t size = 0;
                mts_draco_mesh_out dec = {0};
                mts_result rc = mts_draco_encode(&in, &o, &bytes, &size, &err);
                if (rc == MTS_OK)
                    rc = mts_draco_decode(bytes, size, &dec, &err);
                if (rc == MTS_OK)
                    rc = mts_draco_renumber(&in, &dec, map, NULL, &err);
                CHECKF(t, rc == MTS_OK, "method %d cl %d: %s", method, levels[l], err.msg);
                CHECK(t, rc != MTS_OK || !!dec.colors == with);
                uint32_t wrong = 0;
                for (uint32_t x = 0; rc == MTS_OK && with && x < m.vertex_count; x++)
                    wrong += memcmp(dec.colors + 3 * (size_t)map[x], m.colors + 3 * (size_t)x, 3) != 0;
                CHECKF(t, wrong == 0, "method %d cl %d: %u colours changed", method, levels[l],
                       wrong);
                free(bytes);
                mts_draco_mesh_out_free(&dec);
            }
    free(tris);
    free(map);
    mts_model_free(&m);
}

/* Both forms, both colour sources, batches of 16 splits (180 levels apart
 * on cow's 2,875): after the base and after every batch the client holds
 * the model's colours for every vertex it has, and END checks them. */
static void test_colors_every_batch(mts_test *t)
{
    for (int which = 0; which < 2 && !t->case_failed; which++) {
        mts_stream s;
        if (!colored_stream(t, which, 16, &s))
            return;
        const uint32_t n = s.model.level_count;
        for (int form = 0; form < 2 && !t->case_failed; form++) {
            const mts_stream *x = form ? s.records_form : &s;
            mts_buf b = {0};
            connection(x, n, 0, &b);
            mts_stream_client c;
            mts_stream_client_init(&c);
            mts_error err = {0};
            mts_stream_event ev;
            int got, checked = 0, ended = 0;
            CHECK(t, mts_stream_client_feed(&c, b.data, b.size, &err) == MTS_OK);
            while ((got = mts_stream_client_next(&c, &ev, &err)) > 0) {
                if (ev == MTS_EV_INFO)
                    CHECK(t, (c.info.flags & MTS_INFO_COLORS) &&
                                 !!(c.info.flags & MTS_INFO_RECORDS) == form);
                if (ev == MTS_EV_BASE || ev == MTS_EV_BATCH) {
                    CHECKF(t, same_colors(x, &c), "which %d form %d: colours differ after %u splits",
                           which, form, c.splits);
                    checked++;
                }
                ended += ev == MTS_EV_END;
            }
            CHECKF(t, got == 0 && ended == 1, "which %d form %d: %s", which, form, err.msg);
            CHECK(t, checked == 1 + (int)s.batch_count && c.lod.level == n);
            CHECK(t, c.checksum == s.level_checksum[n] && c.end_checksum == c.checksum);
            /* the colours are in the checksum: without them it is another */
            CHECK(t, mts_stream_checksum(&c.lod, c.quantized) != c.checksum &&
                         mts_stream_checksum_colors(&c.lod, c.quantized, NULL) ==
                             mts_stream_checksum(&c.lod, c.quantized));
            /* a client at any level moves down and up with them in place */
            mts_error e2 = {0};
            CHECK(t, mts_lod_set_level(&c.lod, n / 3, &e2) == MTS_OK && same_colors(x, &c));
            mts_stream_client_free(&c);
            mts_buf_free(&b);
        }
        /* stops: the client ends at each with its colours and END's checksum */
        const uint32_t stops[] = {0, 1, 17, n / 3, n / 2 + 5, n - 1};
        for (size_t i = 0; i < sizeof stops / sizeof stops[0] && !t->case_failed; i++)
            for (int form = 0; form < 2; form++) {
                const mts_stream *x = form ? s.records_form : &s;
                mts_buf b = {0};
                connection(x, stops[i], 0, &b);
                mts_stream_client c;
                mts_stream_client_init(&c);
                mts_error err = {0};
                mts_test_events ev = {0};
                mts_result rc = mts_test_feed(&c, b.data, b.size, 31 + i, 700, &ev, &err);
                CHECKF(t, rc == MTS_OK && ev.end == 1, "stop %u form %d: %s", stops[i], form,
                       err.msg);
                CHECK(t, c.lod.level == stops[i] && c.checksum == s.level_checksum[stops[i]] &&
                             same_colors(x, &c));
                mts_stream_client_free(&c);
                mts_buf_free(&b);
            }
        mts_stream_free(&s);
    }
}

/* A connection cut inside a batch, then a resume: the client keeps the
 * colours it had and the batches that follow bring the rest. */
static void test_colors_resume(mts_test *t)
{
    mts_stream s;
    if (!colored_stream(t, 0, 64, &s))
        return;
    const uint32_t n = s.model.level_count;
    for (int form = 0; form < 2 && !t->case_failed; form++) {
        const mts_stream *x = form ? s.records_form : &s;
        const uint32_t k = x->batch_count / 2;
        mts_buf b = {0};
        connection(x, n, 0, &b);
        mts_buf info = {0};
        mts_stream_put_model_info(x, n, &info);
        /* MODEL_INFO, BASE, batches 0..k-1 and half of batch k */
        const size_t cut = info.size + x->batch_offset[k] +
                           (x->batch_offset[k + 1] - x->batch_offset[k]) / 2;
        mts_stream_client c;
        mts_stream_client_init(&c);
        mts_error err = {0};
        mts_test_events ev = {0};
        CHECKF(t, mts_test_feed(&c, b.data, cut, 5, 900, &ev, &err) == MTS_OK, "%s", err.msg);
        CHECK(t, c.batches == k && ev.end == 0 && same_colors(x, &c));
        uint32_t resume_batch;
        uint64_t id;
        CHECK(t, mts_stream_client_resume_point(&c, &resume_batch, &id) && resume_batch == k &&
                     id == x->stream_id);
        CHECK(t, mts_stream_client_reconnected(&c, &err) == MTS_OK);
        mts_buf again = {0};
        connection(x, n, k, &again);
        ev = (mts_test_events){0};
        CHECKF(t, mts_test_feed(&c, again.data, again.size, 6, 900, &ev, &err) == MTS_OK,
               "form %d: %s", form, err.msg);
        CHECK(t, ev.resumed == 1 && ev.end == 1 && c.lod.level == n && same_colors(x, &c));
        CHECK(t, c.checksum == s.level_checksum[n]);
        mts_stream_client_free(&c);
        mts_buf_free(&again);
        mts_buf_free(&info);
        mts_buf_free(&b);
    }
    mts_stream_free(&s);
}

static uint32_t get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* Feeds MODEL_INFO and what follows of x's bytes up to `upto`, then the
 * frame `frame` of size `size` (replacing x's frame there), or with x NULL
 * only those bytes; after BASE, `tamper` may change the client's state.
 * Returns the first error. */
static mts_result feed_until(const mts_stream *x, size_t upto, const uint8_t *frame, size_t size,
                             void (*tamper)(mts_stream_client *), mts_stream_client *c,
                             mts_error *err)
{
    mts_buf b = {0};
    if (x) {
        mts_stream_put_model_info(x, x->model.level_count, &b);
        mts_buf_put(&b, x->bytes, upto);
    }
    if (frame)
        mts_buf_put(&b, frame, size);
    mts_stream_client_init(c);
    mts_result rc = mts_stream_client_feed(c, b.data, b.size, err);
    mts_stream_event ev;
    int got;
    while (rc == MTS_OK && (got = mts_stream_client_next(c, &ev, err)) != 0) {
        if (got < 0)
            rc = err->code;
        else if (ev == MTS_EV_BASE && tamper)
            tamper(c);
    }
    mts_buf_free(&b);
    return rc;
}

static void all_white(mts_stream_client *c)
{
    memset(c->model.colors, 255, (size_t)c->model.base_vertex_count * 3);
}

static void one_off(mts_stream_client *c)
{
    /* a channel away from both ends: one step is still a colour */
    for (uint32_t x = 0; x < c->model.base_vertex_count * 3; x++)
        if (c->model.colors[x] > 0 && c->model.colors[x] < 255) {
            c->model.colors[x] ^= 1;
            return;
        }
}

static void test_colors_damaged(mts_test *t)
{
    mts_stream s;
    if (!colored_stream(t, 0, 64, &s))
        return;
    const mts_stream *r = s.records_form;
    const uint32_t last = s.batch_count - 1, n = s.model.level_count;
    mts_stream_client c;
    mts_error err = {0};

    /* a flipped bit in a batch (colours run through every body): its CRC */
    {
        const size_t at = s.batch_offset[last], size = s.batch_offset[last + 1] - at;
        uint8_t *f = malloc(size);
        memcpy(f, s.bytes + at, size);
        f[size / 2] ^= 0x10;
        mts_result rc = feed_until(&s, at, f, size, NULL, &c, &err);
        CHECKF(t, rc == MTS_ERR_CHECKSUM && c.rejected && c.batches == last, "%d %s", rc,
               err.msg);
        mts_stream_client_free(&c);
        free(f);
    }
    /* records form: the last split's blue put 300 above its parent's, the
     * frame sealed again: off the range, by name */
    {
        const size_t at = r->batch_offset[last], size = r->batch_offset[last + 1] - at;
        const uint8_t *f = r->bytes + at;
        size_t end = size - 4; /* the CRC */
        size_t start = end - 1;
        while (start > MTS_WIRE_HEADER && (f[start - 1] & 0x80))
            start--;
        mts_buf g = {0};
        mts_buf_put(&g, f, start);
        mts_buf_varint(&g, mts_zigzag_u32(300));
        mts_buf_u32(&g, 0);
        uint8_t *p = g.data;
        const uint32_t len = (uint32_t)g.size - 4;
        p[0] = (uint8_t)len, p[1] = (uint8_t)(len >> 8), p[2] = (uint8_t)(len >> 16),
        p[3] = (uint8_t)(len >> 24);
        const uint32_t crc = mts_crc32c(0, p + MTS_WIRE_HEADER, g.size - MTS_WIRE_HEADER - 4);
        for (int i = 0; i < 4; i++)
            p[g.size - 4 + i] = (uint8_t)(crc >> (8 * i));
        CHECK(t, get_u32(p + g.size - 4) == crc);
        mts_result rc = feed_until(r, at, g.data, g.size, NULL, &c, &err);
        CHECKF(t, rc == MTS_ERR_RANGE && strstr(err.msg, "colour is off the 0..255 range"),
               "%d %s", rc, err.msg);
        mts_stream_client_free(&c);
        mts_buf_free(&g);
    }
    /* splits form: predictions from other base colours than the server's
     * take a residual past 255, refused by name */
    {
        mts_result rc = feed_until(&s, s.size, NULL, 0, all_white, &c, &err);
        CHECKF(t, rc == MTS_ERR_RANGE && strstr(err.msg, "colour is off the 0..255 range"),
               "%d %s", rc, err.msg);
        mts_stream_client_free(&c);
    }
    /* a colour one step off (its children follow it, in range): END's
     * checksum finds it, in both forms */
    for (int form = 0; form < 2; form++) {
        const mts_stream *x = form ? r : &s;
        mts_buf b = {0};
        connection(x, n, 0, &b);
        mts_result rc = feed_until(NULL, 0, b.data, b.size, one_off, &c, &err);
        CHECKF(t, (rc == MTS_ERR_CHECKSUM && strstr(err.msg, "END")) || rc == MTS_ERR_RANGE,
               "form %d: %d %s", form, rc, err.msg);
        CHECK(t, form == 0 || rc == MTS_ERR_CHECKSUM); /* the records form predicts nothing */
        mts_stream_client_free(&c);
        mts_buf_free(&b);
    }
    /* a MODEL_INFO with colours before a BASE without them */
    {
        mts_model m;
        if (build_model(t, "tests/data/cow.off", &m)) {
            mts_stream plain;
            if (mts_stream_build(&m, "cow", NULL, &plain, &err) == MTS_OK) {
                mts_buf b = {0};
                mts_stream_put_model_info(&s, n, &b);
                mts_buf_put(&b, plain.bytes, plain.batch_offset[0]);
                mts_stream_client_init(&c);
                mts_test_events ev = {0};
                mts_result rc = mts_test_feed(&c, b.data, b.size, 1, 500, &ev, &err);
                CHECKF(t, rc == MTS_ERR_FORMAT && strstr(err.msg, "there are colours"), "%d %s",
                       rc, err.msg);
                mts_stream_client_free(&c);
                mts_buf_free(&b);
                mts_stream_free(&plain);
            }
            mts_model_free(&m);
        }
    }
    mts_stream_free(&s);
}

static uint64_t fnv64(const uint8_t *p, size_t n)
{
    uint64_t h = 0xcbf29ce484222325ull;
    for (size_t i = 0; i < n; i++)
        h = (h ^ p[i]) * 0x100000001b3ull;
    return h;
}

/* cow.off without colours streams exactly as the code before colours did
 * (1d93558, built in a separate worktree): the same BASE and BATCH bytes,
 * stream_id, MODEL_INFO tail and checksums, in both forms; a model holding
 * colours without MTS_MODEL_COLORS streams the same. Only MODEL_INFO's
 * minor version (7.1) differs from a 7.0 server's connection. */
static void test_uncolored_unchanged(mts_test *t)
{
    mts_model m;
    if (!build_model(t, "tests/data/cow.off", &m))
        return;
    for (int stray = 0; stray < 2 && !t->case_failed; stray++) {
        if (stray) {
            CHECK(t, mts_test_color_field(&m));
            m.flags &= ~MTS_MODEL_COLORS;
        }
        mts_error err = {0};
        mts_stream_options o = {0};
        o.with_records = 1;
        mts_stream s;
        if (mts_stream_build(&m, "cow", &o, &s, &err) != MTS_OK) {
            CHECKF(t, 0, "%s", err.msg);
            break;
        }
        const mts_stream *r = s.records_form;
        CHECKF(t, s.size == 14911 && fnv64(s.bytes, s.size) == 0xcef17638572209b2ull &&
                      s.stream_id == 0xcef1763857227dccull,
               "splits form: %zu bytes, hash %016llx, id %016llx", s.size,
               (unsigned long long)fnv64(s.bytes, s.size), (unsigned long long)s.stream_id);
        CHECKF(t, r->size == 230310 && fnv64(r->bytes, r->size) == 0x6f0e92a99990a2a7ull &&
                      r->stream_id == 0x6f0e92a99997a5ebull,
               "records form: %zu bytes, hash %016llx, id %016llx", r->size,
               (unsigned long long)fnv64(r->bytes, r->size), (unsigned long long)r->stream_id);
        CHECK(t, s.info_tail_size == 63 &&
                     fnv64(s.info_tail, s.info_tail_size) == 0xf84cc5503ef5f8baull);
        CHECK(t, s.level_checksum[s.model.level_count] == 0x06b1caa758e03f3eull);
        CHECK(t, s.model.colors == NULL && !(s.model.flags & MTS_MODEL_COLORS));
        mts_buf b = {0};
        mts_stream_put_model_info(&s, s.model.level_count, &b);
        mts_wire_model_info mi = {0};
        CHECK(t, b.size == 95 && mts_wire_parse_model_info(b.data + MTS_WIRE_HEADER,
                                                           b.size - MTS_WIRE_HEADER, &mi,
                                                           &err) == MTS_OK);
        CHECK(t, mi.minor == 1 && !(mi.flags & MTS_INFO_COLORS));
        mts_wire_model_info_free(&mi);
        mts_buf_free(&b);
        mts_stream_free(&s);
    }
    mts_model_free(&m);
}

/* What colours cost on cow (asserted loosely, the figures are
 * docs/colors.md's): the coloured stream within 1.5x of Draco coding the
 * full mesh's positions and colours on the same grid. */
static void test_colors_cost(mts_test *t)
{
    for (int which = 0; which < 2 && !t->case_failed; which++) {
        mts_model m;
        if (!colored_model(t, which, &m))
            return;
        mts_error err = {0};
        mts_stream_breakdown bd;
        mts_stream_options o = {0};
        o.breakdown = &bd;
        mts_stream s;
        if (mts_stream_build(&m, "cow", &o, &s, &err) != MTS_OK) {
            CHECKF(t, 0, "%s", err.msg);
            mts_model_free(&m);
            return;
        }
        uint32_t nt = 0;
        uint32_t *tris = malloc((size_t)m.full.index_count * 12 + 12);
        for (uint32_t st = 0; tris && st < m.strip_count; st++)
            for (uint32_t k = m.full.offsets[st]; k + 2 < m.full.offsets[st + 1]; k++)
                nt += (uint32_t)mts_strip_window(m.full.indices + m.full.offsets[st],
                                                 k - m.full.offsets[st], tris + 3 * (size_t)nt);
        mts_draco_mesh dm = {m.vertex_count, nt, m.positions, NULL, tris, m.colors, NULL};
        mts_draco_options dopt = {0};
        dopt.grid = s.grid;
        dopt.compression_level = 7;
        uint8_t *out = NULL;
        size_t draco = 0;
        CHECK(t, tris && mts_draco_encode(&dm, &dopt, &out, &draco, &err) == MTS_OK);
        const size_t full = bd.info_bytes + s.size + bd.end_bytes;
        const double color_bits = bd.color_bits / bd.splits;
        CHECKF(t, full <= 1.5 * draco && color_bits > 1 && color_bits < 24,
               "which %d: stream %zu B, Draco %zu B, %.2f colour bits a split", which, full,
               draco, color_bits);
        free(out);
        free(tris);
        mts_stream_free(&s);
        mts_model_free(&m);
    }
}

int main(void)
{
    mts_test t = {0};
    RUN(&t, test_draco_colors_lossless);
    RUN(&t, test_uncolored_unchanged);
    RUN(&t, test_colors_every_batch);
    RUN(&t, test_colors_resume);
    RUN(&t, test_colors_damaged);
    RUN(&t, test_colors_cost);
    return mts_test_end(&t);
}
