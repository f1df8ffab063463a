// SPDX-License-Identifier: Apache-2.0
#include "backend/gl/gl_lee_splat.h"

#include <epoxy/gl.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "backend/gl/gl_program.h"

namespace fovea::render {

namespace {

// Shared by every pass: the image's size, top-down pixel coordinates (the CPU's) to texels (bottom-
// up), and eq. 5.3's signed CoC as CocModel::signed_coc_px computes it, clamped to +-2 r_cap as
// lee_splat.cpp's Frame::signed_coc.
constexpr const char* kCommon = R"(
const float kInf = uintBitsToFloat(0x7f800000u);
const float kRim = 1e-4;  // lee_splat.cpp's slack on footprint edges
uniform ivec2 u_size;
uniform int u_form;  // CocModel::Terms::Form: 0 zero, 1 regular, 2 focus at infinity
uniform float u_k, u_df, u_ef_px, u_cap, u_rcap;
ivec2 texel(int x, int y_top) { return ivec2(x, u_size.y - 1 - y_top); }
float signed_coc(float d) {
  if (u_form == 0) return 0.0;
  float b;
  if (u_form == 2) {
    float dd = isnan(d) ? kInf : d;
    b = dd > 0.0 ? -u_ef_px / dd : -u_cap;
  } else if (isnan(d) || isinf(d)) {
    b = d < 0.0 ? -u_cap : u_k;
  } else if (d <= 0.0) {
    b = u_df > 0.0 ? -u_cap : 0.0;
  } else {
    b = u_k * (d - u_df) / d;  // Lee 2009, eq. 5.3
  }
  if (isnan(b) || isinf(b)) b = b > 0.0 ? u_cap : -u_cap;
  return clamp(clamp(b, -u_cap, u_cap), -2.0 * u_rcap, 2.0 * u_rcap);
}
// The footprint's half-width at row offset dy (lee_splat.cpp's Footprint::span); < 0: no pixel.
uniform int u_aperture;  // 0 disc, 1 Gaussian, 2 hexagon
float half_width(float dy, float r) {
  if (u_aperture == 2) return dy <= 0.5 * r ? 0.5 * 1.7320508075688772 * r : (r - dy) * 1.7320508075688772;
  return sqrt(max(0.0, r * r - dy * dy));
}
)";

// 1. Per pixel: the sanitised source colour (eq. 5.5 when asked) and B_v; the hidden pixel's colour,
// B_h and whether it passed §5.1.2's three tests.
constexpr const char* kClassify = R"(
uniform sampler2D u_color, u_depth, u_hidden_color, u_hidden_depth;
uniform bool u_use_hidden, u_ldr;
uniform float u_zscale, u_zf_norm, u_eps, u_lap_thr, u_l0, u_falloff, u_gain;
layout(location = 0) out vec4 o_source;
layout(location = 1) out vec4 o_hidden;
layout(location = 2) out vec4 o_ok;
const vec2 kPoisson[12] = vec2[12](vec2(-0.326212, -0.405805), vec2(-0.840144, -0.073580), vec2(-0.695914, 0.457137),
  vec2(-0.203345, 0.620716), vec2(0.962340, -0.194983), vec2(0.473434, -0.480026), vec2(0.519456, 0.767022),
  vec2(0.185461, -0.893124), vec2(0.507431, 0.064425), vec2(0.896420, 0.412458), vec2(-0.321940, -0.932615),
  vec2(-0.791559, -0.597705));
float sane(float v) { return (isnan(v) || isinf(v)) ? 0.0 : clamp(v, -1e30, 1e30); }
vec3 sane(vec3 c) { return vec3(sane(c.r), sane(c.g), sane(c.b)); }
// Lee 2009, eq. 5.5 (lee_splat.cpp's extrapolate_highlight).
vec3 highlight(vec3 f) {
  if (!u_ldr || !(u_l0 < 1.0)) return f;
  float lambda = 0.3 * f.r + 0.59 * f.g + 0.11 * f.b;
  if (!(lambda > u_l0)) return f;
  float ln = clamp((lambda - u_l0) / (1.0 - u_l0), 0.0, 1.0);
  float p = u_falloff > 0.0 ? pow(ln, u_falloff) : 1.0;
  return sane(f * ((1.0 - p) + p * u_gain));
}
float znorm(float d) {
  float z = d / u_zscale;
  return isnan(z) ? 1e6 : clamp(z, 0.0, 1e6);
}
// Lee 2009, eq. 5.1 at (x, y) (top-down) over the Poisson samples within `rad`.
float laplacian(int x, int y, float rad) {
  float zp = znorm(texelFetch(u_depth, texel(x, y), 0).r), sum = 0.0;
  for (int i = 0; i < 12; ++i) {
    int nx = clamp(int(floor(clamp(float(x) + kPoisson[i].x * rad, -1e7, 1e7) + 0.5)), 0, u_size.x - 1);
    int ny = clamp(int(floor(clamp(float(y) + kPoisson[i].y * rad, -1e7, 1e7) + 0.5)), 0, u_size.y - 1);
    sum += znorm(texelFetch(u_depth, texel(nx, ny), 0).r) - zp;
  }
  return sum / 12.0;
}
void main() {
  ivec2 t = ivec2(gl_FragCoord.xy);
  int x = t.x, y = u_size.y - 1 - t.y;
  float zv = texelFetch(u_depth, t, 0).r, bv = signed_coc(zv);
  o_source = vec4(highlight(sane(texelFetch(u_color, t, 0).rgb)), bv);
  o_hidden = vec4(0.0);
  o_ok = vec4(0.0);
  if (!u_use_hidden) return;
  float zh = texelFetch(u_hidden_depth, t, 0).r;
  bool ok = !isnan(zh) && !isinf(zh) && zh > 0.0 && znorm(zh) >= znorm(zv) + u_eps;  // 1: not the same surface
  ok = ok && !(znorm(zv) > u_zf_norm) && !isnan(zv) && !isinf(zv);                  // 2: not background
  ok = ok && laplacian(x, y, 0.5 * abs(bv)) >= u_lap_thr;                            // 3: eq. 5.1
  o_hidden = vec4(highlight(sane(texelFetch(u_hidden_color, t, 0).rgb)), signed_coc(zh));
  o_ok = vec4(ok ? 1.0 : 0.0);
}
)";

