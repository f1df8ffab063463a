// SPDX-License-Identifier: Apache-2.0
#pragma once
// The daemon's online classification stage: labels each published sample with the classifier's
// latest final label and builds GAZE_EVENT start/end messages from runs of final labels
// (centroid, duration, amplitude, peak velocity). Beside them, at once, provisional saccade onsets
// and landings (classify/provisional.h; GAZE_EVENT flag kEventProvisional) and, once the final
// labels have passed one without confirming it, its retraction (kEventRetracted). With method
// "source" it passes the source's own labels and events through (the synthetic source's ground
// truth, a recording's events).
#include <deque>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "classify/classifier.h"
#include "classify/provisional.h"
#include "fovea/protocol/display_geometry.h"
#include "source_api/gaze_source.h"

namespace fovea::trackerd {

class ClassifyStage {
 public:
  // Throws std::invalid_argument for an unknown method (listing the known ones), one that takes no
  // PSO convention but the default (classify::PsoConvention) or cannot weigh pursuit
  // (pursuit_weight > 0; 0 keeps the model's own weight).
  ClassifyStage(const std::string& method, double nominal_rate_hz, const protocol::DisplayGeometry& display,
                classify::PsoConvention pso = classify::PsoConvention::Separate, double pursuit_weight = 0);
  std::string description() const;
  bool passthrough() const { return classifier_ == nullptr; }
  // Provisional events sent, confirmed by the final labels, and retracted so far.
  const classify::ProvisionalCheck& provisional_check() const { return check_; }
  // One item from the source in; the items to publish out (in time order).
  void process(const GazeItem& in, std::vector<GazeItem>& out);
  // End of stream: finalises the remaining labels and closes the open event.
  void flush(std::vector<GazeItem>& out);

 private:
  struct Pending {
    protocol::GazeSample sample;
  };
  struct Run {
    protocol::EyeMovement kind = protocol::EyeMovement::Unknown;
    std::int64_t start_ns = 0;
    double sum_x = 0, sum_y = 0, sum_xd = 0, sum_yd = 0;
    std::size_t valid = 0;
    double first_xd = 0, first_yd = 0, last_xd = 0, last_yd = 0;
    bool have_first = false;
    double peak_velocity = 0;
  };
  void finalise(const std::vector<classify::Labeled>& labels, std::vector<GazeItem>& out);
  void take(const protocol::GazeSample& s, protocol::EyeMovement kind, std::vector<GazeItem>& out);
  void close_run(std::int64_t end_ns, std::vector<GazeItem>& out);
  void provisional(const classify::Sample& cs, std::vector<GazeItem>& out);
  // Retractions of the provisional events the final labels (known up to final_upto_s) passed.
  void retract_upto(double final_upto_s, std::vector<GazeItem>& out);
  protocol::GazeEvent to_event(const classify::ProvisionalEvent& p, std::uint8_t flags) const;
  std::int64_t to_ns(double t_s) const { return origin_ns_ + std::llround(t_s * 1e9); }
  double to_s(std::int64_t ns) const { return static_cast<double>(ns - origin_ns_) * 1e-9; }

  std::string method_;
  protocol::DisplayGeometry display_;
  std::unique_ptr<classify::OnlineClassifier> classifier_;
  std::deque<Pending> pending_;  // pushed, label not yet final
  std::vector<classify::Labeled> labels_;
  classify::ProvisionalDetector detector_;
  classify::ProvisionalCheck check_;
  std::vector<classify::ProvisionalEvent> provisional_;  // scratch
  std::int64_t origin_ns_ = 0;
  bool have_origin_ = false;
  protocol::EyeMovement latest_final_ = protocol::EyeMovement::Unknown;
  Run run_;
  bool run_open_ = false;
  bool have_prev_ = false;
  double prev_xd_ = 0, prev_yd_ = 0;
  std::int64_t prev_t_ = 0;
  std::int64_t final_upto_ns_ = 0;  // time of the newest sample with a final label
  bool have_final_ = false;
  void confirm(protocol::EyeMovement kind, classify::Phase phase, std::int64_t t_ns) {
    if (kind == protocol::EyeMovement::Saccade) check_.final_event(classify::Label::Saccade, phase, to_s(t_ns));
    if (kind == protocol::EyeMovement::Fixation) check_.final_event(classify::Label::Fixation, phase, to_s(t_ns));
  }
};

}  // namespace fovea::trackerd
