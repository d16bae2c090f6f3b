/* Stream files in memory: the file holds the wire's frames byte for byte;
 * every stop read from it by its ranges (levels inside batches and at their
 * ends, triangle budgets, fractions) ends at the level mts-server would stop
 * at, with the server's mesh and checksum there; the bytes read are the
 * TCP connection's plus the header and index; resumes and continuations ask
 * only for the batches not held; and a damaged file (header, table, checks,
 * a frame, cut short) is refused by name with nothing of a bad batch
 * applied. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "build.h"
#include "mesh.h"
#include "stream.h"
#include "stream_file.h"
#include "test.h"
#include "wire.h"

static int build_stream(mts_test *t, const char *path, const char *name, int records,
                        mts_stream *s)
{
    mts_error err = {0};
    mts_mesh mesh = {0};
    mts_model m = {0};
    if (mts_mesh_load(path, NULL, &mesh, NULL, &err) != MTS_OK) {
        CHECKF(t, 0, "%s", err.msg);
        return 0;
    }
    mts_result rc = mts_build_model(&mesh, path, NULL, &m, NULL, &err);
    mts_mesh_free(&mesh);
    mts_stream_options o = {0};
    o.with_records = records;
    if (rc == MTS_OK)
        rc = mts_stream_build(&m, name, &o, s, &err);
    mts_model_free(&m);
    CHECKF(t, rc == MTS_OK, "%s: %s", path, err.msg);
    return rc == MTS_OK;
}

/* Takes every whole frame c holds; -1 on an error (in err). */
static int take_all(mts_stream_client *c, mts_error *err)
{
    mts_stream_event ev;
    int got;
    while ((got = mts_stream_client_next(c, &ev, err)) > 0)
        ;
    return got;
}

/* Reads [plan.from, plan.to) of file into c in pieces from seed, taking the
 * frames as they come. */
static mts_result feed_range(mts_stream_file_reader *r, mts_stream_client *c,
                             const mts_buf *file, uint64_t seed, mts_error *err)
{
    uint64_t at = r->plan.from;
    while (at < r->plan.to) {
        seed = seed * 6364136223846793005ull + 1442695040888963407ull;
        size_t n = 1 + (size_t)((seed >> 33) % 1500);
        if (n > r->plan.to - at)
            n = (size_t)(r->plan.to - at);
        mts_result rc = mts_stream_file_reader_feed(r, c, file->data + at, n, err);
        if (rc != MTS_OK)
            return rc;
        if (take_all(c, err) < 0)
            return err->code;
        at += n;
    }
    return MTS_OK;
}

/* A fresh client reads a stop from the file: the level and checksum it ends
 * with, or an error. */
static mts_result read_stop_with(mts_stream_file_reader *rp, const mts_buf *file,
                                 const mts_stream_file_index *idx, uint8_t kind, uint32_t value,
                                 uint64_t seed, mts_stream_client *c, uint64_t *bytes,
                                 mts_error *err)
{
    mts_stream_file_plan plan;
    mts_stream_file_reader r = *rp;
    mts_stream_client_init(c);
    mts_result rc = mts_stream_file_plan_stop(idx, kind, value, 0, &plan, err);
    if (rc == MTS_OK)
        rc = mts_stream_file_reader_begin(&r, idx, &plan, c, err);
    if (rc == MTS_OK && take_all(c, err) < 0)
        rc = err->code;
    if (rc == MTS_OK)
        rc = feed_range(&r, c, file, seed, err);
    mts_stream_event ev = MTS_EV_NONE;
    if (rc == MTS_OK)
        rc = mts_stream_file_reader_end(&r, c, &ev, err);
    if (rc == MTS_OK && ev != MTS_EV_END)
        rc = mts_error_set(err, MTS_ERR_INTERNAL, "no END");
    if (bytes)
        *bytes = idx->prefix_size + (plan.to - plan.from);
    *rp = r;
    return rc;
}

static mts_result read_stop(const mts_buf *file, const mts_stream_file_index *idx, uint8_t kind,
                            uint32_t value, uint64_t seed, mts_stream_client *c,
                            uint64_t *bytes, mts_error *err)
{
    mts_stream_file_reader r = {0};
    mts_result rc = read_stop_with(&r, file, idx, kind, value, seed, c, bytes, err);
    mts_stream_file_reader_free(&r);
    return rc;
}

/* The bytes of a TCP connection for the same stop, END apart, with the
 * MODEL_INFO of the full level (the file's: a stop's differs in its varints). */
