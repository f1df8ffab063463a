// SPDX-License-Identifier: Apache-2.0
#pragma once
// Runs one frame: plan the passes, run those that are needed and implemented, time each through
// the PassTimer. Owns the backend and the frame's buffers.
//
// Two paths. The readback path renders the G-buffer, brings every plane to the CPU and runs every
// pass there (the reference; the Embree backend's only path). The GPU-resident path (a backend with
// a GpuFrame, frame.gpu=true) keeps the G-buffer in GPU textures and runs there what has a GPU
// implementation (attention's pixel stage, the DOF methods, ULOD's blend, the tone map, the
// overlay; the planner decides, PlannedPass::on_gpu), reads back only the planes this frame's CPU
// passes read (focus reads only the pixels it looks at), uploads the HDR colour a CPU pass made;
// the display image stays on the GPU.
//
// Gaze is latched as late as each pass allows: at the frame's start (LOD selection), again before
// the focus pass and again before the overlay. Every frame records the age of the gaze sample the
// overlay drew at the moment the frame was complete (the GPU's fence, or the CPU image done) as
// "gaze-age" in the timings, and the GPU passes' own times as "gpu.*".
#include <cmath>
#include <limits>
#include <memory>

#include "attention/attention.h"
#include "attention/focus.h"
#include "backend/backend.h"
#include "backend/gpu_frame.h"
#include "dof/dof_image.h"
#include "gaze/gaze_input.h"
#include "gi/gi_pass.h"
#include "lod/lod_frame.h"
#include "lod/lod_policy.h"
#include "image/image.h"
#include "passes/dof_pass.h"
#include "passes/overlay.h"
#include "passes/tonemap.h"
#include "pipeline/pass_timer.h"
#include "pipeline/planner.h"
#include "pipeline/settings.h"

namespace fovea::render {

class EmbreeBackend;

class FramePipeline {
 public:
  FramePipeline(Scene scene, Settings settings, std::unique_ptr<Backend> backend, GazeInput& gaze);

  // The view render() draws: the scene's camera, or one eye of a stereo frame (camera.stereo;
  // Camera::eye_offset_m). A stereo frame is render(Left) then render(Right) with the same times and
  // frame index. The left eye runs every pass the plan asks for; the right eye reuses what both eyes
  // share, done once per frame: attention's object scores, the levels of detail (one level per object
  // for both eyes: a level seen differently by each eye would be binocular rivalry), the focal depth
  // (the eyes accommodate together) and the photon maps. It draws its own G-buffer, DOF, GI gather,
  // tone map and overlay, timed under "right." names ("right.frame", "right.gbuffer", ...) in the
  // left eye's timer frame. Each eye's gaze point is the source's (cyclopean) gaze point at the
  // fixation depth seen from that eye (Camera::eye_shift_x): the focal depth of the frame before when
  // the focus pass runs, else infinity (parallel eyes). Protocol v1 carries one gaze point per sample,
  // so no source's per-eye gaze reaches the renderer yet.
  enum class Eye { Mono, Left, Right };

