// SPDX-License-Identifier: Apache-2.0
#pragma once
// Mesh simplification with meshoptimizer's quadric edge-collapse simplifier, shared by the scene
// loader's `lod: {"simplify": [...]}` and the LOD chains of renderer/lod/.
#include "scene/scene.h"

namespace fovea::render {

// How vertices that share a position but not a normal (or texture coordinate, colour, tangent) are
// treated. Every attribute of the mesh is carried into the simplified levels.
enum class SeamHandling {
  Keep,  // attribute seams: meshopt collapses along a seam only, both sides together (hard edges stay)
  Weld,  // welded by position first (a shadow index buffer): seams do not limit the simplifier
};

struct SimplifiedMesh {
  Mesh mesh;
  float error_m = 0;  // meshopt's relative error x meshopt_simplifyScale (object-space metres)
};

// Joins vertices identical in every attribute and drops triangles with an out-of-range index.
Mesh join_identical_vertices(const Mesh& in);

// Simplifies `full` to about ratio x its triangles (at least one); the error bound is left open so the
// count decides. `full` should come from join_identical_vertices (seams are then real ones).
SimplifiedMesh simplify_mesh(const Mesh& full, double ratio, SeamHandling seams);

}  // namespace fovea::render
