#include "daemon.h"

#include <spdlog/spdlog.h>
#include <sys/prctl.h>

#include <cctype>
#include <charconv>
#include <cmath>
#include <cerrno>
#include <chrono>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <thread>

#include "fovea/protocol/clock.h"
#include "fovea/protocol/csv.h"
#include "service/calibration_stage.h"
#include "fovea/protocol/bounded_file.h"
#include "fovea/protocol/control_socket.h"
#include "service/command_mailbox.h"
#include "service/control_paths.h"
#include "service/systemd_notify.h"
#include "classify_stage.h"
#include "sources/source_table.h"

namespace fovea::trackerd {

using protocol::monotonic_ns;

namespace {

constexpr std::int64_t kMs = 1'000'000;

std::string networks(const std::vector<protocol::Ipv4Cidr>& list) {
  if (list.empty()) return "nowhere";
  std::string s;
  for (const auto& n : list) s += (s.empty() ? "" : ", ") + n.to_string();
  return s;
}

// ---- the daemon ------------------------------------------------------------------------------

class Daemon {
 public:
  Daemon(service::DaemonConfig config, RunOptions run, DaemonSignals signals, ConfigLoader loader)
      : config_(std::move(config)), run_(run), signals_(signals), loader_(std::move(loader)) {}

  int run();

 private:
  enum class Wake { Due, Stop, Attention };

  bool start(std::int64_t start_ns);
  void publish(GazeItem item);
  void send(const GazeItem& item);
  Wake wait_until(std::int64_t due_ns);
  bool attention() const { return (signals_.reload != nullptr && signals_.reload->load()) || mailbox_.pending(); }
  void attend();
  void service_tick();
  protocol::ControlReply execute(const protocol::ControlRequest& request);
  protocol::ControlReply reload(const std::string& why);
  std::string start_recording(const std::string& path, bool append);  // empty or what went wrong
  std::string stop_recording();
  protocol::ControlReply handle_control(const protocol::ControlRequest& request, const std::string& who);
  bool open_control_socket();
  protocol::ControlReply submit_calibration_load(const protocol::ControlRequest& request);
  void publish_control_view();
  void apply_display(const std::optional<protocol::DisplayGeometry>& configured);
  std::string status_line() const;
  bool stopping() const { return signals_.stop != nullptr && signals_.stop->load(); }

  service::DaemonConfig config_;  // the running configuration
  RunOptions run_;
  DaemonSignals signals_;
  ConfigLoader loader_;

