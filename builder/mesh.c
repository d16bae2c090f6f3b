/* Mesh loading: reads the file (its head first, checked against the format,
 * then the rest), picks the parser (mesh_read.c), then
 * runs the one cleaning pipeline every format shares, in the order the
 * builder relies on: triangulate (done while parsing) -> drop degenerate ->
 * drop duplicates -> drop what OpenMesh refuses -> drop unreferenced vertices
 * -> normals. */
#include "mesh.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "fileio.h"
#include "gltf_read.h"
#include "manifold.h"
#include "mesh_read.h"

/* What is read of a mesh file before the rest: the format's signature is
 * there, and the sniffer looks no further. */
#define MESH_HEAD_BYTES ((size_t)65536)

const char *mts_mesh_format_name(mts_mesh_format format)
{
    switch (format) {
    case MTS_MESH_AUTO: return "auto";
    case MTS_MESH_OFF: return "OFF";
    case MTS_MESH_OBJ: return "OBJ";
    case MTS_MESH_PLY: return "PLY";
    case MTS_MESH_STL: return "STL";
    case MTS_MESH_GLTF: return "glTF";
    }
    return "unknown";
}

void mts_mesh_free(mts_mesh *mesh)
{
    if (!mesh)
        return;
    free(mesh->positions);
    free(mesh->normals);
    free(mesh->colors);
    free(mesh->triangles);
    *mesh = (mts_mesh){0};
}

/* ------------------------------------------------------------------------ */
/* Normals                                                                  */

static inline void face_cross(const float *pos, const uint32_t *t, double n[3])
{
    const float *a = pos + (size_t)t[0] * 3, *b = pos + (size_t)t[1] * 3,
                *c = pos + (size_t)t[2] * 3;
    double u[3] = {(double)b[0] - a[0], (double)b[1] - a[1], (double)b[2] - a[2]};
    double v[3] = {(double)c[0] - a[0], (double)c[1] - a[1], (double)c[2] - a[2]};
    n[0] = u[1] * v[2] - u[2] * v[1];
    n[1] = u[2] * v[0] - u[0] * v[2];
    n[2] = u[0] * v[1] - u[1] * v[0];
}

/* Writes the unit vector of (x, y, z) to out, or zero when it has no length. */
static inline void put_unit(float *out, double x, double y, double z)
{
    double len = sqrt(x * x + y * y + z * z);
    if (len > 0 && isfinite(len)) {
        out[0] = (float)(x / len);
        out[1] = (float)(y / len);
        out[2] = (float)(z / len);
    } else {
        out[0] = out[1] = out[2] = 0.0f;
    }
}

void mts_mesh_compute_normals(mts_mesh *mesh)
{
    size_t nv = mesh->vertex_count;
    if (!mesh->normals) {
        mesh->normals = malloc((nv + 1) * 3 * sizeof *mesh->normals);
        if (!mesh->normals)
            return;
    }
    /* Sum in double: the cross products of float positions do not overflow
     * or lose small faces there; if even that buffer cannot be had, sum in
     * the output floats, which is only less exact. */
    double *acc = calloc(nv * 3 + 1, sizeof *acc);
    float *out = mesh->normals;
    memset(out, 0, nv * 3 * sizeof *out);
    for (uint32_t f = 0; f < mesh->triangle_count; f++) {
        const uint32_t *t = mesh->triangles + (size_t)f * 3;
        if (t[0] >= nv || t[1] >= nv || t[2] >= nv)
            continue;
        double n[3];
        face_cross(mesh->positions, t, n);
        for (int k = 0; k < 3; k++)
            for (int c = 0; c < 3; c++) {
                if (acc)
                    acc[(size_t)t[k] * 3 + c] += n[c];
                else
                    out[(size_t)t[k] * 3 + c] += (float)n[c];
            }
    }
    for (size_t v = 0; v < nv; v++) {
        if (acc)
            put_unit(out + v * 3, acc[v * 3], acc[v * 3 + 1], acc[v * 3 + 2]);
        else
            put_unit(out + v * 3, out[v * 3], out[v * 3 + 1], out[v * 3 + 2]);
    }
    free(acc);
}

/* ------------------------------------------------------------------------ */
/* Cleaning                                                                 */

