// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <string_view>

namespace occ {

// A file that appears whole or not at all. Writes go to a temporary beside `path` (its name
// unique per process and file), which commit() flushes, syncs and renames over `path`; an
// AtomicFile destroyed without commit() removes the temporary, so a failed or interrupted
// write never leaves half a file over an earlier one. Every failure is an InputError naming
// `path`.
class AtomicFile {
public:
    explicit AtomicFile(std::string path);
    ~AtomicFile();
    AtomicFile(const AtomicFile&) = delete;
    AtomicFile& operator=(const AtomicFile&) = delete;

    void write(const void* data, size_t bytes);
    void write(std::string_view text) { write(text.data(), text.size()); }
    // Bytes written so far.
    uint64_t size() const { return size_; }
    // Overwrites bytes already written (a header whose lengths are known only at the end).
    void writeAt(uint64_t offset, const void* data, size_t bytes);
    // Appends the whole of another AtomicFile's content (not yet committed), copied in the kernel.
    void append(AtomicFile& other);
    void commit();
    const std::string& path() const { return path_; }

private:
    [[noreturn]] void fail(const std::string& what);
    std::string path_, temporary_;
    std::FILE* file_ = nullptr;
    uint64_t size_ = 0;
};

// The whole of `bytes` to `path`, through an AtomicFile.
void writeFileAtomic(const std::string& path, std::string_view bytes);

// Makes folder `dir` (and its parents) if missing; InputError(dir, ...) if it cannot, or if
// `dir` is a file.
void makeOutputFolder(const std::string& dir);

}  // namespace occ
