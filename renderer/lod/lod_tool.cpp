// SPDX-License-Identifier: Apache-2.0
// fovea-lod: builds level-of-detail chains offline (Lee 2009, eq. 7.4: level L keeps base^-L of the
// triangles) and shows what a chain holds.
//
//   fovea-lod build MESH [--levels 5] [--base 4] [--attributes seams|weld] [--format obj|ply] --out DIR
//   fovea-lod info DIR
#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>

#include "lod/lod_chain.h"
#include "scene/scene_error.h"
#include "scene/mesh_io.h"

namespace fs = std::filesystem;
using namespace fovea::render;

namespace {

void print_chain(const lod::Chain& c) {
  std::printf("%-6s %10s %12s %14s %12s %8s\n", "level", "triangles", "target", "achieved", "error_m", "reached");
  for (std::size_t l = 0; l < c.levels.size(); ++l) {
    const lod::ChainLevel& v = c.levels[l];
    std::printf("%-6zu %10zu %12.6f %14.6f %12.6g %8s\n", l, v.mesh.triangle_count(), v.target_ratio, v.achieved_ratio,
                static_cast<double>(v.error_m), v.reached ? "yes" : "NO");
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"fovea-lod: level-of-detail chains for fovea-render (Lee 2009 eq. 7.4, meshoptimizer)"};
  app.set_version_flag("--version", "fovea-lod " FOVEA_VERSION);
  app.require_subcommand(1);
  CLI::App* build = app.add_subcommand("build", "simplify MESH into a chain: one mesh file per level and manifest.json");
  std::string mesh_path, out_dir, format = "obj", attributes = "seams";
  lod::ChainSettings s;
  build->add_option("mesh", mesh_path, "input mesh (OBJ, PLY, glTF)")->required();
  build->add_option("--levels", s.levels, "levels including the input (level 0)")->check(CLI::Range(1, 16));
  build->add_option("--base", s.base, "beta of eq. 7.4: level L keeps base^-L of the triangles")->check(CLI::Range(1.0001, 1e6));
  build->add_option("--attributes", attributes,
                    "seams: keep normal/UV seams (locked borders); weld: weld by position first (more reduction)")
      ->check(CLI::IsMember({"seams", "weld"}));
  build->add_option("--format", format, "level file format")->check(CLI::IsMember({"obj", "ply"}));
  build->add_option("--out", out_dir, "output directory (created; must be new or empty)")->required();
  CLI::App* info = app.add_subcommand("info", "print a chain's manifest");
  std::string info_dir;
  info->add_option("dir", info_dir, "a directory written by fovea-lod build")->required();
  CLI11_PARSE(app, argc, argv);

  try {
    if (*build) {
      s.attributes = attributes == "weld" ? lod::Attributes::Weld : lod::Attributes::Seams;
      std::error_code ec;
      if (fs::exists(out_dir, ec) && !fs::is_empty(out_dir, ec)) {
        std::cerr << "fovea-lod: --out " << out_dir << " exists and is not empty; nothing was written\n";
        return 2;
      }
      const Mesh mesh = lod::read_mesh(mesh_path);
      const auto t0 = std::chrono::steady_clock::now();
      const lod::Chain chain = lod::build_chain(mesh, s, fs::path(mesh_path).filename().string());
      const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      lod::write_chain(chain, out_dir, format);
      std::printf("fovea-lod: %s, %zu triangles -> %zu levels in %s (%.1f ms, attributes %s)\n", mesh_path.c_str(),
                  mesh.triangle_count(), chain.levels.size(), out_dir.c_str(), ms, lod::to_string(s.attributes));
      print_chain(chain);
      for (const lod::ChainLevel& l : chain.levels) {
        if (!l.reached) {
          std::printf("note: some levels did not reach their target ratio (the achieved ratio is what the level holds)\n");
          break;
        }
      }
      return 0;
    }
    const lod::Chain chain = lod::read_chain(info_dir);
    std::printf("%s: %s, base %g, attributes %s\n", info_dir.c_str(), chain.input_name.c_str(), chain.settings.base,
                lod::to_string(chain.settings.attributes));
    print_chain(chain);
    return 0;
  } catch (const SceneError& e) {
    std::cerr << "fovea-lod: " << e.what() << "\n";
  } catch (const std::exception& e) {
    std::cerr << "fovea-lod: " << e.what() << "\n";
  }
  return 1;
}