  struct Frame {
    FramePlan plan;
    GazeState gaze;            // the last latched sample (the overlay's)
    double gaze_clock_s = 0;   // the frame clock it was read at
    const GBuffer* gbuffer = nullptr;
    const Image8* image = nullptr;  // null when output=gbuffer
    const attention::AttentionFrame* attention = nullptr;  // null when the attention pass did not run
    const attention::FocusResult* focus = nullptr;         // null when the focus pass did not run
    const dof::RgbImage* dof = nullptr;  // the DOF pass's HDR colour; null when it did not run
    double focal_depth_m = 0;            // what the DOF pass focused at (0 when it did not run)
    struct Gi {
      gi::GazeArea area;            // where GI was ray traced (the full screen: a circle around it)
      const char* follows = "";     // "gaze", "attention", "screen centre" or "full screen"
      std::size_t photons = 0, caustic_photons = 0;
      std::uint64_t emitted = 0;
      gi::GiStats render;
      std::string note;  // the tracer's note (fewer photons than asked, and why)
      const char* strategy = "traditional";
      gi::GazeFrameStats gaze;      // gaze-directed: emission map, bins, power scale
      std::size_t importons = 0;    // importon: importons stored
      gi::CsfStats csf;             // gi.periphery=csf: rays cast against full resolution
    };
    const Gi* gi = nullptr;  // null when the gi pass did not run
    struct Lod {
      const char* policy = "none";
      std::vector<lod::Selection> selection;  // per visible object with a chain
      std::uint64_t triangles = 0, full_triangles = 0;  // drawn, and at full detail
      lod::BudgetState budget;
      lod::SwitchState switches;
    };
    const Lod* lod = nullptr;  // null when lod-select did not run
    // The display image lies on the GPU (image is null): read_display() brings it to the CPU, the
    // viewer shows gpu_frame()->display_texture().
    bool on_gpu = false;
    GBufferPlanes read_back;  // on_gpu: the planes of `gbuffer` that are this frame's (the rest are stale)
    GBufferPlanes written;    // on_gpu: the planes the G-buffer pass wrote on the GPU (the others are culled)
    std::size_t focus_pixels_read = 0;  // on_gpu: G-buffer pixels (depth and id) the focus pass read back
    double gaze_age_at_completion_ms = 0;  // the overlay's gaze sample's age when the frame was complete
    double completed_wall_s = 0;           // when it was complete (steady_clock seconds)
    Eye eye = Eye::Mono;
    // Stereo: the depth the eyes converge at, and how far this eye's gaze point was moved from the
    // source's (normalised x; gaze.x is the moved point).
    double fixation_m = std::numeric_limits<double>::infinity();
    double eye_gaze_shift_x = 0;
    bool eye_gaze_measured = false;  // gaze is the tracker's point for this eye, not the vergence's
  };
  // Renders the frame at scene time `scene_time_s` (the previous frame's time for motion vectors)
  // with gaze sampled at `frame_clock_s` on the gaze input. `frame_clock_is_wall`: the frame clock
  // runs with the wall clock (the viewer, --realtime), so a late latch reads the gaze input at the
  // frame clock plus the time spent since the frame began; otherwise (frames on a schedule) the
  // sample stays the one of frame_clock_s, and its age at completion counts the frame's wall time.
  Frame render(std::uint64_t frame_index, double scene_time_s, double previous_time_s, double frame_clock_s,
               PassTimer& timer, bool frame_clock_is_wall = false, Eye eye = Eye::Mono);

  // The last frame's display image when it was made on the GPU (Frame::on_gpu), read back once.
  const Image8& read_display();
  // The backend's GPU-resident frame when this pipeline uses it (null otherwise).
  GpuFrame* gpu_frame() const { return gpu_; }
  // Where the frame's GPU passes run, for the governor's per-device fronts: the GPU's description
  // ("OpenGL 4.6 (NVIDIA H200/PCIe/SSE2)") when the frame is GPU-resident, else "cpu".
  std::string device() const;
  // Why the frame takes the readback path with the current settings ("" when it stays on the GPU).
  std::string gpu_refusal() const;
  // Keep every plane of the G-buffer on the CPU (headless --exr writes its colour): the readback path.
  void require_cpu_gbuffer(bool required) { cpu_gbuffer_required_ = required; }

  FramePlan plan() const;
  // What a stereo frame renders and shares, for --explain and plan.txt ("" for one view).
  std::string stereo_summary() const;
  const Scene& scene() const { return scene_; }
  Scene& mutable_scene() { return scene_; }
  // Call after changing the scene so the backend sees it (the backend builds it again).
  void scene_changed();
  // Call after moving the camera alone (the viewer's navigation): nothing is built again.
  void camera_changed() { backend_->set_camera(scene_.camera); }
  Settings& settings() { return settings_; }
  const Backend& backend() const { return *backend_; }

