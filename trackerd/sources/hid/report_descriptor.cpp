// SPDX-License-Identifier: Apache-2.0
#include "sources/hid/report_descriptor.h"

#include <algorithm>
#include <cstdio>

#include "sources/hid/usage_tables.h"

namespace fovea::trackerd::hid {

namespace {

std::string hex(std::uint32_t v, int digits) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "0x%0*X", digits, v);
  return buf;
}

// Names of short items by prefix with the size bits masked off, for error messages.
const char* item_name(std::uint8_t type, std::uint8_t tag) {
  static constexpr const char* kMain[16] = {nullptr, nullptr, nullptr, nullptr, nullptr, nullptr, nullptr, nullptr,
                                            "Input", "Output", "Collection", "Feature", "End Collection",
                                            nullptr, nullptr, nullptr};
  static constexpr const char* kGlobal[16] = {"Usage Page", "Logical Minimum", "Logical Maximum",
                                              "Physical Minimum", "Physical Maximum", "Unit Exponent", "Unit",
                                              "Report Size", "Report ID", "Report Count", "Push", "Pop",
                                              nullptr, nullptr, nullptr, nullptr};
  static constexpr const char* kLocal[16] = {"Usage", "Usage Minimum", "Usage Maximum", "Designator Index",
                                             "Designator Minimum", "Designator Maximum", nullptr, "String Index",
                                             "String Minimum", "String Maximum", "Delimiter",
                                             nullptr, nullptr, nullptr, nullptr, nullptr};
  const char* name = nullptr;
  switch (type) {
    case 0: name = kMain[tag & 15u]; break;
    case 1: name = kGlobal[tag & 15u]; break;
    case 2: name = kLocal[tag & 15u]; break;
    default: break;
  }
  return name ? name : "reserved item";
}

struct Globals {
  std::uint16_t usage_page = 0;
  std::int64_t logical_min = 0;
  std::uint32_t logical_max_u = 0;
  std::int64_t logical_max_s = 0;
  std::int64_t physical_min = 0;
  std::uint32_t physical_max_u = 0;
  std::int64_t physical_max_s = 0;
  std::int8_t unit_exponent = 0;
  std::uint32_t unit = 0;
  std::uint32_t report_size = 0;
  std::uint8_t report_id = 0;
  std::uint32_t report_count = 0;

  // Linux hid-core convention: a maximum is read as unsigned when the minimum is not negative,
  // because so many devices write "Logical Maximum (255)" as the one byte 0xFF.
  std::int64_t logical_max() const { return logical_min < 0 ? logical_max_s : logical_max_u; }
  std::int64_t physical_max() const { return physical_min < 0 ? physical_max_s : physical_max_u; }
};

struct PendingUsage {
  std::uint32_t min = 0, max = 0;
  bool min_extended = false, max_extended = false;
  std::size_t offset = 0;
};

class Parser {
 public:
  explicit Parser(std::span<const std::uint8_t> bytes) : bytes_(bytes) {}

  ReportDescriptor run() {
    if (bytes_.empty()) throw DescriptorError(0, "empty report descriptor");
    if (bytes_.size() > kMaxDescriptorBytes) {
      throw DescriptorError(kMaxDescriptorBytes, "report descriptor is " + std::to_string(bytes_.size()) +
                                                     " bytes, more than the " + std::to_string(kMaxDescriptorBytes) +
                                                     "-byte maximum");
    }
    std::size_t pos = 0;
    while (pos < bytes_.size()) {
      const std::uint8_t prefix = bytes_[pos];
      if (prefix == 0xFE) {  // long item: 0xFE, bDataSize, bLongItemTag, data (no long items are defined)
        if (bytes_.size() - pos < 3) throw DescriptorError(pos, "truncated long item header");
        const std::size_t size = bytes_[pos + 1];
        if (bytes_.size() - pos - 3 < size) {
          throw DescriptorError(pos, "truncated long item: " + std::to_string(size) + " data bytes declared, " +
                                         std::to_string(bytes_.size() - pos - 3) + " left");
        }
        pos += 3 + size;
        continue;
      }
      const std::size_t size = (prefix & 3u) == 3u ? 4u : (prefix & 3u);
      const auto type = static_cast<std::uint8_t>((prefix >> 2) & 3u);
      const auto tag = static_cast<std::uint8_t>(prefix >> 4);
      offset_ = pos;
      item_ = item_name(type, tag);
      if (bytes_.size() - pos - 1 < size) {
        fail(std::string("truncated item: ") + std::to_string(size) + " data bytes declared, " +
             std::to_string(bytes_.size() - pos - 1) + " left");
      }
      std::uint32_t udata = 0;
      for (std::size_t i = 0; i < size; ++i) udata |= static_cast<std::uint32_t>(bytes_[pos + 1 + i]) << (8 * i);
      const std::int64_t sdata = size == 0 ? 0 : sign_extend(udata, static_cast<std::uint32_t>(8 * size));
      data_size_ = size;
      switch (type) {
        case 0: main_item(tag, udata); break;
        case 1: global_item(tag, udata, sdata); break;
        case 2: local_item(tag, udata); break;
        default: fail("reserved item type 3 (prefix " + hex(prefix, 2) + ")");
      }
      pos += 1 + size;
    }
    offset_ = bytes_.size();
    item_ = "end of descriptor";
    if (!open_.empty()) {
      fail(std::to_string(open_.size()) + " collection(s) not closed; the innermost opened at byte " +
           std::to_string(out_.collections[static_cast<std::size_t>(open_.back())].offset));
    }
    if (delimiter_open_) fail("Delimiter set not closed");
    return std::move(out_);
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw DescriptorError(offset_, std::string(item_) + ": " + what);
  }

