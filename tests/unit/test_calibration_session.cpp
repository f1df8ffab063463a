// SPDX-License-Identifier: Apache-2.0
// fovea::calib step 5: the calibration schedule, the targets file, collection of fixation samples
// per target, and robust (outlier-rejecting) fitting.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "fovea/calib/model.h"
#include "fovea/calib/session.h"

namespace {

using namespace fovea::calib;
namespace fs = std::filesystem;

#define EXPECT_CONTAINS(haystack, needle) \
  EXPECT_NE(std::string(haystack).find(needle), std::string::npos) << "message: " << (haystack)

fs::path temp_path(const std::string& name) {
  return fs::temp_directory_path() / ("fovea-session-" + std::to_string(::getpid()) + "-" + name);
}

TEST(CalibrationSchedule, GridsCoverTheScreenInsideTheMarginInARandomButFixedOrder) {
  for (int points : {5, 9, 16, 64}) {
    ScheduleOptions o;
    o.points = points;
    o.validation_points = 9;
    const auto s = make_schedule(1920, 1080, o);
    ASSERT_EQ(s.size(), static_cast<std::size_t>(points + 9));
    std::set<std::pair<double, double>> distinct;
    double t = o.lead_in_s;
    for (std::size_t i = 0; i < s.size(); ++i) {
      EXPECT_EQ(s[i].index, static_cast<int>(i));
      EXPECT_EQ(s[i].phase, i < static_cast<std::size_t>(points) ? TargetPhase::Calibrate : TargetPhase::Validate);
      EXPECT_GE(s[i].position_px.x, 192 - 1e-9);
      EXPECT_LE(s[i].position_px.x, 1728 + 1e-9);
      EXPECT_GE(s[i].position_px.y, 108 - 1e-9);
      EXPECT_LE(s[i].position_px.y, 972 + 1e-9);
      EXPECT_DOUBLE_EQ(s[i].onset_s, t);
      EXPECT_DOUBLE_EQ(s[i].collect_from_s, t + o.settle_s);
      EXPECT_DOUBLE_EQ(s[i].collect_to_s, t + o.duration_s);
      t += o.duration_s;
      if (s[i].phase == TargetPhase::Calibrate) distinct.insert({s[i].position_px.x, s[i].position_px.y});
    }
    EXPECT_EQ(distinct.size(), static_cast<std::size_t>(points)) << points;
    EXPECT_DOUBLE_EQ(schedule_end_s(s), t);
    // Same seed, same order; another seed, another order.
    const auto again = make_schedule(1920, 1080, o);
    for (std::size_t i = 0; i < s.size(); ++i) EXPECT_EQ(again[i].position_px, s[i].position_px);
    o.seed = 99;
    const auto other = make_schedule(1920, 1080, o);
    bool differs = false;
    for (std::size_t i = 0; i < s.size(); ++i) differs |= !(other[i].position_px == s[i].position_px);
    EXPECT_TRUE(differs) << points;
  }
  // The order for seed 1 is pinned: a change would silently desynchronise recorded sessions and the
  // synthetic viewer's script from fovea-calibrate.
  const auto pinned = make_schedule(1920, 1080, ScheduleOptions{});
  EXPECT_EQ(pinned[0].position_px, (Point{1728, 972}));
  ScheduleOptions fixed;
  fixed.randomize = false;
  const auto rows = make_schedule(1920, 1080, fixed);
  EXPECT_EQ(rows[0].position_px, (Point{192, 108}));
  EXPECT_EQ(rows[1].position_px, (Point{960, 108}));
  EXPECT_EQ(rows[8].position_px, (Point{1728, 972}));
}

TEST(CalibrationSchedule, RefusesBadOptions) {
  ScheduleOptions o;
  o.points = 7;
  try {
    (void)make_schedule(1920, 1080, o);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_CONTAINS(e.what(), "points must be 5, 9, 16 or 64 (got 7)");
  }
  o = {};
  o.settle_s = 2;
  EXPECT_THROW((void)make_schedule(1920, 1080, o), std::invalid_argument);
  o = {};
  o.margin = 0.5;
  EXPECT_THROW((void)make_schedule(1920, 1080, o), std::invalid_argument);
  o = {};
  o.duration_s = std::nan("");
  EXPECT_THROW((void)make_schedule(1920, 1080, o), std::invalid_argument);
  EXPECT_THROW((void)make_schedule(1, 1080, ScheduleOptions{}), std::invalid_argument);
}

TEST(CalibrationTargetsFile, RoundTripsAndNamesWhatIsWrong) {
  const auto windows = place_schedule(make_schedule(1920, 1080, ScheduleOptions{}), 123'000'000'000);
  const fs::path path = temp_path("targets.csv");
  fs::remove(path);
  write_target_windows(path.string(), windows);
  const auto back = read_target_windows(path.string());
  ASSERT_EQ(back.size(), windows.size());
  for (std::size_t i = 0; i < back.size(); ++i) {
    EXPECT_EQ(back[i].index, windows[i].index);
    EXPECT_EQ(back[i].phase, windows[i].phase);
    EXPECT_EQ(back[i].position_px, windows[i].position_px);
    EXPECT_EQ(back[i].onset_ns, windows[i].onset_ns);
    EXPECT_EQ(back[i].collect_from_ns, windows[i].collect_from_ns);
    EXPECT_EQ(back[i].collect_to_ns, windows[i].collect_to_ns);
  }
  // Never replaced; the file stays as it was.
  const auto size = fs::file_size(path);
  EXPECT_THROW(write_target_windows(path.string(), windows), std::runtime_error);
  EXPECT_EQ(fs::file_size(path), size);
  fs::remove(path);

  const auto error_of = [&](const std::string& text) {
    std::ofstream(path) << text;
    std::string what;
    try {
      (void)read_target_windows(path.string());
    } catch (const std::runtime_error& e) {
      what = e.what();
    }
    fs::remove(path);
    return what;
  };
  const std::string header = "index,phase,x_px,y_px,onset_ns,collect_from_ns,collect_to_ns\n";
  EXPECT_CONTAINS(error_of("x,y\n"), ":1: header must be");
  EXPECT_CONTAINS(error_of(header + "0,calibrate,10,20,1,2\n"), ":2: expected 7 fields, found 6");
  EXPECT_CONTAINS(error_of(header + "0,look,10,20,1,2,3\n"), ":2: column phase: must be calibrate or validate");
  EXPECT_CONTAINS(error_of(header + "0,calibrate,nan,20,1,2,3\n"), ":2: column x_px: not a finite number");
  EXPECT_CONTAINS(error_of(header + "0,calibrate,10,20,1,5,3\n"), ":2: times must satisfy");
  EXPECT_CONTAINS(error_of(header + "0,calibrate,10,20,1,2,3x\n"), "column collect_to_ns: not an integer");
  EXPECT_CONTAINS(error_of(header), "no targets");
  EXPECT_CONTAINS(error_of(""), "empty");
}

TEST(CalibrationCollect, KeepsFixationSamplesAndSaysWhyOthersAreDropped) {
  std::vector<TargetWindow> targets(2);
  targets[0] = {0, TargetPhase::Calibrate, {100, 100}, 0, 500, 1500};
  targets[1] = {1, TargetPhase::Validate, {900, 500}, 1500, 2000, 3000};
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0, 0.1);
  std::vector<RawSample> samples;
  for (std::int64_t t = 0; t < 3000; t += 10) {
    RawSample s;
    s.time_ns = t;
    s.valid = true;
    s.state = RawSample::State::Fixation;
    s.raw = t < 1500 ? Point{10 + noise(rng), 20 + noise(rng)} : Point{-5 + noise(rng), 3 + noise(rng)};
    if (t >= 600 && t < 700) s.valid = false;                     // a blink: 10 samples
    if (t >= 800 && t < 850) s.state = RawSample::State::Saccade;  // 5 samples
    if (t == 900 || t == 910) s.raw = {40, 40};                    // looked away
    if (t == 1000) s.raw = {std::nan(""), 1};                      // NaN: never used
    samples.push_back(s);
  }
  const auto c = collect(samples, targets);
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c[0].in_window, 100u);
  EXPECT_EQ(c[0].invalid, 11u);
  EXPECT_EQ(c[0].moving, 5u);
  // The two looks away, and at most a couple of Gaussian samples beyond 3.5 sigma (0.2 % each).
  EXPECT_GE(c[0].outliers, 2u);
  EXPECT_LE(c[0].outliers, 4u);
  EXPECT_EQ(c[0].kept.size(), 100u - 11u - 5u - c[0].outliers);
  for (const auto& k : c[0].kept) EXPECT_LT(std::hypot(k.raw.x - 10, k.raw.y - 20), 1.0);
  EXPECT_TRUE(c[0].used);
  EXPECT_NEAR(c[0].median_raw.x, 10, 0.05);
  EXPECT_TRUE(c[1].used);
  EXPECT_GE(c[1].kept.size(), 98u);

