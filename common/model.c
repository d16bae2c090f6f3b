#include "model.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "lod.h"

void mts_model_free(mts_model *m)
{
    if (!m)
        return;
    mts_bigmem_release(&m->capacity_mem, m->capacity);
    mts_bigmem_release(&m->positions_mem, m->positions);
    mts_bigmem_release(&m->normals_mem, m->normals);
    mts_bigmem_release(&m->colors_mem, m->colors);
    mts_bigmem_release(&m->parents_mem, m->parents);
    mts_strips_free(&m->full);
    mts_strips_free(&m->base);
    mts_bigmem_release(&m->offsets_mem, m->record_offsets);
    mts_bigmem_release(&m->record_mem, m->record_data);
    free(m->level_triangles);
    free(m->level_strips);
    free(m->level_indices);
    free(m->key_levels);
    free(m->growth_offsets);
    free(m->growth_data);
    memset(m, 0, sizeof *m);
}

static mts_result check_strips(const mts_strips *st, const char *name, uint32_t strip_count,
                               uint32_t vertex_limit, mts_error *err)
{
    if (st->strip_count != strip_count)
        return mts_error_set(err, MTS_ERR_FORMAT, "%s strips: %u strips, expected %u", name,
                             st->strip_count, strip_count);
    if (st->offsets[0] != 0)
        return mts_error_set(err, MTS_ERR_FORMAT, "%s strips: first offset is not 0", name);
    for (uint32_t s = 0; s < strip_count; s++) {
        if (st->offsets[s + 1] < st->offsets[s])
            return mts_error_set(err, MTS_ERR_FORMAT, "%s strips: strip %u has a negative length",
                                 name, s);
    }
    if (st->offsets[strip_count] != st->index_count)
        return mts_error_set(err, MTS_ERR_FORMAT, "%s strips: offsets end at %u, %u indices",
                             name, st->offsets[strip_count], st->index_count);
    for (uint32_t i = 0; i < st->index_count; i++) {
        if (st->indices[i] >= vertex_limit)
            return mts_error_set(err, MTS_ERR_RANGE,
                                 "%s strips: index %u at position %u is out of range (%u vertices)",
                                 name, st->indices[i], i, vertex_limit);
    }
    return MTS_OK;
}

static uint32_t strip_triangles(const uint32_t *s, uint32_t n)
{
    uint32_t t = 0;
    for (uint32_t k = 0; k + 2 < n; k++)
        t += s[k] != s[k + 1] && s[k + 1] != s[k + 2] && s[k] != s[k + 2];
    return t;
}

