// SPDX-License-Identifier: Apache-2.0
#pragma once
// GLSL of the G-buffer pass. The fragment shader's shade_local() is a line-by-line port of
// scene/shading.cpp (modified Blinn-Phong, Jensen & Pedersen 2009 eq. 5.21-5.23, 5.33, spot
// smoothstep, area lights as n x n cosine emitters expanded on the CPU by light_samples(), ambient,
// emissive). Keep the two in step: tests/gl/test_gl_backend.cpp compares them pixel by pixel.

namespace fovea::render::gl {

// Most light samples one frame can use (an area light of n x n samples counts n*n). 256 samples of
// 3 vec4 (std140) = 12 KiB, under the 16 KiB minimum GL_MAX_UNIFORM_BLOCK_SIZE of GL 3.3.
inline constexpr int kMaxLightSamples = 256;

inline constexpr const char* kGBufferVertex = R"(#version 330 core
layout(location = 0) in vec3 a_position;
layout(location = 1) in vec3 a_normal;

uniform mat4 u_model;        // object -> world at time now
uniform mat4 u_model_prev;   // object -> world at the previous frame's time
uniform mat3 u_normal_matrix;  // inverse transpose of u_model's upper 3x3
uniform mat4 u_view, u_view_prev, u_proj;

out vec3 v_world;
out vec3 v_normal;
out float v_view_depth;
out vec4 v_clip_prev;
// The depth pre-pass (kDepthVertex) computes gl_Position the same way: both invariant, so the
// shading pass's z test at equal meets exactly the depths the pre-pass wrote.
invariant gl_Position;

void main() {
  vec4 world = u_model * vec4(a_position, 1.0);
  vec4 view = u_view * world;
  v_world = world.xyz;
  v_normal = u_normal_matrix * a_normal;
  // Linear view-space depth (metres along the view axis): affine in view space, so the
  // perspective-correct interpolation below is exact on a planar triangle.
  v_view_depth = -view.z;
  v_clip_prev = u_proj * (u_view_prev * (u_model_prev * vec4(a_position, 1.0)));
  gl_Position = u_proj * view;
}
)";

// The depth pre-pass: kGBufferVertex's position, nothing else.
inline constexpr const char* kDepthVertex = R"(#version 330 core
layout(location = 0) in vec3 a_position;
uniform mat4 u_model;
uniform mat4 u_view, u_proj;
invariant gl_Position;
void main() {
  vec4 world = u_model * vec4(a_position, 1.0);
  vec4 view = u_view * world;
  gl_Position = u_proj * view;
}
)";

inline constexpr const char* kDepthFragment = R"(#version 330 core
void main() {}
)";

// scene/shading.cpp shade_local() and its light samples, shared by the G-buffer's fragment shader
// and the visibility buffer's compute shader (kVisibilityResolve): one shading formula on the GPU.
inline constexpr const char* kShadingGlsl = R"(
// Must stay in step with scene/shading.h LightSample and GlBackend's upload.
struct LightSample {
  vec4 position_kind;    // xyz position, w kind: 0 point, 1 spot, 2 area (cosine emitter)
  vec4 power_cutoff;     // xyz power share (W), w cos_cutoff
  vec4 direction_start;  // xyz spot axis / emitter normal, w cos_falloff_start
};
layout(std140) uniform LightSamples { LightSample u_lights[256]; };
uniform int u_light_count;
uniform vec3 u_ambient;

const float kPi = 3.14159265358979323846;

vec3 finite_or_zero(vec3 v) {
  return vec3(isnan(v.x) || isinf(v.x) ? 0.0 : v.x, isnan(v.y) || isinf(v.y) ? 0.0 : v.y,
              isnan(v.z) || isinf(v.z) ? 0.0 : v.z);
}

