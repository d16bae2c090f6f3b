// Draco shim: see draco.h. C++ stays in this file; everything it exports is
// extern "C", catches every exception and prints nothing.
#include "draco.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <memory>
#include <new>
#include <unordered_map>
#include <vector>

#include "draco/attributes/attribute_quantization_transform.h"
#include "draco/compression/config/compression_shared.h"
#include "draco/compression/decode.h"
#include "draco/compression/encode.h"
#include "draco/core/decoder_buffer.h"
#include "draco/core/options.h"
#include "draco/core/encoder_buffer.h"
#include "draco/mesh/mesh.h"

namespace {

// Draco indexes points and corners with 32-bit ints; stay well inside.
constexpr uint32_t kMaxVertices = 1u << 30;
constexpr uint32_t kMaxTriangles = (1u << 30) / 3;

uint32_t max_quantized(int bits) { return (1u << bits) - 1u; }

bool finite3(const float *v) { return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]); }

// draco_common.c checks the head with these; they must be this Draco's.
static_assert(draco::kDracoMeshBitstreamVersionMajor == MTS_DRACO_BITSTREAM_MAJOR &&
                  draco::kDracoMeshBitstreamVersionMinor == MTS_DRACO_BITSTREAM_MINOR,
              "Draco's bitstream version");
static_assert(draco::TRIANGULAR_MESH == MTS_DRACO_TRIANGULAR_MESH &&
                  draco::MESH_SEQUENTIAL_ENCODING == MTS_DRACO_SEQUENTIAL_BITSTREAM &&
                  draco::MESH_EDGEBREAKER_ENCODING == MTS_DRACO_EDGEBREAKER_BITSTREAM,
              "Draco's head constants");

template <typename T> T *alloc_array(size_t count)
{
    if (count > std::numeric_limits<size_t>::max() / sizeof(T))
        return nullptr;
    return static_cast<T *>(std::malloc(count ? count * sizeof(T) : 1));
}

