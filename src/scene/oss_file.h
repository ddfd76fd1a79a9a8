// SPDX-License-Identifier: MIT
#pragma once

// The .oss scene file: a PreparedScene laid out to be memory-mapped. docs/oss_format.md is the
// byte-level reference; the structs below are that layout, defined once.

#include "scene/prepared_scene.h"

#include <glm/glm.hpp>

#include <bit>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace occ {

static_assert(std::endian::native == std::endian::little,
              "the .oss file is little-endian and mapped as-is; a big-endian port needs byte swapping");

namespace oss {

inline constexpr char kMagic[8] = {'O', 'C', 'C', 'S', 'W', 'O', 'S', 'S'};
// 2: the NODES section (the hierarchy); 3: HLOD placement; 4: leaves stored as their object's
// id alone (NODES), inner nodes' fields in INNER; 5: COLOURS, a colour per vertex (issue 49);
// 6: NORMALS, a normal per vertex (an HLOD's: the full detail's it stands for; issue 49).
inline constexpr uint32_t kVersion = 6;
inline constexpr uint64_t kAlignment = 64;  // of every section, so any element type can be mapped

// Section ids, also their order in the header's table and in the file.
enum class SectionId : uint32_t {
    meshes = 1,     // MeshRecord per mesh
    positions = 2,  // float[3] per vertex, all meshes back to back
    ecol = 3,       // int32 per vertex
    error = 4,      // float per vertex
    triangles = 5,  // uint32[3] per triangle
    map = 6,        // uint32 per (vertex_count + 1) per mesh
    objects = 7,    // ObjectDisk per object
    cos = 8,        // uint32 object id per candidate occluder
    nodes = 9,      // NodeLink per hierarchy node; empty without a hierarchy
    inner = 10,     // InnerDisk per inner node, in node order; empty without a hierarchy
    colours = 11,   // uint32 per vertex, laid out as POSITIONS: RGBA8 (kWhite: the object's colour alone)
    normals = 12,   // uint32 per vertex, laid out as POSITIONS: octahedral snorm16x2 (kNoNormal: none)
};
inline constexpr uint32_t kSectionCount = 12;
const char* sectionName(SectionId id);  // "MESHES", "POSITIONS", ...

// One row of the header's section table.
struct SectionEntry {
    uint32_t id;            // SectionId, equal to row index + 1
    uint32_t element_size;  // bytes per element, fixed per id
    uint64_t offset;        // from the start of the file; a multiple of kAlignment
    uint64_t size;          // bytes, = element count * element_size (padding excluded)
    uint64_t checksum;      // XXH3_64bits (seed 0) of the `size` bytes at `offset`
};
static_assert(sizeof(SectionEntry) == 32);

// The first 512 bytes of the file.
struct Header {
    char magic[8];              // kMagic
    uint32_t version;           // kVersion
    uint32_t header_size;       // sizeof(Header)
    uint64_t file_size;         // bytes of the whole file
    uint32_t section_count;     // kSectionCount
    uint32_t mesh_count;        // >= 1
    uint32_t object_count;      // >= 1
    uint32_t cos_count;         // <= object_count
    uint64_t vertex_count;      // over all meshes
    uint64_t triangle_count;    // over all meshes
    float ct;                   // compactness threshold the COS was built with, in [0, 1]
    uint32_t node_count;        // hierarchy nodes, 0 (none) or 1 + objects' leaves and more
    SectionEntry sections[kSectionCount];
    uint32_t inner_count;       // the hierarchy's inner nodes (< node_count; 0 without one)
    uint8_t reserved1[52];      // 0
    uint64_t header_checksum;   // XXH3_64bits (seed 0) of the bytes before it
};
static_assert(sizeof(Header) == 512 && sizeof(Header) % kAlignment == 0);
static_assert(offsetof(Header, version) == 8 && offsetof(Header, file_size) == 16);
static_assert(offsetof(Header, section_count) == 24 && offsetof(Header, vertex_count) == 40);
static_assert(offsetof(Header, ct) == 56 && offsetof(Header, node_count) == 60 && offsetof(Header, sections) == 64);
static_assert(offsetof(Header, inner_count) == 448 && offsetof(Header, reserved1) == 452 &&
              offsetof(Header, header_checksum) == 504);

// A vertex colour in COLOURS: R | G << 8 | B << 16 | A << 24, RGB sRGB-encoded. The shader
// multiplies it into the object's colour, so kWhite leaves that alone: the objects' meshes are
// white; an HLOD's vertices carry the colours of the objects they stand for.
inline constexpr uint32_t kWhite = 0xFFFFFFFFu;

// A vertex normal in NORMALS: the unit vector's octahedral map (x, y in [-1, 1]) as two snorm16,
// x | y << 16 (GLSL's packSnorm2x16), up to sign: the display lights both sides and turns it to
// the eye. kNoNormal: the vertex has none (the objects' meshes, and an HLOD vertex whose surface
// has no one direction, such as a corner), and is lit by its face's normal.
inline constexpr uint32_t kNoNormal = 0u;
uint32_t encodeNormal(const glm::vec3& unit);  // never kNoNormal
glm::vec3 decodeNormal(uint32_t packed);        // unit length; (0, 0, 1) for kNoNormal

// Where one mesh's elements start in the shared per-vertex / per-triangle / map sections. The
// ranges of consecutive meshes are contiguous (first[i+1] = first[i] + count[i]), from 0.
struct MeshRecord {
    uint64_t vertex_first;       // index into POSITIONS, ECOL, ERROR
    uint64_t triangle_first;     // index into TRIANGLES (in triangles, not indices)
    uint64_t map_first;          // index into MAP; = vertex_first + mesh index
    uint32_t vertex_count;       // n < 2^32 - 1
    uint32_t triangle_count;     // T
    uint32_t q;                  // vertices never collapsed; 1 <= q <= n (0 only when n = 0)
    uint32_t refused_faces;
    uint32_t source_vertices;
    uint32_t dropped_triangles;
};
static_assert(sizeof(MeshRecord) == 48 && offsetof(MeshRecord, vertex_count) == 24);

// ObjectRecord with fixed-width fields and no padding. Every float is finite.
struct ObjectDisk {
    uint32_t mesh;               // < mesh_count
    float color[4];
    float world[16];             // column-major, as glm::mat4
    float aabb_min[3];
    float aabb_max[3];
    float oobb_center[3];
    float oobb_axis[3][3];       // three axes, each xyz
    float oobb_half_extent[3];
    float occluder_normal[3];
    float compactness;           // in [0, 1]
};
static_assert(sizeof(ObjectDisk) == 184 && offsetof(ObjectDisk, world) == 20);
static_assert(offsetof(ObjectDisk, aabb_min) == 84 && offsetof(ObjectDisk, oobb_axis) == 120);
static_assert(offsetof(ObjectDisk, compactness) == 180);
static_assert(sizeof(glm::vec3) == 12 && alignof(glm::vec3) <= 4, "positions are mapped as glm::vec3");

ObjectDisk toDisk(const ObjectRecord& o);
ObjectRecord fromDisk(const ObjectDisk& d);

// The hierarchy on disk (docs/oss_format.md): nodes in breadth-first order, children of a node
// consecutive. A leaf is its object and nothing more (its box, triangles and placement are the
// object's); an inner node's fields live in INNER, in node order.
struct NodeLink {
    uint32_t first;        // inner nodes: the first child; leaves: the object, < object_count
    uint32_t child_count;  // 0: a leaf
};
static_assert(sizeof(NodeLink) == 8);
struct InnerDisk {
    float box_min[3];      // holds the children's boxes
    float box_max[3];
    uint32_t mesh;         // the HLOD mesh, < mesh_count
    float error;           // SceneNode::error: finite, >= 0
    uint64_t triangles;    // the subtree's full-detail triangles: the children's sum
    float world[16];       // where the HLOD mesh is placed, column-major
};
static_assert(sizeof(InnerDisk) == 104 && offsetof(InnerDisk, mesh) == 24 && offsetof(InnerDisk, triangles) == 32 &&
              offsetof(InnerDisk, world) == 40);

// A node as the reader hands it out: NODES and INNER put together, with a leaf's box and
// triangles taken from its object and mesh, and every node's depth.
struct Node {
    float box_min[3];
    float box_max[3];
    uint32_t first_child;  // inner nodes; 0 for leaves
    uint32_t child_count;  // 0: a leaf
    uint32_t object;       // leaves: the object; inner nodes: UINT32_MAX
    uint32_t mesh;         // inner nodes: the HLOD mesh; leaves: UINT32_MAX
    uint32_t depth;        // the parent's + 1; 0 at the root
    float error;           // 0 for leaves
    uint64_t triangles;    // the subtree's full-detail triangles
    float world[16];       // inner nodes: the HLOD mesh's placement; leaves: identity
};

SceneNode fromNode(const Node& n);

}  // namespace oss

