// SPDX-License-Identifier: Apache-2.0
#pragma once
// Eye-movement classification of a gaze stream, online (sample by sample, as the daemon runs) and
// offline (`fovea-ctl classify`). Input positions are degrees of visual angle from the screen centre
// (display geometry and viewing distance convert pixels to degrees beforehand); output is one label
// per input sample, in order.
//
// The methods, their parameters, sources and measured accuracy are documented in trackerd/CLASSIFY.md.
#include <cstdint>
#include <optional>
#include <memory>
#include <string>
#include <vector>

#include "fovea/protocol/display_geometry.h"

namespace fovea::trackerd::classify {

enum class Label : std::uint8_t { Fixation, Saccade, Pso, Pursuit, Blink, Lost, Unknown };
const char* to_string(Label l);  // "fixation", "saccade", "pso", "pursuit", "blink", "lost", "unknown"
inline constexpr int kLabelCount = 7;

struct Sample {
  double t_s = 0;              // sample time, seconds (monotonic, not necessarily evenly spaced)
  double x_deg = 0, y_deg = 0; // gaze in degrees of visual angle from the screen centre; ignored when !valid
  bool valid = true;           // false: tracker lost the eye (NaN in the input, blink, off-screen)
  // Optional: pupil ellipse aspect ratio (minor/major) when the tracker reports it; 0 = unknown.
  // Lee 2009 §3.5.2 calls a blink when it drops below 0.7.
  double pupil_aspect = 0;
};
// Defined behaviour on bad input (no method ever throws from push/flush):
//  - t_s not finite, or not greater than the last accepted t_s (time standing still or going
//    backwards): the sample is labelled Unknown and otherwise ignored (it does not move time).
//  - valid but x_deg/y_deg not finite or beyond +-90 deg (no gaze direction): treated as a lost sample.
//  - valid but reached from the sample before faster than 1000 deg/s (a jump of over 1 deg):
//    noise, treated as a lost sample (pipeline.h, FrontendOptions::max_eye_speed_deg_s).
//  - pupil_aspect not finite or <= 0: unknown (ignored).

struct Labeled {
  std::uint64_t index = 0;  // position of the sample in the input (0-based)
  Label label = Label::Unknown;
};

// Online classification: push samples as they arrive; labels come out once final, in order, after
// a bounded delay (latency_s(): how far behind the newest sample a label may trail). flush() at the
// end of the stream finalises the rest.
//
// Latency contract: after push() of a sample whose time is T (the newest accepted time), every
// sample with t_s < T - latency_s() has been labelled. A rejected sample (bad time) is labelled as
// soon as every sample before it has been.
class OnlineClassifier {
 public:
  virtual ~OnlineClassifier() = default;
  virtual std::string name() const = 0;
  virtual double latency_s() const = 0;
  virtual void push(const Sample& s, std::vector<Labeled>& out) = 0;
  virtual void flush(std::vector<Labeled>& out) = 0;
};

struct ClassifierInfo {
  std::string name;
  std::string summary;  // one line: method, source, what it does
};
// Every method this build knows; the first is the default (the best one, by the benchmark).
const std::vector<ClassifierInfo>& classifiers();

// gbt: pursuit onsets the smoothing calls late (trees_core.h, OnsetHold). A smoothed fixation is
// doubtful where pursuit's weighted mean comes within `ratio` of fixation's; it waits up to
// `hold_s` for a pursuit of at least `min_s` to follow through doubtful fixations alone, and is
// then that pursuit's start. hold_s 0: none.
// gbt: where the post-saccadic oscillation (PSO) goes. Human coders differ: GazeCom's expert has no
// PSO class and runs the saccade into the oscillation's first part; the EyeLink coder and the Lund
// coders (Andersson et al. 2017) label it pso from where it starts. The trees learned GazeCom's;
// ivvt's rule beside them (Nystrom & Holmqvist 2010) marks the PSO and the small saccades the trees
// leave in fixations (trees_core.cpp, WithIvvtMarksCore).
enum class PsoConvention : std::uint8_t {
  Separate,  // "separate": the saccade ends as the trees end it, ivvt's PSO after it is pso, and
             // ivvt's small saccades are taken (the default: meets GazeCom's and the EyeLink set's targets)
  Onset,     // "onset": ivvt's PSO from its onset, cutting the trees' saccade short there, as the
             // EyeLink and Lund coders end saccades; small saccades taken
  None,      // "none": the trees alone, no pso label, GazeCom's coders' convention, at the trees' cost
};
const char* to_string(PsoConvention c);                       // "separate", "onset", "none"
std::optional<PsoConvention> pso_convention(const std::string& name);  // nullopt: none of those

struct PursuitHold {
  double hold_s = 0;
  double ratio = 0.3;
  double min_s = 0.02;
  friend bool operator==(const PursuitHold&, const PursuitHold&) = default;
};
// "" when usable, else what is wrong: hold_s and min_s in [0, 1] s, ratio in (0, 1].
std::string check(const PursuitHold& h);

// What a method may need besides the samples. Two read the display: the Lee 2009 preset (its
// thresholds are in normalized screen units per 60 Hz frame) and gbt (how far the gaze lies off it).
struct ClassifierOptions {
  double nominal_rate_hz = 250;  // a hint only; every method works on the sample times
  protocol::DisplayGeometry display;
  // gbt: a tree model file (bench/train_classifier.py) instead of the one built in; "" = built in.
  std::string model_path;
  // gbt: each sample's label from the model's last stage alone, neither smoothed nor with ivvt's
  // PSO (what bench/train_classifier.py checks against scikit-learn).
  bool trees_only = false;
  // gbt: how the post-saccadic oscillation is labelled (PsoConvention). The other methods find
  // their PSO as their rule does and accept only the default.
  PsoConvention pso = PsoConvention::Separate;
  // Label for analysis, not live: the whole recording is at hand, so labels may wait for as much of
  // it as helps. gbt: its offline second stage (context.h, the whole reach) instead of the online
  // one; the other methods label the same either way.
  bool offline = false;
  // gbt: > 0, the weight of pursuit in the smoothing's choice instead of the model's own
  // (trees_core.h, GbtModel::weights): above it calls pursuit sooner and more often, below less.
  double pursuit_weight = 0;
  // gbt: the pursuit-onset hold instead of the model's own (GbtModel::hold); unset: the model's.
  std::optional<PursuitHold> pursuit_hold;
};

// Throws std::invalid_argument naming the method and listing the known ones (also for a rate that
// is not finite and positive, or an invalid display).
std::unique_ptr<OnlineClassifier> make_classifier(const std::string& name, double nominal_rate_hz);
std::unique_ptr<OnlineClassifier> make_classifier(const std::string& name, const ClassifierOptions& options);

// Runs an online classifier over a whole recording: one label per sample, in order.
std::vector<Label> classify_all(const std::string& name, double nominal_rate_hz, const std::vector<Sample>& samples);
// Labels from pushing the samples one at a time, and when each became final: the time of the newest
// sample pushed when its label came out (the last sample's time for those the final flush gave).
// final_t_s - t_s is a label's latency; NaN where no sample had a finite time yet.
struct OnlineLabels {
  std::vector<Label> labels;
  std::vector<double> final_t_s;
};
OnlineLabels classify_online(const std::string& name, const ClassifierOptions& options,
                             const std::vector<Sample>& samples);
std::vector<Label> classify_all(const std::string& name, const ClassifierOptions& options,
                                const std::vector<Sample>& samples);

}  // namespace fovea::trackerd::classify
