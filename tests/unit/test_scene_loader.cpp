// SPDX-License-Identifier: Apache-2.0
// Scene loading: the bundled scenes, mesh files through assimp, LOD chains, overrides, and the
// catalogue of bad inputs, each of which must name the file, the JSON path and the bad value.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <chrono>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <unistd.h>

#include "scene/scene_loader.h"

namespace fs = std::filesystem;
using namespace fovea::render;
using Json = nlohmann::ordered_json;

namespace {

const fs::path kFixtures = fs::path(FOVEA_TEST_DATA) / "scenes";
const fs::path kBundled = fs::path(FOVEA_SOURCE_DIR) / "renderer" / "scenes";

// A small valid scene the error tests mutate.
Json base_scene() {
  return Json::parse(R"({
    "name": "base",
    "camera": {"position": [0, 1, 5], "target": [0, 1, 0], "width": 64, "height": 48},
    "materials": {
      "white": {"type": "lambertian", "kd": [0.5, 0.5, 0.5]},
      "red": {"type": "blinn-phong", "kd": [0.5, 0.1, 0.1], "ks": [0.3, 0.3, 0.3], "shininess": 20}
    },
    "objects": [
      {"name": "ball", "material": "white", "geometry": {"sphere": {"radius": 0.5}},
       "transform": {"translation": [0, 1, 0]}},
      {"name": "floor", "material": "red", "geometry": {"plane": [4, 4]}}
    ],
    "lights": [{"type": "point", "position": [0, 3, 0], "power": [100, 100, 100]}]
  })");
}

Scene parse(const Json& doc, const std::vector<SceneOverride>& overrides = {}) {
  return parse_scene(doc.dump(), "broken.json", kFixtures, overrides);
}

