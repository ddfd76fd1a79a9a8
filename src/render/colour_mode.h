// SPDX-License-Identifier: MIT
#pragma once

// How a picture colours its items (`render --colours`); no OpenGL needed to name one.
namespace occ::render {

enum class ColourMode {
    Model,    // each object in its model's colour (ObjectDisk::color: glTF baseColorFactor, OBJ Kd, ...)
    Object,   // each object a pastel of its id (objectColour), so that neighbouring parts differ
    Uniform,  // every item one grey: pictures differ only in geometry and shading
};

// "model", "object", "uniform".
inline const char* colourModeName(ColourMode mode) {
    switch (mode) {
        case ColourMode::Model: return "model";
        case ColourMode::Object: return "object";
        case ColourMode::Uniform: return "uniform";
    }
    return "?";
}

}  // namespace occ::render
