// SPDX-License-Identifier: Apache-2.0
#include "backend/gl/gl_lee_mipmap.h"

#include <epoxy/gl.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <initializer_list>
#include <limits>
#include <stdexcept>
#include <string>

#include "backend/gl/gl_program.h"

namespace fovea::render {

namespace {


// Each pass is one GLSL function of its texel, run by a fragment shader (OpenGL 3.3) or a compute
// shader (OpenGL 4.3, writing images): the same code, so both implementations agree texel for texel
// up to the texture unit's filtering, which both use alike.

// lee_mipmap_detail.h's constants and eq. 4.6, shared by the passes.
constexpr const char* kCommon = R"(
const float kTiny = 1e-18;      // the geometric blend's floor for 0 (log2 stays finite)
const float kHuge = 1e18;       // and its ceiling
const float kFarDepth = 1e30;   // non-finite depth: the far limit, kept finite for averaging
// Eq. 4.6 (and eq. 4.11 on the DoN): the continuous mipmap level of a DoB.
float level_of(float sigma, float ks) {
  float x = ks * sigma;
  return x < 0.5 ? 0.0 : 1.0 + log2(x);
}
float clean(float v) { return (isnan(v) || isinf(v)) ? 0.0 : max(v, 0.0); }
)";

// Step 1 (into level 0 of the even atlases): I(0), Z(0), B(0) = sigma = dob_per_coc x |B| of dof/lens.h's signed_coc_px (eq. 5.3) with
// CocModel::terms(); the largest B below starts as B.
constexpr const char* kBasePass = R"(
uniform sampler2D u_color, u_depth;
uniform int u_form;  // CocModel::Terms::Form: 0 zero, 1 regular, 2 focus at infinity
uniform float u_k, u_df, u_ef_px, u_cap, u_scale;
float coc(float d) {
  if (u_form == 0) return 0.0;
  float b;
  if (u_form == 2) {
    b = isnan(d) || (isinf(d) && d > 0.0) ? 0.0 : d > 0.0 ? u_ef_px / d : u_cap;
  } else if (isnan(d) || isinf(d)) {
    b = d < 0.0 ? u_cap : u_k;  // d -> +inf: (d - d_f) / d -> 1
  } else if (d <= 0.0) {
    b = u_df > 0.0 ? u_cap : 0.0;
  } else {
    b = u_k * (d - u_df) / d;  // Lee 2009, eq. 5.3
  }
  b = abs(b);
  return (isnan(b) || isinf(b)) ? u_cap : min(b, u_cap);
}
void base_texel(ivec2 p, out vec4 o_color, out vec4 o_zs) {
  vec3 c = texelFetch(u_color, p, 0).rgb;
  o_color = vec4(clamp(vec3(clean(c.r), clean(c.g), clean(c.b)), kTiny, kHuge), 0.0);
  float d = texelFetch(u_depth, p, 0).r;
  float z = isnan(d) ? kFarDepth : clamp(d, 0.0, kFarDepth);
  float s = u_scale * coc(d);
  s = isnan(s) ? 0.0 : min(s, 3.40282347e38);
  o_zs = vec4(z, s, s, 0.0);
}
)";
constexpr const char* kBaseFragment = R"(
layout(location = 0) out vec4 o_color;
layout(location = 1) out vec4 o_zs;
void main() { base_texel(ivec2(gl_FragCoord.xy), o_color, o_zs); }
)";
constexpr const char* kBaseCompute = R"(
layout(rgba32f, binding = 0) writeonly uniform image2DRect u_out_color;
layout(rgba32f, binding = 1) writeonly uniform image2DRect u_out_zs;
uniform ivec2 u_size;
void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= u_size.x || p.y >= u_size.y) return;
  vec4 c, zs;
  base_texel(p, c, zs);
  imageStore(u_out_color, p, c);
  imageStore(u_out_zs, p, zs);
}
)";

