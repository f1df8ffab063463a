// SPDX-License-Identifier: Apache-2.0
#include "pipeline/settings.h"

#include <cmath>
#include <cstdio>
#include <sstream>
#include <stdexcept>

#include "pipeline/finite_check.h"

namespace fovea::render {

// One table, one row per setting (name, default, allowed values, help): long, and kept whole so that
// --help, --set's checks and the docs read the settings from one place (a typed per-pass split is
// issue 21's pass graph).
const std::vector<SettingSpec>& Settings::specs() {
  static const std::vector<SettingSpec> kSpecs = {
      {"output", "final", "final|gbuffer", "what the frame is built for: the tone-mapped image, or the G-buffer alone"},
      {"shadows", "false", "bool", "shadow rays for direct light in local illumination (Embree backend only)"},
      {"frame.gpu", "true", "bool",
       "OpenGL backend: keep the frame on the GPU (G-buffer, tone map, overlay, display and dof.method=lee-mipmap|"
       "schedl-layered run there; only the planes "
       "the CPU passes read are read back); false: read the whole G-buffer back and run every pass on the CPU (the "
       "reference path)"},
      {"attention.enabled", "true", "bool", "allow the visual attention pass (Lee 2009 ch. 3) when something consumes it"},
      {"attention.device", "auto", "auto|cpu|gpu",
       "where the attention pass's pixel stage runs: auto = on the GPU when the frame's G-buffer lies there "
       "(--backend gl) and the GPU is not a software rasteriser (llvmpipe: the CPU's pixel stage is faster), only "
       "the per-object values read back (lod.policy=ulod: its proxy rendered there too); gpu = there or not at all"},
      {"attention.map_size", "256", "number in [64, 512]",
       "side of the square saliency map in pixels (rounded); the G-buffer is resampled to it (Lee 2009 §3.5.4: 64-512)"},
      {"attention.resample", "box", "box|nearest",
       "G-buffer to map: the mean of the pixels under each map pixel (reads the whole G-buffer) or the one pixel under "
       "its centre (reads map_size^2 pixels, aliases fine detail)"},
      {"attention.groups", "BET", "BET|BE|BT|ET|B|E|T|none",
       "feature groups of Lee 2009 Table 3.2: B luminance and hue, E depth, size and motion, T spatial and temporal "
       "context"},
      {"attention.lambda", "30", "number in [1, 3600]", "frames in the temporal context's running mean (Lee 2009 eq. 3.10)"},
      {"attention.distance_m", "4", "number in [0.01, 10000]",
       "preferred viewing distance L: the spatial context peaks there (Lee 2009 eq. 3.9)"},
      {"attention.kalman", "true", "bool", "smooth each object's attention with a Kalman filter (Lee 2009 §3.3)"},
      {"focus.mode", "gaze+attention", "fixed|gaze|attention|gaze+attention",
       "where the lens focuses: the scene's focus distance, the gazed object, the most attended object, or gaze with "
       "attention breaking ties"},
      {"focus.transition", "lerp", "lerp|lowpass",
       "how the focal depth moves to a new target: linear over focus.transition_ms (Lee 2009 eq. 6.1) or a low-pass filter"},
      {"focus.transition_ms", "300", "number in [0, 2000]", "duration of a lerp focus transition (tau of Lee eq. 6.1)"},
      {"focus.cutoff_hz", "1", "number in [0.01, 2]", "cut-off of the low-pass focus transition (Lee 2009 §6.1: <= 2 Hz)"},
      {"focus.gaze_radius_deg", "1.5", "number in [0, 10]",
       "gaze+attention: objects with pixels this close to the gaze point compete on attention (tracker error 1-2 deg)"},
      {"focus.refocus_on_pursuit", "true", "bool",
       "gaze modes: a pursuit onset (the eye takes up a moving object) refocuses as a fixation onset does"},
      {"dof.enabled", "true", "bool", "depth of field for thin-lens cameras"},
      {"dof.method", "lee-mipmap", "reference|accum|lee-mipmap|lee-splat|schedl-layered",
       "depth-of-field algorithm: reference = thin-lens distributed ray tracing (Embree), accum = the "
       "accumulation-buffer equivalent (any backend), lee-mipmap (Lee 2009 ch. 4), lee-splat (ch. 5), schedl-layered "
       "(Schedl & Wimmer, layered on depth-peeled input)"},
      {"dof.device", "auto", "auto|cpu|gpu",
       "where an image-space dof.method runs: auto = on the GPU when the frame's G-buffer lies there (--backend gl) "
       "and the method has a GPU implementation (lee-mipmap, schedl-layered, lee-splat), else on the CPU; gpu = there or not at all"},
      {"dof.samples", "64", "number in [1, 4096]", "lens samples per frame of the reference and accum methods"},
      {"dof.seed", "1", "number in [0, 4294967295]", "seed of the reference's lens samples (same seed, same image)"},
      {"dof.projection", "sensor", "sensor|display",
       "CoC in pixels: the camera's image plane over its field of view (what the references render), or Lee 2009 "
       "eq. 4.4 with the scene's display geometry"},
      {"dof.anisotropic", "true", "bool", "lee-mipmap: anisotropic mipmap against intensity leakage (Lee 2009 eq. 4.9)"},
      {"dof.sigma_per_coc", "0.5", "number in [0.05, 2]",
       "lee-mipmap: degree of blurring per CoC diameter, sigma = this x C (Lee 2009 §4.1.3: 0.5; 0.25 matches the "
       "thin lens's uniform disc and scores 4-6 dB higher against the ray-traced reference, bench/RESULTS.md)"},
      {"dof.smooth_foreground", "true", "bool", "lee-mipmap: DoN smoothing of blurred foreground boundaries (eqs. 4.10-4.11)"},
      {"dof.hidden", "true", "bool",
       "lee-splat: render the hidden image (the surfaces behind the visible ones, Lee 2009 §5.1.2) for partial "
       "occlusion: a second render per frame (depth peeling on the raster backend: a few scene draws)"},
      {"dof.layers", "3", "number in [1, 8]",
       "schedl-layered: depth-peeled input layers M (the visible one and M - 1 objects behind it: M - 1 extra renders; "
       "the raster backend peels with a scene draw per surface met, shading only the layers kept where it has "
       "compute shaders)"},
      {"dof.aperture", "disc", "disc|gaussian|hexagon", "lee-splat: aperture shape of the splats (the IDF image)"},
      {"lod.enabled", "true", "bool", "level-of-detail selection for objects with LOD chains"},
      {"lod.proxy_resolution", "map", "map|full",
       "lod.policy=ulod: the attention pass's proxy G-buffer (every object at its coarsest level, Lee 2009 §7.2) at "
       "twice the saliency map's side (map) or at the camera's resolution (full)"},
      {"lod.policy", "screen-size", "none|distance|screen-size|brown|ulod|gaze",
       "how levels are chosen: distance (2 log_beta(d / lod.distance_ref_m)), projected error within lod.tolerance_px, "
       "Brown 2003's binary importance, Lee 2009's ULOD L = M(1 - S_o) from the attention pass, or gaze eccentricity "
       "through the Geisler-Perry contrast threshold (renderer/lod/lod_policy.h)"},
      {"lod.tolerance_px", "1", "number in [0.01, 1000]", "screen-size policy: geometric error allowed on screen, pixels"},
      {"lod.switch_in_saccades", "false", "bool",
       "change drawn levels during saccades in flight (saccadic suppression hides it; provisional events from "
       "the daemon say when), unblended; outside saccades a level holds until it is 1.5 levels off (a pop, "
       "counted in lod.csv)"},
      {"lod.distance_ref_m", "2", "number in [0.001, 100000]", "distance policy: full detail up to this distance"},
      {"lod.hysteresis", "0.25", "number in [0, 2]", "levels beyond half a level an object's L must move before its drawn level changes"},
      {"lod.budget_ms", "0", "number in [0, 100000]",
       "frame-time budget (0: none): the selection coarsens every object while frames are slower and says when no "
       "level can meet it"},
      {"gi.enabled", "false", "bool", "gaze-directed global illumination (photon mapping, hybrid composite)"},
      {"gi.caustics", "true", "bool", "caustic photon map when the scene has specular or refractive surfaces"},
      {"gi.gaze_area_deg", "20", "number in [1, 180]", "diameter of the high-quality gaze area in degrees of visual angle"},
      {"gi.area", "gaze", "gaze|full",
       "where GI is ray traced: the gaze area blended into the raster image (Algorithm 8.4), or the full screen"},
      {"gi.photons", "40000", "number in [0, 10000000]", "photons stored in the global map per frame (maxPhotons, Table 8.3)"},
      {"gi.caustic_photons", "20000", "number in [0, 10000000]",
       "photons stored in the caustic map per frame (traced only when the scene has specular or refractive surfaces)"},
      {"gi.trace_depth", "3", "number in [1, 1000]", "surface interactions per photon trace (pmTraceDepth, Table 8.3)"},
      {"gi.nnn", "240", "number in [1, 100000]", "nearest photons per radiance estimate (nNN, Table 8.3)"},
      {"gi.nn_radius", "auto", "auto|number in [0.0001, 1000]",
       "search radius of the radiance estimate, metres (NNRadius, Table 8.3's 0.3 m for its 2 m room); auto: the disc "
       "that holds gi.nnn photons spread evenly over the scene's surfaces at gi.photons, sqrt(nnn A / (pi photons))"},
      {"gi.filter", "cone", "cone|disc", "radiance estimate filter: Jensen's cone filter (k = 1.1) or constant over the disc"},
      {"gi.estimate", "auto", "auto|nearest|radius|precomputed",
       "indirect light per shading point from its gi.nnn nearest photons (Jensen & Pedersen §6.3.2), from every photon "
       "within gi.nn_radius (the GPU gather's estimate), or from the nearest photon's precomputed irradiance "
       "(Christensen 1999; diffuse only, much faster); auto: radius where the gather runs on the GPU, else nearest"},
      {"gi.overlap", "auto", "auto|true|false",
       "trace the next frame's photons on a worker thread while the frame goes on (the frame then uses the maps traced "
       "during the last one: one frame late where things move); traditional strategy only; auto: where the gather "
       "runs on the GPU"},
      {"gi.device", "auto", "auto|cpu|gpu",
       "where the gaze area's photons are gathered: on the GPU where the frame lies (photons still traced by Embree on "
       "the CPU; the raster's direct light, no shadows; mirrors, glass and glTF materials traced on the CPU), or on the "
       "CPU; auto: the GPU where the frame is GPU-resident on a real GPU and nothing needs the CPU's gather"},
      {"gi.precompute_stride", "4", "number in [1, 1000]", "gi.estimate=precomputed: irradiance at every n-th indirect photon"},
      {"gi.strategy", "traditional", "traditional|gaze-directed|importon",
       "how the photon map is built: uniform emission (ch. 6), steered by the last frame's gaze photons (ch. 8: emission "
       "maps, guided reflections, power scaling) or stored only where importons from the gaze area reach (§7.2)"},
      {"gi.emission_ratio", "0.5", "number in [0, 1]", "gaze-directed: share of photons emitted from the emission map (Table 8.3)"},
      {"gi.guided_reflections", "false", "bool",
       "gaze-directed: traditional photons' diffuse reflections are guided too (gazeDirectedReflections; Table 8.3 says "
       "yes, but it biases the power scaling's reference: the gaze area comes out too bright, GI.md)"},
      {"gi.nn_reflect_radius", "0.01", "number in [0.00001, 100]", "gaze-directed: NNReflectRadius, metres (Table 8.3)"},
      {"gi.noise_scale", "0.1", "number in [0, 10]", "gaze-directed: noiseScale of eq. 8.8 (Table 8.3)"},
      {"gi.importons", "10000", "number in [1, 10000000]", "importon: importons traced through the gaze area (n_i, eq. 7.19)"},
      {"gi.periphery", "raster", "raster|csf",
       "outside the gaze area: the G-buffer's local illumination, or Murphy 2007's CSF-driven ray casting (rays only "
       "where the eye resolves them, silhouettes refined, the rest interpolated; gi.csv reports rays against full "
       "resolution)"},
      {"gi.csf_quality", "1", "number in [0, 16]", "gi.periphery=csf: multiplies the cutoff frequency the rays resolve (2: ~4x the rays)"},
      {"gi.ray_depth", "5", "number in [0, 64]", "mirror and glass bounces followed by the GI's eye rays"},
      {"gi.fovea", "0.7", "number in [0, 1]",
       "fraction of the gaze area's radius shown as pure GI before the blend to raster (Algorithm 8.4: 0.7)"},
      {"gi.seed", "1", "number in [0, 4294967295]", "photon seeds (same seed, same photons)"},
      {"tonemap.operator", "reinhard", "reinhard|clamp|exponential", "HDR to display mapping (exponential: eq. 8.7)"},
      {"tonemap.exposure", "1", "number in [0.0001, 10000]", "linear scale applied before tone mapping"},
      {"tonemap.exact", "false", "bool", "sRGB-encode with pow() per channel (reference) instead of a table (<= 1/255 off)"},
      {"debug.finite_checks", kFiniteChecksByDefault ? "true" : "false", "bool",
       "scan every pass's output for NaN/Inf and stop the frame naming the pass, buffer and pixel (on by default "
       "in debug builds)"},
      {"frame.depth_prepass", "true", "bool",
       "OpenGL backend: draw the z-buffer first, then shade each pixel once (z test at equal) instead of every "
       "surface drawn over it (bench/bench_gpu_frame.sh measures both)"},
      {"frame.gbuffer_pass", "auto", "auto|visibility|forward",
       "OpenGL backend: visibility = rasterise triangle ids only, then rebuild the G-buffer and shade each pixel "
       "once in a compute pass (GL 4.3; falls back to forward with one log line where compute is missing); forward "
       "= shade in the raster pass's fragment shader (GL 3.3); auto = visibility on a GPU with compute shaders, "
       "forward on a software rasteriser (llvmpipe), where it is the faster (bench/RESULTS.md). The DOF's depth "
       "peeling goes through the visibility buffer wherever compute shaders are, with auto too (each peeling draw "
       "writes triangle ids, each layer kept is shaded once: faster on llvmpipe as well); forward peels forward"},
      {"frame.effect_passes", "auto", "auto|compute|fragment",
       "OpenGL backend: the passes with two implementations (the tone map, attention's pixel stage, "
       "dof.method=lee-mipmap, schedl-layered and lee-splat, ULOD's blend) as "
       "compute passes (GL 4.3; the fragment passes where compute is missing, as --explain says) or fragment passes "
       "(GL 3.3); auto = compute on a GPU with compute shaders, fragment on a software rasteriser (llvmpipe)"},
      {"debug.gi_first_hits", "gbuffer", "gbuffer|trace",
       "Embree backend with GI: the gaze area's first hits read from the frame's G-buffer (gbuffer), or traced "
       "again (trace: measures what reading them saves)"},
      {"debug.gbuffer_planes", "read", "read|all",
       "GPU-resident frame: the G-buffer pass writes the planes some pass reads (read), or every plane (all: "
       "measures what culling the unread ones saves, bench/bench_gpu_frame.sh)"},
      {"overlay.gaze", "true", "bool", "draw the gaze point (and the gaze area when GI is on)"},
      {"overlay.focus", "false", "bool",
       "outline the focused object (or mark the focal depth) on the display image; plans the focus pass (and "
       "attention for focus.mode=attention|gaze+attention) even without depth of field"},
      {"overlay.map", "none", "none|depth|id|normal|motion|saliency|spatial|temporal|attention|coc|gaze-area|photons",
       "show a map instead of the image: saliency is the pixel saliency S_p, spatial/temporal/attention colour each "
       "object by T_s, T_t, S_o (maps of later passes appear when those passes exist)"},
  };
  return kSpecs;
}

namespace {
const SettingSpec* find_spec(const std::string& key) {
  for (const auto& s : Settings::specs()) {
    if (s.key == key) return &s;
  }
  return nullptr;
}

std::string all_keys() {
  std::string out;
  for (const auto& s : Settings::specs()) out += (out.empty() ? "" : ", ") + s.key;
  return out;
}

void check_value(const SettingSpec& spec, const std::string& value) {
  const auto bad = [&]() {
    throw std::invalid_argument("setting " + spec.key + "=" + value + ": allowed " + spec.allowed);
  };
  if (spec.allowed == "bool") {
    if (value != "true" && value != "false") bad();
    return;
  }
  // "auto|number in [lo, hi]": the word, or a number in range.
  const bool auto_or_number = spec.allowed.rfind("auto|number in [", 0) == 0;
  if (auto_or_number && value == "auto") return;
  if (spec.allowed.rfind("number in [", 0) == 0 || auto_or_number) {
    double lo = 0, hi = 0;
    std::sscanf(spec.allowed.c_str() + (auto_or_number ? 5 : 0), "number in [%lf, %lf]", &lo, &hi);
    std::size_t used = 0;
    double v = 0;
    try {
      v = std::stod(value, &used);
    } catch (const std::exception&) {
      bad();
    }
    if (used != value.size() || !std::isfinite(v) || v < lo || v > hi) bad();
    return;
  }
  std::stringstream options(spec.allowed);
  std::string option;
  while (std::getline(options, option, '|')) {
    if (option == value) return;
  }
  bad();
}
}  // namespace

Settings::Settings() {
  for (const auto& s : specs()) values_[s.key] = s.default_value;
}

void Settings::set(const std::string& key, const std::string& value) {
  const SettingSpec* spec = find_spec(key);
  if (spec == nullptr) throw std::invalid_argument("unknown setting \"" + key + "\"; known: " + all_keys());
  check_value(*spec, value);
  std::string& held = values_[key];
  if (held == value) return;
  held = value;
  ++version_;
}

void Settings::set_assignment(const std::string& assignment) {
  const auto eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0) {
    throw std::invalid_argument("--set \"" + assignment + "\": expected key=value");
  }
  set(assignment.substr(0, eq), assignment.substr(eq + 1));
}

const std::string& Settings::text(const std::string& key) const {
  const auto it = values_.find(key);
  if (it == values_.end()) throw std::invalid_argument("unknown setting \"" + key + "\"");
  return it->second;
}

bool Settings::flag(const std::string& key) const { return text(key) == "true"; }

double Settings::number(const std::string& key) const { return std::stod(text(key)); }

std::map<std::string, std::string> Settings::changed() const {
  std::map<std::string, std::string> out;
  for (const auto& s : specs()) {
    if (values_.at(s.key) != s.default_value) out[s.key] = values_.at(s.key);
  }
  return out;
}

}  // namespace fovea::render
