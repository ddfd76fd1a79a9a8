// SPDX-License-Identifier: MIT
#include "scene/atomic_file.h"

#include "scene/errors.h"

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <vector>

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
    file_ = std::fopen(temporary_.c_str(), "w+b");
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
    size_ += bytes;
}

void AtomicFile::writeAt(uint64_t offset, const void* data, size_t bytes) {
    if (!file_) throw InputError(path_, "write after commit");
    if (offset + bytes > size_) throw InputError(path_, "writeAt past the end of what was written");
    if (std::fflush(file_) != 0) fail("cannot write (disk full?)");
    const auto* p = static_cast<const char*>(data);
    for (size_t done = 0; done < bytes;) {
        const ssize_t n = ::pwrite(::fileno(file_), p + done, bytes - done, off_t(offset + done));
        if (n <= 0) fail("cannot write (disk full?)");
        done += size_t(n);
    }
}

void AtomicFile::append(AtomicFile& other) {
    if (!file_ || !other.file_) throw InputError(path_, "append after commit");
    if (std::fflush(file_) != 0 || std::fflush(other.file_) != 0) fail("cannot write (disk full?)");
    const int in = ::fileno(other.file_), out = ::fileno(file_);
    loff_t from = 0, to = loff_t(size_);
    uint64_t left = other.size_;
    while (left > 0) {
        ssize_t n = ::copy_file_range(in, &from, out, &to, size_t(std::min<uint64_t>(left, 1u << 30)), 0);
        if (n < 0 && (errno == EXDEV || errno == ENOSYS || errno == EINVAL)) {
            // Another file system: copy through a buffer.
            static thread_local std::vector<char> buffer(1 << 20);
            n = ::pread(in, buffer.data(), size_t(std::min<uint64_t>(left, buffer.size())), from);
            if (n > 0) {
                for (ssize_t w = 0; w < n;) {
                    const ssize_t k = ::pwrite(out, buffer.data() + w, size_t(n - w), to + w);
                    if (k <= 0) fail("cannot write (disk full?)");
                    w += k;
                }
                from += n;
                to += n;
            }
        }
        if (n <= 0) fail("cannot copy " + other.temporary_ + " into it");
        left -= uint64_t(n);
    }
    size_ += other.size_;
    // The stream's own position must follow the bytes written behind its back.
    if (std::fseek(file_, 0, SEEK_END) != 0) fail("cannot seek");
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
