// SPDX-License-Identifier: Apache-2.0
#include "sources/hid/hid_source.h"

#include <hidapi/hidapi.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <map>
#include <stdexcept>
#include <thread>

#include "fovea/protocol/clock.h"
#include "sources/hid/usage_tables.h"

namespace fovea::trackerd::hid {

namespace {

std::string hex4(std::uint16_t v) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "%04x", v);
  return buf;
}

// hidapi's strings are wchar_t (UTF-32 on Linux); encode as UTF-8.
std::string utf8(const wchar_t* w) {
  std::string out;
  if (!w) return out;
  for (; *w; ++w) {
    auto c = static_cast<std::uint32_t>(*w);
    if (c > 0x10FFFF || (c >= 0xD800 && c <= 0xDFFF)) c = 0xFFFD;
    if (c < 0x80) {
      out += static_cast<char>(c);
    } else if (c < 0x800) {
      out += static_cast<char>(0xC0 | (c >> 6));
      out += static_cast<char>(0x80 | (c & 0x3F));
    } else if (c < 0x10000) {
      out += static_cast<char>(0xE0 | (c >> 12));
      out += static_cast<char>(0x80 | ((c >> 6) & 0x3F));
      out += static_cast<char>(0x80 | (c & 0x3F));
    } else {
      out += static_cast<char>(0xF0 | (c >> 18));
      out += static_cast<char>(0x80 | ((c >> 12) & 0x3F));
      out += static_cast<char>(0x80 | ((c >> 6) & 0x3F));
      out += static_cast<char>(0x80 | (c & 0x3F));
    }
  }
  return out;
}

std::string device_name(const HidDeviceSummary& d) {
  std::string s = hex4(d.vendor_id) + ":" + hex4(d.product_id);
  std::string name = d.manufacturer;
  if (!d.product.empty()) name += (name.empty() ? "" : " ") + d.product;
  if (!name.empty()) s += " " + name;
  return s;
}

std::string device_label(const HidDeviceSummary& d) { return d.path + " (" + device_name(d) + ")"; }

std::vector<HidDeviceSummary> enumerate(const HidSpec& spec) {
  std::vector<HidDeviceSummary> out;
  hid_device_info* list = hid_enumerate(spec.vendor_id.value_or(0), spec.product_id.value_or(0));
  for (const hid_device_info* d = list; d; d = d->next) {
    HidDeviceSummary s;
    s.path = d->path ? d->path : "";
    s.vendor_id = d->vendor_id;
    s.product_id = d->product_id;
    s.usage_page = d->usage_page;
    s.usage = d->usage;
    s.manufacturer = utf8(d->manufacturer_string);
    s.product = utf8(d->product_string);
    out.push_back(std::move(s));
  }
  hid_free_enumeration(list);
  return out;
}

// The descriptor from sysfs (readable without access to the device node).
std::optional<std::vector<std::uint8_t>> read_sysfs_descriptor(const std::string& device_path) {
  const std::string file = hidraw_descriptor_path(device_path);
  if (file.empty()) return std::nullopt;
  std::ifstream in(file, std::ios::binary);
  if (!in) return std::nullopt;
  std::vector<std::uint8_t> bytes;
  char c;
  // A descriptor is at most 4096 bytes; read one more so an oversized one is reported as such.
  while (bytes.size() <= kMaxDescriptorBytes && in.get(c)) bytes.push_back(static_cast<std::uint8_t>(c));
  return bytes;
}

std::string hid_error_text(hid_device* dev) {
  const std::string s = utf8(hid_error(dev));
  return s.empty() ? "unknown error" : s;
}

void sleep_ms(std::int64_t ms) {
  if (ms > 0) std::this_thread::sleep_for(std::chrono::milliseconds(ms));
}

}  // namespace

HidSpec parse_hid_spec(const std::string& spec) {
  const auto bad = [&](const std::string& why) {
    return std::invalid_argument("source '" + spec + "': " + why +
                                 " (expected 'hid' or 'hid:VID:PID' with VID and PID in hexadecimal, e.g. hid:1234:5678)");
  };
  if (spec == "hid") return {};
  if (spec.rfind("hid:", 0) != 0) throw bad("not a HID source");
  const std::string rest = spec.substr(4);
  const auto colon = rest.find(':');
  if (colon == std::string::npos) throw bad("missing ':' between vendor and product ID");
  const auto parse = [&](std::string s, const char* what) -> std::uint16_t {
    if (s.rfind("0x", 0) == 0 || s.rfind("0X", 0) == 0) s = s.substr(2);
    if (s.empty() || s.size() > 4 || s.find_first_not_of("0123456789abcdefABCDEF") != std::string::npos) {
      throw bad(std::string(what) + " '" + s + "' is not 1 to 4 hexadecimal digits");
    }
    return static_cast<std::uint16_t>(std::stoul(s, nullptr, 16));
  };
  HidSpec out;
  out.vendor_id = parse(rest.substr(0, colon), "vendor ID");
  out.product_id = parse(rest.substr(colon + 1), "product ID");
  return out;
}

