/* glTF 2.0 / GLB reader through tinygltf (see gltf_read.h). tinygltf parses
 * the JSON and resolves the buffers; everything it hands back is checked
 * here again before it is used: accessor counts, offsets and strides against
 * their buffer views, buffer views against their buffers, indices against
 * the vertex count, node references against the node list. Nothing here
 * prints, throws out of the C interface or exits. This file reads the
 * accessors and flattens the scene; gltf_draco.cpp decodes the primitives
 * compressed with KHR_draco_mesh_compression. */
#include "gltf_read.h"

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <map>
#include <new>
#include <string>
#include <vector>

#include <tiny_gltf.h>

#include "gltf_read_internal.h"

extern "C" {
#include "fileio.h"
#include "mesh_read.h"
}

#include <unistd.h>

namespace mts__gltf {

/* tinygltf's message, kept to its own words: quoted text (which may be the
 * file's) is elided, non-printable bytes replaced, the length capped. */
std::string tinygltf_words(const std::string &s)
{
    std::string out;
    char quote = 0;
    for (size_t i = 0; i < s.size() && out.size() < 160; i++) {
        char c = s[i];
        if (quote) {
            if (c == quote || c == '\n')
                quote = 0;
            continue;
        }
        if (c == '\'' || c == '"' || c == '`') {
            quote = c;
            out += "...";
            continue;
        }
        if (c == '\n') {
            if (!out.empty())
                break;
            continue;
        }
        out += (c >= 0x20 && c < 0x7f) ? c : '?';
        if (out.size() >= 10 && out.compare(out.size() - 10, 10, "last read:") == 0)
            break;
    }
    while (!out.empty() && (out.back() == ' ' || out.back() == ':' || out.back() == ';'))
        out.pop_back();
    return out;
}

namespace {

struct FsState {
    std::string dir;      /* "" when external files may not be read */
    uint64_t budget;      /* bytes left under the size cap */
    std::string refusal;  /* why an external file was refused, when one was */
};

/* A plain file name beside the model: no folder, no parent, no scheme. */
bool plain_name(const std::string &rel)
{
    if (rel.empty() || rel == "." || rel == "..")
        return false;
    for (char c : rel)
        if (c == '/' || c == '\\' || c == ':' || c == '\0')
            return false;
    return true;
}

/* The part of abs below dir ("dir/name" from tinygltf's JoinPath), or "" */
std::string below_dir(const FsState *fs, const std::string &abs)
{
    if (fs->dir.empty() || abs.size() <= fs->dir.size() + 1 ||
        abs.compare(0, fs->dir.size(), fs->dir) != 0 || abs[fs->dir.size()] != '/')
        return std::string();
    return abs.substr(fs->dir.size() + 1);
}

bool fs_exists(const std::string &abs, void *user)
{
    FsState *fs = static_cast<FsState *>(user);
    if (fs->dir.empty()) {
        fs->refusal = "an external buffer file cannot be read for a model that is not a local "
                      "file (only data: URIs and GLB's own buffer are)";
        return false;
    }
    /* tinygltf joins the folder and the URI; a path elsewhere is another
     * search path it tries, not the file's URI */
    if (abs.compare(0, fs->dir.size() + 1, fs->dir + "/") != 0)
        return false;
    std::string rel = below_dir(fs, abs);
    if (!plain_name(rel)) {
        fs->refusal = "an external file URI with '/', '..' or a scheme is refused: only files "
                      "beside the .gltf are read";
        return false;
    }
    return access(abs.c_str(), F_OK) == 0;
}

std::string fs_expand(const std::string &path, void *) { return path; }

/* Images are not read: tinygltf reads an image's file before handing it to
 * the image loader, so image files are told by their extension and left
 * alone (tinygltf takes that as a warning, not an error). */
bool image_name(const std::string &rel)
{
    size_t dot = rel.rfind('.');
    if (dot == std::string::npos)
        return false;
    std::string e = rel.substr(dot + 1);
    for (char &c : e)
        c = (char)(c >= 'A' && c <= 'Z' ? c | 0x20 : c);
    return e == "png" || e == "jpg" || e == "jpeg" || e == "ktx" || e == "ktx2" ||
           e == "webp" || e == "gif" || e == "bmp" || e == "dds" || e == "basis" || e == "tga";
}

bool fs_read(std::vector<unsigned char> *out, std::string *err, const std::string &abs,
             void *user)
{
    FsState *fs = static_cast<FsState *>(user);
    std::string rel = below_dir(fs, abs);
    if (plain_name(rel) && image_name(rel))
        return false;
    if (!plain_name(rel)) {
        fs->refusal = "an external file URI with '/', '..' or a scheme is refused: only files "
                      "beside the .gltf are read";
        return false;
    }
    int fd;
    uint64_t size;
    mts_error e = {};
    if (mts_file_open_regular(abs.c_str(), fs->budget, "--max-mesh-bytes", &fd, &size, &e) !=
        MTS_OK) {
        fs->refusal = std::string("external buffer file: ") + e.msg;
        if (err)
            *err = "external file refused";
        return false;
    }
    try {
        out->resize((size_t)size);
    } catch (...) {
        close(fd);
        fs->refusal = "out of memory for an external buffer file";
        return false;
    }
    mts_result r = size ? mts_file_read_exact(fd, abs.c_str(), out->data(), (size_t)size, &e)
                        : MTS_OK;
    close(fd);
    if (r != MTS_OK) {
        fs->refusal = std::string("external buffer file: ") + e.msg;
        return false;
    }
    fs->budget -= size;
    return true;
}

bool fs_write(std::string *, const std::string &, const std::vector<unsigned char> &, void *)
{
    return false;
}

/* Images are never decoded: every image is accepted as empty. */
bool no_image(tinygltf::Image *, const int, std::string *, std::string *, int, int,
              const unsigned char *, int, void *)
{
    return true;
}

Mat identity()
{
    Mat r = {};
    r.m[0] = r.m[5] = r.m[10] = r.m[15] = 1;
    return r;
}

Mat mul(const Mat &a, const Mat &b)
{
    Mat r;
    for (int c = 0; c < 4; c++)
        for (int row = 0; row < 4; row++) {
            double s = 0;
            for (int k = 0; k < 4; k++)
                s += a.m[k * 4 + row] * b.m[c * 4 + k];
            r.m[c * 4 + row] = s;
        }
    return r;
}

} // namespace

size_t component_size(int type)
{
    switch (type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return 2;
    case TINYGLTF_COMPONENT_TYPE_INT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return 4;
    default: return 0;
    }
}

/* A buffer view's byteStride, read only when the view exists (0 else:
 * view_bytes then refuses the index, saying why). */
size_t Reader::view_stride(int view) const
{
    return view >= 0 && (size_t)view < model.bufferViews.size()
               ? model.bufferViews[(size_t)view].byteStride
               : 0;
}

/* The bytes of count elements of elem bytes each, stride apart, at offset
 * in buffer view `view`, all checked to lie inside the view and the view
 * inside its buffer. */
const unsigned char *Reader::view_bytes(int view, size_t offset, size_t count, size_t elem,
                                        size_t stride_given, size_t *stride, const char *what)
{
    const unsigned char *start = whole_view(view, what);
    const tinygltf::BufferView &bv = model.bufferViews[(size_t)view];
    size_t s = stride_given ? stride_given : elem;
    if (s < elem || s > 252)
        fail(MTS_ERR_FORMAT, std::string(what) + ": byte stride " + std::to_string(s) +
                                 " is not valid for " + std::to_string(elem) + "-byte elements");
    if (count > 0) {
        uint64_t need = (uint64_t)offset + (uint64_t)(count - 1) * s + elem;
        if (offset > bv.byteLength || need > bv.byteLength)
            fail(MTS_ERR_RANGE, std::string(what) + ": " + std::to_string(count) +
                                    " elements run past the end of buffer view " +
                                    std::to_string(view) + " (" +
                                    std::to_string(bv.byteLength) + " bytes)");
    }
    *stride = s;
    return start + offset;
}

/* The first byte of buffer view `view` (its byteLength bytes), the view
 * checked to lie inside its buffer. */
const unsigned char *Reader::whole_view(int view, const char *what)
{
    if (view < 0 || (size_t)view >= model.bufferViews.size())
        fail(MTS_ERR_RANGE, std::string(what) + ": buffer view " + std::to_string(view) +
                                " out of range (" + std::to_string(model.bufferViews.size()) +
                                " defined)");
    const tinygltf::BufferView &bv = model.bufferViews[(size_t)view];
    if (bv.buffer < 0 || (size_t)bv.buffer >= model.buffers.size())
        fail(MTS_ERR_RANGE, std::string(what) + ": buffer view " + std::to_string(view) +
                                " names buffer " + std::to_string(bv.buffer) + " of " +
                                std::to_string(model.buffers.size()));
    const std::vector<unsigned char> &data = model.buffers[(size_t)bv.buffer].data;
    if (bv.byteOffset > data.size() || bv.byteLength > data.size() - bv.byteOffset)
        fail(MTS_ERR_RANGE, std::string(what) + ": buffer view " + std::to_string(view) +
                                " runs past the end of its buffer (" +
                                std::to_string(data.size()) + " bytes)");
    return data.data() + bv.byteOffset;
}

float to_float(const unsigned char *p, int ctype, bool normalized)
{
    switch (ctype) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT: {
        float f;
        memcpy(&f, p, 4);
        return f;
    }
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
        float v = (float)(int8_t)p[0];
        return normalized ? std::fmax(v / 127.0f, -1.0f) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return normalized ? p[0] / 255.0f : p[0];
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
        int16_t v;
        memcpy(&v, p, 2);
        return normalized ? std::fmax(v / 32767.0f, -1.0f) : (float)v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
        uint16_t v;
        memcpy(&v, p, 2);
        return normalized ? v / 65535.0f : (float)v;
    }
    default: return 0;
    }
}