mts_result mts_model_validate(const mts_model *m, mts_error *err)
{
    mts_result rc;
    const uint32_t n = m->level_count;
    if (m->vertex_count == 0 || n >= m->vertex_count ||
        m->base_vertex_count != m->vertex_count - n)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "model: %u vertices, %u base vertices and %u levels do not add up",
                             m->vertex_count, m->base_vertex_count, n);
    /* The box is the quantization grid's extent (docs/architecture.md, "The stream"): it
     * must be finite and hold every position, or quantized values leave
     * their range. */
    for (int a = 0; a < 3; a++) {
        if (!isfinite(m->bbox_min[a]) || !isfinite(m->bbox_max[a]) ||
            !(m->bbox_min[a] <= m->bbox_max[a]))
            return mts_error_set(err, MTS_ERR_FORMAT, "model: the bounding box is not finite");
    }
    /* the flag is what a stream and a renderer read: it must not claim
     * colours that are not there, nor hide ones that are */
    if (!(m->flags & MTS_MODEL_COLORS) != !m->colors)
        return mts_error_set(err, MTS_ERR_FORMAT, "model: %s",
                             m->colors ? "colours without the colours flag"
                                       : "the colours flag without colours");
    for (uint64_t i = 0; i < 3 * (uint64_t)m->vertex_count; i++) {
        if (!isfinite(m->positions[i]) || !isfinite(m->normals[i]))
            return mts_error_set(err, MTS_ERR_FORMAT, "model: vertex %llu is not a finite number",
                                 (unsigned long long)(i / 3));
        if (m->positions[i] < m->bbox_min[i % 3] || m->positions[i] > m->bbox_max[i % 3])
            return mts_error_set(err, MTS_ERR_FORMAT,
                                 "model: vertex %llu lies outside the bounding box",
                                 (unsigned long long)(i / 3));
    }
    if ((rc = check_strips(&m->full, "full", m->strip_count, m->vertex_count, err)) != MTS_OK)
        return rc;
    if ((rc = check_strips(&m->base, "base", m->strip_count, m->base_vertex_count, err)) != MTS_OK)
        return rc;
    /* Capacities are the slots a runtime reserves. The replay below checks
     * that no split grows a strip past its capacity; here, that both ends
     * fit, and that the slots together are no bigger than a strip set can
     * ever be: a slot grows only by what records insert, so the base
     * indices plus every record word bound them (and keep a runtime's
     * allocation as small as the model). */
    if (m->strip_count > 0 && !m->capacity)
        return mts_error_set(err, MTS_ERR_FORMAT, "model: the strip capacities are missing");
    uint64_t capacity_total = 0;
    for (uint32_t s = 0; s < m->strip_count; s++) {
        uint32_t blen = m->base.offsets[s + 1] - m->base.offsets[s];
        uint32_t flen = m->full.offsets[s + 1] - m->full.offsets[s];
        if (blen > m->capacity[s] || flen > m->capacity[s])
            return mts_error_set(err, MTS_ERR_RANGE,
                                 "model: strip %u is %u long at the base and %u at the full "
                                 "level, past its capacity %u",
                                 s, blen, flen, m->capacity[s]);
        capacity_total += m->capacity[s];
    }
    if (capacity_total > (uint64_t)m->base.index_count + m->record_word_count)
        return mts_error_set(err, MTS_ERR_RANGE,
                             "model: strip capacities add up to %llu, more than the %u base "
                             "indices and %u record words could ever fill",
                             (unsigned long long)capacity_total, m->base.index_count,
                             m->record_word_count);
    for (uint32_t j = 0; j < n; j++) {
        if (m->parents[j] >= m->base_vertex_count + j)
            return mts_error_set(err, MTS_ERR_RANGE,
                                 "model: split %u has parent %u, not older than its vertex %u", j,
                                 m->parents[j], m->base_vertex_count + j);
    }
    if (m->record_offsets[0] != 0 || m->record_offsets[n] != m->record_word_count)
        return mts_error_set(err, MTS_ERR_FORMAT, "model: record offsets do not span the records");
    for (uint32_t j = 0; j < n; j++) {
        if (m->record_offsets[j + 1] <= m->record_offsets[j])
            return mts_error_set(err, MTS_ERR_FORMAT, "model: record %u has no words", j);
    }

    /* Replay every split, checked, and hold the per-level counts against it. */
    mts_lod lod;
    if ((rc = mts_lod_init(&lod, m, MTS_LOD_AT_BASE, err)) != MTS_OK)
        return rc;
    uint32_t *tri = malloc(((size_t)m->strip_count + 1) * sizeof *tri);
    uint32_t *seen_len = malloc(((size_t)m->strip_count + 1) * sizeof *seen_len);
    if (!tri || !seen_len) {
        free(tri);
        free(seen_len);
        mts_lod_free(&lod);
        return mts_error_set(err, MTS_ERR_NOMEM, "model: out of memory validating");
    }
    uint64_t triangles = 0, indices = 0;
    uint32_t strips = 0;
    for (uint32_t s = 0; s < m->strip_count; s++) {
        uint32_t len;
        const uint32_t *str = mts_lod_strip(&lod, s, &len);
        tri[s] = strip_triangles(str, len);
        seen_len[s] = len;
        triangles += tri[s];
        indices += len;
        strips += len > 0;
    }
    mts_lod_clear_changed(&lod);
    for (uint32_t l = 0;; l++) {
        if (triangles != m->level_triangles[l] || strips != m->level_strips[l] ||
            indices != m->level_indices[l]) {
            rc = mts_error_set(err, MTS_ERR_FORMAT,
                               "model: level %u has %llu triangles / %u strips / %llu indices, "
                               "the level table says %u / %u / %u",
                               l, (unsigned long long)triangles, strips,
                               (unsigned long long)indices, m->level_triangles[l],
                               m->level_strips[l], m->level_indices[l]);
            goto done;
        }
        if (l == n)
            break;
        if ((rc = mts_lod_split(&lod, err)) != MTS_OK)
            goto done;
        uint32_t nc;
        const uint32_t *changed = mts_lod_changed(&lod, &nc);
        for (uint32_t c = 0; c < nc; c++) {
            uint32_t s = changed[c], len;
            const uint32_t *str = mts_lod_strip(&lod, s, &len);
            uint32_t t = strip_triangles(str, len);
            triangles = triangles - tri[s] + t;
            tri[s] = t;
            indices = indices - seen_len[s] + len;
            strips = strips - (seen_len[s] > 0) + (len > 0);
            seen_len[s] = len;
        }
        mts_lod_clear_changed(&lod);
    }
    for (uint32_t s = 0; s < m->strip_count; s++) {
        uint32_t len;
        const uint32_t *str = mts_lod_strip(&lod, s, &len);
        uint32_t flen = m->full.offsets[s + 1] - m->full.offsets[s];
        if (len != flen || memcmp(str, m->full.indices + m->full.offsets[s], (size_t)len * 4) != 0) {
            rc = mts_error_set(err, MTS_ERR_FORMAT,
                               "model: strip %u after every split differs from the full strips", s);
            goto done;
        }
    }
    rc = MTS_OK;
done:
    free(tri);
    free(seen_len);
    mts_lod_free(&lod);
    return rc;
}

uint32_t mts_model_level_for_triangles(const mts_model *m, uint64_t triangles)
{
    uint32_t lo = 0, hi = m->level_count;
    if (m->level_triangles[0] > triangles)
        return 0;
    while (lo < hi) { /* largest level with at most that many triangles */
        uint32_t mid = lo + (hi - lo + 1) / 2;
        if (m->level_triangles[mid] <= triangles)
            lo = mid;
        else
            hi = mid - 1;
    }
    return lo;
}

uint32_t mts_model_level_for_fraction(const mts_model *m, double fraction)
{
    if (!(fraction > 0))
        return 0;
    if (fraction >= 1)
        return m->level_count;
    double vertices = fraction * m->vertex_count + 0.5;
    if (vertices <= m->base_vertex_count)
        return 0;
    uint64_t l = (uint64_t)vertices - m->base_vertex_count;
    return l > m->level_count ? m->level_count : (uint32_t)l;
}

uint64_t mts_model_memory_bytes(const mts_model *m)
{
    uint64_t n = m->level_count;
    return (uint64_t)m->vertex_count * (m->colors ? 27 : 24) + n * 4 + (n + 1) * 4 * 4 +
           (uint64_t)m->strip_count * 4 +
           (uint64_t)m->record_word_count * 4 + ((uint64_t)m->strip_count + 1) * 8 +
           ((uint64_t)m->full.index_count + m->base.index_count) * 4;
}
