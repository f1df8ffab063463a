// SPDX-License-Identifier: Apache-2.0
#pragma once
// Level-of-detail selection: which level of its chain (lod_chain.h) each visible object is drawn at.
// Every policy gives a continuous level L in [0, levels - 1] (0 = full detail); Lee's ULOD blends
// the two adjacent levels by frac(L), the others draw round(L) through hysteresis, and a frame-time
// controller biases every object coarser or finer to hold a budget.
//
//   distance     L = 2 log_beta(d / d_ref): with r(L) = beta^-L triangles and projected area
//                ~ 1 / d^2, the triangles per projected area stay constant.
//   screen-size  the coarsest level whose geometric error, projected at the object's distance,
//                stays within tolerance_px pixels (the projected-screen-size criterion).
//   brown        Brown, Cooper & Pham 2003: binary importance I = sigma(sum w_i f_i) in {-1, 1}
//                (eq. 5) from size, position, rotational and translational motion and luminance
//                contrast; P_LOD = P + a I P - s P (eq. 4 with a and the stress s as shares of P,
//                P_LOD <= P, eq. 3), the level the triangle count maps to: log_beta(P / P_LOD).
//   ulod         Lee 2009, eq. 7.3: L = M (1 - S_o) with the attention pass's S_o; LodSelector
//                takes S_o relative to the frame's most attended object (Lee: "the highest
//                attention value (i.e., S_o = 1)" gets the finest model).
//   gaze         Murphy 2007's contrast sensitivity: the coarsest level whose geometric error,
//                as a visual angle, stays below half a period of the finest grating the eye sees
//                at the object's eccentricity (f_c of eq. 4.3).
//
// Hard cases: S_o outside [0, 1] is clamped and NaN reads as 0 (not attended); an object without a
// chain (levels = 1) is always level 0; non-finite distances, sizes or eccentricities read as the
// farthest / smallest / most peripheral (coarsest) case; a budget no level can meet is reported.
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "perception/csf.h"

