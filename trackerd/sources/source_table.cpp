// SPDX-License-Identifier: Apache-2.0
#include "sources/source_table.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cstring>
#include <fstream>
#include <optional>
#include <stdexcept>

#include "eye/eye_source.h"
#include "fovea/protocol/csv.h"
#include "sim/calibration_viewer.h"
#include "sim/synthetic_eye_frames.h"
#include "sim/synthetic_gaze.h"
#include "sources/gazepoint/gazepoint_source.h"
#include "sources/lsl/lsl_source.h"
#include "sources/hid/hid_source.h"
#include "sources/mouse/mouse_source.h"
#include "sources/pupil/pupil_source.h"
#include "sources/hotplug_camera.h"
#include "sources/replay_source.h"
#include "sources/v4l2_camera.h"
#include "sources/video_file.h"

namespace fovea::trackerd {

namespace {

std::optional<calib::ScheduleOptions> parse_eye_script(const std::string& text) {
  if (text.empty()) return std::nullopt;
  const std::string prefix = "calibration:";
  if (text.rfind(prefix, 0) != 0) {
    throw std::invalid_argument("\"" + text + "\" is not a script; expected calibration:POINTS[:SEED[:VALIDATION]]");
  }
  std::vector<long long> values;
  std::size_t at = prefix.size();
  while (true) {
    const std::size_t colon = text.find(':', at);
    const std::string part = text.substr(at, colon == std::string::npos ? std::string::npos : colon - at);
    long long v = 0;
    const auto r = std::from_chars(part.data(), part.data() + part.size(), v);
    if (part.empty() || r.ec != std::errc{} || r.ptr != part.data() + part.size() || v < 0) {
      throw std::invalid_argument("\"" + text + "\": \"" + part + "\" is not a non-negative integer");
    }
    values.push_back(v);
    if (colon == std::string::npos) break;
    at = colon + 1;
  }
  if (values.size() > 3) throw std::invalid_argument("\"" + text + "\": at most POINTS:SEED:VALIDATION");
  calib::ScheduleOptions o;
  o.points = static_cast<int>(std::min(values[0], 1000LL));
  if (values.size() > 1) o.seed = static_cast<std::uint64_t>(values[1]);
  if (values.size() > 2) o.validation_points = static_cast<int>(std::min(values[2], 1000LL));
  o.check();
  return o;
}

}  // namespace

std::vector<std::string> check_eye_config(const service::EyeConfig& eye) {
  std::vector<std::string> problems;
  try {
    (void)eye::parse_eye_side(eye.side);
  } catch (const std::exception& e) {
    problems.push_back(std::string("eye.side: ") + e.what());
  }
  if (!eye.leds.empty()) {
    try {
      (void)eye::LedLayout::parse(eye.leds);
    } catch (const std::exception& e) {
      problems.push_back(std::string("eye.leds: ") + e.what());
    }
  }
  if (eye.pupil_downscale != 1 && eye.pupil_downscale != 2 && eye.pupil_downscale != 4) {
    problems.push_back("eye.pupil_downscale: " + std::to_string(eye.pupil_downscale) +
                       " is not allowed; allowed: 1, 2, 4");
  }
  try {
    (void)parse_eye_script(eye.synthetic_script);
  } catch (const std::exception& e) {
    problems.push_back(std::string("eye.synthetic_script: ") + e.what());
  }
  try {
    (void)eye::parse_head_offset(eye.synthetic_head_offset_mm);
  } catch (const std::exception& e) {
    problems.push_back(std::string("eye.synthetic_head_offset_mm: ") + e.what());
  }
  for (const auto& [name, v] : {std::pair{"eye.synthetic_width", eye.synthetic_width},
                               std::pair{"eye.synthetic_height", eye.synthetic_height}}) {
    if (v < 32 || v > 4096) problems.push_back(std::string(name) + ": " + std::to_string(v) + " is outside 32..4096");
  }
  return problems;
}

namespace {

// The eye pipeline's settings from the configuration ([eye]); `leds`: the layout to pair glints with.
eye::EyePipelineOptions eye_pipeline_options(const service::DaemonConfig& c, const protocol::DisplayGeometry& display,
                                             const eye::LedLayout& leds) {
  eye::EyePipelineOptions o;
  o.detector.coarse_downscale = c.eye.pupil_downscale;
  o.detector.roi_tracking = c.eye.pupil_roi;
  o.detector.leds = leds;
  o.eye = eye::parse_eye_side(c.eye.side);
  o.display = display;
  return o;
}

void throw_eye_problems(const service::EyeConfig& eye) {
  const std::vector<std::string> problems = check_eye_config(eye);
  if (problems.empty()) return;
  std::string all;
  for (const auto& p : problems) all += (all.empty() ? "" : "; ") + p;
  throw std::invalid_argument(all);
}

// A camera or eye video through the eye pipeline (no calibration map yet: pupil data, no gaze).
// The caller has checked c.eye (before opening the device).
std::unique_ptr<GazeSource> eye_camera_source(std::unique_ptr<FrameSource> frames, const service::DaemonConfig& c,
                                              const protocol::DisplayGeometry& display) {
  eye::EyePipelineOptions o = eye_pipeline_options(c, display, c.eye.leds.empty() ? eye::LedLayout{}
                                                                                   : eye::LedLayout::parse(c.eye.leds));
  if (const auto* cam = dynamic_cast<const V4l2Camera*>(frames.get())) o.nominal_rate_hz = cam->mode().fps();
  if (const auto* video = dynamic_cast<const VideoFileSource*>(frames.get())) o.nominal_rate_hz = video->file_fps();
  return std::make_unique<eye::EyePipelineSource>(std::move(frames), std::move(o));
}

}  // namespace

namespace {

// ---- the factories, one per row ---------------------------------------------------------------

std::string check_synthetic_spec(const std::string& spec) {
  if (spec == "synthetic" || spec == "synthetic:binocular") return {};
  return "--source " + spec + ": the synthetic viewer takes \"synthetic\" or \"synthetic:binocular\"";
}

std::unique_ptr<GazeSource> make_synthetic(const service::DaemonConfig& c, std::int64_t start_time_ns) {
  const double rate = c.source.rate_hz > 0 ? c.source.rate_hz : 250;
  if (!(rate >= 1 && rate <= 10000)) {
    throw std::invalid_argument("--rate " + std::to_string(rate) + " is outside 1..10000 Hz");
  }
  SyntheticGazeOptions so;
  so.binocular = c.source.spec == "synthetic:binocular";
  so.rate_hz = rate;
  so.seed = c.source.seed;
  so.display = c.display.value_or(protocol::DisplayGeometry{});
  so.start_time_ns = start_time_ns;
  return std::make_unique<SyntheticGaze>(so);
}

std::unique_ptr<GazeSource> make_synthetic_eye(const service::DaemonConfig& c, std::int64_t) {
  const protocol::DisplayGeometry display = c.display.value_or(protocol::DisplayGeometry{});
  const double rate = c.source.rate_hz > 0 ? c.source.rate_hz : 120;
  if (!(rate >= 1 && rate <= 1000)) {
    throw std::invalid_argument("--rate " + std::to_string(rate) + " is outside 1..1000 Hz for synthetic-eye");
  }
  throw_eye_problems(c.eye);
  eye::SyntheticEyeFramesOptions fo;
  fo.eye.width = static_cast<int>(c.eye.synthetic_width);
  fo.eye.height = static_cast<int>(c.eye.synthetic_height);
  fo.eye.seed = c.source.seed;
  fo.eye.leds = eye::LedLayout::parse(c.eye.leds.empty() ? "2" : c.eye.leds);
  if (c.eye.synthetic_hard) fo.eye = eye::with_hard_conditions(fo.eye);
  fo.rate_hz = rate;
  fo.display = display;
  fo.calibration_script = parse_eye_script(c.eye.synthetic_script);
  fo.head_offset_mm = eye::parse_head_offset(c.eye.synthetic_head_offset_mm);
  auto frames = std::make_unique<eye::SyntheticEyeFrames>(fo);
  eye::EyePipelineOptions po = eye_pipeline_options(c, display, fo.eye.leds);
  po.nominal_rate_hz = rate;
  po.mm_per_px = frames->mm_per_px();
  po.map = frames->pupil_glint_map();
  po.detector.blink_aspect = frames->blink_aspect();  // the synthetic camera's factory setting
  return std::make_unique<eye::EyePipelineSource>(std::move(frames), std::move(po));
}

// Devices in the configuration's [[devices]] table may be plugged in after start (hotplug).
std::vector<KnownDevice> known_devices(const service::DaemonConfig& c) {
  std::vector<KnownDevice> known;
  for (const auto& d : c.devices) {
    known.push_back(KnownDevice{d.vid, d.pid, d.kind == "hid" ? UsbDeviceKind::hid : UsbDeviceKind::camera, d.name});
  }
  return known;
}

std::unique_ptr<GazeSource> make_hid(const service::DaemonConfig& c, std::int64_t) {
  const std::string& spec = c.source.spec;
  std::string lower = spec;
  for (char& ch : lower) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  bool listed = false;
  for (const auto& k : known_devices(c)) {
    listed |= k.kind == UsbDeviceKind::hid && lower == "hid:" + usb_id(k.vid, k.pid);
  }
  return make_hid_source(spec, c.display.value_or(protocol::DisplayGeometry{}), listed);
}

std::unique_ptr<GazeSource> make_usb_camera(const service::DaemonConfig& c, std::int64_t) {
  throw_eye_problems(c.eye);  // before the device is opened: a settings error is not a device error
  return eye_camera_source(std::make_unique<HotplugCamera>(c.source.spec, known_devices(c)), c,
                           c.display.value_or(protocol::DisplayGeometry{}));
}

std::unique_ptr<GazeSource> make_camera(const service::DaemonConfig& c, std::int64_t) {
  throw_eye_problems(c.eye);
  return eye_camera_source(make_camera_source(c.source.spec), c, c.display.value_or(protocol::DisplayGeometry{}));
}

std::unique_ptr<GazeSource> make_video(const service::DaemonConfig& c, std::int64_t) {
  throw_eye_problems(c.eye);
  return eye_camera_source(make_video_file_source(c.source.spec, true), c,
                           c.display.value_or(protocol::DisplayGeometry{}));
}

std::unique_ptr<GazeSource> make_replay(const service::DaemonConfig& c, std::int64_t start_time_ns) {
  ReplayOptions ro;
  ro.path = c.source.spec.substr(std::strlen("replay:"));
  ro.speed = c.source.speed;
  ro.loop = c.source.loop;
  ro.start_time_ns = start_time_ns;
  std::unique_ptr<ReplaySource> src;
  if (ro.path.size() > 4 && ro.path.compare(ro.path.size() - 4, 4, ".csv") == 0) {
    std::ifstream in(ro.path);
    if (!in) throw std::runtime_error("cannot open " + ro.path);
    src = std::make_unique<ReplaySource>(ro, protocol::read_csv(in, ro.path));  // CSV form (RECORDING.md)
  } else {
    src = std::make_unique<ReplaySource>(ro);
  }
  const auto& rep = src->recovery();
  if (!rep.header_valid || rep.damaged_regions > 0 || rep.truncated_tail) {
    spdlog::warn("{}: {}", ro.path, rep.describe());
  }
  return src;
}

// ---- the table ----------------------------------------------------------------------------------

// A Gazepoint GP3 streams at 60 Hz, the GP3 HD at 150 Hz: [source] rate says which (default 150).
std::unique_ptr<GazeSource> make_gazepoint(const service::DaemonConfig& c, std::int64_t) {
  const double rate = c.source.rate_hz > 0 ? c.source.rate_hz : 150;
  if (!(rate >= 1 && rate <= 1000)) {
    throw std::invalid_argument("--rate " + std::to_string(rate) + " is outside 1..1000 Hz for a Gazepoint tracker");
  }
  return std::make_unique<gazepoint::GazepointSource>(gazepoint::parse_gazepoint_spec(c.source.spec),
                                                      c.display.value_or(protocol::DisplayGeometry{}), rate);
}

// Pupil Core publishes gaze at the eye cameras' rate, 200 Hz by default ([source] rate says otherwise).
std::unique_ptr<GazeSource> make_pupil(const service::DaemonConfig& c, std::int64_t) {
  const double rate = c.source.rate_hz > 0 ? c.source.rate_hz : 200;
  if (!(rate >= 1 && rate <= 1000)) {
    throw std::invalid_argument("--rate " + std::to_string(rate) + " is outside 1..1000 Hz for Pupil Core");
  }
  return std::make_unique<pupil::PupilSource>(pupil::parse_pupil_spec(c.source.spec),
                                              c.display.value_or(protocol::DisplayGeometry{}), rate);
}

std::unique_ptr<GazeSource> make_mouse(const service::DaemonConfig& c, std::int64_t start_time_ns) {
  const double rate = c.source.rate_hz > 0 ? c.source.rate_hz : 120;
  if (!(rate >= 1 && rate <= 1000)) {
    throw std::invalid_argument("--rate " + std::to_string(rate) + " is outside 1..1000 Hz for the mouse");
  }
  return std::make_unique<mouse::MouseSource>(mouse::parse_mouse_spec(c.source.spec), c.display, rate, start_time_ns);
}

// An LSL stream's own rate, unless [source] rate is given (which also lets the daemon start before
// the stream exists).
std::unique_ptr<GazeSource> make_lsl(const service::DaemonConfig& c, std::int64_t) {
  return lsl_source::make_lsl_source(lsl_source::parse_lsl_spec(c.source.spec),
                                     c.display.value_or(protocol::DisplayGeometry{}), c.source.rate_hz);
}

using Arg = SourceKind::Argument;

// clang-format off
constexpr SourceKind kSourceKinds[] = {
  {"synthetic",     Arg::Optional, "synthetic[:binocular]", "seeded model viewer; binocular: each eye's gaze too, "
                                                         "for stereo displays", check_synthetic_spec, make_synthetic},
  {"synthetic-eye", Arg::None,     "synthetic-eye",      "rendered infrared eye images of that viewer through the eye "
                                                         "pipeline, with its factory calibration", nullptr, make_synthetic_eye},
  {"replay:",       Arg::Required, "replay:FILE",        ".fgr or .csv",                           nullptr, make_replay},
  {"hid",           Arg::Optional, "hid[:VID:PID]",      "HID eye tracker",                        nullptr, make_hid},
  {"camera:",       Arg::Required, "camera:/dev/videoN", "eye camera",                             nullptr, make_camera},
  {"camera:usb:",   Arg::Optional, "camera:usb:VID:PID", "eye camera, opened when plugged in",     nullptr, make_usb_camera},
  {"video:",        Arg::Required, "video:FILE",         "eye video",                              nullptr, make_video},
  {"gazepoint:",    Arg::Required, "gazepoint:HOST[:PORT]", "Gazepoint GP3 tracker, through Gazepoint "
                                                         "Control's Open Gaze API; port 4242 by default", gazepoint::check_gazepoint_spec, make_gazepoint},
  {"pupil:",        Arg::Required, "pupil:HOST[:PORT][?surface=NAME|gaze=scene&min_confidence=C]",
                                                         "Pupil Core through Pupil Capture's network API, Pupil Remote on port "
                                                         "50020 by default; screen gaze from the Surface Tracker's surface "
                                                         "\"screen\", or with gaze=scene the scene camera's gaze, for a fovea "
                                                         "calibration to map",
                                                         pupil::check_pupil_spec, make_pupil},
  {"mouse",         Arg::Optional, "mouse[:DISPLAY]",    "the X11 pointer as gaze, 120 Hz unless --rate: for developing "
                                                         "without a tracker", mouse::check_mouse_spec, make_mouse},
  {"lsl",           Arg::Optional, "lsl[:NAME][?x=I&y=J&units=pixels|normalized&confidence=K&min_confidence=C]",
                                                         "a tracker's Lab Streaming Layer stream (the first of type Gaze, or the one "
                                                         "named NAME); channels from its metadata (ScreenX/ScreenY) or x=/y=; gaze "
                                                         "below confidence 0.6 invalid where it has a confidence "
                                                         "channel (min_confidence=0: off); needs a build with liblsl", lsl_source::check_lsl_spec, make_lsl},
};
// clang-format on

// How much of `spec` the row's prefix matches: its length when it fits, else 0.
std::size_t fit(const SourceKind& k, const std::string& spec) {
  const std::size_t n = std::strlen(k.prefix);
  if (spec.compare(0, n, k.prefix) != 0) return 0;
  switch (k.argument) {
    case Arg::None: return spec.size() == n ? n : 0;
    case Arg::Required: return n;  // an empty argument is check_source_spec's to name
    case Arg::Optional: return spec.size() == n || spec[n] == ':' || k.prefix[n - 1] == ':' ? n : 0;
  }
  return 0;
}

}  // namespace

std::span<const SourceKind> source_kinds() { return kSourceKinds; }

const SourceKind* find_source_kind(const std::string& spec) {
  const SourceKind* best = nullptr;
  std::size_t best_fit = 0;
  for (const SourceKind& k : kSourceKinds) {
    if (const std::size_t f = fit(k, spec); f > best_fit) best = &k, best_fit = f;
  }
  return best;
}

std::string source_kind_list() {
  std::string all;
  for (const SourceKind& k : kSourceKinds) all += (all.empty() ? "" : ", ") + std::string(k.syntax);
  return all;
}

std::string source_help() {
  std::string all = "where gaze comes from: ";
  for (const SourceKind& k : kSourceKinds) {
    all += std::string(&k == kSourceKinds ? "" : ", ") + k.syntax + " (" + k.help + ")";
  }
  return all +
         ". Cameras and videos run the eye pipeline (pupil and glint detection) and publish pupil data; their gaze "
         "stays invalid until a calibration is loaded (step 5)";
}

std::string check_source_spec(const std::string& spec) {
  const SourceKind* kind = find_source_kind(spec);
  if (kind == nullptr) {
    return "unknown source \"" + spec + "\"; this build supports: " + source_kind_list();
  }
  if (kind->argument == Arg::Required && spec.size() == std::strlen(kind->prefix)) {
    return "--source " + std::string(kind->prefix) + " needs a file or device name";
  }
  return kind->check != nullptr ? kind->check(spec) : std::string();
}

std::unique_ptr<GazeSource> make_source(const service::DaemonConfig& c, std::int64_t start_time_ns) {
  if (const std::string problem = check_source_spec(c.source.spec); !problem.empty()) {
    throw std::invalid_argument(problem);
  }
  return find_source_kind(c.source.spec)->make(c, start_time_ns);
}

}  // namespace fovea::trackerd
