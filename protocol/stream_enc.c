/* The server's end of a stream (stream.h): building it from a model, its
 * records form, and what each connection is sent of it. */
#include "stream.h"

#include "grow.h"
#include "stream_coding.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "crc32c.h"
#include "lframe.h"
#include "rcoder.h"
#include "reccodec.h"
#include "varint.h"

void mts_stream_free(mts_stream *s)
{
    if (!s)
        return;
    if (s->records_form) {
        mts_stream_free(s->records_form);
        free(s->records_form);
    }
    if (!s->borrowed) {
        mts_model_free(&s->model);
        free(s->quantized);
        free(s->batch_first);
        free(s->announced);
        free(s->level_checksum);
        free(s->oct);
    }
    free(s->bytes);
    free(s->batch_offset);
    free(s->info_tail);
    memset(s, 0, sizeof *s);
}

const mts_stream *mts_stream_for_hello(const mts_stream *s, uint32_t hello_flags)
{
    return (hello_flags & MTS_HELLO_RECORDS) && s->records_form ? s->records_form : s;
}

static mts_result copy_model(const mts_model *src, mts_model *dst, mts_error *err)
{
    memset(dst, 0, sizeof *dst);
    size_t nv = src->vertex_count, n1 = (size_t)src->level_count + 1;
    *dst = *src;
    /* colours travel only where the model says it has them */
    const int colored = (src->flags & MTS_MODEL_COLORS) && src->colors;
    dst->flags = colored ? src->flags : src->flags & ~MTS_MODEL_COLORS;
    dst->colors = colored ? malloc(nv * 3 + 1) : NULL;
    dst->positions = malloc(nv * 12);
    dst->normals = malloc(nv * 12);
    dst->parents = malloc(n1 * 4);
    dst->record_offsets = malloc(n1 * 4);
    dst->record_data = malloc(((size_t)src->record_word_count + 1) * 4);
    dst->level_triangles = malloc(n1 * 4);
    dst->level_strips = malloc(n1 * 4);
    dst->level_indices = malloc(n1 * 4);
    dst->capacity = malloc(((size_t)src->strip_count + 1) * 4);
    dst->key_levels = malloc(((size_t)src->key_count + 1) * 4);
    dst->growth_offsets = src->growth_offsets ? malloc(n1 * 4) : NULL;
    dst->growth_data =
        src->growth_data ? malloc(((size_t)src->growth_word_count + 1) * 4) : NULL;
    memset(&dst->full, 0, sizeof dst->full);
    memset(&dst->base, 0, sizeof dst->base);
    if (!dst->positions || !dst->normals || !dst->parents || !dst->record_offsets ||
        !dst->record_data || !dst->level_triangles || !dst->level_strips ||
        !dst->level_indices || !dst->capacity || !dst->key_levels || (colored && !dst->colors) ||
        (src->growth_offsets && !dst->growth_offsets) || (src->growth_data && !dst->growth_data) ||
        mts_strips_alloc(&dst->full, src->strip_count, src->full.index_count, err) != MTS_OK ||
        mts_strips_alloc(&dst->base, src->strip_count, src->base.index_count, err) != MTS_OK) {
        mts_model_free(dst);
        return mts_error_set(err, MTS_ERR_NOMEM, "stream: out of memory copying the model");
    }
    memcpy(dst->positions, src->positions, nv * 12);
    memcpy(dst->normals, src->normals, nv * 12);
    if (colored)
        memcpy(dst->colors, src->colors, nv * 3);
    memcpy(dst->parents, src->parents, (n1 - 1) * 4);
    memcpy(dst->record_offsets, src->record_offsets, n1 * 4);
    memcpy(dst->record_data, src->record_data, (size_t)src->record_word_count * 4);
    memcpy(dst->level_triangles, src->level_triangles, n1 * 4);
    memcpy(dst->level_strips, src->level_strips, n1 * 4);
    memcpy(dst->level_indices, src->level_indices, n1 * 4);
    if (src->strip_count)
        memcpy(dst->capacity, src->capacity, (size_t)src->strip_count * 4);
    if (src->key_count)
        memcpy(dst->key_levels, src->key_levels, (size_t)src->key_count * 4);
    if (src->growth_offsets)
        memcpy(dst->growth_offsets, src->growth_offsets, n1 * 4);
    if (src->growth_data)
        memcpy(dst->growth_data, src->growth_data, (size_t)src->growth_word_count * 4);
    memcpy(dst->full.offsets, src->full.offsets, ((size_t)src->strip_count + 1) * 4);
    memcpy(dst->full.indices, src->full.indices, (size_t)src->full.index_count * 4);
    memcpy(dst->base.offsets, src->base.offsets, ((size_t)src->strip_count + 1) * 4);
    memcpy(dst->base.indices, src->base.indices, (size_t)src->base.index_count * 4);
    return MTS_OK;
}

/* Renames base vertex x to map[x] everywhere a vertex id appears: the full
 * and base strips, the parents, and in every record (model.h) the indices of
 * its erased runs as well as of its inserted runs -- an erased run must hold
 * exactly the strip's indices when it applies, so it is renamed with them. */
