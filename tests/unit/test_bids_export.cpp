// SPDX-License-Identifier: Apache-2.0
// BIDS export of gaze recordings (issue 26 item 6): the files are read back (gunzip, TSV, JSON) and
// checked against the BIDS 1.10 eye-tracking rules and against the recording itself; the export
// refuses to replace files and bad labels, and exports a damaged recording's intact records.
#include <gtest/gtest.h>
#include <unistd.h>
#include <zlib.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <variant>
#include <vector>

#include "ctl/bids_export.h"
#include "fovea/protocol/recording.h"
#include "temp_dir.h"

namespace {

using namespace fovea::protocol;
using namespace fovea::ctl;
namespace fs = std::filesystem;
using Json = nlohmann::json;

const std::string kSynthetic = std::string(FOVEA_TEST_DATA) + "/recordings/synthetic-250hz-62s.fgr";

struct TempDir : fovea::test::TempDir {
  TempDir() : fovea::test::TempDir("fovea-bids") {}
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string gunzip(const fs::path& p) {
  gzFile f = gzopen(p.c_str(), "rb");
  EXPECT_NE(f, nullptr) << p;
  if (f == nullptr) return "";
  std::string out;
  char buf[65536];
  int n = 0;
  while ((n = gzread(f, buf, sizeof buf)) > 0) out.append(buf, static_cast<std::size_t>(n));
  EXPECT_EQ(n, 0) << "gzread failed on " << p;
  gzclose(f);
  return out;
}

std::vector<std::vector<std::string>> tsv_rows(const std::string& text) {
  std::vector<std::vector<std::string>> rows;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::size_t start = 0;
    for (std::size_t tab; (tab = line.find('\t', start)) != std::string::npos; start = tab + 1) {
      cells.push_back(line.substr(start, tab - start));
    }
    cells.push_back(line.substr(start));
    rows.push_back(cells);
  }
  return rows;
}

BidsOptions options(const fs::path& root) {
  BidsOptions o;
  o.dataset_dir = root.string();
  o.subject = "01";
  o.task = "freeview";
  o.session = "a";
  o.generator_version = "test";
  return o;
}

const fs::path kBeh = "sub-01/ses-a/beh";
const std::string kStem = "sub-01_ses-a_task-freeview_recording-eye1";

TEST(BidsExport, WritesTheEyeTrackingFilesWithTheRequiredFields) {
  TempDir d;
  const Recording rec = read_recording(kSynthetic);
  const BidsResult r = export_bids(rec, options(d.path));
  EXPECT_EQ(r.samples, 15500u);
  EXPECT_EQ(r.valid_samples, 15021u);
  EXPECT_EQ(r.events, 342u);
  EXPECT_EQ(r.markers, 0u);

  // dataset_description.json: Name and BIDSVersion are REQUIRED.
  const Json desc = Json::parse(slurp(d.path / "dataset_description.json"));
  EXPECT_TRUE(desc["Name"].is_string());
  EXPECT_EQ(desc["BIDSVersion"], "1.10.0");

  // The physio sidecar: every REQUIRED field, consistent with the recording.
  const Json j = Json::parse(slurp(d.path / kBeh / (kStem + "_physio.json")));
  for (const char* key : {"SamplingFrequency", "StartTime", "Columns", "PhysioType", "RecordedEye", "SampleCoordinateSystem"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  EXPECT_EQ(j["SamplingFrequency"].get<double>(), rec.header.nominal_rate_hz);
  EXPECT_EQ(j["PhysioType"], "eyetrack");
  EXPECT_EQ(j["SampleCoordinateSystem"], "gaze-on-screen");
  EXPECT_EQ(j["StartTime"].get<double>(), 0.0);
  const auto columns = j["Columns"].get<std::vector<std::string>>();
  ASSERT_GE(columns.size(), 3u);
  EXPECT_EQ(columns[0], "timestamp");
  EXPECT_EQ(columns[1], "x_coordinate");
  EXPECT_EQ(columns[2], "y_coordinate");
  EXPECT_EQ(j["x_coordinate"]["Units"], "pixel");  // REQUIRED for the coordinates
  EXPECT_EQ(j["y_coordinate"]["Units"], "pixel");
  EXPECT_EQ(j["timestamp"]["Units"], "s");
  for (const std::string& c : columns) EXPECT_TRUE(j.contains(c)) << "column " << c << " is not described";
  const Json sp = j["StimulusPresentation"];
  EXPECT_EQ(sp["ScreenResolution"], Json::array({1920, 1080}));
  EXPECT_EQ(sp["ScreenSize"][0].get<double>(), rec.header.display.width_m);
  EXPECT_EQ(sp["ScreenDistance"].get<double>(), rec.header.display.viewing_distance_m);

  // The physio data: no header line, one row per sample, Columns' count on every row.
  const auto rows = tsv_rows(gunzip(d.path / kBeh / (kStem + "_physio.tsv.gz")));
  ASSERT_EQ(rows.size(), 15500u);
  std::size_t na = 0;
  double last_t = -1e300;
  for (const auto& row : rows) {
    ASSERT_EQ(row.size(), columns.size());
    const double t = std::stod(row[0]);
    EXPECT_GE(t, last_t);
    last_t = t;
    if (row[1] == "n/a") {
      ++na;
      EXPECT_EQ(row[2], "n/a");
      EXPECT_EQ(row.back(), "0");
    } else {
      const double x = std::stod(row[1]), y = std::stod(row[2]);
      EXPECT_TRUE(x > -5000 && x < 7000 && y > -5000 && y < 6000) << x << "," << y;
    }
  }
  EXPECT_EQ(15500u - na, 15021u);
  // The first sample's time is the record time, exactly.
  for (const Record& rr : rec.records) {
    if (const auto* s = std::get_if<GazeSample>(&rr.item)) {
      EXPECT_EQ(rows[0][0], std::to_string(s->tracker_time_ns / 1000000000) + "." +
                                std::string(9 - std::to_string(s->tracker_time_ns % 1000000000).size(), '0') +
                                std::to_string(s->tracker_time_ns % 1000000000));
      break;
    }
  }

  // physioevents: its REQUIRED Columns and OnsetSource; 342 events on the timestamp clock.
  const Json ej = Json::parse(slurp(d.path / kBeh / (kStem + "_physioevents.json")));
  EXPECT_EQ(ej["OnsetSource"], "timestamp");
  const auto ecols = ej["Columns"].get<std::vector<std::string>>();
  ASSERT_EQ(ecols.size(), 4u);
  EXPECT_EQ(ecols[0], "onset");
  EXPECT_EQ(ecols[1], "duration");
  const auto erows = tsv_rows(gunzip(d.path / kBeh / (kStem + "_physioevents.tsv.gz")));
  ASSERT_EQ(erows.size(), 342u);
  std::map<std::string, std::size_t> kinds;
  for (const auto& row : erows) {
    ASSERT_EQ(row.size(), ecols.size());
    ++kinds[row[2]];
    EXPECT_GE(std::stod(row[0]), std::stod(rows.front()[0]) - 1.0);
    EXPECT_GE(std::stod(row[1]), 0.0);
  }
  EXPECT_EQ(kinds["blink"], 9u);
  EXPECT_EQ(kinds["fixation"], 171u);
  EXPECT_EQ(kinds["pursuit"], 11u);
  EXPECT_EQ(kinds["saccade"], 151u);

  // Task events: a header line and no rows (no markers); the sidecar carries the screen.
  EXPECT_EQ(slurp(d.path / kBeh / "sub-01_ses-a_task-freeview_events.tsv"), "onset\tduration\ttrial_type\n");
  const Json tj = Json::parse(slurp(d.path / kBeh / "sub-01_ses-a_task-freeview_events.json"));
  for (const char* key : {"ScreenDistance", "ScreenOrigin", "ScreenResolution", "ScreenSize"}) {
    EXPECT_TRUE(tj["StimulusPresentation"].contains(key)) << key;
  }

  // scans.tsv: the acquisition time of the first sample, from the header's clock mapping.
  const auto scans = tsv_rows(slurp(d.path / "sub-01/ses-a/sub-01_ses-a_scans.tsv"));
  ASSERT_EQ(scans.size(), 2u);
  EXPECT_EQ(scans[1][0], "beh/" + kStem + "_physio.tsv.gz");
  EXPECT_EQ(scans[1][1].size(), std::string("2026-01-01T00:00:00.000000Z").size()) << scans[1][1];
}

TEST(BidsExport, MarkersBecomeMessagesAndTaskEvents) {
  TempDir d;
  RecordingHeader h;
  h.device = "unit";
  h.nominal_rate_hz = 100;
  Recording rec;
  rec.header = h;
  rec.report.header_valid = true;
  for (int i = 0; i < 10; ++i) {
    GazeSample s;
    s.tracker_time_ns = 5'000'000'000 + i * 10'000'000;
    s.x = 0.5f;
    s.y = 0.5f;
    s.flags = kGazeValid;
    rec.records.emplace_back(static_cast<std::uint64_t>(i), s);
  }
  Marker m;
  m.time_ns = 5'020'000'000;
  m.label.value = "trial 1, \"go\"";
  rec.records.emplace_back(0, m);
  const BidsResult r = export_bids(rec, options(d.path));
  EXPECT_EQ(r.markers, 1u);
  const auto erows = tsv_rows(gunzip(d.path / kBeh / (kStem + "_physioevents.tsv.gz")));
  ASSERT_EQ(erows.size(), 1u);
  EXPECT_EQ(erows[0], (std::vector<std::string>{"5.020000000", "n/a", "n/a", "trial 1, \"go\""}));
  const auto trows = tsv_rows(slurp(d.path / kBeh / "sub-01_ses-a_task-freeview_events.tsv"));
  ASSERT_EQ(trows.size(), 2u);
  EXPECT_EQ(trows[1], (std::vector<std::string>{"0.020000000", "0", "trial 1, \"go\""}));
  // No pupil was measured: no pupil columns.
  const Json j = Json::parse(slurp(d.path / kBeh / (kStem + "_physio.json")));
  EXPECT_EQ(j["Columns"].size(), 7u);
  // Creation time unknown (0): acq_time n/a.
  const auto scans = tsv_rows(slurp(d.path / "sub-01/ses-a/sub-01_ses-a_scans.tsv"));
  EXPECT_EQ(scans[1][1], "n/a");
}

TEST(BidsExport, NeverReplacesAFile) {
  TempDir d;
  const Recording rec = read_recording(kSynthetic);
  fs::create_directories(d.path / kBeh);
  const fs::path existing = d.path / kBeh / (kStem + "_physioevents.json");
  std::ofstream(existing) << "mine";
  std::ofstream(d.path / "dataset_description.json") << "{\"Name\": \"theirs\", \"BIDSVersion\": \"1.9.0\"}";
  try {
    export_bids(rec, options(d.path));
    FAIL() << "replaced " << existing;
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(existing.string()), std::string::npos) << e.what();
  }
  EXPECT_EQ(slurp(existing), "mine");
  EXPECT_FALSE(fs::exists(d.path / kBeh / (kStem + "_physio.tsv.gz")));  // nothing written
  // A second export into the same dataset: refused for the same names, fine for another run.
  fs::remove(existing);
  export_bids(rec, options(d.path));
  EXPECT_EQ(slurp(d.path / "dataset_description.json"), "{\"Name\": \"theirs\", \"BIDSVersion\": \"1.9.0\"}");
  EXPECT_THROW(export_bids(rec, options(d.path)), std::runtime_error);
  BidsOptions o = options(d.path);
  o.run = "2";
  const BidsResult r2 = export_bids(rec, o);
  EXPECT_TRUE(fs::exists(d.path / kBeh / "sub-01_ses-a_task-freeview_run-2_recording-eye1_physio.tsv.gz"));
  const auto scans = tsv_rows(slurp(d.path / "sub-01/ses-a/sub-01_ses-a_scans.tsv"));
  EXPECT_EQ(scans.size(), 3u);  // one row appended for the second run
}

TEST(BidsExport, RefusesBadLabels) {
  TempDir d;
  const Recording rec = read_recording(kSynthetic);
  for (const auto& [field, value] : std::vector<std::pair<std::string, std::string>>{
           {"subject", "0-1"}, {"subject", ""}, {"task", "free view"}, {"task", "a_b"},
           {"session", "x/y"}, {"recording", "eye.1"}, {"run", "1a"}}) {
    BidsOptions o = options(d.path);
    if (field == "subject") o.subject = value;
    if (field == "task") o.task = value;
    if (field == "session") o.session = value;
    if (field == "recording") o.recording = value;
    if (field == "run") o.run = value;
    try {
      export_bids(rec, o);
      ADD_FAILURE() << field << " \"" << value << "\" was accepted";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find("--" + field), std::string::npos) << e.what();
    }
  }
  EXPECT_TRUE(fs::is_empty(d.path));  // nothing written
}

TEST(BidsExport, ExportsTheIntactRecordsOfADamagedRecording) {
  TempDir d;
  std::string bytes = slurp(kSynthetic);
  // Flip bytes in three places past the header: each costs the record that holds it.
  for (std::size_t at : {bytes.size() / 4, bytes.size() / 2, bytes.size() * 3 / 4}) {
    bytes[at] = static_cast<char>(static_cast<unsigned char>(bytes[at]) ^ 0x5au);
  }
  const fs::path damaged = d.path / "damaged.fgr";
  std::ofstream(damaged, std::ios::binary) << bytes;
  const Recording rec = read_recording(damaged.string());
  ASSERT_EQ(rec.report.damaged_regions, 3u);
  ASSERT_TRUE(rec.report.header_valid);
  std::size_t samples = 0;
  for (const Record& r : rec.records) samples += std::holds_alternative<GazeSample>(r.item) ? 1u : 0u;
  ASSERT_GE(samples, 15497u);
  const BidsResult r = export_bids(rec, options(d.path / "ds"));
  EXPECT_EQ(r.samples, samples);
  const auto rows = tsv_rows(gunzip(d.path / "ds" / kBeh / (kStem + "_physio.tsv.gz")));
  EXPECT_EQ(rows.size(), samples);
}

TEST(BidsExport, GzipRoundTrips) {
  TempDir d;
  std::string text;
  for (int i = 0; i < 100000; ++i) text += std::to_string(i) + "\tn/a\n";
  const fs::path p = d.path / "x.tsv.gz";
  std::ofstream(p, std::ios::binary) << gzip_compress(text);
  EXPECT_EQ(gunzip(p), text);
  EXPECT_LT(fs::file_size(p), text.size() / 3);
}

}  // namespace
