// SPDX-License-Identifier: Apache-2.0
#include "attention/focus.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <optional>
#include <set>
#include <stdexcept>

#include "fovea/protocol/display_geometry.h"

namespace fovea::render::attention {

void FocusSettings::check() const {
  const auto bad = [](const char* field, double value, const char* allowed) {
    char text[160];
    std::snprintf(text, sizeof text, "focus setting %s=%g: allowed %s", field, value, allowed);
    throw std::invalid_argument(text);
  };
  if (!(transition_s >= 0 && transition_s <= 10)) bad("transition_s", transition_s, "[0, 10] seconds");
  if (!(cutoff_hz > 0 && cutoff_hz <= 2)) bad("cutoff_hz", cutoff_hz, "(0, 2] Hz (Lee 2009 §6.1)");
  if (!(gaze_radius_deg >= 0 && gaze_radius_deg <= 10)) bad("gaze_radius_deg", gaze_radius_deg, "[0, 10] degrees");
  if (!(min_attention >= 0 && std::isfinite(min_attention))) bad("min_attention", min_attention, "a finite number >= 0");
  if (!(fixed_depth_m > 0 && std::isfinite(fixed_depth_m))) bad("fixed_depth_m", fixed_depth_m, "a finite depth > 0 m");
}

namespace {

constexpr double kMinDepthM = 1e-3;

double clamp01(double v) { return std::isfinite(v) ? std::clamp(v, 0.0, 1.0) : 0.5; }

std::string object_name(const Scene& scene, std::uint32_t id) {
  const Object* o = scene.object_by_id(id);
  if (o != nullptr && !o->name.empty()) return o->name;
  return "object #" + std::to_string(id);
}

// Numbers in `why` strings: 3 significant digits.
std::string g3(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3g", v);
  return text;
}

}  // namespace

GBufferPixels::GBufferPixels(const GBuffer& g) : g_(g) {
  const std::size_t n = g.size();
  if (n > 0 && g.depth.size() >= n && g.object_id.size() >= n) {
    w_ = g.width;
    h_ = g.height;
  }
}

void GBufferPixels::read(std::uint32_t x0, std::uint32_t y0, std::uint32_t x1, std::uint32_t y1, std::vector<float>& depth,
                         std::vector<std::uint32_t>& ids) {
  depth.clear();
  ids.clear();
  for (std::uint32_t y = y0; y < y1; ++y) {
    const std::size_t row = g_.index(x0, y);
    depth.insert(depth.end(), g_.depth.begin() + static_cast<std::ptrdiff_t>(row),
                 g_.depth.begin() + static_cast<std::ptrdiff_t>(row + (x1 - x0)));
    ids.insert(ids.end(), g_.object_id.begin() + static_cast<std::ptrdiff_t>(row),
               g_.object_id.begin() + static_cast<std::ptrdiff_t>(row + (x1 - x0)));
  }
}

// This frame's inputs, with the G-buffer lookups the rules need (through FocusPixels: each reads
// only the pixels it looks at). Every depth it returns is finite and in [kMinDepthM, far]: NaN, Inf
// and non-positive depths in the G-buffer are skipped.
struct FocusTracker::FrameView {
  FocusPixels& px;
  const Scene& scene;
  const AttentionFrame* attention;
  const protocol::DisplayGeometry& display;
  double far_m;
  bool pixels;  // the G-buffer has pixels and consistent buffers
  std::uint32_t width, height;

  FrameView(FocusPixels& p, const Scene& s, const AttentionFrame* a, const protocol::DisplayGeometry& d)
      : px(p), scene(s), attention(a), display(d), width(p.width()), height(p.height()) {
    const double far = static_cast<double>(s.camera.far_m);
    far_m = std::isfinite(far) && far > kMinDepthM ? far : 100.0;
    pixels = width > 0 && height > 0;
  }

