/* Fuzz target: the Draco base-mesh path of the client, mts_draco_decode
 * (protocol/draco.h), on raw bytes. The input is the Draco buffer a BASE
 * frame carries. A decode that succeeds must keep every promise draco.h makes
 * -- counts within bounds, every index below the vertex count, every
 * quantized value on the grid, positions equal to mts_draco_dequantize of
 * them, normals finite -- since the client copies the mesh into its model on
 * exactly those promises (stream_dec.c, take_base); a failed one must leave the
 * output empty and say why.
 *
 * libdraco itself is Debian's build, not instrumented: the fuzzer sees the
 * shim's coverage and catches crashes inside Draco, not its overreads. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "draco.h"
#include "fuzz_util.h"

int mts_fuzz_draco(const uint8_t *data, size_t size)
{
    /* an exact-size copy, so ASan sees any read past the buffer */
    uint8_t *bytes = malloc(size ? size : 1);
    MTS_FUZZ_CHECK(bytes != NULL);
    if (size)
        memcpy(bytes, data, size);
    mts_draco_mesh_out m;
    mts_error err = {0};
    mts_result rc = mts_draco_decode(bytes, size, &m, &err);
    if (rc != MTS_OK) {
        MTS_FUZZ_CHECK(err.msg[0] != 0 && err.code == rc);
        /* the shim bounds what a buffer may declare by its size, so a few
         * KiB running out of memory is an unbounded allocation (the
         * regression test runs under a memory limit to see it) */
        MTS_FUZZ_CHECK(rc != MTS_ERR_NOMEM);
        MTS_FUZZ_CHECK(m.vertex_count == 0 && m.triangle_count == 0 && !m.positions &&
                       !m.quantized && !m.normals && !m.triangles);
        free(bytes);
        return 0;
    }
    MTS_FUZZ_CHECK(m.vertex_count > 0 && m.triangle_count > 0);
    MTS_FUZZ_CHECK(m.positions && m.quantized && m.triangles);
    MTS_FUZZ_CHECK(m.grid.bits >= 1 && m.grid.bits <= MTS_DRACO_MAX_BITS);
    MTS_FUZZ_CHECK(m.grid.range > 0 && isfinite(m.grid.range));
    const uint32_t maxq = (uint32_t)((1ull << m.grid.bits) - 1);
    for (uint32_t i = 0; i < m.vertex_count; i++) {
        const uint32_t *q = m.quantized + 3 * (size_t)i;
        float p[3];
        MTS_FUZZ_CHECK(q[0] <= maxq && q[1] <= maxq && q[2] <= maxq);
        mts_draco_dequantize(&m.grid, q, p);
        MTS_FUZZ_CHECK(memcmp(p, m.positions + 3 * (size_t)i, sizeof p) == 0);
        if (m.normals) {
            const float *n = m.normals + 3 * (size_t)i;
            MTS_FUZZ_CHECK(isfinite(n[0]) && isfinite(n[1]) && isfinite(n[2]));
        }
    }
    for (size_t k = 0; k < 3 * (size_t)m.triangle_count; k++)
        MTS_FUZZ_CHECK(m.triangles[k] < m.vertex_count);
    mts_draco_mesh_out_free(&m);
    free(bytes);
    return 0;
}

#ifndef MTS_FUZZ_NO_ENTRY
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return mts_fuzz_draco(data, size);
}
#endif
