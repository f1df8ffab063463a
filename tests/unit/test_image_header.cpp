// SPDX-License-Identifier: Apache-2.0
// read_image_header and decode_image_bounded (trackerd/source_api/image_header.h): the declared
// size of PNG, JPEG, BMP and PNM images without decoding them, and decompression bombs (a small
// file declaring 20000x20000, issue 23 item 6) refused before OpenCV allocates.
#include <gtest/gtest.h>

#include <chrono>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "source_api/image_header.h"

using namespace fovea::trackerd;

namespace {

std::vector<std::uint8_t> encoded(const std::string& ext, int w, int h) {
  std::vector<std::uint8_t> out;
  EXPECT_TRUE(cv::imencode(ext, cv::Mat(h, w, CV_8UC1, cv::Scalar(77)), out)) << ext;
  return out;
}

}  // namespace

TEST(ImageHeader, ReadsTheDeclaredSizeOfEachFormat) {
  for (const std::string ext : {".png", ".jpg", ".bmp", ".pgm"}) {
    const auto h = read_image_header(encoded(ext, 321, 123));
    ASSERT_TRUE(h) << ext;
    EXPECT_EQ(h->width, 321u) << ext;
    EXPECT_EQ(h->height, 123u) << ext;
  }
  const std::string ascii = "P2\n# a comment\n 7 5\n255\n";
  const auto p = read_image_header(std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(ascii.data()), ascii.size()));
  ASSERT_TRUE(p);
  EXPECT_EQ(p->format, "PNM");
  EXPECT_EQ(p->width, 7u);
  EXPECT_EQ(p->height, 5u);
}

TEST(ImageHeader, UnknownTruncatedAndGarbageHeadersSayNothing) {
  const std::string text = "not an image";
  EXPECT_FALSE(read_image_header(std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(text.data()), text.size())));
  auto jpg = encoded(".jpg", 16, 16);
  jpg.resize(20);  // before the frame header
  EXPECT_FALSE(read_image_header(jpg));
  auto png = encoded(".png", 16, 16);
  png.resize(20);
  EXPECT_FALSE(read_image_header(png));
  EXPECT_FALSE(read_image_header(std::vector<std::uint8_t>{0xFF, 0xD8, 0xFF, 0xC0, 0x00, 0x01}));
  EXPECT_FALSE(read_image_header(std::vector<std::uint8_t>{}));
}

TEST(ImageHeader, ABombIsRefusedBeforeDecoding) {
  auto png = encoded(".png", 64, 64);
  // IHDR width and height (bytes 16..23) patched to 20000x20000: a few hundred bytes declaring 400 Mpx.
  for (const std::size_t at : {std::size_t{16}, std::size_t{20}}) {
    png[at] = 0, png[at + 1] = 0, png[at + 2] = 20000 >> 8, png[at + 3] = 20000 & 0xFF;
  }
  std::string why;
  const auto start = std::chrono::steady_clock::now();
  EXPECT_TRUE(decode_image_bounded(png, cv::IMREAD_UNCHANGED, kMaxEyeImagePixels, why).empty());
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::milliseconds(100));
  EXPECT_EQ(why, "PNG declaring 20000x20000 pixels; at most 16777216 are decoded");
  // Within the limit it decodes as imread would.
  const cv::Mat ok = decode_image_bounded(encoded(".png", 64, 48), cv::IMREAD_UNCHANGED, kMaxEyeImagePixels, why);
  EXPECT_EQ(ok.size(), cv::Size(64, 48));
  EXPECT_TRUE(decode_image_bounded(encoded(".png", 64, 48), cv::IMREAD_UNCHANGED, 64 * 47, why).empty());
}
