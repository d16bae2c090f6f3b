/* The browser's decoder (mts_web.h): the native stream client, fed from
 * JavaScript (WebSocket messages, or the ranges of a stream file through
 * protocol/stream_file.c's reader), and a follower (client/follow.h, the
 * native view's) whose packed level the page draws. */
#include "mts_web.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef __EMSCRIPTEN__
#include <emscripten/emscripten.h>
#define MTS_WEB_API EMSCRIPTEN_KEEPALIVE
#else
#define MTS_WEB_API
#endif

#include "bytes.h"
#include "camera.h"
#include "follow.h"
#include "stream.h"
#include "stream_file.h"
#include "wire.h"

/* The largest stream file the page reads, as mts-client's default cap: a
 * header that claims more is refused before anything is allocated. */
#define MTS_WEB_FILE_MAX_BYTES ((uint64_t)1 << 30)
/* A range's bytes go to the stream client in pieces of at most this, its
 * frames taken between them: the client holds only so much untaken
 * (mts_stream_client_feed), whatever size of chunk a browser hands over. */
#define MTS_WEB_FILE_PIECE ((size_t)1 << 20)

struct mts_web {
    mts_stream_client client;
    mts_buf out;
    mts_error err;
    int failed, state;
    char checksum[17], server_checksum[17];
    mts_buf models; /* the listing as text, NUL-terminated */
    /* what the page draws: a runtime of its own over the client's model,
     * made at the first show */
    mts_follow follow;
    int have_follow;
    double morph_ms;
    mts_camera_view camera;
    float style[11];
    float bbox[6];
    /* a stream file: its index, kept from one range to the next (a resume
     * or a continuation asks only for the batches not held), the plan of
     * the range under way and the reader that keeps the checks */
    mts_stream_file_index file_idx;
    int have_file_idx, have_file_plan, file_begun;
    mts_stream_file_plan file_plan;
    mts_stream_file_reader file_reader;
    /* colours as RGBA8 for one upload (the native renderer's layout: WebGL
     * fetches 4-byte vertices as they are) */
    uint8_t *rgba;
    size_t rgba_cap;
};

MTS_WEB_API mts_web *mts_web_create(void)
{
    mts_web *w = calloc(1, sizeof *w);
    if (w) {
        mts_stream_client_init(&w->client);
        w->follow.morph.t = 1; /* what the page reads before the first show */
    }
    return w;
}

MTS_WEB_API void mts_web_destroy(mts_web *w)
{
    if (!w)
        return;
    if (w->have_follow)
        mts_follow_free(&w->follow);
    mts_stream_client_free(&w->client);
    mts_stream_file_reader_free(&w->file_reader);
    mts_stream_file_index_free(&w->file_idx);
    mts_buf_free(&w->out);
    mts_buf_free(&w->models);
    free(w->rgba);
    free(w);
}

MTS_WEB_API uint32_t mts_web_set_threads(mts_web *w, uint32_t n)
{
#ifdef __EMSCRIPTEN_PTHREADS__
    /* one pool thread: the threaded build makes one worker ready before
     * the module resolves (PTHREAD_POOL_SIZE), and a thread without one
     * would start only once the page's thread returned to the browser */
    w->client.threads = n > 2 ? 2 : n;
#else
    (void)n;
    w->client.threads = 1;
#endif
    return w->client.threads ? w->client.threads : 1;
}

MTS_WEB_API uint32_t mts_web_threads(const mts_web *w)
{
    return mts_stream_client_threads_used(&w->client);
}

MTS_WEB_API const uint8_t *mts_web_hello(mts_web *w, const char *model, uint32_t stop_kind,
                                         uint32_t stop_value, uint32_t flags)
{
    mts_wire_hello h = {0};
    h.major = MTS_WIRE_MAJOR;
    h.minor = MTS_WIRE_MINOR;
    snprintf(h.model, sizeof h.model, "%s", model ? model : "");
    h.stop_kind = (uint8_t)stop_kind;
    h.stop_value = stop_value;
    h.flags = flags;
    w->out.size = 0;
    mts_wire_put_hello(&w->out, &h);
    return w->out.failed ? NULL : w->out.data;
}