  const auto calib_pts = correspondences(c, TargetPhase::Calibrate);
  EXPECT_EQ(calib_pts.size(), c[0].kept.size());
  for (const auto& p : calib_pts) {
    EXPECT_EQ(p.target, (Point{100, 100}));
    EXPECT_TRUE(std::isfinite(p.raw.x));
  }
  EXPECT_EQ(correspondences(c, TargetPhase::Validate).size(), c[1].kept.size());

  // Too few usable samples: the target is not used, and the reason is spelt out.
  for (auto& s : samples) {
    if (s.time_ns >= 2000) s.state = RawSample::State::Blink;
  }
  const auto c2 = collect(samples, targets);
  EXPECT_FALSE(c2[1].used);
  EXPECT_CONTAINS(c2[1].why_not, "0 of 100 samples usable");
  EXPECT_CONTAINS(c2[1].why_not, "100 during saccades/blinks");
  EXPECT_TRUE(correspondences(c2, TargetPhase::Validate).empty());
}

// side x side targets, 20 noisy samples each, from a quadratic truth; the first `stray` targets
// are measured 40 px off (the viewer looked elsewhere for the whole target).
Point truth_raw(Point target) {
  return {(target.x - 960) / 60 + 0.0004 * (target.x - 960) * (target.y - 540) / 3600, (target.y - 540) / 55};
}