namespace {

uint32_t to_index(const unsigned char *p, size_t size)
{
    if (size == 1)
        return p[0];
    if (size == 2) {
        uint16_t v;
        memcpy(&v, p, 2);
        return v;
    }
    uint32_t v;
    memcpy(&v, p, 4);
    return v;
}

/* glTF's linear-light colour component as the sRGB value an 8-bit colour
 * stores (IEC 61966-2-1); out-of-range results are clamped by the loader. */
float linear_to_srgb(float c)
{
    return c <= 0.0031308f ? 12.92f * c : 1.055f * std::pow(c, 1.0f / 2.4f) - 0.055f;
}

} // namespace

/* COLOR_0 (VEC3 or VEC4 of float, or normalized unsigned byte or short):
 * linear, so converted to sRGB; alpha is dropped and counted. */
void Reader::read_colors(int acc, size_t nv, const std::string &where)
{
    const tinygltf::Accessor &a = model.accessors[(size_t)acc]; /* checked by the caller */
    if (a.type != TINYGLTF_TYPE_VEC3 && a.type != TINYGLTF_TYPE_VEC4)
        fail(MTS_ERR_FORMAT, where + ": COLOR_0 is not a VEC3 or VEC4 accessor");
    if (a.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT &&
        a.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
        a.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT)
        fail(MTS_ERR_FORMAT, where + ": COLOR_0 has an unsupported component type " +
                                 std::to_string(a.componentType));
    const size_t comps = a.type == TINYGLTF_TYPE_VEC4 ? 4 : 3;
    /* integer colours are normalized by the spec, whatever the flag says */
    std::vector<float> v =
        read_floats(a, comps, component_size(a.componentType), true, "COLOR_0", where);
    add_colors(v, comps, nv, where);
}