MTS_WEB_API const uint8_t *mts_web_list(mts_web *w)
{
    w->out.size = 0;
    mts_wire_put_list(&w->out);
    return w->out.failed ? NULL : w->out.data;
}

MTS_WEB_API size_t mts_web_out_size(const mts_web *w)
{
    return w->out.size;
}

static void on_model(void *user, const mts_wire_model_entry *m)
{
    mts_web *w = user;
    char line[128];
    int n = snprintf(line, sizeof line, "%s %u %u %u\n", m->name, m->vertices, m->triangles,
                     m->levels);
    if (w->models.size > 0)
        w->models.size--; /* over the NUL */
    mts_buf_put(&w->models, line, (size_t)n);
    mts_buf_u8(&w->models, 0);
}

static mts_result fail(mts_web *w, mts_result rc)
{
    w->failed = 1;
    return rc;
}

/* What an event of the client changes in what the page reads. */
static mts_result on_event(mts_web *w, mts_stream_event ev)
{
    const mts_stream_client *c = &w->client;
    if (ev == MTS_EV_INFO) {
        w->state = 1;
        memcpy(w->bbox, c->info.bbox_min, 12);
        memcpy(w->bbox + 3, c->info.bbox_max, 12);
    } else if (ev == MTS_EV_BASE) {
        w->state = 2;
    } else if (ev == MTS_EV_RESUMED) {
        /* a resumed or continued conversation: the stream goes on from what
         * is held */
        w->state = c->have_lod ? 2 : 1;
    } else if (ev == MTS_EV_END) {
        w->state = 3;
        snprintf(w->checksum, sizeof w->checksum, "%016llx", (unsigned long long)c->checksum);
        snprintf(w->server_checksum, sizeof w->server_checksum, "%016llx",
                 (unsigned long long)c->end_checksum);
    } else if (ev == MTS_EV_MODELS) {
        w->state = 4;
    } else if (ev == MTS_EV_ERROR) {
        mts_error_set(&w->err, MTS_ERR_FORMAT, "the server says: %s", c->error_text);
        return fail(w, MTS_ERR_FORMAT);
    }
    return MTS_OK;
}

/* Takes every whole frame the client holds. */
static mts_result take_events(mts_web *w)
{
    mts_stream_event ev;
    int got;
    mts_result rc;
    while ((got = mts_stream_client_next(&w->client, &ev, &w->err)) == 1)
        if ((rc = on_event(w, ev)) != MTS_OK)
            return rc;
    if (got < 0)
        return fail(w, w->err.code ? w->err.code : MTS_ERR_FORMAT);
    return MTS_OK;
}

MTS_WEB_API mts_result mts_web_feed(mts_web *w, const uint8_t *data, size_t size)
{
    if (w->failed)
        return w->err.code ? w->err.code : MTS_ERR_FORMAT;
    w->client.on_model = on_model;
    w->client.user = w;
    mts_result rc = mts_stream_client_feed(&w->client, data, size, &w->err);
    if (rc != MTS_OK)
        return fail(w, rc);
    return take_events(w);
}

/* ---- stream files ---------------------------------------------------------- */

static mts_result failed_before(mts_web *w)
{
    return w->err.code ? w->err.code : MTS_ERR_FORMAT;
}

MTS_WEB_API double mts_web_file_prefix_size(mts_web *w, const uint8_t *data, size_t size)
{
    uint64_t prefix = 0;
    if (w->failed)
        return -1;
    if (mts_stream_file_prefix_size(data, size, MTS_WEB_FILE_MAX_BYTES, &prefix, &w->err) !=
        MTS_OK) {
        fail(w, w->err.code);
        return -1;
    }
    return (double)prefix;
}

