#include "webfile.h"

#include <stdlib.h>
#include <string.h>

enum { PH_IDLE, PH_PREFIX, PH_RANGE, PH_READY, PH_FAILED };

struct mts_webfile {
    mts_http *http;
    mts_http_options o;
    mts_stream_file_index idx;
    int have_idx;
    /* the file's first bytes, until the index is parsed (and the start of
     * BASE that came with them, fed on from here) */
    uint8_t *pre;
    size_t pre_len, pre_cap;
    uint64_t prefix_size; /* 0 until the header came */
    mts_stream_file_reader reader;
    mts_stream_client *c;
    uint8_t stop_kind;
    uint32_t stop_value;
    int phase;
    mts_result rc;
    mts_error err;
    uint64_t bytes;
};

mts_result mts_webfile_create(mts_webfile **out, const char *url, const mts_http_options *opts,
                              mts_error *err)
{
    *out = NULL;
    mts_webfile *wf = calloc(1, sizeof *wf);
    if (!wf)
        return mts_error_set(err, MTS_ERR_NOMEM, "out of memory");
    if (opts)
        wf->o = *opts;
    mts_result rc = mts_http_create(&wf->http, url, opts, err);
    if (rc != MTS_OK) {
        free(wf);
        return rc;
    }
    *out = wf;
    return MTS_OK;
}

void mts_webfile_free(mts_webfile *wf)
{
    if (!wf)
        return;
    mts_http_free(wf->http);
    mts_stream_file_index_free(&wf->idx);
    mts_stream_file_reader_free(&wf->reader);
    free(wf->pre);
    free(wf);
}

static int failed(mts_webfile *wf, mts_result rc)
{
    wf->rc = rc;
    wf->phase = PH_FAILED;
    return 0;
}

static int on_data(void *user, uint64_t offset, const uint8_t *data, size_t size)
{
    mts_webfile *wf = user;
    wf->bytes += size;
    if (wf->phase == PH_PREFIX) {
        /* what arrived, never what the header claims: the prefix grows with
         * the bytes and is bounded by the request's range */
        if (offset != wf->pre_len)
            return !failed(wf, mts_error_set(&wf->err, MTS_ERR_INTERNAL,
                                             "%s: bytes out of order", mts_http_url(wf->http)));
        if (wf->pre_len + size > wf->pre_cap) {
            size_t cap = wf->pre_cap ? wf->pre_cap : 4096;
            while (cap < wf->pre_len + size)
                cap *= 2;
            uint8_t *grown = realloc(wf->pre, cap);
            if (!grown)
                return !failed(wf, mts_error_set(&wf->err, MTS_ERR_NOMEM, "out of memory"));
            wf->pre = grown;
            wf->pre_cap = cap;
        }
        memcpy(wf->pre + wf->pre_len, data, size);
        wf->pre_len += size;
        return 0;
    }
    mts_result rc = mts_stream_file_reader_feed(&wf->reader, wf->c, data, size, &wf->err);
    if (rc != MTS_OK) {
        mts_error_prefix(&wf->err, "%s", mts_http_url(wf->http));
        return !failed(wf, rc);
    }
    return 0;
}

static int get(mts_webfile *wf, uint64_t from, uint64_t to, int flags)
{
    mts_result rc = mts_http_get(wf->http, from, to, flags, on_data, wf, &wf->err);
    return rc == MTS_OK ? 1 : failed(wf, rc);
}

/* The index is in: plan the stop, start the stream with the bytes already
 * here, and ask for the rest. */
static int start_range(mts_webfile *wf)
{
    mts_stream_client *c = wf->c;
    const uint32_t first = c->have_lod ? c->batches : 0;
    mts_stream_file_plan plan;
    mts_result rc = mts_stream_file_plan_stop(&wf->idx, wf->stop_kind, wf->stop_value, first,
                                              &plan, &wf->err);
    if (rc == MTS_OK)
        rc = mts_stream_file_reader_begin(&wf->reader, &wf->idx, &plan, c, &wf->err);
    uint64_t next = plan.from;
    if (rc == MTS_OK && wf->pre_len > plan.from) {
        uint64_t hi = wf->pre_len < plan.to ? wf->pre_len : plan.to;
        rc = mts_stream_file_reader_feed(&wf->reader, c, wf->pre + plan.from,
                                         (size_t)(hi - plan.from), &wf->err);
        next = hi;
    }
    if (rc != MTS_OK)
        return failed(wf, mts_error_prefix(&wf->err, "%s", mts_http_url(wf->http)));
    if (next >= plan.to) {
        wf->phase = PH_READY;
        return 0;
    }
    wf->phase = PH_RANGE;
    return get(wf, next, plan.to, 0);
}