// Writes `scene` to `path` atomically: the bytes go to a new temporary file next to `path`
// ("<path>.tmp.<pid>.<n>"), are fsync'ed, and the temporary is renamed over `path`; on any
// failure the temporary is removed and an existing file at `path` is left as it was.
// The scene's content is not validated (so that tests can write files the reader must reject),
// only what the layout needs: per mesh ecol and error have one entry per position, map has
// vertexCount() + 1, triangles a multiple of 3, and every count fits in 32 bits; otherwise
// throws std::invalid_argument naming the mesh. Throws InputError(path, ...) on I/O failure.
// Streams section by section, so its memory use does not grow with the scene.
void writeOss(const std::string& path, const PreparedScene& scene);

// The same file written one mesh at a time, for scenes larger than memory: addMesh in mesh
// order (each mesh's sections go to unnamed temporary files beside `path`, hashed as they are
// written), then finish() with the objects and the COS assembles the file (the spooled sections
// copied in by the kernel) and renames it into place. Same bytes as writeOss of the same scene;
// same checks (std::invalid_argument) and failures (InputError). Destroyed without finish(),
// it leaves nothing behind.
class OssFile;

class OssStreamWriter {
public:
    explicit OssStreamWriter(const std::string& path);
    ~OssStreamWriter();
    OssStreamWriter(const OssStreamWriter&) = delete;
    OssStreamWriter& operator=(const OssStreamWriter&) = delete;

