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
    EXPECT_NE(deviceOutOfMemoryText(cpu, 1 << 20, 0, 0).find("CPU (host memory, TBB) could not allocate 1 MiB"),
              std::string::npos);
}

}  // namespace
}  // namespace occ::k
