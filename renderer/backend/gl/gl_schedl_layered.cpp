// SPDX-License-Identifier: Apache-2.0
#include "backend/gl/gl_schedl_layered.h"

#include <epoxy/gl.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>

#include "backend/gl/gl_program.h"

namespace fovea::render {

namespace {


// Every pass but the box blur is one GLSL function of its output texel, shade(p), run by a fragment
// shader (kFragmentMain) or a compute shader (kComputeMain, OpenGL 4.3) that writes it as an image.
constexpr const char* kFragmentMain = R"(
out vec4 o;
void main() { o = shade(ivec2(gl_FragCoord.xy)); }
)";
constexpr const char* kComputeMain = R"(
layout(rgba32f, binding = 0) writeonly uniform image2D u_out;
uniform ivec2 u_out_size;
void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= u_out_size.x || p.y >= u_out_size.y) return;
  imageStore(u_out, p, shade(p));
}
)";

constexpr const char* kCommon = R"(
const float kInf = uintBitsToFloat(0x7f800000u);
float finite_or_zero(float v) { return (isnan(v) || isinf(v)) ? 0.0 : v; }
// schedl_layered.cpp's sanitized(): NaN, Inf and negative light read as 0.
vec3 sanitized(vec3 c) { return vec3(max(0.0, finite_or_zero(c.r)), max(0.0, finite_or_zero(c.g)), max(0.0, finite_or_zero(c.b))); }
vec4 over(vec4 a, vec4 b) { return a + (1.0 - a.a) * b; }  // premultiplied A over B
)";

// Each input layer once: its sanitised colour and its depth (NaN or none: +inf; negative: 0), so the
// matting reads one texture per layer (eight layers and the accumulator fit 16 texture units).
constexpr const char* kPack = R"(
uniform sampler2D u_color, u_depth;
uniform bool u_has_depth;
vec4 shade(ivec2 p) {
  float z = u_has_depth ? texelFetch(u_depth, p, 0).r : kInf;
  return vec4(sanitized(texelFetch(u_color, p, 0).rgb), isnan(z) ? kInf : max(z, 0.0));
}
)";

// The packed layers 0..7 (u_inputs of them) by index; a sampler array could not be indexed so in 3.30.
constexpr const char* kLayers = R"(
uniform sampler2D u_l0, u_l1, u_l2, u_l3, u_l4, u_l5, u_l6, u_l7;
uniform int u_inputs;
vec4 layer(int l, ivec2 p) {
  if (l == 0) return texelFetch(u_l0, p, 0);
  if (l == 1) return texelFetch(u_l1, p, 0);
  if (l == 2) return texelFetch(u_l2, p, 0);
  if (l == 3) return texelFetch(u_l3, p, 0);
  if (l == 4) return texelFetch(u_l4, p, 0);
  if (l == 5) return texelFetch(u_l5, p, 0);
  if (l == 6) return texelFetch(u_l6, p, 0);
  return texelFetch(u_l7, p, 0);
}
)";

// Step 1: per pixel (nearest finite depth, farthest finite depth, largest visible channel), then
// halving 2x2 to one texel.
constexpr const char* kReduceFirst = R"(
vec4 shade(ivec2 p) {
  float zmin = kInf, zmax = 0.0;
  for (int l = 0; l < 8; ++l) {
    if (l >= u_inputs) break;
    float z = layer(l, p).a;
    if (!isinf(z)) { zmin = min(zmin, z); zmax = max(zmax, z); }
  }
  vec3 c = layer(0, p).rgb;
  return vec4(zmin, zmax, max(c.r, max(c.g, c.b)), 0.0);
}
)";
constexpr const char* kReduceNext = R"(
uniform sampler2D u_src;
uniform ivec2 u_src_size;
vec4 shade(ivec2 dst) {
  ivec2 p = dst * 2;
  vec4 r = texelFetch(u_src, p, 0);
  for (int k = 1; k < 4; ++k) {
    vec4 q = texelFetch(u_src, min(p + ivec2(k & 1, k >> 1), u_src_size - 1), 0);
    r = vec4(min(r.x, q.x), max(r.y, q.y), max(r.z, q.z), 0.0);
  }
  return r;
}
)";

