// SPDX-License-Identifier: Apache-2.0
#include "backend/gl/gl_attention.h"

#include <epoxy/gl.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <initializer_list>
#include <numeric>
#include <stdexcept>
#include <string>

#include "backend/gl/gl_attention_shaders.h"
#include "backend/gl/gl_program.h"

namespace fovea::render {

namespace {

using attention::AttentionSettings;
using attention::FeatureGroups;
using attention::ObjectPixels;

// Per-object tables: slot s at texel (s % 1024, s / 1024); the sums' 16 bands of map rows at
// ((s % 64) 16 + band, s / 64); the depth histograms' 256 bins at ((s % 4) 256 + bin, s / 4).
constexpr int kSlotRow = 1024, kBands = 16, kBins = 256;
constexpr int kReduceBlock = 8;

using namespace gl_attention_glsl;

// A pass's outputs: the variable shade() assigns, its GLSL type and its target's image format.
struct Output {
  const char* name;
  const char* type;    // float, vec2, vec4, uint, uvec4
  const char* format;  // the target texture's, for the compute pass's image
};

// Each full-screen pass is one GLSL function, shade(p), of its output texel p, which assigns the
// pass's outputs; a fragment shader (OpenGL 3.3, a render target per output) or a compute shader
// (OpenGL 4.3, an image per output) runs it, so both implementations compute the same values.
std::string pass_source(const char* body, std::initializer_list<Output> outputs, bool compute) {
  std::string src = compute ? gl::kComputeVersion8x8 : gl::kFragmentVersion;
  src += kSlotLayout;
  int i = 0;
  for (const Output& o : outputs) {
    const std::string index = std::to_string(i++);
    if (compute) {
      const bool integer = o.type[0] == 'u';
      src += std::string(o.type) + " " + o.name + ";\nlayout(" + o.format + ", binding = " + index +
             ") writeonly uniform " + (integer ? "uimage2D" : "image2D") + " u_out" + index + ";\n";
    } else {
      src += "layout(location = " + index + ") out " + o.type + " " + o.name + ";\n";
    }
  }
  src += body;
  if (!compute) return src + "void main() { shade(ivec2(gl_FragCoord.xy)); }\n";
  src += "uniform ivec2 u_extent;\nvoid main() {\n  ivec2 p = ivec2(gl_GlobalInvocationID.xy);\n"
         "  if (p.x >= u_extent.x || p.y >= u_extent.y) return;\n  shade(p);\n";
  i = 0;
  for (const Output& o : outputs) {
    const std::string t = o.type, name = o.name;
    const std::string value = t == "vec4" || t == "uvec4" ? name
                              : t == "vec2"               ? "vec4(" + name + ", 0.0, 0.0)"
                              : t == "float"              ? "vec4(" + name + ", 0.0, 0.0, 0.0)"
                                                          : "uvec4(" + name + ", 0u, 0u, 0u)";
    src += "  imageStore(u_out" + std::to_string(i++) + ", p, " + value + ");\n";
  }
  return src + "}\n";
}

// The pass's fragment program ([0]) and, with `compute`, its compute program ([1]).
void link_pass(unsigned (&programs)[2], const char* body, std::initializer_list<Output> outputs, bool compute,
               const char* what) {
  programs[0] = gl::link_program(gl::kFullscreenVertex, pass_source(body, outputs, false).c_str(), what);
  if (compute) {
    const std::string name = std::string(what) + " (compute)";
    programs[1] = gl::link_compute_program(pass_source(body, outputs, true).c_str(), name.c_str());
  }
}

using gl::delete_texture;

// The map's and the tables' sizes are ints here.
unsigned texture(GLenum internal, GLenum format, GLenum type, int w, int h) {
  return gl::make_texture(internal, format, type, static_cast<std::uint32_t>(w), static_cast<std::uint32_t>(h));
}

int rows_for(std::size_t count, int per_row) {
  return std::max(1, static_cast<int>((count + static_cast<std::size_t>(per_row) - 1) / static_cast<std::size_t>(per_row)));
}

void set_int(unsigned p, const char* name, int v) { glUniform1i(glGetUniformLocation(p, name), v); }
void set_float(unsigned p, const char* name, double v) { glUniform1f(glGetUniformLocation(p, name), static_cast<float>(v)); }
void set_ivec2(unsigned p, const char* name, int x, int y) { glUniform2i(glGetUniformLocation(p, name), x, y); }

// From the radix select's key back to the float.
float from_sortable(std::uint32_t key) {
  const std::uint32_t bits = (key & 0x80000000u) != 0 ? (key & 0x7fffffffu) : ~key;
  float v = 0;
  std::memcpy(&v, &bits, sizeof v);
  return v;
}

}  // namespace

GlAttention::GlAttention(bool compute) {
  const Output rgba{"", "vec4", "rgba32f"};
  const std::string resample = std::string(kResample) + kResampleShade;
  link_pass(resample_program_, resample.c_str(),
            {{"o_image", "vec4", "rgba32f"}, {"o_slot", "uint", "r32ui"}, {"o_depth", "float", "r32f"}}, false,
            "GlAttention resample");
  if (compute) {
    const std::string source = std::string(gl::kComputeVersion8x8) + kSlotLayout +
                               "vec4 o_image;\nuint o_slot;\nfloat o_depth;\n" + kResample + kResampleCompute;
    resample_program_[1] = gl::link_compute_program(source.c_str(), "GlAttention resample (compute)");
  }
  const std::string scatter_vertex = std::string("#version 330 core\n") + kSlotLayout + kScatterVertex;
  scatter_program_ = gl::link_program(scatter_vertex.c_str(), kScatterFragment, "GlAttention scatter");
  link_pass(paint_program_, kPaint, {{"o", "vec2", "rg32f"}}, compute, "GlAttention paint");
  link_pass(down_program_, kDown, {{"o_image", "vec4", "rgba32f"}, {"o_object", "vec2", "rg32f"}}, compute,
            "GlAttention pyramid");
  link_pass(contrast_program_, kContrast, {{"o_c0", rgba.type, rgba.format}, {"o_c1", rgba.type, rgba.format}}, compute,
            "GlAttention contrast");
  link_pass(reduce_program_, kReduce, {{"o0", rgba.type, rgba.format}, {"o1", rgba.type, rgba.format}}, compute,
            "GlAttention reduce");
  link_pass(weigh_program_, kWeigh, {{"o", rgba.type, rgba.format}}, compute, "GlAttention weigh");
  link_pass(normalise_program_, kNormalise, {{"o", "float", "r32f"}}, compute, "GlAttention normalise");
  link_pass(select_init_program_, kSelectInit, {{"o", "uvec4", "rg32ui"}}, compute, "GlAttention select init");
  link_pass(select_program_, kSelect, {{"o", "uvec4", "rg32ui"}}, compute, "GlAttention select");
  glGenVertexArrays(1, &vao_);
  glGenFramebuffers(1, &fbo_);
  glGenQueries(2, queries_);
  gl::check_error("GlAttention", "construction");
}

GlAttention::~GlAttention() {
  glDeleteProgram(scatter_program_);
  for (const unsigned* pair : {resample_program_, paint_program_, down_program_, contrast_program_, reduce_program_,
                               weigh_program_, normalise_program_, select_init_program_, select_program_})
    for (int k = 0; k < 2; ++k) glDeleteProgram(pair[k]);
  ensure_map(0);
  object_capacity_ = 0;
  for (unsigned* t : {&object_ids_, &object_motion_, &counts_, &sums_, &histogram_, &select_[0], &select_[1],
                      &upload_color_, &upload_depth_, &upload_ids_})
    delete_texture(*t);
  glDeleteVertexArrays(1, &vao_);
  glDeleteFramebuffers(1, &fbo_);
  glDeleteQueries(2, queries_);
}

void GlAttention::ensure_map(int n) {
  if (n == n_) return;
  for (Level& l : levels_) {
    delete_texture(l.image);
    delete_texture(l.object);
  }
  for (unsigned* t : {&slots_, &map_depth_, &contrast_[0], &contrast_[1], &weighted_, &saliency_}) delete_texture(*t);
  for (auto& chain : reduce_chain_) {
    for (unsigned& t : chain) delete_texture(t);
    chain.clear();
  }
  reduce_w_.clear();
  reduce_h_.clear();
  n_ = n;
  if (n == 0) return;
  int w = n, h = n;
  for (int l = 0; l < kLevels; ++l) {
    if (l > 0) {
      w = std::max(1, (w + 1) / 2);
      h = std::max(1, (h + 1) / 2);
    }
    levels_[l] = Level{texture(GL_RGBA32F, GL_RGBA, GL_FLOAT, w, h), texture(GL_RG32F, GL_RG, GL_FLOAT, w, h), w, h};
  }
  slots_ = texture(GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, n, n);
  map_depth_ = texture(GL_R32F, GL_RED, GL_FLOAT, n, n);
  for (unsigned& c : contrast_) c = texture(GL_RGBA32F, GL_RGBA, GL_FLOAT, n, n);
  weighted_ = texture(GL_RGBA32F, GL_RGBA, GL_FLOAT, n, n);
  saliency_ = texture(GL_R32F, GL_RED, GL_FLOAT, n, n);
  for (int rw = n, rh = n; rw > 1 || rh > 1;) {
    rw = (rw + kReduceBlock - 1) / kReduceBlock;
    rh = (rh + kReduceBlock - 1) / kReduceBlock;
    for (auto& chain : reduce_chain_) chain.push_back(texture(GL_RGBA32F, GL_RGBA, GL_FLOAT, rw, rh));
    reduce_w_.push_back(rw);
    reduce_h_.push_back(rh);
  }
}

void GlAttention::ensure_objects(std::size_t count) {
  if (count <= object_capacity_ && object_capacity_ != 0) return;
  GLint max_size = 0;
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_size);
  const std::size_t capacity = std::max<std::size_t>(count, 64);
  if (rows_for(capacity, kSlotRow / kBins) > max_size) {
    throw std::runtime_error("GlAttention: " + std::to_string(count) + " scene objects exceed what the per-object " +
                             "tables hold on this device (" + std::to_string(std::size_t{4} * static_cast<std::size_t>(max_size)) + ")");
  }
  for (unsigned* t : {&object_ids_, &object_motion_, &counts_, &sums_, &histogram_, &select_[0], &select_[1]}) delete_texture(*t);
  const int slot_rows = rows_for(capacity, kSlotRow);
  object_ids_ = texture(GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, kSlotRow, slot_rows);
  object_motion_ = texture(GL_R32F, GL_RED, GL_FLOAT, kSlotRow, slot_rows);
  counts_ = texture(GL_R32F, GL_RED, GL_FLOAT, kSlotRow, slot_rows);
  for (unsigned& s : select_) s = texture(GL_RG32UI, GL_RG_INTEGER, GL_UNSIGNED_INT, kSlotRow, slot_rows);
  sums_ = texture(GL_RGBA32F, GL_RGBA, GL_FLOAT, kSlotRow, rows_for(capacity, kSlotRow / kBands));
  histogram_ = texture(GL_R32F, GL_RED, GL_FLOAT, kSlotRow, rows_for(capacity, kSlotRow / kBins));
  object_capacity_ = capacity;
}

