/* Private to the mesh file parsers (mesh_read.c and mesh_read_off.c, _obj,
 * _ply, _stl): what they share. The raw mesh's storage and the polygon fan
 * every format triangulates through, the bounded text cursor and its number
 * scanners, and the text-kind checks that name UTF-16 or binary data for what
 * it is. mesh_read.c also holds the dispatch (sniffing a format and checking
 * a file's head), which calls the few format helpers declared at the end.
 * Not the loader's interface (mesh_read.h): mts__ names.
 *
 * The helpers called a token or a corner at a time are static inline here so
 * that every parser inlines them, as it did when the parsers were one file. */
#ifndef MTS_MESH_READ_INTERNAL_H
#define MTS_MESH_READ_INTERNAL_H

#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "error.h"
#include "mesh_read.h"

/* ------------------------------------------------------------------------ */
/* Storage (mesh_read.c)                                                    */

/* Makes room for `need` vertices (and normals when with_normals). */
mts_result mts__raw_reserve_vertices(mts__mesh_raw *raw, uint64_t need, int with_normals,
                                     mts_error *err);
/* Starts the colour array: every vertex so far without a colour (NaN). */
mts_result mts__raw_enable_colors(mts__mesh_raw *raw, mts_error *err);
/* Vertex i's colour from 3 values in 0..scale, and its alpha (a < 0: none). */
void mts__raw_set_color(mts__mesh_raw *raw, uint32_t i, const double rgb[3], double alpha,
                        double scale);
mts_result mts__raw_reserve_triangles(mts__mesh_raw *raw, uint64_t need, mts_error *err);

/* A polygon being read, fan-triangulated corner by corner as (c0, c[k-1], c[k])
 * so that no corner list is ever stored and the winding is kept. */
typedef struct mts__fan {
    uint32_t first, prev;
    uint32_t corners;
} mts__fan;

static inline mts_result mts__fan_add(mts__mesh_raw *raw, mts__fan *f, uint32_t v, mts_error *err)
{
    if (f->corners >= 2) {
        if (raw->triangle_count == raw->triangle_capacity) {
            mts_result r = mts__raw_reserve_triangles(raw, (uint64_t)raw->triangle_count + 1, err);
            if (r != MTS_OK)
                return r;
        }
        uint32_t *t = raw->triangles + (size_t)raw->triangle_count * 3;
        t[0] = f->first;
        t[1] = f->prev;
        t[2] = v;
        raw->triangle_count++;
    } else if (f->corners == 0) {
        f->first = v;
    }
    f->prev = v;
    f->corners++;
    return MTS_OK;
}

static inline mts_result mts__fan_end(mts__mesh_raw *raw, mts__fan *f, mts_error *err)
{
    mts_mesh_stats *st = raw->stats;
    if (st->file_faces >= MTS__MESH_MAX_COUNT)
        return mts_error_set(err, MTS_ERR_LIMIT, "%s: more than %u faces", raw->name,
                             MTS__MESH_MAX_COUNT);
    st->file_faces++;
    /* a face of 0..2 corners has no area: it is dropped like any degenerate
     * triangle, and counted with them so the report adds up */
    if (f->corners < 3)
        st->degenerate_faces++;
    else if (f->corners > 3)
        st->polygons_triangulated++;
    f->corners = 0;
    return MTS_OK;
}

/* ------------------------------------------------------------------------ */
/* Numbers                                                                  */

static inline uint32_t mts__le32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static inline uint32_t mts__be32(const unsigned char *p)
{
    return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | (uint32_t)p[3];
}

/* An integer with an optional sign; saturates far outside any valid index so
 * that range checks, not overflow, reject absurd values. */
static inline int mts__scan_int(const char **ps, const char *end, int64_t *out)
{
    const char *s = *ps;
    int neg = 0;
    if (s < end && (*s == '+' || *s == '-')) {
        neg = *s == '-';
        s++;
    }
    if (s >= end || (unsigned)(*s - '0') >= 10)
        return -1;
    int64_t v = 0;
    while (s < end && (unsigned)(*s - '0') < 10) {
        if (v < INT64_C(1) << 40)
            v = v * 10 + (*s - '0');
        s++;
    }
    *out = neg ? -v : v;
    *ps = s;
    return 0;
}

/* ------------------------------------------------------------------------ */
/* Text                                                                     */

typedef struct mts__text {
    const char *p, *end;
    uint64_t line; /* 1-based line of p */
    int comments;  /* '#' starts a comment running to the end of the line */
    const char *name;
} mts__text;

