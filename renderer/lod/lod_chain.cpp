// SPDX-License-Identifier: Apache-2.0
#include "lod/lod_chain.h"

#include <meshoptimizer.h>  // MESHOPTIMIZER_VERSION, part of the cache key
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>

#include "lod/mesh_cache_file.h"
#include "scene/mesh_simplify.h"
#include "scene/mesh_io.h"
#include "scene/scene_error.h"

namespace fovea::render::lod {

namespace fs = std::filesystem;

const char* to_string(Attributes a) { return a == Attributes::Weld ? "weld" : "seams"; }

void ChainSettings::check() const {
  if (levels < 1 || levels > 16) throw std::invalid_argument("levels = " + std::to_string(levels) + ": must be 1..16");
  if (!std::isfinite(base) || !(base > 1) || base > 1e6) {
    throw std::invalid_argument("base = " + std::to_string(base) + ": must be a finite number > 1 (Lee's beta, eq. 7.4)");
  }
}

namespace {

std::uint64_t fnv1a(const void* data, std::size_t bytes, std::uint64_t h) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < bytes; ++i) {
    h ^= p[i];
    h *= 0x100000001b3ULL;
  }
  return h;
}

}  // namespace

Chain build_chain(const Mesh& mesh, const ChainSettings& s, const std::string& input_name) {
  s.check();
  Chain chain;
  chain.settings = s;
  chain.input_name = input_name;
  const Mesh full = join_identical_vertices(mesh);
  ChainLevel zero;
  zero.mesh = full;
  zero.reached = full.triangle_count() > 0;
  chain.levels.push_back(zero);
  if (full.triangle_count() == 0) return chain;  // nothing to simplify: one level, reached = false
  for (int l = 1; l < s.levels; ++l) {
    const double ratio = std::pow(s.base, -static_cast<double>(l));  // Lee 2009, eq. 7.4
    ChainLevel level;
    level.target_ratio = ratio;
    SimplifiedMesh simplified = simplify_mesh(full, ratio, s.attributes == Attributes::Weld ? SeamHandling::Weld : SeamHandling::Keep);
    level.mesh = std::move(simplified.mesh);
    level.error_m = simplified.error_m;
    const double tris = static_cast<double>(full.triangle_count());
    level.achieved_ratio = static_cast<double>(level.mesh.triangle_count()) / tris;
    // A target below one triangle is reached by any non-empty level; otherwise within 1.5x of it.
    level.reached = level.mesh.triangle_count() > 0 && (tris * ratio < 1.0 || level.achieved_ratio <= 1.5 * ratio);
    const ChainLevel& previous = chain.levels.back();
    if (level.mesh.triangle_count() == 0 || level.mesh.triangle_count() > previous.mesh.triangle_count()) {
      // The simplifier could not go below the previous level (or collapsed everything): keep the
      // previous level's mesh and say so.
      level.mesh = previous.mesh;
      level.error_m = previous.error_m;
      level.achieved_ratio = previous.achieved_ratio;
      level.reached = false;
    }
    chain.levels.push_back(std::move(level));
  }
  return chain;
}

namespace {

ChainSettings settings_for(const LodChainRequest& r) {
  ChainSettings cs;
  if (r.levels) cs.levels = *r.levels;
  if (r.base) cs.base = *r.base;
  if (r.weld_attributes) cs.attributes = *r.weld_attributes ? Attributes::Weld : Attributes::Seams;
  return cs;
}

// The chain's levels below the full mesh that are coarser than the one before them.
std::vector<LodLevel> chain_levels(const Chain& chain, std::size_t full_triangles) {
  std::vector<LodLevel> out;
  std::size_t prev_tris = full_triangles;
  for (std::size_t l = 1; l < chain.levels.size(); ++l) {
    const ChainLevel& cl = chain.levels[l];
    if (cl.mesh.triangle_count() == 0 || cl.mesh.triangle_count() >= prev_tris) continue;
    prev_tris = cl.mesh.triangle_count();
    LodLevel level;
    level.mesh = std::make_shared<const Mesh>(cl.mesh);
    level.max_error_m = cl.error_m;
    out.push_back(std::move(level));
  }
  return out;
}

}  // namespace

void attach_chains(Scene& scene) {
  // Objects sharing a mesh (glTF instancing) share its levels too.
  std::map<std::pair<const Mesh*, std::string>, std::vector<LodLevel>> built;
  for (Object& o : scene.objects) {
    if (!o.lod_chain) continue;
    if (!o.mesh) {
      o.lod_chain.reset();
      continue;
    }
    // Built once per mesh and settings and cached on disk: the same chain fovea-lod writes.
    const ChainSettings settings = settings_for(*o.lod_chain);
    const std::string key = std::to_string(settings.levels) + "|" + std::to_string(settings.base) + "|" +
                            to_string(settings.attributes);
    auto [it, added] = built.try_emplace({o.mesh.get(), key});
    if (added) it->second = chain_levels(cached_chain(*o.mesh, settings, "scene mesh"), o.mesh->triangle_count());
    o.lods = it->second;
    if (o.lods.empty() && o.lod_chain->implicit) {
      o.lod_chain.reset();
      continue;
    }
    if (o.lods.empty()) {
      throw SceneError(o.lod_chain->where + ": the simplifier could not reduce this mesh at all (" +
                       std::to_string(o.mesh->triangle_count()) + " triangles)");
    }
    for (const LodLevel& l : o.lods) {
      // A chain read back from a damaged cache must not carry NaN into the backends.
      if (!all_finite(*l.mesh) || !std::isfinite(l.max_error_m)) {
        throw SceneError(o.lod_chain->where + ": internal error: non-finite level of detail");
      }
    }
    o.lod_chain.reset();
  }
}

