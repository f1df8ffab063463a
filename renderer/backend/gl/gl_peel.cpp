// SPDX-License-Identifier: Apache-2.0
#include "backend/gl/gl_peel.h"

#include <epoxy/gl.h>

#include <stdexcept>
#include <string>

#include "backend/gl/gl_backend.h"
#include "backend/gl/gl_program.h"

namespace fovea::render {

namespace {


// The state per pixel: .x the object met last, .y the objects met behind the visible one (low 16
// bits), kChosen when this step's layer is the one asked for, kDone once resolved.
constexpr const char* kStateBits = R"(
const uint kDone = 0x80000000u, kChosen = 0x40000000u, kMet = 0xffffu;
)";

// After a draw: the new state from the layer drawn (its depth and id; id 0: no fragment beyond).
constexpr const char* kResolveStep = R"(
uniform sampler2D u_layer_depth, u_last_depth;
uniform usampler2D u_layer_id, u_state;
uniform uint u_layers;  // the deepest layer asked for: a pixel is resolved when it has been met
uniform bool u_first;  // the unpeeled layer: the visible object, nothing met yet
void resolve_pixel(ivec2 p, out float o_depth, out uvec2 o_state) {
  float d = texelFetch(u_layer_depth, p, 0).r;
  uint id = texelFetch(u_layer_id, p, 0).r;
  if (u_first) {
    o_depth = d;
    o_state = uvec2(id, id == 0u ? kDone : 0u);  // a miss stays the background
    return;
  }
  uvec2 s = texelFetch(u_state, p, 0).xy;
  o_depth = texelFetch(u_last_depth, p, 0).r;
  o_state = uvec2(s.x, s.y & ~kChosen);
  if ((s.y & kDone) != 0u) return;
  if (id == 0u) {  // nothing farther along this ray
    o_state.y |= kDone;
    return;
  }
  uint met = s.y & kMet;
  if (id != s.x) met += 1u;  // another object: its first fragment
  o_depth = d;
  // kChosen: this step met a new object, whose planes are layer `met`.
  o_state = uvec2(id, met | (id != s.x && met <= u_layers ? kChosen : 0u) | (met >= u_layers ? kDone : 0u));
}
)";

constexpr const char* kResolve = R"(
layout(location = 0) out float o_depth;
layout(location = 1) out uvec2 o_state;
void main() { resolve_pixel(ivec2(gl_FragCoord.xy), o_depth, o_state); }
)";

// The visibility peel's step on GL 4.3 in one compute pass: the resolve, and the chosen pixels'
// triangles stored straight into their layer (the forward peel copies each layer's planes in a pass
// of its own, kCopy).
constexpr const char* kResolveCompute = R"(
layout(local_size_x = 8, local_size_y = 8) in;
uniform usampler2D u_layer_visibility;
uniform ivec2 u_size;
layout(r32f, binding = 0) uniform writeonly image2D u_out_depth;
layout(rg32ui, binding = 1) uniform writeonly uimage2D u_out_state;
layout(rg32ui, binding = 2) uniform writeonly uimage2DArray u_chosen;  // layer n at index n - 1
void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= u_size.x || p.y >= u_size.y) return;
  float depth;
  uvec2 state;
  resolve_pixel(p, depth, state);
  imageStore(u_out_depth, p, vec4(depth, 0.0, 0.0, 0.0));
  imageStore(u_out_state, p, uvec4(state, 0u, 0u));
  if ((state.y & kChosen) != 0u)
    imageStore(u_chosen, ivec3(p, int(state.y & kMet) - 1), uvec4(texelFetch(u_layer_visibility, p, 0).xy, 0u, 0u));
}
)";

// The layer's planes where this step met the object of layer u_layer.
constexpr const char* kCopy = R"(
uniform sampler2D u_color, u_depth, u_normal, u_motion;
uniform usampler2D u_id, u_state;
uniform uint u_layer;
layout(location = 0) out vec4 o_color;
layout(location = 1) out float o_depth;
layout(location = 2) out uint o_id;
layout(location = 3) out vec4 o_normal;
layout(location = 4) out vec2 o_motion;
void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  uint s = texelFetch(u_state, p, 0).y;
  if ((s & kChosen) == 0u || (s & kMet) != u_layer) discard;
  o_color = texelFetch(u_color, p, 0);
  o_depth = texelFetch(u_depth, p, 0).r;
  o_id = texelFetch(u_id, p, 0).r;
  o_normal = texelFetch(u_normal, p, 0);
  o_motion = texelFetch(u_motion, p, 0).rg;
}
)";