// The SceneError message of parsing `text`, or a test failure if it parses.
std::string error_of_text(const std::string& text, const std::vector<SceneOverride>& overrides = {}) {
  try {
    parse_scene(text, "broken.json", kFixtures, overrides);
  } catch (const SceneError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected a SceneError for:\n" << text;
  return {};
}
std::string error_of(const Json& doc, const std::vector<SceneOverride>& overrides = {}) {
  return error_of_text(doc.dump(), overrides);
}

#define EXPECT_CONTAINS(haystack, needle)                                                             \
  EXPECT_NE(std::string(haystack).find(needle), std::string::npos)                                    \
      << "message: " << (haystack) << "\nexpected to contain: " << (needle)

// File name, JSON path and offending value: the three things every message must name.
void expect_error(const std::string& message, const std::string& path, const std::string& value) {
  EXPECT_CONTAINS(message, "broken.json: ");
  EXPECT_CONTAINS(message, path + " = " + value);
}

bool finite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

void expect_mesh_sane(const Mesh& m, const std::string& what) {
  ASSERT_GT(m.triangle_count(), 0u) << what;
  ASSERT_EQ(m.indices.size() % 3, 0u) << what;
  ASSERT_EQ(m.normals.size(), m.positions.size()) << what;
  for (const std::uint32_t i : m.indices) ASSERT_LT(i, m.positions.size()) << what;
  for (const glm::vec3& p : m.positions) ASSERT_TRUE(finite(p)) << what;
  for (const glm::vec3& n : m.normals) {
    ASSERT_TRUE(finite(n)) << what;
    ASSERT_NEAR(glm::length(n), 1.0f, 1e-3f) << what;
  }
}

// "Nothing non-finite ends up in the Scene", and the structural promises of the loader.
void expect_scene_sane(const Scene& s) {
  EXPECT_TRUE(finite(s.camera.position));
  EXPECT_TRUE(finite(s.camera.target));
  EXPECT_TRUE(finite(s.camera.up));
  EXPECT_GT(s.camera.far_m, s.camera.near_m);
  EXPECT_GT(s.camera.near_m, 0.0f);
  EXPECT_TRUE(std::isfinite(s.camera.lens.aperture_m));
  EXPECT_TRUE(std::isfinite(s.camera.lens.focus_distance_m));
  EXPECT_EQ(fovea::protocol::validate(s.display), "");
  std::set<std::string> names;
  for (std::size_t i = 0; i < s.objects.size(); ++i) {
    const Object& o = s.objects[i];
    EXPECT_EQ(o.id, i + 1) << o.name;
    EXPECT_TRUE(names.insert(o.name).second) << o.name;
    EXPECT_LT(o.material, s.materials.size()) << o.name;
    EXPECT_GE(o.task_importance, 0.0f);
    EXPECT_LE(o.task_importance, 1.0f);
    ASSERT_NE(o.mesh, nullptr);
    expect_mesh_sane(*o.mesh, o.name);
    for (const LodLevel& l : o.lods) {
      expect_mesh_sane(*l.mesh, o.name + " lod");
      EXPECT_TRUE(std::isfinite(l.max_error_m));
      EXPECT_GE(l.max_error_m, 0.0f);
    }
    for (const double t : {0.0, 0.37, 1.0, 2.5, 7.9, 100.0}) {
      const Transform tr = o.transform_at(t);
      EXPECT_TRUE(finite(tr.translation) && finite(tr.rotation_deg) && finite(tr.scale)) << o.name;
    }
  }
  for (const Material& m : s.materials) {
    EXPECT_TRUE(finite(m.kd) && finite(m.ks) && finite(m.emission) && finite(m.reflectance)) << m.name;
    for (int c = 0; c < 3; ++c) EXPECT_LE(m.kd[c] + m.ks[c], 1.0f + 1e-6f) << m.name;
  }
  for (const Light& l : s.lights) {
    EXPECT_TRUE(finite(l.position) && finite(l.power) && finite(l.direction));
    EXPECT_NEAR(glm::length(l.direction), 1.0f, 1e-4f);
  }
}

glm::vec3 bounds_min(const Mesh& m) {
  glm::vec3 lo(INFINITY);
  for (const glm::vec3& p : m.positions) lo = glm::min(lo, p);
  return lo;
}
glm::vec3 bounds_max(const Mesh& m) {
  glm::vec3 hi(-INFINITY);
  for (const glm::vec3& p : m.positions) hi = glm::max(hi, p);
  return hi;
}

const Object& object(const Scene& s, const std::string& name) {
  for (const Object& o : s.objects) {
    if (o.name == name) return o;
  }
  throw std::runtime_error("no object " + name);
}
const Material& material_of(const Scene& s, const Object& o) { return s.materials.at(o.material); }

Json mesh_scene(const std::string& file) {
  Json doc = base_scene();
  doc["objects"][0]["geometry"] = Json{{"mesh", file}};
  return doc;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Bundled scenes

TEST(BundledScenes, EveryBundledSceneLoadsAndIsSane) {
  int count = 0;
  for (const auto& entry : fs::directory_iterator(kBundled)) {
    if (entry.path().extension() != ".json") continue;
    SCOPED_TRACE(entry.path().string());
    const Scene s = load_scene(entry.path());
    EXPECT_EQ(s.source, entry.path());
    EXPECT_FALSE(s.name.empty());
    EXPECT_FALSE(s.lights.empty());
    expect_scene_sane(s);
    ++count;
  }
  EXPECT_GE(count, 3);
}

TEST(BundledScenes, BundledAssetsAreSmall) {
  std::uintmax_t total = 0;
  for (const auto& entry : fs::recursive_directory_iterator(kBundled)) {
    if (entry.is_regular_file()) total += entry.file_size();
  }
  EXPECT_LT(total, 200u * 1024u);
}

TEST(BundledScenes, CornellBoxAsJensenPedersen) {
  const Scene s = load_scene(kBundled / "cornell.json");
  EXPECT_EQ(s.name, "cornell");
  EXPECT_EQ(s.camera.width, 640u);
  EXPECT_EQ(s.camera.height, 480u);
  EXPECT_TRUE(s.camera.lens.is_pinhole());
  // Six walls of two triangles each: the 12-triangle room of J&P §9.
  std::size_t room_triangles = 0;
  for (const char* wall : {"floor", "ceiling", "back_wall", "front_wall", "left_wall", "right_wall"}) {
    const Object& o = object(s, wall);
    room_triangles += o.mesh->triangle_count();
    EXPECT_EQ(material_of(s, o).type, MaterialType::Lambertian);
  }
  EXPECT_EQ(room_triangles, 12u);
  const glm::vec3 red = material_of(s, object(s, "left_wall")).kd;
  const glm::vec3 green = material_of(s, object(s, "right_wall")).kd;
  const glm::vec3 white = material_of(s, object(s, "floor")).kd;
  EXPECT_GT(red.r, 5 * red.g);
  EXPECT_GT(green.g, 5 * green.r);
  EXPECT_FLOAT_EQ(white.r, white.g);
  EXPECT_EQ(material_of(s, object(s, "ceiling")).name, material_of(s, object(s, "back_wall")).name);
  // Walls face into the room: the normal of each wall points towards the room centre.
  const glm::vec3 centre(0, 1.1f, 0);
  for (const Object& o : s.objects) {
    if (o.name == "sphere") continue;
    const glm::mat4 m = o.transform.matrix();
    const glm::vec3 n = glm::normalize(glm::vec3(m * glm::vec4(o.mesh->normals[0], 0)));
    EXPECT_GT(glm::dot(n, centre - glm::vec3(m[3])), 0) << o.name;
  }
  const Object& sphere = object(s, "sphere");
  EXPECT_EQ(material_of(s, sphere).type, MaterialType::BlinnPhong);
  ASSERT_EQ(s.lights.size(), 1u);
  EXPECT_EQ(s.lights[0].type, LightType::Point);
  EXPECT_FLOAT_EQ(s.lights[0].position.y, 1.7f);  // 200 W point light 1.7 m above the floor
  EXPECT_FLOAT_EQ(s.lights[0].power.g, 200.0f);
  EXPECT_FALSE(s.has_specular_or_refractive());
  EXPECT_EQ(s.display.width_px, 1650u);
  EXPECT_DOUBLE_EQ(s.display.viewing_distance_m, 0.6);

  // The specular variant is one override away.
  const Scene glass = load_scene(kBundled / "cornell.json", {{"objects.6.material", "glass"}});
  EXPECT_TRUE(glass.has_specular_or_refractive());
  EXPECT_EQ(material_of(glass, object(glass, "sphere")).type, MaterialType::Glass);
}

TEST(BundledScenes, AttentionSceneHasDepthMotionImportanceAndLod) {
  const Scene s = load_scene(kBundled / "attention.json");
  EXPECT_GE(s.objects.size(), 12u);
  EXPECT_FALSE(s.camera.lens.is_pinhole());
  const glm::vec3 eye = s.camera.position;
  float nearest = INFINITY, farthest = 0;
  std::set<float> importances;
  int animated = 0, rotating = 0, approaching = 0, sideways = 0;
  for (const Object& o : s.objects) {
    if (o.name == "ground") continue;
    const float d = glm::distance(eye, o.transform.translation);
    nearest = std::min(nearest, d);
    farthest = std::max(farthest, d);
    importances.insert(o.task_importance);
    if (!o.animation) continue;
    ++animated;
    float dz = 0, dx = 0, drot = 0;
    for (const AnimationKey& k : o.animation->keys) {
      dz = std::max(dz, std::abs(k.translation.z));
      dx = std::max(dx, std::abs(k.translation.x));
      drot = std::max(drot, glm::length(k.rotation_deg));
    }
    approaching += dz > 1.0f;
    sideways += dx > 1.0f;
    rotating += drot > 90.0f;
  }
  EXPECT_LE(nearest, 1.5f);
  EXPECT_GE(farthest, 14.0f);
  EXPECT_LE(farthest, 16.5f);
  EXPECT_GE(importances.size(), 5u);
  EXPECT_GE(animated, 3);
  EXPECT_GE(approaching, 1);
  EXPECT_GE(sideways, 1);
  EXPECT_GE(rotating, 1);
  EXPECT_TRUE(s.has_animation());
  EXPECT_TRUE(s.has_lods());
  std::set<LightType> kinds;
  for (const Light& l : s.lights) kinds.insert(l.type);
  EXPECT_EQ(kinds.size(), 3u);

  // The blob comes from an OBJ through assimp and carries a decreasing LOD chain.
  const Object& blob = object(s, "blob");
  EXPECT_EQ(blob.mesh->triangle_count(), 320u);
  ASSERT_EQ(blob.lods.size(), 3u);
  std::size_t prev = blob.mesh->triangle_count();
  for (const LodLevel& l : blob.lods) {
    EXPECT_LT(l.mesh->triangle_count(), prev);
    prev = l.mesh->triangle_count();
    EXPECT_GT(l.max_error_m, 0.0f);
    EXPECT_LT(l.max_error_m, 0.5f);  // less than the blob's radius
  }
  // Generated normals point outwards (consistent winding in the asset).
  int outward = 0;
  for (std::size_t i = 0; i < blob.mesh->positions.size(); ++i) {
    outward += glm::dot(blob.mesh->normals[i], blob.mesh->positions[i]) > 0;
  }
  EXPECT_EQ(static_cast<std::size_t>(outward), blob.mesh->positions.size());
}

TEST(BundledScenes, OcclusionSceneHasThinForegroundAndFocusedBackground) {
  const Scene s = load_scene(kBundled / "occlusion.json");
  const Lens& lens = s.camera.lens;
  ASSERT_FALSE(lens.is_pinhole());
  EXPECT_NEAR(lens.aperture_m, 0.05 / 1.4, 1e-9);
  EXPECT_DOUBLE_EQ(lens.focus_distance_m, 6.0);
  int bars = 0, tiles = 0;
  std::set<std::uint32_t> tile_materials;
  for (const Object& o : s.objects) {
    const float depth = s.camera.position.z - o.transform.translation.z;
    const glm::vec3 size = bounds_max(*o.mesh) - bounds_min(*o.mesh);
    if (o.name.starts_with("bar_")) {
      ++bars;
      EXPECT_NEAR(depth, 1.0f, 0.05f);
      EXPECT_LT(std::min(size.x, size.z), 0.03f);  // thin
    } else if (o.name.starts_with("tile_")) {
      ++tiles;
      EXPECT_NEAR(depth, 6.0f, 0.1f);
      tile_materials.insert(o.material);
    }
  }
  EXPECT_GE(bars, 5);
  EXPECT_GE(tiles, 12);
  EXPECT_GE(tile_materials.size(), 3u);
  EXPECT_NEAR(s.camera.position.z - object(s, "background").transform.translation.z, 6.0f, 1e-4f);
}

// ---------------------------------------------------------------------------------------------
// Mesh files

TEST(MeshFiles, ObjQuadsAreTriangulatedAndObjectsMerged) {
  const Scene s = parse(mesh_scene("cube.obj"));
  const Mesh& m = *s.objects[0].mesh;
  EXPECT_EQ(m.triangle_count(), 12u);  // 6 quads in two OBJ objects
  EXPECT_NEAR(bounds_min(m).x, -0.5f, 1e-6f);
  EXPECT_NEAR(bounds_max(m).y, 0.5f, 1e-6f);
  expect_mesh_sane(m, "cube.obj");
}

TEST(MeshFiles, PlyPolygonsAreTriangulated) {
  const Scene s = parse(mesh_scene("pyramid.ply"));
  const Mesh& m = *s.objects[0].mesh;
  EXPECT_EQ(m.triangle_count(), 6u);  // quad base + 4 sides
  EXPECT_NEAR(bounds_max(m).y, 1.0f, 1e-6f);
  expect_mesh_sane(m, "pyramid.ply");
}

TEST(MeshFiles, GltfWithEmbeddedBufferHonoursNodeTransforms) {
  const Scene s = parse(mesh_scene("two_quads.gltf"));
  const Mesh& m = *s.objects[0].mesh;
  EXPECT_EQ(m.triangle_count(), 4u);  // one quad instanced by two nodes
  expect_mesh_sane(m, "two_quads.gltf");
  // Node "right": translated +2 in x, so x in [1.5, 2.5]; node "down": scaled 2x, at y = -2.
  EXPECT_NEAR(bounds_max(m).x, 2.5f, 1e-5f);
  EXPECT_NEAR(bounds_min(m).x, -1.0f, 1e-5f);
  EXPECT_NEAR(bounds_min(m).y, -2.0f, 1e-5f);
  EXPECT_NEAR(bounds_max(m).y, 0.0f, 1e-5f);
  for (const glm::vec3& n : m.normals) EXPECT_NEAR(n.y, 1.0f, 1e-4f);
}

TEST(MeshFiles, SameFileIsLoadedOnceAndShared) {
  Json doc = mesh_scene("cube.obj");
  doc["objects"][1]["geometry"] = Json{{"mesh", "cube.obj"}};
  const Scene s = parse(doc);
  EXPECT_EQ(s.objects[0].mesh, s.objects[1].mesh);
}

// ---------------------------------------------------------------------------------------------
// Levels of detail

TEST(Lod, SimplifyProducesDecreasingTriangleCounts) {
  Json doc = base_scene();
  doc["objects"][0]["geometry"]["sphere"] = Json{{"radius", 1.0}, {"rings", 32}, {"segments", 64}};
  doc["objects"][0]["lod"] = Json{{"simplify", {0.5, 0.25, 0.1, 0.02}}};
  const Scene s = parse(doc);
  const Object& o = s.objects[0];
  ASSERT_EQ(o.lods.size(), 4u);
  std::size_t prev = o.mesh->triangle_count();
  float prev_error = 0;
  for (std::size_t i = 0; i < o.lods.size(); ++i) {
    const LodLevel& l = o.lods[i];
    EXPECT_LT(l.mesh->triangle_count(), prev) << i;
    EXPECT_GE(l.max_error_m, prev_error) << i;  // coarser levels are further from the full mesh
    EXPECT_LT(l.max_error_m, 1.0f) << i;        // but never further than the radius
    prev = l.mesh->triangle_count();
    prev_error = l.max_error_m;
  }
  // Roughly the requested ratios.
  EXPECT_NEAR(static_cast<double>(o.lods[0].mesh->triangle_count()) / static_cast<double>(o.mesh->triangle_count()),
              0.5, 0.1);
  expect_scene_sane(s);
}

TEST(Lod, ExplicitLevelsFromFiles) {
  Json doc = mesh_scene("cube.obj");
  doc["objects"][0]["lod"] = Json::parse(R"([{"mesh": "pyramid.ply", "max_error_m": 0.1},
                                             {"mesh": "two_quads.gltf", "max_error_m": 0.4}])");
  const Scene s = parse(doc);
  ASSERT_EQ(s.objects[0].lods.size(), 2u);
  EXPECT_EQ(s.objects[0].lods[0].mesh->triangle_count(), 6u);
  EXPECT_FLOAT_EQ(s.objects[0].lods[1].max_error_m, 0.4f);
}

TEST(Lod, BadLodInputs) {
  Json doc = base_scene();
  doc["objects"][0]["lod"] = Json{{"simplify", {0.5, 0.6}}};
  expect_error(error_of(doc), "$.objects[0].lod.simplify[1]", "0.6");

  doc["objects"][0]["lod"] = Json{{"simplify", {1.5}}};
  expect_error(error_of(doc), "$.objects[0].lod.simplify[0]", "1.5");

  // A box cannot lose triangles without changing its topology: say so instead of a useless level.
  doc["objects"][0]["geometry"] = Json{{"box", {1, 1, 1}}};
  doc["objects"][0]["lod"] = Json{{"simplify", {0.5}}};
  const std::string msg = error_of(doc);
  expect_error(msg, "$.objects[0].lod.simplify[0]", "0.5");
  EXPECT_CONTAINS(msg, "not fewer than the 12");

  doc = base_scene();
  doc["objects"][0]["lod"] = Json::parse(R"([{"mesh": "cube.obj", "max_error_m": 0.3},
                                             {"mesh": "cube.obj", "max_error_m": 0.1}])");
  expect_error(error_of(doc), "$.objects[0].lod[1].max_error_m", "0.1");
}

