// SPDX-License-Identifier: Apache-2.0
// fovea-ctl's recording tools: convert (.fgr <-> .csv, repairing damaged files; .fgr -> BIDS), info, and classify
// (offline eye-movement classification of a CSV of gaze points, trackerd/CLASSIFY.md).
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>

#include "classify/classifier.h"
#include "classify/evaluate.h"
#include "classify/features.h"
#include "classify/provisional.h"
#include "classify/context.h"
#include "classify/trees_core.h"
#include "ctl/bids_export.h"
#include "ctl/commands.h"
#include "fovea/protocol/bounded_file.h"
#include "fovea/protocol/csv.h"
#include "fovea/protocol/recording.h"

namespace fovea::ctl {
namespace {

using namespace fovea::protocol;

Recording load_any(const std::string& path) {
  if (ends_with(path, ".csv")) {
    std::ifstream in(path);
    if (!in) throw std::runtime_error("cannot open " + path);
    return read_csv(in, path);
  }
  return read_recording(path);
}

// OUT.csv's markers go to OUT.markers.csv, written the same careful way as OUT itself.
void write_markers_beside(const Recording& rec, const std::string& out_path, bool force) {
  const std::string path = out_path.substr(0, out_path.size() - 4) + ".markers.csv";
  std::ostringstream text;
  const std::size_t n = write_markers_csv(text, rec);
  write_new_file(path, text.str(), force);
  std::fprintf(stderr, "fovea-ctl convert: wrote %zu markers to %s\n", n, path.c_str());
}

int cmd_convert(const std::string& in_path, const std::string& out_path, bool force) {
  // A name of our own next to OUT, so rename() is atomic and nobody else's file is touched.
  const std::string tmp = out_path + ".partial-" + std::to_string(getpid());
  try {
    if (!force && std::filesystem::exists(out_path)) {
      throw std::runtime_error(out_path + " already exists (use --force to replace it)");
    }
    const Recording rec = load_any(in_path);
    std::fprintf(stderr, "fovea-ctl convert: %s: %s\n", in_path.c_str(), rec.report.describe().c_str());
    if (ends_with(out_path, ".csv")) {
      std::ofstream out(tmp);
      const std::size_t events = write_csv(out, rec);
      out.close();
      if (!out) throw std::runtime_error("cannot write " + tmp);
      if (events > 0) std::fprintf(stderr, "fovea-ctl convert: %zu events left out (CSV holds samples only)\n", events);
      if (count_markers(rec) > 0) write_markers_beside(rec, out_path, force);
    } else if (ends_with(out_path, ".fgr")) {
      RecordingWriter w(tmp, rec.header);
      for (const Record& r : rec.records) w.append(r);
      w.sync();
    } else {
      throw std::runtime_error("output " + out_path + ": unknown format (use .fgr or .csv)");
    }
    // Replace atomically so an interrupted conversion never leaves a half-written output.
    std::filesystem::rename(tmp, out_path);
    std::fprintf(stderr, "fovea-ctl convert: wrote %s\n", out_path.c_str());
    return 0;
  } catch (const std::exception& e) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    std::fprintf(stderr, "fovea-ctl convert: %s\n", e.what());
    return 1;
  }
}

struct ConvertArgs {
  std::string in_path, out_path, format = "auto";
  bool force = false;
  BidsOptions bids;
};

// convert --format bids: IN (.fgr or .csv) into the BIDS dataset directory OUT (protocol/RECORDING.md,
// "BIDS export"); never replaces a file.
int cmd_convert_bids(const ConvertArgs& a) {
  try {
    if (a.force) throw std::runtime_error("--force does not apply to --format bids: a BIDS export never replaces a file");
    BidsOptions o = a.bids;
    o.dataset_dir = a.out_path;
    o.generator_version = FOVEA_VERSION;
    if (o.subject.empty() || o.task.empty()) throw std::runtime_error("--format bids needs --subject and --task");
    // Labels and existing outputs are checked before the recording is read.
    for (const auto& [what, label] : {std::pair<const char*, const std::string*>{"--subject", &o.subject},
                                      {"--task", &o.task},
                                      {"--recording", &o.recording}}) {
      if (std::string err = bids_label_error(what, *label); !err.empty()) throw std::runtime_error(err);
    }
    if (std::filesystem::exists(a.out_path) && !std::filesystem::is_directory(a.out_path)) {
      throw std::runtime_error(a.out_path + " exists and is not a directory (--format bids writes a BIDS dataset directory)");
    }
    for (const std::string& name : bids_output_names(o)) {
      if (const std::string p = a.out_path + "/" + name; std::filesystem::exists(p)) {
        throw std::runtime_error(p + " already exists; BIDS export never replaces a file (choose another --subject, "
                                 "--session, --task, --run or --recording)");
      }
    }
    const Recording rec = load_any(a.in_path);
    std::fprintf(stderr, "fovea-ctl convert: %s: %s\n", a.in_path.c_str(), rec.report.describe().c_str());
    const BidsResult r = export_bids(rec, o);
    std::fprintf(stderr, "fovea-ctl convert: %zu samples (%zu with valid gaze) at %g Hz%s, %zu eye-movement events, %zu markers\n",
                 r.samples, r.valid_samples, r.sampling_frequency, r.measured_rate ? " (measured: the header has no rate)" : "",
                 r.events, r.markers);
    if (r.unfinished_events > 0) {
      std::fprintf(stderr, "fovea-ctl convert: %zu events left out (started but not ended in the recording)\n",
                   r.unfinished_events);
    }
    for (const std::string& f : r.written) std::fprintf(stderr, "fovea-ctl convert: wrote %s\n", f.c_str());
    if (std::find(r.written.begin(), r.written.end(), r.scans_tsv) == r.written.end()) {
      std::fprintf(stderr, "fovea-ctl convert: added a row to %s\n", r.scans_tsv.c_str());
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fovea-ctl convert: %s\n", e.what());
    return 1;
  }
}

int cmd_convert_any(const ConvertArgs& a) {
  if (a.format == "bids") return cmd_convert_bids(a);
  if (!a.bids.subject.empty() || !a.bids.task.empty() || !a.bids.session.empty() || !a.bids.run.empty() ||
      a.bids.recording != "eye1") {
    std::fprintf(stderr, "fovea-ctl convert: --subject, --task, --session, --run and --recording need --format bids\n");
    return 1;
  }
  const bool csv = ends_with(a.out_path, ".csv"), fgr = ends_with(a.out_path, ".fgr");
  if ((a.format == "csv" && !csv) || (a.format == "fgr" && !fgr)) {
    std::fprintf(stderr, "fovea-ctl convert: --format %s needs OUT ending in .%s\n", a.format.c_str(), a.format.c_str());
    return 1;
  }
  return cmd_convert(a.in_path, a.out_path, a.force);
}

int cmd_info(const std::string& path) {
  try {
    const Recording rec = load_any(path);
    std::size_t samples = 0, valid = 0, markers = 0;
    std::map<std::string, std::size_t> ends;
    std::int64_t first = INT64_MAX, last = INT64_MIN;
    for (const Record& r : rec.records) {
      if (const auto* s = std::get_if<GazeSample>(&r.item)) {
        first = std::min(first, s->tracker_time_ns);  // the span of samples: events may end later
        last = std::max(last, s->tracker_time_ns);
        ++samples;
        if (s->flags & kGazeValid) ++valid;
      } else if (const auto* e = std::get_if<GazeEvent>(&r.item); e != nullptr && e->phase == EventPhase::End) {
        ++ends[to_string(e->kind)];
      } else if (std::holds_alternative<Marker>(r.item)) {
        ++markers;
      }
    }
    std::printf("file        %s\n", path.c_str());
    std::printf("device      %s\n", escape_for_log(rec.header.device).c_str());
    std::printf("display     %s\n", to_string(rec.header.display).c_str());
    std::printf("rate        %.1f Hz (nominal)\n", rec.header.nominal_rate_hz);
    const double span = samples > 1 ? static_cast<double>(last - first) / 1e9 : 0;
    std::printf("span        %.3f s\n", span);
    std::printf("samples     %zu (%zu with valid gaze)", samples, valid);
    if (span > 0) std::printf(", %.1f Hz measured", static_cast<double>(samples - 1) / span);
    std::printf("\n");
    std::printf("events     ");
    for (const auto& [k, n] : ends) std::printf(" %zu %s", n, k.c_str());
    std::printf("\nmarkers     %zu", markers);
    std::printf("\nintegrity   %s\n", rec.report.describe().c_str());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fovea-ctl info: %s\n", e.what());
    return 1;
  }
}

// --- classify: offline eye-movement classification of a CSV of gaze points (trackerd/CLASSIFY.md) ---

// Parses a decimal number field of the classify input; `nan_ok` accepts "nan" (any case) and an
// empty field (how many exports leave a lost sample's cell) as NaN.
double classify_field(const std::string& text, const char* name, bool nan_ok, const std::string& where) {
  std::string t = text;
  while (!t.empty() && (t.back() == ' ' || t.back() == '\t')) t.pop_back();
  std::size_t b = 0;
  while (b < t.size() && (t[b] == ' ' || t[b] == '\t')) ++b;
  t = t.substr(b);
  std::string lower;
  for (char ch : t) lower += (ch >= 'A' && ch <= 'Z') ? static_cast<char>(ch - 'A' + 'a') : ch;
  if (nan_ok && (lower.empty() || lower == "nan" || lower == "-nan" || lower == "+nan")) return std::nan("");
  double v = 0;
  std::size_t used = 0;
  try {
    v = std::stod(t, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (t.empty() || used != t.size() || !std::isfinite(v)) {
    // Shown escaped and shortened: a 50 MB field was echoed whole (issue 23 item 12).
    throw std::runtime_error(where + ": " + name + " \"" + escape_for_log(text, 40) + "\" is not a finite number" +
                             (nan_ok ? ", nan or empty" : ""));
  }
  return v;
}

// The screen the gaze pixels are on, from the command line's RATE_HZ and screen arguments; throws
// when the rate or the geometry is out of range.
DisplayGeometry checked_classify_screen(double rate_hz, std::uint32_t w_px, std::uint32_t h_px, double w_mm,
                                        double h_mm, double dist_mm) {
  if (!std::isfinite(rate_hz) || rate_hz <= 0 || rate_hz > 100000) {
    throw std::runtime_error("RATE_HZ " + std::to_string(rate_hz) + " is out of range (0, 100000]");
  }
  DisplayGeometry g;
  g.width_px = w_px;
  g.height_px = h_px;
  g.width_m = w_mm / 1000.0;
  g.height_m = h_mm / 1000.0;
  g.viewing_distance_m = dist_mm / 1000.0;
  if (const std::string err = validate(g); !err.empty()) throw std::runtime_error("screen geometry: " + err);
  return g;
}

// The comma-separated fields of one row (no quoting: the classify input holds numbers only).
std::vector<std::string> split_classify_row(const std::string& line) {
  std::vector<std::string> f;
  std::size_t start = 0;
  for (std::size_t comma; (comma = line.find(',', start)) != std::string::npos; start = comma + 1) {
    f.push_back(line.substr(start, comma - start));
  }
  f.push_back(line.substr(start));
  return f;
}

// The classify input: one sample per data row, and its t_ms exactly as written (echoed to OUT), or
// as numbered where --renumber replaced a missing or broken one.
struct ClassifyInput {
  std::vector<fovea::trackerd::classify::Sample> samples;
  std::vector<std::string> times;
  std::size_t renumbered = 0;
  std::size_t lost_nan = 0;  // rows whose x_px or y_px is nan or empty
  std::size_t lost_at = 0;   // rows at the --lost-at point
};

// --lost-at: the point an export writes for a lost sample (often 0,0); `set` false: none given.
struct LostPoint {
  bool set = false;
  double x_px = 0, y_px = 0;
};

// Parses --lost-at's "X,Y" (two finite numbers); throws naming the option.
LostPoint parse_lost_point(const std::string& text) {
  const std::vector<std::string> f = split_classify_row(text);
  if (f.size() != 2) {
    throw std::runtime_error("--lost-at \"" + escape_for_log(text, 40) + "\": expected X,Y (two numbers, e.g. 0,0)");
  }
  return {true, classify_field(f[0], "X", false, "--lost-at"), classify_field(f[1], "Y", false, "--lost-at")};
}

// Real exports hold NaN, empty or zero timestamps, or times that reset: with --renumber such a row
// (a time that is empty, not a finite number, or not after the previous row's) is numbered one sample
// period after the previous row, at RATE_HZ. Returns the time to use, and whether it was renumbered.
std::pair<double, bool> classify_time(const std::string& field, bool first, double last_t, double period_ms) {
  double t = std::nan("");
  try {
    t = classify_field(field, "t_ms", true, "");
  } catch (const std::runtime_error&) {
    // not a number: numbered like a NaN
  }
  if (std::isfinite(t) && (first || t > last_t)) return {t, false};
  return {first ? 0.0 : last_t + period_ms, true};
}

std::string format_ms(double t) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.6f", t);
  std::string s = buf;
  while (s.back() == '0') s.pop_back();  // 12.500000 -> 12.5, 12.000000 -> 12
  if (s.back() == '.') s.pop_back();
  return s;
}

// One gaze point in degrees from the screen centre, or invalid where x or y is nan.
fovea::trackerd::classify::Sample classify_sample(const DisplayGeometry& g, double t_ms, double x_px, double y_px) {
  fovea::trackerd::classify::Sample s;
  s.t_s = t_ms / 1000.0;
  s.valid = std::isfinite(x_px) && std::isfinite(y_px);
  if (s.valid) {
    // Pixels (origin top-left) to normalized, then to degrees from the centre: atan(offset / d).
    const Degrees d = normalized_to_degrees(
        g, Normalized{x_px / static_cast<double>(g.width_px), y_px / static_cast<double>(g.height_px)});
    s.x_deg = d.x;
    s.y_deg = d.y;
  }
  return s;
}

// Reads the CSV t_ms,x_px,y_px (trackerd/CLASSIFY.md), naming the file and line of the first bad row.
// renumber_hz > 0: rows without a usable time are numbered at that rate (classify_time), and the
// header may be x_px,y_px (no time column: every row numbered). A row at `lost_at` is lost.
ClassifyInput read_classify_input(const std::string& in_path, const DisplayGeometry& g, double renumber_hz,
                                  const LostPoint& lost_at) {
  std::ifstream in(in_path);
  if (!in) throw std::runtime_error("cannot open " + in_path);
  ClassifyInput input;
  auto& [samples, times, renumbered, lost_nan, lost_at_count] = input;
  std::string line;
  std::size_t line_no = 0;
  double last_t = 0;
  bool time_column = true;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const std::string where = in_path + ":" + std::to_string(line_no);
    if (line_no == 1) {
      if (line.size() >= 3 && line.compare(0, 3, "\xEF\xBB\xBF") == 0) line.erase(0, 3);  // UTF-8 BOM
      time_column = line != "x_px,y_px" || renumber_hz <= 0;
      if (line != "t_ms,x_px,y_px" && time_column) {
        throw std::runtime_error(where + ": header is \"" + escape_for_log(line, 40) +
                                 "\", expected \"t_ms,x_px,y_px\" (or \"x_px,y_px\" with --renumber)");
      }
      continue;
    }
    if (line.empty()) throw std::runtime_error(where + ": empty line (expected t_ms,x_px,y_px)");
    std::vector<std::string> f = split_classify_row(line);
    if (!time_column) f.insert(f.begin(), "");
    if (f.size() != 3) {
      throw std::runtime_error(where + ": " + std::to_string(f.size() - (time_column ? 0 : 1)) + " fields, expected " +
                               (time_column ? "3 (t_ms,x_px,y_px)" : "2 (x_px,y_px)"));
    }
    double t_ms = 0;
    if (renumber_hz > 0) {
      const auto [t, replaced] = classify_time(f[0], samples.empty(), last_t, 1000.0 / renumber_hz);
      t_ms = t;
      if (replaced) {
        ++renumbered;
        f[0] = format_ms(t);
      }
    } else {
      try {
        t_ms = classify_field(f[0], "t_ms", false, where);
      } catch (const std::runtime_error& e) {
        throw std::runtime_error(std::string(e.what()) + " (--renumber numbers such rows at RATE_HZ)");
      }
    }
    double x_px = classify_field(f[1], "x_px", true, where);
    double y_px = classify_field(f[2], "y_px", true, where);
    if (std::isnan(x_px) || std::isnan(y_px)) {
      ++lost_nan;
    } else if (lost_at.set && x_px == lost_at.x_px && y_px == lost_at.y_px) {
      ++lost_at_count;
      x_px = y_px = std::nan("");
    }
    if (!samples.empty() && !(t_ms > last_t)) {
      throw std::runtime_error(where + ": t_ms " + f[0] + " is not after the previous row's " + times.back() +
                               " (times must strictly increase; --renumber numbers such rows at RATE_HZ)");
    }
    last_t = t_ms;
    samples.push_back(classify_sample(g, t_ms, x_px, y_px));
    times.push_back(f[0]);
  }
  if (in.bad()) throw std::runtime_error("error reading " + in_path);
  if (line_no == 0) throw std::runtime_error(in_path + ": empty file (expected the header t_ms,x_px,y_px)");
  return input;
}

struct ClassifyArgs {
  std::string in_path, out_path, method = fovea::trackerd::classify::classifiers().front().name;
  double rate_hz = 0, w_mm = 0, h_mm = 0, dist_mm = 0;
  std::uint32_t w_px = 0, h_px = 0;
  std::optional<std::string> lost_at;  // --lost-at X,Y
  bool force = false, renumber = false, final_times = false, provisional = false;
  std::string model_path;    // --model (gbt)
  bool trees_only = false;   // --trees-only (gbt)
  bool offline = false;      // --offline
  std::string pso = "separate";  // --pso (gbt)
  double pursuit_weight = 0;     // --pursuit-weight (gbt; 0: the model's)
  std::optional<double> pursuit_hold_ms;  // --pursuit-hold (gbt; 0: none; unset: the model's)
  double pursuit_hold_ratio = 0.3;
  double pursuit_hold_min_ms = 20;
  std::string features_out;  // --features-out F.npy (and F.npy.names)
  double features_reach_s = fovea::trackerd::classify::kFeatureReachS;  // --features-reach S
  std::string context_out;   // --context-out F.npy (and F.npy.names)
};

// A matrix of float32 rows as a NumPy .npy file and its column names, one per line, in PATH.names:
// what bench/train_classifier.py trains on. Written beside and renamed: PATH is whole or absent.
void write_npy(const std::string& path, const std::vector<float>& m, const std::vector<std::string>& names) {
  const std::size_t rows = names.empty() ? 0 : m.size() / names.size();
  std::string header = "{'descr': '<f4', 'fortran_order': False, 'shape': (" + std::to_string(rows) + ", " +
                       std::to_string(names.size()) + "), }";
  header.append(63 - (10 + header.size()) % 64, ' ');  // the magic, version and length are 10 bytes
  header += '\n';
  const std::string tmp = path + ".partial-" + std::to_string(getpid());
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    const char magic[] = {'\x93', 'N', 'U', 'M', 'P', 'Y', 1, 0};
    const std::uint16_t len = static_cast<std::uint16_t>(header.size());
    const char len_le[] = {static_cast<char>(len & 0xff), static_cast<char>(len >> 8)};
    out.write(magic, sizeof magic).write(len_le, 2) << header;
    static_assert(std::endian::native == std::endian::little, "the .npy is written as '<f4'");
    out.write(reinterpret_cast<const char*>(m.data()), static_cast<std::streamsize>(m.size() * sizeof(float)));
    std::ofstream names_out(path + ".names", std::ios::trunc);
    for (const std::string& n : names) names_out << n << '\n';
    if (!out.flush() || !names_out.flush()) throw std::runtime_error(path + ": write failed");
  }
  std::filesystem::rename(tmp, path);
}

// --features-out and --context-out: the gbt method's first-stage features of every input row (with
// --features-reach ahead), and the second stage's (with the whole reach, from the first stage of the
// model's online chain, or with --offline of its offline chain).
void write_feature_files(const ClassifyArgs& a, const std::vector<fovea::trackerd::classify::Sample>& samples,
                         const DisplayGeometry& display) {
  namespace cl = fovea::trackerd::classify;
  if (!a.features_out.empty()) {
    write_npy(a.features_out, cl::feature_matrix(samples, display, a.features_reach_s), cl::feature_names());
  }
  if (!a.context_out.empty()) {
    const auto model = a.model_path.empty() ? cl::builtin_gbt_model() : cl::load_gbt_model(a.model_path);
    write_npy(a.context_out, cl::context_matrix(samples, display, model, a.offline),
              cl::context_feature_names(model->frame().trees().class_names()));
  }
}

// "saccade_start@T;..." for the provisional events a row made known (T: the event's time, ms).
std::string provisional_cell(const std::vector<fovea::trackerd::classify::ProvisionalEvent>& events) {
  namespace cl = fovea::trackerd::classify;
  std::string cell;
  for (const auto& e : events) {
    if (!cell.empty()) cell += ';';
    cell += std::string(cl::to_string(e.kind)) + (e.phase == cl::Phase::Start ? "_start@" : "_end@") + format_ms(e.t_s * 1000.0);
  }
  return cell;
}

// Writes t_ms,label, one row per input row, to `tmp` (with --final-times a column final_ms: when the
// label became final; with --provisional a column provisional: the provisional events that row made
// known); returns how many samples got each label, and fills `provisional` with those events.
std::map<std::string, std::size_t> write_classify_labels(const std::string& tmp, const ClassifyInput& input,
                                                         const fovea::trackerd::classify::OnlineLabels& result,
                                                         const ClassifyArgs& a,
                                                         std::vector<fovea::trackerd::classify::ProvisionalEvent>& provisional) {
  namespace cl = fovea::trackerd::classify;
  std::map<std::string, std::size_t> counts;
  std::ofstream out(tmp);
  if (!out) throw std::runtime_error("cannot create " + tmp);
  out << "t_ms,label" << (a.final_times ? ",final_ms" : "") << (a.provisional ? ",provisional" : "") << '\n';
  cl::ProvisionalDetector detector;
  std::vector<cl::ProvisionalEvent> row_events;
  for (std::size_t i = 0; i < input.samples.size(); ++i) {
    const char* label = cl::to_string(result.labels[i]);
    out << input.times[i] << ',' << label;
    if (a.final_times) out << ',' << format_ms(result.final_t_s[i] * 1000.0);
    if (a.provisional) {
      row_events.clear();
      detector.push(input.samples[i], row_events);
      out << ',' << provisional_cell(row_events);
      provisional.insert(provisional.end(), row_events.begin(), row_events.end());
    }
    out << '\n';
    ++counts[label];
  }
  out.close();
  if (!out) throw std::runtime_error("cannot write " + tmp);
  return counts;
}

int cmd_classify(const ClassifyArgs& a) {
  namespace cl = fovea::trackerd::classify;
  const std::string tmp = a.out_path + ".partial-" + std::to_string(getpid());
  try {
    if (!a.force && std::filesystem::exists(a.out_path)) {
      throw std::runtime_error(a.out_path + " already exists (use --force to replace it)");
    }
    const DisplayGeometry g = checked_classify_screen(a.rate_hz, a.w_px, a.h_px, a.w_mm, a.h_mm, a.dist_mm);
    const LostPoint lost_at = a.lost_at ? parse_lost_point(*a.lost_at) : LostPoint{};
    const ClassifyInput input = read_classify_input(a.in_path, g, a.renumber ? a.rate_hz : 0, lost_at);

    cl::ClassifierOptions options;
    options.nominal_rate_hz = a.rate_hz;
    options.display = g;
    options.model_path = a.model_path;
    options.trees_only = a.trees_only;
    options.offline = a.offline;
    options.pso = cl::pso_convention(a.pso).value_or(cl::PsoConvention::Separate);  // CLI checked the name
    options.pursuit_weight = a.pursuit_weight;
    if (a.pursuit_hold_ms) {
      options.pursuit_hold = cl::PursuitHold{*a.pursuit_hold_ms / 1000, a.pursuit_hold_ratio, a.pursuit_hold_min_ms / 1000};
    }
    const cl::OnlineLabels result = cl::classify_online(a.method, options, input.samples);
    write_feature_files(a, input.samples, g);

    std::vector<cl::ProvisionalEvent> provisional;
    const std::map<std::string, std::size_t> counts = write_classify_labels(tmp, input, result, a, provisional);
    std::filesystem::rename(tmp, a.out_path);  // atomic: OUT is either absent/old or complete
    std::fprintf(stderr, "fovea-ctl classify: %zu samples, method %s (online latency %.0f ms):", input.samples.size(),
                 a.method.c_str(), cl::make_classifier(a.method, options)->latency_s() * 1000);
    for (const auto& [k, n] : counts) std::fprintf(stderr, " %zu %s", n, k.c_str());
    if (input.lost_nan > 0 || lost_at.set) {
      std::fprintf(stderr, "\nfovea-ctl classify: %zu rows without a gaze point (x_px or y_px nan or empty)", input.lost_nan);
      if (lost_at.set) std::fprintf(stderr, " and %zu at the --lost-at point %s", input.lost_at, a.lost_at->c_str());
    }
    if (a.renumber) {
      std::fprintf(stderr, "\nfovea-ctl classify: renumbered %zu of %zu rows at %g Hz (missing or broken t_ms)",
                   input.renumbered, input.samples.size(), a.rate_hz);
    }
    if (a.provisional) {
      const cl::ProvisionalAgreement agree = cl::provisional_agreement(provisional, result.labels, input.samples);
      std::fprintf(stderr, "\nfovea-ctl classify: %llu provisional events, %llu confirmed and %llu retracted by the final labels",
                   static_cast<unsigned long long>(agree.emitted), static_cast<unsigned long long>(agree.confirmed),
                   static_cast<unsigned long long>(agree.retracted));
    }
    std::fprintf(stderr, "\nfovea-ctl classify: wrote %s\n", a.out_path.c_str());
    return 0;
  } catch (const std::exception& e) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    std::fprintf(stderr, "fovea-ctl classify: %s\n", e.what());
    return 1;
  }
}