mts_result encode_impl(const mts_draco_mesh *in, const mts_draco_options *opts, uint8_t **out, size_t *size,
                       mts_error *err)
{
    if (!in || !out || !size)
        return mts_error_set(err, MTS_ERR_ARG, "draco encode: NULL argument");
    *out = nullptr;
    *size = 0;
    const uint32_t nv = in->vertex_count, nt = in->triangle_count;
    if (nv == 0 || nt == 0)
        return mts_error_set(err, MTS_ERR_ARG, "draco encode: empty mesh (%u vertices, %u triangles)", nv, nt);
    if (nv > kMaxVertices || nt > kMaxTriangles)
        return mts_error_set(err, MTS_ERR_LIMIT, "draco encode: %u vertices, %u triangles (at most %u, %u)", nv,
                             nt, kMaxVertices, kMaxTriangles);
    if (!in->positions || !in->triangles)
        return mts_error_set(err, MTS_ERR_ARG, "draco encode: NULL positions or triangles");
    for (size_t i = 0; i < 3 * (size_t)nt; ++i)
        if (in->triangles[i] >= nv)
            return mts_error_set(err, MTS_ERR_ARG, "draco encode: triangle %zu uses vertex %u of %u", i / 3,
                                 in->triangles[i], nv);

    mts_draco_options o = {};
    if (opts)
        o = *opts;
    mts_draco_grid grid = o.grid;
    if (grid.bits == 0)
        grid.bits = MTS_DRACO_DEFAULT_POSITION_BITS;
    if (grid.range == 0.f) {
        mts_result r = mts_draco_grid_from_positions(in->positions, nv, grid.bits, &grid, err);
        if (r != MTS_OK)
            return mts_error_prefix(err, "draco encode");
    }
    if (!mts_draco_grid_valid(&grid))
        return mts_error_set(err, MTS_ERR_ARG,
                             "draco encode: bad grid (%d bits, origin %g %g %g, range %g; bits 1..%d, range > 0)",
                             grid.bits, grid.origin[0], grid.origin[1], grid.origin[2], grid.range,
                             MTS_DRACO_MAX_BITS);
    int normal_bits = o.normal_bits == 0 ? MTS_DRACO_DEFAULT_NORMAL_BITS : o.normal_bits;
    const bool with_normals = in->normals && normal_bits != -1;
    if (with_normals && (normal_bits < 1 || normal_bits > MTS_DRACO_MAX_BITS))
        return mts_error_set(err, MTS_ERR_ARG, "draco encode: %d normal bits (1..%d, or -1 for none)",
                             normal_bits, MTS_DRACO_MAX_BITS);
    if (o.method != MTS_DRACO_EDGEBREAKER && o.method != MTS_DRACO_SEQUENTIAL)
        return mts_error_set(err, MTS_ERR_ARG, "draco encode: unknown method %d", (int)o.method);
    int level = o.compression_level == 0 ? 10 : o.compression_level == -1 ? 0 : o.compression_level;
    if (level < 0 || level > 10)
        return mts_error_set(err, MTS_ERR_ARG, "draco encode: compression level %d (1..10, 0 default, -1 fastest)",
                             o.compression_level);

    // Draco keeps an explicit grid's origin and range as option strings
    // (std::to_string: six decimals) and quantizes against what it parses
    // back, which is also what its bitstream carries to the decoder. On a
    // small model (a side under a few centimetres in metres) that moves the
    // grid by a step or more, so each position is snapped to Draco's grid,
    // read back through Draco's own option code, not to ours.
    mts_draco_grid dgrid = grid;
    {
        draco::Options rt;
        rt.SetVector("origin", grid.origin, 3);
        rt.SetFloat("range", grid.range);
        if (!rt.GetVector("origin", 3, dgrid.origin))
            return mts_error_set(err, MTS_ERR_INTERNAL, "draco encode: cannot read the grid's origin back");
        dgrid.range = rt.GetFloat("range", 0.f);
        if (!mts_draco_grid_valid(&dgrid))
            return mts_error_set(err, MTS_ERR_RANGE,
                                 "draco encode: a grid of range %g is below the 1e-06 Draco keeps of it "
                                 "(the model is too small in its units: scale it up)",
                                 grid.range);
    }

    draco::Mesh mesh;
    mesh.set_num_points(nv);
    // One point per vertex, identity mapping: no deduplication anywhere.
    draco::GeometryAttribute pos_ga;
    pos_ga.Init(draco::GeometryAttribute::POSITION, nullptr, 3, draco::DT_FLOAT32, false, sizeof(float) * 3, 0);
    const int pos_id = mesh.AddAttribute(pos_ga, true, nv);
    if (pos_id < 0)
        return mts_error_set(err, MTS_ERR_INTERNAL, "draco encode: cannot add the position attribute");
    draco::PointAttribute *pos_att = mesh.attribute(pos_id);
    // Each position goes in snapped to its grid point: Draco quantizes the
    // snapped value back to the same integer with a margin of almost half a
    // step, so its integers are ours however Draco's own float code was
    // compiled (a fused multiply-add there would otherwise move values that
    // lie near a half step).
    for (uint32_t i = 0; i < nv; ++i) {
        const float *p = in->positions + 3 * (size_t)i;
        uint32_t q[3], q2[3];
        float snapped[3];
        if (!finite3(p) || !mts_draco_quantize(&grid, p, q))
            return mts_error_set(err, MTS_ERR_RANGE,
                                 "draco encode: vertex %u (%g %g %g) outside the grid (origin %g %g %g, range %g)",
                                 i, p[0], p[1], p[2], grid.origin[0], grid.origin[1], grid.origin[2], grid.range);
        mts_draco_dequantize(&dgrid, q, snapped);
        if (!mts_draco_quantize(&dgrid, snapped, q2) || q2[0] != q[0] || q2[1] != q[1] || q2[2] != q[2])
            return mts_error_set(err, MTS_ERR_RANGE,
                                 "draco encode: vertex %u: a %d-bit grid of range %g at origin %g %g %g is finer "
                                 "than float precision",
                                 i, grid.bits, dgrid.range, dgrid.origin[0], dgrid.origin[1], dgrid.origin[2]);
        pos_att->SetAttributeValue(draco::AttributeValueIndex(i), snapped);
    }
    if (with_normals) {
        draco::GeometryAttribute nrm_ga;
        nrm_ga.Init(draco::GeometryAttribute::NORMAL, nullptr, 3, draco::DT_FLOAT32, false, sizeof(float) * 3, 0);
        const int nrm_id = mesh.AddAttribute(nrm_ga, true, nv);
        if (nrm_id < 0)
            return mts_error_set(err, MTS_ERR_INTERNAL, "draco encode: cannot add the normal attribute");
        draco::PointAttribute *nrm_att = mesh.attribute(nrm_id);
        for (uint32_t i = 0; i < nv; ++i) {
            const float *n = in->normals + 3 * (size_t)i;
            if (!finite3(n))
                return mts_error_set(err, MTS_ERR_RANGE, "draco encode: normal of vertex %u is not finite", i);
            nrm_att->SetAttributeValue(draco::AttributeValueIndex(i), n);
        }
    }
    if (in->colors) {
        // Unsigned bytes, normalized as glTF and PLY colours are; no
        // quantization applies to integers, so Draco keeps them exact.
        draco::GeometryAttribute col_ga;
        col_ga.Init(draco::GeometryAttribute::COLOR, nullptr, 3, draco::DT_UINT8, true, 3, 0);
        const int col_id = mesh.AddAttribute(col_ga, true, nv);
        if (col_id < 0)
            return mts_error_set(err, MTS_ERR_INTERNAL, "draco encode: cannot add the colour attribute");
        draco::PointAttribute *col_att = mesh.attribute(col_id);
        for (uint32_t i = 0; i < nv; ++i)
            col_att->SetAttributeValue(draco::AttributeValueIndex(i), in->colors + 3 * (size_t)i);
    }
    mesh.SetNumFaces(nt);
    for (uint32_t f = 0; f < nt; ++f) {
        draco::Mesh::Face face;
        for (int k = 0; k < 3; ++k)
            face[k] = draco::PointIndex(in->triangles[3 * (size_t)f + k]);
        mesh.SetFace(draco::FaceIndex(f), face);
    }

    draco::Encoder enc;
    enc.SetAttributeExplicitQuantization(draco::GeometryAttribute::POSITION, grid.bits, 3, grid.origin, grid.range);
    if (with_normals)
        enc.SetAttributeQuantization(draco::GeometryAttribute::NORMAL, normal_bits);
    // draco_encoder -cl N: speed = 10 - N for both encoding and decoding.
    enc.SetSpeedOptions(10 - level, 10 - level);
    enc.SetEncodingMethod(o.method == MTS_DRACO_SEQUENTIAL ? draco::MESH_SEQUENTIAL_ENCODING
                                                           : draco::MESH_EDGEBREAKER_ENCODING);
    // Sequential stores raw indices unless asked to compress them (draco_encoder
    // never asks: 4.5 bytes per triangle more on bunny00).
    if (o.method == MTS_DRACO_SEQUENTIAL)
        enc.options().SetGlobalBool("compress_connectivity", true);
    draco::EncoderBuffer buf;
    const draco::Status st = enc.EncodeMeshToBuffer(mesh, &buf);
    if (!st.ok())
        return mts_error_set(err, MTS_ERR_INTERNAL, "draco encode: Draco refused the mesh: %s", st.error_msg());
    uint8_t *bytes = alloc_array<uint8_t>(buf.size());
    if (!bytes)
        return mts_error_set(err, MTS_ERR_NOMEM, "draco encode: out of memory (%zu bytes)", buf.size());
    if (buf.size())
        std::memcpy(bytes, buf.data(), buf.size());
    *out = bytes;
    *size = buf.size();
    return MTS_OK;
}

