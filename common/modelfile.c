#include "modelfile.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "crc32c.h"
#include "fileio.h"
#include "reccodec.h"
#include "varint.h"

enum {
    SEC_INFO = 1,
    SEC_POSITIONS,
    SEC_NORMALS,
    SEC_STRIPS_FULL,
    SEC_STRIPS_BASE,
    SEC_SPLITS,
    SEC_LEVELS,
    SEC_SOURCE,
    SEC_CAPACITY, /* version 2 */
    SEC_GROWTH,   /* version 3 */
    SEC_KEY,      /* version 5.1 */
    SEC_COLORS,   /* version 5.2, only in a model with colours */
    SEC_LAST = SEC_COLORS
};

static const char *const section_names[] = {"?",           "info",   "positions",
                                            "normals",     "full strips",
                                            "base strips", "splits", "levels",
                                            "source",      "capacity",
                                            "growth",      "build key",
                                            "colors"};

#define HEADER_SIZE 16u
#define ENTRY_SIZE 24u
#define MAX_SECTIONS 64u
#define INFO_SIZE 60u

static void put_u16(uint8_t *p, uint16_t x)
{
    p[0] = (uint8_t)x;
    p[1] = (uint8_t)(x >> 8);
}

static void put_u32(uint8_t *p, uint32_t x)
{
    for (int i = 0; i < 4; i++)
        p[i] = (uint8_t)(x >> (8 * i));
}

static void put_u64(uint8_t *p, uint64_t x)
{
    for (int i = 0; i < 8; i++)
        p[i] = (uint8_t)(x >> (8 * i));
}

static uint16_t get_u16(const uint8_t *p)
{
    return (uint16_t)(p[0] | p[1] << 8);
}

static uint32_t get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static uint64_t get_u64(const uint8_t *p)
{
    return (uint64_t)get_u32(p) | (uint64_t)get_u32(p + 4) << 32;
}

static void put_u32s(uint8_t *p, const uint32_t *x, size_t n)
{
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
    memcpy(p, x, n * 4);
#else
    for (size_t i = 0; i < n; i++)
        put_u32(p + 4 * i, x[i]);
#endif
}

static void get_u32s(uint32_t *x, const uint8_t *p, size_t n)
{
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
    memcpy(x, p, n * 4);
#else
    for (size_t i = 0; i < n; i++)
        x[i] = get_u32(p + 4 * i);
#endif
}

/* floats travel as their IEEE-754 bit patterns */
static void put_f32s(uint8_t *p, const float *x, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        uint32_t b;
        memcpy(&b, &x[i], 4);
        put_u32(p + 4 * i, b);
    }
}

static void get_f32s(float *x, const uint8_t *p, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        uint32_t b = get_u32(p + 4 * i);
        memcpy(&x[i], &b, 4);
    }
}

static uint64_t align8(uint64_t x)
{
    return (x + 7) & ~(uint64_t)7;
}

/* Section sizes: fixed-size sections from the INFO counts (64-bit: no
 * overflow); the varint sections (splits, levels) and source are whatever
 * they are, and their parse must end exactly at their end. */
typedef struct layout {
    uint32_t vertices, base_vertices, levels, strips, full_indices, base_indices, record_words,
        capacity_total;
    uint64_t size[SEC_LAST + 1];
} layout;

static void layout_sizes(layout *l)
{
    l->size[SEC_INFO] = INFO_SIZE;
    l->size[SEC_POSITIONS] = 12ull * l->vertices;
    l->size[SEC_NORMALS] = 12ull * l->vertices;
    l->size[SEC_STRIPS_FULL] = 4ull * l->strips + 4ull * l->full_indices;
    l->size[SEC_STRIPS_BASE] = 4ull * l->strips + 4ull * l->base_indices;
    l->size[SEC_CAPACITY] = 4ull * l->strips;
    l->size[SEC_COLORS] = 3ull * l->vertices;
}