// Steps 2-3 and eq. 4.10 for level l from level l - 1 (in the other parity's atlas).
constexpr const char* kLevelPass = R"(
uniform sampler2DRect u_color, u_zs;  // the atlases holding level l - 1
uniform ivec2 u_src_origin, u_src, u_dst_origin, u_dst;
uniform bool u_aniso;
uniform float u_zf, u_delta;
// lee_mipmap_detail.h's Taps: eq. 4.1's [1 2 1] / 4 as three bilinear taps one source texel apart around
// the destination texel's centre, i.e. four texels, clamped to the edge.
void taps(int i, int sw, int dw, out int idx[4], out float w[4]) {
  float c = float((2 * i + 1) * sw) / float(2 * dw) - 0.5;
  float base = floor(c - 1.0);
  for (int k = 0; k < 4; ++k) { w[k] = 0.0; idx[k] = clamp(int(base) + k, 0, sw - 1); }
  for (int t = -1; t <= 1; ++t) {
    float g = t == 0 ? 0.5 : 0.25;
    float pos = c + float(t);
    float fl = floor(pos);
    int k = int(fl - base);
    float f = pos - fl;
    w[k] += g * (1.0 - f);
    w[k + 1] += g * f;
  }
}
// Level l's texel p (relative to its region).
void level_texel(ivec2 p, out vec4 o_color, out vec4 o_zs, out vec4 o_don) {
  int ix[4], iy[4];
  float wx[4], wy[4];
  taps(p.x, u_src.x, u_dst.x, ix, wx);
  taps(p.y, u_src.y, u_dst.y, iy, wy);
  vec4 q[16];
  float z = 0.0, s = 0.0, smax = 0.0;
  for (int a = 0; a < 4; ++a) {  // rows first, then columns: the CPU's order of sums
    float rz = 0.0, rs = 0.0;
    for (int b = 0; b < 4; ++b) {
      q[4 * a + b] = texelFetch(u_zs, u_src_origin + ivec2(ix[b], iy[a]));
      rz += wx[b] * q[4 * a + b].x;
      rs += wx[b] * q[4 * a + b].y;
      smax = max(smax, q[4 * a + b].z);
    }
    z += wy[a] * rz;
    s += wy[a] * rs;
  }
  bool background = u_aniso && z > u_zf;
  vec3 acc = vec3(0.0), iso = vec3(0.0);
  float wsum = 0.0, rho = 0.0;
  for (int a = 0; a < 4; ++a) {
    for (int b = 0; b < 4; ++b) {
      float g = wy[a] * wx[b];  // G(q - p), eq. 4.1
      vec3 cq = texelFetch(u_color, u_src_origin + ivec2(ix[b], iy[a])).rgb;
      iso += g * cq;
      float h = background && s > q[4 * a + b].y + u_delta ? 0.0 : g;  // Lee 2009, eq. 4.9
      acc += h * cq;
      wsum += h;
      if (q[4 * a + b].x < u_zf && q[4 * a + b].x < z) rho = max(rho, q[4 * a + b].y);  // eq. 4.10
    }
  }
  o_color = vec4(wsum > 1e-6 ? acc / wsum : iso, 0.0);
  o_zs = vec4(z, s, smax, 0.0);
  o_don = vec4(rho, 0.0, 0.0, 0.0);
}
)";
constexpr const char* kLevelFragment = R"(
layout(location = 0) out vec4 o_color;
layout(location = 1) out vec4 o_zs;
layout(location = 2) out vec4 o_don;
void main() { level_texel(ivec2(gl_FragCoord.xy) - u_dst_origin, o_color, o_zs, o_don); }
)";
constexpr const char* kLevelCompute = R"(
layout(rgba32f, binding = 0) writeonly uniform image2DRect u_out_color;
layout(rgba32f, binding = 1) writeonly uniform image2DRect u_out_zs;
layout(r32f, binding = 2) writeonly uniform image2DRect u_out_don;
void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= u_dst.x || p.y >= u_dst.y) return;
  vec4 c, zs, don;
  level_texel(p, c, zs, don);
  imageStore(u_out_color, u_dst_origin + p, c);
  imageStore(u_out_zs, u_dst_origin + p, zs);
  imageStore(u_out_don, u_dst_origin + p, don);
}
)";

