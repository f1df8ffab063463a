// Headless rendering: frames to PNG (and EXR), per-frame per-pass timings to CSV, a progress bar.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <thread>

#include "app/render_options.h"
#include "pipeline/frame_pipeline.h"

namespace fovea::render {

namespace {

void progress(std::uint64_t done, std::uint64_t total, double ms_per_frame) {
  constexpr int kWidth = 30;
  const int filled = static_cast<int>(static_cast<double>(kWidth) * static_cast<double>(done) / static_cast<double>(total));
  std::fprintf(stderr, "\r[");
  for (int i = 0; i < kWidth; ++i) std::fputc(i < filled ? '=' : (i == filled ? '>' : ' '), stderr);
  std::fprintf(stderr, "] %llu/%llu frames, %.1f ms/frame ", static_cast<unsigned long long>(done),
               static_cast<unsigned long long>(total), ms_per_frame);
  std::fflush(stderr);
}

std::string frame_name(const std::string& dir, std::uint64_t i, const char* ext) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "frame-%06llu.%s", static_cast<unsigned long long>(i), ext);
  return (std::filesystem::path(dir) / buf).string();
}

}  // namespace

int run_headless(const RenderOptions& o) {
  namespace fs = std::filesystem;
  if (o.frames == 0) {
    std::fprintf(stderr, "fovea-render: --headless needs --frames N (N >= 1)\n");
    return 2;
  }
  if (o.out_dir.empty()) {
    std::fprintf(stderr, "fovea-render: --headless needs --out DIR\n");
    return 2;
  }
  // The governor's fronts are read (and refused) before anything is written.
  std::unique_ptr<Governor> governor = make_governor(o);
  std::error_code ec;
  if (fs::exists(o.out_dir) && !fs::is_empty(o.out_dir, ec)) {
    std::fprintf(stderr, "fovea-render: output directory %s is not empty; choose a new one (nothing is overwritten)\n",
                 o.out_dir.c_str());
    return 2;
  }
  fs::create_directories(o.out_dir, ec);
  if (ec) {
    std::fprintf(stderr, "fovea-render: cannot create %s: %s\n", o.out_dir.c_str(), ec.message().c_str());
    return 2;
  }

  Scene scene = load_render_scene(o);
  std::unique_ptr<GazeInput> gaze = make_gaze_input(o.gaze);
  FramePipeline pipeline(std::move(scene), o.settings, make_backend(o.backend), *gaze);
  {
    std::ofstream plan(fs::path(o.out_dir) / "plan.txt");
    plan << "scene " << o.scene_path << "\nbackend " << pipeline.backend().name() << "\ngaze " << gaze->description()
         << "\n" << pipeline.plan().explain();
  }
  PassTimer timer((fs::path(o.out_dir) / "timings.csv").string());
  const bool tty = isatty(STDERR_FILENO) != 0;
  const bool realtime = o.realtime || o.gaze.rfind("udp://", 0) == 0;
  const auto start = std::chrono::steady_clock::now();
  double previous = 0;
  std::ofstream gaze_log(fs::path(o.out_dir) / "gaze.csv");
  gaze_log << "frame,frame_clock_s,gaze_x,gaze_y,valid,movement,age_ms,received,lost\n";
  std::ofstream focus_log, gi_log, lod_log, governor_log;
  if (governor) {
    governor_log.open(fs::path(o.out_dir) / "governor.csv");
    governor_log << "frame,budget_ms,frame_ms,predicted_ms,other_ms,cannot_meet,replans,choices\n";
  }
  for (std::uint64_t i = 0; i < o.frames; ++i) {
    const double scheduled = static_cast<double>(i) / o.fps;
    double clock = scheduled;
    if (realtime) {
      std::this_thread::sleep_until(start + std::chrono::duration<double>(scheduled));
      clock = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    }
    const double now = clock;
    if (governor)
      governor->apply(pipeline.plan(), pipeline.backend().name(), pipeline.scene().camera.width, pipeline.scene().camera.height,
                      pipeline.settings());
    const FramePipeline::Frame f = pipeline.render(i, now, i == 0 ? now : previous, clock, timer);
    previous = now;
    if (governor) {
      // governor.csv: the budget, what the frame took and what the governor chose and expects.
      governor->observe(timer);
      const Governor::State& g = governor->state();
      std::string choices;
      for (const Governor::Choice& c : g.choices) {
        char item[200];
        std::snprintf(item, sizeof item, "%s%s=%s (%.4g %s)", choices.empty() ? "" : "; ", c.effect.c_str(), c.label.c_str(),
                      c.accuracy, c.metric.c_str());
        choices += item;
      }
      char gl[160];
      std::snprintf(gl, sizeof gl, "%llu,%.2f,%.3f,%.3f,%.3f,%d,%llu,", static_cast<unsigned long long>(i), g.budget_ms,
                    g.measured_ms, g.predicted_ms, g.other_ms, g.cannot_meet ? 1 : 0, static_cast<unsigned long long>(g.replans));
      governor_log << gl << '"' << choices << "\"\n";
    }
    {
      auto t = timer.scope("write");
      if (f.image != nullptr) write_png(frame_name(o.out_dir, i, "png"), *f.image);
      if (o.exr || f.image == nullptr) {
        write_exr(frame_name(o.out_dir, i, "exr"), f.gbuffer->width, f.gbuffer->height, f.gbuffer->color);
      }
    }
    char line[256];
    std::snprintf(line, sizeof line, "%llu,%.6f,%.5f,%.5f,%d,%s,%.3f,%llu,%llu\n", static_cast<unsigned long long>(i),
                  clock, f.gaze.x, f.gaze.y, f.gaze.valid ? 1 : 0, protocol::to_string(f.gaze.movement), f.gaze.age_ms,
                  static_cast<unsigned long long>(f.gaze.received), static_cast<unsigned long long>(f.gaze.lost));
    gaze_log << line;
    if (f.focus != nullptr) {
      // focus.csv: what the focus pass decided each frame (only when it ran).
      if (!focus_log.is_open()) {
        focus_log.open(fs::path(o.out_dir) / "focus.csv");
        focus_log << "frame,focal_depth_m,target_depth_m,object,in_transition,why\n";
      }
      std::string why = f.focus->why;
      for (char& ch : why) if (ch == '"') ch = '\'';
      char fl[128];
      std::snprintf(fl, sizeof fl, "%llu,%.4f,%.4f,%u,%d,", static_cast<unsigned long long>(i), f.focus->focal_depth_m,
                    f.focus->target_depth_m, f.focus->object, f.focus->in_transition ? 1 : 0);
      focus_log << fl << '"' << why << "\"\n";
    }
    if (f.gi != nullptr) {
      // gi.csv: where the gi pass ray traced and with how many photons (only when it ran).
      if (!gi_log.is_open()) {
        gi_log.open(fs::path(o.out_dir) / "gi.csv");
        gi_log << "frame,strategy,follows,center_x_px,center_y_px,radius_px,photons,caustic_photons,emitted,pixels,rays,"
                  "photons_used,emission_map,power_scale,importons,periphery_rays,full_resolution_rays,note\n";
      }
      char gl[320];
      std::snprintf(gl, sizeof gl, "%llu,%s,%s,%.1f,%.1f,%.1f,%zu,%zu,%llu,%llu,%llu,%llu,%zu,%.4f,%zu,%llu,%llu,",
                    static_cast<unsigned long long>(i), f.gi->strategy, f.gi->follows, static_cast<double>(f.gi->area.center_px.x), static_cast<double>(f.gi->area.center_px.y),
                    static_cast<double>(f.gi->area.radius_px), f.gi->photons, f.gi->caustic_photons,
                    static_cast<unsigned long long>(f.gi->emitted), static_cast<unsigned long long>(f.gi->render.pixels),
                    static_cast<unsigned long long>(f.gi->render.rays),
                    static_cast<unsigned long long>(f.gi->render.photons_used), f.gi->gaze.emission_map,
                    f.gi->gaze.scale, f.gi->importons, static_cast<unsigned long long>(f.gi->csf.rays_cast),
                    static_cast<unsigned long long>(f.gi->csf.full_resolution_rays));
      gi_log << gl << '"' << f.gi->note << "\"\n";
    }
    if (f.lod != nullptr) {
      // lod.csv: the levels drawn this frame (only when lod-select ran).
      if (!lod_log.is_open()) {
        lod_log.open(fs::path(o.out_dir) / "lod.csv");
        lod_log << "frame,policy,objects,triangles,full_triangles,budget_bias,cannot_meet,levels\n";
      }
      std::string levels;
      for (const lod::Selection& sel : f.lod->selection) {
        char item[48];
        std::snprintf(item, sizeof item, "%s%u:%d", levels.empty() ? "" : " ", sel.id, sel.drawn);
        levels += item;
      }
      char ll[160];
      std::snprintf(ll, sizeof ll, "%llu,%s,%zu,%llu,%llu,%.2f,%d,", static_cast<unsigned long long>(i), f.lod->policy,
                    f.lod->selection.size(), static_cast<unsigned long long>(f.lod->triangles),
                    static_cast<unsigned long long>(f.lod->full_triangles), f.lod->budget.bias,
                    f.lod->budget.cannot_meet ? 1 : 0);
      lod_log << ll << '"' << levels << "\"\n";
    }
    if (tty) progress(i + 1, o.frames, timer.last_ms("frame"));
  }
  if (tty) std::fputc('\n', stderr);
  std::printf("fovea-render: %llu frames of %s with %s (gaze %s) -> %s\n", static_cast<unsigned long long>(o.frames),
              o.scene_path.c_str(), pipeline.backend().name().c_str(), gaze->description().c_str(), o.out_dir.c_str());
  std::printf("%s", timer.summary_table().c_str());
  if (governor) std::printf("governor: %s\n", governor->state().summary().c_str());
  return 0;
}

}  // namespace fovea::render
