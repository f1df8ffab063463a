#include "daemon.h"

#include <spdlog/spdlog.h>
#include <sys/prctl.h>

#include <cerrno>
#include <ctime>
#include <stdexcept>

#include "fovea/protocol/clock.h"
#include "sources/replay_source.h"
#include "sources/synthetic_gaze.h"

namespace fovea::trackerd {

using protocol::monotonic_ns;

std::unique_ptr<GazeSource> make_source(const DaemonOptions& o, std::int64_t start_time_ns) {
  const std::string& spec = o.source_spec;
  if (spec == "synthetic") {
    if (!(o.synthetic_rate_hz >= 1 && o.synthetic_rate_hz <= 10000)) {
      throw std::invalid_argument("--rate " + std::to_string(o.synthetic_rate_hz) + " is outside 1..10000 Hz");
    }
    SyntheticGazeOptions so;
    so.rate_hz = o.synthetic_rate_hz;
    so.seed = o.seed;
    so.display = o.display.value_or(protocol::DisplayGeometry{});
    so.start_time_ns = start_time_ns;
    return std::make_unique<SyntheticGaze>(so);
  }
  if (spec.rfind("replay:", 0) == 0) {
    ReplayOptions ro;
    ro.path = spec.substr(7);
    if (ro.path.empty()) throw std::invalid_argument("--source replay:FILE needs a file name");
    ro.speed = o.replay_speed;
    ro.loop = o.replay_loop;
    ro.start_time_ns = start_time_ns;
    auto src = std::make_unique<ReplaySource>(ro);
    const auto& rep = src->recovery();
    if (!rep.header_valid || rep.damaged_regions > 0 || rep.truncated_tail) {
      spdlog::warn("{}: {}", ro.path, rep.describe());
    }
    return src;
  }
  throw std::invalid_argument("unknown source \"" + spec +
                              "\"; this build supports: synthetic, replay:FILE (camera:, hid and video: come with "
                              "the hardware sources)");
}

namespace {

// Sleeps until `due_ns` on CLOCK_MONOTONIC, waking at least every 100 ms to check `stop`.
bool sleep_until(std::int64_t due_ns, const std::atomic<bool>& stop) {
  while (!stop.load()) {
    const std::int64_t now = monotonic_ns();
    if (now >= due_ns) return true;
    const std::int64_t target = std::min(due_ns, now + 100'000'000);
    timespec ts{static_cast<time_t>(target / 1'000'000'000), static_cast<long>(target % 1'000'000'000)};
    clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
  }
  return false;
}

}  // namespace

int run_daemon(const DaemonOptions& options, const std::atomic<bool>& stop) {
  // Samples are due every 1-4 ms; the default 50 us timer slack would add that much jitter to
  // every wake-up of the pacing loop.
  prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);
  // Give subscribers a moment to be accepted before the first sample is due.
  const std::int64_t start_ns = monotonic_ns() + 50'000'000;
  std::unique_ptr<GazeSource> source;
  try {
    source = make_source(options, start_ns);
  } catch (const std::exception& e) {
    spdlog::error("cannot start source: {}", e.what());
    return 2;
  }
  protocol::ServerOptions so = options.server;
  so.display = options.display.value_or(source->display());
  so.nominal_rate_hz = source->nominal_rate_hz();
  so.source_name = source->description();
  if (so.source_name.size() > 47) so.source_name = so.source_name.substr(0, 44) + "...";

  std::unique_ptr<protocol::GazeServer> server;
  try {
    server = std::make_unique<protocol::GazeServer>(so);
  } catch (const std::exception& e) {
    spdlog::error("{} (is another fovea-trackerd running? choose another --port)", e.what());
    return 2;
  }
  server->on_subscriber_change([](const protocol::SubscriberInfo& s, const char* what) {
    spdlog::info("subscriber {} session {:016x}: {} (lease {} ms)", s.address.to_string(), s.session_id, what,
                 s.lease_ms);
  });

  std::unique_ptr<protocol::RecordingWriter> recorder;
  if (!options.record_path.empty()) {
    protocol::RecordingHeader h;
    h.device = source->description().substr(0, 63);
    h.display = so.display;
    h.nominal_rate_hz = so.nominal_rate_hz;
    h.clock = protocol::RecordingClock::Monotonic;
    h.created_unix_ns = protocol::realtime_ns();
    h.created_clock_ns = monotonic_ns();
    try {
      recorder = std::make_unique<protocol::RecordingWriter>(
          options.record_path, h,
          options.record_append ? protocol::RecordingWriter::Mode::Append : protocol::RecordingWriter::Mode::CreateNew);
    } catch (const std::exception& e) {
      spdlog::error("{}", e.what());
      return 2;
    }
    spdlog::info("recording published gaze to {}", options.record_path);
  }

  spdlog::info("serving {} on {} ({} Hz, display {})", source->description(), server->local_endpoint().to_string(),
               so.nominal_rate_hz, protocol::to_string(so.display));
  if (so.multicast) spdlog::info("also publishing to multicast group {}", so.multicast->group.to_string());

  const std::int64_t end_ns =
      options.duration_s > 0 ? start_ns + static_cast<std::int64_t>(options.duration_s * 1e9) : INT64_MAX;
  bool source_ended = false;
  int status = 0;
  while (!stop.load()) {
    if (source_ended) {
      if (options.exit_when_source_ends) break;
      if (!sleep_until(std::min(end_ns, monotonic_ns() + 100'000'000), stop) || monotonic_ns() >= end_ns) break;
      continue;
    }
    std::optional<GazeItem> item = source->next();
    if (!item) {
      source_ended = true;
      server->set_source_state(protocol::SourceState::Ended);
      spdlog::info("source ended after {} samples", server->stats().samples_published);
      continue;
    }
    const std::int64_t due = due_time_ns(*item);
    if (due >= end_ns) break;
    if (!sleep_until(due, stop)) break;
    const std::uint64_t seq = std::visit([&](const auto& v) { return server->publish(v); }, *item);
    if (recorder) {
      try {
        recorder->append(protocol::Record{seq, *item});
      } catch (const std::exception& e) {
        spdlog::error("{}; recording stopped, streaming continues", e.what());
        recorder.reset();
        status = 1;
      }
    }
  }

  const auto st = server->stats();
  server->stop();
  spdlog::info("stopped: {} samples and {} events published, {} datagrams sent, {} send failures, {} rejected, "
               "{} leases expired{}",
               st.samples_published, st.events_published, st.datagrams_sent, st.send_failures, st.datagrams_rejected,
               st.leases_expired,
               recorder ? ", " + std::to_string(recorder->records_written()) + " records written" : std::string());
  return status;
}

}  // namespace fovea::trackerd
