// SPDX-License-Identifier: Apache-2.0
#include "backend/gl/gl_photon_gather.h"

#include <epoxy/gl.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <stdexcept>
#include <string>

#include "backend/gl/gl_program.h"

namespace fovea::render {

namespace {

constexpr std::uint32_t kScanThreads = 1024;         // the prefix sum's one work group
constexpr std::uint32_t kMinTable = kScanThreads;    // buckets: a power of two, at least one per thread
constexpr std::uint32_t kMaxTable = 1u << 22;        // 16 MiB of counts; more photons share buckets
constexpr std::uint32_t kPhotonGroup = 256;          // photons per work group of count and scatter

// The grid's cell of a point and its bucket; the same formula in every pass (a photon is counted in
// the cell the gather computes for it). Coordinates are clamped so that far-off photons stay integers.
constexpr const char* kGridGlsl = R"(
ivec3 cell_of(vec3 p, float inv_cell) { return ivec3(floor(clamp(p * inv_cell, -1.0e9, 1.0e9))); }
uint bucket_of(ivec3 c, uint mask) {
  uvec3 u = uvec3(c);
  return ((u.x * 73856093u) ^ (u.y * 19349663u) ^ (u.z * 83492791u)) & mask;
}
)";

constexpr const char* kPhotonsBlock = R"(
layout(std430, binding = 0) readonly buffer Photons { vec4 photons[]; };  // position, power, incoming
layout(std430, binding = 1) buffer Counts { uint counts[]; };
uniform uint u_count, u_mask;
uniform float u_inv_cell;
)";

constexpr const char* kCountMain = R"(
void main() {
  uint i = gl_GlobalInvocationID.x;
  if (i >= u_count) return;
  atomicAdd(counts[bucket_of(cell_of(photons[3u * i].xyz, u_inv_cell), u_mask)], 1u);
}
)";

// One work group of 1024: each thread sums its run of buckets, a Hillis-Steele scan over the 1024
// sums, then each thread writes its run's exclusive prefix: starts[b] (and starts[table] = photons) and
// the same into counts[b], the scatter's cursor.
constexpr const char* kScan = R"(#version 430 core
layout(local_size_x = 1024) in;
layout(std430, binding = 1) buffer Counts { uint counts[]; };
layout(std430, binding = 2) writeonly buffer Starts { uint starts[]; };
uniform uint u_table;
shared uint partial[1024];
void main() {
  uint t = gl_LocalInvocationID.x;
  uint run = u_table / 1024u, base = t * run;
  uint sum = 0u;
  for (uint i = 0u; i < run; ++i) sum += counts[base + i];
  partial[t] = sum;
  barrier();
  for (uint offset = 1u; offset < 1024u; offset <<= 1) {
    uint v = t >= offset ? partial[t - offset] : 0u;
    barrier();
    partial[t] += v;
    barrier();
  }
  uint at = partial[t] - sum;
  for (uint i = 0u; i < run; ++i) {
    uint c = counts[base + i];
    starts[base + i] = at;
    counts[base + i] = at;
    at += c;
  }
  if (t == 1023u) starts[u_table] = partial[1023];
}
)";

constexpr const char* kScatterMain = R"(
layout(std430, binding = 3) writeonly buffer Sorted { uint sorted[]; };
void main() {
  uint i = gl_GlobalInvocationID.x;
  if (i >= u_count) return;
  uint slot = atomicAdd(counts[bucket_of(cell_of(photons[3u * i].xyz, u_inv_cell), u_mask)], 1u);
  sorted[slot] = i;
}
)";

