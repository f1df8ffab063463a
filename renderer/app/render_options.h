#pragma once
// What fovea-render was asked to do, parsed from its command line.
#include <string>
#include <vector>

#include "backend/backend.h"
#include "pipeline/settings.h"
#include "scene/scene_loader.h"

namespace fovea::render {

struct RenderOptions {
  std::string scene_path;
  std::vector<SceneOverride> scene_overrides;
  BackendKind backend = BackendKind::Embree;
  std::string gaze = "udp://127.0.0.1:47800";
  Settings settings;
  bool explain = false;
  bool headless = false;
  std::uint64_t frames = 0;  // 0: viewer runs until closed; headless requires > 0
  double fps = 30;
  std::string out_dir;
  bool exr = false;
  bool realtime = false;  // pace frames on the wall clock (default with live gaze)
};

int run_headless(const RenderOptions& options);
int run_viewer(const RenderOptions& options);

}  // namespace fovea::render
