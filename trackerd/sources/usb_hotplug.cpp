// SPDX-License-Identifier: Apache-2.0
#include "sources/usb_hotplug.h"

#include <libusb.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cstdio>
#include <stdexcept>

namespace fovea::trackerd {

namespace {

std::int64_t steady_now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

std::uint16_t parse_usb_hex(const std::string& text, const char* field, const std::string& where) {
  std::string digits = text;
  if (digits.rfind("0x", 0) == 0 || digits.rfind("0X", 0) == 0) digits = digits.substr(2);
  std::uint16_t value = 0;
  const auto r = std::from_chars(digits.data(), digits.data() + digits.size(), value, 16);
  if (digits.empty() || digits.size() > 4 || r.ec != std::errc{} || r.ptr != digits.data() + digits.size()) {
    throw std::invalid_argument(where + ": " + field + " = \"" + text +
                                "\" is not a USB id (1 to 4 hex digits, e.g. \"0x046d\")");
  }
  return value;
}

std::string describe(const KnownDevice& d) {
  return (d.name.empty() ? std::string("USB device") : d.name) + " (" + usb_id(d.vid, d.pid) + ")";
}

// libusb, with hotplug callbacks keeping the device list when the platform supports them.
class LibusbEnumerator final : public UsbEnumerator {
 public:
  LibusbEnumerator() {
    if (const int r = libusb_init(&context_); r != 0) {
      context_ = nullptr;
      throw std::runtime_error(std::string("USB: libusb cannot start (") + libusb_strerror(r) +
                               "); is /dev/bus/usb available?");
    }
    if (libusb_has_capability(LIBUSB_CAP_HAS_HOTPLUG) != 0) {
      const int r = libusb_hotplug_register_callback(
          context_,
          static_cast<libusb_hotplug_event>(LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED | LIBUSB_HOTPLUG_EVENT_DEVICE_LEFT),
          LIBUSB_HOTPLUG_ENUMERATE, LIBUSB_HOTPLUG_MATCH_ANY, LIBUSB_HOTPLUG_MATCH_ANY, LIBUSB_HOTPLUG_MATCH_ANY,
          &LibusbEnumerator::hotplug_callback, this, &handle_);
      hotplug_ = r == LIBUSB_SUCCESS;
    }
  }
  ~LibusbEnumerator() override {
    if (hotplug_) libusb_hotplug_deregister_callback(context_, handle_);
    if (context_ != nullptr) libusb_exit(context_);
  }
  LibusbEnumerator(const LibusbEnumerator&) = delete;
  LibusbEnumerator& operator=(const LibusbEnumerator&) = delete;

  std::vector<UsbDeviceInfo> devices() override {
    if (hotplug_) {
      timeval zero{0, 0};
      libusb_handle_events_timeout_completed(context_, &zero, nullptr);  // deliver pending events
      return known_;
    }
    std::vector<UsbDeviceInfo> list;
    libusb_device** devs = nullptr;
    const ssize_t n = libusb_get_device_list(context_, &devs);
    for (ssize_t i = 0; i < n; ++i) {
      if (const auto info = describe_device(devs[i])) list.push_back(*info);
    }
    if (devs != nullptr) libusb_free_device_list(devs, 1);
    return list;
  }

  void wait(int timeout_ms) override {
    const int ms = std::max(timeout_ms, 0);
    if (hotplug_) {
      timeval tv{ms / 1000, static_cast<suseconds_t>((ms % 1000) * 1000)};
      libusb_handle_events_timeout_completed(context_, &tv, nullptr);
    } else {
      std::this_thread::sleep_for(std::chrono::milliseconds(ms));
    }
  }

  std::string mechanism() const override { return hotplug_ ? "libusb hotplug" : "libusb polling"; }

 private:
  static std::optional<UsbDeviceInfo> describe_device(libusb_device* dev) {
    libusb_device_descriptor d{};
    if (libusb_get_device_descriptor(dev, &d) != 0) return std::nullopt;
    return UsbDeviceInfo{d.idVendor, d.idProduct, libusb_get_bus_number(dev), libusb_get_device_address(dev)};
  }

  // Runs inside libusb_handle_events_* on the thread that calls devices()/wait().
  static int LIBUSB_CALL hotplug_callback(libusb_context*, libusb_device* dev, libusb_hotplug_event event,
                                          void* self) {
    auto& known = static_cast<LibusbEnumerator*>(self)->known_;
    const std::uint8_t bus = libusb_get_bus_number(dev), address = libusb_get_device_address(dev);
    known.erase(std::remove_if(known.begin(), known.end(),
                               [&](const UsbDeviceInfo& i) { return i.bus == bus && i.address == address; }),
                known.end());
    if (event == LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED) {
      if (const auto info = describe_device(dev)) known.push_back(*info);
    }
    return 0;  // stay registered
  }