// Step 2: L_k (eq. 2) with the mattes of eqs. 3-4, then the cascade's over (eqs. 12-13).
constexpr const char* kMatte = R"(
uniform sampler2D u_acc;
uniform int u_mode;                // 0: L_k; 1: acc over L_k (front cascade); 2: L_k over acc (back)
uniform float u_a, u_b, u_c, u_e;  // z_{k-2}, z_{k-1}, z_k, z_{k+1} (+-inf beyond the front and back layers)
uniform bool u_a_finite, u_e_finite;
float w_dot(float d) {  // eq. 3
  if (d >= u_b && d <= u_c) return 1.0;
  if (d > u_a && d < u_b && u_a_finite && u_b > u_a) return (d - u_a) / (u_b - u_a);
  return 0.0;
}
float w_full(float d) {  // eq. 4
  if (d > u_c && d < u_e && u_e_finite && u_e > u_c) return (u_e - d) / (u_e - u_c);
  return w_dot(d);
}
vec4 shade(ivec2 p) {
  vec4 acc = vec4(0.0);
  for (int l = 0; l < 8; ++l) {
    if (l >= u_inputs) break;
    vec4 in_l = layer(l, p);
    float a = l == 0 ? w_full(in_l.a) : w_dot(in_l.a);
    if (a > 0.0) acc = over(acc, vec4(in_l.rgb * a, a));
  }
  vec4 prev = texelFetch(u_acc, p, 0);
  return u_mode == 1 ? over(prev, acc) : u_mode == 2 ? over(acc, prev) : acc;
}
)";

// Step 3: one box of radius u_r along u_dir, edges clamped. Its 2r + 1 texels are read as r bilinear
// samples half-way between neighbours (the texture unit averages each pair, weight 1/2: exact in any
// filter precision; GL_CLAMP_TO_EDGE clamps as the CPU's indices do) and the last one alone.
constexpr const char* kBox = R"(
uniform sampler2D u_src;
uniform ivec2 u_size, u_dir;
uniform int u_r;
out vec4 o;
void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  vec2 centre = vec2(p) + 0.5, size = vec2(u_size), dir = vec2(u_dir);
  vec4 sum = vec4(0.0);
  for (int j = -u_r; j < u_r; j += 2) sum += 2.0 * texture(u_src, (centre + dir * (float(j) + 0.5)) / size);
  sum += texelFetch(u_src, clamp(p + u_r * u_dir, ivec2(0), u_size - 1), 0);
  o = sum * (1.0 / float(2 * u_r + 1));
}
)";

// Step 3 as a compute pass (OpenGL 4.3): the same box, but each invocation slides it along a segment
// of one line (a row, or a column) with a running sum, so a pixel costs two reads and (2r + 1) /
// u_segment for the segment's first window, not 2r + 1: O(1) per pixel for r up to the segment. The
// running sum is compensated (Neumaier), so light that leaves the window leaves no residue in the
// dark beside it (HDR 1e6 against 0.5); a sum that overflowed is summed afresh.
constexpr const char* kBoxCompute = R"(#version 430 core
layout(local_size_x = 64) in;
uniform sampler2D u_src;
layout(rgba32f, binding = 0) writeonly uniform image2D u_dst;
uniform ivec2 u_size, u_dir;
uniform int u_r, u_segment;
ivec2 texel(int i, int line) {
  return u_dir.x == 1 ? ivec2(clamp(i, 0, u_size.x - 1), line) : ivec2(line, clamp(i, 0, u_size.y - 1));
}
void add(inout precise vec4 s, inout precise vec4 c, vec4 v) {
  precise vec4 t = s + v;
  c += mix((v - t) + s, (s - t) + v, greaterThanEqual(abs(s), abs(v)));
  s = t;
}
void window(int x, int line, out precise vec4 s, out precise vec4 c) {
  s = vec4(0.0);
  c = vec4(0.0);
  for (int j = x - u_r; j <= x + u_r; ++j) add(s, c, texelFetch(u_src, texel(j, line), 0));
}
void main() {
  int along = u_dir.x == 1 ? u_size.x : u_size.y, lines = u_dir.x == 1 ? u_size.y : u_size.x;
  int id = int(gl_GlobalInvocationID.x);
  if (id >= lines * ((along + u_segment - 1) / u_segment)) return;
  // Neighbouring invocations take neighbouring lines at one place along them (coherent reads).
  int line = id % lines, x0 = (id / lines) * u_segment, x1 = min(x0 + u_segment, along);
  precise vec4 s, c;
  window(x0, line, s, c);
  float inv = 1.0 / float(2 * u_r + 1);
  for (int x = x0; x < x1; ++x) {
    imageStore(u_dst, texel(x, line), (s + c) * inv);
    if (x + 1 == x1) break;
    add(s, c, texelFetch(u_src, texel(x + u_r + 1, line), 0));
    add(s, c, -texelFetch(u_src, texel(x - u_r, line), 0));
    if (any(isinf(s)) || any(isnan(s)) || any(isinf(c)) || any(isnan(c))) window(x + 1, line, s, c);
  }
}
)";

