// SPDX-License-Identifier: Apache-2.0
#pragma once
// The synthetic eye's imaging geometry (sim/synthetic_eye.h), shared by its files: vectors in the
// head frame, the pinhole eye camera, ellipses in the image as conics, the lid frame, the corneal
// glints, and one frame's geometry (SyntheticEye::Frame: computed in synthetic_eye.cpp, drawn by
// synthetic_eye_render.cpp).
#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include <opencv2/core.hpp>

#include "sim/synthetic_eye.h"

namespace fovea::trackerd::eye::synthetic {

inline constexpr double kPi = std::numbers::pi;
inline constexpr double kDeg = kPi / 180.0;

using V3 = cv::Vec3d;

inline double len(const V3& a) { return std::sqrt(a.dot(a)); }
inline V3 unit(const V3& a, const V3& fallback) {
  const double n = len(a);
  return (n > 1e-300 && std::isfinite(n)) ? a / n : fallback;
}
inline V3 v3(const cv::Point3d& p) { return {p.x, p.y, p.z}; }
inline double clamp01(double x) { return std::clamp(x, 0.0, 1.0); }
inline double smoothstep(double e0, double e1, double x) {
  const double t = clamp01((x - e0) / (e1 - e0));
  return t * t * (3 - 2 * t);
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

struct GlintGeom {
  bool projected = false;  // the reflection point exists and is in front of the camera
  bool on_cap = false;     // on the camera-facing corneal cap (inside the limbus)
  bool visible = false;    // on_cap, inside the image and not behind a lid
  cv::Point2d image;
};

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

}  // namespace fovea::trackerd::eye::synthetic

namespace fovea::trackerd::eye {

// One frame's geometry: everything project() reports and render() draws.
struct SyntheticEye::Frame {
  synthetic::Camera cam;
  synthetic::V3 d, u, v, cornea, pupil_centre;
  double pupil_r = 0;
  double px_per_mm = 1;  // image scale at the pupil
  bool plane_ok = false;
  cv::Matx33d hinv;  // image -> pupil plane (mm)
  synthetic::Conic pupil, iris;
  synthetic::Lids lids;
  LedLayout leds;
  std::vector<synthetic::GlintGeom> glints;  // one per LED
  EyeTruth truth;

  // frame()'s stages, in the order it calls them; members because each fills some of the fields above.
  void place_eye(const SyntheticEyeOptions& o, double yaw, double pitch);
  cv::Matx33d map_pupil_plane();
  void project_for_pupil_radius(const synthetic::FrameSetup& s, double radius);
  void put_glint_on_pupil_edge(const synthetic::FrameSetup& s, const cv::Matx33d& hom);
  synthetic::NearestGlint glint_nearest_pupil_edge(double pupil_radius_mm) const;
  void move_led_onto_pupil_edge(const synthetic::FrameSetup& s, const cv::Matx33d& hom,
                                const synthetic::NearestGlint& best, double radius);
  void fill_truth(const synthetic::GlintContext& gctx, double yaw_deg, double pitch_deg, double openness);
};

}  // namespace fovea::trackerd::eye
