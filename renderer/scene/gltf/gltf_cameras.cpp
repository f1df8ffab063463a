// SPDX-License-Identifier: Apache-2.0
// What a node carries besides a mesh: cameras (glTF 2.0 §3.10: perspective, orthographic) and
// KHR_lights_punctual lights (directional, point, spot), every parameter range checked.
#include <numbers>
#include <string>

#include "scene/gltf/gltf_parse.h"

namespace fovea::render::gltf::detail {

namespace {

const Range kPositive{0, 1e30, true, false, ""};
const Range kNonNegative{0, 1e30, false, false, ""};

Camera read_camera(const Parser& p, const Node& n) {
  Camera c;
  const std::string t = p.typed_object(n, "a camera: type and its parameters", &c.name, "perspective or orthographic");
  if (t == "perspective") {
    const Node pp = p.require(n, "perspective", "the perspective parameters");
    p.expect_object(pp, "yfov, znear, zfar, aspectRatio");
    c.yfov_rad = p.number_f(p.require(pp, "yfov", "the vertical field of view in radians"),
                            Range{0, std::numbers::pi, true, true, "rad"});
    c.znear = p.number_f(p.require(pp, "znear", "the near clip distance"), kPositive);
    if (const auto zf = Parser::get(pp, "zfar")) {
      c.zfar = p.number_f(*zf, kPositive);
      if (!(*c.zfar > c.znear)) p.fail(*zf, "must be greater than znear (" + json::format_number(c.znear) + ")");
    }
    if (const auto ar = Parser::get(pp, "aspectRatio")) c.aspect_ratio = p.number_f(*ar, kPositive);
  } else if (t == "orthographic") {
    c.type = Camera::Type::Orthographic;
    const Node o = p.require(n, "orthographic", "the orthographic parameters");
    p.expect_object(o, "xmag, ymag, znear, zfar");
    const Range nonzero{-1e30, 1e30, false, false, ""};
    for (const char* key : {"xmag", "ymag"}) {
      const Node v = p.require(o, key, "the half extent of the view");
      const float x = p.number_f(v, nonzero);
      if (x == 0.0f) p.fail(v, "must not be zero");
      (std::string_view(key) == "xmag" ? c.xmag : c.ymag) = x;
    }
    c.znear = p.number_f(p.require(o, "znear", "the near clip distance"), kNonNegative);
    const Node zf = p.require(o, "zfar", "the far clip distance");
    c.zfar = p.number_f(zf, kPositive);
    if (!(*c.zfar > c.znear)) p.fail(zf, "must be greater than znear (" + json::format_number(c.znear) + ")");
  } else {
    p.fail(n.path + ".type", &n.v.at("type"), "must be perspective or orthographic");
  }
  return c;
}

Light read_light(const Parser& p, const Node& n) {
  Light l;
  const std::string t = p.typed_object(n, "a light: type, color, intensity, range, spot", &l.name, "directional, point or spot");
  if (t == "directional") {
    l.type = Light::Type::Directional;
  } else if (t == "point") {
    l.type = Light::Type::Point;
  } else if (t == "spot") {
    l.type = Light::Type::Spot;
  } else {
    p.fail(n.path + ".type", &n.v.at("type"), "must be directional, point or spot");
  }
  if (const auto c = Parser::get(n, "color")) l.color = p.vec3(*c, Range{0, 1, false, false, ""}, "linear RGB, each in [0, 1]");
  l.intensity = p.number_or(n, "intensity", kNonNegative, 1.0f);
  if (const auto r = Parser::get(n, "range")) l.range = p.number_f(*r, kPositive);
  if (l.type == Light::Type::Spot) {
    const Node spot = p.require(n, "spot", "the spot light's cone angles");
    p.expect_object(spot, "innerConeAngle, outerConeAngle");
    constexpr double kHalfPi = std::numbers::pi / 2;
    l.outer_cone_rad = p.number_or(spot, "outerConeAngle", Range{0, kHalfPi, true, false, "rad"}, l.outer_cone_rad);
    l.inner_cone_rad = p.number_or(spot, "innerConeAngle", Range{0, l.outer_cone_rad, false, true, "rad (below outerConeAngle)"},
                                   0.0f);
  }
  return l;
}

}  // namespace

void read_cameras_and_lights(Parser& p, const Node& root) {
  p.each(root, "cameras", [&](const Node& n) { p.asset.cameras.push_back(read_camera(p, n)); });
  const auto ext = p.object(root, "extensions", "the asset's extensions");
  if (!ext) return;
  const auto punctual = p.object(*ext, "KHR_lights_punctual", "the lights");
  if (!punctual) return;
  p.each(*punctual, "lights", [&](const Node& n) { p.asset.lights.push_back(read_light(p, n)); });
}

}  // namespace fovea::render::gltf::detail
