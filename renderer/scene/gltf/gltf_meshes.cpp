// SPDX-License-Identifier: Apache-2.0
// Meshes and their primitives (glTF 2.0 §3.7.2): each primitive's attributes decoded with the
// component types the specification allows for them (§3.7.2.1), every index checked against the
// vertex count, triangle strips and fans turned into lists, and a primitive without indices given
// 0, 1, 2, .... Points and lines are left out with a warning; fovea renders surfaces.
#include <algorithm>
#include <string>

#include "scene/gltf/gltf_parse.h"

namespace fovea::render::gltf::detail {

namespace {

constexpr std::uint32_t kPoints = 0, kTriangles = 4, kTriangleStrip = 5, kTriangleFan = 6;

const AccessorRule kPosition{{{3, kFloat, false}}, "VEC3 float"};
const AccessorRule kNormal{{{3, kFloat, false}}, "VEC3 float"};
const AccessorRule kTangent{{{4, kFloat, false}}, "VEC4 float"};
const AccessorRule kTexcoord{{{2, kFloat, false}, {2, kUnsignedByte, true}, {2, kUnsignedShort, true}},
                             "VEC2 float, or VEC2 unsigned byte or unsigned short normalized"};
const AccessorRule kColor{{{3, kFloat, false}, {4, kFloat, false}, {3, kUnsignedByte, true}, {4, kUnsignedByte, true},
                           {3, kUnsignedShort, true}, {4, kUnsignedShort, true}},
                          "VEC3 or VEC4 float, or VEC3 or VEC4 unsigned byte or unsigned short normalized"};
const AccessorRule kIndices{{{1, kUnsignedByte, false}, {1, kUnsignedShort, false}, {1, kUnsignedInt, false}},
                            "SCALAR unsigned byte, unsigned short or unsigned int"};

// Reads attribute `name` if present: its form checked, its count the vertex count.
template <int N>
std::vector<glm::vec<N, float>> attribute(Parser& p, const Node& attributes, const char* name, const AccessorRule& rule,
                                          std::size_t vertices) {
  const auto n = Parser::get(attributes, name);
  if (!n) return {};
  const std::uint32_t a = p.index(*n, p.accessors.size(), "$.accessors");
  expect_form(p, *n, a, name, rule);
  if (vertices != 0 && p.accessors[a].count != vertices) {
    p.fail(*n, "accessor " + std::to_string(a) + " has " + std::to_string(p.accessors[a].count) + " elements, POSITION has " +
                   std::to_string(vertices) + " (every attribute of a primitive has one element per vertex)");
  }
  return read_vectors<N>(p, *n, a);
}

// Triangle lists from strips and fans (§3.7.2.1: strip triangle i is {v_i, v_i+(1+i%2), v_i+(2-i%2)},
// fan triangle i is {v_i+1, v_i+2, v_0}).
std::vector<std::uint32_t> to_triangle_list(Parser& p, const Node& n, const std::vector<std::uint32_t>& v, std::uint32_t mode) {
  if (mode == kTriangles) {
    if (v.size() % 3 != 0) {
      p.fail(n, std::to_string(v.size()) + " indices, not a multiple of 3 (mode 4 draws triangles)");
    }
    return v;
  }
  if (v.size() < 3) return {};
  const std::size_t triangles = v.size() - 2;
  p.charge_decoded(n, std::uint64_t{triangles} * 3 * sizeof(std::uint32_t), "the triangle list");
  std::vector<std::uint32_t> out;
  out.reserve(triangles * 3);
  for (std::size_t i = 0; i < triangles; ++i) {
    if (mode == kTriangleStrip) {
      out.insert(out.end(), {v[i], v[i + 1 + i % 2], v[i + 2 - i % 2]});
    } else {
      out.insert(out.end(), {v[i + 1], v[i + 2], v[0]});
    }
  }
  return out;
}

void note_ignored_attributes(Parser& p, const Node& attributes) {
  static const json::Keys kRead = {"POSITION", "NORMAL", "TANGENT", "TEXCOORD_0", "TEXCOORD_1", "COLOR_0"};
  for (const auto& [key, value] : attributes.v.items()) {
    if (std::find(kRead.begin(), kRead.end(), key) != kRead.end()) continue;
    if (p.ignored_attributes.insert(key).second) {
      p.warn(attributes.path + json::key_suffix(key), "attribute " + key + " is not used by fovea; ignored");
    }
  }
}

std::optional<Primitive> read_primitive(Parser& p, const Node& n) {
  p.expect_object(n, "a primitive: attributes, indices, material, mode");
  const Node attributes = p.require(n, "attributes", "the primitive's vertex attributes");
  p.expect_object(attributes, "attribute names and accessor indices");
  std::uint32_t mode = kTriangles;
  const auto mode_node = Parser::get(n, "mode");
  if (mode_node) mode = static_cast<std::uint32_t>(p.integer(*mode_node, kPoints, kTriangleFan));
  Primitive prim;
  prim.material = p.optional_index(n, "material", p.asset.materials.size(), "$.materials");
  const auto indices_node = Parser::get(n, "indices");
  std::optional<std::uint32_t> indices;
  if (indices_node) indices = p.index(*indices_node, p.accessors.size(), "$.accessors");
  for (const auto& [key, value] : attributes.v.items()) {
    (void)p.index(Node{value, attributes.path + json::key_suffix(key)}, p.accessors.size(), "$.accessors");
  }
  if (mode < kTriangles) {
    p.warn(n.path, "mode " + std::to_string(mode) + " (points or lines) is not rendered; primitive left out");
    return std::nullopt;
  }
  if (Parser::get(attributes, "POSITION") == std::nullopt) {
    p.warn(n.path, "no POSITION attribute; primitive left out");
    return std::nullopt;
  }
  if (const auto targets = Parser::get(n, "targets")) p.warn(targets->path, "morph targets are not supported; ignored");
  note_ignored_attributes(p, attributes);

  prim.positions = attribute<3>(p, attributes, "POSITION", kPosition, 0);
  const std::size_t vertices = prim.positions.size();
  prim.normals = attribute<3>(p, attributes, "NORMAL", kNormal, vertices);
  prim.tangents = attribute<4>(p, attributes, "TANGENT", kTangent, vertices);
  prim.texcoords0 = attribute<2>(p, attributes, "TEXCOORD_0", kTexcoord, vertices);
  prim.texcoords1 = attribute<2>(p, attributes, "TEXCOORD_1", kTexcoord, vertices);
  prim.colors = attribute<4>(p, attributes, "COLOR_0", kColor, vertices);

  std::vector<std::uint32_t> list;
  if (indices) {
    expect_form(p, *indices_node, *indices, "indices", kIndices);
    if (const auto& d = p.accessors[*indices]; d.view && p.asset.buffer_views[*d.view].stride != 0) {
      p.fail(*indices_node, "accessor " + std::to_string(*indices) + " is in bufferView " + std::to_string(*d.view) +
                                ", which has a byteStride; indices must be tightly packed");
    }
    list = read_indices(p, *indices_node, *indices);
    for (std::size_t i = 0; i < list.size(); ++i) {
      if (list[i] >= vertices) {
        p.fail(*indices_node, "index " + std::to_string(list[i]) + " (element " + std::to_string(i) +
                                  " of accessor " + std::to_string(*indices) + ") is not below the vertex count " +
                                  std::to_string(vertices));
      }
    }
  } else {
    p.charge_decoded(n, std::uint64_t{vertices} * sizeof(std::uint32_t), "the generated indices");
    list.resize(vertices);
    for (std::size_t i = 0; i < vertices; ++i) list[i] = static_cast<std::uint32_t>(i);
  }
  prim.indices = to_triangle_list(p, indices_node ? *indices_node : n, list, mode);
  return prim;
}

}  // namespace

void read_meshes(Parser& p, const Node& root) {
  p.each(root, "meshes", [&p](const Node& n) {
    p.expect_object(n, "a mesh: name, primitives");
    Mesh mesh;
    mesh.name = p.optional_string(n, "name", "the mesh's name");
    const Node prims = p.require(n, "primitives", "the mesh's primitives");
    if (!prims.v.is_array() || prims.v.empty()) p.fail(prims, "must be a non-empty array of primitives");
    for (std::size_t i = 0; i < prims.v.size(); ++i) {
      if (auto prim = read_primitive(p, Parser::element(prims, i))) mesh.primitives.push_back(std::move(*prim));
    }
    p.asset.meshes.push_back(std::move(mesh));
  });
}

}  // namespace fovea::render::gltf::detail
