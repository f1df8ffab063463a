// SPDX-License-Identifier: Apache-2.0
#pragma once
// The frame kept on the GPU: what a backend that rasterises on a GPU (the OpenGL backend) offers
// the frame pipeline beyond Backend::render(). The G-buffer stays in GPU textures; only the planes
// the CPU passes read come back; the tone map, the overlay and the display image are made on the
// GPU; the display image is shown from there (the viewer) or read back once (headless PNGs).
// No graphics API types here: the pipeline and its tests stay free of OpenGL.
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "attention/attention.h"
#include "backend/backend.h"
#include "dof/lee_mipmap.h"
#include "dof/lee_splat.h"
#include "dof/lens.h"
#include "dof/schedl_layered.h"

namespace fovea::render {

// Which implementation a GPU pass with two runs (issue 42): the fragment pass (OpenGL 3.3) or the
// compute pass (OpenGL 4.3); Auto: compute where it is the faster (a GPU with compute shaders, not a
// software rasteriser).
enum class GpuPass { Auto, Fragment, Compute };

// The tone map's parameters as the GPU pass takes them (passes/tonemap.h: same operators).
struct GpuTonemap {
  enum class Op { Reinhard, Clamp, Exponential };
  Op op = Op::Reinhard;
  float exposure = 1.0f;
  // Fragment or compute pass (same formula, same bytes); Auto: as set_effect_passes says. Compute
  // without compute shaders is refused.
  using Pass = GpuPass;
  Pass pass = Pass::Auto;
};

// What the overlay pass draws, in the display image's pixels (passes/overlay.h draws the same on the
// CPU): the gaze ring, the gaze area's ring, and the focused object's outline or iso-depth line.
struct GpuOverlay {
  bool gaze = false;
  double gaze_x = 0.5, gaze_y = 0.5;  // normalized screen coordinates
  bool gaze_valid = false;
  double ring_diameter_px = 0;        // the 1 deg ring (at least 3 px)
  double area_diameter_px = 0;        // 0: no gaze-area ring
  enum class Focus { None, Outline, IsoDepth };
  Focus focus = Focus::None;
  std::uint32_t focus_object = 0;     // Outline: the object whose pixels are outlined
  double focal_depth_m = 0;           // IsoDepth: where the scene crosses this depth
  bool focus_in_transition = false;   // cyan during a transition, yellow when settled
  bool any() const { return gaze || focus != Focus::None; }
};

// When the GPU finished the frame, and what each GPU pass took (timer queries).
struct GpuCompletion {
  double wall_s = 0;  // steady_clock seconds (time_since_epoch) when the fence signalled
  std::vector<std::pair<std::string, double>> pass_ms;  // "gpu.gbuffer", "gpu.tonemap", ... in order
};

// One photon as the GPU gather reads it (gi/photon_map.h's Photon: where it landed, its power, its
// direction of travel).
struct GpuPhoton {
  glm::vec3 position{0.0f}, power{0.0f}, incoming{0.0f};
  std::uint32_t light = 0;   // the emitting light (gi::Photon::light)
  bool traditional = true;   // emitted by the naive emitter (gi::EmissionKind::Traditional), else gaze-emitted
};

// The hybrid renderer's GI of the gaze area gathered where the G-buffer lies (GpuFrame::gi_gather;
// gi/GI.md "On the GPU"): photons traced on the CPU, gathered per pixel by radius.
struct GpuGiGather {
  struct Map {  // one photon map and its radiance estimate (gi/photon_map.h EstimateSettings, fixed_radius)
    const std::vector<GpuPhoton>* photons = nullptr;  // null or empty: no light from this map
    float radius = 0;                                 // metres; every photon within it on the front side
    bool cone = true;                                 // Jensen's cone filter, else the disc's constant
    float cone_k = 1.1f;
  };
  Map indirect, caustic;
  // Label the indirect photons the area's pixels used and sum their flux density per light and kind
  // (gi/gi_render.h's marking, for the gaze-directed mapper: read_gi_labels). At most kMaxLabelLights
  // lights.
  bool label = false;
  std::uint32_t lights = 0;
  static constexpr std::uint32_t kMaxLabelLights = 16;
  // The materials whose pixels are gathered here (gi::gbuffer_materials: diffuse and glossy, eq. 5.22's
  // f_r = kd + ks (n.h)^n); every other object's pixels take `traced`.
  struct Surface {
    std::uint32_t object_id = 0;
    glm::vec3 kd{0.0f}, ks{0.0f};
    float shininess = 1.0f;
  };
  std::vector<Surface> surfaces;
  // The eye rays (gi/eye_rays.h): through image point (px, py), y down, the direction
  // right (2 px / w - 1) + up (1 - 2 py / h) - back (right and up scaled by the half-angles' tangents),
  // with unit forward component, so the G-buffer's depth is the distance along it.
  glm::vec3 eye{0.0f}, right{1, 0, 0}, up{0, 1, 0}, back{0, 0, 1};
  glm::vec3 background{0.0f};  // misses
  glm::vec3 ambient{0.0f};     // taken out of the raster's colour as kd * ambient (0: kept)
  // The CPU's values of the pixels it traced (gi/gi_render.h skip_gbuffer_pixels), full image, row 0
  // at the top; read only where a pixel's object is not among `surfaces`. Null: such pixels are 0.
  const std::vector<glm::vec3>* traced = nullptr;
  glm::vec2 centre_px{0.0f};  // the area (image pixels, y down) and Algorithm 8.4's fovea fraction
  float radius_px = 0, fovea_fraction = 0.7f;
};

class GpuFrame {
 public:
  virtual ~GpuFrame() = default;
  // "" when the GPU passes can run on this device; else why not (one line, for the log and --explain).
  virtual const std::string& unavailable_reason() const = 0;
  // The implementation of the passes that have a fragment and a compute one (the tone map's Auto,
  // attention_pixels, dof_lee_mipmap, dof_schedl_layered, ulod_blend): frame.effect_passes. Compute where the device has none runs the
  // fragment passes; effect_passes(asked) says which would run, and why where it is not what was asked.
  virtual void set_effect_passes(GpuPass) {}
  virtual std::string effect_passes(GpuPass /*asked*/) const { return "fragment"; }
  // The passes a frame's plan may run on the GPU, built ahead of their first use (each compiles its
  // programs, tens of milliseconds): ULOD's blend starts only once an object is between levels, and
  // its first frame carried the compile (66 ms on the H200, the ULOD run's p99).
  struct Prepare {
    bool attention = false, ulod_blend = false, lee_mipmap = false, schedl_layered = false, lee_splat = false;
  };
  virtual void prepare(const Prepare&) {}
  // The device, for people: "OpenGL 4.5 (llvmpipe ...)".
  virtual std::string description() const = 0;
  // Renders the G-buffer into GPU textures (Backend::render's settings; readback is ignored) and
  // makes `out` the render's size without touching its planes. Only `planes` are written: the planes
  // this frame's passes read, on the CPU and on the GPU (the others are culled, as a frame graph
  // culls what nobody reads); colour always.
  virtual void render_gbuffer(const FrameTime& time, const BackendSettings& settings, const GBufferPlanes& planes,
                              GBuffer& out) = 0;
  // Reads `planes` of the G-buffer rendered last into `out` (sized by render_gbuffer).
  virtual void read_back(const GBufferPlanes& planes, GBuffer& out) = 0;
  // The HDR colour a CPU pass made (row 0 at the top, the G-buffer's size) replaces the G-buffer's
  // colour as the tone map's input for this frame.
  virtual void upload_hdr(const std::vector<glm::vec3>& hdr, std::uint32_t width, std::uint32_t height) = 0;
  // Lee 2009 ch. 4's depth of field (dof/lee_mipmap.h's method, the same settings) on the G-buffer's
  // colour and depth where they lie; its result replaces the G-buffer's colour as the tone map's input
  // for this frame.
  virtual void dof_lee_mipmap(const dof::CocModel& coc, const dof::LeeMipmapSettings& settings) = 0;
  // Schedl & Wimmer's layered depth of field (dof/schedl_layered.h) on the G-buffer and `layers` - 1
  // layers peeled behind it where they lie (rendered at `time` with `peel_settings`' lens and LOD
  // levels); the same result's use as dof_lee_mipmap's. Waits for the GPU (the peeling's occlusion
  // queries, the depth range the layers are cut by).
  virtual dof::SchedlStats dof_schedl_layered(const FrameTime& time, const BackendSettings& peel_settings,
                                              const dof::CocModel& coc, std::uint32_t layers) = 0;
  // ULOD's blend of adjacent levels where the frame lies (lod/lod_frame.h ulod_blend's arithmetic;
  // on GL backend/gl/gl_ulod_blend.h): the scene drawn again at `next`'s LOD levels aside, and the
  // G-buffer's colour blended towards it by `blend` per object of `ids` where both images show that
  // object. The G-buffer's colour is the blended one afterwards.
  virtual void ulod_blend(const FrameTime& time, const BackendSettings& next, const std::vector<std::uint32_t>& ids,
                          const std::vector<float>& blend) = 0;
  // Depth and ids of the G-buffer rendered last, pixels [x0, x1) x [y0, y1) (row 0 at the top),
  // row-major, as read_back converts them: what the focus pass looks at. Waits for the GPU.
  virtual void read_rect(std::uint32_t x0, std::uint32_t y0, std::uint32_t x1, std::uint32_t y1, std::vector<float>& depth,
                         std::vector<std::uint32_t>& ids) = 0;
  // Lee 2009 ch. 3's pixel stage (attention/attention.h's update() up to eq. 3.7's sums; on GL
  // backend/gl/gl_attention.h) on the G-buffer where it lies, with the camera's depth range of
  // eq. 3.1: `out` gets the per-object values AttentionTracker::update_objects takes. `ids` and
  // `motion`: the scene's objects and each one's B_m (eq. 3.3). Waits for the GPU (reads back a few
  // values per object).
  virtual void attention_pixels(const attention::AttentionSettings& settings, double near_m, double far_m,
                                const std::vector<std::uint32_t>& ids, const std::vector<float>& motion,
                                std::vector<attention::ObjectPixels>& out) = 0;
  // The same on a G-buffer of its own rendered first at `time` with `proxy`'s LOD levels and size
  // (ULOD's proxy, Lee 2009 §7.2), left on the GPU; the frame's G-buffer is untouched.
  virtual void attention_pixels_on(const FrameTime& time, const BackendSettings& proxy,
                                   const attention::AttentionSettings& settings, double near_m, double far_m,
                                   const std::vector<std::uint32_t>& ids, const std::vector<float>& motion,
                                   std::vector<attention::ObjectPixels>& out) = 0;
  // The last attention_pixels' S_p, map_size^2, row 0 at the top (the finite check, tests). Waits.
  virtual void read_saliency(std::vector<float>& saliency) = 0;
  // Lee 2009 ch. 5's point splatting (dof/lee_splat.h, reduce = 1) on the G-buffer where it lies,
  // with the hidden image peeled there (rendered at `time` with `peel_settings`' lens and LOD
  // levels) when settings.use_hidden; the same result's use as dof_lee_mipmap's.
  virtual void dof_lee_splat(const FrameTime& time, const BackendSettings& peel_settings, const dof::CocModel& coc,
                             const dof::LeeSplatSettings& settings) = 0;
  // The HDR colour the tone map reads now (the G-buffer's, the GPU dof's or the upload), linear, row
  // 0 at the top: for tests and for writing the frame out. Waits for the GPU.
  virtual void read_hdr(std::vector<glm::vec3>& hdr) = 0;
  // The hybrid renderer's GI inset (Jensen & Pedersen 2009, Algorithm 8.4, steps 7-8: GI inside the
  // fovea, a linear ramp to local illumination at the radius; gi/gi_render.h hybrid_composite on the
  // CPU): `gi` is the area's GI, full image size, row 0 at the top, read only inside the circle of
  // `radius_px` around `centre_px` (image pixels, y down). Only the circle's bounding box goes up;
  // this frame's tone map blends it over its HDR input.
  virtual void upload_inset(const std::vector<glm::vec3>& gi, std::uint32_t width, std::uint32_t height,
                            glm::vec2 centre_px, float radius_px, float fovea_fraction) = 0;
  // The same inset made where the G-buffer lies (issue 42): each pixel of the area is the raster's
  // direct light (its ambient taken out) plus the photons within each map's radius weighted by the
  // pixel's BRDF, or the CPU's traced value where the G-buffer cannot answer. Throws
  // std::invalid_argument when `traced` is not the image's size; a device without compute shaders
  // throws std::logic_error (gi_gather_unavailable() says why first).
  virtual void gi_gather(const GpuGiGather& gather) = 0;
  // Why gi_gather cannot run here for maps of up to `photons` photons ("" : it can).
  virtual std::string gi_gather_unavailable(std::size_t /*photons*/) const { return "this GPU frame has no GI gather"; }
  // The last gi_gather's GI image: full image size, row 0 at the top, 0 outside the area's box. Waits.
  virtual void read_gi(std::vector<glm::vec3>& gi) = 0;
  // The last gi_gather's labels (with GpuGiGather::label): per indirect photon (its index in
  // indirect.photons) 1 where a pixel used it, and per light the summed flux density (mean channel
  // power / r^2 over the pixels) of traditional and of gaze-emitted photons. Waits.
  virtual void read_gi_labels(std::vector<std::uint8_t>& used, std::vector<double>& traditional,
                              std::vector<double>& gaze) = 0;
  // HDR colour (the G-buffer's, or the upload of this frame; with this frame's inset composited) to
  // the 8-bit display image (sRGB).
  virtual void tonemap(const GpuTonemap& params) = 0;
  virtual void overlay(const GpuOverlay& overlay) = 0;
  // Waits until the GPU has finished everything the frame submitted; collects the passes' GPU times.
  virtual GpuCompletion finish() = 0;
  // The display image, 8-bit sRGB RGB, row 0 at the top.
  virtual void read_display(std::vector<std::uint8_t>& rgb, std::uint32_t& width, std::uint32_t& height) = 0;
  // The display image where it lies, for a window sharing the backend's textures.
  struct Texture {
    unsigned id = 0;
    std::uint32_t width = 0, height = 0, texture_width = 0, texture_height = 0;
  };
  virtual Texture display_texture() const = 0;
};

}  // namespace fovea::render