Mesh read_mesh(const fs::path& path) { return read_mesh_file(path); }

void write_mesh(const Mesh& mesh, const fs::path& path) {
  std::string ext = path.extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  std::ofstream f(path);
  if (!f) throw std::runtime_error(path.string() + ": cannot open for writing");
  f.precision(9);
  if (ext == ".ply") {
    f << "ply\nformat ascii 1.0\ncomment fovea-lod\nelement vertex " << mesh.positions.size()
      << "\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\n"
      << "element face " << mesh.triangle_count() << "\nproperty list uchar uint vertex_indices\nend_header\n";
    for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
      const glm::vec3 p = mesh.positions[i], n = i < mesh.normals.size() ? mesh.normals[i] : glm::vec3(0, 1, 0);
      f << p.x << ' ' << p.y << ' ' << p.z << ' ' << n.x << ' ' << n.y << ' ' << n.z << '\n';
    }
    for (std::size_t t = 0; t + 2 < mesh.indices.size(); t += 3)
      f << "3 " << mesh.indices[t] << ' ' << mesh.indices[t + 1] << ' ' << mesh.indices[t + 2] << '\n';
  } else if (ext == ".obj") {
    f << "# fovea-lod\n";
    for (const glm::vec3& p : mesh.positions) f << "v " << p.x << ' ' << p.y << ' ' << p.z << '\n';
    for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
      const glm::vec3 n = i < mesh.normals.size() ? mesh.normals[i] : glm::vec3(0, 1, 0);
      f << "vn " << n.x << ' ' << n.y << ' ' << n.z << '\n';
    }
    for (std::size_t t = 0; t + 2 < mesh.indices.size(); t += 3) {
      const std::uint32_t a = mesh.indices[t] + 1, b = mesh.indices[t + 1] + 1, c = mesh.indices[t + 2] + 1;
      f << "f " << a << "//" << a << ' ' << b << "//" << b << ' ' << c << "//" << c << '\n';
    }
  } else {
    throw std::runtime_error(path.string() + ": unsupported mesh format '" + ext + "' (use .obj or .ply)");
  }
  if (!f) throw std::runtime_error(path.string() + ": write failed");
}

void write_chain(const Chain& chain, const fs::path& dir, const std::string& format) {
  if (format != "obj" && format != "ply" && format != "fmesh") {
    throw std::runtime_error("format '" + format + "': use obj or ply");
  }
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw std::runtime_error(dir.string() + ": cannot create: " + ec.message());
  nlohmann::json manifest;
  manifest["input"] = chain.input_name;
  manifest["base"] = chain.settings.base;
  manifest["levels"] = chain.levels.size();
  manifest["attributes"] = to_string(chain.settings.attributes);
  manifest["level"] = nlohmann::json::array();
  const std::size_t input_tris = chain.levels.empty() ? 0 : chain.levels[0].mesh.triangle_count();
  for (std::size_t l = 0; l < chain.levels.size(); ++l) {
    const ChainLevel& level = chain.levels[l];
    char name[32];
    std::snprintf(name, sizeof name, "level%zu.%s", l, format.c_str());
    // Level 0 with no triangles has nothing to write: the manifest says so.
    if (level.mesh.triangle_count() > 0) {
      if (format == "fmesh") {
        write_mesh_cache_file(level.mesh, dir / name);
      } else {
        write_mesh(level.mesh, dir / name);
      }
    }
    manifest["level"].push_back({{"file", level.mesh.triangle_count() > 0 ? name : ""},
                                 {"triangles", level.mesh.triangle_count()},
                                 {"input_triangles", input_tris},
                                 {"target_ratio", level.target_ratio},
                                 {"achieved_ratio", level.achieved_ratio},
                                 {"error_m", level.error_m},
                                 {"reached", level.reached}});
  }
  // The manifest last (through a temporary name): a directory with a manifest is complete.
  const fs::path tmp = dir / "manifest.json.tmp";
  {
    std::ofstream f(tmp);
    if (!f) throw std::runtime_error(tmp.string() + ": cannot open for writing");
    f << manifest.dump(2) << '\n';
    if (!f) throw std::runtime_error(tmp.string() + ": write failed");
  }
  fs::rename(tmp, dir / "manifest.json", ec);
  if (ec) throw std::runtime_error((dir / "manifest.json").string() + ": cannot write: " + ec.message());
}

