// SPDX-License-Identifier: Apache-2.0
#include "fovea/protocol/recording.h"

#include "fovea/protocol/bounded_file.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <stdexcept>

#include "fovea/protocol/codec.h"
#include "fovea/protocol/crc32c.h"
#include "fovea/protocol/wire.h"

namespace fovea::protocol {

using wire::load_le;
using wire::store_le;

namespace {
constexpr std::uint8_t kFileMagic[8] = {'F', 'O', 'V', 'E', 'A', 'F', 'G', 'R'};
constexpr std::uint8_t kSync[4] = {0xF0, 0x7E, 0xA1, 0x52};
constexpr std::size_t kRecordPrefix = 16;  // sync, type, flags, length, sequence
constexpr std::uint8_t kRecordHasReceiveTime = 1u << 0;  // flags: an i64 host receive time follows the sequence
constexpr std::size_t kRecordCrc = 4;
constexpr std::size_t kMinRecord = kRecordPrefix + kRecordCrc;

std::string sys_error(const std::string& what, const std::string& path) {
  return what + " " + path + ": " + std::strerror(errno);
}

// Displays are the same when every size agrees to 1 micrometre (text forms round to that).
bool same_display(const DisplayGeometry& a, const DisplayGeometry& b) {
  return a.width_px == b.width_px && a.height_px == b.height_px && std::abs(a.width_m - b.width_m) < 1e-6 &&
         std::abs(a.height_m - b.height_m) < 1e-6 && std::abs(a.viewing_distance_m - b.viewing_distance_m) < 1e-6;
}

void write_display(std::span<std::uint8_t> b, std::size_t off, const DisplayGeometry& g) {
  store_le<std::uint32_t>(b, off, g.width_px);
  store_le<std::uint32_t>(b, off + 4, g.height_px);
  store_le<double>(b, off + 8, g.width_m);
  store_le<double>(b, off + 16, g.height_m);
  store_le<double>(b, off + 24, g.viewing_distance_m);
}

DisplayGeometry read_display(std::span<const std::uint8_t> b, std::size_t off) {
  DisplayGeometry g;
  g.width_px = load_le<std::uint32_t>(b, off);
  g.height_px = load_le<std::uint32_t>(b, off + 4);
  g.width_m = load_le<double>(b, off + 8);
  g.height_m = load_le<double>(b, off + 16);
  g.viewing_distance_m = load_le<double>(b, off + 24);
  return g;
}

std::optional<RecordingHeader> parse_header(std::span<const std::uint8_t> d) {
  if (d.size() < kRecordingHeaderSize) return std::nullopt;
  if (std::memcmp(d.data(), kFileMagic, 8) != 0) return std::nullopt;
  const auto version = load_le<std::uint16_t>(d, 8);
  if (version < 1 || version > kRecordingVersion) return std::nullopt;
  if (load_le<std::uint16_t>(d, 10) != kRecordingHeaderSize) return std::nullopt;
  if (load_le<std::uint32_t>(d, 156) != crc32c(d.first(156))) return std::nullopt;
  RecordingHeader h;
  const auto* dev = reinterpret_cast<const char*>(d.data() + 16);
  h.device.assign(dev, strnlen(dev, 63));
  h.display = read_display(d, 80);
  if (!validate(h.display).empty()) return std::nullopt;
  h.nominal_rate_hz = load_le<double>(d, 112);
  if (!(h.nominal_rate_hz >= 0) || !std::isfinite(h.nominal_rate_hz)) return std::nullopt;
  const auto clock = load_le<std::uint8_t>(d, 120);
  if (clock > 1) return std::nullopt;
  h.clock = static_cast<RecordingClock>(clock);
  h.created_unix_ns = load_le<std::int64_t>(d, 128);
  h.created_clock_ns = load_le<std::int64_t>(d, 136);
  return h;
}

// Decodes one record at the start of `d`; returns its size, or 0 if no intact record starts there.
// A GAZE_EYES record (the per-eye gaze of the sample record before it) goes to `eyes`, not `out`.
std::size_t parse_record(std::span<const std::uint8_t> d, Record& out, std::optional<GazeEyes>* eyes = nullptr) {
  if (d.size() < kMinRecord || std::memcmp(d.data(), kSync, 4) != 0) return 0;
  const auto type_raw = d[4];
  if (type_raw != static_cast<std::uint8_t>(MessageType::GazeSample) &&
      type_raw != static_cast<std::uint8_t>(MessageType::GazeEvent) &&
      type_raw != static_cast<std::uint8_t>(MessageType::Marker) &&
      type_raw != static_cast<std::uint8_t>(MessageType::GazeEyes)) {
    return 0;
  }
  const auto type = static_cast<MessageType>(type_raw);
  const std::uint8_t flags = d[5];
  if ((flags & ~kRecordHasReceiveTime) != 0) return 0;
  if (flags != 0 && type != MessageType::GazeSample) return 0;  // only samples carry a receive time
  const std::size_t extra = flags != 0 ? 8 : 0;
  const std::size_t body = load_le<std::uint16_t>(d, 6);
  if (body != 8 + extra + payload_size(type)) return 0;
  const std::size_t total = 8 + body + kRecordCrc;
  if (d.size() < total) return 0;
  if (load_le<std::uint32_t>(d, 8 + body) != crc32c(d.subspan(4, 4 + body))) return 0;
  Payload p;
  if (!decode_payload(type, d.subspan(kRecordPrefix + extra, body - 8 - extra), p)) return 0;
  if (type == MessageType::GazeEyes) {
    if (eyes != nullptr) *eyes = std::get<GazeEyes>(p);
    out.sequence = load_le<std::uint64_t>(d, 8);
    return total;
  }
  out.sequence = load_le<std::uint64_t>(d, 8);
  out.host_receive_ns.reset();
  if (extra != 0) out.host_receive_ns = load_le<std::int64_t>(d, kRecordPrefix);
  if (type == MessageType::GazeSample) {
    out.item = std::get<GazeSample>(p);
  } else if (type == MessageType::GazeEvent) {
    out.item = std::get<GazeEvent>(p);
  } else {
    out.item = std::get<Marker>(p);
  }
  return total;
}

}  // namespace

std::int64_t Record::time_ns() const {
  if (const auto* s = std::get_if<GazeSample>(&item)) return s->tracker_time_ns;
  if (const auto* m = std::get_if<Marker>(&item)) return m->time_ns;
  const auto& e = std::get<GazeEvent>(item);
  return e.start_time_ns + e.duration_ns;
}

std::string recording_device_name(const std::string& description) { return escape_to_fit(description, 63); }

std::vector<std::uint8_t> encode_recording_header(const RecordingHeader& h) {
  if (h.device.size() > 63) throw std::invalid_argument("recording device name longer than 63 bytes: " + h.device);
  for (const char ch : h.device) {
    if (static_cast<unsigned char>(ch) < 0x20) {
      throw std::invalid_argument("recording device name contains a control character: \"" + h.device + "\"");
    }
  }
  if (!std::isfinite(h.nominal_rate_hz) || h.nominal_rate_hz < 0) {
    throw std::invalid_argument("recording nominal_rate_hz = " + std::to_string(h.nominal_rate_hz) +
                                " (allowed: finite, >= 0)");
  }
  if (static_cast<std::uint8_t>(h.clock) > 1) throw std::invalid_argument("recording clock must be 0 or 1");
  if (auto err = validate(h.display); !err.empty()) throw std::invalid_argument("recording display: " + err);
  std::vector<std::uint8_t> b(kRecordingHeaderSize, 0);
  std::memcpy(b.data(), kFileMagic, 8);
  store_le<std::uint16_t>(b, 8, kRecordingVersion);
  store_le<std::uint16_t>(b, 10, static_cast<std::uint16_t>(kRecordingHeaderSize));
  std::memcpy(b.data() + 16, h.device.data(), h.device.size());
  write_display(b, 80, h.display);
  store_le<double>(b, 112, h.nominal_rate_hz);
  store_le<std::uint8_t>(b, 120, static_cast<std::uint8_t>(h.clock));
  store_le<std::int64_t>(b, 128, h.created_unix_ns);
  store_le<std::int64_t>(b, 136, h.created_clock_ns);
  store_le<std::uint32_t>(b, 156, crc32c(std::span<const std::uint8_t>(b).first(156)));
  return b;
}

namespace {

// One record's bytes: sync, type, flags, length, sequence, [receive time], payload, CRC.
std::vector<std::uint8_t> encode_one_record(const Payload& p, std::uint64_t sequence,
                                            const std::optional<std::int64_t>& host_receive_ns) {
  const MessageType type = type_of(p);
  const auto& r = host_receive_ns;
  const std::size_t extra = r ? 8 : 0;
  const std::size_t body = 8 + extra + payload_size(type);
  std::vector<std::uint8_t> b(8 + body + kRecordCrc, 0);
  std::memcpy(b.data(), kSync, 4);
  b[4] = static_cast<std::uint8_t>(type);
  b[5] = r ? kRecordHasReceiveTime : 0;
  store_le<std::uint16_t>(b, 6, static_cast<std::uint16_t>(body));
  store_le<std::uint64_t>(b, 8, sequence);
  if (r) store_le<std::int64_t>(b, kRecordPrefix, *r);
  encode_payload(p, std::span<std::uint8_t>(b).subspan(kRecordPrefix + extra, body - 8 - extra));
  store_le<std::uint32_t>(b, 8 + body, crc32c(std::span<const std::uint8_t>(b).subspan(4, 4 + body)));
  return b;
}

}  // namespace

std::vector<std::uint8_t> encode_record(const Record& r) {
  const Payload p = std::visit([](const auto& v) -> Payload { return v; }, r.item);
  const MessageType type = type_of(p);
  if (r.host_receive_ns && type != MessageType::GazeSample) {
    throw std::invalid_argument("only gaze samples carry a host receive time in a recording");
  }
  std::vector<std::uint8_t> b = encode_one_record(p, r.sequence, r.host_receive_ns);
  // A sample's per-eye gaze follows it as a GAZE_EYES record of the same sequence (RECORDING.md).
  if (const auto* s = std::get_if<GazeSample>(&r.item); s != nullptr && s->has_eye_gaze()) {
    const auto eyes = encode_one_record(GazeEyes{s->tracker_time_ns, s->left_gaze, s->right_gaze}, r.sequence, {});
    b.insert(b.end(), eyes.begin(), eyes.end());
  }
  return b;
}

RecordingWriter::RecordingWriter(const std::string& path, const RecordingHeader& header, Mode mode) : path_(path) {
  const std::vector<std::uint8_t> head = encode_recording_header(header);
  if (mode == Mode::CreateNew) {
    fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
    if (fd_ < 0) {
      if (errno == EEXIST) {
        throw std::runtime_error("recording " + path + " already exists; choose another name or append to it");
      }
      throw std::runtime_error(sys_error("cannot create recording", path));
    }
  } else {
    // O_NONBLOCK: a FIFO or device at the path is refused below instead of blocking the open or,
    // once its buffer is full, every write of the publishing loop.
    fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_APPEND | O_CLOEXEC | O_NONBLOCK, 0644);
    if (fd_ < 0) throw std::runtime_error(sys_error("cannot open recording", path));
    struct stat st {};
    if (fstat(fd_, &st) != 0) {
      const std::string msg = sys_error("cannot stat recording", path);
      ::close(fd_);
      throw std::runtime_error(msg);
    }
    if (!S_ISREG(st.st_mode)) {
      ::close(fd_);
      throw std::runtime_error("cannot append to " + path + ": not a regular file");
    }
    ::fcntl(fd_, F_SETFL, O_APPEND);
    if (st.st_size > 0) {
      std::vector<std::uint8_t> existing(kRecordingHeaderSize);
      const ssize_t n = ::pread(fd_, existing.data(), existing.size(), 0);
      const auto parsed = n == static_cast<ssize_t>(existing.size()) ? parse_header(existing) : std::nullopt;
      if (!parsed) {
        ::close(fd_);
        throw std::runtime_error("cannot append to " + path + ": it does not start with an intact .fgr header");
      }
      if (!same_display(parsed->display, header.display)) {
        ::close(fd_);
        throw std::runtime_error("cannot append to " + path + ": it was recorded for display " +
                                 to_string(parsed->display) + ", not " + to_string(header.display));
      }
      receive_times_ = load_le<std::uint16_t>(existing, 8) >= 2;
      return;
    }
  }
  if (::write(fd_, head.data(), head.size()) != static_cast<ssize_t>(head.size())) {
    const std::string msg = sys_error("cannot write header of", path);
    ::close(fd_);
    throw std::runtime_error(msg);
  }
}

