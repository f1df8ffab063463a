// SPDX-License-Identifier: Apache-2.0
#include "gi/gi_pass.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <numbers>

#include "backend/embree/embree_backend.h"
#include "gi/eye_rays.h"
#include "gi/optics.h"
#include "scene/shading.h"

namespace fovea::render::gi {

namespace {

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// Indirect photons that project inside the area and are not hidden from the eye (Tables 9.9-9.10's
// "photons in the gaze region").
std::size_t photons_seen_in_area(const EmbreeBackend& backend, const Camera& camera, double now_s, const GazeArea& area,
                                 const std::vector<Photon>& photons) {
  const glm::mat4 view = camera.view_at(now_s);
  const EyeRays eye(camera, now_s);
  if (!eye.ok) return 0;
  return tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, photons.size()), std::size_t{0},
      [&](const tbb::blocked_range<std::size_t>& r, std::size_t count) {
        for (std::size_t i = r.begin(); i < r.end(); ++i) {
          const Photon& p = photons[i];
          if (p.diffuse_bounces == 0) continue;
          const glm::vec3 v = glm::vec3(view * glm::vec4(p.position, 1.0f));
          if (!(v.z < -1e-4f)) continue;  // behind the camera
          const float px = (v.x / -v.z / eye.tan_x + 1.0f) * 0.5f * static_cast<float>(camera.width);
          const float py = (1.0f - v.y / -v.z / eye.tan_y) * 0.5f * static_cast<float>(camera.height);
          if (!area.contains(px, py) || px < 0 || py < 0 || px >= static_cast<float>(camera.width) ||
              py >= static_cast<float>(camera.height)) {
            continue;
          }
          if (glm::dot(p.normal, eye.eye - p.position) <= 0) continue;  // the photon's side faces away
          const glm::vec3 from = p.position + p.normal * (1e-3f * std::max(1.0f, glm::length(p.position)));
          if (!backend.occluded(from, eye.eye)) ++count;
        }
        return count;
      },
      std::plus<>());
}

// The global map's trace settings (maxPhotons, pmTraceDepth, the seed).
TraceSettings global_trace_settings(const GiPassSettings& s) {
  TraceSettings ts;
  ts.stored_photons = s.photons;
  ts.max_depth = s.trace_depth;
  ts.seed = s.seed;
  return ts;
}

// The caustic map (light -> specular -> diffuse) for scenes with specular or refractive surfaces;
// empty for the others, or when the settings ask for none.
PhotonTraceResult trace_caustic_map(const EmbreeBackend& backend, const GiPassSettings& s) {
  if (!s.caustics || s.caustic_photons == 0 || !backend.scene().has_specular_or_refractive()) return {};
  TraceSettings cs;
  cs.mode = TraceMode::Caustic;
  cs.stored_photons = s.caustic_photons;
  cs.max_depth = std::max<std::uint32_t>(s.trace_depth, 2);  // light -> specular -> diffuse at least
  cs.seed = hash_seed(s.seed, 0xca05, 0);
  return trace_photons(backend, cs);
}

// The periphery by CSF-driven ray casting (Murphy 2007): rays where the eye can resolve them, shaded
// with the same local illumination and shadows as the G-buffer.
CsfReconstruction csf_periphery(const EmbreeBackend& backend, const Camera& camera, double now_s, const GazeArea& area,
                                const GiPassSettings& s) {
  const Scene& scene = backend.scene();
  const EyeRays eye(camera, now_s);
  const bool shadows = s.render.shadows;
  const auto cast = [&](glm::vec2 px, SurfaceHit& hit) {
    return eye.ok && backend.intersect(eye.eye, eye.direction_at(px.x, px.y), 0.0f,
                                       std::numeric_limits<float>::infinity(), RayVisibility::All, hit);
  };
  const ObjectAt object_at = [&](glm::vec2 px) -> std::uint32_t {
    SurfaceHit hit;
    return cast(px, hit) ? hit.object_id : 0u;
  };
  const ColourAt colour_at = [&](glm::vec2 px, std::uint32_t) -> glm::vec3 {
    SurfaceHit hit;
    if (!cast(px, hit)) return scene.background;
    const glm::vec3 dir = eye.direction_at(px.x, px.y);
    const glm::vec3 n = glm::dot(dir, hit.geometric_normal) < 0.0f ? hit.normal : -hit.normal;
    struct Shadow {
      const EmbreeBackend* backend;
      glm::vec3 offset;
    } shadow{&backend, n * optics::surface_epsilon(hit.position)};
    const VisibilityFn visible = [](void* c, const glm::vec3& from, const glm::vec3& to) {
      const auto* sh = static_cast<const Shadow*>(c);
      return !sh->backend->occluded(from + sh->offset, to);
    };
    const glm::vec3 c =
        shade_local(scene, *hit.material, hit.position, n, eye.eye, shadows ? visible : nullptr, &shadow);
    return optics::finite3(c) ? c : glm::vec3(0.0f);
  };
  const glm::vec2 gaze = area.center_px;
  return render_csf(scene.display, camera.width, camera.height, gaze, s.csf, object_at, colour_at);
}

