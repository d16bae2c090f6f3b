#include "stream.h"

#include "grow.h"

#include <math.h>
#include <sys/mman.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "crc32c.h"
#include "lframe.h"
#include "rcoder.h"
#include "reccodec.h"
#include "varint.h"

/* ---- shared pieces ---- */

/* Octahedral normal encoding (Meyer et al., "On Floating-Point Normal
 * Vectors", 2010): two numbers of NORMAL_BITS each. 10 bits (Draco's default
 * for normals) is about 0.1 degree, finer than shading shows; each bit more
 * would cost the stream two bits a vertex of noise. Server and client run
 * this same code, so both hold the same decoded normal. */
#define NORMAL_BITS 10
#define NORMAL_MAX ((1 << NORMAL_BITS) - 1)

static void oct_encode(const float n[3], uint16_t out[2])
{
    float l = fabsf(n[0]) + fabsf(n[1]) + fabsf(n[2]);
    float x = l > 0 ? n[0] / l : 0, y = l > 0 ? n[1] / l : 0;
    if (l > 0 && n[2] < 0) {
        float ox = x;
        x = (1 - fabsf(y)) * (ox >= 0 ? 1.0f : -1.0f);
        y = (1 - fabsf(ox)) * (y >= 0 ? 1.0f : -1.0f);
    }
    out[0] = (uint16_t)lrintf((x * 0.5f + 0.5f) * (float)NORMAL_MAX);
    out[1] = (uint16_t)lrintf((y * 0.5f + 0.5f) * (float)NORMAL_MAX);
}

static void oct_decode(const uint16_t in[2], float n[3])
{
    float x = (float)in[0] / (float)NORMAL_MAX * 2.0f - 1.0f,
          y = (float)in[1] / (float)NORMAL_MAX * 2.0f - 1.0f;
    float z = 1.0f - fabsf(x) - fabsf(y);
    if (z < 0) {
        float ox = x;
        x = (1 - fabsf(y)) * (ox >= 0 ? 1.0f : -1.0f);
        y = (1 - fabsf(ox)) * (y >= 0 ? 1.0f : -1.0f);
    }
    float l = sqrtf(x * x + y * y + z * z);
    n[0] = x / l;
    n[1] = y / l;
    n[2] = z / l;
}

static uint64_t mix64(uint64_t h)
{
    h ^= h >> 33;
    h *= 0xff51afd7ed558ccdull;
    h ^= h >> 33;
    h *= 0xc4ceb9fe1a85ec53ull;
    return h ^ (h >> 33);
}

/* A strip's term of the checksum (PROTOCOL.md, END). A server sums it at
 * every level for every strip that changed, so the loop is one multiply
 * and a rotate a pair of indices, not a full mix each; the rotate brings
 * high bits down for the next multiply to spread. */
static uint64_t strip_sum(uint32_t s, const uint32_t *str, uint32_t len)
{
    uint64_t h = mix64(0x5354524950ull ^ ((uint64_t)s << 32 | len));
    uint32_t k = 0;
    for (; k + 1 < len; k += 2) {
        uint64_t w = (uint64_t)str[k] | (uint64_t)str[k + 1] << 32;
        h ^= w;
        h = (h << 31 | h >> 33) * 0x9e3779b97f4a7c15ull;
    }
    if (k < len) {
        h ^= str[k];
        h = (h << 31 | h >> 33) * 0x9e3779b97f4a7c15ull;
    }
    return mix64(h);
}

static uint64_t vertex_sum(uint32_t x, const uint32_t q[3])
{
    return mix64(mix64(mix64(((uint64_t)x << 32) ^ q[0]) ^ q[1]) ^ q[2]);
}

uint64_t mts_stream_checksum(const mts_lod *lod, const uint32_t *quantized)
{
    uint64_t sum = 0;
    for (uint32_t s = 0; s < lod->strip_count; s++) {
        uint32_t len;
        const uint32_t *str = mts_lod_strip(lod, s, &len);
        sum += strip_sum(s, str, len);
    }
    uint32_t nv = lod->model->base_vertex_count + lod->level;
    for (uint32_t x = 0; x < nv; x++)
        sum += vertex_sum(x, quantized + 3 * (size_t)x);
    return sum;
}

/* The adaptive models a stream's splits are coded with (PROTOCOL.md,
 * BATCH). They live as long as the stream, not a batch: server and client
 * code every batch in order (a client resumes with the models it has), so
 * each batch starts from what the ones before it taught, and the first few
 * hundred splits pay for the learning once, not once a batch. */
#define POSITION_CONTEXTS 16
#define FAN_CONTEXTS 32
struct mts__stream_models {
    /* a fan code's start and count by the parent's ring (fan_context) */
    mts_rc_uint_model parent, parent_gap, start[FAN_CONTEXTS], count[FAN_CONTEXTS], lists;
    uint16_t parent_up; /* whether a parent is at least the one before it */
    mts_rc_tree_model sides;
    mts_rc_uint_model full_triangles;
    mts_rc_uint_model capacity; /* the slots a batch announces */
    mts_rc_tree_model rotation;
    uint16_t full_near;            /* a full strip starts next to the one before */
    mts_rc_uint_model full_near_at; /* where among the triangles there */
    uint16_t swap[2];              /* by the previous swap bit */
    /* a position residual in its local frame (lframe.h): the two tangent
     * coordinates, the normal one's magnitude and sign, by context */
    mts_rc_uint_model tangent[POSITION_CONTEXTS], normal_part[POSITION_CONTEXTS];
    uint16_t normal_sign[POSITION_CONTEXTS];
    mts_rc_uint_model normal[2];
};

static void models_init(struct mts__stream_models *m)
{
    mts_rc_uint_model_init(&m->parent);
    mts_rc_uint_model_init(&m->parent_gap);
    mts_rc_prob_init(&m->parent_up, 1);
    for (int k = 0; k < FAN_CONTEXTS; k++) {
        mts_rc_uint_model_init(&m->start[k]);
        mts_rc_uint_model_init(&m->count[k]);
    }
    mts_rc_uint_model_init(&m->lists);
    mts_rc_tree_model_init(&m->sides, 3);
    mts_rc_uint_model_init(&m->full_triangles);
    mts_rc_uint_model_init(&m->capacity);
    mts_rc_tree_model_init(&m->rotation, 2);
    mts_rc_prob_init(&m->full_near, 1);
    mts_rc_uint_model_init(&m->full_near_at);
    mts_rc_prob_init(m->swap, 2);
    for (int k = 0; k < POSITION_CONTEXTS; k++) {
        mts_rc_uint_model_init(&m->tangent[k]);
        mts_rc_uint_model_init(&m->normal_part[k]);
    }
    mts_rc_prob_init(m->normal_sign, POSITION_CONTEXTS);
    mts_rc_uint_model_init(&m->normal[0]);
    mts_rc_uint_model_init(&m->normal[1]);
}

/* The context a fan code is coded in: the parent's ring (the triangles
 * round it, 15 for 15 or more, +16 when it closes), which both ends know
 * before the code. A start is about uniform over the ring and a count
 * about half of it, so one model for all rings spends bits on the mix. */
static unsigned fan_context(struct mts_grow *g, uint32_t u)
{
    int closed;
    int32_t k = mts_grow_ring_size(g, u, &closed);
    if (k < 0)
        k = 0;
    return (unsigned)(k < 15 ? k : 15) + (closed ? 16u : 0u);
}

/* x / 2^shift toward zero, as C's division would give it, without a
 * division: these run a dozen times a split */
static inline int64_t shrink(int64_t x, unsigned shift)
{
    return x < 0 ? -(int64_t)((uint64_t)-x >> shift) : (int64_t)((uint64_t)x >> shift);
}

/* n += (q(a) - o) x (q(b) - o), each difference first shrunk by `shift`
 * (differences of up to 2^16 keep each cross product under 2^33 and a sum
 * over any ring far from int64's limits): a ring's normal, pair by pair. */
static inline void add_cross(const uint32_t *qa, const uint32_t *qb, const uint32_t *o,
                             unsigned shift, int64_t n[3])
{
    int64_t a[3], b[3];
    for (int x = 0; x < 3; x++) {
        a[x] = shrink((int64_t)qa[x] - o[x], shift);
        b[x] = shrink((int64_t)qb[x] - o[x], shift);
    }
    n[0] += a[1] * b[2] - a[2] * b[1];
    n[1] += a[2] * b[0] - a[0] * b[2];
    n[2] += a[0] * b[1] - a[1] * b[0];
}

