// SPDX-License-Identifier: Apache-2.0
#pragma once
// A bundled scene's G-buffer through the raster backend as a DOF input, for the GL DOF tests: the
// visible image, optionally its first peeled layer (Lee's hidden image), and a lens whose CoC is
// `k_px` at the far plane.
#include <filesystem>

#include "backend/gl/gl_backend.h"
#include "dof/dof_image.h"
#include "dof_lens.h"
#include "scene/scene_loader.h"

namespace fovea::render::test {

struct DofSceneImage {
  GBuffer g, hidden;  // hidden: empty unless asked for
  dof::CocModel lens;
  dof::DofInput input(bool with_hidden = false) const {
    dof::DofInput in;
    in.width = g.width;
    in.height = g.height;
    in.color = g.color.data();
    in.depth = g.depth.data();
    if (with_hidden && hidden.size() == g.size()) {
      in.hidden_color = hidden.color.data();
      in.hidden_depth = hidden.depth.data();
    }
    in.coc = lens;
    return in;
  }
};

inline DofSceneImage dof_scene_image(GlBackend& backend, const char* name, double focus_m, double k_px,
                                     std::uint32_t width, std::uint32_t height, bool with_hidden = false) {
  Scene s = load_scene(std::filesystem::path(FOVEA_SOURCE_DIR) / "renderer/scenes" / name);
  s.camera.width = width;
  s.camera.height = height;
  backend.set_scene(s);
  DofSceneImage out;
  backend.render({}, {}, out.g);
  if (with_hidden) {
    BackendSettings peel;
    peel.peel = 1;
    backend.render({}, peel, out.hidden);
  }
  backend.context().make_current();
  out.lens = dof::test::lens_with_k(k_px, focus_m);
  return out;
}

}  // namespace fovea::render::test
