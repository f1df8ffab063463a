// SPDX-License-Identifier: Apache-2.0
#include "pipeline/planner.h"

#include "attention/attention.h"
#include "backend/gpu_frame.h"

#include <algorithm>
#include <cstdio>
#include <stdexcept>

namespace fovea::render {

const char* to_string(Resource r) {
  switch (r) {
    case Resource::LodLevels: return "LOD levels";
    case Resource::GBuffer: return "G-buffer";
    case Resource::Attention: return "attention";
    case Resource::FocalDepth: return "focal depth";
    case Resource::HdrColor: return "HDR colour";
    case Resource::GiInset: return "GI inset";
    case Resource::Display: return "display image";
  }
  return "?";
}

const PlanSettings& PlanContext::typed() const {
  if (parsed == nullptr) throw std::logic_error("PlanContext: the plan settings were not parsed (plan_settings)");
  return *parsed;
}

PassDevice parse_device(const std::string& text) {
  return text == "cpu" ? PassDevice::Cpu : text == "gpu" ? PassDevice::Gpu : PassDevice::Auto;
}

PlanSettings plan_settings(const Settings& s) {
  PlanSettings p;
  p.output = s.is("output", "final") ? Resource::Display : Resource::GBuffer;
  p.attention = s.flag("attention.enabled");
  p.attention_device = parse_device(s.text("attention.device"));
  const std::string& mode = s.text("focus.mode");
  p.focus_mode = mode == "fixed"       ? attention::FocusMode::Fixed
                 : mode == "gaze"      ? attention::FocusMode::Gaze
                 : mode == "attention" ? attention::FocusMode::Attention
                                       : attention::FocusMode::GazeAndAttention;
  p.lod = s.flag("lod.enabled");
  p.lod_policy = lod::parse_policy(s.text("lod.policy"));
  p.lod_budget_ms = s.number("lod.budget_ms");
  p.dof = s.flag("dof.enabled");
  p.dof_method = parse_dof_method(s.text("dof.method"));
  p.dof_device = parse_device(s.text("dof.device"));
  p.gi = s.flag("gi.enabled");
  p.gi_caustics = s.flag("gi.caustics");
  p.gi_full_area = s.is("gi.area", "full");
  p.gi_csf_periphery = s.is("gi.periphery", "csf") && !p.gi_full_area;
  p.gi_device = parse_device(s.text("gi.device"));
  p.gi_estimate = s.text("gi.estimate");
  p.gi_strategy = s.text("gi.strategy");
  p.shadows = s.flag("shadows");
  p.overlay_gaze = s.flag("overlay.gaze");
  p.overlay_focus = s.flag("overlay.focus");
  p.overlay_map = s.text("overlay.map");
  return p;
}

namespace {

bool has(const std::vector<Resource>& set, Resource r) { return std::find(set.begin(), set.end(), r) != set.end(); }

// --- When a pass reads an edge (ReadDecl::active) ---------------------------------------------

// Lee 2009 §7.2: with ULOD the attention pass reads its own proxy render, before the G-buffer.
bool lod_ulod(const PlanContext& c) {
  return c.typed().lod && c.scene.has_lods() && c.typed().lod_policy == lod::Policy::Ulod;
}
bool not_lod_ulod(const PlanContext& c) { return !lod_ulod(c); }
bool focus_uses_attention(const PlanContext& c) {
  return c.typed().focus_mode == attention::FocusMode::Attention ||
         c.typed().focus_mode == attention::FocusMode::GazeAndAttention;
}
bool gi_area_follows_attention(const PlanContext& c) { return !c.gaze_available && !c.typed().gi_full_area; }
bool overlay_draws_attention(const PlanContext& c) { return attention::is_map(c.typed().overlay_map); }
bool overlay_draws_focus(const PlanContext& c) { return c.typed().overlay_focus; }
bool dof_filters_the_image(const PlanContext& c) {
  return c.typed().dof_method != DofMethod::Reference && c.typed().dof_method != DofMethod::Accum;
}

PassRule yes(std::string why) { return {true, std::move(why), true, ""}; }
PassRule no(std::string why) { return {false, std::move(why), true, ""}; }

// --- Each pass's rule: is its effect visible in this scene with these settings ----------------

PassRule gbuffer_rule(const PlanContext&) { return yes("every output starts from the G-buffer"); }

// Where a pass with a GPU implementation runs, said in its rule: on the GPU; on the CPU and why
// (where the frame lies on the GPU and `placement_matters`); or unable, for `setting`=gpu where it
// cannot run there. `blocker`: what keeps it off the GPU ("" : nothing).
void place(PassRule& rule, const PlanContext& c, PassDevice device, const char* setting, const std::string& blocker,
           bool placement_matters) {
  const auto say = [&](const std::string& where) { rule.reason += (rule.reason.empty() ? "" : ", ") + where; };
  if (device == PassDevice::Gpu && (!c.gpu_resident || !blocker.empty())) {
    rule.able = false;
    rule.unable = std::string(setting) + "=gpu: " + (c.gpu_resident ? blocker : std::string("the frame is not on the GPU (see where)"));
  } else if (c.gpu_resident && device != PassDevice::Cpu && blocker.empty()) {
    say("on the GPU");
  } else if (c.gpu_resident && placement_matters) {
    say("on the CPU: " + (blocker.empty() ? std::string(setting) + "=cpu" : blocker));
  }
}

// What keeps attention off the GPU in a GPU-resident frame ("" : nothing): with attention.device=auto,
// a software rasteriser (its pixel stage is ~20x slower on llvmpipe than the CPU's SIMD kernels,
// bench/RESULTS.md, more than the readback of colour it saves). With ULOD its proxy is rendered on
// the GPU too.
std::string attention_gpu_blocker(const PlanContext& c) {
  const PlanSettings& t = c.typed();
  if (c.gpu_is_software && t.attention_device == PassDevice::Auto) {
    return "attention.device=auto on a software rasteriser, where the CPU's pixel stage is faster";
  }
  return "";
}

bool attention_on_gpu(const PlanContext& c) {
  return c.gpu_resident && c.typed().attention_device != PassDevice::Cpu && attention_gpu_blocker(c).empty();
}

PassRule attention_rule(const PlanContext& c) {
  if (!c.typed().attention)
    return no("attention.enabled=false (consumers fall back to gaze or defaults)");
  PassRule rule = yes("");
  place(rule, c, c.typed().attention_device, "attention.device", attention_gpu_blocker(c), true);
  return rule;
}

PassRule focus_rule(const PlanContext& c) {
  const attention::FocusMode mode = c.typed().focus_mode;
  if (mode == attention::FocusMode::Fixed) return no("focus.mode=fixed: the lens focus distance is used");
  std::string why = "focus.mode=" + c.settings.text("focus.mode");
  if (mode == attention::FocusMode::Gaze && !c.gaze_available) why += " without a gaze source: the screen centre is used";
  return yes(why);
}

// Only objects with LOD chains can change detail.
PassRule lod_rule(const PlanContext& c) {
  const Settings& s = c.settings;
  const PlanSettings& t = c.typed();
  if (!t.lod) return no("lod.enabled=false");
  if (!c.scene.has_lods()) return no("no object has an LOD chain");
  std::string why = std::string("objects with LOD chains; lod.policy=") + lod::to_string(t.lod_policy);
  if (t.lod_policy == lod::Policy::Gaze && !c.gaze_available) why += " without a gaze source: eccentricity from the screen centre";
  if (t.lod_budget_ms > 0) why += "; frame budget " + s.text("lod.budget_ms") + " ms";
  return yes(why);
}

// What keeps dof off the GPU in a GPU-resident frame ("" : nothing): a method without a GPU
// implementation, or a CPU pass that must see the DOF colour before the tone map (dof would have to
// be read back, which costs what running it on the GPU saves).
std::string dof_gpu_blocker(const PlanContext& c) {
  const PlanSettings& t = c.typed();
  if (!has_gpu_implementation(t.dof_method)) return "dof.method=" + c.settings.text("dof.method") + " has no GPU implementation yet";
  if (t.gi && t.gi_csf_periphery) return "gi.periphery=csf composites GI over the DOF colour on the CPU";
  return "";
}

bool dof_on_gpu(const PlanContext& c) {
  return c.gpu_resident && c.typed().dof_device != PassDevice::Cpu && dof_gpu_blocker(c).empty();
}

bool always(const PlanContext&) { return true; }

// A pinhole lens keeps everything in focus.
PassRule dof_rule(const PlanContext& c) {
  const Settings& s = c.settings;
  const Lens& lens = c.scene.camera.lens;
  if (!c.typed().dof) return no("dof.enabled=false");
  if (lens.is_pinhole()) return no("pinhole lens: nothing is out of focus");
  char why[160];
  const std::string& method = s.text("dof.method");
  std::snprintf(why, sizeof why, "thin lens F=%.1f mm, aperture %.2f mm, method %s", lens.focal_length_m * 1000,
                lens.aperture_m * 1000, method.c_str());
  PassRule rule = yes(why);
  if (c.typed().dof_method == DofMethod::Reference && !c.backend_traces_rays) {
    rule.able = false;
    rule.unable = "the ray-traced reference needs --backend embree (per-pixel lens rays); accum is the raster "
                  "backend's reference";
    return rule;
  }
  place(rule, c, c.typed().dof_device, "dof.device", dof_gpu_blocker(c), dof_filters_the_image(c));
  return rule;
}

// What keeps the GI gather off the GPU in a GPU-resident frame ("" : nothing). Photons are traced on
// the CPU either way; the GPU gathers by radius, from the raster's direct light.
std::string gi_gpu_blocker(const PlanContext& c) {
  const PlanSettings& t = c.typed();
  if (!c.gpu_gi_unavailable.empty()) return c.gpu_gi_unavailable;
  if (t.gi_estimate == "nearest" || t.gi_estimate == "precomputed")
    return "gi.estimate=" + t.gi_estimate + " is the CPU's (the GPU gathers every photon within the radius)";
  if (t.gi_strategy == "gaze-directed" && c.scene.lights.size() > GpuGiGather::kMaxLabelLights)
    return "gi.strategy=gaze-directed with " + std::to_string(c.scene.lights.size()) + " lights: the GPU labels photons of " +
           std::to_string(GpuGiGather::kMaxLabelLights) + " at most";
  if (t.shadows) return "shadows=true: the GPU's direct light has no shadow rays";
  if (t.gi_csf_periphery) return "gi.periphery=csf makes the periphery on the CPU";
  if (c.gpu_is_software && t.gi_device == PassDevice::Auto)
    return "gi.device=auto on a software rasteriser, where the CPU's kd-tree gather is faster";
  return "";
}

bool gi_on_gpu(const PlanContext& c) {
  return c.gpu_resident && c.typed().gi_device != PassDevice::Cpu && gi_gpu_blocker(c).empty();
}

// Only with light to carry; the caustic map only with specular or refractive surfaces to focus it.
PassRule gi_rule(const PlanContext& c) {
  const Settings& s = c.settings;
  const PlanSettings& t = c.typed();
  if (!t.gi) return no("gi.enabled=false");
  if (c.scene.lights.empty()) return no("the scene has no lights: no light to bounce");
  std::string why = "gi.enabled=true, " + std::to_string(c.scene.lights.size()) + " light(s); caustic map: ";
  if (!t.gi_caustics) {
    why += "off (gi.caustics=false)";
  } else if (c.scene.has_specular_or_refractive()) {
    why += "yes (specular or refractive surfaces)";
  } else {
    why += "no (no specular or refractive surface)";
  }
  if (t.gi_full_area) {
    why += "; gi.area=full: the whole screen is ray traced";
  } else if (c.gaze_available) {
    why += "; the " + s.text("gi.gaze_area_deg") + " deg gaze area follows the gaze";
  } else if (t.attention) {
    why += "; no gaze source: the gaze area follows the most attended object";
  } else {
    why += "; no gaze source and attention.enabled=false: the gaze area stays at the screen centre";
  }
  if (t.gi_csf_periphery) why += "; periphery by CSF-driven ray casting (Murphy 2007)";
  if (c.gi_nn_radius_m > 0) {
    char radius[96];
    std::snprintf(radius, sizeof radius, "; radiance estimate radius %.3g m%s", static_cast<double>(c.gi_nn_radius_m),
                  s.is("gi.nn_radius", "auto") ? " (gi.nn_radius=auto: the scene's surfaces and gi.photons)" : "");
    why += radius;
  }
  PassRule rule = yes(why);
  place(rule, c, t.gi_device, "gi.device", gi_gpu_blocker(c), true);
  if (gi_on_gpu(c)) rule.reason += " (the gather; photons traced by Embree on the CPU)";
  return rule;
}

PassRule tonemap_rule(const PlanContext&) { return yes("output=final is a display image"); }

// Something to draw on top of the display image.
PassRule overlay_rule(const PlanContext& c) {
  const PlanSettings& t = c.typed();
  if (t.overlay_map != "none") return yes("overlay.map=" + t.overlay_map);
  if (t.overlay_gaze && c.gaze_available) return yes("overlay.gaze=true and a gaze source is connected");
  if (t.overlay_focus && t.focus_mode != attention::FocusMode::Fixed) return yes("overlay.focus=true");
  return no(!t.overlay_gaze ? "overlay.gaze=false and overlay.map=none"
                                         : "no gaze source (--gaze none) and overlay.map=none");
}

// --- What each pass reads of the frame's G-buffer (PassDecl::gbuffer_reads) --------------------

bool ulod_attention_first(const FramePlan& plan, const PlanSettings& s) {
  return plan.runs(PassId::LodSelect) && plan.runs(PassId::Attention) && s.lod_policy == lod::Policy::Ulod;
}
// Saliency (luminance, hue), depth and ids; motion comes from the objects' transforms. With ULOD the
// pass reads its own proxy render instead (Lee 2009 §7.2).
GBufferPlanes attention_reads(const FramePlan& plan, const PlanSettings& s) {
  return ulod_attention_first(plan, s) ? GBufferPlanes{} : GBufferPlanes{.color = true, .depth = true, .object_id = true};
}
GBufferPlanes focus_reads(const FramePlan&, const PlanSettings&) { return {.depth = true, .object_id = true}; }
// With attention the objects' depths come from its frame, so focus reads only the pixels around the
// points it looks at; without it an object's depth is the median of its pixels over the whole image.
const char* focus_looks_with_attention(const FramePlan& plan, const PlanSettings&) {
  return plan.runs(PassId::Attention) ? "only the pixels it looks at" : nullptr;
}
// Brown's policy: the last frame's colour and ids (each object's luminance contrast); ULOD's blend:
// this frame's colour and ids (where they lie: lod_blends_where_the_gbuffer_lies). The other
// policies read nothing of the G-buffer.
GBufferPlanes lod_reads(const FramePlan&, const PlanSettings& s) {
  return s.lod_policy == lod::Policy::Brown || s.lod_policy == lod::Policy::Ulod
             ? GBufferPlanes{.color = true, .object_id = true}
             : GBufferPlanes{};
}
const char* lod_blends_where_the_gbuffer_lies(const FramePlan&, const PlanSettings& s) {
  return s.lod_policy == lod::Policy::Ulod ? "ULOD's blend where the G-buffer lies" : nullptr;
}
// The image-space methods filter colour by depth; the references render the scene again.
GBufferPlanes dof_reads(const FramePlan&, const PlanSettings& s) {
  return s.dof_method == DofMethod::Reference || s.dof_method == DofMethod::Accum ? GBufferPlanes{}
                                                                        : GBufferPlanes{.color = true, .depth = true};
}
// gi on the CPU: nothing (it traces its own rays; its inset is composited over the HDR colour where
// that lies). Gathering on the GPU: depth, ids and normals where they lie (the colour is always
// written), and the ids and depth of the area's box read back for the pixels the CPU traces.
GBufferPlanes gi_reads(const FramePlan& plan, const PlanSettings&) {
  return plan.at(PassId::Gi).on_gpu ? GBufferPlanes{.depth = true, .object_id = true, .normal = true} : GBufferPlanes{};
}
const char* gi_gathers_where_the_gbuffer_lies(const FramePlan& plan, const PlanSettings&) {
  return plan.at(PassId::Gi).on_gpu ? "the area's ids and depth, for the pixels it traces" : nullptr;
}
GBufferPlanes tonemap_reads(const FramePlan&, const PlanSettings&) { return {.color = true}; }
// The focus outline (ids) or iso-depth line (depth); G-buffer maps read every plane.
GBufferPlanes overlay_reads(const FramePlan& plan, const PlanSettings& s) {
  GBufferPlanes r;
  if (s.overlay_map != "none") r = GBufferPlanes::all();
  if (plan.runs(PassId::Focus) && s.overlay_focus) r = r | GBufferPlanes{.depth = true, .object_id = true};
  return r;
}

}  // namespace

// "overlay.map=saliency|spatial|temporal|attention", from the one list of attention maps.
const char* attention_overlay_values() {
  static const std::string kWhen = [] {
    std::string out = "overlay.map=";
    for (std::size_t i = 0; i < attention::kMaps.size(); ++i) out += (i ? "|" : "") + std::string(attention::kMaps[i]);
    return out;
  }();
  return kWhen.c_str();
}

const std::vector<PassDecl>& pass_declarations() {
  using R = Resource;
  static const std::vector<PassDecl> kPasses = {
      {PassId::GBuffer, "gbuffer", {{R::LodLevels}}, {R::GBuffer, R::HdrColor}, "scene, camera, time", gbuffer_rule,
       nullptr, always},
      {PassId::Attention, "attention",
       {{R::GBuffer, "unless lod.policy=ulod (then its own proxy render)", not_lod_ulod}}, {R::Attention},
       "scene (object and observer motion, task importance)", attention_rule, attention_reads, attention_on_gpu, true},
      {PassId::Focus, "focus",
       {{R::GBuffer}, {R::Attention, "focus.mode=attention|gaze+attention", focus_uses_attention}}, {R::FocalDepth},
       "gaze", focus_rule, focus_reads, nullptr, true, focus_looks_with_attention},
      {PassId::LodSelect, "lod-select", {{R::Attention, "lod.policy=ulod", lod_ulod}}, {R::LodLevels},
       "camera, gaze, the last frame's G-buffer", lod_rule, lod_reads, nullptr, false, lod_blends_where_the_gbuffer_lies},
      {PassId::Dof, "dof",
       {{R::HdrColor}, {R::FocalDepth}, {R::GBuffer, "an image-space dof.method", dof_filters_the_image}},
       {R::HdrColor}, "the lens", dof_rule, dof_reads, dof_on_gpu},
      {PassId::Gi, "gi",
       {{R::HdrColor}, {R::Attention, "no gaze source (its gaze area)", gi_area_follows_attention}}, {R::GiInset},
       "scene (its own rays), gaze", gi_rule, gi_reads, gi_on_gpu, false, gi_gathers_where_the_gbuffer_lies},
      {PassId::Tonemap, "tonemap", {{R::HdrColor}, {R::GiInset}}, {R::Display}, "tonemap.*", tonemap_rule,
       tonemap_reads, always},
      {PassId::Overlay, "overlay",
       {{R::Display},
        {R::GBuffer},
        {R::Attention, attention_overlay_values(), overlay_draws_attention},
        {R::FocalDepth, "overlay.focus=true", overlay_draws_focus}},
       {R::Display}, "gaze", overlay_rule, overlay_reads, always},
  };
  return kPasses;
}

const PassDecl& declaration(PassId id) { return pass_declarations().at(static_cast<std::size_t>(id)); }

bool FramePlan::runs(PassId id) const { return at(id).runs; }
bool FramePlan::needed(PassId id) const { return at(id).needed; }
const PlannedPass& FramePlan::at(PassId id) const { return passes.at(static_cast<std::size_t>(id)); }

namespace {

std::string join(const std::vector<std::string>& parts, const char* sep = ", ") {
  std::string out;
  for (const std::string& p : parts) out += (out.empty() ? "" : sep) + p;
  return out;
}

std::string names(const std::vector<Resource>& resources) {
  std::vector<std::string> parts;
  for (Resource r : resources) parts.emplace_back(to_string(r));
  return join(parts);
}

// One edge of the graph as built: `consumer` reads `resource`, which `producer` writes.
struct Edge {
  PassId producer, consumer;
  const ReadDecl* read;
};

// Every edge out of `p` with these settings (a pass reading what it writes itself, as dof and the
// overlay do, is not its own consumer).
std::vector<Edge> edges_out(const PassDecl& p, const PlanContext& c) {
  std::vector<Edge> out;
  for (const PassDecl& q : pass_declarations()) {
    if (q.id == p.id) continue;
    for (const ReadDecl& r : q.reads)
      if (has(p.writes, r.resource) && r.reads(c)) {
        out.push_back({p.id, q.id, &r});
        break;
      }
  }
  return out;
}

// The least fixed point of "keep(p) = admit(p) and (p writes the output, or a kept pass reads what p
// writes)": from the output backwards, so a chain of passes that only feed each other is culled.
std::vector<bool> keep_from_output(const PlanContext& c, const std::vector<bool>& admit) {
  std::vector<bool> keep(pass_declarations().size(), false);
  for (bool changed = true; changed;) {
    changed = false;
    for (const PassDecl& p : pass_declarations()) {
      const auto i = static_cast<std::size_t>(p.id);
      if (keep[i] || !admit[i]) continue;
      bool consumed = has(p.writes, c.output());
      for (const Edge& e : edges_out(p, c)) consumed = consumed || keep[static_cast<std::size_t>(e.consumer)];
      if (consumed) keep[i] = changed = true;
    }
  }
  return keep;
}

// Why nothing consumes what `p` writes: each pass that could read it, and why it does not here.
std::string unconsumed(const PassDecl& p, const PlanContext& c) {
  std::vector<std::string> why;
  const bool could_be_output = has(p.writes, Resource::Display) || has(p.writes, Resource::GBuffer);
  if (could_be_output && !has(p.writes, c.output()))
    why.push_back(c.output() == Resource::GBuffer ? "output=gbuffer" : "output=final");
  for (const PassDecl& q : pass_declarations()) {
    if (q.id == p.id) continue;
    for (const ReadDecl& r : q.reads) {
      if (!has(p.writes, r.resource)) continue;
      why.push_back(!r.reads(c) ? std::string(q.name) + " reads it only with " + r.when
                                : std::string(q.name) + " is not needed");
      break;
    }
  }
  return "nothing consumes " + names(p.writes) + (why.empty() ? "" : ": " + join(why));
}

// "dof, overlay (overlay.focus=true)": the needed passes that read what `p` writes.
std::string consumers(const PassDecl& p, const PlanContext& c, const FramePlan& plan) {
  std::vector<std::string> parts;
  for (const Edge& e : edges_out(p, c)) {
    if (!plan.needed(e.consumer)) continue;
    const std::string when = *e.read->when != '\0' && e.read->active != nullptr ? " (" + std::string(e.read->when) + ")" : "";
    parts.push_back(declaration(e.consumer).name + when);
  }
  return join(parts);
}

// Needed passes whose outputs no running pass reads yet ("dof does not run yet").
std::string waiting_on(const PassDecl& p, const PlanContext& c, const FramePlan& plan) {
  std::vector<std::string> parts;
  for (const Edge& e : edges_out(p, c))
    if (plan.needed(e.consumer) && !plan.runs(e.consumer)) parts.emplace_back(declaration(e.consumer).name);
  return join(parts) + (parts.size() == 1 ? " does not run yet" : " do not run yet");
}

}  // namespace

// The graph, built from the declarations: each pass's rule says whether its effect is visible and
// whether it can run; a pass is needed when its effect is wanted and the output depends on what it
// writes through needed passes; it runs when it is needed, able, and some pass that runs (or the
// output) reads what it writes. Needed passes that cannot run are "later"; needed passes whose
// consumers cannot run wait.
FramePlan plan_frame(const PlanContext& given) {
  PlanSettings parsed;
  PlanContext c = given;
  if (c.parsed == nullptr) {  // a caller that does not keep them parsed (tests, one-off plans)
    parsed = plan_settings(given.settings);
    c.parsed = &parsed;
  }
  const std::vector<PassDecl>& decls = pass_declarations();
  FramePlan plan;
  plan.output = c.output();
  std::vector<PassRule> rules;
  std::vector<bool> wanted, runnable;
  for (const PassDecl& d : decls) {
    rules.push_back(d.rule(c));
    wanted.push_back(rules.back().wanted);
    runnable.push_back(rules.back().wanted && rules.back().able);
  }
  const std::vector<bool> needed = keep_from_output(c, wanted);
  const std::vector<bool> runs = keep_from_output(c, runnable);
  for (const PassDecl& d : decls) {
    const auto i = static_cast<std::size_t>(d.id);
    PlannedPass p{d.id, needed[i], runs[i], "", {}, c.gpu_resident && d.on_gpu != nullptr && d.on_gpu(c), {}, ""};
    for (const ReadDecl& r : d.reads)
      if (r.reads(c)) p.reads.push_back(r.resource);
    plan.passes.push_back(std::move(p));
  }
  for (const PassDecl& d : decls) {
    const auto i = static_cast<std::size_t>(d.id);
    PlannedPass& p = plan.passes[i];
    const PassRule& rule = rules[i];
    bool consumed = has(d.writes, c.output());
    for (const Edge& e : edges_out(d, c)) consumed = consumed || needed[static_cast<std::size_t>(e.consumer)];
    if (!consumed) {
      p.reason = unconsumed(d, c);
    } else if (!rule.wanted) {
      p.reason = rule.reason;
    } else {
      p.reason = rule.reason;
      if (d.names_consumers) {
        const std::string by = consumers(d, c, plan);
        if (!by.empty()) p.reason = "consumed by " + by + (rule.reason.empty() ? "" : "; " + rule.reason);
      }
      if (!rule.able) {
        p.reason += " — " + rule.unable;
      } else if (!p.runs) {
        p.reason += "; waits: " + waiting_on(d, c, plan);
      }
    }
  }
  for (PlannedPass& pass : plan.passes) {
    const PassDecl& d = declaration(pass.id);
    if (pass.runs && d.gbuffer_reads != nullptr) pass.gbuffer_reads = d.gbuffer_reads(plan, c.typed());
    const char* where = pass.runs && d.reads_where_the_gbuffer_lies != nullptr
                            ? d.reads_where_the_gbuffer_lies(plan, c.typed())
                            : nullptr;
    if (where != nullptr) pass.reads_where_the_gbuffer_lies = where;
  }
  return plan;
}

std::string FramePlan::explain() const {
  std::string out;
  for (const PlannedPass& p : passes) {
    const PassDecl& d = declaration(p.id);
    char line[768];
    // "later": the output needs the pass but it cannot run with these settings (the reason says why).
    const char* verdict = p.runs ? "run " : (p.needed ? "later" : "skip");
    std::snprintf(line, sizeof line, "  %-5s %-10s %s\n", verdict, d.name, p.reason.c_str());
    out += line;
  }
  out += "  graph      (the passes that run: what each reads -> what it writes; the output: ";
  out += to_string(output);
  out += ")\n";
  std::vector<Resource> made;  // by a pass that runs: only these edges exist this frame
  for (const PlannedPass& p : passes)
    if (p.runs) made.insert(made.end(), declaration(p.id).writes.begin(), declaration(p.id).writes.end());
  for (const PlannedPass& p : passes) {
    if (!p.runs) continue;
    const PassDecl& d = declaration(p.id);
    std::vector<std::string> in;
    for (Resource r : p.reads) {
      if (!has(made, r)) continue;
      if (r != Resource::GBuffer) {
        in.emplace_back(to_string(r));
      } else if (p.gbuffer_reads.any()) {
        in.push_back("G-buffer " + to_string(p.gbuffer_reads));
      }
    }
    in.emplace_back(d.inputs);
    out += "    " + std::string(d.name) + ": " + join(in, "; ") + " -> " + names(d.writes) + "\n";
  }
  if (!placement.empty()) out += "  where " + placement + "\n";
  return out;
}

GBufferPlanes planes_read_on_cpu(const FramePlan& plan) {
  GBufferPlanes r;
  for (const PlannedPass& p : plan.passes) {
    if (p.runs && !p.on_gpu && p.reads_where_the_gbuffer_lies.empty()) r = r | p.gbuffer_reads;
  }
  return r;
}

GBufferPlanes planes_read(const FramePlan& plan) {
  GBufferPlanes r;
  for (const PlannedPass& p : plan.passes) {
    if (p.runs) r = r | p.gbuffer_reads;
  }
  return r;
}

}  // namespace fovea::render
