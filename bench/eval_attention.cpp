// SPDX-License-Identifier: Apache-2.0
// Attention prediction accuracy (Lee 2009 §3.5): replays a gaze recording (.fgr) against a scene's
// playback and reports A1/A2/A3 (the gazed object is among the top 1/2/3 predicted objects), the
// feature-group ablation of Lee's Table 3.2 (B, E, T on/off, 8 combinations), the random-pixel
// baseline, OpenCV's saliency module in place of our bottom-up map, and the saliency-map size versus
// accuracy versus ms/frame.
//
//   fovea-eval-attention synth-viewer --scene S.json --seconds 60 --rate 60 --seed 1 --out V.fgr
//   fovea-eval-attention evaluate --scene S.json --gaze V.fgr [--offset-s 0] [--fps 30]
//                        [--map-sizes 64,128,256] [--width 480 --height 270] [--out DIR]
//
// synth-viewer is a synthetic observer for scenes without real recordings. It shares assumptions with
// the model (it prefers objects of high task importance near the screen centre), so the A-figures it
// yields are optimistic; real figures need recordings of people (evaluate takes any .fgr).
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <numbers>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/saliency.hpp>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench_images.h"
#include "attention/attention.h"
#include "backend/embree/embree_backend.h"
#include "fovea/protocol/display_geometry.h"
#include "fovea/protocol/messages.h"
#include "fovea/protocol/recording.h"
#include "scene/scene_loader.h"

using namespace fovea::render;
namespace proto = fovea::protocol;
using Clock = std::chrono::steady_clock;

