// SPDX-License-Identifier: MIT
#include "prep/collapse_recorder.h"

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModQuadricT.hh>

#include <algorithm>
#include <cmath>

namespace occ {

namespace {

using TriMesh = OpenMesh::TriMesh_ArrayKernelT<>;

// A binary Decimater module that allows every collapse and writes each one down: the removed
// vertex (v0), the kept one (v1), the faces that vanish (fl, fr) and the quadric cost.
template <class MeshT>
class CollapseRecorderT : public OpenMesh::Decimater::ModBaseT<MeshT> {
public:
    DECIMATING_MODULE(CollapseRecorderT, MeshT, CollapseRecorder);

    CollapseRecorderT(MeshT& mesh) : Base(mesh, true) {}

    void attach(CollapseSequence* out, const std::vector<uint32_t>* triangle_of_face,
                OpenMesh::Decimater::ModQuadricT<MeshT>* quadric) {
        out_ = out;
        triangle_of_face_ = triangle_of_face;
        quadric_ = quadric;
    }

    float collapse_priority(const CollapseInfo&) override { return Base::LEGAL_COLLAPSE; }

    void preprocess_collapse(const CollapseInfo& ci) override {
        // The quadric module still holds both endpoints' quadrics before the collapse.
        pending_error_ = std::sqrt(std::max(0.0f, quadric_->collapse_priority(ci)));
    }

    void postprocess_collapse(const CollapseInfo& ci) override {
        uint32_t removed[2];
        size_t count = 0;
        for (auto f : {ci.fl, ci.fr})
            if (f.is_valid()) removed[count++] = (*triangle_of_face_)[size_t(f.idx())];
        if (count == 2 && removed[0] > removed[1]) std::swap(removed[0], removed[1]);
        out_->push(uint32_t(ci.v0.idx()), uint32_t(ci.v1.idx()), pending_error_, removed, count);
    }

private:
    CollapseSequence* out_ = nullptr;
    const std::vector<uint32_t>* triangle_of_face_ = nullptr;
    OpenMesh::Decimater::ModQuadricT<MeshT>* quadric_ = nullptr;
    float pending_error_ = 0.0f;
};

}  // namespace

CollapseSequence openMeshCollapseSequence(const std::vector<glm::vec3>& positions,
                                          const std::vector<uint32_t>& triangles) {
    TriMesh mesh;
    mesh.request_vertex_status();
    mesh.request_edge_status();
    mesh.request_face_status();
    mesh.request_face_normals();
    for (const glm::vec3& p : positions) mesh.add_vertex(TriMesh::Point(p.x, p.y, p.z));

    CollapseSequence sequence;
    std::vector<uint32_t> triangle_of_face;
    std::vector<uint32_t> refused;
    for (uint32_t t = 0; t < triangles.size() / 3; ++t) {
        const TriMesh::VertexHandle vs[3] = {TriMesh::VertexHandle(int(triangles[3 * t])),
                                             TriMesh::VertexHandle(int(triangles[3 * t + 1])),
                                             TriMesh::VertexHandle(int(triangles[3 * t + 2]))};
        // OpenMesh also reports a refused face on omerr (which import redirects off the
        // terminal); the count is what we keep.
        const TriMesh::FaceHandle f = mesh.add_face(vs[0], vs[1], vs[2]);
        if (f.is_valid())
            triangle_of_face.push_back(t);
        else
            refused.push_back(t);
    }
    sequence.refused_faces = uint32_t(refused.size());
    for (uint32_t t : refused)
        for (int c = 0; c < 3; ++c) mesh.status(TriMesh::VertexHandle(int(triangles[3 * t + c]))).set_locked(true);
    for (auto v : mesh.vertices())
        if (mesh.is_boundary(v)) mesh.status(v).set_locked(true);
    mesh.update_face_normals();

    OpenMesh::Decimater::DecimaterT<TriMesh> decimater(mesh);
    OpenMesh::Decimater::ModQuadricT<TriMesh>::Handle quadric;
    CollapseRecorderT<TriMesh>::Handle recorder;
    decimater.add(quadric);
    decimater.add(recorder);
    decimater.module(quadric).unset_max_err();
    decimater.module(recorder).attach(&sequence, &triangle_of_face, &decimater.module(quadric));
    if (!decimater.initialize()) return sequence;
    decimater.decimate(0);  // 0: as many collapses as are legal
    return sequence;
}

}  // namespace occ
