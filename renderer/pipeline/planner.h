#pragma once
// The effect planner: builds each frame's pass list backwards from the requested output and leaves
// out every pass whose effect the scene and settings cannot show, with the reason for each
// decision (`fovea-render --explain`).
#include <string>
#include <vector>

#include "backend/gbuffer.h"
#include "pipeline/settings.h"
#include "scene/scene.h"

namespace fovea::render {

enum class PassId { GBuffer, Attention, Focus, LodSelect, Dof, Gi, Tonemap, Overlay };
inline constexpr int kPassCount = 8;

struct FramePlan;

struct PassDecl {
  PassId id;
  const char* name;
  const char* reads;
  const char* writes;
  const char* needed_when;
  // Typed: the planes of this frame's G-buffer the pass reads, with these settings and this plan
  // (null: none). What the GPU-resident frame writes and reads back is derived from these.
  GBufferPlanes (*gbuffer_reads)(const FramePlan& plan, const Settings& settings) = nullptr;
  // The pass has a GPU implementation that runs where the G-buffer lies (the GPU-resident frame);
  // the others run on the CPU from a readback of what they read.
  bool on_gpu = false;
};
// The passes in pipeline order.
const std::vector<PassDecl>& pass_declarations();
const PassDecl& declaration(PassId id);

struct PlannedPass {
  PassId id;
  bool needed = false;       // the requested output needs this pass's effect
  bool runs = false;         // runs this frame: needed, and able to run with these settings
  std::string reason;
  GBufferPlanes gbuffer_reads;  // what it reads of the G-buffer when it runs (PassDecl::gbuffer_reads)
};

struct PlanContext {
  const Scene& scene;
  const Settings& settings;
  bool gaze_available = false;  // a gaze source other than "none"
  bool backend_traces_rays = true;  // the backend takes per-pixel lens rays (Embree; not the raster backend)
};

struct FramePlan {
  std::vector<PlannedPass> passes;  // pipeline order
  // Where the frame runs, for people (FramePipeline fills it in: the GPU-resident path and what it
  // reads back, or why the frame takes the readback path). Empty: not said.
  std::string placement;
  bool runs(PassId id) const;
  bool needed(PassId id) const;
  const PlannedPass& at(PassId id) const;
  // One line per pass: run, skip, or later (needed but cannot run), and why; then the graph of the
  // passes that run: what each reads (the G-buffer's planes typed) and writes.
  std::string explain() const;
};

FramePlan plan_frame(const PlanContext& context);

// The GPU-resident frame's planes (from the declarations of the passes that run): what the passes
// without a GPU implementation read (the readback), and what every pass reads (what the G-buffer
// pass must write; the rest is culled).
GBufferPlanes planes_read_on_cpu(const FramePlan& plan);
GBufferPlanes planes_read(const FramePlan& plan);

}  // namespace fovea::render
