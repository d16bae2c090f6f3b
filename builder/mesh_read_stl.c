/* The STL parser: ASCII and binary, with the corners of every facet welded
 * into shared vertices. */
#include "mesh_read_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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
mts_result mts__stl_binary_count(const char *name, const unsigned char *head, size_t head_size,
                                 uint64_t size, uint32_t *count, mts_error *err)
{
    *count = mts__le32(head + 80);
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
    mts_result r = mts__stl_binary_count(raw->name, b, size, size, &count, err);
    if (r != MTS_OK)
        return r;
    if ((r = mts__raw_reserve_vertices(raw, (uint64_t)count * 3, 0, err)) != MTS_OK ||
        (r = mts__raw_reserve_triangles(raw, count, err)) != MTS_OK)
        return r;
    for (uint32_t f = 0; f < count; f++) {
        const unsigned char *rec = b + 84 + (size_t)f * 50 + 12; /* past the facet normal */
        float *p = raw->positions + (size_t)f * 9;
        for (int k = 0; k < 9; k++) {
            uint32_t u = mts__le32(rec + 4 * k);
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
static mts_result stl_unexpected(const mts__text *t, const char *kw, const char *w, size_t n,
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
static mts_result stl_expect(mts__text *t, const char *kw, uint32_t facet, mts_error *err)
{
    mts__text_space(t);
    if (mts__text_eof(t))
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "%s: truncated: the file ends inside facet %u (expected '%s')", t->name,
                             facet, kw);
    const char *w;
    size_t n = mts__text_word(t, &w);
    if (!mts__word_is(w, n, kw))
        return stl_unexpected(t, kw, w, n, facet, err);
    return MTS_OK;
}

static mts_result stl_floats(mts__text *t, float *v, uint32_t facet, mts_error *err)
{
    for (int c = 0; c < 3; c++) {
        mts__text_space(t);
        if (mts__text_eof(t))
            return mts_error_set(err, MTS_ERR_FORMAT, "%s: truncated: the file ends inside facet %u",
                                 t->name, facet);
        mts_result r = mts__text_float(t, &v[c], err);
        if (r != MTS_OK)
            return r;
    }
    return MTS_OK;
}

static mts_result stl_ascii(mts__mesh_raw *raw, const char *data, size_t size, mts_error *err)
{
    mts__text t = {data, data + size, 1, 0, raw->name};
    mts_result r;
    uint32_t facet = 0;
    if ((r = stl_expect(&t, "solid", 0, err)) != MTS_OK)
        return r;
    mts__text_next_line(&t); /* the solid's name */
    for (;;) {
        mts__text_space(&t);
        if (mts__text_eof(&t))
            return mts_error_set(err, MTS_ERR_FORMAT, "%s: truncated: no 'endsolid' after %u facets",
                                 t.name, facet);
        const char *w;
        size_t n = mts__text_word(&t, &w);
        if (mts__word_is(w, n, "endsolid")) {
            mts__text_next_line(&t);
            mts__text_space(&t);
            if (mts__text_eof(&t))
                break;
            /* several solids in one file */
            if ((r = stl_expect(&t, "solid", facet, err)) != MTS_OK)
                return r;
            mts__text_next_line(&t);
            continue;
        }
        if (!mts__word_is(w, n, "facet"))
            return stl_unexpected(&t, n > 0 && w[0] == 'e' ? "endsolid" : "facet", w, n, facet,
                                  err);
        float normal[3];
        if ((r = stl_expect(&t, "normal", facet, err)) != MTS_OK ||
            (r = stl_floats(&t, normal, facet, err)) != MTS_OK ||
            (r = stl_expect(&t, "outer", facet, err)) != MTS_OK ||
            (r = stl_expect(&t, "loop", facet, err)) != MTS_OK)
            return r;
        mts__fan poly = {0, 0, 0};
        for (;;) {
            mts__text_space(&t);
            if (mts__text_eof(&t))
                return mts_error_set(err, MTS_ERR_FORMAT,
                                     "%s: truncated: the file ends inside facet %u", t.name, facet);
            n = mts__text_word(&t, &w);
            if (mts__word_is(w, n, "endloop"))
                break;
            if (!mts__word_is(w, n, "vertex"))
                return stl_unexpected(&t, n > 0 && w[0] == 'e' ? "endloop" : "vertex", w, n,
                                      facet, err);
            uint32_t v = raw->vertex_count;
            if ((r = mts__raw_reserve_vertices(raw, (uint64_t)v + 1, 0, err)) != MTS_OK ||
                (r = stl_floats(&t, raw->positions + (size_t)v * 3, facet, err)) != MTS_OK)
                return r;
            raw->vertex_count = v + 1;
            if ((r = mts__fan_add(raw, &poly, v, err)) != MTS_OK)
                return r;
        }
        if ((r = stl_expect(&t, "endfacet", facet, err)) != MTS_OK ||
            (r = mts__fan_end(raw, &poly, err)) != MTS_OK)
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
    if (size >= 84 && 84 + (uint64_t)mts__le32((const unsigned char *)data + 80) * 50 == size)
        return 1;
    size_t i = 0;
    while (i < size && mts__is_space(data[i]))
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
