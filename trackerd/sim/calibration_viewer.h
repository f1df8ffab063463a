// SPDX-License-Identifier: Apache-2.0
#pragma once
// The synthetic viewer that follows a calibration: the eye's motion while a user does what a
// calibration asks (look at each target in turn), and a whole simulated calibration session as the
// daemon would publish it (`--source synthetic-eye --eye-script calibration:...`,
// `fovea-ctl synth-calibration`, bench_calibration).
//
// The motion (TargetFollowingMotion), per target of the schedule (calibration/include/fovea/calib/session.h):
//  - before the first target the eye looks at the screen centre;
//  - after each onset a reaction latency (uniform 180-280 ms: saccadic latency to a step target,
//    Carpenter 1988; Leigh & Zee), then a saccade towards the target. Saccade duration follows the
//    main sequence, D = 2.2 ms/deg x A + 21 ms (Carpenter 1988; the same relation as the random
//    viewer, sim/synthetic_gaze.h), with a minimum-jerk position profile
//    s(tau) = 10 tau^3 - 15 tau^4 + 6 tau^5 (Flash & Hogan 1985);
//  - primary saccades undershoot by 5-10 % of the amplitude (Becker 1989), and a corrective saccade
//    to the target follows 120-200 ms after the primary one ends;
//  - during fixation: physiological jitter, an Ornstein-Uhlenbeck drift (time constant 0.4 s)
//    plus white tremor, together `jitter_rms_deg` RMS (radial; default 0.1 deg), and occasional
//    microsaccades (Poisson, 0.5 per second by default) that bring the drift back near the point
//    fixated (main-sequence duration, amplitude = the drift displacement, ~0.1-0.3 deg);
//  - blinks every 3-6 s (uniform), 150 ms with the lids fully closed, lids closing and opening over
//    `lid_transition_s` either side (as SyntheticEyeMotion). Blinks are independent of the targets,
//    so they may fall inside collection windows (collection drops those samples);
//  - after the last target the eye goes back to the screen centre and stays there.
//  - fixation_bias_deg: a constant offset of every fixation from the point aimed at (the target,
//    or the centre), per viewer. People fixate a few tenths of a degree off a target's centre
//    (a preferred retinal locus that is not exactly the foveola's centre; calibration absorbs it).
//    Default 0: the eye lands on the target (up to jitter).
// Deterministic for the seed; frame k is at start_time_ns + round(k * 1e9 / rate_hz) like
// SyntheticEyeMotion.
#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "eye/eye_source.h"
#include "sim/synthetic_eye_frames.h"
#include "fovea/calib/session.h"
#include "fovea/protocol/display_geometry.h"
#include "fovea/protocol/messages.h"
#include "source_api/gaze_source.h"

namespace fovea::trackerd::eye {

struct TargetFollowingOptions {
  double rate_hz = 120;
  std::uint64_t seed = 1;
  protocol::DisplayGeometry display;
  std::int64_t start_time_ns = 0;      // time of frame 0 (the schedule's time 0)
  double lid_transition_s = 0.05;
  cv::Point3d head_offset_mm{0, 0, 0};  // for the truth's eye rotation (screen_to_eye_rotation with offset)
  protocol::Degrees fixation_bias_deg{0, 0};
  double reaction_min_s = 0.18, reaction_max_s = 0.28;
  double undershoot_min = 0.05, undershoot_max = 0.10;         // fraction of the primary saccade's amplitude
  double correction_delay_min_s = 0.12, correction_delay_max_s = 0.20;
  double jitter_rms_deg = 0.1;         // fixation jitter (drift + tremor), radial RMS
  double microsaccade_rate_hz = 0.5;
  double blink_interval_min_s = 3, blink_interval_max_s = 6, blink_duration_s = 0.15;
  void check() const;                  // std::invalid_argument naming the bad option
};

// A planned (macro) saccade: the primary saccades to each target, the corrective ones and the one
// back to the centre (microsaccades are not listed).
struct PlannedSaccade {
  double start_s = 0, duration_s = 0;  // from frame 0
  protocol::Degrees from, to;          // the points aimed at (without jitter)
  double amplitude_deg = 0;
  bool corrective = false;
  int target = -1;                     // index of the schedule's target; -1: back to the centre
};

class TargetFollowingMotion {
 public:
  // schedule: times relative to frame 0. Throws std::invalid_argument for bad options.
  TargetFollowingMotion(std::vector<calib::ScheduledTarget> schedule, TargetFollowingOptions options);
  SyntheticEyeFrameTruth next();
  const std::vector<PlannedSaccade>& saccades() const { return saccades_; }
  // The last planned saccade's end: from then on the eye fixates the centre.
  double settled_at_centre_s() const;

