/* An indexed triangle mesh read from OFF, OBJ, PLY (ASCII and binary), STL or glTF 2.0
 * (ASCII and binary), cleaned so that the builder can trust it:
 *   - polygons are fan-triangulated;
 *   - faces with a repeated index or zero area are dropped (counted);
 *   - duplicate faces (the same triangle up to rotation) are dropped (counted);
 *   - faces OpenMesh refuses (non-manifold edges/vertices) are dropped (counted);
 *   - vertices no kept face references are dropped and the rest renumbered
 *     in their original order;
 *   - normals come from the file when it has per-vertex normals, else they are
 *     area-weighted face normals;
 *   - colours come from the file when every kept vertex has one, as 8-bit
 *     sRGB (glTF's linear colours converted), out-of-range values clamped
 *     and counted, alpha dropped; a non-finite colour is refused.
 * STL has no shared vertices, so identical positions are welded first. */
#ifndef MTS_MESH_H
#define MTS_MESH_H

#include <stddef.h>
#include <stdint.h>

#include "error.h"

typedef struct mts_mesh {
    uint32_t vertex_count;
    uint32_t triangle_count;
    float *positions;    /* 3 per vertex */
    float *normals;      /* 3 per vertex, unit length (or zero for a vertex of zero-area faces only) */
    uint32_t *triangles; /* 3 per triangle, counter-clockwise seen from outside */
    uint8_t *colors;     /* 3 per vertex (8-bit sRGB red, green, blue), or NULL: the file
                            has none (or the caller dropped them) */
    /* 1 when the normals came from the file (the mesh's own shading), 0 when
     * mts_mesh_compute_normals made them: a stream need not carry those,
     * since a client can shade the faces it has (docs/PROTOCOL.md). */
    int normals_given;
} mts_mesh;

typedef enum mts_mesh_format {
    MTS_MESH_AUTO = 0, /* from the file name's extension, else from the content */
    MTS_MESH_OFF,
    MTS_MESH_OBJ,
    MTS_MESH_PLY,
    MTS_MESH_STL,
    MTS_MESH_GLTF /* glTF 2.0: .gltf (JSON) and .glb (binary), see gltf_read.h */
} mts_mesh_format;

/* What loading found and fixed, for the user's report. */
typedef struct mts_mesh_stats {
    mts_mesh_format format;
    uint32_t file_vertices;          /* vertices as declared/read in the file */
    uint32_t file_faces;             /* faces (polygons) read from the file */
    uint32_t polygons_triangulated;  /* faces with more than 3 corners */
    uint32_t degenerate_faces;       /* repeated index or zero area: dropped */
    uint32_t duplicate_faces;        /* same triangle again: dropped */
    uint32_t nonmanifold_faces;      /* refused by OpenMesh: dropped */
    uint32_t unreferenced_vertices;  /* dropped */
    uint32_t welded_vertices;        /* STL corners merged into shared vertices */
    int normals_from_file;           /* 1 when the file's normals were used */
    /* Header lines that are no keyword of the format, skipped so that a
     * file real tools read is read here too (Blender 2.47 wrote PLY headers
     * with "Created by ..." lacking "comment"); the caller warns. */
    uint32_t skipped_header_lines;
    uint32_t first_skipped_header_line; /* its 1-based line number, when there is one */
    /* glTF POINTS and LINES primitives: no surface, skipped */
    uint32_t skipped_primitives;
    /* Vertex colours (PLY red green blue [alpha], OBJ "v x y z r g b",
     * COFF, ASCII or binary, glTF COLOR_0), stored as 8-bit sRGB in
     * mesh.colors. */
    int colors_from_file;          /* 1 when the mesh keeps the file's colours */
    int colors_alpha;              /* 1 when they came with alpha, which is dropped:
                                    * the model is drawn opaque */
    uint32_t colors_translucent;   /* vertices whose dropped alpha was below opaque */
    uint32_t colors_clamped;       /* colour components outside their range, clamped */
    /* Kept vertices without a colour in a file where others have one (OBJ
     * may mix "v x y z" and "v x y z r g b", glTF primitives with and
     * without COLOR_0): the mesh then has no colours at all, since a
     * vertex of no colour has no right one to draw; the caller warns. */
    uint32_t colors_missing;
} mts_mesh_stats;

/* The default size cap of a mesh file (mts_mesh_options.max_bytes). */
#define MTS_MESH_DEFAULT_MAX_BYTES ((uint64_t)4 << 30) /* 4 GiB */

/* Options; a zero-initialised struct means the defaults. */
typedef struct mts_mesh_options {
    mts_mesh_format format; /* MTS_MESH_AUTO by default */
    uint64_t max_bytes;     /* a larger file or buffer is refused; 0: 4 GiB */
    int no_colors;          /* 1: the file's vertex colours are not kept (nor counted) */
} mts_mesh_options;

/* Reads and cleans a mesh file. On failure the message names the file and the
 * problem (missing, empty, truncated at line/byte N, bad index ...), never
 * the file's own text: a file may be anything, and messages end up in logs.
 * Only a regular file is read (a FIFO, a device or a directory is refused
 * without blocking), and only up to opts->max_bytes, checked before reading.
 * With MTS_MESH_AUTO and no known extension the format comes from the first
 * 64 KiB. Those first bytes are checked against the format before the rest
 * is read, where the format has a signature (OFF's keyword, PLY's magic, a
 * binary STL's facet count against the file's size, OBJ's being text), so
 * that a file that is not a mesh costs a small read, not the whole file;
 * a binary STL is read only as far as its facets go. stats may be NULL;
 * opts may be NULL for the defaults. */
mts_result mts_mesh_load(const char *path, const mts_mesh_options *opts, mts_mesh *mesh,
                         mts_mesh_stats *stats, mts_error *err);

/* The same from memory (a downloaded file); name is used in messages and, with
 * MTS_MESH_AUTO, its extension picks the format. */
mts_result mts_mesh_load_memory(const char *name, const void *data, size_t size,
                                const mts_mesh_options *opts, mts_mesh *mesh,
                                mts_mesh_stats *stats, mts_error *err);

void mts_mesh_free(mts_mesh *mesh);

/* Area-weighted vertex normals from the triangles (overwrites mesh->normals). */
void mts_mesh_compute_normals(mts_mesh *mesh);

const char *mts_mesh_format_name(mts_mesh_format format);

#endif