// What decides the maps' photons (a change in any of them: the worker's maps are not this frame's).
bool same_maps_settings(const GiPassSettings& a, const GiPassSettings& b) {
  return a.photons == b.photons && a.caustic_photons == b.caustic_photons && a.caustics == b.caustics &&
         a.trace_depth == b.trace_depth && a.seed == b.seed && a.strategy == b.strategy;
}

// The maps' sizes and the first note (fewer photons than asked, or power scaling held) for the result.
void record_map_stats(const PhotonMaps& maps, GiPassResult& r) {
  r.photons = maps.global.photons.size();
  r.caustic_photons = maps.caustic.photons.size();
  r.emitted = maps.global.emitted + maps.caustic.emitted;
  r.note = !maps.global.note.empty() ? maps.global.note
           : !r.gaze.note.empty()    ? r.gaze.note
                                     : maps.caustic.note;
}

}  // namespace

double surface_area_m2(const Scene& scene) {
  double area = 0;
  for (const Object& o : scene.objects) {
    if (!o.mesh) continue;
    const glm::mat4 m = o.transform_at(0).matrix();
    const Mesh& mesh = *o.mesh;
    double a = 0;
    for (std::size_t i = 0; i + 2 < mesh.indices.size(); i += 3) {
      if (mesh.indices[i] >= mesh.positions.size() || mesh.indices[i + 1] >= mesh.positions.size() ||
          mesh.indices[i + 2] >= mesh.positions.size())
        continue;
      const glm::vec3 p0 = m * glm::vec4(mesh.positions[mesh.indices[i]], 1.0f);
      const glm::vec3 p1 = m * glm::vec4(mesh.positions[mesh.indices[i + 1]], 1.0f);
      const glm::vec3 p2 = m * glm::vec4(mesh.positions[mesh.indices[i + 2]], 1.0f);
      a += 0.5 * static_cast<double>(glm::length(glm::cross(p1 - p0, p2 - p0)));
    }
    if (std::isfinite(a)) area += a;
  }
  return area;
}

float auto_nn_radius(double area_m2, std::uint32_t nearest, std::uint32_t photons) {
  constexpr float kTable83 = 0.3f;
  if (!(area_m2 > 0) || !std::isfinite(area_m2) || nearest == 0 || photons == 0) return kTable83;
  const double r = std::sqrt(static_cast<double>(nearest) * area_m2 / (std::numbers::pi * static_cast<double>(photons)));
  return std::isfinite(r) && r > 0 ? static_cast<float>(std::clamp(r, 1e-4, 1000.0)) : kTable83;
}

const char* to_string(Strategy s) {
  switch (s) {
    case Strategy::Traditional: return "traditional";
    case Strategy::GazeDirected: return "gaze-directed";
    case Strategy::Importon: return "importon";
  }
  return "traditional";
}

GiPass::GiPass() : own_(std::make_unique<EmbreeBackend>()), backend_(own_.get()) {}
GiPass::GiPass(EmbreeBackend& shared) : backend_(&shared), has_scene_(true) {}
GiPass::~GiPass() { drop_next_maps(); }

