// SPDX-License-Identifier: Apache-2.0
#pragma once
// CSF-driven peripheral ray casting (Murphy 2007, "Hybrid Image/Model-Based Gaze-Contingent
// Rendering", ch. 4-5): cast rays only as densely as the eye can resolve at each eccentricity,
// connect them into an intermediate mesh of concentric rings around the point of regard, refine the
// quads a silhouette passes through, and fill the full-resolution image from that mesh.
//
// Contrast sensitivity: Geisler & Perry's model, Murphy 2007 eqs. 4.1-4.3 (perception/csf.h, which
// the LOD pass's gaze policy uses too): f_c(e), the highest frequency visible at eccentricity e.
//
// Sampling: Murphy discretises eq. 4.3 against "a ray every n pixels" (4.4.4); here the image's pixel
// grid resolves at most its Nyquist frequency N(p) = 1 / (2 * pixel pitch in degrees) at pixel p
// (pitch from protocol::DisplayGeometry: the image fills the screen). A ray every s pixels resolves
// N / s, so the eye needs
//   s(p) = N(p) / (quality * f_c(e(p)))   pixels between rays,
// one ray per pixel where s <= 1 (f_c >= N: the foveal disc), and rays spaced by s (clamped to the
// settings' ring spacing range) further out, so the ray density falls as (f_c / N)^2.
//
// Intermediate mesh (Murphy 4.4.4, 5.2.2): every pixel inside the foveal disc gets its own ray (the
// disc is not part of the mesh); outside it, concentric rings. Ring k+1 lies s_k pixels outside ring
// k (s_k: the spacing at ring k's radius, the smallest over directions, so no direction is
// undersampled), and ring k has ceil(2 pi r_k / s_k) vertices, so the ray spacing along and across
// the rings is the same. Vertex counts change from ring to ring; consecutive rings are joined by a
// zipper over angle that emits a quad where the two rings' next vertices line up and a triangle,
// stored as a quad with a repeated index, where one ring has an extra vertex. Vertices sit at pixel
// centres (a ray through a vertex is the ray of that pixel) and vertices landing on the same pixel
// are merged. Quads entirely off the screen are dropped. When no pixel needs full-rate rays (the
// foveal disc is empty), a vertex at the point of regard is joined to the first ring by a fan.
//
// Silhouette refinement (Murphy 5.2.3): a quad whose corners hit different objects is subdivided
// at its edge midpoints and centre (rays at the new points), recursively, down to pieces at most one
// pixel across; there every pixel centre the piece covers gets its own ray. With
// `refine_neighbours`, quads sharing an edge with a disagreeing quad get a ray through every pixel
// they cover: a silhouette that enters and leaves a quad through the same edge (near-tangent to it)
// leaves that quad's corners in agreement, and no subdivision sample is sure to find it, but its
// neighbour across the edge disagrees.
//
// Reconstruction: pixels in the foveal disc and in pixel-level pieces are ray cast; pixels in
// pieces whose corners agree take that object id and the colour interpolated (barycentrically, the
// quad split along its 0-2 diagonal) from the corners; any pixel no piece covers is ray cast.
//
// Hard cases: a NaN or infinite gaze coordinate means the screen centre (no gaze known: the centre is
// the likeliest point of regard). A gaze outside the screen is used as given, but pulled to within 16
// image sizes of the screen (a desktop display then sees every pixel at > 60 deg eccentricity, where
// the spacing is at or near its maximum, and positions stay precise in float). 0x0 images give empty
// results without calling any callback; 1x1 images one ray. A display geometry that
// protocol::validate rejects, and invalid settings (see validate(CsfSettings)), throw
// std::invalid_argument naming the field. Quality 0 is the coarsest sampling (every ring at the
// maximum spacing, no foveal disc); negative, NaN or infinite quality is rejected.
#include <cstdint>
#include <functional>
#include <glm/glm.hpp>
#include <string>
#include <vector>

#include "fovea/protocol/display_geometry.h"
#include "perception/csf.h"

