// SPDX-License-Identifier: Apache-2.0
// The parts of the LSL source and outlet that need no liblsl: the lsl: spec with its confidence
// threshold (a documented default where the stream has confidence, min_confidence=0 to turn it off),
// the channel formats that cannot carry gaze, and the events stream's text format.
#include <gtest/gtest.h>

#include <regex>
#include <stdexcept>

#include "lsl/lsl_outlet.h"
#include "sources/lsl/lsl_source.h"

namespace {

using namespace fovea::trackerd;
using lsl_source::effective_min_confidence;
using lsl_source::parse_lsl_spec;

TEST(LslSpec, ConfidenceIsGatedByDefaultOnlyWhereTheStreamHasIt) {
  const auto plain = parse_lsl_spec("lsl:Tobii");
  EXPECT_FALSE(plain.min_confidence.has_value());
  EXPECT_EQ(effective_min_confidence(plain, true), lsl_source::kDefaultMinConfidence);
  EXPECT_EQ(lsl_source::kDefaultMinConfidence, 0.6);
  EXPECT_EQ(effective_min_confidence(plain, false), 0.0);
  const auto off = parse_lsl_spec("lsl:Tobii?min_confidence=0");
  ASSERT_TRUE(off.min_confidence.has_value());
  EXPECT_EQ(effective_min_confidence(off, true), 0.0);
  EXPECT_EQ(effective_min_confidence(parse_lsl_spec("lsl?min_confidence=0.8"), true), 0.8);
}

TEST(LslSpec, SaysTheThresholdAsWrittenIncludingZero) {
  EXPECT_EQ(parse_lsl_spec("lsl:Tobii?min_confidence=0").to_string(), "lsl:Tobii?min_confidence=0");
  EXPECT_EQ(parse_lsl_spec("lsl:Tobii?x=0&y=1&units=pixels&min_confidence=0.25").to_string(),
            "lsl:Tobii?x=0&y=1&units=pixels&min_confidence=0.25");
  EXPECT_EQ(parse_lsl_spec("lsl:Tobii").to_string(), "lsl:Tobii");
}

TEST(LslSpec, ABadThresholdIsNamed) {
  for (const char* bad : {"lsl?min_confidence=1.5", "lsl?min_confidence=-0.1", "lsl?min_confidence=nan",
                          "lsl?min_confidence=", "lsl?min_confidence=0.5x"}) {
    try {
      parse_lsl_spec(bad);
      ADD_FAILURE() << bad << " was accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("min_confidence="), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
    }
  }
}

TEST(LslSpec, FormatsThatCannotCarryGazeAreNamed) {
  for (const int numeric : {1, 2, 4, 5, 6, 7}) EXPECT_EQ(lsl_source::unusable_channel_format(numeric), "") << numeric;
  EXPECT_NE(lsl_source::unusable_channel_format(3).find("strings (channel format string)"), std::string::npos);
  EXPECT_NE(lsl_source::unusable_channel_format(0).find("undefined"), std::string::npos);
  EXPECT_NE(lsl_source::unusable_channel_format(42).find("42"), std::string::npos);
}

TEST(LslEvents, TextsFollowTheDocumentedFormat) {
  fovea::protocol::GazeEvent e;
  e.kind = fovea::protocol::EyeMovement::Saccade;
  e.phase = fovea::protocol::EventPhase::Start;
  e.centroid_x = 0.48123f;
  e.centroid_y = 0.52104f;
  EXPECT_EQ(lsl_event_text(e), "saccade start x=0.4812 y=0.5210");
  e.phase = fovea::protocol::EventPhase::End;
  e.duration_ns = 42'000'000;
  e.amplitude_deg = 5.123f;
  e.peak_velocity_deg_s = 310.2f;
  EXPECT_EQ(lsl_event_text(e), "saccade end duration_ms=42.0 amplitude_deg=5.12 peak_velocity_deg_s=310 x=0.4812 y=0.5210");
  e.kind = fovea::protocol::EyeMovement::Pursuit;
  EXPECT_TRUE(lsl_event_text(e).starts_with("pursuit end "));
  EXPECT_NE(std::string(kLslEventFormat).find("KIND PHASE"), std::string::npos);
}

}  // namespace
