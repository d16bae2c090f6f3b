/* The mesh file parsers: OFF (ASCII, binary), OBJ, PLY (ASCII, binary LE/BE)
 * and STL (ASCII, binary). Each works on the whole file in memory, bounded by
 * an end pointer (no NUL terminator needed, so a downloaded buffer is parsed
 * in place), and trusts no count it reads: allocations grow with what was
 * actually parsed or are capped by what the remaining bytes could hold, every
 * index is checked against the vertex count before it is stored, and every
 * binary read is bounds-checked. Messages name the file, the line or the
 * item and what was expected, never the file's own text: a file may be
 * anything (a secret a link points to, bytes a terminal acts on), and
 * messages end up in logs. */
#include "mesh_read.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------------------ */
/* Storage                                                                  */

void mts__mesh_raw_free(mts__mesh_raw *raw)
{
    free(raw->positions);
    free(raw->normals);
    free(raw->colors);
    free(raw->triangles);
    raw->positions = NULL;
    raw->normals = NULL;
    raw->colors = NULL;
    raw->triangles = NULL;
    raw->vertex_count = raw->vertex_capacity = 0;
    raw->triangle_count = raw->triangle_capacity = 0;
}

/* The next capacity for `need` items: doubling from `current` (or 256),
 * capped at the loader's limit (callers have checked need against it). */
static uint64_t grown_capacity(uint32_t current, uint64_t need)
{
    uint64_t cap = current ? (uint64_t)current * 2 : 256;
    while (cap < need)
        cap *= 2;
    return cap > MTS__MESH_MAX_COUNT ? MTS__MESH_MAX_COUNT : cap;
}

/* Makes room for `need` vertices (positions, and normals when with_normals;
 * new normals start at zero because OBJ sums into them). Doubling keeps the
 * cost linear; callers only ask for what they have parsed or what the bytes
 * left could hold, so a lying header cannot make this allocate. */
static mts_result raw_reserve_vertices(mts__mesh_raw *raw, uint64_t need, int with_normals,
                                       mts_error *err)
{
    if (need <= raw->vertex_capacity)
        return MTS_OK;
    if (need > MTS__MESH_MAX_COUNT)
        return mts_error_set(err, MTS_ERR_LIMIT, "%s: more than %u vertices", raw->name,
                             MTS__MESH_MAX_COUNT);
    uint64_t cap = grown_capacity(raw->vertex_capacity, need);
    float *p = realloc(raw->positions, (size_t)cap * 3 * sizeof *p);
    if (!p)
        goto nomem;
    raw->positions = p;
    if (with_normals) {
        float *n = realloc(raw->normals, (size_t)cap * 3 * sizeof *n);
        if (!n)
            goto nomem;
        memset(n + (size_t)raw->vertex_capacity * 3, 0,
               (size_t)(cap - raw->vertex_capacity) * 3 * sizeof *n);
        raw->normals = n;
    }
    if (raw->colors) {
        float *c = realloc(raw->colors, (size_t)cap * 3 * sizeof *c);
        if (!c)
            goto nomem;
        for (size_t i = (size_t)raw->vertex_capacity * 3; i < (size_t)cap * 3; i++)
            c[i] = NAN;
        raw->colors = c;
    }
    raw->vertex_capacity = (uint32_t)cap;
    return MTS_OK;
nomem:
    return mts_error_set(err, MTS_ERR_NOMEM, "%s: out of memory for %llu vertices", raw->name,
                         (unsigned long long)cap);
}

/* Starts the colour array (every vertex so far without a colour, NaN);
 * raw_reserve_vertices grows it from then on. */
static mts_result raw_enable_colors(mts__mesh_raw *raw, mts_error *err)
{
    if (raw->colors)
        return MTS_OK;
    size_t cap = raw->vertex_capacity ? raw->vertex_capacity : 1;
    raw->colors = malloc(cap * 3 * sizeof *raw->colors);
    if (!raw->colors)
        return mts_error_set(err, MTS_ERR_NOMEM, "%s: out of memory for colours", raw->name);
    for (size_t i = 0; i < cap * 3; i++)
        raw->colors[i] = NAN;
    return MTS_OK;
}

/* Vertex i's colour from 3 values in 0..scale (1 for floats, 255 for
 * bytes), and its alpha when there is one (a < 0: none). */
static void raw_set_color(mts__mesh_raw *raw, uint32_t i, const double rgb[3], double alpha,
                          double scale)
{
    float *c = raw->colors + (size_t)i * 3;
    for (int k = 0; k < 3; k++)
        c[k] = (float)(rgb[k] / scale);
    if (alpha >= 0) {
        mts_mesh_stats *st = raw->stats;
        st->colors_alpha = 1;
        st->colors_translucent += alpha < scale && st->colors_translucent < UINT32_MAX;
    }
}

static mts_result raw_reserve_triangles(mts__mesh_raw *raw, uint64_t need, mts_error *err)
{
    if (need <= raw->triangle_capacity)
        return MTS_OK;
    if (need > MTS__MESH_MAX_COUNT)
        return mts_error_set(err, MTS_ERR_LIMIT, "%s: more than %u triangles", raw->name,
                             MTS__MESH_MAX_COUNT);
    uint64_t cap = grown_capacity(raw->triangle_capacity, need);
    uint32_t *t = realloc(raw->triangles, (size_t)cap * 3 * sizeof *t);
    if (!t)
        return mts_error_set(err, MTS_ERR_NOMEM, "%s: out of memory for %llu triangles",
                             raw->name, (unsigned long long)cap);
    raw->triangles = t;
    raw->triangle_capacity = (uint32_t)cap;
    return MTS_OK;
}

/* A polygon being read, fan-triangulated corner by corner as (c0, c[k-1], c[k])
 * so that no corner list is ever stored and the winding is kept. */
typedef struct fan {
    uint32_t first, prev;
    uint32_t corners;
} fan;

