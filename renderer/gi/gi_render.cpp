// SPDX-License-Identifier: Apache-2.0
#include "gi/gi_render.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <unordered_map>
#include <chrono>
#include <cmath>
#include <numbers>

#include "backend/embree/embree_backend.h"
#include "gi/eye_rays.h"
#include "gi/optics.h"
#include "scene/shading.h"

namespace fovea::render::gi {

namespace {

using optics::finite3;
using optics::reflect;
using optics::surface_epsilon;
glm::vec3 finite_or_zero(const glm::vec3& v) { return finite3(v) ? v : glm::vec3(0.0f); }

// Shadow rays for shade_local, from the shaded point pushed off its surface.
struct ShadowRays {
  const EmbreeBackend* backend = nullptr;
  glm::vec3 offset{0.0f};
};
bool visible(void* context, const glm::vec3& from, const glm::vec3& to) {
  const auto* c = static_cast<const ShadowRays*>(context);
  return !c->backend->occluded(from + c->offset, to);
}

// Adds each photon's flux density (mean channel power / r^2) to its light's traditional or gaze sum.
void accumulate_flux_by_kind(const std::vector<Photon>& photons, const std::vector<std::uint32_t>& used, float r2,
                             std::vector<double>& traditional, std::vector<double>& gaze) {
  if (!(r2 > 0)) return;
  for (std::uint32_t i : used) {
    const Photon& p = photons[i];
    if (p.light >= traditional.size()) continue;
    const double flux = static_cast<double>((p.power.x + p.power.y + p.power.z) / (3.0f * r2));
    (p.kind == EmissionKind::Traditional ? traditional : gaze)[p.light] += flux;
  }
}

// Labels a photon as used (relaxed atomic byte stores: many shading points share photons).
void label(std::uint8_t* seen, std::uint32_t i) { std::atomic_ref<std::uint8_t>(seen[i]).store(1, std::memory_order_relaxed); }

struct Tracer {
  const EmbreeBackend& backend;
  const Scene& lights;  // the scene's lights, without ambient unless asked for
  const PhotonMaps& maps;
  const GiRenderSettings& s;
  std::uint8_t* seen_indirect;  // per global photon, when labelling
  std::uint8_t* seen_caustic;   // per caustic photon
  struct Local {
    Neighbours scratch;
    std::vector<std::uint32_t> used;
    Neighbours estimate_scratch;           // a lazily precomputed photon's own neighbourhood
    std::vector<float> trad_split, gaze_split;
    std::vector<double> traditional_flux, gaze_flux;
    std::uint64_t rays = 0;
  };

  glm::vec3 radiance(const glm::vec3& origin, const glm::vec3& dir, std::uint32_t depth, Local& local, bool mark) const {
    ++local.rays;
    SurfaceHit hit;
    if (!backend.intersect(origin, dir, 0.0f, std::numeric_limits<float>::infinity(), RayVisibility::All, hit)) {
      return lights.background;
    }
    return shade(origin, dir, hit, depth, local, mark);
  }

  // Direct light at a diffuse or glossy hit seen from `origin`: eq. 5.22 (or a PBR material's
  // appendix B with the sample intersect() evaluated, turned to the side seen) with shadow rays,
  // exactly as the G-buffer shades it. `n` is the shading normal on the side seen.
  glm::vec3 direct_light(const glm::vec3& origin, const SurfaceHit& hit, bool from_front, const glm::vec3& n,
                         float eps) const {
    ShadowRays shadow{&backend, n * eps};
    const VisibilityFn vis = s.shadows ? &visible : nullptr;
    if (hit.pbr) {
      SurfaceSample sample = *hit.pbr;
      if (!from_front) sample.normal = -sample.normal;
      return shade_pbr(lights, sample, hit.position, origin, vis, &shadow);
    }
    return shade_local(lights, *hit.material, hit.position, n, origin, vis, &shadow);
  }

