// SPDX-License-Identifier: Apache-2.0
#pragma once
// A source kind's check (source_table.h, SourceKind::check) from its spec parser: empty when the
// parser takes the spec, else what it said was wrong.
#include <exception>
#include <string>

namespace fovea::trackerd {

template <typename Parse>
std::string spec_problem(Parse&& parse, const std::string& spec) {
  try {
    (void)parse(spec);
    return {};
  } catch (const std::exception& e) {
    return e.what();
  }
}

}  // namespace fovea::trackerd
