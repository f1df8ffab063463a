// SPDX-License-Identifier: Apache-2.0
#pragma once
#include <cstddef>
// Thin-lens circle of confusion (CoC) for the depth-of-field pass.
//
//   V = F d / (d - F),  V_f = F d_f / (d_f - F)                               Lee 2009, eq. 4.2
//   R = |V - V_f| E / V = (E F / (d_f - F)) |d - d_f| / d                       Lee 2009, eq. 4.3
//   C = DPI (d_s / d_r) R                                                        Lee 2009, eq. 4.4
//   B = K (d - d_f) / d,  K = DPI (d_s / d_r) E F / (d_f - F)  (signed CoC)      Lee 2009, eq. 5.3
//   c = |A f (d - d_f)| / (d (d_f - f)),  A = f / N                              Schedl & Wimmer, eq. 1
// Schedl & Wimmer's eq. 1 is eq. 4.3 with the aperture diameter A = f / N, so one model serves both.
//
// Two ways to project R (metres on the image plane) to pixels:
// - Display (Lee eq. 4.4): the image is shown on a display of known size at distance d_s; DPI is the
//   image's pixels per metre of display, and R is scaled by d_s / d_r from the retina to the screen.
// - Sensor: the rendering camera's image plane at the image distance d_r spans the vertical field of
//   view, so pixels per metre = height / (2 d_r tan(fov / 2)). When the field of view matches what the
//   display subtends, both give the same C.
//
// Hard cases are finite by construction: a focus distance at or inside the focal length (no real
// image: the lens is taken as focused just beyond F), focus at infinity (the limit R = E F / d),
// depth 0 (CoC clamped to max_coc_px), infinite or NaN depth (the limit d -> infinity: R = E F /
// (d_f - F)), a pinhole (E = 0: C = 0 everywhere).
#include <cstdint>

#include "fovea/protocol/display_geometry.h"
#include "scene/scene.h"

namespace fovea::render::dof {

enum class CocProjection { Sensor, Display };

struct CocModel {
  double focal_length_m = 0.05;  // F
  double aperture_m = 0;         // E (0: pinhole)
  double focus_m = 2;            // d_f, view-axis distance in focus
  double px_per_image_m = 0;     // pixels per metre on the image plane: DPI d_s / d_r, or H / (2 d_r tan(fov/2))
  double max_coc_px = 1e4;       // every CoC is clamped to this diameter (the image's diagonal by default)

  // signed_coc_px's constants, for code that evaluates eq. 5.3 elsewhere (the GPU passes' shaders):
  // Zero: C = 0 (a pinhole); Regular: B = K (d - d_f) / d; FocusAtInfinity: B = -E F px / d. Depth
  // NaN or +inf: B = K (Regular) or 0; depth <= 0 or -inf: |B| = cap (Regular with d_f = 0: 0 at d = 0).
  struct Terms {
    enum class Form { Zero, Regular, FocusAtInfinity };
    Form form = Form::Zero;
    double k = 0;      // K of eq. 5.3 in pixels, unclamped (may be +inf for a focus at F)
    double df = 0;     // d_f, >= 0
    double ef_px = 0;  // E F px_per_image_m (FocusAtInfinity)
    double cap = 0;    // max_coc_px, >= 0
  };
  Terms terms() const;
  // K of eq. 5.3 in pixels: C(d) = K |d - d_f| / d. 0 for a pinhole; finite always.
  double k_px() const;
  // Unsigned CoC diameter in pixels (eqs. 4.3-4.4), in [0, max_coc_px]; NaN/inf depth: the far limit.
  double coc_px(double depth_m) const;
  // Signed CoC B (eq. 5.3): negative in front of the focal plane, positive behind; |B| <= max_coc_px.
  double signed_coc_px(double depth_m) const;
  // scale x coc_px(depth[i]) for n depths into out (NaN products as 0, beyond float's range as its
  // largest value): the scalar call's values, with the common case (finite focus, finite positive
  // depth) in a vectorisable loop.
  void scaled_coc_px(const float* depth, std::size_t n, double scale, float* out) const;
  // The depths at which the CoC diameter equals c (Schedl & Wimmer eqs. 5-9, the inverted CoC):
  // near (in front of d_f) and far (behind; +infinity when c >= the far limit K, eq. 8's bound).
  double depth_near_for_coc(double c_px) const;
  double depth_far_for_coc(double c_px) const;
  bool pinhole() const { return !(aperture_m > 0) || !(px_per_image_m > 0); }
};

// The model for a scene's lens at focus distance `focus_m` (the focus pass's result, or the lens's
// own focus distance), rendered at width x height with the camera's vertical field of view.
// Projection::Display uses the scene's display geometry (Lee eq. 4.4); Sensor the field of view.
// The image distance d_r is the lens's image_distance_m, or V_f of eq. 4.2 at focus_m when that is 0.
CocModel coc_model(const Camera& camera, const protocol::DisplayGeometry& display, double focus_m,
                   CocProjection projection);

// A photographic lens (Schedl & Wimmer): focal length F, f-number N (E = F / N; N = inf: pinhole).
Lens photographic_lens(double focal_length_m, double f_number, double focus_distance_m);

}  // namespace fovea::render::dof
