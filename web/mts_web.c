/* The browser's decoder (mts_web.h): the native stream client, fed from
 * JavaScript, and a view runtime the page draws. */
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
#include "morph.h"
#include "lod.h"
#include "stream.h"
#include "strips.h"
#include "wire.h"

struct mts_web {
    mts_stream_client client;
    mts_wire_reader reader;
    mts_buf out;
    mts_error err;
    int failed, state;
    char checksum[17], server_checksum[17];
    mts_buf models; /* the listing as text, NUL-terminated */
    /* the view: a runtime of its own over the client's model */
    mts_lod view;
    int have_view;
    uint32_t announced;
    uint32_t *packed, *strip_first, *strip_length;
    float *strip_rgb; /* 3 floats a strip drawn */
    mts_camera_view camera;
    mts_morph morph;
    int shown; /* a level was shown: later changes morph */
    uint32_t morph_serial; /* counts the morph's range changes */
    float style[11];
    uint64_t packed_cap;
    uint32_t packed_count, strip_cap, strip_drawn;
    uint32_t triangles, strips;
    float bbox[6];
};

MTS_WEB_API mts_web *mts_web_create(void)
{
    mts_web *w = calloc(1, sizeof *w);
    if (w) {
        mts_stream_client_init(&w->client);
        w->morph.t = 1;
    }
    return w;
}