static inline uint32_t tri_hash(uint32_t a, uint32_t b, uint32_t c)
{
    uint64_t h = (uint64_t)a * UINT64_C(0x9E3779B97F4A7C15);
    h ^= (uint64_t)b * UINT64_C(0xC2B2AE3D27D4EB4F) + (h >> 29);
    h ^= (uint64_t)c * UINT64_C(0x165667B19E3779F9) + (h >> 31);
    return (uint32_t)(h ^ (h >> 32));
}

/* The rotation of t that starts at its smallest index: two triangles are
 * the same oriented face exactly when these agree. */
static inline void tri_canonical(const uint32_t *t, uint32_t k[3])
{
    int r = t[0] < t[1] ? (t[0] < t[2] ? 0 : 2) : (t[1] < t[2] ? 1 : 2);
    k[0] = t[r];
    k[1] = t[(r + 1) % 3];
    k[2] = t[(r + 2) % 3];
}

/* Drops repeated-index and zero-area triangles in place; returns the count kept. */
static uint32_t drop_degenerate(const float *pos, uint32_t *tri, uint32_t n, uint32_t *dropped)
{
    uint32_t kept = 0;
    for (uint32_t f = 0; f < n; f++) {
        const uint32_t *t = tri + (size_t)f * 3;
        double c[3];
        if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) {
            (*dropped)++;
            continue;
        }
        face_cross(pos, t, c);
        if (c[0] == 0 && c[1] == 0 && c[2] == 0) {
            (*dropped)++;
            continue;
        }
        memmove(tri + (size_t)kept * 3, t, 3 * sizeof *t);
        kept++;
    }
    return kept;
}

/* Drops later copies of a triangle (up to rotation) in place, keeping the
 * first, with an open-addressing table of kept triangles. */
static mts_result drop_duplicates(uint32_t *tri, uint32_t *count, uint32_t *dropped,
                                  const char *name, mts_error *err)
{
    uint32_t n = *count;
    uint64_t cap = 16;
    while (cap < (uint64_t)n * 2)
        cap *= 2;
    uint32_t *table = malloc((size_t)cap * sizeof *table);
    if (!table)
        return mts_error_set(err, MTS_ERR_NOMEM, "%s: out of memory checking %u triangles for "
                             "duplicates", name, n);
    memset(table, 0xff, (size_t)cap * sizeof *table);
    uint32_t kept = 0;
    for (uint32_t f = 0; f < n; f++) {
        uint32_t k[3], o[3];
        tri_canonical(tri + (size_t)f * 3, k);
        uint32_t h = tri_hash(k[0], k[1], k[2]) & (uint32_t)(cap - 1);
        int dup = 0;
        while (table[h] != UINT32_MAX) {
            tri_canonical(tri + (size_t)table[h] * 3, o);
            if (o[0] == k[0] && o[1] == k[1] && o[2] == k[2]) {
                dup = 1;
                break;
            }
            h = (h + 1) & (uint32_t)(cap - 1);
        }
        if (dup) {
            (*dropped)++;
            continue;
        }
        memmove(tri + (size_t)kept * 3, tri + (size_t)f * 3, 3 * sizeof *tri);
        table[h] = kept++;
    }
    free(table);
    *count = kept;
    return MTS_OK;
}

/* The kept vertices' colours (raw's, NaN for none) as 8-bit sRGB in
 * mesh->colors, when every kept vertex has one; a vertex the file left
 * uncoloured has no right colour to draw, so a mix keeps none and says how
 * many lacked one (colors_missing) for the caller to warn. Only kept
 * vertices count: an unreferenced vertex without a colour harms nothing.
 *
 * Vertices are carried one for one: cleaning drops faces and unreferenced
 * vertices but never merges two vertices (only STL's corners are welded,
 * and STL has no colours). So two vertices at one position with different
 * colours stay two, as two with different normals do: the colour seam the
 * file draws is kept, at the price of the crack in connectivity the file
 * already has there. Welding them would pick one colour and smear it
 * across the seam, changing what the mesh looks like to mend a
 * connectivity the file never had. */
