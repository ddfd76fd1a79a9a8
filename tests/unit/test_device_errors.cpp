// SPDX-License-Identifier: MIT
// The one-line reasons a GPU cannot run this build (issue 35): what each names and asks for.
// The CUDA paths that throw them (a driver too old, a GPU without kernels, a full device) need
// a GPU to happen; the words are checked here, and the full-device path end to end through
// OCC_DEVICE_ALLOC_FAIL_AT in tests/cli_device.sh.
#include "device_memory.h"

#include <gtest/gtest.h>

namespace occ::k {
namespace {

TEST(DeviceErrors, ADriverTooOldSaysWhatItSupportsAndWhatIsNeeded) {
    const std::string text = driverTooOldText(12040, 13000);
    EXPECT_NE(text.find("supports CUDA up to 12.4"), std::string::npos) << text;
    EXPECT_NE(text.find("CUDA 13.0 runtime"), std::string::npos) << text;
    EXPECT_NE(text.find("update the driver"), std::string::npos) << text;
    EXPECT_EQ(text.find("no usable CUDA device"), std::string::npos) << "a GPU is there: not the no-device words";
    EXPECT_EQ(text.find('\n'), std::string::npos);
}

TEST(DeviceErrors, AGpuWithoutKernelsNamesItsArchitectureAndWhatToRebuildFor) {
    const std::string text = noKernelImageText(1, "NVIDIA A10", 8, 6, "90");
    EXPECT_NE(text.find("CUDA device 1 (NVIDIA A10, compute capability 8.6)"), std::string::npos) << text;
    EXPECT_NE(text.find("built for 90"), std::string::npos) << text;
    EXPECT_NE(text.find("OCC_CUDA_ARCHITECTURES=86"), std::string::npos) << text;
    EXPECT_EQ(text.find("no usable CUDA device"), std::string::npos);
    EXPECT_EQ(text.find('\n'), std::string::npos);
}

TEST(DeviceErrors, AFullDeviceNamesTheGpuItsMemoryAndTheRequest) {
    DeviceInfo gpu;
    gpu.ordinal = 0;
    gpu.name = "NVIDIA H100";
    const std::string text = deviceOutOfMemoryText(gpu, uint64_t(3) << 30, uint64_t(1) << 29, uint64_t(80) << 30);
    EXPECT_NE(text.find("out of device memory: CUDA device 0 (NVIDIA H100, 81920 MiB, 512 MiB free) could not allocate "
                        "3072 MiB"),
              std::string::npos)
        << text;
    const std::string temporary = deviceOutOfMemoryText(gpu, 0, 0, 0);
    EXPECT_NE(temporary.find("CUDA device 0 (NVIDIA H100) could not allocate a device algorithm's temporary storage"),
              std::string::npos)
        << temporary;
    DeviceInfo cpu;
    cpu.name = "CPU (host memory, TBB)";
    EXPECT_NE(deviceOutOfMemoryText(cpu, 1 << 20, 0, 0).find("CPU (host memory, TBB) could not allocate 1.0 MiB"),
              std::string::npos);
}

// Item 7: the window's GL context and the CUDA device. The decision is checked here; the CUDA
// call that lists the context's devices (cudaGLGetDevices) needs a GPU and its X screen.
TEST(DeviceErrors, TheWindowTakesItsContextsGpuOrSaysWhyItCannot) {
    DeviceInfo in_use;
    in_use.ordinal = 1;
    in_use.name = "NVIDIA H100";
    // The context is on the device in use (one of several it spans): nothing to do.
    GlDeviceChoice c = chooseGlContextDevice(-1, in_use, {0, 1}, "NVIDIA L40", "");
    EXPECT_EQ(c.select, -1);
    EXPECT_TRUE(c.error.empty());
    // Elsewhere, no --device: the context's GPU becomes the device.
    c = chooseGlContextDevice(-1, in_use, {0}, "NVIDIA L40", "");
    EXPECT_EQ(c.select, 0);
    EXPECT_TRUE(c.error.empty()) << c.error;
    // Elsewhere, --device given: one line naming both GPUs and the two ways out.
    c = chooseGlContextDevice(1, in_use, {0}, "NVIDIA L40", "");
    EXPECT_EQ(c.select, -1);
    EXPECT_NE(c.error.find("--device 1 is CUDA device 1 (NVIDIA H100), but the window's OpenGL context is on CUDA device "
                           "0 (NVIDIA L40)"),
              std::string::npos)
        << c.error;
    EXPECT_NE(c.error.find("give --device 0 or open the window on GPU 1's X screen"), std::string::npos) << c.error;
    EXPECT_EQ(c.error.find('\n'), std::string::npos);
    // A context on no CUDA GPU (another vendor's, or Mesa's): refused with CUDA's reason.
    c = chooseGlContextDevice(-1, in_use, {}, "?", "OS call failed or operation not supported on this OS");
    EXPECT_EQ(c.select, -1);
    EXPECT_NE(c.error.find("on no GPU CUDA can use (OS call failed"), std::string::npos) << c.error;
    EXPECT_NE(c.error.find("--headless or --no-display"), std::string::npos) << c.error;
}

}  // namespace
}  // namespace occ::k
