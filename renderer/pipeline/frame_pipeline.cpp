// SPDX-License-Identifier: Apache-2.0
#include "pipeline/frame_pipeline.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <unordered_map>

#include "attention/focus_input.h"
#include "backend/embree/embree_backend.h"
#include "dof/lee_splat.h"
#include "dof/reference.h"
#include "dof/schedl_layered.h"
#include "passes/tonemap.h"
#include "pipeline/finite_check.h"

namespace fovea::render {

namespace {
// The attention.* settings as the tracker's settings.
attention::AttentionSettings attention_settings(const Settings& s) {
  attention::AttentionSettings a;
  a.map_size = static_cast<int>(std::lround(s.number("attention.map_size")));
  a.resample = s.is("attention.resample", "nearest") ? attention::Resample::Nearest : attention::Resample::Box;
  const std::string& groups = s.text("attention.groups");
  a.groups.image = groups.find('B') != std::string::npos;
  a.groups.object = groups.find('E') != std::string::npos;
  a.groups.context = groups.find('T') != std::string::npos;
  a.temporal_window = static_cast<int>(std::lround(s.number("attention.lambda")));
  a.preferred_distance_m = s.number("attention.distance_m");
  a.kalman = s.flag("attention.kalman");
  return a;
}

attention::FocusSettings focus_settings(const Settings& s, const Lens& lens) {
  attention::FocusSettings f;
  const std::string& mode = s.text("focus.mode");
  f.mode = mode == "fixed"       ? attention::FocusMode::Fixed
           : mode == "gaze"      ? attention::FocusMode::Gaze
           : mode == "attention" ? attention::FocusMode::Attention
                                 : attention::FocusMode::GazeAndAttention;
  f.transition =
      s.is("focus.transition", "lowpass") ? attention::FocusTransition::LowPass : attention::FocusTransition::Lerp;
  f.transition_s = s.number("focus.transition_ms") / 1000.0;
  f.cutoff_hz = s.number("focus.cutoff_hz");
  f.gaze_radius_deg = s.number("focus.gaze_radius_deg");
  f.refocus_on_pursuit = s.flag("focus.refocus_on_pursuit");
  if (std::isfinite(lens.focus_distance_m) && lens.focus_distance_m > 0) f.fixed_depth_m = lens.focus_distance_m;
  return f;
}

// The gi.* settings (and shadows) as the gi pass's; gi.area=full shows GI everywhere (fovea 1, no CSF
// periphery).
gi::GiPassSettings gi_pass_settings(const Settings& s, double scene_area_m2) {
  const auto count = [&](const char* key) { return static_cast<std::uint32_t>(std::lround(s.number(key))); };
  const bool full = s.is("gi.area", "full");
  gi::GiPassSettings gs;
  const std::string& strategy = s.text("gi.strategy");
  gs.strategy = strategy == "gaze-directed" ? gi::Strategy::GazeDirected
                : strategy == "importon"    ? gi::Strategy::Importon
                                            : gi::Strategy::Traditional;
  gs.photons = count("gi.photons");
  gs.caustic_photons = count("gi.caustic_photons");
  gs.caustics = s.flag("gi.caustics");
  gs.trace_depth = count("gi.trace_depth");
  gs.seed = static_cast<std::uint64_t>(s.number("gi.seed"));
  gs.render.estimate.nearest = count("gi.nnn");
  gs.render.estimate.max_radius = s.is("gi.nn_radius", "auto")
                                      ? gi::auto_nn_radius(scene_area_m2, gs.render.estimate.nearest, gs.photons)
                                      : static_cast<float>(s.number("gi.nn_radius"));
  gs.render.estimate.filter = s.is("gi.filter", "disc") ? gi::EstimateFilter::Disc : gi::EstimateFilter::Cone;
  gs.render.caustic_estimate.filter = gs.render.estimate.filter;
  gs.render.indirect_estimate =
      s.is("gi.estimate", "precomputed") ? gi::IndirectEstimate::Precomputed : gi::IndirectEstimate::Nearest;
  // gi.estimate=auto gathers by radius where the gather runs on the GPU (FramePipeline::run_gi).
  gs.render.estimate.fixed_radius = gs.render.caustic_estimate.fixed_radius = s.is("gi.estimate", "radius");
  gs.overlap = s.is("gi.overlap", "true");  // auto: FramePipeline::run_gi
  gs.render.ray_depth = count("gi.ray_depth");
  gs.render.shadows = s.flag("shadows");
  gs.precompute_stride = count("gi.precompute_stride");
  gs.gaze.emission_ratio = s.number("gi.emission_ratio");
  gs.gaze.gaze_directed_reflections = s.flag("gi.guided_reflections");
  gs.gaze.nn_reflect_radius = static_cast<float>(s.number("gi.nn_reflect_radius"));
  gs.gaze.noise_scale = static_cast<float>(s.number("gi.noise_scale"));
  gs.importons = count("gi.importons");
  gs.fovea = full ? 1.0f : static_cast<float>(s.number("gi.fovea"));
  gs.csf_periphery = s.is("gi.periphery", "csf") && !full;
  gs.csf.quality = s.number("gi.csf_quality");
  return gs;
}

lod::PolicySettings lod_policy_settings(const Settings& s) {
  lod::PolicySettings ps;
  ps.policy = lod::parse_policy(s.text("lod.policy"));
  ps.tolerance_px = s.number("lod.tolerance_px");
  ps.distance_ref_m = s.number("lod.distance_ref_m");
  ps.hysteresis = s.number("lod.hysteresis");
  ps.switch_in_saccades = s.flag("lod.switch_in_saccades");
  return ps;
}

TonemapParams tonemap_params(const Settings& s) {
  TonemapParams p;
  p.exposure = static_cast<float>(s.number("tonemap.exposure"));
  p.op = s.text("tonemap.operator");
  p.exact = s.flag("tonemap.exact");
  return p;
}

double steady_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

GpuTonemap::Op gpu_operator(const std::string& op) {
  return op == "reinhard" ? GpuTonemap::Op::Reinhard
         : op == "exponential" ? GpuTonemap::Op::Exponential
                               : GpuTonemap::Op::Clamp;
}
}  // namespace

FramePipeline::FramePipeline(Scene scene, Settings settings, std::unique_ptr<Backend> backend, GazeInput& gaze)
    : scene_(std::move(scene)), settings_(std::move(settings)), backend_(std::move(backend)), gaze_(gaze) {
  backend_->set_scene(scene_);
  GpuFrame* gpu = backend_->gpu_frame();
  if (gpu != nullptr && gpu->unavailable_reason().empty()) {
    gpu_ = gpu;
  } else if (gpu != nullptr) {
    // One line, once: the device cannot run the GPU passes, so every frame takes the readback path.
    std::fprintf(stderr, "fovea-render: GPU passes off (%s): the frame is read back and every pass runs on the CPU\n",
                 gpu->unavailable_reason().c_str());
  }
}

const FramePipeline::PassSettings& FramePipeline::pass_settings() const {
  if (parsed_valid_ && parsed_version_ == settings_.version()) return parsed_;
  parsed_.attention = attention_settings(settings_);
  parsed_.focus = focus_settings(settings_, scene_.camera.lens);
  if (!(scene_area_m2_ >= 0)) scene_area_m2_ = gi::surface_area_m2(scene_);  // once per scene (NaN: not yet)
  parsed_.gi = gi_pass_settings(settings_, scene_area_m2_);
  parsed_.lod = lod_policy_settings(settings_);
  parsed_.lod_budget_ms = settings_.number("lod.budget_ms");
  parsed_.tonemap = tonemap_params(settings_);
  parsed_.plan = plan_settings(settings_);
  parsed_.dof = dof_pass_settings(settings_);
  parsed_.shadows = settings_.flag("shadows");
  parsed_.depth_prepass = settings_.flag("frame.depth_prepass");
  parsed_.visibility_buffer = visibility_buffer();
  parsed_.effect_passes = settings_.is("frame.effect_passes", "compute")    ? GpuPass::Compute
                          : settings_.is("frame.effect_passes", "fragment") ? GpuPass::Fragment
                                                                            : GpuPass::Auto;
  parsed_.finite_checks = settings_.flag("debug.finite_checks");
  parsed_.gaze_area_deg = settings_.flag("gi.enabled") ? settings_.number("gi.gaze_area_deg") : 0.0;
  parsed_version_ = settings_.version();
  parsed_valid_ = true;
  return parsed_;
}

void FramePipeline::scene_changed() {
  parsed_valid_ = false;  // the focus settings read the lens
  scene_area_m2_ = std::nan("");  // gi.nn_radius=auto reads the surfaces
  backend_->set_scene(scene_);
  if (gi_pass_) gi_pass_->set_scene(scene_);
}

// Why the GPU frame cannot gather GI with these settings ("" : it can): the maps' photons as asked,
// and the last emission round's overshoot (photon_tracer.h: at most 8192 a round), must fit.
std::string FramePipeline::gpu_gi_unavailable(const gi::GiPassSettings& gs) const {
  if (gpu_ == nullptr) return "";
  const std::size_t photons = std::size_t{std::max(gs.photons, gs.caustic_photons)} + 8192;
  return gpu_->gi_gather_unavailable(photons);
}

FramePlan FramePipeline::plan() const {
  const BackendCapabilities can = backend_->capabilities();
  const PassSettings& parsed = pass_settings();
  FramePlan plan = plan_frame(PlanContext{scene_, settings_, gaze_.available(), can.per_pixel_lens, &parsed.plan,
                                          gpu_refusal().empty(), can.software_rasteriser,
                                          parsed.gi.render.estimate.max_radius,
                                          gpu_gi_unavailable(parsed.gi)});
  plan.placement = placement(plan);
  return plan;
}

std::string FramePipeline::stereo_summary() const {
  const Camera& cam = scene_.camera;
  if (!cam.stereo) return "";
  char head[160];
  std::snprintf(head, sizeof head, "stereo     two views of %ux%u, the eyes %.1f mm apart along the camera's right axis",
                cam.width, cam.height, 1000.0 * static_cast<double>(cam.ipd_m));
  const FramePlan p = plan();
  std::string once, each;
  for (const PlannedPass& pass : p.passes) {
    if (!pass.runs) continue;
    const bool shared = pass.id == PassId::Attention || pass.id == PassId::LodSelect || pass.id == PassId::Focus;
    (shared ? once : each) += std::string(", ") + declaration(pass.id).name;
  }
  if (p.runs(PassId::Gi)) once += ", gi's photon maps";
  return std::string(head) + ", parallel view axes; once per frame (left eye): " +
         (once.empty() ? "nothing" : once.substr(2)) + "; per eye: " + (each.empty() ? "nothing" : each.substr(2)) +
         "; each eye's gaze: its own where the source measures both eyes (udp:// from a binocular tracker), "
         "else the source's gaze point at the fixation depth (" +
         (p.runs(PassId::Focus) ? "the focal depth of the frame before" : "infinity: the focus pass does not run") + ")";
}

std::string FramePipeline::device() const { return gpu_refusal().empty() ? gpu_->description() : "cpu"; }

std::string FramePipeline::gpu_refusal() const {
  if (gpu_ == nullptr) {
    GpuFrame* gpu = backend_->gpu_frame();
    return gpu != nullptr ? "GPU passes unavailable: " + gpu->unavailable_reason()
                          : "the " + backend_->name() + " backend renders on the CPU";
  }
  if (!settings_.flag("frame.gpu")) return "frame.gpu=false";
  if (!settings_.is("output", "final")) return "output=" + settings_.text("output") + " reads the whole G-buffer";
  if (!settings_.is("overlay.map", "none")) return "overlay.map=" + settings_.text("overlay.map") + " is drawn on the CPU";
  if (cpu_gbuffer_required_) return "the G-buffer is read on the CPU (--exr, --log-objects)";
  return "";
}

// What the G-buffer pass writes on the GPU: what some pass of this frame reads (colour always: the
// tone map's input), or every plane with debug.gbuffer_planes=all.
GBufferPlanes FramePipeline::planes_written(const FramePlan& plan) const {
  if (settings_.is("debug.gbuffer_planes", "all")) return GBufferPlanes::all();
  return planes_read(plan) | GBufferPlanes{.color = true};
}

// frame.gbuffer_pass: auto takes the visibility buffer where the backend says it is the faster.
bool FramePipeline::visibility_buffer() const {
  return settings_.is("frame.gbuffer_pass", "visibility") ||
         (settings_.is("frame.gbuffer_pass", "auto") && backend_->capabilities().visibility_buffer_faster);
}

std::string FramePipeline::placement(const FramePlan& plan) const {
  const std::string refusal = gpu_refusal();
  if (!refusal.empty()) return "cpu        every plane read back, every pass on the CPU: " + refusal;
  const BackendCapabilities can = backend_->capabilities();
  const bool visibility = pass_settings().visibility_buffer && can.visibility_buffer;
  const bool automatic = settings_.is("frame.gbuffer_pass", "auto");
  const std::string how =
      visibility ? "visibility buffer + compute shading"
      : !can.visibility_buffer && !settings_.is("frame.gbuffer_pass", "forward")
          ? "forward raster shading: no compute shaders (OpenGL 4.3)"
          : automatic ? "forward raster shading: frame.gbuffer_pass=auto on a software rasteriser"
                      : "forward raster shading";
  // The passes of this frame that run where the G-buffer lies, after it.
  std::string on_gpu;
  for (const PlannedPass& p : plan.passes)
    if (p.runs && p.on_gpu && p.id != PassId::GBuffer) on_gpu += std::string(", ") + declaration(p.id).name;
  // The CPU passes that read the G-buffer where it lies, and how.
  std::string looks;
  for (const PlannedPass& p : plan.passes)
    if (p.runs && !p.on_gpu && !p.reads_where_the_gbuffer_lies.empty())
      looks += std::string(looks.empty() ? "" : "; ") + declaration(p.id).name + ": " + p.reads_where_the_gbuffer_lies;
  return "gpu        " + gpu_->description() + ": G-buffer (" + how + ")" + on_gpu +
         " on the GPU (effect passes: " + gpu_->effect_passes(pass_settings().effect_passes) + "); G-buffer planes written: " +
         to_string(planes_written(plan)) + "; read back: " + to_string(planes_read_on_cpu(plan)) +
         (looks.empty() ? "" : " (" + looks + ")");
}

namespace {

// The timer's prefix for one eye's render, ended however the render ends.
class TimerPrefix {
 public:
  TimerPrefix(PassTimer& timer, std::string prefix) : timer_(timer) { timer_.set_prefix(std::move(prefix)); }
  ~TimerPrefix() { timer_.set_prefix(""); }
  TimerPrefix(const TimerPrefix&) = delete;
  TimerPrefix& operator=(const TimerPrefix&) = delete;

