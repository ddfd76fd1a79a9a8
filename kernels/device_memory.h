// SPDX-License-Identifier: MIT
#pragma once

#include "scene/errors.h"

#include <atomic>
#include <cstddef>
#include <algorithm>
#include <cstdint>
#include <exception>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

// The three kinds of memory of a frame (docs/architecture.md, "Memory and the bus"), kept apart by type:
//   DeviceArray<T> / DevicePtr<T>  device memory the kernels work on: cudaMalloc under CUDA,
//                                  64-byte-aligned host memory in the CPU build, which stands for
//                                  it. Host code can hold, offset and pass a DevicePtr, but not
//                                  read or write through it: that takes device_access.h, which
//                                  only kernel sources include.
//   PinnedArray<T>                 host memory the bus copies from and to at full speed
//                                  (cudaMallocHost under CUDA), indexable by the host.
//   the mapped .oss                plain host memory, read by the host only.
// Every byte between host and device goes through the bus below, which counts it per calling
// thread, so the CPU build measures exactly what a GPU build would move.

namespace occ::k {

struct DeviceAccess;  // kernels/device_access.h: how kernel sources reach the memory
template <class T>
class DevicePtr;
// The pointer static_cast: typed views of untyped device memory (a BufferProvider's slots).
template <class T, class U>
DevicePtr<T> devicePtrCast(DevicePtr<U> p);
template <class T>
DevicePtr<const T> hostView(const T* p);

// A typed pointer into device memory. Null by default.
template <class T>
class DevicePtr {
public:
    DevicePtr() = default;
    DevicePtr(std::nullptr_t) {}
    template <class U, class = std::enable_if_t<std::is_convertible_v<U*, T*>>>
    DevicePtr(DevicePtr<U> other) : p_(other.p_) {}

