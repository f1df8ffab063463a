// SPDX-License-Identifier: Apache-2.0
// fovea-ctl's eye tools: detect-pupil (the eye pipeline's detector on image files), synth-eye (test
// images with their exact truth) and synth-calibration (a recorded calibration session of the
// synthetic viewer).
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>

#include <opencv2/imgcodecs.hpp>
#include <spdlog/spdlog.h>

#include "ctl/commands.h"
#include "eye/eye_detector.h"
#include "fovea/protocol/bounded_file.h"
#include "fovea/protocol/clock.h"
#include "fovea/protocol/recording.h"
#include "sim/calibration_viewer.h"
#include "sim/synthetic_eye.h"
#include "sim/synthetic_eye_frames.h"
#include "source_api/image_header.h"

namespace fovea::ctl {

// Declared in commands.h (convert's markers CSV writes through it too).
void write_new_file(const std::string& path, const std::string& text, bool force) {
  if (!force && std::filesystem::exists(path)) {
    throw std::runtime_error(path + " already exists (use --force to replace it)");
  }
  const std::string tmp = path + ".partial-" + std::to_string(getpid());
  {
    std::ofstream out(tmp);
    out << text;
    out.close();
    if (!out) {
      std::error_code ignored;
      std::filesystem::remove(tmp, ignored);
      throw std::runtime_error("cannot write " + path);
    }
  }
  std::filesystem::rename(tmp, path);
}

namespace {

using namespace fovea::protocol;

namespace eye = fovea::trackerd::eye;
using trackerd::decode_image_bounded;
using trackerd::kMaxEyeImagePixels;
// An eye image file: a few MB at most (a raw 4096x4096 grey BMP is 16 MiB).
constexpr std::size_t kMaxImageFileBytes = 64u << 20;

// A CSV field: quoted when it holds a comma, a quote or a line break (RFC 4180).
std::string csv_field(const std::string& text) {
  if (text.find_first_of(",\"\r\n") == std::string::npos) return text;
  std::string out = "\"";
  for (const char ch : text) {
    if (ch == '"') out += '"';
    out += ch;
  }
  return out + "\"";
}

std::string fixed3(double v) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.3f", std::isfinite(v) ? v : 0.0);
  return buf;
}

std::string glint_list(const std::vector<cv::Point2d>& points) {
  std::string out;
  for (const auto& p : points) out += (out.empty() ? "" : ";") + fixed3(p.x) + ":" + fixed3(p.y);
  return out;
}


int cmd_detect_pupil(const std::vector<std::string>& images, const std::string& out_path, bool force,
                     const std::string& leds, int downscale, bool track) {
  eye::DetectorSettings settings;
  try {
    if (!leds.empty()) settings.leds = eye::LedLayout::parse(leds);
    settings.coarse_downscale = downscale;
    settings.roi_tracking = track;
    settings.validate();
    if (!out_path.empty() && !force && std::filesystem::exists(out_path)) {
      throw std::runtime_error(out_path + " already exists (use --force to replace it)");
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fovea-ctl detect-pupil: %s\n", e.what());
    return 2;
  }
  eye::EyeDetector detector(settings);
  const std::string header = "file,pupil_x,pupil_y,major,minor,angle_deg,confidence,glint_count,glints\n";
  std::string csv = header;
  std::fputs(header.c_str(), stdout);
  int status = 0;
  for (const std::string& file : images) {
    std::error_code ec;
    const auto st = std::filesystem::status(file, ec);
    cv::Mat image;
    std::string why;
    if (!std::filesystem::exists(st)) {
      why = "no such file";
    } else if (std::filesystem::is_directory(st)) {
      why = "is a directory";
    } else {
      // Bounded before decoding: a small file can declare a huge image (issue 23 item 6).
      try {
        const std::string bytes =
            protocol::read_bounded_file(file, {.max_bytes = kMaxImageFileBytes, .what = "image"});
        image = decode_image_bounded(
            std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size()),
            cv::IMREAD_UNCHANGED, kMaxEyeImagePixels, why);
        if (image.empty()) why = "cannot be read as an image: " + why;
      } catch (const std::runtime_error& e) {
        why = e.what();
      }
    }
    if (!why.empty()) {
      std::fprintf(stderr, "fovea-ctl detect-pupil: %s: %s\n", file.c_str(), why.c_str());
      status = 1;
      continue;
    }
    if (!track) detector.reset();
    const eye::EyeMeasurement m = detector.detect(image);
    std::string row = csv_field(file) + ",";
    if (m.pupil_found) {
      row += fixed3(m.pupil.centre.x) + "," + fixed3(m.pupil.centre.y) + "," + fixed3(m.pupil.major) + "," +
             fixed3(m.pupil.minor) + "," + fixed3(m.pupil.angle_deg) + ",";
    } else {
      row += ",,,,,";
    }
    std::vector<cv::Point2d> glints;
    for (const auto& g : m.glints) glints.push_back(g.centre);
    row += fixed3(m.confidence) + "," + std::to_string(glints.size()) + "," + glint_list(glints) + "\n";
    std::fputs(row.c_str(), stdout);
    csv += row;
  }
  std::fflush(stdout);
  if (!out_path.empty()) {
    try {
      write_new_file(out_path, csv, force);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "fovea-ctl detect-pupil: %s\n", e.what());
      return 1;
    }
  }
  return status;
}

