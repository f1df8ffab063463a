// SPDX-License-Identifier: Apache-2.0
#include "sources/mouse/mouse_source.h"

#include <cstdlib>
#include <ctime>
#include <stdexcept>

#include "fovea/protocol/bounded_file.h"
#include "fovea/protocol/clock.h"
#include "source_api/spec_check.h"

// Last: Xlib defines macros (None, Status, True, ...) that would rewrite names in the headers above.
#include <X11/Xlib.h>

namespace fovea::trackerd::mouse {

namespace {
constexpr std::int64_t kSliceNs = 10'000'000;  // sleep in slices, so interrupt() is seen within 10 ms
}

struct MouseSource::X {
  Display* display = nullptr;
  ~X() {
    if (display != nullptr) XCloseDisplay(display);
  }
};

std::optional<std::string> parse_mouse_spec(const std::string& spec) {
  if (spec == "mouse") return std::nullopt;
  if (spec.rfind("mouse:", 0) != 0 || spec.size() == 6) {
    throw std::invalid_argument("source " + protocol::escape_for_log(spec) +
                                ": expected mouse or mouse:DISPLAY (an X display, e.g. mouse::0)");
  }
  return spec.substr(6);
}

std::string check_mouse_spec(const std::string& spec) { return spec_problem(parse_mouse_spec, spec); }

MouseSource::MouseSource(const std::optional<std::string>& display_name,
                         std::optional<protocol::DisplayGeometry> configured, double rate_hz, std::int64_t start_time_ns)
    : x_(std::make_unique<X>()), rate_hz_(rate_hz), next_tick_ns_(start_time_ns) {
  const char* env = std::getenv("DISPLAY");
  display_name_ = display_name.value_or(env != nullptr ? env : "");
  if (display_name_.empty()) {
    throw std::runtime_error("source mouse: no X display (DISPLAY is not set; name one: mouse:DISPLAY, e.g. mouse::0)");
  }
  x_->display = XOpenDisplay(display_name_.c_str());
  if (x_->display == nullptr) {
    throw std::runtime_error("source mouse: cannot open X display " + protocol::escape_for_log(display_name_) +
                             " (is an X server running there, and may this user connect to it?)");
  }
  const int screen = DefaultScreen(x_->display);
  if (configured) {
    geometry_ = *configured;
  } else {
    geometry_.width_px = static_cast<std::uint32_t>(DisplayWidth(x_->display, screen));
    geometry_.height_px = static_cast<std::uint32_t>(DisplayHeight(x_->display, screen));
    const int mm_w = DisplayWidthMM(x_->display, screen), mm_h = DisplayHeightMM(x_->display, screen);
    if (mm_w > 0 && mm_h > 0) {  // else the default geometry's physical size
      geometry_.width_m = mm_w / 1000.0;
      geometry_.height_m = mm_h / 1000.0;
    }
  }
}

MouseSource::~MouseSource() = default;

std::optional<GazeItem> MouseSource::next() {
  // The next tick on the absolute schedule (a late call skips ticks rather than bursting).
  const std::int64_t period = static_cast<std::int64_t>(1e9 / rate_hz_);
  std::int64_t now = protocol::monotonic_ns();
  if (next_tick_ns_ < now - period) next_tick_ns_ = now;
  while (now < next_tick_ns_) {
    if (interrupted_.exchange(false)) return std::nullopt;
    const std::int64_t until = std::min(next_tick_ns_, now + kSliceNs);
    timespec ts{static_cast<time_t>(until / 1'000'000'000), static_cast<long>(until % 1'000'000'000)};
    clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
    now = protocol::monotonic_ns();
  }
  next_tick_ns_ += period;

  Window root = 0, child = 0;
  int root_x = 0, root_y = 0, win_x = 0, win_y = 0;
  unsigned mask = 0;
  const int screen = DefaultScreen(x_->display);
  const bool on_screen = XQueryPointer(x_->display, RootWindow(x_->display, screen), &root, &child, &root_x, &root_y,
                                       &win_x, &win_y, &mask) == True;
  protocol::GazeSample s;
  s.tracker_time_ns = protocol::monotonic_ns();
  ++samples_;
  if (on_screen) {
    const double w = DisplayWidth(x_->display, screen), h = DisplayHeight(x_->display, screen);
    // Pixel centres: the pointer at pixel (px, py) looks at ((px + 0.5) / w, (py + 0.5) / h).
    const double nx = (root_x + 0.5) / w, ny = (root_y + 0.5) / h;
    s.x = static_cast<float>(nx);
    s.y = static_cast<float>(ny);
    const protocol::Degrees d = protocol::normalized_to_degrees(geometry_, {nx, ny});
    s.x_deg = static_cast<float>(d.x);
    s.y_deg = static_cast<float>(d.y);
    s.confidence = 1;
    s.flags = protocol::kGazeValid;
  } else {
    ++off_screen_;
  }
  return GazeItem{s};
}

std::string MouseSource::status_detail() const {
  return std::to_string(samples_) + " pointer samples (" + std::to_string(off_screen_) + " on another screen)";
}

}  // namespace fovea::trackerd::mouse