// classify's options for the gbt method: its model, chains, smoothing and training outputs.
void add_gbt_options(CLI::App& sub, ClassifyArgs& cls) {
  auto* classify = &sub;
  classify->add_option("--model", cls.model_path,
                       "gbt: a tree model written by bench/train_classifier.py instead of the built-in one")
      ->check(CLI::ExistingFile);
  classify->add_flag("--trees-only", cls.trees_only,
                     "gbt: each sample's own label from the model's last stage, neither smoothed nor with ivvt's "
                     "PSO (what bench/train_classifier.py compares with scikit-learn)");
  classify->add_flag("--offline", cls.offline,
                     "label for analysis: gbt uses its offline chain, whose features look 256 ms and whose second "
                     "stage 512 ms ahead of each sample instead of the daemon's 64 and 32 ms (other methods "
                     "label the same either way)");
  classify->add_option("--pso", cls.pso,
                       "gbt: separate: the saccade ends where the trees end it (as GazeCom's coders, whom they "
                       "learned from), the post-saccadic oscillation after it is labelled pso, and the small "
                       "saccades the trees leave in fixations are labelled saccade, both by ivvt's rule beside the "
                       "trees; onset: the pso from the oscillation's onset, cutting the saccade short there (as the "
                       "EyeLink and Lund coders end saccades); none: the trees alone, no pso label, the oscillation "
                       "in the saccade or fixation and most saccades under 1 degree in the fixation, as GazeCom's "
                       "coders put them (cheaper; final as soon as the trees' labels, as with the others)")
      ->check(CLI::IsMember({"separate", "onset", "none"}))
      ->capture_default_str();
  classify->add_option("--pursuit-weight", cls.pursuit_weight,
                       "W: gbt: weigh pursuit's smoothed probability by W when choosing among the classes but "
                       "the saccade, instead of the model's own weight (the built-in model's: 1); above it "
                       "pursuit is called sooner and more often, below less")
      ->check(CLI::Range(0.01, 100.0));
  auto* hold = classify->add_option(
      "--pursuit-hold", cls.pursuit_hold_ms,
      "MS: gbt: a smoothed fixation whose pursuit comes within --pursuit-hold-ratio of it waits up to MS for a "
      "pursuit of --pursuit-hold-min to follow through such fixations alone, and is then that pursuit's start "
      "(onsets the smoothing calls late move back; only those labels wait longer), instead of the model's own "
      "hold; 0: none")
      ->check(CLI::Range(0.0, 1000.0));
  classify->add_option("--pursuit-hold-ratio", cls.pursuit_hold_ratio,
                       "R: with --pursuit-hold: a fixation is doubtful where pursuit's weighted smoothed "
                       "probability is at least R times fixation's")
      ->check(CLI::Range(0.01, 1.0))
      ->needs(hold)
      ->capture_default_str();
  classify->add_option("--pursuit-hold-min", cls.pursuit_hold_min_ms,
                       "MS: with --pursuit-hold: how long the pursuit after a held fixation must last")
      ->check(CLI::Range(0.0, 1000.0))
      ->needs(hold)
      ->capture_default_str();
  classify->add_option("--features-out", cls.features_out,
                       "F.npy: also write the gbt method's features of every row (float32 rows x features, NaN "
                       "where a scale's window leaves the gaze run) and their names to F.npy.names, for training");
  classify->add_option("--features-reach", cls.features_reach_s,
                       "S: --features-out's features look at most S seconds ahead of each row, as a first stage "
                       "trained for a shorter latency computes them (a window longer than S ends S ahead)")
      ->check(CLI::Range(0.001, fovea::trackerd::classify::kFeatureReachS))
      ->capture_default_str();
  classify->add_option("--context-out", cls.context_out,
                       "F.npy: also write the gbt method's second-stage features of every row (the first stage's "
                       "probabilities up to 512 ms around it, from the first stage of --model's or the built-in "
                       "model's online chain, or with --offline its offline chain) and their names to F.npy.names, "
                       "for training");

}