  // The radiance leaving `hit` towards `origin` (along -dir).
  glm::vec3 shade(const glm::vec3& origin, const glm::vec3& dir, const SurfaceHit& hit, std::uint32_t depth,
                  Local& local, bool mark) const {
    const Material& m = *hit.material;
    const bool from_front = glm::dot(dir, hit.geometric_normal) < 0.0f;
    const glm::vec3 n = from_front ? hit.normal : -hit.normal;
    const float eps = surface_epsilon(hit.position);
    switch (m.type) {
      case MaterialType::Emissive: return finite_or_zero(m.emission);
      case MaterialType::Mirror: {
        if (depth >= s.ray_depth) return glm::vec3(0.0f);
        const glm::vec3 r = glm::clamp(m.reflectance, 0.0f, 1.0f);
        return r * radiance(hit.position + n * eps, reflect(dir, n), depth + 1, local, mark);
      }
      case MaterialType::Glass: {
        if (depth >= s.ray_depth) return glm::vec3(0.0f);
        const glm::vec3 tint = glm::clamp(m.reflectance, 0.0f, 1.0f);
        const float ior = std::isfinite(m.ior) && m.ior > 0 ? m.ior : 1.5f;
        glm::vec3 refracted(0.0f);
        const float f = optics::fresnel_dielectric(glm::normalize(dir), n, from_front ? 1.0f / ior : ior, refracted);
        glm::vec3 l = f * radiance(hit.position + n * eps, reflect(glm::normalize(dir), n), depth + 1, local, mark);
        if (f < 1.0f) l += (1.0f - f) * radiance(hit.position - n * eps, refracted, depth + 1, local, mark);
        return tint * l;
      }
      case MaterialType::Lambertian:
      case MaterialType::BlinnPhong:
      case MaterialType::MetallicRoughness: break;
    }
    glm::vec3 l = direct_light(origin, hit, from_front, n, eps);
    // Photon terms: sum f_r(l = -incoming, v) Phi_p / (pi r^2) over the nearest photons (eq. 6.6).
    const glm::vec3 v = glm::normalize(origin - hit.position);
    // A PBR material's BRDF is normalised (glTF appendix B): its photon terms use kd / pi and the
    // normalised Blinn-Phong lobe (n + 8) / (8 pi) ks (n.h)^n, its factors' nearest (GI.md).
    const bool normalised = m.type == MaterialType::MetallicRoughness;
    const float shininess = m.shininess;
    const glm::vec3 kd = normalised ? hit.diffuse_albedo() / std::numbers::pi_v<float> : m.kd;
    const glm::vec3 ks = !m.is_glossy() ? glm::vec3(0.0f)
                         : normalised   ? m.ks * ((shininess + 8) / (8 * std::numbers::pi_v<float>))
                                        : m.ks;
    const auto brdf = [&](const Photon& p) {
      if (ks == glm::vec3(0.0f)) return kd;
      const glm::vec3 h = glm::normalize(v - p.incoming);  // eq. 5.21
      return kd + ks * std::pow(std::max(0.0f, glm::dot(n, h)), shininess);
    };
    if (s.indirect && s.indirect_estimate == IndirectEstimate::Precomputed) {
      // The nearest precomputed photon on a surface facing the same way (Christensen 1999: normals
      // within ~25 deg), its irradiance times the diffuse BRDF.
      const glm::vec3 nn = n;
      maps.precomputed.nearest(hit.position, 1, s.estimate.max_radius, local.scratch,
                               [&nn](const Photon& p) { return glm::dot(p.normal, nn) > 0.9f; });
      if (local.scratch.size() == 1) {
        const std::uint32_t i = local.scratch.index[0];
        const std::size_t lights_n = maps.lights();
        local.trad_split.resize(lights_n);
        local.gaze_split.resize(lights_n);
        l += kd * maps.irradiance_of(i, local.estimate_scratch, local.used, local.trad_split.data(), local.gaze_split.data());
        if (mark) {
          label(seen_indirect, i);
          for (std::size_t k = 0; k < lights_n && k < local.traditional_flux.size(); ++k) {
            local.traditional_flux[k] += static_cast<double>(local.trad_split[k]);
            local.gaze_flux[k] += static_cast<double>(local.gaze_split[k]);
          }
        }
      }
    } else if (s.indirect && !maps.indirect.empty()) {
      l += maps.indirect.flux_density(hit.position, n, s.estimate, local.scratch, brdf, mark ? &local.used : nullptr);
      if (mark) {
        for (std::uint32_t i : local.used) label(seen_indirect, i);
        accumulate_flux_by_kind(maps.global.photons, local.used, local.scratch.radius2, local.traditional_flux,
                                local.gaze_flux);
      }
    }
    if (s.caustics && !maps.caustics.empty()) {
      l += maps.caustics.flux_density(hit.position, n, s.caustic_estimate, local.scratch, brdf, mark ? &local.used : nullptr);
      if (mark)
        for (std::uint32_t i : local.used) label(seen_caustic, i);
    }
    return finite_or_zero(l);
  }
};

}  // namespace

bool GazeArea::contains(float x, float y) const {
  const float dx = x - center_px.x, dy = y - center_px.y;
  return dx * dx + dy * dy <= radius_px * radius_px;
}

PixelBox pixel_box(const GazeArea& area, std::uint32_t width, std::uint32_t height) {
  const float r = area.radius_px;
  if (!std::isfinite(r) || !(r > 0) || !std::isfinite(area.center_px.x) || !std::isfinite(area.center_px.y)) return {};
  const auto clip = [](float v, std::uint32_t hi) {
    return static_cast<std::uint32_t>(std::clamp(v, 0.0f, static_cast<float>(hi)));
  };
  return {clip(std::floor(area.center_px.x - r), width), clip(std::floor(area.center_px.y - r), height),
          clip(std::ceil(area.center_px.x + r), width), clip(std::ceil(area.center_px.y + r), height)};
}

GazeArea gaze_area(const protocol::DisplayGeometry& display, std::uint32_t width, std::uint32_t height,
                   glm::vec2 gaze_normalized, double diameter_deg) {
  GazeArea a;
  const glm::vec2 g = std::isfinite(gaze_normalized.x) && std::isfinite(gaze_normalized.y) ? gaze_normalized : glm::vec2(0.5f);
  a.center_px = {g.x * static_cast<float>(width), g.y * static_cast<float>(height)};
  const double d = std::isfinite(diameter_deg) ? std::clamp(diameter_deg, 0.0, 179.0) : 0.0;
  const double px = protocol::degrees_to_image_pixels(display, width, d);
  a.radius_px = std::isfinite(px) && px > 0 ? static_cast<float>(0.5 * px) : 0.0f;
  return a;
}

void PhotonMaps::index() {
  std::vector<std::uint32_t> after_bounce;
  for (std::size_t i = 0; i < global.photons.size(); ++i)
    if (global.photons[i].diffuse_bounces > 0) after_bounce.push_back(static_cast<std::uint32_t>(i));
  if (after_bounce.empty()) {
    indirect.clear();
  } else {
    indirect.build(global.photons, after_bounce);
  }
  if (caustic.photons.empty()) {
    caustics.clear();
  } else {
    caustics.build_all(caustic.photons);
  }
}

void PhotonMaps::precompute_irradiance(const EstimateSettings& s, std::uint32_t stride, bool lazy) {
  const auto t0 = std::chrono::steady_clock::now();
  precompute_settings_ = s;
  const std::size_t n = global.photons.size();
  lights_ = 0;
  for (const Photon& p : global.photons) lights_ = std::max<std::size_t>(lights_, std::size_t{p.light} + 1);
  irradiance_.assign(n, glm::vec3(0.0f));
  irradiance_traditional_.assign(n * lights_, 0.0f);
  irradiance_gaze_.assign(n * lights_, 0.0f);
  irradiance_state_ = std::make_unique<std::atomic<std::uint8_t>[]>(n);  // value-initialised: 0, none computed
  std::vector<std::uint32_t> chosen;
  const std::uint32_t step = std::max<std::uint32_t>(1, stride);
  std::uint32_t k = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (global.photons[i].diffuse_bounces == 0) continue;
    if (k++ % step == 0) chosen.push_back(static_cast<std::uint32_t>(i));
  }
  if (chosen.empty() || indirect.empty()) {
    precomputed.clear();
  } else {
    precomputed.build(global.photons, chosen);
    if (!lazy) {
      struct Scratch {
        Neighbours nb;
        std::vector<std::uint32_t> used;
      };
      tbb::enumerable_thread_specific<Scratch> scratch;
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, chosen.size(), 64), [&](const tbb::blocked_range<std::size_t>& r) {
        Scratch& sc = scratch.local();
        for (std::size_t j = r.begin(); j < r.end(); ++j) irradiance_of(chosen[j], sc.nb, sc.used, nullptr, nullptr);
      });
    }
  }
  precompute_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

