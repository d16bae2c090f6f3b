/* The mesh parsers' shared part and their dispatch: the raw mesh's storage,
 * the number scanners, the text helpers that are not inline
 * (mesh_read_internal.h holds those), the text-kind checks, and the sniffing
 * of a file's format and the check of its head before the rest is read. The
 * parsers are one file a format: mesh_read_off.c (ASCII and binary OFF),
 * mesh_read_obj.c, mesh_read_ply.c (ASCII, binary LE/BE) and mesh_read_stl.c
 * (ASCII, binary).
 *
 * Each parser works on the whole file in memory, bounded by an end pointer (no
 * NUL terminator needed, so a downloaded buffer is parsed in place), and
 * trusts no count it reads: allocations grow with what was actually parsed
 * or are capped by what the remaining bytes could hold, every index is
 * checked against the vertex count before it is stored, and every binary
 * read is bounds-checked. Messages name the file, the line or the item and
 * what was expected, never the file's own text: a file may be anything (a
 * secret a link points to, bytes a terminal acts on), and messages end up in
 * logs. */
#include "mesh_read_internal.h"

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
mts_result mts__raw_reserve_vertices(mts__mesh_raw *raw, uint64_t need, int with_normals,
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
 * mts__raw_reserve_vertices grows it from then on. */
mts_result mts__raw_enable_colors(mts__mesh_raw *raw, mts_error *err)
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
void mts__raw_set_color(mts__mesh_raw *raw, uint32_t i, const double rgb[3], double alpha,
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

mts_result mts__raw_reserve_triangles(mts__mesh_raw *raw, uint64_t need, mts_error *err)
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

/* ------------------------------------------------------------------------ */
/* Numbers                                                                  */

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

/* ------------------------------------------------------------------------ */
/* Text                                                                     */

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
mts_result mts__text_refuse(const char *name, const char *data, size_t size,
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

int mts__token_len(const mts__text *t)
{
    const char *s = t->p;
    while (s < t->end && !mts__is_space(*s) && s - t->p < 40)
        s++;
    return (int)(s - t->p);
}

mts_result mts__text_bad_number(const mts__text *t, mts_error *err)
{
    if (t->p + mts__token_len(t) >= t->end) /* cut inside the number: the file ends early */
        return mts_error_set(err, MTS_ERR_FORMAT, "%s: truncated at line %llu: the file ends "
                             "inside a number", t->name, (unsigned long long)t->line);
    return mts_error_set(err, MTS_ERR_FORMAT, "%s: line %llu: bad number", t->name,
                         (unsigned long long)t->line);
}

/* A colour value at t->p (the caller has skipped blanks and checked there
 * is one) of vertex i. Returns 1 with *out set, 0 at a token that is no
 * number (the readers always ignored what follows a vertex, and still do:
 * that vertex has no colour), and -1 with err set for a value written as
 * a non-finite number ("nan", "inf", or one past a float's range), which
 * is refused naming the vertex. */
int mts__text_color_value(mts__text *t, uint32_t i, float *out, mts_error *err)
{
    const char *s = t->p;
    int r = mts__mesh_scan_float(&s, t->end, out);
    if (r == 0 && mts__token_ends(t, s)) {
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
        mts__le32((const unsigned char *)data + 8) == file_size)
        return MTS_MESH_GLTF;
    /* binary STL first: its 80-byte header may say anything, even "solid" */
    if (size >= 84 && 84 + (uint64_t)mts__le32((const unsigned char *)data + 80) * 50 == file_size)
        return MTS_MESH_STL;
    if (size >= 4 && memcmp(data, "ply", 3) == 0 && (data[3] == '\n' || data[3] == '\r'))
        return MTS_MESH_PLY;
    mts__text t = {data + mts__bom_length(data, size), data + size, 1, 1, ""};
    mts__text_space(&t);
    const char *w;
    size_t wn = mts__text_word(&t, &w);
    mts__off_flags fl;
    size_t k = mts__off_keyword(w, wn, &fl);
    if (k > 0 && (k == wn || (unsigned)(w[k] - '0') < 10))
        return MTS_MESH_OFF;
    size_t head = size < 65536 ? size : 65536;
    if (mts__word_is(w, wn, "solid") && find_bytes(data, head, "facet"))
        return MTS_MESH_STL;
    /* OBJ has no magic: the first keyword of the first few lines that carry one */
    t = (mts__text){data + mts__bom_length(data, size), data + head, 1, 1, ""};
    for (int lines = 0; lines < 64 && !mts__text_eof(&t); lines++) {
        mts__text_space(&t);
        wn = mts__text_word(&t, &w);
        static const char *const obj_words[] = {"v", "vn", "vt", "vp", "f", "o", "g", "s",
                                                 "l", "mtllib", "usemtl"};
        for (size_t i = 0; i < sizeof obj_words / sizeof obj_words[0]; i++)
            if (mts__word_is(w, wn, obj_words[i]))
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
        mts__text t = {head + mts__bom_length(head, head_size), head + head_size, 1, 1, name};
        mts__text_space(&t);
        const char *w;
        size_t wn = mts__text_word(&t, &w);
        /* a first word cut by the head's end decides only once it is longer
         * than the longest keyword, "STCN4nOFF", and the character after it */
        if (mts__text_eof(&t) && wn <= 10)
            return MTS_OK;
        mts__off_flags fl;
        size_t k;
        return mts__off_check_keyword(name, head, head_size, w, wn, &fl, &k, err);
    }
    case MTS_MESH_PLY: {
        mts__text t = {head, head + head_size, 1, 0, name};
        const char *w;
        size_t wn = mts__text_word(&t, &w);
        if ((mts__text_eof(&t) && wn <= 3) || mts__word_is(w, wn, "ply"))
            return MTS_OK;
        return mts__ply_no_magic(name, head, head_size, err);
    }
    case MTS_MESH_STL: {
        /* stl_is_binary (mesh_read_stl.c) with the file's size: ASCII when
         * it starts with "solid" and is not exactly a binary STL's size */
        size_t i = 0;
        while (i < head_size && mts__is_space(head[i]))
            i++;
        if (i == head_size)
            return MTS_OK;
        const unsigned char *b = (const unsigned char *)head;
        int exact = head_size >= 84 && 84 + (uint64_t)mts__le32(b + 80) * 50 == file_size;
        if (!exact && head_size - i >= 5 && memcmp(head + i, "solid", 5) == 0)
            return MTS_OK;
        if (head_size < 84)
            return MTS_OK;
        uint32_t count;
        mts_result r = mts__stl_binary_count(name, b, head_size, file_size, &count, err);
        if (r == MTS_OK)
            *read_size = 84 + (uint64_t)count * 50; /* what follows the facets is never read */
        return r;
    }
    case MTS_MESH_OBJ:
        return mts__obj_check_text(name, head, head_size, err);
    default:
        return MTS_OK;
    }
}