std::vector<Correspondence> grid_samples(int side, int stray) {
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0, 0.05);
  std::vector<Correspondence> out;
  int target = 0;
  for (int j = 0; j < side; ++j) {
    for (int i = 0; i < side; ++i) {
      const Point t{192 + 1536.0 * i / (side - 1), 108 + 864.0 * j / (side - 1)};
      for (int k = 0; k < 20; ++k) {
        Point raw = truth_raw(t);
        raw.x += noise(rng);
        raw.y += noise(rng);
        if (target < stray) raw.x += 40.0 / 60;
        out.push_back({raw, t});
      }
      ++target;
    }
  }
  return out;
}

TEST(CalibrationRobustFit, Poly2DropsAStrayTargetOthersKeepEverything) {
  // 16 targets: a whole stray target stands out from the fit of the other 15.
  const auto pts = grid_samples(4, 1);
  const ModelFit robust = fit_model("poly2", pts);  // Auto: robust for poly2
  EXPECT_GE(robust.outliers_rejected, 20u);
  EXPECT_LE(robust.outliers_rejected, 30u);
  const ModelFit plain = fit_model("poly2", pts, FitOptions{FitOptions::Robust::Off});
  EXPECT_EQ(plain.outliers_rejected, 0u);
  const Point probe{704, 396};  // near the stray corner, between targets
  const Point r = robust.model->apply(truth_raw(probe)), p = plain.model->apply(truth_raw(probe));
  EXPECT_LT(std::hypot(r.x - probe.x, r.y - probe.y), 1.0);
  EXPECT_GT(std::hypot(p.x - probe.x, p.y - probe.y), 3 * std::hypot(r.x - probe.x, r.y - probe.y));
  // Clean data: next to nothing rejected.
  EXPECT_LE(fit_model("poly2", grid_samples(4, 0)).outliers_rejected, 3u);
  // Affine is not robust unless asked.
  EXPECT_EQ(fit_model("affine", pts).outliers_rejected, 0u);
  EXPECT_GE(fit_model("affine", pts, FitOptions{FitOptions::Robust::On}).outliers_rejected, 1u);
  // Never below half of the points, whatever the data.
  const auto mostly_stray = grid_samples(4, 10);
  EXPECT_LE(fit_model("poly2", mostly_stray).outliers_rejected, mostly_stray.size() / 2);
}

TEST(CalibrationRobustFit, ScatteredBadSamplesAreDroppedEvenOnNineTargets) {
  // A few wild samples inside otherwise good targets (a glint mismatch, a lid): dropped. A whole
  // stray target of a 3x3 grid is not: poly2's 6 terms per axis give each of 9 targets so much
  // leverage that the fit bends to it (CALIBRATION.md); validation shows such a calibration.
  auto pts = grid_samples(3, 0);
  for (std::size_t i = 0; i < pts.size(); i += 23) pts[i].raw.y += 1.5;
  const ModelFit robust = fit_model("poly2", pts);
  EXPECT_GE(robust.outliers_rejected, 8u);
  const Point probe{1344, 756};
  const Point r = robust.model->apply(truth_raw(probe));
  EXPECT_LT(std::hypot(r.x - probe.x, r.y - probe.y), 1.0);
}

