// SPDX-License-Identifier: Apache-2.0
#include "scene/scene_loader.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <string_view>
#include <utility>

#include "scene/geometry.h"
#include "scene/gltf/gltf_scene.h"
#include "scene/json_path.h"
#include "scene/mesh_io.h"
#include "scene/mesh_simplify.h"
#include "scene/scene_gltf_include.h"
#include "scene/scene_overrides.h"
#include "scene/scene_schema.h"

namespace fovea::render {

namespace {

using namespace json;
using namespace schema;

constexpr double kMaxCoordinate = 1e6;  // metres; larger values lose float precision in the backends
// The scene's memory budget, checked before anything is allocated (issue 23 item 8: 20 spheres at
// the largest rings and segments took 5.5 GB, a 16384^2 camera ended in a bare std::bad_alloc).
// The renderer holds ~170 bytes per triangle (mesh, BVH, LOD levels, GPU buffers: measured with
// 10,000 spheres), so 32 M triangles is ~5 GB; a 28 M-triangle scan still loads.
constexpr std::uint64_t kMaxSceneTriangles = 32'000'000;
constexpr std::uint64_t kMaxCameraPixels = std::uint64_t{7680} * 4320;  // 8K UHD

// The scene's sections, read through json::Reader (errors by path) against the schema.
class Loader : private json::Reader {
 public:
  Loader(std::string source, std::filesystem::path base_dir, LoadReport* report = nullptr)
      : json::Reader(std::move(source)), base_dir_(std::move(base_dir)), report_(report) {}

  json::Reader& reader() { return *this; }

  // ---- sections ----
  Scene build(const Json& doc, const std::string& default_name);

 private:
  glm::vec3 position(const Node& n, const char* what) const {
    return vec3(n, Range{-kMaxCoordinate, kMaxCoordinate, false, false, "m"}, what);
  }
  Camera camera(const Node& n, Camera c = {});
  Lens lens(const Node& n);
  Animation animation(const Node& n, bool camera);
  std::vector<Material> materials(const Node& n);
  Material material(const Node& n, std::string name);
  Transform transform(const Node& n);
  // A geometry as read and checked, before its mesh is built.
  struct Shape {
    std::string kind;  // mesh, box, plane, sphere, cylinder
    Node node;         // the shape's own node ($...geometry.sphere)
    glm::vec3 size{0.0f};
    float radius = 0, height = 0;
    int rings = 16, segments = 32;
    std::uint64_t triangles = 0;  // known before building (0 for a mesh file: counted once read)
    std::string what;             // for the budget's message
  };
  Shape shape(const Node& geometry);
  std::shared_ptr<const Mesh> build_shape(const Shape& s);
  void budget_procedural_shapes(const Node& objects);
  std::shared_ptr<const Mesh> mesh_file(const Node& n);
  // The levels the scene gives (files or simplification ratios), or none and the chain it asks for.
  std::vector<LodLevel> lods(const Node& n, const Mesh& full, std::optional<LodChainRequest>& chain);
  Light light(const Node& n);
  protocol::DisplayGeometry display(const Node& n);
  void check_finite(const Scene& s) const;

  // Counts a geometry's triangles into the scene's budget; fails at `n` before it is built if the
  // scene would exceed kMaxSceneTriangles.
  // `total`: the scene's triangles with this one, when known (the procedural pre-pass).
  void budget_triangles(const Node& n, std::uint64_t triangles, const std::string& what, std::uint64_t total = 0);

