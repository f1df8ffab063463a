// SPDX-License-Identifier: Apache-2.0
#include <gtest/gtest.h>

#include "fovea/protocol/sequence_tracker.h"

using fovea::protocol::SequenceTracker;
using V = SequenceTracker::Verdict;

TEST(SequenceTracker, CountsGapsDuplicatesAndReordering) {
  SequenceTracker t;
  t.reset(100);
  EXPECT_EQ(t.on_arrival(100), V::New);
  EXPECT_EQ(t.on_arrival(101), V::New);
  EXPECT_EQ(t.on_arrival(104), V::New);  // 102, 103 missing
  EXPECT_EQ(t.counts().lost, 2u);
  EXPECT_EQ(t.on_arrival(103), V::Reordered);
  EXPECT_EQ(t.counts().lost, 1u);
  EXPECT_EQ(t.on_arrival(103), V::Duplicate);
  EXPECT_EQ(t.on_arrival(104), V::Duplicate);
  EXPECT_EQ(t.on_arrival(99), V::TooOld);
  EXPECT_EQ(t.counts().received, 4u);
  EXPECT_EQ(t.counts().duplicated, 2u);
  EXPECT_EQ(t.counts().reordered, 1u);
}

TEST(SequenceTracker, LossBeforeFirstArrivalAndHugeGaps) {
  SequenceTracker t;
  t.reset(10);
  t.on_arrival(13);
  EXPECT_EQ(t.counts().lost, 3u);
  t.on_arrival(1000);
  EXPECT_EQ(t.counts().lost, 3u + 986u);
  EXPECT_EQ(t.on_arrival(13), V::TooOld);  // beyond the 64-entry window
  EXPECT_EQ(t.on_arrival(999), V::Reordered);
}

TEST(SequenceTracker, ResetKeepsTotalsAcrossSessions) {
  SequenceTracker t;
  t.reset(0);
  for (std::uint64_t s = 0; s < 10; ++s) t.on_arrival(s);
  t.reset(0);  // daemon restarted: sequence numbers start again
  for (std::uint64_t s = 0; s < 5; ++s) EXPECT_EQ(t.on_arrival(s), V::New);
  EXPECT_EQ(t.counts().received, 15u);
  EXPECT_EQ(t.counts().lost, 0u);
}

// Issue 23 item 5: one datagram with sequence 2^63 must not blackhole the client.
TEST(SequenceTracker, OneHugeSequenceNumberIsImplausibleAndChangesNothing) {
  SequenceTracker t;
  t.reset(100);
  for (std::uint64_t s = 100; s < 110; ++s) t.on_arrival(s);
  EXPECT_EQ(t.on_arrival(std::uint64_t{1} << 63), V::Implausible);
  for (std::uint64_t s = 110; s < 120; ++s) EXPECT_EQ(t.on_arrival(s), V::New) << s;
  EXPECT_EQ(t.counts().received, 20u);
  EXPECT_EQ(t.counts().lost, 0u);
  EXPECT_EQ(t.counts().implausible, 1u);
  EXPECT_EQ(t.highest(), 119u);
  // Before the first arrival too, and a jump just within the bound is still a (large) loss.
  SequenceTracker u;
  u.reset(0);
  EXPECT_EQ(u.on_arrival(~std::uint64_t{0}), V::Implausible);
  EXPECT_EQ(u.on_arrival(SequenceTracker::kMaxPlausibleJump), V::New);
  EXPECT_EQ(u.counts().lost, SequenceTracker::kMaxPlausibleJump);
}

// A stream that really moved (a run of arrivals that follow each other) is followed, not lost.
TEST(SequenceTracker, AStreamThatReallyJumpedIsFollowedAfterARun) {
  SequenceTracker t;
  t.reset(0);
  for (std::uint64_t s = 0; s < 5; ++s) t.on_arrival(s);
  const std::uint64_t far = std::uint64_t{1} << 40;
  for (int k = 0; k < SequenceTracker::kResyncRun - 1; ++k) {
    EXPECT_EQ(t.on_arrival(far + static_cast<std::uint64_t>(k)), V::Implausible) << k;
  }
  EXPECT_EQ(t.on_arrival(far + SequenceTracker::kResyncRun - 1), V::New);
  EXPECT_EQ(t.on_arrival(far + SequenceTracker::kResyncRun), V::New);
  EXPECT_EQ(t.counts().resyncs, 1u);
  EXPECT_EQ(t.counts().implausible, 0u);
  EXPECT_EQ(t.counts().received, 5u + SequenceTracker::kResyncRun + 1);
  EXPECT_EQ(t.counts().lost, 0u);  // unknown across the jump, not counted as lost
  // Scattered huge numbers (spoofing) never form a run.
  SequenceTracker u;
  u.reset(0);
  u.on_arrival(0);
  for (std::uint64_t k = 0; k < 100; ++k) {
    EXPECT_EQ(u.on_arrival(far + k * 1000), V::Implausible);
    EXPECT_EQ(u.on_arrival(k + 1), V::New);
  }
  EXPECT_EQ(u.counts().resyncs, 0u);
}

// Issue 23 item 3: samples published while a client was unsubscribed (its lease lapsed) are lost,
// and a resubscription must not hide them.
TEST(SequenceTracker, LossWhileUnsubscribedSurvivesTheResubscription) {
  SequenceTracker t;
  t.reset(0);
  for (std::uint64_t s = 0; s < 10; ++s) t.on_arrival(s);
  t.reset(2260);  // the new session starts 2250 samples later (~9 s at 250 Hz)
  for (std::uint64_t s = 2260; s < 2270; ++s) EXPECT_EQ(t.on_arrival(s), V::New);
  EXPECT_EQ(t.counts().lost, 2250u);
  EXPECT_EQ(t.counts().received, 20u);
}

// MARKER: SUBSCRIBED names no next marker sequence; the first arrival starts the stream.
TEST(SequenceTracker, FromFirstArrivalCountsNothingBeforeItAsLost) {
  fovea::protocol::SequenceTracker t;
  t.reset_from_first_arrival();
  EXPECT_EQ(t.on_arrival(41), fovea::protocol::SequenceTracker::Verdict::New);
  EXPECT_EQ(t.counts().lost, 0u);
  EXPECT_EQ(t.on_arrival(43), fovea::protocol::SequenceTracker::Verdict::New);
  EXPECT_EQ(t.counts().lost, 1u) << "after the first arrival gaps count as usual";
  EXPECT_EQ(t.on_arrival(40), fovea::protocol::SequenceTracker::Verdict::TooOld);
  t.reset(100);  // an ordinary reset afterwards is unaffected
  EXPECT_EQ(t.on_arrival(102), fovea::protocol::SequenceTracker::Verdict::New);
  EXPECT_EQ(t.counts().lost, 1u + 56u + 2u) << "44..99 skipped while unsubscribed, then 100 and 101";
}
