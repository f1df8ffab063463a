// SPDX-License-Identifier: Apache-2.0
#pragma once
// Who fovea-monitor answers (MONITOR.md "Security"): every HTTP request must name, in its Host
// header, a name this monitor is reached by (DNS rebinding: a page of evil.example whose name
// later resolves to 127.0.0.1 still sends "Host: evil.example"); a WebSocket must come from a page
// of this monitor (its Origin, when a browser sends one: cross-site WebSocket hijacking) and carry
// the run's token. Pure functions, so that each rule is tested alone.
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace fovea::monitor {

struct HostPort {
  std::string host;  // lower case; an IPv6 literal without its brackets
  std::optional<std::uint16_t> port;
};

// "Host" header syntax (RFC 9110 §7.2: uri-host [":" port]); nullopt when malformed.
std::optional<HostPort> parse_host(std::string_view header);

struct AllowedHosts {
  // The names always accepted: the loopback names (localhost, 127.0.0.0/8 literals, ::1), with any
  // port (an SSH tunnel's local port differs from the monitor's), plus the listening address when
  // it is not loopback, and names given with --allow-host (exact, any port).
  std::vector<std::string> names;
  bool accepts(const HostPort& h) const;
};

AllowedHosts allowed_hosts(const std::string& listen_ip, const std::vector<std::string>& extra_names);

// The Host header is present, well formed and accepted.
bool host_allowed(std::string_view host_header, const AllowedHosts& allowed);

// A WebSocket's Origin: absent (not a browser: curl, scripts; they still need the token), or
// exactly "http://" + the request's own Host. "null" (sandboxed or file: pages) is refused.
bool origin_allowed(std::optional<std::string_view> origin, std::string_view host_header);

// The token from a request target "/ws?token=HEX" (other parameters ignored); empty when none.
std::string token_of(std::string_view target);
// Constant-time comparison (libsodium), false for different lengths or an empty token.
bool token_matches(std::string_view given, std::string_view expected);
// 128 random bits as 32 hex digits (libsodium's generator).
std::string new_token();

// The request target's path without the query ("/ws?token=x" -> "/ws").
std::string_view path_of(std::string_view target);

}  // namespace fovea::monitor