/* Where a new vertex is expected: the mean of the corners around it right
 * after its split (grow.h, mts_grow_around_newest), on the grid; the local
 * frame its residual is coded in (lframe.h), from the ring's normal: the
 * sum over the triangles (v, a, b) of (q(a) - pred) x (q(b) - pred), which
 * does not need v; and, as the context, the ring's spread (the mean over
 * the corners of their largest per-axis distance from the prediction: a
 * local edge length, which residuals scale with). Server and client hold
 * the same ring and the same grid points, so they agree exactly. */
static unsigned predict_position(const uint32_t *around, uint32_t k, const uint32_t *quantized,
                                 uint32_t parent, unsigned grid_bits, int64_t pred[3],
                                 mts_lframe *frame)
{
    const uint32_t *qu = quantized + 3 * (size_t)parent;
    const int64_t zero[3] = {0, 0, 0};
    if (k == 0) {
        for (int a = 0; a < 3; a++)
            pred[a] = qu[a];
        mts_lframe_make(zero, frame);
        return 0;
    }
    /* one pass over the pairs (around holds pairs: k is even): the sum,
     * and the normal about u (for a closed ring the same about any point) */
    const unsigned shift = grid_bits > 16 ? grid_bits - 16 : 0;
    uint64_t sum[3] = {0, 0, 0};
    int64_t n[3] = {0, 0, 0};
    for (uint32_t i = 0; i + 1 < k; i += 2) {
        const uint32_t *qa = quantized + 3 * (size_t)around[i];
        const uint32_t *qb = quantized + 3 * (size_t)around[i + 1];
        for (int x = 0; x < 3; x++)
            sum[x] += (uint64_t)qa[x] + qb[x];
        add_cross(qa, qb, qu, shift, n);
    }
    uint64_t far = 0;
    /* an eighth of the way from the centroid to u: a collapse kept u and
     * took v off towards its ring's middle, and on every mesh tried this
     * takes 1-2 % off the positions (0 on one) */
    for (int a = 0; a < 3; a++) {
        pred[a] = (int64_t)((7 * sum[a] + (uint64_t)k * qu[a] + 4 * (uint64_t)k) / (8 * (uint64_t)k));
        uint64_t d = (uint64_t)(pred[a] > qu[a] ? pred[a] - qu[a] : qu[a] - pred[a]);
        far = d > far ? d : far;
    }
    mts_lframe_make(n, frame);
    unsigned ctx = 0;
    while (far >> ctx && ctx < POSITION_CONTEXTS - 1)
        ctx++;
    return ctx;
}

/* Where a new vertex's normal is expected: the area-weighted normal of the
 * faces around it right after its split (pairs from
 * mts_grow_around_newest, v's grid point already decoded), as an
 * octahedral code; the parent's code where the faces have no area. All in
 * integers: a prediction must come out bit for bit the same on every
 * platform, and floating-point contraction may differ between builds. */
static void predict_normal(const uint32_t *around, uint32_t k, const uint32_t *quantized,
                           uint32_t v, unsigned grid_bits, const uint16_t parent_code[2],
                           uint16_t code[2])
{
    const unsigned shift = grid_bits > 16 ? grid_bits - 16 : 0;
    const uint32_t *qv = quantized + 3 * (size_t)v;
    int64_t n[3] = {0, 0, 0};
    for (uint32_t i = 0; i + 1 < k; i += 2)
        add_cross(quantized + 3 * (size_t)around[i], quantized + 3 * (size_t)around[i + 1], qv,
                  shift, n);
    /* keep |x| + |y| + |z| under 2^40 so NORMAL_MAX times it fits; halving
     * (toward zero, as C divides) keeps the direction */
    for (;;) {
        int64_t l = (n[0] < 0 ? -n[0] : n[0]) + (n[1] < 0 ? -n[1] : n[1]) +
                    (n[2] < 0 ? -n[2] : n[2]);
        if (l < ((int64_t)1 << 40))
            break;
        n[0] /= 2;
        n[1] /= 2;
        n[2] /= 2;
    }
    int64_t ax = n[0] < 0 ? -n[0] : n[0], ay = n[1] < 0 ? -n[1] : n[1],
            az = n[2] < 0 ? -n[2] : n[2], l = ax + ay + az;
    if (l == 0) {
        code[0] = parent_code[0];
        code[1] = parent_code[1];
        return;
    }
    /* oct_encode's map with x / l and y / l as fractions: the lower half
     * folds over the diagonals (a zero component counts as positive) */
    int64_t x = n[0], y = n[1];
    if (n[2] < 0) {
        x = (l - ay) * (n[0] >= 0 ? 1 : -1);
        y = (l - ax) * (n[1] >= 0 ? 1 : -1);
    }
    /* round(NORMAL_MAX (x + l) / 2l), x + l in [0, 2l] */
    code[0] = (uint16_t)((NORMAL_MAX * (x + l) + l) / (2 * l));
    code[1] = (uint16_t)((NORMAL_MAX * (y + l) + l) / (2 * l));
}

/* ---- server ---- */

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
        !dst->level_indices || !dst->capacity || !dst->key_levels ||
        (src->growth_offsets && !dst->growth_offsets) || (src->growth_data && !dst->growth_data) ||
        mts_strips_alloc(&dst->full, src->strip_count, src->full.index_count, err) != MTS_OK ||
        mts_strips_alloc(&dst->base, src->strip_count, src->base.index_count, err) != MTS_OK) {
        mts_model_free(dst);
        return mts_error_set(err, MTS_ERR_NOMEM, "stream: out of memory copying the model");
    }
    memcpy(dst->positions, src->positions, nv * 12);
    memcpy(dst->normals, src->normals, nv * 12);
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
    int ok = pos && nor && q;
    if (ok) {
        for (uint32_t x = 0; x < nb; x++) {
            memcpy(pos + 3 * (size_t)map[x], m->positions + 3 * (size_t)x, 12);
            memcpy(nor + 3 * (size_t)map[x], m->normals + 3 * (size_t)x, 12);
            memcpy(q + 3 * (size_t)map[x], quantized + 3 * (size_t)x, 12);
        }
        memcpy(m->positions, pos, (size_t)nb * 12);
        memcpy(m->normals, nor, (size_t)nb * 12);
        memcpy(quantized, q, (size_t)nb * 12);
    }
    free(pos);
    free(nor);
    free(q);
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

/* A base vertex's place in grid order (x, then y, then z; ties in Draco's
 * order): the stream's base ids (PROTOCOL.md, BASE). */
typedef struct grid_key {
    uint32_t q[3], d;
} grid_key;

static int cmp_grid_key(const void *a, const void *b)
{
    const grid_key *x = a, *y = b;
    for (int k = 0; k < 3; k++) {
        if (x->q[k] != y->q[k])
            return x->q[k] < y->q[k] ? -1 : 1;
    }
    return x->d < y->d ? -1 : x->d > y->d;
}

/* Puts Draco's decoded vertices in grid order, in place, and gives each
 * decoded id its new one (rank, when not NULL). Builders number the base in
 * the order of its positions (build.c), so this is mostly no renaming at
 * all, and splits sorted by parent stay sorted on the wire; Draco's own
 * order (Edgebreaker's traversal) is the builder's shuffled. 0 when out of
 * memory. */