// ---------------------------------------------------------------------------------------------
// Animation

TEST(Animation, KeysAreInterpolatedAndLooped) {
  Json doc = base_scene();
  doc["objects"][0]["animation"] = Json::parse(R"({"loop": true, "keys": [
      {"t": 0, "translation": [0, 0, 0], "rotation_deg": [0, 0, 0]},
      {"t": 2, "translation": [2, 0, -4], "rotation_deg": [0, 90, 0]}]})");
  doc["objects"][1]["animation"] = Json::parse(R"({"loop": false, "keys": [
      {"t": 1, "translation": [0, 1, 0]}, {"t": 3, "translation": [0, 3, 0]}]})");
  doc["camera"]["animation"] = Json::parse(R"({"keys": [{"t": 0}, {"t": 4, "translation": [4, 0, 0]}]})");
  const Scene s = parse(doc);
  ASSERT_TRUE(s.has_animation());
  const Object& ball = s.objects[0];
  const Transform mid = ball.transform_at(1.0);
  EXPECT_NEAR(mid.translation.x, 1.0f, 1e-5f);
  EXPECT_NEAR(mid.translation.y, 1.0f, 1e-5f);  // base translation y = 1 plus 0
  EXPECT_NEAR(mid.translation.z, -2.0f, 1e-5f);
  EXPECT_NEAR(mid.rotation_deg.y, 45.0f, 1e-4f);
  const Transform wrapped = ball.transform_at(3.0);  // loop of length 2: t = 3 is t = 1
  EXPECT_NEAR(wrapped.translation.x, 1.0f, 1e-5f);

  const Object& floor = s.objects[1];
  EXPECT_NEAR(floor.transform_at(0.0).translation.y, 1.0f, 1e-6f);   // clamped before the first key
  EXPECT_NEAR(floor.transform_at(2.0).translation.y, 2.0f, 1e-6f);
  EXPECT_NEAR(floor.transform_at(10.0).translation.y, 3.0f, 1e-6f);  // held after the last key

  EXPECT_NEAR(s.camera.position_at(2.0).x, 2.0f, 1e-5f);
  EXPECT_TRUE(s.camera.animation->loop);  // default
}

