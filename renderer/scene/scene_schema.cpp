// SPDX-License-Identifier: Apache-2.0
#include "scene/scene_schema.h"

namespace fovea::render::schema {

const Keys& keys_of(Kind k) {
  switch (k) {
    case Kind::Scene: return kSceneKeys;
    case Kind::Camera: return kCameraKeys;
    case Kind::Lens: return kLensKeys;
    case Kind::Animation: return kAnimationKeys;
    case Kind::AnimationKey: return kObjectKeyframeKeys;
    case Kind::Material: return kMaterialKeys;
    case Kind::Object: return kObjectKeys;
    case Kind::Geometry: return kGeometryKeys;
    case Kind::Sphere: return kSphereKeys;
    case Kind::Cylinder: return kCylinderKeys;
    case Kind::Transform: return kTransformKeys;
    case Kind::Lod: return kLodSimplifyKeys;
    case Kind::LodLevel: return kLodLevelKeys;
    case Kind::Light: return kLightKeys;
    case Kind::Display: return kDisplayKeys;
    default: return kNoKeys;  // arrays, maps of user-chosen names, and plain values
  }
}

Kind child_kind(Kind parent, std::string_view key) {
  switch (parent) {
    case Kind::Scene:
      if (key == "camera") return Kind::Camera;
      if (key == "materials") return Kind::Materials;
      if (key == "objects") return Kind::Objects;
      if (key == "lights") return Kind::Lights;
      if (key == "display") return Kind::Display;
      return Kind::Value;
    case Kind::Camera:
      if (key == "lens") return Kind::Lens;
      if (key == "animation") return Kind::Animation;
      return Kind::Value;
    case Kind::Animation: return key == "keys" ? Kind::AnimationKeys : Kind::Value;
    case Kind::Materials: return Kind::Material;  // materials given as {"name": {...}}
    case Kind::Object:
      if (key == "geometry") return Kind::Geometry;
      if (key == "transform") return Kind::Transform;
      if (key == "animation") return Kind::Animation;
      if (key == "lod") return Kind::Lod;
      return Kind::Value;
    case Kind::Geometry:
      if (key == "sphere") return Kind::Sphere;
      if (key == "cylinder") return Kind::Cylinder;
      return Kind::Value;
    default: return Kind::Value;
  }
}

Kind element_kind(Kind parent) {
  switch (parent) {
    case Kind::Objects: return Kind::Object;
    case Kind::Lights: return Kind::Light;
    case Kind::Materials: return Kind::Material;
    case Kind::AnimationKeys: return Kind::AnimationKey;
    case Kind::Lod: return Kind::LodLevel;
    default: return Kind::Value;
  }
}


}  // namespace fovea::render::schema
