// SPDX-License-Identifier: Apache-2.0
#pragma once
// Procedural meshes for bundled scenes and tests. All are centred at the origin, unit-sized as
// documented, with outward normals and counter-clockwise front faces.
#include "scene/scene.h"

namespace fovea::render {

Mesh make_box(glm::vec3 size);                          // axis-aligned, size in metres
Mesh make_sphere(float radius, int rings, int segments);
Mesh make_plane(glm::vec2 size);                        // in XZ, normal +Y
Mesh make_cylinder(float radius, float height, int segments);  // axis Y, capped

}  // namespace fovea::render
