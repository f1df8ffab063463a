// SPDX-License-Identifier: Apache-2.0
// make_gltf_standin OUT_DIR [--small]: writes a "Sponza-sized" glTF 2.0 stand-in scene,
// OUT_DIR/standin.gltf, OUT_DIR/standin.bin and OUT_DIR/textures/*.jpg|*.png.
//
// Why: the benchmarks want a scene the size of Crytek Sponza (262k triangles, about 25 materials
// and about 70 textures of 1-2k pixels), but Sponza itself cannot be committed. So a stand-in of
// the same size and material count is generated here, by a program in the repository, instead.
//
// What: a two-storey courtyard (atrium) of 30 m x 14 m x 12 m, metres, Y up: a tiled floor with a
// slab border, four two-storey walls, arcades of columns (lathed, 48 segments) with half-torus arches
// on both long sides and both storeys, a balustrade of lathed balusters, gallery slabs, a wooden
// ceiling with beams, curtains hanging from the upper arcade and banners on the end walls (wavy,
// double-sided), potted plants (pots and alpha-masked double-sided leaves), doors, and decorative
// spheres on pedestals. Repeated parts are glTF instances (several nodes pointing at one mesh;
// meshes that differ only in material share their accessors). A perspective camera node "view"
// looks down the long axis; two KHR_lights_punctual point lights and a spot light the courtyard.
//
// About 262,000 triangles as rendered (every instance counted), 25 materials and 70 textures:
// 25 base colour (JPEG quality 90, sRGB; the alpha-masked leaves' is a PNG with alpha), 25 tangent-
// space normal maps (PNG, RGB = (n + 1) / 2, +Y up the image) and 20 metallic-roughness maps (PNG;
// R occlusion, G roughness, B metallic; also the material's occlusion texture). 10 textures are
// 2048x2048, the other 60 1024x1024. Every primitive has POSITION (with min and max), NORMAL,
// TEXCOORD_0 and UNSIGNED_INT indices; some have TANGENT, the others leave it to the loader.
//
// Everything is procedural with fixed seeds (cv::RNG), so every run writes the same bytes (with the
// same OpenCV and its JPEG and PNG encoders). --small writes the same structure with 64x64 textures
// and about 1/14 of the triangles, for a quick check.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <numbers>
#include <string>
#include <system_error>
#include <vector>

#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace {

namespace fs = std::filesystem;
using json = nlohmann::ordered_json;

constexpr float kPi = std::numbers::pi_v<float>;

// ---------------------------------------------------------------------------------------------
// Materials and their textures.

enum class Pattern { Tiles, Slabs, Bricks, Plaster, Planks, Wood, Marble, Stone, Fabric, Banner, Terracotta, Soil, Metal, Iron, Leaf };

struct MaterialSpec {
  const char* name;
  Pattern pattern;
  cv::Vec3f a, b;       // sRGB tints, 0..1, R G B
  float roughness;      // mean roughness (the texture's G, or the factor without one)
  float metallic;
  float bump;           // relief in pixels of a 1024 texture: the normal map's strength
  bool mr;              // has a metallic-roughness (and occlusion) texture
  bool big;             // base colour and normal map 2048 (else 1024)
  bool mask;            // alphaMode MASK (base colour PNG with alpha)
  bool double_sided;
};

enum MaterialId : std::uint32_t {
  kFloorTiles, kFloorSlabs, kWallBrick, kWallPlaster, kCeilingWood, kGalleryFloor, kColumnMarble, kColumnTrim,
  kArchStone, kEntablature, kBalustrade, kBeamWood, kDoorWood, kCurtainRed, kCurtainGreen, kCurtainBlue,
  kBanner, kTerracotta, kSoil, kLeaves, kGold, kBronze, kSphereMarble, kPedestal, kIron, kMaterialCount
};

// clang-format off
const std::array<MaterialSpec, kMaterialCount> kMaterials = {{
  {"floor_tiles",    Pattern::Tiles,      {0.62f, 0.55f, 0.45f}, {0.35f, 0.27f, 0.22f}, 0.55f, 0.0f, 3.0f, true,  true,  false, false},
  {"floor_slabs",    Pattern::Slabs,      {0.58f, 0.56f, 0.52f}, {0.44f, 0.42f, 0.40f}, 0.70f, 0.0f, 3.0f, true,  false, false, false},
  {"wall_brick",     Pattern::Bricks,     {0.55f, 0.30f, 0.22f}, {0.70f, 0.46f, 0.33f}, 0.85f, 0.0f, 4.0f, true,  true,  false, false},
  {"wall_plaster",   Pattern::Plaster,    {0.80f, 0.74f, 0.62f}, {0.66f, 0.58f, 0.46f}, 0.90f, 0.0f, 10.0f, true, true,  false, false},
  {"ceiling_wood",   Pattern::Planks,     {0.42f, 0.27f, 0.16f}, {0.58f, 0.40f, 0.25f}, 0.70f, 0.0f, 3.0f, true,  true,  false, false},
  {"gallery_floor",  Pattern::Planks,     {0.50f, 0.36f, 0.24f}, {0.66f, 0.50f, 0.34f}, 0.60f, 0.0f, 3.0f, true,  true,  false, false},
  {"column_marble",  Pattern::Marble,     {0.88f, 0.86f, 0.82f}, {0.45f, 0.43f, 0.42f}, 0.25f, 0.0f, 2.0f, true,  false, false, false},
  {"column_trim",    Pattern::Stone,      {0.74f, 0.70f, 0.62f}, {0.55f, 0.51f, 0.45f}, 0.75f, 0.0f, 8.0f, true,  false, false, false},
  {"arch_stone",     Pattern::Stone,      {0.70f, 0.64f, 0.55f}, {0.50f, 0.45f, 0.38f}, 0.80f, 0.0f, 10.0f, true, false, false, false},
  {"entablature",    Pattern::Stone,      {0.78f, 0.74f, 0.66f}, {0.60f, 0.56f, 0.50f}, 0.75f, 0.0f, 8.0f, true,  false, false, false},
  {"balustrade",     Pattern::Marble,     {0.92f, 0.90f, 0.86f}, {0.60f, 0.58f, 0.55f}, 0.30f, 0.0f, 2.0f, true,  false, false, false},
  {"beam_wood",      Pattern::Wood,       {0.30f, 0.18f, 0.10f}, {0.45f, 0.30f, 0.18f}, 0.75f, 0.0f, 4.0f, true,  false, false, false},
  {"door_wood",      Pattern::Planks,     {0.32f, 0.20f, 0.12f}, {0.46f, 0.31f, 0.19f}, 0.65f, 0.0f, 3.0f, true,  false, false, false},
  {"curtain_red",    Pattern::Fabric,     {0.55f, 0.08f, 0.07f}, {0.85f, 0.65f, 0.25f}, 0.90f, 0.0f, 1.5f, false, false, false, true},
  {"curtain_green",  Pattern::Fabric,     {0.10f, 0.38f, 0.15f}, {0.85f, 0.65f, 0.25f}, 0.90f, 0.0f, 1.5f, false, false, false, true},
  {"curtain_blue",   Pattern::Fabric,     {0.10f, 0.16f, 0.48f}, {0.85f, 0.65f, 0.25f}, 0.90f, 0.0f, 1.5f, false, false, false, true},
  {"banner",         Pattern::Banner,     {0.45f, 0.06f, 0.10f}, {0.90f, 0.72f, 0.28f}, 0.85f, 0.0f, 2.0f, false, false, false, true},
  {"pot_terracotta", Pattern::Terracotta, {0.68f, 0.36f, 0.22f}, {0.52f, 0.26f, 0.16f}, 0.80f, 0.0f, 6.0f, true,  false, false, false},
  {"soil",           Pattern::Soil,       {0.22f, 0.15f, 0.10f}, {0.40f, 0.32f, 0.24f}, 0.95f, 0.0f, 6.0f, true,  false, false, false},
  {"plant_leaves",   Pattern::Leaf,       {0.12f, 0.32f, 0.08f}, {0.45f, 0.62f, 0.20f}, 0.60f, 0.0f, 2.0f, false, false, true,  true},
  {"sphere_gold",    Pattern::Metal,      {1.00f, 0.78f, 0.34f}, {0.85f, 0.62f, 0.22f}, 0.30f, 1.0f, 1.5f, true,  false, false, false},
  {"sphere_bronze",  Pattern::Metal,      {0.80f, 0.50f, 0.30f}, {0.55f, 0.35f, 0.22f}, 0.40f, 1.0f, 1.5f, true,  false, false, false},
  {"sphere_marble",  Pattern::Marble,     {0.30f, 0.42f, 0.38f}, {0.85f, 0.88f, 0.84f}, 0.20f, 0.0f, 1.0f, true,  false, false, false},
  {"pedestal_stone", Pattern::Slabs,      {0.66f, 0.63f, 0.58f}, {0.50f, 0.48f, 0.45f}, 0.70f, 0.0f, 3.0f, true,  false, false, false},
  {"iron",           Pattern::Iron,       {0.20f, 0.20f, 0.21f}, {0.32f, 0.32f, 0.33f}, 0.45f, 0.9f, 2.0f, true,  false, false, false},
}};
// clang-format on

// A material's texture layers, float, before encoding.
struct Layers {
  cv::Mat colour;  // CV_32FC3, sRGB R G B in 0..1
  cv::Mat height;  // CV_32F, 0..1
  cv::Mat rough;   // CV_32F, 0..1
  cv::Mat metal;   // CV_32F, 0..1
  cv::Mat alpha;   // CV_32F, 0..1; only for MASK materials
};

float clamp01(float x) { return std::clamp(x, 0.0f, 1.0f); }

// Tileable value noise in about 0..1: cx x cy random cells (powers of two dividing n), cubic.
cv::Mat value_noise(int n, int cx, int cy, cv::RNG& rng) {
  cx = std::clamp(cx, 4, n);
  cy = std::clamp(cy, 4, n);
  cv::Mat cells(cy, cx, CV_32F);
  rng.fill(cells, cv::RNG::UNIFORM, 0.0, 1.0);
  constexpr int kPad = 2;
  cv::Mat padded, big;
  cv::copyMakeBorder(cells, padded, kPad, kPad, kPad, kPad, cv::BORDER_WRAP);
  const int sx = n / cx, sy = n / cy;
  cv::resize(padded, big, cv::Size(padded.cols * sx, padded.rows * sy), 0, 0, cv::INTER_CUBIC);
  return big(cv::Rect(kPad * sx, kPad * sy, n, n)).clone();
}

