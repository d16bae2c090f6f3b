// Thin shim over OpenMesh's decimater; see simplify.h.
#include "simplify.h"

#include <algorithm>
#include <cstdint>
#include <cfloat>
#include <cmath>
#include <cstdlib>
#include <new>
#include <vector>

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModNormalFlippingT.hh>
#include <OpenMesh/Tools/Decimater/ModQuadricT.hh>

#include "om_quiet.h"

namespace {

// OpenMesh's triangle mesh with its own collapse test: the decimater asks
// is_collapse_ok of every outgoing halfedge of every vertex it (re)scores,
// and the library's compiled one checks each property access by type name
// (Debian builds it with assertions), most of the simplifier's time. This
// one answers the same question through the header-inline accessors, which
// build without them; the decimater takes it by name lookup on Mesh.
class Mesh : public OpenMesh::TriMesh_ArrayKernelT<> {
public:
    // Whether collapsing v0v1 (v0 into v1) keeps the mesh a manifold:
    // Dey et al.'s link condition -- the vertices adjacent to both v0 and v1
    // are exactly the edge's opposite vertices -- and no triangle left with
    // two boundary sides, no interior edge between two boundary vertices.
    bool is_collapse_ok(HalfedgeHandle v0v1)
    {
        if (status(edge_handle(v0v1)).deleted())
            return false;
        HalfedgeHandle v1v0 = opposite_halfedge_handle(v0v1);
        VertexHandle v0 = to_vertex_handle(v1v0), v1 = to_vertex_handle(v0v1);
        VertexHandle vl, vr;
        for (int side = 0; side < 2; side++) {
            HalfedgeHandle h = side ? v1v0 : v0v1;
            if (is_boundary(h))
                continue;
            HalfedgeHandle a = next_halfedge_handle(h), b = next_halfedge_handle(a);
            // a triangle hanging by this edge alone would become a lone edge
            if (is_boundary(opposite_halfedge_handle(a)) && is_boundary(opposite_halfedge_handle(b)))
                return false;
            (side ? vr : vl) = to_vertex_handle(a);
        }
        if (vl.is_valid() && vl == vr)
            return false;
        if (is_boundary(v0) && is_boundary(v1) && !is_boundary(v0v1) && !is_boundary(v1v0))
            return false;
        // v0's neighbours marked with a fresh stamp: no pass to clear them
        if (++stamp_ == 0) {
            std::fill(mark_.begin(), mark_.end(), 0u);
            stamp_ = 1;
        }
        if (mark_.size() < n_vertices())
            mark_.resize(n_vertices(), 0u);
        HalfedgeHandle start = halfedge_handle(v0), h = start;
        if (h.is_valid())
            do {
                mark_[(size_t)to_vertex_handle(h).idx()] = stamp_;
                h = next_halfedge_handle(opposite_halfedge_handle(h));
            } while (h != start);
        start = h = halfedge_handle(v1);
        if (h.is_valid())
            do {
                VertexHandle w = to_vertex_handle(h);
                if (mark_[(size_t)w.idx()] == stamp_ && w != vl && w != vr)
                    return false;
                h = next_halfedge_handle(opposite_halfedge_handle(h));
            } while (h != start);
        return true;
    }

    // A face's normal, as the library's own (the same three points in the
    // same order, the same arithmetic) without a circulator: the decimater
    // and the normal-flipping guard take it by name lookup on Mesh, for
    // every face around each collapse they weigh.
    Normal calc_face_normal(FaceHandle f) const
    {
        HalfedgeHandle h0 = halfedge_handle(f), h1 = next_halfedge_handle(h0),
                       h2 = next_halfedge_handle(h1);
        return PolyMesh::calc_face_normal(point(to_vertex_handle(h0)), point(to_vertex_handle(h1)),
                                          point(to_vertex_handle(h2)));
    }

    // The halfedge from a to b, or an invalid one: the decimater asks it of
    // the two opposite vertices of every collapse it weighs (a tetrahedron
    // test), and the library's compiled one checks every handle it touches.
    HalfedgeHandle find_halfedge(VertexHandle a, VertexHandle b) const
    {
        HalfedgeHandle start = halfedge_handle(a), h = start;
        if (h.is_valid())
            do {
                if (to_vertex_handle(h) == b)
                    return h;
                h = next_halfedge_handle(opposite_halfedge_handle(h));
            } while (h != start);
        return HalfedgeHandle();
    }

