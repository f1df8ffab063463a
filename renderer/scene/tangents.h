// SPDX-License-Identifier: Apache-2.0
#pragma once
// Tangent frames for normal maps when a glTF file gives none: glTF 2.0 (§3.7.2.1) asks for
// MikkTSpace (Mikkelsen 2008, "Simulation of Wrinkled Surfaces Revisited"), the frame the tools that
// bake normal maps use. This follows the reference implementation's rules with its default settings
// (angular threshold 180°, so one tangent per group):
//   - vertices are welded by value (position, normal, texture coordinate), so duplicates an exporter
//     wrote count as one;
//   - around each welded vertex, triangles form groups: connected through shared, consistently wound
//     edges and of the same UV orientation (the sign of their texture-space area), so the two sides
//     of a mirrored UV seam never mix;
//   - a group's tangent and bitangent are the sums of its triangles' dP/du and dP/dv directions,
//     each projected into the vertex normal's plane, normalised and weighted by the triangle's angle
//     at the vertex (that angle measured in the normal's plane);
//   - a degenerate triangle (no UV area) takes a tangent another triangle at the same vertex has.
// Where one mesh vertex ends up with two tangents (a mirrored seam the file did not split), the
// vertex is split: the result is exactly MikkTSpace's per-corner output re-indexed.
//
// Not bit-identical to mikktspace.c: its fixed-point welding and float summation order differ,
// which moves tangents by rounding only.
#include <cstdint>
#include <vector>

#include "scene/scene.h"

namespace fovea::render {

// Fills mesh.tangents from texture-coordinate set `set` (which must have one coordinate per vertex),
// splitting vertices whose corners need different tangents (every attribute array is extended).
// w follows glTF: cross(normal, tangent) * w is the bitangent, pointing up the image (decreasing v).
void generate_mikktspace_tangents(Mesh& mesh, std::uint32_t set);

}  // namespace fovea::render
