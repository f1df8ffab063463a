// SPDX-License-Identifier: Apache-2.0
#pragma once
// The shared online machinery every method runs on:
//
//   push(Sample) -> [Pipeline: reject bad times] -> [Frontend: lost/blink, gap fill-in] -> [Core: the method]
//
// The front end turns raw samples into Prepared samples, in order: gaze (valid, and reached at a
// speed an eye can move), filled (a short gap bridged by linear interpolation, Olsen 2012 §2.4), or
// a loss (blink or lost, final). A core labels
// Prepared samples and emits them in order; the pipeline interleaves the samples it rejected.
// Each stage holds a sample for a bounded time (in sample time), so the whole pipeline's latency is
// the sum of the stages' bounds.
#include <cmath>
#include <deque>
#include <functional>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include "classify/classifier.h"
#include "fovea/protocol/display_geometry.h"

namespace fovea::trackerd::classify {

// Times are doubles in seconds, so a neighbour exactly 10 ms away at 1000 Hz (8 ms, 40 ms at
// 250 Hz) came out a hair nearer or further depending on where the tracker's clock started, and a
// window took it or not, and labels moved with it. So times are compared with this slack. ivvt's
// and gbt's smoothing windows (+-h around a sample, or the span h after one: ivvt's PSO and pursuit
// look-ahead) are open, a sample h away out, and nothing waits for a sample beyond them (on the
// EyeLink set ivvt's fixation+saccade kappa is 0.840 so, 0.830 with closed ones, 0.833 with edges
// at random); ivt's 20 ms velocity window spans 20 ms (edges in, as Olsen 2012 counts it), and a
// duration a run must reach or stay within (ivt's, idt's; the fill-in's 75 ms gap, a blink's 0.5 s)
// passes at exactly D. (gbt's first-stage features have their own, as the model was trained:
// features.cpp; its context's windows are closed.)
inline constexpr double kTimeSlackS = 1e-6;

struct Prepared {
  enum class Kind : std::uint8_t { Gaze, Filled, Blink, Lost };
  std::uint64_t index = 0;
  double t = 0;
  double x = 0, y = 0;  // degrees from the screen centre (Gaze, Filled)
  Kind kind = Kind::Gaze;
  bool has_gaze() const { return kind == Kind::Gaze || kind == Kind::Filled; }
};

struct FrontendOptions {
  // Gaps (time from the last valid sample to the next) up to this long are bridged by linear
  // interpolation; 0 turns fill-in off. Olsen 2012 (Tobii I-VT): 75 ms.
  double gap_fill_max_s = 0.075;
  // An unbridged loss of data counts as a blink while it is at most this old (time since the last
  // valid sample); afterwards, or with no valid sample before it, as lost. 0: never (only the pupil
  // aspect ratio calls blinks). Blinks last about 100-400 ms; we take 0.5 s as the ceiling.
  double loss_blink_max_s = 0.5;
  double blink_aspect = 0.7;  // Lee 2009 §3.5.2: pupil ellipse aspect ratio below this is a blink
  // A sample that moved faster than an eye can from the sample before it is noise, not gaze
  // (Nystrom & Holmqvist 2010 §2.3: above 1000 deg/s): it is treated as a lost sample (bridged like
  // one). The next sample is judged against it, so a tracker whose gaze steps once (a mistimed
  // sample) loses one sample, not the rest. Jumps up to min_artifact_jump_deg are never judged
  // (a 1000 Hz tracker's noise alone moves that far between samples); 0: no limit.
  double max_eye_speed_deg_s = 1000;
  double min_artifact_jump_deg = 1.0;
  // The lid's artefact around a blink: as the lid uncovers the pupil its centre moves, so a blink is
  // followed by what looks like a saccade (SR Research, EyeLink 1000 User Manual, "Blinks": the
  // parser embeds each blink in a saccade). A saccade or PSO run that begins where a blink ends is
  // labelled blink, for at most the lid's up-phase, about 200 ms (Evinger, Manning & Sibony 1991,
  // "Eyelid movements", Invest Ophthalmol Vis Sci 32:387-400); 0: off. The closing side is left
  // alone: telling a run before a blink from a saccade would hold every saccade's labels back until
  // it ends, and on the human-coded EyeLink sessions it changed no score.
  double lid_opening_max_s = 0.200;
};

// The lid-artefact rule of FrontendOptions, on the pipeline's labelled output (in order, nothing
// held back).
class BlinkEdges {
 public:
  explicit BlinkEdges(double opening_max_s) : opening_max_s_(opening_max_s) {}
  void push(const Labeled& l, double t, std::vector<Labeled>& out);

 private:
  double opening_max_s_;
  bool after_blink_ = false;      // the labels since the last blink were all saccade/PSO
  double opening_start_t_ = -1;  // time of the first of them (-1: none yet)
};

class Frontend {
 public:
  using Emit = std::function<void(const Prepared&)>;
  explicit Frontend(FrontendOptions o) : o_(o) {}
  void push(std::uint64_t index, const Sample& s, const Emit& emit);  // s.t_s already accepted
  void flush(const Emit& emit);
  double latency_s() const { return o_.gap_fill_max_s + kTimeSlackS; }  // a gap of exactly the most is held

