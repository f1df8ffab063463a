// SPDX-License-Identifier: Apache-2.0
// fovea::calib::Poly2Map and the least-squares solver under it.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "fovea/calib/least_squares.h"
#include "fovea/calib/poly2.h"

namespace {

using fovea::calib::Correspondence;
using fovea::calib::Matrix;
using fovea::calib::Point;
using fovea::calib::Poly2Map;

// A known quadratic in raw units (pupil-glint-like vectors of a few pixels to normalised screen).
Point truth(Point r) {
  return {0.5 + 0.04 * r.x - 0.002 * r.y + 0.0015 * r.x * r.y + 0.0009 * r.x * r.x - 0.0004 * r.y * r.y,
          0.45 + 0.001 * r.x + 0.05 * r.y - 0.0007 * r.x * r.y + 0.0002 * r.x * r.x + 0.0012 * r.y * r.y};
}

std::vector<Correspondence> grid(int n, double half, Point offset = {}) {
  std::vector<Correspondence> out;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const Point r{offset.x - half + 2 * half * i / (n - 1), offset.y - half + 2 * half * j / (n - 1)};
      out.push_back({r, truth(r)});
    }
  }
  return out;
}

std::string message_of(const std::vector<Correspondence>& pts) {
  try {
    (void)Poly2Map::fit(pts);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(no exception)";
}

TEST(LeastSquares, SolvesASquareSystemExactly) {
  Matrix a(3, 3), b(3, 1);
  const double av[3][3] = {{2, 1, 0}, {1, 3, 1}, {0, 1, 4}};
  const double x[3] = {1, -2, 0.5};
  for (std::size_t i = 0; i < 3; ++i) {
    for (std::size_t j = 0; j < 3; ++j) {
      a(i, j) = av[i][j];
      b(i, 0) += av[i][j] * x[j];
    }
  }
  const auto s = fovea::calib::solve_least_squares(a, b);
  ASSERT_TRUE(s.full_rank);
  for (std::size_t j = 0; j < 3; ++j) EXPECT_NEAR(s.x(j, 0), x[j], 1e-14);
  EXPECT_GT(s.condition, 1.0);
  EXPECT_GE(s.condition, s.r_diagonal_ratio * (1 - 1e-12));  // the |R_ii| ratio is a lower bound
}

TEST(LeastSquares, SingularValuesOfADiagonalMatrix) {
  Matrix a(4, 3);
  a(0, 0) = 3;
  a(1, 1) = -7;
  a(2, 2) = 0.5;
  const auto sv = fovea::calib::singular_values(a);
  ASSERT_EQ(sv.size(), 3u);
  EXPECT_NEAR(sv[0], 7, 1e-14);
  EXPECT_NEAR(sv[1], 3, 1e-14);
  EXPECT_NEAR(sv[2], 0.5, 1e-14);
}

TEST(LeastSquares, MinimisesTheResidualOfAnOverdeterminedSystem) {
  // Line fit y = c0 + c1 t through points off the line: the normal equations give the answer.
  const std::vector<double> t = {0, 1, 2, 3, 4}, y = {1.1, 2.9, 5.2, 6.8, 9.1};
  Matrix a(5, 2), b(5, 1);
  for (std::size_t i = 0; i < 5; ++i) {
    a(i, 0) = 1;
    a(i, 1) = t[i];
    b(i, 0) = y[i];
  }
  const auto s = fovea::calib::solve_least_squares(a, b);
  ASSERT_TRUE(s.full_rank);
  // Closed form: slope = cov(t, y) / var(t), intercept = mean(y) - slope mean(t).
  const double mt = 2, my = (1.1 + 2.9 + 5.2 + 6.8 + 9.1) / 5;
  double cov = 0, var = 0;
  for (std::size_t i = 0; i < 5; ++i) {
    cov += (t[i] - mt) * (y[i] - my);
    var += (t[i] - mt) * (t[i] - mt);
  }
  EXPECT_NEAR(s.x(1, 0), cov / var, 1e-13);
  EXPECT_NEAR(s.x(0, 0), my - cov / var * mt, 1e-13);
}

TEST(LeastSquares, ReportsRankDeficiencyWithoutThrowing) {
  Matrix a(4, 3), b(4, 1);
  for (std::size_t i = 0; i < 4; ++i) {
    a(i, 0) = 1;
    a(i, 1) = static_cast<double>(i);
    a(i, 2) = 2.0 * static_cast<double>(i) + 1;  // = col0 + 2 col1
  }
  const auto s = fovea::calib::solve_least_squares(a, b);
  EXPECT_FALSE(s.full_rank);
  EXPECT_EQ(s.rank, 2u);
  EXPECT_GT(s.condition, 1e12);
  EXPECT_THROW((void)fovea::calib::solve_least_squares(Matrix(2, 3), Matrix(2, 1)), std::invalid_argument);
  EXPECT_THROW((void)fovea::calib::solve_least_squares(Matrix(4, 3), Matrix(3, 1)), std::invalid_argument);
}

TEST(Poly2Map, RecoversAKnownPolynomialExactly) {
  for (const Point offset : {Point{0, 0}, Point{250, -140}}) {  // also far from the origin (conditioning)
    const auto pts = grid(5, 12, offset);
    const Poly2Map m = Poly2Map::fit(pts);
    EXPECT_EQ(m.points, 25u);
    EXPECT_LT(m.rms_residual, 1e-12);
    EXPECT_LT(m.max_residual, 1e-12);
    EXPECT_GT(m.condition, 1);
    EXPECT_LT(m.condition, 20) << "normalisation should make a square grid well conditioned";
    // Off the fitted points too, including outside the grid.
    for (const Point r : {Point{offset.x + 3.3, offset.y - 7.1}, Point{offset.x - 15, offset.y + 15}}) {
      const Point got = m.apply(r), want = truth(r);
      EXPECT_NEAR(got.x, want.x, 1e-10);
      EXPECT_NEAR(got.y, want.y, 1e-10);
    }
  }
}

TEST(Poly2Map, SixPointsInGeneralPositionAreEnough) {
  std::vector<Correspondence> pts;
  for (const Point r : {Point{0, 0}, Point{10, 0}, Point{0, 10}, Point{10, 10}, Point{5, 2}, Point{3, 8}}) {
    pts.push_back({r, truth(r)});
  }
  const Poly2Map m = Poly2Map::fit(pts);
  EXPECT_LT(m.rms_residual, 1e-12);
  const Point got = m.apply({7, 7}), want = truth({7, 7});
  EXPECT_NEAR(got.x, want.x, 1e-9);
  EXPECT_NEAR(got.y, want.y, 1e-9);
}

TEST(Poly2Map, NoisyTargetsGiveResidualsAtTheNoiseLevel) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> noise(0.0, 0.002);
  auto pts = grid(9, 10);
  const auto clean = pts;
  for (auto& c : pts) c.target = {c.target.x + noise(rng), c.target.y + noise(rng)};
  const Poly2Map m = Poly2Map::fit(pts);
  // 81 points, 6 parameters per axis: the residual is close to the noise (sqrt(2) for two axes).
  EXPECT_GT(m.rms_residual, 0.002);
  EXPECT_LT(m.rms_residual, 0.0035);
  EXPECT_GE(m.max_residual, m.rms_residual);
  // The fitted map is closer to the truth than the noise is.
  double err2 = 0;
  for (const auto& c : clean) {
    const Point p = m.apply(c.raw);
    err2 += std::pow(p.x - c.target.x, 2) + std::pow(p.y - c.target.y, 2);
  }
  EXPECT_LT(std::sqrt(err2 / static_cast<double>(clean.size())), 0.0015);
}