static mts_result take_colors(const float *col, uint32_t used, mts_mesh *mesh,
                              mts_mesh_stats *st, const char *name, mts_error *err)
{
    uint32_t missing = 0;
    for (size_t v = 0; v < used; v++)
        missing += isnan(col[v * 3]);
    if (missing == used)
        return MTS_OK; /* no kept vertex has a colour: the mesh has none */
    if (missing) {
        st->colors_missing = missing;
        return MTS_OK;
    }
    uint8_t *c = malloc((size_t)used * 3 + 1);
    if (!c)
        return mts_error_set(err, MTS_ERR_NOMEM, "%s: out of memory for colours", name);
    uint32_t clamped = 0;
    for (size_t k = 0; k < (size_t)used * 3; k++) {
        float x = col[k];
        if (x < 0.0f || x > 1.0f) {
            clamped += clamped < UINT32_MAX;
            x = x < 0.0f ? 0.0f : 1.0f;
        }
        c[k] = (uint8_t)lrintf(x * 255.0f);
    }
    st->colors_clamped = clamped;
    st->colors_from_file = 1;
    mesh->colors = c;
    return MTS_OK;
}

/* Turns a parsed raw mesh into the cleaned mesh; takes over raw's arrays. */
static mts_result clean(mts__mesh_raw *raw, mts_mesh *mesh, mts_mesh_stats *st, mts_error *err)
{
    const char *name = raw->name;
    mts_result r = MTS_OK;
    uint8_t *accepted = NULL;
    uint32_t *remap = NULL;
    uint32_t nv = raw->vertex_count;
    uint32_t *tri = raw->triangles;
    uint32_t n = drop_degenerate(raw->positions, tri, raw->triangle_count, &st->degenerate_faces);

    if (n > 0 && (r = drop_duplicates(tri, &n, &st->duplicate_faces, name, err)) != MTS_OK)
        goto done;

    if (n > 0) {
        accepted = malloc(n);
        if (!accepted) {
            r = mts_error_set(err, MTS_ERR_NOMEM, "%s: out of memory", name);
            goto done;
        }
        uint32_t refused = 0;
        if ((r = mts_manifold_filter(nv, tri, n, accepted, &refused, err)) != MTS_OK) {
            mts_error_prefix(err, "%s", name);
            goto done;
        }
        uint32_t kept = 0;
        for (uint32_t f = 0; f < n; f++)
            if (accepted[f])
                memmove(tri + (size_t)kept++ * 3, tri + (size_t)f * 3, 3 * sizeof *tri);
        st->nonmanifold_faces = refused;
        n = kept;
    }
    if (n == 0 && st->file_faces == 0) {
        /* the file has no surface at all: say so, rather than that cleaning
         * left nothing of it */
        if (raw->obj_points || raw->obj_lines)
            r = mts_error_set(err, MTS_ERR_FORMAT,
                              "%s: no triangles: the file has %u vertices, %u points ('p') and "
                              "%u lines ('l') but no faces (points and lines are not a surface)",
                              name, st->file_vertices, raw->obj_points, raw->obj_lines);
        else if (st->file_vertices)
            r = mts_error_set(err, MTS_ERR_FORMAT,
                              "%s: no triangles: the file has %u vertices but no faces (a point "
                              "cloud, not a surface)",
                              name, st->file_vertices);
        else
            r = mts_error_set(err, MTS_ERR_FORMAT,
                              "%s: no triangles: the file has no faces and no vertices", name);
        goto done;
    }
    if (n == 0) {
        r = mts_error_set(err, MTS_ERR_FORMAT,
                          "%s: no triangles left after cleaning (%u faces read: %u degenerate, "
                          "%u duplicate, %u non-manifold)",
                          name, st->file_faces, st->degenerate_faces, st->duplicate_faces,
                          st->nonmanifold_faces);
        goto done;
    }

    /* Unreferenced vertices go; the rest keep their order, so vertex i of
     * the result is still the i-th surviving vertex of the file. */
    remap = malloc(((size_t)nv + 1) * sizeof *remap);
    if (!remap) {
        r = mts_error_set(err, MTS_ERR_NOMEM, "%s: out of memory", name);
        goto done;
    }
    memset(remap, 0xff, (size_t)nv * sizeof *remap);
    for (size_t i = 0; i < (size_t)n * 3; i++)
        remap[tri[i]] = 0;
    uint32_t used = 0;
    float *pos = raw->positions, *nor = raw->normals, *col = raw->colors;
    for (uint32_t v = 0; v < nv; v++) {
        if (remap[v] == UINT32_MAX)
            continue;
        remap[v] = used;
        memmove(pos + (size_t)used * 3, pos + (size_t)v * 3, 3 * sizeof *pos);
        if (nor)
            memmove(nor + (size_t)used * 3, nor + (size_t)v * 3, 3 * sizeof *nor);
        if (col)
            memmove(col + (size_t)used * 3, col + (size_t)v * 3, 3 * sizeof *col);
        used++;
    }
    if (col && (r = take_colors(col, used, mesh, st, name, err)) != MTS_OK)
        goto done;
    for (size_t i = 0; i < (size_t)n * 3; i++)
        tri[i] = remap[tri[i]];
    st->unreferenced_vertices = nv - used;

    /* Hand the arrays over, shrunk to size (a failed shrink keeps the old block). */
    float *p = realloc(pos, (size_t)used * 3 * sizeof *p);
    mesh->positions = p ? p : pos;
    uint32_t *t = realloc(tri, (size_t)n * 3 * sizeof *t);
    mesh->triangles = t ? t : tri;
    mesh->vertex_count = used;
    mesh->triangle_count = n;
    raw->positions = NULL;
    raw->triangles = NULL;
    if (nor) {
        float *q = realloc(nor, (size_t)used * 3 * sizeof *q);
        mesh->normals = q ? q : nor;
        raw->normals = NULL;
    }

    if (mesh->normals) {
        /* the file's normals, made unit length; a zero or unusable one gets
         * the computed normal instead of staying zero */
        int missing = 0;
        float *nn = mesh->normals;
        for (size_t v = 0; v < used; v++) {
            put_unit(nn + v * 3, nn[v * 3], nn[v * 3 + 1], nn[v * 3 + 2]);
            missing |= nn[v * 3] == 0 && nn[v * 3 + 1] == 0 && nn[v * 3 + 2] == 0;
        }
        st->normals_from_file = 1;
        mesh->normals_given = 1;
        if (missing) {
            mts_mesh computed = *mesh;
            computed.normals = NULL;
            mts_mesh_compute_normals(&computed);
            if (!computed.normals) {
                r = mts_error_set(err, MTS_ERR_NOMEM, "%s: out of memory", name);
                goto done;
            }
            for (size_t v = 0; v < used; v++)
                if (nn[v * 3] == 0 && nn[v * 3 + 1] == 0 && nn[v * 3 + 2] == 0)
                    memcpy(nn + v * 3, computed.normals + v * 3, 3 * sizeof *nn);
            free(computed.normals);
        }
    } else {
        mts_mesh_compute_normals(mesh);
        if (!mesh->normals)
            r = mts_error_set(err, MTS_ERR_NOMEM, "%s: out of memory for normals", name);
    }
done:
    free(accepted);
    free(remap);
    return r;
}

