/* Internal to the mesh loader (mesh.c + mesh_read.c and the per-format
 * mesh_read_off.c, _obj.c, _ply.c, _stl.c): the parsers and what they hand to
 * the cleaning pipeline. Not part of the public API.
 *
 * A parser reads the bytes of one file and fills an mts__mesh_raw: positions
 * (and normals and colours when the file has them per vertex) plus the polygons already
 * fan-triangulated, winding kept, with every index checked against the vertex
 * count. Everything after that (degenerate, duplicate and non-manifold faces,
 * unreferenced vertices, normals) is mesh.c's job, the same for every format. */
#ifndef MTS_MESH_READ_H
#define MTS_MESH_READ_H

#include <stddef.h>
#include <stdint.h>

#include "error.h"
#include "mesh.h"

/* Every count (vertices, polygons, triangles, corners) stays below 2^31 so
 * that it fits an int anywhere downstream (OpenMesh handles are int). */
#define MTS__MESH_MAX_COUNT 0x7fffffffu

typedef struct mts__mesh_raw {
    const char *name;        /* for messages */
    uint32_t vertex_count;
    uint32_t vertex_capacity;
    float *positions;        /* 3 per vertex */
    float *normals;          /* 3 per vertex when the file has per-vertex normals, else NULL */
    /* 3 per vertex once some vertex has a colour, else NULL: sRGB red,
     * green, blue nominally in 0..1 but not yet clamped (mesh.c clamps and
     * counts), NaN for a vertex the file gives no colour (a parser refuses
     * a non-finite colour, so NaN means only that). Alpha is not kept: the
     * parser counts it in stats (colors_alpha, colors_translucent). */
    float *colors;
    uint32_t triangle_count;
    uint32_t triangle_capacity;
    uint32_t *triangles;     /* 3 per triangle, indices < vertex_count */
    mts_mesh_stats *stats;   /* the parser fills format, file_*, polygons_triangulated,
                              * welded_vertices, skipped_header_lines, and counts
                              * polygons of < 3 corners in degenerate_faces */
    uint32_t obj_points, obj_lines; /* OBJ 'p' and 'l' elements, which have no surface:
                                     * a file of only those is refused as such */
} mts__mesh_raw;

void mts__mesh_raw_free(mts__mesh_raw *raw);

/* The parsers. data need not be NUL-terminated; size > 0. The OFF parser
 * reads ASCII and binary OFF ("OFF BINARY": Geomview's big-endian layout with
 * a colour count per face, and OpenMesh's little-endian one without), with
 * COFF's vertex colours either way. */
mts_result mts__mesh_read_off(mts__mesh_raw *raw, const char *data, size_t size, mts_error *err);
mts_result mts__mesh_read_obj(mts__mesh_raw *raw, const char *data, size_t size, mts_error *err);
mts_result mts__mesh_read_ply(mts__mesh_raw *raw, const char *data, size_t size, mts_error *err);
mts_result mts__mesh_read_stl(mts__mesh_raw *raw, const char *data, size_t size, mts_error *err);

/* "UTF-16 (big-endian)" and the like when data (the start of a file) is
 * UTF-16 or UTF-32 text, by its byte order mark or its NUL high bytes;
 * NULL otherwise. For messages: no reader takes such text. */
const char *mts__mesh_wide_text(const char *data, size_t size);

/* The format the content looks like, or MTS_MESH_AUTO when none fits. Only
 * the first 64 KiB are looked at. */
mts_mesh_format mts__mesh_sniff(const char *data, size_t size);
/* The same from the head of a file of file_size bytes (head_size of them,
 * at least 64 KiB unless that is the whole file). */
mts_mesh_format mts__mesh_sniff_head(const char *head, size_t head_size, uint64_t file_size);

/* Checks the head of a file of file_size bytes against what the parser of
 * format will require of it, so that a file that cannot be one is refused
 * before the rest is read: the same rules and the same messages as the
 * parser, applied only where the head decides them. *read_size gets how
 * much of the file the parser needs (all of it, but a binary STL's facets
 * end where its count says). */
mts_result mts__mesh_check_head(mts_mesh_format format, const char *name, const char *head,
                                size_t head_size, uint64_t file_size, uint64_t *read_size,
                                mts_error *err);

/* Parses a decimal floating-point number at *s (no leading blanks) into the
 * nearest float, exactly as strtof would in the C locale, without needing a
 * NUL terminator. On success advances *s and returns 0; returns -1 when there
 * is no number there and -2 when it does not fit a float. Exposed for tests. */
int mts__mesh_scan_float(const char **s, const char *end, float *out);

#endif
