#pragma once
// Synthetic gaze: a seeded, deterministic model of a viewer looking at a screen. Fixations of
// 150-600 ms with drift, tremor and tracker noise; saccades on the main sequence (duration about
// 2.2 ms/deg + 21 ms, peak velocity saturating towards ~600 deg/s); blinks; occasional smooth
// pursuit. The source labels its own movements (ground truth) in samples and events.
#include <cstdint>
#include <deque>
#include <random>
#include <vector>

#include "source_api/gaze_source.h"

namespace fovea::trackerd {

struct SyntheticGazeOptions {
  double rate_hz = 250;
  std::uint64_t seed = 1;
  protocol::DisplayGeometry display;
  std::int64_t start_time_ns = 0;
  double noise_deg = 0.03;  // RMS tracker noise per axis (precision of a good video tracker)
};

// Main-sequence relations used by the generator (and checked by its tests).
double saccade_duration_s(double amplitude_deg);       // Carpenter 1988: 2.2 ms/deg + 21 ms
double saccade_peak_velocity(double amplitude_deg);    // 600 (1 - exp(-A / 9)) deg/s

class SyntheticGaze final : public GazeSource {
 public:
  explicit SyntheticGaze(SyntheticGazeOptions options);
  std::string description() const override;
  protocol::DisplayGeometry display() const override { return options_.display; }
  double nominal_rate_hz() const override { return options_.rate_hz; }
  std::optional<GazeItem> next() override;

 private:
  struct Vec2 {
    double x = 0, y = 0;
  };
  enum class Phase { Fixation, Saccade, Pursuit, Blink };
  struct Segment {
    Phase phase = Phase::Fixation;
    double duration_s = 0;
    Vec2 from, to;            // degrees from screen centre
    Vec2 velocity;            // pursuit, deg/s
    std::vector<double> profile;  // saccade: normalized position at 256 even steps of normalized time
  };

  void step();  // generates the next sample and any events due before it
  // step()'s stages, in the order it calls them (the order of the random draws).
  double advance_segments_to(std::int64_t t_ns);
  Vec2 true_eye_position(double t, std::int64_t t_ns, double dt);
  double track_true_eye(const Vec2& eye, double dt);
  protocol::GazeSample measured_sample(std::int64_t t_ns, const Vec2& eye, double velocity);
  void add_pupil_and_eye_cameras(protocol::GazeSample& s, const Vec2& eye, double dt);
  protocol::EyeData eye_camera_data(const Vec2& eye, double pupil_mm, double vergence_px);
  void start_segment(Segment s, std::int64_t t_ns);
  void end_segment(std::int64_t t_ns);
  Segment plan_after(const Segment& finished);
  Vec2 position_in_segment(double t_s);
  Vec2 random_target(const Vec2& from);
  bool on_screen(const Vec2& deg, double margin) const;
  protocol::GazeEvent make_event(protocol::EventPhase phase, std::int64_t t_ns) const;

  SyntheticGazeOptions options_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> gauss_{0.0, 1.0};
  std::uniform_real_distribution<double> uniform_{0.0, 1.0};
  std::deque<GazeItem> pending_;
  std::uint64_t sample_index_ = 0;

  Segment segment_;
  std::int64_t segment_start_ns_ = 0;
  Vec2 drift_;              // accumulated fixation drift
  Vec2 last_true_;          // last noise-free eye position
  bool have_last_ = false;
  Vec2 sum_pos_;            // for centroids
  std::size_t sum_count_ = 0;
  double peak_velocity_ = 0;
  double pupil_phase_ = 0;
};

}  // namespace fovea::trackerd