static int renumber_base(mts_model *m, uint32_t *quantized, const uint32_t *map)
{
    const uint32_t nb = m->base_vertex_count;
#define MAP(x) ((x) < nb ? map[x] : (x))
    for (uint32_t i = 0; i < m->full.index_count; i++)
        m->full.indices[i] = MAP(m->full.indices[i]);
    for (uint32_t i = 0; i < m->base.index_count; i++)
        m->base.indices[i] = MAP(m->base.indices[i]);
    for (uint32_t j = 0; j < m->level_count; j++)
        m->parents[j] = MAP(m->parents[j]);
    for (uint32_t j = 0; j < m->level_count; j++) {
        uint32_t *p = m->record_data + m->record_offsets[j];
        uint32_t edits = *p++;
        for (uint32_t e = 0; e < edits; e++) {
            /* strip, erase_count, insert_count, subst_count; erased runs, then
             * inserted runs, each (position, length, indices); positions */
            uint32_t runs = p[1] + p[2], substs = p[3];
            p += 4;
            for (uint32_t k = 0; k < runs; k++) {
                uint32_t run = p[1];
                p += 2;
                for (uint32_t r = 0; r < run; r++, p++)
                    *p = MAP(*p);
            }
            p += substs;
        }
    }
    /* the new triangles of splits described explicitly name vertices */
    for (uint32_t j = 0; m->growth_data && j < m->level_count; j++) {
        uint32_t *w = m->growth_data + m->growth_offsets[j];
        if (w[2] != MTS_GROWTH_EXPLICIT)
            continue;
        uint32_t *born = w + 5 + w[3];
        for (uint32_t k = 0; k < 3 * w[4]; k++)
            born[k] = MAP(born[k]);
    }
#undef MAP
    float *pos = malloc((size_t)nb * 12 + 1), *nor = malloc((size_t)nb * 12 + 1);
    uint32_t *q = malloc((size_t)nb * 12 + 1);
    uint8_t *col = m->colors ? malloc((size_t)nb * 3 + 1) : NULL;
    int ok = pos && nor && q && (!m->colors || col);
    if (ok) {
        for (uint32_t x = 0; x < nb; x++) {
            memcpy(pos + 3 * (size_t)map[x], m->positions + 3 * (size_t)x, 12);
            memcpy(nor + 3 * (size_t)map[x], m->normals + 3 * (size_t)x, 12);
            memcpy(q + 3 * (size_t)map[x], quantized + 3 * (size_t)x, 12);
            if (col)
                memcpy(col + 3 * (size_t)map[x], m->colors + 3 * (size_t)x, 3);
        }
        memcpy(m->positions, pos, (size_t)nb * 12);
        memcpy(m->normals, nor, (size_t)nb * 12);
        memcpy(quantized, q, (size_t)nb * 12);
        if (col)
            memcpy(m->colors, col, (size_t)nb * 3);
    }
    free(pos);
    free(nor);
    free(q);
    free(col);
    return ok;
}

/* The base mesh's triangles: the base strips' drawn windows. */
static uint32_t *base_triangles(const mts_model *m, uint32_t *count)
{
    uint32_t *t = malloc(((size_t)m->base.index_count + 1) * 12);
    uint32_t n = 0;
    if (!t)
        return NULL;
    for (uint32_t s = 0; s < m->strip_count; s++) {
        const uint32_t *str = m->base.indices + m->base.offsets[s];
        uint32_t len = m->base.offsets[s + 1] - m->base.offsets[s];
        for (uint32_t k = 0; k + 2 < len; k++)
            n += (uint32_t)mts_strip_window(str, k, t + 3 * (size_t)n);
    }
    *count = n;
    return t;
}

/* Encodes the base with Draco, decodes it back and renumbers the model to the
 * decoded vertices in grid order (mts__stream_base_in_grid_order); falls back
 * to the order-keeping sequential method when Edgebreaker changed the mesh
 * itself (split or dropped vertices). */
static mts_result encode_base(mts_stream *s, int method, uint8_t **draco, size_t *draco_size,
                              mts_error *err)
{
    mts_model *m = &s->model;
    const uint32_t nb = m->base_vertex_count;
    uint32_t nt = 0;
    uint32_t *tris = base_triangles(m, &nt);
    uint32_t *map = malloc((size_t)nb * 4 + 4);
    mts_draco_mesh_out dec = {0};
    mts_result rc = MTS_OK;
    if (!tris || !map) {
        rc = mts_error_set(err, MTS_ERR_NOMEM, "stream: out of memory for the base mesh");
        goto done;
    }
    const int carry_normals = (m->flags & MTS_MODEL_NORMALS_GIVEN) != 0;
    for (int attempt = 0; attempt < 2; attempt++) {
        mts_draco_mesh in = {nb, nt, m->positions, carry_normals ? m->normals : NULL, tris,
                             m->colors, s->quantized};
        mts_draco_options o = {0};
        o.grid = s->grid;
        o.method = attempt == 0 ? method : MTS_DRACO_SEQUENTIAL;
        free(*draco);
        *draco = NULL;
        mts_draco_mesh_out_free(&dec);
        if ((rc = mts_draco_encode(&in, &o, draco, draco_size, err)) != MTS_OK ||
            (rc = mts_draco_decode(*draco, *draco_size, &dec, err)) != MTS_OK)
            goto done;
        if (dec.vertex_count == nb && (dec.normals != NULL) == carry_normals &&
            (dec.colors != NULL) == (m->colors != NULL) &&
            mts_draco_renumber(&in, &dec, map, NULL, err) == MTS_OK) {
            s->draco_method = o.method;
            break;
        }
        if (attempt == 1) {
            rc = mts_error_set(err, MTS_ERR_INTERNAL,
                               "stream: the sequential Draco encoding did not round-trip");
            goto done;
        }
    }
    /* map: model id -> decoded id -> its place in grid order */
    uint32_t *rank = malloc((size_t)nb * 4 + 4);
    if (!rank || !mts__stream_base_in_grid_order(&dec, rank)) {
        free(rank);
        rc = mts_error_set(err, MTS_ERR_NOMEM, "stream: out of memory renumbering");
        goto done;
    }
    for (uint32_t x = 0; x < nb; x++)
        map[x] = rank[map[x]];
    free(rank);
    /* ids are renamed before the copy, so a failed copy leaves a broken model:
     * the caller frees it */
    if (!renumber_base(m, s->quantized, map)) {
        rc = mts_error_set(err, MTS_ERR_NOMEM, "stream: out of memory renumbering");
        goto done;
    }
    /* The stream stands for what clients decode: Draco's grid (it stores the
     * origin and range in its own precision, which can move them in the last
     * bits), Draco's base normals, and every position -- base and refinement
     * alike -- dequantized on that one grid, so they meet without cracks. */
    s->grid = dec.grid;
    for (uint32_t x = 0; x < nb; x++) {
        if (memcmp(s->quantized + 3 * (size_t)x, dec.quantized + 3 * (size_t)x, 12) != 0) {
            rc = mts_error_set(err, MTS_ERR_INTERNAL,
                               "stream: base vertex %u changed its grid point through Draco", x);
            goto done;
        }
        if (carry_normals)
            memcpy(m->normals + 3 * (size_t)x, dec.normals + 3 * (size_t)x, 12);
        /* Draco codes byte colours losslessly (draco.h): a client's base
         * colours are the model's, or the stream would stand for others */
        if (m->colors && memcmp(m->colors + 3 * (size_t)x, dec.colors + 3 * (size_t)x, 3) != 0) {
            rc = mts_error_set(err, MTS_ERR_INTERNAL,
                               "stream: base vertex %u changed its colour through Draco", x);
            goto done;
        }
    }
    for (uint32_t x = 0; x < m->vertex_count; x++)
        mts_draco_dequantize(&s->grid, s->quantized + 3 * (size_t)x, m->positions + 3 * (size_t)x);
done:
    free(tris);
    free(map);
    mts_draco_mesh_out_free(&dec);
    return rc;
}

