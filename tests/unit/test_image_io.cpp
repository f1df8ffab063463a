// SPDX-License-Identifier: Apache-2.0
// The renderer's PNG writer (libpng): pixels round-trip exactly, a failure names the file and the
// reason and leaves no file behind.
#include <gtest/gtest.h>
#include <png.h>

#include <filesystem>

#include "image/image.h"

namespace fovea::render {
namespace {

namespace fs = std::filesystem;

Image8 read_back(const fs::path& path) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  EXPECT_NE(png_image_begin_read_from_file(&image, path.c_str()), 0) << image.message;
  image.format = PNG_FORMAT_RGB;
  Image8 out;
  out.resize(image.width, image.height);
  EXPECT_NE(png_image_finish_read(&image, nullptr, out.rgb.data(), 0, nullptr), 0) << image.message;
  return out;
}

TEST(WritePng, PixelsRoundTripExactly) {
  Image8 image;
  image.resize(37, 21);  // odd sizes: no row padding assumed
  for (std::size_t i = 0; i < image.rgb.size(); ++i) image.rgb[i] = static_cast<std::uint8_t>((i * 7919) % 256);
  const fs::path path = fs::temp_directory_path() / ("fovea-png-" + std::to_string(::getpid()) + ".png");
  write_png(path.string(), image);
  const Image8 back = read_back(path);
  fs::remove(path);
  EXPECT_EQ(back.width, 37u);
  EXPECT_EQ(back.height, 21u);
  EXPECT_EQ(back.rgb, image.rgb);
}

TEST(WritePng, AFailureNamesTheFileAndLeavesNothing) {
  Image8 image;
  image.resize(4, 4);
  const std::string path = "/nonexistent-dir/frame.png";
  try {
    write_png(path, image);
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("No such file"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(path));
  Image8 empty;
  EXPECT_THROW(write_png((fs::temp_directory_path() / "fovea-empty.png").string(), empty), std::runtime_error);
  EXPECT_FALSE(fs::exists(fs::temp_directory_path() / "fovea-empty.png"));
}

}  // namespace
}  // namespace fovea::render