static int base_in_grid_order(mts_draco_mesh_out *dec, uint32_t *rank)
{
    const uint32_t nv = dec->vertex_count;
    grid_key *k = malloc(((size_t)nv + 1) * sizeof *k);
    uint32_t *r = malloc(((size_t)nv + 1) * 4);
    float *f = malloc(((size_t)nv + 1) * 12);
    uint32_t *q = malloc(((size_t)nv + 1) * 12);
    int ok = k && r && f && q;
    if (ok) {
        for (uint32_t d = 0; d < nv; d++) {
            memcpy(k[d].q, dec->quantized + 3 * (size_t)d, 12);
            k[d].d = d;
        }
        qsort(k, nv, sizeof *k, cmp_grid_key);
        for (uint32_t x = 0; x < nv; x++)
            r[k[x].d] = x;
        for (uint32_t d = 0; d < nv; d++)
            memcpy(q + 3 * (size_t)r[d], dec->quantized + 3 * (size_t)d, 12);
        memcpy(dec->quantized, q, (size_t)nv * 12);
        for (uint32_t d = 0; d < nv; d++)
            memcpy(f + 3 * (size_t)r[d], dec->positions + 3 * (size_t)d, 12);
        memcpy(dec->positions, f, (size_t)nv * 12);
        for (uint32_t d = 0; dec->normals && d < nv; d++)
            memcpy(f + 3 * (size_t)r[d], dec->normals + 3 * (size_t)d, 12);
        if (dec->normals)
            memcpy(dec->normals, f, (size_t)nv * 12);
        for (size_t i = 0; i < 3 * (size_t)dec->triangle_count; i++)
            dec->triangles[i] = dec->triangles[i] < nv ? r[dec->triangles[i]] : dec->triangles[i];
        if (rank)
            memcpy(rank, r, (size_t)nv * 4);
    }
    free(k);
    free(r);
    free(f);
    free(q);
    return ok;
}

/* Encodes the base with Draco, decodes it back and renumbers the model to the
 * decoded vertices in grid order (base_in_grid_order); falls back to the
 * order-keeping sequential method when Edgebreaker changed the mesh itself
 * (split or dropped vertices). */
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
        mts_draco_mesh in = {nb, nt, m->positions, carry_normals ? m->normals : NULL, tris};
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
    if (!rank || !base_in_grid_order(&dec, rank)) {
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
    uint64_t sum = mts_stream_checksum(&lod, s->quantized);
    for (uint32_t st = 0; st < m->strip_count; st++) {
        uint32_t len;
        const uint32_t *str = mts_lod_strip(&lod, st, &len);
        hs[st] = strip_sum(st, str, len);
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
            hs[st] = strip_sum(st, str, len);
            sum += hs[st];
        }
        mts_lod_clear_changed(&lod);
        uint32_t v = m->base_vertex_count + l;
        sum += vertex_sum(v, s->quantized + 3 * (size_t)v);
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
    uint8_t *fan_context; /* per split: its fan code's context */
    mts_grow_full_path *paths;
    uint8_t *swaps;
    uint64_t swap_count;
} prediction_pass;

static void pass_free(prediction_pass *p)
{
    free(p->residual);
    free(p->context);
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
    if (!pass->residual || !pass->context || !pass->fan_context || !pass->paths || !pass->swaps)
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
        pass->fan_context[j] = (uint8_t)fan_context(g, u);
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
        pass->context[j] = (uint8_t)predict_position(around, k, s->quantized, u, s->grid.bits,
                                                     pred, &frame);
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
            predict_normal(around, k, s->quantized, v, s->grid.bits, oct + 2 * (size_t)u, code);
            r[3] = (int32_t)oct[2 * (size_t)v] - code[0];
            r[4] = (int32_t)oct[2 * (size_t)v + 1] - code[1];
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

/* The bits a triangle id of the full level takes. */
static unsigned triangle_id_bits(uint32_t triangles)
{
    unsigned b = 0;
    while (b < 32 && (triangles - 1) >> b)
        b++;
    return b;
}

static void encode_full(mts_rc_encoder *e, struct mts__stream_models *md,
                        const prediction_pass *pass, uint32_t slots, uint32_t triangles)
{
    const unsigned id_bits = triangle_id_bits(triangles);
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
        oct_encode(m->normals + 3 * (size_t)x, o);
        oct_decode(o, m->normals + 3 * (size_t)x);
    }
    if ((rc = encode_base(s, opts->draco_method, &draco, &draco_size, err)) != MTS_OK)
        goto fail;
    for (uint32_t x = 0; x < nb && carry_normals; x++)
        oct_encode(m->normals + 3 * (size_t)x, oct + 2 * (size_t)x);

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
    models_init(models);
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
                          (s->records ? MTS_INFO_RECORDS : 0));
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

/* ---- client ---- */

/* ST_SKIP_BASE: a resumed conversation that the server started from batch 0
 * after our base was in; its BASE is the one we hold (same stream_id). */
enum { ST_INFO = 0, ST_BASE, ST_BATCHES, ST_DONE, ST_FAILED, ST_SKIP_BASE };

/* A client reserves room per level and per slot for the counts MODEL_INFO
 * announces before any data arrives (take_info bounds the slots by the
 * vertices), so those counts are capped: 2^24 vertices (a 16M-vertex model
 * holds about 1.2 GB here once it has all come). */
#define CLIENT_MAX_VERTICES (1u << 24)
#define RECORDS_HUGE ((size_t)2 << 20) /* a huge page */

void mts_stream_client_init(mts_stream_client *c)
{
    memset(c, 0, sizeof *c);
}

void mts_stream_client_free(mts_stream_client *c)
{
    if (c->have_lod)
        mts_lod_free(&c->lod);
    mts_grow_free(c->grow);
    free(c->models);
    free(c->oct);
    mts_wire_model_info_free(&c->info);
    mts_model_free(&c->model);
    free(c->quantized);
    memset(c, 0, sizeof *c);
}

static mts_result fail(mts_stream_client *c, mts_result rc)
{
    c->state = ST_FAILED;
    return rc;
}

static int crc_ok(const uint8_t *payload, size_t size)
{
    if (size < 4)
        return 0;
    const uint8_t *t = payload + size - 4;
    uint32_t want = (uint32_t)t[0] | (uint32_t)t[1] << 8 | (uint32_t)t[2] << 16 |
                    (uint32_t)t[3] << 24;
    return mts_crc32c(0, payload, size - 4) == want;
}

/* A frame that failed its CRC: nothing of it applied and the state as it
 * was, so a resumed conversation can bring it again (c->rejected). */
static mts_result reject(mts_stream_client *c, mts_result rc)
{
    c->rejected = 1;
    return rc;
}

