// SPDX-License-Identifier: Apache-2.0
#include "gi/csf_mask.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <unordered_map>
#include <unordered_set>

namespace fovea::render::gi {

namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;
// Directions sampled around a ring when taking the smallest spacing over directions.
constexpr int kRingDirections = 32;
// Gaze further than this many image sizes off the screen is pulled in (see the header).
constexpr double kMaxGazeOffsetImages = 16.0;


std::string field_error(const char* field, double value, const char* allowed) {
  return std::string("CsfSettings.") + field + " = " + std::to_string(value) + " (allowed " + allowed + ")";
}

void throw_if_invalid(const protocol::DisplayGeometry& display, const CsfSettings& settings) {
  if (auto err = protocol::validate(display); !err.empty()) throw std::invalid_argument("display geometry: " + err);
  if (auto err = validate(settings); !err.empty()) throw std::invalid_argument(err);
}

glm::dvec2 resolve_gaze(glm::dvec2 gaze, double width, double height) {
  if (!std::isfinite(gaze.x) || !std::isfinite(gaze.y)) return {width / 2, height / 2};
  const double margin_x = kMaxGazeOffsetImages * std::max(width, 1.0);
  const double margin_y = kMaxGazeOffsetImages * std::max(height, 1.0);
  return {std::clamp(gaze.x, -margin_x, width + margin_x), std::clamp(gaze.y, -margin_y, height + margin_y)};
}

double cross(glm::dvec2 a, glm::dvec2 b) { return a.x * b.y - a.y * b.x; }

// Merges vertices that land on the same pixel: a pixel's ray is cast once. Vertices only collide
// where the spacing is near one pixel; a dense grid covers the screen plus `margin` pixels around it
// (every quad that reaches the screen has its corners in there); vertices further out are kept
// as they come (their quads are culled).
class VertexSet {
 public:
  VertexSet(std::vector<glm::vec2>& out, std::uint32_t width, std::uint32_t height, std::int64_t margin)
      : out_(out),
        margin_(margin),
        grid_width_(std::int64_t{width} + 2 * margin),
        grid_height_(std::int64_t{height} + 2 * margin),
        grid_(static_cast<std::size_t>(grid_width_ * grid_height_), kNone) {}
  std::uint32_t at_pixel_of(glm::dvec2 p) {
    const double fx = std::floor(p.x), fy = std::floor(p.y);
    const std::int64_t gx = static_cast<std::int64_t>(fx) + margin_, gy = static_cast<std::int64_t>(fy) + margin_;
    const auto index = static_cast<std::uint32_t>(out_.size());
    if (gx >= 0 && gy >= 0 && gx < grid_width_ && gy < grid_height_) {
      std::uint32_t& cell = grid_[static_cast<std::size_t>(gy * grid_width_ + gx)];
      if (cell != kNone) return cell;
      cell = index;
    }
    out_.emplace_back(static_cast<float>(fx + 0.5), static_cast<float>(fy + 0.5));
    return index;
  }

 private:
  static constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
  std::vector<glm::vec2>& out_;
  std::int64_t margin_, grid_width_, grid_height_;
  std::vector<std::uint32_t> grid_;
};

// One ring's vertices in order of angle; `closed` rings wrap from the last vertex to the first.
struct RingVertices {
  std::vector<std::uint32_t> index;
  std::vector<double> angle;
  double step = 0;
  bool closed = true;
};

// Joins two rings with a zipper over angle: a quad (a_i, a_i+1, b_j+1, b_j) where the rings' next
// vertices line up (within half the finer step), otherwise a triangle that advances the ring whose
// next vertex comes first, stored as a quad with a repeated index.
void zip_rings(const RingVertices& inner, const RingVertices& outer, std::vector<std::uint32_t>& quads) {
  const std::size_t na = inner.index.size(), nb = outer.index.size();
  if (na == 0 || nb == 0) return;
  const bool closed = inner.closed && outer.closed;
  const std::size_t end_a = closed ? na : na - 1, end_b = closed ? nb : nb - 1;
  auto index_a = [&](std::size_t i) { return inner.index[i % na]; };
  auto index_b = [&](std::size_t j) { return outer.index[j % nb]; };
  auto angle_a = [&](std::size_t i) { return i < na ? inner.angle[i] : inner.angle[i - na] + kTwoPi; };
  auto angle_b = [&](std::size_t j) { return j < nb ? outer.angle[j] : outer.angle[j - nb] + kTwoPi; };
  const double tolerance = 0.5 * std::min(inner.step, outer.step);
  std::size_t i = 0, j = 0;
  while (i < end_a || j < end_b) {
    bool advance_a = false, advance_b = false;
    if (i == end_a) {
      advance_b = true;
    } else if (j == end_b) {
      advance_a = true;
    } else {
      const double next_a = angle_a(i + 1), next_b = angle_b(j + 1);
      if (std::abs(next_a - next_b) <= tolerance) {
        advance_a = advance_b = true;
      } else {
        (next_a < next_b ? advance_a : advance_b) = true;
      }
    }
    const std::size_t i2 = advance_a ? i + 1 : i, j2 = advance_b ? j + 1 : j;
    quads.insert(quads.end(), {index_a(i), index_a(i2), index_b(j2), index_b(j)});
    i = i2;
    j = j2;
  }
}

}  // namespace

