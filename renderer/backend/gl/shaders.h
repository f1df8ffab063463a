// SPDX-License-Identifier: Apache-2.0
#pragma once
// GLSL of the G-buffer pass. The fragment shader's shade_local() and shade_pbr() are line-by-line
// ports of scene/shading.cpp (modified Blinn-Phong, Jensen & Pedersen 2009 eq. 5.21-5.23, 5.33, spot
// smoothstep, area lights as n x n cosine emitters expanded on the CPU by light_samples(), ambient,
// emissive; glTF 2.0 appendix B with evaluate_pbr()'s textures). Keep them in step:
// tests/gl/test_gl_backend.cpp and tests/gl/test_gl_gltf.cpp compare them pixel by pixel.

namespace fovea::render::gl {

// Most light samples one frame can use (an area light of n x n samples counts n*n). 256 samples of
// 3 vec4 (std140) = 12 KiB, under the 16 KiB minimum GL_MAX_UNIFORM_BLOCK_SIZE of GL 3.3.
inline constexpr int kMaxLightSamples = 256;

inline constexpr const char* kGBufferVertex = R"(#version 330 core
layout(location = 0) in vec3 a_position;
layout(location = 1) in vec3 a_normal;
// PBR attributes (a second buffer; when a mesh has none they are disabled and read the generic
// values GlBackend sets: 0, and colour 1).
layout(location = 2) in vec2 a_uv0;
layout(location = 3) in vec2 a_uv1;
layout(location = 4) in vec4 a_color;
layout(location = 5) in vec4 a_tangent;

uniform mat4 u_model;        // object -> world at time now
uniform mat4 u_model_prev;   // object -> world at the previous frame's time
uniform mat3 u_normal_matrix;  // inverse transpose of u_model's upper 3x3
uniform mat4 u_view, u_view_prev, u_proj;

out vec3 v_world;
out vec3 v_normal;
out float v_view_depth;
out vec4 v_clip_prev;
out vec2 v_uv0, v_uv1;
out vec4 v_color;
out vec3 v_tangent, v_bitangent;  // world space, in the surface (they transform with the model matrix)
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
  v_uv0 = a_uv0;
  v_uv1 = a_uv1;
  v_color = a_color;
  v_tangent = mat3(u_model) * a_tangent.xyz;
  v_bitangent = mat3(u_model) * (cross(a_normal, a_tangent.xyz) * (a_tangent.w < 0.0 ? -1.0 : 1.0));
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

// scene/shading.cpp sum_lights() for light sample i: the irradiance at x (0 when the sample is
// behind the normal or outside its cone), and the unit direction to it in l.
vec3 light_irradiance(int i, vec3 x, vec3 n, out vec3 l) {
  LightSample s = u_lights[i];
  l = vec3(0.0, 0.0, 1.0);
  vec3 to_light = s.position_kind.xyz - x;
  float d2 = dot(to_light, to_light);
  if (!(d2 > 1e-12)) return vec3(0.0);
  float d = sqrt(d2);
  l = to_light / d;
  float cos_theta = dot(n, l);
  if (cos_theta <= 0.0) return vec3(0.0);
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
  if (emit <= 0.0) return vec3(0.0);
  return s.power_cutoff.xyz * (emit * cos_theta / d2);
}

vec3 view_direction(vec3 x, vec3 eye, vec3 n) {
  vec3 to_eye = eye - x;
  float eye_dist = length(to_eye);
  return eye_dist > 0.0 ? to_eye / eye_dist : n;
}

// scene/shading.cpp shade_local(), without the visibility callback (no shadows in the raster backend).
vec3 shade_local(vec3 x, vec3 n, vec3 eye, vec3 kd, vec3 ks, vec3 emission, float shininess, bool emissive) {
  if (emissive) return finite_or_zero(emission + kd * u_ambient);
  vec3 v = view_direction(x, eye, n);
  vec3 radiance = kd * u_ambient;
  for (int i = 0; i < u_light_count; ++i) {
    vec3 l;
    vec3 irradiance = light_irradiance(i, x, n, l);
    if (irradiance == vec3(0.0)) continue;
    vec3 h = normalize(l + v);  // eq. 5.21
    float n_dot_h = max(0.0, dot(n, h));
    // std::pow(0, 0) == 1 in C++; GLSL leaves pow(0, 0) undefined.
    float highlight = shininess == 0.0 ? 1.0 : pow(n_dot_h, shininess);
    vec3 brdf = ks * highlight + kd;  // eq. 5.22
    radiance += brdf * irradiance;
  }
  return finite_or_zero(radiance);
}

// scene/shading.cpp pbr_brdf(): glTF 2.0 appendix B.
vec3 pbr_brdf(vec3 n, vec3 base, float metallic, float roughness, vec3 l, vec3 v) {
  float n_dot_l = max(0.0, dot(n, l));
  float n_dot_v = max(1e-4, abs(dot(n, v)));
  if (n_dot_l <= 0.0) return vec3(0.0);
  vec3 h = l + v;
  float h_len = length(h);
  h = h_len > 1e-12 ? h / h_len : n;
  float n_dot_h = max(0.0, dot(n, h));
  float v_dot_h = clamp(abs(dot(v, h)), 0.0, 1.0);
  float alpha = max(roughness * roughness, 1e-3), a2 = alpha * alpha;
  vec3 c_diff = mix(base, vec3(0.0), metallic);
  vec3 f0 = mix(vec3(0.04), base, metallic);
  float fw = pow(1.0 - v_dot_h, 5.0);
  vec3 fresnel = f0 + (vec3(1.0) - f0) * fw;
  float denom_d = n_dot_h * n_dot_h * (a2 - 1.0) + 1.0;
  float d = a2 / (kPi * denom_d * denom_d);
  float vis = 1.0 / ((n_dot_l + sqrt(a2 + (1.0 - a2) * n_dot_l * n_dot_l)) *
                     (n_dot_v + sqrt(a2 + (1.0 - a2) * n_dot_v * n_dot_v)));
  return (vec3(1.0) - fresnel) * c_diff / kPi + fresnel * (d * vis);
}

// scene/shading.cpp shade_pbr(), without shadows.
vec3 shade_pbr(vec3 x, vec3 n, vec3 eye, vec3 base, float metallic, float roughness, float occlusion, vec3 emission) {
  vec3 v = view_direction(x, eye, n);
  vec3 c_diff = mix(base, vec3(0.0), metallic);
  vec3 f0 = mix(vec3(0.04), base, metallic);
  vec3 radiance = emission + u_ambient * (c_diff + f0) * occlusion;
  for (int i = 0; i < u_light_count; ++i) {
    vec3 l;
    vec3 irradiance = light_irradiance(i, x, n, l);
    if (irradiance == vec3(0.0)) continue;
    radiance += pbr_brdf(n, base, metallic, roughness, l, v) * irradiance;
  }
  return finite_or_zero(radiance);
}
)";