// The scene's object ids in ascending order (the first of a repeated id counts, as the CPU's slot
// table), each with its B_m, up into the slot tables.
void GlAttention::upload_objects(const GlAttentionObjects& objects) {
  if (objects.motion.size() != objects.ids.size()) {
    throw std::invalid_argument("GlAttention: " + std::to_string(objects.motion.size()) + " motion values for " +
                                std::to_string(objects.ids.size()) + " object ids");
  }
  std::vector<std::size_t> order(objects.ids.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return objects.ids[a] < objects.ids[b]; });
  sorted_ids_.clear();
  sorted_motion_.clear();
  for (std::size_t i : order) {
    const std::uint32_t id = objects.ids[i];
    if (id == 0 || (!sorted_ids_.empty() && sorted_ids_.back() == id)) continue;
    sorted_ids_.push_back(id);
    sorted_motion_.push_back(std::isfinite(objects.motion[i]) ? objects.motion[i] : 0.0f);
  }
  objects_ = sorted_ids_.size();
  ensure_objects(objects_);
  const int rows = rows_for(objects_, kSlotRow);
  const std::size_t cells = static_cast<std::size_t>(rows) * kSlotRow;
  std::vector<std::uint32_t> ids(cells, 0u);
  std::vector<float> motion(cells, 0.0f);
  std::copy(sorted_ids_.begin(), sorted_ids_.end(), ids.begin());
  std::copy(sorted_motion_.begin(), sorted_motion_.end(), motion.begin());
  glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
  glBindTexture(GL_TEXTURE_2D, object_ids_);
  glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, kSlotRow, rows, GL_RED_INTEGER, GL_UNSIGNED_INT, ids.data());
  glBindTexture(GL_TEXTURE_2D, object_motion_);
  glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, kSlotRow, rows, GL_RED, GL_FLOAT, motion.data());
}