TEST(Animation, BadKeys) {
  Json doc = base_scene();
  doc["objects"][0]["animation"] = Json::parse(R"({"keys": [{"t": 1}, {"t": 1}]})");
  expect_error(error_of(doc), "$.objects[0].animation.keys[1].t", "1");
  doc["objects"][0]["animation"] = Json::parse(R"({"keys": []})");
  expect_error(error_of(doc), "$.objects[0].animation.keys", "[]");
  doc["objects"][0]["animation"] = Json::parse(R"({"keys": [{"t": 0}], "loop": "yes"})");
  expect_error(error_of(doc), "$.objects[0].animation.loop", "\"yes\"");
  doc = base_scene();
  doc["camera"]["animation"] = Json::parse(R"({"keys": [{"t": 0, "rotation_deg": [0, 10, 0]}]})");
  expect_error(error_of(doc), "$.camera.animation.keys[0].rotation_deg", "[0,10,0]");
}

// ---------------------------------------------------------------------------------------------
// Camera, lens, materials, lights, display

TEST(Parsing, DefaultsAndBasicValues) {
  const Scene s = parse(base_scene());
  EXPECT_EQ(s.name, "base");
  EXPECT_EQ(s.source, fs::path("broken.json"));
  EXPECT_EQ(s.camera.width, 64u);
  EXPECT_TRUE(s.camera.lens.is_pinhole());
  EXPECT_EQ(s.display, fovea::protocol::DisplayGeometry{});
  ASSERT_EQ(s.materials.size(), 2u);
  EXPECT_EQ(s.materials[0].name, "white");  // file order is kept
  EXPECT_EQ(s.objects[1].material, 1u);
  EXPECT_EQ(s.objects[1].id, 2u);
  expect_scene_sane(s);

  Json unnamed = base_scene();
  unnamed.erase("name");
  EXPECT_EQ(parse_scene(unnamed.dump(), "dir/room.json", kFixtures).name, "room");
}

TEST(Parsing, StereoCamera) {
  const Scene mono = parse(base_scene());
  EXPECT_FALSE(mono.camera.stereo);
  EXPECT_FLOAT_EQ(mono.camera.ipd_m, 0.063f);
  EXPECT_EQ(mono.camera.eye_offset_m, 0.0f);
  const Scene stereo = parse(base_scene(), {{"camera.stereo", "true"}, {"camera.ipd_m", "0.07"}});
  EXPECT_TRUE(stereo.camera.stereo);
  EXPECT_FLOAT_EQ(stereo.camera.ipd_m, 0.07f);
  for (const char* bad : {"0", "-0.06", "1.5"}) {
    const std::string msg = error_of(base_scene(), {{"camera.ipd_m", bad}});
    expect_error(msg, "$.camera.ipd_m", bad);
    EXPECT_CONTAINS(msg, "(0, 1]");
  }
  expect_error(error_of(base_scene(), {{"camera.stereo", "2"}}), "$.camera.stereo", "2");
}

