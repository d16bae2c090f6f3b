/* KHR_draco_mesh_compression primitives of the glTF reader (gltf_read.cpp):
 * the rename that lets tinygltf read their JSON, and their decoding through
 * Draco, the compressed bytes checked as hostile as the rest of the file. */
#include "gltf_read_internal.h"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "draco/compression/decode.h"
#include "draco/core/decoder_buffer.h"
#include "draco/core/draco_types.h"
#include "draco/mesh/mesh.h"

extern "C" {
#include "draco.h"
#include "mesh_read.h"
}

namespace mts__gltf {

namespace {

/* tinygltf 2.7 refuses a file whose primitive's indices accessor has no
 * buffer view, which is what a KHR_draco_mesh_compression primitive's is
 * (its indices are in the Draco buffer). So before tinygltf sees the JSON,
 * each such primitive's "indices" key is renamed, in place and at the same
 * length, to "extras" (and an "extras" it had to a name nothing reads):
 * tinygltf then keeps the accessor number as the primitive's extras, where
 * draco_primitive finds it. The scan follows only the JSON's structure
 * (strings, nesting, keys) and gives up, renaming nothing, on anything it
 * does not understand: tinygltf's parse then says what is wrong. */
class DracoIndicesScan {
  public:
    /* the key tokens to rename in json[0..n): offset, length, and which
     * key it is ('i' "indices", renamed "extras"; 'e' "extras", renamed
     * out of the way) */
    struct Patch {
        size_t at, len;
        char what;
    };
    std::vector<Patch> patches;

    void scan(const char *json, size_t n)
    {
        s = json;
        end = json + n;
        p = json;
        if (!run())
            patches.clear();
    }

  private:
    enum Role { OTHER, TOP, MESHES, MESH, PRIMS, PRIM, EXTS, DRACO };
    struct Frame {
        char kind;         /* '{' or '[' */
        Role role;
        size_t prim;       /* the primitive record, for PRIM and EXTS */
        bool want_key;     /* an object's next string is a key */
        Role child;        /* the role of the value after the key just read */
    };
    struct Prim {
        std::vector<Patch> keys;
        bool draco = false;
    };
    const char *s = nullptr, *end = nullptr, *p = nullptr;
    std::vector<Frame> stack;
    std::vector<Prim> prims;

    void ws()
    {
        while (p < end && (*p == ' ' || *p == '\t' || *p == '\n' || *p == '\r'))
            p++;
    }

    /* a string token from p (at its quote); its text with \u00XX and
     * one-letter escapes decoded (enough to compare with ASCII names) */
    bool string(std::string *text)
    {
        p++;
        while (p < end && *p != '"') {
            char c = *p++;
            if (c == '\\') {
                if (p >= end)
                    return false;
                char e = *p++;
                if (e == 'u') {
                    if (end - p < 4)
                        return false;
                    unsigned v = 0;
                    for (int i = 0; i < 4; i++) {
                        char h = *p++;
                        v = v * 16 + (unsigned)(h >= '0' && h <= '9'   ? h - '0'
                                                : h >= 'a' && h <= 'f' ? h - 'a' + 10
                                                : h >= 'A' && h <= 'F' ? h - 'A' + 10
                                                                       : 99);
                    }
                    c = v < 0x80 ? (char)v : '?';
                } else {
                    c = e;
                }
            }
            if (text->size() < 64)
                *text += c;
        }
        if (p >= end)
            return false;
        p++;
        return true;
    }

    Role child_role(Role parent, const std::string &key) const
    {
        switch (parent) {
        case TOP: return key == "meshes" ? MESHES : OTHER;
        case MESH: return key == "primitives" ? PRIMS : OTHER;
        case PRIM: return key == "extensions" ? EXTS : OTHER;
        case EXTS: return key == "KHR_draco_mesh_compression" ? DRACO : OTHER;
        default: return OTHER;
        }
    }

