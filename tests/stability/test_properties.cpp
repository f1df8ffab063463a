// SPDX-License-Identifier: Apache-2.0
// Property tests (ctest -L stability): random inputs across each function's valid domain, and a
// share of hostile ones (NaN, Inf, huge, denormal), give outputs that are finite and within the
// documented bounds, or a clear refusal. Seeded: a failure names its seed and input.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include <fovea/protocol/codec.h>
#include <fovea/protocol/display_geometry.h>

#include "canonical_messages.h"
#include "dof/lens.h"
#include "lod/lod_policy.h"
#include "passes/tonemap.h"
#include "scene/shading.h"

namespace {

using namespace fovea;

constexpr int kTrials = 2000;

// A double from the valid domain most of the time, else a hostile value.
struct Source {
  std::mt19937_64 rng{20261123};
  double uniform(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); }
  double hostile() {
    static const double values[] = {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity(),
                                    -std::numeric_limits<double>::infinity(), 1e300, -1e300, 1e-310, 0.0, -0.0};
    return values[rng() % std::size(values)];
  }
  double maybe_hostile(double lo, double hi, std::uint64_t one_in = 10) { return rng() % one_in == 0 ? hostile() : uniform(lo, hi); }
};

TEST(Properties, DisplayGeometryConversionsAreFiniteAndRoundTrip) {
  Source src;
  for (int t = 0; t < kTrials; ++t) {
    protocol::DisplayGeometry g;
    g.width_m = src.uniform(0.05, 2);
    g.height_m = src.uniform(0.05, 1.5);
    g.viewing_distance_m = src.uniform(0.1, 3);
    ASSERT_EQ(protocol::validate(g), "");
    const protocol::Normalized p{src.uniform(-5, 6), src.uniform(-5, 6)};
    const protocol::Degrees d = protocol::normalized_to_degrees(g, p);
    ASSERT_TRUE(std::isfinite(d.x) && std::isfinite(d.y)) << "trial " << t;
    ASSERT_LT(std::abs(d.x), 90.0);
    ASSERT_LT(std::abs(d.y), 90.0);
    const protocol::Normalized back = protocol::degrees_to_normalized(g, d);
    ASSERT_TRUE(std::isfinite(back.x) && std::isfinite(back.y)) << "trial " << t;
    // Angles beyond 89 deg are clamped on the way back (documented): the round trip holds inside.
    if (std::abs(d.x) < 89) {
      EXPECT_NEAR(back.x, p.x, 1e-6 * std::max(1.0, std::abs(p.x))) << "trial " << t;
    }
    if (std::abs(d.y) < 89) {
      EXPECT_NEAR(back.y, p.y, 1e-6 * std::max(1.0, std::abs(p.y))) << "trial " << t;
    }
    const double a = protocol::angle_between_deg(d, protocol::normalized_to_degrees(g, {src.uniform(0, 1), src.uniform(0, 1)}));
    ASSERT_TRUE(std::isfinite(a) && a >= 0 && a <= 180) << "trial " << t;
  }
}

TEST(Properties, GazeSamplesRoundTripTheWireAndNonFiniteIsRefused) {
  Source src;
  protocol::Message m;
  for (const auto& [name, message] : test::canonical_messages())
    if (std::holds_alternative<protocol::GazeSample>(message.payload)) m = message;
  ASSERT_TRUE(std::holds_alternative<protocol::GazeSample>(m.payload));
  for (int t = 0; t < kTrials; ++t) {
    auto& s = std::get<protocol::GazeSample>(m.payload);
    const auto f = [&](double lo, double hi) { return static_cast<float>(src.uniform(lo, hi)); };
    s.x = f(-10, 10);
    s.y = f(-10, 10);
    s.x_deg = f(-180, 180);
    s.y_deg = f(-180, 180);
    s.angular_velocity_deg_s = f(0, 3e4);
    s.confidence = f(0, 1);
    s.left.pupil_x_px = f(-1e6, 1e6);
    s.right.pupil_diameter_mm = t % 50 == 0 ? std::numeric_limits<float>::denorm_min() : f(0, 12);
    const bool poison = t % 7 == 0;
    if (poison) s.y_deg = static_cast<float>(src.hostile() == 0 ? std::numeric_limits<double>::infinity() : std::numeric_limits<double>::quiet_NaN());
    if (poison) {
      EXPECT_THROW(protocol::encode(m), std::invalid_argument) << "trial " << t << ": a non-finite field left on the wire";
      continue;
    }
    const auto bytes = protocol::encode(m);
    protocol::Message back;
    ASSERT_TRUE(protocol::decode(bytes, back)) << "trial " << t;
    EXPECT_EQ(std::get<protocol::GazeSample>(back.payload), s) << "trial " << t;
  }
}

TEST(Properties, CircleOfConfusionIsFiniteNonNegativeAndBounded) {
  Source src;
  for (int t = 0; t < kTrials; ++t) {
    render::dof::CocModel c;
    c.focal_length_m = src.maybe_hostile(0.001, 0.3, 20);
    c.aperture_m = src.maybe_hostile(0, 0.1, 20);
    c.focus_m = src.maybe_hostile(0.01, 1000, 20);
    c.px_per_image_m = src.maybe_hostile(1e3, 1e6, 20);
    c.max_coc_px = src.uniform(1, 1e4);
    const double depth = src.maybe_hostile(0, 1e4, 5);
    const double coc = c.coc_px(depth);
    ASSERT_TRUE(std::isfinite(coc) && coc >= 0 && coc <= c.max_coc_px)
        << "trial " << t << ": F " << c.focal_length_m << " E " << c.aperture_m << " d_f " << c.focus_m << " depth "
        << depth << " -> " << coc;
    const double b = c.signed_coc_px(depth);
    ASSERT_TRUE(std::isfinite(b) && std::abs(b) <= c.max_coc_px) << "trial " << t;
    ASSERT_TRUE(std::isfinite(c.k_px())) << "trial " << t;
  }
}

