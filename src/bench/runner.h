// SPDX-License-Identifier: MIT
#pragma once

// What the benchmarks that run occswitch as child processes share (bench all, bench massive):
// a runner that times a child, stops it on a timeout or Ctrl-C and reports its peak memory, and
// the per-frame stats of a render run.

#include "scene/csv.h"
#include "scene/errors.h"
#include "util/number_format.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace occ::bench {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// Set by the benchmarks' SIGINT/SIGTERM handler; the runner stops its child when it sees it.
inline volatile std::sig_atomic_t g_interrupted = 0;

// While alive, SIGINT and SIGTERM set g_interrupted instead of ending the process (the runner
// then stops its child's whole process group and reports it); the old handlers come back after.
class InterruptHandlers {
public:
    InterruptHandlers() {
        struct sigaction action {};
        action.sa_handler = [](int) { g_interrupted = 1; };
        sigemptyset(&action.sa_mask);
        ::sigaction(SIGINT, &action, &old_int_);
        ::sigaction(SIGTERM, &action, &old_term_);
    }
    ~InterruptHandlers() {
        ::sigaction(SIGINT, &old_int_, nullptr);
        ::sigaction(SIGTERM, &old_term_, nullptr);
    }
    InterruptHandlers(const InterruptHandlers&) = delete;
    InterruptHandlers& operator=(const InterruptHandlers&) = delete;

private:
    struct sigaction old_int_ {}, old_term_ {};
};

inline std::string secondsText(double v) {
    char b[32];
    std::snprintf(b, sizeof b, "%.0f", v);
    return b;
}

inline std::string readText(const fs::path& path) {
    std::ifstream f(path, std::ios::binary);
    std::stringstream ss;
    ss << f.rdbuf();
    return ss.str();
}

// The last `n` lines of a log, indented, for an error report.
inline std::string tailOf(const fs::path& log, size_t n) {
    std::vector<std::string> lines;
    std::istringstream in(readText(log));
    for (std::string line; std::getline(in, line);) {
        // Progress bars redraw with carriage returns; keep what was drawn last.
        const size_t cr = line.find_last_of('\r');
        if (cr != std::string::npos) line = line.substr(cr + 1);
        if (!line.empty()) lines.push_back(line);
    }
    std::string out;
    for (size_t i = lines.size() > n ? lines.size() - n : 0; i < lines.size(); ++i) out += "    " + lines[i] + "\n";
    return out;
}

inline std::string findInPath(const std::string& name) {
    const char* path = std::getenv("PATH");
    if (!path) return {};
    std::istringstream in(path);
    for (std::string dir; std::getline(in, dir, ':');) {
        const fs::path candidate = fs::path(dir.empty() ? "." : dir) / name;
        if (::access(candidate.c_str(), X_OK) == 0) return candidate.string();
    }
    return {};
}


// The occswitch the benchmark's child runs start: $OCCSWITCH_SELF where set (launch/gpu-check's
// bundle runs the binary through its own dynamic loader, so /proc/self/exe names the loader,
// not occswitch, and the bundle's wrapper script says which command starts this build), else
// this process's executable.
inline std::string selfExecutable() {
    const char* self = std::getenv("OCCSWITCH_SELF");
    if (self && *self) return self;
    return fs::read_symlink("/proc/self/exe").string();
}

struct RunResult {
    double seconds = 0;
    double peak_mb = 0;  // largest resident set of the child (and of children it waited for)
    fs::path log;
};

// The largest resident set of a process so far (VmHWM in /proc/<pid>/status), in MiB; -1 when
// it cannot be read (the process is gone).
inline double residentHighWaterMb(const std::string& pid) {
    std::ifstream in("/proc/" + pid + "/status");
    std::string line;
    while (std::getline(in, line))
        if (line.rfind("VmHWM:", 0) == 0) return std::atof(line.c_str() + 6) / 1024.0;
    return -1.0;
}