MTS_WEB_API mts_result mts_web_file_index(mts_web *w, const uint8_t *data, size_t size)
{
    if (w->failed)
        return failed_before(w);
    mts_stream_file_index_free(&w->file_idx);
    w->have_file_idx = 0;
    mts_result rc =
        mts_stream_file_index_parse(data, size, MTS_WEB_FILE_MAX_BYTES, &w->file_idx, &w->err);
    if (rc != MTS_OK)
        return fail(w, rc);
    w->have_file_idx = 1;
    return MTS_OK;
}

MTS_WEB_API double mts_web_file_size(const mts_web *w)
{
    return w->have_file_idx ? (double)w->file_idx.file_size : 0;
}

MTS_WEB_API int mts_web_file_resume_point(const mts_web *w)
{
    const mts_stream_client *c = &w->client;
    if (w->failed || c->lod.broken)
        return -1;
    return c->have_lod ? (int)c->batches : 0;
}

MTS_WEB_API mts_result mts_web_file_plan(mts_web *w, uint32_t stop_kind, uint32_t stop_value)
{
    if (w->failed)
        return failed_before(w);
    if (!w->have_file_idx) {
        mts_error_set(&w->err, MTS_ERR_ARG, "stream file: no index to plan from");
        return fail(w, MTS_ERR_ARG);
    }
    int first = mts_web_file_resume_point(w);
    mts_result rc = mts_stream_file_plan_stop(&w->file_idx, (uint8_t)stop_kind, stop_value,
                                              first > 0 ? (uint32_t)first : 0, &w->file_plan,
                                              &w->err);
    if (rc != MTS_OK)
        return fail(w, rc);
    w->have_file_plan = 1;
    return MTS_OK;
}

MTS_WEB_API double mts_web_file_from(const mts_web *w)
{
    return w->have_file_plan ? (double)w->file_plan.from : 0;
}

MTS_WEB_API double mts_web_file_to(const mts_web *w)
{
    return w->have_file_plan ? (double)w->file_plan.to : 0;
}

MTS_WEB_API mts_result mts_web_file_begin(mts_web *w)
{
    if (w->failed)
        return failed_before(w);
    if (!w->have_file_plan) {
        mts_error_set(&w->err, MTS_ERR_ARG, "stream file: no plan to begin");
        return fail(w, MTS_ERR_ARG);
    }
    mts_stream_client *c = &w->client;
    mts_result rc = MTS_OK;
    if (w->file_begun && w->state == 3) {
        /* a higher stop after the last ended: the batches held stay */
        uint32_t batch;
        uint64_t id;
        rc = mts_stream_client_continue(c, &batch, &id, &w->err);
        w->checksum[0] = w->server_checksum[0] = 0;
    } else if (w->file_begun) {
        /* the last range broke: its frame cut short is dropped, and it
         * comes again whole at the start of this one */
        rc = mts_stream_client_reconnected(c, &w->err);
    }
    if (rc == MTS_OK)
        rc = mts_stream_file_reader_begin(&w->file_reader, &w->file_idx, &w->file_plan, c,
                                          &w->err);
    if (rc != MTS_OK)
        return fail(w, rc);
    w->file_begun = 1;
    return take_events(w);
}

MTS_WEB_API mts_result mts_web_file_feed(mts_web *w, const uint8_t *data, size_t size)
{
    if (w->failed)
        return failed_before(w);
    while (size > 0) {
        size_t n = size < MTS_WEB_FILE_PIECE ? size : MTS_WEB_FILE_PIECE;
        mts_result rc =
            mts_stream_file_reader_feed(&w->file_reader, &w->client, data, n, &w->err);
        if (rc != MTS_OK)
            return fail(w, rc);
        if ((rc = take_events(w)) != MTS_OK)
            return rc;
        data += n;
        size -= n;
    }
    return MTS_OK;
}

MTS_WEB_API int mts_web_file_done(const mts_web *w)
{
    return w->file_begun && mts_stream_file_reader_done(&w->file_reader);
}