// Attachments 1, 2 and 5: what the visibility peel's draws write.
constexpr GLenum kVisibilityBuffers[6] = {GL_NONE, GL_COLOR_ATTACHMENT1, GL_COLOR_ATTACHMENT2,
                                          GL_NONE, GL_NONE,              GL_COLOR_ATTACHMENT5};

constexpr GLenum kBuffers[5] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1, GL_COLOR_ATTACHMENT2,
                                GL_COLOR_ATTACHMENT3, GL_COLOR_ATTACHMENT4};

void check(const char* where) { gl::check_error("GlPeeling", where); }

void complete(const char* what) {
  const GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
  if (status != GL_FRAMEBUFFER_COMPLETE) {
    throw std::runtime_error(std::string("GlPeeling: ") + what + " framebuffer incomplete (status " +
                             std::to_string(status) + ")");
  }
}


void bind(int unit, unsigned texture, unsigned program, const char* name) {
  gl::bind_sampler(unit, texture, program, name);
}

unsigned link(const char* body, const char* what) {
  const std::string source = std::string("#version 330 core\n") + kStateBits + body;
  return gl::link_program(gl::kFullscreenVertex, source.c_str(), what);
}

// GL 4.3: compute shaders, image stores, texture views (the chosen layers' array seen as 2D textures).
bool has_compute() { return epoxy_gl_version() >= 43; }

}  // namespace

GlPeeling::GlPeeling() {
  resolve_program_ = link((std::string(kResolveStep) + kResolve).c_str(), "GlPeeling resolve");
  if (has_compute()) {
    const std::string source = std::string("#version 430 core\n") + kStateBits + kResolveStep + kResolveCompute;
    resolve_compute_program_ = gl::link_compute_program(source.c_str(), "GlPeeling compute resolve");
  }
  copy_program_ = link(kCopy, "GlPeeling copy");
  glGenVertexArrays(1, &vao_);
  glGenQueries(1, &query_);
  check("GlPeeling()");
}

GlPeeling::~GlPeeling() {
  release();
  if (query_ != 0) glDeleteQueries(1, &query_);
  if (vao_ != 0) glDeleteVertexArrays(1, &vao_);
  if (resolve_program_ != 0) glDeleteProgram(resolve_program_);
  if (copy_program_ != 0) glDeleteProgram(copy_program_);
  if (resolve_compute_program_ != 0) glDeleteProgram(resolve_compute_program_);
}

void GlPeeling::release() {
  for (Targets* t : targets()) {
    if (t->fbo != 0) glDeleteFramebuffers(1, &t->fbo);
    glDeleteTextures(5, t->textures);
    if (t->visibility != 0) glDeleteTextures(1, &t->visibility);
    t->visibility = 0;
    if (t->z != 0) glDeleteRenderbuffers(1, &t->z);
    *t = Targets{};
  }
  results_.clear();
  if (chosen_ != 0) glDeleteTextures(1, &chosen_);
  chosen_ = 0;
  for (State& s : state_) {
    if (s.fbo != 0) glDeleteFramebuffers(1, &s.fbo);
    if (s.depth != 0) glDeleteTextures(1, &s.depth);
    if (s.ids != 0) glDeleteTextures(1, &s.ids);
    s = State{};
  }
  width_ = height_ = 0;
}

std::vector<GlPeeling::Targets*> GlPeeling::targets() {
  std::vector<Targets*> all{&layer_};
  for (Targets& t : results_) all.push_back(&t);
  return all;
}