static int fixed_size(uint32_t id)
{
    return id != SEC_SPLITS && id != SEC_LEVELS && id != SEC_SOURCE && id != SEC_GROWTH &&
           id != SEC_KEY;
}

/* Per-level counts change by a little from one level to the next. */
static size_t levels_encode(const mts_model *m, uint8_t *out)
{
    uint8_t *o = out;
    uint32_t t = 0, s = 0, i = 0;
    for (uint32_t l = 0; l <= m->level_count; l++) {
        o += mts_varint_put(o, mts_zigzag_u32(m->level_triangles[l] - t));
        o += mts_varint_put(o, mts_zigzag_u32(m->level_strips[l] - s));
        o += mts_varint_put(o, mts_zigzag_u32(m->level_indices[l] - i));
        t = m->level_triangles[l];
        s = m->level_strips[l];
        i = m->level_indices[l];
    }
    return (size_t)(o - out);
}

static int levels_decode(const uint8_t *p, const uint8_t *end, mts_model *m)
{
    uint32_t t = 0, s = 0, i = 0;
    for (uint32_t l = 0; l <= m->level_count; l++) {
        uint32_t dt, ds, di;
        if (!mts_varint_get(&p, end, &dt) || !mts_varint_get(&p, end, &ds) ||
            !mts_varint_get(&p, end, &di))
            return 0;
        t += mts_unzigzag_u32(dt);
        s += mts_unzigzag_u32(ds);
        i += mts_unzigzag_u32(di);
        m->level_triangles[l] = t;
        m->level_strips[l] = s;
        m->level_indices[l] = i;
    }
    return p == end;
}

/* Key levels as deltas, then per split its description (model.h), every
 * value a varint: mostly 3 bytes a split. */
static size_t growth_bound(const mts_model *m)
{
    return ((size_t)m->key_count + 1 + m->growth_word_count) * MTS_VARINT32_MAX_BYTES;
}

static size_t growth_encode(const mts_model *m, uint8_t *out)
{
    uint8_t *o = out;
    o += mts_varint_put(o, m->key_count);
    uint32_t prev = 0;
    for (uint32_t k = 0; k < m->key_count; k++) {
        o += mts_varint_put(o, m->key_levels[k] - prev);
        prev = m->key_levels[k];
    }
    for (uint32_t i = 0; i < m->growth_word_count; i++)
        o += mts_varint_put(o, m->growth_data[i]);
    return (size_t)(o - out);
}

/* Fills key_levels, growth_offsets and growth_data (room for `room` words);
 * returns 0 unless the section holds exactly the model's splits. */
static int growth_decode(const uint8_t *p, const uint8_t *end, mts_model *m, size_t room)
{
    uint32_t kc;
    if (!mts_varint_get(&p, end, &kc) || kc > (size_t)(end - p) || kc >= m->level_count + 1u)
        return 0;
    m->key_levels = malloc(((size_t)kc + 1) * 4);
    if (!m->key_levels)
        return 0;
    m->key_count = kc;
    uint64_t level = 0;
    for (uint32_t k = 0; k < kc; k++) {
        uint32_t d;
        if (!mts_varint_get(&p, end, &d) || d == 0)
            return 0;
        level += d;
        if (level >= m->level_count)
            return 0;
        m->key_levels[k] = (uint32_t)level;
    }
    size_t w = 0;
    for (uint32_t j = 0; j < m->level_count; j++) {
        m->growth_offsets[j] = (uint32_t)w;
        uint32_t head[3];
        for (int i = 0; i < 3; i++) {
            if (w >= room || !mts_varint_get(&p, end, &head[i]))
                return 0;
            m->growth_data[w++] = head[i];
        }
        if (head[2] != MTS_GROWTH_EXPLICIT)
            continue;
        uint32_t moved, born;
        if (w + 2 > room || !mts_varint_get(&p, end, &moved) || !mts_varint_get(&p, end, &born))
            return 0;
        m->growth_data[w++] = moved;
        m->growth_data[w++] = born;
        uint64_t more = (uint64_t)moved + 3ull * born;
        if (more > room - w)
            return 0;
        for (uint64_t i = 0; i < more; i++) {
            if (!mts_varint_get(&p, end, &m->growth_data[w++]))
                return 0;
        }
    }
    m->growth_offsets[m->level_count] = (uint32_t)w;
    m->growth_word_count = (uint32_t)w;
    return p == end;
}

