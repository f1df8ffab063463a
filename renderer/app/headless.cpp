// SPDX-License-Identifier: Apache-2.0
// Headless rendering: frames to PNG (and EXR), per-frame per-pass timings to CSV, a progress bar.
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <stdexcept>
#include <vector>
#include <thread>

#include "app/render_options.h"
#include "pipeline/frame_pipeline.h"

namespace fovea::render {

namespace {

namespace fs = std::filesystem;

void progress(std::uint64_t done, std::uint64_t total, double ms_per_frame) {
  constexpr int kWidth = 30;
  const int filled = static_cast<int>(static_cast<double>(kWidth) * static_cast<double>(done) / static_cast<double>(total));
  std::fprintf(stderr, "\r[");
  for (int i = 0; i < kWidth; ++i) std::fputc(i < filled ? '=' : (i == filled ? '>' : ' '), stderr);
  std::fprintf(stderr, "] %llu/%llu frames, %.1f ms/frame ", static_cast<unsigned long long>(done),
               static_cast<unsigned long long>(total), ms_per_frame);
  std::fflush(stderr);
}

std::string frame_name(const std::string& dir, std::uint64_t i, const char* ext, const char* eye = "") {
  char buf[48];
  std::snprintf(buf, sizeof buf, "frame-%06llu%s.%s", static_cast<unsigned long long>(i), eye, ext);
  return (std::filesystem::path(dir) / buf).string();
}

// The run's CSV files, in the order they were always declared (and so closed in reverse).
struct CsvLogs {
  std::ofstream gaze, focus, gi, lod, governor, stereo, objects;
};

// Refuses a run without frames or an output directory before anything is loaded.
bool headless_options_given(const RenderOptions& o) {
  if (o.frames == 0) {
    std::fprintf(stderr, "fovea-render: --headless needs --frames N (N >= 1)\n");
    return false;
  }
  if (o.out_dir.empty()) {
    std::fprintf(stderr, "fovea-render: --headless needs --out DIR\n");
    return false;
  }
  return true;
}

// Refuses a directory that already holds files (nothing is overwritten), else creates it.
bool prepare_output_dir(const RenderOptions& o) {
  std::error_code ec;
  if (fs::exists(o.out_dir) && !fs::is_empty(o.out_dir, ec)) {
    std::fprintf(stderr, "fovea-render: output directory %s is not empty; choose a new one (nothing is overwritten)\n",
                 o.out_dir.c_str());
    return false;
  }
  fs::create_directories(o.out_dir, ec);
  if (ec) {
    std::fprintf(stderr, "fovea-render: cannot create %s: %s\n", o.out_dir.c_str(), ec.message().c_str());
    return false;
  }
  return true;
}

// plan.txt: what the run renders with, so a directory of frames explains itself.
void write_plan(const RenderOptions& o, const FramePipeline& pipeline, const GazeInput& gaze) {
  std::ofstream plan(fs::path(o.out_dir) / "plan.txt");
  plan << "scene " << o.scene_path << "\nbackend " << pipeline.backend().name() << "\ngaze " << gaze.description()
       << "\n" << pipeline.plan().explain();
  if (!pipeline.stereo_summary().empty()) plan << pipeline.stereo_summary() << "\n";
}

// gaze.csv always; governor.csv with a governor. The per-pass files open on the first frame their pass runs.
void open_csv_logs(CsvLogs& logs, const std::string& out_dir, bool with_governor) {
  logs.gaze.open(fs::path(out_dir) / "gaze.csv");
  logs.gaze << "frame,frame_clock_s,gaze_x,gaze_y,valid,movement,age_ms,received,lost,age_at_completion_ms\n";
  if (with_governor) {
    logs.governor.open(fs::path(out_dir) / "governor.csv");
    logs.governor << "frame,budget_ms,frame_ms,predicted_ms,other_ms,cannot_meet,replans,choices\n";
  }
}

// The frame's clock: its scheduled time i / fps, or, paced in real time, the wall clock after sleeping until then.
double frame_clock_s(std::uint64_t i, double fps, bool realtime, std::chrono::steady_clock::time_point start) {
  const double scheduled = static_cast<double>(i) / fps;
  double clock = scheduled;
  if (realtime) {
    std::this_thread::sleep_until(start + std::chrono::duration<double>(scheduled));
    clock = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  return clock;
}

// The governor picks the frame's settings for all its views' pixels (a stereo frame's two eyes).
void govern(Governor* governor, FramePipeline& pipeline) {
  if (!governor) return;
  const Camera& cam = pipeline.scene().camera;
  governor->apply(pipeline.plan(), pipeline.backend().name(), pipeline.device(), cam.width * (cam.stereo ? 2u : 1u),
                  cam.height, pipeline.settings());
}

// The governor picks the frame's settings, the pipeline renders it (motion vectors from the previous frame's
// time), and the governor sees what it cost before anything else is timed.
FramePipeline::Frame render_one_frame(FramePipeline& pipeline, Governor* governor, PassTimer& timer, std::uint64_t i,
                                      double clock, double& previous, bool realtime) {
  const double now = clock;
  govern(governor, pipeline);
  FramePipeline::Frame f = pipeline.render(i, now, i == 0 ? now : previous, clock, timer, realtime);
  previous = now;
  if (governor) governor->observe(timer);
  return f;
}

// governor.csv: the budget, what the frame took and what the governor chose and expects.
void write_governor_row(std::ofstream& governor_log, const Governor::State& g, std::uint64_t i) {
  std::string choices;
  for (const Governor::Choice& c : g.choices) {
    char item[200];
    std::snprintf(item, sizeof item, "%s%s=%s (%.4g %s)", choices.empty() ? "" : "; ", c.effect.c_str(),
                  c.label.c_str(), c.accuracy, c.metric.c_str());
    choices += item;
  }
  char gl[160];
  std::snprintf(gl, sizeof gl, "%llu,%.2f,%.3f,%.3f,%.3f,%d,%llu,", static_cast<unsigned long long>(i), g.budget_ms,
                g.measured_ms, g.predicted_ms, g.other_ms, g.cannot_meet ? 1 : 0,
                static_cast<unsigned long long>(g.replans));
  governor_log << gl << '"' << choices << "\"\n";
}

// The frame's PNG, and its HDR colour as EXR when asked for (or when there is no PNG), timed as "write".
void write_frame_images(const RenderOptions& o, std::uint64_t i, FramePipeline& pipeline, const FramePipeline::Frame& f,
                        PassTimer& timer) {
  if (o.no_images) return;
  auto t = timer.scope("write");
  if (f.on_gpu) {
    const Image8* image = nullptr;
    {
      auto r = timer.scope("readback.display");  // the display image's one trip to the CPU, for the PNG
      image = &pipeline.read_display();
    }
    write_png(frame_name(o.out_dir, i, "png"), *image);
    return;
  }
  if (f.image != nullptr) write_png(frame_name(o.out_dir, i, "png"), *f.image);
  if (o.exr || f.image == nullptr) {
    write_exr(frame_name(o.out_dir, i, "exr"), f.gbuffer->width, f.gbuffer->height, f.gbuffer->color);
  }
}

// gaze.csv: the gaze sample the frame was rendered with (the overlay's, after the late latches), and
// its age when the frame was complete.
void write_gaze_row(std::ofstream& gaze_log, std::uint64_t i, double clock, const FramePipeline::Frame& f) {
  const GazeState& gaze = f.gaze;
  char line[288];
  std::snprintf(line, sizeof line, "%llu,%.6f,%.5f,%.5f,%d,%s,%.3f,%llu,%llu,%.3f\n", static_cast<unsigned long long>(i),
                clock, gaze.x, gaze.y, gaze.valid ? 1 : 0, protocol::to_string(gaze.movement), gaze.age_ms,
                static_cast<unsigned long long>(gaze.received), static_cast<unsigned long long>(gaze.lost),
                f.gaze_age_at_completion_ms);
  gaze_log << line;
}

// focus.csv: what the focus pass decided each frame (only when it ran).
void write_focus_row(std::ofstream& focus_log, const std::string& out_dir, std::uint64_t i,
                     const attention::FocusResult& focus) {
  if (!focus_log.is_open()) {
    focus_log.open(fs::path(out_dir) / "focus.csv");
    focus_log << "frame,focal_depth_m,target_depth_m,object,in_transition,why\n";
  }
  std::string why = focus.why;
  for (char& ch : why) if (ch == '"') ch = '\'';
  char fl[128];
  std::snprintf(fl, sizeof fl, "%llu,%.4f,%.4f,%u,%d,", static_cast<unsigned long long>(i), focus.focal_depth_m,
                focus.target_depth_m, focus.object, focus.in_transition ? 1 : 0);
  focus_log << fl << '"' << why << "\"\n";
}

// gi.csv: where the gi pass ray traced and with how many photons (only when it ran).
void write_gi_row(std::ofstream& gi_log, const std::string& out_dir, std::uint64_t i,
                  const FramePipeline::Frame::Gi& gi) {
  if (!gi_log.is_open()) {
    gi_log.open(fs::path(out_dir) / "gi.csv");
    gi_log << "frame,strategy,follows,center_x_px,center_y_px,radius_px,photons,caustic_photons,emitted,pixels,rays,"
              "photons_used,emission_map,power_scale,importons,periphery_rays,full_resolution_rays,note\n";
  }
  char gl[320];
  std::snprintf(gl, sizeof gl, "%llu,%s,%s,%.1f,%.1f,%.1f,%zu,%zu,%llu,%llu,%llu,%llu,%zu,%.4f,%zu,%llu,%llu,",
                static_cast<unsigned long long>(i), gi.strategy, gi.follows, static_cast<double>(gi.area.center_px.x),
                static_cast<double>(gi.area.center_px.y), static_cast<double>(gi.area.radius_px), gi.photons,
                gi.caustic_photons,
                static_cast<unsigned long long>(gi.emitted), static_cast<unsigned long long>(gi.render.pixels),
                static_cast<unsigned long long>(gi.render.rays),
                static_cast<unsigned long long>(gi.render.photons_used), gi.gaze.emission_map,
                gi.gaze.scale, gi.importons, static_cast<unsigned long long>(gi.csf.rays_cast),
                static_cast<unsigned long long>(gi.csf.full_resolution_rays));
  gi_log << gl << '"' << gi.note << "\"\n";
}

// lod.csv: the levels drawn this frame (only when lod-select ran).
void write_lod_row(std::ofstream& lod_log, const std::string& out_dir, std::uint64_t i,
                   const FramePipeline::Frame::Lod& lod) {
  if (!lod_log.is_open()) {
    lod_log.open(fs::path(out_dir) / "lod.csv");
    lod_log << "frame,policy,objects,triangles,full_triangles,budget_bias,cannot_meet,in_saccade,pops,"
               "switched_in_saccade,blended,levels\n";
  }
  std::string levels;
  for (const lod::Selection& sel : lod.selection) {
    char item[48];
    std::snprintf(item, sizeof item, "%s%u:%d", levels.empty() ? "" : " ", sel.id, sel.drawn);
    levels += item;
  }
  char ll[200];
  std::snprintf(ll, sizeof ll, "%llu,%s,%zu,%llu,%llu,%.2f,%d,%d,%d,%d,%d,", static_cast<unsigned long long>(i), lod.policy,
                lod.selection.size(), static_cast<unsigned long long>(lod.triangles),
                static_cast<unsigned long long>(lod.full_triangles), lod.budget.bias,
                lod.budget.cannot_meet ? 1 : 0, lod.switches.in_saccade ? 1 : 0, lod.switches.pops,
                lod.switches.switched_in_saccade, lod.switches.blended);
  lod_log << ll << '"' << levels << "\"\n";
}

// A stereo frame: the left eye (every pass), its image kept, then the right eye (the shared work
// reused, FramePipeline::Eye), written side by side as one PNG (left | right, 2W x H: what a headset's
// display or a stereo video player takes), each eye's HDR colour as EXR when asked. gaze.csv gets
// the left eye's row; stereo.csv both eyes' gaze points, where each came from, and the fixation depth.
void render_stereo_frame(const RenderOptions& o, FramePipeline& pipeline, Governor* governor, PassTimer& timer,
                         std::uint64_t i, double clock, double& previous, bool realtime, CsvLogs& logs,
                         Image8& side_by_side) {
  using Eye = FramePipeline::Eye;
  const double before = i == 0 ? clock : previous;
  govern(governor, pipeline);  // once for both eyes; it sees both eyes' times after the right eye
  FramePipeline::Frame f[2];
  bool png = false;  // an image to show (output=gbuffer has none: EXR only)
  for (int e = 0; e < 2; ++e) {
    f[e] = pipeline.render(i, clock, before, clock, timer, realtime, e == 0 ? Eye::Left : Eye::Right);
    if (o.no_images) continue;
    const Image8* image = f[e].image;
    if (f[e].on_gpu) {
      auto r = timer.scope(e == 0 ? "readback.display" : "right.readback.display");
      image = &pipeline.read_display();
    }
    png = image != nullptr;
    if (image != nullptr) {
      if (e == 0) side_by_side.resize(2 * image->width, image->height);
      const std::size_t row = std::size_t{3} * image->width, x0 = e == 0 ? 0 : row;
      for (std::size_t y = 0; y < image->height; ++y) {
        std::copy_n(image->rgb.data() + y * row, row, side_by_side.rgb.data() + 2 * y * row + x0);
      }
    }
    if (!f[e].on_gpu && (o.exr || image == nullptr)) {
      write_exr(frame_name(o.out_dir, i, "exr", e == 0 ? "-left" : "-right"), f[e].gbuffer->width,
                f[e].gbuffer->height, f[e].gbuffer->color);
    }
  }
  previous = clock;
  if (governor) {
    governor->observe(timer);
    write_governor_row(logs.governor, governor->state(), i);
  }
  if (png) {
    auto t = timer.scope("write");
    write_png(frame_name(o.out_dir, i, "png"), side_by_side);
  }
  write_gaze_row(logs.gaze, i, clock, f[0]);
  if (f[0].focus != nullptr) write_focus_row(logs.focus, o.out_dir, i, *f[0].focus);
  if (f[0].gi != nullptr) write_gi_row(logs.gi, o.out_dir, i, *f[0].gi);
  if (f[0].lod != nullptr) write_lod_row(logs.lod, o.out_dir, i, *f[0].lod);
  if (!logs.stereo.is_open()) {
    logs.stereo.open(fs::path(o.out_dir) / "stereo.csv");
    logs.stereo << "frame,ipd_m,fixation_m,left_gaze_x,right_gaze_x,gaze_y,left_shift_x,right_shift_x,"
                   "left_age_at_completion_ms,right_age_at_completion_ms,left_gaze_from,right_gaze_from,right_gaze_y\n";
  }
  // Where each eye's point came from: the tracker's measurement of that eye, or the vergence on the
  // fixation depth from the one (cyclopean) point.
  const auto from = [](const FramePipeline::Frame& e) { return e.eye_gaze_measured ? "tracker" : "vergence"; };
  char line[384];
  std::snprintf(line, sizeof line, "%llu,%.4f,%.4f,%.5f,%.5f,%.5f,%.5f,%.5f,%.3f,%.3f,%s,%s,%.5f\n",
                static_cast<unsigned long long>(i), static_cast<double>(pipeline.scene().camera.ipd_m),
                f[0].fixation_m, f[0].gaze.x, f[1].gaze.x, f[0].gaze.y, f[0].eye_gaze_shift_x, f[1].eye_gaze_shift_x,
                f[0].gaze_age_at_completion_ms, f[1].gaze_age_at_completion_ms, from(f[0]), from(f[1]), f[1].gaze.y);
  logs.stereo << line;
}

// objects.csv (--log-objects): per frame, each object with pixels in the G-buffer: how many, their
// centre (normalised, x right, y down) and median depth.
void write_objects_rows(std::ofstream& log, const std::string& out_dir, std::uint64_t i, const GBuffer& g,
                        const Scene& scene) {
  if (!log.is_open()) {
    log.open(fs::path(out_dir) / "objects.csv");
    log << "frame,object,name,pixels,x,y,median_depth_m\n";
  }
  if (g.object_id.size() != g.size() || g.depth.size() != g.size()) {
    throw std::runtime_error("--log-objects: this frame's G-buffer has no object ids or depths");
  }
  struct Seen {
    double sx = 0, sy = 0;
    std::vector<float> depth;
  };
  std::map<std::uint32_t, Seen> seen;
  for (std::uint32_t y = 0; y < g.height; ++y) {
    for (std::uint32_t x = 0; x < g.width; ++x) {
      const std::uint32_t id = g.object_id[g.index(x, y)];
      if (id == 0) continue;
      Seen& s = seen[id];
      s.sx += x + 0.5;
      s.sy += y + 0.5;
      s.depth.push_back(g.depth[g.index(x, y)]);
    }
  }
  for (auto& [id, s] : seen) {
    const double n = static_cast<double>(s.depth.size());
    auto mid = s.depth.begin() + static_cast<std::ptrdiff_t>(s.depth.size() / 2);
    std::nth_element(s.depth.begin(), mid, s.depth.end());
    const Object* o = scene.object_by_id(id);
    char row[160];
    std::snprintf(row, sizeof row, ",%zu,%.5f,%.5f,%.4f\n", s.depth.size(), s.sx / n / g.width, s.sy / n / g.height,
                  static_cast<double>(*mid));
    log << i << ',' << id << ',' << (o != nullptr ? o->name : std::string()) << row;
  }
}

// One frame's files: its images, then its rows in gaze.csv and in the per-pass CSVs whose pass ran.
void write_frame_files(const RenderOptions& o, std::uint64_t i, double clock, FramePipeline& pipeline,
                       const FramePipeline::Frame& f, PassTimer& timer, CsvLogs& logs) {
  write_frame_images(o, i, pipeline, f, timer);
  write_gaze_row(logs.gaze, i, clock, f);
  if (f.focus != nullptr) write_focus_row(logs.focus, o.out_dir, i, *f.focus);
  if (f.gi != nullptr) write_gi_row(logs.gi, o.out_dir, i, *f.gi);
  if (f.lod != nullptr) write_lod_row(logs.lod, o.out_dir, i, *f.lod);
  if (o.log_objects) write_objects_rows(logs.objects, o.out_dir, i, *f.gbuffer, pipeline.scene());
}

// stdout: what was rendered where, the per-pass timing table and the governor's last state.
void print_summary(const RenderOptions& o, const FramePipeline& pipeline, const GazeInput& gaze, const PassTimer& timer,
                   const Governor* governor) {
  std::printf("fovea-render: %llu frames of %s with %s (gaze %s) -> %s\n", static_cast<unsigned long long>(o.frames),
              o.scene_path.c_str(), pipeline.backend().name().c_str(), gaze.description().c_str(), o.out_dir.c_str());
  std::printf("%s", timer.summary_table().c_str());
  if (governor) std::printf("governor: %s\n", governor->state().summary().c_str());
}

}  // namespace

int run_headless(const RenderOptions& o) {
  if (!headless_options_given(o)) return 2;
  // The governor's fronts are read (and refused) before anything is written.
  std::unique_ptr<Governor> governor = make_governor(o);
  if (!prepare_output_dir(o)) return 2;

  LoadReport load;
  Scene scene = load_render_scene(o, &load);
  const bool stereo = scene.camera.stereo;
  std::unique_ptr<GazeInput> gaze = make_gaze_input(o.gaze);
  const auto backend_start = std::chrono::steady_clock::now();
  FramePipeline pipeline(std::move(scene), o.settings, make_backend(o.backend), *gaze);
  load.add_since("backend", backend_start, backend_load_note(o.backend));
  if (o.verbose) std::fprintf(stderr, "fovea-render: %s\n", load.summary().c_str());
  pipeline.require_cpu_gbuffer(o.exr || o.log_objects);  // the EXR is the G-buffer's colour
  write_plan(o, pipeline, *gaze);
  PassTimer timer((fs::path(o.out_dir) / "timings.csv").string());
  // The load phases as the first rows of frame 0 (load.parse, load.textures, load.lod, load.backend).
  timer.begin_frame(0, 0);
  for (const LoadReport::Phase& phase : load.phases) timer.record("load." + phase.name, phase.ms);
  const bool tty = isatty(STDERR_FILENO) != 0;
  const bool realtime = o.realtime || o.gaze.rfind("udp://", 0) == 0;
  const auto start = std::chrono::steady_clock::now();
  double previous = 0;
  CsvLogs logs;
  open_csv_logs(logs, o.out_dir, governor != nullptr);
  Image8 side_by_side;
  for (std::uint64_t i = 0; i < o.frames; ++i) {
    const double clock = frame_clock_s(i, o.fps, realtime, start);
    if (stereo) {
      render_stereo_frame(o, pipeline, governor.get(), timer, i, clock, previous, realtime, logs, side_by_side);
      if (tty) progress(i + 1, o.frames, timer.last_ms("frame") + timer.last_ms("right.frame"));
      continue;
    }
    const FramePipeline::Frame f = render_one_frame(pipeline, governor.get(), timer, i, clock, previous, realtime);
    if (governor) write_governor_row(logs.governor, governor->state(), i);
    write_frame_files(o, i, clock, pipeline, f, timer, logs);
    if (tty) progress(i + 1, o.frames, timer.last_ms("frame"));
  }
  if (tty) std::fputc('\n', stderr);
  print_summary(o, pipeline, *gaze, timer, governor.get());
  return 0;
}

}  // namespace fovea::render
