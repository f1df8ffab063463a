// SPDX-License-Identifier: Apache-2.0
// The default method: I-VVT, velocity-velocity threshold identification (Komogortsev & Karpov 2013,
// "Automated classification and scoring of smooth pursuit eye movements in the presence of
// fixations and saccades", Behav Res Methods 45:203-215): a high velocity threshold separates
// saccades; among the rest, a low velocity threshold separates pursuit from fixation. Fixed
// thresholds break across trackers (a 60 Hz remote tracker's noise velocity exceeds a lab tracker's
// pursuit), so both thresholds here adapt to the measured noise, and the saccade detector carries
// onset/offset and post-saccadic oscillation (PSO) handling:
//
//  1. Velocity: least-squares slope over a 20 ms window centred on the sample (at least one
//     neighbour each side) -- a first-order Savitzky-Golay differentiator, as in Nystrom &
//     Holmqvist 2010 and REMoDNaV (19 ms) -- of the per-axis angles, turned into the eye's true
//     angular velocity at the sample (tangent_vector: per-axis angles overstate movements off the
//     axes, by 1 / cos 40 deg = 1.31 for a vertical one at 40 deg horizontal eccentricity).
//  2. Noise: sigma, the tracker's position noise per tangent axis, from the median absolute deviation of
//     each sample from the line through its neighbours (a robust second difference, insensitive to
//     saccades and linear motion), over the last 1 s. The velocity noise of a sample is then
//     sigma_v = sigma / sqrt(sum (t - mean t)^2) over its window.
//  3. Saccades (Nystrom & Holmqvist 2010, with Engbert & Kliegl 2003's lambda = 6): a peak above
//     max(30 deg/s, 6 sigma_v); onset walks back while the velocity falls and stays above half the
//     peak threshold (their onset:peak ratio 3 sigma : 6 sigma); offset is the first sample below
//     that or where the velocity, already under half the saccade's peak, rises again (a local
//     minimum: the eye has landed, e.g. on a moving target).
//  4. PSO (Nystrom & Holmqvist 2010; 40 ms as REMoDNaV's max_pso_duration): within 40 ms after the
//     offset, a renewed rise of the velocity above the offset velocity + max(3 sigma_v, 5 deg/s)
//     (N&H 2010 use the local noise level, mean + 3 SD, as the PSO threshold), or a velocity
//     against the saccade's direction of more than max(3 sigma_v, 5 deg/s) (the swing back:
//     Hooge, Nystrom, Cornelissen & Holmqvist 2015, the PSO as overshoot and return), marks the
//     samples from the offset to the last such sample as PSO -- also when the rise passes the peak
//     threshold (their "high-velocity PSO"): no new saccade starts within those 40 ms.
//  5. Pursuit vs fixation (REMoDNaV, Dar, Wagner & Hanke 2021: a velocity threshold on low-pass
//     filtered gaze, 2 deg/s): the least-squares slope over +-100 ms of the surrounding
//     inter-saccadic samples (a low-pass filter with its first zero at 5 Hz, close to REMoDNaV's
//     4 Hz) must exceed max(2 deg/s, 3 x its own noise sigma / sqrt(sum (t - mean t)^2)); the
//     second term keeps a noisy or short stretch from passing for pursuit. Within 100 ms after a
//     saccade (the window cut short by it) pursuit also needs pursuit before the saccade, in about
//     the same direction: what follows a saccade alone is mostly the eye settling.
//  6. Pursuit covers ground (Larsson et al. 2015): a run of moving samples is pursuit only once
//     its low-pass position has left a fixation's spatial range (1.9 deg) of where the run began;
//     each sample waits up to 200 ms for that (smooth_label).
//
// Latency: the velocity window (10 ms) plus the pursuit window (100 ms) plus the range look-ahead
// (200 ms) = 310 ms in this core; the saccade onset walk-back and the PSO window fit inside it.
#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <optional>

#include "classify/pipeline.h"

