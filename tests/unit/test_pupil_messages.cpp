// SPDX-License-Identifier: Apache-2.0
// Pupil Core's network API as data (sources/pupil/pupil_messages.h): the spec, the surface and gaze
// payloads as Pupil Capture packs them, and every way a hostile publisher's payload is refused.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <msgpack.hpp>
#include <string>
#include <vector>

#include "sources/pupil/pupil_messages.h"

namespace fovea::trackerd::pupil {
namespace {

using Bytes = std::vector<std::uint8_t>;

Bytes bytes(const msgpack::sbuffer& b) { return Bytes(b.data(), b.data() + b.size()); }

// A gaze entry as Pupil packs it (map with string keys; on_surf only on surfaces).
void pack_gaze(msgpack::packer<msgpack::sbuffer>& p, double x, double y, double conf, double t, int on_surf = -1) {
  p.pack_map(on_surf >= 0 ? 5 : 4);
  p.pack("topic"), p.pack("gaze.3d.01.");
  p.pack("norm_pos"), p.pack_array(2), p.pack(x), p.pack(y);
  p.pack("confidence"), p.pack(conf);
  p.pack("timestamp"), p.pack(t);
  if (on_surf >= 0) p.pack("on_surf"), p.pack(on_surf == 1);
}

Bytes surface(const std::string& name, const std::vector<std::array<double, 4>>& gaze, int on_surf = 1) {
  msgpack::sbuffer b;
  msgpack::packer<msgpack::sbuffer> p(b);
  p.pack_map(3);
  p.pack("name"), p.pack(name);
  p.pack("timestamp"), p.pack(1.0);
  p.pack("gaze_on_surfaces"), p.pack_array(static_cast<std::uint32_t>(gaze.size()));
  for (const auto& g : gaze) pack_gaze(p, g[0], g[1], g[2], g[3], on_surf);
  return bytes(b);
}

std::string gaze_error(const Bytes& payload) {
  std::string error;
  EXPECT_FALSE(parse_gaze_payload(payload, error));
  return error;
}

TEST(PupilMessages, SurfaceGazeAsPupilCaptureSendsIt) {
  std::string error;
  const auto g = parse_surface_payload(surface("screen", {{0.25, 0.75, 0.97, 5000.5}, {1.2, 0.5, 0.4, 5000.505}}, 1),
                                       "screen", error);
  ASSERT_TRUE(g) << error;
  ASSERT_EQ(g->size(), 2u);
  EXPECT_DOUBLE_EQ((*g)[0].x, 0.25);
  EXPECT_DOUBLE_EQ((*g)[0].y_up, 0.75);  // Pupil's y points up: the source flips it
  EXPECT_DOUBLE_EQ((*g)[0].confidence, 0.97);
  EXPECT_DOUBLE_EQ((*g)[1].timestamp, 5000.505);
  EXPECT_TRUE((*g)[0].on_surface);
  // Another surface's event is not the screen's.
  EXPECT_FALSE(parse_surface_payload(surface("table", {}), "screen", error));
  EXPECT_NE(error.find("not the surface \"screen\""), std::string::npos) << error;
  // No gaze on the surface since the last world frame: an empty list, fine.
  const auto none = parse_surface_payload(surface("screen", {}), "screen", error);
  ASSERT_TRUE(none) << error;
  EXPECT_TRUE(none->empty());
}

TEST(PupilMessages, SceneGazeDatum) {
  msgpack::sbuffer b;
  msgpack::packer<msgpack::sbuffer> p(b);
  pack_gaze(p, 0.4, 0.6, 0.9, 7.25);
  std::string error;
  const auto g = parse_gaze_payload(bytes(b), error);
  ASSERT_TRUE(g) << error;
  EXPECT_DOUBLE_EQ(g->x, 0.4);
  EXPECT_DOUBLE_EQ(g->timestamp, 7.25);
}

TEST(PupilMessages, HostilePayloadsAreRefusedWhole) {
  EXPECT_NE(gaze_error(Bytes{0xc1, 0x00, 0x01}).find("not msgpack"), std::string::npos);
  EXPECT_NE(gaze_error(Bytes{0x93, 0x01, 0x02, 0x03}).find("not a map"), std::string::npos);  // [1, 2, 3]
  EXPECT_NE(gaze_error(Bytes{0x2a}).find("not a map"), std::string::npos);                    // 42
  EXPECT_NE(gaze_error(Bytes(kMaxPayloadBytes + 1, 0x80)).find("at most"), std::string::npos);
  const auto field = [](const char* key, auto value, bool with_pos = true) {
    msgpack::sbuffer b;
    msgpack::packer<msgpack::sbuffer> p(b);
    p.pack_map(with_pos ? 3 : 2);
    if (with_pos) p.pack("norm_pos"), p.pack_array(2), p.pack(0.5), p.pack(0.5);
    p.pack("timestamp"), p.pack(1.0);
    p.pack(key), p.pack(value);
    return bytes(b);
  };
  EXPECT_NE(gaze_error(field("confidence", 0.9, false)).find("norm_pos is missing"), std::string::npos);
  EXPECT_NE(gaze_error(field("confidence", std::numeric_limits<double>::quiet_NaN())).find("confidence"),
            std::string::npos);
  EXPECT_NE(gaze_error(field("confidence", 7.0)).find("confidence"), std::string::npos);
  EXPECT_NE(gaze_error(field("confidence", std::string("high"))).find("confidence"), std::string::npos);
  msgpack::sbuffer b;
  msgpack::packer<msgpack::sbuffer> p(b);
  p.pack_map(3);
  p.pack("norm_pos"), p.pack_array(1), p.pack(0.5);
  p.pack("confidence"), p.pack(0.9);
  p.pack("timestamp"), p.pack(1.0);
  EXPECT_NE(gaze_error(bytes(b)).find("norm_pos is not [x, y]"), std::string::npos);
  // Trailing bytes after the object, a surface whose gaze is not a list, deep nesting.
  Bytes trailing = surface("screen", {});
  trailing.push_back(0x00);
  std::string error;
  EXPECT_FALSE(parse_surface_payload(trailing, "screen", error));
  EXPECT_NE(error.find("bytes after"), std::string::npos) << error;
  msgpack::sbuffer s;
  msgpack::packer<msgpack::sbuffer> sp(s);
  sp.pack_map(2), sp.pack("name"), sp.pack("screen"), sp.pack("gaze_on_surfaces"), sp.pack_map(0);
  EXPECT_FALSE(parse_surface_payload(bytes(s), "screen", error));
  EXPECT_NE(error.find("not a list"), std::string::npos) << error;
  Bytes deep(100, 0x91);  // [[[[...]]]] a hundred levels
  deep.push_back(0x00);
  EXPECT_FALSE(parse_gaze_payload(deep, error));
}

TEST(PupilMessages, SpecsAndRemoteReplies) {
  const PupilSpec d = parse_pupil_spec("pupil:127.0.0.1");
  EXPECT_EQ(d.to_string(), "127.0.0.1:50020");
  EXPECT_EQ(d.surface, "screen");
  EXPECT_DOUBLE_EQ(d.min_confidence, 0.6);
  const PupilSpec s = parse_pupil_spec("pupil:capture-pc:50030?surface=monitor&min_confidence=0.8");
  EXPECT_EQ(s.to_string(), "capture-pc:50030");
  EXPECT_EQ(s.surface, "monitor");
  EXPECT_DOUBLE_EQ(s.min_confidence, 0.8);
  EXPECT_FALSE(s.scene_gaze);
  EXPECT_TRUE(parse_pupil_spec("pupil:127.0.0.1?gaze=scene&min_confidence=0.7").scene_gaze);
  EXPECT_FALSE(parse_pupil_spec("pupil:127.0.0.1?gaze=surface").scene_gaze);
  EXPECT_NE(check_pupil_spec("pupil:h?gaze=scene&surface=monitor").find("gaze=scene uses no surface"), std::string::npos);
  for (const char* bad : {"pupil:", "pupil:h:0", "pupil:h:x", "pupil:h?min_confidence=2", "pupil:h?colour=red",
                          "pupil:h?surface=", "pupil:a b", "pupil:h?gaze=eye", "pupil:h?gaze="}) {
    EXPECT_NE(check_pupil_spec(bad).find("expected pupil:HOST"), std::string::npos) << bad;
  }
  EXPECT_EQ(parse_port_reply("50021"), 50021);
  EXPECT_FALSE(parse_port_reply("0"));
  EXPECT_FALSE(parse_port_reply("50021 "));
  EXPECT_FALSE(parse_port_reply("Unknown command."));
  EXPECT_DOUBLE_EQ(*parse_time_reply("5000.123456"), 5000.123456);
  EXPECT_FALSE(parse_time_reply("nan"));
  EXPECT_FALSE(parse_time_reply("1e300"));
  EXPECT_FALSE(parse_time_reply(""));
}

}  // namespace
}  // namespace fovea::trackerd::pupil
