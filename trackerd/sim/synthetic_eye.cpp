// SPDX-License-Identifier: Apache-2.0
#include "sim/synthetic_eye.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

#include <opencv2/imgproc.hpp>

namespace fovea::trackerd::eye {

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kDeg = kPi / 180.0;
constexpr double kMaxAngleDeg = 60.0;  // render()/project() clamp |yaw|, |pitch| to this

using V3 = cv::Vec3d;

double len(const V3& a) { return std::sqrt(a.dot(a)); }
V3 unit(const V3& a, const V3& fallback) {
  const double n = len(a);
  return (n > 1e-300 && std::isfinite(n)) ? a / n : fallback;
}
V3 v3(const cv::Point3d& p) { return {p.x, p.y, p.z}; }
double clamp01(double x) { return std::clamp(x, 0.0, 1.0); }
double smoothstep(double e0, double e1, double x) {
  const double t = clamp01((x - e0) / (e1 - e0));
  return t * t * (3 - 2 * t);
}
// (1 - z^2)^2 for |z| < 1, else 0: a smooth bump with compact support.
double bump(double z) {
  const double q = 1 - z * z;
  return q > 0 ? q * q : 0.0;
}

// splitmix64: a small, fast, well-mixed generator. Used for the instance's look (seeded from the
// options' seed) and for the per-frame noise (seeded by one draw from the instance's mt19937_64),
// so results do not depend on the standard library's distribution implementations.
struct SplitMix {
  std::uint64_t state;
  std::uint64_t next() {
    std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }  // [0, 1)
  double uniform(double a, double b) { return a + (b - a) * uniform(); }
  int integer(int lo, int hi) {  // [lo, hi]
    return lo + static_cast<int>(next() % static_cast<std::uint64_t>(hi - lo + 1));
  }
};

// Inverse of the standard normal CDF (Acklam's rational approximation, relative error < 1.2e-9).
double inverse_normal_cdf(double p) {
  static constexpr double a[] = {-3.969683028665376e+01, 2.209460984245205e+02, -2.759285104469687e+02,
                                 1.383577518672690e+02,  -3.066479806614716e+01, 2.506628277459239e+00};
  static constexpr double b[] = {-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
                                 6.680131188771972e+01, -1.328068155288572e+01};
  static constexpr double c[] = {-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
                                 -2.549732539343734e+00, 4.374664141464968e+00,  2.938163982698783e+00};
  static constexpr double d[] = {7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
                                 3.754408661907416e+00};
  constexpr double plow = 0.02425;
  if (p < plow) {
    const double q = std::sqrt(-2 * std::log(p));
    return (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
           ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1);
  }
  if (p <= 1 - plow) {
    const double q = p - 0.5, r = q * q;
    return (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
           (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1);
  }
  return -inverse_normal_cdf(1 - p);
}

// Sensor noise: 65536 standard-normal quantiles, indexed by 16 random bits per pixel. The marginal
// is a Gaussian discretised into equiprobable steps (tails cut at 4.3 sigma), about ten times
// faster than Box–Muller.
const std::array<float, 65536>& normal_table() {
  static const std::array<float, 65536> table = [] {
    std::array<float, 65536> t{};
    double sum2 = 0;
    for (std::size_t i = 0; i < t.size(); ++i) {
      const double z = inverse_normal_cdf((static_cast<double>(i) + 0.5) / 65536.0);
      sum2 += z * z;
      t[i] = static_cast<float>(z);
    }
    const double scale = 1.0 / std::sqrt(sum2 / 65536.0);  // unit variance exactly
    for (float& z : t) z = static_cast<float>(static_cast<double>(z) * scale);
    return t;
  }();
  return table;
}

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

// A pinhole camera: position, orthonormal basis (right = image x, down = image y, forward) and
// intrinsics in the pixel convention of ellipse.h (pixel i covers [i, i+1)).
struct Camera {
  V3 pos, right, down, fwd;
  double f = 1, cx = 0, cy = 0;

  static Camera make(const EyeCamera& c, int width, int height) {
    Camera cam;
    cam.pos = v3(c.position_mm);
    cam.fwd = unit(v3(c.look_at_mm) - cam.pos, V3(0, 0, -1));
    // Image down as close as possible to head +y: right = head_down x forward, down = forward x right.
    V3 r = V3(0, 1, 0).cross(cam.fwd);
    if (len(r) < 1e-6) r = V3(0, 0, 1).cross(cam.fwd);  // looking straight up or down
    cam.right = unit(r, V3(1, 0, 0));
    cam.down = cam.fwd.cross(cam.right);
    cam.f = (width / 2.0) / std::tan(c.horizontal_fov_deg * kDeg / 2);
    cam.cx = width / 2.0;
    cam.cy = height / 2.0;
    return cam;
  }
  V3 to_camera(const V3& x) const {
    const V3 rel = x - pos;
    return {rel.dot(right), rel.dot(down), rel.dot(fwd)};
  }
  // False when the point is not in front of the camera.
  bool project(const V3& x, cv::Point2d& out) const {
    const V3 c = to_camera(x);
    if (!(c[2] > 1e-6)) return false;
    out = {cx + f * c[0] / c[2], cy + f * c[1] / c[2]};
    return std::isfinite(out.x) && std::isfinite(out.y);
  }
  // Projection that never fails (points behind the camera are pushed just in front): for anchors.
  cv::Point2d project_clamped(const V3& x) const {
    const V3 c = to_camera(x);
    const double z = std::max(c[2], 1e-3);
    return {cx + f * c[0] / z, cy + f * c[1] / z};
  }
  // K * R * vec for a direction (homogeneous image coordinates).
  cv::Vec3d image_direction(const V3& vec) const {
    const double xr = vec.dot(right), yr = vec.dot(down), zr = vec.dot(fwd);
    return {f * xr + cx * zr, f * yr + cy * zr, zr};
  }
};

// An ellipse in the image written as (x - c)^T A (x - c) = 1 with A symmetric positive definite.
struct Conic {
  bool valid = false;
  cv::Point2d c;
  double a11 = 0, a12 = 0, a22 = 0;
  double half_w = 0, half_h = 0;  // half extents of the bounding box

  double q(double x, double y) const {  // < 0 inside, 0 on the boundary
    const double ex = x - c.x, ey = y - c.y;
    return a11 * ex * ex + 2 * a12 * ex * ey + a22 * ey * ey - 1;
  }
  // Signed distance to the boundary in pixels, to first order: Q / |grad Q|; exact on the boundary
  // and with the right sign everywhere (|value| >= half the true distance far away).
  double signed_distance(double x, double y) const {
    const double ex = x - c.x, ey = y - c.y;
    const double gx = 2 * (a11 * ex + a12 * ey), gy = 2 * (a12 * ex + a22 * ey);
    const double qv = a11 * ex * ex + 2 * a12 * ex * ey + a22 * ey * ey - 1;
    return qv / std::sqrt(gx * gx + gy * gy + 1e-300);
  }
  // Area coverage of the pixel centred at (x, y) by the inside: a 1-px box filter across the
  // boundary, evaluated at the pixel centre (unbiased: symmetric about the boundary).
  double coverage(double x, double y) const { return clamp01(0.5 - signed_distance(x, y)); }

  Ellipse ellipse() const {
    Ellipse e;
    e.centre = c;
    if (!valid) return e;
    const double tr = a11 + a22, diff = a11 - a22;
    const double root = std::sqrt(diff * diff / 4 + a12 * a12);
    const double lmin = tr / 2 - root, lmax = tr / 2 + root;  // lmin <-> major axis
    e.major = 2 / std::sqrt(lmin);
    e.minor = 2 / std::sqrt(lmax);
    // Direction of the eigenvector of lmax is 0.5 atan2(2 a12, a11 - a22); the major axis is normal to it.
    double angle = 0.5 * std::atan2(2 * a12, diff) / kDeg + 90.0;
    if (root < 1e-12 * tr) angle = 0;  // a circle: any direction
    angle = std::fmod(angle, 180.0);
    if (angle < 0) angle += 180.0;
    if (angle >= 180.0) angle -= 180.0;
    e.angle_deg = angle;
    return e;
  }
};

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

// The lid frame: an image axis through the two eye corners (s = -1 and +1 at the corners, h the
// signed distance from that axis in pixels, positive towards head +y). Each lid margin is the
// curve h = (1 - s^2)(k0 + k1 s): a parabola skewed slightly so the eye is almond-shaped.
struct Lids {
  cv::Point2d mid, t{1, 0}, n{0, 1};
  double half = 1;
  double u0 = 0, u1 = 0;    // upper lid as rendered
  double l0 = 0, l1 = 0;    // lower lid
  double uo0 = 0, uo1 = 0;  // upper lid fully open (for the skin crease)
  double open = 1;          // 0..1: how far the upper lid is from the lower lid

  static double curve(double k0, double k1, double s) { return (1 - s * s) * (k0 + k1 * s); }
  static double slope(double k0, double k1, double s) { return -2 * s * (k0 + k1 * s) + (1 - s * s) * k1; }
  double s_of(cv::Point2d p) const { return ((p.x - mid.x) * t.x + (p.y - mid.y) * t.y) / half; }
  double h_of(cv::Point2d p) const { return (p.x - mid.x) * n.x + (p.y - mid.y) * n.y; }
  bool inside(cv::Point2d p) const {
    const double s = s_of(p), h = h_of(p);
    return std::abs(s) < 1 && h > curve(u0, u1, s) && h < curve(l0, l1, s);
  }
  cv::Point2d point(double s, double h) const {
    return {mid.x + s * half * t.x + h * n.x, mid.y + s * half * t.y + h * n.y};
  }
};

// Box-filter coverage of the pixel by the slab between the two margins (du, dl inside distances).
double opening_coverage(double du, double dl) {
  return clamp01(std::min(du + 0.5, 1.0) + std::min(dl + 0.5, 1.0) - 1.0);
}

struct GlintGeom {
  bool projected = false;  // the reflection point exists and is in front of the camera
  bool on_cap = false;     // on the camera-facing corneal cap (inside the limbus)
  bool visible = false;    // on_cap, inside the image and not behind a lid
  cv::Point2d image;
};

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
}

// ---------------------------------------------------------------------------------------------
// The instance's look: everything about the eye's appearance that a real person and a real
// headset keep from frame to frame, drawn once from the seed.

struct SyntheticEye::Look {
  static constexpr int kTheta = 512, kRho = 32;  // iris texture: angle x normalised radius

