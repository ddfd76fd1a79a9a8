// SPDX-License-Identifier: MIT
#pragma once

#include "scene/scene.h"

#include <atomic>
#include <cstdint>
#include <functional>
#include <string>

namespace occ {

inline constexpr uint32_t kMaxPlantObjects = 10'000'000;

struct PlantOptions {
    uint32_t objects = 2000;  // exact object count, 1 .. kMaxPlantObjects
    uint64_t seed = 1;
};

// Where the plant puts things, so camera paths can walk through it. Units are metres, y is up.
// Bays of bayPitch x bayPitch tile x in [0, baysX * bayPitch] and z in [0, baysZ * bayPitch];
// floor f's walking surface is at y = f * storeyHeight (its slab lies just below it, and the
// top floor also has a roof slab). In every bay the bands corridorMin..corridorMax of bay-local
// x and of bay-local z are corridors: from the floor surface up to corridorClearance above it
// they hold no geometry, except within 0.5 m of the building's outer walls. Corridors line up
// from bay to bay, so they form a street grid on every floor.
struct PlantLayout {
    uint32_t floors = 1;
    uint32_t baysX = 1;
    uint32_t baysZ = 1;
    float bayPitch = 12.0f;
    float storeyHeight = 6.0f;
    float slabThickness = 0.3f;
    float corridorMin = 4.6f;
    float corridorMax = 7.4f;
    float corridorClearance = 2.2f;
};

// The grid generatePlant(options) uses: about 40 objects per bay per floor, at most 6 floors,
// bays as square as possible. Throws UsageError if options.objects is 0 or above
// kMaxPlantObjects.
PlantLayout plantLayout(const PlantOptions& options);

// A procedural industrial plant laid out as plantLayout(options): per bay and floor a slab,
// columns, girders, outer walls and some inner walls with door gaps, then equipment in the four
// quadrants between the corridors (boxes, motors, vertical tanks, horizontal vessels, spheres on
// the ground floor) and, overhead, pipes (risers from the quadrants, racks over the corridors,
// with 90-degree elbows) and cable trays.
//
// Returns exactly options.objects objects; object i owns mesh i (no sharing), named
// "<kind>_<i>" with kind one of slab, wall, column, girder, equipment, motor, tank, vessel,
// sphere, pipe, tray, and Object::color equals Mesh::color. Every mesh is closed and
// two-manifold with shared vertices (each directed edge appears once, its reverse once),
// triangles are counter-clockwise seen from outside and never degenerate, and it has between
// 12 triangles (a box) and 20 000. Every 25th bay-floor, starting with the first, holds one
// object of 15 000 to 20 000 triangles (a finely tessellated tank or pipe coil) unless its
// share of the objects is used up by its structure, so plants of 2000 objects or more always
// have one; every plant's first object is a 12-triangle slab. Meshes are in local coordinates near their origin and
// world matrices are rigid (translation, and a quarter turn for lying vessels).
//
// The result depends only on the options (a splitmix64 stream per bay-floor; no standard
// distributions). Throws UsageError as plantLayout does.
Scene generatePlant(const PlantOptions& options);

// The same plant handed out one object at a time (object i's mesh and world matrix, in order,
// Mesh::color its colour), so a plant larger than memory can be written as it is made.
using PlantSink = std::function<void(Mesh&& mesh, const glm::mat4& world)>;
void generatePlant(const PlantOptions& options, const PlantSink& sink);

// generatePlant streamed into a glTF file (GltfStreamWriter: .glb, or .gltf + .bin beyond the
// 4 GiB of a .glb), holding one mesh at a time; counts what it wrote in *progress as it goes.
struct PlantProgress {
    std::atomic<uint64_t> objects{0}, triangles{0};
};
void writePlant(const std::string& path, const PlantOptions& options, PlantProgress* progress = nullptr);

}  // namespace occ
