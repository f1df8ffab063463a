// SPDX-License-Identifier: Apache-2.0
// Calibration accuracy versus cost (step 5): error against the number of calibration points and
// the model, on the synthetic eye following a calibration (trackerd/sim/calibration_viewer.h) with
// realistic fixation behaviour, image noise and a head offset.
//
// For every points count (5, 9, 16, 64) x head offset (0, and --offset) x viewer (seed: its own eye
// look, target order and eye movements) x imaging (normal, hard): one simulated session (the
// calibration targets, then 9 validation targets) through the daemon's pipeline (eye detector,
// factory map, classifier); then per input (the pupil–glint vector of the sample; the
// factory-calibrated screen gaze in px, Jensen & Pedersen's setting of correcting a tracker's own
// calibration) and model (affine, homography, poly2, bilinear-grid, poly2+bilinear-grid; and for
// the screen input the uncalibrated baseline "none" = the factory calibration) collect, fit, map the
// validation samples and measure:
//   mean_err_deg   mean over validation targets of the mean angular error of their kept samples
//   p95_err_deg    95th percentile of the kept validation samples' errors
//   precision_deg  RMS over validation targets of the samples' angular distance from their mean
//   session_s      what the user sits through (schedule end); fit_ms: median of repeated fits
// A fit the model refuses (e.g. bilinear-grid on 5 points) is a row with status n/a and the reason.
// Writes bench/results/bench_calibration.csv (or --csv); bench/plot_calibration.py plots it.
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "sim/calibration_viewer.h"
#include "fovea/calib/model.h"
#include "fovea/calib/session.h"
#include "fovea/protocol/display_geometry.h"

