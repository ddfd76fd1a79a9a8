// SPDX-License-Identifier: MIT
#pragma once

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>

namespace occ {

// `v` with `digits` decimals, as printf's "%.*f" writes it, or "n/a" when it is not finite: the
// one formatter of numbers for tables, CSV fields, logs and the window's title.
inline std::string fixed(double v, int digits) {
    if (!std::isfinite(v)) return "n/a";
    char buffer[64];
    std::snprintf(buffer, sizeof buffer, "%.*f", digits, v);
    return buffer;
}

// Bytes as MiB for messages: one decimal below 100 MiB (small scenes, test limits), whole above.
inline std::string mebibytes(uint64_t bytes) {
    const double mib = double(bytes) / double(1u << 20);
    return fixed(mib, mib < 100.0 ? 1 : 0) + " MiB";
}

}  // namespace occ