// Depth peeling (gl_peel.h), shared by the forward G-buffer's and the visibility buffer's peel so that
// both keep the same fragments: true for a fragment not farther than the last layer's by the Embree
// backend's step past its last hit (max(1e-4, 1e-5 t) in distance t, here in view depth), or at a
// pixel already resolved.
inline constexpr const char* kPeelTest = R"(
uniform sampler2D u_peel_depth;
uniform usampler2D u_peel_state;
bool peeled_away(ivec2 p, float view_depth, vec3 world, vec3 eye) {
  float last = texelFetch(u_peel_depth, p, 0).r;
  float cos_view = clamp(view_depth / max(length(world - eye), 1e-30), 0.0, 1.0);
  return view_depth <= last + max(1e-4 * cos_view, 1e-5 * last) || texelFetch(u_peel_state, p, 0).y >= 0x80000000u;
}
)";

// After "#version 330 core", kShadingGlsl and kPeelTest.
inline constexpr const char* kGBufferFragment = R"(
in vec3 v_world;
in vec3 v_normal;
in float v_view_depth;
in vec4 v_clip_prev;
in vec2 v_uv0, v_uv1;
in vec4 v_color;
in vec3 v_tangent, v_bitangent;

uniform vec3 u_eye;
uniform vec2 u_viewport;   // width, height in pixels
uniform int u_moved;       // 0: same model and view matrices at both times, motion exactly 0
uniform uint u_object_id;
uniform int u_emissive;
uniform vec3 u_kd, u_ks, u_emission;
uniform float u_shininess;
// MetallicRoughness (scene/shading.h evaluate_pbr): factors, then one sampler per texture slot
// (0 base colour, 1 metallic-roughness, 2 normal, 3 occlusion, 4 emissive); bit k of u_tex_present
// says slot k has a texture, bit k of u_tex_set1 that it reads TEXCOORD_1.
uniform bool u_pbr;
uniform vec4 u_base_color;
uniform vec2 u_metallic_roughness;
uniform vec3 u_emissive_factor;
uniform float u_normal_scale, u_occlusion_strength;
uniform bool u_alpha_test;
uniform float u_alpha_cutoff;
uniform int u_tex_present, u_tex_set1;
uniform sampler2D u_tex_base, u_tex_mr, u_tex_normal, u_tex_occlusion, u_tex_emissive;
// Depth peeling (gl_peel.h, kPeelTest): keep only fragments farther than the last layer's.
uniform bool u_peel;

