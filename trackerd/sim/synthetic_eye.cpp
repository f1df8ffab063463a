// SPDX-License-Identifier: Apache-2.0
// SyntheticEye: its options' checks, and one frame's geometry (project()): the eye turned by yaw and
// pitch, the pupil and iris image conics, the lids and the corneal glints. The look, the shading and
// the camera's effects are in synthetic_eye_look.cpp, synthetic_eye_render.cpp and
// synthetic_eye_capture.cpp.
#include "sim/synthetic_eye.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

#include "sim/synthetic_eye_geometry.h"
#include "sim/synthetic_eye_look.h"

namespace fovea::trackerd::eye {

using namespace synthetic;  // sim/synthetic_eye_geometry.h

namespace {

constexpr double kMaxAngleDeg = 60.0;  // render()/project() clamp |yaw|, |pitch| to this

std::string num(double v) {
  std::ostringstream out;
  out << v;
  return out.str();
}

void check_range(const char* field, double value, double lo, double hi) {
  if (!std::isfinite(value) || value < lo || value > hi)
    throw std::invalid_argument(std::string("SyntheticEyeOptions.") + field + " = " + num(value) + ": allowed " +
                                num(lo) + ".." + num(hi));
}

void check_point(const char* field, const cv::Point3d& p) {
  for (const double c : {p.x, p.y, p.z})
    if (!std::isfinite(c) || std::abs(c) > 1000)
      throw std::invalid_argument(std::string("SyntheticEyeOptions.") + field + " = (" + num(p.x) + ", " + num(p.y) +
                                  ", " + num(p.z) + "): allowed finite millimetres, |each| <= 1000");
}

// Angles: a non-finite one is an error; a finite one beyond the eye's range is clamped to it (the
// truth reports the angle rendered), so a gaze source that overshoots cannot stop a daemon.
double checked_angle(const char* name, double value) {
  if (!std::isfinite(value))
    throw std::invalid_argument(std::string("SyntheticEye: ") + name + " = " + num(value) + ": allowed finite degrees (" +
                                num(-kMaxAngleDeg) + ".." + num(kMaxAngleDeg) + "; beyond is clamped)");
  return std::clamp(value, -kMaxAngleDeg, kMaxAngleDeg);
}

// The image conic of the circle a^2 + b^2 = r^2 in a plane mapped to the image by the homography
// H (plane coordinates (a, b, 1) -> homogeneous pixels): C_img = H^-T diag(1, 1, -r^2) H^-1.
Conic image_conic(const cv::Matx33d& hinv, double r) {
  Conic out;
  const cv::Matx33d cp(1, 0, 0, 0, 1, 0, 0, 0, -r * r);
  cv::Matx33d m = hinv.t() * cp * hinv;
  // Normalise the scale (the conic is homogeneous) for numerical comfort.
  double scale = 0;
  for (int i = 0; i < 9; ++i) scale = std::max(scale, std::abs(m.val[i]));
  if (!(scale > 0) || !std::isfinite(scale)) return out;
  m *= 1.0 / scale;
  const double a = m(0, 0), b = (m(0, 1) + m(1, 0)) / 2, c = m(1, 1);
  const double d = (m(0, 2) + m(2, 0)) / 2, e = (m(1, 2) + m(2, 1)) / 2, f = m(2, 2);
  const double det = a * c - b * b;
  if (!(std::abs(det) > 1e-300)) return out;
  // Centre: [a b; b c] x0 = -[d; e].
  const double x0 = (-d * c + b * e) / det, y0 = (-a * e + b * d) / det;
  const double q0 = f + d * x0 + e * y0;  // Q at the centre
  // An ellipse: the quadratic part definite with the centre value of the opposite sign.
  if (!(det > 0) || !(a * q0 < 0)) return out;
  out.c = {x0, y0};
  out.a11 = a / -q0;
  out.a12 = b / -q0;
  out.a22 = c / -q0;
  const double det_a = out.a11 * out.a22 - out.a12 * out.a12;
  out.half_w = std::sqrt(out.a22 / det_a);
  out.half_h = std::sqrt(out.a11 / det_a);
  out.valid = std::isfinite(x0) && std::isfinite(y0) && std::isfinite(out.half_w) && std::isfinite(out.half_h);
  return out;
}

// Specular reflection on the cornea sphere (centre cc, radius r) of the LED at led seen from cam:
// the surface point whose normal bisects the directions to the LED and to the camera. The fixed
// point iteration contracts by about r / distance per step.
bool corneal_reflection(const V3& cc, double r, const V3& led, const V3& cam, V3& point, V3& normal) {
  V3 n = unit(unit(led - cc, V3(0, 0, 1)) + unit(cam - cc, V3(0, 0, 1)), V3(0, 0, 1));
  for (int i = 0; i < 200; ++i) {
    const V3 x = cc + r * n;
    const V3 next = unit(unit(led - x, n) + unit(cam - x, n), n);
    const double change = len(next - n);
    n = next;
    if (change < 1e-13) break;
  }
  normal = n;
  point = cc + r * n;
  return std::isfinite(point[0]) && std::isfinite(point[1]) && std::isfinite(point[2]);
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Validation

void SyntheticEyeOptions::validate() const {
  check_range("width", width, 1, 4096);
  check_range("height", height, 1, 4096);
  check_range("eye.cornea_radius_mm", eye.cornea_radius_mm, 4, 15);
  check_range("eye.rotation_to_cornea_mm", eye.rotation_to_cornea_mm, 0, 15);
  check_range("eye.cornea_to_pupil_mm", eye.cornea_to_pupil_mm, 0.5, 10);
  check_range("eye.iris_radius_mm", eye.iris_radius_mm, 2, 10);
  check_range("eye.pupil_radius_mm", eye.pupil_radius_mm, 0.3, 0.95 * eye.iris_radius_mm);
  check_range("eye.eyeball_radius_mm", eye.eyeball_radius_mm, 6, 20);
  check_point("camera.position_mm", camera.position_mm);
  check_point("camera.look_at_mm", camera.look_at_mm);
  const V3 cam = v3(camera.position_mm);
  check_range("camera.position_mm (distance from the rotation centre)", len(cam), eye.eyeball_radius_mm + 1.0, 1733);
  check_range("camera.look_at_mm (distance from camera.position_mm)", len(v3(camera.look_at_mm) - cam), 1.0, 3465);
  check_range("camera.horizontal_fov_deg", camera.horizontal_fov_deg, 5, 160);
  if (leds.positions_mm.size() > 8)
    throw std::invalid_argument("SyntheticEyeOptions.leds: " + std::to_string(leds.positions_mm.size()) +
                                " LEDs: allowed 0..8");
  for (std::size_t i = 0; i < leds.positions_mm.size(); ++i) {
    const cv::Point2d p = leds.positions_mm[i];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || std::abs(p.x) > 1000 || std::abs(p.y) > 1000)
      throw std::invalid_argument("SyntheticEyeOptions.leds[" + std::to_string(i) + "] = (" + num(p.x) + ", " +
                                  num(p.y) + "): allowed finite millimetres, |each| <= 1000");
  }
  check_range("noise_sigma", noise_sigma, 0, 100);
  check_range("motion_blur_px", motion_blur_px, 0, 64);
  check_range("motion_blur_angle_deg", motion_blur_angle_deg, -3600, 3600);
  check_range("defocus_px", defocus_px, 0, 32);
  check_range("eyelid_cover", eyelid_cover, 0, 1);
  check_range("illumination_gradient", illumination_gradient, 0, 1);
  check_range("exposure", exposure, 0.05, 2);
  check_range("eyelash_length", eyelash_length, 0.2, 4);
  if (pupil_iris_contrast != 0) check_range("pupil_iris_contrast (0: the iris's own)", pupil_iris_contrast, 2, 150);
}

// ---------------------------------------------------------------------------------------------
// One frame's geometry: everything project() reports and render() draws.

namespace {

// LED k's position: in the lens plane, offset along the camera's image axes.
V3 led_position(const Camera& cam, cv::Point2d offset) { return cam.pos + offset.x * cam.right + offset.y * cam.down; }

GlintGeom glint_for(const GlintContext& g, cv::Point2d offset) {
  GlintGeom out;
  V3 point, normal;
  if (!corneal_reflection(g.cornea, g.cornea_r, led_position(g.cam, offset), g.cam.pos, point, normal)) return out;
  if (!g.cam.project(point, out.image)) return out;
  out.projected = true;
  out.on_cap = normal.dot(g.d) > g.cap_cos && normal.dot(g.cam.pos - point) > 0;
  return out;
}

Lids make_lids(const Camera& cam, const EyeModel& eye, double pitch, double openness, double cover,
               const Conic& pupil, double skew_u, double skew_l) {
  Lids lids;
  const double k = eye.eyeball_radius_mm / 12.0;  // anatomy scales with the eye
  const double front = eye.rotation_to_cornea_mm + eye.cornea_to_pupil_mm;
  const double rl = eye.eyeball_radius_mm + 0.5 * k;  // lid margins rest on the eyeball
  const auto on_ball = [&](double x, double y) {
    return V3(x, y, std::sqrt(std::max(rl * rl - x * x - y * y, 1.0)));
  };
  // Head-fixed corners; the lids follow vertical gaze partly (lid–eye coordination).
  const cv::Point2d a = cam.project_clamped(V3(-13.0 * k, 1.0 * k, 7.0 * k));
  const cv::Point2d b = cam.project_clamped(V3(13.0 * k, 0.0, 7.0 * k));
  const double y_up = -4.6 * k + 0.75 * front * std::sin(pitch);
  const double y_lo = 5.6 * k + 0.35 * front * std::sin(pitch);
  const cv::Point2d up = cam.project_clamped(on_ball(0.0, y_up));
  const cv::Point2d lo = cam.project_clamped(on_ball(0.0, y_lo));

  lids.mid = (a + b) * 0.5;
  const cv::Point2d ab = b - a;
  const double dist = std::hypot(ab.x, ab.y);
  if (dist > 1e-6 && std::isfinite(dist)) {
    lids.t = ab * (1.0 / dist);
    lids.half = dist / 2;
  }
  lids.n = {-lids.t.y, lids.t.x};
  const cv::Point2d down = cam.project_clamped(V3(0, 1, front)) - cam.project_clamped(V3(0, 0, front));
  if (down.x * lids.n.x + down.y * lids.n.y < 0) lids.n = -lids.n;

  const auto fit = [&](cv::Point2d apex, double skew, double& k0, double& k1) {
    const double s = std::clamp(lids.s_of(apex), -0.7, 0.7), h = lids.h_of(apex);
    k0 = h / ((1 - s * s) * (1 + skew * s));
    k1 = k0 * skew;
  };
  fit(up, skew_u, lids.uo0, lids.uo1);
  fit(lo, skew_l, lids.l0, lids.l1);
  if (!(lids.uo0 < -0.02 * lids.half)) {  // a camera that sees the lids edge-on or upside down
    lids.uo0 = -0.3 * lids.half;
    lids.uo1 = lids.uo0 * skew_u;
  }
  if (!(lids.l0 > 0.02 * lids.half)) {
    lids.l0 = 0.15 * lids.half;
    lids.l1 = lids.l0 * skew_l;
  }

  // The upper lid lowers towards the lower lid: by openness, and further so that `cover` of the
  // pupil's vertical extent (along the lid frame's h, in the pupil centre's column) is hidden.
  double open = clamp01(openness);
  if (cover > 0 && pupil.valid) {
    const double sc = lids.s_of(pupil.c), hc = lids.h_of(pupil.c);
    if (std::abs(sc) < 1) {
      // Half extent of the ellipse along n: sqrt(n^T A^-1 n).
      const double det = pupil.a11 * pupil.a22 - pupil.a12 * pupil.a12;
      const double nx = lids.n.x, ny = lids.n.y;
      const double ext = std::sqrt((pupil.a22 * nx * nx - 2 * pupil.a12 * nx * ny + pupil.a11 * ny * ny) / det);
      const double target = hc - ext + cover * 2 * ext;
      const double uo = Lids::curve(lids.uo0, lids.uo1, sc), lo_h = Lids::curve(lids.l0, lids.l1, sc);
      if (lo_h - uo > 1e-9) open = std::min(open, clamp01((lo_h - target) / (lo_h - uo)));
    }
  }
  lids.open = open;
  lids.u0 = lids.l0 + (lids.uo0 - lids.l0) * open;
  lids.u1 = lids.l1 + (lids.uo1 - lids.l1) * open;
  return lids;
}

// Share of the ellipse's image area inside the lid opening: a 64 x 64 grid over the unit disc,
// mapped affinely onto the ellipse (affine maps keep area ratios).
double visible_fraction(const Conic& e, const Lids& lids) {
  if (!e.valid) return 0;
  const Ellipse el = e.ellipse();
  const double th = el.angle_deg * kDeg;
  const cv::Point2d ax(std::cos(th) * el.major / 2, std::sin(th) * el.major / 2);
  const cv::Point2d ay(-std::sin(th) * el.minor / 2, std::cos(th) * el.minor / 2);
  constexpr int n = 64;
  int total = 0, seen = 0;
  for (int i = 0; i < n; ++i) {
    const double p = (i + 0.5) / n * 2 - 1;
    for (int j = 0; j < n; ++j) {
      const double q = (j + 0.5) / n * 2 - 1;
      if (p * p + q * q > 1) continue;
      ++total;
      if (lids.inside(e.c + ax * p + ay * q)) ++seen;
    }
  }
  return total ? static_cast<double>(seen) / total : 0.0;
}

// Moves the LED at `led` (lens-plane mm) until its glint lands on `target` (pixels): Newton's method with a
// forward-difference Jacobian; the glint moves smoothly with its LED. False when it does not get there.
bool place_glint(const GlintContext& gctx, cv::Point2d target, cv::Point2d& led) {
  for (int it = 0; it < 40; ++it) {
    const GlintGeom g = glint_for(gctx, led);
    if (!g.projected) return false;
    const cv::Point2d err = g.image - target;
    if (std::hypot(err.x, err.y) < 1e-8) return true;
    constexpr double step = 1e-4;  // mm
    const GlintGeom gx = glint_for(gctx, led + cv::Point2d(step, 0));
    const GlintGeom gy = glint_for(gctx, led + cv::Point2d(0, step));
    if (!gx.projected || !gy.projected) return false;
    const double j00 = (gx.image.x - g.image.x) / step, j10 = (gx.image.y - g.image.y) / step;
    const double j01 = (gy.image.x - g.image.x) / step, j11 = (gy.image.y - g.image.y) / step;
    const double jd = j00 * j11 - j01 * j10;
    if (!(std::abs(jd) > 1e-300)) return false;
    cv::Point2d delta((j11 * err.x - j01 * err.y) / jd, (-j10 * err.x + j00 * err.y) / jd);
    const double dn = std::hypot(delta.x, delta.y);
    if (dn > 20) delta *= 20 / dn;  // keeps early steps sane
    led -= delta;
    if (!std::isfinite(led.x) || !std::isfinite(led.y) || std::abs(led.x) > 1000 || std::abs(led.y) > 1000)
      return false;
  }
  return false;
}

}  // namespace

SyntheticEye::SyntheticEye(SyntheticEyeOptions options)
    : options_(std::move(options)), rng_(options_.seed) {
  options_.validate();
  look_ = std::make_shared<const Look>(options_);
}

// The optical axis d(yaw, pitch) of synthetic_eye.h, the pupil-plane axes and the cornea and pupil centres.
void SyntheticEye::Frame::place_eye(const SyntheticEyeOptions& o, double yaw, double pitch) {
  const EyeModel& eye = o.eye;
  cam = Camera::make(o.camera, o.width, o.height);
  d = V3(std::sin(yaw) * std::cos(pitch), std::sin(pitch), std::cos(yaw) * std::cos(pitch));
  u = V3(std::cos(yaw), 0, -std::sin(yaw));  // pupil-plane axes: u (eye's right), v = d x u (eye's down)
  v = d.cross(u);
  cornea = eye.rotation_to_cornea_mm * d;
  pupil_centre = cornea + eye.cornea_to_pupil_mm * d;
  px_per_mm = cam.f / std::max(len(pupil_centre - cam.pos), 1e-3);
}

// Homography from pupil-plane millimetres (a, b) -> X = P + a u + b v -> pixels, returned; hinv is its
// inverse, set (with plane_ok) only when the camera sees the front of the disc.
cv::Matx33d SyntheticEye::Frame::map_pupil_plane() {
  const cv::Vec3d h0 = cam.image_direction(u), h1 = cam.image_direction(v);
  const cv::Vec3d h2 = cam.image_direction(pupil_centre - cam.pos);
  const cv::Matx33d hom(h0[0], h1[0], h2[0], h0[1], h1[1], h2[1], h0[2], h1[2], h2[2]);
  const bool facing = (cam.pos - pupil_centre).dot(d) > 1e-6;  // the camera sees the front of the disc
  const double det = cv::determinant(hom);
  if (facing && std::isfinite(det) && std::abs(det) > 1e-12) {
    hinv = hom.inv();
    plane_ok = true;
  }
  return hom;
}

// Everything that depends on the pupil radius: the pupil and iris image conics, the lids (which may
// cover a share of the pupil) and each LED's glint with its visibility.
void SyntheticEye::Frame::project_for_pupil_radius(const FrameSetup& s, double radius) {
  const SyntheticEyeOptions& o = s.o;
  const EyeModel& eye = o.eye;
  pupil_r = radius;
  pupil = plane_ok ? image_conic(hinv, radius) : Conic{};
  iris = plane_ok ? image_conic(hinv, eye.iris_radius_mm) : Conic{};
  if (!iris.valid) pupil = Conic{};
  lids = make_lids(cam, eye, s.pitch, s.openness, o.eyelid_cover, pupil, s.lid_skew_upper, s.lid_skew_lower);
  glints.clear();
  for (const cv::Point2d& led : leds.positions_mm) {
    GlintGeom g = glint_for(s.gctx, led);
    g.visible = g.on_cap && g.image.x >= 0 && g.image.y >= 0 && g.image.x < o.width && g.image.y < o.height &&
                lids.inside(g.image);
    glints.push_back(g);
  }
}

// SyntheticEyeOptions::glint_on_pupil_edge: the pupil radius (within 1..4 mm) whose boundary passes
// through the glint nearest to it, or, when none does or that glint is hidden, that glint's LED moved.
void SyntheticEye::Frame::put_glint_on_pupil_edge(const FrameSetup& s, const cv::Matx33d& hom) {
  const NearestGlint best = glint_nearest_pupil_edge(s.o.eye.pupil_radius_mm);
  if (best.led >= 0) {
    const std::size_t kb = static_cast<std::size_t>(best.led);
    const double radius = std::clamp(best.r, 1.0, 4.0);
    project_for_pupil_radius(s, radius);
    if (radius != best.r || !glints[kb].visible) move_led_onto_pupil_edge(s, hom, best, radius);
  }
}

// The glint nearest to the pupil boundary, measured as a pupil radius in the pupil plane
// (back-projecting a glint onto the plane gives the radius whose boundary passes through it).
// Visible glints first; when none is visible, any reflection (its LED will be moved).
NearestGlint SyntheticEye::Frame::glint_nearest_pupil_edge(double pupil_radius_mm) const {
  NearestGlint best;
  for (const bool need_visible : {true, false}) {
    double best_gap = std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < glints.size(); ++k) {
      const GlintGeom& g = glints[k];
      if (!g.projected || (need_visible && !g.visible)) continue;
      const cv::Vec3d q = hinv * cv::Vec3d(g.image.x, g.image.y, 1.0);
      if (!(std::abs(q[2]) > 1e-300)) continue;
      const cv::Point2d ab(q[0] / q[2], q[1] / q[2]);
      const double r = std::hypot(ab.x, ab.y), gap = std::abs(r - pupil_radius_mm);
      if (std::isfinite(r) && gap < best_gap) {
        best.led = static_cast<int>(k);
        best_gap = gap;
        best.r = r;
        best.ab = ab;
      }
    }
    if (best.led >= 0) break;
  }
  return best;
}

// No allowed radius reaches this glint (or it is hidden): move its LED in the lens plane until its
// glint lands on the boundary of the nearest allowed pupil, at the glint's own angle or, if that
// point is hidden, the nearest visible angle (place_glint). The LED stays put when no angle works.
void SyntheticEye::Frame::move_led_onto_pupil_edge(const FrameSetup& s, const cv::Matx33d& hom,
                                                   const NearestGlint& best, double radius) {
  const std::size_t kb = static_cast<std::size_t>(best.led);
  const double phi0 = best.r > 1e-9 ? std::atan2(best.ab.y, best.ab.x) : 0.0;
  for (int attempt = 0; attempt < 12; ++attempt) {
    const double phi = phi0 + (attempt % 2 ? 1 : -1) * ((attempt + 1) / 2) * 30 * kDeg;
    const cv::Vec3d th = hom * cv::Vec3d(radius * std::cos(phi), radius * std::sin(phi), 1.0);
    const cv::Point2d target(th[0] / th[2], th[1] / th[2]);
    cv::Point2d led = leds.positions_mm[kb];
    if (!place_glint(s.gctx, target, led)) continue;
    const GlintGeom g = glint_for(s.gctx, led);
    if (!g.on_cap || g.image.x < 0 || g.image.y < 0 || g.image.x >= s.o.width || g.image.y >= s.o.height ||
        !lids.inside(g.image))
      continue;
    leds.positions_mm[kb] = led;
    project_for_pupil_radius(s, radius);
    break;
  }
}

// EyeTruth from the final geometry; the glint centroid counts every LED's reflection, visible or not.
void SyntheticEye::Frame::fill_truth(const GlintContext& gctx, double yaw_deg, double pitch_deg, double openness) {
  EyeTruth& t = truth;
  t.yaw_deg = yaw_deg;
  t.pitch_deg = pitch_deg;
  t.openness = openness;
  t.pupil = pupil.ellipse();
  if (!pupil.valid) {
    cv::Point2d c;
    if (cam.project(pupil_centre, c)) t.pupil.centre = c;
  }
  t.pupil_visible_fraction = visible_fraction(pupil, lids);
  t.closed = !(t.pupil_visible_fraction > 0);
  t.pupil_radius_mm = pupil_r;
  t.leds_used = leds;
  cv::Point2d sum(0, 0);
  int counted = 0;
  for (std::size_t k = 0; k < glints.size(); ++k) {
    const GlintGeom& g = glints[k];
    if (!g.projected) continue;
    sum += g.image;
    ++counted;
    if (g.visible) {
      t.glints.push_back(g.image);
      t.glint_led.push_back(static_cast<int>(k));
    }
  }
  if (counted > 0) {
    t.glint_centroid = sum * (1.0 / counted);
  } else {
    // No LEDs (or none reflects): the reference is where a coaxial LED's glint would be.
    const GlintGeom g = glint_for(gctx, {0, 0});
    t.glint_centroid = g.projected ? g.image : t.pupil.centre;
  }
  t.pupil_glint = t.pupil.centre - t.glint_centroid;
}

SyntheticEye::Frame SyntheticEye::frame(double yaw_deg, double pitch_deg, double openness) const {
  yaw_deg = checked_angle("yaw_deg", yaw_deg);
  pitch_deg = checked_angle("pitch_deg", pitch_deg);
  if (!std::isfinite(openness))
    throw std::invalid_argument("SyntheticEye: openness = " + num(openness) + ": allowed 0..1");
  openness = clamp01(openness);
  const SyntheticEyeOptions& o = options_;
  const EyeModel& eye = o.eye;

  Frame fr;
  const double yaw = yaw_deg * kDeg, pitch = pitch_deg * kDeg;
  fr.place_eye(o, yaw, pitch);
  const cv::Matx33d hom = fr.map_pupil_plane();
  fr.leds = o.leds;
  const FrameSetup setup{o, pitch, openness, look_->lid_skew_upper, look_->lid_skew_lower,
                         GlintContext{fr.cam, fr.cornea, fr.d, eye.cornea_radius_mm,
                                      std::cos(std::asin(std::min(eye.iris_radius_mm / eye.cornea_radius_mm, 1.0)))}};
  fr.project_for_pupil_radius(setup, eye.pupil_radius_mm);
  if (o.glint_on_pupil_edge && fr.plane_ok && fr.pupil.valid) fr.put_glint_on_pupil_edge(setup, hom);
  fr.fill_truth(setup.gctx, yaw_deg, pitch_deg, openness);
  return fr;
}

EyeTruth SyntheticEye::project(double yaw_deg, double pitch_deg, double openness) const {
  return frame(yaw_deg, pitch_deg, openness).truth;
}

}  // namespace fovea::trackerd::eye