// Step 4: I' = L^_{kf-1} over (L_kf over L^_{kf+1}) (eq. 13), normalised (§3.3.1).
constexpr const char* kComposite = R"(
uniform sampler2D u_front, u_layer, u_back;
uniform bool u_has_front, u_has_back, u_copy;
uniform float u_max_in;
vec4 shade(ivec2 p) {
  vec3 result = layer(0, p).rgb;  // no coverage (or nothing blurs): the input
  if (!u_copy) {
    vec4 r = texelFetch(u_layer, p, 0);
    if (u_has_back) r = over(r, texelFetch(u_back, p, 0));
    if (u_has_front) r = over(texelFetch(u_front, p, 0), r);
    if (r.a > 1e-6 && !isinf(r.a)) {
      vec3 c = r.rgb / r.a;
      result = clamp(vec3(finite_or_zero(c.r), finite_or_zero(c.g), finite_or_zero(c.b)), 0.0, u_max_in);
    }
  }
  return vec4(result, 1.0);
}
)";

void check(const char* where) { gl::check_error("GlSchedlLayered", where); }

// A fragment pass of kCommon and `parts` (which end in a main of their own, or in shade(): then
// kFragmentMain follows).
unsigned link(std::initializer_list<const char*> parts, const char* what, bool shade = true) {
  std::string source = std::string(gl::kFragmentVersion) + kCommon;
  for (const char* p : parts) source += p;
  if (shade) source += kFragmentMain;
  return gl::link_program(gl::kFullscreenVertex, source.c_str(), what);
}

// The same shade() as a compute pass.
unsigned link_compute(std::initializer_list<const char*> parts, const char* what) {
  std::string source = std::string(gl::kComputeVersion8x8) + kCommon;
  for (const char* p : parts) source += p;
  source += kComputeMain;
  return gl::link_compute_program(source.c_str(), what);
}

unsigned rgba32f(std::uint32_t w, std::uint32_t h) {
  unsigned t = 0;
  glGenTextures(1, &t);
  glBindTexture(GL_TEXTURE_2D, t);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, static_cast<GLsizei>(w), static_cast<GLsizei>(h), 0, GL_RGBA, GL_FLOAT,
               nullptr);
  // Bilinear for the box blur's paired reads (the other passes fetch texels); edges clamped.
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  return t;
}

void bind(int unit, unsigned texture, unsigned program, const char* name) {
  gl::bind_sampler(unit, texture, program, name);
}

void del(unsigned& t) {
  if (t != 0) glDeleteTextures(1, &t);
  t = 0;
}

}  // namespace

