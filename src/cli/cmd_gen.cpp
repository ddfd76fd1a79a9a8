// SPDX-License-Identifier: MIT
#include "cli/commands.h"

#include "util/progress.h"

#include "import/glb_writer.h"
#include "import/grid.h"
#include "import/import.h"
#include "import/plant.h"
#include "scene/errors.h"

#include <chrono>
#include <filesystem>
#include <iostream>

namespace occ::cli {

namespace {


struct GenOptions {
    std::string model = kDefaultModel;
    GridOptions grid;
    PlantOptions plant;
    std::string out;
};

void checkOutputPath(const std::string& out) {
    const std::filesystem::path p(out);
    std::string ext = p.extension().string();
    if (ext != ".glb" && ext != ".gltf")
        throw UsageError("-o " + out + ": the output must be a .glb file (or .gltf, its buffer in a .bin beside it)");
    const std::filesystem::path dir = p.parent_path().empty() ? "." : p.parent_path();
    std::error_code ec;
    if (!std::filesystem::is_directory(dir, ec)) throw UsageError("-o " + out + ": folder " + dir.string() + " does not exist");
}

void report(const std::string& what, const std::string& out, const Scene& written_objects, uint64_t copies) {
    std::error_code ec;
    const auto bytes = std::filesystem::file_size(out, ec);
    std::cerr << "wrote " << out << ": " << what << ", " << written_objects.objects.size() * copies << " objects, "
              << written_objects.triangleCount() * copies << " triangles, " << (ec ? 0 : bytes) << " bytes\n";
}

int runGrid(const GenOptions& o) {
    checkOutputPath(o.out);
    const Scene model = importModel(o.model);
    writeGrid(o.out, model, o.grid);
    report(std::to_string(o.grid.nx) + "x" + std::to_string(o.grid.ny) + "x" + std::to_string(o.grid.nz) + " grid of " +
               o.model,
           o.out, model, uint64_t(o.grid.nx) * o.grid.ny * o.grid.nz);
    return 0;
}

int runPlant(const GenOptions& o) {
    checkOutputPath(o.out);
    plantLayout(o.plant);  // bad options fail before anything is written
    PlantProgress progress;
    const auto start = std::chrono::steady_clock::now();
    {
        ProgressBar bar("gen plant", "objects", "tri", [&] {
            return ProgressBar::Sample{double(progress.objects), double(o.plant.objects), double(progress.triangles)};
        });
        writePlant(o.out, o.plant, &progress);
    }
    std::error_code ec;
    const auto bytes = std::filesystem::file_size(o.out, ec);
    const auto bin = std::filesystem::file_size(std::filesystem::path(o.out).replace_extension(".bin"), ec);
    std::cerr << "wrote " << o.out << ": plant, seed " << o.plant.seed << ", " << progress.objects << " objects, "
              << progress.triangles << " triangles, " << bytes << " bytes"
              << (std::filesystem::path(o.out).extension() == ".gltf"
                      ? " + " + std::to_string(ec ? 0 : bin) + " in " +
                            std::filesystem::path(o.out).replace_extension(".bin").string()
                      : std::string())
              << ", " << std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() << " s\n";
    return 0;
}

}  // namespace

Command addGenCommand(CLI::App& app) {
    auto o = std::make_shared<GenOptions>();
    CLI::App* gen = app.add_subcommand("gen", "Write a procedural test scene as binary glTF (.glb).");
    gen->require_subcommand(1);

    CLI::App* grid = gen->add_subcommand(
        "grid", "Tile a model nx*ny*nz times by node instancing (meshes stored once).\n"
                "10x10x10 engines = 115 000 objects, 121 M triangles.");
    grid->add_option("--model", o->model, "model to tile (any importable file)")->capture_default_str();
    grid->add_option("--nx", o->grid.nx, "tiles along x")->capture_default_str();
    grid->add_option("--ny", o->grid.ny, "tiles along y")->capture_default_str();
    grid->add_option("--nz", o->grid.nz, "tiles along z")->capture_default_str();
    grid->add_option("--spacing", o->grid.spacing, "distance between tile origins (0 = 1.25 x model extent)")
        ->capture_default_str();
    grid->add_option("-o,--out", o->out, "output .glb file")->required();

    CLI::App* plant = gen->add_subcommand(
        "plant", "Procedural industrial plant: floors, walls, tanks, boxes, pipes, cable runs, girders.\n"
                 "Deterministic: same options, same bytes.");
    plant->add_option("--objects", o->plant.objects, "number of objects")->capture_default_str();
    plant->add_option("--seed", o->plant.seed, "random seed")->capture_default_str();
    plant->add_option("-o,--out", o->out, "output .glb file, or .gltf (+ .bin) for plants over the 4 GiB of a .glb")
        ->required();

    return {gen, [o, grid] { return grid->parsed() ? runGrid(*o) : runPlant(*o); }};
}

}  // namespace occ::cli