TEST(Parsing, MaterialsAsArray) {
  Json doc = base_scene();
  doc["materials"] = Json::parse(R"([{"name": "white", "type": "lambertian"},
                                     {"name": "red", "type": "mirror", "reflectance": [0.9, 0.5, 0.5]}])");
  const Scene s = parse(doc);
  EXPECT_EQ(s.materials[1].type, MaterialType::Mirror);
  EXPECT_FLOAT_EQ(s.materials[1].ks.g, 0.5f);  // highlight tinted by the reflectance
  EXPECT_FLOAT_EQ(s.materials[1].kd.r, 0.0f);
  EXPECT_TRUE(s.has_specular_or_refractive());

  doc["materials"][1]["name"] = "white";
  expect_error(error_of(doc), "$.materials[1].name", "\"white\"");
}

TEST(Parsing, Lenses) {
  Json doc = base_scene();
  doc["camera"]["lens"] = Json::parse(R"({"type": "thin-lens", "focal_length_mm": 35, "aperture_mm": 10,
                                          "focus_distance_m": 3, "image_distance_mm": 36})");
  Scene s = parse(doc);
  EXPECT_DOUBLE_EQ(s.camera.lens.focal_length_m, 0.035);
  EXPECT_DOUBLE_EQ(s.camera.lens.aperture_m, 0.010);
  EXPECT_DOUBLE_EQ(s.camera.lens.image_distance_m, 0.036);

  doc["camera"]["lens"] = Json::parse(R"({"type": "human-eye", "focus_distance_m": 0.8})");
  s = parse(doc);
  const Lens eye = Lens::human_eye(0.8);
  EXPECT_DOUBLE_EQ(s.camera.lens.focal_length_m, eye.focal_length_m);
  EXPECT_DOUBLE_EQ(s.camera.lens.aperture_m, 0.004);
  EXPECT_DOUBLE_EQ(s.camera.lens.image_distance_m, 0.024);
  EXPECT_DOUBLE_EQ(s.camera.lens.focus_distance_m, 0.8);

  doc["camera"]["lens"] = Json::parse(R"({"type": "thin-lens", "focal_length_mm": 50, "f_number": 2,
                                          "aperture_mm": 25, "focus_distance_m": 3})");
  expect_error(error_of(doc), "$.camera.lens.aperture_mm", "25");
  doc["camera"]["lens"] = Json::parse(R"({"type": "thin-lens", "focal_length_mm": 50, "focus_distance_m": 3})");
  EXPECT_CONTAINS(error_of(doc), "$.camera.lens.f_number: missing required field");
  doc["camera"]["lens"] = Json::parse(R"({"type": "thin-lens", "focal_length_mm": 50, "f_number": 2,
                                          "focus_distance_m": 0.04})");
  expect_error(error_of(doc), "$.camera.lens.focus_distance_m", "0.04");
  doc["camera"]["lens"] = Json::parse(R"({"type": "pinhole", "f_number": 2})");
  expect_error(error_of(doc), "$.camera.lens.f_number", "2");
  doc["camera"]["lens"] = Json::parse(R"({"type": "fisheye"})");
  expect_error(error_of(doc), "$.camera.lens.type", "\"fisheye\"");
}

TEST(Parsing, LightsOfEveryKind) {
  Json doc = base_scene();
  doc["lights"] = Json::parse(R"([
      {"type": "spot", "position": [0, 3, 0], "direction": [0, -2, 0], "power": [10, 10, 10], "cutoff_deg": 3},
      {"type": "area", "position": [0, 3, 0], "normal": [0, 0, -5], "size": [2, 1], "power": [1, 2, 3],
       "samples": 16}])");
  const Scene s = parse(doc);
  EXPECT_EQ(s.lights[0].type, LightType::Spot);
  EXPECT_FLOAT_EQ(s.lights[0].direction.y, -1.0f);
  EXPECT_FLOAT_EQ(s.lights[0].spot_falloff_deg, 3.0f);  // default 5, limited to the cutoff
  EXPECT_EQ(s.lights[1].type, LightType::Area);
  EXPECT_FLOAT_EQ(s.lights[1].direction.z, -1.0f);
  EXPECT_EQ(s.lights[1].area_samples, 16);
  EXPECT_FLOAT_EQ(s.lights[1].area_size.x, 2.0f);
  expect_scene_sane(s);
}

// ---------------------------------------------------------------------------------------------
// The catalogue of bad inputs

TEST(SceneErrors, MissingMeshFileNamesTheResolvedPath) {
  const std::string msg = error_of(mesh_scene("meshes/nope.obj"));
  expect_error(msg, "$.objects[0].geometry.mesh", "\"meshes/nope.obj\"");
  EXPECT_CONTAINS(msg, (kFixtures / "meshes" / "nope.obj").string());
}

TEST(SceneErrors, UnsupportedMeshFormatNamesExtensionAndSupportedList) {
  const std::string msg = error_of(mesh_scene("model.stl"));
  expect_error(msg, "$.objects[0].geometry.mesh", "\"model.stl\"");
  EXPECT_CONTAINS(msg, "'.stl'");
  EXPECT_CONTAINS(msg, ".obj, .ply, .gltf, .glb");
}

TEST(SceneErrors, DegenerateMeshWithoutTriangles) {
  const std::string msg = error_of(mesh_scene("lines_only.obj"));
  expect_error(msg, "$.objects[0].geometry.mesh", "\"lines_only.obj\"");
  EXPECT_CONTAINS(msg, "no triangles");
}

TEST(SceneErrors, NonFiniteVertexInMeshFileIsRejectedOrRepaired) {
  // Whatever assimp makes of "nan" in an OBJ, no NaN may reach the Scene.
  try {
    const Scene s = parse(mesh_scene("nan_vertex.obj"));
    expect_scene_sane(s);
  } catch (const SceneError& e) {
    expect_error(e.what(), "$.objects[0].geometry.mesh", "\"nan_vertex.obj\"");
  }
}

