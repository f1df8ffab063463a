// SPDX-License-Identifier: Apache-2.0
// Buffers (external files, data: URIs, the GLB BIN chunk), bufferViews and images (glTF 2.0 §3.6,
// §3.8.3). Each buffer is read whole, within the per-file and total budgets of ReadOptions; each
// bufferView is checked to lie inside its buffer, so accessor reads need check only the view.
#include <stdexcept>
#include <string>

#include "fovea/protocol/bounded_file.h"
#include "scene/gltf/gltf_parse.h"

namespace fovea::render::gltf::detail {

namespace {

constexpr std::int64_t kMaxLength = std::int64_t{1} << 40;

Buffer read_buffer(Parser& p, const Node& n, std::size_t i, std::optional<std::string_view> glb_bin) {
  p.expect_object(n, "a buffer: byteLength and uri");
  const Node length_node = p.require(n, "byteLength", "the buffer's length in bytes");
  const std::size_t length = static_cast<std::size_t>(p.integer(length_node, 1, kMaxLength));
  p.charge_buffer(length_node, length);
  Buffer b;
  const auto uri = Parser::get(n, "uri");
  if (!uri) {
    if (i != 0 || !glb_bin) p.fail(n, "a buffer without a uri must be buffer 0 of a .glb file with a BIN chunk");
    if (glb_bin->size() < length || glb_bin->size() > length + 3) {
      p.fail(length_node, "the GLB BIN chunk has " + std::to_string(glb_bin->size()) +
                              " bytes; it must hold byteLength bytes plus at most 3 of padding");
    }
    b.bytes.assign(glb_bin->begin(), glb_bin->begin() + static_cast<std::ptrdiff_t>(length));
    return b;
  }
  if (is_data_uri(p.string(*uri, "a relative path or a data: URI"))) {
    b.bytes = decode_data_uri(p, *uri, p.options.max_data_uri_bytes, nullptr);
  } else {
    if (length > p.options.max_buffer_file_bytes) {
      p.fail(length_node, "more than the limit of " + std::to_string(p.options.max_buffer_file_bytes) +
                              " bytes for a buffer file (ReadOptions::max_buffer_file_bytes)");
    }
    const std::filesystem::path file = resolve_uri(p, *uri);
    std::string bytes;
    try {
      bytes = protocol::read_bounded_file(file.string(), {p.options.max_buffer_file_bytes, false, "glTF buffer"});
    } catch (const std::runtime_error& e) {
      p.fail(*uri, e.what());
    }
    b.bytes.assign(bytes.begin(), bytes.end());
  }
  if (b.bytes.size() < length) {
    p.fail(length_node, "the buffer's data has only " + std::to_string(b.bytes.size()) + " bytes");
  }
  b.bytes.resize(length);
  return b;
}

BufferView read_buffer_view(Parser& p, const Node& n) {
  p.expect_object(n, "a bufferView: buffer, byteOffset, byteLength, byteStride");
  BufferView v;
  v.buffer = p.index(p.require(n, "buffer", "the buffer's index"), p.asset.buffers.size(), "$.buffers");
  const std::size_t buffer_length = p.asset.buffers[v.buffer].bytes.size();
  if (const auto o = Parser::get(n, "byteOffset")) v.offset = static_cast<std::size_t>(p.integer(*o, 0, kMaxLength));
  const Node length_node = p.require(n, "byteLength", "the view's length in bytes");
  v.length = static_cast<std::size_t>(p.integer(length_node, 1, kMaxLength));
  if (v.offset > buffer_length || v.length > buffer_length - v.offset) {
    p.fail(n.path, nullptr, std::to_string(v.length) + " bytes from byte " + std::to_string(v.offset) +
                                " pass the end of buffer " + std::to_string(v.buffer) + " (" +
                                std::to_string(buffer_length) + " bytes)");
  }
  if (const auto s = Parser::get(n, "byteStride")) {
    v.stride = static_cast<std::uint32_t>(p.integer(*s, 0, 1000));
    if (v.stride < 4 || v.stride > 252 || v.stride % 4 != 0) p.fail(*s, "must be a multiple of 4 in 4..252");
  }
  return v;
}

}  // namespace

void read_buffers(Parser& p, const Node& root, std::optional<std::string_view> glb_bin) {
  if (const auto buffers = p.array(root, "buffers")) {
    for (std::size_t i = 0; i < buffers->v.size(); ++i) p.asset.buffers.push_back(read_buffer(p, Parser::element(*buffers, i), i, glb_bin));
  }
  p.each(root, "bufferViews", [&](const Node& n) { p.asset.buffer_views.push_back(read_buffer_view(p, n)); });
}

void read_images(Parser& p, const Node& root) {
  p.each(root, "images", [&p](const Node& n) {
    p.expect_object(n, "an image: uri, or bufferView and mimeType");
    Image im;
    im.name = p.optional_string(n, "name", "the image's name");
    im.mime_type = p.optional_string(n, "mimeType", "the image's media type, image/png or image/jpeg");
    const auto uri = Parser::get(n, "uri");
    im.buffer_view = p.optional_index(n, "bufferView", p.asset.buffer_views.size(), "$.bufferViews");
    if (uri.has_value() == im.buffer_view.has_value()) p.fail(n, "an image has either a uri or a bufferView");
    if (im.buffer_view && im.mime_type.empty()) p.fail(n.path + ".mimeType", nullptr, "missing required field: an image in a bufferView needs its mimeType");
    if (uri) {
      if (is_data_uri(p.string(*uri, "a relative path or a data: URI"))) {
        std::string mime;
        im.data = decode_data_uri(p, *uri, p.options.max_data_uri_bytes, &mime);
        p.charge_buffer(*uri, im.data.size());
        if (im.mime_type.empty()) im.mime_type = mime;
      } else {
        // Kept as a reference even when missing: the scene builder decodes the images materials use
        // and warns about each it cannot read, naming the material.
        im.file = resolve_uri(p, *uri);
      }
    }
    p.asset.images.push_back(std::move(im));
  });
}

}  // namespace fovea::render::gltf::detail