struct SynthEyeArgs {
  std::string dir, size = "320x240", leds = "2";
  int count = 20;
  bool hard = false;
  std::uint64_t seed = 1;
  double pupil_iris_contrast = 0, exposure = 1, eyelash_length = 1;
  double lid_cover = -1;  // < 0: as --hard (or not) says
  bool lit_lashes = false;
};

int cmd_synth_eye(const SynthEyeArgs& a) {
  const std::string& dir = a.dir;
  const std::string& size = a.size;
  const int count = a.count;
  const bool hard = a.hard;
  try {
    unsigned w = 0, h = 0;
    char tail = 0;
    if (std::sscanf(size.c_str(), "%ux%u%c", &w, &h, &tail) != 2 || w < 32 || h < 32 || w > 4096 || h > 4096) {
      throw std::runtime_error("--size \"" + size + "\": expected WxH, each 32..4096 (e.g. 320x240)");
    }
    if (count < 1 || count > 100000) {
      throw std::runtime_error("--count " + std::to_string(count) + " is outside 1..100000");
    }
    eye::SyntheticEyeOptions o;
    o.width = static_cast<int>(w);
    o.height = static_cast<int>(h);
    o.seed = a.seed;
    o.leds = eye::LedLayout::parse(a.leds);
    if (hard) o = eye::with_hard_conditions(o);
    o.pupil_iris_contrast = a.pupil_iris_contrast;
    o.exposure = a.exposure;
    o.eyelash_length = a.eyelash_length;
    o.lit_lashes = a.lit_lashes;
    if (a.lid_cover >= 0) o.eyelid_cover = a.lid_cover;
    eye::SyntheticEye generator(o);  // checks the options before anything is created
    std::error_code ec;
    if (std::filesystem::exists(dir, ec)) {
      if (!std::filesystem::is_directory(dir, ec)) throw std::runtime_error(dir + " exists and is not a directory");
      if (!std::filesystem::is_empty(dir, ec)) {
        throw std::runtime_error(dir + " is not empty (synth-eye writes only into a new or empty directory)");
      }
    } else if (!std::filesystem::create_directories(dir, ec)) {
      throw std::runtime_error("cannot create " + dir + ": " + ec.message());
    }
    std::mt19937_64 rng(a.seed ^ 0x5eed5eedULL);  // the gazes; the generator draws its noise from its own
    std::uniform_real_distribution<double> angle(-20.0, 20.0);
    std::string csv =
        "file,pupil_x,pupil_y,major,minor,angle_deg,closed,glint_count,glints,pupil_glint_x,pupil_glint_y\n";
    for (int i = 0; i < count; ++i) {
      const double yaw = angle(rng), pitch = angle(rng);
      eye::EyeTruth t;
      const cv::Mat image = generator.render(yaw, pitch, 1.0, &t);
      char name[32];
      std::snprintf(name, sizeof name, "eye_%04d.png", i);
      const std::string path = (std::filesystem::path(dir) / name).string();
      if (!cv::imwrite(path, image)) throw std::runtime_error("cannot write " + path);
      csv += std::string(name) + ",";
      if (t.closed) {
        csv += ",,,,,1,";
      } else {
        csv += fixed3(t.pupil.centre.x) + "," + fixed3(t.pupil.centre.y) + "," + fixed3(t.pupil.major) + "," +
               fixed3(t.pupil.minor) + "," + fixed3(t.pupil.angle_deg) + ",0,";
      }
      csv += std::to_string(t.glints.size()) + "," + glint_list(t.glints) + ",";
      csv += t.closed ? std::string(",") : fixed3(t.pupil_glint.x) + "," + fixed3(t.pupil_glint.y);
      csv += "\n";
    }
    write_new_file((std::filesystem::path(dir) / "truth.csv").string(), csv, false);
    std::string conditions = hard ? " (hard conditions)" : "";
    if (a.pupil_iris_contrast > 0) conditions += " (dark iris: " + fixed3(a.pupil_iris_contrast) + " levels above the pupil)";
    if (a.exposure != 1) conditions += " (exposure " + fixed3(a.exposure) + ")";
    if (a.eyelash_length != 1) conditions += " (lashes " + fixed3(a.eyelash_length) + "x)";
    if (a.lit_lashes) conditions += " (lit lashes)";
    if (a.lid_cover >= 0) conditions += " (upper lid over " + fixed3(a.lid_cover) + " of the pupil)";
    std::fprintf(stderr, "fovea-ctl synth-eye: wrote %d image(s) %ux%u%s and truth.csv to %s\n", count, w, h,
                 conditions.c_str(), dir.c_str());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fovea-ctl synth-eye: %s\n", e.what());
    return 1;
  }
}