// Runs the steps of the benchmark as child processes in their own process group, stdout and
// stderr into a log each, so that a timeout or Ctrl-C stops a whole mpirun job and a failure
// can be reported with the lines that explain it.
class Runner {
public:
    Runner(fs::path logs, double timeout_s, std::string label = "bench all")
        : logs_(std::move(logs)), timeout_s_(timeout_s), label_(std::move(label)) {}

    RunResult run(const std::string& name, const std::vector<std::string>& argv) {
        RunResult r;
        r.log = logs_ / (name + ".log");
        {
            std::ofstream header(r.log, std::ios::trunc);
            header << "#";
            for (const std::string& a : argv) header << ' ' << a;
            header << "\n";
            if (!header) throw InputError(r.log.string(), "cannot write the log");
        }
        posix_spawn_file_actions_t actions;
        posix_spawn_file_actions_init(&actions);
        posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
        posix_spawn_file_actions_addopen(&actions, 1, r.log.c_str(), O_WRONLY | O_APPEND, 0644);
        posix_spawn_file_actions_adddup2(&actions, 1, 2);
        posix_spawnattr_t attributes;
        posix_spawnattr_init(&attributes);
        posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETPGROUP);
        posix_spawnattr_setpgroup(&attributes, 0);
        std::vector<char*> args;
        for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
        args.push_back(nullptr);
        pid_t pid = 0;
        // A child that posix_spawn starts shares this process's memory until it execs, and Linux
        // carries that memory's high-water mark into the child's ru_maxrss: ru_maxrss is the
        // child's own peak only where it is above this process's; otherwise the child's own
        // high-water mark, read while it runs, is (bench massive's runs after it mapped the 10^6
        // plant all said 6 772 MB).
        const double own_mb = residentHighWaterMb("self");
        double polled_mb = -1.0;
        const auto start = Clock::now();
        const int rc = ::posix_spawnp(&pid, args[0], &actions, &attributes, args.data(), environ);
        posix_spawn_file_actions_destroy(&actions);
        posix_spawnattr_destroy(&attributes);
        if (rc != 0) throw SystemError(label_ + ": " + name + ": cannot start " + argv[0] + ": " + std::strerror(rc));

        int status = 0;
        struct rusage usage {};
        for (;;) {
            polled_mb = std::max(polled_mb, residentHighWaterMb(std::to_string(pid)));
            const pid_t w = ::wait4(pid, &status, WNOHANG, &usage);
            if (w == pid) break;
            if (w < 0 && errno != EINTR)
                throw SystemError(label_ + ": " + name + ": wait failed: " + std::strerror(errno));
            const double elapsed = std::chrono::duration<double>(Clock::now() - start).count();
            if (g_interrupted || elapsed > timeout_s_) {
                stop(pid);
                if (g_interrupted) throw SystemError(label_ + ": interrupted during " + name + " (log: " + r.log.string() + ")");
                throw SystemError(label_ + ": " + name + " took more than " + secondsText(timeout_s_) +
                                  " s and was stopped; its log: " + r.log.string());
            }
            std::this_thread::sleep_for(std::chrono::milliseconds(20));
        }
        r.seconds = std::chrono::duration<double>(Clock::now() - start).count();
        const double maxrss_mb = double(usage.ru_maxrss) / 1024.0;  // Linux reports kilobytes
        r.peak_mb = maxrss_mb > own_mb || polled_mb < 0.0 ? maxrss_mb : polled_mb;
        if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
            const std::string how = WIFEXITED(status) ? "exit status " + std::to_string(WEXITSTATUS(status))
                                                      : "signal " + std::to_string(WTERMSIG(status));
            std::fprintf(stderr, "%s: %s failed; the end of %s:\n%s", label_.c_str(), name.c_str(), r.log.c_str(),
                         tailOf(r.log, 8).c_str());
            throw SystemError(label_ + ": " + name + " failed (" + how + "); its log: " + r.log.string());
        }
        return r;
    }