/* ------------------------------------------------------------------------ */
/* Loading                                                                  */

static mts_mesh_format format_from_name(const char *name)
{
    const char *slash = strrchr(name, '/');
    const char *dot = strrchr(slash ? slash + 1 : name, '.');
    if (!dot)
        return MTS_MESH_AUTO;
    static const struct {
        const char *ext;
        mts_mesh_format format;
    } exts[] = {{"off", MTS_MESH_OFF}, {"obj", MTS_MESH_OBJ}, {"ply", MTS_MESH_PLY},
                {"stl", MTS_MESH_STL}, {"gltf", MTS_MESH_GLTF}, {"glb", MTS_MESH_GLTF}};
    for (size_t i = 0; i < sizeof exts / sizeof exts[0]; i++) {
        const char *a = dot + 1, *b = exts[i].ext;
        while (*a && *b && (*a | 0x20) == *b) /* ASCII case folding; the exts are lower case */
            a++, b++;
        if (!*a && !*b)
            return exts[i].format;
    }
    return MTS_MESH_AUTO;
}

static mts_result unknown_format(const char *name, const char *data, size_t size,
                                 mts_error *err)
{
    /* UTF-16 text hides every keyword the sniffer looks for */
    const char *wide = mts__mesh_wide_text(data, size);
    if (wide)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "%s: unknown mesh format: the file is %s, and mesh files are read "
                             "as ASCII (or UTF-8) text or binary",
                             name, wide);
    return mts_error_set(err, MTS_ERR_FORMAT,
                         "%s: unknown mesh format (not OFF, OBJ, PLY, STL or glTF by name or content)",
                         name);
}