layout(location = 0) out vec4 o_color;
layout(location = 1) out float o_depth;
layout(location = 2) out uint o_object_id;
layout(location = 3) out vec4 o_normal;
layout(location = 4) out vec2 o_motion;

bool has_texture(int slot) { return (u_tex_present & (1 << slot)) != 0; }
vec2 slot_uv(int slot) { return (u_tex_set1 & (1 << slot)) != 0 ? v_uv1 : v_uv0; }

// evaluate_pbr()'s bent normal: the normal map in the front side's frame, turned round on a back face.
vec3 bent_normal(vec3 front, vec3 tangent_space) {
  float w = dot(cross(front, v_tangent), v_bitangent) < 0.0 ? -1.0 : 1.0;
  vec3 t_ortho = v_tangent - front * dot(front, v_tangent);
  float t_len = length(t_ortho);
  if (!(t_len > 1e-12) || isinf(t_len)) return front;
  vec3 t = t_ortho / t_len;
  vec3 b = cross(front, t) * w;
  vec3 tn = tangent_space * 2.0 - 1.0;
  tn.xy *= u_normal_scale;
  vec3 bent = t * tn.x + b * tn.y + front * tn.z;
  float len = length(bent);
  return len > 1e-12 && !isinf(len) && dot(bent, front) > 0.0 ? bent / len : front;
}

