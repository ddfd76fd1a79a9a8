// SPDX-License-Identifier: MIT
#pragma once

// The GLSL sources of src/render/shaders/*.glsl, embedded by CMake at configure time (the build
// re-runs it when a shader changes): <pass>.<stage>.glsl becomes k<Pass><Stage>.
namespace occ::render::shaders {

extern const char* const kShadedVert;
extern const char* const kShadedFrag;
extern const char* const kBoxVert;
extern const char* const kBoxFrag;

}  // namespace occ::render::shaders
