// SPDX-License-Identifier: Apache-2.0
#include "lod/lod_policy.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace fovea::render::lod {

namespace {

double clamp_level(double l, int levels) {
  const double top = std::max(0, levels - 1);
  return std::isfinite(l) ? std::clamp(l, 0.0, top) : top;  // non-finite: the coarsest
}

// The continuous level at which a per-level error (any monotone measure: pixels, degrees) crosses
// `tolerance`: the coarsest whole level within it, plus the share of the way to the next level's
// error, interpolated linearly.
double level_within(const std::vector<double>& error, double tolerance) {
  if (error.empty()) return 0;
  if (!(tolerance > 0) || !std::isfinite(tolerance)) return std::isfinite(tolerance) ? 0.0 : static_cast<double>(error.size() - 1);
  std::size_t l = 0;
  while (l + 1 < error.size() && std::isfinite(error[l + 1]) && error[l + 1] <= tolerance) ++l;
  if (l + 1 >= error.size()) return static_cast<double>(l);
  const double e0 = error[l], e1 = error[l + 1];
  const double frac = std::isfinite(e1) && e1 > e0 ? std::clamp((tolerance - e0) / (e1 - e0), 0.0, 1.0) : 0.0;
  return static_cast<double>(l) + frac;
}

double finite_or(double v, double fallback) { return std::isfinite(v) ? v : fallback; }

}  // namespace

const char* to_string(Policy p) {
  switch (p) {
    case Policy::None: return "none";
    case Policy::Distance: return "distance";
    case Policy::ScreenSize: return "screen-size";
    case Policy::Brown: return "brown";
    case Policy::Ulod: return "ulod";
    case Policy::Gaze: return "gaze";
  }
  return "none";
}

Policy parse_policy(const std::string& name) {
  for (Policy p : {Policy::None, Policy::Distance, Policy::ScreenSize, Policy::Brown, Policy::Ulod, Policy::Gaze})
    if (name == to_string(p)) return p;
  throw std::invalid_argument("lod policy '" + name + "': one of none, distance, screen-size, brown, ulod, gaze");
}

int brown_importance(const ObjectView& o, const BrownSettings& s, const FrameStats& frame) {
  const double r = finite_or(o.projected_radius_px, 0.0);
  const double area = std::numbers::pi * r * r;
  const bool size = o.screen_area_px > 0 && area / o.screen_area_px > s.size_share;
  const bool position = std::abs(finite_or(o.screen_x, 0.0) - 0.5) < s.position_box / 2 &&
                        std::abs(finite_or(o.screen_y, 0.0) - 0.5) < s.position_box / 2;
  const double rot = finite_or(o.rotation_deg_per_frame, 0.0), vel = finite_or(o.velocity_px_per_frame, 0.0);
  const bool rotation = rot > s.rotation_min_deg && rot > frame.rotation_mean + s.rotation_sd * frame.rotation_sd;
  const bool translation = vel > s.velocity_min_px && vel > frame.velocity_mean + s.velocity_sd * frame.velocity_sd;
  const bool luminance = finite_or(o.luminance_contrast, 0.0) > s.luminance_min;
  const bool f[5] = {size, position, rotation, translation, luminance};
  double sum = 0;
  for (int i = 0; i < 5; ++i) sum += f[i] ? s.weights[i] : 0.0;  // Brown et al. 2003, eq. 5
  return sum > s.threshold ? 1 : -1;
}

