// SPDX-License-Identifier: Apache-2.0
// The photon map's kd-tree and radiance estimate (renderer/gi/photon_map.h) against brute force.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>

#include "gi/photon_map.h"

namespace fovea::render::gi {
namespace {

std::vector<Photon> random_photons(std::size_t n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<Photon> photons(n);
  for (Photon& p : photons) {
    p.position = {u(rng), u(rng), u(rng)};
    p.power = glm::vec3(1.0f);
    p.incoming = glm::vec3(0, -1, 0);
  }
  return photons;
}

std::vector<std::pair<float, std::uint32_t>> brute_nearest(const std::vector<Photon>& photons, const glm::vec3& x,
                                                           std::size_t k, float radius, bool (*accept)(const Photon&)) {
  std::vector<std::pair<float, std::uint32_t>> all;
  for (std::size_t i = 0; i < photons.size(); ++i) {
    const glm::vec3 d = photons[i].position - x;
    const float d2 = glm::dot(d, d);
    if (d2 < radius * radius && (!accept || accept(photons[i]))) all.emplace_back(d2, static_cast<std::uint32_t>(i));
  }
  std::sort(all.begin(), all.end());
  if (all.size() > k) all.resize(k);
  return all;
}

TEST(GiPhotonMap, NearestMatchesBruteForceForEverySizeAndK) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.2f, 1.2f);
  for (std::size_t n : {1u, 2u, 3u, 7u, 64u, 1000u, 4097u}) {
    const std::vector<Photon> photons = random_photons(n, static_cast<std::uint32_t>(n));
    PhotonMap map;
    map.build_all(photons);
    ASSERT_EQ(map.size(), n);
    Neighbours nb;
    for (int q = 0; q < 40; ++q) {
      const glm::vec3 x{u(rng), u(rng), u(rng)};
      for (std::uint32_t k : {1u, 5u, 50u}) {
        for (float radius : {0.1f, 0.5f, 10.0f}) {
          map.nearest(x, k, radius, nb);
          const auto want = brute_nearest(photons, x, k, radius, nullptr);
          ASSERT_EQ(nb.size(), want.size()) << "n " << n << " k " << k << " r " << radius;
          for (std::size_t i = 0; i < want.size(); ++i) {
            EXPECT_FLOAT_EQ(nb.distance2[i], want[i].first);
          }
        }
      }
    }
  }
}

TEST(GiPhotonMap, NearestHonoursThePredicateAndASubset) {
  std::vector<Photon> photons = random_photons(2000, 3);
  for (std::size_t i = 0; i < photons.size(); i += 3) photons[i].diffuse_bounces = 1;
  const auto indirect = [](const Photon& p) { return p.diffuse_bounces > 0; };
  PhotonMap map;
  map.build_all(photons);
  Neighbours nb;
  map.nearest({0.1f, 0.2f, -0.3f}, 30, 1.0f, nb, indirect);
  const auto want = brute_nearest(photons, {0.1f, 0.2f, -0.3f}, 30, 1.0f, +[](const Photon& p) { return p.diffuse_bounces > 0; });
  ASSERT_EQ(nb.size(), want.size());
  for (std::size_t i = 0; i < want.size(); ++i) EXPECT_EQ(nb.index[i], want[i].second);

  // A map over a subset indexes only those photons.
  std::vector<std::uint32_t> subset;
  for (std::uint32_t i = 0; i < photons.size(); i += 3) subset.push_back(i);
  PhotonMap sub;
  sub.build(photons, subset);
  EXPECT_EQ(sub.size(), subset.size());
  sub.nearest({0.1f, 0.2f, -0.3f}, 30, 1.0f, nb);
  ASSERT_EQ(nb.size(), want.size());
  for (std::size_t i = 0; i < want.size(); ++i) EXPECT_EQ(nb.index[i], want[i].second);
}

TEST(GiPhotonMap, WithinMatchesBruteForce) {
  const std::vector<Photon> photons = random_photons(3000, 11);
  PhotonMap map;
  map.build_all(photons);
  std::vector<std::uint32_t> got;
  map.within({0.3f, -0.2f, 0.0f}, 0.4f, got);
  std::sort(got.begin(), got.end());
  std::vector<std::uint32_t> want;
  for (std::uint32_t i = 0; i < photons.size(); ++i) {
    const glm::vec3 d = photons[i].position - glm::vec3(0.3f, -0.2f, 0.0f);
    if (glm::dot(d, d) < 0.16f) want.push_back(i);
  }
  EXPECT_EQ(got, want);
}