void GiPass::set_scene(const Scene& scene) {
  drop_next_maps();                  // traced in the old scene, and the backend is about to change
  if (own_) own_->set_scene(scene);  // a shared backend has the scene from its owner
  has_scene_ = true;
  gaze_mapper_.reset();  // last frame's paths belong to the old scene
}

// The global map by strategy: traditional, gaze-directed (steered by last frame's labelled map), or
// emitted towards the importons the gaze area sees.
void GiPass::trace_global_map(const Camera& camera, double now_s, const GazeArea& area, const GiPassSettings& s) {
  TraceSettings ts = global_trace_settings(s);
  if (s.strategy == Strategy::GazeDirected) {
    GazeDirectedSettings gs = s.gaze;
    gs.max_photons = s.photons;
    gs.trace_depth = s.trace_depth;
    gs.seed = s.seed;
    maps_.global = gaze_mapper_.trace(*backend_, gs, &result_.gaze);
  } else if (s.strategy == Strategy::Importon) {
    ImportonSettings is;
    is.importons = s.importons;
    is.reach = s.render.estimate.max_radius;
    is.seed = s.seed;
    importons_.build(*backend_, camera, now_s, area, is);
    result_.importons = importons_.size();
    ts.max_emitted_per_stored = 1000;  // most photons land where the gaze area cannot see them
    maps_.global = trace_photons_with_importons(*backend_, ts, importons_);
  } else {
    maps_.global = trace_photons(*backend_, ts);
  }
}

const GiPassResult& GiPass::run(const Camera& camera, double now_s, const GazeArea& area, const GiPassSettings& s,
                                const std::vector<glm::vec3>& local, std::vector<glm::vec3>& out,
                                const GBuffer* primary) {
  assert(&out != &local && "GiPass::run: out may not alias local (gi_pass.h)");
  result_ = GiPassResult{};
  result_.strategy = s.strategy;
  // The worker traces with the backend as the last frame left it: done before the time moves on.
  const auto waiting = std::chrono::steady_clock::now();
  if (next_.done.valid()) next_.done.wait();
  next_.waited_ms = ms_since(waiting);
  backend_->set_time(now_s);
  const bool gaze_directed = s.strategy == Strategy::GazeDirected;
  if (!gaze_directed) gaze_mapper_.reset();

  // A second eye's run keeps the maps (and their precomputed irradiance) of the first.
  const bool overlap = can_overlap(s);
  if (!overlap) drop_next_maps();
  if (!s.reuse_maps) {
    if (overlap) {
      take_overlapped_maps(camera, now_s, area, s);
    } else {
      trace_maps(camera, now_s, area, s);
    }
  }
  auto t0 = std::chrono::steady_clock::now();
  if (!s.reuse_maps && s.render.indirect_estimate == IndirectEstimate::Precomputed) {
    maps_.precompute_irradiance(s.render.estimate, s.precompute_stride);
    result_.precompute_ms = ms_since(t0);
  }

  // The periphery by CSF-driven ray casting (Murphy 2007), when asked, in place of `local`.
  const std::vector<glm::vec3>* base = &local;
  if (s.csf_periphery) {
    t0 = std::chrono::steady_clock::now();
    CsfReconstruction rec = csf_periphery(*backend_, camera, now_s, area, s);
    periphery_ = std::move(rec.colours);
    result_.csf = rec.stats;
    base = &periphery_;
    result_.periphery_ms = ms_since(t0);
  }

  // The second pass inside the area, then Algorithm 8.4.
  t0 = std::chrono::steady_clock::now();
  gi_color_.assign(base->size(), glm::vec3(0.0f));
  render_gaze_area(*backend_, camera, now_s, maps_, area, s.render, gi_color_, &result_.render,
                   gaze_directed || s.label_gaze_photons, primary);
  result_.render_ms = ms_since(t0);
  if (s.composite) {
    t0 = std::chrono::steady_clock::now();
    hybrid_composite(*base, gi_color_, camera.width, camera.height, area, s.fovea, out);
    result_.composite_ms = ms_since(t0);
  }

  if (s.count_area_photons) result_.area_photons = photons_seen_in_area(*backend_, camera, now_s, area, maps_.global.photons);
  record_map_stats(maps_, result_);
  // The labelled map steers the next frame (it is not read again this frame).
  finish_deferred_ = gaze_directed && !s.keep_maps && s.defer_gaze_finish;
  if (gaze_directed && !s.keep_maps && !s.defer_gaze_finish) gaze_mapper_.finish_frame(std::move(maps_.global), result_.render);
  // The next frame's maps, while this frame goes on (a stereo frame's once its second eye is done).
  if (overlap && !s.keep_maps) start_next_maps(s);
  return result_;
}