  service::SystemdNotifier notifier_;
  service::CommandMailbox mailbox_;
  std::unique_ptr<GazeSource> source_;
  std::unique_ptr<service::CalibrationStage> calibration_;
  // A calibration loaded by the control command; kept over reloads until "configured" or a restart.
  std::optional<std::string> calibration_override_;
  // What the control thread needs to prepare a calibration-load without touching the loop's state:
  // the configured file and the display, as the publishing loop last set them.
  struct ControlView {
    std::string configured_calibration;
    protocol::DisplayGeometry display;
    std::string running_calibration;  // its description, for the log
    std::string calibration_dir;      // "" : any file; else calibration-load is confined to it
  };
  mutable std::mutex control_view_mutex_;
  ControlView control_view_;
  std::unique_ptr<ClassifyStage> classify_;  // rebuilt on reload when the method changes
  std::vector<GazeItem> outgoing_;
  std::unique_ptr<protocol::GazeServer> server_;
  std::unique_ptr<protocol::ControlSocket> control_socket_;  // local control; null: none
  std::unique_ptr<protocol::RecordingWriter> recorder_;
  std::string recording_path_;
  std::string start_dir_ = std::filesystem::current_path().string();  // record-start's default directory
  protocol::DisplayGeometry display_;  // what clients are told
  std::uint64_t control_refused_logged_ = 0;
  std::int64_t next_refusal_check_ns_ = 0;
  std::int64_t next_health_check_ns_ = 0;
  std::string source_problem_;
  int status_ = 0;
  // A device source can block in next() waiting for data; this thread interrupts it when the loop
  // must attend (stop, reload, control) or has not ticked the watchdog for 500 ms.
  std::atomic<std::int64_t> in_next_since_ns_{0};
  std::atomic<bool> watcher_stop_{false};
  std::thread watcher_;
  void watch_source();
};

void Daemon::watch_source() {
  while (!watcher_stop_.load()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    const std::int64_t since = in_next_since_ns_.load();
    if (since != 0 && (stopping() || attention() || monotonic_ns() - since > 500 * kMs)) source_->interrupt();
  }
}

bool Daemon::start(std::int64_t start_ns) {
  try {
    source_ = make_source(config_, start_ns);
  } catch (const std::exception& e) {
    spdlog::error("cannot start source: {}", e.what());
    return false;
  }
  try {
    classify_ = std::make_unique<ClassifyStage>(config_.classifier.method, source_->nominal_rate_hz(),
                                                config_.display.value_or(source_->display()));
  } catch (const std::exception& e) {
    spdlog::error("classifier: {}", e.what());
    return false;
  }
  try {
    calibration_ = service::load_calibration_stage(config_.calibration.file,
                                                   config_.display.value_or(source_->display()));
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return false;
  }
  protocol::ServerOptions so;
  try {
    so = service::server_options(config_);
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return false;
  }
  display_ = config_.display.value_or(source_->display());
  so.display = display_;
  so.nominal_rate_hz = source_->nominal_rate_hz();
  so.source_name = source_->description();
  if (so.source_name.size() > 47) so.source_name = so.source_name.substr(0, 44) + "...";
  try {
    server_ = std::make_unique<protocol::GazeServer>(so);
  } catch (const std::exception& e) {
    spdlog::error("{} (is another fovea-trackerd running? choose another --port)", e.what());
    return false;
  }
  server_->on_subscriber_change([](const protocol::SubscriberInfo& s, const char* what) {
    spdlog::info("subscriber {} session {:016x}: {} (lease {} ms)", s.address.to_string(), s.session_id, what,
                 s.lease_ms);
  });
  // Control commands come only through the local socket (its file permissions say who), on its own
  // thread; the publishing loop executes them between samples. The gaze server gets no control
  // handler and an empty allow-list: over UDP it refuses every command (issue 23).
  publish_control_view();
  if (!open_control_socket()) return false;

  if (!config_.record.path.empty()) {
    if (const std::string err = start_recording(config_.record.path, config_.record.append); !err.empty()) {
      spdlog::error("{}", err);
      return false;
    }
  }
  spdlog::info("serving {} on {} ({} Hz, display {})", protocol::escape_for_log(source_->description()), server_->local_endpoint().to_string(),
               so.nominal_rate_hz, protocol::to_string(display_));
  if (so.multicast) spdlog::info("also publishing to multicast group {}", so.multicast->group.to_string());
  if (!config_.network.control_allow.empty()) {
    spdlog::warn("network.control_allow ({}) is ignored: control commands come only through the control socket, "
                 "whose permissions say who may send them (UDP shows nothing but a source address); remove the key",
                 networks(config_.network.control_allow));
  }
  spdlog::info("calibration: {}; classifier: {}", calibration_->description(), classify_->description());
  if (notifier_.watchdog_interval_ns() > 0) {
    spdlog::info("systemd watchdog: pinging every {} ms", notifier_.watchdog_interval_ns() / kMs);
  }
  return true;
}

// calibration -> online classifier -> publisher -> recorder
void Daemon::publish(GazeItem item) {
  calibration_->apply(item);
  outgoing_.clear();
  classify_->process(item, outgoing_);
  for (const GazeItem& out : outgoing_) send(out);
}

void Daemon::send(const GazeItem& item) {
  const std::uint64_t seq = std::visit([&](const auto& v) { return server_->publish(v); }, item);
  if (recorder_) {
    try {
      recorder_->append(protocol::Record{seq, item});
    } catch (const std::exception& e) {
      spdlog::error("{}; recording stopped, streaming continues", e.what());
      recorder_.reset();
      recording_path_.clear();
      status_ = 1;
    }
  }
}

// Sleeps until `due_ns` on CLOCK_MONOTONIC in short steps, so a signal, a reload or a control
// command is seen within 50 ms and the watchdog keeps being fed during long waits.
Daemon::Wake Daemon::wait_until(std::int64_t due_ns) {
  while (true) {
    if (stopping()) return Wake::Stop;
    if (attention()) return Wake::Attention;
    service_tick();
    const std::int64_t now = monotonic_ns();
    if (now >= due_ns) return Wake::Due;
    const std::int64_t target = std::min(due_ns, now + 50 * kMs);
    timespec ts{static_cast<time_t>(target / 1'000'000'000), static_cast<long>(target % 1'000'000'000)};
    clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
  }
}

void Daemon::attend() {
  if (signals_.reload != nullptr && signals_.reload->exchange(false)) reload("SIGHUP");
  if (mailbox_.pending()) mailbox_.drain();
}

void Daemon::service_tick() {
  const std::int64_t now = monotonic_ns();
  if (now >= next_health_check_ns_) {
    next_health_check_ns_ = now + 200 * kMs;
    const std::string problem = source_->problem();
    if (problem != source_problem_) {
      if (problem.empty()) {
        spdlog::info("{}: working again", protocol::escape_for_log(source_->description()));
      } else {
        spdlog::warn("{}", problem);
      }
      source_problem_ = problem;
      server_->set_source_state(problem.empty() ? protocol::SourceState::Running : protocol::SourceState::Retrying);
    }
  }
  notifier_.watchdog_tick(now);
  notifier_.status_tick(now, [&] { return status_line(); });
  if (now >= next_refusal_check_ns_) {
    next_refusal_check_ns_ = now + 1000 * kMs;
    const auto st = server_->stats();
    if (st.control_refused > control_refused_logged_) {
      spdlog::warn("refused {} control request(s) over UDP ({} refused so far): control is local only",
                   st.control_refused - control_refused_logged_, st.control_refused);
      control_refused_logged_ = st.control_refused;
    }
  }
}

std::string Daemon::status_line() const {
  const auto st = server_->stats();
  std::string s = protocol::escape_for_log(source_->description()) + ", " + std::to_string(static_cast<long>(source_->nominal_rate_hz())) +
                  " Hz, " + std::to_string(st.subscribers) + " subscribers, " + std::to_string(st.samples_published) +
                  " samples";
  if (const std::string detail = source_->status_detail(); !detail.empty()) s += ", " + detail;
  s += ", calibration " + calibration_->description();
  if (recorder_) s += ", recording " + recording_path_;
  return s;
}

protocol::ControlReply Daemon::execute(const protocol::ControlRequest& r) {
  protocol::ControlReply out{r.command, protocol::ControlResult::Ok, {}};
  const auto fail = [&](const std::string& why) {
    out.result = protocol::ControlResult::Failed;
    out.message.value = why;
    return out;
  };
  switch (r.command) {
    case protocol::ControlCommand::Reload:
      return reload("control request");
    case protocol::ControlCommand::StartRecording: {
      if (r.argument.value.empty()) return fail("record-start needs a file path");
      if (recorder_) return fail("already recording to " + recording_path_);
      std::string path;
      try {
        path = service::confined_path(r.argument.value, config_.network.control_dir.empty() ? start_dir_
                                                                                            : config_.network.control_dir);
      } catch (const std::exception& e) {
        // The log has it all; the 63-byte reply keeps the reason, not the path the client knows.
        spdlog::warn("{}", e.what());
        const std::string what = e.what();
        const std::size_t colon = what.rfind(": ");
        return fail(colon == std::string::npos ? what : what.substr(colon + 2));
      }
      if (const std::string err = start_recording(path, false); !err.empty()) return fail(err);
      out.message.value = "recording to " + recording_path_;
      return out;
    }
    case protocol::ControlCommand::StopRecording: {
      if (!recorder_) return fail("not recording");
      out.message.value = stop_recording();
      return out;
    }
    case protocol::ControlCommand::LoadCalibration:
      return fail("calibration-load is prepared on the control thread");  // submit_calibration_load
  }
  return fail("unknown command");
}

// One control command from the control socket (`who` for the log); what a client sent reaches the
// log escaped, so a newline in a path cannot forge a log line.
protocol::ControlReply Daemon::handle_control(const protocol::ControlRequest& r, const std::string& who) {
  spdlog::info("control {} from {}{}", protocol::to_string(r.command), who,
               r.argument.value.empty() ? std::string() : " (" + protocol::escape_for_log(r.argument.value) + ")");
  protocol::ControlReply reply = r.command == protocol::ControlCommand::LoadCalibration
                                     ? submit_calibration_load(r)
                                     : mailbox_.submit(r, [this, r] { return execute(r); }, std::chrono::milliseconds(3000));
  spdlog::log(reply.result == protocol::ControlResult::Ok ? spdlog::level::info : spdlog::level::warn,
              "control {}: {}: {}", protocol::to_string(r.command), protocol::to_string(reply.result),
              protocol::escape_for_log(reply.message.value));
  return reply;
}

// The local control socket (protocol/control_socket.h), mode 0660: the daemon's user and group.
bool Daemon::open_control_socket() {
  if (config_.network.control_socket == "none") {
    spdlog::info("no control socket (control_socket = none)");
    return true;
  }
  try {
    const std::string path = config_.network.control_socket.empty()
                                 ? protocol::default_control_socket(server_->local_endpoint().port)
                                 : config_.network.control_socket;
    control_socket_ = std::make_unique<protocol::ControlSocket>(
        path, 0660, [this](const protocol::ControlRequest& r, const protocol::PeerCredentials& who) {
          return handle_control(r, "the control socket (" + who.to_string() + ")");
        });
    spdlog::info("control commands from {} (mode 0660: this user and group)", protocol::escape_for_log(path));
    return true;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return false;
  }
}

// The publishing loop tells the control thread the configured calibration file and the display.
void Daemon::publish_control_view() {
  std::lock_guard lock(control_view_mutex_);
  control_view_ = {config_.calibration.file, display_, calibration_->description(), config_.network.calibration_dir};
}

// calibration-load: "none" no calibration; "configured" the configuration's file; anything else a
// file to load. The file is read and checked here, on the control thread (bounded, regular files
// only: calibration_stage.h); the publishing loop only swaps the result in, if the display it was
// checked against is still the one clients are told.
protocol::ControlReply Daemon::submit_calibration_load(const protocol::ControlRequest& r) {
  const auto reply = [](protocol::ControlResult result, std::string text) {
    protocol::ControlReply out{protocol::ControlCommand::LoadCalibration, result, {}};
    if (text.size() > 63) text = text.substr(0, 60) + "...";
    out.message.value = std::move(text);
    return out;
  };
  const std::string& argument = r.argument.value;
  if (argument.empty()) return reply(protocol::ControlResult::Failed, "calibration-load needs a file, none or configured");
  ControlView view;
  {
    std::lock_guard lock(control_view_mutex_);
    view = control_view_;
  }
  const std::optional<std::string> next_override =
      argument == "configured" ? std::nullopt : std::optional<std::string>(argument == "none" ? "" : argument);
  // std::function must be copyable: the loaded stage travels in a shared holder.
  auto stage = std::make_shared<std::unique_ptr<service::CalibrationStage>>();
  try {
    std::string file = next_override.value_or(view.configured_calibration);
    const bool confined = next_override && !next_override->empty() && !view.calibration_dir.empty();
    if (confined) {
      try {
        file = service::confined_path(file, view.calibration_dir, "calibration-load", "calibrations directory");
      } catch (const std::exception& e) {
        spdlog::warn("{}", e.what());  // in full; the 63-byte reply keeps the reason
        const std::string what = e.what();
        return reply(protocol::ControlResult::Failed, what.substr(what.rfind(": ") + 2));
      }
    }
    *stage = service::load_calibration_stage(file, view.display, /*follow_symlinks=*/!confined);
  } catch (const std::exception& e) {
    spdlog::error("calibration-load {}: {}; keeping {}", protocol::escape_for_log(argument), e.what(),
                  view.running_calibration);
    return reply(protocol::ControlResult::Failed, e.what());
  }
  const auto swap_in = [this, stage, next_override, view, reply] {
    if (!(display_ == view.display)) {
      return reply(protocol::ControlResult::Failed, "the display changed while the file was read; load it again");
    }
    calibration_ = std::move(*stage);
    calibration_override_ = next_override;
    publish_control_view();
    spdlog::info("calibration (control request): {}", calibration_->description());
    notifier_.status(status_line());
    return reply(protocol::ControlResult::Ok, "loaded " + calibration_->summary());
  };
  return mailbox_.submit(r, swap_in, std::chrono::milliseconds(3000));
}

std::string Daemon::start_recording(const std::string& path, bool append) {
  protocol::RecordingHeader h;
  h.device = protocol::recording_device_name(source_->description());
  h.display = display_;
  h.nominal_rate_hz = source_->nominal_rate_hz();
  h.clock = protocol::RecordingClock::Monotonic;
  h.created_unix_ns = protocol::realtime_ns();
  h.created_clock_ns = monotonic_ns();
  try {
    recorder_ = std::make_unique<protocol::RecordingWriter>(
        path, h, append ? protocol::RecordingWriter::Mode::Append : protocol::RecordingWriter::Mode::CreateNew);
  } catch (const std::exception& e) {
    return e.what();
  }
  recording_path_ = path;
  spdlog::info("recording published gaze to {}", path);
  return {};
}

std::string Daemon::stop_recording() {
  if (!recorder_) return "not recording";
  const std::string what =
      "stopped recording to " + recording_path_ + " (" + std::to_string(recorder_->records_written()) + " records)";
  recorder_.reset();  // closes the file
  recording_path_.clear();
  spdlog::info("{}", what);
  return what;
}

void Daemon::apply_display(const std::optional<protocol::DisplayGeometry>& configured) {
  const protocol::DisplayGeometry g = configured.value_or(source_->display());
  if (g == display_) return;
  display_ = g;
  server_->set_display(g);
  if (!(g == source_->display())) {
    spdlog::info(
        "display {} is what clients are told from now on; the source computes visual angles on its own "
        "geometry {} until a restart",
        protocol::to_string(g), protocol::to_string(source_->display()));
  }
  if (recorder_)
    spdlog::warn("{} keeps the display geometry of its header; record-stop/record-start to record the new one",
                 recording_path_);
}

// Adopts a new configuration without closing the socket or dropping a session. Settings that need
// a restart (source, listen address, port, multicast, devices) are logged and kept.
protocol::ControlReply Daemon::reload(const std::string& why) {
  protocol::ControlReply out{protocol::ControlCommand::Reload, protocol::ControlResult::Ok, {}};
  notifier_.reloading();
  spdlog::info("reloading configuration from {} ({})", config_.origin, why);
  service::DaemonConfig next;
  try {
    next = loader_ ? loader_() : config_;
  } catch (const std::exception& e) {
    spdlog::error("reload failed; keeping the running configuration:\n{}", e.what());
    notifier_.reloaded(status_line());
    out.result = protocol::ControlResult::Failed;
    out.message.value = std::string("configuration invalid: ") + e.what();
    return out;
  }
  const service::ConfigChanges changes = service::diff(config_, next);
  for (const auto& c : changes.needs_restart) spdlog::warn("{}: needs a restart; keeping the running value", c);
  next = service::adopt_live(config_, next);

