// SPDX-License-Identifier: Apache-2.0
// A glTF asset through load_scene and the Embree backend: two quads of different base colours are
// two objects, each shaded with its own material (fails if nodes were merged or materials dropped).
#include <gtest/gtest.h>

#include <string>

#include "backend/embree/embree_backend.h"
#include "gi/photon_tracer.h"
#include "gltf_render_check.h"
#include "gltf_test_assets.h"
#include "gltf_textured_quads.h"
#include "scene/scene_gltf_include.h"
#include "scene/scene_loader.h"

using namespace fovea::render;
using namespace fovea::test;

namespace {

GBuffer render(const Scene& s, EmbreeGeometry geometry = EmbreeGeometry::Flattened) {
  EmbreeOptions options;
  options.geometry = geometry;
  EmbreeBackend b(options);
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
  EXPECT_NE(load_error(file, {{"lights.0.power", "[1,1,1]"}}).find("a glTF scene takes only camera.width, camera.height, camera.stereo and camera.ipd_m"),
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
  // Instanced geometry: the alpha test sits on the instanced mesh's own BVH.
  const GBuffer g = render(s, EmbreeGeometry::Instanced);
  EXPECT_EQ(g.object_id[pixel_of(s.camera, g, GltfTexturedQuads::centre(1) + glm::vec3(-0.25f, 0, 0))], 0u);
  EXPECT_EQ(g.object_id[pixel_of(s.camera, g, GltfTexturedQuads::centre(1) + glm::vec3(0.25f, 0, 0))], 2u);
}

// Generated tangents follow MikkTSpace at a mirrored UV seam (gltf_textured_quads.h).
TEST(GltfRender, AMirroredSeamUnderANormalMapTiltsEachHalfItsOwnWay) {
  TempDir dir;
  const GltfMirroredSeam strip;
  const Scene s = load_scene(write_gltf(dir.path, "seam", strip.doc(), strip.bin()),
                             {{"camera.width", "128"}, {"camera.height", "64"}});
  expect_mirrored_seam(s.camera, render(s), render(without_normal_maps(s)));
}

// Single-sided materials are back-face culled, with the winding a mirroring node turns round.
TEST(GltfRender, SingleSidedBackFacesAreCulled) {
  TempDir dir;
  const GltfSidedQuads quads;
  const Scene s = load_scene(write_gltf(dir.path, "sided", quads.doc(), quads.bin()),
                             {{"camera.width", "192"}, {"camera.height", "128"}});
  expect_sided_quads(s.camera, render(s));
  expect_sided_quads(s.camera, render(s, EmbreeGeometry::Instanced));
  // Culling is the camera's: a shadow ray still meets the culled quad's back.
  EmbreeBackend b;
  b.set_scene(s);
  SurfaceHit hit;
  EXPECT_TRUE(b.intersect({0, 0.6f, 4}, {0, 0, -1}, 0, 10, RayVisibility::All, hit));
}

namespace {

std::filesystem::path write_json(const std::filesystem::path& dir, const std::string& name, const std::string& text) {
  write_file(dir / name, text);
  return dir / name;
}

}  // namespace

// A JSON scene around a glTF asset: the file's objects and camera pose, the JSON's lens, lights,
// display, per-object task importance and LOD by pattern, and an object of its own.
TEST(GltfRender, JsonSceneIncludesAGltfAssetWithOverrides) {
  TempDir dir;
  const GltfTexturedQuads quads;
  write_gltf(dir.path, "quads", quads.doc(), quads.bin());
  const auto file = write_json(dir.path, "around.json", R"({
    "name": "around",
    "gltf": {"file": "quads.gltf", "camera": "eye", "objects": [
      {"match": "tilt_*", "task_importance": 0.75},
      {"match": "checker", "task_importance": 0.25, "lod": "none"},
      {"match": "mask", "lod": {"chain": {"levels": 3}}}]},
    "camera": {"width": 96, "height": 64, "lens": {"type": "human-eye", "focus_distance_m": 4}},
    "materials": {"white": {"type": "lambertian", "kd": [0.8, 0.8, 0.8]}},
    "objects": [{"name": "ball", "material": "white", "geometry": {"sphere": {"radius": 0.2}},
                 "transform": {"translation": [0, 0, 1]}}],
    "lights": [{"type": "point", "position": [0, 2, 4], "power": [300, 300, 300]}],
    "display": {"width_px": 96, "height_px": 64, "width_mm": 500, "height_mm": 333, "viewing_distance_mm": 600}
  })");
  LoadReport report;
  const Scene s = load_scene(file, {}, {}, &report);
  ASSERT_EQ(s.objects.size(), 7u);
  EXPECT_EQ(s.objects[6].name, "ball");
  EXPECT_EQ(s.objects[6].id, 7u);
  EXPECT_EQ(s.materials.at(s.objects[6].material).name, "white");
  EXPECT_EQ(s.camera.position, glm::vec3(0, 0, 4));  // the file's camera node
  EXPECT_EQ(s.camera.width, 96u);
  EXPECT_DOUBLE_EQ(s.camera.lens.focal_length_m, 0.0167);  // human eye
  ASSERT_EQ(s.lights.size(), 1u);                           // the JSON's replace the file's
  EXPECT_EQ(s.lights[0].position, glm::vec3(0, 2, 4));
  EXPECT_FLOAT_EQ(s.objects[4].task_importance, 0.75f);  // tilt_x
  EXPECT_FLOAT_EQ(s.objects[5].task_importance, 0.75f);  // tilt_y
  EXPECT_FLOAT_EQ(s.objects[0].task_importance, 0.25f);  // checker
  EXPECT_FALSE(s.objects[0].lod_chain.has_value());
  ASSERT_TRUE(s.objects[1].lod_chain.has_value());
  EXPECT_EQ(s.objects[1].lod_chain->levels, 3);
  EXPECT_FALSE(s.objects[1].lod_chain->implicit);
  EXPECT_EQ(s.textures.size(), 4u);
  ASSERT_GE(report.phases.size(), 2u);  // parse, then the asset's textures
  EXPECT_EQ(report.phases[0].name, "parse");
  EXPECT_EQ(report.phases[1].name, "textures");
  const GBuffer g = render(s);
  EXPECT_EQ(g.object_id[g.index(48, 32)], 7u);  // the ball in front of the middle
}

TEST(GltfRender, JsonSceneIncludeErrorsNameTheirPath) {
  TempDir dir;
  const GltfTexturedQuads quads;
  write_gltf(dir.path, "quads", quads.doc(), quads.bin());
  const auto error = [&](const std::string& gltf) {
    return load_error(write_json(dir.path, "bad.json", R"({"gltf": )" + gltf + "}"), {});
  };
  EXPECT_NE(error(R"({"file": "quads.gltf", "objects": [{"match": "lamp*", "task_importance": 1}]})")
                .find("$.gltf.objects[0].match = \"lamp*\": matches no object of quads.gltf (objects: checker, mask, set1, "
                      "flat, tilt_x, tilt_y)"),
            std::string::npos);
  EXPECT_NE(error(R"({"file": "missing.glb"})").find("$.gltf.file = \"missing.glb\""), std::string::npos);
  EXPECT_NE(error(R"({"file": "quads.bin"})").find("must name a .gltf or .glb file"), std::string::npos);
  EXPECT_NE(error(R"({"file": "quads.gltf", "objects": [{"match": "mask", "task_importance": 2}]})")
                .find("$.gltf.objects[0].task_importance = 2: must be a finite number in [0, 1]"),
            std::string::npos);
  EXPECT_NE(error(R"({"file": "quads.gltf", "camera": "top"})").find("no perspective camera node named \"top\""),
            std::string::npos);
  EXPECT_NE(error(R"({"file": "quads.gltf", "scale": 2})").find("$.gltf.scale"), std::string::npos);
}

TEST(GltfRender, GlobMatch) {
  EXPECT_TRUE(glob_match("arch*", "arch_12"));
  EXPECT_TRUE(glob_match("*", ""));
  EXPECT_TRUE(glob_match("col?mn/p*", "column/p0"));
  EXPECT_FALSE(glob_match("col?mn", "colmn"));
  EXPECT_FALSE(glob_match("a*b", "acbd"));
  EXPECT_TRUE(glob_match("*a*b*", "xxaxxbxx"));
  // A hostile pattern stays linear-time.
  EXPECT_FALSE(glob_match("*a*a*a*a*a*a*a*a*b", std::string(5000, 'a')));
}

// GI on textured PBR: intersect() evaluates the material at the hit, and photons leaving a textured
// surface carry its texel's diffuse colour (the checker's red texel reflects red only).
TEST(GltfRender, PhotonsCarryTheTexturedAlbedo) {
  TempDir dir;
  const GltfTexturedQuads quads;
  write_gltf(dir.path, "quads", quads.doc(), quads.bin());
  // A white wall in front of the quads, a light between them, in front of the checker.
  const auto file = write_json(dir.path, "gi.json", R"({
    "gltf": {"file": "quads.gltf"},
    "materials": {"white": {"type": "lambertian", "kd": [0.8, 0.8, 0.8]}},
    "objects": [{"name": "wall", "material": "white", "geometry": {"box": [10, 10, 0.02]},
                 "transform": {"translation": [0, 0, 1]}}],
    "lights": [{"type": "point", "position": [-1.45, 0.85, 0.3], "power": [100, 100, 100]}]
  })");
  const Scene s = load_scene(file);
  EmbreeBackend backend;
  backend.set_scene(s);
  // The checker's top-left texel is red; its bottom-right grey.
  SurfaceHit hit;
  const glm::vec3 eye(0, 0, 0.9f);
  ASSERT_TRUE(backend.intersect(eye, GltfTexturedQuads::centre(0) + glm::vec3(-0.25f, 0.25f, 0) - eye, 0, 10,
                                RayVisibility::All, hit));
  ASSERT_TRUE(hit.pbr.has_value());
  EXPECT_NEAR(hit.pbr->base_color.r, 1.0f, 1e-3f);
  EXPECT_NEAR(hit.pbr->base_color.g, 0.0f, 1e-3f);
  EXPECT_EQ(hit.diffuse_albedo(), hit.pbr->base_color);  // metallic 0
  ASSERT_TRUE(backend.intersect(eye, GltfTexturedQuads::centre(0) + glm::vec3(0.25f, -0.25f, 0) - eye, 0, 10,
                                RayVisibility::All, hit));
  EXPECT_NEAR(hit.pbr->base_color.g, 0.2158605f, 1e-3f);  // sRGB 128
  gi::TraceSettings ts;
  ts.stored_photons = 40000;
  const gi::PhotonTraceResult res = gi::trace_photons(backend, ts);
  std::size_t checked = 0, red = 0;
  for (const gi::Photon& p : res.photons) {
    if (p.parent == gi::kNoParent || p.position.z < 0.9f) continue;  // on the wall, after a bounce
    const glm::vec3 from = res.photons[p.parent].position - GltfTexturedQuads::centre(0);
    if (std::abs(from.z) > 1e-3f || !(from.x < -0.02f && from.x > -0.48f && from.y > 0.02f && from.y < 0.48f)) continue;
    ++checked;
    // Diffuse reflection: red only. The specular lobe (F0 = 0.04 of a dielectric) reflects white.
    if (std::max(p.power.g, p.power.b) < 1e-3f * p.power.r) {
      ++red;
    } else {
      EXPECT_NEAR(p.power.g, p.power.r, 1e-3f * p.power.r) << "neither diffuse red nor specular white";
    }
  }
  EXPECT_GT(checked, 20u);
  EXPECT_GT(red, checked * 8 / 10) << red << " of " << checked << " photons off the red texel are red";
}
