// SPDX-License-Identifier: Apache-2.0
#include "scene/tangents.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <map>
#include <stdexcept>
#include <unordered_map>

namespace fovea::render {
namespace {

constexpr std::uint32_t kNone = 0xFFFFFFFFu;

// A triangle's texture-space frame: the unit directions of dP/du and dP/dv, and whether its UV
// area is positive (orientation preserving) or it has none at all (degenerate).
struct Face {
  glm::vec3 os{0.0f}, ot{0.0f};
  bool orient = true;
  bool degenerate = true;
};

// Welded vertex ids: vertices equal in position, normal and texture coordinate share one.
std::vector<std::uint32_t> weld(const Mesh& m, const std::vector<glm::vec2>& uv) {
  struct Key {
    float v[8];
    bool operator==(const Key& o) const { return std::memcmp(v, o.v, sizeof v) == 0; }
  };
  struct Hash {
    std::size_t operator()(const Key& k) const {
      std::size_t h = 1469598103934665603ull;
      const auto* b = reinterpret_cast<const unsigned char*>(k.v);
      for (std::size_t i = 0; i < sizeof k.v; ++i) h = (h ^ b[i]) * 1099511628211ull;
      return h;
    }
  };
  std::unordered_map<Key, std::uint32_t, Hash> ids;
  std::vector<std::uint32_t> out(m.positions.size());
  for (std::size_t i = 0; i < out.size(); ++i) {
    Key k{};
    const glm::vec3 p = m.positions[i], n = m.normals[i];
    const float vals[8] = {p.x, p.y, p.z, n.x, n.y, n.z, uv[i].x, uv[i].y};
    for (int c = 0; c < 8; ++c) k.v[c] = vals[c] == 0.0f ? 0.0f : vals[c];  // -0 welds with +0
    out[i] = ids.emplace(k, static_cast<std::uint32_t>(ids.size())).first->second;
  }
  return out;
}

Face face_frame(const Mesh& m, const std::vector<glm::vec2>& uv, std::size_t f) {
  const std::uint32_t a = m.indices[3 * f], b = m.indices[3 * f + 1], c = m.indices[3 * f + 2];
  const glm::vec3 d1 = m.positions[b] - m.positions[a], d2 = m.positions[c] - m.positions[a];
  const glm::vec2 t21 = uv[b] - uv[a], t31 = uv[c] - uv[a];
  const float area = t21.x * t31.y - t21.y * t31.x;  // twice the signed UV area
  Face face;
  face.orient = area > 0;
  if (!(std::abs(area) > 1e-20f) || !std::isfinite(area)) return face;
  // dP/du and dP/dv times the signed area (mikktspace.c InitTriInfo), then unit length with the sign undone.
  const glm::vec3 os = t31.y * d1 - t21.y * d2, ot = -t31.x * d1 + t21.x * d2;
  const float los = glm::length(os), lot = glm::length(ot), sign = face.orient ? 1.0f : -1.0f;
  if (!(los > 0) || !(lot > 0) || !std::isfinite(los) || !std::isfinite(lot)) return face;
  face.os = os * (sign / los);
  face.ot = ot * (sign / lot);
  face.degenerate = false;
  return face;
}

// For each triangle edge k (corner k to corner k+1), the triangle across it whose edge runs the other
// way between the same welded vertices (kNone at a border, a non-manifold or inconsistently wound edge).
std::vector<std::uint32_t> neighbours(const std::vector<std::uint32_t>& idx, const std::vector<std::uint32_t>& welded) {
  std::unordered_map<std::uint64_t, std::uint32_t> edges;  // directed edge -> face, or kNone if seen twice
  const auto key = [](std::uint32_t from, std::uint32_t to) { return (std::uint64_t{from} << 32) | to; };
  const std::size_t faces = idx.size() / 3;
  for (std::size_t f = 0; f < faces; ++f)
    for (std::size_t k = 0; k < 3; ++k) {
      const std::uint64_t e = key(welded[idx[3 * f + k]], welded[idx[3 * f + (k + 1) % 3]]);
      auto [it, fresh] = edges.emplace(e, static_cast<std::uint32_t>(f));
      if (!fresh) it->second = kNone;
    }
  std::vector<std::uint32_t> out(3 * faces, kNone);
  for (std::size_t f = 0; f < faces; ++f)
    for (std::size_t k = 0; k < 3; ++k) {
      const auto it = edges.find(key(welded[idx[3 * f + (k + 1) % 3]], welded[idx[3 * f + k]]));
      if (it != edges.end() && it->second != kNone && it->second != f) out[3 * f + k] = it->second;
    }
  return out;
}

// The corner (0..2) of face f at welded vertex v, or 3 when it has none.
std::size_t corner_at(const std::vector<std::uint32_t>& idx, const std::vector<std::uint32_t>& welded, std::size_t f,
                      std::uint32_t v) {
  std::size_t k = 0;
  while (k < 3 && welded[idx[3 * f + k]] != v) ++k;
  return k;
}

glm::vec3 in_plane(const glm::vec3& v, const glm::vec3& n) { return v - n * glm::dot(n, v); }

glm::vec3 unit_or_zero(const glm::vec3& v) {
  const float l = glm::length(v);
  return l > 0 && std::isfinite(l) ? v / l : glm::vec3(0.0f);
}

// Any unit vector perpendicular to n: the tangent of a vertex no triangle gives a frame to.
glm::vec3 any_perpendicular(const glm::vec3& n) {
  const glm::vec3 axis = std::abs(n.x) < 0.9f ? glm::vec3(1, 0, 0) : glm::vec3(0, 1, 0);
  const glm::vec3 t = unit_or_zero(in_plane(axis, n));
  return t == glm::vec3(0.0f) ? glm::vec3(1, 0, 0) : t;
}

// Appends a copy of vertex i (every attribute the mesh has) and returns its index.
std::uint32_t duplicate_vertex(Mesh& m, std::uint32_t i) {
  const auto copy = [i](auto& attribute) {
    if (!attribute.empty()) attribute.push_back(attribute[i]);
  };
  copy(m.positions);
  copy(m.normals);
  copy(m.texcoords0);
  copy(m.texcoords1);
  copy(m.colors);
  copy(m.tangents);
  return static_cast<std::uint32_t>(m.positions.size() - 1);
}

}  // namespace

void generate_mikktspace_tangents(Mesh& m, std::uint32_t set) {
  const std::vector<glm::vec2> uv = m.texcoords(set);  // a copy: splitting vertices grows the mesh's
  if (uv.size() != m.positions.size() || m.normals.size() != m.positions.size())
    throw std::invalid_argument("generate_mikktspace_tangents: texture coordinates or normals missing");
  const std::vector<std::uint32_t>& idx = m.indices;
  const std::size_t faces = idx.size() / 3;
  const std::vector<std::uint32_t> welded = weld(m, uv);
  std::vector<Face> frame(faces);
  for (std::size_t f = 0; f < faces; ++f) frame[f] = face_frame(m, uv, f);
  const std::vector<std::uint32_t> across = neighbours(idx, welded);

  // Groups around each welded vertex, grown across shared edges between triangles of one orientation
  // (mikktspace.c Build4RuleGroups), each summed as EvalTspace does.
  std::vector<glm::vec4> corner(3 * faces, glm::vec4(0.0f));
  std::vector<std::uint8_t> done(3 * faces, 0);
  std::vector<std::uint32_t> stack, members;
  for (std::size_t f0 = 0; f0 < faces; ++f0)
    for (std::size_t k0 = 0; k0 < 3; ++k0) {
      if (done[3 * f0 + k0] || frame[f0].degenerate) continue;
      const std::uint32_t v = welded[idx[3 * f0 + k0]];
      const bool orient = frame[f0].orient;
      members.clear();
      stack.assign(1, static_cast<std::uint32_t>(f0));
      done[3 * f0 + k0] = 1;
      while (!stack.empty()) {
        const std::uint32_t f = stack.back();
        stack.pop_back();
        members.push_back(f);
        const std::size_t k = corner_at(idx, welded, f, v);
        // The two edges at this corner: k -> k+1 and k-1 -> k.
        for (const std::uint32_t g : {across[3 * f + k], across[3 * f + (k + 2) % 3]}) {
          if (g == kNone || frame[g].degenerate || frame[g].orient != orient) continue;
          const std::size_t kg = corner_at(idx, welded, g, v);
          if (kg > 2 || done[3 * g + kg]) continue;
          done[3 * g + kg] = 1;
          stack.push_back(g);
        }
      }
      const glm::vec3 n = m.normals[idx[3 * f0 + k0]];
      glm::vec3 os(0.0f), ot(0.0f);
      for (const std::uint32_t f : members) {
        const std::size_t k = corner_at(idx, welded, f, v);
        const glm::vec3 p1 = m.positions[idx[3 * f + k]];
        const glm::vec3 e1 = unit_or_zero(in_plane(m.positions[idx[3 * f + (k + 2) % 3]] - p1, n));
        const glm::vec3 e2 = unit_or_zero(in_plane(m.positions[idx[3 * f + (k + 1) % 3]] - p1, n));
        const float angle = std::acos(std::clamp(glm::dot(e1, e2), -1.0f, 1.0f));
        os += angle * unit_or_zero(in_plane(frame[f].os, n));
        ot += angle * unit_or_zero(in_plane(frame[f].ot, n));
      }
      glm::vec3 t = unit_or_zero(os);
      if (t == glm::vec3(0.0f)) t = any_perpendicular(n);
      // The bitangent points up the image, against dP/dv (glTF's normal maps: +Y up).
      const glm::vec4 tangent(t, glm::dot(glm::cross(n, t), ot) > 0 ? -1.0f : 1.0f);
      for (const std::uint32_t f : members) corner[3 * f + corner_at(idx, welded, f, v)] = tangent;
    }

  // Degenerate triangles' corners take a tangent another corner of the same welded vertex has.
  std::vector<glm::vec4> any_at(m.positions.size() == 0 ? 0 : *std::max_element(welded.begin(), welded.end()) + 1,
                                glm::vec4(0.0f));
  for (std::size_t c = 0; c < corner.size(); ++c)
    if (corner[c].w != 0.0f) any_at[welded[idx[c]]] = corner[c];
  for (std::size_t c = 0; c < corner.size(); ++c)
    if (corner[c].w == 0.0f) {
      const glm::vec4 t = any_at[welded[idx[c]]];
      corner[c] = t.w != 0.0f ? t : glm::vec4(any_perpendicular(m.normals[idx[c]]), 1.0f);
    }

  // Per-corner tangents back onto vertices: a vertex whose corners disagree is split.
  m.tangents.assign(m.positions.size(), glm::vec4(0.0f));
  std::vector<std::uint8_t> assigned(m.positions.size(), 0);
  std::map<std::pair<std::uint32_t, std::array<float, 4>>, std::uint32_t> copies;
  for (std::size_t c = 0; c < corner.size(); ++c) {
    const std::uint32_t i = m.indices[c];
    const glm::vec4 t = corner[c];
    if (!assigned[i]) {
      assigned[i] = 1;
      m.tangents[i] = t;
      continue;
    }
    if (m.tangents[i] == t) continue;
    const auto key = std::make_pair(i, std::array<float, 4>{t.x, t.y, t.z, t.w});
    auto it = copies.find(key);
    if (it == copies.end()) {
      const std::uint32_t j = duplicate_vertex(m, i);
      m.tangents[j] = t;
      it = copies.emplace(key, j).first;
    }
    m.indices[c] = it->second;
  }
  // Vertices no triangle uses still get a unit tangent.
  for (std::size_t i = 0; i < m.tangents.size(); ++i)
    if (m.tangents[i].w == 0.0f) m.tangents[i] = glm::vec4(any_perpendicular(m.normals[i]), 1.0f);
}

}  // namespace fovea::render
