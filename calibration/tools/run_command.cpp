// SPDX-License-Identifier: Apache-2.0
#include "run_command.h"

#include <CLI/CLI.hpp>
#define GLFW_INCLUDE_NONE
#include <GL/gl.h>
#include <GLFW/glfw3.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "fovea/calib/model.h"
#include "fovea/calib/session.h"
#include "fovea/calib/validation.h"
#include "fovea/protocol/client.h"
#include "fovea/protocol/clock.h"
#include "fovea/protocol/control_socket.h"
#include "fovea/protocol/recording.h"
#include "fovea/protocol/udp.h"
#include "gaze_samples.h"
#include "validation_report.h"

namespace fovea::calib {

namespace {

namespace fs = std::filesystem;
namespace proto = fovea::protocol;

constexpr std::int64_t kMs = 1'000'000;

struct Session {
  proto::DisplayGeometry display;
  double nominal_rate_hz = 0;
  std::string device;
  std::vector<proto::Record> samples;  // GAZE_SAMPLE records, in time order
  std::vector<TargetWindow> targets;
};

Display to_calib_display(const proto::DisplayGeometry& g) {
  return Display{static_cast<double>(g.width_px), static_cast<double>(g.height_px), g.width_m * 1000,
                 g.height_m * 1000, g.viewing_distance_m * 1000};
}

ScheduleOptions schedule_options(const RunArgs& a) {
  ScheduleOptions o;
  o.points = a.points;
  o.validation_points = a.validation_points;
  o.seed = a.seed;
  o.randomize = !a.fixed_order;
  o.lead_in_s = a.lead_in_s;
  o.shrink_s = a.shrink_s;
  o.settle_s = a.settle_s;
  o.duration_s = a.duration_s;
  o.check();
  return o;
}

const proto::GazeSample& sample_of(const proto::Record& r) { return std::get<proto::GazeSample>(r.item); }

// --- what is calibrated: the input and the eye ---

bool has_pupil_glint(const proto::EyeData& e) {
  constexpr std::uint8_t both = proto::kEyePupilValid | proto::kEyeGlintValid;
  return (e.flags & both) == both;
}

struct InputChoice {
  std::string input;  // kInputPupilGlint or kInputScreen
  std::string eye;    // pupil-glint: "left" or "right"
};

InputChoice choose_input(const RunArgs& a, const std::vector<proto::Record>& samples) {
  std::size_t left = 0, right = 0, gaze = 0;
  for (const auto& r : samples) {
    const auto& s = sample_of(r);
    left += has_pupil_glint(s.left) ? 1u : 0u;
    right += has_pupil_glint(s.right) ? 1u : 0u;
    gaze += (s.flags & proto::kGazeValid) != 0 ? 1u : 0u;
  }
  InputChoice c;
  if (a.input == "screen" || (a.input == "auto" && left == 0 && right == 0)) {
    if (gaze == 0) {
      throw std::runtime_error("no sample of the " + std::to_string(samples.size()) +
                               " received has a valid gaze or a pupil-glint vector: is the tracker seeing an eye?");
    }
    c.input = kInputScreen;
    return c;
  }
  c.input = kInputPupilGlint;
  c.eye = a.eye != "auto" ? a.eye : (left > right ? "left" : "right");
  if ((c.eye == "left" ? left : right) == 0) {
    throw std::runtime_error("no sample has a pupil-glint vector for the " + c.eye + " eye (left: " +
                             std::to_string(left) + ", right: " + std::to_string(right) + " samples)");
  }
  return c;
}

std::vector<RawSample> raw_samples(const Session& s, const InputChoice& in) {
  const GazeInput input = in.input == kInputPupilGlint ? GazeInput::PupilGlint : GazeInput::Screen;
  std::vector<RawSample> out;
  out.reserve(s.samples.size());
  for (const auto& r : s.samples) out.push_back(to_raw_sample(sample_of(r), input, in.eye == "left", s.display));
  std::stable_sort(out.begin(), out.end(), [](const RawSample& a, const RawSample& b) { return a.time_ns < b.time_ns; });
  return out;
}

// The most accurate model for what was collected, from bench_calibration (bench/RESULTS.md): with a
// full grid of 16 or more targets, a bilinear grid on top of poly2 (pixels); on 9, poly2 (Fick
// angles for pupil-glint; the grid on top for screen input); below 6 targets, a homography.
std::string auto_model(const InputChoice& in, std::size_t targets_used, bool full_grid) {
  if (full_grid && (targets_used >= 16 || in.input == kInputScreen)) return "poly2+bilinear-grid";
  return targets_used >= 6 ? "poly2" : "homography";
}

void print_collection(const std::vector<TargetCollection>& collected) {
  std::printf("%5s  %-9s  %8s %8s  %6s  %s\n", "index", "phase", "x_px", "y_px", "kept", "samples in window");
  for (const auto& c : collected) {
    std::printf("%5d  %-9s  %8.1f %8.1f  %6zu  %zu (%zu invalid, %zu moving, %zu off target)%s%s\n", c.target.index,
                to_string(c.target.phase), c.target.position_px.x, c.target.position_px.y, c.kept.size(), c.in_window,
                c.invalid, c.moving, c.outliers, c.used ? "" : "  NOT USED: ", c.used ? "" : c.why_not.c_str());
  }
}

struct ControlAnswer {
  std::optional<proto::ControlReply> reply;
  std::string error;
  bool ok() const { return reply && reply->result == proto::ControlResult::Ok; }
  std::string text() const {
    if (!reply) return error + " (is fovea-trackerd running there, and new enough to know calibration-load?)";
    return std::string(proto::to_string(reply->result)) + ": " + reply->message.value;
  }
};

// calibration-load `argument` through the daemon's control socket on this host, else over UDP
// (protocol/control_socket.h: send_control_to_daemon).
ControlAnswer load_on_daemon(const proto::Endpoint& server, const std::string& argument, int timeout_ms) {
  proto::ControlRequest req{proto::ControlCommand::LoadCalibration, {}};
  req.argument.value = argument;
  ControlAnswer a;
  std::string via;
  a.reply = proto::send_control_to_daemon(server, "", req, timeout_ms, a.error, via);
  return a;
}

// Tells the daemon to load `file`; true when it did.
bool tell_daemon(const RunArgs& a, const std::string& file) {
  const proto::Endpoint server = proto::parse_endpoint(a.server, proto::kDefaultPort);
  if (file.size() > 63) {
    std::fprintf(stderr,
                 "fovea-calibrate run: %s is written, but its absolute path is longer than the 63 bytes a control "
                 "message carries; load it with 'fovea-ctl calibration-load' from a shorter path, or name it in "
                 "the daemon's [calibration] file and send SIGHUP\n",
                 file.c_str());
    return false;
  }
  const ControlAnswer answer = load_on_daemon(server, file, 4000);
  std::fprintf(answer.ok() ? stdout : stderr, "daemon %s: calibration-load: %s\n", server.to_string().c_str(),
               answer.text().c_str());
  return answer.ok();
}

// --- the analysis shared by live and headless runs ---

// The model to fit and the space it is fitted in, from what the collection kept.
struct ModelChoice {
  std::size_t used = 0;                 // calibration targets with enough fixation samples
  std::size_t calibration_targets = 0;  // all calibration targets shown
  std::string kind;                     // fit_calibration's kind, or "poly2+bilinear-grid"
  bool fick = false;                    // fitted to Fick angles rather than screen pixels
};

ModelChoice choose_model(const RunArgs& a, const InputChoice& in, const std::vector<TargetCollection>& collected) {
  ModelChoice m;
  for (const auto& c : collected) {
    if (c.target.phase != TargetPhase::Calibrate) continue;
    ++m.calibration_targets;
    m.used += c.used ? 1u : 0u;
  }
  if (m.used == 0) throw std::runtime_error("no calibration target has enough fixation samples; nothing to fit");
  const bool full_grid = m.used == m.calibration_targets &&
                         (m.calibration_targets == 9 || m.calibration_targets == 16 || m.calibration_targets == 64);
  m.kind = a.model == "auto" ? auto_model(in, m.used, full_grid) : a.model;
  const bool grid = m.kind == "bilinear-grid" || m.kind == "poly2+bilinear-grid";
  m.fick = a.target_space == kTargetFickDegrees ||
           (a.target_space == "auto" && in.input == kInputPupilGlint && !grid);
  if (m.fick && grid) throw std::runtime_error(m.kind + " corrects screen pixels: use --target-space px");
  return m;
}

// Fits the chosen model to the calibration targets (poly2+bilinear-grid: J&P's grid correcting a
// poly2 fit) and records what it calibrates.
Calibration fit_model(const ModelChoice& m, const InputChoice& in, const std::vector<Correspondence>& corr,
                      const Display& display) {
  Calibration cal;
  try {
    if (m.kind == "poly2+bilinear-grid") {
      const Calibration base = fit_calibration("poly2", corr);
      cal = fit_calibration("bilinear-grid", corr, &base);
      cal.outliers_rejected = base.outliers_rejected;
    } else {
      cal = fit_calibration(m.kind, corr, nullptr, {}, m.fick ? &display : nullptr);
    }
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error("fitting " + m.kind + " to " + std::to_string(m.used) + " of " +
                             std::to_string(m.calibration_targets) + " calibration targets: " + e.what());
  }
  cal.input = in.input;
  cal.eye = in.eye;
  cal.display = display;
  std::printf("model: %s in %s, %zu samples (%zu rejected as outliers), rms residual %.3f %s\n", m.kind.c_str(),
              m.fick ? "Fick angles" : "pixels", cal.points_used, cal.outliers_rejected, cal.rms_residual,
              m.fick ? "deg" : "px");
  return cal;
}

// Validation on the separate targets: every valid sample in the window that is not in a saccade
// or blink (no off-target filtering: the figures must include what a user would get).
std::vector<ValidationSample> validation_samples(const std::vector<TargetWindow>& targets,
                                                 const std::vector<RawSample>& raw, const Calibration& cal,
                                                 const InputChoice& in) {
  std::vector<ValidationSample> vs;
  for (const TargetWindow& t : targets) {
    if (t.phase != TargetPhase::Validate) continue;
    for (const RawSample& r : raw) {
      if (r.time_ns < t.collect_from_ns || r.time_ns >= t.collect_to_ns || !r.valid) continue;
      if (r.state == RawSample::State::Saccade || r.state == RawSample::State::Blink ||
          r.state == RawSample::State::Pursuit) {
        continue;
      }
      ValidationSample v;
      v.target_px = t.position_px;
      v.measured_px = cal.apply(r.raw);
      if (in.input == kInputScreen) v.before_px = r.raw;
      vs.push_back(v);
    }
  }
  return vs;
}

// Prints the validation table and records its overall figures in the calibration (none without samples).
std::optional<ValidationResult> validate_calibration(const std::vector<ValidationSample>& vs, Calibration& cal) {
  std::optional<ValidationResult> result;
  if (vs.empty()) {
    std::printf("validation: none (no validation targets, or no usable samples on them)\n");
  } else {
    result = validate(vs, *cal.display);
    std::printf("%s", format_table(*result).c_str());
    cal.validation = to_json(result->after);
    std::size_t vt = 0;
    for (const auto& t : result->targets) vt += t.after.has_data() ? 1u : 0u;
    cal.validation["targets"] = vt;
    cal.validation["date"] = utc_now_iso8601();
    // Each target's error vector, for the validation figure a viewer draws (fovea-monitor).
    nlohmann::json points = nlohmann::json::array();
    for (const auto& t : result->targets) {
      points.push_back({{"target_px", {t.target_px.x, t.target_px.y}},
                        {"mean_error_px", t.after.has_data() ? nlohmann::json::array({t.after.mean_error_px.x, t.after.mean_error_px.y})
                                                             : nlohmann::json(nullptr)},
                        {"accuracy_deg", t.after.has_data() ? nlohmann::json(t.after.accuracy_deg) : nlohmann::json(nullptr)}});
    }
    cal.validation["points"] = points;
  }
  return result;
}

// Writes the calibration file and the report, then has the daemon load it when asked; 1 when it did not.
int write_results(const RunArgs& a, const Calibration& cal, const std::optional<ValidationResult>& result,
                  const std::vector<ValidationSample>& vs, const ModelChoice& m, const InputChoice& in, bool live) {
  save_calibration(cal, a.out, a.force);
  std::printf("wrote %s: %s\n", a.out.c_str(), cal.describe().c_str());
  if (!a.report_dir.empty() && result) {
    write_validation_report(a.report_dir, *result, vs, *cal.display,
                            "fovea-calibrate run: " + m.kind + " on " + in.input + ", " + std::to_string(m.used) +
                                " calibration targets");
    std::printf("wrote the validation report to %s\n", a.report_dir.c_str());
  }
  if ((live && !a.no_load) || (!live && a.load)) {
    if (!tell_daemon(a, fs::absolute(a.out).lexically_normal().string())) return 1;
  }
  return 0;
}

int analyse(const RunArgs& a, const Session& s, bool live) {
  if (s.samples.empty()) throw std::runtime_error("no gaze samples were received or recorded");
  const InputChoice in = choose_input(a, s.samples);
  const std::vector<RawSample> raw = raw_samples(s, in);
  const std::vector<TargetCollection> collected = collect(raw, s.targets);
  std::printf("input: %s%s, %zu samples, %zu targets\n", in.input.c_str(),
              in.eye.empty() ? "" : (" (" + in.eye + " eye)").c_str(), raw.size(), s.targets.size());
  print_collection(collected);

  const std::vector<Correspondence> corr = correspondences(collected, TargetPhase::Calibrate);
  const ModelChoice m = choose_model(a, in, collected);
  const Display display = to_calib_display(s.display);
  Calibration cal = fit_model(m, in, corr, display);
  const std::vector<ValidationSample> vs = validation_samples(s.targets, raw, cal, in);
  const std::optional<ValidationResult> result = validate_calibration(vs, cal);
  return write_results(a, cal, result, vs, m, in, live);
}

// --- live: the target window ---

struct WindowSize {
  int width = 0, height = 0;
};

std::optional<WindowSize> parse_window(const std::string& text) {
  if (text.empty()) return std::nullopt;
  int w = 0, h = 0;
  char tail = 0;
  if (std::sscanf(text.c_str(), "%dx%d%c", &w, &h, &tail) != 2 || w < 64 || h < 64 || w > 16384 || h > 16384) {
    throw std::runtime_error("--window " + text + ": expected WxH (64..16384 each)");
  }
  return WindowSize{w, h};
}

void draw_disc(double cx, double cy, double r, float grey) {
  glColor3f(grey, grey, grey);
  glBegin(GL_TRIANGLE_FAN);
  glVertex2d(cx, cy);
  for (int i = 0; i <= 48; ++i) {
    const double a = 2 * M_PI * i / 48;
    glVertex2d(cx + r * std::cos(a), cy + r * std::sin(a));
  }
  glEnd();
}

class TargetWindowGl {
 public:
  TargetWindowGl(const std::optional<WindowSize>& size, const proto::DisplayGeometry& display) : display_(display) {
    glfwSetErrorCallback([](int code, const char* text) { std::fprintf(stderr, "GLFW error %d: %s\n", code, text); });
    if (glfwInit() != GLFW_TRUE) {
      throw std::runtime_error("cannot open a window (GLFW could not initialise: no display? run under a desktop "
                               "session, or use --headless --from SESSION.fgr)");
    }
    GLFWmonitor* monitor = size ? nullptr : glfwGetPrimaryMonitor();
    int w = size ? size->width : 0, h = size ? size->height : 0;
    if (monitor != nullptr) {
      const GLFWvidmode* mode = glfwGetVideoMode(monitor);
      w = mode->width;
      h = mode->height;
    } else if (!size) {
      glfwTerminate();
      throw std::runtime_error("no monitor found for a full-screen window; pass --window WxH");
    }
    window_ = glfwCreateWindow(w, h, "fovea-calibrate", monitor, nullptr);
    if (window_ == nullptr) {
      glfwTerminate();
      throw std::runtime_error("cannot create the calibration window");
    }
    glfwMakeContextCurrent(window_);
    glfwSwapInterval(1);
    if (monitor != nullptr &&
        (static_cast<std::uint32_t>(w) != display.width_px || static_cast<std::uint32_t>(h) != display.height_px)) {
      std::fprintf(stderr,
                   "fovea-calibrate run: the monitor is %dx%d but the daemon's display is %ux%u px; targets are "
                   "scaled to fit (set the daemon's [display] to this monitor for a true calibration)\n",
                   w, h, display.width_px, display.height_px);
    }
  }
  ~TargetWindowGl() {
    if (window_ != nullptr) glfwDestroyWindow(window_);
    glfwTerminate();
  }
  TargetWindowGl(const TargetWindowGl&) = delete;
  TargetWindowGl& operator=(const TargetWindowGl&) = delete;