static inline int mts__is_blank(char c)
{
    return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

static inline int mts__is_space(char c) { return mts__is_blank(c) || c == '\n'; }

/* Skips blanks (and a comment) but stays on this line. */
static inline void mts__text_blank(mts__text *t)
{
    while (t->p < t->end && mts__is_blank(*t->p))
        t->p++;
    if (t->comments && t->p < t->end && *t->p == '#')
        while (t->p < t->end && *t->p != '\n')
            t->p++;
}

/* Skips blanks, comments and line ends: to the next token or the end. */
static inline void mts__text_space(mts__text *t)
{
    for (;;) {
        mts__text_blank(t);
        if (t->p < t->end && *t->p == '\n') {
            t->p++;
            t->line++;
            continue;
        }
        return;
    }
}

static inline void mts__text_next_line(mts__text *t)
{
    const char *nl = t->p < t->end ? memchr(t->p, '\n', (size_t)(t->end - t->p)) : NULL;
    if (nl) {
        t->p = nl + 1;
        t->line++;
    } else {
        t->p = t->end;
    }
}

/* The length of a UTF-8 byte order mark at the start, which some Windows
 * tools write: left in, it would hide an OBJ's first keyword and shift
 * every index after it. */
static inline size_t mts__bom_length(const char *data, size_t size)
{
    return size >= 3 && memcmp(data, "\xEF\xBB\xBF", 3) == 0 ? 3 : 0;
}

static inline int mts__text_eof(const mts__text *t) { return t->p >= t->end; }
static inline int mts__text_eol(const mts__text *t) { return t->p >= t->end || *t->p == '\n'; }

static inline int mts__token_ends(const mts__text *t, const char *s)
{
    return s >= t->end || mts__is_space(*s) || (t->comments && *s == '#');
}

/* Up to 40 characters of the token at t->p: enough to tell a number cut by
 * the end of the file from a bad one. */
int mts__token_len(const mts__text *t);
/* "bad number", or "truncated" when the token runs into the end. */
mts_result mts__text_bad_number(const mts__text *t, mts_error *err);

/* A float token at t->p (the caller has skipped blanks and checked there is
 * one). */
static inline mts_result mts__text_float(mts__text *t, float *out, mts_error *err)
{
    const char *s = t->p;
    int r = mts__mesh_scan_float(&s, t->end, out);
    if (r == -2)
        return mts_error_set(err, MTS_ERR_FORMAT, "%s: line %llu: a number is out of range",
                             t->name, (unsigned long long)t->line);
    if (r != 0 || !mts__token_ends(t, s))
        return mts__text_bad_number(t, err);
    t->p = s;
    return MTS_OK;
}

static inline mts_result mts__text_int(mts__text *t, int64_t *out, mts_error *err)
{
    const char *s = t->p;
    if (mts__scan_int(&s, t->end, out) != 0 || !mts__token_ends(t, s))
        return mts__text_bad_number(t, err);
    t->p = s;
    return MTS_OK;
}

/* The next word (a run of non-space characters) on this line; length 0 at the
 * end of a line. */
static inline size_t mts__text_word(mts__text *t, const char **word)
{
    mts__text_blank(t);
    const char *s = t->p;
    while (t->p < t->end && !mts__is_space(*t->p))
        t->p++;
    *word = s;
    return (size_t)(t->p - s);
}

static inline int mts__word_is(const char *w, size_t n, const char *lit)
{
    return strlen(lit) == n && memcmp(w, lit, n) == 0;
}

/* Refuses data that should be text and is not (UTF-16, UTF-32, binary),
 * saying what it is; MTS_OK for plain text. */
mts_result mts__text_refuse(const char *name, const char *data, size_t size,
                            const char *article, const char *ascii, const char *tail,
                            mts_error *err);
/* A vertex colour value at t->p: 1 read, 0 no number (no colour), -1 a
 * non-finite value (err set). */
int mts__text_color_value(mts__text *t, uint32_t i, float *out, mts_error *err);

/* ------------------------------------------------------------------------ */
/* What the dispatch asks of each format                                    */

/* What the header keyword [ST][C][N][4][n]OFF says is in each vertex. */
typedef struct mts__off_flags {
    int texcoords, colors, normals, four, ndim;
} mts__off_flags;

/* The length of the OFF keyword at the start of w (0: none) and its flags. */
size_t mts__off_keyword(const char *w, size_t n, mts__off_flags *fl);
/* The first word of an OFF file checked: *k is the keyword's length. */
mts_result mts__off_check_keyword(const char *name, const char *data, size_t size,
                                  const char *w, size_t wn, mts__off_flags *fl, size_t *k,
                                  mts_error *err);
/* An OBJ file is text: refuses UTF-16 and binary data. */
mts_result mts__obj_check_text(const char *name, const char *data, size_t size,
                               mts_error *err);
/* Refuses a file without the 'ply' magic, naming what it is instead. */
mts_result mts__ply_no_magic(const char *name, const char *data, size_t size,
                             mts_error *err);
/* A binary STL's facet count, checked against the limit and the file size. */
mts_result mts__stl_binary_count(const char *name, const unsigned char *head,
                                 size_t head_size, uint64_t file_size, uint32_t *count,
                                 mts_error *err);

#endif