// classify: offline eye-movement classification (trackerd/CLASSIFY.md)
CLI::App* add_classify_command(CLI::App& app, ClassifyArgs& cls) {
  auto* classify = app.add_subcommand("classify", "label every gaze sample of a CSV (t_ms,x_px,y_px) as fixation, "
                                                  "saccade, pso, pursuit, blink, lost or unknown");
  classify->add_option("IN", cls.in_path, "input CSV with header t_ms,x_px,y_px (nan or an empty x_px/y_px marks a lost sample)")
      ->required()
      ->check(CLI::ExistingFile);
  classify->add_option("OUT", cls.out_path, "output CSV t_ms,label, one row per input row (refuses to overwrite)")
      ->required();
  classify->add_option("RATE_HZ", cls.rate_hz, "nominal sample rate, Hz")->required();
  classify->add_option("SCREEN_W_PX", cls.w_px, "screen width, pixels")->required();
  classify->add_option("SCREEN_H_PX", cls.h_px, "screen height, pixels")->required();
  classify->add_option("SCREEN_W_MM", cls.w_mm, "screen width, millimetres")->required();
  classify->add_option("SCREEN_H_MM", cls.h_mm, "screen height, millimetres")->required();
  classify->add_option("DIST_MM", cls.dist_mm, "eye-to-screen distance, millimetres")->required();
  {
    std::vector<std::string> names;
    std::string help = "classification method:";
    for (const auto& m : fovea::trackerd::classify::classifiers()) {
      names.push_back(m.name);
      help += "\n  " + m.name + (names.size() == 1 ? " (default)" : "") + ": " + m.summary;
    }
    classify->add_option("--method", cls.method, help)->check(CLI::IsMember(names))->capture_default_str();
  }
  classify->add_flag("--force", cls.force, "replace OUT if it exists");
  classify->add_flag("--renumber", cls.renumber,
                     "number rows at RATE_HZ where t_ms is missing, not a number or not after the previous row's "
                     "(real exports hold NaN, zero or reset timestamps), and accept a header x_px,y_px without "
                     "times; OUT shows the numbered times, and the count is reported");
  classify->add_option("--lost-at", cls.lost_at,
                       "X,Y: rows at exactly this point are lost samples too (many exports write a fixed point, often "
                       "0,0, for them); the count is reported");
  classify->add_flag("--final-times", cls.final_times,
                     "add a column final_ms: the t_ms of the newest row pushed when the label became final (the "
                     "classifier runs online, one row at a time, as in the daemon): final_ms - t_ms is its latency");
  classify->add_flag("--provisional", cls.provisional,
                     "add a column provisional: the provisional events (saccade start/end, fixation start, as the "
                     "daemon sends them before the final labels) each row made known, as KIND_PHASE@T_MS joined "
                     "by ';'; reports how many the final labels confirmed and retracted");
  add_gbt_options(*classify, cls);

  return classify;
}

}  // namespace