/* nv colours of comps (3 or 4) linear components each, appended as sRGB */
void Reader::add_colors(const std::vector<float> &v, size_t comps, size_t nv,
                        const std::string &where)
{
    if (v.size() != nv * comps)
        fail(MTS_ERR_FORMAT, where + ": COLOR_0 count differs from POSITION's");
    for (size_t i = 0; i < nv; i++) {
        const float *c = v.data() + i * comps;
        for (size_t k = 0; k < comps; k++)
            if (!std::isfinite(c[k]))
                fail(MTS_ERR_FORMAT, where + ": COLOR_0 of vertex " + std::to_string(i) +
                                         " is not a finite number (infinite or NaN)");
        for (int k = 0; k < 3; k++)
            col.push_back(linear_to_srgb(c[k]));
        if (comps == 4) {
            alpha = true;
            translucent += c[3] < 1.0f && translucent < UINT32_MAX;
        }
    }
    any_color = true;
}

/* The values of accessor a, comps per element, as floats (normalized
 * integers mapped to 0..1 or -1..1), sparse values applied; every offset
 * and count checked. */
std::vector<float> Reader::read_floats(const tinygltf::Accessor &a, size_t comps, size_t cs,
                                       bool normalized, const char *what,
                                       const std::string &where)
{
    const char *w = where.c_str();
    std::vector<float> v;
    if (a.bufferView >= 0) {
        size_t stride;
        const unsigned char *p =
            view_bytes(a.bufferView, a.byteOffset, a.count, comps * cs,
                       view_stride(a.bufferView), &stride, w);
        v.resize(a.count * comps);
        for (size_t i = 0; i < a.count; i++)
            for (size_t c = 0; c < comps; c++)
                v[i * comps + c] = to_float(p + i * stride + c * cs, a.componentType, normalized);
    } else {
        /* all zeros but for sparse values: bounded by the bytes that could
         * say anything about them */
        if (!a.sparse.isSparse || a.count > (uint64_t)cap / (4 * comps))
            fail(MTS_ERR_FORMAT, where + ": " + what + " accessor has no buffer view");
        v.assign(a.count * comps, 0.0f);
    }
    if (a.sparse.isSparse) {
        if (a.sparse.count < 0 || (size_t)a.sparse.count > a.count)
            fail(MTS_ERR_RANGE, where + ": sparse count out of range");
        size_t n = (size_t)a.sparse.count, is = component_size(a.sparse.indices.componentType);
        if (is == 0 || is == 4 ? a.sparse.indices.componentType !=
                                     TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT
                               : (a.sparse.indices.componentType !=
                                      TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
                                  a.sparse.indices.componentType !=
                                      TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT))
            fail(MTS_ERR_FORMAT, where + ": sparse indices of an unsupported type");
        if (a.sparse.indices.byteOffset < 0 || a.sparse.values.byteOffset < 0)
            fail(MTS_ERR_RANGE, where + ": negative sparse byte offset");
        size_t istride, vstride;
        const unsigned char *ip = view_bytes(a.sparse.indices.bufferView,
                                             (size_t)a.sparse.indices.byteOffset, n, is, 0,
                                             &istride, w);
        const unsigned char *vp = view_bytes(a.sparse.values.bufferView,
                                             (size_t)a.sparse.values.byteOffset, n, comps * cs, 0,
                                             &vstride, w);
        for (size_t k = 0; k < n; k++) {
            uint32_t i = to_index(ip + k * istride, is);
            if (i >= a.count)
                fail(MTS_ERR_RANGE, where + ": sparse index " + std::to_string(i) +
                                        " out of range (" + std::to_string(a.count) +
                                        " elements)");
            for (size_t c = 0; c < comps; c++)
                v[(size_t)i * comps + c] =
                    to_float(vp + k * vstride + c * cs, a.componentType, normalized);
        }
    }
    return v;
}

