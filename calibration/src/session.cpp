// SPDX-License-Identifier: Apache-2.0
#include "fovea/calib/session.h"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <stdexcept>

namespace fovea::calib {

const char* to_string(TargetPhase p) { return p == TargetPhase::Calibrate ? "calibrate" : "validate"; }

void ScheduleOptions::check() const {
  auto bad = [](const std::string& what) { throw std::invalid_argument("calibration schedule: " + what); };
  if (points != 5 && points != 9 && points != 16 && points != 64) {
    bad("points must be 5, 9, 16 or 64 (got " + std::to_string(points) + ")");
  }
  if (validation_points != 0 && validation_points != 4 && validation_points != 9) {
    bad("validation points must be 0, 4 or 9 (got " + std::to_string(validation_points) + ")");
  }
  if (!(margin >= 0 && margin < 0.5)) bad("margin must be in [0, 0.5) of the screen");
  const bool finite = std::isfinite(lead_in_s) && std::isfinite(shrink_s) && std::isfinite(settle_s) &&
                      std::isfinite(duration_s);
  if (!finite || lead_in_s < 0 || shrink_s < 0 || settle_s < 0) bad("times must be finite and >= 0");
  if (!(duration_s > settle_s)) bad("the target duration must exceed the settle time (nothing would be collected)");
  if (duration_s > 60) bad("a target duration above 60 s is not a calibration");
}

namespace {

// Fractions of the usable area: n evenly spaced values from 0 to 1.
std::vector<double> spaced(int n) {
  std::vector<double> out;
  for (int i = 0; i < n; ++i) out.push_back(n == 1 ? 0.5 : static_cast<double>(i) / (n - 1));
  return out;
}

std::vector<Point> grid_fractions(int points) {
  if (points == 5) return {{0, 0}, {1, 0}, {0.5, 0.5}, {0, 1}, {1, 1}};
  const int side = points == 9 ? 3 : points == 16 ? 4 : 8;
  std::vector<Point> out;
  for (double y : spaced(side))
    for (double x : spaced(side)) out.push_back({x, y});
  return out;
}

std::vector<Point> validation_fractions(int points) {
  if (points == 0) return {};
  if (points == 4) return {{0.25, 0.25}, {0.75, 0.25}, {0.25, 0.75}, {0.75, 0.75}};
  std::vector<Point> out;
  for (double y : {0.25, 0.5, 0.75})
    for (double x : {0.25, 0.5, 0.75}) out.push_back({x, y});
  return out;
}

// Fisher–Yates with the raw output of mt19937_64 (fully specified by the standard), so the order
// for a seed is the same on every platform and library.
template <class T>
void shuffle(std::vector<T>& v, std::mt19937_64& rng) {
  for (std::size_t i = v.size(); i > 1; --i) {
    const std::size_t j = static_cast<std::size_t>(rng() % i);
    std::swap(v[i - 1], v[j]);
  }
}

}  // namespace

std::vector<ScheduledTarget> make_schedule(double width_px, double height_px, const ScheduleOptions& o) {
  o.check();
  if (!(width_px >= 2 && height_px >= 2 && std::isfinite(width_px) && std::isfinite(height_px))) {
    throw std::invalid_argument("calibration schedule: the display must be at least 2x2 px");
  }
  const double x0 = o.margin * width_px, y0 = o.margin * height_px;
  const double w = width_px - 2 * x0, h = height_px - 2 * y0;
  auto to_px = [&](Point f) { return Point{x0 + f.x * w, y0 + f.y * h}; };

  std::mt19937_64 rng(o.seed);
  std::vector<Point> calibrate = grid_fractions(o.points), validate = validation_fractions(o.validation_points);
  if (o.randomize) {
    shuffle(calibrate, rng);
    shuffle(validate, rng);
  }
  std::vector<ScheduledTarget> out;
  double t = o.lead_in_s;
  auto add = [&](const std::vector<Point>& fractions, TargetPhase phase) {
    for (const Point& f : fractions) {
      ScheduledTarget s;
      s.index = static_cast<int>(out.size());
      s.phase = phase;
      s.position_px = to_px(f);
      s.onset_s = t;
      s.collect_from_s = t + o.settle_s;
      s.collect_to_s = t + o.duration_s;
      out.push_back(s);
      t += o.duration_s;
    }
  };
  add(calibrate, TargetPhase::Calibrate);
  add(validate, TargetPhase::Validate);
  return out;
}

double schedule_end_s(const std::vector<ScheduledTarget>& schedule) {
  return schedule.empty() ? 0 : schedule.back().collect_to_s;
}

std::vector<TargetWindow> place_schedule(const std::vector<ScheduledTarget>& schedule, std::int64_t start_ns) {
  auto at = [&](double s) { return start_ns + static_cast<std::int64_t>(std::llround(s * 1e9)); };
  std::vector<TargetWindow> out;
  for (const ScheduledTarget& s : schedule) {
    out.push_back({s.index, s.phase, s.position_px, at(s.onset_s), at(s.collect_from_s), at(s.collect_to_s)});
  }
  return out;
}

namespace {

constexpr const char* kTargetsHeader = "index,phase,x_px,y_px,onset_ns,collect_from_ns,collect_to_ns";

std::string format_double(double v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

}  // namespace

void write_target_windows(const std::string& path, std::span<const TargetWindow> targets) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::exists(path, ec)) throw std::runtime_error(path + ": exists; not replaced");
  const std::string temp = path + ".partial";
  {
    std::ofstream out(temp, std::ios::trunc);
    if (!out) throw std::runtime_error(temp + ": cannot create (" + std::strerror(errno) + ")");
    out << kTargetsHeader << "\n";
    for (const TargetWindow& t : targets) {
      out << t.index << ',' << to_string(t.phase) << ',' << format_double(t.position_px.x) << ','
          << format_double(t.position_px.y) << ',' << t.onset_ns << ',' << t.collect_from_ns << ','
          << t.collect_to_ns << "\n";
    }
    out.flush();
    if (!out) {
      fs::remove(temp, ec);
      throw std::runtime_error(temp + ": write failed");
    }
  }
  // link(2) refuses an existing name, so a file created meanwhile is not replaced either.
  if (::link(temp.c_str(), path.c_str()) != 0) {
    const int err = errno;
    fs::remove(temp, ec);
    throw std::runtime_error(path + ": cannot create (" + std::strerror(err) + ")");
  }
  fs::remove(temp, ec);
}

