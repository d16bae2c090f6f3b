/* The OBJ parser: v (with the common r g b [a] colour extension), vn, vt and
 * f lines; everything else is skipped. */
#include "mesh_read_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

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

static mts_result obj_floats(mts__text *t, float *v, unsigned n, const char *what, mts_error *err)
{
    for (unsigned c = 0; c < n; c++) {
        mts__text_blank(t);
        if (mts__text_eol(t))
            return mts_error_set(err, MTS_ERR_FORMAT,
                                 "%s: %sline %llu: '%s' has %u values, expected %u", t->name,
                                 mts__text_eof(t) ? "truncated at " : "",
                                 (unsigned long long)t->line, what, c, n);
        mts_result r = mts__text_float(t, &v[c], err);
        if (r != MTS_OK)
            return r;
    }
    return MTS_OK;
}

static mts_result obj_index(mts__text *t, int64_t *out, mts_error *err)
{
    const char *s = t->p;
    if (mts__scan_int(&s, t->end, out) != 0 || !(mts__token_ends(t, s) || *s == '/'))
        return mts__text_bad_number(t, err);
    t->p = s;
    return MTS_OK;
}

static mts_result obj_range(const mts__text *t, const char *what, int64_t idx, uint32_t count,
                            mts_error *err)
{
    return mts_error_set(err, MTS_ERR_RANGE, "%s: line %llu: %s index %lld out of range (%u defined)",
                         t->name, (unsigned long long)t->line, what, (long long)idx, count);
}

/* OBJ has no magic, and its reader skips the lines it does not know, so
 * without this a file of anything would be read to its end for nothing
 * (and UTF-16 text would end in "no triangles"): an OBJ file is text, and a
 * NUL byte says this one is not. */
mts_result mts__obj_check_text(const char *name, const char *data, size_t size, mts_error *err)
{
    return mts__text_refuse(name, data, size, "an OBJ", "ASCII OBJ", "", err);
}

mts_result mts__mesh_read_obj(mts__mesh_raw *raw, const char *data, size_t size, mts_error *err)
{
    mts__text t = {data + mts__bom_length(data, size), data + size, 1, 1, raw->name};
    mts_mesh_stats *st = raw->stats;
    st->format = MTS_MESH_OBJ;
    mts_result r = mts__obj_check_text(raw->name, data, size, err);
    if (r != MTS_OK)
        return r;
    float *vn = NULL; /* unit normals of the vn lines, 3 each */
    uint32_t vn_count = 0, vn_capacity = 0, vt_count = 0;
    int every_corner_has_vn = 1;

    while (!mts__text_eof(&t)) {
        mts__text_blank(&t);
        const char *w;
        size_t wn = mts__text_word(&t, &w);
        if (mts__word_is(w, wn, "v")) {
            uint32_t i = raw->vertex_count;
            if ((r = mts__raw_reserve_vertices(raw, (uint64_t)i + 1, 1, err)) != MTS_OK ||
                (r = obj_floats(&t, raw->positions + (size_t)i * 3, 3, "v", err)) != MTS_OK)
                goto done;
            raw->vertex_count = i + 1;
            /* after x y z: nothing, w (rational curves' weight, no colour),
             * or the common extension r g b in 0..1 (MeshLab, ZBrush,
             * Blender), which some write with a fourth, alpha */
            float x[5];
            unsigned n = 0;
            for (;;) {
                mts__text_blank(&t);
                if (mts__text_eol(&t) || n == 5)
                    break;
                int got = mts__text_color_value(&t, i, &x[n], err);
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
                if ((r = mts__raw_enable_colors(raw, err)) != MTS_OK)
                    goto done;
                const double rgb[3] = {x[0], x[1], x[2]};
                mts__raw_set_color(raw, i, rgb, n == 4 ? fmax(0.0, x[3]) : -1.0, 1.0);
            }
        } else if (mts__word_is(w, wn, "vn")) {
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
        } else if (mts__word_is(w, wn, "vt")) {
            if (vt_count < MTS__MESH_MAX_COUNT)
                vt_count++;
        } else if (mts__word_is(w, wn, "f")) {
            mts__fan poly = {0, 0, 0};
            for (;;) {
                mts__text_blank(&t);
                if (mts__text_eol(&t))
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
                if (!mts__token_ends(&t, t.p)) {
                    r = mts__text_bad_number(&t, err);
                    goto done;
                }
                every_corner_has_vn &= in != 0;
                if ((r = mts__fan_add(raw, &poly, (uint32_t)rv, err)) != MTS_OK)
                    goto done;
            }
            if ((r = mts__fan_end(raw, &poly, err)) != MTS_OK)
                goto done;
        } else if (mts__word_is(w, wn, "p") || mts__word_is(w, wn, "l")) {
            /* no surface, but named if nothing else is there */
            uint32_t *n = w[0] == 'p' ? &raw->obj_points : &raw->obj_lines;
            *n += *n < UINT32_MAX;
        }
        /* anything else (vt values, g, o, s, usemtl, mtllib, comments) does
         * not shape the surface */
        mts__text_next_line(&t);
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