void Reader::read_positions(int acc, const Mat &m, const std::string &where)
{
    if (acc < 0 || (size_t)acc >= model.accessors.size())
        fail(MTS_ERR_RANGE, where + ": POSITION accessor " + std::to_string(acc) +
                                " out of range (" + std::to_string(model.accessors.size()) +
                                " defined)");
    const tinygltf::Accessor &a = model.accessors[(size_t)acc];
    if (a.type != TINYGLTF_TYPE_VEC3)
        fail(MTS_ERR_FORMAT, where + ": POSITION is not a VEC3 accessor");
    size_t cs = component_size(a.componentType);
    if (!cs || a.componentType == TINYGLTF_COMPONENT_TYPE_INT ||
        a.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
        fail(MTS_ERR_FORMAT, where + ": POSITION has an unsupported component type " +
                                 std::to_string(a.componentType));
    if (a.count > MTS__MESH_MAX_COUNT)
        fail(MTS_ERR_LIMIT, where + ": POSITION count over the limit");
    std::vector<float> v = read_floats(a, 3, cs, a.normalized, "POSITION", where);
    place_positions(v, a.count, m, where);
}

/* nv positions (3 floats each) appended in world space, checked finite */
void Reader::place_positions(const std::vector<float> &v, size_t nv, const Mat &m,
                             const std::string &where)
{
    if (v.size() != nv * 3)
        fail(MTS_ERR_FORMAT, where + ": POSITION count differs from its accessor's");
    for (size_t i = 0; i < nv; i++) {
        double x = v[i * 3], y = v[i * 3 + 1], z = v[i * 3 + 2];
        if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z))
            fail(MTS_ERR_FORMAT, where + ": position " + std::to_string(i) +
                                     " is not a finite number (infinite or NaN)");
        for (int r = 0; r < 3; r++) {
            double t = m.m[r] * x + m.m[4 + r] * y + m.m[8 + r] * z + m.m[12 + r];
            if (!std::isfinite(t) || std::fabs(t) > 3.0e38)
                fail(MTS_ERR_FORMAT, where + ": position " + std::to_string(i) +
                                         " is not finite after the node transforms");
            pos.push_back((float)t);
        }
    }
}