std::vector<TargetWindow> read_target_windows(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open (" + std::strerror(errno) + ")");
  std::string line;
  std::size_t no = 0;
  std::vector<TargetWindow> out;
  bool header = false;
  while (std::getline(in, line)) {
    ++no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    const std::string where = path + ":" + std::to_string(no);
    if (!header) {
      if (line != kTargetsHeader) {
        throw std::runtime_error(where + ": header must be '" + std::string(kTargetsHeader) + "'");
      }
      header = true;
      continue;
    }
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) f.push_back(cell);
    if (f.size() != 7) throw std::runtime_error(where + ": expected 7 fields, found " + std::to_string(f.size()));
    static const char* names[] = {"index", "phase", "x_px", "y_px", "onset_ns", "collect_from_ns", "collect_to_ns"};
    auto integer = [&](std::size_t col) {
      std::int64_t v = 0;
      const auto r = std::from_chars(f[col].data(), f[col].data() + f[col].size(), v);
      if (r.ec != std::errc{} || r.ptr != f[col].data() + f[col].size()) {
        throw std::runtime_error(where + ": column " + names[col] + ": not an integer: '" + f[col] + "'");
      }
      return v;
    };
    auto real = [&](std::size_t col) {
      double v = 0;
      const auto r = std::from_chars(f[col].data(), f[col].data() + f[col].size(), v);
      if (r.ec != std::errc{} || r.ptr != f[col].data() + f[col].size() || !std::isfinite(v)) {
        throw std::runtime_error(where + ": column " + names[col] + ": not a finite number: '" + f[col] + "'");
      }
      return v;
    };
    TargetWindow t;
    t.index = static_cast<int>(integer(0));
    if (f[1] == "calibrate") t.phase = TargetPhase::Calibrate;
    else if (f[1] == "validate") t.phase = TargetPhase::Validate;
    else throw std::runtime_error(where + ": column phase: must be calibrate or validate, not '" + f[1] + "'");
    t.position_px = {real(2), real(3)};
    t.onset_ns = integer(4);
    t.collect_from_ns = integer(5);
    t.collect_to_ns = integer(6);
    if (!(t.onset_ns <= t.collect_from_ns && t.collect_from_ns < t.collect_to_ns)) {
      throw std::runtime_error(where + ": times must satisfy onset_ns <= collect_from_ns < collect_to_ns");
    }
    out.push_back(t);
  }
  if (!header) throw std::runtime_error(path + ": empty (no header)");
  if (out.empty()) throw std::runtime_error(path + ": no targets");
  return out;
}