// The gather over the area's box. MAP is 0 (indirect) or 1 (caustic) in kGatherMap's copies.
constexpr const char* kGatherHead = R"(#version 430 core
layout(local_size_x = 8, local_size_y = 8) in;
layout(rgba32f, binding = 0) uniform writeonly image2D u_out;
layout(std430, binding = 0) readonly buffer Photons0 { vec4 photons0[]; };
layout(std430, binding = 1) readonly buffer Starts0 { uint starts0[]; };
layout(std430, binding = 2) readonly buffer Sorted0 { uint sorted0[]; };
layout(std430, binding = 3) readonly buffer Photons1 { vec4 photons1[]; };
layout(std430, binding = 4) readonly buffer Starts1 { uint starts1[]; };
layout(std430, binding = 5) readonly buffer Sorted1 { uint sorted1[]; };
struct Surface { uint id; float shininess; float pad0, pad1; vec4 kd; vec4 ks; };
layout(std430, binding = 6) readonly buffer Surfaces { Surface surfaces[]; };  // sorted by id
uniform int u_surfaces;
uniform sampler2D u_color, u_depth, u_normal, u_traced;
uniform usampler2D u_id;
uniform bool u_has_traced;
uniform ivec2 u_origin, u_box, u_size;  // the box (image pixels, y down) and the image
uniform vec2 u_centre;
uniform float u_radius;
uniform vec3 u_eye, u_right, u_up, u_back, u_background, u_ambient;
uniform uint u_count[2], u_mask[2];
uniform float u_inv_cell[2], u_r[2], u_cone_k[2];
uniform bool u_cone[2];
// Labelling (the gaze-directed mapper's): the indirect photons used, and per invocation the flux
// density it gathered per light, traditional photons in [0, 16), gaze-emitted in [16, 32).
layout(std430, binding = 7) buffer Labels { uint labels[]; };
layout(std430, binding = 8) writeonly buffer Partials { float partials[]; };
uniform bool u_label;
uniform uint u_lights;
float flux[32];
shared float group_flux[64][32];
const float kPi = 3.14159265358979;
bool finite3(vec3 v) { return !any(isnan(v)) && !any(isinf(v)); }
vec3 brdf(vec3 n, vec3 v, vec3 incoming, vec3 kd, vec3 ks, float shininess) {
  if (ks == vec3(0.0)) return kd;
  vec3 h = normalize(v - incoming);  // eq. 5.21
  return kd + ks * pow(max(0.0, dot(n, h)), shininess);
}
)";

constexpr const char* kGatherMap = R"(
vec3 gatherMAP(vec3 x, vec3 n, vec3 v, vec3 kd, vec3 ks, float shininess) {
  if (u_count[MAP] == 0u) return vec3(0.0);
  float r = u_r[MAP], r2 = r * r, k = u_cone_k[MAP];
  ivec3 c = cell_of(x, u_inv_cell[MAP]);
  vec3 sum = vec3(0.0);
  for (int dz = -1; dz <= 1; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        ivec3 cc = c + ivec3(dx, dy, dz);
        uint b = bucket_of(cc, u_mask[MAP]);
        for (uint s = startsMAP[b]; s < startsMAP[b + 1u]; ++s) {
          uint i = sortedMAP[s];
          vec3 p = photonsMAP[3u * i].xyz;
          vec3 d = p - x;
          float d2 = dot(d, d);
          if (d2 >= r2 || cell_of(p, u_inv_cell[MAP]) != cc) continue;
          vec3 incoming = photonsMAP[3u * i + 2u].xyz;
          if (dot(incoming, n) >= 0.0) continue;  // arrived at the other side (Jensen 2001, 7.2)
          float w = u_cone[MAP] ? max(0.0, 1.0 - sqrt(d2) / (k * r)) : 1.0;  // Jensen 2001, eq. 7.7
          vec3 power = photonsMAP[3u * i + 1u].xyz;
          sum += w * power * brdf(n, v, incoming, kd, ks, shininess);
          if (MAP == 0 && u_label) {  // gi_render.cpp's accumulate_flux_by_kind, and the label
            labels[i] = 1u;
            uint tag = floatBitsToUint(photonsMAP[3u * i].w), light = tag & 255u;
            if (light < u_lights) flux[((tag >> 8) != 0u ? 16u : 0u) + light] += (power.x + power.y + power.z) / (3.0 * r2);
          }
        }
      }
  float norm = u_cone[MAP] ? 1.0 - 2.0 / (3.0 * k) : 1.0;
  vec3 e = sum / (norm * kPi * r2);  // eq. 6.6
  return finite3(e) ? max(e, vec3(0.0)) : vec3(0.0);
}
)";

