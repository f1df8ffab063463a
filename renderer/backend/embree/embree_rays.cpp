// SPDX-License-Identifier: Apache-2.0
// The Embree backend's rays (embree_rays.h): shadow rays between a shaded point and a light sample,
// and a tile's primary rays with each EmbreeTraversal (single, packets of 4, 8 or 16, one stream)
// or the peeled layer of depth peeling by object.
#include "backend/embree/embree_rays.h"

#include <algorithm>
#include <cmath>

namespace fovea::render::embree_detail {

// True if a shadow caster lies on origin + t d for t in (0, t_far).
bool segment_occluded(RTCScene scene, const glm::vec3& origin, const glm::vec3& d, float t_far) {
  RTCIntersectContext ic;
  rtcInitIntersectContext(&ic);
  RTCRay ray{};
  ray.org_x = origin.x;
  ray.org_y = origin.y;
  ray.org_z = origin.z;
  ray.dir_x = d.x;
  ray.dir_y = d.y;
  ray.dir_z = d.z;
  ray.tnear = 0.0f;
  ray.tfar = t_far;
  ray.mask = kMaskShadowCaster;
  rtcOccluded1(scene, &ic, &ray);
  return !(ray.tfar >= 0.0f);  // Embree sets tfar = -inf when occluded
}

bool shadow_visible(void* context, const glm::vec3& from, const glm::vec3& to) {
  auto* c = static_cast<ShadowContext*>(context);
  ++c->rays;
  const glm::vec3 origin = from + c->offset;
  const glm::vec3 d = to - origin;
  const float len = glm::length(d);
  if (!(len > c->epsilon) || !std::isfinite(len)) return true;  // light on the surface: nothing between
  return !segment_occluded(c->scene, origin, d, 1.0f - c->epsilon / len);  // stop just short of the light sample
}

namespace {

template <class Ray>
void fill_ray(Ray& r, const Frame& f, std::uint32_t x, std::uint32_t y) {
  glm::vec3 o, d;
  f.ray(x, y, o, d);
  r.org_x = o.x;
  r.org_y = o.y;
  r.org_z = o.z;
  r.dir_x = d.x;
  r.dir_y = d.y;
  r.dir_z = d.z;
  r.tnear = f.near_m;
  r.tfar = f.far_m;
  r.mask = kMaskPrimary;
  r.time = 0.0f;
  r.flags = 0;
}

// Packet traits: rtcIntersectN and the pixel block each packet covers.
template <int N>
struct Packet;
template <>
struct Packet<4> {
  using RayHit = RTCRayHit4;
  static constexpr std::uint32_t bw = 2, bh = 2;
  static void intersect(const int* valid, RTCScene s, RTCIntersectContext* c, RayHit* r) { rtcIntersect4(valid, s, c, r); }
};
template <>
struct Packet<8> {
  using RayHit = RTCRayHit8;
  static constexpr std::uint32_t bw = 4, bh = 2;
  static void intersect(const int* valid, RTCScene s, RTCIntersectContext* c, RayHit* r) { rtcIntersect8(valid, s, c, r); }
};
template <>
struct Packet<16> {
  using RayHit = RTCRayHit16;
  static constexpr std::uint32_t bw = 4, bh = 4;
  static void intersect(const int* valid, RTCScene s, RTCIntersectContext* c, RayHit* r) { rtcIntersect16(valid, s, c, r); }
};

}  // namespace

void trace_single(RTCScene scene, const Frame& f, std::uint32_t x0, std::uint32_t y0, std::uint32_t x1,
                  std::uint32_t y1, TileHits& hits) {
  RTCIntersectContext ic;
  rtcInitIntersectContext(&ic);
  cull_back_faces(ic, scene);  // the camera sees single-sided materials from the front only
  ic.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  for (std::uint32_t y = y0; y < y1; ++y) {
    for (std::uint32_t x = x0; x < x1; ++x) {
      RTCRayHit rh{};
      fill_ray(rh.ray, f, x, y);
      rh.hit.geomID = kInvalidId;
      rh.hit.instID[0] = kInvalidId;
      rtcIntersect1(scene, &ic, &rh);
      hits[tile_slot(x - x0, y - y0)] = {rh.ray.tfar, rh.hit.u, rh.hit.v, rh.hit.geomID, rh.hit.primID, rh.hit.instID[0]};
    }
  }
}

template <int N>
void trace_packets(RTCScene scene, const Frame& f, std::uint32_t x0, std::uint32_t y0, std::uint32_t x1,
                   std::uint32_t y1, TileHits& hits) {
  using P = Packet<N>;
  RTCIntersectContext ic;
  rtcInitIntersectContext(&ic);
  cull_back_faces(ic, scene);  // the camera sees single-sided materials from the front only
  ic.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  for (std::uint32_t by = y0; by < y1; by += P::bh) {
    for (std::uint32_t bx = x0; bx < x1; bx += P::bw) {
      typename P::RayHit rh{};
      alignas(64) std::array<int, static_cast<std::size_t>(N)> valid{};
      for (int i = 0; i < N; ++i) {
        const std::uint32_t x = bx + static_cast<std::uint32_t>(i) % P::bw;
        const std::uint32_t y = by + static_cast<std::uint32_t>(i) / P::bw;
        const auto lane = static_cast<std::size_t>(i);
        valid[lane] = (x < x1 && y < y1) ? -1 : 0;
        glm::vec3 o = f.eye, d(0, 0, -1);
        if (valid[lane] != 0) f.ray(x, y, o, d);
        rh.ray.org_x[lane] = o.x;
        rh.ray.org_y[lane] = o.y;
        rh.ray.org_z[lane] = o.z;
        rh.ray.dir_x[lane] = d.x;
        rh.ray.dir_y[lane] = d.y;
        rh.ray.dir_z[lane] = d.z;
        rh.ray.tnear[lane] = f.near_m;
        rh.ray.tfar[lane] = f.far_m;
        rh.ray.mask[lane] = kMaskPrimary;
        rh.hit.geomID[lane] = kInvalidId;
        rh.hit.instID[0][lane] = kInvalidId;
      }
      P::intersect(valid.data(), scene, &ic, &rh);
      for (int i = 0; i < N; ++i) {
        const auto lane = static_cast<std::size_t>(i);
        if (valid[lane] == 0) continue;
        const std::uint32_t x = bx + static_cast<std::uint32_t>(i) % P::bw;
        const std::uint32_t y = by + static_cast<std::uint32_t>(i) / P::bw;
        hits[tile_slot(x - x0, y - y0)] = {rh.ray.tfar[lane], rh.hit.u[lane],      rh.hit.v[lane],
                                           rh.hit.geomID[lane], rh.hit.primID[lane], rh.hit.instID[0][lane]};
      }
    }
  }
}

void trace_stream(RTCScene scene, const Frame& f, std::uint32_t x0, std::uint32_t y0, std::uint32_t x1,
                  std::uint32_t y1, TileHits& hits) {
  RTCIntersectContext ic;
  rtcInitIntersectContext(&ic);
  cull_back_faces(ic, scene);  // the camera sees single-sided materials from the front only
  ic.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  std::array<RTCRayHit, kTile * kTile> rh{};
  unsigned count = 0;
  for (std::uint32_t y = y0; y < y1; ++y) {
    for (std::uint32_t x = x0; x < x1; ++x) {
      RTCRayHit& r = rh[count++];
      fill_ray(r.ray, f, x, y);
      r.hit.geomID = kInvalidId;
      r.hit.instID[0] = kInvalidId;
    }
  }
  rtcIntersect1M(scene, &ic, rh.data(), count, sizeof(RTCRayHit));
  count = 0;
  for (std::uint32_t y = y0; y < y1; ++y) {
    for (std::uint32_t x = x0; x < x1; ++x) {
      const RTCRayHit& r = rh[count++];
      hits[tile_slot(x - x0, y - y0)] = {r.ray.tfar, r.hit.u, r.hit.v, r.hit.geomID, r.hit.primID, r.hit.instID[0]};
    }
  }
}

// Depth peeling by object: the first hit of the peel-th object behind the visible one, continuing
// the ray past each further hit of an object already met (its back faces, its other parts).
void trace_peeled(RTCScene scene, const Frame& f, std::uint32_t x0, std::uint32_t y0, std::uint32_t x1,
                  std::uint32_t y1, bool instanced, std::uint32_t peel, TileHits& hits) {
  RTCIntersectContext ic;
  rtcInitIntersectContext(&ic);
  cull_back_faces(ic, scene);  // the camera sees single-sided materials from the front only
  for (std::uint32_t y = y0; y < y1; ++y) {
    for (std::uint32_t x = x0; x < x1; ++x) {
      Hit out;  // miss unless another object is found
      RTCRayHit rh{};
      fill_ray(rh.ray, f, x, y);
      rh.hit.geomID = kInvalidId;
      rh.hit.instID[0] = kInvalidId;
      rtcIntersect1(scene, &ic, &rh);
      if (rh.hit.geomID != kInvalidId) {
        unsigned current = instanced ? rh.hit.instID[0] : rh.hit.geomID;
        std::uint32_t met = 0;  // objects met behind the visible one
        for (int step = 0; step < 256; ++step) {
          const float t = rh.ray.tfar;
          fill_ray(rh.ray, f, x, y);
          rh.ray.tnear = t + std::max(1e-4f, 1e-5f * t);
          rh.hit.geomID = kInvalidId;
          rh.hit.instID[0] = kInvalidId;
          if (!(rh.ray.tnear < rh.ray.tfar)) break;
          rtcIntersect1(scene, &ic, &rh);
          if (rh.hit.geomID == kInvalidId) break;
          const unsigned id = instanced ? rh.hit.instID[0] : rh.hit.geomID;
          if (id != current) {
            current = id;
            if (++met == peel) {
              out = {rh.ray.tfar, rh.hit.u, rh.hit.v, rh.hit.geomID, rh.hit.primID, rh.hit.instID[0]};
              break;
            }
          }
        }
      }
      hits[tile_slot(x - x0, y - y0)] = out;
    }
  }
}

template void trace_packets<4>(RTCScene, const Frame&, std::uint32_t, std::uint32_t, std::uint32_t, std::uint32_t,
                               TileHits&);
template void trace_packets<8>(RTCScene, const Frame&, std::uint32_t, std::uint32_t, std::uint32_t, std::uint32_t,
                               TileHits&);
template void trace_packets<16>(RTCScene, const Frame&, std::uint32_t, std::uint32_t, std::uint32_t, std::uint32_t,
                                TileHits&);

}  // namespace fovea::render::embree_detail