// --- synth-calibration: a recorded calibration session of the synthetic viewer ---

// An eye image size from --eye-size.
struct EyeImageSize {
  unsigned w = 0, h = 0;
};

// Parses --eye-size WxH, each side 32..4096.
EyeImageSize parse_eye_image_size(const std::string& size) {
  unsigned w = 0, h = 0;
  char tail = 0;
  if (std::sscanf(size.c_str(), "%ux%u%c", &w, &h, &tail) != 2 || w < 32 || h < 32 || w > 4096 || h > 4096) {
    throw std::runtime_error("--eye-size \"" + size + "\": expected WxH, each 32..4096 (e.g. 320x240)");
  }
  return {w, h};
}

// Where the viewer sits: --head-offset and --display, the message naming the flag whose text is wrong.
void set_viewer_placement(eye::CalibrationSessionOptions& o, const std::string& head_offset,
                          const std::string& display_text) {
  try {
    o.head_offset_mm = eye::parse_head_offset(head_offset);
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(std::string("--head-offset: ") + e.what());
  }
  if (!display_text.empty()) {
    try {
      o.display = parse_display_geometry(display_text);
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(std::string("--display: ") + e.what());
    }
  }
}

// The targets shown, checked here so that a bad combination is reported as the flags' fault.
void set_target_schedule(fovea::calib::ScheduleOptions& schedule, int points, int validation_points,
                         std::uint64_t seed) {
  schedule.points = points;
  schedule.validation_points = validation_points;
  schedule.seed = seed;
  try {
    schedule.check();
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(std::string("--points/--validation-points: ") + e.what());
  }
}

// The synthetic eye's image size, look (the seed) and imaging conditions.
void set_eye_imaging(eye::SyntheticEyeOptions& e, EyeImageSize size, std::uint64_t seed, bool hard) {
  e.width = static_cast<int>(size.w);
  e.height = static_cast<int>(size.h);
  e.seed = seed;
  if (hard) e = eye::with_hard_conditions(e);
}

