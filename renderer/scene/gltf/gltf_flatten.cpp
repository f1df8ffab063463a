// SPDX-License-Identifier: Apache-2.0
#include "scene/gltf/gltf_flatten.h"

#include <map>
#include <set>
#include <utility>

namespace fovea::render::gltf {

namespace {

// The node's name made unique among the instances so far: "name", then "name#2", "name#3", ...
class UniqueNames {
 public:
  std::string take(const std::string& base) {
    if (used_.insert(base).second) return base;
    int& next = next_[base];
    if (next < 2) next = 2;
    for (;; ++next) {
      std::string candidate = base + "#" + std::to_string(next);
      if (used_.insert(candidate).second) return candidate;
    }
  }

 private:
  std::set<std::string> used_;
  std::map<std::string, int> next_;
};

std::vector<std::uint32_t> roots(const Asset& asset, std::optional<std::uint32_t> scene) {
  if (!scene) scene = asset.scene;
  if (!scene && !asset.scenes.empty()) scene = 0;
  if (scene) return *scene < asset.scenes.size() ? asset.scenes[*scene].nodes : std::vector<std::uint32_t>{};
  std::vector<bool> is_child(asset.nodes.size(), false);
  for (const Node& n : asset.nodes) {
    for (const std::uint32_t c : n.children) {
      if (c < is_child.size()) is_child[c] = true;
    }
  }
  std::vector<std::uint32_t> out;
  for (std::uint32_t i = 0; i < asset.nodes.size(); ++i) {
    if (!is_child[i]) out.push_back(i);
  }
  return out;
}

// Depth first from the scene's roots, children in the file's order: visit(node index, world).
template <class Visit>
void walk(const Asset& asset, std::optional<std::uint32_t> scene, Visit visit) {
  std::vector<bool> visited(asset.nodes.size(), false);  // read_gltf refuses cycles; a hand-made asset may not
  std::vector<std::pair<std::uint32_t, glm::mat4>> stack;  // node, parent's world; no recursion for deep graphs
  const std::vector<std::uint32_t> top = roots(asset, scene);
  for (auto it = top.rbegin(); it != top.rend(); ++it) stack.emplace_back(*it, glm::mat4(1.0f));
  while (!stack.empty()) {
    const auto [index, parent_world] = stack.back();
    stack.pop_back();
    if (index >= asset.nodes.size() || visited[index]) continue;
    visited[index] = true;
    const Node& node = asset.nodes[index];
    const glm::mat4 world = parent_world * node.local;
    visit(index, world);
    for (auto c = node.children.rbegin(); c != node.children.rend(); ++c) stack.emplace_back(*c, world);
  }
}

}  // namespace

std::vector<MeshInstance> flatten(const Asset& asset, std::optional<std::uint32_t> scene) {
  std::vector<MeshInstance> out;
  UniqueNames names;
  walk(asset, scene, [&](std::uint32_t index, const glm::mat4& world) {
    const Node& node = asset.nodes[index];
    if (node.mesh) {
      out.push_back({index, names.take(node.name.empty() ? "node" + std::to_string(index) : node.name), world, *node.mesh});
    }
  });
  return out;
}

std::vector<std::optional<glm::mat4>> node_worlds(const Asset& asset, std::optional<std::uint32_t> scene) {
  std::vector<std::optional<glm::mat4>> out(asset.nodes.size());
  walk(asset, scene, [&](std::uint32_t index, const glm::mat4& world) { out[index] = world; });
  return out;
}

}  // namespace fovea::render::gltf
