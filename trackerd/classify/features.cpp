// SPDX-License-Identifier: Apache-2.0
#include "classify/features.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace fovea::trackerd::classify {
namespace {

constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();
constexpr double kNoiseHalfS = 0.128;
constexpr std::size_t kNoiseMaxTriples = 64;

// std::hypot guards against overflow at a cost (a third of the features' time at 1000 Hz); gaze
// displacements are a few tens of degrees at most.
double length(double x, double y) { return std::sqrt(x * x + y * y); }

// A sample of the run around the centre: time and displacement from the centre sample (tangent
// frame at the centre, degrees).
struct Point {
  double t = 0, x = 0, y = 0;
};

// The centre's gaze run on one side (step -1: back, +1: forward) into `out`, the centre first, up
// to the first sample at or beyond kFeatureReachS (needed to interpolate there). Returns the time
// to the sample without gaze that ended the run, or kFeatureReachS where none did within it (also
// where the buffer, i.e. the stream, ends first).
double run_side(const std::deque<Prepared>& buf, std::size_t i, int step, const TangentMap& tm, std::vector<Point>& out) {
  out.clear();
  const Prepared& c = buf[i];
  for (std::ptrdiff_t k = static_cast<std::ptrdiff_t>(i); k >= 0 && k < static_cast<std::ptrdiff_t>(buf.size());
       k += step) {
    const Prepared& p = buf[static_cast<std::size_t>(k)];
    const double dt = std::abs(p.t - c.t);
    if (!p.has_gaze()) return std::min(dt, kFeatureReachS);
    const TangentVector d = tm(p.x - c.x, p.y - c.y);
    out.push_back({dt, d.x, d.y});
    if (dt >= kFeatureReachS) break;
  }
  return kFeatureReachS;
}

// The displacement at |t| = d on one side, interpolated; false where the run ends sooner. The
// scales ascend, so the search goes on from `from`, the last segment found.
bool position_at(const std::vector<Point>& side, double d, std::size_t& from, Point& p) {
  for (std::size_t k = std::max<std::size_t>(from, 1); k < side.size(); ++k) {
    if (side[k].t < d) continue;
    from = k;
    const Point& a = side[k - 1];
    const Point& b = side[k];
    const double w = b.t > a.t ? (d - a.t) / (b.t - a.t) : 1.0;
    p = {d, a.x + w * (b.x - a.x), a.y + w * (b.y - a.y)};
    return true;
  }
  from = side.size();
  return false;
}

// Time from a sample to the nearest sample without gaze on one side, capped at the reach.
double time_to_loss(const std::deque<Prepared>& buf, std::size_t i, int step) {
  for (std::ptrdiff_t k = static_cast<std::ptrdiff_t>(i) + step;
       k >= 0 && k < static_cast<std::ptrdiff_t>(buf.size()); k += step) {
    const Prepared& p = buf[static_cast<std::size_t>(k)];
    const double dt = std::abs(p.t - buf[i].t);
    if (dt > kFeatureReachS) break;
    if (!p.has_gaze()) return dt;
  }
  return kFeatureReachS;
}

// Running sums over the samples of the window, grown one scale at a time.
struct WindowSums {
  double n = 0, sx = 0, sy = 0, sxx = 0, syy = 0, path = 0;
  void add(const Point& p) {
    n += 1, sx += p.x, sy += p.y, sxx += p.x * p.x, syy += p.y * p.y;
  }
  // Take in one side's samples out to |t| <= d; k counts those already in.
  void grow(const std::vector<Point>& side, double d, std::size_t& k) {
    while (k < side.size() && side[k].t <= d) {
      add(side[k]);
      path += length(side[k].x - side[k - 1].x, side[k].y - side[k - 1].y);
      ++k;
    }
  }
  double rms_spread() const {
    const double mx = sx / n, my = sy / n;
    return std::sqrt(std::max(0.0, sxx / n - mx * mx + syy / n - my * my));
  }
};

// The tracker's noise: the median magnitude of second differences within +-kNoiseHalfS, of at most
// kNoiseMaxTriples evenly spread (at 1000 Hz there are 256; the median of 64 is as good and 4x
// cheaper).
float noise_deg(const std::vector<Point>& back, const std::vector<Point>& fwd, std::vector<Point>& seq,
                std::vector<double>& d2) {
  seq.clear();
  for (std::size_t k = back.size(); k-- > 1;) {
    if (back[k].t <= kNoiseHalfS) seq.push_back(back[k]);
  }
  for (const Point& p : fwd) {
    if (p.t <= kNoiseHalfS) seq.push_back(p);
  }
  if (seq.size() < 3) return kNaNf;
  const std::size_t triples = seq.size() - 2;
  const std::size_t stride = (triples + kNoiseMaxTriples - 1) / kNoiseMaxTriples;
  d2.clear();
  for (std::size_t k = 1; k + 1 < seq.size(); k += stride) {
    d2.push_back(length(seq[k - 1].x - 2 * seq[k].x + seq[k + 1].x, seq[k - 1].y - 2 * seq[k].y + seq[k + 1].y));
  }
  auto mid = d2.begin() + static_cast<std::ptrdiff_t>(d2.size() / 2);
  std::nth_element(d2.begin(), mid, d2.end());
  return static_cast<float>(*mid);
}

// How far the gaze lies outside the display: the angle to the nearest point of it.
float offscreen_deg(const protocol::DisplayGeometry& display, double x, double y) {
  const protocol::Normalized n = protocol::degrees_to_normalized(display, {x, y});
  const protocol::Normalized on{std::clamp(n.x, 0.0, 1.0), std::clamp(n.y, 0.0, 1.0)};
  if (on.x == n.x && on.y == n.y) return 0.0f;
  return static_cast<float>(protocol::angle_between_deg(protocol::normalized_to_degrees(display, on), {x, y}));
}

// The reusable buffers of one thread's feature computation (no allocation per sample).
struct Scratch {
  std::vector<Point> back, fwd, seq;
  std::vector<double> d2;
};

void scale_features(const std::vector<Point>& back, const std::vector<Point>& fwd, double d, WindowSums& sums,
                    std::size_t& kb, std::size_t& kf, std::size_t& sb, std::size_t& sf, float* out) {
  sums.grow(back, d, kb);
  sums.grow(fwd, d, kf);
  Point pb, pf;
  if (!position_at(back, d, sb, pb) || !position_at(fwd, d, sf, pf)) {
    std::fill(out, out + kFeaturesPerScale, kNaNf);
    return;
  }
  const double nb = length(pb.x, pb.y), nf = length(pf.x, pf.y);
  const double net = length(pf.x - pb.x, pf.y - pb.y);
  // The path through the window's samples plus the interpolated ends beyond its outermost ones.
  const double path = sums.path + length(pb.x - back[kb - 1].x, pb.y - back[kb - 1].y) +
                      length(pf.x - fwd[kf - 1].x, pf.y - fwd[kf - 1].y);
  out[0] = static_cast<float>(net / (2 * d));
  out[1] = static_cast<float>(nb / d);
  out[2] = static_cast<float>(nf / d);
  out[3] = nb > 0 && nf > 0 ? static_cast<float>((-pb.x * pf.x - pb.y * pf.y) / (nb * nf)) : 0.0f;
  out[4] = static_cast<float>(sums.rms_spread());
  out[5] = path > 0 ? static_cast<float>(net / path) : 1.0f;
}

}  // namespace