GlSchedlLayered::GlSchedlLayered(bool compute) {
  passes_[0] = {link({kPack}, "GlSchedlLayered pack"), link({kLayers, kReduceFirst}, "GlSchedlLayered reduction"),
                link({kReduceNext}, "GlSchedlLayered reduction (halving)"),
                link({kLayers, kMatte}, "GlSchedlLayered matting"), link({kLayers, kComposite}, "GlSchedlLayered composite")};
  box_program_ = link({kBox}, "GlSchedlLayered box blur", false);
  if (compute) {
    box_compute_ = gl::link_compute_program(kBoxCompute, "GlSchedlLayered box blur (compute)");
    passes_[1] = {link_compute({kPack}, "GlSchedlLayered pack (compute)"),
                  link_compute({kLayers, kReduceFirst}, "GlSchedlLayered reduction (compute)"),
                  link_compute({kReduceNext}, "GlSchedlLayered reduction, halving (compute)"),
                  link_compute({kLayers, kMatte}, "GlSchedlLayered matting (compute)"),
                  link_compute({kLayers, kComposite}, "GlSchedlLayered composite (compute)")};
  }
  glGenVertexArrays(1, &vao_);
  glGenFramebuffers(1, &fbo_);
  glGenQueries(2, queries_);
  check("GlSchedlLayered()");
}

GlSchedlLayered::~GlSchedlLayered() {
  release();
  for (unsigned& t : upload_color_) del(t);
  for (unsigned& t : upload_depth_) del(t);
  glDeleteQueries(2, queries_);
  if (fbo_ != 0) glDeleteFramebuffers(1, &fbo_);
  if (vao_ != 0) glDeleteVertexArrays(1, &vao_);
  for (const Passes& ps : passes_)
    for (unsigned p : {ps.pack, ps.reduce_first, ps.reduce_next, ps.matte, ps.composite})
      if (p != 0) glDeleteProgram(p);
  for (unsigned p : {box_program_, box_compute_})
    if (p != 0) glDeleteProgram(p);
}

void GlSchedlLayered::release() {
  for (unsigned* t : {&front_[0], &front_[1], &back_[0], &back_[1], &layer_, &scratch_, &output_}) del(*t);
  for (unsigned& t : packed_) del(t);
  for (unsigned& t : reduction_) del(t);
  reduction_.clear();
  reduction_sizes_.clear();
  width_ = height_ = 0;
}

void GlSchedlLayered::ensure(std::uint32_t width, std::uint32_t height) {
  if (width == width_ && height == height_ && output_ != 0) return;
  release();
  for (unsigned* t : {&front_[0], &front_[1], &back_[0], &back_[1], &layer_, &scratch_, &output_})
    *t = rgba32f(width, height);
  for (unsigned& t : packed_) t = rgba32f(width, height);
  std::uint32_t w = width, h = height;
  reduction_.push_back(rgba32f(w, h));
  reduction_sizes_.emplace_back(w, h);
  while (w > 1 || h > 1) {
    w = (w + 1) / 2;
    h = (h + 1) / 2;
    reduction_.push_back(rgba32f(w, h));
    reduction_sizes_.emplace_back(w, h);
  }
  width_ = width;
  height_ = height;
  check("GlSchedlLayered::ensure");
}

// `program`'s pass over w x h texels of `texture`: a draw, or a dispatch writing it as an image.
void GlSchedlLayered::draw_into(unsigned program, unsigned texture, std::uint32_t w, std::uint32_t h) {
  if (compute_ && program != box_program_) {
    glUniform2i(glGetUniformLocation(program, "u_out_size"), static_cast<GLint>(w), static_cast<GLint>(h));
    glBindImageTexture(0, texture, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA32F);
    glDispatchCompute((w + 7) / 8, (h + 7) / 8, 1);
    glMemoryBarrier(gl::kComputeWrittenBarrier);
    return;
  }
  glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
  glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, texture, 0);
  glDrawBuffer(GL_COLOR_ATTACHMENT0);
  glViewport(0, 0, static_cast<GLsizei>(w), static_cast<GLsizei>(h));
  glDrawArrays(GL_TRIANGLES, 0, 3);
}

