// SPDX-License-Identifier: Apache-2.0
// A glTF asset through load_scene and the OpenGL backend (headless, EGL): the same check as the
// Embree one in test_gltf_render.cpp.
#include <gtest/gtest.h>

#include "backend/backend.h"
#include "gltf_render_check.h"
#include "gltf_test_assets.h"
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
