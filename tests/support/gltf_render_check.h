// SPDX-License-Identifier: Apache-2.0
#pragma once
// The rendered check of GltfTwoQuads (gltf_test_assets.h) at 64x48, shared by the Embree and GL
// tests: two objects (the nodes were not merged) shaded red on the left and green on the right (each
// kept its material), nothing between them.
#include <gtest/gtest.h>

#include "backend/gbuffer.h"

namespace fovea::test {

inline void expect_two_quads(const render::GBuffer& g) {
  ASSERT_EQ(g.width, 64u);
  ASSERT_EQ(g.height, 48u);
  const std::size_t left = g.index(16, 24), right = g.index(48, 24), gap = g.index(32, 24);
  EXPECT_EQ(g.object_id[left], 1u);
  EXPECT_EQ(g.object_id[right], 2u);
  EXPECT_EQ(g.object_id[gap], 0u);
  const glm::vec3 l = g.color[left], r = g.color[right];
  EXPECT_GT(l.r, 0.05f) << "left " << l.r << " " << l.g << " " << l.b;
  EXPECT_GT(r.g, 0.05f) << "right " << r.r << " " << r.g << " " << r.b;
  EXPECT_LT(l.g, 0.1f * l.r);
  EXPECT_LT(r.r, 0.1f * r.g);
  // Blue only from the specular lobe's grey F0 = 0.04 (glTF appendix B), never the base colour.
  EXPECT_LT(l.b, 0.1f * l.r);
  EXPECT_LT(r.b, 0.1f * r.g);
}

}  // namespace fovea::test