std::string validate(const CsfSettings& s) {
  if (std::string e = perception::validate(s, "CsfSettings."); !e.empty()) return e;
  if (!(std::isfinite(s.quality) && s.quality >= 0)) return field_error("quality", s.quality, "finite >= 0");
  if (!(std::isfinite(s.min_ring_spacing_px) && s.min_ring_spacing_px >= 1 && s.min_ring_spacing_px <= 4096))
    return field_error("min_ring_spacing_px", s.min_ring_spacing_px, "[1, 4096] pixels");
  if (!(std::isfinite(s.max_ring_spacing_px) && s.max_ring_spacing_px >= s.min_ring_spacing_px &&
        s.max_ring_spacing_px <= 4096))
    return field_error("max_ring_spacing_px", s.max_ring_spacing_px, "[min_ring_spacing_px, 4096] pixels");
  return {};
}

CsfSamplingField::CsfSamplingField(const protocol::DisplayGeometry& display, std::uint32_t width, std::uint32_t height,
                                   glm::dvec2 gaze_px, const CsfSettings& settings)
    : display_(display),
      width_(std::max(1.0, static_cast<double>(width))),
      height_(std::max(1.0, static_cast<double>(height))),
      gaze_px_(resolve_gaze(gaze_px, static_cast<double>(width), static_cast<double>(height))),
      gaze_deg_(),
      settings_(settings) {
  throw_if_invalid(display, settings);
  gaze_deg_ = degrees_at(gaze_px_);
}

protocol::Degrees CsfSamplingField::degrees_at(glm::dvec2 p) const {
  return protocol::normalized_to_degrees(display_, {p.x / width_, p.y / height_});
}

double CsfSamplingField::eccentricity_deg(glm::dvec2 p) const {
  return protocol::angle_between_deg(gaze_deg_, degrees_at(p));
}

double CsfSamplingField::nyquist_cpd(glm::dvec2 p) const {
  const double pitch_x = protocol::angle_between_deg(degrees_at({p.x - 0.5, p.y}), degrees_at({p.x + 0.5, p.y}));
  const double pitch_y = protocol::angle_between_deg(degrees_at({p.x, p.y - 0.5}), degrees_at({p.x, p.y + 0.5}));
  return 1.0 / (2.0 * std::max(pitch_x, pitch_y));
}

double CsfSamplingField::cutoff_cpd(glm::dvec2 p) const { return cutoff_frequency_cpd(eccentricity_deg(p), settings_); }

double CsfSamplingField::required_spacing_px(glm::dvec2 p) const {
  if (settings_.quality == 0) return std::numeric_limits<double>::infinity();
  return nyquist_cpd(p) / (settings_.quality * cutoff_cpd(p));
}

