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

inline constexpr const char* kGBufferFragment = R"(#version 330 core
in vec3 v_world;
in vec3 v_normal;
in float v_view_depth;
in vec4 v_clip_prev;

// Must stay in step with scene/shading.h LightSample and GlBackend's upload.
struct LightSample {
  vec4 position_kind;    // xyz position, w kind: 0 point, 1 spot, 2 area (cosine emitter)
  vec4 power_cutoff;     // xyz power share (W), w cos_cutoff
  vec4 direction_start;  // xyz spot axis / emitter normal, w cos_falloff_start
};
layout(std140) uniform LightSamples { LightSample u_lights[256]; };
uniform int u_light_count;

uniform vec3 u_eye;
uniform vec3 u_ambient;
uniform vec2 u_viewport;   // width, height in pixels
uniform int u_moved;       // 0: same model and view matrices at both times, motion exactly 0
uniform uint u_object_id;
uniform int u_emissive;
uniform vec3 u_kd, u_ks, u_emission;
uniform float u_shininess;

layout(location = 0) out vec4 o_color;
layout(location = 1) out float o_depth;
layout(location = 2) out uint o_object_id;
layout(location = 3) out vec4 o_normal;
layout(location = 4) out vec2 o_motion;

const float kPi = 3.14159265358979323846;

vec3 finite_or_zero(vec3 v) {
  return vec3(isnan(v.x) || isinf(v.x) ? 0.0 : v.x, isnan(v.y) || isinf(v.y) ? 0.0 : v.y,
              isnan(v.z) || isinf(v.z) ? 0.0 : v.z);
}

// scene/shading.cpp shade_local(), without the visibility callback (no shadows in the raster backend).
vec3 shade_local(vec3 x, vec3 n, vec3 eye) {
  if (u_emissive != 0) return finite_or_zero(u_emission + u_kd * u_ambient);
  vec3 to_eye = eye - x;
  float eye_dist = length(to_eye);
  vec3 v = eye_dist > 0.0 ? to_eye / eye_dist : n;
  vec3 radiance = u_kd * u_ambient;
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
    float highlight = u_shininess == 0.0 ? 1.0 : pow(n_dot_h, u_shininess);
    vec3 brdf = u_ks * highlight + u_kd;  // eq. 5.22
    radiance += brdf * irradiance;
  }
  return finite_or_zero(radiance);
}

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

  o_color = vec4(shade_local(v_world, n, u_eye), 1.0);
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

}  // namespace fovea::render::gl