 private:
  Prepared::Kind loss_kind(double t, bool aspect_blink, bool artifact) const;
  void release_unfilled(const Emit& emit);
  struct Held {
    Prepared p;
    bool aspect_blink = false;
    bool artifact = false;  // a gaze direction reached too fast: noise, never called a blink
  };
  bool implausible_speed(double t, double x, double y) const;
  FrontendOptions o_;
  bool have_valid_ = false;
  Prepared last_valid_;
  bool have_position_ = false;  // the last sample with a gaze direction, plausible or not
  double position_t_ = 0, position_x_ = 0, position_y_ = 0;
  std::vector<Held> held_;  // an invalid run that may still be bridged
};

// A method: labels Prepared samples, emitting (index, label) strictly in input order.
class Core {
 public:
  virtual ~Core() = default;
  virtual void push(const Prepared& p, std::vector<Labeled>& out) = 0;
  virtual void flush(std::vector<Labeled>& out) = 0;
  virtual double latency_s() const = 0;  // the core's own bound, in sample time
};

class Pipeline final : public OnlineClassifier {
 public:
  Pipeline(std::string name, FrontendOptions fo, std::unique_ptr<Core> core)
      : name_(std::move(name)), frontend_(fo), core_(std::move(core)), edges_(fo.lid_opening_max_s) {}
  std::string name() const override { return name_; }
  double latency_s() const override { return frontend_.latency_s() + core_->latency_s(); }
  void push(const Sample& s, std::vector<Labeled>& out) override;
  void flush(std::vector<Labeled>& out) override;

 private:
  void forward(std::vector<Labeled>& out);  // core output + rejected samples, in index order
  std::string name_;
  Frontend frontend_;
  std::unique_ptr<Core> core_;
  std::uint64_t next_index_ = 0;
  bool have_time_ = false;
  double last_t_ = 0;
  void emit(const Labeled& l, double t, std::vector<Labeled>& out) { edges_.push(l, t, out); }
  // Index and time of the rejected / accepted samples not yet emitted.
  std::deque<std::pair<std::uint64_t, double>> rejected_;
  std::deque<std::pair<std::uint64_t, double>> accepted_;
  std::vector<Labeled> core_out_;
  BlinkEdges edges_;
};

// --- geometry shared by the methods -------------------------------------------------------------

inline constexpr double kDegToRad = std::numbers::pi / 180.0;
inline constexpr double kRadToDeg = 180.0 / std::numbers::pi;

// Angle between two gaze directions given as per-axis angles from the screen centre (the same
// convention as protocol::normalized_to_degrees: the screen point is (tan x, tan y) * distance).
inline double angle_between_deg(double ax, double ay, double bx, double by) {
  return protocol::angle_between_deg({ax, ay}, {bx, by});
}

// A rate of change (or a small change) of the per-axis angles, (dx, dy), at the gaze direction
// (x_deg, y_deg), as the eye's rotation: its components in the tangent frame of that direction whose
// first axis points along increasing x, so that its length is the true angular speed (or angle).
// Per-axis angles overstate movements off the axes: a vertical one at 40 deg horizontal eccentricity
// reads 1 / cos 40 deg = 1.31 times too fast, which pushes pursuit over a saccade threshold.
struct TangentVector {
  double x = 0, y = 0;
};
// The unit vector of a gaze direction given as per-axis angles: (tan x, tan y, 1) normalised.
struct Direction {
  double x = 0, y = 0, z = 1;
  double dot(const Direction& o) const { return x * o.x + y * o.y + z * o.z; }
};
inline Direction direction(double x_deg, double y_deg) {
  const double tx = std::tan(x_deg * kDegToRad), ty = std::tan(y_deg * kDegToRad);
  const double l = std::sqrt(1 + tx * tx + ty * ty);
  return {tx / l, ty / l, 1 / l};
}

// The same as a linear map at one direction, for callers that apply it to many changes there.
struct TangentMap {
  double xx = 1, xy = 0, yx = 0, yy = 1;
  TangentVector operator()(double dx, double dy) const { return {xx * dx + xy * dy, yx * dx + yy * dy}; }
};
TangentMap tangent_map(double x_deg, double y_deg);
inline TangentVector tangent_vector(double x_deg, double y_deg, double dx, double dy) {
  return tangent_map(x_deg, y_deg)(dx, dy);
}

// The cores of each method (one file each).
std::unique_ptr<Core> make_ivt_core();      // ivt.cpp
std::unique_ptr<Core> make_idt_core();      // idt.cpp
std::unique_ptr<Core> make_lee_core(const protocol::DisplayGeometry& display);  // lee2009.cpp
std::unique_ptr<Core> make_ivvt_core();     // ivvt.cpp
// ivvt.cpp: ivvt's marks alone, each sample `saccade`, `pso` or `unknown` as soon as its mark is
// final (within 80 ms of the sample, not ivvt's 310): what gbt takes from ivvt (trees_core.cpp).
std::unique_ptr<Core> make_ivvt_marks_core();

}  // namespace fovea::trackerd::classify
