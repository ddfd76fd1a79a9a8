// SPDX-License-Identifier: MIT
#include "render/window.h"

#include "device_memory.h"

#include "render/frame_display.h"
#include "render/gl_check.h"
#include "render/png_writer.h"
#include "render/sort_last.h"
#include "view/camera_path.h"
#include "util/number_format.h"

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include <glm/gtc/matrix_transform.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <thread>
#include <utility>

namespace occ::render {

namespace {

using Clock = std::chrono::steady_clock;

const char* modeName(CullMode m) { return m == CullMode::Full ? "full" : m == CullMode::Lod ? "lod" : "oc+lod"; }

// Input gathered by GLFW's callbacks between two pumps.
struct Input {
    double scroll = 0;
    std::vector<int> pressed;  // keys pressed (not held) since the last pump
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

// The window and what the user does in it, for either driver below: the one-rank loop and the
// display rank of the switch. Keys F, R, P and Esc are handled here; the mode keys are given to
// the driver (takeMode).
class Session {
public:
    Session(const OssFile& file, const WindowOptions& wo) : wo_(wo) {
        if (!glfwInit()) {
            const char* why = nullptr;
            glfwGetError(&why);
            throw WindowUnavailable(std::string("window: GLFW cannot start (") + (why ? why : "no reason given") +
                                    "); without an X display render headless (EGL) or under xvfb-run");
        }
        glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
        glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 5);
        glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
        glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
        window_ = glfwCreateWindow(int(wo.width), int(wo.height), "occswitch", nullptr, nullptr);
        if (!window_) {
            const char* why = nullptr;
            glfwGetError(&why);
            glfwTerminate();
            throw WindowUnavailable(std::string("window: no OpenGL 4.5 core window (") +
                                    (why ? why : "no reason given") +
                                    "); the X server needs GLX and a 24-bit screen, or render headless (EGL)");
        }
        glfwMakeContextCurrent(window_);
        // CUDA-OpenGL interop registers the display's buffers on the CUDA device: the window's
        // context must be on it (on a workstation with several GPUs the X screen's may not be).
        k::matchGlContextDevice(wo.device);
        glfwSwapInterval(0);
        glfwSetWindowUserPointer(window_, &input_);
        glfwSetKeyCallback(window_, onKey);
        glfwSetScrollCallback(window_, onScroll);

        if (!wo.path.empty()) path_ = readCameraPath(wo.path);
        // Without a path, start where an orbit of the scene starts: outside, looking at its middle.
        const PathScene scene = pathSceneOf(file);
        const std::vector<CameraPose> start = path_.empty() ? orbitPath(scene, 1) : path_;
        fly_.lookAlong(start.front());
        k::Aabb bounds{glm::vec3(1e30f), glm::vec3(-1e30f)};
        for (const k::Aabb& b : scene.objects)
            bounds.min = glm::min(bounds.min, b.min), bounds.max = glm::max(bounds.max, b.max);
        fly_.speed = scene.objects.empty() ? 1.0f : 0.1f * glm::length(bounds.max - bounds.min);
        glfwGetCursorPos(window_, &last_x_, &last_y_);
        last_ = title_time_ = Clock::now();
    }
    Session(const Session&) = delete;
    Session& operator=(const Session&) = delete;
    // The drivers destroy their displays first: those still need the window's context.
    ~Session() {
        if (composite_fbo_) glDeleteFramebuffers(1, &composite_fbo_);
        if (composite_texture_) glDeleteTextures(1, &composite_texture_);
        glfwDestroyWindow(window_);
        glfwTerminate();
    }

    void printStart(const std::string& extra) const {
        std::printf("window: %ux%u, %s%s; keys: drag = look, WASD/QE = move, scroll = speed, 1/2/3 = mode, "
                    "F = freeze, R = record, P = screenshot, Esc = quit\n",
                    wo_.width, wo_.height, reinterpret_cast<const char*>(glGetString(GL_RENDERER)), extra.c_str());
        std::fflush(stdout);
    }

