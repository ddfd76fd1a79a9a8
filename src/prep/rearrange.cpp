// SPDX-License-Identifier: MIT
#include "prep/rearrange.h"

namespace occ {

CollapseArrays recordCollapseArrays(uint32_t vertex_count, uint32_t triangle_count, const CollapseSequence& sequence) {
    CollapseArrays a;
    a.ecol.assign(vertex_count, -1);
    a.permuteV.assign(vertex_count, UINT32_MAX);
    a.permuteT.assign(triangle_count, UINT32_MAX);
    a.map.assign(size_t(vertex_count) + 1, 0);

    uint32_t m = vertex_count, t = triangle_count;
    a.map[m] = t;
    for (size_t i = 0; i < sequence.size(); ++i) {
        const uint32_t u = sequence.removed[i];
        a.ecol[u] = int32_t(sequence.kept[i]);
        a.permuteV[u] = m - 1;
        for (uint32_t j = sequence.triangle_offsets[i]; j < sequence.triangle_offsets[i + 1]; ++j)
            a.permuteT[sequence.triangles[j]] = --t;
        --m;
        a.map[m] = t;
    }
    a.q = m;
    // Survivors fill the front, in their original order.
    uint32_t next = 0;
    for (uint32_t v = 0; v < vertex_count; ++v)
        if (a.permuteV[v] == UINT32_MAX) a.permuteV[v] = next++;
    next = 0;
    for (uint32_t tri = 0; tri < triangle_count; ++tri)
        if (a.permuteT[tri] == UINT32_MAX) a.permuteT[tri] = next++;
    for (uint32_t k = 0; k < a.q; ++k) a.map[k] = a.map[a.q];
    return a;
}

ProgressiveMesh rearrange(const std::vector<glm::vec3>& positions, const std::vector<uint32_t>& triangles,
                          const CollapseSequence& sequence, const CollapseArrays& arrays) {
    const size_t n = positions.size(), tc = triangles.size() / 3;
    ProgressiveMesh pm;
    pm.positions.resize(n);
    pm.ecol.assign(n, -1);
    pm.error.assign(n, 0.0f);
    pm.triangles.resize(triangles.size());
    pm.map = arrays.map;
    pm.q = arrays.q;
    pm.refused_faces = sequence.refused_faces;
    for (size_t v = 0; v < n; ++v) {
        const uint32_t nv = arrays.permuteV[v];
        pm.positions[nv] = positions[v];
        if (arrays.ecol[v] >= 0) pm.ecol[nv] = int32_t(arrays.permuteV[size_t(arrays.ecol[v])]);
    }
    for (size_t i = 0; i < sequence.size(); ++i) pm.error[arrays.permuteV[sequence.removed[i]]] = sequence.error[i];
    for (size_t t = 0; t < tc; ++t) {
        const uint32_t nt = arrays.permuteT[t];
        for (int c = 0; c < 3; ++c) pm.triangles[3 * nt + c] = arrays.permuteV[triangles[3 * t + c]];
    }
    return pm;
}

}  // namespace occ