TEST(SceneErrors, ZeroAreaDisplay) {
  Json doc = base_scene();
  doc["display"] = Json{{"width_px", 1920}, {"height_px", 1080}, {"width_mm", 0}, {"height_mm", 300},
                        {"viewing_distance_mm", 600}};
  std::string msg = error_of(doc);
  expect_error(msg, "$.display.width_mm", "0");
  EXPECT_CONTAINS(msg, "non-zero area");
  doc["display"]["width_mm"] = 500;
  doc["display"]["height_px"] = 0;
  expect_error(error_of(doc), "$.display.height_px", "0");
}

TEST(SceneErrors, NaNAndInfinityInTransform) {
  Json doc = base_scene();
  doc["objects"][0]["transform"]["translation"][1] = "nan";
  std::string msg = error_of(doc);
  expect_error(msg, "$.objects[0].transform.translation[1]", "\"nan\"");
  EXPECT_CONTAINS(msg, "finite number");

  doc["objects"][0]["transform"]["translation"][1] = "Infinity";
  expect_error(error_of(doc), "$.objects[0].transform.translation[1]", "\"Infinity\"");

  // Numbers that overflow a double are caught by the parser, at their path.
  doc["objects"][0]["transform"]["translation"][1] = "@OVERFLOW@";
  std::string text = doc.dump();
  const std::string marker = "\"@OVERFLOW@\"";
  text.replace(text.find(marker), marker.size(), "1e999");
  msg = error_of_text(text);
  expect_error(msg, "$.objects[0].transform.translation[1]", "1e999");
  EXPECT_CONTAINS(msg, "finite number");

  text.replace(text.find("1e999"), 5, "-1e999");
  expect_error(error_of_text(text), "$.objects[0].transform.translation[1]", "-1e999");

  doc = base_scene();
  doc["objects"][0]["transform"]["rotation_deg"] = {0, "NaN", 0};
  expect_error(error_of(doc), "$.objects[0].transform.rotation_deg[1]", "\"NaN\"");
  doc = base_scene();
  doc["objects"][0]["transform"]["scale"] = 0;
  expect_error(error_of(doc), "$.objects[0].transform.scale", "0");
}

TEST(SceneErrors, UnknownMaterialReference) {
  Json doc = base_scene();
  doc["objects"][1]["material"] = "gold";
  const std::string msg = error_of(doc);
  expect_error(msg, "$.objects[1].material", "\"gold\"");
  EXPECT_CONTAINS(msg, "white, red");
}

TEST(SceneErrors, UnknownFieldsAreNotIgnored) {
  Json doc = base_scene();
  doc["objects"][0]["transfrom"] = doc["objects"][0]["transform"];
  std::string msg = error_of(doc);
  expect_error(msg, "$.objects[0].transfrom", "{\"translation\":[0,1,0]}");
  EXPECT_CONTAINS(msg, "unknown field");
  EXPECT_CONTAINS(msg, "name, geometry, material, transform");
  EXPECT_CONTAINS(msg, "did you mean 'transform'");

  doc = base_scene();
  doc["camera"]["fov"] = 60;
  expect_error(error_of(doc), "$.camera.fov", "60");
  doc = base_scene();
  doc["lightz"] = Json::array();
  expect_error(error_of(doc), "$.lightz", "[]");
  // A field of another material type is named as such.
  doc = base_scene();
  doc["materials"]["white"]["ks"] = {0.1, 0.1, 0.1};
  msg = error_of(doc);
  expect_error(msg, "$.materials.white.ks", "[0.1,0.1,0.1]");
  EXPECT_CONTAINS(msg, "does not apply to a lambertian material");
  // Light fields per type.
  doc = base_scene();
  doc["lights"][0]["cutoff_deg"] = 20;
  expect_error(error_of(doc), "$.lights[0].cutoff_deg", "20");
}

TEST(SceneErrors, WrongTypes) {
  Json doc = base_scene();
  doc["camera"]["width"] = "640";
  std::string msg = error_of(doc);
  expect_error(msg, "$.camera.width", "\"640\"");
  EXPECT_CONTAINS(msg, "integer in 1..16384");
  doc["camera"]["width"] = 640.5;
  expect_error(error_of(doc), "$.camera.width", "640.5");
  doc = base_scene();
  doc["materials"]["white"]["kd"] = 0.5;
  expect_error(error_of(doc), "$.materials.white.kd", "0.5");
  doc = base_scene();
  doc["objects"][0]["name"] = 7;
  expect_error(error_of(doc), "$.objects[0].name", "7");
  doc = base_scene();
  doc["camera"] = Json::array();
  expect_error(error_of(doc), "$.camera", "[]");
  doc = base_scene();
  doc["lights"] = Json::object();
  expect_error(error_of(doc), "$.lights", "{}");
  EXPECT_CONTAINS(error_of_text("[1, 2]"), "broken.json: $ = [1,2]");
}

TEST(SceneErrors, EmptyOrMissingObjects) {
  Json doc = base_scene();
  doc["objects"] = Json::array();
  expect_error(error_of(doc), "$.objects", "[]");
  doc.erase("objects");
  EXPECT_CONTAINS(error_of(doc), "broken.json: $.objects: missing required field");
}