namespace {

// The angular window of the screen as seen from the gaze: the full circle when the gaze is on (or
// next to) the screen, otherwise the range spanned by its corners.
struct AngularWindow {
  bool full = true;
  double begin = 0, end = kTwoPi;
};

AngularWindow screen_window(glm::dvec2 gaze, double width, double height) {
  if (gaze.x >= -1 && gaze.x <= width + 1 && gaze.y >= -1 && gaze.y <= height + 1) return {};
  const double reference = std::atan2(height / 2 - gaze.y, width / 2 - gaze.x);
  double lo = 0, hi = 0;
  for (glm::dvec2 corner : {glm::dvec2{0, 0}, glm::dvec2{width, 0}, glm::dvec2{0, height}, glm::dvec2{width, height}}) {
    double relative = std::atan2(corner.y - gaze.y, corner.x - gaze.x) - reference;
    relative = std::remainder(relative, kTwoPi);  // (-pi, pi]: the corners lie within pi/2 of the reference
    lo = std::min(lo, relative);
    hi = std::max(hi, relative);
  }
  return {false, reference + lo, reference + hi};
}

// Smallest required spacing over directions at distance r from the gaze (clamping is the caller's).
double ring_spacing_raw(const CsfSamplingField& field, const AngularWindow& window, double r) {
  const glm::dvec2 gaze = field.gaze_px();
  if (r <= 0) return field.required_spacing_px(gaze);
  double smallest = std::numeric_limits<double>::infinity();
  for (int k = 0; k < kRingDirections; ++k) {
    const double t = (static_cast<double>(k) + 0.5) / kRingDirections;
    const double angle = window.begin + t * (window.end - window.begin);
    smallest = std::min(smallest, field.required_spacing_px(gaze + r * glm::dvec2{std::cos(angle), std::sin(angle)}));
  }
  return smallest;
}

// The radius out to which some direction needs a ray per pixel (raw spacing <= 1); the spacing grows
// with eccentricity, so bracket by doubling and bisect.
double foveal_radius(const CsfSamplingField& field, const AngularWindow& window, double r_far) {
  if (ring_spacing_raw(field, window, 0) > 1) return 0;
  double lo = 0, hi = 1;
  while (hi < r_far && ring_spacing_raw(field, window, hi) <= 1) {
    lo = hi;
    hi *= 2;
  }
  if (hi >= r_far && ring_spacing_raw(field, window, r_far) <= 1) return r_far;
  hi = std::min(hi, r_far);
  for (int iteration = 0; iteration < 40 && hi - lo > 1e-3; ++iteration) {
    const double mid = 0.5 * (lo + hi);
    (ring_spacing_raw(field, window, mid) <= 1 ? lo : hi) = mid;
  }
  return lo;
}

// How far the screen reaches from the gaze: its farthest corner, and its nearest point (0 when the gaze is on it).
struct ScreenReach {
  double r_far = 0, r_near = 0;
};

ScreenReach screen_reach(glm::dvec2 gaze, double w, double h) {
  ScreenReach reach;
  for (glm::dvec2 corner : {glm::dvec2{0, 0}, glm::dvec2{w, 0}, glm::dvec2{0, h}, glm::dvec2{w, h}})
    reach.r_far = std::max(reach.r_far, glm::length(corner - gaze));
  reach.r_near = glm::length(gaze - glm::clamp(gaze, glm::dvec2{0, 0}, glm::dvec2{w, h}));
  return reach;
}

// s_k, the spacing at ring radius r (Murphy 4.4.4): the smallest over directions, clamped to the settings' range.
double clamped_ring_spacing(const CsfSamplingField& field, const AngularWindow& window, const CsfSettings& settings,
                            double r) {
  return std::clamp(ring_spacing_raw(field, window, r), settings.min_ring_spacing_px, settings.max_ring_spacing_px);
}

// The rings' radii and spacings, inner to outer.
struct RingRadii {
  std::vector<std::pair<double, double>> rings;  // radius, spacing
  bool fan_from_gaze = false;                    // no foveal disc: join the first ring to a vertex at the gaze
};

// Radii: from the foveal disc (or the gaze point) outwards by the spacing at each ring, until a ring
// lies a full spacing beyond the farthest corner (its chords then clear the screen). Rings wholly
// inside r_near are skipped; once the spacing is at its maximum it stays there (it grows with
// eccentricity), so those are stepped over in one go.
RingRadii ring_radii(const CsfSamplingField& field, const AngularWindow& window, const CsfSettings& settings,
                     double r_fovea, const ScreenReach& reach) {
  auto clamped_spacing = [&](double r) { return clamped_ring_spacing(field, window, settings, r); };
  RingRadii radii;
  double r = r_fovea;
  double spacing = clamped_spacing(r);
  while (r + spacing < reach.r_near) {
    if (spacing >= settings.max_ring_spacing_px) {
      const double steps = std::floor((reach.r_near - r) / spacing) - 1;
      if (steps >= 1) {
        r += steps * spacing;
        spacing = clamped_spacing(r);
        continue;
      }
    }
    r += spacing;
    spacing = clamped_spacing(r);
  }
  radii.fan_from_gaze = r <= 0;
  if (r > 0) radii.rings.emplace_back(r, spacing);
  do {
    r += spacing;
    spacing = clamped_spacing(r);
    radii.rings.emplace_back(r, spacing);
  } while (r < reach.r_far + spacing);
  return radii;
}

// One ring's vertices, `full_count` = ceil(2 pi r_k / s_k) around the full circle (Murphy 4.4.4), or
// only those that see the screen when the gaze is off it.
RingVertices place_ring(glm::dvec2 gaze, double radius, double full_count, const AngularWindow& window,
                        VertexSet& vertex_set) {
  RingVertices ring;
  ring.step = kTwoPi / full_count;
  std::int64_t first = 0, last = static_cast<std::int64_t>(full_count) - 1;
  if (!window.full) {
    // One vertex beyond the window on either side, so the quads at its edges still cover the screen.
    const auto a = static_cast<std::int64_t>(std::floor(window.begin / ring.step)) - 1;
    const auto b = static_cast<std::int64_t>(std::ceil(window.end / ring.step)) + 1;
    if (b - a + 1 < static_cast<std::int64_t>(full_count)) {
      first = a;
      last = b;
      ring.closed = false;
    }
  }
  for (std::int64_t i = first; i <= last; ++i) {
    const double angle = static_cast<double>(i) * ring.step;
    ring.angle.push_back(angle);
    ring.index.push_back(vertex_set.at_pixel_of(gaze + radius * glm::dvec2{std::cos(angle), std::sin(angle)}));
  }
  return ring;
}

// Joins a ring to the one inside it (Murphy 5.2.2): the zipper, or the fan from the gaze vertex.
void join_rings(const RingVertices& previous, const RingVertices& ring, bool fan_from_gaze,
                std::vector<std::uint32_t>& quads) {
  if (previous.index.empty()) return;
  if (fan_from_gaze && previous.index.size() == 1) {
    // The fan: the gaze vertex with every consecutive pair of the first ring.
    const std::size_t n = ring.index.size(), end = ring.closed ? n : n - 1;
    for (std::size_t j = 0; j < end; ++j)
      quads.insert(quads.end(), {previous.index[0], previous.index[0], ring.index[(j + 1) % n], ring.index[j]});
  } else {
    zip_rings(previous, ring, quads);
  }
}

// The intermediate mesh before culling (Murphy 4.4.4, 5.2.2): every ring's vertices (into
// mesh.vertices, merged per pixel) and the quads joining consecutive rings, which it returns.
std::vector<std::uint32_t> connect_rings(RingMesh& mesh, const RingRadii& radii, glm::dvec2 gaze,
                                         const AngularWindow& window, const CsfSettings& settings) {
  VertexSet vertex_set(mesh.vertices, mesh.width, mesh.height,
                       static_cast<std::int64_t>(std::ceil(2 * settings.max_ring_spacing_px)) + 2);
  std::vector<std::uint32_t> quads;
  RingVertices previous;
  if (radii.fan_from_gaze) {
    previous.index.push_back(vertex_set.at_pixel_of(gaze));
    previous.angle.push_back(0);
    previous.step = kTwoPi;
    previous.closed = window.full;
  }
  for (const auto& [radius, ring_spacing] : radii.rings) {
    const double full_count = std::max(3.0, std::ceil(kTwoPi * radius / ring_spacing));
    RingVertices ring = place_ring(gaze, radius, full_count, window, vertex_set);
    join_rings(previous, ring, radii.fan_from_gaze, quads);
    mesh.ring_radii_px.push_back(static_cast<float>(radius));
    mesh.ring_vertex_counts.push_back(static_cast<std::uint32_t>(full_count));
    previous = std::move(ring);
  }
  return quads;
}

// Drop quads that cover no part of the screen, then the vertices only they used.
void keep_onscreen_quads(RingMesh& mesh, const std::vector<std::uint32_t>& quads) {
  const double w = mesh.width, h = mesh.height;
  std::vector<std::uint32_t> remap(mesh.vertices.size(), std::numeric_limits<std::uint32_t>::max());
  std::vector<glm::vec2> kept_vertices;
  for (std::size_t q = 0; q + 3 < quads.size(); q += 4) {
    glm::vec2 lo(std::numeric_limits<float>::max()), hi(std::numeric_limits<float>::lowest());
    for (std::size_t c = 0; c < 4; ++c) {
      lo = glm::min(lo, mesh.vertices[quads[q + c]]);
      hi = glm::max(hi, mesh.vertices[quads[q + c]]);
    }
    if (hi.x < 0 || hi.y < 0 || lo.x > static_cast<float>(w) || lo.y > static_cast<float>(h)) continue;
    for (std::size_t c = 0; c < 4; ++c) {
      std::uint32_t& target = remap[quads[q + c]];
      if (target == std::numeric_limits<std::uint32_t>::max()) {
        target = static_cast<std::uint32_t>(kept_vertices.size());
        kept_vertices.push_back(mesh.vertices[quads[q + c]]);
      }
      mesh.quads.push_back(target);
    }
  }
  mesh.vertices = std::move(kept_vertices);
}

}  // namespace