double continuous_level(const ObjectView& o, const PolicySettings& s, const FrameStats& frame) {
  if (o.levels <= 1) return 0;
  const double beta = std::isfinite(o.base) && o.base > 1 ? o.base : 4.0;
  const double d = finite_or(o.distance_m, std::numeric_limits<double>::infinity());
  const auto errors_in = [&](auto to_unit) {
    std::vector<double> e(static_cast<std::size_t>(o.levels), 0.0);
    for (std::size_t l = 0; l < e.size(); ++l)
      e[l] = l < o.level_error_m.size() ? to_unit(static_cast<double>(o.level_error_m[l])) : std::numeric_limits<double>::infinity();
    return e;
  };
  switch (s.policy) {
    case Policy::None: return 0;
    case Policy::Distance: {
      if (!(d > 0) || !std::isfinite(d)) return clamp_level(std::numeric_limits<double>::infinity(), o.levels);
      const double ref = s.distance_ref_m > 0 ? s.distance_ref_m : 1.0;
      return clamp_level(d <= ref ? 0.0 : 2.0 * std::log(d / ref) / std::log(beta), o.levels);
    }
    case Policy::ScreenSize: {
      if (!(d > 0) || !std::isfinite(d)) return clamp_level(std::numeric_limits<double>::infinity(), o.levels);
      const double px_per_rad = finite_or(o.px_per_radian, 0.0);
      return clamp_level(level_within(errors_in([&](double e) { return e / d * px_per_rad; }), s.tolerance_px), o.levels);
    }
    case Policy::Brown: {
      const int importance = brown_importance(o, s.brown, frame);
      // Eq. 4 with a and s as shares of P: P_LOD = P (1 + a I - s), at most P (eq. 3).
      const double share = std::clamp(1.0 + s.brown.a * importance - frame.stress, 1e-9, 1.0);
      return clamp_level(-std::log(share) / std::log(beta), o.levels);
    }
    case Policy::Ulod: {
      const double so = std::isfinite(o.attention) ? std::clamp(o.attention, 0.0, 1.0) : 0.0;
      return clamp_level(static_cast<double>(o.levels - 1) * (1.0 - so), o.levels);  // Lee 2009, eq. 7.3
    }
    case Policy::Gaze: {
      if (!(d > 0) || !std::isfinite(d)) return clamp_level(std::numeric_limits<double>::infinity(), o.levels);
      const double ecc = std::abs(finite_or(o.eccentricity_deg, 180.0));
      const double fc = perception::cutoff_frequency_cpd(ecc, s.csf);  // Murphy 2007, eq. 4.3
      const double tolerance_deg = fc > 0 && std::isfinite(fc) ? 0.5 / fc : std::numeric_limits<double>::infinity();
      return clamp_level(level_within(errors_in([&](double e) { return std::atan2(e, d) * 180.0 / std::numbers::pi; }),
                                      tolerance_deg),
                         o.levels);
    }
  }
  return 0;
}

void LodSelector::set_budget_ms(double ms) {
  budget_ = BudgetState{};
  budget_.target_ms = std::isfinite(ms) && ms > 0 ? ms : 0.0;
}