static size_t tcp_bytes(const mts_stream *s, uint32_t stop)
{
    mts_error err = {0};
    mts_buf b = {0};
    mts_stream_put_model_info(s, s->model.level_count, &b);
    size_t off, len, info = b.size;
    mts_buf_free(&b);
    if (mts_stream_range(s, 0, stop, &off, &len, &err) != MTS_OK)
        return 0;
    return info + len;
}

static void check_stops(mts_test *t, const mts_stream *s, const mts_buf *file)
{
    mts_error err = {0};
    mts_stream_file_index idx;
    mts_result rc = mts_stream_file_index_parse(file->data, file->size, 0, &idx, &err);
    CHECKF(t, rc == MTS_OK, "%s", err.msg);
    if (rc != MTS_OK)
        return mts_stream_file_index_free(&idx);
    const uint32_t levels = s->model.level_count;
    const uint64_t index_bytes = file->size - (tcp_bytes(s, levels));
    /* the header, table and checks: what a file costs beyond the frames */
    CHECKF(t, index_bytes < 64 + 16ull * (s->batch_count + 1), "index of %llu bytes",
           (unsigned long long)index_bytes);
    struct {
        uint8_t kind;
        uint32_t value;
    } stops[64];
    int n = 0;
    stops[n].kind = MTS_STOP_LEVEL, stops[n++].value = 0;
    stops[n].kind = MTS_STOP_LEVEL, stops[n++].value = levels;
    stops[n].kind = MTS_STOP_LEVEL, stops[n++].value = levels + 7;
    for (uint32_t k = 1; k <= 3 && k < s->batch_count; k++) {
        stops[n].kind = MTS_STOP_LEVEL, stops[n++].value = s->batch_first[k];     /* a boundary */
        stops[n].kind = MTS_STOP_LEVEL, stops[n++].value = s->batch_first[k] + 1; /* just past */
        stops[n].kind = MTS_STOP_LEVEL, stops[n++].value = s->batch_first[k] - 1; /* just before */
    }
    for (uint32_t k = 1; k < 8; k++) {
        stops[n].kind = MTS_STOP_LEVEL, stops[n++].value = levels / 8 * k + k * 13;
        const uint32_t full = s->model.level_triangles[levels];
        stops[n].kind = MTS_STOP_TRIANGLES, stops[n++].value = full / 8 * k + k;
        stops[n].kind = MTS_STOP_FRACTION, stops[n++].value = 125000 * k - 777;
    }
    /* triangle budgets exactly at, and one below, the first split of a batch */
    for (uint32_t k = 1; k <= 2 && k < s->batch_count; k++) {
        stops[n].kind = MTS_STOP_TRIANGLES,
        stops[n++].value = s->model.level_triangles[s->batch_first[k] + 1];
        stops[n].kind = MTS_STOP_TRIANGLES,
        stops[n++].value = s->model.level_triangles[s->batch_first[k] + 1] - 1;
    }
    stops[n].kind = MTS_STOP_TRIANGLES, stops[n++].value = 0;
    for (int i = 0; i < n && !t->case_failed; i++) {
        mts_stream_client c;
        uint64_t bytes = 0;
        rc = read_stop(file, &idx, stops[i].kind, stops[i].value, 977 + i, &c, &bytes, &err);
        const uint32_t want = mts_stream_stop_level(s, stops[i].kind, stops[i].value);
        CHECKF(t, rc == MTS_OK, "stop %u/%u: %s", stops[i].kind, stops[i].value, err.msg);
        if (rc == MTS_OK) {
            CHECKF(t, c.lod.level == want && c.stop_level == want,
                   "stop %u/%u: at level %u, the server stops at %u", stops[i].kind,
                   stops[i].value, c.lod.level, want);
            CHECKF(t, c.checksum == s->level_checksum[want],
                   "stop %u/%u: checksum differs at level %u", stops[i].kind, stops[i].value,
                   want);
            CHECK(t, c.info.stop_triangles == s->model.level_triangles[want]);
            /* a coloured stream's colours, every vertex at the stop (END's
             * checksum sums them too) */
            const size_t nv = (size_t)s->model.base_vertex_count + want;
            CHECKF(t, !s->model.colors ||
                          ((c.model.flags & MTS_MODEL_COLORS) && c.vertex_room >= nv &&
                           memcmp(c.model.colors, s->model.colors, nv * 3) == 0),
                   "stop %u/%u: colours differ at level %u", stops[i].kind, stops[i].value, want);
            CHECK(t, !!s->model.colors == !!c.model.colors);
            /* what a client fetches: the TCP connection's bytes and the index */
            CHECKF(t, bytes == tcp_bytes(s, want) + index_bytes,
                   "stop %u/%u: %llu bytes read, TCP %zu + index %llu", stops[i].kind,
                   stops[i].value, (unsigned long long)bytes, tcp_bytes(s, want),
                   (unsigned long long)index_bytes);
        }
        mts_stream_client_free(&c);
    }
    mts_stream_file_index_free(&idx);
}