static inline mts_result fan_add(mts__mesh_raw *raw, fan *f, uint32_t v, mts_error *err)
{
    if (f->corners >= 2) {
        if (raw->triangle_count == raw->triangle_capacity) {
            mts_result r = raw_reserve_triangles(raw, (uint64_t)raw->triangle_count + 1, err);
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

static inline mts_result fan_end(mts__mesh_raw *raw, fan *f, mts_error *err)
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

static inline uint32_t le32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static inline uint32_t be32(const unsigned char *p)
{
    return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | (uint32_t)p[3];
}

static const double pow10_exact[23] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,
                                       1e8,  1e9,  1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
                                       1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

/* Fast path: for up to 19 significant digits and a small exponent, m * 10^e
 * in double is one correctly rounded operation on exact operands. Rounding
 * that double to float again gives the correctly rounded float unless the
 * double landed exactly on a midpoint between two floats (the only case where
 * double rounding can differ), so those, and everything else, go to strtof
 * on a NUL-terminated copy of the token. */
int mts__mesh_scan_float(const char **ps, const char *end, float *out)
{
    const char *s = *ps;
    const char *start = s;
    int neg = 0;
    if (s < end && (*s == '+' || *s == '-')) {
        neg = *s == '-';
        s++;
    }
    uint64_t m = 0;
    int sig = 0, digits = 0, inexact = 0;
    int64_t e10 = 0;
    while (s < end && (unsigned)(*s - '0') < 10) {
        unsigned d = (unsigned)(*s - '0');
        if (sig < 19) {
            m = m * 10 + d;
            sig += m != 0;
        } else {
            e10++;
            inexact |= d != 0;
        }
        digits++;
        s++;
    }
    if (s < end && *s == '.') {
        s++;
        while (s < end && (unsigned)(*s - '0') < 10) {
            unsigned d = (unsigned)(*s - '0');
            if (sig < 19) {
                m = m * 10 + d;
                sig += m != 0;
                e10--;
            } else {
                inexact |= d != 0;
            }
            digits++;
            s++;
        }
    }
    if (digits == 0)
        return -1;
    if (s < end && (*s == 'e' || *s == 'E')) {
        const char *q = s + 1;
        int eneg = 0;
        if (q < end && (*q == '+' || *q == '-')) {
            eneg = *q == '-';
            q++;
        }
        if (q >= end || (unsigned)(*q - '0') >= 10)
            return -1; /* "1e" or "1e+": not a number strtof would take whole */
        int64_t ev = 0;
        while (q < end && (unsigned)(*q - '0') < 10) {
            if (ev < 1000000) /* saturate: far beyond float's range either way */
                ev = ev * 10 + (*q - '0');
            q++;
        }
        e10 += eneg ? -ev : ev;
        s = q;
    }
    if (m == 0) {
        *out = neg ? -0.0f : 0.0f;
        *ps = s;
        return 0;
    }
    if (!inexact && m <= (UINT64_C(1) << 53) && e10 >= -22 && e10 <= 22) {
        double d = (double)m;
        d = e10 < 0 ? d / pow10_exact[-e10] : d * pow10_exact[e10];
        if (d >= FLT_MIN && d <= FLT_MAX) {
            uint64_t bits;
            memcpy(&bits, &d, sizeof bits);
            if ((bits & UINT64_C(0x1fffffff)) != UINT64_C(0x10000000)) {
                float f = (float)d;
                *out = neg ? -f : f;
                *ps = s;
                return 0;
            }
        }
    }
    size_t len = (size_t)(s - start);
    char small[64];
    char *buf = len < sizeof small ? small : malloc(len + 1);
    if (!buf)
        return -1;
    memcpy(buf, start, len);
    buf[len] = '\0';
    char *stop;
    float f = strtof(buf, &stop);
    int ok = stop == buf + len;
    if (buf != small)
        free(buf);
    if (!ok)
        return -1; /* a locale with another decimal point; never in the C locale */
    if (isinf(f))
        return -2;
    *out = f;
    *ps = s;
    return 0;
}

/* An integer with an optional sign; saturates far outside any valid index so
 * that range checks, not overflow, reject absurd values. */
static int scan_int(const char **ps, const char *end, int64_t *out)
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

typedef struct text {
    const char *p, *end;
    uint64_t line; /* 1-based line of p */
    int comments;  /* '#' starts a comment running to the end of the line */
    const char *name;
} text;

static inline int is_blank(char c)
{
    return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

static inline int is_space(char c) { return is_blank(c) || c == '\n'; }

/* Skips blanks (and a comment) but stays on this line. */
static inline void text_blank(text *t)
{
    while (t->p < t->end && is_blank(*t->p))
        t->p++;
    if (t->comments && t->p < t->end && *t->p == '#')
        while (t->p < t->end && *t->p != '\n')
            t->p++;
}

/* Skips blanks, comments and line ends: to the next token or the end. */
static inline void text_space(text *t)
{
    for (;;) {
        text_blank(t);
        if (t->p < t->end && *t->p == '\n') {
            t->p++;
            t->line++;
            continue;
        }
        return;
    }
}

static inline void text_next_line(text *t)
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
static size_t bom_length(const char *data, size_t size)
{
    return size >= 3 && memcmp(data, "\xEF\xBB\xBF", 3) == 0 ? 3 : 0;
}

/* What the bytes of a file that should be text are instead. Windows
 * editors save "Unicode" text as UTF-16 (box_UTF16BE.obj in assimp's test
 * models), whose NUL high bytes a text reader would otherwise take for
 * binary junk, or skip as unknown lines and then find no faces: the user
 * is told what the file is, so that saving it as UTF-8 is the obvious fix. */
enum text_kind { TEXT_PLAIN, TEXT_UTF16LE, TEXT_UTF16BE, TEXT_UTF32LE, TEXT_UTF32BE, TEXT_BINARY };

static int text_kind_of(const char *data, size_t size, size_t *nul_at)
{
    const unsigned char *b = (const unsigned char *)data;
    *nul_at = 0;
    /* byte order marks; UTF-32's little-endian one starts with UTF-16's */
    if (size >= 4 && memcmp(b, "\xFF\xFE\0\0", 4) == 0)
        return TEXT_UTF32LE;
    if (size >= 4 && memcmp(b, "\0\0\xFE\xFF", 4) == 0)
        return TEXT_UTF32BE;
    if (size >= 2 && b[0] == 0xFF && b[1] == 0xFE)
        return TEXT_UTF16LE;
    if (size >= 2 && b[0] == 0xFE && b[1] == 0xFF)
        return TEXT_UTF16BE;
    /* no mark: mostly-ASCII UTF-16 has a NUL in (nearly) every other byte
     * and none in between, since no character is U+0000; binary data and
     * zero padding have NULs at both parities */
    size_t pairs = (size < 512 ? size : 512) / 2, nul[2] = {0, 0};
    for (size_t i = 0; i < pairs * 2; i++)
        nul[i & 1] += b[i] == 0;
    if (pairs >= 2 && nul[1] == 0 && nul[0] * 4 >= pairs * 3)
        return TEXT_UTF16BE;
    if (pairs >= 2 && nul[0] == 0 && nul[1] * 4 >= pairs * 3)
        return TEXT_UTF16LE;
    const char *nul_byte = memchr(data, 0, size);
    if (nul_byte) {
        *nul_at = (size_t)(nul_byte - data);
        return TEXT_BINARY;
    }
    return TEXT_PLAIN;
}

static const char *text_kind_name(int kind)
{
    switch (kind) {
    case TEXT_UTF16LE: return "UTF-16 (little-endian)";
    case TEXT_UTF16BE: return "UTF-16 (big-endian)";
    case TEXT_UTF32LE: return "UTF-32 (little-endian)";
    case TEXT_UTF32BE: return "UTF-32 (big-endian)";
    default: return NULL;
    }
}

const char *mts__mesh_wide_text(const char *data, size_t size)
{
    size_t nul_at;
    return text_kind_name(text_kind_of(data, size, &nul_at));
}

/* Refuses data that should be text and is not, saying what it is: `article`
 * names the format ("an OBJ"), `ascii` what the reader takes ("ASCII OBJ"),
 * `tail` what else was missing ("" or " (and no 'ply' magic)"). MTS_OK when
 * the data is plain text. */
static mts_result text_refuse(const char *name, const char *data, size_t size,
                              const char *article, const char *ascii, const char *tail,
                              mts_error *err)
{
    size_t nul_at;
    int kind = text_kind_of(data, size, &nul_at);
    if (kind == TEXT_PLAIN)
        return MTS_OK;
    if (kind == TEXT_BINARY)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "%s: not %s file: the file is binary (byte %zu is a NUL byte), not "
                             "%s%s",
                             name, article, nul_at, ascii, tail);
    return mts_error_set(err, MTS_ERR_FORMAT,
                         "%s: the file is %s, not %s: save it as UTF-8 or ASCII", name,
                         text_kind_name(kind), ascii);
}

static inline int text_eof(const text *t) { return t->p >= t->end; }
static inline int text_eol(const text *t) { return t->p >= t->end || *t->p == '\n'; }

static inline int token_ends(const text *t, const char *s)
{
    return s >= t->end || is_space(*s) || (t->comments && *s == '#');
}

static int token_len(const text *t)
{
    const char *s = t->p;
    while (s < t->end && !is_space(*s) && s - t->p < 40)
        s++;
    return (int)(s - t->p);
}

static mts_result text_bad_number(const text *t, mts_error *err)
{
    if (t->p + token_len(t) >= t->end) /* cut inside the number: the file ends early */
        return mts_error_set(err, MTS_ERR_FORMAT, "%s: truncated at line %llu: the file ends "
                             "inside a number", t->name, (unsigned long long)t->line);
    return mts_error_set(err, MTS_ERR_FORMAT, "%s: line %llu: bad number", t->name,
                         (unsigned long long)t->line);
}

/* A float token at t->p (the caller has skipped blanks and checked there is
 * one). */
static mts_result text_float(text *t, float *out, mts_error *err)
{
    const char *s = t->p;
    int r = mts__mesh_scan_float(&s, t->end, out);
    if (r == -2)
        return mts_error_set(err, MTS_ERR_FORMAT, "%s: line %llu: a number is out of range",
                             t->name, (unsigned long long)t->line);
    if (r != 0 || !token_ends(t, s))
        return text_bad_number(t, err);
    t->p = s;
    return MTS_OK;
}

static mts_result text_int(text *t, int64_t *out, mts_error *err)
{
    const char *s = t->p;
    if (scan_int(&s, t->end, out) != 0 || !token_ends(t, s))
        return text_bad_number(t, err);
    t->p = s;
    return MTS_OK;
}

/* The next word (a run of non-space characters) on this line; length 0 at the
 * end of a line. */
static size_t text_word(text *t, const char **word)
{
    text_blank(t);
    const char *s = t->p;
    while (t->p < t->end && !is_space(*t->p))
        t->p++;
    *word = s;
    return (size_t)(t->p - s);
}

static inline int word_is(const char *w, size_t n, const char *lit)
{
    return strlen(lit) == n && memcmp(w, lit, n) == 0;
}

/* ------------------------------------------------------------------------ */
/* OFF                                                                      */

/* What the header keyword [ST][C][N][4][n]OFF says is in each vertex. */
typedef struct off_flags {
    int texcoords, colors, normals, four, ndim;
} off_flags;

/* Reads the Geomview header keyword into *fl and returns the length consumed
 * through "OFF", or 0 when the word is not an OFF keyword. */
static size_t off_keyword(const char *w, size_t n, off_flags *fl)
{
    size_t i = 0;
    *fl = (off_flags){0, 0, 0, 0, 0};
    if (n - i >= 2 && w[i] == 'S' && w[i + 1] == 'T') {
        fl->texcoords = 1;
        i += 2;
    }
    if (i < n && w[i] == 'C') {
        fl->colors = 1;
        i++;
    }
    if (i < n && w[i] == 'N') {
        fl->normals = 1;
        i++;
    }
    if (i < n && w[i] == '4') {
        fl->four = 1;
        i++;
    }
    if (i < n && w[i] == 'n') {
        fl->ndim = 1;
        i++;
    }
    if (n - i < 3 || memcmp(w + i, "OFF", 3) != 0)
        return 0;
    return i + 3;
}

/* The first word of an OFF file: a keyword, or (in some collections, such
 * as ModelNet) a keyword with the vertex count glued to it, "OFF1234 5678
 * 0"; anything else after OFF is not OFF. *k is the keyword's length. */
static mts_result off_check_keyword(const char *name, const char *data, size_t size,
                                    const char *w, size_t wn, off_flags *fl, size_t *k,
                                    mts_error *err)
{
    *k = off_keyword(w, wn, fl);
    if (*k == 0 || (*k < wn && (unsigned)(w[*k] - '0') >= 10)) {
        /* binary OFF starts with the keyword line too: without it, UTF-16
         * or binary data is named as what it is */
        mts_result r = text_refuse(name, data, size, "an OFF", "ASCII OFF",
                                   " (ASCII and binary OFF start with the OFF keyword)", err);
        if (r != MTS_OK)
            return r;
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "%s: not an OFF file (the first word is not OFF or a variant of it)",
                             name);
    }
    return MTS_OK;
}

static mts_result off_truncated(const text *t, const char *what, uint32_t expected,
                                uint32_t got, mts_error *err)
{
    return mts_error_set(err, MTS_ERR_FORMAT, "%s: truncated: expected %u %s, file ends after %u",
                         t->name, expected, what, got);
}

/* A header count: a non-negative integer below the 2^31 limit. */
static mts_result off_count(text *t, const char *what, uint32_t *out, mts_error *err)
{
    text_space(t);
    if (text_eof(t))
        return mts_error_set(err, MTS_ERR_FORMAT, "%s: truncated: the OFF header has no %s count",
                             t->name, what);
    int64_t v;
    mts_result r = text_int(t, &v, err);
    if (r != MTS_OK)
        return r;
    if (v < 0)
        return mts_error_set(err, MTS_ERR_FORMAT, "%s: line %llu: negative %s count %lld",
                             t->name, (unsigned long long)t->line, what, (long long)v);
    if (v > (int64_t)MTS__MESH_MAX_COUNT)
        return mts_error_set(err, MTS_ERR_LIMIT,
                             "%s: line %llu: a %s count of %lld is over the limit of %u",
                             t->name, (unsigned long long)t->line, what, (long long)v,
                             MTS__MESH_MAX_COUNT);
    *out = (uint32_t)v;
    return MTS_OK;
}

/* Binary OFF ("[ST][C][N]OFF BINARY" and a newline, then 32-bit words) comes
 * in two layouts, and the header does not say which:
 *  - Geomview's spec (also CGAL): big-endian ints and floats; every face ends
 *    with a colour count (0..4) and that many floats; a C vertex has 4 colour
 *    floats.
 *  - OpenMesh's writer (OpenMesh-commandlineSubdivider and the like): the
 *    writing machine's byte order, little endian in practice, and no colour
 *    count after a face; with C, vertices may carry 3 or 4 colour words (ints
 *    or floats) and faces 3 or 4 more, either possibly absent.
 * Both are: #vertices #faces #edges, per vertex x y z [normal] [colour] [s t],
 * per face n i[0] .. i[n-1] [colour]. Each candidate layout is first walked
 * through (counts and indices checked, nothing stored), and the first that
 * reads as a valid file ending exactly at the end is parsed. When none does (a
 * truncated or corrupt file), the byte order whose counts are the more
 * plausible is parsed in its usual layout so that the error says where the
 * file breaks. */
typedef struct offb_layout {
    uint8_t big;     /* byte order */
    uint8_t vwords;  /* 32-bit words per vertex */
    uint8_t counted; /* each face ends with a colour count and that many words */
    uint8_t fwords;  /* else: colour words after each face's indices */
} offb_layout;

static inline uint32_t offb_u32(const unsigned char *p, int big)
{
    return big ? be32(p) : le32(p);
}

/* Whether layout L reads as a valid file: every face has corners (neither
 * Geomview nor OpenMesh reads a face without any, and without this a
 * Geomview file cut after half its faces would read as the other layout
 * with empty faces between), every index is in range, and the faces end
 * exactly at the end (or only white space follows). Then *tris is the
 * triangle count. Each face takes at least 4 bytes, so this is linear in the
 * file size whatever the counts say. */
static int offb_walk(const unsigned char *p, const unsigned char *end, uint32_t nv, uint32_t nf,
                     offb_layout L, uint64_t *tris)
{
    uint64_t vbytes = (uint64_t)nv * L.vwords * 4;
    if (vbytes > (uint64_t)(end - p))
        return 0;
    p += vbytes;
    uint64_t t = 0;
    for (uint32_t f = 0; f < nf; f++) {
        if (end - p < 4)
            return 0;
        uint32_t n = offb_u32(p, L.big); /* a negative count reads as huge */
        p += 4;
        if (n == 0 || n > (size_t)(end - p) / 4)
            return 0;
        for (uint32_t c = 0; c < n; c++, p += 4)
            if (offb_u32(p, L.big) >= nv) /* and negative ones */
                return 0;
        t += n >= 3 ? n - 2 : 0;
        uint32_t nc = L.fwords;
        if (L.counted) {
            if (end - p < 4)
                return 0;
            nc = offb_u32(p, L.big);
            p += 4;
            if (nc > 4)
                return 0;
        }
        if ((size_t)(end - p) < (size_t)nc * 4)
            return 0;
        p += (size_t)nc * 4;
    }
    while (p < end && is_space((char)*p))
        p++;
    *tris = t;
    return p == end;
}

/* How many of the first words after the counts read, in byte order big, as
 * zero or a float of moderate magnitude, as coordinates do; the other order
 * makes most of them tiny, huge or not numbers. */
static int offb_sane_floats(const unsigned char *p, const unsigned char *end, int big)
{
    int sane = 0;
    for (int i = 0; i < 48 && end - p >= 4; i++, p += 4) {
        uint32_t u = offb_u32(p, big);
        uint32_t e = u >> 23 & 0xff;
        sane += (u & 0x7fffffffu) == 0 || (e >= 127 - 60 && e <= 127 + 60);
    }
    return sane;
}

static mts_result offb_truncated(const char *name, const char *what, uint32_t expected,
                                 uint32_t got, mts_error *err)
{
    return mts_error_set(err, MTS_ERR_FORMAT, "%s: truncated: expected %u %s, file ends after %u",
                         name, expected, what, got);
}

/* The binary part of an OFF file: p is the byte after the header line. */
static mts_result off_binary(mts__mesh_raw *raw, const off_flags *fl, const unsigned char *p,
                             const unsigned char *end, mts_error *err)
{
    const char *name = raw->name;
    mts_mesh_stats *st = raw->stats;
    const size_t size = (size_t)(end - p);
    if (size < 12)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "%s: truncated: the binary OFF counts take 12 bytes, the file has "
                             "%zu after the header",
                             name, size);

    /* The counts in both byte orders, ranked: fits the file > within the
     * limit > over it; then by how coordinate-like the data after them
     * reads, then by the smaller claim. */
    const unsigned base = 3 + (fl->normals ? 3 : 0) + (fl->texcoords ? 2 : 0);
    uint32_t nvo[2], nfo[2];
    uint64_t need[2];
    int rank[2], sane[2];
    for (int b = 0; b < 2; b++) {
        nvo[b] = offb_u32(p, b);
        nfo[b] = offb_u32(p + 4, b);
        /* the least any layout takes: the words every vertex has, 4 bytes a face */
        need[b] = 12 + (uint64_t)nvo[b] * base * 4 + (uint64_t)nfo[b] * 4;
        int over = nvo[b] > MTS__MESH_MAX_COUNT || nfo[b] > MTS__MESH_MAX_COUNT;
        rank[b] = over ? 0 : need[b] <= size ? 2 : 1;
        sane[b] = offb_sane_floats(p + 12, end, b);
    }
    const int first = rank[0] != rank[1] ? rank[1] > rank[0]
                      : sane[0] != sane[1] ? sane[1] > sane[0]
                                           : need[1] < need[0];

    /* The candidate layouts of each byte order, most likely first. */
    offb_layout cand[2][12];
    int ncand[2] = {0, 0};
    for (int b = 0; b < 2; b++) {
        if (!fl->colors) {
            offb_layout geomview = {(uint8_t)b, (uint8_t)base, 1, 0};
            offb_layout openmesh = {(uint8_t)b, (uint8_t)base, 0, 0};
            cand[b][ncand[b]++] = b ? geomview : openmesh;
            cand[b][ncand[b]++] = b ? openmesh : geomview;
            continue;
        }
        static const uint8_t vcol[2][3] = {{3, 4, 0}, {4, 3, 0}};
        static const int8_t fcol[2][4] = {{0, 3, 4, -1}, {-1, 0, 3, 4}}; /* -1: counted */
        for (int v = 0; v < 3; v++)
            for (int f = 0; f < 4; f++)
                cand[b][ncand[b]++] = (offb_layout){(uint8_t)b, (uint8_t)(base + vcol[b][v]),
                                                    fcol[b][f] < 0,
                                                    (uint8_t)(fcol[b][f] < 0 ? 0 : fcol[b][f])};
    }
    offb_layout L = cand[first][0];
    uint64_t tris = 0;
    int exact = 0;
    for (int k = 0; k < 2 && !exact; k++) {
        int b = k ? !first : first;
        if (rank[b] != 2)
            continue; /* cannot end at the end */
        for (int c = 0; c < ncand[b] && !exact; c++)
            if (offb_walk(p + 12, end, nvo[b], nfo[b], cand[b][c], &tris)) {
                L = cand[b][c];
                exact = 1;
            }
    }

    const int big = L.big;
    const uint32_t nv = nvo[big], nf = nfo[big];
    if (nv > MTS__MESH_MAX_COUNT)
        return mts_error_set(err, MTS_ERR_LIMIT, "%s: %u vertices is over the limit of %u", name,
                             nv, MTS__MESH_MAX_COUNT);
    if (nf > MTS__MESH_MAX_COUNT)
        return mts_error_set(err, MTS_ERR_LIMIT, "%s: %u faces is over the limit of %u", name, nf,
                             MTS__MESH_MAX_COUNT);
    p += 12;

    const size_t vstride = (size_t)L.vwords * 4;
    if ((uint64_t)nv * vstride > (uint64_t)(end - p))
        return offb_truncated(name, "vertices", nv, (uint32_t)((size_t)(end - p) / vstride), err);
    mts_result r = raw_reserve_vertices(raw, nv, fl->normals, err);
    if (r != MTS_OK)
        return r;
    const unsigned values = fl->normals ? 6 : 3;
    for (uint32_t i = 0; i < nv; i++, p += vstride) {
        uint32_t u[6];
        for (unsigned c = 0; c < values; c++) {
            u[c] = offb_u32(p + 4 * c, big);
            if ((u[c] & 0x7f800000u) == 0x7f800000u)
                return mts_error_set(err, MTS_ERR_FORMAT, "%s: vertex %u has a non-finite %s",
                                     name, i, c < 3 ? "coordinate" : "normal");
        }
        memcpy(raw->positions + (size_t)i * 3, u, 3 * sizeof *u);
        if (fl->normals)
            memcpy(raw->normals + (size_t)i * 3, u + 3, 3 * sizeof *u);
    }
    raw->vertex_count = nv;
    st->file_vertices = nv;

    /* the walk counted the triangles; otherwise reserve what the bytes left
     * could hold (16 per triangle) and grow from there */
    size_t left = (size_t)(end - p);
    uint64_t want = exact ? tris : (nf < left / 16 + 1 ? nf : left / 16 + 1);
    if ((r = raw_reserve_triangles(raw, want, err)) != MTS_OK)
        return r;

    for (uint32_t f = 0; f < nf; f++) {
        if (end - p < 4)
            return offb_truncated(name, "faces", nf, f, err);
        int32_t n = (int32_t)offb_u32(p, big);
        p += 4;
        if (n < 0)
            return mts_error_set(err, MTS_ERR_FORMAT, "%s: face %u has %d corners", name, f, n);
        size_t avail = (size_t)(end - p) / 4;
        if ((uint32_t)n > avail)
            return mts_error_set(err, MTS_ERR_FORMAT,
                                 "%s: truncated: expected %u faces, file ends after %u (face %u "
                                 "claims %d corners, the file holds %zu more)",
                                 name, nf, f, f, n, avail);
        fan poly = {0, 0, 0};
        for (int32_t c = 0; c < n; c++, p += 4) {
            int32_t idx = (int32_t)offb_u32(p, big);
            if (idx < 0 || (uint32_t)idx >= nv)
                return mts_error_set(err, MTS_ERR_RANGE,
                                     "%s: face %u: vertex index %d out of range (%u vertices)",
                                     name, f, idx, nv);
            if ((r = fan_add(raw, &poly, (uint32_t)idx, err)) != MTS_OK)
                return r;
        }
        uint32_t nc = L.fwords;
        if (L.counted) {
            if (end - p < 4)
                return offb_truncated(name, "faces", nf, f, err);
            int32_t c = (int32_t)offb_u32(p, big);
            p += 4;
            if (c < 0 || c > 4)
                return mts_error_set(err, MTS_ERR_FORMAT,
                                     "%s: face %u: colour count %d is not 0 to 4", name, f, c);
            nc = (uint32_t)c;
        }
        if ((size_t)(end - p) < (size_t)nc * 4)
            return offb_truncated(name, "faces", nf, f, err);
        p += (size_t)nc * 4;
        if ((r = fan_end(raw, &poly, err)) != MTS_OK)
            return r;
    }
    return MTS_OK;
}

/* A colour value at t->p (the caller has skipped blanks and checked there
 * is one) of vertex i. Returns 1 with *out set, 0 at a token that is no
 * number (the readers always ignored what follows a vertex, and still do:
 * that vertex has no colour), and -1 with err set for a value written as
 * a non-finite number ("nan", "inf", or one past a float's range), which
 * is refused naming the vertex. */
static int text_color_value(text *t, uint32_t i, float *out, mts_error *err)
{
    const char *s = t->p;
    int r = mts__mesh_scan_float(&s, t->end, out);
    if (r == 0 && token_ends(t, s)) {
        t->p = s;
        return 1;
    }
    s = t->p + (t->p < t->end && (*t->p == '+' || *t->p == '-'));
    int nonfinite = r == -2;
    if (t->end - s >= 3)
        nonfinite |= ((s[0] | 0x20) == 'n' && (s[1] | 0x20) == 'a' && (s[2] | 0x20) == 'n') ||
                     ((s[0] | 0x20) == 'i' && (s[1] | 0x20) == 'n' && (s[2] | 0x20) == 'f');
    if (!nonfinite)
        return 0;
    mts_error_set(err, MTS_ERR_FORMAT,
                  "%s: line %llu: vertex %u: a colour value is not a finite number", t->name,
                  (unsigned long long)t->line, i);
    return -1;
}

/* What the colours of an ASCII COFF file look like so far. Geomview's
 * spec says 4 floats in 0..1; MeshLab, OpenMesh and most converters write
 * integers in 0..255. The file decides, once all are read: integers of
 * which some pass 1 are 0..255, anything else 0..1. */
typedef struct off_color_scan {
    int over_one;      /* some value > 1 */
    int integral;      /* every value an integer */
    uint32_t below_1;  /* alphas below 1 (translucent if the scale is 1) */
    uint32_t below_255; /* and below 255 */
} off_color_scan;

/* The rest of vertex i's line after x y z [normal]: [r g b [a]] [s t].
 * A vertex with anything else there (nothing, or one colour-map index,
 * which needs a map OFF files do not carry) has no colour. */
static mts_result off_vertex_color(text *t, mts__mesh_raw *raw, const off_flags *fl, uint32_t i,
                                   off_color_scan *oc, mts_error *err)
{
    float x[8];
    unsigned n = 0;
    for (;;) {
        text_blank(t);
        if (text_eol(t) || n == 8)
            break;
        int got = text_color_value(t, i, &x[n], err);
        if (got < 0)
            return MTS_ERR_FORMAT;
        if (got == 0)
            return MTS_OK;
        n++;
    }
    unsigned nc = fl->texcoords && n >= 2 ? n - 2 : n;
    if (nc != 3 && nc != 4)
        return MTS_OK;
    mts_result r = raw_enable_colors(raw, err);
    if (r != MTS_OK)
        return r;
    for (unsigned c = 0; c < nc; c++) {
        oc->over_one |= x[c] > 1;
        oc->integral &= x[c] == floorf(x[c]);
    }
    memcpy(raw->colors + (size_t)i * 3, x, 3 * sizeof *x);
    if (nc == 4) {
        raw->stats->colors_alpha = 1;
        oc->below_1 += x[3] < 1;
        oc->below_255 += x[3] < 255;
    }
    return MTS_OK;
}

static void off_colors_scale(mts__mesh_raw *raw, const off_color_scan *oc)
{
    if (!raw->colors)
        return;
    const int bytes = oc->over_one && oc->integral;
    if (bytes)
        for (size_t k = 0; k < (size_t)raw->vertex_count * 3; k++)
            raw->colors[k] /= 255.0f; /* NaN stays NaN */
    raw->stats->colors_translucent = bytes ? oc->below_255 : oc->below_1;
}

mts_result mts__mesh_read_off(mts__mesh_raw *raw, const char *data, size_t size, mts_error *err)
{
    text t = {data + bom_length(data, size), data + size, 1, 1, raw->name};
    mts_mesh_stats *st = raw->stats;
    st->format = MTS_MESH_OFF;

    text_space(&t);
    const char *w;
    size_t wn = text_word(&t, &w);
    off_flags fl;
    size_t k;
    mts_result r0 = off_check_keyword(t.name, data, size, w, wn, &fl, &k, err);
    if (r0 != MTS_OK)
        return r0;
    const int normals = fl.normals;
    if (k < wn)
        t.p = w + k;
    if (fl.four)
        return mts_error_set(err, MTS_ERR_VERSION, "%s: 4D OFF is not supported", t.name);
    text_blank(&t);
    if (t.end - t.p >= 6 && memcmp(t.p, "BINARY", 6) == 0 && token_ends(&t, t.p + 6)) {
        if (fl.ndim)
            return mts_error_set(err, MTS_ERR_VERSION, "%s: binary nOFF is not supported",
                                 t.name);
        /* the binary data starts right after the newline that ends the
         * header line; blanks and a comment may come before it */
        t.p += 6;
        text_blank(&t);
        if (text_eof(&t))
            return mts_error_set(err, MTS_ERR_FORMAT,
                                 "%s: truncated: the file ends in the binary OFF header line",
                                 t.name);
        if (*t.p != '\n')
            return mts_error_set(err, MTS_ERR_FORMAT,
                                 "%s: line %llu: unexpected text after OFF BINARY", t.name,
                                 (unsigned long long)t.line);
        return off_binary(raw, &fl, (const unsigned char *)t.p + 1,
                          (const unsigned char *)t.end, err);
    }
    if (fl.ndim) {
        uint32_t dim;
        mts_result r = off_count(&t, "dimension", &dim, err);
        if (r != MTS_OK)
            return r;
        if (dim != 3)
            return mts_error_set(err, MTS_ERR_VERSION, "%s: %u-dimensional OFF is not supported",
                                 t.name, dim);
    }

    uint32_t nv, nf;
    mts_result r = off_count(&t, "vertex", &nv, err);
    if (r == MTS_OK)
        r = off_count(&t, "face", &nf, err);
    if (r != MTS_OK)
        return r;
    text_next_line(&t); /* the edge count, which nobody uses */

    /* Reserve only what the remaining bytes can hold ("x y z" is at least 5
     * bytes, a face at least 2): the counts are claims, not facts. */
    size_t left = (size_t)(t.end - t.p);
    uint64_t want_v = nv < left / 5 + 1 ? nv : left / 5 + 1;
    uint64_t want_f = nf < left / 2 + 1 ? nf : left / 2 + 1;
    if ((r = raw_reserve_vertices(raw, want_v, normals, err)) != MTS_OK ||
        (r = raw_reserve_triangles(raw, want_f, err)) != MTS_OK)
        return r;

    const unsigned values = normals ? 6 : 3;
    off_color_scan oc = {0, 1, 0, 0};
    for (uint32_t i = 0; i < nv; i++) {
        text_space(&t);
        if (text_eof(&t))
            return off_truncated(&t, "vertices", nv, i, err);
        if ((r = raw_reserve_vertices(raw, (uint64_t)i + 1, normals, err)) != MTS_OK)
            return r;
        float v[6];
        for (unsigned c = 0; c < values; c++) {
            text_blank(&t);
            if (text_eof(&t))
                return off_truncated(&t, "vertices", nv, i, err);
            if (text_eol(&t))
                return mts_error_set(err, MTS_ERR_FORMAT,
                                     "%s: line %llu: vertex %u has %u values, expected %u",
                                     t.name, (unsigned long long)t.line, i, c, values);
            if ((r = text_float(&t, &v[c], err)) != MTS_OK)
                return r;
        }
        memcpy(raw->positions + (size_t)i * 3, v, 3 * sizeof *v);
        if (normals)
            memcpy(raw->normals + (size_t)i * 3, v + 3, 3 * sizeof *v);
        raw->vertex_count = i + 1;
        if (fl.colors && (r = off_vertex_color(&t, raw, &fl, i, &oc, err)) != MTS_OK)
            return r;
        text_next_line(&t); /* texture coordinates */
    }
    st->file_vertices = nv;
    if (fl.colors)
        off_colors_scale(raw, &oc);

    for (uint32_t f = 0; f < nf; f++) {
        text_space(&t);
        if (text_eof(&t))
            return off_truncated(&t, "faces", nf, f, err);
        int64_t n;
        if ((r = text_int(&t, &n, err)) != MTS_OK)
            return r;
        if (n < 0 || n > (int64_t)MTS__MESH_MAX_COUNT)
            return mts_error_set(err, MTS_ERR_FORMAT, "%s: line %llu: face %u has %lld corners",
                                 t.name, (unsigned long long)t.line, f, (long long)n);
        fan poly = {0, 0, 0};
        for (int64_t c = 0; c < n; c++) {
            text_blank(&t);
            if (text_eof(&t))
                return off_truncated(&t, "faces", nf, f, err);
            if (text_eol(&t))
                return mts_error_set(err, MTS_ERR_FORMAT,
                                     "%s: line %llu: face %u has %lld indices, expected %lld",
                                     t.name, (unsigned long long)t.line, f, (long long)c,
                                     (long long)n);
            int64_t idx;
            if ((r = text_int(&t, &idx, err)) != MTS_OK)
                return r;
            if (idx < 0 || idx >= nv)
                return mts_error_set(err, MTS_ERR_RANGE,
                                     "%s: line %llu: face %u: vertex index %lld out of range "
                                     "(%u vertices)",
                                     t.name, (unsigned long long)t.line, f, (long long)idx, nv);
            if ((r = fan_add(raw, &poly, (uint32_t)idx, err)) != MTS_OK)
                return r;
        }
        if ((r = fan_end(raw, &poly, err)) != MTS_OK)
            return r;
        text_next_line(&t); /* a face colour */
    }
    return MTS_OK;
}

/* ------------------------------------------------------------------------ */
/* OBJ                                                                      */

/* Resolves a 1-based (or negative, counted back from the latest) OBJ index
 * against the count defined so far; returns -1 when out of range. */
static int64_t obj_resolve(int64_t idx, uint32_t count)
{
    if (idx > 0)
        return idx <= count ? idx - 1 : -1;
    if (idx < 0)
        return -idx <= count ? count + idx : -1;
    return -1;
}

static mts_result obj_floats(text *t, float *v, unsigned n, const char *what, mts_error *err)
{
    for (unsigned c = 0; c < n; c++) {
        text_blank(t);
        if (text_eol(t))
            return mts_error_set(err, MTS_ERR_FORMAT,
                                 "%s: %sline %llu: '%s' has %u values, expected %u", t->name,
                                 text_eof(t) ? "truncated at " : "", (unsigned long long)t->line,
                                 what, c, n);
        mts_result r = text_float(t, &v[c], err);
        if (r != MTS_OK)
            return r;
    }
    return MTS_OK;
}

static mts_result obj_index(text *t, int64_t *out, mts_error *err)
{
    const char *s = t->p;
    if (scan_int(&s, t->end, out) != 0 || !(token_ends(t, s) || *s == '/'))
        return text_bad_number(t, err);
    t->p = s;
    return MTS_OK;
}

static mts_result obj_range(const text *t, const char *what, int64_t idx, uint32_t count,
                            mts_error *err)
{
    return mts_error_set(err, MTS_ERR_RANGE, "%s: line %llu: %s index %lld out of range (%u defined)",
                         t->name, (unsigned long long)t->line, what, (long long)idx, count);
}

/* OBJ has no magic, and its reader skips the lines it does not know, so
 * without this a file of anything would be read to its end for nothing
 * (and UTF-16 text would end in "no triangles"): an OBJ file is text, and a
 * NUL byte says this one is not. */
static mts_result obj_check_text(const char *name, const char *data, size_t size, mts_error *err)
{
    return text_refuse(name, data, size, "an OBJ", "ASCII OBJ", "", err);
}

mts_result mts__mesh_read_obj(mts__mesh_raw *raw, const char *data, size_t size, mts_error *err)
{
    text t = {data + bom_length(data, size), data + size, 1, 1, raw->name};
    mts_mesh_stats *st = raw->stats;
    st->format = MTS_MESH_OBJ;
    mts_result r = obj_check_text(raw->name, data, size, err);
    if (r != MTS_OK)
        return r;
    float *vn = NULL; /* unit normals of the vn lines, 3 each */
    uint32_t vn_count = 0, vn_capacity = 0, vt_count = 0;
    int every_corner_has_vn = 1;

    while (!text_eof(&t)) {
        text_blank(&t);
        const char *w;
        size_t wn = text_word(&t, &w);
        if (word_is(w, wn, "v")) {
            uint32_t i = raw->vertex_count;
            if ((r = raw_reserve_vertices(raw, (uint64_t)i + 1, 1, err)) != MTS_OK ||
                (r = obj_floats(&t, raw->positions + (size_t)i * 3, 3, "v", err)) != MTS_OK)
                goto done;
            raw->vertex_count = i + 1;
            /* after x y z: nothing, w (rational curves' weight, no colour),
             * or the common extension r g b in 0..1 (MeshLab, ZBrush,
             * Blender), which some write with a fourth, alpha */
            float x[5];
            unsigned n = 0;
            for (;;) {
                text_blank(&t);
                if (text_eol(&t) || n == 5)
                    break;
                int got = text_color_value(&t, i, &x[n], err);
                if (got < 0) {
                    r = MTS_ERR_FORMAT;
                    goto done;
                }
                if (got == 0) {
                    n = 0;
                    break;
                }
                n++;
            }
            if (n == 3 || n == 4) {
                if ((r = raw_enable_colors(raw, err)) != MTS_OK)
                    goto done;
                const double rgb[3] = {x[0], x[1], x[2]};
                raw_set_color(raw, i, rgb, n == 4 ? fmax(0.0, x[3]) : -1.0, 1.0);
            }
        } else if (word_is(w, wn, "vn")) {
            if (vn_count == vn_capacity) {
                if (vn_count >= MTS__MESH_MAX_COUNT) {
                    r = mts_error_set(err, MTS_ERR_LIMIT, "%s: more than %u normals", t.name,
                                      MTS__MESH_MAX_COUNT);
                    goto done;
                }
                uint64_t cap = vn_capacity ? (uint64_t)vn_capacity * 2 : 256;
                if (cap > MTS__MESH_MAX_COUNT)
                    cap = MTS__MESH_MAX_COUNT;
                float *grown = realloc(vn, (size_t)cap * 3 * sizeof *grown);
                if (!grown) {
                    r = mts_error_set(err, MTS_ERR_NOMEM, "%s: out of memory for normals", t.name);
                    goto done;
                }
                vn = grown;
                vn_capacity = (uint32_t)cap;
            }
            float *n = vn + (size_t)vn_count * 3;
            if ((r = obj_floats(&t, n, 3, "vn", err)) != MTS_OK)
                goto done;
            /* stored unit length so that a vertex named with several normals
             * gets their plain average direction */
            double len = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
            for (int c = 0; c < 3; c++)
                n[c] = len > 0 ? (float)(n[c] / len) : 0.0f;
            vn_count++;
        } else if (word_is(w, wn, "vt")) {
            if (vt_count < MTS__MESH_MAX_COUNT)
                vt_count++;
        } else if (word_is(w, wn, "f")) {
            fan poly = {0, 0, 0};
            for (;;) {
                text_blank(&t);
                if (text_eol(&t))
                    break;
                int64_t iv, it = 0, in = 0, rv;
                if ((r = obj_index(&t, &iv, err)) != MTS_OK)
                    goto done;
                if ((rv = obj_resolve(iv, raw->vertex_count)) < 0) {
                    r = obj_range(&t, "vertex", iv, raw->vertex_count, err);
                    goto done;
                }
                if (t.p < t.end && *t.p == '/') {
                    t.p++;
                    if (t.p < t.end && *t.p != '/') {
                        if ((r = obj_index(&t, &it, err)) != MTS_OK)
                            goto done;
                        if (obj_resolve(it, vt_count) < 0) {
                            r = obj_range(&t, "texture", it, vt_count, err);
                            goto done;
                        }
                    }
                    if (t.p < t.end && *t.p == '/') {
                        t.p++;
                        if ((r = obj_index(&t, &in, err)) != MTS_OK)
                            goto done;
                        int64_t rn = obj_resolve(in, vn_count);
                        if (rn < 0) {
                            r = obj_range(&t, "normal", in, vn_count, err);
                            goto done;
                        }
                        float *dst = raw->normals + (size_t)rv * 3;
                        const float *src = vn + (size_t)rn * 3;
                        dst[0] += src[0];
                        dst[1] += src[1];
                        dst[2] += src[2];
                    }
                }
                if (!token_ends(&t, t.p)) {
                    r = text_bad_number(&t, err);
                    goto done;
                }
                every_corner_has_vn &= in != 0;
                if ((r = fan_add(raw, &poly, (uint32_t)rv, err)) != MTS_OK)
                    goto done;
            }
            if ((r = fan_end(raw, &poly, err)) != MTS_OK)
                goto done;
        } else if (word_is(w, wn, "p") || word_is(w, wn, "l")) {
            /* no surface, but named if nothing else is there */
            uint32_t *n = w[0] == 'p' ? &raw->obj_points : &raw->obj_lines;
            *n += *n < UINT32_MAX;
        }
        /* anything else (vt values, g, o, s, usemtl, mtllib, comments) does
         * not shape the surface */
        text_next_line(&t);
    }
    st->file_vertices = raw->vertex_count;
    if (vn_count == 0 || !every_corner_has_vn || st->file_faces == 0) {
        free(raw->normals);
        raw->normals = NULL;
    }
done:
    free(vn);
    return r;
}

/* ------------------------------------------------------------------------ */
/* PLY                                                                      */

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
    text t;
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
        if (word_is(w, n, names[i].name))
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
static mts_result ply_no_magic(const char *name, const char *data, size_t size, mts_error *err)
{
    mts_result r = text_refuse(name, data, size, "a PLY", "ASCII PLY", " (and no 'ply' magic)", err);
    if (r != MTS_OK)
        return r;
    return mts_error_set(err, MTS_ERR_FORMAT, "%s: not a PLY file (no 'ply' magic)", name);
}

/* Reads the header up to and including the end_header line. */
static mts_result ply_header(ply *P, mts__mesh_raw *raw, mts_error *err)
{
    text *t = &P->t;
    const char *name = raw->name;
    const char *w;
    size_t wn = text_word(t, &w);
    if (!word_is(w, wn, "ply"))
        return ply_no_magic(name, P->data, P->size, err);
    text_next_line(t);
    int have_format = 0;
    ply_elem *cur = NULL;
    for (;;) {
        if (text_eof(t))
            return mts_error_set(err, MTS_ERR_FORMAT, "%s: truncated: the PLY header has no end_header",
                                 name);
        wn = text_word(t, &w);
        if (word_is(w, wn, "end_header")) {
            text_next_line(t);
            break;
        } else if (wn == 0 || word_is(w, wn, "comment") || word_is(w, wn, "obj_info")) {
            /* nothing */
        } else if (word_is(w, wn, "format")) {
            const char *f, *v;
            size_t fn = text_word(t, &f), vn = text_word(t, &v);
            if (word_is(f, fn, "ascii"))
                P->format = PLY_ASCII;
            else if (word_is(f, fn, "binary_little_endian"))
                P->format = PLY_LE;
            else if (word_is(f, fn, "binary_big_endian"))
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
        } else if (word_is(w, wn, "element")) {
            if (P->elem_count == PLY_MAX_ELEMENTS)
                return mts_error_set(err, MTS_ERR_LIMIT, "%s: more than %d PLY elements", name,
                                     PLY_MAX_ELEMENTS);
            const char *en;
            size_t enn = text_word(t, &en);
            text_blank(t);
            int64_t count;
            if (enn == 0 || text_eol(t) || scan_int(&t->p, t->end, &count) != 0 ||
                !token_ends(t, t->p) || count < 0)
                return mts_error_set(err, MTS_ERR_FORMAT, "%s: line %llu: bad element line", name,
                                     (unsigned long long)t->line);
            if (count > (int64_t)MTS__MESH_MAX_COUNT)
                return mts_error_set(err, MTS_ERR_LIMIT,
                                     "%s: line %llu: %lld elements is over the limit of %u",
                                     name, (unsigned long long)t->line, (long long)count,
                                     MTS__MESH_MAX_COUNT);
            cur = &P->elems[P->elem_count++];
            memset(cur, 0, sizeof *cur);
            /* named in messages by what it means to us, not by the file's text */
            snprintf(cur->name, sizeof cur->name, "element %u", P->elem_count);
            cur->count = (uint32_t)count;
            cur->first = P->prop_count;
            if (word_is(en, enn, "vertex") || word_is(en, enn, "face")) {
                int kind = word_is(en, enn, "vertex") ? ELEM_VERTEX : ELEM_FACE;
                snprintf(cur->name, sizeof cur->name, "%s", kind == ELEM_VERTEX ? "vertex" : "face");
                for (uint32_t e = 0; e + 1 < P->elem_count; e++)
                    if (P->elems[e].kind == kind)
                        return mts_error_set(err, MTS_ERR_FORMAT, "%s: two '%s' elements", name,
                                             cur->name);
                cur->kind = kind;
            }
        } else if (word_is(w, wn, "property")) {
            if (!cur)
                return mts_error_set(err, MTS_ERR_FORMAT, "%s: line %llu: property before any element",
                                     name, (unsigned long long)t->line);
            if (P->prop_count == PLY_MAX_PROPERTIES)
                return mts_error_set(err, MTS_ERR_LIMIT, "%s: more than %d PLY properties", name,
                                     PLY_MAX_PROPERTIES);
            ply_prop prop = {PLY_NONE, PLY_NONE, ROLE_SKIP};
            const char *tw, *pn;
            size_t twn = text_word(t, &tw);
            if (word_is(tw, twn, "list")) {
                const char *cw;
                size_t cwn = text_word(t, &cw);
                twn = text_word(t, &tw);
                prop.count_type = (uint8_t)ply_type_of(cw, cwn);
                if (prop.count_type == PLY_NONE || prop.count_type == PLY_F32 ||
                    prop.count_type == PLY_F64)
                    return mts_error_set(err, MTS_ERR_FORMAT, "%s: line %llu: bad list count type",
                                         name, (unsigned long long)t->line);
            }
            prop.type = (uint8_t)ply_type_of(tw, twn);
            size_t pnn = text_word(t, &pn);
            if (prop.type == PLY_NONE || pnn == 0)
                return mts_error_set(err, MTS_ERR_FORMAT, "%s: line %llu: bad property type",
                                     name, (unsigned long long)t->line);
            int is_list = prop.count_type != PLY_NONE;
            if (cur->kind == ELEM_VERTEX && !is_list) {
                static const char *const coords[] = {"x", "y", "z", "nx", "ny", "nz"};
                for (int c = 0; c < 6; c++)
                    if (word_is(pn, pnn, coords[c]))
                        prop.role = (uint8_t)(ROLE_X + c);
                /* the names MeshLab, Blender, Open3D and CloudCompare write
                 * ("diffuse_" from some scanners' software) */
                static const char *const colors[2][4] = {
                    {"red", "green", "blue", "alpha"},
                    {"diffuse_red", "diffuse_green", "diffuse_blue", "diffuse_alpha"}};
                for (int n = 0; n < 2; n++)
                    for (int c = 0; c < 4; c++)
                        if (word_is(pn, pnn, colors[n][c]))
                            prop.role = (uint8_t)(ROLE_RED + c);
            } else if (cur->kind == ELEM_FACE &&
                       (word_is(pn, pnn, "vertex_indices") || word_is(pn, pnn, "vertex_index"))) {
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
        text_next_line(t);
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
    text_space(&P->t);
    if (text_eof(&P->t))
        return 1;
    const char *s = P->t.p;
    float f;
    if (mts__mesh_scan_float(&s, P->t.end, &f) != 0 || !token_ends(&P->t, s))
        return P->t.p + token_len(&P->t) >= P->t.end ? 1 : 2; /* cut inside: truncated */
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
        text_space(&P->t);
        if (text_eof(&P->t))
            return 1;
        const char *s = P->t.p;
        if (scan_int(&s, P->t.end, out) == 0 && token_ends(&P->t, s)) {
            P->t.p = s;
            return 0;
        }
        /* else only an integral value written as a float ("3.0") in a
         * float-typed list */
        if (type != PLY_F32 && type != PLY_F64)
            return P->t.p + token_len(&P->t) >= P->t.end ? 1 : 2; /* cut inside: truncated */
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
        text_space(&P->t);
        if (text_eof(&P->t))
            return 1;
        while (P->t.p < P->t.end && !is_space(*P->t.p))
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
    P->t = (text){data, data + size, 1, 0, name};
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
    if (with_colors && (r = raw_enable_colors(raw, err)) != MTS_OK)
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
        if ((r = raw_reserve_vertices(raw, nv < cap_v ? nv : cap_v, with_normals, err)) != MTS_OK ||
            (r = raw_reserve_triangles(raw, face->count < cap_f ? face->count : cap_f, err)) != MTS_OK)
            goto done;
    }

    for (uint32_t e = 0; e < P->elem_count; e++) {
        const ply_elem *el = &P->elems[e];
        const ply_prop *props = P->props + el->first;
        if (el->props == 0)
            continue; /* nothing in the file to read, however many it claims */
        for (uint32_t i = 0; i < el->count; i++) {
            float v[ROLE_COUNT] = {0};
            fan poly = {0, 0, 0};
            int status = 0;
            if (el->kind == ELEM_VERTEX &&
                (r = raw_reserve_vertices(raw, (uint64_t)i + 1, with_normals, err)) != MTS_OK)
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
                    if ((r = fan_add(raw, &poly, (uint32_t)idx, err)) != MTS_OK)
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
                    raw_set_color(raw, i, rgb,
                                  has_rgba[3] ? fmax(0.0, v[ROLE_ALPHA] / color_scale[3]) : -1.0,
                                  1.0);
                }
            } else if (el->kind == ELEM_FACE) {
                if ((r = fan_end(raw, &poly, err)) != MTS_OK)
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

/* ------------------------------------------------------------------------ */
/* STL                                                                      */

static inline uint32_t hash3(uint32_t a, uint32_t b, uint32_t c)
{
    uint64_t h = (uint64_t)a * UINT64_C(0x9E3779B97F4A7C15);
    h ^= (uint64_t)b * UINT64_C(0xC2B2AE3D27D4EB4F) + (h >> 29);
    h ^= (uint64_t)c * UINT64_C(0x165667B19E3779F9) + (h >> 31);
    return (uint32_t)(h ^ (h >> 32));
}

static inline uint32_t float_key(float f)
{
    if (f == 0.0f)
        f = 0.0f; /* -0 and +0 are the same position */
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    return u;
}

/* STL stores every facet's corners separately: merge corners at identical
 * positions into one vertex (first appearance order) through a hash table so
 * that the mesh has connectivity. */
static mts_result stl_weld(mts__mesh_raw *raw, mts_error *err)
{
    uint32_t n = raw->vertex_count;
    raw->stats->file_vertices = n;
    if (n == 0)
        return MTS_OK;
    uint64_t cap = 16;
    while (cap < (uint64_t)n * 2)
        cap *= 2;
    uint32_t *table = malloc((size_t)cap * sizeof *table);
    uint32_t *remap = malloc((size_t)n * sizeof *remap);
    if (!table || !remap) {
        free(table);
        free(remap);
        return mts_error_set(err, MTS_ERR_NOMEM, "%s: out of memory welding %u corners", raw->name,
                             n);
    }
    memset(table, 0xff, (size_t)cap * sizeof *table);
    float *pos = raw->positions;
    uint32_t unique = 0;
    for (uint32_t c = 0; c < n; c++) {
        const float *p = pos + (size_t)c * 3;
        uint32_t h = hash3(float_key(p[0]), float_key(p[1]), float_key(p[2])) & (uint32_t)(cap - 1);
        for (;;) {
            uint32_t u = table[h];
            if (u == UINT32_MAX) {
                /* unique <= c, so this never overwrites a corner not yet seen */
                memmove(pos + (size_t)unique * 3, p, 3 * sizeof *p);
                table[h] = unique;
                remap[c] = unique++;
                break;
            }
            const float *q = pos + (size_t)u * 3;
            if (q[0] == p[0] && q[1] == p[1] && q[2] == p[2]) {
                remap[c] = u;
                break;
            }
            h = (h + 1) & (uint32_t)(cap - 1);
        }
    }
    uint32_t *t = raw->triangles;
    for (size_t i = 0; i < (size_t)raw->triangle_count * 3; i++)
        t[i] = remap[t[i]];
    raw->vertex_count = unique;
    raw->stats->welded_vertices = n - unique;
    free(table);
    free(remap);
    return MTS_OK;
}

/* A binary STL's facet count (at byte 80), checked against the limit and
 * against the size of the file (which head, 84 bytes or more, starts). */
static mts_result stl_binary_count(const char *name, const unsigned char *head, size_t head_size,
                                   uint64_t size, uint32_t *count, mts_error *err)
{
    *count = le32(head + 80);
    /* a file that does not start with "solid" is taken for binary; UTF-16
     * text (ASCII STL saved as "Unicode") is told apart before its
     * characters are read as a facet count */
    const char *wide = mts__mesh_wide_text((const char *)head, head_size);
    if (wide && 84 + (uint64_t)*count * 50 != size)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "%s: the file is %s, not ASCII STL: save it as UTF-8 or ASCII", name,
                             wide);
    if (*count > MTS__MESH_MAX_COUNT / 3)
        return mts_error_set(err, MTS_ERR_LIMIT, "%s: %u facets is over the limit of %u", name,
                             *count, MTS__MESH_MAX_COUNT / 3);
    uint64_t need = 84 + (uint64_t)*count * 50;
    if (need > size)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "%s: truncated: expected %u facets (%llu bytes), the file has %llu bytes",
                             name, *count, (unsigned long long)need, (unsigned long long)size);
    return MTS_OK;
}

static mts_result stl_binary(mts__mesh_raw *raw, const char *data, size_t size, mts_error *err)
{
    const char *wide = size < 84 ? mts__mesh_wide_text(data, size) : NULL;
    if (wide)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "%s: the file is %s, not ASCII STL: save it as UTF-8 or ASCII",
                             raw->name, wide);
    if (size < 84)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "%s: truncated: a binary STL needs 84 header bytes, the file has %zu",
                             raw->name, size);
    const unsigned char *b = (const unsigned char *)data;
    uint32_t count;
    mts_result r = stl_binary_count(raw->name, b, size, size, &count, err);
    if (r != MTS_OK)
        return r;
    if ((r = raw_reserve_vertices(raw, (uint64_t)count * 3, 0, err)) != MTS_OK ||
        (r = raw_reserve_triangles(raw, count, err)) != MTS_OK)
        return r;
    for (uint32_t f = 0; f < count; f++) {
        const unsigned char *rec = b + 84 + (size_t)f * 50 + 12; /* past the facet normal */
        float *p = raw->positions + (size_t)f * 9;
        for (int k = 0; k < 9; k++) {
            uint32_t u = le32(rec + 4 * k);
            memcpy(&p[k], &u, sizeof u);
            if (!isfinite(p[k]))
                return mts_error_set(err, MTS_ERR_FORMAT, "%s: facet %u has a non-finite coordinate",
                                     raw->name, f);
        }
        uint32_t *t = raw->triangles + (size_t)f * 3;
        t[0] = 3 * f;
        t[1] = 3 * f + 1;
        t[2] = 3 * f + 2;
        raw->stats->file_faces++;
    }
    raw->vertex_count = count * 3;
    raw->triangle_count = count;
    return MTS_OK;
}

/* A word that is not the keyword expected; when it is the keyword's start
 * cut off by the end of the file, the file was truncated, not corrupt. */
static mts_result stl_unexpected(const text *t, const char *kw, const char *w, size_t n,
                                 uint32_t facet, mts_error *err)
{
    if (t->p >= t->end && n < strlen(kw) && memcmp(w, kw, n) == 0)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "%s: truncated: the file ends inside facet %u (expected '%s')", t->name,
                             facet, kw);
    return mts_error_set(err, MTS_ERR_FORMAT, "%s: line %llu: expected '%s', found another word",
                         t->name, (unsigned long long)t->line, kw);
}

