// SPDX-License-Identifier: Apache-2.0
// BIDS export of a gaze recording; see bids_export.h and protocol/RECORDING.md ("BIDS export").
#include "ctl/bids_export.h"

#include <fcntl.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <variant>

namespace fovea::ctl {
namespace {

using namespace fovea::protocol;
using Json = nlohmann::ordered_json;
namespace fs = std::filesystem;

// Record-clock nanoseconds as exact decimal seconds (9 decimals): no binary rounding.
std::string seconds(std::int64_t ns) {
  const bool negative = ns < 0;
  // Magnitude without overflow for INT64_MIN.
  const std::uint64_t mag = negative ? std::uint64_t{0} - static_cast<std::uint64_t>(ns) : static_cast<std::uint64_t>(ns);
  char buf[48];
  std::snprintf(buf, sizeof buf, "%s%llu.%09llu", negative ? "-" : "", static_cast<unsigned long long>(mag / 1000000000u),
                static_cast<unsigned long long>(mag % 1000000000u));
  return buf;
}

std::string fixed(double v, int decimals) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

// UTC date-time as BIDS writes it: YYYY-MM-DDThh:mm:ss.ffffffZ.
std::string iso8601_utc(std::int64_t unix_ns) {
  std::int64_t secs = unix_ns / 1000000000;
  std::int64_t frac_ns = unix_ns % 1000000000;
  if (frac_ns < 0) {
    frac_ns += 1000000000;
    --secs;
  }
  const std::time_t t = static_cast<std::time_t>(secs);
  std::tm tm{};
  if (gmtime_r(&t, &tm) == nullptr) return "n/a";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%04d-%02d-%02dT%02d:%02d:%02d.%06lldZ", tm.tm_year + 1900, tm.tm_mon + 1, tm.tm_mday,
                tm.tm_hour, tm.tm_min, tm.tm_sec, static_cast<long long>(frac_ns / 1000));
  return buf;
}

struct Names {
  std::string subject_dir;  // sub-X[/ses-Y], relative to the root
  std::string prefix;       // sub-X[_ses-Y]
  std::string task_stem;    // prefix_task-T[_run-N]
  std::string stem;         // task_stem_recording-R (physio files)
};

Names names_for(const BidsOptions& o) {
  Names n;
  n.subject_dir = "sub-" + o.subject;
  n.prefix = "sub-" + o.subject;
  if (!o.session.empty()) {
    n.subject_dir += "/ses-" + o.session;
    n.prefix += "_ses-" + o.session;
  }
  n.task_stem = n.prefix + "_task-" + o.task;
  if (!o.run.empty()) n.task_stem += "_run-" + o.run;
  n.stem = n.task_stem + "_recording-" + o.recording;
  return n;
}

void check_options(const BidsOptions& o) {
  for (const auto& [what, label] : {std::pair<const char*, const std::string*>{"--subject", &o.subject},
                                    {"--task", &o.task},
                                    {"--recording", &o.recording}}) {
    if (std::string err = bids_label_error(what, *label); !err.empty()) throw std::runtime_error(err);
  }
  if (!o.session.empty()) {
    if (std::string err = bids_label_error("--session", o.session); !err.empty()) throw std::runtime_error(err);
  }
  if (!o.run.empty() && !std::all_of(o.run.begin(), o.run.end(), [](char c) { return c >= '0' && c <= '9'; })) {
    throw std::runtime_error("--run \"" + o.run + "\" is not a BIDS index (digits only, for example 1 or 02)");
  }
  if (o.dataset_dir.empty()) throw std::runtime_error("no output directory given");
}

// Which eye-tracking clock the record times are on, for the timestamp column's Origin.
std::string clock_origin(RecordingClock c) {
  return c == RecordingClock::Realtime ? "Unix epoch (CLOCK_REALTIME of the recording host)"
                                       : "boot of the recording host (its CLOCK_MONOTONIC)";
}

struct Tables {
  std::string physio, physioevents, events;
  std::vector<std::string> columns;
};

bool any_pupil(const std::vector<const GazeSample*>& samples, bool left) {
  return std::any_of(samples.begin(), samples.end(), [left](const GazeSample* s) {
    return ((left ? s->left : s->right).flags & kEyePupilValid) != 0;
  });
}

std::string pupil_cell(const EyeData& e) {
  return (e.flags & kEyePupilValid) != 0 ? fixed(static_cast<double>(e.pupil_diameter_mm), 4) : "n/a";
}

struct EventRow {
  std::int64_t onset_ns;
  std::string duration, trial_type, message;
};

Json stimulus_presentation(const DisplayGeometry& g) {
  Json sp;
  sp["ScreenDistance"] = g.viewing_distance_m;
  sp["ScreenOrigin"] = Json::array({"top", "left"});
  sp["ScreenResolution"] = Json::array({g.width_px, g.height_px});
  sp["ScreenSize"] = Json::array({g.width_m, g.height_m});
  return sp;
}

Json column(const std::string& long_name, const std::string& description, const char* units) {
  Json c;
  c["LongName"] = long_name;
  c["Description"] = description;
  if (units != nullptr) c["Units"] = units;
  return c;
}

// The physio sidecar: the REQUIRED SamplingFrequency, StartTime, Columns (Continuous), PhysioType
// (eyetrack), RecordedEye, SampleCoordinateSystem, and Units of x_coordinate and y_coordinate.
Json physio_sidecar(const Recording& rec, const Tables& t, double rate, bool measured) {
  const RecordingHeader& h = rec.header;
  Json j;
  j["SamplingFrequency"] = rate;
  j["StartTime"] = 0;
  j["Columns"] = t.columns;
  j["PhysioType"] = "eyetrack";
  j["RecordedEye"] = "cyclopean";
  j["SampleCoordinateSystem"] = "gaze-on-screen";
  j["Manufacturer"] = "fovea";
  j["ManufacturersModelName"] = h.device.empty() ? "unknown" : h.device;
  j["StimulusPresentation"] = stimulus_presentation(h.display);
  std::string desc = "Gaze of a fovea recording (.fgr): one row per GAZE_SAMPLE record, in file order; the gaze point "
                     "combines both eyes (cyclopean). Rows with gaze_valid 0 have n/a coordinates.";
  if (measured) desc += " The recording had no nominal rate; SamplingFrequency was measured from the sample times.";
  if (!rec.report.header_valid) desc += " The recording's header was damaged: the screen geometry is fovea's default.";
  j["Description"] = desc;
  for (const std::string& c : t.columns) {
    if (c == "timestamp") {
      Json col = column("Sample time", "The sample's time on the recording clock (tracker time mapped to the host clock).", "s");
      col["Origin"] = clock_origin(h.clock);
      j[c] = col;
    } else if (c == "x_coordinate") {
      j[c] = column("Gaze position (x)", "Horizontal gaze position on the screen, pixels from the left edge (may lie off screen).", "pixel");
    } else if (c == "y_coordinate") {
      j[c] = column("Gaze position (y)", "Vertical gaze position on the screen, pixels from the top edge, down positive.", "pixel");
    } else if (c == "x_deg") {
      j[c] = column("Gaze angle (x)", "Visual angle from the screen centre, right positive.", "deg");
    } else if (c == "y_deg") {
      j[c] = column("Gaze angle (y)", "Visual angle from the screen centre, down positive.", "deg");
    } else if (c == "left_pupil_diameter" || c == "right_pupil_diameter") {
      j[c] = column(c == "left_pupil_diameter" ? "Left pupil diameter" : "Right pupil diameter",
                    "Pupil diameter; n/a where the tracker did not find the pupil.", "mm");
    } else if (c == "confidence") {
      j[c] = column("Confidence", "The tracker's confidence in the gaze point, 0 to 1.", nullptr);
    } else if (c == "gaze_valid") {
      Json col = column("Gaze valid", "Whether the sample carries a gaze point.", nullptr);
      col["Levels"] = Json{{"0", "no gaze (coordinates n/a)"}, {"1", "valid gaze"}};
      j[c] = col;
    }
  }
  return j;
}

Json physioevents_sidecar() {
  Json j;
  j["Columns"] = Json::array({"onset", "duration", "trial_type", "message"});
  j["Description"] = "Eye-movement events classified by fovea-trackerd (final events; provisional ones are not recorded) "
                     "and experimenter markers (MARKER records) as messages.";
  j["OnsetSource"] = "timestamp";
  j["onset"] = Json{{"Description", "Event start, on the clock of the physio file's timestamp column."}, {"Units", "s"}};
  j["duration"] = Json{{"Description", "Event duration; n/a for messages."}, {"Units", "s"}};
  j["trial_type"] = Json{{"Description", "Eye-movement class of the event; n/a for messages."},
                         {"Levels", Json{{"fixation", "a fixation"},
                                         {"saccade", "a saccade"},
                                         {"pursuit", "a smooth pursuit"},
                                         {"blink", "a blink (gaze lost with the eye closed)"},
                                         {"unknown", "an event the classifier could not name"}}}};
  j["message"] = Json{{"Description", "A marker's label (an experimenter's event sent to fovea-trackerd); n/a for eye-movement events."}};
  return j;
}

Json events_sidecar(const DisplayGeometry& g) {
  Json j;
  j["StimulusPresentation"] = stimulus_presentation(g);
  j["onset"] = Json{{"Description", "Seconds from the first gaze sample of the physio recording."}, {"Units", "s"}};
  j["duration"] = Json{{"Description", "Markers are instants: 0."}, {"Units", "s"}};
  j["trial_type"] = Json{{"Description", "The marker's label, as the experiment sent it (fovea-ctl mark, the SDKs)."}};
  return j;
}

Json dataset_description(const std::string& version) {
  Json j;
  j["Name"] = "fovea gaze recordings";
  j["BIDSVersion"] = kBidsVersion;
  j["DatasetType"] = "raw";
  j["GeneratedBy"] = Json::array({Json{{"Name", "fovea-ctl convert --format bids"}, {"Version", version}}});
  return j;
}

// One physio.tsv row: the columns build_tables names, n/a where the gaze is invalid.
std::string physio_row(const GazeSample& s, double w, double h, bool left, bool right) {
  const bool valid = (s.flags & kGazeValid) != 0;
  std::string row = seconds(s.tracker_time_ns);
  row += '\t';
  row += valid ? fixed(static_cast<double>(s.x) * w, 4) : "n/a";
  row += '\t';
  row += valid ? fixed(static_cast<double>(s.y) * h, 4) : "n/a";
  row += '\t';
  row += valid ? fixed(static_cast<double>(s.x_deg), 5) : "n/a";
  row += '\t';
  row += valid ? fixed(static_cast<double>(s.y_deg), 5) : "n/a";
  if (left) row += '\t' + pupil_cell(s.left);
  if (right) row += '\t' + pupil_cell(s.right);
  row += '\t' + fixed(static_cast<double>(s.confidence), 4);
  row += valid ? "\t1\n" : "\t0\n";
  return row;
}

Tables build_tables(const Recording& rec, BidsResult& res) {
  const DisplayGeometry& g = rec.header.display;
  std::vector<const GazeSample*> samples;
  std::vector<EventRow> ev;
  std::vector<EventRow> markers;
  std::size_t starts = 0;
  for (const Record& r : rec.records) {
    if (const auto* s = std::get_if<GazeSample>(&r.item)) {
      samples.push_back(s);
    } else if (const auto* e = std::get_if<GazeEvent>(&r.item)) {
      if (e->provisional()) continue;
      if (e->phase == EventPhase::Start) {
        ++starts;
        continue;
      }
      ev.push_back({e->start_time_ns, seconds(e->duration_ns), to_string(e->kind), "n/a"});
    } else if (const auto* m = std::get_if<Marker>(&r.item)) {
      markers.push_back({m->time_ns, "n/a", "n/a", m->label.value});
    }
  }
  if (samples.empty()) throw std::runtime_error("the recording holds no gaze samples: nothing to export");
  res.samples = samples.size();
  res.events = ev.size();
  res.markers = markers.size();
  res.unfinished_events = starts > ev.size() ? starts - ev.size() : 0;

  Tables t;
  t.columns = {"timestamp", "x_coordinate", "y_coordinate", "x_deg", "y_deg"};
  const bool left = any_pupil(samples, true), right = any_pupil(samples, false);
  if (left) t.columns.push_back("left_pupil_diameter");
  if (right) t.columns.push_back("right_pupil_diameter");
  t.columns.push_back("confidence");
  t.columns.push_back("gaze_valid");
  const double w = static_cast<double>(g.width_px), h = static_cast<double>(g.height_px);
  t.physio.reserve(samples.size() * 80);
  for (const GazeSample* s : samples) {
    if ((s->flags & kGazeValid) != 0) ++res.valid_samples;
    t.physio += physio_row(*s, w, h, left, right);
  }

  // physioevents: eye-movement events and markers together, by onset (stable: file order on ties).
  std::vector<EventRow> all = ev;
  all.insert(all.end(), markers.begin(), markers.end());
  std::stable_sort(all.begin(), all.end(), [](const EventRow& a, const EventRow& b) { return a.onset_ns < b.onset_ns; });
  for (const EventRow& e : all) {
    t.physioevents += seconds(e.onset_ns) + '\t' + e.duration + '\t' + e.trial_type + '\t' + e.message + '\n';
  }

  // events.tsv (task events): the markers, onset from the first sample.
  const std::int64_t t0 = samples.front()->tracker_time_ns;
  std::stable_sort(markers.begin(), markers.end(), [](const EventRow& a, const EventRow& b) { return a.onset_ns < b.onset_ns; });
  t.events = "onset\tduration\ttrial_type\n";
  for (const EventRow& m : markers) t.events += seconds(m.onset_ns - t0) + "\t0\t" + m.message + '\n';

  // Rate: the header's nominal rate, or measured from the sample times when the header has none.
  if (std::isfinite(rec.header.nominal_rate_hz) && rec.header.nominal_rate_hz > 0) {
    res.sampling_frequency = rec.header.nominal_rate_hz;
  } else {
    const std::int64_t span = samples.back()->tracker_time_ns - t0;
    if (samples.size() < 2 || span <= 0) {
      throw std::runtime_error("the recording has no nominal sample rate and too few samples to measure one "
                               "(BIDS requires SamplingFrequency)");
    }
    res.sampling_frequency = std::round(static_cast<double>(samples.size() - 1) / (static_cast<double>(span) / 1e9) * 1000) / 1000;
    res.measured_rate = true;
  }
  return t;
}

// Creates `path` holding `data`, never replacing anything: written beside it under a name of our own,
// then hard-linked into place (link(2) fails if the name exists, even one that appeared meanwhile).
void create_file(const std::string& path, const std::string& data) {
  const std::string tmp = path + ".partial-" + std::to_string(getpid());
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw std::runtime_error("cannot create " + tmp + ": " + std::strerror(errno));
    out.write(data.data(), static_cast<std::streamsize>(data.size()));
    out.close();
    if (!out) {
      std::error_code ignored;
      fs::remove(tmp, ignored);
      throw std::runtime_error("cannot write " + tmp);
    }
  }
  const int rc = ::link(tmp.c_str(), path.c_str());
  const int err = errno;
  ::unlink(tmp.c_str());
  if (rc != 0) {
    if (err == EEXIST) throw std::runtime_error(path + " already exists; BIDS export never replaces a file");
    throw std::runtime_error("cannot create " + path + ": " + std::strerror(err));
  }
}

