// SPDX-License-Identifier: Apache-2.0
// The lsl: source in a build without liblsl: it says so in one line.
#include <stdexcept>

#include "lsl/lsl_outlet.h"
#include "sources/lsl/lsl_source.h"

namespace fovea::trackerd::lsl_source {

std::unique_ptr<GazeSource> make_lsl_source(const LslSpec& spec, protocol::DisplayGeometry, double) {
  throw std::runtime_error("source \"" + spec.to_string() + "\": " + lsl_library_info());
}

}  // namespace fovea::trackerd::lsl_source