/* Expects keyword `kw` as the next word (across lines). */
static mts_result stl_expect(text *t, const char *kw, uint32_t facet, mts_error *err)
{
    text_space(t);
    if (text_eof(t))
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "%s: truncated: the file ends inside facet %u (expected '%s')", t->name,
                             facet, kw);
    const char *w;
    size_t n = text_word(t, &w);
    if (!word_is(w, n, kw))
        return stl_unexpected(t, kw, w, n, facet, err);
    return MTS_OK;
}

static mts_result stl_floats(text *t, float *v, uint32_t facet, mts_error *err)
{
    for (int c = 0; c < 3; c++) {
        text_space(t);
        if (text_eof(t))
            return mts_error_set(err, MTS_ERR_FORMAT, "%s: truncated: the file ends inside facet %u",
                                 t->name, facet);
        mts_result r = text_float(t, &v[c], err);
        if (r != MTS_OK)
            return r;
    }
    return MTS_OK;
}

static mts_result stl_ascii(mts__mesh_raw *raw, const char *data, size_t size, mts_error *err)
{
    text t = {data, data + size, 1, 0, raw->name};
    mts_result r;
    uint32_t facet = 0;
    if ((r = stl_expect(&t, "solid", 0, err)) != MTS_OK)
        return r;
    text_next_line(&t); /* the solid's name */
    for (;;) {
        text_space(&t);
        if (text_eof(&t))
            return mts_error_set(err, MTS_ERR_FORMAT, "%s: truncated: no 'endsolid' after %u facets",
                                 t.name, facet);
        const char *w;
        size_t n = text_word(&t, &w);
        if (word_is(w, n, "endsolid")) {
            text_next_line(&t);
            text_space(&t);
            if (text_eof(&t))
                break;
            /* several solids in one file */
            if ((r = stl_expect(&t, "solid", facet, err)) != MTS_OK)
                return r;
            text_next_line(&t);
            continue;
        }
        if (!word_is(w, n, "facet"))
            return stl_unexpected(&t, n > 0 && w[0] == 'e' ? "endsolid" : "facet", w, n, facet,
                                  err);
        float normal[3];
        if ((r = stl_expect(&t, "normal", facet, err)) != MTS_OK ||
            (r = stl_floats(&t, normal, facet, err)) != MTS_OK ||
            (r = stl_expect(&t, "outer", facet, err)) != MTS_OK ||
            (r = stl_expect(&t, "loop", facet, err)) != MTS_OK)
            return r;
        fan poly = {0, 0, 0};
        for (;;) {
            text_space(&t);
            if (text_eof(&t))
                return mts_error_set(err, MTS_ERR_FORMAT,
                                     "%s: truncated: the file ends inside facet %u", t.name, facet);
            n = text_word(&t, &w);
            if (word_is(w, n, "endloop"))
                break;
            if (!word_is(w, n, "vertex"))
                return stl_unexpected(&t, n > 0 && w[0] == 'e' ? "endloop" : "vertex", w, n,
                                      facet, err);
            uint32_t v = raw->vertex_count;
            if ((r = raw_reserve_vertices(raw, (uint64_t)v + 1, 0, err)) != MTS_OK ||
                (r = stl_floats(&t, raw->positions + (size_t)v * 3, facet, err)) != MTS_OK)
                return r;
            raw->vertex_count = v + 1;
            if ((r = fan_add(raw, &poly, v, err)) != MTS_OK)
                return r;
        }
        if ((r = stl_expect(&t, "endfacet", facet, err)) != MTS_OK ||
            (r = fan_end(raw, &poly, err)) != MTS_OK)
            return r;
        facet++;
    }
    return MTS_OK;
}

