// SPDX-License-Identifier: Apache-2.0
// Gazepoint's Open Gaze API as text (sources/gazepoint/open_gaze.h): what a record and an
// acknowledgement look like on the wire, and every way a hostile or broken server's line is refused.
#include <gtest/gtest.h>

#include <string>

#include "sources/gazepoint/open_gaze.h"

namespace fovea::trackerd::gazepoint {
namespace {

Element element(const std::string& line) {
  std::string error;
  const auto e = parse_element(line, error);
  EXPECT_TRUE(e) << line << ": " << error;
  return e.value_or(Element{});
}

std::string element_error(const std::string& line) {
  std::string error;
  EXPECT_FALSE(parse_element(line, error)) << line;
  return error;
}

std::string record_error(const std::string& line) {
  std::string error;
  const auto e = parse_element(line, error);
  if (!e) return error;
  EXPECT_FALSE(parse_record(*e, error)) << line;
  return error;
}

TEST(OpenGaze, ARecordAsGazepointControlSendsIt) {
  const Element e = element(
      R"(<REC CNT="72" TIME="4.71323" TIME_TICK="47132300" BPOGX="0.51234" BPOGY="0.25000" BPOGV="1" )"
      R"(LPUPILD="0.00412" LPUPILV="1" RPUPILD="0.00398" RPUPILV="0" />)");
  std::string error;
  const auto r = parse_record(e, error);
  ASSERT_TRUE(r) << error;
  EXPECT_EQ(r->counter, 72u);
  EXPECT_DOUBLE_EQ(*r->time_s, 4.71323);
  EXPECT_EQ(r->time_tick, 47132300);
  // Fractions of the screen, origin top-left, y down: fovea's normalised coordinates unchanged.
  EXPECT_DOUBLE_EQ(r->best_x, 0.51234);
  EXPECT_DOUBLE_EQ(r->best_y, 0.25);
  EXPECT_TRUE(r->best_valid);
  ASSERT_TRUE(r->left_pupil_mm);
  EXPECT_NEAR(*r->left_pupil_mm, 4.12, 1e-9);  // metres on the wire
  EXPECT_FALSE(r->right_pupil_mm) << "RPUPILV=0";
}

TEST(OpenGaze, WhitespaceAndAnInvalidPointAreFine) {
  const Element e = element("  <REC BPOGX=\"0.00000\"\tBPOGY=\"0.00000\" BPOGV=\"0\"/>");
  std::string error;
  const auto r = parse_record(e, error);
  ASSERT_TRUE(r) << error;
  EXPECT_FALSE(r->best_valid);
  EXPECT_FALSE(r->counter);
  EXPECT_FALSE(r->time_s);
}

TEST(OpenGaze, LinesThatAreNotElementsAreRefusedWithTheReason) {
  EXPECT_NE(element_error("garbage\x01\x02").find("not an XML element"), std::string::npos);
  EXPECT_NE(element_error("<REC CNT=\"1\" BPOGX=\"0.5\"").find("does not end"), std::string::npos);
  EXPECT_NE(element_error("<REC CNT=1 />").find("no quoted value"), std::string::npos);
  EXPECT_NE(element_error("<REC CNT=\"1 />").find("does not end"), std::string::npos);
  EXPECT_NE(element_error("<REC CNT=\"1\" CNT=\"2\" />").find("twice"), std::string::npos);
  EXPECT_NE(element_error("<REC A=\"x\ny\" />").find("not allowed"), std::string::npos);
  EXPECT_NE(element_error("<REC A=\"<b>\" />").find("not allowed"), std::string::npos);
  EXPECT_NE(element_error("<REC A=\"1\"B=\"2\" />").find("no space"), std::string::npos);
  EXPECT_NE(element_error("<REC /> trailing").find("after the element"), std::string::npos);
  EXPECT_NE(element_error("<rec />").find("without a name"), std::string::npos);
  EXPECT_NE(element_error("<REC " + std::string(kMaxLineBytes, 'A') + " />").find("bytes"), std::string::npos);
  std::string many = "<REC";
  for (int i = 0; i < 65; ++i) many += " A" + std::to_string(i) + "=\"1\"";
  EXPECT_NE(element_error(many + " />").find("more than 64"), std::string::npos);
}

TEST(OpenGaze, RecordsWithBadValuesAreRefusedNeverHalfUsed) {
  EXPECT_NE(record_error(R"(<REC BPOGX="nan" BPOGY="0.5" BPOGV="1" />)").find("BPOGX=\"nan\" is not a finite number"),
            std::string::npos);
  EXPECT_NE(record_error(R"(<REC BPOGX="abc" BPOGY="0.5" BPOGV="1" />)").find("not a finite number"), std::string::npos);
  EXPECT_NE(record_error(R"(<REC BPOGX="0.5 " BPOGY="0.5" BPOGV="1" />)").find("not a finite number"), std::string::npos);
  EXPECT_NE(record_error(R"(<REC BPOGX="1e308" BPOGY="0.5" BPOGV="1" />)").find("beyond"), std::string::npos);
  EXPECT_NE(record_error(R"(<REC BPOGX="1e999" BPOGY="0.5" BPOGV="1" />)").find("not a finite"), std::string::npos);
  EXPECT_NE(record_error(R"(<REC BPOGX="0" BPOGY="-1e308" BPOGV="0" />)").find("beyond"), std::string::npos)
      << "an invalid point is no licence for junk";
  EXPECT_NE(record_error(R"(<REC BPOGX="0.5" BPOGV="1" />)").find("required"), std::string::npos);
  EXPECT_NE(record_error(R"(<REC BPOGX="0.5" BPOGY="0.5" BPOGV="2" />)").find("not 0 or 1"), std::string::npos);
  EXPECT_NE(record_error(R"(<REC CNT="-1" BPOGX="0.5" BPOGY="0.5" BPOGV="1" />)").find("CNT"), std::string::npos);
  EXPECT_NE(record_error(R"(<REC TIME="-3" BPOGX="0.5" BPOGY="0.5" BPOGV="1" />)").find("TIME"), std::string::npos);
  EXPECT_NE(record_error(R"(<REC TIME_TICK="1.5" BPOGX="0.5" BPOGY="0.5" BPOGV="1" />)").find("TIME_TICK"),
            std::string::npos);
  EXPECT_NE(record_error(R"(<ACK ID="X" />)").find("not a data record"), std::string::npos);
  // Off-screen gaze a little outside 0..1 is what the tracker reports: kept.
  std::string error;
  EXPECT_TRUE(parse_record(element(R"(<REC BPOGX="-0.2" BPOGY="1.3" BPOGV="1" />)"), error)) << error;
}

// Each eye's point of gaze (ENABLE_SEND_POG_LEFT / _RIGHT), the stereo renderer's per-eye gaze:
// kept when its V flag says valid, absent otherwise, refused when beyond -1..2 screens or malformed.
TEST(OpenGaze, EachEyesPointOfGaze) {
  std::string error;
  const auto r = parse_record(element(R"(<REC BPOGX="0.50000" BPOGY="0.25000" BPOGV="1" LPOGX="0.48000" )"
                                      R"(LPOGY="0.25100" LPOGV="1" RPOGX="0.52000" RPOGY="0.24900" RPOGV="0" />)"),
                              error);
  ASSERT_TRUE(r) << error;
  ASSERT_TRUE(r->left_pog);
  EXPECT_DOUBLE_EQ(r->left_pog->x, 0.48);
  EXPECT_DOUBLE_EQ(r->left_pog->y, 0.251);
  EXPECT_FALSE(r->right_pog) << "RPOGV=0";
  const auto monocular = parse_record(element(R"(<REC BPOGX="0.5" BPOGY="0.5" BPOGV="1" />)"), error);
  ASSERT_TRUE(monocular);
  EXPECT_FALSE(monocular->left_pog || monocular->right_pog) << "a tracker not sending them: the best point only";
  EXPECT_NE(record_error(R"(<REC BPOGX="0.5" BPOGY="0.5" BPOGV="1" LPOGX="7" LPOGY="0.5" LPOGV="1" />)").find("LPOGX, LPOGY"),
            std::string::npos);
  EXPECT_NE(record_error(R"(<REC BPOGX="0.5" BPOGY="0.5" BPOGV="1" RPOGX="x" RPOGY="0.5" RPOGV="1" />)").find("RPOGX"),
            std::string::npos);
  EXPECT_NE(record_error(R"(<REC BPOGX="0.5" BPOGY="0.5" BPOGV="1" RPOGX="0.5" RPOGY="0.5" RPOGV="yes" />)").find("RPOGV"),
            std::string::npos);
}

TEST(OpenGaze, ScreenSizeAndStartCommands) {
  const auto size = screen_size(element(R"(<ACK ID="SCREEN_SIZE" X="0" Y="0" WIDTH="2560" HEIGHT="1440" />)"));
  ASSERT_TRUE(size);
  EXPECT_EQ(size->first, 2560u);
  EXPECT_EQ(size->second, 1440u);
  EXPECT_FALSE(screen_size(element(R"(<ACK ID="SCREEN_SIZE" WIDTH="0" HEIGHT="1440" />)")));
  EXPECT_FALSE(screen_size(element(R"(<ACK ID="ENABLE_SEND_DATA" STATE="1" />)")));
  const auto commands = start_commands();
  ASSERT_FALSE(commands.empty());
  EXPECT_EQ(commands.back(), "<SET ID=\"ENABLE_SEND_DATA\" STATE=\"1\" />\r\n") << "data last, once all is enabled";
  bool best = false, left = false, right = false;
  for (const auto& c : commands) {
    best |= c == "<SET ID=\"ENABLE_SEND_POG_BEST\" STATE=\"1\" />\r\n";
    left |= c == "<SET ID=\"ENABLE_SEND_POG_LEFT\" STATE=\"1\" />\r\n";
    right |= c == "<SET ID=\"ENABLE_SEND_POG_RIGHT\" STATE=\"1\" />\r\n";
    EXPECT_EQ(c.substr(c.size() - 2), "\r\n");
  }
  EXPECT_TRUE(best);
  EXPECT_TRUE(left && right) << "each eye's point of gaze, for stereo displays";
}

TEST(OpenGaze, SourceSpecs) {
  EXPECT_EQ(parse_gazepoint_spec("gazepoint:127.0.0.1").to_string(), "127.0.0.1:4242");
  EXPECT_EQ(parse_gazepoint_spec("gazepoint:tracker-pc.lab:4300").to_string(), "tracker-pc.lab:4300");
  for (const char* bad : {"gazepoint:", "gazepoint::4242", "gazepoint:host:0", "gazepoint:host:70000",
                          "gazepoint:host:x", "gazepoint:ho st", "gazepoint:a/b"}) {
    const std::string msg = check_gazepoint_spec(bad);
    EXPECT_NE(msg.find("expected gazepoint:HOST[:PORT]"), std::string::npos) << bad << ": " << msg;
  }
  EXPECT_EQ(check_gazepoint_spec("gazepoint:192.168.1.20:4242"), "");
}

}  // namespace
}  // namespace fovea::trackerd::gazepoint
