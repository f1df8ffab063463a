// SPDX-License-Identifier: Apache-2.0
#pragma once
// `synthetic-eye`: a frame source that renders the synthetic eye (sim/synthetic_eye.h) as a camera
// would deliver it, driven by the synthetic viewer's gaze (sim/synthetic_gaze.h, without
// tracker noise) so the whole eye pipeline — detection, mapping, classification, publishing — runs
// on images with a known truth.
//
// Geometry: the eye sits on the screen centre's normal at the viewing distance; a gaze point on the
// screen (degrees from the centre, protocol convention) becomes the eye rotation that points its
// optical axis at that point (screen_to_eye_rotation). Blink phases of the viewer close the lids
// (openness 0); the lids close and reopen over `lid_transition_s` either side of each blink.
//
// Frames are paced in real time like a camera: next() blocks until a frame's due time on
// CLOCK_MONOTONIC (frame k at start + k / rate; the viewer's sample k has the same time). When
// rendering falls behind by more than two frame periods, frames are skipped (counted as dropped,
// sequence numbers jump) as a camera with a full buffer queue would.
//
// The synthetic eye's "factory calibration" is what a manufacturer would ship with a tracker,
// derived from its model rather than from a user looking at targets; it stands in for a user
// calibration (step 5) so the synthetic eye yields screen gaze out of the box:
//  - factory_map: a second-order polynomial (calib::Poly2Map) fitted from the exact pupil–glint
//    vectors SyntheticEye::project() gives for a 9x9 grid of screen points covering the whole
//    screen (corners included) to the eye rotation (yaw, pitch) that looks at each point; the
//    display geometry then gives the screen point. Fitting to the rotation rather than straight to
//    normalised screen coordinates matters: the pupil–glint vector grows roughly like the sine of
//    the rotation while screen positions grow like its tangent, an odd (cubic) difference that a
//    quadratic cannot follow: fitted to the screen, the model error is 0.57 deg mean (1.7 max) on
//    the default display; fitted to the rotation, 0.34 deg mean (1.2 max).
//  - factory_blink_aspect: the detector's blink threshold on the pupil ellipse's minor/major.
//    Lee 2009's 0.7 assumes a camera near the line of sight; this camera looks up at the eye from
//    33 deg below, where an open pupil looks as flat as 0.59 at the top corners of the screen, so
//    the threshold is set to 0.9 x the flattest open pupil over the screen (at most 0.7).
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "eye/eye_source.h"
#include "sim/synthetic_eye.h"
#include "fovea/calib/poly2.h"
#include "fovea/calib/session.h"
#include "source_api/frame_source.h"
#include "sim/synthetic_gaze.h"

namespace fovea::trackerd::eye {

struct EyeRotation {
  double yaw_deg = 0, pitch_deg = 0;
};
// The eye rotation (SyntheticEye's yaw/pitch) whose optical axis passes through the screen point
// `gaze` (degrees from the screen centre), for an eye on the centre's normal at the viewing
// distance; and back.
EyeRotation screen_to_eye_rotation(const protocol::DisplayGeometry& display, protocol::Degrees gaze);
protocol::Degrees eye_rotation_to_screen(const protocol::DisplayGeometry& display, EyeRotation rotation);

// Head offset: the eye displaced from the calibration position (on the screen centre's normal at
// the viewing distance) by `head_offset_mm` in the head frame (x right, y down, z towards the
// screen; the head is translated, not turned). The rotation that looks at the screen point `gaze`
// (degrees from the screen centre as seen from the calibration position, i.e. which screen point)
// from the displaced eye. Equal to the overload above for a zero offset.
EyeRotation screen_to_eye_rotation(const protocol::DisplayGeometry& display, protocol::Degrees gaze,
                                   cv::Point3d head_offset_mm);

// The eye options as a camera fixed to the screen sees the displaced eye (a remote tracker: the
// camera and its LEDs stay with the screen while the head moves). The synthetic eye camera is near
// the eye (|position_mm| ~ 42 mm) where a remote camera is at about the viewing distance D; the
// camera (and with it the LEDs around its lens, and its look-at point: its orientation is kept) is
// moved by -head_offset_mm * |position_mm| / D. That keeps, exactly, the direction from the eye to
// the camera and the relative change of their distance that a camera at the screen would see, so
// the eye translates in the image by the same visual angle and the glints (and the pupil–glint
// vector) change with the viewing direction and the distance as they would for the remote camera.
// Not modelled: the remote camera's own (smaller) perspective and LED spread, depth of field, and
// the spectacle reflections (fixed in the image). Identity for a zero offset. Throws
// std::invalid_argument for a non-finite offset or one beyond 250 mm in any axis.
SyntheticEyeOptions with_head_offset(SyntheticEyeOptions options, const protocol::DisplayGeometry& display,
                                     cv::Point3d head_offset_mm);

// The hard imaging conditions of --eye-hard / synth-eye --hard: strong sensor noise (sigma 10),
// 2 px motion blur, the upper lid over 30% of the pupil, spectacle reflections and a 0.4
// illumination gradient. Other options are kept.
SyntheticEyeOptions with_hard_conditions(SyntheticEyeOptions options);
bool has_hard_conditions(const SyntheticEyeOptions& options);

// The synthetic eye's factory calibration (see above): pupil–glint vector (px) -> eye rotation
// (yaw, pitch in degrees) from `grid` x `grid` screen points, corners included. Throws
// std::invalid_argument if the fit fails (degenerate eye or camera geometry).
calib::Poly2Map fit_factory_map(const SyntheticEye& eye, const protocol::DisplayGeometry& display, int grid = 9);
// The pipeline's map from a factory map: rotation -> screen degrees -> normalised.
PupilGlintMap factory_pupil_glint_map(const calib::Poly2Map& map, const protocol::DisplayGeometry& display);
// 0.9 x the smallest pupil minor/major over the screen's 9x9 grid with open lids, at most 0.7.
double factory_blink_aspect(const SyntheticEye& eye, const protocol::DisplayGeometry& display);
// Pupil size scale at the eye for this eye and camera: the pupil diameter in millimetres over its
// projected major axis in pixels, at straight-ahead gaze.
double pupil_mm_per_px(const SyntheticEye& eye);

// What one frame shows, exactly.
struct SyntheticEyeFrameTruth {
  std::int64_t time_ns = 0;
  std::uint64_t sequence = 0;
  protocol::Degrees gaze_deg;       // where the eye looks on the screen
  protocol::Normalized gaze;        // the same, normalised
  EyeRotation rotation;
  double openness = 1;              // 1 open .. 0 closed
  bool blink = false;               // inside one of the viewer's blink phases
};

// The eye's motion alone (no images): the truth of frame 0, 1, 2, ... Deterministic for a seed;
// SyntheticEyeFrames with the same rate, seed and display shows exactly this motion (its times
// offset by its start time).
class SyntheticEyeMotion {
 public:
  SyntheticEyeMotion(double rate_hz, std::uint64_t seed, const protocol::DisplayGeometry& display,
                     std::int64_t start_time_ns, double lid_transition_s = 0.05);
  SyntheticEyeFrameTruth next();