TEST(Poly2Map, RefusesTooFewPoints) {
  auto pts = grid(3, 5);
  pts.resize(5);
  const std::string msg = message_of(pts);
  EXPECT_NE(msg.find("5 correspondence"), std::string::npos) << msg;
  EXPECT_NE(msg.find("at least 6"), std::string::npos) << msg;
  EXPECT_NE(message_of({}).find("0 correspondence"), std::string::npos);
}

TEST(Poly2Map, RefusesCollinearPoints) {
  std::vector<Correspondence> pts;
  for (int i = 0; i < 12; ++i) {
    const Point r{1.0 + 0.7 * i, -2.0 + 0.3 * i};  // all on one line
    pts.push_back({r, truth(r)});
  }
  const std::string msg = message_of(pts);
  EXPECT_NE(msg.find("do not determine"), std::string::npos) << msg;
  EXPECT_NE(msg.find("collinear"), std::string::npos) << msg;
  // Horizontal line (v constant) and points on one circle (a conic) are degenerate too.
  for (auto& c : pts) c.raw.y = 3;
  EXPECT_NE(message_of(pts).find("do not determine"), std::string::npos);
  std::vector<Correspondence> circle;
  for (int i = 0; i < 10; ++i) {
    const double a = 0.6 * i;
    const Point r{5 * std::cos(a), 5 * std::sin(a)};
    circle.push_back({r, truth(r)});
  }
  EXPECT_NE(message_of(circle).find("rank 5 of 6"), std::string::npos) << message_of(circle);
  // Six copies of three points: not enough distinct points.
  std::vector<Correspondence> repeated;
  for (int k = 0; k < 2; ++k) {
    for (const Point r : {Point{0, 0}, Point{4, 1}, Point{1, 5}}) repeated.push_back({r, truth(r)});
  }
  EXPECT_NE(message_of(repeated).find("do not determine"), std::string::npos);
}

TEST(Poly2Map, RefusesNonFiniteInput) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  for (int field = 0; field < 4; ++field) {
    auto pts = grid(3, 5);
    double* f[4] = {&pts[4].raw.x, &pts[4].raw.y, &pts[4].target.x, &pts[4].target.y};
    *f[field] = field % 2 ? inf : nan;
    const std::string msg = message_of(pts);
    EXPECT_NE(msg.find("correspondence 4"), std::string::npos) << msg;
    EXPECT_NE(msg.find("not finite"), std::string::npos) << msg;
  }
  auto pts = grid(3, 5);
  pts[0].raw.x = 1e200;
  EXPECT_NE(message_of(pts).find("not finite"), std::string::npos);
}

TEST(Poly2Map, ApplyOfNonFiniteInputIsNotFinite) {
  const Poly2Map m = Poly2Map::fit(grid(4, 5));
  const Point p = m.apply({std::numeric_limits<double>::quiet_NaN(), 0});
  EXPECT_FALSE(std::isfinite(p.x) && std::isfinite(p.y));
  EXPECT_NE(m.describe().find("poly2, 16 points"), std::string::npos) << m.describe();
}

}  // namespace
