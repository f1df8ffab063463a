// SPDX-License-Identifier: Apache-2.0
// Level-of-detail chains (renderer/lod/lod_chain.h): Lee 2009 eq. 7.4's ratios, seams kept,
// files and manifest round trip, the cache.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <cstdlib>
#include <fstream>

#include "lod/lod_chain.h"
#include "scene/geometry.h"
#include "scene/scene_loader.h"

namespace fovea::render::lod {
namespace {

namespace fs = std::filesystem;

fs::path temp_dir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("fovea_lod_test_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  return d;
}

TEST(LodChain, LevelsFollowEq74AndRecordTheirError) {
  const Mesh sphere = make_sphere(1.0f, 64, 128);  // 16k triangles: every level reachable
  ChainSettings s;
  const Chain c = build_chain(sphere, s, "sphere");
  ASSERT_EQ(c.levels.size(), 5u);
  const double tris = static_cast<double>(sphere.triangle_count());
  EXPECT_EQ(c.levels[0].mesh.triangle_count(), sphere.triangle_count());
  float previous_error = -1;
  for (std::size_t l = 1; l < c.levels.size(); ++l) {
    const ChainLevel& v = c.levels[l];
    EXPECT_DOUBLE_EQ(v.target_ratio, std::pow(4.0, -static_cast<double>(l)));  // Lee 2009, eq. 7.4
    EXPECT_TRUE(v.reached) << l;
    EXPECT_NEAR(v.achieved_ratio, v.target_ratio, 0.2 * v.target_ratio) << l;
    EXPECT_NEAR(static_cast<double>(v.mesh.triangle_count()) / tris, v.achieved_ratio, 1e-12);
    EXPECT_GT(v.error_m, previous_error);  // coarser levels deviate more
    EXPECT_LT(v.error_m, 1.0f);            // a unit sphere: errors well inside its size
    previous_error = v.error_m;
    EXPECT_EQ(v.mesh.normals.size(), v.mesh.positions.size());
  }
  // Another base: r(L) = 2^-L.
  s.base = 2;
  s.levels = 3;
  const Chain c2 = build_chain(sphere, s);
  EXPECT_NEAR(c2.levels[2].achieved_ratio, 0.25, 0.05);
}

// A cylinder's caps meet its side at hard edges (split normals). Seams mode keeps the crease at
// every level: wherever a rim vertex with a cap normal remains, a side vertex with a horizontal
// normal sits at the same position. Weld mode joins the two and (meshoptimizer 0.18) then cannot
// simplify the cylinder at all: its levels say so.
TEST(LodChain, SeamsModeKeepsHardEdges) {
  const Mesh cyl = make_cylinder(1.0f, 2.0f, 256);
  ChainSettings seams;
  seams.levels = 3;
  ChainSettings weld = seams;
  weld.attributes = Attributes::Weld;
  const Chain a = build_chain(cyl, seams), b = build_chain(cyl, weld);
  ASSERT_TRUE(a.levels[1].reached);
  const Mesh& m = a.levels[1].mesh;
  std::size_t rim_cap = 0;
  for (std::size_t i = 0; i < m.positions.size(); ++i) {
    const glm::vec3 p = m.positions[i];
    const bool on_rim = std::abs(std::abs(p.y) - 1.0f) < 1e-5f && std::abs(std::hypot(p.x, p.z) - 1.0f) < 1e-4f;
    if (!on_rim || std::abs(m.normals[i].y) < 0.99f) continue;
    ++rim_cap;
    bool side_partner = false;
    for (std::size_t j = 0; j < m.positions.size(); ++j)
      side_partner = side_partner || (m.positions[j] == p && std::abs(m.normals[j].y) < 0.01f);
    EXPECT_TRUE(side_partner) << "rim vertex " << i << " lost its side twin: the crease was smeared";
  }
  EXPECT_GT(rim_cap, 8u);
  EXPECT_FALSE(b.levels[1].reached);
  EXPECT_GT(b.levels[1].achieved_ratio, 0.9);
}

TEST(LodChain, FilesAndManifestRoundTrip) {
  const Mesh sphere = make_sphere(0.5f, 32, 64);
  const Chain c = build_chain(sphere, ChainSettings{}, "sphere.obj");
  for (const std::string format : {"obj", "ply"}) {
    const fs::path dir = temp_dir("roundtrip_" + format);
    write_chain(c, dir, format);
    EXPECT_TRUE(fs::exists(dir / "manifest.json"));
    EXPECT_TRUE(fs::exists(dir / ("level0." + format)));
    const Chain back = read_chain(dir);
    ASSERT_EQ(back.levels.size(), c.levels.size());
    EXPECT_EQ(back.input_name, "sphere.obj");
    for (std::size_t l = 0; l < c.levels.size(); ++l) {
      EXPECT_EQ(back.levels[l].mesh.triangle_count(), c.levels[l].mesh.triangle_count()) << format << " " << l;
      EXPECT_FLOAT_EQ(back.levels[l].error_m, c.levels[l].error_m);
      EXPECT_EQ(back.levels[l].reached, c.levels[l].reached);
    }
    fs::remove_all(dir);
  }
}

TEST(LodChain, CacheBuildsOnceAndRebuildsADamagedEntry) {
  const fs::path root = temp_dir("cache");
  const Mesh sphere = make_sphere(0.5f, 32, 64);
  bool hit = true;
  const Chain first = cached_chain(sphere, ChainSettings{}, "s", root, &hit);
  EXPECT_FALSE(hit);
  const Chain second = cached_chain(sphere, ChainSettings{}, "s", root, &hit);
  EXPECT_TRUE(hit);
  ASSERT_EQ(second.levels.size(), first.levels.size());
  for (std::size_t l = 0; l < first.levels.size(); ++l)
    EXPECT_EQ(second.levels[l].mesh.triangle_count(), first.levels[l].mesh.triangle_count());
  // Other settings: another entry.
  ChainSettings three;
  three.levels = 3;
  cached_chain(sphere, three, "s", root, &hit);
  EXPECT_FALSE(hit);
  // A deleted level file: the entry is rebuilt, not trusted.
  for (const auto& e : fs::directory_iterator(root)) fs::remove(e.path() / "level2.ply");
  const Chain rebuilt = cached_chain(sphere, ChainSettings{}, "s", root, &hit);
  EXPECT_FALSE(hit);
  EXPECT_EQ(rebuilt.levels[2].mesh.triangle_count(), first.levels[2].mesh.triangle_count());
  fs::remove_all(root);
}

// A scene asks for a chain; the loader builds it through the same code and cache as fovea-lod.
TEST(LodChain, ScenesBuildChainsThroughTheCache) {
  const fs::path root = temp_dir("scene_cache");
  ::setenv("FOVEA_LOD_CACHE", root.c_str(), 1);
  const std::string json = R"({"name": "lod", "camera": {"position": [0, 0, 5], "target": [0, 0, 0]},
    "materials": {"m": {"type": "lambertian", "kd": [0.5, 0.5, 0.5]}},
    "objects": [{"name": "ball", "material": "m", "geometry": {"sphere": {"radius": 1, "rings": 48, "segments": 96}},
                 "lod": {"chain": {"levels": 4, "base": 4}}}],
    "lights": [{"type": "point", "position": [0, 3, 3], "power": [100, 100, 100]}]})";
  Scene a = parse_scene(json, "lod.json", fs::temp_directory_path());
  ASSERT_TRUE(a.objects[0].lod_chain.has_value());  // the loader keeps the request; lod/ builds it
  EXPECT_TRUE(a.objects[0].lods.empty());
  attach_chains(a);
  EXPECT_FALSE(a.objects[0].lod_chain.has_value());
  ASSERT_EQ(a.objects[0].lods.size(), 3u);
  std::size_t previous = a.objects[0].mesh->triangle_count();
  float previous_error = 0;
  for (const LodLevel& l : a.objects[0].lods) {
    EXPECT_LT(l.mesh->triangle_count(), previous);
    EXPECT_GE(l.max_error_m, previous_error);
    previous = l.mesh->triangle_count();
    previous_error = l.max_error_m;
  }
  EXPECT_FALSE(fs::is_empty(root));  // the chain went to the cache
  Scene b = parse_scene(json, "lod.json", fs::temp_directory_path());
  attach_chains(b);
  ASSERT_EQ(b.objects[0].lods.size(), 3u);
  EXPECT_EQ(b.objects[0].lods[2].mesh->triangle_count(), a.objects[0].lods[2].mesh->triangle_count());
  // Both forms at once, or bad chain settings: errors that name the field.
  std::string both = json;
  both.replace(both.find("\"chain\""), 7, "\"simplify\": [0.5], \"chain\"");
  EXPECT_THROW(parse_scene(both, "lod.json", fs::temp_directory_path()), SceneError);
  std::string bad = json;
  bad.replace(bad.find("\"base\": 4"), 9, "\"base\": 1");
  try {
    parse_scene(bad, "lod.json", fs::temp_directory_path());
    FAIL() << "base 1 accepted";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("base"), std::string::npos) << e.what();
  }
  ::unsetenv("FOVEA_LOD_CACHE");
  fs::remove_all(root);
}

}  // namespace
}  // namespace fovea::render::lod