 private:
  struct Ahead {
    std::int64_t time_ns = 0;
    protocol::Degrees deg;
    protocol::Normalized norm;
    bool blink = false;
  };
  void fill(std::int64_t until_ns);

  protocol::DisplayGeometry display_;
  SyntheticGaze gaze_;
  std::int64_t lid_ns_;
  std::deque<Ahead> ahead_;
  std::int64_t last_blink_ns_ = INT64_MIN;
  std::uint64_t sequence_ = 0;
};

class TargetFollowingMotion;  // sim/calibration_viewer.h

struct SyntheticEyeFramesOptions {
  SyntheticEyeOptions eye;           // image size, seed, LEDs, imaging effects (the viewer uses eye.seed too)
  double rate_hz = 120;              // 1..1000
  protocol::DisplayGeometry display;
  // Frame 0 is due then (CLOCK_MONOTONIC); nullopt: when next() is first called (so a daemon that
  // holds the source until subscribers arrive does not start behind and drop frames).
  std::optional<std::int64_t> start_time_ns;
  bool realtime = true;              // false: deliver frames as fast as they render (tests, benchmarks)
  double lid_transition_s = 0.05;
  // Set: the viewer follows the calibration schedule make_schedule(display px, *calibration_script)
  // (sim/calibration_viewer.h, TargetFollowingMotion, seeded by eye.seed) instead of the random
  // viewer; frame 0 is the session start (schedule times are relative to it).
  std::optional<calib::ScheduleOptions> calibration_script;
  // The eye displaced from the calibration position (see with_head_offset); the factory
  // calibration stays the one fitted at the calibration position. Zero: the nominal geometry.
  cv::Point3d head_offset_mm{0, 0, 0};
  // With calibration_script: where this viewer fixates relative to a target's centre (degrees,
  // constant per viewer; people fixate a few tenths of a degree off). Default none.
  protocol::Degrees fixation_bias_deg{0, 0};
};

class SyntheticEyeFrames final : public FrameSource {
 public:
  // Throws std::invalid_argument for a rate outside 1..1000 Hz or an image smaller than 32x32.
  explicit SyntheticEyeFrames(SyntheticEyeFramesOptions options);
  ~SyntheticEyeFrames() override;

  FrameSourceStatus status() const override;
  std::optional<EyeFrame> next(int timeout_ms) override;

  const SyntheticEyeFramesOptions& options() const { return options_; }
  // Truth of the frame next() returned last (sequence and time match that frame).
  const SyntheticEyeFrameTruth& last_truth() const { return truth_; }
  const EyeTruth& last_render_truth() const { return render_truth_; }
  const calib::Poly2Map& factory_map() const { return factory_map_; }
  // The factory calibration as the eye pipeline's map.
  PupilGlintMap pupil_glint_map() const { return factory_pupil_glint_map(factory_map_, options_.display); }
  double blink_aspect() const { return blink_aspect_; }
  double mm_per_px() const { return mm_per_px_; }
  // With calibration_script: the schedule followed (times relative to frame 0); else empty.
  const std::vector<calib::ScheduledTarget>& schedule() const { return schedule_; }
  // Time of frame 0 (set by the first next() unless start_time_ns was given): with schedule(),
  // calib::place_schedule(schedule(), *origin_ns()) gives the targets on the frames' clock.
  std::optional<std::int64_t> origin_ns() const { return origin_ns_; }

 private:
  SyntheticEyeFrameTruth next_truth();

  SyntheticEyeFramesOptions options_;
  SyntheticEye eye_;  // as rendered (with the head offset); the factory calibration uses the nominal eye
  std::vector<calib::ScheduledTarget> schedule_;
  std::unique_ptr<SyntheticEyeMotion> motion_;        // the random viewer, or
  std::unique_ptr<TargetFollowingMotion> script_;     // the calibration viewer
  calib::Poly2Map factory_map_;
  double blink_aspect_ = 0.7;
  double mm_per_px_ = 0;
  std::optional<std::int64_t> origin_ns_;  // time of frame 0
  std::uint64_t index_ = 0;  // frame index of the next frame due
  SyntheticEyeFrameTruth truth_;
  EyeTruth render_truth_;

  mutable std::mutex status_mutex_;
  FrameSourceStatus status_;
};

}  // namespace fovea::trackerd::eye
