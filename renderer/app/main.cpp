// SPDX-License-Identifier: Apache-2.0
// fovea-render: the gaze-contingent renderer (interactive viewer or headless frames).
#include <CLI/CLI.hpp>
#include <cstdio>

#include "app/render_options.h"
#include "pipeline/frame_pipeline.h"

namespace {

// --list-objects: one line an object. The scene is loaded without its LOD chains, which a listing of
// the full meshes does not need (building one can take seconds).
void print_objects(const fovea::render::Scene& scene) {
  for (const fovea::render::Object& obj : scene.objects) {
    const fovea::render::Material& m = scene.materials.at(obj.material);
    std::printf("%u\t%s\t%zu triangles\t%s (%s)\n", obj.id, obj.name.c_str(), obj.mesh ? obj.mesh->triangle_count() : 0,
                m.name.c_str(), to_string(m.type));
  }
}

// --list-settings: every render setting with its default, allowed values and meaning.
void print_settings() {
  for (const auto& s : fovea::render::Settings::specs()) {
    std::printf("%-20s default %-15s allowed %s\n    %s\n", s.key.c_str(), s.default_value.c_str(), s.allowed.c_str(),
                s.description.c_str());
  }
}

// --set KEY=VALUE into the settings, --scene-set PATH=VALUE (and --stereo) into the scene overrides.
// Throws std::invalid_argument naming the assignment that is malformed or unknown.
void apply_assignments(fovea::render::RenderOptions& o, const std::vector<std::string>& sets,
                       const std::vector<std::string>& scene_sets, bool stereo) {
  for (const auto& s : sets) o.settings.set_assignment(s);
  for (const auto& s : scene_sets) {
    const auto eq = s.find('=');
    if (eq == std::string::npos || eq == 0) throw std::invalid_argument("--scene-set \"" + s + "\": expected path=value");
    o.scene_overrides.push_back({s.substr(0, eq), s.substr(eq + 1)});
  }
  if (stereo) o.scene_overrides.push_back({"camera.stereo", "true"});
}

// --explain: the frame plan. The backend starts too: where the frame runs (the GPU path, what it
// reads back) is its answer.
void print_plan(const fovea::render::RenderOptions& o, const std::string& backend) {
  using namespace fovea::render;
  const auto gaze = make_gaze_input(o.gaze);
  FramePipeline pipeline(load_render_scene(o), o.settings, make_backend(o.backend), *gaze);
  std::printf("frame plan for %s (%s backend, gaze %s):\n", o.scene_path.c_str(), backend.c_str(),
              gaze->description().c_str());
  std::printf("%s", pipeline.plan().explain().c_str());
  if (!pipeline.stereo_summary().empty()) std::printf("%s\n", pipeline.stereo_summary().c_str());
}

}  // namespace

int main(int argc, char** argv) {
  using namespace fovea::render;
  CLI::App app{
      "fovea-render: renders a scene with the perceptual pipeline, driven by gaze from fovea-trackerd.\n"
      "Interactive viewer by default; --headless writes frames, timings and the frame plan to --out DIR."};
  app.set_version_flag("--version", "fovea-render " FOVEA_VERSION);
  RenderOptions o;
  std::string backend = "embree";
  std::vector<std::string> sets, scene_sets;
  bool list_settings = false, list_objects = false;
  app.add_option("--scene", o.scene_path, "scene file: JSON, or a glTF 2.0 asset (.gltf, .glb) (renderer/SCENES.md)");
  app.add_option("--camera", o.camera, "glTF scenes: view from the camera node of this name (default: the first)");
  app.add_flag("--list-objects", list_objects,
               "print the scene's objects (id, name, triangles, material and its type), one a line, and exit");
  app.add_option("--backend", backend, "G-buffer backend")->check(CLI::IsMember({"embree", "gl"}))->capture_default_str();
  app.add_option("--gaze", o.gaze, "udp://HOST:PORT (fovea-trackerd), file:REC.fgr (on the frame clock), mouse, none")
      ->capture_default_str();
  app.add_option("--set", sets, "render setting key=value (repeatable; --list-settings shows them)");
  app.add_option("--scene-set", scene_sets, "scene override path=value, e.g. camera.width=320 (repeatable)");
  bool stereo = false;
  app.add_flag("--stereo", stereo,
               "render two views, the eyes camera.ipd_m apart (default 0.063 m; --scene-set camera.ipd_m=M), each "
               "camera.width x camera.height: attention, levels of detail, focus and photon maps once per frame, the "
               "rest per eye; headless PNGs are left | right side by side (same as --scene-set camera.stereo=true)");
  app.add_flag("--explain", o.explain, "print the frame plan (which passes run and why) and exit");
  app.add_flag("-v,--verbose", o.verbose,
               "print what loading cost, phase by phase (parse, textures, lod, backend; headless runs also "
               "record them in timings.csv as load.* rows)");
  app.add_flag("--list-settings", list_settings, "list every render setting with default and allowed values");
  app.add_flag("--headless", o.headless, "render without a window to --out DIR");
  app.add_option("--frames", o.frames, "frames to render (headless: required; viewer: close after N)");
  app.add_option("--fps", o.fps, "frame rate of the frame clock")->check(CLI::Range(0.1, 1000.0))->capture_default_str();
  app.add_option("--out", o.out_dir, "headless output directory (created; must be empty)");
  CLI::Option* exr = app.add_flag("--exr", o.exr, "headless: also write HDR colour as OpenEXR");
  app.add_flag("--no-images", o.no_images,
               "headless: write no frame images, only the CSVs and plan.txt (benchmarks: a frame kept on the GPU is "
               "then never read back)")
      ->excludes(exr);
  app.add_flag("--log-objects", o.log_objects,
               "headless: also write objects.csv, where each object shows each frame (its pixels, their centre in "
               "normalised screen coordinates and their median depth): the truth for gaze measurements such as "
               "bench/bench_pursuit_focus.py");
  app.add_flag("--realtime", o.realtime, "headless: pace frames on the wall clock (default with udp:// gaze)");
  app.add_option("--budget-ms", o.budget_ms,
                 "frame-time budget: the governor picks each running effect's settings (DOF method, GI photons and "
                 "strategy, saliency map size, LOD policy) from the measured accuracy-vs-time fronts to maximise "
                 "accuracy within it, adapts to measured times, and reports the expected accuracy (viewer title, "
                 "headless governor.csv)")
      ->check(CLI::Range(0.1, 1e6));
  app.add_option("--fronts", o.fronts_path,
                 "the governor's fronts JSON (default: the ones measured on the project's machine, "
                 "renderer/governor/fronts.json, built in)");
  CLI11_PARSE(app, argc, argv);

  if (list_settings) {
    print_settings();
    return 0;
  }
  if (o.scene_path.empty()) {
    std::fprintf(stderr, "fovea-render: --scene FILE is required (bundled scenes: renderer/scenes/*.json in the source "
                         "tree, " FOVEA_SCENES_DIR "/*.json where installed)\n");
    return 2;
  }
  o.backend = backend == "gl" ? BackendKind::OpenGL : BackendKind::Embree;
  try {
    apply_assignments(o, sets, scene_sets, stereo);
    if (list_objects) {
      print_objects(load_scene(o.scene_path, o.scene_overrides, o.camera));
      return 0;
    }
    if (o.explain) {
      print_plan(o, backend);
      return 0;
    }
    return o.headless ? run_headless(o) : run_viewer(o);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fovea-render: %s\n", e.what());
    return 2;
  }
}
