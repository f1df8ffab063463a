// The synthetic source must look like a real viewer: main-sequence saccades, fixation durations,
// blinks, pursuit, and every value encodable (finite, in range).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>

#include "fovea/protocol/codec.h"
#include "sim/synthetic_gaze.h"

using namespace fovea;
using namespace fovea::trackerd;
using protocol::EventPhase;
using protocol::EyeMovement;
using protocol::GazeEvent;
using protocol::GazeSample;

namespace {
std::vector<GazeItem> generate(double rate, double seconds, std::uint64_t seed,
                               const SyntheticGazeOptions& base = {}) {
  SyntheticGazeOptions o = base;
  o.rate_hz = rate;
  o.seed = seed;
  SyntheticGaze g(o);
  std::vector<GazeItem> items;
  const auto end = static_cast<std::int64_t>(seconds * 1e9);
  while (true) {
    auto item = g.next();
    if (!item || due_time_ns(*item) > end) break;
    items.push_back(*item);
  }
  return items;
}
}  // namespace

TEST(SyntheticGaze, MainSequenceRelations) {
  EXPECT_NEAR(saccade_duration_s(10) * 1000, 43, 1e-9);
  EXPECT_LT(saccade_peak_velocity(40), 700);
  EXPECT_GT(saccade_peak_velocity(40), 500);
  EXPECT_LT(saccade_peak_velocity(2), saccade_peak_velocity(10));
}

TEST(SyntheticGaze, SameSeedSameStreamOtherSeedOtherStream) {
  const auto a = generate(250, 5, 3), b = generate(250, 5, 3), c = generate(250, 5, 4);
  EXPECT_EQ(a, b);
  EXPECT_NE(a, c);
}

TEST(SyntheticGaze, MovementsHaveRealisticStatistics) {
  const auto items = generate(1000, 120, 11);  // 1 kHz resolves saccade velocity profiles
  std::map<EyeMovement, int> ends;
  int saccades_checked = 0;
  double max_peak = 0;
  std::int64_t last_time = INT64_MIN;
  for (const auto& item : items) {
    const std::int64_t t = due_time_ns(item);
    EXPECT_GE(t, last_time) << "items must come in time order";
    last_time = t;
    if (const auto* s = std::get_if<GazeSample>(&item)) {
      EXPECT_NO_THROW(protocol::encode(protocol::Message{protocol::Header{}, *s}));
      continue;
    }
    const auto& e = std::get<GazeEvent>(item);
    EXPECT_NO_THROW(protocol::encode(protocol::Message{protocol::Header{}, e}));
    if (e.phase != EventPhase::End) continue;
    ++ends[e.kind];
    const double dur_ms = static_cast<double>(e.duration_ns) / 1e6;
    if (e.kind == EyeMovement::Fixation) {
      EXPECT_GE(dur_ms, 150 - 1);
      EXPECT_LE(dur_ms, 600 + 1);
    }
    if (e.kind == EyeMovement::Saccade) {
      const double a = static_cast<double>(e.amplitude_deg);
      EXPECT_NEAR(dur_ms, 2.2 * a + 21, 1.5) << "duration off the main sequence for " << a << " deg";
      const double peak = static_cast<double>(e.peak_velocity_deg_s);
      max_peak = std::max(max_peak, peak);
      EXPECT_LT(peak, 700) << a << " deg";
      EXPECT_NEAR(peak, saccade_peak_velocity(a), 0.2 * saccade_peak_velocity(a) + 10) << a << " deg";
      ++saccades_checked;
    }
    if (e.kind == EyeMovement::Blink) {
      EXPECT_GE(dur_ms, 99);
      EXPECT_LE(dur_ms, 301);
    }
  }
  EXPECT_GT(ends[EyeMovement::Fixation], 150);
  EXPECT_GT(saccades_checked, 100);
  EXPECT_GT(ends[EyeMovement::Blink], 3);
  EXPECT_GT(ends[EyeMovement::Pursuit], 3);
  EXPECT_GT(max_peak, 350) << "large saccades should approach the velocity saturation";
}