namespace {

constexpr const char* kSynthDevice = "fovea-eval-attention synth-viewer";
constexpr const char* kCaveat =
    "CAVEAT: the synthetic viewer shares assumptions with the model (it fixates objects in proportion to "
    "their task importance T_i and prefers the screen centre, as T_i and the spatial context T_s do), so "
    "A-figures measured on its recordings are optimistic; real figures need recordings of people "
    "(evaluate takes any .fgr).";

struct Failure : std::runtime_error {
  using std::runtime_error::runtime_error;
};

Scene load(const std::string& path, std::uint32_t w, std::uint32_t h) {
  if (!std::filesystem::exists(path)) throw Failure("scene file not found: " + path);
  Scene scene = load_scene(path);
  scene.camera.width = w;
  scene.camera.height = h;
  return scene;
}

// T_i per object id (0 for ids that name no object).
std::vector<float> importance_by_id(const Scene& scene) {
  std::uint32_t max_id = 0;
  for (const Object& o : scene.objects) max_id = std::max(max_id, o.id);
  std::vector<float> t(std::size_t{max_id} + 1, 0.0f);
  for (const Object& o : scene.objects) t[o.id] = o.task_importance;
  return t;
}

float importance(const std::vector<float>& t, std::uint32_t id) { return id < t.size() ? t[id] : 0.0f; }

// Normalised screen extent of `deg` degrees of visual angle at the screen centre, along x and y.
double deg_to_norm_x(const proto::DisplayGeometry& d, double deg) {
  return 2.0 * d.viewing_distance_m * std::tan(deg * std::numbers::pi / 360.0) / d.width_m;
}
double deg_to_norm_y(const proto::DisplayGeometry& d, double deg) {
  return 2.0 * d.viewing_distance_m * std::tan(deg * std::numbers::pi / 360.0) / d.height_m;
}

struct Visible {
  std::size_t pixels = 0;
  double sum_x = 0, sum_y = 0;
  double cx() const { return sum_x / static_cast<double>(pixels); }
  double cy() const { return sum_y / static_cast<double>(pixels); }
};

// Visible foreground objects (T_i > 0) of an item buffer: pixel count and centroid (normalised).
std::map<std::uint32_t, Visible> visible_foreground(const GBuffer& g, const std::vector<float>& t) {
  std::map<std::uint32_t, Visible> out;
  for (std::uint32_t y = 0; y < g.height; ++y) {
    for (std::uint32_t x = 0; x < g.width; ++x) {
      const std::uint32_t id = g.object_id[g.index(x, y)];
      if (importance(t, id) <= 0.0f) continue;
      Visible& v = out[id];
      ++v.pixels;
      v.sum_x += (x + 0.5) / g.width;
      v.sum_y += (y + 0.5) / g.height;
    }
  }
  return out;
}

// ------------------------------------------------------------------------------------------------
// synth-viewer
// ------------------------------------------------------------------------------------------------

struct SynthOptions {
  std::string scene, out;
  double seconds = 60, rate = 60;
  std::uint64_t seed = 1;
  std::uint32_t width = 160, height = 90;
  double random_share = 0.2, scatter_deg = 0.5, tremor_deg = 0.1, tracker_error_deg = 1.0;
};

int synth_viewer(const SynthOptions& o) {
  Scene scene = load(o.scene, o.width, o.height);
  const auto t_of = importance_by_id(scene);
  const proto::DisplayGeometry& disp = scene.display;
  EmbreeBackend backend;
  backend.set_scene(scene);
  std::mt19937_64 rng(o.seed);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  std::normal_distribution<double> gauss(0.0, 1.0);

  const double ux = deg_to_norm_x(disp, 1.0), uy = deg_to_norm_y(disp, 1.0);  // 1 deg, normalised
  const double err_dir = 2 * std::numbers::pi * uni(rng);
  const double err_x = o.tracker_error_deg * ux * std::cos(err_dir), err_y = o.tracker_error_deg * uy * std::sin(err_dir);

  proto::RecordingHeader header;
  header.device = kSynthDevice;
  header.display = disp;
  header.nominal_rate_hz = o.rate;
  header.clock = proto::RecordingClock::Monotonic;
  proto::RecordingWriter writer(o.out, header);

  // The current target: an object (followed while it moves) or a fixed random point; a landing offset.
  struct Target {
    std::uint32_t id = 0;  // 0: a random point
    double px = 0.5, py = 0.5;
    double off_x = 0, off_y = 0;
  } target;
  enum class Phase { Saccade, Fixation } phase = Phase::Fixation;
  double gx = 0.5, gy = 0.5;          // true gaze (without tracker error)
  double sac_x = 0, sac_y = 0;        // saccade start
  std::int64_t phase_start = 0, phase_end = 0;  // samples
  std::size_t fixations = 0, on_objects = 0, saccade_samples = 0;
  double prev_x = -1, prev_y = -1;

  const auto choose = [&](const std::map<std::uint32_t, Visible>& vis) {
    Target t;
    t.off_x = o.scatter_deg * ux * gauss(rng);
    t.off_y = o.scatter_deg * uy * gauss(rng);
    const double total = static_cast<double>(std::size_t{o.width} * o.height);
    std::vector<std::pair<std::uint32_t, double>> w;
    double sum = 0;
    for (const auto& [id, v] : vis) {
      const double rx = 2 * (v.cx() - 0.5), ry = 2 * (v.cy() - 0.5);
      const double r2 = (rx * rx + ry * ry) / 2;  // a screen corner at 1
      const double wi = static_cast<double>(importance(t_of, id)) * std::sqrt(static_cast<double>(v.pixels) / total) *
                        std::exp(-2.0 * r2);
      w.emplace_back(id, wi);
      sum += wi;
    }
    if (uni(rng) < o.random_share || sum <= 0) {
      t.px = 0.02 + 0.96 * uni(rng);
      t.py = 0.02 + 0.96 * uni(rng);
      return t;
    }
    double pick = uni(rng) * sum;
    t.id = w.back().first;
    for (const auto& [id, wi] : w) {
      if (pick < wi) {
        t.id = id;
        break;
      }
      pick -= wi;
    }
    return t;
  };
  const auto target_pos = [&](const std::map<std::uint32_t, Visible>& vis, double& x, double& y) {
    if (target.id != 0) {
      const auto it = vis.find(target.id);
      if (it == vis.end()) return false;
      target.px = it->second.cx();
      target.py = it->second.cy();
    }
    x = target.px + target.off_x;
    y = target.py + target.off_y;
    return true;
  };
  const auto fixation_samples = [&] { return static_cast<std::int64_t>(std::lround((0.2 + 0.4 * uni(rng)) * o.rate)); };

  const auto n = static_cast<std::int64_t>(std::llround(o.seconds * o.rate));
  GBuffer g;
  for (std::int64_t k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) / o.rate;
    backend.render({t, k == 0 ? t : t - 1.0 / o.rate}, {}, g);
    const auto vis = visible_foreground(g, t_of);
    double tx = 0, ty = 0;
    bool lost = phase == Phase::Fixation && !target_pos(vis, tx, ty);
    if (k == 0 || (phase == Phase::Fixation && (k >= phase_end || lost))) {
      target = choose(vis);
      ++fixations;
      if (target.id != 0) ++on_objects;
      target_pos(vis, tx, ty);
      if (k == 0) {
        phase = Phase::Fixation;
        phase_start = 0;
        phase_end = fixation_samples();
        gx = tx;
        gy = ty;
      } else {
        // Main sequence: duration 2.2 ms/deg + 21 ms.
        const proto::Degrees a = proto::normalized_to_degrees(disp, {gx, gy});
        const proto::Degrees b = proto::normalized_to_degrees(disp, {tx, ty});
        const double amp = proto::angle_between_deg(a, b);
        const double dur_s = (2.2 * amp + 21) / 1000;
        phase = Phase::Saccade;
        sac_x = gx;
        sac_y = gy;
        phase_start = k;
        phase_end = k + std::max<std::int64_t>(1, std::llround(dur_s * o.rate));
      }
    }
    proto::EyeMovement state = proto::EyeMovement::Fixation;
    if (phase == Phase::Saccade) {
      if (!target_pos(vis, tx, ty)) {  // the object went out of sight: land where it was last seen
        tx = target.px + target.off_x;
        ty = target.py + target.off_y;
      }
      const double tau = static_cast<double>(k - phase_start + 1) / static_cast<double>(phase_end - phase_start);
      const double s = 0.5 - 0.5 * std::cos(std::numbers::pi * std::min(1.0, tau));
      gx = sac_x + (tx - sac_x) * s;
      gy = sac_y + (ty - sac_y) * s;
      state = proto::EyeMovement::Saccade;
      ++saccade_samples;
      if (k + 1 >= phase_end) {
        phase = Phase::Fixation;
        phase_start = k + 1;
        phase_end = k + 1 + fixation_samples();
      }
    } else {
      gx = tx;
      gy = ty;
    }
    double x = gx + err_x, y = gy + err_y;
    if (state == proto::EyeMovement::Fixation) {
      x += o.tremor_deg * ux * gauss(rng);
      y += o.tremor_deg * uy * gauss(rng);
    }
    x = std::clamp(x, 0.0, 1.0);
    y = std::clamp(y, 0.0, 1.0);
    proto::GazeSample sample;
    sample.tracker_time_ns = static_cast<std::int64_t>(std::llround(t * 1e9));
    sample.x = static_cast<float>(x);
    sample.y = static_cast<float>(y);
    const proto::Degrees d = proto::normalized_to_degrees(disp, {x, y});
    sample.x_deg = static_cast<float>(d.x);
    sample.y_deg = static_cast<float>(d.y);
    if (prev_x >= 0) {
      const double v = proto::angle_between_deg(proto::normalized_to_degrees(disp, {prev_x, prev_y}), d) * o.rate;
      sample.angular_velocity_deg_s = static_cast<float>(v);
    }
    prev_x = x;
    prev_y = y;
    sample.confidence = 1.0f;
    sample.state = state;
    sample.flags = proto::kGazeValid;
    writer.append(proto::Record{static_cast<std::uint64_t>(k), sample});
  }
  writer.sync();
  std::printf("wrote %s: %lld samples at %g Hz over %g s of %s, %zu fixations (%zu on objects, %zu on random points), "
              "%zu saccade samples, tracker error %.2f deg at %.0f deg\n",
              o.out.c_str(), static_cast<long long>(n), o.rate, o.seconds, o.scene.c_str(), fixations, on_objects,
              fixations - on_objects, saccade_samples, o.tracker_error_deg, err_dir * 180 / std::numbers::pi);
  std::printf("%s\n", kCaveat);
  return 0;
}

