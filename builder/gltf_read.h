/* glTF 2.0 (.gltf JSON with its buffers, and binary .glb) through tinygltf
 * (Debian's libtinygltf), behind a C interface as simplify.cpp does for
 * OpenMesh. Internal to the mesh loader (mesh.c): not part of the public API.
 *
 * The default scene's (else the first scene's, else every root node's)
 * meshes are flattened into one mesh in world space, each node's transform
 * (matrix, or translation * rotation * scale) applied. TRIANGLES,
 * TRIANGLE_STRIP and TRIANGLE_FAN primitives become triangles, with
 * their COLOR_0 when they have one; POINTS and
 * LINES primitives have no surface and are skipped and counted. Positions
 * are float or normalized integer VEC3; indices 8, 16 or 32-bit; sparse
 * accessors are applied. Every accessor, buffer view and index is checked
 * against what it refers to: no count or offset in the file is trusted.
 * Images are never decoded or read; an external buffer is read only from the
 * model's own folder (a plain file name: no '/', '\\', ".." or scheme), and
 * only when the model came from a file (dir non-NULL); data: URIs are read
 * in place. KHR_draco_mesh_compression primitives are decoded through
 * Draco, the compressed bytes checked as hostile as the rest (see
 * gltf_draco.cpp). TEXCOORD_n and NORMAL are not read. */
#ifndef MTS_GLTF_READ_H
#define MTS_GLTF_READ_H

#include <stddef.h>
#include <stdint.h>

#include "error.h"

#ifdef __cplusplus
extern "C" {
#endif

/* What the reader hands back; arrays are malloc'd (free with
 * mts_gltf_mesh_free), triangle indices < vertex_count. */
typedef struct mts_gltf_mesh {
    float *positions;           /* 3 per vertex, world space */
    /* 3 per vertex when some primitive has COLOR_0, else NULL: sRGB
     * (converted from glTF's linear colours) nominally in 0..1, unclamped;
     * NaN for the vertices of a primitive without COLOR_0 */
    float *colors;
    int colors_alpha;             /* some COLOR_0 was VEC4: alpha dropped */
    uint32_t colors_translucent;  /* vertices whose alpha was below 1 */
    uint32_t vertex_count;
    uint32_t *triangles;        /* 3 per triangle */
    uint32_t triangle_count;
    uint32_t primitives;        /* triangle primitives read */
    uint32_t point_primitives;  /* POINTS: skipped */
    uint32_t line_primitives;   /* LINES, LINE_LOOP, LINE_STRIP: skipped */
} mts_gltf_mesh;

/* 1 when data starts with the GLB magic "glTF". */
int mts_gltf_is_glb(const void *data, size_t size);

/* Reads a .gltf or .glb held in memory. name is for messages; dir is the
 * folder of the file the bytes came from (external buffers are read from
 * there, their bytes counted against max_bytes together with size), or NULL
 * when external buffers may not be read (a download). */
mts_result mts_gltf_read(const char *name, const void *data, size_t size, const char *dir,
                         uint64_t max_bytes, mts_gltf_mesh *out, mts_error *err);

void mts_gltf_mesh_free(mts_gltf_mesh *m);

#ifdef __cplusplus
}
#endif

#endif
