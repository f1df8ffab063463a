#include "fovea/protocol/sequence_tracker.h"

namespace fovea::protocol {

void SequenceTracker::reset(std::uint64_t first_expected) {
  started_ = false;
  base_ = first_expected;
  highest_ = 0;
  window_ = 0;
}

SequenceTracker::Verdict SequenceTracker::on_arrival(std::uint64_t seq) {
  if (seq < base_) return Verdict::TooOld;
  if (!started_) {
    // Everything between the subscription point and the first arrival was lost.
    counts_.lost += seq - base_;
    started_ = true;
    highest_ = seq;
    window_ = 1;
    ++counts_.received;
    return Verdict::New;
  }
  if (seq > highest_) {
    const std::uint64_t gap = seq - highest_;
    counts_.lost += gap - 1;
    window_ = gap >= 64 ? 1 : (window_ << gap) | 1;
    highest_ = seq;
    ++counts_.received;
    return Verdict::New;
  }
  const std::uint64_t age = highest_ - seq;
  if (age >= 64) return Verdict::TooOld;
  const std::uint64_t bit = std::uint64_t{1} << age;
  if ((window_ & bit) != 0) {
    ++counts_.duplicated;
    return Verdict::Duplicate;
  }
  window_ |= bit;
  ++counts_.reordered;
  ++counts_.received;
  if (counts_.lost > 0) --counts_.lost;
  return Verdict::Reordered;
}

}  // namespace fovea::protocol