MTS_WEB_API mts_result mts_web_file_end(mts_web *w)
{
    if (w->failed)
        return failed_before(w);
    mts_stream_event ev;
    mts_result rc = mts_stream_file_reader_end(&w->file_reader, &w->client, &ev, &w->err);
    if (rc != MTS_OK)
        return fail(w, rc);
    return on_event(w, ev);
}

MTS_WEB_API const char *mts_web_error(const mts_web *w)
{
    return w->failed ? w->err.msg : "";
}

MTS_WEB_API int mts_web_state(const mts_web *w)
{
    return w->state;
}

MTS_WEB_API uint32_t mts_web_received_level(const mts_web *w)
{
    const mts_stream_client *c = &w->client;
    if (w->state < 2)
        return 0;
    return c->splits < c->stop_level ? c->splits : c->stop_level;
}

MTS_WEB_API uint32_t mts_web_stop_level(const mts_web *w)
{
    return w->client.stop_level;
}

MTS_WEB_API uint32_t mts_web_level_count(const mts_web *w)
{
    return w->client.info.levels;
}

MTS_WEB_API uint32_t mts_web_vertices(const mts_web *w)
{
    return w->state >= 2 ? w->client.model.base_vertex_count + w->client.splits : 0;
}

MTS_WEB_API uint32_t mts_web_batches(const mts_web *w)
{
    return w->client.batches;
}

MTS_WEB_API const char *mts_web_checksum(const mts_web *w)
{
    return w->checksum;
}

MTS_WEB_API const char *mts_web_server_checksum(const mts_web *w)
{
    return w->server_checksum;
}

MTS_WEB_API const float *mts_web_positions(const mts_web *w)
{
    return w->client.model.positions;
}

MTS_WEB_API const float *mts_web_normals(const mts_web *w)
{
    return w->client.model.normals;
}

MTS_WEB_API int mts_web_has_colors(const mts_web *w)
{
    return w->state >= 2 && (w->client.model.flags & MTS_MODEL_COLORS) && w->client.model.colors;
}

/* count colours of 3 bytes as RGBA8, alpha 255, in w->rgba; NULL when out
 * of memory. */
static const uint8_t *as_rgba(mts_web *w, const uint8_t *rgb, uint32_t count)
{
    size_t need = (size_t)count * 4u;
    if (need > w->rgba_cap) {
        uint8_t *p = realloc(w->rgba, need);
        if (!p)
            return NULL;
        w->rgba = p;
        w->rgba_cap = need;
    }
    for (size_t i = 0; i < count; i++) {
        memcpy(w->rgba + 4 * i, rgb + 3 * i, 3);
        w->rgba[4 * i + 3] = 255;
    }
    return w->rgba;
}

MTS_WEB_API const uint8_t *mts_web_colors_rgba(mts_web *w, uint32_t first, uint32_t count)
{
    if (!mts_web_has_colors(w) || (uint64_t)first + count > mts_web_vertices(w))
        return NULL;
    return as_rgba(w, w->client.model.colors + 3 * (size_t)first, count);
}

MTS_WEB_API const float *mts_web_bbox(const mts_web *w)
{
    return w->bbox;
}

MTS_WEB_API const char *mts_web_models(const mts_web *w)
{
    return w->models.size ? (const char *)w->models.data : "";
}

MTS_WEB_API mts_result mts_web_show(mts_web *w, uint32_t level, double now_ms)
{
    mts_stream_client *c = &w->client;
    mts_result rc;
    if (w->state < 2 || !c->have_lod)
        return MTS_OK; /* nothing to draw yet */
    mts_follow_source src = mts_follow_source_of_stream(c);
    if (!w->have_follow) {
        /* the first picture has nothing to slide from: what came, at once
         * (and no morph program to compile before it) */
        mts_follow_options fo = {1, w->morph_ms, 1};
        if ((rc = mts_follow_init(&w->follow, &src, &fo, &w->err)) != MTS_OK)
            return rc;
        w->have_follow = 1;
    }
    if ((rc = mts_follow_sync(&w->follow, &src, level, now_ms, NULL, &w->err)) != MTS_OK)
        return rc;
    /* the page repacks the whole level; nothing takes the changed list */
    mts_follow_clear_changed(&w->follow);
    return mts_follow_pack(&w->follow, &w->err);
}

