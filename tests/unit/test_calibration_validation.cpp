// SPDX-License-Identifier: Apache-2.0
// fovea::calib validation: display geometry (pixels -> millimetres -> visual angle), accuracy and
// precision per target and overall (Jensen & Pedersen 2009, Tables 4.1/4.2), lost samples,
// before/after, the table and JSON.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include "fovea/calib/display.h"
#include "fovea/calib/validation.h"

namespace {

using namespace fovea::calib;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kDeg = 180.0 / std::numbers::pi;

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  } catch (const std::exception& e) {
    return std::string("(wrong exception type) ") + e.what();
  }
  return "(no error)";
}

#define EXPECT_CONTAINS(haystack, needle) \
  EXPECT_NE(std::string(haystack).find(needle), std::string::npos) << "message: " << (haystack)

// Reference angle in long double: acos of the normalised dot product (fine for angles that are not
// tiny).
double reference_angle_deg(const Display& d, Point a, Point b) {
  const Point ma = px_to_mm(d, a), mb = px_to_mm(d, b);
  const long double ax = ma.x, ay = ma.y, az = d.distance_mm, bx = mb.x, by = mb.y, bz = d.distance_mm;
  const long double dot = ax * bx + ay * by + az * bz;
  const long double na = std::sqrt(ax * ax + ay * ay + az * az), nb = std::sqrt(bx * bx + by * by + bz * bz);
  return static_cast<double>(std::acos(dot / (na * nb)) * 180.0L / std::numbers::pi_v<long double>);
}

const Display kDisplay{};  // 1920x1080 px, 531.3x298.9 mm, 650 mm
const Point kCentre{960, 540};

std::vector<ValidationSample> at(Point target, const std::vector<Point>& measured) {
  std::vector<ValidationSample> out;
  for (const Point& m : measured) out.push_back({target, m, std::nullopt});
  return out;
}

void expect_all_finite(const ErrorStats& s) {
  for (const double v : {s.accuracy_deg, s.accuracy_mm, s.precision_rms_deg, s.precision_std_deg, s.min_deg, s.max_deg,
                         s.mean_error_px.x, s.mean_error_px.y}) {
    EXPECT_TRUE(std::isfinite(v));
  }
}

// --- display ---

TEST(CalibrationDisplay, DefaultIsUsableAndMillimetresAreFromTheCentre) {
  EXPECT_EQ(check(kDisplay), "");
  EXPECT_DOUBLE_EQ(px_per_mm(kDisplay), 1920 / 531.3);
  const Point c = px_to_mm(kDisplay, kCentre);
  EXPECT_DOUBLE_EQ(c.x, 0);
  EXPECT_DOUBLE_EQ(c.y, 0);
  const Point corner = px_to_mm(kDisplay, {1920, 1080});
  EXPECT_NEAR(corner.x, 531.3 / 2, 1e-12);
  EXPECT_NEAR(corner.y, 298.9 / 2, 1e-12);
  const Point top_left = px_to_mm(kDisplay, {0, 0});
  EXPECT_NEAR(top_left.x, -531.3 / 2, 1e-12);
  EXPECT_NEAR(top_left.y, -298.9 / 2, 1e-12);
}

TEST(CalibrationDisplay, OnePixelAtTheCentre) {
  // A 1-pixel horizontal error at the centre: atan(1 / px_per_mm / distance).
  const double want = std::atan(1 / px_per_mm(kDisplay) / kDisplay.distance_mm) * kDeg;
  EXPECT_NEAR(angle_between_deg(kDisplay, kCentre, {kCentre.x + 1, kCentre.y}), want, want * 1e-12);
  EXPECT_NEAR(angle_between_deg(kDisplay, {kCentre.x + 1, kCentre.y}, kCentre), want, want * 1e-12);
  EXPECT_NEAR(want * 60, 1.4636, 1e-3);  // about 1.46 arcmin
  // Vertically, with the vertical pixel pitch.
  const double want_y = std::atan(kDisplay.height_mm / kDisplay.height_px / kDisplay.distance_mm) * kDeg;
  EXPECT_NEAR(angle_between_deg(kDisplay, kCentre, {kCentre.x, kCentre.y - 1}), want_y, want_y * 1e-12);
  EXPECT_EQ(angle_between_deg(kDisplay, kCentre, kCentre), 0.0);
}

