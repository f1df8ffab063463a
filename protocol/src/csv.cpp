// SPDX-License-Identifier: Apache-2.0
#include "fovea/protocol/csv.h"

#include "fovea/protocol/bounded_file.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <istream>
#include <ostream>
#include <stdexcept>
#include <vector>

namespace fovea::protocol {

namespace {

constexpr const char* kColumns[] = {
    "sequence", "tracker_time_ns", "x", "y", "x_deg", "y_deg", "angular_velocity_deg_s", "confidence", "state",
    "gaze_valid", "left_flags", "left_pupil_x_px", "left_pupil_y_px", "left_pupil_diameter_mm",
    "left_pupil_glint_x_px", "left_pupil_glint_y_px", "right_flags", "right_pupil_x_px", "right_pupil_y_px",
    "right_pupil_diameter_mm", "right_pupil_glint_x_px", "right_pupil_glint_y_px", "host_receive_ns"};
constexpr std::size_t kColumnCount = sizeof(kColumns) / sizeof(kColumns[0]);
// Files written before host_receive_ns existed have the first 22 columns only; they are still read.
constexpr std::size_t kOldColumnCount = kColumnCount - 1;

std::string fmt_float(float v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.9g", static_cast<double>(v));  // round-trips binary32 exactly
  return buf;
}

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> out;
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = line.find(',', start);
    out.push_back(line.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  for (auto& f : out) {
    while (!f.empty() && (f.back() == ' ' || f.back() == '\r')) f.pop_back();
    while (!f.empty() && f.front() == ' ') f.erase(f.begin());
  }
  return out;
}

struct LineParser {
  const std::string& source;
  std::size_t line_no;
  const std::vector<std::string>& fields;