void Reader::read_indices(int acc, uint32_t vertices, std::vector<uint32_t> &out,
                          const std::string &where)
{
    const char *w = where.c_str();
    if (acc < 0 || (size_t)acc >= model.accessors.size())
        fail(MTS_ERR_RANGE, where + ": indices accessor " + std::to_string(acc) +
                                " out of range (" + std::to_string(model.accessors.size()) +
                                " defined)");
    const tinygltf::Accessor &a = model.accessors[(size_t)acc];
    if (a.type != TINYGLTF_TYPE_SCALAR ||
        (a.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
         a.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
         a.componentType != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT))
        fail(MTS_ERR_FORMAT,
             where + ": indices are not unsigned 8, 16 or 32-bit scalars");
    if (a.count > MTS__MESH_MAX_COUNT)
        fail(MTS_ERR_LIMIT, where + ": index count over the limit");
    if (a.bufferView < 0 || a.sparse.isSparse)
        fail(MTS_ERR_FORMAT, where + ": indices accessor without a buffer view, or sparse");
    size_t cs = component_size(a.componentType), stride;
    const unsigned char *p = view_bytes(a.bufferView, a.byteOffset, a.count, cs,
                                        view_stride(a.bufferView), &stride, w);
    out.resize(a.count);
    for (size_t i = 0; i < a.count; i++) {
        uint32_t x = to_index(p + i * stride, cs);
        if (x >= vertices)
            fail(MTS_ERR_RANGE, where + ": index " + std::to_string(i) + " is " +
                                    std::to_string(x) + ", out of range (" +
                                    std::to_string(vertices) + " vertices)");
        out[i] = x;
    }
}

void Reader::primitive(const tinygltf::Primitive &p, const Mat &m, const std::string &where)
{
    int mode = p.mode < 0 ? TINYGLTF_MODE_TRIANGLES : p.mode;
    auto dx = p.extensions.find("KHR_draco_mesh_compression");
    if (mode == TINYGLTF_MODE_POINTS) {
        points++;
        return;
    }
    if (mode == TINYGLTF_MODE_LINE || mode == TINYGLTF_MODE_LINE_LOOP ||
        mode == TINYGLTF_MODE_LINE_STRIP) {
        lines++;
        return;
    }
    if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP &&
        mode != TINYGLTF_MODE_TRIANGLE_FAN)
        fail(MTS_ERR_FORMAT, where + ": unknown primitive mode " + std::to_string(mode));
    auto it = p.attributes.find("POSITION");
    if (it == p.attributes.end())
        fail(MTS_ERR_FORMAT, where + ": no POSITION attribute");
    int pacc = it->second;
    if (pacc < 0 || (size_t)pacc >= model.accessors.size())
        fail(MTS_ERR_RANGE, where + ": POSITION accessor " + std::to_string(pacc) +
                                " out of range (" + std::to_string(model.accessors.size()) +
                                " defined)");
    size_t nv = model.accessors[(size_t)pacc].count;
    for (const auto &kv : p.attributes) {
        if (kv.second < 0 || (size_t)kv.second >= model.accessors.size())
            fail(MTS_ERR_RANGE, where + ": an attribute's accessor " +
                                    std::to_string(kv.second) + " is out of range (" +
                                    std::to_string(model.accessors.size()) + " defined)");
        if (model.accessors[(size_t)kv.second].count != nv)
            fail(MTS_ERR_FORMAT, where + ": vertex attributes of different counts (" +
                                     std::to_string(model.accessors[(size_t)kv.second].count) +
                                     " and POSITION's " + std::to_string(nv) + ")");
    }
    uint64_t base = pos.size() / 3;
    if (base + nv > MTS__MESH_MAX_COUNT || (pos.size() + nv * 3) * 4 > cap)
        fail(MTS_ERR_LIMIT, where + ": the flattened mesh grows over the size cap (" +
                                std::to_string(cap) + " bytes, --max-mesh-bytes)");
    std::vector<uint32_t> idx;
    if (dx != p.extensions.end()) {
        draco_primitive(p, dx->second, mode, m, nv, idx, where);
        mode = TINYGLTF_MODE_TRIANGLES; /* what Draco decodes, whatever the mode */
    } else {
        read_positions(pacc, m, where);
        auto ci = p.attributes.find("COLOR_0");
        if (ci != p.attributes.end())
            read_colors(ci->second, nv, where);
        else
            col.insert(col.end(), nv * 3, std::nanf(""));
        if (p.indices >= 0) {
            read_indices(p.indices, (uint32_t)nv, idx, where);
        } else {
            idx.resize(nv);
            for (size_t i = 0; i < nv; i++)
                idx[i] = (uint32_t)i;
        }
    }
    /* a mirroring transform turns the winding over */
    const double *a = m.m;
    double det = a[0] * (a[5] * a[10] - a[9] * a[6]) - a[4] * (a[1] * a[10] - a[9] * a[2]) +
                 a[8] * (a[1] * a[6] - a[5] * a[2]);
    bool flip = det < 0;
    size_t n = idx.size(), before = tri.size();
    if (mode == TINYGLTF_MODE_TRIANGLES && n % 3)
        fail(MTS_ERR_FORMAT, where + ": a TRIANGLES primitive of " + std::to_string(n) +
                                 (p.indices >= 0 ? " indices" : " vertices") +
                                 ", not a multiple of 3");
    size_t ntri = mode == TINYGLTF_MODE_TRIANGLES ? n / 3 : (n >= 3 ? n - 2 : 0);
    if ((tri.size() / 3 + ntri) > MTS__MESH_MAX_COUNT || (pos.size() * 4 + (tri.size() + ntri * 3) * 4) > cap)
        fail(MTS_ERR_LIMIT, where + ": the flattened mesh grows over the size cap (" +
                                std::to_string(cap) + " bytes, --max-mesh-bytes)");
    tri.reserve(tri.size() + ntri * 3);
    for (size_t k = 0; k < ntri; k++) {
        uint32_t v0, v1, v2;
        if (mode == TINYGLTF_MODE_TRIANGLES) {
            v0 = idx[k * 3], v1 = idx[k * 3 + 1], v2 = idx[k * 3 + 2];
        } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
            v0 = idx[k], v1 = idx[k + 1 + k % 2], v2 = idx[k + 2 - k % 2];
        } else {
            v0 = idx[k + 1], v1 = idx[k + 2], v2 = idx[0];
        }
        if (flip)
            std::swap(v1, v2);
        tri.push_back((uint32_t)base + v0);
        tri.push_back((uint32_t)base + v1);
        tri.push_back((uint32_t)base + v2);
    }
    (void)before;
    primitives++;
}