static uint64_t fnv64(const uint8_t *p, size_t n)
{
    uint64_t h = 0xcbf29ce484222325ull;
    for (size_t i = 0; i < n; i++)
        h = (h ^ p[i]) * 0x100000001b3ull;
    return h;
}

static void put_crc(mts_buf *b, size_t frame_start)
{
    size_t payload = frame_start + MTS_WIRE_HEADER;
    uint32_t crc = b->failed ? 0 : mts_crc32c(0, b->data + payload, b->size - payload);
    mts_buf_u32(b, crc);
}

static int cancelled(const mts_stream_options *opts, uint32_t j)
{
    return (j & 4095) == 0 && opts->cancel && *opts->cancel;
}

static mts_result level_checksums(mts_stream *s, const mts_stream_options *opts, mts_error *err)
{
    const mts_model *m = &s->model;
    mts_lod lod;
    mts_result rc = mts_lod_init(&lod, m, MTS_LOD_AT_BASE, err);
    if (rc != MTS_OK)
        return rc;
    uint64_t *hs = malloc(((size_t)m->strip_count + 1) * 8);
    if (!hs) {
        mts_lod_free(&lod);
        return mts_error_set(err, MTS_ERR_NOMEM, "stream: out of memory");
    }
    uint64_t sum = mts_stream_checksum_colors(&lod, s->quantized, m->colors);
    for (uint32_t st = 0; st < m->strip_count; st++) {
        uint32_t len;
        const uint32_t *str = mts_lod_strip(&lod, st, &len);
        hs[st] = mts__stream_strip_sum(st, str, len);
    }
    mts_lod_clear_changed(&lod);
    s->level_checksum[0] = sum;
    for (uint32_t l = 0; l < m->level_count; l++) {
        if (cancelled(opts, l)) {
            rc = mts_error_set(err, MTS_ERR_ARG, "stream: cancelled");
            break;
        }
        if ((rc = mts_lod_split(&lod, err)) != MTS_OK)
            break;
        uint32_t nc;
        const uint32_t *changed = mts_lod_changed(&lod, &nc);
        for (uint32_t c = 0; c < nc; c++) {
            uint32_t st = changed[c], len;
            const uint32_t *str = mts_lod_strip(&lod, st, &len);
            sum -= hs[st];
            hs[st] = mts__stream_strip_sum(st, str, len);
            sum += hs[st];
        }
        mts_lod_clear_changed(&lod);
        uint32_t v = m->base_vertex_count + l;
        sum += mts__stream_vertex_sum(v, s->quantized + 3 * (size_t)v);
        if (m->colors)
            sum += mts__stream_color_sum(v, m->colors + 3 * (size_t)v);
        s->level_checksum[l + 1] = sum;
    }
    free(hs);
    mts_lod_free(&lod);
    return rc;
}

/* What the server's run of the client's growth leaves for the encoder:
 * per split its position residuals (and normal code residuals) and the
 * context they are coded in, and the full strips' description. */
typedef struct prediction_pass {
    int32_t *residual; /* 5 per split: position x y z, normal code a b */
    uint8_t *context;
    int16_t *color;        /* 3 per split, where the stream has colours: the
                              residual decorrelated (mts__stream_color_forward) */
    uint8_t *color_context;
    uint8_t *fan_context; /* per split: its fan code's context */
    mts_grow_full_path *paths;
    uint8_t *swaps;
    uint64_t swap_count;
} prediction_pass;

static void pass_free(prediction_pass *p)
{
    free(p->residual);
    free(p->context);
    free(p->color);
    free(p->color_context);
    free(p->fan_context);
    free(p->paths);
    free(p->swaps);
    memset(p, 0, sizeof *p);
}

