// SPDX-License-Identifier: Apache-2.0
// fovea::calib validation on random input over its whole valid domain (ctest -L stability): any
// usable display, targets anywhere, measured points on screen, far off it (1e6 px and up to the
// largest doubles), lost (NaN, infinite) — every figure that comes out is finite, the angles lie in
// [0, 180], and the table and JSON hold no NaN.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "fovea/calib/display.h"
#include "fovea/calib/validation.h"

namespace {

using namespace fovea::calib;

double log_uniform(std::mt19937_64& rng, double lo, double hi) {
  return std::exp(std::uniform_real_distribution<double>(std::log(lo), std::log(hi))(rng));
}

Display random_display(std::mt19937_64& rng) {
  Display d;
  d.width_px = std::floor(log_uniform(rng, 1, 65536));
  d.height_px = std::floor(log_uniform(rng, 1, 65536));
  d.width_mm = log_uniform(rng, 1e-3, 1e5);
  d.height_mm = log_uniform(rng, 1e-3, 1e5);
  d.distance_mm = log_uniform(rng, 1e-3, 1e5);
  return d;
}

// A measured point relative to the target: close, off screen, absurdly far, or lost.
Point random_measured(std::mt19937_64& rng, const Display& d, Point target) {
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  std::uniform_real_distribution<double> u(-1, 1);
  switch (std::uniform_int_distribution<int>(0, 9)(rng)) {
    case 0: return {nan, nan};
    case 1: return {inf, target.y};
    case 2: return {target.x + u(rng) * 1e6, target.y + u(rng) * 1e6};
    case 3: return {u(rng) * 1.7e308, u(rng) * 1.7e308};
    case 4: return {u(rng) * std::pow(10.0, std::uniform_real_distribution<double>(0, 300)(rng)), target.y};
    case 5: return target;  // exact
    case 6: return {target.x + u(rng) * 1e-9, target.y};
    default: return {target.x + u(rng) * d.width_px * 0.05, target.y + u(rng) * d.height_px * 0.05};
  }
}

bool all_numbers_finite(const nlohmann::json& j) {
  if (j.is_number()) return std::isfinite(j.get<double>());
  if (j.is_array() || j.is_object()) {
    for (const auto& v : j) {
      if (!all_numbers_finite(v)) return false;
    }
  }
  return true;
}

void expect_sane(const ErrorStats& s, const std::string& where) {
  for (const double v : {s.accuracy_deg, s.accuracy_mm, s.precision_rms_deg, s.precision_std_deg, s.min_deg, s.max_deg,
                         s.mean_error_px.x, s.mean_error_px.y}) {
    ASSERT_TRUE(std::isfinite(v)) << where;
  }
  for (const double deg : {s.accuracy_deg, s.precision_rms_deg, s.precision_std_deg, s.min_deg, s.max_deg}) {
    ASSERT_GE(deg, 0) << where;
    ASSERT_LE(deg, 180 + 1e-9) << where;
  }
  ASSERT_GE(s.accuracy_mm, 0) << where;
  ASSERT_LE(s.min_deg, s.max_deg) << where;
  if (s.has_data()) {
    ASSERT_LE(s.min_deg, s.accuracy_deg + 1e-9) << where;
    ASSERT_GE(s.max_deg, s.accuracy_deg - 1e-9) << where;
  }
}

TEST(ValidationStability, RandomInputGivesFiniteFigures) {
  std::mt19937_64 rng(20091);
  for (int trial = 0; trial < 400; ++trial) {
    const Display d = trial == 0 ? Display{} : random_display(rng);
    ASSERT_EQ(check(d), "") << to_string(d);
    const int targets = std::uniform_int_distribution<int>(1, 8)(rng);
    const bool with_before = trial % 2 == 0;
    std::vector<ValidationSample> samples;
    std::uniform_real_distribution<double> on_screen(-0.2, 1.2);
    std::vector<Point> where;
    for (int t = 0; t < targets; ++t) where.push_back({on_screen(rng) * d.width_px, on_screen(rng) * d.height_px});
    const int n = std::uniform_int_distribution<int>(1, 60)(rng);
    for (int i = 0; i < n; ++i) {
      const Point target = where[std::uniform_int_distribution<std::size_t>(0, where.size() - 1)(rng)];
      ValidationSample s{target, random_measured(rng, d, target), std::nullopt};
      if (with_before) s.before_px = random_measured(rng, d, target);
      samples.push_back(s);
    }
    samples.push_back({where[0], where[0], with_before ? std::optional<Point>(where[0]) : std::nullopt});  // one usable
    const std::string ctx = "trial " + std::to_string(trial) + " display " + to_string(d);
    ValidationResult r;
    ASSERT_NO_THROW(r = validate(samples, d)) << ctx;
    expect_sane(r.after, ctx + " overall");
    ASSERT_EQ(r.before.has_value(), with_before) << ctx;
    if (r.before) expect_sane(*r.before, ctx + " overall before");
    std::size_t total = 0;
    for (const auto& t : r.targets) {
      expect_sane(t.after, ctx);
      if (t.before) expect_sane(*t.before, ctx + " before");
      total += t.after.samples + t.after.lost;
    }
    ASSERT_EQ(total, samples.size()) << ctx;
    ASSERT_TRUE(all_numbers_finite(to_json(r))) << ctx;
    const std::string table = format_table(r);
    ASSERT_EQ(table.find("nan"), std::string::npos) << ctx << "\n" << table;
    ASSERT_EQ(table.find("inf"), std::string::npos) << ctx << "\n" << table;
  }
}

TEST(ValidationStability, AnglesBetweenAnyFinitePointsAreFinite) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1, 1), e(-300, 308);
  for (int i = 0; i < 20000; ++i) {
    const Display d = i == 0 ? Display{} : random_display(rng);
    const auto pt = [&] { return Point{u(rng) * std::pow(10.0, e(rng)), u(rng) * std::pow(10.0, e(rng))}; };
    const Point a = pt(), b = i % 3 == 0 ? Point{a.x + u(rng), a.y} : pt();
    const double deg = angle_between_deg(d, a, b);
    ASSERT_TRUE(std::isfinite(deg)) << to_string(d) << " " << a.x << "," << a.y << " " << b.x << "," << b.y;
    ASSERT_GE(deg, 0);
    ASSERT_LE(deg, 180 + 1e-9);
  }
  // The extremes.
  const double big = std::numeric_limits<double>::max();
  for (const Point a : {Point{big, big}, Point{-big, big}, Point{big, -big}, Point{0, 0}}) {
    for (const Point b : {Point{-big, -big}, Point{big, big}, Point{1, 1}}) {
      const double deg = angle_between_deg(Display{}, a, b);
      ASSERT_TRUE(std::isfinite(deg));
      ASSERT_LE(deg, 180 + 1e-9);
    }
  }
}

}  // namespace
