// SPDX-License-Identifier: MIT
#include "device_memory.h"

#include "device_test_support.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <fstream>
#include <numeric>
#include <sstream>
#include <string>
#include <vector>

namespace occ::k {
namespace {

using Bus = test::DeviceTest;
using DeviceArrays = test::DeviceTest;

// The bus counts exactly the bytes it moves between host and device, since the experiments
// report host <-> device traffic from these counters (BusCounters, device_memory.h).
TEST_F(Bus, CopiesCountTheirBytesInTheirDirection) {
    constexpr size_t n = 1000;  // 4000 bytes of uint32_t
    std::vector<uint32_t> host(n);
    std::iota(host.begin(), host.end(), 0u);
    DeviceArray<uint32_t> device(n);

    const BusCounters start = busCounters();
    copyToDevice(device.ptr(), host.data(), n);
    const BusCounters uploaded = busCounters();
    EXPECT_EQ(uploaded.h2d_bytes - start.h2d_bytes, n * sizeof(uint32_t));
    EXPECT_EQ(uploaded.h2d_copies - start.h2d_copies, 1u);
    EXPECT_EQ(uploaded.d2h_bytes, start.d2h_bytes);
    EXPECT_EQ(uploaded.d2h_copies, start.d2h_copies);

    std::vector<uint32_t> back(n);
    copyToHost(back.data(), DevicePtr<const uint32_t>(device.ptr()), n);
    const BusCounters downloaded = busCounters();
    EXPECT_EQ(downloaded.d2h_bytes - uploaded.d2h_bytes, n * sizeof(uint32_t));
    EXPECT_EQ(downloaded.d2h_copies - uploaded.d2h_copies, 1u);
    EXPECT_EQ(downloaded.h2d_bytes, uploaded.h2d_bytes);
    EXPECT_EQ(back, host);
}

TEST_F(Bus, ReadBackCountsOneElement) {
    const DeviceArray<uint64_t> device = test::toDevice(std::vector<uint64_t>{7, 8, 9});
    const BusCounters start = busCounters();
    EXPECT_EQ(readBack(device.ptr() + 2), 9u);
    EXPECT_EQ(busCounters().d2h_bytes - start.d2h_bytes, sizeof(uint64_t));
    EXPECT_EQ(busCounters().d2h_copies - start.d2h_copies, 1u);
}

TEST_F(Bus, DeviceToDeviceCopiesDoNotCrossTheBus) {
    constexpr size_t n = 513;
    const DeviceArray<uint8_t> from = test::filledDevice<uint8_t>(n, 0x5a);
    DeviceArray<uint8_t> to(n);
    const BusCounters start = busCounters();
    copyOnDevice(to.ptr(), from.ptr(), n);
    deviceToDevice(DevicePtr<void>(to.ptr()), DevicePtr<const void>(from.ptr()), n);
    deviceMemset(DevicePtr<void>(to.ptr()), 0x33, n);
    const BusCounters after = busCounters();
    EXPECT_EQ(after.h2d_bytes, start.h2d_bytes);
    EXPECT_EQ(after.d2h_bytes, start.d2h_bytes);
    EXPECT_EQ(after.h2d_copies, start.h2d_copies);
    EXPECT_EQ(after.d2h_copies, start.d2h_copies);
    EXPECT_EQ(after.d2d_bytes - start.d2d_bytes, 2 * n);  // the memset is no copy
    EXPECT_EQ(test::toHost(to), std::vector<uint8_t>(n, 0x33));
}

TEST_F(Bus, ZeroBytesCopyNothingAndCountNothing) {
    DeviceArray<uint32_t> device(1);
    const BusCounters start = busCounters();
    copyToDevice(device.ptr(), static_cast<const uint32_t*>(nullptr), 0);
    copyToHost(static_cast<uint32_t*>(nullptr), DevicePtr<const uint32_t>(device.ptr()), 0);
    const BusCounters after = busCounters();
    EXPECT_EQ(after.h2d_copies, start.h2d_copies);
    EXPECT_EQ(after.d2h_copies, start.d2h_copies);
    EXPECT_EQ(after.h2d_bytes, start.h2d_bytes);
}

TEST_F(DeviceArrays, ResizeKeepKeepsTheContentsOnTheDevice) {
    DeviceArray<uint32_t> a = test::toDevice(std::vector<uint32_t>{1, 2, 3});
    const BusCounters start = busCounters();
    a.resizeKeep(1000);
    EXPECT_EQ(busCounters().h2d_bytes, start.h2d_bytes) << "growing moves nothing over the bus";
    EXPECT_EQ(busCounters().d2h_bytes, start.d2h_bytes);
    EXPECT_EQ(busCounters().d2d_bytes - start.d2d_bytes, 3 * sizeof(uint32_t));
    EXPECT_EQ(a.size(), 1000u);
    EXPECT_EQ(test::toHost(a, 3), (std::vector<uint32_t>{1, 2, 3}));
}

TEST_F(DeviceArrays, CapacityNeverShrinks) {
    DeviceArray<float> a(100);
    const DevicePtr<float> before = a.ptr();
    a.resize(10);
    EXPECT_EQ(a.size(), 10u);
    EXPECT_EQ(a.capacity(), 100u);
    EXPECT_TRUE(a.ptr() == before) << "shrinking reallocates nothing";
    a.resize(100);
    EXPECT_TRUE(a.ptr() == before);
}

// Issue 35: the device algorithms' temporary storage comes from a cache made once: a block handed
// back is lent again to a request of its size class (or one up to half the size) without a new
// deviceAlloc, blocks lent at once are distinct, and releaseTemporaries frees only what is not
// lent.
TEST_F(DeviceArrays, TemporariesAreLentAgainFromTheCache) {
    releaseTemporaries();  // what earlier tests handed back
    const DeviceAllocationCounters start = deviceAllocationCounters();
    void* const a = temporaryAlloc(3'000'013);
    void* const b = temporaryAlloc(3'000'013);
    EXPECT_NE(a, b);
    EXPECT_EQ(deviceAllocationCounters().allocations - start.allocations, 2u);
    EXPECT_GE(deviceAllocationCounters().temporary_cached_bytes - start.temporary_cached_bytes, 2 * 3'000'013u);
    temporaryFree(a);
    void* const again = temporaryAlloc(2'000'000);  // a smaller request takes the free block
    EXPECT_EQ(again, a);
    EXPECT_EQ(deviceAllocationCounters().allocations - start.allocations, 2u);
    void* const small = temporaryAlloc(1000);  // far smaller: a block of its own size
    EXPECT_EQ(deviceAllocationCounters().allocations - start.allocations, 3u);
    EXPECT_EQ(deviceAllocationCounters().temporary_requests - start.temporary_requests, 4u);
    temporaryFree(small);
    temporaryFree(b);
    const DeviceAllocationCounters before_release = deviceAllocationCounters();
    EXPECT_GE(releaseTemporaries(), 3'000'013u + 1000u);
    EXPECT_EQ(deviceAllocationCounters().frees - before_release.frees, 2u) << "the lent block stays";
    temporaryFree(again);
    EXPECT_GE(releaseTemporaries(), 3'000'013u);
    temporaryFree(nullptr);
}

// The CPU build's large device arrays ask for transparent huge pages: on a virtual machine a
// first write into fresh memory costs one fault per 4 KiB page (16 MiB took 60-70 ms here),
// and the active arrays are first written in the frame loop, as a walk's resident set grows.
// Checked where it can be seen: the kernel's smaps entry for the array's mapping says whether
// it may be backed by huge pages (THPeligible); where THP is off entirely, nothing to check.
TEST_F(DeviceArrays, LargeArraysMayBeBackedByHugePagesInTheCpuBuild) {
    if (std::string(deviceBackend()) != "cpu-tbb") GTEST_SKIP() << "GPU memory: the CUDA allocator's pages";
    std::ifstream mode_file("/sys/kernel/mm/transparent_hugepage/enabled");
    std::string mode;
    std::getline(mode_file, mode);
    if (mode.empty() || mode.find("[never]") != std::string::npos) GTEST_SKIP() << "THP off on this machine: " << mode;
    void* const block = temporaryAlloc(6u << 20);  // deviceAlloc's memory, as every array's
    const auto at = reinterpret_cast<uintptr_t>(block);
    EXPECT_EQ(at % (2u << 20), 0u) << "aligned to a huge page";
    std::ifstream smaps("/proc/self/smaps");
    std::string line;
    bool inside = false, found = false;
    while (std::getline(smaps, line)) {
        unsigned long lo = 0, hi = 0;
        char dash = 0;
        std::istringstream head(line);
        if (line.find(':') > line.find(' ') && (head >> std::hex >> lo >> dash >> hi) && dash == '-') {
            inside = lo <= at && at < hi;
            continue;
        }
        if (inside && line.rfind("THPeligible:", 0) == 0) {
            found = true;
            EXPECT_NE(line.find('1'), std::string::npos) << line << " (THP mode " << mode << ")";
        }
    }
    EXPECT_TRUE(found) << "no smaps entry with THPeligible for the array at 0x" << std::hex << at;
    temporaryFree(block);
}

}  // namespace
}  // namespace occ::k