 private:
  Scene scene_;
  Settings settings_;
  std::unique_ptr<Backend> backend_;
  GazeInput& gaze_;
  GBuffer gbuffer_;
  Image8 image_;
  attention::AttentionTracker attention_;  // settings from attention.* each frame it runs
  attention::FocusSettings focus_settings_;  // what focus_ was built with (focus.* and the lens)
  attention::FocusTracker focus_;
  DofPass dof_;
  std::unique_ptr<gi::GiPass> gi_pass_;  // created on the first frame that runs gi
  EmbreeBackend* gi_tracer_ = nullptr;   // the frame's backend when it is Embree: gi traces with it
  lod::LodSelector lod_selector_;
  lod::BoundsCache lod_bounds_;
  Frame::Lod lod_frame_;
  std::vector<std::uint8_t> lod_levels_;  // per scene object, for the backend
  // Chooses this frame's levels from the camera, the last frame's attention and G-buffer, and gaze.
  void run_lod_select(const GazeState& gaze, double now_s, double previous_s, double last_frame_ms);
  GBuffer ulod_next_;  // lod.policy=ulod: the next-coarser levels, blended into the colour
  GBuffer proxy_;      // lod.policy=ulod: every object at its coarsest level, for the attention pass
  void blend_ulod(const FrameTime& time, const BackendSettings& drawn);
  void blend_ulod_on_gpu(const FrameTime& time, const BackendSettings& drawn);
  std::vector<std::uint32_t> ulod_ids_;  // the objects blending this frame, and
  std::vector<float> ulod_factors_;      // their factors (the GPU's blend)
  // The attention pass on `g` (the proxy or the frame's G-buffer) with attention.* applied.
  const attention::AttentionFrame& run_attention(const GBuffer& g, double now_s, double previous_s, bool check);
  // The attention pass with its pixel stage on the GPU (attention.device; the planner decides), on
  // the frame's G-buffer or, with `proxy`, on ULOD's proxy rendered there.
  const attention::AttentionFrame& run_attention_on_gpu(double now_s, double previous_s, bool check,
                                                        const BackendSettings* proxy = nullptr);
  std::vector<std::uint32_t> attention_ids_;      // the scene's objects, and
  std::vector<float> attention_motion_;           // their B_m, for the GPU's pixel stage
  std::vector<attention::ObjectPixels> attention_pixels_;
  std::vector<float> gpu_saliency_;               // read back for the finite check (debug only)
  std::vector<glm::vec3> hybrid_;
  std::vector<glm::vec3> gpu_checked_;  // a GPU pass's colour read back for the finite check (debug only)
  Frame::Gi gi_frame_;
  void place_gi_area(const Frame& f);  // gi_frame_'s area and what it follows
  std::string gpu_gi_unavailable(const gi::GiPassSettings& gs) const;
  // Places the gaze area, runs the gi pass over `local` into hybrid_, records its stage times.
  void run_gi(const Frame& f, const std::vector<glm::vec3>& local, double now_s, PassTimer& timer);
  // render()'s steps, in pipeline order: each times its pass under its timings.csv name, runs it,
  // checks what it wrote when debug.finite_checks (`check`), and records it in the Frame.
  void step_gaze(Frame& f, double frame_clock_s, PassTimer& timer);
  void step_attention_on_proxy(Frame& f, double now_s, double previous_s, bool check, PassTimer& timer);
  void step_lod_select(Frame& f, double now_s, double previous_s, PassTimer& timer);
  void step_gbuffer(const Frame& f, double now_s, double previous_s, bool check, PassTimer& timer);
  void step_attention(Frame& f, double now_s, double previous_s, bool check, PassTimer& timer);
  void step_focus(Frame& f, double frame_clock_s, bool check, PassTimer& timer);
  // dof and gi return the HDR colour they wrote, for the next pass.
  const std::vector<glm::vec3>& step_dof(Frame& f, double now_s, double previous_s, bool check, PassTimer& timer);
  const std::vector<glm::vec3>& step_gi(Frame& f, const std::vector<glm::vec3>& hdr, double now_s, bool check,
                                        PassTimer& timer);
  void step_tonemap(Frame& f, const std::vector<glm::vec3>& hdr, PassTimer& timer);
  void step_overlay(const Frame& f, PassTimer& timer);
  // The GPU passes this plan may run, for GpuFrame::prepare.
  GpuFrame::Prepare gpu_passes(const FramePlan& plan) const;
  // The GPU-resident path's steps (Frame::on_gpu).
  void step_gbuffer_on_gpu(Frame& f, double now_s, double previous_s, bool check, PassTimer& timer);
  void step_tonemap_on_gpu(const Frame& f, const std::vector<glm::vec3>& hdr, bool hdr_from_cpu, PassTimer& timer);
  void step_overlay_on_gpu(const Frame& f, PassTimer& timer);
  // Ends the frame: waits for the GPU (on_gpu), records the GPU times and the gaze's age then.
  void step_complete(Frame& f, PassTimer& timer);
  // Stereo: puts the camera at the eye (the backend's too), and for the left eye fixes the frame's
  // fixation depth and keeps what the right eye reuses.
  void begin_eye(Frame& f, Eye eye, std::uint64_t frame_index);
  void end_shared_work(const Frame& f);  // after focus: what the right eye reuses
  // The gaze as this frame's eye sees it (Frame::eye_gaze_shift_x); the source's for Mono.
  GazeState eye_gaze(Frame& f, const GazeState& source) const;
  struct SharedByEyes {  // the left eye's, for the right eye of the same frame
    const attention::AttentionFrame* attention = nullptr;
    const attention::FocusResult* focus = nullptr;
    bool lod = false, gi = false;
    std::uint64_t frame = ~std::uint64_t{0};  // the left eye's frame index (none: ~0)
    double fixation_m = std::numeric_limits<double>::infinity();
  } shared_;
  bool focus_ran_ = false;  // the focus pass ran in the frame before (its depth: the fixation's)
  // Reads the gaze input again (the frame clock advanced by the wall time spent when it is the wall
  // clock); timed as "gaze".
  void late_latch(Frame& f, PassTimer& timer);
  GBufferPlanes planes_written(const FramePlan& plan) const;
  std::string placement(const FramePlan& plan) const;
  bool visibility_buffer() const;  // the G-buffer pass asked of the backend (frame.gbuffer_pass)

