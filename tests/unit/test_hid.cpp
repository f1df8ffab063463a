// SPDX-License-Identifier: Apache-2.0
// HID "Eye and Head Trackers" source: report descriptor parser, eye-tracker mapping, report
// decoding, tracker clock, spec parsing and user-facing messages. Descriptors are built by hand
// with a tiny item emitter, after the shape of Microsoft's reference eye-tracker drivers (the
// layout consumer trackers implement), plus a boot mouse and keyboard (HID 1.11 appendix B/E).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "fovea/protocol/display_geometry.h"
#include "sources/hid/eye_tracker.h"
#include "sources/hid/hid_source.h"
#include "sources/hid/report_descriptor.h"
#include "source_api/tracker_clock.h"
#include "sources/hid/usage_tables.h"

namespace {

using namespace fovea::trackerd::hid;
using fovea::trackerd::TrackerClock;
using Bytes = std::vector<std::uint8_t>;

// ---------------------------------------------------------------------------------------------
// A tiny report descriptor emitter: one method per item, data sized to fit the value.
class Desc {
 public:
  // Short item with explicit data size (0, 1, 2 or 4 bytes).
  Desc& item(std::uint8_t prefix_without_size, std::uint32_t value, int size) {
    const std::uint8_t code = size == 4 ? 3 : static_cast<std::uint8_t>(size);
    b_.push_back(static_cast<std::uint8_t>(prefix_without_size | code));
    for (int i = 0; i < size; ++i) b_.push_back(static_cast<std::uint8_t>(value >> (8 * i)));
    return *this;
  }
  Desc& unsigned_item(std::uint8_t p, std::uint32_t v) { return item(p, v, v <= 0xFF ? 1 : v <= 0xFFFF ? 2 : 4); }
  Desc& signed_item(std::uint8_t p, std::int64_t v) {
    const int size = v >= -128 && v <= 127 ? 1 : v >= -32768 && v <= 32767 ? 2 : 4;
    return item(p, static_cast<std::uint32_t>(v), size);
  }
  Desc& raw(std::initializer_list<std::uint8_t> bytes) {
    b_.insert(b_.end(), bytes);
    return *this;
  }

  Desc& page(std::uint32_t p) { return unsigned_item(0x04, p); }
  Desc& usage(std::uint32_t id) { return unsigned_item(0x08, id); }
  Desc& usage_ext(std::uint16_t page, std::uint16_t id) { return item(0x08, make_usage(page, id), 4); }
  Desc& usage_min(std::uint32_t id) { return unsigned_item(0x18, id); }
  Desc& usage_max(std::uint32_t id) { return unsigned_item(0x28, id); }
  Desc& lmin(std::int64_t v) { return signed_item(0x14, v); }
  Desc& lmax(std::int64_t v) { return signed_item(0x24, v); }
  Desc& lmax_unsigned(std::uint32_t v) { return unsigned_item(0x24, v); }
  Desc& pmin(std::int64_t v) { return signed_item(0x34, v); }
  Desc& pmax(std::int64_t v) { return signed_item(0x44, v); }
  Desc& unit_exp(int e) { return item(0x54, static_cast<std::uint32_t>(e) & 0xFu, 1); }
  Desc& unit(std::uint32_t u) { return unsigned_item(0x64, u); }
  Desc& size(std::uint32_t bits) { return unsigned_item(0x74, bits); }
  Desc& id(std::uint32_t id) { return unsigned_item(0x84, id); }
  Desc& count(std::uint32_t n) { return unsigned_item(0x94, n); }
  Desc& push() { return item(0xA4, 0, 0); }
  Desc& pop() { return item(0xB4, 0, 0); }
  Desc& input(std::uint32_t flags) { return item(0x80, flags, 1); }
  Desc& output(std::uint32_t flags) { return item(0x90, flags, 1); }
  Desc& feature(std::uint32_t flags) { return item(0xB0, flags, 1); }
  Desc& collection(CollectionKind k) { return item(0xA0, static_cast<std::uint32_t>(k), 1); }
  Desc& end() { return item(0xC0, 0, 0); }

  const Bytes& bytes() const { return b_; }
  std::size_t offset() const { return b_.size(); }  // where the next item will start

 private:
  Bytes b_;
};

constexpr std::uint32_t kData = flag::Variable;                       // Data, Var, Abs
constexpr std::uint32_t kStatic = flag::Constant | flag::Variable;    // Const, Var, Abs
constexpr std::uint32_t kPad = flag::Constant;                        // Const, Array

// Little-endian bit packer for reports.
class Report {
 public:
  explicit Report(std::optional<std::uint8_t> id = std::nullopt) : id_(id) {}
  Report& put(std::uint64_t v, unsigned bits) {
    for (unsigned i = 0; i < bits; ++i) bits_.push_back(i < 64 && ((v >> i) & 1u) != 0);
    return *this;
  }
  Report& put_signed(std::int64_t v, unsigned bits) { return put(static_cast<std::uint64_t>(v), bits); }
  Bytes bytes() const {
    Bytes out;
    if (id_) out.push_back(*id_);
    const std::size_t start = out.size();
    out.resize(start + (bits_.size() + 7) / 8, 0);
    for (std::size_t i = 0; i < bits_.size(); ++i) {
      if (bits_[i]) out[start + i / 8] = static_cast<std::uint8_t>(out[start + i / 8] | (1u << (i % 8)));
    }
    return out;
  }