    // The decimater's priority module (ModQuadricT<Mesh>), for heap_vertex
    // below; set once the module is added.
    void *quadric = nullptr;

private:
    std::vector<uint32_t> mark_;
    uint32_t stamp_ = 0;
};

// A binary module that vetoes nothing: it is here to see every collapse the
// decimater performs, in order, right before it happens.
template <class MeshT> class ModRecordT : public OpenMesh::Decimater::ModBaseT<MeshT> {
public:
    DECIMATING_MODULE(ModRecordT, MeshT, Record);

    explicit ModRecordT(MeshT &mesh) : Base(mesh, true) {}

    void preprocess_collapse(const CollapseInfo &ci) override
    {
        mts_collapse c;
        c.removed = (uint32_t)ci.v0.idx();
        c.kept = (uint32_t)ci.v1.idx();
        c.faces_removed = (ci.fl.is_valid() ? 1u : 0u) + (ci.fr.is_valid() ? 1u : 0u);
        collapses.push_back(c);
        if (progress && progress->fn && target > 0 && (collapses.size() & 1023) == 0)
            progress->fn(progress->user, "simplify", (double)collapses.size() / (double)target);
    }

    std::vector<mts_collapse> collapses;
    const mts_progress *progress = nullptr;
    size_t target = 0;
};

// The quadric's priority plus a colour term, after Garland and Heckbert,
// "Simplifying Surfaces with Color and Texture using Quadric Error
// Metrics" (IEEE Visualization 1998), reduced to what a half-edge collapse
// needs: the kept vertex keeps its own colour (the stream sends the source
// colour of every vertex), so instead of their colour quadric over a moving
// attribute vector each vertex holds the area-weighted sums of the colours
// it stands for (area, sum of colours, sum of squared colours), and the
// error of representing them by a colour c is
//     area |c|^2 - 2 c . sum + sum of squares,
// accumulated on collapse as the geometric quadric is. Like the quadric's
// priority it is the total error of the merged vertex, not the increment.
template <class MeshT> class ModQuadricColorT : public OpenMesh::Decimater::ModQuadricT<MeshT> {
public:
    typedef ModQuadricColorT<MeshT> Self;
    typedef OpenMesh::Decimater::ModHandleT<Self> Handle;
    typedef OpenMesh::Decimater::ModQuadricT<MeshT> Quadric;
    typedef typename Quadric::CollapseInfo CollapseInfo;
    DECIMATER_MODNAME(QuadricColor)

    explicit ModQuadricColorT(MeshT &mesh) : Quadric(mesh) {}

    // colors: 3 bytes a vertex; area: each vertex's third of its faces'
    // areas; scale: what a squared colour distance (channels over 255,
    // summed) of unit area costs in the quadric's units.
    void set_colors(const uint8_t *colors, const std::vector<double> &area, double scale)
    {
        size_t n = area.size();
        stats_.assign(n, Stats{});
        for (size_t v = 0; v < n; v++) {
            Stats &s = stats_[v];
            s.area = area[v];
            for (int k = 0; k < 3; k++) {
                double c = colors[3 * v + k] / 255.0;
                s.sum[k] = area[v] * c;
                s.sq += area[v] * c * c;
            }
            s.own[0] = colors[3 * v] / 255.0;
            s.own[1] = colors[3 * v + 1] / 255.0;
            s.own[2] = colors[3 * v + 2] / 255.0;
        }
        scale_ = scale;
    }

    float collapse_priority(const CollapseInfo &ci) override
    {
        float q = Quadric::collapse_priority(ci);
        if (q < 0)
            return q;
        const Stats &a = stats_[(size_t)ci.v0.idx()], &b = stats_[(size_t)ci.v1.idx()];
        const double *c = b.own; // the kept vertex's colour
        double area = a.area + b.area, sq = a.sq + b.sq, dot = 0, cc = 0;
        for (int k = 0; k < 3; k++) {
            dot += c[k] * (a.sum[k] + b.sum[k]);
            cc += c[k] * c[k];
        }
        double e = area * cc - 2 * dot + sq;
        return q + (float)(scale_ * (e > 0 ? e : 0));
    }

    void postprocess_collapse(const CollapseInfo &ci) override
    {
        Quadric::postprocess_collapse(ci);
        Stats &a = stats_[(size_t)ci.v0.idx()], &b = stats_[(size_t)ci.v1.idx()];
        b.area += a.area;
        b.sq += a.sq;
        for (int k = 0; k < 3; k++)
            b.sum[k] += a.sum[k];
    }

private:
    struct Stats {
        double area = 0, sum[3] = {0, 0, 0}, sq = 0, own[3] = {0, 0, 0};
    };
    std::vector<Stats> stats_;
    double scale_ = 0;
};

} // namespace