std::string hidraw_descriptor_path(const std::string& device_path, const std::string& sysfs_root) {
  const std::string prefix = "/dev/";
  if (device_path.rfind(prefix, 0) != 0) return {};
  const std::string node = device_path.substr(prefix.size());
  if (node.rfind("hidraw", 0) != 0 || node.size() == 6 ||
      node.find_first_not_of("0123456789", 6) != std::string::npos) {
    return {};
  }
  return sysfs_root + "/class/hidraw/" + node + "/device/report_descriptor";
}

std::string no_eye_tracker_message(const HidSpec& spec, const std::vector<HidDeviceSummary>& present) {
  std::string which = spec.vendor_id ? "HID device " + hex4(*spec.vendor_id) + ":" + hex4(spec.product_id.value_or(0))
                                     : std::string("HID eye tracker");
  if (present.empty()) {
    return "no " + which + " found: " +
           (spec.vendor_id ? std::string("no HID device with that vendor:product ID is present")
                           : std::string("no HID devices are present at all (is the tracker plugged in? "
                                         "`ls /sys/class/hidraw` lists them)"));
  }
  // hidapi lists one entry per top-level collection; group them by device node.
  std::map<std::string, std::vector<const HidDeviceSummary*>> by_path;
  for (const auto& d : present) by_path[d.path].push_back(&d);
  std::string list;
  for (const auto& [path, entries] : by_path) {
    list += "\n  " + path + "  " + device_name(*entries.front());
    std::string usages;
    for (const auto* e : entries) {
      if (e->usage_page == 0 && e->usage == 0) continue;
      usages += (usages.empty() ? "" : ", ") + describe_usage(make_usage(e->usage_page, e->usage));
    }
    if (!usages.empty()) list += "  [" + usages + "]";
  }
  return "no " + which + " found: none of the " + std::to_string(by_path.size()) +
         " HID device(s) present has an Eye Tracker collection on usage page 0x12 (Eye and Head Trackers):" + list;
}

std::string permission_message(const std::string& device_path, const HidDeviceSummary& device) {
  return "permission denied opening " + device_path + " (" + device_name(device) +
         "): the udev rule deploy/70-fovea-trackers.rules grants the 'fovea' group read/write access to eye "
         "trackers; install it (sudo cp deploy/70-fovea-trackers.rules /etc/udev/rules.d/ && sudo udevadm control "
         "--reload && sudo udevadm trigger), make sure this user is in group 'fovea', then re-plug the tracker. "
         "`ls -l " + device_path + "` shows who may open it now.";
}

struct HidSource::Device {
  hid_device* handle = nullptr;
  HidDeviceSummary info;
  ReportDescriptor descriptor;
  ~Device() {
    if (handle) hid_close(handle);
  }
};

HidSource::HidSource(HidSourceOptions options) : options_(std::move(options)) {
  spec_ = parse_hid_spec(options_.spec);
  if (hid_init() != 0) throw std::runtime_error("hidapi initialisation failed: " + hid_error_text(nullptr));
  try {
    open_device();
  } catch (const std::exception& e) {
    if (!options_.wait_for_device) throw;
    // A known device that is not plugged in yet: serve status and open it when it arrives.
    description_ = options_.spec;
    display_ = options_.fallback_display;
    rate_hz_ = options_.assumed_rate_hz;
    next_retry_ns_ = 0;
    std::lock_guard lock(status_mutex_);
    status_.healthy = false;
    status_.problem = std::string(e.what()) + "; waiting for it to be plugged in; retrying every " +
                      std::to_string(options_.retry_interval_ms) + " ms";
  }
}

HidSource::~HidSource() = default;