 private:
  std::optional<std::uint8_t> id_;
  std::vector<bool> bits_;
};

// An eye tracker shaped like Microsoft's reference drivers: one Eye Tracker application collection
// with Tracking Data (Input 0x10: 3 pad bytes, timestamp as 8 one-byte elements, gaze point and
// both eye positions as signed 32-bit micrometres), Capabilities (0x11), Configuration (0x12),
// Status (0x13) and Control (0x14) feature reports.
Bytes reference_eye_tracker() {
  Desc d;
  d.page(0x12).usage(0x01).collection(CollectionKind::Application);
  d.collection(CollectionKind::Logical).id(0x10);
  d.lmin(0).lmax_unsigned(0xFF).size(8).count(3).input(kStatic);  // padding (no usage)
  d.usage(0x20).count(8).input(kData);                           // Sensor Timestamp, 8 bytes
  d.count(1).size(32).lmin(std::numeric_limits<std::int32_t>::min()).lmax(std::numeric_limits<std::int32_t>::max());
  d.usage(0x24).collection(CollectionKind::Physical).count(2).usage(0x21).usage(0x22).input(kData).end();
  d.usage(0x25).collection(CollectionKind::Physical).count(3).usage(0x21).usage(0x22).usage(0x23).input(kData).end();
  d.usage(0x26).collection(CollectionKind::Physical).count(3).usage(0x21).usage(0x22).usage(0x23).input(kData).end();
  d.end();
  d.collection(CollectionKind::Logical).id(0x11);  // Capabilities
  d.size(8).count(1).lmin(1).lmax(4).usage(0x0100).feature(kStatic);
  d.count(5).size(32).lmin(0).lmax(0x7FFFFFFF);
  d.usage(0x0101).usage(0x0102).usage(0x0103).usage(0x0104).usage(0x0105).feature(kStatic);
  d.end();
  d.collection(CollectionKind::Logical).id(0x12);  // Configuration
  d.size(8).count(1).feature(kStatic);
  d.size(16).lmin(0).lmax_unsigned(0xFFFF).usage(0x0200).feature(kStatic).usage(0x0201).feature(kStatic);
  d.size(32).lmax(0x7FFFFFFF).usage(0x0202).feature(kStatic);
  d.size(16).lmax_unsigned(0xFFFF).usage(0x0203).feature(kStatic);
  d.size(32).count(2).lmax(0x7FFFFFFF).usage(0x0204).usage(0x0205).feature(kStatic);
  d.end();
  d.collection(CollectionKind::Logical).id(0x13);  // Status
  d.size(8).count(1).feature(kStatic);
  d.lmin(0).lmax(4).usage(0x0301).feature(kData);
  d.size(16).lmax(0x7FFF).usage(0x0300).feature(kData);
  d.end();
  d.collection(CollectionKind::Logical).id(0x14);  // Control
  d.size(8).count(1).lmin(0).lmax(7).usage(0x0400).feature(kData);
  d.end();
  d.end();
  return d.bytes();
}

Bytes reference_gaze_report(std::uint64_t ts, std::int32_t gx, std::int32_t gy, std::array<std::int32_t, 3> left,
                            std::array<std::int32_t, 3> right) {
  Report r(0x10);
  r.put(0xAABBCC, 24).put(ts, 64).put_signed(gx, 32).put_signed(gy, 32);
  for (auto v : left) r.put_signed(v, 32);
  for (auto v : right) r.put_signed(v, 32);
  return r.bytes();
}

// HID 1.11 appendix B.2: boot protocol mouse.
Bytes boot_mouse() {
  return {0x05, 0x01, 0x09, 0x02, 0xA1, 0x01, 0x09, 0x01, 0xA1, 0x00, 0x05, 0x09, 0x19, 0x01, 0x29, 0x03, 0x15, 0x00,
          0x25, 0x01, 0x95, 0x03, 0x75, 0x01, 0x81, 0x02, 0x95, 0x01, 0x75, 0x05, 0x81, 0x01, 0x05, 0x01, 0x09, 0x30,
          0x09, 0x31, 0x15, 0x81, 0x25, 0x7F, 0x75, 0x08, 0x95, 0x02, 0x81, 0x06, 0xC0, 0xC0};
}

// HID 1.11 appendix B.1 / E.6: boot protocol keyboard.
Bytes boot_keyboard() {
  return {0x05, 0x01, 0x09, 0x06, 0xA1, 0x01, 0x05, 0x07, 0x19, 0xE0, 0x29, 0xE7, 0x15, 0x00, 0x25, 0x01, 0x75, 0x01,
          0x95, 0x08, 0x81, 0x02, 0x95, 0x01, 0x75, 0x08, 0x81, 0x01, 0x95, 0x05, 0x75, 0x01, 0x05, 0x08, 0x19, 0x01,
          0x29, 0x05, 0x91, 0x02, 0x95, 0x01, 0x75, 0x03, 0x91, 0x01, 0x95, 0x06, 0x75, 0x08, 0x15, 0x00, 0x25, 0x65,
          0x05, 0x07, 0x19, 0x00, 0x29, 0x65, 0x81, 0x00, 0xC0};
}

// A compact tracker without report IDs: fields at odd bit offsets, signed 12-bit gaze in units of
// 0.1 mm (unit cm, exponent -2), a 16-bit timestamp, a 3-bit status.
Bytes packed_eye_tracker() {
  Desc d;
  d.page(0x12).usage(0x01).collection(CollectionKind::Application);
  d.size(3).count(1).input(kPad);                                   // bits 0..2
  d.usage(0x20).size(16).lmin(0).lmax_unsigned(0xFFFF).input(kData);  // bits 3..18
  d.usage(0x24).collection(CollectionKind::Physical);
  d.unit(0x11).unit_exp(-2).lmin(-2048).lmax(2047).size(12).count(2).usage_min(0x21).usage_max(0x22).input(kData);
  d.end();                                                          // x bits 19..30, y bits 31..42
  d.unit(0).unit_exp(0).size(3).count(1).lmin(0).lmax(4).usage_ext(0x12, 0x0301).input(kData);  // bits 43..45
  d.size(2).input(kPad);                                            // bits 46..47
  d.end();
  return d.bytes();
}

Bytes packed_report(std::uint16_t ts, std::int32_t x, std::int32_t y, std::uint32_t status) {
  Report r;
  r.put(0b101, 3).put(ts, 16).put_signed(x, 12).put_signed(y, 12).put(status, 3).put(0, 2);
  return r.bytes();
}

// Two Input reports: head position (ID 1) and gaze (ID 2); the gaze report has no timestamp.
Bytes two_report_eye_tracker() {
  Desc d;
  d.page(0x12).usage(0x01).collection(CollectionKind::Application);
  d.id(1).usage(0x27).collection(CollectionKind::Physical);
  d.lmin(-32768).lmax(32767).size(16).count(3).usage(0x21).usage(0x22).usage(0x23).input(kData).end();
  d.id(2).usage(0x24).collection(CollectionKind::Physical);
  d.lmin(0).lmax(0x7FFFFFFF).size(32).count(2).usage(0x21).usage(0x22).input(kData).end();
  d.end();
  return d.bytes();
}

std::string error_of(const Bytes& bytes, std::size_t* offset = nullptr) {
  try {
    (void)parse_report_descriptor(bytes);
  } catch (const DescriptorError& e) {
    if (offset) *offset = e.offset();
    return e.what();
  }
  return "(parsed)";
}

// ---------------------------------------------------------------------------------------------
TEST(HidDescriptor, ParsesReferenceEyeTrackerLayouts) {
  const auto d = parse_report_descriptor(reference_eye_tracker());
  EXPECT_TRUE(d.uses_report_ids);
  ASSERT_EQ(d.application_usages().size(), 1u);
  EXPECT_EQ(d.application_usages()[0], eht::EyeTracker);

  const ReportLayout* in = d.find(ReportType::Input, 0x10);
  ASSERT_NE(in, nullptr);
  EXPECT_EQ(in->bit_length, 24u + 64u + 64u + 96u + 96u);
  EXPECT_EQ(in->wire_size(true), 44u);
  ASSERT_EQ(in->fields.size(), 5u);
  EXPECT_TRUE(in->fields[0].usages.empty());
  EXPECT_EQ(in->fields[1].bit_offset, 24u);
  EXPECT_EQ(in->fields[1].count, 8u);
  EXPECT_EQ(in->fields[1].usage_of(7), eht::SensorTimestamp);  // the last usage repeats
  EXPECT_EQ(in->fields[2].bit_offset, 88u);
  EXPECT_EQ(in->fields[2].logical_min, std::numeric_limits<std::int32_t>::min());
  EXPECT_EQ(in->fields[2].usage_of(1), eht::PositionY);
  EXPECT_TRUE(d.path_contains(in->fields[2].collection, eht::GazePoint));
  EXPECT_TRUE(d.path_contains(in->fields[3].collection, eht::LeftEyePosition));
  EXPECT_FALSE(d.path_contains(in->fields[3].collection, eht::RightEyePosition));
  EXPECT_TRUE(d.path_contains(in->fields[4].collection, eht::EyeTracker));

  const ReportLayout* config = d.find(ReportType::Feature, 0x12);
  ASSERT_NE(config, nullptr);
  EXPECT_EQ(config->bit_length, 152u);
  EXPECT_EQ(config->fields.back().bit_offset, 88u);
  EXPECT_EQ(config->fields.back().logical_max, 0x7FFFFFFF);
  EXPECT_EQ(config->fields[1].logical_max, 0xFFFF);  // 2-byte 0xFFFF with min 0 reads unsigned
  EXPECT_NE(d.find(ReportType::Feature, 0x14), nullptr);
  EXPECT_EQ(d.find(ReportType::Output, 0x10), nullptr);
}

TEST(HidDescriptor, BootMouseAndKeyboardParse) {
  const auto mouse = parse_report_descriptor(boot_mouse());
  EXPECT_FALSE(mouse.uses_report_ids);
  const ReportLayout* m = mouse.find(ReportType::Input, 0);
  ASSERT_NE(m, nullptr);
  EXPECT_EQ(m->bit_length, 24u);
  ASSERT_EQ(m->fields.size(), 3u);
  EXPECT_EQ(m->fields[0].usage_of(2), make_usage(0x09, 3));  // Button 3
  EXPECT_EQ(m->fields[2].usage_of(1), make_usage(0x01, 0x31));  // Y
  EXPECT_TRUE(m->fields[2].is_signed());
  EXPECT_TRUE(m->fields[2].flags & flag::Relative);
  const Bytes motion{0x05, 0xFE, 0x03};  // buttons 1+3, x -2, y +3
  EXPECT_EQ(field_value(m->fields[0], motion, 0), 1);
  EXPECT_EQ(field_value(m->fields[0], motion, 1), 0);
  EXPECT_EQ(field_value(m->fields[0], motion, 2), 1);
  EXPECT_EQ(field_value(m->fields[2], motion, 0), -2);
  EXPECT_EQ(field_value(m->fields[2], motion, 1), 3);

  const auto kb = parse_report_descriptor(boot_keyboard());
  ASSERT_NE(kb.find(ReportType::Input, 0), nullptr);
  EXPECT_EQ(kb.find(ReportType::Input, 0)->bit_length, 64u);
  ASSERT_NE(kb.find(ReportType::Output, 0), nullptr);
  EXPECT_EQ(kb.find(ReportType::Output, 0)->bit_length, 8u);
  EXPECT_FALSE(kb.find(ReportType::Input, 0)->fields[2].is_variable());  // key array
}

TEST(HidDescriptor, MouseAndKeyboardAreNotEyeTrackers) {
  try {
    (void)map_eye_tracker(parse_report_descriptor(boot_mouse()));
    FAIL() << "a mouse mapped as an eye tracker";
  } catch (const NotAnEyeTracker& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("no Eye Tracker application collection"), std::string::npos) << what;
    EXPECT_NE(what.find("Generic Desktop / Mouse (0x01:0x02)"), std::string::npos) << what;
    EXPECT_NE(what.find("Button"), std::string::npos) << what;
  }
  try {
    (void)map_eye_tracker(parse_report_descriptor(boot_keyboard()));
    FAIL() << "a keyboard mapped as an eye tracker";
  } catch (const NotAnEyeTracker& e) {
    EXPECT_NE(std::string(e.what()).find("Keyboard"), std::string::npos) << e.what();
  }
}

