// SPDX-License-Identifier: Apache-2.0
// Level-of-detail chains (renderer/lod/lod_chain.h): Lee 2009 eq. 7.4's ratios, seams kept,
// files and manifest round trip, the cache.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <cstdlib>
#include <cstring>
#include <iterator>
#include <fstream>

#include "lod/lod_chain.h"
#include "lod/mesh_cache_file.h"
#include "scene/geometry.h"
#include "scene/gltf/gltf_scene.h"
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
  for (const auto& e : fs::directory_iterator(root)) fs::remove(e.path() / "level2.fmesh");
  const Chain rebuilt = cached_chain(sphere, ChainSettings{}, "s", root, &hit);
  EXPECT_FALSE(hit);
  EXPECT_EQ(rebuilt.levels[2].mesh.triangle_count(), first.levels[2].mesh.triangle_count());
  fs::remove_all(root);
}

// A textured grid: UVs split along x = 0 (a seam: same positions, u 0.5 on the left and 0.6 on the
// right), colours and tangents.
Mesh textured_grid(int n) {
  Mesh m;
  for (int half = 0; half < 2; ++half) {
    const auto base = static_cast<std::uint32_t>(m.positions.size());
    for (int j = 0; j <= n; ++j) {
      for (int i = 0; i <= n; ++i) {
        const float x = static_cast<float>(half * n + i) / static_cast<float>(n) - 1.0f, y = static_cast<float>(j) / static_cast<float>(n);
        m.positions.push_back({x, y, 0.02f * std::sin(9.0f * x) * std::cos(7.0f * y)});
        m.normals.push_back({0, 0, 1});
        m.texcoords0.push_back({static_cast<float>(half) * 0.6f + 0.5f * static_cast<float>(i) / static_cast<float>(n), y});
        m.texcoords1.push_back({x, y});
        m.colors.push_back({1, y, 0, 1});
        m.tangents.push_back({1, 0, 0, 1});
      }
    }
    const auto row = static_cast<std::uint32_t>(n + 1);
    for (std::uint32_t j = 0; j < static_cast<std::uint32_t>(n); ++j) {
      for (std::uint32_t i = 0; i < static_cast<std::uint32_t>(n); ++i) {
        const std::uint32_t a = base + j * row + i;
        m.indices.insert(m.indices.end(), {a, a + 1, a + row + 1, a, a + row + 1, a + row});
      }
    }
  }
  return m;
}

// Every attribute goes into every level and through the cache; the UV seam stays a seam.
TEST(LodChain, AttributesAndUvSeamsSurviveLevelsAndTheCache) {
  const Mesh grid = textured_grid(32);
  const fs::path root = temp_dir("attributes");
  bool hit = true;
  const Chain built = cached_chain(grid, ChainSettings{}, "grid", root, &hit);
  EXPECT_FALSE(hit);
  const Chain cached = cached_chain(grid, ChainSettings{}, "grid", root, &hit);
  EXPECT_TRUE(hit);
  for (const Chain* c : {&built, &cached}) {
    ASSERT_EQ(c->levels.size(), 5u);
    for (std::size_t l = 0; l < c->levels.size(); ++l) {
      const Mesh& m = c->levels[l].mesh;
      ASSERT_GT(m.triangle_count(), 0u);
      ASSERT_EQ(m.texcoords0.size(), m.positions.size()) << l;
      ASSERT_EQ(m.texcoords1.size(), m.positions.size()) << l;
      ASSERT_EQ(m.colors.size(), m.positions.size()) << l;
      ASSERT_EQ(m.tangents.size(), m.positions.size()) << l;
      for (std::size_t i = 0; i < m.positions.size(); ++i) {
        // Each vertex keeps its own attributes: UV1 is its position, colour.g its y.
        EXPECT_NEAR(m.texcoords1[i].x, m.positions[i].x, 1e-6f);
        EXPECT_NEAR(m.colors[i].g, m.positions[i].y, 1e-6f);
        // The seam: the two sides never share a vertex (left u <= 0.5, right u >= 0.6).
        if (m.positions[i].x < -1e-6f) {
          EXPECT_LE(m.texcoords0[i].x, 0.5f + 1e-6f);
        }
        if (m.positions[i].x > 1e-6f) {
          EXPECT_GE(m.texcoords0[i].x, 0.6f - 1e-6f);
        }
      }
      for (std::size_t t = 0; t < m.indices.size(); t += 3) {
        bool left = false, right = false;
        for (std::size_t k = 0; k < 3; ++k) {
          const float x = m.positions[m.indices[t + k]].x;
          left = left || x < -1e-6f;
          right = right || x > 1e-6f;
        }
        EXPECT_FALSE(left && right) << "a triangle across the UV seam at level " << l << ": "
                                    << m.positions[m.indices[t]].x << "," << m.texcoords0[m.indices[t]].x << " "
                                    << m.positions[m.indices[t + 1]].x << "," << m.texcoords0[m.indices[t + 1]].x << " "
                                    << m.positions[m.indices[t + 2]].x << "," << m.texcoords0[m.indices[t + 2]].x;
      }
    }
    EXPECT_EQ(c->levels[2].mesh.triangle_count(), built.levels[2].mesh.triangle_count());
  }
  EXPECT_LT(built.levels[2].mesh.triangle_count(), grid.triangle_count() / 8);
  fs::remove_all(root);
}

