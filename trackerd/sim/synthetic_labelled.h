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

// realistic: with the movements the plain model leaves out (SyntheticGazeOptions: microsaccades at
// 1.5/s of fixation, pursuit with catch-up saccades).
inline LabelledGaze synthetic_labelled(double rate_hz, double seconds, std::uint64_t seed, bool realistic = false) {
  SyntheticGazeOptions o;
  o.rate_hz = rate_hz;
  o.seed = seed;
  if (realistic) {
    o.microsaccades_per_s = 1.5;
    o.catch_up_saccades = true;
  }
  SyntheticGaze g(o);
  LabelledGaze l;
  const auto n = static_cast<std::size_t>(rate_hz * seconds);
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
    l.truth.push_back(truth_label(s->state));
  }
  return l;
}

}  // namespace fovea::trackerd::classify
