#include "image/image.h"

#include <ImfRgbaFile.h>

#include <algorithm>
#include <cmath>
#include <opencv2/imgcodecs.hpp>
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

float linear_to_srgb(float v) {
  v = std::clamp(v, 0.0f, 1.0f);
  return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}

void write_png(const std::string& path, const Image8& image) {
  cv::Mat bgr(static_cast<int>(image.height), static_cast<int>(image.width), CV_8UC3);
  for (std::uint32_t y = 0; y < image.height; ++y) {
    auto* row = bgr.ptr<std::uint8_t>(static_cast<int>(y));
    for (std::uint32_t x = 0; x < image.width; ++x) {
      const std::size_t i = (std::size_t{y} * image.width + x) * 3;
      row[3 * x + 0] = image.rgb[i + 2];
      row[3 * x + 1] = image.rgb[i + 1];
      row[3 * x + 2] = image.rgb[i + 0];
    }
  }
  bool ok = false;
  try {
    ok = cv::imwrite(path, bgr);
  } catch (const cv::Exception& e) {
    throw std::runtime_error("cannot write PNG " + path + ": " + e.what());
  }
  if (!ok) throw std::runtime_error("cannot write PNG " + path);
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
