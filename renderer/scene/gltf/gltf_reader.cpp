// SPDX-License-Identifier: Apache-2.0
#include "scene/gltf/gltf_reader.h"

#include <algorithm>
#include <cctype>
#include <stdexcept>
#include <string>
#include <utility>

#include "fovea/protocol/bounded_file.h"
#include "scene/gltf/gltf_parse.h"

namespace fovea::render::gltf {

namespace detail {

std::optional<Node> Parser::array(const Node& parent, std::string_view key) const {
  auto n = get(parent, key);
  if (n && !n->v.is_array()) fail(*n, "must be an array");
  return n;
}

std::uint32_t Parser::index(const Node& n, std::size_t count, const char* what) const {
  if (count == 0) fail(n, std::string("refers to ") + what + ", but the asset has none");
  const std::string allowed = std::string("must be an index into ") + what + " (0.." + std::to_string(count - 1) + ")";
  if (!n.v.is_number_integer() && !n.v.is_number_unsigned()) fail(n, allowed);
  if (n.v.is_number_unsigned()) {
    if (n.v.get<std::uint64_t>() >= count) fail(n, allowed);
  } else if (n.v.get<std::int64_t>() < 0 || static_cast<std::uint64_t>(n.v.get<std::int64_t>()) >= count) {
    fail(n, allowed);
  }
  return static_cast<std::uint32_t>(n.v.get<std::uint64_t>());
}

std::optional<std::uint32_t> Parser::optional_index(const Node& parent, std::string_view key, std::size_t count,
                                                    const char* what) const {
  const auto n = get(parent, key);
  if (!n) return std::nullopt;
  return index(*n, count, what);
}

std::string Parser::optional_string(const Node& parent, std::string_view key, const char* what) const {
  const auto n = get(parent, key);
  return n ? string(*n, what) : std::string();
}

float Parser::number_or(const Node& parent, std::string_view key, const Range& r, float fallback) const {
  const auto n = get(parent, key);
  return n ? number_f(*n, r) : fallback;
}

std::optional<Node> Parser::object(const Node& parent, std::string_view key, const char* what) const {
  auto n = get(parent, key);
  if (n) expect_object(*n, what);
  return n;
}

void Parser::charge_decoded(const Node& n, std::uint64_t bytes, const std::string& what) {
  if (bytes > options.max_decoded_bytes - std::min(decoded_bytes, options.max_decoded_bytes)) {
    fail(n, what + " would take " + std::to_string(bytes) + " bytes, past the asset's budget of " +
                std::to_string(options.max_decoded_bytes) + " bytes of vertex and index data (" +
                std::to_string(decoded_bytes) + " used)");
  }
  decoded_bytes += static_cast<std::size_t>(bytes);
}

void Parser::charge_buffer(const Node& n, std::uint64_t bytes) {
  if (bytes > options.max_total_buffer_bytes - std::min(buffer_bytes, options.max_total_buffer_bytes)) {
    fail(n, std::to_string(bytes) + " bytes would take the asset's buffers past their budget of " +
                std::to_string(options.max_total_buffer_bytes) + " bytes (" + std::to_string(buffer_bytes) +
                " used)");
  }
  buffer_bytes += static_cast<std::size_t>(bytes);
}

namespace {

// The extensions this reader implements; any other in extensionsRequired refuses the asset.
const json::Keys kSupportedExtensions = {"KHR_lights_punctual", "KHR_materials_emissive_strength"};

// "2.0" -> {2, 0}; none when not "<major>.<minor>".
std::optional<std::pair<int, int>> parse_version(const std::string& s) {
  const auto dot = s.find('.');
  if (dot == std::string::npos || dot == 0 || dot + 1 == s.size() || dot > 4 || s.size() - dot > 5) return std::nullopt;
  const auto digits = [](std::string_view t) { return std::all_of(t.begin(), t.end(), [](char c) { return c >= '0' && c <= '9'; }); };
  if (!digits(std::string_view(s).substr(0, dot)) || !digits(std::string_view(s).substr(dot + 1))) return std::nullopt;
  return std::pair{std::stoi(s.substr(0, dot)), std::stoi(s.substr(dot + 1))};
}

void read_header(Parser& p, const Node& root) {
  const Node asset = p.require(root, "asset", "the asset object with its version (\"2.0\")");
  p.expect_object(asset, "the asset's version and generator");
  const Node version = p.require(asset, "version", "the glTF version (\"2.0\")");
  p.asset.version = p.string(version, "the glTF version, \"2.0\"");
  const auto v = parse_version(p.asset.version);
  if (!v) p.fail(version, "must be a version \"<major>.<minor>\", e.g. \"2.0\"");
  if (v->first != 2) p.fail(version, "unsupported glTF version; this reader reads glTF 2.x");
  if (const auto min = Parser::get(asset, "minVersion")) {
    const auto mv = parse_version(p.string(*min, "the least glTF version a reader must support"));
    if (!mv) p.fail(*min, "must be a version \"<major>.<minor>\", e.g. \"2.0\"");
    if (*mv != std::pair{2, 0}) p.fail(*min, "this reader supports glTF 2.0 only");
  }
  p.asset.generator = p.optional_string(asset, "generator", "the tool that wrote the asset");

  if (const auto used = p.array(root, "extensionsUsed")) {
    for (std::size_t i = 0; i < used->v.size(); ++i) {
      const Node e = Parser::element(*used, i);
      std::string name = p.string(e, "an extension's name");
      if (std::find(kSupportedExtensions.begin(), kSupportedExtensions.end(), name) == kSupportedExtensions.end()) {
        p.warn(e.path, "extension " + name + " is not supported; its data is ignored");
      }
      p.asset.extensions_used.push_back(std::move(name));
    }
  }
  if (const auto required = p.array(root, "extensionsRequired")) {
    for (std::size_t i = 0; i < required->v.size(); ++i) {
      const Node e = Parser::element(*required, i);
      const std::string name = p.string(e, "an extension's name");
      if (std::find(kSupportedExtensions.begin(), kSupportedExtensions.end(), name) == kSupportedExtensions.end()) {
        p.fail(e, "the asset requires extension " + name + ", which this reader does not support (supported: " +
                      json::join(kSupportedExtensions) + ")");
      }
    }
  }
  for (const char* ignored : {"animations", "skins"}) {
    if (const auto a = p.array(root, ignored); a && !a->v.empty()) p.warn(a->path, "not supported; ignored");
  }
}

bool has_extension(const std::string& name, std::string_view ext) {
  const auto dot = name.rfind('.');
  if (dot == std::string::npos) return false;
  std::string e = name.substr(dot);
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return e == ext;
}

}  // namespace

}  // namespace detail

Asset read_gltf_bytes(std::string_view bytes, const std::string& name, const std::filesystem::path& folder,
                      const ReadOptions& options) {
  using namespace detail;
  Asset asset;
  asset.source = name;
  asset.folder = folder;
  if (bytes.size() > options.max_file_bytes) {
    throw SceneError(name + ": " + std::to_string(bytes.size()) + " bytes, more than the limit of " +
                     std::to_string(options.max_file_bytes));
  }
  std::string_view text = bytes;
  std::optional<std::string_view> bin;
  if (has_extension(name, ".glb") || has_glb_magic(bytes)) {
    const Container c = split_glb(bytes, name);
    text = c.json;
    bin = c.bin;
  }
  const Json doc = json::parse_document(std::string(text), name);
  Parser p(asset, options);
  const detail::Node root{doc, "$"};
  read_header(p, root);
  read_buffers(p, root, bin);
  read_images(p, root);
  read_materials(p, root);
  read_accessors(p, root);
  read_meshes(p, root);
  read_cameras_and_lights(p, root);
  read_nodes_and_scenes(p, root);
  return asset;
}

Asset read_gltf(const std::filesystem::path& file, const ReadOptions& options) {
  std::string bytes;
  try {
    bytes = protocol::read_bounded_file(file.string(), {options.max_file_bytes, true, "glTF file"});
  } catch (const std::runtime_error& e) {
    throw SceneError(e.what());
  }
  std::filesystem::path folder = file.parent_path();
  if (folder.empty()) folder = ".";
  return read_gltf_bytes(bytes, file.string(), folder, options);
}

std::span<const std::uint8_t> image_bytes(const Asset& asset, std::size_t image) {
  if (image >= asset.images.size()) return {};
  const Image& im = asset.images[image];
  if (!im.data.empty()) return im.data;
  if (!im.buffer_view) return {};
  const BufferView& v = asset.buffer_views.at(*im.buffer_view);
  return std::span<const std::uint8_t>(asset.buffers.at(v.buffer).bytes).subspan(v.offset, v.length);
}

}  // namespace fovea::render::gltf
