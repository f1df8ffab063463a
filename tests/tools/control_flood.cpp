// SPDX-License-Identifier: Apache-2.0
// Sends N record-stop requests, one after another, to the daemon serving HOST:PORT, the way
// fovea-ctl does (its control socket, found as fovea-ctl finds it), and prints each reply as
// "RESULT: MESSAGE", or "no reply: WHY". One process sends the whole flood: a shell loop of
// fovea-ctl runs spent its time starting processes, not flooding (under ASan on CI's machine the
// service test took 190 s and then over its 240 s limit, most of it in 600 process starts).
// Usage: fovea-control-flood HOST:PORT N
#include <cstdio>
#include <cstdlib>
#include <string>

#include "fovea/protocol/control_socket.h"
#include "fovea/protocol/udp.h"

using namespace fovea::protocol;

int main(int argc, char** argv) {
  if (argc != 3 || std::atoi(argv[2]) <= 0) {
    std::fprintf(stderr, "usage: %s HOST:PORT N\n", argv[0]);
    return 2;
  }
  const Endpoint server = parse_endpoint(argv[1], kDefaultPort);
  const int n = std::atoi(argv[2]);
  ControlRequest request;
  request.command = ControlCommand::StopRecording;
  int unanswered = 0;
  for (int i = 0; i < n; ++i) {
    std::string error, via;
    const auto reply = send_control_to_daemon(server, "", request, 3000, error, via);
    if (reply) {
      std::printf("%s: %s\n", to_string(reply->result), reply->message.value.c_str());
    } else {
      std::printf("no reply: %s\n", error.c_str());
      ++unanswered;
    }
  }
  return unanswered == 0 ? 0 : 1;
}
