// SPDX-License-Identifier: Apache-2.0
// CSV form of gaze recordings: exact round trip of samples and display, and errors that name the
// source, the line and the column.
#include <gtest/gtest.h>

#include <cstdint>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "fovea/protocol/csv.h"

namespace {

using namespace fovea::protocol;

constexpr const char* kColumnLine =
    "sequence,tracker_time_ns,x,y,x_deg,y_deg,angular_velocity_deg_s,confidence,state,gaze_valid,left_flags,"
    "left_pupil_x_px,left_pupil_y_px,left_pupil_diameter_mm,left_pupil_glint_x_px,left_pupil_glint_y_px,"
    "right_flags,right_pupil_x_px,right_pupil_y_px,right_pupil_diameter_mm,right_pupil_glint_x_px,"
    "right_pupil_glint_y_px";  // the 22 columns of files written before host_receive_ns: still read

Recording sample_recording() {
  Recording rec;
  rec.header.device = "csv test rig";
  rec.header.display = DisplayGeometry{};  // 1920x1080, 531.3 x 298.9 mm, 650 mm
  rec.header.nominal_rate_hz = 250.0;
  rec.report.header_valid = true;
  std::int64_t t = -8'000'000;  // times may be negative on some clocks
  for (std::uint64_t i = 0; i < 60; ++i) {
    t += 4'000'000;
    Record r;
    r.sequence = 1000 + i;
    if (i % 9 == 4) {
      GazeEvent e;
      e.kind = EyeMovement::Saccade;
      e.phase = EventPhase::End;
      e.start_time_ns = t - 20'000'000;
      e.duration_ns = 20'000'000;
      e.amplitude_deg = 3.25f;
      r.item = e;
    } else {
      const float k = static_cast<float>(i);
      GazeSample s;
      s.tracker_time_ns = t;
      // Values that need all nine significant digits of %.9g to come back exactly.
      s.x = 0.1f + k / 3.0f;
      s.y = 1.0f / (k + 7.0f);
      s.x_deg = -17.123456789f + k * 0.577f;
      s.y_deg = 3.3333333f - k / 11.0f;
      s.angular_velocity_deg_s = k * k * 1.0000001f;
      s.confidence = k / 59.0f;
      s.state = static_cast<EyeMovement>(i % 5);
      s.flags = (i % 3 == 0) ? 0 : kGazeValid;
      s.left = EyeData{static_cast<std::uint8_t>(i % 4), 320.123f + k, 240.987f - k, 3.14159265f, -0.1f * k, 0.7f};
      s.right = EyeData{static_cast<std::uint8_t>((i + 1) % 4), 300.5f, 1e-7f * k, 0.0f, -1e6f, 1e20f};
      r.item = s;
    }
    rec.records.push_back(r);
  }
  return rec;
}

std::vector<Record> samples_of(const Recording& rec) {
  std::vector<Record> out;
  for (const Record& r : rec.records) {
    if (std::holds_alternative<GazeSample>(r.item)) out.push_back(r);
  }
  return out;
}

const std::string kGoodRow = "7,1000000,0.5,0.25,0,-6.5625,12.5,0.75,fixation,1,3,323.5,214,3.5,0.25,-6,1,317,214,3.5,0,0";

// A valid file: 4 comment lines (1..4), the column line (5), data rows from line 6 on.
std::string csv_with_rows(const std::vector<std::string>& rows) {
  std::string s =
      "# fovea gaze samples v1\n# device: hand written\n# display: 1920x1080@531.3x298.9mm,650.0mm\n"
      "# sample_rate_hz: 250\n";
  s += kColumnLine;
  s += "\n";
  for (const std::string& r : rows) s += r + "\n";
  return s;
}

// Replaces field `col` (0-based) of a CSV row.
std::string with_field(const std::string& row, std::size_t col, const std::string& value) {
  std::vector<std::string> fields;
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = row.find(',', start);
    fields.push_back(row.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  fields.at(col) = value;
  std::string out;
  for (std::size_t i = 0; i < fields.size(); ++i) out += (i ? "," : "") + fields[i];
  return out;
}

Recording parse_csv(const std::string& text, const std::string& name = "input.csv") {
  std::istringstream in(text);
  return read_csv(in, name);
}

// The error message read_csv gives for `text`, or a marker if it did not throw.
std::string csv_error(const std::string& text, const std::string& name = "input.csv") {
  try {
    parse_csv(text, name);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "(read_csv did not throw)";
}

void expect_mentions(const std::string& msg, const std::vector<std::string>& parts) {
  for (const std::string& p : parts) EXPECT_NE(msg.find(p), std::string::npos) << "\"" << p << "\" not in: " << msg;
}

TEST(Csv, RoundTripIsExact) {
  const Recording rec = sample_recording();
  std::ostringstream out;
  const std::size_t events = write_csv(out, rec);
  const std::vector<Record> samples = samples_of(rec);
  EXPECT_EQ(events, rec.records.size() - samples.size());
  EXPECT_GT(events, 0u);

  const Recording back = parse_csv(out.str(), "roundtrip.csv");
  EXPECT_EQ(back.records, samples);  // every float bit for bit
  EXPECT_EQ(back.header.display, rec.header.display);
  EXPECT_EQ(back.header.nominal_rate_hz, 250.0);
  EXPECT_EQ(back.header.device, "csv test rig");
  EXPECT_TRUE(back.report.header_valid);
  EXPECT_EQ(back.report.records, samples.size());

  // And writing it again gives the same text minus nothing (events were already gone).
  std::ostringstream again;
  EXPECT_EQ(write_csv(again, back), 0u);
  EXPECT_EQ(again.str(), out.str());
}

TEST(Csv, HeaderLinesCarryDeviceDisplayAndRate) {
  Recording rec;
  rec.header.device = "lab 3";
  rec.header.display = DisplayGeometry{2560, 1440, 0.6, 0.3375, 0.7};
  rec.header.nominal_rate_hz = 1000.0;
  std::ostringstream out;
  write_csv(out, rec);
  const std::string expected = std::string("# fovea gaze samples v1\n# device: lab 3\n") +
                               "# display: 2560x1440@600x337.5mm,700mm\n# sample_rate_hz: 1000\n" +
                               kColumnLine + ",host_receive_ns\n";
  EXPECT_EQ(out.str(), expected);
  const Recording back = parse_csv(out.str());
  EXPECT_TRUE(back.records.empty());
  EXPECT_EQ(back.header.display, rec.header.display);
  EXPECT_EQ(back.header.nominal_rate_hz, 1000.0);
  EXPECT_EQ(back.header.device, "lab 3");
}

TEST(Csv, HandWrittenFileWithBlankLinesAndCrLf) {
  std::string text = csv_with_rows({kGoodRow, "", with_field(with_field(kGoodRow, 0, "8"), 1, "5000000")});
  std::string crlf;
  for (const char c : text) {
    if (c == '\n') crlf += '\r';
    crlf += c;
  }
  const Recording rec = parse_csv(crlf);
  ASSERT_EQ(rec.records.size(), 2u);
  EXPECT_EQ(rec.header.device, "hand written");
  EXPECT_EQ(rec.records[0].sequence, 7u);
  const auto& s = std::get<GazeSample>(rec.records[0].item);
  EXPECT_EQ(s.tracker_time_ns, 1'000'000);
  EXPECT_EQ(s.x, 0.5f);
  EXPECT_EQ(s.y_deg, -6.5625f);
  EXPECT_EQ(s.state, EyeMovement::Fixation);
  EXPECT_EQ(s.flags, kGazeValid);
  EXPECT_EQ(s.left, (EyeData{3, 323.5f, 214.0f, 3.5f, 0.25f, -6.0f}));
  EXPECT_EQ(s.right, (EyeData{1, 317.0f, 214.0f, 3.5f, 0.0f, 0.0f}));
  EXPECT_EQ(rec.records[1].time_ns(), 5'000'000);
}

TEST(Csv, WithoutCommentLinesDefaultsAreUsed) {
  const Recording rec = parse_csv(std::string(kColumnLine) + "\n" + kGoodRow + "\n");
  ASSERT_EQ(rec.records.size(), 1u);
  EXPECT_EQ(rec.header.display, DisplayGeometry{});
  EXPECT_EQ(rec.header.device, "csv import");
}

TEST(Csv, WrongColumnCountNamesSourceAndLine) {
  const std::string row = kGoodRow.substr(0, kGoodRow.rfind(','));  // 21 columns
  const std::string msg = csv_error(csv_with_rows({kGoodRow, row}), "short.csv");
  expect_mentions(msg, {"short.csv:7:", "22", "21"});
  expect_mentions(csv_error(csv_with_rows({kGoodRow + ",9"}), "long.csv"), {"long.csv:6:", "23"});
}

TEST(Csv, BadColumnHeader) {
  std::string text = csv_with_rows({kGoodRow});
  text.replace(text.find(",x,y,"), 5, ",x,why,");
  expect_mentions(csv_error(text, "hdr.csv"), {"hdr.csv:5:", "column 4", "\"why\"", "\"y\""});

  text = csv_with_rows({});
  text.replace(text.find(",right_pupil_glint_y_px"), 23, "");
  expect_mentions(csv_error(text, "hdr2.csv"), {"hdr2.csv:5:", "23", "found 21"});
}

TEST(Csv, MissingColumnHeaderLine) {
  expect_mentions(csv_error("# fovea gaze samples v1\n" + kGoodRow + "\n", "nohead.csv"), {"nohead.csv:2:"});
  expect_mentions(csv_error("# only comments\n", "comments.csv"), {"comments.csv", "no column header"});
  expect_mentions(csv_error("", "empty.csv"), {"empty.csv", "no column header"});
}

struct BadValue {
  std::size_t col;
  std::string value;
  std::string column_name;
  std::string why;
};

TEST(Csv, BadValuesNameSourceLineAndColumn) {
  const std::vector<BadValue> cases = {
      {2, "abc", "x", "not a number"},
      {3, "", "y", "not a number"},
      {4, "1.5.2", "x_deg", "not a number"},
      {7, "nan", "confidence", "finite"},
      {2, "NaN", "x", "finite"},
      {6, "inf", "angular_velocity_deg_s", "finite"},
      {7, "1.5", "confidence", "out of range"},
      {7, "-0.01", "confidence", "out of range"},
      {4, "181", "x_deg", "out of range"},
      {6, "-1", "angular_velocity_deg_s", "out of range"},
      {13, "-3", "left_pupil_diameter_mm", "out of range"},
      {8, "wink", "state", "fixation"},
      {8, "Fixation", "state", "fixation"},
      {0, "-1", "sequence", "not an integer"},
      {1, "12.5", "tracker_time_ns", "not an integer"},
      {9, "2", "gaze_valid", "out of range"},
      {10, "4", "left_flags", "out of range"},
      {16, "x", "right_flags", "not an integer"},
      {21, "nan", "right_pupil_glint_y_px", "finite"},
  };
  for (const BadValue& c : cases) {
    SCOPED_TRACE(c.column_name + " = \"" + c.value + "\"");
    const std::string text = csv_with_rows({kGoodRow, kGoodRow, with_field(kGoodRow, c.col, c.value)});
    const std::string msg = csv_error(text, "bad.csv");
    expect_mentions(msg, {"bad.csv:8:", "column " + std::to_string(c.col + 1), "(" + c.column_name + ")", c.why});
  }
}

TEST(Csv, TimeGoingBackwards) {
  const std::string later = with_field(kGoodRow, 1, "2000000");
  const std::string earlier = with_field(kGoodRow, 1, "1999999");
  const std::string msg = csv_error(csv_with_rows({later, later, earlier}), "time.csv");
  expect_mentions(msg, {"time.csv:8:", "tracker_time_ns", "backwards"});
}

TEST(Csv, BadCommentHeaderValues) {
  std::string text = csv_with_rows({kGoodRow});
  text.replace(text.find("1920x1080"), 9, "1920by1080");
  expect_mentions(csv_error(text, "disp.csv"), {"disp.csv:3:", "1920by1080"});
  text = csv_with_rows({kGoodRow});
  text.replace(text.find("sample_rate_hz: 250"), 19, "sample_rate_hz: nan");
  expect_mentions(csv_error(text, "rate.csv"), {"rate.csv:4:", "sample_rate_hz"});
}

TEST(Csv, ErrorsReturnNothingPartial) {
  // read_csv throws instead of returning the rows before the bad one.
  const std::string text = csv_with_rows({kGoodRow, kGoodRow, with_field(kGoodRow, 7, "2")});
  std::istringstream in(text);
  EXPECT_THROW(read_csv(in, "x.csv"), std::runtime_error);
}

}  // namespace

TEST(Csv, MarkersGoToTheirOwnCsvWithLabelsQuoted) {
  Recording rec = sample_recording();
  Marker a;
  a.marker_id = 1;
  a.time_ns = a.received_ns = 42;
  a.label.value = "trial 1, \"go\"";
  Marker b;
  b.marker_id = 2;
  b.time_ns = 40;
  b.received_ns = 45;
  b.flags = kMarkerClientTime;
  b.label.value = "Reiz \xc3\xa4";
  rec.records.push_back(Record{0, a});
  rec.records.push_back(Record{1, b});
  EXPECT_EQ(count_markers(rec), 2u);

  std::ostringstream samples;
  EXPECT_EQ(write_csv(samples, rec), rec.records.size() - samples_of(rec).size() - 2)
      << "markers are not events: they are not counted as left out";
  EXPECT_EQ(parse_csv(samples.str(), "s.csv").records, samples_of(rec));

  std::ostringstream markers;
  EXPECT_EQ(write_markers_csv(markers, rec), 2u);
  EXPECT_EQ(markers.str(),
            "# fovea markers v1\n"
            "# times: the recording's clock, as the samples' tracker_time_ns\n"
            "sequence,time_ns,received_ns,time_source,label\n"
            "0,42,42,daemon,\"trial 1, \"\"go\"\"\"\n"
            "1,40,45,client,\"Reiz \xc3\xa4\"\n");
}

TEST(Csv, HostReceiveTimesRoundTripAndMayBeAbsent) {
  Recording rec = sample_recording();
  std::size_t n = 0;
  for (Record& r : rec.records) {
    if (std::holds_alternative<GazeSample>(r.item) && n++ % 2 == 0) r.host_receive_ns = r.time_ns() + 1'234'567;
  }
  std::ostringstream out;
  write_csv(out, rec);
  const std::string first = ",-2765433\n";  // the first sample's receive time: -4 ms + 1.234567 ms
  ASSERT_NE(out.str().find(first), std::string::npos) << out.str().substr(0, 1200);
  EXPECT_NE(out.str().find(",\n"), std::string::npos) << "a sample without a receive time ends in an empty field";
  EXPECT_EQ(parse_csv(out.str(), "rt.csv").records, samples_of(rec));
  // A receive time that is not an integer is named like any bad value.
  std::string bad = out.str();
  bad.replace(bad.find(first), first.size(), ",12x\n");
  expect_mentions(csv_error(bad, "rt.csv"), {"rt.csv:6:", "column 23 (host_receive_ns)", "\"12x\"", "not an integer"});
}
