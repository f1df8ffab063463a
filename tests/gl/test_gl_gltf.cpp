// SPDX-License-Identifier: Apache-2.0
// A glTF asset through load_scene and the OpenGL backend (headless, EGL): the same check as the
// Embree one in test_gltf_render.cpp.
#include <gtest/gtest.h>

#include <cmath>

#include "backend/backend.h"
#include "gltf_render_check.h"
#include "gltf_test_assets.h"
#include "gltf_textured_quads.h"
#include "scene/scene_loader.h"

using namespace fovea::render;
using namespace fovea::test;

TEST(GlGltf, TwoQuadsAreTwoObjectsInTheirOwnColours) {
  TempDir dir;
  const GltfTwoQuads quads;
  write_file(dir.path / "quads.glb", glb_bytes(quads.doc(), quads.bin()));
  const Scene s = load_scene(dir.path / "quads.glb", {{"camera.width", "64"}, {"camera.height", "48"}});
  const auto backend = make_backend(BackendKind::OpenGL);
  backend->set_scene(s);
  GBuffer g;
  backend->render(FrameTime{}, BackendSettings{}, g);
  expect_two_quads(g);
}

namespace {

GBuffer render(BackendKind kind, const Scene& s, BackendSettings settings = {}) {
  const auto backend = make_backend(kind);
  backend->set_scene(s);
  GBuffer g;
  backend->render(FrameTime{}, settings, g);
  return g;
}

Scene textured_quads(const TempDir& dir) {
  const GltfTexturedQuads quads;
  return load_scene(write_gltf(dir.path, "quads", quads.doc(), quads.bin()), {{"camera.width", "192"}, {"camera.height", "128"}});
}

}  // namespace

// glTF 2.0 points on the OpenGL backend: the Embree test's checks (gltf_textured_quads.h).
TEST(GlGltf, TexturedQuadsShowTheSpecificationsPoints) {
  TempDir dir;
  const Scene s = textured_quads(dir);
  expect_textured_quads(s.camera, render(BackendKind::OpenGL, s), render(BackendKind::OpenGL, without_normal_maps(s)));
  // A depth pre-pass leaves the alpha-tested quad to the shading pass: its masked half stays empty.
  BackendSettings prepass;
  prepass.depth_prepass = true;
  const GBuffer g = render(BackendKind::OpenGL, s, prepass);
  EXPECT_EQ(g.object_id[pixel_of(s.camera, g, GltfTexturedQuads::centre(1) + glm::vec3(-0.25f, 0, 0))], 0u);
  EXPECT_EQ(g.object_id[pixel_of(s.camera, g, GltfTexturedQuads::centre(1) + glm::vec3(0.25f, 0, 0))], 2u);
}

// Generated tangents follow MikkTSpace at a mirrored UV seam: the Embree test's checks.
TEST(GlGltf, AMirroredSeamUnderANormalMapTiltsEachHalfItsOwnWay) {
  TempDir dir;
  const GltfMirroredSeam strip;
  const Scene s = load_scene(write_gltf(dir.path, "seam", strip.doc(), strip.bin()),
                             {{"camera.width", "128"}, {"camera.height", "64"}});
  expect_mirrored_seam(s.camera, render(BackendKind::OpenGL, s), render(BackendKind::OpenGL, without_normal_maps(s)));
}

// Single-sided materials are back-face culled, with the winding a mirroring node turns round.
TEST(GlGltf, SingleSidedBackFacesAreCulled) {
  TempDir dir;
  const GltfSidedQuads quads;
  const Scene s = load_scene(write_gltf(dir.path, "sided", quads.doc(), quads.bin()),
                             {{"camera.width", "192"}, {"camera.height", "128"}});
  expect_sided_quads(s.camera, render(BackendKind::OpenGL, s));
  BackendSettings prepass;
  prepass.depth_prepass = true;
  expect_sided_quads(s.camera, render(BackendKind::OpenGL, s, prepass));
}

// The two backends shade the same textures with the same BRDF: the images agree wherever both see
// the same object (texture filtering differs by design: derivatives against ray cones, and the
// GPU's filtering precision).
TEST(GlGltf, TexturedQuadsAgreeWithEmbree) {
  TempDir dir;
  const Scene s = textured_quads(dir);
  const GBuffer gl = render(BackendKind::OpenGL, s), rt = render(BackendKind::Embree, s);
  ASSERT_EQ(gl.size(), rt.size());
  double se = 0, peak = 0;
  std::size_t same = 0;
  for (std::size_t i = 0; i < gl.size(); ++i) {
    if (gl.object_id[i] != rt.object_id[i]) continue;  // silhouettes and the mask's edge may differ by a pixel
    ++same;
    for (int c = 0; c < 3; ++c) {
      const double d = gl.color[i][c] - rt.color[i][c];
      se += d * d;
      peak = std::max(peak, static_cast<double>(rt.color[i][c]));
    }
  }
  ASSERT_GT(same, gl.size() * 95 / 100);
  const double psnr = 10 * std::log10(peak * peak / (se / static_cast<double>(3 * same)));
  EXPECT_GT(psnr, 35.0) << "PSNR " << psnr << " dB over " << same << " pixels";
}
