// SPDX-License-Identifier: Apache-2.0
#pragma once
// One frame of gaze-directed hybrid rendering (Jensen & Pedersen 2009, ch. 7-8) as one object: the
// photon maps by the chosen strategy, the GI of the gaze area, and the composite into the local
// image (Algorithm 8.4). The frame pipeline's gi pass and bench_gi both run it. It ray traces with
// the frame's own Embree backend when the frame has one (one BVH of the scene, at the frame's
// levels of detail), else with an Embree backend of its own (beside the raster backend).
#include <cstdint>
#include <future>
#include <memory>
#include <string>
#include <vector>

#include "gi/csf_mask.h"
#include "gi/gaze_photons.h"
#include "gi/gi_render.h"

namespace fovea::render {
class EmbreeBackend;
}

namespace fovea::render::gi {

enum class Strategy { Traditional, GazeDirected, Importon };
const char* to_string(Strategy s);

// The scene's surface area in square metres: every object's full mesh, in world space at time 0.
double surface_area_m2(const Scene& scene);

// The radiance estimate's radius (NNRadius) for a scene of `area_m2` with `photons` stored: the
// disc that holds `nearest` photons where they spread evenly over the surfaces, r = sqrt(k A /
// (pi N)) (Jensen's density estimate read backwards). Table 8.3's 0.3 m is this rule for its 2 m
// room; a 26 m courtyard needs metres. Falls back to 0.3 m when the area or counts are unusable.
float auto_nn_radius(double area_m2, std::uint32_t nearest, std::uint32_t photons);

struct GiPassSettings {
  Strategy strategy = Strategy::Traditional;
  std::uint32_t photons = 40000;          // stored in the global map (maxPhotons)
  std::uint32_t caustic_photons = 20000;  // stored in the caustic map (only with specular/refractive surfaces)
  bool caustics = true;
  std::uint32_t trace_depth = 3;          // pmTraceDepth
  std::uint64_t seed = 1;
  GiRenderSettings render;
  std::uint32_t precompute_stride = 4;    // with render.indirect_estimate = Precomputed
  GazeDirectedSettings gaze;              // strategy GazeDirected (max_photons, trace_depth, seed taken from above)
  std::uint32_t importons = 10000;        // strategy Importon (reach: render.estimate.max_radius)
  float fovea = 0.7f;                     // Algorithm 8.4's share of the radius shown as pure GI
  // Algorithm 8.4's composite here (out = local with the area's GI blended in); false: the caller
  // composites gi_image() itself (the GPU-resident frame, on the GPU), `local` is not read and `out`
  // is left as it is.
  bool composite = true;
  // The periphery (outside the gaze area): the caller's local image, or Murphy 2007's CSF-driven ray
  // casting (csf_mask.h: rays where the eye can resolve them, interpolated elsewhere, with the same
  // local illumination and shadows as the G-buffer), which then replaces `local`.
  bool csf_periphery = false;
  CsfSettings csf;
  // Label the photons that shade the area even when the strategy does not need it (statistics).
  bool label_gaze_photons = false;
  // Count the indirect photons visible inside the area (bench_gi's density measure; ~1 ray each).
  bool count_area_photons = false;
  // A stereo frame's two eyes share one set of photon maps (they depend on the scene, not the view):
  // the first eye's run traces them and keeps them (keep_maps: the gaze-directed mapper is not
  // handed them yet), the second's reuses them (reuse_maps: nothing traced or indexed; the maps of
  // the last run, which must be of the same scene time) and then hands them on, so the photons both
  // eyes' areas used steer the next frame. Both false for one view.
  bool keep_maps = false, reuse_maps = false;
  // Trace the next frame's photon maps on a worker thread once this frame's are used (issue 42: CPU
  // tracing overlapped with the GPU's gather and the next frame's G-buffer), so a frame waits only for
  // what is left of it. A frame then renders with the maps traced at the previous frame's scene time:
  // one frame late where objects or lights move (the first frame, and a frame after set_scene or a
  // change of settings, traces its own). Taken only with the traditional strategy (gaze-directed
  // photons follow this frame's labels, importons this frame's area) and an Embree backend of the
  // pass's own (the frame's renders meanwhile); otherwise ignored.
  bool overlap = false;
  // The caller labels more of the photons this run used (the GPU gather: add_labels) and then calls
  // finish_gaze_frame, instead of run handing the labelled map to the gaze-directed mapper itself.
  bool defer_gaze_finish = false;
};

struct GiPassResult {
  Strategy strategy = Strategy::Traditional;
  GiStats render;
  GazeFrameStats gaze;
  std::size_t photons = 0, caustic_photons = 0, importons = 0;
  std::uint64_t emitted = 0;
  std::size_t area_photons = 0;  // with count_area_photons: indirect photons seen inside the area
  CsfStats csf;                  // with csf_periphery: rays cast against full resolution
  double periphery_ms = 0;
  std::string note;              // fewer photons than asked and why, or power scaling held
  // Stage times, milliseconds.
  double photons_ms = 0, index_ms = 0, precompute_ms = 0, render_ms = 0, composite_ms = 0;
  // With overlap: the maps came from the worker (photons_ms then is the wait for it, index_ms 0), and
  // what tracing and indexing them took there.
  bool overlapped = false;
  double overlapped_trace_ms = 0;
};

class GiPass {
 public:
  // An Embree backend of its own; set_scene() gives it the scene.
  GiPass();
  // Traces with `shared` (the frame's backend, which outlives this pass): its scene, its time and the
  // levels of detail of its last render. set_scene() then only starts the pass afresh.
  explicit GiPass(EmbreeBackend& shared);
  ~GiPass();
  GiPass(const GiPass&) = delete;
  GiPass& operator=(const GiPass&) = delete;

