// SPDX-License-Identifier: Apache-2.0
// Hard cases of the photon map (renderer/gi/photon_map.h): empty maps, nNN larger than the map,
// radius 0, non-finite queries and photons. Every estimate stays finite.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "gi/photon_map.h"

namespace fovea::render::gi {
namespace {

Photon photon_at(glm::vec3 p) {
  Photon ph;
  ph.position = p;
  ph.power = glm::vec3(1.0f);
  ph.incoming = glm::vec3(0, -1, 0);
  return ph;
}

TEST(GiPhotonMapStability, HardCasesAreFiniteAndEmptyWhereTheyShouldBe) {
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  const glm::vec3 up(0, 1, 0);
  Neighbours nb;
  EstimateSettings s;

  PhotonMap empty;
  empty.build_all({});
  EXPECT_TRUE(empty.empty());
  empty.nearest({0, 0, 0}, 10, 1.0f, nb);
  EXPECT_EQ(nb.size(), 0u);
  EXPECT_EQ(empty.flux_density({0, 0, 0}, up, s, nb), glm::vec3(0.0f));

  // Non-finite photons are left out of the tree.
  std::vector<Photon> photons = {photon_at({0, 0, 0}), photon_at({nan, 0, 0}), photon_at({0.1f, 0, 0}),
                                 photon_at({inf, 0, 0})};
  PhotonMap map;
  map.build_all(photons);
  EXPECT_EQ(map.size(), 2u);

  // nNN larger than the map: all of them, and the estimate uses the search radius.
  s.nearest = 1000;
  s.max_radius = 0.5f;
  map.nearest({0, 0, 0}, 1000, 0.5f, nb);
  EXPECT_EQ(nb.size(), 2u);
  const glm::vec3 e = map.flux_density({0, 0, 0}, up, s, nb);
  EXPECT_TRUE(std::isfinite(e.x) && e.x > 0);

  // Radius 0, negative, NaN; k = 0: nothing found, estimate 0.
  for (float r : {0.0f, -1.0f, nan}) {
    s.max_radius = r;
    EXPECT_EQ(map.flux_density({0, 0, 0}, up, s, nb), glm::vec3(0.0f)) << r;
    map.nearest({0, 0, 0}, 5, r, nb);
    EXPECT_EQ(nb.size(), 0u);
  }
  s.max_radius = 0.5f;
  s.nearest = 0;
  EXPECT_EQ(map.flux_density({0, 0, 0}, up, s, nb), glm::vec3(0.0f));

  // One nearest photon exactly at the query: r = 0, no finite density: 0, not Inf.
  s.nearest = 1;
  EXPECT_EQ(map.flux_density({0, 0, 0}, up, s, nb), glm::vec3(0.0f));

  // Non-finite query point or normal, infinite radius, cone k below 1 or NaN.
  s.nearest = 10;
  EXPECT_EQ(map.flux_density({nan, 0, 0}, up, s, nb), glm::vec3(0.0f));
  EXPECT_EQ(map.flux_density({0, 0, 0}, {nan, 1, 0}, s, nb), glm::vec3(0.0f));
  s.max_radius = inf;
  s.cone_k = nan;
  const glm::vec3 wide = map.flux_density({0.05f, 0, 0}, up, s, nb);
  EXPECT_TRUE(std::isfinite(wide.x));
  s.cone_k = 0.2f;
  EXPECT_TRUE(std::isfinite(map.flux_density({0.05f, 0, 0}, up, s, nb).x));
  // A weight returning NaN cannot make the estimate NaN.
  s.max_radius = 0.5f;
  const glm::vec3 w = map.flux_density({0.05f, 0, 0}, up, s, nb, [nan](const Photon&) { return glm::vec3(nan); });
  EXPECT_TRUE(std::isfinite(w.x));
}

}  // namespace
}  // namespace fovea::render::gi