static mts_result take_info(mts_stream_client *c, const uint8_t *p, size_t n, mts_error *err)
{
    mts_result rc = mts_wire_parse_model_info(p, n, &c->info, err);
    if (rc != MTS_OK)
        return rc;
    const mts_wire_model_info *mi = &c->info;
    /* Every count here is the server's word, and what the client sizes
     * before data arrives follows from them, so each is held to what the
     * others and the stream's invariants allow (PROTOCOL.md, MODEL_INFO,
     * "What a client checks"), and the claim that cannot be true is named.
     * Vertices are the root: capped here, and what they claim is only
     * reserved, the per-vertex arrays growing as vertices arrive. */
    if (mi->vertices > CLIENT_MAX_VERTICES)
        return mts_error_set(err, MTS_ERR_LIMIT,
                             "MODEL_INFO claims %u vertices (%u base, %u levels); this client "
                             "takes at most %u",
                             mi->vertices, mi->base_vertices, mi->levels, CLIENT_MAX_VERTICES);
    /* a builder keeps no vertex outside a triangle (mesh cleaning drops
     * them), so the full level's triangles have every vertex as a corner */
    if ((uint64_t)mi->vertices > 3ull * mi->triangles)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "MODEL_INFO claims %u vertices (%u base, %u levels) for %u "
                             "triangles, which have at most %llu corners",
                             mi->vertices, mi->base_vertices, mi->levels, mi->triangles,
                             3ull * mi->triangles);
    /* no triangle goes away on the way up: every level has at most the
     * full level's */
    if (mi->stop_triangles > mi->triangles)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "MODEL_INFO claims %u triangles at the stop level, more than the "
                             "%u of the full level",
                             mi->stop_triangles, mi->triangles);
    /* A slot holds a strip of a triangle at least at some level (else it
     * would not be one), and growth opens a slot only when every one it has
     * holds a strip: there are never more slots than the triangles of one
     * level, which are at most the full level's (built models: 5.5 to 6.6
     * slots a hundred triangles). */
    if (mi->strips > mi->triangles)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "MODEL_INFO claims %u strips for %u triangles", mi->strips,
                             mi->triangles);
    const uint64_t cap = mi->capacity_total;
    /* every full-level triangle is drawn by a strip no longer than its
     * slot, so the capacities bound the triangles, and with them every
     * count the batches may announce (explicit lists, the full strips) */
    if (mi->triangles > cap)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "MODEL_INFO claims %u triangles, more than strip capacities of "
                             "%llu indices can draw",
                             mi->triangles, (unsigned long long)cap);
    /* a slot's capacity is its longest strip, three indices at least */
    if (3ull * mi->strips > cap)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "MODEL_INFO claims %u strips, but strip capacities of %llu indices "
                             "hold at most %llu (three a strip)",
                             mi->strips, (unsigned long long)cap, (unsigned long long)cap / 3);
    /* A capacity is the longest its slot is at any level, so the slots add
     * up to more than any one level's strips, but not by much: built models
     * hold 4.3 to 4.7 capacity per vertex (cow, bunny00, fandisk_large; 2.4
     * indices per vertex at the full level). 16 per vertex is this client's
     * bound (the one that is a policy, not an invariant), and with the
     * checks above it bounds the triangles and slots too. */
    if (cap > 16ull * mi->vertices)
        return mts_error_set(err, MTS_ERR_LIMIT,
                             "MODEL_INFO claims %llu indices of strip capacity for %u vertices "
                             "(this client takes 16 a vertex)",
                             (unsigned long long)cap, mi->vertices);
    mts_model *m = &c->model;
    size_t n1 = (size_t)mi->levels + 1;
    m->vertex_count = mi->vertices;
    m->base_vertex_count = mi->base_vertices;
    m->level_count = mi->levels;
    m->strip_count = mi->strips;
    memcpy(m->bbox_min, mi->bbox_min, 12);
    memcpy(m->bbox_max, mi->bbox_max, 12);
    snprintf(m->source, sizeof m->source, "%s", mi->model);
    /* the per-vertex arrays come with the vertices (reserve_vertices);
     * these stay untouched but for the levels and slots that arrive */
    m->parents = calloc(n1, 4);
    m->record_offsets = calloc(n1, 4);
    m->capacity = calloc((size_t)mi->strips + 1, 4);
    c->models = malloc(sizeof *c->models);
    if (mi->flags & MTS_INFO_NORMALS)
        m->flags = MTS_MODEL_NORMALS_GIVEN;
    c->vertex_room = 0;
    if (!m->parents || !m->record_offsets || !m->capacity || !c->models ||
        mts_strips_alloc(&m->full, mi->strips, 0, err) != MTS_OK)
        return mts_error_set(err, MTS_ERR_NOMEM,
                             "MODEL_INFO: out of memory for %u levels and %u strips", mi->levels,
                             mi->strips);
    /* The slots' room is MODEL_INFO's total; each slot's capacity (the
     * longest it is at any level) comes with BASE or the batch that first
     * uses it, and is 0 until then (take_capacities). The full strips never
     * travel: this model's full strips are strip_count empty ones, so it may
     * start runtimes at the base (which reads base and capacity), never at
     * the full level, and is not for mts_model_validate or mts_verify_model. */
    m->capacity_room = cap;
    c->announced = 0;
    c->announced_sum = 0;
    models_init(c->models);
    c->grid.bits = mi->quant_bits;
    memcpy(c->grid.origin, mi->grid_origin, 12);
    c->grid.range = mi->grid_range;
    c->stop_level = mi->stop_level;
    c->records = (mi->flags & MTS_INFO_RECORDS) != 0;
    /* Records that pass mts_lod_split may still be padded (edits that
     * change nothing, runs put back), so what a records-form client keeps
     * is bounded here by the model: a key level's record rewrites every
     * slot (erase and insert at most its capacity, 5 words of header), and
     * 256 words a split on top. Built models use an eighth of it (bunny00:
     * 1.73 M words of 13.7 M; 24 words a split between key levels, 650 at
     * most). */
    c->record_word_limit = 256ull * mi->levels +
                           (mi->key_count + 1ull) * (2 * cap + 5ull * mi->strips);
    return MTS_OK;
}

/* A resumed conversation's MODEL_INFO against the first one: everything the
 * client's state depends on must be equal, or the batches to come belong to
 * another stream. The minor version may differ (a server upgraded in
 * between speaks the same stream). */
static mts_result check_resumed_info(mts_stream_client *c, const uint8_t *p, size_t n,
                                     mts_error *err)
{
    mts_wire_model_info mi = {0};
    mts_result rc = mts_wire_parse_model_info(p, n, &mi, err);
    if (rc != MTS_OK)
        return rc;
    const mts_wire_model_info *a = &c->info;
    const char *what = NULL;
    if (mi.stream_id != a->stream_id)
        what = "stream_ids";
    else if (strcmp(mi.model, a->model) != 0)
        what = "names";
    else if (mi.vertices != a->vertices || mi.base_vertices != a->base_vertices ||
             mi.levels != a->levels || mi.triangles != a->triangles || mi.strips != a->strips)
        what = "counts";
    else if (!c->continuing &&
             (mi.stop_level != a->stop_level || mi.stop_triangles != a->stop_triangles))
        what = "stop levels";
    else if (c->continuing && (mi.stop_level < c->lod.level || mi.stop_level > a->levels))
        what = "stop levels (a continuation's may only rise)";
    else if (mi.flags != a->flags)
        what = "flags (normals, form)";
    else if (memcmp(mi.bbox_min, a->bbox_min, 12) != 0 ||
             memcmp(mi.bbox_max, a->bbox_max, 12) != 0 || mi.quant_bits != a->quant_bits ||
             memcmp(mi.grid_origin, a->grid_origin, 12) != 0 ||
             memcmp(&mi.grid_range, &a->grid_range, 4) != 0)
        what = "grids";
    else if (mi.batch_count != a->batch_count || mi.batch_size != a->batch_size)
        what = "batches";
    else if (mi.capacity_total != a->capacity_total)
        what = "strip capacities";
    else if (mi.key_count != a->key_count ||
             (a->key_count && memcmp(mi.key_levels, a->key_levels, (size_t)a->key_count * 4) != 0))
        what = "key levels";
    if (!what && c->continuing) {
        /* the new stop: the runtime goes up to it as far as the splits held
         * allow (the last batch decoded may reach past the old stop) */
        c->info.stop_level = c->stop_level = mi.stop_level;
        c->info.stop_triangles = mi.stop_triangles;
        uint32_t target = c->splits < c->stop_level ? c->splits : c->stop_level;
        rc = mts_lod_set_level(&c->lod, target, err);
        if (rc != MTS_OK) {
            mts_wire_model_info_free(&mi);
            return rc;
        }
    }
    if (what)
        rc = mts_error_set(err, MTS_ERR_FORMAT,
                           "MODEL_INFO on resume: '%s' is now another stream (%s differ: stream "
                           "%016llx, was %016llx) than the one this client holds %u batches of; "
                           "not mixing two streams",
                           mi.model, what, (unsigned long long)mi.stream_id,
                           (unsigned long long)a->stream_id, c->batches);
    mts_wire_model_info_free(&mi);
    return rc;
}

/* Capacities for slots c->announced .. upto-1 (PROTOCOL.md, "Capacities"):
 * announced in order, never more slots than there are, and together never
 * past MODEL_INFO's total, which the client's runtime reserved. They come as
 * varints from cur (BASE, the records form) or coded from d (the splits
 * form's batches). The runtime lays the new slots out once it has started
 * (after BASE). */
static mts_result take_capacities(mts_stream_client *c, mts_cursor *cur, mts_rc_decoder *d,
                                  uint32_t upto, const char *frame, mts_error *err)
{
    mts_model *m = &c->model;
    const uint32_t from = c->announced;
    /* a varint is a byte at least; a coded one is bounded by the total */
    if (upto < from || upto > m->strip_count || (cur && upto - from > mts_cursor_left(cur)))
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "%s: capacities for slots up to %u (%u announced, %u slots) are "
                             "malformed",
                             frame, upto, from, m->strip_count);
    uint64_t sum = c->announced_sum;
    uint32_t s = from;
    for (; s < upto && sum <= c->info.capacity_total; s++) {
        m->capacity[s] = cur ? mts_cursor_varint(cur) : mts_rc_decode_uint(d, &c->models->capacity);
        sum += m->capacity[s];
    }
    if ((cur ? !cur->ok : !d->ok) || sum > c->info.capacity_total) {
        for (uint32_t x = from; x < s; x++)
            m->capacity[x] = 0;
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "%s: strip capacities add up to %llu or more, past MODEL_INFO's %u",
                             frame, (unsigned long long)sum, c->info.capacity_total);
    }
    c->announced = upto;
    c->announced_sum = sum;
    if (c->have_lod) {
        mts_result rc = mts_lod_announce(&c->lod, from, err);
        if (rc != MTS_OK)
            return mts_error_prefix(err, "%s", frame);
    }
    return MTS_OK;
}