glm::vec3 PhotonMaps::compute_irradiance(std::uint32_t i, Neighbours& scratch, std::vector<std::uint32_t>& used,
                                         float* trad, float* gaze) const {
  const Photon& p = global.photons[i];
  const glm::vec3 e = indirect.flux_density(p.position, p.normal, precompute_settings_, scratch, {}, &used);
  // The same neighbourhood's flux split by the kind of photon, per light (the gaze-directed mapper's
  // power scaling reads it through the render's labels).
  std::vector<double> t(lights_, 0.0), g(lights_, 0.0);
  accumulate_flux_by_kind(global.photons, used, scratch.radius2, t, g);
  for (std::size_t l = 0; l < lights_; ++l) {
    if (trad) trad[l] = static_cast<float>(t[l]);
    if (gaze) gaze[l] = static_cast<float>(g[l]);
  }
  return e;
}

glm::vec3 PhotonMaps::irradiance_of(std::uint32_t i, Neighbours& scratch, std::vector<std::uint32_t>& used, float* trad,
                                    float* gaze) const {
  if (i >= irradiance_.size() || !irradiance_state_) return glm::vec3(0.0f);
  std::atomic<std::uint8_t>& state = irradiance_state_[i];
  const auto copy_split = [&] {
    for (std::size_t l = 0; l < lights_; ++l) {
      if (trad) trad[l] = irradiance_traditional_[i * lights_ + l];
      if (gaze) gaze[l] = irradiance_gaze_[i * lights_ + l];
    }
  };
  if (state.load(std::memory_order_acquire) == 2) {
    copy_split();
    return irradiance_[i];
  }
  // Not there yet: compute; the thread that claims the photon stores the value, any other thread
  // that got here meanwhile uses its own (identical) result.
  std::vector<float> t(lights_), g(lights_);
  const glm::vec3 e = compute_irradiance(i, scratch, used, t.data(), g.data());
  std::uint8_t expected = 0;
  if (state.compare_exchange_strong(expected, 1, std::memory_order_acq_rel)) {
    irradiance_[i] = e;
    std::copy(t.begin(), t.end(), irradiance_traditional_.begin() + static_cast<std::ptrdiff_t>(i * lights_));
    std::copy(g.begin(), g.end(), irradiance_gaze_.begin() + static_cast<std::ptrdiff_t>(i * lights_));
    state.store(2, std::memory_order_release);
  }
  for (std::size_t l = 0; l < lights_; ++l) {
    if (trad) trad[l] = t[l];
    if (gaze) gaze[l] = g[l];
  }
  return e;
}

