// SPDX-License-Identifier: Apache-2.0
#pragma once
// Provisional online events: a saccade's onset and landing (and so the next fixation's onset) said
// as soon as the newest sample shows them, without the look-ahead the classifiers' final labels
// wait for (ivvt: ~110 ms, up to 385 ms while the eye moves slowly). The renderer acts on them at once (refocus at fixation onset, level
// changes hidden by saccadic suppression); the final labels follow, and a provisional event they do
// not confirm is retracted (ProvisionalCheck). Documented in trackerd/CLASSIFY.md, "Two speeds".
//
// The detector is a causal velocity-threshold detector (I-VT, Salvucci & Goldberg 2000) whose
// threshold adapts to the tracker's noise as the default method's does (Nystrom & Holmqvist 2010,
// onset/offset at half the peak threshold):
//  - velocity: least-squares slope over the trailing 10 ms (at least the last two samples; the
//    default method's window is 20 ms centred), so it lags the eye by about 5 ms, never by a
//    look-ahead;
//  - threshold T = max(30 deg/s, median + 6 robust SD of this velocity while the eye is quiet, over
//    the last 1 s): Nystrom & Holmqvist 2010's data-driven peak threshold (mean + 6 SD of the
//    velocities below it), with median and MAD so saccades the detector missed do not inflate it.
//    Taken from the detector's own speeds, not from the position noise's second differences as ivvt
//    does: a tracker's filter colours its noise (Niehorster, Zemblys & Holmqvist 2021), which keeps
//    the slow part a 10 ms slope sees while the second differences shrink; with EyeLink's heuristic
//    filter on synthetic gaze the second-difference threshold made 92-137 false starts a minute.
//    Until 32 quiet speeds are in: 4 sigma_v of 0.05 deg position noise;
//  - onset: two consecutive samples above T, or one above 2T; the event goes out at the second
//    (at most one sample after the crossing); its time is the last sample before the crossing below
//    T/2 (walked back at most 20 ms), its position that sample's;
//  - landing: the first sample below T/2 whose successors over the next 4 ms (at least one sample)
//    all stay below T (a post-saccadic oscillation may rise above T/2 again); at 250 Hz the end goes
//    out one sample (4 ms) after the landing sample. Saccade End and Fixation Start carry the landing
//    time and point. A saccade that has not landed after 150 ms (pursuit, drift, an artefact) is
//    dropped without an end: the final labels decide. No new onset within 40 ms of a landing (the
//    post-saccadic oscillation's longest, as ivvt's PSO window);
//  - lost samples reset it; a sample reached faster than 1000 deg/s over more than 1 deg is noise
//    and skipped (the front end's rule, pipeline.h).
#include <cstdint>
#include <deque>
#include <vector>

#include "classify/classifier.h"

namespace fovea::trackerd::classify {

enum class Phase : std::uint8_t { Start, End };

struct ProvisionalEvent {
  Label kind = Label::Saccade;  // Saccade (Start, End) or Fixation (Start)
  Phase phase = Phase::Start;
  double onset_s = 0;     // the event's onset (a saccade's onset also for its End)
  double t_s = 0;         // when it happened: onset for a Start, landing for a saccade's End
  double emitted_s = 0;   // time of the newest sample when it was known
  double x_deg = 0, y_deg = 0;  // position at onset (Start) or landing (End)
  double amplitude_deg = 0;     // End: onset to landing
  double peak_deg_s = 0;        // End: highest velocity seen
};

struct ProvisionalOptions {
  double window_s = 0.010;        // trailing velocity window
  double peak_floor_deg_s = 30;   // lowest threshold (the I-VT standard, Olsen 2012)
  double peak_k = 6;              // Nystrom & Holmqvist 2010: 6 SD of the quiet velocities
  double hold_s = 0.004;          // landing must hold this long (at least one sample)
  double max_saccade_s = 0.150;   // no landing by then: not a saccade we can call early
  double walk_back_s = 0.020;     // onset search before the crossing
  double refractory_s = 0.040;    // after a landing (ivvt's kPsoMaxS)
  double max_eye_speed_deg_s = 1000, min_artifact_jump_deg = 1.0;  // pipeline.h FrontendOptions
};

class ProvisionalDetector {
 public:
  explicit ProvisionalDetector(ProvisionalOptions o = {}) : o_(o) {}
  // Samples in time order (a sample not later than the last is ignored).
  void push(const Sample& s, std::vector<ProvisionalEvent>& out);

 private:
  struct Point {
    double t, x, y, v;
  };
  enum class State : std::uint8_t { Quiet, Rising, InSaccade, Landing, Blocked };
  void reset();
  // Speed of the newest point (the trailing window's slope) and the threshold T for it.
  void velocity(Point& newest);
  void add_quiet_speed(const Point& p);
  void advance(const Point& p, double prev_v, std::vector<ProvisionalEvent>& out);
  void start_saccade(const Point& crossing, double emitted_s, std::vector<ProvisionalEvent>& out);
  void land(double emitted_s, std::vector<ProvisionalEvent>& out);

  ProvisionalOptions o_;
  std::deque<Point> recent_;  // the last walk_back_s + window_s of gaze, newest last
  std::deque<double> speeds_, speed_t_;  // the detector's speeds while quiet, the last 1 s
  double speed_threshold_ = 0;           // their median + peak_k robust SD
  bool measured_ = false;
  std::size_t since_update_ = 0;
  State state_ = State::Quiet;
  Point crossing_{}, onset_{}, landing_{};
  double peak_ = 0;
  double threshold_ = 0;
  bool have_landing_ = false;
  double last_landing_t_ = 0;
};

// Matches provisional events against the final events of the same kind and phase, and retracts
// those the final labels do not confirm within `tolerance_s` of their time.
class ProvisionalCheck {
 public:
  explicit ProvisionalCheck(double tolerance_s = 0.050) : tolerance_s_(tolerance_s) {}
  void provisional(const ProvisionalEvent& e) { pending_.push_back(e); ++emitted_; }
  // A final event (a run of final labels starting or ending at t_s).
  void final_event(Label kind, Phase phase, double t_s);
  // The final labels are known up to t_s: pending events older than t_s - tolerance are retracted.
  void final_upto(double t_s, std::vector<ProvisionalEvent>& retracted);
  std::uint64_t emitted() const { return emitted_; }
  std::uint64_t confirmed() const { return confirmed_; }
  std::uint64_t retracted() const { return retracted_; }

 private:
  double tolerance_s_;
  std::deque<ProvisionalEvent> pending_;
  std::uint64_t emitted_ = 0, confirmed_ = 0, retracted_ = 0;
};

// Runs the detector over a recording (offline evaluation): every provisional event, in order.
std::vector<ProvisionalEvent> provisional_events(const std::vector<Sample>& samples, ProvisionalOptions o = {});

}  // namespace fovea::trackerd::classify