    DevicePtr operator+(size_t i) const { return DevicePtr(p_ + i); }
    explicit operator bool() const { return p_ != nullptr; }
    friend bool operator==(DevicePtr a, DevicePtr b) { return a.p_ == b.p_; }

private:
    explicit DevicePtr(T* p) : p_(p) {}
    T* p_ = nullptr;
    template <class>
    friend class DevicePtr;
    template <class>
    friend class DeviceArray;
    friend struct DeviceAccess;
    template <class A, class B>
    friend DevicePtr<A> devicePtrCast(DevicePtr<B> p);
    template <class A>
    friend DevicePtr<const A> hostView(const A* p);
};

template <class T, class U>
DevicePtr<T> devicePtrCast(DevicePtr<U> p) {
    return DevicePtr<T>(static_cast<T*>(p.p_));
}

// Whether the device reads host memory in place (the CPU build: its device memory is host
// memory). Then hostView(p) is a device pointer to host data p, read without a copy (the mapped
// .oss, say); in a CUDA build it is null and the data must be copied up.
bool deviceReadsHostMemory();
template <class T>
DevicePtr<const T> hostView(const T* p) {
    return deviceReadsHostMemory() ? DevicePtr<const T>(p) : DevicePtr<const T>();
}

// Raw allocation of device memory (bytes may be 0). Never returns null: throws
// DeviceOutOfMemory (a SystemError naming the device, what it has and what was asked: exit 1,
// the machine's limit, not a bad input) when the device has no room, SystemError for any other
// CUDA failure. deviceFree(nullptr) is a no-op. For tests of that path on any machine,
// OCC_DEVICE_ALLOC_FAIL_AT=N makes the process's N-th deviceAlloc (from 0) fail as if the
// device were full.
void* deviceAlloc(size_t bytes);
class DeviceOutOfMemory : public occ::SystemError {
public:
    using occ::SystemError::SystemError;
};
void deviceFree(void* p);
// Every allocation of device memory goes through deviceAlloc and deviceFree; these count them,
// process-wide, for tests that a frame allocates nothing once the first is done (a cudaMalloc or
// cudaFree waits for the whole device). temporary_requests: the device algorithms' temporary
// storage (sorts, scans, compactions) asked of the cache below.
struct DeviceAllocationCounters {
    uint64_t allocations = 0;           // deviceAlloc calls (cudaMalloc)
    uint64_t frees = 0;                 // deviceFree calls of a non-null pointer (cudaFree)
    uint64_t temporary_requests = 0;    // temporaryAlloc calls
    uint64_t temporary_cached_bytes = 0;  // device memory the cache holds now, lent out or free
    uint64_t live_bytes = 0;              // allocated by deviceAlloc and not freed, now
    uint64_t peak_bytes = 0;              // the most live_bytes has been since resetDevicePeak
};
DeviceAllocationCounters deviceAllocationCounters();
void resetDevicePeak();
// The device algorithms' temporary storage: a cache made once per process. A request takes a
// free block of its size class (sizes rounded up to a quarter of their power of two, at least
// 256 bytes) or, failing that, a fresh deviceAlloc; temporaryFree hands the block back to the
// cache, not to the device. Blocks are only freed when the device runs out of memory (then the
// request is tried once more) or by releaseTemporaries. Thread-safe. Lending a block back while
// a kernel still uses it is safe: every kernel and copy runs on the one default stream, so the
// next user of the block is ordered after it.
void* temporaryAlloc(size_t bytes);
void temporaryFree(void* p);
// Frees the cache's blocks that are not lent out; returns their bytes.
uint64_t releaseTemporaries();
// Pinned host memory, the same contract.
void* pinnedAlloc(size_t bytes);
void pinnedFree(void* p);

// The device this process works on.
struct DeviceInfo {
    int ordinal = -1;          // CUDA device number; -1 in the CPU build
    std::string name;          // "NVIDIA H200", or "CPU (host memory, TBB)"
    std::string uuid;          // CUDA's device UUID as hex, empty in the CPU build
    uint64_t total_bytes = 0;  // device memory (0 in the CPU build: host memory)
    int major = 0, minor = 0;  // CUDA compute capability (0.0 in the CPU build)
    int driver_version = 0;    // CUDA version the driver supports, 1000 x major + 10 x minor (0: CPU)
    int runtime_version = 0;   // CUDA runtime this build carries, likewise (0: CPU)
};
// The one-line reasons a GPU cannot run this build, each naming the GPU (or driver), what it
// has and what is needed (issue 35); selectDevice and deviceAlloc throw them as SystemError
// (exit 1). Distinct from "no usable CUDA device" (no NVIDIA driver or no GPU: nothing to run
// on, which launch/gpu-check reports as exit 3). Versions as CUDA gives them (12040: 12.4).
std::string driverTooOldText(int driver_version, int runtime_version);
std::string noKernelImageText(int ordinal, const std::string& name, int major, int minor, const std::string& built);
// bytes_free / bytes_total: 0 where not known (the CPU build).
std::string deviceOutOfMemoryText(const DeviceInfo& device, uint64_t bytes, uint64_t bytes_free, uint64_t bytes_total);
// The GPU architectures this build carries kernels for (OCC_CUDA_ARCHITECTURES), "" in the CPU build.
const char* builtArchitectures();
// Binds the calling process to its device, once, before any other device call. requested:
// a CUDA device number, or -1 for the node-local rank of an MPI job (OMPI_COMM_WORLD_LOCAL_RANK,
// MPI_LOCALRANKID or SLURM_LOCALID; 0 outside one) modulo the device count, so that each rank
// on a node takes its own GPU. Throws SystemError when there is no CUDA device (with CUDA's
// reason) and UsageError for a requested number that does not exist. The CPU build has one
// device, 0. Calling it again with the same request returns the same device.
DeviceInfo selectDevice(int requested = -1);
// The device selectDevice bound (selecting the default one if none was).
const DeviceInfo& currentDevice();
// With an OpenGL context current (a window's): makes sure it is on the CUDA device, so that
// CUDA-OpenGL interop can register its buffers. Under CUDA, when it is not: with no --device
// given (requested < 0) the context's GPU becomes the device (selectDevice again, before any
// device memory is allocated); with one given, SystemError naming both GPUs. A context CUDA
// cannot use at all (another vendor's) is a SystemError too. A no-op in the CPU build.
void matchGlContextDevice(int requested);
// matchGlContextDevice's decision, apart from CUDA (so that it is tested without a GPU): given
// the --device asked for (-1: none), the device in use and the CUDA devices of the GL context
// (empty: none, why_none says why), either nothing to do, a device to select, or the error.
struct GlDeviceChoice {
    int select = -1;    // the device to select, -1: none
    std::string error;  // non-empty: the one line to refuse with
};
GlDeviceChoice chooseGlContextDevice(int requested, const DeviceInfo& current, const std::vector<int>& gl_devices,
                                     const std::string& gl_name, const std::string& why_none);
// Throws SystemError naming the device, its memory and what is free when it has less than
// `bytes` free for `what` ("the scene F"; `detail`, if any, says what the bytes are); a no-op in
// the CPU build, whose memory is the host's. For tests of that path on any machine,
// OCC_DEVICE_MEMORY_BYTES=N makes the device hold at most N bytes (free: N less what
// deviceAlloc holds; deviceAlloc beyond it is DeviceOutOfMemory), in both builds.
void requireDeviceMemory(uint64_t bytes, const std::string& what, const std::string& detail = "");
// The device memory CUDA reserves for the kernels' local memory (their stacks) when it launches
// them: the stack size limit for every thread the GPU can hold at once. 0 in the CPU build.
uint64_t kernelLocalMemoryBytes();

// Waits until every kernel launched so far has finished (a no-op on the CPU).
void deviceSynchronize();
// "cpu-tbb" or "cuda".
const char* deviceBackend();
// For a failure a device algorithm reported in its own exception type (Thrust's system_error
// under CUDA, which is not a SystemError): "CUDA: " and its message. "" for any other exception.
std::string deviceErrorText(const std::exception& e);
// Whether this build's device can run kernels here: always in the CPU build; under CUDA, when
// a CUDA device is visible (else false, with CUDA's reason in *why when why is not null).
bool deviceAvailable(std::string* why = nullptr);

// What crossed between host and device memory on the calling thread since it started, all
// purposes: the bus's explicit copies and the scalars kernels return (reductions, counts).
// Device-to-device copies do not cross the bus; they are counted apart.
struct BusCounters {
    uint64_t h2d_bytes = 0, d2h_bytes = 0, d2d_bytes = 0;
    uint64_t h2d_copies = 0, d2h_copies = 0;
};
const BusCounters& busCounters();
// While one is alive on a thread, that thread's bus traffic is a measurement's (the exact and
// reference passes of the display, debug pictures), counted in measurementBusCounters() instead
// of busCounters(). Scopes nest.
class BusMeasurementScope {
public:
    BusMeasurementScope();
    ~BusMeasurementScope();
    BusMeasurementScope(const BusMeasurementScope&) = delete;
    BusMeasurementScope& operator=(const BusMeasurementScope&) = delete;
};
const BusCounters& measurementBusCounters();

// The bus: the one copy path between host and device. Sizes are in bytes; 0 copies nothing.
// Pointers must be valid for `bytes` (host memory on the host side, device memory on the
// other); ranges must not overlap. Throws SystemError on a CUDA failure.
void busToDevice(DevicePtr<void> dst, const void* src, size_t bytes);
void busToHost(void* dst, DevicePtr<const void> src, size_t bytes);
void deviceToDevice(DevicePtr<void> dst, DevicePtr<const void> src, size_t bytes);
// Sets `bytes` bytes of device memory to `value` (no bus traffic).
void deviceMemset(DevicePtr<void> dst, int value, size_t bytes);

// Typed copies of n elements. The source may be const or not.
template <class T>
void copyToDevice(DevicePtr<T> dst, const T* src, size_t n) {
    busToDevice(DevicePtr<void>(dst), src, n * sizeof(T));
}
template <class T, class U, class = std::enable_if_t<std::is_same_v<std::remove_const_t<U>, T>>>
void copyToHost(T* dst, DevicePtr<U> src, size_t n) {
    busToHost(dst, DevicePtr<const void>(src), n * sizeof(T));
}
template <class T, class U, class = std::enable_if_t<std::is_same_v<std::remove_const_t<U>, T>>>
void copyOnDevice(DevicePtr<T> dst, DevicePtr<U> src, size_t n) {
    deviceToDevice(DevicePtr<void>(dst), DevicePtr<const void>(src), n * sizeof(T));
}
// One element back to the host.
template <class U>
std::remove_const_t<U> readBack(DevicePtr<U> src) {
    std::remove_const_t<U> value;
    copyToHost(&value, src, 1);
    return value;
}

// What DeviceArray and PinnedArray share: an owned, growable allocation from Alloc / Free.
// Contents are uninitialised after construction and after resize (resize keeps nothing when it
// grows). Capacity never shrinks.
template <class T, void* (*Alloc)(size_t), void (*Free)(void*)>
class OwnedArray {
public:
    OwnedArray() = default;
    explicit OwnedArray(size_t n) { resize(n); }
    ~OwnedArray() { Free(data_); }
    OwnedArray(OwnedArray&& o) noexcept
        : data_(std::exchange(o.data_, nullptr)), size_(std::exchange(o.size_, 0)),
          capacity_(std::exchange(o.capacity_, 0)) {}
    OwnedArray& operator=(OwnedArray&& o) noexcept {
        std::swap(data_, o.data_);
        std::swap(size_, o.size_);
        std::swap(capacity_, o.capacity_);
        return *this;
    }
    OwnedArray(const OwnedArray&) = delete;
    OwnedArray& operator=(const OwnedArray&) = delete;