  void set_scene(const Scene& scene);
  // One frame at scene time now_s: out = local with the GI of `area` blended in (unless
  // s.composite is false). local and out are camera.width x camera.height; out may not alias local.
  // `primary`: the frame's G-buffer when it holds this camera's first hits exactly (the frame's
  // Embree backend's): the area's eye rays are not traced again (render_gaze_area).
  const GiPassResult& run(const Camera& camera, double now_s, const GazeArea& area, const GiPassSettings& s,
                          const std::vector<glm::vec3>& local, std::vector<glm::vec3>& out,
                          const GBuffer* primary = nullptr);
  // The GI of the area alone (HDR, 0 outside it) from the last run.
  const std::vector<glm::vec3>& gi_image() const { return gi_color_; }
  const GiPassResult& last() const { return result_; }
  // The last run's photon maps (a GPU gather reads them).
  const PhotonMaps& maps() const { return maps_; }
  // What a GPU gather labelled of the last run's photons (indices into maps().global.photons) and the
  // flux density it gathered per light from traditional and gaze-emitted photons (GiStats'): added to
  // the run's own labels and sums, as render_gaze_area's marking does.
  void add_labels(const std::vector<std::uint32_t>& used, const std::vector<double>& traditional,
                  const std::vector<double>& gaze);
  // After a run with defer_gaze_finish: the labelled map to the gaze-directed mapper (it steers the
  // next frame). Nothing when that run did not defer.
  void finish_gaze_frame();
  const EmbreeBackend& backend() const { return *backend_; }

 private:
  void trace_maps(const Camera& camera, double now_s, const GazeArea& area, const GiPassSettings& s);
  // overlap: this frame's maps from the worker when it traced them with these settings (waits), else
  // traced here; and the worker started on the next frame's.
  bool can_overlap(const GiPassSettings& s) const;
  void take_overlapped_maps(const Camera& camera, double now_s, const GazeArea& area, const GiPassSettings& s);
  void start_next_maps(const GiPassSettings& s);
  void drop_next_maps();  // waits for the worker and forgets its maps
  void trace_global_map(const Camera& camera, double now_s, const GazeArea& area, const GiPassSettings& s);

  std::unique_ptr<EmbreeBackend> own_;  // null when tracing with the frame's backend
  EmbreeBackend* backend_ = nullptr;    // own_ or the frame's
  bool has_scene_ = false;
  bool finish_deferred_ = false;  // the last run left finish_gaze_frame to the caller
  PhotonMaps maps_;
  GazePhotonMapper gaze_mapper_;
  ImportonMap importons_;
  std::vector<glm::vec3> gi_color_, periphery_;
  struct Next {  // the worker's maps of the next frame
    std::future<void> done;
    PhotonMaps maps;
    GiPassSettings settings;  // what they were traced with
    double trace_ms = 0;
    double waited_ms = 0;  // by this run, before it set the backend's time
  } next_;
  GiPassResult result_;
};

}  // namespace fovea::render::gi