RingMesh ring_mesh(const protocol::DisplayGeometry& display, std::uint32_t width, std::uint32_t height,
                   glm::vec2 gaze_px, const CsfSettings& settings) {
  const CsfSamplingField field(display, width, height, glm::dvec2(gaze_px), settings);
  RingMesh mesh;
  mesh.width = width;
  mesh.height = height;
  const glm::dvec2 gaze = field.gaze_px();
  mesh.gaze_px = glm::vec2(gaze);
  if (width == 0 || height == 0) return mesh;

  const double w = width, h = height;
  const ScreenReach reach = screen_reach(gaze, w, h);
  const AngularWindow window = screen_window(gaze, w, h);

  const double r_fovea = foveal_radius(field, window, reach.r_far);
  mesh.foveal_radius_px = static_cast<float>(r_fovea);
  if (r_fovea >= reach.r_far) return mesh;  // every pixel needs its own ray

  const RingRadii radii = ring_radii(field, window, settings, r_fovea, reach);
  const std::vector<std::uint32_t> quads = connect_rings(mesh, radii, gaze, window, settings);
  keep_onscreen_quads(mesh, quads);
  return mesh;
}

std::uint64_t CsfRayMask::rays() const {
  return static_cast<std::uint64_t>(std::count_if(mask.begin(), mask.end(), [](std::uint8_t m) { return m != 0; }));
}