namespace fovea::trackerd::classify {
namespace {

constexpr double kVelHalfS = 0.010;        // 20 ms velocity window (Nystrom & Holmqvist 2010; Olsen 2012)
constexpr double kPeakFloorDegS = 30.0;    // lowest saccade peak threshold (the I-VT standard, Olsen 2012)
constexpr double kPeakK = 6.0;             // Engbert & Kliegl 2003 lambda; Nystrom & Holmqvist 2010: mean + 6 SD
constexpr double kOnsetRatio = 0.5;        // Nystrom & Holmqvist 2010: onset at 3 SD vs peak at 6 SD
constexpr double kPsoMaxS = 0.040;         // Nystrom & Holmqvist 2010; REMoDNaV max_pso_duration
constexpr double kMarkHoldS = 0.030;       // marks only: a saccade's onset walk-back may still reach this far back
constexpr double kPsoK = 3.0;              // a renewed rise of 3 sigma_v counts as an oscillation
constexpr double kPsoMinRiseDegS = 5.0;    // ... and at least this much (ignores drift-sized wiggles)
constexpr double kSmoothHalfS = 0.100;     // pursuit low-pass window (REMoDNaV: 4 Hz low-pass)
constexpr double kPursuitFloorDegS = 2.0;  // REMoDNaV pursuit_velthresh
constexpr double kPursuitK = 3.0;          // slope must exceed 3 standard errors of noise
constexpr double kPursuitRangeDeg = 1.9;   // Larsson et al. 2015 eta_maxFix: a fixation's spatial range stays below
constexpr double kPursuitLookS = 0.200;    // how long a moving sample waits for its movement to reach that range
constexpr double kCatchUpMaxAngleDeg = 45; // Larsson et al. 2015 phi: pursuit goes on in about the same direction
constexpr double kNoiseWindowS = 1.0;      // trailing window of the noise estimate
constexpr double kNoisePriorDeg = 0.05;    // until 16 residuals are in: a typical video tracker
constexpr std::size_t kNoiseMaxResiduals = 4096;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
const double kCosPursuitRange = std::cos(kPursuitRangeDeg * kDegToRad);

struct Fit {
  double vx = 0, vy = 0, stt = 0;
  double mt = 0, mx = 0, my = 0;  // the centroid the line passes through
  std::size_t n = 0;
};

class IvvtCore final : public Core {
 public:
  explicit IvvtCore(bool marks_only = false) : marks_only_(marks_only) {}
  // marks_only: a sample's saccade or PSO mark is final once its velocity is in, no open
  // PSO window covers it (the window closes kVelHalfS after its 40 ms, below) and a saccade's onset
  // walk-back can no longer reach it (kMarkHoldS), long before its fixation/pursuit test.
  double latency_s() const override {
    return marks_only_ ? kVelHalfS + kPsoMaxS + kMarkHoldS
                     : kVelHalfS + kSmoothHalfS + kPursuitLookS - 3 * kTimeSlackS;
  }

  void push(const Prepared& p, std::vector<Labeled>& out) override {
    Entry e;
    e.p = p;
    if (p.has_gaze()) e.tangent = tangent_map(p.x, p.y);
    buf_.push_back(e);
    ++count_;
    newest_t_ = p.t;
    if (!p.has_gaze()) {
      while (vel_next_ + 1 < count_) compute_velocity(vel_next_++);
      close_pso();
      state_ = State::Idle;
      vel_next_ = count_;
      break_upto_ = count_;
    } else {
      while (vel_next_ < count_ && at(vel_next_).p.t + kVelHalfS - kTimeSlackS < newest_t_) {
        compute_velocity(vel_next_++);
      }
    }
    // Every sample of a PSO window whose end is kVelHalfS past has its velocity: the window is
    // over. finalize() and the next saccade_step() would close it (no sample in it is finalized
    // before: its smoothing waits kSmoothHalfS > kPsoMaxS); closing it now changes nothing but when
    // its marks are known.
    if (state_ == State::Pso && newest_t_ > pso_end_t_ + kVelHalfS - 2 * kTimeSlackS) close_pso();
    // Marks only: the pursuit test and the full labels are never asked for (most of the core's
    // time), and nothing the marks need waits on them.
    if (!marks_only_) finalize(out, false);
    emit_marks(out, false);
    trim();
  }

  void flush(std::vector<Labeled>& out) override {
    while (vel_next_ < count_) compute_velocity(vel_next_++);
    close_pso();
    state_ = State::Idle;
    if (!marks_only_) finalize(out, true);
    emit_marks(out, true);
    trim();
  }