TEST(SceneErrors, RangesAreEnforced) {
  struct Case {
    const char* pointer;
    Json value;
    const char* path;
    const char* shown;
  };
  const std::vector<Case> cases = {
      {"/camera/vertical_fov_deg", 180, "$.camera.vertical_fov_deg", "180"},
      {"/camera/vertical_fov_deg", 0, "$.camera.vertical_fov_deg", "0"},
      {"/camera/height", 16385, "$.camera.height", "16385"},
      {"/camera/near", 200, "$.camera.near", "200"},
      {"/camera/target", Json{0, 1, 5}, "$.camera.target", "[0,1,5]"},
      {"/camera/up", Json{0, 0, -1}, "$.camera.up", "[0,0,-1]"},
      {"/objects/0/task_importance", 1.5, "$.objects[0].task_importance", "1.5"},
      {"/objects/0/geometry/sphere/radius", -1, "$.objects[0].geometry.sphere.radius", "-1"},
      {"/objects/0/geometry/sphere/rings", 1, "$.objects[0].geometry.sphere.rings", "1"},
      {"/objects/1/geometry/plane", Json{4, 0}, "$.objects[1].geometry.plane[1]", "0"},
      {"/materials/red/ks", Json{0.6, 0.3, 0.3}, "$.materials.red.ks", "[0.6,0.3,0.3]"},  // kd + ks > 1
      {"/materials/white/kd", Json{0.5, -0.1, 0.5}, "$.materials.white.kd[1]", "-0.1"},
      {"/materials/red/shininess", -2, "$.materials.red.shininess", "-2"},
      {"/lights/0/power", Json{1, 1, -1}, "$.lights[0].power[2]", "-1"},
      {"/lights/0/type", "laser", "$.lights[0].type", "\"laser\""},
      {"/ambient", Json{0.1, 0.1}, "$.ambient", "[0.1,0.1]"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.pointer);
    Json doc = base_scene();
    doc[Json::json_pointer(c.pointer)] = c.value;
    expect_error(error_of(doc), c.path, c.shown);
  }

  Json doc = base_scene();
  doc["materials"]["glass"] = Json{{"type", "glass"}, {"ior", 0.9}};
  expect_error(error_of(doc), "$.materials.glass.ior", "0.9");
  doc = base_scene();
  doc["lights"][0] = Json::parse(R"({"type": "spot", "position": [0, 3, 0], "direction": [0, -1, 0],
                                     "power": [1, 1, 1], "cutoff_deg": 95})");
  expect_error(error_of(doc), "$.lights[0].cutoff_deg", "95");
  doc["lights"][0]["cutoff_deg"] = 20;
  doc["lights"][0]["falloff_deg"] = 25;
  expect_error(error_of(doc), "$.lights[0].falloff_deg", "25");
  doc["lights"][0] = Json::parse(R"({"type": "area", "position": [0, 3, 0], "normal": [0, 0, 0],
                                     "power": [1, 1, 1]})");
  expect_error(error_of(doc), "$.lights[0].normal", "[0,0,0]");
  doc["lights"][0]["normal"] = {0, -1, 0};
  doc["lights"][0]["samples"] = 17;
  expect_error(error_of(doc), "$.lights[0].samples", "17");
}

TEST(SceneErrors, DuplicatesAndSyntax) {
  Json doc = base_scene();
  doc["objects"][1]["name"] = "ball";
  std::string msg = error_of(doc);
  expect_error(msg, "$.objects[1].name", "\"ball\"");
  EXPECT_CONTAINS(msg, "$.objects[0].name");

  msg = error_of_text(R"({"camera": {"width": 10, "width": 20}})");
  EXPECT_CONTAINS(msg, "broken.json: $.camera.width: duplicate key");

  msg = error_of_text("{\"camera\": {\"width\": 10,}}");
  EXPECT_CONTAINS(msg, "broken.json: invalid JSON");
  EXPECT_CONTAINS(msg, "line 1");
}

// Issue 23 item 8: 20 spheres at the largest rings and segments took 5.5 GB; a 16384^2 camera
// ended in a bare std::bad_alloc. The budget is checked before anything is built, by path.
TEST(SceneErrors, TheMemoryBudgetIsCheckedBeforeBuildingByPath) {
  Json doc = base_scene();
  doc["objects"] = Json::array();
  for (int i = 0; i < 20; ++i) {
    doc["objects"].push_back({{"name", "s" + std::to_string(i)}, {"material", "white"},
                              {"geometry", {{"sphere", {{"radius", 0.5}, {"rings", 1024}, {"segments", 2048}}}}}});
  }
  const auto start = std::chrono::steady_clock::now();
  std::string msg = error_of(doc);
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::milliseconds(500)) << "built before it was refused";
  // 4,194,304 triangles each: the eighth takes the scene past 32 M.
  EXPECT_CONTAINS(msg, "broken.json: $.objects[7].geometry.sphere");
  EXPECT_CONTAINS(msg, "a sphere of 1024 rings and 2048 segments takes the scene to 33554432 triangles");
  EXPECT_CONTAINS(msg, "a scene may hold 32000000");

  doc = base_scene();
  doc["camera"]["width"] = 16384;
  doc["camera"]["height"] = 16384;
  msg = error_of(doc);
  EXPECT_CONTAINS(msg, "broken.json: $.camera");
  EXPECT_CONTAINS(msg, "16384x16384 pixels; at most 33177600 (7680x4320)");
  doc["camera"]["width"] = 7680;
  doc["camera"]["height"] = 4320;
  EXPECT_NO_THROW(parse(doc));
}

// Issue 23 item 12: a mesh that is a FIFO was reported "not found" (and a FIFO must not be opened).
TEST(SceneErrors, AMeshThatIsNotARegularFileIsNamedSo) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("fovea-scene-fifo-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  ASSERT_EQ(::mkfifo((dir / "pipe.obj").c_str(), 0600), 0);
  Json doc = base_scene();
  doc["objects"][0]["geometry"] = {{"mesh", "pipe.obj"}};
  std::string msg;
  try {
    parse_scene(doc.dump(), "broken.json", dir);
  } catch (const SceneError& e) {
    msg = e.what();
  }
  std::filesystem::remove_all(dir);
  EXPECT_CONTAINS(msg, "$.objects[0].geometry.mesh");
  EXPECT_CONTAINS(msg, "pipe.obj is not a regular file");
}

// Issue 23 item 7: 100,000 levels overflowed the stack (fovea-render segfaulted).
TEST(SceneErrors, DeepNestingIsRefusedByName) {
  for (const std::size_t depth : {std::size_t{65}, std::size_t{100000}, std::size_t{1000000}}) {
    const std::string text = "{\"objects\": " + std::string(depth, '[') + std::string(depth, ']') + "}";
    const std::string msg = error_of_text(text);
    EXPECT_CONTAINS(msg, "broken.json: $.objects[0][0][0][0][0]...: nested deeper than 64 levels");
    EXPECT_LT(msg.size(), 200u);
  }
  std::string objects;
  for (int i = 0; i < 100000; ++i) objects += "{\"a\": ";
  objects += "1" + std::string(100000, '}');
  EXPECT_CONTAINS(error_of_text(objects), "broken.json: $.a.a.a.a.a.a...: nested deeper than 64 levels");
  // 63 levels below the document still parse (and then fail as a scene, by path).
  const std::string ok = "{\"objects\": " + std::string(63, '[') + std::string(63, ']') + "}";
  EXPECT_EQ(error_of_text(ok).find("nested deeper"), std::string::npos);
}