// 2. Eq. 5.2's k_n(C) per point: 1 / the IDF summed over the point's discrete footprint (centred on
// its pixel, radius r = min(|B| / 2, r_cap)): rows |dy| <= floor(r + rim), per row the pixels within
// floor(half width + rim). The Gaussian (sigma = r / 2) row sums shrink with |dy|: one running sum.
constexpr const char* kNorm = R"(
uniform sampler2D u_source, u_hidden, u_ok;
out vec2 o;
float norm_of(float b) {
  float r = min(0.5 * abs(b), u_rcap), rows = floor(r + kRim), total = 0.0;
  if (u_aperture == 1) {
    float a = r > 0.0 ? 2.0 / (r * r) : 0.0;
    float m = floor(half_width(0.0, r) + kRim), row = 1.0;
    for (float k = 1.0; k <= m; k += 1.0) row += 2.0 * exp(-k * k * a);
    for (float dy = 0.0; dy <= rows; dy += 1.0) {
      float hw = half_width(dy, r);
      if (hw < 0.0) continue;
      for (float mn = floor(hw + kRim); m > mn; m -= 1.0) row -= 2.0 * exp(-m * m * a);
      total += (dy == 0.0 ? 1.0 : 2.0) * exp(-dy * dy * a) * row;
    }
  } else {
    for (float dy = 0.0; dy <= rows; dy += 1.0) {
      float hw = half_width(dy, r);
      if (hw >= 0.0) total += (dy == 0.0 ? 1.0 : 2.0) * (2.0 * floor(hw + kRim) + 1.0);
    }
  }
  return total > 0.0 ? 1.0 / total : 1.0;
}
void main() {
  ivec2 t = ivec2(gl_FragCoord.xy);
  float hidden = texelFetch(u_ok, t, 0).r > 0.5 ? norm_of(texelFetch(u_hidden, t, 0).a) : 0.0;
  o = vec2(norm_of(texelFetch(u_source, t, 0).a), hidden);
}
)";

