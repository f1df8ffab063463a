// SPDX-License-Identifier: Apache-2.0
#include "classify_stage.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include <fmt/format.h>

namespace fovea::trackerd {

using protocol::EventPhase;
using protocol::EyeMovement;
using protocol::GazeEvent;
using protocol::GazeSample;

namespace {

// PSO belongs to the saccade it follows (the wire has no PSO class); lost/unknown make no event.
EyeMovement to_movement(classify::Label l) {
  switch (l) {
    case classify::Label::Fixation: return EyeMovement::Fixation;
    case classify::Label::Saccade:
    case classify::Label::Pso: return EyeMovement::Saccade;
    case classify::Label::Pursuit: return EyeMovement::Pursuit;
    case classify::Label::Blink: return EyeMovement::Blink;
    case classify::Label::Lost:
    case classify::Label::Unknown: return EyeMovement::Unknown;
  }
  return EyeMovement::Unknown;
}

double angle_deg(double ax, double ay, double bx, double by) {
  return protocol::angle_between_deg({ax, ay}, {bx, by});
}

}  // namespace

ClassifyStage::ClassifyStage(const std::string& method, double nominal_rate_hz, const protocol::DisplayGeometry& display,
                             classify::PsoConvention pso, double pursuit_weight)
    : method_(method.empty() ? classify::classifiers().front().name : method), display_(display) {
  if (method_ != "source") {
    classify::ClassifierOptions o;
    o.nominal_rate_hz = nominal_rate_hz > 0 ? nominal_rate_hz : 250;
    o.display = display;  // gbt measures how far the gaze lies off it; lee2009's thresholds are in its units
    o.pso = pso;
    o.pursuit_weight = pursuit_weight;
    classifier_ = classify::make_classifier(method_, o);
    if (pso == classify::PsoConvention::None) method_ += " without a PSO class";
    if (pso == classify::PsoConvention::Onset) method_ += " with the PSO from its onset";
    if (pursuit_weight > 0) method_ += fmt::format(" with pursuit weighed {}", pursuit_weight);
  }
}

std::string ClassifyStage::description() const {
  if (!classifier_) return "source (the source's own labels and events are passed through)";
  char buf[224];
  std::snprintf(buf, sizeof buf,
                "%s (labels final at most %.0f ms after the sample; sample state trails by up to that; provisional saccade events at once)",
                method_.c_str(), classifier_->latency_s() * 1000);
  return buf;
}

void ClassifyStage::process(const GazeItem& in, std::vector<GazeItem>& out) {
  if (!classifier_) {
    out.push_back(in);
    return;
  }
  const auto* sample = std::get_if<GazeSample>(&in);
  if (sample == nullptr) return;  // the classifier's events replace the source's
  GazeSample s = *sample;
  if (!have_origin_) {
    origin_ns_ = s.tracker_time_ns;
    have_origin_ = true;
  }
  classify::Sample cs;
  cs.t_s = static_cast<double>(s.tracker_time_ns - origin_ns_) * 1e-9;
  cs.valid = (s.flags & protocol::kGazeValid) != 0;
  cs.x_deg = s.x_deg;
  cs.y_deg = s.y_deg;
  if (cs.valid && s.angular_velocity_deg_s == 0.0f && have_prev_ && s.tracker_time_ns > prev_t_) {
    // Sources that report no velocity (HID trackers) get one from consecutive samples.
    const double v = angle_deg(prev_xd_, prev_yd_, s.x_deg, s.y_deg) / (static_cast<double>(s.tracker_time_ns - prev_t_) * 1e-9);
    if (std::isfinite(v)) s.angular_velocity_deg_s = static_cast<float>(std::min(v, 5000.0));
  }
  if (cs.valid) {
    have_prev_ = true;
    prev_xd_ = s.x_deg;
    prev_yd_ = s.y_deg;
    prev_t_ = s.tracker_time_ns;
  }
  labels_.clear();
  classifier_->push(cs, labels_);
  pending_.push_back({s});
  finalise(labels_, out);
  provisional(cs, out);
  s.state = latest_final_;
  out.insert(out.begin(), GazeItem{s});  // the sample itself goes out first, events (in the past) after
}

void ClassifyStage::provisional(const classify::Sample& cs, std::vector<GazeItem>& out) {
  // New provisional events first (they are about now), then retractions of older ones the final
  // labels have passed.
  provisional_.clear();
  detector_.push(cs, provisional_);
  for (const auto& p : provisional_) {
    check_.provisional(p);
    out.push_back(to_event(p, protocol::kEventProvisional));
  }
  if (have_final_) retract_upto(to_s(final_upto_ns_), out);
}

void ClassifyStage::retract_upto(double final_upto_s, std::vector<GazeItem>& out) {
  provisional_.clear();
  check_.final_upto(final_upto_s, provisional_);
  for (const auto& p : provisional_) out.push_back(to_event(p, protocol::kEventProvisional | protocol::kEventRetracted));
}

GazeEvent ClassifyStage::to_event(const classify::ProvisionalEvent& p, std::uint8_t flags) const {
  GazeEvent e;
  e.kind = p.kind == classify::Label::Saccade ? EyeMovement::Saccade : EyeMovement::Fixation;
  e.phase = p.phase == classify::Phase::Start ? EventPhase::Start : EventPhase::End;
  e.flags = flags;
  e.start_time_ns = to_ns(p.onset_s);
  e.duration_ns = e.phase == EventPhase::End ? std::max<std::int64_t>(0, to_ns(p.t_s) - e.start_time_ns) : 0;
  e.centroid_x_deg = static_cast<float>(p.x_deg);
  e.centroid_y_deg = static_cast<float>(p.y_deg);
  const auto norm = protocol::degrees_to_normalized(display_, {p.x_deg, p.y_deg});
  e.centroid_x = static_cast<float>(norm.x);
  e.centroid_y = static_cast<float>(norm.y);
  e.amplitude_deg = static_cast<float>(p.amplitude_deg);
  e.peak_velocity_deg_s = static_cast<float>(p.peak_deg_s);
  return e;
}

void ClassifyStage::flush(std::vector<GazeItem>& out) {
  if (!classifier_) return;
  labels_.clear();
  classifier_->flush(labels_);
  finalise(labels_, out);
  if (run_open_ && have_prev_) close_run(prev_t_, out);
  // Every label is final now: what is still unconfirmed never will be.
  retract_upto(std::numeric_limits<double>::infinity(), out);
}

void ClassifyStage::finalise(const std::vector<classify::Labeled>& labels, std::vector<GazeItem>& out) {
  for (const auto& l : labels) {
    if (pending_.empty()) break;
    const GazeSample s = pending_.front().sample;
    pending_.pop_front();
    latest_final_ = to_movement(l.label);
    take(s, latest_final_, out);
    final_upto_ns_ = s.tracker_time_ns;
    have_final_ = true;
  }
}

void ClassifyStage::take(const GazeSample& s, EyeMovement kind, std::vector<GazeItem>& out) {
  if (!run_open_ || kind != run_.kind) {
    if (run_open_) close_run(s.tracker_time_ns, out);
    run_ = Run{};
    run_.kind = kind;
    run_.start_ns = s.tracker_time_ns;
    run_open_ = true;
    if (kind != EyeMovement::Unknown) {
      confirm(kind, classify::Phase::Start, s.tracker_time_ns);
      GazeEvent e;
      e.kind = kind;
      e.phase = EventPhase::Start;
      e.start_time_ns = s.tracker_time_ns;
      e.centroid_x = s.x;
      e.centroid_y = s.y;
      e.centroid_x_deg = s.x_deg;
      e.centroid_y_deg = s.y_deg;
      out.push_back(e);
    }
  }
  if (s.flags & protocol::kGazeValid) {
    run_.sum_x += static_cast<double>(s.x);
    run_.sum_y += static_cast<double>(s.y);
    run_.sum_xd += static_cast<double>(s.x_deg);
    run_.sum_yd += static_cast<double>(s.y_deg);
    ++run_.valid;
    if (!run_.have_first) {
      run_.first_xd = s.x_deg;
      run_.first_yd = s.y_deg;
      run_.have_first = true;
    }
    run_.last_xd = s.x_deg;
    run_.last_yd = s.y_deg;
    run_.peak_velocity = std::max(run_.peak_velocity, static_cast<double>(s.angular_velocity_deg_s));
  }
}

void ClassifyStage::close_run(std::int64_t end_ns, std::vector<GazeItem>& out) {
  run_open_ = false;
  if (run_.kind == EyeMovement::Unknown) return;
  confirm(run_.kind, classify::Phase::End, end_ns);
  GazeEvent e;
  e.kind = run_.kind;
  e.phase = EventPhase::End;
  e.start_time_ns = run_.start_ns;
  e.duration_ns = std::max<std::int64_t>(0, end_ns - run_.start_ns);
  if (run_.valid > 0) {
    const double n = static_cast<double>(run_.valid);
    // Saccades report their landing point; the others the mean position.
    const bool landing = run_.kind == EyeMovement::Saccade;
    e.centroid_x_deg = static_cast<float>(landing ? run_.last_xd : run_.sum_xd / n);
    e.centroid_y_deg = static_cast<float>(landing ? run_.last_yd : run_.sum_yd / n);
    const auto norm = protocol::degrees_to_normalized(display_, {e.centroid_x_deg, e.centroid_y_deg});
    e.centroid_x = static_cast<float>(norm.x);
    e.centroid_y = static_cast<float>(norm.y);
    e.amplitude_deg = static_cast<float>(angle_deg(run_.first_xd, run_.first_yd, run_.last_xd, run_.last_yd));
    e.peak_velocity_deg_s = static_cast<float>(run_.peak_velocity);
  }
  out.push_back(e);
}

}  // namespace fovea::trackerd
