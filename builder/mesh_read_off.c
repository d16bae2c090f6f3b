/* The OFF parser: ASCII OFF with Geomview's [ST][C][N][4][n] header keyword
 * (colours per vertex, 0..1 or 0..255 as the file shows), and binary OFF in
 * Geomview's big-endian layout or OpenMesh's little-endian one. */
#include "mesh_read_internal.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

/* Reads the Geomview header keyword into *fl and returns the length consumed
 * through "OFF", or 0 when the word is not an OFF keyword. */
size_t mts__off_keyword(const char *w, size_t n, mts__off_flags *fl)
{
    size_t i = 0;
    *fl = (mts__off_flags){0, 0, 0, 0, 0};
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
mts_result mts__off_check_keyword(const char *name, const char *data, size_t size,
                                  const char *w, size_t wn, mts__off_flags *fl, size_t *k,
                                  mts_error *err)
{
    *k = mts__off_keyword(w, wn, fl);
    if (*k == 0 || (*k < wn && (unsigned)(w[*k] - '0') >= 10)) {
        /* binary OFF starts with the keyword line too: without it, UTF-16
         * or binary data is named as what it is */
        mts_result r = mts__text_refuse(name, data, size, "an OFF", "ASCII OFF",
                                        " (ASCII and binary OFF start with the OFF keyword)", err);
        if (r != MTS_OK)
            return r;
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "%s: not an OFF file (the first word is not OFF or a variant of it)",
                             name);
    }
    return MTS_OK;
}

static mts_result off_truncated(const mts__text *t, const char *what, uint32_t expected,
                                uint32_t got, mts_error *err)
{
    return mts_error_set(err, MTS_ERR_FORMAT, "%s: truncated: expected %u %s, file ends after %u",
                         t->name, expected, what, got);
}

