// SPDX-License-Identifier: Apache-2.0
#pragma once
// Reading a glTF 2.0 asset (.gltf with its buffers, or .glb) into gltf::Asset (gltf_asset.h).
// Everything in the file is untrusted: every index is range checked, every accessor read is bounds
// checked against its bufferView and buffer, URIs resolve only inside the asset's folder, and every
// size is checked against ReadOptions before anything is allocated. Errors are SceneError with
// "<file>: <JSON path> = <value>: <what is allowed>" (json_path.h), as for scene files.
#include <cstddef>
#include <filesystem>
#include <string>
#include <string_view>

#include "scene/gltf/gltf_asset.h"
#include "scene/scene_error.h"

namespace fovea::render::gltf {

struct ReadOptions {
  std::size_t max_file_bytes = std::size_t{256} << 20;      // the .gltf or .glb itself
  std::size_t max_buffer_file_bytes = std::size_t{1} << 30; // each external .bin
  std::size_t max_total_buffer_bytes = std::size_t{2} << 30;  // all buffers together (files, data: URIs, GLB)
  std::size_t max_data_uri_bytes = std::size_t{64} << 20;   // each data: URI, decoded
  // Vertex and index data decoded into the asset, all primitives together: an accessor of 4e9
  // elements without a bufferView (all zeros) is refused here before it is allocated.
  std::size_t max_decoded_bytes = std::size_t{4} << 30;
};

// Reads `file` (.glb by its extension or its "glTF" magic, else JSON). Relative URIs resolve in the
// file's folder. Throws SceneError.
Asset read_gltf(const std::filesystem::path& file, const ReadOptions& options = {});

// The same from bytes in memory; `name` is the source for messages and picks GLB by extension or
// magic. URIs resolve in `folder`; an empty folder refuses every external URI (data: URIs work).
Asset read_gltf_bytes(std::string_view bytes, const std::string& name, const std::filesystem::path& folder,
                      const ReadOptions& options = {});

}  // namespace fovea::render::gltf
