// SPDX-License-Identifier: Apache-2.0
// The arrival rules of the network sources (trackerd/sources/arrival_guard.h): the cap at 4x the
// declared rate with a second of backlog allowed, the flood's start and end, the counts, and times
// from the future.
#include "sources/arrival_guard.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

namespace fovea::trackerd::net {
namespace {

constexpr std::int64_t kS = 1'000'000'000;
constexpr std::int64_t kT0 = 1000 * kS;  // arrival times start here

struct Tally {
  int kept = 0, dropped = 0, began = 0, kept_flooding = 0;
};

// `n` arrivals at `rate_hz` from `start_ns`; returns the time after the last.
std::int64_t arrive(ArrivalGuard& g, std::int64_t start_ns, int n, double rate_hz, Tally& t) {
  std::int64_t now = start_ns;
  for (int i = 0; i < n; ++i) {
    now = start_ns + static_cast<std::int64_t>(std::llround(i * 1e9 / rate_hz));
    const ArrivalGuard::Admission a = g.admit(now);
    (a.keep ? t.kept : t.dropped) += 1;
    if (a.flood_began) ++t.began;
    if (a.keep && a.flooding) ++t.kept_flooding;
  }
  return now;
}

TEST(ArrivalGuard, ASourceAtItsDeclaredRateLosesNothing) {
  ArrivalGuard g(150);
  Tally t;
  arrive(g, kT0, 1500, 150, t);
  EXPECT_EQ(t.kept, 1500);
  EXPECT_EQ(t.dropped, 0);
  EXPECT_EQ(g.status(), "");
  // Three times over still passes: the cap is four times the declared rate.
  arrive(g, kT0 + 20 * kS, 4500, 450, t);
  EXPECT_EQ(t.dropped, 0);
}

TEST(ArrivalGuard, ASecondOfBacklogDeliveredAtOncePassesWhole) {
  ArrivalGuard g(150);
  Tally t;
  const std::int64_t end = arrive(g, kT0, 300, 150, t);
  // TCP held a second of records during a stall and delivers them in one read.
  const std::int64_t burst = end + kS;
  for (int i = 0; i < 150; ++i) {
    const ArrivalGuard::Admission a = g.admit(burst);
    EXPECT_TRUE(a.keep) << i;
    EXPECT_FALSE(a.flooding) << i;
    EXPECT_EQ(a.within_pace, i == 0) << i;  // the burst emptied the bucket
  }
  arrive(g, burst + kS / 150, 300, 150, t);
  EXPECT_EQ(t.dropped, 0);
  EXPECT_EQ(g.stats().floods, 0u);
}

TEST(ArrivalGuard, ASustainedHundredfoldFloodIsPublishedAtFourTimesTheDeclaredRate) {
  ArrivalGuard g(150);
  g.set_name("gazepoint:test");
  Tally t;
  arrive(g, kT0, 150, 150, t);
  const int before = t.kept;
  // 5 s at 15000/s: the bucket's 150, then 600/s.
  arrive(g, kT0 + 2 * kS, 5 * 15000, 15000, t);
  const int kept = t.kept - before;
  EXPECT_NEAR(kept, 150 + 5 * 600, 3);
  EXPECT_EQ(t.dropped, 5 * 15000 - kept);
  EXPECT_EQ(t.began, 1);
  // The bucket's 150 and the 6 tokens that came back meanwhile went before the first drop.
  EXPECT_NEAR(t.kept_flooding, kept - 156, 1);
  const ArrivalGuard::Stats s = g.stats();
  EXPECT_TRUE(s.flooding);
  EXPECT_NEAR(s.arrival_rate_hz, 15000, 150);
  EXPECT_EQ(s.dropped, static_cast<std::uint64_t>(t.dropped));
  EXPECT_EQ(s.floods, 1u);
  EXPECT_EQ(g.cap_hz(), 600);
  EXPECT_EQ(g.status(), ", FLOODING: 15000/s against 150 Hz declared, publishing at most 600/s, " +
                            std::to_string(t.dropped) + " dropped over the 4x cap in 1 flood");
}

TEST(ArrivalGuard, TheSamplesKeptAreTheFirstToArriveWithinThePace) {
  ArrivalGuard g(100);
  std::vector<bool> kept;
  for (int i = 0; i < 1000; ++i) kept.push_back(g.admit(kT0 + i * 100'000).keep);  // 10000/s
  std::size_t first_drop = 0;
  while (kept[first_drop]) ++first_drop;
  EXPECT_EQ(first_drop, 104u);  // the whole bucket first, and the 4 tokens back meanwhile
  // Then one in 25: 400/s of the 10000/s, each the first to arrive after a token came back.
  std::size_t last = 0;
  int later = 0;
  for (std::size_t i = first_drop; i < kept.size(); ++i) {
    if (!kept[i]) continue;
    if (last > 0) {
      EXPECT_NEAR(static_cast<double>(i - last), 25, 1) << i;
    }
    last = i;
    ++later;
  }
  EXPECT_NEAR(later, 896 / 25, 1);
}

TEST(ArrivalGuard, AFloodEndsAfterASecondWithoutADropAndIsCountedOnce) {
  ArrivalGuard g(150);
  Tally t;
  std::int64_t now = arrive(g, kT0, 3000, 3000, t);  // 1 s at 20x
  ASSERT_TRUE(g.stats().flooding);
  const std::uint64_t dropped = g.stats().dropped;
  // Back to 150 Hz: nothing dropped; the flood lasts until a second after its last drop.
  bool ended = false;
  for (int i = 1; i <= 300; ++i) {
    const ArrivalGuard::Admission a = g.admit(now + i * kS / 150);
    EXPECT_TRUE(a.keep);
    if (i < 148) {
      EXPECT_TRUE(a.flooding) << i;  // stamped on arrival until the flood is over
    } else if (i > 152) {
      EXPECT_FALSE(a.flooding) << i;
    }
    ended = ended || !a.flooding;
  }
  EXPECT_TRUE(ended);
  const ArrivalGuard::Stats s = g.stats();
  EXPECT_FALSE(s.flooding);
  EXPECT_EQ(s.dropped, dropped);
  EXPECT_EQ(g.status(), ", " + std::to_string(dropped) + " dropped over the 4x cap in 1 flood");
  // A second flood is counted as such.
  now += 10 * kS;
  arrive(g, now, 3000, 3000, t);
  EXPECT_EQ(t.began, 2);
  EXPECT_EQ(g.stats().floods, 2u);
  EXPECT_NE(g.status().find(" dropped over the 4x cap in 2 floods"), std::string::npos) << g.status();
}

TEST(ArrivalGuard, AFloodThatFallsSilentEndsByPoll) {
  ArrivalGuard g(60);
  Tally t;
  const std::int64_t end = arrive(g, kT0, 2000, 10000, t);
  ASSERT_TRUE(g.stats().flooding);
  g.poll(end + kS / 2);
  EXPECT_TRUE(g.stats().flooding);
  g.poll(end + kS);
  EXPECT_FALSE(g.stats().flooding);
  EXPECT_EQ(g.status().find("FLOODING"), std::string::npos);
}

TEST(ArrivalGuard, ASlowSourceStillHasABurstOfSixteen) {
  ArrivalGuard g(1);
  int kept = 0;
  for (int i = 0; i < 40; ++i) kept += g.admit(kT0).keep ? 1 : 0;
  EXPECT_EQ(kept, 16);
}

TEST(ArrivalGuard, WithoutADeclaredRateNothingIsCapped) {
  for (const double rate : {0.0, -5.0, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
    ArrivalGuard g(rate);
    Tally t;
    arrive(g, kT0, 10000, 1e6, t);
    EXPECT_EQ(t.dropped, 0) << rate;
    EXPECT_EQ(g.cap_hz(), 0) << rate;
    EXPECT_EQ(g.status(), "") << rate;
  }
}

TEST(ArrivalGuard, ArrivalTimesThatStepBackRefillNothing) {
  ArrivalGuard g(100);
  int kept = 0;
  for (int i = 0; i < 300; ++i) kept += g.admit(kT0 - i * kS).keep ? 1 : 0;  // a hostile clock
  EXPECT_EQ(kept, 100);
}

TEST(ArrivalGuard, TimesFromTheFutureAreStampedOnArrivalAndCounted) {
  ArrivalGuard g(200);
  const std::int64_t arrived = kT0;
  EXPECT_EQ(g.not_after_arrival(arrived - 15'000'000, arrived), arrived - 15'000'000);
  EXPECT_EQ(g.not_after_arrival(arrived, arrived), arrived);  // taken as it arrived: not later
  EXPECT_EQ(g.status(), "");
  EXPECT_EQ(g.not_after_arrival(arrived + 45'000'000, arrived), arrived);
  EXPECT_EQ(g.not_after_arrival(arrived + 1, arrived), arrived);
  EXPECT_EQ(g.not_after_arrival(arrived + 20'000'000, arrived), arrived);
  const ArrivalGuard::Stats s = g.stats();
  EXPECT_EQ(s.future, 3u);
  EXPECT_EQ(s.max_lead_ns, 45'000'000);
  EXPECT_EQ(g.status(), ", 3 from the future (up to 45.0 ms ahead; stamped on arrival)");
  // Extreme values do not overflow the lead.
  EXPECT_EQ(g.not_after_arrival(std::numeric_limits<std::int64_t>::max(), 0), 0);
  EXPECT_EQ(g.stats().max_lead_ns, std::numeric_limits<std::int64_t>::max());
}

}  // namespace
}  // namespace fovea::trackerd::net
