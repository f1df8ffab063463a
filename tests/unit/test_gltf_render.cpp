// SPDX-License-Identifier: Apache-2.0
// A glTF asset through load_scene and the Embree backend: two quads of different base colours are
// two objects, each shaded with its own material (fails if nodes were merged or materials dropped).
#include <gtest/gtest.h>

#include <string>

#include "backend/embree/embree_backend.h"
#include "gltf_render_check.h"
#include "gltf_test_assets.h"
#include "gltf_textured_quads.h"
#include "scene/scene_loader.h"

using namespace fovea::render;
using namespace fovea::test;

namespace {

GBuffer render(const Scene& s) {
  EmbreeBackend b;
  b.set_scene(s);
  GBuffer g;
  b.render(FrameTime{}, BackendSettings{}, g);
  return g;
}

std::string load_error(const std::filesystem::path& file, const std::vector<SceneOverride>& overrides,
                       const std::string& camera = {}) {
  try {
    (void)load_scene(file, overrides, camera);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST(GltfRender, TwoQuadsAreTwoObjectsInTheirOwnColours) {
  TempDir dir;
  const GltfTwoQuads quads;
  write_file(dir.path / "quads.glb", glb_bytes(quads.doc(), quads.bin()));
  const Scene s = load_scene(dir.path / "quads.glb", {{"camera.width", "64"}, {"camera.height", "48"}});
  ASSERT_EQ(s.objects.size(), 2u);
  ASSERT_EQ(s.camera.width, 64u);
  ASSERT_EQ(s.camera.height, 48u);
  expect_two_quads(render(s));
}

TEST(GltfRender, SameSceneFromGltfWithDataUri) {
  TempDir dir;
  const GltfTwoQuads quads;
  const auto file = write_gltf_data_uri(dir.path, "quads", quads.doc(), quads.bin());
  const Scene s = load_scene(file, {}, "eye");
  EXPECT_EQ(s.camera.position, glm::vec3(0, 0, 3));
  EXPECT_EQ(s.objects.size(), 2u);
}

TEST(GltfRender, OverridesAndCameraAreChecked) {
  TempDir dir;
  const GltfTwoQuads quads;
  const auto file = write_gltf_data_uri(dir.path, "quads", quads.doc(), quads.bin());
  EXPECT_NE(load_error(file, {{"lights.0.power", "[1,1,1]"}}).find("a glTF scene takes only camera.width and camera.height"),
            std::string::npos);
  EXPECT_NE(load_error(file, {{"camera.width", "wide"}}).find("must be an integer in [1, 16384]"), std::string::npos);
  EXPECT_NE(load_error(file, {}, "top").find("(camera nodes: \"eye\")"), std::string::npos);
  const auto json = std::filesystem::path(FOVEA_SOURCE_DIR) / "renderer/scenes/cornell.json";
  EXPECT_NE(load_error(json, {}, "eye").find("a JSON scene has one camera"), std::string::npos);
}

// glTF 2.0 points on the Embree backend: texture orientation, sRGB decoding, alpha MASK,
// TEXCOORD_1, COLOR_0, normal maps on X and Y (gltf_textured_quads.h).
TEST(GltfRender, TexturedQuadsShowTheSpecificationsPoints) {
  TempDir dir;
  const GltfTexturedQuads quads;
  const auto file = write_gltf(dir.path, "quads", quads.doc(), quads.bin());
  const Scene s = load_scene(file, {{"camera.width", "192"}, {"camera.height", "128"}});
  ASSERT_EQ(s.objects.size(), 6u);
  ASSERT_EQ(s.textures.size(), 4u);
  expect_textured_quads(s.camera, render(s), render(without_normal_maps(s)));
}
