// SPDX-License-Identifier: Apache-2.0
// The glTF scene builder (scene/gltf/gltf_scene.h) on assets built in memory: objects per (mesh
// node, primitive), shared meshes, exact world matrices, materials, cameras and lights.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

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

TEST(GltfScene, MaterialFactorsMapToTheInterimModel) {
  const Material plastic = material_from_gltf(material({0.5f, 0.25f, 1}, 0, 1), "p");
  EXPECT_EQ(plastic.type, MaterialType::Lambertian);
  EXPECT_EQ(plastic.kd, glm::vec3(0.5f, 0.25f, 1));
  const Material metal = material_from_gltf(material({1, 0.5f, 0}, 1, 0.5f), "m");
  EXPECT_EQ(metal.type, MaterialType::BlinnPhong);
  EXPECT_EQ(metal.kd, glm::vec3(0));
  EXPECT_EQ(metal.ks, glm::vec3(1, 0.5f, 0));
  EXPECT_FLOAT_EQ(metal.shininess, 30.0f);  // alpha = 0.25: 2 / 0.0625 - 2
  const Material mirror_like = material_from_gltf(material({1, 1, 1}, 0, 0), "s");
  EXPECT_FLOAT_EQ(mirror_like.shininess, 10000.0f);
  EXPECT_NEAR(mirror_like.ks.x, 0.04f, 1e-6f);
  gltf::Material lamp = material({0, 0, 0});
  lamp.emissive_factor = {1, 0.5f, 0.25f};
  lamp.emissive_strength = 4;
  const Material e = material_from_gltf(lamp, "lamp");
  EXPECT_EQ(e.type, MaterialType::Emissive);
  EXPECT_EQ(e.emission, glm::vec3(4, 2, 1));
}

TEST(GltfScene, TexturesAreListedInAWarning) {
  gltf::Asset a = instanced();
  a.materials[0].base_color_texture = gltf::TextureRef{};
  a.materials[0].normal_texture = gltf::TextureRef{};
  std::vector<std::string> warnings;
  (void)scene_from_gltf(a, {}, &warnings);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_EQ(warnings[0], "two.gltf: material \"red\": textures not rendered yet: baseColorTexture, normalTexture");
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
