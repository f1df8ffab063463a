// SPDX-License-Identifier: Apache-2.0
#pragma once
// The GPU-resident frame on OpenGL (backend/gpu_frame.h): the G-buffer pass without readback, the
// tone map (a compute pass on GL 4.3 GPUs) and the overlay as fragment-shader passes on the
// G-buffer's textures, an RGBA8 display
// image, GPU timestamp queries around each pass and a fence for the frame's completion. Shares the
// backend's context. Needs OpenGL 3.3 with timer queries and fences (core there); a context without
// them leaves unavailable_reason() set and the pipeline on the readback path.
#include <memory>
#include <string>
#include <vector>

#include "backend/gpu_frame.h"

namespace fovea::render {

class GlAttention;
class GlBackend;
class GlLeeMipmap;
class GlLeeSplat;
class GlPhotonGather;
class GlSchedlLayered;
class GlUlodBlend;

class GlFrame final : public GpuFrame {
 public:
  explicit GlFrame(GlBackend& backend);
  ~GlFrame() override;
  GlFrame(const GlFrame&) = delete;
  GlFrame& operator=(const GlFrame&) = delete;

  const std::string& unavailable_reason() const override { return unavailable_; }
  void set_effect_passes(GpuPass pass) override { effect_pass_ = pass; }
  void prepare(const Prepare& passes) override;
  std::string effect_passes(GpuPass asked) const override;
  std::string description() const override;
  void render_gbuffer(const FrameTime& time, const BackendSettings& settings, const GBufferPlanes& planes,
                      GBuffer& out) override;
  void read_back(const GBufferPlanes& planes, GBuffer& out) override;
  void upload_hdr(const std::vector<glm::vec3>& hdr, std::uint32_t width, std::uint32_t height) override;
  void dof_lee_mipmap(const dof::CocModel& coc, const dof::LeeMipmapSettings& settings) override;
  dof::SchedlStats dof_schedl_layered(const FrameTime& time, const BackendSettings& peel_settings,
                                      const dof::CocModel& coc, std::uint32_t layers) override;
  void attention_pixels(const attention::AttentionSettings& settings, double near_m, double far_m,
                        const std::vector<std::uint32_t>& ids, const std::vector<float>& motion,
                        std::vector<attention::ObjectPixels>& out) override;
  void attention_pixels_on(const FrameTime& time, const BackendSettings& proxy,
                           const attention::AttentionSettings& settings, double near_m, double far_m,
                           const std::vector<std::uint32_t>& ids, const std::vector<float>& motion,
                           std::vector<attention::ObjectPixels>& out) override;
  void read_saliency(std::vector<float>& saliency) override;
  void ulod_blend(const FrameTime& time, const BackendSettings& next, const std::vector<std::uint32_t>& ids,
                  const std::vector<float>& blend) override;
  void read_rect(std::uint32_t x0, std::uint32_t y0, std::uint32_t x1, std::uint32_t y1, std::vector<float>& depth,
                 std::vector<std::uint32_t>& ids) override;
  void dof_lee_splat(const FrameTime& time, const BackendSettings& peel_settings, const dof::CocModel& coc,
                     const dof::LeeSplatSettings& settings) override;
  void read_hdr(std::vector<glm::vec3>& hdr) override;
  void upload_inset(const std::vector<glm::vec3>& gi, std::uint32_t width, std::uint32_t height, glm::vec2 centre_px,
                    float radius_px, float fovea_fraction) override;
  void gi_gather(const GpuGiGather& gather) override;
  std::string gi_gather_unavailable(std::size_t photons) const override;
  void read_gi(std::vector<glm::vec3>& gi) override;
  void read_gi_labels(std::vector<std::uint8_t>& used, std::vector<double>& traditional,
                      std::vector<double>& gaze) override;
  void tonemap(const GpuTonemap& params) override;
  void overlay(const GpuOverlay& overlay) override;
  GpuCompletion finish() override;
  void read_display(std::vector<std::uint8_t>& rgb, std::uint32_t& width, std::uint32_t& height) override;
  Texture display_texture() const override;

 private:
  // GPU timestamps around one pass; queries are pooled and read once the frame's fence signalled.
  void begin_timed(const char* pass);
  void end_timed();
  unsigned pooled_query();
  void ensure_display(std::uint32_t texture_width, std::uint32_t texture_height);
  void begin_fullscreen_pass(unsigned program);
  unsigned hdr_input() const;  // the texture this frame's tone map reads (hdr_source_)
  // The effect passes run as compute passes when `asked` (the device decides Auto and can refuse).
  bool effect_compute(GpuPass asked) const;
  bool effect_compute() const { return effect_compute(effect_pass_); }

  GlBackend& backend_;
  std::string unavailable_;
  unsigned tonemap_program_ = 0, overlay_program_ = 0, vao_ = 0;
  unsigned tonemap_compute_ = 0;  // GL 4.3: the tone map as a compute pass
  bool compute_faster_ = false;   // ... on a GPU, not a software rasteriser (GpuPass::Auto)
  GpuPass effect_pass_ = GpuPass::Auto;  // set_effect_passes
  unsigned display_fbo_ = 0, display_texture_ = 0;
  std::uint32_t display_tw_ = 0, display_th_ = 0;
  unsigned hdr_texture_ = 0;
  std::uint32_t hdr_w_ = 0, hdr_h_ = 0;
  // What this frame's tone map reads: the G-buffer's colour, the upload of a CPU pass (row 0 at the
  // top), or the GPU dof's output.
  enum class HdrSource { GBuffer, Upload, Dof };
  HdrSource hdr_source_ = HdrSource::GBuffer;
  std::unique_ptr<GlAttention> attention_;   // made on first use
  bool attention_compute();                  // makes attention_; true: this frame runs its compute passes
  std::unique_ptr<GlLeeMipmap> lee_mipmap_;  // made on first use
  std::unique_ptr<GlLeeSplat> lee_splat_;    // made on first use
  std::unique_ptr<GlSchedlLayered> schedl_;  // made on first use
  std::unique_ptr<GlUlodBlend> ulod_;        // made on first use
  std::unique_ptr<GlPhotonGather> gather_;   // made on first use
  unsigned dof_output_ = 0;                  // the texture the last GPU dof wrote
  struct Inset {
    bool active = false;  // this frame has one
    unsigned texture = 0;  // upload_inset's
    unsigned shown = 0;    // what the tone map reads: `texture`, or the GPU gather's output
    glm::ivec2 origin{0}, size{0};  // its box in image pixels (y down)
    glm::vec2 centre{0.0f};
    float radius = 0, fovea = 0;    // pixels
  } inset_;
  std::vector<unsigned> query_pool_;
  struct Timed {
    std::string pass;
    unsigned start = 0, end = 0;
  };
  std::vector<Timed> timed_;  // this frame's passes and their timestamp queries
  std::vector<std::uint8_t> rgba_scratch_;
};

}  // namespace fovea::render