// 3. One instanced quad per point (instance 2i: pixel i's visible point, 2i + 1: its hidden one)
// over its footprint's bounding box; a hidden point that failed the tests is a degenerate quad.
constexpr const char* kSplatVertex = R"(
uniform sampler2D u_source, u_hidden, u_ok, u_norm;
flat out vec4 v_point;  // cx, cy (top-down), r, B
flat out vec4 v_cw;     // premultiplied colour and weight of eq. 5.2
flat out int v_hidden;
void main() {
  int i = gl_InstanceID >> 1;
  bool hidden = (gl_InstanceID & 1) == 1;
  int x = i % u_size.x, y = i / u_size.x;
  ivec2 t = texel(x, y);
  gl_Position = vec4(2.0, 2.0, 0.0, 1.0);
  v_hidden = hidden ? 1 : 0;
  if (hidden && texelFetch(u_ok, t, 0).r < 0.5) return;
  vec4 p = hidden ? texelFetch(u_hidden, t, 0) : texelFetch(u_source, t, 0);
  vec2 n = texelFetch(u_norm, t, 0).rg;
  float k = hidden ? n.g : n.r;
  float r = min(0.5 * abs(p.a), u_rcap), rows = floor(r + kRim);
  v_point = vec4(float(x), float(y), r, p.a);
  v_cw = vec4(p.rgb * k, k);
  vec2 corner = vec2(float(gl_VertexID & 1), float(gl_VertexID >> 1));
  vec2 lo = vec2(float(x) - rows, float(u_size.y - 1 - y) - rows);  // in GL pixels (y up)
  vec2 at = lo + corner * (2.0 * rows + 1.0);
  gl_Position = vec4(at / vec2(u_size) * 2.0 - 1.0, 0.0, 1.0);
}
)";
// Eq. 5.3 against the destination pixel q: layer 0 in front, 1 the same depth group, 2 behind (a
// hidden point never in front: M^0 is not defined, §5.1.4).
constexpr const char* kSplatFragment = R"(
uniform sampler2D u_source;
uniform float u_delta;
flat in vec4 v_point;
flat in vec4 v_cw;
flat in int v_hidden;
layout(location = 0) out vec4 o_front;
layout(location = 1) out vec4 o_same;
layout(location = 2) out vec4 o_behind;
void main() {
  ivec2 q = ivec2(gl_FragCoord.xy);
  float qx = float(q.x), qy = float(u_size.y - 1 - q.y);
  float dy = abs(qy - v_point.y), dx = abs(qx - v_point.x), r = v_point.z;
  float hw = half_width(dy, r);
  if (hw < 0.0 || dy > floor(r + kRim) || dx > floor(hw + kRim)) discard;
  vec4 cw = v_cw;
  if (u_aperture == 1) {
    float a = r > 0.0 ? 2.0 / (r * r) : 0.0;
    cw *= exp(-dy * dy * a) * exp(-dx * dx * a);
  }
  float bv = texelFetch(u_source, q, 0).a, t = u_delta * abs(bv), d = v_point.w - bv;
  int l = max(v_hidden, int(d >= -t) + int(d > t));
  o_front = l == 0 ? cw : vec4(0.0);
  o_same = l == 1 ? cw : vec4(0.0);
  o_behind = l == 2 ? cw : vec4(0.0);
}
)";

