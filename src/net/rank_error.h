// SPDX-License-Identifier: MIT
#pragma once

#include "scene/errors.h"

#include <string>

namespace occ {

// Raised when another rank cannot be trusted any more: one of its messages is malformed, it
// sent nothing for too long, it died or it gave up. what() is "rank R: detail" (an InputError
// whose "file" is "rank R"), so the command line prints "error: rank R: detail" like any other
// bad input. rank() is the rank at fault, not necessarily the one that noticed.
class RankError : public InputError {
public:
    RankError(int rank, const std::string& detail)
        : InputError("rank " + std::to_string(rank), detail), rank_(rank), detail_(detail) {}
    int rank() const { return rank_; }
    // what() without the "rank R: " prefix.
    const std::string& detail() const { return detail_; }

private:
    int rank_;
    std::string detail_;
};

}  // namespace occ