std::size_t PhotonMaps::precomputed_count() const {
  std::size_t n = 0;
  for (std::size_t i = 0; i < irradiance_.size(); ++i) n += irradiance_state_ && irradiance_state_[i].load() == 2 ? 1u : 0u;
  return n;
}

namespace {

// render_gaze_area's `primary`: the eye rays' first hits as the frame's G-buffer holds them, where it
// is exactly this camera's (same size, the depth, normal and id planes filled).
class GBufferFirstHits {
 public:
  enum class Kind { Trace, Miss, Hit };
  // `need_normal` false: Hit pixels are not shaded here (skip_gbuffer_pixels), the normal plane may be empty.
  GBufferFirstHits(const GBuffer* g, const Camera& camera, const Scene& scene, bool need_normal) {
    const std::size_t n = std::size_t{camera.width} * camera.height;
    if (g == nullptr || g->width != camera.width || g->height != camera.height || g->depth.size() != n ||
        (need_normal && g->normal.size() != n) || g->object_id.size() != n)
      return;
    g_ = g;
    material_of_ = gbuffer_materials(scene);
  }
  bool available() const { return g_ != nullptr; }
  // Pixel i's first hit along `dir` from `eye`: a miss, a diffuse or glossy hit (filled in), or Trace
  // (no G-buffer, or a mirror, glass or emitter: a refraction needs the geometric normal's side).
  Kind at(std::size_t i, const glm::vec3& eye, const glm::vec3& dir, SurfaceHit& hit) const {
    if (g_ == nullptr) return Kind::Trace;
    const std::uint32_t id = g_->object_id[i];
    if (id == 0) return Kind::Miss;  // the ray tracer's own miss
    const auto found = material_of_.find(id);
    const Material* m = found != material_of_.end() ? found->second : nullptr;
    const float depth = g_->depth[i];
    if (m == nullptr || !std::isfinite(depth) || !(depth > 0)) return Kind::Trace;
    hit.t = depth;
    hit.position = eye + dir * depth;  // EyeRays' directions have a unit forward component
    hit.normal = i < g_->normal.size() ? g_->normal[i] : glm::vec3(0.0f);  // faces the camera: the side the ray arrives on
    hit.geometric_normal = hit.normal;
    hit.object_id = id;
    hit.material = m;
    return Kind::Hit;
  }

