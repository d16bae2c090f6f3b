// Thin shim: asks OpenMesh's half-edge connectivity which faces it accepts.
#include "manifold.h"

#include <new>

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>

#include "om_quiet.h"

namespace {
struct TopoTraits : public OpenMesh::DefaultTraits {};
typedef OpenMesh::TriMesh_ArrayKernelT<TopoTraits> TopoMesh;
} // namespace

extern "C" mts_result mts_manifold_filter(uint32_t vertex_count, const uint32_t *triangles,
                                          uint32_t triangle_count, uint8_t *accepted,
                                          uint32_t *refused_count, mts_error *err)
{
    try {
        mts::OmQuiet quiet;
        TopoMesh mesh;
        mesh.reserve(vertex_count, (size_t)triangle_count * 3 / 2 + 3, triangle_count);
        for (uint32_t v = 0; v < vertex_count; v++)
            mesh.add_vertex(TopoMesh::Point(0, 0, 0));
        uint32_t refused = 0;
        for (uint32_t f = 0; f < triangle_count; f++) {
            const uint32_t *t = triangles + 3 * (size_t)f;
            if (t[0] >= vertex_count || t[1] >= vertex_count || t[2] >= vertex_count)
                return mts_error_set(err, MTS_ERR_RANGE,
                                     "triangle %u has a vertex index out of range (%u vertices)",
                                     f, vertex_count);
            TopoMesh::FaceHandle fh = mesh.add_face(TopoMesh::VertexHandle((int)t[0]),
                                                    TopoMesh::VertexHandle((int)t[1]),
                                                    TopoMesh::VertexHandle((int)t[2]));
            accepted[f] = fh.is_valid() ? 1 : 0;
            refused += fh.is_valid() ? 0 : 1;
        }
        if (refused_count)
            *refused_count = refused;
        return MTS_OK;
    } catch (const std::bad_alloc &) {
        return mts_error_set(err, MTS_ERR_NOMEM, "out of memory building the half-edge mesh");
    } catch (const std::exception &e) {
        return mts_error_set(err, MTS_ERR_INTERNAL, "OpenMesh: %s", e.what());
    }
}
