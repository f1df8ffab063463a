// SPDX-License-Identifier: Apache-2.0
#pragma once
// A general HID report descriptor parser (Device Class Definition for HID 1.11, §6.2.2): turns the
// item stream into report layouts — for each report type and ID, the fields with their bit offsets,
// sizes, usages, ranges, units and collection paths — and extracts field values from raw reports.
//
// Strict and safe: a malformed descriptor (truncated item, Pop without Push, unbalanced collections,
// report size 0 or > 32, a report longer than the kernel's 16 KiB limit, reserved items, ...) throws
// DescriptorError naming the byte offset of the offending item. Nothing a descriptor says can make
// the parser read out of bounds, overflow or allocate without bound (every list it grows is bounded
// by the descriptor's length or a documented cap).
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace fovea::trackerd::hid {

// Usage page in the high 16 bits, usage ID in the low 16 bits ("extended usage").
using Usage = std::uint32_t;
constexpr Usage make_usage(std::uint16_t page, std::uint16_t id) {
  return (static_cast<Usage>(page) << 16) | id;
}
constexpr std::uint16_t usage_page(Usage u) { return static_cast<std::uint16_t>(u >> 16); }
constexpr std::uint16_t usage_id(Usage u) { return static_cast<std::uint16_t>(u & 0xFFFFu); }

// Limits (the Linux kernel's where it has one).
inline constexpr std::size_t kMaxDescriptorBytes = 4096;       // HID_MAX_DESCRIPTOR_SIZE
inline constexpr std::uint32_t kMaxReportBits = 16384u * 8u;    // HID_MAX_BUFFER_SIZE bytes
inline constexpr std::size_t kMaxGlobalStackDepth = 16;
inline constexpr std::size_t kMaxCollectionDepth = 32;
inline constexpr std::size_t kMaxUsagesPerMainItem = 1024;     // usage items (a range is one)

class DescriptorError : public std::runtime_error {
 public:
  DescriptorError(std::size_t offset, const std::string& what);
  std::size_t offset() const { return offset_; }

 private:
  std::size_t offset_;
};

enum class ReportType : std::uint8_t { Input = 0, Output = 1, Feature = 2 };
const char* to_string(ReportType t);

enum class CollectionKind : std::uint8_t {
  Physical = 0, Application = 1, Logical = 2, Report = 3, NamedArray = 4, UsageSwitch = 5, UsageModifier = 6,
};  // 0x07-0x7F reserved (rejected), 0x80-0xFF vendor-defined (kept as their raw value)
std::string to_string(CollectionKind k);

struct Collection {
  std::uint8_t kind = 0;             // CollectionKind or a vendor value 0x80-0xFF
  std::optional<Usage> usage;        // the first local usage before the Collection item
  int parent = -1;                   // index into ReportDescriptor::collections, -1 at top level
  std::size_t offset = 0;            // byte offset of the Collection item
};

// Main item data bits (HID 1.11 §6.2.2.5).
namespace flag {
inline constexpr std::uint32_t Constant = 1u << 0;
inline constexpr std::uint32_t Variable = 1u << 1;
inline constexpr std::uint32_t Relative = 1u << 2;
inline constexpr std::uint32_t Wrap = 1u << 3;
inline constexpr std::uint32_t NonLinear = 1u << 4;
inline constexpr std::uint32_t NoPreferred = 1u << 5;
inline constexpr std::uint32_t NullState = 1u << 6;
inline constexpr std::uint32_t Volatile = 1u << 7;
inline constexpr std::uint32_t BufferedBytes = 1u << 8;
}  // namespace flag

// One Usage item or one Usage Minimum/Maximum pair, resolved to extended usages.
struct UsageRange {
  Usage min = 0, max = 0;  // min == max for a single usage
  std::uint32_t size() const { return usage_id(max) - usage_id(min) + 1u; }
};

// One Input/Output/Feature main item: `count` elements of `bit_size` bits, packed little-endian
// from `bit_offset` (counted from the first data bit, i.e. after the report ID byte if any).
struct Field {
  ReportType type = ReportType::Input;
  std::uint8_t report_id = 0;     // 0 when the descriptor uses no report IDs
  std::uint32_t bit_offset = 0;
  std::uint32_t bit_size = 0;     // 1..32
  std::uint32_t count = 0;
  std::uint32_t flags = 0;        // flag::*
  std::vector<UsageRange> usages; // in declaration order; empty for padding
  std::int64_t logical_min = 0, logical_max = 0;
  std::int64_t physical_min = 0, physical_max = 0;  // both 0: physical = logical
  std::uint32_t unit = 0;         // HID unit code (0: none)
  std::int8_t unit_exponent = 0;
  int collection = -1;            // innermost enclosing collection, -1 if none
  std::size_t offset = 0;         // byte offset of the main item in the descriptor

  bool is_constant() const { return (flags & flag::Constant) != 0; }
  bool is_variable() const { return (flags & flag::Variable) != 0; }
  bool is_signed() const { return logical_min < 0; }
  // The usage of element `index` of a Variable field: usages are assigned in order (ranges
  // expanded); elements beyond the last usage repeat the last one (HID 1.11 §6.2.2.8).
  std::optional<Usage> usage_of(std::uint32_t index) const;
  // The first element index whose usage is `u` (nullopt if none within `count`); O(usage items).
  std::optional<std::uint32_t> index_of(Usage u) const;
  std::uint32_t bit_length() const { return bit_size * count; }
};

struct ReportLayout {
  ReportType type = ReportType::Input;
  std::uint8_t id = 0;
  std::uint32_t bit_length = 0;  // of the data after the report ID byte
  std::vector<Field> fields;
  // Bytes on the wire, including the report ID byte when the descriptor uses IDs.
  std::size_t wire_size(bool uses_report_ids) const { return (bit_length + 7u) / 8u + (uses_report_ids ? 1u : 0u); }
};

struct ReportDescriptor {
  bool uses_report_ids = false;
  std::vector<Collection> collections;
  std::vector<ReportLayout> reports;  // in order of first appearance

  const ReportLayout* find(ReportType type, std::uint8_t id) const;
  // Collection indices from the outermost to `collection` (empty for -1).
  std::vector<int> collection_path(int collection) const;
  bool path_contains(int collection, Usage usage) const;
  // Top-level Application collections' usages, in order.
  std::vector<Usage> application_usages() const;
};

// Parses a report descriptor; throws DescriptorError (with the byte offset) if it is malformed.
ReportDescriptor parse_report_descriptor(std::span<const std::uint8_t> bytes);

// Little-endian bit extraction: `bit_size` (1..64) bits starting at `bit_offset` of `data`.
// Returns nullopt when the bits are not all inside `data` (never reads out of bounds).
std::optional<std::uint64_t> extract_bits(std::span<const std::uint8_t> data, std::uint64_t bit_offset,
                                          std::uint32_t bit_size);
// Two's-complement sign extension of a `bit_size`-bit value (1..64).
std::int64_t sign_extend(std::uint64_t value, std::uint32_t bit_size);

// Element `index` of `field` from report data (after the report ID byte), sign-extended when the
// field's logical minimum is negative; nullopt if out of bounds.
std::optional<std::int64_t> field_value(const Field& field, std::span<const std::uint8_t> data, std::uint32_t index);

// "Generic Desktop" etc. for the pages a user is likely to meet; "0xFF00 (vendor)" otherwise.
std::string usage_page_name(std::uint16_t page);
// "Generic Desktop / Mouse (0x01:0x02)", with names for the usages fovea knows.
std::string describe_usage(Usage u);

}  // namespace fovea::trackerd::hid
