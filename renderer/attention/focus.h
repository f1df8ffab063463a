// SPDX-License-Identifier: Apache-2.0
#pragma once
// The focus pass: where the thin lens focuses this frame (Lee 2009 §6.1), from attention without a
// tracker, from gaze with one, or from both.
//
//  - attention: the focal depth is the depth of the most attended object; when no foreground object
//    is visible (or its attention falls below `min_attention`), the depth at the screen centre.
//  - gaze: the object under the gaze point (item buffer), refocused at fixation onset (a new
//    fixation in the gaze stream) and at pursuit onset (the eye took up a moving object: issue 43),
//    and held during saccades and blinks.
//  - gaze+attention: trackers err by 1-2 deg (Jensen & Pedersen 2009, Table 4.1), so the gazed object
//    is chosen among the foreground objects with pixels within `gaze_radius_deg` of the gaze point:
//    the one with the highest attention S_o wins (Lee §6.3's ambiguity); with no foreground object
//    in reach, the depth under the gaze point.
// A change of the focused target starts a transition: linear interpolation of the focal depth over
// `transition_s` (eq. 6.1, Z_f = lerp(Z_p(t), Z_n(t), t/tau), both depths followed while they move),
// or a low-pass filter with cut-off `cutoff_hz` (<= 2 Hz; critically damped second order).
#include <cstdint>
#include <string>
#include <vector>

#include "attention/attention.h"
#include "backend/gbuffer.h"
#include "fovea/protocol/display_geometry.h"

namespace fovea::render::attention {

enum class FocusMode { Fixed, Gaze, Attention, GazeAndAttention };
enum class FocusTransition { Lerp, LowPass };

struct FocusSettings {
  FocusMode mode = FocusMode::GazeAndAttention;
  FocusTransition transition = FocusTransition::Lerp;
  double transition_s = 0.3;     // eq. 6.1's tau
  double cutoff_hz = 1.0;        // low-pass cut-off, (0, 2]
  double gaze_radius_deg = 1.5;  // how far from the gaze point an object may be and still be the gazed one
  double min_attention = 1e-3;   // below: no foreground object is attended (screen-centre depth)
  double fixed_depth_m = 2.0;    // FocusMode::Fixed (the lens' focus distance)
  bool refocus_on_pursuit = true; // a pursuit onset refocuses as a fixation onset does
  void check() const;            // std::invalid_argument naming the bad field
  bool operator==(const FocusSettings&) const = default;
};

// What the focus pass knows about the gaze this frame.
struct FocusGaze {
  bool available = false;        // a gaze source is connected
  bool valid = false;            // this sample has valid gaze
  double x = 0.5, y = 0.5;       // normalised screen coordinates
  bool saccade_or_blink = false; // the stream says the eye is moving or closed: hold the focus
  std::uint64_t fixations = 0;   // fixation onsets seen so far (a change = a new fixation: refocus)
  std::uint64_t pursuits = 0;    // pursuit onsets seen so far (a change: refocus, with refocus_on_pursuit)
};

struct FocusResult {
  double focal_depth_m = 2.0;    // what the lens focuses at this frame (after the transition)
  double target_depth_m = 2.0;   // where the transition is heading
  std::uint32_t object = 0;      // the focused object (0: a depth without an object, e.g. screen centre)
  bool object_visible = false;   // ... has pixels this frame (else it keeps the depth it last had)
  bool in_transition = false;
  std::string why;               // "attention: red_ball (S_o 0.42)", "gaze+attention: ...", for --explain and overlays
};

// What the focus pass reads of the frame's G-buffer (row 0 at the top): small rectangles of depth
// and object ids around the points it looks at, and the whole planes only when an object's depth is
// not in the attention frame (its median over the image). GBufferPixels reads a G-buffer on the CPU;
// the GPU-resident frame reads the rectangles back from where the G-buffer lies (FramePipeline).
class FocusPixels {
 public:
  virtual ~FocusPixels() = default;
  // The image's size; 0 x 0 when it has no depth or id plane.
  virtual std::uint32_t width() const = 0;
  virtual std::uint32_t height() const = 0;
  // Depth and ids of the pixels [x0, x1) x [y0, y1) (inside the image), row-major.
  virtual void read(std::uint32_t x0, std::uint32_t y0, std::uint32_t x1, std::uint32_t y1, std::vector<float>& depth,
                    std::vector<std::uint32_t>& ids) = 0;
  // The whole image: its depth and object_id planes.
  virtual const GBuffer& whole() = 0;
};

class GBufferPixels final : public FocusPixels {
 public:
  explicit GBufferPixels(const GBuffer& g);
  std::uint32_t width() const override { return w_; }
  std::uint32_t height() const override { return h_; }
  void read(std::uint32_t x0, std::uint32_t y0, std::uint32_t x1, std::uint32_t y1, std::vector<float>& depth,
            std::vector<std::uint32_t>& ids) override;
  const GBuffer& whole() override { return g_; }