TEST(HidDescriptor, EyeTrackerWithoutGazePointIsRejected) {
  Desc d;
  d.page(0x12).usage(0x01).collection(CollectionKind::Application);
  d.usage(0x27).collection(CollectionKind::Physical).lmin(0).lmax(1000).size(16).count(2);
  d.usage(0x21).usage(0x22).input(kData).end().end();
  try {
    (void)map_eye_tracker(parse_report_descriptor(d.bytes()));
    FAIL();
  } catch (const NotAnEyeTracker& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("no Gaze Point"), std::string::npos) << what;
    EXPECT_NE(what.find("Eye and Head Trackers / Position X"), std::string::npos) << what;
  }
}

TEST(HidDescriptor, GazeOutsideTheEyeTrackerCollectionDoesNotCount) {
  Desc d;
  d.page(0x12).usage(0x01).collection(CollectionKind::Application).end();
  d.page(0x12).usage(0x02).collection(CollectionKind::Application);  // Head Tracker
  d.usage(0x24).collection(CollectionKind::Physical).lmin(0).lmax(1000).size(16).count(2);
  d.usage(0x21).usage(0x22).input(kData).end().end();
  EXPECT_THROW((void)map_eye_tracker(parse_report_descriptor(d.bytes())), NotAnEyeTracker);
}

TEST(HidDescriptor, PushPopAndDelimiters) {
  Desc d;
  d.page(0x01).usage(0x02).collection(CollectionKind::Application);
  d.size(8).count(1).lmin(0).lmax(100).push();
  d.size(4).count(2).usage(0x30).usage(0x31).input(kData);
  d.pop();
  // Delimiter set: only the first usage of the set counts.
  d.item(0xA8, 1, 1).usage(0x32).usage(0x33).item(0xA8, 0, 1).input(kData);
  d.end();
  const auto r = parse_report_descriptor(d.bytes());
  const ReportLayout* in = r.find(ReportType::Input, 0);
  ASSERT_NE(in, nullptr);
  ASSERT_EQ(in->fields.size(), 2u);
  EXPECT_EQ(in->fields[0].bit_size, 4u);
  EXPECT_EQ(in->fields[1].bit_size, 8u);  // restored by Pop
  EXPECT_EQ(in->fields[1].count, 1u);
  EXPECT_EQ(in->fields[1].bit_offset, 8u);
  ASSERT_EQ(in->fields[1].usages.size(), 1u);
  EXPECT_EQ(in->fields[1].usages[0].min, make_usage(0x01, 0x32));
}

TEST(HidDescriptor, UsagePageAppliesAtTheMainItemAndExtendedUsagesKeepTheirs) {
  Desc d;
  d.page(0x01).usage(0x02).collection(CollectionKind::Application);
  d.usage(0x30).usage_ext(0x12, 0x21).page(0x09);  // 0x30 joins page 9 (set before the main item)
  d.size(8).count(2).lmin(0).lmax(10).input(kData).end();
  const auto r = parse_report_descriptor(d.bytes());
  const auto& f = r.find(ReportType::Input, 0)->fields[0];
  EXPECT_EQ(f.usage_of(0), make_usage(0x09, 0x30));
  EXPECT_EQ(f.usage_of(1), eht::PositionX);
  EXPECT_EQ(f.index_of(eht::PositionX), 1u);
  EXPECT_FALSE(f.index_of(eht::PositionY).has_value());
}