namespace fovea::render::gi {

// The eye's contrast sensitivity (Geisler & Perry's constants ct0, alpha, e2_deg; perception/csf.h)
// and how densely to sample against it.
struct CsfSettings : perception::GeislerPerry {
  // Multiplies the cutoff frequency the rays must resolve: 2 halves the spacing (about 4x the
  // peripheral rays), 0.5 doubles it. 0: the coarsest sampling. Finite and >= 0.
  double quality = 1.0;
  // Range of the distance between rings (and between rays along a ring), in pixels; 1 <= min <= max.
  double min_ring_spacing_px = 1.0;
  double max_ring_spacing_px = 16.0;
  // Also refine the quads that share an edge with a quad whose corners disagree (see above).
  bool refine_neighbours = true;
};

// Empty when the settings are usable; otherwise the field, its value and the allowed range.
std::string validate(const CsfSettings& settings);

// Eqs. 4.1-4.3 for these settings' constants.
using perception::contrast_threshold;
using perception::cutoff_eccentricity_deg;
using perception::cutoff_frequency_cpd;

// The per-pixel quantities of the sampling for one image on one display and one point of regard.
// Positions are continuous pixel coordinates (pixel (x, y) spans [x, x+1) x [y, y+1), its centre is
// (x + 0.5, y + 0.5)); the image fills the screen, so a W x H image on a display of any resolution
// has W x H pixels of width_m / W x height_m / H metres.
class CsfSamplingField {
 public:
  // Throws std::invalid_argument for a geometry validate() rejects or invalid settings. The gaze is
  // resolved as described at the top (NaN: the centre; far off: pulled in).
  CsfSamplingField(const protocol::DisplayGeometry& display, std::uint32_t width, std::uint32_t height,
                   glm::dvec2 gaze_px, const CsfSettings& settings);

  glm::dvec2 gaze_px() const { return gaze_px_; }
  // Angle between the point of regard and p as seen by the eye (protocol::angle_between_deg).
  double eccentricity_deg(glm::dvec2 p) const;
  // Nyquist frequency of the pixel grid at p in cycles/deg: 1 / (2 pitch), with the pitch the larger
  // of the angles one pixel subtends horizontally and vertically there.
  double nyquist_cpd(glm::dvec2 p) const;
  // f_c(e(p)) of eq. 4.3.
  double cutoff_cpd(glm::dvec2 p) const;
  // Pixels between rays the eye needs at p: nyquist / (quality * f_c), not clamped; +inf at quality 0.
  double required_spacing_px(glm::dvec2 p) const;

 private:
  protocol::DisplayGeometry display_;
  double width_, height_;  // image size in pixels, at least 1 (the geometry maps an empty image too)
  glm::dvec2 gaze_px_;
  protocol::Degrees gaze_deg_;
  CsfSettings settings_;
  protocol::Degrees degrees_at(glm::dvec2 p) const;
};

// Murphy's intermediate mesh of concentric rings around the point of regard.
struct RingMesh {
  std::uint32_t width = 0, height = 0;
  glm::vec2 gaze_px{0.0f};         // the resolved point of regard
  float foveal_radius_px = 0;      // every pixel whose centre is within this distance gets a ray
  std::vector<float> ring_radii_px;             // rings that reach the screen, inner to outer
  std::vector<std::uint32_t> ring_vertex_counts;  // vertices of each full ring (before culling)
  std::vector<glm::vec2> vertices;              // pixel centres, one ray each
  std::vector<std::uint32_t> quads;             // 4 vertex indices per quad; a triangle repeats one

  std::size_t quad_count() const { return quads.size() / 4; }
  std::size_t ring_count() const { return ring_radii_px.size(); }
};

// Throws as CsfSamplingField does.
RingMesh ring_mesh(const protocol::DisplayGeometry& display, std::uint32_t width, std::uint32_t height,
                   glm::vec2 gaze_px, const CsfSettings& settings);

// Which pixels get a ray before silhouette refinement: the foveal disc and the mesh's vertices.
struct CsfRayMask {
  std::uint32_t width = 0, height = 0;
  std::vector<std::uint8_t> mask;  // row-major, 1: a ray through this pixel's centre