// 3 on OpenGL 4.3, as compute passes: the same sums as a tiled gather. First the reach, the largest
// footprint's row count over every point (visible and hidden), by an atomic maximum; then one
// 16x16 workgroup per tile of destination pixels walks the points within that reach of its tile in
// batches of 256: each thread loads one pixel's points and keeps those whose footprint's bounding box
// meets the tile, compacted in pixel order by a prefix sum (so every run adds in the same order),
// and each thread adds the kept points that cover its pixel into its three layers (eq. 5.3), as the
// fragment pass's blending does. No float atomics, no rasteriser.
constexpr const char* kReach = R"(
layout(local_size_x = 8, local_size_y = 8) in;
uniform sampler2D u_source, u_hidden, u_ok;
layout(std430, binding = 0) buffer Reach { uint u_reach; };
void main() {
  ivec2 t = ivec2(gl_GlobalInvocationID.xy);
  if (t.x >= u_size.x || t.y >= u_size.y) return;
  float r = min(0.5 * abs(texelFetch(u_source, t, 0).a), u_rcap);
  if (texelFetch(u_ok, t, 0).r > 0.5) r = max(r, min(0.5 * abs(texelFetch(u_hidden, t, 0).a), u_rcap));
  atomicMax(u_reach, uint(floor(r + kRim)));
}
)";
constexpr const char* kSplatCompute = R"(
layout(local_size_x = 16, local_size_y = 16) in;
uniform sampler2D u_source, u_hidden, u_ok, u_norm;
uniform float u_delta;
layout(std430, binding = 0) readonly buffer Reach { uint u_reach; };
layout(rgba32f, binding = 0) uniform writeonly image2D u_front;
layout(rgba32f, binding = 1) uniform writeonly image2D u_same;
layout(rgba32f, binding = 2) uniform writeonly image2D u_behind;
shared vec4 s_point[512];  // x, y (texels), r, B
shared vec4 s_cw[512];     // premultiplied colour and weight of eq. 5.2; w < 0: a hidden point (-w)
shared uint s_scan[256];
// The point's footprint (rows = floor(r + rim) around it) meets the tile [lo, lo + 15]^2.
bool meets(ivec2 p, float r, ivec2 lo) {
  int rows = int(floor(r + kRim));
  ivec2 d = max(max(lo - p, p - (lo + 15)), ivec2(0));
  return d.x <= rows && d.y <= rows;
}
void main() {
  ivec2 lo = ivec2(gl_WorkGroupID.xy) * 16;
  ivec2 q = lo + ivec2(gl_LocalInvocationID.xy);
  uint lid = gl_LocalInvocationIndex;
  bool inside = q.x < u_size.x && q.y < u_size.y;
  float bv = inside ? texelFetch(u_source, q, 0).a : 0.0, t = u_delta * abs(bv);
  vec4 acc0 = vec4(0.0), acc1 = vec4(0.0), acc2 = vec4(0.0);
  int reach = int(min(u_reach, 1u << 20));
  ivec2 wlo = max(lo - reach, ivec2(0)), whi = min(lo + 15 + reach, u_size - 1);
  int ww = whi.x - wlo.x + 1, n = ww * (whi.y - wlo.y + 1);
  for (int base = 0; base < n; base += 256) {
    // This thread's pixel's points that may reach the tile.
    int i = base + int(lid);
    vec4 pv = vec4(0.0), ph = vec4(0.0), cv = vec4(0.0), ch = vec4(0.0);
    uint keep = 0u;  // bit 0: the visible point, bit 1: the hidden one
    if (i < n) {
      ivec2 p = wlo + ivec2(i % ww, i / ww);
      vec2 k = texelFetch(u_norm, p, 0).rg;
      vec4 src = texelFetch(u_source, p, 0);
      float r = min(0.5 * abs(src.a), u_rcap);
      if (meets(p, r, lo)) {
        keep |= 1u;
        pv = vec4(vec2(p), r, src.a);
        cv = vec4(src.rgb * k.r, k.r);
      }
      if (texelFetch(u_ok, p, 0).r > 0.5) {
        vec4 hid = texelFetch(u_hidden, p, 0);
        float rh = min(0.5 * abs(hid.a), u_rcap);
        if (meets(p, rh, lo)) {
          keep |= 2u;
          ph = vec4(vec2(p), rh, hid.a);
          ch = vec4(hid.rgb * k.g, -k.g);
        }
      }
    }
    // Inclusive prefix sum of the kept counts (Hillis-Steele): pixel order, the same every run.
    uint mine = bitCount(keep);
    s_scan[lid] = mine;
    barrier();
    for (uint off = 1u; off < 256u; off <<= 1u) {
      uint v = lid >= off ? s_scan[lid - off] : 0u;
      barrier();
      s_scan[lid] += v;
      barrier();
    }
    uint at = s_scan[lid] - mine, m = s_scan[255];
    if ((keep & 1u) != 0u) { s_point[at] = pv; s_cw[at] = cv; at += 1u; }
    if ((keep & 2u) != 0u) { s_point[at] = ph; s_cw[at] = ch; }
    barrier();
    if (inside) {
      for (uint j = 0u; j < m; ++j) {
        vec4 P = s_point[j];
        float dy = abs(float(q.y) - P.y), dx = abs(float(q.x) - P.x), r = P.z;
        float hw = half_width(dy, r);
        if (hw < 0.0 || dy > floor(r + kRim) || dx > floor(hw + kRim)) continue;
        vec4 cw = s_cw[j];
        int hidden = cw.a < 0.0 ? 1 : 0;
        cw.a = abs(cw.a);
        if (u_aperture == 1) {
          float a = r > 0.0 ? 2.0 / (r * r) : 0.0;
          cw *= exp(-dy * dy * a) * exp(-dx * dx * a);
        }
        float d = P.w - bv;
        int l = max(hidden, int(d >= -t) + int(d > t));
        if (l == 0) acc0 += cw; else if (l == 1) acc1 += cw; else acc2 += cw;
      }
    }
    barrier();  // the next batch overwrites the shared points
  }
  if (!inside) return;
  imageStore(u_front, q, acc0);
  imageStore(u_same, q, acc1);
  imageStore(u_behind, q, acc2);
}
)";

