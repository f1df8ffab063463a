// SPDX-License-Identifier: Apache-2.0
#pragma once
// Synthetic gaze: a seeded, deterministic model of a viewer looking at a screen. Fixations of
// 150-600 ms with drift, tremor and tracker noise; saccades on the main sequence (duration about
// 2.2 ms/deg + 21 ms, peak velocity saturating towards ~600 deg/s); blinks; occasional smooth
// pursuit. The source labels its own movements (ground truth) in samples and events.
#include <cstdint>
#include <deque>
#include <optional>
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
  // Post-saccadic oscillations (PSO) of a pupil-based tracker: the pupil moves inside the iris, so
  // the tracked pupil centre lags, overshoots and rings where the eyeball stops (Nystrom, Hooge &
  // Holmqvist 2013, Vision Res 92:59). Bouzat, Freije, Frapiccini & Gasaneo 2018 (Phys Rev Lett
  // 120:178101, Eq. 2): the pupil is a damped oscillator in the eyeball's frame driven by the
  // eyeball's acceleration; stiffness k = 0.032 /ms^2 and damping 0.15 /ms are the example values of
  // Schweitzer & Rolfs's simulator (2022, Neuromethods 183; a 35 ms period, damping ratio 0.42).
  // The samples show the pupil; its own motion's ground truth is last_sample_pupil_motion().
  bool post_saccadic_oscillations = false;
  // Spectral slope of the tracker noise, power ~ 1/f^alpha (Kasdin 1995, Proc IEEE 83:802, over the
  // last second of samples): 0 white, as unfiltered trackers are; filtered trackers colour it
  // (Niehorster, Zemblys & Holmqvist 2021, Behav Res Methods 53:311), and Niehorster, Zemblys,
  // Beelders & Holmqvist 2020 (Behav Res Methods 52:2515) ask that methods be tested across signal
  // types. noise_deg stays the noise's standard deviation. Outside [0, 2] the constructor throws.
  // Each eye's point of gaze too (GazeSample::left_gaze, right_gaze; PROTOCOL.md §4.18), as a
  // binocular tracker reports it: the sample's point plus and minus an independent offset of
  // noise_deg RMS per axis, so that their mean is the sample's point (a tracker's combined gaze) and
  // each eye is noisier than it. Its draws come from a random stream of their own: the sample
  // stream is the same with it as without.
  bool binocular = false;
  double noise_alpha = 0;
  // Blinks as a video tracker records them: the eye rotates downward 1-2 deg as the lid starts to
  // close and is back before it reopens (Riggs, Kelly, Manning & Moore 1987, IOVS 28:334; shaped
  // here like a saccade of that size, down and back), and the pupil stays tracked while the lid
  // moves: a blink seen in the eye-openness signal lasts about 60 ms longer than its loss of the
  // pupil (Nystrom et al. 2024, Behav Res Methods, doi:10.3758/s13428-023-02333-9; split evenly here between closing and
  // opening, for want of a source). The blink's ground truth covers the tracked lid movement too.
  bool blink_eye_movements = false;
};

// Stream of noise with power spectrum ~ 1/f^alpha (0 <= alpha <= 2) and unit standard deviation:
// white gaussian draws through Kasdin's (1995) fractional-differencing filter, h_0 = 1,
// h_k = h_(k-1) (k - 1 + alpha/2) / k, truncated at `taps` (below rate/taps the spectrum flattens).
// Throws std::invalid_argument for an alpha outside [0, 2] (or NaN).
class PowerLawNoise {
 public:
  PowerLawNoise(double alpha, std::size_t taps);
  double next(double white);  // feeds one N(0,1) draw, returns the next noise value

 private:
  std::vector<double> h_;
  std::vector<double> history_;  // ring of the last taps draws
  std::size_t head_ = 0;
  double scale_ = 1;
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
  // Ground truth the protocol's movement states do not carry (post_saccadic_oscillations), for the
  // sample next() returned last, whose state names what the eyeball does: a saccade ends where the
  // tracked pupil, past the eyeball's peak velocity, stops moving on in its direction at 5 deg/s or
  // more (Schweitzer & Rolfs's simulator's criterion), which may be before the eyeball stops (the
  // rest of the eyeball's saccade is then PSO) or after it (SaccadeTail: still the saccade); then the
  // pupil rings while its oscillation's velocity envelope exceeds 5 deg/s (Oscillation: the PSO).
  enum class PupilMotion : std::uint8_t { None, SaccadeTail, Oscillation };
  PupilMotion last_sample_pupil_motion() const { return pupil_motion_; }

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
    // Blink (blink_eye_movements): the eye's downward dip and back, and the stretch of the blink
    // in which the lid covers the pupil.
    Vec2 dip;
    double covered_from_s = 0, covered_to_s = 0;
  };

  void step();  // generates the next sample and any events due before it
  // step()'s stages, in the order it calls them (the order of the random draws).
  double advance_segments_to(std::int64_t t_ns);
  Vec2 true_eye_position(double t, std::int64_t t_ns, double dt);
  void move_pupil_to(std::int64_t t_ns);
  Vec2 pupil_offset() const;
  void update_pso_truth(double t);
  double track_true_eye(const Vec2& eye, double dt);
  protocol::GazeSample measured_sample(std::int64_t t_ns, const Vec2& tracked, double velocity);
  void add_pupil_and_eye_cameras(protocol::GazeSample& s, const Vec2& eye, double dt, double t);
  protocol::EyeData eye_camera_data(const Vec2& eye, double pupil_mm, double vergence_px);
  void add_eye_gaze(protocol::GazeSample& s);
  void start_segment(Segment s, std::int64_t t_ns);
  void end_segment(std::int64_t t_ns);
  Segment plan_after(const Segment& finished);
  Segment plan_saccade(const Vec2& from, const Vec2& to) const;
  Segment plan_blink();
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
  // post_saccadic_oscillations: the tracked pupil centre and its velocity (deg, deg/s), the eyeball
  // it is tied to at the last integration step, and the PSO's ground truth.
  bool have_pupil_ = false;
  std::int64_t pupil_ns_ = 0;
  Vec2 pupil_, pupil_v_, eyeball_, eyeball_v_;
  bool saccade_ended_ = false;  // a saccade ended and its pupil has not yet come to rest
  Vec2 saccade_dir_;            // that saccade's direction (unit vector)
  PupilMotion pupil_motion_ = PupilMotion::None;
  // noise_alpha > 0: coloured tracker noise per axis.
  std::optional<PowerLawNoise> noise_x_, noise_y_;
  std::mt19937_64 eye_rng_;  // binocular: the per-eye offsets' own stream
};

}  // namespace fovea::trackerd