  libusb_context* context_ = nullptr;
  libusb_hotplug_callback_handle handle_ = 0;
  bool hotplug_ = false;
  std::vector<UsbDeviceInfo> known_;  // hotplug mode: kept by the callback
};

}  // namespace

std::string usb_id(std::uint16_t vid, std::uint16_t pid) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "%04x:%04x", static_cast<unsigned>(vid), static_cast<unsigned>(pid));
  return buf;
}

KnownDevice parse_known_device(const std::string& vid, const std::string& pid, const std::string& kind,
                               const std::string& name, const std::string& where) {
  KnownDevice d;
  d.vid = parse_usb_hex(vid, "vid", where);
  d.pid = parse_usb_hex(pid, "pid", where);
  if (kind == "camera") {
    d.kind = UsbDeviceKind::camera;
  } else if (kind == "hid") {
    d.kind = UsbDeviceKind::hid;
  } else {
    throw std::invalid_argument(where + ": kind = \"" + kind + "\" is not one of \"camera\", \"hid\"");
  }
  d.name = name.empty() ? usb_id(d.vid, d.pid) : name;
  return d;
}

std::unique_ptr<UsbEnumerator> make_libusb_enumerator() { return std::make_unique<LibusbEnumerator>(); }

UsbWatcher::UsbWatcher(std::unique_ptr<UsbEnumerator> enumerator, std::vector<KnownDevice> table,
                       Callback on_arrival, Callback on_departure)
    : enumerator_(std::move(enumerator)),
      table_(std::move(table)),
      on_arrival_(std::move(on_arrival)),
      on_departure_(std::move(on_departure)) {}

UsbWatcher::~UsbWatcher() { stop(); }

const KnownDevice* UsbWatcher::known(std::uint16_t vid, std::uint16_t pid) const {
  for (const auto& k : table_) {
    if (k.vid == vid && k.pid == pid) return &k;
  }
  return nullptr;
}

void UsbWatcher::poll() {
  std::lock_guard lock(poll_mutex_);
  std::vector<UsbDeviceInfo> now;
  for (const auto& d : enumerator_->devices()) {
    if (known(d.vid, d.pid) != nullptr) now.push_back(d);
  }
  const auto contains = [](const std::vector<UsbDeviceInfo>& v, const UsbDeviceInfo& d) {
    return std::find(v.begin(), v.end(), d) != v.end();
  };
  for (const auto& d : present_) {
    if (!contains(now, d) && on_departure_) on_departure_(*known(d.vid, d.pid), d);
  }
  for (const auto& d : now) {
    if (!contains(present_, d) && on_arrival_) on_arrival_(*known(d.vid, d.pid), d);
  }
  present_ = std::move(now);
}

void UsbWatcher::start(int interval_ms) {
  if (running_.exchange(true)) return;
  thread_ = std::thread([this, interval_ms] {
    while (running_) {
      poll();
      enumerator_->wait(std::min(interval_ms, 200));  // short waits keep stop() prompt
    }
  });
}

void UsbWatcher::stop() {
  running_ = false;
  if (thread_.joinable()) thread_.join();
}

DeviceSupervisor::DeviceSupervisor(KnownDevice wanted, Opener open, int retry_interval_ms, Clock clock)
    : wanted_(std::move(wanted)),
      open_(std::move(open)),
      retry_interval_ms_(std::max(retry_interval_ms, 0)),
      clock_(clock ? std::move(clock) : Clock(steady_now_ns)) {
  status_.description = "usb:" + usb_id(wanted_.vid, wanted_.pid) + " (" + wanted_.name + ")";
  status_.healthy = false;
  status_.problem = "waiting for " + describe(wanted_) + " to be plugged in";
}

void DeviceSupervisor::on_arrival(const KnownDevice& known, const UsbDeviceInfo& device) {
  if (known.vid != wanted_.vid || known.pid != wanted_.pid) return;
  {
    std::lock_guard lock(mutex_);
    events_.push_back({true, device});
  }
  event_arrived_.notify_all();
}

void DeviceSupervisor::on_departure(const KnownDevice& known, const UsbDeviceInfo& device) {
  if (known.vid != wanted_.vid || known.pid != wanted_.pid) return;
  {
    std::lock_guard lock(mutex_);
    events_.push_back({false, device});
  }
  event_arrived_.notify_all();
}

void DeviceSupervisor::set_state(bool healthy, const std::string& problem) {
  std::lock_guard lock(mutex_);
  status_.healthy = healthy;
  status_.problem = problem;
}