// Fractal sum of `octaves` noises from `cells` cells up, normalised to 0..1.
cv::Mat fbm(int n, int cells, int octaves, cv::RNG& rng, int stretch_y = 1) {
  cv::Mat sum = cv::Mat::zeros(n, n, CV_32F);
  double amp = 1.0;
  for (int o = 0; o < octaves; ++o) {
    const int c = cells << o;
    sum += amp * value_noise(n, c, std::max(4, c / stretch_y), rng);
    amp *= 0.5;
  }
  cv::normalize(sum, sum, 0.0, 1.0, cv::NORM_MINMAX);
  return sum;
}

// Gaussian blur that wraps round the edges (the textures tile).
cv::Mat wrap_blur(const cv::Mat& m, double sigma) {
  const int pad = std::min(m.cols - 1, static_cast<int>(std::ceil(3.0 * sigma)) + 1);
  cv::Mat padded, blurred;
  cv::copyMakeBorder(m, padded, pad, pad, pad, pad, cv::BORDER_WRAP);
  cv::GaussianBlur(padded, blurred, cv::Size(0, 0), sigma);
  return blurred(cv::Rect(pad, pad, m.cols, m.rows)).clone();
}

// A filled rectangle drawn with its copies one period left and up, for patterns that tile.
void wrapped_rect(cv::Mat& m, cv::Rect r, const cv::Scalar& v) {
  for (int dy = 0; dy <= 1; ++dy) {
    for (int dx = 0; dx <= 1; ++dx) {
      const cv::Rect s(r.x - dx * m.cols, r.y - dy * m.rows, r.width, r.height);
      if ((s & cv::Rect(0, 0, m.cols, m.rows)).area() > 0) cv::rectangle(m, s, v, cv::FILLED);
    }
  }
}

// Per pixel a + (b - a) t.
cv::Mat lerp_colour(const cv::Mat& t, const cv::Vec3f& a, const cv::Vec3f& b) {
  cv::Mat out(t.size(), CV_32FC3);
  for (int y = 0; y < t.rows; ++y) {
    const float* tp = t.ptr<float>(y);
    auto* o = out.ptr<cv::Vec3f>(y);
    for (int x = 0; x < t.cols; ++x) o[x] = a + (b - a) * clamp01(tp[x]);
  }
  return out;
}

// Per pixel colour * k.
void scale_colour(cv::Mat& colour, const cv::Mat& k) {
  for (int y = 0; y < colour.rows; ++y) {
    auto* c = colour.ptr<cv::Vec3f>(y);
    const float* kp = k.ptr<float>(y);
    for (int x = 0; x < colour.cols; ++x) c[x] *= kp[x];
  }
}

// Per pixel colour = mix(other, colour, w).
void mix_colour(cv::Mat& colour, const cv::Vec3f& other, const cv::Mat& w) {
  for (int y = 0; y < colour.rows; ++y) {
    auto* c = colour.ptr<cv::Vec3f>(y);
    const float* wp = w.ptr<float>(y);
    for (int x = 0; x < colour.cols; ++x) c[x] = other + (c[x] - other) * clamp01(wp[x]);
  }
}

cv::Mat constant(int n, float v) { return cv::Mat(n, n, CV_32F, cv::Scalar(static_cast<double>(v))); }

// Square tiles in a checker of the two tints, with grout.
void tiles(const MaterialSpec& s, int n, cv::RNG& rng, Layers& l) {
  const int count = 8, cell = n / count, g = std::max(1, n / 320);
  cv::Mat tone = constant(n, 0.5f), mask = constant(n, 0.0f);
  for (int j = 0; j < count; ++j) {
    for (int i = 0; i < count; ++i) {
      const float t = ((i + j) % 2 ? 0.8f : 0.2f) + rng.uniform(-0.1f, 0.1f);
      const cv::Rect r(i * cell + g, j * cell + g, cell - 2 * g, cell - 2 * g);
      cv::rectangle(tone, r, cv::Scalar(static_cast<double>(t)), cv::FILLED);
      cv::rectangle(mask, r, cv::Scalar(1.0), cv::FILLED);
    }
  }
  const cv::Mat grain = fbm(n, 8, 6, rng);
  l.height = wrap_blur(mask, std::max(0.7, 0.8 * g)) * 0.9 + grain * 0.1;
  l.colour = lerp_colour(tone + (grain - 0.5) * 0.3, s.a, s.b);
  mix_colour(l.colour, {0.42f, 0.40f, 0.37f}, l.height * 1.5 - 0.3);
  l.rough = s.roughness + (grain - 0.5) * 0.2 + (1.0 - mask) * 0.25;
}

// Rows of stone slabs of random lengths.
void slabs(const MaterialSpec& s, int n, cv::RNG& rng, Layers& l) {
  const int rows = 4, row_h = n / rows, unit = n / 8, g = std::max(1, n / 256);
  cv::Mat tone = constant(n, 0.5f), mask = constant(n, 0.0f);
  for (int j = 0; j < rows; ++j) {
    int x = rng.uniform(0, unit);
    const int end = x + n;
    while (x < end) {
      const int w = std::min(end - x, unit * rng.uniform(1, 4));
      const cv::Rect r(x + g, j * row_h + g, w - 2 * g, row_h - 2 * g);
      wrapped_rect(tone, r, cv::Scalar(static_cast<double>(rng.uniform(0.0f, 1.0f))));
      wrapped_rect(mask, r, cv::Scalar(1.0));
      x += w;
    }
  }
  const cv::Mat grain = fbm(n, 8, 6, rng), pits = fbm(n, 32, 3, rng);
  l.height = wrap_blur(mask, std::max(0.7, 1.0 * g)) * 0.8 + pits * 0.2;
  l.colour = lerp_colour(tone * 0.5 + grain * 0.5, s.a, s.b);
  mix_colour(l.colour, {0.30f, 0.29f, 0.27f}, l.height * 2.0 - 0.2);
  l.rough = s.roughness + (grain - 0.5) * 0.2;
}

// Running-bond bricks with mortar.
void bricks(const MaterialSpec& s, int n, cv::RNG& rng, Layers& l) {
  const int rows = 16, cols = 8, bh = n / rows, bw = n / cols, g = std::max(1, n / 256);
  cv::Mat tone = constant(n, 0.5f), mask = constant(n, 0.0f);
  for (int j = 0; j < rows; ++j) {
    const int offset = (j % 2) * bw / 2;
    for (int i = 0; i < cols; ++i) {
      const cv::Rect r(offset + i * bw + g, j * bh + g, bw - 2 * g, bh - 2 * g);
      wrapped_rect(tone, r, cv::Scalar(static_cast<double>(rng.uniform(0.0f, 1.0f))));
      wrapped_rect(mask, r, cv::Scalar(1.0));
    }
  }
  const cv::Mat grain = fbm(n, 16, 6, rng), chips = fbm(n, 64, 2, rng);
  cv::Mat m = wrap_blur(mask, std::max(0.7, 0.8 * g));
  m = m.mul(0.7 + chips * 0.6);
  cv::threshold(m, m, 1.0, 1.0, cv::THRESH_TRUNC);
  l.height = m * 0.85 + grain * 0.15;
  l.colour = lerp_colour(tone * 0.7 + grain * 0.3, s.a, s.b);
  mix_colour(l.colour, {0.62f, 0.60f, 0.55f}, m * 2.0 - 0.4);
  l.rough = s.roughness + (grain - 0.5) * 0.15;
}

// Smooth plaster with stains.
void plaster(const MaterialSpec& s, int n, cv::RNG& rng, Layers& l) {
  const cv::Mat tone = fbm(n, 4, 8, rng), bumps = fbm(n, 32, 4, rng), waves = fbm(n, 4, 3, rng);
  l.height = bumps * 0.6 + waves * 0.4;
  l.colour = lerp_colour(tone, s.a, s.b);
  cv::Mat stain = fbm(n, 4, 5, rng);
  stain = 1.0 - cv::max(stain - 0.65, 0.0) * 1.2;
  scale_colour(l.colour, stain);
  l.rough = s.roughness + (bumps - 0.5) * 0.1;
}

// Wood grain along v (the texture's vertical), the phase warped by stretched noise.
cv::Mat grain_field(int n, float lines, cv::RNG& rng) {
  const cv::Mat warp = fbm(n, 8, 4, rng, 8);
  cv::Mat g(n, n, CV_32F);
  for (int y = 0; y < n; ++y) {
    const float* w = warp.ptr<float>(y);
    float* o = g.ptr<float>(y);
    for (int x = 0; x < n; ++x) {
      const float phase = 2.0f * kPi * (lines * static_cast<float>(x) / static_cast<float>(n) + 3.0f * w[x]);
      o[x] = std::pow(0.5f + 0.5f * std::sin(phase), 3.0f);
    }
  }
  return g;
}

// Boards in strips along v, staggered ends, with grain.
void planks(const MaterialSpec& s, int n, cv::RNG& rng, Layers& l) {
  const int strips = 8, sw = n / strips, g = std::max(1, n / 400);
  cv::Mat tone = constant(n, 0.5f), mask = constant(n, 0.0f);
  for (int i = 0; i < strips; ++i) {
    int y = rng.uniform(0, n / 2);
    const int end = y + n;
    while (y < end) {
      const int h = std::min(end - y, rng.uniform(n / 4, n / 2 + 1));
      const cv::Rect r(i * sw + g, y + g, sw - 2 * g, h - 2 * g);
      wrapped_rect(tone, r, cv::Scalar(static_cast<double>(rng.uniform(0.0f, 1.0f))));
      wrapped_rect(mask, r, cv::Scalar(1.0));
      y += h;
    }
  }
  const cv::Mat grain = grain_field(n, 48.0f, rng);
  l.height = wrap_blur(mask, std::max(0.6, 0.7 * g)).mul(0.9 + grain * 0.1);
  l.colour = lerp_colour(tone * 0.55 + grain * 0.45, s.a, s.b);
  mix_colour(l.colour, {0.08f, 0.05f, 0.03f}, l.height * 3.0 - 0.5);
  l.rough = s.roughness + (grain - 0.5) * 0.15;
}