void HidSource::open_device() {
  const auto present = enumerate(spec_);
  // Candidates: interfaces whose top-level collection the backend reports as an Eye Tracker; if the
  // backend reports no usages, every interface (the descriptor decides).
  std::vector<const HidDeviceSummary*> candidates;
  for (const auto& d : present) {
    if (d.usage_page == kEyeHeadTrackerPage && d.usage == usage_id(eht::EyeTracker)) candidates.push_back(&d);
  }
  const bool backend_reports_usages = std::any_of(present.begin(), present.end(), [](const auto& d) {
    return d.usage_page != 0 || d.usage != 0;
  });
  if (candidates.empty() && (!backend_reports_usages || spec_.vendor_id)) {
    for (const auto& d : present) candidates.push_back(&d);
  }
  if (candidates.empty()) throw std::runtime_error(no_eye_tracker_message(spec_, present));

  std::string first_problem;
  for (const HidDeviceSummary* c : candidates) {
    auto dev = std::make_unique<Device>();
    dev->info = *c;
    std::optional<std::vector<std::uint8_t>> bytes = read_sysfs_descriptor(c->path);
    if (!bytes) {
#if HID_API_VERSION >= HID_API_MAKE_VERSION(0, 14, 0)
      if (hid_device* h = hid_open_path(c->path.c_str())) {
        std::vector<std::uint8_t> buf(HID_API_MAX_REPORT_DESCRIPTOR_SIZE);
        const int n = hid_get_report_descriptor(h, buf.data(), buf.size());
        if (n > 0) bytes = std::vector<std::uint8_t>(buf.begin(), buf.begin() + n);
        hid_close(h);
      }
#endif
      if (!bytes) {
        if (first_problem.empty()) {
          first_problem = "cannot read the report descriptor of " + device_label(*c) + " (" +
                          (hidraw_descriptor_path(c->path).empty() ? std::string("not a hidraw device")
                                                                   : hidraw_descriptor_path(c->path)) +
                          ")";
        }
        continue;
      }
    }
    try {
      dev->descriptor = parse_report_descriptor(*bytes);
      decoder_.emplace(map_eye_tracker(dev->descriptor));
    } catch (const std::exception& e) {  // DescriptorError, NotAnEyeTracker
      if (first_problem.empty()) first_problem = device_label(*c) + ": " + e.what();
      continue;
    }
    dev->handle = hid_open_path(c->path.c_str());
    if (!dev->handle) {
      const int err = ::access(c->path.c_str(), R_OK | W_OK) == 0 ? 0 : errno;
      if (err == EACCES || err == EPERM) throw std::runtime_error(permission_message(c->path, *c));
      throw std::runtime_error("cannot open " + device_label(*c) + ": " +
                               (err ? std::string(std::strerror(err)) : hid_error_text(nullptr)));
    }
    device_ = std::move(dev);
    break;
  }
  if (!device_) {
    if (first_problem.empty()) throw std::runtime_error(no_eye_tracker_message(spec_, present));
    throw std::runtime_error(first_problem);
  }

  clock_.reset();
  if (const auto& ts = decoder_->layout().timestamp) clock_.emplace(decoder_->layout().timestamp_tick_s, ts->bit_size);
  read_features();
  description_ = "hid:" + hex4(device_->info.vendor_id) + ":" + hex4(device_->info.product_id);
  if (!device_->info.product.empty()) description_ += " " + device_->info.product;
  std::lock_guard lock(status_mutex_);
  status_.device = device_label(device_->info);
  status_.healthy = true;
  status_.problem.clear();
}

void HidSource::read_features() {
  const auto& layout = decoder_->layout();
  const bool ids = layout.uses_report_ids;
  const auto read = [&](const ValueLocation& loc) -> std::vector<std::uint8_t> {
    const ReportLayout* r = device_->descriptor.find(ReportType::Feature, loc.report_id);
    if (!r) return {};
    // hid_get_feature_report wants (and returns) the report ID byte first, 0 without IDs.
    std::vector<std::uint8_t> buf(r->wire_size(ids) + (ids ? 0u : 1u), 0);
    buf[0] = loc.report_id;
    const int n = hid_get_feature_report(device_->handle, buf.data(), buf.size());
    if (n <= 0) return {};
    buf.resize(static_cast<std::size_t>(n));
    return buf;
  };

  display_ = options_.fallback_display;
  if (layout.screen_width) {
    if (const auto screen = calibrated_screen_m(layout, read(*layout.screen_width))) {
      protocol::DisplayGeometry g = display_;
      g.width_m = screen->first;
      g.height_m = screen->second;
      if (protocol::validate(g).empty()) display_ = g;
    }
  }
  rate_hz_ = options_.assumed_rate_hz;
  rate_reported_ = false;
  if (layout.sampling_frequency) {
    const auto f = feature_value(*layout.sampling_frequency, read(*layout.sampling_frequency));
    if (f && *f > 0 && *f <= 10000) {
      rate_hz_ = static_cast<double>(*f);
      rate_reported_ = true;
    }
  }
  std::optional<std::int64_t> config_status;
  if (layout.configuration_status) {
    config_status = feature_value(*layout.configuration_status, read(*layout.configuration_status));
  }
  std::lock_guard lock(status_mutex_);
  status_.configuration_status = config_status;
}