// scene/shading.cpp shade_local(), without the visibility callback (no shadows in the raster backend).
vec3 shade_local(vec3 x, vec3 n, vec3 eye, vec3 kd, vec3 ks, vec3 emission, float shininess, bool emissive) {
  if (emissive) return finite_or_zero(emission + kd * u_ambient);
  vec3 to_eye = eye - x;
  float eye_dist = length(to_eye);
  vec3 v = eye_dist > 0.0 ? to_eye / eye_dist : n;
  vec3 radiance = kd * u_ambient;
  for (int i = 0; i < u_light_count; ++i) {
    LightSample s = u_lights[i];
    vec3 to_light = s.position_kind.xyz - x;
    float d2 = dot(to_light, to_light);
    if (!(d2 > 1e-12)) continue;
    float d = sqrt(d2);
    vec3 l = to_light / d;
    float cos_theta = dot(n, l);
    if (cos_theta <= 0.0) continue;
    float emit = 1.0 / (4.0 * kPi);  // isotropic point light: E = Phi / (4 pi d^2) cos(theta), eq. 5.33
    int kind = int(s.position_kind.w + 0.5);
    if (kind == 1) {
      float c = dot(-l, s.direction_start.xyz);
      float cutoff = s.power_cutoff.w, start = s.direction_start.w;
      float t = clamp((c - cutoff) / (start - cutoff), 0.0, 1.0);
      emit *= t * t * (3.0 - 2.0 * t);  // smoothstep across the soft edge
    } else if (kind == 2) {
      emit = max(0.0, dot(-l, s.direction_start.xyz)) / kPi;  // Lambertian emitter
    }
    if (emit <= 0.0) continue;
    vec3 irradiance = s.power_cutoff.xyz * (emit * cos_theta / d2);
    vec3 h = normalize(l + v);  // eq. 5.21
    float n_dot_h = max(0.0, dot(n, h));
    // std::pow(0, 0) == 1 in C++; GLSL leaves pow(0, 0) undefined.
    float highlight = shininess == 0.0 ? 1.0 : pow(n_dot_h, shininess);
    vec3 brdf = ks * highlight + kd;  // eq. 5.22
    radiance += brdf * irradiance;
  }
  return finite_or_zero(radiance);
}
)";

// After "#version 330 core" and kShadingGlsl.
inline constexpr const char* kGBufferFragment = R"(
in vec3 v_world;
in vec3 v_normal;
in float v_view_depth;
in vec4 v_clip_prev;

uniform vec3 u_eye;
uniform vec2 u_viewport;   // width, height in pixels
uniform int u_moved;       // 0: same model and view matrices at both times, motion exactly 0
uniform uint u_object_id;
uniform int u_emissive;
uniform vec3 u_kd, u_ks, u_emission;
uniform float u_shininess;
// Depth peeling (gl_peel.h): keep only fragments farther than the last layer's, by the Embree
// backend's epsilon, at pixels not yet resolved.
uniform bool u_peel;
uniform sampler2D u_peel_depth;
uniform usampler2D u_peel_state;

layout(location = 0) out vec4 o_color;
layout(location = 1) out float o_depth;
layout(location = 2) out uint o_object_id;
layout(location = 3) out vec4 o_normal;
layout(location = 4) out vec2 o_motion;

void main() {
  // Geometric normal as the fallback for a degenerate interpolated normal (computed outside any
  // branch: derivatives need uniform control flow).
  vec3 geometric = cross(dFdx(v_world), dFdy(v_world));
  float len = length(v_normal);
  vec3 n;
  if (len > 1e-20 && !isinf(len)) {
    n = v_normal / len;
    if (!gl_FrontFacing) n = -n;  // the G-buffer normal faces the camera
  } else {
    float glen = length(geometric);
    n = glen > 0.0 ? geometric / glen : vec3(0.0, 0.0, 1.0);
    if (dot(n, u_eye - v_world) < 0.0) n = -n;
  }
  if (u_peel) {  // after the derivatives: they need every fragment of the quad
    ivec2 p = ivec2(gl_FragCoord.xy);
    // Embree's step past the last hit along the ray, max(1e-4, 1e-5 t) in distance t, in view depth.
    float last = texelFetch(u_peel_depth, p, 0).r;
    float cos_view = clamp(v_view_depth / max(length(v_world - u_eye), 1e-30), 0.0, 1.0);
    if (v_view_depth <= last + max(1e-4 * cos_view, 1e-5 * last) || texelFetch(u_peel_state, p, 0).y >= 0x80000000u)
      discard;
  }

  o_color = vec4(shade_local(v_world, n, u_eye, u_kd, u_ks, u_emission, u_shininess, u_emissive != 0), 1.0);
  o_depth = v_view_depth;
  o_object_id = u_object_id;
  o_normal = vec4(n, 0.0);

  // Motion in pixels, y down: where this surface point is now (the pixel centre) minus where it was
  // at the previous frame's time. Zero if it was behind the previous camera (no meaningful position).
  vec2 now_px = vec2(gl_FragCoord.x, u_viewport.y - gl_FragCoord.y);
  vec2 motion = vec2(0.0);
  if (u_moved != 0 && v_clip_prev.w > 1e-6) {
    vec2 ndc = v_clip_prev.xy / v_clip_prev.w;
    vec2 prev_px = vec2((ndc.x * 0.5 + 0.5) * u_viewport.x, (0.5 - ndc.y * 0.5) * u_viewport.y);
    motion = now_px - prev_px;
  }
  o_motion = vec2(isnan(motion.x) || isinf(motion.x) ? 0.0 : motion.x,
                  isnan(motion.y) || isinf(motion.y) ? 0.0 : motion.y);
}
)";