constexpr const char* kGatherMain = R"(
int surface_of(uint id) {
  int lo = 0, hi = u_surfaces;
  while (lo < hi) {
    int mid = (lo + hi) >> 1;
    if (surfaces[mid].id < id) lo = mid + 1; else hi = mid;
  }
  return lo < u_surfaces && surfaces[lo].id == id ? lo : -1;
}
vec3 traced(ivec2 b) { return u_has_traced ? texelFetch(u_traced, b, 0).rgb : vec3(0.0); }
vec3 shade(ivec2 px, ivec2 b) {
  ivec2 t = ivec2(px.x, u_size.y - 1 - px.y);
  uint id = texelFetch(u_id, t, 0).r;
  if (id == 0u) return u_background;
  int m = surface_of(id);
  float depth = texelFetch(u_depth, t, 0).r;
  if (m < 0 || isnan(depth) || isinf(depth) || !(depth > 0.0)) return traced(b);
  vec2 q = vec2(px) + 0.5;
  vec3 dir = u_right * (2.0 * q.x / float(u_size.x) - 1.0) + u_up * (1.0 - 2.0 * q.y / float(u_size.y)) - u_back;
  vec3 x = u_eye + dir * depth;
  vec3 n = texelFetch(u_normal, t, 0).xyz;
  vec3 v = normalize(u_eye - x);
  vec3 kd = surfaces[m].kd.rgb, ks = surfaces[m].ks.rgb;
  float shininess = surfaces[m].shininess;
  vec3 l = texelFetch(u_color, t, 0).rgb - kd * u_ambient;
  l += gather0(x, n, v, kd, ks, shininess) + gather1(x, n, v, kd, ks, shininess);
  return finite3(l) ? l : vec3(0.0);
}
void main() {
  for (int k = 0; k < 32; ++k) flux[k] = 0.0;
  ivec2 b = ivec2(gl_GlobalInvocationID.xy);
  if (b.x < u_box.x && b.y < u_box.y) {
    ivec2 px = u_origin + b;
    vec2 q = vec2(px) + 0.5 - u_centre;
    vec3 c = dot(q, q) <= u_radius * u_radius ? shade(px, b) : vec3(0.0);  // gi::GazeArea::contains
    imageStore(u_out, b, vec4(c, 1.0));
  }
  if (!u_label) return;  // uniform: the whole work group leaves or none
  // The work group's sums per light and kind (a column each), for the CPU to add up.
  uint t = gl_LocalInvocationIndex;
  for (int k = 0; k < 32; ++k) group_flux[t][k] = flux[k];
  barrier();
  if (t < 32u) {
    float total = 0.0;
    for (uint j = 0u; j < 64u; ++j) total += group_flux[j][t];
    partials[(gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * 32u + t] = total;
  }
}
)";

std::string replace_all(std::string s, const std::string& from, const std::string& to) {
  for (std::size_t at = s.find(from); at != std::string::npos; at = s.find(from, at + to.size())) s.replace(at, from.size(), to);
  return s;
}

std::string photon_pass(const char* main) {
  return std::string("#version 430 core\nlayout(local_size_x = ") + std::to_string(kPhotonGroup) + ") in;\n" + kGridGlsl +
         kPhotonsBlock + main;
}

std::string gather_source() {
  return std::string(kGatherHead) + kGridGlsl + replace_all(kGatherMap, "MAP", "0") + replace_all(kGatherMap, "MAP", "1") +
         kGatherMain;
}

void check(const char* where) { gl::check_error("GlPhotonGather", where); }

// A storage buffer of at least `bytes` (grown by half again when too small; contents undefined after growing).
void ensure_buffer(unsigned& buffer, std::size_t& capacity, std::size_t bytes) {
  if (buffer == 0) glGenBuffers(1, &buffer);
  if (bytes <= capacity && capacity > 0) return;
  capacity = std::max<std::size_t>(bytes + bytes / 2, 64);
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, buffer);
  glBufferData(GL_SHADER_STORAGE_BUFFER, static_cast<GLsizeiptr>(capacity), nullptr, GL_DYNAMIC_DRAW);
}