std::string HidSource::description() const { return description_; }
protocol::DisplayGeometry HidSource::display() const { return display_; }
double HidSource::nominal_rate_hz() const { return rate_hz_; }

HidSourceStatus HidSource::status() const {
  std::lock_guard lock(status_mutex_);
  HidSourceStatus s = status_;
  if (s.healthy && s.configuration_status && *s.configuration_status != eht::StatusReady &&
      *s.configuration_status != 0) {
    s.problem = std::string("the tracker reports: ") + configuration_status_name(*s.configuration_status);
  }
  return s;
}

void HidSource::interrupt() { interrupted_.store(true); }

void HidSource::lose_device(const std::string& why) {
  const std::string label = device_ ? device_label(device_->info) : std::string("the tracker");
  device_.reset();  // closes the handle
  next_retry_ns_ = protocol::monotonic_ns() + std::int64_t{options_.retry_interval_ms} * 1'000'000;
  std::lock_guard lock(status_mutex_);
  status_.healthy = false;
  status_.problem = "lost " + label + ": " + why + "; retrying every " +
                    std::to_string(options_.retry_interval_ms) + " ms";
}

bool HidSource::try_reopen() {
  try {
    open_device();
  } catch (const std::exception& e) {
    std::lock_guard lock(status_mutex_);
    const auto cut = status_.problem.find("; retrying");
    const std::string head = status_.problem.substr(0, cut);
    status_.problem = head + "; retrying every " + std::to_string(options_.retry_interval_ms) + " ms (last try: " +
                      e.what() + ")";
    return false;
  }
  hold_ = {0.5, 0.5};
  std::lock_guard lock(status_mutex_);
  ++status_.reconnects;
  return true;
}

std::optional<GazeItem> HidSource::next() {
  std::vector<std::uint8_t> buf;
  while (!interrupted_.exchange(false)) {  // one-shot: the next call reads again
    if (!device_) {
      const std::int64_t now = protocol::monotonic_ns();
      if (now >= next_retry_ns_) {
        if (try_reopen()) continue;
        next_retry_ns_ = now + std::int64_t{options_.retry_interval_ms} * 1'000'000;
      }
      sleep_ms(std::min<std::int64_t>(options_.read_timeout_ms, (next_retry_ns_ - now) / 1'000'000 + 1));
      continue;
    }
    std::size_t size = 1;
    for (const auto& r : decoder_->layout().input_reports) size = std::max(size, r.second);
    buf.resize(size + 64);  // room for devices that send more than they declare
    const int n = hid_read_timeout(device_->handle, buf.data(), buf.size(), options_.read_timeout_ms);
    if (n < 0) {
      lose_device("read failed (" + hid_error_text(device_->handle) + ")");
      continue;
    }
    if (n == 0) continue;
    const std::int64_t receive_ns = protocol::monotonic_ns();
    GazeReport report;
    const DecodeResult r = decoder_->decode(std::span<const std::uint8_t>(buf.data(), static_cast<std::size_t>(n)), report);
    {
      std::lock_guard lock(status_mutex_);
      status_.reports_rejected = decoder_->counters().rejected();
      status_.other_reports = decoder_->counters().other;
      if (r == DecodeResult::Gaze) ++status_.samples;
      if (clock_) status_.clock_resets = clock_->resets();
      if (report.status) status_.configuration_status = report.status;
    }
    if (r != DecodeResult::Gaze) continue;
    const std::int64_t t = report.timestamp_ticks && clock_ ? clock_->map(*report.timestamp_ticks, receive_ns) : receive_ns;
    protocol::GazeSample s = to_gaze_sample(report, display_, t, hold_);
    if (s.flags & protocol::kGazeValid) hold_ = {static_cast<double>(s.x), static_cast<double>(s.y)};
    return GazeItem{s};
  }
  return std::nullopt;
}

}  // namespace fovea::trackerd::hid

namespace fovea::trackerd {

std::unique_ptr<GazeSource> make_hid_source(const std::string& spec, const protocol::DisplayGeometry& fallback_display,
                                            bool wait_for_device) {
  hid::HidSourceOptions options;
  options.spec = spec;
  options.fallback_display = fallback_display;
  options.wait_for_device = wait_for_device;
  return std::make_unique<hid::HidSource>(options);
}

}  // namespace fovea::trackerd