  double skin = 160, sclera = 200, pupil = 22, lash = 50;
  double iris_inner = 100;    // iris level next to the pupil (flat there, so the edge is unbiased)
  std::vector<float> iris;    // kRho rows of kTheta grey levels
  // Skin: a few low-frequency waves, separable per wave: cos(kx x + phi + ky y).
  struct Wave {
    double kx, ky, phase, amp;
  };
  std::vector<Wave> waves;
  std::vector<float> wave_cx, wave_sx;  // [wave][x]
  std::vector<float> wave_cy, wave_sy;  // [wave][y]
  double lid_skew_upper = 0, lid_skew_lower = 0;
  struct Lash {
    double s, length_mm, tilt, curl, width_mm, opacity;
  };
  std::vector<Lash> lashes;
  struct Reflection {
    cv::Point2d centre;  // pixels
    double a, b, angle, strength;
  };
  std::vector<Reflection> reflections;
  cv::Point2d gradient_dir{1, 0};

  explicit Look(const SyntheticEyeOptions& o);

 private:
  // Look()'s stages, in the order it calls them (the order of the random draws); members because
  // each fills some of the fields above.
  float& iris_at(int ir, int it);
  void draw_iris_texture(SplitMix& rng);
  static std::vector<double> iris_low_frequency(SplitMix& rng);
  void add_collarette_and_limbal_ring(const std::vector<double>& low, const std::vector<double>& col_phase);
  void add_iris_fibres(SplitMix& rng);
  void add_iris_crypts(SplitMix& rng);
  void draw_skin_waves(SplitMix& rng, const SyntheticEyeOptions& o);
  void tabulate_skin_waves(std::size_t w, std::size_t h);
  void draw_lashes(SplitMix& rng);
  void draw_spectacle_reflections(SplitMix& rng, const SyntheticEyeOptions& o);
};

SyntheticEye::Look::Look(const SyntheticEyeOptions& o) {
  SplitMix rng{o.seed ^ 0x5EED0F0E7E5ull};
  skin = rng.uniform(152, 168);
  sclera = rng.uniform(192, 206);
  pupil = rng.uniform(17, 27);
  lash = rng.uniform(44, 56);
  draw_iris_texture(rng);
  draw_skin_waves(rng, o);
  lid_skew_upper = rng.uniform(-0.18, 0.18);
  lid_skew_lower = rng.uniform(-0.15, 0.15);
  draw_lashes(rng);
  draw_spectacle_reflections(rng, o);
  const double ga = rng.uniform(0, 2 * kPi);
  gradient_dir = {std::cos(ga), std::sin(ga)};
}

// The iris texel at (radius row ir, angle column it), the angle wrapping around.
float& SyntheticEye::Look::iris_at(int ir, int it) {
  return iris[static_cast<std::size_t>(ir * kTheta + ((it % kTheta) + kTheta) % kTheta)];
}

// Iris texture in (angle, normalised radius 0 = pupil edge .. 1 = limbus): radial fibres,
// crypts, a collarette ring and a darker limbal ring, as the iris looks in near infrared.
void SyntheticEye::Look::draw_iris_texture(SplitMix& rng) {
  const double base = rng.uniform(98, 112);
  iris.assign(static_cast<std::size_t>(kTheta * kRho), static_cast<float>(base));
  const std::vector<double> low = iris_low_frequency(rng);
  std::vector<double> col_phase(4);
  for (double& p : col_phase) p = rng.uniform(0, 2 * kPi);
  add_collarette_and_limbal_ring(low, col_phase);
  add_iris_fibres(rng);
  add_iris_crypts(rng);
  for (float& v : iris) v = std::clamp(v, 82.0f, 130.0f);
  double inner = 0;
  for (int it = 0; it < kTheta; ++it)
    inner += static_cast<double>(iris_at(0, it)) + static_cast<double>(iris_at(1, it));
  iris_inner = inner / (2.0 * kTheta);
}

// Angular variation shared by every radius: six harmonics with amplitude falling as 1/sqrt(k).
std::vector<double> SyntheticEye::Look::iris_low_frequency(SplitMix& rng) {
  std::vector<double> low(kTheta, 0.0);
  for (int k = 1; k <= 6; ++k) {
    const double amp = rng.uniform(0.5, 2.5) / std::sqrt(k), ph = rng.uniform(0, 2 * kPi);
    for (int it = 0; it < kTheta; ++it)
      low[static_cast<std::size_t>(it)] += amp * std::cos(k * 2 * kPi * it / kTheta + ph);
  }
  return low;
}

// The low-frequency pattern, a wavy bright collarette near a third of the radius and the darker
// limbal ring towards the outer edge.
void SyntheticEye::Look::add_collarette_and_limbal_ring(const std::vector<double>& low,
                                                        const std::vector<double>& col_phase) {
  for (int ir = 0; ir < kRho; ++ir) {
    const double rho = ir / (kRho - 1.0);
    for (int it = 0; it < kTheta; ++it) {
      const double th = 2 * kPi * it / kTheta;
      const double collarette_r =
          0.33 + 0.04 * std::sin(3 * th + col_phase[0]) + 0.02 * std::sin(7 * th + col_phase[1]);
      double v = low[static_cast<std::size_t>(it)];
      v += 6.0 * std::exp(-std::pow((rho - collarette_r) / 0.06, 2));
      v -= 16.0 * smoothstep(0.72, 1.0, rho);
      iris_at(ir, it) += static_cast<float>(v);
    }
  }
}

// Radial fibres, bright or dark, each a Gaussian in angle that swirls slightly from its inner to
// its outer end and fades in and out along the radius.
void SyntheticEye::Look::add_iris_fibres(SplitMix& rng) {
  const int fibres = 220;
  for (int j = 0; j < fibres; ++j) {
    const double th0 = rng.uniform(0, kTheta);
    const double width = rng.uniform(1.0, 4.0);  // bins
    const double amp = rng.uniform() < 0.55 ? rng.uniform(3, 10) : -rng.uniform(3, 9);
    const double r0 = rng.uniform(0.0, 0.55), r1 = std::min(1.0, r0 + rng.uniform(0.25, 0.7));
    const double swirl = rng.uniform(-6, 6);  // bins of angular drift from inner to outer end
    for (int ir = 0; ir < kRho; ++ir) {
      const double rho = ir / (kRho - 1.0);
      const double wr = smoothstep(r0, r0 + 0.08, rho) * (1 - smoothstep(r1 - 0.08, r1, rho));
      if (wr <= 0) continue;
      const double centre = th0 + swirl * rho;
      const int lo = static_cast<int>(std::floor(centre - 3 * width));
      const int hi = static_cast<int>(std::ceil(centre + 3 * width));
      for (int it = lo; it <= hi; ++it) {
        const double z = (it - centre) / width;
        iris_at(ir, it) += static_cast<float>(amp * wr * std::exp(-z * z));
      }
    }
  }
}

void SyntheticEye::Look::add_iris_crypts(SplitMix& rng) {
  for (int j = 0; j < 12; ++j) {  // crypts: dark lacunae
    const double th0 = rng.uniform(0, kTheta), r0 = rng.uniform(0.15, 0.7);
    const double wt = rng.uniform(4, 12), wr = rng.uniform(0.04, 0.1), amp = rng.uniform(8, 16);
    for (int ir = 0; ir < kRho; ++ir) {
      const double dr = (ir / (kRho - 1.0) - r0) / wr;
      if (std::abs(dr) > 3) continue;
      for (int it = static_cast<int>(th0 - 3 * wt); it <= static_cast<int>(th0 + 3 * wt); ++it) {
        const double dt = (it - th0) / wt;
        iris_at(ir, it) -= static_cast<float>(amp * std::exp(-dr * dr - dt * dt));
      }
    }
  }
}

// Skin waves, wavelengths relative to the image so the look does not depend on resolution.
void SyntheticEye::Look::draw_skin_waves(SplitMix& rng, const SyntheticEyeOptions& o) {
  const double size = std::max(o.width, o.height);
  const std::size_t w = static_cast<std::size_t>(o.width), h = static_cast<std::size_t>(o.height);
  for (int k = 0; k < 4; ++k) {
    const double lambda = rng.uniform(0.35, 1.4) * size, dir = rng.uniform(0, 2 * kPi);
    waves.push_back({2 * kPi / lambda * std::cos(dir), 2 * kPi / lambda * std::sin(dir), rng.uniform(0, 2 * kPi),
                     rng.uniform(1.5, 4.0)});
  }
  tabulate_skin_waves(w, h);
}

// Per-column and per-row factors of each wave, so that render() gets amp cos(kx x + phi + ky y) as
// cx cy - sx sy at pixel centres without evaluating a cosine per pixel.
void SyntheticEye::Look::tabulate_skin_waves(std::size_t w, std::size_t h) {
  wave_cx.resize(waves.size() * w);
  wave_sx.resize(waves.size() * w);
  wave_cy.resize(waves.size() * h);
  wave_sy.resize(waves.size() * h);
  for (std::size_t k = 0; k < waves.size(); ++k) {
    for (std::size_t x = 0; x < w; ++x) {
      const double arg = waves[k].kx * (static_cast<double>(x) + 0.5) + waves[k].phase;
      wave_cx[k * w + x] = static_cast<float>(waves[k].amp * std::cos(arg));
      wave_sx[k * w + x] = static_cast<float>(waves[k].amp * std::sin(arg));
    }
    for (std::size_t y = 0; y < h; ++y) {
      const double arg = waves[k].ky * (static_cast<double>(y) + 0.5);
      wave_cy[k * h + y] = static_cast<float>(std::cos(arg));
      wave_sy[k * h + y] = static_cast<float>(std::sin(arg));
    }
  }
}

// Upper lashes: hang from the upper lid margin over the eye, fanning out towards the corners.
void SyntheticEye::Look::draw_lashes(SplitMix& rng) {
  const int n_lashes = 70;
  for (int j = 0; j < n_lashes; ++j) {
    Lash l;
    l.s = rng.uniform(-0.92, 0.92);
    const double edge = 1 - l.s * l.s;
    l.length_mm = (rng.uniform() < 0.15 ? rng.uniform(4.5, 7.0) : rng.uniform(1.5, 4.5)) * (0.45 + 0.55 * edge);
    l.tilt = 0.9 * l.s + rng.uniform(-0.35, 0.35);  // radians from image "down" towards +t
    l.curl = (l.s >= 0 ? 1 : -1) * rng.uniform(0.1, 0.7);
    l.width_mm = rng.uniform(0.06, 0.11);
    l.opacity = rng.uniform(0.55, 0.95);
    lashes.push_back(l);
  }
}

// Spectacle reflections: 1-3 large soft ellipses or streaks, fixed to the headset (and camera).
void SyntheticEye::Look::draw_spectacle_reflections(SplitMix& rng, const SyntheticEyeOptions& o) {
  const int n_refl = rng.integer(1, 3);
  const double wd = o.width, ht = o.height, small = std::min(wd, ht);
  for (int j = 0; j < n_refl; ++j) {
    Reflection r;
    r.centre = {wd * rng.uniform(0.25, 0.75), ht * rng.uniform(0.25, 0.75)};
    const bool streak = rng.uniform() < 0.5;
    r.a = small * rng.uniform(0.12, 0.35);
    r.b = r.a * (streak ? rng.uniform(0.12, 0.3) : rng.uniform(0.45, 0.9));
    r.angle = rng.uniform(0, kPi);
    r.strength = rng.uniform(0.3, 0.65);
    reflections.push_back(r);
  }
}

// ---------------------------------------------------------------------------------------------
// One frame's geometry: everything project() reports and render() draws.

namespace {

struct GlintContext {
  const Camera& cam;
  V3 cornea, d;
  double cornea_r;
  double cap_cos;  // cos of the limbus angle at the cornea centre, asin(iris radius / cornea radius)
};

// What frame() fixes before it chooses the pupil radius: the inputs of every project_for_pupil_radius.
struct FrameSetup {
  const SyntheticEyeOptions& o;
  double pitch;                           // radians, clamped
  double openness;                        // clamped to 0..1
  double lid_skew_upper, lid_skew_lower;  // the instance's look
  GlintContext gctx;
};

// The glint nearest to the pupil boundary, as the pupil radius whose boundary passes through it.
struct NearestGlint {
  int led = -1;    // -1: none
  double r = 0;    // mm
  cv::Point2d ab;  // the glint back-projected onto the pupil plane, mm
};

}  // namespace

struct SyntheticEye::Frame {
  Camera cam;
  V3 d, u, v, cornea, pupil_centre;
  double pupil_r = 0;
  double px_per_mm = 1;  // image scale at the pupil
  bool plane_ok = false;
  cv::Matx33d hinv;  // image -> pupil plane (mm)
  Conic pupil, iris;
  Lids lids;
  LedLayout leds;
  std::vector<GlintGeom> glints;  // one per LED
  EyeTruth truth;

