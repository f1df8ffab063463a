// SPDX-License-Identifier: Apache-2.0
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
#include "fovea/protocol/viewer_feed.h"
#include "service/command_mailbox.h"
#include "service/control_paths.h"
#include "service/systemd_notify.h"
#include "classify_stage.h"
#include "lsl/lsl_outlet.h"
#include "daemon_changes.h"
#include "viewer_status.h"
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
  void shut_down();
  void publish(GazeItem item, std::optional<std::int64_t> receive_ns, const std::vector<protocol::Marker>& markers);
  void send(const GazeItem& item, std::optional<std::int64_t> receive_ns = std::nullopt);
  void record(const protocol::Record& record);
  void record_markers();
  Wake wait_until(std::int64_t due_ns);
  bool attention() const { return mailbox_.pending(); }
  void service_tick();
  // Control: prepared on the control thread or the SIGHUP worker, one at a time, against the view
  // the loop last published (daemon_changes.h); the loop runs only the swap (mailbox).
  protocol::ControlReply handle_control(const protocol::ControlRequest& request, const std::string& who);
  protocol::ControlReply prepare_and_submit(const protocol::ControlRequest& request);
  protocol::ControlReply submit_reload(const RunningView& view, const std::string& why);
  protocol::ControlReply submit_record_start(const protocol::ControlRequest& request, const RunningView& view);
  protocol::ControlReply submit_calibration_load(const protocol::ControlRequest& request, const RunningView& view);
  void watch_reload_signal();
  RunningView running_view() const;
  // The loop's side.
  protocol::ControlReply apply_reload(PreparedReload& prepared, const std::string& why);
  void adopt_recording(PendingRecording& recording);
  std::string stop_recording();
  bool open_control_socket();
  void open_viewer_feed(const std::string& control_path);
  void publish_viewer_status(std::int64_t now);
  bool open_lsl_outlet_if_asked();
  void watch_server();
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
  // Declared before the source, so destroyed after it: the source offers it frames.
  std::unique_ptr<protocol::ViewerFeedServer> viewer_;  // local viewers' feed; null: none
  std::int64_t next_viewer_status_ns_ = 0;
  std::unique_ptr<GazeSource> source_;
  std::unique_ptr<service::CalibrationStage> calibration_;
  // A calibration loaded by the control command; kept over reloads until "configured" or a restart.
  std::optional<std::string> calibration_override_;
  // What the control side prepares against: the loop publishes it after every change it makes.
  mutable std::mutex control_view_mutex_;
  RunningView control_view_;
  std::mutex prepare_mutex_;  // one change prepared and applied at a time
  std::thread reload_worker_;  // prepares SIGHUP reloads
  std::unique_ptr<ClassifyStage> classify_;  // rebuilt on reload when the method changes
  std::vector<GazeItem> outgoing_;
  // Declared before the server, so destroyed after it: the server's marker callback pushes to it.
  std::unique_ptr<LslOutlet> lsl_;  // [lsl] outlet; null: none
  std::unique_ptr<protocol::GazeServer> server_;
  std::unique_ptr<protocol::ControlSocket> control_socket_;  // local control; null: none
  std::unique_ptr<protocol::RecordingWriter> recorder_;
  // Markers the server published (control thread), waiting for the loop to record them.
  mutable std::mutex markers_mutex_;
  std::vector<protocol::Record> markers_in_;
  std::uint64_t markers_unrecorded_ = 0;  // dropped because the loop fell 4096 behind
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

constexpr std::chrono::milliseconds kApplyTimeout{3000};  // for the loop to pick a prepared change up