unsigned GlAttention::use(const unsigned (&programs)[2]) const {
  const unsigned p = programs[compute_ ? 1 : 0];
  glUseProgram(p);
  return p;
}

// The current pass over w x h texels of its targets: a full-screen triangle into them, or a compute
// dispatch writing them as images (the formats as the pass declared them).
void GlAttention::draw(std::initializer_list<Target> targets, int w, int h) {
  if (compute_) {
    GLint p = 0;
    glGetIntegerv(GL_CURRENT_PROGRAM, &p);
    glUniform2i(glGetUniformLocation(static_cast<GLuint>(p), "u_extent"), w, h);
    GLuint unit = 0;
    for (const Target& t : targets) glBindImageTexture(unit++, t.texture, 0, GL_FALSE, 0, GL_WRITE_ONLY, t.format);
    glDispatchCompute(static_cast<GLuint>((w + 7) / 8), static_cast<GLuint>((h + 7) / 8), 1);
    // The next pass reads them as textures, the scatter's vertices and the readbacks as pixels.
    glMemoryBarrier(gl::kComputeWrittenBarrier | GL_PIXEL_BUFFER_BARRIER_BIT);
    return;
  }
  unsigned textures[3] = {0, 0, 0};
  std::size_t n = 0;
  for (const Target& t : targets) textures[n++] = t.texture;
  gl::attach_targets(fbo_, std::span<const unsigned>(textures, n));
  glViewport(0, 0, w, h);
  glDrawArrays(GL_TRIANGLES, 0, 3);
}