 private:
  const GBuffer& g_;
  std::uint32_t w_ = 0, h_ = 0;
};

class FocusTracker {
 public:
  explicit FocusTracker(FocusSettings settings = {});
  // `attention` may be null (attention not planned): gaze+attention then acts as gaze, attention as
  // the screen centre. `display` converts gaze_radius_deg to pixels of the G-buffer.
  const FocusResult& update(double time_s, const GBuffer& g, const Scene& scene, const AttentionFrame* attention,
                            const FocusGaze& gaze, const protocol::DisplayGeometry& display);
  // The same on a G-buffer read through `pixels` (only what the rules look at).
  const FocusResult& update(double time_s, FocusPixels& pixels, const Scene& scene, const AttentionFrame* attention,
                            const FocusGaze& gaze, const protocol::DisplayGeometry& display);
  const FocusResult& last() const { return result_; }
  void reset();

 private:
  // What the lens is pointed at: its depth is re-read every frame, so a moving object is followed.
  struct Target {
    enum class Kind { Fixed, Depth, Centre, Point, Object } kind = Kind::Centre;
    std::uint32_t object = 0;   // Kind::Object
    double x = 0.5, y = 0.5;    // Kind::Point: the gaze point it was picked at (Object: likewise, if by gaze)
    double depth_m = 2.0;       // the last depth it resolved to (Kind::Depth: the depth itself)
    std::string why;
  };
  struct FrameView;  // this frame's inputs (focus.cpp)
  Target pick_attention(const FrameView& f) const;
  Target pick_gaze(const FrameView& f, double x, double y, bool with_attention) const;
  double resolve(const FrameView& f, Target& t, bool* visible = nullptr) const;
  // update()'s stages (focus.cpp).
  struct FocalDepth {
    double depth_m;
    bool in_transition;
  };
  double advance_clock(double time_s);
  Target pick_target(const FrameView& f, const FocusGaze& gaze, bool& held);
  Target follow_gaze(const FrameView& f, const FocusGaze& gaze, bool& held);
  void start_transition_if_changed(const Target& next);
  FocalDepth focal_depth(const FrameView& f, double zn, double dt);
  FocalDepth lerp_focal_depth(const FrameView& f, double zn);
  FocalDepth low_pass_focal_depth(double zn, double dt);

  FocusSettings settings_;
  FocusResult result_;
  Target target_, from_;          // Z_n's and Z_p's targets of eq. 6.1
  double last_time_s_ = 0;
  double transition_elapsed_s_ = 0;  // t of eq. 6.1: the frame gaps summed since the change (never backwards)
  double filter_velocity_ = 0;    // low-pass state (the position is result_.focal_depth_m)
  std::uint64_t last_fixations_ = 0, last_pursuits_ = 0;
  bool started_ = false;
  bool gaze_target_ = false;      // target_ was picked from the gaze (gaze modes hold it until the next fixation)
};

}  // namespace fovea::render::attention