// A uniform flux density on a plane: Phi per photon on a grid of spacing h is Phi / h^2 W/m^2.
TEST(GiPhotonMap, FluxDensityOfAUniformGridIsPowerPerArea) {
  std::vector<Photon> photons;
  const float h = 0.01f, phi = 0.002f;
  for (int i = -100; i <= 100; ++i)
    for (int j = -100; j <= 100; ++j) {
      Photon p;
      p.position = {static_cast<float>(i) * h, 0.0f, static_cast<float>(j) * h};
      p.power = glm::vec3(phi);
      p.incoming = glm::vec3(0, -1, 0);
      photons.push_back(p);
    }
  PhotonMap map;
  map.build_all(photons);
  Neighbours scratch;
  EstimateSettings s;
  s.nearest = 400;
  s.max_radius = 1.0f;
  s.filter = EstimateFilter::Disc;
  const float expected = phi / (h * h);
  const glm::vec3 up(0, 1, 0);
  EXPECT_NEAR(map.flux_density({0.003f, 0, 0.002f}, up, s, scratch).x, expected, 0.05f * expected);
  s.filter = EstimateFilter::Cone;
  EXPECT_NEAR(map.flux_density({0.003f, 0, 0.002f}, up, s, scratch).x, expected, 0.05f * expected);
  // Photons arriving at the other side do not count.
  EXPECT_EQ(map.flux_density({0, 0, 0}, -up, s, scratch).x, 0.0f);
  // A weight multiplies each photon's power (a BRDF of 1/pi gives radiance).
  const glm::vec3 l = map.flux_density({0, 0, 0}, up, s, scratch,
                                       [](const Photon&) { return glm::vec3(1.0f / std::numbers::pi_v<float>); });
  EXPECT_NEAR(l.x, expected / std::numbers::pi_v<float>, 0.05f * expected);
}

// The radius gather (EstimateSettings::fixed_radius): every front-side photon within max_radius, over
// the disc of max_radius, whatever `nearest` says; against brute force with both filters.
TEST(GiPhotonMap, FixedRadiusGathersEveryPhotonInTheDisc) {
  std::vector<Photon> photons = random_photons(3000, 11);
  for (std::size_t i = 0; i < photons.size(); i += 3) photons[i].incoming = glm::vec3(0, 1, 0);  // the back side
  for (std::size_t i = 0; i < photons.size(); ++i) photons[i].power = glm::vec3(0.001f * static_cast<float>(i % 7 + 1));
  PhotonMap map;
  map.build_all(photons);
  Neighbours scratch;
  const glm::vec3 up(0, 1, 0), x(0.1f, -0.2f, 0.05f);
  for (const EstimateFilter filter : {EstimateFilter::Disc, EstimateFilter::Cone}) {
    EstimateSettings s;
    s.fixed_radius = true;
    s.nearest = 1;  // not read
    s.max_radius = 0.3f;
    s.filter = filter;
    const float k = s.cone_k, r = s.max_radius;
    double sum = 0;
    for (const Photon& p : photons) {
      const float d = glm::length(p.position - x);
      if (d >= r || glm::dot(p.incoming, up) >= 0) continue;
      sum += static_cast<double>(p.power.x * (filter == EstimateFilter::Cone ? std::max(0.0f, 1.0f - d / (k * r)) : 1.0f));
    }
    const double norm = filter == EstimateFilter::Cone ? 1.0 - 2.0 / (3.0 * static_cast<double>(k)) : 1.0;
    const double want = sum / (norm * std::numbers::pi * static_cast<double>(r * r));
    EXPECT_NEAR(static_cast<double>(map.flux_density(x, up, s, scratch).x), want, 1e-5 * want);
    EXPECT_NEAR(scratch.radius2, r * r, 1e-7f);
  }
  EstimateSettings none;
  none.fixed_radius = true;
  none.max_radius = std::numeric_limits<float>::infinity();  // no disc to divide by
  EXPECT_EQ(map.flux_density(x, up, none, scratch), glm::vec3(0.0f));
}

}  // namespace
}  // namespace fovea::render::gi