void GlAttention::resample(const GlAttentionInput& in, double near_m, double far_m, const AttentionSettings& s) {
  // read_source of gbuffer_resample.cpp: the depth range of eq. 3.1 and what depths are clamped to.
  const double z_range = (std::isfinite(far_m - near_m) && far_m > near_m) ? far_m - near_m : 1.0;
  const float fnear = static_cast<float>(std::isfinite(near_m) ? near_m : 0.0);
  const float ffar = static_cast<float>(std::isfinite(far_m) ? far_m : static_cast<double>(fnear) + 1.0);
  const unsigned p = use(resample_program_);
  gl::bind_sampler(0, in.color, p, "u_color");
  gl::bind_sampler(1, in.depth, p, "u_depth");
  gl::bind_sampler(2, in.object_id, p, "u_ids");
  gl::bind_sampler(3, object_ids_, p, "u_objects");
  set_int(p, "u_n", n_);
  set_int(p, "u_objects_count", static_cast<int>(objects_));
  set_ivec2(p, "u_size", static_cast<int>(in.width), static_cast<int>(in.height));
  set_int(p, "u_nearest", s.resample == attention::Resample::Nearest);
  set_int(p, "u_has_image", in.width > 0 && in.height > 0);
  set_int(p, "u_has_color", in.color != 0);
  set_int(p, "u_has_depth", in.depth != 0);
  set_int(p, "u_has_ids", in.object_id != 0);
  glUniform1f(glGetUniformLocation(p, "u_near"), fnear);
  glUniform1f(glGetUniformLocation(p, "u_far"), ffar);
  set_float(p, "u_inv_range", 1.0 / z_range);
  if (!compute_) {
    draw({{levels_[0].image, GL_RGBA32F}, {slots_, GL_R32UI}, {map_depth_, GL_R32F}}, n_, n_);
    return;
  }
  glBindImageTexture(0, levels_[0].image, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA32F);
  glBindImageTexture(1, slots_, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_R32UI);
  glBindImageTexture(2, map_depth_, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_R32F);
  glDispatchCompute(static_cast<GLuint>(n_), static_cast<GLuint>(n_), 1);  // a workgroup per map pixel
  glMemoryBarrier(gl::kComputeWrittenBarrier | GL_PIXEL_BUFFER_BARRIER_BIT);
}