static void test_frames_are_the_wire(mts_test *t)
{
    mts_stream s = {0};
    if (!build_stream(t, "tests/data/cow.off", "cow", 0, &s))
        return;
    mts_error err = {0};
    mts_buf file = {0};
    CHECKF(t, mts_stream_file_write(&s, &file, &err) == MTS_OK, "%s", err.msg);
    mts_stream_file_index idx;
    CHECKF(t, mts_stream_file_index_parse(file.data, file.size, 0, &idx, &err) == MTS_OK, "%s",
           err.msg);
    if (!t->case_failed) {
        /* MODEL_INFO, BASE and every BATCH where the index says, as sent */
        mts_buf info = {0};
        mts_stream_put_model_info(&s, s.model.level_count, &info);
        CHECK(t, memcmp(file.data + MTS_SFILE_HEADER_SIZE, info.data, info.size) == 0);
        const size_t base = s.batch_count ? s.batch_offset[0] : s.size;
        CHECK(t, idx.base_size == base &&
                     memcmp(file.data + idx.base_offset, s.bytes, base) == 0);
        CHECK(t, idx.batch_count == s.batch_count);
        for (uint32_t k = 0; k < s.batch_count && !t->case_failed; k++)
            CHECKF(t, memcmp(file.data + idx.batch_offset[k], s.bytes + s.batch_offset[k],
                             s.batch_offset[k + 1] - s.batch_offset[k]) == 0,
                   "batch %u", k);
        CHECK(t, idx.batch_offset[s.batch_count] == file.size);
        CHECK(t, idx.boundary_triangles[s.batch_count] == s.model.level_triangles[s.model.level_count]);
        mts_buf_free(&info);
    }
    mts_stream_file_index_free(&idx);
    mts_buf_free(&file);
    mts_stream_free(&s);
}

static void stops_of(mts_test *t, const char *path, int records)
{
    mts_stream s = {0};
    if (!build_stream(t, path, "m", records, &s))
        return;
    mts_error err = {0};
    mts_buf file = {0};
    const mts_stream *form = records ? s.records_form : &s;
    CHECKF(t, mts_stream_file_write(form, &file, &err) == MTS_OK, "%s", err.msg);
    if (!t->case_failed)
        check_stops(t, form, &file);
    mts_buf_free(&file);
    mts_stream_free(&s);
}

static void test_cow_stops(mts_test *t)
{
    stops_of(t, "tests/data/cow.off", 0);
}

static void test_cow_records_form_stops(mts_test *t)
{
    stops_of(t, "tests/data/cow.off", 1);
}

/* A coloured model (the builder reads the PLY's colours): the file's
 * frames carry them as the wire does, and every stop ends with them. */
static void test_colored_cow_stops(mts_test *t)
{
    stops_of(t, "tests/data/cow_colors.ply", 0);
    stops_of(t, "tests/data/cow_colors.ply", 1);
}

static void test_shared_model_stops(mts_test *t)
{
    char path[1024];
    const char *names[] = {"bunny00.off", "fandisk_large.off"};
    for (int i = 0; i < 2; i++) {
        if (!mts_test_model(names[i], path, sizeof path)) {
            SKIP(t, "%s not found (../shared/models)", names[i]);
            return;
        }
        stops_of(t, path, 0);
    }
}

/* A preview, continued twice: each continuation asks only for the batches
 * past those held, and ends at the server's mesh. */
