#pragma once
// Running the project's programs as whole processes from a test: a shell command's exit status, a
// file's text, waiting for a file, a port unlikely to be taken.
#include <sys/wait.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <thread>

namespace fovea::test {

inline int exit_status(const std::string& command) {
  const int rc = std::system(command.c_str());
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

inline std::string read_text(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

inline bool wait_for(const std::filesystem::path& p, double seconds) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < end) {
    if (std::filesystem::exists(p) && std::filesystem::file_size(p) > 0) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return false;
}

inline int random_port() {
  std::random_device rd;
  return 40000 + static_cast<int>(rd() % 9000);
}

}  // namespace fovea::test