namespace {

// Calls visit(x, y) for every pixel whose centre is within `radius` of `centre` and on the image.
template <typename Visit>
void for_each_foveal_pixel(const RingMesh& mesh, Visit&& visit) {
  const double radius = mesh.foveal_radius_px;
  if (!(radius > 0)) return;
  const double cx = mesh.gaze_px.x, cy = mesh.gaze_px.y;
  const double y_lo = std::max(0.0, std::ceil(cy - radius - 0.5));
  const double y_hi = std::min(static_cast<double>(mesh.height) - 1, std::floor(cy + radius - 0.5));
  for (double y = y_lo; y <= y_hi; ++y) {
    const double dy = y + 0.5 - cy;
    const double half = std::sqrt(std::max(0.0, radius * radius - dy * dy));
    const double x_lo = std::max(0.0, std::ceil(cx - half - 0.5));
    const double x_hi = std::min(static_cast<double>(mesh.width) - 1, std::floor(cx + half - 0.5));
    for (double x = x_lo; x <= x_hi; ++x) visit(static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y));
  }
}

bool on_image(const RingMesh& mesh, glm::vec2 p) {
  return p.x >= 0 && p.y >= 0 && p.x < static_cast<float>(mesh.width) && p.y < static_cast<float>(mesh.height);
}

std::size_t pixel_index(const RingMesh& mesh, glm::vec2 p) {
  return static_cast<std::size_t>(p.y) * mesh.width + static_cast<std::size_t>(p.x);
}

}  // namespace

CsfRayMask ray_mask(const RingMesh& mesh) {
  CsfRayMask out;
  out.width = mesh.width;
  out.height = mesh.height;
  out.mask.assign(std::size_t{mesh.width} * mesh.height, 0);
  for_each_foveal_pixel(mesh, [&](std::uint32_t x, std::uint32_t y) { out.mask[std::size_t{y} * mesh.width + x] = 1; });
  for (glm::vec2 v : mesh.vertices)
    if (on_image(mesh, v)) out.mask[pixel_index(mesh, v)] = 1;
  return out;
}

CsfRayMask csf_ray_mask(const protocol::DisplayGeometry& display, std::uint32_t width, std::uint32_t height,
                        glm::vec2 gaze_px, const CsfSettings& settings) {
  return ray_mask(ring_mesh(display, width, height, gaze_px, settings));
}

namespace {

// Builds the refinement's samples, casting one ray per distinct position.
class SampleCache {
 public:
  SampleCache(SilhouetteRefinement& out, const ObjectAt& object_at) : out_(out), object_at_(object_at) {}
  std::uint32_t add(glm::vec2 p) {
    const auto [it, inserted] = index_.try_emplace(key(p), static_cast<std::uint32_t>(out_.sample_px.size()));
    if (inserted) {
      out_.sample_px.push_back(p);
      out_.sample_object.push_back(object_at_(p));
      ++out_.rays_cast;
    }
    return it->second;
  }
  // The midpoint of a and b: a itself when both are the same sample (the repeated corner of a
  // triangle), otherwise a new ray unless a neighbour already cast it.
  std::uint32_t midpoint(std::uint32_t a, std::uint32_t b) {
    if (a == b) return a;
    return add((out_.sample_px[a] + out_.sample_px[b]) * 0.5f);
  }