  void global_item(std::uint8_t tag, std::uint32_t udata, std::int64_t sdata) {
    switch (tag) {
      case 0:
        if (udata > 0xFFFF) fail("usage page " + hex(udata, 8) + " does not fit 16 bits");
        g_.usage_page = static_cast<std::uint16_t>(udata);
        break;
      case 1: g_.logical_min = sdata; break;
      case 2: g_.logical_max_u = udata; g_.logical_max_s = sdata; break;
      case 3: g_.physical_min = sdata; break;
      case 4: g_.physical_max_u = udata; g_.physical_max_s = sdata; break;
      case 5:
        // HID 1.11: a 4-bit two's-complement nibble; some devices write a full signed byte.
        if (udata <= 0xF) {
          g_.unit_exponent = static_cast<std::int8_t>(sign_extend(udata, 4));
        } else if (sdata >= -127 && sdata <= 127) {
          g_.unit_exponent = static_cast<std::int8_t>(sdata);
        } else {
          fail("unit exponent " + std::to_string(sdata) + " (allowed -127..127)");
        }
        break;
      case 6: g_.unit = udata; break;
      case 7:
        if (udata == 0 || udata > 32) fail("report size " + std::to_string(udata) + " bits (allowed 1..32)");
        g_.report_size = udata;
        break;
      case 8:
        if (udata == 0 || udata > 255) fail("report ID " + std::to_string(udata) + " (allowed 1..255)");
        if (!out_.uses_report_ids && fields_without_id_) {
          fail("report ID " + std::to_string(udata) + " after main items that had no report ID (at byte " +
               std::to_string(first_field_without_id_) + ")");
        }
        out_.uses_report_ids = true;
        g_.report_id = static_cast<std::uint8_t>(udata);
        break;
      case 9:
        if (udata > kMaxReportBits) {
          fail("report count " + std::to_string(udata) + " (allowed 0.." + std::to_string(kMaxReportBits) + ")");
        }
        g_.report_count = udata;
        break;
      case 10:
        if (data_size_ != 0) fail("Push carries data");
        if (stack_.size() >= kMaxGlobalStackDepth) {
          fail("global stack deeper than " + std::to_string(kMaxGlobalStackDepth));
        }
        stack_.push_back(g_);
        break;
      case 11:
        if (data_size_ != 0) fail("Pop carries data");
        if (stack_.empty()) fail("Pop without Push");
        g_ = stack_.back();
        stack_.pop_back();
        break;
      default: fail("reserved global item tag " + hex(tag, 1));
    }
  }