  std::filesystem::path base_dir_;
  LoadReport* report_ = nullptr;  // a glTF asset's load phases
  std::map<std::string, std::shared_ptr<const Mesh>> mesh_cache_;  // by resolved path
  std::uint64_t triangles_ = 0;                                     // the scene's so far
};

void Loader::budget_triangles(const Node& n, std::uint64_t triangles, const std::string& what, std::uint64_t total) {
  if (total == 0) total = triangles_ + triangles;
  if (total > kMaxSceneTriangles) {
    fail(n, what + " takes the scene to " + std::to_string(total) + " triangles; a scene may hold " +
                std::to_string(kMaxSceneTriangles) + " (about 5 GB in the renderer): use fewer or coarser objects");
  }
  triangles_ += triangles;
}

// ---------------------------------------------------------------------------------------------
// Sections

Scene Loader::build(const Json& doc, const std::string& default_name) {
  const Node root{doc, "$"};
  check_keys(root, kSceneKeys, "a scene");
  // A glTF asset ($.gltf) gives the objects, materials, camera and lights the JSON does not.
  const auto gltf = get(root, "gltf");
  Scene scene = gltf ? read_gltf_include(*this, *gltf, base_dir_, report_) : Scene{};
  scene.name = default_name;
  if (auto n = get(root, "name")) scene.name = string(*n, "the scene's name");

  if (!gltf) {
    scene.camera = camera(require(root, "camera", "the camera (position, target, lens, ...)"));
  } else if (auto c = get(root, "camera")) {
    // Without a position and target, the file's camera is kept and these fields change it.
    const bool pose = get(*c, "position") || get(*c, "target");
    scene.camera = camera(*c, pose ? Camera{} : scene.camera);
  }

  const std::size_t first_material = scene.materials.size();
  if (auto m = gltf ? get(root, "materials") : require(root, "materials", "the named materials the objects use")) {
    for (Material& mat : materials(*m)) scene.materials.push_back(std::move(mat));
  }

  std::map<std::string, std::string> object_names;  // name -> path of its first use
  for (const Object& o : scene.objects) object_names.emplace(o.name, gltf->path + ".file");
  const std::size_t first_object = scene.objects.size();
  const auto objects_node = gltf ? get(root, "objects") : require(root, "objects", "an array of objects");
  static const Json kEmpty = Json::array();
  const Node objects = objects_node ? *objects_node : Node{kEmpty, "$.objects"};
  if (!objects.v.is_array() || (!gltf && objects.v.empty())) fail(objects, "must be a non-empty array of objects");
  budget_procedural_shapes(objects);
  for (std::size_t i = 0; i < objects.v.size(); ++i) {
    const Node n = element(objects, i);
    check_keys(n, kObjectKeys, "an object");
    Object obj;
    const Node name = require(n, "name", "a unique object name");
    obj.name = string(name, "a unique object name");
    if (obj.name.empty()) fail(name, "must be a non-empty string");
    if (const auto [it, fresh] = object_names.emplace(obj.name, name.path); !fresh) {
      fail(name, "duplicate object name (first used at " + it->second + "); object names must be unique");
    }
    obj.id = static_cast<std::uint32_t>(first_object + i + 1);

    // The JSON's own materials (a glTF asset's are its objects' own).
    const Node mat = require(n, "material", "the name of a material in $.materials");
    const std::string mat_name = string(mat, "the name of a material in $.materials");
    const auto mats_begin = scene.materials.begin() + static_cast<std::ptrdiff_t>(first_material);
    const auto found = std::find_if(mats_begin, scene.materials.end(), [&](const Material& m) { return m.name == mat_name; });
    if (found == scene.materials.end()) {
      std::string known;
      for (auto it = mats_begin; it != scene.materials.end(); ++it) known += (known.empty() ? "" : ", ") + it->name;
      fail(mat, "unknown material; defined materials: " + known);
    }
    obj.material = static_cast<std::uint32_t>(found - scene.materials.begin());

    const Shape geometry = shape(require(n, "geometry", "one of mesh, box, sphere, plane, cylinder"));
    budget_triangles(geometry.node, geometry.triangles, geometry.what);
    obj.mesh = build_shape(geometry);
    if (auto t = get(n, "transform")) obj.transform = transform(*t);
    if (auto a = get(n, "animation")) obj.animation = animation(*a, false);
    if (auto ti = get(n, "task_importance")) obj.task_importance = number_f(*ti, Range{0, 1, false, false, ""});
    if (auto l = get(n, "lod")) obj.lods = lods(*l, *obj.mesh, obj.lod_chain);
    scene.objects.push_back(std::move(obj));
  }

  if (auto lights = get(root, "lights")) {
    if (!lights->v.is_array()) fail(*lights, "must be an array of lights");
    scene.lights.clear();  // a glTF asset's lights (or its default rig) give way to the JSON's
    for (std::size_t i = 0; i < lights->v.size(); ++i) scene.lights.push_back(light(element(*lights, i)));
  }
  if (auto a = get(root, "ambient")) scene.ambient = colour(*a, "ambient radiance [r, g, b] >= 0");
  if (auto b = get(root, "background")) scene.background = colour(*b, "background radiance [r, g, b] >= 0");
  if (auto d = get(root, "display")) scene.display = display(*d);

  check_finite(scene);
  return scene;
}

Camera Loader::camera(const Node& n, Camera c) {
  check_keys(n, kCameraKeys, "the camera");
  if (auto v = get(n, "position")) c.position = position(*v, "camera position [x, y, z] in metres");
  if (auto v = get(n, "target")) c.target = position(*v, "point looked at [x, y, z] in metres");
  if (auto v = get(n, "up")) c.up = direction(*v, "up vector [x, y, z]");
  if (auto v = get(n, "vertical_fov_deg")) c.vertical_fov_deg = number_f(*v, Range{0, 180, true, true, "degrees"});
  if (auto v = get(n, "width")) c.width = static_cast<std::uint32_t>(integer(*v, 1, 16384));
  if (auto v = get(n, "height")) c.height = static_cast<std::uint32_t>(integer(*v, 1, 16384));
  if (std::uint64_t{c.width} * c.height > kMaxCameraPixels) {
    fail(n, "width x height = " + std::to_string(c.width) + "x" + std::to_string(c.height) + " pixels; at most " +
                std::to_string(kMaxCameraPixels) + " (7680x4320) are rendered");
  }
  const auto near = get(n, "near");
  const auto far = get(n, "far");
  if (near) c.near_m = number_f(*near, Range{0, kMaxCoordinate, true, false, "m"});
  if (far) c.far_m = number_f(*far, Range{0, kMaxCoordinate, true, false, "m"});
  if (!(c.near_m < c.far_m)) {
    const Node& at = far ? *far : *near;
    fail(at, "camera near and far must satisfy 0 < near < far (near = " + format_number(c.near_m) +
                 " m, far = " + format_number(c.far_m) + " m)");
  }
  const glm::vec3 view = c.target - c.position;
  if (!(glm::length(view) > 1e-6f)) {
    const auto t = get(n, "target");
    fail(t ? t->path : n.path + ".target", t ? &t->v : nullptr, "camera target must differ from its position");
  }
  if (!(glm::length(glm::cross(glm::normalize(view), c.up)) > 1e-4f)) {
    const auto u = get(n, "up");
    fail(u ? u->path : n.path + ".up", u ? &u->v : nullptr,
         "camera up must not be parallel to the view direction (target - position)");
  }
  if (auto v = get(n, "lens")) c.lens = lens(*v);
  if (auto v = get(n, "animation")) c.animation = animation(*v, true);
  if (auto v = get(n, "stereo")) c.stereo = boolean(*v);
  // 0.063 m is the adult mean; up to 1 m allows hyperstereo (a wider baseline for distant scenes).
  if (auto v = get(n, "ipd_m")) c.ipd_m = number_f(*v, Range{0, 1, true, false, "m"});
  return c;
}

Lens Loader::lens(const Node& n) {
  expect_object(n, "a lens: {\"type\": \"pinhole\" | \"thin-lens\" | \"human-eye\", ...}");
  const Node type_node = require(n, "type", "\"pinhole\", \"thin-lens\" or \"human-eye\"");
  const std::string type = string(type_node, "\"pinhole\", \"thin-lens\" or \"human-eye\"");
  Lens l;
  if (type == "pinhole") {
    check_keys(n, kPinholeKeys, "a pinhole lens");
    l.aperture_m = 0;
    return l;
  }
  if (type == "human-eye") {
    check_keys(n, kHumanEyeKeys, "the human-eye lens");
    // The eye's focal length is 16.7 mm; it can only focus beyond it (Lee 2009, §4.1.2).
    const double focus = number(require(n, "focus_distance_m", "distance the eye is focused at, metres"),
                                Range{0.0167, kMaxCoordinate, true, false, "m"});
    return Lens::human_eye(focus);
  }
  if (type != "thin-lens") fail(type_node, "unknown lens type; allowed: pinhole, thin-lens, human-eye");
  check_keys(n, kThinLensKeys, "a thin lens");
  const double focal_mm =
      number(require(n, "focal_length_mm", "focal length F in millimetres"), Range{0, 10000, true, false, "mm"});
  l.focal_length_m = focal_mm / 1000.0;
  const auto f_number = get(n, "f_number");
  const auto aperture = get(n, "aperture_mm");
  if (f_number && aperture) {
    fail(*aperture, "give either f_number or aperture_mm, not both (aperture diameter E = F / N)");
  }
  if (f_number) {
    l.aperture_m = l.focal_length_m / number(*f_number, Range{0.5, 1024, false, false, ""});
  } else if (aperture) {
    l.aperture_m = number(*aperture, Range{0, 10000, true, false, "mm"}) / 1000.0;
  } else {
    fail(n.path + ".f_number", nullptr, "missing required field: f_number or aperture_mm (the aperture)");
  }
  const Node focus = require(n, "focus_distance_m", "distance the lens is focused at, metres");
  l.focus_distance_m = number(focus, Range{0, kMaxCoordinate, true, false, "m"});
  // Lee 2009, eq. 4.2: a real image exists only for objects beyond the focal length.
  if (!(l.focus_distance_m > l.focal_length_m)) {
    fail(focus, "must be greater than the focal length (" + format_number(focal_mm) + " mm) for a real image");
  }
  if (auto d = get(n, "image_distance_mm")) {
    const double di = number(*d, Range{0, 10000, true, false, "mm"});
    if (!(di > focal_mm)) {
      fail(*d, "must be greater than focal_length_mm (" + format_number(focal_mm) + ") for a real image");
    }
    l.image_distance_m = di / 1000.0;
  }
  return l;
}

Animation Loader::animation(const Node& n, bool camera) {
  check_keys(n, kAnimationKeys, "an animation: {\"loop\": bool, \"keys\": [...]}");
  Animation a;
  if (auto l = get(n, "loop")) a.loop = boolean(*l);
  const Node keys = require(n, "keys", "an array of keyframes {\"t\", \"translation\", \"rotation_deg\"}");
  if (!keys.v.is_array() || keys.v.empty()) fail(keys, "must be a non-empty array of keyframes");
  for (std::size_t i = 0; i < keys.v.size(); ++i) {
    const Node k = element(keys, i);
    check_keys(k, camera ? kCameraKeyframeKeys : kObjectKeyframeKeys,
               camera ? "a camera keyframe (camera animation moves position and target; no rotation)" : "a keyframe");
    AnimationKey key;
    const Node t = require(k, "t", "keyframe time in seconds");
    key.time_s = number(t, Range{0, 1e9, false, false, "s"});
    if (!a.keys.empty() && !(key.time_s > a.keys.back().time_s)) {
      fail(t, "keyframe times must be strictly increasing (previous t = " + format_number(a.keys.back().time_s) + ")");
    }
    if (auto v = get(k, "translation")) key.translation = position(*v, "offset [x, y, z] in metres");
    if (auto v = get(k, "rotation_deg")) key.rotation_deg = vec3(*v, Range{-1e6, 1e6, false, false, "degrees"},
                                                                 "Euler angles [x, y, z] in degrees");
    a.keys.push_back(key);
  }
  return a;
}

std::vector<Material> Loader::materials(const Node& n) {
  std::vector<Material> out;
  if (n.v.is_object()) {
    for (const auto& [name, m] : n.v.items()) {
      const Node mn{m, n.path + key_suffix(name)};
      if (mn.v.is_object() && mn.v.contains("name")) {
        fail(mn.path + ".name", &mn.v["name"], "not allowed when materials is an object: the key is the name");
      }
      if (name.empty()) fail(mn, "material names must be non-empty");
      out.push_back(material(mn, name));
    }
  } else if (n.v.is_array()) {
    std::map<std::string, std::string> seen;
    for (std::size_t i = 0; i < n.v.size(); ++i) {
      const Node mn = element(n, i);
      expect_object(mn, "a material");
      const Node name = require(mn, "name", "a unique material name");
      const std::string s = string(name, "a unique material name");
      if (s.empty()) fail(name, "must be a non-empty string");
      if (const auto [it, fresh] = seen.emplace(s, name.path); !fresh) {
        fail(name, "duplicate material name (first used at " + it->second + ")");
      }
      out.push_back(material(mn, s));
    }
  } else {
    fail(n, "must be an object {\"name\": {material}} or an array [{\"name\": ..., ...}]");
  }
  if (out.empty()) fail(n, "must define at least one material");
  return out;
}

Material Loader::material(const Node& n, std::string name) {
  expect_object(n, "a material");
  Material m;
  m.name = std::move(name);
  const Node type_node = require(n, "type", "lambertian, blinn-phong, mirror, glass or emissive");
  const std::string type = string(type_node, "lambertian, blinn-phong, mirror, glass or emissive");
  const Range unit{0, 1, false, false, ""};
  const auto rgb01 = [&](const Node& v, const char* what) { return vec3(v, unit, what); };
  Keys allowed;
  if (type == "lambertian") {
    allowed = {"type", "kd"};
    m.type = MaterialType::Lambertian;
    m.kd = glm::vec3(0.8f);
    m.ks = glm::vec3(0.0f);
  } else if (type == "blinn-phong") {
    allowed = {"type", "kd", "ks", "shininess"};
    m.type = MaterialType::BlinnPhong;
    m.kd = glm::vec3(0.6f);
    m.ks = glm::vec3(0.3f);
    m.shininess = 32;
  } else if (type == "mirror" || type == "glass") {
    allowed = type == "mirror" ? Keys{"type", "reflectance", "shininess"}
                               : Keys{"type", "reflectance", "ior", "shininess"};
    m.type = type == "mirror" ? MaterialType::Mirror : MaterialType::Glass;
    m.kd = glm::vec3(0.0f);  // local illumination shows only the highlight; reflection is the GI pass's
    m.shininess = 1000;
  } else if (type == "emissive") {
    allowed = {"type", "emission"};
    m.type = MaterialType::Emissive;
    m.kd = glm::vec3(0.0f);
    m.ks = glm::vec3(0.0f);
    m.emission = glm::vec3(1.0f);
  } else {
    fail(type_node, "unknown material type; allowed: lambertian, blinn-phong, mirror, glass, emissive");
  }
  allowed.push_back("comment");
  if (n.v.contains("name")) allowed.push_back("name");  // array form
  for (const auto& [k, v] : n.v.items()) {
    if (std::find(allowed.begin(), allowed.end(), k) != allowed.end()) continue;
    const bool known = std::find(kMaterialKeys.begin(), kMaterialKeys.end(), k) != kMaterialKeys.end();
    fail(n.path + key_suffix(k), &v,
         known ? "field does not apply to a " + type + " material; allowed here: " + join(allowed)
               : unknown_field_message(k, allowed));
  }
  check_keys(n, allowed, "a material");
  if (auto v = get(n, "kd")) m.kd = rgb01(*v, "diffuse coefficient [r, g, b] in [0, 1]");
  if (auto v = get(n, "ks")) m.ks = rgb01(*v, "specular coefficient [r, g, b] in [0, 1]");
  if (auto v = get(n, "shininess")) m.shininess = number_f(*v, Range{0, 1e5, false, false, ""});
  if (auto v = get(n, "reflectance")) m.reflectance = rgb01(*v, "reflectance tint [r, g, b] in [0, 1]");
  if (auto v = get(n, "ior")) m.ior = number_f(*v, Range{1, 10, false, false, ""});
  if (auto v = get(n, "emission")) m.emission = colour(*v, "emitted radiance [r, g, b] >= 0, W/(sr m^2)");
  if (m.type == MaterialType::Mirror || m.type == MaterialType::Glass) m.ks = m.reflectance;
  // The modified Blinn-Phong BRDF f_r = k_s (n.h)^n + k_d (Jensen & Pedersen 2009, eq. 5.22) is not
  // energy conserving; we at least ask that a surface reflect no more than it receives per channel.
  for (int c = 0; c < 3; ++c) {
    if (m.kd[c] + m.ks[c] > 1.0f + 1e-6f) {
      const auto v = get(n, "ks");
      const Node& at = v ? *v : *get(n, "kd");
      fail(at, "kd + ks must be <= 1 in every channel (channel " + std::to_string(c) + ": kd = " +
                   format_number(m.kd[c]) + ", ks = " + format_number(m.ks[c]) + ") so the surface conserves energy");
    }
  }
  return m;
}

Transform Loader::transform(const Node& n) {
  check_keys(n, kTransformKeys, "a transform {\"translation\", \"rotation_deg\", \"scale\"}");
  Transform t;
  if (auto v = get(n, "translation")) t.translation = position(*v, "translation [x, y, z] in metres");
  if (auto v = get(n, "rotation_deg")) {
    t.rotation_deg = vec3(*v, Range{-1e6, 1e6, false, false, "degrees"}, "Euler angles [x, y, z] in degrees");
  }
  if (auto v = get(n, "scale")) {
    const Range r{0, 1e6, true, false, ""};
    t.scale = v->v.is_number() || v->v.is_string() ? glm::vec3(number_f(*v, r))
                                                   : vec3(*v, r, "a number or [x, y, z], each > 0");
  }
  return t;
}

Loader::Shape Loader::shape(const Node& n) {
  check_keys(n, kGeometryKeys, "geometry: one of mesh, box, sphere, plane, cylinder");
  std::optional<Node> found;
  std::string kind;
  for (const std::string_view k : kShapeKeys) {
    if (auto c = get(n, k)) {
      if (found) {
        fail(n, "must have exactly one of " + join(kShapeKeys) + " (found " + kind + " and " + std::string(k) + ")");
      }
      found.emplace(Node{c->v, c->path});
      kind = k;
    }
  }
  if (!found) fail(n, "must have exactly one of " + join(kShapeKeys));
  Shape out{.kind = kind, .node = *found, .what = {}};
  const Node& shape = *found;
  const Range size{0, kMaxCoordinate, true, false, "m"};
  if (kind == "box") {
    out.size = vec3(shape, size, "box size [x, y, z] in metres");
    out.triangles = 12;
  } else if (kind == "plane") {
    out.size = glm::vec3(vec<2>(shape, size, "plane size [x, z] in metres"), 0.0f);
    out.triangles = 2;
  } else if (kind == "sphere") {
    check_keys(shape, kSphereKeys, "a sphere {\"radius\", \"rings\", \"segments\"}");
    out.radius = number_f(require(shape, "radius", "sphere radius in metres"), size);
    out.rings = 16;
    if (auto v = get(shape, "rings")) out.rings = static_cast<int>(integer(*v, 2, 1024));
    if (auto v = get(shape, "segments")) out.segments = static_cast<int>(integer(*v, 3, 2048));
    out.triangles = 2 * static_cast<std::uint64_t>(out.rings) * static_cast<std::uint64_t>(out.segments);
    out.what = "a sphere of " + std::to_string(out.rings) + " rings and " + std::to_string(out.segments) + " segments";
  } else if (kind == "cylinder") {
    check_keys(shape, kCylinderKeys, "a cylinder {\"radius\", \"height\", \"segments\"}");
    out.radius = number_f(require(shape, "radius", "cylinder radius in metres"), size);
    out.height = number_f(require(shape, "height", "cylinder height in metres"), size);
    if (auto v = get(shape, "segments")) out.segments = static_cast<int>(integer(*v, 3, 2048));
    out.triangles = 4 * static_cast<std::uint64_t>(out.segments);
  }
  if (out.what.empty()) out.what = "a " + kind;
  return out;
}

std::shared_ptr<const Mesh> Loader::build_shape(const Shape& s) {
  if (s.kind == "mesh") return mesh_file(s.node);
  if (s.kind == "box") return std::make_shared<const Mesh>(make_box(s.size));
  if (s.kind == "plane") return std::make_shared<const Mesh>(make_plane(glm::vec2(s.size)));
  if (s.kind == "sphere") return std::make_shared<const Mesh>(make_sphere(s.radius, s.rings, s.segments));
  return std::make_shared<const Mesh>(make_cylinder(s.radius, s.height, s.segments));
}

// Before any mesh is built, the procedural shapes' triangles are summed against the budget, so a
// scene over it is refused at the object that crosses it without first building the ones before.
// Errors in a geometry are left to the object loop, which reports them in the file's order.
void Loader::budget_procedural_shapes(const Node& objects) {
  std::uint64_t total = 0;
  for (std::size_t i = 0; i < objects.v.size(); ++i) {
    const Node n = element(objects, i);
    const auto g = n.v.is_object() ? get(n, "geometry") : std::nullopt;
    if (!g) continue;
    std::uint64_t triangles = 0;
    try {
      const Shape s = shape(*g);
      triangles = s.triangles;
      total += triangles;
      if (total > kMaxSceneTriangles) budget_triangles(s.node, triangles, s.what, total);
    } catch (const SceneError&) {
      if (total > kMaxSceneTriangles) throw;  // the budget's own error
    }
  }
}

std::shared_ptr<const Mesh> Loader::mesh_file(const Node& n) {
  const std::string rel = string(n, "a mesh file path relative to the scene file");
  std::filesystem::path path = std::filesystem::path(rel);
  if (path.is_relative()) path = base_dir_ / path;
  path = path.lexically_normal();
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  static const Keys kSupported{".obj", ".ply", ".gltf", ".glb"};
  if (std::find(kSupported.begin(), kSupported.end(), ext) == kSupported.end()) {
    fail(n, "unsupported mesh format '" + (ext.empty() ? std::string("(no extension)") : ext) +
                "'; supported: " + join(kSupported));
  }
  std::error_code ec;
  const auto st = std::filesystem::status(path, ec);
  if (!std::filesystem::exists(st)) fail(n, "mesh file not found: " + path.string());
  // Item 12 of issue 23: a FIFO, device or directory was reported "not found" (a FIFO is never opened).
  if (!std::filesystem::is_regular_file(st)) fail(n, "mesh file " + path.string() + " is not a regular file");
  if (auto it = mesh_cache_.find(path.string()); it != mesh_cache_.end()) return it->second;
  std::shared_ptr<Mesh> mesh;
  try {
    mesh = std::make_shared<Mesh>(read_mesh_file(path));
  } catch (const SceneError& e) {
    fail(n, e.what());
  }
  // A mesh file's size is known only once read (bounded by the file); counted once however often used.
  budget_triangles(n, mesh->indices.size() / 3, "mesh file " + path.filename().string());
  mesh_cache_.emplace(path.string(), mesh);
  return mesh;
}

// ---------------------------------------------------------------------------------------------
// Levels of detail

// Simplifies `full` to about ratio * its triangles (scene/mesh_simplify.h), welding vertices that
// share a position so UV or normal seams do not lock the simplifier (SCENES.md). The error reached
// is returned in metres.
Mesh simplify(const Mesh& full, double ratio, float& error_m) {
  SimplifiedMesh s = simplify_mesh(full, ratio, SeamHandling::Weld);
  error_m = s.error_m;
  return std::move(s.mesh);
}

std::vector<LodLevel> Loader::lods(const Node& n, const Mesh& full, std::optional<LodChainRequest>& chain) {
  std::vector<LodLevel> out;
  if (n.v.is_object() && get(n, "chain")) {
    check_keys(n, kLodSimplifyKeys, "{\"chain\": {...}}, {\"simplify\": [ratios]} or [{\"mesh\", \"max_error_m\"}]");
    if (get(n, "simplify")) fail(n, "give either \"chain\" or \"simplify\", not both");
    const Node c = *get(n, "chain");
    check_keys(c, kLodChainKeys, "an LOD chain {\"levels\", \"base\", \"attributes\"}");
    LodChainRequest request;
    if (auto v = get(c, "levels")) request.levels = static_cast<int>(number(*v, Range{2, 16, false, false, ""}));
    if (auto v = get(c, "base")) request.base = number(*v, Range{1, 1e6, true, false, ""});
    if (auto v = get(c, "attributes")) {
      const std::string a = string(*v, "seams or weld");
      if (a != "seams" && a != "weld") fail(*v, "must be seams or weld");
      request.weld_attributes = a == "weld";
    }
    // Built (or loaded from the disk cache) by lod::attach_chains after loading: the same chain
    // fovea-lod writes.
    request.where = source_ + ": " + c.path;
    chain = std::move(request);
    return out;
  }
  if (n.v.is_object()) {
    check_keys(n, kLodSimplifyKeys, "{\"chain\": {...}}, {\"simplify\": [ratios]} or [{\"mesh\", \"max_error_m\"}]");
    const Node ratios = require(n, "simplify", "an array of triangle-count ratios in (0, 1), decreasing");
    if (!ratios.v.is_array() || ratios.v.empty()) fail(ratios, "must be a non-empty array of ratios in (0, 1)");
    double prev_ratio = 1;
    std::size_t prev_tris = full.triangle_count();
    for (std::size_t i = 0; i < ratios.v.size(); ++i) {
      const Node r = element(ratios, i);
      const double ratio = number(r, Range{0, 1, true, true, ""});
      if (!(ratio < prev_ratio)) {
        fail(r, "ratios must be strictly decreasing (previous " + format_number(prev_ratio) + ")");
      }
      LodLevel level;
      Mesh m = simplify(full, ratio, level.max_error_m);
      if (m.triangle_count() == 0 || m.triangle_count() >= prev_tris) {
        fail(r, "the simplifier reached " + std::to_string(m.triangle_count()) + " triangles, not fewer than the " +
                    std::to_string(prev_tris) + " of the previous level; use a finer mesh or fewer levels");
      }
      prev_tris = m.triangle_count();
      prev_ratio = ratio;
      level.mesh = std::make_shared<const Mesh>(std::move(m));
      out.push_back(std::move(level));
    }
    return out;
  }
  if (!n.v.is_array() || n.v.empty()) {
    fail(n, "must be {\"simplify\": [ratios]} or a non-empty array [{\"mesh\": file, \"max_error_m\": x}]");
  }
  float prev_error = 0;
  for (std::size_t i = 0; i < n.v.size(); ++i) {
    const Node l = element(n, i);
    check_keys(l, kLodLevelKeys, "a level of detail {\"mesh\", \"max_error_m\"}");
    LodLevel level;
    level.mesh = mesh_file(require(l, "mesh", "the mesh file of this level"));
    const Node e = require(l, "max_error_m", "geometric error of this level in metres");
    level.max_error_m = number_f(e, Range{0, kMaxCoordinate, false, false, "m"});
    if (level.max_error_m < prev_error) {
      fail(e, "levels must be ordered from fine to coarse: max_error_m must not decrease (previous " +
                  format_number(prev_error) + ")");
    }
    prev_error = level.max_error_m;
    out.push_back(std::move(level));
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// Lights, display

Light Loader::light(const Node& n) {
  expect_object(n, "a light");
  const Node type_node = require(n, "type", "point, spot or area");
  const std::string type = string(type_node, "point, spot or area");
  Light l;
  if (type == "point") {
    check_keys(n, kPointLightKeys, "a point light");
    l.type = LightType::Point;
  } else if (type == "spot") {
    check_keys(n, kSpotLightKeys, "a spot light");
    l.type = LightType::Spot;
  } else if (type == "area") {
    check_keys(n, kAreaLightKeys, "an area light");
    l.type = LightType::Area;
  } else {
    fail(type_node, "unknown light type; allowed: point, spot, area");
  }
  l.position = position(require(n, "position", "light position [x, y, z] in metres"), "position [x, y, z] in metres");
  l.power = colour(require(n, "power", "radiant power [r, g, b] in watts"), "radiant power [r, g, b] in watts, >= 0");
  if (l.type == LightType::Spot) {
    l.direction = direction(require(n, "direction", "spot axis [x, y, z]"), "spot axis [x, y, z]");
    l.spot_cutoff_deg = number_f(require(n, "cutoff_deg", "half-angle of the cone in degrees"),
                                 Range{0, 90, true, false, "degrees"});
    l.spot_falloff_deg = std::min(5.0f, l.spot_cutoff_deg);
    if (auto f = get(n, "falloff_deg")) {
      l.spot_falloff_deg = number_f(*f, Range{0, static_cast<double>(l.spot_cutoff_deg), false, false,
                                              "degrees (at most cutoff_deg)"});
    }
  } else if (l.type == LightType::Area) {
    l.direction = direction(require(n, "normal", "emitting side's normal [x, y, z]"), "normal [x, y, z]");
    if (auto s = get(n, "size")) {
      l.area_size = vec<2>(*s, Range{0, kMaxCoordinate, true, false, "m"}, "extent [u, v] in metres");
    }
    if (auto s = get(n, "samples")) l.area_samples = static_cast<int>(integer(*s, 1, 16));
  }
  return l;
}

protocol::DisplayGeometry Loader::display(const Node& n) {
  check_keys(n, kDisplayKeys, "display geometry");
  protocol::DisplayGeometry g;
  if (auto v = get(n, "width_px")) g.width_px = static_cast<std::uint32_t>(integer(*v, 1, 65536));
  if (auto v = get(n, "height_px")) g.height_px = static_cast<std::uint32_t>(integer(*v, 1, 65536));
  const Range mm{0, 100000, true, false, "mm (a display needs a non-zero area)"};
  if (auto v = get(n, "width_mm")) g.width_m = number(*v, mm) / 1000.0;
  if (auto v = get(n, "height_mm")) g.height_m = number(*v, mm) / 1000.0;
  if (auto v = get(n, "viewing_distance_mm")) {
    g.viewing_distance_m = number(*v, Range{0, 100000, true, false, "mm"}) / 1000.0;
  }
  if (const std::string err = protocol::validate(g); !err.empty()) fail(n, "invalid display geometry: " + err);
  return g;
}

// The last line of defence of "no NaN or Inf crosses a module boundary": everything above
// validated its inputs, so a failure here is a loader bug, reported rather than passed on.
void Loader::check_finite(const Scene& s) const {
  const auto bad = [&](const std::string& what) { throw SceneError(source_ + ": internal error: non-finite " + what); };
  const auto v3 = [&](const glm::vec3& v, const std::string& what) {
    if (!all_finite(v)) bad(what);
  };
  const auto tr = [&](const Transform& t, const std::string& what) {
    v3(t.translation, what + " translation");
    v3(t.rotation_deg, what + " rotation");
    v3(t.scale, what + " scale");
  };
  const auto anim = [&](const std::optional<Animation>& a, const std::string& what) {
    if (!a) return;
    for (const AnimationKey& k : a->keys) {
      if (!std::isfinite(k.time_s)) bad(what + " key time");
      v3(k.translation, what + " key translation");
      v3(k.rotation_deg, what + " key rotation");
    }
  };
  const auto mesh = [&](const Mesh& m, const std::string& what) {
    for (const glm::vec3& p : m.positions) v3(p, what + " vertex");
    for (const glm::vec3& p : m.normals) v3(p, what + " normal");
  };
  const Camera& c = s.camera;
  v3(c.position, "camera position");
  v3(c.target, "camera target");
  v3(c.up, "camera up");
  anim(c.animation, "camera animation");
  for (const double d : {c.lens.focal_length_m, c.lens.aperture_m, c.lens.focus_distance_m, c.lens.image_distance_m}) {
    if (!std::isfinite(d)) bad("lens parameter");
  }
  for (const Material& m : s.materials) {
    v3(m.kd, m.name + " kd");
    v3(m.ks, m.name + " ks");
    v3(m.reflectance, m.name + " reflectance");
    v3(m.emission, m.name + " emission");
    if (!std::isfinite(m.shininess) || !std::isfinite(m.ior)) bad(m.name + " shininess/ior");
  }
  for (const Object& o : s.objects) {
    tr(o.transform, o.name);
    anim(o.animation, o.name + " animation");
    mesh(*o.mesh, o.name + " mesh");
    for (const LodLevel& l : o.lods) {
      mesh(*l.mesh, o.name + " lod");
      if (!std::isfinite(l.max_error_m)) bad(o.name + " lod error");
    }
  }
  for (const Light& l : s.lights) {
    v3(l.position, "light position");
    v3(l.power, "light power");
    v3(l.direction, "light direction");
  }
  v3(s.ambient, "ambient");
  v3(s.background, "background");
}

}  // namespace

Scene parse_scene(const std::string& json_text, const std::string& source_name, const std::filesystem::path& base_dir,
                  const std::vector<SceneOverride>& overrides, LoadReport* report) {
  Json doc = parse_document(json_text, source_name);
  Loader loader(source_name, base_dir, report);
  for (const SceneOverride& o : overrides) apply_override(doc, o, loader.reader());
  std::string default_name = std::filesystem::path(source_name).stem().string();
  if (default_name.empty()) default_name = source_name;
  Scene scene = loader.build(doc, default_name);
  scene.source = source_name;
  return scene;
}

double LoadReport::total_ms() const {
  double t = 0;
  for (const Phase& p : phases) t += p.ms;
  return t;
}

std::string LoadReport::summary() const {
  char buf[64];
  std::snprintf(buf, sizeof buf, "load %.0f ms:", total_ms());
  std::string out = buf;
  for (std::size_t i = 0; i < phases.size(); ++i) {
    std::snprintf(buf, sizeof buf, "%s %s %.0f ms", i == 0 ? "" : ",", phases[i].name.c_str(), phases[i].ms);
    out += buf;
    if (!phases[i].note.empty()) out += " (" + phases[i].note + ")";
  }
  return out;
}

Scene load_scene(const std::filesystem::path& path, const std::vector<SceneOverride>& overrides,
                 const std::string& camera, LoadReport* report) {
  if (is_gltf_file(path)) return load_gltf_scene(path, overrides, camera, report);
  const auto start = std::chrono::steady_clock::now();
  if (!camera.empty()) {
    throw SceneError(path.string() + ": --camera " + camera + ": a JSON scene has one camera (--camera picks a glTF "
                     "camera node)");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) throw SceneError(path.string() + ": cannot open scene file");
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw SceneError(path.string() + ": read error");
  LoadReport included;  // an included glTF asset's phases
  Scene scene = parse_scene(text.str(), path.string(), path.parent_path(), overrides, &included);
  scene.source = path;
  if (report) {
    // The JSON's parse is what the included asset's phases leave of the whole.
    const double all = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    report->add("parse", std::max(0.0, all - included.total_ms() + (included.phases.empty() ? 0.0 : included.phases[0].ms)),
                included.phases.empty() ? std::string() : included.phases[0].note);
    for (std::size_t i = 1; i < included.phases.size(); ++i) report->phases.push_back(included.phases[i]);
  }
  return scene;
}

}  // namespace fovea::render