static void test_continue_and_resume(mts_test *t)
{
    mts_stream s = {0};
    if (!build_stream(t, "tests/data/cow.off", "cow", 0, &s))
        return;
    mts_error err = {0};
    mts_buf file = {0};
    mts_stream_file_index idx;
    CHECK(t, mts_stream_file_write(&s, &file, &err) == MTS_OK);
    CHECK(t, mts_stream_file_index_parse(file.data, file.size, 0, &idx, &err) == MTS_OK);
    mts_stream_client c;
    mts_stream_file_reader r = {0};
    mts_stream_file_plan plan;
    mts_stream_event ev;
    const uint32_t levels = s.model.level_count;
    /* the reader keeps the checks from one range to the next */
    CHECK(t, read_stop_with(&r, &file, &idx, MTS_STOP_LEVEL, levels / 5 + 3, 5, &c, NULL, &err) ==
                 MTS_OK);
    const uint32_t stops[] = {levels / 2 + 11, levels};
    for (int i = 0; i < 2 && !t->case_failed; i++) {
        uint32_t first;
        uint64_t id;
        CHECKF(t, mts_stream_client_continue(&c, &first, &id, &err) == MTS_OK, "%s", err.msg);
        CHECK(t, mts_stream_file_plan_stop(&idx, MTS_STOP_LEVEL, stops[i], first, &plan, &err) ==
                     MTS_OK);
        CHECK(t, plan.from == idx.batch_offset[first]);
        CHECK(t, mts_stream_file_reader_begin(&r, &idx, &plan, &c, &err) == MTS_OK);
        CHECK(t, take_all(&c, &err) >= 0);
        CHECKF(t, feed_range(&r, &c, &file, 11 + i, &err) == MTS_OK, "%s", err.msg);
        CHECKF(t, mts_stream_file_reader_end(&r, &c, &ev, &err) == MTS_OK, "%s", err.msg);
        CHECK(t, c.lod.level == stops[i] && c.checksum == s.level_checksum[stops[i]]);
    }
    mts_stream_client_free(&c);

    /* cut in the middle of a batch, resumed from the first batch not held */
    mts_stream_client_init(&c);
    CHECK(t, mts_stream_file_plan_stop(&idx, MTS_STOP_LEVEL, levels, 0, &plan, &err) == MTS_OK);
    CHECK(t, mts_stream_file_reader_begin(&r, &idx, &plan, &c, &err) == MTS_OK);
    const uint64_t cut = idx.batch_offset[idx.batch_count / 2] + 17;
    r.plan.to = cut; /* as a connection that broke there */
    CHECK(t, feed_range(&r, &c, &file, 3, &err) == MTS_OK);
    CHECK(t, c.batches == idx.batch_count / 2);
    CHECKF(t, mts_stream_client_reconnected(&c, &err) == MTS_OK, "%s", err.msg);
    CHECK(t, mts_stream_file_plan_stop(&idx, MTS_STOP_LEVEL, levels, c.batches, &plan, &err) ==
                 MTS_OK);
    CHECK(t, mts_stream_file_reader_begin(&r, &idx, &plan, &c, &err) == MTS_OK);
    CHECK(t, take_all(&c, &err) >= 0);
    CHECKF(t, feed_range(&r, &c, &file, 4, &err) == MTS_OK, "%s", err.msg);
    CHECKF(t, mts_stream_file_reader_end(&r, &c, &ev, &err) == MTS_OK, "%s", err.msg);
    CHECK(t, c.lod.level == levels && c.checksum == s.level_checksum[levels]);
    mts_stream_client_free(&c);
    mts_stream_file_reader_free(&r);
    mts_stream_file_index_free(&idx);
    mts_buf_free(&file);
    mts_stream_free(&s);
}

