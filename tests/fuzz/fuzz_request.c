/* Fuzz target: the server's request handling. The input is the bytes a client
 * sends first; this follows server/server.c (conn_read, then conn_answer),
 * whose parsing is static there, step for step on the same library calls:
 * the frame header check against the server's input buffer, then LIST, or a
 * HELLO parsed by mts_wire_parse_hello and resolved against a served stream
 * (model lookup, stale check, mts_stream_stop_level, mts_stream_range) into
 * the MODEL_INFO (head and shared tail), range and END the server would send,
 * which must parse back on a client.
 *
 * The served stream is a small torus named "fuzz", built once with its
 * records form, which a HELLO's flags pick as in server.c
 * (mts_stream_for_hello). */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fuzz_util.h"
#include "stream.h"
#include "wire.h"

/* server.c's IN_MAX: the first frame must fit this buffer */
#define MTS_FUZZ_SERVER_IN_MAX 512

static const mts_stream *mts_fuzz_request_stream(void)
{
    static mts_stream s;
    static int built;
    if (!built) {
        mts_error err = {0};
        if (mts_fuzz_torus_stream(8, 10, 8, 1, &s, &err) != MTS_OK) {
            fprintf(stderr, "fuzz_request: cannot build the served stream: %s\n", err.msg);
            abort();
        }
        built = 1;
    }
    return &s;
}

/* What conn_answer does with a HELLO, after parsing it. */
static void mts_fuzz_answer_hello(const mts_wire_hello *h)
{
    const mts_stream *st = mts_fuzz_request_stream();
    MTS_FUZZ_CHECK(mts_wire_valid_name(h->model, strlen(h->model)));
    if (strcmp(h->model, st->name) != 0)
        return; /* ERROR unknown_model */
    /* the form it asked for (this server has both) */
    st = mts_stream_for_hello(st, h->flags);
    MTS_FUZZ_CHECK(st->records == ((h->flags & MTS_HELLO_RECORDS) != 0));
    if (h->resume_batch > 0 && h->stream_id != st->stream_id)
        return; /* ERROR stale */
    uint32_t stop = mts_stream_stop_level(st, h->stop_kind, h->stop_value);
    MTS_FUZZ_CHECK(stop <= st->model.level_count);
    size_t off = 0, len = 0;
    mts_error err = {0};
    if (mts_stream_range(st, h->resume_batch, stop, &off, &len, &err) != MTS_OK) {
        MTS_FUZZ_CHECK(err.msg[0] != 0);
        return; /* ERROR protocol: bad resume */
    }
    MTS_FUZZ_CHECK(off <= st->size && len <= st->size - off);
    /* MODEL_INFO as the server sends it: a per-connection head, then the
     * stream's shared tail */
    mts_buf head = {0}, tail = {0}, info = {0};
    mts_stream_put_model_info_head(st, stop, &head);
    mts_stream_put_end(st, stop, (uint32_t)(head.size + st->info_tail_size + len), &tail);
    MTS_FUZZ_CHECK(!head.failed && !tail.failed);
    mts_buf_put(&head, st->info_tail, st->info_tail_size);
    /* the same bytes as the whole message built at once, and what a client parses */
    mts_stream_put_model_info(st, stop, &info);
    MTS_FUZZ_CHECK(!head.failed && !info.failed && info.size == head.size &&
                   memcmp(info.data, head.data, info.size) == 0);
    mts_wire_model_info mi;
    MTS_FUZZ_CHECK(head.size > MTS_WIRE_HEADER && head.data[4] == MTS_MSG_MODEL_INFO &&
                   mts_fuzz_get_u32(head.data) == head.size - 4);
    MTS_FUZZ_CHECK(mts_wire_parse_model_info(head.data + MTS_WIRE_HEADER,
                                             head.size - MTS_WIRE_HEADER, &mi, &err) == MTS_OK);
    MTS_FUZZ_CHECK(mi.stop_level == stop && mi.stream_id == st->stream_id);
    MTS_FUZZ_CHECK(!!(mi.flags & MTS_INFO_RECORDS) == st->records);
    mts_wire_model_info_free(&mi);
    mts_wire_end e;
    MTS_FUZZ_CHECK(mts_wire_parse_end(tail.data + MTS_WIRE_HEADER, tail.size - MTS_WIRE_HEADER,
                                      &e, &err) == MTS_OK);
    MTS_FUZZ_CHECK(e.final_level == stop && e.stream_bytes == head.size + len + tail.size);
    mts_buf_free(&info);
    mts_buf_free(&head);
    mts_buf_free(&tail);
}

int mts_fuzz_request(const uint8_t *data, size_t size)
{
    /* conn_read: the whole first frame must be in the server's buffer */
    if (size < MTS_WIRE_HEADER)
        return 0;
    uint32_t len = mts_fuzz_get_u32(data);
    if (len == 0 || len > MTS_FUZZ_SERVER_IN_MAX - 4)
        return 0; /* ERROR protocol: garbage */
    if (size < 4 + (size_t)len)
        return 0; /* waits for more */
    /* an exact-size copy of the payload, so ASan sees any read past it */
    size_t n = len - 1;
    uint8_t *payload = malloc(n ? n : 1);
    MTS_FUZZ_CHECK(payload != NULL);
    memcpy(payload, data + MTS_WIRE_HEADER, n);
    uint8_t type = data[4];
    if (type == MTS_MSG_LIST) {
        const mts_stream *st = mts_fuzz_request_stream();
        mts_wire_model_entry e = {{0}, st->model.vertex_count, 0, st->model.level_count,
                                  (uint32_t)st->size};
        memcpy(e.name, st->name, sizeof e.name); /* both MTS_WIRE_MAX_NAME + 1 */
        mts_buf b = {0};
        mts_wire_put_models(&b, &e, 1);
        MTS_FUZZ_CHECK(!b.failed);
        mts_buf_free(&b);
    } else if (type == MTS_MSG_HELLO) {
        mts_wire_hello h;
        mts_error err = {0};
        mts_result rc = mts_wire_parse_hello(payload, n, &h, &err);
        if (rc == MTS_OK)
            mts_fuzz_answer_hello(&h);
        else
            MTS_FUZZ_CHECK(err.msg[0] != 0 && (rc == MTS_ERR_FORMAT || rc == MTS_ERR_VERSION));
    }
    free(payload);
    return 0;
}

#ifndef MTS_FUZZ_NO_ENTRY
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return mts_fuzz_request(data, size);
}
#endif