TEST(Properties, TonemappedImagesAreDefinedForAnyRadiance) {
  Source src;
  for (const char* op : {"reinhard", "clamp", "exponential"}) {
    std::vector<glm::vec3> hdr(64 * 16);
    for (auto& c : hdr)
      c = glm::vec3(static_cast<float>(src.maybe_hostile(0, 100, 6)), static_cast<float>(src.maybe_hostile(0, 1, 6)),
                    static_cast<float>(src.maybe_hostile(-1, 1e6, 6)));
    render::TonemapParams p;
    p.op = op;
    p.exposure = static_cast<float>(src.uniform(0.01, 100));
    render::Image8 out;
    render::tonemap(hdr, 64, 16, p, out);
    ASSERT_EQ(out.rgb.size(), hdr.size() * 3) << op;
    // Deterministic and monotone in radiance for finite non-negative input.
    for (std::size_t i = 0; i + 1 < hdr.size(); ++i) {
      const float a = hdr[i].r, b = hdr[i + 1].r;
      if (std::isfinite(a) && std::isfinite(b) && a >= 0 && b >= 0 && a <= b) {
        EXPECT_LE(out.rgb[3 * i], out.rgb[3 * (i + 1)]) << op << " " << a << " vs " << b;
      }
    }
  }
}

TEST(Properties, LocalShadingIsFiniteAndNonNegative) {
  Source src;
  for (int t = 0; t < kTrials / 4; ++t) {
    render::Scene scene;
    scene.ambient = glm::vec3(static_cast<float>(src.uniform(0, 0.2)));
    for (int k = 0; k < 3; ++k) {
      render::Light l;
      l.type = static_cast<render::LightType>(src.rng() % 3);
      l.position = glm::vec3(static_cast<float>(src.maybe_hostile(-10, 10, 30)), static_cast<float>(src.uniform(-10, 10)),
                             static_cast<float>(src.uniform(-10, 10)));
      l.power = glm::vec3(static_cast<float>(src.uniform(0, 1e4)));
      scene.lights.push_back(l);
    }
    render::Material m;
    m.type = src.rng() % 2 ? render::MaterialType::Lambertian : render::MaterialType::BlinnPhong;
    m.kd = glm::vec3(static_cast<float>(src.uniform(0, 1)));
    m.ks = glm::vec3(static_cast<float>(src.uniform(0, 1)));
    m.shininess = static_cast<float>(src.uniform(0, 2000));
    const glm::vec3 p(static_cast<float>(src.uniform(-10, 10)), static_cast<float>(src.uniform(-10, 10)),
                      static_cast<float>(src.uniform(-10, 10)));
    glm::vec3 n(static_cast<float>(src.uniform(-1, 1)), static_cast<float>(src.uniform(-1, 1)),
                static_cast<float>(src.uniform(-1, 1)));
    n = glm::length(n) > 1e-3f ? glm::normalize(n) : glm::vec3(0, 1, 0);
    const glm::vec3 eye = t % 13 == 0 ? p : p + glm::vec3(0, 0, static_cast<float>(src.uniform(0.001, 50)));
    const glm::vec3 c = render::shade_local(scene, m, p, n, eye);
    ASSERT_TRUE(std::isfinite(c.r) && std::isfinite(c.g) && std::isfinite(c.b)) << "trial " << t;
    ASSERT_GE(std::min({c.r, c.g, c.b}), 0.0f) << "trial " << t;
  }
}

TEST(Properties, EveryLodPolicyGivesALevelInTheChain) {
  Source src;
  for (int t = 0; t < kTrials; ++t) {
    render::lod::ObjectView o;
    o.id = 1;
    o.levels = 1 + static_cast<int>(src.rng() % 6);
    for (int l = 0; l < o.levels; ++l) {
      o.level_error_m.push_back(static_cast<float>(src.maybe_hostile(0, 0.1 * l, 20)));
      o.level_triangles.push_back(100000 >> (2 * l));
    }
    o.distance_m = src.maybe_hostile(0, 100);
    o.radius_m = src.maybe_hostile(0, 5);
    o.projected_radius_px = src.maybe_hostile(0, 2000);
    o.eccentricity_deg = src.maybe_hostile(0, 90);
    o.attention = src.maybe_hostile(-0.5, 1.5);
    o.velocity_px_per_frame = src.maybe_hostile(0, 50);
    o.luminance_contrast = src.maybe_hostile(0, 1);
    for (render::lod::Policy p : {render::lod::Policy::None, render::lod::Policy::Distance, render::lod::Policy::ScreenSize,
                                  render::lod::Policy::Brown, render::lod::Policy::Ulod, render::lod::Policy::Gaze}) {
      render::lod::PolicySettings s;
      s.policy = p;
      const double l = render::lod::continuous_level(o, s, render::lod::FrameStats{});
      ASSERT_TRUE(std::isfinite(l) && l >= 0 && l <= o.levels - 1)
          << render::lod::to_string(p) << " trial " << t << " -> " << l;
    }
  }
}

}  // namespace
