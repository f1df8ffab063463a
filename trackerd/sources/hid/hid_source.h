// SPDX-License-Identifier: Apache-2.0
#pragma once
// `hid[:VID:PID]`: a gaze source for trackers that speak the USB HID "Eye and Head Trackers" usage
// page (0x12) — the standard consumer trackers implement for operating-system eye control. Opens
// the device with hidapi (hidraw backend), reads and parses its report descriptor, finds the eye
// tracker usages (eye_tracker.h) and turns Input reports into gaze samples on CLOCK_MONOTONIC.
//
// When the device goes away while streaming, next() does not end the source: status() turns
// unhealthy with the reason, and next() keeps trying to reopen it every retry interval until it is
// back (or interrupt() is called, when next() returns nullopt).
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "source_api/gaze_source.h"
#include "sources/hid/eye_tracker.h"
#include "sources/hid/report_descriptor.h"
#include "source_api/tracker_clock.h"

namespace fovea::trackerd::hid {

// "hid" (any eye tracker) or "hid:VID:PID" (hexadecimal, optional 0x).
struct HidSpec {
  std::optional<std::uint16_t> vendor_id, product_id;
};
// Throws std::invalid_argument naming the spec and the allowed form.
HidSpec parse_hid_spec(const std::string& spec);

// One enumerated HID interface (a top-level collection), as hidapi reports it.
struct HidDeviceSummary {
  std::string path;  // /dev/hidrawN for the hidraw backend
  std::uint16_t vendor_id = 0, product_id = 0;
  std::uint16_t usage_page = 0, usage = 0;  // 0 when the backend does not report them
  std::string manufacturer, product;
};

// "/dev/hidraw3" -> "/sys/class/hidraw/hidraw3/device/report_descriptor"; empty if `path` is not
// a hidraw node.
std::string hidraw_descriptor_path(const std::string& device_path, const std::string& sysfs_root = "/sys");

// The "no eye tracker" message: which devices there are and that none speaks usage page 0x12.
std::string no_eye_tracker_message(const HidSpec& spec, const std::vector<HidDeviceSummary>& present);
// The "permission denied" message, naming the node and the udev rule that grants access.
std::string permission_message(const std::string& device_path, const HidDeviceSummary& device);

struct HidSourceStatus {
  std::string device;          // "/dev/hidraw3 (1234:5678 Acme Eye Tracker 5)"
  bool healthy = true;
  std::string problem;         // why not healthy, and what is being done about it
  std::optional<std::int64_t> configuration_status;  // the tracker's own, when it reports it
  std::uint64_t samples = 0;
  std::uint64_t reports_rejected = 0;  // unknown ID, too short, empty
  std::uint64_t other_reports = 0;     // valid Input reports that carry no gaze
  std::uint64_t reconnects = 0;
  std::uint64_t clock_resets = 0;
};

struct HidSourceOptions {
  std::string spec = "hid";
  protocol::DisplayGeometry fallback_display;  // used where the tracker reports no screen size
  int retry_interval_ms = 1000;
  int read_timeout_ms = 100;   // how often a blocked next() checks interrupt()
  double assumed_rate_hz = 60; // nominal rate when the tracker reports no sampling frequency
  // A device from the configuration's known-device table may be absent at start: instead of
  // throwing, the source reports it unhealthy and opens it once it is plugged in (hotplug).
  bool wait_for_device = false;
};

class HidSource final : public GazeSource {
 public:
  // Opens the first matching device; throws std::runtime_error with a message a user can act on
  // (no device: which there are; permission denied: which node and which udev rule; descriptor
  // without the eye tracker usages: what it has instead).
  explicit HidSource(HidSourceOptions options);
  ~HidSource() override;
  HidSource(const HidSource&) = delete;
  HidSource& operator=(const HidSource&) = delete;

  std::string description() const override;
  protocol::DisplayGeometry display() const override;
  double nominal_rate_hz() const override;
  // Blocks until the next gaze report. While the device is lost it retries opening it; returns
  // nullopt only after interrupt().
  std::optional<GazeItem> next() override;

  HidSourceStatus status() const;  // thread-safe
  void interrupt() override;       // thread-safe, one-shot: next() returns nullopt within read_timeout_ms
  bool ended() const override { return false; }  // a device never ends; it is lost and reopened
  std::string problem() const override {
    const HidSourceStatus s = status();
    return s.healthy ? std::string() : s.problem;
  }
  const EyeTrackerLayout& layout() const { return decoder_->layout(); }

 private:
  struct Device;
  void open_device();  // throws std::runtime_error
  void lose_device(const std::string& why);
  bool try_reopen();
  void read_features();

  HidSourceOptions options_;
  HidSpec spec_;
  std::unique_ptr<Device> device_;
  std::optional<EyeTrackerDecoder> decoder_;
  std::optional<TrackerClock> clock_;
  protocol::DisplayGeometry display_;
  double rate_hz_ = 0;
  bool rate_reported_ = false;
  protocol::Normalized hold_{0.5, 0.5};
  std::int64_t next_retry_ns_ = 0;
  std::atomic<bool> interrupted_{false};
  mutable std::mutex status_mutex_;
  HidSourceStatus status_;
  std::string description_;
};

}  // namespace fovea::trackerd::hid

namespace fovea::trackerd {

// The factory the daemon's make_source uses for "hid" and "hid:VID:PID" (returns a
// hid::HidSource; dynamic_cast to reach status() and interrupt()). Throws std::invalid_argument for
// a malformed spec and std::runtime_error when no usable tracker can be opened.
std::unique_ptr<GazeSource> make_hid_source(const std::string& spec, const protocol::DisplayGeometry& fallback_display,
                                            bool wait_for_device = false);

}  // namespace fovea::trackerd
