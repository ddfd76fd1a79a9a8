// SPDX-License-Identifier: MIT
#include "cli/commands.h"
#include "device_memory.h"
#include "scene/errors.h"

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <new>
#include <string>

namespace {

constexpr int kExitInputError = 2;

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
        std::cerr << "error: " << e.what() << " (see occswitch --help)\n";
        return kExitInputError;
    } catch (const occ::InputError& e) {
        std::cerr << "error: " << e.what() << "\n";
        return kExitInputError;
    } catch (const occ::OptionError& e) {
        // The library names its parameter; the user typed a flag.
        std::cerr << "error: " << flagFor(e.option()) << " " << e.detail() << "\n";
        return kExitInputError;
    } catch (const occ::UsageError& e) {
        std::cerr << "error: " << e.what() << "\n";
        return kExitInputError;
    } catch (const occ::SystemError& e) {
        std::cerr << "error: " << e.what() << "\n";
        return 1;
    } catch (const std::bad_alloc&) {
        std::cerr << "error: out of memory\n";
        return kExitInputError;
    } catch (const std::exception& e) {
        // A device algorithm's failure (Thrust's system_error under CUDA) is the machine's.
        const std::string device = occ::k::deviceErrorText(e);
        if (!device.empty()) {
            std::cerr << "error: " << device << "\n";
            return 1;
        }
        // Anything else is our bug, not the input's; still one line and a failing status.
        std::cerr << "error: internal: " << e.what() << "\n";
        return 1;
    }
    return 0;
}
