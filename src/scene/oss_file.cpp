// SPDX-License-Identifier: MIT
#include "scene/oss_file.h"

#include "scene/lod_prefix.h"

#include "scene/errors.h"

#include <glm/gtc/type_ptr.hpp>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <xxhash.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <system_error>
#include <thread>
#include <utility>

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

namespace occ {

namespace oss {

namespace {

struct SectionKind {
    const char* name;
    uint32_t element_size;
};

// Indexed by SectionId - 1.
constexpr SectionKind kKinds[kSectionCount] = {
    {"MESHES", sizeof(MeshRecord)}, {"POSITIONS", 3 * sizeof(float)}, {"ECOL", sizeof(int32_t)},
    {"ERROR", sizeof(float)},        {"TRIANGLES", 3 * sizeof(uint32_t)}, {"MAP", sizeof(uint32_t)},
    {"OBJECTS", sizeof(ObjectDisk)}, {"COS", sizeof(uint32_t)},          {"NODES", sizeof(NodeLink)},
    {"INNER", sizeof(InnerDisk)},    {"COLOURS", sizeof(uint32_t)},       {"NORMALS", sizeof(uint32_t)},
};

}  // namespace

const char* sectionName(SectionId id) {
    const uint32_t i = uint32_t(id) - 1;
    return i < kSectionCount ? kKinds[i].name : "UNKNOWN";
}

uint32_t encodeNormal(const glm::vec3& unit) {
    // Octahedral map: onto |x| + |y| + |z| = 1, the lower half folded over the diagonals.
    const float l1 = std::abs(unit.x) + std::abs(unit.y) + std::abs(unit.z);
    glm::vec2 o = l1 > 0.0f && std::isfinite(l1) ? glm::vec2(unit.x, unit.y) / l1 : glm::vec2(0.0f);
    if (l1 > 0.0f && unit.z < 0.0f)
        o = (1.0f - glm::abs(glm::vec2(o.y, o.x))) * glm::vec2(o.x >= 0.0f ? 1.0f : -1.0f, o.y >= 0.0f ? 1.0f : -1.0f);
    const auto snorm = [](float v) { return uint32_t(uint16_t(int16_t(std::lround(std::clamp(v, -1.0f, 1.0f) * 32767.0f)))); };
    const uint32_t packed = snorm(o.x) | snorm(o.y) << 16;
    return packed == kNoNormal ? 1u : packed;  // (0, 0, 1) itself: a hair off, so it is one
}

glm::vec3 decodeNormal(uint32_t packed) {
    const glm::vec2 o(std::max(-1.0f, float(int16_t(packed & 0xFFFFu)) / 32767.0f),
                      std::max(-1.0f, float(int16_t(packed >> 16)) / 32767.0f));
    glm::vec3 n(o.x, o.y, 1.0f - std::abs(o.x) - std::abs(o.y));
    if (n.z < 0.0f) {
        const glm::vec2 f = (1.0f - glm::abs(glm::vec2(o.y, o.x))) * glm::vec2(o.x >= 0.0f ? 1.0f : -1.0f, o.y >= 0.0f ? 1.0f : -1.0f);
        n.x = f.x, n.y = f.y;
    }
    return glm::normalize(n);
}

ObjectDisk toDisk(const ObjectRecord& o) {
    ObjectDisk d{};
    d.mesh = o.mesh;
    std::memcpy(d.color, glm::value_ptr(o.color), sizeof d.color);
    std::memcpy(d.world, glm::value_ptr(o.world), sizeof d.world);
    std::memcpy(d.aabb_min, glm::value_ptr(o.aabb.min), sizeof d.aabb_min);
    std::memcpy(d.aabb_max, glm::value_ptr(o.aabb.max), sizeof d.aabb_max);
    std::memcpy(d.oobb_center, glm::value_ptr(o.oobb.center), sizeof d.oobb_center);
    for (int a = 0; a < 3; ++a) std::memcpy(d.oobb_axis[a], glm::value_ptr(o.oobb.axis[a]), sizeof d.oobb_axis[a]);
    std::memcpy(d.oobb_half_extent, glm::value_ptr(o.oobb.half_extent), sizeof d.oobb_half_extent);
    std::memcpy(d.occluder_normal, glm::value_ptr(o.occluder_normal), sizeof d.occluder_normal);
    d.compactness = o.compactness;
    return d;
}

ObjectRecord fromDisk(const ObjectDisk& d) {
    ObjectRecord o;
    o.mesh = d.mesh;
    o.color = glm::make_vec4(d.color);
    o.world = glm::make_mat4(d.world);
    o.aabb.min = glm::make_vec3(d.aabb_min);
    o.aabb.max = glm::make_vec3(d.aabb_max);
    o.oobb.center = glm::make_vec3(d.oobb_center);
    for (int a = 0; a < 3; ++a) o.oobb.axis[a] = glm::make_vec3(d.oobb_axis[a]);
    o.oobb.half_extent = glm::make_vec3(d.oobb_half_extent);
    o.occluder_normal = glm::make_vec3(d.occluder_normal);
    o.compactness = d.compactness;
    return o;
}

SceneNode fromNode(const Node& d) {
    SceneNode n;
    n.box.min = glm::make_vec3(d.box_min);
    n.box.max = glm::make_vec3(d.box_max);
    n.first_child = d.first_child;
    n.child_count = d.child_count;
    n.object = d.object;
    n.mesh = d.mesh;
    n.depth = d.depth;
    n.error = d.error;
    n.triangles = d.triangles;
    std::memcpy(glm::value_ptr(n.world), d.world, sizeof d.world);
    return n;
}

}  // namespace oss

using namespace oss;

namespace {

constexpr uint64_t alignUp(uint64_t x) { return (x + kAlignment - 1) / kAlignment * kAlignment; }

constexpr uint64_t kHeaderChecksummedBytes = offsetof(Header, header_checksum);

std::string str(uint64_t v) { return std::to_string(v); }
std::string str(uint32_t v) { return std::to_string(v); }
std::string str(int32_t v) { return std::to_string(v); }
std::string str(float v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.9g", double(v));
    return buf;
}
std::string hexByte(std::byte b) {
    char buf[8];
    std::snprintf(buf, sizeof buf, "0x%02x", unsigned(b));
    return buf;
}

// A violation found in a file: which section, the byte offset of the bad field, what is wrong.
struct Failure {
    const char* section;
    uint64_t offset;
    std::string what;
};

[[noreturn]] void raise(const std::string& path, const Failure& f) {
    throw InputError(path, std::string("section ") + f.section + " at offset " + str(f.offset) + ": " + f.what);
}

// Runs check(i) for i in [0, count) in parallel and returns the failure of the lowest i that
// fails, so that the reported error does not depend on scheduling.
std::optional<Failure> lowestFailure(uint32_t first, uint32_t count,
                                     const std::function<std::optional<Failure>(uint32_t)>& check) {
    std::mutex mutex;
    std::atomic<uint32_t> lowest{first + count};
    std::optional<Failure> result;
    tbb::parallel_for(tbb::blocked_range<uint32_t>(first, first + count), [&](const tbb::blocked_range<uint32_t>& r) {
        for (uint32_t i = r.begin(); i != r.end(); ++i) {
            if (i >= lowest.load(std::memory_order_relaxed)) return;
            if (std::optional<Failure> f = check(i)) {
                std::lock_guard lock(mutex);
                if (i < lowest.load(std::memory_order_relaxed)) {
                    lowest.store(i, std::memory_order_relaxed);
                    result = std::move(f);
                }
                return;
            }
        }
    });
    return result;
}

std::optional<Failure> lowestFailure(uint32_t count, const std::function<std::optional<Failure>(uint32_t)>& check) {
    return lowestFailure(0, count, check);
}

// The temporary file writeOss fills, with a running XXH3 of the current section. Where the
// file system allows, it is an unnamed O_TMPFILE in the target's folder that only gets a name
// at commit(), so a prep killed mid-write (Ctrl-C, OOM) leaves nothing behind at all; otherwise
// a named temporary that the destructor removes unless commit() renamed it into place.
class TempFileWriter {
public:
    explicit TempFileWriter(const std::string& path) : path_(path), state_(XXH3_createState(), &XXH3_freeState) {
        if (!state_) throw std::bad_alloc();
        std::string dir = std::filesystem::path(path_).parent_path().string();
        if (dir.empty()) dir = ".";
        fd_ = ::open(dir.c_str(), O_TMPFILE | O_WRONLY | O_CLOEXEC, 0666);
        unnamed_ = fd_ >= 0;
        if (!unnamed_ && errno == ENOENT)
            throw InputError(path_, "cannot create temporary file in " + dir + ": " + std::strerror(errno));
        static std::atomic<uint64_t> counter{0};
        for (int attempt = 0;; ++attempt) {
            tmp_ = path + ".tmp." + std::to_string(::getpid()) + "." + std::to_string(counter++);
            if (unnamed_) break;
            fd_ = ::open(tmp_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
            named_ = fd_ >= 0;
            if (named_) break;
            if (errno != EEXIST || attempt == 100)
                throw InputError(path_, "cannot create temporary file " + tmp_ + ": " + std::strerror(errno));
        }
        buffer_.reserve(kBufferSize);
    }
    ~TempFileWriter() {
        if (fd_ >= 0) ::close(fd_);
        if (!committed_ && named_) ::unlink(tmp_.c_str());
    }
    TempFileWriter(const TempFileWriter&) = delete;
    TempFileWriter& operator=(const TempFileWriter&) = delete;

    uint64_t position() const { return position_; }

    void zeros(uint64_t n) {
        static const std::byte kZeros[kAlignment * 8] = {};
        while (n > 0) {
            const uint64_t chunk = std::min<uint64_t>(n, sizeof kZeros);
            append(kZeros, chunk);
            n -= chunk;
        }
    }
    void padToAlignment() { zeros(alignUp(position_) - position_); }

    void beginSection() {
        padToAlignment();
        section_offset_ = position_;
        XXH3_64bits_reset(state_.get());
    }
    void put(const void* data, uint64_t n) {
        if (n == 0) return;
        XXH3_64bits_update(state_.get(), data, n);
        append(data, n);
    }
    SectionEntry endSection(SectionId id) {
        return {uint32_t(id), kKinds[uint32_t(id) - 1].element_size, section_offset_, position_ - section_offset_,
                XXH3_64bits_digest(state_.get())};
    }

    // Copies byte ranges of other files to given offsets of this one, in the kernel, the
    // ranges in parallel (after what is buffered is written); position() becomes `end`.
    struct Copy {
        int fd;
        uint64_t from, size, to;
    };
    void copyRanges(const std::vector<Copy>& copies, uint64_t end) {
        flush();
        std::vector<int> failed(copies.size(), 0);
        const auto run = [&](size_t i) {
            loff_t from = loff_t(copies[i].from), to = loff_t(copies[i].to);
            for (uint64_t n = copies[i].size; n > 0;) {
                const ssize_t c = ::copy_file_range(copies[i].fd, &from, fd_, &to, size_t(std::min<uint64_t>(n, 1u << 28)), 0);
                if (c < 0 && errno == EINTR) continue;
                if (c <= 0) {
                    failed[i] = c < 0 ? errno : EIO;
                    return;
                }
                n -= uint64_t(c);
            }
        };
        // A thread per range but the first; where no thread can be started, the rest run here.
        std::vector<std::thread> threads;
        size_t here_from = copies.size();
        try {
            for (size_t i = 1; i < copies.size(); ++i) threads.emplace_back(run, i);
        } catch (const std::system_error&) {
            here_from = 1 + threads.size();
        }
        if (!copies.empty()) run(0);
        for (size_t i = here_from; i < copies.size(); ++i) run(i);
        for (std::thread& t : threads) t.join();
        for (const int e : failed)
            if (e) {
                errno = e;
                ioFailure("cannot copy a section into");
            }
        position_ = end;
        if (::lseek(fd_, off_t(position_), SEEK_SET) < 0) ioFailure("cannot seek in");
    }

    // Writes the header over the placeholder at offset 0, syncs, and renames into place.
    void commit(const Header& header, bool durable) {
        flush();
        const auto* p = reinterpret_cast<const std::byte*>(&header);
        for (uint64_t done = 0; done < sizeof header;) {
            const ssize_t n = ::pwrite(fd_, p + done, sizeof header - done, off_t(done));
            if (n < 0 && errno == EINTR) continue;
            if (n <= 0) ioFailure("cannot write");
            done += uint64_t(n);
        }
        if (durable && ::fsync(fd_) != 0) ioFailure("cannot sync");
        if (unnamed_) {
            // linkat cannot replace a file, so the unnamed file gets a fresh name first and is
            // then renamed over the target like a named temporary.
            const std::string proc = "/proc/self/fd/" + std::to_string(fd_);
            if (::linkat(AT_FDCWD, proc.c_str(), AT_FDCWD, tmp_.c_str(), AT_SYMLINK_FOLLOW) != 0)
                ioFailure("cannot name");
        }
        named_ = true;
        const int fd = std::exchange(fd_, -1);
        if (::close(fd) != 0) ioFailure("cannot close");
        if (::rename(tmp_.c_str(), path_.c_str()) != 0)
            throw InputError(path_, "cannot rename " + tmp_ + " into place: " + std::strerror(errno));
        committed_ = true;
        if (!durable) return;
        // The rename is durable only once the directory is synced. The new file is already in
        // place, so a failure here is not reported as a failed write.
        std::string dir = std::filesystem::path(path_).parent_path().string();
        if (dir.empty()) dir = ".";
        const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
        if (dfd >= 0) {
            ::fsync(dfd);
            ::close(dfd);
        }
    }

private:
    static constexpr uint64_t kBufferSize = 1 << 20;

    [[noreturn]] void ioFailure(const char* action) {
        throw InputError(path_, std::string(action) + " temporary file " + tmp_ + ": " + std::strerror(errno));
    }
    void append(const void* data, uint64_t n) {
        position_ += n;
        if (buffer_.size() + n > kBufferSize) flush();
        if (n >= kBufferSize) {
            writeAll(static_cast<const std::byte*>(data), n);
        } else {
            const auto* p = static_cast<const std::byte*>(data);
            buffer_.insert(buffer_.end(), p, p + n);
        }
    }
    void flush() {
        writeAll(buffer_.data(), buffer_.size());
        buffer_.clear();
    }
    void writeAll(const std::byte* p, uint64_t n) {
        while (n > 0) {
            const ssize_t w = ::write(fd_, p, std::min<uint64_t>(n, 1u << 30));
            if (w < 0 && errno == EINTR) continue;
            if (w <= 0) ioFailure("cannot write");
            p += w;
            n -= uint64_t(w);
        }
    }

    std::string path_, tmp_;
    bool unnamed_ = false;  // fd_ is an O_TMPFILE without a name yet
    bool named_ = false;    // tmp_ exists on disk and must be removed on failure
    std::unique_ptr<XXH3_state_t, decltype(&XXH3_freeState)> state_;
    int fd_ = -1;
    bool committed_ = false;
    std::vector<std::byte> buffer_;
    uint64_t position_ = 0;
    uint64_t section_offset_ = 0;
};

// One section's bytes while the meshes stream in: an unnamed temporary file in the target's
// folder (removed by the kernel when closed), written through a buffer and hashed as it goes.
class SectionSpool {
public:
    explicit SectionSpool(const std::string& path) : path_(path), state_(XXH3_createState(), &XXH3_freeState) {
        if (!state_) throw std::bad_alloc();
        std::string dir = std::filesystem::path(path).parent_path().string();
        if (dir.empty()) dir = ".";
        fd_ = ::open(dir.c_str(), O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
        if (fd_ < 0) {
            // No O_TMPFILE here: a named file, unlinked at once.
            static std::atomic<uint64_t> counter{0};
            const std::string tmp = path + ".spool." + std::to_string(::getpid()) + "." + std::to_string(counter++);
            fd_ = ::open(tmp.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
            if (fd_ < 0) throw InputError(path_, "cannot create temporary file " + tmp + ": " + std::strerror(errno));
            ::unlink(tmp.c_str());
        }
        XXH3_64bits_reset(state_.get());
        buffer_.reserve(kBufferSize);
    }
    ~SectionSpool() {
        if (fd_ >= 0) ::close(fd_);
    }
    SectionSpool(const SectionSpool&) = delete;
    SectionSpool& operator=(const SectionSpool&) = delete;

    void put(const void* data, uint64_t n) {
        if (n == 0) return;
        XXH3_64bits_update(state_.get(), data, n);
        size_ += n;
        const auto* p = static_cast<const std::byte*>(data);
        if (buffer_.size() + n > kBufferSize) flush();
        if (n >= kBufferSize) {
            writeAll(p, n);
        } else {
            buffer_.insert(buffer_.end(), p, p + n);
        }
    }
    void flush() {
        writeAll(buffer_.data(), buffer_.size());
        buffer_.clear();
    }
    // Hashes bytes that come before what is spooled (the section's part copied from elsewhere).
    void hashPrefix(const void* data, uint64_t n) { XXH3_64bits_update(state_.get(), data, n); }
    int fd() const { return fd_; }
    uint64_t size() const { return size_; }
    uint64_t digest() const { return XXH3_64bits_digest(state_.get()); }

private:
    static constexpr uint64_t kBufferSize = 1 << 20;
    void writeAll(const std::byte* p, uint64_t n) {
        while (n > 0) {
            const ssize_t w = ::write(fd_, p, std::min<uint64_t>(n, 1u << 30));
            if (w < 0 && errno == EINTR) continue;
            if (w <= 0) throw InputError(path_, std::string("cannot write temporary file of a section: ") + std::strerror(errno));
            p += w;
            n -= uint64_t(w);
        }
    }
    std::string path_;
    std::unique_ptr<XXH3_state_t, decltype(&XXH3_freeState)> state_;
    int fd_ = -1;
    uint64_t size_ = 0;
    std::vector<std::byte> buffer_;
};

void requireMeshLayout(const ProgressiveMesh& m, uint64_t index) {
    constexpr uint64_t kMax32 = std::numeric_limits<uint32_t>::max();
    auto bad = [&](const std::string& what) { throw std::invalid_argument("writeOss: mesh " + str(index) + ": " + what); };
    const uint64_t n = m.positions.size();
    if (n >= kMax32) bad(str(n) + " vertices do not fit in 32 bits");
    if (m.triangles.size() % 3 != 0) bad("triangle index count is not a multiple of 3");
    if (m.triangles.size() / 3 > kMax32) bad("triangle count does not fit in 32 bits");
    if (m.ecol.size() != n) bad("ecol has " + str(uint64_t(m.ecol.size())) + " entries, expected " + str(n));
    if (m.error.size() != n) bad("error has " + str(uint64_t(m.error.size())) + " entries, expected " + str(n));
    if (m.map.size() != n + 1) bad("map has " + str(uint64_t(m.map.size())) + " entries, expected " + str(n + 1));
    if (!m.colours.empty() && m.colours.size() != n)
        bad("colours has " + str(uint64_t(m.colours.size())) + " entries, expected 0 or " + str(n));
    if (!m.normals.empty() && m.normals.size() != n)
        bad("normals has " + str(uint64_t(m.normals.size())) + " entries, expected 0 or " + str(n));
}

}  // namespace

namespace {

// A per-vertex u32 section's part for one mesh of n vertices: its values, or n times `none`
// where the mesh has none.
void putPerVertex(SectionSpool& spool, const std::vector<uint32_t>& values, uint64_t n, uint32_t none) {
    if (!values.empty()) {
        spool.put(values.data(), values.size() * sizeof(uint32_t));
        return;
    }
    const std::vector<uint32_t> fill(std::min<uint64_t>(n, 4096), none);
    for (uint64_t done = 0; done < n; done += fill.size())
        spool.put(fill.data(), std::min<uint64_t>(fill.size(), n - done) * sizeof(uint32_t));
}

}  // namespace

struct OssStreamWriter::Impl {
    explicit Impl(const std::string& p)
        : path(p), file(p), positions(p), ecol(p), error(p), triangles(p), map(p), colours(p), normals(p) {}
    std::string path;
    TempFileWriter file;
    SectionSpool positions, ecol, error, triangles, map, colours, normals;
    std::vector<MeshRecord> records;
    uint64_t vertex_count = 0, triangle_count = 0;
    bool durable = true;
    // addMeshesOf: the flat file the seven per-mesh sections start with, and each one's range in
    // it (POSITIONS .. MAP, then COLOURS and NORMALS).
    int prefix_fd = -1;
    uint64_t prefix_offset[7] = {}, prefix_size[7] = {};
    ~Impl() {
        if (prefix_fd >= 0) ::close(prefix_fd);
    }
};

OssStreamWriter::OssStreamWriter(const std::string& path) : impl_(std::make_unique<Impl>(path)) {}
OssStreamWriter::~OssStreamWriter() = default;

uint32_t OssStreamWriter::addMesh(const ProgressiveMesh& m) {
    Impl& w = *impl_;
    const uint64_t i = w.records.size();
    requireMeshLayout(m, i);
    if (i >= std::numeric_limits<uint32_t>::max()) throw std::invalid_argument("writeOss: too many meshes for 32 bits");
    w.records.push_back(MeshRecord{w.vertex_count, w.triangle_count, w.vertex_count + i, m.vertexCount(),
                                   m.triangleCount(), m.q, m.refused_faces, m.source_vertices, m.dropped_triangles});
    w.vertex_count += m.vertexCount();
    w.triangle_count += m.triangleCount();
    w.positions.put(m.positions.data(), m.positions.size() * sizeof(glm::vec3));
    w.ecol.put(m.ecol.data(), m.ecol.size() * sizeof(int32_t));
    w.error.put(m.error.data(), m.error.size() * sizeof(float));
    w.triangles.put(m.triangles.data(), m.triangles.size() * sizeof(uint32_t));
    w.map.put(m.map.data(), m.map.size() * sizeof(uint32_t));
    putPerVertex(w.colours, m.colours, m.positions.size(), kWhite);
    putPerVertex(w.normals, m.normals, m.positions.size(), kNoNormal);
    return uint32_t(i);
}

void OssStreamWriter::setDurable(bool durable) { impl_->durable = durable; }

void OssStreamWriter::addMeshesOf(const OssFile& flat) {
    Impl& w = *impl_;
    if (!w.records.empty() || w.prefix_fd >= 0) throw std::logic_error("OssStreamWriter::addMeshesOf: must come first");
    w.prefix_fd = ::open(flat.path().c_str(), O_RDONLY | O_CLOEXEC);
    if (w.prefix_fd < 0) throw InputError(flat.path(), std::string("cannot open: ") + std::strerror(errno));
    const auto records = flat.meshRecords();
    w.records.assign(records.begin(), records.end());
    w.vertex_count = flat.vertexCount();
    w.triangle_count = flat.triangleCount();
    SectionSpool* spools[] = {&w.positions, &w.ecol, &w.error, &w.triangles, &w.map, &w.colours, &w.normals};
    const std::vector<OssFile::SectionInfo> sections = flat.sections();  // [0] is the header, [id] section id
    tbb::parallel_for(0, 7, [&](int k) {
        const uint32_t id = k < 5 ? uint32_t(k + 2) : k == 5 ? uint32_t(SectionId::colours) : uint32_t(SectionId::normals);
        const std::span<const std::byte> bytes = flat.sectionBytes(id);
        w.prefix_offset[k] = sections[size_t(id)].offset;
        w.prefix_size[k] = bytes.size();
        for (uint64_t at = 0; at < bytes.size(); at += OssFile::kReleaseBytes) {
            spools[k]->hashPrefix(bytes.data() + at, std::min<uint64_t>(OssFile::kReleaseBytes, bytes.size() - at));
            flat.releasePages();
        }
    }, tbb::simple_partitioner());
}

uint32_t OssStreamWriter::meshCount() const { return uint32_t(impl_->records.size()); }
uint64_t OssStreamWriter::vertexCount() const { return impl_->vertex_count; }
uint64_t OssStreamWriter::triangleCount() const { return impl_->triangle_count; }

void OssStreamWriter::finish(std::span<const ObjectRecord> objects, std::span<const uint32_t> cos, float ct,
                             std::span<const SceneNode> nodes) {
    Impl& s = *impl_;
    constexpr uint64_t kMax32 = std::numeric_limits<uint32_t>::max();
    if (objects.size() > kMax32) throw std::invalid_argument("writeOss: " + str(uint64_t(objects.size())) + " objects do not fit in 32 bits");
    if (cos.size() > kMax32) throw std::invalid_argument("writeOss: " + str(uint64_t(cos.size())) + " COS entries do not fit in 32 bits");
    if (nodes.size() >= kMax32) throw std::invalid_argument("writeOss: " + str(uint64_t(nodes.size())) + " nodes do not fit in 32 bits");
    TempFileWriter& w = s.file;
    Header h{};
    w.zeros(sizeof h);  // placeholder; the header is written last, once the checksums are known

    w.beginSection();
    w.put(s.records.data(), s.records.size() * sizeof(MeshRecord));
    h.sections[0] = w.endSection(SectionId::meshes);
    // The five large sections: each one's part from addMeshesOf's file, then its spool, copied
    // by the kernel, all at once (their offsets follow from their sizes).
    SectionSpool* spools[] = {&s.positions, &s.ecol, &s.error, &s.triangles, &s.map};
    std::vector<TempFileWriter::Copy> copies;
    uint64_t at = w.position();
    for (int k = 0; k < 5; ++k) {
        SectionSpool& spool = *spools[k];
        spool.flush();
        at = alignUp(at);
        const uint64_t size = s.prefix_size[k] + spool.size();
        if (s.prefix_size[k] > 0) copies.push_back({s.prefix_fd, s.prefix_offset[k], s.prefix_size[k], at});
        if (spool.size() > 0) copies.push_back({spool.fd(), 0, spool.size(), at + s.prefix_size[k]});
        const SectionId id = SectionId(k + 2);
        h.sections[k + 1] = {uint32_t(id), kKinds[uint32_t(id) - 1].element_size, at, size, spool.digest()};
        at += size;
    }
    w.copyRanges(copies, at);
    w.beginSection();
    for (const ObjectRecord& o : objects) {
        const ObjectDisk d = toDisk(o);
        w.put(&d, sizeof d);
    }
    h.sections[6] = w.endSection(SectionId::objects);
    w.beginSection();
    w.put(cos.data(), cos.size() * sizeof(uint32_t));
    h.sections[7] = w.endSection(SectionId::cos);
    // A leaf is its object alone; an inner node's fields go to INNER, in node order.
    w.beginSection();
    uint64_t inner_count = 0;
    for (const SceneNode& n : nodes) {
        const NodeLink l{n.child_count ? n.first_child : n.object, n.child_count};
        w.put(&l, sizeof l);
        inner_count += n.child_count > 0;
    }
    h.sections[8] = w.endSection(SectionId::nodes);
    w.beginSection();
    for (const SceneNode& n : nodes) {
        if (n.child_count == 0) continue;
        InnerDisk d{};
        std::memcpy(d.box_min, glm::value_ptr(n.box.min), sizeof d.box_min);
        std::memcpy(d.box_max, glm::value_ptr(n.box.max), sizeof d.box_max);
        d.mesh = n.mesh;
        d.error = n.error;
        d.triangles = n.triangles;
        std::memcpy(d.world, glm::value_ptr(n.world), sizeof d.world);
        w.put(&d, sizeof d);
    }
    h.sections[9] = w.endSection(SectionId::inner);
    // COLOURS and NORMALS, last in the file, copied as the five above are.
    for (int k = 5; k < 7; ++k) {
        SectionSpool& spool = k == 5 ? s.colours : s.normals;
        const SectionId id = k == 5 ? SectionId::colours : SectionId::normals;
        spool.flush();
        const uint64_t from = alignUp(w.position()), size = s.prefix_size[k] + spool.size();
        std::vector<TempFileWriter::Copy> tail_copies;
        if (s.prefix_size[k] > 0) tail_copies.push_back({s.prefix_fd, s.prefix_offset[k], s.prefix_size[k], from});
        if (spool.size() > 0) tail_copies.push_back({spool.fd(), 0, spool.size(), from + s.prefix_size[k]});
        w.padToAlignment();
        w.copyRanges(tail_copies, from + size);
        h.sections[uint32_t(id) - 1] = {uint32_t(id), kKinds[uint32_t(id) - 1].element_size, from, size, spool.digest()};
    }
    w.padToAlignment();

    std::memcpy(h.magic, kMagic, sizeof h.magic);
    h.version = kVersion;
    h.header_size = sizeof(Header);
    h.file_size = w.position();
    h.section_count = kSectionCount;
    h.mesh_count = uint32_t(s.records.size());
    h.object_count = uint32_t(objects.size());
    h.cos_count = uint32_t(cos.size());
    h.vertex_count = s.vertex_count;
    h.triangle_count = s.triangle_count;
    h.ct = ct;
    h.node_count = uint32_t(nodes.size());
    h.inner_count = uint32_t(inner_count);
    h.header_checksum = XXH3_64bits(&h, kHeaderChecksummedBytes);
    w.commit(h, s.durable);
}

void writeOss(const std::string& path, const PreparedScene& scene) {
    // Layout inputs are checked before anything is created.
    constexpr uint64_t kMax32 = std::numeric_limits<uint32_t>::max();
    if (scene.meshes.size() > kMax32)
        throw std::invalid_argument("writeOss: " + str(uint64_t(scene.meshes.size())) + " meshes do not fit in 32 bits");
    for (size_t i = 0; i < scene.meshes.size(); ++i) requireMeshLayout(scene.meshes[i], i);
    OssStreamWriter writer(path);
    for (const ProgressiveMesh& m : scene.meshes) writer.addMesh(m);
    writer.finish(scene.objects, scene.cos, scene.ct, scene.nodes);
}


OssFile OssFile::open(const std::string& path, Pages pages) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
    struct stat st {};
    if (::fstat(fd, &st) != 0) {
        const int e = errno;
        ::close(fd);
        throw InputError(path, std::string("cannot stat: ") + std::strerror(e));
    }
    if (!S_ISREG(st.st_mode)) {
        ::close(fd);
        throw InputError(path, "not a regular file");
    }
    const uint64_t size = uint64_t(st.st_size);
    if (size < sizeof(Header)) {
        ::close(fd);
        raise(path, {"HEADER", 0,
                     "file is " + str(size) + " bytes, shorter than the " + str(uint64_t(sizeof(Header))) +
                         "-byte header (truncated, or not an .oss file)"});
    }
    if (size > std::numeric_limits<size_t>::max()) {
        ::close(fd);
        throw InputError(path, "file of " + str(size) + " bytes cannot be mapped by this build");
    }
    void* p = ::mmap(nullptr, size_t(size), PROT_READ, MAP_PRIVATE, fd, 0);
    const int map_errno = errno;
    ::close(fd);  // the mapping keeps the file open
    if (p == MAP_FAILED) throw InputError(path, std::string("cannot map: ") + std::strerror(map_errno));

