/* What the bench programs share beyond common/cli.h (whose cli_now is their
 * clock): a comparison for qsort, and the bytes a connection receives.
 * Header-only: each program is one file. */
#ifndef MTS_BENCH_COMMON_H
#define MTS_BENCH_COMMON_H

#include <stdint.h>

#include "stream.h"

static inline int bench_cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* MODEL_INFO + the stream up to stop + END, as a server sends them: the
 * byte count, 0 on an error. */
static inline size_t bench_connection_bytes(const mts_stream *s, uint32_t stop, mts_buf *out)
{
    mts_error err;
    size_t off, len;
    out->size = 0;
    mts_stream_put_model_info(s, stop, out);
    if (mts_stream_range(s, 0, stop, &off, &len, &err) != MTS_OK)
        return 0;
    mts_buf_put(out, s->bytes + off, len);
    mts_stream_put_end(s, stop, (uint32_t)out->size, out);
    return out->failed ? 0 : out->size;
}

#endif
