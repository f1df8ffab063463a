// SPDX-License-Identifier: Apache-2.0
#include "source_api/image_header.h"

#include <cctype>
#include <opencv2/imgcodecs.hpp>

namespace fovea::trackerd {

namespace {

std::uint32_t be16(const std::uint8_t* p) { return (std::uint32_t{p[0]} << 8) | p[1]; }
std::uint32_t be32(const std::uint8_t* p) { return (be16(p) << 16) | be16(p + 2); }
std::uint32_t le32(const std::uint8_t* p) {
  return std::uint32_t{p[0]} | (std::uint32_t{p[1]} << 8) | (std::uint32_t{p[2]} << 16) | (std::uint32_t{p[3]} << 24);
}

std::optional<ImageHeader> jpeg(std::span<const std::uint8_t> b) {
  std::size_t i = 2;  // after SOI
  while (i + 4 <= b.size()) {
    if (b[i] != 0xFF) return std::nullopt;
    const std::uint8_t marker = b[i + 1];
    if (marker == 0xFF) {  // fill byte
      ++i;
      continue;
    }
    if (marker == 0xD8 || (marker >= 0xD0 && marker <= 0xD7) || marker == 0x01) {  // no length
      i += 2;
      continue;
    }
    const std::uint32_t length = be16(&b[i + 2]);
    if (length < 2) return std::nullopt;
    // SOF0..SOF15 except DHT (C4), JPG (C8) and DAC (CC).
    if (marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC) {
      if (i + 9 > b.size()) return std::nullopt;
      return ImageHeader{"JPEG", be16(&b[i + 7]), be16(&b[i + 5])};
    }
    if (marker == 0xD9 || marker == 0xDA) return std::nullopt;  // EOI or scan before any frame header
    i += 2 + length;
  }
  return std::nullopt;
}

std::optional<ImageHeader> pnm(std::span<const std::uint8_t> b) {
  // "P5 <ws> width <ws> height ...", with # comments to the end of a line.
  std::size_t i = 2;
  std::uint64_t values[2] = {0, 0};
  for (std::uint64_t& v : values) {
    for (;;) {
      while (i < b.size() && std::isspace(b[i])) ++i;
      if (i < b.size() && b[i] == '#') {
        while (i < b.size() && b[i] != '\n') ++i;
        continue;
      }
      break;
    }
    if (i >= b.size() || !std::isdigit(b[i])) return std::nullopt;
    while (i < b.size() && std::isdigit(b[i])) {
      v = v * 10 + (b[i++] - '0');
      if (v > 0xFFFFFFFFu) return std::nullopt;
    }
  }
  return ImageHeader{"PNM", static_cast<std::uint32_t>(values[0]), static_cast<std::uint32_t>(values[1])};
}

}  // namespace

std::optional<ImageHeader> read_image_header(std::span<const std::uint8_t> b) {
  static constexpr std::uint8_t kPng[8] = {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A};
  if (b.size() >= 24 && std::equal(kPng, kPng + 8, b.begin()) && b[12] == 'I' && b[13] == 'H' && b[14] == 'D' &&
      b[15] == 'R') {
    return ImageHeader{"PNG", be32(&b[16]), be32(&b[20])};
  }
  if (b.size() >= 4 && b[0] == 0xFF && b[1] == 0xD8) return jpeg(b);
  if (b.size() >= 26 && b[0] == 'B' && b[1] == 'M' && le32(&b[14]) >= 40) {
    const auto h = static_cast<std::int32_t>(le32(&b[22]));  // negative: top-down rows
    const std::uint32_t height = h < 0 ? static_cast<std::uint32_t>(-static_cast<std::int64_t>(h)) : static_cast<std::uint32_t>(h);
    return ImageHeader{"BMP", le32(&b[18]), height};
  }
  if (b.size() >= 3 && b[0] == 'P' && b[1] >= '1' && b[1] <= '6') return pnm(b);
  return std::nullopt;
}

cv::Mat decode_image_bounded(std::span<const std::uint8_t> bytes, int flags, std::uint64_t max_pixels,
                             std::string& why) {
  const std::optional<ImageHeader> h = read_image_header(bytes);
  if (!h) {
    why = "not a PNG, JPEG, BMP or PNM image whose size its header says";
    return {};
  }
  const std::uint64_t pixels = std::uint64_t{h->width} * h->height;
  if (pixels == 0 || pixels > max_pixels) {
    why = h->format + " declaring " + std::to_string(h->width) + "x" + std::to_string(h->height) + " pixels; at most " +
          std::to_string(max_pixels) + " are decoded";
    return {};
  }
  cv::Mat image;
  try {
    image = cv::imdecode(cv::Mat(1, static_cast<int>(bytes.size()), CV_8UC1, const_cast<std::uint8_t*>(bytes.data())),
                         flags);
  } catch (const cv::Exception&) {
    image.release();
  }
  if (image.empty()) why = h->format + " that OpenCV cannot decode (corrupt or unsupported)";
  return image;
}

}  // namespace fovea::trackerd
