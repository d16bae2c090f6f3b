/* The PLY parser: ASCII, binary little- and big-endian; the vertex and face
 * elements are read (positions, normals, colours, index lists), the others
 * skipped. */
#include "mesh_read_internal.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum ply_type { PLY_NONE, PLY_I8, PLY_U8, PLY_I16, PLY_U16, PLY_I32, PLY_U32, PLY_F32, PLY_F64 };
static const unsigned ply_size[] = {0, 1, 1, 2, 2, 4, 4, 4, 8};

enum ply_role {
    ROLE_SKIP,
    ROLE_X,
    ROLE_Y,
    ROLE_Z,
    ROLE_NX,
    ROLE_NY,
    ROLE_NZ,
    ROLE_INDICES,
    ROLE_RED,
    ROLE_GREEN,
    ROLE_BLUE,
    ROLE_ALPHA,
    ROLE_COUNT
};
enum ply_kind { ELEM_OTHER, ELEM_VERTEX, ELEM_FACE };
enum ply_format { PLY_ASCII, PLY_LE, PLY_BE };

#define PLY_MAX_ELEMENTS 64
#define PLY_MAX_PROPERTIES 1024

typedef struct ply_prop {
    uint8_t type;       /* the scalar, or the list's item type */
    uint8_t count_type; /* the list's count type; PLY_NONE for a scalar */
    uint8_t role;
} ply_prop;

typedef struct ply_elem {
    char name[32];
    uint32_t count;
    uint32_t first, props; /* its properties in the flat property array */
    int kind;
    uint64_t min_bytes; /* the least one instance can take in the file */
} ply_elem;

typedef struct ply {
    int format;
    ply_elem elems[PLY_MAX_ELEMENTS];
    ply_prop props[PLY_MAX_PROPERTIES];
    uint32_t elem_count, prop_count;
    /* the data cursor: text for ASCII, bytes otherwise */
    mts__text t;
    const unsigned char *p, *end;
    const char *data; /* the whole file, for the messages of one that is not PLY */
    size_t size;
    const char *body; /* where the data starts, after end_header */
} ply;

static int ply_type_of(const char *w, size_t n)
{
    static const struct {
        const char *name;
        int type;
    } names[] = {{"char", PLY_I8},     {"int8", PLY_I8},     {"uchar", PLY_U8},
                 {"uint8", PLY_U8},    {"short", PLY_I16},   {"int16", PLY_I16},
                 {"ushort", PLY_U16},  {"uint16", PLY_U16},  {"int", PLY_I32},
                 {"int32", PLY_I32},   {"uint", PLY_U32},    {"uint32", PLY_U32},
                 {"float", PLY_F32},   {"float32", PLY_F32}, {"double", PLY_F64},
                 {"float64", PLY_F64}};
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
        if (mts__word_is(w, n, names[i].name))
            return names[i].type;
    return PLY_NONE;
}

/* "vertices", "faces", or "items of element N" for the others. */
static const char *ply_noun(const ply_elem *e, char *buf, size_t size)
{
    if (e->kind != ELEM_OTHER)
        return e->kind == ELEM_VERTEX ? "vertices" : "faces";
    snprintf(buf, size, "items of %s", e->name);
    return buf;
}

/* "vertex I", "face I", or "element N, item I". */
static const char *ply_item(const ply_elem *e, uint32_t i, char *buf, size_t size)
{
    snprintf(buf, size, e->kind == ELEM_OTHER ? "%s, item %u" : "%s %u", e->name, i);
    return buf;
}

/* A file without the magic: UTF-16 or binary data is named as such (a
 * binary PLY's header is text too). */
mts_result mts__ply_no_magic(const char *name, const char *data, size_t size, mts_error *err)
{
    mts_result r = mts__text_refuse(name, data, size, "a PLY", "ASCII PLY",
                                    " (and no 'ply' magic)", err);
    if (r != MTS_OK)
        return r;
    return mts_error_set(err, MTS_ERR_FORMAT, "%s: not a PLY file (no 'ply' magic)", name);
}