void GlAttention::scatter(int mode, unsigned target, int target_w, int target_h, int shift) {
  const unsigned p = scatter_program_;
  glUseProgram(p);
  gl::bind_sampler(0, slots_, p, "u_slots");
  gl::bind_sampler(1, select_[select_current_], p, "u_select");
  gl::bind_sampler(2, saliency_, p, "u_saliency");
  gl::bind_sampler(3, map_depth_, p, "u_map_depth");
  set_int(p, "u_n", n_);
  set_int(p, "u_mode", mode);
  set_int(p, "u_shift", shift);
  set_ivec2(p, "u_target", target_w, target_h);
  gl::attach_targets(fbo_, {target});
  glViewport(0, 0, target_w, target_h);
  const float zero[4] = {0, 0, 0, 0};
  glClearBufferfv(GL_COLOR, 0, zero);
  // Additive blending in primitive order: the same sums every run.
  glEnable(GL_BLEND);
  glBlendEquation(GL_FUNC_ADD);
  glBlendFunc(GL_ONE, GL_ONE);
  glDrawArrays(GL_POINTS, 0, n_ * n_);
  glDisable(GL_BLEND);
}

void GlAttention::paint_and_pyramids() {
  const int slot_rows = rows_for(object_capacity_, kSlotRow);
  scatter(0, counts_, kSlotRow, slot_rows, 0);
  unsigned p = use(paint_program_);
  gl::bind_sampler(0, slots_, p, "u_slots");
  gl::bind_sampler(1, counts_, p, "u_counts");
  gl::bind_sampler(2, object_motion_, p, "u_motion");
  set_float(p, "u_pixels", static_cast<double>(n_) * n_);
  draw({{levels_[0].object, GL_RG32F}}, n_, n_);
  p = use(down_program_);
  for (int l = 1; l < kLevels; ++l) {
    gl::bind_sampler(0, levels_[l - 1].image, p, "u_image");
    gl::bind_sampler(1, levels_[l - 1].object, p, "u_object");
    set_ivec2(p, "u_src", levels_[l - 1].w, levels_[l - 1].h);
    draw({{levels_[l].image, GL_RGBA32F}, {levels_[l].object, GL_RG32F}}, levels_[l].w, levels_[l].h);
  }
}

void GlAttention::contrast(const FeatureGroups& groups) {
  const unsigned p = use(contrast_program_);
  static const char* kImage[kLevels] = {"u_i0", "u_i1", "u_i2", "u_i3", "u_i4", "u_i5", "u_i6"};
  static const char* kObject[kLevels] = {"u_o0", "u_o1", "u_o2", "u_o3", "u_o4", "u_o5", "u_o6"};
  GLint dims[2 * kLevels];
  for (int l = 0; l < kLevels; ++l) {
    gl::bind_sampler(l, levels_[l].image, p, kImage[l]);
    gl::bind_sampler(kLevels + l, levels_[l].object, p, kObject[l]);
    dims[2 * l] = levels_[l].w;
    dims[2 * l + 1] = levels_[l].h;
  }
  glUniform2iv(glGetUniformLocation(p, "u_dim"), kLevels, dims);
  set_int(p, "u_n", n_);
  set_int(p, "u_image_group", groups.image);
  set_int(p, "u_object_group", groups.object);
  draw({{contrast_[0], GL_RGBA32F}, {contrast_[1], GL_RGBA32F}}, n_, n_);
}

unsigned GlAttention::reduce_max(unsigned in0, unsigned in1) {
  const unsigned p = use(reduce_program_);
  int w = n_, h = n_;
  for (std::size_t k = 0; k < reduce_chain_[0].size(); ++k) {
    gl::bind_sampler(0, in0, p, "u_in0");
    gl::bind_sampler(1, in1, p, "u_in1");
    set_ivec2(p, "u_src", w, h);
    draw({{reduce_chain_[0][k], GL_RGBA32F}, {reduce_chain_[1][k], GL_RGBA32F}}, reduce_w_[k], reduce_h_[k]);
    in0 = reduce_chain_[0][k];
    in1 = reduce_chain_[1][k];
    w = reduce_w_[k];
    h = reduce_h_[k];
  }
  reduced_[0] = in0;
  reduced_[1] = in1;
  return in0;
}