void out_free(mts_draco_mesh_out *m)
{
    std::free(m->positions);
    std::free(m->quantized);
    std::free(m->normals);
    std::free(m->triangles);
    std::free(m->colors);
    std::memset(m, 0, sizeof *m);
}

mts_result decode_impl(const uint8_t *data, size_t size, mts_draco_mesh_out *out, mts_error *err)
{
    if (!out)
        return mts_error_set(err, MTS_ERR_ARG, "draco decode: NULL argument");
    std::memset(out, 0, sizeof *out);
    if (!data || size == 0)
        return mts_error_set(err, MTS_ERR_FORMAT, "draco decode: empty buffer");
    if (const mts_result rc = mts_draco_check_head(data, size, err))
        return rc;

    draco::DecoderBuffer db;
    db.Init(reinterpret_cast<const char *>(data), size);
    {
        auto type = draco::Decoder::GetEncodedGeometryType(&db);
        if (!type.ok())
            return mts_error_set(err, MTS_ERR_FORMAT, "draco decode: %s", type.status().error_msg());
        if (type.value() != draco::TRIANGULAR_MESH)
            return mts_error_set(err, MTS_ERR_FORMAT, "draco decode: not a triangle mesh (geometry type %d)",
                                 (int)type.value());
    }
    draco::Decoder dec;
    // Keep the integer positions: we dequantize them ourselves.
    dec.SetSkipAttributeTransform(draco::GeometryAttribute::POSITION);
    auto res = dec.DecodeMeshFromBuffer(&db);
    if (!res.ok())
        return mts_error_set(err, MTS_ERR_FORMAT, "draco decode: %s", res.status().error_msg());
    const std::unique_ptr<draco::Mesh> mesh = std::move(res).value();
    if (!mesh)
        return mts_error_set(err, MTS_ERR_FORMAT, "draco decode: no mesh");

    const uint64_t np = mesh->num_points(), nf = mesh->num_faces();
    if (np == 0 || nf == 0)
        return mts_error_set(err, MTS_ERR_FORMAT, "draco decode: empty mesh (%llu points, %llu faces)",
                             (unsigned long long)np, (unsigned long long)nf);
    if (np > kMaxVertices || nf > kMaxTriangles)
        return mts_error_set(err, MTS_ERR_LIMIT, "draco decode: %llu points, %llu faces (at most %u, %u)",
                             (unsigned long long)np, (unsigned long long)nf, kMaxVertices, kMaxTriangles);
    if (mesh->NumNamedAttributes(draco::GeometryAttribute::POSITION) != 1)
        return mts_error_set(err, MTS_ERR_FORMAT, "draco decode: %d position attributes (want 1)",
                             mesh->NumNamedAttributes(draco::GeometryAttribute::POSITION));
    const draco::PointAttribute *pos = mesh->GetNamedAttribute(draco::GeometryAttribute::POSITION);
    if (!pos || pos->num_components() != 3 ||
        (pos->data_type() != draco::DT_INT32 && pos->data_type() != draco::DT_UINT32))
        return mts_error_set(err, MTS_ERR_FORMAT, "draco decode: positions are not 3 quantized integers");
    draco::AttributeQuantizationTransform qt;
    if (!qt.InitFromAttribute(*pos))
        return mts_error_set(err, MTS_ERR_FORMAT, "draco decode: positions carry no quantization grid");
    mts_draco_grid grid;
    grid.bits = qt.quantization_bits();
    if (qt.min_values().size() != 3)
        return mts_error_set(err, MTS_ERR_FORMAT, "draco decode: grid origin has %zu values",
                             qt.min_values().size());
    for (int c = 0; c < 3; ++c)
        grid.origin[c] = qt.min_value(c);
    grid.range = qt.range();
    if (!mts_draco_grid_valid(&grid))
        return mts_error_set(err, MTS_ERR_RANGE, "draco decode: bad grid (%d bits, origin %g %g %g, range %g)",
                             grid.bits, grid.origin[0], grid.origin[1], grid.origin[2], grid.range);

    const draco::PointAttribute *nrm = nullptr;
    if (mesh->NumNamedAttributes(draco::GeometryAttribute::NORMAL) > 1)
        return mts_error_set(err, MTS_ERR_FORMAT, "draco decode: %d normal attributes",
                             mesh->NumNamedAttributes(draco::GeometryAttribute::NORMAL));
    if (mesh->NumNamedAttributes(draco::GeometryAttribute::NORMAL) == 1) {
        nrm = mesh->GetNamedAttribute(draco::GeometryAttribute::NORMAL);
        if (!nrm || nrm->num_components() != 3 || nrm->data_type() != draco::DT_FLOAT32)
            return mts_error_set(err, MTS_ERR_FORMAT, "draco decode: normals are not 3 floats");
    }

    const draco::PointAttribute *col = nullptr;
    if (mesh->NumNamedAttributes(draco::GeometryAttribute::COLOR) > 1)
        return mts_error_set(err, MTS_ERR_FORMAT, "draco decode: %d colour attributes",
                             mesh->NumNamedAttributes(draco::GeometryAttribute::COLOR));
    if (mesh->NumNamedAttributes(draco::GeometryAttribute::COLOR) == 1) {
        col = mesh->GetNamedAttribute(draco::GeometryAttribute::COLOR);
        if (!col || col->num_components() != 3 || col->data_type() != draco::DT_UINT8)
            return mts_error_set(err, MTS_ERR_FORMAT, "draco decode: colours are not 3 bytes");
    }

    mts_draco_mesh_out m = {};
    m.vertex_count = (uint32_t)np;
    m.triangle_count = (uint32_t)nf;
    m.grid = grid;
    m.positions = alloc_array<float>(3 * np);
    m.quantized = alloc_array<uint32_t>(3 * np);
    m.triangles = alloc_array<uint32_t>(3 * nf);
    if (nrm)
        m.normals = alloc_array<float>(3 * np);
    if (col)
        m.colors = alloc_array<uint8_t>(3 * np);
    if (!m.positions || !m.quantized || !m.triangles || (nrm && !m.normals) || (col && !m.colors)) {
        out_free(&m);
        return mts_error_set(err, MTS_ERR_NOMEM, "draco decode: out of memory (%llu points, %llu faces)",
                             (unsigned long long)np, (unsigned long long)nf);
    }
    const uint32_t maxq = max_quantized(grid.bits);
    for (uint32_t i = 0; i < m.vertex_count; ++i) {
        const draco::AttributeValueIndex avi = pos->mapped_index(draco::PointIndex(i));
        std::array<uint32_t, 3> q;
        if (avi.value() >= pos->size() || !pos->GetValue<uint32_t, 3>(avi, &q)) {
            out_free(&m);
            return mts_error_set(err, MTS_ERR_RANGE, "draco decode: point %u has no position", i);
        }
        for (int c = 0; c < 3; ++c)
            if (q[c] > maxq) {
                out_free(&m);
                return mts_error_set(err, MTS_ERR_RANGE,
                                     "draco decode: point %u: quantized value %u outside the %d-bit grid", i, q[c],
                                     grid.bits);
            }
        std::memcpy(m.quantized + 3 * (size_t)i, q.data(), sizeof(uint32_t) * 3);
        mts_draco_dequantize(&grid, m.quantized + 3 * (size_t)i, m.positions + 3 * (size_t)i);
        if (nrm) {
            const draco::AttributeValueIndex nvi = nrm->mapped_index(draco::PointIndex(i));
            std::array<float, 3> n;
            if (nvi.value() >= nrm->size() || !nrm->GetValue<float, 3>(nvi, &n) || !finite3(n.data())) {
                out_free(&m);
                return mts_error_set(err, MTS_ERR_RANGE, "draco decode: point %u has no valid normal", i);
            }
            std::memcpy(m.normals + 3 * (size_t)i, n.data(), sizeof(float) * 3);
        }
        if (col) {
            const draco::AttributeValueIndex cvi = col->mapped_index(draco::PointIndex(i));
            std::array<uint8_t, 3> rgb;
            if (cvi.value() >= col->size() || !col->GetValue<uint8_t, 3>(cvi, &rgb)) {
                out_free(&m);
                return mts_error_set(err, MTS_ERR_RANGE, "draco decode: point %u has no colour", i);
            }
            std::memcpy(m.colors + 3 * (size_t)i, rgb.data(), 3);
        }
    }
    for (uint32_t f = 0; f < m.triangle_count; ++f) {
        const draco::Mesh::Face &face = mesh->face(draco::FaceIndex(f));
        for (int k = 0; k < 3; ++k) {
            const uint32_t v = face[k].value();
            if (v >= m.vertex_count) {
                out_free(&m);
                return mts_error_set(err, MTS_ERR_RANGE, "draco decode: face %u uses point %u of %u", f, v,
                                     m.vertex_count);
            }
            m.triangles[3 * (size_t)f + k] = v;
        }
    }
    *out = m;
    return MTS_OK;
}

