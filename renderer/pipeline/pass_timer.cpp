// SPDX-License-Identifier: Apache-2.0
#include "pipeline/pass_timer.h"

#include <algorithm>
#include <cstdio>
#include <stdexcept>

namespace fovea::render {

PassTimer::PassTimer(const std::string& csv_path) : csv_(csv_path) {
  if (!csv_) throw std::runtime_error("cannot write timing CSV " + csv_path);
  csv_ << "frame,scene_time_s,pass,ms\n";
}

void PassTimer::begin_frame(std::uint64_t frame, double scene_time_s) {
  frame_ = frame;
  scene_time_s_ = scene_time_s;
  this_frame_.clear();
}

void PassTimer::record(const std::string& name, double ms) {
  const std::string pass = prefix_ + name;
  if (!samples_.contains(pass)) order_.push_back(pass);
  samples_[pass].push_back(ms);
  this_frame_[pass] += ms;
  if (csv_.is_open()) {
    char line[160];
    std::snprintf(line, sizeof line, "%llu,%.6f,%s,%.4f\n", static_cast<unsigned long long>(frame_), scene_time_s_,
                  pass.c_str(), ms);
    csv_ << line;
    csv_.flush();
  }
}

double PassTimer::last_ms(const std::string& pass) const {
  const auto it = samples_.find(prefix_ + pass);
  return it == samples_.end() || it->second.empty() ? 0.0 : it->second.back();
}

double PassTimer::frame_ms(const std::string& pass) const {
  const auto it = this_frame_.find(prefix_ + pass);
  return it == this_frame_.end() ? 0.0 : it->second;
}

std::map<std::string, PassTimer::Summary> PassTimer::summary() const {
  std::map<std::string, Summary> out;
  for (const auto& [pass, v] : samples_) {
    std::vector<double> s = v;
    std::sort(s.begin(), s.end());
    Summary sum;
    sum.count = s.size();
    for (double x : s) sum.mean_ms += x;
    sum.mean_ms /= static_cast<double>(s.size());
    sum.p50_ms = s[s.size() / 2];
    sum.p95_ms = s[std::min(s.size() - 1, static_cast<std::size_t>(0.95 * static_cast<double>(s.size())))];
    sum.max_ms = s.back();
    out[pass] = sum;
  }
  return out;
}

std::string PassTimer::summary_table() const {
  const auto sums = summary();
  // The first column as wide as the longest pass name ("readback.display", "load.textures").
  int width = 12;
  for (const std::string& pass : order_) width = std::max(width, static_cast<int>(std::min<std::size_t>(pass.size(), 40)));
  char line[200];
  std::snprintf(line, sizeof line, "%-*s %7s %9s %9s %9s %9s\n", width, "pass", "frames", "mean ms", "p50 ms", "p95 ms",
                "max ms");
  std::string out = line;
  for (const std::string& pass : order_) {
    const Summary& s = sums.at(pass);
    std::snprintf(line, sizeof line, "%-*s %7zu %9.3f %9.3f %9.3f %9.3f\n", width, pass.c_str(), s.count, s.mean_ms,
                  s.p50_ms, s.p95_ms, s.max_ms);
    out += line;
  }
  return out;
}

}  // namespace fovea::render