void Reader::node(int index, const Mat &parent, std::vector<char> &state, int depth)
{
    if (index < 0 || (size_t)index >= model.nodes.size())
        fail(MTS_ERR_RANGE, "node " + std::to_string(index) + " out of range (" +
                                std::to_string(model.nodes.size()) + " defined)");
    if (state[(size_t)index] == 1)
        fail(MTS_ERR_FORMAT, "node " + std::to_string(index) +
                                 " is its own ancestor (the node hierarchy has a cycle)");
    /* glTF's nodes form trees: a node reached again (two parents, or
     * listed twice) would be walked once for each path to it, which nodes
     * shared at every level make exponential in the depth */
    if (state[(size_t)index] == 2)
        fail(MTS_ERR_FORMAT, "node " + std::to_string(index) +
                                 " is reached twice (two parents, or listed twice): glTF "
                                 "nodes form trees");
    if (depth > 1024)
        fail(MTS_ERR_LIMIT, "the node hierarchy is more than 1024 levels deep");
    const tinygltf::Node &n = model.nodes[(size_t)index];
    Mat local = identity();
    if (n.matrix.size() == 16) {
        for (int i = 0; i < 16; i++)
            local.m[i] = n.matrix[(size_t)i];
    } else {
        Mat t = identity(), r = identity(), s = identity();
        if (n.translation.size() == 3)
            for (int i = 0; i < 3; i++)
                t.m[12 + i] = n.translation[(size_t)i];
        if (n.rotation.size() == 4) {
            double x = n.rotation[0], y = n.rotation[1], z = n.rotation[2], w = n.rotation[3];
            double l = std::sqrt(x * x + y * y + z * z + w * w);
            if (l > 0) {
                x /= l, y /= l, z /= l, w /= l;
            }
            r.m[0] = 1 - 2 * (y * y + z * z), r.m[1] = 2 * (x * y + z * w),
            r.m[2] = 2 * (x * z - y * w);
            r.m[4] = 2 * (x * y - z * w), r.m[5] = 1 - 2 * (x * x + z * z),
            r.m[6] = 2 * (y * z + x * w);
            r.m[8] = 2 * (x * z + y * w), r.m[9] = 2 * (y * z - x * w),
            r.m[10] = 1 - 2 * (x * x + y * y);
        }
        if (n.scale.size() == 3)
            for (int i = 0; i < 3; i++)
                s.m[i * 5] = n.scale[(size_t)i];
        local = mul(t, mul(r, s));
    }
    for (double v : local.m)
        if (!std::isfinite(v))
            fail(MTS_ERR_FORMAT, "node " + std::to_string(index) +
                                     ": its transform is not finite");
    Mat world = mul(parent, local);
    if (n.mesh >= 0) {
        if ((size_t)n.mesh >= model.meshes.size())
            fail(MTS_ERR_RANGE, "node " + std::to_string(index) + ": mesh " +
                                    std::to_string(n.mesh) + " out of range (" +
                                    std::to_string(model.meshes.size()) + " defined)");
        const tinygltf::Mesh &mesh = model.meshes[(size_t)n.mesh];
        for (size_t k = 0; k < mesh.primitives.size(); k++)
            primitive(mesh.primitives[k], world,
                      "mesh " + std::to_string(n.mesh) + " primitive " + std::to_string(k));
    }
    state[(size_t)index] = 1;
    for (int c : n.children)
        node(c, world, state, depth + 1);
    state[(size_t)index] = 2;
}

} // namespace mts__gltf