  bool wants_close() const {
    return glfwWindowShouldClose(window_) == GLFW_TRUE || glfwGetKey(window_, GLFW_KEY_ESCAPE) == GLFW_PRESS;
  }

  // Draws the target shown at `t_s` seconds into the schedule (none between targets).
  void draw(const std::vector<ScheduledTarget>& schedule, const ScheduleOptions& o, double t_s) {
    glfwPollEvents();
    int fw = 0, fh = 0;
    glfwGetFramebufferSize(window_, &fw, &fh);
    glViewport(0, 0, fw, fh);
    glClearColor(0.45f, 0.45f, 0.45f, 1.0f);  // mid grey: the pupil neither constricts nor dilates much between targets
    glClear(GL_COLOR_BUFFER_BIT);
    glMatrixMode(GL_PROJECTION);
    glLoadIdentity();
    glOrtho(0, display_.width_px, display_.height_px, 0, -1, 1);  // display pixels, y down
    glMatrixMode(GL_MODELVIEW);
    glLoadIdentity();
    const double px = std::max(1.0, static_cast<double>(display_.width_px) / 1920.0);
    for (const ScheduledTarget& t : schedule) {
      if (t_s < t.onset_s || t_s >= t.onset_s + o.duration_s) continue;
      // Shrinking target: large to catch the eye, then small to hold it (radius 24 -> 7 px at 1080p).
      const double k = o.shrink_s > 0 ? std::clamp((t_s - t.onset_s) / o.shrink_s, 0.0, 1.0) : 1.0;
      const double r = (24 - 17 * k) * px;
      draw_disc(t.position_px.x, t.position_px.y, r, 0.95f);
      draw_disc(t.position_px.x, t.position_px.y, 2 * px, 0.05f);
    }
    glfwSwapBuffers(window_);
  }