 private:
  static std::uint64_t key(glm::vec2 p) {
    // Midpoints of a shared edge are bitwise equal ((a + b) / 2 is symmetric), so exact bits suffice.
    std::uint32_t bx = 0, by = 0;
    static_assert(sizeof(float) == sizeof(std::uint32_t));
    std::memcpy(&bx, &p.x, sizeof bx);
    std::memcpy(&by, &p.y, sizeof by);
    return (std::uint64_t{bx} << 32) | by;
  }
  SilhouetteRefinement& out_;
  const ObjectAt& object_at_;
  std::unordered_map<std::uint64_t, std::uint32_t> index_;
};

bool corners_agree(const SilhouetteRefinement& r, const std::array<std::uint32_t, 4>& c) {
  const std::uint32_t id = r.sample_object[c[0]];
  return r.sample_object[c[1]] == id && r.sample_object[c[2]] == id && r.sample_object[c[3]] == id;
}

// Splits a piece at its edge midpoints and centre until its pieces agree or are a pixel across.
void subdivide(SilhouetteRefinement& r, SampleCache& cache, const std::array<std::uint32_t, 4>& c, int depth) {
  glm::vec2 p[4];
  for (int k = 0; k < 4; ++k) p[k] = r.sample_px[c[static_cast<std::size_t>(k)]];
  const glm::vec2 extent = glm::max(glm::max(p[0], p[1]), glm::max(p[2], p[3])) -
                           glm::min(glm::min(p[0], p[1]), glm::min(p[2], p[3]));
  if (std::max(extent.x, extent.y) <= 1.0f || depth >= 24) {
    r.pieces.push_back({{c[0], c[1], c[2], c[3]}, true});
    return;
  }
  const std::uint32_t m01 = cache.midpoint(c[0], c[1]), m12 = cache.midpoint(c[1], c[2]);
  const std::uint32_t m23 = cache.midpoint(c[2], c[3]), m30 = cache.midpoint(c[3], c[0]);
  const std::uint32_t centre = cache.add((p[0] + p[1] + p[2] + p[3]) * 0.25f);
  const std::array<std::array<std::uint32_t, 4>, 4> children = {{{c[0], m01, centre, m30},
                                                                 {m01, c[1], m12, centre},
                                                                 {centre, m12, c[2], m23},
                                                                 {m30, centre, m23, c[3]}}};
  for (const auto& child : children) {
    if (corners_agree(r, child)) {
      r.pieces.push_back({{child[0], child[1], child[2], child[3]}, false});
    } else {
      subdivide(r, cache, child, depth + 1);
    }
  }
}

std::uint64_t edge_key(std::uint32_t a, std::uint32_t b) {
  return (std::uint64_t{std::min(a, b)} << 32) | std::max(a, b);
}

}  // namespace

SilhouetteRefinement refine_silhouettes(const RingMesh& mesh, const ObjectAt& object_at, const CsfSettings& settings) {
  SilhouetteRefinement r;
  SampleCache cache(r, object_at);
  for (std::uint32_t v = 0; v < mesh.vertices.size(); ++v) {
    // Mesh vertices are distinct pixel centres: one ray each, at the same index as in the mesh.
    r.sample_px.push_back(mesh.vertices[v]);
    r.sample_object.push_back(object_at(mesh.vertices[v]));
    ++r.rays_cast;
  }
  const std::size_t quad_count = mesh.quad_count();
  r.quad_refined.assign(quad_count, 0);
  auto corners_of = [&](std::size_t q) {
    return std::array<std::uint32_t, 4>{mesh.quads[4 * q], mesh.quads[4 * q + 1], mesh.quads[4 * q + 2],
                                        mesh.quads[4 * q + 3]};
  };
  for (std::size_t q = 0; q < quad_count; ++q) {
    if (!corners_agree(r, corners_of(q))) {
      r.quad_refined[q] = 1;
      ++r.disagreeing_quads;
    }
  }
  if (settings.refine_neighbours && r.disagreeing_quads > 0) {
    // The edges of the disagreeing quads; any other quad with one of those edges is a neighbour.
    std::unordered_set<std::uint64_t> silhouette_edges;
    for (std::size_t q = 0; q < quad_count; ++q) {
      if (!r.quad_refined[q]) continue;
      const auto c = corners_of(q);
      for (std::size_t k = 0; k < 4; ++k)
        if (c[k] != c[(k + 1) % 4]) silhouette_edges.insert(edge_key(c[k], c[(k + 1) % 4]));
    }
    std::vector<std::uint8_t> neighbour(quad_count, 0);
    for (std::size_t q = 0; q < quad_count; ++q) {
      if (r.quad_refined[q]) continue;
      const auto c = corners_of(q);
      for (std::size_t k = 0; k < 4 && !neighbour[q]; ++k)
        if (c[k] != c[(k + 1) % 4] && silhouette_edges.count(edge_key(c[k], c[(k + 1) % 4])) != 0) neighbour[q] = 1;
    }
    for (std::size_t q = 0; q < quad_count; ++q)
      if (neighbour[q] && !r.quad_refined[q]) r.quad_refined[q] = 2;
  }
  for (std::size_t q = 0; q < quad_count; ++q) {
    const auto c = corners_of(q);
    if (r.quad_refined[q] == 0) {
      r.pieces.push_back({{c[0], c[1], c[2], c[3]}, false});
      continue;
    }
    ++r.refined_quads;
    if (r.quad_refined[q] == 2) {
      // A neighbour whose corners agree: the silhouette, if it enters at all, does so between two
      // corners, where no subdivision sample is sure to catch it; cast every pixel it covers.
      r.pieces.push_back({{c[0], c[1], c[2], c[3]}, true});
    } else {
      subdivide(r, cache, c, 0);
    }
    r.quad_refined[q] = 1;
  }
  return r;
}

