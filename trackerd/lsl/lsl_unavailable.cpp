// SPDX-License-Identifier: Apache-2.0
// The LSL outlet in a build without liblsl: every use says so in one line.
#include <stdexcept>

#include "lsl/lsl_outlet.h"

namespace fovea::trackerd {

bool lsl_available() { return false; }

std::string lsl_library_info() {
  return "this fovea-trackerd was built without liblsl (the Lab Streaming Layer library, not packaged by Debian): "
         "install upstream's release .deb from github.com/sccn/liblsl and rebuild (README, \"Lab Streaming Layer\")";
}

std::unique_ptr<LslOutlet> open_lsl_outlet(const LslOutletOptions&) { throw std::runtime_error(lsl_library_info()); }

}  // namespace fovea::trackerd