std::uint32_t table_size(std::uint32_t photons) {
  std::uint32_t t = kMinTable;
  while (t < kMaxTable && t < 2 * photons) t <<= 1;
  return t;
}

}  // namespace

std::string GlPhotonGather::unavailable_reason(const GlFeatures& features, std::size_t photons) {
  if (!features.at_least(4, 3)) return "the GPU gather needs compute shaders (OpenGL 4.3), this context is " + features.version();
  const std::int64_t max_block = features.max_storage_block;
  const double bytes = 48.0 * static_cast<double>(photons);
  if (bytes > static_cast<double>(max_block)) {
    return std::to_string(photons) + " photons need a " + std::to_string(static_cast<long long>(bytes) >> 20) +
           " MiB storage buffer on the GPU; the device allows " + std::to_string(max_block >> 20) + " MiB";
  }
  return "";
}

GlPhotonGather::GlPhotonGather(const GlFeatures& features) : max_storage_block_(features.max_storage_block) {
  count_program_ = gl::link_compute_program(photon_pass(kCountMain).c_str(), "GlPhotonGather count");
  scan_program_ = gl::link_compute_program(kScan, "GlPhotonGather scan");
  scatter_program_ = gl::link_compute_program(photon_pass(kScatterMain).c_str(), "GlPhotonGather scatter");
  gather_program_ = gl::link_compute_program(gather_source().c_str(), "GlPhotonGather gather");
  check("GlPhotonGather()");
}

GlPhotonGather::~GlPhotonGather() {
  for (unsigned p : {count_program_, scan_program_, scatter_program_, gather_program_})
    if (p != 0) glDeleteProgram(p);
  for (Grid& g : grids_)
    for (unsigned* b : {&g.photons, &g.counts, &g.starts, &g.sorted})
      if (*b != 0) glDeleteBuffers(1, b);
  for (unsigned* b : {&surfaces_, &labels_, &partials_})
    if (*b != 0) glDeleteBuffers(1, b);
  gl::delete_texture(traced_);
  gl::delete_texture(output_);
}

// Step 2: the hash grid of one map, cells `radius` wide.
void GlPhotonGather::build(Grid& grid, const GpuGiGather::Map& map) {
  const std::vector<GpuPhoton>* photons = map.photons;
  grid.count = 0;
  if (photons == nullptr || photons->empty() || !(map.radius > 0) || !std::isfinite(map.radius)) return;
  const std::size_t n = photons->size();
  if (48.0 * static_cast<double>(n) > static_cast<double>(max_storage_block_)) {  // the plan should have kept it on the CPU
    throw std::length_error("GlPhotonGather: " + std::to_string(n) + " photons exceed the device's storage-buffer size (" +
                            std::to_string(max_storage_block_) + " bytes)");
  }
  grid.count = static_cast<std::uint32_t>(n);
  grid.table = table_size(grid.count);
  grid.cell = map.radius;
  // Step 1: up they go, three vec4 each.
  std::vector<glm::vec4> packed(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const GpuPhoton& p = (*photons)[i];
    // w: the light and the kind (gaze-emitted: bit 8) for the labels, as the float of those bits.
    packed[3 * i] = glm::vec4(p.position, std::bit_cast<float>(std::min<std::uint32_t>(p.light, 255u) |
                                                               (p.traditional ? 0u : 1u << 8)));
    packed[3 * i + 1] = glm::vec4(p.power, 0.0f);
    packed[3 * i + 2] = glm::vec4(p.incoming, 0.0f);
  }
  const std::size_t photon_bytes = packed.size() * sizeof(glm::vec4);
  ensure_buffer(grid.photons, grid.photons_bytes, photon_bytes);
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, grid.photons);
  glBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, static_cast<GLsizeiptr>(photon_bytes), packed.data());
  ensure_buffer(grid.sorted, grid.sorted_bytes, n * sizeof(std::uint32_t));
  ensure_buffer(grid.counts, grid.counts_bytes, std::size_t{grid.table} * sizeof(std::uint32_t));
  ensure_buffer(grid.starts, grid.starts_bytes, (std::size_t{grid.table} + 1) * sizeof(std::uint32_t));
  const std::uint32_t zero = 0;
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, grid.counts);
  glClearBufferSubData(GL_SHADER_STORAGE_BUFFER, GL_R32UI, 0, std::size_t{grid.table} * sizeof(std::uint32_t), GL_RED_INTEGER,
                       GL_UNSIGNED_INT, &zero);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, grid.photons);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, grid.counts);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, grid.starts);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, grid.sorted);
  const GLuint groups = (grid.count + kPhotonGroup - 1) / kPhotonGroup;
  const auto grid_uniforms = [&](unsigned program) {
    glUseProgram(program);
    glUniform1ui(glGetUniformLocation(program, "u_count"), grid.count);
    glUniform1ui(glGetUniformLocation(program, "u_mask"), grid.table - 1);
    glUniform1f(glGetUniformLocation(program, "u_inv_cell"), 1.0f / grid.cell);
  };
  grid_uniforms(count_program_);
  glDispatchCompute(groups, 1, 1);
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  glUseProgram(scan_program_);
  glUniform1ui(glGetUniformLocation(scan_program_, "u_table"), grid.table);
  glDispatchCompute(1, 1, 1);
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  grid_uniforms(scatter_program_);
  glDispatchCompute(groups, 1, 1);
  glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  check("GlPhotonGather::build");
}