  std::optional<double> sane(double d) const {
    if (!std::isfinite(d) || d <= 0) return std::nullopt;
    return std::clamp(d, kMinDepthM, far_m);
  }

  // The pixel under a normalised screen point (clamped to the image).
  std::uint32_t column_at(double x) const { return static_cast<std::uint32_t>(std::min(clamp01(x) * width, width - 1.0)); }
  std::uint32_t row_at(double y) const { return static_cast<std::uint32_t>(std::min(clamp01(y) * height, height - 1.0)); }
  std::uint32_t id_at(double x, double y) const {
    if (!pixels) return 0;
    std::vector<float> depth;
    std::vector<std::uint32_t> ids;
    const std::uint32_t cx = column_at(x), cy = row_at(y);
    px.read(cx, cy, cx + 1, cy + 1, depth, ids);
    return ids[0];
  }

  // The depth under a normalised screen point: the pixel there, or, when its depth is not a number,
  // the nearest hit pixel with one within 2 pixels; the far plane where nothing is hit.
  double depth_at(double nx, double ny) const {
    if (!pixels) return far_m;
    const long cx = column_at(nx), cy = row_at(ny);
    const long w = static_cast<long>(width), h = static_cast<long>(height);
    const long x0 = std::max(0L, cx - 2), y0 = std::max(0L, cy - 2);
    const long x1 = std::min(w, cx + 3), y1 = std::min(h, cy + 3);
    std::vector<float> depth;
    std::vector<std::uint32_t> ids;
    px.read(static_cast<std::uint32_t>(x0), static_cast<std::uint32_t>(y0), static_cast<std::uint32_t>(x1),
            static_cast<std::uint32_t>(y1), depth, ids);
    const auto at = [&](long x, long y) { return static_cast<std::size_t>((y - y0) * (x1 - x0) + (x - x0)); };
    if (ids[at(cx, cy)] == 0) return far_m;
    if (auto d = sane(depth[at(cx, cy)])) return *d;
    for (long r = 1; r <= 2; ++r) {
      for (long py = std::max(0L, cy - r); py <= std::min(h - 1, cy + r); ++py) {
        for (long qx = std::max(0L, cx - r); qx <= std::min(w - 1, cx + r); ++qx) {
          const std::size_t j = at(qx, py);
          if (ids[j] == 0) continue;
          if (auto d = sane(depth[j])) return *d;
        }
      }
    }
    return far_m;
  }

  const ObjectAttention* attended(std::uint32_t id) const {
    if (attention == nullptr || id == 0) return nullptr;
    for (const ObjectAttention& o : attention->objects) {
      if (o.id == id) return &o;
    }
    return nullptr;
  }

  // An object's depth: ObjectAttention::depth_m when the attention pass has it, else the median depth
  // of its G-buffer pixels (the whole planes). nullopt when the object is not visible (or none of its
  // depths is a number).
  std::optional<double> object_depth(std::uint32_t id) const {
    if (const ObjectAttention* a = attended(id)) {
      if (auto d = sane(a->depth_m)) return d;
    }
    if (!pixels || id == 0) return std::nullopt;
    const GBuffer& g = px.whole();
    std::vector<float> depths;
    for (std::size_t i = 0; i < g.size(); ++i) {
      if (g.object_id[i] == id && std::isfinite(g.depth[i]) && g.depth[i] > 0) depths.push_back(g.depth[i]);
    }
    if (depths.empty()) return std::nullopt;
    const auto mid = depths.begin() + static_cast<std::ptrdiff_t>(depths.size() / 2);
    std::nth_element(depths.begin(), mid, depths.end());
    return sane(static_cast<double>(*mid));
  }

  // A foreground object: task importance T_i > 0 (Lee 2009 §3.2), or one the attention pass lists.
  bool foreground(std::uint32_t id) const {
    if (id == 0) return false;
    if (attended(id) != nullptr) return true;
    const Object* o = scene.object_by_id(id);
    return o != nullptr && o->task_importance > 0;
  }