/* Room in the per-vertex arrays for `count` vertices (at most the model's).
 * They hold the vertices that arrived, the base once decoded and each split
 * as it is decoded, not what MODEL_INFO claims: a server that claims
 * millions of vertices and sends a few thousand costs a few thousand.
 * Doubling keeps the copying to a constant a vertex; the new normals are
 * zero, as a stream without normals leaves them. 0 when out of memory (the
 * arrays that did grow stay valid). */
static int reserve_vertices(mts_stream_client *c, uint32_t count)
{
    mts_model *m = &c->model;
    if (count <= c->vertex_room)
        return 1;
    uint64_t room = 2ull * c->vertex_room;
    if (room < count)
        room = count;
    if (room > m->vertex_count)
        room = m->vertex_count;
    if (room < count)
        return 0;
    float *pos = realloc(m->positions, (size_t)room * 12);
    if (pos)
        m->positions = pos;
    float *nrm = realloc(m->normals, (size_t)room * 12);
    if (nrm) {
        memset(nrm + 3 * (size_t)c->vertex_room, 0, (size_t)(room - c->vertex_room) * 12);
        m->normals = nrm;
    }
    uint32_t *q = realloc(c->quantized, (size_t)room * 12);
    if (q)
        c->quantized = q;
    uint16_t *o = NULL;
    if ((m->flags & MTS_MODEL_NORMALS_GIVEN) && (o = realloc(c->oct, (size_t)room * 4)) != NULL)
        c->oct = o;
    if (!pos || !nrm || !q || ((m->flags & MTS_MODEL_NORMALS_GIVEN) && !o))
        return 0;
    c->vertex_room = (uint32_t)room;
    return 1;
}

static mts_result take_base(mts_stream_client *c, const uint8_t *p, size_t n, mts_error *err)
{
    /* the CRC has checked out (mts_stream_client_frame) */
    mts_model *m = &c->model;
    const uint32_t nb = m->base_vertex_count;
    mts_cursor cur = mts_cursor_make(p, n - 4);
    uint32_t dsize = mts_cursor_varint(&cur);
    const uint8_t *draco = mts_cursor_bytes(&cur, dsize);
    if (!draco)
        return mts_error_set(err, MTS_ERR_FORMAT, "BASE: Draco mesh runs past the message");
    mts_draco_mesh_out dec = {0};
    mts_result rc = mts_draco_decode(draco, dsize, &dec, err);
    if (rc != MTS_OK)
        return mts_error_prefix(err, "BASE");
    const int carry_normals = (m->flags & MTS_MODEL_NORMALS_GIVEN) != 0;
    if (dec.vertex_count != nb || (dec.normals != NULL) != carry_normals ||
        dec.grid.bits != c->grid.bits ||
        memcmp(dec.grid.origin, c->grid.origin, 12) != 0 || dec.grid.range != c->grid.range) {
        rc = mts_error_set(err, MTS_ERR_FORMAT,
                           "BASE: Draco mesh has %u vertices (expected %u), another grid, or "
                           "normals where MODEL_INFO says %s",
                           dec.vertex_count, nb, carry_normals ? "there are" : "there are none");
        mts_draco_mesh_out_free(&dec);
        return rc;
    }
    /* no triangle goes away on the way up: the base has at most the
     * triangles of any level */
    if (dec.triangle_count > c->info.stop_triangles) {
        rc = mts_error_set(err, MTS_ERR_FORMAT,
                           "BASE: Draco mesh has %u triangles, more than the %u MODEL_INFO "
                           "claims at the stop level",
                           dec.triangle_count, c->info.stop_triangles);
        mts_draco_mesh_out_free(&dec);
        return rc;
    }
    if (!base_in_grid_order(&dec, NULL) || !reserve_vertices(c, nb)) {
        mts_draco_mesh_out_free(&dec);
        return mts_error_set(err, MTS_ERR_NOMEM, "BASE: out of memory for %u vertices", nb);
    }
    memcpy(m->positions, dec.positions, (size_t)nb * 12);
    if (carry_normals) {
        memcpy(m->normals, dec.normals, (size_t)nb * 12);
        for (uint32_t x = 0; x < nb; x++)
            oct_encode(m->normals + 3 * (size_t)x, c->oct + 2 * (size_t)x);
    }
    memcpy(c->quantized, dec.quantized, (size_t)nb * 12);
    mts_draco_mesh_out_free(&dec);

    /* the slots the base uses, their capacities and lengths (each within
     * its capacity); then the indices */
    const uint32_t k0 = mts_cursor_varint(&cur);
    if ((rc = take_capacities(c, &cur, NULL, k0, "BASE", err)) != MTS_OK)
        return rc;
    uint64_t total = 0;
    if (k0 > mts_cursor_left(&cur))
        return mts_error_set(err, MTS_ERR_FORMAT, "BASE: %u strip lengths cannot fit", k0);
    /* the announced slots' lengths: a varint each, so no more than the
     * message holds; the slots after them are empty at level 0 */
    uint32_t *lens = calloc((size_t)k0 + 1, 4);
    if (!lens)
        return mts_error_set(err, MTS_ERR_NOMEM, "BASE: out of memory");
    for (uint32_t s = 0; s < k0; s++) {
        lens[s] = mts_cursor_varint(&cur);
        total += lens[s];
        if (lens[s] > m->capacity[s]) {
            uint32_t len = lens[s];
            free(lens);
            return mts_error_set(err, MTS_ERR_RANGE,
                                 "BASE: strip %u has %u indices, more than its slot's capacity %u",
                                 s, len, m->capacity[s]);
        }
    }
    if (!cur.ok || total > mts_cursor_left(&cur)) {
        free(lens);
        return mts_error_set(err, MTS_ERR_FORMAT, "BASE: strip indices cannot fit the message");
    }
    if ((rc = mts_strips_alloc(&m->base, m->strip_count, (uint32_t)total, err)) != MTS_OK) {
        free(lens);
        return rc;
    }
    uint32_t o = 0;
    for (uint32_t s = 0; s < m->strip_count; s++) {
        m->base.offsets[s] = o;
        uint32_t prev = 0;
        for (uint32_t k = 0; s < k0 && k < lens[s]; k++) {
            prev += mts_unzigzag_u32(mts_cursor_varint(&cur));
            if (prev >= nb) {
                free(lens);
                return mts_error_set(err, MTS_ERR_RANGE,
                                     "BASE: strip %u index %u is not a base vertex (%u)", s, prev,
                                     nb);
            }
            m->base.indices[o++] = prev;
        }
    }
    m->base.offsets[m->strip_count] = o;
    free(lens);
    if (!cur.ok || mts_cursor_left(&cur) != 0)
        return mts_error_set(err, MTS_ERR_FORMAT, "BASE: malformed strips");
    /* the records form brings every record: nothing to grow */
    mts_grow_options go = {0};
    go.key_levels = c->info.key_levels;
    go.key_count = c->info.key_count;
    if (!c->records &&
        (rc = mts_grow_create(&m->base, nb, m->level_count, &go, &c->grow, err)) != MTS_OK)
        return mts_error_prefix(err, "BASE");
    if ((rc = mts_lod_init(&c->lod, m, MTS_LOD_AT_BASE, err)) != MTS_OK)
        return rc;
    c->have_lod = 1;
    mts_lod_set_available(&c->lod, 0);
    return MTS_OK;
}

/* Room in the client's model for `words` more record words from word `at`.
 * A whole model's records run to megabytes (bunny00: 1.7 M words), and a
 * fresh page costs a fault on first touch, which on a virtual machine is
 * dearer than decoding the page's records: large buffers are asked for in
 * huge pages where the kernel gives them (madvise; a hint, nothing more). */