Chain read_chain(const fs::path& dir) {
  const fs::path mpath = dir / "manifest.json";
  std::ifstream f(mpath);
  if (!f) throw std::runtime_error(mpath.string() + ": cannot read");
  nlohmann::json m;
  try {
    m = nlohmann::json::parse(f);
  } catch (const std::exception& e) {
    throw std::runtime_error(mpath.string() + ": not JSON: " + e.what());
  }
  Chain chain;
  try {
    chain.input_name = m.at("input").get<std::string>();
    chain.settings.base = m.at("base").get<double>();
    chain.settings.levels = static_cast<int>(m.at("levels").get<std::size_t>());
    chain.settings.attributes = m.at("attributes").get<std::string>() == "weld" ? Attributes::Weld : Attributes::Seams;
    for (const auto& l : m.at("level")) {
      ChainLevel level;
      const std::string file = l.at("file").get<std::string>();
      if (!file.empty()) {
        const fs::path mesh_file = dir / file;
        level.mesh = mesh_file.extension() == ".fmesh" ? read_mesh_cache_file(mesh_file) : read_mesh(mesh_file);
      }
      level.target_ratio = l.at("target_ratio").get<double>();
      level.achieved_ratio = l.at("achieved_ratio").get<double>();
      level.error_m = l.at("error_m").get<float>();
      level.reached = l.at("reached").get<bool>();
      if (level.mesh.triangle_count() != l.at("triangles").get<std::size_t>()) {
        throw std::runtime_error(file + " has " + std::to_string(level.mesh.triangle_count()) + " triangles, the manifest says " +
                                 std::to_string(l.at("triangles").get<std::size_t>()));
      }
      chain.levels.push_back(std::move(level));
    }
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error(mpath.string() + ": " + e.what());
  } catch (const SceneError& e) {
    throw std::runtime_error(mpath.string() + ": " + e.what());
  }
  if (chain.levels.size() != static_cast<std::size_t>(chain.settings.levels)) {
    throw std::runtime_error(mpath.string() + ": lists " + std::to_string(chain.levels.size()) + " levels, says " +
                             std::to_string(chain.settings.levels));
  }
  return chain;
}

fs::path default_cache_root() {
  if (const char* e = std::getenv("FOVEA_LOD_CACHE"); e != nullptr && *e != '\0') return e;
  if (const char* x = std::getenv("XDG_CACHE_HOME"); x != nullptr && *x != '\0') return fs::path(x) / "fovea" / "lod";
  if (const char* h = std::getenv("HOME"); h != nullptr && *h != '\0') return fs::path(h) / ".cache" / "fovea" / "lod";
  return fs::temp_directory_path() / "fovea-lod-cache";
}

Chain cached_chain(const Mesh& mesh, const ChainSettings& s, const std::string& input_name, fs::path root, bool* hit) {
  s.check();
  if (hit) *hit = false;
  if (root.empty()) root = default_cache_root();
  std::uint64_t h = 0xcbf29ce484222325ULL;
  h = fnv1a(mesh.positions.data(), mesh.positions.size() * sizeof(glm::vec3), h);
  h = fnv1a(mesh.normals.data(), mesh.normals.size() * sizeof(glm::vec3), h);
  h = fnv1a(mesh.indices.data(), mesh.indices.size() * sizeof(std::uint32_t), h);
  h = fnv1a(mesh.texcoords0.data(), mesh.texcoords0.size() * sizeof(glm::vec2), h);
  h = fnv1a(mesh.texcoords1.data(), mesh.texcoords1.size() * sizeof(glm::vec2), h);
  h = fnv1a(mesh.colors.data(), mesh.colors.size() * sizeof(glm::vec4), h);
  h = fnv1a(mesh.tangents.data(), mesh.tangents.size() * sizeof(glm::vec4), h);
  // fmesh: every attribute (the PLY of earlier caches had positions and normals only).
  const std::string key = std::to_string(s.levels) + "|" + std::to_string(s.base) + "|" + to_string(s.attributes) +
                          "|meshopt" + std::to_string(MESHOPTIMIZER_VERSION) + "|fmesh";
  h = fnv1a(key.data(), key.size(), h);
  char name[32];
  std::snprintf(name, sizeof name, "%016llx", static_cast<unsigned long long>(h));
  const fs::path dir = root / name;
  std::error_code ec;
  if (fs::exists(dir / "manifest.json", ec)) {
    try {
      Chain c = read_chain(dir);
      if (hit) *hit = true;
      return c;
    } catch (const std::exception&) {
      // A damaged entry (a file deleted, a partial write): rebuilt below.
    }
  }
  Chain chain = build_chain(mesh, s, input_name);
  try {
    write_chain(chain, dir, "fmesh");
  } catch (const std::exception&) {
    // An unwritable cache costs the next run a rebuild, nothing else.
  }
  return chain;
}

}  // namespace fovea::render::lod
