// SPDX-License-Identifier: Apache-2.0
#pragma once
// Visual attention tracking (Lee 2009, ch. 3): a bottom-up pixel saliency map from the G-buffer
// (luminance and hue, depth, object size, object motion; §3.1), turned into per-object attention
// modulated by top-down contexts (task importance, spatial and temporal context; §3.2) and smoothed
// per object by a discrete Kalman filter. The attention pass of the renderer's pipeline runs it once
// per frame; the focus pass (focus.h) and LOD selection consume its result.
//
// Equations (Lee 2009):
//   B_d = (z - z_near) / (z_far - z_near)                                   (3.1)
//   B_s(k) = pixels of k / pixels of the image                               (3.2)
//   B_m(k) = |p^t(k) - p^{t-1}(k)|, p the vertex farthest from k's centre      (3.3)
//   C_f = 1/6 sum_{i in 0..2} sum_{j in 3,4} |B_f^i - B_f^{i+j}|            (3.4)
//   S_p = normalise(sum_f w_f C_f),  w_f = 1 / max C_f                        (3.5, 3.6)
//   S^_o(k) = T_i(k) / n(k) sum_{(u,v) in k} S_p(u, v)                       (3.7)
//   S_o(k) = (T_s(k) + T_t(k)) S^_o(k)                                       (3.8)
//   T_s(k) = 0 if v.w > 0 and dx > 0, else c_s (x/c_x) e^{-(x/c_x)^2} e^{-c_y y^2}   (3.9)
//   T_t(k) = 1/lambda sum of the last lambda T_s(k)                          (3.10)
#include <algorithm>
#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "backend/gbuffer.h"
#include "scene/scene.h"

namespace fovea::render::attention {

// The attention pass's maps an overlay shows (overlay.map; Lee 2009 Fig. 3.4), in the viewer's
// cycling order: the one list the planner, the pipeline, the overlay and the viewer read.
inline constexpr std::array<std::string_view, 4> kMaps = {"saliency", "spatial", "temporal", "attention"};
inline bool is_map(std::string_view name) { return std::find(kMaps.begin(), kMaps.end(), name) != kMaps.end(); }

// The feature groups of Lee 2009 §3.5.2 / Table 3.2, switchable for the ablation.
struct FeatureGroups {
  bool image = true;    // B: luminance and hue
  bool object = true;   // E: depth, size, motion
  bool context = true;  // T: spatial and temporal context (off: S_o = S^_o)
  bool operator==(const FeatureGroups&) const = default;
};

// How the G-buffer becomes the map's input: the mean of the source pixels under each map pixel
// (reads the whole G-buffer: memory-bound, ~1.5 ms for 960x540 on this project's 2-core machine),
// or the one source pixel under its centre (reads map_size^2 pixels; aliases fine detail).
enum class Resample { Box, Nearest };

struct AttentionSettings {
  int map_size = 256;               // the saliency map is map_size x map_size, 64..512
  Resample resample = Resample::Box;
  FeatureGroups groups;
  double preferred_distance_m = 4;  // L of eq. 3.9: the distance of maximum spatial emphasis, c_x = L / 0.707
  double c_y = 4;                   // screen emphasis of eq. 3.9; y = distance from the screen centre, normalised
                                    // so that a screen corner is at 1
  int temporal_window = 30;         // lambda of eq. 3.10, frames (>= 1)
  bool kalman = true;               // smooth S_o per object (§3.2.1, last paragraph)
  double kalman_process_noise = 1e-3, kalman_measurement_noise = 1e-2;
  // Throws std::invalid_argument naming the bad field.
  void check() const;
  bool operator==(const AttentionSettings&) const = default;
};

// One visible object with task importance T_i > 0 (background objects, T_i = 0, are never attended).
struct ObjectAttention {
  std::uint32_t id = 0;
  std::size_t pixels = 0;        // n(k) in the saliency map
  double size = 0;               // B_s(k)
  double motion = 0;             // B_m(k), metres per frame
  double saliency = 0;           // S^_o(k), eq. 3.7
  double spatial = 0;            // T_s(k), eq. 3.9
  double temporal = 0;           // T_t(k), eq. 3.10
  double attention_raw = 0;      // S_o(k), eq. 3.8
  double attention = 0;          // S_o(k) after the Kalman filter (== raw when it is off)
  double screen_x = 0, screen_y = 0;  // normalised screen position of the object's pixels' centroid
  double distance_m = 0;         // x of eq. 3.9: observer to object centre
  double depth_m = 0;            // median view depth of its pixels (what the focus pass focuses at)
};

struct AttentionFrame {
  int map_width = 0, map_height = 0;
  std::vector<float> saliency;   // S_p, map_width x map_height, row-major, row 0 at the top, in [0, 1]
  std::vector<float> contrast[5];  // C_l, C_h, C_d, C_s, C_m before weighting (for overlays and tests)
  std::vector<std::uint32_t> ids;  // the item buffer resampled to the map (nearest)
  std::vector<ObjectAttention> objects;  // sorted by attention, highest first
  std::uint32_t most_attended = 0;       // objects[0].id, or 0 when no foreground object is visible
  double seconds = 0;            // time the update took (wall clock)
  double saliency_seconds = 0;   // of which the pixel saliency map: resampling, features, pyramids, eqs. 3.1-3.6
  double resample_seconds = 0;   // of which the resampling of the G-buffer to the map (and HLS, eq. 3.1)
};

// What the pixel stage (§3.1 and eq. 3.7's sums) hands the object stage for one scene object seen
// in the map: the CPU's update() makes it from its own maps, the GPU's pixel stage
// (backend/gl/gl_attention.h) reads it back, a few values per object.
struct ObjectPixels {
  std::uint32_t id = 0;
  std::size_t pixels = 0;       // n(k): its pixels in the map (the item buffer resampled nearest)
  double sum_saliency = 0;      // the sum of S_p over them
  double sum_x = 0, sum_y = 0;  // the sum of their centres, map coordinates normalised to [0, 1], y down
  double depth_m = 0;           // the median of their view depths (nearest), clamped to [near, far]
};

class AttentionTracker {
 public:
  explicit AttentionTracker(AttentionSettings settings = {});
  ~AttentionTracker();
  AttentionTracker(AttentionTracker&&) noexcept;
  AttentionTracker& operator=(AttentionTracker&&) noexcept;
  // One frame: `g` is the frame's G-buffer, `scene` the scene at `time_s` (objects, camera, their
  // animations), `previous_time_s` the previous frame's time (object motion, observer motion; equal to
  // time_s on the first frame or after reset). Frames are expected in order; a gap of any length or
  // a time going backwards is handled (motion measured over the gap, never NaN).
  const AttentionFrame& update(const GBuffer& g, const Scene& scene, double time_s, double previous_time_s);
  // The object stage alone (eqs. 3.7-3.10 and the Kalman filter, as update() runs it after its maps)
  // on a pixel stage computed elsewhere: `pixels` for a map_size x map_size map, the objects in any
  // order (ids that are not objects of `scene`, and objects without pixels, are not listed). The
  // frame's maps stay empty; `pixel_seconds` is reported as the saliency and resampling time.
  const AttentionFrame& update_objects(const std::vector<ObjectPixels>& pixels, int map_size, const Scene& scene,
                                       double time_s, double previous_time_s, double pixel_seconds = 0);
  // B_m of eq. 3.3 for `o` between the two times (0 when it cannot be measured): what the pixel
  // stage paints into the motion plane.
  float object_motion(const Object& o, double time_s, double previous_time_s);
  const AttentionFrame& last() const { return frame_; }
  const AttentionSettings& settings() const { return settings_; }
  void set_settings(const AttentionSettings& settings);  // resets the temporal state when needed
  void reset();                                          // forget temporal context and filters

