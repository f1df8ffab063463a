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