  void local_item(std::uint8_t tag, std::uint32_t udata) {
    const bool extended = data_size_ == 4;
    switch (tag) {
      case 0:
        if (take_usage()) add_usage(PendingUsage{udata, udata, extended, extended, offset_});
        break;
      case 1:
      case 2: {
        if (!take_usage()) break;
        auto& half = tag == 1 ? pending_min_ : pending_max_;
        auto& other = tag == 1 ? pending_max_ : pending_min_;
        if (half) fail(std::string("second ") + item_ + " before its pair");
        half = PendingUsage{udata, udata, extended, extended, offset_};
        if (other) {
          PendingUsage r;
          r.min = pending_min_->min;
          r.min_extended = pending_min_->min_extended;
          r.max = pending_max_->max;
          r.max_extended = pending_max_->max_extended;
          r.offset = pending_min_->offset;
          pending_min_.reset();
          pending_max_.reset();
          add_usage(r);
        }
        break;
      }
      case 3: case 4: case 5: case 7: case 8: case 9: break;  // designators and strings: not needed
      case 10:
        if (udata == 1) {
          if (delimiter_open_) fail("nested Delimiter set");
          delimiter_open_ = true;
          delimiter_taken_ = false;
        } else if (udata == 0) {
          if (!delimiter_open_) fail("Delimiter close without open");
          delimiter_open_ = false;
        } else {
          fail("Delimiter value " + std::to_string(udata) + " (allowed 0 close, 1 open)");
        }
        break;
      default: fail("reserved local item tag " + hex(tag, 1));
    }
  }

  // Inside a Delimiter set only the first usage counts (the alternatives are synonyms).
  bool take_usage() {
    if (!delimiter_open_) return true;
    if (delimiter_taken_ && !pending_min_ && !pending_max_) return false;
    delimiter_taken_ = true;
    return true;
  }

  void add_usage(const PendingUsage& u) {
    if (usages_.size() >= kMaxUsagesPerMainItem) {
      fail("more than " + std::to_string(kMaxUsagesPerMainItem) + " usages before one main item");
    }
    usages_.push_back(u);
  }

  // Joins 16-bit usages with the usage page in effect at the main item (HID 1.11 §6.2.2.8).
  std::vector<UsageRange> resolve_usages() const {
    if (pending_min_ || pending_max_) {
      const std::size_t at = pending_min_ ? pending_min_->offset : pending_max_->offset;
      fail("Usage Minimum/Maximum at byte " + std::to_string(at) + " without its pair");
    }
    std::vector<UsageRange> out;
    out.reserve(usages_.size());
    for (const auto& u : usages_) {
      const std::uint32_t page_min = u.min_extended ? (u.min >> 16) : g_.usage_page;
      const std::uint32_t page_max = u.max_extended ? (u.max >> 16) : page_min;
      const std::uint32_t id_min = u.min & 0xFFFFu, id_max = u.max & 0xFFFFu;
      if (page_min != page_max) {
        fail("usage range at byte " + std::to_string(u.offset) + " spans usage pages " + hex(page_min, 4) +
             " and " + hex(page_max, 4));
      }
      if (id_min > id_max) {
        fail("usage range at byte " + std::to_string(u.offset) + " has minimum " + hex(id_min, 4) +
             " above maximum " + hex(id_max, 4));
      }
      out.push_back(UsageRange{(page_min << 16) | id_min, (page_max << 16) | id_max});
    }
    return out;
  }

  void clear_locals() {
    usages_.clear();
    pending_min_.reset();
    pending_max_.reset();
  }

  void main_item(std::uint8_t tag, std::uint32_t udata) {
    switch (tag) {
      case 8: add_field(ReportType::Input, udata); break;
      case 9: add_field(ReportType::Output, udata); break;
      case 11: add_field(ReportType::Feature, udata); break;
      case 10: {
        if (udata > 0xFF) fail("collection type " + hex(udata, 8) + " does not fit a byte");
        if (udata >= 0x07 && udata <= 0x7F) fail("reserved collection type " + hex(udata, 2));
        if (open_.size() >= kMaxCollectionDepth) {
          fail("collections nested deeper than " + std::to_string(kMaxCollectionDepth));
        }
        if (delimiter_open_) fail("Collection inside a Delimiter set");
        Collection c;
        c.kind = static_cast<std::uint8_t>(udata);
        const auto usages = resolve_usages();
        if (!usages.empty()) c.usage = usages.front().min;
        c.parent = open_.empty() ? -1 : open_.back();
        c.offset = offset_;
        out_.collections.push_back(c);
        open_.push_back(static_cast<int>(out_.collections.size() - 1));
        clear_locals();
        break;
      }
      case 12:
        if (data_size_ != 0) fail("End Collection carries data");
        if (open_.empty()) fail("End Collection without an open Collection");
        if (delimiter_open_) fail("End Collection inside a Delimiter set");
        open_.pop_back();
        clear_locals();
        break;
      default: fail("reserved main item tag " + hex(tag, 1));
    }
  }