struct Key3 {
    uint32_t v[3];
    bool operator==(const Key3 &o) const { return v[0] == o.v[0] && v[1] == o.v[1] && v[2] == o.v[2]; }
    bool operator<(const Key3 &o) const
    {
        return v[0] != o.v[0] ? v[0] < o.v[0] : v[1] != o.v[1] ? v[1] < o.v[1] : v[2] < o.v[2];
    }
};
struct Key3Hash {
    size_t operator()(const Key3 &k) const
    {
        uint64_t h = 0x9e3779b97f4a7c15ull;
        for (uint32_t x : k.v)
            h = (h ^ x) * 0x100000001b3ull;
        return (size_t)(h ^ (h >> 29));
    }
};

// A triangle's rotation that starts at its smallest index (orientation kept).
Key3 canonical(uint32_t a, uint32_t b, uint32_t c)
{
    if (a <= b && a <= c)
        return Key3{{a, b, c}};
    if (b <= a && b <= c)
        return Key3{{b, c, a}};
    return Key3{{c, a, b}};
}

constexpr uint32_t kNone = 0xffffffffu;

/* Original vertex i's grid point: as the caller quantized it, where it says,
 * else its position quantized on the decoded grid. 0 when off that grid. */
bool orig_point(const mts_draco_mesh *orig, const mts_draco_grid *grid, uint32_t i, uint32_t q[3])
{
    if (!orig->quantized)
        return mts_draco_quantize(grid, orig->positions + 3 * (size_t)i, q) != 0;
    const uint32_t maxq = max_quantized(grid->bits);
    std::memcpy(q, orig->quantized + 3 * (size_t)i, sizeof(uint32_t) * 3);
    return q[0] <= maxq && q[1] <= maxq && q[2] <= maxq;
}