static mts_result predict_all(mts_stream *s, const mts_stream_options *opts, const uint16_t *oct,
                              int carry_normals, prediction_pass *pass, mts_error *err)
{
    const mts_model *m = &s->model;
    const uint32_t nb = m->base_vertex_count, n = m->level_count;
    pass->residual = malloc((size_t)n * 20 + 1);
    pass->context = malloc((size_t)n + 1);
    pass->fan_context = malloc((size_t)n + 1);
    pass->paths = malloc(((size_t)m->strip_count + 1) * sizeof *pass->paths);
    pass->swaps = malloc((size_t)m->full.index_count + 1);
    if (m->colors) {
        pass->color = malloc((size_t)n * 6 + 1);
        pass->color_context = malloc((size_t)n + 1);
    }
    if (!pass->residual || !pass->context || !pass->fan_context || !pass->paths || !pass->swaps ||
        (m->colors && (!pass->color || !pass->color_context)))
        return mts_error_set(err, MTS_ERR_NOMEM, "stream: out of memory predicting '%s'",
                             s->name);
    mts_grow_options go = {0};
    go.key_levels = m->key_levels;
    go.key_count = m->key_count;
    mts_grow *g = NULL;
    mts_result rc = mts_grow_create(&m->base, nb, n, &go, &g, err);
    const mts_grow_full given = {.strips = &m->full, .slot_count = m->strip_count};
    for (uint32_t j = 0; j < n && rc == MTS_OK; j++) {
        const uint32_t v = nb + j, u = m->parents[j];
        mts_grow_split sp;
        if (cancelled(opts, j)) {
            rc = mts_error_set(err, MTS_ERR_ARG, "stream: cancelled");
            break;
        }
        if (!mts_grow_model_split(g, m, j, &sp)) {
            rc = mts_error_set(err, MTS_ERR_ARG,
                               "split %u's description names no fan of the mesh; rebuild it "
                               "with mts-build",
                               j);
            break;
        }
        const uint32_t *rec;
        uint32_t words;
        pass->fan_context[j] = (uint8_t)mts__stream_fan_context(g, u);
        if ((rc = mts_grow_next(g, &sp, &given, &rec, &words, err)) != MTS_OK)
            break;
        /* what a splits-form client will derive must be the model's record,
         * which the records form sends: else the two forms part (a model
         * from another builder, say) */
        if (words != m->record_offsets[j + 1] - m->record_offsets[j] ||
            memcmp(rec, m->record_data + m->record_offsets[j], (size_t)words * 4) != 0) {
            rc = mts_error_set(err, MTS_ERR_INVARIANT,
                               "split %u's record is not what its description grows; rebuild "
                               "it with mts-build",
                               j);
            break;
        }
        const uint32_t *around;
        uint32_t k;
        if ((rc = mts_grow_around_newest(g, &around, &k, err)) != MTS_OK)
            break;
        int64_t pred[3], local[3];
        mts_lframe frame;
        pass->context[j] = (uint8_t)mts__stream_predict_position(around, k, s->quantized, u,
                                                                 s->grid.bits, pred, &frame);
        for (int a = 0; a < 3; a++)
            local[a] = (int64_t)s->quantized[3 * (size_t)v + a] - pred[a];
        /* the grid has at most 2^30 points an axis, so |local| < 2^31 */
        mts_lframe_forward(&frame, local);
        int32_t *r = pass->residual + 5 * (size_t)j;
        for (int a = 0; a < 3; a++)
            r[a] = (int32_t)local[a];
        r[3] = r[4] = 0;
        if (carry_normals) {
            uint16_t code[2];
            mts__stream_predict_normal(around, k, s->quantized, v, s->grid.bits,
                                       oct + 2 * (size_t)u, code);
            r[3] = (int32_t)oct[2 * (size_t)v] - code[0];
            r[4] = (int32_t)oct[2 * (size_t)v + 1] - code[1];
        }
        if (m->colors) {
            int32_t cp[3], d[3], t[3];
            pass->color_context[j] =
                (uint8_t)mts__stream_predict_color(around, k, m->colors, u, cp);
            for (int c = 0; c < 3; c++)
                d[c] = (int32_t)m->colors[3 * (size_t)v + c] - cp[c];
            mts__stream_color_forward(d, t);
            for (int c = 0; c < 3; c++)
                pass->color[3 * (size_t)j + c] = (int16_t)t[c];
        }
    }
    if (rc == MTS_OK && n > 0)
        rc = mts_grow_full_describe(g, &m->full, pass->paths, pass->swaps, &pass->swap_count,
                                    err);
    mts_grow_free(g);
    return rc == MTS_OK ? MTS_OK : mts_error_prefix(err, "stream: model '%s'", s->name);
}

/* A parent, against the one before it: the builder sorts splits by parent
 * within windows (reorder.h), so it is mostly a short way above it; else
 * (a new run) it is coded as v - 1 - u. */
static void encode_parent(mts_rc_encoder *e, struct mts__stream_models *md, uint32_t before,
                          uint32_t u, uint32_t v)
{
    const unsigned up = u >= before;
    mts_rc_encode_bit(e, &md->parent_up, up);
    if (up)
        mts_rc_encode_uint(e, &md->parent_gap, u - before);
    else
        mts_rc_encode_uint(e, &md->parent, v - 1 - u);
}

static void encode_full(mts_rc_encoder *e, struct mts__stream_models *md,
                        const prediction_pass *pass, uint32_t slots, uint32_t triangles)
{
    const unsigned id_bits = mts__stream_triangle_id_bits(triangles);
    for (uint32_t st = 0; st < slots; st++)
        mts_rc_encode_uint(e, &md->full_triangles, pass->paths[st].triangles);
    /* then strip by strip as the client walks them (grow.h, mts_grow_full):
     * its start, next to the strip before or anywhere, and the swap bits
     * the walk does not force */
    uint64_t k = 0;
    unsigned last = 0;
    for (uint32_t st = 0; st < slots; st++) {
        const mts_grow_full_path *p = &pass->paths[st];
        if (!p->triangles)
            continue;
        const int near = p->near != MTS_GROW_NONE;
        if (p->near_count)
            mts_rc_encode_bit(e, &md->full_near, near);
        if (near)
            mts_rc_encode_uint(e, &md->full_near_at, p->near);
        else
            mts_rc_encode_direct(e, p->first, id_bits);
        mts_rc_encode_tree(e, &md->rotation, p->rotation);
        for (uint32_t i = 2; i < p->triangles; i++, k++) {
            const unsigned bit = pass->swaps[k] & 1;
            if (!(pass->swaps[k] & 2))
                mts_rc_encode_bit(e, &md->swap[last], bit);
            last = bit;
        }
    }
}

/* 1 + the highest slot split j's record edits (0: none; a malformed record
 * is found, by name, when the stream's growth derives it). */