MTS_WEB_API void mts_web_set_morph_ms(mts_web *w, double ms)
{
    w->morph_ms = ms > 0 && ms <= 1e6 ? ms : 0;
    w->follow.morph.ms = w->morph_ms;
}

MTS_WEB_API int mts_web_morph_active(const mts_web *w)
{
    return w->follow.morph.active;
}

MTS_WEB_API float mts_web_morph_t(const mts_web *w)
{
    return w->follow.morph.t;
}

MTS_WEB_API uint32_t mts_web_morph_first(const mts_web *w)
{
    return w->follow.morph.first;
}

MTS_WEB_API uint32_t mts_web_morph_count(const mts_web *w)
{
    return w->follow.morph.count;
}

MTS_WEB_API const float *mts_web_morph_from(const mts_web *w)
{
    return w->follow.morph.from;
}

MTS_WEB_API const uint8_t *mts_web_morph_from_colors_rgba(mts_web *w)
{
    const mts_morph *mo = &w->follow.morph;
    if (!mts_web_has_colors(w) || !mo->count || !mo->from_colors)
        return NULL;
    return as_rgba(w, mo->from_colors, mo->count);
}

MTS_WEB_API uint32_t mts_web_morph_serial(const mts_web *w)
{
    return w->follow.morph_serial;
}

MTS_WEB_API uint32_t mts_web_shown_level(const mts_web *w)
{
    return w->have_follow ? w->follow.lod->level : 0;
}

MTS_WEB_API uint32_t mts_web_shown_triangles(const mts_web *w)
{
    return w->follow.shown.triangles;
}

MTS_WEB_API uint32_t mts_web_shown_strips(const mts_web *w)
{
    return w->follow.shown.strips;
}

MTS_WEB_API const uint32_t *mts_web_indices(const mts_web *w)
{
    return w->follow.packed.indices;
}

MTS_WEB_API uint32_t mts_web_index_count(const mts_web *w)
{
    return (uint32_t)w->follow.packed.count;
}

MTS_WEB_API uint32_t mts_web_strip_count(const mts_web *w)
{
    return w->follow.packed.strips;
}

MTS_WEB_API const uint32_t *mts_web_strip_first(const mts_web *w)
{
    return w->follow.packed.strip_first;
}

MTS_WEB_API const uint32_t *mts_web_strip_length(const mts_web *w)
{
    return w->follow.packed.strip_length;
}

MTS_WEB_API const float *mts_web_strip_colors(const mts_web *w)
{
    return w->follow.packed.strip_rgb;
}

MTS_WEB_API const float *mts_web_camera(mts_web *w, float yaw_deg, float pitch_deg, float zoom,
                                        float aspect)
{
    mts_render_camera cam = {yaw_deg, pitch_deg, zoom, 35.0f};
    mts_camera_compute(w->client.model.bbox_min, w->client.model.bbox_max, &cam, aspect,
                       &w->camera);
    return w->camera.mvp;
}

MTS_WEB_API const float *mts_web_style(mts_web *w)
{
    mts_render_style st;
    mts_camera_default_style(&st);
    memcpy(w->style, st.background, 16);
    memcpy(w->style + 4, st.color, 12);
    w->style[7] = st.ambient;
    mts_camera_light(w->style + 8);
    return w->style;
}

MTS_WEB_API int mts_web_flat(const mts_web *w)
{
    return w->state >= 1 && !(w->client.info.flags & MTS_INFO_NORMALS);
}

MTS_WEB_API const char *mts_web_shader(int fragment)
{
    return fragment ? mts_camera_fragment_glsl : mts_camera_vertex_glsl;
}
