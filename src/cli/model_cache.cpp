// SPDX-License-Identifier: MIT
#include "cli/model_cache.h"

#include "scene/atomic_file.h"
#include "scene/errors.h"
#include "scene/oss_file.h"

#include <xxhash.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <unistd.h>

namespace occ::cli {

namespace fs = std::filesystem;

namespace {

// "size hash" of a file's bytes, read in chunks.
std::string identity(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError(path, "cannot open: " + std::string(std::strerror(errno)));
    XXH3_state_t* state = XXH3_createState();
    XXH3_64bits_reset(state);
    std::vector<char> chunk(1 << 20);
    uint64_t size = 0;
    while (in) {
        in.read(chunk.data(), std::streamsize(chunk.size()));
        const std::streamsize n = in.gcount();
        if (n <= 0) break;
        XXH3_64bits_update(state, chunk.data(), size_t(n));
        size += uint64_t(n);
    }
    const uint64_t hash = XXH3_64bits_digest(state);
    XXH3_freeState(state);
    char text[64];
    std::snprintf(text, sizeof text, "%llu %016llx", (unsigned long long)size, (unsigned long long)hash);
    return text;
}

std::string readSmall(const std::string& path) {
    std::ifstream in(path);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

bool writable(const fs::path& dir) { return ::access(dir.empty() ? "." : dir.c_str(), W_OK) == 0; }

}  // namespace

std::string preparedScene(const std::string& input) {
    if (lowerExtension(input) == ".oss") return input;
    std::error_code ec;
    if (!fs::exists(input, ec)) throw InputError(input, "missing: no such file");
    const std::string id = identity(input);
    const fs::path model(input);
    fs::path cache = fs::path(input + ".oss");
    if (!writable(model.parent_path())) {
        const char* xdg = std::getenv("XDG_CACHE_HOME");
        const char* home = std::getenv("HOME");
        const fs::path root = xdg && *xdg ? fs::path(xdg) : fs::path(home && *home ? home : "/tmp") / ".cache";
        makeOutputFolder((root / "occswitch").string());
        cache = root / "occswitch" / (model.filename().string() + "." + id.substr(id.find(' ') + 1) + ".oss");
    }
    const std::string source = cache.string() + ".source";
    const std::string stamp = "occswitch prepared-scene cache v1: " + id + "\n";
    if (fs::exists(cache, ec) && readSmall(source) == stamp) {
        try {
            (void)OssFile::open(cache.string(), OssFile::Pages::Release);  // only checked here
            std::fprintf(stderr, "%s: using the prepared scene %s (the model is unchanged)\n", input.c_str(),
                         cache.c_str());
            return cache.string();
        } catch (const InputError&) {
            // A damaged cache is made again.
        }
    }
    std::fprintf(stderr, "%s: preparing it into %s (once; reused while the model is unchanged)\n",
                 input.c_str(), cache.c_str());
    fs::remove(source, ec);  // the stamp goes only with a whole scene
    prepareModel(input, cache.string());
    writeFileAtomic(source, stamp);
    return cache.string();
}

}  // namespace occ::cli