static uint32_t record_slots_end(const mts_model *m, uint32_t j)
{
    const uint32_t *p = m->record_data + m->record_offsets[j],
                   *end = m->record_data + m->record_offsets[j + 1];
    uint32_t top = 0;
    for (uint32_t e = 0, edits = p < end ? *p++ : 0; e < edits && p; e++) {
        uint32_t st;
        if ((p = mts_record_skip_edit(p, end, &st)) != NULL)
            top = st + 1 > top ? st + 1 : top;
    }
    return top;
}

/* When each slot's capacity travels (PROTOCOL.md, "Capacities"): with BASE
 * the slots up to the last one the base uses, with each batch those up to
 * the last one its records use, so the first picture does not wait for the
 * capacities of every slot any level will ever use (on bunny00 5,275 slots,
 * 5.5 KB, where the base needs 15). */
static mts_result announce_schedule(mts_stream *s, mts_error *err)
{
    const mts_model *m = &s->model;
    s->announced = malloc(((size_t)s->batch_count + 1) * 4);
    if (!s->announced)
        return mts_error_set(err, MTS_ERR_NOMEM, "stream: out of memory");
    uint32_t a = 0;
    for (uint32_t st = 0; st < m->strip_count; st++) {
        if (m->base.offsets[st + 1] > m->base.offsets[st])
            a = st + 1;
    }
    s->announced[0] = a;
    for (uint32_t k = 0; k < s->batch_count; k++) {
        for (uint32_t j = s->batch_first[k]; j < s->batch_first[k + 1]; j++) {
            uint32_t t = record_slots_end(m, j);
            a = t > a ? t : a;
        }
        s->announced[k + 1] = a;
    }
    return MTS_OK;
}

/* A BATCH's header: its index and how many slots it announces; then, in the
 * records form, their capacities (the splits form codes them in its body,
 * encode_capacities). Where it starts and how many splits it holds follow
 * from MODEL_INFO's batch size. */
static void put_batch_head(mts_buf *b, const mts_stream *s, uint32_t k, int capacities)
{
    mts_buf_varint(b, k);
    mts_buf_varint(b, s->announced[k + 1] - s->announced[k]);
    for (uint32_t st = s->announced[k]; capacities && st < s->announced[k + 1]; st++)
        mts_buf_varint(b, s->model.capacity[st]);
}

static void encode_capacities(mts_rc_encoder *e, struct mts__stream_models *md,
                              const mts_stream *s, uint32_t k)
{
    for (uint32_t st = s->announced[k]; st < s->announced[k + 1]; st++)
        mts_rc_encode_uint(e, &md->capacity, s->model.capacity[st]);
}

static mts_result build_info_tail(mts_stream *s);
static mts_result breakdown_finish(const mts_stream *s, mts_stream_breakdown *bd);

/* The records form of a built stream (PROTOCOL.md, "Records form"): its
 * BASE frame as is, then per batch the splits' records in the model file's
 * encoding (reccodec.h) and each new vertex against its parent, as plain
 * varints: a client then only checks and applies records, with no growth
 * to run, which is what a fast link wants. */
mts_result mts_stream_add_records_form(mts_stream *s, mts_error *err)
{
    if (s->records || s->records_form)
        return MTS_OK;
    const uint16_t *oct = s->oct;
    const int carry_normals = oct != NULL;
    const mts_model *m = &s->model;
    const uint32_t nb = m->base_vertex_count;
    mts_stream *r = calloc(1, sizeof *r);
    mts_buf b = {0};
    uint8_t *rec = NULL;
    size_t rec_cap = 0;
    mts_result rc = MTS_OK;
    if (!r)
        goto nomem;
    memcpy(r->name, s->name, sizeof r->name);
    r->model = s->model;
    r->quantized = s->quantized;
    r->grid = s->grid;
    r->draco_method = s->draco_method;
    r->batch_count = s->batch_count;
    r->batch_first = s->batch_first;
    r->announced = s->announced;
    r->level_checksum = s->level_checksum;
    r->borrowed = 1;
    r->records = 1;
    r->batch_offset = malloc(((size_t)s->batch_count + 1) * sizeof *r->batch_offset);
    if (!r->batch_offset)
        goto nomem;
    const size_t base_end = s->batch_count ? s->batch_offset[0] : s->size;
    mts_buf_put(&b, s->bytes, base_end);
    for (uint32_t k = 0; k < s->batch_count; k++) {
        const uint32_t first = s->batch_first[k], count = s->batch_first[k + 1] - first;
        r->batch_offset[k] = b.size;
        size_t f = mts_wire_frame_begin(&b, MTS_MSG_BATCH);
        put_batch_head(&b, s, k, 1);
        size_t need = mts_reccodec_bound(m, first, count), written = 0;
        if (need > rec_cap) {
            free(rec);
            rec_cap = need;
            if (!(rec = malloc(rec_cap)))
                goto nomem;
        }
        if ((rc = mts_reccodec_encode(m, first, count, rec, rec_cap, &written, err)) != MTS_OK)
            goto fail;
        mts_buf_put(&b, rec, written);
        for (uint32_t i = 0; i < count; i++) {
            const uint32_t j = first + i, v = nb + j, u = m->parents[j];
            for (int a = 0; a < 3; a++)
                mts_buf_varint(&b, mts_zigzag_u32(s->quantized[3 * (size_t)v + a] -
                                                  s->quantized[3 * (size_t)u + a]));
            for (int a = 0; a < 2 && carry_normals; a++)
                mts_buf_varint(&b, mts_zigzag_u32((uint32_t)oct[2 * (size_t)v + a] -
                                                  oct[2 * (size_t)u + a]));
            for (int c = 0; c < 3 && m->colors; c++)
                mts_buf_varint(&b, mts_zigzag_u32((uint32_t)m->colors[3 * (size_t)v + c] -
                                                  m->colors[3 * (size_t)u + c]));
        }
        put_crc(&b, f);
        mts_wire_frame_end(&b, f);
    }
    r->batch_offset[s->batch_count] = b.size;
    if (b.failed)
        goto nomem;
    r->bytes = b.data;
    r->size = b.size;
    b.data = NULL;
    r->stream_id = fnv64(r->bytes, r->size) ^ ((uint64_t)r->size << 1);
    if (build_info_tail(r) != MTS_OK)
        goto nomem;
    free(rec);
    s->records_form = r;
    return MTS_OK;
nomem:
    rc = mts_error_set(err, MTS_ERR_NOMEM, "stream: out of memory for the records form of '%s'",
                       s->name);
fail:
    free(rec);
    mts_buf_free(&b);
    if (r) {
        mts_stream_free(r);
        free(r);
    }
    return rc;
}

