// SPDX-License-Identifier: Apache-2.0
#pragma once
// Mesh files (OBJ, PLY, glTF) through assimp, as scenes and LOD chains read them.
#include <filesystem>

#include "scene/geometry.h"
#include "scene/scene_error.h"

namespace fovea::render {

// Reads a mesh file as scenes read them: triangulated, identical vertices joined, missing normals
// generated (smooth), node transforms applied. Throws SceneError naming the file and the problem
// (not found, unreadable, no triangles, a non-finite position).
Mesh read_mesh_file(const std::filesystem::path& path);

}  // namespace fovea::render