 private:
  const GBuffer* g_ = nullptr;
  std::unordered_map<std::uint32_t, const Material*> material_of_;
};

// §8.4.4: the photons that shaded the gaze area get kInGazeRegion; returns how many.
std::uint64_t label_in_gaze_region(std::vector<Photon>& photons, const std::vector<std::uint8_t>& seen) {
  std::uint64_t n = 0;
  for (std::size_t i = 0; i < seen.size(); ++i)
    if (seen[i]) {
      photons[i].flags |= kInGazeRegion;
      ++n;
    }
  return n;
}

}  // namespace

std::unordered_map<std::uint32_t, const Material*> gbuffer_materials(const Scene& scene) {
  std::unordered_map<std::uint32_t, const Material*> out;
  for (const Object& o : scene.objects) {
    const Material* m = o.material < scene.materials.size() ? &scene.materials[o.material] : nullptr;
    // PBR materials are traced: their textures need the hit's coordinates, which the G-buffer lacks.
    if (m != nullptr && (!m->is_diffuse_or_glossy() || m->type == MaterialType::MetallicRoughness)) m = nullptr;
    const auto [at, added] = out.emplace(o.id, m);
    if (!added && at->second != m) at->second = nullptr;  // an id shared by materials: traced instead
  }
  return out;
}