mts_result mts_stream_build(const mts_model *model, const char *name,
                            const mts_stream_options *opts, mts_stream *s, mts_error *err)
{
    static const mts_stream_options defaults = {0};
    if (!opts)
        opts = &defaults;
    memset(s, 0, sizeof *s);
    if (!mts_wire_valid_name(name, strlen(name)))
        return mts_error_set(err, MTS_ERR_ARG, "stream: '%s' is not a valid model name", name);
    snprintf(s->name, sizeof s->name, "%s", name);
    mts_buf b = {0};
    uint8_t *draco = NULL;
    uint16_t *oct = NULL;
    struct mts__stream_models *models = NULL;
    prediction_pass pass = {0};
    size_t draco_size = 0;
    if (!model->growth_data || !model->growth_offsets)
        return mts_error_set(err, MTS_ERR_ARG,
                             "stream: model '%s' has no split descriptions; rebuild it with "
                             "mts-build",
                             name);
    if (model->key_count > MTS_WIRE_MAX_KEYS)
        return mts_error_set(err, MTS_ERR_LIMIT,
                             "stream: model '%s' has %u key levels, more than a client takes (%u)",
                             name, model->key_count, MTS_WIRE_MAX_KEYS);
    mts_result rc = copy_model(model, &s->model, err);
    if (rc != MTS_OK)
        return rc;
    mts_model *m = &s->model;
    const uint32_t nv = m->vertex_count, nb = m->base_vertex_count, n = m->level_count;
    uint64_t capacity_total = 0;
    for (uint32_t st = 0; st < m->strip_count; st++)
        capacity_total += m->capacity[st];
    if (capacity_total > UINT32_MAX) {
        rc = mts_error_set(err, MTS_ERR_LIMIT, "stream: model '%s' has slots of %llu indices",
                           name, (unsigned long long)capacity_total);
        goto fail;
    }

    /* one grid for base and batches: the full model's box */
    if ((rc = mts_draco_grid_from_positions(m->positions, nv, opts->quant_bits ? opts->quant_bits : 14,
                                            &s->grid, err)) != MTS_OK)
        goto fail;
    s->quantized = malloc((size_t)nv * 12 + 4);
    s->batch_first = NULL;
    s->level_checksum = malloc(((size_t)n + 1) * 8);
    if (!s->quantized || !s->level_checksum)
        goto nomem;
    for (uint32_t x = 0; x < nv; x++) {
        uint32_t *q = s->quantized + 3 * (size_t)x;
        mts_draco_quantize(&s->grid, m->positions + 3 * (size_t)x, q);
        mts_draco_dequantize(&s->grid, q, m->positions + 3 * (size_t)x);
    }
    /* normals, where the stream carries them, as the client will decode
     * them; the codes are kept, since encoding a decoded normal again need
     * not give the same code. The base's are Draco's (encode_base). */
    const int carry_normals = (m->flags & MTS_MODEL_NORMALS_GIVEN) != 0;
    if (!carry_normals) /* the stream stands for what a client holds: none */
        memset(m->normals, 0, (size_t)nv * 12);
    oct = malloc((size_t)nv * 4 + 4);
    if (!oct)
        goto nomem;
    for (uint32_t x = nb; x < nv && carry_normals; x++) {
        uint16_t *o = oct + 2 * (size_t)x;
        mts__stream_oct_encode(m->normals + 3 * (size_t)x, o);
        mts__stream_oct_decode(o, m->normals + 3 * (size_t)x);
    }
    if ((rc = encode_base(s, opts->draco_method, &draco, &draco_size, err)) != MTS_OK)
        goto fail;
    for (uint32_t x = 0; x < nb && carry_normals; x++)
        mts__stream_oct_encode(m->normals + 3 * (size_t)x, oct + 2 * (size_t)x);

    /* levels/100 splits a batch, within 64..2048: a batch is what a client
     * applies between two frames, so a big model gets more than a hundred */
    const uint32_t per = opts->batch_splits ? opts->batch_splits
                         : n / 100 > 2048                ? 2048
                         : n / 100 > 64                  ? n / 100
                                                         : 64;
    s->batch_count = n == 0 ? 0 : (n + per - 1) / per;
    s->batch_first = malloc(((size_t)s->batch_count + 1) * 4);
    s->batch_offset = malloc(((size_t)s->batch_count + 1) * sizeof *s->batch_offset);
    if (!s->batch_first || !s->batch_offset)
        goto nomem;
    for (uint32_t k = 0; k < s->batch_count; k++)
        s->batch_first[k] = k * per;
    s->batch_first[s->batch_count] = n;
    if ((rc = announce_schedule(s, err)) != MTS_OK)
        goto fail;
    mts_stream_breakdown *bd = opts->breakdown;
    if (bd) {
        memset(bd, 0, sizeof *bd);
        bd->vertices = nv;
        bd->base_vertices = nb;
        bd->splits = n;
    }
    /* BASE */
    size_t f = mts_wire_frame_begin(&b, MTS_MSG_BASE);
    mts_buf_varint(&b, (uint32_t)draco_size);
    mts_buf_put(&b, draco, draco_size);
    const size_t strips_at = b.size;
    const uint32_t k0 = s->announced[0];
    mts_buf_varint(&b, k0);
    const size_t caps_at = b.size;
    for (uint32_t st = 0; st < k0; st++)
        mts_buf_varint(&b, m->capacity[st]);
    const size_t caps_bytes = b.size - caps_at;
    for (uint32_t st = 0; st < k0; st++)
        mts_buf_varint(&b, m->base.offsets[st + 1] - m->base.offsets[st]);
    for (uint32_t st = 0; st < k0; st++) {
        uint32_t prev = 0;
        for (uint32_t k = m->base.offsets[st]; k < m->base.offsets[st + 1]; k++) {
            mts_buf_varint(&b, mts_zigzag_u32(m->base.indices[k] - prev));
            prev = m->base.indices[k];
        }
    }
    if (bd) {
        bd->base_draco_bytes = draco_size;
        bd->capacity_bytes = caps_bytes;
        bd->base_strip_bytes = b.size - strips_at - caps_bytes;
    }
    put_crc(&b, f);
    mts_wire_frame_end(&b, f);

    /* BATCHes: per split its parent, how it changes the triangles (the
     * fan code, grow.h) and its vertex, range-coded (PROTOCOL.md, BATCH);
     * the records are the client's to derive. The server first runs the
     * growth a client will run: positions are predicted from the ring a
     * split leaves around its vertex, and the full strips are described on
     * the full level's triangles, which the last batch carries ahead of
     * its splits. */
    if ((rc = predict_all(s, opts, oct, carry_normals, &pass, err)) != MTS_OK)
        goto fail;
    models = malloc(sizeof *models);
    if (!models)
        goto nomem;
    mts__stream_models_init(models);
    for (uint32_t k = 0; k < s->batch_count; k++) {
        const uint32_t first = s->batch_first[k], count = s->batch_first[k + 1] - first;
        s->batch_offset[k] = b.size;
        f = mts_wire_frame_begin(&b, MTS_MSG_BATCH);
        put_batch_head(&b, s, k, 0);
        mts_rc_encoder e;
        mts_rc_encoder_init(&e, &b);
        const size_t coded_at = b.size;
/* the field the next coded bits are counted under, when counting */
#define COUNT_AS(field) (e.cost = bd ? &bd->field : NULL)
        COUNT_AS(capacity_bits);
        encode_capacities(&e, models, s, k);
        for (uint32_t i = 0; i < count; i++) {
            uint32_t j = first + i, v = nb + j, u = m->parents[j];
            const uint32_t *w = m->growth_data + m->growth_offsets[j];
            COUNT_AS(parent_bits);
            encode_parent(&e, models, j ? m->parents[j - 1] : 0, u, v);
            COUNT_AS(fan_bits);
            mts_rc_encode_tree(&e, &models->sides, w[2]);
            if (w[2] == MTS_GROWTH_EXPLICIT) {
                for (uint32_t q = 0; q < 2 + w[3] + 3 * w[4]; q++)
                    mts_rc_encode_uint(&e, &models->lists, w[3 + q]);
            } else {
                mts_rc_encode_uint(&e, &models->start[pass.fan_context[j]], w[0]);
                mts_rc_encode_uint(&e, &models->count[pass.fan_context[j]], w[1]);
            }
            if (j == n - 1) {
                COUNT_AS(full_strips_bits);
                encode_full(&e, models, &pass, m->strip_count, m->level_triangles[n]);
            }
            const int32_t *r = pass.residual + 5 * (size_t)j;
            COUNT_AS(position_bits);
            const unsigned ctx = pass.context[j];
            mts_rc_encode_sint(&e, &models->tangent[ctx], r[0]);
            mts_rc_encode_sint(&e, &models->tangent[ctx], r[1]);
            mts_rc_encode_uint(&e, &models->normal_part[ctx],
                               (uint32_t)(r[2] < 0 ? -(int64_t)r[2] : r[2]));
            if (r[2])
                mts_rc_encode_bit(&e, &models->normal_sign[ctx], r[2] < 0);
            COUNT_AS(normal_bits);
            for (int a = 0; a < 2 && carry_normals; a++)
                mts_rc_encode_sint(&e, &models->normal[a], r[3 + a]);
            COUNT_AS(color_bits);
            for (int c = 0; c < 3 && m->colors; c++) {
                const int16_t *t = pass.color + 3 * (size_t)j;
                mts_rc_encode_sint(
                    &e, &models->color[c][mts__stream_color_context(pass.color_context[j], c, t[0])],
                    t[c]);
            }
        }
#undef COUNT_AS
        e.cost = NULL; /* the flush carries no field */
        mts_rc_encoder_flush(&e);
        if (bd)
            bd->coded_bytes += b.size - coded_at;
        put_crc(&b, f);
        mts_wire_frame_end(&b, f);
    }
    s->batch_offset[s->batch_count] = b.size;
    if (b.failed)
        goto nomem;
    s->bytes = b.data;
    s->size = b.size;
    b.data = NULL;
    s->stream_id = fnv64(s->bytes, s->size) ^ ((uint64_t)s->size << 1);
    if ((rc = level_checksums(s, opts, err)) != MTS_OK)
        goto fail;
    if (build_info_tail(s) != MTS_OK)
        goto nomem;
    if (bd && breakdown_finish(s, bd) != MTS_OK)
        goto nomem;
    /* the codes stay: a records form (now or later) sends them */
    s->oct = carry_normals ? oct : NULL;
    if (!carry_normals)
        free(oct);
    oct = NULL;
    if (opts->with_records && (rc = mts_stream_add_records_form(s, err)) != MTS_OK)
        goto fail;
    free(draco);
    free(models);
    pass_free(&pass);
    return MTS_OK;
nomem:
    rc = mts_error_set(err, MTS_ERR_NOMEM, "stream: out of memory encoding '%s'", name);
fail:
    free(draco);
    free(oct);
    free(models);
    pass_free(&pass);
    mts_buf_free(&b);
    mts_stream_free(s);
    return rc;
}