  bool at(std::uint32_t x, std::uint32_t y) const { return mask[std::size_t{y} * width + x] != 0; }
  std::uint64_t rays() const;
  std::uint64_t full_resolution_rays() const { return std::uint64_t{width} * height; }
};

CsfRayMask ray_mask(const RingMesh& mesh);
CsfRayMask csf_ray_mask(const protocol::DisplayGeometry& display, std::uint32_t width, std::uint32_t height,
                        glm::vec2 gaze_px, const CsfSettings& settings);

// The ray-casting callbacks: the object a ray through pixel position px hits (0: background), and the
// colour of that hit. Positions are continuous pixel coordinates and may lie a little off the screen
// (vertices of quads that straddle its border).
using ObjectAt = std::function<std::uint32_t(glm::vec2 px)>;
using ColourAt = std::function<glm::vec3(glm::vec2 px, std::uint32_t object_id)>;

// A leaf of the refinement: four samples (a triangle repeats one). Uniform pieces (all corners hit
// the same object) are interpolated; pixel-level pieces get a ray per covered pixel.
struct RefinedPiece {
  std::uint32_t corners[4] = {0, 0, 0, 0};  // indices into SilhouetteRefinement's samples
  bool pixel_level = false;
};

struct SilhouetteRefinement {
  // Samples: the mesh's vertices (same indices), then the points added by subdivision.
  std::vector<glm::vec2> sample_px;
  std::vector<std::uint32_t> sample_object;
  std::vector<RefinedPiece> pieces;
  std::vector<std::uint8_t> quad_refined;  // per mesh quad: 1 when it was subdivided
  std::uint64_t rays_cast = 0;             // object_at calls: mesh vertices plus subdivision points
  std::uint64_t refined_quads = 0;         // mesh quads with disagreeing corners, plus their neighbours
  std::uint64_t disagreeing_quads = 0;     // mesh quads whose corners disagree
};

SilhouetteRefinement refine_silhouettes(const RingMesh& mesh, const ObjectAt& object_at, const CsfSettings& settings);

struct CsfStats {
  std::uint64_t full_resolution_rays = 0;  // width * height
  std::uint64_t rays_cast = 0;             // every object_at call
  std::uint64_t mesh_rays = 0;             // one per mesh vertex
  std::uint64_t refinement_rays = 0;       // subdivision points
  std::uint64_t foveal_rays = 0;           // pixels of the foveal disc
  std::uint64_t pixel_level_rays = 0;      // pixels of pixel-level pieces
  std::uint64_t gap_rays = 0;              // pixels no piece covered
  std::uint64_t rings = 0, quads = 0, refined_quads = 0, disagreeing_quads = 0, pixel_level_pieces = 0;

  double ray_fraction() const {
    return full_resolution_rays == 0 ? 0.0 : static_cast<double>(rays_cast) / static_cast<double>(full_resolution_rays);
  }
};

struct CsfReconstruction {
  std::uint32_t width = 0, height = 0;
  std::vector<std::uint32_t> object_ids;  // row-major
  std::vector<glm::vec3> colours;         // row-major
  CsfStats stats;
};

// Fills every pixel of the mesh's image from the refinement (see the top of this header).
CsfReconstruction reconstruct(const RingMesh& mesh, const SilhouetteRefinement& refinement, const ObjectAt& object_at,
                              const ColourAt& colour_at);

// ring_mesh, refine_silhouettes and reconstruct in one call.
CsfReconstruction render_csf(const protocol::DisplayGeometry& display, std::uint32_t width, std::uint32_t height,
                             glm::vec2 gaze_px, const CsfSettings& settings, const ObjectAt& object_at,
                             const ColourAt& colour_at);

}  // namespace fovea::render::gi
