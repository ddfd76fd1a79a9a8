// SPDX-License-Identifier: MIT
#include "cli/commands.h"
#include "device_memory.h"
#include "scene/errors.h"

#include <algorithm>
#include <cstdio>
#include <new>
#include <string>

namespace {

constexpr int kExitInputError = 2;

// Prints "error: " + what as one line in one write: under mpirun the ranks share stderr, and
// pieces written one by one interleave with another rank's line.
int fail(const std::string& what, int status) {
    const std::string line = "error: " + what + "\n";
    std::fwrite(line.data(), 1, line.size(), stderr);
    std::fflush(stderr);
    return status;
}

// The command-line flag of a library parameter (OptionError::option()): its name with dashes,
// but for the two whose flags differ.
std::string flagFor(std::string option) {
    if (option == "viewport") return "--size";
    if (option == "tiles") return "--nx/--ny/--nz";
    std::replace(option.begin(), option.end(), '_', '-');
    return "--" + option;
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"occswitch: interactive rendering of massive CAD models with occlusion culling,\n"
                 "per-object progressive meshes and occlusion-switch MPI ranks."};
    app.require_subcommand(1);
    app.set_version_flag("--version", std::string("occswitch 0.1"));

    const std::vector<occ::cli::Command> commands{occ::cli::addInfoCommand(app), occ::cli::addGenCommand(app),
                                                   occ::cli::addPrepCommand(app), occ::cli::addVerifyCommand(app),
                                                   occ::cli::addPathCommand(app), occ::cli::addRenderCommand(app),
                                                   occ::cli::addBenchCommand(app)};

    try {
        app.parse(argc, argv);
        for (const occ::cli::Command& command : commands)
            if (command.app->parsed()) return command.run();
    } catch (const CLI::Success& e) {
        return app.exit(e);
    } catch (const CLI::ParseError& e) {
        return fail(std::string(e.what()) + " (see occswitch --help)", kExitInputError);
    } catch (const occ::InputError& e) {
        return fail(e.what(), kExitInputError);
    } catch (const occ::OptionError& e) {
        // The library names its parameter; the user typed a flag.
        return fail(flagFor(e.option()) + " " + e.detail(), kExitInputError);
    } catch (const occ::UsageError& e) {
        return fail(e.what(), kExitInputError);
    } catch (const occ::SystemError& e) {
        return fail(e.what(), 1);
    } catch (const std::bad_alloc& e) {
        // A device algorithm's temporary storage that did not fit (Thrust's bad_alloc under
        // CUDA) is the machine's limit; the host's own allocations stay "out of memory".
        const std::string device = occ::k::deviceErrorText(e);
        if (!device.empty()) return fail(device, 1);
        return fail("out of memory", kExitInputError);
    } catch (const std::exception& e) {
        // A device algorithm's failure (Thrust's system_error under CUDA) is the machine's.
        const std::string device = occ::k::deviceErrorText(e);
        if (!device.empty()) return fail(device, 1);
        // Anything else is our bug, not the input's; still one line and a failing status.
        return fail(std::string("internal: ") + e.what(), 1);
    }
    return 0;
}
