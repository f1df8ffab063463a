// SPDX-License-Identifier: Apache-2.0
#include "dof/lens.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace fovea::render::dof {

namespace {
// d_f - F, kept > 0: a focus distance at or inside the focal length has no real image; the lens is
// then taken as focused just beyond F (a huge but finite K, and every CoC is clamped anyway).
double focus_gap(double focus_m, double focal_m) {
  const double min_gap = std::max(1e-9, 1e-6 * focal_m);
  const double gap = focus_m - focal_m;
  return gap > min_gap ? gap : min_gap;  // NaN: min_gap
}
}  // namespace

double CocModel::k_px() const {
  if (pinhole() || !std::isfinite(aperture_m) || !std::isfinite(px_per_image_m) || !(focal_length_m > 0)) return 0;
  // Focus at infinity: K -> E F / (d_f - F) -> 0 and C(d) = K |d - d_f| / d -> E F / d (see coc_px).
  if (std::isinf(focus_m)) return 0;
  const double k = aperture_m * focal_length_m / focus_gap(focus_m, focal_length_m) * px_per_image_m;
  return std::isfinite(k) ? std::min(k, max_coc_px) : max_coc_px;
}

CocModel::Terms CocModel::terms() const {
  Terms t;
  t.cap = std::max(0.0, max_coc_px);
  if (pinhole() || !std::isfinite(aperture_m) || !std::isfinite(px_per_image_m) || !(focal_length_m > 0)) return t;
  if (std::isinf(focus_m) && focus_m > 0) {
    t.form = Terms::Form::FocusAtInfinity;  // everything nearer is in front of the focal plane: R = E F / d
    t.ef_px = aperture_m * focal_length_m * px_per_image_m;
    return t;
  }
  t.form = Terms::Form::Regular;
  t.k = aperture_m * focal_length_m / focus_gap(focus_m, focal_length_m) * px_per_image_m;
  t.df = std::isfinite(focus_m) ? std::max(focus_m, 0.0) : 0.0;
  return t;
}

double CocModel::signed_coc_px(double depth_m) const {
  const Terms t = terms();
  const double cap = t.cap;
  double b = 0;
  if (t.form == Terms::Form::Zero) return 0;
  if (t.form == Terms::Form::FocusAtInfinity) {
    const double d = std::isnan(depth_m) ? std::numeric_limits<double>::infinity() : depth_m;
    b = d > 0 ? -t.ef_px / d : -cap;
  } else if (std::isnan(depth_m) || std::isinf(depth_m)) {
    b = depth_m < 0 ? -cap : t.k;  // d -> +inf: (d - d_f) / d -> 1
  } else if (depth_m <= 0) {
    b = t.df > 0 ? -cap : 0;  // at the lens: an unbounded CoC in front of the focal plane
  } else {
    b = t.k * (depth_m - t.df) / depth_m;
  }
  if (!std::isfinite(b)) b = b > 0 ? cap : -cap;
  return std::clamp(b, -cap, cap);
}

double CocModel::coc_px(double depth_m) const { return std::fabs(signed_coc_px(depth_m)); }

void CocModel::scaled_coc_px(const float* depth, std::size_t n, double scale, float* out) const {
  // A product beyond float's range is kept at its largest finite value, never +inf.
  constexpr double kMaxFinite = static_cast<double>(std::numeric_limits<float>::max());
  const auto slow = [&](float d) {
    const double v = scale * coc_px(static_cast<double>(d));
    return std::isfinite(v) ? static_cast<float>(std::clamp(v, 0.0, kMaxFinite)) : 0.0f;
  };
  if (pinhole() || !std::isfinite(aperture_m) || !std::isfinite(px_per_image_m) || !(focal_length_m > 0) ||
      !std::isfinite(focus_m) || !std::isfinite(scale)) {
    for (std::size_t i = 0; i < n; ++i) out[i] = slow(depth[i]);
    return;
  }
  // signed_coc_px's regular branch: B = K (d - d_f) / d, clamped to the cap (eq. 5.3).
  const Terms t = terms();
  const double k = t.k, df = t.df, cap = t.cap;
  if (!std::isfinite(k)) {
    for (std::size_t i = 0; i < n; ++i) out[i] = slow(depth[i]);
    return;
  }
#pragma omp simd
  for (std::size_t i = 0; i < n; ++i) {
    const double d = static_cast<double>(depth[i]);
    const bool regular = d > 0 && d <= kMaxFinite;
    const double dd = regular ? d : 1.0;
    const double v = scale * std::min(std::fabs(k * (dd - df) / dd), cap);
    out[i] = regular ? static_cast<float>(std::clamp(v, 0.0, kMaxFinite)) : 0.0f;
  }
  for (std::size_t i = 0; i < n; ++i) {
    const float d = depth[i];
    if (!(d > 0 && static_cast<double>(d) <= kMaxFinite)) out[i] = slow(d);
  }
}