namespace {

// Calls visit(x, y, barycentric weights of corners 0..3) for every pixel centre inside the piece,
// split into triangles (0, 1, 2) and (0, 2, 3). Edges are inclusive: a pixel on a shared edge may be
// visited by both sides, which the caller resolves.
template <typename Visit>
void rasterize_piece(const std::array<glm::dvec2, 4>& p, std::uint32_t width, std::uint32_t height, Visit&& visit) {
  constexpr double kInsideTolerance = -1e-9;
  constexpr std::array<std::array<int, 3>, 2> kTriangles = {{{0, 1, 2}, {0, 2, 3}}};
  for (const auto& tri : kTriangles) {
    const glm::dvec2 a = p[static_cast<std::size_t>(tri[0])], b = p[static_cast<std::size_t>(tri[1])],
                     c = p[static_cast<std::size_t>(tri[2])];
    const double area = cross(b - a, c - a);
    if (std::abs(area) < 1e-9) continue;
    const glm::dvec2 lo = glm::min(glm::min(a, b), c), hi = glm::max(glm::max(a, b), c);
    // Pixel centres (x + 0.5, y + 0.5) inside the bounding box, on the image.
    const double x0 = std::max(0.0, std::ceil(lo.x - 0.5));
    const double x1 = std::min(static_cast<double>(width) - 1, std::floor(hi.x - 0.5));
    const double y0 = std::max(0.0, std::ceil(lo.y - 0.5));
    const double y1 = std::min(static_cast<double>(height) - 1, std::floor(hi.y - 0.5));
    for (double y = y0; y <= y1; ++y) {
      for (double x = x0; x <= x1; ++x) {
        const glm::dvec2 q{x + 0.5, y + 0.5};
        // Barycentric weights (signed sub-areas over the signed area: orientation drops out).
        const double wa = cross(c - b, q - b) / area, wb = cross(a - c, q - c) / area, wc = cross(b - a, q - a) / area;
        if (wa < kInsideTolerance || wb < kInsideTolerance || wc < kInsideTolerance) continue;
        std::array<double, 4> weights{0, 0, 0, 0};
        weights[static_cast<std::size_t>(tri[0])] += wa;
        weights[static_cast<std::size_t>(tri[1])] += wb;
        weights[static_cast<std::size_t>(tri[2])] += wc;
        visit(static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y), weights);
      }
    }
  }
}

enum PixelState : std::uint8_t { kUnset = 0, kInterpolated = 1, kRayCast = 2 };

// The output with its size and the counts known before any pixel is filled: the mesh's and the refinement's.
CsfReconstruction sized_reconstruction(const RingMesh& mesh, const SilhouetteRefinement& refinement,
                                       std::size_t pixels) {
  CsfReconstruction out;
  out.width = mesh.width;
  out.height = mesh.height;
  out.object_ids.assign(pixels, 0);
  out.colours.assign(pixels, glm::vec3(0.0f));
  CsfStats& stats = out.stats;
  stats.full_resolution_rays = pixels;
  stats.rings = mesh.ring_count();
  stats.quads = mesh.quad_count();
  stats.refined_quads = refinement.refined_quads;
  stats.disagreeing_quads = refinement.disagreeing_quads;
  stats.mesh_rays = std::min<std::uint64_t>(mesh.vertices.size(), refinement.rays_cast);
  stats.refinement_rays = refinement.rays_cast - stats.mesh_rays;
  return out;
}

// Working state of the reconstruction: what each pixel holds so far, and the samples' colours.
struct Reconstructor {
  const RingMesh& mesh;
  const SilhouetteRefinement& refinement;
  const ObjectAt& object_at;
  const ColourAt& colour_at;
  CsfReconstruction& out;
  std::vector<std::uint8_t> state;
  // Colours of the samples, shaded on first use (the hit is already known: no new ray).
  std::vector<glm::vec3> sample_colour;
  std::vector<std::uint8_t> sample_shaded;

  Reconstructor(const RingMesh& m, const SilhouetteRefinement& r, const ObjectAt& object, const ColourAt& colour,
                CsfReconstruction& o, std::size_t pixels)
      : mesh(m),
        refinement(r),
        object_at(object),
        colour_at(colour),
        out(o),
        state(pixels, kUnset),
        sample_colour(r.sample_px.size()),
        sample_shaded(r.sample_px.size(), 0) {}

  void cast_pixel(std::uint32_t x, std::uint32_t y, std::uint64_t& counter) {
    const std::size_t i = std::size_t{y} * mesh.width + x;
    if (state[i] == kRayCast) return;
    const glm::vec2 centre{static_cast<float>(x) + 0.5f, static_cast<float>(y) + 0.5f};
    out.object_ids[i] = object_at(centre);
    out.colours[i] = colour_at(centre, out.object_ids[i]);
    state[i] = kRayCast;
    ++counter;
  }

  glm::vec3 colour_of(std::uint32_t s) {
    if (!sample_shaded[s]) {
      sample_colour[s] = colour_at(refinement.sample_px[s], refinement.sample_object[s]);
      sample_shaded[s] = 1;
    }
    return sample_colour[s];
  }

