// SPDX-License-Identifier: Apache-2.0
#pragma once
// The time-budget governor (fovea-render --budget-ms): given a frame-time budget, picks each running
// effect's settings from its measured accuracy-versus-time front (fronts.json, made by
// bench/make_fronts.py from the benchmarks' CSVs) to maximise accuracy within the budget, corrects
// each front's times by what the passes really take on this machine and scene, and reports the
// accuracy it expects.
//
// Choice: the combination of one option per running effect (dof, gi, attention, lod: the passes the
// frame plan runs) that maximises the sum of the effects' normalised accuracies (0 = the front's least
// accurate option, 1 = its most accurate) with predicted time <= budget - the frame's other passes.
// Predicted time of an option: its measured time, scaled by the image's pixel count for image-space
// effects, times the effect's correction factor (an exponential average of measured / predicted).
// It re-plans every `replan_frames` frames, and at once when a frame runs over the budget by 20 %;
// it keeps the current choice while that fits and is within 0.05 of the best utility (no flicker).
// When even the cheapest combination does not fit it takes that one and says it cannot meet the budget.
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "pipeline/pass_timer.h"
#include "pipeline/planner.h"
#include "pipeline/settings.h"

namespace fovea::render {

struct FrontOption {
  std::string label;
  std::map<std::string, std::string> settings;
  double ms = 0;        // measured at the front's pixel count
  double accuracy = 0;  // in the front's metric
};

struct Front {
  std::string effect;   // dof, gi, attention, lod
  std::string backend;  // empty: any backend
  // Where its times were measured, as a part of FramePipeline::device() ("llvmpipe", "NVIDIA H200";
  // "cpu": no GPU-resident frame); empty: any. The first front of an effect that matches the
  // backend and the device is used, so device fronts come before the general one.
  std::string device;
  std::vector<std::string> passes;  // the PassTimer names its time is measured by
  std::string metric, reference, source;
  bool higher_better = true;
  bool scales_with_pixels = false;
  double pixels = 0;
  std::vector<FrontOption> options;  // sorted by time
};

// Parses fronts JSON; throws std::invalid_argument naming the field and front that is wrong (and
// any option setting the renderer does not know or accept).
std::vector<Front> parse_fronts(const std::string& json_text, const std::string& origin);
std::vector<Front> load_fronts(const std::string& path);
// The fronts measured on the project's machine, built into the binary.
const std::vector<Front>& builtin_fronts();

class Governor {
 public:
  Governor(double budget_ms, std::vector<Front> fronts);

  struct Choice {
    std::string effect, label, metric;
    double accuracy = 0, predicted_ms = 0, correction = 1;
  };
  struct State {
    double budget_ms = 0;
    double predicted_ms = 0;  // the effects' predicted time plus the frame's other passes
    double measured_ms = 0;   // the last frame
    double other_ms = 0;      // the frame's passes the governor does not choose for (average)
    bool cannot_meet = false;
    std::uint64_t replans = 0;
    std::vector<Choice> choices;
    std::string summary() const;  // one line: "budget 50 ms, predicted 47.1: dof lee-mipmap ... (33.2 PSNR dB)"
  };

  // Before a frame: chooses (when due) and writes the chosen options into `settings`. `device`:
  // FramePipeline::device(), matched against Front::device. width x height: the pixels of all the
  // frame's views (a stereo frame: 2 x camera.width), which image-space fronts scale by.
  // Stereo frames' right-eye passes ("right." names, FramePipeline::Eye) count in observe() as
  // the same passes: an effect's time is both eyes', the frame's both renders.
  void apply(const FramePlan& plan, const std::string& backend, const std::string& device, std::uint32_t width,
             std::uint32_t height, Settings& settings);
  // After the frame: the passes' measured times update the corrections and the other passes' time.
  void observe(const PassTimer& timer);
  const State& state() const { return state_; }
  void set_budget_ms(double ms);
  int replan_frames = 10;

 private:
  double budget_ms_;
  std::vector<Front> fronts_;
  std::map<std::string, double> correction_;  // per effect
  std::map<std::string, std::size_t> chosen_;  // effect -> option index
  std::vector<const Front*> active_;
  double pixels_ = 0;
  double other_ms_ = -1;  // unknown until the first frame
  int frames_since_plan_ = 0;
  bool over_ = false;
  State state_;
  double predicted(const Front& f, const FrontOption& o) const;
  void plan();
};

}  // namespace fovea::render