// ------------------------------------------------------------------------------------------------
// evaluate
// ------------------------------------------------------------------------------------------------

struct EvalOptions {
  std::string scene, gaze, out;
  double offset_s = 0, fps = 30;
  std::string map_sizes = "64,128,256";
  int ablation_map = 0;  // 0: the largest of map_sizes
  std::uint32_t width = 480, height = 270;
  std::uint64_t seed = 1;
};

// One method's ranking score over the scored frames.
struct Score {
  std::string section, method;
  int b = -1, e = -1, t = -1;  // feature groups (ablation and sweep rows), -1: not applicable
  int map = 0;
  std::size_t frames = 0, hits[3] = {0, 0, 0};
  double ms_sum = 0;
  std::size_t ms_n = 0;
  double a(int k) const { return frames ? static_cast<double>(hits[k]) / static_cast<double>(frames) : 0.0; }
  double ms() const { return ms_n ? ms_sum / static_cast<double>(ms_n) : 0.0; }
  void add(std::uint32_t gazed, const std::vector<std::uint32_t>& ranked) {
    ++frames;
    if (gazed == 0) return;
    for (std::size_t k = 0; k < 3; ++k) {
      if (k < ranked.size() && ranked[k] == gazed) {
        for (std::size_t j = k; j < 3; ++j) ++hits[j];
        break;
      }
    }
  }
};