void DeviceSupervisor::apply_events() {
  std::deque<Event> events;
  {
    std::lock_guard lock(mutex_);
    events.swap(events_);
  }
  for (const auto& e : events) {
    if (e.arrival) {
      if (present_ && *present_ == e.device) continue;
      if (source_) {  // a second instance while one is open: keep the open one
        continue;
      }
      present_ = e.device;
      next_retry_ns_ = 0;  // open at once
      continue;
    }
    if (!present_ || !(*present_ == e.device)) continue;
    if (source_) {
      const FrameSourceStatus s = source_->status();
      frames_before_ += s.frames;
      dropped_before_ += s.dropped;
      source_.reset();  // closes the device; it is gone, so errors while closing are ignored
    }
    present_.reset();
    std::lock_guard lock(mutex_);
    status_.frames = frames_before_;
    status_.dropped = dropped_before_;
    status_.healthy = false;
    status_.problem = describe(wanted_) + " was unplugged; waiting for it to return";
  }
}

void DeviceSupervisor::try_open() {
  const std::int64_t now = clock_();
  if (source_ || !present_ || now < next_retry_ns_) return;
  try {
    source_ = open_(*present_);
    std::lock_guard lock(mutex_);
    ++opens_;
    const FrameSourceStatus s = source_->status();
    status_.description = "usb:" + usb_id(wanted_.vid, wanted_.pid) + " (" + wanted_.name + ") " + s.description;
    status_.healthy = s.healthy;
    status_.problem = s.problem;
  } catch (const std::exception& e) {
    source_.reset();
    next_retry_ns_ = now + std::int64_t{retry_interval_ms_} * 1'000'000;
    set_state(false, describe(wanted_) + " is plugged in but cannot be opened: " + e.what() + "; retrying every " +
                         std::to_string(retry_interval_ms_) + " ms");
  }
}

std::optional<EyeFrame> DeviceSupervisor::next(int timeout_ms) {
  apply_events();
  try_open();
  if (!source_) {
    // Wait for an arrival rather than spinning; a retry due sooner cuts the wait short.
    std::int64_t wait_ms = std::max(timeout_ms, 0);
    if (present_) wait_ms = std::min<std::int64_t>(wait_ms, std::max<std::int64_t>(0, (next_retry_ns_ - clock_()) / 1'000'000));
    {
      std::unique_lock lock(mutex_);
      event_arrived_.wait_for(lock, std::chrono::milliseconds(wait_ms), [&] { return !events_.empty(); });
    }
    apply_events();
    try_open();
    if (!source_) return std::nullopt;
  }
  std::optional<EyeFrame> frame;
  try {
    frame = source_->next(timeout_ms);
  } catch (const std::exception& e) {
    // Sources report loss through status(), but a throwing one must not take the daemon down.
    const FrameSourceStatus s = source_->status();
    frames_before_ += s.frames;
    dropped_before_ += s.dropped;
    source_.reset();
    next_retry_ns_ = clock_() + std::int64_t{retry_interval_ms_} * 1'000'000;
    set_state(false, describe(wanted_) + ": " + e.what() + "; re-opening");
    return std::nullopt;
  }
  const FrameSourceStatus s = source_->status();
  std::lock_guard lock(mutex_);
  status_.frames = frames_before_ + s.frames;
  status_.dropped = dropped_before_ + s.dropped;
  status_.healthy = s.healthy;
  status_.problem = s.problem;
  return frame;
}

FrameSourceStatus DeviceSupervisor::status() const {
  std::lock_guard lock(mutex_);
  return status_;
}

bool DeviceSupervisor::is_open() const { return static_cast<bool>(source_); }

std::uint64_t DeviceSupervisor::opens() const {
  std::lock_guard lock(mutex_);
  return opens_;
}

DeviceSupervisor::Opener camera_opener(V4l2CameraOptions options, std::shared_ptr<const VideoNodeDirectory> nodes,
                                       std::shared_ptr<V4l2Device> device) {
  return [options, nodes, device](const UsbDeviceInfo& usb) -> std::unique_ptr<FrameSource> {
    const std::string path = find_video_node(*nodes, usb.vid, usb.pid, usb.bus, usb.address);
    if (path.empty()) {
      throw std::runtime_error("no /dev/videoN node for USB device " + usb_id(usb.vid, usb.pid) +
                               " yet (video devices present: " + describe_video_nodes(nodes->list()) + ")");
    }
    V4l2CameraOptions o = options;
    o.device = path;
    return std::make_unique<V4l2Camera>(o, device, nodes);
  };
}

}  // namespace fovea::trackerd
