// SPDX-License-Identifier: Apache-2.0
#include "image/image.h"

#include <ImfRgbaFile.h>

#include <algorithm>
#include <cmath>
#include <png.h>

#include <cerrno>
#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <stdexcept>

namespace fovea::render {

void Image8::set(std::uint32_t x, std::uint32_t y, glm::vec3 c) {
  const std::size_t i = (std::size_t{y} * width + x) * 3;
  for (int k = 0; k < 3; ++k) {
    const float v = std::isfinite(c[k]) ? std::clamp(c[k], 0.0f, 1.0f) : 0.0f;
    rgb[i + static_cast<std::size_t>(k)] = static_cast<std::uint8_t>(std::lround(v * 255.0f));
  }
}

glm::vec3 Image8::get(std::uint32_t x, std::uint32_t y) const {
  const std::size_t i = (std::size_t{y} * width + x) * 3;
  return {rgb[i] / 255.0f, rgb[i + 1] / 255.0f, rgb[i + 2] / 255.0f};
}

namespace {

// libpng reports errors through longjmp; this C-style writer holds nothing with a destructor across
// it and returns libpng's message (empty on success).
std::string write_png_rows(std::FILE* file, const Image8& image, std::vector<png_bytep>& rows) {
  static thread_local char message[256];
  message[0] = '\0';
  png_structp png = png_create_write_struct(
      PNG_LIBPNG_VER_STRING, nullptr,
      [](png_structp p, png_const_charp text) {
        std::snprintf(message, sizeof message, "%s", text);
        png_longjmp(p, 1);
      },
      nullptr);
  if (png == nullptr) return "out of memory";
  png_infop info = png_create_info_struct(png);
  if (info == nullptr || setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return message[0] != '\0' ? message : "libpng failed";
  }
  png_init_io(png, file);
  // Level 1: frames are written every frame; the deflate levels above it cost several times the
  // time for a few percent of size.
  png_set_compression_level(png, 1);
  png_set_IHDR(png, info, image.width, image.height, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_sRGB_gAMA_and_cHRM(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
  png_write_info(png, info);
  png_write_image(png, rows.data());
  png_write_end(png, info);
  png_destroy_write_struct(&png, &info);
  return "";
}

}  // namespace

// libpng directly (not OpenCV's imgcodecs, which brings GDAL, Poppler, HDF5 and video codecs with it
// into a renderer that must be carried, with its libraries, to machines without a package registry).
void write_png(const std::string& path, const Image8& image) {
  if (image.width == 0 || image.height == 0 || image.rgb.size() != std::size_t{image.width} * image.height * 3) {
    throw std::runtime_error("cannot write PNG " + path + ": the image is " + std::to_string(image.width) + "x" +
                             std::to_string(image.height) + " with " + std::to_string(image.rgb.size()) + " bytes");
  }
  std::vector<png_bytep> rows(image.height);
  for (std::uint32_t y = 0; y < image.height; ++y) {
    rows[y] = const_cast<png_bytep>(&image.rgb[std::size_t{y} * image.width * 3]);  // libpng only reads them
  }
  std::FILE* file = std::fopen(path.c_str(), "wb");
  if (file == nullptr) throw std::runtime_error("cannot write PNG " + path + ": " + std::strerror(errno));
  const std::string error = write_png_rows(file, image, rows);
  const bool closed = std::fclose(file) == 0;
  if (!error.empty() || !closed) {
    std::remove(path.c_str());  // no half-written frame is left behind
    throw std::runtime_error("cannot write PNG " + path + ": " + (error.empty() ? std::string(std::strerror(errno)) : error));
  }
}

void write_exr(const std::string& path, std::uint32_t width, std::uint32_t height, const std::vector<glm::vec3>& rgb) {
  std::vector<Imf::Rgba> pixels(std::size_t{width} * height);
  for (std::size_t i = 0; i < pixels.size(); ++i) {
    const glm::vec3 c = rgb[i];
    // Half floats overflow to Inf above 65504: clamp so no Inf lands in the file.
    const auto h = [](float v) { return std::isfinite(v) ? std::clamp(v, -65504.0f, 65504.0f) : 0.0f; };
    pixels[i] = Imf::Rgba(h(c.r), h(c.g), h(c.b), 1.0f);
  }
  try {
    Imf::RgbaOutputFile file(path.c_str(), static_cast<int>(width), static_cast<int>(height), Imf::WRITE_RGB);
    file.setFrameBuffer(pixels.data(), 1, width);
    file.writePixels(static_cast<int>(height));
  } catch (const std::exception& e) {
    throw std::runtime_error("cannot write EXR " + path + ": " + e.what());
  }
}

}  // namespace fovea::render
