// SPDX-License-Identifier: Apache-2.0
#pragma once
// Depth of field by layered blurring with depth-peeled input: Schedl & Wimmer, "A layered
// depth-of-field method for solving partial occlusion" (JWSCG 2012), as a CPU image operation.
//
//   L_k = (I_0 w_k(Z_0)) over (I_1 w'_k(Z_1)) over ... (I_{M-1} w'_k(Z_{M-1}))       eq. 2
//   w'_k: 0 -> 1 over [z_{k-2}, z_{k-1}], 1 over [z_{k-1}, z_k], 0 behind (hard back cut)  eq. 3
//   w_k:  as w'_k, but falling 1 -> 0 over [z_k, z_{k+1}]                                eq. 4
//   anchors z_k = D1((d_k + d_{k+1}) / 2) in front of the focus layer, D2(...) behind  eqs. 5-9
//   d_pix = 4 sigma                                                                        eq. 10
//   cascaded blur: front  L^_k = (L^_{k-1} over L_k) * H^_k, back  L^_k = (L_k over L^_{k+1}) * H^_k
//   I' = L^_{kf-1} over (L_kf over L^_{kf+1}), sigma^_k = |k - kf|                  eqs. 11-14
//   the layers' own blur sigma_k = sqrt(sigma^_k^2 + sigma_{k -+ 1}^2)                   eq. 15
// Colours are premultiplied by alpha throughout and the result divided by its alpha (§3.3.1).
//
// Choices the paper leaves open, here:
// - Depth peeling gives layers I_1.. of the next objects behind the visible one (Embree,
//   BackendSettings::peel); M = 1 (visible only) works too, without the hidden content.
// - The Gaussian H^_k is approximated by three box blurs of matched variance (Wells 1986), O(1) per
//   pixel whatever sigma, edges clamped.
// - Layers are added until the anchors cover the frame's depth range (nearest and farthest finite
//   depth of every input layer), at most max_layers; D2's bound (eq. 8) ends the back layers early
//   (the last one reaches infinity).
// - The front layer L_0 has z_{-2} = z_{-1} = -inf, the back layer z_{K-1} = z_K = +inf.
#include <cstdint>
#include <optional>
#include <vector>

#include "dof/dof_image.h"

namespace fovea::render::dof {

// A depth-peeled layer behind the visible one (colour, depth: +inf or the far plane where empty).
struct PeeledLayer {
  const glm::vec3* color = nullptr;
  const float* depth = nullptr;
};

struct SchedlSettings {
  int max_layers = 64;  // K at most (front + focus + back)
};

struct SchedlStats {
  int layers = 0;       // K
  int focus_layer = 0;  // k_focus
  double seconds = 0;
};

// The K layers' boundaries (eqs. 5-9), front to back, and the focus layer kf: what the GPU
// implementation (backend/gl/gl_schedl_layered.h) takes from the CPU's own choice.
struct SchedlAnchors {
  std::vector<double> z;  // z[k], k = 0..K-2: the boundary between layers k and k+1
  int kf = 0;
  int K = 1;
  // z_k, with -inf in front of the front layer and +inf behind the back layer.
  double anchor(int k) const;
};
// The anchors for a frame whose finite depths (every input layer's) span [zmin, zmax] (zmin = +inf:
// none), at most max_layers layers; nullopt when no depth blurs by half a pixel (the output is then
// the input).
std::optional<SchedlAnchors> schedl_anchors(const CocModel& coc, double zmin, double zmax, int max_layers);
// The radii of three box blurs whose variances add up to sigma^2 (Wells 1986): eq. 11's H^_k.
std::vector<int> schedl_box_radii(double sigma);

// `peeled` are the layers behind the visible image of `in` (in.hidden_* is ignored: pass it here).
// out is resized to in.pixels(); finite, >= 0 and at most the inputs' largest channel. A pinhole
// (or every CoC below half a pixel) returns the input exactly (non-finite colour as 0).
void schedl_layered(const DofInput& in, const std::vector<PeeledLayer>& peeled, const SchedlSettings& s,
                    RgbImage& out, SchedlStats* stats = nullptr);

}  // namespace fovea::render::dof