namespace fovea::render::lod {

enum class Policy { None, Distance, ScreenSize, Brown, Ulod, Gaze };
const char* to_string(Policy p);
// "none", "distance", "screen-size", "brown", "ulod", "gaze"; throws std::invalid_argument otherwise.
Policy parse_policy(const std::string& name);

// One visible object this frame, as the policies see it.
struct ObjectView {
  std::uint32_t id = 0;
  int levels = 1;                        // levels of its chain (1: no chain)
  double base = 4;                       // beta of its chain
  std::vector<float> level_error_m;      // geometric error per level (level 0: 0)
  std::vector<std::size_t> level_triangles;
  double distance_m = 1;                 // eye to the bounding sphere's centre
  double radius_m = 0;                   // bounding sphere radius
  double projected_radius_px = 0;        // the bounding sphere on the image
  double screen_area_px = 1;             // the image's area (Brown's size feature)
  double screen_x = 0.5, screen_y = 0.5; // normalised position of its centre
  double eccentricity_deg = 0;           // from the gaze point
  double px_per_radian = 1000;           // image pixels per radian at the centre (focal length in pixels)
  double attention = 0;                  // S_o of Lee's attention pass, [0, 1]
  double rotation_deg_per_frame = 0;     // largest per-axis rotation since the last frame
  double velocity_px_per_frame = 0;      // projected velocity
  double luminance_contrast = 0;         // relative contrast inside its projection (0.01 = 1 %)
};

struct BrownSettings {
  // Feature thresholds (Brown et al. 2003, §3.2).
  double size_share = 0.02;       // projected area over screen area above which size is important
  double position_box = 0.5;      // centred box (share of width and height) inside which position is
  double rotation_min_deg = 0.5;  // per frame, then > mean + rotation_sd x sd of visible objects
  double rotation_sd = 1.0;
  double velocity_min_px = 0.5;   // per frame, then > mean + velocity_sd x sd
  double velocity_sd = 1.0;
  double luminance_min = 0.01;    // contrast above 1 %
  // Eq. 5's weights (size, position, rotation, translation, luminance) and the step's threshold.
  double weights[5] = {1, 1, 1, 1, 1};
  double threshold = 2.5;         // sum w_i f_i above this: important (I = 1), else I = -1
  double a = 0.5;                 // eq. 4's scale as a share of P
};

struct PolicySettings {
  Policy policy = Policy::Ulod;
  double distance_ref_m = 2;      // distance policy: full detail up to here
  double tolerance_px = 1;        // screen-size policy: geometric error allowed on screen
  BrownSettings brown;
  perception::GeislerPerry csf;   // gaze policy: Geisler-Perry constants (Murphy eqs. 4.1-4.3)
  double hysteresis = 0.25;       // levels: a drawn level changes when L leaves it by 0.5 + this
  // Saccadic suppression (the eye is nearly blind during a saccade: Matin 1974; Volkmann 1986):
  // during a saccade in flight every drawn level goes straight to round(L), unblended; outside
  // saccades a drawn level holds until L is more than kSwitchSlack levels off (then it pops, a
  // change the viewer may see, counted), and ULOD draws no blend. Off: ULOD blends, the others
  // switch through the hysteresis whenever L moves.
  bool switch_in_saccades = false;
};
inline constexpr double kSwitchSlack = 1.5;

// The policy's continuous level of one object, before the frame-time bias, in [0, levels - 1].
// `stress` (Brown's s, a share of P in [0, 1 + a]) and the visible objects' motion statistics (for
// Brown's relative features) come from the frame (LodSelector fills them).
struct FrameStats {
  double rotation_mean = 0, rotation_sd = 0, velocity_mean = 0, velocity_sd = 0;
  double stress = 0;
};
double continuous_level(const ObjectView& o, const PolicySettings& s, const FrameStats& frame);
// Eq. 5 alone: Brown's importance of an object, -1 or 1.
int brown_importance(const ObjectView& o, const BrownSettings& s, const FrameStats& frame);

// The per-frame selection with memory: hysteresis per object and a frame-time budget controller.
struct Selection {
  std::uint32_t id = 0;
  double level = 0;      // continuous level after the bias, [0, levels - 1]
  int drawn = 0;         // the level drawn (after hysteresis)
  int blend_to = 0;      // ULOD: the adjacent level blended in with weight `blend`
  double blend = 0;
};

// What the level changes of the last frame were: changes outside a saccade are pops a viewer may
// see (ULOD's blended changes are not: its weight moves continuously); blended objects cost ULOD's
// second pass.
struct SwitchState {
  bool in_saccade = false;
  int pops = 0;                // objects whose drawn level changed outside a saccade (not blended)
  int switched_in_saccade = 0; // objects whose drawn level changed during a saccade
  int blended = 0;             // objects drawn as a blend of two levels
};

struct BudgetState {
  double target_ms = 0;     // 0: no budget
  double bias = 0;          // levels added to every object (>= 0)
  bool cannot_meet = false; // every object is at its coarsest level and the frame is still over
  std::string why;
};

class LodSelector {
 public:
  explicit LodSelector(PolicySettings s = {}) : settings_(std::move(s)) {}
  void set_settings(const PolicySettings& s) { settings_ = s; }
  const PolicySettings& settings() const { return settings_; }
  // Frame-time budget (0: none). The controller raises the bias by 0.25 level per frame while the
  // measured frame time is over the budget and lowers it while it is under 85 % of it.
  void set_budget_ms(double ms);
  // Selects this frame's levels. last_frame_ms: the measured time of the previous frame (budget).
  // top_attention: the S_o of the frame's most attended object, chain or not (ULOD takes S_o relative
  // to it); NaN or <= 0: the largest among `objects`.
  const std::vector<Selection>& select(const std::vector<ObjectView>& objects, double last_frame_ms,
                                       double top_attention = std::numeric_limits<double>::quiet_NaN());
  const BudgetState& budget() const { return budget_; }
  // Whether a saccade is in flight for the next select() (GazeState::in_saccade).
  void set_in_saccade(bool in_saccade) { in_saccade_ = in_saccade; }
  const SwitchState& switches() const { return switches_; }

 private:
  PolicySettings settings_;
  BudgetState budget_;
  std::vector<Selection> out_;
  std::vector<std::pair<std::uint32_t, int>> drawn_;  // object id -> drawn level last frame
  double stress_ = 0;
  bool in_saccade_ = false;
  SwitchState switches_;
  int choose_drawn(const ObjectView& o, double l, int previous, Selection& sel) const;
};

}  // namespace fovea::render::lod
