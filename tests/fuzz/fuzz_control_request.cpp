// SPDX-License-Identifier: Apache-2.0
// libFuzzer entry point for what the daemon does with a control request's bytes before it acts
// (issue 23): the datagram decoded as the control socket decodes it, the path argument confined to
// a directory as record-start and calibration-load confine it, and the argument escaped for the
// log. Whatever the bytes: a path that comes back lies inside the directory (lexically, and with
// its directory's links resolved), a refusal is a PathRefused, and the escaped text holds no
// control character that could forge a log line or reach a terminal.
#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <span>
#include <string>

#include "fovea/protocol/bounded_file.h"
#include "fovea/protocol/codec.h"
#include "service/control_paths.h"

namespace {

namespace fs = std::filesystem;

// A directory with a subdirectory and a link that leads out of it, made once per process and
// removed at its exit.
struct Root {
  fs::path dir;
  Root() {
    const fs::path d = fs::temp_directory_path() / ("fovea-fuzz-control-" + std::to_string(::getpid()));
    fs::create_directories(d / "sub");
    std::error_code ec;
    fs::create_directory_symlink("/", d / "out", ec);
    dir = fs::canonical(d);
  }
  ~Root() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

const fs::path& root() {
  static const Root r;
  return r.dir;
}

bool within(const fs::path& inner, const fs::path& outer) {
  auto i = inner.begin();
  for (auto o = outer.begin(); o != outer.end(); ++o, ++i) {
    if (i == inner.end() || *i != *o) return false;
  }
  return true;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace fovea;
  protocol::Message m;
  if (!protocol::decode(std::span<const std::uint8_t>(data, size), m)) return 0;
  const auto* request = std::get_if<protocol::ControlRequest>(&m.payload);
  if (request == nullptr) return 0;
  const std::string& argument = request->argument.value;

  for (const char c : protocol::escape_for_log(argument)) {
    const auto b = static_cast<unsigned char>(c);
    if (b < 0x20 || b == 0x7f) std::abort();  // a newline or an escape sequence reached the log
  }
  try {
    const fs::path p = trackerd::service::confined_path(argument, root().string());
    if (!within(p, root()) || p == root()) std::abort();
    if (!within(fs::canonical(p.parent_path()), root())) std::abort();
  } catch (const trackerd::service::PathRefused&) {
    // refused, with a reason: what a hostile request should get
  }
  return 0;
}