    uint32_t addMesh(const ProgressiveMesh& mesh);  // returns the mesh's index
    // Takes every mesh of `flat` as meshes 0 .. flat.meshCount() - 1, before any other: their
    // bytes are copied by the kernel from flat's file at finish (not spooled), hashed now.
    // flat must stay open until finish; its pages are released as they are hashed.
    void addMeshesOf(const OssFile& flat);
    // false: finish does not fsync the file (a temporary that this process reads back and
    // removes); true, the default, makes the written file durable before its rename.
    void setDurable(bool durable);
    uint32_t meshCount() const;
    uint64_t vertexCount() const;
    uint64_t triangleCount() const;
    void finish(std::span<const ObjectRecord> objects, std::span<const uint32_t> cos, float ct,
                std::span<const SceneNode> nodes = {});

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

// A validated, read-only memory mapping of a .oss file. Views returned by it point into the
// mapping and live as long as the OssFile. The file must not be modified in place while mapped
// (writeOss never does: it replaces files by renaming).
class OssFile {
public:
    // Maps `path` and checks, in this order, before returning: header size, magic, version,
    // header checksum, header fields, the section table (id, element size, 64-byte alignment,
    // size = count * element size, inside the file, canonical position so that sections are in
    // order and do not overlap), zero padding between and after sections, every section's
    // checksum, then every index and value (see docs/oss_format.md, "Validation"). Throws
    // InputError(path, "section S at offset O: what"), O the byte offset of the bad field or element.
    // pages Release: validation drops what it has read from the resident set as it goes
    // (releasePages), so that open holds at most about kReleaseBytes of the file: for a pass
    // that reads the file once (prep's hierarchy). Keep (the default): the pages validation
    // read stay mapped for the frames that read them again.
    enum class Pages { Keep, Release };
    static OssFile open(const std::string& path, Pages pages = Pages::Keep);

    OssFile(OssFile&& other) noexcept;
    OssFile& operator=(OssFile&& other) noexcept;
    OssFile(const OssFile&) = delete;
    OssFile& operator=(const OssFile&) = delete;
    ~OssFile();

    const std::string& path() const { return path_; }
    uint64_t fileSize() const { return size_; }
    // Drops the mapping's pages from this process's resident set (they stay in the page cache,
    // and a later read maps them again). Passes over a whole file call it as they go, so that
    // reading a file larger than memory does not hold it: validation of a file opened with
    // Pages::Release, and prep's HLOD pass over the flat scene.
    void releasePages() const;
    static constexpr uint64_t kReleaseBytes = uint64_t(256) << 20;
    // releasePages when the file was opened with Pages::Release.
    void releaseIfAsked() const {
        if (release_pages_) releasePages();
    }
    uint32_t meshCount() const { return header().mesh_count; }
    uint32_t objectCount() const { return header().object_count; }
    uint64_t vertexCount() const { return header().vertex_count; }      // over meshes, not instances
    uint64_t triangleCount() const { return header().triangle_count; }  // over meshes, not instances
    float ct() const { return header().ct; }