    /* a value starts: its role, from where it is */
    Role value_role()
    {
        if (stack.empty())
            return TOP;
        Frame &f = stack.back();
        if (f.kind == '{')
            return f.child;
        return f.role == MESHES ? MESH : f.role == PRIMS ? PRIM : OTHER;
    }

    bool open(char kind)
    {
        if (stack.size() >= 512)
            return false;
        Role r = value_role();
        /* a role holds only for the container kind glTF gives it */
        bool object = kind == '{';
        if ((r == MESHES || r == PRIMS) == object)
            r = OTHER;
        size_t prim = stack.empty() ? 0 : stack.back().prim;
        if (r == PRIM) {
            prim = prims.size();
            prims.emplace_back();
        }
        if (r == DRACO)
            prims[prim].draco = true;
        stack.push_back(Frame{kind, r, prim, object, OTHER});
        p++;
        return true;
    }

    bool run()
    {
        ws();
        if (p >= end || *p != '{')
            return false;
        for (;;) {
            ws();
            if (p >= end)
                return false;
            char c = *p;
            Frame *f = stack.empty() ? nullptr : &stack.back();
            if (f && f->kind == '{' && f->want_key) {
                if (c == '}') {
                    /* an empty object, or a trailing comma tinygltf refuses */
                } else {
                    if (c != '"')
                        return false;
                    const char *at = p;
                    std::string key;
                    if (!string(&key))
                        return false;
                    ws();
                    if (p >= end || *p != ':')
                        return false;
                    p++;
                    f->want_key = false;
                    f->child = child_role(f->role, key);
                    if (f->role == PRIM && (key == "indices" || key == "extras"))
                        prims[f->prim].keys.push_back(
                            Patch{(size_t)(at - s), (size_t)(p - 1 - at), key[0]});
                    continue;
                }
            }
            if (c == '{' || c == '[') {
                if (!open(c))
                    return false;
                continue;
            }
            if (c == '}' || c == ']') {
                if (!f || f->kind != (c == '}' ? '{' : '['))
                    return false;
                if (f->role == PRIM && prims[f->prim].draco)
                    for (const Patch &k : prims[f->prim].keys)
                        patches.push_back(k);
                stack.pop_back();
                p++;
                if (stack.empty())
                    return true;
                continue;
            }
            if (c == ',') {
                if (!f)
                    return false;
                if (f->kind == '{')
                    f->want_key = true;
                p++;
                continue;
            }
            if (!f)
                return false;
            if (c == '"') {
                std::string ignored;
                if (!string(&ignored))
                    return false;
                continue;
            }
            /* a number, true, false or null */
            const char *from = p;
            while (p < end && *p != ',' && *p != '}' && *p != ']' && *p != ' ' &&
                   *p != '\t' && *p != '\n' && *p != '\r')
                p++;
            if (p == from)
                return false;
        }
    }
};

} // namespace

/* A copy of the file with the renames made, or an empty vector when there
 * are none to make (then the file is read as it is). The copy is of the
 * whole file, a GLB's binary chunk too, since tinygltf reads one block;
 * only files with Draco primitives pay for it. */
std::vector<unsigned char> draco_renamed(const unsigned char *bytes, size_t size, bool glb)
{
    size_t json_at = 0, json_len = size;
    if (glb) {
        /* header (12 bytes), then the JSON chunk's length and type */
        if (size < 20)
            return {};
        uint32_t len, type;
        memcpy(&len, bytes + 12, 4);
        memcpy(&type, bytes + 16, 4);
        if (type != 0x4E4F534Au || len > size - 20)
            return {};
        json_at = 20;
        json_len = len;
    }
    DracoIndicesScan scan;
    scan.scan(reinterpret_cast<const char *>(bytes) + json_at, json_len);
    if (scan.patches.empty())
        return {};
    std::vector<unsigned char> out(bytes, bytes + size);
    for (const DracoIndicesScan::Patch &k : scan.patches) {
        const char *name = k.what == 'i' ? "\"extras\"" : "\"mtsxtr\"";
        unsigned char *at = out.data() + json_at + k.at;
        memset(at, ' ', k.len);
        memcpy(at, name, 8); /* every key token named so is 8 bytes or more */
    }
    return out;
}

namespace {

/* A non-negative integer JSON value as an int, or -1 */
int json_id(const tinygltf::Value &v)
{
    if (!v.IsNumber())
        return -1;
    double d = v.GetNumberAsDouble();
    return d >= 0 && d <= 0x7fffffff && d == std::floor(d) ? (int)d : -1;
}

/* The triangle count a Draco buffer's head declares; the head has passed
 * mts_draco_check_head, so its version, method and varints are known good. */
uint64_t draco_declared_faces(const unsigned char *d, size_t n)
{
    const unsigned char *p = d + 11, *end = d + n;
    auto varint = [&]() {
        uint64_t x = 0;
        for (int i = 0; i < 5 && p < end; i++) {
            unsigned char b = *p++;
            x |= (uint64_t)(b & 0x7f) << (7 * i);
            if (!(b & 0x80))
                break;
        }
        return x;
    };
    if (d[8] == MTS_DRACO_SEQUENTIAL_BITSTREAM)
        return varint();
    /* Edgebreaker: traversal type, vertices, then faces */
    p++;
    varint();
    return varint();
}

/* The Draco attribute the extension maps glTF attribute `name` to, or
 * nullptr when the extension does not name it (the primitive's own accessor
 * then holds it, as the extension allows). */
const draco::PointAttribute *draco_attribute(const draco::Mesh &dm,
                                             const tinygltf::Value &attrs, const char *name,
                                             const std::string &w)
{
    if (!attrs.Has(name))
        return nullptr;
    int id = json_id(attrs.Get(name));
    if (id < 0)
        fail(MTS_ERR_FORMAT, w + ": the Draco attribute id of " + name +
                                 " is not a non-negative integer");
    const draco::PointAttribute *att = dm.GetAttributeByUniqueId((uint32_t)id);
    if (!att)
        fail(MTS_ERR_FORMAT, w + ": " + name + "'s Draco attribute id " + std::to_string(id) +
                                 " is not in the Draco mesh");
    return att;
}

/* Draco attribute att's value for each of np points, comps components each,
 * as floats (integers normalized when `normalized`, as to_float does); the
 * point-to-value map and every value's bytes checked against what Draco
 * holds. */
std::vector<float> draco_floats(const draco::PointAttribute &att, size_t np, size_t comps,
                                bool normalized, const char *name, const std::string &w)
{
    int ctype;
    switch (att.data_type()) {
    case draco::DT_FLOAT32: ctype = TINYGLTF_COMPONENT_TYPE_FLOAT; break;
    case draco::DT_INT8: ctype = TINYGLTF_COMPONENT_TYPE_BYTE; break;
    case draco::DT_UINT8: ctype = TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE; break;
    case draco::DT_INT16: ctype = TINYGLTF_COMPONENT_TYPE_SHORT; break;
    case draco::DT_UINT16: ctype = TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT; break;
    default:
        fail(MTS_ERR_FORMAT, w + ": " + name + " is of Draco data type " +
                                 std::to_string((int)att.data_type()) +
                                 ", not float or 8 or 16-bit integers");
    }
    if (att.num_components() != comps)
        fail(MTS_ERR_FORMAT, w + ": " + name + " has " + std::to_string(att.num_components()) +
                                 " components in the Draco mesh, " + std::to_string(comps) +
                                 " in its accessor");
    if (!att.buffer() || (!att.is_mapping_identity() && att.indices_map_size() < np))
        fail(MTS_ERR_FORMAT, w + ": " + name + " does not cover the Draco mesh's points");
    const size_t cs = component_size(ctype), bytes = att.buffer()->data_size();
    std::vector<float> v(np * comps);
    for (size_t i = 0; i < np; i++) {
        draco::AttributeValueIndex avi = att.mapped_index(draco::PointIndex((uint32_t)i));
        int64_t at = avi.value() < att.size() ? att.GetBytePos(avi) : -1;
        if (at < 0 || (uint64_t)at + comps * cs > bytes)
            fail(MTS_ERR_RANGE, w + ": point " + std::to_string(i) + " has no " + name +
                                    " value in the Draco mesh");
        const unsigned char *q = att.buffer()->data() + at;
        for (size_t c = 0; c < comps; c++)
            v[i * comps + c] = to_float(q + c * cs, ctype, normalized);
    }
    return v;
}

} // namespace

/* A KHR_draco_mesh_compression primitive: the extension's buffer view is
 * decoded by Draco; the attributes it names (POSITION, COLOR_0) come from
 * the decoded mesh, those it does not from their accessors, and the
 * triangles from its faces. The compressed bytes are the file's: the head is
 * checked before Draco allocates for the counts it declares, and every
 * count Draco hands back against the primitive's accessors, which the caller
 * has held to the size cap. */
void Reader::draco_primitive(const tinygltf::Primitive &p, const tinygltf::Value &ext,
                             int mode, const Mat &m, size_t nv, std::vector<uint32_t> &idx,
                             const std::string &where)
{
    const std::string w = where + ": KHR_draco_mesh_compression";
    if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP)
        fail(MTS_ERR_FORMAT, w + " in a primitive of mode " + std::to_string(mode) +
                                 ": the extension holds TRIANGLES (4) or TRIANGLE_STRIP (5)");
    if (!ext.IsObject())
        fail(MTS_ERR_FORMAT, w + " is not an object");
    int view = ext.Has("bufferView") ? json_id(ext.Get("bufferView")) : -1;
    if (view < 0)
        fail(MTS_ERR_FORMAT, w + ": no bufferView (a non-negative integer)");
    if (!ext.Has("attributes") || !ext.Get("attributes").IsObject())
        fail(MTS_ERR_FORMAT, w + ": no attributes object");
    const tinygltf::Value &attrs = ext.Get("attributes");
    for (const std::string &k : attrs.Keys())
        if (!p.attributes.count(k))
            fail(MTS_ERR_FORMAT, w + ": its attributes name one the primitive has not");
    const unsigned char *d = whole_view(view, w.c_str());
    const size_t len = model.bufferViews[(size_t)view].byteLength;