 private:
  proto::DisplayGeometry display_;
  GLFWwindow* window_ = nullptr;
};

// --- live: collecting the session ---

// The files --save-session writes; empty without it.
struct SessionFiles {
  std::string fgr, targets;
};

// Refuses, before anything is shown, to replace the calibration file or a saved session.
SessionFiles check_outputs_free(const RunArgs& a) {
  if (!a.force && fs::exists(a.out)) throw std::runtime_error(a.out + ": exists; refusing to overwrite it (use --force)");
  SessionFiles f;
  f.fgr = a.save_session.empty() ? "" : a.save_session + ".fgr";
  f.targets = a.save_session.empty() ? "" : a.save_session + ".targets.csv";
  for (const std::string& p : {f.fgr, f.targets}) {
    if (!p.empty() && fs::exists(p)) throw std::runtime_error(p + ": exists; not replaced (--save-session)");
  }
  return f;
}

// The display geometry comes with the subscription; a first short subscription would cost a
// synthetic viewer its script, so the window opens at the daemon's STATUS display instead.
Session session_from_status(const RunArgs& a, const proto::Endpoint& server) {
  const auto status = proto::GazeClient::query_status(server, a.connect_timeout_ms);
  if (!status) {
    throw std::runtime_error("no answer from fovea-trackerd at " + server.to_string() + " within " +
                             std::to_string(a.connect_timeout_ms) + " ms (is it running? --server HOST:PORT)");
  }
  Session s;
  s.display = status->display;
  s.nominal_rate_hz = status->nominal_rate_hz;
  s.device = status->source.value;
  return s;
}

proto::ClientOptions sample_stream_options(const proto::Endpoint& server) {
  proto::ClientOptions co;
  co.server = server;
  co.streams = proto::kStreamSamples;
  co.name = "fovea-calibrate";
  co.queue_capacity = 1 << 18;
  return co;
}

void subscribe(proto::GazeClient& client, const RunArgs& a, const proto::Endpoint& server) {
  client.start();
  if (!client.wait_subscribed(a.connect_timeout_ms)) {
    throw std::runtime_error("could not subscribe to fovea-trackerd at " + server.to_string());
  }
}

// Screen input is calibrated on the tracker's own gaze: the daemon's current calibration must be
// off while we collect, and is restored if we do not finish.
void switch_daemon_calibration_off(const proto::Endpoint& server) {
  const ControlAnswer answer = load_on_daemon(server, "none", 4000);
  if (!answer.ok()) {
    throw std::runtime_error("could not switch the daemon's calibration off for collection: " + answer.text());
  }
}

void restore_daemon_calibration(const proto::Endpoint& server) {
  (void)load_on_daemon(server, "configured", 2000);
}

// Shows the schedule while the stream is recorded into s.samples, until a sample's tracker time
// passes the schedule's end; returns the tracker time of the first sample, which started the schedule.
std::int64_t record_schedule(proto::GazeClient& client, TargetWindowGl& window,
                             const std::vector<ScheduledTarget>& schedule, const ScheduleOptions& so, Session& s) {
  std::vector<std::pair<proto::GazeSample, proto::Arrival>> batch;
  std::optional<std::int64_t> start_ns;  // tracker clock: the first sample received starts the schedule
  std::int64_t last_arrival = proto::monotonic_ns();
  const double end_s = schedule_end_s(schedule) + 0.2;
  while (true) {
    batch.clear();
    client.poll(batch);
    for (const auto& [sample, arrival] : batch) {
      if (!start_ns) start_ns = sample.tracker_time_ns;
      s.samples.push_back(proto::Record{arrival.sequence, sample});
      last_arrival = arrival.receive_ns;
    }
    const std::int64_t now = proto::monotonic_ns();
    if (now - last_arrival > 3000 * kMs) {
      throw std::runtime_error("the gaze stream stopped for 3 s (" + std::to_string(s.samples.size()) +
                               " samples so far); calibration abandoned");
    }
    if (window.wants_close()) throw std::runtime_error("abandoned by the user (Esc or window closed); nothing written");
    const double t_s =
        start_ns ? static_cast<double>(now + client.stats().clock_offset_ns - *start_ns) * 1e-9 : -1.0;
    if (start_ns && !s.samples.empty() &&
        static_cast<double>(sample_of(s.samples.back()).tracker_time_ns - *start_ns) * 1e-9 >= end_s) {
      return *start_ns;
    }
    window.draw(schedule, so, t_s);
  }
}

// Keeps the session (--save-session) for headless runs: the recording and its targets file.
void save_session(const Session& s, const SessionFiles& f, const proto::GazeClient& client) {
  proto::RecordingHeader h;
  h.device = ("calibration session: " + s.device).substr(0, 63);
  h.display = s.display;
  h.nominal_rate_hz = s.nominal_rate_hz;
  h.clock = proto::RecordingClock::Monotonic;
  h.created_unix_ns = proto::realtime_ns();
  h.created_clock_ns = proto::monotonic_ns() + client.stats().clock_offset_ns;
  {
    proto::RecordingWriter w(f.fgr, h);
    for (const auto& r : s.samples) w.append(r);
    w.sync();
  }
  write_target_windows(f.targets, s.targets);
  std::printf("saved the session to %s and %s\n", f.fgr.c_str(), f.targets.c_str());
}

int run_live(const RunArgs& a) {
  const proto::Endpoint server = proto::parse_endpoint(a.server, proto::kDefaultPort);
  const ScheduleOptions so = schedule_options(a);
  const auto size = parse_window(a.window);
  const SessionFiles files = check_outputs_free(a);

  Session s = session_from_status(a, server);
  const std::vector<ScheduledTarget> schedule =
      make_schedule(s.display.width_px, s.display.height_px, so);
  TargetWindowGl window(size, s.display);
  window.draw(schedule, so, -1);

  proto::GazeClient client(sample_stream_options(server));
  subscribe(client, a, server);
  const bool screen_input = a.input == "screen";
  if (screen_input) switch_daemon_calibration_off(server);
  auto restore = [&] {
    if (screen_input) restore_daemon_calibration(server);
  };

  std::int64_t start_ns = 0;
  try {
    start_ns = record_schedule(client, window, schedule, so, s);
  } catch (...) {
    restore();
    throw;
  }
  client.stop();
  s.targets = place_schedule(schedule, start_ns);
  std::stable_sort(s.samples.begin(), s.samples.end(),
                   [](const proto::Record& x, const proto::Record& y) { return x.time_ns() < y.time_ns(); });
  if (!files.fgr.empty()) save_session(s, files, client);
  try {
    return analyse(a, s, true);
  } catch (...) {
    restore();
    throw;
  }
}

int run_headless(const RunArgs& a) {
  if (a.from.empty()) throw std::runtime_error("--headless needs --from SESSION.fgr");
  std::string targets = a.targets;
  if (targets.empty()) {
    fs::path p(a.from);
    p.replace_extension(".targets.csv");
    targets = p.string();
  }
  const proto::Recording rec = proto::read_recording(a.from);
  if (rec.report.damaged_regions > 0 || rec.report.truncated_tail) {
    std::fprintf(stderr, "fovea-calibrate run: %s: %s; using the intact records\n", a.from.c_str(),
                 rec.report.describe().c_str());
  }
  Session s;
  s.display = rec.header.display;
  s.nominal_rate_hz = rec.header.nominal_rate_hz;
  s.device = rec.header.device;
  for (const auto& r : rec.records) {
    if (std::holds_alternative<proto::GazeSample>(r.item)) s.samples.push_back(r);
  }
  s.targets = read_target_windows(targets);
  return analyse(a, s, false);
}

}  // namespace

CLI::App* add_run_subcommand(CLI::App& app, RunArgs& a) {
  auto* run = app.add_subcommand(
      "run", "calibrate: show targets, collect the tracker's raw stream, fit, validate, write CAL.json and make "
             "fovea-trackerd load it (or --headless --from a recorded session)");
  run->add_option("--out", a.out, "calibration file to write")->required();
  run->add_flag("--force", a.force, "replace --out if it exists");
  run->add_option("--server", a.server, "fovea-trackerd HOST[:PORT]")->capture_default_str();
  run->add_option("--points", a.points, "calibration targets: 5, 9, 16 or 64")
      ->check(CLI::IsMember({5, 9, 16, 64}))
      ->capture_default_str();
  run->add_option("--validation-points", a.validation_points, "separate validation targets: 0, 4 or 9")
      ->check(CLI::IsMember({0, 4, 9}))
      ->capture_default_str();
  run->add_option("--seed", a.seed, "order of the targets")->capture_default_str();
  run->add_flag("--fixed-order", a.fixed_order, "show the targets row by row instead of in random order");
  run->add_option("--dwell", a.duration_s, "seconds each target is shown")->capture_default_str();
  run->add_option("--settle", a.settle_s, "seconds after a target appears before samples are collected")
      ->capture_default_str();
  run->add_option("--shrink", a.shrink_s, "seconds over which the target shrinks")->capture_default_str();
  run->add_option("--model", a.model,
                  "auto (a full grid of 16+ targets, or 9 on screen input: poly2+bilinear-grid; 6+ targets: "
                  "poly2; fewer: homography) | poly2 | affine | homography | bilinear-grid | poly2+bilinear-grid "
                  "(J&P's grid correcting a poly2)")
      ->check(CLI::IsMember({"auto", "poly2", "affine", "homography", "bilinear-grid", "poly2+bilinear-grid"}))
      ->capture_default_str();
  run->add_option("--input", a.input,
                  "auto (pupil-glint when the stream carries pupil-glint vectors, else screen) | pupil-glint | "
                  "screen (correct the tracker's own gaze; the daemon's calibration is switched off meanwhile)")
      ->check(CLI::IsMember({"auto", "pupil-glint", "screen"}))
      ->capture_default_str();
  run->add_option("--eye", a.eye, "pupil-glint: auto | left | right")
      ->check(CLI::IsMember({"auto", "left", "right"}))
      ->capture_default_str();
  run->add_option("--target-space", a.target_space,
                  "what the model is fitted to: auto (pupil-glint: fick-deg, screen: px) | px (screen pixels) | "
                  "fick-deg (the line of sight's yaw and pitch, which the eye's rotation follows)")
      ->check(CLI::IsMember({"auto", "px", "fick-deg"}))
      ->capture_default_str();
  run->add_option("--report", a.report_dir, "also write the validation report (tables, errors.png) to DIR");
  run->add_option("--save-session", a.save_session, "keep the session as PREFIX.fgr and PREFIX.targets.csv");
  run->add_option("--window", a.window, "a WxH window instead of full screen");
  run->add_flag("--no-load", a.no_load, "do not tell the daemon to load the new calibration");
  run->add_flag("--headless", a.headless, "no window, no daemon: analyse a recorded session (--from)");
  run->add_option("--from", a.from, "headless: the session recording SESSION.fgr");
  run->add_option("--targets", a.targets, "headless: its targets file (default SESSION.targets.csv)");
  run->add_flag("--load", a.load, "headless: also tell the daemon at --server to load the result");
  return run;
}

int run_calibration(const RunArgs& a) {
  try {
    (void)schedule_options(a);
    if (a.headless) {
      if (!a.force && fs::exists(a.out)) {
        throw std::runtime_error(a.out + ": exists; refusing to overwrite it (use --force)");
      }
      return run_headless(a);
    }
    return run_live(a);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fovea-calibrate run: %s\n", e.what());
    return 1;
  }
}

}  // namespace fovea::calib
