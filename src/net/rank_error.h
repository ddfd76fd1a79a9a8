// SPDX-License-Identifier: MIT
#pragma once

#include "scene/errors.h"

#include <string>

namespace occ {

// Raised when another rank cannot be trusted any more: one of its messages is malformed, it
// sent nothing for too long, it died or it gave up. That is a failure of the job, not of the
// user's input, so it is a SystemError (exit status 1): what() is "rank R: detail" and the
// command line prints "error: rank R: detail". rank() is the rank at fault, not necessarily the
// one that noticed.
class RankError : public SystemError {
public:
    RankError(int rank, const std::string& detail)
        : SystemError("rank " + std::to_string(rank) + ": " + detail), rank_(rank), detail_(detail) {}
    int rank() const { return rank_; }
    // what() without the "rank R: " prefix.
    const std::string& detail() const { return detail_; }

private:
    int rank_;
    std::string detail_;
};

}  // namespace occ