  // frame()'s stages, in the order it calls them; members because each fills some of the fields above.
  void place_eye(const SyntheticEyeOptions& o, double yaw, double pitch);
  cv::Matx33d map_pupil_plane();
  void project_for_pupil_radius(const FrameSetup& s, double radius);
  void put_glint_on_pupil_edge(const FrameSetup& s, const cv::Matx33d& hom);
  NearestGlint glint_nearest_pupil_edge(double pupil_radius_mm) const;
  void move_led_onto_pupil_edge(const FrameSetup& s, const cv::Matx33d& hom, const NearestGlint& best,
                                double radius);
  void fill_truth(const GlintContext& gctx, double yaw_deg, double pitch_deg, double openness);
};

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

// ---------------------------------------------------------------------------------------------
// Rendering

namespace {

// atan2 to about 2e-6 rad (a minimax polynomial for atan on [0, 1] and octant folding): the iris
// texture lookup needs no more, and it is several times faster than std::atan2.
double fast_atan2(double y, double x) {
  const double ax = std::abs(x), ay = std::abs(y);
  const double mx = std::max(ax, ay), mn = std::min(ax, ay);
  const double a = mx > 0 ? mn / mx : 0.0, z = a * a;
  double r = a * (0.99997726 + z * (-0.33262347 + z * (0.19354346 + z * (-0.11643287 + z * (0.05265332 + z * -0.01172120)))));
  if (ay > ax) r = kPi / 2 - r;
  if (x < 0) r = kPi - r;
  return y < 0 ? -r : r;
}

double normal_cdf(double z) { return 0.5 * std::erfc(-z / std::numbers::sqrt2); }

// A glint as a pixel-integrated Gaussian (so its centroid is unbiased for any sigma), separable.
struct GlintSplat {
  int x0 = 0, x1 = 0, y0 = 0, y1 = 0;  // [x0, x1) x [y0, y1)
  std::vector<float> gx, gy;
};

GlintSplat make_splat(cv::Point2d c, double sigma, double peak, int width, int height) {
  GlintSplat s;
  if (!(std::abs(c.x) < 1e6 && std::abs(c.y) < 1e6)) return s;  // far outside: nothing to draw
  const double reach = 4 * sigma + 1;
  s.x0 = std::max(0, static_cast<int>(std::floor(c.x - reach)));
  s.x1 = std::min(width, static_cast<int>(std::ceil(c.x + reach)));
  s.y0 = std::max(0, static_cast<int>(std::floor(c.y - reach)));
  s.y1 = std::min(height, static_cast<int>(std::ceil(c.y + reach)));
  const double norm = normal_cdf(0.5 / sigma) - normal_cdf(-0.5 / sigma);  // a centred pixel gets `peak`
  const double amp = std::sqrt(peak) / norm;
  for (int x = s.x0; x < s.x1; ++x)
    s.gx.push_back(static_cast<float>(amp * (normal_cdf((x + 1 - c.x) / sigma) - normal_cdf((x - c.x) / sigma))));
  for (int y = s.y0; y < s.y1; ++y)
    s.gy.push_back(static_cast<float>(amp * (normal_cdf((y + 1 - c.y) / sigma) - normal_cdf((y - c.y) / sigma))));
  return s;
}

// Draws a lash (a polyline of tapered thick segments) into a coverage buffer (max-composited).
void draw_stroke(cv::Mat1f& cover, const std::vector<cv::Point2d>& pts, double width, double opacity) {
  for (std::size_t i = 0; i + 1 < pts.size(); ++i) {
    const cv::Point2d a = pts[i], b = pts[i + 1];
    if (!(std::abs(a.x) < 1e6 && std::abs(a.y) < 1e6 && std::abs(b.x) < 1e6 && std::abs(b.y) < 1e6)) continue;
    const double taper0 = 1 - 0.6 * static_cast<double>(i) / static_cast<double>(pts.size() - 1);
    const double taper1 = 1 - 0.6 * static_cast<double>(i + 1) / static_cast<double>(pts.size() - 1);
    const double wmax = width * taper0;
    const double reach = wmax / 2 + 1;
    const int x0 = std::max(0, static_cast<int>(std::floor(std::min(a.x, b.x) - reach)));
    const int x1 = std::min(cover.cols, static_cast<int>(std::ceil(std::max(a.x, b.x) + reach)));
    const int y0 = std::max(0, static_cast<int>(std::floor(std::min(a.y, b.y) - reach)));
    const int y1 = std::min(cover.rows, static_cast<int>(std::ceil(std::max(a.y, b.y) + reach)));
    const cv::Point2d ab = b - a;
    const double l2 = ab.dot(ab) + 1e-300;
    const double reach2 = reach * reach;
    for (int y = y0; y < y1; ++y) {
      // The columns this row can touch: where the segment is within `reach` of the row.
      int xa = x0, xb = x1;
      if (std::abs(ab.y) > 1e-9) {
        double t0 = (y + 0.5 - reach - a.y) / ab.y, t1 = (y + 0.5 + reach - a.y) / ab.y;
        if (t0 > t1) std::swap(t0, t1);
        t0 = std::clamp(t0, 0.0, 1.0);
        t1 = std::clamp(t1, 0.0, 1.0);
        const double xs0 = a.x + ab.x * t0, xs1 = a.x + ab.x * t1;
        xa = std::max(x0, static_cast<int>(std::floor(std::min(xs0, xs1) - reach)));
        xb = std::min(x1, static_cast<int>(std::ceil(std::max(xs0, xs1) + reach)));
      }
      float* row = cover.ptr<float>(y);
      for (int x = xa; x < xb; ++x) {
        const cv::Point2d p(x + 0.5 - a.x, y + 0.5 - a.y);
        const double tt = std::clamp(p.dot(ab) / l2, 0.0, 1.0);
        const double dx = p.x - tt * ab.x, dy = p.y - tt * ab.y;
        const double d2 = dx * dx + dy * dy;
        if (d2 >= reach2) continue;
        const double dist = std::sqrt(d2);
        const double w = width * (taper0 + (taper1 - taper0) * tt);
        // Box-filtered coverage of a line of width w (thin lines: fainter, not thicker).
        const double c = std::clamp(0.5 + w / 2 - dist, 0.0, std::min(1.0, w)) * opacity;
        row[x] = std::max(row[x], static_cast<float>(c));
      }
    }
  }
}

cv::Mat1f disc_kernel(double radius) {
  const int r = static_cast<int>(std::ceil(radius + 0.5));
  cv::Mat1f k(2 * r + 1, 2 * r + 1);
  double sum = 0;
  for (int y = -r; y <= r; ++y)
    for (int x = -r; x <= r; ++x) {
      const double w = clamp01(radius + 0.5 - std::hypot(x, y));
      k(y + r, x + r) = static_cast<float>(w);
      sum += w;
    }
  k *= 1.0 / sum;
  return k;
}

cv::Mat1f line_kernel(double length, double angle_deg) {
  const double half = length / 2;
  const int r = static_cast<int>(std::ceil(half + 1));
  cv::Mat1f k(2 * r + 1, 2 * r + 1, 0.0f);
  const double c = std::cos(angle_deg * kDeg), s = std::sin(angle_deg * kDeg);
  const int n = std::max(2, static_cast<int>(std::ceil(length * 8)));
  for (int i = 0; i < n; ++i) {  // bilinear splats of points evenly along the segment
    const double t = -half + length * (i + 0.5) / n;
    const double x = r + t * c, y = r + t * s;
    const int ix = static_cast<int>(std::floor(x)), iy = static_cast<int>(std::floor(y));
    const double fx = x - ix, fy = y - iy;
    k(iy, ix) += static_cast<float>((1 - fx) * (1 - fy));
    k(iy, ix + 1) += static_cast<float>(fx * (1 - fy));
    k(iy + 1, ix) += static_cast<float>((1 - fx) * fy);
    k(iy + 1, ix + 1) += static_cast<float>(fx * fy);
  }
  k *= 1.0 / cv::sum(k)[0];
  return k;
}

// Glints: every reflection on the corneal cap is drawn (masked by the lids per pixel); the
// truth lists those whose centre is inside the image and the lid opening.
std::vector<GlintSplat> glint_splats(const std::vector<GlintGeom>& glints, int width, int height) {
  const double sigma = std::clamp(std::sqrt(static_cast<double>(width) * height / (320.0 * 240.0)), 0.8, 2.5);
  std::vector<GlintSplat> splats;
  for (const GlintGeom& g : glints)
    if (g.on_cap) {
      GlintSplat s = make_splat(g.image, sigma, 700.0, width, height);
      if (s.x0 < s.x1 && s.y0 < s.y1) splats.push_back(std::move(s));
    }
  return splats;
}

// Per-frame constants of the pixel loop. The frame's geometry is small and copied; the look's
// textures are pointed to.
struct Shading {
  int width = 0, height = 0;
  std::size_t w = 0, h = 0;
  Camera cam;
  Lids lids;
  Conic pc, ic;      // pupil, iris
  cv::Matx33d hinv;  // image -> pupil plane (mm)
  struct {
    double skin = 0, sclera = 0, pupil = 0, lash = 0, iris_inner = 0;  // grey levels
    const float* iris = nullptr;                                      // Look::kRho rows of Look::kTheta
    const float *wave_cx = nullptr, *wave_sx = nullptr, *wave_cy = nullptr, *wave_sy = nullptr;
    std::size_t nw = 0;  // skin waves
  } look;
  bool iris_on = false;
  double ix0 = 0, ix1 = 0, iy0 = 0, iy1 = 0;  // the iris's bounding box, 2 px wider
  double px0 = 0, px1 = 0, py0 = 0, py1 = 0;  // the pupil's
  double pupil_r = 0;                         // mm
  double flat0 = 0, flat1 = 0;                // mm past the pupil: the iris is flat, then fades into its texture
  double rho_scale = 0, theta_scale = 0;      // pupil-plane polar coordinates -> iris texture bins
  double ox = 0, oy = 0, oz = 0, o2 = 0, rb2 = 0;  // camera -> eyeball centre in camera axes; its |.|^2; radius^2
  double lash_line_w = 0, lower_line_w = 0, crease_w = 0, socket_w = 0, shadow_w = 0;  // pixels
  double inv_half = 0;
  double band = 0, band2 = 0;  // margin features lie within this
  double crease0 = 0, crease1 = 0;
};

// What every pixel of row y shares.
struct RowShading {
  int y = 0;
  double py = 0, yn = 0, dy = 0;
  float cy[8]{}, sy[8]{};  // the skin waves' factors for this row
  std::array<const GlintSplat*, 8> active{};  // the glints that reach this row
  std::size_t n_active = 0;
  bool in_iris = false, in_pupil = false;
};

RowShading row_shading(const Shading& c, const std::vector<GlintSplat>& splats, int y) {
  RowShading r;
  r.y = y;
  r.py = y + 0.5;
  r.yn = (r.py - c.cam.cy) / c.cam.f;
  r.dy = r.py - c.lids.mid.y;
  for (std::size_t k = 0; k < c.look.nw; ++k) {
    r.cy[k] = c.look.wave_cy[k * c.h + static_cast<std::size_t>(y)];
    r.sy[k] = c.look.wave_sy[k * c.h + static_cast<std::size_t>(y)];
  }
  for (const GlintSplat& s : splats)
    if (y >= s.y0 && y < s.y1 && r.n_active < r.active.size()) r.active[r.n_active++] = &s;
  r.in_iris = c.iris_on && r.py >= c.iy0 && r.py <= c.iy1;
  r.in_pupil = c.pc.valid && r.py >= c.py0 && r.py <= c.py1;
  return r;
}

// A pixel's place in the lid frame (s, hh) and its distances inside the upper and lower margins.
struct LidDistances {
  double s, hh;
  double raw_u, raw_l;  // along n
  double du, dl;        // perpendicular to the margin within `band` of it, else raw
};

// Distances from the lid margins: vertical (along n) everywhere, made perpendicular only
// near the margins, where the coverage and the margin lines need them.
LidDistances lid_distances(const Shading& c, double dx, double dy) {
  const Lids& lids = c.lids;
  const double s = (dx * lids.t.x + dy * lids.t.y) * c.inv_half;
  const double hh = dx * lids.n.x + dy * lids.n.y;
  const double omsq = 1 - s * s;
  const double raw_u = hh - omsq * (lids.u0 + lids.u1 * s), raw_l = omsq * (lids.l0 + lids.l1 * s) - hh;
  double du = raw_u, dl = raw_l;
  const double su = Lids::slope(lids.u0, lids.u1, s) * c.inv_half, sl = Lids::slope(lids.l0, lids.l1, s) * c.inv_half;
  if (raw_u * raw_u < c.band2 * (1 + su * su)) du = raw_u / std::sqrt(1 + su * su);
  if (raw_l * raw_l < c.band2 * (1 + sl * sl)) dl = raw_l / std::sqrt(1 + sl * sl);
  return {s, hh, raw_u, raw_l, du, dl};
}

// The skin's soft waves at pixel x of the row: sum of amp cos(kx x + phi + ky y), separable per wave.
double skin_wave(const Shading& c, const RowShading& r, int x) {
  double wave = 0;
  for (std::size_t k = 0; k < c.look.nw; ++k)
    wave += static_cast<double>(c.look.wave_cx[k * c.w + static_cast<std::size_t>(x)] * r.cy[k] -
                                c.look.wave_sx[k * c.w + static_cast<std::size_t>(x)] * r.sy[k]);
  return wave;
}

// Skin: base level, soft waves, socket shading near the opening, the lash line along the
// upper margin, a fainter line along the lower margin and the upper-lid crease.
double skin_level(const Shading& c, const LidDistances& ld, double wave, double corner) {
  double skin = c.look.skin + wave;
  const double outside = std::max(-ld.raw_u, -ld.raw_l);
  if (outside > 0) {
    const double q = 1 + outside / c.socket_w;
    skin *= 1 - 0.12 / (q * q);
  }
  const double crease_d = (ld.hh - Lids::curve(c.crease0, c.crease1, ld.s)) / c.crease_w;
  if (std::abs(crease_d) < 3.5) skin *= 1 - 0.14 * c.lids.open * corner * std::exp(-crease_d * crease_d);
  if (ld.du > -c.band && ld.du < 1.5) {  // above the upper margin: the lash line
    const double xu = -ld.du;
    const double mu = xu < 0.5 * c.lash_line_w ? 1.0 : bump((xu - 0.5 * c.lash_line_w) / (0.5 * c.lash_line_w));
    skin += (c.look.lash - skin) * 0.92 * mu * corner;
  }
  if (ld.dl > -c.band && ld.dl < 1.5) {  // below the lower margin
    const double xl = -ld.dl;
    const double ml = xl < 0.3 * c.lower_line_w ? 1.0 : bump((xl - 0.3 * c.lower_line_w) / (0.7 * c.lower_line_w));
    skin += (95.0 - skin) * 0.5 * ml * corner;
  }
  return skin;
}

}  // namespace

// render()'s stages that read the instance's Look (a private type, hence members); the others are
// file-local functions. Their order in render() is the order of the image effects.
struct SyntheticEye::RenderStages {
  static Shading shading(const Frame& fr, const Look& look, const SyntheticEyeOptions& o, double ppm);
  static cv::Mat1f shade_pixels(const Shading& c, const std::vector<GlintSplat>& splats);
  static double eye_level(const Shading& c, const RowShading& r, const LidDistances& ld, int x, double px,
                          double wave);
  static double iris_level(const Shading& c, double px, double py);
  static void draw_eyelashes(cv::Mat1f& img, const Lids& lids, const Look& look, double ppm);
  static void add_spectacle_reflections(cv::Mat1f& img, const Look& look);
};

Shading SyntheticEye::RenderStages::shading(const Frame& fr, const Look& look, const SyntheticEyeOptions& o,
                                            double ppm) {
  Shading c;
  c.width = o.width;
  c.height = o.height;
  c.w = static_cast<std::size_t>(c.width);
  c.h = static_cast<std::size_t>(c.height);
  c.cam = fr.cam;
  c.lids = fr.lids;
  c.pc = fr.pupil;
  c.ic = fr.iris;
  c.hinv = fr.hinv;
  c.look.skin = look.skin;
  c.look.sclera = look.sclera;
  c.look.pupil = look.pupil;
  c.look.lash = look.lash;
  c.look.iris_inner = look.iris_inner;
  c.look.iris = look.iris.data();
  c.look.wave_cx = look.wave_cx.data();
  c.look.wave_sx = look.wave_sx.data();
  c.look.wave_cy = look.wave_cy.data();
  c.look.wave_sy = look.wave_sy.data();
  c.look.nw = look.waves.size();

  const Conic& pc = fr.pupil;
  const Conic& ic = fr.iris;
  c.iris_on = ic.valid;
  c.ix0 = ic.c.x - ic.half_w - 2;
  c.ix1 = ic.c.x + ic.half_w + 2;
  c.iy0 = ic.c.y - ic.half_h - 2;
  c.iy1 = ic.c.y + ic.half_h + 2;
  c.px0 = pc.c.x - pc.half_w - 2;
  c.px1 = pc.c.x + pc.half_w + 2;
  c.py0 = pc.c.y - pc.half_h - 2;
  c.py1 = pc.c.y + pc.half_h + 2;
  const double iris_r = o.eye.iris_radius_mm;
  c.pupil_r = fr.pupil_r;
  // The iris is flat for a few pixels outside the pupil so the pupil edge has the same contrast
  // all round (an unbiased edge for centre measurements), then fades into its texture.
  c.flat0 = std::max(0.15, 2.5 / ppm);
  c.flat1 = c.flat0 + std::max(0.3, 3.0 / ppm);
  c.rho_scale = (Look::kRho - 1) / std::max(iris_r - c.pupil_r, 1e-6);
  c.theta_scale = Look::kTheta / (2 * kPi);
  // Sclera shading: cosine of incidence on the eyeball sphere from the ray's distance to its centre.
  const V3 oc = -fr.cam.pos;  // camera -> eyeball centre
  c.ox = oc.dot(fr.cam.right);
  c.oy = oc.dot(fr.cam.down);
  c.oz = oc.dot(fr.cam.fwd);
  c.o2 = oc.dot(oc);
  c.rb2 = o.eye.eyeball_radius_mm * o.eye.eyeball_radius_mm;
  c.lash_line_w = std::max(1.2, 0.22 * ppm);
  c.lower_line_w = std::max(0.8, 0.12 * ppm);
  c.crease_w = std::max(1.5, 0.9 * ppm);
  c.socket_w = std::max(2.0, 2.0 * ppm);
  c.shadow_w = std::max(0.8, 0.5 * ppm);
  c.inv_half = 1.0 / fr.lids.half;
  c.band = c.lash_line_w + 2.0;
  c.band2 = c.band * c.band;
  c.crease0 = fr.lids.uo0 * 1.6;
  c.crease1 = fr.lids.uo1 * 1.6;
  return c;
}

// Skin, eye and glints pixel by pixel, the eye blended over the skin by the pixel's coverage of the
// lid opening.
cv::Mat1f SyntheticEye::RenderStages::shade_pixels(const Shading& c, const std::vector<GlintSplat>& splats) {
  cv::Mat1f img(c.height, c.width);
  for (int y = 0; y < c.height; ++y) {
    float* row = img.ptr<float>(y);
    const RowShading r = row_shading(c, splats, y);
    for (int x = 0; x < c.width; ++x) {
      const double px = x + 0.5;
      const LidDistances ld = lid_distances(c, px - c.lids.mid.x, r.dy);
      const double open = opening_coverage(ld.du, ld.dl);
      const double corner = clamp01((1.06 - std::abs(ld.s)) / 0.12);  // lid-margin features fade at the corners
      const double wave = skin_wave(c, r, x);
      const double skin = skin_level(c, ld, wave, corner);
      double value = skin;
      if (open > 0) {
        const double eye = eye_level(c, r, ld, x, px, wave);
        value = skin + (eye - skin) * open;
      }
      row[x] = static_cast<float>(value);
    }
  }
  return img;
}

// The eye in the lid opening at pixel (px, r.py): the sclera shaded by the cosine of incidence, the
// iris and the pupil by their area coverage, the upper lid's shadow and the glints.
double SyntheticEye::RenderStages::eye_level(const Shading& c, const RowShading& r, const LidDistances& ld, int x,
                                             double px, double wave) {
  const double py = r.py;
  const double xn = (px - c.cam.cx) / c.cam.f;
  const double od = c.ox * xn + c.oy * r.yn + c.oz;
  const double dist2 = c.o2 - od * od / (xn * xn + r.yn * r.yn + 1);
  const double cosi = std::sqrt(std::max(0.0, 1 - dist2 / c.rb2));
  double eye = c.look.sclera * (0.6 + 0.4 * cosi) + 0.3 * wave;
  if (r.in_iris && px >= c.ix0 && px <= c.ix1) {
    const double ai = c.ic.coverage(px, py);
    if (ai > 0) {
      double ap = 0;
      if (r.in_pupil && px >= c.px0 && px <= c.px1) ap = std::min(c.pc.coverage(px, py), ai);
      double iris_v = c.look.iris_inner;
      if (ai - ap > 0) iris_v = iris_level(c, px, py);
      eye = eye * (1 - ai) + iris_v * (ai - ap) + c.look.pupil * ap;
    }
  }
  const double shadow_x = std::max(ld.raw_u, 0.0) / c.shadow_w;
  if (shadow_x < 8) eye *= 1 - 0.3 * std::exp(-shadow_x);  // the upper lid's shadow
  for (std::size_t k = 0; k < r.n_active; ++k) {
    const GlintSplat& g = *r.active[k];
    if (x >= g.x0 && x < g.x1)
      eye += static_cast<double>(g.gx[static_cast<std::size_t>(x - g.x0)] * g.gy[static_cast<std::size_t>(r.y - g.y0)]);
  }
  return eye;
}

// The iris at pixel (px, py): the pixel mapped onto the pupil plane (hinv), its polar coordinates
// looked up bilinearly in the look's iris texture, faded in from iris_inner past the flat ring.
double SyntheticEye::RenderStages::iris_level(const Shading& c, double px, double py) {
  double iris_v = c.look.iris_inner;
  const double qa = c.hinv(0, 0) * px + c.hinv(0, 1) * py + c.hinv(0, 2);
  const double qb = c.hinv(1, 0) * px + c.hinv(1, 1) * py + c.hinv(1, 2);
  const double qw = c.hinv(2, 0) * px + c.hinv(2, 1) * py + c.hinv(2, 2);
  const double a = qa / qw, b = qb / qw;
  const double rho = std::sqrt(a * a + b * b);
  const double blend = smoothstep(c.flat0, c.flat1, rho - c.pupil_r);
  if (blend > 0 && std::isfinite(rho)) {
    const double tr = std::clamp((rho - c.pupil_r) * c.rho_scale, 0.0, Look::kRho - 1.0);
    double tt = (fast_atan2(b, a) + kPi) * c.theta_scale;
    const int r0 = std::min(static_cast<int>(tr), Look::kRho - 2);
    int t0 = static_cast<int>(tt);
    const double fr_r = tr - r0, fr_t = tt - t0;
    t0 %= Look::kTheta;
    const int t1 = (t0 + 1) % Look::kTheta;
    const float* r0p = &c.look.iris[static_cast<std::size_t>(r0 * Look::kTheta)];
    const float* r1p = r0p + Look::kTheta;
    const double tex = (1 - fr_r) * ((1 - fr_t) * static_cast<double>(r0p[t0]) + fr_t * static_cast<double>(r0p[t1])) +
                       fr_r * ((1 - fr_t) * static_cast<double>(r1p[t0]) + fr_t * static_cast<double>(r1p[t1]));
    iris_v += (tex - c.look.iris_inner) * blend;
  }
  return iris_v;
}

// Eyelashes over everything (they are in front of the eye), darkening towards their level.
void SyntheticEye::RenderStages::draw_eyelashes(cv::Mat1f& img, const Lids& lids, const Look& look, double ppm) {
  const int width = img.cols, height = img.rows;
  cv::Mat1f cover(height, width, 0.0f);
  std::vector<cv::Point2d> pts(8);
  for (const Look::Lash& l : look.lashes) {
    const double hb = Lids::curve(lids.u0, lids.u1, l.s);
    const cv::Point2d base = lids.point(l.s, hb);
    // Direction: image "down" of the lid frame, turned towards the corners.
    const double ct = std::cos(l.tilt), st = std::sin(l.tilt);
    const cv::Point2d d0 = lids.n * ct + lids.t * st;
    const double cc = std::cos(l.tilt + l.curl), sc = std::sin(l.tilt + l.curl);
    const cv::Point2d d1 = lids.n * cc + lids.t * sc;
    const double length = l.length_mm * ppm;
    const cv::Point2d p1 = base + d0 * (0.55 * length), p2 = p1 + d1 * (0.55 * length);
    for (std::size_t i = 0; i < pts.size(); ++i) {  // quadratic Bezier
      const double t = static_cast<double>(i) / static_cast<double>(pts.size() - 1);
      pts[i] = base * ((1 - t) * (1 - t)) + p1 * (2 * t * (1 - t)) + p2 * (t * t);
    }
    draw_stroke(cover, pts, std::max(0.7, l.width_mm * ppm), l.opacity);
  }
  const float level = static_cast<float>(look.lash);
  for (int y = 0; y < height; ++y) {
    float* row = img.ptr<float>(y);
    const float* c = cover.ptr<float>(y);
    for (int x = 0; x < width; ++x)
      if (c[x] > 0) row[x] += (std::min(row[x], level) - row[x]) * c[x];
  }
}

// Spectacle reflections: soft, flat-topped, semi-transparent (screen blend).
void SyntheticEye::RenderStages::add_spectacle_reflections(cv::Mat1f& img, const Look& look) {
  const int width = img.cols, height = img.rows;
  for (const Look::Reflection& r : look.reflections) {
    const double ca = std::cos(r.angle), sa = std::sin(r.angle);
    const double reach = std::max(r.a, r.b) * 1.6 + 1;
    const int x0 = std::max(0, static_cast<int>(r.centre.x - reach));
    const int x1 = std::min(width, static_cast<int>(r.centre.x + reach) + 1);
    const int y0 = std::max(0, static_cast<int>(r.centre.y - reach));
    const int y1 = std::min(height, static_cast<int>(r.centre.y + reach) + 1);
    for (int y = y0; y < y1; ++y) {
      float* row = img.ptr<float>(y);
      for (int x = x0; x < x1; ++x) {
        const double ex = x + 0.5 - r.centre.x, ey = y + 0.5 - r.centre.y;
        const double u = (ex * ca + ey * sa) / r.a, v = (-ex * sa + ey * ca) / r.b;
        const double q2 = u * u + v * v;
        if (q2 > 2.6) continue;
        const double a = r.strength * std::exp(-q2 * q2);
        const double val = static_cast<double>(row[x]);
        row[x] = static_cast<float>(val + (255.0 - val) * a);
      }
    }
  }
}

namespace {

// Uneven illumination: a tilted gradient times a vignette.
void apply_uneven_illumination(cv::Mat1f& img, double g, cv::Point2d gradient_dir) {
  const int width = img.cols, height = img.rows;
  const double cx = width / 2.0, cyy = height / 2.0, rd = std::max(std::hypot(cx, cyy), 1e-9);
  for (int y = 0; y < height; ++y) {
    float* row = img.ptr<float>(y);
    const double ry = (y + 0.5 - cyy) / rd;
    for (int x = 0; x < width; ++x) {
      const double rx = (x + 0.5 - cx) / rd;
      const double tilt = 1 + 0.5 * g * (rx * gradient_dir.x + ry * gradient_dir.y);
      const double vignette = 1 - 0.45 * g * (rx * rx + ry * ry);
      row[x] = static_cast<float>(static_cast<double>(row[x]) * std::max(0.0, tilt * vignette));
    }
  }
}

// Optics: defocus (disc), then motion (line).
void apply_optics(cv::Mat1f& img, const SyntheticEyeOptions& o) {
  if (o.defocus_px >= 0.3) cv::filter2D(img, img, CV_32F, disc_kernel(o.defocus_px), {-1, -1}, 0, cv::BORDER_REPLICATE);
  if (o.motion_blur_px >= 0.5)
    cv::filter2D(img, img, CV_32F, line_kernel(o.motion_blur_px, o.motion_blur_angle_deg), {-1, -1}, 0,
                 cv::BORDER_REPLICATE);
}

// Sensor: Gaussian noise, rounding, clipping. The noise comes from its own generator, seeded by the
// frame's one draw from the instance's, 16 bits a pixel in row-major order.
cv::Mat sensor_readout(const cv::Mat1f& img, double noise_sigma, std::uint64_t noise_seed) {
  const int width = img.cols, height = img.rows;
  cv::Mat out(height, width, CV_8U);
  const auto& table = normal_table();
  SplitMix noise{noise_seed};
  const float ns = static_cast<float>(noise_sigma);
  std::uint64_t bits = 0;
  int left = 0;
  for (int y = 0; y < height; ++y) {
    const float* row = img.ptr<float>(y);
    std::uint8_t* dst = out.ptr<std::uint8_t>(y);
    for (int x = 0; x < width; ++x) {
      float v = row[x];
      if (ns > 0) {
        if (left == 0) {
          bits = noise.next();
          left = 4;
        }
        v += ns * table[static_cast<std::size_t>(bits & 0xFFFFu)];
        bits >>= 16;
        --left;
      }
      v = std::floor(v + 0.5f);
      dst[x] = static_cast<std::uint8_t>(std::clamp(v, 0.0f, 255.0f));
    }
  }
  return out;
}

}  // namespace

cv::Mat SyntheticEye::render(double yaw_deg, double pitch_deg, double openness, EyeTruth* truth) {
  const Frame fr = frame(yaw_deg, pitch_deg, openness);
  const std::uint64_t noise_seed = rng_();  // one draw per frame, whatever the options
  const Look& look = *look_;
  const SyntheticEyeOptions& o = options_;
  const double ppm = std::max(fr.px_per_mm, 1e-3);

  const std::vector<GlintSplat> splats = glint_splats(fr.glints, o.width, o.height);
  cv::Mat1f img = RenderStages::shade_pixels(RenderStages::shading(fr, look, o, ppm), splats);
  if (o.eyelashes && !look.lashes.empty()) RenderStages::draw_eyelashes(img, fr.lids, look, ppm);
  if (o.illumination_gradient > 0) apply_uneven_illumination(img, o.illumination_gradient, look.gradient_dir);
  if (o.glasses_reflection) RenderStages::add_spectacle_reflections(img, look);
  apply_optics(img, o);
  cv::Mat out = sensor_readout(img, o.noise_sigma, noise_seed);
  if (truth) *truth = fr.truth;
  return out;
}

}  // namespace fovea::trackerd::eye
