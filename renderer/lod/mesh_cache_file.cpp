// SPDX-License-Identifier: Apache-2.0
#include "lod/mesh_cache_file.h"

#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <vector>

namespace fovea::render::lod {

namespace {

constexpr char kMagic[8] = {'F', 'O', 'V', 'M', 'E', 'S', 'H', '1'};
constexpr std::size_t kArrays = 7;  // positions, normals, uv0, uv1, colors, tangents, indices

// Bytes per element of each array, in file order.
constexpr std::size_t kElementBytes[kArrays] = {12, 12, 8, 8, 16, 16, 4};

template <class T>
void put(std::string& out, const std::vector<T>& v) {
  if (v.empty()) return;
  out.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
}

template <class T>
void take(const std::string& bytes, std::size_t& at, std::uint64_t count, std::vector<T>& v) {
  v.resize(count);
  if (count == 0) return;  // memcpy's pointers must not be null, even for no bytes
  std::memcpy(v.data(), bytes.data() + at, count * sizeof(T));
  at += count * sizeof(T);
}

}  // namespace

void write_mesh_cache_file(const Mesh& m, const std::filesystem::path& path) {
  static_assert(sizeof(glm::vec3) == 12 && sizeof(glm::vec2) == 8 && sizeof(glm::vec4) == 16);
  std::string out(kMagic, sizeof kMagic);
  const std::uint64_t counts[kArrays] = {m.positions.size(), m.normals.size(), m.texcoords0.size(), m.texcoords1.size(),
                                         m.colors.size(),    m.tangents.size(), m.indices.size()};
  out.append(reinterpret_cast<const char*>(counts), sizeof counts);
  put(out, m.positions);
  put(out, m.normals);
  put(out, m.texcoords0);
  put(out, m.texcoords1);
  put(out, m.colors);
  put(out, m.tangents);
  put(out, m.indices);
  std::ofstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error(path.string() + ": cannot open for writing");
  f.write(out.data(), static_cast<std::streamsize>(out.size()));
  if (!f) throw std::runtime_error(path.string() + ": write failed");
}

Mesh read_mesh_cache_file(const std::filesystem::path& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error(path.string() + ": cannot read");
  const std::string bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  std::uint64_t counts[kArrays];
  const std::size_t header = sizeof kMagic + sizeof counts;
  if (bytes.size() < header || std::memcmp(bytes.data(), kMagic, sizeof kMagic) != 0) {
    throw std::runtime_error(path.string() + ": not a fovea mesh cache file");
  }
  std::memcpy(counts, bytes.data() + sizeof kMagic, sizeof counts);
  std::uint64_t payload = 0;
  for (std::size_t k = 0; k < kArrays; ++k) {
    if (counts[k] > bytes.size() / kElementBytes[k]) throw std::runtime_error(path.string() + ": truncated");
    payload += counts[k] * kElementBytes[k];
  }
  if (payload != bytes.size() - header) throw std::runtime_error(path.string() + ": size does not match its counts");
  const std::uint64_t n = counts[0];
  for (std::size_t k = 1; k < 6; ++k) {
    if (counts[k] != 0 && counts[k] != n) throw std::runtime_error(path.string() + ": an attribute not one per position");
  }
  if (counts[6] % 3 != 0) throw std::runtime_error(path.string() + ": index count not a multiple of 3");
  Mesh m;
  std::size_t at = header;
  take(bytes, at, counts[0], m.positions);
  take(bytes, at, counts[1], m.normals);
  take(bytes, at, counts[2], m.texcoords0);
  take(bytes, at, counts[3], m.texcoords1);
  take(bytes, at, counts[4], m.colors);
  take(bytes, at, counts[5], m.tangents);
  take(bytes, at, counts[6], m.indices);
  for (const std::uint32_t i : m.indices) {
    if (i >= n) throw std::runtime_error(path.string() + ": index " + std::to_string(i) + " past the vertices");
  }
  if (!all_finite(m)) throw std::runtime_error(path.string() + ": a value is not finite");
  return m;
}

}  // namespace fovea::render::lod