/* Reads the header up to and including the end_header line. */
static mts_result ply_header(ply *P, mts__mesh_raw *raw, mts_error *err)
{
    mts__text *t = &P->t;
    const char *name = raw->name;
    const char *w;
    size_t wn = mts__text_word(t, &w);
    if (!mts__word_is(w, wn, "ply"))
        return mts__ply_no_magic(name, P->data, P->size, err);
    mts__text_next_line(t);
    int have_format = 0;
    ply_elem *cur = NULL;
    for (;;) {
        if (mts__text_eof(t))
            return mts_error_set(err, MTS_ERR_FORMAT, "%s: truncated: the PLY header has no end_header",
                                 name);
        wn = mts__text_word(t, &w);
        if (mts__word_is(w, wn, "end_header")) {
            mts__text_next_line(t);
            break;
        } else if (wn == 0 || mts__word_is(w, wn, "comment") || mts__word_is(w, wn, "obj_info")) {
            /* nothing */
        } else if (mts__word_is(w, wn, "format")) {
            const char *f, *v;
            size_t fn = mts__text_word(t, &f), vn = mts__text_word(t, &v);
            if (mts__word_is(f, fn, "ascii"))
                P->format = PLY_ASCII;
            else if (mts__word_is(f, fn, "binary_little_endian"))
                P->format = PLY_LE;
            else if (mts__word_is(f, fn, "binary_big_endian"))
                P->format = PLY_BE;
            else
                return mts_error_set(err, MTS_ERR_VERSION,
                                     "%s: line %llu: unknown PLY format (not ascii, "
                                     "binary_little_endian or binary_big_endian)",
                                     name, (unsigned long long)t->line);
            if (vn == 0 || v[0] != '1')
                return mts_error_set(err, MTS_ERR_VERSION, "%s: line %llu: the PLY version is not 1.x",
                                     name, (unsigned long long)t->line);
            have_format = 1;
        } else if (mts__word_is(w, wn, "element")) {
            if (P->elem_count == PLY_MAX_ELEMENTS)
                return mts_error_set(err, MTS_ERR_LIMIT, "%s: more than %d PLY elements", name,
                                     PLY_MAX_ELEMENTS);
            const char *en;
            size_t enn = mts__text_word(t, &en);
            mts__text_blank(t);
            int64_t count;
            if (enn == 0 || mts__text_eol(t) || mts__scan_int(&t->p, t->end, &count) != 0 ||
                !mts__token_ends(t, t->p) || count < 0)
                return mts_error_set(err, MTS_ERR_FORMAT, "%s: line %llu: bad element line", name,
                                     (unsigned long long)t->line);
            if (count > (int64_t)MTS__MESH_MAX_COUNT)
                return mts_error_set(err, MTS_ERR_LIMIT,
                                     "%s: line %llu: %lld elements is over the limit of %u",
                                     name, (unsigned long long)t->line, (long long)count,
                                     MTS__MESH_MAX_COUNT);
            cur = &P->elems[P->elem_count++];
            memset(cur, 0, sizeof *cur);
            /* named in messages by what it means to us, not by the file's mts__text */
            snprintf(cur->name, sizeof cur->name, "element %u", P->elem_count);
            cur->count = (uint32_t)count;
            cur->first = P->prop_count;
            if (mts__word_is(en, enn, "vertex") || mts__word_is(en, enn, "face")) {
                int kind = mts__word_is(en, enn, "vertex") ? ELEM_VERTEX : ELEM_FACE;
                snprintf(cur->name, sizeof cur->name, "%s", kind == ELEM_VERTEX ? "vertex" : "face");
                for (uint32_t e = 0; e + 1 < P->elem_count; e++)
                    if (P->elems[e].kind == kind)
                        return mts_error_set(err, MTS_ERR_FORMAT, "%s: two '%s' elements", name,
                                             cur->name);
                cur->kind = kind;
            }
        } else if (mts__word_is(w, wn, "property")) {
            if (!cur)
                return mts_error_set(err, MTS_ERR_FORMAT, "%s: line %llu: property before any element",
                                     name, (unsigned long long)t->line);
            if (P->prop_count == PLY_MAX_PROPERTIES)
                return mts_error_set(err, MTS_ERR_LIMIT, "%s: more than %d PLY properties", name,
                                     PLY_MAX_PROPERTIES);
            ply_prop prop = {PLY_NONE, PLY_NONE, ROLE_SKIP};
            const char *tw, *pn;
            size_t twn = mts__text_word(t, &tw);
            if (mts__word_is(tw, twn, "list")) {
                const char *cw;
                size_t cwn = mts__text_word(t, &cw);
                twn = mts__text_word(t, &tw);
                prop.count_type = (uint8_t)ply_type_of(cw, cwn);
                if (prop.count_type == PLY_NONE || prop.count_type == PLY_F32 ||
                    prop.count_type == PLY_F64)
                    return mts_error_set(err, MTS_ERR_FORMAT, "%s: line %llu: bad list count type",
                                         name, (unsigned long long)t->line);
            }
            prop.type = (uint8_t)ply_type_of(tw, twn);
            size_t pnn = mts__text_word(t, &pn);
            if (prop.type == PLY_NONE || pnn == 0)
                return mts_error_set(err, MTS_ERR_FORMAT, "%s: line %llu: bad property type",
                                     name, (unsigned long long)t->line);
            int is_list = prop.count_type != PLY_NONE;
            if (cur->kind == ELEM_VERTEX && !is_list) {
                static const char *const coords[] = {"x", "y", "z", "nx", "ny", "nz"};
                for (int c = 0; c < 6; c++)
                    if (mts__word_is(pn, pnn, coords[c]))
                        prop.role = (uint8_t)(ROLE_X + c);
                /* the names MeshLab, Blender, Open3D and CloudCompare write
                 * ("diffuse_" from some scanners' software) */
                static const char *const colors[2][4] = {
                    {"red", "green", "blue", "alpha"},
                    {"diffuse_red", "diffuse_green", "diffuse_blue", "diffuse_alpha"}};
                for (int n = 0; n < 2; n++)
                    for (int c = 0; c < 4; c++)
                        if (mts__word_is(pn, pnn, colors[n][c]))
                            prop.role = (uint8_t)(ROLE_RED + c);
            } else if (cur->kind == ELEM_FACE &&
                       (mts__word_is(pn, pnn, "vertex_indices") ||
                        mts__word_is(pn, pnn, "vertex_index"))) {
                if (!is_list)
                    return mts_error_set(err, MTS_ERR_FORMAT,
                                         "%s: line %llu: the face's vertex indices are not a list",
                                         name, (unsigned long long)t->line);
                prop.role = ROLE_INDICES;
            }
            P->props[P->prop_count++] = prop;
            cur->props++;
        } else {
            /* Not a PLY keyword. Blender 2.47 wrote "Created by Blender3D
             * ..." without "comment" (Wuson.ply in assimp's test models),
             * and assimp and MeshLab read such files: skipped like a
             * comment, and counted so that the caller can warn. A line that
             * mattered (a misspelt element) shows up as missing data next. */
            mts_mesh_stats *st = raw->stats;
            if (st->skipped_header_lines == 0)
                st->first_skipped_header_line =
                    t->line > UINT32_MAX ? UINT32_MAX : (uint32_t)t->line;
            st->skipped_header_lines += st->skipped_header_lines < UINT32_MAX;
        }
        mts__text_next_line(t);
    }
    if (!have_format)
        return mts_error_set(err, MTS_ERR_FORMAT, "%s: the PLY header has no format line", name);
    return MTS_OK;
}

