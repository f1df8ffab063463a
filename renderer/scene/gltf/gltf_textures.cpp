// SPDX-License-Identifier: Apache-2.0
#include "scene/gltf/gltf_textures.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstring>
#include <exception>
#include <optional>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <span>
#include <string>

#include "fovea/protocol/bounded_file.h"
#include "source_api/image_header.h"

namespace fovea::render::gltf {

namespace {

std::string image_label(const Asset& a, std::uint32_t image) {
  std::string out = "$.images[" + std::to_string(image) + "]";
  const Image& im = a.images[image];
  if (!im.file.empty()) {
    out += " (\"" + im.file.filename().string() + "\")";
  } else if (!im.name.empty()) {
    out += " (\"" + im.name + "\")";
  }
  return out;
}

// An image's encoded bytes and declared size (phase one, before the budget is known).
struct Encoded {
  std::string owned;                    // an external file's bytes
  std::span<const std::uint8_t> bytes;  // owned, or the asset's bufferView / data: URI
  std::uint32_t width = 0, height = 0;
  std::string error;                    // set when the image cannot be used
};

Encoded read_encoded(const Asset& a, std::uint32_t image, const TextureOptions& options) {
  Encoded e;
  if (image >= a.images.size()) {
    e.error = "no such image";
    return e;
  }
  const Image& im = a.images[image];
  if (!im.file.empty()) {
    try {
      e.owned = protocol::read_bounded_file(im.file.string(), {.max_bytes = options.max_image_file_bytes,
                                                                .follow_symlinks = true, .what = "image file"});
    } catch (const std::exception& ex) {
      e.error = ex.what();
      return e;
    }
    e.bytes = {reinterpret_cast<const std::uint8_t*>(e.owned.data()), e.owned.size()};
  } else {
    e.bytes = image_bytes(a, image);
  }
  if (e.bytes.empty()) {
    e.error = "no image data";
    return e;
  }
  const auto header = trackerd::read_image_header(e.bytes);
  if (!header || header->width == 0 || header->height == 0) {
    e.error = "not a PNG or JPEG image whose header gives its size";
    return e;
  }
  if (std::uint64_t{header->width} * header->height > options.max_image_pixels) {
    e.error = header->format + " declaring " + std::to_string(header->width) + "x" + std::to_string(header->height) +
              " pixels; at most " + std::to_string(options.max_image_pixels) + " are decoded";
    return e;
  }
  e.width = header->width;
  e.height = header->height;
  return e;
}

// The decoded image as RGBA8, whatever OpenCV gave (grey, grey + alpha, BGR, BGRA; 8 or 16 bits).
bool to_rgba8(const cv::Mat& decoded, std::vector<std::uint8_t>& rgba) {
  cv::Mat m = decoded;
  if (m.depth() == CV_16U) m.convertTo(m, CV_8U, 1.0 / 257.0);
  if (m.depth() != CV_8U) return false;
  cv::Mat out;
  switch (m.channels()) {
    case 1: cv::cvtColor(m, out, cv::COLOR_GRAY2RGBA); break;
    case 3: cv::cvtColor(m, out, cv::COLOR_BGR2RGBA); break;
    case 4: cv::cvtColor(m, out, cv::COLOR_BGRA2RGBA); break;
    default: return false;
  }
  if (!out.isContinuous()) out = out.clone();
  rgba.assign(out.data, out.data + out.total() * 4);
  return true;
}

// The fewest levels to leave out of every image so that all chains fit the budget.
std::uint32_t levels_to_drop(const std::vector<Encoded>& encoded, std::size_t budget) {
  for (std::uint32_t k = 0; k < 32; ++k) {
    std::size_t total = 0;
    for (const Encoded& e : encoded) {
      if (e.error.empty()) total += mip_chain_bytes(std::max(1u, e.width >> k), std::max(1u, e.height >> k));
    }
    if (total <= budget) return k;
  }
  return 32;
}

std::string mib(std::size_t bytes) { return std::to_string((bytes + (1u << 19)) >> 20) + " MiB"; }

}  // namespace

DecodedTextures decode_textures(const Asset& a, const std::vector<TextureRequest>& requests, const TextureOptions& options) {
  DecodedTextures out;
  out.images.resize(requests.size());
  std::vector<Encoded> encoded(requests.size());
  tbb::parallel_for(std::size_t{0}, requests.size(), [&](std::size_t i) { encoded[i] = read_encoded(a, requests[i].image, options); });

  out.dropped_levels = levels_to_drop(encoded, options.budget_bytes);
  std::vector<std::string> errors(requests.size());
  tbb::parallel_for(std::size_t{0}, requests.size(), [&](std::size_t i) {
    Encoded& e = encoded[i];
    if (!e.error.empty()) {
      errors[i] = e.error;
      return;
    }
    std::string why;
    const cv::Mat decoded = trackerd::decode_image_bounded(e.bytes, cv::IMREAD_UNCHANGED, options.max_image_pixels, why);
    std::vector<std::uint8_t> rgba;
    if (decoded.empty()) {
      errors[i] = why;
    } else if (decoded.cols != static_cast<int>(e.width) || decoded.rows != static_cast<int>(e.height)) {
      errors[i] = "decoded to " + std::to_string(decoded.cols) + "x" + std::to_string(decoded.rows) +
                  " pixels, not the header's " + std::to_string(e.width) + "x" + std::to_string(e.height);
    } else if (!to_rgba8(decoded, rgba)) {
      errors[i] = "an image format with " + std::to_string(decoded.channels()) + " channels of depth " +
                  std::to_string(decoded.depth()) + " (8 or 16-bit grey, grey-alpha, RGB or RGBA are read)";
    } else {
      const std::uint32_t k = out.dropped_levels;
      const std::size_t max = mip_chain_bytes(std::max(1u, e.width >> k), std::max(1u, e.height >> k));
      MipChainResult chain = make_texture_image(image_label(a, requests[i].image), e.width, e.height, std::move(rgba),
                                                requests[i].srgb, max);
      if (chain.image) {
        out.images[i] = std::move(chain.image);
      } else {
        errors[i] = "could not be mip-mapped";
      }
    }
    e.owned.clear();
    e.owned.shrink_to_fit();
  });

  for (std::size_t i = 0; i < requests.size(); ++i) {
    if (out.images[i]) {
      out.bytes += out.images[i]->bytes();
    } else {
      out.warnings.push_back(requests[i].used_by + ": " + image_label(a, requests[i].image) + ": " + errors[i] +
                             ": the texture is left out (the material's factors are used)");
    }
  }
  if (out.dropped_levels > 0) {
    out.warnings.push_back("textures: the full mip chains exceed the texture budget of " + mib(options.budget_bytes) +
                           ": every texture loaded at 1/" + std::to_string(1u << std::min(out.dropped_levels, 31u)) +
                           " of its resolution (" + mib(out.bytes) + ")");
  }
  return out;
}

}  // namespace fovea::render::gltf
