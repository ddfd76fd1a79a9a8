// SPDX-License-Identifier: MIT
#include "render/window.h"

#include "render/frame_display.h"
#include "render/gl_check.h"
#include "render/png_writer.h"
#include "view/camera_path.h"

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include <glm/gtc/matrix_transform.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>

namespace occ::render {

namespace {

const char* modeName(CullMode m) { return m == CullMode::Full ? "full" : m == CullMode::Lod ? "lod" : "oc+lod"; }

// Input gathered by GLFW's callbacks between two frames.
struct Input {
    double scroll = 0;
    std::vector<int> pressed;  // keys pressed (not held) since the last frame
};

void onKey(GLFWwindow* w, int key, int, int action, int) {
    if (action == GLFW_PRESS) static_cast<Input*>(glfwGetWindowUserPointer(w))->pressed.push_back(key);
}

void onScroll(GLFWwindow* w, double, double dy) { static_cast<Input*>(glfwGetWindowUserPointer(w))->scroll += dy; }

std::string nextFreeName(const std::string& dir, const std::string& stem, const std::string& ext) {
    for (int i = 0;; ++i) {
        const std::string name = dir + "/" + stem + "_" + std::to_string(i) + ext;
        if (!std::filesystem::exists(name)) return name;
    }
}

// The fly camera: eye, yaw and pitch (degrees), speed in scene units per second.
struct FlyCamera {
    glm::vec3 eye{0.0f};
    float yaw = 0, pitch = 0, speed = 1;
    CameraPose base;  // fovy, near, far

    glm::vec3 forward() const {
        const float y = glm::radians(yaw), p = glm::radians(pitch);
        return {std::cos(p) * std::sin(y), std::sin(p), -std::cos(p) * std::cos(y)};
    }
    void lookAlong(const CameraPose& pose) {
        base = pose;
        eye = pose.eye;
        const glm::vec3 f = glm::normalize(pose.target - pose.eye);
        pitch = glm::degrees(std::asin(glm::clamp(f.y, -1.0f, 1.0f)));
        yaw = glm::degrees(std::atan2(f.x, -f.z));
    }
    CameraPose pose() const {
        CameraPose p = base;
        p.eye = eye;
        p.target = eye + forward();
        p.up = {0.0f, 1.0f, 0.0f};
        return p;
    }
};

}  // namespace

int runWindow(const OssFile& file, const PipelineOptions& options, const WindowOptions& wo) {
    if (!glfwInit()) {
        const char* why = nullptr;
        glfwGetError(&why);
        throw WindowUnavailable(std::string("window: GLFW cannot start (") + (why ? why : "no reason given") +
                          "); without an X display render headless (EGL) or under xvfb-run");
    }
    // Destroyed after the display below: its destructor still needs the window's context.
    struct Glfw {
        GLFWwindow* window = nullptr;
        ~Glfw() {
            if (window) glfwDestroyWindow(window);
            glfwTerminate();
        }
    } glfw;
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 5);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    GLFWwindow* window = glfw.window = glfwCreateWindow(int(wo.width), int(wo.height), "occswitch", nullptr, nullptr);
    if (!window) {
        const char* why = nullptr;
        glfwGetError(&why);
        throw WindowUnavailable(std::string("window: no OpenGL 4.5 core window (") + (why ? why : "no reason given") +
                          "); the X server needs GLX and a 24-bit screen, or render headless (EGL)");
    }
    glfwMakeContextCurrent(window);
    glfwSwapInterval(0);
    Input input;
    glfwSetWindowUserPointer(window, &input);
    glfwSetKeyCallback(window, onKey);
    glfwSetScrollCallback(window, onScroll);

    Pipeline pipeline(file, options);
    FrameDisplay display(pipeline, wo.width, wo.height, DisplayOptions{});
    std::printf("window: %ux%u, %s; keys: drag = look, WASD/QE = move, scroll = speed, 1/2/3 = mode, F = freeze, "
                "R = record, P = screenshot, Esc = quit\n",
                wo.width, wo.height, reinterpret_cast<const char*>(glGetString(GL_RENDERER)));

    std::vector<CameraPose> path;
    if (!wo.path.empty()) path = readCameraPath(wo.path);
    // Without a path, start where an orbit of the scene starts: outside, looking at its middle.
    const PathScene scene = pathSceneOf(file);
    const std::vector<CameraPose> start = path.empty() ? orbitPath(scene, 1) : path;
    FlyCamera fly;
    fly.lookAlong(start.front());
    k::Aabb bounds{glm::vec3(1e30f), glm::vec3(-1e30f)};
    for (const k::Aabb& b : scene.objects) bounds.min = glm::min(bounds.min, b.min), bounds.max = glm::max(bounds.max, b.max);
    fly.speed = scene.objects.empty() ? 1.0f : 0.1f * glm::length(bounds.max - bounds.min);

