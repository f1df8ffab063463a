// SPDX-License-Identifier: Apache-2.0
#pragma once
// The CPU time a process has used, from /proc: the benchmarks that run fovea-trackerd as a process
// report its cost as a share of one core.
#include <unistd.h>

#include <fstream>
#include <sstream>
#include <string>

namespace fovea::bench {

// utime + stime of `pid`, seconds.
inline double cpu_seconds(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  std::getline(in, line);
  // Fields after the parenthesised command name; utime and stime are fields 14 and 15.
  std::istringstream rest(line.substr(line.rfind(')') + 2));
  std::string field;
  double ticks = 0;
  for (int i = 3; i <= 15 && rest >> field; ++i) {
    if (i == 14 || i == 15) ticks += std::stod(field);
  }
  return ticks / static_cast<double>(sysconf(_SC_CLK_TCK));
}

}  // namespace fovea::bench
