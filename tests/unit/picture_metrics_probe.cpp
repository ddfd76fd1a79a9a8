// SPDX-License-Identifier: MIT
// picture_metrics_probe OURS.ppm REFERENCE.ppm: prints "ssim psnr_db perceptible_percent" of two
// same-sized 8-bit binary PPMs (P6, maxval 255), for tests/ssim_skimage_check.py to hold
// against scikit-image. A bad file is reported with its name and the byte offset, exit 1.
#include "render/picture_metrics.h"

#include <cctype>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace {

struct Picture {
    uint32_t width = 0, height = 0;
    std::vector<uint8_t> rgb;
};

class PpmReader {
public:
    PpmReader(std::string path, std::vector<uint8_t> bytes) : path_(std::move(path)), bytes_(std::move(bytes)) {}

    Picture read() {
        if (bytes_.size() < 2 || bytes_[0] != 'P' || bytes_[1] != '6') fail("not a binary PPM (no 'P6' magic)");
        pos_ = 2;
        Picture picture;
        picture.width = number("width");
        if (picture.width == 0) failAt(field_start_, "width 0");
        picture.height = number("height");
        if (picture.height == 0) failAt(field_start_, "height 0");
        const uint32_t maxval = number("maxval");
        if (maxval != 255) failAt(field_start_, "maxval " + std::to_string(maxval) + ", only 8-bit (255) is read");
        // Exactly one whitespace byte separates the header from the pixels.
        if (pos_ >= bytes_.size() || !std::isspace(bytes_[pos_])) fail("expected one whitespace byte after maxval");
        ++pos_;
        const uint64_t size = 3ull * picture.width * picture.height;
        if (bytes_.size() - pos_ < size)
            fail("pixel data ends after " + std::to_string(bytes_.size() - pos_) + " of " + std::to_string(size) +
                 " bytes");
        picture.rgb.assign(bytes_.begin() + std::ptrdiff_t(pos_), bytes_.begin() + std::ptrdiff_t(pos_ + size));
        return picture;
    }

private:
    [[noreturn]] void fail(const std::string& what) const { failAt(pos_, what); }
    [[noreturn]] void failAt(size_t offset, const std::string& what) const {
        throw std::runtime_error(path_ + ": byte " + std::to_string(offset) + ": " + what);
    }

    // Netpbm allows whitespace and '#' comments to end of line between header fields.
    void skipSpace() {
        while (pos_ < bytes_.size()) {
            if (bytes_[pos_] == '#') {
                while (pos_ < bytes_.size() && bytes_[pos_] != '\n') ++pos_;
            } else if (std::isspace(bytes_[pos_])) {
                ++pos_;
            } else {
                break;
            }
        }
    }

    uint32_t number(const char* field) {
        skipSpace();
        if (pos_ >= bytes_.size() || !std::isdigit(bytes_[pos_]))
            fail(std::string("expected the ") + field + " as a decimal number");
        field_start_ = pos_;
        uint64_t value = 0;
        while (pos_ < bytes_.size() && std::isdigit(bytes_[pos_])) {
            value = value * 10 + uint64_t(bytes_[pos_++] - '0');
            if (value > 1u << 20) failAt(field_start_, std::string(field) + " is over 1048576");
        }
        return uint32_t(value);
    }

    std::string path_;
    std::vector<uint8_t> bytes_;
    size_t pos_ = 0;
    size_t field_start_ = 0;  // where the header field last read began, for its errors
};

Picture readPpm(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw std::runtime_error(path + ": cannot open");
    std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    return PpmReader(path, std::move(bytes)).read();
}

}  // namespace

int main(int argc, char** argv) {
    if (argc != 3) {
        std::fprintf(stderr, "usage: %s OURS.ppm REFERENCE.ppm\n", argv[0]);
        return 2;
    }
    try {
        const Picture ours = readPpm(argv[1]), ref = readPpm(argv[2]);
        if (ours.width != ref.width || ours.height != ref.height)
            throw std::runtime_error(std::string(argv[1]) + " is " + std::to_string(ours.width) + "x" +
                                     std::to_string(ours.height) + " but " + argv[2] + " is " +
                                     std::to_string(ref.width) + "x" + std::to_string(ref.height));
        const occ::render::PictureDifference d = occ::render::comparePictures(
            ours.rgb.data(), ref.rgb.data(), nullptr, nullptr, ours.width, ours.height, 1.0f);
        std::printf("%.17g %.17g %.17g\n", d.ssim, d.psnr_db, d.perceptible_percent);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "picture_metrics_probe: %s\n", e.what());
        return 1;
    }
    return 0;
}
