// SPDX-License-Identifier: Apache-2.0
// fovea::calib step 5 models: affine and homography baselines, the Jensen & Pedersen 2009
// calibration-vector grid (eqs. 4.1-4.2), the model interface and the calibration file.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "fovea/calib/bilinear_grid.h"
#include "fovea/calib/linear_maps.h"
#include "fovea/calib/model.h"

namespace {

using namespace fovea::calib;
namespace fs = std::filesystem;

std::vector<Correspondence> sample(int n, Point (*truth)(Point), double lo = -10, double hi = 10) {
  std::vector<Correspondence> out;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const Point r{lo + (hi - lo) * i / (n - 1), lo + (hi - lo) * j / (n - 1) + 0.1 * i};
      out.push_back({r, truth(r)});
    }
  }
  return out;
}

Point affine_truth(Point r) { return {840 + 31.5 * r.x - 2.25 * r.y, 525 + 1.5 * r.x + 28.0 * r.y}; }
Point homography_truth(Point r) {
  const double w = 1 + 0.004 * r.x - 0.003 * r.y;
  return {(840 + 31.5 * r.x - 2.25 * r.y) / w, (525 + 1.5 * r.x + 28.0 * r.y) / w};
}

fs::path temp_path(const std::string& name) {
  return fs::temp_directory_path() / ("fovea-calib-" + std::to_string(::getpid()) + "-" + name);
}

TEST(AffineMap, RecoversAnExactAffineMap) {
  const auto pts = sample(3, affine_truth);
  const AffineMap m = AffineMap::fit(pts);
  const std::array<double, 6> want{840, 31.5, -2.25, 525, 1.5, 28.0};
  for (std::size_t k = 0; k < 6; ++k) EXPECT_NEAR(m.a[k], want[k], 1e-9) << k;
  EXPECT_LT(m.stats.rms_residual, 1e-9);
  EXPECT_EQ(m.stats.points, 9u);
  EXPECT_GE(m.stats.condition, 1.0);
  EXPECT_LT(m.stats.condition, 10.0);
}

TEST(HomographyMap, RecoversAnExactHomography) {
  const auto pts = sample(4, homography_truth);
  const HomographyMap m = HomographyMap::fit(pts);
  EXPECT_LT(m.stats.rms_residual, 1e-8);
  EXPECT_NEAR(m.h[8], 1.0, 0);
  for (const Point r : {Point{3.3, -7.1}, Point{-9, 9}, Point{0, 0}}) {
    const Point want = homography_truth(r), got = m.apply(r);
    EXPECT_NEAR(got.x, want.x, 1e-8);
    EXPECT_NEAR(got.y, want.y, 1e-8);
  }
  // Exactly four points in general position determine it too.
  const std::vector<Correspondence> four{{{-10, -10}, homography_truth({-10, -10})},
                                         {{10, -10}, homography_truth({10, -10})},
                                         {{10, 10}, homography_truth({10, 10})},
                                         {{-10, 10}, homography_truth({-10, 10})}};
  const HomographyMap m4 = HomographyMap::fit(four);
  const Point got = m4.apply({2, 3}), want = homography_truth({2, 3});
  EXPECT_NEAR(got.x, want.x, 1e-8);
  EXPECT_NEAR(got.y, want.y, 1e-8);
}

// A 3x3 grid at x in {0, 100, 200}, y in {0, 50, 100} with distinct vectors v_ij = (i + 10 j, -2 i + j),
// two samples per target whose mean is target - v_ij.
Point v_of(std::size_t i, std::size_t j) {
  return {static_cast<double>(i) + 10.0 * static_cast<double>(j), -2.0 * static_cast<double>(i) + static_cast<double>(j)};
}
std::vector<Correspondence> grid_points() {
  std::vector<Correspondence> out;
  for (std::size_t j = 0; j < 3; ++j) {
    for (std::size_t i = 0; i < 3; ++i) {
      const Point t{100.0 * static_cast<double>(i), 50.0 * static_cast<double>(j)};
      const Point v = v_of(i, j);
      out.push_back({{t.x - v.x + 1.5, t.y - v.y - 0.5}, t});
      out.push_back({{t.x - v.x - 1.5, t.y - v.y + 0.5}, t});
    }
  }
  return out;
}

void expect_point(Point got, Point want, const char* what) {
  EXPECT_NEAR(got.x, want.x, 1e-12) << what;
  EXPECT_NEAR(got.y, want.y, 1e-12) << what;
}

