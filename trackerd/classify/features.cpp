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
constexpr std::size_t kCompactRows = 4096;  // pop_front moves the rows once this many are dropped
// Times this close are the same time: a sample d after the centre, as rounding gives it (5.076 -
// 5.072 = 0.0040000000000004), is the point at d, not a hair before it, so a 250 Hz scale of 4 ms
// reads that sample itself, not an interpolation 1e-13 of the way to the next (whose direction,
// where the gaze stood still, would be noise). Trackers stamp samples in microseconds at best.
constexpr double kSameTimeS = 1e-9;

// std::hypot guards against overflow at a cost; gaze displacements are a few tens of degrees at most.
double length(double x, double y) { return std::sqrt(x * x + y * y); }

// How far the gaze lies outside the display: the angle to the nearest point of it.
float offscreen_deg(const protocol::DisplayGeometry& display, double x, double y) {
  const protocol::Normalized n = protocol::degrees_to_normalized(display, {x, y});
  const protocol::Normalized on{std::clamp(n.x, 0.0, 1.0), std::clamp(n.y, 0.0, 1.0)};
  if (on.x == n.x && on.y == n.y) return 0.0f;
  return static_cast<float>(protocol::angle_between_deg(protocol::normalized_to_degrees(display, on), {x, y}));
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
    for (double lag : kStepLagsS) n.push_back("speed_b_4ms_lag" + std::to_string(std::lround(lag * 1000)) + "ms");
    for (double lead : kStepLeadsS) n.push_back("speed_f_4ms_lead" + std::to_string(std::lround(lead * 1000)) + "ms");
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

void FeatureWindow::clear() {
  rows_.clear();
  front_ = 0;
  base_ = 0;
  last_loss_ = -1;
  last_ = before_last_ = Row{};
}

void FeatureWindow::pop_front(std::size_t n) {
  front_ = std::min(rows_.size(), front_ + n);
  if (front_ >= kCompactRows && 2 * front_ >= rows_.size()) {
    rows_.erase(rows_.begin(), rows_.begin() + static_cast<std::ptrdiff_t>(front_));
    base_ += static_cast<std::int64_t>(front_);
    front_ = 0;
  }
}

void FeatureWindow::push(const Prepared& p) {
  const std::int64_t k = end();
  Row r;
  r.t = p.t;
  r.x = p.x;
  r.y = p.y;
  r.gaze = p.has_gaze();
  r.filled = p.kind == Prepared::Kind::Filled;
  r.prev_loss = last_loss_;
  if (!r.gaze) {
    for (std::int64_t j = std::max(last_loss_, first()); j < k; ++j) rows_[static_cast<std::size_t>(j - base_)].next_loss = k;
    last_loss_ = k;
  }
  // The sums go on from the previous row's, kept here (not read from rows_, which may have dropped
  // it), so they are the same however much the window holds.
  if (k % static_cast<std::int64_t>(kChunkSamples) != 0) {
    r.sums = last_.sums;
    r.ref_x = last_.ref_x;
    r.ref_y = last_.ref_y;
  }
  if (r.gaze) {
    if (r.sums.n == 0) r.ref_x = r.x, r.ref_y = r.y;  // the chunk's first gaze sample
    const double dx = r.x - r.ref_x, dy = r.y - r.ref_y;
    r.sums.n += 1, r.sums.x += dx, r.sums.y += dy;
    r.sums.xx += dx * dx, r.sums.xy += dx * dy, r.sums.yy += dy * dy;
    if (k > 0 && last_.gaze) {
      // Each step's rotation in the tangent frame where it starts, and the previous row's |second
      // difference| in its own.
      const TangentMap m = tangent_map(last_.x, last_.y);
      const TangentVector step = m(r.x - last_.x, r.y - last_.y);
      r.sums.path += length(step.x, step.y);
      if (k > 1 && before_last_.gaze && k - 1 >= first()) {
        const TangentVector d2 = m(before_last_.x - 2 * last_.x + r.x, before_last_.y - 2 * last_.y + r.y);
        rows_[static_cast<std::size_t>(k - 1 - base_)].d2 = length(d2.x, d2.y);
      }
    }
  }
  rows_.push_back(r);
  before_last_ = last_;
  last_ = r;
}

FeatureWindow::Centred FeatureWindow::centred_sums(std::int64_t a, std::int64_t b, double cx, double cy) const {
  Centred c;
  const auto chunk = static_cast<std::int64_t>(kChunkSamples);
  for (std::int64_t lo = a; lo <= b;) {
    const std::int64_t hi = std::min(b, (lo / chunk + 1) * chunk - 1);
    const Row& h = at(hi);
    const Row& l = at(lo);
    Sums s = h.sums;
    if (lo == a && !(lo % chunk == 0)) {
      // Without the rows before lo: lo's inclusive sums less its own part.
      const double dx = l.x - l.ref_x, dy = l.y - l.ref_y;
      s.n -= l.sums.n - 1, s.x -= l.sums.x - dx, s.y -= l.sums.y - dy;
      s.xx -= l.sums.xx - dx * dx, s.xy -= l.sums.xy - dx * dy, s.yy -= l.sums.yy - dy * dy;
    }
    // The steps into lo+1 .. hi (and into lo from a chunk's start: the step across the boundary).
    c.path += lo == a ? h.sums.path - l.sums.path : h.sums.path;
    const double dx = h.ref_x - cx, dy = h.ref_y - cy;
    c.n += s.n;
    c.sx += s.x + s.n * dx;
    c.sy += s.y + s.n * dy;
    c.sxx += s.xx + 2 * dx * s.x + s.n * dx * dx;
    c.sxy += s.xy + dx * s.y + dy * s.x + s.n * dx * dy;
    c.syy += s.yy + 2 * dy * s.y + s.n * dy * dy;
    lo = hi + 1;
  }
  return c;
}

float FeatureWindow::noise(std::int64_t a, std::int64_t b) const {
  if (b - a < 2) return kNaNf;
  const std::int64_t triples = b - a - 1;
  const std::int64_t stride = (triples + static_cast<std::int64_t>(kNoiseMaxTriples) - 1) /
                              static_cast<std::int64_t>(kNoiseMaxTriples);
  std::array<double, kNoiseMaxTriples> d2{};
  std::size_t n = 0;
  for (std::int64_t k = a + 1; k < b && n < d2.size(); k += stride) d2[n++] = at(k).d2;
  auto mid = d2.begin() + static_cast<std::ptrdiff_t>(n / 2);
  std::nth_element(d2.begin(), mid, d2.begin() + static_cast<std::ptrdiff_t>(n));
  return static_cast<float>(*mid);
}

// The point at time offset u from row c, between rows r0 and r1 (offsets u0 <= u <= u1), in c's
// tangent frame.
TangentVector FeatureWindow::point_at(const Row& c, const Row& r0, const Row& r1, double u, const TangentMap& tm) {
  const double u0 = r0.t - c.t, u1 = r1.t - c.t;
  const double v = std::abs(u - u0) <= kSameTimeS ? 0.0 : std::abs(u1 - u) <= kSameTimeS ? 1.0 : (u - u0) / (u1 - u0);
  return tm(r0.x + v * (r1.x - r0.x) - c.x, r0.y + v * (r1.y - r0.y) - c.y);
}

// One scale's features of row ci over [t - d, t + a] (a = d but where the reach is shorter), whose
// run reaches rows bj (the last d or more before it) and f (the first a or more after it).
void FeatureWindow::scale_features(std::int64_t ci, std::int64_t bj, std::int64_t f, const TangentMap& tm, double d,
                                   double a, float* o) const {
  const Row& c = at(ci);
  const TangentVector pb = point_at(c, at(bj), at(bj + 1), -d, tm), pf = point_at(c, at(f - 1), at(f), a, tm);
  // The window's samples: -d <= t - t_c <= a.
  const std::int64_t first = c.t - at(bj).t <= d + kSameTimeS ? bj : bj + 1;
  const std::int64_t last = at(f).t - c.t <= a + kSameTimeS ? f : f - 1;
  const Centred sum = centred_sums(first, last, c.x, c.y);
  const double mx = sum.sx / sum.n, my = sum.sy / sum.n;
  const double cxx = sum.sxx / sum.n - mx * mx, cxy = sum.sxy / sum.n - mx * my, cyy = sum.syy / sum.n - my * my;
  // trace(M cov M^T): the spread in the centre's tangent frame.
  const double spread2 = (tm.xx * tm.xx + tm.yx * tm.yx) * cxx + 2 * (tm.xx * tm.xy + tm.yx * tm.yy) * cxy +
                         (tm.xy * tm.xy + tm.yy * tm.yy) * cyy;
  const TangentVector ea = tm(at(first).x - c.x, at(first).y - c.y), eb = tm(at(last).x - c.x, at(last).y - c.y);
  const double nb = length(pb.x, pb.y), nf = length(pf.x, pf.y);
  const double net = length(pf.x - pb.x, pf.y - pb.y);
  // The path through the window's samples plus the interpolated ends beyond its outermost ones.
  const double path = sum.path + length(pb.x - ea.x, pb.y - ea.y) + length(pf.x - eb.x, pf.y - eb.y);
  o[0] = static_cast<float>(net / (d + a));
  o[1] = static_cast<float>(nb / d);
  o[2] = static_cast<float>(nf / a);
  o[3] = nb > 0 && nf > 0 ? static_cast<float>((-pb.x * pf.x - pb.y * pf.y) / (nb * nf)) : 0.0f;
  o[4] = static_cast<float>(std::sqrt(std::max(0.0, spread2)));
  // Gaze that did not move at all (a still eye on a tracker that reports whole pixels) made no
  // straight movement: 0, as noise, not 1 (a model read 1 as pursuit there).
  o[5] = path > 0 ? static_cast<float>(net / path) : 0.0f;
}

void FeatureWindow::features(std::size_t i, const protocol::DisplayGeometry& display, float* out,
                             double reach_s) const {
  const std::int64_t ci = first() + static_cast<std::int64_t>(i);
  const Row& c = at(ci);
  float* tail = out + kFeatureScalesS.size() * kFeaturesPerScale;
  const auto loss_time = [&](std::int64_t j, double cap) {
    if (j < first() || j >= end()) return static_cast<float>(cap);
    return static_cast<float>(std::min(std::abs(at(j).t - c.t), cap));
  };
  tail[0] = loss_time(c.prev_loss, kFeatureReachS);
  tail[1] = loss_time(c.next_loss, reach_s);
  tail[2] = c.filled ? 1.0f : 0.0f;
  float* steps = tail + kTailFeatures;
  if (!c.gaze) {
    std::fill(out, tail, kNaNf);
    tail[2] = tail[3] = tail[4] = kNaNf;
    std::fill(steps, steps + kStepLagsS.size() + kStepLeadsS.size(), kNaNf);
    return;
  }
  // The centre's run among the rows held: [lo, hi].
  const std::int64_t lo = std::max(first(), c.prev_loss + 1);
  const std::int64_t hi = c.next_loss >= 0 ? c.next_loss - 1 : end() - 1;
  const auto row_it = [&](std::int64_t j) { return rows_.begin() + static_cast<std::ptrdiff_t>(j - base_); };
  const auto index_of = [&](std::vector<Row>::const_iterator it) { return base_ + (it - rows_.begin()); };
  // The first row at or after ci that is d or more after the centre (hi + 1: none in the run), and
  // the first row from lo that is less than d before it.
  const auto ahead = [&](double d) {
    return index_of(
        std::partition_point(row_it(ci), row_it(hi + 1), [&](const Row& r) { return r.t - c.t < d - kSameTimeS; }));
  };
  const auto within_before = [&](double d) {
    return index_of(
        std::partition_point(row_it(lo), row_it(ci), [&](const Row& r) { return c.t - r.t >= d - kSameTimeS; }));
  };
  const TangentMap tm = tangent_map(c.x, c.y);
  for (std::size_t s = 0; s < kFeatureScalesS.size(); ++s) {
    const double d = kFeatureScalesS[s], a = std::min(d, reach_s);
    float* o = out + s * kFeaturesPerScale;
    const std::int64_t f = ahead(a), w = within_before(d);  // rows f-1, f and w-1, w bracket t + a, t - d
    if (f > hi || w == lo) {
      std::fill(o, o + kFeaturesPerScale, kNaNf);
      continue;
    }
    scale_features(ci, w - 1, f, tm, d, a, o);
  }
  // The noise's window: the run's rows within kNoiseHalfS before and min(kNoiseHalfS, reach) after.
  const std::int64_t na = index_of(std::partition_point(
      row_it(lo), row_it(ci), [&](const Row& r) { return c.t - r.t > kNoiseHalfS + kSameTimeS; }));
  const std::int64_t nb = index_of(std::partition_point(
      row_it(ci), row_it(hi + 1), [&](const Row& r) { return r.t - c.t <= std::min(kNoiseHalfS, reach_s) + kSameTimeS; }));
  tail[3] = noise(na, nb - 1);
  tail[4] = offscreen_deg(display, c.x, c.y);
  // The 4 ms steps that end kStepLagsS before the sample and start kStepLeadsS after it: where the
  // gaze has just landed they show the movement that brought it there.
  const auto point = [&](double u, TangentVector& p) {  // at offset u from the centre, if the run has it
    if (u < 0) {
      const std::int64_t w = within_before(-u);  // rows w-1 and w bracket t + u
      if (w == lo) return false;
      p = point_at(c, at(w - 1), at(w), u, tm);
    } else {
      if (u > reach_s + kSameTimeS) return false;
      const std::int64_t f = ahead(u);  // rows f-1 and f bracket t + u
      if (f > hi) return false;
      p = point_at(c, at(f - 1), at(f), u, tm);
    }
    return true;
  };
  constexpr double kStep = kFeatureScalesS[0];
  const auto step_speed = [&](double from, double to) {
    TangentVector a, b;
    return point(from, a) && point(to, b) ? static_cast<float>(length(b.x - a.x, b.y - a.y) / kStep) : kNaNf;
  };
  for (double lag : kStepLagsS) *steps++ = step_speed(-lag - kStep, -lag);
  for (double lead : kStepLeadsS) *steps++ = step_speed(lead, lead + kStep);
}

void sample_features(const std::deque<Prepared>& buf, std::size_t i, const protocol::DisplayGeometry& display,
                     float* out, double reach_s) {
  FeatureWindow w;
  for (const Prepared& p : buf) w.push(p);
  w.features(i, display, out, reach_s);
}

}  // namespace fovea::trackerd::classify
