// SPDX-License-Identifier: Apache-2.0
#pragma once
// The LOD cache's mesh file (`.fmesh`): every attribute of a Mesh (positions, normals, both texture
// coordinate sets, colours, tangents, indices) in one little-endian binary file, so a cached chain of
// a textured glTF object comes back with its UVs (OBJ and PLY as assimp reads them would drop the
// tangents and second UV set). The cache is a user's own directory, but a damaged or planted file
// must not crash or allocate without bound: every count is checked against the file's size first.
#include <filesystem>

#include "scene/scene.h"

namespace fovea::render::lod {

void write_mesh_cache_file(const Mesh& mesh, const std::filesystem::path& path);
// Throws std::runtime_error naming the file and what is wrong with it.
Mesh read_mesh_cache_file(const std::filesystem::path& path);

}  // namespace fovea::render::lod
