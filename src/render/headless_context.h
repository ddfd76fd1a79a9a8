// SPDX-License-Identifier: MIT
#pragma once

#include <string>

namespace occ::render {

// An OpenGL 4.5 core context without a window or an X server, current on the calling thread
// from construction to destruction. It renders into framebuffer objects only.
// Tries, in order: the EGL device platform (EGL_EXT_platform_device) on a device that is not a
// software renderer, i.e. a real GPU; then Mesa's surfaceless platform (llvmpipe on a machine
// without a GPU). Throws SystemError saying what EGL lacks when neither gives a 4.5 context.
// cuda_device >= 0: among EGL devices that name their CUDA device (EGL_NV_device_cuda), the one
// that is CUDA device cuda_device comes first, so that CUDA-OpenGL interop shares one GPU.
class HeadlessContext {
public:
    explicit HeadlessContext(int cuda_device = -1);
    ~HeadlessContext();
    HeadlessContext(const HeadlessContext&) = delete;
    HeadlessContext& operator=(const HeadlessContext&) = delete;

    // "EGL device" or "EGL surfaceless", then GL_RENDERER, e.g. "EGL surfaceless, llvmpipe (LLVM 15.0.6, 256 bits)".
    const std::string& description() const { return description_; }

private:
    void* display_ = nullptr;
    void* context_ = nullptr;
    std::string description_;
};

}  // namespace occ::render
