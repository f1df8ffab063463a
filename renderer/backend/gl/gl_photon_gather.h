// SPDX-License-Identifier: Apache-2.0
#pragma once
// The gaze area's global illumination gathered where the G-buffer lies (issue 42; renderer/gi/GI.md
// "On the GPU"). Jensen & Pedersen trace photons on the CPU and gather them per pixel; here the CPU
// still traces (Embree), and the GPU gathers:
//   1. the photons go up (48 bytes each);
//   2. a hash grid over them, cells the estimate's radius wide, by three compute passes: photons per
//      bucket (atomics), one work group's prefix sum over the buckets, photons scattered into their
//      buckets' ranges;
//   3. one compute pass over the area's pixels: the raster's direct light (eq. 5.22 without shadows,
//      its ambient taken out: the photons replace it) plus every photon of each map within its radius
//      that arrived on the pixel's front side, weighted by eq. 5.22's f_r and Jensen's cone filter,
//      over the disc (eq. 6.6). The 27 cells around the pixel hold every such photon; a photon counts
//      only in its own cell, so buckets that two cells share are not counted twice.
// The radius gather is the by-design difference to the CPU's k nearest (a grid cannot keep the k
// nearest cheaply): gi/photon_map.h EstimateSettings::fixed_radius is its CPU reference, the same sum
// (tests/gl/test_gl_photon_gather.cpp). Pixels the G-buffer cannot answer (mirrors, glass, emitters,
// glTF materials) take the CPU's traced values. Photons within a bucket land in any order, so sums may
// differ in their last bits from run to run. OpenGL 4.3.
#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "backend/gl/gl_context.h"
#include "backend/gpu_frame.h"

namespace fovea::render {

class GlPhotonGather {
 public:
  // Why this context cannot run it ("" when it can): compute shaders and storage buffers (GL 4.3),
  // and one storage buffer of `photons` photons (48 bytes each) within the device's limit.
  static std::string unavailable_reason(const GlFeatures& features, std::size_t photons = 0);
  // Compiles its programs on the current context; throws std::runtime_error with the driver's log.
  explicit GlPhotonGather(const GlFeatures& features);
  ~GlPhotonGather();
  GlPhotonGather(const GlPhotonGather&) = delete;
  GlPhotonGather& operator=(const GlPhotonGather&) = delete;

  struct GBufferInput {  // the G-buffer's textures, the image in their lower-left width x height texels
    unsigned color = 0, depth = 0, object_id = 0, normal = 0;
    std::uint32_t width = 0, height = 0;
  };
  // The GI of the pixels of [origin, origin + size) (image pixels, y down) inside the gather's circle;
  // the box's other pixels are 0. Throws std::invalid_argument when gather.traced is not the image's size.
  void run(const GBufferInput& gbuffer, const GpuGiGather& gather, glm::ivec2 origin, glm::ivec2 size);
  // RGBA32F, the last run's box, row 0 at the box's top.
  unsigned output() const { return output_; }
  // The last run's box, RGB, row 0 at the top.
  void read(std::vector<glm::vec3>& box) const;
  // The last run's labels (GpuFrame::read_gi_labels); empty without GpuGiGather::label.
  void read_labels(std::vector<std::uint8_t>& used, std::vector<double>& traditional, std::vector<double>& gaze) const;

 private:
  struct Grid {
    unsigned photons = 0, counts = 0, starts = 0, sorted = 0;  // storage buffers
    std::size_t photons_bytes = 0, counts_bytes = 0, starts_bytes = 0, sorted_bytes = 0;  // their capacities
    std::uint32_t count = 0, table = 0;  // photons, buckets (a power of two)
    float cell = 0;                      // metres
  };
  void build(Grid& grid, const GpuGiGather::Map& map);
  void upload_traced(const GpuGiGather& gather, std::uint32_t width, glm::ivec2 origin, glm::ivec2 size);
  void upload_surfaces(const std::vector<GpuGiGather::Surface>& surfaces);
  void gather(const GBufferInput& gbuffer, const GpuGiGather& gather, glm::ivec2 origin, glm::ivec2 size);

  std::int64_t max_storage_block_ = 0;  // GlFeatures::max_storage_block
  unsigned count_program_ = 0, scan_program_ = 0, scatter_program_ = 0, gather_program_ = 0;
  Grid grids_[2];  // indirect, caustic
  unsigned surfaces_ = 0, traced_ = 0, output_ = 0;
  std::size_t surface_capacity_ = 0;
  // Labelling: a word per indirect photon, and per work group of the gather 2 x kMaxLabelLights sums.
  unsigned labels_ = 0, partials_ = 0;
  std::size_t labels_bytes_ = 0, partials_bytes_ = 0;
  bool labelled_ = false;
  std::uint32_t label_lights_ = 0, label_groups_ = 0;
  void prepare_labels(const GpuGiGather& gather, glm::ivec2 size);
  int surface_count_ = 0;
  bool has_traced_ = false;
  glm::ivec2 output_size_{0}, traced_size_{0};
};

}  // namespace fovea::render
