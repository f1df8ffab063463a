// SPDX-License-Identifier: Apache-2.0
#include "daemon_changes.h"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <system_error>

#include "fovea/protocol/bounded_file.h"
#include "fovea/protocol/clock.h"
#include "service/control_paths.h"

namespace fovea::trackerd {

std::string RunningView::recordings_dir() const {
  return config.network.control_dir.empty() ? start_dir : config.network.control_dir;
}

std::string RunningView::calibrations_dir() const {
  return config.network.calibration_dir.empty() ? recordings_dir() : config.network.calibration_dir;
}

// ---- recordings ------------------------------------------------------------------------------

PendingRecording::PendingRecording(const std::string& path, bool append, const RunningView& view,
                                   const protocol::DisplayGeometry& display)
    : path_(path), display_(display) {
  protocol::RecordingHeader h;
  h.device = protocol::recording_device_name(view.source_description);
  h.display = display;
  h.nominal_rate_hz = view.nominal_rate_hz;
  h.clock = protocol::RecordingClock::Monotonic;
  h.created_unix_ns = protocol::realtime_ns();
  h.created_clock_ns = protocol::monotonic_ns();
  std::error_code ec;
  // CreateNew makes the file or fails (O_EXCL); Append makes it only where none was.
  const bool existed = append && std::filesystem::symlink_status(path, ec).type() != std::filesystem::file_type::not_found;
  writer_ = std::make_unique<protocol::RecordingWriter>(
      path, h, append ? protocol::RecordingWriter::Mode::Append : protocol::RecordingWriter::Mode::CreateNew);
  created_ = !existed;
}

PendingRecording& PendingRecording::operator=(PendingRecording&& other) noexcept {
  if (this != &other) {
    discard();
    writer_ = std::move(other.writer_);
    path_ = std::move(other.path_);
    display_ = other.display_;
    created_ = other.created_;
  }
  return *this;
}

PendingRecording::~PendingRecording() { discard(); }

void PendingRecording::discard() {
  if (!writer_) return;
  const bool remove = created_ && writer_->records_written() == 0;
  writer_.reset();
  if (remove && ::unlink(path_.c_str()) != 0 && errno != ENOENT) {
    spdlog::warn("could not remove the unused recording {}: {}", protocol::escape_for_log(path_), std::strerror(errno));
  }
}

std::unique_ptr<protocol::RecordingWriter> PendingRecording::adopt() {
  created_ = false;
  return std::move(writer_);
}

PendingRecording prepare_record_start(const std::string& requested, const RunningView& view) {
  if (requested.empty()) throw std::runtime_error("record-start needs a file path");
  if (!view.recording_path.empty()) {
    throw std::runtime_error("already recording to " + protocol::escape_for_log(view.recording_path));
  }
  const std::string path = service::confined_path(requested, view.recordings_dir());
  return PendingRecording(path, false, view, view.display);
}

// ---- calibration -----------------------------------------------------------------------------

PreparedCalibration prepare_calibration_load(const std::string& argument, const RunningView& view) {
  if (argument.empty()) throw std::runtime_error("calibration-load needs a file, none or configured");
  PreparedCalibration out;
  out.display = view.display;
  out.override_file =
      argument == "configured" ? std::nullopt : std::optional<std::string>(argument == "none" ? "" : argument);
  if (!out.override_file) {
    out.stage = service::load_calibration_stage(view.config.calibration.file, view.display);
  } else if (out.override_file->empty()) {
    out.stage = service::load_calibration_stage("", view.display);
  } else {
    // A client names this file: inside the calibrations directory, never through a link.
    out.override_file = service::confined_path(argument, view.calibrations_dir(), "calibration-load",
                                               "calibrations directory");
    out.stage = service::load_calibration_stage(*out.override_file, view.display, /*follow_symlinks=*/false);
  }
  return out;
}

// ---- reload ----------------------------------------------------------------------------------

namespace {

// The calibration a reload runs with: calibration-load's file if one is in force (it was confined
// when it was loaded: read it again without links), else the configured one; read again even when
// the name is unchanged, as the file may have been refitted.
void reload_calibration(const RunningView& view, PreparedReload& p) {
  try {
    p.calibration = view.calibration_override
                        ? service::load_calibration_stage(*view.calibration_override, p.display, false)
                        : service::load_calibration_stage(p.next.calibration.file, p.display);
  } catch (const std::exception& e) {
    spdlog::error("{}; keeping the previous calibration", e.what());
    p.next.calibration = view.config.calibration;
    p.problems = e.what();
  }
}

void reload_recording(const RunningView& view, PreparedReload& p) {
  if (p.next.record == view.config.record) return;
  p.restart_recording = true;
  if (p.next.record.path.empty()) return;
  try {
    p.recording = PendingRecording(p.next.record.path, p.next.record.append, view, p.display);
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    p.problems = e.what();
  }
}

// A new stage for a new method, PSO convention or pursuit weight, or a new display (the stage labels on it and
// places its events on it); it starts afresh, as at a method change.
void reload_classifier(const RunningView& view, PreparedReload& p) {
  if (p.next.classifier == view.config.classifier && p.display == view.display) return;
  try {
    const service::ClassifierConfig& next = p.next.classifier;
    p.classifier = std::make_unique<ClassifyStage>(next.method, view.nominal_rate_hz, p.display, next.pso_convention(),
                                                   next.pursuit_weight);
  } catch (const std::exception& e) {
    spdlog::error("classifier {}: {}; keeping the running one", p.next.classifier.method, e.what());
    p.next.classifier = view.config.classifier;
  }
}

}  // namespace

PreparedReload prepare_reload(const RunningView& view, const ConfigLoader& loader) {
  PreparedReload p;
  service::DaemonConfig read = loader ? loader() : view.config;
  p.changes = service::diff(view.config, read);
  for (const auto& c : p.changes.needs_restart) spdlog::warn("{}: needs a restart; keeping the running value", c);
  p.next = service::adopt_live(view.config, read);
  p.display = p.next.display.value_or(view.source_display);
  reload_calibration(view, p);
  reload_recording(view, p);
  reload_classifier(view, p);
  return p;
}

}  // namespace fovea::trackerd