// Solid wood: grain only.
void wood(const MaterialSpec& s, int n, cv::RNG& rng, Layers& l) {
  const cv::Mat grain = grain_field(n, 24.0f, rng), tone = fbm(n, 4, 5, rng);
  l.height = grain * 0.7 + tone * 0.3;
  l.colour = lerp_colour(grain * 0.6 + tone * 0.4, s.a, s.b);
  l.rough = s.roughness + (tone - 0.5) * 0.2;
}

// Marble: thin veins from a turbulent sine.
void marble(const MaterialSpec& s, int n, cv::RNG& rng, Layers& l) {
  const cv::Mat turb = fbm(n, 4, 6, rng), cloud = fbm(n, 8, 5, rng);
  cv::Mat vein(n, n, CV_32F);
  for (int y = 0; y < n; ++y) {
    const float* t = turb.ptr<float>(y);
    float* o = vein.ptr<float>(y);
    for (int x = 0; x < n; ++x) {
      const float phase = 2.0f * kPi * 2.0f * static_cast<float>(x + y) / static_cast<float>(n) + 7.0f * t[x];
      o[x] = std::exp(-10.0f * std::abs(std::sin(phase)));
    }
  }
  l.height = 0.6 - vein * 0.3 + cloud * 0.1;
  l.colour = lerp_colour(vein * 0.85 + cloud * 0.2, s.a, s.b);
  l.rough = s.roughness + vein * 0.15 + (cloud - 0.5) * 0.1;
}

// Weathered stone: cloudy tone, pitted surface.
void stone(const MaterialSpec& s, int n, cv::RNG& rng, Layers& l) {
  const cv::Mat tone = fbm(n, 8, 6, rng), pits = fbm(n, 32, 4, rng), big = fbm(n, 4, 3, rng);
  cv::Mat p;
  cv::pow(pits, 1.5, p);
  l.height = p * 0.6 + big * 0.4;
  l.colour = lerp_colour(tone * 0.7 + (1.0 - pits) * 0.3, s.a, s.b);
  l.rough = s.roughness + (pits - 0.5) * 0.2;
}

// Woven cloth, a woven band in the second tint near the bottom.
void fabric(const MaterialSpec& s, int n, cv::RNG& rng, Layers& l) {
  const int p = std::max(4, n / 128);
  const cv::Mat tone = fbm(n, 4, 5, rng);
  cv::Mat weave(n, n, CV_32F);
  for (int y = 0; y < n; ++y) {
    float* o = weave.ptr<float>(y);
    for (int x = 0; x < n; ++x) {
      const float sx = std::sin(2.0f * kPi * static_cast<float>(x) / static_cast<float>(p));
      const float sy = std::sin(2.0f * kPi * static_cast<float>(y) / static_cast<float>(p));
      o[x] = 0.5f + 0.5f * sx * sy;
    }
  }
  l.height = weave * 0.8 + tone * 0.2;
  l.colour = lerp_colour(tone * 0.25, s.a, s.a * 1.25f);
  scale_colour(l.colour, 0.8 + weave * 0.2);
  cv::Mat band = constant(n, 0.0f);
  cv::rectangle(band, cv::Rect(0, n * 86 / 100, n, n * 6 / 100), cv::Scalar(1.0), cv::FILLED);
  cv::rectangle(band, cv::Rect(0, n * 94 / 100, n, std::max(1, n / 100)), cv::Scalar(1.0), cv::FILLED);
  mix_colour(l.colour, s.b, 1.0 - band);
  l.rough = s.roughness - band * 0.3;
}

// A heraldic banner: cloth with a border and an emblem in the second tint.
void banner(const MaterialSpec& s, int n, cv::RNG& rng, Layers& l) {
  fabric(s, n, rng, l);
  cv::Mat emblem = constant(n, 0.0f);
  const int t = std::max(1, n / 40);
  cv::rectangle(emblem, cv::Rect(n / 16, n / 16, n - n / 8, n - n / 8), cv::Scalar(1.0), t, cv::LINE_AA);
  cv::circle(emblem, cv::Point(n / 2, n * 2 / 5), n / 5, cv::Scalar(1.0), t, cv::LINE_AA);
  const std::vector<cv::Point> diamond = {{n / 2, n * 2 / 5 - n / 8}, {n / 2 + n / 12, n * 2 / 5},
                                          {n / 2, n * 2 / 5 + n / 8}, {n / 2 - n / 12, n * 2 / 5}};
  cv::fillConvexPoly(emblem, diamond, cv::Scalar(1.0), cv::LINE_AA);
  mix_colour(l.colour, s.b, 1.0 - emblem);
  l.height += emblem * 0.5;
  l.rough -= emblem * 0.3;
}

// Terracotta: warm noise, thrown rings round the pot (v is up).
void terracotta(const MaterialSpec& s, int n, cv::RNG& rng, Layers& l) {
  const cv::Mat tone = fbm(n, 8, 6, rng), grit = fbm(n, 64, 2, rng);
  cv::Mat rings(n, n, CV_32F);
  for (int y = 0; y < n; ++y) {
    const float v = 0.5f + 0.5f * std::sin(2.0f * kPi * 12.0f * static_cast<float>(y) / static_cast<float>(n));
    rings.row(y).setTo(cv::Scalar(static_cast<double>(v)));
  }
  l.height = rings * 0.5 + grit * 0.3 + tone * 0.2;
  l.colour = lerp_colour(tone * 0.8 + rings * 0.2, s.a, s.b);
  l.rough = s.roughness + (grit - 0.5) * 0.1;
}

// Soil: clumps and pebbles.
void soil(const MaterialSpec& s, int n, cv::RNG& rng, Layers& l) {
  const cv::Mat clumps = fbm(n, 32, 4, rng);
  cv::Mat pebbles = constant(n, 0.0f);
  for (int i = 0; i < 200; ++i) {
    const cv::Point c(rng.uniform(0, n), rng.uniform(0, n));
    cv::circle(pebbles, c, std::max(1, n * rng.uniform(4, 12) / 1024), cv::Scalar(1.0), cv::FILLED, cv::LINE_AA);
  }
  pebbles = wrap_blur(pebbles, std::max(0.6, n / 1024.0));
  l.height = clumps * 0.6 + pebbles * 0.4;
  l.colour = lerp_colour(clumps * 0.5 + pebbles, s.a, s.b);
  l.rough = s.roughness - pebbles * 0.2;
}

// Scratches: random thin lines.
cv::Mat scratches(int n, int count, cv::RNG& rng) {
  cv::Mat m = constant(n, 0.0f);
  for (int i = 0; i < count; ++i) {
    const cv::Point a(rng.uniform(0, n), rng.uniform(0, n));
    const float ang = rng.uniform(0.0f, 2.0f * kPi), len = static_cast<float>(n) * rng.uniform(0.02f, 0.15f);
    const cv::Point b(a.x + static_cast<int>(len * std::cos(ang)), a.y + static_cast<int>(len * std::sin(ang)));
    cv::line(m, a, b, cv::Scalar(static_cast<double>(rng.uniform(0.3f, 1.0f))), 1, cv::LINE_AA);
  }
  return m;
}

// Polished metal with scratches.
void metal(const MaterialSpec& s, int n, cv::RNG& rng, Layers& l) {
  const cv::Mat tone = fbm(n, 4, 6, rng), sc = scratches(n, 300, rng);
  l.height = 0.5 + tone * 0.1 - sc * 0.3;
  l.colour = lerp_colour(tone * 0.5 + sc * 0.3, s.a, s.b);
  l.rough = s.roughness + (tone - 0.5) * 0.15 + sc * 0.2;
  l.metal = constant(n, s.metallic);
}

// Wrought iron with rust patches (rust is not metal, and rough).
void iron(const MaterialSpec& s, int n, cv::RNG& rng, Layers& l) {
  const cv::Mat tone = fbm(n, 8, 5, rng), patches = fbm(n, 4, 6, rng), grit = fbm(n, 64, 2, rng);
  cv::Mat rust = cv::min(cv::max((patches - 0.55) * 5.0, 0.0), 1.0);
  l.height = 0.5 + rust.mul(grit) * 0.4 + tone * 0.1;
  l.colour = lerp_colour(tone, s.a, s.b);
  mix_colour(l.colour, {0.42f, 0.20f, 0.09f}, 1.0 - rust);
  l.rough = s.roughness + rust * 0.45;
  l.metal = s.metallic * (1.0 - rust);
}

// One leaf on the u axis, its outline in alpha, midrib and veins raised.
void leaf(const MaterialSpec& s, int n, cv::RNG& rng, Layers& l) {
  const float fn = static_cast<float>(n);
  std::vector<cv::Point> outline;
  constexpr int kSteps = 48;
  std::vector<float> half_width(kSteps + 1);
  for (int k = 0; k <= kSteps; ++k) {
    const float t = static_cast<float>(k) / kSteps;
    half_width[static_cast<std::size_t>(k)] = 0.42f * fn * 0.5f * std::pow(std::max(0.0f, std::sin(kPi * t)), 0.7f) * (1.0f - 0.35f * t);
  }
  for (int k = 0; k <= kSteps; ++k) {
    const float t = static_cast<float>(k) / kSteps;
    outline.emplace_back(static_cast<int>(fn * (0.03f + 0.94f * t)), static_cast<int>(fn * 0.5f - half_width[static_cast<std::size_t>(k)]));
  }
  for (int k = kSteps; k >= 0; --k) {
    const float t = static_cast<float>(k) / kSteps;
    outline.emplace_back(static_cast<int>(fn * (0.03f + 0.94f * t)), static_cast<int>(fn * 0.5f + half_width[static_cast<std::size_t>(k)]));
  }
  cv::Mat shape = cv::Mat::zeros(n, n, CV_8U);
  cv::fillPoly(shape, std::vector<std::vector<cv::Point>>{outline}, cv::Scalar(255));  // LINE_AA here is slow
  shape.convertTo(l.alpha, CV_32F, 1.0 / 255.0);
  l.alpha = wrap_blur(l.alpha, std::max(0.5, n / 2048.0));  // soft edge

  cv::Mat veins = constant(n, 0.0f);
  const int t = std::max(1, n / 128);
  cv::line(veins, {static_cast<int>(0.03f * fn), n / 2}, {static_cast<int>(0.97f * fn), n / 2}, cv::Scalar(1.0), t, cv::LINE_AA);
  for (int i = 1; i < 10; ++i) {
    const float u = 0.03f + 0.094f * static_cast<float>(i);
    const float w = half_width[static_cast<std::size_t>(static_cast<float>(kSteps) * (u + 0.1f > 1.0f ? 1.0f : u + 0.1f))];
    for (const int side : {-1, 1}) {
      cv::line(veins, {static_cast<int>(u * fn), n / 2}, {static_cast<int>((u + 0.1f) * fn), n / 2 + side * static_cast<int>(0.85f * w)},
               cv::Scalar(0.7), std::max(1, t / 2), cv::LINE_AA);
    }
  }
  const cv::Mat tone = fbm(n, 4, 5, rng);
  l.height = 0.4 + wrap_blur(veins, std::max(0.6, n / 512.0)) * 0.5 + tone * 0.1;
  l.colour = lerp_colour(tone * 0.6 + veins * 0.4, s.a, s.b);
  l.rough = s.roughness + (tone - 0.5) * 0.1;
}