static void put_strips(uint8_t *p, const mts_strips *st)
{
    for (uint32_t s = 0; s < st->strip_count; s++)
        put_u32(p + 4 * (size_t)s, st->offsets[s + 1] - st->offsets[s]);
    put_u32s(p + 4 * (size_t)st->strip_count, st->indices, st->index_count);
}

mts_result mts_modelfile_encode(const mts_model *m, uint8_t **out, size_t *out_size,
                                mts_error *err)
{
    if (m->strip_count > 0 && !m->capacity)
        return mts_error_set(err, MTS_ERR_ARG, "the model has no strip capacities");
    uint64_t capacity_total = 0;
    for (uint32_t s = 0; s < m->strip_count; s++)
        capacity_total += m->capacity[s];
    if (capacity_total > UINT32_MAX)
        return mts_error_set(err, MTS_ERR_LIMIT, "strip capacities add up to %llu indices",
                             (unsigned long long)capacity_total);
    layout l = {m->vertex_count, m->base_vertex_count, m->level_count, m->strip_count,
                m->full.index_count, m->base.index_count, m->record_word_count,
                (uint32_t)capacity_total, {0}};
    layout_sizes(&l);
    size_t source_len = strnlen(m->source, sizeof m->source);
    size_t key_len = strnlen(m->build_key, sizeof m->build_key);
    size_t splits_cap = mts_reccodec_bound(m, 0, m->level_count);
    size_t levels_cap = ((size_t)m->level_count + 1) * 3 * MTS_VARINT32_MAX_BYTES;
    uint8_t *splits = malloc(splits_cap + 1), *levels = malloc(levels_cap);
    if (!splits || !levels) {
        free(splits);
        free(levels);
        return mts_error_set(err, MTS_ERR_NOMEM, "out of memory encoding the records");
    }
    /* a model made by hand (tests) may lack descriptions: no growth section */
    const int has_growth = m->growth_data && m->growth_offsets && (!m->key_count || m->key_levels);
    uint8_t *growth = malloc(has_growth ? growth_bound(m) : 1);
    if (!growth) {
        free(splits);
        free(levels);
        return mts_error_set(err, MTS_ERR_NOMEM, "out of memory encoding the splits");
    }
    l.size[SEC_GROWTH] = has_growth ? growth_encode(m, growth) : 0;
    size_t splits_len = 0;
    mts_result rc = mts_reccodec_encode(m, 0, m->level_count, splits, splits_cap, &splits_len, err);
    if (rc != MTS_OK) {
        free(splits);
        free(levels);
        free(growth);
        return rc;
    }
    l.size[SEC_SPLITS] = splits_len;
    l.size[SEC_LEVELS] = levels_encode(m, levels);
    l.size[SEC_SOURCE] = source_len;
    l.size[SEC_KEY] = key_len;

    /* The sections in id order: a model without growth (made by hand) is
     * written without growth and the build key, one without colours
     * without the colour section, so that its file is byte for byte what
     * version 5.1 wrote. */
    const int has_colors = (m->flags & MTS_MODEL_COLORS) != 0;
    if (has_colors && !m->colors) {
        free(splits);
        free(levels);
        free(growth);
        return mts_error_set(err, MTS_ERR_ARG, "the model's flags say colours, it has none");
    }
    l.size[SEC_COLORS] = has_colors ? l.size[SEC_COLORS] : 0;
    uint32_t ids[SEC_LAST], count = 0;
    for (uint32_t id = 1; id <= SEC_LAST; id++)
        if ((id != SEC_GROWTH && id != SEC_KEY) || has_growth)
            if (id != SEC_COLORS || has_colors)
                ids[count++] = id;
    uint64_t offset[SEC_LAST + 1] = {0};
    uint64_t at = align8(HEADER_SIZE + (uint64_t)ENTRY_SIZE * count);
    for (uint32_t k = 0; k < count; k++) {
        offset[ids[k]] = at;
        /* no padding after the last section: any truncation cuts into data */
        at = k + 1 == count ? at + l.size[ids[k]] : align8(at + l.size[ids[k]]);
    }
    uint8_t *buf = at > SIZE_MAX ? NULL : calloc(1, (size_t)at);
    if (!buf) {
        free(splits);
        free(levels);
        free(growth);
        return mts_error_set(err, MTS_ERR_NOMEM, "out of memory for a %llu-byte model file",
                             (unsigned long long)at);
    }

    uint8_t *p = buf + offset[SEC_INFO];
    const uint32_t info[8] = {l.vertices,     l.base_vertices, l.levels,
                              l.strips,       l.full_indices,  l.base_indices,
                              l.record_words, l.capacity_total};
    put_u32s(p, info, 8);
    put_f32s(p + 32, m->bbox_min, 3);
    put_f32s(p + 44, m->bbox_max, 3);
    put_u32s(p + 56, &m->flags, 1);
    put_f32s(buf + offset[SEC_POSITIONS], m->positions, 3 * (size_t)l.vertices);
    put_f32s(buf + offset[SEC_NORMALS], m->normals, 3 * (size_t)l.vertices);
    put_strips(buf + offset[SEC_STRIPS_FULL], &m->full);
    put_strips(buf + offset[SEC_STRIPS_BASE], &m->base);
    if (l.strips) /* capacity may be NULL without strips */
        put_u32s(buf + offset[SEC_CAPACITY], m->capacity, l.strips);
    memcpy(buf + offset[SEC_SPLITS], splits, splits_len);
    memcpy(buf + offset[SEC_LEVELS], levels, (size_t)l.size[SEC_LEVELS]);
    free(splits);
    free(levels);
    memcpy(buf + offset[SEC_SOURCE], m->source, source_len);
    if (has_growth) {
        memcpy(buf + offset[SEC_GROWTH], growth, (size_t)l.size[SEC_GROWTH]);
        memcpy(buf + offset[SEC_KEY], m->build_key, key_len);
    }
    free(growth);
    if (has_colors)
        memcpy(buf + offset[SEC_COLORS], m->colors, (size_t)l.size[SEC_COLORS]);

    memcpy(buf, "MTSM", 4);
    put_u16(buf + 4, MTS_MODELFILE_MAJOR);
    put_u16(buf + 6, has_colors ? MTS_MODELFILE_MINOR : MTS_MODELFILE_MINOR_PLAIN);
    put_u32(buf + 8, count);
    for (uint32_t k = 0; k < count; k++) {
        const uint32_t id = ids[k];
        uint8_t *e = buf + HEADER_SIZE + ENTRY_SIZE * k;
        put_u32(e, id);
        put_u32(e + 4, mts_crc32c(0, buf + offset[id], (size_t)l.size[id]));
        put_u64(e + 8, offset[id]);
        put_u64(e + 16, l.size[id]);
    }
    uint32_t hcrc = mts_crc32c(0, buf, 12);
    hcrc = mts_crc32c(hcrc, buf + HEADER_SIZE, (size_t)ENTRY_SIZE * count);
    put_u32(buf + 12, hcrc);
    *out = buf;
    *out_size = (size_t)at;
    return MTS_OK;
}