// The visibility buffer (GlVisibilityPass): the raster pass writes which triangle covers each pixel,
// nothing else; kVisibilityResolve rebuilds the G-buffer's planes from it.
inline constexpr const char* kVisibilityFragment = R"(#version 330 core
uniform uint u_draw;  // 1 + the object's index in the frame's draw list (0: background)
layout(location = 0) out uvec2 o_visibility;
void main() { o_visibility = uvec2(u_draw, uint(gl_PrimitiveID)); }
)";

// After "#version 430 core" and kShadingGlsl. One invocation per pixel: the triangle the raster pass
// found there, intersected with the pixel centre's ray from the eye, gives the barycentrics the
// fragment shader would have interpolated with (perspective-correct interpolation is exactly that
// intersection), and from them every plane of kGBufferFragment, with the same formulas.
inline constexpr const char* kVisibilityResolve = R"(
layout(local_size_x = 8, local_size_y = 8) in;

// Must stay in step with GlVisibilityPass's DrawStd430.
struct Draw {
  mat4 model;
  mat4 model_prev;
  mat4 normal_matrix;   // mat3 in the upper left
  vec4 kd_emissive;     // w: 1 emissive
  vec4 ks_shininess;
  vec4 emission_moved;  // w: 1 when model or view differ between the two times
  uvec4 mesh;           // x first index, y first vertex (in the scene-wide buffers), z object id
};
layout(std430, binding = 0) readonly buffer Draws { Draw u_draws[]; };
layout(std430, binding = 1) readonly buffer Vertices { float u_vertices[]; };  // position, normal
layout(std430, binding = 2) readonly buffer Indices { uint u_indices[]; };

uniform usampler2D u_visibility;
layout(rgba32f, binding = 0) uniform writeonly image2D u_color;
layout(r32f, binding = 1) uniform writeonly image2D u_depth;
layout(r32ui, binding = 2) uniform writeonly uimage2D u_id;
layout(rgba32f, binding = 3) uniform writeonly image2D u_normal;
layout(rg32f, binding = 4) uniform writeonly image2D u_motion;
uniform int u_planes;  // bit k: plane k (colour, depth, id, normal, motion) is written
uniform mat4 u_view, u_view_prev, u_proj, u_inv_proj, u_inv_view;
uniform vec3 u_eye;
uniform ivec2 u_size;
uniform vec3 u_background;
uniform float u_far;

vec3 vertex_position(uint v) { return vec3(u_vertices[6u * v], u_vertices[6u * v + 1u], u_vertices[6u * v + 2u]); }
vec3 vertex_normal(uint v) { return vec3(u_vertices[6u * v + 3u], u_vertices[6u * v + 4u], u_vertices[6u * v + 5u]); }