std::vector<int> parse_maps(const std::string& text) {
  std::vector<int> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    std::size_t used = 0;
    int m = 0;
    try {
      m = std::stoi(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != item.size() || m < 64 || m > 512) throw Failure("--map-sizes: bad size '" + item + "': allowed 64..512");
    out.push_back(m);
  }
  if (out.empty()) throw Failure("--map-sizes: no size given");
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

using fovea::bench::to_bgr8;

std::vector<std::uint32_t> top3(const attention::AttentionFrame& f) {
  std::vector<std::uint32_t> r;
  for (std::size_t k = 0; k < f.objects.size() && k < 3; ++k) r.push_back(f.objects[k].id);
  return r;
}

// OpenCV's saliency in place of S_p: per object the mean of the OpenCV map (resampled to the
// tracker's m x m map) over the object's map pixels, times T_i (eq. 3.7), optionally times
// T_s + T_t of the full model (eq. 3.8). No Kalman filter.
std::vector<std::uint32_t> opencv_ranking(const cv::Mat& sal, const attention::AttentionFrame& f,
                                          const std::vector<float>& t_of, bool context) {
  std::map<std::uint32_t, std::pair<double, std::size_t>> sum;
  for (int y = 0; y < f.map_height; ++y) {
    const float* row = sal.ptr<float>(y);
    for (int x = 0; x < f.map_width; ++x) {
      const std::uint32_t id = f.ids[static_cast<std::size_t>(y) * static_cast<std::size_t>(f.map_width) +
                                     static_cast<std::size_t>(x)];
      if (importance(t_of, id) <= 0.0f) continue;
      auto& s = sum[id];
      s.first += static_cast<double>(row[x]);
      ++s.second;
    }
  }
  std::vector<std::pair<double, std::uint32_t>> scored;
  for (const auto& obj : f.objects) {
    const auto it = sum.find(obj.id);
    if (it == sum.end()) continue;
    double s = static_cast<double>(importance(t_of, obj.id)) * it->second.first / static_cast<double>(it->second.second);
    if (context) s *= obj.spatial + obj.temporal;
    scored.emplace_back(-s, obj.id);
  }
  std::sort(scored.begin(), scored.end());
  std::vector<std::uint32_t> r;
  for (std::size_t k = 0; k < scored.size() && k < 3; ++k) r.push_back(scored[k].second);
  return r;
}

cv::Mat opencv_map(cv::saliency::StaticSaliency& method, const cv::Mat& bgr, int m, double& ms) {
  const auto start = Clock::now();
  cv::Mat small, out, f;
  cv::resize(bgr, small, cv::Size(m, m), 0, 0, cv::INTER_AREA);
  if (!method.computeSaliency(small, out)) throw Failure("OpenCV computeSaliency failed");
  ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
  out.convertTo(f, CV_32F);
  if (f.rows != m || f.cols != m) cv::resize(f, f, cv::Size(m, m), 0, 0, cv::INTER_LINEAR);
  return f;
}

int evaluate(const EvalOptions& o) {
  const std::vector<int> maps = parse_maps(o.map_sizes);
  const int amap = o.ablation_map ? o.ablation_map : maps.back();
  if (amap < 64 || amap > 512) throw Failure("--ablation-map: allowed 64..512");
  Scene scene = load(o.scene, o.width, o.height);
  const auto t_of = importance_by_id(scene);
  if (!std::filesystem::exists(o.gaze)) throw Failure("gaze recording not found: " + o.gaze);
  const proto::Recording rec = proto::read_recording(o.gaze);
  std::vector<proto::GazeSample> samples;
  for (const auto& r : rec.records) {
    if (const auto* s = std::get_if<proto::GazeSample>(&r.item)) samples.push_back(*s);
  }
  if (samples.empty()) throw Failure(o.gaze + ": the recording holds no gaze samples");
  std::stable_sort(samples.begin(), samples.end(),
                   [](const auto& a, const auto& b) { return a.tracker_time_ns < b.tracker_time_ns; });
  const bool synthetic = rec.header.device == kSynthDevice;

  // Lee §3.5.2: only fixation and drift. With states: Fixation counts; Saccade, Pursuit, Blink and
  // Unknown do not. Without states: |p_k - p_{k-1}| (normalised, per sample) < 0.03 fixation,
  // < 0.1 drift, else saccade; a sample after an invalid one has no velocity and is left out.
  bool has_state = false;
  for (const auto& s : samples) has_state |= s.state != proto::EyeMovement::Unknown;
  const std::size_t ns = samples.size();
  std::vector<char> keep(ns, 0);
  std::vector<double> stime(ns);
  const std::int64_t t0 = samples.front().tracker_time_ns;
  std::size_t n_fix = 0, n_drift = 0;
  for (std::size_t i = 0; i < ns; ++i) {
    const auto& s = samples[i];
    stime[i] = static_cast<double>(s.tracker_time_ns - t0) * 1e-9 + o.offset_s;
    const bool valid = (s.flags & proto::kGazeValid) != 0 && std::isfinite(s.x) && std::isfinite(s.y);
    if (!valid) continue;
    if (has_state) {
      keep[i] = s.state == proto::EyeMovement::Fixation;
      if (keep[i]) ++n_fix;
    } else if (i > 0 && (samples[i - 1].flags & proto::kGazeValid) != 0) {
      const double v = std::hypot(static_cast<double>(s.x - samples[i - 1].x), static_cast<double>(s.y - samples[i - 1].y));
      keep[i] = v < 0.1;
      if (keep[i]) ++(v < 0.03 ? n_fix : n_drift);
    }
  }
  const double first = stime.front(), last = stime.back();
  const auto k0 = static_cast<std::int64_t>(std::ceil(std::max(0.0, first) * o.fps - 1e-9));
  const auto k1 = static_cast<std::int64_t>(std::floor(last * o.fps + 1e-9));
  if (last < 0 || k1 < k0) {
    std::ostringstream msg;
    msg << o.gaze << ": no gaze sample falls in the scene's time range (scene time >= 0): the samples cover scene "
        << "time " << first << " .. " << last << " s with --offset-s " << o.offset_s;
    throw Failure(msg.str());
  }

  EmbreeBackend backend;
  backend.set_scene(scene);
  // Ablation trackers (index b*4 + e*2 + t) at the ablation map; full-model trackers for the other sizes.
  std::vector<attention::AttentionTracker> ablation;
  std::vector<Score> ablation_scores;
  for (int b = 0; b < 2; ++b) {
    for (int e = 0; e < 2; ++e) {
      for (int t = 0; t < 2; ++t) {
        attention::AttentionSettings s;
        s.map_size = amap;
        s.groups = {b == 1, e == 1, t == 1};
        ablation.emplace_back(s);
        Score sc;
        sc.section = "ablation";
        sc.method = "fovea";
        sc.b = b;
        sc.e = e;
        sc.t = t;
        sc.map = amap;
        ablation_scores.push_back(sc);
      }
    }
  }
  constexpr std::size_t kFull = 7;
  std::map<int, attention::AttentionTracker> sweep;
  std::map<int, Score> sweep_scores;
  // Keys: m for box resampling, -m for nearest (attention.resample), both full model.
  for (int m : maps) {
    for (const int key : {m, -m}) {
      if (key != amap) {
        attention::AttentionSettings s;
        s.map_size = m;
        s.resample = key < 0 ? attention::Resample::Nearest : attention::Resample::Box;
        sweep.emplace(key, attention::AttentionTracker(s));
      }
      Score sc;
      sc.section = "map_size";
      sc.method = key < 0 ? "fovea nearest" : "fovea";
      sc.b = sc.e = sc.t = 1;
      sc.map = m;
      sweep_scores[key] = sc;
    }
  }
  const auto baseline = [&](const std::string& method, int t) {
    Score sc;
    sc.section = "baseline";
    sc.method = method;
    sc.t = t;
    sc.map = method == "random pixel" ? 0 : amap;
    return sc;
  };
  Score random = baseline("random pixel", -1);
  Score sr_plain = baseline("opencv spectral residual", 0), sr_ctx = baseline("opencv spectral residual", 1);
  Score fg_plain = baseline("opencv fine grained", 0), fg_ctx = baseline("opencv fine grained", 1);
  cv::setNumThreads(1);
  auto spectral = cv::saliency::StaticSaliencySpectralResidual::create();
  auto fine = cv::saliency::StaticSaliencyFineGrained::create();
  std::mt19937_64 rng(o.seed);
  std::uniform_int_distribution<std::size_t> pixel(0, std::size_t{o.width} * o.height - 1);
  const double radius_px = proto::degrees_to_image_pixels(scene.display, o.width, 1.0);
  const int r = static_cast<int>(std::ceil(radius_px));

  std::size_t frames = 0, no_sample = 0, not_fixation = 0, background_only = 0, scored = 0, gaze_miss = 0,
              snapped = 0;
  // Per object: scored frames it was gazed at, and frames the full model ranked it first (0: none).
  std::map<std::uint32_t, std::pair<std::size_t, std::size_t>> who;
  GBuffer g;
  std::size_t j = 0;  // sample cursor
  const auto wall = Clock::now();
  for (std::int64_t k = k0; k <= k1; ++k) {
    const double t = static_cast<double>(k) / o.fps, prev = k == k0 ? t : t - 1.0 / o.fps;
    backend.render({t, prev}, {}, g);
    ++frames;
    const attention::AttentionFrame* full = nullptr;
    std::vector<std::vector<std::uint32_t>> ranks(8);
    for (std::size_t c = 0; c < 8; ++c) {
      const auto& f = ablation[c].update(g, scene, t, prev);
      ranks[c] = top3(f);
      ablation_scores[c].ms_sum += f.seconds * 1e3;
      ++ablation_scores[c].ms_n;
      if (c == kFull) full = &f;
    }
    std::map<int, std::vector<std::uint32_t>> sweep_ranks;
    for (auto& [m, tracker] : sweep) {
      const auto& f = tracker.update(g, scene, t, prev);
      sweep_ranks[m] = top3(f);
      sweep_scores[m].ms_sum += f.seconds * 1e3;
      ++sweep_scores[m].ms_n;
    }
    sweep_ranks[amap] = ranks[kFull];
    sweep_scores[amap].ms_sum += full->seconds * 1e3;
    ++sweep_scores[amap].ms_n;
    const cv::Mat bgr = to_bgr8(g);
    double sr_ms = 0, fg_ms = 0;
    const cv::Mat sr_map = opencv_map(*spectral, bgr, amap, sr_ms);
    const cv::Mat fg_map = opencv_map(*fine, bgr, amap, fg_ms);
    for (Score* s : {&sr_plain, &sr_ctx, &fg_plain, &fg_ctx}) {
      s->ms_sum += s->method == "opencv fine grained" ? fg_ms : sr_ms;
      ++s->ms_n;
    }

    // The sample nearest to this frame, within half a frame.
    while (j + 1 < ns && std::abs(stime[j + 1] - t) <= std::abs(stime[j] - t)) ++j;
    if (std::abs(stime[j] - t) > 0.5 / o.fps + 1e-9) {
      ++no_sample;
      continue;
    }
    if (!keep[j]) {
      ++not_fixation;
      continue;
    }
    bool any_foreground = false;
    for (std::uint32_t id : g.object_id) {
      if (importance(t_of, id) > 0.0f) {
        any_foreground = true;
        break;
      }
    }
    if (!any_foreground) {
      ++background_only;
      continue;
    }
    ++scored;
    // The gazed object: the foreground object under the gaze point, else the nearest foreground
    // pixel's object within 1 deg of visual angle, else none (a miss for every method).
    const int gx = static_cast<int>(std::floor(static_cast<double>(samples[j].x) * o.width));
    const int gy = static_cast<int>(std::floor(static_cast<double>(samples[j].y) * o.height));
    const auto id_at = [&](int x, int y) -> std::uint32_t {
      if (x < 0 || y < 0 || x >= static_cast<int>(o.width) || y >= static_cast<int>(o.height)) return 0;
      const std::uint32_t id = g.object_id[g.index(static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y))];
      return importance(t_of, id) > 0.0f ? id : 0;
    };
    std::uint32_t gazed = id_at(gx, gy);
    if (gazed == 0) {
      double best = radius_px * radius_px + 1e-9;
      for (int dy = -r; dy <= r; ++dy) {
        for (int dx = -r; dx <= r; ++dx) {
          const double d2 = dx * dx + dy * dy;
          if (d2 > best) continue;
          const std::uint32_t id = id_at(gx + dx, gy + dy);
          if (id != 0 && d2 < best) {
            best = d2;
            gazed = id;
          }
        }
      }
      if (gazed != 0) ++snapped;
    }
    if (gazed == 0) ++gaze_miss;
    ++who[gazed].first;
    if (!ranks[kFull].empty()) ++who[ranks[kFull][0]].second;
    for (std::size_t c = 0; c < 8; ++c) ablation_scores[c].add(gazed, ranks[c]);
    for (auto& [m, sc] : sweep_scores) sc.add(gazed, sweep_ranks[m]);
    // Random pixel: 1, 2 or 3 distinct uniformly random pixels; their objects are the prediction.
    std::vector<std::size_t> px;
    while (px.size() < 3) {
      const std::size_t p = pixel(rng);
      if (std::find(px.begin(), px.end(), p) == px.end()) px.push_back(p);
    }
    std::vector<std::uint32_t> rr;
    for (std::size_t p : px) rr.push_back(g.object_id[p]);
    random.add(gazed, rr);
    sr_plain.add(gazed, opencv_ranking(sr_map, *full, t_of, false));
    sr_ctx.add(gazed, opencv_ranking(sr_map, *full, t_of, true));
    fg_plain.add(gazed, opencv_ranking(fg_map, *full, t_of, false));
    fg_ctx.add(gazed, opencv_ranking(fg_map, *full, t_of, true));
  }
  const double wall_s = std::chrono::duration<double>(Clock::now() - wall).count();
  if (scored == 0) {
    throw Failure(o.gaze + ": no frame to score: " + std::to_string(frames) + " frames, " + std::to_string(no_sample) +
                  " without a sample, " + std::to_string(not_fixation) + " not fixation/drift, " +
                  std::to_string(background_only) + " with only background");
  }

  std::vector<Score> baselines = {random, sr_plain, sr_ctx, fg_plain, fg_ctx};
  std::ostringstream text;
  char line[512];
#define put(...)                                \
  do {                                          \
    std::snprintf(line, sizeof line, __VA_ARGS__); \
    text << line;                               \
  } while (0)
  put("scene %s at %ux%u, %g fps; gaze %s (device '%s', %zu samples; %s: %zu fixation, %zu drift samples kept)\n",
      o.scene.c_str(), o.width, o.height, o.fps, o.gaze.c_str(), rec.header.device.c_str(), ns,
      has_state ? "sample states, Fixation kept" : "no states, velocity rule |dp| < 0.03 fixation, < 0.1 drift", n_fix,
      n_drift);
  put("frames %zu (scene time %.3f .. %.3f s): %zu without a sample within half a frame, %zu not fixation/drift, "
      "%zu with only background; %zu scored, of which %zu with the gaze on no foreground object within 1 deg "
      "(misses for every method) and %zu snapped to the nearest object within 1 deg (%.1f px); %.1f s\n",
      frames, static_cast<double>(k0) / o.fps, static_cast<double>(k1) / o.fps, no_sample, not_fixation,
      background_only, scored, gaze_miss, snapped, radius_px, wall_s);
  if (synthetic) put("%s\n", kCaveat);
  put("\nFeature groups (Lee 2009 Table 3.2), map %dx%d, %zu frames\n", amap, amap, scored);
  put("%-2s %-2s %-2s %7s %7s %7s %18s %10s\n", "B", "E", "T", "A1", "A2", "A3", "hits (1/2/3)", "ms/frame");
  for (const Score& s : ablation_scores) {
    put("%-2d %-2d %-2d %7.3f %7.3f %7.3f %6zu/%5zu/%5zu %10.3f\n", s.b, s.e, s.t, s.a(0), s.a(1), s.a(2), s.hits[0],
        s.hits[1], s.hits[2], s.ms());
  }
  put("\nBaselines, %zu frames\n", scored);
  put("%-28s %-4s %5s %7s %7s %7s %18s %10s\n", "method", "T", "map", "A1", "A2", "A3", "hits (1/2/3)", "ms/frame");
  for (const Score& s : baselines) {
    put("%-28s %-4s %5d %7.3f %7.3f %7.3f %6zu/%5zu/%5zu %10.3f\n", s.method.c_str(),
        s.t < 0 ? "-" : (s.t ? "1" : "0"), s.map, s.a(0), s.a(1), s.a(2), s.hits[0], s.hits[1], s.hits[2], s.ms());
  }
  put("\nMap size and resampling (attention.resample), full model (B E T), %zu frames\n", scored);
  put("%-9s %-8s %7s %7s %7s %18s %10s\n", "map", "resample", "A1", "A2", "A3", "hits (1/2/3)", "ms/frame");
  for (const auto& [key, s] : sweep_scores) {
    put("%4dx%-4d %-8s %7.3f %7.3f %7.3f %6zu/%5zu/%5zu %10.3f\n", s.map, s.map, key < 0 ? "nearest" : "box", s.a(0),
        s.a(1), s.a(2), s.hits[0], s.hits[1], s.hits[2], s.ms());
  }
  put("\nGazed object versus the full model's first choice (map %dx%d), frames\n", amap, amap);
  put("%-20s %5s %8s %10s\n", "object", "T_i", "gazed", "ranked 1st");
  for (const auto& [id, n] : who) {
    const Object* obj = scene.object_by_id(id);
    put("%-20s %5.2f %8zu %10zu\n", id == 0 ? "(none)" : (obj ? obj->name.c_str() : "?"),
        static_cast<double>(importance(t_of, id)), n.first, n.second);
  }
#undef put
  std::cout << text.str();

  if (!o.out.empty()) {
    std::filesystem::create_directories(o.out);
    const std::string csv_path = (std::filesystem::path(o.out) / "eval_attention.csv").string();
    std::ofstream csv(csv_path);
    if (!csv) throw Failure("cannot write " + csv_path);
    csv << "section,method,B,E,T,map,frames,hits_1,hits_2,hits_3,A1,A2,A3,ms_per_frame\n";
    const auto row = [&](const Score& s) {
      const auto flag = [](int v) { return v < 0 ? std::string() : std::to_string(v); };
      csv << s.section << "," << s.method << "," << flag(s.b) << "," << flag(s.e) << "," << flag(s.t) << ","
          << s.map << "," << s.frames << "," << s.hits[0] << "," << s.hits[1] << "," << s.hits[2] << "," << s.a(0)
          << "," << s.a(1) << "," << s.a(2) << "," << s.ms() << "\n";
    };
    for (const Score& s : ablation_scores) row(s);
    for (const Score& s : baselines) row(s);
    for (const auto& [m, s] : sweep_scores) row(s);
    const std::string md_path = (std::filesystem::path(o.out) / "report.md").string();
    std::ofstream md(md_path);
    if (!md) throw Failure("cannot write " + md_path);
    md << "# Attention prediction accuracy (Lee 2009 §3.5)\n\n"
       << "A_k: share of scored frames whose gazed object is among the top k predicted objects. Scored frames: a gaze "
          "sample within half a frame, fixation/drift only, at least one foreground object (T_i > 0) visible. The "
          "gazed object is the foreground object under the gaze point, else the nearest within 1 deg; frames with "
          "neither count as misses. Random pixel: the objects under 1, 2, 3 distinct uniformly random pixels. "
          "OpenCV rows: the OpenCV map (at the map size) averaged per object times T_i (eq. 3.7), with T: times "
          "T_s + T_t of the full model (eq. 3.8), no Kalman filter. ms/frame: mean AttentionTracker::update "
          "(OpenCV rows: resize + computeSaliency).\n\n"
       << "```\n"
       << text.str() << "```\n";
    std::printf("wrote %s and %s\n", csv_path.c_str(), md_path.c_str());
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Attention prediction accuracy (Lee 2009 §3.5): A1/A2/A3 of a gaze recording against a scene's "
               "playback, the B/E/T ablation (Table 3.2), random-pixel and OpenCV saliency baselines, map size "
               "versus accuracy and ms/frame"};
  app.require_subcommand(1);
  app.footer(kCaveat);

  SynthOptions so;
  auto* synth = app.add_subcommand(
      "synth-viewer",
      std::string("A synthetic observer for scenes without real recordings: renders the item buffer along the "
                  "scene's animation and writes gaze samples (.fgr, tracker time = scene time): fixations of "
                  "200-600 ms on visible foreground objects (T_i > 0) chosen in proportion to T_i x sqrt(visible "
                  "pixel share) x a centre bias, 20 % on random points, 0.5 deg landing scatter, a constant 1 deg "
                  "tracker error in a random direction per session, main-sequence saccades (2.2 ms/deg + 21 ms). ") +
          kCaveat);
  synth->add_option("--scene", so.scene, "scene file (JSON)")->required();
  synth->add_option("--out", so.out, "recording to write (.fgr; never overwritten)")->required();
  synth->add_option("--seconds", so.seconds, "length, seconds")->check(CLI::Range(0.1, 36000.0));
  synth->add_option("--rate", so.rate, "sample rate, Hz")->check(CLI::Range(1.0, 2000.0));
  synth->add_option("--seed", so.seed, "random seed");
  synth->add_option("--width", so.width, "item-buffer width the viewer looks at")->check(CLI::Range(16, 4096));
  synth->add_option("--height", so.height, "item-buffer height")->check(CLI::Range(16, 4096));
  synth->add_option("--random-share", so.random_share, "share of fixations on random points")->check(CLI::Range(0.0, 1.0));
  synth->add_option("--tracker-error-deg", so.tracker_error_deg, "constant tracker error, degrees")
      ->check(CLI::Range(0.0, 10.0));

  EvalOptions eo;
  auto* eval = app.add_subcommand(
      "evaluate",
      "Plays the scene at --fps (scene time = sample time - first sample time + --offset-s), renders Embree G-buffers, "
      "takes the nearest gaze sample within half a frame, keeps fixation/drift (Lee §3.5.2: the sample state when the "
      "recording has one, Fixation only; else the velocity |dp| per sample < 0.03 fixation, < 0.1 drift), finds the "
      "gazed foreground object (under the gaze, else nearest within 1 deg) and scores the top 1/2/3 objects of: the "
      "8 feature-group combinations B/E/T (one tracker each, fed every frame), the random-pixel baseline, OpenCV "
      "spectral residual and fine grained saliency in place of S_p, and the full model per map size (ms/frame).");
  eval->add_option("--scene", eo.scene, "scene file (JSON)")->required();
  eval->add_option("--gaze", eo.gaze, "gaze recording (.fgr)")->required();
  eval->add_option("--offset-s", eo.offset_s, "scene time of the first sample, seconds");
  eval->add_option("--fps", eo.fps, "frames per second of the playback")->check(CLI::Range(1.0, 240.0));
  eval->add_option("--map-sizes", eo.map_sizes, "saliency-map sizes of the sweep, comma-separated (64..512)");
  eval->add_option("--ablation-map", eo.ablation_map, "map size of the ablation and OpenCV rows (default: the largest)");
  eval->add_option("--width", eo.width, "G-buffer width")->check(CLI::Range(16, 8192));
  eval->add_option("--height", eo.height, "G-buffer height")->check(CLI::Range(16, 8192));
  eval->add_option("--seed", eo.seed, "random seed of the random-pixel baseline");
  eval->add_option("--out", eo.out, "directory for eval_attention.csv and report.md");

  CLI11_PARSE(app, argc, argv);
  try {
    if (synth->parsed()) return synth_viewer(so);
    return evaluate(eo);
  } catch (const std::exception& e) {
    std::cerr << "fovea-eval-attention: error: " << e.what() << "\n";
    return 1;
  }
}