    struct MeshView {
        std::span<const glm::vec3> positions;
        std::span<const int32_t> ecol;
        std::span<const float> error;
        std::span<const uint32_t> triangles;  // 3 corners per triangle
        std::span<const uint32_t> map;        // positions.size() + 1 entries
        std::span<const uint32_t> colours;    // positions.size() entries (oss::kWhite: none of its own)
        std::span<const uint32_t> normals;    // positions.size() entries (oss::kNoNormal: none)
        uint32_t q = 0;
        uint32_t refused_faces = 0;
        uint32_t source_vertices = 0;
        uint32_t dropped_triangles = 0;

        uint32_t vertexCount() const { return uint32_t(positions.size()); }
        uint32_t triangleCount() const { return uint32_t(triangles.size() / 3); }
    };
    MeshView mesh(uint32_t i) const;  // throws std::out_of_range if i >= meshCount()
    ProgressiveMesh progressiveMesh(uint32_t i) const;  // a copy of mesh(i)

    std::span<const oss::ObjectDisk> objects() const;  // zero-copy, objectCount() records
    std::span<const oss::MeshRecord> meshRecords() const;  // where each mesh's arrays start
    // The whole sections, all meshes back to back (index them with meshRecords()), zero-copy:
    // what the runtime streams from and uploads once.
    std::span<const glm::vec3> allPositions() const;
    std::span<const int32_t> allEcol() const;
    std::span<const uint32_t> allTriangles() const;  // 3 corners per triangle, mesh-local numbering
    std::span<const uint32_t> allMaps() const;
    std::span<const uint32_t> allColours() const;  // laid out as allPositions()
    std::span<const uint32_t> allNormals() const;  // laid out as allPositions()
    ObjectRecord object(uint32_t i) const;             // throws std::out_of_range if i >= objectCount()
    std::span<const uint32_t> cos() const;             // sorted by compactness, highest first
    // The hierarchy (empty without one), breadth-first; inner nodes' HLODs are meshes. Built
    // from NODES and INNER when the file is opened (120 bytes a node in memory).
    std::span<const oss::Node> nodes() const { return nodes_; }
    uint32_t nodeCount() const { return header().node_count; }
    // The hierarchy's HLODs: inner nodes, the distinct HLOD meshes they draw (repeated subtrees
    // share one) and those meshes' triangles, each counted once.
    struct HlodCounts {
        uint64_t inner = 0, meshes = 0, triangles = 0;
    };
    HlodCounts hlodCounts() const;

    struct SectionInfo {
        std::string name;
        uint64_t offset = 0;
        uint64_t size = 0;   // bytes, padding excluded
        uint64_t count = 0;  // elements
    };
    std::vector<SectionInfo> sections() const;  // in file order, for `occswitch info`
    // The bytes of section `id` (oss::SectionId, 1-based), as stored (checksummed at open).
    std::span<const std::byte> sectionBytes(uint32_t id) const;

    // Checks the LOD prefix property of every mesh: for every k in [q, n], the first map[k]
    // triangles with corners walked through ecol until < k are non-degenerate and every later
    // triangle is degenerate. O(triangles + sum over collapses of the collapsed vertex's
    // valence) per mesh, meshes in parallel. Throws InputError(path, "section MAP at offset O:
    // mesh M: ...") for the lowest-numbered mesh that violates it.
    void verifyLodPrefix() const;

    PreparedScene toPreparedScene() const;  // a full copy

private:
    OssFile() = default;
    const oss::Header& header() const { return *reinterpret_cast<const oss::Header*>(base_); }
    template <typename T>
    const T* sectionData(oss::SectionId id) const;
    void validate() const;
    std::vector<oss::Node> validateNodes() const;  // NODES and INNER checked and put together
    void unmap() noexcept;

    std::string path_;
    std::vector<oss::Node> nodes_;
    const std::byte* base_ = nullptr;
    uint64_t size_ = 0;
    bool release_pages_ = false;  // opened with Pages::Release
};

}  // namespace occ
