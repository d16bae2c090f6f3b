/* What the fuzz targets, their seed generator and the regression test share:
 * small models built in memory (a torus, or tests/data/cow.off), the stream
 * a server sends for a stop point, and the checksum repairs that let mutated
 * input reach the decoders behind a CRC.
 *
 * Everything here is static inline: the regression test includes every
 * target's .c file into one program, and gcc's -Wunused-function would
 * refuse plain static helpers one of them does not use. */
#ifndef MTS_FUZZ_UTIL_H
#define MTS_FUZZ_UTIL_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "build.h"
#include "bytes.h"
#include "crc32c.h"
#include "mesh.h"
#include "model.h"
#include "stream.h"
#include "wire.h"

/* A broken promise of the code under test: report and abort, which libFuzzer
 * records as a crash and the regression test as a failed program. */
#define MTS_FUZZ_CHECK(cond)                                                              \
    do {                                                                                  \
        if (!(cond)) {                                                                    \
            fprintf(stderr, "%s:%d: fuzz check failed: %s\n", __FILE__, __LINE__, #cond); \
            abort();                                                                      \
        }                                                                                 \
    } while (0)

static inline uint32_t mts_fuzz_get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static inline void mts_fuzz_put_u32(uint8_t *p, uint32_t x)
{
    p[0] = (uint8_t)x;
    p[1] = (uint8_t)(x >> 8);
    p[2] = (uint8_t)(x >> 16);
    p[3] = (uint8_t)(x >> 24);
}

/* A broken connection in a stream_client input (fuzz_stream_client.c). */
#define MTS_FUZZ_CUT "\xffMTSCUT\xff"
#define MTS_FUZZ_CUT_SIZE 8

static inline const uint8_t *mts_fuzz_find_cut(const uint8_t *p, size_t size)
{
    for (size_t i = 0; i + MTS_FUZZ_CUT_SIZE <= size; i++)
        if (p[i] == 0xff && memcmp(p + i, MTS_FUZZ_CUT, MTS_FUZZ_CUT_SIZE) == 0)
            return p + i;
    return NULL;
}

/* Rewrites the trailing CRC-32C of every whole BASE and BATCH frame of a
 * server->client byte stream, so that a mutation inside a frame reaches the
 * frame's decoder instead of stopping at the checksum (a fuzzer cannot find
 * the matching CRC by mutation). Stops at the first frame header the wire
 * reader would refuse or a frame cut short. */
static inline void mts_fuzz_fix_stream_crcs(uint8_t *p, size_t size)
{
    size_t at = 0;
    while (size - at >= MTS_WIRE_HEADER) {
        uint32_t len = mts_fuzz_get_u32(p + at);
        if (len == 0 || len > MTS_WIRE_MAX_FRAME || len > size - at - 4)
            return;
        uint8_t type = p[at + 4];
        size_t payload = len - 1;
        if ((type == MTS_MSG_BASE || type == MTS_MSG_BATCH) && payload >= 4) {
            uint8_t *pl = p + at + MTS_WIRE_HEADER;
            mts_fuzz_put_u32(pl + payload - 4, mts_crc32c(0, pl, payload - 4));
        }
        at += 4 + (size_t)len;
    }
}

/* The same for a .mtsm file (common/modelfile.h): every section whose bounds
 * lie inside the file gets its CRC, then the header its CRC. */
static inline void mts_fuzz_fix_modelfile_crcs(uint8_t *p, size_t size)
{
    if (size < 16)
        return;
    uint32_t count = mts_fuzz_get_u32(p + 8);
    if (count == 0 || count > 64 || 16 + 24 * (size_t)count > size)
        return;
    for (uint32_t i = 0; i < count; i++) {
        uint8_t *e = p + 16 + 24 * (size_t)i;
        uint64_t off = mts_fuzz_get_u32(e + 8) | (uint64_t)mts_fuzz_get_u32(e + 12) << 32;
        uint64_t len = mts_fuzz_get_u32(e + 16) | (uint64_t)mts_fuzz_get_u32(e + 20) << 32;
        if (off <= size && len <= size - off)
            mts_fuzz_put_u32(e + 4, mts_crc32c(0, p + off, (size_t)len));
    }
    uint32_t crc = mts_crc32c(0, p, 12);
    mts_fuzz_put_u32(p + 12, mts_crc32c(crc, p + 16, 24 * (size_t)count));
}

/* A closed torus of nu x nv vertices as OFF text (NUL-terminated, malloc'ed):
 * a small manifold mesh with no boundary and no poles, so every vertex can
 * be collapsed and the models stay small and fast to fuzz. */
static inline char *mts_fuzz_torus_off(int nu, int nv, size_t *size)
{
    mts_buf b = {0};
    char line[128];
    int n = snprintf(line, sizeof line, "OFF\n%d %d 0\n", nu * nv, 2 * nu * nv);
    mts_buf_put(&b, line, (size_t)n);
    for (int i = 0; i < nu; i++) {
        for (int j = 0; j < nv; j++) {
            /* four decimals: the text, and so the seeds, do not depend on
             * the last bits of libm's cos and sin */
            double a = 6.283185307179586 * i / nu, c = 6.283185307179586 * j / nv;
            double r = 2.0 + 0.8 * cos(c);
            n = snprintf(line, sizeof line, "%.4f %.4f %.4f\n", r * cos(a), r * sin(a),
                         0.8 * sin(c));
            mts_buf_put(&b, line, (size_t)n);
        }
    }
    for (int i = 0; i < nu; i++) {
        for (int j = 0; j < nv; j++) {
            int a = i * nv + j, bq = ((i + 1) % nu) * nv + j, c = ((i + 1) % nu) * nv + (j + 1) % nv,
                d = i * nv + (j + 1) % nv;
            n = snprintf(line, sizeof line, "3 %d %d %d\n3 %d %d %d\n", a, bq, c, a, c, d);
            mts_buf_put(&b, line, (size_t)n);
        }
    }
    mts_buf_u8(&b, 0);
    if (b.failed) {
        mts_buf_free(&b);
        return NULL;
    }
    *size = b.size - 1;
    return (char *)b.data;
}

/* Builds a model from OFF text in memory (data != NULL) or from a file. */
static inline mts_result mts_fuzz_build_model(const char *name, const char *data, size_t size,
                                              uint32_t base_vertices, mts_model *model,
                                              mts_error *err)
{
    mts_mesh mesh = {0};
    mts_result rc = data ? mts_mesh_load_memory(name, data, size, NULL, &mesh, NULL, err)
                         : mts_mesh_load(name, NULL, &mesh, NULL, err);
    if (rc != MTS_OK)
        return rc;
    mts_build_options o = {0};
    o.base_vertices = base_vertices;
    rc = mts_build_model(&mesh, name, &o, model, NULL, err);
    mts_mesh_free(&mesh);
    return rc;
}

/* A torus model and its stream (model name "fuzz"), batches of batch_splits;
 * with_records: also its records form (s->records_form). */
static inline mts_result mts_fuzz_torus_stream(int nu, int nv, uint32_t batch_splits,
                                               int with_records, mts_stream *s, mts_error *err)
{
    size_t size = 0;
    char *off = mts_fuzz_torus_off(nu, nv, &size);
    if (!off)
        return mts_error_set(err, MTS_ERR_NOMEM, "fuzz: out of memory");
    mts_model m;
    mts_result rc = mts_fuzz_build_model("torus.off", off, size, 0, &m, err);
    free(off);
    if (rc != MTS_OK)
        return rc;
    mts_stream_options o = {0};
    o.batch_splits = batch_splits;
    o.with_records = with_records;
    rc = mts_stream_build(&m, "fuzz", &o, s, err);
    mts_model_free(&m);
    return rc;
}

/* What a server sends a connection that asked for stop_level, from batch
 * resume (0: from the start): MODEL_INFO, BASE unless it resumes, the
 * batches up to stop_level, END; only the first `keep` bytes of it (a
 * connection that broke there; SIZE_MAX: all) are appended to out. */
static inline void mts_fuzz_conversation(const mts_stream *s, uint32_t resume, uint32_t stop_level,
                                         size_t keep, mts_buf *out)
{
    mts_error err = {0};
    mts_buf b = {0};
    size_t off = 0, len = 0;
    mts_stream_put_model_info(s, stop_level, &b);
    if (mts_stream_range(s, resume, stop_level, &off, &len, &err) != MTS_OK) {
        out->failed = 1;
        mts_buf_free(&b);
        return;
    }
    mts_buf_put(&b, s->bytes + off, len);
    mts_stream_put_end(s, stop_level, (uint32_t)b.size, &b); /* END counts what came before */
    out->failed |= b.failed;
    mts_buf_put(out, b.data, keep < b.size ? keep : b.size);
    mts_buf_free(&b);
}

#endif