/* Damage at one place: the error names the part, and a bad batch is not applied. */
static void test_damage_named(mts_test *t)
{
    mts_stream s = {0};
    if (!build_stream(t, "tests/data/cow.off", "cow", 0, &s))
        return;
    mts_error err = {0};
    mts_buf file = {0};
    mts_stream_file_index idx;
    CHECK(t, mts_stream_file_write(&s, &file, &err) == MTS_OK);
    CHECK(t, mts_stream_file_index_parse(file.data, file.size, 0, &idx, &err) == MTS_OK);
    uint8_t *copy = malloc(file.size);
    mts_buf bad = {copy, file.size, file.size, 0};
    struct {
        uint64_t at;
        const char *says;
    } cases[] = {
        {0, "not a stream file"},
        {5, "CRC"},                                     /* the header (its version) */
        {MTS_SFILE_HEADER_SIZE + 8, "MODEL_INFO and table"}, /* inside MODEL_INFO */
        {idx.prefix_size - 6, "MODEL_INFO and table"},       /* the table */
        {idx.checks_offset + 3, "checks' CRC"},         /* the checks */
        {idx.batch_offset[2] + 9, "BATCH 2: checksum"}, /* a frame */
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0] && copy; i++) {
        memcpy(copy, file.data, file.size);
        copy[cases[i].at] ^= 0x5a;
        mts_stream_file_index bidx;
        mts_stream_client c;
        mts_result rc = mts_stream_file_index_parse(copy, bad.size, 0, &bidx, &err);
        if (rc == MTS_OK)
            rc = read_stop(&bad, &bidx, MTS_STOP_LEVEL, s.model.level_count, 1, &c, NULL, &err);
        else
            mts_stream_client_init(&c);
        CHECKF(t, rc != MTS_OK && strstr(err.msg, cases[i].says),
               "damage at %llu: \"%s\", expected \"%s\"", (unsigned long long)cases[i].at,
               rc == MTS_OK ? "accepted" : err.msg, cases[i].says);
        if (cases[i].at == idx.batch_offset[2] + 9)
            CHECKF(t, c.batches == 2 && c.rejected, "%u batches applied", c.batches);
        mts_stream_client_free(&c);
        mts_stream_file_index_free(&bidx);
    }
    /* a prefix cut short, a file over the cap, a wrong version */
    mts_stream_file_index bidx;
    CHECK(t, mts_stream_file_index_parse(file.data, 20, 0, &bidx, &err) == MTS_ERR_FORMAT &&
                 strstr(err.msg, "header"));
    mts_stream_file_index_free(&bidx);
    CHECK(t, mts_stream_file_index_parse(file.data, idx.prefix_size - 1, 0, &bidx, &err) ==
                 MTS_ERR_FORMAT &&
             strstr(err.msg, "prefix"));
    mts_stream_file_index_free(&bidx);
    CHECK(t, mts_stream_file_index_parse(file.data, file.size, 1000, &bidx, &err) ==
                 MTS_ERR_RANGE &&
             strstr(err.msg, "size cap"));
    mts_stream_file_index_free(&bidx);
    /* the range read past its end */
    mts_stream_client c;
    mts_stream_client_init(&c);
    mts_stream_file_plan plan;
    mts_stream_file_reader r = {0};
    CHECK(t, mts_stream_file_plan_stop(&idx, MTS_STOP_LEVEL, 10, 0, &plan, &err) == MTS_OK);
    CHECK(t, mts_stream_file_reader_begin(&r, &idx, &plan, &c, &err) == MTS_OK);
    CHECK(t, mts_stream_file_reader_feed(&r, &c, file.data + plan.from,
                                         (size_t)(plan.to - plan.from) + 1, &err) ==
                 MTS_ERR_FORMAT &&
             strstr(err.msg, "past the range"));
    /* a range that ended early is no END */
    mts_stream_event ev;
    CHECK(t, mts_stream_file_reader_end(&r, &c, &ev, &err) != MTS_OK && ev == MTS_EV_NONE);
    mts_stream_file_reader_free(&r);
    mts_stream_client_free(&c);

    /* A table whose counts lie (its CRC right: whoever wrote the file
     * wrote both) says batch 3's first split fits a budget it does not: the
     * checks vouch for the mesh, and the mesh shows the lie. */
    const uint32_t lv = s.batch_first[3] + 1;
    const uint64_t real = s.model.level_triangles[lv];
    CHECK(t, real - s.model.level_triangles[lv - 1] >= 2);
    s.model.level_triangles[lv] = real - 1;
    mts_buf lying = {0};
    CHECK(t, mts_stream_file_write(&s, &lying, &err) == MTS_OK);
    s.model.level_triangles[lv] = real;
    mts_stream_file_index lidx;
    CHECK(t, mts_stream_file_index_parse(lying.data, lying.size, 0, &lidx, &err) == MTS_OK);
    mts_result rc = read_stop(&lying, &lidx, MTS_STOP_TRIANGLES, (uint32_t)(real - 1), 1, &c,
                              NULL, &err);
    CHECKF(t, rc == MTS_ERR_FORMAT && strstr(err.msg, "disagree with the mesh"),
           "a lying table: %s", rc == MTS_OK ? "accepted" : err.msg);
    mts_stream_client_free(&c);
    mts_stream_file_index_free(&lidx);
    mts_buf_free(&lying);
    /* the same budget from the honest file ends below it */
    CHECK(t, read_stop(&file, &idx, MTS_STOP_TRIANGLES, (uint32_t)(real - 1), 1, &c, NULL,
                       &err) == MTS_OK &&
                 c.info.stop_triangles <= real - 1);
    mts_stream_client_free(&c);
    free(copy);
    mts_stream_file_index_free(&idx);
    mts_buf_free(&file);
    mts_stream_free(&s);
}

int main(void)
{
    mts_test t = {0};
    RUN(&t, test_frames_are_the_wire);
    RUN(&t, test_cow_stops);
    RUN(&t, test_cow_records_form_stops);
    RUN(&t, test_colored_cow_stops);
    RUN(&t, test_shared_model_stops);
    RUN(&t, test_continue_and_resume);
    RUN(&t, test_damage_named);
    return mts_test_end(&t);
}
