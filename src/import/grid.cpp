// SPDX-License-Identifier: MIT
#include "import/grid.h"

#include "import/glb_writer.h"
#include "scene/errors.h"

#include <glm/gtc/matrix_transform.hpp>

#include <algorithm>
#include <cmath>

namespace occ {

void writeGrid(const std::string& path, const Scene& model, const GridOptions& options) {
    const uint64_t tiles = uint64_t(options.nx) * options.ny * options.nz;
    if (tiles == 0) throw OptionError("tiles", std::to_string(options.nx) + "x" + std::to_string(options.ny) + "x" +
                                            std::to_string(options.nz) + ": every count must be at least 1");
    // glTF node indices are 32-bit and every tile holds one node per object plus its own.
    if (tiles * (model.objects.size() + 1) > (1ull << 31))
        throw OptionError("tiles", std::to_string(tiles) + " tiles of " + std::to_string(model.objects.size()) +
                         " objects exceed the 2^31 nodes a glTF file can index");
    if (!(options.spacing >= 0.0f) || !std::isfinite(options.spacing))
        throw OptionError("spacing", "must be a finite number >= 0");

    const Bounds bounds = model.worldBounds();
    const glm::vec3 extent = bounds.max - bounds.min;
    const float spacing =
        options.spacing > 0.0f ? options.spacing : 1.25f * std::max({extent.x, extent.y, extent.z, 1e-6f});

    std::vector<GltfNode> nodes;
    nodes.reserve(size_t(tiles * (model.objects.size() + 1)));
    std::vector<uint32_t> roots;
    roots.reserve(size_t(tiles));
    for (uint32_t z = 0; z < options.nz; ++z)
        for (uint32_t y = 0; y < options.ny; ++y)
            for (uint32_t x = 0; x < options.nx; ++x) {
                GltfNode tile;
                tile.matrix = glm::translate(glm::mat4(1.0f), glm::vec3(float(x), float(y), float(z)) * spacing);
                const uint32_t tile_index = uint32_t(nodes.size());
                for (uint32_t c = 0; c < model.objects.size(); ++c) tile.children.push_back(tile_index + 1 + c);
                nodes.push_back(std::move(tile));
                for (const Object& o : model.objects) {
                    GltfNode child;
                    child.mesh = int32_t(o.mesh);
                    child.matrix = o.world;
                    nodes.push_back(std::move(child));
                }
                roots.push_back(tile_index);
            }
    writeGlb(path, model.meshes, nodes, roots);
}

}  // namespace occ