/* A buffer that starts with "solid" is ASCII unless its size is exactly
 * what a binary STL with the count at byte 80 would take: some binary
 * exporters put "solid" in the 80-byte header. */
static int stl_is_binary(const char *data, size_t size)
{
    if (size >= 84 && 84 + (uint64_t)le32((const unsigned char *)data + 80) * 50 == size)
        return 1;
    size_t i = 0;
    while (i < size && is_space(data[i]))
        i++;
    return !(size - i >= 5 && memcmp(data + i, "solid", 5) == 0);
}

mts_result mts__mesh_read_stl(mts__mesh_raw *raw, const char *data, size_t size, mts_error *err)
{
    raw->stats->format = MTS_MESH_STL;
    mts_result r = stl_is_binary(data, size) ? stl_binary(raw, data, size, err)
                                             : stl_ascii(raw, data, size, err);
    if (r == MTS_OK)
        r = stl_weld(raw, err);
    return r;
}

/* ------------------------------------------------------------------------ */
/* Sniffing                                                                 */

static const char *find_bytes(const char *hay, size_t n, const char *needle)
{
    size_t k = strlen(needle);
    for (size_t i = 0; i + k <= n; i++)
        if (hay[i] == needle[0] && memcmp(hay + i, needle, k) == 0)
            return hay + i;
    return NULL;
}

