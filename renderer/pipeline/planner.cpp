#include "pipeline/planner.h"

#include "attention/attention.h"

#include <cstdio>
#include <stdexcept>

namespace fovea::render {

namespace {

// What each pass reads of the frame's G-buffer (PassDecl::gbuffer_reads).
bool ulod_attention_first(const FramePlan& plan, const Settings& s) {
  return plan.runs(PassId::LodSelect) && plan.runs(PassId::Attention) && s.is("lod.policy", "ulod");
}
// Saliency (luminance, hue), depth and ids; motion comes from the objects' transforms. With ULOD the
// pass reads its own proxy render instead (Lee 2009 §7.2).
GBufferPlanes attention_reads(const FramePlan& plan, const Settings& s) {
  return ulod_attention_first(plan, s) ? GBufferPlanes{} : GBufferPlanes{.color = true, .depth = true, .object_id = true};
}
GBufferPlanes focus_reads(const FramePlan&, const Settings&) { return {.depth = true, .object_id = true}; }
// The last frame's colour and ids (screen coverage); ULOD blends colour by id.
GBufferPlanes lod_reads(const FramePlan&, const Settings&) { return {.color = true, .object_id = true}; }
// The image-space methods filter colour by depth; the references render the scene again.
GBufferPlanes dof_reads(const FramePlan&, const Settings& s) {
  return s.is("dof.method", "reference") || s.is("dof.method", "accum") ? GBufferPlanes{}
                                                                        : GBufferPlanes{.color = true, .depth = true};
}
// gi: nothing. It traces its own rays; its inset is composited over the HDR colour where that lies.
GBufferPlanes tonemap_reads(const FramePlan&, const Settings&) { return {.color = true}; }
// The focus outline (ids) or iso-depth line (depth); G-buffer maps read every plane.
GBufferPlanes overlay_reads(const FramePlan& plan, const Settings& s) {
  GBufferPlanes r;
  if (!s.is("overlay.map", "none")) r = GBufferPlanes::all();
  if (plan.runs(PassId::Focus) && s.flag("overlay.focus")) r = r | GBufferPlanes{.depth = true, .object_id = true};
  return r;
}

}  // namespace

const std::vector<PassDecl>& pass_declarations() {
  static const std::vector<PassDecl> kPasses = {
      {PassId::GBuffer, "gbuffer", "scene, camera, time", "colour, depth, id, normal, motion",
       "always: every output starts from it", nullptr, true},
      {PassId::Attention, "attention", "scene (object and observer motion, task importance)",
       "per-object attention S_o, saliency maps",
       "focus, lod-select or an attention overlay (overlay.map=saliency|spatial|temporal|attention) consume it",
       attention_reads},
      {PassId::Focus, "focus", "gaze, attention", "focal depth",
       "dof runs or overlay.focus shows it, and focus is not fixed", focus_reads},
      {PassId::LodSelect, "lod-select", "camera, gaze, the last frame's attention (and its G-buffer)", "LOD level per object",
       "the scene has LOD chains and lod.enabled", lod_reads},
      {PassId::Dof, "dof", "focal depth", "HDR colour", "a thin lens with an aperture and dof.enabled",
       dof_reads},
      {PassId::Gi, "gi", "scene (its own rays), gaze (or attention)", "the gaze area's GI (composited over the HDR colour)",
       "gi.enabled and the scene has lights"},
      {PassId::Tonemap, "tonemap", "HDR colour (the G-buffer's, dof's), the GI inset", "display image (sRGB 8-bit)",
       "the output is an image", tonemap_reads,
       true},
      {PassId::Overlay, "overlay", "display image, gaze, maps", "display image",
       "overlay.gaze with a gaze source, or overlay.map", overlay_reads, true},
  };
  return kPasses;
}

const PassDecl& declaration(PassId id) { return pass_declarations().at(static_cast<std::size_t>(id)); }

bool FramePlan::runs(PassId id) const { return at(id).runs; }
bool FramePlan::needed(PassId id) const { return at(id).needed; }
const PlannedPass& FramePlan::at(PassId id) const { return passes.at(static_cast<std::size_t>(id)); }

std::string FramePlan::explain() const {
  std::string out;
  for (const PlannedPass& p : passes) {
    const PassDecl& d = declaration(p.id);
    char line[512];
    // "later": the output needs the pass but it cannot run with these settings (the reason says why).
    const char* verdict = p.runs ? "run " : (p.needed ? "later" : "skip");
    std::snprintf(line, sizeof line, "  %-5s %-10s %s\n", verdict, d.name, p.reason.c_str());
    out += line;
  }
  out += "  graph      (the passes that run: what each reads -> what it writes)\n";
  for (const PlannedPass& p : passes) {
    if (!p.runs) continue;
    const PassDecl& d = declaration(p.id);
    const std::string gbuffer = p.gbuffer_reads.any() ? "G-buffer " + to_string(p.gbuffer_reads) + "; " : "";
    out += "    " + std::string(d.name) + ": " + gbuffer + d.reads + " -> " + d.writes + "\n";
  }
  if (!placement.empty()) out += "  where " + placement + "\n";
  return out;
}

namespace {

// What the per-pass decisions share: the inputs, the plan they fill in, and the facts a later
// decision reads from an earlier one (decisions run backwards from the output, consumers first).
struct Planning {
  const PlanContext& c;
  const Scene& scene;
  const Settings& s;
  FramePlan& plan;
  bool image = false;                 // output=final: a display image
  bool shows_focus = false;           // decide_focus: the focus overlay draws the focal depth
  bool lod_uses_attention = false;    // decide_attention: lod.policy=ulod reads attention
  bool gi_follows_attention = false;  // decide_attention: no gaze source, the gaze area follows attention
};

void decide(FramePlan& plan, PassId id, bool needed, std::string reason) {
  PlannedPass& p = plan.passes[static_cast<std::size_t>(id)];
  p.needed = needed;
  p.runs = needed;
  p.reason = std::move(reason);
}

// Backwards from the output: the display image needs tonemap.
void decide_tonemap(Planning& p) {
  decide(p.plan, PassId::Tonemap, p.image,
         p.image ? "output=final is a display image" : "output=gbuffer: no display image");
}

// Overlays go on top of the display image.
void decide_overlay(Planning& p) {
  const Settings& s = p.s;
  const bool image = p.image;
  const bool map_overlay = image && !s.is("overlay.map", "none");
  const bool gaze_overlay = image && s.flag("overlay.gaze") && p.c.gaze_available;
  const bool focus_overlay = image && s.flag("overlay.focus") && !s.is("focus.mode", "fixed");
  std::string overlay_reason;
  if (!image) {
    overlay_reason = "output=gbuffer: nothing to draw on";
  } else if (map_overlay) {
    overlay_reason = "overlay.map=" + s.text("overlay.map");
  } else if (gaze_overlay) {
    overlay_reason = "overlay.gaze=true and a gaze source is connected";
  } else if (focus_overlay) {
    overlay_reason = "overlay.focus=true";
  } else {
    overlay_reason = !s.flag("overlay.gaze") ? "overlay.gaze=false and overlay.map=none"
                                             : "no gaze source (--gaze none) and overlay.map=none";
  }
  decide(p.plan, PassId::Overlay, map_overlay || gaze_overlay || focus_overlay, overlay_reason);
}

// Global illumination: only with light to carry; the caustic map only with specular/refractive
// surfaces to focus it.
void decide_gi(Planning& p) {
  const Settings& s = p.s;
  if (!p.image) {
    decide(p.plan, PassId::Gi, false, "output=gbuffer");
  } else if (!s.flag("gi.enabled")) {
    decide(p.plan, PassId::Gi, false, "gi.enabled=false");
  } else if (p.scene.lights.empty()) {
    decide(p.plan, PassId::Gi, false, "the scene has no lights: no light to bounce");
  } else {
    std::string why = "gi.enabled=true, " + std::to_string(p.scene.lights.size()) + " light(s); caustic map: ";
    if (!s.flag("gi.caustics")) {
      why += "off (gi.caustics=false)";
    } else if (p.scene.has_specular_or_refractive()) {
      why += "yes (specular or refractive surfaces)";
    } else {
      why += "no (no specular or refractive surface)";
    }
    if (s.is("gi.area", "full")) {
      why += "; gi.area=full: the whole screen is ray traced";
    } else if (p.c.gaze_available) {
      why += "; the " + s.text("gi.gaze_area_deg") + " deg gaze area follows the gaze";
    } else if (s.flag("attention.enabled")) {
      why += "; no gaze source: the gaze area follows the most attended object";
    } else {
      why += "; no gaze source and attention.enabled=false: the gaze area stays at the screen centre";
    }
    if (s.is("gi.periphery", "csf") && !s.is("gi.area", "full")) {
      why += "; periphery by CSF-driven ray casting (Murphy 2007)";
    }
    decide(p.plan, PassId::Gi, true, why);
  }
}

// Depth of field: a pinhole lens keeps everything in focus.
void decide_dof(Planning& p) {
  const Settings& s = p.s;
  const Lens& lens = p.scene.camera.lens;
  if (!p.image) {
    decide(p.plan, PassId::Dof, false, "output=gbuffer");
  } else if (!s.flag("dof.enabled")) {
    decide(p.plan, PassId::Dof, false, "dof.enabled=false");
  } else if (lens.is_pinhole()) {
    decide(p.plan, PassId::Dof, false, "pinhole lens: nothing is out of focus");
  } else {
    char why[160];
    const std::string& method = s.text("dof.method");
    std::snprintf(why, sizeof why, "thin lens F=%.1f mm, aperture %.2f mm, method %s", lens.focal_length_m * 1000,
                  lens.aperture_m * 1000, method.c_str());
    decide(p.plan, PassId::Dof, true, why);
    PlannedPass& dof = p.plan.passes[static_cast<std::size_t>(PassId::Dof)];
    if (method == "reference" && !p.c.backend_traces_rays) {
      dof.runs = false;
      dof.reason += " — the ray-traced reference needs --backend embree (per-pixel lens rays); accum is the raster "
                    "backend's reference";
    }
  }
}

// LOD selection: only objects with LOD chains can change detail.
void decide_lod_select(Planning& p) {
  const Settings& s = p.s;
  if (!s.flag("lod.enabled")) {
    decide(p.plan, PassId::LodSelect, false, "lod.enabled=false");
  } else if (!p.scene.has_lods()) {
    decide(p.plan, PassId::LodSelect, false, "no object has an LOD chain");
  } else {
    std::string why = "objects with LOD chains; lod.policy=" + s.text("lod.policy");
    if (s.is("lod.policy", "gaze") && !p.c.gaze_available) {
      why += " without a gaze source: eccentricity from the screen centre";
    }
    if (s.number("lod.budget_ms") > 0) why += "; frame budget " + s.text("lod.budget_ms") + " ms";
    decide(p.plan, PassId::LodSelect, true, why);
  }
}

// Focus: consumed by DOF, and shown by the focus overlay (which lands before DOF, step 7).
void decide_focus(Planning& p) {
  const Settings& s = p.s;
  const FramePlan& plan = p.plan;
  const std::string& mode = s.text("focus.mode");
  p.shows_focus = p.image && s.flag("overlay.focus");
  if (!plan.needed(PassId::Dof) && !p.shows_focus) {
    decide(p.plan, PassId::Focus, false,
           p.image ? "nothing consumes a focal depth (dof not planned, overlay.focus=false)"
                   : "nothing consumes a focal depth (dof not planned)");
  } else if (mode == "fixed") {
    decide(p.plan, PassId::Focus, false, "focus.mode=fixed: the lens focus distance is used");
  } else {
    std::string why = plan.needed(PassId::Dof) ? "dof needs a focal depth" : "overlay.focus shows the focal depth";
    if (plan.needed(PassId::Dof) && p.shows_focus) why += " (overlay.focus shows it)";
    why += "; focus.mode=" + mode;
    if ((mode == "gaze") && !p.c.gaze_available) why += " without a gaze source: the screen centre is used";
    decide(p.plan, PassId::Focus, true, why);
  }
}

// Attention: computed only when something consumes it.
void decide_attention(Planning& p) {
  const Settings& s = p.s;
  const FramePlan& plan = p.plan;
  const std::string& mode = s.text("focus.mode");
  std::vector<std::string> consumers;
  if (plan.needed(PassId::Focus) && (mode == "attention" || mode == "gaze+attention")) consumers.push_back("focus");
  p.lod_uses_attention = plan.needed(PassId::LodSelect) && s.is("lod.policy", "ulod");
  if (p.lod_uses_attention) consumers.push_back("lod-select (lod.policy=ulod)");
  p.gi_follows_attention = plan.needed(PassId::Gi) && !p.c.gaze_available && !s.is("gi.area", "full");
  if (p.gi_follows_attention) consumers.push_back("gi (no gaze source: its gaze area)");
  const std::string& overlay_map = s.text("overlay.map");
  if (p.image && attention::is_map(overlay_map)) {
    consumers.push_back("overlay (overlay.map=" + overlay_map + ")");
  }
  if (consumers.empty()) {
    decide(p.plan, PassId::Attention, false, "nothing consumes attention");
  } else if (!s.flag("attention.enabled")) {
    decide(p.plan, PassId::Attention, false, "attention.enabled=false (consumers fall back to gaze or defaults)");
  } else {
    std::string list;
    for (const auto& k : consumers) list += (list.empty() ? "" : ", ") + k;
    decide(p.plan, PassId::Attention, true, "consumed by " + list);
  }
}

// An implemented pass whose consumers are all needed-but-not-implemented would compute something
// nobody reads: it waits (needed, not run) until a consumer runs.
void wait_unless(FramePlan& plan, PassId id, bool consumer_runs, const std::string& why) {
  PlannedPass& p = plan.passes[static_cast<std::size_t>(id)];
  if (p.runs && !consumer_runs) {
    p.runs = false;
    p.reason += "; waits: " + why;
  }
}

// Focus feeds dof (and the focus overlay).
void wait_focus(Planning& p) {
  wait_unless(p.plan, PassId::Focus, p.plan.runs(PassId::Dof) || p.shows_focus,
              "dof does not run with this method (overlay.focus=true shows the focus meanwhile)");
}

// Attention feeds focus, lod-select and the attention overlays; runs after wait_focus, whose verdict it reads.
void wait_attention(Planning& p) {
  const Settings& s = p.s;
  const FramePlan& plan = p.plan;
  const std::string& mode = s.text("focus.mode");
  const bool attention_overlay = p.image && attention::is_map(s.text("overlay.map"));
  wait_unless(p.plan, PassId::Attention,
              attention_overlay || (p.lod_uses_attention && plan.runs(PassId::LodSelect)) ||
                  (p.gi_follows_attention && plan.runs(PassId::Gi)) ||
                  (plan.runs(PassId::Focus) && (mode == "attention" || mode == "gaze+attention")),
              "none of its consumers runs yet");
}

}  // namespace

// Each decision may read the ones before it (focus reads dof, attention reads focus, lod-select and
// gi), so the order below is the order of the reasoning, not the pipeline order.
FramePlan plan_frame(const PlanContext& c) {
  FramePlan plan;
  for (const PassDecl& d : pass_declarations()) plan.passes.push_back({d.id, false, false, "", {}});
  Planning p{c, c.scene, c.settings, plan};
  p.image = c.settings.is("output", "final");
  decide_tonemap(p);
  decide_overlay(p);
  decide_gi(p);
  decide_dof(p);
  decide_lod_select(p);
  decide_focus(p);
  decide_attention(p);
  decide(plan, PassId::GBuffer, true, "every output starts from the G-buffer");
  wait_focus(p);
  wait_attention(p);
  for (PlannedPass& pass : plan.passes) {
    const PassDecl& d = declaration(pass.id);
    if (pass.runs && d.gbuffer_reads != nullptr) pass.gbuffer_reads = d.gbuffer_reads(plan, c.settings);
  }
  return plan;
}

GBufferPlanes planes_read_on_cpu(const FramePlan& plan) {
  GBufferPlanes r;
  for (const PlannedPass& p : plan.passes) {
    if (p.runs && !declaration(p.id).on_gpu) r = r | p.gbuffer_reads;
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
