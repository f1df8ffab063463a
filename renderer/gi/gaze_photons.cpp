// SPDX-License-Identifier: Apache-2.0
#include "gi/gaze_photons.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <utility>

#include "backend/embree/embree_backend.h"
#include "gi/eye_rays.h"
#include "gi/optics.h"

namespace fovea::render::gi {

namespace {

// Eqs. 8.8-8.9: r_new = normalise(r_old + (e_x, e_y, e_z) noiseScale), e uniform in [-1, 1].
glm::vec3 add_noise(const glm::vec3& r, float noise_scale, Pcg32& rng) {
  const glm::vec3 n = glm::vec3(2 * rng.uniform() - 1, 2 * rng.uniform() - 1, 2 * rng.uniform() - 1) * noise_scale;
  const glm::vec3 v = r + n;
  const float len = glm::length(v);
  return len > 1e-6f && std::isfinite(len) ? v / len : r;
}

}  // namespace

std::vector<EmissionDirection> build_emission_map(std::vector<Photon>& photons, const Scene& scene, GazeFrameStats& stats) {
  std::vector<EmissionDirection> map;
  std::vector<std::uint8_t> root_added(photons.size(), 0);
  stats.gaze_photons = 0;
  stats.new_gaze_photons = 0;
  // Algorithm 8.5: newest photons first, so the emission map lists the newest traces first.
  for (std::size_t i = photons.size(); i-- > 0;) {
    if (!(photons[i].flags & kInGazeRegion)) continue;
    ++stats.gaze_photons;
    if (photons[i].flags & kTraditional) ++stats.new_gaze_photons;
    std::size_t j = i;
    bool first = true;
    bool walked = false;
    while (photons[j].parent != kNoParent && photons[j].parent < j) {
      const std::size_t parent = photons[j].parent;
      photons[parent].outgoing = photons[j].incoming;
      photons[parent].flags |= kOnPathToGaze;
      if (first) photons[parent].flags |= kChildInGaze;
      first = false;
      walked = true;
      j = parent;
    }
    // A photon lit straight from the light has no path to record (its light is the ray tracer's
    // direct term); the root of a longer trace gives the emission direction, once per trace.
    if (!walked || root_added[j]) continue;
    root_added[j] = 1;
    const Photon& root = photons[j];
    if (root.light >= scene.lights.size()) continue;
    // The emission itself (the root's incoming direction differs when a mirror or glass came first).
    map.push_back({root.emission_direction, root.emission_origin, root.seed, root.light, (root.flags & kTraditional) != 0});
  }
  return map;
}

void GazePhotonMapper::reset() {
  inactive_ = {};
  inactive_tree_.clear();
  emission_map_.clear();
  last_scale_.clear();
  applied_scale_.clear();
  traditional_flux_.clear();
  gaze_flux_.clear();
  last_traditional_.clear();
  last_gaze_emitted_.clear();
  last_emitted_ = 0;
  frame_ = 0;
}

void GazePhotonMapper::finish_frame(PhotonTraceResult&& rendered, const GiStats& render) {
  inactive_ = std::move(rendered);
  inactive_tree_.clear();
  traditional_flux_ = render.traditional_flux;
  gaze_flux_ = render.gaze_flux;
}

// This frame's emissions: N in all, r N from the emission map (and its fill bin), the rest traditional.
struct GazePhotonMapper::EmissionPlan {
  std::uint64_t n_total = 1, n_gaze = 0, n_trad = 0;
  double ratio = 0.5;  // emissionRatio, within [0, 1]
  std::vector<EmittedPhoton> emissions;
  std::vector<std::uint64_t> trad_per_light, gaze_per_light;
};

namespace {

// Powers (eq. 7.23): Phi_l / N_l for every photon of light l, gaze photons times s_l.
void scale_photon_powers(PhotonTraceResult& r, std::size_t lights, const std::vector<double>& last_scale) {
  for (Photon& p : r.photons) {
    const std::uint64_t n_l = p.light < lights ? r.emitted_per_light[p.light] : 0;
    const double scale = p.kind == EmissionKind::Traditional ? 1.0 : last_scale[p.light];
    p.power = n_l > 0 ? p.power * static_cast<float>(scale / static_cast<double>(n_l)) : glm::vec3(0.0f);
  }
}

}  // namespace

// Without a labelled map from the last frame: traditional photon mapping (§8.4.3).
PhotonTraceResult GazePhotonMapper::trace_traditional(const EmbreeBackend& backend, const TraceSettings& ts,
                                                      GazeFrameStats& st, GazeFrameStats* stats) {
  PhotonTraceResult r = trace_photons(backend, ts);
  last_emitted_ = r.emitted;
  last_traditional_ = r.emitted_per_light;
  last_gaze_emitted_.assign(r.emitted_per_light.size(), 0);
  applied_scale_.assign(r.emitted_per_light.size(), 1.0);
  st.traditional = r.emitted;
  st.note = "traditional emission (no gaze-labelled map from the last frame yet)";
  if (stats) *stats = st;
  return r;
}

// Photon power scaling: s_l = r F_t / ((1 - r) F_g) with the last frame's r and fluxes (see the header).
void GazePhotonMapper::measure_power_scales(std::size_t lights, GazeFrameStats& st) {
  std::vector<double> last_trad(lights, 0), last_gaze(lights, 0);
  // The inactive map's emissions per light (its r), recorded when it was traced.
  for (std::size_t l = 0; l < lights; ++l) {
    last_trad[l] = l < last_traditional_.size() ? static_cast<double>(last_traditional_[l]) : 0.0;
    last_gaze[l] = l < last_gaze_emitted_.size() ? static_cast<double>(last_gaze_emitted_[l]) : 0.0;
  }
  st.scale_measured = true;
  for (std::size_t l = 0; l < lights; ++l) {
    const double total = last_trad[l] + last_gaze[l];
    const double r = total > 0 ? last_gaze[l] / total : 0.0;
    const double f_t = l < traditional_flux_.size() ? traditional_flux_[l] : 0.0;
    const double applied = l < applied_scale_.size() && applied_scale_[l] > 0 ? applied_scale_[l] : 1.0;
    const double f_g = l < gaze_flux_.size() ? gaze_flux_[l] / applied : 0.0;  // as if emitted with s = 1
    const double s_l = f_g > 0 ? r * f_t / ((1 - r) * f_g) : 0.0;
    if (f_t > 0 && f_g > 0 && r > 0 && r < 1 && std::isfinite(s_l) && s_l > 0) {
      last_scale_[l] = s_l;
    } else if (last_gaze[l] > 0 || emission_map_.size() > 0) {
      st.scale_measured = false;  // held: no traditional or no gaze-emitted photon shaded the area
    }
  }
  st.scale = lights > 0 ? last_scale_[0] : 1.0;
}

// Guided diffuse reflections (§8.4.7) from the photons on paths to the gaze region: the guide
// follows the nearest such photon of the inactive map (inactive_tree_, rebuilt here).
DiffuseGuide GazePhotonMapper::diffuse_guide(const GazeDirectedSettings& s) {
  std::vector<std::uint32_t> on_path;
  for (std::size_t i = 0; i < inactive_.photons.size(); ++i) {
    const Photon& p = inactive_.photons[i];
    if ((p.flags & kOnPathToGaze) && glm::dot(p.outgoing, p.outgoing) > 0.5f) on_path.push_back(static_cast<std::uint32_t>(i));
  }
  if (on_path.empty()) {
    inactive_tree_.clear();
  } else {
    inactive_tree_.build(inactive_.photons, on_path);
  }
  const float radius = s.nn_reflect_radius, noise = s.noise_scale;
  const bool guide_traditional = s.gaze_directed_reflections;
  return [&guide_tree = std::as_const(inactive_tree_), radius, noise, guide_traditional](
             const Photon& stored, const glm::vec3& n, Pcg32& rng) -> std::optional<glm::vec3> {
    if (guide_tree.empty() || (stored.kind == EmissionKind::Traditional && !guide_traditional)) return std::nullopt;
    thread_local Neighbours nb;
    guide_tree.nearest(stored.position, 1, radius, nb, [&n](const Photon& p) { return glm::dot(p.normal, n) > 0.5f; });
    if (nb.size() == 0) return std::nullopt;  // case 3: the cosine lobe
    const Photon& q = guide_tree.photons()[nb.index[0]];
    // Case 2: its child reached the gaze region: spread the new photon around it (eqs. 8.8-8.9).
    return (q.flags & kChildInGaze) ? add_noise(q.outgoing, noise, rng) : q.outgoing;  // case 1: the same way
  };
}

// The gaze bins: r N emissions from the emission map, newest first, along the stored origins,
// directions and seeds (§8.4.6: the same path again); past the map's end the fill bin.
void GazePhotonMapper::emit_gaze_photons(const Scene& scene, const GazeDirectedSettings& s, std::uint64_t trace_seed,
                                         EmissionPlan& plan, GazeFrameStats& st) const {
  Pcg32 fill_rng(hash_seed(s.seed, frame_, 0xf111));
  for (std::uint64_t k = 0; k < plan.n_gaze; ++k) {
    EmittedPhoton e;
    if (k < emission_map_.size()) {
      const EmissionDirection& d = emission_map_[k];
      e.origin = d.origin;  // the same origin, direction and random numbers as last time
      e.direction = d.direction;
      e.power = emitted_power(scene.lights[d.light], d.direction);
      e.light = d.light;
      e.seed = d.seed;
      e.kind = d.from_traditional ? EmissionKind::NewGaze : EmissionKind::OldGaze;
      (d.from_traditional ? st.new_gaze : st.old_gaze) += 1;
    } else {
      // The fill bin: a map direction plus noise, a new seed, emitted as an old gaze photon.
      const EmissionDirection& d = emission_map_[fill_rng.next() % emission_map_.size()];
      e.origin = d.origin;
      e.direction = add_noise(d.direction, s.noise_scale, fill_rng);
      e.power = emitted_power(scene.lights[d.light], e.direction);
      e.light = d.light;
      e.seed = hash_seed(trace_seed, 0xf111, k);
      e.kind = EmissionKind::OldGaze;
      ++st.fill;
    }
    plan.emissions.push_back(e);
    ++plan.gaze_per_light[e.light];
  }
}

// This frame's emissions: N in all (the last frame's, adjusted towards maxPhotons stored), r N
// from the emission map, newest first, filled up with noisy map directions; the rest traditional.
GazePhotonMapper::EmissionPlan GazePhotonMapper::plan_emissions(const Scene& scene, const GazeDirectedSettings& s,
                                                                std::uint64_t trace_seed, GazeFrameStats& st) const {
  const std::size_t lights = scene.lights.size();
  EmissionPlan plan;
  plan.n_total = std::max<std::uint64_t>(1, last_emitted_);
  plan.ratio = std::isfinite(s.emission_ratio) ? std::clamp(s.emission_ratio, 0.0, 1.0) : 0.5;
  plan.n_gaze =
      emission_map_.empty() ? 0 : static_cast<std::uint64_t>(std::llround(plan.ratio * static_cast<double>(plan.n_total)));
  plan.n_trad = plan.n_total - plan.n_gaze;
  plan.emissions.reserve(plan.n_total);
  plan.trad_per_light.assign(lights, 0);
  plan.gaze_per_light.assign(lights, 0);
  emit_gaze_photons(scene, s, trace_seed, plan, st);
  // The traditional bin: each light's share of the rest, uniform directions, fresh seeds.
  const std::vector<double> share = light_shares(scene);
  for (std::size_t l = 0; l < lights; ++l) {
    const auto n_l = static_cast<std::uint64_t>(std::llround(share[l] * static_cast<double>(plan.n_trad)));
    for (std::uint64_t k = 0; k < n_l; ++k) plan.emissions.push_back(emit_from_light(scene, l, hash_seed(trace_seed, l, k)));
    plan.trad_per_light[l] = n_l;
  }
  st.traditional = plan.n_trad;
  return plan;
}

// What the next frame needs of this one: its emissions per light (its r), the s its gaze photons
// carry, and an N aimed at maxPhotons stored.
void GazePhotonMapper::remember_emissions(const EmissionPlan& plan, const PhotonTraceResult& r,
                                          const GazeDirectedSettings& s) {
  last_traditional_ = plan.trad_per_light;
  last_gaze_emitted_ = plan.gaze_per_light;
  applied_scale_ = last_scale_;
  // Aim the next frame's emission at maxPhotons stored.
  if (!r.photons.empty()) {
    const double adjust = static_cast<double>(s.max_photons) / static_cast<double>(r.photons.size());
    last_emitted_ = static_cast<std::uint64_t>(std::clamp(static_cast<double>(plan.n_total) * adjust, 1.0,
                                                          static_cast<double>(plan.n_total) * 4.0));
  }
}

PhotonTraceResult GazePhotonMapper::trace(const EmbreeBackend& backend, const GazeDirectedSettings& s, GazeFrameStats* stats) {
  const auto t0 = std::chrono::steady_clock::now();
  const Scene& scene = backend.scene();
  GazeFrameStats st;
  ++frame_;
  TraceSettings ts;
  ts.stored_photons = s.max_photons;
  ts.max_depth = s.trace_depth;
  ts.seed = hash_seed(s.seed, frame_, 0x7ad);
  last_scale_.resize(scene.lights.size(), 1.0);
  if (inactive_.photons.empty() || scene.lights.empty() || s.max_photons == 0) {
    return trace_traditional(backend, ts, st, stats);  // no labelled map from the last frame yet
  }

  // The emission map and the per-light counts of the last frame's gaze photons.
  emission_map_ = build_emission_map(inactive_.photons, scene, st);
  st.emission_map = emission_map_.size();
  const std::size_t lights = scene.lights.size();
  measure_power_scales(lights, st);
  const DiffuseGuide guide = diffuse_guide(s);
  const EmissionPlan plan = plan_emissions(scene, s, ts.seed, st);

  PhotonTraceResult r;
  r.rays = trace_emitted(backend, ts, plan.emissions, r.photons, guide);
  r.emitted = plan.emissions.size();
  r.emitted_per_light.assign(lights, 0);
  for (std::size_t l = 0; l < lights; ++l) r.emitted_per_light[l] = plan.trad_per_light[l] + plan.gaze_per_light[l];
  scale_photon_powers(r, lights, last_scale_);
  remember_emissions(plan, r, s);
  if (!st.scale_measured) {
    st.note = "photon power scaling held from an earlier frame: no traditional or no gaze-emitted photon shaded the last "
              "gaze area (emissionRatio " + std::to_string(plan.ratio) + ")";
  }
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (stats) *stats = st;
  return r;
}

void ImportonMap::build(const EmbreeBackend& backend, const Camera& camera, double now_s, const GazeArea& area,
                        const ImportonSettings& s) {
  importons_.clear();
  reach_ = std::isfinite(s.reach) && s.reach > 0 ? s.reach : 0.0f;
  const EyeRays eye(camera, now_s);
  if (!eye.ok || s.importons == 0 || !(area.radius_px > 0) || !std::isfinite(area.radius_px) ||
      !std::isfinite(area.center_px.x) || !std::isfinite(area.center_px.y)) {
    tree_.clear();
    return;
  }
  std::vector<Photon> found(s.importons);
  std::vector<std::uint8_t> stored(s.importons, 0);
  tbb::parallel_for(tbb::blocked_range<std::uint32_t>(0, s.importons), [&](const tbb::blocked_range<std::uint32_t>& r) {
    for (std::uint32_t k = r.begin(); k < r.end(); ++k) {
      Pcg32 rng(hash_seed(s.seed, 0x1b0, k));
      // A uniform point of the gaze area's disc (clipped to the image).
      const float rad = area.radius_px * std::sqrt(rng.uniform()), phi = 2 * std::numbers::pi_v<float> * rng.uniform();
      const float px = area.center_px.x + rad * std::cos(phi), py = area.center_px.y + rad * std::sin(phi);
      if (px < 0 || py < 0 || px >= static_cast<float>(camera.width) || py >= static_cast<float>(camera.height)) continue;
      glm::vec3 origin = eye.eye, dir = eye.direction_at(px, py);
      SurfaceHit hit;
      for (int depth = 0; depth < 8; ++depth) {
        if (!backend.intersect(origin, dir, 0.0f, std::numeric_limits<float>::infinity(), RayVisibility::All, hit)) break;
        const Material& m = *hit.material;
        const bool front = glm::dot(dir, hit.geometric_normal) < 0.0f;
        const glm::vec3 n = front ? hit.normal : -hit.normal;
        const float eps = optics::surface_epsilon(hit.position);
        if (m.is_diffuse_or_glossy()) {
          Photon& imp = found[k];
          imp.position = hit.position;
          imp.normal = n;
          imp.incoming = glm::normalize(dir);
          imp.power = glm::vec3(1.0f - rad / area.radius_px);  // importance: 1 at the gaze point, 0 at the edge
          stored[k] = 1;
          break;
        }
        if (m.type == MaterialType::Mirror) {
          dir = optics::reflect(glm::normalize(dir), n);
          origin = hit.position + n * eps;
        } else if (m.type == MaterialType::Glass) {
          const float ior = std::isfinite(m.ior) && m.ior > 0 ? m.ior : 1.5f;
          glm::vec3 refracted(0.0f);
          const float f = optics::fresnel_dielectric(glm::normalize(dir), n, front ? 1.0f / ior : ior, refracted);
          if (rng.uniform() < f) {
            dir = optics::reflect(glm::normalize(dir), n);
            origin = hit.position + n * eps;
          } else {
            dir = refracted;
            origin = hit.position - n * eps;
          }
        } else {
          break;  // an emitter: nothing to light
        }
      }
    }
  });
  for (std::uint32_t k = 0; k < s.importons; ++k)
    if (stored[k]) importons_.push_back(found[k]);
  if (importons_.empty()) {
    tree_.clear();
  } else {
    tree_.build_all(importons_);
  }
}

bool ImportonMap::important(const glm::vec3& position, const glm::vec3& normal) const {
  if (tree_.empty() || !(reach_ > 0)) return false;
  thread_local Neighbours nb;
  tree_.nearest(position, 1, reach_, nb, [&normal](const Photon& p) { return p.power.x > 0 && glm::dot(p.normal, normal) > 0.0f; });
  return nb.size() > 0;
}

PhotonTraceResult trace_photons_with_importons(const EmbreeBackend& backend, const TraceSettings& s,
                                               const ImportonMap& importance) {
  TraceSettings t = s;
  t.store_if = [&importance](const glm::vec3& p, const glm::vec3& n) { return importance.important(p, n); };
  if (importance.size() == 0) {
    PhotonTraceResult r;
    r.note = "no importons (the gaze area sees no diffuse surface): no photon stored";
    return r;
  }
  return trace_photons(backend, t);
}

}  // namespace fovea::render::gi
