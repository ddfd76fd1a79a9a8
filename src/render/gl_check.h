// SPDX-License-Identifier: MIT
#pragma once

#include "scene/errors.h"

#include <epoxy/gl.h>

#include <string>

namespace occ::render {

// Throws SystemError("OpenGL: CALL failed at FILE:LINE: GL_INVALID_...") if the GL error flag is
// set. Used through OCC_GL_CHECK after every call that can fail for reasons other than our bug
// (allocation, framebuffer completeness), and once per frame to catch everything else.
void checkGlError(const char* call, const char* file, int line);

// Why a shader or program failed, with its info log: throws SystemError naming `what`.
GLuint compileProgram(const char* what, const char* vertex_source, const char* fragment_source);

}  // namespace occ::render

#define OCC_GL_CHECK(call)                                          \
    do {                                                            \
        call;                                                       \
        ::occ::render::checkGlError(#call, __FILE__, __LINE__);     \
    } while (0)
