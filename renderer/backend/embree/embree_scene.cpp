// SPDX-License-Identifier: Apache-2.0
// The Embree backend's geometry (embree_scene.h): the scene's meshes prepared for Embree, one
// geometry per object and level of detail (flattened or instanced, see the note above set_scene),
// the level of detail enabled per object, and animated objects moved to a frame's time.
#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "backend/embree/embree_backend.h"
#include "backend/embree/embree_scene.h"
#include "scene/shading.h"

namespace fovea::render {

using namespace embree_detail;

namespace {

std::shared_ptr<const PreparedMesh> prepare(const Mesh& mesh) {
  auto out = std::make_shared<PreparedMesh>();
  out->positions.reserve(mesh.positions.size());
  for (const glm::vec3& p : mesh.positions) out->positions.push_back(finite(p) ? p : glm::vec3(0.0f));
  if (mesh.normals.size() == mesh.positions.size()) {
    out->normals.reserve(mesh.normals.size());
    for (const glm::vec3& n : mesh.normals) out->normals.push_back(finite(n) ? n : glm::vec3(0.0f));
  }
  const std::size_t n = mesh.positions.size();
  for (std::uint32_t set = 0; set < 2; ++set) {
    if (mesh.texcoords(set).size() == n) out->texcoords[set] = mesh.texcoords(set);
  }
  if (mesh.colors.size() == n) out->colors = mesh.colors;
  if (mesh.tangents.size() == n) out->tangents = mesh.tangents;
  out->indices.reserve(mesh.indices.size());
  for (std::size_t t = 0; t + 2 < mesh.indices.size(); t += 3) {
    const std::uint32_t a = mesh.indices[t], b = mesh.indices[t + 1], c = mesh.indices[t + 2];
    if (a >= n || b >= n || c >= n) continue;
    out->indices.insert(out->indices.end(), {a, b, c});
  }
  return out;
}

const Material& default_material() {
  static const Material m;
  return m;
}

// Writes M * p for every position into an Embree vertex buffer (non-finite results become the
// origin: a collapsed object is a set of degenerate triangles Embree never reports).
void write_world_vertices(float* dst, const PreparedMesh& mesh, const glm::mat4& m) {
  for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
    glm::vec3 p = glm::vec3(m * glm::vec4(mesh.positions[i], 1.0f));
    if (!finite(p)) p = glm::vec3(0.0f);
    dst[3 * i] = p.x;
    dst[3 * i + 1] = p.y;
    dst[3 * i + 2] = p.z;
  }
}

RTCGeometry new_triangle_geometry(RTCDevice device, const PreparedMesh& mesh) {
  RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                               3 * sizeof(float), mesh.positions.size()));
  auto* indices = static_cast<std::uint32_t*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                                      3 * sizeof(std::uint32_t), mesh.triangle_count()));
  if (vertices != nullptr) {
    for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
      vertices[3 * i] = mesh.positions[i].x;
      vertices[3 * i + 1] = mesh.positions[i].y;
      vertices[3 * i + 2] = mesh.positions[i].z;
    }
  }
  if (indices != nullptr) std::copy(mesh.indices.begin(), mesh.indices.end(), indices);
  return g;
}

// Embree's filter for an alpha test: a hit whose alpha is below the cutoff is no hit.
void alpha_filter(const RTCFilterFunctionNArguments* args) {
  const auto* test = static_cast<const HitFilter*>(args->geometryUserPtr);
  if (test == nullptr || !test->alpha_tested) return;
  const PreparedMesh& m = *test->mesh;
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] != -1) continue;
    const unsigned prim = RTCHitN_primID(args->hit, args->N, i);
    if (prim >= m.triangle_count()) continue;
    const float u = RTCHitN_u(args->hit, args->N, i), v = RTCHitN_v(args->hit, args->N, i), w = 1.0f - u - v;
    const std::uint32_t* idx = &m.indices[3 * std::size_t{prim}];
    SurfacePoint point;
    for (std::uint32_t set = 0; set < 2; ++set) {
      const auto& tc = m.texcoords[set];
      if (!tc.empty()) point.uv[set] = w * tc[idx[0]] + u * tc[idx[1]] + v * tc[idx[2]];
      point.lod[set] = -1e30f;  // the base level (see HitFilter)
    }
    if (!m.colors.empty()) point.color = w * m.colors[idx[0]] + u * m.colors[idx[1]] + v * m.colors[idx[2]];
    if (pbr_alpha(*test->scene, *test->material, point) < test->material->alpha_cutoff) args->valid[i] = 0;
  }
}

