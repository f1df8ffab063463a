// SPDX-License-Identifier: Apache-2.0
#pragma once
// Labelled gaze for classifier tests and benchmarks: the synthetic source's samples in degrees,
// with its ground truth (it knows which movement it is making) as the reference labels.
#include <cstdint>
#include <vector>

#include "classify/classifier.h"
#include "sim/synthetic_gaze.h"

namespace fovea::trackerd::classify {

struct LabelledGaze {
  std::vector<Sample> samples;
  std::vector<Label> truth;
};

inline Label truth_label(protocol::EyeMovement m) {
  switch (m) {
    case protocol::EyeMovement::Fixation: return Label::Fixation;
    case protocol::EyeMovement::Saccade: return Label::Saccade;
    case protocol::EyeMovement::Pursuit: return Label::Pursuit;
    case protocol::EyeMovement::Blink: return Label::Blink;
    case protocol::EyeMovement::Unknown: return Label::Unknown;
  }
  return Label::Unknown;
}

// The generator with what the plain model leaves out (issue 25; each in SyntheticGazeOptions):
// microsaccades at 1.5/s of fixation, pursuit with catch-up saccades, post-saccadic oscillations,
// blinks with their eye movement and tracked lid movement.
inline SyntheticGazeOptions realistic_gaze_options(double rate_hz, std::uint64_t seed) {
  SyntheticGazeOptions o;
  o.rate_hz = rate_hz;
  o.seed = seed;
  o.microsaccades_per_s = 1.5;
  o.catch_up_saccades = true;
  o.post_saccadic_oscillations = true;
  o.blink_eye_movements = true;
  return o;
}

// The truth is the generator's movement state, or the pupil's own motion where there is one
// (last_sample_pupil_motion(): the saccade's tail, the PSO).
inline LabelledGaze synthetic_labelled(const SyntheticGazeOptions& o, double seconds) {
  SyntheticGaze g(o);
  LabelledGaze l;
  const auto n = static_cast<std::size_t>(o.rate_hz * seconds);
  while (l.samples.size() < n) {
    const auto item = g.next();
    if (!item) break;
    const auto* s = std::get_if<protocol::GazeSample>(&*item);
    if (s == nullptr) continue;
    Sample c;
    c.t_s = static_cast<double>(s->tracker_time_ns) * 1e-9;
    c.valid = (s->flags & protocol::kGazeValid) != 0;
    c.x_deg = s->x_deg;
    c.y_deg = s->y_deg;
    l.samples.push_back(c);
    switch (g.last_sample_pupil_motion()) {
      case SyntheticGaze::PupilMotion::SaccadeTail: l.truth.push_back(Label::Saccade); break;
      case SyntheticGaze::PupilMotion::Oscillation: l.truth.push_back(Label::Pso); break;
      case SyntheticGaze::PupilMotion::None: l.truth.push_back(truth_label(s->state)); break;
    }
  }
  return l;
}

// realistic: realistic_gaze_options().
inline LabelledGaze synthetic_labelled(double rate_hz, double seconds, std::uint64_t seed, bool realistic = false) {
  SyntheticGazeOptions o;
  o.rate_hz = rate_hz;
  o.seed = seed;
  return synthetic_labelled(realistic ? realistic_gaze_options(rate_hz, seed) : o, seconds);
}

}  // namespace fovea::trackerd::classify