void GiPass::add_labels(const std::vector<std::uint32_t>& used, const std::vector<double>& traditional,
                        const std::vector<double>& gaze) {
  std::vector<Photon>& photons = maps_.global.photons;
  for (const std::uint32_t i : used) {
    if (i >= photons.size() || (photons[i].flags & kInGazeRegion) != 0) continue;
    photons[i].flags |= kInGazeRegion;
    ++result_.render.photons_used;
  }
  GiStats& r = result_.render;
  r.traditional_flux.resize(std::max(r.traditional_flux.size(), traditional.size()), 0.0);
  r.gaze_flux.resize(std::max(r.gaze_flux.size(), gaze.size()), 0.0);
  for (std::size_t l = 0; l < traditional.size(); ++l) r.traditional_flux[l] += traditional[l];
  for (std::size_t l = 0; l < gaze.size(); ++l) r.gaze_flux[l] += gaze[l];
}

void GiPass::finish_gaze_frame() {
  if (!finish_deferred_) return;
  finish_deferred_ = false;
  gaze_mapper_.finish_frame(std::move(maps_.global), result_.render);
}

bool GiPass::can_overlap(const GiPassSettings& s) const {
  return s.overlap && own_ != nullptr && s.strategy == Strategy::Traditional;
}

void GiPass::take_overlapped_maps(const Camera& camera, double now_s, const GazeArea& area, const GiPassSettings& s) {
  if (!next_.done.valid() || !same_maps_settings(next_.settings, s)) {
    drop_next_maps();
    trace_maps(camera, now_s, area, s);
    return;
  }
  next_.done.get();  // ready (run waited); rethrows what the worker threw
  result_.photons_ms = next_.waited_ms;
  result_.overlapped = true;
  result_.overlapped_trace_ms = next_.trace_ms;
  maps_ = std::move(next_.maps);  // the trees' spans move with the photons' buffers
  next_.maps = PhotonMaps{};
}

// The worker traces with the backend at the time this frame set; the next run waits for it before it
// sets the backend's time again.
void GiPass::start_next_maps(const GiPassSettings& s) {
  next_.settings = s;
  next_.done = std::async(std::launch::async, [this] {
    const auto t0 = std::chrono::steady_clock::now();
    // trace_maps for the traditional strategy, the only one overlapped (can_overlap).
    next_.maps.global = trace_photons(*backend_, global_trace_settings(next_.settings));
    next_.maps.caustic = trace_caustic_map(*backend_, next_.settings);
    next_.maps.index();
    next_.trace_ms = ms_since(t0);
  });
}

void GiPass::drop_next_maps() {
  if (next_.done.valid()) {
    try {
      next_.done.get();
    } catch (const std::exception&) {  // its maps are not used; this frame traces its own and says why if it fails too
    }
  }
  next_.maps = PhotonMaps{};
}

// The first pass: the global map by strategy and the caustic map for specular or refractive
// surfaces, then their kd-trees.
void GiPass::trace_maps(const Camera& camera, double now_s, const GazeArea& area, const GiPassSettings& s) {
  auto t0 = std::chrono::steady_clock::now();
  trace_global_map(camera, now_s, area, s);
  maps_.caustic = trace_caustic_map(*backend_, s);
  result_.photons_ms = ms_since(t0);
  t0 = std::chrono::steady_clock::now();
  maps_.index();
  result_.index_ms = ms_since(t0);
}

}  // namespace fovea::render::gi