namespace {

using namespace fovea;
using trackerd::eye::CalibrationInput;

struct Job {
  int points = 9;
  bool offset = false;
  std::uint64_t viewer = 1;
  bool hard = false;
};

struct Row {
  Job job;
  std::string input, model, status, reason;
  double mean_err = NAN, p95 = NAN, precision = NAN, session_s = 0, fit_ms = NAN, sim_s = 0;
  std::size_t cal_used = 0, cal_targets = 0, val_used = 0, val_targets = 0;
};

protocol::Degrees deg_of(const protocol::DisplayGeometry& d, calib::Point px) {
  return protocol::normalized_to_degrees(d, {px.x / d.width_px, px.y / d.height_px});
}

void measure(Row& r, const std::vector<calib::TargetCollection>& collected, const protocol::DisplayGeometry& d,
             const std::function<calib::Point(calib::Point)>& map) {
  std::vector<double> all;
  double sum_target = 0, sum_prec2 = 0;
  int targets = 0;
  for (const auto& c : collected) {
    if (c.target.phase != calib::TargetPhase::Validate || !c.used) continue;
    const protocol::Degrees goal = deg_of(d, c.target.position_px);
    std::vector<protocol::Degrees> mapped;
    double e = 0, mx = 0, my = 0;
    for (const auto& s : c.kept) {
      const protocol::Degrees g = deg_of(d, map(s.raw));
      mapped.push_back(g);
      const double err = protocol::angle_between_deg(g, goal);
      all.push_back(err);
      e += err;
      mx += g.x;
      my += g.y;
    }
    const double n = static_cast<double>(mapped.size());
    mx /= n;
    my /= n;
    double p2 = 0;
    for (const auto& g : mapped) {
      const double a = protocol::angle_between_deg(g, {mx, my});
      p2 += a * a;
    }
    sum_target += e / n;
    sum_prec2 += p2 / n;
    ++targets;
  }
  if (targets == 0 || all.empty()) {
    r.status = "n/a";
    r.reason = "no validation target usable";
    return;
  }
  std::sort(all.begin(), all.end());
  r.mean_err = sum_target / targets;
  r.p95 = all[std::min(all.size() - 1, static_cast<std::size_t>(std::ceil(0.95 * static_cast<double>(all.size()))) - 1)];
  r.precision = std::sqrt(sum_prec2 / targets);
  r.status = "ok";
}

std::string csv_text(std::string s) {
  for (char& c : s) c = (c == ',' || c == '\n' || c == '"') ? ';' : c;
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_calibration: calibration error versus points and model on the synthetic eye"};
  int viewers = 4, threads = 2, fit_repeats = 7;
  bool quick = false, no_hard = false;
  // 60 Hz and 160x120 keep the default run (4 viewers x 4 point counts x 2 offsets x 2 imagings =
  // 64 sessions, ~3000 s of simulated calibration) within minutes on two cores.
  double rate = 60;
  std::string csv_path = "bench/results/bench_calibration.csv", offset_text = "25,-15,40", size = "160x120";
  std::string points_text = "5,9,16,64";
  app.add_option("--viewers", viewers, "viewers (seeds 1..N) per condition")->check(CLI::Range(1, 64))->capture_default_str();
  app.add_option("--threads", threads, "simulation threads")->check(CLI::Range(1, 64))->capture_default_str();
  app.add_option("--rate", rate, "eye camera rate, Hz")->capture_default_str();
  app.add_option("--eye-size", size, "eye image WxH")->capture_default_str();
  app.add_option("--offset", offset_text, "the head offset X,Y,Z mm")->capture_default_str();
  app.add_option("--points", points_text, "calibration point counts")->capture_default_str();
  app.add_option("--csv", csv_path, "CSV to write (replaced)")->capture_default_str();
  app.add_option("--fit-repeats", fit_repeats, "fits timed per model (median)")->capture_default_str();
  app.add_flag("--no-hard", no_hard, "normal imaging only");
  app.add_flag("--quick", quick, "2 viewers, 5 and 9 points, normal imaging only (a smoke run)");
  CLI11_PARSE(app, argc, argv);
  spdlog::set_level(spdlog::level::warn);  // one start-up line per session otherwise
  if (quick) {
    viewers = 2;
    points_text = "5,9";
    no_hard = true;
  }
  unsigned w = 0, h = 0;
  if (std::sscanf(size.c_str(), "%ux%u", &w, &h) != 2) {
    std::fprintf(stderr, "--eye-size %s: expected WxH\n", size.c_str());
    return 2;
  }
  std::vector<int> point_counts;
  for (std::size_t pos = 0; pos < points_text.size();) {
    const std::size_t end = std::min(points_text.find(',', pos), points_text.size());
    point_counts.push_back(std::stoi(points_text.substr(pos, end - pos)));
    pos = end + 1;
  }
  const cv::Point3d offset = trackerd::eye::parse_head_offset(offset_text);
  const protocol::DisplayGeometry display;
  const calib::Display calib_display{static_cast<double>(display.width_px), static_cast<double>(display.height_px),
                                     display.width_m * 1000, display.height_m * 1000,
                                     display.viewing_distance_m * 1000};

  // The longest sessions first, so the threads finish together.
  std::vector<Job> jobs;
  for (const int p : point_counts)
    for (const bool off : {false, true})
      for (const bool hard : no_hard ? std::vector<bool>{false} : std::vector<bool>{false, true})
        for (int v = 1; v <= viewers; ++v) jobs.push_back({p, off, static_cast<std::uint64_t>(v), hard});
  std::stable_sort(jobs.begin(), jobs.end(), [](const Job& a, const Job& b) { return a.points > b.points; });

  const std::vector<std::string> models = {"affine", "homography", "poly2", "bilinear-grid", "poly2+bilinear-grid"};
  std::vector<Row> rows;
  std::mutex mutex;
  std::atomic<std::size_t> next{0};
  const auto t0 = std::chrono::steady_clock::now();
  const auto work = [&] {
    for (std::size_t j; (j = next.fetch_add(1)) < jobs.size();) {
      const Job job = jobs[j];
      trackerd::eye::CalibrationSessionOptions o;
      o.schedule.points = job.points;
      o.schedule.validation_points = 9;
      o.schedule.seed = job.viewer;
      o.eye.width = static_cast<int>(w);
      o.eye.height = static_cast<int>(h);
      o.eye.seed = job.viewer;
      if (job.hard) o.eye = trackerd::eye::with_hard_conditions(o.eye);
      o.head_offset_mm = job.offset ? offset : cv::Point3d{0, 0, 0};
      o.rate_hz = rate;
      o.display = display;
      const auto s0 = std::chrono::steady_clock::now();
      const auto session = trackerd::eye::simulate_calibration_session(o);
      const double sim_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - s0).count();
      std::vector<Row> out;
      for (const CalibrationInput input : {CalibrationInput::PupilGlint, CalibrationInput::Screen}) {
        const auto raw = trackerd::eye::raw_samples(session.samples, input, display);
        const auto collected = calib::collect(raw, session.targets);
        const auto corr = calib::correspondences(collected, calib::TargetPhase::Calibrate);
        Row base;
        base.job = job;
        base.input = trackerd::eye::to_string(input);
        base.session_s = session.session_s;
        base.sim_s = sim_s;
        for (const auto& c : collected) {
          const bool cal = c.target.phase == calib::TargetPhase::Calibrate;
          (cal ? base.cal_targets : base.val_targets) += 1;
          if (c.used) (cal ? base.cal_used : base.val_used) += 1;
        }
        std::vector<std::string> names = models;
        if (input == CalibrationInput::Screen) names.insert(names.begin(), "none");
        // The same models fitted to the Fick angles of the targets (what fovea-calibrate run does
        // for pupil-glint input): the eye rotates, the screen is flat.
        if (input == CalibrationInput::PupilGlint) {
          for (const char* m : {"affine@fick", "homography@fick", "poly2@fick"}) names.push_back(m);
        }
        for (const std::string& model : names) {
          Row r = base;
          r.model = model;
          if (model == "none") {
            measure(r, collected, display, [](calib::Point p) { return p; });
            r.fit_ms = 0;
            out.push_back(r);
            continue;
          }
          if (model == "bilinear-grid" && input == CalibrationInput::PupilGlint) {
            r.status = "n/a";
            r.reason = "the grid corrects screen points (J&P); a pupil-glint vector is not one: see poly2+bilinear-grid";
            out.push_back(r);
            continue;
          }
          const auto fit = [&] {
            if (model == "poly2+bilinear-grid") {
              const calib::Calibration b = calib::fit_calibration("poly2", corr);
              return calib::fit_calibration("bilinear-grid", corr, &b);
            }
            if (const auto at = model.find("@fick"); at != std::string::npos) {
              return calib::fit_calibration(model.substr(0, at), corr, nullptr, {}, &calib_display);
            }
            return calib::fit_calibration(model, corr);
          };
          try {
            std::vector<double> times;
            calib::Calibration cal;
            for (int k = 0; k < std::max(fit_repeats, 1); ++k) {
              const auto f0 = std::chrono::steady_clock::now();
              cal = fit();
              times.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - f0).count());
            }
            std::sort(times.begin(), times.end());
            r.fit_ms = times[times.size() / 2];
            measure(r, collected, display, [&cal](calib::Point p) { return cal.apply(p); });
          } catch (const std::exception& e) {
            r.status = "n/a";
            r.reason = e.what();
          }
          out.push_back(r);
        }
      }
      std::lock_guard lock(mutex);
      rows.insert(rows.end(), out.begin(), out.end());
      std::fprintf(stderr, "  %2zu/%zu  %2d points, offset %d, viewer %llu, %s: %.1f s session simulated in %.1f s\n",
                   rows.size() / 14, jobs.size(), job.points, job.offset ? 1 : 0,
                   static_cast<unsigned long long>(job.viewer), job.hard ? "hard" : "normal", session.session_s, sim_s);
    }
  };
  std::vector<std::thread> pool;
  for (int i = 0; i < threads; ++i) pool.emplace_back(work);
  for (auto& t : pool) t.join();
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  std::sort(rows.begin(), rows.end(), [](const Row& a, const Row& b) {
    return std::tie(a.job.offset, a.job.hard, a.input, a.model, a.job.points, a.job.viewer) <
           std::tie(b.job.offset, b.job.hard, b.input, b.model, b.job.points, b.job.viewer);
  });
  std::ofstream csv(csv_path);
  if (!csv) {
    std::fprintf(stderr, "cannot write %s\n", csv_path.c_str());
    return 1;
  }
  csv << "# bench_calibration: " << rate << " Hz, eye " << w << "x" << h << ", display " << protocol::to_string(display)
      << ", head offset " << offset_text << " mm, " << viewers << " viewers, 9 validation targets\n";
  csv << "points,model,input,offset_mm,imaging,viewer,status,mean_err_deg,p95_err_deg,precision_deg,session_s,fit_ms,"
         "cal_used,cal_targets,val_used,val_targets,reason\n";
  for (const Row& r : rows) {
    char buf[512];
    std::snprintf(buf, sizeof buf, "%d,%s,%s,%s,%s,%llu,%s,%.4f,%.4f,%.4f,%.2f,%.4f,%zu,%zu,%zu,%zu,", r.job.points,
                  r.model.c_str(), r.input.c_str(), r.job.offset ? csv_text(offset_text).c_str() : "0",
                  r.job.hard ? "hard" : "normal", static_cast<unsigned long long>(r.job.viewer), r.status.c_str(),
                  r.mean_err, r.p95, r.precision, r.session_s, r.fit_ms, r.cal_used, r.cal_targets, r.val_used,
                  r.val_targets);
    csv << buf << csv_text(r.reason) << "\n";
  }

  // Summary: mean over viewers of the mean error (deg), per offset/imaging/input/model x points.
  std::map<std::string, std::map<int, std::pair<double, int>>> table;
  std::map<std::string, std::string> why;
  for (const Row& r : rows) {
    const std::string key = std::string(r.job.offset ? "offset" : "0     ") + "  " + (r.job.hard ? "hard  " : "normal") +
                            "  " + r.input + "  " + r.model;
    auto& cell = table[key][r.job.points];
    if (r.status == "ok") {
      cell.first += r.mean_err;
      cell.second += 1;
    }
  }
  std::printf("mean validation error (deg), mean over %d viewers; n/a = refused\n%-52s", viewers, "offset imaging input model");
  for (const int p : point_counts) std::printf(" %7d", p);
  std::printf("\n");
  for (const auto& [key, cells] : table) {
    std::printf("%-52s", key.c_str());
    for (const int p : point_counts) {
      const auto it = cells.find(p);
      if (it == cells.end() || it->second.second == 0) {
        std::printf(" %7s", "n/a");
      } else {
        std::printf(" %7.3f", it->second.first / it->second.second);
      }
    }
    std::printf("\n");
  }
  std::printf("%zu sessions, %d threads, %.0f s wall; wrote %s\n", jobs.size(), threads, wall, csv_path.c_str());
  return 0;
}
