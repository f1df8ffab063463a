// SPDX-License-Identifier: Apache-2.0
#pragma once
// What reload, record-start and calibration-load change, prepared off the publishing loop (issue 23:
// nothing slow on the publishing thread). The control thread and the SIGHUP worker read the
// configuration and calibration files, open recordings and build stages against a RunningView, the
// loop's last published picture of itself; the loop then only swaps the results in. The daemon
// prepares one change at a time, so the view a change was prepared against is still the loop's
// state when the loop applies it.
#include <memory>
#include <optional>
#include <string>

#include "classify_stage.h"
#include "daemon.h"
#include "fovea/protocol/display_geometry.h"
#include "fovea/protocol/recording.h"
#include "service/calibration_stage.h"
#include "service/config.h"

namespace fovea::trackerd {

// What the control side knows of the running daemon; the publishing loop publishes a copy after
// every change it makes.
struct RunningView {
  service::DaemonConfig config;                     // the running configuration
  std::optional<std::string> calibration_override;  // calibration-load's file, kept over reloads ("": none)
  protocol::DisplayGeometry display;                // what clients are told
  protocol::DisplayGeometry source_display;         // the source's own geometry
  std::string source_description;
  double nominal_rate_hz = 0;
  std::string running_calibration;  // its description, for the log
  std::string recording_path;       // "": not recording
  std::string start_dir;            // the daemon's working directory when it started

  // Where record-start creates files: [network] control_dir, else start_dir.
  std::string recordings_dir() const;
  // Where calibration-load reads files: [network] calibration_dir, else recordings_dir().
  std::string calibrations_dir() const;
};

// A recording opened off the loop. Until adopt() hands its writer over it owns the file, and a file
// it created is removed again when it is dropped: a record-start or reload that was not carried out
// (the loop busy past the reply's deadline, the daemon stopping) leaves nothing behind.
class PendingRecording {
 public:
  PendingRecording() = default;
  // Creates `path` (append: opens it to append) with a header for `display` and the view's source.
  // Throws std::runtime_error naming the file and what is wrong.
  PendingRecording(const std::string& path, bool append, const RunningView& view,
                   const protocol::DisplayGeometry& display);
  PendingRecording(PendingRecording&&) noexcept = default;
  PendingRecording& operator=(PendingRecording&& other) noexcept;
  PendingRecording(const PendingRecording&) = delete;
  PendingRecording& operator=(const PendingRecording&) = delete;
  ~PendingRecording();

  explicit operator bool() const { return writer_ != nullptr; }
  const std::string& path() const { return path_; }
  const protocol::DisplayGeometry& display() const { return display_; }
  std::unique_ptr<protocol::RecordingWriter> adopt();  // the loop takes the file over

 private:
  void discard();
  std::unique_ptr<protocol::RecordingWriter> writer_;
  std::string path_;
  protocol::DisplayGeometry display_;
  bool created_ = false;  // this object made the file: remove it if it is never adopted
};

// record-start PATH: the path confined to the recordings directory (service/control_paths.h) and
// the recording created there. Throws std::runtime_error with what is wrong, the path escaped.
PendingRecording prepare_record_start(const std::string& requested, const RunningView& view);

// calibration-load ARGUMENT ("none", "configured" or a file confined to the calibrations
// directory and never read through a symbolic link): the loaded stage, checked against the
// display clients are told. Throws std::runtime_error with what is wrong.
struct PreparedCalibration {
  std::unique_ptr<service::CalibrationStage> stage;
  std::optional<std::string> override_file;  // what becomes RunningView::calibration_override
  protocol::DisplayGeometry display;         // checked against this display
};
PreparedCalibration prepare_calibration_load(const std::string& argument, const RunningView& view);

// A reload, ready to swap in: the configuration read again (with the command line's overrides) and
// every file and stage it names loaded. What failed keeps its running value and is in `problems`.
struct PreparedReload {
  service::DaemonConfig next;      // what the daemon runs afterwards
  service::ConfigChanges changes;  // against the running configuration
  protocol::DisplayGeometry display;  // what clients are told afterwards
  std::unique_ptr<service::CalibrationStage> calibration;  // null: keep the running one
  bool restart_recording = false;  // [record] changed: stop the running recording, adopt `recording`
  PendingRecording recording;      // empty: record nothing
  std::unique_ptr<ClassifyStage> classifier;  // null: keep the running one
  std::string problems;                       // "" when everything was adopted
};
// Throws what `loader` throws (an invalid configuration: nothing to apply). Logs what it loads.
PreparedReload prepare_reload(const RunningView& view, const ConfigLoader& loader);

}  // namespace fovea::trackerd