void GlSchedlLayered::bind_layers(unsigned program) const {
  const char* names[kMaxInputLayers] = {"u_l0", "u_l1", "u_l2", "u_l3", "u_l4", "u_l5", "u_l6", "u_l7"};
  for (int l = 0; l < kMaxInputLayers; ++l) bind(l, packed_[static_cast<std::size_t>(l)], program, names[l]);
  glUniform1i(glGetUniformLocation(program, "u_inputs"), inputs_);
}

void GlSchedlLayered::pack(const GlDofInput& visible, const std::vector<GlDofInput>& peeled) {
  const unsigned p = passes().pack;
  glUseProgram(p);
  for (int l = 0; l < inputs_; ++l) {
    const GlDofInput& in = l == 0 ? visible : peeled[static_cast<std::size_t>(l - 1)];
    bind(0, in.color, p, "u_color");
    bind(1, in.depth, p, "u_depth");
    glUniform1i(glGetUniformLocation(p, "u_has_depth"), in.depth != 0 ? 1 : 0);
    draw_into(p, packed_[static_cast<std::size_t>(l)], width_, height_);
  }
}

GlSchedlLayered::Range GlSchedlLayered::reduce() {
  const unsigned first = passes().reduce_first, next = passes().reduce_next;
  glUseProgram(first);
  bind_layers(first);
  draw_into(first, reduction_[0], width_, height_);
  glUseProgram(next);
  for (std::size_t i = 1; i < reduction_.size(); ++i) {
    bind(0, reduction_[i - 1], next, "u_src");
    glUniform2i(glGetUniformLocation(next, "u_src_size"), static_cast<GLint>(reduction_sizes_[i - 1].first),
                static_cast<GLint>(reduction_sizes_[i - 1].second));
    draw_into(next, reduction_[i], reduction_sizes_[i].first, reduction_sizes_[i].second);
  }
  float texel[4] = {0, 0, 0, 0};
  glBindFramebuffer(GL_FRAMEBUFFER, fbo_);  // the last level (a compute pass attached nothing)
  glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, reduction_.back(), 0);
  glReadBuffer(GL_COLOR_ATTACHMENT0);
  glReadPixels(0, 0, 1, 1, GL_RGBA, GL_FLOAT, texel);
  return {texel[0], texel[1], texel[2]};
}

void GlSchedlLayered::matte(const dof::SchedlAnchors& an, int k, int mode, unsigned acc, unsigned to) {
  const unsigned p = passes().matte;
  glUseProgram(p);
  bind_layers(p);
  bind(kMaxInputLayers, acc, p, "u_acc");
  glUniform1i(glGetUniformLocation(p, "u_mode"), mode);
  const auto f = [](double v) { return static_cast<float>(v); };  // +-inf stay infinite
  glUniform1f(glGetUniformLocation(p, "u_a"), f(an.anchor(k - 2)));
  glUniform1f(glGetUniformLocation(p, "u_b"), f(an.anchor(k - 1)));
  glUniform1f(glGetUniformLocation(p, "u_c"), f(an.anchor(k)));
  glUniform1f(glGetUniformLocation(p, "u_e"), f(an.anchor(k + 1)));
  glUniform1i(glGetUniformLocation(p, "u_a_finite"), std::isfinite(an.anchor(k - 2)) ? 1 : 0);
  glUniform1i(glGetUniformLocation(p, "u_e_finite"), std::isfinite(an.anchor(k + 1)) ? 1 : 0);
  draw_into(p, to, width_, height_);
}

void GlSchedlLayered::gaussian(unsigned image, double sigma) {
  if (!(sigma > 0.3)) return;
  if (compute_) {
    gaussian_compute(image, sigma);
    return;
  }
  const unsigned p = box_program_;
  glUseProgram(p);
  glUniform2i(glGetUniformLocation(p, "u_size"), static_cast<GLint>(width_), static_cast<GLint>(height_));
  for (const int r : dof::schedl_box_radii(sigma)) {
    if (r <= 0) continue;
    glUniform1i(glGetUniformLocation(p, "u_r"), r);
    bind(0, image, p, "u_src");
    glUniform2i(glGetUniformLocation(p, "u_dir"), 1, 0);
    draw_into(p, scratch_, width_, height_);
    bind(0, scratch_, p, "u_src");
    glUniform2i(glGetUniformLocation(p, "u_dir"), 0, 1);
    draw_into(p, image, width_, height_);
  }
}