 private:
  struct Entry {
    Prepared p;
    TangentMap tangent;  // per-axis changes at the sample -> the eye's rotation (tangent_vector)
    double v = kNaN;     // speed, deg/s (NaN: no neighbour to differentiate against)
    double vx = 0, vy = 0;  // the velocity itself, in the tangent frame at the sample (tangent_vector)
    double sv = 0;       // velocity noise (sigma_v) at this sample
    double sigma = 0;    // position noise estimate when the velocity was computed
    bool marked = false;
    Label mark = Label::Unknown;  // Saccade or Pso when marked
    // The pursuit test (smooth()), once the sample's low-pass window is complete:
    bool smoothed = false;
    bool moving = false;     // the low-pass slope says the eye moves
    bool cut_left = false;   // that window begins at a saccade less than its half-width before
    Direction s_dir;         // low-pass position: the window's least-squares line at the sample
    double dx = 0, dy = 0;   // the line's slope as an angular velocity (tangent_vector), deg/s
  };

  Entry& at(std::uint64_t k) { return buf_[static_cast<std::size_t>(k - base_)]; }
  bool gaze(std::uint64_t k) { return at(k).p.has_gaze(); }

  // Least-squares slope of x(t), y(t) over entries a..b.
  Fit fit(std::uint64_t a, std::uint64_t b) {
    Fit f;
    double mt = 0, mx = 0, my = 0;
    for (std::uint64_t j = a; j <= b; ++j) {
      mt += at(j).p.t;
      mx += at(j).p.x;
      my += at(j).p.y;
    }
    const double n = static_cast<double>(b - a + 1);
    mt /= n, mx /= n, my /= n;
    f.mt = mt, f.mx = mx, f.my = my;
    double sxt = 0, syt = 0;
    for (std::uint64_t j = a; j <= b; ++j) {
      const double dt = at(j).p.t - mt;
      f.stt += dt * dt;
      sxt += dt * (at(j).p.x - mx);
      syt += dt * (at(j).p.y - my);
    }
    f.n = static_cast<std::size_t>(b - a + 1);
    if (f.stt > 0) f.vx = sxt / f.stt, f.vy = syt / f.stt;
    return f;
  }

  void compute_velocity(std::uint64_t k) {
    Entry& e = at(k);
    if (!e.p.has_gaze()) return;
    const double t = e.p.t;
    std::uint64_t a = k, b = k;
    while (a > base_ && gaze(a - 1) && at(a - 1).p.t >= t - kVelHalfS + kTimeSlackS) --a;
    if (a == k && a > base_ && gaze(a - 1)) --a;
    while (b + 1 < count_ && gaze(b + 1) && at(b + 1).p.t <= t + kVelHalfS - kTimeSlackS) ++b;
    if (b == k && b + 1 < count_ && gaze(b + 1)) ++b;
    add_noise_residual(k);
    e.sigma = sigma_;
    if (a != b) {
      const Fit f = fit(a, b);
      const TangentVector w = e.tangent(f.vx, f.vy);  // the true angular velocity
      e.v = std::hypot(w.x, w.y);
      e.vx = w.x, e.vy = w.y;
      e.sv = f.stt > 0 ? sigma_ / std::sqrt(f.stt) : 0;
    }
    saccade_step(k);
  }

  // --- noise -------------------------------------------------------------------------------------
  void add_noise_residual(std::uint64_t k) {
    if (k == base_ || k + 1 >= count_) return;
    const Prepared &p0 = at(k - 1).p, &p1 = at(k).p, &p2 = at(k + 1).p;
    if (p0.kind != Prepared::Kind::Gaze || p1.kind != Prepared::Kind::Gaze || p2.kind != Prepared::Kind::Gaze) return;
    const double w = (p1.t - p0.t) / (p2.t - p0.t);
    const double c = std::sqrt(1 + w * w + (1 - w) * (1 - w));  // residual SD in units of sigma
    // Measured as true angles, as the velocities are (tangent_vector).
    const TangentVector off = at(k).tangent(p1.x - (p0.x + w * (p2.x - p0.x)), p1.y - (p0.y + w * (p2.y - p0.y)));
    residuals_.push_back({p1.t, std::abs(off.x) / c});
    residuals_.push_back({p1.t, std::abs(off.y) / c});
    while (!residuals_.empty() &&
           (residuals_.front().first < p1.t - kNoiseWindowS + kTimeSlackS || residuals_.size() > kNoiseMaxResiduals)) {
      residuals_.pop_front();
    }
    if (residuals_.size() >= 16 && ++since_update_ >= std::max<std::size_t>(1, residuals_.size() / 32)) {
      since_update_ = 0;
      scratch_.clear();
      for (const auto& r : residuals_) scratch_.push_back(r.second);
      auto mid = scratch_.begin() + static_cast<std::ptrdiff_t>(scratch_.size() / 2);
      std::nth_element(scratch_.begin(), mid, scratch_.end());
      sigma_ = *mid / 0.6745;  // MAD of a zero-mean normal
    }
  }

