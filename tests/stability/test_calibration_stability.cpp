// SPDX-License-Identifier: Apache-2.0
// Hard cases of fovea::calib fitting and calibration files (ctest -L stability): degenerate,
// too few, non-finite and ill-conditioned point sets, incomplete grids, files from newer versions.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include "fovea/calib/bilinear_grid.h"
#include "fovea/calib/linear_maps.h"
#include "fovea/calib/model.h"

namespace {

using namespace fovea::calib;
namespace fs = std::filesystem;

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no error)";
}

#define EXPECT_CONTAINS(haystack, needle) \
  EXPECT_NE(std::string(haystack).find(needle), std::string::npos) << "message: " << (haystack)

std::string fit_error(const std::string& kind, const std::vector<Correspondence>& pts) {
  return error_of([&] { (void)fit_model(kind, pts); });
}

std::vector<Correspondence> on_line(std::size_t n) {
  std::vector<Correspondence> out;
  for (std::size_t i = 0; i < n; ++i) {
    const double t = static_cast<double>(i);
    out.push_back({{t, 2 * t + 1}, {100 * t, 50 * t}});
  }
  return out;
}

std::vector<Correspondence> square_grid(double jitter_y = 1.0) {
  std::vector<Correspondence> out;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const Point r{static_cast<double>(i), jitter_y * static_cast<double>(j)};
      out.push_back({r, {100.0 * i, 100.0 * j}});
    }
  return out;
}

TEST(CalibrationStability, CollinearPointsAreRefused) {
  for (const char* kind : {"affine", "homography", "poly2"}) {
    const std::string msg = fit_error(kind, on_line(10));
    EXPECT_CONTAINS(msg, "collinear");
    EXPECT_CONTAINS(msg, "do not determine");
  }
  // Homography: three of four points on one line.
  const std::vector<Correspondence> three_on_line{{{0, 0}, {0, 0}}, {{1, 0}, {10, 0}}, {{2, 0}, {20, 0}}, {{0, 1}, {0, 10}}};
  EXPECT_CONTAINS(fit_error("homography", three_on_line), "rank");
}

TEST(CalibrationStability, DuplicatePointsAreRefused) {
  const std::vector<Correspondence> dup{{{0, 0}, {0, 0}}, {{0, 0}, {0, 0}}, {{1, 1}, {5, 5}}, {{1, 1}, {5, 5}}};
  const std::string msg = fit_error("affine", dup);
  EXPECT_CONTAINS(msg, "2 distinct");
  EXPECT_CONTAINS(fit_error("homography", dup), "2 distinct");
}

TEST(CalibrationStability, TooFewPointsAreRefused) {
  EXPECT_CONTAINS(fit_error("affine", on_line(2)), "needs at least 3 points");
  const auto grid = square_grid();
  EXPECT_CONTAINS(fit_error("homography", {grid.begin(), grid.begin() + 3}), "needs at least 4 points");
  EXPECT_CONTAINS(fit_error("poly2", on_line(5)), "at least 6");
  EXPECT_CONTAINS(fit_error("bilinear-grid", on_line(3)), "2x2 grid");
}

TEST(CalibrationStability, NonFiniteSamplesAreRefused) {
  for (const auto& kind : model_kinds()) {
    auto pts = square_grid();
    pts[4].raw.y = std::nan("");
    const std::string msg = fit_error(kind, pts);
    EXPECT_CONTAINS(msg, "correspondence 4");
    EXPECT_CONTAINS(msg, "not finite");
    pts[4].raw.y = 1;
    pts[2].target.x = INFINITY;
    EXPECT_CONTAINS(fit_error(kind, pts), "not finite");
  }
}

TEST(CalibrationStability, IllConditionedFitsAreReportedOrRefused) {
  // Nearly collinear at 1e-4: fits, and says so through the condition number.
  auto mild = square_grid(1e-4);
  for (auto& c : mild) c.raw.y += c.raw.x;  // also skew: correlated columns
  const auto m = fit_model("affine", mild).model;
  EXPECT_GT(m->stats().condition, 1e3);
  EXPECT_LT(m->stats().rms_residual, 1e-6);
  // Collinear to working precision: refused.
  auto severe = square_grid(1e-13);
  for (auto& c : severe) c.raw.y += c.raw.x;
  EXPECT_CONTAINS(fit_error("affine", severe), "do not determine");
  EXPECT_CONTAINS(fit_error("homography", severe), "do not determine");
}

