// SPDX-License-Identifier: Apache-2.0
// The attention tracker (attention.h): its settings, the stages of update() in the order it runs
// them (the pixel stage's object features and saliency map, eqs. 3.2-3.6, on the map that
// gbuffer_resample.cpp and feature_pyramid.cpp make; the object stage, eqs. 3.7-3.10 and the
// Kalman filter) and update_objects().
#include "attention/attention.h"

#include <algorithm>
#include <tbb/parallel_invoke.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <unordered_map>

#include "attention/feature_pyramid.h"
#include "attention/gbuffer_resample.h"

namespace fovea::render::attention {

void AttentionSettings::check() const {
  const auto bad = [](const std::string& what) { throw std::invalid_argument("attention settings: " + what); };
  if (map_size < 64 || map_size > 512) bad("map_size=" + std::to_string(map_size) + ": allowed 64..512");
  if (!std::isfinite(preferred_distance_m) || preferred_distance_m <= 0) {
    bad("preferred_distance_m=" + std::to_string(preferred_distance_m) + ": allowed a finite number > 0");
  }
  if (!std::isfinite(c_y) || c_y < 0) bad("c_y=" + std::to_string(c_y) + ": allowed a finite number >= 0");
  if (temporal_window < 1 || temporal_window > 100000) {
    bad("temporal_window=" + std::to_string(temporal_window) + ": allowed 1..100000 frames");
  }
  if (!std::isfinite(kalman_process_noise) || kalman_process_noise <= 0) {
    bad("kalman_process_noise=" + std::to_string(kalman_process_noise) + ": allowed a finite number > 0");
  }
  if (!std::isfinite(kalman_measurement_noise) || kalman_measurement_noise <= 0) {
    bad("kalman_measurement_noise=" + std::to_string(kalman_measurement_noise) + ": allowed a finite number > 0");
  }
}

using namespace detail;

namespace {

enum Feature { kLum = 0, kHue = 1, kDepth = 2, kSize = 3, kMotion = 4 };

bool finite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// Per visible scene object, this frame.
struct Slot {
  const Object* object = nullptr;
  std::size_t full_pixels = 0;  // pixels in the map's item buffer (eq. 3.2)
  float size = 0, motion = 0;   // B_s, B_m
  std::size_t n = 0;            // pixels in the map
  double sum_saliency = 0, sum_x = 0, sum_y = 0;
  std::vector<float> depths;
};

}  // namespace

// Buffers reused from frame to frame: allocating ~2 MB of maps per frame costs page faults.
struct AttentionTracker::Scratch {
  Pyramid planes[kPlanes];
  Magnified magnified[kPlanes];
  std::vector<float> map_depth, sbar;
  std::vector<std::uint32_t> map_slot;
};

AttentionTracker::AttentionTracker(AttentionSettings settings)
    : settings_(settings), scratch_(std::make_unique<Scratch>()) {
  settings_.check();
}
AttentionTracker::~AttentionTracker() = default;
AttentionTracker::AttentionTracker(AttentionTracker&&) noexcept = default;
AttentionTracker& AttentionTracker::operator=(AttentionTracker&&) noexcept = default;

void AttentionTracker::set_settings(const AttentionSettings& s) {
  s.check();
  const bool temporal_changed = s.temporal_window != settings_.temporal_window || s.kalman != settings_.kalman ||
                                s.kalman_process_noise != settings_.kalman_process_noise ||
                                s.kalman_measurement_noise != settings_.kalman_measurement_noise ||
                                s.groups.context != settings_.groups.context;
  settings_ = s;
  if (temporal_changed) reset();
}

void AttentionTracker::reset() { tracks_.clear(); }

glm::vec3 AttentionTracker::farthest_vertex(const std::shared_ptr<const Mesh>& mesh) {
  if (!mesh || mesh->positions.empty()) return glm::vec3(0.0f);
  auto it = extents_.find(mesh.get());
  if (it != extents_.end() && it->second.mesh.lock() == mesh) return it->second.farthest;
  if (extents_.size() > 4096) std::erase_if(extents_, [](const auto& e) { return e.second.mesh.expired(); });
  // The object's centre: the centre of its object-space bounding box (finite vertices only).
  glm::vec3 lo(std::numeric_limits<float>::max()), hi(std::numeric_limits<float>::lowest());
  for (const glm::vec3& p : mesh->positions) {
    if (!finite(p)) continue;
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  glm::vec3 far_v(0.0f);
  if (lo.x <= hi.x) {
    const glm::vec3 centre = 0.5f * (lo + hi);
    float best = -1;
    for (const glm::vec3& p : mesh->positions) {
      if (!finite(p)) continue;
      const float d = glm::dot(p - centre, p - centre);
      if (d > best) {
        best = d;
        far_v = p;
      }
    }
  }
  extents_[mesh.get()] = Extent{mesh, far_v};
  return far_v;
}

// The stages of AttentionTracker::update, in the order it runs them.
namespace {

// Scene objects by id, and a dense slot for each one seen in the map (made on first sight).
struct SlotTable {
  explicit SlotTable(const Scene& s) : scene(s) {
    object_index.reserve(scene.objects.size() * 2);
    for (std::size_t i = 0; i < scene.objects.size(); ++i) object_index.emplace(scene.objects[i].id, i);
  }
  // The object's slot + 1; 0 for the background and for ids that are not objects of the scene.
  std::uint32_t slot_for(std::uint32_t id) {
    if (id == 0) return 0;
    if (id == last_id) return last_slot;
    auto it = slot_of.find(id);
    std::uint32_t s = 0;
    if (it != slot_of.end()) {
      s = it->second;
    } else {
      const auto o = object_index.find(id);
      if (o != object_index.end()) {
        slots.push_back(Slot{&scene.objects[o->second], 0, 0, 0, 0, 0, 0, 0, {}});
        s = static_cast<std::uint32_t>(slots.size());
      }
      slot_of.emplace(id, s);
    }
    last_id = id;
    last_slot = s;
    return s;
  }
  const Scene& scene;
  std::unordered_map<std::uint32_t, std::size_t> object_index;
  std::vector<Slot> slots;
  std::unordered_map<std::uint32_t, std::uint32_t> slot_of;  // id -> slot + 1 (0: not an object of the scene)
  std::uint32_t last_id = 0, last_slot = 0;
};

// Object features: B_s (eq. 3.2) and B_m (eq. 3.3).
// B_s counts the pixels of the item buffer as resampled to the map (nearest), over the map's
// pixels: the map is the image the paper's GPU pass works on, and it spares a second pass over the
// full-resolution buffer (an object smaller than a map pixel may get 0; it has no pixels in S_p
// either, so eq. 3.7 cannot list it anyway).
void count_object_pixels(const std::vector<std::uint32_t>& ids, std::size_t npix, SlotTable& table,
                         std::vector<std::uint32_t>& map_slot) {
  std::vector<Slot>& slots = table.slots;
  map_slot.assign(npix, 0);
  for (std::size_t m = 0; m < npix; ++m) {
    map_slot[m] = table.slot_for(ids[m]);
    if (map_slot[m] != 0) ++slots[map_slot[m] - 1].full_pixels;
  }
}

// B_m (eq. 3.3): the displacement over the frame of the vertex `p` farthest from the object's
// centre, so that self-rotation counts as well as translation. An animation yielding a non-finite
// transform makes the object's motion 0 (it cannot be measured; it must not poison the maps).
float measure_motion(const Object& o, glm::vec3 p, double time_s, double previous_time_s) {
  const glm::mat4 now = o.transform_at(time_s).matrix();
  const glm::mat4 before = o.transform_at(previous_time_s).matrix();
  const glm::vec3 a = glm::vec3(now * glm::vec4(p, 1.0f)), b = glm::vec3(before * glm::vec4(p, 1.0f));
  const float d = glm::length(a - b);
  return (finite(a) && finite(b) && std::isfinite(d)) ? d : 0.0f;
}

// B_s (eq. 3.2) and B_m (eq. 3.3) per visible object; `motion` gives eq. 3.3's B_m of an object.
template <class Motion>
void measure_size_and_motion(std::vector<Slot>& slots, std::size_t npix, const Motion& motion) {
  for (Slot& s : slots) {
    s.size = static_cast<float>(static_cast<double>(s.full_pixels) / static_cast<double>(npix));
    s.motion = motion(*s.object);
  }
}

// The size and motion planes of Fig. 3.3's DSM texture: each object's B_s and B_m on its pixels.
void paint_object_planes(const std::vector<std::uint32_t>& map_slot, const std::vector<Slot>& slots, std::size_t npix,
                         Pyramid (&planes)[kPlanes]) {
  float* __restrict size0 = planes[kPSize][0].v.data();
  float* __restrict motion0 = planes[kPMotion][0].v.data();
  for (std::size_t m = 0; m < npix; ++m) {
    if (map_slot[m] != 0) {
      size0[m] = slots[map_slot[m] - 1].size;
      motion0[m] = slots[map_slot[m] - 1].motion;
    }
  }
}

// Pyramids and centre-surround (eq. 3.4): the five contrast maps C_f (0 for a group that is off).
// They are independent: computed as parallel tasks (TBB).
void contrast_maps(Pyramid (&planes)[kPlanes], Magnified (&magnified)[kPlanes], int n, const FeatureGroups& groups,
                   std::vector<float> (&maps)[5]) {
  const auto un = static_cast<std::size_t>(n), npix = un * un;
  const bool image_group = groups.image, object_group = groups.object;
  const auto contrast = [&](bool on, Feature feature, Plane plane) {
    if (!on) {
      maps[feature].assign(npix, 0.0f);
      return;
    }
    build_pyramid(planes[plane]);
    centre_surround(planes[plane], n, magnified[plane], maps[feature]);
  };
  tbb::parallel_invoke(
      [&] {
        if (!image_group) {
          maps[kHue].assign(npix, 0.0f);
          return;
        }
        tbb::parallel_invoke([&] { build_pyramid(planes[kPHa]); }, [&] { build_pyramid(planes[kPHb]); });
        centre_surround_vector(planes[kPHa], planes[kPHb], n, magnified[kPHa], magnified[kPHb], maps[kHue]);
      },
      [&] { contrast(image_group, kLum, kPL); }, [&] { contrast(object_group, kDepth, kPDepth); },
      [&] { contrast(object_group, kSize, kPSize); }, [&] { contrast(object_group, kMotion, kPMotion); });
}

// Weights (eq. 3.6) and S_p (eq. 3.5): the weighted sum of the contrast maps, normalised to [0, 1].
// The contrast maps are sanitised in place (NaN and Inf: 0).
void saliency_map(std::vector<float> (&maps)[5], const FeatureGroups& groups, std::size_t npix, std::vector<float>& sbar,
                  std::vector<float>& saliency) {
  saliency.assign(npix, 0.0f);
  if (groups.image || groups.object) {
    sbar.assign(npix, 0.0f);
    float* __restrict sb = sbar.data();
    for (auto& map : maps) {
      float* __restrict c = map.data();
      float mx = 0;
#pragma omp simd reduction(max : mx)
      for (std::size_t i = 0; i < npix; ++i) {
        // Contrast is >= 0; NaN and Inf (impossible with finite inputs) become 0 as a guard.
        const float v = c[i] >= 0.0f && c[i] <= std::numeric_limits<float>::max() ? c[i] : 0.0f;
        c[i] = v;
        mx = std::max(mx, v);
      }
      if (mx <= 0) continue;  // eq. 3.6: a map without contrast contributes nothing (not 1/0)
      const float w = 1.0f / mx;
#pragma omp simd
      for (std::size_t i = 0; i < npix; ++i) sb[i] += w * c[i];
    }
    // Normalise to [0, 1] by min and max; a map whose pixels are all equal has no salient pixel: 0.
    float lo = std::numeric_limits<float>::max(), hi = 0;
#pragma omp simd reduction(min : lo) reduction(max : hi)
    for (std::size_t i = 0; i < npix; ++i) {
      lo = std::min(lo, sb[i]);
      hi = std::max(hi, sb[i]);
    }
    const float span = hi - lo;
    if (span > 1e-6f * std::max(1.0f, hi)) {
      const float inv = 1.0f / span;
      float* __restrict out = saliency.data();
#pragma omp simd
      for (std::size_t i = 0; i < npix; ++i) out[i] = std::clamp((sb[i] - lo) * inv, 0.0f, 1.0f);
    }
  } else {
    // Neither B nor E: there is no bottom-up map, every pixel counts alike (S_p = 1) so that
    // S^_o = T_i and the top-down contexts alone decide (the "T only" row of Lee's Table 3.2).
    std::fill(saliency.begin(), saliency.end(), 1.0f);
  }
}

// Object level, eq. 3.7's sums: per object its map pixels, their saliency, their centroid and depths.
void accumulate_object_pixels(const std::vector<std::uint32_t>& map_slot, const std::vector<float>& saliency,
                              const std::vector<float>& map_depth, int n, std::vector<Slot>& slots) {
  const auto un = static_cast<std::size_t>(n);
  for (std::size_t y = 0; y < un; ++y) {
    for (std::size_t x = 0; x < un; ++x) {
      const std::size_t m = y * un + x;
      if (map_slot[m] == 0) continue;
      Slot& s = slots[map_slot[m] - 1];
      ++s.n;
      s.sum_saliency += static_cast<double>(saliency[m]);
      s.sum_x += (static_cast<double>(x) + 0.5) / n;
      s.sum_y += (static_cast<double>(y) + 0.5) / n;
      s.depths.push_back(map_depth[m]);
    }
  }
}

// The observer of eq. 3.9 over the frame, and the equation's constants.
struct SpatialContext {
  glm::dvec3 eye_now, eye_before;  // observer position now and at the previous frame
  bool moving_forward;             // v . w > 0
  double c_x, c_s, c_y;
};

// Top-down contexts (eqs. 3.8-3.10): the observer and the constants of eq. 3.9.
SpatialContext spatial_context(const Camera& camera, const AttentionSettings& settings, double time_s,
                               double previous_time_s) {
  // Observer: position now and at the previous frame, viewing direction v, moving direction w.
  // A camera animation that yields non-finite positions counts as an observer that does not move.
  glm::dvec3 eye_now = glm::dvec3(camera.position_at(time_s));
  glm::dvec3 eye_before = glm::dvec3(camera.position_at(previous_time_s));
  if (!std::isfinite(eye_now.x + eye_now.y + eye_now.z)) eye_now = glm::dvec3(camera.position);
  if (!std::isfinite(eye_before.x + eye_before.y + eye_before.z)) eye_before = eye_now;
  const glm::dvec3 view = glm::dvec3(camera.target) - glm::dvec3(camera.position);  // v (animation moves both)
  const glm::dvec3 moving = eye_now - eye_before;                                     // w
  const bool moving_forward = glm::dot(view, moving) > 0;
  // Eq. 3.9's distance term (x/c_x) e^{-(x/c_x)^2} peaks at x/c_x = 1/sqrt(2); the paper's
  // c_x = L / 0.707 is L / (1/sqrt 2) rounded, and we use c_x = sqrt(2) L so the peak is exactly at L.
  // c_s scales the peak of the product (screen term <= 1) to 0.5: c_s = 0.5 / (e^{-1/2} / sqrt 2), so
  // T_s lies in [0, 0.5] and reaches 0.5 for an object at distance L in the screen centre.
  const double c_x = std::numbers::sqrt2 * settings.preferred_distance_m;
  const double c_s = 0.5 / (std::exp(-0.5) / std::numbers::sqrt2);
  return SpatialContext{eye_now, eye_before, moving_forward, c_x, c_s, settings.c_y};
}

// Kalman time step: |time_s - previous_time_s| (time going backwards is a step of the same
// length), at most 1 s (a longer gap would extrapolate the rate too far; the filter re-converges
// within a frame after a long gap anyway, its covariance having grown).
double kalman_time_step(double time_s, double previous_time_s) {
  double dt = std::fabs(time_s - previous_time_s);
  if (!std::isfinite(dt)) dt = 0;
  dt = std::min(dt, 1.0);
  return dt;
}

// The pixel stage's sums of the slots seen in the map, with each one's median depth.
std::vector<ObjectPixels> object_pixels(std::vector<Slot>& slots) {
  std::vector<ObjectPixels> out;
  out.reserve(slots.size());
  for (Slot& s : slots) {
    if (s.n == 0) continue;
    auto mid = s.depths.begin() + static_cast<std::ptrdiff_t>(s.depths.size() / 2);
    std::nth_element(s.depths.begin(), mid, s.depths.end());
    out.push_back(ObjectPixels{s.object->id, s.n, s.sum_saliency, s.sum_x, s.sum_y, static_cast<double>(*mid)});
  }
  return out;
}

// Eq. 3.7: S^_o = T_i / n sum S_p over the object's pixels, with their centroid and median depth.
ObjectAttention object_saliency(const Object& o, const ObjectPixels& p, std::size_t npix, float motion) {
  ObjectAttention a;
  a.id = o.id;
  a.pixels = p.pixels;
  a.size = static_cast<double>(static_cast<float>(static_cast<double>(p.pixels) / static_cast<double>(npix)));
  a.motion = motion;
  const auto n = static_cast<double>(p.pixels);
  a.saliency = static_cast<double>(o.task_importance) * p.sum_saliency / n;  // eq. 3.7
  a.screen_x = p.sum_x / n;
  a.screen_y = p.sum_y / n;
  a.depth_m = p.depth_m;
  return a;
}

// Eq. 3.9: T_s from the observer-to-object distance, its change over the frame and the screen position.
void spatial_emphasis(const Object& o, const SpatialContext& ctx, double time_s, double previous_time_s,
                      ObjectAttention& a) {
  // x and dx of eq. 3.9: observer to object centre (the transform's translation) now and at the
  // previous frame. A non-finite object position makes x = 0 and dx = 0 (T_s = 0 then: no
  // distance emphasis for an object we cannot place).
  const glm::dvec3 centre_now = glm::dvec3(o.transform_at(time_s).translation);
  const glm::dvec3 centre_before = glm::dvec3(o.transform_at(previous_time_s).translation);
  double x_now = glm::length(centre_now - ctx.eye_now), x_before = glm::length(centre_before - ctx.eye_before);
  if (!std::isfinite(x_now)) x_now = 0;
  if (!std::isfinite(x_before)) x_before = x_now;
  a.distance_m = x_now;
  const double dx = x_now - x_before;
  const double sy = std::hypot(a.screen_x - 0.5, a.screen_y - 0.5) / std::sqrt(0.5);  // corner = 1
  if (ctx.moving_forward && dx > 0) {
    a.spatial = 0;  // moving forward and the object moves away: not attended (eq. 3.9, first case)
  } else {
    const double r = x_now / ctx.c_x;
    a.spatial = ctx.c_s * r * std::exp(-r * r) * std::exp(-ctx.c_y * sy * sy);
  }
  if (!std::isfinite(a.spatial)) a.spatial = 0;
}

// The objects eq. 3.7 lists (foreground objects of the scene with pixels in the map), with S^_o and
// T_s; `spatial_now` gets each one's T_s. `motion` gives an object's B_m.
template <class Motion>
void list_objects(const std::vector<ObjectPixels>& pixels, const Scene& scene, std::size_t npix,
                  const SpatialContext& ctx, double time_s, double previous_time_s, const Motion& motion,
                  std::vector<ObjectAttention>& objects, std::map<std::uint32_t, double>& spatial_now) {
  std::unordered_map<std::uint32_t, const Object*> by_id;
  by_id.reserve(scene.objects.size() * 2);
  for (const Object& o : scene.objects) by_id.emplace(o.id, &o);
  for (const ObjectPixels& p : pixels) {
    const auto it = p.id != 0 && p.pixels > 0 ? by_id.find(p.id) : by_id.end();
    const Object* o = it != by_id.end() ? it->second : nullptr;
    if (o == nullptr || !(o->task_importance > 0)) continue;  // not an object, invisible, or background
    if (spatial_now.count(o->id) != 0) continue;               // listed twice: the first counts
    ObjectAttention a = object_saliency(*o, p, npix, motion(*o));
    spatial_emphasis(*o, ctx, time_s, previous_time_s, a);
    spatial_now[o->id] = a.spatial;
    objects.push_back(a);
  }
}

// Objects by attention, highest first (ties by id), and the most attended one.
void rank_by_attention(AttentionFrame& f) {
  std::sort(f.objects.begin(), f.objects.end(), [](const ObjectAttention& a, const ObjectAttention& b) {
    return a.attention != b.attention ? a.attention > b.attention : a.id < b.id;
  });
  if (!f.objects.empty()) f.most_attended = f.objects.front().id;
}

}  // namespace

// Eq. 3.10: T_t = (1/lambda) sum of the last lambda T_s. A frame in which an object was not listed
// (not visible, or no pixels in the map) contributes T_s = 0, and so does every frame before the
// object was first seen: T_t rises over lambda frames. A track whose last lambda T_s are all 0 is
// dropped (bounded memory with many objects coming and going).
void AttentionTracker::age_tracks(const std::map<std::uint32_t, double>& spatial_now, std::size_t lambda) {
  for (auto& [id, track] : tracks_) {
    if (spatial_now.count(id) == 0) {
      track.spatial[track.next] = 0;
      track.next = (track.next + 1) % track.spatial.size();
      ++track.zeros;
      track.filtered = false;  // out of view this frame: the filter restarts when it comes back
    }
  }
  std::erase_if(tracks_, [&](const auto& t) { return t.second.zeros >= lambda && spatial_now.count(t.first) == 0; });
}

// Eq. 3.10 for a listed object: its T_s joins the ring of the last lambda; T_t is their mean.
double AttentionTracker::temporal_context(Track& t, double spatial, std::size_t lambda) {
  if (t.spatial.size() != lambda) {
    t.spatial.assign(lambda, 0.0);
    t.next = 0;
  }
  t.spatial[t.next] = spatial;
  t.next = (t.next + 1) % lambda;
  t.zeros = spatial > 0 ? 0 : t.zeros + 1;
  double sum = 0;
  for (double v : t.spatial) sum += v;
  return sum / static_cast<double>(lambda);
}

// Discrete Kalman filter (Lee §3.3, stage 4), constant-velocity model: state (attention, rate),
// F = [1 dt; 0 1], white-noise acceleration of spectral density q:
// Q = q [dt^3/3 dt^2/2; dt^2/2 dt]; measurement H = [1 0] with variance r. An object seen for the
// first time (or again after a frame out of view) starts at its measurement.
double AttentionTracker::kalman_filter(Track& t, double z, double dt, double q, double rn) {
  if (!t.filtered) {
    t.x = z;
    t.v = 0;
    t.p00 = rn;
    t.p01 = 0;
    t.p11 = 1;
    t.filtered = true;
  } else {
    // Predict.
    const double x = t.x + dt * t.v;
    const double p00 = t.p00 + dt * (2 * t.p01 + dt * t.p11) + q * dt * dt * dt / 3;
    const double p01 = t.p01 + dt * t.p11 + q * dt * dt / 2;
    const double p11 = t.p11 + q * dt;
    // Update.
    const double s = p00 + rn;
    const double k0 = p00 / s, k1 = p01 / s;
    const double innovation = z - x;
    t.x = x + k0 * innovation;
    t.v = t.v + k1 * innovation;
    t.p00 = (1 - k0) * p00;
    t.p01 = (1 - k0) * p01;
    t.p11 = p11 - k1 * p01;
    if (!std::isfinite(t.x + t.v + t.p00 + t.p01 + t.p11)) {
      t.x = z;
      t.v = 0;
      t.p00 = rn;
      t.p01 = 0;
      t.p11 = 1;
    }
  }
  return std::max(0.0, t.x);  // the state keeps its sign; what we report is >= 0
}

// Per listed object: T_t (eq. 3.10), S_o (eq. 3.8) and S_o after the Kalman filter (§3.2.1).
void AttentionTracker::filter_attention(std::vector<ObjectAttention>& objects, std::size_t lambda, double dt) {
  const double q = settings_.kalman_process_noise, rn = settings_.kalman_measurement_noise;
  for (ObjectAttention& a : objects) {
    Track& t = tracks_[a.id];
    a.temporal = temporal_context(t, a.spatial, lambda);
    // Eq. 3.8; without the context group, S_o = S^_o.
    a.attention_raw = settings_.groups.context ? (a.spatial + a.temporal) * a.saliency : a.saliency;
    if (!std::isfinite(a.attention_raw)) a.attention_raw = 0;
    a.attention = settings_.kalman ? kalman_filter(t, a.attention_raw, dt, q, rn) : a.attention_raw;
  }
}

float AttentionTracker::object_motion(const Object& o, double time_s, double previous_time_s) {
  return measure_motion(o, farthest_vertex(o.mesh), time_s, previous_time_s);
}

void AttentionTracker::object_stage(const std::vector<ObjectPixels>& pixels, std::size_t npix, const Scene& scene,
                                    double time_s, double previous_time_s) {
  AttentionFrame& f = frame_;
  const SpatialContext context = spatial_context(scene.camera, settings_, time_s, previous_time_s);
  const auto lambda = static_cast<std::size_t>(settings_.temporal_window);
  const double dt = kalman_time_step(time_s, previous_time_s);
  std::map<std::uint32_t, double> spatial_now;  // T_s of this frame, per listed object
  const auto motion = [&](const Object& o) { return object_motion(o, time_s, previous_time_s); };
  list_objects(pixels, scene, npix, context, time_s, previous_time_s, motion, f.objects, spatial_now);
  age_tracks(spatial_now, lambda);
  filter_attention(f.objects, lambda, dt);
  rank_by_attention(f);
}

const AttentionFrame& AttentionTracker::update(const GBuffer& g, const Scene& scene, double time_s,
                                               double previous_time_s) {
  const auto start = std::chrono::steady_clock::now();
  const int n = settings_.map_size;
  const auto un = static_cast<std::size_t>(n), npix = un * un;
  AttentionFrame& f = frame_;
  f.map_width = f.map_height = n;
  f.objects.clear();
  f.most_attended = 0;
  Scratch& sc = *scratch_;

  // Pixel saliency map (§3.1): the G-buffer resampled to n x n, the object features, eqs. 3.1-3.6.
  SlotTable table(scene);
  const Source src = read_source(g, scene.camera);
  const ResampleGrid grid = resample_grid(src, n, settings_.resample);
  resample_gbuffer(src, grid, n, settings_.resample, sc.planes, f.ids, sc.map_depth);
  f.resample_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  count_object_pixels(f.ids, npix, table, sc.map_slot);
  measure_size_and_motion(table.slots, npix, [&](const Object& o) { return object_motion(o, time_s, previous_time_s); });
  paint_object_planes(sc.map_slot, table.slots, npix, sc.planes);
  contrast_maps(sc.planes, sc.magnified, n, settings_.groups, f.contrast);
  saliency_map(f.contrast, settings_.groups, npix, sc.sbar, f.saliency);
  f.saliency_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  // Object attention (§3.2): eq. 3.7, the top-down contexts of eqs. 3.8-3.10, the Kalman filter.
  accumulate_object_pixels(sc.map_slot, f.saliency, sc.map_depth, n, table.slots);
  object_stage(object_pixels(table.slots), npix, scene, time_s, previous_time_s);
  f.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return f;
}

const AttentionFrame& AttentionTracker::update_objects(const std::vector<ObjectPixels>& pixels, int map_size,
                                                       const Scene& scene, double time_s, double previous_time_s,
                                                       double pixel_seconds) {
  const auto start = std::chrono::steady_clock::now();
  if (map_size < 1) throw std::invalid_argument("AttentionTracker::update_objects: map_size must be >= 1");
  AttentionFrame& f = frame_;
  f.map_width = f.map_height = map_size;
  f.saliency.clear();
  for (auto& c : f.contrast) c.clear();
  f.ids.clear();
  f.objects.clear();
  f.most_attended = 0;
  const auto un = static_cast<std::size_t>(map_size);
  object_stage(pixels, un * un, scene, time_s, previous_time_s);
  f.saliency_seconds = f.resample_seconds = pixel_seconds;
  f.seconds = pixel_seconds + std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return f;
}

}  // namespace fovea::render::attention
