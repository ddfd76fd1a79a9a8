// SPDX-License-Identifier: MIT
#include "render/headless_context.h"

#include "render/gl_check.h"

#include <epoxy/egl.h>

#include <algorithm>
#include <cstring>
#include <vector>

namespace occ::render {

namespace {

bool hasExtension(const char* list, const char* name) {
    if (!list) return false;
    const size_t n = std::strlen(name);
    for (const char* p = list; (p = std::strstr(p, name)) != nullptr; p += n)
        if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
    return false;
}

// Initialises `display` and creates a current 4.5 core context on it, or returns null and
// leaves the display terminated.
EGLContext makeContext(EGLDisplay display, std::string& why) {
    EGLint major = 0, minor = 0;
    if (!eglInitialize(display, &major, &minor)) {
        why = "eglInitialize failed";
        return EGL_NO_CONTEXT;
    }
    if (!hasExtension(eglQueryString(display, EGL_EXTENSIONS), "EGL_KHR_surfaceless_context")) {
        why = "no EGL_KHR_surfaceless_context";
        eglTerminate(display);
        return EGL_NO_CONTEXT;
    }
    if (!eglBindAPI(EGL_OPENGL_API)) {
        why = "eglBindAPI(EGL_OPENGL_API) failed";
        eglTerminate(display);
        return EGL_NO_CONTEXT;
    }
    const EGLint config_attributes[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
    EGLConfig config = nullptr;
    EGLint configs = 0;
    const bool have_config = eglChooseConfig(display, config_attributes, &config, 1, &configs) && configs > 0;
    const EGLint context_attributes[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 5,
                                         EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                         EGL_NONE};
    // EGL_KHR_no_config_context lets a surfaceless context skip the config.
    EGLContext context = eglCreateContext(display, have_config ? config : EGL_NO_CONFIG_KHR, EGL_NO_CONTEXT,
                                          context_attributes);
    if (context == EGL_NO_CONTEXT) {
        why = "no OpenGL 4.5 core context (eglCreateContext error 0x" + [] {
            char b[16];
            std::snprintf(b, sizeof b, "%x", unsigned(eglGetError()));
            return std::string(b);
        }() + ")";
        eglTerminate(display);
        return EGL_NO_CONTEXT;
    }
    if (!eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context)) {
        why = "eglMakeCurrent without a surface failed";
        eglDestroyContext(display, context);
        eglTerminate(display);
        return EGL_NO_CONTEXT;
    }
    return context;
}

}  // namespace

HeadlessContext::HeadlessContext(int cuda_device) {
    const char* client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    std::string why_device = "no EGL_EXT_platform_device", why_surfaceless = "no EGL_MESA_platform_surfaceless";
    if (hasExtension(client, "EGL_EXT_platform_device") && hasExtension(client, "EGL_EXT_device_enumeration")) {
        EGLint count = 0;
        eglQueryDevicesEXT(0, nullptr, &count);
        std::vector<EGLDeviceEXT> devices(size_t(count > 0 ? count : 0));
        if (count > 0) eglQueryDevicesEXT(count, devices.data(), &count);
        why_device = "no hardware EGL device";
        // The CUDA device's own GL device first (EGL_NV_device_cuda names it), the others after.
        const auto cudaOrdinal = [](EGLDeviceEXT device) -> EGLAttrib {
            EGLAttrib ordinal = -1;
            if (!hasExtension(eglQueryDeviceStringEXT(device, EGL_EXTENSIONS), "EGL_NV_device_cuda") ||
                !eglQueryDeviceAttribEXT(device, EGL_CUDA_DEVICE_NV, &ordinal))
                return -1;
            return ordinal;
        };
        if (cuda_device >= 0)
            std::stable_partition(devices.begin(), devices.end(),
                                  [&](EGLDeviceEXT d) { return cudaOrdinal(d) == cuda_device; });
        for (EGLDeviceEXT device : devices) {
            // Mesa marks its software device; llvmpipe is better reached through surfaceless.
            if (hasExtension(eglQueryDeviceStringEXT(device, EGL_EXTENSIONS), "EGL_MESA_device_software")) continue;
            EGLDisplay display = eglGetPlatformDisplayEXT(EGL_PLATFORM_DEVICE_EXT, device, nullptr);
            if (display == EGL_NO_DISPLAY) continue;
            if (EGLContext context = makeContext(display, why_device); context != EGL_NO_CONTEXT) {
                display_ = display;
                context_ = context;
                const EGLAttrib ordinal = cudaOrdinal(device);
                description_ = ordinal >= 0 ? "EGL device (CUDA device " + std::to_string(ordinal) + ")" : "EGL device";
                break;
            }
        }
    }
    if (!context_ && hasExtension(client, "EGL_MESA_platform_surfaceless")) {
        EGLDisplay display = eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
        if (display == EGL_NO_DISPLAY) {
            why_surfaceless = "eglGetPlatformDisplay(surfaceless) failed";
        } else if (EGLContext context = makeContext(display, why_surfaceless); context != EGL_NO_CONTEXT) {
            display_ = display;
            context_ = context;
            description_ = "EGL surfaceless";
        }
    }
    if (!context_)
        throw SystemError("OpenGL: no headless OpenGL 4.5 context: EGL device platform: " + why_device +
                          "; surfaceless platform: " + why_surfaceless +
                          " (install libegl1 and libgl1-mesa-dri, or run launch/setup)");
    description_ += std::string(", ") + reinterpret_cast<const char*>(glGetString(GL_RENDERER));
}

HeadlessContext::~HeadlessContext() {
    eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    eglDestroyContext(display_, context_);
    eglTerminate(display_);
}

}  // namespace occ::render