// A vertex's best collapse, as the library's heap_vertex chooses it -- the
// lowest priority among the outgoing halfedges whose collapse is legal and
// passes the binary modules, the first of equals in circulation order --
// but the cheap, pure quadric priority first for all of them and the
// costly, pure tests (link condition, normal flips) then in ascending order
// only until one passes, instead of the tests for every one.
template <>
void OpenMesh::Decimater::DecimaterT<Mesh>::heap_vertex(VertexHandle vh)
{
    typedef OpenMesh::Decimater::ModQuadricT<Mesh> Quadric;
    Quadric *quadric = static_cast<Quadric *>(mesh_.quadric);
    struct candidate {
        float prio;
        int order;
        Mesh::HalfedgeHandle h;
    };
    candidate local[32];
    std::vector<candidate> more;
    candidate *c = local;
    int n = 0;
    for (Mesh::VertexOHalfedgeIter it(mesh_, vh); it.is_valid(); ++it) {
        CollapseInfo ci(mesh_, *it);
        float prio = quadric->collapse_priority(ci);
        if (!(prio >= 0.0f && prio < FLT_MAX))
            continue;
        if (n == 32 && c == local) {
            more.assign(local, local + 32);
            c = nullptr;
        }
        if (c)
            c[n] = candidate{prio, n, *it};
        else
            more.push_back(candidate{prio, n, *it});
        n++;
    }
    if (!c)
        c = more.data();
    std::sort(c, c + n, [](const candidate &a, const candidate &b) {
        return a.prio < b.prio || (a.prio == b.prio && a.order < b.order);
    });
    Mesh::HalfedgeHandle target;
    float best = -1;
    for (int k = 0; k < n; k++) {
        CollapseInfo ci(mesh_, c[k].h);
        if (this->is_collapse_legal(ci) && this->collapse_priority(ci) >= 0.0f) {
            target = c[k].h;
            best = c[k].prio;
            break;
        }
    }
    mesh_.property(collapse_target_, vh) = target;
    mesh_.property(priority_, vh) = target.is_valid() ? best : -1;
    if (target.is_valid()) {
        if (heap_->is_stored(vh))
            heap_->update(vh);
        else
            heap_->insert(vh);
    } else if (heap_->is_stored(vh)) {
        heap_->remove(vh);
    }
}

