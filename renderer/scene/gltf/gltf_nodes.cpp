// SPDX-License-Identifier: Apache-2.0
// The node graph and its scenes (glTF 2.0 §3.5): each node's local transform (a column-major matrix,
// or translation * rotation * scale with the quaternion normalised), its mesh, camera and light. The
// graph must be a forest: a node with two parents or a cycle is refused, naming the nodes, and a
// scene lists root nodes only, each once.
#include <algorithm>
#include <string>

#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include "scene/gltf/gltf_parse.h"

namespace fovea::render::gltf::detail {

namespace {

constexpr std::uint32_t kNone = 0xFFFFFFFFu;
const Range kAny{-1e30, 1e30, false, false, ""};

glm::mat4 local_transform(const Parser& p, const Node& n) {
  const auto matrix = Parser::get(n, "matrix");
  const auto t = Parser::get(n, "translation");
  const auto r = Parser::get(n, "rotation");
  const auto s = Parser::get(n, "scale");
  if (matrix) {
    if (t || r || s) p.fail(matrix->path, nullptr, "a node has either a matrix or translation, rotation and scale, not both");
    if (!matrix->v.is_array() || matrix->v.size() != 16) p.fail(*matrix, "must be an array of 16 numbers (column-major)");
    glm::mat4 m(1.0f);
    for (std::size_t i = 0; i < 16; ++i) {
      m[static_cast<int>(i / 4)][static_cast<int>(i % 4)] = p.number_f(Parser::element(*matrix, i), kAny);
    }
    return m;
  }
  glm::mat4 m(1.0f);
  if (t) m = glm::translate(m, p.vec3(*t, kAny, "translation x, y, z"));
  if (r) {
    const glm::vec4 q = p.vec<4>(*r, Range{-1e6, 1e6, false, false, ""}, "a unit quaternion x, y, z, w");
    const float len = glm::length(q);
    if (!(len > 1e-6f)) p.fail(*r, "must be a unit quaternion x, y, z, w (not zero)");
    m *= glm::mat4_cast(glm::quat(q.w / len, q.x / len, q.y / len, q.z / len));
  }
  if (s) m = glm::scale(m, p.vec3(*s, kAny, "scale x, y, z"));
  return m;
}

Node children_path(const Node& nodes, std::size_t i) {
  const Node node = Parser::element(nodes, i);
  return Node{node.v.at("children"), node.path + ".children"};
}

// Refuses a cycle: each node has at most one parent here, so walking up from any node either ends
// at a root or comes back round.
void check_acyclic(const Parser& p, const Node& nodes, const std::vector<std::uint32_t>& parent) {
  std::vector<std::uint8_t> state(parent.size(), 0);  // 0 unvisited, 1 on the current walk, 2 done
  std::vector<std::uint32_t> walk;
  for (std::uint32_t start = 0; start < parent.size(); ++start) {
    walk.clear();
    std::uint32_t at = start;
    while (at != kNone && state[at] == 0) {
      state[at] = 1;
      walk.push_back(at);
      at = parent[at];
    }
    if (at != kNone && state[at] == 1) {
      std::string ring;
      for (auto it = std::find(walk.begin(), walk.end(), at); it != walk.end(); ++it) ring += std::to_string(*it) + " -> ";
      p.fail(children_path(nodes, parent[at]).path, nullptr,
             "the node graph has a cycle (child to parent: " + ring + std::to_string(at) + "); it must be a forest");
    }
    for (const std::uint32_t w : walk) state[w] = 2;
  }
}

void read_nodes(Parser& p, const Node& nodes) {
  const std::size_t count = nodes.v.size();
  std::vector<std::uint32_t> parent(count, kNone);
  for (std::size_t i = 0; i < count; ++i) {
    const Node n = Parser::element(nodes, i);
    p.expect_object(n, "a node");
    gltf::Node node;
    node.name = p.optional_string(n, "name", "the node's name");
    node.mesh = p.optional_index(n, "mesh", p.asset.meshes.size(), "$.meshes");
    node.camera = p.optional_index(n, "camera", p.asset.cameras.size(), "$.cameras");
    if (const auto ext = p.object(n, "extensions", "the node's extensions")) {
      if (const auto lp = p.object(*ext, "KHR_lights_punctual", "the node's light")) {
        node.light = p.index(p.require(*lp, "light", "the light's index"), p.asset.lights.size(),
                             "$.extensions.KHR_lights_punctual.lights");
      }
    }
    node.local = local_transform(p, n);
    if (const auto children = p.array(n, "children")) {
      for (std::size_t c = 0; c < children->v.size(); ++c) {
        const Node cn = Parser::element(*children, c);
        const std::uint32_t child = p.index(cn, count, "$.nodes");
        if (child == i) p.fail(cn, "node " + std::to_string(i) + " cannot be its own child (the node graph has a cycle)");
        if (parent[child] != kNone) {
          p.fail(cn, "node " + std::to_string(child) + " is already a child of node " + std::to_string(parent[child]) +
                         "; a node has at most one parent");
        }
        parent[child] = static_cast<std::uint32_t>(i);
        node.children.push_back(child);
      }
    }
    p.asset.nodes.push_back(std::move(node));
  }
  check_acyclic(p, nodes, parent);
}

}  // namespace

void read_nodes_and_scenes(Parser& p, const Node& root) {
  const auto nodes = p.array(root, "nodes");
  std::vector<bool> is_child(nodes ? nodes->v.size() : 0, false);
  if (nodes) {
    read_nodes(p, *nodes);
    for (const gltf::Node& n : p.asset.nodes) {
      for (const std::uint32_t c : n.children) is_child[c] = true;
    }
  }
  if (const auto scenes = p.array(root, "scenes")) {
    for (std::size_t i = 0; i < scenes->v.size(); ++i) {
      const Node n = Parser::element(*scenes, i);
      p.expect_object(n, "a scene: name, nodes");
      SceneRoots s;
      s.name = p.optional_string(n, "name", "the scene's name");
      std::vector<bool> listed(p.asset.nodes.size(), false);
      if (const auto list = p.array(n, "nodes")) {
        for (std::size_t k = 0; k < list->v.size(); ++k) {
          const Node e = Parser::element(*list, k);
          const std::uint32_t node = p.index(e, p.asset.nodes.size(), "$.nodes");
          if (is_child[node]) p.fail(e, "node " + std::to_string(node) + " is a child of another node; a scene lists root nodes");
          if (listed[node]) p.fail(e, "node " + std::to_string(node) + " is listed twice");
          listed[node] = true;
          s.nodes.push_back(node);
        }
      }
      p.asset.scenes.push_back(std::move(s));
    }
  }
  p.asset.scene = p.optional_index(root, "scene", p.asset.scenes.size(), "$.scenes");
}

}  // namespace fovea::render::gltf::detail