TEST(HidDescriptor, LongItemsAreSkipped) {
  Desc d;
  d.page(0x01).usage(0x02).collection(CollectionKind::Application);
  d.raw({0xFE, 0x03, 0xF0, 0x01, 0x02, 0x03});
  d.size(8).count(1).lmin(0).lmax(1).usage(0x30).input(kData).end();
  EXPECT_EQ(parse_report_descriptor(d.bytes()).find(ReportType::Input, 0)->bit_length, 8u);
}

// ---------------------------------------------------------------------------------------------
// Malformed descriptors: each class of error, with the byte offset of the offending item.
struct Malformed {
  const char* name;
  Bytes bytes;
  std::size_t offset;
  const char* message;
};

std::vector<Malformed> malformed_descriptors() {
  std::vector<Malformed> out;
  out.push_back({"empty", {}, 0, "empty report descriptor"});
  out.push_back({"truncated item", {0x05, 0x01, 0x26, 0xFF}, 2, "truncated item: 2 data bytes declared, 1 left"});
  out.push_back({"truncated 4-byte item", {0x05, 0x01, 0x27, 0xFF, 0xFF}, 2, "4 data bytes declared, 2 left"});
  out.push_back({"truncated long item header", {0x05, 0x01, 0xFE, 0x02}, 2, "truncated long item header"});
  out.push_back({"truncated long item", {0xFE, 0x05, 0x10, 0x01}, 0, "truncated long item: 5 data bytes"});
  out.push_back({"pop without push", {0x05, 0x01, 0xB4}, 2, "Pop: Pop without Push"});
  out.push_back({"end collection without collection", {0x05, 0x01, 0xC0}, 2, "End Collection without an open"});
  {
    Desc d;
    d.page(1).usage(2).collection(CollectionKind::Application).collection(CollectionKind::Physical).end();
    out.push_back({"unclosed collection", d.bytes(), d.offset(), "1 collection(s) not closed"});
  }
  {
    Desc d;
    d.page(1).usage(2).collection(CollectionKind::Application);
    const std::size_t at = d.offset();
    d.size(0);
    out.push_back({"report size 0", d.bytes(), at, "report size 0 bits (allowed 1..32)"});
  }
  {
    Desc d;
    d.page(1);
    const std::size_t at = d.offset();
    d.size(33);
    out.push_back({"report size 33", d.bytes(), at, "report size 33 bits"});
  }
  {
    Desc d;
    d.page(1);
    const std::size_t at = d.offset();
    d.item(0x94, 0xFFFFFFFFu, 4);
    out.push_back({"absurd report count", d.bytes(), at, "report count 4294967295"});
  }
  {
    Desc d;
    d.page(1).usage(2).collection(CollectionKind::Application).size(32).count(4096).lmin(0).lmax(1);
    d.usage(0x30).input(kData);  // exactly 16 KiB: allowed
    const std::size_t at = d.offset();
    d.size(1).count(1).input(kData);
    out.push_back({"report bits overflow", d.bytes(), at + 4, "would be 131073 bits"});
  }
  {
    Desc d;
    d.page(1);
    const std::size_t at = d.offset();
    d.id(0);
    out.push_back({"report ID 0", d.bytes(), at, "report ID 0 (allowed 1..255)"});
  }
  {
    Desc d;
    d.page(1);
    for (int i = 0; i < 16; ++i) d.push();
    const std::size_t at = d.offset();
    d.push();
    out.push_back({"push overflow", d.bytes(), at, "global stack deeper than 16"});
  }
  {
    Desc d;
    for (int i = 0; i < 32; ++i) d.collection(CollectionKind::Logical);
    const std::size_t at = d.offset();
    d.collection(CollectionKind::Logical);
    out.push_back({"collection depth", d.bytes(), at, "collections nested deeper than 32"});
  }
  out.push_back({"reserved item type", {0x05, 0x01, 0x0D, 0x00}, 2, "reserved item type 3"});
  out.push_back({"reserved global tag", {0x05, 0x01, 0xC4}, 2, "reserved global item tag"});
  out.push_back({"reserved collection type", {0xA1, 0x07}, 0, "reserved collection type 0x07"});
  {
    Desc d;
    d.page(1).usage(2).collection(CollectionKind::Application).size(8).count(1).lmin(0).lmax(1).usage_min(1);
    const std::size_t at = d.offset();
    d.input(kData).end();
    out.push_back({"usage minimum without maximum", d.bytes(), at, "without its pair"});
  }
  {
    Desc d;
    d.page(1).usage_min(5).usage_max(2).size(8).count(1).lmin(0).lmax(1);
    const std::size_t at = d.offset();
    d.input(kData);
    out.push_back({"usage range reversed", d.bytes(), at, "above maximum"});
  }
  {
    Desc d;
    d.page(1).count(1);
    const std::size_t at = d.offset();
    d.input(kData);
    out.push_back({"no report size", d.bytes(), at, "no Report Size before this main item"});
  }
  {
    Desc d;
    d.page(1).size(8).count(1).lmin(0).lmax(1).input(kData);
    const std::size_t at = d.offset();
    d.id(3);
    out.push_back({"report ID after unnumbered fields", d.bytes(), at, "after main items that had no report ID"});
  }
  {
    Desc d;
    d.page(1).size(8).count(1).lmin(0).lmax(1).push().id(2).input(kData).pop();
    const std::size_t at = d.offset();
    d.input(kData);
    out.push_back({"main item without report ID", d.bytes(), at, "without a report ID"});
  }
  {
    Desc d;
    d.page(1).size(8).count(1).lmin(10).lmax(5).usage(0x30);
    const std::size_t at = d.offset();
    d.input(kData);
    out.push_back({"logical min above max", d.bytes(), at, "logical minimum 10 above logical maximum 5"});
  }
  {
    Bytes big(kMaxDescriptorBytes + 1, 0xB4);
    out.push_back({"too long", big, kMaxDescriptorBytes, "more than the 4096-byte maximum"});
  }
  return out;
}

TEST(HidDescriptor, MalformedDescriptorsNameTheByteOffset) {
  for (const auto& m : malformed_descriptors()) {
    std::size_t offset = 99999;
    const std::string what = error_of(m.bytes, &offset);
    EXPECT_EQ(offset, m.offset) << m.name << ": " << what;
    EXPECT_NE(what.find(m.message), std::string::npos) << m.name << ": " << what;
    EXPECT_NE(what.find("report descriptor byte " + std::to_string(m.offset)), std::string::npos) << what;
  }
}

TEST(HidDescriptor, EveryTruncationOfAValidDescriptorIsAnErrorOrAValidPrefix) {
  const Bytes full = reference_eye_tracker();
  for (std::size_t n = 0; n < full.size(); ++n) {
    const Bytes cut(full.begin(), full.begin() + static_cast<std::ptrdiff_t>(n));
    std::size_t offset = 0;
    const std::string what = error_of(cut, &offset);
    // A cut inside the top-level collection leaves it open: never a silent success. (Before the
    // first main item, the prefix is an empty but well-formed descriptor.)
    if (what == "(parsed)") {
      const auto d = parse_report_descriptor(cut);
      EXPECT_TRUE(d.reports.empty() && d.collections.empty()) << "prefix of " << n << " bytes";
    }
    EXPECT_LE(offset, n);
  }
}

