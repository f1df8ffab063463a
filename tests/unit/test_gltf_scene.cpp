// SPDX-License-Identifier: Apache-2.0
// The glTF scene builder (scene/gltf/gltf_scene.h) on assets built in memory: objects per (mesh
// node, primitive), shared meshes, exact world matrices, materials, cameras and lights.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include <opencv2/imgcodecs.hpp>

#include "scene/gltf/gltf_reader.h"
#include "scene/gltf/gltf_scene.h"

using namespace fovea::render;

namespace {

gltf::Primitive quad(std::optional<std::uint32_t> material, bool normals = true) {
  gltf::Primitive p;
  p.positions = {{-0.5f, -0.5f, 0}, {0.5f, -0.5f, 0}, {0.5f, 0.5f, 0}, {-0.5f, 0.5f, 0}};
  if (normals) p.normals.assign(4, glm::vec3(0, 0, 1));
  p.indices = {0, 1, 2, 0, 2, 3};
  p.material = material;
  return p;
}

gltf::Node node(const std::string& name, glm::mat4 local, std::optional<std::uint32_t> mesh) {
  gltf::Node n;
  n.name = name;
  n.local = local;
  n.mesh = mesh;
  return n;
}

gltf::Material material(glm::vec3 base, float metallic = 0, float roughness = 1) {
  gltf::Material m;
  m.base_color_factor = glm::vec4(base, 1);
  m.metallic_factor = metallic;
  m.roughness_factor = roughness;
  return m;
}

// One quad mesh (red), instanced by nodes "a" (x - 1) and "b" (x + 2, scale 2).
gltf::Asset instanced() {
  gltf::Asset a;
  a.source = "two.gltf";
  a.materials.push_back(material({1, 0, 0}));
  a.materials.back().name = "red";
  a.meshes.push_back({"quad", {quad(0)}});
  a.nodes.push_back(node("a", glm::translate(glm::mat4(1.0f), {-1, 0, 0}), 0));
  a.nodes.push_back(node("b", glm::scale(glm::translate(glm::mat4(1.0f), {2, 0, 0}), glm::vec3(2)), 0));
  return a;
}

std::string error_of(const gltf::Asset& a, const GltfSceneOptions& o = {}) {
  try {
    (void)scene_from_gltf(a, o);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST(GltfScene, InstancedMeshIsSharedAndPlacedByTheWorldMatrix) {
  const Scene s = scene_from_gltf(instanced(), {});
  ASSERT_EQ(s.objects.size(), 2u);
  EXPECT_EQ(s.objects[0].name, "a");
  EXPECT_EQ(s.objects[1].name, "b");
  EXPECT_EQ(s.objects[0].id, 1u);
  EXPECT_EQ(s.objects[1].id, 2u);
  EXPECT_EQ(s.objects[0].mesh.get(), s.objects[1].mesh.get());  // one Mesh, two instances
  const glm::vec4 corner(0.5f, 0.5f, 0, 1);  // vertex 2
  const glm::vec3 b = glm::vec3(s.objects[1].transform.matrix() * corner);
  EXPECT_EQ(b, glm::vec3(3, 1, 0));
  EXPECT_EQ(glm::vec3(s.objects[0].transform.matrix() * corner), glm::vec3(-0.5f, 0.5f, 0));
  EXPECT_EQ(s.objects[1].transform.translation, glm::vec3(2, 0, 0));
  EXPECT_EQ(s.objects[1].transform.scale, glm::vec3(2));
  ASSERT_EQ(s.materials.size(), 1u);  // both use material 0
  EXPECT_EQ(s.camera.width, 640u);
  EXPECT_EQ(s.camera.height, 480u);
}

TEST(GltfScene, ShearMatrixStaysExact) {
  gltf::Asset a = instanced();
  glm::mat4 shear(1.0f);
  shear[1][0] = 0.5f;  // x += 0.5 y
  a.nodes[0].local = shear;
  const Scene s = scene_from_gltf(a, {});
  EXPECT_EQ(s.objects[0].transform.matrix(), shear);
}

TEST(GltfScene, PrimitivesBecomeObjectsNamedByIndex) {
  gltf::Asset a;
  a.source = "multi.gltf";
  a.materials = {material({1, 0, 0}), material({0, 1, 0})};
  a.meshes.push_back({"m", {quad(0), quad(1)}});
  a.nodes.push_back(node("box", glm::mat4(1.0f), 0));
  const Scene s = scene_from_gltf(a, {});
  ASSERT_EQ(s.objects.size(), 2u);
  EXPECT_EQ(s.objects[0].name, "box/p0");
  EXPECT_EQ(s.objects[1].name, "box/p1");
  EXPECT_NE(s.objects[0].material, s.objects[1].material);
  EXPECT_EQ(s.materials[s.objects[1].material].kd, glm::vec3(0, 1, 0));
  EXPECT_EQ(s.materials[s.objects[1].material].name, "material1");
}

TEST(GltfScene, DefaultMaterialAndComputedNormals) {
  gltf::Asset a;
  a.source = "plain.gltf";
  a.meshes.push_back({"m", {quad(std::nullopt, false)}});
  a.nodes.push_back(node("q", glm::mat4(1.0f), 0));
  const Scene s = scene_from_gltf(a, {});
  ASSERT_EQ(s.objects.size(), 1u);
  const Material& m = s.materials.at(s.objects[0].material);
  EXPECT_EQ(m.name, "gltf-default");
  EXPECT_EQ(m.type, MaterialType::Lambertian);
  EXPECT_EQ(m.kd, glm::vec3(0.8f));
  const Mesh& mesh = *s.objects[0].mesh;
  ASSERT_EQ(mesh.normals.size(), 4u);
  for (const glm::vec3& n : mesh.normals) EXPECT_EQ(n, glm::vec3(0, 0, 1));
}

TEST(GltfScene, MaterialFactorsAreKeptWithTheirBlinnPhongForGi) {
  const Material plastic = material_from_gltf(material({0.5f, 0.25f, 1}, 0, 1), "p");
  EXPECT_EQ(plastic.type, MaterialType::MetallicRoughness);
  EXPECT_EQ(plastic.pbr.base_color, glm::vec4(0.5f, 0.25f, 1, 1));
  EXPECT_EQ(plastic.pbr.metallic, 0.0f);
  EXPECT_EQ(plastic.pbr.roughness, 1.0f);
  EXPECT_EQ(plastic.kd, glm::vec3(0.5f, 0.25f, 1));
  const Material metal = material_from_gltf(material({1, 0.5f, 0}, 1, 0.5f), "m");
  EXPECT_EQ(metal.kd, glm::vec3(0));
  EXPECT_EQ(metal.ks, glm::vec3(1, 0.5f, 0));
  EXPECT_FLOAT_EQ(metal.shininess, 30.0f);  // alpha = 0.25: 2 / 0.0625 - 2
  const Material mirror_like = material_from_gltf(material({1, 1, 1}, 0, 0), "s");
  EXPECT_FLOAT_EQ(mirror_like.shininess, 10000.0f);
  EXPECT_NEAR(mirror_like.ks.x, 0.04f, 1e-6f);
  gltf::Material lamp = material({0, 0, 0});
  lamp.emissive_factor = {1, 0.5f, 0.25f};
  lamp.emissive_strength = 4;
  lamp.alpha_mode = gltf::AlphaMode::Mask;
  lamp.alpha_cutoff = 0.3f;
  lamp.double_sided = true;
  const Material e = material_from_gltf(lamp, "lamp");
  EXPECT_EQ(e.pbr.emissive, glm::vec3(4, 2, 1));
  EXPECT_EQ(e.pbr.alpha_mode, AlphaMode::Mask);
  EXPECT_FLOAT_EQ(e.pbr.alpha_cutoff, 0.3f);
  EXPECT_TRUE(e.pbr.double_sided);
  lamp.alpha_mode = gltf::AlphaMode::Blend;
  EXPECT_FLOAT_EQ(material_from_gltf(lamp, "glass").pbr.alpha_cutoff, 0.5f);  // BLEND drawn as MASK 0.5
}

namespace {

std::vector<std::uint8_t> png_bytes(const cv::Mat& bgra) {
  std::vector<std::uint8_t> out;
  EXPECT_TRUE(cv::imencode(".png", bgra, out));
  return out;
}

// instanced() with material "red" textured: base colour from image 0 (a 2x2 PNG in memory), the
// normal map from image 1 (an external file that does not exist).
gltf::Asset textured() {
  gltf::Asset a = instanced();
  a.folder = "/nonexistent-fovea-test-folder";
  cv::Mat img(2, 2, CV_8UC4, cv::Scalar(0, 0, 255, 255));  // BGRA red
  img.at<cv::Vec4b>(0, 1) = cv::Vec4b(255, 0, 0, 128);     // (1, 0): blue, half transparent
  gltf::Image embedded;
  embedded.data = png_bytes(img);
  embedded.mime_type = "image/png";
  gltf::Image missing;
  missing.file = a.folder / "normal.png";
  a.images = {embedded, missing};
  a.textures = {{"base", std::nullopt, 0}, {"normal", std::nullopt, 1}};
  a.materials[0].base_color_texture = gltf::TextureRef{0, 0};
  a.materials[0].normal_texture = gltf::TextureRef{1, 1};
  a.meshes[0].primitives[0].texcoords0 = {{0, 1}, {1, 1}, {1, 0}, {0, 0}};
  a.meshes[0].primitives[0].texcoords1 = a.meshes[0].primitives[0].texcoords0;
  return a;
}

}  // namespace

TEST(GltfScene, TexturesAreDecodedAndAMissingImageIsAWarning) {
  std::vector<std::string> warnings;
  const Scene s = scene_from_gltf(textured(), {}, &warnings);
  ASSERT_EQ(s.textures.size(), 1u);  // the normal map's image is missing
  const TextureImage& t = *s.textures[0];
  EXPECT_TRUE(t.srgb);
  ASSERT_EQ(t.levels.size(), 2u);  // 2x2, 1x1
  EXPECT_EQ(t.levels[0].rgba[0], 255);  // texel (0, 0): red, RGBA order
  EXPECT_EQ(t.levels[0].rgba[2], 0);
  EXPECT_EQ(t.levels[0].rgba[4 + 2], 255);  // texel (1, 0): blue
  EXPECT_EQ(t.levels[0].rgba[4 + 3], 128);
  const Material& m = s.materials.at(0);
  ASSERT_TRUE(m.pbr.base_color_texture.has_value());
  EXPECT_EQ(m.pbr.base_color_texture->texture, 0u);
  EXPECT_FALSE(m.pbr.normal_texture.has_value());  // left out: the factor (none) stands alone
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("two.gltf: material \"red\" normalTexture: $.images[1] (\"normal.png\"): image file "),
            std::string::npos)
      << warnings[0];
  EXPECT_NE(warnings[0].find("the texture is left out (the material's factors are used)"), std::string::npos);
  const Mesh& mesh = *s.objects[0].mesh;
  EXPECT_EQ(mesh.texcoords0.size(), 4u);
  EXPECT_EQ(mesh.texcoords1.size(), 4u);
  // Tangents generated for the normal map's set (u along +x): (1, 0, 0), right-handed.
  ASSERT_EQ(mesh.tangents.size(), 4u);
  for (const glm::vec4& t4 : mesh.tangents) {
    EXPECT_NEAR(t4.x, 1.0f, 1e-6f);
    EXPECT_NEAR(t4.w, 1.0f, 1e-6f);
  }
}

TEST(GltfScene, ADecompressionBombIsRefusedBeforeDecoding) {
  gltf::Asset a = textured();
  // A PNG whose IHDR declares 20000 x 20000 pixels (400 M, past the 8192^2 limit).
  std::vector<std::uint8_t>& png = a.images[0].data;
  ASSERT_GT(png.size(), 24u);
  for (std::size_t k : {16u, 20u}) {
    png[k] = 0, png[k + 1] = 0, png[k + 2] = 20000 >> 8, png[k + 3] = 20000 & 0xFF;
  }
  std::vector<std::string> warnings;
  const Scene s = scene_from_gltf(a, {}, &warnings);
  EXPECT_TRUE(s.textures.empty());
  EXPECT_FALSE(s.materials.at(0).pbr.base_color_texture.has_value());
  ASSERT_GE(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("PNG declaring 20000x20000 pixels; at most 67108864 are decoded"), std::string::npos)
      << warnings[0];
}

TEST(GltfScene, TexturesPastTheBudgetLoadAtALowerLevel) {
  gltf::Asset a = textured();
  a.images[0].data = png_bytes(cv::Mat(64, 64, CV_8UC4, cv::Scalar(10, 20, 30, 255)));
  GltfSceneOptions o;
  o.textures.budget_bytes = mip_chain_bytes(16, 16);  // fits 16x16, not 64x64 or 32x32
  std::vector<std::string> warnings;
  const Scene s = scene_from_gltf(a, o, &warnings);
  ASSERT_EQ(s.textures.size(), 1u);
  EXPECT_EQ(s.textures[0]->levels[0].width, 16u);
  EXPECT_EQ(s.textures[0]->bytes(), mip_chain_bytes(16, 16));
  bool said = false;
  for (const std::string& w : warnings) said = said || w.find("every texture loaded at 1/4 of its resolution") != std::string::npos;
  EXPECT_TRUE(said);
}

TEST(GltfScene, CameraFromTheFileAndByName) {
  gltf::Asset a = instanced();
  gltf::Camera c;
  c.yfov_rad = std::numbers::pi_v<float> / 4;
  c.znear = 0.1f;
  c.zfar = 50.0f;
  a.cameras.push_back(c);
  gltf::Node front = node("front", glm::translate(glm::mat4(1.0f), {0, 0, 5}), std::nullopt);
  front.camera = 0;
  gltf::Node side = node("side", glm::rotate(glm::translate(glm::mat4(1.0f), {5, 0, 0}), glm::radians(90.0f), {0, 1, 0}),
                         std::nullopt);
  side.camera = 0;
  a.nodes.push_back(front);
  a.nodes.push_back(side);
  const Scene s = scene_from_gltf(a, {});
  EXPECT_EQ(s.camera.position, glm::vec3(0, 0, 5));
  EXPECT_EQ(s.camera.target, glm::vec3(0, 0, 4));
  EXPECT_FLOAT_EQ(s.camera.vertical_fov_deg, 45.0f);
  EXPECT_FLOAT_EQ(s.camera.near_m, 0.1f);
  EXPECT_FLOAT_EQ(s.camera.far_m, 50.0f);
  GltfSceneOptions o;
  o.camera_name = "side";
  const Scene side_view = scene_from_gltf(a, o);
  EXPECT_EQ(side_view.camera.position, glm::vec3(5, 0, 0));
  EXPECT_NEAR(side_view.camera.target.x, 4.0f, 1e-6f);  // looking down -X
  o.camera_name = "top";
  EXPECT_EQ(error_of(a, o), "two.gltf: no perspective camera node named \"top\" (camera nodes: \"front\", \"side\")");
}

TEST(GltfScene, WithoutACameraTheBoundsAreFramed) {
  const Scene s = scene_from_gltf(instanced(), {});
  // Bounds x in [-1.5, 3] (a: [-1.5, -0.5], b: [1, 3]), y in [-1, 1]: the camera looks at the centre from +Z.
  EXPECT_NEAR(s.camera.target.x, 0.75f, 1e-6f);
  EXPECT_NEAR(s.camera.target.y, 0.0f, 1e-6f);
  EXPECT_GT(s.camera.position.z, 3.0f);
  EXPECT_EQ(s.camera.position.x, s.camera.target.x);
}

TEST(GltfScene, PunctualLightsConvertAndNoneGiveTheDefaultRig) {
  gltf::Asset a = instanced();
  EXPECT_EQ(scene_from_gltf(a, {}).lights.size(), 2u);  // the default rig
  gltf::Light point;
  point.intensity = 10;
  point.color = {1, 0.5f, 0};
  a.lights.push_back(point);
  gltf::Node lamp = node("lamp", glm::translate(glm::mat4(1.0f), {1, 2, 3}), std::nullopt);
  lamp.light = 0;
  a.nodes.push_back(lamp);
  const Scene s = scene_from_gltf(a, {});
  ASSERT_EQ(s.lights.size(), 1u);
  EXPECT_EQ(s.lights[0].type, LightType::Point);
  EXPECT_EQ(s.lights[0].position, glm::vec3(1, 2, 3));
  const float four_pi = 4 * std::numbers::pi_v<float>;
  EXPECT_NEAR(s.lights[0].power.x, four_pi * 10, 1e-4f);
  EXPECT_NEAR(s.lights[0].power.y, four_pi * 5, 1e-4f);
  EXPECT_EQ(s.lights[0].power.z, 0.0f);
}

TEST(GltfScene, NonInvertibleNodeMatrixIsRefusedByItsPath) {
  gltf::Asset a = instanced();
  a.nodes[1].local = glm::scale(glm::mat4(1.0f), {1, 0, 1});
  EXPECT_NE(error_of(a).find("two.gltf: $.nodes[1] (\"b\"): world matrix is not invertible"), std::string::npos)
      << error_of(a);
  a.nodes[1].local[3][0] = std::nanf("");
  EXPECT_NE(error_of(a).find("$.nodes[1] (\"b\"): world matrix is not finite"), std::string::npos) << error_of(a);
}

TEST(GltfScene, AnAssetWithoutTrianglesIsRefused) {
  gltf::Asset a;
  a.source = "empty.gltf";
  EXPECT_NE(error_of(a).find("nothing to render"), std::string::npos);
}

// The CC0 sample with its occlusion-roughness-metallic image missing, as the shared data has it.
TEST(GltfScene, BoomBoxWarnsOnceAboutItsMissingImage) {
  const std::filesystem::path file = "/work/shared/data/gltf/BoomBox/glTF/BoomBox.gltf";
  if (!std::filesystem::exists(file)) GTEST_SKIP() << file << " is not on this machine";
  std::vector<std::string> warnings;
  const Scene s = scene_from_gltf(gltf::read_gltf(file), {}, &warnings);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("material \"BoomBox_Mat\" metallicRoughnessTexture, material \"BoomBox_Mat\" "
                             "occlusionTexture: $.images[1] (\"BoomBox_occlusionRoughnessMetallic.png\")"),
            std::string::npos)
      << warnings[0];
  EXPECT_EQ(s.textures.size(), 3u);  // base colour, normal, emissive
  const PbrParameters& m = s.materials.at(0).pbr;
  EXPECT_TRUE(m.base_color_texture && m.normal_texture && m.emissive_texture);
  EXPECT_FALSE(m.metallic_roughness_texture || m.occlusion_texture);
}