TEST(CalibrationDisplay, AnglesMatchTheDirectFormulaAndAreSymmetric) {
  // From the centre to a point: atan(r / distance).
  const Point corner{1920, 1080};
  const Point mm = px_to_mm(kDisplay, corner);
  EXPECT_NEAR(angle_between_deg(kDisplay, kCentre, corner), std::atan(std::hypot(mm.x, mm.y) / 650) * kDeg, 1e-12);
  // Corner to corner, and between arbitrary points, against acos in long double.
  for (const auto& [a, b] : std::vector<std::pair<Point, Point>>{
           {{0, 0}, {1920, 1080}}, {{100, 900}, {1700, 200}}, {{-3000, 500}, {5000, 600}}, {{300, 300}, {310, 290}}}) {
    EXPECT_NEAR(angle_between_deg(kDisplay, a, b), reference_angle_deg(kDisplay, a, b), 1e-9);
    EXPECT_DOUBLE_EQ(angle_between_deg(kDisplay, a, b), angle_between_deg(kDisplay, b, a));
  }
  // Mirror images about the centre subtend the same angle.
  EXPECT_NEAR(angle_between_deg(kDisplay, {100, 100}, {110, 100}), angle_between_deg(kDisplay, {1820, 980}, {1810, 980}),
              1e-12);
  // Tiny angles keep their precision (1e-6 px at the corner).
  const double tiny = angle_between_deg(kDisplay, corner, {corner.x + 1e-6, corner.y});
  const double small = angle_between_deg(kDisplay, corner, {corner.x + 1e-2, corner.y});
  EXPECT_GT(tiny, 0);
  EXPECT_NEAR(tiny / small, 1e-4, 1e-9);
  // Opposite directions far away: 180 degrees; non-finite: NaN.
  EXPECT_NEAR(angle_between_deg(kDisplay, {-1e300, 540}, {1e300, 540}), 180, 1e-9);
  EXPECT_TRUE(std::isnan(angle_between_deg(kDisplay, {kNaN, 0}, kCentre)));
}

TEST(CalibrationDisplay, CheckNamesTheBadField) {
  Display d;
  d.width_px = 0;
  EXPECT_CONTAINS(check(d), "width_px");
  d = {};
  d.height_px = 70000;
  EXPECT_CONTAINS(check(d), "height_px");
  d = {};
  d.width_mm = kNaN;
  EXPECT_CONTAINS(check(d), "width_mm");
  d = {};
  d.height_mm = -1;
  EXPECT_CONTAINS(check(d), "height_mm");
  d = {};
  d.distance_mm = std::numeric_limits<double>::infinity();
  EXPECT_CONTAINS(check(d), "distance_mm");
  d = {};
  d.distance_mm = 200000;
  EXPECT_CONTAINS(check(d), "distance_mm");
}

TEST(CalibrationDisplay, JsonRoundTrip) {
  const Display d{1680, 1050, 473.76, 296.1, 650};
  const nlohmann::json j = to_json(d);
  EXPECT_EQ(j.at("width_px"), 1680);
  EXPECT_EQ(j.at("distance_mm"), 650);
  EXPECT_EQ(display_from_json(j, "cal.json: display"), d);
  EXPECT_EQ(display_from_json(nlohmann::json::parse(j.dump()), "x"), d);

  nlohmann::json missing = j;
  missing.erase("height_mm");
  EXPECT_CONTAINS(error_of([&] { (void)display_from_json(missing, "cal.json: display"); }),
                  "cal.json: display: field 'height_mm' is missing");
  nlohmann::json text = j;
  text["width_px"] = "1680";
  EXPECT_CONTAINS(error_of([&] { (void)display_from_json(text, "cal.json: display"); }),
                  "field 'width_px' must be a number");
  nlohmann::json zero = j;
  zero["distance_mm"] = 0;
  EXPECT_CONTAINS(error_of([&] { (void)display_from_json(zero, "cal.json: display"); }), "cal.json: display: distance_mm");
  EXPECT_CONTAINS(error_of([&] { (void)display_from_json(nlohmann::json::array(), "here"); }), "here: must be a JSON object");
}

