// SPDX-License-Identifier: Apache-2.0
#include <gtest/gtest.h>

#include <cmath>

#include "fovea/protocol/display_geometry.h"

using namespace fovea::protocol;

TEST(DisplayGeometry, JensenPedersenWorkedExample) {
  // Jensen & Pedersen 2009 §2.1.1: a 22" 1680x1050 monitor has 3.55 px/mm; at 650 mm a pixel is
  // about 1.5 arc minutes, and 2 degrees span 22.7 mm.
  DisplayGeometry g;
  g.width_px = 1680;
  g.height_px = 1050;
  const double diag_m = 0.5588;
  const double aspect = 1680.0 / 1050.0;
  g.height_m = diag_m / std::sqrt(1 + aspect * aspect);
  g.width_m = g.height_m * aspect;
  g.viewing_distance_m = 0.65;
  EXPECT_NEAR(pixels_per_mm(g), 3.55, 0.005);
  EXPECT_NEAR(visual_angle_deg(1e-3 / pixels_per_mm(g), 0.65) * 60, 1.5, 0.02);
  EXPECT_NEAR(visual_angle_deg(0.0227, 0.65), 2.0, 0.005);
}

TEST(DisplayGeometry, NormalizedAndDegreesAreInverse) {
  const DisplayGeometry g;
  for (double x = -0.2; x <= 1.2; x += 0.1) {
    for (double y = -0.2; y <= 1.2; y += 0.1) {
      const Degrees d = normalized_to_degrees(g, {x, y});
      const Normalized n = degrees_to_normalized(g, d);
      EXPECT_NEAR(n.x, x, 1e-12);
      EXPECT_NEAR(n.y, y, 1e-12);
    }
  }
  const Degrees centre = normalized_to_degrees(g, {0.5, 0.5});
  EXPECT_DOUBLE_EQ(centre.x, 0.0);
  const Degrees right_edge = normalized_to_degrees(g, {1.0, 0.5});
  EXPECT_NEAR(right_edge.x, std::atan(g.width_m / 2 / g.viewing_distance_m) * 180 / M_PI, 1e-12);
  EXPECT_GT(normalized_to_degrees(g, {0.5, 0.9}).y, 0) << "y grows downwards";
}

TEST(DisplayGeometry, ExtremeAnglesStayFinite) {
  const DisplayGeometry g;
  for (double a : {-1e9, -90.0, -89.999, 89.999, 90.0, 1e9}) {
    const Normalized n = degrees_to_normalized(g, {a, a});
    EXPECT_TRUE(std::isfinite(n.x) && std::isfinite(n.y)) << a;
  }
}

TEST(DisplayGeometry, ParseAndValidate) {
  const DisplayGeometry g = parse_display_geometry("2560x1440@597x336mm,700mm");
  EXPECT_EQ(g.width_px, 2560u);
  EXPECT_DOUBLE_EQ(g.height_m, 0.336);
  EXPECT_DOUBLE_EQ(g.viewing_distance_m, 0.7);
  EXPECT_EQ(parse_display_geometry(to_string(g)), g);
  for (const char* bad : {"", "1920x1080", "0x1080@531x299mm,650mm", "1920x1080@0x299mm,650mm",
                          "1920x1080@531x299mm,-650mm", "1920x1080@531x299mm,650mm trailing", "1920x1080@nanx299mm,650mm"}) {
    try {
      parse_display_geometry(bad);
      ADD_FAILURE() << "accepted \"" << bad << "\"";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << "message must quote the input: " << e.what();
    }
  }
  DisplayGeometry zero_area;
  zero_area.height_m = 0;
  EXPECT_NE(validate(zero_area).find("height_m"), std::string::npos);
}

TEST(DisplayGeometry, AngleBetweenGazeDirections) {
  EXPECT_NEAR(angle_between_deg({0, 0}, {10, 0}), 10.0, 1e-12);
  EXPECT_NEAR(angle_between_deg({0, -7}, {0, 5}), 12.0, 1e-12);
  EXPECT_DOUBLE_EQ(angle_between_deg({3, 4}, {3, 4}), 0.0);
  // Off-axis: compare with the dot product of the two direction vectors.
  const double d2r = M_PI / 180;
  const double ax = std::tan(20 * d2r), ay = std::tan(-10 * d2r), bx = std::tan(-5 * d2r), by = std::tan(15 * d2r);
  const double dot = (ax * bx + ay * by + 1) / (std::sqrt(ax * ax + ay * ay + 1) * std::sqrt(bx * bx + by * by + 1));
  EXPECT_NEAR(angle_between_deg({20, -10}, {-5, 15}), std::acos(dot) / d2r, 1e-9);
  // Tiny angles (fixational tremor) keep their precision.
  EXPECT_NEAR(angle_between_deg({0, 0}, {1e-7, 0}), 1e-7, 1e-15);
  EXPECT_GT(angle_between_deg({1, 1}, {1 + 1e-7, 1}), 0.0);
}