// ---------------------------------------------------------------------------------------------
TEST(HidBits, ExtractsLittleEndianFieldsAtOddOffsets) {
  const Bytes data{0b10110100, 0b01101001, 0xFF, 0x00, 0x80};
  EXPECT_EQ(extract_bits(data, 0, 1), 0u);
  EXPECT_EQ(extract_bits(data, 2, 3), 0b101u);
  EXPECT_EQ(extract_bits(data, 5, 7), 0b1001101u);   // crosses the first byte boundary
  EXPECT_EQ(extract_bits(data, 4, 20), 0xFF69Bu);
  EXPECT_EQ(extract_bits(data, 39, 1), 1u);
  EXPECT_FALSE(extract_bits(data, 39, 2).has_value());  // one bit past the end
  EXPECT_FALSE(extract_bits(data, 41, 1).has_value());
  EXPECT_FALSE(extract_bits(data, 0, 0).has_value());
  EXPECT_FALSE(extract_bits(data, 0, 65).has_value());
  EXPECT_FALSE(extract_bits(data, std::numeric_limits<std::uint64_t>::max(), 8).has_value());
  EXPECT_FALSE(extract_bits({}, 0, 1).has_value());
  const Bytes eight{1, 2, 3, 4, 5, 6, 7, 0x88};
  EXPECT_EQ(extract_bits(eight, 0, 64), 0x8807060504030201u);
}

TEST(HidBits, SignExtension) {
  EXPECT_EQ(sign_extend(0xFFF, 12), -1);
  EXPECT_EQ(sign_extend(0x800, 12), -2048);
  EXPECT_EQ(sign_extend(0x7FF, 12), 2047);
  EXPECT_EQ(sign_extend(1, 1), -1);
  EXPECT_EQ(sign_extend(0x80000000u, 32), std::numeric_limits<std::int32_t>::min());
  EXPECT_EQ(sign_extend(0xFFFFFFFFFFFFFFFFu, 64), -1);
  EXPECT_EQ(sign_extend(0x1F0, 8), -16);  // bits above the size are ignored
}

// ---------------------------------------------------------------------------------------------
TEST(HidEyeTracker, MapsTheReferenceDescriptor) {
  const auto layout = map_eye_tracker(parse_report_descriptor(reference_eye_tracker()));
  EXPECT_TRUE(layout.uses_report_ids);
  EXPECT_EQ(layout.gaze_report_id, 0x10);
  EXPECT_EQ(layout.gaze_report_size, 44u);
  EXPECT_EQ(layout.gaze_x.bit_offset, 88u);
  EXPECT_EQ(layout.gaze_y.bit_offset, 120u);
  EXPECT_TRUE(layout.gaze_x.is_signed);
  ASSERT_TRUE(layout.timestamp);
  EXPECT_EQ(layout.timestamp->bit_offset, 24u);
  EXPECT_EQ(layout.timestamp->bit_size, 64u);  // 8 one-byte elements joined
  EXPECT_DOUBLE_EQ(layout.timestamp_tick_s, 1e-6);
  ASSERT_TRUE(layout.left_eye);
  ASSERT_TRUE(layout.right_eye);
  EXPECT_EQ(layout.left_eye->z.bit_offset, 216u);
  EXPECT_EQ(layout.right_eye->x.bit_offset, 248u);
  EXPECT_FALSE(layout.input_status);
  ASSERT_TRUE(layout.screen_width);
  EXPECT_EQ(layout.screen_width->report_id, 0x12);
  EXPECT_EQ(layout.screen_width->bit_offset, 88u);
  EXPECT_EQ(layout.screen_height->bit_offset, 120u);
  ASSERT_TRUE(layout.sampling_frequency);
  EXPECT_EQ(layout.sampling_frequency->report_id, 0x13);
  ASSERT_TRUE(layout.configuration_status);
  ASSERT_TRUE(layout.tracker_quality);
  EXPECT_NE(layout.summary().find("gaze point in Input report 16"), std::string::npos) << layout.summary();
}

TEST(HidEyeTracker, DecodesKnownValues) {
  EyeTrackerDecoder decoder(map_eye_tracker(parse_report_descriptor(reference_eye_tracker())));
  const auto report = reference_gaze_report(0x0102030405060708u, 265650, 149450, {-32000, 1000, 600000},
                                            {32000, 1000, 610000});
  ASSERT_EQ(report.size(), 44u);
  GazeReport g;
  ASSERT_EQ(decoder.decode(report, g), DecodeResult::Gaze);
  ASSERT_TRUE(g.timestamp_ticks);
  EXPECT_EQ(*g.timestamp_ticks, 0x0102030405060708u);
  EXPECT_TRUE(g.gaze_valid);
  EXPECT_NEAR(g.gaze_x_m, 0.26565, 1e-12);
  EXPECT_NEAR(g.gaze_y_m, 0.14945, 1e-12);
  EXPECT_TRUE(g.left.valid);
  EXPECT_NEAR(g.left.x_m, -0.032, 1e-12);
  EXPECT_NEAR(g.left.z_m, 0.6, 1e-12);
  EXPECT_TRUE(g.right.valid);
  EXPECT_NEAR(g.right.z_m, 0.61, 1e-12);

  const fovea::protocol::DisplayGeometry display;  // 531.3 x 298.9 mm at 650 mm
  const auto s = to_gaze_sample(g, display, 123456789);
  EXPECT_EQ(s.tracker_time_ns, 123456789);
  EXPECT_NEAR(s.x, 0.5, 1e-6);
  EXPECT_NEAR(s.y, 0.5, 1e-6);
  EXPECT_NEAR(s.x_deg, 0.0, 1e-4);
  EXPECT_EQ(s.flags, fovea::protocol::kGazeValid);
  EXPECT_EQ(s.confidence, 1.0f);
  EXPECT_EQ(s.left.flags, fovea::protocol::kEyePupilValid);
  EXPECT_EQ(s.right.flags, fovea::protocol::kEyePupilValid);

  // Top-left corner: visual angle by the display geometry.
  const auto corner = reference_gaze_report(1, 0, 0, {0, 0, 0}, {0, 0, 0});
  ASSERT_EQ(decoder.decode(corner, g), DecodeResult::Gaze);
  const auto c = to_gaze_sample(g, display, 0);
  const auto expect = fovea::protocol::normalized_to_degrees(display, {0, 0});
  EXPECT_NEAR(c.x, 0.0, 1e-9);
  EXPECT_NEAR(c.x_deg, expect.x, 1e-4);
  EXPECT_NEAR(c.y_deg, expect.y, 1e-4);
  EXPECT_LT(c.x_deg, -20);
  EXPECT_EQ(c.left.flags, 0);  // an eye at the origin is an eye not seen
  EXPECT_EQ(decoder.counters().gaze, 2u);
}