extern "C" mts_result mts_simplify(const float *positions, uint32_t vertex_count,
                                   const uint32_t *triangles, uint32_t triangle_count,
                                   const mts_simplify_options *opts,
                                   mts_simplify_result *result, mts_error *err)
{
    static const mts_simplify_options defaults = {};
    if (!opts)
        opts = &defaults;
    *result = mts_simplify_result{};
    if (vertex_count == 0 || triangle_count == 0)
        return mts_error_set(err, MTS_ERR_ARG, "simplify: empty mesh");

    try {
        mts::OmQuiet quiet;
        Mesh mesh;
        mesh.reserve(vertex_count, (size_t)triangle_count * 3 / 2 + 3, triangle_count);
        for (uint32_t v = 0; v < vertex_count; v++) {
            const float *p = positions + 3 * (size_t)v;
            mesh.add_vertex(Mesh::Point(p[0], p[1], p[2]));
        }
        for (uint32_t f = 0; f < triangle_count; f++) {
            const uint32_t *t = triangles + 3 * (size_t)f;
            if (t[0] >= vertex_count || t[1] >= vertex_count || t[2] >= vertex_count)
                return mts_error_set(err, MTS_ERR_RANGE,
                                     "simplify: triangle %u has a vertex out of range", f);
            Mesh::FaceHandle fh = mesh.add_face(Mesh::VertexHandle((int)t[0]),
                                                Mesh::VertexHandle((int)t[1]),
                                                Mesh::VertexHandle((int)t[2]));
            if (!fh.is_valid())
                return mts_error_set(err, MTS_ERR_ARG,
                                     "simplify: triangle %u is not manifold (filter the mesh first)",
                                     f);
        }
        mesh.request_face_normals();
        mesh.update_face_normals();

        uint32_t target = opts->base_vertices;
        if (target == 0) {
            target = vertex_count / 100;
            if (target < 4)
                target = 4;
        }
        if (target > vertex_count)
            target = vertex_count;

        OpenMesh::Decimater::DecimaterT<Mesh> decimater(mesh);
        OpenMesh::Decimater::ModQuadricT<Mesh>::Handle quadric;
        ModQuadricColorT<Mesh>::Handle colored;
        OpenMesh::Decimater::ModNormalFlippingT<Mesh>::Handle flip;
        ModRecordT<Mesh>::Handle record;
        // an uncoloured mesh (or no weight) takes the plain quadric, so that
        // its collapses are exactly those of the builder before colours
        const bool by_color = opts->colors && opts->color_weight > 0;
        if (by_color)
            decimater.add(colored);
        else
            decimater.add(quadric);
        decimater.add(flip);
        decimater.add(record);
        OpenMesh::Decimater::ModQuadricT<Mesh> &prio =
            by_color ? decimater.module(colored) : decimater.module(quadric);
        prio.unset_max_err(); // priority only, no error cap
        mesh.quadric = &prio;
        if (by_color) {
            std::vector<double> area(vertex_count, 0.0);
            float lo[3] = {FLT_MAX, FLT_MAX, FLT_MAX}, hi[3] = {-FLT_MAX, -FLT_MAX, -FLT_MAX};
            for (uint32_t v = 0; v < vertex_count; v++)
                for (int k = 0; k < 3; k++) {
                    lo[k] = std::min(lo[k], positions[3 * (size_t)v + k]);
                    hi[k] = std::max(hi[k], positions[3 * (size_t)v + k]);
                }
            // the quadric's faces weigh by area, so the colours' vertices do
            for (uint32_t f = 0; f < triangle_count; f++) {
                const uint32_t *t = triangles + 3 * (size_t)f;
                double e1[3], e2[3];
                for (int k = 0; k < 3; k++) {
                    e1[k] = (double)positions[3 * (size_t)t[1] + k] - positions[3 * (size_t)t[0] + k];
                    e2[k] = (double)positions[3 * (size_t)t[2] + k] - positions[3 * (size_t)t[0] + k];
                }
                double cx = e1[1] * e2[2] - e1[2] * e2[1], cy = e1[2] * e2[0] - e1[0] * e2[2],
                       cz = e1[0] * e2[1] - e1[1] * e2[0];
                double a = 0.5 * std::sqrt(cx * cx + cy * cy + cz * cz) / 3;
                for (int k = 0; k < 3; k++)
                    area[t[k]] += a;
            }
            double diag2 = 0;
            for (int k = 0; k < 3; k++)
                diag2 += ((double)hi[k] - lo[k]) * ((double)hi[k] - lo[k]);
            decimater.module(colored).set_colors(opts->colors, area, opts->color_weight * diag2);
        }
        decimater.module(flip).set_max_normal_deviation(
            opts->max_normal_deviation_deg > 0 ? opts->max_normal_deviation_deg : 90.0);
        ModRecordT<Mesh> &rec = decimater.module(record);
        rec.progress = &opts->progress;
        rec.target = vertex_count - target;
        rec.collapses.reserve(vertex_count - target);
        if (!decimater.initialize())
            return mts_error_set(err, MTS_ERR_INTERNAL, "simplify: OpenMesh decimater did not initialise");
        decimater.decimate_to(target);

        size_t n = rec.collapses.size();
        result->collapses = (mts_collapse *)malloc((n ? n : 1) * sizeof(mts_collapse));
        if (!result->collapses)
            return mts_error_set(err, MTS_ERR_NOMEM, "simplify: out of memory for %zu collapses", n);
        uint32_t faces = triangle_count;
        for (size_t i = 0; i < n; i++) {
            result->collapses[i] = rec.collapses[i];
            faces -= rec.collapses[i].faces_removed;
        }
        result->collapse_count = (uint32_t)n;
        result->base_vertices = vertex_count - (uint32_t)n;
        result->base_triangles = faces;
        mts_progress_report(&opts->progress, "simplify", 1.0);
        return MTS_OK;
    } catch (const std::bad_alloc &) {
        mts_simplify_result_free(result);
        return mts_error_set(err, MTS_ERR_NOMEM, "simplify: out of memory");
    } catch (const std::exception &e) {
        mts_simplify_result_free(result);
        return mts_error_set(err, MTS_ERR_INTERNAL, "simplify: OpenMesh: %s", e.what());
    }
}

extern "C" void mts_simplify_result_free(mts_simplify_result *result)
{
    if (!result)
        return;
    free(result->collapses);
    *result = mts_simplify_result{};
}