// 4. Lee 2009, eq. 5.4: D <- L^2; D <- L^1 + (1 - L^1_a) D; D <- L^0 + (1 - L^0_a) D, each D divided
// by its alpha (empty: 0); a pixel no splat covers keeps its source colour. u_copy: a pinhole lens,
// the input itself (non-finite as 0), as the CPU returns it.
constexpr const char* kCompose = R"(
uniform sampler2D u_front, u_same, u_behind, u_source, u_color;
uniform bool u_copy;
out vec4 o;
float finite_or_zero(float v) { return (isnan(v) || isinf(v)) ? 0.0 : v; }
void unit_alpha(inout vec3 d, inout float da) {
  if (da > 1e-20) { d /= da; da = 1.0; } else { d = vec3(0.0); da = 0.0; }
}
void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  vec3 r;
  if (u_copy) {
    r = texelFetch(u_color, p, 0).rgb;
  } else {
    vec4 l2 = texelFetch(u_behind, p, 0), l1 = texelFetch(u_same, p, 0), l0 = texelFetch(u_front, p, 0);
    vec3 d = l2.rgb;
    float da = l2.a;
    unit_alpha(d, da);
    float keep = 1.0 - min(max(l1.a, 0.0), 1.0);
    d = l1.rgb + keep * d;
    da = l1.a + keep * da;
    unit_alpha(d, da);
    keep = 1.0 - min(max(l0.a, 0.0), 1.0);
    d = l0.rgb + keep * d;
    da = l0.a + keep * da;
    unit_alpha(d, da);
    r = da > 0.0 ? d : texelFetch(u_source, p, 0).rgb;
  }
  o = vec4(finite_or_zero(r.r), finite_or_zero(r.g), finite_or_zero(r.b), 1.0);
}
)";

GLuint program(const char* body, const char* what) {
  const std::string fragment = std::string("#version 330 core\n") + kCommon + body;
  return gl::link_program(gl::kFullscreenVertex, fragment.c_str(), what);
}

GLuint compute_program(const char* body, const char* what) {
  const std::string source = std::string("#version 430 core\n") + kCommon + body;
  return gl::link_compute_program(source.c_str(), what);
}

float to_float(double v) {
  constexpr double kMax = std::numeric_limits<float>::max();
  return std::isnan(v) ? 0.0f : v > kMax ? std::numeric_limits<float>::infinity() : static_cast<float>(std::max(v, -kMax));
}

int aperture_index(dof::Aperture a) { return a == dof::Aperture::Gaussian ? 1 : a == dof::Aperture::Hexagon ? 2 : 0; }

}  // namespace

GlLeeSplat::GlLeeSplat(bool compute) {
  classify_program_ = program(kClassify, "GlLeeSplat classify");
  norm_program_ = program(kNorm, "GlLeeSplat normalise");
  const std::string header = std::string("#version 330 core\n") + kCommon;
  const std::string vertex = header + kSplatVertex, fragment = header + kSplatFragment;
  splat_program_ = gl::link_program(vertex.c_str(), fragment.c_str(), "GlLeeSplat splat");
  compose_program_ = program(kCompose, "GlLeeSplat compose");
  if (compute) {
    reach_program_ = compute_program(kReach, "GlLeeSplat reach");
    splat_compute_program_ = compute_program(kSplatCompute, "GlLeeSplat compute splat");
    glGenBuffers(1, &reach_);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, reach_);
    glBufferData(GL_SHADER_STORAGE_BUFFER, sizeof(std::uint32_t), nullptr, GL_DYNAMIC_DRAW);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
  }
  glGenVertexArrays(1, &vao_);
  glGenFramebuffers(1, &fbo_);
  glGenQueries(2, queries_);
  gl::check_error("GlLeeSplat", "construction");
}