// SESSION.fgr and SESSION.targets.csv.
struct SessionFiles {
  std::string fgr, targets;
};

// The session's two files for --out (with or without .fgr); refused when either exists, so that both
// are new or neither is written.
SessionFiles new_session_files(const std::string& out) {
  const std::string base = ends_with(out, ".fgr") ? out.substr(0, out.size() - 4) : out;
  const std::string fgr = base + ".fgr", targets = base + ".targets.csv";
  std::error_code ec;
  for (const std::string& p : {fgr, targets}) {
    if (std::filesystem::exists(p, ec) || std::filesystem::is_symlink(p, ec)) {
      throw std::runtime_error(p + " already exists (synth-calibration never overwrites; it writes " + fgr +
                               " and " + targets + " together)");
    }
  }
  return {fgr, targets};
}

// The recording's header: the monotonic clock the daemon records on, frame 0 at o.start_time_ns.
RecordingHeader session_recording_header(const eye::CalibrationSessionOptions& o, std::uint64_t seed,
                                         std::int64_t created_unix) {
  RecordingHeader header;
  header.device = ("synthetic-eye calibration seed " + std::to_string(seed)).substr(0, 63);
  header.display = o.display;
  header.nominal_rate_hz = o.rate_hz;
  header.clock = RecordingClock::Monotonic;
  header.created_unix_ns = created_unix;
  header.created_clock_ns = o.start_time_ns;
  return header;
}

// Writes SESSION.fgr, then SESSION.targets.csv; the .fgr is removed again if either fails.
void write_session_files(const SessionFiles& files, const RecordingHeader& header,
                         const eye::CalibrationSession& session) {
  std::error_code ec;
  try {
    RecordingWriter writer(files.fgr, header, RecordingWriter::Mode::CreateNew);
    std::uint64_t sequence = 0;
    for (const auto& item : session.published) {
      std::visit([&](const auto& v) { writer.append(Record{sequence++, v}); }, item);
    }
    writer.sync();
  } catch (...) {
    std::filesystem::remove(files.fgr, ec);
    throw;
  }
  try {
    fovea::calib::write_target_windows(files.targets, session.targets);
  } catch (...) {
    std::filesystem::remove(files.fgr, ec);
    throw;
  }
}

// The tool's one-line summary on stdout.
void print_session_summary(const SessionFiles& files, const eye::CalibrationSession& session,
                           const eye::CalibrationSessionOptions& o, EyeImageSize size, bool hard, std::uint64_t seed) {
  std::size_t calibrate = 0;
  for (const auto& t : session.targets) calibrate += t.phase == fovea::calib::TargetPhase::Calibrate ? 1 : 0;
  std::printf("synth-calibration: %s (%zu samples, %zu events, %.1f s at %.0f Hz, eye %ux%u%s, seed %llu, head "
              "offset %g,%g,%g mm) and %s (%zu calibration + %zu validation targets)\n",
              files.fgr.c_str(), session.samples.size(), session.events.size(), session.session_s, o.rate_hz, size.w,
              size.h, hard ? " hard" : "", static_cast<unsigned long long>(seed), o.head_offset_mm.x,
              o.head_offset_mm.y, o.head_offset_mm.z, files.targets.c_str(), calibrate,
              session.targets.size() - calibrate);
}