TEST(SyntheticGaze, BlinksInvalidateGazeAndGazeStaysOnScreen) {
  const auto items = generate(250, 60, 5);
  int blink_samples = 0, valid = 0;
  for (const auto& item : items) {
    const auto* s = std::get_if<GazeSample>(&item);
    if (s == nullptr) continue;
    if (s->state == EyeMovement::Blink) {
      ++blink_samples;
      EXPECT_EQ(s->flags & protocol::kGazeValid, 0);
      EXPECT_EQ(s->confidence, 0.0f);
    } else {
      ++valid;
      EXPECT_TRUE(s->flags & protocol::kGazeValid);
      EXPECT_GT(s->x, -0.05f);
      EXPECT_LT(s->x, 1.05f);
      EXPECT_GT(s->y, -0.05f);
      EXPECT_LT(s->y, 1.05f);
      EXPECT_GT(s->left.pupil_diameter_mm, 2.0f);
    }
  }
  EXPECT_GT(blink_samples, 0);
  EXPECT_EQ(blink_samples + valid, 60 * 250 + 1);
}

TEST(SyntheticGaze, HighRatesAndOddDisplaysStayFinite) {
  for (double rate : {30.0, 2000.0}) {
    SyntheticGazeOptions o;
    o.rate_hz = rate;
    o.display.width_m = 3.0;  // a wall-sized display at arm's length: wide angles
    o.display.viewing_distance_m = 0.3;
    SyntheticGaze g(o);
    for (int i = 0; i < 20000; ++i) {
      const auto item = g.next();
      ASSERT_TRUE(item);
      if (const auto* s = std::get_if<GazeSample>(&*item)) {
        ASSERT_NO_THROW(protocol::encode(protocol::Message{protocol::Header{}, *s})) << "rate " << rate;
      }
    }
  }
}

// Issue 25: the movements the plain model leaves out, each off by default.
namespace {
std::vector<GazeEvent> ends_of(const std::vector<GazeItem>& items) {
  std::vector<GazeEvent> out;
  for (const auto& it : items) {
    if (const auto* e = std::get_if<GazeEvent>(&it); e != nullptr && e->phase == EventPhase::End) out.push_back(*e);
  }
  return out;
}
}  // namespace

TEST(SyntheticGaze, MicrosaccadesComeAtTheirRateAndSize) {
  SyntheticGazeOptions o;
  o.microsaccades_per_s = 1.5;
  const auto ends = ends_of(generate(500, 300, 5, o));
  double fixation_s = 0;
  std::vector<double> small;
  for (const auto& e : ends) {
    if (e.kind == EyeMovement::Fixation) fixation_s += static_cast<double>(e.duration_ns) * 1e-9;
    if (e.kind == EyeMovement::Saccade && e.amplitude_deg < 0.9f) small.push_back(e.amplitude_deg);
  }
  const double rate = static_cast<double>(small.size()) / fixation_s;
  EXPECT_GT(rate, 1.0);
  EXPECT_LT(rate, 2.0);
  std::sort(small.begin(), small.end());
  EXPECT_NEAR(small[small.size() / 2], 0.3, 0.08) << "median amplitude";
  EXPECT_GE(small.front(), 0.09);
  for (const auto& e : ends_of(generate(500, 300, 5))) {
    if (e.kind == EyeMovement::Saccade) {
      EXPECT_GE(e.amplitude_deg, 0.9f) << "off by default: none under 1 deg (by the axes)";
    }
  }
}

TEST(SyntheticGaze, PursuitLagsAndCatchesUpWithSaccades) {
  SyntheticGazeOptions o;
  o.catch_up_saccades = true;
  const auto ends = ends_of(generate(500, 300, 6, o));
  int catch_ups = 0, pursuits = 0;
  for (std::size_t i = 1; i + 1 < ends.size(); ++i) {
    if (ends[i].kind == EyeMovement::Pursuit) {
      ++pursuits;
      EXPECT_LE(ends[i].duration_ns, 400'000'001) << "pursuit stretches of at most 400 ms";
    }
    if (ends[i].kind == EyeMovement::Saccade && ends[i - 1].kind == EyeMovement::Pursuit &&
        ends[i + 1].kind == EyeMovement::Pursuit) {
      ++catch_ups;
      EXPECT_LT(ends[i].amplitude_deg, 2.0f) << "a catch-up saccade makes up a lag of a few tenths of a degree";
    }
  }
  EXPECT_GT(pursuits, 50);
  EXPECT_GT(catch_ups, 20);
  for (const auto& e : ends_of(generate(500, 300, 6))) {
    if (e.kind == EyeMovement::Pursuit) {
      EXPECT_GE(e.duration_ns, 399'000'000) << "off by default: one stretch";
    }
  }
}
