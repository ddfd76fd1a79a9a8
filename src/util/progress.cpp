// SPDX-License-Identifier: MIT
#include "util/progress.h"

#include <cstdio>
#include <unistd.h>

namespace occ {

ProgressBar::ProgressBar(std::string label, std::string unit, std::string rate_unit, std::function<Sample()> sample)
    : label_(std::move(label)), unit_(std::move(unit)), rate_unit_(std::move(rate_unit)), sample_(std::move(sample)),
      start_(std::chrono::steady_clock::now()), enabled_(::isatty(STDERR_FILENO) == 1) {
    if (!enabled_) return;
    thread_ = std::thread([this] {
        while (!stop_) {
            draw();
            for (int i = 0; i < 5 && !stop_; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(40));
        }
    });
}

ProgressBar::~ProgressBar() {
    if (!enabled_) return;
    stop_ = true;
    thread_.join();
    std::fprintf(stderr, "\r\033[K");
    std::fflush(stderr);
}

void ProgressBar::draw() {
    const Sample s = sample_();
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    const double fraction = s.total > 0 ? std::min(1.0, s.done / s.total) : 0.0;
    constexpr int kWidth = 30;
    char bar[kWidth + 1];
    for (int i = 0; i < kWidth; ++i) bar[i] = i < int(fraction * kWidth) ? '#' : '.';
    bar[kWidth] = 0;
    const double rate = seconds > 0 ? s.work / seconds : 0.0;
    char eta[32] = "--";
    if (fraction > 0.01) std::snprintf(eta, sizeof(eta), "%.0f s", seconds * (1.0 - fraction) / fraction);
    std::fprintf(stderr, "\r%s [%s] %.0f/%.0f %s  %.2f M %s/s  ETA %s\033[K", label_.c_str(), bar, s.done, s.total,
                 unit_.c_str(), rate / 1e6, rate_unit_.c_str(), eta);
    std::fflush(stderr);
}

}  // namespace occ