  // --- saccades and PSO ----------------------------------------------------------------------------
  enum class State : std::uint8_t { Idle, Saccade, Pso };

  void mark(std::uint64_t k, Label l) {
    at(k).marked = true;
    at(k).mark = l;
  }

  void close_pso() {
    if (state_ != State::Pso) return;
    if (pso_has_above_) {
      for (std::uint64_t j = std::max(pso_start_, fin_next_); j <= pso_last_above_; ++j) {
        if (gaze(j) && !at(j).marked) mark(j, Label::Pso);
      }
    }
    state_ = State::Idle;
  }

  void saccade_step(std::uint64_t k) {
    const Entry& e = at(k);
    if (std::isnan(e.v)) {
      close_pso();
      state_ = State::Idle;
      return;
    }
    const double peak_thr = std::max(kPeakFloorDegS, kPeakK * e.sv);
    const double onset_thr = kOnsetRatio * peak_thr;
    if (state_ == State::Pso) {
      if (e.p.t > pso_end_t_ - kTimeSlackS) {
        close_pso();  // window over: handled below as idle
      } else {
        // Fast oscillations count too (N&H 2010's "high-velocity PSO"): no saccade follows
        // another within 40 ms. So does the swing back against the saccade (Hooge et al. 2015: the
        // PSO overshoots and returns), which a speed test misses while the return is slower than
        // the landing.
        const double back = -(e.vx * sac_ux_ + e.vy * sac_uy_);
        if (e.v > pso_thr_ || back > std::max(kPsoK * e.sv, kPsoMinRiseDegS)) {
          pso_has_above_ = true;
          pso_last_above_ = k;
        }
        return;
      }
    }
    if (state_ == State::Saccade) {
      const bool offset = e.v < onset_thr || (prev_v_ < 0.5 * peak_v_ && e.v > prev_v_ + e.sv);
      if (!offset) {
        mark(k, Label::Saccade);
        peak_v_ = std::max(peak_v_, e.v);
        prev_v_ = e.v;
        return;
      }
      state_ = State::Pso;
      // The saccade's direction, in the frame of the velocities.
      const TangentVector d = e.tangent(e.p.x - sac_x0_, e.p.y - sac_y0_);
      const double a = std::hypot(d.x, d.y);
      sac_ux_ = a > 0 ? d.x / a : 0, sac_uy_ = a > 0 ? d.y / a : 0;
      pso_start_ = k;
      pso_end_t_ = e.p.t + kPsoMaxS;
      pso_thr_ = e.v + std::max(kPsoK * e.sv, kPsoMinRiseDegS);
      pso_has_above_ = false;
      return;
    }
    if (e.v > peak_thr) {
      mark(k, Label::Saccade);
      // Onset: walk back down the rising flank (still unlabelled samples only; with marks only,
      // not over marks already sent).
      std::uint64_t onset = k;
      const std::uint64_t floor = marks_only_ ? marks_next_ : fin_next_;
      for (std::uint64_t j = k; j > floor && j > base_;) {
        --j;
        const Entry& q = at(j);
        const Entry& r = at(j + 1);
        if (!q.p.has_gaze() || q.marked || std::isnan(q.v)) break;
        if (q.v <= kOnsetRatio * std::max(kPeakFloorDegS, kPeakK * q.sv) || q.v > r.v + q.sv) break;
        mark(j, Label::Saccade);
        onset = j;
      }
      state_ = State::Saccade;
      sac_x0_ = at(onset).p.x, sac_y0_ = at(onset).p.y;
      peak_v_ = e.v;
      prev_v_ = e.v;
    }
  }

