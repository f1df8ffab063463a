// SPDX-License-Identifier: Apache-2.0
// Visual attention tracking (Lee 2009 ch. 3): milliseconds per frame of AttentionTracker::update on
// Embree G-buffers of renderer/scenes/attention.json over its 8 s animation, per saliency-map size,
// split into the pixel saliency map (resampling, features, pyramids, eqs. 3.1-3.6) and the object
// stage (eq. 3.7, contexts 3.8-3.10, Kalman, sort); OpenCV's saliency module on the same frames at
// the same map sizes as a peer baseline for the bottom-up map (spectral residual, Hou & Zhang 2007;
// fine-grained, Montabone & Soto 2010); the pixel stage as GL passes (backend/gl/gl_attention.h,
// headless EGL: llvmpipe here, a GPU where there is one) at its GPU time, with the object stage after
// it and its largest S_p difference from the CPU's map; and the object stage alone for 256 synthetic
// objects.
//
// Usage: bench_attention [--frames N] [--csv FILE] [--sizes 512x512,960x540] [--maps 64,128,256,512] [--no-gl]
// Plain table on stdout (median and p95 over the frames; the first frame is a warm-up, not counted).
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/saliency.hpp>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "bench_images.h"
#include "attention/attention.h"
#include "backend/embree/embree_backend.h"
#include "backend/gl/gl_attention.h"
#include "backend/gl/gl_backend.h"
#include "scene/geometry.h"
#include "scene/scene_loader.h"

using namespace fovea::render;
using Clock = std::chrono::steady_clock;

namespace {

struct Stats {
  std::vector<double> ms;
  double median() const { return quantile(0.5); }
  double p95() const { return quantile(0.95); }
  double quantile(double q) const {
    if (ms.empty()) return 0;
    std::vector<double> v = ms;
    std::sort(v.begin(), v.end());
    return v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1) + 0.5)];
  }
};

double ms_since(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

using fovea::bench::to_bgr8;

std::vector<std::pair<std::uint32_t, std::uint32_t>> parse_sizes(const std::string& text) {
  std::vector<std::pair<std::uint32_t, std::uint32_t>> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    unsigned w = 0, h = 0;
    if (std::sscanf(item.c_str(), "%ux%u", &w, &h) != 2 || w == 0 || h == 0) throw std::runtime_error("bad size " + item);
    out.emplace_back(w, h);
  }
  return out;
}

struct Row {
  std::string input, method;
  int map = 0;
  std::size_t frames = 0;
  Stats total, saliency, resample, object;
  std::size_t objects = 0;  // listed objects, last frame
  double vs_cpu = -1;       // GL rows: the largest |S_p(GL) - S_p(CPU)| over the frames
  std::string device = "cpu";
};

// The GL pixel stage and its context; absent (with the reason printed) where EGL has no context.
struct GlRows {
  std::unique_ptr<GlBackend> context;
  std::unique_ptr<GlAttention> attention;
  std::string device;
  // Per implementation (fragment, compute) and map size: the object stage after the GPU's.
  std::map<int, attention::AttentionTracker> trackers[2];
  std::vector<float> saliency;
  std::vector<attention::ObjectPixels> pixels;
};

// One frame's pixel stage on the GPU and the object stage after it into `r`; `cpu` is the CPU's frame
// of the same settings (the map the GPU's is compared with).
void time_gl(GlRows& gl, GlAttention::Pass pass, int map, const GBuffer& g, const Scene& scene, double t,
             double previous, const attention::AttentionFrame& cpu, Row* r) {
  attention::AttentionTracker& tracker = gl.trackers[pass == GlAttention::Pass::Compute ? 1 : 0].at(map);
  GlAttentionObjects objects;
  for (const Object& o : scene.objects) {
    objects.ids.push_back(o.id);
    objects.motion.push_back(tracker.object_motion(o, t, previous));
  }
  double gpu_ms = 0;
  gl.attention->run_gbuffer(g, scene.camera.near_m, scene.camera.far_m, tracker.settings(), objects, gl.pixels, &gpu_ms,
                            pass);
  const auto start = Clock::now();
  const attention::AttentionFrame& f = tracker.update_objects(gl.pixels, map, scene, t, previous, gpu_ms * 1e-3);
  const double object_ms = ms_since(start);
  if (r == nullptr) return;  // warm-up
  r->total.ms.push_back(gpu_ms + object_ms);
  r->saliency.ms.push_back(gpu_ms);
  r->object.ms.push_back(object_ms);
  r->objects = f.objects.size();
  r->device = gl.device;
  gl.attention->read_saliency(gl.saliency);
  double worst = 0;
  for (std::size_t i = 0; i < gl.saliency.size() && i < cpu.saliency.size(); ++i)
    worst = std::max(worst, static_cast<double>(std::fabs(gl.saliency[i] - cpu.saliency[i])));
  r->vs_cpu = std::max(r->vs_cpu, worst);
}