GlLeeSplat::~GlLeeSplat() {
  for (unsigned p : {classify_program_, norm_program_, splat_program_, compose_program_, reach_program_,
                     splat_compute_program_})
    if (p != 0) glDeleteProgram(p);
  if (reach_ != 0) glDeleteBuffers(1, &reach_);
  for (unsigned* t : {&source_, &hidden_, &hidden_ok_, &norm_, &layers_[0], &layers_[1], &layers_[2], &output_,
                      &upload_color_, &upload_depth_, &upload_hidden_color_, &upload_hidden_depth_})
    gl::delete_texture(*t);
  glDeleteVertexArrays(1, &vao_);
  glDeleteFramebuffers(1, &fbo_);
  glDeleteQueries(2, queries_);
}

void GlLeeSplat::ensure_targets(std::uint32_t width, std::uint32_t height) {
  if (width == width_ && height == height_ && output_ != 0) return;
  for (unsigned* t : {&source_, &hidden_, &hidden_ok_, &norm_, &layers_[0], &layers_[1], &layers_[2], &output_})
    gl::delete_texture(*t);
  for (unsigned* t : {&source_, &hidden_, &layers_[0], &layers_[1], &layers_[2], &output_})
    *t = gl::make_texture(GL_RGBA32F, GL_RGBA, GL_FLOAT, width, height);
  hidden_ok_ = gl::make_texture(GL_R8, GL_RED, GL_UNSIGNED_BYTE, width, height);
  norm_ = gl::make_texture(GL_RG32F, GL_RG, GL_FLOAT, width, height);
  width_ = width;
  height_ = height;
}

void GlLeeSplat::draw_into(std::initializer_list<unsigned> targets) {
  gl::attach_targets(fbo_, targets);
  glViewport(0, 0, static_cast<GLsizei>(width_), static_cast<GLsizei>(height_));
}

namespace {

// The uniforms of kCommon: the size, eq. 5.3's terms, r_cap and the aperture.
void set_common(unsigned p, std::uint32_t w, std::uint32_t h, const dof::CocModel& coc, const dof::LeeSplatSettings& s) {
  const dof::CocModel::Terms t = coc.terms();
  glUniform2i(glGetUniformLocation(p, "u_size"), static_cast<GLint>(w), static_cast<GLint>(h));
  glUniform1i(glGetUniformLocation(p, "u_form"), static_cast<GLint>(t.form));
  glUniform1f(glGetUniformLocation(p, "u_k"), to_float(t.k));
  glUniform1f(glGetUniformLocation(p, "u_df"), to_float(t.df));
  glUniform1f(glGetUniformLocation(p, "u_ef_px"), to_float(t.ef_px));
  glUniform1f(glGetUniformLocation(p, "u_cap"), to_float(t.cap));
  // lee_splat.cpp's footprint cap: the image diagonal (at least 1 px).
  const double diagonal = std::hypot(static_cast<double>(w), static_cast<double>(h));
  glUniform1f(glGetUniformLocation(p, "u_rcap"), to_float(std::max(1.0, diagonal)));
  glUniform1i(glGetUniformLocation(p, "u_aperture"), aperture_index(s.aperture));
}

}  // namespace