protocol::ControlReply failed(protocol::ControlCommand command, std::string why) {
  protocol::ControlReply out{command, protocol::ControlResult::Failed, {}};
  out.message.value = std::move(why);
  return out;
}

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
                                                config_.display.value_or(source_->display()),
                                                config_.classifier.pso_convention(), config_.classifier.pursuit_weight);
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
  if (!open_lsl_outlet_if_asked()) return false;
  watch_server();
  // Control commands come only through the local socket (its file permissions say who), on its own
  // thread; the publishing loop executes them between samples. The gaze server gets no control
  // handler and an empty allow-list: over UDP it refuses every command (issue 23).
  publish_control_view();
  if (!open_control_socket()) return false;

  if (!config_.record.path.empty()) {
    try {
      PendingRecording recording(config_.record.path, config_.record.append, running_view(), display_);
      adopt_recording(recording);
    } catch (const std::exception& e) {
      spdlog::error("{}", e.what());
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

// calibration -> online classifier -> publisher -> recorder. `receive_ns`: when the item reached this
// host, where the source says (a network tracker); it goes with the sample, which the classifier
// hands on in the same call (its events, in the past, follow it).
void Daemon::publish(GazeItem item, std::optional<std::int64_t> receive_ns,
                     const std::vector<protocol::Marker>& markers) {
  for (const protocol::Marker& m : markers) server_->publish(m);  // recorded through on_marker
  calibration_->apply(item);
  outgoing_.clear();
  classify_->process(item, outgoing_);
  bool sample_sent = false;
  for (const GazeItem& out : outgoing_) {
    const bool is_sample = std::holds_alternative<protocol::GazeSample>(out);
    send(out, is_sample && !sample_sent ? receive_ns : std::nullopt);
    sample_sent = sample_sent || is_sample;
  }
}

void Daemon::send(const GazeItem& item, std::optional<std::int64_t> receive_ns) {
  std::uint64_t seq = 0;
  std::optional<std::int64_t> stored_receive;
  if (const auto* s = std::get_if<protocol::GazeSample>(&item)) {
    seq = server_->publish(*s, receive_ns.value_or(s->tracker_time_ns));
    if (lsl_) lsl_->push(*s);
    // Stored only where it says something the sample's time does not (RECORDING.md).
    if (receive_ns && *receive_ns != s->tracker_time_ns) stored_receive = receive_ns;
  } else {
    const auto& event = std::get<protocol::GazeEvent>(item);
    seq = server_->publish(event);
    if (event.provisional()) return;
    if (lsl_) lsl_->push(event);  // recordings keep the final labels (RECORDING.md)
  }
  record_markers();  // those that came before this item, so the file stays nearly in time order
  std::visit([&](const auto& v) { record(protocol::Record{seq, v, stored_receive}); }, item);
}

void Daemon::record_markers() {
  std::vector<protocol::Record> markers;
  {
    std::lock_guard lock(markers_mutex_);
    if (markers_in_.empty()) return;
    markers.swap(markers_in_);
  }
  for (const protocol::Record& m : markers) record(m);
}

void Daemon::record(const protocol::Record& record) {
  if (recorder_) {
    try {
      recorder_->append(record);
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

void Daemon::service_tick() {
  record_markers();  // also while the source is quiet
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
  publish_viewer_status(now);
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
  if (st.markers_published > 0) s += ", " + std::to_string(st.markers_published) + " markers";
  {
    std::lock_guard lock(markers_mutex_);
    if (markers_unrecorded_ > 0) s += " (" + std::to_string(markers_unrecorded_) + " not recorded: the loop fell behind)";
  }
  if (const std::string detail = source_->status_detail(); !detail.empty()) s += ", " + detail;
  s += ", calibration " + calibration_->description();
  if (recorder_) s += ", recording " + recording_path_;
  if (lsl_) s += ", LSL " + lsl_->status();
  if (viewer_) {
    const auto ef = viewer_->stats();
    if (ef.readers > 0) s += ", " + std::to_string(ef.readers) + " viewer(s)";
  }
  return s;
}

// One control command from the control socket (`who` for the log); what a client sent reaches the
// log escaped, so a newline in a path cannot forge a log line.
protocol::ControlReply Daemon::handle_control(const protocol::ControlRequest& r, const std::string& who) {
  spdlog::info("control {} from {}{}", protocol::to_string(r.command), who,
               r.argument.value.empty() ? std::string() : " (" + protocol::escape_for_log(r.argument.value) + ")");
  const protocol::ControlReply reply = prepare_and_submit(r);
  spdlog::log(reply.result == protocol::ControlResult::Ok ? spdlog::level::info : spdlog::level::warn,
              "control {}: {}: {}", protocol::to_string(r.command), protocol::to_string(reply.result),
              protocol::escape_for_log(reply.message.value));
  return reply;
}

// Reads what the command names here, off the publishing loop, and hands the loop only the swap.
// Changes are prepared one at a time, and each waits until the loop has applied it, so the next
// one is prepared against the state this one left.
protocol::ControlReply Daemon::prepare_and_submit(const protocol::ControlRequest& r) {
  std::lock_guard lock(prepare_mutex_);
  const RunningView view = running_view();
  try {
    switch (r.command) {
      case protocol::ControlCommand::Reload:
        return submit_reload(view, "control request");
      case protocol::ControlCommand::StartRecording:
        return submit_record_start(r, view);
      case protocol::ControlCommand::StopRecording:
        return mailbox_.submit(r, [this, r] {
          protocol::ControlReply out{r.command, protocol::ControlResult::Ok, {}};
          if (!recorder_) out.result = protocol::ControlResult::Failed;
          out.message.value = stop_recording();
          return out;
        }, kApplyTimeout);
      case protocol::ControlCommand::LoadCalibration:
        return submit_calibration_load(r, view);
    }
    throw std::runtime_error("unknown command");
  } catch (const service::PathRefused& e) {
    // The log has it all; the 63-byte reply keeps the reason, not the path the client knows.
    spdlog::warn("{}", e.what());
    return failed(r.command, e.reason());
  } catch (const std::exception& e) {
    return failed(r.command, e.what());  // handle_control logs the reply
  }
}

protocol::ControlReply Daemon::submit_record_start(const protocol::ControlRequest& r, const RunningView& view) {
  // std::function must be copyable: the open file travels in a shared holder, and is removed
  // again if the loop never adopts it.
  auto recording = std::make_shared<PendingRecording>(prepare_record_start(r.argument.value, view));
  return mailbox_.submit(r, [this, r, recording] {
    protocol::ControlReply out{r.command, protocol::ControlResult::Failed, {}};
    if (recorder_) {
      out.message.value = "already recording to " + recording_path_;
    } else if (!(display_ == recording->display())) {
      out.message.value = "the display changed while the file was made; start again";
    } else {
      adopt_recording(*recording);
      out.result = protocol::ControlResult::Ok;
      out.message.value = "recording to " + recording_path_;
    }
    return out;
  }, kApplyTimeout);
}

// calibration-load: "none" no calibration; "configured" the configuration's file; anything else a
// file in the calibrations directory. Read and checked here (bounded, regular files only:
// calibration_stage.h); the loop swaps the result in if the display it was checked against is
// still the one clients are told.
protocol::ControlReply Daemon::submit_calibration_load(const protocol::ControlRequest& r, const RunningView& view) {
  auto prepared = std::make_shared<PreparedCalibration>();
  try {
    *prepared = prepare_calibration_load(r.argument.value, view);
  } catch (const service::PathRefused&) {
    throw;
  } catch (const std::exception& e) {
    spdlog::error("calibration-load {}: {}; keeping {}", protocol::escape_for_log(r.argument.value), e.what(),
                  view.running_calibration);
    return failed(r.command, e.what());
  }
  return mailbox_.submit(r, [this, r, prepared] {
    protocol::ControlReply out{r.command, protocol::ControlResult::Failed, {}};
    if (!(display_ == prepared->display)) {
      out.message.value = "the display changed while the file was read; load it again";
      return out;
    }
    calibration_ = std::move(prepared->stage);
    calibration_override_ = prepared->override_file;
    publish_control_view();
    spdlog::info("calibration (control request): {}", calibration_->description());
    notifier_.status(status_line());
    out.result = protocol::ControlResult::Ok;
    out.message.value = "loaded " + calibration_->summary();
    return out;
  }, kApplyTimeout);
}

protocol::ControlReply Daemon::submit_reload(const RunningView& view, const std::string& why) {
  const protocol::ControlRequest request{protocol::ControlCommand::Reload, {}};
  notifier_.reloading();
  spdlog::info("reloading configuration from {} ({})", view.config.origin, why);
  std::shared_ptr<PreparedReload> prepared;
  try {
    prepared = std::make_shared<PreparedReload>(prepare_reload(view, loader_));
  } catch (const std::exception& e) {
    spdlog::error("reload failed; keeping the running configuration:\n{}", e.what());
    // READY=1 again, with the status only the loop can compose.
    const protocol::ControlReply out = failed(request.command, std::string("configuration invalid: ") + e.what());
    return mailbox_.submit(request, [this, out] {
      notifier_.reloaded(status_line());
      return out;
    }, kApplyTimeout);
  }
  return mailbox_.submit(request, [this, prepared, why] { return apply_reload(*prepared, why); }, kApplyTimeout);
}

// SIGHUP: the signal handler only sets a flag; this thread prepares the reload the flag asks for.
void Daemon::watch_reload_signal() {
  while (!watcher_stop_.load()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    if (signals_.reload == nullptr || !signals_.reload->exchange(false)) continue;
    std::lock_guard lock(prepare_mutex_);
    const protocol::ControlReply reply = submit_reload(running_view(), "SIGHUP");
    if (reply.result != protocol::ControlResult::Ok) {
      spdlog::warn("reload (SIGHUP): {}", protocol::escape_for_log(reply.message.value));
    }
  }
}

RunningView Daemon::running_view() const {
  std::lock_guard lock(control_view_mutex_);
  return control_view_;
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
    open_viewer_feed(path);
    return true;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return false;
  }
}

// The feed for local viewers (fovea-monitor: PROTOCOL.md §17), beside the control socket and with its
// permissions: eye images show the user's face. A daemon that cannot open it still tracks.
void Daemon::open_viewer_feed(const std::string& control_path) {
  const std::string path = protocol::viewer_socket_for(control_path);
  try {
    viewer_ = std::make_unique<protocol::ViewerFeedServer>(path, 0660);
    source_->show_eye_frames(viewer_.get());
    spdlog::info("viewer feed (daemon status{}) on {} (mode 0660)",
                 source_->makes_eye_frames() ? ", eye images at most 30 Hz and 320x240" : "",
                 protocol::escape_for_log(path));
  } catch (const std::exception& e) {
    spdlog::warn("no viewer feed: {}", e.what());
  }
}

// Composed on the loop once a second, and only while a viewer listens (a few microseconds).
void Daemon::publish_viewer_status(std::int64_t now) {
  if (!viewer_ || viewer_->readers() == 0 || now < next_viewer_status_ns_) return;
  next_viewer_status_ns_ = now + 1000 * kMs;
  const auto st = server_->stats();
  const auto feed = viewer_->stats();
  ViewerStatus v;
  v.time_ns = now;
  v.source = source_->description();
  v.source_problem = source_problem_;
  v.source_detail = source_->status_detail();
  v.nominal_rate_hz = source_->nominal_rate_hz();
  v.display = display_;
  v.samples_published = st.samples_published;
  v.events_published = st.events_published;
  v.markers_published = st.markers_published;
  v.subscribers = st.subscribers;
  v.classifier = classify_->description();
  v.calibration = calibration_->description();
  v.calibration_validation_json = calibration_->validation_json();
  v.recording = recorder_ ? recording_path_ : std::string();
  if (lsl_) v.lsl = lsl_->status();
  v.viewers = feed.readers;
  v.eye_frames_shown = feed.offered;
  v.eye_frames_missed = feed.dropped;
  viewer_->publish_status(to_json(v));
}

// The publishing loop tells the control side what it runs (daemon_changes.h), after every change.
// What the server's thread reports: markers it published (to the recording, through the loop, and
// to LSL at once) and subscribers coming and going (to the log).
void Daemon::watch_server() {
  server_->on_marker([this](const protocol::Marker& m, std::uint64_t sequence) {
    if (lsl_) lsl_->push(m);
    std::lock_guard lock(markers_mutex_);
    if (markers_in_.size() >= 4096) {
      ++markers_unrecorded_;
      return;
    }
    markers_in_.push_back(protocol::Record{sequence, m});
  });
  server_->on_subscriber_change([](const protocol::SubscriberInfo& s, const char* what) {
    spdlog::info("subscriber {} session {:016x}: {} (lease {} ms)", s.address.to_string(), s.session_id, what,
                 s.lease_ms);
  });
}

// The LSL outlets, named after [lsl] name and told apart between daemons on one host by the port.
bool Daemon::open_lsl_outlet_if_asked() {
  if (!config_.lsl.outlet) return true;
  LslOutletOptions o;
  o.name = config_.lsl.name;
  o.source_id = fmt::format("fovea-trackerd-{}", config_.network.port);
  o.nominal_rate_hz = source_->nominal_rate_hz();
  o.display = display_;
  o.device = source_->description();
  try {
    lsl_ = open_lsl_outlet(o);
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return false;
  }
  spdlog::info("LSL outlets \"{0} gaze\" (Gaze, {1} channels, {2} Hz), \"{0} markers\" (Markers: the experiment's "
               "markers, verbatim) and \"{0} events\" (GazeEvents: eye-movement events), source_id {3}-*; {4}",
               o.name, kLslGazeChannels.size(), o.nominal_rate_hz, o.source_id, lsl_library_info());
  return true;
}

void Daemon::publish_control_view() {
  RunningView v;
  v.config = config_;
  v.calibration_override = calibration_override_;
  v.display = display_;
  v.source_display = source_->display();
  v.source_description = source_->description();
  v.nominal_rate_hz = source_->nominal_rate_hz();
  v.running_calibration = calibration_->description();
  v.recording_path = recording_path_;
  v.start_dir = start_dir_;
  std::lock_guard lock(control_view_mutex_);
  control_view_ = std::move(v);
}

void Daemon::adopt_recording(PendingRecording& recording) {
  recording_path_ = recording.path();
  recorder_ = recording.adopt();
  spdlog::info("recording published gaze to {}", protocol::escape_for_log(recording_path_));
  publish_control_view();
}

std::string Daemon::stop_recording() {
  if (!recorder_) return "not recording";
  record_markers();  // every marker published before the stop is in the file
  const std::string what =
      "stopped recording to " + recording_path_ + " (" + std::to_string(recorder_->records_written()) + " records)";
  recorder_.reset();  // closes the file
  recording_path_.clear();
  spdlog::info("{}", protocol::escape_for_log(what));
  publish_control_view();
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

// Swaps in a prepared reload without closing the socket or dropping a session. Settings that need
// a restart (source, listen address, port, multicast, devices) were logged and kept.
protocol::ControlReply Daemon::apply_reload(PreparedReload& p, const std::string& why) {
  apply_display(p.next.display);
  if (p.calibration) {
    calibration_ = std::move(p.calibration);
    spdlog::info("calibration: {}{}", calibration_->description(),
                 calibration_override_ ? " (loaded by calibration-load; kept over reloads)" : "");
  }
  server_->set_limits(p.next.network.lease_ms, p.next.network.max_subscribers);
  if (p.restart_recording) {
    if (recorder_) stop_recording();
    if (p.recording) adopt_recording(p.recording);
  }
  if (p.classifier) {
    outgoing_.clear();
    classify_->flush(outgoing_);  // close the old classifier's open event before switching
    for (const GazeItem& pending : outgoing_) send(pending);
    classify_ = std::move(p.classifier);
    spdlog::info("classifier: {}", classify_->description());
  }
  spdlog::set_level(spdlog::level::from_str(p.next.log_level));
  for (const auto& c : p.changes.live) spdlog::info("applied: {}", c);
  config_ = p.next;
  publish_control_view();
  notifier_.reloaded(status_line());

  protocol::ControlReply out{protocol::ControlCommand::Reload, protocol::ControlResult::Ok, {}};
  if (!p.problems.empty()) {
    out.result = protocol::ControlResult::Failed;
    out.message.value = p.problems;
  } else {
    out.message.value = "reloaded: " + std::to_string(p.changes.live.size()) + " applied, " +
                        std::to_string(p.changes.needs_restart.size()) + " need a restart";
  }
  spdlog::info("{} ({})", p.problems.empty() ? out.message.value : "reload finished with problems", why);
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
  reload_worker_ = std::thread([this] { watch_reload_signal(); });
  if (run_.wait_subscribers > 0) {
    // As gpsfake does: hold the source until the expected clients are listening, so they see the
    // stream from its first sample (regression tests diff what they receive).
    spdlog::info("waiting for {} subscriber(s) before starting the source", run_.wait_subscribers);
    while (!stopping() && server_->stats().subscribers < run_.wait_subscribers) {
      service_tick();
      if (mailbox_.pending()) mailbox_.drain();
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }

  const std::int64_t end_ns =
      run_.duration_s > 0 ? start_ns + static_cast<std::int64_t>(run_.duration_s * 1e9) : INT64_MAX;
  bool source_ended = false;
  std::optional<GazeItem> item;  // the next item, waiting for its time
  std::optional<std::int64_t> item_receive_ns;  // when it reached this host, if the source says
  std::vector<protocol::Marker> item_markers;    // met by the source on the way to it
  while (!stopping()) {
    if (mailbox_.pending()) mailbox_.drain();  // prepared changes, swapped in between two items
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
      item_receive_ns = item ? source_->last_receive_ns() : std::nullopt;
      item_markers = source_->take_markers();
      if (!item && !source_->ended()) {  // a device with nothing yet, or interrupted: attend, go on
        if (monotonic_ns() >= end_ns) break;
        service_tick();
        continue;
      }
      if (!item) {
        for (const protocol::Marker& m : item_markers) server_->publish(m);  // those after the last item
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
    if (w == Wake::Attention) continue;  // swap changes in, then wait for the same item again
    publish(std::move(*item), item_receive_ns, item_markers);
    item.reset();
  }

  shut_down();
  return status_;
}

// Stops the helper threads and the server, then logs what was done.
void Daemon::shut_down() {
  watcher_stop_ = true;
  if (watcher_.joinable()) watcher_.join();
  notifier_.stopping();
  mailbox_.close();
  if (reload_worker_.joinable()) reload_worker_.join();
  control_socket_.reset();
  if (viewer_) {
    source_->show_eye_frames(nullptr);
    const auto ef = viewer_->stats();
    spdlog::info("viewer feed: {} eye frames shown, {} sent, {} messages missed by slow viewers, {} viewers turned away",
                 ef.offered, ef.sent, ef.dropped, ef.refused);
    viewer_.reset();
  }
  const auto st = server_->stats();
  server_->stop();
  spdlog::info(
      "stopped: {} samples and {} events published, {} datagrams sent, {} send failures, {} rejected, "
      "{} leases expired, {} control requests, {} control requests refused{}",
      st.samples_published, st.events_published, st.datagrams_sent, st.send_failures, st.datagrams_rejected,
      st.leases_expired, st.control_requests, st.control_refused,
      recorder_ ? ", " + std::to_string(recorder_->records_written()) + " records written" : std::string());
  // The source's counts in full: a network source's run past 256 characters (its arrival rules last).
  if (const std::string detail = source_->status_detail(); !detail.empty()) {
    spdlog::info("{}: {}", protocol::escape_for_log(source_->description()), protocol::escape_for_log(detail, 1024));
  }
  // liblsl 1.16's outlet destructor can crash while consumers are still connected: it frees its
  // sample factory before the consumer queues that hold samples from it (sccn/liblsl#218, fixed
  // after 1.16.2; fovea-trackerd died with SIGSEGV after "stopped" in 1 CI run of the LslOutlet
  // test). The daemon exits next, so the outlet is left to the process's end: its streams go when
  // the process does, as they would have a moment earlier. Held by a global so that LeakSanitizer
  // sees it reachable (a plain pointer: no destructor runs at exit either).
  if (lsl_) lsl_outlet_left_to_exit = lsl_.release();
}

}  // namespace

LslOutlet* lsl_outlet_left_to_exit = nullptr;  // NOLINT(cppcoreguidelines-avoid-non-const-global-variables)

int run_daemon(const service::DaemonConfig& config, const RunOptions& run, const DaemonSignals& signals,
               ConfigLoader reload_config) {
  Daemon d(config, run, signals, std::move(reload_config));
  return d.run();
}

}  // namespace fovea::trackerd