void GlAttention::saliency(const FeatureGroups& groups) {
  reduce_max(contrast_[0], contrast_[1]);
  unsigned p = use(weigh_program_);
  gl::bind_sampler(0, contrast_[0], p, "u_c0");
  gl::bind_sampler(1, contrast_[1], p, "u_c1");
  gl::bind_sampler(2, reduced_[0], p, "u_max0");
  gl::bind_sampler(3, reduced_[1], p, "u_max1");
  draw({{weighted_, GL_RGBA32F}}, n_, n_);
  const unsigned range = reduce_max(weighted_, weighted_);
  p = use(normalise_program_);
  gl::bind_sampler(0, weighted_, p, "u_weighted");
  gl::bind_sampler(1, range, p, "u_range");
  set_int(p, "u_all_off", !groups.image && !groups.object);
  draw({{saliency_, GL_R32F}}, n_, n_);
}

// Four rounds of 8 bits, most significant first: after the last, each object's key is its median's.
void GlAttention::median_depths() {
  const int slot_rows = rows_for(object_capacity_, kSlotRow);
  const int histogram_rows = rows_for(object_capacity_, kSlotRow / kBins);
  select_current_ = 0;
  unsigned p = use(select_init_program_);
  gl::bind_sampler(0, counts_, p, "u_counts");
  draw({{select_[0], GL_RG32UI}}, kSlotRow, slot_rows);
  for (int shift = 24; shift >= 0; shift -= 8) {
    scatter(2, histogram_, kSlotRow, histogram_rows, shift);
    p = use(select_program_);
    gl::bind_sampler(0, select_[select_current_], p, "u_select");
    gl::bind_sampler(1, histogram_, p, "u_histogram");
    set_int(p, "u_shift", shift);
    set_int(p, "u_objects_count", static_cast<int>(objects_));
    draw({{select_[1 - select_current_], GL_RG32UI}}, kSlotRow, slot_rows);
    select_current_ = 1 - select_current_;
  }
}

void GlAttention::read_objects(std::vector<ObjectPixels>& out) {
  out.clear();
  if (objects_ == 0) return;
  const int sum_rows = rows_for(objects_, kSlotRow / kBands), slot_rows = rows_for(objects_, kSlotRow);
  std::vector<float> sums(static_cast<std::size_t>(sum_rows) * kSlotRow * 4);
  std::vector<std::uint32_t> select(static_cast<std::size_t>(slot_rows) * kSlotRow * 4);
  glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, sums_, 0);
  glReadBuffer(GL_COLOR_ATTACHMENT0);
  glReadPixels(0, 0, kSlotRow, sum_rows, GL_RGBA, GL_FLOAT, sums.data());
  glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, select_[select_current_], 0);
  glReadPixels(0, 0, kSlotRow, slot_rows, GL_RGBA_INTEGER, GL_UNSIGNED_INT, select.data());
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  for (std::size_t s = 0; s < objects_; ++s) {
    double count = 0, sum_s = 0, sum_x = 0, sum_y = 0;
    for (std::size_t b = 0; b < kBands; ++b) {
      const float* v = &sums[((s / 64) * kSlotRow + (s % 64) * kBands + b) * 4];
      count += static_cast<double>(v[0]);
      sum_s += static_cast<double>(v[1]);
      sum_x += static_cast<double>(v[2]);
      sum_y += static_cast<double>(v[3]);
    }
    if (count < 0.5) continue;
    const std::uint32_t key = select[s * 4];
    out.push_back(ObjectPixels{sorted_ids_[s], static_cast<std::size_t>(std::llround(count)), sum_s, sum_x, sum_y,
                               static_cast<double>(from_sortable(key))});
  }
}