TEST(LodChain, ADamagedCacheFileIsRefusedByName) {
  const fs::path dir = temp_dir("fmesh");
  fs::create_directories(dir);
  const fs::path file = dir / "level0.fmesh";
  write_mesh_cache_file(textured_grid(2), file);
  EXPECT_EQ(read_mesh_cache_file(file).triangle_count(), 16u);
  std::string bytes;
  {
    std::ifstream f(file, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
  }
  const auto expect_refused = [&](const std::string& content, const std::string& why) {
    std::ofstream(file, std::ios::binary).write(content.data(), static_cast<std::streamsize>(content.size()));
    try {
      (void)read_mesh_cache_file(file);
      ADD_FAILURE() << "accepted: " << why;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(file.string()), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
    }
  };
  expect_refused(bytes.substr(0, bytes.size() - 4), "size does not match");
  std::string huge = bytes;
  const std::uint64_t count = std::uint64_t{1} << 60;
  std::memcpy(huge.data() + 8, &count, 8);  // 2^60 positions
  expect_refused(huge, "truncated");
  std::string past = bytes;
  const std::uint32_t big = 1000;
  std::memcpy(past.data() + past.size() - 4, &big, 4);  // the last index
  expect_refused(past, "index 1000 past the vertices");
  expect_refused("FOVMESH0", "not a fovea mesh cache file");
  fs::remove_all(dir);
}

// Every glTF object gets a default chain; instances share their mesh's levels; a mesh too small to
// reduce keeps none (no error).
TEST(LodChain, GltfObjectsGetChainsSharedByInstances) {
  const fs::path root = temp_dir("gltf_cache");
  ::setenv("FOVEA_LOD_CACHE", root.c_str(), 1);
  const Mesh grid = textured_grid(24);
  gltf::Asset a;
  a.source = "grid.gltf";
  gltf::Primitive p;
  p.positions = grid.positions;
  p.normals = grid.normals;
  p.texcoords0 = grid.texcoords0;
  p.indices = grid.indices;
  gltf::Primitive tiny;
  tiny.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  tiny.indices = {0, 1, 2};
  a.meshes = {{"grid", {p}}, {"tiny", {tiny}}};
  for (int k = 0; k < 2; ++k) {
    gltf::Node n;
    n.name = "grid" + std::to_string(k);
    n.mesh = 0;
    n.local[3] = glm::vec4(static_cast<float>(3 * k), 0, 0, 1);
    a.nodes.push_back(n);
  }
  gltf::Node t;
  t.name = "tiny";
  t.mesh = 1;
  a.nodes.push_back(t);
  Scene s = scene_from_gltf(a, {});
  ASSERT_EQ(s.objects.size(), 3u);
  for (const Object& o : s.objects) EXPECT_TRUE(o.lod_chain && o.lod_chain->implicit);
  attach_chains(s);
  ASSERT_EQ(s.objects[0].lods.size(), 4u);
  ASSERT_EQ(s.objects[1].lods.size(), 4u);
  for (std::size_t l = 0; l < 4; ++l) {
    EXPECT_EQ(s.objects[0].lods[l].mesh.get(), s.objects[1].lods[l].mesh.get());  // shared, not copied
    EXPECT_EQ(s.objects[0].lods[l].mesh->texcoords0.size(), s.objects[0].lods[l].mesh->positions.size());
  }
  EXPECT_TRUE(s.objects[2].lods.empty());
  EXPECT_FALSE(s.objects[2].lod_chain.has_value());
  ::unsetenv("FOVEA_LOD_CACHE");
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