  std::array<glm::dvec2, 4> corner_positions(const RefinedPiece& piece) const {
    std::array<glm::dvec2, 4> p;
    for (std::size_t k = 0; k < 4; ++k) p[k] = glm::dvec2(refinement.sample_px[piece.corners[k]]);
    return p;
  }
};

// Mesh vertices sit on pixel centres: their rays are those pixels' rays.
void take_vertex_rays(Reconstructor& rec) {
  const RingMesh& mesh = rec.mesh;
  for (std::uint32_t v = 0; v < mesh.vertices.size() && v < rec.refinement.sample_px.size(); ++v) {
    if (!on_image(mesh, mesh.vertices[v])) continue;
    const std::size_t i = pixel_index(mesh, mesh.vertices[v]);
    rec.out.object_ids[i] = rec.refinement.sample_object[v];
    rec.out.colours[i] = rec.colour_of(v);
    rec.state[i] = kRayCast;
  }
}

// Every pixel of the foveal disc gets its own ray (Murphy 4.4.4: f_c >= N there).
void cast_foveal_disc(Reconstructor& rec) {
  for_each_foveal_pixel(rec.mesh,
                        [&](std::uint32_t x, std::uint32_t y) { rec.cast_pixel(x, y, rec.out.stats.foveal_rays); });
}

// Every pixel centre a pixel-level piece covers gets its own ray (Murphy 5.2.3).
void cast_pixel_level_pieces(Reconstructor& rec) {
  CsfStats& stats = rec.out.stats;
  for (const RefinedPiece& piece : rec.refinement.pieces) {
    if (!piece.pixel_level) continue;
    ++stats.pixel_level_pieces;
    rasterize_piece(rec.corner_positions(piece), rec.mesh.width, rec.mesh.height,
                    [&](std::uint32_t x, std::uint32_t y, const std::array<double, 4>&) {
                      rec.cast_pixel(x, y, stats.pixel_level_rays);
                    });
  }
}

// Pixels of pieces whose corners agree, not yet ray cast, take that object and the colour
// interpolated barycentrically from the corners.
void interpolate_uniform_pieces(Reconstructor& rec) {
  for (const RefinedPiece& piece : rec.refinement.pieces) {
    if (piece.pixel_level) continue;
    const std::uint32_t id = rec.refinement.sample_object[piece.corners[0]];
    rasterize_piece(rec.corner_positions(piece), rec.mesh.width, rec.mesh.height,
                    [&](std::uint32_t x, std::uint32_t y, const std::array<double, 4>& weights) {
                      const std::size_t i = std::size_t{y} * rec.mesh.width + x;
                      if (rec.state[i] != kUnset) return;
                      glm::dvec3 colour(0.0);
                      for (std::size_t k = 0; k < 4; ++k)
                        if (weights[k] != 0) colour += weights[k] * glm::dvec3(rec.colour_of(piece.corners[k]));
                      rec.out.object_ids[i] = id;
                      rec.out.colours[i] = glm::vec3(colour);
                      rec.state[i] = kInterpolated;
                    });
  }
}

// Any pixel no piece covered gets its own ray.
void cast_gaps(Reconstructor& rec) {
  for (std::uint32_t y = 0; y < rec.mesh.height; ++y)
    for (std::uint32_t x = 0; x < rec.mesh.width; ++x)
      if (rec.state[std::size_t{y} * rec.mesh.width + x] == kUnset) rec.cast_pixel(x, y, rec.out.stats.gap_rays);
}

}  // namespace

CsfReconstruction reconstruct(const RingMesh& mesh, const SilhouetteRefinement& refinement, const ObjectAt& object_at,
                              const ColourAt& colour_at) {
  const std::size_t pixels = std::size_t{mesh.width} * mesh.height;
  CsfReconstruction out = sized_reconstruction(mesh, refinement, pixels);
  if (pixels == 0) return out;

  Reconstructor rec(mesh, refinement, object_at, colour_at, out, pixels);
  take_vertex_rays(rec);
  cast_foveal_disc(rec);
  cast_pixel_level_pieces(rec);
  interpolate_uniform_pieces(rec);
  cast_gaps(rec);

  CsfStats& stats = out.stats;
  stats.rays_cast = refinement.rays_cast + stats.foveal_rays + stats.pixel_level_rays + stats.gap_rays;
  return out;
}

CsfReconstruction render_csf(const protocol::DisplayGeometry& display, std::uint32_t width, std::uint32_t height,
                             glm::vec2 gaze_px, const CsfSettings& settings, const ObjectAt& object_at,
                             const ColourAt& colour_at) {
  const RingMesh mesh = ring_mesh(display, width, height, gaze_px, settings);
  const SilhouetteRefinement refinement = refine_silhouettes(mesh, object_at, settings);
  return reconstruct(mesh, refinement, object_at, colour_at);
}

}  // namespace fovea::render::gi
