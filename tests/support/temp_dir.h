// SPDX-License-Identifier: Apache-2.0
#pragma once
// A private temporary directory (mode 0700, from mkdtemp) for one test, removed with everything in
// it when the test is done.
#include <stdlib.h>

#include <filesystem>
#include <string>
#include <system_error>

namespace fovea::test {

struct TempDir {
  std::filesystem::path path;
  explicit TempDir(const std::string& prefix = "fovea-test") {
    std::string tmpl = (std::filesystem::temp_directory_path() / (prefix + "-XXXXXX")).string();
    path = ::mkdtemp(tmpl.data());
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
};

}  // namespace fovea::test
