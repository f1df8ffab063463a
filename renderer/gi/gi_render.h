// SPDX-License-Identifier: Apache-2.0
#pragma once
// The second pass of photon mapping and the gaze-directed hybrid render (Jensen & Pedersen 2009,
// §6.3, §7.5, §8.3): eye rays through the pixels of a circular gaze area, shaded with
//   direct light by shadow rays (the modified Blinn-Phong of scene/shading.h, eq. 5.22, the same
//     function the raster side uses, so the two halves of the hybrid image agree),
//   indirect light from the global photon map (photons after at least one diffuse bounce),
//   caustics from the caustic map (light -> specular+ -> diffuse),
//   mirror reflection and glass refraction by recursive rays,
// then blended into the local-illumination image from 0.7 of the radius outward (Algorithm 8.4).
//
// Radiometry: the photon tracer moves light between surfaces with kd as albedo (photon_tracer.h);
// the view-facing BRDF is eq. 5.22's f_r = k_d + k_s (n.h)^n for the direct and the photon terms
// alike, so the ratio of indirect to direct light is the physical one, and the gaze area matches
// the raster image where there is no indirect light. The ambient term of local illumination (its
// stand-in for indirect light) is left out inside the area: the photon map is the real thing.
#include <atomic>
#include <cstdint>
#include <memory>
#include <unordered_map>
#include <vector>

#include "fovea/protocol/display_geometry.h"
#include "backend/gbuffer.h"
#include "gi/photon_map.h"
#include "gi/photon_tracer.h"
#include "scene/scene.h"

namespace fovea::render {
class EmbreeBackend;
}

namespace fovea::render::gi {

// A circle on the image, pixels (x right, y down, pixel centres at +0.5).
struct GazeArea {
  glm::vec2 center_px{0.0f};
  float radius_px = 0;
  bool contains(float x, float y) const;
};

// The pixel rows [y0, y1) and columns [x0, x1) a gaze area's circle touches, clipped to a width x
// height image (empty where nothing of it is on the image, or its centre or radius is not finite).
struct PixelBox {
  std::uint32_t x0 = 0, y0 = 0, x1 = 0, y1 = 0;
};
PixelBox pixel_box(const GazeArea& area, std::uint32_t width, std::uint32_t height);

// The area a visual angle of `diameter_deg` subtends around gaze point (normalised screen
// coordinates, [0, 1]^2, y down) on `display`, for an image `width` x `height` that fills the
// screen (eqs. 2.1-2.2). A non-finite gaze point gives the screen centre.
GazeArea gaze_area(const protocol::DisplayGeometry& display, std::uint32_t width, std::uint32_t height,
                   glm::vec2 gaze_normalized, double diameter_deg);

// The photon maps of one frame.
struct PhotonMaps {
  PhotonTraceResult global;   // every stored photon of the global trace
  PhotonTraceResult caustic;  // the caustic trace's photons (empty without specular/refractive surfaces)
  PhotonMap indirect;         // global photons with >= 1 diffuse bounce (direct light comes from shadow rays)
  PhotonMap caustics;         // all caustic photons
  void index();               // (re)builds both trees over the traces' photons

  // Precomputed irradiance (Christensen 1999, "Faster photon map global illumination"): the flux
  // density at every stride-th indirect photon, from its own neighbourhood (settings' nNN and
  // radius), so a shading point needs only its nearest precomputed photon with a similar normal
  // instead of nNN photons. Glossy indirect light (k_s) is left out: the stored value is irradiance.
  // Lazy (the default): a photon's value is computed the first time a shading point needs it
  // (thread-safe; the same value whichever thread computes it), so only photons near what the gaze
  // area sees cost anything; eager computes all of them up front.
  PhotonMap precomputed;  // the photons that carry a value
  double precompute_seconds = 0;
  void precompute_irradiance(const EstimateSettings& s, std::uint32_t stride, bool lazy = true);
  // Irradiance of precomputed photon i (an index of global.photons), and its flux split by photon
  // kind per light into trad and gaze (lights() floats each; may be null).
  glm::vec3 irradiance_of(std::uint32_t i, Neighbours& scratch, std::vector<std::uint32_t>& used, float* trad,
                          float* gaze) const;
  std::size_t lights() const { return lights_; }
  std::size_t precomputed_count() const;  // values computed so far

