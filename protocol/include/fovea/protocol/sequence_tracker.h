// SPDX-License-Identifier: Apache-2.0
#pragma once
// Classifies arriving sequence numbers as new, lost (gap), duplicated or reordered, with a
// 64-entry history window (as RTP receivers do).
//
// A jump ahead of more than kMaxPlausibleJump is not taken on trust (issue 23 item 5: one datagram
// with sequence 2^63, from a buggy server or a spoofed multicast source, made every later sample
// "too old" and the loss absurd): it is counted as implausible and not delivered. If the stream
// really moved (kResyncRun consecutive implausible arrivals that follow each other), the tracker
// resynchronises to it and counts the resynchronisation; the gap is then unknown, not lost.
#include <cstdint>

namespace fovea::protocol {

struct SequenceCounts {
  std::uint64_t received = 0;      // distinct sequence numbers delivered
  std::uint64_t lost = 0;          // gaps not (yet) filled, also across resubscriptions to the same stream
  std::uint64_t duplicated = 0;
  std::uint64_t reordered = 0;     // arrived after a later one (filled a gap)
  std::uint64_t implausible = 0;   // jumps beyond kMaxPlausibleJump, not delivered
  std::uint64_t resyncs = 0;       // times the tracker followed a stream that really jumped
};

class SequenceTracker {
 public:
  enum class Verdict { New, Duplicate, Reordered, TooOld, Implausible };
  // 2^24: 28 minutes of a 10 kHz stream, far beyond any lease (at most 10 minutes).
  static constexpr std::uint64_t kMaxPlausibleJump = std::uint64_t{1} << 24;
  static constexpr int kResyncRun = 8;

  // A new session: the next sequence number expected (from SUBSCRIBED); arrivals before it are
  // TooOld. If the tracker already followed this stream and first_expected lies a plausible
  // distance ahead, the numbers skipped while unsubscribed are counted as lost.
  void reset(std::uint64_t first_expected);
  // A new session of a stream whose next number the server did not say (MARKER): the first arrival
  // starts it, and nothing before it counts as lost.
  void reset_from_first_arrival();
  Verdict on_arrival(std::uint64_t seq);
  const SequenceCounts& counts() const { return counts_; }
  bool started() const { return started_; }
  std::uint64_t highest() const { return highest_; }

 private:
  Verdict implausible(std::uint64_t seq);
  void start_at(std::uint64_t seq);
  bool started_ = false;
  bool from_first_ = false;
  std::uint64_t base_ = 0;     // first sequence number this tracker is responsible for
  std::uint64_t highest_ = 0;  // highest seen so far (valid when started_)
  std::uint64_t window_ = 0;   // bit i: highest_ - i has arrived
  std::uint64_t run_last_ = 0;  // the last implausible arrival, and how many followed each other
  int run_length_ = 0;
  SequenceCounts counts_;
};

}  // namespace fovea::protocol
