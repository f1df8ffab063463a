// SPDX-License-Identifier: Apache-2.0
#include "classify/pipeline.h"

namespace fovea::trackerd::classify {

// --- Frontend ---------------------------------------------------------------------------------

Prepared::Kind Frontend::loss_kind(double t, bool aspect_blink, bool artifact) const {
  if (aspect_blink) return Prepared::Kind::Blink;  // direct evidence: the lid covers the pupil
  if (artifact) return Prepared::Kind::Lost;       // the tracker saw something, not an eye
  if (o_.loss_blink_max_s > 0 && have_valid_ && t - last_valid_.t <= o_.loss_blink_max_s + kTimeSlackS) return Prepared::Kind::Blink;
  return Prepared::Kind::Lost;
}

void Frontend::release_unfilled(const Emit& emit) {
  for (Held& h : held_) {
    h.p.kind = loss_kind(h.p.t, h.aspect_blink, h.artifact);
    emit(h.p);
  }
  held_.clear();
}

bool Frontend::implausible_speed(double t, double x, double y) const {
  if (o_.max_eye_speed_deg_s <= 0 || !have_position_) return false;
  const double jump = std::hypot(x - position_x_, y - position_y_);
  // t > position_t_ (the pipeline accepts only increasing times); written as a product, a step in
  // a nanosecond (or in less time than a double can tell) is as implausible as it is.
  return jump > o_.min_artifact_jump_deg && jump > o_.max_eye_speed_deg_s * (t - position_t_);
}

void Frontend::push(std::uint64_t index, const Sample& s, const Emit& emit) {
  const double t = s.t_s;
  const bool aspect_blink = std::isfinite(s.pupil_aspect) && s.pupil_aspect > 0 && s.pupil_aspect < o_.blink_aspect;
  const bool direction = s.valid && !aspect_blink && std::isfinite(s.x_deg) && std::isfinite(s.y_deg) &&
                         std::abs(s.x_deg) <= 90 && std::abs(s.y_deg) <= 90;
  const bool gaze = direction && !implausible_speed(t, s.x_deg, s.y_deg);
  if (direction) {
    have_position_ = true;
    position_t_ = t, position_x_ = s.x_deg, position_y_ = s.y_deg;
  }
  if (gaze) {
    Prepared p{index, t, s.x_deg, s.y_deg, Prepared::Kind::Gaze};
    if (!held_.empty()) {
      // Held samples are only ever a run that may still be bridged (see below): bridge it if this
      // sample closes it in time, otherwise it is a loss.
      if (t - last_valid_.t <= o_.gap_fill_max_s + kTimeSlackS) {  // a gap of exactly the most is bridged
        const double span = t - last_valid_.t;
        for (Held& h : held_) {
          const double f = (h.p.t - last_valid_.t) / span;  // Olsen 2012 §2.4: linear interpolation
          h.p.x = last_valid_.x + f * (p.x - last_valid_.x);
          h.p.y = last_valid_.y + f * (p.y - last_valid_.y);
          h.p.kind = Prepared::Kind::Filled;
          emit(h.p);
        }
        held_.clear();
      } else {
        release_unfilled(emit);
      }
    }
    emit(p);
    last_valid_ = p;
    have_valid_ = true;
    return;
  }
  Held h{Prepared{index, t, 0, 0, Prepared::Kind::Lost}, aspect_blink, direction};
  const bool may_fill = have_valid_ && o_.gap_fill_max_s > 0 && !aspect_blink &&
                        t - last_valid_.t <= o_.gap_fill_max_s + kTimeSlackS;
  if (may_fill) {
    held_.push_back(h);
    return;
  }
  release_unfilled(emit);  // the run has outlived the fill-in limit (or holds a blink): a loss
  h.p.kind = loss_kind(t, aspect_blink, direction);
  emit(h.p);
}

void Frontend::flush(const Emit& emit) { release_unfilled(emit); }  // a gap at the end is never bridged

// --- Pipeline ---------------------------------------------------------------------------------

void Pipeline::push(const Sample& s, std::vector<Labeled>& out) {
  const std::uint64_t index = next_index_++;
  if (!std::isfinite(s.t_s) || (have_time_ && !(s.t_s > last_t_))) {
    rejected_.emplace_back(index, s.t_s);  // time standing still or going backwards: Unknown, ignored otherwise
  } else {
    have_time_ = true;
    last_t_ = s.t_s;
    accepted_.emplace_back(index, s.t_s);
    frontend_.push(index, s, [this](const Prepared& p) { core_->push(p, core_out_); });
  }
  forward(out);
}

void Pipeline::flush(std::vector<Labeled>& out) {
  frontend_.flush([this](const Prepared& p) { core_->push(p, core_out_); });
  core_->flush(core_out_);
  forward(out);
}

void Pipeline::forward(std::vector<Labeled>& out) {
  for (const Labeled& l : core_out_) {
    while (!rejected_.empty() && rejected_.front().first < l.index) {
      emit({rejected_.front().first, Label::Unknown}, rejected_.front().second, out);
      rejected_.pop_front();
    }
    // The core labels accepted samples in order: this one is accepted_'s first.
    const double t = !accepted_.empty() && accepted_.front().first == l.index ? accepted_.front().second : last_t_;
    emit(l, t, out);
    if (!accepted_.empty() && accepted_.front().first == l.index) accepted_.pop_front();
  }
  core_out_.clear();
  while (!rejected_.empty() && (accepted_.empty() || rejected_.front().first < accepted_.front().first)) {
    emit({rejected_.front().first, Label::Unknown}, rejected_.front().second, out);
    rejected_.pop_front();
  }
}

void BlinkEdges::push(const Labeled& l, double t, std::vector<Labeled>& out) {
  const bool movement = l.label == Label::Saccade || l.label == Label::Pso;
  if (movement && after_blink_ && opening_max_s_ > 0) {  // the lid opening
    if (opening_start_t_ < 0) opening_start_t_ = t;
    if (t - opening_start_t_ <= opening_max_s_) {
      out.push_back({l.index, Label::Blink});
      return;
    }
  }
  out.push_back(l);
  if (!movement || !after_blink_) {
    after_blink_ = l.label == Label::Blink;
    opening_start_t_ = -1;
  }
}

// The direction is u = T / L with T = (tan x, tan y, 1), L = |T|; a change dT = (sec^2 x dx,
// sec^2 y dy, 0) turns it by du = (dT - u (u . dT)) / L. In the orthonormal frame e1 = the unit
// part of (1, 0, 0) orthogonal to u, e2 = u x e1, both orthogonal to u, du's components are
// dT . e1 / L and dT . e2 / L.
TangentMap tangent_map(double x_deg, double y_deg) {
  const Direction u = direction(x_deg, y_deg);
  const double ux = u.x, uy = u.y, uz = u.z, l = 1 / uz, tx = ux * l, ty = uy * l;
  const double n1 = std::sqrt(1 - ux * ux);  // |(1, 0, 0) - u ux| > 0: |x_deg| < 90
  const double e1x = (1 - ux * ux) / n1, e1y = -ux * uy / n1;
  // e2 = u x e1 with e1z = -ux uz / n1: its x and y components.
  const double e1z = -ux * uz / n1;
  const double e2x = uy * e1z - uz * e1y, e2y = uz * e1x - ux * e1z;
  // dT = (sx dx, sy dy, 0): the map's columns are sx e1 / l, sy e2 / l (rows: e1, e2 components).
  const double sx = (1 + tx * tx) / l, sy = (1 + ty * ty) / l;
  return {sx * e1x, sy * e1y, sx * e2x, sy * e2y};
}

}  // namespace fovea::trackerd::classify