// The boxes of gaussian() by running sums (kBoxCompute): along rows into scratch_, along columns back.
void GlSchedlLayered::gaussian_compute(unsigned image, double sigma) {
  const unsigned p = box_compute_;
  glUseProgram(p);
  glUniform2i(glGetUniformLocation(p, "u_size"), static_cast<GLint>(width_), static_cast<GLint>(height_));
  const auto pass = [&](unsigned from, unsigned to, int r, glm::ivec2 dir) {
    // A segment of at least r pixels keeps the first window's 2r + 1 reads at most ~2 a pixel; at
    // most 128, so a 1080-pixel line still spreads over 9 invocations.
    const int segment = std::clamp(r, 16, 128);
    const auto along = static_cast<int>(dir.x == 1 ? width_ : height_), lines = static_cast<int>(dir.x == 1 ? height_ : width_);
    const auto invocations = static_cast<std::uint32_t>(lines * ((along + segment - 1) / segment));
    glUniform1i(glGetUniformLocation(p, "u_r"), r);
    glUniform1i(glGetUniformLocation(p, "u_segment"), segment);
    glUniform2i(glGetUniformLocation(p, "u_dir"), dir.x, dir.y);
    bind(0, from, p, "u_src");
    glBindImageTexture(0, to, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA32F);
    glDispatchCompute((invocations + 63) / 64, 1, 1);
    glMemoryBarrier(gl::kComputeWrittenBarrier);
  };
  for (const int r : dof::schedl_box_radii(sigma)) {
    if (r <= 0) continue;
    pass(image, scratch_, r, {1, 0});
    pass(scratch_, image, r, {0, 1});
  }
  glBindImageTexture(0, 0, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA32F);
}

void GlSchedlLayered::composite(unsigned front, unsigned back, bool copy, float max_in) {
  const unsigned p = passes().composite;
  glUseProgram(p);
  bind_layers(p);
  bind(kMaxInputLayers, front != 0 ? front : layer_, p, "u_front");
  bind(kMaxInputLayers + 1, layer_, p, "u_layer");
  bind(kMaxInputLayers + 2, back != 0 ? back : layer_, p, "u_back");
  glUniform1i(glGetUniformLocation(p, "u_has_front"), front != 0 ? 1 : 0);
  glUniform1i(glGetUniformLocation(p, "u_has_back"), back != 0 ? 1 : 0);
  glUniform1i(glGetUniformLocation(p, "u_copy"), copy ? 1 : 0);
  glUniform1f(glGetUniformLocation(p, "u_max_in"), max_in);
  draw_into(p, output_, width_, height_);
}