mts_mesh_format mts__mesh_sniff(const char *data, size_t size)
{
    return mts__mesh_sniff_head(data, size < 65536 ? size : 65536, size);
}

mts_mesh_format mts__mesh_sniff_head(const char *data, size_t size, uint64_t file_size)
{
    /* GLB: its magic, version 2 and its length the file's */
    if (size >= 12 && memcmp(data, "glTF", 4) == 0 &&
        le32((const unsigned char *)data + 8) == file_size)
        return MTS_MESH_GLTF;
    /* binary STL first: its 80-byte header may say anything, even "solid" */
    if (size >= 84 && 84 + (uint64_t)le32((const unsigned char *)data + 80) * 50 == file_size)
        return MTS_MESH_STL;
    if (size >= 4 && memcmp(data, "ply", 3) == 0 && (data[3] == '\n' || data[3] == '\r'))
        return MTS_MESH_PLY;
    text t = {data + bom_length(data, size), data + size, 1, 1, ""};
    text_space(&t);
    const char *w;
    size_t wn = text_word(&t, &w);
    off_flags fl;
    size_t k = off_keyword(w, wn, &fl);
    if (k > 0 && (k == wn || (unsigned)(w[k] - '0') < 10))
        return MTS_MESH_OFF;
    size_t head = size < 65536 ? size : 65536;
    if (word_is(w, wn, "solid") && find_bytes(data, head, "facet"))
        return MTS_MESH_STL;
    /* OBJ has no magic: the first keyword of the first few lines that carry one */
    t = (text){data + bom_length(data, size), data + head, 1, 1, ""};
    for (int lines = 0; lines < 64 && !text_eof(&t); lines++) {
        text_space(&t);
        wn = text_word(&t, &w);
        static const char *const obj_words[] = {"v", "vn", "vt", "vp", "f", "o", "g", "s",
                                                 "l", "mtllib", "usemtl"};
        for (size_t i = 0; i < sizeof obj_words / sizeof obj_words[0]; i++)
            if (word_is(w, wn, obj_words[i]))
                return MTS_MESH_OBJ;
        if (wn > 0)
            break;
    }
    return MTS_MESH_AUTO;
}