TEST(BilinearGrid, FitsVectorsAsMeanOfTargetMinusMeasured) {
  const BilinearGrid g = BilinearGrid::fit(grid_points());
  ASSERT_EQ(g.xs, (std::vector<double>{0, 100, 200}));
  ASSERT_EQ(g.ys, (std::vector<double>{0, 50, 100}));
  for (std::size_t j = 0; j < 3; ++j)
    for (std::size_t i = 0; i < 3; ++i) expect_point(g.vector_at(i, j), v_of(i, j), "v_ij");
  EXPECT_TRUE(std::isnan(g.stats.condition));
  EXPECT_EQ(g.stats.points, 18u);
}

TEST(BilinearGrid, InteriorPointFollowsEquation42ByHand) {
  const BilinearGrid g = BilinearGrid::fit(grid_points());
  // p = (130, 20): cell x_1 = 100, x_2 = 200, y_1 = 0, y_2 = 50; eq. 4.1: alpha = 0.3, beta = 0.4.
  const double alpha = 0.3, beta = 0.4;
  const Point v11 = v_of(1, 0), v12 = v_of(1, 1), v21 = v_of(2, 0), v22 = v_of(2, 1);
  // v11 = (1, -2), v12 = (11, -1), v21 = (2, -4), v22 = (12, -3).
  const Point want{(1 - alpha) * (v11.x * (1 - beta) + v12.x * beta) + alpha * (v21.x * (1 - beta) + v22.x * beta),
                   (1 - alpha) * (v11.y * (1 - beta) + v12.y * beta) + alpha * (v21.y * (1 - beta) + v22.y * beta)};
  expect_point(want, {0.7 * (0.6 * 1 + 0.4 * 11) + 0.3 * (0.6 * 2 + 0.4 * 12),
                      0.7 * (0.6 * -2 + 0.4 * -1) + 0.3 * (0.6 * -4 + 0.4 * -3)}, "hand");
  expect_point(g.correction({130, 20}), want, "eq 4.2");
  expect_point(g.apply({130, 20}), {130 + want.x, 20 + want.y}, "p + v_p");
  // On a grid point the correction is that point's vector.
  expect_point(g.correction({100, 50}), v_of(1, 1), "at Q");
}

TEST(BilinearGrid, CornerRegionsUseTheSingleAdjacentVector) {
  const BilinearGrid g = BilinearGrid::fit(grid_points());
  expect_point(g.correction({-10, -10}), v_of(0, 0), "top-left");
  expect_point(g.correction({-1e6, 1e6}), v_of(0, 2), "far corner");
  expect_point(g.correction({250, -3}), v_of(2, 0), "x beyond, y before");
  expect_point(g.correction({201, 101}), v_of(2, 2), "just beyond the last point");
}

TEST(BilinearGrid, BordersUseOnlyAlphaOrOnlyBeta) {
  const BilinearGrid g = BilinearGrid::fit(grid_points());
  // Above / below the grid: only alpha (x), along the outer row.
  expect_point(g.correction({130, -40}), {0.7 * v_of(1, 0).x + 0.3 * v_of(2, 0).x, 0.7 * v_of(1, 0).y + 0.3 * v_of(2, 0).y},
               "top");
  expect_point(g.correction({130, 400}), {0.7 * v_of(1, 2).x + 0.3 * v_of(2, 2).x, 0.7 * v_of(1, 2).y + 0.3 * v_of(2, 2).y},
               "bottom");
  // Left / right of the grid: only beta (y), along the outer column.
  expect_point(g.correction({-20, 20}), {0.6 * v_of(0, 0).x + 0.4 * v_of(0, 1).x, 0.6 * v_of(0, 0).y + 0.4 * v_of(0, 1).y},
               "left");
  expect_point(g.correction({300, 70}), {0.6 * v_of(2, 1).x + 0.4 * v_of(2, 2).x, 0.6 * v_of(2, 1).y + 0.4 * v_of(2, 2).y},
               "right");
  // Continuous across the grid's edge.
  expect_point(g.correction({200, 20}), g.correction({200.000001, 20}), "edge continuity");
}

TEST(BilinearGrid, ZeroVectorsAreTheIdentity) {
  std::vector<Correspondence> pts;
  for (double y : {0.0, 525.0, 1050.0})
    for (double x : {0.0, 420.0, 840.0, 1680.0}) pts.push_back({{x, y}, {x, y}});
  const BilinearGrid g = BilinearGrid::fit(pts);
  for (const Point p : {Point{1, 2}, Point{900, 700}, Point{-50, 2000}, Point{1680, 1050}}) {
    EXPECT_EQ(g.apply(p), p);
  }
  EXPECT_EQ(g.stats.rms_residual, 0);
}

