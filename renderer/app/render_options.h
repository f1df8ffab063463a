// SPDX-License-Identifier: Apache-2.0
#pragma once
// What fovea-render was asked to do, parsed from its command line.
#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include "backend/backend.h"
#include "governor/governor.h"
#include "lod/lod_chain.h"
#include "pipeline/settings.h"
#include "scene/scene_loader.h"

namespace fovea::render {

struct RenderOptions {
  std::string scene_path;
  std::string camera;  // --camera: a glTF camera node's name
  std::vector<SceneOverride> scene_overrides;
  BackendKind backend = BackendKind::Embree;
  std::string gaze = "udp://127.0.0.1:47800";
  Settings settings;
  bool explain = false;
  bool verbose = false;  // --verbose: the load phases on stderr
  bool headless = false;
  std::uint64_t frames = 0;  // 0: viewer runs until closed; headless requires > 0
  double fps = 30;
  std::string out_dir;
  bool exr = false;
  bool no_images = false;  // headless: CSVs and plan.txt only
  bool log_objects = false;  // headless: objects.csv, where each object shows each frame
  bool realtime = false;  // pace frames on the wall clock (default with live gaze)
  double budget_ms = 0;   // > 0: the governor picks effect settings to hold this frame time
  std::string fronts_path;  // the governor's fronts (empty: the built-in ones)
};

// The governor --budget-ms asks for (null without a budget), on --fronts or the built-in fronts.
inline std::unique_ptr<Governor> make_governor(const RenderOptions& o) {
  if (!(o.budget_ms > 0)) return nullptr;
  return std::make_unique<Governor>(o.budget_ms, o.fronts_path.empty() ? builtin_fronts() : load_fronts(o.fronts_path));
}

// The scene as every mode renders it: loaded with its overrides, then its LOD chains attached;
// the phases' times go to `report` when given.
inline Scene load_render_scene(const RenderOptions& o, LoadReport* report = nullptr) {
  Scene scene = load_scene(o.scene_path, o.scene_overrides, o.camera, report);
  const auto start = std::chrono::steady_clock::now();
  std::size_t levels = 0;
  lod::attach_chains(scene);
  for (const Object& obj : scene.objects) levels += obj.lods.size();
  if (report) {
    report->add_since("lod", start, std::to_string(levels) + " levels");
  }
  return scene;
}

// The backend's share of loading (timed around the pipeline's construction, which gives the backend
// the scene): Embree builds its BVH, OpenGL uploads meshes and textures and compiles its programs.
inline const char* backend_load_note(BackendKind kind) {
  return kind == BackendKind::OpenGL ? "OpenGL upload and programs" : "Embree BVH build";
}

int run_headless(const RenderOptions& options);
int run_viewer(const RenderOptions& options);

}  // namespace fovea::render