  void add_field(ReportType type, std::uint32_t flags) {
    if (delimiter_open_) fail("main item inside a Delimiter set");
    const auto usages = resolve_usages();
    clear_locals();
    if (g_.report_count == 0) return;  // declares nothing
    if (g_.report_size == 0) fail("no Report Size before this main item");
    if (out_.uses_report_ids && g_.report_id == 0) {
      fail("main item without a report ID in a descriptor that uses report IDs");
    }
    const bool constant = (flags & flag::Constant) != 0;
    if (!constant && g_.logical_min > g_.logical_max()) {
      fail("logical minimum " + std::to_string(g_.logical_min) + " above logical maximum " +
           std::to_string(g_.logical_max()));
    }
    auto it = std::find_if(out_.reports.begin(), out_.reports.end(), [&](const ReportLayout& r) {
      return r.type == type && r.id == g_.report_id;
    });
    if (it == out_.reports.end()) {
      ReportLayout r;
      r.type = type;
      r.id = g_.report_id;
      out_.reports.push_back(std::move(r));
      it = out_.reports.end() - 1;
    }
    const std::uint64_t bits = static_cast<std::uint64_t>(g_.report_size) * g_.report_count;
    const std::uint64_t total = it->bit_length + bits;
    if (total > kMaxReportBits) {
      fail(std::string(to_string(type)) + " report " + std::to_string(g_.report_id) + " would be " +
           std::to_string(total) + " bits, more than the " + std::to_string(kMaxReportBits) + "-bit maximum");
    }
    Field f;
    f.type = type;
    f.report_id = g_.report_id;
    f.bit_offset = it->bit_length;
    f.bit_size = g_.report_size;
    f.count = g_.report_count;
    f.flags = flags;
    f.usages = usages;
    f.logical_min = g_.logical_min;
    f.logical_max = g_.logical_max();
    f.physical_min = g_.physical_min;
    f.physical_max = g_.physical_max();
    f.unit = g_.unit;
    f.unit_exponent = g_.unit_exponent;
    f.collection = open_.empty() ? -1 : open_.back();
    f.offset = offset_;
    it->bit_length = static_cast<std::uint32_t>(total);
    it->fields.push_back(std::move(f));
    if (g_.report_id == 0 && !fields_without_id_) {
      fields_without_id_ = true;
      first_field_without_id_ = offset_;
    }
  }

  std::span<const std::uint8_t> bytes_;
  std::size_t offset_ = 0;
  std::size_t data_size_ = 0;
  const char* item_ = "";
  Globals g_;
  std::vector<Globals> stack_;
  std::vector<PendingUsage> usages_;
  std::optional<PendingUsage> pending_min_, pending_max_;
  bool delimiter_open_ = false, delimiter_taken_ = false;
  std::vector<int> open_;
  bool fields_without_id_ = false;
  std::size_t first_field_without_id_ = 0;
  ReportDescriptor out_;
};

}  // namespace

DescriptorError::DescriptorError(std::size_t offset, const std::string& what)
    : std::runtime_error("report descriptor byte " + std::to_string(offset) + ": " + what), offset_(offset) {}

const char* to_string(ReportType t) {
  switch (t) {
    case ReportType::Input: return "Input";
    case ReportType::Output: return "Output";
    case ReportType::Feature: return "Feature";
  }
  return "?";
}

std::string to_string(CollectionKind k) {
  switch (k) {
    case CollectionKind::Physical: return "Physical";
    case CollectionKind::Application: return "Application";
    case CollectionKind::Logical: return "Logical";
    case CollectionKind::Report: return "Report";
    case CollectionKind::NamedArray: return "Named Array";
    case CollectionKind::UsageSwitch: return "Usage Switch";
    case CollectionKind::UsageModifier: return "Usage Modifier";
  }
  return "vendor " + hex(static_cast<std::uint32_t>(k), 2);
}

std::optional<Usage> Field::usage_of(std::uint32_t index) const {
  if (usages.empty()) return std::nullopt;
  for (const auto& r : usages) {
    if (index < r.size()) return r.min + index;
    index -= r.size();
  }
  return usages.back().max;
}