    // Takes the events since the last call: keys, mouse look and the motion of held keys.
    // Returns false once the user has quit (Esc or the window closed).
    bool pump() {
        glfwPollEvents();
        const auto now = Clock::now();
        const float dt = std::min(0.25f, std::chrono::duration<float>(now - last_).count());
        last_ = now;
        for (int key : input_.pressed) {
            switch (key) {
            case GLFW_KEY_ESCAPE: glfwSetWindowShouldClose(window_, GLFW_TRUE); break;
            case GLFW_KEY_1: mode_ = CullMode::Full; break;
            case GLFW_KEY_2: mode_ = CullMode::Lod; break;
            case GLFW_KEY_3: mode_ = CullMode::OcLod; break;
            case GLFW_KEY_F:
                if (!freeze_refusal_.empty()) {
                    std::printf("window: %s\n", freeze_refusal_.c_str());
                    break;
                }
                frozen_ = !frozen_;
                std::printf("window: culling %s\n", frozen_ ? "frozen" : "live");
                break;
            case GLFW_KEY_R:
                if (recording_) writeRecording();
                recording_ = !recording_;
                if (recording_) std::printf("window: recording\n");
                break;
            case GLFW_KEY_P: screenshot_ = true; break;
            default: break;
            }
        }
        input_.pressed.clear();
        if (input_.scroll != 0) fly_.speed *= std::pow(1.25f, float(input_.scroll)), input_.scroll = 0;

        // Mouse look while the left button is held; keys move along the view.
        double x = 0, y = 0;
        glfwGetCursorPos(window_, &x, &y);
        if (glfwGetMouseButton(window_, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS) {
            fly_.yaw += 0.2f * float(x - last_x_);
            fly_.pitch = glm::clamp(fly_.pitch - 0.2f * float(y - last_y_), -89.0f, 89.0f);
        }
        last_x_ = x, last_y_ = y;
        const glm::vec3 f = fly_.forward(), right = glm::normalize(glm::cross(f, glm::vec3(0, 1, 0)));
        const auto held = [&](int k) { return glfwGetKey(window_, k) == GLFW_PRESS; };
        glm::vec3 move(0.0f);
        if (held(GLFW_KEY_W)) move += f;
        if (held(GLFW_KEY_S)) move -= f;
        if (held(GLFW_KEY_D)) move += right;
        if (held(GLFW_KEY_A)) move -= right;
        if (held(GLFW_KEY_E)) move.y += 1;
        if (held(GLFW_KEY_Q)) move.y -= 1;
        flying_ = move != glm::vec3(0.0f);
        if (flying_) fly_.eye += move * fly_.speed * dt;
        std::fflush(stdout);
        return !glfwWindowShouldClose(window_);
    }

    // The camera of the next frame: the path's next pose until a key moves the camera or the
    // path ends, then the fly camera's. Recorded while recording.
    CameraPose nextPose() {
        CameraPose pose = fly_.pose();
        if (path_frame_ < path_.size() && !flying_) {
            pose = path_[path_frame_++];
            fly_.lookAlong(pose);
        } else {
            path_frame_ = path_.size();
        }
        if (recording_) recorded_.push_back(pose);
        return pose;
    }

    bool frozen() const { return frozen_; }
    // Where the user looks now (between frames: no path step, nothing recorded).
    CameraPose flyPose() const { return fly_.pose(); }
    k::Camera camera(const CameraPose& pose) const { return toKernelCamera(pose, wo_.width, wo_.height); }

    // A mode key pressed since the last call, if any.
    std::optional<CullMode> takeMode() { return std::exchange(mode_, std::nullopt); }

    // Shows the picture in `target` (a screenshot first when P was pressed).
    void present(FrameTarget& target) {
        if (screenshot_) {
            std::vector<uint8_t> rgb;
            target.readColour(rgb);
            writeScreenshot(rgb);
        }
        blit(target.framebuffer());
    }

    // Shows a picture made elsewhere (3 * W * H bytes, bottom row first: a sort-last composite).
    void present(const std::vector<uint8_t>& rgb) {
        if (screenshot_) writeScreenshot(rgb);
        if (!composite_texture_) {
            glCreateTextures(GL_TEXTURE_2D, 1, &composite_texture_);
            glTextureStorage2D(composite_texture_, 1, GL_RGBA8, GLsizei(wo_.width), GLsizei(wo_.height));
            glCreateFramebuffers(1, &composite_fbo_);
            glNamedFramebufferTexture(composite_fbo_, GL_COLOR_ATTACHMENT0, composite_texture_, 0);
        }
        glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
        glTextureSubImage2D(composite_texture_, 0, 0, 0, GLsizei(wo_.width), GLsizei(wo_.height), GL_RGB,
                            GL_UNSIGNED_BYTE, rgb.data());
        blit(composite_fbo_);
    }

    // F then says this instead of freezing (a layout that cannot draw a frozen frame).
    void refuseFreeze(std::string why) { freeze_refusal_ = std::move(why); }

    // Counts a new frame and, every half second, sets the title: fps, then `what`, then the
    // frozen and recording marks.
    void frameShown(const std::function<std::string()>& what) {
        ++title_frames_;
        const auto now = Clock::now();
        const double since = std::chrono::duration<double>(now - title_time_).count();
        if (since < 0.5) return;
        const std::string title = "occswitch  " + fixed(double(title_frames_) / since, 1) + " fps  " + what() +
                                  (frozen_ ? "  [frozen]" : "") + (recording_ ? "  [recording]" : "");
        glfwSetWindowTitle(window_, title.c_str());
        title_time_ = now;
        title_frames_ = 0;
    }

    // At the end: a recording still running is written.
    void finish() {
        if (recording_ && !recorded_.empty()) writeRecording();
        recording_ = false;
    }

private:
    void writeScreenshot(const std::vector<uint8_t>& rgb) {
        screenshot_ = false;
        const std::string name = nextFreeName(wo_.out, "screenshot", ".png");
        writePng(name, wo_.width, wo_.height, 3, rgb.data());
        std::printf("window: screenshot %s\n", name.c_str());
        std::fflush(stdout);
    }

    void blit(GLuint framebuffer) {
        int fw = 0, fh = 0;
        glfwGetFramebufferSize(window_, &fw, &fh);
        glBlitNamedFramebuffer(framebuffer, 0, 0, 0, GLint(wo_.width), GLint(wo_.height), 0, 0, fw, fh,
                               GL_COLOR_BUFFER_BIT, GL_LINEAR);
        checkGlError("presenting the frame", __FILE__, __LINE__);
        glfwSwapBuffers(window_);
    }

    void writeRecording() {
        const std::string name = nextFreeName(wo_.out, "recorded", ".cam");
        writeCameraPath(name, recorded_);
        std::printf("window: recorded %zu poses to %s\n", recorded_.size(), name.c_str());
        recorded_.clear();
    }

    WindowOptions wo_;
    GLFWwindow* window_ = nullptr;
    Input input_;
    FlyCamera fly_;
    std::vector<CameraPose> path_, recorded_;
    size_t path_frame_ = 0;
    bool frozen_ = false, recording_ = false, flying_ = false, screenshot_ = false;
    std::optional<CullMode> mode_;
    std::string freeze_refusal_;
    GLuint composite_texture_ = 0, composite_fbo_ = 0;
    double last_x_ = 0, last_y_ = 0;
    Clock::time_point last_, title_time_;
    uint64_t title_frames_ = 0;
};

}  // namespace

std::vector<FrameRecord> runWindow(Transport& transport, const OssFile& file, const PipelineOptions& options,
                                   const WindowOptions& wo, roles::RunOptions run, roles::RunSummary& summary) {
    Session session(file, wo);
    std::unique_ptr<FrameDisplay> display;  // made with the pipeline of the first frame
    Pipeline* shown = nullptr;              // the pipeline whose frame the display holds
    const int ranks = transport.size();
    const roles::RankLayout layout(ranks);
    // Sort-last (2 + P ranks): the window shows the composite of every display rank's partition.
    std::unique_ptr<SortLastCompositor> compositor;
    const std::vector<uint8_t>* composite = nullptr;
    DisplayOptions display_options;
    display_options.colours = wo.colours;
    if (layout.displays() > 1) {
        compositor = std::make_unique<SortLastCompositor>(transport, layout.displayRanks(), run.timeout);
        display_options.items = true;
        session.refuseFreeze("F (freeze) needs 1 to 3 ranks: with " + std::to_string(ranks) +
                             " each display rank holds only its partition of the frame");
    }
    const auto show = [&] {
        if (composite) session.present(*composite);
        else session.present(display->target());
    };
    // Each frame's camera and when it was taken from the user (the latency's start).
    std::vector<int64_t> taken_ns;
    CameraPose sent, view;  // the newest camera sent; where the user looks (the view of a frozen frame)
    double latency_ms = 0;
    uint64_t latency_frames = 0, latency_count = 0;
    std::optional<CullMode> mode;  // a mode key not applied yet (one rank)
    const auto now_ns = [] {
        return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch()).count();
    };
    Clock::time_point presented = Clock::now();
    // While a culling rank (or, sort-last, another display rank) works: the window answers, and
    // shows the newest complete frame about 60 times a second.
    const auto answer = [&] {
        session.pump();
        if (!display || (compositor && !composite) || Clock::now() - presented < std::chrono::milliseconds(16)) return;
        if (session.frozen() && shown) display->drawCullingView(*shown, session.camera(session.flyPose()));
        show();
        presented = Clock::now();
    };

