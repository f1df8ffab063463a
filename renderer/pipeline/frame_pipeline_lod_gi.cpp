// SPDX-License-Identifier: Apache-2.0
// The frame pipeline's two passes that keep state of their own across frames beside the G-buffer:
// level-of-detail selection (with ULOD's blend) and the gi pass (frame_pipeline.h).
#include <algorithm>
#include <cmath>
#include <limits>

#include "backend/embree/embree_backend.h"
#include "pipeline/frame_pipeline.h"
#include "pipeline/gi_gather_input.h"

namespace fovea::render {

// Where GI is ray traced: around the gaze point, else the most attended object, else the screen
// centre; or everything (gi.area=full).
void FramePipeline::place_gi_area(const Frame& f) {
  const Settings& s = settings_;
  const Camera& cam = scene_.camera;
  const bool full = s.is("gi.area", "full");
  glm::vec2 centre(0.5f);
  if (full) {
    gi_frame_.follows = "full screen";
  } else if (gaze_.available()) {
    centre = {static_cast<float>(f.gaze.x), static_cast<float>(f.gaze.y)};
    gi_frame_.follows = "gaze";
  } else if (f.attention != nullptr && !f.attention->objects.empty()) {
    const attention::ObjectAttention& top = f.attention->objects.front();
    double x = top.screen_x;
    if (f.eye == Eye::Right) {  // the left eye's attention frame: the object where the right eye sees it
      Camera left = cam;
      left.eye_offset_m = -cam.eye_offset_m;
      x += cam.eye_shift_x(top.depth_m) - left.eye_shift_x(top.depth_m);
    }
    centre = {static_cast<float>(x), static_cast<float>(top.screen_y)};
    gi_frame_.follows = "attention";
  } else {
    gi_frame_.follows = "screen centre";
  }
  if (full) {
    gi_frame_.area.center_px = {0.5f * static_cast<float>(cam.width), 0.5f * static_cast<float>(cam.height)};
    gi_frame_.area.radius_px = 0.5f * std::hypot(static_cast<float>(cam.width), static_cast<float>(cam.height)) + 1.0f;
  } else {
    gi_frame_.area = gi::gaze_area(scene_.display, cam.width, cam.height, centre, s.number("gi.gaze_area_deg"));
  }
}

void FramePipeline::run_gi(const Frame& f, const std::vector<glm::vec3>& local, double now_s, PassTimer& timer) {
  if (!gi_pass_) {
    // One instance of the scene in Embree: the frame's own when it ray traces (its BVH, its levels of
    // detail), else a ray tracer beside the raster backend.
    gi_tracer_ = dynamic_cast<EmbreeBackend*>(backend_.get());
    if (gi_tracer_ != nullptr) {
      gi_pass_ = std::make_unique<gi::GiPass>(*gi_tracer_);
    } else {
      gi_pass_ = std::make_unique<gi::GiPass>();
      gi_pass_->set_scene(scene_);
    }
  }
  // The frame's levels, whatever the backend rendered last (ULOD's next-coarser levels, a peeled layer).
  if (gi_tracer_ != nullptr) gi_tracer_->set_lod_levels(lod_levels_);
  gi_frame_ = Frame::Gi{};
  place_gi_area(f);
  const Camera& cam = scene_.camera;
  gi::GiPassSettings gs = pass_settings().gi;
  // On the GPU-resident path the inset is composited on the GPU (the tone map's input), unless the
  // CSF periphery replaces the local image, which is then made on the CPU anyway. With gi.device the
  // GPU gathers it too: the CPU traces the photons and the pixels the G-buffer cannot answer.
  gi_gathered_on_gpu_ = f.on_gpu && f.plan.at(PassId::Gi).on_gpu;
  gi_inset_on_gpu_ = f.on_gpu && !gs.csf_periphery;
  gs.composite = !gi_inset_on_gpu_;
  if (gi_gathered_on_gpu_) {
    gs.render.estimate.fixed_radius = gs.render.caustic_estimate.fixed_radius = true;
    gs.render.skip_gbuffer_pixels = true;
    gs.overlap = gs.overlap || settings_.is("gi.overlap", "auto");
    gs.defer_gaze_finish = true;  // the GPU's labels first (gather_gi_on_gpu)
  }
  gi_fovea_ = gs.fovea;
  // A stereo frame traces the photon maps once, for the left eye (GiPassSettings::keep_maps).
  gs.keep_maps = f.eye == Eye::Left;
  gs.reuse_maps = f.eye == Eye::Right && shared_.gi;
  // The frame's G-buffer holds the area's first hits when the frame's backend is the GI's ray tracer.
  const GBuffer* primary =
      gi_tracer_ != nullptr && !f.on_gpu && settings_.is("debug.gi_first_hits", "gbuffer") ? &gbuffer_ : nullptr;
  if (gi_gathered_on_gpu_) primary = &read_gi_area_ids(gi_frame_.area, timer);
  const gi::GiPassResult& r = gi_pass_->run(cam, now_s, gi_frame_.area, gs, local, hybrid_, primary);
  if (gi_gathered_on_gpu_) gather_gi_on_gpu(gs, now_s, timer);
  if (f.eye == Eye::Left) shared_.gi = true;
  if (!gs.reuse_maps) {
    timer.record("gi.photons", r.photons_ms);  // with overlap: the wait for the worker
    if (r.overlapped) {
      timer.record("gi.photons_overlapped", r.overlapped_trace_ms);
    } else {
      timer.record("gi.index", r.index_ms);
    }
    if (gs.render.indirect_estimate == gi::IndirectEstimate::Precomputed) timer.record("gi.precompute", r.precompute_ms);
  }
  timer.record("gi.render", r.render_ms);
  timer.record("gi.composite", r.composite_ms);
  if (gs.csf_periphery) timer.record("gi.periphery", r.periphery_ms);
  gi_frame_.csf = r.csf;
  gi_frame_.strategy = gi::to_string(r.strategy);
  gi_frame_.render = r.render;
  if (gi_gathered_on_gpu_) {  // gi.csv's pixels: the area's, the GPU's and the CPU's; rays stay the CPU's
    const gi::PixelBox box = gi::pixel_box(gi_frame_.area, cam.width, cam.height);
    std::uint64_t pixels = 0;
    for (std::uint32_t y = box.y0; y < box.y1; ++y)
      for (std::uint32_t x = box.x0; x < box.x1; ++x)
        pixels += gi_frame_.area.contains(static_cast<float>(x) + 0.5f, static_cast<float>(y) + 0.5f) ? 1u : 0u;
    gi_frame_.render.pixels = pixels;
  }
  gi_frame_.gaze = r.gaze;
  gi_frame_.photons = r.photons;
  gi_frame_.caustic_photons = r.caustic_photons;
  gi_frame_.importons = r.importons;
  gi_frame_.emitted = r.emitted;
  gi_frame_.note = r.note;
}

const GBuffer& FramePipeline::read_gi_area_ids(const gi::GazeArea& area, PassTimer& timer) {
  auto t = timer.scope("gi.ids");
  const Camera& cam = scene_.camera;
  GBuffer& g = gi_area_ids_;
  if (g.width != cam.width || g.height != cam.height) {
    g.width = cam.width;
    g.height = cam.height;
    g.depth.assign(g.size(), 0.0f);
    g.object_id.assign(g.size(), 0);
  }
  // The circle's pixel rows and columns, as render_gaze_area visits them; the rest stays stale (unread).
  const gi::PixelBox box = gi::pixel_box(area, cam.width, cam.height);
  const std::uint32_t x0 = box.x0, x1 = box.x1, y0 = box.y0, y1 = box.y1;
  if (x1 <= x0 || y1 <= y0) return g;
  gpu_->read_rect(x0, y0, x1, y1, gi_rect_depth_, gi_rect_ids_);
  const std::uint32_t w = x1 - x0;
  for (std::uint32_t y = y0; y < y1; ++y)
    for (std::uint32_t x = x0; x < x1; ++x) {
      const std::size_t from = std::size_t{y - y0} * w + (x - x0);
      g.depth[g.index(x, y)] = gi_rect_depth_[from];
      g.object_id[g.index(x, y)] = gi_rect_ids_[from];
    }
  return g;
}

void FramePipeline::gather_gi_on_gpu(const gi::GiPassSettings& gs, double now_s, PassTimer& timer) {
  auto t = timer.scope("gi.gather");
  const gi::PhotonMaps& maps = gi_pass_->maps();
  pack_gpu_photons(maps.indirect, gi_photons_[0], gi_photon_index_[0]);
  pack_gpu_photons(maps.caustics, gi_photons_[1], gi_photon_index_[1]);
  GpuGiGather g = gi_gather_input(scene_, scene_.camera, now_s, gi_frame_.area, gs.fovea, gs.render.ambient);
  const auto map_of = [](const std::vector<GpuPhoton>& photons, const gi::EstimateSettings& e, bool on) {
    return GpuGiGather::Map{on ? &photons : nullptr, e.max_radius, e.filter == gi::EstimateFilter::Cone, e.cone_k};
  };
  g.indirect = map_of(gi_photons_[0], gs.render.estimate, gs.render.indirect);
  g.caustic = map_of(gi_photons_[1], gs.render.caustic_estimate, gs.render.caustics);
  g.traced = &gi_pass_->gi_image();
  // The gaze-directed mapper steers the next frame by the photons this one used (§8.4.4).
  g.label = gs.strategy == gi::Strategy::GazeDirected || gs.label_gaze_photons;
  gpu_->gi_gather(g);
  if (!g.label) return;
  auto wait = timer.scope("gi.labels");
  std::vector<std::uint8_t> used;
  std::vector<double> traditional, gaze;
  gpu_->read_gi_labels(used, traditional, gaze);
  std::vector<std::uint32_t> photons;
  for (std::size_t i = 0; i < used.size() && i < gi_photon_index_[0].size(); ++i)
    if (used[i] != 0) photons.push_back(gi_photon_index_[0][i]);
  gi_pass_->add_labels(photons, traditional, gaze);
  if (!gs.keep_maps) gi_pass_->finish_gaze_frame();
}

void FramePipeline::blend_ulod(const FrameTime& time, const BackendSettings& drawn) {
  // Lee 2009 §7.3 with Giegl et al.'s unpopping LOD: each object is drawn at floor(L) and at the next
  // level, and the two images are blended by frac(L), so a continuous L never pops between levels.
  // One more G-buffer render when any object is between levels.
  BackendSettings next = drawn;
  if (!lod::ulod_next_levels(scene_, lod_frame_.selection, next.lod_levels)) return;
  lod::ulod_pixel_mask(gbuffer_, lod_frame_.selection, next.pixel_mask);
  next.readback = {.color = true, .object_id = true};  // the blend reads nothing else
  backend_->render(time, next, ulod_next_);
  lod::ulod_blend(gbuffer_, ulod_next_, lod_frame_.selection);
}

// blend_ulod where the frame lies: the next levels drawn aside on the GPU and blended there, so the
// G-buffer's colour is the blended one for every later pass and nothing is read back or uploaded.
void FramePipeline::blend_ulod_on_gpu(const FrameTime& time, const BackendSettings& drawn) {
  BackendSettings next = drawn;
  if (!lod::ulod_next_levels(scene_, lod_frame_.selection, next.lod_levels)) return;
  ulod_ids_.clear();
  ulod_factors_.clear();
  for (const lod::Selection& sel : lod_frame_.selection) {
    if (!(sel.blend > 0) || sel.blend_to == sel.drawn) continue;
    ulod_ids_.push_back(sel.id);
    ulod_factors_.push_back(static_cast<float>(std::clamp(sel.blend, 0.0, 1.0)));
  }
  gpu_->ulod_blend(time, next, ulod_ids_, ulod_factors_);
}

void FramePipeline::run_lod_select(const GazeState& gaze, double now_s, double previous_s, double last_frame_ms) {
  const PassSettings& parsed = pass_settings();
  const lod::PolicySettings& ps = parsed.lod;
  lod_selector_.set_settings(ps);
  if (lod_selector_.budget().target_ms != parsed.lod_budget_ms) lod_selector_.set_budget_ms(parsed.lod_budget_ms);
  lod_frame_ = Frame::Lod{};
  lod_frame_.policy = lod::to_string(ps.policy);
  const attention::AttentionFrame& att = attention_.last();
  lod::ViewInputs in;
  in.now_s = now_s;
  in.previous_s = previous_s;
  in.gaze_x = gaze.x;
  in.gaze_y = gaze.y;
  // Only Brown's policy reads the last frame (luminance contrast); the planner reads its colour and
  // ids back for it on the GPU path, and only for it.
  in.last_frame = ps.policy == lod::Policy::Brown ? &gbuffer_ : nullptr;
  in.attention = [&att](std::uint32_t id) {
    for (const attention::ObjectAttention& a : att.objects)
      if (a.id == id) return a.attention;
    return 0.0;
  };
  std::vector<std::size_t> object_of;
  const std::vector<lod::ObjectView> views = lod::object_views(scene_, in, lod_bounds_, object_of);
  // ULOD: S_o relative to the frame's most attended object, whether it has a chain or not.
  const double top_attention = att.objects.empty() ? std::numeric_limits<double>::quiet_NaN() : att.objects.front().attention;
  lod_selector_.set_in_saccade(gaze.in_saccade);
  const std::vector<lod::Selection>& sel = lod_selector_.select(views, last_frame_ms, top_attention);
  lod_levels_.assign(scene_.objects.size(), 0);
  for (std::size_t k = 0; k < sel.size(); ++k) {
    const std::size_t i = object_of[k];
    lod_levels_[i] = static_cast<std::uint8_t>(std::clamp(sel[k].drawn, 0, 255));
    lod_frame_.triangles += views[k].level_triangles[static_cast<std::size_t>(std::clamp(sel[k].drawn, 0, views[k].levels - 1))];
    lod_frame_.full_triangles += views[k].level_triangles[0];
  }
  lod_frame_.selection = sel;
  lod_frame_.budget = lod_selector_.budget();
  lod_frame_.switches = lod_selector_.switches();
}

}  // namespace fovea::render