TEST(BilinearGrid, NotFiniteInputGivesNaN) {
  const BilinearGrid g = BilinearGrid::fit(grid_points());
  EXPECT_TRUE(std::isnan(g.apply({std::nan(""), 3}).x));
}

TEST(Calibration, GridOnTopOfAnotherModelComposes) {
  // Base: an affine calibration from raw tracker units; the truth adds a smooth distortion that
  // the affine map cannot follow, and the grid corrects what is left.
  auto truth = [](Point r) {
    const Point a = affine_truth(r);
    return Point{a.x + 0.2 * r.x * r.y, a.y - 0.15 * r.x * r.x};
  };
  std::vector<Correspondence> pts;
  for (int i = 0; i < 5; ++i)
    for (int j = 0; j < 5; ++j) {
      const Point target{100.0 + 370.0 * i, 80.0 + 220.0 * j};
      // invert truth approximately by fixed-point iteration: raw whose truth() is the target
      Point r{(target.x - 840) / 31.5, (target.y - 525) / 28.0};
      for (int k = 0; k < 50; ++k) {
        const Point t = truth(r);
        r = {r.x + (target.x - t.x) / 31.5, r.y + (target.y - t.y) / 28.0};
      }
      pts.push_back({r, target});
    }
  Calibration base = fit_calibration("affine", pts);
  const Calibration cal = fit_calibration("bilinear-grid", pts, &base);
  ASSERT_TRUE(cal.on_top_of);
  EXPECT_EQ(cal.on_top_of->kind(), "affine");
  EXPECT_EQ(cal.model->kind(), "bilinear-grid");
  // apply = grid(base(raw)), exactly.
  for (const auto& c : pts) {
    const Point b = base.model->apply(c.raw);
    EXPECT_EQ(cal.apply(c.raw), cal.model->apply(b));
  }
  EXPECT_LT(cal.rms_residual, 0.5 * base.rms_residual);
  // The base of a composed calibration cannot be stacked again.
  EXPECT_THROW((void)fit_calibration("affine", pts, &cal), std::invalid_argument);
}

TEST(Calibration, FitModelKnowsEveryKindAndRefusesOthers) {
  const auto pts = sample(4, affine_truth);
  for (const auto& kind : model_kinds()) {
    if (kind == "bilinear-grid") continue;
    const auto m = fit_model(kind, pts).model;
    EXPECT_EQ(m->kind(), kind);
    EXPECT_NEAR(m->apply({1, 2}).x, affine_truth({1, 2}).x, 1e-7) << kind;
  }
  try {
    (void)fit_model("spline", pts);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("unknown calibration model 'spline'"), std::string::npos) << e.what();
  }
}

TEST(Calibration, FileRoundTripsEveryModel) {
  const auto poly_pts = sample(4, homography_truth);
  for (const auto& kind : model_kinds()) {
    const Calibration cal = kind == "bilinear-grid" ? fit_calibration(kind, grid_points()) : fit_calibration(kind, poly_pts);
    const fs::path path = temp_path(kind + ".json");
    fs::remove(path);
    Calibration withdisplay = fit_calibration(kind, kind == "bilinear-grid" ? grid_points() : poly_pts);
    withdisplay.display = Display{1680, 1050, 474, 296, 600};
    withdisplay.input = kInputPupilGlint;
    withdisplay.eye = "left";
    withdisplay.validation = {{"targets", 4}, {"accuracy_deg", 0.5}};
    save_calibration(withdisplay, path);
    const Calibration back = load_calibration(path);
    EXPECT_EQ(back.model->kind(), kind);
    EXPECT_EQ(back.points_used, cal.points_used);
    ASSERT_TRUE(back.display.has_value());
    EXPECT_EQ(*back.display, *withdisplay.display);
    EXPECT_EQ(back.input, kInputPupilGlint);
    EXPECT_EQ(back.eye, "left");
    EXPECT_EQ(back.validated_accuracy_deg(), 0.5);
    EXPECT_EQ(back.created.size(), 20u);
    EXPECT_EQ(back.created.back(), 'Z');
    for (const Point p : {Point{1, 2}, Point{130, 20}, Point{-3, 7}}) {
      EXPECT_EQ(back.apply(p), withdisplay.apply(p)) << kind;
    }
    // Refuses to overwrite unless asked.
    EXPECT_THROW(save_calibration(cal, path), std::runtime_error);
    EXPECT_NO_THROW(save_calibration(cal, path, true));
    fs::remove(path);
  }
}

}  // namespace