// The camera's context filter: a hit on the back of a single-sided triangle is no hit. Embree's
// geometry normal Ng points to the side from which the triangle's vertices run counter-clockwise
// (glTF's and OpenGL's front), so a front face has Ng against the ray and a back face along it.
void back_face_filter(const RTCFilterFunctionNArguments* args) {
  const auto* f = static_cast<const HitFilter*>(args->geometryUserPtr);
  if (f == nullptr || !f->single_sided) return;
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] != -1) continue;
    const glm::vec3 ng(RTCHitN_Ng_x(args->hit, args->N, i), RTCHitN_Ng_y(args->hit, args->N, i),
                       RTCHitN_Ng_z(args->hit, args->N, i));
    const glm::vec3 d(RTCRayN_dir_x(args->ray, args->N, i), RTCRayN_dir_y(args->ray, args->N, i),
                      RTCRayN_dir_z(args->ray, args->N, i));
    if (f->front_sign * glm::dot(ng, d) > 0.0f) args->valid[i] = 0;
  }
}

bool invertible(const glm::mat4& m) {
  const float det = glm::determinant(glm::mat3(m));
  return finite(m) && std::isfinite(det) && std::abs(det) > 1e-30f;
}

}  // namespace

namespace embree_detail {

void set_hit_filter(RTCGeometry g, const HitFilter* filter) {
  rtcSetGeometryUserData(g, const_cast<HitFilter*>(filter));
  if (!filter->alpha_tested) return;
  rtcSetGeometryIntersectFilterFunction(g, &alpha_filter);
  rtcSetGeometryOccludedFilterFunction(g, &alpha_filter);
}

void cull_back_faces(RTCIntersectContext& context, RTCScene scene) {
  // Embree refuses (asserts on) a context filter in a scene built without the flag.
  if ((rtcGetSceneFlags(scene) & RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION) != 0) context.filter = &back_face_filter;
}

}  // namespace embree_detail

namespace {

bool single_sided(const Material& m) { return m.type == MaterialType::MetallicRoughness && !m.pbr.double_sided; }
bool alpha_tested(const Material& m) { return m.type == MaterialType::MetallicRoughness && m.pbr.alpha_tested(); }

// The filter data for a mesh drawn with material `m` (owned by `im`); null when it needs none.
const HitFilter* hit_filter_for(EmbreeBackend::Impl& im, const Material& m, const PreparedMesh& mesh, float front_sign) {
  if (!alpha_tested(m) && !single_sided(m)) return nullptr;
  im.hit_filters.push_back(
      std::make_unique<HitFilter>(HitFilter{&im.scene, &m.pbr, &mesh, alpha_tested(m), single_sided(m), front_sign}));
  return im.hit_filters.back().get();
}

// The scene flags for `s`: a context filter when some object is single-sided (cull_back_faces).
RTCSceneFlags filter_flags(const Scene& s) {
  const bool any = std::any_of(s.objects.begin(), s.objects.end(), [&](const Object& o) {
    return o.material < s.materials.size() && single_sided(s.materials[o.material]);
  });
  return any ? RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION : RTC_SCENE_FLAG_NONE;
}

// Instanced mode: one object-space BVH per distinct mesh, and per alpha-tested material using it
// (the filter reads the material), built on first use.
using MeshScenes = std::map<std::pair<const PreparedMesh*, const Material*>, RTCScene>;
RTCScene instanced_mesh_scene(EmbreeBackend::Impl& im, MeshScenes& scenes, const PreparedMesh& pm, const Material& m,
                              const std::string& object) {
  RTCScene& ms = scenes[{&pm, alpha_tested(m) || single_sided(m) ? &m : nullptr}];
  if (ms != nullptr) return ms;
  ms = rtcNewScene(im.device);
  rtcSetSceneFlags(ms, filter_flags(im.scene));
  im.mesh_scenes.push_back(ms);
  RTCGeometry tri = new_triangle_geometry(im.device, pm);
  // In object space the winding is the file's: a mirroring instance transform turns Ng and the ray alike.
  if (const HitFilter* filter = hit_filter_for(im, m, pm, 1.0f)) set_hit_filter(tri, filter);
  rtcCommitGeometry(tri);
  rtcAttachGeometry(ms, tri);
  rtcReleaseGeometry(tri);
  rtcCommitScene(ms);
  im.check("mesh of object '" + object + "'");
  return ms;
}

}  // namespace