  [[noreturn]] void fail(std::size_t col, const std::string& why) const {
    throw std::runtime_error(source + ":" + std::to_string(line_no) + ": column " + std::to_string(col + 1) + " (" +
                             kColumns[col] + ") = \"" + escape_for_log(fields[col], 40) + "\": " + why);
  }
  template <typename T>
  T integer(std::size_t col, T lo, T hi) const {
    const std::string& f = fields[col];
    T v{};
    const auto [ptr, ec] = std::from_chars(f.data(), f.data() + f.size(), v);
    if (ec != std::errc{} || ptr != f.data() + f.size()) fail(col, "not an integer");
    if (v < lo || v > hi) fail(col, "out of range " + std::to_string(lo) + ".." + std::to_string(hi));
    return v;
  }
  float real(std::size_t col, double lo = -1e30, double hi = 1e30) const {
    const std::string& f = fields[col];
    char* end = nullptr;
    const double v = std::strtod(f.c_str(), &end);
    if (f.empty() || end != f.c_str() + f.size()) fail(col, "not a number");
    if (!std::isfinite(v)) fail(col, "must be finite (NaN and Inf are not allowed)");
    if (v < lo || v > hi) {
      char buf[96];
      std::snprintf(buf, sizeof buf, "out of range [%g, %g]", lo, hi);
      fail(col, buf);
    }
    return static_cast<float>(v);
  }
  EyeMovement state(std::size_t col) const {
    for (std::uint8_t i = 0; i <= kMaxEyeMovement; ++i) {
      if (fields[col] == to_string(static_cast<EyeMovement>(i))) return static_cast<EyeMovement>(i);
    }
    fail(col, "expected one of unknown, fixation, saccade, pursuit, blink");
  }
  EyeData eye(std::size_t col) const {
    EyeData e;
    e.flags = integer<std::uint8_t>(col, 0, kEyeFlagMask);
    e.pupil_x_px = real(col + 1);
    e.pupil_y_px = real(col + 2);
    e.pupil_diameter_mm = real(col + 3, 0.0);
    e.pupil_glint_x_px = real(col + 4);
    e.pupil_glint_y_px = real(col + 5);
    return e;
  }
};

void write_eye(std::ostream& out, const EyeData& e) {
  out << ',' << unsigned{e.flags} << ',' << fmt_float(e.pupil_x_px) << ',' << fmt_float(e.pupil_y_px) << ','
      << fmt_float(e.pupil_diameter_mm) << ',' << fmt_float(e.pupil_glint_x_px) << ','
      << fmt_float(e.pupil_glint_y_px);
}

// A "# key: value" comment line carries a header field (as write_csv writes them); other comments are ignored.
void apply_header_comment(RecordingHeader& header, const std::string& line, const std::string& source,
                          std::size_t line_no) {
  const auto colon = line.find(':');
  if (colon == std::string::npos) return;
  std::string key = line.substr(1, colon - 1);
  std::string value = line.substr(colon + 1);
  while (!key.empty() && key.front() == ' ') key.erase(key.begin());
  while (!value.empty() && value.front() == ' ') value.erase(value.begin());
  try {
    if (key == "device") {
      header.device = recording_device_name(value);
    } else if (key == "display") {
      header.display = parse_display_geometry(value);
    } else if (key == "sample_rate_hz") {
      std::size_t used = 0;
      const double hz = std::stod(value, &used);
      if (used != value.size() || !std::isfinite(hz) || hz < 0 || hz > 100000) {
        throw std::invalid_argument("sample_rate_hz \"" + value + "\" is not a number in [0, 100000]");
      }
      header.nominal_rate_hz = hz;
    }
  } catch (const std::exception& e) {
    throw std::runtime_error(source + ":" + std::to_string(line_no) + ": " + e.what());
  }
}

// The column line must name exactly kColumns in order (or the first 22 of them): a file of another
// layout is refused, not misread. Returns how many columns the lines have.
std::size_t check_column_line(const std::vector<std::string>& fields, const std::string& source, std::size_t line_no) {
  if (fields.size() != kColumnCount && fields.size() != kOldColumnCount) {
    throw std::runtime_error(source + ":" + std::to_string(line_no) + ": expected the " +
                             std::to_string(kColumnCount) + "-column header starting \"sequence,tracker_time_ns,\"" +
                             ", found " + std::to_string(fields.size()) + " columns");
  }
  for (std::size_t i = 0; i < fields.size(); ++i) {
    if (fields[i] != kColumns[i]) {
      throw std::runtime_error(source + ":" + std::to_string(line_no) + ": column " + std::to_string(i + 1) +
                               " is \"" + fields[i] + "\", expected \"" + kColumns[i] + "\"");
    }
  }
  return fields.size();
}

// Columns 1..21 in column order, so the error names the first bad column of the line.
GazeSample parse_sample(const LineParser& p) {
  GazeSample s;
  s.tracker_time_ns = p.integer<std::int64_t>(1, INT64_MIN, INT64_MAX);
  s.x = p.real(2);
  s.y = p.real(3);
  s.x_deg = p.real(4, -180, 180);
  s.y_deg = p.real(5, -180, 180);
  s.angular_velocity_deg_s = p.real(6, 0.0);
  s.confidence = p.real(7, 0.0, 1.0);
  s.state = p.state(8);
  s.flags = p.integer<std::uint8_t>(9, 0, 1) ? kGazeValid : 0;
  s.left = p.eye(10);
  s.right = p.eye(16);
  return s;
}

// Samples must arrive in time order (as a recording holds them); a line that goes back in time is an error.
void append_sample_line(Recording& rec, const std::vector<std::string>& fields, std::size_t columns,
                        const std::string& source, std::size_t line_no) {
  if (fields.size() != columns) {
    throw std::runtime_error(source + ":" + std::to_string(line_no) + ": expected " + std::to_string(columns) +
                             " columns, found " + std::to_string(fields.size()));
  }
  const LineParser p{source, line_no, fields};
  Record r;
  r.sequence = p.integer<std::uint64_t>(0, 0, UINT64_MAX);
  const GazeSample s = parse_sample(p);
  if (!rec.records.empty() && s.tracker_time_ns < rec.records.back().time_ns()) {
    throw std::runtime_error(source + ":" + std::to_string(line_no) +
                             ": tracker_time_ns goes backwards (samples must be in time order)");
  }
  r.item = s;
  // Empty: the source had no receive time of its own (the sample's time is the host's).
  if (columns == kColumnCount && !fields[22].empty()) r.host_receive_ns = p.integer<std::int64_t>(22, INT64_MIN, INT64_MAX);
  rec.records.push_back(r);
}

}  // namespace

std::size_t write_csv(std::ostream& out, const Recording& rec) {
  out << "# fovea gaze samples v1\n";
  std::string device = rec.header.device;
  for (char& ch : device) {
    if (static_cast<unsigned char>(ch) < 0x20) ch = ' ';  // one line per header field
  }
  out << "# device: " << device << "\n";
  out << "# display: " << to_string(rec.header.display) << "\n";
  char rate[64];
  std::snprintf(rate, sizeof rate, "%.17g", rec.header.nominal_rate_hz);
  out << "# sample_rate_hz: " << rate << "\n";
  for (std::size_t i = 0; i < kColumnCount; ++i) out << (i ? "," : "") << kColumns[i];
  out << "\n";
  std::size_t events = 0;
  for (const Record& r : rec.records) {
    const auto* s = std::get_if<GazeSample>(&r.item);
    if (s == nullptr) {
      if (std::holds_alternative<GazeEvent>(r.item)) ++events;
      continue;
    }
    out << r.sequence << ',' << s->tracker_time_ns << ',' << fmt_float(s->x) << ',' << fmt_float(s->y) << ','
        << fmt_float(s->x_deg) << ',' << fmt_float(s->y_deg) << ',' << fmt_float(s->angular_velocity_deg_s) << ','
        << fmt_float(s->confidence) << ',' << to_string(s->state) << ',' << ((s->flags & kGazeValid) ? 1 : 0);
    write_eye(out, s->left);
    write_eye(out, s->right);
    out << ',';
    if (r.host_receive_ns) out << *r.host_receive_ns;
    out << '\n';
  }
  return events;
}

std::size_t count_markers(const Recording& rec) {
  return static_cast<std::size_t>(std::count_if(rec.records.begin(), rec.records.end(), [](const Record& r) {
    return std::holds_alternative<Marker>(r.item);
  }));
}

std::size_t write_markers_csv(std::ostream& out, const Recording& rec) {
  out << "# fovea markers v1\n";
  out << "# times: the recording's clock, as the samples' tracker_time_ns\n";
  out << "sequence,time_ns,received_ns,time_source,label\n";
  std::size_t n = 0;
  for (const Record& r : rec.records) {
    const auto* m = std::get_if<Marker>(&r.item);
    if (m == nullptr) continue;
    // Labels are printable UTF-8 (the decoder refused anything else); commas and quotes stay
    // inside one quoted field.
    std::string label;
    for (const char ch : m->label.value) label += ch == '"' ? std::string("\"\"") : std::string(1, ch);
    out << r.sequence << ',' << m->time_ns << ',' << m->received_ns << ','
        << ((m->flags & kMarkerClientTime) != 0 ? "client" : "daemon") << ",\"" << label << "\"\n";
    ++n;
  }
  return n;
}

Recording read_csv(std::istream& in, const std::string& source) {
  Recording rec;
  rec.report.header_valid = true;
  rec.header.device = "csv import";
  std::string line;
  std::size_t line_no = 0;
  std::size_t columns = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    if (line[0] == '#') {
      apply_header_comment(rec.header, line, source, line_no);
      continue;
    }
    const std::vector<std::string> fields = split(line);
    if (columns == 0) {
      columns = check_column_line(fields, source, line_no);
      continue;
    }
    append_sample_line(rec, fields, columns, source, line_no);
  }
  if (columns == 0) throw std::runtime_error(source + ": no column header line found (is this a fovea gaze CSV?)");
  rec.report.records = rec.records.size();
  return rec;
}

}  // namespace fovea::protocol