/* Reading one value, ASCII or binary. Returns 0, 1 at the end of the data, 2
 * for a bad token / non-finite or non-integral value. */
static int ply_binary(ply *P, int type, double *out)
{
    unsigned n = ply_size[type];
    if ((size_t)(P->end - P->p) < n)
        return 1;
    uint64_t u = 0;
    if (P->format == PLY_LE)
        for (unsigned i = n; i-- > 0;)
            u = u << 8 | P->p[i];
    else
        for (unsigned i = 0; i < n; i++)
            u = u << 8 | P->p[i];
    P->p += n;
    switch (type) {
    case PLY_I8: *out = (int8_t)(uint8_t)u; break;
    case PLY_U8: *out = (uint8_t)u; break;
    case PLY_I16: *out = (int16_t)(uint16_t)u; break;
    case PLY_U16: *out = (uint16_t)u; break;
    case PLY_I32: *out = (int32_t)(uint32_t)u; break;
    case PLY_U32: *out = (uint32_t)u; break;
    case PLY_F32: {
        uint32_t w = (uint32_t)u;
        float f;
        memcpy(&f, &w, sizeof f);
        *out = f;
        break;
    }
    default: {
        double d;
        memcpy(&d, &u, sizeof d);
        *out = d;
        break;
    }
    }
    return isfinite(*out) ? 0 : 2;
}

