// SPDX-License-Identifier: Apache-2.0
#include "scene/scene_gltf_include.h"

#include <cstdio>
#include <vector>

#include "scene/gltf/gltf_reader.h"
#include "scene/gltf/gltf_scene.h"
#include "scene/scene_schema.h"

namespace fovea::render {

using json::Node;

bool glob_match(std::string_view pattern, std::string_view name) {
  // Iterative with one backtrack point per '*': linear for the patterns people write, never
  // exponential for hostile ones.
  std::size_t p = 0, s = 0, star = std::string_view::npos, resume = 0;
  while (s < name.size()) {
    if (p < pattern.size() && (pattern[p] == '?' || pattern[p] == name[s])) {
      ++p;
      ++s;
    } else if (p < pattern.size() && pattern[p] == '*') {
      star = p++;
      resume = s;
    } else if (star != std::string_view::npos) {
      p = star + 1;
      s = ++resume;
    } else {
      return false;
    }
  }
  while (p < pattern.size() && pattern[p] == '*') ++p;
  return p == pattern.size();
}

namespace {

// Some of the scene's object names, for a message: "a, b, c, ... (40 objects)".
std::string some_names(const Scene& s) {
  std::string out;
  for (std::size_t i = 0; i < s.objects.size() && i < 8; ++i) out += (i == 0 ? "" : ", ") + s.objects[i].name;
  if (s.objects.size() > 8) out += ", ... (" + std::to_string(s.objects.size()) + " objects)";
  return out;
}

// $.gltf.objects[i].lod: {"chain": {"levels", "base", "attributes"}} replaces the default chain,
// "none" removes it.
void read_lod(const json::Reader& r, const Node& n, std::optional<LodChainRequest>& chain) {
  if (n.v.is_string()) {
    if (r.string(n, "\"none\" or {\"chain\": {...}}") != "none") r.fail(n, "must be \"none\" or {\"chain\": {...}}");
    chain.reset();
    return;
  }
  r.check_keys(n, {"chain", "comment"}, "\"none\" or {\"chain\": {\"levels\", \"base\", \"attributes\"}}");
  const Node c = r.require(n, "chain", "the chain's settings: {\"levels\", \"base\", \"attributes\"}");
  r.check_keys(c, schema::kLodChainKeys, "a level-of-detail chain");
  LodChainRequest req;
  if (auto v = r.get(c, "levels")) req.levels = static_cast<int>(r.integer(*v, 1, 16));
  if (auto v = r.get(c, "base")) req.base = r.number(*v, json::Range{1, 1e6, true, false, ""});
  if (auto v = r.get(c, "attributes")) {
    const std::string a = r.string(*v, "\"seams\" or \"weld\"");
    if (a != "seams" && a != "weld") r.fail(*v, "must be \"seams\" or \"weld\"");
    req.weld_attributes = a == "weld";
  }
  req.where = r.source() + ": " + c.path;
  chain = req;
}

}  // namespace

Scene read_gltf_include(const json::Reader& r, const Node& n, const std::filesystem::path& base_dir, LoadReport* report) {
  r.check_keys(n, {"file", "camera", "objects", "comment"}, "a glTF asset: {\"file\", \"camera\", \"objects\"}");
  const Node file = r.require(n, "file", "the .gltf or .glb file, relative to the scene file");
  std::filesystem::path path = r.string(file, "a .gltf or .glb file path relative to the scene file");
  if (path.is_relative()) path = base_dir / path;
  path = path.lexically_normal();
  if (!is_gltf_file(path)) r.fail(file, "must name a .gltf or .glb file");
  std::string camera;
  if (auto c = r.get(n, "camera")) camera = r.string(*c, "the name of a camera node in the asset");
  Scene scene;
  try {
    scene = load_gltf_scene(path, {}, camera, report);
  } catch (const SceneError& e) {
    r.fail(file, e.what());
  }
  if (auto objects = r.get(n, "objects")) {
    if (!objects->v.is_array()) r.fail(*objects, "must be an array of {\"match\", \"task_importance\", \"lod\"}");
    for (std::size_t i = 0; i < objects->v.size(); ++i) {
      const Node o = r.element(*objects, i);
      r.check_keys(o, {"match", "task_importance", "lod", "comment"}, "an override: {\"match\", \"task_importance\", \"lod\"}");
      const Node match = r.require(o, "match", "a glob pattern of object names (\"arch*\", \"column_?\")");
      const std::string pattern = r.string(match, "a glob pattern of object names");
      std::size_t matched = 0;
      for (Object& obj : scene.objects) {
        if (!glob_match(pattern, obj.name)) continue;
        ++matched;
        // Later overrides win where they set the same field.
        if (auto ti = r.get(o, "task_importance")) obj.task_importance = r.number_f(*ti, json::Range{0, 1, false, false, ""});
        if (auto l = r.get(o, "lod")) read_lod(r, *l, obj.lod_chain);
      }
      if (matched == 0) r.fail(match, "matches no object of " + path.filename().string() + " (objects: " + some_names(scene) + ")");
    }
  }
  return scene;
}

}  // namespace fovea::render
