#pragma once
// Classifies arriving sequence numbers as new, lost (gap), duplicated or reordered, with a
// 64-entry history window (as RTP receivers do).
#include <cstdint>

namespace fovea::protocol {

struct SequenceCounts {
  std::uint64_t received = 0;    // distinct sequence numbers delivered
  std::uint64_t lost = 0;        // gaps not (yet) filled
  std::uint64_t duplicated = 0;
  std::uint64_t reordered = 0;   // arrived after a later one (filled a gap)
};

class SequenceTracker {
 public:
  enum class Verdict { New, Duplicate, Reordered, TooOld };

  // The next sequence number expected (from SUBSCRIBED); arrivals before it are TooOld.
  void reset(std::uint64_t first_expected);
  Verdict on_arrival(std::uint64_t seq);
  const SequenceCounts& counts() const { return counts_; }
  bool started() const { return started_; }
  std::uint64_t highest() const { return highest_; }

 private:
  bool started_ = false;
  std::uint64_t base_ = 0;     // first sequence number this tracker is responsible for
  std::uint64_t highest_ = 0;  // highest seen so far (valid when started_)
  std::uint64_t window_ = 0;   // bit i: highest_ - i has arrived
  SequenceCounts counts_;
};

}  // namespace fovea::protocol
