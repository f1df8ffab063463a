// SPDX-License-Identifier: Apache-2.0
// Encode + decode cost per message, and the checksums used on the wire path and in recordings.
#include <benchmark/benchmark.h>

#include <vector>

#include "fovea/protocol/codec.h"
#include "fovea/protocol/cookie.h"
#include "fovea/protocol/crc32c.h"
#include "fovea/protocol/recording.h"

using namespace fovea::protocol;

namespace {

GazeSample typical_sample() {
  GazeSample s;
  s.tracker_time_ns = 123'456'789'000;
  s.x = 0.42f;
  s.y = 0.58f;
  s.x_deg = -3.1f;
  s.y_deg = 2.2f;
  s.angular_velocity_deg_s = 14.0f;
  s.confidence = 0.97f;
  s.state = EyeMovement::Fixation;
  s.flags = kGazeValid;
  s.left = EyeData{kEyePupilValid | kEyeGlintValid, 310.0f, 250.0f, 3.6f, -2.8f, 2.0f};
  s.right = s.left;
  return s;
}

Payload payload_for(int which) {
  switch (which) {
    case 0: return typical_sample();
    case 1: {
      GazeEvent e;
      e.kind = EyeMovement::Saccade;
      e.phase = EventPhase::End;
      e.start_time_ns = 1;
      e.duration_ns = 40'000'000;
      e.amplitude_deg = 8;
      e.peak_velocity_deg_s = 350;
      return e;
    }
    case 2: {
      Subscribed s;
      s.session_id = 7;
      s.streams = kStreamSamples;
      s.lease_ms = 5000;
      s.nominal_rate_hz = 1000;
      return s;
    }
    default: {
      StatusReply s;
      s.source.value = "replay:demo.fgr";
      return s;
    }
  }
}

const char* kNames[] = {"GAZE_SAMPLE", "GAZE_EVENT", "SUBSCRIBED", "STATUS_REPLY"};

void BM_Encode(benchmark::State& state) {
  const Message m{Header{}, payload_for(static_cast<int>(state.range(0)))};
  std::array<std::uint8_t, kMaxDatagramSize> buf{};
  for (auto _ : state) {
    benchmark::DoNotOptimize(encode_into(m, buf));
    benchmark::ClobberMemory();
  }
  state.SetLabel(kNames[state.range(0)]);
}
BENCHMARK(BM_Encode)->DenseRange(0, 3);

void BM_Decode(benchmark::State& state) {
  const auto bytes = encode(Message{Header{}, payload_for(static_cast<int>(state.range(0)))});
  Message out;
  for (auto _ : state) {
    benchmark::DoNotOptimize(decode(bytes, out));
    benchmark::ClobberMemory();
  }
  state.SetLabel(kNames[state.range(0)]);
}
BENCHMARK(BM_Decode)->DenseRange(0, 3);

void BM_EncodeDecodeRoundTrip(benchmark::State& state) {
  const Message m{Header{}, payload_for(static_cast<int>(state.range(0)))};
  std::array<std::uint8_t, kMaxDatagramSize> buf{};
  Message out;
  for (auto _ : state) {
    const std::size_t n = encode_into(m, buf);
    benchmark::DoNotOptimize(decode(std::span<const std::uint8_t>(buf.data(), n), out));
  }
  state.SetLabel(kNames[state.range(0)]);
}
BENCHMARK(BM_EncodeDecodeRoundTrip)->DenseRange(0, 3);

void BM_Crc32c(benchmark::State& state) {
  std::vector<std::uint8_t> data(static_cast<std::size_t>(state.range(0)));
  for (std::size_t i = 0; i < data.size(); ++i) data[i] = static_cast<std::uint8_t>(i * 31);
  for (auto _ : state) benchmark::DoNotOptimize(crc32c(data));
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations()) * state.range(0));
}
BENCHMARK(BM_Crc32c)->Arg(104)->Arg(65536);

void BM_RecordEncode(benchmark::State& state) {
  const Record r{42, typical_sample()};
  for (auto _ : state) benchmark::DoNotOptimize(encode_record(r));
}
BENCHMARK(BM_RecordEncode);

void BM_CookieIssueAndCheck(benchmark::State& state) {
  const CookieJar jar(10'000);
  const Endpoint peer{0x7F000001, 40000};
  for (auto _ : state) {
    const Cookie c = jar.issue(peer, 99, 1'000'000'000);
    benchmark::DoNotOptimize(jar.check(c, peer, 99, 1'000'000'000));
  }
}
BENCHMARK(BM_CookieIssueAndCheck);

}  // namespace

BENCHMARK_MAIN();
