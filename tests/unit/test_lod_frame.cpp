// SPDX-License-Identifier: Apache-2.0
// What the lod-select pass and bench_lod share (renderer/lod/lod_frame.h): object views from the
// scene, bounding spheres cached per mesh, ULOD's second-pass levels and its image-space blend.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>

#include "lod/lod_frame.h"

namespace fovea::render::lod {
namespace {

std::shared_ptr<const Mesh> box_mesh(float half) {
  auto m = std::make_shared<Mesh>();
  for (int k = 0; k < 8; ++k)
    m->positions.push_back({(k & 1) ? half : -half, (k & 2) ? half : -half, (k & 4) ? half : -half});
  m->indices = {0, 1, 2, 1, 3, 2};
  return m;
}

Scene two_object_scene() {
  Scene s;
  s.camera.position = {0, 0, 5};
  s.camera.target = {0, 0, 0};
  s.camera.width = 64;
  s.camera.height = 48;
  s.materials.push_back(Material{});
  Object plain;  // no chain: drawn at full detail, not listed
  plain.id = 1;
  plain.mesh = box_mesh(1);
  s.objects.push_back(plain);
  Object chained;
  chained.id = 7;
  chained.mesh = box_mesh(0.5f);
  chained.lods.push_back({box_mesh(0.5f), 0.01f});
  chained.lods.push_back({box_mesh(0.5f), 0.04f});
  chained.transform.translation = {1, 0, 0};
  chained.transform.scale = glm::vec3(2);
  s.objects.push_back(chained);
  return s;
}

TEST(LodFrame, ViewsListOnlyObjectsWithAChainWithWorldSizesAndAttention) {
  const Scene s = two_object_scene();
  BoundsCache bounds;
  std::vector<std::size_t> index;
  ViewInputs in;
  in.attention = [](std::uint32_t id) { return id == 7 ? 0.4 : 0.9; };
  const auto views = object_views(s, in, bounds, index);
  ASSERT_EQ(views.size(), 1u);
  EXPECT_EQ(index[0], 1u);
  EXPECT_EQ(views[0].id, 7u);
  EXPECT_EQ(views[0].levels, 3);
  EXPECT_NEAR(views[0].radius_m, 2 * 0.5 * std::sqrt(3.0), 1e-5);  // the cube's corner, scaled by 2
  EXPECT_NEAR(views[0].level_error_m[2], 0.08, 1e-6);               // object-space error scaled to world
  EXPECT_NEAR(views[0].distance_m, std::sqrt(26.0), 1e-5);
  EXPECT_DOUBLE_EQ(views[0].attention, 0.4);
  EXPECT_GT(views[0].screen_x, 0.5);  // right of the centre
  EXPECT_TRUE(std::isfinite(views[0].eccentricity_deg));
}

TEST(LodFrame, BoundsAreCachedPerMeshAndRecomputedWhenTheMeshChanges) {
  BoundsCache bounds;
  Mesh m;
  m.positions = {{0, 0, 0}, {2, 0, 0}};
  EXPECT_FLOAT_EQ(bounds.of(m).radius, 1.0f);
  m.positions.push_back({0, 4, 0});
  const auto& sphere = bounds.of(m);
  EXPECT_FLOAT_EQ(sphere.centre.y, 2.0f);
  EXPECT_GT(sphere.radius, 2.0f);
}

TEST(LodFrame, SecondPassLevelsAndBlendOnlyWhereTheSameObjectCoversThePixel) {
  const Scene s = two_object_scene();
  std::vector<Selection> sel(1);
  sel[0].id = 7;
  sel[0].drawn = 1;
  sel[0].blend_to = 2;
  sel[0].blend = 0.25;
  std::vector<std::uint8_t> levels;
  ASSERT_TRUE(ulod_next_levels(s, sel, levels));
  EXPECT_EQ(levels, (std::vector<std::uint8_t>{0, 2}));
  GBuffer base, next;
  base.resize(3, 1);
  next.resize(3, 1);
  base.object_id = {7, 7, 1};
  next.object_id = {7, 0, 1};  // pixel 1: the coarser level does not cover it
  base.color.assign(3, glm::vec3(1));
  next.color.assign(3, glm::vec3(0));
  ulod_blend(base, next, sel);
  EXPECT_FLOAT_EQ(base.color[0].x, 0.75f);
  EXPECT_FLOAT_EQ(base.color[1].x, 1.0f);  // no hole
  EXPECT_FLOAT_EQ(base.color[2].x, 1.0f);  // not blending
  sel[0].blend = 0;
  EXPECT_FALSE(ulod_next_levels(s, sel, levels));
}

}  // namespace
}  // namespace fovea::render::lod
