// SPDX-License-Identifier: Apache-2.0
// Prints every canonical message as hex, 16 bytes per line with offsets, for the golden files
// (--golden DIR writes DIR/<name>.hex) and for the worked examples in protocol/PROTOCOL.md.
#include <cstdio>
#include <fstream>
#include <string>

#include "canonical_messages.h"
#include "fovea/protocol/codec.h"

int main(int argc, char** argv) {
  using namespace fovea;
  const std::string golden_dir = argc == 3 && std::string(argv[1]) == "--golden" ? argv[2] : "";
  for (const auto& [name, m] : test::canonical_messages()) {
    const auto bytes = protocol::encode(m);
    std::string hex;
    for (std::size_t i = 0; i < bytes.size(); ++i) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "%02x", bytes[i]);
      hex += buf;
      hex += (i % 16 == 15 || i + 1 == bytes.size()) ? "\n" : " ";
    }
    if (!golden_dir.empty()) {
      std::ofstream(golden_dir + "/" + name + ".hex") << hex;
    } else {
      std::printf("## %s (%s, %zu bytes)\n%s\n", name.c_str(), protocol::to_string(m.header.type), bytes.size(),
                  hex.c_str());
    }
  }
  return 0;
}