    /* its indices accessor, kept as its extras (see DracoIndicesScan) */
    int iacc = p.indices;
    if (iacc < 0 && p.extras.IsInt() && p.extras.GetNumberAsInt() >= 0)
        iacc = p.extras.GetNumberAsInt();
    /* the most triangles the primitive's index (or vertex) count allows */
    size_t n = nv;
    if (iacc >= 0) {
        if ((size_t)iacc >= model.accessors.size())
            fail(MTS_ERR_RANGE, where + ": indices accessor " + std::to_string(iacc) +
                                    " out of range (" +
                                    std::to_string(model.accessors.size()) + " defined)");
        n = model.accessors[(size_t)iacc].count;
        if (n > MTS__MESH_MAX_COUNT || (uint64_t)n * 4 > cap)
            fail(MTS_ERR_LIMIT, where + ": index count over the limit");
    }
    const size_t max_faces = mode == TINYGLTF_MODE_TRIANGLES ? n / 3 : (n >= 3 ? n - 2 : 0);

    if (len >= 8 && memcmp(d, "DRACO", 5) == 0 && d[7] == draco::POINT_CLOUD)
        fail(MTS_ERR_FORMAT, w + ": the Draco buffer holds a point cloud, not a triangle mesh");
    mts_error e = {};
    if (mts_result r = mts_draco_check_head(d, len, &e)) {
        const char *msg = e.msg;
        if (!strncmp(msg, "draco decode: ", 14))
            msg += 14;
        fail(r, w + ": " + msg);
    }
    uint64_t declared = draco_declared_faces(d, len);
    if (declared > max_faces)
        fail(MTS_ERR_RANGE, w + ": the Draco buffer declares " + std::to_string(declared) +
                                " triangles, more than the primitive's " + std::to_string(n) +
                                (iacc >= 0 ? " indices" : " vertices") + " hold");