std::optional<std::uint32_t> Field::index_of(Usage u) const {
  std::uint64_t index = 0;
  for (const auto& r : usages) {
    if (u >= r.min && u <= r.max) {
      index += u - r.min;
      break;
    }
    index += r.size();
  }
  if (usages.empty() || index >= count) return std::nullopt;
  // Not found in any range: elements past the last usage repeat it (handled by the range check
  // above only when it is the last one), so a miss leaves index past every range.
  if (usage_of(static_cast<std::uint32_t>(index)) != u) return std::nullopt;
  return static_cast<std::uint32_t>(index);
}

const ReportLayout* ReportDescriptor::find(ReportType type, std::uint8_t id) const {
  for (const auto& r : reports) {
    if (r.type == type && r.id == id) return &r;
  }
  return nullptr;
}

std::vector<int> ReportDescriptor::collection_path(int collection) const {
  std::vector<int> path;
  // Parents always precede children, so the walk ends within collections.size() steps.
  for (int c = collection; c >= 0 && static_cast<std::size_t>(c) < collections.size() &&
                           path.size() <= collections.size();
       c = collections[static_cast<std::size_t>(c)].parent) {
    path.push_back(c);
  }
  std::reverse(path.begin(), path.end());
  return path;
}

bool ReportDescriptor::path_contains(int collection, Usage usage) const {
  for (int c : collection_path(collection)) {
    if (collections[static_cast<std::size_t>(c)].usage == usage) return true;
  }
  return false;
}

std::vector<Usage> ReportDescriptor::application_usages() const {
  std::vector<Usage> out;
  for (const auto& c : collections) {
    if (c.parent == -1 && c.kind == static_cast<std::uint8_t>(CollectionKind::Application)) {
      out.push_back(c.usage.value_or(0));
    }
  }
  return out;
}

ReportDescriptor parse_report_descriptor(std::span<const std::uint8_t> bytes) { return Parser(bytes).run(); }

std::optional<std::uint64_t> extract_bits(std::span<const std::uint8_t> data, std::uint64_t bit_offset,
                                          std::uint32_t bit_size) {
  if (bit_size == 0 || bit_size > 64) return std::nullopt;
  const std::uint64_t available = static_cast<std::uint64_t>(data.size()) * 8u;
  if (bit_offset > available || bit_size > available - bit_offset) return std::nullopt;
  std::uint64_t value = 0;
  std::uint32_t got = 0;
  std::uint64_t pos = bit_offset;
  while (got < bit_size) {
    const auto shift = static_cast<std::uint32_t>(pos % 8u);
    const std::uint32_t take = std::min(8u - shift, bit_size - got);
    const std::uint64_t bits = (static_cast<std::uint64_t>(data[static_cast<std::size_t>(pos / 8u)]) >> shift) &
                               ((1u << take) - 1u);
    value |= bits << got;
    got += take;
    pos += take;
  }
  return value;
}

std::int64_t sign_extend(std::uint64_t value, std::uint32_t bit_size) {
  if (bit_size == 0) return 0;
  if (bit_size >= 64) return static_cast<std::int64_t>(value);
  const std::uint64_t mask = (std::uint64_t{1} << bit_size) - 1u;
  const std::uint64_t sign = std::uint64_t{1} << (bit_size - 1u);
  value &= mask;
  return static_cast<std::int64_t>((value ^ sign) - sign);  // modular, well defined in C++20
}

std::optional<std::int64_t> field_value(const Field& field, std::span<const std::uint8_t> data,
                                        std::uint32_t index) {
  if (index >= field.count) return std::nullopt;
  const std::uint64_t offset = field.bit_offset + static_cast<std::uint64_t>(index) * field.bit_size;
  const auto raw = extract_bits(data, offset, field.bit_size);
  if (!raw) return std::nullopt;
  return field.is_signed() ? sign_extend(*raw, field.bit_size) : static_cast<std::int64_t>(*raw);
}

std::string usage_page_name(std::uint16_t page) {
  if (const char* name = find_usage_page_name(page)) return name;
  if (page >= 0xFF00) return hex(page, 4) + " (vendor)";
  return hex(page, 4);
}

std::string describe_usage(Usage u) {
  std::string s = usage_page_name(usage_page(u));
  if (const char* name = find_usage_name(u)) {
    s += " / ";
    s += name;
  }
  s += " (" + hex(usage_page(u), 2) + ":" + hex(usage_id(u), 2) + ")";
  return s;
}

}  // namespace fovea::trackerd::hid