static mts_result reserve_records(mts_stream_client *c, size_t at, size_t words, mts_error *err)
{
    mts_model *m = &c->model;
    if (words > UINT32_MAX - 1 - at)
        return mts_error_set(err, MTS_ERR_LIMIT, "BATCH: records past 2^32 words");
    if (at + words + 1 <= c->record_capacity)
        return MTS_OK;
    size_t cap = c->record_capacity ? c->record_capacity : 4096;
    while (cap < at + words + 1)
        cap *= 2;
    /* doubling stops at the records form's bound: memory stays within it */
    if (c->record_word_limit && cap > c->record_word_limit + 1 &&
        at + words + 1 <= c->record_word_limit + 1)
        cap = (size_t)c->record_word_limit + 1;
    uint32_t *w = NULL;
    if (cap * 4 >= RECORDS_HUGE) {
        if (posix_memalign((void **)&w, RECORDS_HUGE, cap * 4) != 0)
            w = NULL;
        if (w) {
#ifdef MADV_HUGEPAGE
            madvise(w, cap * 4, MADV_HUGEPAGE);
#endif
            if (at)
                memcpy(w, m->record_data, at * 4);
            free(m->record_data);
        }
    } else {
        w = realloc(m->record_data, cap * 4);
    }
    if (!w)
        return mts_error_set(err, MTS_ERR_NOMEM, "BATCH: out of memory for %zu record words",
                             cap);
    m->record_data = w;
    c->record_capacity = cap;
    return MTS_OK;
}

/* Appends one derived record to the client's model. */
static mts_result keep_record(mts_stream_client *c, uint32_t j, const uint32_t *r, uint32_t words,
                              mts_error *err)
{
    mts_model *m = &c->model;
    size_t at = m->record_offsets[j];
    mts_result rc = reserve_records(c, at, words, err);
    if (rc != MTS_OK)
        return rc;
    memcpy(m->record_data + at, r, (size_t)words * 4);
    m->record_offsets[j + 1] = (uint32_t)(at + words);
    m->record_word_count = (uint32_t)(at + words);
    return MTS_OK;
}

/* Where a client's full-level walk takes each strip's start and its swap
 * bits from: the batch's coder, as the walk goes (grow.h, mts_grow_full). */
typedef struct full_source {
    mts_rc_decoder *d;
    struct mts__stream_models *md;
    unsigned id_bits;
} full_source;

static unsigned swap_from_coder(void *user, unsigned previous)
{
    full_source *x = user;
    return mts_rc_decode_bit(x->d, &x->md->swap[previous & 1]);
}

static int start_from_coder(void *user, const uint32_t *near, uint32_t near_count,
                            uint32_t *first, uint32_t *rotation)
{
    full_source *x = user;
    if (near_count && mts_rc_decode_bit(x->d, &x->md->full_near)) {
        const uint32_t k = mts_rc_decode_uint(x->d, &x->md->full_near_at);
        if (k >= near_count)
            return 0;
        *first = near[k];
    } else {
        *first = mts_rc_decode_direct(x->d, x->id_bits);
    }
    *rotation = mts_rc_decode_tree(x->d, &x->md->rotation);
    return x->d->ok;
}

/* The full strips' description, after the last split's fan code: per slot
 * its triangle count; each strip's start and the swap bits the walk does
 * not force follow as the last split resolves them, read through `src`.
 * The counts are bounded by the full level's triangles, which MODEL_INFO
 * gave, before anything is allocated. */
static mts_result decode_full(mts_stream_client *c, mts_rc_decoder *d, mts_grow_full *full,
                              full_source *src, mts_error *err)
{
    struct mts__stream_models *md = c->models;
    const uint32_t slots = c->model.strip_count, triangles = c->info.triangles;
    mts_grow_full_path *paths = calloc((size_t)slots + 1, sizeof *paths);
    if (!paths)
        return mts_error_set(err, MTS_ERR_NOMEM, "out of memory for the full strips");
    uint64_t tris = 0;
    for (uint32_t st = 0; st < slots && d->ok && tris <= triangles; st++) {
        paths[st].triangles = mts_rc_decode_uint(d, &md->full_triangles);
        tris += paths[st].triangles;
    }
    if (!d->ok || tris > triangles) {
        free(paths);
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "the full strips are malformed (%llu triangles of %u)",
                             (unsigned long long)tris, triangles);
    }
    *src = (full_source){d, md, triangle_id_bits(triangles)};
    full->paths = paths;
    full->swap_bit = swap_from_coder;
    full->start = start_from_coder;
    full->user = src;
    return MTS_OK;
}

/* A batch's splits: each one's parent, fan code (or explicit lists) and
 * vertex, its record derived on the way (grow.h). The CRC has checked out,
 * so a malformed split means a broken server: the client stops there. */
static mts_result take_splits(mts_stream_client *c, mts_rc_decoder *d, mts_grow_full *full,
                              uint32_t index, uint32_t first, uint32_t count, uint32_t maxq,
                              mts_error *err)
{
    struct mts__stream_models *md = c->models;
    mts_model *m = &c->model;
    const uint32_t nb = m->base_vertex_count;
    mts_result rc;
    full_source src;
    for (uint32_t i = 0; i < count; i++) {
        const uint32_t j = first + i, v = nb + j, before = j ? m->parents[j - 1] : 0;
        if (!reserve_vertices(c, v + 1))
            return mts_error_set(err, MTS_ERR_NOMEM, "BATCH %u: out of memory for %u vertices",
                                 index, v + 1);
        /* up: u = before + gap, below v; else u = v - 1 - back, below before */
        const unsigned up = mts_rc_decode_bit(d, &md->parent_up);
        const uint32_t x = mts_rc_decode_uint(d, up ? &md->parent_gap : &md->parent);
        const int bad = up ? x > v - 1 - before : x >= v || v - 1 - x >= before;
        unsigned sides = mts_rc_decode_tree(d, &md->sides);
        if (!d->ok || bad || sides > MTS_GROWTH_EXPLICIT)
            return mts_error_set(err, MTS_ERR_FORMAT, "BATCH %u: split %u malformed", index, j);
        mts_grow_split sp = {0};
        sp.parent = up ? before + x : v - 1 - x;
        m->parents[j] = sp.parent;
        const uint32_t *r;
        uint32_t rw;
        if (sides == MTS_GROWTH_EXPLICIT) {
            /* a split moves at most the triangles there are, and no
             * triangle ever goes away on the way up, so it brings back at
             * most those still to come: that bounds the lists (by the
             * capacities, take_info) before anything is allocated */
            sp.left = sp.right = MTS_GROW_NONE;
            sp.moved_count = mts_rc_decode_uint(d, &md->lists);
            sp.born_count = mts_rc_decode_uint(d, &md->lists);
            mts_grow_figures fig;
            mts_grow_get_figures(c->grow, &fig);
            uint64_t words = (uint64_t)sp.moved_count + 3ull * sp.born_count;
            if (!d->ok || words == 0 || words > SIZE_MAX / 4 || sp.moved_count > fig.triangles ||
                fig.triangles > c->info.triangles ||
                sp.born_count > c->info.triangles - fig.triangles)
                return mts_error_set(err, MTS_ERR_FORMAT,
                                     "BATCH %u: split %u lists %u moved and %u new triangles "
                                     "(%u there, %u at the full level)",
                                     index, j, sp.moved_count, sp.born_count, fig.triangles,
                                     c->info.triangles);
            uint32_t *lists = malloc((size_t)words * 4);
            if (!lists)
                return mts_error_set(err, MTS_ERR_NOMEM, "BATCH %u: out of memory", index);
            for (uint64_t q = 0; q < words && d->ok; q++)
                lists[q] = mts_rc_decode_uint(d, &md->lists);
            sp.moved = lists;
            sp.born = lists + sp.moved_count;
            rc = !d->ok ? mts_error_set(err, MTS_ERR_FORMAT, "BATCH %u: split %u truncated",
                                        index, j)
                 : j + 1 == m->level_count ? decode_full(c, d, full, &src, err)
                                           : MTS_OK;
            if (rc == MTS_OK)
                rc = mts_grow_next(c->grow, &sp, full, &r, &rw, err);
            free(lists);
        } else {
            mts_grow_fan_code fc = {0, 0, sides};
            const unsigned fctx = fan_context(c->grow, sp.parent);
            fc.start = mts_rc_decode_uint(d, &md->start[fctx]);
            fc.count = mts_rc_decode_uint(d, &md->count[fctx]);
            if (!d->ok || !mts_grow_fan_decode(c->grow, sp.parent, &fc, &sp.left, &sp.right))
                return mts_error_set(err, MTS_ERR_FORMAT,
                                     "BATCH %u: split %u names no fan of vertex %u (start %u, "
                                     "count %u, sides %u)",
                                     index, j, sp.parent, fc.start, fc.count, fc.sides);
            rc = j + 1 == m->level_count ? decode_full(c, d, full, &src, err) : MTS_OK;
            if (rc == MTS_OK)
                rc = mts_grow_next(c->grow, &sp, full, &r, &rw, err);
        }
        if (rc == MTS_OK)
            rc = keep_record(c, j, r, rw, err);
        if (rc != MTS_OK)
            return mts_error_prefix(err, "BATCH %u", index);
        const uint32_t *around;
        uint32_t k;
        if ((rc = mts_grow_around_newest(c->grow, &around, &k, err)) != MTS_OK)
            return mts_error_prefix(err, "BATCH %u", index);
        int64_t pred[3], local[3];
        mts_lframe frame;
        unsigned ctx =
            predict_position(around, k, c->quantized, sp.parent, c->grid.bits, pred, &frame);
        local[0] = mts_rc_decode_sint(d, &md->tangent[ctx]);
        local[1] = mts_rc_decode_sint(d, &md->tangent[ctx]);
        local[2] = mts_rc_decode_uint(d, &md->normal_part[ctx]);
        if (local[2] && mts_rc_decode_bit(d, &md->normal_sign[ctx]))
            local[2] = -local[2];
        mts_lframe_inverse(&frame, local);
        uint32_t *q = c->quantized + 3 * (size_t)v;
        for (int a = 0; a < 3; a++) {
            int64_t x = pred[a] + local[a];
            if (x < 0 || x > maxq)
                return mts_error_set(err, MTS_ERR_RANGE, "BATCH %u: vertex %u is off the grid",
                                     index, v);
            q[a] = (uint32_t)x;
        }
        mts_draco_dequantize(&c->grid, q, m->positions + 3 * (size_t)v);
        if (c->oct) {
            uint16_t *o = c->oct + 2 * (size_t)v, ou[2];
            predict_normal(around, k, c->quantized, v, c->grid.bits,
                           c->oct + 2 * (size_t)sp.parent, ou);
            for (int a = 0; a < 2; a++) {
                int64_t x = (int64_t)ou[a] + mts_rc_decode_sint(d, &md->normal[a]);
                if (x < 0 || x > NORMAL_MAX)
                    return mts_error_set(err, MTS_ERR_RANGE,
                                         "BATCH %u: vertex %u's normal is off its code", index,
                                         v);
                o[a] = (uint16_t)x;
            }
            oct_decode(o, m->normals + 3 * (size_t)v);
        }
    }
    if (!d->ok || !mts_rc_decoder_finished(d))
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "BATCH %u: the coded splits %s", index,
                             d->ok ? "end before the message does"
                                   : "are malformed or run past the message");
    return MTS_OK;
}

