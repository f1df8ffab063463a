// SPDX-License-Identifier: Apache-2.0
#pragma once
// Level-of-detail chains (Lee 2009, ch. 7): level L keeps r(L) = base^-L of the full mesh's
// triangles (eq. 7.4, base beta = 4), built once with meshoptimizer's quadric edge-collapse
// simplifier and cached on disk.
//
// Attributes. Debian 12's meshoptimizer (0.18) predates meshopt_simplifyWithAttributes (0.20), so
// normals cannot enter the quadric error. Vertices identical in position and normal are joined first
// (duplicates generators and exporters leave); then, selectable:
//   Seams (default): vertices that share a position but not a normal are attribute seams to
//     meshopt, which collapses only along a seam and both sides together: hard edges stay hard.
//   Weld: vertices that share a position are welded (a shadow index buffer), so seams do not limit
//     the simplifier; kept vertices keep their own normals, so a crease can smear.
// Each level records the target and achieved ratios and meshopt's error in metres; a ratio the
// simplifier cannot reach (a box has nothing to collapse) is reported as reached = false with the
// count it stopped at, never silently copied.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "scene/scene.h"

namespace fovea::render::lod {

enum class Attributes { Seams, Weld };
const char* to_string(Attributes a);

struct ChainSettings {
  int levels = 5;        // including level 0, the input (1..16)
  double base = 4;       // beta of eq. 7.4 (> 1)
  Attributes attributes = Attributes::Seams;
  // Throws std::invalid_argument naming the bad field.
  void check() const;
};

struct ChainLevel {
  Mesh mesh;
  double target_ratio = 1;    // base^-L
  double achieved_ratio = 1;  // triangles / input triangles
  float error_m = 0;          // meshopt's relative error x meshopt_simplifyScale (object-space metres)
  bool reached = true;        // achieved within 1.5x of the target (or the target is below one triangle)
};

struct Chain {
  std::vector<ChainLevel> levels;  // levels[0] is the input
  ChainSettings settings;
  std::string input_name;          // for the manifest
};

// Builds the chain. Meshes with 0 triangles give one level (the input) and a note in reached; 1 or
// 2 triangles cannot lose any: their coarser levels repeat the input with reached = false.
// Non-manifold and degenerate input is simplified as it is (meshopt tolerates both); triangles with
// out-of-range indices are dropped first.
Chain build_chain(const Mesh& mesh, const ChainSettings& s, const std::string& input_name = "");

// Writes level files (format "obj", "ply", or "fmesh": the cache's binary file with every attribute,
// lod/mesh_cache_file.h) and manifest.json into dir (created):
// {"input", "base", "levels", "attributes", "level": [{"file", "triangles", "target_ratio",
// "achieved_ratio", "error_m", "reached"}]}. Throws std::runtime_error naming the path on failure.
void write_chain(const Chain& chain, const std::filesystem::path& dir, const std::string& format = "obj");

// Reads a directory written by write_chain back (OBJ and PLY through assimp, as scenes read meshes;
// .fmesh exactly). Throws std::runtime_error naming the file and the problem.
Chain read_chain(const std::filesystem::path& dir);

// The cache: a directory per (mesh content, settings) under `root` (default: $FOVEA_LOD_CACHE, else
// $XDG_CACHE_HOME/fovea/lod, else ~/.cache/fovea/lod). Builds and writes on a miss; a damaged entry
// is rebuilt. `hit` (optional) says whether it came from the cache.
Chain cached_chain(const Mesh& mesh, const ChainSettings& s, const std::string& input_name = "",
                   std::filesystem::path root = {}, bool* hit = nullptr);
std::filesystem::path default_cache_root();

// Builds or loads (cached_chain) the chain each object of `scene` asks for (Object::lod_chain, kept
// by the scene loader) and fills its Object::lods with the chain's levels below the full mesh;
// levels the simplifier could not take below the previous one are left out. Clears the requests.
// Throws SceneError naming the scene file and the object's "lod.chain" when the simplifier cannot
// reduce a mesh at all. Run it after load_scene / parse_scene whenever the scene will be drawn
// with its levels of detail (fovea-render does).
void attach_chains(Scene& scene);

// Mesh files (OBJ, PLY, glTF) as scenes read them (scene/mesh_io.h).
Mesh read_mesh(const std::filesystem::path& path);
void write_mesh(const Mesh& mesh, const std::filesystem::path& path);  // .obj or .ply (ASCII)

}  // namespace fovea::render::lod