mts_result mts_webfile_begin(mts_webfile *wf, mts_stream_client *c, uint8_t stop_kind,
                             uint32_t stop_value, mts_error *err)
{
    mts_http_cancel(wf->http);
    wf->c = c;
    wf->stop_kind = stop_kind;
    wf->stop_value = stop_value;
    wf->rc = MTS_OK;
    if (wf->have_idx) {
        start_range(wf);
    } else {
        wf->phase = PH_PREFIX;
        uint64_t to = wf->prefix_size ? wf->prefix_size : MTS_SFILE_FIRST_REQUEST;
        if (wf->pre_len < to)
            get(wf, wf->pre_len, to, wf->prefix_size ? 0 : MTS_HTTP_UP_TO);
    }
    if (wf->phase == PH_FAILED) {
        *err = wf->err;
        return wf->rc;
    }
    return MTS_OK;
}

/* The prefix request ended: ask for the rest of it, or read the index. */
static int prefix_done(mts_webfile *wf)
{
    const uint64_t cap = wf->o.max_bytes ? wf->o.max_bytes : ((uint64_t)1 << 30);
    mts_result rc;
    if (!wf->prefix_size &&
        (rc = mts_stream_file_prefix_size(wf->pre, wf->pre_len, cap, &wf->prefix_size,
                                          &wf->err)) != MTS_OK)
        return failed(wf, mts_error_prefix(&wf->err, "%s", mts_http_url(wf->http)));
    if (wf->pre_len < wf->prefix_size)
        return get(wf, wf->pre_len, wf->prefix_size, 0);
    if ((rc = mts_stream_file_index_parse(wf->pre, wf->pre_len, cap, &wf->idx, &wf->err)) !=
        MTS_OK)
        return failed(wf, mts_error_prefix(&wf->err, "%s", mts_http_url(wf->http)));
    wf->have_idx = 1;
    if (!wf->c) { /* mts_webfile_read_index: the index was all it asked for */
        wf->phase = PH_IDLE;
        return 0;
    }
    return start_range(wf);
}

mts_result mts_webfile_read_index(mts_webfile *wf, mts_error *err)
{
    if (wf->have_idx)
        return MTS_OK;
    mts_http_cancel(wf->http);
    wf->c = NULL;
    wf->rc = MTS_OK;
    wf->phase = PH_PREFIX;
    uint64_t to = wf->prefix_size ? wf->prefix_size : MTS_SFILE_FIRST_REQUEST;
    if (wf->pre_len >= to)
        prefix_done(wf);
    else if (get(wf, wf->pre_len, to, wf->prefix_size ? 0 : MTS_HTTP_UP_TO))
        while (wf->phase == PH_PREFIX)
            mts_webfile_poll(wf, NULL, -1);
    if (wf->phase == PH_FAILED) {
        *err = wf->err;
        return wf->rc;
    }
    return MTS_OK;
}

int mts_webfile_poll(mts_webfile *wf, mts_stream_client *c, int timeout_ms)
{
    wf->c = c;
    if (wf->phase != PH_PREFIX && wf->phase != PH_RANGE)
        return 0;
    if (mts_http_poll(wf->http, timeout_ms))
        return wf->phase != PH_FAILED;
    if (wf->phase == PH_FAILED)
        return 0; /* a callback failed the transfer: its error, not libcurl's */
    mts_result rc = mts_http_result(wf->http, &wf->err);
    if (rc != MTS_OK)
        return failed(wf, rc);
    if (wf->phase == PH_PREFIX)
        return prefix_done(wf);
    if (!mts_stream_file_reader_done(&wf->reader))
        return failed(wf, mts_error_set(&wf->err, MTS_ERR_IO,
                                        "%s: the range ended early", mts_http_url(wf->http)));
    wf->phase = PH_READY;
    return 0;
}

mts_result mts_webfile_result(const mts_webfile *wf, mts_error *err)
{
    if (wf->phase == PH_FAILED) {
        *err = wf->err;
        return wf->rc;
    }
    if (wf->phase != PH_READY)
        return mts_error_set(err, MTS_ERR_ARG, "%s: the conversation is not over",
                             mts_http_url(wf->http));
    return MTS_OK;
}

mts_result mts_webfile_end(mts_webfile *wf, mts_stream_client *c, mts_stream_event *event,
                           mts_error *err)
{
    *event = MTS_EV_NONE;
    if (wf->phase != PH_READY)
        return mts_webfile_result(wf, err);
    mts_result rc = mts_stream_file_reader_end(&wf->reader, c, event, err);
    if (rc != MTS_OK)
        mts_error_prefix(err, "%s", mts_http_url(wf->http));
    wf->phase = PH_IDLE;
    return rc;
}

void mts_webfile_cancel(mts_webfile *wf)
{
    mts_http_cancel(wf->http);
    if (wf->phase == PH_PREFIX || wf->phase == PH_RANGE)
        wf->phase = PH_IDLE;
}

uint64_t mts_webfile_bytes(const mts_webfile *wf)
{
    return wf->bytes;
}

const mts_stream_file_index *mts_webfile_index(const mts_webfile *wf)
{
    return wf->have_idx ? &wf->idx : NULL;
}

int mts_webfile_http_version(const mts_webfile *wf)
{
    return mts_http_last(wf->http).http_version;
}

mts_http_info mts_webfile_http_last(const mts_webfile *wf)
{
    return mts_http_last(wf->http);
}