// Steps 4-5 per output pixel. A level is read through its region of the atlases: bilinear by the
// texture unit, the coordinate clamped to the region's outer texel centres (GL_CLAMP_TO_EDGE within
// the level; the texel beyond a clamped edge gets weight 0 and is a zero of the gap).
constexpr const char* kFinalPass = R"(
uniform sampler2D u_input;  // the input colour, for the pixels in focus
uniform sampler2DRect u_color_even, u_color_odd, u_zs_even, u_zs_odd, u_don_even, u_don_odd;
uniform ivec2 u_origin[16], u_lsize[16];
uniform int u_top, u_max_level;
uniform float u_ks, u_diag;  // u_diag: 1/sqrt 2 (circular, Fig. 4.4b) or 1
uniform bool u_smooth, u_geometric;
// The 3x3 neighbourhood of eq. 4.8 and its binomial weights (lee_mipmap_detail.h's Neighbourhood); y is
// negated so the samples are summed in the CPU's order (its rows run top-down).
const float kW[9] = float[9](0.25, 0.125, 0.125, 0.125, 0.125, 0.0625, 0.0625, 0.0625, 0.0625);
vec2 offset(int k) {
  const vec2 kO[9] = vec2[9](vec2(0, 0), vec2(1, 0), vec2(-1, 0), vec2(0, 1), vec2(0, -1), vec2(1, 1),
                             vec2(-1, 1), vec2(1, -1), vec2(-1, -1));
  vec2 o = kO[k];
  if (k >= 5) o *= u_diag;
  return vec2(o.x, -o.y);
}
// Level l at uv (+ an offset in its own texels) in atlas coordinates.
vec2 at(int l, vec2 uv, vec2 texels) {
  vec2 n = vec2(u_lsize[l]);
  return vec2(u_origin[l]) + clamp(uv * n + texels, vec2(0.5), n - 0.5);
}
vec3 colour(int l, vec2 uv, vec2 texels) {
  vec2 c = at(l, uv, texels);
  return (l & 1) == 0 ? texture(u_color_even, c).rgb : texture(u_color_odd, c).rgb;
}
float dob(int l, vec2 uv) {
  vec2 c = at(l, uv, vec2(0.0));
  return (l & 1) == 0 ? texture(u_zs_even, c).y : texture(u_zs_odd, c).y;
}
vec3 blend(vec3 a, vec3 b, float beta) {
  return u_geometric ? a * exp2(beta * log2(b / a))  // a^(1-beta) b^beta: Lee 2009, eq. 4.8
                     : a + beta * (b - a);
}
// A pixel in focus in a blurred image: the input, non-finite and negative as 0.
vec4 copied(ivec2 p) {
  vec3 c = texelFetch(u_input, p, 0).rgb;
  return vec4(clean(c.r), clean(c.g), clean(c.b), 1.0);
}
// A pinhole, or an image with nothing out of focus: the input bit for bit, non-finite as 0 (as the
// CPU's copy_input).
float finite(float v) { return (isnan(v) || isinf(v)) ? 0.0 : v; }
vec4 unchanged(ivec2 p) {
  vec3 c = texelFetch(u_input, p, 0).rgb;
  return vec4(finite(c.r), finite(c.g), finite(c.b), 1.0);
}
// The output's texel p.
vec4 final_texel(ivec2 p) {
  if (u_top < 1) return unchanged(p);
  vec2 uv = (vec2(p) + 0.5) / vec2(u_lsize[0]);
  // M as top_mipmap_level chooses it, from the image's largest DoB (the max pyramid's top texel).
  float smax = ((u_top & 1) == 0 ? texelFetch(u_zs_even, u_origin[u_top]) : texelFetch(u_zs_odd, u_origin[u_top])).z;
  if (!(smax > 0.0)) return unchanged(p);
  int M = max(1, int(floor(level_of(smax, u_ks))));
  if (u_max_level > 0) M = min(M, u_max_level);
  M = min(M, u_top);
  float sigma = texelFetch(u_zs_even, p).y;
  if (u_smooth) {
    // Step 4: rho(M) magnified with the circular filter in level M - 1's texels, n by eq. 4.11, and
    // the DoB read at the continuous level n.
    vec2 scale = vec2(u_lsize[M]) / vec2(u_lsize[M - 1]);
    float rho = 0.0;
    for (int k = 0; k < 9; ++k) {
      vec2 c = at(M, uv, offset(k) * scale);
      rho += kW[k] * ((M & 1) == 0 ? texture(u_don_even, c).r : texture(u_don_odd, c).r);
    }
    float n = min(level_of(rho, u_ks), float(M));  // Lee 2009, eq. 4.11
    if (n > 0.0) {
      int n0 = min(int(n), M);
      float fn = n - float(n0);
      float sa = dob(n0, uv);
      sigma = (n0 + 1 <= M && fn > 0.0) ? sa + fn * (dob(n0 + 1, uv) - sa) : sa;
    }
  }
  float m = min(level_of(sigma, u_ks), float(M + 1));  // Lee 2009, eq. 4.6
  if (!(m > 0.0)) return copied(p);
  int l = int(m);
  float beta = m - float(l);
  if (l > M) { l = M; beta = 1.0; }
  vec3 res = vec3(0.0), hi = vec3(0.0);
  if (l == 0) {
    // No level -1: the pixel blended with its level-0 circular 3x3 (eq. 4.8's value at m = 1).
    vec3 self = texelFetch(u_color_even, p).rgb, filtered = vec3(0.0);
    for (int k = 0; k < 9; ++k) filtered += kW[k] * colour(0, uv, offset(k));
    res = blend(self, filtered, beta);
    hi = max(self, filtered);
  } else {
    // Step 5: eq. 4.8 over the neighbourhood, I(l - 1) and I(l) each read at offsets of its own texels.
    for (int k = 0; k < 9; ++k) {
      vec3 a = colour(l - 1, uv, offset(k)), b = colour(l, uv, offset(k));
      res += kW[k] * blend(a, b, beta);
      hi = max(hi, max(a, b));
    }
  }
  return vec4(clamp(res, vec3(0.0), hi), 1.0);
}
)";
constexpr const char* kFinalFragment = R"(
out vec4 o_color;
void main() { o_color = final_texel(ivec2(gl_FragCoord.xy)); }
)";
constexpr const char* kFinalCompute = R"(
layout(rgba32f, binding = 0) writeonly uniform image2D u_out;
void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= u_lsize[0].x || p.y >= u_lsize[0].y) return;
  imageStore(u_out, p, final_texel(p));
}
)";