 private:
  struct Rng {
    std::uint64_t state;
    std::uint64_t next();
    double uniform();  // [0, 1)
    double uniform(double a, double b) { return a + (b - a) * uniform(); }
    double normal();
  };
  protocol::Degrees aimed(double t_s) const;  // planned position (saccades, no jitter)

  std::vector<calib::ScheduledTarget> schedule_;
  TargetFollowingOptions options_;
  std::vector<PlannedSaccade> saccades_;
  protocol::Degrees centre_;
  Rng jitter_rng_, blink_rng_;
  std::uint64_t k_ = 0;
  // Fixation jitter state (degrees, per axis) and the running microsaccade.
  double drift_x_ = 0, drift_y_ = 0;
  bool in_micro_ = false;
  double micro_start_s_ = 0, micro_dur_s_ = 0, micro_from_x_ = 0, micro_from_y_ = 0, micro_to_x_ = 0,
         micro_to_y_ = 0;
  // Blinks: [start, end) of the current or next one, fully closed inside.
  double blink_start_s_ = 0, blink_end_s_ = 0, prev_blink_end_s_ = -1e9;
};

// ---- a simulated calibration session ----------------------------------------------------------

struct CalibrationSessionOptions {
  calib::ScheduleOptions schedule;     // which targets, when (validation_points too)
  SyntheticEyeOptions eye;             // seed (viewer and look), image size, LEDs, imaging (with_hard_conditions)
  cv::Point3d head_offset_mm{0, 0, 0};
  protocol::Degrees fixation_bias_deg{0, 0};
  double rate_hz = 120;
  protocol::DisplayGeometry display;
  std::int64_t start_time_ns = 0;      // frame 0's time on the tracker clock
  double tail_s = 0.5;                 // simulated after the last target's end (the return to the centre)
  std::string classifier_method;       // "" = the daemon's default
};

struct CalibrationSession {
  std::vector<GazeItem> published;            // samples and events in the order the daemon publishes them
  std::vector<protocol::GazeSample> samples;  // the samples of `published`
  std::vector<protocol::GazeEvent> events;    // the events of `published`
  std::vector<calib::TargetWindow> targets;   // on the samples' clock (place_schedule at frame 0's time)
  std::vector<SyntheticEyeFrameTruth> truth;  // per frame, in order (the samples' times)
  double session_s = 0;                       // what the user sits through: schedule_end_s
  double factory_blink_aspect = 0;
  std::string source_description, classifier_description;
};

// Runs what `fovea-trackerd --source synthetic-eye --eye-script calibration:...` publishes:
// SyntheticEyeFrames (realtime = false, following the schedule) -> EyePipelineSource (the factory
// map, the daemon's default detector settings and the factory blink threshold; right eye) ->
// ClassifyStage (the daemon's default classifier) for schedule_end + tail_s seconds of frames.
// Throws std::invalid_argument for bad options.
CalibrationSession simulate_calibration_session(const CalibrationSessionOptions& options);

// What calibration is fitted on, from a published sample.
enum class CalibrationInput {
  PupilGlint,  // the EyeData pupil–glint vector (eye-camera pixels); valid with pupil and glint
  Screen,      // the tracker's own (factory-calibrated) gaze, screen pixels; valid with kGazeValid
};
const char* to_string(CalibrationInput input);  // "pupil-glint", "screen"
// The samples as collection sees them (calib::collect), the tracker's state mapped to RawSample's.
std::vector<calib::RawSample> raw_samples(std::span<const protocol::GazeSample> samples, CalibrationInput input,
                                          const protocol::DisplayGeometry& display, EyeSide eye = EyeSide::Right);

// "X,Y,Z" millimetres (e.g. "25,-15,40"); std::invalid_argument naming the text and the form.
cv::Point3d parse_head_offset(const std::string& text);

}  // namespace fovea::trackerd::eye
