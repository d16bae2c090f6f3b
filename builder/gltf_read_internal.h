/* Private to the glTF reader (C++ only: gltf_read.cpp, which reads accessors
 * and flattens the scene, and gltf_draco.cpp, which decodes
 * KHR_draco_mesh_compression primitives): the reader's state and the helpers
 * both call. Not the C interface (gltf_read.h). */
#ifndef MTS_GLTF_READ_INTERNAL_H
#define MTS_GLTF_READ_INTERNAL_H

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <tiny_gltf.h>

#include "gltf_read.h"

namespace mts__gltf {

/* A refusal, thrown to mts_gltf_read, which turns it into the error. */
struct Fail {
    mts_result code;
    std::string msg;
};

[[noreturn]] inline void fail(mts_result code, const std::string &msg) { throw Fail{code, msg}; }

/* tinygltf's message, kept to its own words: quoted text (which may be the
 * file's) is elided, non-printable bytes replaced, the length capped. */
std::string tinygltf_words(const std::string &s);

struct Mat {
    double m[16]; /* column-major, as glTF */
};

class Reader {
  public:
    Reader(const tinygltf::Model &m, uint64_t out_cap) : model(m), cap(out_cap) {}
    const tinygltf::Model &model;
    uint64_t cap;
    std::vector<float> pos;
    std::vector<uint32_t> tri;
    /* 3 per vertex, sRGB, NaN for a primitive without COLOR_0 */
    std::vector<float> col;
    bool any_color = false, alpha = false;
    uint32_t translucent = 0;
    uint32_t primitives = 0, points = 0, lines = 0;

    /* per node: 0 not reached yet, 1 on the path from the root, 2 done */
    void node(int index, const Mat &parent, std::vector<char> &state, int depth);

  private:
    const unsigned char *whole_view(int view, const char *what);
    const unsigned char *view_bytes(int view, size_t offset, size_t count, size_t elem,
                                    size_t stride_given, size_t *stride, const char *what);
    size_t view_stride(int view) const;
    std::vector<float> read_floats(const tinygltf::Accessor &a, size_t comps, size_t cs,
                                   bool normalized, const char *what, const std::string &where);
    void read_positions(int acc, const Mat &m, const std::string &where);
    void place_positions(const std::vector<float> &v, size_t nv, const Mat &m,
                         const std::string &where);
    void read_colors(int acc, size_t nv, const std::string &where);
    void add_colors(const std::vector<float> &v, size_t comps, size_t nv,
                    const std::string &where);
    void read_indices(int acc, uint32_t vertices, std::vector<uint32_t> &out,
                      const std::string &where);
    void draco_primitive(const tinygltf::Primitive &p, const tinygltf::Value &ext, int mode,
                         const Mat &m, size_t nv, std::vector<uint32_t> &idx,
                         const std::string &where);
    void primitive(const tinygltf::Primitive &p, const Mat &m, const std::string &where);
};

/* The bytes of one component of a glTF component type (0: not one). */
size_t component_size(int type);
/* One component as a float, integers normalized when `normalized`. */
float to_float(const unsigned char *p, int ctype, bool normalized);

/* The file with each Draco primitive's "indices" key renamed so that
 * tinygltf reads it (gltf_draco.cpp says why), or empty when there are none. */
std::vector<unsigned char> draco_renamed(const unsigned char *bytes, size_t size, bool glb);

} // namespace mts__gltf

#endif