/* glTF through the C++ shim: its flattened mesh becomes the raw mesh the
 * other parsers fill. dir: where external buffers may be read, or NULL. */
static mts_result read_gltf(mts__mesh_raw *raw, const char *data, size_t size, const char *dir,
                            uint64_t cap, mts_error *err)
{
    mts_gltf_mesh g;
    mts_result r = mts_gltf_read(raw->name, data, size, dir, cap, &g, err);
    if (r != MTS_OK)
        return r;
    raw->positions = g.positions;
    raw->triangles = g.triangles;
    raw->colors = g.colors;
    raw->stats->colors_alpha = g.colors_alpha;
    raw->stats->colors_translucent = g.colors_translucent;
    raw->vertex_count = raw->vertex_capacity = g.vertex_count;
    raw->triangle_count = raw->triangle_capacity = g.triangle_count;
    raw->obj_points = g.point_primitives;
    raw->obj_lines = g.line_primitives;
    raw->stats->file_vertices = g.vertex_count;
    raw->stats->file_faces = g.triangle_count;
    raw->stats->skipped_primitives = g.point_primitives + g.line_primitives;
    return MTS_OK;
}

static mts_result load_memory(const char *name, const void *data, size_t size,
                              const mts_mesh_options *opts, const char *dir, mts_mesh *mesh,
                              mts_mesh_stats *stats, mts_error *err)
{
    mts_mesh_stats local;
    mts_mesh_stats *st = stats ? stats : &local;
    *st = (mts_mesh_stats){0};
    if (!mesh)
        return mts_error_set(err, MTS_ERR_ARG, "mts_mesh_load: no mesh to fill");
    *mesh = (mts_mesh){0};
    if (!name)
        name = "(memory)";
    if (!data && size > 0)
        return mts_error_set(err, MTS_ERR_ARG, "%s: no data", name);
    mts_mesh_format format = opts ? opts->format : MTS_MESH_AUTO;
    if ((unsigned)format > MTS_MESH_GLTF)
        return mts_error_set(err, MTS_ERR_ARG, "%s: unknown mesh format option %d", name,
                             (int)format);
    if (size == 0)
        return mts_error_set(err, MTS_ERR_FORMAT, "%s: empty file", name);
    uint64_t cap = opts && opts->max_bytes ? opts->max_bytes : MTS_MESH_DEFAULT_MAX_BYTES;
    if (size > cap)
        return mts_error_set(err, MTS_ERR_LIMIT,
                             "%s: %zu bytes, over the size cap of %llu bytes (--max-mesh-bytes)",
                             name, size, (unsigned long long)cap);
    if (format == MTS_MESH_AUTO)
        format = format_from_name(name);
    if (format == MTS_MESH_AUTO)
        format = mts__mesh_sniff(data, size);
    if (format == MTS_MESH_AUTO)
        return unknown_format(name, data, size, err);

    mts__mesh_raw raw = {0};
    raw.name = name;
    raw.stats = st;
    mts_result r;
    switch (format) {
    case MTS_MESH_OFF: r = mts__mesh_read_off(&raw, data, size, err); break;
    case MTS_MESH_OBJ: r = mts__mesh_read_obj(&raw, data, size, err); break;
    case MTS_MESH_PLY: r = mts__mesh_read_ply(&raw, data, size, err); break;
    case MTS_MESH_GLTF: r = read_gltf(&raw, data, size, dir, cap, err); break;
    default: r = mts__mesh_read_stl(&raw, data, size, err); break;
    }
    st->format = format;
    if (opts && opts->no_colors) {
        /* dropped before cleaning looks at them: nothing to count or warn of */
        free(raw.colors);
        raw.colors = NULL;
        st->colors_alpha = 0;
        st->colors_translucent = 0;
    }
    if (r == MTS_OK)
        r = clean(&raw, mesh, st, err);
    if (r != MTS_OK)
        mts_mesh_free(mesh);
    mts__mesh_raw_free(&raw);
    return r;
}

