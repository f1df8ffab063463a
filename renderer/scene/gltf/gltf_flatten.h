// SPDX-License-Identifier: Apache-2.0
#pragma once
// The mesh instances of a glTF scene: one per node with a mesh, with its world matrix. This is what
// a scene builder adds (Falcor's addMeshInstance): several nodes sharing a mesh keep one mesh index.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "scene/gltf/gltf_asset.h"

namespace fovea::render::gltf {

struct MeshInstance {
  std::uint32_t node = 0;
  std::string name;
  glm::mat4 world{1.0f};  // parent's world * local
  std::uint32_t mesh = 0;
};

// Walks the scene `scene`, or the asset's default scene, or its first, or (an asset without scenes)
// every root node in index order; depth first, children in the file's order.
// Names: the node's name, or "node<N>" (N its index) when it has none; a name already given to an
// earlier instance gets "#2", "#3", ... (the first free one), so every instance's name is unique.
std::vector<MeshInstance> flatten(const Asset& asset, std::optional<std::uint32_t> scene = std::nullopt);

// The world matrix of every node the same walk reaches (camera and light nodes too), indexed by
// node; none for a node outside that scene.
std::vector<std::optional<glm::mat4>> node_worlds(const Asset& asset, std::optional<std::uint32_t> scene = std::nullopt);

}  // namespace fovea::render::gltf