const std::vector<std::string>& feature_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n;
    for (double d : kFeatureScalesS) {
      const std::string ms = std::to_string(static_cast<int>(std::lround(d * 1000))) + "ms";
      for (const char* f : {"speed_c_", "speed_b_", "speed_f_", "cos_", "disp_", "straight_"}) n.push_back(f + ms);
    }
    for (const char* f : {"loss_before_s", "loss_after_s", "filled", "noise_deg", "offscreen_deg"}) n.emplace_back(f);
    return n;
  }();
  return names;
}

std::size_t feature_index(const std::string& name) {
  const auto& n = feature_names();
  const auto it = std::find(n.begin(), n.end(), name);
  if (it == n.end()) throw std::out_of_range("no feature named " + name);
  return static_cast<std::size_t>(it - n.begin());
}

void sample_features(const std::deque<Prepared>& buf, std::size_t i, const protocol::DisplayGeometry& display,
                     float* out) {
  const Prepared& c = buf[i];
  float* tail = out + kFeatureScalesS.size() * kFeaturesPerScale;
  tail[2] = c.kind == Prepared::Kind::Filled ? 1.0f : 0.0f;
  if (!c.has_gaze()) {
    std::fill(out, tail + 5, kNaNf);
    tail[0] = static_cast<float>(time_to_loss(buf, i, -1));
    tail[1] = static_cast<float>(time_to_loss(buf, i, +1));
    return;
  }
  thread_local Scratch scratch;
  const TangentMap tm = tangent_map(c.x, c.y);
  tail[0] = static_cast<float>(run_side(buf, i, -1, tm, scratch.back));
  tail[1] = static_cast<float>(run_side(buf, i, +1, tm, scratch.fwd));
  const std::vector<Point>& back = scratch.back;
  const std::vector<Point>& fwd = scratch.fwd;
  WindowSums sums;
  sums.add(back[0]);
  std::size_t kb = 1, kf = 1, sb = 1, sf = 1;
  for (std::size_t s = 0; s < kFeatureScalesS.size(); ++s) {
    scale_features(back, fwd, kFeatureScalesS[s], sums, kb, kf, sb, sf, out + s * kFeaturesPerScale);
  }
  tail[3] = noise_deg(back, fwd, scratch.seq, scratch.d2);
  tail[4] = offscreen_deg(display, c.x, c.y);
}

}  // namespace fovea::trackerd::classify
