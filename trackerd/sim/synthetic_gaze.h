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
  // Movements real viewers make that the plain model leaves out (issue 25: classifiers fitted to it
  // did not transfer). Off by default, so the daemon's synthetic source stays as it was.
  // Microsaccades during fixation, about this many per second of fixation (Engbert & Kliegl 2003,
  // Vision Res 43:1035: 1-2/s), amplitude log-normal with median 0.3 deg within 0.1-1 deg
  // (Martinez-Conde, Macknik & Hubel 2004, Nat Rev Neurosci 5:229), on the main sequence; labelled
  // saccade, as human coders of lab recordings label them.
  double microsaccades_per_s = 0;
  // Pursuit that lags its target (gain 0.9) and catches up with saccades (de Brouwer, Yuksel,
  // Blohm, Missal & Lefevre 2002, J Neurophysiol 87:1772: catch-up saccades every few hundred ms
  // during pursuit): the eye pursues for 200-400 ms, then a saccade of the accumulated lag (plus 10 %)
  // brings it back onto the target, and pursuit goes on.
  bool catch_up_saccades = false;
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
    // Pursuit with catch-up saccades: the target's velocity, where the target is at the segment's end,
    // and how much of the pursuit is left after this segment (its catch-up saccade's too).
    Vec2 target_velocity, target_end;
    double pursuit_left_s = 0;
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
  Segment plan_saccade(const Vec2& from, const Vec2& to) const;
  Segment plan_pursuit(Segment carrier, const Vec2& from);
  bool continue_pursuit(const Segment& finished, Segment& next);
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
