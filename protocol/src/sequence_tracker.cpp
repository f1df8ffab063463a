// SPDX-License-Identifier: Apache-2.0
#include "fovea/protocol/sequence_tracker.h"

namespace fovea::protocol {

void SequenceTracker::reset(std::uint64_t first_expected) {
  if (started_ && first_expected > highest_ + 1 && first_expected - highest_ <= kMaxPlausibleJump) {
    counts_.lost += first_expected - highest_ - 1;  // published while this client was not subscribed
  }
  started_ = false;
  from_first_ = false;
  base_ = first_expected;
  highest_ = 0;
  window_ = 0;
  run_length_ = 0;
}

void SequenceTracker::reset_from_first_arrival() {
  reset(0);
  from_first_ = true;
}

void SequenceTracker::start_at(std::uint64_t seq) {
  started_ = true;
  highest_ = seq;
  window_ = 1;
  run_length_ = 0;
  ++counts_.received;
}

// Not delivered; a run of kResyncRun arrivals that follow each other (each within the window of
// the one before) means the stream itself is there now: follow it.
SequenceTracker::Verdict SequenceTracker::implausible(std::uint64_t seq) {
  ++counts_.implausible;
  const bool follows = run_length_ > 0 && seq > run_last_ && seq - run_last_ < 64;
  run_length_ = follows ? run_length_ + 1 : 1;
  run_last_ = seq;
  if (run_length_ < kResyncRun) return Verdict::Implausible;
  ++counts_.resyncs;
  counts_.implausible -= static_cast<std::uint64_t>(kResyncRun);
  counts_.received += static_cast<std::uint64_t>(kResyncRun) - 1;  // the run's earlier members
  base_ = seq - (static_cast<std::uint64_t>(kResyncRun) - 1);
  start_at(seq);
  return Verdict::New;
}

SequenceTracker::Verdict SequenceTracker::on_arrival(std::uint64_t seq) {
  if (seq < base_) return Verdict::TooOld;  // before this session's first sequence number
  if (!started_ && from_first_) {
    from_first_ = false;
    base_ = seq;
  }
  if (!started_) {
    if (seq - base_ > kMaxPlausibleJump) return implausible(seq);
    // Everything between the subscription point and the first arrival was lost.
    counts_.lost += seq - base_;
    start_at(seq);
    return Verdict::New;
  }
  if (seq > highest_) {
    const std::uint64_t gap = seq - highest_;
    if (gap > kMaxPlausibleJump) return implausible(seq);
    run_length_ = 0;
    counts_.lost += gap - 1;
    window_ = gap >= 64 ? 1 : (window_ << gap) | 1;
    highest_ = seq;
    ++counts_.received;
    return Verdict::New;
  }
  const std::uint64_t age = highest_ - seq;
  if (age >= 64) return Verdict::TooOld;
  run_length_ = 0;
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