  // The ids of every object with at least one pixel centre within `radius_deg` of the gaze point.
  std::set<std::uint32_t> ids_near(double x, double y, double radius_deg) const {
    std::set<std::uint32_t> ids;
    if (!pixels) return ids;
    ids.insert(id_at(x, y));
    // degrees_to_pixels gives the diameter of a circle subtending the angle: twice the radius in.
    double r = protocol::degrees_to_image_pixels(display, width, 2.0 * radius_deg) / 2.0;
    if (!std::isfinite(r) || r < 0) r = 0;
    r = std::min(r, static_cast<double>(width) + height);
    const double cx = clamp01(x) * width, cy = clamp01(y) * height;
    const auto lo = [](double v) { return static_cast<std::uint32_t>(std::max(0.0, std::floor(v))); };
    const auto hi = [](double v, std::uint32_t n) { return static_cast<std::uint32_t>(std::clamp(std::ceil(v), 0.0, n - 1.0)); };
    // The circle's bounding box, read in one piece.
    const std::uint32_t x0 = lo(cx - r), y0 = lo(cy - r), x1 = hi(cx + r, width) + 1, y1 = hi(cy + r, height) + 1;
    if (x0 >= x1 || y0 >= y1) return ids;
    std::vector<float> depth;
    std::vector<std::uint32_t> box;
    px.read(x0, y0, x1, y1, depth, box);
    for (std::uint32_t py = y0; py < y1; ++py) {
      for (std::uint32_t qx = x0; qx < x1; ++qx) {
        if (std::hypot(qx + 0.5 - cx, py + 0.5 - cy) <= r) ids.insert(box[std::size_t{py - y0} * (x1 - x0) + (qx - x0)]);
      }
    }
    ids.erase(0);
    return ids;
  }
};

FocusTracker::FocusTracker(FocusSettings settings) : settings_(settings) {
  settings_.check();
  reset();
}

void FocusTracker::reset() {
  result_ = FocusResult{};
  result_.focal_depth_m = result_.target_depth_m = settings_.fixed_depth_m;
  target_ = from_ = Target{};
  last_time_s_ = transition_elapsed_s_ = filter_velocity_ = 0;
  last_fixations_ = last_pursuits_ = 0;
  started_ = gaze_target_ = false;
}

// Attention mode (Lee 2009 §6.1): the most attended foreground object; when none is attended (or its
// S_o is below min_attention), the depth at the screen centre.
FocusTracker::Target FocusTracker::pick_attention(const FrameView& f) const {
  Target t;
  const char* mode = settings_.mode == FocusMode::Attention ? "attention" : "gaze+attention";
  const ObjectAttention* best = nullptr;
  if (f.attention != nullptr) {
    for (const ObjectAttention& o : f.attention->objects) {
      if (!std::isfinite(o.attention) || o.attention < settings_.min_attention || o.id == 0) continue;
      if (!f.object_depth(o.id)) continue;
      if (best == nullptr || o.attention > best->attention) best = &o;
    }
  }
  if (best == nullptr) {
    t.kind = Target::Kind::Centre;
    t.why = std::string(mode) + (f.attention == nullptr ? ": no attention" : ": no foreground object attended") +
            (settings_.mode == FocusMode::GazeAndAttention ? " and no gaze" : "") + ", screen centre";
    return t;
  }
  t.kind = Target::Kind::Object;
  t.object = best->id;
  t.why = std::string(mode) + ": " + object_name(f.scene, best->id) + " (S_o " + g3(best->attention) + ")" +
          (settings_.mode == FocusMode::GazeAndAttention ? ", no gaze" : "");
  return t;
}

// Gaze modes at a fixation onset. Gaze: the foreground object under the gaze point. Gaze+attention:
// trackers err by 1-2 deg (Jensen & Pedersen 2009, Table 4.1), so every foreground object with a pixel
// within gaze_radius_deg is a candidate and the highest attention S_o wins (Lee §6.3's ambiguity of
// monocular gaze); ties go to the object under the gaze point, then to the lower id. Neither finds
// an object: the depth under the gaze point.
FocusTracker::Target FocusTracker::pick_gaze(const FrameView& f, double x, double y, bool with_attention) const {
  Target t;
  t.x = clamp01(x);
  t.y = clamp01(y);
  if (with_attention && f.attention != nullptr) {
    const std::set<std::uint32_t> near = f.ids_near(t.x, t.y, settings_.gaze_radius_deg);
    const std::uint32_t under = f.id_at(t.x, t.y);
    const ObjectAttention* best = nullptr;
    int candidates = 0;
    const auto score = [](const ObjectAttention& o) {
      return std::isfinite(o.attention) ? o.attention : -std::numeric_limits<double>::infinity();
    };
    for (const ObjectAttention& o : f.attention->objects) {
      if (o.id == 0 || !near.contains(o.id) || !f.object_depth(o.id)) continue;
      ++candidates;
      if (best == nullptr || score(o) > score(*best) ||
          (score(o) == score(*best) && (o.id == under || (best->id != under && o.id < best->id)))) {
        best = &o;
      }
    }
    if (best != nullptr) {
      t.kind = Target::Kind::Object;
      t.object = best->id;
      t.why = "gaze+attention: " + object_name(f.scene, best->id) + " (S_o " + g3(best->attention) + ", " +
              std::to_string(candidates) + " candidate(s) within " + g3(settings_.gaze_radius_deg) + " deg)";
      return t;
    }
    t.kind = Target::Kind::Point;
    t.why = "gaze+attention: no foreground object within " + g3(settings_.gaze_radius_deg) +
            " deg, depth under the gaze point";
    return t;
  }
  const char* mode = with_attention ? "gaze+attention (no attention)" : "gaze";
  const std::uint32_t id = f.id_at(t.x, t.y);
  if (f.foreground(id) && f.object_depth(id)) {
    t.kind = Target::Kind::Object;
    t.object = id;
    t.why = std::string(mode) + ": " + object_name(f.scene, id) + " under the gaze point";
    return t;
  }
  t.kind = Target::Kind::Point;
  t.why = std::string(mode) + ": depth under the gaze point (" +
          (id == 0 ? std::string("nothing hit: far plane") : object_name(f.scene, id) + ", background") + ")";
  return t;
}

// The target's depth this frame; an object that is no longer visible keeps its last depth.
double FocusTracker::resolve(const FrameView& f, Target& t, bool* visible) const {
  if (visible != nullptr) *visible = true;
  std::optional<double> d;
  switch (t.kind) {
    case Target::Kind::Fixed: d = f.sane(settings_.fixed_depth_m); break;
    case Target::Kind::Depth: d = f.sane(t.depth_m); break;
    case Target::Kind::Centre: d = f.depth_at(0.5, 0.5); break;
    case Target::Kind::Point: d = f.depth_at(t.x, t.y); break;
    case Target::Kind::Object:
      d = f.object_depth(t.object);
      if (!d && visible != nullptr) *visible = false;
      break;
  }
  if (d) t.depth_m = *d;
  if (!std::isfinite(t.depth_m) || t.depth_m <= 0) t.depth_m = f.far_m;  // only a never-resolved target
  return t.depth_m;
}

// The frame gap; a time going backwards (or not a number) holds the transition.
double FocusTracker::advance_clock(double time_s) {
  double dt = 0;
  if (started_ && std::isfinite(time_s) && time_s > last_time_s_) dt = time_s - last_time_s_;
  if (std::isfinite(time_s)) last_time_s_ = time_s;
  if (!std::isfinite(dt)) dt = 0;  // an overflowing gap
  transition_elapsed_s_ = std::min(transition_elapsed_s_ + dt, 1e9);
  return dt;
}

// 1. The target this frame, by mode (Lee 2009 §6.1); `held` when a saccade or blink keeps the last one.
FocusTracker::Target FocusTracker::pick_target(const FrameView& f, const FocusGaze& gaze, bool& held) {
  Target next = target_;
  switch (settings_.mode) {
    case FocusMode::Fixed:
      next = Target{};
      next.kind = Target::Kind::Fixed;
      next.why = "fixed: the lens focus distance (" + g3(settings_.fixed_depth_m) + " m)";
      break;
    case FocusMode::Attention: next = pick_attention(f); break;
    case FocusMode::Gaze:
    case FocusMode::GazeAndAttention: next = follow_gaze(f, gaze, held); break;
  }
  return next;
}

// The gaze modes: refocus at a fixation or pursuit onset, hold the target through saccades and blinks.
FocusTracker::Target FocusTracker::follow_gaze(const FrameView& f, const FocusGaze& gaze, bool& held) {
  Target next = target_;
  const bool with_attention = settings_.mode == FocusMode::GazeAndAttention;
  const bool can_look = gaze.available && gaze.valid && !gaze.saccade_or_blink;
  const bool visible = !gaze_target_ || target_.kind != Target::Kind::Object || f.object_depth(target_.object);
  const bool onset =
      gaze.fixations != last_fixations_ || (settings_.refocus_on_pursuit && gaze.pursuits != last_pursuits_);
  if (can_look && (!gaze_target_ || onset || !visible)) {
    // Refocus: the first gaze, a fixation or pursuit onset, or the focused object has gone.
    next = pick_gaze(f, gaze.x, gaze.y, with_attention);
    gaze_target_ = true;
    last_fixations_ = gaze.fixations;
    last_pursuits_ = gaze.pursuits;
  } else if (gaze_target_ && !visible) {
    // The focused object went during a saccade or blink: whatever is now where the fixation was.
    next = pick_gaze(f, target_.x, target_.y, with_attention);
  } else if (!gaze_target_) {
    // No gaze yet (no source, blink at start-up): attention alone, or the screen centre.
    if (with_attention) {
      next = pick_attention(f);
    } else {
      next = Target{};
      next.kind = Target::Kind::Centre;
      next.why = gaze.available ? "gaze: no valid gaze yet, screen centre" : "gaze: no gaze source, screen centre";
    }
  } else {
    held = gaze.available && (gaze.saccade_or_blink || !gaze.valid);
  }
  return next;
}

// 2. A new target starts a transition (eq. 6.1) from where the old one is now. Reads last frame's
// result_ (update() overwrites it only at the end).
void FocusTracker::start_transition_if_changed(const Target& next) {
  const bool changed = next.kind != target_.kind || next.object != target_.object ||
                       (next.kind == Target::Kind::Point && (next.x != target_.x || next.y != target_.y));
  const double focal_before = result_.focal_depth_m;
  const bool lerp_running = result_.in_transition && settings_.transition == FocusTransition::Lerp;
  if (started_ && changed) {
    if (lerp_running) {
      // A change before the last transition finished: start again from the current focal depth
      // (Lee notes plain lerp cannot respond until the prior transition completes; this can).
      from_ = Target{};
      from_.kind = Target::Kind::Depth;
      from_.depth_m = focal_before;
    } else {
      from_ = target_;
    }
    transition_elapsed_s_ = 0;
  }
}

// 3. The focal depth on the way to the target's depth zn.
FocusTracker::FocalDepth FocusTracker::focal_depth(const FrameView& f, double zn, double dt) {
  FocalDepth focal{zn, false};
  if (!started_ || settings_.mode == FocusMode::Fixed) {
    // Nothing to move from: the first target is in focus at once, and no transition is running
    // (the lerp below would otherwise start one from a default target on the next frame).
    filter_velocity_ = 0;
    transition_elapsed_s_ = 1e9;
    from_ = target_;
  } else if (settings_.transition == FocusTransition::Lerp) {
    focal = lerp_focal_depth(f, zn);
  } else {
    focal = low_pass_focal_depth(zn, dt);
  }
  if (!std::isfinite(focal.depth_m) || focal.depth_m <= 0) {
    focal.depth_m = zn;
    filter_velocity_ = 0;
  }
  return focal;
}

// Lee 2009, eq. 6.1: Z_f(t) = lerp(Z_p(t), Z_n(t), t / tau), both depths followed as they move.
FocusTracker::FocalDepth FocusTracker::lerp_focal_depth(const FrameView& f, double zn) {
  FocalDepth focal{zn, false};
  const double s =
      settings_.transition_s > 0 ? std::clamp(transition_elapsed_s_ / settings_.transition_s, 0.0, 1.0) : 1.0;
  if (s < 1 - 1e-9) {  // (frame times summed may fall an ulp short of tau)
    const double zp = resolve(f, from_);
    focal.depth_m = zp + (zn - zp) * s;
    focal.in_transition = true;
  }
  return focal;
}

// Low-pass alternative (Lee 2009 §6.1, cut-off <= 2 Hz): a critically damped second-order filter
// x'' = w^2 (z - x) - 2 w x', solved exactly over the frame gap for the target held since the last
// frame (sample and hold), so any gap is stable. w puts the -3 dB point at cutoff_hz: for a
// critically damped pair |H(f)| = 1 / (1 + (f/f0)^2), so f_-3dB = f0 sqrt(sqrt(2) - 1).
// Lee reports overshoot at the end of the transition with his filter; critically damped, a step
// never overshoots (it still lags behind a moving target). Starts from last frame's result_.
FocusTracker::FocalDepth FocusTracker::low_pass_focal_depth(double zn, double dt) {
  const double focal_before = result_.focal_depth_m, target_before = result_.target_depth_m;
  const double w = 2 * std::numbers::pi * settings_.cutoff_hz / std::sqrt(std::sqrt(2.0) - 1.0);
  const double e0 = focal_before - target_before, v0 = filter_velocity_;
  const double decay = std::exp(-w * dt);
  const double b = v0 + w * e0;
  double e = (e0 + b * dt) * decay;
  double v = (v0 - w * b * dt) * decay;
  if (!std::isfinite(e) || !std::isfinite(v)) e = v = 0;
  FocalDepth focal{zn, false};
  focal.depth_m = target_before + e;
  filter_velocity_ = v;
  const double tolerance = 1e-3 * std::max(1.0, std::abs(zn));
  focal.in_transition = std::abs(focal.depth_m - zn) > tolerance || std::abs(v) > tolerance;
  return focal;
}

const FocusResult& FocusTracker::update(double time_s, const GBuffer& g, const Scene& scene,
                                        const AttentionFrame* attention, const FocusGaze& gaze,
                                        const protocol::DisplayGeometry& display) {
  GBufferPixels pixels(g);
  return update(time_s, pixels, scene, attention, gaze, display);
}

const FocusResult& FocusTracker::update(double time_s, FocusPixels& pixels, const Scene& scene,
                                        const AttentionFrame* attention, const FocusGaze& gaze,
                                        const protocol::DisplayGeometry& display) {
  const FrameView f(pixels, scene, attention, display);
  const double dt = advance_clock(time_s);
  bool held = false;
  Target next = pick_target(f, gaze, held);
  start_transition_if_changed(next);
  target_ = std::move(next);
  bool visible = true;
  const double zn = resolve(f, target_, &visible);
  const FocalDepth focal = focal_depth(f, zn, dt);

  started_ = true;
  result_.focal_depth_m = focal.depth_m;
  result_.target_depth_m = zn;
  result_.object = target_.kind == Target::Kind::Object ? target_.object : 0;
  result_.object_visible = result_.object != 0 && visible;
  result_.in_transition = focal.in_transition;
  result_.why = target_.why + (held ? " (held: saccade or blink)" : "");
  return result_;
}

}  // namespace fovea::render::attention
