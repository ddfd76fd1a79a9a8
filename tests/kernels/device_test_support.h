// SPDX-License-Identifier: MIT
#pragma once

// What every kernel test shares: fixtures are built in std::vector on the host, uploaded over
// the bus, and the kernels' results downloaded again before anything is asserted on them, since
// host code cannot read device memory (device_memory.h). The same sources are built against the
// CPU kernels and the CUDA kernels; DeviceTest skips a test where the build's device cannot
// run kernels (the CUDA binary on a machine without a GPU).
#include "device_memory.h"
#include "kernel_types.h"
#include "scan.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace occ::k::test {

// A device copy of `v`. Room for one element is allocated even for an empty vector, so that
// ptr() is never null and a kernel given count 0 still gets a valid pointer; size() is v.size().
template <class T>
DeviceArray<T> toDevice(const std::vector<T>& v) {
    DeviceArray<T> a(std::max<size_t>(v.size(), 1));
    a.resize(v.size());  // capacity never shrinks: the one element stays allocated
    copyToDevice(a.ptr(), v.data(), v.size());
    return a;
}

// n copies of `value` on the device (e.g. a sentinel a kernel must overwrite, or must not).
template <class T>
DeviceArray<T> filledDevice(size_t n, const T& value) {
    return toDevice(std::vector<T>(n, value));
}

// The first n elements behind p, on the host.
template <class T>
std::vector<std::remove_const_t<T>> toHost(DevicePtr<T> p, size_t n) {
    std::vector<std::remove_const_t<T>> v(n);
    copyToHost(v.data(), DevicePtr<const std::remove_const_t<T>>(p), n);
    return v;
}
template <class T>
std::vector<T> toHost(const DeviceArray<T>& a, size_t n) {
    return toHost(a.ptr(), n);
}
template <class T>
std::vector<T> toHost(const DeviceArray<T>& a) {
    return toHost(a.ptr(), a.size());
}

// One frame's packed layout (scan.h) as streamCollect and streamObjectByObject read it, from
// the block vectors; the offsets are the kernels' exclusiveScan of the counts, downloaded.
struct LayoutPair {
    std::vector<uint32_t> objects, vertex_count, triangle_count;
    std::vector<uint64_t> vertex_offset, triangle_offset;
    uint64_t vertex_total = 0, triangle_total = 0;
    DeviceArray<uint32_t> device_vertex_count, device_triangle_count;
    DeviceArray<uint64_t> device_vertex_offset, device_triangle_offset;

    LayoutPair(std::vector<uint32_t> ids, std::vector<uint32_t> vc, std::vector<uint32_t> tc)
        : objects(std::move(ids)), vertex_count(std::move(vc)), triangle_count(std::move(tc)) {
        const uint32_t n = count();
        device_vertex_count = toDevice(vertex_count);
        device_triangle_count = toDevice(triangle_count);
        device_vertex_offset.resize(std::max<size_t>(n, 1));  // written by the scans
        device_triangle_offset.resize(std::max<size_t>(n, 1));
        vertex_total = exclusiveScan(device_vertex_count.ptr(), n, device_vertex_offset.ptr());
        triangle_total = exclusiveScan(device_triangle_count.ptr(), n, device_triangle_offset.ptr());
        vertex_offset = toHost(device_vertex_offset, n);
        triangle_offset = toHost(device_triangle_offset, n);
    }

    uint32_t count() const { return uint32_t(objects.size()); }
    HostLayout host() const {
        return {objects.data(),         vertex_count.data(), triangle_count.data(), vertex_offset.data(),
                triangle_offset.data(), count(),             vertex_total,          triangle_total};
    }
    // Rewrites the ids (for a test that breaks a layout on purpose).
    void setObjects(std::vector<uint32_t> ids) { objects = std::move(ids); }
};

// Why this build's device cannot run kernels here, or empty when it can (the CPU build always
// can). Asked once per process.
// An object that is only a box (what the culling kernels look at).
inline ObjectInfo boxObject(const glm::vec3& lo, const glm::vec3& hi) {
    ObjectInfo o{};
    o.aabb = {lo, hi};
    return o;
}

inline const std::string& deviceMissing() {
    static const std::string reason = [] {
        std::string why;
        if (deviceAvailable(&why)) return std::string();
        return std::string("the ") + deviceBackend() + " kernels need a device: " + (why.empty() ? "none found" : why);
    }();
    return reason;
}

// The fixture of every test that touches device memory: it skips the test, saying why, where
// the device cannot run kernels (the CUDA binary on a machine without a GPU), so that each test
// reports itself skipped rather than passed. A suite takes it by an alias of its own name
// (`using Scan = test::DeviceTest;`, then TEST_F(Scan, ...)). Tests of host-only code
// (frustumFromViewProj, sharedEdgeFlags, hzmLayout) stay plain TESTs and run everywhere.
class DeviceTest : public ::testing::Test {
protected:
    void SetUp() override {
        if (!deviceMissing().empty()) GTEST_SKIP() << deviceMissing();
    }
};

}  // namespace occ::k::test