const std::vector<Selection>& LodSelector::select(const std::vector<ObjectView>& objects, double last_frame_ms,
                                                 double top_attention) {
  out_.clear();
  // The frame-time controller: 0.25 level per frame towards the budget.
  int max_levels = 1;
  for (const ObjectView& o : objects) max_levels = std::max(max_levels, o.levels);
  const bool over = budget_.target_ms > 0 && std::isfinite(last_frame_ms) && last_frame_ms > budget_.target_ms;
  if (budget_.target_ms > 0 && std::isfinite(last_frame_ms)) {
    if (over) budget_.bias = std::min(budget_.bias + 0.25, static_cast<double>(max_levels - 1));
    else if (last_frame_ms < 0.85 * budget_.target_ms) budget_.bias = std::max(0.0, budget_.bias - 0.25);
  } else if (budget_.target_ms <= 0) {
    budget_.bias = 0;
  }
  // Brown's relative motion features and stress.
  FrameStats frame;
  if (!objects.empty()) {
    double rs = 0, rs2 = 0, vs = 0, vs2 = 0;
    for (const ObjectView& o : objects) {
      const double r = finite_or(o.rotation_deg_per_frame, 0.0), v = finite_or(o.velocity_px_per_frame, 0.0);
      rs += r;
      rs2 += r * r;
      vs += v;
      vs2 += v * v;
    }
    const auto n = static_cast<double>(objects.size());
    frame.rotation_mean = rs / n;
    frame.rotation_sd = std::sqrt(std::max(0.0, rs2 / n - frame.rotation_mean * frame.rotation_mean));
    frame.velocity_mean = vs / n;
    frame.velocity_sd = std::sqrt(std::max(0.0, vs2 / n - frame.velocity_mean * frame.velocity_mean));
  }
  const bool brown = settings_.policy == Policy::Brown;
  // Brown's stress s (eq. 4) from the controller's bias: (1 + a)(1 - 4^-bias), from 0 (no stress) to
  // 1 + a (even important objects at their coarsest).
  frame.stress = brown ? (1.0 + settings_.brown.a) * (1.0 - std::pow(4.0, -budget_.bias)) : 0.0;
  // ULOD: S_o relative to the frame's most attended object (Lee §7.3: "an object with the highest
  // attention value (i.e., S_o = 1) is rendered using its finest model"); the attention pass's S_o
  // are not scaled so that the top one is 1.
  double max_attention = std::isfinite(top_attention) && top_attention > 0 ? top_attention : 0.0;
  if (max_attention <= 0)
    for (const ObjectView& o : objects)
      if (std::isfinite(o.attention)) max_attention = std::max(max_attention, o.attention);
  bool all_coarsest = true;
  std::vector<std::pair<std::uint32_t, int>> drawn;
  SwitchState switches;
  switches.in_saccade = in_saccade_;
  for (const ObjectView& o : objects) {
    Selection sel;
    sel.id = o.id;
    const double top = std::max(0, o.levels - 1);
    ObjectView relative = o;
    if (settings_.policy == Policy::Ulod && max_attention > 0 && std::isfinite(o.attention))
      relative.attention = o.attention / max_attention;
    double l = continuous_level(relative, settings_, frame);
    if (!brown) l = std::min(top, l + budget_.bias);
    sel.level = l;
    int previous = -1;
    for (const auto& [id, lv] : drawn_)
      if (id == o.id) previous = lv;
    sel.drawn = choose_drawn(o, l, previous, sel);
    if (previous >= 0 && sel.drawn != previous) {
      const bool blended_change = settings_.policy == Policy::Ulod && !settings_.switch_in_saccades;
      if (in_saccade_) ++switches.switched_in_saccade;
      else if (!blended_change) ++switches.pops;
    }
    if (sel.blend > 0 && sel.blend_to != sel.drawn) ++switches.blended;
    all_coarsest = all_coarsest && sel.drawn >= o.levels - 1;
    drawn.emplace_back(o.id, sel.drawn);
    out_.push_back(sel);
  }
  drawn_ = std::move(drawn);
  switches_ = switches;
  budget_.cannot_meet = over && all_coarsest;
  budget_.why = budget_.cannot_meet ? "every object is at its coarsest level and the frame (" + std::to_string(last_frame_ms) +
                                          " ms) is still over the budget (" + std::to_string(budget_.target_ms) + " ms)"
                                    : "";
  return out_;
}

// The level drawn for continuous level l (previous: last frame's drawn level, -1 for an object new
// in view); fills the blend of `sel`.
int LodSelector::choose_drawn(const ObjectView& o, double l, int previous, Selection& sel) const {
  const int top = std::max(0, o.levels - 1);
  sel.blend_to = -1;
  sel.blend = 0;
  int d = 0;
  if (settings_.switch_in_saccades) {
    // Saccadic suppression: switch freely during a saccade; hold outside one within the slack.
    d = static_cast<int>(std::lround(l));
    if (!in_saccade_ && previous >= 0 && std::abs(l - previous) <= kSwitchSlack) d = previous;
  } else if (settings_.policy == Policy::Ulod) {
    // ULOD: the two adjacent levels, blended in image space by the fraction.
    d = static_cast<int>(std::floor(l));
    sel.blend_to = std::min(d + 1, top);
    sel.blend = l - std::floor(l);
  } else {
    // Hysteresis: the drawn level changes only when L leaves it by more than half a level plus h.
    const double h = std::max(0.0, finite_or(settings_.hysteresis, 0.0));
    d = static_cast<int>(std::lround(l));
    if (previous >= 0 && std::abs(l - previous) <= 0.5 + h) d = previous;
  }
  d = std::clamp(d, 0, top);
  if (sel.blend_to < 0) sel.blend_to = d;
  return d;
}

}  // namespace fovea::render::lod
