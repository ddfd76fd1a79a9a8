// SPDX-License-Identifier: MIT
#include "prep/vertex_normals.h"

#include "prep/symmetric_eigen.h"
#include "scene/oss_file.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace occ {

std::vector<uint32_t> hlodVertexNormals(const ProgressiveMesh& pm, float planarity, uint32_t keep) {
    const uint32_t n = pm.vertexCount();
    // Upper triangle of the symmetric tensor: xx, xy, xz, yy, yz, zz.
    std::vector<std::array<double, 6>> tensor(n, std::array<double, 6>{});
    std::vector<uint8_t> has_face(n, 0);
    for (size_t t = 0; t + 2 < pm.triangles.size(); t += 3) {
        const uint32_t a = pm.triangles[t], b = pm.triangles[t + 1], c = pm.triangles[t + 2];
        const glm::dvec3 cross = glm::cross(glm::dvec3(pm.positions[b]) - glm::dvec3(pm.positions[a]),
                                            glm::dvec3(pm.positions[c]) - glm::dvec3(pm.positions[a]));
        const double twice_area = glm::length(cross);
        if (!(twice_area > 0.0) || !std::isfinite(twice_area)) continue;
        // area n n^T = cross cross^T / (2 |cross|)
        const glm::dvec3 m = cross / std::sqrt(2.0 * twice_area);
        const std::array<double, 6> f{m.x * m.x, m.x * m.y, m.x * m.z, m.y * m.y, m.y * m.z, m.z * m.z};
        for (const uint32_t v : {a, b, c}) {
            has_face[v] = 1;
            for (int k = 0; k < 6; ++k) tensor[v][k] += f[k];
        }
    }
    // Placed vertices come before their members (ecol[v] < v), so a sweep from the last vertex
    // down hands each member's gathered tensor on before its cluster hands its own.
    for (uint32_t v = n; v-- > 0;) {
        const int32_t into = pm.ecol[v];
        if (into >= 0 && uint32_t(into) < v && !has_face[uint32_t(into)])
            for (int k = 0; k < 6; ++k) tensor[uint32_t(into)][k] += tensor[v][k];
    }
    std::vector<uint32_t> normals(n, oss::kNoNormal);
    for (uint32_t v = 0; v < std::min(n, keep); ++v) {
        const std::array<double, 6>& t = tensor[v];
        const double trace = t[0] + t[3] + t[5];
        if (!(trace > 0.0) || !std::isfinite(trace)) continue;
        double a[3][3] = {{t[0], t[1], t[2]}, {t[1], t[3], t[4]}, {t[2], t[4], t[5]}};
        double values[3], vectors[3][3];
        symmetricEigen(a, values, vectors);
        int top = 0;
        for (int i = 1; i < 3; ++i)
            if (values[i] > values[top]) top = i;
        if (!(values[top] >= double(planarity) * trace)) continue;
        const glm::dvec3 axis(vectors[0][top], vectors[1][top], vectors[2][top]);
        const double length = glm::length(axis);
        if (!(length > 0.0)) continue;
        normals[v] = oss::encodeNormal(glm::vec3(axis / length));
    }
    return normals;
}

}  // namespace occ
