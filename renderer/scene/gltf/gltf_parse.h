// SPDX-License-Identifier: Apache-2.0
#pragma once
// Internal to the glTF reader: the parser state shared by its steps, one step per file
// (gltf_glb.cpp, gltf_uri.cpp, gltf_buffers.cpp, gltf_accessors.cpp, gltf_meshes.cpp,
// gltf_materials.cpp, gltf_cameras.cpp, gltf_nodes.cpp), run in that order by gltf_reader.cpp.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "scene/gltf/gltf_asset.h"
#include "scene/gltf/gltf_reader.h"
#include "scene/json_path.h"

namespace fovea::render::gltf::detail {

using json::Json;
using json::Node;
using json::Range;

// glTF component types (§3.6.2.2).
inline constexpr std::uint32_t kByte = 5120, kUnsignedByte = 5121, kShort = 5122, kUnsignedShort = 5123,
                               kUnsignedInt = 5125, kFloat = 5126;

// An accessor as declared, checked when read: its elements lie inside its bufferView and buffer.
struct AccessorDesc {
  std::optional<std::uint32_t> view;  // none: all zeros
  std::size_t offset = 0;             // byteOffset within the view
  std::uint32_t component_type = kFloat;
  std::uint32_t components = 1;       // SCALAR 1, VEC2 2, ..., MAT4 16
  bool normalized = false;
  std::size_t count = 0;
};

// The parser: json::Reader's typed reads with errors by path, the asset being filled and the
// budgets of ReadOptions.
class Parser : public json::Reader {
 public:
  Parser(Asset& a, const ReadOptions& o) : json::Reader(a.source), asset(a), options(o) {}

  Asset& asset;
  const ReadOptions& options;
  std::vector<AccessorDesc> accessors;
  std::size_t buffer_bytes = 0;   // all buffers so far, against max_total_buffer_bytes
  std::size_t decoded_bytes = 0;  // vertex and index data so far, against max_decoded_bytes
  std::set<std::string> ignored_attributes;

  // The array at parent.key; none when absent; an error when not an array.
  std::optional<Node> array(const Node& parent, std::string_view key) const;
  // Calls f(element) for each element of the array at parent.key, if there is one.
  template <class F>
  void each(const Node& parent, std::string_view key, F&& f) const {
    if (const auto a = array(parent, key)) {
      for (std::size_t i = 0; i < a->v.size(); ++i) f(element(*a, i));
    }
  }
  // An index into the asset's array `what` ("$.accessors") of `count` elements.
  std::uint32_t index(const Node& n, std::size_t count, const char* what) const;
  std::optional<std::uint32_t> optional_index(const Node& parent, std::string_view key, std::size_t count,
                                              const char* what) const;
  // The object `n` (checked to be one, `what` it holds), its name (none: "") and the string at
  // n.type, one of `types` ("directional, point or spot").
  std::string typed_object(const Node& n, const char* what, std::string* name, const char* types) const {
    expect_object(n, what);
    *name = optional_string(n, "name", "a name");
    return string(require(n, "type", types), types);
  }
  std::string optional_string(const Node& parent, std::string_view key, const char* what) const;
  float number_or(const Node& parent, std::string_view key, const Range& r, float fallback) const;
  // An object at parent.key (checked to be one), if present.
  std::optional<Node> object(const Node& parent, std::string_view key, const char* what) const;
  std::size_t size_value(const Node& n, std::size_t hi) const {
    return static_cast<std::size_t>(integer(n, 0, static_cast<std::int64_t>(hi)));
  }

  void warn(const std::string& path, const std::string& what) { asset.warnings.push_back(source_ + ": " + path + ": " + what); }
  // Counts `bytes` of decoded data for the element at `n`; fails before allocating past the budget.
  void charge_decoded(const Node& n, std::uint64_t bytes, const std::string& what);
  // Counts `bytes` of buffer data; fails past max_total_buffer_bytes.
  void charge_buffer(const Node& n, std::uint64_t bytes);
};

// ---- GLB container (gltf_glb.cpp) ----
struct Container {
  std::string_view json;
  std::optional<std::string_view> bin;  // the BIN chunk, if any
};
bool has_glb_magic(std::string_view bytes);
Container split_glb(std::string_view bytes, const std::string& source);

// ---- URIs (gltf_uri.cpp) ----
bool is_data_uri(std::string_view uri);
// The bytes of a base64 data: URI at `n`, at most `max_bytes` (checked before decoding); its media
// type goes to `mime`.
std::vector<std::uint8_t> decode_data_uri(const Parser& p, const Node& n, std::size_t max_bytes, std::string* mime);
// A relative URI at `n`, percent-decoded and resolved inside the asset's folder: refuses schemes,
// absolute paths, ".." above the folder, and symbolic links leading out of it. The file need not
// exist.
std::filesystem::path resolve_uri(const Parser& p, const Node& n);

// ---- steps ----
void read_buffers(Parser& p, const Node& root, std::optional<std::string_view> glb_bin);  // and bufferViews
void read_images(Parser& p, const Node& root);
void read_accessors(Parser& p, const Node& root);
void read_materials(Parser& p, const Node& root);  // samplers, textures, materials
void read_meshes(Parser& p, const Node& root);
void read_cameras_and_lights(Parser& p, const Node& root);
void read_nodes_and_scenes(Parser& p, const Node& root);

// ---- accessor reads (gltf_accessors.cpp) ----
// The (components, componentType, normalized) combinations an attribute allows, and their text.
struct AccessorForm {
  std::uint32_t components, component_type;
  bool normalized;
};
struct AccessorRule {
  std::vector<AccessorForm> forms;
  const char* text;  // "VEC3 float"
};
// Checks that accessor `a`, referred to at `ref`, has one of `rule`'s forms.
void expect_form(const Parser& p, const Node& ref, std::uint32_t a, const char* what, const AccessorRule& rule);
// Decodes accessor `a` into N-wide vectors (integers normalised per §3.11; a narrower accessor
// leaves the rest 0, and w 1). Values must be finite.
template <int N>
std::vector<glm::vec<N, float>> read_vectors(Parser& p, const Node& ref, std::uint32_t a);
std::vector<std::uint32_t> read_indices(Parser& p, const Node& ref, std::uint32_t a);
std::string describe_form(const AccessorDesc& d);  // "VEC3 float", "SCALAR unsigned short"

}  // namespace fovea::render::gltf::detail