 private:
  // Per object: the spatial-context history of eq. 3.10 (a ring of the last lambda T_s, 0 for frames
  // the object was not visible) and its Kalman filter (state: attention and its rate).
  struct Track {
    std::vector<double> spatial;  // ring buffer of lambda values
    std::size_t next = 0;         // where the next T_s goes
    std::size_t zeros = 0;        // consecutive frames with T_s = 0 (the track is dropped after lambda)
    double x = 0, v = 0;               // Kalman state: attention and its rate (per second)
    double p00 = 1, p01 = 0, p11 = 1;  // covariance
    bool filtered = false;             // the filter has a state (the object was visible last frame)
  };
  // Object space: the mesh vertex farthest from the mesh's bounding-box centre (eq. 3.3's p), per mesh.
  struct Extent {
    std::weak_ptr<const Mesh> mesh;  // expired: the address may have been reused, recompute
    glm::vec3 farthest{0.0f};
  };
  glm::vec3 farthest_vertex(const std::shared_ptr<const Mesh>& mesh);
  // The stages of update() that keep the per-object tracks (eqs. 3.8 and 3.10, the Kalman filter).
  // The object stage of update() and update_objects(): eqs. 3.7-3.10, the filter, the ranking.
  void object_stage(const std::vector<ObjectPixels>& pixels, std::size_t npix, const Scene& scene, double time_s,
                    double previous_time_s);
  void age_tracks(const std::map<std::uint32_t, double>& spatial_now, std::size_t lambda);
  void filter_attention(std::vector<ObjectAttention>& objects, std::size_t lambda, double dt);
  static double temporal_context(Track& t, double spatial, std::size_t lambda);
  static double kalman_filter(Track& t, double z, double dt, double q, double rn);
  struct Scratch;
  AttentionSettings settings_;
  std::unique_ptr<Scratch> scratch_;
  AttentionFrame frame_;
  std::map<std::uint32_t, Track> tracks_;
  std::map<const Mesh*, Extent> extents_;
};

}  // namespace fovea::render::attention