/* One value as a double: binary as stored, ASCII through the float scanner. */
static int ply_get_real(ply *P, int type, double *out)
{
    if (P->format != PLY_ASCII)
        return ply_binary(P, type, out);
    mts__text_space(&P->t);
    if (mts__text_eof(&P->t))
        return 1;
    const char *s = P->t.p;
    float f;
    if (mts__mesh_scan_float(&s, P->t.end, &f) != 0 || !mts__token_ends(&P->t, s))
        return P->t.p + mts__token_len(&P->t) >= P->t.end ? 1 : 2; /* cut inside: truncated */
    P->t.p = s;
    *out = f;
    return 0;
}

static int ply_get_float(ply *P, int type, float *out)
{
    double d;
    int r = ply_get_real(P, type, &d);
    if (r == 0) {
        if (fabs(d) > FLT_MAX)
            return 2;
        *out = (float)d;
    }
    return r;
}

static int ply_get_int(ply *P, int type, int64_t *out)
{
    if (P->format == PLY_ASCII) {
        mts__text_space(&P->t);
        if (mts__text_eof(&P->t))
            return 1;
        const char *s = P->t.p;
        if (mts__scan_int(&s, P->t.end, out) == 0 && mts__token_ends(&P->t, s)) {
            P->t.p = s;
            return 0;
        }
        /* else only an integral value written as a float ("3.0") in a
         * float-typed list */
        if (type != PLY_F32 && type != PLY_F64)
            return P->t.p + mts__token_len(&P->t) >= P->t.end ? 1 : 2; /* cut inside: truncated */
    }
    double d;
    int r = ply_get_real(P, type, &d);
    if (r == 0) {
        if (d != floor(d) || fabs(d) > 1e15)
            return 2;
        *out = (int64_t)d;
    }
    return r;
}

/* Skips n values of one type. */
static int ply_skip(ply *P, int type, uint64_t n)
{
    if (P->format != PLY_ASCII) {
        uint64_t bytes = n * ply_size[type]; /* n < 2^31, size <= 8: no overflow */
        if ((uint64_t)(P->end - P->p) < bytes)
            return 1;
        P->p += bytes;
        return 0;
    }
    for (uint64_t i = 0; i < n; i++) {
        mts__text_space(&P->t);
        if (mts__text_eof(&P->t))
            return 1;
        while (P->t.p < P->t.end && !mts__is_space(*P->t.p))
            P->t.p++;
    }
    return 0;
}

static mts_result ply_value_error(const ply *P, const ply_elem *e, uint32_t i, int status,
                                  const char *name, mts_error *err)
{
    char what[64];
    /* a binary body under a header that says ascii (a hand-edited header,
     * or a tool that wrote the wrong word) is named, not taken for a bad
     * value or a cut file */
    if (P->format == PLY_ASCII && memchr(P->body, 0, (size_t)(P->data + P->size - P->body)))
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "%s: line %llu: %s: the header says ascii, but the data is binary",
                             name, (unsigned long long)P->t.line, ply_item(e, i, what, sizeof what));
    if (status == 1)
        return mts_error_set(err, MTS_ERR_FORMAT, "%s: truncated: expected %u %s, file ends after %u",
                             name, e->count, ply_noun(e, what, sizeof what), i);
    if (P->format == PLY_ASCII)
        return mts_error_set(err, MTS_ERR_FORMAT, "%s: line %llu: bad value in %s", name,
                             (unsigned long long)P->t.line, ply_item(e, i, what, sizeof what));
    return mts_error_set(err, MTS_ERR_FORMAT, "%s: %s: a value is not finite or not an integer",
                         name, ply_item(e, i, what, sizeof what));
}