 private:
  PassTimer& timer_;
};

// The module-boundary check (finite_check.h) on a G-buffer a pass wrote.
void require_finite_gbuffer(const char* pass, const GBuffer& g) {
  require_finite(pass, "color", g.color, g.width);
  require_finite(pass, "depth", g.depth, g.width);
  require_finite(pass, "normal", g.normal, g.width);
  require_finite(pass, "motion", g.motion, g.width);
}

void require_finite_attention(const attention::AttentionFrame& a) {
  require_finite("attention", "saliency map", a.saliency, static_cast<std::uint32_t>(a.map_width));
  std::vector<double> values;
  for (const attention::ObjectAttention& o : a.objects)
    values.insert(values.end(), {o.attention, o.attention_raw, o.screen_x, o.screen_y, o.depth_m, o.distance_m});
  require_finite("attention", "object attention (S_o, screen position, depth)", values);
}

}  // namespace

// The passes in pipeline order, each run only when the plan says so. The ULOD policy moves the
// attention pass before lod-select and the G-buffer (step_attention_on_proxy); the HDR colour is
// handed from the G-buffer through dof and gi to tonemap. On the GPU-resident path the G-buffer, the
// tone map and the overlay run on the GPU and the CPU passes read what was read back of it.
FramePipeline::Frame FramePipeline::render(std::uint64_t frame_index, double now_s, double previous_s,
                                           double frame_clock_s, PassTimer& timer, bool frame_clock_is_wall, Eye eye) {
  const bool right = eye == Eye::Right;  // reuses the left eye's shared work (Eye)
  if (right && shared_.frame != frame_index) {
    throw std::logic_error("FramePipeline::render: the right eye of frame " + std::to_string(frame_index) +
                           " without its left eye");
  }
  if (!right) timer.begin_frame(frame_index, now_s);
  TimerPrefix prefix(timer, right ? "right." : "");
  auto whole = timer.scope("frame");
  frame_start_wall_s_ = steady_seconds();
  frame_clock_s_ = frame_clock_s;
  clock_is_wall_ = frame_clock_is_wall;
  Frame f;
  begin_eye(f, eye, frame_index);
  f.plan = plan();
  f.on_gpu = gpu_refusal().empty();
  const PassSettings& ps = pass_settings();
  const bool check = ps.finite_checks;
  if (dof_.settings() != ps.dof) dof_.set_settings(ps.dof);  // the coc map draws with them too
  step_gaze(f, frame_clock_s, timer);
  if (!right) lod_levels_.clear();
  gi_inset_on_gpu_ = gi_gathered_on_gpu_ = false;
  const bool attention_first = !right && f.plan.runs(PassId::LodSelect) && f.plan.runs(PassId::Attention) &&
                               ps.plan.lod_policy == lod::Policy::Ulod;
  if (right && f.plan.runs(PassId::Attention)) f.attention = shared_.attention;
  if (attention_first) step_attention_on_proxy(f, now_s, previous_s, check, timer);
  if (f.plan.runs(PassId::LodSelect)) {
    if (!right) step_lod_select(f, now_s, previous_s, timer);
    if (right && shared_.lod) f.lod = &lod_frame_;  // lod_levels_ stay the left eye's
  }
  if (f.on_gpu) {
    step_gbuffer_on_gpu(f, now_s, previous_s, check, timer);
  } else {
    step_gbuffer(f, now_s, previous_s, check, timer);
  }
  f.gbuffer = &gbuffer_;
  if (!right && f.plan.runs(PassId::Attention) && !attention_first) step_attention(f, now_s, previous_s, check, timer);
  if (f.plan.runs(PassId::Focus)) {
    late_latch(f, timer);
    if (!right) step_focus(f, f.gaze_clock_s, check, timer);
    if (right) f.focus = shared_.focus;
  }
  if (!right) end_shared_work(f);
  const std::vector<glm::vec3>* hdr = &gbuffer_.color;
  if (f.plan.runs(PassId::Dof)) hdr = &step_dof(f, now_s, previous_s, check, timer);
  if (f.plan.runs(PassId::Gi)) hdr = &step_gi(f, *hdr, now_s, check, timer);
  if (f.on_gpu) {
    if (f.plan.runs(PassId::Tonemap)) step_tonemap_on_gpu(f, *hdr, hdr != &gbuffer_.color, timer);
    if (f.plan.runs(PassId::Overlay)) {
      late_latch(f, timer);
      step_overlay_on_gpu(f, timer);
    }
  } else {
    if (f.plan.runs(PassId::Tonemap)) step_tonemap(f, *hdr, timer);
    if (f.plan.runs(PassId::Overlay)) {
      late_latch(f, timer);
      step_overlay(f, timer);
    }
  }
  step_complete(f, timer);
  return f;
}

void FramePipeline::late_latch(Frame& f, PassTimer& timer) {
  if (!clock_is_wall_) return;  // frames on a schedule: the frame's sample stays (deterministic output)
  auto t = timer.scope("gaze");
  const double now_wall = steady_seconds();
  f.gaze_clock_s = frame_clock_s_ + (now_wall - frame_start_wall_s_);
  f.gaze = eye_gaze(f, gaze_.at(f.gaze_clock_s));
  latch_wall_s_ = now_wall;
}

void FramePipeline::begin_eye(Frame& f, Eye eye, std::uint64_t frame_index) {
  f.eye = eye;
  const float half = 0.5f * scene_.camera.ipd_m;
  const float offset = eye == Eye::Left ? -half : eye == Eye::Right ? half : 0.0f;
  if (scene_.camera.eye_offset_m != offset) {  // the camera alone: nothing is built again
    scene_.camera.eye_offset_m = offset;
    backend_->set_camera(scene_.camera);
  }
  if (eye == Eye::Left) {
    shared_ = SharedByEyes{};
    shared_.frame = frame_index;
    shared_.fixation_m = focus_ran_ ? focus_.last().focal_depth_m : std::numeric_limits<double>::infinity();
  } else if (eye == Eye::Mono) {
    shared_.frame = ~std::uint64_t{0};  // no right eye follows
  }
  f.fixation_m = eye == Eye::Mono ? std::numeric_limits<double>::infinity() : shared_.fixation_m;
}

void FramePipeline::end_shared_work(const Frame& f) {
  focus_ran_ = f.focus != nullptr;
  shared_.attention = f.attention;
  shared_.focus = f.focus;
  shared_.lod = f.lod != nullptr;
}

// A stereo eye's gaze: the tracker's point for this eye where the source measures it (a
// binocular tracker: each eye's point on the screen is where it looks in its own view), else the
// source's point moved by the vergence on the fixation depth (Camera::eye_shift_x).
GazeState FramePipeline::eye_gaze(Frame& f, const GazeState& source) const {
  GazeState g = source;
  const auto& measured = f.eye == Eye::Left ? source.left_eye : f.eye == Eye::Right ? source.right_eye : std::nullopt;
  f.eye_gaze_measured = measured.has_value();
  if (measured) {
    g.x = std::clamp(measured->x, 0.0, 1.0);
    g.y = std::clamp(measured->y, 0.0, 1.0);
    f.eye_gaze_shift_x = g.x - source.x;
    return g;
  }
  f.eye_gaze_shift_x = scene_.camera.eye_shift_x(f.fixation_m);
  g.x = std::clamp(g.x + f.eye_gaze_shift_x, 0.0, 1.0);
  return g;
}

void FramePipeline::step_complete(Frame& f, PassTimer& timer) {
  if (f.on_gpu) {
    GpuCompletion done;
    {
      auto t = timer.scope("gpu.wait");
      done = gpu_->finish();
    }
    for (const auto& [pass, ms] : done.pass_ms) timer.record(pass, ms);
    f.completed_wall_s = done.wall_s;
  } else {
    f.completed_wall_s = steady_seconds();
  }
  // Not a pass: how old the gaze the overlay drew was when the frame was complete.
  f.gaze_age_at_completion_ms = f.gaze.age_ms + (f.completed_wall_s - latch_wall_s_) * 1000.0;
  timer.record("gaze-age", f.gaze_age_at_completion_ms);
}

// What this plan may run where the frame lies (GpuFrame::prepare builds it before its first use).
GpuFrame::Prepare FramePipeline::gpu_passes(const FramePlan& plan) const {
  GpuFrame::Prepare p;
  p.attention = plan.runs(PassId::Attention) && plan.at(PassId::Attention).on_gpu;
  p.ulod_blend = plan.runs(PassId::LodSelect) && pass_settings().plan.lod_policy == lod::Policy::Ulod;
  if (plan.runs(PassId::Dof) && plan.at(PassId::Dof).on_gpu) {
    const DofMethod m = dof_.settings().method;
    p.lee_mipmap = m == DofMethod::LeeMipmap;
    p.schedl_layered = m == DofMethod::SchedlLayered;
    p.lee_splat = m == DofMethod::LeeSplat;
  }
  return p;
}

void FramePipeline::step_gbuffer_on_gpu(Frame& f, double now_s, double previous_s, bool check, PassTimer& timer) {
  auto t = timer.scope("gbuffer");
  const PassSettings& ps = pass_settings();
  BackendSettings bs;
  bs.shadows = ps.shadows;
  bs.lod_levels = lod_levels_;
  bs.depth_prepass = ps.depth_prepass;
  bs.visibility_buffer = ps.visibility_buffer;
  f.read_back = planes_read_on_cpu(f.plan);
  f.written = planes_written(f.plan);
  gpu_->set_effect_passes(ps.effect_passes);
  gpu_->prepare(gpu_passes(f.plan));
  gpu_->render_gbuffer(FrameTime{now_s, previous_s}, bs, f.written, gbuffer_);
  {
    auto r = timer.scope("gbuffer.readback");
    gpu_->read_back(f.read_back, gbuffer_);
  }
  if (f.lod != nullptr && ps.plan.lod_policy == lod::Policy::Ulod) blend_ulod_on_gpu(FrameTime{now_s, previous_s}, bs);
  if (check) require_finite_gbuffer("gbuffer", gbuffer_);
}

void FramePipeline::step_tonemap_on_gpu(const Frame& f, const std::vector<glm::vec3>& hdr, bool hdr_from_cpu,
                                        PassTimer& timer) {
  auto t = timer.scope("tonemap");
  if (hdr_from_cpu) gpu_->upload_hdr(hdr, f.gbuffer->width, f.gbuffer->height);
  if (f.gi != nullptr && gi_inset_on_gpu_ && !gi_gathered_on_gpu_) {  // gathered: the inset is already there
    gpu_->upload_inset(gi_pass_->gi_image(), f.gbuffer->width, f.gbuffer->height, f.gi->area.center_px,
                       f.gi->area.radius_px, gi_fovea_);
  }
  const TonemapParams& p = pass_settings().tonemap;
  gpu_->tonemap(GpuTonemap{gpu_operator(p.op), p.exposure, GpuTonemap::Pass::Auto});
}

// draw_focus and draw_gaze's marks (passes/overlay.h) as the GPU pass draws them.
void FramePipeline::step_overlay_on_gpu(const Frame& f, PassTimer& timer) {
  auto t = timer.scope("overlay");
  GpuOverlay o;
  const PassSettings& ps = pass_settings();
  if (f.focus != nullptr && ps.plan.overlay_focus) {
    // The focus pass knows whether its object has pixels; the ids are not read back for this.
    const std::uint32_t id = f.focus->object;
    const bool seen = id != 0 && f.focus->object_visible;
    o.focus = seen ? GpuOverlay::Focus::Outline
              : std::isfinite(f.focus->focal_depth_m) ? GpuOverlay::Focus::IsoDepth
                                                      : GpuOverlay::Focus::None;
    o.focus_object = id;
    o.focal_depth_m = f.focus->focal_depth_m;
    o.focus_in_transition = f.focus->in_transition;
  }
  if (ps.plan.overlay_gaze && gaze_.available()) {
    const std::uint32_t w = f.gbuffer->width;
    o.gaze = true;
    o.gaze_x = f.gaze.x;
    o.gaze_y = f.gaze.y;
    o.gaze_valid = f.gaze.valid;
    o.ring_diameter_px = std::max(3.0, degrees_to_pixels(scene_.display, w, 1.0));
    const double area = ps.gaze_area_deg;
    o.area_diameter_px = area > 0 ? degrees_to_pixels(scene_.display, w, area) : 0.0;
  }
  gpu_->overlay(o);
}

const Image8& FramePipeline::read_display() {
  if (gpu_ == nullptr) throw std::logic_error("FramePipeline::read_display: the frame is not on the GPU");
  std::uint32_t w = 0, h = 0;
  gpu_->read_display(display_.rgb, w, h);
  display_.width = w;
  display_.height = h;
  return display_;
}

void FramePipeline::step_gaze(Frame& f, double frame_clock_s, PassTimer& timer) {
  auto t = timer.scope("gaze");
  f.gaze_clock_s = frame_clock_s;
  f.gaze = eye_gaze(f, gaze_.at(frame_clock_s));
  latch_wall_s_ = steady_seconds();
}

// Lee 2009 §7.2: when attention chooses the levels (ULOD), the attention pass runs first, on a
// G-buffer of every object's coarsest level (its proxy: the attention values barely change, Fig.
// 7.1), so the levels follow this frame's attention (cost model eq. 7.2: T_n + T_a + t (a + r)).
void FramePipeline::step_attention_on_proxy(Frame& f, double now_s, double previous_s, bool check, PassTimer& timer) {
  BackendSettings ps;
  ps.shadows = settings_.flag("shadows");
  ps.lod_levels.assign(scene_.objects.size(), 255);  // clamped to each object's coarsest level
  if (settings_.is("lod.proxy_resolution", "map"))
    lod::proxy_size(scene_.camera.width, scene_.camera.height,
                    static_cast<int>(settings_.number("attention.map_size")), ps.width, ps.height);
  if (f.on_gpu && f.plan.at(PassId::Attention).on_gpu) {  // the proxy and its pixel stage where the frame lies
    auto t = timer.scope("attention");
    f.attention = &run_attention_on_gpu(now_s, previous_s, check, &ps);
    return;
  }
  {
    auto t = timer.scope("attention.proxy");
    backend_->render(FrameTime{now_s, previous_s}, ps, proxy_);
    if (check) require_finite_gbuffer("attention.proxy", proxy_);
  }
  auto t = timer.scope("attention");
  f.attention = &run_attention(proxy_, now_s, previous_s, check);
}

void FramePipeline::step_lod_select(Frame& f, double now_s, double previous_s, PassTimer& timer) {
  const double last_frame_ms = timer.last_ms("frame");
  auto t = timer.scope("lod-select");
  run_lod_select(f.gaze, now_s, previous_s, last_frame_ms);
  f.lod = &lod_frame_;
}

void FramePipeline::step_gbuffer(const Frame& f, double now_s, double previous_s, bool check, PassTimer& timer) {
  auto t = timer.scope("gbuffer");
  const PassSettings& ps = pass_settings();
  BackendSettings bs;
  bs.shadows = ps.shadows;
  bs.lod_levels = lod_levels_;
  bs.depth_prepass = ps.depth_prepass;
  bs.visibility_buffer = ps.visibility_buffer;
  backend_->render(FrameTime{now_s, previous_s}, bs, gbuffer_);
  if (f.lod != nullptr && ps.plan.lod_policy == lod::Policy::Ulod) {
    auto u = timer.scope("gbuffer.ulod");  // the next levels' render and the blend, inside "gbuffer"
    blend_ulod(FrameTime{now_s, previous_s}, bs);
  }
  if (check) require_finite_gbuffer("gbuffer", gbuffer_);
}

void FramePipeline::step_attention(Frame& f, double now_s, double previous_s, bool check, PassTimer& timer) {
  auto t = timer.scope("attention");
  if (f.on_gpu && f.plan.at(PassId::Attention).on_gpu) {
    f.attention = &run_attention_on_gpu(now_s, previous_s, check);
  } else {
    f.attention = &run_attention(gbuffer_, now_s, previous_s, check);
  }
}

namespace {

// The focus pass's view of a G-buffer that lies on the GPU: the rectangles it looks at are read back
// as it looks (a few hundred pixels), the whole depth and id planes once, only when an object's
// median depth is not in the attention frame.
class GpuFocusPixels final : public attention::FocusPixels {
 public:
  GpuFocusPixels(GpuFrame& gpu, GBuffer& frame, bool planes_read_back) : gpu_(gpu), frame_(frame), whole_(planes_read_back) {}
  std::uint32_t width() const override { return frame_.width; }
  std::uint32_t height() const override { return frame_.height; }
  void read(std::uint32_t x0, std::uint32_t y0, std::uint32_t x1, std::uint32_t y1, std::vector<float>& depth,
            std::vector<std::uint32_t>& ids) override {
    if (whole_) {
      attention::GBufferPixels(frame_).read(x0, y0, x1, y1, depth, ids);
      return;
    }
    gpu_.read_rect(x0, y0, x1, y1, depth, ids);
    pixels_read_ += std::size_t{x1 - x0} * (y1 - y0);
  }
  const GBuffer& whole() override {
    if (!whole_) {
      gpu_.read_back({.depth = true, .object_id = true}, frame_);
      whole_ = true;
      pixels_read_ += frame_.size();
    }
    return frame_;
  }
  std::size_t pixels_read() const { return pixels_read_; }