void GlAttention::run(const GlAttentionInput& in, double near_m, double far_m, const AttentionSettings& s,
                      const GlAttentionObjects& objects, std::vector<ObjectPixels>& out, Pass pass) {
  s.check();
  if (pass == Pass::Compute && !has_compute()) {
    throw std::invalid_argument("GlAttention: the compute passes need OpenGL 4.3 (built without them)");
  }
  compute_ = pass == Pass::Compute;
  GLint vao = 0;
  glGetIntegerv(GL_VERTEX_ARRAY_BINDING, &vao);
  glBindVertexArray(vao_);
  glDisable(GL_DEPTH_TEST);
  glDisable(GL_BLEND);
  ensure_map(s.map_size);
  upload_objects(objects);
  resample(in, near_m, far_m, s);
  paint_and_pyramids();
  contrast(s.groups);
  saliency(s.groups);
  scatter(1, sums_, kSlotRow, rows_for(object_capacity_, kSlotRow / kBands), 0);
  median_depths();
  read_objects(out);
  if (compute_) {
    for (GLuint unit = 0; unit < 3; ++unit) glBindImageTexture(unit, 0, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_R32F);
  }
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  glBindVertexArray(static_cast<GLuint>(vao));
  gl::check_error("GlAttention", "run");
}

void GlAttention::read_saliency(std::vector<float>& out) {
  out.assign(static_cast<std::size_t>(n_) * static_cast<std::size_t>(n_), 0.0f);
  if (n_ == 0) return;
  glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
  glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, saliency_, 0);
  glReadBuffer(GL_COLOR_ATTACHMENT0);
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  glReadPixels(0, 0, n_, n_, GL_RED, GL_FLOAT, out.data());  // texel row y is map row y
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  gl::check_error("GlAttention", "read_saliency");
}

void GlAttention::read_contrast(std::vector<float> (&out)[5]) {
  const std::size_t npix = static_cast<std::size_t>(n_) * static_cast<std::size_t>(n_);
  std::vector<float> rgba[2];
  glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
  glReadBuffer(GL_COLOR_ATTACHMENT0);
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  for (int k = 0; k < 2; ++k) {
    rgba[k].resize(npix * 4);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, contrast_[k], 0);
    if (n_ > 0) glReadPixels(0, 0, n_, n_, GL_RGBA, GL_FLOAT, rgba[k].data());
  }
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  for (int f = 0; f < 5; ++f) {
    out[f].resize(npix);
    for (std::size_t i = 0; i < npix; ++i) out[f][i] = f < 4 ? rgba[0][i * 4 + static_cast<std::size_t>(f)] : rgba[1][i * 4];
  }
  gl::check_error("GlAttention", "read_contrast");
}

void GlAttention::run_gbuffer(const GBuffer& g, double near_m, double far_m, const AttentionSettings& s,
                              const GlAttentionObjects& objects, std::vector<ObjectPixels>& out, double* gpu_ms,
                              Pass pass) {
  const std::uint32_t w = g.width, h = g.height;
  const std::size_t npix = std::size_t{w} * h;
  const bool has_image = npix > 0;
  GlAttentionInput in{0, 0, 0, w, h};
  if (has_image && g.color.size() >= npix) {
    static_assert(sizeof(glm::vec3) == 3 * sizeof(float), "the colour plane goes up as packed floats");
    in.color = gl::upload_top_first(upload_color_, GL_RGBA32F, GL_RGB, &g.color[0].x, w, h, 3, staging_);
  }
  if (has_image && g.depth.size() >= npix) in.depth = gl::upload_top_first(upload_depth_, GL_R32F, GL_RED, g.depth.data(), w, h, 1, staging_);
  if (has_image && g.object_id.size() >= npix) {
    if (upload_ids_ == 0) upload_ids_ = texture(GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, 1, 1);
    std::vector<std::uint32_t> flipped(npix);
    for (std::uint32_t y = 0; y < h; ++y)
      std::copy_n(g.object_id.begin() + static_cast<std::ptrdiff_t>(std::size_t{y} * w), w,
                  flipped.begin() + static_cast<std::ptrdiff_t>(std::size_t{h - 1 - y} * w));
    glBindTexture(GL_TEXTURE_2D, upload_ids_);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_R32UI, static_cast<GLsizei>(w), static_cast<GLsizei>(h), 0, GL_RED_INTEGER,
                 GL_UNSIGNED_INT, flipped.data());
    in.object_id = upload_ids_;
  }
  glQueryCounter(queries_[0], GL_TIMESTAMP);
  run(in, near_m, far_m, s, objects, out, pass);
  glQueryCounter(queries_[1], GL_TIMESTAMP);
  if (gpu_ms != nullptr) *gpu_ms = gl::elapsed_ms(queries_);
}

}  // namespace fovea::render