TEST(CalibrationDisplay, TextFormRoundTripAndParseErrors) {
  const Display d = parse_display("1920x1080@531.3x298.9mm,650mm");
  EXPECT_EQ(d, Display{});
  EXPECT_EQ(to_string(d), "1920x1080@531.3x298.9mm,650mm");
  EXPECT_EQ(parse_display(to_string(Display{1680, 1050, 473.76, 296.1, 700})), (Display{1680, 1050, 473.76, 296.1, 700}));
  for (const char* bad : {"", "1920x1080", "1920x1080@531.3x298.9mm", "1920x1080@531.3x298.9mm,650",
                          "1920x1080@531.3x298.9mm,650mm trailing", " 1920x1080@531.3x298.9mm,650mm", "abc",
                          "1920*1080@531.3x298.9mm,650mm", "0x10x1080@531.3x298.9mm,650mm",
                          "+1920x1080@531.3x298.9mm,650mm"}) {
    EXPECT_CONTAINS(error_of([&] { (void)parse_display(bad); }), "is not of the form WxH@WMMxHMMmm,DISTmm") << bad;
  }
  EXPECT_CONTAINS(error_of([&] { (void)parse_display("0x1080@531.3x298.9mm,650mm"); }), "width_px");
  EXPECT_CONTAINS(error_of([&] { (void)parse_display("1920x1080@531.3x298.9mm,-650mm"); }), "distance_mm");
  EXPECT_CONTAINS(error_of([&] { (void)parse_display("1920x1080@nanx298.9mm,650mm"); }), "width_mm");
}

// --- validation ---

TEST(CalibrationValidation, AccuracyInDegreesAndMillimetres) {
  // Target at the centre, every sample 10 px to the right.
  const auto r = validate(at(kCentre, {{970, 540}, {970, 540}, {970, 540}}), kDisplay);
  ASSERT_EQ(r.targets.size(), 1u);
  const ErrorStats& s = r.targets[0].after;
  EXPECT_EQ(s.samples, 3u);
  EXPECT_EQ(s.lost, 0u);
  const double want = std::atan(10 / px_per_mm(kDisplay) / 650) * kDeg;
  EXPECT_NEAR(s.accuracy_deg, want, 1e-12);
  EXPECT_NEAR(s.accuracy_mm, 10 / px_per_mm(kDisplay), 1e-12);
  EXPECT_NEAR(s.min_deg, want, 1e-12);
  EXPECT_NEAR(s.max_deg, want, 1e-12);
  EXPECT_NEAR(s.mean_error_px.x, 10, 1e-12);
  EXPECT_NEAR(s.mean_error_px.y, 0, 1e-12);
  EXPECT_EQ(s.precision_rms_deg, 0);  // identical samples
  EXPECT_EQ(s.precision_std_deg, 0);
  EXPECT_FALSE(r.before.has_value());
  EXPECT_FALSE(r.targets[0].before.has_value());
  // Overall = the only target.
  EXPECT_DOUBLE_EQ(r.after.accuracy_deg, s.accuracy_deg);
  EXPECT_EQ(r.after.samples, 3u);
}

TEST(CalibrationValidation, SymmetricTargetsHaveEqualErrors) {
  // Targets mirrored about the centre, errors mirrored too (10 px outwards, 5 px down/up).
  std::vector<ValidationSample> v = at({460, 240}, {{450, 235}, {450, 235}});
  const auto w = at({1460, 840}, {{1470, 845}, {1470, 845}});
  v.insert(v.end(), w.begin(), w.end());
  const auto r = validate(v, kDisplay);
  ASSERT_EQ(r.targets.size(), 2u);
  EXPECT_NEAR(r.targets[0].after.accuracy_deg, r.targets[1].after.accuracy_deg, 1e-12);
  EXPECT_NEAR(r.targets[0].after.accuracy_mm, r.targets[1].after.accuracy_mm, 1e-12);
  // Off-centre a pixel subtends less than at the centre.
  const double at_centre = std::atan(std::hypot(10 / px_per_mm(kDisplay), 5 * 298.9 / 1080) / 650) * kDeg;
  EXPECT_LT(r.targets[0].after.accuracy_deg, at_centre);
  EXPECT_NEAR(r.after.accuracy_deg, r.targets[0].after.accuracy_deg, 1e-12);
  EXPECT_NEAR(r.after.mean_error_px.x, 0, 1e-12);  // the mirrored vectors cancel
}