// The CPU's traced pixels of the box (row 0 at the top, as the output).
void GlPhotonGather::upload_traced(const GpuGiGather& gather, std::uint32_t width, glm::ivec2 origin, glm::ivec2 size) {
  has_traced_ = gather.traced != nullptr;
  if (!has_traced_) return;
  if (traced_ == 0 || traced_size_ != size) {
    gl::delete_texture(traced_);
    traced_ = gl::make_texture(GL_RGB32F, GL_RGB, GL_FLOAT, static_cast<std::uint32_t>(size.x), static_cast<std::uint32_t>(size.y));
    traced_size_ = size;
  }
  glBindTexture(GL_TEXTURE_2D, traced_);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
  glPixelStorei(GL_UNPACK_ROW_LENGTH, static_cast<GLint>(width));
  glPixelStorei(GL_UNPACK_SKIP_PIXELS, origin.x);
  glPixelStorei(GL_UNPACK_SKIP_ROWS, origin.y);
  glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, size.x, size.y, GL_RGB, GL_FLOAT, gather.traced->data());
  glPixelStorei(GL_UNPACK_ROW_LENGTH, 0);
  glPixelStorei(GL_UNPACK_SKIP_PIXELS, 0);
  glPixelStorei(GL_UNPACK_SKIP_ROWS, 0);
}

// The gathered materials sorted by id (the shader's binary search), 48 bytes each.
void GlPhotonGather::upload_surfaces(const std::vector<GpuGiGather::Surface>& surfaces) {
  struct Packed {
    std::uint32_t id;
    float shininess, pad0 = 0, pad1 = 0;
    glm::vec4 kd, ks;
  };
  std::vector<Packed> packed;
  packed.reserve(surfaces.size());
  for (const GpuGiGather::Surface& s : surfaces) packed.push_back({s.object_id, s.shininess, 0, 0, glm::vec4(s.kd, 0), glm::vec4(s.ks, 0)});
  std::stable_sort(packed.begin(), packed.end(), [](const Packed& a, const Packed& b) { return a.id < b.id; });
  surface_count_ = static_cast<int>(packed.size());
  ensure_buffer(surfaces_, surface_capacity_, std::max<std::size_t>(1, packed.size()) * sizeof(Packed));
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, surfaces_);
  if (!packed.empty())
    glBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, static_cast<GLsizeiptr>(packed.size() * sizeof(Packed)), packed.data());
}