int cmd_synth_calibration(const std::string& out, int points, int validation_points, std::uint64_t seed, bool hard,
                          const std::string& head_offset, const std::string& display_text, const std::string& size) {
  try {
    const EyeImageSize eye_size = parse_eye_image_size(size);
    eye::CalibrationSessionOptions o;
    set_viewer_placement(o, head_offset, display_text);
    set_target_schedule(o.schedule, points, validation_points, seed);
    set_eye_imaging(o.eye, eye_size, seed, hard);
    const SessionFiles files = new_session_files(out);
    spdlog::set_level(spdlog::level::warn);  // the pipeline's start-up lines: not this tool's one-line summary
    o.start_time_ns = monotonic_ns();  // frame 0 on this machine's monotonic clock, as the daemon records
    const std::int64_t created_unix = realtime_ns();
    const eye::CalibrationSession session = eye::simulate_calibration_session(o);
    write_session_files(files, session_recording_header(o, seed, created_unix), session);
    print_session_summary(files, session, o, eye_size, hard, seed);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fovea-ctl synth-calibration: %s\n", e.what());
    return 1;
  }
}

// detect-pupil: the eye pipeline's detector on image files.
Command add_detect_pupil_command(CLI::App& app) {
  struct Options {
    std::vector<std::string> images;
    std::string out, leds;
    int downscale = eye::DetectorSettings{}.coarse_downscale;
    bool track = false, force = false;
  };
  auto o = std::make_shared<Options>();
  auto* detect_pupil = app.add_subcommand(
      "detect-pupil", "find the pupil and corneal glints in eye images (PNG, JPEG, ... 8 or 16 bit); one CSV row "
                      "per image: file,pupil_x,pupil_y,major,minor,angle_deg,confidence,glint_count,glints (pixels from "
                      "the top-left corner; confidence = probability that the centre is within 1 px; method: "
                      "trackerd/eye/EYE.md)");
  detect_pupil->add_option("IMAGE", o->images, "eye images")->required();
  detect_pupil->add_option("--out", o->out, "also write the CSV to this file (refuses to overwrite)");
  detect_pupil->add_flag("--force", o->force, "with --out: replace the file if it exists");
  detect_pupil->add_option("--leds", o->leds,
                           "LED layout to pair glints with: a preset 0..5 or \"x,y;x,y;...\" in mm (default: "
                           "unknown, glints unpaired)");
  detect_pupil->add_option("--downscale", o->downscale, "coarse pupil search on an image 1, 2 or 4 times smaller")
      ->check(CLI::IsMember({1, 2, 4}))
      ->capture_default_str();
  detect_pupil->add_flag("--track", o->track,
                         "treat the images as consecutive video frames: search near the last pupil first, and "
                         "for a pupil found inside a dark iris inside such an iris around it (default: every "
                         "image on its own)");
  return {detect_pupil, [o] { return cmd_detect_pupil(o->images, o->out, o->force, o->leds, o->downscale, o->track); }};
}

// synth-eye: test images for the detector, with their exact truth.
Command add_synth_eye_command(CLI::App& app) {
  auto o = std::make_shared<SynthEyeArgs>();
  auto* synth_eye = app.add_subcommand(
      "synth-eye", "write synthetic infrared eye images (eye_0000.png, ...) with their exact truth (truth.csv) "
                   "for gazes drawn uniformly within +-20 degrees");
  synth_eye->add_option("--out", o->dir, "new or empty directory to write into")->required();
  synth_eye->add_option("--count", o->count, "number of images")->capture_default_str();
  synth_eye->add_option("--size", o->size, "image size WxH")->capture_default_str();
  synth_eye->add_flag("--hard", o->hard,
                      "hard conditions: sensor noise 10, 2 px motion blur, upper lid over 30% of the pupil, "
                      "spectacle reflections, uneven illumination");
  synth_eye->add_option("--seed", o->seed, "random seed (same seed, same images)")->capture_default_str();
  synth_eye->add_option("--leds", o->leds, "LED layout: a preset 0..5 or \"x,y;x,y;...\" in mm")
      ->capture_default_str();
  synth_eye->add_option("--pupil-iris-contrast", o->pupil_iris_contrast,
                        "a dark iris: grey levels between the pupil and the iris next to it, 2..150 "
                        "(dark-brown irises under infrared: 5..15; 0: each eye's own, about 80)")
      ->check(CLI::Range(0.0, 150.0))
      ->capture_default_str();
  synth_eye->add_option("--exposure", o->exposure,
                        "weak or strong infrared light: every lit level times this, 0.05..2 (the sensor noise stays)")
      ->check(CLI::Range(0.05, 2.0))
      ->capture_default_str();
  synth_eye->add_option("--lash-length", o->eyelash_length,
                        "every eyelash times this, 0.2..4 (at 2.5 the long ones hang across the pupil)")
      ->check(CLI::Range(0.2, 4.0))
      ->capture_default_str();
  synth_eye->add_flag("--lit-lashes", o->lit_lashes,
                      "lashes lit by the infrared LEDs: grey lines across the pupil, as infrared cameras see them "
                      "(by default they only darken what they cover)");
  synth_eye->add_option("--lid-cover", o->lid_cover,
                        "share of the pupil's height the upper lid covers, 0..1, with the eye looking straight "
                        "ahead (it drops further when the eye looks down; default 0, 0.3 with --hard)")
      ->check(CLI::Range(0.0, 1.0));
  return {synth_eye, [o] { return cmd_synth_eye(*o); }};
}