TEST(CalibrationStability, MissingGridTargetIsNamed) {
  auto pts = square_grid();
  pts.erase(pts.begin() + 5);  // target (100, 200)
  const std::string msg = fit_error("bilinear-grid", pts);
  EXPECT_CONTAINS(msg, "do not form a full 3x3 grid");
  EXPECT_CONTAINS(msg, "no samples for target (100, 200)");
  // A single column is not a grid.
  std::vector<Correspondence> column;
  for (int j = 0; j < 4; ++j) column.push_back({{0, 1.0 * j}, {50, 100.0 * j}});
  EXPECT_CONTAINS(fit_error("bilinear-grid", column), "at least 2 of each");
}

TEST(CalibrationStability, GridTargetsWithinToleranceShareAGridPoint) {
  auto pts = square_grid();
  pts.push_back({{0.1, 0.1}, {0.01, -0.02}});  // a second sample of target (0, 0), slightly off
  const BilinearGrid g = BilinearGrid::fit(pts);
  EXPECT_EQ(g.xs.size(), 3u);
  EXPECT_EQ(g.ys.size(), 3u);
}

TEST(CalibrationStability, GridExtrapolationIsConstantOutward) {
  const BilinearGrid g = BilinearGrid::fit(square_grid());
  const Point far = g.correction({1e9, -1e9}), corner = g.vector_at(2, 0);
  EXPECT_EQ(far, corner);
}

class CalibrationFileStability : public ::testing::Test {
 protected:
  fs::path path_ = fs::temp_directory_path() / ("fovea-calib-stab-" + std::to_string(::getpid()) + ".json");
  void TearDown() override { fs::remove(path_); }
  void write(const std::string& text) {
    std::ofstream(path_, std::ios::trunc) << text;
  }
  std::string load_error() {
    return error_of([&] { (void)load_calibration(path_); });
  }
};

TEST_F(CalibrationFileStability, NewerVersionIsRefusedClearly) {
  write(R"({"format":"fovea-calibration","version":2,"model":{"kind":"warp9"}})");
  EXPECT_EQ(load_error(), path_.string() + ": written by a newer fovea (version 2); this build reads version 1");
}

// Issue 23 item 7, for the file a control request names: deep nesting is refused while parsing.
TEST_F(CalibrationFileStability, DeepNestingIsRefusedWhileParsing) {
  write("{\"model\": " + std::string(100000, '[') + std::string(100000, ']') + "}");
  EXPECT_EQ(load_error(), path_.string() + ": nested deeper than 32 levels; not a fovea calibration file");
  write(std::string(31, '[') + std::string(31, ']'));
  EXPECT_CONTAINS(load_error(), "must be a JSON object");
}

TEST_F(CalibrationFileStability, BadFieldsAreNamed) {
  write("{not json");
  EXPECT_CONTAINS(load_error(), "not valid JSON");
  write(R"({"format":"something-else","version":1})");
  EXPECT_CONTAINS(load_error(), "field 'format'");
  const std::string good_tail = R"(,"points_used":9,"rms_residual":0.5,"condition":2,"created":"2026-01-01T00:00:00Z"})";
  write(R"({"format":"fovea-calibration","version":1,"model":{"a":[1,0,0,0,1,0]})" + good_tail);
  std::string msg = load_error();
  EXPECT_CONTAINS(msg, path_.string() + ": model: field 'kind' is missing");
  write(R"({"format":"fovea-calibration","version":1,"model":{"kind":"affine","a":[1,0,0]})" + good_tail);
  EXPECT_CONTAINS(load_error(), "field 'a' must be an array of 6 numbers");
  write(R"({"format":"fovea-calibration","version":1,"model":{"kind":"bilinear-grid","xs":[0,1],"ys":[0,1],"vectors":[[0,0],[0,0],[0,0]]})" +
        good_tail);
  EXPECT_CONTAINS(load_error(), "field 'vectors' must be an array of 4");
  write(R"({"format":"fovea-calibration","version":1,"model":{"kind":"affine","a":[1,0,0,0,1,0]},"points_used":9})");
  EXPECT_CONTAINS(load_error(), "field 'rms_residual' is missing");
  write(R"({"format":"fovea-calibration","version":1,"model":{"kind":"affine","a":[1,0,0,0,1,0]})" + good_tail);
  EXPECT_EQ(load_error(), "(no error)");
  fs::remove(path_);
  EXPECT_CONTAINS(load_error(), "cannot open");
}

}  // namespace