void GlLeeSplat::classify(const GlDofInput& in, const GlDofInput* hidden, const dof::CocModel& coc,
                          const dof::LeeSplatSettings& s) {
  const unsigned p = classify_program_;
  glUseProgram(p);
  set_common(p, width_, height_, coc, s);
  const bool use_hidden = s.use_hidden && hidden != nullptr && hidden->color != 0 && hidden->depth != 0;
  gl::bind_sampler(0, in.color, p, "u_color");
  gl::bind_sampler(1, in.depth, p, "u_depth");
  gl::bind_sampler(2, use_hidden ? hidden->color : in.color, p, "u_hidden_color");
  gl::bind_sampler(3, use_hidden ? hidden->depth : in.depth, p, "u_hidden_depth");
  const auto set = [p](const char* name, double v) { glUniform1f(glGetUniformLocation(p, name), to_float(v)); };
  glUniform1i(glGetUniformLocation(p, "u_use_hidden"), use_hidden ? 1 : 0);
  glUniform1i(glGetUniformLocation(p, "u_ldr"), s.ldr_highlights ? 1 : 0);
  // §5.1.2's normalised depth: depth / d_f (1 m without a finite focus distance).
  const double zf = coc.focus_m, zscale = (std::isfinite(zf) && zf > 0) ? zf : 1.0;
  set("u_zscale", zscale);
  const double zf_norm = zf / zscale;
  set("u_zf_norm", std::isnan(zf_norm) ? std::numeric_limits<double>::infinity() : zf_norm);  // NaN: test 2 passes
  set("u_eps", std::isfinite(s.hidden_epsilon) ? s.hidden_epsilon : 0.05);
  set("u_lap_thr", std::isfinite(s.laplacian_threshold) ? s.laplacian_threshold : 0.01);
  set("u_l0", s.highlight_threshold);
  set("u_falloff", std::max(0.0, s.highlight_falloff));
  set("u_gain", std::isfinite(s.highlight_gain) ? s.highlight_gain : 1.0);
  draw_into({source_, hidden_, hidden_ok_});
  glDrawArrays(GL_TRIANGLES, 0, 3);
}

void GlLeeSplat::normalise(const dof::CocModel& coc, const dof::LeeSplatSettings& s) {
  const unsigned p = norm_program_;
  glUseProgram(p);
  set_common(p, width_, height_, coc, s);
  gl::bind_sampler(0, source_, p, "u_source");
  gl::bind_sampler(1, hidden_, p, "u_hidden");
  gl::bind_sampler(2, hidden_ok_, p, "u_ok");
  draw_into({norm_});
  glDrawArrays(GL_TRIANGLES, 0, 3);
}

// The splat passes' program with its inputs: kCommon's uniforms, eq. 5.3's delta and the points.
void GlLeeSplat::use_splat_program(unsigned p, const dof::CocModel& coc, const dof::LeeSplatSettings& s) {
  glUseProgram(p);
  set_common(p, width_, height_, coc, s);
  glUniform1f(glGetUniformLocation(p, "u_delta"), to_float(std::isfinite(s.delta) ? std::max(0.0, s.delta) : 0.4));
  gl::bind_sampler(0, source_, p, "u_source");
  gl::bind_sampler(1, hidden_, p, "u_hidden");
  gl::bind_sampler(2, hidden_ok_, p, "u_ok");
  gl::bind_sampler(3, norm_, p, "u_norm");
}

void GlLeeSplat::splat(const dof::CocModel& coc, const dof::LeeSplatSettings& s) {
  use_splat_program(splat_program_, coc, s);
  draw_into({layers_[0], layers_[1], layers_[2]});
  const float zero[4] = {0, 0, 0, 0};
  for (int k = 0; k < 3; ++k) glClearBufferfv(GL_COLOR, k, zero);
  // Additive blending in point order: every pixel sums its splats in the same order each run.
  glEnable(GL_BLEND);
  glBlendEquation(GL_FUNC_ADD);
  glBlendFunc(GL_ONE, GL_ONE);
  glDrawArraysInstanced(GL_TRIANGLE_STRIP, 0, 4, static_cast<GLsizei>(2 * std::size_t{width_} * height_));
  glDisable(GL_BLEND);
}

void GlLeeSplat::splat_compute(const dof::CocModel& coc, const dof::LeeSplatSettings& s) {
  const std::uint32_t zero = 0;
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, reach_);
  glBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, sizeof zero, &zero);
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, reach_);
  use_splat_program(reach_program_, coc, s);
  glDispatchCompute((width_ + 7) / 8, (height_ + 7) / 8, 1);
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  use_splat_program(splat_compute_program_, coc, s);
  for (GLuint k = 0; k < 3; ++k) glBindImageTexture(k, layers_[k], 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA32F);
  glDispatchCompute((width_ + 15) / 16, (height_ + 15) / 16, 1);
  glMemoryBarrier(gl::kComputeWrittenBarrier);
  for (GLuint k = 0; k < 3; ++k) glBindImageTexture(k, 0, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA32F);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, 0);
}