mts_result mts_mesh_load_memory(const char *name, const void *data, size_t size,
                                const mts_mesh_options *opts, mts_mesh *mesh,
                                mts_mesh_stats *stats, mts_error *err)
{
    return load_memory(name, data, size, opts, NULL, mesh, stats, err);
}

mts_result mts_mesh_load(const char *path, const mts_mesh_options *opts, mts_mesh *mesh,
                         mts_mesh_stats *stats, mts_error *err)
{
    if (stats)
        *stats = (mts_mesh_stats){0};
    if (mesh)
        *mesh = (mts_mesh){0};
    if (!path || !mesh)
        return mts_error_set(err, MTS_ERR_ARG, "mts_mesh_load: no %s", path ? "mesh" : "path");
    mts_mesh_options o = opts ? *opts : (mts_mesh_options){0};
    if ((unsigned)o.format > MTS_MESH_GLTF)
        return mts_error_set(err, MTS_ERR_ARG, "%s: unknown mesh format option %d", path,
                             (int)o.format);
    uint64_t cap = o.max_bytes ? o.max_bytes : MTS_MESH_DEFAULT_MAX_BYTES;
    if (cap > SIZE_MAX / 2)
        cap = SIZE_MAX / 2;
    int fd;
    uint64_t file_size;
    mts_result r = mts_file_open_regular(path, cap, "--max-mesh-bytes", &fd, &file_size, err);
    if (r != MTS_OK)
        return r;
    char *data = NULL;
    uint64_t size = file_size;
    if (file_size > 0) {
        /* The head first: enough to tell the format and whether the file
         * can be one, before anything in proportion to its size is held. */
        size_t head = file_size < MESH_HEAD_BYTES ? (size_t)file_size : MESH_HEAD_BYTES;
        data = malloc(head);
        if (!data) {
            r = mts_error_set(err, MTS_ERR_NOMEM, "%s: out of memory", path);
            goto done;
        }
        if ((r = mts_file_read_exact(fd, path, data, head, err)) != MTS_OK)
            goto done;
        if (o.format == MTS_MESH_AUTO)
            o.format = format_from_name(path);
        if (o.format == MTS_MESH_AUTO)
            o.format = mts__mesh_sniff_head(data, head, file_size);
        if (o.format == MTS_MESH_AUTO) {
            r = unknown_format(path, data, head, err);
            goto done;
        }
        if ((r = mts__mesh_check_head(o.format, path, data, head, file_size, &size, err)) !=
            MTS_OK)
            goto done;
        if (size > head) {
            char *whole = realloc(data, (size_t)size);
            if (!whole) {
                r = mts_error_set(err, MTS_ERR_NOMEM, "%s: out of memory for %llu bytes", path,
                                  (unsigned long long)size);
                goto done;
            }
            data = whole;
            if ((r = mts_file_read_exact(fd, path, data + head, (size_t)size - head, err)) !=
                MTS_OK)
                goto done;
        }
    }
    close(fd);
    fd = -1;
    if (o.format == MTS_MESH_GLTF) {
        /* external buffers are read from the model's own folder only */
        const char *slash = strrchr(path, '/');
        char *dir = NULL;
        if (slash) {
            dir = malloc((size_t)(slash - path) + 2);
            if (!dir) {
                r = mts_error_set(err, MTS_ERR_NOMEM, "%s: out of memory", path);
                goto done;
            }
            memcpy(dir, path, (size_t)(slash - path));
            dir[slash - path] = 0;
            if (slash == path)
                strcpy(dir, "/");
        }
        r = load_memory(path, data, (size_t)size, &o, dir ? dir : ".", mesh, stats, err);
        free(dir);
    } else {
        r = mts_mesh_load_memory(path, data, (size_t)size, &o, mesh, stats, err);
    }
done:
    if (fd >= 0)
        close(fd);
    free(data);
    return r;
}
