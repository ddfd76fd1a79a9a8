// SPDX-License-Identifier: MIT
#pragma once

#include <stdexcept>
#include <string>

namespace occ {

// Raised for untrusted input that cannot be used: a model file, a .oss file, a message.
// what() is "FILE: detail" so the command line can print "error: " + what() on one line.
class InputError : public std::runtime_error {
public:
    InputError(const std::string& file, const std::string& detail)
        : std::runtime_error(file + ": " + detail), file_(file) {}
    const std::string& file() const { return file_; }

private:
    std::string file_;
};

// Raised for impossible command-line options and arguments.
class UsageError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

// Raised when the machine cannot do what was asked: no OpenGL or EGL, a failed GL or CUDA call,
// a rank of the job that died. what() names the call or the rank; the command line prints
// "error: " + what() and exits with status 1.
class SystemError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

}  // namespace occ