TEST(CalibrationValidation, PrecisionRmsVersusStd) {
  // theta = the angle of 1 px at the centre; the samples lie within 3 px of it, where the angle per
  // pixel is the same to 1e-5 relative.
  const double theta = angle_between_deg(kDisplay, kCentre, {kCentre.x + 1, kCentre.y});
  const auto px = [](double dx) { return Point{kCentre.x + dx, kCentre.y}; };
  // Jitter between 0 and +2 px: every step is 2 px, so RMS = 2 theta; the mean is +1 px, every
  // sample 1 px from it, so STD = theta. Accuracy: mean of 0, 2, 0, 2 px = 1 px.
  {
    const auto s = validate(at(kCentre, {px(0), px(2), px(0), px(2)}), kDisplay).targets[0].after;
    EXPECT_NEAR(s.precision_rms_deg, 2 * theta, 2 * theta * 1e-5);
    EXPECT_NEAR(s.precision_std_deg, theta, theta * 1e-5);
    EXPECT_NEAR(s.accuracy_deg, theta, theta * 1e-5);
    EXPECT_NEAR(s.min_deg, 0, 1e-15);
    EXPECT_NEAR(s.max_deg, 2 * theta, 2 * theta * 1e-5);
  }
  // A slow drift 0, 1, 2, 3 px: steps of 1 px, RMS = theta; about the mean (1.5 px) the distances
  // are 1.5, 0.5, 0.5, 1.5 px: STD = sqrt((2.25 + 0.25 + 0.25 + 2.25) / 4) theta = sqrt(1.25) theta.
  {
    const auto s = validate(at(kCentre, {px(0), px(1), px(2), px(3)}), kDisplay).targets[0].after;
    EXPECT_NEAR(s.precision_rms_deg, theta, theta * 1e-5);
    EXPECT_NEAR(s.precision_std_deg, std::sqrt(1.25) * theta, theta * 1e-5);
    EXPECT_NEAR(s.accuracy_deg, 1.5 * theta, theta * 1e-5);
  }
  // Steps of 3 and 4 px at right angles: RMS = sqrt((9 + 16) / 2) theta.
  {
    const auto s =
        validate(at(kCentre, {kCentre, {kCentre.x + 3, kCentre.y}, {kCentre.x + 3, kCentre.y + 4 * 1080 / 298.9 * 531.3 / 1920}}),
                 kDisplay)
            .targets[0]
            .after;
    EXPECT_NEAR(s.precision_rms_deg, std::sqrt(12.5) * theta, theta * 1e-4);
  }
  // One sample: no pairs, no spread.
  {
    const auto s = validate(at(kCentre, {px(5)}), kDisplay).targets[0].after;
    EXPECT_EQ(s.samples, 1u);
    EXPECT_EQ(s.precision_rms_deg, 0);
    EXPECT_EQ(s.precision_std_deg, 0);
    EXPECT_NEAR(s.accuracy_deg, 5 * theta, theta * 1e-4);
  }
}