void GlLeeSplat::compose(bool copy, unsigned input_color) {
  const unsigned p = compose_program_;
  glUseProgram(p);
  gl::bind_sampler(0, layers_[0], p, "u_front");
  gl::bind_sampler(1, layers_[1], p, "u_same");
  gl::bind_sampler(2, layers_[2], p, "u_behind");
  gl::bind_sampler(3, source_, p, "u_source");
  gl::bind_sampler(4, input_color, p, "u_color");
  glUniform1i(glGetUniformLocation(p, "u_copy"), copy ? 1 : 0);
  draw_into({output_});
  glDrawArrays(GL_TRIANGLES, 0, 3);
}

void GlLeeSplat::run(const GlDofInput& in, const GlDofInput* hidden, const dof::CocModel& coc,
                     const dof::LeeSplatSettings& s, Pass pass) {
  if (pass == Pass::Compute && !has_compute()) {
    throw std::invalid_argument("GlLeeSplat: the compute splat needs OpenGL 4.3 (built without it)");
  }
  if (s.reduce > 1) {
    throw std::invalid_argument("GlLeeSplat: reduce = " + std::to_string(s.reduce) +
                                " (Lee 2009 §5.3's reduced point array) runs on the CPU only (dof/lee_splat.h)");
  }
  if (hidden != nullptr && (hidden->width != in.width || hidden->height != in.height)) {
    throw std::invalid_argument("GlLeeSplat: the hidden image is " + std::to_string(hidden->width) + "x" +
                                std::to_string(hidden->height) + ", the visible one " + std::to_string(in.width) + "x" +
                                std::to_string(in.height));
  }
  if (in.width == 0 || in.height == 0) return;
  GLint vao = 0;
  glGetIntegerv(GL_VERTEX_ARRAY_BINDING, &vao);
  glBindVertexArray(vao_);
  glDisable(GL_DEPTH_TEST);
  glDisable(GL_BLEND);
  glDisable(GL_SCISSOR_TEST);
  ensure_targets(in.width, in.height);
  classify(in, hidden, coc, s);
  const bool pinhole = coc.terms().form == dof::CocModel::Terms::Form::Zero;
  if (!pinhole) {
    normalise(coc, s);
    if (pass == Pass::Compute) {
      splat_compute(coc, s);
    } else {
      splat(coc, s);
    }
  }
  compose(pinhole, in.color);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  glBindVertexArray(static_cast<GLuint>(vao));
  gl::check_error("GlLeeSplat", "run");
}

void GlLeeSplat::run_image(const dof::DofInput& in, const dof::LeeSplatSettings& s, dof::RgbImage& out, double* gpu_ms,
                           Pass pass) {
  const std::uint32_t w = in.width, h = in.height;
  out.assign(in.pixels(), glm::vec3(0.0f));
  if (in.pixels() == 0 || in.color == nullptr) return;
  static_assert(sizeof(glm::vec3) == 3 * sizeof(float), "colour goes up as packed floats");
  const std::vector<float> far(in.pixels(), std::numeric_limits<float>::infinity());
  const GlDofInput visible{gl::upload_top_first(upload_color_, GL_RGBA32F, GL_RGB, &in.color[0].x, w, h, 3, staging_),
                           gl::upload_top_first(upload_depth_, GL_R32F, GL_RED, in.depth ? in.depth : far.data(), w, h, 1,
                                                staging_),
                           w, h};
  GlDofInput hidden{};
  const bool with_hidden = in.hidden_color != nullptr && in.hidden_depth != nullptr;
  if (with_hidden) {
    hidden = {gl::upload_top_first(upload_hidden_color_, GL_RGBA32F, GL_RGB, &in.hidden_color[0].x, w, h, 3, staging_),
              gl::upload_top_first(upload_hidden_depth_, GL_R32F, GL_RED, in.hidden_depth, w, h, 1, staging_), w, h};
  }
  dof::CocModel coc = in.coc;
  if (in.depth == nullptr) coc.aperture_m = 0;  // no depth: nothing can be defocused (the CPU copies the input)
  glQueryCounter(queries_[0], GL_TIMESTAMP);
  run(visible, with_hidden ? &hidden : nullptr, coc, s, pass);
  glQueryCounter(queries_[1], GL_TIMESTAMP);
  if (gpu_ms != nullptr) *gpu_ms = gl::elapsed_ms(queries_);
  gl::read_rgb_top_first(fbo_, output_, w, h, out, staging_);
}

}  // namespace fovea::render
