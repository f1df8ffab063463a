// SPDX-License-Identifier: Apache-2.0
#include "attention/attention.h"

#include <algorithm>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <unordered_map>

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

namespace {

constexpr int kLevels = 7;  // pyramid levels 0 (finest) to 6 (coarsest), Lee 2009 §3.1.1
enum Feature { kLum = 0, kHue = 1, kDepth = 2, kSize = 3, kMotion = 4 };

// One level of a one-channel feature pyramid.
struct Level {
  int w = 0, h = 0;
  std::vector<float> v;  // w * h
};
using Pyramid = Level[kLevels];

// 2x2 box downsampling (what glGenerateMipmap does for power-of-two sizes). For an odd size the level
// below is ceil(n / 2) and the missing texel of the last 2x2 block repeats the edge texel.
void downsample(const Level& src, Level& dst) {
  dst.w = std::max(1, (src.w + 1) / 2);
  dst.h = std::max(1, (src.h + 1) / 2);
  const auto sw = static_cast<std::size_t>(src.w), dw = static_cast<std::size_t>(dst.w);
  dst.v.resize(dw * static_cast<std::size_t>(dst.h));
  const std::size_t pairs = sw / 2;  // whole 2x2 blocks per row
  for (int y = 0; y < dst.h; ++y) {
    const float* __restrict a = src.v.data() + static_cast<std::size_t>(std::min(2 * y, src.h - 1)) * sw;
    const float* __restrict b = src.v.data() + static_cast<std::size_t>(std::min(2 * y + 1, src.h - 1)) * sw;
    float* __restrict o = dst.v.data() + static_cast<std::size_t>(y) * dw;
#pragma omp simd
    for (std::size_t x = 0; x < pairs; ++x) o[x] = 0.25f * (a[2 * x] + a[2 * x + 1] + b[2 * x] + b[2 * x + 1]);
    if (pairs < dw) o[pairs] = 0.5f * (a[sw - 1] + b[sw - 1]);  // odd width: the edge texel twice
  }
}

void build_pyramid(Pyramid& pyr) {
  for (int l = 1; l < kLevels; ++l) downsample(pyr[l - 1], pyr[l]);
}

// Bilinear magnification of a coarse level onto the n samples of level 0 along one axis, as a GPU's
// texture unit does with GL_LINEAR and GL_CLAMP_TO_EDGE: level-0 sample k sits at (k + 0.5) / n,
// texel j of an m-texel level at (j + 0.5) / m.
struct Axis {
  std::vector<int> i0, i1;
  std::vector<float> f;
};
Axis axis(int n, int m) {
  Axis a;
  a.i0.resize(static_cast<std::size_t>(n));
  a.i1.resize(static_cast<std::size_t>(n));
  a.f.resize(static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) {
    const double s = (k + 0.5) * m / n - 0.5;
    const double fl = std::floor(s);
    const int j = static_cast<int>(fl);
    const auto i = static_cast<std::size_t>(k);
    a.i0[i] = std::clamp(j, 0, m - 1);
    a.i1[i] = std::clamp(j + 1, 0, m - 1);
    a.f[i] = static_cast<float>(s - fl);
  }
  return a;
}

// The coarse levels 1..6 of a pyramid magnified horizontally to n columns (h_L rows each), and the
// vertical lerp of each output row: level-0 row y of level L is a[y] + f[y] (b[y] - a[y]).
struct Magnified {
  std::vector<float> rows[kLevels];
  Axis vertical[kLevels];
  void build(const Pyramid& pyr, int n) {
    const auto un = static_cast<std::size_t>(n);
    for (int l = 1; l < kLevels; ++l) {
      const Level& lv = pyr[l];
      const Axis ax = axis(n, lv.w);
      vertical[l] = axis(n, lv.h);
      auto& hz = rows[l];
      hz.resize(static_cast<std::size_t>(lv.h) * un);
      for (int y = 0; y < lv.h; ++y) {
        const float* row = lv.v.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(lv.w);
        float* o = hz.data() + static_cast<std::size_t>(y) * un;
        for (std::size_t x = 0; x < un; ++x) {
          const float p = row[ax.i0[x]], q = row[ax.i1[x]];
          o[x] = p + ax.f[x] * (q - p);
        }
      }
    }
  }
  struct Row {
    const float* a[kLevels];
    const float* b[kLevels];
    float f[kLevels];
  };
  Row row(std::size_t y, std::size_t un) const {
    Row r{};
    for (int l = 1; l < kLevels; ++l) {
      r.a[l] = rows[l].data() + static_cast<std::size_t>(vertical[l].i0[y]) * un;
      r.b[l] = rows[l].data() + static_cast<std::size_t>(vertical[l].i1[y]) * un;
      r.f[l] = vertical[l].f[y];
    }
    return r;
  }
};

// Eq. 3.4 for one feature: C = 1/6 sum_{i in 0..2} sum_{j in 3,4} |B^i - B^{i+j}|, every level
// sampled at the level-0 pixel (Fig. 3.3's shader: texture2D(DSM, tc0, i)), coarse levels by
// bilinear magnification (first horizontally per level, then a vertical lerp per output row, fused
// with the differences so the row loop vectorises).
void centre_surround(const Pyramid& pyr, int n, Magnified& mg, std::vector<float>& out) {
  const auto un = static_cast<std::size_t>(n);
  out.resize(un * un);
  mg.build(pyr, n);
  for (std::size_t y = 0; y < un; ++y) {
    const Magnified::Row r = mg.row(y, un);
    const float* __restrict p0 = pyr[0].v.data() + y * un;
    const float *__restrict a1 = r.a[1], *__restrict b1 = r.b[1], *__restrict a2 = r.a[2], *__restrict b2 = r.b[2];
    const float *__restrict a3 = r.a[3], *__restrict b3 = r.b[3], *__restrict a4 = r.a[4], *__restrict b4 = r.b[4];
    const float *__restrict a5 = r.a[5], *__restrict b5 = r.b[5], *__restrict a6 = r.a[6], *__restrict b6 = r.b[6];
    const float f1 = r.f[1], f2 = r.f[2], f3 = r.f[3], f4 = r.f[4], f5 = r.f[5], f6 = r.f[6];
    float* __restrict o = out.data() + y * un;
#pragma omp simd
    for (std::size_t x = 0; x < un; ++x) {
      const float v0 = p0[x];
      const float v1 = a1[x] + f1 * (b1[x] - a1[x]), v2 = a2[x] + f2 * (b2[x] - a2[x]);
      const float v3 = a3[x] + f3 * (b3[x] - a3[x]), v4 = a4[x] + f4 * (b4[x] - a4[x]);
      const float v5 = a5[x] + f5 * (b5[x] - a5[x]), v6 = a6[x] + f6 * (b6[x] - a6[x]);
      o[x] = (std::fabs(v0 - v3) + std::fabs(v0 - v4) + std::fabs(v1 - v4) + std::fabs(v1 - v5) + std::fabs(v2 - v5) +
              std::fabs(v2 - v6)) *
             (1.0f / 6.0f);
    }
  }
}

// Eq. 3.4 for the hue vector (two pyramids, its components): |B^i - B^{i+j}| is the Euclidean
// distance between the two levels' vectors.
void centre_surround_vector(const Pyramid& pu, const Pyramid& pw, int n, Magnified& mu, Magnified& mw,
                            std::vector<float>& out) {
  const auto un = static_cast<std::size_t>(n);
  out.resize(un * un);
  mu.build(pu, n);
  mw.build(pw, n);
  for (std::size_t y = 0; y < un; ++y) {
    const Magnified::Row r = mu.row(y, un), q = mw.row(y, un);
    const float *__restrict u0 = pu[0].v.data() + y * un, *__restrict w0 = pw[0].v.data() + y * un;
    const float *__restrict ua1 = r.a[1], *__restrict ub1 = r.b[1], *__restrict ua2 = r.a[2], *__restrict ub2 = r.b[2];
    const float *__restrict ua3 = r.a[3], *__restrict ub3 = r.b[3], *__restrict ua4 = r.a[4], *__restrict ub4 = r.b[4];
    const float *__restrict ua5 = r.a[5], *__restrict ub5 = r.b[5], *__restrict ua6 = r.a[6], *__restrict ub6 = r.b[6];
    const float *__restrict wa1 = q.a[1], *__restrict wb1 = q.b[1], *__restrict wa2 = q.a[2], *__restrict wb2 = q.b[2];
    const float *__restrict wa3 = q.a[3], *__restrict wb3 = q.b[3], *__restrict wa4 = q.a[4], *__restrict wb4 = q.b[4];
    const float *__restrict wa5 = q.a[5], *__restrict wb5 = q.b[5], *__restrict wa6 = q.a[6], *__restrict wb6 = q.b[6];
    const float f1 = r.f[1], f2 = r.f[2], f3 = r.f[3], f4 = r.f[4], f5 = r.f[5], f6 = r.f[6];
    float* __restrict o = out.data() + y * un;
#pragma omp simd
    for (std::size_t x = 0; x < un; ++x) {
      const float x0 = u0[x], y0 = w0[x];
      const float x1 = ua1[x] + f1 * (ub1[x] - ua1[x]), y1 = wa1[x] + f1 * (wb1[x] - wa1[x]);
      const float x2 = ua2[x] + f2 * (ub2[x] - ua2[x]), y2 = wa2[x] + f2 * (wb2[x] - wa2[x]);
      const float x3 = ua3[x] + f3 * (ub3[x] - ua3[x]), y3 = wa3[x] + f3 * (wb3[x] - wa3[x]);
      const float x4 = ua4[x] + f4 * (ub4[x] - ua4[x]), y4 = wa4[x] + f4 * (wb4[x] - wa4[x]);
      const float x5 = ua5[x] + f5 * (ub5[x] - ua5[x]), y5 = wa5[x] + f5 * (wb5[x] - wa5[x]);
      const float x6 = ua6[x] + f6 * (ub6[x] - ua6[x]), y6 = wa6[x] + f6 * (wb6[x] - wa6[x]);
      const float d03 = std::sqrt((x0 - x3) * (x0 - x3) + (y0 - y3) * (y0 - y3));
      const float d04 = std::sqrt((x0 - x4) * (x0 - x4) + (y0 - y4) * (y0 - y4));
      const float d14 = std::sqrt((x1 - x4) * (x1 - x4) + (y1 - y4) * (y1 - y4));
      const float d15 = std::sqrt((x1 - x5) * (x1 - x5) + (y1 - y5) * (y1 - y5));
      const float d25 = std::sqrt((x2 - x5) * (x2 - x5) + (y2 - y5) * (y2 - y5));
      const float d26 = std::sqrt((x2 - x6) * (x2 - x6) + (y2 - y6) * (y2 - y6));
      o[x] = (d03 + d04 + d14 + d15 + d25 + d26) * (1.0f / 6.0f);
    }
  }
}

// (cos, sin) of the hue angle h6 * 60 deg, h6 in [0, 6): a table of 1536 steps with linear
// interpolation (error < 3e-6, far below the 8-bit colour it stands for), instead of two libm
// calls per map pixel.
glm::vec2 hue_direction(float h6) {
  constexpr int kSteps = 1536;
  static const std::vector<glm::vec2> table = [] {
    std::vector<glm::vec2> t(kSteps + 1);
    for (int i = 0; i <= kSteps; ++i) {
      const double a = 2.0 * std::numbers::pi * i / kSteps;
      t[static_cast<std::size_t>(i)] = {static_cast<float>(std::cos(a)), static_cast<float>(std::sin(a))};
    }
    return t;
  }();
  const float s = (h6 > 0 ? std::min(h6, 6.0f) : 0.0f) * (kSteps / 6.0f);  // NaN: 0 (never a NaN cast)
  const auto i = std::min(static_cast<std::size_t>(s), static_cast<std::size_t>(kSteps - 1));
  const float f = s - static_cast<float>(i);
  return table[i] + f * (table[i + 1] - table[i]);
}

float finite_or(float v, float fallback) { return std::isfinite(v) ? v : fallback; }
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

// The planar feature maps (level 0 of each pyramid): L, the hue vector's two components, and the
// DSM texture of Fig. 3.3 (depth, size, motion) as three planes.
enum Plane { kPL = 0, kPHa, kPHb, kPDepth, kPSize, kPMotion, kPlanes };

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

// The G-buffer as the resampling reads it: which planes it has, and the depth range of eq. 3.1.
struct Source {
  const GBuffer& g;
  std::size_t W, H;
  bool has_image, has_color, has_depth, has_ids;
  double z_range;    // z_far - z_near of eq. 3.1 (1 for a degenerate camera)
  float fnear, ffar;  // what depths are clamped to
};

Source read_source(const GBuffer& g, const Camera& camera) {
  // A G-buffer with missing planes is read as black, at the far plane and without objects.
  const std::size_t W = g.width, H = g.height;
  const bool has_image = W > 0 && H > 0;
  const bool has_color = has_image && g.color.size() >= W * H;
  const bool has_depth = has_image && g.depth.size() >= W * H;
  const bool has_ids = has_image && g.object_id.size() >= W * H;
  const double z_near = camera.near_m, z_far = camera.far_m;
  const double z_range = (std::isfinite(z_far - z_near) && z_far > z_near) ? z_far - z_near : 1.0;
  const float fnear = static_cast<float>(std::isfinite(z_near) ? z_near : 0.0);
  const float ffar = static_cast<float>(std::isfinite(z_far) ? z_far : static_cast<double>(fnear) + 1.0);
  return Source{g, W, H, has_image, has_color, has_depth, has_ids, z_range, fnear, ffar};
}

// Per map column (x) and row (y): the source columns / rows [c0, c1) of its box, and the one source
// column / row under its centre (n).
struct ResampleGrid {
  explicit ResampleGrid(std::size_t un) : cx0(un), cx1(un), cy0(un), cy1(un), nx(un), ny(un) {}
  std::vector<int> cx0, cx1, cy0, cy1, nx, ny;
};

// Resample the G-buffer to n x n.
// Colour and depth: box filter (the mean of the source pixels whose centres fall in the map
// pixel; when the map is finer than the image, or with Resample::Nearest, the one source pixel
// under the map pixel's centre).
// Ids and the per-object depth: nearest (the source pixel under the map pixel's centre): ids must
// not be averaged. The map is square like the paper's (64^2 .. 512^2); the image's aspect is not kept.
// HDR colour is clamped to [0, 1] per source pixel before filtering: HLS is a display-colour model
// (the paper reads an 8-bit render target), and a lamp's radiance of 8 must not dwarf the rest.
ResampleGrid resample_grid(const Source& src, int n, Resample resample) {
  const auto un = static_cast<std::size_t>(n);
  const std::size_t W = src.W, H = src.H;
  ResampleGrid grid(un);
  for (std::size_t k = 0; k < un; ++k) {
    if (!src.has_image) break;
    const auto range = [&](std::size_t size, std::vector<int>& a, std::vector<int>& b, std::vector<int>& near_i) {
      const auto s = static_cast<double>(size);
      const auto kk = static_cast<double>(k);
      int lo = static_cast<int>(std::ceil(kk * s / n - 0.5));
      int hi = static_cast<int>(std::ceil((kk + 1) * s / n - 0.5));  // centres in [k, k+1) * s / n
      const int centre = std::clamp(static_cast<int>(std::floor((kk + 0.5) * s / n)), 0, static_cast<int>(size) - 1);
      lo = std::clamp(lo, 0, static_cast<int>(size));
      hi = std::clamp(hi, 0, static_cast<int>(size));
      if (hi <= lo || resample == Resample::Nearest) {
        lo = centre;
        hi = centre + 1;
      }
      a[k] = lo;
      b[k] = hi;
      near_i[k] = centre;
    };
    range(W, grid.cx0, grid.cx1, grid.nx);
    range(H, grid.cy0, grid.cy1, grid.ny);
  }
  return grid;
}

// Box: the source rows of map row y summed per source column (straight loops over whole rows;
// comparisons written as `v > 0 ? v : 0` map NaN to the fallback without a branch).
void accumulate_box_rows(const Source& src, const ResampleGrid& grid, std::size_t y, std::vector<float>& col_rgb,
                         std::vector<float>& col_z) {
  const GBuffer& g = src.g;
  const std::size_t W = src.W;
  const bool has_color = src.has_color, has_depth = src.has_depth, has_ids = src.has_ids;
  const float fnear = src.fnear, ffar = src.ffar;
  const float depth_fallback = ffar;
  const std::vector<int>&cy0 = grid.cy0, &cy1 = grid.cy1;
  std::fill(col_rgb.begin(), col_rgb.end(), 0.0f);
  std::fill(col_z.begin(), col_z.end(), 0.0f);
  float* __restrict crgb = col_rgb.data();
  float* __restrict cz = col_z.data();
  for (int sy = cy0[y]; sy < cy1[y]; ++sy) {
    const std::size_t row = static_cast<std::size_t>(sy) * W;
    if (has_color) {
      const float* __restrict c = &g.color[row].x;
#pragma omp simd
      for (std::size_t i = 0; i < 3 * W; ++i) {
        const float v = c[i] > 0.0f ? c[i] : 0.0f;  // NaN: 0
        crgb[i] += v < 1.0f ? v : 1.0f;
      }
    }
    // Background pixels (id 0) sit at the far plane whatever the depth plane says; NaN and +Inf: far.
    if (has_depth) {
      const float* __restrict dp = g.depth.data() + row;
      if (has_ids) {
        const std::uint32_t* __restrict ip = g.object_id.data() + row;
#pragma omp simd
        for (std::size_t sx = 0; sx < W; ++sx) {
          float d = dp[sx] < ffar ? dp[sx] : ffar;
          d = d > fnear ? d : fnear;
          cz[sx] += ip[sx] != 0 ? d : depth_fallback;
        }
      } else {
#pragma omp simd
        for (std::size_t sx = 0; sx < W; ++sx) {
          const float d = dp[sx] < ffar ? dp[sx] : ffar;
          cz[sx] += d > fnear ? d : fnear;
        }
      }
    } else {
      for (std::size_t sx = 0; sx < W; ++sx) cz[sx] += depth_fallback;
    }
  }
}

// Nearest: the one source pixel under each map pixel's centre, read directly (no pass over whole
// source rows), into the same per-column layout with one column per map pixel.
void read_nearest_row(const Source& src, const ResampleGrid& grid, std::size_t un, std::size_t y,
                      std::vector<float>& col_rgb, std::vector<float>& col_z) {
  const GBuffer& g = src.g;
  const std::size_t W = src.W;
  const bool has_color = src.has_color, has_depth = src.has_depth, has_ids = src.has_ids;
  const float fnear = src.fnear, ffar = src.ffar;
  const float depth_fallback = ffar;
  const std::vector<int>&nx = grid.nx, &ny = grid.ny;
  const std::size_t row = static_cast<std::size_t>(ny[y]) * W;
  for (std::size_t x = 0; x < un; ++x) {
    const std::size_t i = row + static_cast<std::size_t>(nx[x]);
    for (glm::length_t c = 0; c < 3; ++c) {
      const float v = has_color ? g.color[i][c] : 0.0f;
      const float v0 = v > 0.0f ? v : 0.0f;  // NaN: 0
      col_rgb[3 * x + static_cast<std::size_t>(c)] = v0 < 1.0f ? v0 : 1.0f;
    }
    float d = depth_fallback;
    if (has_depth && (!has_ids || g.object_id[i] != 0)) {
      d = g.depth[i] < ffar ? g.depth[i] : ffar;
      d = d > fnear ? d : fnear;
    }
    col_z[x] = d;
  }
}

// One map pixel's lightness and hue vector.
struct Hls {
  float l, hue_a, hue_b;
};

// HLS (Lee 2009 §3.1.1): L = (max + min) / 2, S = chroma / (1 - |2L - 1|), H the hexcone angle.
// Hue is an angle, so |B_h^i - B_h^{i+j}| of eq. 3.4 is taken between hue vectors
// (S cos H, S sin H): the chord between two hues on the colour wheel, scaled by saturation.
// Grey pixels have S = 0, the zero vector: no hue, no NaN, and no contrast against any grey.
Hls hls(float r, float gg, float b) {
  const float mx = std::max({r, gg, b}), mn = std::min({r, gg, b});
  const float l = 0.5f * (mx + mn), chroma = mx - mn;
  float ha = 0, hb = 0;
  if (chroma > 1e-6f) {
    const float sat = std::clamp(chroma / std::max(1e-6f, 1.0f - std::fabs(2.0f * l - 1.0f)), 0.0f, 1.0f);
    float h6 = 0;  // hue in sixths of a turn
    if (mx == r) {
      h6 = (gg - b) / chroma;  // in [-1, 1]
      if (h6 < 0) h6 += 6.0f;
    } else if (mx == gg) {
      h6 = (b - r) / chroma + 2.0f;
    } else {
      h6 = (r - gg) / chroma + 4.0f;
    }
    const glm::vec2 dir = hue_direction(h6);
    ha = sat * dir.x;
    hb = sat * dir.y;
  }
  return Hls{l, ha, hb};
}

// Where the resampling writes: level 0 of the L, hue and depth planes, the map's ids (nearest) and
// the per-pixel depth the per-object median is taken of (nearest).
struct ResampleTarget {
  float* lum0;
  float* hue_a0;
  float* hue_b0;
  float* depth0;
  std::vector<std::uint32_t>& ids;
  std::vector<float>& map_depth;
};

// Map rows [y_begin, y_end): per map row the source columns (box or nearest), then the columns of
// each map pixel's box summed, then HLS and eq. 3.1. `col_rgb` and `col_z` are this range's own
// scratch rows.
void resample_rows(const Source& src, const ResampleGrid& grid, std::size_t un, bool nearest, const ResampleTarget& out,
                   std::size_t y_begin, std::size_t y_end) {
  const GBuffer& g = src.g;
  const std::size_t W = src.W;
  const bool has_image = src.has_image, has_depth = src.has_depth, has_ids = src.has_ids;
  const float fnear = src.fnear, ffar = src.ffar;
  const float fz_near = fnear, fz_inv_range = static_cast<float>(1.0 / src.z_range);
  const std::vector<int>&cx0 = grid.cx0, &cx1 = grid.cx1, &cy0 = grid.cy0, &cy1 = grid.cy1;
  const std::vector<int>&nx = grid.nx, &ny = grid.ny;
  float* __restrict lum0 = out.lum0;
  float* __restrict hue_a0 = out.hue_a0;
  float* __restrict hue_b0 = out.hue_b0;
  float* __restrict depth0 = out.depth0;
  std::vector<std::uint32_t>& ids = out.ids;
  std::vector<float>& map_depth = out.map_depth;
  std::vector<float> col_rgb(nearest ? un * 3 : W * 3), col_z(nearest ? un : W);
  for (std::size_t y = y_begin; y < y_end && has_image; ++y) {
    if (nearest) {
      read_nearest_row(src, grid, un, y, col_rgb, col_z);
    } else {
      accumulate_box_rows(src, grid, y, col_rgb, col_z);
    }
    const float* __restrict crgb = col_rgb.data();
    const float* __restrict cz = col_z.data();
    const int rows_in = nearest ? 1 : cy1[y] - cy0[y];
    for (std::size_t x = 0; x < un; ++x) {
      float r = 0, gg = 0, b = 0, z = 0;
      const int c0 = nearest ? static_cast<int>(x) : cx0[x], c1 = nearest ? c0 + 1 : cx1[x];
      for (int sx = c0; sx < c1; ++sx) {
        const auto k = static_cast<std::size_t>(sx);
        r += crgb[3 * k];
        gg += crgb[3 * k + 1];
        b += crgb[3 * k + 2];
        z += cz[k];
      }
      const std::size_t m = y * un + x;
      const int count = rows_in * (c1 - c0);
      const float inv = count > 0 ? 1.0f / static_cast<float>(count) : 0.0f;
      r *= inv;
      gg *= inv;
      b *= inv;
      z = count > 0 ? z * inv : ffar;
      const Hls c = hls(r, gg, b);
      lum0[m] = c.l;
      hue_a0[m] = c.hue_a;
      hue_b0[m] = c.hue_b;
      depth0[m] = std::clamp((z - fz_near) * fz_inv_range, 0.0f, 1.0f);  // eq. 3.1
      const std::size_t ni = static_cast<std::size_t>(ny[y]) * W + static_cast<std::size_t>(nx[x]);
      if (has_ids) ids[m] = g.object_id[ni];
      if (has_depth && ids[m] != 0) map_depth[m] = std::clamp(finite_or(g.depth[ni], ffar), fnear, ffar);
    }
  }
}

// The resampled G-buffer: level 0 of the planes, the map's ids and per-pixel depth. Map rows are
// independent: split over the cores (TBB), each range with its own scratch rows.
void resample_gbuffer(const Source& src, const ResampleGrid& grid, int n, Resample resample, Pyramid (&planes)[kPlanes],
                      std::vector<std::uint32_t>& ids, std::vector<float>& map_depth) {
  const auto un = static_cast<std::size_t>(n), npix = un * un;
  for (Pyramid& p : planes) {
    p[0].w = p[0].h = n;
    p[0].v.assign(npix, 0.0f);
  }
  const ResampleTarget out{planes[kPL][0].v.data(), planes[kPHa][0].v.data(), planes[kPHb][0].v.data(),
                           planes[kPDepth][0].v.data(), ids, map_depth};
  ids.assign(npix, 0);
  map_depth.assign(npix, src.ffar);  // nearest: per-object median depth
  static_assert(sizeof(glm::vec3) == 3 * sizeof(float), "the colour plane is read as packed floats");
  const bool nearest = resample == Resample::Nearest;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, un, 8), [&](const tbb::blocked_range<std::size_t>& r) {
    resample_rows(src, grid, un, nearest, out, r.begin(), r.end());
  });
}

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
