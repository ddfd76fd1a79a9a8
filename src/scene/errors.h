// SPDX-License-Identifier: MIT
#pragma once

#include <cstdio>
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

// Raised by the library for a parameter out of its range. option() names the parameter as the
// library's own options do ("alpha", "viewport", "device"), never a command-line flag; the
// command line prints it under its flag (cli/main.cpp), other callers as it is:
// what() is "option: detail".
class OptionError : public UsageError {
public:
    // A parameter's value as a user would type it ("0.5", "3", not "0.500000").
    static std::string value(double v) {
        char text[32];
        std::snprintf(text, sizeof text, "%g", v);
        return text;
    }
    OptionError(const std::string& option, const std::string& detail)
        : UsageError(option + ": " + detail), option_(option), detail_(detail) {}
    const std::string& option() const { return option_; }
    const std::string& detail() const { return detail_; }

private:
    std::string option_, detail_;
};

// Raised when the machine cannot do what was asked: no OpenGL or EGL, a failed GL or CUDA call,
// a rank of the job that died. what() names the call or the rank; the command line prints
// "error: " + what() and exits with status 1.
class SystemError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

}  // namespace occ