using namespace mts__gltf;

extern "C" int mts_gltf_is_glb(const void *data, size_t size)
{
    return size >= 4 && memcmp(data, "glTF", 4) == 0;
}

extern "C" void mts_gltf_mesh_free(mts_gltf_mesh *m)
{
    if (!m)
        return;
    free(m->positions);
    free(m->triangles);
    free(m->colors);
    *m = mts_gltf_mesh{};
}

extern "C" mts_result mts_gltf_read(const char *name, const void *data, size_t size,
                                    const char *dir, uint64_t max_bytes, mts_gltf_mesh *out,
                                    mts_error *err)
{
    *out = mts_gltf_mesh{};
    if (!name)
        name = "(memory)";
    try {
        const unsigned char *bytes = static_cast<const unsigned char *>(data);
        bool glb = mts_gltf_is_glb(data, size);
        std::vector<unsigned char> renamed = draco_renamed(bytes, size, glb);
        if (!renamed.empty()) {
            bytes = renamed.data();
            data = renamed.data();
        }
        if (size > 0xffffffffu)
            fail(MTS_ERR_LIMIT, "a glTF file over 4 GiB is not read");
        if (glb && size >= 8) {
            uint32_t version;
            memcpy(&version, bytes + 4, 4);
            if (version == 1)
                fail(MTS_ERR_VERSION, "glTF 1.0 is not supported (binary glTF version 1); "
                                      "glTF 2.0 is");
            if (version != 2)
                fail(MTS_ERR_VERSION, "GLB version " + std::to_string(version) +
                                          " is not supported; glTF 2.0 is");
        }
        FsState fs;
        fs.dir = dir ? dir : "";
        if (dir && !*dir)
            fs.dir = ".";
        fs.budget = max_bytes > size ? max_bytes - size : 0;
        tinygltf::TinyGLTF loader;
        loader.SetImageLoader(no_image, nullptr);
        tinygltf::FsCallbacks cb = {fs_exists, fs_expand, fs_read, fs_write, &fs};
        loader.SetFsCallbacks(cb);
        tinygltf::Model model;
        std::string terr, twarn;
        bool ok = glb ? loader.LoadBinaryFromMemory(&model, &terr, &twarn, bytes,
                                                     (unsigned)size, fs.dir)
                      : loader.LoadASCIIFromString(&model, &terr, &twarn,
                                                   static_cast<const char *>(data),
                                                   (unsigned)size, fs.dir);
        if (ok && !model.asset.version.empty() && model.asset.version[0] == '1')
            fail(MTS_ERR_VERSION, "glTF 1.0 is not supported; glTF 2.0 is");
        if (!ok) {
            if (!fs.refusal.empty())
                fail(MTS_ERR_IO, fs.refusal);
            /* glTF 1.0 has no "asset" version 2 and objects where 2.0 has arrays */
            std::string t(static_cast<const char *>(data), size < 65536 ? size : 65536);
            size_t a = t.find("\"asset\"");
            if (a != std::string::npos) {
                size_t v = t.find("\"version\"", a);
                if (v != std::string::npos && v < a + 200) {
                    size_t q = t.find('"', t.find(':', v) + 1);
                    if (q != std::string::npos && q + 1 < t.size() && t[q + 1] == '1')
                        fail(MTS_ERR_VERSION, "glTF 1.0 is not supported; glTF 2.0 is");
                }
            }
            if (terr.find("not found") != std::string::npos ||
                terr.find("Failed to load external") != std::string::npos)
                fail(MTS_ERR_IO, "an external buffer file the model names is missing beside "
                                 "it");
            fail(MTS_ERR_FORMAT, "not a valid glTF 2.0 file (tinygltf: " +
                                     tinygltf_words(terr.empty() ? twarn : terr) + ")");
        }
        for (const std::string &e : model.extensionsRequired) {
            if (e == "EXT_meshopt_compression")
                fail(MTS_ERR_FORMAT, "EXT_meshopt_compression is not read yet");
            /* other required extensions are about materials, textures,
             * lights or instancing: the geometry read here is as it is */
        }
        uint64_t cap = max_bytes ? max_bytes : ((uint64_t)4 << 30);
        Reader R(model, cap);
        std::vector<char> state(model.nodes.size(), 0);
        std::vector<int> roots;
        int scene = model.defaultScene;
        if (scene >= (int)model.scenes.size() && !model.scenes.empty())
            fail(MTS_ERR_RANGE, "default scene " + std::to_string(scene) + " out of range (" +
                                    std::to_string(model.scenes.size()) + " defined)");
        if (scene < 0 && !model.scenes.empty())
            scene = 0;
        if (scene >= 0 && scene < (int)model.scenes.size()) {
            roots = model.scenes[(size_t)scene].nodes;
        } else {
            /* no scene: every node that is no other node's child */
            std::vector<char> child(model.nodes.size(), 0);
            for (const tinygltf::Node &n : model.nodes)
                for (int c : n.children)
                    if (c >= 0 && (size_t)c < child.size())
                        child[(size_t)c] = 1;
            for (size_t i = 0; i < model.nodes.size(); i++)
                if (!child[i])
                    roots.push_back((int)i);
        }
        Mat id = identity();
        for (int r : roots)
            R.node(r, id, state, 0);
        if (R.tri.empty()) {
            if (R.points || R.lines)
                fail(MTS_ERR_FORMAT, "no triangles: the scene has " + std::to_string(R.points) +
                                         " point and " + std::to_string(R.lines) +
                                         " line primitives but no triangle primitives");
            fail(MTS_ERR_FORMAT, "no triangles: the scene has no triangle primitives");
        }
        out->vertex_count = (uint32_t)(R.pos.size() / 3);
        out->triangle_count = (uint32_t)(R.tri.size() / 3);
        out->positions = static_cast<float *>(malloc(R.pos.size() * sizeof(float)));
        out->triangles = static_cast<uint32_t *>(malloc(R.tri.size() * sizeof(uint32_t)));
        if (!out->positions || !out->triangles) {
            mts_gltf_mesh_free(out);
            fail(MTS_ERR_NOMEM, "out of memory");
        }
        memcpy(out->positions, R.pos.data(), R.pos.size() * sizeof(float));
        memcpy(out->triangles, R.tri.data(), R.tri.size() * sizeof(uint32_t));
        if (R.any_color) {
            out->colors = static_cast<float *>(malloc(R.col.size() * sizeof(float)));
            if (!out->colors) {
                mts_gltf_mesh_free(out);
                fail(MTS_ERR_NOMEM, "out of memory");
            }
            memcpy(out->colors, R.col.data(), R.col.size() * sizeof(float));
            out->colors_alpha = R.alpha;
            out->colors_translucent = R.translucent;
        }
        out->primitives = R.primitives;
        out->point_primitives = R.points;
        out->line_primitives = R.lines;
        return MTS_OK;
    } catch (const Fail &f) {
        mts_gltf_mesh_free(out);
        return mts_error_set(err, f.code, "%s: %s", name, f.msg.c_str());
    } catch (const std::bad_alloc &) {
        mts_gltf_mesh_free(out);
        return mts_error_set(err, MTS_ERR_NOMEM, "%s: out of memory", name);
    } catch (...) {
        mts_gltf_mesh_free(out);
        return mts_error_set(err, MTS_ERR_FORMAT, "%s: not a valid glTF 2.0 file", name);
    }
}
