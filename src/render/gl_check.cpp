// SPDX-License-Identifier: MIT
#include "render/gl_check.h"

#include <vector>

namespace occ::render {

namespace {

const char* glErrorName(GLenum e) {
    switch (e) {
    case GL_INVALID_ENUM: return "GL_INVALID_ENUM";
    case GL_INVALID_VALUE: return "GL_INVALID_VALUE";
    case GL_INVALID_OPERATION: return "GL_INVALID_OPERATION";
    case GL_INVALID_FRAMEBUFFER_OPERATION: return "GL_INVALID_FRAMEBUFFER_OPERATION";
    case GL_OUT_OF_MEMORY: return "GL_OUT_OF_MEMORY";
    case GL_STACK_OVERFLOW: return "GL_STACK_OVERFLOW";
    case GL_STACK_UNDERFLOW: return "GL_STACK_UNDERFLOW";
    default: return "unknown GL error";
    }
}

GLuint compileShader(const char* what, GLenum stage, const char* source) {
    const GLuint shader = glCreateShader(stage);
    glShaderSource(shader, 1, &source, nullptr);
    glCompileShader(shader);
    GLint ok = 0;
    glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        GLint length = 0;
        glGetShaderiv(shader, GL_INFO_LOG_LENGTH, &length);
        std::vector<char> log(size_t(length) + 1, '\0');
        glGetShaderInfoLog(shader, length, nullptr, log.data());
        glDeleteShader(shader);
        throw SystemError(std::string("OpenGL: ") + what + (stage == GL_VERTEX_SHADER ? " vertex" : " fragment") +
                          " shader does not compile: " + log.data());
    }
    return shader;
}

}  // namespace

void checkGlError(const char* call, const char* file, int line) {
    const GLenum e = glGetError();
    if (e == GL_NO_ERROR) return;
    while (glGetError() != GL_NO_ERROR) {
    }
    throw SystemError(std::string("OpenGL: ") + call + " failed at " + file + ":" + std::to_string(line) + ": " +
                      glErrorName(e));
}

GLuint compileProgram(const char* what, const char* vertex_source, const char* fragment_source) {
    const GLuint vs = compileShader(what, GL_VERTEX_SHADER, vertex_source);
    const GLuint fs = compileShader(what, GL_FRAGMENT_SHADER, fragment_source);
    const GLuint program = glCreateProgram();
    glAttachShader(program, vs);
    glAttachShader(program, fs);
    glLinkProgram(program);
    glDeleteShader(vs);
    glDeleteShader(fs);
    GLint ok = 0;
    glGetProgramiv(program, GL_LINK_STATUS, &ok);
    if (!ok) {
        GLint length = 0;
        glGetProgramiv(program, GL_INFO_LOG_LENGTH, &length);
        std::vector<char> log(size_t(length) + 1, '\0');
        glGetProgramInfoLog(program, length, nullptr, log.data());
        glDeleteProgram(program);
        throw SystemError(std::string("OpenGL: ") + what + " program does not link: " + log.data());
    }
    return program;
}

}  // namespace occ::render
