// SPDX-License-Identifier: Apache-2.0
#pragma once
// CSV import/export of gaze samples; columns documented in protocol/RECORDING.md.
#include <iosfwd>
#include <string>

#include "fovea/protocol/recording.h"

namespace fovea::protocol {

// Writes the header comments, the column line and one line per sample. Events and markers are not
// part of this CSV form; returns how many records were events and therefore left out.
std::size_t write_csv(std::ostream& out, const Recording& rec);

// The recording's markers as their own CSV (columns in RECORDING.md: sequence, time_ns on the same
// clock as the samples' tracker_time_ns, received_ns, time_source, label quoted as RFC 4180 says);
// returns how many.
std::size_t write_markers_csv(std::ostream& out, const Recording& rec);
std::size_t count_markers(const Recording& rec);

// Parses the CSV form. Throws std::runtime_error naming `source_name`, the line, the column and
// the allowed range on the first bad value; nothing partial is returned.
Recording read_csv(std::istream& in, const std::string& source_name);

}  // namespace fovea::protocol
