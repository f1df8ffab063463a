// SPDX-License-Identifier: Apache-2.0
#pragma once
// A G-buffer backend: Embree ray casting (backend/embree) or OpenGL raster (backend/gl). Both
// produce the same G-buffer for the same scene and time, up to rasterization tolerance, and shade
// with the same BRDF (scene/shading.h), so their images can be composited without a seam.
#include <memory>
#include <string>
#include <vector>

#include "backend/gbuffer.h"
#include "backend/lens_sample.h"
#include "scene/scene.h"

namespace fovea::render {

struct FrameTime {
  double now_s = 0;       // scene time of this frame
  double previous_s = 0;  // scene time of the previous frame (motion vectors); == now_s for the first
};

struct BackendSettings {
  bool shadows = false;   // shadow rays for direct light (Embree); GL ignores this and says so
  // Thin-lens primary rays (the DOF references). Embree: per pixel or one point; GL: one point only
  // (an off-axis frustum), per_pixel is refused. Depth stays view-axis depth from the lens plane.
  LensSample lens;
  // Depth peeling by object (Lee 2009 §5.1.2's hidden image H; Schedl & Wimmer's M layers): with
  // peel = n each pixel shows the surface of the n-th object met behind the visible one along its
  // ray (background where there is none); an object's own back faces and other parts are skipped
  // (each object counts once). 0: the visible surface. Both backends (the raster one by depth peeling,
  // backend/gl/gl_peel.h; render() only: the layer is read back).
  std::uint32_t peel = 0;
  // Level of detail per scene object (index into Scene::objects): 0 the full mesh, k the object's
  // lods[k - 1], clamped to what it has. Empty (or shorter than the object list): full detail.
  // Embree switches geometry per frame; the raster backend draws the chosen mesh too.
  std::vector<std::uint8_t> lod_levels;
  // Render at width x height instead of the camera's resolution (0: the camera's), with the camera's
  // field of view and aspect (pixels stretch if the aspect differs). The attention pass's proxy
  // G-buffer (Lee 2009 §7.2) is rendered near the saliency map's size this way.
  std::uint32_t width = 0, height = 0;
  // Non-empty (one byte per output pixel): only the pixels marked non-zero need to be right; the
  // Embree backend skips 16x16 tiles with none marked (background there). ULOD's second pass reads only
  // the pixels of objects between levels. The raster backend draws everything regardless.
  std::vector<std::uint8_t> pixel_mask;
  // The planes the caller reads. The raster backend reads back only these from the GPU (the others
  // keep what GBuffer::resize() leaves: depth at the far plane, the rest 0); the Embree backend
  // writes every plane anyway. ULOD's second pass reads colour and id; the GPU-resident frame
  // reads what its CPU passes read, or nothing.
  GBufferPlanes readback = GBufferPlanes::all();
  // Raster backend: lay down the z-buffer first with a position-only pass, then shade with the z
  // test at equal, so every pixel is shaded once however many surfaces cover it (the G-buffer pass is
  // bound by fragment shading and writes, bench/RESULTS.md). The image is the same but where two
  // surfaces lie at exactly one depth: the later-drawn wins instead of the first. Embree ignores it.
  bool depth_prepass = false;
  // Raster backend with compute shaders (BackendCapabilities::visibility_buffer): rasterise only
  // triangle ids, then rebuild the planes and shade each pixel once in a compute pass
  // (GlVisibilityPass). Where the backend cannot, it draws the forward G-buffer and says so once.
  bool visibility_buffer = false;
  // Raster backend, peeled layers (peel > 0, render_peeled_layers): peel through the visibility
  // buffer where the backend can (each peeling draw writes triangle ids, each layer kept is shaded
  // once; 1.7-2.3x faster than shading every draw even on llvmpipe, bench/RESULTS.md); false: the
  // forward peel. The layers are the same.
  bool peel_visibility = true;
  // Raster backend: render() draws into targets of its own (forward shading) and reads back from
  // there, so the G-buffer a GPU-resident frame keeps in the backend's textures stays as it is (the
  // DOF references render the scene again mid-frame). Embree ignores it.
  bool keep_frame = false;
};

// What a backend can do beyond the G-buffer every backend renders. Passes ask this, never the
// backend's name.
struct BackendCapabilities {
  bool shadow_rays = false;     // honours BackendSettings::shadows
  bool per_pixel_lens = false;  // BackendSettings::lens with a lens point per pixel (the ray-traced DOF reference)
  bool peeling = false;         // BackendSettings::peel > 0 (Lee's hidden image, Schedl & Wimmer's layers)
  bool visibility_buffer = false;  // BackendSettings::visibility_buffer (GL 4.3 compute shaders)
  // ... and it is the faster G-buffer here: a GPU, not a software rasteriser (bench/RESULTS.md: 3x
  // faster on an H200, 2-4x slower on llvmpipe). frame.gbuffer_pass=auto follows this.
  bool visibility_buffer_faster = false;
  // The GPU passes run on a software rasteriser (Mesa's llvmpipe: the CPU's own cores).
  bool software_rasteriser = false;
  bool operator==(const BackendCapabilities&) const = default;
};

class GpuFrame;

class Backend {
 public:
  virtual ~Backend() = default;
  virtual std::string name() const = 0;  // for people: logs, file names, --explain
  virtual BackendCapabilities capabilities() const = 0;
  // Builds acceleration structures / uploads meshes. Called again when the scene changes.
  virtual void set_scene(const Scene& scene) = 0;
  // The camera of the scene set last changes (a stereo frame's other eye, the viewer's moves):
  // nothing is built or uploaded again. Ignored before set_scene().
  virtual void set_camera(const Camera& camera) = 0;
  // Renders the scene set last at the given time into `out` (resized to the camera's resolution).
  virtual void render(const FrameTime& time, const BackendSettings& settings, GBuffer& out) = 0;
  // The depth-peeled layers 1..out.size() behind the visible one (settings.peel is ignored), layer k
  // into out[k - 1]. By default one render per layer; the raster backend finds them all in one
  // peeling loop.
  virtual void render_peeled_layers(const FrameTime& time, const BackendSettings& settings, std::vector<GBuffer>& out) {
    for (std::size_t k = 0; k < out.size(); ++k) {
      BackendSettings layer = settings;
      layer.peel = static_cast<std::uint32_t>(k + 1);
      render(time, layer, out[k]);
    }
  }
  // The GPU-resident frame (backend/gpu_frame.h), or null where the backend has none (Embree). Owned
  // by the backend; check its unavailable_reason() before use.
  virtual GpuFrame* gpu_frame() { return nullptr; }
};

enum class BackendKind { Embree, OpenGL };
// Throws std::runtime_error with the reason if the backend cannot start (e.g. no display for GL).
std::unique_ptr<Backend> make_backend(BackendKind kind);

}  // namespace fovea::render
