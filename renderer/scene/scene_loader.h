// SPDX-License-Identifier: Apache-2.0
#pragma once
// Loads JSON scene files (format: renderer/SCENES.md) into a validated Scene. Every error names the
// file, the JSON path, the bad value and the allowed range, e.g.
//   scenes/room.json: $.objects[2].transform.translation[1] = nan: must be a finite number
//
// The loader reads JSON through scene/json_path.h, checks it against scene/scene_schema.h, applies
// overrides (scene/scene_overrides.h) and reads mesh files through scene/mesh_io.h. A scene's LOD
// chains ("lod": {"chain": ...}) are not built here: the loader keeps the request
// (Object::lod_chain) and lod::attach_chains (lod/lod_chain.h) builds or loads them.
#include <chrono>
#include <filesystem>
#include <string>
#include <vector>

#include "scene/scene.h"
#include "scene/scene_error.h"

namespace fovea::render {

// Overrides applied to the JSON document before validation: "camera.width=320" sets the value at
// that dotted path (array elements by index: "lights.0.power=[10,10,10]"). The value is parsed as
// JSON if it can be, else taken as a string. An override naming a path that does not exist in the
// document and is not a known optional field is an error.
struct SceneOverride {
  std::string path;
  std::string value;
};

// What loading cost, phase by phase (fovea-render --verbose prints it, headless runs record it in
// timings.csv as the load.* rows of frame 0): parse (the file, its buffers and meshes), textures
// (decoding and mip chains), lod (chains built or read from the cache), backend (Embree's BVH build
// or the OpenGL upload). Each phase may carry a note ("12 textures, 96 MiB").
struct LoadReport {
  struct Phase {
    std::string name;
    double ms = 0;
    std::string note;
  };
  std::vector<Phase> phases;
  void add(std::string name, double ms, std::string note = {}) { phases.push_back({std::move(name), ms, std::move(note)}); }
  // Adds a phase that began at `start` and ends now.
  void add_since(std::string name, std::chrono::steady_clock::time_point start, std::string note = {}) {
    add(std::move(name), std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count(),
        std::move(note));
  }
  double total_ms() const;
  std::string summary() const;  // "load 812 ms: parse 120 ms, textures 540 ms (12 textures, 96 MiB), ..."
};

// Throws SceneError. Mesh files are resolved relative to the scene file's directory.
// A .gltf or .glb file (by its extension, any case) is read by gltf::read_gltf and built by
// scene_from_gltf (scene/gltf/gltf_scene.h); its warnings go to stderr. Its overrides may only set
// camera.width and camera.height; `camera` names the glTF camera node to view from (empty: the
// first). A JSON scene has one camera: a non-empty `camera` is an error.
Scene load_scene(const std::filesystem::path& path, const std::vector<SceneOverride>& overrides = {},
                 const std::string& camera = {}, LoadReport* report = nullptr);
// The same from text; `source_name` is used in messages and `base_dir` to resolve mesh files.
Scene parse_scene(const std::string& json_text, const std::string& source_name, const std::filesystem::path& base_dir,
                  const std::vector<SceneOverride>& overrides = {}, LoadReport* report = nullptr);

}  // namespace fovea::render
