// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>

namespace occ {

// splitmix64 (Steele, Lea & Flood, "Fast splittable pseudorandom number generators", 2014).
// Generators and conversions of our own, because std:: distributions differ between standard
// libraries, and procedural scenes and camera paths must come out the same everywhere.
class SplitMix64 {
public:
    explicit SplitMix64(uint64_t seed) : state_(seed) {}
    uint64_t next() {
        uint64_t z = (state_ += 0x9e3779b97f4a7c15ull);
        z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
        z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
        return z ^ (z >> 31);
    }

private:
    uint64_t state_;
};

}  // namespace occ