void main() {
  // Geometric normal as the fallback for a degenerate interpolated normal (computed outside any
  // branch: derivatives need uniform control flow).
  vec3 geometric = cross(dFdx(v_world), dFdy(v_world));
  // Every texture read before any discard: implicit derivatives need the whole quad. The alpha
  // test reads the base level (as the Embree backend's filter does).
  vec4 tex_base = vec4(1.0), tex_mr = vec4(1.0), tex_normal = vec4(0.5, 0.5, 1.0, 1.0), tex_occ = vec4(1.0),
       tex_emissive = vec4(1.0);
  float alpha_base = 1.0;
  if (u_pbr) {
    if (has_texture(0)) {
      tex_base = texture(u_tex_base, slot_uv(0));
      alpha_base = textureLod(u_tex_base, slot_uv(0), 0.0).a;
    }
    if (has_texture(1)) tex_mr = texture(u_tex_mr, slot_uv(1));
    if (has_texture(2)) tex_normal = texture(u_tex_normal, slot_uv(2));
    if (has_texture(3)) tex_occ = texture(u_tex_occlusion, slot_uv(3));
    if (has_texture(4)) tex_emissive = texture(u_tex_emissive, slot_uv(4));
    if (u_alpha_test && clamp(u_base_color.a * v_color.a * alpha_base, 0.0, 1.0) < u_alpha_cutoff) discard;
  }
  float len = length(v_normal);
  vec3 n;
  vec3 front = vec3(0.0, 0.0, 1.0);
  bool back_face = false;
  if (len > 1e-20 && !isinf(len)) {
    front = v_normal / len;
    back_face = !gl_FrontFacing;
    n = back_face ? -front : front;  // the G-buffer normal faces the camera
  } else {
    float glen = length(geometric);
    n = glen > 0.0 ? geometric / glen : vec3(0.0, 0.0, 1.0);
    if (dot(n, u_eye - v_world) < 0.0) n = -n;
    front = n;
  }
  // After the derivatives: they need every fragment of the quad.
  if (u_peel && peeled_away(ivec2(gl_FragCoord.xy), v_view_depth, v_world, u_eye)) discard;

  if (u_pbr) {
    vec3 base = clamp((u_base_color * v_color * tex_base).rgb, 0.0, 1.0);
    float metallic = clamp(u_metallic_roughness.x * tex_mr.b, 0.0, 1.0);
    float roughness = clamp(u_metallic_roughness.y * tex_mr.g, 0.0, 1.0);
    float occlusion = has_texture(3) ? clamp(1.0 + u_occlusion_strength * (tex_occ.r - 1.0), 0.0, 1.0) : 1.0;
    vec3 emission = max(u_emissive_factor * tex_emissive.rgb, vec3(0.0));
    vec3 shading_normal = n;
    if (has_texture(2) && dot(v_tangent, v_tangent) > 0.0) {
      shading_normal = bent_normal(front, tex_normal.rgb);
      if (back_face) shading_normal = -shading_normal;
    }
    o_color = vec4(shade_pbr(v_world, shading_normal, u_eye, base, metallic, roughness, occlusion, emission), 1.0);
  } else {
    o_color = vec4(shade_local(v_world, n, u_eye, u_kd, u_ks, u_emission, u_shininess, u_emissive != 0), 1.0);
  }
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

// Depth peeling through the visibility buffer (GlVisibilityPass::raster_peel, gl_peel.h): each
// peeling draw writes the view depth and object id the peel's resolve reads, and which triangle it
// kept (attachment 5), no shading; kVisibilityResolve shades each chosen layer once. The position and
// view depth as kGBufferVertex computes them, and kGBufferFragment's discard (kPeelTest), so that both
// peels keep the same fragments.
inline constexpr const char* kPeelVisibilityVertex = R"(#version 330 core
layout(location = 0) in vec3 a_position;
uniform mat4 u_model;
uniform mat4 u_view, u_proj;
out vec3 v_world;
out float v_view_depth;
invariant gl_Position;
void main() {
  vec4 world = u_model * vec4(a_position, 1.0);
  vec4 view = u_view * world;
  v_world = world.xyz;
  v_view_depth = -view.z;
  gl_Position = u_proj * view;
}
)";

// After "#version 330 core" and kPeelTest.
inline constexpr const char* kPeelVisibilityFragment = R"(
uniform uint u_draw;       // 1 + the object's index in the frame's draw list
uniform uint u_object_id;  // its Object::id
uniform vec3 u_eye;
uniform bool u_peel;  // false: the unpeeled layer
in vec3 v_world;
in float v_view_depth;
layout(location = 1) out float o_depth;
layout(location = 2) out uint o_object_id;
layout(location = 5) out uvec2 o_visibility;
void main() {
  if (u_peel && peeled_away(ivec2(gl_FragCoord.xy), v_view_depth, v_world, u_eye)) discard;
  o_depth = v_view_depth;
  o_object_id = u_object_id;
  o_visibility = uvec2(u_draw, uint(gl_PrimitiveID));
}
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