  // --- fixation vs pursuit, and output -------------------------------------------------------------
  // Step 1, per sample: does the low-pass gaze move?
  void smooth(std::uint64_t f) {
    Entry& e = at(f);
    e.smoothed = true;
    if (!e.p.has_gaze() || e.marked || std::isnan(e.v)) return;
    const double t = e.p.t;
    std::uint64_t a = f, b = f;
    const auto usable = [&](std::uint64_t j) { return gaze(j) && !at(j).marked; };
    while (a > base_ && usable(a - 1) && at(a - 1).p.t >= t - kSmoothHalfS + kTimeSlackS) --a;
    while (b + 1 < vel_next_ && usable(b + 1) && at(b + 1).p.t <= t + kSmoothHalfS - kTimeSlackS) ++b;
    if (b - a + 1 < 3) return;
    const Fit fw = fit(a, b);
    if (!(fw.stt > 0)) return;
    const double threshold = std::max(kPursuitFloorDegS, kPursuitK * e.sigma / std::sqrt(fw.stt));
    const TangentVector w = e.tangent(fw.vx, fw.vy);
    e.moving = std::hypot(w.x, w.y) > threshold;
    e.s_dir = direction(fw.mx + fw.vx * (t - fw.mt), fw.my + fw.vy * (t - fw.mt));  // per-axis angles, as the samples
    e.dx = w.x, e.dy = w.y;
    e.cut_left = a > base_ && at(a - 1).marked && at(a - 1).p.t > t - kSmoothHalfS + kTimeSlackS;  // within it
  }

  // Step 2, per sample in order: fixation or pursuit; nullopt while the look-ahead is incomplete.
  //  - Right after a saccade the window holds only what follows it: the eye settling (glissades,
  //    Bahill, Clark & Stark 1975; in pupil-based trackers the pupil moving inside the iris,
  //    Nystrom, Hooge & Holmqvist 2013) passes for pursuit there. So a window cut short by a saccade
  //    on its left says pursuit only when the eye pursued before that saccade, in about the same
  //    direction (a catch-up saccade; Larsson et al. 2015's phi = 45 deg).
  //  - Otherwise a run of moving samples is pursuit only once its low-pass position has moved
  //    kPursuitRangeDeg from where the run began (Larsson, Nystrom, Andersson & Stridh 2015,
  //    "Detection of fixations and smooth pursuit movements in high-speed eye-tracking data",
  //    Biomed Signal Process Control 18:145-152: eta_maxFix = 1.9 deg, the spatial range beyond
  //    which a segment is no fixation). Fixational drift and the slow wander of video trackers move
  //    the eye at pursuit-like speeds for tens of ms but stay within a fixation's range; on still
  //    images ivvt called a quarter of all samples pursuit without this. A sample waits at most
  //    kPursuitLookS for its run to reach the range.
  std::optional<Label> smooth_label(std::uint64_t f, bool flushing) {
    const Entry& e = at(f);
    if (!e.moving) {
      run_open_ = false;
      return Label::Fixation;
    }
    if (!run_open_) {
      run_open_ = true;
      run_confirmed_ = false;
      run_start_ = e.s_dir;
    }
    if (e.cut_left) {
      if (before_saccade_ != Label::Pursuit || !same_direction(e.dx, e.dy, pursuit_dx_, pursuit_dy_)) return Label::Fixation;
      run_confirmed_ = true;
      return Label::Pursuit;
    }
    if (run_confirmed_) return Label::Pursuit;
    for (std::uint64_t j = f; j < count_; ++j) {
      const Entry& q = at(j);
      if (q.p.t > e.p.t + kPursuitLookS - kTimeSlackS) return Label::Fixation;
      if (!q.smoothed) return flushing ? std::optional<Label>(Label::Fixation) : std::nullopt;
      if (!q.moving) return Label::Fixation;  // the run ended within a fixation's range
      if (q.s_dir.dot(run_start_) <= kCosPursuitRange) {  // the angle between them >= kPursuitRangeDeg
        run_confirmed_ = true;
        return Label::Pursuit;
      }
    }
    return flushing ? std::optional<Label>(Label::Fixation) : std::nullopt;
  }

  static bool same_direction(double ax, double ay, double bx, double by) {
    const double na = std::hypot(ax, ay), nb = std::hypot(bx, by);
    if (!(na > 0) || !(nb > 0)) return false;
    return (ax * bx + ay * by) / (na * nb) >= std::cos(kCatchUpMaxAngleDeg * kDegToRad);
  }

