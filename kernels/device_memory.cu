// SPDX-License-Identifier: MIT
#include "device_access.h"
#include "scene/errors.h"
#include "util/number_format.h"

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <cstring>
#include <map>
#include <mutex>
#include <new>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#if !defined(__CUDACC__)
#include <sys/mman.h>
#endif

#if defined(__CUDACC__)
#include <cuda_gl_interop.h>
#include <cuda_runtime.h>
#include <thrust/system/detail/bad_alloc.h>
#include <thrust/system_error.h>

// Every CUDA runtime call goes through this: a failure becomes one SystemError naming the call,
// where it was made and CUDA's own words (e.g. "no CUDA-capable device is detected").
#define OCC_CUDA_CHECK(call)                                                                              \
    do {                                                                                                  \
        const cudaError_t occ_cuda_status = (call);                                                       \
        if (occ_cuda_status != cudaSuccess)                                                               \
            throw occ::SystemError(std::string("CUDA: ") + #call + " failed at " + __FILE__ + ":" +        \
                                   std::to_string(__LINE__) + ": " + cudaGetErrorString(occ_cuda_status)); \
    } while (0)
#endif

namespace occ::k {

namespace {

thread_local BusCounters t_frame_bus, t_measurement_bus;
thread_local int t_measuring = 0;

BusCounters& bus() { return t_measuring ? t_measurement_bus : t_frame_bus; }

void countToDevice(size_t bytes) {
    bus().h2d_bytes += bytes;
    ++bus().h2d_copies;
}

void countToHost(size_t bytes) {
    bus().d2h_bytes += bytes;
    ++bus().d2h_copies;
}

}  // namespace

const BusCounters& busCounters() { return t_frame_bus; }
const BusCounters& measurementBusCounters() { return t_measurement_bus; }
BusMeasurementScope::BusMeasurementScope() { ++t_measuring; }
BusMeasurementScope::~BusMeasurementScope() { --t_measuring; }

void countReadback(size_t bytes) { countToHost(bytes); }

namespace {

#if defined(__CUDACC__)
int nodeLocalRank() {
    for (const char* name : {"OMPI_COMM_WORLD_LOCAL_RANK", "MPI_LOCALRANKID", "SLURM_LOCALID"})
        if (const char* v = std::getenv(name)) {
            char* end = nullptr;
            const long rank = std::strtol(v, &end, 10);
            if (end != v && *end == '\0' && rank >= 0 && rank < (1 << 20)) return int(rank);
        }
    return 0;
}

#endif

bool g_selected = false;
int g_requested = -1;
DeviceInfo g_device;

std::string cudaVersion(int v) { return std::to_string(v / 1000) + "." + std::to_string(v % 1000 / 10); }

// OCC_DEVICE_ALLOC_FAIL_AT (deviceAlloc's contract): the call, from 0, that fails; -1: none.
long injectedAllocFailure() {
    static const long at = [] {
        const char* v = std::getenv("OCC_DEVICE_ALLOC_FAIL_AT");
        if (!v || !*v) return -1L;
        char* end = nullptr;
        const long n = std::strtol(v, &end, 10);
        return end != v && *end == '\0' && n >= 0 ? n : -1L;
    }();
    return at;
}
// OCC_DEVICE_MEMORY_BYTES (requireDeviceMemory's contract): the most the device holds.
uint64_t injectedDeviceBytes() {
    static const uint64_t most = [] {
        const char* v = std::getenv("OCC_DEVICE_MEMORY_BYTES");
        if (!v || !*v) return ~uint64_t(0);
        char* end = nullptr;
        const unsigned long long n = std::strtoull(v, &end, 10);
        return end != v && *end == '\0' ? uint64_t(n) : ~uint64_t(0);
    }();
    return most;
}
std::atomic<uint64_t> g_allocations{0}, g_frees{0}, g_temporary_requests{0};

// What deviceAlloc lent, by block, for the live and peak byte counts.
struct LiveBlocks {
    std::mutex mutex;
    std::unordered_map<void*, size_t> bytes;
    uint64_t live = 0, peak = 0;
};
LiveBlocks& liveBlocks() {
    static auto* blocks = new LiveBlocks;  // never destroyed: frees may come during exit
    return *blocks;
}
void* counted(void* p, size_t bytes) {
    LiveBlocks& l = liveBlocks();
    const std::lock_guard<std::mutex> lock(l.mutex);
    l.bytes[p] = bytes;
    l.live += bytes;
    l.peak = std::max(l.peak, l.live);
    return p;
}
void uncount(void* p) {
    ++g_frees;
    LiveBlocks& l = liveBlocks();
    const std::lock_guard<std::mutex> lock(l.mutex);
    if (const auto it = l.bytes.find(p); it != l.bytes.end()) {
        l.live -= it->second;
        l.bytes.erase(it);
    }
}
// What is free under OCC_DEVICE_MEMORY_BYTES: its bytes less those allocated; all of
// `free_bytes` without it.
uint64_t availableBytes(uint64_t free_bytes) {
    const uint64_t most = injectedDeviceBytes();
    if (most == ~uint64_t(0)) return free_bytes;
    LiveBlocks& l = liveBlocks();
    const std::lock_guard<std::mutex> lock(l.mutex);
    return std::min(free_bytes, most > l.live ? most - l.live : 0);
}
// Counts a deviceAlloc call; whether it must fail as if the device were full (the tests'
// OCC_DEVICE_ALLOC_FAIL_AT and OCC_DEVICE_MEMORY_BYTES).
bool allocFailsNow(size_t bytes) {
    const long at = injectedAllocFailure();
    return g_allocations.fetch_add(1) == uint64_t(at) || availableBytes(~uint64_t(0)) < bytes;
}

}  // namespace

std::string driverTooOldText(int driver_version, int runtime_version) {
    return "CUDA: the NVIDIA driver supports CUDA up to " + cudaVersion(driver_version) +
           "; occswitch-cuda carries the CUDA " + cudaVersion(runtime_version) +
           " runtime, which needs a newer driver: update the driver (or build occswitch-cuda with the CUDA the driver "
           "supports)";
}

std::string noKernelImageText(int ordinal, const std::string& name, int major, int minor, const std::string& built) {
    return "CUDA device " + std::to_string(ordinal) + " (" + name + ", compute capability " + std::to_string(major) +
           "." + std::to_string(minor) + ") has no kernels in this build (built for " + (built.empty() ? "none" : built) +
           "): rebuild with OCC_CUDA_ARCHITECTURES=" + std::to_string(major) + std::to_string(minor) +
           " (launch/setup reads it; cmake -DOCC_CUDA_ARCHITECTURES=" + std::to_string(major) + std::to_string(minor) + ")";
}

std::string deviceOutOfMemoryText(const DeviceInfo& d, uint64_t bytes, uint64_t bytes_free, uint64_t bytes_total) {
    std::string device = d.ordinal >= 0 ? "CUDA device " + std::to_string(d.ordinal) + " (" + d.name : d.name;
    if (d.ordinal >= 0) {
        if (bytes_total) device += ", " + mebibytes(bytes_total) + ", " + mebibytes(bytes_free) + " free";
        device += ")";
    }
    return "out of device memory: " + device + " could not allocate " +
           (bytes ? mebibytes(bytes) : std::string("a device algorithm's temporary storage")) +
           " (a smaller --budget, a smaller scene, or a device with more memory)";
}

namespace {
std::string tooSmallText(const DeviceInfo& d, uint64_t total, uint64_t free_bytes, uint64_t bytes, const std::string& what,
                         const std::string& detail) {
    const std::string device = d.ordinal >= 0 ? "CUDA device " + std::to_string(d.ordinal) + " (" + d.name + ", " +
                                                    mebibytes(total) + ")"
                                              : d.name;
    return device + " has " + mebibytes(free_bytes) + " free; " + mebibytes(bytes) + " needed for " + what +
           (detail.empty() ? "" : " (" + detail + ")") + ": a smaller --budget, a smaller scene, or a device with more memory";
}
}  // namespace

GlDeviceChoice chooseGlContextDevice(int requested, const DeviceInfo& current, const std::vector<int>& gl_devices,
                                     const std::string& gl_name, const std::string& why_none) {
    GlDeviceChoice c;
    if (gl_devices.empty()) {
        c.error = "CUDA: the window's OpenGL context is on no GPU CUDA can use (" + why_none +
                  "): CUDA-OpenGL interop needs the NVIDIA GPU's X screen; or render --headless or --no-display";
        return c;
    }
    for (const int g : gl_devices)
        if (g == current.ordinal) return c;
    const std::string gl = std::to_string(gl_devices[0]);
    if (requested >= 0)
        c.error = "--device " + std::to_string(requested) + " is CUDA device " + std::to_string(current.ordinal) + " (" +
                  current.name + "), but the window's OpenGL context is on CUDA device " + gl + " (" + gl_name +
                  "): CUDA-OpenGL interop needs both on one GPU: give --device " + gl + " or open the window on GPU " +
                  std::to_string(current.ordinal) + "'s X screen";
    else
        c.select = gl_devices[0];
    return c;
}

const char* builtArchitectures() {
#if defined(OCC_CUDA_ARCHITECTURES_TEXT)
    return OCC_CUDA_ARCHITECTURES_TEXT;
#else
    return "";
#endif
}

const DeviceInfo& currentDevice() {
    if (!g_selected) selectDevice(-1);
    return g_device;
}

#if defined(__CUDACC__)

namespace {
__global__ void occProbeKernel() {}

// The device's free and total memory, 0 and 0 where CUDA cannot say (for an error's text).
std::pair<uint64_t, uint64_t> memoryNow() {
    size_t bytes_free = 0, total = 0;
    if (cudaMemGetInfo(&bytes_free, &total) != cudaSuccess) cudaGetLastError(), bytes_free = total = 0;
    return {bytes_free, total};
}
}  // namespace

void* deviceAlloc(size_t bytes) {
    void* p = nullptr;
    const cudaError_t status =
        allocFailsNow(bytes) ? cudaErrorMemoryAllocation : cudaMalloc(&p, bytes ? bytes : 1);
    if (status == cudaErrorMemoryAllocation) {
        cudaGetLastError();  // clears the sticky error so that later calls work
        const auto [bytes_free, total] = memoryNow();
        throw DeviceOutOfMemory(deviceOutOfMemoryText(currentDevice(), bytes, bytes_free, total));
    }
    OCC_CUDA_CHECK(status);
    return counted(p, bytes);
}
void deviceFree(void* p) {
    if (!p) return;
    uncount(p);
    cudaFree(p);  // in destructors: a failure here has nowhere to go
}
void* pinnedAlloc(size_t bytes) {
    void* p = nullptr;
    const cudaError_t status = cudaMallocHost(&p, bytes ? bytes : 1);
    if (status == cudaErrorMemoryAllocation) {
        cudaGetLastError();
        throw std::bad_alloc();
    }
    OCC_CUDA_CHECK(status);
    return p;
}
void pinnedFree(void* p) {
    if (p) cudaFreeHost(p);
}
void deviceSynchronize() { OCC_CUDA_CHECK(cudaDeviceSynchronize()); }
const char* deviceBackend() { return "cuda"; }
std::string deviceErrorText(const std::exception& e) {
    if (const auto* thrust_error = dynamic_cast<const thrust::system_error*>(&e))
        return std::string("CUDA: ") + thrust_error->what();
    // Thrust's own allocator (a device algorithm's temporary storage) when the device is full.
    if (dynamic_cast<const thrust::system::detail::bad_alloc*>(&e)) {
        const auto [bytes_free, total] = memoryNow();
        return deviceOutOfMemoryText(currentDevice(), 0, bytes_free, total);
    }
    return "";
}

DeviceInfo selectDevice(int requested) {
    if (g_selected && requested == g_requested) return g_device;
    // A driver older than the runtime this build carries makes every CUDA call fail as if there
    // were no device; said apart, since there is a GPU to run on.
    int driver = 0;
    if (cudaDriverGetVersion(&driver) != cudaSuccess) cudaGetLastError(), driver = 0;
    if (driver > 0 && driver < CUDART_VERSION) throw occ::SystemError(driverTooOldText(driver, CUDART_VERSION));
    int count = 0;
    const cudaError_t status = cudaGetDeviceCount(&count);
    if (status != cudaSuccess || count == 0) {
        cudaGetLastError();
        throw occ::SystemError(std::string("CUDA: no usable CUDA device (") +
                               (status != cudaSuccess ? cudaGetErrorString(status) : "none found") +
                               "); occswitch-cuda needs an NVIDIA GPU and its driver, occswitch runs on the CPU");
    }
    if (requested >= count)
        throw occ::OptionError("device", std::to_string(requested) + ": this machine has " + std::to_string(count) +
                              " CUDA device" + (count > 1 ? "s" : "") + " (0 to " + std::to_string(count - 1) + ")");
    const int ordinal = requested >= 0 ? requested : nodeLocalRank() % count;
    OCC_CUDA_CHECK(cudaSetDevice(ordinal));
    cudaDeviceProp prop{};
    OCC_CUDA_CHECK(cudaGetDeviceProperties(&prop, ordinal));
    DeviceInfo d;
    d.ordinal = ordinal;
    d.name = prop.name;
    d.total_bytes = prop.totalGlobalMem;
    static const char* hex = "0123456789abcdef";
    for (int i = 0; i < 16; ++i) {
        const auto b = static_cast<unsigned char>(prop.uuid.bytes[i]);
        d.uuid += hex[b >> 4];
        d.uuid += hex[b & 15];
    }
    d.major = prop.major;
    d.minor = prop.minor;
    d.driver_version = driver;
    d.runtime_version = CUDART_VERSION;
    // A GPU whose architecture this build has no code for fails every kernel launch with "no
    // kernel image is available": said once, here, with what to rebuild for.
    occProbeKernel<<<1, 1>>>();
    const cudaError_t probe = cudaGetLastError();
    if (probe == cudaErrorNoKernelImageForDevice || probe == cudaErrorInvalidDeviceFunction)
        throw occ::SystemError(noKernelImageText(ordinal, d.name, d.major, d.minor, builtArchitectures()));
    OCC_CUDA_CHECK(probe);
    OCC_CUDA_CHECK(cudaDeviceSynchronize());
    g_device = d;
    g_requested = requested;
    g_selected = true;
    return d;
}

void matchGlContextDevice(int requested) {
    const DeviceInfo& d = currentDevice();
    unsigned int count = 0;
    int devices[16] = {};
    const cudaError_t status = cudaGLGetDevices(&count, devices, 16, cudaGLDeviceListAll);
    std::string why_none, gl_name = "?";
    if (status != cudaSuccess || count == 0) {
        why_none = status != cudaSuccess ? cudaGetErrorString(status) : "none listed";
        cudaGetLastError();
        count = 0;
    } else {
        cudaDeviceProp prop{};
        if (cudaGetDeviceProperties(&prop, devices[0]) == cudaSuccess) gl_name = prop.name;
    }
    const GlDeviceChoice choice = chooseGlContextDevice(requested, d, std::vector<int>(devices, devices + count), gl_name, why_none);
    if (!choice.error.empty()) throw occ::SystemError(choice.error);
    if (choice.select >= 0) selectDevice(choice.select);  // the context's GPU: nothing is on the device yet
}

void requireDeviceMemory(uint64_t bytes, const std::string& what, const std::string& detail) {
    const DeviceInfo& d = currentDevice();
    size_t free_bytes = 0, total = 0;
    OCC_CUDA_CHECK(cudaMemGetInfo(&free_bytes, &total));
    const uint64_t available = availableBytes(free_bytes);
    if (bytes > available) throw occ::SystemError(tooSmallText(d, total, available, bytes, what, detail));
}
uint64_t kernelLocalMemoryBytes() {
    size_t stack = 0;
    OCC_CUDA_CHECK(cudaDeviceGetLimit(&stack, cudaLimitStackSize));
    cudaDeviceProp prop{};
    OCC_CUDA_CHECK(cudaGetDeviceProperties(&prop, currentDevice().ordinal));
    return uint64_t(stack) * uint64_t(prop.multiProcessorCount) * uint64_t(prop.maxThreadsPerMultiProcessor);
}
bool deviceAvailable(std::string* why) {
    int count = 0;
    const cudaError_t status = cudaGetDeviceCount(&count);
    if (status != cudaSuccess || count == 0) {
        if (why) *why = status != cudaSuccess ? cudaGetErrorString(status) : "no CUDA device";
        cudaGetLastError();
        return false;
    }
    return true;
}

void busToDevice(DevicePtr<void> dst, const void* src, size_t bytes) {
    if (bytes == 0) return;
    OCC_CUDA_CHECK(cudaMemcpy(raw(dst), src, bytes, cudaMemcpyHostToDevice));
    countToDevice(bytes);
}
void busToHost(void* dst, DevicePtr<const void> src, size_t bytes) {
    if (bytes == 0) return;
    OCC_CUDA_CHECK(cudaMemcpy(dst, raw(src), bytes, cudaMemcpyDeviceToHost));
    countToHost(bytes);
}
void deviceToDevice(DevicePtr<void> dst, DevicePtr<const void> src, size_t bytes) {
    if (bytes == 0) return;
    OCC_CUDA_CHECK(cudaMemcpy(raw(dst), raw(src), bytes, cudaMemcpyDeviceToDevice));
    bus().d2d_bytes += bytes;
}
void deviceMemset(DevicePtr<void> dst, int value, size_t bytes) {
    if (bytes == 0) return;
    OCC_CUDA_CHECK(cudaMemset(raw(dst), value, bytes));
}

GlBufferView::GlBufferView(uint32_t gl_buffer, void*) {
    cudaGraphicsResource_t resource = nullptr;
    const cudaError_t status = cudaGraphicsGLRegisterBuffer(&resource, gl_buffer, cudaGraphicsRegisterFlagsNone);
    if (status != cudaSuccess) {
        cudaGetLastError();
        throw occ::SystemError(std::string("CUDA: cannot register OpenGL buffer ") + std::to_string(gl_buffer) +
                               " for interop (is the GL context on this CUDA device?): " +
                               cudaGetErrorString(status));
    }
    resource_ = resource;
}
GlBufferView::~GlBufferView() {
    auto resource = static_cast<cudaGraphicsResource_t>(resource_);
    if (mapped_) cudaGraphicsUnmapResources(1, &resource, 0);
    cudaGraphicsUnregisterResource(resource);
}
void GlBufferView::map() {
    if (mapped_) return;
    auto resource = static_cast<cudaGraphicsResource_t>(resource_);
    OCC_CUDA_CHECK(cudaGraphicsMapResources(1, &resource, 0));
    void* p = nullptr;
    size_t bytes = 0;
    OCC_CUDA_CHECK(cudaGraphicsResourceGetMappedPointer(&p, &bytes, resource));
    ptr_ = DeviceAccess::wrap(p);
    mapped_ = true;
}
void GlBufferView::unmap() {
    if (!mapped_) return;
    auto resource = static_cast<cudaGraphicsResource_t>(resource_);
    OCC_CUDA_CHECK(cudaGraphicsUnmapResources(1, &resource, 0));
    ptr_ = nullptr;
    mapped_ = false;
}
bool GlBufferView::usesInterop() { return true; }

#else

namespace {

constexpr size_t kHugePage = size_t(2) << 20;

void* alignedAlloc(size_t bytes) {
    const size_t need = bytes ? bytes : 1;
    if (need >= kHugePage) {
        // Large arrays (the active arrays, staging, the scene) on transparent huge pages where the
        // kernel allows them: their first writes, which come in the frame loop as the arrays
        // fill up, then fault 2 MiB in at a time instead of 4 KiB. On a virtual machine a fault
        // costs microseconds: a compaction's 8 MB into fresh memory took 30-50 ms in 4 KiB faults.
        const size_t rounded = (need + kHugePage - 1) / kHugePage * kHugePage;
        void* p = std::aligned_alloc(kHugePage, rounded);
        if (!p) throw std::bad_alloc();
        madvise(p, rounded, MADV_HUGEPAGE);  // advice: ignored (an error we need not act on) without THP
        return p;
    }
    // 64-byte alignment: cache lines, and what the GPU's allocator gives too.
    void* p = std::aligned_alloc(64, (need + 63) / 64 * 64);
    if (!p) throw std::bad_alloc();
    return p;
}

}  // namespace

void* deviceAlloc(size_t bytes) {
    if (allocFailsNow(bytes)) throw DeviceOutOfMemory(deviceOutOfMemoryText(currentDevice(), bytes, 0, 0));
    return counted(alignedAlloc(bytes), bytes);
}
void deviceFree(void* p) {
    if (!p) return;
    uncount(p);
    std::free(p);
}
void* pinnedAlloc(size_t bytes) { return alignedAlloc(bytes); }
void pinnedFree(void* p) { std::free(p); }
void deviceSynchronize() {}
const char* deviceBackend() { return "cpu-tbb"; }
std::string deviceErrorText(const std::exception&) { return ""; }

DeviceInfo selectDevice(int requested) {
    if (requested > 0)
        throw occ::OptionError("device", std::to_string(requested) +
                                              ": this build runs its kernels on the CPU, device 0 (occswitch-cuda uses GPUs)");
    g_device = DeviceInfo{-1, "CPU (host memory, TBB)", "", 0};
    g_requested = requested;
    g_selected = true;
    return g_device;
}

void requireDeviceMemory(uint64_t bytes, const std::string& what, const std::string& detail) {
    const uint64_t available = availableBytes(~uint64_t(0));  // host memory: only a test's limit applies
    if (bytes > available) throw occ::SystemError(tooSmallText(currentDevice(), 0, available, bytes, what, detail));
}
uint64_t kernelLocalMemoryBytes() { return 0; }
void matchGlContextDevice(int) {}
bool deviceAvailable(std::string*) { return true; }

void busToDevice(DevicePtr<void> dst, const void* src, size_t bytes) {
    if (bytes == 0) return;
    std::memcpy(raw(dst), src, bytes);
    countToDevice(bytes);
}
void busToHost(void* dst, DevicePtr<const void> src, size_t bytes) {
    if (bytes == 0) return;
    std::memcpy(dst, raw(src), bytes);
    countToHost(bytes);
}
void deviceToDevice(DevicePtr<void> dst, DevicePtr<const void> src, size_t bytes) {
    if (bytes == 0) return;
    std::memmove(raw(dst), raw(src), bytes);
    bus().d2d_bytes += bytes;
}
void deviceMemset(DevicePtr<void> dst, int value, size_t bytes) {
    if (bytes == 0) return;
    std::memset(raw(dst), value, bytes);
}

GlBufferView::GlBufferView(uint32_t, void* mapped) : ptr_(DeviceAccess::wrap(mapped)), mapped_(true) {}
GlBufferView::~GlBufferView() = default;
void GlBufferView::map() {}
void GlBufferView::unmap() {}
bool GlBufferView::usesInterop() { return false; }

#endif

namespace {

// The temporary-storage cache (temporaryAlloc's contract). Made on first use and never
// destroyed: its blocks may outlive the CUDA context at exit, when freeing them would fail.
struct TemporaryCache {
    std::mutex mutex;
    std::multimap<size_t, void*> free;      // size class -> block
    std::unordered_map<void*, size_t> lent;  // block -> size class
    uint64_t bytes = 0;                      // held, lent or free
};
TemporaryCache& temporaryCache() {
    static auto* cache = new TemporaryCache;
    return *cache;
}

// Sizes rounded up to a quarter of their power of two (at most a quarter more than asked),
// at least 256 bytes.
size_t sizeClass(size_t bytes) {
    if (bytes <= 256) return 256;
    size_t top = 256;
    while (bytes > 2 * top) top <<= 1;  // bytes in (top, 2 top]
    const size_t step = top / 4;
    return (bytes + step - 1) / step * step;
}

uint64_t releaseFreeLocked(TemporaryCache& c) {
    uint64_t released = 0;
    for (auto& [size, p] : c.free) {
        deviceFree(p);
        released += size;
    }
    c.free.clear();
    c.bytes -= released;
    return released;
}

}  // namespace

void* temporaryAlloc(size_t bytes) {
    ++g_temporary_requests;
    const size_t size = sizeClass(bytes);
    TemporaryCache& c = temporaryCache();
    const std::lock_guard<std::mutex> lock(c.mutex);
    // A free block of this class, or one class or two up (at most twice the size).
    if (auto it = c.free.lower_bound(size); it != c.free.end() && it->first <= 2 * size) {
        void* p = it->second;
        c.lent.emplace(p, it->first);
        c.free.erase(it);
        return p;
    }
    void* p = nullptr;
    try {
        p = deviceAlloc(size);
    } catch (const DeviceOutOfMemory&) {
        if (c.free.empty()) throw;
        releaseFreeLocked(c);
        p = deviceAlloc(size);
    }
    c.lent.emplace(p, size);
    c.bytes += size;
    return p;
}

void temporaryFree(void* p) {
    if (!p) return;
    TemporaryCache& c = temporaryCache();
    const std::lock_guard<std::mutex> lock(c.mutex);
    const auto it = c.lent.find(p);
    if (it == c.lent.end()) return;  // not the cache's: nothing to hand back
    c.free.emplace(it->second, p);
    c.lent.erase(it);
}

uint64_t releaseTemporaries() {
    TemporaryCache& c = temporaryCache();
    const std::lock_guard<std::mutex> lock(c.mutex);
    return releaseFreeLocked(c);
}

DeviceAllocationCounters deviceAllocationCounters() {
    DeviceAllocationCounters n;
    n.allocations = g_allocations;
    n.frees = g_frees;
    n.temporary_requests = g_temporary_requests;
    {
        TemporaryCache& c = temporaryCache();
        const std::lock_guard<std::mutex> lock(c.mutex);
        n.temporary_cached_bytes = c.bytes;
    }
    LiveBlocks& l = liveBlocks();
    const std::lock_guard<std::mutex> lock(l.mutex);
    n.live_bytes = l.live;
    n.peak_bytes = l.peak;
    return n;
}

void resetDevicePeak() {
    LiveBlocks& l = liveBlocks();
    const std::lock_guard<std::mutex> lock(l.mutex);
    l.peak = l.live;
}

bool deviceReadsHostMemory() {
#if defined(__CUDACC__)
    return false;
#else
    return true;
#endif
}

}  // namespace occ::k