static mts_result get_strips(const uint8_t *p, uint32_t strip_count, uint32_t index_count,
                             const char *name, const char *what, mts_strips *st, mts_error *err)
{
    mts_result rc = mts_strips_alloc(st, strip_count, index_count, err);
    if (rc != MTS_OK)
        return rc;
    uint64_t o = 0;
    for (uint32_t s = 0; s < strip_count; s++) {
        st->offsets[s] = (uint32_t)o;
        o += get_u32(p + 4 * (size_t)s);
        if (o > index_count)
            return mts_error_set(err, MTS_ERR_FORMAT,
                                 "%s: %s: strip %u runs past the %u indices the file declares",
                                 name, what, s, index_count);
    }
    if (o != index_count)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "%s: %s: strip lengths add up to %llu, the file declares %u", name,
                             what, (unsigned long long)o, index_count);
    st->offsets[strip_count] = index_count;
    get_u32s(st->indices, p + 4 * (size_t)strip_count, index_count);
    return MTS_OK;
}

mts_result mts_modelfile_decode(const void *data, size_t size, const char *name, mts_model *m,
                                mts_error *err)
{
    const uint8_t *buf = data;
    mts_result rc;
    memset(m, 0, sizeof *m);
    if (size < HEADER_SIZE)
        return size == 0 ? mts_error_set(err, MTS_ERR_FORMAT, "%s: empty file", name)
                         : mts_error_set(err, MTS_ERR_FORMAT,
                                         "%s: truncated: %zu bytes, the header alone is 16", name,
                                         size);
    if (memcmp(buf, "MTSM", 4) != 0)
        return mts_error_set(err, MTS_ERR_FORMAT, "%s: not an mtstream model (bad magic)", name);
    uint16_t major = get_u16(buf + 4), minor = get_u16(buf + 6);
    /* version 1's records have no erase runs and its strips no capacities,
     * version 2's splits no descriptions a stream can send, version 3's
     * INFO no flags, version 4's records came from the growth rules of
     * protocol 4.x: nothing here can use them, but mts-build makes the
     * model anew */
    if (major >= 1 && major < MTS_MODELFILE_MAJOR)
        return mts_error_set(err, MTS_ERR_VERSION,
                             "%s: model file version %u is from an older mtstream; rebuild it "
                             "with mts-build",
                             name, major);
    if (major != MTS_MODELFILE_MAJOR)
        return mts_error_set(err, MTS_ERR_VERSION,
                             "%s: model file version %u.%u; this build reads version %u.x", name,
                             major, minor, MTS_MODELFILE_MAJOR);
    uint32_t count = get_u32(buf + 8);
    if (count == 0 || count > MAX_SECTIONS)
        return mts_error_set(err, MTS_ERR_FORMAT, "%s: %u sections (1..%u allowed)", name, count,
                             MAX_SECTIONS);
    uint64_t table_end = HEADER_SIZE + (uint64_t)ENTRY_SIZE * count;
    if (table_end > size)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "%s: truncated: the section table needs %llu bytes, the file has %zu",
                             name, (unsigned long long)table_end, size);
    uint32_t hcrc = mts_crc32c(0, buf, 12);
    hcrc = mts_crc32c(hcrc, buf + HEADER_SIZE, (size_t)ENTRY_SIZE * count);
    if (hcrc != get_u32(buf + 12))
        return mts_error_set(err, MTS_ERR_CHECKSUM, "%s: header checksum mismatch", name);

    const uint8_t *sec[SEC_LAST + 1] = {0};
    uint64_t sec_size[SEC_LAST + 1] = {0};
    for (uint32_t i = 0; i < count; i++) {
        const uint8_t *e = buf + HEADER_SIZE + ENTRY_SIZE * i;
        uint32_t id = get_u32(e);
        uint64_t off = get_u64(e + 8), len = get_u64(e + 16);
        const char *sname = id >= 1 && id <= SEC_LAST ? section_names[id] : "unknown";
        if (off > size || len > size - off)
            return mts_error_set(err, MTS_ERR_FORMAT,
                                 "%s: truncated: section '%s' needs bytes %llu..%llu, the file "
                                 "has %zu",
                                 name, sname, (unsigned long long)off,
                                 (unsigned long long)(off + len), size);
        if (off < table_end)
            return mts_error_set(err, MTS_ERR_FORMAT, "%s: section '%s' overlaps the header",
                                 name, sname);
        if (mts_crc32c(0, buf + off, (size_t)len) != get_u32(e + 4))
            return mts_error_set(err, MTS_ERR_CHECKSUM, "%s: checksum mismatch in section '%s'",
                                 name, sname);
        if (id < 1 || id > SEC_LAST)
            continue; /* a newer minor version's section */
        if (sec[id])
            return mts_error_set(err, MTS_ERR_FORMAT, "%s: section '%s' appears twice", name,
                                 sname);
        sec[id] = buf + off;
        sec_size[id] = len;
    }
    for (uint32_t id = 1; id <= SEC_LAST; id++) {
        if (!sec[id] && id != SEC_SOURCE && id != SEC_GROWTH && id != SEC_KEY &&
            id != SEC_COLORS)
            return mts_error_set(err, MTS_ERR_FORMAT, "%s: section '%s' is missing", name,
                                 section_names[id]);
    }
    if (sec_size[SEC_INFO] != INFO_SIZE)
        return mts_error_set(err, MTS_ERR_FORMAT, "%s: info section is %llu bytes, expected %u",
                             name, (unsigned long long)sec_size[SEC_INFO], INFO_SIZE);
    layout l;
    const uint8_t *info = sec[SEC_INFO];
    l.vertices = get_u32(info);
    l.base_vertices = get_u32(info + 4);
    l.levels = get_u32(info + 8);
    l.strips = get_u32(info + 12);
    l.full_indices = get_u32(info + 16);
    l.base_indices = get_u32(info + 20);
    l.record_words = get_u32(info + 24);
    l.capacity_total = get_u32(info + 28);
    size_t source_len = sec[SEC_SOURCE] ? (size_t)sec_size[SEC_SOURCE] : 0;
    layout_sizes(&l);
    for (uint32_t id = 2; id <= SEC_LAST; id++) {
        if (sec[id] && fixed_size(id) && sec_size[id] != l.size[id])
            return mts_error_set(err, MTS_ERR_FORMAT,
                                 "%s: section '%s' is %llu bytes; the counts in 'info' need %llu",
                                 name, section_names[id], (unsigned long long)sec_size[id],
                                 (unsigned long long)l.size[id]);
    }
    if (l.vertices == 0 || l.levels >= l.vertices || l.base_vertices != l.vertices - l.levels)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "%s: %u vertices, %u base vertices and %u levels do not add up", name,
                             l.vertices, l.base_vertices, l.levels);
    /* every varint takes a byte at least: the counts behind the varint
     * sections are bounded by their sizes before anything is allocated */
    if (l.record_words > sec_size[SEC_SPLITS] || l.levels > sec_size[SEC_SPLITS])
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "%s: %u splits of %u words cannot fit the %llu bytes of 'splits'",
                             name, l.levels, l.record_words,
                             (unsigned long long)sec_size[SEC_SPLITS]);
    /* capacities could otherwise ask a runtime for slots of any size: they
     * are bounded by what could ever fill them (see the top of modelfile.h) */
    if (l.capacity_total > (uint64_t)l.base_indices + l.record_words)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "%s: %u indices of strip capacity, more than the %u base indices "
                             "and %u record words could ever fill",
                             name, l.capacity_total, l.base_indices, l.record_words);
    if (3 * ((uint64_t)l.levels + 1) > sec_size[SEC_LEVELS])
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "%s: %u levels cannot fit the %llu bytes of 'levels'", name,
                             l.levels + 1, (unsigned long long)sec_size[SEC_LEVELS]);

    /* Every size is now bounded by the file's own size: allocations are too. */
    size_t nv3 = 3 * (size_t)l.vertices, n1 = (size_t)l.levels + 1;
    m->vertex_count = l.vertices;
    m->base_vertex_count = l.base_vertices;
    m->level_count = l.levels;
    m->strip_count = l.strips;
    m->record_word_count = l.record_words;
    m->capacity = malloc(((size_t)l.strips + 1) * 4);
    m->positions = malloc(nv3 * 4);
    m->normals = malloc(nv3 * 4);
    m->parents = malloc(n1 * 4);
    m->record_offsets = malloc(n1 * 4);
    m->record_data = malloc(((size_t)l.record_words + 1) * 4);
    m->level_triangles = malloc(n1 * 4);
    m->level_strips = malloc(n1 * 4);
    m->level_indices = malloc(n1 * 4);
    if (sec[SEC_GROWTH]) {
        m->growth_offsets = malloc(n1 * 4);
        /* every word of the descriptions takes a byte at least */
        m->growth_data = malloc(((size_t)sec_size[SEC_GROWTH] + 1) * 4);
    }
    if (!m->capacity || !m->positions || !m->normals || !m->parents || !m->record_offsets ||
        !m->record_data || !m->level_triangles || !m->level_strips || !m->level_indices ||
        (sec[SEC_GROWTH] && (!m->growth_offsets || !m->growth_data))) {
        rc = mts_error_set(err, MTS_ERR_NOMEM, "%s: out of memory", name);
        goto fail;
    }
    get_f32s(m->bbox_min, info + 32, 3);
    get_f32s(m->bbox_max, info + 44, 3);
    m->flags = get_u32(info + 56);
    if (m->flags & ~(MTS_MODEL_NORMALS_GIVEN | MTS_MODEL_COLORS)) {
        rc = mts_error_set(err, MTS_ERR_FORMAT, "%s: unknown model flags 0x%x", name, m->flags);
        goto fail;
    }
    if (!(m->flags & MTS_MODEL_COLORS) != !sec[SEC_COLORS]) {
        rc = mts_error_set(err, MTS_ERR_FORMAT,
                           sec[SEC_COLORS] ? "%s: section 'colors' in a model whose 'info' "
                                             "flags say it has no colours"
                                           : "%s: section 'colors' is missing ('info' flags "
                                             "say the model has colours)",
                           name);
        goto fail;
    }
    if (sec[SEC_COLORS]) {
        /* its size was checked against 'info' with the other fixed sections */
        if (!(m->colors = malloc(nv3 + 1))) {
            rc = mts_error_set(err, MTS_ERR_NOMEM, "%s: out of memory", name);
            goto fail;
        }
        memcpy(m->colors, sec[SEC_COLORS], nv3);
    }
    get_f32s(m->positions, sec[SEC_POSITIONS], nv3);
    get_f32s(m->normals, sec[SEC_NORMALS], nv3);
    if ((rc = get_strips(sec[SEC_STRIPS_FULL], l.strips, l.full_indices, name, "full strips",
                         &m->full, err)) != MTS_OK)
        goto fail;
    if ((rc = get_strips(sec[SEC_STRIPS_BASE], l.strips, l.base_indices, name, "base strips",
                         &m->base, err)) != MTS_OK)
        goto fail;
    get_u32s(m->capacity, sec[SEC_CAPACITY], l.strips);
    uint64_t capacity_sum = 0;
    for (uint32_t s = 0; s < l.strips; s++)
        capacity_sum += m->capacity[s];
    if (capacity_sum != l.capacity_total) {
        rc = mts_error_set(err, MTS_ERR_FORMAT,
                           "%s: strip capacities add up to %llu, 'info' declares %u", name,
                           (unsigned long long)capacity_sum, l.capacity_total);
        goto fail;
    }
    mts_reccodec_out ro = {m->parents, m->record_offsets, m->record_data, l.record_words, 0};
    size_t consumed = 0, words = 0;
    if ((rc = mts_reccodec_decode(sec[SEC_SPLITS], (size_t)sec_size[SEC_SPLITS],
                                  l.base_vertices, 0, l.levels, &ro, &consumed, &words, err)) !=
        MTS_OK) {
        mts_error_prefix(err, "%s: section 'splits'", name);
        goto fail;
    }
    if (consumed != sec_size[SEC_SPLITS] || words != l.record_words) {
        rc = mts_error_set(err, MTS_ERR_FORMAT,
                           "%s: section 'splits' holds %zu of its %llu bytes and %zu of the %u "
                           "words 'info' declares",
                           name, consumed, (unsigned long long)sec_size[SEC_SPLITS], words,
                           l.record_words);
        goto fail;
    }
    if (!levels_decode(sec[SEC_LEVELS], sec[SEC_LEVELS] + sec_size[SEC_LEVELS], m)) {
        rc = mts_error_set(err, MTS_ERR_FORMAT,
                           "%s: section 'levels' does not hold exactly %u levels", name,
                           l.levels + 1);
        goto fail;
    }
    if (sec[SEC_GROWTH] && !growth_decode(sec[SEC_GROWTH], sec[SEC_GROWTH] + sec_size[SEC_GROWTH], m,
                       (size_t)sec_size[SEC_GROWTH] + 1)) {
        rc = mts_error_set(err, MTS_ERR_FORMAT,
                           "%s: section 'growth' does not hold exactly %u split descriptions",
                           name, l.levels);
        goto fail;
    }
    for (size_t i = 0; i < source_len && i + 1 < sizeof m->source; i++)
        m->source[i] = sec[SEC_SOURCE][i] ? (char)sec[SEC_SOURCE][i] : '?';
    for (size_t i = 0; sec[SEC_KEY] && i < sec_size[SEC_KEY] && i + 1 < sizeof m->build_key; i++)
        m->build_key[i] = sec[SEC_KEY][i] ? (char)sec[SEC_KEY][i] : '?';
    if ((rc = mts_model_validate(m, err)) != MTS_OK) {
        mts_error_prefix(err, "%s", name);
        goto fail;
    }
    return MTS_OK;