TEST(HidEyeTracker, CalibratedScreenSizeFromTheConfigurationReport) {
  const auto layout = map_eye_tracker(parse_report_descriptor(reference_eye_tracker()));
  Report config(0x12);
  config.put(0, 8).put(0x10AC, 16).put(0xA0B1, 16).put(12345, 32).put(0x1E20, 16).put(597900, 32).put(336300, 32);
  const auto screen = calibrated_screen_m(layout, config.bytes());
  ASSERT_TRUE(screen);
  EXPECT_NEAR(screen->first, 0.5979, 1e-12);
  EXPECT_NEAR(screen->second, 0.3363, 1e-12);
  // Wrong report ID, too short, zero size: no screen size (the configured display applies).
  Bytes wrong_id = config.bytes();
  wrong_id[0] = 0x13;
  EXPECT_FALSE(calibrated_screen_m(layout, wrong_id));
  Bytes short_report = config.bytes();
  short_report.resize(10);
  EXPECT_FALSE(calibrated_screen_m(layout, short_report));
  Report zero(0x12);
  zero.put(0, 152);
  EXPECT_FALSE(calibrated_screen_m(layout, zero.bytes()));

  Report status(0x13);
  status.put(0, 8).put(4, 8).put(90, 16);
  EXPECT_EQ(feature_value(*layout.configuration_status, status.bytes()), 4);
  EXPECT_EQ(feature_value(*layout.sampling_frequency, status.bytes()), 90);
}

TEST(HidEyeTracker, OddBitOffsetsSignedFieldsUnitsAndStatus) {
  const auto layout = map_eye_tracker(parse_report_descriptor(packed_eye_tracker()));
  EXPECT_FALSE(layout.uses_report_ids);
  EXPECT_EQ(layout.gaze_report_size, 6u);
  EXPECT_EQ(layout.gaze_x.bit_offset, 19u);
  EXPECT_EQ(layout.gaze_y.bit_offset, 31u);
  EXPECT_EQ(layout.gaze_x.bit_size, 12u);
  EXPECT_EQ(layout.timestamp->bit_offset, 3u);
  EXPECT_EQ(layout.timestamp->bit_size, 16u);
  ASSERT_TRUE(layout.input_status);
  EXPECT_EQ(layout.input_status->bit_offset, 43u);
  EXPECT_FALSE(layout.left_eye);

  EyeTrackerDecoder decoder(layout);
  GazeReport g;
  // x = -1000 * 0.1 mm = -0.1 m (left of the screen), y = 1500 * 0.1 mm = 0.15 m.
  ASSERT_EQ(decoder.decode(packed_report(0xBEEF, -1000, 1500, 1), g), DecodeResult::Gaze);
  EXPECT_EQ(g.timestamp_ticks, 0xBEEFu);
  EXPECT_TRUE(g.gaze_valid);
  EXPECT_NEAR(g.gaze_x_m, -0.1, 1e-12);
  EXPECT_NEAR(g.gaze_y_m, 0.15, 1e-12);
  EXPECT_EQ(g.status, 1);
  fovea::protocol::DisplayGeometry display;
  display.width_m = 0.5;
  display.height_m = 0.3;
  auto s = to_gaze_sample(g, display, 0);
  EXPECT_NEAR(s.x, -0.2, 1e-6);  // off-screen gaze is still gaze
  EXPECT_NEAR(s.y, 0.5, 1e-6);
  EXPECT_EQ(s.flags, fovea::protocol::kGazeValid);

  // The tracker says it needs calibration: the sample is not valid, held at the given point.
  ASSERT_EQ(decoder.decode(packed_report(1, 100, 100, eht::StatusUserCalibrationNeeded), g), DecodeResult::Gaze);
  s = to_gaze_sample(g, display, 0, {0.25, 0.75});
  EXPECT_EQ(s.flags, 0);
  EXPECT_EQ(s.confidence, 0.0f);
  EXPECT_FLOAT_EQ(s.x, 0.25f);
  EXPECT_FLOAT_EQ(s.y, 0.75f);

  // The extremes of a signed 12-bit field; a status outside the known values (7) is kept raw.
  ASSERT_EQ(decoder.decode(packed_report(1, -2048, 2047, 7), g), DecodeResult::Gaze);
  EXPECT_TRUE(g.gaze_valid);
  EXPECT_NEAR(g.gaze_x_m, -0.2048, 1e-12);
  EXPECT_EQ(g.status, 7);  // raw: unknown statuses do not invalidate
  EXPECT_EQ(to_gaze_sample(g, display, 0).flags, fovea::protocol::kGazeValid);
}

TEST(HidEyeTracker, OutOfLogicalRangeMeansNoData) {
  Desc d;
  d.page(0x12).usage(0x01).collection(CollectionKind::Application);
  d.usage(0x24).collection(CollectionKind::Physical).lmin(0).lmax(600000).size(32).count(2);
  d.usage(0x21).usage(0x22).input(kData | flag::NullState).end().end();
  EyeTrackerDecoder decoder(map_eye_tracker(parse_report_descriptor(d.bytes())));
  GazeReport g;
  ASSERT_EQ(decoder.decode(Report().put(0xFFFFFFFF, 32).put(1000, 32).bytes(), g), DecodeResult::Gaze);
  EXPECT_FALSE(g.gaze_valid);
  EXPECT_EQ(to_gaze_sample(g, {}, 0).flags, 0);
  ASSERT_EQ(decoder.decode(Report().put(600000, 32).put(1000, 32).bytes(), g), DecodeResult::Gaze);
  EXPECT_TRUE(g.gaze_valid);
}

TEST(HidEyeTracker, PhysicalRangeScales) {
  Desc d;
  d.page(0x12).usage(0x01).collection(CollectionKind::Application);
  d.usage(0x24).collection(CollectionKind::Physical).lmin(0).lmax(1000).pmin(0).pmax(500000).size(16).count(2);
  d.usage(0x21).usage(0x22).input(kData).end().end();
  EyeTrackerDecoder decoder(map_eye_tracker(parse_report_descriptor(d.bytes())));
  GazeReport g;
  ASSERT_EQ(decoder.decode(Report().put(500, 16).put(1000, 16).bytes(), g), DecodeResult::Gaze);
  EXPECT_NEAR(g.gaze_x_m, 0.25, 1e-12);  // 500/1000 of 500000 um
  EXPECT_NEAR(g.gaze_y_m, 0.5, 1e-12);
  EXPECT_FALSE(g.timestamp_ticks);
}

TEST(HidEyeTracker, NonLengthUnitsAreRejected) {
  Desc d;
  d.page(0x12).usage(0x01).collection(CollectionKind::Application);
  d.unit(0x1001).usage(0x24).collection(CollectionKind::Physical).lmin(0).lmax(1000).size(16).count(2);
  d.usage(0x21).usage(0x22).input(kData).end().end();
  try {
    (void)map_eye_tracker(parse_report_descriptor(d.bytes()));
    FAIL();
  } catch (const NotAnEyeTracker& e) {
    EXPECT_NE(std::string(e.what()).find("unit 0x1001, which is not a length"), std::string::npos) << e.what();
  }
  ValueLocation inch;
  inch.unit = 0x13;  // English linear, inch
  EXPECT_NEAR(*length_m(inch, 10), 0.254, 1e-12);
  ValueLocation ms;
  ms.unit = 0x1001;
  ms.unit_exponent = -3;
  EXPECT_NEAR(*tick_seconds(ms), 1e-3, 1e-15);
  EXPECT_FALSE(length_m(ms, 1));
}