// Step 3: every pixel of the box.
void GlPhotonGather::gather(const GBufferInput& g, const GpuGiGather& in, glm::ivec2 origin, glm::ivec2 size) {
  const unsigned p = gather_program_;
  glUseProgram(p);
  const auto loc = [p](const char* name) { return glGetUniformLocation(p, name); };
  for (unsigned m = 0; m < 2; ++m) {
    const Grid& grid = grids_[m];
    const GpuGiGather::Map& map = m == 0 ? in.indirect : in.caustic;
    const std::string i = "[" + std::to_string(m) + "]";
    glUniform1ui(loc(("u_count" + i).c_str()), grid.count);
    glUniform1ui(loc(("u_mask" + i).c_str()), grid.count > 0 ? grid.table - 1 : 0);
    glUniform1f(loc(("u_inv_cell" + i).c_str()), grid.count > 0 ? 1.0f / grid.cell : 0.0f);
    glUniform1f(loc(("u_r" + i).c_str()), map.radius);
    glUniform1f(loc(("u_cone_k" + i).c_str()), std::max(1.0f, std::isfinite(map.cone_k) ? map.cone_k : 1.0f));
    glUniform1i(loc(("u_cone" + i).c_str()), map.cone ? 1 : 0);
    // An empty map still binds something (its buffers may not exist yet).
    const unsigned photons = grid.photons != 0 ? grid.photons : surfaces_;
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3 * m, photons);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3 * m + 1, grid.starts != 0 ? grid.starts : surfaces_);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 3 * m + 2, grid.sorted != 0 ? grid.sorted : surfaces_);
  }
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 6, surfaces_);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 7, labelled_ ? labels_ : surfaces_);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 8, labelled_ ? partials_ : surfaces_);
  glUniform1i(loc("u_label"), labelled_ ? 1 : 0);
  glUniform1ui(loc("u_lights"), label_lights_);
  glUniform1i(loc("u_surfaces"), surface_count_);
  gl::bind_sampler(0, g.color, p, "u_color");
  gl::bind_sampler(1, g.depth, p, "u_depth");
  gl::bind_sampler(2, g.normal, p, "u_normal");
  gl::bind_sampler(3, g.object_id, p, "u_id");
  gl::bind_sampler(4, has_traced_ ? traced_ : g.color, p, "u_traced");
  glActiveTexture(GL_TEXTURE0);
  glUniform1i(loc("u_has_traced"), has_traced_ ? 1 : 0);
  glUniform2i(loc("u_origin"), origin.x, origin.y);
  glUniform2i(loc("u_box"), size.x, size.y);
  glUniform2i(loc("u_size"), static_cast<GLint>(g.width), static_cast<GLint>(g.height));
  glUniform2f(loc("u_centre"), in.centre_px.x, in.centre_px.y);
  glUniform1f(loc("u_radius"), in.radius_px);
  const auto vec3 = [&](const char* name, const glm::vec3& v) { glUniform3f(loc(name), v.x, v.y, v.z); };
  vec3("u_eye", in.eye);
  vec3("u_right", in.right);
  vec3("u_up", in.up);
  vec3("u_back", in.back);
  vec3("u_background", in.background);
  vec3("u_ambient", in.ambient);
  glBindImageTexture(0, output_, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA32F);
  glDispatchCompute(static_cast<GLuint>((size.x + 7) / 8), static_cast<GLuint>((size.y + 7) / 8), 1);
  glMemoryBarrier(gl::kComputeWrittenBarrier);
  glBindImageTexture(0, 0, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA32F);
  check("GlPhotonGather::gather");
}

