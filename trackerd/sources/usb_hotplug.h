// SPDX-License-Identifier: Apache-2.0
#pragma once
// USB hotplug: a table of known tracker/camera VID:PIDs, a watcher that reports known devices
// arriving and leaving, and a supervisor that keeps one wanted device open across unplug/replug.
//
//   UsbEnumerator     what is attached now (real: libusb; tests: FakeUsbEnumerator-like fakes)
//   UsbWatcher        diffs successive snapshots, calls on_arrival/on_departure for known devices
//   DeviceSupervisor  a FrameSource that opens the wanted device on arrival, closes it on departure,
//                     re-opens it on return, and reports "waiting for ..." while it is away
//
// Threading: UsbWatcher::poll() runs the callbacks on the calling thread; start() runs poll() on the
// watcher's own thread (waking on libusb hotplug events, or every interval when polling), so the
// callbacks then come from that thread. Callbacks are never run concurrently with each other. The
// supervisor's on_arrival/on_departure only queue the event under a mutex; opening and closing
// happen in its next(), on the consumer's thread, so a device is never closed under a reader.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "source_api/frame_source.h"
#include "sources/v4l2_camera.h"
#include "sources/v4l2_device.h"

namespace fovea::trackerd {

enum class UsbDeviceKind { camera, hid };

// One row of the config's [[devices]] table.
struct KnownDevice {
  std::uint16_t vid = 0, pid = 0;
  UsbDeviceKind kind = UsbDeviceKind::camera;
  std::string name;
};

// Builds a table row from the config's strings ("0x046d" or "046d", "camera" | "hid"); throws
// std::invalid_argument naming `where` (e.g. "fovea.toml [[devices]] #2") and the allowed values.
KnownDevice parse_known_device(const std::string& vid, const std::string& pid, const std::string& kind,
                               const std::string& name, const std::string& where);
std::string usb_id(std::uint16_t vid, std::uint16_t pid);  // "046d:0825"

struct UsbDeviceInfo {
  std::uint16_t vid = 0, pid = 0;
  std::uint8_t bus = 0, address = 0;  // identifies one plugged-in instance
  bool operator==(const UsbDeviceInfo&) const = default;
};

class UsbEnumerator {
 public:
  virtual ~UsbEnumerator() = default;
  // The devices attached now.
  virtual std::vector<UsbDeviceInfo> devices() = 0;
  // Blocks up to timeout_ms or until the set of devices may have changed.
  virtual void wait(int timeout_ms) = 0;
  virtual std::string mechanism() const = 0;  // "libusb hotplug", "libusb polling", "fake"
};

// libusb: hotplug callbacks when libusb_has_capability(LIBUSB_CAP_HAS_HOTPLUG), otherwise
// libusb_get_device_list on each devices() call. Throws std::runtime_error when libusb cannot start.
std::unique_ptr<UsbEnumerator> make_libusb_enumerator();

class UsbWatcher {
 public:
  using Callback = std::function<void(const KnownDevice&, const UsbDeviceInfo&)>;
  UsbWatcher(std::unique_ptr<UsbEnumerator> enumerator, std::vector<KnownDevice> table, Callback on_arrival,
             Callback on_departure);
  ~UsbWatcher();
  UsbWatcher(const UsbWatcher&) = delete;
  UsbWatcher& operator=(const UsbWatcher&) = delete;

  // One pass: devices known to the table that appeared since the last pass get on_arrival, those
  // gone get on_departure (devices present at the first pass arrive then). Unknown devices are
  // ignored. Thread-safe.
  void poll();
  // Runs poll() on the watcher's thread until stop() (or destruction); interval_ms bounds the wait
  // between passes when the enumerator has no hotplug events.
  void start(int interval_ms = 1000);
  void stop();
  std::string mechanism() const { return enumerator_->mechanism(); }
  const KnownDevice* known(std::uint16_t vid, std::uint16_t pid) const;

 private:
  std::unique_ptr<UsbEnumerator> enumerator_;
  std::vector<KnownDevice> table_;
  Callback on_arrival_, on_departure_;
  std::mutex poll_mutex_;
  std::vector<UsbDeviceInfo> present_;  // known devices seen at the last pass
  std::atomic<bool> running_{false};
  std::thread thread_;
};

// Keeps one wanted device (by VID:PID) open as a FrameSource across unplug and replug.
class DeviceSupervisor final : public FrameSource {
 public:
  // Opens a source for the arrived device; throws (any std::exception) when it cannot, e.g. its
  // /dev/videoN node has not appeared yet: the supervisor then retries every retry_interval_ms while
  // the device stays plugged in.
  using Opener = std::function<std::unique_ptr<FrameSource>(const UsbDeviceInfo&)>;
  using Clock = std::function<std::int64_t()>;
  DeviceSupervisor(KnownDevice wanted, Opener open, int retry_interval_ms = 1000, Clock clock = nullptr);

  // Thread-safe; to be called from UsbWatcher's callbacks (events for other devices are ignored).
  void on_arrival(const KnownDevice& known, const UsbDeviceInfo& device);
  void on_departure(const KnownDevice& known, const UsbDeviceInfo& device);

  FrameSourceStatus status() const override;
  // Applies queued arrivals/departures (opening/closing), then reads from the open source; nullopt
  // while the device is away.
  std::optional<EyeFrame> next(int timeout_ms) override;
  bool is_open() const;
  std::uint64_t opens() const;

 private:
  struct Event {
    bool arrival;
    UsbDeviceInfo device;
  };
  void apply_events();
  void try_open();
  void set_state(bool healthy, const std::string& problem);

  KnownDevice wanted_;
  Opener open_;
  int retry_interval_ms_;
  Clock clock_;

  std::unique_ptr<FrameSource> source_;      // touched only on the consumer's thread
  std::optional<UsbDeviceInfo> present_;     // the plugged-in instance, if any
  std::int64_t next_retry_ns_ = 0;
  std::uint64_t frames_before_ = 0, dropped_before_ = 0;  // from earlier opens

  mutable std::mutex mutex_;  // guards events_, opens_, status_
  std::condition_variable event_arrived_;
  std::deque<Event> events_;
  std::uint64_t opens_ = 0;
  FrameSourceStatus status_;
};

// An Opener for cameras: maps VID:PID (and bus/address) to its /dev/videoN through `nodes` and
// opens V4l2Camera with `options` (its device field is replaced).
DeviceSupervisor::Opener camera_opener(V4l2CameraOptions options, std::shared_ptr<const VideoNodeDirectory> nodes,
                                       std::shared_ptr<V4l2Device> device = real_v4l2_device());

}  // namespace fovea::trackerd
