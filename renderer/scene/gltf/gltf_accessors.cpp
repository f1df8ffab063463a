// SPDX-License-Identifier: Apache-2.0
// Accessors (glTF 2.0 §3.6.2): declared, checked, then decoded on demand into typed arrays. Every
// accessor with a bufferView is bounds checked once when read (offset + stride * (count - 1) +
// element size within the view, the view within its buffer), so decoding never reads outside the
// data. min and max are not trusted. Sparse accessors (§3.6.2.3) are refused with a message saying
// so: no exporter fovea's scenes come from writes them for mesh data.
#include <cmath>
#include <cstring>
#include <string>

#include "scene/gltf/gltf_parse.h"

namespace fovea::render::gltf::detail {

namespace {

struct TypeName {
  const char* name;
  std::uint32_t components, rows;  // rows > 0: a matrix of `rows` rows and columns
};
constexpr TypeName kTypes[] = {{"SCALAR", 1, 0}, {"VEC2", 2, 0}, {"VEC3", 3, 0}, {"VEC4", 4, 0},
                               {"MAT2", 4, 2},   {"MAT3", 9, 3}, {"MAT4", 16, 4}};

std::uint32_t component_size(std::uint32_t type) {
  switch (type) {
    case kByte: case kUnsignedByte: return 1;
    case kShort: case kUnsignedShort: return 2;
    default: return 4;
  }
}

const char* component_name(std::uint32_t type) {
  switch (type) {
    case kByte: return "byte";
    case kUnsignedByte: return "unsigned byte";
    case kShort: return "short";
    case kUnsignedShort: return "unsigned short";
    case kUnsignedInt: return "unsigned int";
    default: return "float";
  }
}

const TypeName& type_of(const AccessorDesc& d) {
  for (const TypeName& t : kTypes) {
    if (t.components == d.components) return t;
  }
  return kTypes[0];
}

// Bytes of one element; matrix columns start on 4-byte boundaries (§3.6.2.4).
std::size_t element_size(const AccessorDesc& d) {
  const TypeName& t = type_of(d);
  const std::size_t c = component_size(d.component_type);
  if (t.rows == 0) return d.components * c;
  return t.rows * ((t.rows * c + 3) / 4 * 4);
}

// One component as a float: normalised integers per §3.11, others converted.
float component(const std::uint8_t* at, std::uint32_t type, bool normalized) {
  switch (type) {
    case kByte: { std::int8_t v; std::memcpy(&v, at, 1); return normalized ? std::max(v / 127.0f, -1.0f) : v; }
    case kUnsignedByte: return normalized ? *at / 255.0f : *at;
    case kShort: { std::int16_t v; std::memcpy(&v, at, 2); return normalized ? std::max(v / 32767.0f, -1.0f) : v; }
    case kUnsignedShort: { std::uint16_t v; std::memcpy(&v, at, 2); return normalized ? v / 65535.0f : v; }
    case kUnsignedInt: { std::uint32_t v; std::memcpy(&v, at, 4); return static_cast<float>(v); }
    default: { float v; std::memcpy(&v, at, 4); return v; }
  }
}

// The first byte of the accessor's data and its stride; nullptr for an accessor without a view.
const std::uint8_t* data_of(const Parser& p, const AccessorDesc& d, std::size_t* stride) {
  *stride = element_size(d);
  if (!d.view) return nullptr;
  const BufferView& v = p.asset.buffer_views[*d.view];
  if (v.stride != 0) *stride = v.stride;
  return p.asset.buffers[v.buffer].bytes.data() + v.offset + d.offset;
}

AccessorDesc read_accessor(const Parser& p, const Node& n) {
  p.expect_object(n, "an accessor: bufferView, byteOffset, componentType, count, type");
  AccessorDesc d;
  d.view = p.optional_index(n, "bufferView", p.asset.buffer_views.size(), "$.bufferViews");
  if (const auto o = Parser::get(n, "byteOffset")) d.offset = p.size_value(*o, std::size_t{1} << 40);
  const Node ct = p.require(n, "componentType", "5120 byte .. 5126 float");
  d.component_type = static_cast<std::uint32_t>(p.integer(ct, 0, 100000));
  if (d.component_type < kByte || d.component_type > kFloat || d.component_type == 5124) {
    p.fail(ct, "must be a component type: 5120 byte, 5121 unsigned byte, 5122 short, 5123 unsigned short, "
               "5125 unsigned int or 5126 float");
  }
  if (const auto nm = Parser::get(n, "normalized")) d.normalized = p.boolean(*nm);
  if (d.normalized && (d.component_type == kFloat || d.component_type == kUnsignedInt)) {
    p.fail(n.path + ".normalized", nullptr, "only byte and short components may be normalized");
  }
  const Node count = p.require(n, "count", "the number of elements");
  d.count = p.size_value(count, 0xFFFFFFFFu);
  if (d.count == 0) p.fail(count, "must be at least 1");
  const Node type = p.require(n, "type", "SCALAR, VEC2, VEC3, VEC4, MAT2, MAT3 or MAT4");
  const std::string t = p.string(type, "SCALAR, VEC2, VEC3, VEC4, MAT2, MAT3 or MAT4");
  d.components = 0;
  for (const TypeName& tn : kTypes) {
    if (t == tn.name) d.components = tn.components;
  }
  if (d.components == 0) p.fail(type, "must be SCALAR, VEC2, VEC3, VEC4, MAT2, MAT3 or MAT4");
  if (const auto sparse = Parser::get(n, "sparse")) {
    p.fail(sparse->path, nullptr, "sparse accessors are not supported by this reader (write the accessor dense)");
  }
  if (!d.view) return d;
  const BufferView& v = p.asset.buffer_views[*d.view];
  const std::size_t elem = element_size(d), csize = component_size(d.component_type);
  if (v.stride != 0 && v.stride < elem) {
    p.fail(n.path, nullptr, "bufferView " + std::to_string(*d.view) + " has byteStride " + std::to_string(v.stride) +
                                ", less than one " + describe_form(d) + " element (" + std::to_string(elem) + " bytes)");
  }
  if ((v.offset + d.offset) % csize != 0) {
    p.fail(n.path, nullptr, describe_form(d) + " elements start at byte " + std::to_string(v.offset + d.offset) +
                                " of buffer " + std::to_string(v.buffer) + ", not a multiple of the component size " +
                                std::to_string(csize));
  }
  const std::uint64_t stride = v.stride != 0 ? v.stride : elem;
  const std::uint64_t end = std::uint64_t{d.offset} + stride * (d.count - 1) + elem;  // < 2^41: no overflow
  if (end > v.length) {
    p.fail(n.path, nullptr, std::to_string(d.count) + " " + describe_form(d) + " elements from byte " +
                                std::to_string(d.offset) + " pass the end of bufferView " + std::to_string(*d.view) +
                                " (" + std::to_string(v.length) + " bytes)");
  }
  return d;
}

}  // namespace

std::string describe_form(const AccessorDesc& d) {
  return std::string(type_of(d).name) + " " + component_name(d.component_type) + (d.normalized ? " normalized" : "");
}

void read_accessors(Parser& p, const Node& root) {
  p.each(root, "accessors", [&](const Node& n) { p.accessors.push_back(read_accessor(p, n)); });
}

void expect_form(const Parser& p, const Node& ref, std::uint32_t a, const char* what, const AccessorRule& rule) {
  const AccessorDesc& d = p.accessors[a];
  for (const AccessorForm& f : rule.forms) {
    if (f.components == d.components && f.component_type == d.component_type && f.normalized == d.normalized) return;
  }
  p.fail(ref, "accessor " + std::to_string(a) + " is " + describe_form(d) + "; " + what + " must be " + rule.text);
}

template <int N>
std::vector<glm::vec<N, float>> read_vectors(Parser& p, const Node& ref, std::uint32_t a) {
  const AccessorDesc& d = p.accessors[a];
  p.charge_decoded(ref, std::uint64_t{d.count} * sizeof(glm::vec<N, float>),
                   "accessor " + std::to_string(a) + "'s " + std::to_string(d.count) + " elements");
  std::vector<glm::vec<N, float>> out(d.count, glm::vec<N, float>(0.0f));
  if constexpr (N == 4) {
    if (d.components < 4) {
      for (auto& v : out) v.w = 1.0f;
    }
  }
  std::size_t stride = 0;
  const std::uint8_t* data = data_of(p, d, &stride);
  if (data == nullptr) return out;
  const std::size_t csize = component_size(d.component_type);
  const int n = std::min(N, static_cast<int>(d.components));
  for (std::size_t i = 0; i < d.count; ++i) {
    const std::uint8_t* e = data + i * stride;
    for (int c = 0; c < n; ++c) {
      const float x = component(e + static_cast<std::size_t>(c) * csize, d.component_type, d.normalized);
      if (!std::isfinite(x)) {
        p.fail("$.accessors" + json::index_suffix(a), nullptr,
               "element " + std::to_string(i) + " component " + std::to_string(c) + " is " + json::format_number(x) +
                   "; vertex data must be finite");
      }
      out[i][c] = x;
    }
  }
  return out;
}

template std::vector<glm::vec2> read_vectors<2>(Parser&, const Node&, std::uint32_t);
template std::vector<glm::vec3> read_vectors<3>(Parser&, const Node&, std::uint32_t);
template std::vector<glm::vec4> read_vectors<4>(Parser&, const Node&, std::uint32_t);

std::vector<std::uint32_t> read_indices(Parser& p, const Node& ref, std::uint32_t a) {
  const AccessorDesc& d = p.accessors[a];
  p.charge_decoded(ref, std::uint64_t{d.count} * sizeof(std::uint32_t),
                   "accessor " + std::to_string(a) + "'s " + std::to_string(d.count) + " indices");
  std::vector<std::uint32_t> out(d.count, 0u);
  std::size_t stride = 0;
  const std::uint8_t* data = data_of(p, d, &stride);
  if (data == nullptr) return out;
  for (std::size_t i = 0; i < d.count; ++i) {
    const std::uint8_t* e = data + i * stride;
    switch (d.component_type) {
      case kUnsignedByte: out[i] = *e; break;
      case kUnsignedShort: { std::uint16_t v; std::memcpy(&v, e, 2); out[i] = v; break; }
      default: std::memcpy(&out[i], e, 4); break;
    }
  }
  return out;
}

}  // namespace fovea::render::gltf::detail
