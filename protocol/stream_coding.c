/* What both ends of a stream compute alike (stream_coding.h): the normals'
 * codes, the checksum's terms, the coding models and their contexts, the
 * predictions, the base's grid order. */
#include "stream_coding.h"

#include "stream.h"

#include "grow.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void mts__stream_oct_encode(const float n[3], uint16_t out[2])
{
    float l = fabsf(n[0]) + fabsf(n[1]) + fabsf(n[2]);
    float x = l > 0 ? n[0] / l : 0, y = l > 0 ? n[1] / l : 0;
    if (l > 0 && n[2] < 0) {
        float ox = x;
        x = (1 - fabsf(y)) * (ox >= 0 ? 1.0f : -1.0f);
        y = (1 - fabsf(ox)) * (y >= 0 ? 1.0f : -1.0f);
    }
    out[0] = (uint16_t)lrintf((x * 0.5f + 0.5f) * (float)MTS__STREAM_NORMAL_MAX);
    out[1] = (uint16_t)lrintf((y * 0.5f + 0.5f) * (float)MTS__STREAM_NORMAL_MAX);
}

void mts__stream_oct_decode(const uint16_t in[2], float n[3])
{
    float x = (float)in[0] / (float)MTS__STREAM_NORMAL_MAX * 2.0f - 1.0f,
          y = (float)in[1] / (float)MTS__STREAM_NORMAL_MAX * 2.0f - 1.0f;
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

uint64_t mts__stream_strip_sum(uint32_t s, const uint32_t *str, uint32_t len)
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

uint64_t mts__stream_vertex_sum(uint32_t x, const uint32_t q[3])
{
    return mix64(mix64(mix64(((uint64_t)x << 32) ^ q[0]) ^ q[1]) ^ q[2]);
}

uint64_t mts_stream_checksum(const mts_lod *lod, const uint32_t *quantized)
{
    return mts_stream_checksum_colors(lod, quantized, NULL);
}

uint64_t mts_stream_checksum_colors(const mts_lod *lod, const uint32_t *quantized,
                                    const uint8_t *colors)
{
    uint64_t sum = 0;
    for (uint32_t s = 0; s < lod->strip_count; s++) {
        uint32_t len;
        const uint32_t *str = mts_lod_strip(lod, s, &len);
        sum += mts__stream_strip_sum(s, str, len);
    }
    uint32_t nv = lod->model->base_vertex_count + lod->level;
    for (uint32_t x = 0; x < nv; x++)
        sum += mts__stream_vertex_sum(x, quantized + 3 * (size_t)x);
    for (uint32_t x = 0; colors && x < nv; x++)
        sum += mts__stream_color_sum(x, colors + 3 * (size_t)x);
    return sum;
}

void mts__stream_models_init(struct mts__stream_models *m)
{
    mts_rc_uint_model_init(&m->parent);
    mts_rc_uint_model_init(&m->parent_gap);
    mts_rc_prob_init(&m->parent_up, 1);
    for (int k = 0; k < MTS__STREAM_FAN_CONTEXTS; k++) {
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
    for (int k = 0; k < MTS__STREAM_POSITION_CONTEXTS; k++) {
        mts_rc_uint_model_init(&m->tangent[k]);
        mts_rc_uint_model_init(&m->normal_part[k]);
    }
    mts_rc_prob_init(m->normal_sign, MTS__STREAM_POSITION_CONTEXTS);
    mts_rc_uint_model_init(&m->normal[0]);
    mts_rc_uint_model_init(&m->normal[1]);
    for (int c = 0; c < 3; c++)
        for (int k = 0; k < MTS__STREAM_COLOR_CONTEXTS; k++)
            mts_rc_uint_model_init(&m->color[c][k]);
}

/* The bits of |x| (0 for 0), at most MTS__STREAM_COLOR_CONTEXTS - 1. */
static unsigned color_bits(uint32_t a)
{
    unsigned b = 0;
    while (a >> b && b < MTS__STREAM_COLOR_CONTEXTS - 1)
        b++;
    return b;
}

unsigned mts__stream_predict_color(const uint32_t *around, uint32_t k, const uint8_t *colors,
                                   uint32_t parent, int32_t pred[3])
{
    const uint8_t *cu = colors + 3 * (size_t)parent;
    if (k == 0) {
        for (int c = 0; c < 3; c++)
            pred[c] = cu[c];
        return 0;
    }
    /* k <= 2 x the triangles round v, so the sums stay far below 2^32 */
    uint32_t sum[3] = {0, 0, 0};
    for (uint32_t i = 0; i < k; i++)
        for (int c = 0; c < 3; c++)
            sum[c] += colors[3 * (size_t)around[i] + c];
    /* an eighth of the way from the ring's mean to u, as for positions:
     * on cow and bunny00 with smooth, shaded and normal-mapped colours it
     * codes 0-4 % under the ring's mean alone, 3-35 % under u's colour */
    uint32_t far = 0;
    for (int c = 0; c < 3; c++) {
        pred[c] = (int32_t)((7 * sum[c] + k * cu[c] + 4 * k) / (8 * k));
        const int32_t mean = (int32_t)((2 * sum[c] + k) / (2 * k));
        for (uint32_t i = 0; i < k; i++) {
            const int32_t d = colors[3 * (size_t)around[i] + c] - mean;
            const uint32_t a = (uint32_t)(d < 0 ? -d : d);
            far = a > far ? a : far;
        }
    }
    return color_bits(far);
}

unsigned mts__stream_color_context(unsigned ring, int component, int32_t y)
{
    return component == 0 ? ring : color_bits((uint32_t)(y < 0 ? -y : y));
}

/* floor(x / 2) for any int32, whatever C's >> does with negative values */
static inline int32_t half_floor(int32_t x)
{
    return x >= 0 ? x / 2 : -((1 - x) / 2);
}

void mts__stream_color_forward(const int32_t d[3], int32_t t[3])
{
    const int32_t co = d[0] - d[2], b = d[2] + half_floor(co), cg = d[1] - b;
    t[0] = b + half_floor(cg);
    t[1] = co;
    t[2] = cg;
}

void mts__stream_color_inverse(const int32_t t[3], int32_t d[3])
{
    const int32_t b = t[0] - half_floor(t[2]);
    d[1] = t[2] + b;
    d[2] = b - half_floor(t[1]);
    d[0] = d[2] + t[1];
}

uint64_t mts__stream_color_sum(uint32_t x, const uint8_t rgb[3])
{
    return mix64(mix64(((uint64_t)x << 32) ^ 0x524742ull) ^
                 ((uint64_t)rgb[0] | (uint64_t)rgb[1] << 8 | (uint64_t)rgb[2] << 16));
}

unsigned mts__stream_fan_context(struct mts_grow *g, uint32_t u)
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

unsigned mts__stream_predict_position(const uint32_t *around, uint32_t k,
                                      const uint32_t *quantized, uint32_t parent,
                                      unsigned grid_bits, int64_t pred[3], mts_lframe *frame)
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
    while (far >> ctx && ctx < MTS__STREAM_POSITION_CONTEXTS - 1)
        ctx++;
    return ctx;
}

void mts__stream_predict_normal(const uint32_t *around, uint32_t k, const uint32_t *quantized,
                                uint32_t v, unsigned grid_bits, const uint16_t parent_code[2],
                                uint16_t code[2])
{
    const unsigned shift = grid_bits > 16 ? grid_bits - 16 : 0;
    const uint32_t *qv = quantized + 3 * (size_t)v;
    int64_t n[3] = {0, 0, 0};
    for (uint32_t i = 0; i + 1 < k; i += 2)
        add_cross(quantized + 3 * (size_t)around[i], quantized + 3 * (size_t)around[i + 1], qv,
                  shift, n);
    /* keep |x| + |y| + |z| under 2^40 so MTS__STREAM_NORMAL_MAX times it
     * fits; halving (toward zero, as C divides) keeps the direction */
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
    /* mts__stream_oct_encode's map with x / l and y / l as fractions: the
     * lower half folds over the diagonals (a zero component counts as
     * positive) */
    int64_t x = n[0], y = n[1];
    if (n[2] < 0) {
        x = (l - ay) * (n[0] >= 0 ? 1 : -1);
        y = (l - ax) * (n[1] >= 0 ? 1 : -1);
    }
    /* round(MTS__STREAM_NORMAL_MAX (x + l) / 2l), x + l in [0, 2l] */
    code[0] = (uint16_t)((MTS__STREAM_NORMAL_MAX * (x + l) + l) / (2 * l));
    code[1] = (uint16_t)((MTS__STREAM_NORMAL_MAX * (y + l) + l) / (2 * l));
}

unsigned mts__stream_triangle_id_bits(uint32_t triangles)
{
    unsigned b = 0;
    while (b < 32 && (triangles - 1) >> b)
        b++;
    return b;
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

int mts__stream_base_in_grid_order(mts_draco_mesh_out *dec, uint32_t *rank)
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
        /* colours through q's room: 3 bytes a vertex fit in its 12 */
        uint8_t *c = (uint8_t *)q;
        for (uint32_t d = 0; dec->colors && d < nv; d++)
            memcpy(c + 3 * (size_t)r[d], dec->colors + 3 * (size_t)d, 3);
        if (dec->colors)
            memcpy(dec->colors, c, (size_t)nv * 3);
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
