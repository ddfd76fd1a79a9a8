// SPDX-License-Identifier: MIT
#pragma once

// For kernel sources only (kernels/*.cu): how a kernel reaches the memory behind a DevicePtr.
// Host code in src/ and roles/ must not include this; tests/unit/test_device_memory.cpp checks
// that none does, and that host code cannot read through a DevicePtr.
#include "device_memory.h"

namespace occ::k {

struct DeviceAccess {
    template <class T>
    static T* raw(DevicePtr<T> p) {
        return p.p_;
    }
    // A kernel's own raw pointer back into the typed world, to call another kernel with it.
    template <class T>
    static DevicePtr<T> wrap(T* p) {
        return DevicePtr<T>(p);
    }
};

template <class T>
T* raw(DevicePtr<T> p) {
    return DeviceAccess::raw(p);
}

// Counts `bytes` that came back to the host outside the bus's copies: the result of a Thrust
// reduction or the end of a copy_if, which Thrust copies device -> host itself.
void countReadback(size_t bytes);

}  // namespace occ::k