uint32_t mts_stream_stop_level(const mts_stream *s, uint8_t kind, uint32_t value)
{
    const mts_model *m = &s->model;
    switch (kind) {
    case MTS_STOP_LEVEL:
        return value < m->level_count ? value : m->level_count;
    case MTS_STOP_TRIANGLES:
        return mts_model_level_for_triangles(m, value);
    case MTS_STOP_FRACTION:
        return mts_model_level_for_fraction(m, value / 1e6);
    default:
        return m->level_count;
    }
}

mts_result mts_stream_range(const mts_stream *s, uint32_t resume_batch, uint32_t stop_level,
                            size_t *offset, size_t *length, mts_error *err)
{
    /* batches needed: those whose first split is below the stop level */
    uint32_t end = 0;
    while (end < s->batch_count && s->batch_first[end] < stop_level)
        end++;
    if (resume_batch > end)
        return mts_error_set(err, MTS_ERR_RANGE,
                             "resume from batch %u, but the stream to level %u has %u batches",
                             resume_batch, stop_level, end);
    size_t from = resume_batch == 0 ? 0 : s->batch_offset[resume_batch];
    size_t to = s->batch_count ? s->batch_offset[end] : s->size;
    *offset = from;
    *length = to - from;
    return MTS_OK;
}

/* MODEL_INFO's fields for a stop level; the tail's arrays are left NULL. */
static void info_fields(const mts_stream *s, uint32_t stop_level, mts_wire_model_info *mi)
{
    const mts_model *m = &s->model;
    memset(mi, 0, sizeof *mi);
    mi->minor = MTS_WIRE_MINOR;
    mi->stream_id = s->stream_id;
    snprintf(mi->model, sizeof mi->model, "%s", s->name);
    mi->vertices = m->vertex_count;
    mi->base_vertices = m->base_vertex_count;
    mi->levels = m->level_count;
    mi->triangles = m->level_triangles[m->level_count];
    mi->strips = m->strip_count;
    mi->stop_level = stop_level;
    mi->stop_triangles = m->level_triangles[stop_level];
    memcpy(mi->bbox_min, m->bbox_min, 12);
    memcpy(mi->bbox_max, m->bbox_max, 12);
    mi->quant_bits = (uint8_t)s->grid.bits;
    mi->flags = (uint8_t)(((m->flags & MTS_MODEL_NORMALS_GIVEN) ? MTS_INFO_NORMALS : 0) |
                          (s->records ? MTS_INFO_RECORDS : 0) |
                          (m->colors ? MTS_INFO_COLORS : 0));
    memcpy(mi->grid_origin, s->grid.origin, 12);
    mi->grid_range = s->grid.range;
    mi->batch_count = s->batch_count;
    mi->key_count = m->key_count;
}

