// SPDX-License-Identifier: Apache-2.0
#pragma once
// The Embree backend's rays: the camera's frame (a ray through each pixel, pinhole or thin lens),
// primary rays traced over a tile with each EmbreeTraversal or peeled by object, and the shadow
// rays of scene/shading.h's visibility callback. Internal to the backend; embree_rays.cpp has the
// kernels, embree_backend.cpp the tile pass that calls them.
#include <embree3/rtcore.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "backend/embree/embree_scene.h"

namespace fovea::render::embree_detail {

constexpr unsigned kInvalidId = std::numeric_limits<unsigned>::max();
constexpr std::uint32_t kTile = 16;  // pixels per tile side: one TBB task, one Embree stream

// Per-frame, per-object matrices.
struct ObjectFrame {
  glm::mat4 model_now{1.0f};
  glm::mat3 normal_now{1.0f};         // cofactor of model_now
  glm::mat4 clip_now{1.0f};           // projection * view(now) * model(now): object -> clip now
  glm::mat4 clip_prev{1.0f};          // the same at the previous frame's time
  bool moves = false;                 // clip_now != clip_prev: motion can be non-zero
};

// Everything a tile needs, computed once per frame.
struct Frame {
  std::uint32_t width = 0, height = 0;
  glm::vec3 eye{0.0f}, right{1, 0, 0}, up{0, 1, 0}, back{0, 0, 1};
  float tan_x = 1, tan_y = 1;  // half-extent of the image plane at view depth 1
  float cone_spread = 0;       // a pixel's ray-cone spread angle, atan(2 tan_y / height) (texture level)
  float near_m = 0, far_m = 0;
  bool motion = false;
  glm::mat4 view_proj_now{1.0f}, view_proj_prev{1.0f};
  std::vector<ObjectFrame> objects;

  // Ray direction through the centre of pixel (x, y), scaled so its component along the view
  // axis is exactly 1: ray parameter t is then linear view-space depth, and [near, far] in t is
  // the same clip range as the OpenGL backend's near and far planes.
  glm::vec3 direction(std::uint32_t x, std::uint32_t y) const {
    const float ndc_x = 2.0f * (static_cast<float>(x) + 0.5f) / static_cast<float>(width) - 1.0f;
    const float ndc_y = 1.0f - 2.0f * (static_cast<float>(y) + 0.5f) / static_cast<float>(height);
    return right * (ndc_x * tan_x) + up * (ndc_y * tan_y) - back;
  }

  // Thin lens (BackendSettings::lens): the ray of pixel (x, y) leaves from its lens point and passes
  // through the pixel's point on the plane in focus; divided by the focus distance its view-axis
  // component stays 1, so t is still view-axis depth (from the lens plane).
  LensSample lens;
  bool lens_on = false;
  float lens_radius = 0, focus = 1;
  void ray(std::uint32_t x, std::uint32_t y, glm::vec3& origin, glm::vec3& dir) const {
    dir = direction(x, y);
    origin = eye;
    if (!lens_on) return;
    const glm::vec2 p = lens_sampling::pixel_lens_point(lens, x, y) * lens_radius;
    const glm::vec3 offset = right * p.x + up * p.y;
    const glm::vec3 focal = eye + dir * focus;
    origin = eye + offset;
    dir = (focal - origin) / focus;
  }
};

struct Hit {
  float t = 0, u = 0, v = 0;
  unsigned geom = kInvalidId, prim = kInvalidId, inst = kInvalidId;
};

// Shadow rays: rtcOccluded1 from the shaded point (pushed off the surface along the normal) to
// the light sample.
struct ShadowContext {
  RTCScene scene = nullptr;
  glm::vec3 offset{0.0f};  // normal * epsilon
  float epsilon = 0;
  std::uint64_t rays = 0;
};

// True if a shadow caster lies on origin + t d for t in (0, t_far).
bool segment_occluded(RTCScene scene, const glm::vec3& origin, const glm::vec3& d, float t_far);

// scene/shading.h's VisibilityFn: `context` is a ShadowContext, whose rays it counts.
bool shadow_visible(void* context, const glm::vec3& from, const glm::vec3& to);

// A tile's primary hits, hits[tile_slot(x - x0, y - y0)] for the pixels [x0, x1) x [y0, y1).
using TileHits = std::array<Hit, kTile * kTile>;
constexpr std::size_t tile_slot(std::uint32_t dx, std::uint32_t dy) { return std::size_t{dy} * kTile + dx; }

// One ray per pixel (rtcIntersect1).
void trace_single(RTCScene scene, const Frame& f, std::uint32_t x0, std::uint32_t y0, std::uint32_t x1,
                  std::uint32_t y1, TileHits& hits);
// Packets of N = 4, 8 or 16 rays (rtcIntersectN) on 2x2, 4x2 or 4x4 pixel blocks.
template <int N>
void trace_packets(RTCScene scene, const Frame& f, std::uint32_t x0, std::uint32_t y0, std::uint32_t x1,
                   std::uint32_t y1, TileHits& hits);
// The whole tile as one stream (rtcIntersect1M).
void trace_stream(RTCScene scene, const Frame& f, std::uint32_t x0, std::uint32_t y0, std::uint32_t x1,
                  std::uint32_t y1, TileHits& hits);
// Depth peeling by object: the first hit of the peel-th object behind the visible one.
void trace_peeled(RTCScene scene, const Frame& f, std::uint32_t x0, std::uint32_t y0, std::uint32_t x1,
                  std::uint32_t y1, bool instanced, std::uint32_t peel, TileHits& hits);

}  // namespace fovea::render::embree_detail