  // Calibration: read again even when the name is unchanged (the file may have been refitted);
  // checked against the display the clients are told from now on.
  apply_display(next.display);
  std::string problems;
  try {
    calibration_ = service::load_calibration_stage(calibration_override_.value_or(next.calibration.file), display_);
    spdlog::info("calibration: {}{}", calibration_->description(),
                 calibration_override_ ? " (loaded by calibration-load; kept over reloads)" : "");
  } catch (const std::exception& e) {
    spdlog::error("{}; keeping the previous calibration", e.what());
    next.calibration = config_.calibration;
    problems = e.what();
  }
  server_->set_limits(next.network.lease_ms, next.network.max_subscribers);
  if (!(next.record == config_.record)) {
    if (recorder_) stop_recording();
    if (!next.record.path.empty()) {
      if (const std::string err = start_recording(next.record.path, next.record.append); !err.empty()) {
        spdlog::error("{}", err);
        problems = err;
      }
    }
  }
  if (next.classifier.method != config_.classifier.method) {
    try {
      outgoing_.clear();
      classify_->flush(outgoing_);  // close the old classifier's open event before switching
      for (const GazeItem& pending : outgoing_) send(pending);
      classify_ = std::make_unique<ClassifyStage>(next.classifier.method, source_->nominal_rate_hz(), display_);
      spdlog::info("classifier: {}", classify_->description());
    } catch (const std::exception& e) {
      spdlog::error("classifier {}: {}; keeping {}", next.classifier.method, e.what(), classify_->description());
      next.classifier.method = config_.classifier.method;
    }
  }
  spdlog::set_level(spdlog::level::from_str(next.log_level));
  for (const auto& c : changes.live) spdlog::info("applied: {}", c);
  config_ = next;
  publish_control_view();
  notifier_.reloaded(status_line());