// Adds the recording's row to the session's scans.tsv (created with the columns filename, acq_time
// where missing). An existing scans.tsv is only appended to, with one write(2): its columns are kept
// (filename and acq_time filled in, any other n/a); one without a filename column is refused.
std::string add_scans_row(const std::string& root, const Names& n, const std::string& physio_rel, const std::string& acq,
                          std::vector<std::string>& created) {
  const std::string path = root + "/" + n.subject_dir + "/" + n.prefix + "_scans.tsv";
  const std::string acq_cell = acq.empty() ? "n/a" : acq;
  if (!fs::exists(path)) {
    create_file(path, "filename\tacq_time\n" + physio_rel + '\t' + acq_cell + '\n');
    created.push_back(path);
    return path;
  }
  std::ifstream in(path, std::ios::binary);
  std::string header;
  std::getline(in, header);
  if (!header.empty() && header.back() == '\r') header.pop_back();
  std::string text;
  bool has_filename = false;
  std::size_t start = 0;
  for (std::size_t tab = 0; start <= header.size(); start = tab + 1) {
    tab = header.find('\t', start);
    if (tab == std::string::npos) tab = header.size();
    const std::string name = header.substr(start, tab - start);
    if (!text.empty()) text += '\t';
    if (name == "filename") has_filename = true;
    text += name == "filename" ? physio_rel : name == "acq_time" ? acq_cell : "n/a";
  }
  if (!has_filename) {
    throw std::runtime_error(path + " exists without a filename column (its header is \"" + header.substr(0, 80) +
                             "\"): not a scans.tsv this export can add to");
  }
  text += '\n';
  in.seekg(0, std::ios::end);
  const auto size = in.tellg();
  if (size > 0) {
    in.seekg(size - std::streamoff{1});
    char last = '\n';
    in.get(last);
    if (last != '\n') text = '\n' + text;
  }
  const int fd = ::open(path.c_str(), O_WRONLY | O_APPEND | O_CLOEXEC);
  if (fd < 0) throw std::runtime_error("cannot append to " + path + ": " + std::strerror(errno));
  const ssize_t w = ::write(fd, text.data(), text.size());
  ::close(fd);
  if (w != static_cast<ssize_t>(text.size())) throw std::runtime_error("cannot append to " + path);
  return path;
}

}  // namespace