/* ------------------------------------------------------------------------ */
/* The head of a file, before the rest is read                              */

mts_result mts__mesh_check_head(mts_mesh_format format, const char *name, const char *head,
                                size_t head_size, uint64_t file_size, uint64_t *read_size,
                                mts_error *err)
{
    *read_size = file_size;
    if (head_size >= file_size)
        return MTS_OK; /* the parser sees it all and says what is wrong */
    switch (format) {
    case MTS_MESH_OFF: {
        text t = {head + bom_length(head, head_size), head + head_size, 1, 1, name};
        text_space(&t);
        const char *w;
        size_t wn = text_word(&t, &w);
        /* a first word cut by the head's end decides only once it is longer
         * than the longest keyword, "STCN4nOFF", and the character after it */
        if (text_eof(&t) && wn <= 10)
            return MTS_OK;
        off_flags fl;
        size_t k;
        return off_check_keyword(name, head, head_size, w, wn, &fl, &k, err);
    }
    case MTS_MESH_PLY: {
        text t = {head, head + head_size, 1, 0, name};
        const char *w;
        size_t wn = text_word(&t, &w);
        if ((text_eof(&t) && wn <= 3) || word_is(w, wn, "ply"))
            return MTS_OK;
        return ply_no_magic(name, head, head_size, err);
    }
    case MTS_MESH_STL: {
        /* stl_is_binary with the file's size: ASCII when it starts with
         * "solid" and is not exactly a binary STL's size */
        size_t i = 0;
        while (i < head_size && is_space(head[i]))
            i++;
        if (i == head_size)
            return MTS_OK;
        const unsigned char *b = (const unsigned char *)head;
        int exact = head_size >= 84 && 84 + (uint64_t)le32(b + 80) * 50 == file_size;
        if (!exact && head_size - i >= 5 && memcmp(head + i, "solid", 5) == 0)
            return MTS_OK;
        if (head_size < 84)
            return MTS_OK;
        uint32_t count;
        mts_result r = stl_binary_count(name, b, head_size, file_size, &count, err);
        if (r == MTS_OK)
            *read_size = 84 + (uint64_t)count * 50; /* what follows the facets is never read */
        return r;
    }
    case MTS_MESH_OBJ:
        return obj_check_text(name, head, head_size, err);
    default:
        return MTS_OK;
    }
}