TEST(HidEyeTracker, MultipleReportIdsAndRejectedReports) {
  EyeTrackerDecoder decoder(map_eye_tracker(parse_report_descriptor(two_report_eye_tracker())));
  EXPECT_EQ(decoder.layout().gaze_report_id, 2);
  EXPECT_EQ(decoder.layout().gaze_report_size, 9u);
  GazeReport g;
  EXPECT_EQ(decoder.decode(Report(1).put(1, 16).put(2, 16).put(3, 16).bytes(), g), DecodeResult::OtherReport);
  EXPECT_EQ(decoder.decode(Report(2).put(100000, 32).put(50000, 32).bytes(), g), DecodeResult::Gaze);
  EXPECT_NEAR(g.gaze_x_m, 0.1, 1e-12);
  EXPECT_EQ(decoder.decode(Report(3).put(1, 64).bytes(), g), DecodeResult::UnknownReportId);
  EXPECT_EQ(decoder.decode(Report(2).put(100000, 32).put(5, 24).bytes(), g), DecodeResult::TooShort);
  EXPECT_FALSE(g.gaze_valid);
  EXPECT_EQ(decoder.decode(Bytes{}, g), DecodeResult::Empty);
  EXPECT_EQ(decoder.decode(Bytes{2}, g), DecodeResult::TooShort);
  // Longer than declared: accepted, the tail ignored (as the kernel does).
  EXPECT_EQ(decoder.decode(Report(2).put(100000, 32).put(50000, 32).put(0xFFFF, 16).bytes(), g), DecodeResult::Gaze);
  EXPECT_NEAR(g.gaze_y_m, 0.05, 1e-12);
  const auto& c = decoder.counters();
  EXPECT_EQ(c.gaze, 2u);
  EXPECT_EQ(c.other, 1u);
  EXPECT_EQ(c.unknown_id, 1u);
  EXPECT_EQ(c.too_short, 2u);
  EXPECT_EQ(c.empty, 1u);
  EXPECT_EQ(c.rejected(), 4u);
}

TEST(HidEyeTracker, RandomReportsNeverMisbehave) {
  for (const Bytes& desc : {reference_eye_tracker(), packed_eye_tracker(), two_report_eye_tracker()}) {
    EyeTrackerDecoder decoder(map_eye_tracker(parse_report_descriptor(desc)));
    std::mt19937 rng(7);
    for (int i = 0; i < 2000; ++i) {
      Bytes r(rng() % 60);
      for (auto& b : r) b = static_cast<std::uint8_t>(rng());
      if (!r.empty() && i % 2 == 0) r[0] = decoder.layout().gaze_report_id;
      GazeReport g;
      if (decoder.decode(r, g) != DecodeResult::Gaze) continue;
      const auto s = to_gaze_sample(g, {}, 0);
      ASSERT_TRUE(std::isfinite(s.x) && std::isfinite(s.y) && std::isfinite(s.x_deg) && std::isfinite(s.y_deg));
      ASSERT_TRUE(s.flags == 0 || (s.x >= -1 && s.x <= 2 && s.y >= -1 && s.y <= 2));
    }
  }
}

// ---------------------------------------------------------------------------------------------
TEST(HidClock, FirstReportAnchorsAndCounterWrapIsUnwrapped) {
  TrackerClock clock(1e-6, 16);  // 16-bit microsecond counter: wraps every 65.5 ms
  const std::int64_t t0 = 5'000'000'000;
  for (int k = 0; k < 500; ++k) {
    const std::uint64_t ticks = (65000u + static_cast<std::uint64_t>(k) * 1000u) & 0xFFFFu;
    const std::int64_t receive = t0 + std::int64_t{k} * 1'000'000 + 2'000'000;  // constant 2 ms latency
    ASSERT_EQ(clock.map(ticks, receive), receive) << k;
  }
  EXPECT_EQ(clock.resets(), 0u);
}