    bool frozen = false, recording = false;
    std::vector<CameraPose> recorded;
    size_t path_frame = 0;
    uint64_t frame = 0;
    double last_x = 0, last_y = 0;
    glfwGetCursorPos(window, &last_x, &last_y);
    auto last = std::chrono::steady_clock::now();
    auto title_time = last;
    uint64_t title_frames = 0;
    FrameStats stats;
    while (!glfwWindowShouldClose(window)) {
        glfwPollEvents();
        const auto now = std::chrono::steady_clock::now();
        const float dt = std::min(0.25f, std::chrono::duration<float>(now - last).count());
        last = now;

        for (int key : input.pressed) {
            switch (key) {
            case GLFW_KEY_ESCAPE: glfwSetWindowShouldClose(window, GLFW_TRUE); break;
            case GLFW_KEY_1:
            case GLFW_KEY_2:
            case GLFW_KEY_3: {
                const CullMode m = key == GLFW_KEY_1 ? CullMode::Full : key == GLFW_KEY_2 ? CullMode::Lod : CullMode::OcLod;
                pipeline.setMode(m);
                std::printf("window: mode %s\n", modeName(m));
                break;
            }
            case GLFW_KEY_F:
                frozen = !frozen;
                std::printf("window: culling %s\n", frozen ? "frozen" : "live");
                break;
            case GLFW_KEY_R:
                if (recording) {
                    const std::string name = nextFreeName(wo.out, "recorded", ".cam");
                    writeCameraPath(name, recorded);
                    std::printf("window: recorded %zu poses to %s\n", recorded.size(), name.c_str());
                    recorded.clear();
                }
                recording = !recording;
                if (recording) std::printf("window: recording\n");
                break;
            case GLFW_KEY_P: {
                // The target holds the last frame drawn, live or frozen; display.picture() would keep
                // the first frozen one.
                const std::string name = nextFreeName(wo.out, "screenshot", ".png");
                std::vector<uint8_t> rgb;
                display.target().readColour(rgb);
                writePng(name, wo.width, wo.height, 3, rgb.data());
                std::printf("window: screenshot %s\n", name.c_str());
                break;
            }
            default: break;
            }
        }
        input.pressed.clear();
        if (input.scroll != 0) fly.speed *= std::pow(1.25f, float(input.scroll)), input.scroll = 0;

        // Mouse look while the left button is held; keys move along the view.
        double x = 0, y = 0;
        glfwGetCursorPos(window, &x, &y);
        if (glfwGetMouseButton(window, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS) {
            fly.yaw += 0.2f * float(x - last_x);
            fly.pitch = glm::clamp(fly.pitch - 0.2f * float(y - last_y), -89.0f, 89.0f);
        }
        last_x = x, last_y = y;
        const glm::vec3 f = fly.forward(), right = glm::normalize(glm::cross(f, glm::vec3(0, 1, 0)));
        const auto held = [&](int k) { return glfwGetKey(window, k) == GLFW_PRESS; };
        glm::vec3 move(0.0f);
        if (held(GLFW_KEY_W)) move += f;
        if (held(GLFW_KEY_S)) move -= f;
        if (held(GLFW_KEY_D)) move += right;
        if (held(GLFW_KEY_A)) move -= right;
        if (held(GLFW_KEY_E)) move.y += 1;
        if (held(GLFW_KEY_Q)) move.y -= 1;
        const bool flying = move != glm::vec3(0.0f);
        if (flying) fly.eye += move * fly.speed * dt;

        // The path plays one pose per frame until a key moves the camera or it ends.
        CameraPose pose = fly.pose();
        if (path_frame < path.size() && !flying) {
            pose = path[path_frame++];
            fly.lookAlong(pose);
        } else {
            path_frame = path.size();
        }
        if (recording) recorded.push_back(pose);

        const k::Camera camera = toKernelCamera(pose, wo.width, wo.height);
        if (!frozen) {
            stats = pipeline.runFrame(pose, frame++);
            display.display(pipeline, pose);
        } else {
            // The frozen frame from where the camera is now, with what it culled.
            display.drawCullingView(pipeline, camera);
        }
        int fw = 0, fh = 0;
        glfwGetFramebufferSize(window, &fw, &fh);
        glBlitNamedFramebuffer(display.target().framebuffer(), 0, 0, 0, GLint(wo.width), GLint(wo.height), 0, 0, fw,
                               fh, GL_COLOR_BUFFER_BIT, GL_LINEAR);
        checkGlError("presenting the frame", __FILE__, __LINE__);
        glfwSwapBuffers(window);

        ++title_frames;
        const double since = std::chrono::duration<double>(now - title_time).count();
        if (since >= 0.5) {
            char title[256];
            std::snprintf(title, sizeof title, "occswitch  %.1f fps  %llu visible objects  %llu triangles  %s%s%s",
                          double(title_frames) / since, static_cast<unsigned long long>(stats.objects_visible),
                          static_cast<unsigned long long>(stats.active_triangles), modeName(pipeline.mode()),
                          frozen ? "  [frozen]" : "", recording ? "  [recording]" : "");
            glfwSetWindowTitle(window, title);
            title_time = now;
            title_frames = 0;
        }
        std::fflush(stdout);
    }
    if (recording && !recorded.empty()) {
        const std::string name = nextFreeName(wo.out, "recorded", ".cam");
        writeCameraPath(name, recorded);
        std::printf("window: recorded %zu poses to %s\n", recorded.size(), name.c_str());
    }
    return 0;
}

}  // namespace occ::render
