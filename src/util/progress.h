// SPDX-License-Identifier: MIT
#pragma once

#include <atomic>
#include <chrono>
#include <functional>
#include <string>
#include <thread>

namespace occ {

// A progress line redrawn in place on stderr while work runs on other threads, only when stderr
// is a terminal (logs and CI get the caller's one summary line instead).
// sample() is called from the drawing thread and must be thread-safe.
class ProgressBar {
public:
    struct Sample {
        double done = 0, total = 0;  // units of the bar (objects, meshes, ...)
        double work = 0;             // units of the rate (triangles, ...)
    };
    ProgressBar(std::string label, std::string unit, std::string rate_unit, std::function<Sample()> sample);
    ~ProgressBar();  // stops and clears the line

private:
    void draw();
    std::string label_, unit_, rate_unit_;
    std::function<Sample()> sample_;
    std::chrono::steady_clock::time_point start_;
    std::atomic<bool> stop_{false};
    std::thread thread_;
    bool enabled_ = false;
};

}  // namespace occ