void check(const char* where) { gl::check_error("GlLeeMipmap", where); }

unsigned link(const char* body, const char* main, const char* what) {
  const std::string source = std::string(gl::kFragmentVersion) + kCommon + body + main;
  return gl::link_program(gl::kFullscreenVertex, source.c_str(), what);
}

unsigned link_compute(const char* body, const char* main, const char* what) {
  const std::string source = std::string(gl::kComputeVersion8x8) + kCommon + body + main;
  return gl::link_compute_program(source.c_str(), what);
}

void dispatch(glm::ivec2 size) {
  glDispatchCompute(static_cast<GLuint>((size.x + 7) / 8), static_cast<GLuint>((size.y + 7) / 8), 1);
  glMemoryBarrier(gl::kComputeWrittenBarrier);
}

int mip_size(std::uint32_t n, int level) { return std::max(1, static_cast<int>(n >> level)); }

void bind(int unit, GLenum target, unsigned texture, unsigned program, const char* name) {
  gl::bind_sampler(unit, texture, program, name, target);
}

void delete_texture(unsigned& t) {
  if (t != 0) glDeleteTextures(1, &t);
  t = 0;
}

}  // namespace

GlLeeMipmap::GlLeeMipmap(bool compute) {
  base_program_[0] = link(kBasePass, kBaseFragment, "GlLeeMipmap base pass");
  level_program_[0] = link(kLevelPass, kLevelFragment, "GlLeeMipmap level pass");
  final_program_[0] = link(kFinalPass, kFinalFragment, "GlLeeMipmap final pass");
  if (compute) {
    base_program_[1] = link_compute(kBasePass, kBaseCompute, "GlLeeMipmap base pass (compute)");
    level_program_[1] = link_compute(kLevelPass, kLevelCompute, "GlLeeMipmap level pass (compute)");
    final_program_[1] = link_compute(kFinalPass, kFinalCompute, "GlLeeMipmap final pass (compute)");
  }
  glGenVertexArrays(1, &vao_);
  glGenFramebuffers(1, &fbo_);
  glGenQueries(2, queries_);
  check("GlLeeMipmap()");
}