std::string bids_label_error(const std::string& what, const std::string& label) {
  if (label.empty()) return what + " is empty (a BIDS label is one or more letters or digits)";
  for (char c : label) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9');
    if (!ok) {
      std::string shown;
      for (char d : label.substr(0, 40)) shown += (d >= 0x20 && d < 0x7f) ? d : '?';
      return what + " \"" + shown + "\" is not a BIDS label: letters and digits only (no '-', '_', spaces or punctuation)";
    }
  }
  return "";
}

std::vector<std::string> bids_output_names(const BidsOptions& o) {
  const Names n = names_for(o);
  const std::string dir = n.subject_dir + "/beh/";
  return {dir + n.stem + "_physio.tsv.gz",       dir + n.stem + "_physio.json",   dir + n.stem + "_physioevents.tsv.gz",
          dir + n.stem + "_physioevents.json",   dir + n.task_stem + "_events.tsv", dir + n.task_stem + "_events.json"};
}

std::string gzip_compress(const std::string& data) {
  z_stream zs{};
  // windowBits 15 + 16: a gzip header and trailer rather than zlib's.
  if (deflateInit2(&zs, 6, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK) {
    throw std::runtime_error("zlib: deflateInit2 failed");
  }
  std::string out(deflateBound(&zs, static_cast<uLong>(data.size())) + 32, '\0');
  zs.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
  zs.avail_in = static_cast<uInt>(data.size());
  zs.next_out = reinterpret_cast<Bytef*>(out.data());
  zs.avail_out = static_cast<uInt>(out.size());
  const int rc = deflate(&zs, Z_FINISH);
  const uLong total = zs.total_out;
  deflateEnd(&zs);
  if (rc != Z_STREAM_END) throw std::runtime_error("zlib: deflate failed (" + std::to_string(rc) + ")");
  out.resize(total);
  return out;
}

BidsResult export_bids(const Recording& rec, const BidsOptions& o) {
  check_options(o);
  BidsResult res;
  const Tables t = build_tables(rec, res);
  const Names n = names_for(o);
  const std::string root = o.dataset_dir;
  const std::vector<std::string> rel = bids_output_names(o);
  for (const std::string& r : rel) {
    const std::string p = root + "/" + r;
    std::error_code ec;
    if (fs::symlink_status(p, ec).type() != fs::file_type::not_found) {
      throw std::runtime_error(p + " already exists; BIDS export never replaces a file (choose another --subject, "
                               "--session, --task, --run or --recording)");
    }
  }
  if (t.physio.size() > std::size_t{UINT32_MAX}) throw std::runtime_error("recording too large for one physio file");

  // The first sample's wall-clock time, from the header's mapping of the record clock.
  std::string acq;
  if (rec.report.header_valid && rec.header.created_unix_ns != 0) {
    std::int64_t first = 0;
    for (const Record& r : rec.records) {
      if (const auto* s = std::get_if<GazeSample>(&r.item)) {
        first = s->tracker_time_ns;
        break;
      }
    }
    acq = iso8601_utc(rec.header.created_unix_ns + (first - rec.header.created_clock_ns));
  }

  const std::vector<std::string> contents = {
      gzip_compress(t.physio),
      physio_sidecar(rec, t, res.sampling_frequency, res.measured_rate).dump(2) + "\n",
      gzip_compress(t.physioevents),
      physioevents_sidecar().dump(2) + "\n",
      t.events,
      events_sidecar(rec.header.display).dump(2) + "\n",
  };

  std::vector<std::string> created;
  try {
    fs::create_directories(root + "/" + n.subject_dir + "/beh");
    const std::string desc = root + "/dataset_description.json";
    if (!fs::exists(desc)) {
      try {
        create_file(desc, dataset_description(o.generator_version).dump(2) + "\n");
        created.push_back(desc);
      } catch (const std::runtime_error&) {
        if (!fs::exists(desc)) throw;  // someone else wrote it meanwhile: theirs stays
      }
    }
    for (std::size_t i = 0; i < rel.size(); ++i) {
      create_file(root + "/" + rel[i], contents[i]);
      created.push_back(root + "/" + rel[i]);
    }
    // scans.tsv names data files relative to the session (or subject) directory.
    res.scans_tsv = add_scans_row(root, n, "beh/" + n.stem + "_physio.tsv.gz", acq, created);
  } catch (...) {
    for (auto it = created.rbegin(); it != created.rend(); ++it) {
      std::error_code ignored;
      fs::remove(*it, ignored);
    }
    throw;
  }
  res.written = created;
  return res;
}

}  // namespace fovea::ctl