double CocModel::depth_near_for_coc(double c_px) const {
  // Schedl & Wimmer eqs. 5-6: C = K (d_f - d) / d for d < d_f  =>  d = K d_f / (K + C).
  const double k = k_px();
  if (!(k > 0) || !(c_px > 0) || !std::isfinite(focus_m)) return std::isfinite(focus_m) ? focus_m : 0.0;
  return k * focus_m / (k + c_px);
}

double CocModel::depth_far_for_coc(double c_px) const {
  // Schedl & Wimmer eqs. 7-8: C = K (d - d_f) / d for d > d_f  =>  d = K d_f / (K - C), valid only
  // for C < K (eq. 8): beyond, no depth blurs that much and the layer reaches infinity.
  const double k = k_px();
  if (!std::isfinite(focus_m)) return std::numeric_limits<double>::infinity();
  if (!(k > 0) || !(c_px > 0)) return focus_m;
  if (c_px >= k) return std::numeric_limits<double>::infinity();
  return k * focus_m / (k - c_px);
}

CocModel coc_model(const Camera& camera, const protocol::DisplayGeometry& display, double focus_m,
                   CocProjection projection) {
  const Lens& lens = camera.lens;
  CocModel m;
  m.focal_length_m = lens.focal_length_m;
  m.aperture_m = lens.is_pinhole() ? 0.0 : lens.aperture_m;
  m.focus_m = std::isnan(focus_m) ? lens.focus_distance_m : focus_m;
  const double w = camera.width, h = camera.height;
  m.max_coc_px = std::max(1.0, std::hypot(w, h));
  // d_r: the lens's image distance (the eye's 24 mm), else V_f of eq. 4.2 at the current focus: a
  // camera refocuses by moving its lens, and the renderer keeps the field of view, so the sensor
  // spans the field of view at V_f. Then the Sensor projection is exactly what a thin-lens ray
  // tracer with this aperture produces: C = E |d - d_f| / (d d_f) x height / (2 tan(fov / 2)).
  double d_r = lens.image_distance_m;
  if (!(d_r > 0)) {
    const double f = lens.focal_length_m;
    d_r = std::isinf(m.focus_m) ? f : f * m.focus_m / focus_gap(m.focus_m, f);
  }
  if (!(d_r > 0) || !std::isfinite(d_r)) {
    m.px_per_image_m = 0;
    return m;
  }
  if (projection == CocProjection::Display) {
    // Lee eq. 4.4: DPI (image pixels per metre of display) x d_s / d_r.
    const double display_w_m = display.width_m, d_s = display.viewing_distance_m;
    const double dpi = display_w_m > 0 ? w / display_w_m : 0.0;
    m.px_per_image_m = dpi * d_s / d_r;
  } else {
    const double tan_half = std::tan(static_cast<double>(camera.vertical_fov_deg) * 3.14159265358979323846 / 360.0);
    m.px_per_image_m = tan_half > 0 ? h / (2.0 * d_r * tan_half) : 0.0;
  }
  if (!std::isfinite(m.px_per_image_m) || m.px_per_image_m < 0) m.px_per_image_m = 0;
  return m;
}

Lens photographic_lens(double focal_length_m, double f_number, double focus_distance_m) {
  Lens l;
  l.focal_length_m = focal_length_m;
  l.aperture_m = (f_number > 0 && std::isfinite(f_number)) ? focal_length_m / f_number : 0.0;
  l.focus_distance_m = focus_distance_m;
  return l;
}

}  // namespace fovea::render::dof
