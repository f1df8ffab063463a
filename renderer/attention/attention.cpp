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

// One level of a feature pyramid (one or two channels interleaved).
struct Level {
  int w = 0, h = 0;
  std::vector<float> v;  // w * h * channels
};

// 2x2 box downsampling (what glGenerateMipmap does for power-of-two sizes). For an odd size the level
// below is ceil(n / 2) and the missing texel of the last 2x2 block repeats the edge texel.
void downsample(const Level& src, Level& dst, int ch) {
  dst.w = std::max(1, (src.w + 1) / 2);
  dst.h = std::max(1, (src.h + 1) / 2);
  dst.v.assign(static_cast<std::size_t>(dst.w) * static_cast<std::size_t>(dst.h) * static_cast<std::size_t>(ch), 0.0f);
  for (int y = 0; y < dst.h; ++y) {
    const int y0 = std::min(2 * y, src.h - 1), y1 = std::min(2 * y + 1, src.h - 1);
    for (int x = 0; x < dst.w; ++x) {
      const int x0 = std::min(2 * x, src.w - 1), x1 = std::min(2 * x + 1, src.w - 1);
      for (int c = 0; c < ch; ++c) {
        const auto at = [&](int xx, int yy) {
          return src.v[(static_cast<std::size_t>(yy) * static_cast<std::size_t>(src.w) + static_cast<std::size_t>(xx)) *
                           static_cast<std::size_t>(ch) +
                       static_cast<std::size_t>(c)];
        };
        dst.v[(static_cast<std::size_t>(y) * static_cast<std::size_t>(dst.w) + static_cast<std::size_t>(x)) *
                  static_cast<std::size_t>(ch) +
              static_cast<std::size_t>(c)] = 0.25f * (at(x0, y0) + at(x1, y0) + at(x0, y1) + at(x1, y1));
      }
    }
  }
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

// Eq. 3.4 for one feature (ch = 1, or 2 for the hue vector, whose difference is the Euclidean
// distance of the two vectors): C = 1/6 sum_{i in 0..2} sum_{j in 3,4} |B^i - B^{i+j}|, every level
// sampled at the level-0 pixel (Fig. 3.3's shader: texture2D(DSM, tc0, i)), coarse levels by
// bilinear magnification. Works row by row: the levels are first magnified horizontally (h_L x n
// each), then each output row is a vertical lerp of two of those rows.
void centre_surround(const Level (&pyr)[kLevels], int ch, int n, std::vector<float>& out) {
  const auto un = static_cast<std::size_t>(n), uch = static_cast<std::size_t>(ch);
  out.assign(un * un, 0.0f);
  std::vector<float> horizontal[kLevels];
  Axis vertical[kLevels];
  for (int l = 1; l < kLevels; ++l) {
    const Level& lv = pyr[l];
    const Axis ax = axis(n, lv.w);
    vertical[l] = axis(n, lv.h);
    auto& hz = horizontal[l];
    hz.resize(static_cast<std::size_t>(lv.h) * un * uch);
    for (int y = 0; y < lv.h; ++y) {
      const float* row = lv.v.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(lv.w) * uch;
      float* o = hz.data() + static_cast<std::size_t>(y) * un * uch;
      for (std::size_t x = 0; x < un; ++x) {
        const auto a = static_cast<std::size_t>(ax.i0[x]) * uch, b = static_cast<std::size_t>(ax.i1[x]) * uch;
        for (std::size_t c = 0; c < uch; ++c) o[x * uch + c] = row[a + c] + ax.f[x] * (row[b + c] - row[a + c]);
      }
    }
  }
  std::vector<float> rows(static_cast<std::size_t>(kLevels) * un * uch);
  for (std::size_t y = 0; y < un; ++y) {
    const float* r[kLevels];
    r[0] = pyr[0].v.data() + y * un * uch;
    for (int l = 1; l < kLevels; ++l) {
      const Axis& ay = vertical[l];
      const float* a = horizontal[l].data() + static_cast<std::size_t>(ay.i0[y]) * un * uch;
      const float* b = horizontal[l].data() + static_cast<std::size_t>(ay.i1[y]) * un * uch;
      const float f = ay.f[y];
      float* o = rows.data() + static_cast<std::size_t>(l) * un * uch;
      for (std::size_t k = 0; k < un * uch; ++k) o[k] = a[k] + f * (b[k] - a[k]);
      r[l] = o;
    }
    float* c_out = out.data() + y * un;
    if (ch == 1) {
      for (std::size_t x = 0; x < un; ++x) {
        c_out[x] = (std::fabs(r[0][x] - r[3][x]) + std::fabs(r[0][x] - r[4][x]) + std::fabs(r[1][x] - r[4][x]) +
                    std::fabs(r[1][x] - r[5][x]) + std::fabs(r[2][x] - r[5][x]) + std::fabs(r[2][x] - r[6][x])) /
                   6.0f;
      }
    } else {
      const auto d = [&](int i, int j, std::size_t x) {
        const float da = r[i][2 * x] - r[j][2 * x], db = r[i][2 * x + 1] - r[j][2 * x + 1];
        return std::sqrt(da * da + db * db);
      };
      for (std::size_t x = 0; x < un; ++x) {
        c_out[x] = (d(0, 3, x) + d(0, 4, x) + d(1, 4, x) + d(1, 5, x) + d(2, 5, x) + d(2, 6, x)) / 6.0f;
      }
    }
  }
}

void build_pyramid(Level (&pyr)[kLevels], int ch) {
  for (int l = 1; l < kLevels; ++l) downsample(pyr[l - 1], pyr[l], ch);
}

// (cos, sin) of the hue angle h6 * 60 deg, h6 in [0, 6): a table of 1536 steps with linear
// interpolation (error < 3e-6, far below the 8-bit colour it stands for), instead of two libm
// calls per map pixel.
glm::dvec2 hue_direction(double h6) {
  constexpr int kSteps = 1536;
  static const std::vector<glm::dvec2> table = [] {
    std::vector<glm::dvec2> t(kSteps + 1);
    for (int i = 0; i <= kSteps; ++i) {
      const double a = 2.0 * std::numbers::pi * i / kSteps;
      t[static_cast<std::size_t>(i)] = {std::cos(a), std::sin(a)};
    }
    return t;
  }();
  const double s = (h6 > 0 ? std::min(h6, 6.0) : 0.0) * (kSteps / 6.0);  // NaN: 0 (never a NaN cast)
  const auto i = std::min(static_cast<std::size_t>(s), static_cast<std::size_t>(kSteps - 1));
  const double f = s - static_cast<double>(i);
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

}  // namespace

AttentionTracker::AttentionTracker(AttentionSettings settings) : settings_(settings) { settings_.check(); }

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

const AttentionFrame& AttentionTracker::update(const GBuffer& g, const Scene& scene, double time_s,
                                               double previous_time_s) {
  const auto start = std::chrono::steady_clock::now();
  const int n = settings_.map_size;
  const auto un = static_cast<std::size_t>(n), npix = un * un;
  AttentionFrame& f = frame_;
  f.map_width = f.map_height = n;
  f.objects.clear();
  f.most_attended = 0;

  // --- Scene objects by id (dense slots for the visible ones) -------------------------------------
  std::unordered_map<std::uint32_t, std::size_t> object_index;
  object_index.reserve(scene.objects.size() * 2);
  for (std::size_t i = 0; i < scene.objects.size(); ++i) object_index.emplace(scene.objects[i].id, i);
  std::vector<Slot> slots;
  std::unordered_map<std::uint32_t, std::uint32_t> slot_of;  // id -> slot + 1 (0: not an object of the scene)
  std::uint32_t last_id = 0, last_slot = 0;
  const auto slot_for = [&](std::uint32_t id) -> std::uint32_t {
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
  };

  // A G-buffer with missing planes is read as black, at the far plane and without objects.
  const std::size_t W = g.width, H = g.height;
  const bool has_image = W > 0 && H > 0;
  const bool has_color = has_image && g.color.size() >= W * H;
  const bool has_depth = has_image && g.depth.size() >= W * H;
  const bool has_ids = has_image && g.object_id.size() >= W * H;

  // --- Resample the G-buffer to n x n ----------------------------------------------------------
  // Colour and depth: box filter (the mean of the source pixels whose centres fall in the map
  // pixel; when the map is finer than the image, the one source pixel under the map pixel's centre).
  // Ids and the per-object depth: nearest (the source pixel under the map pixel's centre): ids must
  // not be averaged. The map is square like the paper's (64^2 .. 512^2); the image's aspect is not kept.
  // HDR colour is clamped to [0, 1] per source pixel before filtering: HLS is a display-colour model
  // (the paper reads an 8-bit render target), and a lamp's radiance of 8 must not dwarf the rest.
  const double z_near = scene.camera.near_m, z_far = scene.camera.far_m;
  const double z_range = (std::isfinite(z_far - z_near) && z_far > z_near) ? z_far - z_near : 1.0;
  const float fnear = static_cast<float>(std::isfinite(z_near) ? z_near : 0.0);
  const float ffar = static_cast<float>(std::isfinite(z_far) ? z_far : static_cast<double>(fnear) + 1.0);
  std::vector<int> cx0(un), cx1(un), cy0(un), cy1(un), nx(un), ny(un);
  for (std::size_t k = 0; k < un; ++k) {
    if (!has_image) break;
    const auto range = [&](std::size_t size, std::vector<int>& a, std::vector<int>& b, std::vector<int>& near_i) {
      const auto s = static_cast<double>(size);
      const auto kk = static_cast<double>(k);
      int lo = static_cast<int>(std::ceil(kk * s / n - 0.5));
      int hi = static_cast<int>(std::ceil((kk + 1) * s / n - 0.5));  // centres in [k, k+1) * s / n
      const int centre = std::clamp(static_cast<int>(std::floor((kk + 0.5) * s / n)), 0, static_cast<int>(size) - 1);
      lo = std::clamp(lo, 0, static_cast<int>(size));
      hi = std::clamp(hi, 0, static_cast<int>(size));
      if (hi <= lo) {
        lo = centre;
        hi = centre + 1;
      }
      a[k] = lo;
      b[k] = hi;
      near_i[k] = centre;
    };
    range(W, cx0, cx1, nx);
    range(H, cy0, cy1, ny);
  }

  Level lum[kLevels], hue[kLevels], dsm[kLevels];  // DSM interleaves depth, size, motion (Fig. 3.3)
  for (Level* p : {&lum[0], &hue[0], &dsm[0]}) {
    p->w = p->h = n;
  }
  lum[0].v.assign(npix, 0.0f);
  hue[0].v.assign(npix * 2, 0.0f);
  dsm[0].v.assign(npix * 3, 0.0f);
  f.ids.assign(npix, 0);
  std::vector<float> map_depth(npix, ffar);  // nearest: per-object median depth

  // Per map row: accumulate the source rows of its box column by column (r, g, b, z per map pixel),
  // then convert. Comparisons written as `v > 0 ? v : 0` map NaN to the fallback without a branch.
  // Map rows are independent: split over the cores (TBB), each range with its own scratch rows.
  const float depth_fallback = ffar;
  // Per map row: first the box's source rows summed per source column (straight loops over whole
  // rows), then the columns of each map pixel's box summed.
  const auto resample_rows = [&](std::size_t y_begin, std::size_t y_end) {
  std::vector<float> col(W * 4), acc(un * 4);
  for (std::size_t y = y_begin; y < y_end && has_image; ++y) {
    std::fill(col.begin(), col.end(), 0.0f);
    for (int sy = cy0[y]; sy < cy1[y]; ++sy) {
      const std::size_t row = static_cast<std::size_t>(sy) * W;
      if (has_color) {
        const glm::vec3* c = g.color.data() + row;
        for (std::size_t sx = 0; sx < W; ++sx) {
          const float cr = c[sx].x > 0.0f ? c[sx].x : 0.0f, cg = c[sx].y > 0.0f ? c[sx].y : 0.0f,
                      cb = c[sx].z > 0.0f ? c[sx].z : 0.0f;  // NaN: 0
          col[4 * sx] += cr < 1.0f ? cr : 1.0f;
          col[4 * sx + 1] += cg < 1.0f ? cg : 1.0f;
          col[4 * sx + 2] += cb < 1.0f ? cb : 1.0f;
        }
      }
      // Background pixels (id 0) sit at the far plane whatever the depth plane says; NaN and +Inf: far.
      if (has_depth) {
        const float* dp = g.depth.data() + row;
        const std::uint32_t* ip = has_ids ? g.object_id.data() + row : nullptr;
        for (std::size_t sx = 0; sx < W; ++sx) {
          float d = dp[sx] < ffar ? dp[sx] : ffar;
          d = d > fnear ? d : fnear;
          col[4 * sx + 3] += (ip == nullptr || ip[sx] != 0) ? d : depth_fallback;
        }
      } else {
        for (std::size_t sx = 0; sx < W; ++sx) col[4 * sx + 3] += depth_fallback;
      }
    }
    for (std::size_t x = 0; x < un; ++x) {
      float r = 0, gg = 0, b = 0, z = 0;
      for (int sx = cx0[x]; sx < cx1[x]; ++sx) {
        const float* c = col.data() + 4 * static_cast<std::size_t>(sx);
        r += c[0];
        gg += c[1];
        b += c[2];
        z += c[3];
      }
      acc[4 * x] = r;
      acc[4 * x + 1] = gg;
      acc[4 * x + 2] = b;
      acc[4 * x + 3] = z;
    }
    const int rows_in = cy1[y] - cy0[y];
    for (std::size_t x = 0; x < un; ++x) {
      const std::size_t m = y * un + x;
      const int count = rows_in * (cx1[x] - cx0[x]);
      const double inv = count > 0 ? 1.0 / static_cast<double>(count) : 0.0;
      const glm::dvec3 rgb = glm::dvec3(acc[4 * x], acc[4 * x + 1], acc[4 * x + 2]) * inv;
      const double z = count > 0 ? static_cast<double>(acc[4 * x + 3]) * inv : static_cast<double>(ffar);
      // HLS (Lee 2009 §3.1.1): L = (max + min) / 2, S = chroma / (1 - |2L - 1|), H the hexcone angle.
      // Hue is an angle, so |B_h^i - B_h^{i+j}| of eq. 3.4 is taken between hue vectors
      // (S cos H, S sin H): the chord between two hues on the colour wheel, scaled by saturation.
      // Grey pixels have S = 0, the zero vector: no hue, no NaN, and no contrast against any grey.
      const double mx = std::max({rgb.r, rgb.g, rgb.b}), mn = std::min({rgb.r, rgb.g, rgb.b});
      const double l = 0.5 * (mx + mn), chroma = mx - mn;
      double ha = 0, hb = 0;
      if (chroma > 1e-9) {
        const double sat = std::clamp(chroma / std::max(1e-9, 1.0 - std::fabs(2.0 * l - 1.0)), 0.0, 1.0);
        double h6 = 0;  // hue in sixths of a turn
        if (mx == rgb.r) {
          h6 = (rgb.g - rgb.b) / chroma;  // in [-1, 1]
          if (h6 < 0) h6 += 6.0;
        } else if (mx == rgb.g) {
          h6 = (rgb.b - rgb.r) / chroma + 2.0;
        } else {
          h6 = (rgb.r - rgb.g) / chroma + 4.0;
        }
        const glm::dvec2 dir = hue_direction(h6);
        ha = sat * dir.x;
        hb = sat * dir.y;
      }
      lum[0].v[m] = static_cast<float>(l);
      hue[0].v[2 * m] = static_cast<float>(ha);
      hue[0].v[2 * m + 1] = static_cast<float>(hb);
      dsm[0].v[3 * m] = static_cast<float>(std::clamp((z - z_near) / z_range, 0.0, 1.0));  // eq. 3.1
      const std::size_t ni = static_cast<std::size_t>(ny[y]) * W + static_cast<std::size_t>(nx[x]);
      if (has_ids) f.ids[m] = g.object_id[ni];
      if (has_depth && f.ids[m] != 0) map_depth[m] = std::clamp(finite_or(g.depth[ni], ffar), fnear, ffar);
    }
  }
  };
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, un, 8),
                    [&](const tbb::blocked_range<std::size_t>& r) { resample_rows(r.begin(), r.end()); });

  // --- Object features: B_s (eq. 3.2) and B_m (eq. 3.3) -------------------------------------------
  // B_s counts the pixels of the item buffer as resampled to the map (nearest), over the map's
  // pixels: the map is the image the paper's GPU pass works on, and it spares a second pass over the
  // full-resolution buffer (an object smaller than a map pixel may get 0; it has no pixels in S_p
  // either, so eq. 3.7 cannot list it anyway).
  std::vector<std::uint32_t> map_slot(npix, 0);
  for (std::size_t m = 0; m < npix; ++m) {
    map_slot[m] = slot_for(f.ids[m]);
    if (map_slot[m] != 0) ++slots[map_slot[m] - 1].full_pixels;
  }
  for (Slot& s : slots) {
    s.size = static_cast<float>(static_cast<double>(s.full_pixels) / static_cast<double>(npix));
    // B_m: the displacement over the frame of the vertex farthest from the object's centre, so that
    // self-rotation counts as well as translation. An animation yielding a non-finite transform
    // makes the object's motion 0 (it cannot be measured; it must not poison the maps).
    const glm::vec3 p = farthest_vertex(s.object->mesh);
    const glm::mat4 now = s.object->transform_at(time_s).matrix();
    const glm::mat4 before = s.object->transform_at(previous_time_s).matrix();
    const glm::vec3 a = glm::vec3(now * glm::vec4(p, 1.0f)), b = glm::vec3(before * glm::vec4(p, 1.0f));
    const float d = glm::length(a - b);
    s.motion = (finite(a) && finite(b) && std::isfinite(d)) ? d : 0.0f;
  }
  for (std::size_t m = 0; m < npix; ++m) {
    if (map_slot[m] != 0) {
      dsm[0].v[3 * m + 1] = slots[map_slot[m] - 1].size;
      dsm[0].v[3 * m + 2] = slots[map_slot[m] - 1].motion;
    }
  }

  // --- Pyramids, centre-surround (eq. 3.4), weights (eq. 3.6), S_p (eq. 3.5) ----------------------
  const bool image_group = settings_.groups.image, object_group = settings_.groups.object;
  for (auto& c : f.contrast) c.assign(npix, 0.0f);
  // The five contrast maps are independent: computed as parallel tasks (TBB).
  if (object_group) build_pyramid(dsm, 3);
  const auto dsm_channel = [&](int c) {
    // Split the interleaved DSM pyramid into a one-channel pyramid for eq. 3.4.
    Level one[kLevels];
    for (int l = 0; l < kLevels; ++l) {
      one[l].w = dsm[l].w;
      one[l].h = dsm[l].h;
      const std::size_t sz = static_cast<std::size_t>(dsm[l].w) * static_cast<std::size_t>(dsm[l].h);
      one[l].v.resize(sz);
      for (std::size_t i = 0; i < sz; ++i) one[l].v[i] = dsm[l].v[3 * i + static_cast<std::size_t>(c)];
    }
    centre_surround(one, 1, n, f.contrast[kDepth + c]);
  };
  tbb::parallel_invoke(
      [&] {
        if (!image_group) return;
        build_pyramid(hue, 2);
        centre_surround(hue, 2, n, f.contrast[kHue]);
      },
      [&] {
        if (!image_group) return;
        build_pyramid(lum, 1);
        centre_surround(lum, 1, n, f.contrast[kLum]);
      },
      [&] {
        if (object_group) dsm_channel(0);
      },
      [&] {
        if (object_group) dsm_channel(1);
      },
      [&] {
        if (object_group) dsm_channel(2);
      });
  f.saliency.assign(npix, 0.0f);
  if (image_group || object_group) {
    std::vector<double> sbar(npix, 0.0);
    for (auto& c : f.contrast) {
      float mx = 0;
      for (float& v : c) {
        if (!std::isfinite(v)) v = 0;  // cannot happen with finite inputs; kept as a guard
        mx = std::max(mx, v);
      }
      if (mx <= 0) continue;  // eq. 3.6: a map without contrast contributes nothing (not 1/0)
      const double w = 1.0 / static_cast<double>(mx);
      for (std::size_t i = 0; i < npix; ++i) sbar[i] += w * static_cast<double>(c[i]);
    }
    // Normalise to [0, 1] by min and max; a map whose pixels are all equal has no salient pixel: 0.
    const auto [lo, hi] = std::minmax_element(sbar.begin(), sbar.end());
    const double span = *hi - *lo;
    if (span > 1e-12 * std::max(1.0, *hi)) {
      for (std::size_t i = 0; i < npix; ++i) f.saliency[i] = static_cast<float>(std::clamp((sbar[i] - *lo) / span, 0.0, 1.0));
    }
  } else {
    // Neither B nor E: there is no bottom-up map, every pixel counts alike (S_p = 1) so that
    // S^_o = T_i and the top-down contexts alone decide (the "T only" row of Lee's Table 3.2).
    std::fill(f.saliency.begin(), f.saliency.end(), 1.0f);
  }

  f.saliency_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  // --- Object level: eq. 3.7 ----------------------------------------------------------------------
  for (std::size_t y = 0; y < un; ++y) {
    for (std::size_t x = 0; x < un; ++x) {
      const std::size_t m = y * un + x;
      if (map_slot[m] == 0) continue;
      Slot& s = slots[map_slot[m] - 1];
      ++s.n;
      s.sum_saliency += static_cast<double>(f.saliency[m]);
      s.sum_x += (static_cast<double>(x) + 0.5) / n;
      s.sum_y += (static_cast<double>(y) + 0.5) / n;
      s.depths.push_back(map_depth[m]);
    }
  }

  // --- Top-down contexts: eqs. 3.8-3.10 -----------------------------------------------------------
  // Observer: position now and at the previous frame, viewing direction v, moving direction w.
  // A camera animation that yields non-finite positions counts as an observer that does not move.
  glm::dvec3 eye_now = glm::dvec3(scene.camera.position_at(time_s));
  glm::dvec3 eye_before = glm::dvec3(scene.camera.position_at(previous_time_s));
  if (!std::isfinite(eye_now.x + eye_now.y + eye_now.z)) eye_now = glm::dvec3(scene.camera.position);
  if (!std::isfinite(eye_before.x + eye_before.y + eye_before.z)) eye_before = eye_now;
  const glm::dvec3 view = glm::dvec3(scene.camera.target) - glm::dvec3(scene.camera.position);  // v (animation moves both)
  const glm::dvec3 moving = eye_now - eye_before;                                                 // w
  const bool moving_forward = glm::dot(view, moving) > 0;
  // Eq. 3.9's distance term (x/c_x) e^{-(x/c_x)^2} peaks at x/c_x = 1/sqrt(2); the paper's
  // c_x = L / 0.707 is L / (1/sqrt 2) rounded, and we use c_x = sqrt(2) L so the peak is exactly at L.
  // c_s scales the peak of the product (screen term <= 1) to 0.5: c_s = 0.5 / (e^{-1/2} / sqrt 2), so
  // T_s lies in [0, 0.5] and reaches 0.5 for an object at distance L in the screen centre.
  const double c_x = std::numbers::sqrt2 * settings_.preferred_distance_m;
  const double c_s = 0.5 / (std::exp(-0.5) / std::numbers::sqrt2);
  const auto lambda = static_cast<std::size_t>(settings_.temporal_window);
  // Kalman time step: |time_s - previous_time_s| (time going backwards is a step of the same
  // length), at most 1 s (a longer gap would extrapolate the rate too far; the filter re-converges
  // within a frame after a long gap anyway, its covariance having grown).
  double dt = std::fabs(time_s - previous_time_s);
  if (!std::isfinite(dt)) dt = 0;
  dt = std::min(dt, 1.0);

  std::map<std::uint32_t, double> spatial_now;  // T_s of this frame, per listed object
  for (Slot& s : slots) {
    const Object& o = *s.object;
    if (!(o.task_importance > 0) || s.n == 0) continue;  // background objects and invisible ones
    ObjectAttention a;
    a.id = o.id;
    a.pixels = s.n;
    a.size = s.size;
    a.motion = s.motion;
    a.saliency = static_cast<double>(o.task_importance) * s.sum_saliency / static_cast<double>(s.n);  // eq. 3.7
    a.screen_x = s.sum_x / static_cast<double>(s.n);
    a.screen_y = s.sum_y / static_cast<double>(s.n);
    auto mid = s.depths.begin() + static_cast<std::ptrdiff_t>(s.depths.size() / 2);
    std::nth_element(s.depths.begin(), mid, s.depths.end());
    a.depth_m = *mid;
    // x and dx of eq. 3.9: observer to object centre (the transform's translation) now and at the
    // previous frame. A non-finite object position makes x = 0 and dx = 0 (T_s = 0 then: no
    // distance emphasis for an object we cannot place).
    const glm::dvec3 centre_now = glm::dvec3(o.transform_at(time_s).translation);
    const glm::dvec3 centre_before = glm::dvec3(o.transform_at(previous_time_s).translation);
    double x_now = glm::length(centre_now - eye_now), x_before = glm::length(centre_before - eye_before);
    if (!std::isfinite(x_now)) x_now = 0;
    if (!std::isfinite(x_before)) x_before = x_now;
    a.distance_m = x_now;
    const double dx = x_now - x_before;
    const double sy = std::hypot(a.screen_x - 0.5, a.screen_y - 0.5) / std::sqrt(0.5);  // corner = 1
    if (moving_forward && dx > 0) {
      a.spatial = 0;  // moving forward and the object moves away: not attended (eq. 3.9, first case)
    } else {
      const double r = x_now / c_x;
      a.spatial = c_s * r * std::exp(-r * r) * std::exp(-settings_.c_y * sy * sy);
    }
    if (!std::isfinite(a.spatial)) a.spatial = 0;
    spatial_now[o.id] = a.spatial;
    f.objects.push_back(a);
  }

  // Eq. 3.10: T_t = (1/lambda) sum of the last lambda T_s. A frame in which an object was not listed
  // (not visible, or no pixels in the map) contributes T_s = 0, and so does every frame before the
  // object was first seen: T_t rises over lambda frames. A track whose last lambda T_s are all 0 is
  // dropped (bounded memory with many objects coming and going).
  for (auto& [id, track] : tracks_) {
    if (spatial_now.count(id) == 0) {
      track.spatial[track.next] = 0;
      track.next = (track.next + 1) % track.spatial.size();
      ++track.zeros;
      track.filtered = false;  // out of view this frame: the filter restarts when it comes back
    }
  }
  std::erase_if(tracks_, [&](const auto& t) { return t.second.zeros >= lambda && spatial_now.count(t.first) == 0; });
  const double q = settings_.kalman_process_noise, rn = settings_.kalman_measurement_noise;
  for (ObjectAttention& a : f.objects) {
    Track& t = tracks_[a.id];
    if (t.spatial.size() != lambda) {
      t.spatial.assign(lambda, 0.0);
      t.next = 0;
    }
    t.spatial[t.next] = a.spatial;
    t.next = (t.next + 1) % lambda;
    t.zeros = a.spatial > 0 ? 0 : t.zeros + 1;
    double sum = 0;
    for (double v : t.spatial) sum += v;
    a.temporal = sum / static_cast<double>(lambda);
    // Eq. 3.8; without the context group, S_o = S^_o.
    a.attention_raw = settings_.groups.context ? (a.spatial + a.temporal) * a.saliency : a.saliency;
    if (!std::isfinite(a.attention_raw)) a.attention_raw = 0;

    // Discrete Kalman filter (Lee §3.3, stage 4), constant-velocity model: state (attention, rate),
    // F = [1 dt; 0 1], white-noise acceleration of spectral density q:
    // Q = q [dt^3/3 dt^2/2; dt^2/2 dt]; measurement H = [1 0] with variance r. An object seen for the
    // first time (or again after a frame out of view) starts at its measurement.
    if (!settings_.kalman) {
      a.attention = a.attention_raw;
      continue;
    }
    const double z = a.attention_raw;
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
    a.attention = std::max(0.0, t.x);  // the state keeps its sign; what we report is >= 0
  }

  std::sort(f.objects.begin(), f.objects.end(), [](const ObjectAttention& a, const ObjectAttention& b) {
    return a.attention != b.attention ? a.attention > b.attention : a.id < b.id;
  });
  if (!f.objects.empty()) f.most_attended = f.objects.front().id;
  f.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return f;
}

}  // namespace fovea::render::attention
