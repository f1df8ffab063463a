// SPDX-License-Identifier: Apache-2.0
#pragma once
// Photons and the photon map: a left-balanced kd-tree over photon positions with k-nearest-neighbour
// search, and the radiance estimate (Jensen 2001; Jensen & Pedersen 2009, §6.2.3 and §6.3.2).
//
// The photons themselves stay where the tracer wrote them (an array in trace order, with parent
// links between the stored photons of one trace, as the gaze photons of Jensen & Pedersen §8.4.2);
// the tree holds indices, so a map can index any subset of them (the indirect photons, the caustic
// photons, ...) and parent links never move.
//
// Complexity: build O(n log n) (nth_element per level); a k-nearest query O(k log n) on average.
#include <cstdint>
#include <functional>
#include <glm/glm.hpp>
#include <limits>
#include <span>
#include <vector>

namespace fovea::render::gi {

inline constexpr std::uint32_t kNoParent = std::numeric_limits<std::uint32_t>::max();

// Table 8.2's flag bits (Jensen & Pedersen 2009, §8.4.2).
enum PhotonFlag : std::uint8_t {
  kInGazeRegion = 1u << 0,   // used to shade the gaze area in the last frame's render
  kOnPathToGaze = 1u << 1,   // part of a trace that reached the gaze region (set by back-tracking)
  kChildInGaze = 1u << 2,    // its child photon is in the gaze region
  kTraditional = 1u << 3,    // emitted by the naive emitter ("reserved for photon power scaling")
};

// How a photon's trace was emitted (§8.4.6's three bins).
enum class EmissionKind : std::uint8_t { Traditional, NewGaze, OldGaze };

struct Photon {
  glm::vec3 position{0.0f};
  glm::vec3 power{0.0f};       // W per channel
  glm::vec3 incoming{0.0f};    // unit direction of travel when it arrived (Jensen's indir)
  glm::vec3 outgoing{0.0f};    // unit direction it left in (the next photon's incoming; 0 at the end)
  glm::vec3 normal{0.0f};      // unit surface normal where it was stored (front side: dot(incoming, n) < 0)
  glm::vec3 emission_origin{0.0f};     // where its trace left the light
  glm::vec3 emission_direction{0.0f};  // and which way (the photon emission map's entry, §8.4.5)
  std::uint32_t parent = kNoParent;  // the previous stored photon of the same trace
  std::uint32_t seed = 0;            // the trace's frame-coherent seed (§8.4.6)
  std::uint8_t flags = 0;            // PhotonFlag bits
  std::uint8_t light = 0;            // index of the emitting light (0..255)
  std::uint8_t diffuse_bounces = 0;  // diffuse reflections before this hit (0: lit straight from the light)
  bool via_specular = false;         // reached here through at least one specular bounce (mirror, glass)
  EmissionKind kind = EmissionKind::Traditional;
};

// The k nearest photons of a query, nearest first; squared distances alongside.
struct Neighbours {
  std::vector<std::uint32_t> index;
  std::vector<float> distance2;
  float radius2 = 0;  // squared radius of the sphere the search used (the farthest neighbour's when k were found)
  void clear() {
    index.clear();
    distance2.clear();
    radius2 = 0;
  }
  std::size_t size() const { return index.size(); }
};

// The radiance estimate's filter (Jensen 2001, §7.2.2): constant over the disc of radius r
// (dividing by pi r^2), or the cone filter w = 1 - d / (k r), normalised by 1 - 2 / (3k).
enum class EstimateFilter { Disc, Cone };

struct EstimateSettings {
  std::uint32_t nearest = 240;  // nNN (Table 8.3)
  float max_radius = 0.3f;      // NNRadius, metres (Table 8.3)
  EstimateFilter filter = EstimateFilter::Cone;
  float cone_k = 1.1f;  // Jensen's k >= 1 (values below 1 are read as 1)
  // Every photon within max_radius, the disc's radius max_radius (`nearest` is not read): the radius
  // gather of GPU photon mapping (a hash grid cannot keep the k nearest cheaply), and its CPU
  // reference. Where photons are dense it averages over a larger disc than the k nearest would
  // (more blur, less noise); where sparse, over fewer photons (more noise).
  bool fixed_radius = false;
};

class PhotonMap {
 public:
  // Indexes photons[i] for every i in `subset` (all photons when subset is empty and all_if_empty).
  // Photons with non-finite positions are left out. The span must outlive the map (or the next build).
  void build(std::span<const Photon> photons, std::span<const std::uint32_t> subset);
  void build_all(std::span<const Photon> photons);
  void clear();

  std::size_t size() const { return nodes_.size(); }
  bool empty() const { return nodes_.empty(); }
  std::span<const Photon> photons() const { return photons_; }
  // The indexed photons (indices into photons()), in the tree's order: what a copy of the map needs.
  std::vector<std::uint32_t> indexed() const;

  // The (up to) k nearest indexed photons within max_radius of x that pass `accept` (all when empty).
  // k = 0 or max_radius <= 0 (or NaN): none. Results nearest first.
  void nearest(const glm::vec3& x, std::uint32_t k, float max_radius, Neighbours& out,
               const std::function<bool(const Photon&)>& accept = {}) const;

  // Every indexed photon within radius of x (unordered).
  void within(const glm::vec3& x, float radius, std::vector<std::uint32_t>& out) const;

  // Irradiance-like flux density at x on a surface with unit normal n: sum of the powers of the
  // nearest photons arriving at the front side, weighted by the filter, over the disc's area
  // (Jensen & Pedersen eqs. 6.4-6.6 without the BRDF). `weight` (optional) multiplies each photon's
  // power, e.g. by the BRDF towards the viewer: radiance = flux_density(..., f_r). Finite always;
  // 0 when fewer than one photon is found. `used` (optional) receives the photons that contributed;
  // scratch.radius2 the squared radius of the disc they were gathered from.
  glm::vec3 flux_density(const glm::vec3& x, const glm::vec3& n, const EstimateSettings& s, Neighbours& scratch,
                         const std::function<glm::vec3(const Photon&)>& weight = {},
                         std::vector<std::uint32_t>* used = nullptr) const;

 private:
  struct Node {
    glm::vec3 position;
    std::uint32_t photon;  // index into photons_
    std::uint8_t axis;     // splitting axis of this node (0..2), 3 for a leaf
  };
  std::span<const Photon> photons_;
  std::vector<Node> nodes_;  // left-balanced heap order: children of i at 2i+1 and 2i+2
  void build_subtree(std::vector<Node>& items, std::size_t begin, std::size_t end, std::size_t slot);
};

}  // namespace fovea::render::gi
