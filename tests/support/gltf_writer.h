// SPDX-License-Identifier: Apache-2.0
#pragma once
// Writing small glTF 2.0 assets for tests: a binary buffer built from typed arrays, the JSON beside
// it, and the three containers (.gltf + .bin, .gltf with a data: URI, .glb).
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

namespace fovea::test {

using GltfJson = nlohmann::ordered_json;

// The binary buffer and its views: each add() appends 4-byte aligned data and a bufferView.
struct GltfBin {
  std::vector<std::uint8_t> bytes;
  GltfJson views = GltfJson::array();
  template <class T>
  std::size_t add(const std::vector<T>& data, std::uint32_t stride = 0) {
    while (bytes.size() % 4 != 0) bytes.push_back(0);
    const std::size_t offset = bytes.size();
    bytes.resize(offset + data.size() * sizeof(T));
    std::memcpy(bytes.data() + offset, data.data(), data.size() * sizeof(T));
    GltfJson v = {{"buffer", 0}, {"byteOffset", offset}, {"byteLength", data.size() * sizeof(T)}};
    if (stride != 0) v["byteStride"] = stride;
    views.push_back(v);
    return views.size() - 1;
  }
};

inline std::string base64(const std::vector<std::uint8_t>& in) {
  static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (std::size_t i = 0; i < in.size(); i += 3) {
    const std::uint32_t b = (std::uint32_t{in[i]} << 16) | (i + 1 < in.size() ? std::uint32_t{in[i + 1]} << 8 : 0u) |
                            (i + 2 < in.size() ? std::uint32_t{in[i + 2]} : 0u);
    out += k[(b >> 18) & 63];
    out += k[(b >> 12) & 63];
    out += i + 1 < in.size() ? k[(b >> 6) & 63] : '=';
    out += i + 2 < in.size() ? k[b & 63] : '=';
  }
  return out;
}

inline void write_file(const std::filesystem::path& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

// name.gltf beside name.bin.
inline std::filesystem::path write_gltf(const std::filesystem::path& dir, const std::string& name, GltfJson doc,
                                        const GltfBin& bin) {
  doc["buffers"] = GltfJson::array({{{"uri", name + ".bin"}, {"byteLength", bin.bytes.size()}}});
  doc["bufferViews"] = bin.views;
  write_file(dir / (name + ".bin"), std::string(bin.bytes.begin(), bin.bytes.end()));
  write_file(dir / (name + ".gltf"), doc.dump());
  return dir / (name + ".gltf");
}

inline std::filesystem::path write_gltf_data_uri(const std::filesystem::path& dir, const std::string& name, GltfJson doc,
                                                 const GltfBin& bin) {
  doc["buffers"] = GltfJson::array(
      {{{"uri", "data:application/octet-stream;base64," + base64(bin.bytes)}, {"byteLength", bin.bytes.size()}}});
  doc["bufferViews"] = bin.views;
  write_file(dir / (name + ".gltf"), doc.dump());
  return dir / (name + ".gltf");
}

// The GLB container's bytes: header, JSON chunk (space padded), BIN chunk (zero padded).
inline std::string glb_bytes(GltfJson doc, const GltfBin& bin) {
  doc["buffers"] = GltfJson::array({{{"byteLength", bin.bytes.size()}}});
  doc["bufferViews"] = bin.views;
  std::string json = doc.dump();
  while (json.size() % 4 != 0) json += ' ';
  std::string b(bin.bytes.begin(), bin.bytes.end());
  while (b.size() % 4 != 0) b += '\0';
  std::string out;
  const auto u32 = [&out](std::uint32_t v) { out.append(reinterpret_cast<const char*>(&v), 4); };
  out += "glTF";
  u32(2);
  u32(static_cast<std::uint32_t>(12 + 8 + json.size() + 8 + b.size()));
  u32(static_cast<std::uint32_t>(json.size()));
  out += "JSON";
  out += json;
  u32(static_cast<std::uint32_t>(b.size()));
  out.append("BIN\0", 4);
  out += b;
  return out;
}

}  // namespace fovea::test
