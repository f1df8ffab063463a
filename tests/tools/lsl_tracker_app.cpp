// SPDX-License-Identifier: Apache-2.0
// A tracker's app as the lsl: source test needs one (tests/integration/test_lsl_source.cpp), in its
// own process: it opens a liblsl outlet of a known gaze trajectory in pixels with XDF channel
// metadata (or none, with --bare; or, with --strings, a stream of type Gaze whose two channels are
// strings "xxx...", which the source must refuse), waits for GO_FILE (which holds t0, the grid's
// start on liblsl's clock), pushes samples [FROM, TO) on the grid t0 + k / 250 Hz in bursts of 10
// every 40 ms, each burst once its last sample's time has passed (a tracker sends what it has
// taken), lingers 0.5 s for the inlet to drain them, waits for QUIT_FILE unless it is "-", and quits as an app does: _exit, without
// destroying the outlet. (liblsl 1.16.2's outlet destructor races its sender threads and crashed
// the test process now and then, sccn/liblsl#218, fixed after that release; an app that quits or
// dies is the case the source must handle anyway.)
//
// With --flood the outlet declares 60 Hz and, from GO_FILE on, pushes the trajectory's samples
// from FROM on at up to ~30,000/s (500x) for TO - FROM milliseconds, each stamped when it is pushed (a
// misbehaving app; the source must cap what it publishes).
//
//   lsl_tracker_app NAME FROM TO GO_FILE QUIT_FILE|- [--bare|--strings|--flood]
#include <lsl_cpp.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <thread>
#include <vector>

namespace {

constexpr double kRate = 250;

// Sample k of the trajectory: NaN every 25th from 7, confidence 0.2 every 25th from 13.
std::vector<float> sample(int k) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  return {k % 25 == 7 ? nan : 100.0f + static_cast<float>(k), 200.0f + 0.5f * static_cast<float>(k),
          k % 25 == 13 ? 0.2f : 0.9f, 3.0f + 0.001f * static_cast<float>(k), 3.5f};
}

lsl::stream_info tracker_info(const std::string& name, bool with_metadata, double rate = kRate) {
  lsl::stream_info info(name, "Gaze", 5, rate, lsl::cf_float32, name + "-" + std::to_string(lsl::local_clock()));
  if (!with_metadata) return info;
  lsl::xml_element chns = info.desc().append_child("channels");
  const char* rows[][4] = {{"gx", "both", "ScreenX", "pixels"},
                           {"gy", "both", "ScreenY", "pixels"},
                           {"conf", "both", "Confidence", "normalized"},
                           {"pl", "left", "Diameter", "mm"},
                           {"pr", "right", "Diameter", "mm"}};
  for (const auto& r : rows) {
    chns.append_child("channel").append_child_value("label", r[0]).append_child_value("eye", r[1])
        .append_child_value("type", r[2]).append_child_value("unit", r[3]);
  }
  return info;
}

// Waits up to 30 s for `path` to exist; returns its first number (0 if none).
double wait_for_file(const std::string& path) {
  for (int i = 0; i < 1500 && !std::filesystem::exists(path); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  double value = 0;
  std::ifstream(path) >> value;
  return value;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string mode = argc == 7 ? argv[6] : "";
  if (argc != 6 && mode != "--bare" && mode != "--strings" && mode != "--flood") {
    std::fprintf(stderr, "usage: lsl_tracker_app NAME FROM TO GO_FILE QUIT_FILE|- [--bare|--strings|--flood]\n");
    return 2;
  }
  const std::string name = argv[1], quit = argv[5];
  const int from = std::atoi(argv[2]), to = std::atoi(argv[3]);
  const bool strings = mode == "--strings";
  const bool flood = mode == "--flood";
  const std::string uid = name + "-" + std::to_string(lsl::local_clock());
  const lsl::stream_info info = strings ? lsl::stream_info(name, "Gaze", 2, kRate, lsl::cf_string, uid)
                                : flood ? tracker_info(name, true, 60.0)
                                        : tracker_info(name, mode != "--bare");
  auto* outlet = new lsl::stream_outlet(info);  // never destroyed: see above
  const double t0 = wait_for_file(argv[4]);
  if (flood) {
    const double until = lsl::local_clock() + (to - from) * 1e-3;
    // ~30,000 samples/s (500x the declared rate): as fast as a looping app, without taking a whole
    // core from the tests running beside it.
    for (int k = from; lsl::local_clock() < until; ++k) {
      outlet->push_sample(sample(k));
      if (k % 300 == 299) std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }
  const std::vector<std::string> text(2, std::string(40, 'x'));
  for (int k = from; k < to && !flood; k += 10) {
    const int end = std::min(k + 10, to);
    while (lsl::local_clock() < t0 + (end - 1) / kRate) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    for (int j = k; j < end; ++j) {
      if (strings) {
        outlet->push_sample(text, t0 + j / kRate, j + 1 == end);
      } else {
        outlet->push_sample(sample(j), t0 + j / kRate, j + 1 == end);
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(40));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  if (quit != "-") wait_for_file(quit);
  std::fflush(nullptr);
  ::_exit(0);
}