fail:
    mts_model_free(m);
    return rc;
}

mts_result mts_modelfile_save(const mts_model *m, const char *path, uint64_t *bytes,
                              mts_error *err)
{
    uint8_t *buf = NULL;
    size_t size = 0;
    mts_result rc = mts_modelfile_encode(m, &buf, &size, err);
    if (rc != MTS_OK)
        return rc;
    rc = mts_file_write_atomic(path, buf, size, err);
    free(buf);
    if (rc != MTS_OK)
        return rc;
    if (bytes)
        *bytes = size;
    return MTS_OK;
}

mts_result mts_modelfile_load(const char *path, mts_model *m, mts_error *err)
{
    memset(m, 0, sizeof *m);
    FILE *f = fopen(path, "rb");
    if (!f)
        return mts_error_set(err, MTS_ERR_IO, "%s: %s", path, strerror(errno));
    struct stat st;
    if (fstat(fileno(f), &st) != 0 || !S_ISREG(st.st_mode)) {
        fclose(f);
        return mts_error_set(err, MTS_ERR_IO, "%s: not a regular file", path);
    }
    size_t size = (size_t)st.st_size;
    uint8_t *buf = malloc(size ? size : 1);
    if (!buf) {
        fclose(f);
        return mts_error_set(err, MTS_ERR_NOMEM, "%s: out of memory for %zu bytes", path, size);
    }
    size_t got = fread(buf, 1, size, f);
    int read_err = ferror(f);
    fclose(f);
    if (read_err || got != size) {
        free(buf);
        return mts_error_set(err, MTS_ERR_IO, "%s: read failed", path);
    }
    mts_result rc = mts_modelfile_decode(buf, size, path, m, err);
    free(buf);
    return rc;
}
