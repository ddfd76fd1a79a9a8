// SPDX-License-Identifier: MIT
#include "cli/commands.h"
#include "scene/errors.h"

#include <cstdio>
#include <iostream>
#include <new>

namespace {

constexpr int kExitInputError = 2;

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
        // Anything else is our bug, not the input's; still one line and a failing status.
        std::cerr << "error: internal: " << e.what() << "\n";
        return 1;
    }
    return 0;
}