Layers make_layers(const MaterialSpec& s, int n, std::uint64_t seed) {
  cv::RNG rng(seed);
  Layers l;
  switch (s.pattern) {
    case Pattern::Tiles: tiles(s, n, rng, l); break;
    case Pattern::Slabs: slabs(s, n, rng, l); break;
    case Pattern::Bricks: bricks(s, n, rng, l); break;
    case Pattern::Plaster: plaster(s, n, rng, l); break;
    case Pattern::Planks: planks(s, n, rng, l); break;
    case Pattern::Wood: wood(s, n, rng, l); break;
    case Pattern::Marble: marble(s, n, rng, l); break;
    case Pattern::Stone: stone(s, n, rng, l); break;
    case Pattern::Fabric: fabric(s, n, rng, l); break;
    case Pattern::Banner: banner(s, n, rng, l); break;
    case Pattern::Terracotta: terracotta(s, n, rng, l); break;
    case Pattern::Soil: soil(s, n, rng, l); break;
    case Pattern::Metal: metal(s, n, rng, l); break;
    case Pattern::Iron: iron(s, n, rng, l); break;
    case Pattern::Leaf: leaf(s, n, rng, l); break;
  }
  if (l.metal.empty()) l.metal = constant(n, s.metallic);
  return l;
}

// A layer resampled to n x n (the metallic-roughness map is smaller than the base colour).
cv::Mat at_size(const cv::Mat& m, int n) {
  if (m.cols == n) return m;
  cv::Mat out;
  cv::resize(m, out, cv::Size(n, n), 0, 0, cv::INTER_AREA);
  return out;
}

// Tangent-space normals from the height field: n = (-dh/du, +dh/dv_up, 1) with the relief `bump`
// pixels of a 1024 texture; RGB = (n + 1) / 2 (written as BGR).
cv::Mat normal_map(const cv::Mat& height, float bump) {
  const int n = height.cols;
  cv::Mat padded, dx, dy;
  cv::copyMakeBorder(height, padded, 1, 1, 1, 1, cv::BORDER_WRAP);
  cv::Sobel(padded, dx, CV_32F, 1, 0, 3);
  cv::Sobel(padded, dy, CV_32F, 0, 1, 3);
  const float k = bump * static_cast<float>(n) / 1024.0f / 8.0f;  // a 3x3 Sobel is 8x the slope
  cv::Mat out(n, n, CV_8UC3);
  for (int y = 0; y < n; ++y) {
    const float* gx = dx.ptr<float>(y + 1) + 1;
    const float* gy = dy.ptr<float>(y + 1) + 1;
    auto* o = out.ptr<cv::Vec3b>(y);
    for (int x = 0; x < n; ++x) {
      // Rows grow down the image; +Y is up it, so the slope up the image is -dh/drow and
      // the normal's y is +dh/drow.
      const glm::vec3 nm = glm::normalize(glm::vec3(-k * gx[x], k * gy[x], 1.0f));
      const auto enc = [](float c) { return cv::saturate_cast<std::uint8_t>(std::lround(127.5f * (c + 1.0f))); };
      o[x] = cv::Vec3b(enc(nm.z), enc(nm.y), enc(nm.x));
    }
  }
  return out;
}

// Occlusion from the height field: crevices below their surroundings are darker.
cv::Mat occlusion(const cv::Mat& height) {
  const cv::Mat around = wrap_blur(height, std::max(1.0, height.cols / 256.0));
  cv::Mat ao = 1.0 - cv::min(cv::max((around - height) * 3.0, 0.0), 0.6);
  return ao;
}

cv::Mat to_u8(const cv::Mat& m) {
  cv::Mat out;
  m.convertTo(out, CV_8U, 255.0);  // saturating, rounding
  return out;
}

struct TextureFiles {
  std::string base, normal, mr;  // URIs relative to the .gltf; mr empty where none
  int base_size = 0, normal_size = 0, mr_size = 0;
};

bool write_image(const fs::path& path, const cv::Mat& m, const std::vector<int>& params) {
  bool ok = false;
  try {
    ok = cv::imwrite(path.string(), m, params);
  } catch (const cv::Exception& e) {
    std::fprintf(stderr, "make_gltf_standin: %s: %s\n", path.c_str(), e.what());
    return false;
  }
  if (!ok) std::fprintf(stderr, "make_gltf_standin: cannot write %s\n", path.c_str());
  return ok;
}

// Generates and writes material `m`'s textures; false (after a message) when a file cannot be written.
bool write_textures(const fs::path& dir, std::uint32_t m, bool small, TextureFiles& f) {
  const MaterialSpec& s = kMaterials[m];
  const int big = small ? 64 : (s.big ? 2048 : 1024), mr_size = small ? 64 : 1024;
  const Layers l = make_layers(s, big, 0x5f0a7e00u + 7919u * m);
  const std::string name = s.name;
  const std::vector<int> png = {cv::IMWRITE_PNG_COMPRESSION, 6};

  cv::Mat rgb = to_u8(l.colour), bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  f.base_size = f.normal_size = big;
  if (s.mask) {
    std::vector<cv::Mat> channels;
    cv::split(bgr, channels);
    channels.push_back(to_u8(l.alpha));
    cv::Mat bgra;
    cv::merge(channels, bgra);
    f.base = "textures/" + name + "_basecolor.png";
    if (!write_image(dir / f.base, bgra, png)) return false;
  } else {
    f.base = "textures/" + name + "_basecolor.jpg";
    if (!write_image(dir / f.base, bgr, {cv::IMWRITE_JPEG_QUALITY, 90})) return false;
  }
  f.normal = "textures/" + name + "_normal.png";
  if (!write_image(dir / f.normal, normal_map(l.height, s.bump), png)) return false;
  if (s.mr) {
    f.mr = "textures/" + name + "_mr.png";  // R occlusion, G roughness, B metallic (BGR order here)
    f.mr_size = mr_size;
    const cv::Mat mr = to_u8(at_size(l.metal, mr_size)), rough = to_u8(at_size(l.rough, mr_size)),
                  ao = to_u8(at_size(occlusion(l.height), mr_size));
    cv::Mat bgr_mr;
    cv::merge(std::vector<cv::Mat>{mr, rough, ao}, bgr_mr);
    if (!write_image(dir / f.mr, bgr_mr, png)) return false;
  }
  return true;
}

// ---------------------------------------------------------------------------------------------
// Geometry.

struct Geo {
  std::vector<glm::vec3> pos, nrm;
  std::vector<glm::vec2> uv;
  std::vector<std::uint32_t> idx;

  std::uint32_t vertex(const glm::vec3& p, const glm::vec3& n, const glm::vec2& t) {
    pos.push_back(p);
    nrm.push_back(n);
    uv.push_back(t);
    return static_cast<std::uint32_t>(pos.size() - 1);
  }
  // A triangle wound counter-clockwise seen from the side its vertex normals face.
  void tri(std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    const glm::vec3 face = glm::cross(pos[b] - pos[a], pos[c] - pos[a]);
    if (glm::dot(face, nrm[a] + nrm[b] + nrm[c]) < 0.0f) std::swap(b, c);
    idx.insert(idx.end(), {a, b, c});
  }
  void quad(std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t d) {
    tri(a, b, c);
    tri(a, c, d);
  }
  std::size_t triangles() const { return idx.size() / 3; }
};

int subdivisions(float length, float per_metre) { return std::max(1, static_cast<int>(std::lround(length * per_metre))); }

