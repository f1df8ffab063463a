// SPDX-License-Identifier: Apache-2.0
#pragma once
// Gazepoint's Open Gaze API (version 2.0, the TCP protocol of Gazepoint Control / GP3 trackers;
// port 4242): the text it speaks, without any socket. Each message either way is one XML element
// on a line ending in "\r\n":
//   client: <SET ID="ENABLE_SEND_POG_BEST" STATE="1" />   <GET ID="SCREEN_SIZE" />
//   server: <ACK ID="ENABLE_SEND_POG_BEST" STATE="1" />   <NACK ID="..." />
//           <REC CNT="72" TIME="4.71323" BPOGX="0.51" BPOGY="0.48" BPOGV="1" ... />
// A line comes from a peer we do not trust: it is parsed strictly and bounded, and whatever does not
// parse is refused with the reason (counted by the source), never half-used.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace fovea::trackerd::gazepoint {

inline constexpr std::uint16_t kDefaultPort = 4242;
// Longer lines are refused unread (a REC with every field enabled is under 2 KB).
inline constexpr std::size_t kMaxLineBytes = 16 * 1024;

// "gazepoint:HOST[:PORT]": HOST an IPv4 address or a name; PORT 1..65535 (default 4242).
struct GazepointSpec {
  std::string host;
  std::uint16_t port = kDefaultPort;
  std::string to_string() const;  // "HOST:PORT"
};
// Throws std::invalid_argument naming the spec and the form it should have.
GazepointSpec parse_gazepoint_spec(const std::string& spec);
// Empty when `spec` parses, else the message (the source table's check).
std::string check_gazepoint_spec(const std::string& spec);

// One element: <NAME A="v" B="w" />. Attribute values are kept as text.
struct Element {
  std::string name;
  std::vector<std::pair<std::string, std::string>> attributes;
  const std::string* attribute(std::string_view key) const;  // nullptr when absent
};
// The element on `line` (without its line end), or nullopt with `error` saying what is wrong: not
// an element, a name or attribute that is not [A-Z0-9_], a value with '<', '&' or a control
// character, an attribute given twice, more than 64 attributes, a line over kMaxLineBytes.
std::optional<Element> parse_element(std::string_view line, std::string& error);

// The fields of a data record fovea reads; what was not sent is nullopt.
struct Record {
  std::optional<std::uint64_t> counter;  // CNT
  std::optional<double> time_s;          // TIME: the tracker's clock, seconds
  std::optional<std::int64_t> time_tick;  // TIME_TICK: the tracker host's high-resolution counter
  double best_x = 0, best_y = 0;          // BPOGX, BPOGY: fraction of the screen, origin top-left
  bool best_valid = false;                // BPOGV
  std::optional<double> left_pupil_mm, right_pupil_mm;  // LPUPILD, RPUPILD (metres on the wire), when valid
  // LPOGX/LPOGY, RPOGX/RPOGY: each eye's point of gaze, fraction of the screen, when LPOGV/RPOGV say
  // valid (ENABLE_SEND_POG_LEFT / _RIGHT); the best point above combines them.
  struct Point { double x = 0, y = 0; };
  std::optional<Point> left_pog, right_pog;
};
// A REC element as a record, or nullopt with `error`: BPOGX, BPOGY and BPOGV are required (fovea
// enables them); every number must parse whole and be finite; the point of gaze, valid or not, must
// lie within -1..2 screens (Gazepoint reports off-screen gaze a little outside 0..1, never farther,
// and 0, 0 when invalid); CNT and
// TIME_TICK are integers, TIME non-negative.
std::optional<Record> parse_record(const Element& rec, std::string& error);

// What fovea sends to start the stream, in order: counter, time, best point of gaze, eye data
// (pupil size), the screen size, then ENABLE_SEND_DATA. Each command ends in "\r\n".
std::vector<std::string> start_commands();

// "WIDTH x HEIGHT" of an <ACK ID="SCREEN_SIZE" ... />, when the element is one and its numbers parse.
std::optional<std::pair<std::uint32_t, std::uint32_t>> screen_size(const Element& ack);

}  // namespace fovea::trackerd::gazepoint
