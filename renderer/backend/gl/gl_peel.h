// SPDX-License-Identifier: Apache-2.0
#pragma once
// Depth peeling by object on the raster backend (BackendSettings::peel): the same layers as the
// Embree backend's trace_peeled. Along each pixel's ray, the n-th object met behind the visible one;
// an object's own back faces and other parts are skipped (consecutive fragments of one object count
// once); the background where there is none.
//
// Classic depth peeling (Everitt 2001) finds the fragments in depth order, one per scene draw: draw
// k keeps, per pixel, the nearest fragment farther than draw k - 1's (by Embree's epsilon,
// max(1e-4 m, 1e-5 d)). A resolve pass counts per pixel the changes of object id along that order
// and copies each layer's planes where the count reaches its number. Draws stop when no pixel got a fragment
// (an occlusion query) or after kMaxSteps (Embree's loop stops at 256 hits; a pixel still unresolved
// then keeps the background).
//
// run_visibility peels through the visibility buffer instead (GL 4.3, a scene GlVisibilityPass
// shades): each draw writes only view depth, object id and which triangle it kept, and each chosen
// layer is shaded once at the end by the visibility pass's compute shading. The same layers (the
// same fragments kept, by the same test), at a draw's cost without its shading: on GPUs whose raster
// pipeline is a small part of the chip (the H200) the forward peel's shading was most of its 27-29 ms.
//
// Needs a current OpenGL 3.3 context; the scene is drawn by the caller (GlBackend), into targets of
// its own, so the frame's G-buffer textures are left as they were.
#include <cstdint>
#include <functional>
#include <vector>

namespace fovea::render {

class GlPeeling {
 public:
  static constexpr int kMaxSteps = 64;

  GlPeeling();
  ~GlPeeling();
  GlPeeling(const GlPeeling&) = delete;
  GlPeeling& operator=(const GlPeeling&) = delete;

  // What a peeling draw discards against: per pixel the last layer's depth (R32F) and the state
  // (RG32UI: .y bit 31 set when the pixel is resolved).
  struct Against {
    unsigned depth = 0, state = 0;
  };
  // draw(fbo, against): clear `fbo` (its five G-buffer planes) to the background and draw every
  // object into it, discarding fragments against `against` (null: the first, unpeeled layer).
  using DrawLayer = std::function<void(unsigned fbo, const Against* against)>;
  // clear(fbo): the background G-buffer (what a pixel without a peeled surface shows).
  using Clear = std::function<void(unsigned fbo)>;

  // Peels layers 1..`layers` (>= 1) of a width x height image in one loop (layer n costs what
  // layers 1..n do); layer n is in result_fbo(n)'s five planes.
  void run(std::uint32_t width, std::uint32_t height, std::uint32_t layers, const DrawLayer& draw, const Clear& clear);
  // The visibility-buffer peel: draw(fbo, against) rasterises view depth, object id and (1 + draw,
  // primitive) into attachments 1, 2 and 5 of `fbo` (bound, cleared, its draw buffers set);
  // shade(visibility, planes) writes a layer's five planes (colour, depth, id, normal, motion) from
  // its visibility texture (0: the background).
  using Shade = std::function<void(unsigned visibility, const unsigned planes[5])>;
  // Needs OpenGL 4.3 (its step is one compute pass; the shading too): std::logic_error otherwise.
  void run_visibility(std::uint32_t width, std::uint32_t height, std::uint32_t layers, const DrawLayer& draw,
                      const Shade& shade);
  unsigned result_fbo(std::uint32_t layer) const { return results_.at(layer - 1).fbo; }
  // Layer n's colour (RGBA32F) and depth (R32F) textures, for GPU passes that read the layers.
  unsigned result_color(std::uint32_t layer) const { return results_.at(layer - 1).textures[0]; }
  unsigned result_depth(std::uint32_t layer) const { return results_.at(layer - 1).textures[1]; }
  int steps() const { return steps_; }  // scene draws of the last run (the unpeeled one included)

 private:
  struct Targets {  // the G-buffer's five planes, the visibility ids (attachment 5) and a z-buffer
    unsigned fbo = 0, textures[5] = {0, 0, 0, 0, 0}, visibility = 0, z = 0;
  };
  struct State {  // one side of the ping-pong state
    unsigned fbo = 0, depth = 0, ids = 0;
  };
  void ensure(std::uint32_t width, std::uint32_t height, std::uint32_t layers);
  void release();
  std::vector<Targets*> targets();  // the draw's and the results'
  // The loop both peels share: draws until no pixel gets a fragment, resolving and copying each step.
  void peel(std::uint32_t layers, const DrawLayer& draw);
  void clear_visibility(unsigned fbo);  // the visibility peel's draw target: no fragment anywhere
  void resolve(const State& from, const State& to, std::uint32_t layers, bool first);
  // The visibility peel's step on GL 4.3: the resolve and the chosen triangles in one compute pass.
  void resolve_compute(const State& from, const State& to, std::uint32_t layers);
  void copy_chosen(const State& state, std::uint32_t layer);

  unsigned resolve_program_ = 0, copy_program_ = 0, vao_ = 0, query_ = 0;
  unsigned resolve_compute_program_ = 0;  // 0 below GL 4.3
  unsigned chosen_ = 0;  // GL 4.3: the results' triangles, one array layer each (their visibility textures are views)
  bool visibility_ = false;  // this run peels through the visibility buffer
  Targets layer_;
  std::vector<Targets> results_;  // layer n in results_[n - 1]
  State state_[2];
  std::uint32_t width_ = 0, height_ = 0;
  int steps_ = 0;
};

}  // namespace fovea::render