// A flat grid from `o` along U (nu cells) and V (nv cells), facing U x V; the image's up along V.
// `uv_u`, `uv_v`: how many times the texture repeats along U and V.
void grid(Geo& g, glm::vec3 o, glm::vec3 u, glm::vec3 v, int nu, int nv, float uv_u, float uv_v) {
  const glm::vec3 n = glm::normalize(glm::cross(u, v));
  const std::uint32_t base = static_cast<std::uint32_t>(g.pos.size());
  for (int j = 0; j <= nv; ++j) {
    for (int i = 0; i <= nu; ++i) {
      const float s = static_cast<float>(i) / static_cast<float>(nu), t = static_cast<float>(j) / static_cast<float>(nv);
      g.vertex(o + s * u + t * v, n, {s * uv_u, (1.0f - t) * uv_v});
    }
  }
  const auto at = [&](int i, int j) { return base + static_cast<std::uint32_t>(j * (nu + 1) + i); };
  for (int j = 0; j < nv; ++j) {
    for (int i = 0; i < nu; ++i) g.quad(at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
  }
}

// A box of half extents h round c: six grids of `per_metre` cells, texture repeats `uv_per_metre`.
void box(Geo& g, glm::vec3 c, glm::vec3 h, float per_metre, float uv_per_metre) {
  struct Face {
    glm::vec3 origin, u, v;
  };
  const Face faces[] = {
      {{h.x, -h.y, h.z}, {0, 0, -2 * h.z}, {0, 2 * h.y, 0}},    // +X
      {{-h.x, -h.y, -h.z}, {0, 0, 2 * h.z}, {0, 2 * h.y, 0}},   // -X
      {{-h.x, -h.y, h.z}, {2 * h.x, 0, 0}, {0, 2 * h.y, 0}},    // +Z
      {{h.x, -h.y, -h.z}, {-2 * h.x, 0, 0}, {0, 2 * h.y, 0}},   // -Z
      {{-h.x, h.y, h.z}, {2 * h.x, 0, 0}, {0, 0, -2 * h.z}},    // +Y
      {{-h.x, -h.y, -h.z}, {2 * h.x, 0, 0}, {0, 0, 2 * h.z}},   // -Y
  };
  for (const Face& f : faces) {
    const float lu = glm::length(f.u), lv = glm::length(f.v);
    grid(g, c + f.origin, f.u, f.v, subdivisions(lu, per_metre), subdivisions(lv, per_metre), lu * uv_per_metre,
         lv * uv_per_metre);
  }
}

// A surface of revolution round +Y of the profile (radius, height) points, smooth along it;
// u goes round `u_repeat` times, v runs down the profile at `v_per_metre`. Optional flat caps.
void lathe(Geo& g, const std::vector<glm::vec2>& profile, int segments, float u_repeat, float v_per_metre,
           bool cap_bottom = false, bool cap_top = false) {
  const std::size_t rings = profile.size();
  std::vector<float> arc(rings, 0.0f);
  for (std::size_t j = 1; j < rings; ++j) arc[j] = arc[j - 1] + glm::length(profile[j] - profile[j - 1]);
  const std::uint32_t base = static_cast<std::uint32_t>(g.pos.size());
  for (std::size_t j = 0; j < rings; ++j) {
    const glm::vec2 d = profile[std::min(j + 1, rings - 1)] - profile[j > 0 ? j - 1 : 0];
    const glm::vec2 pn = glm::normalize(glm::vec2(d.y, -d.x));  // outward for a profile going up
    for (int i = 0; i <= segments; ++i) {
      const float a = 2.0f * kPi * static_cast<float>(i) / static_cast<float>(segments);
      const glm::vec3 radial(std::cos(a), 0.0f, -std::sin(a));
      g.vertex(radial * profile[j].x + glm::vec3(0, profile[j].y, 0), glm::normalize(radial * pn.x + glm::vec3(0, pn.y, 0)),
               {u_repeat * static_cast<float>(i) / static_cast<float>(segments), (arc.back() - arc[j]) * v_per_metre});
    }
  }
  const auto at = [&](std::size_t j, int i) {
    return base + static_cast<std::uint32_t>(j * static_cast<std::size_t>(segments + 1) + static_cast<std::size_t>(i));
  };
  for (std::size_t j = 0; j + 1 < rings; ++j) {
    for (int i = 0; i < segments; ++i) g.quad(at(j, i), at(j, i + 1), at(j + 1, i + 1), at(j + 1, i));
  }
  for (const bool top : {false, true}) {
    if (!(top ? cap_top : cap_bottom)) continue;
    const glm::vec2 p = top ? profile.back() : profile.front();
    const glm::vec3 n(0, top ? 1 : -1, 0);
    const std::uint32_t centre = g.vertex({0, p.y, 0}, n, {0.5f, 0.5f});
    const std::uint32_t ring = static_cast<std::uint32_t>(g.pos.size());
    for (int i = 0; i <= segments; ++i) {
      const float a = 2.0f * kPi * static_cast<float>(i) / static_cast<float>(segments);
      g.vertex({p.x * std::cos(a), p.y, -p.x * std::sin(a)}, n, {0.5f + 0.5f * std::cos(a), 0.5f + 0.5f * std::sin(a)});
    }
    for (int i = 0; i < segments; ++i) g.tri(centre, ring + static_cast<std::uint32_t>(i), ring + static_cast<std::uint32_t>(i) + 1);
  }
}

// Profile points from f(t), t in 0..1, `rings` + 1 of them.
template <typename F>
std::vector<glm::vec2> profile(int rings, F f) {
  std::vector<glm::vec2> p;
  for (int j = 0; j <= rings; ++j) p.push_back(f(static_cast<float>(j) / static_cast<float>(rings)));
  return p;
}

// Half a torus in the XY plane over the X axis, from (-R, 0) up to (R, 0): an arch.
void half_torus(Geo& g, float major, float minor, int along, int around) {
  const std::uint32_t base = static_cast<std::uint32_t>(g.pos.size());
  for (int j = 0; j <= along; ++j) {
    const float phi = kPi * static_cast<float>(j) / static_cast<float>(along);
    const glm::vec3 dir(-std::cos(phi), std::sin(phi), 0.0f);
    for (int i = 0; i <= around; ++i) {
      const float th = 2.0f * kPi * static_cast<float>(i) / static_cast<float>(around);
      const glm::vec3 n = std::cos(th) * dir + std::sin(th) * glm::vec3(0, 0, 1);
      g.vertex(major * dir + minor * n, n, {4.0f * static_cast<float>(j) / static_cast<float>(along), static_cast<float>(i) / static_cast<float>(around)});
    }
  }
  const auto at = [&](int j, int i) { return base + static_cast<std::uint32_t>(j * (around + 1) + i); };
  for (int j = 0; j < along; ++j) {
    for (int i = 0; i < around; ++i) g.quad(at(j, i), at(j + 1, i), at(j + 1, i + 1), at(j, i + 1));
  }
}

// A UV sphere of radius r (one triangle per cell at the poles).
void sphere(Geo& g, float r, int segments, int rings) {
  const std::uint32_t base = static_cast<std::uint32_t>(g.pos.size());
  for (int j = 0; j <= rings; ++j) {
    const float th = kPi * static_cast<float>(j) / static_cast<float>(rings);
    for (int i = 0; i <= segments; ++i) {
      const float ph = 2.0f * kPi * static_cast<float>(i) / static_cast<float>(segments);
      const glm::vec3 n(std::sin(th) * std::cos(ph), std::cos(th), -std::sin(th) * std::sin(ph));
      g.vertex(r * n, n, {2.0f * static_cast<float>(i) / static_cast<float>(segments), static_cast<float>(j) / static_cast<float>(rings)});
    }
  }
  const auto at = [&](int j, int i) { return base + static_cast<std::uint32_t>(j * (segments + 1) + i); };
  for (int j = 0; j < rings; ++j) {
    for (int i = 0; i < segments; ++i) {
      if (j != 0) g.tri(at(j, i), at(j, i + 1), at(j + 1, i + 1));
      if (j != rings - 1) g.tri(at(j, i), at(j + 1, i + 1), at(j + 1, i));
    }
  }
}

// Area-weighted vertex normals, for displaced grids.
void smooth_normals(Geo& g, std::size_t first_vertex, std::size_t first_index) {
  for (std::size_t v = first_vertex; v < g.nrm.size(); ++v) g.nrm[v] = glm::vec3(0.0f);
  for (std::size_t i = first_index; i + 2 < g.idx.size(); i += 3) {
    const glm::vec3 f = glm::cross(g.pos[g.idx[i + 1]] - g.pos[g.idx[i]], g.pos[g.idx[i + 2]] - g.pos[g.idx[i]]);
    for (std::size_t k = 0; k < 3; ++k) g.nrm[g.idx[i + k]] += f;
  }
  for (std::size_t v = first_vertex; v < g.nrm.size(); ++v) g.nrm[v] = glm::normalize(g.nrm[v]);
}

// Cloth hanging from its top edge at the origin, `w` wide along X and `h` down, facing +Z, folded:
// z = amplitude * sin(...) with the folds deepening towards the hem.
void cloth(Geo& g, float w, float h, int nu, int nv, float folds, float depth, float uv_u, float seed_phase) {
  const std::size_t v0 = g.pos.size(), i0 = g.idx.size();
  grid(g, {-w / 2, -h, 0}, {w, 0, 0}, {0, h, 0}, nu, nv, uv_u, 1.0f);
  for (std::size_t v = v0; v < g.pos.size(); ++v) {
    glm::vec3& p = g.pos[v];
    const float s = (p.x + w / 2) / w, down = -p.y / h;  // 0 at the top, 1 at the hem
    const float amp = depth * (0.6f + 0.4f * down);
    p.z = amp * std::sin(2.0f * kPi * folds * s + seed_phase + 1.5f * down * std::sin(3.0f * s + seed_phase));
    p.x *= 1.0f - 0.08f * (1.0f - down);  // gathered at the top
  }
  smooth_normals(g, v0, i0);
}

// A leaf from the origin along +X, bent down, as a grid (both sides drawn: doubleSided).
void leaf_blade(Geo& g, const glm::mat4& m, float length, float width, float droop, int nu, int nv) {
  const std::size_t v0 = g.pos.size(), i0 = g.idx.size();
  grid(g, {0, 0, -width / 2}, {length, 0, 0}, {0, 0, width}, nu, nv, 1.0f, 1.0f);
  // Texture v runs across the leaf: the leaf image lies along u, its midrib at v = 0.5.
  for (std::size_t v = v0; v < g.pos.size(); ++v) {
    glm::vec3 p = g.pos[v];
    const float s = p.x / length;
    p.y -= droop * s * s;
    p.y += 0.15f * width * std::abs(p.z) / (width / 2);  // a shallow V along the midrib
    g.pos[v] = glm::vec3(m * glm::vec4(p, 1.0f));
  }
  smooth_normals(g, v0, i0);
}

// Per-vertex tangents (Lengyel): dP/du made orthogonal to the normal; w so that cross(n, t) w
// points up the image (towards decreasing glTF v), as glTF's bitangent does.
std::vector<glm::vec4> tangents(const Geo& g) {
  std::vector<glm::vec3> tan(g.pos.size(), glm::vec3(0.0f)), bit(g.pos.size(), glm::vec3(0.0f));
  for (std::size_t i = 0; i + 2 < g.idx.size(); i += 3) {
    const std::uint32_t a = g.idx[i], b = g.idx[i + 1], c = g.idx[i + 2];
    const glm::vec3 e1 = g.pos[b] - g.pos[a], e2 = g.pos[c] - g.pos[a];
    const glm::vec2 d1 = g.uv[b] - g.uv[a], d2 = g.uv[c] - g.uv[a];
    const float det = d1.x * d2.y - d2.x * d1.y;
    if (std::abs(det) < 1e-12f) continue;
    const float sign = det > 0 ? 1.0f : -1.0f;
    const glm::vec3 t = (e1 * d2.y - e2 * d1.y) * sign, bt = (e2 * d1.x - e1 * d2.x) * sign;
    for (const std::uint32_t v : {a, b, c}) {
      tan[v] += t;
      bit[v] += bt;
    }
  }
  std::vector<glm::vec4> out(g.pos.size(), glm::vec4(1, 0, 0, 1));
  for (std::size_t v = 0; v < out.size(); ++v) {
    const glm::vec3 n = g.nrm[v];
    glm::vec3 t = tan[v] - n * glm::dot(n, tan[v]);
    if (glm::length(t) < 1e-12f) {  // no UV gradient: any tangent perpendicular to n
      t = glm::cross(std::abs(n.x) < 0.9f ? glm::vec3(1, 0, 0) : glm::vec3(0, 1, 0), n);
    }
    t = glm::normalize(t);
    out[v] = glm::vec4(t, glm::dot(glm::cross(n, t), bit[v]) > 0 ? -1.0f : 1.0f);
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// The glTF document and its buffer.

struct Accessors {
  int position = -1, normal = -1, texcoord = -1, tangent = -1, indices = -1;
  std::size_t triangles = 0;
};

class Writer {
 public:
  json doc;
  std::vector<std::uint8_t> bin;
  std::size_t unique_triangles = 0, instanced_triangles = 0;
  std::vector<std::size_t> mesh_triangles;

  Accessors add(const Geo& g, bool with_tangents) {
    Accessors a;
    glm::vec3 lo(g.pos.front()), hi(g.pos.front());
    for (const glm::vec3& p : g.pos) {
      lo = glm::min(lo, p);
      hi = glm::max(hi, p);
    }
    const auto count = g.pos.size();
    a.position = accessor(view(g.pos.data(), count * sizeof(glm::vec3), 34962), 5126, count, "VEC3");
    doc["accessors"][static_cast<std::size_t>(a.position)]["min"] = {double{lo.x}, double{lo.y}, double{lo.z}};
    doc["accessors"][static_cast<std::size_t>(a.position)]["max"] = {double{hi.x}, double{hi.y}, double{hi.z}};
    a.normal = accessor(view(g.nrm.data(), count * sizeof(glm::vec3), 34962), 5126, count, "VEC3");
    a.texcoord = accessor(view(g.uv.data(), count * sizeof(glm::vec2), 34962), 5126, count, "VEC2");
    if (with_tangents) {
      const std::vector<glm::vec4> t = tangents(g);
      a.tangent = accessor(view(t.data(), count * sizeof(glm::vec4), 34962), 5126, count, "VEC4");
    }
    a.indices = accessor(view(g.idx.data(), g.idx.size() * sizeof(std::uint32_t), 34963), 5125, g.idx.size(), "SCALAR");
    a.triangles = g.triangles();
    unique_triangles += a.triangles;
    return a;
  }

  // A mesh of primitives (accessors, material); meshes may share accessors.
  std::uint32_t mesh(const std::string& name, const std::vector<std::pair<Accessors, std::uint32_t>>& prims) {
    json p = json::array();
    std::size_t tris = 0;
    for (const auto& [a, material] : prims) {
      json attributes = {{"POSITION", a.position}, {"NORMAL", a.normal}, {"TEXCOORD_0", a.texcoord}};
      if (a.tangent >= 0) attributes["TANGENT"] = a.tangent;
      p.push_back({{"attributes", attributes}, {"indices", a.indices}, {"material", material}, {"mode", 4}});
      tris += a.triangles;
    }
    doc["meshes"].push_back({{"name", name}, {"primitives", p}});
    mesh_triangles.push_back(tris);
    return static_cast<std::uint32_t>(doc["meshes"].size() - 1);
  }

  // A node; `mesh` < 0 for none. Transform as translation, rotation, scale (left out when identity).
  std::uint32_t node(const std::string& name, int mesh, glm::vec3 t = glm::vec3(0.0f), glm::quat r = glm::quat(1, 0, 0, 0),
                     glm::vec3 s = glm::vec3(1.0f)) {
    json n = {{"name", name}};
    if (mesh >= 0) {
      n["mesh"] = mesh;
      instanced_triangles += mesh_triangles[static_cast<std::size_t>(mesh)];
    }
    if (t != glm::vec3(0.0f)) n["translation"] = {tidy(t.x), tidy(t.y), tidy(t.z)};
    if (r != glm::quat(1, 0, 0, 0)) n["rotation"] = {tidy(r.x, 1e6), tidy(r.y, 1e6), tidy(r.z, 1e6), tidy(r.w, 1e6)};
    if (s != glm::vec3(1.0f)) n["scale"] = {tidy(s.x), tidy(s.y), tidy(s.z)};
    doc["nodes"].push_back(n);
    return static_cast<std::uint32_t>(doc["nodes"].size() - 1);
  }

  void children(std::uint32_t parent, const std::vector<std::uint32_t>& kids) { doc["nodes"][parent]["children"] = kids; }

  // Rounded for a tidy file: millimetres, or `scale` for rotations.
  static double tidy(float v, double scale = 1e4) { return std::round(static_cast<double>(v) * scale) / scale; }

 private:
  int view(const void* data, std::size_t bytes, int target) {
    while (bin.size() % 4 != 0) bin.push_back(0);
    const std::size_t offset = bin.size();
    bin.resize(offset + bytes);
    std::memcpy(bin.data() + offset, data, bytes);
    doc["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", offset}, {"byteLength", bytes}, {"target", target}});
    return static_cast<int>(doc["bufferViews"].size() - 1);
  }
  int accessor(int buffer_view, int component, std::size_t count, const char* type) {
    doc["accessors"].push_back({{"bufferView", buffer_view}, {"componentType", component}, {"count", count}, {"type", type}});
    return static_cast<int>(doc["accessors"].size() - 1);
  }
};

glm::quat yaw(float deg) { return glm::angleAxis(glm::radians(deg), glm::vec3(0, 1, 0)); }

// The courtyard's nodes and meshes. `q` scales every resolution: 4 full, 1 for --small.
void build_scene(Writer& w, int q, std::vector<std::uint32_t>& roots) {
  const float fq = static_cast<float>(q);
  const float density = 1.0f * fq;  // grid cells per metre on the big surfaces
  const auto single = [&](const std::string& name, const Geo& g, bool tan, std::uint32_t material) {
    return static_cast<int>(w.mesh(name, {{w.add(g, tan), material}}));
  };
  const auto root = [&](const std::string& name, int mesh, glm::vec3 t = glm::vec3(0.0f), glm::quat r = glm::quat(1, 0, 0, 0),
                        glm::vec3 s = glm::vec3(1.0f)) { roots.push_back(w.node(name, mesh, t, r, s)); };

  // Dimensions (metres): x -15..15 (the long axis), z -7..7, y 0..12.
  constexpr float kHalfX = 15.0f, kHalfZ = 7.0f, kHeight = 12.0f, kStorey = 6.3f, kRowZ = 4.0f;
  constexpr float kColumnH = 4.0f, kUpperScale = 0.8f, kBay = 3.0f;
  constexpr int kColumns = 9;  // per row, x = -12 .. 12

  // Floor: tiled courtyard, slab border round it (long strips instanced by a half turn).
  {
    Geo court, strip, end;
    grid(court, {-12, 0, 4}, {24, 0, 0}, {0, 0, -8}, subdivisions(24, density), subdivisions(8, density), 8.0f, 8.0f / 3.0f);
    grid(strip, {-kHalfX, 0, kHalfZ}, {30, 0, 0}, {0, 0, -3}, subdivisions(30, density), subdivisions(3, density), 15.0f, 1.5f);
    grid(end, {-kHalfX, 0, 4}, {3, 0, 0}, {0, 0, -8}, subdivisions(3, density), subdivisions(8, density), 1.5f, 4.0f);
    root("floor_courtyard", single("floor_courtyard", court, true, kFloorTiles));
    const int s = single("floor_border_long", strip, true, kFloorSlabs), e = single("floor_border_end", end, true, kFloorSlabs);
    root("floor_border_south", s);
    root("floor_border_north", s, glm::vec3(0.0f), yaw(180));
    root("floor_border_west", e);
    root("floor_border_east", e, glm::vec3(0.0f), yaw(180));
  }

  // Walls: two storeys, inward facing; the far wall of each pair is the same mesh turned round.
  {
    Geo long_lo, long_hi, end_lo, end_hi;
    const float upper = kHeight - kStorey;
    grid(long_lo, {-kHalfX, 0, -kHalfZ}, {30, 0, 0}, {0, kStorey, 0}, subdivisions(30, density), subdivisions(kStorey, density),
         30.0f / 1.5f, kStorey / 1.5f);
    grid(long_hi, {-kHalfX, kStorey, -kHalfZ}, {30, 0, 0}, {0, upper, 0}, subdivisions(30, density), subdivisions(upper, density),
         30.0f / 3.0f, upper / 3.0f);
    grid(end_lo, {-kHalfX, 0, kHalfZ}, {0, 0, -14}, {0, kStorey, 0}, subdivisions(14, density), subdivisions(kStorey, density),
         14.0f / 1.5f, kStorey / 1.5f);
    grid(end_hi, {-kHalfX, kStorey, kHalfZ}, {0, 0, -14}, {0, upper, 0}, subdivisions(14, density), subdivisions(upper, density),
         14.0f / 3.0f, upper / 3.0f);
    const int ll = single("wall_long_lower", long_lo, true, kWallBrick), lh = single("wall_long_upper", long_hi, true, kWallPlaster);
    const int el = single("wall_end_lower", end_lo, true, kWallBrick), eh = single("wall_end_upper", end_hi, true, kWallPlaster);
    root("wall_north_lower", ll);
    root("wall_north_upper", lh);
    root("wall_south_lower", ll, glm::vec3(0.0f), yaw(180));
    root("wall_south_upper", lh, glm::vec3(0.0f), yaw(180));
    root("wall_west_lower", el);
    root("wall_west_upper", eh);
    root("wall_east_lower", el, glm::vec3(0.0f), yaw(180));
    root("wall_east_upper", eh, glm::vec3(0.0f), yaw(180));
  }

  // Ceiling and its beams.
  {
    Geo ceiling, beam;
    grid(ceiling, {-kHalfX, kHeight, -kHalfZ}, {30, 0, 0}, {0, 0, 14}, subdivisions(30, density), subdivisions(14, density), 30.0f / 4.0f,
         14.0f / 4.0f);
    box(beam, {0, -0.2f, 0}, {0.15f, 0.2f, kHalfZ}, 0.5f * fq, 0.5f);
    root("ceiling", single("ceiling", ceiling, true, kCeilingWood));
    const int b = single("beam", beam, false, kBeamWood);
    for (int i = 0; i < 15; ++i) root("beam_" + std::to_string(i), b, {-14.0f + 2.0f * static_cast<float>(i), kHeight, 0});
  }

  // Gallery slabs (the upper storey's floor, the lower arcade's ceiling) and the entablatures.
  {
    Geo slab, ent_lo, ent_hi;
    box(slab, {0, 0, 0}, {kHalfX, 0.15f, 1.5f}, 0.5f * fq, 0.5f);
    box(ent_lo, {0, 0, 0}, {12.5f, 0.3f, 0.35f}, 0.5f * fq, 0.5f);
    box(ent_hi, {0, 0, 0}, {12.5f, 0.275f, 0.3f}, 0.5f * fq, 0.5f);
    const int s = single("gallery_slab", slab, true, kGalleryFloor);
    root("gallery_slab_north", s, {0, kStorey - 0.15f, -5.5f});
    root("gallery_slab_south", s, {0, kStorey - 0.15f, 5.5f});
    const int el = single("entablature_lower", ent_lo, false, kEntablature);
    const int eh = single("entablature_upper", ent_hi, false, kEntablature);
    for (const float z : {-kRowZ, kRowZ}) {
      const std::string side = z < 0 ? "north" : "south";
      root("entablature_lower_" + side, el, {0, 6.0f, z});
      root("entablature_upper_" + side, eh, {0, kStorey + kColumnH * kUpperScale + 1.72f * kUpperScale + 0.2f, z});
    }
  }

  // Columns (shaft + trim, two primitives) and arches, both storeys; the upper ones are the same
  // meshes scaled.
  {
    const int seg = 12 * q;
    Geo shaft, trim;
    lathe(shaft, profile(3 * q, [](float t) { return glm::vec2(0.29f - 0.03f * t + 0.012f * std::sin(kPi * t), 0.45f + 3.05f * t); }),
          seg, 1.0f, 1.0f / 3.0f);
    box(trim, {0, 0.125f, 0}, {0.45f, 0.125f, 0.45f}, 0.5f * fq, 1.0f);  // plinth
    const int moulding = std::max(1, 5 * q / 4);
    lathe(trim, profile(moulding, [](float t) { return glm::vec2(0.34f + 0.07f * std::sin(kPi * t), 0.25f + 0.2f * t); }), seg, 2.0f, 1.0f);
    lathe(trim, profile(moulding, [](float t) { return glm::vec2(0.27f + 0.17f * t * t, 3.5f + 0.3f * t); }), seg, 2.0f, 1.0f);
    box(trim, {0, 3.9f, 0}, {0.47f, 0.1f, 0.47f}, 0.5f * fq, 1.0f);  // abacus
    Geo arch;
    half_torus(arch, kBay / 2, 0.22f, 8 * q, 3 * q);
    const int column = static_cast<int>(w.mesh("column", {{w.add(shaft, true), kColumnMarble}, {w.add(trim, false), kColumnTrim}}));
    const int a = single("arch", arch, true, kArchStone);
    for (int storey = 0; storey < 2; ++storey) {
      const float y = storey == 0 ? 0.0f : kStorey;
      const float s = storey == 0 ? 1.0f : kUpperScale;
      for (const float z : {-kRowZ, kRowZ}) {
        const std::string tag = std::string(storey == 0 ? "lower_" : "upper_") + (z < 0 ? "north_" : "south_");
        for (int i = 0; i < kColumns; ++i) {
          const float x = -12.0f + kBay * static_cast<float>(i);
          root("column_" + tag + std::to_string(i), column, {x, y, z}, glm::quat(1, 0, 0, 0), glm::vec3(s));
          if (i + 1 < kColumns) {
            root("arch_" + tag + std::to_string(i), a, {x + kBay / 2, y + kColumnH * s, z}, glm::quat(1, 0, 0, 0), {1.0f, s, s});
          }
        }
      }
    }
  }

  // The upper gallery's balustrade: lathed balusters between the columns, and a rail.
  {
    Geo baluster, rail;
    lathe(baluster, profile(5 * q / 2, [](float t) {
            const float r = 0.05f + 0.035f * std::pow(std::sin(kPi * (0.15f + 0.7f * t)), 4.0f) - 0.015f * std::sin(2.0f * kPi * t);
            return glm::vec2(r, 0.8f * t);
          }),
          3 * q, 1.0f, 1.0f);
    box(rail, {0, 0, 0}, {12.0f, 0.07f, 0.12f}, 0.5f * fq, 1.0f);
    const int b = single("baluster", baluster, false, kBalustrade), r = single("rail", rail, false, kBalustrade);
    for (const float z : {-kRowZ, kRowZ}) {
      const std::string side = z < 0 ? "north_" : "south_";
      root("rail_" + side.substr(0, side.size() - 1), r, {0, kStorey + 0.87f, z});
      int k = 0;
      for (int bay = 0; bay + 1 < kColumns; ++bay) {
        for (int i = 0; i < 7; ++i) {
          const float x = -12.0f + kBay * static_cast<float>(bay) + 0.6f + 0.3f * static_cast<float>(i);
          root("baluster_" + side + std::to_string(k++), b, {x, kStorey, z});
        }
      }
    }
  }

  // Curtains hanging from rods in the upper arcade (three colours sharing one cloth's accessors),
  // banners on the end walls.
  {
    Geo curtain, rod, flag;
    cloth(curtain, 2.4f, 5.2f, 12 * q, 10 * q, 6.0f, 0.07f, 2.0f, 0.3f);
    lathe(rod, profile(1, [](float t) { return glm::vec2(0.03f, 2.7f * t); }), 4 * q, 1.0f, 1.0f, true, true);
    cloth(flag, 1.4f, 3.4f, 4 * q, 8 * q, 2.0f, 0.04f, 1.0f, 1.1f);
    const Accessors cloth_acc = w.add(curtain, false);
    const int colours[] = {static_cast<int>(w.mesh("curtain_red", {{cloth_acc, kCurtainRed}})),
                           static_cast<int>(w.mesh("curtain_green", {{cloth_acc, kCurtainGreen}})),
                           static_cast<int>(w.mesh("curtain_blue", {{cloth_acc, kCurtainBlue}}))};
    const int rod_mesh = single("curtain_rod", rod, false, kIron);
    const float top = kStorey + 3.9f;
    int k = 0;
    for (const float z : {-kRowZ + 0.45f, kRowZ - 0.45f}) {
      for (const int bay : {1, 3, 5}) {
        const float x = -12.0f + kBay * static_cast<float>(bay) + kBay / 2;
        const glm::quat face = z < 0 ? glm::quat(1, 0, 0, 0) : yaw(180);  // the front faces the courtyard
        root("curtain_" + std::to_string(k), colours[k % 3], {x, top, z}, face);
        root("curtain_rod_" + std::to_string(k), rod_mesh, {x - 1.35f, top + 0.04f, z},
             glm::angleAxis(glm::radians(-90.0f), glm::vec3(0, 0, 1)));
        ++k;
      }
    }
    const int banner = single("banner", flag, false, kBanner);
    k = 0;
    for (const float x : {-kHalfX + 0.1f, kHalfX - 0.1f}) {
      for (const float z : {-4.0f, 0.0f, 4.0f}) {
        root("banner_" + std::to_string(k++), banner, {x, kStorey + 4.6f, z}, yaw(x < 0 ? 90.0f : -90.0f));
      }
    }
  }

  // Doors in the end walls.
  {
    Geo door;
    box(door, {0, 1.8f, 0}, {0.06f, 1.8f, 1.2f}, 0.5f * fq, 0.5f);
    const int d = single("door", door, false, kDoorWood);
    root("door_west", d, {-kHalfX, 0, 0});
    root("door_east", d, {kHalfX, 0, 0}, yaw(180));
  }

  // Potted plants: a pot (pot and soil primitives) and a cluster of leaves, children of a plant node.
  {
    Geo pot, earth, leaves;
    lathe(pot, profile(4 * q, [](float t) {
            const float rim = t > 0.88f ? 0.03f * std::sin(kPi * (t - 0.88f) / 0.12f) : 0.0f;
            return glm::vec2(0.2f + 0.14f * std::pow(t, 0.8f) + rim, 0.62f * t);
          }),
          12 * q, 2.0f, 1.0f, true, false);
    lathe(earth, profile(1, [](float t) { return glm::vec2(0.33f, 0.5f + 0.06f * t); }), 12 * q, 1.0f, 1.0f, false, true);
    cv::RNG rng(0x1eaf);
    for (int i = 0; i < 36; ++i) {
      const float azimuth = rng.uniform(0.0f, 360.0f), elevation = rng.uniform(15.0f, 65.0f);
      glm::mat4 m = glm::translate(glm::mat4(1.0f), glm::vec3(rng.uniform(-0.08f, 0.08f), 0.5f, rng.uniform(-0.08f, 0.08f)));
      m = m * glm::mat4_cast(glm::angleAxis(glm::radians(azimuth), glm::vec3(0, 1, 0)) *
                             glm::angleAxis(glm::radians(elevation), glm::vec3(0, 0, 1)) *
                             glm::angleAxis(glm::radians(rng.uniform(-20.0f, 20.0f)), glm::vec3(1, 0, 0)));
      leaf_blade(leaves, m, rng.uniform(0.5f, 0.85f), rng.uniform(0.16f, 0.24f), rng.uniform(0.15f, 0.35f), 2 * q, std::max(1, q / 2));
    }
    const int pot_mesh = static_cast<int>(w.mesh("pot", {{w.add(pot, false), kTerracotta}, {w.add(earth, false), kSoil}}));
    const int leaf_mesh = single("leaves", leaves, false, kLeaves);
    int k = 0;
    cv::RNG place(0x9a27);
    for (const float z : {-3.2f, 3.2f}) {
      for (const float x : {-10.5f, -4.5f, 4.5f, 10.5f}) {
        const std::string name = "plant_" + std::to_string(k++);
        const std::uint32_t p = w.node(name + "_pot", pot_mesh);
        const std::uint32_t l = w.node(name + "_leaves", leaf_mesh, glm::vec3(0.0f), yaw(place.uniform(0.0f, 360.0f)),
                                       glm::vec3(place.uniform(0.9f, 1.2f)));
        const std::uint32_t plant = w.node(name, -1, {x, 0, z}, yaw(place.uniform(0.0f, 360.0f)));
        w.children(plant, {p, l});
        roots.push_back(plant);
      }
    }
  }

  // Decorative spheres on pedestals: a big bronze one in the middle, gold and marble ones round it
  // (two meshes sharing one sphere's accessors).
  {
    Geo big_sphere, small_sphere, pedestal, plinth;
    sphere(big_sphere, 0.7f, 16 * q, 8 * q);
    sphere(small_sphere, 0.3f, 12 * q, 6 * q);
    box(pedestal, {0, 0.6f, 0}, {0.5f, 0.6f, 0.5f}, 0.5f * fq, 1.0f);
    box(plinth, {0, 0.45f, 0}, {0.25f, 0.45f, 0.25f}, 0.5f * fq, 1.0f);
    root("sphere_bronze", single("sphere_bronze", big_sphere, false, kBronze), {0, 1.9f, 0}, yaw(30));
    root("pedestal_centre", single("pedestal", pedestal, false, kPedestal));
    const Accessors small_acc = w.add(small_sphere, false);
    const int gold = static_cast<int>(w.mesh("sphere_gold", {{small_acc, kGold}}));
    const int marble = static_cast<int>(w.mesh("sphere_marble", {{small_acc, kSphereMarble}}));
    const int pl = single("pedestal_small", plinth, false, kPedestal);
    int k = 0;
    for (const float x : {-7.0f, 7.0f}) {
      for (const float z : {-2.2f, 2.2f}) {
        const std::string n = std::to_string(k);
        root("sphere_" + n, (k % 2) ? marble : gold, {x, 1.2f, z}, yaw(45.0f * static_cast<float>(k)));
        root("pedestal_" + n, pl, {x, 0, z});
        ++k;
      }
    }
  }
}

bool write_file(const fs::path& path, const void* data, std::size_t bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (out) out.write(static_cast<const char*>(data), static_cast<std::streamsize>(bytes));
  out.close();
  if (!out) {
    std::fprintf(stderr, "make_gltf_standin: cannot write %s\n", path.c_str());
    return false;
  }
  return true;
}

int usage(const char* argv0) {
  std::fprintf(stderr,
               "usage: %s OUT_DIR [--small]\n"
               "writes OUT_DIR/standin.gltf, standin.bin and textures/: a Sponza-sized courtyard (about 262k triangles,\n"
               "25 materials, 70 textures of 1024 and 2048 pixels); --small: 64-pixel textures, about 1/14 of the triangles\n",
               argv0);
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  fs::path out;
  bool small = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--small") {
      small = true;
    } else if (a == "-h" || a == "--help") {
      usage(argv[0]);
      return 0;
    } else if (!a.empty() && a[0] == '-') {
      std::fprintf(stderr, "make_gltf_standin: unknown option %s\n", a.c_str());
      return usage(argv[0]);
    } else if (out.empty()) {
      out = a;
    } else {
      return usage(argv[0]);
    }
  }
  if (out.empty()) return usage(argv[0]);

  const auto start = std::chrono::steady_clock::now();
  std::error_code ec;
  fs::create_directories(out / "textures", ec);
  if (ec) {
    std::fprintf(stderr, "make_gltf_standin: cannot create %s: %s\n", (out / "textures").c_str(), ec.message().c_str());
    return 1;
  }

  // Textures: per material base colour, normal map and (for 20 of them) metallic-roughness.
  std::array<TextureFiles, kMaterialCount> files;
  for (std::uint32_t m = 0; m < kMaterialCount; ++m) {
    if (!write_textures(out, m, small, files[m])) return 1;
  }

  Writer w;  // its document's arrays are made below, in the order they are written
  json& doc = w.doc;
  doc["asset"] = {{"version", "2.0"}, {"generator", "fovea bench/make_gltf_standin"},
                  {"copyright", "Procedurally generated (Apache-2.0): a stand-in for Crytek Sponza"}};
  doc["extensionsUsed"] = json::array({"KHR_lights_punctual"});
  doc["scene"] = 0;
  for (const char* k : {"bufferViews", "accessors", "meshes", "nodes"}) doc[k] = json::array();

  // Samplers: 0 repeat (tiling), 1 clamp (leaves and banners: one image over the surface).
  doc["samplers"] = {{{"magFilter", 9729}, {"minFilter", 9987}, {"wrapS", 10497}, {"wrapT", 10497}},
                     {{"magFilter", 9729}, {"minFilter", 9987}, {"wrapS", 33071}, {"wrapT", 33071}}};
  doc["images"] = json::array();
  doc["textures"] = json::array();
  doc["materials"] = json::array();
  int texture_count = 0;
  std::map<int, int, std::greater<>> sizes;  // texture size -> how many
  const auto add_texture = [&](const std::string& uri, int sampler, int size) {
    const bool png = uri.size() > 4 && uri.compare(uri.size() - 4, 4, ".png") == 0;
    const std::string name = fs::path(uri).stem().string();
    doc["images"].push_back({{"name", name}, {"uri", uri}, {"mimeType", png ? "image/png" : "image/jpeg"}});
    doc["textures"].push_back({{"name", name}, {"sampler", sampler}, {"source", texture_count}});
    ++sizes[size];
    return texture_count++;
  };
  for (std::uint32_t m = 0; m < kMaterialCount; ++m) {
    const MaterialSpec& s = kMaterials[m];
    const int sampler = (m == kLeaves || m == kBanner) ? 1 : 0;
    json pbr = {{"baseColorTexture", {{"index", add_texture(files[m].base, sampler, files[m].base_size)}}}};
    pbr["baseColorFactor"] = {1.0, 1.0, 1.0, 1.0};
    json mat = {{"name", s.name}};
    const int normal = add_texture(files[m].normal, sampler, files[m].normal_size);
    if (s.mr) {
      const int mr = add_texture(files[m].mr, sampler, files[m].mr_size);
      pbr["metallicFactor"] = 1.0;
      pbr["roughnessFactor"] = 1.0;
      pbr["metallicRoughnessTexture"] = {{"index", mr}};
      mat["pbrMetallicRoughness"] = pbr;
      mat["normalTexture"] = {{"index", normal}, {"scale", 1.0}};
      mat["occlusionTexture"] = {{"index", mr}, {"strength", 1.0}};
    } else {
      pbr["metallicFactor"] = Writer::tidy(s.metallic);
      pbr["roughnessFactor"] = Writer::tidy(s.roughness);
      mat["pbrMetallicRoughness"] = pbr;
      mat["normalTexture"] = {{"index", normal}, {"scale", 1.0}};
    }
    if (s.mask) {
      mat["alphaMode"] = "MASK";
      mat["alphaCutoff"] = 0.5;
    }
    if (s.double_sided) mat["doubleSided"] = true;
    doc["materials"].push_back(mat);
  }

  std::vector<std::uint32_t> roots;
  build_scene(w, small ? 1 : 4, roots);

  // The camera, in the courtyard's west end looking east down the long axis, a little up.
  doc["cameras"] = json::array({{{"name", "view"}, {"type", "perspective"},
                     {"perspective", {{"yfov", 1.0}, {"znear", 0.1}, {"zfar", 100.0}, {"aspectRatio", 16.0 / 9.0}}}}});
  const std::uint32_t cam = w.node("view", -1, {-11.5f, 1.7f, 0.0f},
                                   glm::quatLookAtRH(glm::normalize(glm::vec3(1.0f, 0.09f, 0.0f)), glm::vec3(0, 1, 0)));
  doc["nodes"][cam]["camera"] = 0;
  roots.push_back(cam);

  // Lights (candela): two warm points over the courtyard, a spot on the central sphere.
  doc["extensions"]["KHR_lights_punctual"]["lights"] = {
      {{"name", "courtyard_west"}, {"type", "point"}, {"color", {1.0, 0.9, 0.76}}, {"intensity", 300.0}},
      {{"name", "courtyard_east"}, {"type", "point"}, {"color", {1.0, 0.9, 0.76}}, {"intensity", 300.0}},
      {{"name", "sphere_spot"}, {"type", "spot"}, {"color", {0.85, 0.9, 1.0}}, {"intensity", 600.0},
       {"spot", {{"innerConeAngle", 0.2}, {"outerConeAngle", 0.45}}}},
  };
  const glm::vec3 spot_at(-5.0f, 9.5f, 0.0f), target(0.0f, 1.9f, 0.0f);
  const std::array<std::pair<const char*, glm::vec3>, 2> points = {{{"light_west", {-6.5f, 8.0f, 0.0f}}, {"light_east", {6.5f, 8.0f, 0.0f}}}};
  for (std::size_t i = 0; i < points.size(); ++i) {
    const std::uint32_t l = w.node(points[i].first, -1, points[i].second);
    doc["nodes"][l]["extensions"]["KHR_lights_punctual"]["light"] = i;
    roots.push_back(l);
  }
  const std::uint32_t spot = w.node("light_spot", -1, spot_at, glm::quatLookAtRH(glm::normalize(target - spot_at), glm::vec3(0, 1, 0)));
  doc["nodes"][spot]["extensions"]["KHR_lights_punctual"]["light"] = 2;
  roots.push_back(spot);

  doc["scenes"] = json::array({{{"name", "courtyard"}, {"nodes", roots}}});
  doc["buffers"] = json::array({{{"uri", "standin.bin"}, {"byteLength", w.bin.size()}}});

  if (!write_file(out / "standin.bin", w.bin.data(), w.bin.size())) return 1;
  const std::string text = doc.dump(1) + "\n";
  if (!write_file(out / "standin.gltf", text.data(), text.size())) return 1;

  std::size_t mesh_nodes = 0;
  for (const auto& n : doc["nodes"]) mesh_nodes += n.contains("mesh") ? 1u : 0u;
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::string size_list;
  for (const auto& [size, count] : sizes) {
    size_list += (size_list.empty() ? "" : ", ") + std::to_string(count) + " at " + std::to_string(size) + " px";
  }
  std::printf("%s: %zu triangles as rendered (%zu stored), %zu nodes (%zu with a mesh), %zu meshes, %zu materials, "
              "%d textures (%s), %zu bytes of buffer; %.1f s\n",
              (out / "standin.gltf").c_str(), w.instanced_triangles, w.unique_triangles, doc["nodes"].size(), mesh_nodes,
              doc["meshes"].size(), doc["materials"].size(), texture_count, size_list.c_str(), w.bin.size(), seconds);
  return 0;
}