GlLeeMipmap::~GlLeeMipmap() {
  for (Atlas& a : atlas_)
    for (unsigned* t : {&a.color, &a.zs, &a.don}) delete_texture(*t);
  for (unsigned* t : {&output_, &upload_color_, &upload_depth_}) delete_texture(*t);
  glDeleteQueries(2, queries_);
  if (fbo_ != 0) glDeleteFramebuffers(1, &fbo_);
  if (vao_ != 0) glDeleteVertexArrays(1, &vao_);
  for (int i = 0; i < 2; ++i)
    for (unsigned p : {base_program_[i], level_program_[i], final_program_[i]})
      if (p != 0) glDeleteProgram(p);
}

// Levels 0..top (every level of a GL mipmap, up to 1 texel along the longer side: the CPU's
// top_mipmap_level caps M there), the even ones stacked in one atlas, the odd ones in the other, a
// row of zeros between them.
void GlLeeMipmap::ensure_targets(std::uint32_t width, std::uint32_t height) {
  if (width == width_ && height == height_ && output_ != 0) return;
  for (Atlas& a : atlas_)
    for (unsigned* t : {&a.color, &a.zs, &a.don}) delete_texture(*t);
  delete_texture(output_);
  top_ = static_cast<int>(std::floor(std::log2(static_cast<double>(std::max(width, height)))));
  if (top_ >= kMaxLevels) throw std::invalid_argument("GlLeeMipmap: an image side of " + std::to_string(std::max(width, height)) + " px");
  int rows[2] = {0, 0};
  for (int l = 0; l <= top_; ++l) {
    origin_[l] = {0, rows[l & 1]};
    size_[l] = {mip_size(width, l), mip_size(height, l)};
    rows[l & 1] += size_[l].y + 1;
  }
  glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
  for (int parity = 0; parity < 2; ++parity) {
    Atlas& a = atlas_[parity];
    a.width = mip_size(width, parity);
    a.height = std::max(1, rows[parity]);
    const auto make = [&](GLenum format, GLenum channels) {
      unsigned t = 0;
      glGenTextures(1, &t);
      glBindTexture(GL_TEXTURE_RECTANGLE, t);
      glTexImage2D(GL_TEXTURE_RECTANGLE, 0, static_cast<GLint>(format), a.width, a.height, 0, channels, GL_FLOAT, nullptr);
      glTexParameteri(GL_TEXTURE_RECTANGLE, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
      glTexParameteri(GL_TEXTURE_RECTANGLE, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
      glTexParameteri(GL_TEXTURE_RECTANGLE, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
      glTexParameteri(GL_TEXTURE_RECTANGLE, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
      // Zeros: the gaps between levels are read with weight 0 at a clamped edge, never as NaN.
      glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_RECTANGLE, t, 0);
      const float zero[4] = {0, 0, 0, 0};
      glDrawBuffer(GL_COLOR_ATTACHMENT0);
      glClearBufferfv(GL_COLOR, 0, zero);
      return t;
    };
    a.color = make(GL_RGBA32F, GL_RGBA);
    a.zs = make(GL_RGBA32F, GL_RGBA);
    a.don = make(GL_R32F, GL_RED);
  }
  glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_RECTANGLE, 0, 0);
  glGenTextures(1, &output_);
  glBindTexture(GL_TEXTURE_2D, output_);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, static_cast<GLsizei>(width), static_cast<GLsizei>(height), 0, GL_RGBA,
               GL_FLOAT, nullptr);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  width_ = width;
  height_ = height;
  check("GlLeeMipmap::ensure_targets");
}

// Draws one full-screen triangle over `viewport` of `targets` (draw buffers 0, 1, ...).
void GlLeeMipmap::draw_into(GLenum target, std::initializer_list<unsigned> textures, glm::ivec2 origin, glm::ivec2 size) {
  gl::attach_targets(fbo_, textures, target);
  const GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
  if (status != GL_FRAMEBUFFER_COMPLETE) {
    throw std::runtime_error("GlLeeMipmap: framebuffer incomplete (status " + std::to_string(status) + ")");
  }
  glViewport(origin.x, origin.y, size.x, size.y);
  glDrawArrays(GL_TRIANGLES, 0, 3);
}

void GlLeeMipmap::base_pass(const GlDofInput& in, const dof::CocModel& coc, const dof::LeeMipmapSettings& s) {
  const unsigned p = base_program_[compute_ ? 1 : 0];
  glUseProgram(p);
  bind(0, GL_TEXTURE_2D, in.color, p, "u_color");
  bind(1, GL_TEXTURE_2D, in.depth, p, "u_depth");
  const dof::CocModel::Terms t = coc.terms();
  const auto to_float = [](double v) {
    constexpr double kMax = std::numeric_limits<float>::max();
    return std::isnan(v) ? 0.0f : v > kMax ? std::numeric_limits<float>::infinity() : static_cast<float>(std::max(v, -kMax));
  };
  // sigma = C / 2 (Lee §4.1.3) by default; dob_per_coc = 1/4 matches a uniform disc's variance.
  const double dob = std::isfinite(s.dob_per_coc) && s.dob_per_coc > 0 ? s.dob_per_coc : 0.5;
  glUniform1i(glGetUniformLocation(p, "u_form"), static_cast<GLint>(t.form));
  glUniform1f(glGetUniformLocation(p, "u_k"), to_float(t.k));
  glUniform1f(glGetUniformLocation(p, "u_df"), to_float(t.df));
  glUniform1f(glGetUniformLocation(p, "u_ef_px"), to_float(t.ef_px));
  glUniform1f(glGetUniformLocation(p, "u_cap"), to_float(t.cap));
  glUniform1f(glGetUniformLocation(p, "u_scale"), to_float(dob));
  if (compute_) {
    glUniform2i(glGetUniformLocation(p, "u_size"), size_[0].x, size_[0].y);
    glBindImageTexture(0, atlas_[0].color, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA32F);
    glBindImageTexture(1, atlas_[0].zs, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA32F);
    dispatch(size_[0]);
  } else {
    draw_into(GL_TEXTURE_RECTANGLE, {atlas_[0].color, atlas_[0].zs}, origin_[0], size_[0]);
  }
}

void GlLeeMipmap::level_pass(int level, float zf, const dof::LeeMipmapSettings& s) {
  const unsigned p = level_program_[compute_ ? 1 : 0];
  glUseProgram(p);
  const Atlas& src = atlas_[(level - 1) & 1];
  const Atlas& dst = atlas_[level & 1];
  bind(0, GL_TEXTURE_RECTANGLE, src.color, p, "u_color");
  bind(1, GL_TEXTURE_RECTANGLE, src.zs, p, "u_zs");
  const glm::ivec2 so = origin_[level - 1], ss = size_[level - 1], dor = origin_[level], ds = size_[level];
  glUniform2i(glGetUniformLocation(p, "u_src_origin"), so.x, so.y);
  glUniform2i(glGetUniformLocation(p, "u_src"), ss.x, ss.y);
  glUniform2i(glGetUniformLocation(p, "u_dst_origin"), dor.x, dor.y);
  glUniform2i(glGetUniformLocation(p, "u_dst"), ds.x, ds.y);
  glUniform1i(glGetUniformLocation(p, "u_aniso"), s.anisotropic ? 1 : 0);
  glUniform1f(glGetUniformLocation(p, "u_zf"), zf);
  glUniform1f(glGetUniformLocation(p, "u_delta"), std::isfinite(s.delta) ? static_cast<float>(s.delta) : 0.0f);
  if (compute_) {
    glBindImageTexture(0, dst.color, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA32F);
    glBindImageTexture(1, dst.zs, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA32F);
    glBindImageTexture(2, dst.don, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_R32F);
    dispatch(ds);
  } else {
    draw_into(GL_TEXTURE_RECTANGLE, {dst.color, dst.zs, dst.don}, dor, ds);
  }
}

void GlLeeMipmap::final_pass(const GlDofInput& in, int top, const dof::LeeMipmapSettings& s) {
  const unsigned p = final_program_[compute_ ? 1 : 0];
  glUseProgram(p);
  bind(0, GL_TEXTURE_2D, in.color, p, "u_input");
  bind(1, GL_TEXTURE_RECTANGLE, atlas_[0].color, p, "u_color_even");
  bind(2, GL_TEXTURE_RECTANGLE, atlas_[1].color, p, "u_color_odd");
  bind(3, GL_TEXTURE_RECTANGLE, atlas_[0].zs, p, "u_zs_even");
  bind(4, GL_TEXTURE_RECTANGLE, atlas_[1].zs, p, "u_zs_odd");
  bind(5, GL_TEXTURE_RECTANGLE, atlas_[0].don, p, "u_don_even");
  bind(6, GL_TEXTURE_RECTANGLE, atlas_[1].don, p, "u_don_odd");
  glUniform2iv(glGetUniformLocation(p, "u_origin"), kMaxLevels, &origin_[0].x);
  glUniform2iv(glGetUniformLocation(p, "u_lsize"), kMaxLevels, &size_[0].x);
  const float ks = std::isfinite(s.k_sigma) && s.k_sigma > 0 ? static_cast<float>(s.k_sigma) : 2.0f / 3.0f;
  glUniform1i(glGetUniformLocation(p, "u_top"), top);
  glUniform1i(glGetUniformLocation(p, "u_max_level"), std::max(0, s.max_level));
  glUniform1f(glGetUniformLocation(p, "u_ks"), ks);
  glUniform1f(glGetUniformLocation(p, "u_diag"), s.circular ? 0.70710678f : 1.0f);
  glUniform1i(glGetUniformLocation(p, "u_smooth"), s.smooth_foreground ? 1 : 0);
  glUniform1i(glGetUniformLocation(p, "u_geometric"), s.geometric ? 1 : 0);
  if (compute_) {
    glBindImageTexture(0, output_, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA32F);
    dispatch(size_[0]);
  } else {
    draw_into(GL_TEXTURE_2D, {output_}, {0, 0}, size_[0]);
  }
}

void GlLeeMipmap::run(const GlDofInput& in, const dof::CocModel& coc, const dof::LeeMipmapSettings& s, Pass pass) {
  if (in.width == 0 || in.height == 0) throw std::invalid_argument("GlLeeMipmap::run: an empty image");
  if (pass == Pass::Compute && !has_compute()) {
    throw std::invalid_argument("GlLeeMipmap: the compute passes need OpenGL 4.3 (built without them)");
  }
  compute_ = pass == Pass::Compute;
  ensure_targets(in.width, in.height);
  glDisable(GL_DEPTH_TEST);
  glDisable(GL_SCISSOR_TEST);
  glDisable(GL_BLEND);
  glBindVertexArray(vao_);
  // A pinhole (or no depth) copies the input: the final pass alone, told there are no levels.
  const bool pinhole = coc.pinhole() || in.depth == 0;
  const float zf = std::isfinite(coc.focus_m) ? static_cast<float>(std::max(coc.focus_m, 0.0))
                                              : (coc.focus_m > 0 ? 1e30f : 0.0f);
  if (!pinhole) {
    base_pass(in, coc, s);
    for (int l = 1; l <= top_; ++l) level_pass(l, zf, s);
  }
  final_pass(in, pinhole ? 0 : top_, s);
  if (compute_) {
    for (GLuint unit = 0; unit < 3; ++unit) glBindImageTexture(unit, 0, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA32F);
  }
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  glBindVertexArray(0);
  glUseProgram(0);
  glActiveTexture(GL_TEXTURE0);
  check("GlLeeMipmap::run");
}

void GlLeeMipmap::run_image(const dof::DofInput& in, const dof::LeeMipmapSettings& s, dof::RgbImage& out,
                            double* gpu_ms, Pass pass) {
  const std::uint32_t w = in.width, h = in.height;
  out.assign(in.pixels(), glm::vec3(0.0f));
  if (in.pixels() == 0 || in.color == nullptr) return;
  const unsigned color = gl::upload_top_first(upload_color_, GL_RGB32F, GL_RGB, &in.color[0].x, w, h, 3, staging_);
  const unsigned depth = gl::upload_top_first(upload_depth_, GL_R32F, GL_RED, in.depth, w, h, 1, staging_);
  glQueryCounter(queries_[0], GL_TIMESTAMP);
  run(GlDofInput{color, depth, w, h}, in.coc, s, pass);
  glQueryCounter(queries_[1], GL_TIMESTAMP);
  gl::read_rgb_top_first(fbo_, output_, w, h, out, staging_);
  if (gpu_ms != nullptr) *gpu_ms = gl::elapsed_ms(queries_);
  check("GlLeeMipmap::run_image");
}

}  // namespace fovea::render