dof::SchedlStats GlSchedlLayered::run(const GlDofInput& visible, const std::vector<GlDofInput>& peeled,
                                      const dof::CocModel& coc, const dof::SchedlSettings& s, Pass pass) {
  const auto start = std::chrono::steady_clock::now();
  if (visible.width == 0 || visible.height == 0) throw std::invalid_argument("GlSchedlLayered::run: an empty image");
  if (pass == Pass::Compute && !has_compute()) {
    throw std::invalid_argument("GlSchedlLayered: the compute box blur needs OpenGL 4.3 (built without it)");
  }
  compute_ = pass == Pass::Compute;
  ensure(visible.width, visible.height);
  // The peeled layers that carry colour and depth, as the CPU's input_layers keeps them.
  std::vector<GlDofInput> layers;
  for (const GlDofInput& l : peeled)
    if (l.color != 0 && l.depth != 0) layers.push_back(l);
  if (layers.size() + 1 > static_cast<std::size_t>(kMaxInputLayers)) {
    throw std::invalid_argument("GlSchedlLayered::run: " + std::to_string(layers.size() + 1) + " input layers, at most " +
                                std::to_string(kMaxInputLayers));
  }
  inputs_ = static_cast<int>(layers.size()) + 1;
  glDisable(GL_DEPTH_TEST);
  glDisable(GL_SCISSOR_TEST);
  glDisable(GL_BLEND);
  glBindVertexArray(vao_);
  pack(visible, layers);
  const Range range = reduce();
  const std::optional<dof::SchedlAnchors> chosen =
      dof::schedl_anchors(coc, static_cast<double>(range.zmin), static_cast<double>(range.zmax), s.max_layers);
  dof::SchedlStats stats;
  if (!chosen) {
    composite(0, 0, true, range.max_in);
    stats.layers = 1;
  } else {
    const dof::SchedlAnchors& an = *chosen;
    const int kf = an.kf, K = an.K;
    unsigned front = 0, back = 0;
    if (kf > 0) {  // eqs. 12-13 in front of the focus layer: L^_k = (L^_{k-1} over L_k) * H^_k
      int cur = 0;
      matte(an, 0, 0, front_[1], front_[0]);
      gaussian(front_[0], kf);
      for (int k = 1; k < kf; ++k) {
        matte(an, k, 1, front_[cur], front_[1 - cur]);
        cur = 1 - cur;
        gaussian(front_[cur], kf - k);
      }
      front = front_[cur];
    }
    if (kf < K - 1) {  // behind it: L^_k = (L_k over L^_{k+1}) * H^_k
      int cur = 0;
      matte(an, K - 1, 0, back_[1], back_[0]);
      gaussian(back_[0], K - 1 - kf);
      for (int k = K - 2; k > kf; --k) {
        matte(an, k, 2, back_[cur], back_[1 - cur]);
        cur = 1 - cur;
        gaussian(back_[cur], k - kf);
      }
      back = back_[cur];
    }
    matte(an, kf, 0, scratch_, layer_);  // (mode 0 reads no accumulator; scratch_ is not written here)
    composite(front, back, false, range.max_in);
    stats.layers = K;
    stats.focus_layer = kf;
  }
  if (compute_) glBindImageTexture(0, 0, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA32F);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  glBindVertexArray(0);
  glUseProgram(0);
  glActiveTexture(GL_TEXTURE0);
  check("GlSchedlLayered::run");
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return stats;
}

dof::SchedlStats GlSchedlLayered::run_image(const dof::DofInput& in, const std::vector<dof::PeeledLayer>& peeled,
                                            const dof::SchedlSettings& s, dof::RgbImage& out, double* gpu_ms, Pass pass) {
  const std::uint32_t w = in.width, h = in.height;
  out.assign(in.pixels(), glm::vec3(0.0f));
  if (in.pixels() == 0 || in.color == nullptr) return {};
  const std::size_t n = 1 + peeled.size();
  upload_color_.resize(n, 0);
  upload_depth_.resize(n, 0);
  const auto as_gl = [&](std::size_t l, const glm::vec3* color, const float* depth) {
    return GlDofInput{gl::upload_top_first(upload_color_[l], GL_RGB32F, GL_RGB, color != nullptr ? &color[0].x : nullptr,
                                           w, h, 3, staging_),
                      gl::upload_top_first(upload_depth_[l], GL_R32F, GL_RED, depth, w, h, 1, staging_), w, h};
  };
  const GlDofInput visible = as_gl(0, in.color, in.depth);
  std::vector<GlDofInput> layers;
  for (std::size_t l = 0; l < peeled.size(); ++l) layers.push_back(as_gl(l + 1, peeled[l].color, peeled[l].depth));
  glQueryCounter(queries_[0], GL_TIMESTAMP);
  const dof::SchedlStats stats = run(visible, layers, in.coc, s, pass);
  glQueryCounter(queries_[1], GL_TIMESTAMP);
  gl::read_rgb_top_first(fbo_, output_, w, h, out, staging_);
  if (gpu_ms != nullptr) *gpu_ms = gl::elapsed_ms(queries_);
  check("GlSchedlLayered::run_image");
  return stats;
}

}  // namespace fovea::render
