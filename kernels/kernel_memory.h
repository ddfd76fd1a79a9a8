// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <cstring>
#include <utility>

namespace occ::k {

// Memory the kernels work on: managed memory under CUDA (host code may read and write it, the
// GPU sees it too), 64-byte-aligned host memory in the CPU build. Never returns null; throws
// std::bad_alloc. kernelFree(nullptr) is a no-op.
void* kernelAlloc(size_t bytes);
void kernelFree(void* p);
// Waits until every kernel launched so far has finished (a no-op on the CPU).
void kernelSynchronize();
// "cpu-tbb" or "cuda".
const char* kernelBackend();

// A fixed-size array in kernel memory. Contents are uninitialised after construction/resize.
template <class T>
class KernelArray {
public:
    KernelArray() = default;
    explicit KernelArray(size_t n) { resize(n); }
    ~KernelArray() { kernelFree(data_); }
    KernelArray(KernelArray&& o) noexcept : data_(std::exchange(o.data_, nullptr)), size_(std::exchange(o.size_, 0)), capacity_(std::exchange(o.capacity_, 0)) {}
    KernelArray& operator=(KernelArray&& o) noexcept {
        std::swap(data_, o.data_);
        std::swap(size_, o.size_);
        std::swap(capacity_, o.capacity_);
        return *this;
    }
    KernelArray(const KernelArray&) = delete;
    KernelArray& operator=(const KernelArray&) = delete;

    // Grows the allocation if needed (contents are not kept when it grows).
    void resize(size_t n) {
        if (n > capacity_) {
            kernelFree(data_);
            data_ = static_cast<T*>(kernelAlloc(n * sizeof(T)));
            capacity_ = n;
        }
        size_ = n;
    }
    // Grows keeping the first size() elements.
    void resizeKeep(size_t n) {
        if (n > capacity_) {
            T* fresh = static_cast<T*>(kernelAlloc(n * sizeof(T)));
            if (size_) std::memcpy(fresh, data_, size_ * sizeof(T));
            kernelFree(data_);
            data_ = fresh;
            capacity_ = n;
        }
        size_ = n;
    }
    T* data() { return data_; }
    const T* data() const { return data_; }
    size_t size() const { return size_; }
    T& operator[](size_t i) { return data_[i]; }
    const T& operator[](size_t i) const { return data_[i]; }
    T* begin() { return data_; }
    T* end() { return data_ + size_; }
    const T* begin() const { return data_; }
    const T* end() const { return data_ + size_; }

private:
    T* data_ = nullptr;
    size_t size_ = 0, capacity_ = 0;
};

}  // namespace occ::k