RecordingWriter::~RecordingWriter() {
  if (fd_ >= 0) ::close(fd_);
}

void RecordingWriter::append(const Record& r) {
  std::vector<std::uint8_t> bytes;
  if (r.host_receive_ns && !receive_times_) {
    Record older = r;  // what a version-1 file can hold
    older.host_receive_ns.reset();
    bytes = encode_record(older);
  } else {
    bytes = encode_record(r);
  }
  const ssize_t n = ::write(fd_, bytes.data(), bytes.size());
  if (n != static_cast<ssize_t>(bytes.size())) {
    if (n >= 0) errno = ENOSPC;  // a short write sets no errno; the usual cause is a full disk
    throw std::runtime_error(sys_error("cannot append record to", path_));
  }
  ++written_;
}

void RecordingWriter::sync() { ::fdatasync(fd_); }

std::string RecoveryReport::describe() const {
  std::string s = std::to_string(records) + " intact records";
  if (!header_valid) s += "; header damaged (defaults used)";
  if (damaged_regions > 0) {
    s += "; skipped " + std::to_string(bytes_skipped) + " bytes in " + std::to_string(damaged_regions) +
         " damaged region(s)";
  }
  if (truncated_tail) s += "; file ends inside a record";
  if (eyes_unjoined > 0) s += "; " + std::to_string(eyes_unjoined) + " per-eye record(s) without their sample";
  return s;
}