TEST(CalibrationRobustFit, FileRecordsRejectedOutliersAndDescribesItself) {
  Calibration cal = fit_calibration("poly2", grid_samples(4, 1));
  cal.input = kInputPupilGlint;
  cal.eye = "right";
  EXPECT_GE(cal.outliers_rejected, 20u);
  EXPECT_CONTAINS(cal.describe(), "poly2 on pupil-glint (right eye)");
  EXPECT_CONTAINS(cal.describe(), "not validated");
  cal.validation = {{"accuracy_deg", 0.612}};
  EXPECT_CONTAINS(cal.describe(), "validated 0.61 deg");
  const fs::path path = temp_path("robust.json");
  fs::remove(path);
  save_calibration(cal, path);
  EXPECT_EQ(load_calibration(path).outliers_rejected, cal.outliers_rejected);
  fs::remove(path);
}

}  // namespace

namespace {

TEST(CalibrationFickAngles, RoundTripAndAFitInAnglesMapsBackToPixels) {
  const Display d;
  for (const Point px : {Point{960, 540}, Point{0, 0}, Point{1920, 1080}, Point{100, 900}, Point{-500, 3000}}) {
    const Point a = px_to_fick_deg(d, px);
    const Point back = fick_deg_to_px(d, a);
    EXPECT_NEAR(back.x, px.x, 1e-9);
    EXPECT_NEAR(back.y, px.y, 1e-9);
  }
  EXPECT_NEAR(px_to_fick_deg(d, {960, 540}).x, 0, 1e-12);
  // 265.65 mm right at 650 mm: atan(265.65 / 650) = 22.22 deg.
  EXPECT_NEAR(px_to_fick_deg(d, {1920, 540}).x, std::atan(265.65 / 650) * 180 / M_PI, 1e-9);
  EXPECT_TRUE(std::isnan(fick_deg_to_px(d, {90, 0}).x));
  EXPECT_TRUE(std::isnan(fick_deg_to_px(d, {std::nan(""), 0}).y));

  // A raw signal that is exactly quadratic in the angles: poly2 in Fick angles is exact, in pixels not.
  std::vector<Correspondence> pts;
  for (double y : {108.0, 540.0, 972.0}) {
    for (double x : {192.0, 960.0, 1728.0}) {
      const Point a = px_to_fick_deg(d, {x, y});
      pts.push_back({{std::sin(a.x * M_PI / 180) * 30, std::sin(a.y * M_PI / 180) * 30}, {x, y}});
    }
  }
  const Calibration in_angles = fit_calibration("poly2", pts, nullptr, {}, &d);
  EXPECT_EQ(in_angles.target_space, kTargetFickDegrees);
  ASSERT_TRUE(in_angles.display.has_value());
  const Calibration in_px = fit_calibration("poly2", pts);
  const Point probe{1344, 324};
  const Point a = px_to_fick_deg(d, probe);
  const Point raw{std::sin(a.x * M_PI / 180) * 30, std::sin(a.y * M_PI / 180) * 30};
  const Point pa = in_angles.apply(raw), pp = in_px.apply(raw);
  EXPECT_LT(std::hypot(pa.x - probe.x, pa.y - probe.y), std::hypot(pp.x - probe.x, pp.y - probe.y));
  // The file keeps the space; without its display it is refused.
  const fs::path path = temp_path("fick.json");
  fs::remove(path);
  save_calibration(in_angles, path);
  const Calibration back = load_calibration(path);
  EXPECT_EQ(back.target_space, kTargetFickDegrees);
  EXPECT_EQ(back.apply(raw), in_angles.apply(raw));
  fs::remove(path);
  Calibration no_display = fit_calibration("poly2", pts, nullptr, {}, &d);
  no_display.display.reset();
  save_calibration(no_display, path);
  try {
    (void)load_calibration(path);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_CONTAINS(e.what(), "display");
  }
  fs::remove(path);
  // Stacking a grid on a model in angles is refused (the grid corrects pixels).
  EXPECT_THROW((void)fit_calibration("bilinear-grid", pts, &in_angles), std::invalid_argument);
}

}  // namespace
