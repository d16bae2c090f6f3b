/* Private to protocol/stream_*.c, not installed and not part of the public
 * API (that is stream.h): what the server's encoder (stream_enc.c) and the
 * client's decoder (stream_dec.c) must compute alike, bit for bit, for a
 * stream to decode at all -- the normals' codes, the checksum's terms, the
 * adaptive models and their contexts, the predictions, the base's grid
 * order. One copy of each, so the two ends cannot drift apart. */
#ifndef MTS_STREAM_CODING_H
#define MTS_STREAM_CODING_H

#include <stdint.h>

#include "draco.h"
#include "lframe.h"
#include "rcoder.h"

struct mts_grow;

/* Octahedral normal encoding (Meyer et al., "On Floating-Point Normal
 * Vectors", 2010): two numbers of MTS__STREAM_NORMAL_BITS each. 10 bits
 * (Draco's default for normals) is about 0.1 degree, finer than shading
 * shows; each bit more would cost the stream two bits a vertex of noise.
 * Server and client run this same code, so both hold the same decoded
 * normal. */
#define MTS__STREAM_NORMAL_BITS 10
#define MTS__STREAM_NORMAL_MAX ((1 << MTS__STREAM_NORMAL_BITS) - 1)

void mts__stream_oct_encode(const float n[3], uint16_t out[2]);
void mts__stream_oct_decode(const uint16_t in[2], float n[3]);

/* A strip's term of the checksum (PROTOCOL.md, END). A server sums it at
 * every level for every strip that changed, so the loop is one multiply
 * and a rotate a pair of indices, not a full mix each; the rotate brings
 * high bits down for the next multiply to spread. */
uint64_t mts__stream_strip_sum(uint32_t s, const uint32_t *str, uint32_t len);
/* A vertex's term of the checksum: its id and grid point. */
uint64_t mts__stream_vertex_sum(uint32_t x, const uint32_t q[3]);

/* The adaptive models a stream's splits are coded with (PROTOCOL.md,
 * BATCH). They live as long as the stream, not a batch: server and client
 * code every batch in order (a client resumes with the models it has), so
 * each batch starts from what the ones before it taught, and the first few
 * hundred splits pay for the learning once, not once a batch. */
#define MTS__STREAM_POSITION_CONTEXTS 16
#define MTS__STREAM_FAN_CONTEXTS 32
#define MTS__STREAM_COLOR_CONTEXTS 8
struct mts__stream_models {
    /* a fan code's start and count by the parent's ring
     * (mts__stream_fan_context) */
    mts_rc_uint_model parent, parent_gap, start[MTS__STREAM_FAN_CONTEXTS],
        count[MTS__STREAM_FAN_CONTEXTS], lists;
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
    mts_rc_uint_model tangent[MTS__STREAM_POSITION_CONTEXTS],
        normal_part[MTS__STREAM_POSITION_CONTEXTS];
    uint16_t normal_sign[MTS__STREAM_POSITION_CONTEXTS];
    mts_rc_uint_model normal[2];
    /* a colour residual's Y, Co, Cg (mts__stream_color_forward), each by
     * its context (mts__stream_color_context) */
    mts_rc_uint_model color[3][MTS__STREAM_COLOR_CONTEXTS];
};

void mts__stream_models_init(struct mts__stream_models *m);

/* The context a fan code is coded in: the parent's ring (the triangles
 * round it, 15 for 15 or more, +16 when it closes), which both ends know
 * before the code. A start is about uniform over the ring and a count
 * about half of it, so one model for all rings spends bits on the mix. */
unsigned mts__stream_fan_context(struct mts_grow *g, uint32_t u);

/* Where a new vertex is expected: the mean of the corners around it right
 * after its split (grow.h, mts_grow_around_newest), on the grid; the local
 * frame its residual is coded in (lframe.h), from the ring's normal: the
 * sum over the triangles (v, a, b) of (q(a) - pred) x (q(b) - pred), which
 * does not need v; and, as the context, the ring's spread (the mean over
 * the corners of their largest per-axis distance from the prediction: a
 * local edge length, which residuals scale with). Server and client hold
 * the same ring and the same grid points, so they agree exactly. */
unsigned mts__stream_predict_position(const uint32_t *around, uint32_t k,
                                      const uint32_t *quantized, uint32_t parent,
                                      unsigned grid_bits, int64_t pred[3], mts_lframe *frame);

/* Where a new vertex's normal is expected: the area-weighted normal of the
 * faces around it right after its split (pairs from
 * mts_grow_around_newest, v's grid point already decoded), as an
 * octahedral code; the parent's code where the faces have no area. All in
 * integers: a prediction must come out bit for bit the same on every
 * platform, and floating-point contraction may differ between builds. */
void mts__stream_predict_normal(const uint32_t *around, uint32_t k, const uint32_t *quantized,
                                uint32_t v, unsigned grid_bits, const uint16_t parent_code[2],
                                uint16_t code[2]);

/* Where a new vertex's colour is expected, from colours both ends hold
 * once its split has applied: an eighth of the way from the mean colour of
 * the corners around it (mts_grow_around_newest, each counted as often as
 * it is listed) to its parent's, per channel, in integers; u's own where
 * there are none. Returns the context the residual's Y is coded in: the
 * significant bits (at most 7) of the ring's spread, the largest
 * |colour - the ring's rounded mean| over corners and channels. */
unsigned mts__stream_predict_color(const uint32_t *around, uint32_t k, const uint8_t *colors,
                                   uint32_t parent, int32_t pred[3]);

/* The context of a colour residual's component (0: Y, 1: Co, 2: Cg): Y's
 * is the ring's (above); Co's and Cg's the significant bits of |Y| (at most
 * 7), as a colour that moved in brightness tends to move in hue too. */
unsigned mts__stream_color_context(unsigned ring, int component, int32_t y);

/* A colour residual (r, g, b differences, each in -255..255) to YCoCg-R
 * (Malvar and Sullivan, 2003) and back: lifting steps in integers, exact
 * both ways. Co = r - b, t = b + floor(Co / 2), Cg = g - t, Y = t +
 * floor(Cg / 2); |Y| <= 255, |Co| <= 510, |Cg| <= 510. */
void mts__stream_color_forward(const int32_t d[3], int32_t t[3]);
void mts__stream_color_inverse(const int32_t t[3], int32_t d[3]);

/* A colour's term of the checksum (PROTOCOL.md, END): its vertex id and its
 * bytes; summed beside mts__stream_vertex_sum for a stream with colours. */
uint64_t mts__stream_color_sum(uint32_t x, const uint8_t rgb[3]);

/* The bits a triangle id of the full level takes. */
unsigned mts__stream_triangle_id_bits(uint32_t triangles);

/* Puts Draco's decoded vertices in grid order, in place, and gives each
 * decoded id its new one (rank, when not NULL). Builders number the base in
 * the order of its positions (build.c), so this is mostly no renaming at
 * all, and splits sorted by parent stay sorted on the wire; Draco's own
 * order (Edgebreaker's traversal) is the builder's shuffled. 0 when out of
 * memory. */
int mts__stream_base_in_grid_order(mts_draco_mesh_out *dec, uint32_t *rank);

#endif