void store(ivec2 p, vec3 color, float depth, uint id, vec3 n, vec2 motion) {
  if ((u_planes & 1) != 0) imageStore(u_color, p, vec4(color, 1.0));
  if ((u_planes & 2) != 0) imageStore(u_depth, p, vec4(depth, 0.0, 0.0, 0.0));
  if ((u_planes & 4) != 0) imageStore(u_id, p, uvec4(id, 0u, 0u, 0u));
  if ((u_planes & 8) != 0) imageStore(u_normal, p, vec4(n, 0.0));
  if ((u_planes & 16) != 0) imageStore(u_motion, p, vec4(motion, 0.0, 0.0));
}

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= u_size.x || p.y >= u_size.y) return;
  uvec2 vis = texelFetch(u_visibility, p, 0).xy;
  if (vis.x == 0u) {  // what clear_gbuffer leaves where no object is
    store(p, u_background, u_far, 0u, vec3(0.0), vec2(0.0));
    return;
  }
  Draw d = u_draws[vis.x - 1u];
  uint first = d.mesh.x + 3u * vis.y;
  uint i0 = d.mesh.y + u_indices[first], i1 = d.mesh.y + u_indices[first + 1u], i2 = d.mesh.y + u_indices[first + 2u];
  vec3 p0 = vertex_position(i0), p1 = vertex_position(i1), p2 = vertex_position(i2);
  vec3 w0 = (d.model * vec4(p0, 1.0)).xyz, w1 = (d.model * vec4(p1, 1.0)).xyz, w2 = (d.model * vec4(p2, 1.0)).xyz;

  // The pixel centre's ray from the eye (the frustum's apex, also for a sheared lens view).
  vec2 ndc = (vec2(p) + 0.5) / vec2(u_size) * 2.0 - 1.0;
  vec4 near_view = u_inv_proj * vec4(ndc, -1.0, 1.0);
  vec3 dir = mat3(u_inv_view) * (near_view.xyz / near_view.w);
  // Moeller-Trumbore: the barycentrics of the ray's hit on the triangle's plane.
  vec3 e1 = w1 - w0, e2 = w2 - w0;
  vec3 pv = cross(dir, e2);
  float det = dot(e1, pv);
  vec3 tv = u_eye - w0;
  vec3 qv = cross(tv, e1);
  float b1 = 1.0 / 3.0, b2 = 1.0 / 3.0;  // a triangle seen exactly edge-on: its centroid
  if (abs(det) > 0.0 && !isinf(det)) {
    b1 = dot(tv, pv) / det;
    b2 = dot(dir, qv) / det;
  }
  float b0 = 1.0 - b1 - b2;
  vec3 x = b0 * w0 + b1 * w1 + b2 * w2;
  float depth = -(u_view * vec4(x, 1.0)).z;

  // kGBufferFragment's normal: interpolated, facing the camera; the geometric one where degenerate.
  vec3 interpolated = mat3(d.normal_matrix) * (b0 * vertex_normal(i0) + b1 * vertex_normal(i1) + b2 * vertex_normal(i2));
  vec3 geometric = cross(e1, e2);
  float len = length(interpolated);
  vec3 n;
  if (len > 1e-20 && !isinf(len)) {
    n = interpolated / len;
    if (!(dot(geometric, u_eye - x) > 0.0)) n = -n;  // gl_FrontFacing: counter-clockwise as seen
  } else {
    float glen = length(geometric);
    n = glen > 0.0 ? geometric / glen : vec3(0.0, 0.0, 1.0);
    if (dot(n, u_eye - x) < 0.0) n = -n;
  }
  vec3 color = shade_local(x, n, u_eye, d.kd_emissive.xyz, d.ks_shininess.xyz, d.emission_moved.xyz,
                           d.ks_shininess.w, d.kd_emissive.w > 0.5);

  vec2 motion = vec2(0.0);
  if (d.emission_moved.w > 0.5) {
    vec3 object_point = b0 * p0 + b1 * p1 + b2 * p2;
    vec4 clip_prev = u_proj * (u_view_prev * (d.model_prev * vec4(object_point, 1.0)));
    if (clip_prev.w > 1e-6) {
      vec2 now_px = vec2(float(p.x) + 0.5, float(u_size.y) - (float(p.y) + 0.5));
      vec2 ndc_prev = clip_prev.xy / clip_prev.w;
      vec2 prev_px = vec2((ndc_prev.x * 0.5 + 0.5) * float(u_size.x), (0.5 - ndc_prev.y * 0.5) * float(u_size.y));
      motion = now_px - prev_px;
    }
  }
  motion = vec2(isnan(motion.x) || isinf(motion.x) ? 0.0 : motion.x, isnan(motion.y) || isinf(motion.y) ? 0.0 : motion.y);
  store(p, color, depth, d.mesh.z, n, motion);
}
)";

}  // namespace fovea::render::gl