void GlPeeling::ensure(std::uint32_t width, std::uint32_t height, std::uint32_t layers) {
  if (width == width_ && height == height_ && layer_.fbo != 0 && results_.size() == layers) return;
  release();
  results_.resize(layers);
  if (resolve_compute_program_ != 0) {  // the layers' triangles in one array the compute resolve writes
    glGenTextures(1, &chosen_);
    glBindTexture(GL_TEXTURE_2D_ARRAY, chosen_);
    glTexStorage3D(GL_TEXTURE_2D_ARRAY, 1, GL_RG32UI, static_cast<GLsizei>(width), static_cast<GLsizei>(height),
                   static_cast<GLsizei>(layers));
    glBindTexture(GL_TEXTURE_2D_ARRAY, 0);
  }
  for (Targets* t : targets()) {
    GlBackend::make_gbuffer_target(t->fbo, t->textures, t->z, width, height);
    complete("layer");
    if (chosen_ != 0 && t != &layer_) {  // result n: a 2D view of the array's layer n - 1
      const auto layer = static_cast<GLuint>(t - results_.data());
      glGenTextures(1, &t->visibility);
      glTextureView(t->visibility, GL_TEXTURE_2D, chosen_, GL_RG32UI, 0, 1, layer, 1);
      glBindTexture(GL_TEXTURE_2D, t->visibility);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
      glBindTexture(GL_TEXTURE_2D, 0);
    } else {
      t->visibility = gl::make_texture(GL_RG32UI, GL_RG_INTEGER, GL_UNSIGNED_INT, width, height);
    }
    glBindFramebuffer(GL_FRAMEBUFFER, t->fbo);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT5, GL_TEXTURE_2D, t->visibility, 0);
  }
  for (State& s : state_) {
    glGenFramebuffers(1, &s.fbo);
    glBindFramebuffer(GL_FRAMEBUFFER, s.fbo);
    s.depth = gl::make_texture(GL_R32F, GL_RED, GL_FLOAT, width, height);
    s.ids = gl::make_texture(GL_RG32UI, GL_RG_INTEGER, GL_UNSIGNED_INT, width, height);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, s.depth, 0);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT1, GL_TEXTURE_2D, s.ids, 0);
    glDrawBuffers(2, kBuffers);
    complete("state");
  }
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  width_ = width;
  height_ = height;
  check("GlPeeling::ensure");
}

void GlPeeling::resolve(const State& from, const State& to, std::uint32_t layers, bool first) {
  const unsigned p = resolve_program_;
  glBindFramebuffer(GL_FRAMEBUFFER, to.fbo);
  glViewport(0, 0, static_cast<GLsizei>(width_), static_cast<GLsizei>(height_));
  glUseProgram(p);
  bind(0, layer_.textures[1], p, "u_layer_depth");
  bind(1, layer_.textures[2], p, "u_layer_id");
  bind(2, from.depth, p, "u_last_depth");
  bind(3, from.ids, p, "u_state");
  glUniform1ui(glGetUniformLocation(p, "u_layers"), layers);
  glUniform1i(glGetUniformLocation(p, "u_first"), first ? 1 : 0);
  glDrawArrays(GL_TRIANGLES, 0, 3);
}

void GlPeeling::resolve_compute(const State& from, const State& to, std::uint32_t layers) {
  const unsigned p = resolve_compute_program_;
  glUseProgram(p);
  bind(0, layer_.textures[1], p, "u_layer_depth");
  bind(1, layer_.textures[2], p, "u_layer_id");
  bind(2, from.depth, p, "u_last_depth");
  bind(3, from.ids, p, "u_state");
  bind(4, layer_.visibility, p, "u_layer_visibility");
  glUniform1ui(glGetUniformLocation(p, "u_layers"), layers);
  glUniform1i(glGetUniformLocation(p, "u_first"), 0);
  glUniform2i(glGetUniformLocation(p, "u_size"), static_cast<GLint>(width_), static_cast<GLint>(height_));
  glBindImageTexture(0, to.depth, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_R32F);
  glBindImageTexture(1, to.ids, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RG32UI);
  glBindImageTexture(2, chosen_, 0, GL_TRUE, 0, GL_WRITE_ONLY, GL_RG32UI);
  glDispatchCompute((width_ + 7) / 8, (height_ + 7) / 8, 1);
  // The next draw samples the state; the shading reads the chosen triangles by texture fetches.
  glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT | GL_SHADER_IMAGE_ACCESS_BARRIER_BIT | GL_FRAMEBUFFER_BARRIER_BIT);
  for (GLuint k = 0; k < 3; ++k) glBindImageTexture(k, 0, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_R32F);
}