/* The part of MODEL_INFO every connection shares, encoded once. */
static mts_result build_info_tail(mts_stream *s)
{
    const mts_model *m = &s->model;
    mts_wire_model_info mi;
    info_fields(s, m->level_count, &mi);
    mts_buf tail = {0};
    /* batches are equal but the last (stream_build), which MODEL_INFO
     * gives as one size */
    mi.batch_size = s->batch_count ? s->batch_first[1] : 0;
    /* the slots' room; each slot's capacity comes when it is first used */
    uint64_t total = 0;
    for (uint32_t st = 0; st < m->strip_count; st++)
        total += m->capacity[st];
    mi.capacity_total = (uint32_t)total; /* < 2^32: checked at build */
    mi.key_levels = m->key_levels;
    mts_wire_put_model_info_tail(&tail, &mi);
    if (tail.failed) {
        mts_buf_free(&tail);
        return MTS_ERR_NOMEM;
    }
    s->info_tail = tail.data;
    s->info_tail_size = tail.size;
    return MTS_OK;
}

static size_t varint_size(uint32_t x)
{
    uint8_t tmp[8];
    return mts_varint_put(tmp, x);
}

/* The breakdown's frames that stream building does not write itself. */
static mts_result breakdown_finish(const mts_stream *s, mts_stream_breakdown *bd)
{
    const mts_model *m = &s->model;
    mts_buf t = {0};
    mts_stream_put_model_info(s, m->level_count, &t);
    bd->info_bytes = t.size;
    t.size = 0;
    mts_stream_put_end(s, m->level_count, (uint32_t)(bd->info_bytes + s->size), &t);
    bd->end_bytes = t.size;
    const int failed = t.failed;
    mts_buf_free(&t);
    if (failed)
        return MTS_ERR_NOMEM;
    for (uint32_t k = 0; k < s->batch_count; k++)
        bd->info_batch_bytes += varint_size(s->batch_first[k + 1] - s->batch_first[k]);
    bd->base_bytes = s->batch_count ? s->batch_offset[0] : s->size;
    bd->batch_bytes = s->size - bd->base_bytes;
    bd->framing_bytes = bd->base_bytes - bd->base_draco_bytes - bd->base_strip_bytes -
                        bd->capacity_bytes + bd->batch_bytes - bd->coded_bytes;
    return MTS_OK;
}

void mts_stream_put_model_info_head(const mts_stream *s, uint32_t stop_level, mts_buf *out)
{
    mts_wire_model_info mi;
    info_fields(s, stop_level, &mi);
    mts_wire_put_model_info_head(out, &mi, s->info_tail_size);
}

void mts_stream_put_model_info(const mts_stream *s, uint32_t stop_level, mts_buf *out)
{
    mts_stream_put_model_info_head(s, stop_level, out);
    mts_buf_put(out, s->info_tail, s->info_tail_size);
}

void mts_stream_put_end(const mts_stream *s, uint32_t stop_level, uint32_t bytes_before_end,
                        mts_buf *out)
{
    mts_wire_end e = {stop_level, s->level_checksum[stop_level], 0};
    /* the END frame counts itself: its size depends on the count, so settle it */
    mts_buf probe = {0};
    for (int i = 0; i < 3; i++) {
        probe.size = 0;
        mts_wire_put_end(&probe, &e);
        e.stream_bytes = bytes_before_end + (uint32_t)probe.size;
    }
    mts_buf_free(&probe);
    mts_wire_put_end(out, &e);
}