std::vector<Command> add_recording_commands(CLI::App& app) {
  struct Options {
    ConvertArgs cv;
    std::string info_path;
    ClassifyArgs cls;
  };
  auto o = std::make_shared<Options>();
  auto& [cv, info_path, cls] = *o;
  auto* convert = app.add_subcommand("convert", "convert between .fgr and .csv (also repairs damaged .fgr files), or "
                                                "export a recording to a BIDS dataset (--format bids)");
  convert->add_option("IN", cv.in_path, "input .fgr or .csv")->required()->check(CLI::ExistingFile);
  convert->add_option("OUT", cv.out_path, "output .fgr or .csv; with --format bids the BIDS dataset directory")->required();
  convert->add_flag("--force", cv.force, "replace OUT if it exists (not with --format bids)");
  convert->add_option("--format", cv.format,
                      "auto (by OUT's extension: .fgr or .csv), fgr, csv, or bids: OUT is a BIDS dataset directory "
                      "(eye-tracking physio + physioevents, BIDS 1.10; never replaces a file)")
      ->check(CLI::IsMember({"auto", "fgr", "csv", "bids"}))
      ->capture_default_str();
  convert->add_option("--subject", cv.bids.subject, "--format bids: the sub-<label> (letters and digits)");
  convert->add_option("--task", cv.bids.task, "--format bids: the task-<label>");
  convert->add_option("--session", cv.bids.session, "--format bids: the ses-<label> (default: none)");
  convert->add_option("--run", cv.bids.run, "--format bids: the run-<index> (digits; default: none)");
  convert->add_option("--recording", cv.bids.recording, "--format bids: the recording-<label>")->capture_default_str();

  auto* info = app.add_subcommand("info", "describe a recording: display, rate, span, events, integrity");
  info->add_option("FILE", info_path, ".fgr or .csv file")->required()->check(CLI::ExistingFile);

  CLI::App* classify = add_classify_command(app, cls);

  return {
      {convert, [o] { return cmd_convert_any(o->cv); }},
      {info, [o] { return cmd_info(o->info_path); }},
      {classify,
       [o] { return cmd_classify(o->cls); }},
  };
}

}  // namespace fovea::ctl
