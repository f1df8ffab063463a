// SPDX-License-Identifier: Apache-2.0
#include "request_checks.h"

#include <sodium.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <stdexcept>

namespace fovea::monitor {

namespace {

std::string lower(std::string_view s) {
  std::string out(s);
  std::transform(out.begin(), out.end(), out.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return out;
}

// reg-name / IPv4 characters (RFC 3986 unreserved and sub-delims minus those never seen in a host).
bool host_char(char c) {
  return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '-' || c == '.' || c == '_' || c == '~';
}

bool loopback_name(const std::string& h) {
  if (h == "localhost" || h == "::1" || h == "0:0:0:0:0:0:0:1") return true;
  // 127.0.0.0/8 as a dotted quad.
  int parts = 0;
  std::size_t i = 0;
  int first = -1;
  while (i <= h.size()) {
    const std::size_t dot = std::min(h.find('.', i), h.size());
    int v = -1;
    const auto [p, ec] = std::from_chars(h.data() + i, h.data() + dot, v);
    if (ec != std::errc() || p != h.data() + dot || dot == i || dot - i > 3 || v < 0 || v > 255) return false;
    if (parts == 0) first = v;
    ++parts;
    i = dot + 1;
  }
  return parts == 4 && first == 127;
}

}  // namespace

std::optional<HostPort> parse_host(std::string_view header) {
  if (header.empty() || header.size() > 255) return std::nullopt;
  HostPort out;
  std::string_view rest;
  if (header.front() == '[') {
    const std::size_t close = header.find(']');
    if (close == std::string_view::npos || close == 1) return std::nullopt;
    const std::string_view inside = header.substr(1, close - 1);
    if (!std::all_of(inside.begin(), inside.end(), [](char c) { return std::isxdigit(static_cast<unsigned char>(c)) != 0 || c == ':' || c == '.'; }))
      return std::nullopt;
    out.host = lower(inside);
    rest = header.substr(close + 1);
  } else {
    const std::size_t colon = header.find(':');
    const std::string_view name = header.substr(0, colon);
    if (name.empty() || !std::all_of(name.begin(), name.end(), host_char)) return std::nullopt;
    out.host = lower(name);
    rest = colon == std::string_view::npos ? std::string_view() : header.substr(colon);
  }
  if (!rest.empty()) {
    if (rest.front() != ':' || rest.size() < 2 || rest.size() > 6) return std::nullopt;
    unsigned v = 0;
    const auto [p, ec] = std::from_chars(rest.data() + 1, rest.data() + rest.size(), v);
    if (ec != std::errc() || p != rest.data() + rest.size() || v == 0 || v > 65535) return std::nullopt;
    out.port = static_cast<std::uint16_t>(v);
  }
  return out;
}

bool AllowedHosts::accepts(const HostPort& h) const {
  return loopback_name(h.host) || std::find(names.begin(), names.end(), h.host) != names.end();
}

AllowedHosts allowed_hosts(const std::string& listen_ip, const std::vector<std::string>& extra_names) {
  AllowedHosts a;
  if (!listen_ip.empty() && listen_ip != "0.0.0.0" && !loopback_name(lower(listen_ip))) a.names.push_back(lower(listen_ip));
  for (const std::string& n : extra_names) {
    const auto parsed = parse_host(n);
    if (!parsed || parsed->port) throw std::invalid_argument("--allow-host \"" + n + "\": a host name or address without a port is needed");
    a.names.push_back(parsed->host);
  }
  return a;
}

bool host_allowed(std::string_view host_header, const AllowedHosts& allowed) {
  const auto h = parse_host(host_header);
  return h && allowed.accepts(*h);
}

bool origin_allowed(std::optional<std::string_view> origin, std::string_view host_header) {
  if (!origin) return true;
  const std::string_view scheme = "http://";
  if (origin->size() <= scheme.size() || lower(origin->substr(0, scheme.size())) != scheme) return false;
  const auto from = parse_host(origin->substr(scheme.size()));
  const auto to = parse_host(host_header);
  return from && to && from->host == to->host && from->port == to->port;
}

std::string_view path_of(std::string_view target) { return target.substr(0, target.find('?')); }

std::string token_of(std::string_view target) {
  const std::size_t q = target.find('?');
  if (q == std::string_view::npos) return {};
  std::string_view query = target.substr(q + 1);
  while (!query.empty()) {
    const std::size_t amp = query.find('&');
    const std::string_view pair = query.substr(0, amp);
    if (pair.substr(0, 6) == "token=") return std::string(pair.substr(6));
    if (amp == std::string_view::npos) break;
    query = query.substr(amp + 1);
  }
  return {};
}

bool token_matches(std::string_view given, std::string_view expected) {
  if (expected.empty() || given.size() != expected.size()) return false;
  return sodium_memcmp(given.data(), expected.data(), expected.size()) == 0;
}

std::string new_token() {
  if (sodium_init() < 0) throw std::runtime_error("libsodium could not be initialised");
  unsigned char raw[16];
  randombytes_buf(raw, sizeof raw);
  char hex[2 * sizeof raw + 1];
  sodium_bin2hex(hex, sizeof hex, raw, sizeof raw);
  return hex;
}

}  // namespace fovea::monitor
