// SPDX-License-Identifier: Apache-2.0
#pragma once
// An image's declared size, read from its header without decoding it, so that a decompression bomb
// (issue 23 item 6: a 543-byte JPEG declaring 20000x20000 took `fovea-ctl detect-pupil` to 4.4 GB
// and 179 s; a 388 KB PNG to 1.7 GB) is refused before OpenCV allocates for it. OpenCV's own limit
// (OPENCV_IO_MAX_IMAGE_PIXELS) is read when the library loads, too late for a program to lower it.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>

#include <opencv2/core.hpp>

namespace fovea::trackerd {

struct ImageHeader {
  std::string format;  // "JPEG", "PNG", "BMP", "PNM"
  std::uint32_t width = 0, height = 0;
};

// JPEG (the first SOFn frame header), PNG (IHDR), BMP (BITMAPINFOHEADER and later) and binary or
// ASCII PNM (P1-P6); nullopt for other formats or a header too short or malformed to say.
std::optional<ImageHeader> read_image_header(std::span<const std::uint8_t> bytes);

// An eye camera's frame is at most this many pixels (4096 x 4096: 16 MiB of 8-bit grey).
inline constexpr std::uint64_t kMaxEyeImagePixels = std::uint64_t{4096} * 4096;

// Decodes an image file's bytes as OpenCV's imread would (`flags`), after checking its header:
// a format read_image_header knows, declaring at most max_pixels. Empty with `why` set otherwise.
cv::Mat decode_image_bounded(std::span<const std::uint8_t> bytes, int flags, std::uint64_t max_pixels,
                             std::string& why);

}  // namespace fovea::trackerd