/* A records-form batch's body (PROTOCOL.md, "Records form"): the splits'
 * parents and records, then each new vertex against its parent. The records
 * are only decoded here, into the client's model; mts_lod_split checks each
 * against the strips as it applies it, as it would a derived one. */
static mts_result take_records(mts_stream_client *c, const uint8_t *p, size_t n, uint32_t index,
                               uint32_t first, uint32_t count, uint32_t maxq, mts_error *err)
{
    mts_model *m = &c->model;
    const uint32_t nb = m->base_vertex_count;
    /* a split's words never outnumber its bytes (reccodec.h), so n more
     * words hold the batch whatever it says */
    size_t at = m->record_offsets[first];
    if (at > c->record_word_limit)
        return mts_error_set(err, MTS_ERR_LIMIT, "BATCH %u: records past the model's bound",
                             index);
    size_t room = c->record_word_limit - at < n ? (size_t)(c->record_word_limit - at) : n;
    mts_result rc = reserve_records(c, at, room, err);
    if (rc != MTS_OK)
        return mts_error_prefix(err, "BATCH %u", index);
    /* reccodec refuses to write past room: more words than the model's
     * bound allows (MTS_ERR_LIMIT) */
    mts_reccodec_out out = {m->parents + first, m->record_offsets + first, m->record_data + at,
                            room, (uint32_t)at};
    size_t used = 0, words = 0;
    rc = mts_reccodec_decode(p, n, nb, first, count, &out, &used, &words, err);
    if (rc != MTS_OK)
        return mts_error_prefix(err, "BATCH %u", index);
    m->record_word_count = (uint32_t)(at + words);
    mts_cursor cur = mts_cursor_make(p + used, n - used);
    for (uint32_t i = 0; i < count; i++) {
        const uint32_t v = nb + first + i, u = m->parents[first + i];
        if (!reserve_vertices(c, v + 1))
            return mts_error_set(err, MTS_ERR_NOMEM, "BATCH %u: out of memory for %u vertices",
                                 index, v + 1);
        uint32_t *q = c->quantized + 3 * (size_t)v;
        for (int a = 0; a < 3; a++) {
            int64_t x = (int64_t)c->quantized[3 * (size_t)u + a] +
                        (int32_t)mts_unzigzag_u32(mts_cursor_varint(&cur));
            if (!cur.ok || x < 0 || x > maxq)
                return mts_error_set(err, MTS_ERR_RANGE,
                                     "BATCH %u: vertex %u is %s", index, v,
                                     cur.ok ? "off the grid" : "cut short");
            q[a] = (uint32_t)x;
        }
        mts_draco_dequantize(&c->grid, q, m->positions + 3 * (size_t)v);
        if (c->oct) {
            uint16_t *o = c->oct + 2 * (size_t)v;
            for (int a = 0; a < 2; a++) {
                int64_t x = (int64_t)c->oct[2 * (size_t)u + a] +
                            (int32_t)mts_unzigzag_u32(mts_cursor_varint(&cur));
                if (!cur.ok || x < 0 || x > NORMAL_MAX)
                    return mts_error_set(err, MTS_ERR_RANGE,
                                         "BATCH %u: vertex %u's normal is %s", index, v,
                                         cur.ok ? "off its code" : "cut short");
                o[a] = (uint16_t)x;
            }
            oct_decode(o, m->normals + 3 * (size_t)v);
        }
    }
    if (mts_cursor_left(&cur) != 0)
        return mts_error_set(err, MTS_ERR_FORMAT, "BATCH %u: %zu bytes after its records", index,
                             mts_cursor_left(&cur));
    return MTS_OK;
}

/* A batch: its header, then either (splits form) the full strips'
 * description in the last batch and the splits, all range-coded, or
 * (records form) the records and vertices. */
static mts_result take_batch(mts_stream_client *c, const uint8_t *p, size_t n, mts_error *err)
{
    /* the CRC has checked out (mts_stream_client_frame) */
    mts_model *m = &c->model;
    mts_cursor cur = mts_cursor_make(p, n - 4);
    const uint32_t index = mts_cursor_varint(&cur), more = mts_cursor_varint(&cur);
    if (!cur.ok)
        return mts_error_set(err, MTS_ERR_FORMAT, "BATCH: truncated header");
    if (index != c->batches || index >= c->info.batch_count)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "BATCH %u out of order: expected batch %u of %u", index, c->batches,
                             c->info.batch_count);
    /* MODEL_INFO's sizes add up to the levels (mts_wire_parse_model_info) */
    const uint32_t first = mts_wire_batch_first(&c->info, index),
                   count = mts_wire_batch_splits(&c->info, index);
    if (first != c->splits || count > m->level_count - first)
        return mts_error_set(err, MTS_ERR_INTERNAL, "BATCH %u: the client is at split %u, not %u",
                             index, c->splits, first);
    if (more > m->strip_count - c->announced)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "BATCH %u announces %u slots, past the %u there are (%u so far)",
                             index, more, m->strip_count, c->announced);
    const uint32_t upto = c->announced + more;
    char what[32];
    snprintf(what, sizeof what, "BATCH %u", index);
    const uint32_t maxq = (uint32_t)((1ull << c->grid.bits) - 1);
    mts_result rc = MTS_OK;
    if (c->records) {
        if ((rc = take_capacities(c, &cur, NULL, upto, what, err)) != MTS_OK ||
            (rc = take_records(c, cur.p, mts_cursor_left(&cur), index, first, count, maxq, err)) !=
                MTS_OK)
            return rc;
        goto applied;
    }
    mts_rc_decoder d;
    if (!mts_rc_decoder_init(&d, cur.p, mts_cursor_left(&cur)))
        return mts_error_set(err, MTS_ERR_FORMAT, "BATCH %u: no coded splits", index);
    if ((rc = take_capacities(c, NULL, &d, upto, what, err)) != MTS_OK)
        return rc;
    mts_grow_full full = {.slot_count = m->strip_count};
    rc = take_splits(c, &d, &full, index, first, count, maxq, err);
    free((void *)full.paths);
    if (rc != MTS_OK)
        return rc;