TEST(CalibrationValidation, LostSamplesAreCountedAndNeverProduceNaN) {
  const auto px = [](double dx) { return Point{kCentre.x + dx, kCentre.y}; };
  const double inf = std::numeric_limits<double>::infinity();
  // Lost samples between usable ones are skipped: the pairs are (0, 2) and (2, 0).
  const auto r = validate(at(kCentre, {px(0), {kNaN, kNaN}, px(2), {kNaN, 540}, {inf, 0}, px(0)}), kDisplay);
  const ErrorStats& s = r.targets[0].after;
  EXPECT_EQ(s.samples, 3u);
  EXPECT_EQ(s.lost, 3u);
  expect_all_finite(s);
  const double theta = angle_between_deg(kDisplay, kCentre, px(1));
  EXPECT_NEAR(s.precision_rms_deg, 2 * theta, 2 * theta * 1e-5);
  EXPECT_NEAR(s.accuracy_deg, 2 * theta / 3, theta * 1e-5);
  EXPECT_EQ(r.after.lost, 3u);
  const std::string dumped = to_json(r).at("targets").at(0).at("after").dump();
  EXPECT_EQ(dumped.find("null"), std::string::npos) << dumped;  // every figure present
  EXPECT_EQ(format_table(r).find("nan"), std::string::npos);
}

TEST(CalibrationValidation, TargetWithOnlyLostSamples) {
  std::vector<ValidationSample> v = at({100, 100}, {{kNaN, kNaN}, {kNaN, kNaN}});
  const auto w = at(kCentre, {{970, 540}, {970, 540}});
  v.insert(v.end(), w.begin(), w.end());
  const auto r = validate(v, kDisplay);
  ASSERT_EQ(r.targets.size(), 2u);
  const ErrorStats& empty = r.targets[0].after;
  EXPECT_FALSE(empty.has_data());
  EXPECT_EQ(empty.samples, 0u);
  EXPECT_EQ(empty.lost, 2u);
  expect_all_finite(empty);
  EXPECT_EQ(empty.accuracy_deg, 0);
  // Skipped in the overall mean, counted in the overall lost.
  EXPECT_DOUBLE_EQ(r.after.accuracy_deg, r.targets[1].after.accuracy_deg);
  EXPECT_EQ(r.after.samples, 2u);
  EXPECT_EQ(r.after.lost, 2u);
  // JSON: absent figures are null, the counts are there.
  const nlohmann::json j = to_json(r);
  const auto& t0 = j.at("targets").at(0);
  EXPECT_EQ(t0.at("target_px"), nlohmann::json::array({100.0, 100.0}));
  EXPECT_EQ(t0.at("after").at("samples"), 0);
  EXPECT_EQ(t0.at("after").at("lost"), 2);
  for (const char* k : {"accuracy_deg", "accuracy_mm", "precision_rms_deg", "precision_std_deg", "min_deg", "max_deg",
                        "mean_error_px"}) {
    EXPECT_TRUE(t0.at("after").at(k).is_null()) << k;
    EXPECT_TRUE(j.at("targets").at(1).at("after").at(k).is_number() || j.at("targets").at(1).at("after").at(k).is_array())
        << k;
  }
  EXPECT_TRUE(t0.at("before").is_null());
  EXPECT_TRUE(j.at("overall").at("before").is_null());
  const std::string table = format_table(r);
  EXPECT_CONTAINS(table, "overall");
  EXPECT_CONTAINS(table, " -");
  EXPECT_CONTAINS(table, "1 target(s) had only lost samples");
}

TEST(CalibrationValidation, RefusesWhatCannotBeValidated) {
  EXPECT_CONTAINS(error_of([] { (void)validate({}, kDisplay); }), "no samples");
  EXPECT_CONTAINS(error_of([] { (void)validate(at(kCentre, {{kNaN, kNaN}, {kNaN, 1}}), kDisplay); }),
                  "no usable sample: all 2 measured points are lost");
  EXPECT_CONTAINS(error_of([] { (void)validate(at({kNaN, 5}, {kCentre}), kDisplay); }), "sample 1: target");
  Display bad;
  bad.distance_mm = 0;
  EXPECT_CONTAINS(error_of([&] { (void)validate(at(kCentre, {kCentre}), bad); }), "distance_mm");
}