// Geometry: flattened vs instanced (both kept; EmbreeOptions::geometry selects).
//  - Flattened: world-space vertices, one geometry per object. A static scene gets a single SAH
//    BVH over all triangles; a scene with animation is DYNAMIC (Embree then keeps one BVH per
//    geometry under a top-level BVH, so only the moved objects are rebuilt, at LOW quality).
//    Rays never pay a transform.
//  - Instanced: one object-space BVH per distinct mesh, objects are instances. A frame only
//    updates instance matrices and rebuilds the (tiny) top level, but every ray that enters an
//    instance is transformed into object space.
// With tens of objects and few animated, rebuilding the animated meshes' BVHs each frame costs
// little next to tracing a 1024x768 frame, and flattened traversal is faster: measured side by
// side (bench_embree "compare", geometry only, packet16) flattened vs instanced was 28.9 vs 28.1
// Mrays/s on the Cornell room, 19.5 vs 18.2 on 64 objects with 4 animated, 18.4 vs 15.5 on
// cornell.json, 18.8 vs 17.3 on attention.json. So flattened is the default (EmbreeOptions);
// instancing stays selectable for scenes with many animated or repeated heavy meshes.
void EmbreeBackend::set_scene(const Scene& scene) {
  Impl& im = *impl_;
  im.release_scene();
  im.scene = scene;
  const Scene& s = im.scene;
  const bool instanced = options_.geometry == EmbreeGeometry::Instanced;
  const bool any_animated = std::any_of(s.objects.begin(), s.objects.end(),
                                        [](const Object& o) { return o.animation.has_value(); });

  im.top = rtcNewScene(im.device);
  rtcSetSceneFlags(im.top, filter_flags(s));
  if (any_animated) {
    rtcSetSceneFlags(im.top, RTC_SCENE_FLAG_DYNAMIC | filter_flags(s));
    rtcSetSceneBuildQuality(im.top, RTC_BUILD_QUALITY_LOW);
  }

  std::map<const Mesh*, std::shared_ptr<const PreparedMesh>> prepared;
  MeshScenes mesh_scene;
  for (std::size_t i = 0; i < s.objects.size(); ++i) {
    const Object& o = s.objects[i];
    if (!o.mesh) continue;
    // Level 0 (the full mesh) and every LOD level get their own geometry; only one per object is
    // enabled at a time (BackendSettings::lod_levels), so switching costs a commit, not a rebuild.
    for (std::uint32_t lod = 0; lod <= o.lods.size(); ++lod) {
      const std::shared_ptr<const Mesh>& source = lod == 0 ? o.mesh : o.lods[lod - 1].mesh;
      if (!source) continue;
      auto& pm = prepared[source.get()];
      if (!pm) pm = prepare(*source);
      if (pm->triangle_count() == 0 || pm->positions.empty()) continue;

      ObjectRecord r;
      r.object = i;
      r.material = o.material < s.materials.size() ? &s.materials[o.material] : &default_material();
      r.mesh = pm;
      r.animated = o.animation.has_value();
      r.lod = lod;
      r.lod_active = lod == 0;
      r.committed = o.transform_at(0).matrix();
      r.normal_committed = cofactor(r.committed);
      const bool emitter = r.material->type == MaterialType::Emissive;

      RTCGeometry g = nullptr;
      if (instanced) {
        g = rtcNewGeometry(im.device, RTC_GEOMETRY_TYPE_INSTANCE);
        rtcSetGeometryInstancedScene(g, instanced_mesh_scene(im, mesh_scene, *pm, *r.material, o.name));
        rtcSetGeometryTimeStepCount(g, 1);
        r.enabled = invertible(r.committed);
        const glm::mat4 m = r.enabled ? r.committed : glm::mat4(1.0f);
        rtcSetGeometryTransform(g, 0, RTC_FORMAT_FLOAT4X4_COLUMN_MAJOR, &m[0][0]);
        if (!r.enabled) rtcDisableGeometry(g);
      } else {
        g = new_triangle_geometry(im.device, *pm);
        auto* vertices = static_cast<float*>(rtcGetGeometryBufferData(g, RTC_BUFFER_TYPE_VERTEX, 0));
        if (vertices != nullptr) write_world_vertices(vertices, *pm, r.committed);
        if (r.animated) rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_LOW);
        // World-space vertices: a mirroring transform (negative determinant) has turned Ng round.
        const float front = glm::determinant(glm::mat3(r.committed)) < 0 ? -1.0f : 1.0f;
        if (const HitFilter* filter = hit_filter_for(im, *r.material, *pm, front)) set_hit_filter(g, filter);
      }
      if (emitter) rtcSetGeometryMask(g, kMaskEmitter);
      if (!r.lod_active) rtcDisableGeometry(g);
      rtcCommitGeometry(g);
      rtcAttachGeometryByID(im.top, g, static_cast<unsigned>(im.records.size()));
      rtcReleaseGeometry(g);  // the scene holds it; r.geometry stays valid while `top` lives
      r.geometry = g;
      im.check("object '" + o.name + "'");
      im.records.push_back(std::move(r));
    }
  }
  rtcCommitScene(im.top);
  im.check("scene '" + s.name + "'");
  im.has_scene = true;
}