/* A header count: a non-negative integer below the 2^31 limit. */
static mts_result off_count(mts__text *t, const char *what, uint32_t *out, mts_error *err)
{
    mts__text_space(t);
    if (mts__text_eof(t))
        return mts_error_set(err, MTS_ERR_FORMAT, "%s: truncated: the OFF header has no %s count",
                             t->name, what);
    int64_t v = 0; /* set unless text_int fails; compilers cannot always see that */
    mts_result r = mts__text_int(t, &v, err);
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
 * per face n i[0] .. i[n-1] [colour]. Vertex colours are kept, as ASCII
 * COFF's are (offb_color_scale says how they read); face colours are
 * skipped, as ASCII OFF's are. Each candidate layout is first walked through
 * (counts and indices checked, nothing stored), and the first that reads as
 * a valid file ending exactly at the end is parsed. When none does (a
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
    return big ? mts__be32(p) : mts__le32(p);
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
    while (p < end && mts__is_space((char)*p))
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

/* How binary COFF's vertex colour words read: ncol (3 or 4) words at word
 * `at` of each of nv vertices, vstride bytes apart. Geomview writes floats
 * in 0..1; OpenMesh integers in 0..255 or floats, and says not which. When
 * every word is at most 255 they are integers in 0..255 (*ints set): a
 * float colour above 0 has a far larger bit pattern, and 0 is 0 either way.
 * Floats otherwise, their range decided as ASCII COFF's is: integral values
 * of which some pass 1 are 0..255, anything else 0..1. Returns the scale,
 * 255 or 1. */
static float offb_color_scale(const unsigned char *p, uint32_t nv, size_t vstride, unsigned at,
                              unsigned ncol, int big, int *ints)
{
    int small = 1, over_one = 0, integral = 1;
    for (uint32_t i = 0; i < nv; i++, p += vstride)
        for (unsigned c = 0; c < ncol; c++) {
            uint32_t u = offb_u32(p + 4 * (at + c), big);
            float f;
            memcpy(&f, &u, sizeof f);
            small &= u <= 255;
            if (isfinite(f)) { /* the others are refused as the vertices are read */
                over_one |= f > 1;
                integral &= f == floorf(f);
            }
        }
    *ints = small;
    return small || (over_one && integral) ? 255.0f : 1.0f;
}

static mts_result offb_truncated(const char *name, const char *what, uint32_t expected,
                                 uint32_t got, mts_error *err)
{
    return mts_error_set(err, MTS_ERR_FORMAT, "%s: truncated: expected %u %s, file ends after %u",
                         name, expected, what, got);
}

/* The binary part of an OFF file: p is the byte after the header line. */
static mts_result off_binary(mts__mesh_raw *raw, const mts__off_flags *fl, const unsigned char *p,
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
    mts_result r = mts__raw_reserve_vertices(raw, nv, fl->normals, err);
    if (r != MTS_OK)
        return r;
    const unsigned values = fl->normals ? 6 : 3;
    /* the colour words after x y z [normal]: none, or 3 or 4 with C */
    const unsigned ncol = L.vwords - base;
    int ints = 0;
    float scale = 1.0f;
    uint32_t translucent = 0;
    if (ncol >= 3) {
        scale = offb_color_scale(p, nv, vstride, values, ncol, big, &ints);
        if ((r = mts__raw_enable_colors(raw, err)) != MTS_OK)
            return r;
    }
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
        if (ncol < 3)
            continue;
        float c[4];
        for (unsigned k = 0; k < ncol; k++) {
            uint32_t w = offb_u32(p + 4 * (values + k), big);
            if (ints) {
                c[k] = (float)w;
                continue;
            }
            memcpy(&c[k], &w, sizeof w);
            if (!isfinite(c[k]))
                return mts_error_set(err, MTS_ERR_FORMAT,
                                     "%s: vertex %u: a colour value is not a finite number", name,
                                     i);
        }
        for (unsigned k = 0; k < 3; k++)
            raw->colors[(size_t)i * 3 + k] = c[k] / scale;
        if (ncol == 4)
            translucent += c[3] < scale;
    }
    raw->vertex_count = nv;
    if (ncol == 4) {
        st->colors_alpha = 1;
        st->colors_translucent = translucent;
    }
    st->file_vertices = nv;

    /* the walk counted the triangles; otherwise reserve what the bytes left
     * could hold (16 per triangle) and grow from there */
    size_t left = (size_t)(end - p);
    uint64_t want = exact ? tris : (nf < left / 16 + 1 ? nf : left / 16 + 1);
    if ((r = mts__raw_reserve_triangles(raw, want, err)) != MTS_OK)
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
        mts__fan poly = {0, 0, 0};
        for (int32_t c = 0; c < n; c++, p += 4) {
            int32_t idx = (int32_t)offb_u32(p, big);
            if (idx < 0 || (uint32_t)idx >= nv)
                return mts_error_set(err, MTS_ERR_RANGE,
                                     "%s: face %u: vertex index %d out of range (%u vertices)",
                                     name, f, idx, nv);
            if ((r = mts__fan_add(raw, &poly, (uint32_t)idx, err)) != MTS_OK)
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
        if ((r = mts__fan_end(raw, &poly, err)) != MTS_OK)
            return r;
    }
    return MTS_OK;
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
static mts_result off_vertex_color(mts__text *t, mts__mesh_raw *raw, const mts__off_flags *fl,
                                   uint32_t i, off_color_scan *oc, mts_error *err)
{
    float x[8];
    unsigned n = 0;
    for (;;) {
        mts__text_blank(t);
        if (mts__text_eol(t) || n == 8)
            break;
        int got = mts__text_color_value(t, i, &x[n], err);
        if (got < 0)
            return MTS_ERR_FORMAT;
        if (got == 0)
            return MTS_OK;
        n++;
    }
    unsigned nc = fl->texcoords && n >= 2 ? n - 2 : n;
    if (nc != 3 && nc != 4)
        return MTS_OK;
    mts_result r = mts__raw_enable_colors(raw, err);
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
    mts__text t = {data + mts__bom_length(data, size), data + size, 1, 1, raw->name};
    mts_mesh_stats *st = raw->stats;
    st->format = MTS_MESH_OFF;

    mts__text_space(&t);
    const char *w;
    size_t wn = mts__text_word(&t, &w);
    mts__off_flags fl;
    size_t k;
    mts_result r0 = mts__off_check_keyword(t.name, data, size, w, wn, &fl, &k, err);
    if (r0 != MTS_OK)
        return r0;
    const int normals = fl.normals;
    if (k < wn)
        t.p = w + k;
    if (fl.four)
        return mts_error_set(err, MTS_ERR_VERSION, "%s: 4D OFF is not supported", t.name);
    mts__text_blank(&t);
    if (t.end - t.p >= 6 && memcmp(t.p, "BINARY", 6) == 0 && mts__token_ends(&t, t.p + 6)) {
        if (fl.ndim)
            return mts_error_set(err, MTS_ERR_VERSION, "%s: binary nOFF is not supported",
                                 t.name);
        /* the binary data starts right after the newline that ends the
         * header line; blanks and a comment may come before it */
        t.p += 6;
        mts__text_blank(&t);
        if (mts__text_eof(&t))
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
    mts__text_next_line(&t); /* the edge count, which nobody uses */

    /* Reserve only what the remaining bytes can hold ("x y z" is at least 5
     * bytes, a face at least 2): the counts are claims, not facts. */
    size_t left = (size_t)(t.end - t.p);
    uint64_t want_v = nv < left / 5 + 1 ? nv : left / 5 + 1;
    uint64_t want_f = nf < left / 2 + 1 ? nf : left / 2 + 1;
    if ((r = mts__raw_reserve_vertices(raw, want_v, normals, err)) != MTS_OK ||
        (r = mts__raw_reserve_triangles(raw, want_f, err)) != MTS_OK)
        return r;

    const unsigned values = normals ? 6 : 3;
    off_color_scan oc = {0, 1, 0, 0};
    for (uint32_t i = 0; i < nv; i++) {
        mts__text_space(&t);
        if (mts__text_eof(&t))
            return off_truncated(&t, "vertices", nv, i, err);
        if ((r = mts__raw_reserve_vertices(raw, (uint64_t)i + 1, normals, err)) != MTS_OK)
            return r;
        float v[6];
        for (unsigned c = 0; c < values; c++) {
            mts__text_blank(&t);
            if (mts__text_eof(&t))
                return off_truncated(&t, "vertices", nv, i, err);
            if (mts__text_eol(&t))
                return mts_error_set(err, MTS_ERR_FORMAT,
                                     "%s: line %llu: vertex %u has %u values, expected %u",
                                     t.name, (unsigned long long)t.line, i, c, values);
            if ((r = mts__text_float(&t, &v[c], err)) != MTS_OK)
                return r;
        }
        memcpy(raw->positions + (size_t)i * 3, v, 3 * sizeof *v);
        if (normals)
            memcpy(raw->normals + (size_t)i * 3, v + 3, 3 * sizeof *v);
        raw->vertex_count = i + 1;
        if (fl.colors && (r = off_vertex_color(&t, raw, &fl, i, &oc, err)) != MTS_OK)
            return r;
        mts__text_next_line(&t); /* texture coordinates */
    }
    st->file_vertices = nv;
    if (fl.colors)
        off_colors_scale(raw, &oc);

    for (uint32_t f = 0; f < nf; f++) {
        mts__text_space(&t);
        if (mts__text_eof(&t))
            return off_truncated(&t, "faces", nf, f, err);
        int64_t n;
        if ((r = mts__text_int(&t, &n, err)) != MTS_OK)
            return r;
        if (n < 0 || n > (int64_t)MTS__MESH_MAX_COUNT)
            return mts_error_set(err, MTS_ERR_FORMAT, "%s: line %llu: face %u has %lld corners",
                                 t.name, (unsigned long long)t.line, f, (long long)n);
        mts__fan poly = {0, 0, 0};
        for (int64_t c = 0; c < n; c++) {
            mts__text_blank(&t);
            if (mts__text_eof(&t))
                return off_truncated(&t, "faces", nf, f, err);
            if (mts__text_eol(&t))
                return mts_error_set(err, MTS_ERR_FORMAT,
                                     "%s: line %llu: face %u has %lld indices, expected %lld",
                                     t.name, (unsigned long long)t.line, f, (long long)c,
                                     (long long)n);
            int64_t idx;
            if ((r = mts__text_int(&t, &idx, err)) != MTS_OK)
                return r;
            if (idx < 0 || idx >= nv)
                return mts_error_set(err, MTS_ERR_RANGE,
                                     "%s: line %llu: face %u: vertex index %lld out of range "
                                     "(%u vertices)",
                                     t.name, (unsigned long long)t.line, f, (long long)idx, nv);
            if ((r = mts__fan_add(raw, &poly, (uint32_t)idx, err)) != MTS_OK)
                return r;
        }
        if ((r = mts__fan_end(raw, &poly, err)) != MTS_OK)
            return r;
        mts__text_next_line(&t); /* a face colour */
    }
    return MTS_OK;
}
