#include "pipeline/frame_pipeline.h"

#include "passes/tonemap.h"

namespace fovea::render {

FramePipeline::FramePipeline(Scene scene, Settings settings, std::unique_ptr<Backend> backend, GazeInput& gaze)
    : scene_(std::move(scene)), settings_(std::move(settings)), backend_(std::move(backend)), gaze_(gaze) {
  backend_->set_scene(scene_);
}

FramePlan FramePipeline::plan() const { return plan_frame(PlanContext{scene_, settings_, gaze_.available()}); }

FramePipeline::Frame FramePipeline::render(std::uint64_t frame_index, double now_s, double previous_s,
                                           double frame_clock_s, PassTimer& timer) {
  timer.begin_frame(frame_index, now_s);
  auto whole = timer.scope("frame");
  Frame f;
  f.plan = plan();
  {
    auto t = timer.scope("gaze");
    f.gaze = gaze_.at(frame_clock_s);
  }
  {
    auto t = timer.scope("gbuffer");
    BackendSettings bs;
    bs.shadows = settings_.flag("shadows");
    backend_->render(FrameTime{now_s, previous_s}, bs, gbuffer_);
  }
  f.gbuffer = &gbuffer_;
  // attention, focus, lod-select, dof and gi arrive with steps 6-9; the plan says when they would run.
  if (f.plan.runs(PassId::Tonemap)) {
    auto t = timer.scope("tonemap");
    TonemapParams p;
    p.exposure = static_cast<float>(settings_.number("tonemap.exposure"));
    p.op = settings_.text("tonemap.operator");
    p.exact = settings_.flag("tonemap.exact");
    tonemap(gbuffer_.color, gbuffer_.width, gbuffer_.height, p, image_);
    f.image = &image_;
  }
  if (f.plan.runs(PassId::Overlay)) {
    auto t = timer.scope("overlay");
    const std::string& map = settings_.text("overlay.map");
    if (map != "none") draw_gbuffer_map(image_, gbuffer_, map, scene_.camera.far_m);
    if (settings_.flag("overlay.gaze") && gaze_.available()) {
      const double area = settings_.flag("gi.enabled") ? settings_.number("gi.gaze_area_deg") : 0.0;
      draw_gaze(image_, scene_.display, GazeMark{f.gaze.x, f.gaze.y, f.gaze.valid}, area);
    }
  }
  return f;
}

}  // namespace fovea::render
