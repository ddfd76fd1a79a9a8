// SPDX-License-Identifier: MIT
// One libFuzzer target per decoder of untrusted bytes (OCC_FUZZ_TARGET picks it): the model
// importers (by file extension: the bytes go to a file of that kind; glTF also through the
// streaming reader), the .oss reader and the
// wire messages. A decoder may reject its input (InputError for files, RankError for messages,
// std::bad_alloc for an absurd size);
// anything else (a crash, a sanitizer report, another exception) is a finding.
#include "import/import.h"
#include "import/scene_source.h"
#include "net/messages.h"
#include "scene/errors.h"
#include "scene/oss_file.h"

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <new>
#include <stdexcept>
#include <string>

#include <unistd.h>

namespace {

const std::string& scratchFile(const char* extension) {
    static const std::string path = "/tmp/occ_fuzz_" + std::to_string(::getpid()) + extension;
    // Removed when the fuzzer exits (its time is up, or the corpus ran): nothing left in /tmp.
    // Registered once path is made, so that it runs before path is destroyed.
    static const bool removed_at_exit = std::atexit([] { std::remove(path.c_str()); }) == 0;
    (void)removed_at_exit;
    return path;
}

void writeFile(const std::string& path, const uint8_t* data, size_t size) {
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (!f) throw std::runtime_error("cannot write " + path);
    if (size > 0 && std::fwrite(data, 1, size, f) != size) {
        std::fclose(f);
        throw std::runtime_error("cannot write " + path);
    }
    std::fclose(f);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    using namespace occ;
#if defined(OCC_FUZZ_MESSAGES)
    const DecodeContext ctx{};
    const std::span<const uint8_t> bytes(data, size);
    try { (void)decodeCameraPacket(bytes, ctx); } catch (const RankError&) {}
    try { (void)decodeVisibleSetDelta(bytes, ctx); } catch (const RankError&) {}
    try { (void)decodeEndOfFrame(bytes, ctx); } catch (const RankError&) {}
    try { (void)decodeReport(bytes, ctx); } catch (const RankError&) {}
#else
    const std::string& path = scratchFile(OCC_FUZZ_EXTENSION);
    writeFile(path, data, size);
    try {
#if defined(OCC_FUZZ_OSS)
        const OssFile file = OssFile::open(path);
        file.verifyLodPrefix();
#else
        (void)importModel(path);
#endif
    } catch (const InputError&) {
    } catch (const std::bad_alloc&) {
    }
#if !defined(OCC_FUZZ_OSS)
    // glTF also through the streaming reader prep uses for large files, every mesh read.
    const std::string extension = OCC_FUZZ_EXTENSION;
    if (extension == ".glb" || extension == ".gltf") {
        try {
            std::string why;
            if (const auto source = streamGltf(path, {}, &why))
                for (uint32_t m = 0; m < source->meshCount(); ++m) (void)source->mesh(m);
        } catch (const InputError&) {
        } catch (const std::bad_alloc&) {
        }
    }
#endif
#endif
    return 0;
}
