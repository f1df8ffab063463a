// SPDX-License-Identifier: Apache-2.0
// Hard cases of LOD chains (renderer/lod/lod_chain.h): meshes with 0, 1 and 2 triangles,
// non-manifold and degenerate input, out-of-range indices, a ratio simplification cannot reach,
// bad settings, unreadable files.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <stdexcept>

#include "lod/lod_chain.h"
#include "scene/geometry.h"

namespace fovea::render::lod {
namespace {

namespace fs = std::filesystem;

void expect_finite(const Chain& c) {
  for (const ChainLevel& l : c.levels) {
    EXPECT_TRUE(std::isfinite(l.error_m) && l.error_m >= 0);
    EXPECT_TRUE(std::isfinite(l.achieved_ratio));
    for (const glm::vec3& p : l.mesh.positions) ASSERT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z));
    for (std::uint32_t i : l.mesh.indices) ASSERT_LT(i, l.mesh.positions.size());
  }
}

Mesh triangles(int n) {
  Mesh m;
  for (int t = 0; t < n; ++t) {
    const auto base = static_cast<std::uint32_t>(m.positions.size());
    const float x = static_cast<float>(t);
    m.positions.insert(m.positions.end(), {{x, 0, 0}, {x + 1, 0, 0}, {x, 1, 0}});
    m.normals.insert(m.normals.end(), 3, glm::vec3(0, 0, 1));
    m.indices.insert(m.indices.end(), {base, base + 1, base + 2});
  }
  return m;
}

TEST(LodChainStability, TinyMeshesReportWhatTheyCouldNotReach) {
  // 0 triangles: one level, nothing to simplify, not "reached".
  const Chain empty = build_chain(Mesh{}, ChainSettings{});
  ASSERT_EQ(empty.levels.size(), 1u);
  EXPECT_FALSE(empty.levels[0].reached);
  for (int n : {1, 2}) {
    const Chain c = build_chain(triangles(n), ChainSettings{});
    ASSERT_EQ(c.levels.size(), 5u) << n;
    expect_finite(c);
    for (std::size_t l = 1; l < c.levels.size(); ++l) {
      EXPECT_GE(c.levels[l].mesh.triangle_count(), 1u);
      EXPECT_LE(c.levels[l].mesh.triangle_count(), c.levels[l - 1].mesh.triangle_count());
    }
    EXPECT_FALSE(c.levels.back().reached && static_cast<double>(n) * c.levels.back().target_ratio >= 1.0);
  }
  // A box cannot lose triangles without changing shape: the levels say they did not reach the ratio.
  const Chain box = build_chain(make_box({1, 1, 1}), ChainSettings{});
  expect_finite(box);
  bool any_unreached = false;
  for (const ChainLevel& l : box.levels) any_unreached = any_unreached || !l.reached;
  EXPECT_TRUE(any_unreached);
}

TEST(LodChainStability, NonManifoldDegenerateAndBrokenIndices) {
  Mesh m = make_sphere(1.0f, 16, 32);
  // Non-manifold: a fin of three triangles sharing one edge; degenerate: zero-area triangles.
  const auto base = static_cast<std::uint32_t>(m.positions.size());
  m.positions.insert(m.positions.end(), {{0, 0, 0}, {0, 2, 0}, {1, 1, 0}, {-1, 1, 0}, {0, 1, 1}, {5, 5, 5}});
  m.normals.insert(m.normals.end(), 6, glm::vec3(0, 0, 1));
  m.indices.insert(m.indices.end(), {base, base + 1, base + 2, base, base + 1, base + 3, base, base + 1, base + 4,
                                     base + 5, base + 5, base + 5, base, base, base + 1});
  // Out-of-range indices: dropped.
  m.indices.insert(m.indices.end(), {0, 1, 99999});
  const Chain c = build_chain(m, ChainSettings{});
  expect_finite(c);
  EXPECT_EQ(c.levels[0].mesh.triangle_count(), m.triangle_count() - 1);
  EXPECT_LT(c.levels[1].mesh.triangle_count(), c.levels[0].mesh.triangle_count());
}

TEST(LodChainStability, BadSettingsAndFilesAreNamed) {
  ChainSettings s;
  s.levels = 0;
  try {
    build_chain(triangles(1), s);
    FAIL() << "levels 0 accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("levels"), std::string::npos);
  }
  s = ChainSettings{};
  for (double b : {1.0, 0.5, std::nan(""), std::numeric_limits<double>::infinity()}) {
    s.base = b;
    EXPECT_THROW(build_chain(triangles(1), s), std::invalid_argument) << b;
  }
  const fs::path dir = fs::temp_directory_path() / ("fovea_lod_bad_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  // No manifest, a manifest that is not JSON, one whose level file is missing: errors name the file.
  EXPECT_THROW(read_chain(dir), std::runtime_error);
  std::ofstream(dir / "manifest.json") << "{ not json";
  try {
    read_chain(dir);
    FAIL() << "bad manifest accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("manifest.json"), std::string::npos);
  }
  write_chain(build_chain(make_sphere(1.0f, 16, 32), ChainSettings{}), dir, "obj");
  fs::remove(dir / "level3.obj");
  try {
    read_chain(dir);
    FAIL() << "missing level file accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("level3.obj"), std::string::npos) << e.what();
  }
  EXPECT_THROW(write_chain(build_chain(triangles(1), ChainSettings{}), dir / "x", "stl"), std::runtime_error);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace fovea::render::lod
