// SPDX-License-Identifier: Apache-2.0
#pragma once
// A calibration session: which targets are shown where and when (the schedule), and how the raw
// samples recorded while a target was shown become calibration points (collection).
//
// The same schedule drives `fovea-calibrate run` (targets in a window), the synthetic viewer that
// follows it (`fovea-trackerd --source synthetic-eye --eye-script calibration:...`,
// `fovea-ctl synth-calibration`) and `fovea-calibrate run --headless`, so a session recorded from
// any of them is read back exactly as it was shown. calibration/CALIBRATION.md documents both.
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "fovea/calib/point.h"

namespace fovea::calib {

enum class TargetPhase { Calibrate, Validate };
const char* to_string(TargetPhase p);  // "calibrate", "validate"

struct ScheduleOptions {
  int points = 9;             // calibration targets: 5 (corners + centre), 9, 16 or 64 (square grids)
  int validation_points = 4;  // 0, 4 (quadrant centres) or 9 (3x3 at 25/50/75 %)
  double margin = 0.1;        // targets keep this fraction of the screen's width/height from each edge
  std::uint64_t seed = 1;     // order of the targets (calibration first, then validation)
  bool randomize = true;      // false: row by row, top-left first
  double lead_in_s = 1.0;     // nothing shown before the first target
  double shrink_s = 0.8;      // the target shrinks from its start size to its dwell size
  double settle_s = 0.6;      // samples before this (from onset) are not collected: eye still landing
  double duration_s = 1.6;    // the target is shown this long; samples up to its end are collected
  void check() const;         // std::invalid_argument naming the bad option
};

struct ScheduledTarget {
  int index = 0;              // position in the order shown (0-based, calibration and validation)
  TargetPhase phase = TargetPhase::Calibrate;
  Point position_px;          // screen pixels, origin top-left, y down
  double onset_s = 0;         // seconds from the session start
  double collect_from_s = 0;  // onset + settle
  double collect_to_s = 0;    // onset + duration
};

// The targets in the order shown. Deterministic for the options (own shuffle, not std::shuffle,
// so every platform shows the same order for a seed). Throws std::invalid_argument for bad options
// or a display smaller than 2x2 px.
std::vector<ScheduledTarget> make_schedule(double width_px, double height_px, const ScheduleOptions& options);
double schedule_end_s(const std::vector<ScheduledTarget>& schedule);  // last target's end

// Where a target is on the tracker's clock (as recorded beside a session).
struct TargetWindow {
  int index = 0;
  TargetPhase phase = TargetPhase::Calibrate;
  Point position_px;
  std::int64_t onset_ns = 0, collect_from_ns = 0, collect_to_ns = 0;
};
std::vector<TargetWindow> place_schedule(const std::vector<ScheduledTarget>& schedule, std::int64_t start_ns);

// The targets file beside a session recording (SESSION.targets.csv):
//   index,phase,x_px,y_px,onset_ns,collect_from_ns,collect_to_ns
// write_target_windows never replaces an existing file (std::runtime_error); read_target_windows
// names the file, line and column at fault.
void write_target_windows(const std::string& path, std::span<const TargetWindow> targets);
std::vector<TargetWindow> read_target_windows(const std::string& path);

// One raw sample as collection sees it: the calibration input (pupil–glint vector, or the
// tracker's own screen point in pixels) and what the tracker said about it.
struct RawSample {
  std::int64_t time_ns = 0;
  Point raw;
  bool valid = false;         // pupil (and glint) found / gaze valid; invalid samples are never used
  enum class State { Unknown, Fixation, Saccade, Pursuit, Blink } state = State::Unknown;
};

struct CollectOptions {
  // Samples whose tracker state is Saccade or Blink are dropped (Pursuit too: the eye is moving);
  // Unknown (no classifier, e.g. an eye camera before it is calibrated) and Fixation are kept.
  // Then, per target, samples farther from the median point than `mad_k` robust standard
  // deviations (median distance / 1.1774, the Rayleigh median; at least `min_spread` raw units) are
  // dropped as not looking at it.
  double mad_k = 3.5;
  double min_spread = 1e-6;
  std::size_t min_samples = 5;  // a target with fewer kept samples is not used (and says why)
};

struct TargetCollection {
  TargetWindow target;
  std::vector<RawSample> kept;
  std::size_t in_window = 0, invalid = 0, moving = 0, outliers = 0;
  bool used = false;
  std::string why_not;        // when !used: e.g. "3 of 96 samples usable (61 invalid, 32 moving)"
  Point median_raw;           // of the kept samples (when any)
};

// Gathers, per target, the samples inside its collection window. `samples` sorted by time.
std::vector<TargetCollection> collect(std::span<const RawSample> samples, std::span<const TargetWindow> targets,
                                      const CollectOptions& options = {});

// The kept samples of the used targets of one phase as correspondences (target px, raw).
std::vector<Correspondence> correspondences(std::span<const TargetCollection> collected, TargetPhase phase);

}  // namespace fovea::calib