namespace embree_detail {

// The levels of detail asked for (BackendSettings::lod_levels): one geometry per object enabled.
void select_lods(EmbreeBackend::Impl& im, const BackendSettings& settings, EmbreeGeometry geometry) {
  const Scene& s = im.scene;
  bool lod_changed = false;
  for (ObjectRecord& r : im.records) {
    const Object& o = s.objects[r.object];
    const std::uint32_t want = r.object < settings.lod_levels.size()
                                   ? std::min<std::uint32_t>(settings.lod_levels[r.object], static_cast<std::uint32_t>(o.lods.size()))
                                   : 0u;
    const bool active = r.lod == want;
    if (active == r.lod_active) continue;
    r.lod_active = active;
    lod_changed = true;
    if (active && (geometry != EmbreeGeometry::Instanced || r.enabled)) rtcEnableGeometry(r.geometry);
    if (!active) rtcDisableGeometry(r.geometry);
    rtcCommitGeometry(r.geometry);
  }
  if (lod_changed) {
    rtcCommitScene(im.top);
    im.check("switching levels of detail");
  }
}

}  // namespace embree_detail

void EmbreeBackend::set_lod_levels(const std::vector<std::uint8_t>& levels) {
  if (!impl_->has_scene) return;
  BackendSettings settings;
  settings.lod_levels = levels;
  select_lods(*impl_, settings, options_.geometry);
}

void EmbreeBackend::set_time(double now_s) {
  Impl& im = *impl_;
  if (!im.has_scene) return;
  const Scene& s = im.scene;
  const bool instanced = options_.geometry == EmbreeGeometry::Instanced;
  bool changed = false;
  for (ObjectRecord& r : im.records) {
    if (!r.animated) continue;
    const glm::mat4 m = s.objects[r.object].transform_at(now_s).matrix();
    if (m == r.committed) continue;
    r.committed = m;
    r.normal_committed = cofactor(m);
    changed = true;
    if (instanced) {
      const bool ok = invertible(m);
      if (ok) rtcSetGeometryTransform(r.geometry, 0, RTC_FORMAT_FLOAT4X4_COLUMN_MAJOR, &m[0][0]);
      if (ok && !r.enabled && r.lod_active) rtcEnableGeometry(r.geometry);
      if (!ok && r.enabled && r.lod_active) rtcDisableGeometry(r.geometry);
      r.enabled = ok;
    } else {
      auto* vertices = static_cast<float*>(rtcGetGeometryBufferData(r.geometry, RTC_BUFFER_TYPE_VERTEX, 0));
      if (vertices != nullptr) write_world_vertices(vertices, *r.mesh, m);
      rtcUpdateGeometryBuffer(r.geometry, RTC_BUFFER_TYPE_VERTEX, 0);
    }
    rtcCommitGeometry(r.geometry);
  }
  if (changed) {
    rtcCommitScene(im.top);
    im.check("updating animated objects");
  }
}

}  // namespace fovea::render