void GlPhotonGather::run(const GBufferInput& gbuffer, const GpuGiGather& in, glm::ivec2 origin, glm::ivec2 size) {
  const std::size_t pixels = std::size_t{gbuffer.width} * gbuffer.height;
  if (in.traced != nullptr && in.traced->size() != pixels) {
    throw std::invalid_argument("GlPhotonGather::run: the traced image has " + std::to_string(in.traced->size()) +
                                " pixels, the G-buffer " + std::to_string(gbuffer.width) + "x" +
                                std::to_string(gbuffer.height));
  }
  if (size.x <= 0 || size.y <= 0 || origin.x < 0 || origin.y < 0 ||
      origin.x + size.x > static_cast<int>(gbuffer.width) || origin.y + size.y > static_cast<int>(gbuffer.height)) {
    throw std::invalid_argument("GlPhotonGather::run: the box is not inside the image");
  }
  if (output_ == 0 || output_size_ != size) {
    gl::delete_texture(output_);
    output_ = gl::make_texture(GL_RGBA32F, GL_RGBA, GL_FLOAT, static_cast<std::uint32_t>(size.x), static_cast<std::uint32_t>(size.y));
    output_size_ = size;
  }
  build(grids_[0], in.indirect);
  build(grids_[1], in.caustic);
  upload_surfaces(in.surfaces);
  upload_traced(in, gbuffer.width, origin, size);
  prepare_labels(in, size);
  gather(gbuffer, in, origin, size);
}

// A cleared label per indirect photon and room for each work group's sums.
void GlPhotonGather::prepare_labels(const GpuGiGather& in, glm::ivec2 size) {
  labelled_ = in.label && grids_[0].count > 0;
  label_lights_ = std::min(in.lights, GpuGiGather::kMaxLabelLights);
  label_groups_ = static_cast<std::uint32_t>((size.x + 7) / 8) * static_cast<std::uint32_t>((size.y + 7) / 8);
  if (!labelled_) return;
  const std::size_t label_bytes = std::size_t{grids_[0].count} * sizeof(std::uint32_t);
  ensure_buffer(labels_, labels_bytes_, label_bytes);
  ensure_buffer(partials_, partials_bytes_, std::size_t{label_groups_} * 32 * sizeof(float));
  const std::uint32_t zero = 0;
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, labels_);
  glClearBufferSubData(GL_SHADER_STORAGE_BUFFER, GL_R32UI, 0, static_cast<GLsizeiptr>(label_bytes), GL_RED_INTEGER,
                       GL_UNSIGNED_INT, &zero);
}

void GlPhotonGather::read_labels(std::vector<std::uint8_t>& used, std::vector<double>& traditional,
                                 std::vector<double>& gaze) const {
  used.clear();
  traditional.assign(label_lights_, 0.0);
  gaze.assign(label_lights_, 0.0);
  if (!labelled_) return;
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  std::vector<std::uint32_t> words(grids_[0].count);
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, labels_);
  glGetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, static_cast<GLsizeiptr>(words.size() * sizeof(std::uint32_t)), words.data());
  used.reserve(words.size());
  for (std::uint32_t w : words) used.push_back(w != 0 ? 1 : 0);
  std::vector<float> partial(std::size_t{label_groups_} * 32);
  glBindBuffer(GL_SHADER_STORAGE_BUFFER, partials_);
  glGetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, static_cast<GLsizeiptr>(partial.size() * sizeof(float)), partial.data());
  for (std::size_t g = 0; g < label_groups_; ++g)
    for (std::uint32_t l = 0; l < label_lights_; ++l) {
      traditional[l] += static_cast<double>(partial[g * 32 + l]);
      gaze[l] += static_cast<double>(partial[g * 32 + 16 + l]);
    }
  check("GlPhotonGather::read_labels");
}

void GlPhotonGather::read(std::vector<glm::vec3>& box) const {
  box.clear();
  if (output_ == 0) return;
  std::vector<glm::vec4> rgba(static_cast<std::size_t>(output_size_.x) * static_cast<std::size_t>(output_size_.y));
  glBindTexture(GL_TEXTURE_2D, output_);
  glPixelStorei(GL_PACK_ALIGNMENT, 4);
  glGetTexImage(GL_TEXTURE_2D, 0, GL_RGBA, GL_FLOAT, rgba.data());
  box.reserve(rgba.size());
  for (const glm::vec4& c : rgba) box.emplace_back(c);
  check("GlPhotonGather::read");
}

}  // namespace fovea::render