// synth-calibration: a recorded calibration session of the synthetic viewer.
Command add_synth_calibration_command(CLI::App& app) {
  struct Options {
    std::string out, offset = "0,0,0", display, size = "320x240";
    int points = 9, validation = 4;
    std::uint64_t seed = 1;
    bool hard = false;
  };
  auto o = std::make_shared<Options>();
  auto* synth_calibration = app.add_subcommand(
      "synth-calibration",
      "write a recorded calibration session of the synthetic viewer, for fovea-calibrate run --headless --from: "
      "the synthetic eye follows the calibration targets (reaction, main-sequence saccades with undershoot and "
      "correction, fixation jitter, blinks) and goes through the daemon's eye pipeline and classifier, as "
      "fovea-trackerd --source synthetic-eye --eye-script calibration:POINTS[:SEED] publishes; writes SESSION.fgr "
      "and the targets shown, on the recording's clock, as SESSION.targets.csv");
  synth_calibration->add_option("--out", o->out, "SESSION.fgr to write (with SESSION.targets.csv beside it; refuses "
                                                 "to overwrite either)")
      ->required();
  synth_calibration->add_option("--points", o->points, "calibration targets: 5, 9, 16 or 64")
      ->check(CLI::IsMember({5, 9, 16, 64}))
      ->capture_default_str();
  synth_calibration->add_option("--validation-points", o->validation, "validation targets after them: 0, 4 or 9")
      ->check(CLI::IsMember({0, 4, 9}))
      ->capture_default_str();
  synth_calibration->add_option("--seed", o->seed, "the viewer, its eye's look and the target order")
      ->capture_default_str();
  synth_calibration->add_flag("--eye-hard", o->hard,
                              "hard imaging conditions: sensor noise 10, 2 px motion blur, upper lid over 30% of "
                              "the pupil, spectacle reflections, uneven illumination");
  synth_calibration->add_option("--head-offset", o->offset,
                                "X,Y,Z mm: the eye displaced from the position the tracker's factory calibration "
                                "assumes (x right, y down, z towards the screen; camera fixed to the screen)")
      ->capture_default_str();
  synth_calibration->add_option("--display", o->display,
                                "display geometry WxH@WMMxHMMmm,DISTmm (default " + to_string(DisplayGeometry{}) + ")");
  synth_calibration->add_option("--eye-size", o->size, "eye image size WxH")->capture_default_str();
  return {synth_calibration, [o] {
            return cmd_synth_calibration(o->out, o->points, o->validation, o->seed, o->hard, o->offset, o->display,
                                         o->size);
          }};
}

}  // namespace

std::vector<Command> add_eye_commands(CLI::App& app) {
  // Braced initializers run left to right: the subcommands are added (and listed by --help) in this order.
  return {add_detect_pupil_command(app), add_synth_eye_command(app), add_synth_calibration_command(app)};
}

}  // namespace fovea::ctl