    draco::DecoderBuffer db;
    db.Init(reinterpret_cast<const char *>(d), len);
    draco::Decoder dec;
    auto res = dec.DecodeMeshFromBuffer(&db);
    if (!res.ok())
        fail(MTS_ERR_FORMAT, w + ": Draco cannot decode its buffer (" +
                                 tinygltf_words(res.status().error_msg_string()) + ")");
    const std::unique_ptr<draco::Mesh> dm = std::move(res).value();
    if (!dm)
        fail(MTS_ERR_FORMAT, w + ": Draco decoded no mesh");
    const size_t np = dm->num_points(), nf = dm->num_faces();
    if (np != nv)
        fail(MTS_ERR_FORMAT, w + ": the Draco mesh has " + std::to_string(np) +
                                 " points, the POSITION accessor " + std::to_string(nv));
    if (mode == TINYGLTF_MODE_TRIANGLES && iacc >= 0 ? nf * 3 != n : nf > max_faces)
        fail(MTS_ERR_FORMAT, w + ": the Draco mesh has " + std::to_string(nf) +
                                 " triangles, the primitive's " + std::to_string(n) +
                                 (iacc >= 0 ? " indices" : " vertices") + " make " +
                                 std::to_string(max_faces));

    int pacc = p.attributes.at("POSITION"); /* the caller checked it */
    if (const draco::PointAttribute *pa = draco_attribute(*dm, attrs, "POSITION", w)) {
        const tinygltf::Accessor &a = model.accessors[(size_t)pacc];
        if (a.type != TINYGLTF_TYPE_VEC3)
            fail(MTS_ERR_FORMAT, where + ": POSITION is not a VEC3 accessor");
        place_positions(draco_floats(*pa, np, 3, a.normalized, "POSITION", w), np, m, where);
    } else {
        read_positions(pacc, m, where);
    }
    auto ci = p.attributes.find("COLOR_0");
    if (ci == p.attributes.end()) {
        col.insert(col.end(), np * 3, std::nanf(""));
    } else if (const draco::PointAttribute *ca = draco_attribute(*dm, attrs, "COLOR_0", w)) {
        const tinygltf::Accessor &a = model.accessors[(size_t)ci->second];
        if (a.type != TINYGLTF_TYPE_VEC3 && a.type != TINYGLTF_TYPE_VEC4)
            fail(MTS_ERR_FORMAT, where + ": COLOR_0 is not a VEC3 or VEC4 accessor");
        const size_t comps = a.type == TINYGLTF_TYPE_VEC4 ? 4 : 3;
        /* integer colours are normalized by the spec, whatever the flag says */
        add_colors(draco_floats(*ca, np, comps, true, "COLOR_0", w), comps, np, where);
    } else {
        read_colors(ci->second, np, where);
    }
    idx.resize(nf * 3);
    for (size_t f = 0; f < nf; f++) {
        const draco::Mesh::Face &face = dm->face(draco::FaceIndex((uint32_t)f));
        for (int k = 0; k < 3; k++) {
            uint32_t v = face[k].value();
            if (v >= np)
                fail(MTS_ERR_RANGE, w + ": Draco triangle " + std::to_string(f) +
                                        " uses point " + std::to_string(v) + " of " +
                                        std::to_string(np));
            idx[f * 3 + k] = v;
        }
    }
}

} // namespace mts__gltf