void render_gaze_area(const EmbreeBackend& backend, const Camera& camera, double now_s, PhotonMaps& maps,
                      const GazeArea& area, const GiRenderSettings& s, std::vector<glm::vec3>& hdr, GiStats* stats,
                      bool mark, const GBuffer* primary) {
  const auto t0 = std::chrono::steady_clock::now();
  GiStats st;
  const EyeRays eye(camera, now_s);
  const std::size_t n = std::size_t{camera.width} * camera.height;
  if (hdr.size() != n) hdr.assign(n, glm::vec3(0.0f));
  const bool usable = eye.ok && std::isfinite(area.center_px.x) && std::isfinite(area.center_px.y) &&
                      std::isfinite(area.radius_px) && area.radius_px > 0;
  if (usable) {
    // A gaze point off the screen still renders the part of its area that is on it.
    const auto [x0, y0, x1, y1] = pixel_box(area, camera.width, camera.height);
    Scene lights;
    lights.lights = backend.scene().lights;
    lights.background = backend.scene().background;
    lights.ambient = s.ambient ? backend.scene().ambient : glm::vec3(0.0f);
    std::vector<std::uint8_t> seen_indirect(mark ? maps.global.photons.size() : 0), seen_caustic(mark ? maps.caustic.photons.size() : 0);
    const Tracer tracer{backend, lights, maps, s, seen_indirect.data(), seen_caustic.data()};
    const GBufferFirstHits first_hits(primary, camera, backend.scene(), !s.skip_gbuffer_pixels);
    const bool skip = s.skip_gbuffer_pixels && first_hits.available();
    std::atomic<std::uint64_t> reused{0};
    tbb::enumerable_thread_specific<Tracer::Local> locals;
    std::atomic<std::uint64_t> pixels{0};
    if (y1 > y0 && x1 > x0) {
      tbb::parallel_for(tbb::blocked_range<std::uint32_t>(y0, y1), [&](const tbb::blocked_range<std::uint32_t>& rows) {
        Tracer::Local& local = locals.local();
        local.traditional_flux.resize(lights.lights.size(), 0.0);
        local.gaze_flux.resize(lights.lights.size(), 0.0);
        std::uint64_t count = 0, from_gbuffer = 0;
        for (std::uint32_t y = rows.begin(); y < rows.end(); ++y) {
          for (std::uint32_t x = x0; x < x1; ++x) {
            if (!area.contains(static_cast<float>(x) + 0.5f, static_cast<float>(y) + 0.5f)) continue;
            const std::size_t i = std::size_t{y} * camera.width + x;
            const glm::vec3 dir = eye.direction(x, y);
            ++count;
            SurfaceHit hit;
            const GBufferFirstHits::Kind kind = first_hits.at(i, eye.eye, dir, hit);
            if (skip && kind != GBufferFirstHits::Kind::Trace) {
              --count;  // the caller's pixel
              continue;
            }
            switch (kind) {
              case GBufferFirstHits::Kind::Trace: hdr[i] = tracer.radiance(eye.eye, dir, 0, local, mark); break;
              case GBufferFirstHits::Kind::Miss:  // the eye ray, answered by the G-buffer
                ++local.rays;
                ++from_gbuffer;
                hdr[i] = lights.background;
                break;
              case GBufferFirstHits::Kind::Hit:
                ++local.rays;
                ++from_gbuffer;
                hdr[i] = tracer.shade(eye.eye, dir, hit, 0, local, mark);
                break;
            }
          }
        }
        pixels.fetch_add(count, std::memory_order_relaxed);
        reused.fetch_add(from_gbuffer, std::memory_order_relaxed);
      });
    }
    st.pixels = pixels.load();
    st.primary_from_gbuffer = reused.load();
    st.traditional_flux.assign(lights.lights.size(), 0.0);
    st.gaze_flux.assign(lights.lights.size(), 0.0);
    for (const Tracer::Local& local : locals) {
      st.rays += local.rays;
      for (std::size_t l = 0; l < local.traditional_flux.size(); ++l) {
        st.traditional_flux[l] += local.traditional_flux[l];
        st.gaze_flux[l] += local.gaze_flux[l];
      }
    }
    st.photons_used += label_in_gaze_region(maps.global.photons, seen_indirect);
    st.photons_used += label_in_gaze_region(maps.caustic.photons, seen_caustic);
  }
  st.render_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (stats) *stats = st;
}

void hybrid_composite(const std::vector<glm::vec3>& local, const std::vector<glm::vec3>& gi, std::uint32_t width,
                      std::uint32_t height, const GazeArea& area, float fovea_fraction, std::vector<glm::vec3>& out) {
  const std::size_t n = std::size_t{width} * height;
  if (&out != &local) out = local;
  if (local.size() < n || gi.size() < n) return;
  const float radius = area.radius_px;
  if (!(radius > 0) || !std::isfinite(radius) || !std::isfinite(area.center_px.x) || !std::isfinite(area.center_px.y)) return;
  const float fovea = std::clamp(std::isfinite(fovea_fraction) ? fovea_fraction : 0.7f, 0.0f, 1.0f) * radius;
  tbb::parallel_for(tbb::blocked_range<std::uint32_t>(0, height), [&](const tbb::blocked_range<std::uint32_t>& rows) {
    for (std::uint32_t y = rows.begin(); y < rows.end(); ++y) {
      for (std::uint32_t x = 0; x < width; ++x) {
        const float dx = static_cast<float>(x) + 0.5f - area.center_px.x, dy = static_cast<float>(y) + 0.5f - area.center_px.y;
        const float d = std::sqrt(dx * dx + dy * dy);
        if (d >= radius) continue;  // Algorithm 8.4 step 7: local illumination
        const std::size_t i = std::size_t{y} * width + x;
        // Step 8: GI inside the fovea, then a linear ramp to local illumination at the radius.
        const float alpha = d >= fovea && radius > fovea ? (d - fovea) / (radius - fovea) : 0.0f;
        out[i] = alpha * local[i] + (1.0f - alpha) * gi[i];
      }
    }
  });
}

}  // namespace fovea::render::gi