 private:
  GpuFrame& gpu_;
  GBuffer& frame_;
  bool whole_;  // the frame's depth and ids are on the CPU (read back for another pass, or by whole())
  std::size_t pixels_read_ = 0;
};

}  // namespace

void FramePipeline::step_focus(Frame& f, double frame_clock_s, bool check, PassTimer& timer) {
  auto t = timer.scope("focus");
  const attention::FocusSettings& wanted = pass_settings().focus;
  if (wanted != focus_settings_) {  // a changed setting starts the focus afresh
    focus_settings_ = wanted;
    focus_ = attention::FocusTracker(wanted);
  }
  // On the frame clock (the gaze's clock): transitions are perceptual time, even with the scene paused.
  const attention::FocusGaze gaze = attention::focus_gaze_from(f.gaze, gaze_.available());
  if (f.on_gpu) {
    GpuFocusPixels pixels(*gpu_, gbuffer_, f.read_back.depth && f.read_back.object_id);
    focus_.update(frame_clock_s, pixels, scene_, f.attention, gaze, scene_.display);
    f.focus_pixels_read = pixels.pixels_read();
  } else {
    focus_.update(frame_clock_s, gbuffer_, scene_, f.attention, gaze, scene_.display);
  }
  f.focus = &focus_.last();
  if (check) {
    require_finite("focus", "focal depth", std::vector<double>{f.focus->focal_depth_m, f.focus->target_depth_m});
  }
}

const std::vector<glm::vec3>& FramePipeline::step_dof(Frame& f, double now_s, double previous_s, bool check,
                                                      PassTimer& timer) {
  auto t = timer.scope("dof");
  // The focus pass's depth; with focus.mode=fixed (focus not run) the lens's own focus distance.
  const double focus_m = f.focus != nullptr ? f.focus->focal_depth_m : scene_.camera.lens.focus_distance_m;
  f.focal_depth_m = focus_m;
  if (f.on_gpu && f.plan.at(PassId::Dof).on_gpu) {
    // Where the G-buffer lies; the tone map reads its result there (the CPU's colour is unchanged).
    const DofPassSettings& d = dof_.settings();
    BackendSettings peel;
    peel.lod_levels = lod_levels_;
    peel.peel_visibility = !settings_.is("frame.gbuffer_pass", "forward");
    const bool peels = backend_->capabilities().peeling;
    if (d.method == DofMethod::SchedlLayered) {
      gpu_->dof_schedl_layered(FrameTime{now_s, previous_s}, peel, dof_.coc_model(scene_, focus_m), peels ? d.layers : 1u);
    } else if (d.method == DofMethod::LeeSplat) {
      gpu_->dof_lee_splat(FrameTime{now_s, previous_s}, peel, dof_.coc_model(scene_, focus_m), lee_splat_settings(d, peels));
    } else {
      gpu_->dof_lee_mipmap(dof_.coc_model(scene_, focus_m), d.mipmap);
    }
    if (check) {  // the module boundary's check, at the cost of a readback (debug.finite_checks)
      gpu_->read_hdr(gpu_checked_);
      require_finite("dof", "colour (GPU)", gpu_checked_, gbuffer_.width);
    }
    return gbuffer_.color;
  }
  const dof::RgbImage& color = dof_.run(*backend_, scene_, gbuffer_, lod_levels_, focus_m, FrameTime{now_s, previous_s});
  if (check) require_finite("dof", "colour", color, gbuffer_.width);
  f.dof = &color;
  return color;
}

const std::vector<glm::vec3>& FramePipeline::step_gi(Frame& f, const std::vector<glm::vec3>& hdr, double now_s,
                                                     bool check, PassTimer& timer) {
  auto t = timer.scope("gi");
  run_gi(f, hdr, now_s, timer);
  f.gi = &gi_frame_;
  if (gi_gathered_on_gpu_) return hdr;  // gathered where the G-buffer lies; the GPU's tone map composites it
  if (gi_inset_on_gpu_) {  // the GPU's tone map composites the inset over `hdr`
    if (check) require_finite("gi", "GI of the gaze area", gi_pass_->gi_image(), gbuffer_.width);
    return hdr;
  }
  if (check) require_finite("gi", "hybrid colour", hybrid_, gbuffer_.width);
  return hybrid_;
}

void FramePipeline::step_tonemap(Frame& f, const std::vector<glm::vec3>& hdr, PassTimer& timer) {
  auto t = timer.scope("tonemap");
  tonemap(hdr, gbuffer_.width, gbuffer_.height, pass_settings().tonemap, image_);
  f.image = &image_;
}

void FramePipeline::step_overlay(const Frame& f, PassTimer& timer) {
  auto t = timer.scope("overlay");
  const PassSettings& ps = pass_settings();
  const std::string& map = ps.plan.overlay_map;
  if (attention::is_map(map)) {
    if (f.attention != nullptr) {
      draw_attention_map(image_, *f.attention, map);
      draw_attention_mark(image_, *f.attention);
    }
  } else if (map == "coc") {
    const double focus_m = f.dof != nullptr   ? f.focal_depth_m
                           : f.focus != nullptr ? f.focus->focal_depth_m
                                                : scene_.camera.lens.focus_distance_m;
    draw_coc_map(image_, gbuffer_, dof_.coc_model(scene_, focus_m));
  } else if (map != "none") {
    draw_gbuffer_map(image_, gbuffer_, map, scene_.camera.far_m);
  }
  if (f.focus != nullptr && ps.plan.overlay_focus) {
    draw_focus(image_, gbuffer_, f.focus->object, f.focus->focal_depth_m, f.focus->in_transition, f.focus->why);
  }
  if (ps.plan.overlay_gaze && gaze_.available()) {
    draw_gaze(image_, scene_.display, GazeMark{f.gaze.x, f.gaze.y, f.gaze.valid}, ps.gaze_area_deg);
  }
}

// The pixel stage where the G-buffer lies, the object stage here (Lee 2009 §3.2: the top-down
// contexts and the Kalman filter keep per-object state across frames).
const attention::AttentionFrame& FramePipeline::run_attention_on_gpu(double now_s, double previous_s, bool check,
                                                                     const BackendSettings* proxy) {
  const attention::AttentionSettings& wanted = pass_settings().attention;
  if (wanted != attention_.settings()) attention_.set_settings(wanted);
  const auto start = steady_seconds();
  attention_ids_.clear();
  attention_motion_.clear();
  for (const Object& o : scene_.objects) {
    attention_ids_.push_back(o.id);
    attention_motion_.push_back(attention_.object_motion(o, now_s, previous_s));
  }
  const double near_m = scene_.camera.near_m, far_m = scene_.camera.far_m;
  if (proxy != nullptr) {
    gpu_->attention_pixels_on(FrameTime{now_s, previous_s}, *proxy, wanted, near_m, far_m, attention_ids_,
                              attention_motion_, attention_pixels_);
  } else {
    gpu_->attention_pixels(wanted, near_m, far_m, attention_ids_, attention_motion_, attention_pixels_);
  }
  const attention::AttentionFrame& a = attention_.update_objects(attention_pixels_, wanted.map_size, scene_, now_s,
                                                                  previous_s, steady_seconds() - start);
  if (check) {  // the module boundary's check, at the cost of reading the map back (debug.finite_checks)
    gpu_->read_saliency(gpu_saliency_);
    require_finite("attention", "saliency map (GPU)", gpu_saliency_, static_cast<std::uint32_t>(wanted.map_size));
    require_finite_attention(a);
  }
  return a;
}

const attention::AttentionFrame& FramePipeline::run_attention(const GBuffer& g, double now_s, double previous_s,
                                                              bool check) {
  const attention::AttentionSettings& wanted = pass_settings().attention;
  if (wanted != attention_.settings()) attention_.set_settings(wanted);
  const attention::AttentionFrame& a = attention_.update(g, scene_, now_s, previous_s);
  if (check) require_finite_attention(a);
  return a;
}

}  // namespace fovea::render