applied:
    c->batches++;
    c->splits += count;
    mts_lod_set_available(&c->lod, c->splits);
    uint32_t target = c->splits < c->stop_level ? c->splits : c->stop_level;
    if ((rc = mts_lod_set_level(&c->lod, target, err)) != MTS_OK)
        return mts_error_prefix(err, "BATCH %u", index);
    return MTS_OK;
}

static mts_result take_end(mts_stream_client *c, const uint8_t *p, size_t n, mts_error *err)
{
    mts_wire_end e;
    mts_result rc = mts_wire_parse_end(p, n, &e, err);
    if (rc != MTS_OK)
        return rc;
    if (e.final_level != c->stop_level || c->lod.level != c->stop_level)
        return mts_error_set(err, MTS_ERR_FORMAT,
                             "END at level %u, but the client is at %u of the %u it asked for",
                             e.final_level, c->lod.level, c->stop_level);
    c->end_checksum = e.checksum;
    c->checksum = mts_stream_checksum(&c->lod, c->quantized);
    if (c->checksum != e.checksum)
        return mts_error_set(err, MTS_ERR_CHECKSUM,
                             "END: the mesh at level %u differs from the server's (checksum "
                             "%016llx, server %016llx)",
                             e.final_level, (unsigned long long)c->checksum,
                             (unsigned long long)e.checksum);
    return MTS_OK;
}

static void skip_model(void *user, const mts_wire_model_entry *m)
{
    (void)user;
    (void)m;
}

mts_result mts_stream_client_frame(mts_stream_client *c, uint8_t type, const uint8_t *payload,
                                   size_t size, mts_stream_event *event, mts_error *err)
{
    *event = MTS_EV_NONE;
    c->rejected = 0;
    mts_result rc;
    if (c->state == ST_FAILED || c->state == ST_DONE)
        return mts_error_set(err, MTS_ERR_ARG, "stream: frame after the end of the stream");
    if (type == MTS_MSG_ERROR) {
        if ((rc = mts_wire_parse_error(payload, size, &c->error_code, c->error_text,
                                       sizeof c->error_text, err)) != MTS_OK)
            return fail(c, rc);
        c->state = ST_DONE;
        *event = MTS_EV_ERROR;
        return MTS_OK;
    }
    switch (c->state) {
    case ST_INFO:
        if (c->resuming) {
            if (type != MTS_MSG_MODEL_INFO)
                break;
            if ((rc = check_resumed_info(c, payload, size, err)) != MTS_OK)
                return fail(c, rc);
            c->state = c->batches == 0 ? ST_SKIP_BASE : ST_BATCHES;
            c->resumes++;
            *event = MTS_EV_RESUMED;
            return MTS_OK;
        }
        if (type == MTS_MSG_MODELS) {
            /* the whole listing is checked before any entry is handed on:
             * a caller that prints them must not print half a bad frame */
            if ((rc = mts_wire_parse_models(payload, size, skip_model, NULL, err)) != MTS_OK ||
                (rc = mts_wire_parse_models(payload, size, c->on_model ? c->on_model : skip_model,
                                            c->user, err)) != MTS_OK)
                return fail(c, rc);
            c->state = ST_DONE;
            *event = MTS_EV_MODELS;
            return MTS_OK;
        }
        if (type != MTS_MSG_MODEL_INFO)
            break;
        if ((rc = take_info(c, payload, size, err)) != MTS_OK)
            return fail(c, rc);
        c->state = ST_BASE;
        *event = MTS_EV_INFO;
        return MTS_OK;
    case ST_BASE:
        if (type != MTS_MSG_BASE)
            break;
        if (!crc_ok(payload, size))
            return reject(c, mts_error_set(err, MTS_ERR_CHECKSUM,
                                           "BASE: checksum mismatch; not applied"));
        if ((rc = take_base(c, payload, size, err)) != MTS_OK)
            return fail(c, rc);
        c->state = ST_BATCHES;
        *event = MTS_EV_BASE;
        return MTS_OK;
    case ST_SKIP_BASE:
        /* the same stream_id means the same bytes: this BASE is the one in
         * place; the CRC still guards against a corrupted frame */
        if (type != MTS_MSG_BASE)
            break;
        if (!crc_ok(payload, size))
            return reject(c, mts_error_set(err, MTS_ERR_CHECKSUM,
                                           "BASE (resumed): checksum mismatch; not applied"));
        c->state = ST_BATCHES;
        return MTS_OK;
    case ST_BATCHES:
        if (type == MTS_MSG_BATCH) {
            if (!crc_ok(payload, size))
                return reject(c, mts_error_set(err, MTS_ERR_CHECKSUM,
                                               "BATCH %u: checksum mismatch; rejected, not "
                                               "applied",
                                               c->batches));
            if ((rc = take_batch(c, payload, size, err)) != MTS_OK)
                return fail(c, rc);
            *event = MTS_EV_BATCH;
            return MTS_OK;
        }
        if (type != MTS_MSG_END)
            break;
        if ((rc = take_end(c, payload, size, err)) != MTS_OK)
            return fail(c, rc);
        c->state = ST_DONE;
        *event = MTS_EV_END;
        return MTS_OK;
    }
    return fail(c, mts_error_set(err, MTS_ERR_FORMAT, "stream: unexpected message type %u",
                                 type));
}

int mts_stream_client_resume_point(const mts_stream_client *c, uint32_t *resume_batch,
                                   uint64_t *stream_id)
{
    *resume_batch = 0;
    *stream_id = 0;
    if (c->state == ST_DONE || c->state == ST_FAILED)
        return 0;
    if (c->have_lod && c->batches > 0) {
        *resume_batch = c->batches;
        *stream_id = c->info.stream_id;
    }
    return 1;
}

mts_result mts_stream_client_continue(mts_stream_client *c, uint32_t *resume_batch,
                                      uint64_t *stream_id, mts_error *err)
{
    if (c->state != ST_DONE || !c->have_lod || !c->end_checksum || c->lod.broken)
        return mts_error_set(err, MTS_ERR_ARG,
                             "stream: only a stream that ended with a checked END continues");
    *resume_batch = c->batches;
    *stream_id = c->info.stream_id;
    c->state = ST_INFO;
    c->resuming = 1;
    c->continuing = 1;
    c->end_checksum = 0;
    return MTS_OK;
}

mts_result mts_stream_client_reconnected(mts_stream_client *c, mts_error *err)
{
    if (c->state == ST_DONE || c->state == ST_FAILED)
        return mts_error_set(err, MTS_ERR_ARG, "stream: cannot resume a stream that %s",
                             c->state == ST_DONE ? "ended" : "failed");
    if (!c->have_lod) {
        /* nothing applied yet: start over, keeping only the caller's hooks */
        void (*on_model)(void *, const mts_wire_model_entry *) = c->on_model;
        void *user = c->user;
        uint32_t resumes = c->resumes;
        mts_stream_client_free(c);
        mts_stream_client_init(c);
        c->on_model = on_model;
        c->user = user;
        c->resumes = resumes;
        return MTS_OK;
    }
    /* from ST_BATCHES, ST_SKIP_BASE, or ST_INFO of a resume broken again */
    c->state = ST_INFO;
    c->resuming = 1;
    return MTS_OK;
}