MTS_WEB_API void mts_web_destroy(mts_web *w)
{
    if (!w)
        return;
    if (w->have_view)
        mts_lod_free(&w->view);
    mts_morph_free(&w->morph);
    mts_stream_client_free(&w->client);
    mts_wire_reader_free(&w->reader);
    mts_buf_free(&w->out);
    mts_buf_free(&w->models);
    free(w->packed);
    free(w->strip_first);
    free(w->strip_length);
    free(w->strip_rgb);
    free(w);
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

MTS_WEB_API mts_result mts_web_feed(mts_web *w, const uint8_t *data, size_t size)
{
    if (w->failed)
        return w->err.code ? w->err.code : MTS_ERR_FORMAT;
    w->client.on_model = on_model;
    w->client.user = w;
    mts_result rc = mts_wire_reader_feed(&w->reader, data, size, &w->err);
    if (rc != MTS_OK)
        return fail(w, rc);
    uint8_t type;
    const uint8_t *p;
    size_t len;
    int got;
    while ((got = mts_wire_reader_next(&w->reader, &type, &p, &len, &w->err)) == 1) {
        mts_stream_event ev;
        if ((rc = mts_stream_client_frame(&w->client, type, p, len, &ev, &w->err)) != MTS_OK)
            return fail(w, rc);
        if (ev == MTS_EV_INFO) {
            w->state = 1;
            memcpy(w->bbox, w->client.info.bbox_min, 12);
            memcpy(w->bbox + 3, w->client.info.bbox_max, 12);
        } else if (ev == MTS_EV_BASE) {
            w->state = 2;
        } else if (ev == MTS_EV_END) {
            w->state = 3;
            snprintf(w->checksum, sizeof w->checksum, "%016llx",
                     (unsigned long long)w->client.checksum);
            snprintf(w->server_checksum, sizeof w->server_checksum, "%016llx",
                     (unsigned long long)w->client.end_checksum);
        } else if (ev == MTS_EV_MODELS) {
            w->state = 4;
        } else if (ev == MTS_EV_ERROR) {
            mts_error_set(&w->err, MTS_ERR_FORMAT, "the server says: %s", w->client.error_text);
            return fail(w, MTS_ERR_FORMAT);
        }
    }
    if (got < 0)
        return fail(w, w->err.code ? w->err.code : MTS_ERR_FORMAT);
    return MTS_OK;
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

MTS_WEB_API const float *mts_web_bbox(const mts_web *w)
{
    return w->bbox;
}

MTS_WEB_API const char *mts_web_models(const mts_web *w)
{
    return w->models.size ? (const char *)w->models.data : "";
}

/* Packs the view's level as one joined strip. */
static mts_result pack(mts_web *w)
{
    const mts_lod *l = &w->view;
    uint64_t need = mts_strips_pack_bound(l->length, l->strip_count, 1);
    if (need > UINT32_MAX)
        return mts_error_set(&w->err, MTS_ERR_LIMIT, "web: %llu packed indices",
                             (unsigned long long)need);
    if (need > w->packed_cap) {
        uint32_t *p = realloc(w->packed, (size_t)(need ? need : 1) * sizeof *p);
        if (!p)
            return mts_error_set(&w->err, MTS_ERR_NOMEM, "web: %llu packed indices",
                                 (unsigned long long)need);
        w->packed = p;
        w->packed_cap = need;
    }
    if (l->strip_count > w->strip_cap) {
        uint32_t *f = realloc(w->strip_first, (size_t)l->strip_count * sizeof *f);
        if (f)
            w->strip_first = f;
        uint32_t *n = realloc(w->strip_length, (size_t)l->strip_count * sizeof *n);
        if (n)
            w->strip_length = n;
        float *rgb = realloc(w->strip_rgb, (size_t)l->strip_count * 3 * sizeof *rgb);
        if (rgb)
            w->strip_rgb = rgb;
        if (!f || !n || !rgb)
            return mts_error_set(&w->err, MTS_ERR_NOMEM, "web: %u strips", l->strip_count);
        w->strip_cap = l->strip_count;
    }
    w->packed_count = (uint32_t)mts_strips_pack(l->data, l->slot, l->length, l->strip_count, 0,
                                                0, w->packed, w->strip_first);
    uint32_t k = 0;
    for (uint32_t s = 0; s < l->strip_count; s++)
        if (l->length[s] >= 3) {
            mts_camera_strip_color(s, w->strip_rgb + 3 * (size_t)k);
            w->strip_length[k++] = l->length[s];
        }
    w->strip_drawn = k;
    mts_strip_stats ss;
    mts_lod_strip_stats(l, &ss);
    w->triangles = (uint32_t)ss.triangles;
    w->strips = ss.strips;
    return MTS_OK;
}

MTS_WEB_API mts_result mts_web_show(mts_web *w, uint32_t level, double now_ms)
{
    mts_stream_client *c = &w->client;
    mts_result rc;
    if (w->state < 2 || !c->have_lod)
        return MTS_OK; /* nothing to draw yet */
    if (!w->have_view) {
        if ((rc = mts_lod_init(&w->view, &c->model, MTS_LOD_AT_BASE, &w->err)) != MTS_OK)
            return rc;
        w->have_view = 1;
        w->announced = c->announced;
    }
    /* slots the stream laid out since are laid out before the view uses them */
    if (c->announced > w->announced) {
        if ((rc = mts_lod_announce(&w->view, w->announced, &w->err)) != MTS_OK)
            return rc;
        w->announced = c->announced;
    }
    uint32_t available = mts_web_received_level(w);
    mts_lod_set_available(&w->view, available);
    uint32_t target = level < available ? level : available;
    int range_changed = 0;
    if (!w->shown) {
        /* the first picture has nothing to slide from: what came, at once
         * (and no morph program to compile before it) */
        if ((rc = mts_lod_set_level(&w->view, target, &w->err)) != MTS_OK)
            return rc;
        w->shown = 1;
    } else if ((rc = mts_morph_move(&w->morph, &w->view, &c->model, target, now_ms,
                                    &range_changed, &w->err)) != MTS_OK) {
        return rc;
    }
    w->morph_serial += range_changed;
    return pack(w);
}

MTS_WEB_API void mts_web_set_morph_ms(mts_web *w, double ms)
{
    w->morph.ms = ms > 0 && ms <= 1e6 ? ms : 0;
}

MTS_WEB_API int mts_web_morph_active(const mts_web *w)
{
    return w->morph.active;
}

MTS_WEB_API float mts_web_morph_t(const mts_web *w)
{
    return w->morph.t;
}

MTS_WEB_API uint32_t mts_web_morph_first(const mts_web *w)
{
    return w->morph.first;
}

MTS_WEB_API uint32_t mts_web_morph_count(const mts_web *w)
{
    return w->morph.count;
}

MTS_WEB_API const float *mts_web_morph_from(const mts_web *w)
{
    return w->morph.from;
}

MTS_WEB_API uint32_t mts_web_morph_serial(const mts_web *w)
{
    return w->morph_serial;
}

MTS_WEB_API uint32_t mts_web_shown_level(const mts_web *w)
{
    return w->have_view ? w->view.level : 0;
}

MTS_WEB_API uint32_t mts_web_shown_triangles(const mts_web *w)
{
    return w->triangles;
}

MTS_WEB_API uint32_t mts_web_shown_strips(const mts_web *w)
{
    return w->strips;
}

MTS_WEB_API const uint32_t *mts_web_indices(const mts_web *w)
{
    return w->packed;
}

MTS_WEB_API uint32_t mts_web_index_count(const mts_web *w)
{
    return w->packed_count;
}

MTS_WEB_API uint32_t mts_web_strip_count(const mts_web *w)
{
    return w->strip_drawn;
}

MTS_WEB_API const uint32_t *mts_web_strip_first(const mts_web *w)
{
    return w->strip_first;
}

MTS_WEB_API const uint32_t *mts_web_strip_length(const mts_web *w)
{
    return w->strip_length;
}

MTS_WEB_API const float *mts_web_strip_colors(const mts_web *w)
{
    return w->strip_rgb;
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
