// SPDX-License-Identifier: Apache-2.0
// libFuzzer entry point for scene JSON (issue 23): whatever the text, parse_scene must either
// return a scene or throw SceneError naming what is wrong, never crash, overflow the stack or
// allocate without bound. Mesh paths resolve against an empty directory, so no file is read.
#include <cstdint>
#include <cstdlib>
#include <string>

#include "scene/scene_error.h"
#include "scene/scene_loader.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    (void)fovea::render::parse_scene(text, "fuzz.json", "/nonexistent/fovea-fuzz");
  } catch (const fovea::render::SceneError&) {
    // the expected outcome for nearly every input
  }
  return 0;
}
