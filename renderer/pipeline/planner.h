// SPDX-License-Identifier: Apache-2.0
#pragma once
// The effect planner: a typed pass graph built each frame from the passes' declarations (Filament's
// FrameGraph is the model). Each pass declares the resources it reads (some only with certain
// settings) and writes, and a rule: whether its effect is visible in this scene with these settings,
// and whether it can run. The planner keeps a pass when the frame's output depends on what it
// writes, through passes that are kept, and culls the rest; every decision carries its reason
// (`fovea-render --explain` prints them and the graph).
#include <string>
#include <vector>

#include "attention/focus.h"
#include "backend/gbuffer.h"
#include "lod/lod_policy.h"
#include "passes/dof_pass.h"
#include "pipeline/settings.h"
#include "scene/scene.h"

namespace fovea::render {

enum class PassId { GBuffer, Attention, Focus, LodSelect, Dof, Gi, Tonemap, Overlay };
inline constexpr int kPassCount = 8;

// What flows between the passes of one frame. The G-buffer's planes are typed further
// (GBufferPlanes); HdrColor is the colour the tone map reads (the G-buffer's colour plane, replaced
// by dof's), GiInset the gaze area's global illumination composited over it.
enum class Resource { LodLevels, GBuffer, Attention, FocalDepth, HdrColor, GiInset, Display };
inline constexpr int kResourceCount = 7;
const char* to_string(Resource r);

struct FramePlan;

// The settings the passes' rules and edges decide on, typed: parsed once per settings change
// (FramePipeline keeps them with Settings::version), not looked up as strings by every rule of every
// frame. The reasons for people still quote the settings' text.
// attention.device, dof.device: where a pass with a GPU implementation runs. Auto: on the GPU where
// the frame's G-buffer lies there and nothing keeps it off; Gpu: there or not at all (the planner
// says why); Cpu: on the CPU, from a readback.
enum class PassDevice { Auto, Cpu, Gpu };

struct PlanSettings {
  Resource output = Resource::Display;  // output=final: the display image; output=gbuffer: the G-buffer
  bool attention = true;
  PassDevice attention_device = PassDevice::Auto;
  attention::FocusMode focus_mode = attention::FocusMode::GazeAndAttention;
  bool lod = true;
  lod::Policy lod_policy = lod::Policy::ScreenSize;
  double lod_budget_ms = 0;
  bool dof = true;
  DofMethod dof_method = DofMethod::LeeMipmap;
  PassDevice dof_device = PassDevice::Auto;
  bool gi = false, gi_caustics = true, gi_full_area = false, gi_csf_periphery = false;
  PassDevice gi_device = PassDevice::Auto;
  std::string gi_estimate = "auto", gi_strategy = "traditional";
  bool shadows = false;
  bool overlay_gaze = true, overlay_focus = false;
  std::string overlay_map = "none";
  bool operator==(const PlanSettings&) const = default;
};
PlanSettings plan_settings(const Settings& settings);
PassDevice parse_device(const std::string& text);  // "auto|cpu|gpu"; anything else: Auto

struct PlanContext {
  const Scene& scene;
  const Settings& settings;  // for the reasons' text
  bool gaze_available = false;  // a gaze source other than "none"
  bool backend_traces_rays = true;  // the backend takes per-pixel lens rays (Embree; not the raster backend)
  // plan_settings(settings), when the caller keeps them parsed; null: plan_frame parses them.
  const PlanSettings* parsed = nullptr;
  // The frame's G-buffer lies on the GPU (FramePipeline's GPU-resident path): passes with a GPU
  // implementation run there.
  bool gpu_resident = false;
  // ... and the "GPU" is a software rasteriser on the CPU's own cores (llvmpipe): passes whose GPU
  // version is much slower there than their CPU version (attention: ~20x, bench/RESULTS.md) stay on
  // the CPU with device=auto.
  bool gpu_is_software = false;
  // The radiance estimate's radius the gi pass will use (gi.nn_radius resolved; 0: not known here).
  float gi_nn_radius_m = 0.0f;
  // Why the GPU frame cannot gather GI (GpuFrame::gi_gather_unavailable; "" : it can).
  std::string gpu_gi_unavailable{};
  const PlanSettings& typed() const;  // *parsed; throws std::logic_error when unset
  // What the frame hands out: the display image (output=final) or the G-buffer (output=gbuffer).
  Resource output() const { return typed().output; }
};

// A pass's own verdict, before the graph: is its effect visible in this scene with these settings
// (`wanted`), and can it run here (`able`; e.g. the ray-traced DOF reference on the raster backend
// cannot). `reason` says why, for people; `unable` says what is missing.
struct PassRule {
  bool wanted = false;
  std::string reason;
  bool able = true;
  std::string unable;
};

// One edge into a pass: the resource, and when the pass reads it (null `active`: always).
struct ReadDecl {
  ReadDecl(Resource r, const char* w = "", bool (*a)(const PlanContext&) = nullptr) : resource(r), when(w), active(a) {}
  Resource resource;
  const char* when;  // the settings that make the pass read it, for people ("lod.policy=ulod")
  bool (*active)(const PlanContext&);
  bool reads(const PlanContext& c) const { return active == nullptr || active(c); }
};

struct PassDecl {
  PassId id;
  const char* name;
  std::vector<ReadDecl> reads;
  std::vector<Resource> writes;
  const char* inputs;  // what it reads from outside the graph (scene, camera, gaze), for people
  PassRule (*rule)(const PlanContext&);
  // Typed: the planes of this frame's G-buffer the pass reads, with these settings and this plan
  // (null: none). What the GPU-resident frame writes and reads back is derived from these.
  GBufferPlanes (*gbuffer_reads)(const FramePlan& plan, const PlanSettings& settings) = nullptr;
  // With these settings the pass has a GPU implementation that runs where the G-buffer lies (the
  // GPU-resident frame); null: it has none. Passes that do not run on the GPU run on the CPU from a
  // readback of what they read.
  bool (*on_gpu)(const PlanContext&) = nullptr;
  // Its reason starts with who consumes it (attention, focus: their only purpose is their consumers).
  bool names_consumers = false;
  // With these settings and this plan it reads its G-buffer planes where the G-buffer lies rather than
  // from a readback, though the pass itself runs on the CPU: returns how, for people ("only the
  // pixels it looks at"), or null. Focus with attention reads rectangles around the points it looks
  // at (the objects' depths come from attention); lod-select's ULOD blend runs on the GPU. In a
  // GPU-resident frame nothing is read back whole for such a pass. Null function: never.
  const char* (*reads_where_the_gbuffer_lies)(const FramePlan& plan, const PlanSettings& settings) = nullptr;
};
// The passes in pipeline order.
const std::vector<PassDecl>& pass_declarations();
const PassDecl& declaration(PassId id);

struct PlannedPass {
  PassId id;
  bool needed = false;       // the requested output depends on this pass's effect
  bool runs = false;         // runs this frame: needed, able, and what it writes is read by a pass that runs
  std::string reason;
  GBufferPlanes gbuffer_reads;  // what it reads of the G-buffer when it runs (PassDecl::gbuffer_reads)
  bool on_gpu = false;          // runs on the GPU: the frame is GPU-resident and PassDecl::on_gpu says so
  std::vector<Resource> reads;  // the resources it reads with these settings (the graph's edges in)
  // PassDecl::reads_where_the_gbuffer_lies in this plan ("" : it reads from a readback where it runs).
  std::string reads_where_the_gbuffer_lies;
};

struct FramePlan {
  std::vector<PlannedPass> passes;  // pipeline order
  Resource output = Resource::Display;
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
