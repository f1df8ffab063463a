// SPDX-License-Identifier: Apache-2.0
// The GLB container (glTF 2.0 §4.4): a 12-byte header (magic "glTF", version 2, total length), a
// JSON chunk, then an optional BIN chunk; chunks of other types are skipped as the spec asks. Every
// length is checked against the bytes actually there.
#include <bit>
#include <cstring>
#include <string>

#include "scene/gltf/gltf_parse.h"

namespace fovea::render::gltf::detail {

namespace {

constexpr std::uint32_t kMagic = 0x46546C67;      // "glTF"
constexpr std::uint32_t kChunkJson = 0x4E4F534A;  // "JSON"
constexpr std::uint32_t kChunkBin = 0x004E4942;   // "BIN\0"

std::uint32_t u32_at(std::string_view bytes, std::size_t at) {
  std::uint32_t v = 0;
  std::memcpy(&v, bytes.data() + at, sizeof v);  // GLB is little-endian, as is every host fovea builds for
  return v;
}

[[noreturn]] void fail(const std::string& source, std::size_t at, const std::string& what) {
  throw SceneError(source + ": GLB byte " + std::to_string(at) + ": " + what);
}

}  // namespace

bool has_glb_magic(std::string_view bytes) { return bytes.size() >= 4 && bytes.substr(0, 4) == "glTF"; }

Container split_glb(std::string_view bytes, const std::string& source) {
  static_assert(std::endian::native == std::endian::little, "GLB is little-endian");
  if (bytes.size() < 12) {
    fail(source, 0, "a GLB file starts with a 12-byte header; the file has " + std::to_string(bytes.size()) + " bytes");
  }
  if (u32_at(bytes, 0) != kMagic) fail(source, 0, "bad magic; a GLB file starts with \"glTF\"");
  const std::uint32_t version = u32_at(bytes, 4);
  if (version != 2) fail(source, 4, "GLB version " + std::to_string(version) + "; this reader reads version 2");
  const std::uint32_t length = u32_at(bytes, 8);
  if (length != bytes.size()) {
    fail(source, 8, "the header gives a length of " + std::to_string(length) + " bytes, the file has " +
                        std::to_string(bytes.size()) + " (truncated or padded)");
  }
  Container c;
  bool have_json = false;
  std::size_t at = 12;
  for (int chunk = 0; at < bytes.size(); ++chunk) {
    if (bytes.size() - at < 8) fail(source, at, "chunk " + std::to_string(chunk) + ": its 8-byte header is cut off");
    const std::uint32_t chunk_length = u32_at(bytes, at);
    const std::uint32_t type = u32_at(bytes, at + 4);
    const std::size_t data = at + 8;
    if (chunk_length > bytes.size() - data) {
      fail(source, at, "chunk " + std::to_string(chunk) + " of " + std::to_string(chunk_length) +
                           " bytes passes the end of the file (" + std::to_string(bytes.size() - data) + " bytes left)");
    }
    if (chunk_length % 4 != 0) {
      fail(source, at, "chunk " + std::to_string(chunk) + " has " + std::to_string(chunk_length) +
                           " bytes; chunks are padded to a multiple of 4");
    }
    const std::string_view payload = bytes.substr(data, chunk_length);
    if (chunk == 0) {
      if (type != kChunkJson) fail(source, at + 4, "the first chunk must be the JSON chunk");
      c.json = payload;
      have_json = true;
    } else if (type == kChunkJson) {
      fail(source, at + 4, "a second JSON chunk");
    } else if (type == kChunkBin) {
      if (chunk != 1) fail(source, at + 4, "the BIN chunk must follow the JSON chunk directly");
      c.bin = payload;
    }
    at = data + chunk_length;
  }
  if (!have_json) fail(source, 12, "no JSON chunk");
  return c;
}

}  // namespace fovea::render::gltf::detail