namespace {

// A GAZE_EYES record belongs to the sample record just before it (same sequence and capture time);
// one that does not (its sample was damaged) is counted, never joined to another sample.
void join_eyes(Recording& rec, std::uint64_t sequence, const GazeEyes& eyes) {
  GazeSample* s = rec.records.empty() ? nullptr : std::get_if<GazeSample>(&rec.records.back().item);
  if (s != nullptr && rec.records.back().sequence == sequence && s->tracker_time_ns == eyes.tracker_time_ns &&
      !s->has_eye_gaze()) {
    s->left_gaze = eyes.left;
    s->right_gaze = eyes.right;
  } else {
    ++rec.report.eyes_unjoined;
  }
}

}  // namespace

Recording parse_recording(std::span<const std::uint8_t> data) {
  Recording rec;
  std::size_t pos = 0;
  if (auto h = parse_header(data)) {
    rec.header = *h;
    rec.report.header_valid = true;
    pos = kRecordingHeaderSize;
  } else if (data.size() >= 8 && std::memcmp(data.data(), kFileMagic, 8) == 0) {
    pos = 8;  // damaged header: look for records after the magic
  } else {
    // Not a recording unless a record can be found somewhere (a file whose first bytes were lost).
    bool found = false;
    for (std::size_t i = 0; i + kMinRecord <= data.size() && !found; ++i) {
      Record r;
      found = parse_record(data.subspan(i), r) != 0;
    }
    if (!found) throw std::runtime_error("not a fovea recording (no .fgr header and no intact record)");
  }

  bool in_damage = false;
  while (pos < data.size()) {
    Record r;
    std::optional<GazeEyes> eyes;
    const std::size_t n = parse_record(data.subspan(pos), r, &eyes);
    if (n > 0 && eyes) {
      join_eyes(rec, r.sequence, *eyes);
      pos += n;
      in_damage = false;
      continue;
    }
    if (n > 0) {
      rec.records.push_back(std::move(r));
      pos += n;
      in_damage = false;
      continue;
    }
    if (!in_damage) {
      ++rec.report.damaged_regions;
      in_damage = true;
    }
    // Resynchronise at the next sync marker.
    std::size_t next = pos + 1;
    while (next + 4 <= data.size() && std::memcmp(data.data() + next, kSync, 4) != 0) ++next;
    if (next + 4 > data.size()) next = data.size();
    rec.report.bytes_skipped += next - pos;
    if (next == data.size()) {
      // The last region ran to the end of the file: a record cut short (or garbage at the end).
      rec.report.truncated_tail = true;
    }
    pos = next;
  }
  rec.report.records = rec.records.size();
  return rec;
}

// Read, not mapped: a file that shrinks while it is read (a recorder truncating it, a hostile user)
// made the mapped pages fault with SIGBUS (issue 23 item 11), and a FIFO blocked the reader. Only a
// regular file is read, up to kMaxRecordingBytes.
Recording read_recording(const std::string& path) {
  const std::string bytes = read_bounded_file(path, {.max_bytes = kMaxRecordingBytes, .what = "recording"});
  if (bytes.empty()) throw std::runtime_error("recording " + escape_for_log(path) + " is empty");
  try {
    return parse_recording(
        std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size()));
  } catch (const std::exception& e) {
    throw std::runtime_error(escape_for_log(path) + ": " + e.what());
  }
}

}  // namespace fovea::protocol
