// SPDX-License-Identifier: Apache-2.0
// URIs of buffers and images (glTF 2.0 §3.6.1.1, RFC 3986): base64 data: URIs up to a size limit,
// or relative paths, percent-decoded and confined to the asset's folder. A path that is absolute,
// has a scheme, climbs out with "..", or reaches out through a symbolic link is refused, so that an
// asset cannot make fovea read /etc/passwd or a neighbour's files.
#include <array>
#include <string>
#include <system_error>

#include "scene/gltf/gltf_parse.h"

namespace fovea::render::gltf::detail {

namespace {

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

std::string percent_decode(const Parser& p, const Node& n, const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (text[i] != '%') {
      out += text[i];
      continue;
    }
    const int hi = i + 2 < text.size() ? hex_value(text[i + 1]) : -1;
    const int lo = i + 2 < text.size() ? hex_value(text[i + 2]) : -1;
    if (hi < 0 || lo < 0) p.fail(n, "bad percent-encoding at character " + std::to_string(i) + " ('%' takes two hex digits)");
    const char c = static_cast<char>(hi * 16 + lo);
    if (c == '\0') p.fail(n, "percent-encodes a NUL byte");
    out += c;
    i += 2;
  }
  return out;
}

// Whether `inner` (canonical) lies inside `outer` (canonical).
bool inside(const std::filesystem::path& outer, const std::filesystem::path& inner) {
  auto o = outer.begin();
  auto i = inner.begin();
  for (; o != outer.end(); ++o, ++i) {
    if (o->empty()) continue;  // a trailing separator
    if (i == inner.end() || *o != *i) return false;
  }
  return true;
}

constexpr std::array<int, 256> base64_table() {
  std::array<int, 256> t{};
  for (int& v : t) v = -1;
  const char* alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  for (int i = 0; i < 64; ++i) t[static_cast<unsigned char>(alphabet[i])] = i;
  return t;
}

}  // namespace

bool is_data_uri(std::string_view uri) { return uri.starts_with("data:"); }

std::vector<std::uint8_t> decode_data_uri(const Parser& p, const Node& n, std::size_t max_bytes, std::string* mime) {
  const std::string& uri = n.v.get_ref<const std::string&>();
  const auto comma = uri.find(',');
  if (comma == std::string::npos) p.fail(n, "a data: URI needs a ',' before its data");
  const std::string_view header = std::string_view(uri).substr(5, comma - 5);
  if (!header.ends_with(";base64")) p.fail(n, "a data: URI must be base64 (\"data:<type>;base64,...\")");
  if (mime != nullptr) *mime = std::string(header.substr(0, header.find(';')));
  std::string_view b64 = std::string_view(uri).substr(comma + 1);
  while (!b64.empty() && b64.back() == '=') b64.remove_suffix(1);
  const std::uint64_t decoded = b64.size() / 4 * 3 + (b64.size() % 4 == 0 ? 0 : b64.size() % 4 - 1);
  if (decoded > max_bytes) {
    p.fail(n.path, nullptr, "a data: URI of " + std::to_string(decoded) + " bytes, more than the limit of " +
                                std::to_string(max_bytes) + " (ReadOptions::max_data_uri_bytes)");
  }
  if (b64.size() % 4 == 1) p.fail(n.path, nullptr, "bad base64 in the data: URI (its length)");
  static constexpr std::array<int, 256> kTable = base64_table();
  std::vector<std::uint8_t> out;
  out.reserve(static_cast<std::size_t>(decoded));
  std::uint32_t acc = 0;
  int bits = 0;
  for (std::size_t i = 0; i < b64.size(); ++i) {
    const int v = kTable[static_cast<unsigned char>(b64[i])];
    if (v < 0) p.fail(n.path, nullptr, "bad base64 in the data: URI at character " + std::to_string(comma + 1 + i));
    acc = (acc << 6) | static_cast<std::uint32_t>(v);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out.push_back(static_cast<std::uint8_t>((acc >> bits) & 0xFFu));
    }
  }
  return out;
}

std::filesystem::path resolve_uri(const Parser& p, const Node& n) {
  const std::string uri = p.string(n, "a relative path or a data: URI");
  if (p.asset.folder.empty()) p.fail(n, "an external file, but the asset was read from memory without a folder");
  const auto colon = uri.find(':');
  if (colon != std::string::npos && uri.find('/') > colon) {
    p.fail(n, "a URI with a scheme; only relative paths inside the asset's folder and data: URIs are read");
  }
  if (uri.find('\\') != std::string::npos) p.fail(n, "contains '\\'; URIs separate folders with '/'");
  const std::string path = percent_decode(p, n, uri);
  if (path.empty()) p.fail(n, "an empty path");
  if (path.front() == '/') p.fail(n, "an absolute path; only paths relative to the asset's folder are read");
  std::filesystem::path relative;
  int depth = 0;
  std::size_t start = 0;
  while (start <= path.size()) {
    const auto end = std::min(path.find('/', start), path.size());
    const std::string segment = path.substr(start, end - start);
    start = end + 1;
    if (segment.empty() || segment == ".") continue;
    if (segment == "..") {
      if (--depth < 0) p.fail(n, "outside the asset's folder");
      relative = relative.parent_path();
      continue;
    }
    ++depth;
    relative /= segment;
  }
  if (relative.empty()) p.fail(n, "names the asset's folder, not a file");
  std::error_code ec;
  const std::filesystem::path folder = std::filesystem::weakly_canonical(p.asset.folder, ec);
  if (ec) p.fail(n, "the asset's folder " + p.asset.folder.string() + " cannot be resolved: " + ec.message());
  const std::filesystem::path target = std::filesystem::weakly_canonical(folder / relative, ec);
  if (ec) p.fail(n, "cannot be resolved: " + ec.message());
  if (!inside(folder, target)) p.fail(n, "leads outside the asset's folder (through a symbolic link) to " + target.string());
  return target;
}

}  // namespace fovea::render::gltf::detail