TEST(CalibrationValidation, TargetsInOrderOfFirstAppearance) {
  const std::vector<ValidationSample> v{{{500, 500}, {501, 500}, std::nullopt},
                                        {{100, 100}, {100, 101}, std::nullopt},
                                        {{500, 500}, {503, 500}, std::nullopt},
                                        {{-0.0, 7}, {0, 7}, std::nullopt},
                                        {{0.0, 7}, {0, 8}, std::nullopt}};
  const auto r = validate(v, kDisplay);
  ASSERT_EQ(r.targets.size(), 3u);
  EXPECT_EQ(r.targets[0].target_px, (Point{500, 500}));
  EXPECT_EQ(r.targets[0].after.samples, 2u);
  EXPECT_NEAR(r.targets[0].after.mean_error_px.x, 2, 1e-12);
  EXPECT_EQ(r.targets[1].target_px, (Point{100, 100}));
  EXPECT_EQ(r.targets[2].after.samples, 2u);  // -0 and +0 are the same target
  // Overall: each target weighs the same.
  double sum = 0;
  for (const auto& t : r.targets) sum += t.after.accuracy_deg;
  EXPECT_NEAR(r.after.accuracy_deg, sum / 3, 1e-15);
  EXPECT_EQ(r.after.samples, 5u);
  double lo = 1e9, hi = 0;
  for (const auto& t : r.targets) {
    lo = std::min(lo, t.after.min_deg);
    hi = std::max(hi, t.after.max_deg);
  }
  EXPECT_EQ(r.after.min_deg, lo);
  EXPECT_EQ(r.after.max_deg, hi);
}

TEST(CalibrationValidation, BeforeAndAfter) {
  std::vector<ValidationSample> v;
  for (int i = 0; i < 4; ++i) {
    v.push_back({kCentre, {961, 540}, Point{980, 550}});
    v.push_back({{200, 200}, {200, 199}, Point{230, 240}});
  }
  v.push_back({{200, 200}, {201, 200}, Point{kNaN, kNaN}});  // lost before, not after
  const auto r = validate(v, kDisplay);
  ASSERT_TRUE(r.before.has_value());
  ASSERT_TRUE(r.targets[0].before.has_value());
  EXPECT_EQ(r.targets[1].before->samples, 4u);
  EXPECT_EQ(r.targets[1].before->lost, 1u);
  EXPECT_EQ(r.targets[1].after.samples, 5u);
  EXPECT_NEAR(r.targets[0].before->mean_error_px.x, 20, 1e-12);
  EXPECT_NEAR(r.targets[0].before->mean_error_px.y, 10, 1e-12);
  EXPECT_NEAR(r.targets[0].before->accuracy_deg, angle_between_deg(kDisplay, kCentre, {980, 550}), 1e-12);
  EXPECT_GT(r.before->accuracy_deg, 5 * r.after.accuracy_deg);
  const nlohmann::json j = to_json(r);
  EXPECT_TRUE(j.at("overall").at("before").at("accuracy_deg").is_number());
  EXPECT_EQ(j.at("targets").at(1).at("before").at("lost"), 1);
  const std::string table = format_table(r);
  EXPECT_CONTAINS(table, "before");
  EXPECT_CONTAINS(table, "after");
  EXPECT_CONTAINS(table, "overall");

  // One sample without a before: no before anywhere.
  v.push_back({kCentre, {960, 541}, std::nullopt});
  const auto r2 = validate(v, kDisplay);
  EXPECT_FALSE(r2.before.has_value());
  for (const auto& t : r2.targets) EXPECT_FALSE(t.before.has_value());
  EXPECT_EQ(format_table(r2).find("before"), std::string::npos);
}

TEST(CalibrationValidation, FarOffScreenSamplesStayFinite) {
  const auto r = validate(at(kCentre, {{1e6, 540}, {-1e300, 1e300}, {1.7e308, -1.7e308}, {970, 540}}), kDisplay);
  const ErrorStats& s = r.targets[0].after;
  EXPECT_EQ(s.samples, 4u);
  expect_all_finite(s);
  EXPECT_LE(s.max_deg, 180);
  EXPECT_GT(s.max_deg, 89);
  EXPECT_EQ(format_table(r).find("nan"), std::string::npos);
  EXPECT_EQ(format_table(r).find("inf"), std::string::npos);
}

}  // namespace