  void finalize(std::vector<Labeled>& out, bool flushing) {
    while (smooth_next_ < vel_next_) {
      const Entry& e = at(smooth_next_);
      const bool ready =
          flushing || smooth_next_ < break_upto_ || newest_t_ > e.p.t + kSmoothHalfS + kVelHalfS - 2 * kTimeSlackS;
      if (!ready) break;
      if (state_ == State::Pso && newest_t_ > pso_end_t_ + kVelHalfS - 2 * kTimeSlackS) close_pso();
      smooth(smooth_next_++);
    }
    while (fin_next_ < smooth_next_) {
      const Entry& e = at(fin_next_);
      Label l;
      if (e.p.kind == Prepared::Kind::Blink) l = Label::Blink;
      else if (e.p.kind == Prepared::Kind::Lost) l = Label::Lost;
      else if (e.marked) l = e.mark;
      else if (std::isnan(e.v)) l = Label::Unknown;
      else {
        const auto smooth = smooth_label(fin_next_, flushing);
        if (!smooth) break;
        l = *smooth;
      }
      if (l != Label::Fixation && l != Label::Pursuit) run_open_ = false;
      if (e.marked && (fin_next_ == 0 || !at(fin_next_ - 1).marked)) before_saccade_ = last_smooth_;
      if (l == Label::Fixation || l == Label::Pursuit) last_smooth_ = l;
      if (l == Label::Pursuit) pursuit_dx_ = e.dx, pursuit_dy_ = e.dy;
      out.push_back({e.p.index, l});
      ++fin_next_;
    }
  }

  // marks_only: each sample's label as soon as its mark is final: `saccade` or `pso`, or `unknown`
  // for anything else (the caller asks only for the marks; the saccade and PSO steps run as ever,
  // so the marks are those of the full labels, but for an onset walk-back that would reach over
  // kMarkHoldS to marks already sent).
  void emit_marks(std::vector<Labeled>& out, bool flushing) {
    if (!marks_only_) return;
    const double settled_t = newest_t_ - kVelHalfS - kMarkHoldS;  // a walk-back starts after this
    while (marks_next_ < vel_next_ && !(state_ == State::Pso && pso_start_ <= marks_next_)) {
      const Entry& e = at(marks_next_);
      if (!flushing && marks_next_ >= break_upto_ && e.p.t > settled_t) break;
      ++marks_next_;
      const bool marked = e.p.has_gaze() && e.marked;
      out.push_back({e.p.index, marked ? e.mark : Label::Unknown});
    }
  }

  void trim() {
    // Keep the pursuit window's history before the next sample to finalize (and its velocity window).
    const std::uint64_t next = marks_only_ ? marks_next_ : fin_next_;
    const double ref = next < count_ ? at(next).p.t : newest_t_;
    while (base_ + 1 < next && buf_[1].p.t < ref - kSmoothHalfS - kVelHalfS + 2 * kTimeSlackS) {
      buf_.pop_front();
      ++base_;
    }
  }

  std::deque<Entry> buf_;
  std::uint64_t base_ = 0;       // absolute position of buf_[0]
  std::uint64_t count_ = 0;      // entries pushed
  std::uint64_t vel_next_ = 0;   // next entry needing its velocity
  std::uint64_t smooth_next_ = 0; // next entry for the pursuit test
  std::uint64_t fin_next_ = 0;   // next entry to label
  std::uint64_t break_upto_ = 0; // entries before this precede a loss: nothing after them matters
  bool marks_only_ = false;
  std::uint64_t marks_next_ = 0;  // marks_only: the next entry whose mark is to be sent
  double newest_t_ = 0;
  Label last_smooth_ = Label::Fixation;     // the last fixation/pursuit label given
  Label before_saccade_ = Label::Fixation;  // what the eye did before the last saccade
  double pursuit_dx_ = 0, pursuit_dy_ = 0;  // the direction of the last pursuit sample
  bool run_open_ = false;       // the samples labelled last were a run of moving samples
  bool run_confirmed_ = false;  // ... that has moved a fixation's range: pursuit
  Direction run_start_;  // the low-pass position where the run began

  std::deque<std::pair<double, double>> residuals_;  // (time, |residual| / its SD factor)
  std::vector<double> scratch_;
  std::size_t since_update_ = 0;
  double sigma_ = kNoisePriorDeg;

  State state_ = State::Idle;
  double peak_v_ = 0, prev_v_ = 0;
  double sac_x0_ = 0, sac_y0_ = 0;  // the saccade's onset position
  double sac_ux_ = 0, sac_uy_ = 0;  // its direction, onset to offset (unit vector)
  std::uint64_t pso_start_ = 0, pso_last_above_ = 0;
  double pso_end_t_ = 0, pso_thr_ = 0;
  bool pso_has_above_ = false;
};

}  // namespace

std::unique_ptr<Core> make_ivvt_core() { return std::make_unique<IvvtCore>(); }
std::unique_ptr<Core> make_ivvt_marks_core() { return std::make_unique<IvvtCore>(true); }

}  // namespace fovea::trackerd::classify