namespace {

double median(std::vector<double> v) {
  const std::size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  double m = v[mid];
  if (v.size() % 2 == 0) {
    m = 0.5 * (m + *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid)));
  }
  return m;
}

}  // namespace

std::vector<TargetCollection> collect(std::span<const RawSample> samples, std::span<const TargetWindow> targets,
                                      const CollectOptions& options) {
  std::vector<TargetCollection> out;
  for (const TargetWindow& t : targets) {
    TargetCollection c;
    c.target = t;
    const auto first = std::lower_bound(samples.begin(), samples.end(), t.collect_from_ns,
                                        [](const RawSample& s, std::int64_t v) { return s.time_ns < v; });
    std::vector<RawSample> usable;
    for (auto it = first; it != samples.end() && it->time_ns < t.collect_to_ns; ++it) {
      ++c.in_window;
      if (!it->valid || !std::isfinite(it->raw.x) || !std::isfinite(it->raw.y)) {
        ++c.invalid;
      } else if (it->state == RawSample::State::Saccade || it->state == RawSample::State::Blink ||
                 it->state == RawSample::State::Pursuit) {
        ++c.moving;
      } else {
        usable.push_back(*it);
      }
    }
    if (!usable.empty()) {
      std::vector<double> xs, ys;
      for (const RawSample& s : usable) {
        xs.push_back(s.raw.x);
        ys.push_back(s.raw.y);
      }
      const Point m{median(xs), median(ys)};
      // Robust spread: for isotropic Gaussian scatter with sigma per axis the distance from the centre
      // is Rayleigh distributed with median sigma * sqrt(2 ln 2) = 1.1774 sigma, so sigma is
      // estimated as the median distance / 1.1774 (the 2-D analogue of 1.4826 MAD).
      std::vector<double> d;
      for (const RawSample& s : usable) d.push_back(std::hypot(s.raw.x - m.x, s.raw.y - m.y));
      const double spread = std::max(median(d) / 1.1774, options.min_spread);
      for (std::size_t i = 0; i < usable.size(); ++i) {
        if (d[i] <= options.mad_k * spread) c.kept.push_back(usable[i]);
        else ++c.outliers;
      }
      c.median_raw = m;
    }
    c.used = c.kept.size() >= options.min_samples;
    if (!c.used) {
      std::ostringstream why;
      why << c.kept.size() << " of " << c.in_window << " samples usable (need " << options.min_samples << "; "
          << c.invalid << " invalid, " << c.moving << " during saccades/blinks, " << c.outliers << " off target)";
      c.why_not = why.str();
    }
    out.push_back(std::move(c));
  }
  return out;
}

std::vector<Correspondence> correspondences(std::span<const TargetCollection> collected, TargetPhase phase) {
  std::vector<Correspondence> out;
  for (const TargetCollection& c : collected) {
    if (!c.used || c.target.phase != phase) continue;
    for (const RawSample& s : c.kept) out.push_back({s.raw, c.target.position_px});
  }
  return out;
}

}  // namespace fovea::calib
