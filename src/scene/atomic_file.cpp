// SPDX-License-Identifier: MIT
#include "scene/atomic_file.h"

#include "scene/errors.h"

#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>

#include <fcntl.h>
#include <unistd.h>

namespace occ {

namespace {

std::string temporaryFor(const std::string& path) {
    static std::atomic<uint64_t> serial{0};
    return path + ".tmp." + std::to_string(::getpid()) + "." + std::to_string(serial++);
}

}  // namespace

AtomicFile::AtomicFile(std::string path) : path_(std::move(path)), temporary_(temporaryFor(path_)) {
    file_ = std::fopen(temporary_.c_str(), "wb");
    if (!file_)
        throw InputError(path_, "cannot create " + temporary_ + ": " + std::strerror(errno) +
                                    (errno == ENOENT ? " (missing folder?)" : ""));
}

AtomicFile::~AtomicFile() {
    if (file_) std::fclose(file_);
    if (!temporary_.empty()) std::remove(temporary_.c_str());
}

void AtomicFile::fail(const std::string& what) {
    const std::string reason = what + ": " + std::strerror(errno);
    if (file_) std::fclose(file_);
    file_ = nullptr;
    std::remove(temporary_.c_str());
    temporary_.clear();
    throw InputError(path_, reason);
}

void AtomicFile::write(const void* data, size_t bytes) {
    if (!file_) throw InputError(path_, "write after commit");
    if (bytes > 0 && std::fwrite(data, 1, bytes, file_) != bytes) fail("cannot write (disk full?)");
}

void AtomicFile::commit() {
    if (!file_) throw InputError(path_, "committed twice");
    if (std::fflush(file_) != 0 || ::fsync(::fileno(file_)) != 0) fail("cannot write (disk full?)");
    const int closed = std::fclose(file_);
    file_ = nullptr;
    if (closed != 0) fail("cannot write");
    if (std::rename(temporary_.c_str(), path_.c_str()) != 0) {
        fail("cannot rename " + temporary_ + " into place");
    }
    temporary_.clear();
    // The rename is durable once the folder is synced; the file is in place already.
    const std::filesystem::path parent = std::filesystem::path(path_).parent_path();
    const std::filesystem::path dir = parent.empty() ? std::filesystem::path(".") : parent;
    const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd >= 0) {
        ::fsync(fd);
        ::close(fd);
    }
}

void writeFileAtomic(const std::string& path, std::string_view bytes) {
    AtomicFile file(path);
    file.write(bytes);
    file.commit();
}

void makeOutputFolder(const std::string& dir) {
    std::error_code ec;
    if (std::filesystem::exists(dir, ec) && !std::filesystem::is_directory(dir, ec))
        throw InputError(dir, "exists and is not a folder");
    std::filesystem::create_directories(dir, ec);
    if (ec) throw InputError(dir, "cannot create the folder: " + ec.message());
}

}  // namespace occ