    void resize(size_t n) {
        if (n > capacity_) replace(n, 0);
        size_ = n;
    }
    // At least n elements: grows to n + n / 2 when short (contents not kept), so that a need
    // that creeps up from frame to frame does not reallocate every frame.
    void growTo(size_t n) {
        if (size_ < n) resize(n + n / 2);
    }
    size_t size() const { return size_; }
    size_t capacity() const { return capacity_; }
    bool empty() const { return size_ == 0; }

protected:
    // A fresh allocation of n elements; `keep` elements are copied over by copy(fresh, old).
    template <class Copy>
    void replace(size_t n, size_t keep, Copy&& copy) {
        T* fresh = static_cast<T*>(Alloc(n * sizeof(T)));
        if (keep) copy(fresh, data_);
        Free(data_);
        data_ = fresh;
        capacity_ = n;
    }
    void replace(size_t n, size_t) {
        replace(n, 0, [](T*, T*) {});
    }
    T* data_ = nullptr;
    size_t size_ = 0, capacity_ = 0;
};

// A growable array in device memory that host code can hand to kernels but not read.
// resizeKeep keeps the contents (a device-to-device copy when it grows).
template <class T>
class DeviceArray : public OwnedArray<T, deviceAlloc, deviceFree> {
    using Base = OwnedArray<T, deviceAlloc, deviceFree>;

public:
    using Base::Base;
    void resizeKeep(size_t n) {
        if (n > this->capacity_)
            this->replace(n, this->size_, [&](T* fresh, T* old) {
                deviceToDevice(DevicePtr<void>(DevicePtr<T>(fresh)), DevicePtr<const void>(DevicePtr<const T>(old)),
                               this->size_ * sizeof(T));
            });
        this->size_ = n;
    }
    DevicePtr<T> ptr() { return DevicePtr<T>(this->data_); }
    DevicePtr<const T> ptr() const { return DevicePtr<const T>(this->data_); }
};

// A growable array of pinned host memory, what the bus moves at full speed; the host indexes it.
template <class T>
class PinnedArray : public OwnedArray<T, pinnedAlloc, pinnedFree> {
    using Base = OwnedArray<T, pinnedAlloc, pinnedFree>;

public:
    using Base::Base;
    T* data() { return this->data_; }
    const T* data() const { return this->data_; }
    T& operator[](size_t i) { return this->data_[i]; }
    const T& operator[](size_t i) const { return this->data_[i]; }
    T* begin() { return this->data_; }
    T* end() { return this->data_ + this->size_; }
    const T* begin() const { return this->data_; }
    const T* end() const { return this->data_ + this->size_; }
};

// Memory someone else owns and lends the kernels: the display's OpenGL buffers, which hold the
// active arrays themselves so that nothing is mirrored and re-uploaded (docs/architecture.md,
// "Memory and the bus"). Slots are the lender's names for its buffers.
class BufferProvider {
public:
    virtual ~BufferProvider() = default;
    // Makes slot `slot` hold at least `bytes` (its contents are not kept when it has to grow).
    virtual void reserve(uint32_t slot, size_t bytes) = 0;
    virtual size_t capacity(uint32_t slot) const = 0;
    // Where slot `slot` is now: valid between beginDeviceWrites and endDeviceWrites (CUDA-OpenGL
    // interop maps the buffers for that time; in the CPU build they stay mapped).
    virtual DevicePtr<void> pointer(uint32_t slot) const = 0;
    // Bracket the kernels' writes of a frame: waits until the lender no longer reads what the
    // last frame wrote, then maps; unmaps so that the lender may read.
    virtual void beginDeviceWrites() = 0;
    virtual void endDeviceWrites() = 0;
};

// A growable device buffer in memory of its own (a DeviceArray) or in a BufferProvider's slot.
// reserve grows it by half again when short; contents are not kept when it grows.
template <class T>
class ProvidedBuffer {
public:
    void reserve(size_t n) {
        if (n <= capacity()) return;
        const size_t grown = n + n / 2;
        if (provider_)
            provider_->reserve(slot_, grown * sizeof(T));
        else
            owned_.resize(grown);
    }
    size_t capacity() const { return provider_ ? provider_->capacity(slot_) / sizeof(T) : owned_.size(); }
    DevicePtr<T> ptr() const {
        if (provider_) return devicePtrCast<T>(provider_->pointer(slot_));
        return owned_.ptr();
    }
    bool provided() const { return provider_ != nullptr; }
    // From now on the memory is provider's slot (within its write bracket); the first `keep`
    // elements are copied there from the buffer's own memory, which is then freed. Call inside
    // the provider's write bracket.
    void lendFrom(BufferProvider* provider, uint32_t slot, size_t keep) {
        provider->reserve(slot, std::max<size_t>(1, std::max(keep, owned_.size())) * sizeof(T));
        copyOnDevice(devicePtrCast<T>(provider->pointer(slot)), owned_.ptr(), keep);
        provider_ = provider;
        slot_ = slot;
        owned_ = DeviceArray<T>();
    }

private:
    // Its own memory: a DeviceArray whose whole size is capacity.
    mutable DeviceArray<T> owned_;
    BufferProvider* provider_ = nullptr;
    uint32_t slot_ = 0;
};

// An OpenGL buffer object as device memory the kernels write. CPU build: `mapped`, the buffer's
// persistent, coherent mapping (GL 4.4 buffer storage), is this build's device memory. CUDA
// build: the buffer is registered once with CUDA-OpenGL interop (cudaGraphicsGLRegisterBuffer)
// and mapped between map() and unmap(); `mapped` is unused (pass null). Construct it with the
// buffer's GL context current. Throws SystemError when CUDA cannot register the buffer (its GL
// context is not on this CUDA device).
class GlBufferView {
public:
    GlBufferView(uint32_t gl_buffer, void* mapped);
    ~GlBufferView();
    GlBufferView(const GlBufferView&) = delete;
    GlBufferView& operator=(const GlBufferView&) = delete;
    void map();
    void unmap();
    DevicePtr<void> ptr() const { return ptr_; }  // valid while mapped (always, in the CPU build)
    // Whether the device writes GL buffers through interop (CUDA) rather than GL's own
    // mapping of them (CPU).
    static bool usesInterop();

private:
    void* resource_ = nullptr;  // cudaGraphicsResource_t under CUDA
    DevicePtr<void> ptr_;
    bool mapped_ = false;
};

}  // namespace occ::k