private:
    static void stop(pid_t pid) {
        ::kill(-pid, SIGTERM);
        int status = 0;
        for (int i = 0; i < 250; ++i) {  // 5 s for mpirun to stop its ranks
            if (::waitpid(pid, &status, WNOHANG) == pid) {
                ::kill(-pid, SIGKILL);  // anything of the group that outlived it
                return;
            }
            std::this_thread::sleep_for(std::chrono::milliseconds(20));
        }
        ::kill(-pid, SIGKILL);
        ::waitpid(pid, &status, 0);
    }

    fs::path logs_;
    double timeout_s_;
    std::string label_;
};

// ---------------------------------------------------------------------------------------------
// CSV files the runs write

// The per-frame stats of one `render` run. Means are over the display's (rank 0's) frames
// without the first, which streams the whole first view and warms every cache.
struct RenderStats {
    explicit RenderStats(const fs::path& path) : csv(CsvTable::read(path.string())) {
        const bool ranked = csv.has("rank");
        for (size_t r = 0; r < csv.rows(); ++r)
            if (!ranked || csv.text(r, csv.col("rank")) == "0") display.push_back(r);
        if (display.empty()) throw InputError(path.string(), "no rows of rank 0");
        std::sort(display.begin(), display.end(),
                  [&](size_t a, size_t b) { return csv.num(a, "frame") < csv.num(b, "frame"); });
        measured.assign(display.size() > 1 ? display.begin() + 1 : display.begin(), display.end());
    }
    double mean(const std::string& column) const {
        const size_t c = csv.col(column);
        double sum = 0;
        size_t n = 0;
        for (size_t r : measured) {
            const double v = csv.num(r, c);
            if (std::isfinite(v)) sum += v, ++n;
        }
        return n ? sum / double(n) : NAN;
    }
    // What a frame of the display takes: the pipeline stages it runs plus drawing.
    double frameMs(size_t row) const {
        return csv.num(row, "ms_total") + (csv.has("ms_draw") ? csv.num(row, "ms_draw") : 0.0);
    }
    double meanFrameMs() const {
        double total = 0;
        for (size_t r : measured) total += frameMs(r);
        return total / double(measured.size());
    }
    // The median over the measured frames of the sum of `columns` (columns this run lacks count
    // 0; NaN when no frame was measured).
    double median(std::initializer_list<const char*> columns) const {
        std::vector<double> v;
        for (size_t r : measured) {
            double sum = 0;
            for (const char* c : columns)
                if (csv.has(c)) sum += csv.num(r, c);
            v.push_back(sum);
        }
        return medianOf(v);
    }
    double medianFrameMs() const {
        std::vector<double> v;
        for (size_t r : measured) v.push_back(frameMs(r));
        return medianOf(v);
    }
    // The occlusion stage: choosing the occluders, their depth raster, the HZM build and the test.
    double medianOcclusionMs() const {
        return median({"ms_occluder_select", "ms_depth_raster", "ms_hzm_build", "ms_hzm_test"});
    }
    // The cores a render run has (its kernels use all of them): the "per core" of the rates.
    static unsigned cores() { return std::max(1u, std::thread::hardware_concurrency()); }
    // The depth raster's occluder triangles per second per core (`cores` of them, as the render
    // run had), median over the measured frames that rastered any; NaN when none did.
    double medianRasterRatePerCore(unsigned cores = RenderStats::cores()) const {
        std::vector<double> v;
        if (!csv.has("occluder_triangles") || !csv.has("ms_depth_raster")) return NAN;
        for (size_t r : measured) {
            const double ms = csv.num(r, "ms_depth_raster"), tris = csv.num(r, "occluder_triangles");
            if (ms > 0 && tris > 0) v.push_back(tris / (ms / 1000.0) / double(std::max(1u, cores)));
        }
        return medianOf(v);
    }
    static double medianOf(std::vector<double> v) {
        if (v.empty()) return NAN;
        std::sort(v.begin(), v.end());
        return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
    }
    CsvTable csv;
    std::vector<size_t> display;   // rank 0's rows in frame order
    std::vector<size_t> measured;  // the same without frame 0
};

}  // namespace occ::bench