TEST(HidClock, JitterIsRemovedAndSamplesAreNeverInTheFuture) {
  TrackerClock clock(1e-6, 32);
  std::mt19937 rng(3);
  const std::int64_t t0 = 1'000'000'000;
  std::int64_t last = 0;
  std::int64_t min_latency = INT64_MAX;
  for (int k = 0; k < 2000; ++k) {
    const std::int64_t truth = t0 + std::int64_t{k} * 4'000'000;  // 250 Hz
    const std::int64_t latency = 1'000'000 + static_cast<std::int64_t>(rng() % 3'000'000);
    min_latency = std::min(min_latency, latency);
    const std::int64_t mapped = clock.map(static_cast<std::uint64_t>(k) * 4000u, truth + latency);
    ASSERT_LE(mapped, truth + latency);
    ASSERT_GE(mapped, last);
    last = mapped;
    // Settled: the offset is the least latency of the last second, 1..4 ms of jitter down to
    // within 0.3 ms of the least seen.
    if (k > 1000) {
      ASSERT_GE(mapped - truth, min_latency) << k;
      ASSERT_LE(mapped - truth, min_latency + 300'000) << k;
    }
  }
}

TEST(HidClock, FollowsASlowTrackerClockWithinItsDriftAllowance) {
  TrackerClock clock(1e-6, 64);
  const std::int64_t t0 = 0;
  for (int k = 0; k < 60 * 250; ++k) {  // one minute at 250 Hz, tracker 200 ppm slow
    const std::int64_t host = t0 + std::int64_t{k} * 4'000'000;
    const auto ticks = static_cast<std::uint64_t>(static_cast<double>(k) * 4000.0 * (1 - 200e-6));
    const std::int64_t receive = host + 1'000'000;
    const std::int64_t mapped = clock.map(ticks, receive);
    ASSERT_LE(mapped, receive);
    ASSERT_GE(mapped, receive - 300'000) << k;  // lag: drift x 1 s window = 0.2 ms
    if (k == 250) {
      EXPECT_FALSE(clock.drift_ppm()) << "a drift from one window";
    }
  }
  EXPECT_EQ(clock.resets(), 0u);
  // The offset host - tracker grows by 200 us per second: +200 ppm, found within 1 ppm.
  ASSERT_TRUE(clock.drift_ppm());
  EXPECT_NEAR(*clock.drift_ppm(), 200.0, 1.0);
}

TEST(HidClock, ResetsAndGapsReanchor) {
  TrackerClock clock(1e-6, 32);
  EXPECT_FALSE(clock.anchored());  // what a status line must not show as an offset of 0
  EXPECT_EQ(clock.map(1'000'000, 10'000'000'000), 10'000'000'000);
  EXPECT_TRUE(clock.anchored());
  EXPECT_EQ(clock.map(1'004'000, 10'004'000'000), 10'004'000'000);
  EXPECT_EQ(clock.map(10, 10'008'000'000), 10'008'000'000);  // counter went backwards: reset
  EXPECT_EQ(clock.resets(), 1u);
  EXPECT_EQ(clock.map(4010, 10'012'000'000), 10'012'000'000);
  EXPECT_EQ(clock.map(100'004'010, 10'016'000'000), 10'016'000'000);  // 100 s jump in 4 ms
  EXPECT_EQ(clock.resets(), 2u);
  clock.reset();  // reconnect: next report anchors afresh (not counted as a reset)
  EXPECT_FALSE(clock.anchored());
  EXPECT_EQ(clock.map(7, 20'000'000'000), 20'000'000'000);
  EXPECT_EQ(clock.resets(), 2u);
}

// ---------------------------------------------------------------------------------------------
TEST(HidSpecs, ParsesSpecs) {
  EXPECT_FALSE(parse_hid_spec("hid").vendor_id);
  const auto s = parse_hid_spec("hid:2104:0313");
  EXPECT_EQ(s.vendor_id, 0x2104);
  EXPECT_EQ(s.product_id, 0x0313);
  EXPECT_EQ(parse_hid_spec("hid:0x2104:0XaBc").product_id, 0x0ABC);
  for (const char* bad : {"hid:", "hid:2104", "hid:2104:", "hid:zz:1", "hid:12345:1", "usb:1:2", "hid:1:2:3", ""}) {
    try {
      (void)parse_hid_spec(bad);
      FAIL() << bad;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("hid:VID:PID"), std::string::npos) << e.what();
    }
  }
}

TEST(HidSpecs, HidrawDescriptorPath) {
  EXPECT_EQ(hidraw_descriptor_path("/dev/hidraw3"), "/sys/class/hidraw/hidraw3/device/report_descriptor");
  EXPECT_EQ(hidraw_descriptor_path("/dev/hidraw12", "/tmp/sys"), "/tmp/sys/class/hidraw/hidraw12/device/report_descriptor");
  EXPECT_EQ(hidraw_descriptor_path("/dev/hidraw"), "");
  EXPECT_EQ(hidraw_descriptor_path("/dev/hidraw1/../../etc"), "");
  EXPECT_EQ(hidraw_descriptor_path("1-2:1.0"), "");
}

TEST(HidSpecs, UserFacingMessages) {
  std::vector<HidDeviceSummary> present;
  present.push_back({"/dev/hidraw0", 0x046d, 0xc52b, 0x01, 0x02, "Logitech", "USB Receiver"});
  present.push_back({"/dev/hidraw0", 0x046d, 0xc52b, 0x01, 0x06, "Logitech", "USB Receiver"});
  present.push_back({"/dev/hidraw1", 0x1050, 0x0407, 0xF1D0, 0x01, "Yubico", "YubiKey"});
  const std::string m = no_eye_tracker_message({}, present);
  EXPECT_NE(m.find("none of the 2 HID device(s) present"), std::string::npos) << m;
  EXPECT_NE(m.find("usage page 0x12"), std::string::npos) << m;
  EXPECT_NE(m.find("/dev/hidraw0  046d:c52b Logitech USB Receiver  [Generic Desktop / Mouse (0x01:0x02), "
                   "Generic Desktop / Keyboard (0x01:0x06)]"),
            std::string::npos)
      << m;
  EXPECT_NE(m.find("FIDO Alliance"), std::string::npos) << m;
  EXPECT_NE(no_eye_tracker_message({}, {}).find("no HID devices are present"), std::string::npos);
  EXPECT_NE(no_eye_tracker_message(parse_hid_spec("hid:2104:313"), {}).find("no HID device 2104:0313 found"),
            std::string::npos);

  const std::string p = permission_message("/dev/hidraw3", {"/dev/hidraw3", 0x2104, 0x0313, 0x12, 0x01, "Acme", "Eye"});
  EXPECT_NE(p.find("permission denied opening /dev/hidraw3 (2104:0313 Acme Eye)"), std::string::npos) << p;
  EXPECT_NE(p.find("deploy/70-fovea-trackers.rules"), std::string::npos) << p;
  EXPECT_NE(p.find("'fovea' group"), std::string::npos) << p;
}

TEST(HidSource, AbsentDeviceIsAClearError) {
  // No device has vendor:product ffff:fffe; whatever this machine has, that is a clean failure.
  try {
    (void)fovea::trackerd::make_hid_source("hid:ffff:fffe", {});
    FAIL() << "opened a device that cannot exist";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("ffff:fffe"), std::string::npos) << e.what();
  }
  EXPECT_THROW((void)fovea::trackerd::make_hid_source("hid:nope", {}), std::invalid_argument);
}

// The fuzz corpus holds the hand-built descriptors above; FOVEA_WRITE_HID_CORPUS=DIR rewrites it.
TEST(HidCorpus, HoldsTheHandBuiltDescriptors) {
  const char* dir = std::getenv("FOVEA_WRITE_HID_CORPUS");
  if (!dir) {
    const std::filesystem::path corpus = std::filesystem::path(FOVEA_SOURCE_DIR) / "tests/fuzz/corpus/hid_descriptor";
    const auto read = [&](const char* name) {
      std::ifstream in(corpus / name, std::ios::binary);
      return Bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    };
    EXPECT_EQ(read("reference_eye_tracker.bin"), reference_eye_tracker());
    EXPECT_EQ(read("packed_eye_tracker.bin"), packed_eye_tracker());
    EXPECT_EQ(read("two_report_eye_tracker.bin"), two_report_eye_tracker());
    EXPECT_EQ(read("boot_mouse.bin"), boot_mouse());
    EXPECT_EQ(read("boot_keyboard.bin"), boot_keyboard());
    return;
  }
  std::filesystem::create_directories(dir);
  const auto write = [&](const std::string& name, const Bytes& b) {
    std::ofstream out(std::filesystem::path(dir) / name, std::ios::binary);
    out.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
  };
  write("reference_eye_tracker.bin", reference_eye_tracker());
  write("packed_eye_tracker.bin", packed_eye_tracker());
  write("two_report_eye_tracker.bin", two_report_eye_tracker());
  write("boot_mouse.bin", boot_mouse());
  write("boot_keyboard.bin", boot_keyboard());
  Bytes cut = reference_eye_tracker();
  cut.resize(cut.size() / 2);
  write("reference_truncated_half.bin", cut);
  Bytes cut_item = reference_eye_tracker();
  cut_item.resize(60);
  write("reference_truncated_item.bin", cut_item);
  Bytes flipped = reference_eye_tracker();
  flipped[flipped.size() / 3] ^= 0x5A;
  write("reference_flipped.bin", flipped);
  Bytes resized = packed_eye_tracker();
  resized[10] = 0x75;  // an item prefix where data was
  write("packed_mutated.bin", resized);
  int i = 0;
  for (const auto& m : malformed_descriptors()) {
    if (m.bytes.size() > 512) continue;
    write("malformed_" + std::to_string(i++) + ".bin", m.bytes);
  }
}

}  // namespace