TEST(SceneErrors, GeometryNeedsExactlyOneShape) {
  Json doc = base_scene();
  doc["objects"][0]["geometry"]["box"] = {1, 1, 1};
  std::string msg = error_of(doc);
  EXPECT_CONTAINS(msg, "broken.json: $.objects[0].geometry = ");
  EXPECT_CONTAINS(msg, "exactly one of");
  doc["objects"][0]["geometry"] = Json::object();
  expect_error(error_of(doc), "$.objects[0].geometry", "{}");
  doc["objects"][0]["geometry"] = Json{{"cone", 1}};
  expect_error(error_of(doc), "$.objects[0].geometry.cone", "1");
}

TEST(SceneErrors, LoadSceneNamesTheFile) {
  const fs::path dir = fs::temp_directory_path() / ("fovea_scene_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path file = dir / "typo.json";
  Json doc = base_scene();
  doc["objects"][0]["materal"] = "white";
  std::ofstream(file) << doc.dump(2);
  try {
    load_scene(file);
    ADD_FAILURE() << "expected a SceneError";
  } catch (const SceneError& e) {
    EXPECT_CONTAINS(e.what(), file.string() + ": $.objects[0].materal = \"white\"");
    EXPECT_CONTAINS(e.what(), "did you mean 'material'");
  }
  try {
    load_scene(dir / "absent.json");
    ADD_FAILURE() << "expected a SceneError";
  } catch (const SceneError& e) {
    EXPECT_CONTAINS(e.what(), (dir / "absent.json").string());
  }
  fs::remove_all(dir);
}

// ---------------------------------------------------------------------------------------------
// Overrides

TEST(Overrides, SetValuesBeforeValidation) {
  const Scene s = parse(base_scene(), {{"camera.width", "320"},
                                       {"lights.0.power", "[1,2,3]"},
                                       {"objects.1.material", "white"},  // not JSON: taken as a string
                                       {"objects.0.task_importance", "0.75"},
                                       {"ambient", "[0.1, 0.2, 0.3]"},   // absent but a known optional field
                                       {"camera.lens.type", "human-eye"},
                                       {"camera.lens.focus_distance_m", "2"},
                                       {"materials.red.ks", "[0.1, 0.1, 0.1]"}});
  EXPECT_EQ(s.camera.width, 320u);
  EXPECT_EQ(s.lights[0].power, glm::vec3(1, 2, 3));
  EXPECT_EQ(s.objects[1].material, 0u);
  EXPECT_FLOAT_EQ(s.objects[0].task_importance, 0.75f);
  EXPECT_FLOAT_EQ(s.ambient.b, 0.3f);
  EXPECT_DOUBLE_EQ(s.camera.lens.focus_distance_m, 2.0);
  EXPECT_DOUBLE_EQ(s.camera.lens.image_distance_m, 0.024);
  EXPECT_FLOAT_EQ(s.materials[1].ks.r, 0.1f);
}

TEST(Overrides, BadOverridesFailClearly) {
  std::string msg = error_of(base_scene(), {{"camera.widht", "320"}});
  EXPECT_CONTAINS(msg, "broken.json: override 'camera.widht=320'");
  EXPECT_CONTAINS(msg, "$.camera.widht");
  EXPECT_CONTAINS(msg, "did you mean 'width'");

  msg = error_of(base_scene(), {{"foo", "1"}});
  EXPECT_CONTAINS(msg, "override 'foo=1'");
  EXPECT_CONTAINS(msg, "$.foo: no such field");

  msg = error_of(base_scene(), {{"lights.3.power", "[1,1,1]"}});
  EXPECT_CONTAINS(msg, "override 'lights.3.power=[1,1,1]'");
  EXPECT_CONTAINS(msg, "$.lights[3]: index out of range (the array has 1 elements)");

  msg = error_of(base_scene(), {{"lights.first.power", "1"}});
  EXPECT_CONTAINS(msg, "$.lights is an array");

  msg = error_of(base_scene(), {{"camera.width.x", "1"}});
  EXPECT_CONTAINS(msg, "$.camera.width = 64 is not an object or array");

  msg = error_of(base_scene(), {{"camera..width", "1"}});
  EXPECT_CONTAINS(msg, "empty path segment");
  msg = error_of(base_scene(), {{"", "1"}});
  EXPECT_CONTAINS(msg, "override '=1'");

  msg = error_of(base_scene(), {{"materials.gold.kd", "[1,1,1]"}});  // materials are named in the file
  EXPECT_CONTAINS(msg, "$.materials.gold: no such field");

  // A value that passes the path but fails validation names the override too.
  msg = error_of(base_scene(), {{"camera.width", "0"}});
  expect_error(msg, "$.camera.width", "0");
  EXPECT_CONTAINS(msg, "set by override 'camera.width=0'");
  msg = error_of(base_scene(), {{"lights.0.power", "[1,2]"}});
  expect_error(msg, "$.lights[0].power", "[1,2]");
  EXPECT_CONTAINS(msg, "set by override 'lights.0.power=[1,2]'");
  msg = error_of(base_scene(), {{"objects.0.transform.translation.0", "1e999"}});
  expect_error(msg, "$.objects[0].transform.translation[0]", "\"1e999\"");
}

// The example in renderer/SCENES.md is a scene that loads (its mesh path is relative to renderer/scenes/).
TEST(Documentation, ScenesMdExampleLoads) {
  std::ifstream in(fs::path(FOVEA_SOURCE_DIR) / "renderer" / "SCENES.md");
  ASSERT_TRUE(in);
  const std::string doc((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto section = doc.find("## Example");
  ASSERT_NE(section, std::string::npos);
  const auto begin = doc.find("```json\n", section);
  ASSERT_NE(begin, std::string::npos);
  const auto end = doc.find("```", begin + 8);
  ASSERT_NE(end, std::string::npos);
  const Scene s = parse_scene(doc.substr(begin + 8, end - begin - 8), "SCENES.md", kBundled);
  EXPECT_EQ(s.name, "example");
  EXPECT_EQ(s.objects.size(), 3u);
  EXPECT_TRUE(s.has_lods());
  EXPECT_TRUE(s.has_animation());
  EXPECT_TRUE(s.has_specular_or_refractive());
  expect_scene_sane(s);
}