    OssFile f;
    f.path_ = path;
    f.base_ = static_cast<const std::byte*>(p);
    f.size_ = size;
    f.release_pages_ = pages == Pages::Release;
    // Validation touches every byte once, front to back.
    ::madvise(p, size_t(size), MADV_SEQUENTIAL);
    f.validate();
    f.nodes_ = f.validateNodes();
    f.releaseIfAsked();
    ::madvise(p, size_t(size), MADV_NORMAL);
    return f;
}

OssFile::OssFile(OssFile&& other) noexcept
    : path_(std::move(other.path_)), nodes_(std::move(other.nodes_)), base_(std::exchange(other.base_, nullptr)),
      size_(std::exchange(other.size_, 0)),
      release_pages_(other.release_pages_) {}

OssFile& OssFile::operator=(OssFile&& other) noexcept {
    if (this != &other) {
        unmap();
        path_ = std::move(other.path_);
        nodes_ = std::move(other.nodes_);
        base_ = std::exchange(other.base_, nullptr);
        size_ = std::exchange(other.size_, 0);
        release_pages_ = other.release_pages_;
    }
    return *this;
}

OssFile::~OssFile() { unmap(); }

void OssFile::releasePages() const {
    if (base_) ::madvise(const_cast<std::byte*>(base_), size_t(size_), MADV_DONTNEED);
}

void OssFile::unmap() noexcept {
    if (base_) ::munmap(const_cast<std::byte*>(base_), size_t(size_));
    base_ = nullptr;
    size_ = 0;
}

template <typename T>
const T* OssFile::sectionData(SectionId id) const {
    return reinterpret_cast<const T*>(base_ + header().sections[uint32_t(id) - 1].offset);
}

void OssFile::validate() const {
    const Header& h = header();
    auto fail = [&](const char* section, uint64_t offset, const std::string& what) {
        raise(path_, {section, offset, what});
    };

    // Header. Magic and version come before the checksum so that another file type or a future
    // version is named as such rather than reported as corrupt.
    if (std::memcmp(h.magic, kMagic, sizeof kMagic) != 0) fail("HEADER", 0, "bad magic, not an .oss file");
    if (h.version != kVersion)
        fail("HEADER", offsetof(Header, version),
             "format version " + str(h.version) + ", this build reads version " + str(kVersion) +
                 (h.version < kVersion ? " (prepare the model again: occswitch prep)" : ""));
    if (XXH3_64bits(base_, kHeaderChecksummedBytes) != h.header_checksum)
        fail("HEADER", offsetof(Header, header_checksum), "header checksum mismatch (corrupt header)");
    if (h.header_size != sizeof(Header))
        fail("HEADER", offsetof(Header, header_size),
             "header size " + str(h.header_size) + ", expected " + str(uint64_t(sizeof(Header))));
    if (h.file_size != size_)
        fail("HEADER", offsetof(Header, file_size),
             "the header says the file is " + str(h.file_size) + " bytes but it is " + str(size_) +
                 (size_ < h.file_size ? " (truncated)" : " (data appended)"));
    if (h.section_count != kSectionCount)
        fail("HEADER", offsetof(Header, section_count),
             str(h.section_count) + " sections, expected " + str(kSectionCount));
    if (h.mesh_count == 0) fail("HEADER", offsetof(Header, mesh_count), "no meshes");
    if (h.object_count == 0) fail("HEADER", offsetof(Header, object_count), "no objects");
    if (h.cos_count > h.object_count)
        fail("HEADER", offsetof(Header, cos_count),
             "COS has " + str(h.cos_count) + " entries but there are only " + str(h.object_count) + " objects");
    if (!(h.ct >= 0.0f && h.ct <= 1.0f))
        fail("HEADER", offsetof(Header, ct), "compactness threshold ct = " + str(h.ct) + " is not in [0, 1]");
    if (h.node_count == 0 ? h.inner_count != 0 : h.inner_count == 0 || h.inner_count >= h.node_count)
        fail("HEADER", offsetof(Header, inner_count),
             str(h.inner_count) + " inner nodes for " + str(h.node_count) +
                 " nodes (none without a hierarchy; else at least the root, and fewer than the nodes)");
    for (uint64_t i = 0; i < sizeof h.reserved1; ++i)
        if (h.reserved1[i] != 0) fail("HEADER", offsetof(Header, reserved1) + i, "reserved byte is not 0");

    // Section table. Sections must sit at their canonical positions: in id order, each at the
    // first multiple of 64 after the previous one, the file ending at the first multiple of 64
    // after the last. With zero padding, every byte of the file is then covered by a checksum
    // or must be zero, so that no flipped byte goes unnoticed.
    uint64_t map_count = 0;
    if (__builtin_add_overflow(h.vertex_count, uint64_t(h.mesh_count), &map_count))
        fail("HEADER", offsetof(Header, vertex_count), "vertex count " + str(h.vertex_count) + " overflows");
    const uint64_t counts[kSectionCount] = {h.mesh_count, h.vertex_count, h.vertex_count,  h.vertex_count,
                                            h.triangle_count, map_count,  h.object_count, h.cos_count,
                                            h.node_count, h.inner_count, h.vertex_count, h.vertex_count};
    auto requireZeros = [&](const char* section, uint64_t from, uint64_t to, const char* where) {
        for (uint64_t o = from; o < to; ++o)
            if (base_[o] != std::byte{0})
                fail(section, o, std::string("padding byte ") + where + " the section is " + hexByte(base_[o]) +
                                     ", must be 0");
    };
    uint64_t previous_end = sizeof(Header);
    for (uint32_t i = 0; i < kSectionCount; ++i) {
        const SectionEntry& e = h.sections[i];
        const SectionKind& kind = kKinds[i];
        const uint64_t row = offsetof(Header, sections) + i * sizeof(SectionEntry);
        if (e.id != i + 1)
            fail(kind.name, row, "section table row " + str(i) + " has id " + str(e.id) + ", expected " + str(i + 1));
        if (e.element_size != kind.element_size)
            fail(kind.name, row + offsetof(SectionEntry, element_size),
                 "element size " + str(e.element_size) + ", expected " + str(kind.element_size));
        uint64_t bytes = 0;
        if (__builtin_mul_overflow(counts[i], uint64_t(kind.element_size), &bytes))
            fail(kind.name, row + offsetof(SectionEntry, size),
                 str(counts[i]) + " elements of " + str(kind.element_size) + " bytes overflow 64 bits");
        if (e.size != bytes)
            fail(kind.name, row + offsetof(SectionEntry, size),
                 "size " + str(e.size) + " bytes, expected " + str(counts[i]) + " elements * " +
                     str(kind.element_size) + " bytes = " + str(bytes));
        if (e.offset % kAlignment != 0)
            fail(kind.name, e.offset, "offset is not a multiple of " + str(kAlignment));
        uint64_t end = 0;
        if (__builtin_add_overflow(e.offset, e.size, &end) || end > size_)
            fail(kind.name, e.offset,
                 "the section's " + str(e.size) + " bytes extend past the end of the file (" + str(size_) + " bytes)");
        if (e.offset != alignUp(previous_end))
            fail(kind.name, e.offset,
                 "section starts at " + str(e.offset) + ", expected " + str(alignUp(previous_end)) +
                     " (sections follow each other in id order, each at the next multiple of 64)");
        requireZeros(kind.name, previous_end, e.offset, "before");
        previous_end = end;
    }
    if (alignUp(previous_end) != size_)
        fail(kKinds[kSectionCount - 1].name, previous_end,
             "the file is " + str(size_) + " bytes, expected " + str(alignUp(previous_end)) +
                 " (the last section padded to a multiple of 64)");
    requireZeros(kKinds[kSectionCount - 1].name, previous_end, size_, "after");

    // Checksums a chunk at a time (the same digest as in one go), with Pages::Release the pages
    // read dropped as it goes: a file larger than memory is then read, not held.
    // The sections are hashed in parallel; the first one that fails (in file order) is named.
    std::vector<uint8_t> mismatch(kSectionCount, 0);
    tbb::parallel_for(uint32_t(0), kSectionCount, [&](uint32_t i) {
        const SectionEntry& e = h.sections[i];
        const std::unique_ptr<XXH3_state_t, XXH_errorcode (*)(XXH3_state_t*)> state(XXH3_createState(), XXH3_freeState);
        if (!state) throw std::bad_alloc();
        XXH3_64bits_reset(state.get());
        for (uint64_t at = 0; at < e.size; at += kReleaseBytes) {
            XXH3_64bits_update(state.get(), base_ + e.offset + at, size_t(std::min(kReleaseBytes, e.size - at)));
            releaseIfAsked();
        }
        mismatch[i] = XXH3_64bits_digest(state.get()) != e.checksum;
    }, tbb::simple_partitioner());
    for (uint32_t i = 0; i < kSectionCount; ++i)
        if (mismatch[i]) fail(kKinds[i].name, h.sections[i].offset, "checksum mismatch (corrupt data)");

    // Every index and value. From here on the bytes are what a writer wrote; these checks catch
    // a writer's bugs and hand-made files, and make every later access in bounds.
    const MeshRecord* records = sectionData<MeshRecord>(SectionId::meshes);
    const uint64_t meshes_offset = h.sections[0].offset;
    uint64_t vertex_run = 0, triangle_run = 0;
    for (uint32_t i = 0; i < h.mesh_count; ++i) {
        const MeshRecord& r = records[i];
        const uint64_t at = meshes_offset + uint64_t(i) * sizeof(MeshRecord);
        const auto mesh = [&] { return "mesh " + str(i) + ": "; };  // messages are built only on failure
        if (r.vertex_first != vertex_run)
            fail("MESHES", at + offsetof(MeshRecord, vertex_first),
                 mesh() + "vertex_first = " + str(r.vertex_first) + ", expected " + str(vertex_run) +
                     " (meshes are stored back to back)");
        if (r.triangle_first != triangle_run)
            fail("MESHES", at + offsetof(MeshRecord, triangle_first),
                 mesh() + "triangle_first = " + str(r.triangle_first) + ", expected " + str(triangle_run) +
                     " (meshes are stored back to back)");
        if (r.map_first != vertex_run + i)
            fail("MESHES", at + offsetof(MeshRecord, map_first),
                 mesh() + "map_first = " + str(r.map_first) + ", expected " + str(vertex_run + i));
        if (r.vertex_count == std::numeric_limits<uint32_t>::max())  // map needs n + 1 entries
            fail("MESHES", at + offsetof(MeshRecord, vertex_count), mesh() + "vertex count 2^32 - 1 is too large");
        if (r.vertex_count > h.vertex_count - vertex_run)
            fail("MESHES", at + offsetof(MeshRecord, vertex_count),
                 mesh() + "vertices [" + str(vertex_run) + ", " + str(vertex_run + r.vertex_count) +
                     ") extend past the " + str(h.vertex_count) + " vertices of the file");
        if (r.triangle_count > h.triangle_count - triangle_run)
            fail("MESHES", at + offsetof(MeshRecord, triangle_count),
                 mesh() + "triangles [" + str(triangle_run) + ", " + str(triangle_run + r.triangle_count) +
                     ") extend past the " + str(h.triangle_count) + " triangles of the file");
        if (r.q > r.vertex_count)
            fail("MESHES", at + offsetof(MeshRecord, q),
                 mesh() + "q = " + str(r.q) + " exceeds the vertex count " + str(r.vertex_count));
        if (r.q == 0 && r.vertex_count > 0)
            fail("MESHES", at + offsetof(MeshRecord, q), mesh() + "q = 0, but vertex 0 has no lower vertex to collapse to");
        vertex_run += r.vertex_count;
        triangle_run += r.triangle_count;
    }
    if (vertex_run != h.vertex_count)
        fail("MESHES", meshes_offset,
             "the meshes hold " + str(vertex_run) + " vertices, the file " + str(h.vertex_count));
    if (triangle_run != h.triangle_count)
        fail("MESHES", meshes_offset,
             "the meshes hold " + str(triangle_run) + " triangles, the file " + str(h.triangle_count));

    const auto section_offset = [&](SectionId id) { return h.sections[uint32_t(id) - 1].offset; };
    const uint64_t positions_at = section_offset(SectionId::positions), ecol_at = section_offset(SectionId::ecol),
                   error_at = section_offset(SectionId::error), triangles_at = section_offset(SectionId::triangles),
                   map_at = section_offset(SectionId::map);
    const auto check_mesh = [&](uint32_t i) -> std::optional<Failure> {
        const MeshRecord& r = records[i];
        const MeshView m = mesh(i);
        const uint32_t n = r.vertex_count;
        const auto name = [&] { return "mesh " + str(i) + ": "; };
        for (uint32_t v = 0; v < n; ++v) {
            const glm::vec3 p = m.positions[v];
            if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
                return Failure{"POSITIONS", positions_at + (r.vertex_first + v) * 12,
                               name() + "position " + str(v) + " is not finite"};
        }
        for (uint32_t v = 0; v < n; ++v) {
            const int32_t e = m.ecol[v];
            const uint64_t at = ecol_at + (r.vertex_first + v) * 4;
            if (v < r.q && e != -1)
                return Failure{"ECOL", at, name() + "ecol[" + str(v) + "] = " + str(e) + " but " + str(v) + " < q = " +
                                               str(r.q) + " (never-collapsed vertices have ecol -1)"};
            if (v >= r.q && e < 0)
                return Failure{"ECOL", at, name() + "ecol[" + str(v) + "] = " + str(e) + " is negative but " + str(v) +
                                               " >= q = " + str(r.q)};
            if (v >= r.q && uint32_t(e) >= v)
                return Failure{"ECOL", at, name() + "ecol[" + str(v) + "] = " + str(e) + " is not < " + str(v)};
        }
        for (uint32_t v = 0; v < n; ++v)
            if (!std::isfinite(m.error[v]))
                return Failure{"ERROR", error_at + (r.vertex_first + v) * 4,
                               name() + "error[" + str(v) + "] = " + str(m.error[v]) + " is not finite"};
        for (uint64_t c = 0; c < m.triangles.size(); ++c)
            if (m.triangles[c] >= n)
                return Failure{"TRIANGLES", triangles_at + r.triangle_first * 12 + c * 4,
                               name() + "triangle " + str(c / 3) + " corner " + str(c % 3) + " = " + str(m.triangles[c]) +
                                   " is not < vertex count " + str(n)};
        const auto map_entry = [&](uint32_t k) { return map_at + (r.map_first + k) * 4; };
        for (uint32_t k = 0; k < r.q; ++k)
            if (m.map[k] != m.map[r.q])
                return Failure{"MAP", map_entry(k), name() + "map[" + str(k) + "] = " + str(m.map[k]) + " differs from map[q = " +
                                                        str(r.q) + "] = " + str(m.map[r.q]) +
                                                        " (entries below q repeat map[q])"};
        for (uint32_t k = 1; k <= n; ++k)
            if (m.map[k] < m.map[k - 1])
                return Failure{"MAP", map_entry(k), name() + "map[" + str(k) + "] = " + str(m.map[k]) + " < map[" +
                                                        str(k - 1) + "] = " + str(m.map[k - 1]) +
                                                        " (map must be non-decreasing)"};
        if (m.map[n] != r.triangle_count)
            return Failure{"MAP", map_entry(n), name() + "map[" + str(n) + "] = " + str(m.map[n]) +
                                                    ", expected the triangle count " + str(r.triangle_count)};
        return std::nullopt;
    };
    // In runs of meshes of about kReleaseBytes (with Pages::Release the pages read dropped after
    // each); the runs ascend, so the first failing run's lowest failure is the file's.
    for (uint32_t first = 0; first < h.mesh_count;) {
        uint32_t last = first;
        for (uint64_t bytes = 0; last < h.mesh_count && (last == first || bytes < kReleaseBytes); ++last)
            bytes += uint64_t(records[last].vertex_count) * 28 + uint64_t(records[last].triangle_count) * 12;
        const std::optional<Failure> mesh_failure = lowestFailure(first, last - first, check_mesh);
        releaseIfAsked();
        if (mesh_failure) raise(path_, *mesh_failure);
        first = last;
    }

    // Object records: every float finite, so that culling and LOD never see a NaN.
    struct FloatField {
        const char* name;
        uint32_t first, count;  // in floats after the mesh id
    };
    static constexpr FloatField kFields[] = {{"color", 0, 4},        {"world", 4, 16},        {"aabb_min", 20, 3},
                                             {"aabb_max", 23, 3},    {"oobb_center", 26, 3},  {"oobb_axis", 29, 9},
                                             {"oobb_half_extent", 38, 3}, {"occluder_normal", 41, 3},
                                             {"compactness", 44, 1}};
    constexpr uint32_t kFloats = (sizeof(ObjectDisk) - sizeof(uint32_t)) / sizeof(float);
    static_assert(kFloats == 45);
    const ObjectDisk* objs = sectionData<ObjectDisk>(SectionId::objects);
    const uint64_t objects_at = section_offset(SectionId::objects);
    const std::optional<Failure> object_failure = lowestFailure(h.object_count, [&](uint32_t i) -> std::optional<Failure> {
        const ObjectDisk& d = objs[i];
        const uint64_t at = objects_at + uint64_t(i) * sizeof(ObjectDisk);
        const auto name = [&] { return "object " + str(i) + ": "; };
        if (d.mesh >= h.mesh_count)
            return Failure{"OBJECTS", at, name() + "mesh " + str(d.mesh) + " is not < mesh count " + str(h.mesh_count)};
        float floats[kFloats];
        std::memcpy(floats, reinterpret_cast<const std::byte*>(&d) + sizeof(uint32_t), sizeof floats);
        bool all_finite = true;  // branch-free first: the field walk below is only for the message
        for (const float x : floats) all_finite &= std::isfinite(x);
        if (!all_finite)
            for (const FloatField& f : kFields)
                for (uint32_t j = 0; j < f.count; ++j)
                    if (!std::isfinite(floats[f.first + j]))
                        return Failure{"OBJECTS", at + 4 + (f.first + j) * 4,
                                       name() + f.name + (f.count > 1 ? "[" + str(j) + "]" : std::string()) + " = " +
                                           str(floats[f.first + j]) + " is not finite"};
        if (!(d.compactness >= 0.0f && d.compactness <= 1.0f))
            return Failure{"OBJECTS", at + offsetof(ObjectDisk, compactness),
                           name() + "compactness " + str(d.compactness) + " is not in [0, 1]"};
        return std::nullopt;
    });
    if (object_failure) raise(path_, *object_failure);

    const uint32_t* cos_ids = sectionData<uint32_t>(SectionId::cos);
    const uint64_t cos_at = section_offset(SectionId::cos);
    std::vector<bool> in_cos(h.object_count, false);
    for (uint32_t j = 0; j < h.cos_count; ++j) {
        const uint32_t id = cos_ids[j];
        const uint64_t at = cos_at + uint64_t(j) * 4;
        const auto entry = [&] { return "cos[" + str(j) + "] = " + str(id); };
        if (id >= h.object_count) fail("COS", at, entry() + " is not < object count " + str(h.object_count));
        if (in_cos[id]) fail("COS", at, entry() + " appears twice");
        in_cos[id] = true;
        const float c = objs[id].compactness;
        if (c < h.ct) fail("COS", at, entry() + " has compactness " + str(c) + " < ct = " + str(h.ct));
        if (j > 0 && c > objs[cos_ids[j - 1]].compactness)
            fail("COS", at, entry() + " has compactness " + str(c) + " > " + str(objs[cos_ids[j - 1]].compactness) +
                                " of cos[" + str(j - 1) + "] (must be sorted highest first)");
    }
    releaseIfAsked();
}

std::vector<Node> OssFile::validateNodes() const {
    const Header& h = header();
    std::vector<Node> out;
    if (h.node_count == 0) return out;
    const NodeLink* links = sectionData<NodeLink>(SectionId::nodes);
    const InnerDisk* inner = sectionData<InnerDisk>(SectionId::inner);
    const ObjectDisk* objs = sectionData<ObjectDisk>(SectionId::objects);
    const MeshRecord* meshes = sectionData<MeshRecord>(SectionId::meshes);
    const uint64_t links_at = h.sections[uint32_t(SectionId::nodes) - 1].offset;
    const uint64_t inner_at = h.sections[uint32_t(SectionId::inner) - 1].offset;
    const auto fail = [&](uint32_t i, size_t field, const std::string& what) {
        raise(path_, {"NODES", links_at + uint64_t(i) * sizeof(NodeLink) + field, "node " + str(i) + ": " + what});
    };
    std::vector<uint32_t> inner_of(h.node_count, UINT32_MAX);  // an inner node's INNER record
    const auto failInner = [&](uint32_t i, size_t field, const std::string& what) {
        raise(path_, {"INNER", inner_at + uint64_t(inner_of[i]) * sizeof(InnerDisk) + field,
                      "node " + str(i) + " (inner record " + str(inner_of[i]) + "): " + what});
    };
    // One pass in node order: breadth-first, so every node's parent comes before it and the
    // children of consecutive inner nodes follow each other from node 1 on. That makes the
    // nodes one tree; each object must then be exactly one leaf.
    out.resize(h.node_count);
    std::vector<uint32_t> parent(h.node_count, UINT32_MAX);
    std::vector<bool> leaf_of(h.object_count, false);
    uint64_t next_child = 1, leaves = 0;
    uint32_t inner_seen = 0;
    for (uint32_t i = 0; i < h.node_count; ++i) {
        const NodeLink& l = links[i];
        Node& n = out[i];
        if (i > 0 && parent[i] == UINT32_MAX)
            fail(i, 0, "no node has it as a child (the tree reaches only " + str(next_child) + " nodes)");
        if (i == 0 && l.child_count == 0) fail(i, offsetof(NodeLink, child_count), "the root has no children");
        n.depth = i == 0 ? 0 : out[parent[i]].depth + 1;
        n.child_count = l.child_count;
        if (l.child_count == 0) {
            if (l.first >= h.object_count)
                fail(i, 0, "leaf object " + str(l.first) + " is not < object count " + str(h.object_count));
            if (leaf_of[l.first]) fail(i, 0, "object " + str(l.first) + " is a second leaf");
            leaf_of[l.first] = true;
            ++leaves;
            const ObjectDisk& o = objs[l.first];
            std::memcpy(n.box_min, o.aabb_min, sizeof n.box_min);
            std::memcpy(n.box_max, o.aabb_max, sizeof n.box_max);
            n.first_child = 0;
            n.object = l.first;
            n.mesh = UINT32_MAX;
            n.error = 0.0f;
            n.triangles = meshes[o.mesh].triangle_count;
            for (int e = 0; e < 16; ++e) n.world[e] = e % 5 == 0 ? 1.0f : 0.0f;
            continue;
        }
        if (inner_seen == h.inner_count)
            fail(i, offsetof(NodeLink, child_count),
                 "inner node past the " + str(h.inner_count) + " the header counts (and INNER holds)");
        inner_of[i] = inner_seen++;
        const InnerDisk& d = inner[inner_of[i]];
        if (l.first != next_child)
            fail(i, 0, "first_child " + str(l.first) + ", expected " + str(next_child) +
                           " (children follow in breadth-first order)");
        if (l.child_count > h.node_count - next_child)
            fail(i, offsetof(NodeLink, child_count),
                 str(l.child_count) + " children from node " + str(next_child) + " pass the " + str(h.node_count) + " nodes");
        for (int a = 0; a < 3; ++a) {
            if (!std::isfinite(d.box_min[a]) || !std::isfinite(d.box_max[a]))
                failInner(i, offsetof(InnerDisk, box_min), "box is not finite");
            if (d.box_min[a] > d.box_max[a])
                failInner(i, offsetof(InnerDisk, box_min) + 4 * size_t(a),
                          "box_min[" + str(uint32_t(a)) + "] = " + str(d.box_min[a]) + " > box_max = " + str(d.box_max[a]));
        }
        if (d.mesh >= h.mesh_count)
            failInner(i, offsetof(InnerDisk, mesh), "HLOD mesh " + str(d.mesh) + " is not < mesh count " + str(h.mesh_count));
        if (!(d.error >= 0.0f && d.error < INFINITY))  // also NaN
            failInner(i, offsetof(InnerDisk, error), "error " + str(d.error) + " is not a finite number >= 0");
        for (int e = 0; e < 16; ++e)
            if (!std::isfinite(d.world[e]))
                failInner(i, offsetof(InnerDisk, world) + 4 * size_t(e), "world[" + str(uint32_t(e)) + "] is not finite");
        std::memcpy(n.box_min, d.box_min, sizeof n.box_min);
        std::memcpy(n.box_max, d.box_max, sizeof n.box_max);
        n.first_child = l.first;
        n.object = UINT32_MAX;
        n.mesh = d.mesh;
        n.error = d.error;
        n.triangles = d.triangles;
        std::memcpy(n.world, d.world, sizeof n.world);
        for (uint32_t c = l.first; c < l.first + l.child_count; ++c) parent[c] = i;
        next_child += l.child_count;
    }
    if (next_child != h.node_count) fail(0, 0, "the tree reaches " + str(next_child) + " of the " + str(h.node_count) + " nodes");
    if (inner_seen != h.inner_count)
        raise(path_, {"INNER", inner_at + uint64_t(inner_seen) * sizeof(InnerDisk),
                      str(h.inner_count) + " inner records, but the nodes have " + str(inner_seen) + " inner nodes"});
    if (leaves != h.object_count)
        fail(0, 0, str(leaves) + " leaves for " + str(h.object_count) + " objects (one leaf per object)");
    // Bottom-up: a node holds its children's boxes and triangles.
    std::vector<uint64_t> sums(h.node_count, 0);
    for (uint32_t i = h.node_count; i-- > 1;) {
        const Node& n = out[i];
        const Node& p = out[parent[i]];
        for (int a = 0; a < 3; ++a)
            if (n.box_min[a] < p.box_min[a] || n.box_max[a] > p.box_max[a])
                failInner(parent[i], offsetof(InnerDisk, box_min), "box does not hold child " + str(i) + "'s box");
        if (__builtin_add_overflow(sums[parent[i]], n.triangles, &sums[parent[i]]))
            failInner(parent[i], offsetof(InnerDisk, triangles), "the children's triangles overflow 64 bits");
    }
    for (uint32_t i = 0; i < h.node_count; ++i)
        if (out[i].child_count > 0 && out[i].triangles != sums[i])
            failInner(i, offsetof(InnerDisk, triangles), str(out[i].triangles) + " triangles, its children have " + str(sums[i]));
    return out;
}

OssFile::MeshView OssFile::mesh(uint32_t i) const {
    if (i >= meshCount()) throw std::out_of_range("OssFile::mesh: " + str(i) + " >= mesh count " + str(meshCount()));
    const MeshRecord& r = sectionData<MeshRecord>(SectionId::meshes)[i];
    MeshView m;
    m.positions = {sectionData<glm::vec3>(SectionId::positions) + r.vertex_first, r.vertex_count};
    m.ecol = {sectionData<int32_t>(SectionId::ecol) + r.vertex_first, r.vertex_count};
    m.error = {sectionData<float>(SectionId::error) + r.vertex_first, r.vertex_count};
    m.triangles = {sectionData<uint32_t>(SectionId::triangles) + r.triangle_first * 3, size_t(r.triangle_count) * 3};
    m.map = {sectionData<uint32_t>(SectionId::map) + r.map_first, size_t(r.vertex_count) + 1};
    m.colours = {sectionData<uint32_t>(SectionId::colours) + r.vertex_first, r.vertex_count};
    m.normals = {sectionData<uint32_t>(SectionId::normals) + r.vertex_first, r.vertex_count};
    m.q = r.q;
    m.refused_faces = r.refused_faces;
    m.source_vertices = r.source_vertices;
    m.dropped_triangles = r.dropped_triangles;
    return m;
}

std::span<const ObjectDisk> OssFile::objects() const {
    return {sectionData<ObjectDisk>(SectionId::objects), objectCount()};
}

ObjectRecord OssFile::object(uint32_t i) const {
    if (i >= objectCount())
        throw std::out_of_range("OssFile::object: " + str(i) + " >= object count " + str(objectCount()));
    return fromDisk(objects()[i]);
}

std::span<const MeshRecord> OssFile::meshRecords() const {
    return {sectionData<MeshRecord>(SectionId::meshes), meshCount()};
}
std::span<const glm::vec3> OssFile::allPositions() const {
    return {sectionData<glm::vec3>(SectionId::positions), size_t(vertexCount())};
}
std::span<const int32_t> OssFile::allEcol() const {
    return {sectionData<int32_t>(SectionId::ecol), size_t(vertexCount())};
}
std::span<const uint32_t> OssFile::allTriangles() const {
    return {sectionData<uint32_t>(SectionId::triangles), size_t(triangleCount()) * 3};
}
std::span<const uint32_t> OssFile::allMaps() const {
    return {sectionData<uint32_t>(SectionId::map), size_t(vertexCount() + meshCount())};
}

std::span<const uint32_t> OssFile::allColours() const {
    return {sectionData<uint32_t>(SectionId::colours), size_t(vertexCount())};
}

std::span<const uint32_t> OssFile::allNormals() const {
    return {sectionData<uint32_t>(SectionId::normals), size_t(vertexCount())};
}

std::span<const uint32_t> OssFile::cos() const { return {sectionData<uint32_t>(SectionId::cos), header().cos_count}; }

OssFile::HlodCounts OssFile::hlodCounts() const {
    HlodCounts c;
    std::vector<uint8_t> seen(meshCount(), 0);
    for (const Node& n : nodes()) {
        if (n.child_count == 0) continue;
        ++c.inner;
        if (seen[n.mesh]) continue;
        seen[n.mesh] = 1;
        ++c.meshes;
        c.triangles += meshRecords()[n.mesh].triangle_count;
    }
    return c;
}

std::span<const std::byte> OssFile::sectionBytes(uint32_t id) const {
    if (id < 1 || id > kSectionCount) throw std::out_of_range("OssFile::sectionBytes: no section " + std::to_string(id));
    const SectionEntry& e = header().sections[id - 1];
    return {base_ + e.offset, size_t(e.size)};
}

std::vector<OssFile::SectionInfo> OssFile::sections() const {
    std::vector<SectionInfo> out;
    out.push_back({"HEADER", 0, sizeof(Header), 1});
    for (uint32_t i = 0; i < kSectionCount; ++i) {
        const SectionEntry& e = header().sections[i];
        out.push_back({kKinds[i].name, e.offset, e.size, e.size / e.element_size});
    }
    return out;
}

void OssFile::verifyLodPrefix() const {
    tbb::enumerable_thread_specific<LodPrefixScratch> scratch;
    const uint64_t map_at = header().sections[uint32_t(SectionId::map) - 1].offset;
    const std::optional<Failure> failure = lowestFailure(meshCount(), [&](uint32_t i) -> std::optional<Failure> {
        const MeshView m = mesh(i);
        const std::optional<LodPrefixViolation> v =
            checkLodPrefix(m.vertexCount(), m.ecol, m.triangles, m.map, m.q, scratch.local());
        if (!v) return std::nullopt;
        const uint64_t map_first = sectionData<MeshRecord>(SectionId::meshes)[i].map_first;
        return Failure{"MAP", map_at + (map_first + v->k) * 4,
                       "mesh " + str(i) + ": LOD prefix broken at k = " + str(v->k) + ": " + v->what};
    });
    if (failure) raise(path_, *failure);
}

ProgressiveMesh OssFile::progressiveMesh(uint32_t i) const {
    const MeshView v = mesh(i);
    ProgressiveMesh m;
    m.positions.assign(v.positions.begin(), v.positions.end());
    m.ecol.assign(v.ecol.begin(), v.ecol.end());
    m.error.assign(v.error.begin(), v.error.end());
    m.triangles.assign(v.triangles.begin(), v.triangles.end());
    m.map.assign(v.map.begin(), v.map.end());
    // All white reads back as none of its own, as it was written.
    if (std::any_of(v.colours.begin(), v.colours.end(), [](uint32_t c) { return c != kWhite; }))
        m.colours.assign(v.colours.begin(), v.colours.end());
    if (std::any_of(v.normals.begin(), v.normals.end(), [](uint32_t n) { return n != kNoNormal; }))
        m.normals.assign(v.normals.begin(), v.normals.end());
    m.q = v.q;
    m.refused_faces = v.refused_faces;
    m.source_vertices = v.source_vertices;
    m.dropped_triangles = v.dropped_triangles;
    return m;
}

PreparedScene OssFile::toPreparedScene() const {
    PreparedScene scene;
    scene.ct = ct();
    scene.meshes.reserve(meshCount());
    for (uint32_t i = 0; i < meshCount(); ++i) scene.meshes.push_back(progressiveMesh(i));
    scene.objects.reserve(objectCount());
    for (const ObjectDisk& d : objects()) scene.objects.push_back(fromDisk(d));
    const std::span<const uint32_t> c = cos();
    scene.cos.assign(c.begin(), c.end());
    scene.nodes.reserve(nodeCount());
    for (const Node& d : nodes()) scene.nodes.push_back(fromNode(d));
    return scene;
}

}  // namespace occ