  // The passes' typed settings, parsed from settings_ once per change (Settings::version) or scene
  // change, not from strings every frame.
  struct PassSettings {
    attention::AttentionSettings attention;
    attention::FocusSettings focus;
    gi::GiPassSettings gi;
    lod::PolicySettings lod;
    double lod_budget_ms = 0;
    TonemapParams tonemap;
    PlanSettings plan;  // what the planner's rules decide on
    DofPassSettings dof;
    bool shadows = false, depth_prepass = true, visibility_buffer = false, finite_checks = false;
    GpuPass effect_passes = GpuPass::Auto;  // frame.effect_passes
    double gaze_area_deg = 0;  // gi.gaze_area_deg when gi.enabled (the overlay's area ring), else 0
  };
  // Parsed again only when the settings' version moved or the scene changed (a cache: const).
  const PassSettings& pass_settings() const;
  mutable PassSettings parsed_;
  mutable std::uint64_t parsed_version_ = 0;
  mutable bool parsed_valid_ = false;
  mutable double scene_area_m2_ = std::nan("");  // for gi.nn_radius=auto; NaN until measured

  GpuFrame* gpu_ = nullptr;  // the backend's, when it has one that can run
  bool cpu_gbuffer_required_ = false;
  bool gi_inset_on_gpu_ = false; // this frame's GI inset is composited by the GPU's tone map
  bool gi_gathered_on_gpu_ = false;  // ... and was gathered there (gi.device)
  GBuffer gi_area_ids_;              // the gaze area's ids and depth read back for the GPU gather (the rest stale)
  std::vector<GpuPhoton> gi_photons_[2];  // the maps as the GPU gather takes them: indirect, caustic
  std::vector<std::uint32_t> gi_photon_index_[2];  // ... and each one's index in its trace's photons
  // Reads back the area's ids and depth (the pixels the CPU traces for the GPU gather).
  const GBuffer& read_gi_area_ids(const gi::GazeArea& area, PassTimer& timer);
  // Hands the area's gather to the GPU (the maps of the last gi run, the CPU's traced pixels).
  void gather_gi_on_gpu(const gi::GiPassSettings& gs, double now_s, PassTimer& timer);
  std::vector<float> gi_rect_depth_;
  std::vector<std::uint32_t> gi_rect_ids_;
  float gi_fovea_ = 0.7f;        // its fovea fraction (Algorithm 8.4)
  double frame_clock_s_ = 0;     // this frame's
  bool clock_is_wall_ = false;
  double frame_start_wall_s_ = 0, latch_wall_s_ = 0;  // steady_clock seconds
  Image8 display_;               // read_display()'s
};

}  // namespace fovea::render