mts_result renumber_impl(const mts_draco_mesh *orig, const mts_draco_mesh_out *dec, uint32_t *vmap,
                         uint32_t *fmap, mts_error *err)
{
    if (!orig || !dec || !vmap)
        return mts_error_set(err, MTS_ERR_ARG, "draco renumber: NULL argument");
    const uint32_t nv = orig->vertex_count, nt = orig->triangle_count;
    if ((nv && !orig->positions) || (nt && !orig->triangles) || (dec->vertex_count && !dec->quantized) ||
        (dec->triangle_count && !dec->triangles))
        return mts_error_set(err, MTS_ERR_ARG, "draco renumber: NULL arrays");
    if (nv != dec->vertex_count || nt != dec->triangle_count)
        return mts_error_set(err, MTS_ERR_INVARIANT,
                             "draco renumber: the decoded mesh has %u vertices, %u triangles; the original %u, %u",
                             dec->vertex_count, dec->triangle_count, nv, nt);
    if (!mts_draco_grid_valid(&dec->grid))
        return mts_error_set(err, MTS_ERR_ARG, "draco renumber: bad grid in the decoded mesh");
    for (size_t i = 0; i < 3 * (size_t)nt; ++i)
        if (orig->triangles[i] >= nv || dec->triangles[i] >= nv)
            return mts_error_set(err, MTS_ERR_ARG, "draco renumber: triangle %zu has an index out of range", i / 3);

    // 0. The sequential method keeps the order: try the identity first.
    {
        bool same = std::memcmp(orig->triangles, dec->triangles, sizeof(uint32_t) * 3 * (size_t)nt) == 0;
        for (uint32_t i = 0; same && i < nv; ++i) {
            uint32_t q[3];
            same = orig_point(orig, &dec->grid, i, q) &&
                   std::memcmp(q, dec->quantized + 3 * (size_t)i, sizeof q) == 0;
        }
        if (same) {
            for (uint32_t i = 0; i < nv; ++i)
                vmap[i] = i;
            if (fmap)
                for (uint32_t f = 0; f < nt; ++f)
                    fmap[f] = f;
            return MTS_OK;
        }
    }

    // 1. Classes of equal quantized position, matched by sorting both sides.
    std::vector<std::pair<Key3, uint32_t>> os(nv), ds(nv);
    for (uint32_t i = 0; i < nv; ++i) {
        Key3 k;
        if (!orig_point(orig, &dec->grid, i, k.v))
            return mts_error_set(err, MTS_ERR_INVARIANT, "draco renumber: vertex %u lies outside the decoded grid", i);
        os[i] = {k, i};
        Key3 d;
        std::memcpy(d.v, dec->quantized + 3 * (size_t)i, sizeof d.v);
        ds[i] = {d, i};
    }
    std::sort(os.begin(), os.end());
    std::sort(ds.begin(), ds.end());
    std::vector<uint32_t> oclass(nv), dclass(nv);
    uint32_t nclass = 0;
    for (uint32_t i = 0; i < nv;) {
        if (!(os[i].first == ds[i].first))
            return mts_error_set(err, MTS_ERR_INVARIANT,
                                 "draco renumber: vertex %u's quantized position (%u %u %u) is not decoded as often "
                                 "as in the original",
                                 os[i].second, os[i].first.v[0], os[i].first.v[1], os[i].first.v[2]);
        uint32_t j = i;
        while (j < nv && os[j].first == os[i].first) {
            if (!(ds[j].first == os[i].first))
                return mts_error_set(err, MTS_ERR_INVARIANT,
                                     "draco renumber: quantized position (%u %u %u) occurs a different number of "
                                     "times in the decoded mesh",
                                     os[i].first.v[0], os[i].first.v[1], os[i].first.v[2]);
            oclass[os[j].second] = nclass;
            dclass[ds[j].second] = nclass;
            ++j;
        }
        if (j < nv && ds[j].first == os[i].first)
            return mts_error_set(err, MTS_ERR_INVARIANT,
                                 "draco renumber: quantized position (%u %u %u) occurs more often when decoded",
                                 os[i].first.v[0], os[i].first.v[1], os[i].first.v[2]);
        if (j - i == 1) // unique on both sides
            vmap[os[i].second] = ds[i].second;
        else
            for (uint32_t k = i; k < j; ++k)
                vmap[os[k].second] = kNone;
        ++nclass;
        i = j;
    }
    std::vector<uint8_t> taken(nv, 0);
    uint32_t unmatched = 0;
    for (uint32_t i = 0; i < nv; ++i) {
        if (vmap[i] != kNone)
            taken[vmap[i]] = 1;
        else
            ++unmatched;
    }

    // 2. Shared positions: propagate through oriented faces.
    if (unmatched) {
        // decoded directed edge (a -> b) -> the face's third vertex, kNone if
        // the edge is in more than one decoded face.
        std::unordered_map<uint64_t, uint32_t> third;
        third.reserve(3 * (size_t)nt);
        for (uint32_t f = 0; f < nt; ++f) {
            const uint32_t *t = dec->triangles + 3 * (size_t)f;
            for (int k = 0; k < 3; ++k) {
                const uint64_t key = (uint64_t)t[k] << 32 | t[(k + 1) % 3];
                auto ins = third.emplace(key, t[(k + 2) % 3]);
                if (!ins.second)
                    ins.first->second = kNone;
            }
        }
        // original vertex -> its faces (CSR)
        std::vector<uint32_t> start(nv + 1, 0), faces(3 * (size_t)nt);
        for (size_t i = 0; i < 3 * (size_t)nt; ++i)
            start[orig->triangles[i] + 1]++;
        for (uint32_t i = 0; i < nv; ++i)
            start[i + 1] += start[i];
        {
            std::vector<uint32_t> fill(start.begin(), start.end() - 1);
            for (size_t i = 0; i < 3 * (size_t)nt; ++i)
                faces[fill[orig->triangles[i]]++] = (uint32_t)(i / 3);
        }
        std::vector<uint32_t> queue;
        std::vector<uint8_t> queued(nt, 0);
        for (uint32_t f = 0; f < nt; ++f) {
            queue.push_back(f);
            queued[f] = 1;
        }
        while (!queue.empty() && unmatched) {
            const uint32_t f = queue.back();
            queue.pop_back();
            queued[f] = 0;
            const uint32_t *t = orig->triangles + 3 * (size_t)f;
            for (int k = 0; k < 3; ++k) {
                const uint32_t a = t[k], b = t[(k + 1) % 3], c = t[(k + 2) % 3];
                if (vmap[a] == kNone || vmap[b] == kNone || vmap[c] != kNone)
                    continue;
                auto it = third.find((uint64_t)vmap[a] << 32 | vmap[b]);
                if (it == third.end() || it->second == kNone)
                    continue;
                const uint32_t C = it->second;
                if (taken[C] || dclass[C] != oclass[c])
                    continue;
                vmap[c] = C;
                taken[C] = 1;
                --unmatched;
                for (uint32_t e = start[c]; e < start[c + 1]; ++e)
                    if (!queued[faces[e]]) {
                        queued[faces[e]] = 1;
                        queue.push_back(faces[e]);
                    }
            }
        }
        if (unmatched)
            return mts_error_set(err, MTS_ERR_INVARIANT,
                                 "draco renumber: %u vertices share positions and cannot be told apart by "
                                 "connectivity",
                                 unmatched);
    }

    // 3. Check: every oriented original face maps to a decoded face.
    std::unordered_map<Key3, std::vector<uint32_t>, Key3Hash> dfaces;
    dfaces.reserve(nt);
    for (uint32_t f = nt; f-- > 0;) { // reversed: pop_back hands out ascending ids
        const uint32_t *t = dec->triangles + 3 * (size_t)f;
        dfaces[canonical(t[0], t[1], t[2])].push_back(f);
    }
    for (uint32_t f = 0; f < nt; ++f) {
        const uint32_t *t = orig->triangles + 3 * (size_t)f;
        auto it = dfaces.find(canonical(vmap[t[0]], vmap[t[1]], vmap[t[2]]));
        if (it == dfaces.end() || it->second.empty())
            return mts_error_set(err, MTS_ERR_INVARIANT,
                                 "draco renumber: triangle %u (%u %u %u) has no decoded match with the same "
                                 "orientation",
                                 f, t[0], t[1], t[2]);
        if (fmap)
            fmap[f] = it->second.back();
        it->second.pop_back();
    }
    return MTS_OK;
}

} // namespace