    // One rank: the last frame's figures, for the title while frozen.
    uint64_t last_visible = 0, last_triangles = 0;
    const auto takeModeKey = [&] {
        if (const std::optional<CullMode> m = session.takeMode()) {
            if (ranks == 1) mode = m;
            else
                std::printf("window: the mode keys need one rank; with %d ranks the mode is --mode (%s)\n", ranks,
                            modeName(options.mode));
        }
    };
    // The camera source: the user's newest pose when the frame loop asks (a camera buffer of one).
    run.live = true;
    run.next_camera = [&](uint64_t f, CameraPose& pose) {
        if (!session.pump()) return false;
        takeModeKey();
        // One rank, frozen: no frame runs; the window draws the frozen frame, with its occluders,
        // from where the user flies, until F again (with more ranks the switch goes on culling
        // the frozen camera, see the sink).
        while (ranks == 1 && session.frozen() && shown) {
            const CameraPose at = session.nextPose();
            display->drawCullingView(*shown, session.camera(at));
            session.present(display->target());
            session.frameShown([&] {
                return std::to_string(last_visible) + " visible objects  " + std::to_string(last_triangles) +
                       " triangles  " + modeName(shown->mode());
            });
            std::fflush(stdout);
            if (!session.pump()) return false;
            takeModeKey();
        }
        // One rank: this pipeline culls the next frame; the mode changes before it.
        if (mode && shown) {
            shown->setMode(*mode);
            std::printf("window: mode %s\n", modeName(*mode));
            mode.reset();
        }
        view = session.nextPose();
        // A frozen frame stays what it was: the culling goes on with the camera it had.
        if (!session.frozen() || f == 0) sent = view;
        pose = sent;
        if (taken_ns.size() != f) throw std::logic_error("runWindow: cameras out of order");
        taken_ns.push_back(now_ns());
        return true;
    };
    // The frame sink: draws the frame (or, frozen, the frozen frame from where the user flies),
    // presents it and sets the title.
    run.draw = [&](Pipeline& pipeline, const CameraPose& pose, uint64_t f, const FrameStats& stats) {
        if (!display) display = std::make_unique<FrameDisplay>(pipeline, wo.width, wo.height, display_options);
        shown = &pipeline;
        DisplayStats drawn;
        if (session.frozen()) display->drawCullingView(pipeline, session.camera(view));
        else drawn = display->display(pipeline, pose);
        if (compositor) composite = compositor->composite(*display, answer);
        show();
        presented = Clock::now();
        if (ranks == 1) {
            last_visible = stats.objects_visible;
            last_triangles = stats.active_triangles;
            session.frameShown([&] {
                return std::to_string(stats.objects_visible) + " visible objects  " +
                       std::to_string(stats.active_triangles) + " triangles  " + modeName(pipeline.mode());
            });
            std::fflush(stdout);
            return drawn;
        }
        // The camera of frame f + 1 (or later) was taken before frame f is drawn.
        const double ms = double(now_ns() - taken_ns.at(f)) / 1e6;
        const uint64_t frames = taken_ns.size() - 1 - f;
        // The last frame has no later camera (the user quit): its 0 frames are no latency.
        if (f > 0 && frames > 0) latency_ms += ms, latency_frames += frames, ++latency_count;
        const size_t visible = pipeline.visibleObjects().size();
        session.frameShown([&] {
            return std::to_string(ranks) + " ranks  latency " + std::to_string(frames) + " frame" +
                   (frames == 1 ? "" : "s") + " " + fixed(ms, 1) + " ms  " + std::to_string(visible) +
                   " visible objects  " + modeName(options.mode);
        });
        return drawn;
    };
    // Sleeping in between, so that the culling ranks get the CPU.
    run.idle = [&] {
        answer();
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    };
    session.printStart(ranks == 1 ? "" : ", " + std::to_string(ranks) + " ranks (rank 0 displays)");
    std::vector<FrameRecord> records = roles::runRanks(transport, file, options, run, summary);
    session.finish();
    if (ranks > 1)
        std::printf("window: %llu frames on %d ranks, latency %.2f frames and %.2f ms (mean of the frames after the "
                    "first)\n",
                    static_cast<unsigned long long>(summary.frames), ranks,
                    latency_count ? double(latency_frames) / double(latency_count) : 0.0,
                    latency_count ? latency_ms / double(latency_count) : 0.0);
    std::fflush(stdout);
    display.reset();
    return records;
}

}  // namespace occ::render
