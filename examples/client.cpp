// SPDX-License-Identifier: Apache-2.0
// A fovea client in 30 lines: subscribe to fovea-trackerd, print every fixation as soon as the
// daemon says it (provisional, at the saccade's landing) and the gaze once a second.
//   fovea-example-client [HOST:PORT] [SECONDS]     (defaults 127.0.0.1:47800, 5)
#include <fovea/protocol/client.h>

#include <chrono>
#include <cstdio>
#include <string>
#include <thread>

int main(int argc, char** argv) {
  using namespace fovea::protocol;
  ClientOptions options;
  options.server = parse_endpoint(argc > 1 ? argv[1] : "127.0.0.1", kDefaultPort);
  options.streams = kStreamSamples | kStreamEvents | kStreamProvisional;
  GazeClient client(options);
  client.on_event([](const GazeEvent& e, const Arrival&) {
    if (e.kind == EyeMovement::Fixation && e.phase == EventPhase::Start && (e.flags & kEventRetracted) == 0)
      std::printf("fixation%s at (%.3f, %.3f)\n", e.provisional() ? " (provisional)" : "", double{e.centroid_x}, double{e.centroid_y});
  });
  client.start();
  if (!client.wait_subscribed(3000)) return std::fprintf(stderr, "no fovea-trackerd at %s\n", options.server.to_string().c_str()), 1;
  for (int s = 0; s < (argc > 2 ? std::stoi(argv[2]) : 5); ++s) {
    std::this_thread::sleep_for(std::chrono::seconds(1));
    if (const auto g = client.latest_sample()) std::printf("gaze (%.3f, %.3f) %s\n", double{g->x}, double{g->y}, to_string(g->state));
  }
  std::printf("%llu samples, %llu lost\n", static_cast<unsigned long long>(client.stats().samples.received),
              static_cast<unsigned long long>(client.stats().samples.lost));
}