extern "C" {

mts_result mts_draco_encode(const mts_draco_mesh *in, const mts_draco_options *opts, uint8_t **out, size_t *size,
                            mts_error *err)
{
    try {
        return encode_impl(in, opts, out, size, err);
    } catch (const std::bad_alloc &) {
        return mts_error_set(err, MTS_ERR_NOMEM, "draco encode: out of memory");
    } catch (const std::exception &e) {
        return mts_error_set(err, MTS_ERR_INTERNAL, "draco encode: %s", e.what());
    } catch (...) {
        return mts_error_set(err, MTS_ERR_INTERNAL, "draco encode: unknown exception");
    }
}

mts_result mts_draco_decode(const uint8_t *data, size_t size, mts_draco_mesh_out *out, mts_error *err)
{
    try {
        return decode_impl(data, size, out, err);
    } catch (const std::bad_alloc &) {
        if (out)
            out_free(out);
        return mts_error_set(err, MTS_ERR_NOMEM, "draco decode: out of memory");
    } catch (const std::exception &e) {
        if (out)
            out_free(out);
        return mts_error_set(err, MTS_ERR_FORMAT, "draco decode: %s", e.what());
    } catch (...) {
        if (out)
            out_free(out);
        return mts_error_set(err, MTS_ERR_FORMAT, "draco decode: unknown exception");
    }
}

void mts_draco_mesh_out_free(mts_draco_mesh_out *mesh)
{
    if (mesh)
        out_free(mesh);
}

mts_result mts_draco_renumber(const mts_draco_mesh *original, const mts_draco_mesh_out *decoded,
                              uint32_t *vertex_map, uint32_t *face_map, mts_error *err)
{
    try {
        return renumber_impl(original, decoded, vertex_map, face_map, err);
    } catch (const std::bad_alloc &) {
        return mts_error_set(err, MTS_ERR_NOMEM, "draco renumber: out of memory");
    } catch (const std::exception &e) {
        return mts_error_set(err, MTS_ERR_INTERNAL, "draco renumber: %s", e.what());
    } catch (...) {
        return mts_error_set(err, MTS_ERR_INTERNAL, "draco renumber: unknown exception");
    }
}

} // extern "C"
