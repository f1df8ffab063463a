// SPDX-License-Identifier: Apache-2.0
#pragma once
// The one per-pass timing instrument: every pass of every frame is timed through it, and it writes
// CSV (frame,scene_time_s,pass,ms). Benchmarks read the same CSV.
#include <chrono>
#include <cstdint>
#include <fstream>
#include <map>
#include <string>
#include <vector>

namespace fovea::render {

class PassTimer {
 public:
  PassTimer() = default;
  // Also streams each record to `csv_path` as it is taken (header written first).
  explicit PassTimer(const std::string& csv_path);

  void begin_frame(std::uint64_t frame, double scene_time_s);
  void record(const std::string& pass, double ms);
  // Passes recorded from now on are named prefix + pass (a stereo frame's right eye: "right."), in
  // the CSV, the summary and last_ms/frame_ms alike; "" ends it.
  void set_prefix(std::string prefix) { prefix_ = std::move(prefix); }
  const std::string& prefix() const { return prefix_; }

  class Scope {
   public:
    Scope(PassTimer& timer, std::string pass)
        : timer_(timer), pass_(std::move(pass)), start_(std::chrono::steady_clock::now()) {}
    ~Scope() {
      timer_.record(pass_, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start_).count());
    }
    Scope(const Scope&) = delete;
    Scope& operator=(const Scope&) = delete;

   private:
    PassTimer& timer_;
    std::string pass_;
    std::chrono::steady_clock::time_point start_;
  };
  Scope scope(std::string pass) { return Scope(*this, std::move(pass)); }

  struct Summary {
    std::size_t count = 0;
    double mean_ms = 0, p50_ms = 0, p95_ms = 0, max_ms = 0;
  };
  // Per pass, over all frames recorded so far (the pass "frame" is the whole frame).
  std::map<std::string, Summary> summary() const;
  std::string summary_table() const;
  double last_ms(const std::string& pass) const;
  // The pass's time in the frame begun last (summed when it ran more than once); 0 when it did not run.
  double frame_ms(const std::string& pass) const;

 private:
  std::ofstream csv_;
  std::uint64_t frame_ = 0;
  double scene_time_s_ = 0;
  std::map<std::string, std::vector<double>> samples_;
  std::map<std::string, double> this_frame_;
  std::vector<std::string> order_;
  std::string prefix_;
};

}  // namespace fovea::render