void GlPeeling::copy_chosen(const State& state, std::uint32_t layer) {
  glBindFramebuffer(GL_FRAMEBUFFER, results_[layer - 1].fbo);
  glViewport(0, 0, static_cast<GLsizei>(width_), static_cast<GLsizei>(height_));
  const unsigned p = copy_program_;
  glDrawBuffers(5, kBuffers);
  glUseProgram(p);
  bind(0, layer_.textures[0], p, "u_color");
  bind(1, layer_.textures[1], p, "u_depth");
  bind(2, layer_.textures[2], p, "u_id");
  bind(3, layer_.textures[3], p, "u_normal");
  bind(4, layer_.textures[4], p, "u_motion");
  bind(5, state.ids, p, "u_state");
  glUniform1ui(glGetUniformLocation(p, "u_layer"), layer);
  glDrawArrays(GL_TRIANGLES, 0, 3);
}

void GlPeeling::run(std::uint32_t width, std::uint32_t height, std::uint32_t layers, const DrawLayer& draw,
                    const Clear& clear) {
  if (layers == 0) throw std::invalid_argument("GlPeeling::run: no layer behind the visible one asked for");
  ensure(width, height, layers);
  visibility_ = false;
  for (const Targets& t : results_) clear(t.fbo);
  peel(layers, draw);
  check("GlPeeling::run");
}

void GlPeeling::run_visibility(std::uint32_t width, std::uint32_t height, std::uint32_t layers, const DrawLayer& draw,
                               const Shade& shade) {
  if (layers == 0) throw std::invalid_argument("GlPeeling::run_visibility: no layer behind the visible one asked for");
  if (resolve_compute_program_ == 0) {  // the visibility pass shading the layers needs GL 4.3 too
    throw std::logic_error("GlPeeling::run_visibility: needs OpenGL 4.3 (compute shaders)");
  }
  ensure(width, height, layers);
  visibility_ = true;
  for (const Targets& t : results_) clear_visibility(t.fbo);
  const DrawLayer draw_cleared = [&](unsigned fbo, const Against* against) {
    clear_visibility(fbo);
    draw(fbo, against);
  };
  peel(layers, draw_cleared);
  // Each layer's planes from the triangles it kept; a pixel without one shows the background.
  for (const Targets& t : results_) shade(t.visibility, t.textures);
  check("GlPeeling::run_visibility");
}

void GlPeeling::clear_visibility(unsigned fbo) {
  glBindFramebuffer(GL_FRAMEBUFFER, fbo);
  glViewport(0, 0, static_cast<GLsizei>(width_), static_cast<GLsizei>(height_));
  glDisable(GL_SCISSOR_TEST);
  glDrawBuffers(6, kVisibilityBuffers);
  const GLfloat no_depth[4] = {0, 0, 0, 0};
  const GLuint none[4] = {0, 0, 0, 0};
  const GLfloat far_z = 1.0f;
  glClearBufferfv(GL_COLOR, 1, no_depth);
  glClearBufferuiv(GL_COLOR, 2, none);
  glClearBufferuiv(GL_COLOR, 5, none);
  glDepthMask(GL_TRUE);
  glClearBufferfv(GL_DEPTH, 0, &far_z);
}

void GlPeeling::peel(std::uint32_t layers, const DrawLayer& draw) {
  draw(layer_.fbo, nullptr);
  steps_ = 1;
  const auto fullscreen = [&] {
    glDisable(GL_DEPTH_TEST);
    glDisable(GL_SCISSOR_TEST);
    glDisable(GL_BLEND);
    glBindVertexArray(vao_);
  };
  fullscreen();
  resolve(state_[1], state_[0], layers, true);
  int current = 0;
  while (steps_ < kMaxSteps) {
    const Against against{state_[current].depth, state_[current].ids};
    glBeginQuery(GL_ANY_SAMPLES_PASSED, query_);
    draw(layer_.fbo, &against);
    glEndQuery(GL_ANY_SAMPLES_PASSED);
    ++steps_;
    GLuint any = 0;
    glGetQueryObjectuiv(query_, GL_QUERY_RESULT, &any);
    if (any == 0) break;  // no pixel has a surface farther along: every pixel is resolved
    if (visibility_) {
      resolve_compute(state_[current], state_[1 - current], layers);
      current = 1 - current;
      continue;
    }
    fullscreen();
    resolve(state_[current], state_[1 - current], layers, false);
    current = 1 - current;
    for (std::uint32_t n = 1; n <= layers; ++n) copy_chosen(state_[current], n);
  }
  glBindVertexArray(0);
  glUseProgram(0);
  glActiveTexture(GL_TEXTURE0);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
}

}  // namespace fovea::render