mts_result mts__mesh_read_ply(mts__mesh_raw *raw, const char *data, size_t size, mts_error *err)
{
    const char *name = raw->name;
    mts_mesh_stats *st = raw->stats;
    st->format = MTS_MESH_PLY;
    ply *P = calloc(1, sizeof *P); /* the property table is too big for some stacks */
    if (!P)
        return mts_error_set(err, MTS_ERR_NOMEM, "%s: out of memory", name);
    P->t = (mts__text){data, data + size, 1, 0, name};
    P->data = data;
    P->size = size;
    mts_result r = ply_header(P, raw, err);
    if (r != MTS_OK)
        goto done;
    P->body = P->t.p;

    ply_elem *vert = NULL, *face = NULL;
    int has_xyz[3] = {0, 0, 0}, has_n[3] = {0, 0, 0}, has_rgba[4] = {0, 0, 0, 0},
        has_indices = 0;
    double color_scale[4] = {1, 1, 1, 1};
    for (uint32_t e = 0; e < P->elem_count; e++) {
        ply_elem *el = &P->elems[e];
        uint64_t min = 0;
        for (uint32_t k = 0; k < el->props; k++) {
            const ply_prop *pr = &P->props[el->first + k];
            /* the least an instance takes: a scalar's bytes or a list's count
             * in binary, a character and a separator per value in ASCII */
            min += P->format == PLY_ASCII
                       ? 1
                       : ply_size[pr->count_type != PLY_NONE ? pr->count_type : pr->type];
            if (pr->role >= ROLE_X && pr->role <= ROLE_Z)
                has_xyz[pr->role - ROLE_X] = 1;
            else if (pr->role >= ROLE_NX && pr->role <= ROLE_NZ)
                has_n[pr->role - ROLE_NX] = 1;
            else if (pr->role >= ROLE_RED && pr->role <= ROLE_ALPHA) {
                /* 8-bit is what PLY writers use; ushort is 16-bit; floats
                 * are 0..1 (assimp's float-color.ply, Open3D); other
                 * integer types hold 0..255 where they are written at all */
                has_rgba[pr->role - ROLE_RED] = 1;
                color_scale[pr->role - ROLE_RED] = pr->type == PLY_U16   ? 65535.0
                                                   : pr->type == PLY_F32 ||
                                                           pr->type == PLY_F64
                                                       ? 1.0
                                                       : 255.0;
            } else if (pr->role == ROLE_INDICES)
                has_indices = 1;
        }
        el->min_bytes = min;
        if (el->kind == ELEM_VERTEX)
            vert = el;
        else if (el->kind == ELEM_FACE)
            face = el;
    }
    if (!vert || !has_xyz[0] || !has_xyz[1] || !has_xyz[2]) {
        r = mts_error_set(err, MTS_ERR_FORMAT, "%s: the PLY file has no vertex element with x, y, z",
                          name);
        goto done;
    }
    if (!face || !has_indices) {
        r = mts_error_set(err, MTS_ERR_FORMAT, "%s: no triangles: the PLY file has no face element "
                          "with vertex_indices", name);
        goto done;
    }
    int with_normals = has_n[0] && has_n[1] && has_n[2];
    int with_colors = has_rgba[0] && has_rgba[1] && has_rgba[2];
    const uint32_t nv = vert->count;
    if (with_colors && (r = mts__raw_enable_colors(raw, err)) != MTS_OK)
        goto done;

    if (P->format != PLY_ASCII) {
        P->p = (const unsigned char *)P->t.p;
        P->end = (const unsigned char *)P->t.end;
    }
    size_t left = (size_t)(P->t.end - P->t.p);
    {
        /* reserve what the bytes left can hold, not what the header claims */
        uint64_t cap_v = vert->min_bytes ? left / vert->min_bytes + 1 : nv;
        uint64_t cap_f = face->min_bytes ? left / face->min_bytes + 1 : face->count;
        uint64_t want_v = nv < cap_v ? nv : cap_v;
        uint64_t want_f = face->count < cap_f ? face->count : cap_f;
        if ((r = mts__raw_reserve_vertices(raw, want_v, with_normals, err)) != MTS_OK ||
            (r = mts__raw_reserve_triangles(raw, want_f, err)) != MTS_OK)
            goto done;
    }

    for (uint32_t e = 0; e < P->elem_count; e++) {
        const ply_elem *el = &P->elems[e];
        const ply_prop *props = P->props + el->first;
        if (el->props == 0)
            continue; /* nothing in the file to read, however many it claims */
        for (uint32_t i = 0; i < el->count; i++) {
            float v[ROLE_COUNT] = {0};
            mts__fan poly = {0, 0, 0};
            int status = 0;
            if (el->kind == ELEM_VERTEX &&
                (r = mts__raw_reserve_vertices(raw, (uint64_t)i + 1, with_normals, err)) != MTS_OK)
                goto done;
            for (uint32_t k = 0; k < el->props && status == 0; k++) {
                const ply_prop *pr = &props[k];
                if (pr->count_type == PLY_NONE) {
                    if (pr->role != ROLE_SKIP)
                        status = ply_get_float(P, pr->type, &v[pr->role]);
                    else
                        status = ply_skip(P, pr->type, 1);
                    continue;
                }
                int64_t n;
                if ((status = ply_get_int(P, pr->count_type, &n)) != 0)
                    break;
                if (n < 0 || n > (int64_t)MTS__MESH_MAX_COUNT) {
                    char what[64];
                    r = mts_error_set(err, MTS_ERR_FORMAT, "%s: %s: list of %lld items", name,
                                      ply_item(el, i, what, sizeof what), (long long)n);
                    goto done;
                }
                if (pr->role != ROLE_INDICES) {
                    status = ply_skip(P, pr->type, (uint64_t)n);
                    continue;
                }
                for (int64_t c = 0; c < n && status == 0; c++) {
                    int64_t idx;
                    if ((status = ply_get_int(P, pr->type, &idx)) != 0)
                        break;
                    if (idx < 0 || idx >= nv) {
                        if (P->format == PLY_ASCII)
                            r = mts_error_set(err, MTS_ERR_RANGE,
                                              "%s: line %llu: face %u: vertex index %lld out of "
                                              "range (%u vertices)",
                                              name, (unsigned long long)P->t.line, i,
                                              (long long)idx, nv);
                        else
                            r = mts_error_set(err, MTS_ERR_RANGE,
                                              "%s: face %u: vertex index %lld out of range "
                                              "(%u vertices)",
                                              name, i, (long long)idx, nv);
                        goto done;
                    }
                    if ((r = mts__fan_add(raw, &poly, (uint32_t)idx, err)) != MTS_OK)
                        goto done;
                }
            }
            if (status != 0) {
                r = ply_value_error(P, el, i, status, name, err);
                goto done;
            }
            if (el->kind == ELEM_VERTEX) {
                memcpy(raw->positions + (size_t)i * 3, v + ROLE_X, 3 * sizeof *v);
                if (with_normals)
                    memcpy(raw->normals + (size_t)i * 3, v + ROLE_NX, 3 * sizeof *v);
                if (with_colors) {
                    /* each channel by its own type's range (mesh.c clamps) */
                    double rgb[3];
                    for (int c = 0; c < 3; c++)
                        rgb[c] = v[ROLE_RED + c] / color_scale[c];
                    mts__raw_set_color(raw, i, rgb,
                                       has_rgba[3] ? fmax(0.0, v[ROLE_ALPHA] / color_scale[3])
                                                   : -1.0,
                                       1.0);
                }
            } else if (el->kind == ELEM_FACE) {
                if ((r = mts__fan_end(raw, &poly, err)) != MTS_OK)
                    goto done;
            }
        }
        if (el->kind == ELEM_VERTEX)
            raw->vertex_count = nv;
    }
    st->file_vertices = nv;
done:
    free(P);
    return r;
}
