/* Fuzz target: the glTF 2.0 reader (builder/gltf_read.cpp and gltf_draco.cpp,
 * through Debian's tinygltf) behind the mesh loader, as mts-server meets a
 * downloaded model:
 * mts_mesh_load_memory with the file's bytes, named fuzz.glb when they
 * start with GLB's magic and fuzz.gltf otherwise (either name picks the
 * glTF reader; the reader itself tells GLB from JSON by the magic).
 *
 * Input: the file's bytes as they are (no mode byte), so real .glb and
 * .gltf files go into the corpus unchanged.
 *
 * From memory the reader may not read external buffer files (dir NULL);
 * such a file fails with MTS_ERR_IO. That input is then read again as
 * mts-build reads a file, with a folder (one that does not exist, so that
 * nothing is read from disk whatever the URI), which runs the URI checks
 * and the file callbacks tinygltf calls.
 *
 * The size cap is small (MTS_FUZZ_GLTF_MAX_BYTES): a node may instance one
 * mesh many times, and the flattened mesh grows to the cap, which the
 * cleaning then walks; a bigger cap only makes executions slower.
 *
 * A load that succeeds must give what mesh.h promises the builder: counts
 * above zero, every index below the vertex count, no repeated index in a
 * triangle, finite positions and normals; a failed one must say why, leave
 * the mesh empty, and not be out of memory (the input and cap are small,
 * so running out is an unbounded allocation). tinygltf is Debian's build,
 * not instrumented: the fuzzer sees the shim's coverage and catches crashes
 * inside tinygltf and its overreads through the C library (memcpy), not
 * its own silent ones. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fuzz_util.h"
#include "gltf_read.h"
#include "mesh.h"

#define MTS_FUZZ_GLTF_MAX_BYTES ((uint64_t)256 << 10)

/* A folder that does not exist: tinygltf's callbacks join it with each
 * buffer URI, and nothing there can be opened. */
#define MTS_FUZZ_GLTF_NO_DIR "/nonexistent/mts-fuzz-gltf"

static void mts_fuzz_check_mesh(const mts_mesh *m)
{
    MTS_FUZZ_CHECK(m->vertex_count > 0 && m->triangle_count > 0);
    MTS_FUZZ_CHECK(m->positions && m->normals && m->triangles);
    for (size_t i = 0; i < 3 * (size_t)m->vertex_count; i++)
        MTS_FUZZ_CHECK(isfinite(m->positions[i]) && isfinite(m->normals[i]));
    for (uint32_t t = 0; t < m->triangle_count; t++) {
        const uint32_t *v = m->triangles + 3 * (size_t)t;
        MTS_FUZZ_CHECK(v[0] < m->vertex_count && v[1] < m->vertex_count &&
                       v[2] < m->vertex_count);
        MTS_FUZZ_CHECK(v[0] != v[1] && v[1] != v[2] && v[0] != v[2]);
    }
}

/* The reader's own promises (gltf_read.h) on what it hands the loader. */
static void mts_fuzz_check_gltf(const mts_gltf_mesh *g)
{
    MTS_FUZZ_CHECK(g->vertex_count > 0 && g->triangle_count > 0 && g->primitives > 0);
    MTS_FUZZ_CHECK(g->positions && g->triangles);
    for (size_t i = 0; i < 3 * (size_t)g->vertex_count; i++)
        MTS_FUZZ_CHECK(isfinite(g->positions[i]));
    for (size_t k = 0; k < 3 * (size_t)g->triangle_count; k++)
        MTS_FUZZ_CHECK(g->triangles[k] < g->vertex_count);
    MTS_FUZZ_CHECK(g->colors || (!g->colors_alpha && !g->colors_translucent));
}

int mts_fuzz_gltf(const uint8_t *data, size_t size)
{
    /* an exact-size copy, so ASan sees any read past the file */
    uint8_t *bytes = malloc(size ? size : 1);
    MTS_FUZZ_CHECK(bytes != NULL);
    if (size)
        memcpy(bytes, data, size);
    const char *name = mts_gltf_is_glb(bytes, size) ? "fuzz.glb" : "fuzz.gltf";
    mts_mesh_options o = {0};
    o.max_bytes = MTS_FUZZ_GLTF_MAX_BYTES;
    mts_mesh m;
    mts_mesh_stats st;
    mts_error err = {0};
    mts_result rc = mts_mesh_load_memory(name, bytes, size, &o, &m, &st, &err);
    if (rc == MTS_OK) {
        MTS_FUZZ_CHECK(st.format == MTS_MESH_GLTF);
        mts_fuzz_check_mesh(&m);
        MTS_FUZZ_CHECK(st.colors_from_file == (m.colors != NULL));
        mts_mesh_free(&m);
    } else {
        MTS_FUZZ_CHECK(err.msg[0] != 0 && err.code == rc);
        MTS_FUZZ_CHECK(rc != MTS_ERR_NOMEM);
        MTS_FUZZ_CHECK(m.vertex_count == 0 && m.triangle_count == 0 && !m.positions &&
                       !m.normals && !m.triangles && !m.colors);
    }
    if (rc == MTS_ERR_IO) {
        mts_gltf_mesh g;
        mts_error gerr = {0};
        mts_result grc = mts_gltf_read(name, bytes, size, MTS_FUZZ_GLTF_NO_DIR,
                                       MTS_FUZZ_GLTF_MAX_BYTES, &g, &gerr);
        if (grc == MTS_OK) {
            mts_fuzz_check_gltf(&g);
        } else {
            MTS_FUZZ_CHECK(gerr.msg[0] != 0 && gerr.code == grc);
            MTS_FUZZ_CHECK(grc != MTS_ERR_NOMEM);
            MTS_FUZZ_CHECK(!g.positions && !g.triangles && !g.colors);
        }
        mts_gltf_mesh_free(&g);
    }
    free(bytes);
    return 0;
}

#ifndef MTS_FUZZ_NO_ENTRY
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return mts_fuzz_gltf(data, size);
}
#endif