// 256 objects, each a 32x32 patch of its own colour and depth in a 512x512 G-buffer; the camera
// moves forward and a quarter of the objects move.
void synthetic_objects(std::vector<Row>& rows, int frames) {
  Scene scene;
  scene.camera.position = {0, 0, 0};
  scene.camera.target = {0, 0, -1};
  scene.camera.far_m = 100;
  Animation forward;
  forward.loop = false;
  forward.keys = {{0, {0, 0, 0}, {}}, {100, {0, 0, -100}, {}}};
  scene.camera.animation = forward;
  const auto mesh = std::make_shared<Mesh>(make_box({0.5f, 0.5f, 0.5f}));
  GBuffer g;
  g.resize(512, 512);
  for (std::uint32_t k = 0; k < 256; ++k) {
    Object o;
    o.id = k + 1;
    o.mesh = mesh;
    o.task_importance = 0.1f + 0.9f * static_cast<float>(k % 17) / 16.0f;
    o.transform.translation = {static_cast<float>(k % 16) - 8, static_cast<float>(k / 16) - 8, -3 - static_cast<float>(k % 23)};
    if (k % 4 == 0) {
      Animation a;
      a.keys = {{0, {}, {}}, {2, {1, 0, -3}, {0, 180, 0}}, {4, {}, {}}};
      o.animation = a;
    }
    scene.objects.push_back(o);
    const std::uint32_t x0 = (k % 16) * 32, y0 = (k / 16) * 32;
    for (std::uint32_t y = y0; y < y0 + 32; ++y) {
      for (std::uint32_t x = x0; x < x0 + 32; ++x) {
        const std::size_t i = g.index(x, y);
        g.color[i] = glm::vec3(static_cast<float>(k % 5) / 4, static_cast<float>(k % 7) / 6, static_cast<float>(k % 3) / 2);
        g.depth[i] = 3 + static_cast<float>(k % 23);
        g.object_id[i] = k + 1;
      }
    }
  }
  for (int map : {64, 256}) {
    attention::AttentionSettings s;
    s.map_size = map;
    attention::AttentionTracker tracker(s);
    Row row{"synthetic 256 objects 512x512", "fovea object stage", map, 0, {}, {}, {}, {}, 0};
    for (int k = 0; k <= frames; ++k) {
      const double t = k / 60.0;
      const auto& f = tracker.update(g, scene, t, k == 0 ? t : t - 1.0 / 60);
      if (k == 0) continue;
      row.total.ms.push_back(f.seconds * 1e3);
      row.saliency.ms.push_back(f.saliency_seconds * 1e3);
      row.resample.ms.push_back(f.resample_seconds * 1e3);
      row.object.ms.push_back((f.seconds - f.saliency_seconds) * 1e3);
      row.objects = f.objects.size();
    }
    row.frames = row.total.ms.size();
    rows.push_back(std::move(row));
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Attention tracking (Lee 2009 ch. 3) time per frame versus map size, with OpenCV saliency as a peer"};
  int frames = 40, rounds = 1;
  std::string csv_path, sizes_text = "512x512,960x540", maps_text = "64,128,256,512";
  // The bundled scene: FOVEA_SOURCE_DIR in the environment (a copy of the tree elsewhere, as on the
  // device machine), else the tree this was built from.
  const char* env_src = std::getenv("FOVEA_SOURCE_DIR");
  std::string scene_path =
      std::string(env_src != nullptr && *env_src != '\0' ? env_src : FOVEA_SOURCE_DIR) + "/renderer/scenes/attention.json";
  app.add_option("--frames", frames, "frames over the scene's 8 s animation")->check(CLI::Range(5, 100000));
  app.add_option("--rounds", rounds, "time every stored frame this many times (more samples, same frames)")
      ->check(CLI::Range(1, 1000));
  app.add_option("--csv", csv_path, "also write the table as CSV");
  app.add_option("--sizes", sizes_text, "G-buffer resolutions, WxH comma-separated");
  app.add_option("--scene", scene_path, "scene file");
  app.add_option("--maps", maps_text, "saliency-map sizes, comma-separated (64..512)");
  bool no_gl = false;
  app.add_flag("--no-gl", no_gl, "skip the GL pixel stage's rows");
  CLI11_PARSE(app, argc, argv);

  GlRows gl;
  if (!no_gl) {
    try {
      gl.context = std::make_unique<GlBackend>();
      gl.context->context().make_current();
      gl.attention = std::make_unique<GlAttention>(gl.context->context().features().at_least(4, 3));
      gl.device = "OpenGL " + gl.context->context().features().version() + " (" + gl.context->context().renderer() + ")";
      std::printf("gl rows on %s\n", gl.device.c_str());
    } catch (const std::exception& e) {
      std::printf("gl rows skipped: %s\n", e.what());
      gl.attention.reset();
    }
  }

  cv::setNumThreads(1);  // the tracker runs on one thread; compare like with like
  std::vector<Row> rows;
  std::vector<int> maps;
  for (const auto& [m, unused] : parse_sizes(std::regex_replace(maps_text, std::regex("(\\d+)"), "$1x1"))) {
    maps.push_back(static_cast<int>(m));
  }
  for (const auto& [w, h] : parse_sizes(sizes_text)) {
    Scene scene = load_scene(scene_path);
    scene.camera.width = w;
    scene.camera.height = h;
    EmbreeBackend backend;
    backend.set_scene(scene);
    const std::string input = scene.name + " " + std::to_string(w) + "x" + std::to_string(h);
    std::map<int, attention::AttentionTracker> trackers, nearest;  // attention.resample box / nearest
    std::map<std::string, Row> by_key;
    const auto row_for = [&](const std::string& method, int map) -> Row& {
      Row& r = by_key[method + "/" + std::to_string(1000 + map)];
      r.input = input;
      r.method = method;
      r.map = map;
      return r;
    };
    for (int m : maps) {
      attention::AttentionSettings s;
      s.map_size = m;
      trackers.emplace(m, attention::AttentionTracker(s));
      for (auto& by_map : gl.trackers) by_map.insert_or_assign(m, attention::AttentionTracker(s));
      s.resample = attention::Resample::Nearest;
      nearest.emplace(m, attention::AttentionTracker(s));
    }
    auto spectral = cv::saliency::StaticSaliencySpectralResidual::create();
    auto fine = cv::saliency::StaticSaliencyFineGrained::create();
    // Render every frame first, then time the methods over the stored frames: the renderer's own
    // time and cache traffic do not land between the timed updates.
    std::vector<GBuffer> frames_g(static_cast<std::size_t>(frames) + 1);
    std::vector<cv::Mat> frames_bgr;
    for (int k = 0; k <= frames; ++k) {
      const double t = 8.0 * k / frames, previous = k == 0 ? t : t - 1.0 / 60;
      backend.render({t, previous}, {}, frames_g[static_cast<std::size_t>(k)]);
      frames_bgr.push_back(to_bgr8(frames_g[static_cast<std::size_t>(k)]));
    }
    for (int round = 0; round < rounds; ++round) {
    for (int k = 0; k <= frames; ++k) {
      const double t = 8.0 * k / frames, previous = k == 0 ? t : t - 1.0 / 60;
      const GBuffer& g = frames_g[static_cast<std::size_t>(k)];
      const cv::Mat& bgr = frames_bgr[static_cast<std::size_t>(k)];
      for (int m : maps) {
        const auto& fn = nearest.at(m).update(g, scene, t, previous);
        if (k > 0 || round > 0) {
          Row& r = row_for("fovea, nearest resample", m);
          r.total.ms.push_back(fn.seconds * 1e3);
          r.saliency.ms.push_back(fn.saliency_seconds * 1e3);
          r.resample.ms.push_back(fn.resample_seconds * 1e3);
          r.object.ms.push_back((fn.seconds - fn.saliency_seconds) * 1e3);
          r.objects = fn.objects.size();
        }
        const auto& f = trackers.at(m).update(g, scene, t, previous);
        if (gl.attention) {  // the fragment passes, and the compute passes where the context has them
          gl.context->context().make_current();
          const bool warm_up = k == 0 && round == 0;
          time_gl(gl, GlAttention::Pass::Fragment, m, g, scene, t, previous, f,
                  warm_up ? nullptr : &row_for("fovea gl (GPU pixel stage)", m));
          if (gl.attention->has_compute()) {
            time_gl(gl, GlAttention::Pass::Compute, m, g, scene, t, previous, f,
                    warm_up ? nullptr : &row_for("fovea gl compute (GPU pixel stage)", m));
          }
        }
        cv::Mat small, out;
        auto start = Clock::now();
        cv::resize(bgr, small, cv::Size(m, m), 0, 0, cv::INTER_AREA);
        spectral->computeSaliency(small, out);
        const double spectral_ms = ms_since(start);
        start = Clock::now();
        cv::resize(bgr, small, cv::Size(m, m), 0, 0, cv::INTER_AREA);
        fine->computeSaliency(small, out);
        const double fine_ms = ms_since(start);
        if (k == 0 && round == 0) continue;  // warm-up
        Row& r = row_for("fovea (Lee 2009)", m);
        r.total.ms.push_back(f.seconds * 1e3);
        r.saliency.ms.push_back(f.saliency_seconds * 1e3);
        r.resample.ms.push_back(f.resample_seconds * 1e3);
        r.object.ms.push_back((f.seconds - f.saliency_seconds) * 1e3);
        r.objects = f.objects.size();
        row_for("opencv spectral residual", m).saliency.ms.push_back(spectral_ms);
        row_for("opencv spectral residual", m).total.ms.push_back(spectral_ms);
        row_for("opencv fine grained", m).saliency.ms.push_back(fine_ms);
        row_for("opencv fine grained", m).total.ms.push_back(fine_ms);
      }
    }
    }
    for (auto& [key, r] : by_key) {
      r.frames = r.total.ms.size();
      rows.push_back(std::move(r));
    }
  }
  synthetic_objects(rows, std::max(frames, 30));

  std::printf("%-32s %-26s %5s %6s %10s %10s %12s %12s %10s %8s\n", "input", "method", "map", "frames", "total_ms",
              "p95_ms", "saliency_ms", "resample_ms", "object_ms", "objects");
  std::ofstream csv;
  if (!csv_path.empty()) {
    csv.open(csv_path);
    if (!csv) {
      std::cerr << "cannot write " << csv_path << "\n";
      return 1;
    }
    csv << "input,method,map,frames,total_median_ms,total_p95_ms,saliency_median_ms,resample_median_ms,object_median_ms,"
           "objects,gl_vs_cpu_max_diff,device\n";
  }
  for (const Row& r : rows) {
    const bool ours = r.method.rfind("fovea", 0) == 0;
    std::printf("%-32s %-26s %5d %6zu %10.3f %10.3f %12.3f %12s %10s %8s\n", r.input.c_str(), r.method.c_str(), r.map,
                r.frames, r.total.median(), r.total.p95(), r.saliency.median(),
                ours ? std::to_string(r.resample.median()).substr(0, 6).c_str() : "-",
                ours ? std::to_string(r.object.median()).substr(0, 6).c_str() : "-",
                ours ? std::to_string(r.objects).c_str() : "-");
    if (csv) {
      csv << r.input << "," << r.method << "," << r.map << "," << r.frames << "," << r.total.median() << ","
          << r.total.p95() << "," << r.saliency.median() << "," << (ours ? std::to_string(r.resample.median()) : "") << ","
          << (ours ? std::to_string(r.object.median()) : "")
          << "," << (ours ? std::to_string(r.objects) : "") << "," << (r.vs_cpu >= 0 ? std::to_string(r.vs_cpu) : "")
          << ",\"" << r.device << "\"\n";
    }
  }
  return 0;
}