  if (!problems.empty()) {
    out.result = protocol::ControlResult::Failed;
    out.message.value = problems;
  } else {
    out.message.value = "reloaded: " + std::to_string(changes.live.size()) + " applied, " +
                        std::to_string(changes.needs_restart.size()) + " need a restart";
  }
  spdlog::info("{}", problems.empty() ? out.message.value : "reload finished with problems");
  return out;
}

int Daemon::run() {
  // Samples are due every 1-4 ms; the default 50 us timer slack would add that much jitter to
  // every wake-up of the pacing loop.
  prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);
  // Give subscribers a moment to be accepted before the first sample is due.
  const std::int64_t start_ns = monotonic_ns() + 50 * kMs;
  if (!start(start_ns)) return 2;
  notifier_.ready(status_line());
  watcher_ = std::thread([this] { watch_source(); });
  if (run_.wait_subscribers > 0) {
    // As gpsfake does: hold the source until the expected clients are listening, so they see the
    // stream from its first sample (regression tests diff what they receive).
    spdlog::info("waiting for {} subscriber(s) before starting the source", run_.wait_subscribers);
    while (!stopping() && server_->stats().subscribers < run_.wait_subscribers) {
      service_tick();
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }

  const std::int64_t end_ns =
      run_.duration_s > 0 ? start_ns + static_cast<std::int64_t>(run_.duration_s * 1e9) : INT64_MAX;
  bool source_ended = false;
  std::optional<GazeItem> item;  // the next item, waiting for its time
  while (!stopping()) {
    attend();
    if (source_ended) {
      if (run_.exit_when_source_ends) break;
      const Wake w = wait_until(std::min(end_ns, monotonic_ns() + 100 * kMs));
      if (w == Wake::Stop || monotonic_ns() >= end_ns) break;
      continue;
    }
    if (!item) {
      in_next_since_ns_.store(monotonic_ns());
      item = source_->next();
      in_next_since_ns_.store(0);
      if (!item && !source_->ended()) {  // a device with nothing yet, or interrupted: attend, go on
        if (monotonic_ns() >= end_ns) break;
        service_tick();
        continue;
      }
      if (!item) {
        outgoing_.clear();
        classify_->flush(outgoing_);
        for (const GazeItem& out : outgoing_) send(out);
        source_ended = true;
        server_->set_source_state(protocol::SourceState::Ended);
        spdlog::info("source ended after {} samples", server_->stats().samples_published);
        continue;
      }
    }
    const std::int64_t due = due_time_ns(*item);
    if (due >= end_ns) break;
    const Wake w = wait_until(due);
    if (w == Wake::Stop) break;
    if (w == Wake::Attention) continue;  // attend, then wait for the same item again
    publish(std::move(*item));
    item.reset();
  }

  watcher_stop_ = true;
  if (watcher_.joinable()) watcher_.join();
  notifier_.stopping();
  mailbox_.close();
  control_socket_.reset();
  const auto st = server_->stats();
  server_->stop();
  spdlog::info(
      "stopped: {} samples and {} events published, {} datagrams sent, {} send failures, {} rejected, "
      "{} leases expired, {} control requests, {} control requests refused{}",
      st.samples_published, st.events_published, st.datagrams_sent, st.send_failures, st.datagrams_rejected,
      st.leases_expired, st.control_requests, st.control_refused,
      recorder_ ? ", " + std::to_string(recorder_->records_written()) + " records written" : std::string());
  if (const std::string detail = source_->status_detail(); !detail.empty()) {
    spdlog::info("{}: {}", protocol::escape_for_log(source_->description()), protocol::escape_for_log(detail));
  }
  return status_;
}

}  // namespace

int run_daemon(const service::DaemonConfig& config, const RunOptions& run, const DaemonSignals& signals,
               ConfigLoader reload_config) {
  Daemon d(config, run, signals, std::move(reload_config));
  return d.run();
}

}  // namespace fovea::trackerd