 private:
  EstimateSettings precompute_settings_;
  std::size_t lights_ = 0;
  // Per global photon: the value, its split [photon * lights + light], and its state (0 none, 1 being
  // computed, 2 done).
  mutable std::vector<glm::vec3> irradiance_;
  mutable std::vector<float> irradiance_traditional_, irradiance_gaze_;
  mutable std::unique_ptr<std::atomic<std::uint8_t>[]> irradiance_state_;
  glm::vec3 compute_irradiance(std::uint32_t i, Neighbours& scratch, std::vector<std::uint32_t>& used, float* trad,
                               float* gaze) const;
};

// How the indirect term is estimated.
enum class IndirectEstimate {
  Nearest,      // nNN nearest photons per shading point (Jensen & Pedersen §6.3.2)
  Precomputed,  // the nearest precomputed irradiance photon (PhotonMaps::precompute_irradiance)
};

struct GiRenderSettings {
  EstimateSettings estimate;    // nNN = 240, NNRadius = 0.3 m (Table 8.3), cone filter
  EstimateSettings caustic_estimate{60, 0.1f, EstimateFilter::Cone, 1.1f};  // caustics are sharper: fewer, nearer photons
  IndirectEstimate indirect_estimate = IndirectEstimate::Nearest;
  std::uint32_t ray_depth = 5;  // mirror/glass bounces followed by eye rays
  bool shadows = true;
  bool indirect = true;
  bool caustics = true;
  bool ambient = false;  // keep local illumination's ambient term inside the area (false: photons replace it)
  // With `primary`: pixels the G-buffer answers (misses, diffuse and glossy first hits) are left as
  // they are, for the caller to shade (the GPU gather, backend/gpu_frame.h gi_gather); only the
  // pixels that must be traced are. `primary` then needs depth and ids only.
  bool skip_gbuffer_pixels = false;
};

// Per object id, the material whose first hits the G-buffer answers (diffuse and glossy, not a glTF
// material, whose textures need the hit's coordinates), or null where the pixel must be traced: a
// mirror, glass, an emitter, a glTF material, an id that several materials share.
std::unordered_map<std::uint32_t, const Material*> gbuffer_materials(const Scene& scene);

struct GiStats {
  std::uint64_t pixels = 0;           // shaded inside the area
  std::uint64_t rays = 0;             // eye, reflection and refraction rays (shadow rays not counted)
  std::uint64_t primary_from_gbuffer = 0;  // first hits read from the frame's G-buffer, not traced
  std::uint64_t photons_used = 0;     // distinct photons that shaded the area (the gaze photons of §8.4.4)
  // With marking: per light, the indirect flux density the area's shading points gathered from
  // traditionally emitted photons and from gaze-emitted ones (sum over points of sum Phi / r^2, same
  // neighbourhoods for both): what the gaze-directed mapper's power scaling compares.
  std::vector<double> traditional_flux, gaze_flux;
  double render_seconds = 0;
};

// The GI image of a gaze area, traced with `backend` (set to the frame's scene and time) through
// `camera` at scene time now_s. hdr: width x height of the camera, row-major; only pixels inside
// `area` are written. When mark is true the photons that shaded the area get kInGazeRegion in their
// flags, as §8.4.4's ray-tracing step labels them (with precomputed irradiance: the precomputed
// photon each shading point used).
//
// `primary`: the frame's G-buffer when it holds exactly the hits of these eye rays (the Embree
// backend's, same camera, time and levels of detail): the area's first hits on diffuse and glossy
// surfaces, and its background pixels, are then read from its depth, normal and id planes instead of
// being ray traced again (position = eye + direction x depth: EyeRays' directions have unit
// forward component, the depth is along it). Mirrors, glass and emitters are traced as before (a
// refraction needs the geometric normal's side, which the G-buffer does not keep).
void render_gaze_area(const EmbreeBackend& backend, const Camera& camera, double now_s, PhotonMaps& maps,
                      const GazeArea& area, const GiRenderSettings& s, std::vector<glm::vec3>& hdr,
                      GiStats* stats = nullptr, bool mark = false, const GBuffer* primary = nullptr);

// Algorithm 8.4: inside the fovea (fovea_fraction x radius) the GI image, outside the area the
// local one, a linear ramp between. out may alias local. Pixels outside the area are copied.
void hybrid_composite(const std::vector<glm::vec3>& local, const std::vector<glm::vec3>& gi, std::uint32_t width,
                      std::uint32_t height, const GazeArea& area, float fovea_fraction, std::vector<glm::vec3>& out);

}  // namespace fovea::render::gi
