// SPDX-License-Identifier: Apache-2.0
#include "passes/overlay.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>

namespace fovea::render {

namespace {
void ring(Image8& img, double cx, double cy, double radius, double thickness, glm::vec3 colour) {
  const double r_out = radius + thickness / 2, r_in = std::max(0.0, radius - thickness / 2);
  const int x0 = std::max(0, static_cast<int>(std::floor(cx - r_out)));
  const int x1 = std::min(static_cast<int>(img.width) - 1, static_cast<int>(std::ceil(cx + r_out)));
  const int y0 = std::max(0, static_cast<int>(std::floor(cy - r_out)));
  const int y1 = std::min(static_cast<int>(img.height) - 1, static_cast<int>(std::ceil(cy + r_out)));
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      const double d = std::hypot(x + 0.5 - cx, y + 0.5 - cy);
      if (d <= r_out && d >= r_in) img.set(static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y), colour);
    }
  }
}

glm::vec3 id_colour(std::uint32_t id) {
  if (id == 0) return glm::vec3(0.0f);
  std::uint32_t h = id * 2654435761u;  // Knuth's multiplicative hash: neighbours get distinct hues
  return {0.3f + 0.7f * static_cast<float>(h & 0xFF) / 255.0f, 0.3f + 0.7f * static_cast<float>((h >> 8) & 0xFF) / 255.0f,
          0.3f + 0.7f * static_cast<float>((h >> 16) & 0xFF) / 255.0f};
}
}  // namespace

void draw_gaze(Image8& image, const protocol::DisplayGeometry& display, const GazeMark& gaze, double area_deg) {
  const double cx = gaze.x * image.width, cy = gaze.y * image.height;
  const double one_deg = std::max(3.0, degrees_to_pixels(display, image.width, 1.0));
  const glm::vec3 colour = gaze.valid ? glm::vec3(1.0f, 0.15f, 0.1f) : glm::vec3(0.6f);
  ring(image, cx, cy, one_deg / 2, 2.0, colour);
  if (area_deg > 0) ring(image, cx, cy, degrees_to_pixels(display, image.width, area_deg) / 2, 1.0, colour * 0.8f);
}

void draw_focus(Image8& image, const GBuffer& g, std::uint32_t focused_object, double focal_depth_m,
                bool in_transition, const std::string& /*label: no text drawing yet*/) {
  const std::size_t n = g.size();
  if (image.width == 0 || image.height == 0 || n == 0 || g.object_id.size() < n || g.depth.size() < n) return;
  const glm::vec3 colour = in_transition ? glm::vec3(0.2f, 0.85f, 1.0f) : glm::vec3(1.0f, 0.85f, 0.1f);
  // The G-buffer pixel behind image pixel (x, y); -1 outside the image.
  const auto at = [&](long x, long y) -> long {
    if (x < 0 || y < 0 || x >= static_cast<long>(image.width) || y >= static_cast<long>(image.height)) return -1;
    const auto gx = static_cast<std::uint32_t>(static_cast<std::uint64_t>(x) * g.width / image.width);
    const auto gy = static_cast<std::uint32_t>(static_cast<std::uint64_t>(y) * g.height / image.height);
    return static_cast<long>(g.index(gx, gy));
  };
  bool object_seen = false;
  if (focused_object != 0) {
    // Outline, 2 px wide so that it reads at a glance: the object's pixels with a pixel that is not
    // the object (or the image edge) within 2 px along a row or column.
    const auto is_object = [&](long i) { return i >= 0 && g.object_id[static_cast<std::size_t>(i)] == focused_object; };
    for (long y = 0; y < static_cast<long>(image.height); ++y) {
      for (long x = 0; x < static_cast<long>(image.width); ++x) {
        if (!is_object(at(x, y))) continue;
        object_seen = true;
        bool edge = false;
        for (long d = 1; d <= 2 && !edge; ++d) {
          edge = !is_object(at(x - d, y)) || !is_object(at(x + d, y)) || !is_object(at(x, y - d)) ||
                 !is_object(at(x, y + d));
        }
        if (edge) image.set(static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y), colour);
      }
    }
  }
  if (object_seen || !std::isfinite(focal_depth_m)) return;
  // No object: the iso-depth line, where the depth of hit pixels crosses the focal depth between
  // neighbours, and the pixels at the focal depth (within kIsoDepthTolerance of it: a surface lying
  // along the contour, as a floor row seen level at the focal depth, would otherwise be dotted by
  // the depth's last bit, differently by each G-buffer pass). NaN and Inf depths are skipped.
  const auto side = [&](long i) -> int {
    if (i < 0) return 0;
    const auto k = static_cast<std::size_t>(i);
    const double d = static_cast<double>(g.depth[k]);
    if (g.object_id[k] == 0 || !std::isfinite(d)) return 0;
    if (std::abs(d - focal_depth_m) <= kIsoDepthTolerance * focal_depth_m) return 2;
    return d < focal_depth_m ? -1 : 1;
  };
  const auto across = [](int here, int there) { return (there == -1 || there == 1) && there != here; };
  for (long y = 0; y < static_cast<long>(image.height); ++y) {
    for (long x = 0; x < static_cast<long>(image.width); ++x) {
      const int here = side(at(x, y));
      if (here == 0) continue;
      const int right = side(at(x + 1, y)), below = side(at(x, y + 1));
      if (here == 2 || across(here, right) || across(here, below)) {
        image.set(static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y), colour);
      }
    }
  }
}

bool draw_gbuffer_map(Image8& img, const GBuffer& g, const std::string& map, float far_m) {
  if (map != "depth" && map != "id" && map != "normal" && map != "motion") return false;
  img.resize(g.width, g.height);
  float max_depth = 0;
  for (std::size_t i = 0; i < g.size(); ++i) {
    if (g.object_id[i] != 0) max_depth = std::max(max_depth, g.depth[i]);
  }
  if (max_depth <= 0) max_depth = far_m;
  for (std::uint32_t y = 0; y < g.height; ++y) {
    for (std::uint32_t x = 0; x < g.width; ++x) {
      const std::size_t i = g.index(x, y);
      glm::vec3 c(0.0f);
      if (map == "depth") {
        c = glm::vec3(g.object_id[i] == 0 ? 0.0f : 1.0f - g.depth[i] / max_depth);  // near is bright
      } else if (map == "id") {
        c = id_colour(g.object_id[i]);
      } else if (map == "normal") {
        c = g.object_id[i] == 0 ? glm::vec3(0.0f) : g.normal[i] * 0.5f + 0.5f;
      } else {
        c = glm::vec3(0.5f + g.motion[i].x / 20.0f, 0.5f + g.motion[i].y / 20.0f, 0.5f);  // 10 px = full scale
      }
      img.set(x, y, c);
    }
  }
  return true;
}

namespace {
// Black -> blue -> red -> yellow -> white, piecewise linear in v in [0, 1] (NaN reads as 0).
glm::vec3 heat(float v) {
  if (!(v > 0)) return glm::vec3(0.0f);
  v = std::min(v, 1.0f);
  static const glm::vec3 stops[] = {{0.0f, 0.0f, 0.0f}, {0.1f, 0.1f, 0.75f}, {0.85f, 0.1f, 0.1f}, {1.0f, 0.85f, 0.1f},
                                    {1.0f, 1.0f, 1.0f}};
  const float s = v * 4.0f;
  const int i = std::min(3, static_cast<int>(s));
  return glm::mix(stops[i], stops[i + 1], s - static_cast<float>(i));
}
}  // namespace

void draw_coc_map(Image8& img, const GBuffer& g, const dof::CocModel& coc) {
  if (img.width == 0 || img.height == 0) return;
  if (g.width == 0 || g.height == 0 || g.depth.size() < std::size_t{g.width} * g.height) {
    img.resize(img.width, img.height);
    return;
  }
  double max_c = 1;
  for (const float d : g.depth) max_c = std::max(max_c, coc.coc_px(static_cast<double>(d)));
  for (std::uint32_t y = 0; y < img.height; ++y) {
    const auto gy = std::min<std::uint32_t>(g.height - 1, static_cast<std::uint32_t>((y + 0.5) * g.height / img.height));
    for (std::uint32_t x = 0; x < img.width; ++x) {
      const auto gx = std::min<std::uint32_t>(g.width - 1, static_cast<std::uint32_t>((x + 0.5) * g.width / img.width));
      const double b = coc.signed_coc_px(static_cast<double>(g.depth[g.index(gx, gy)]));
      glm::vec3 c = heat(static_cast<float>(std::fabs(b) / max_c));
      if (b < 0) c.b = std::min(1.0f, c.b + 0.3f);
      img.set(x, y, c);
    }
  }
}

bool draw_attention_map(Image8& img, const attention::AttentionFrame& f, const std::string& map) {
  if (!attention::is_map(map)) return false;
  const std::size_t n = static_cast<std::size_t>(std::max(0, f.map_width)) * static_cast<std::size_t>(std::max(0, f.map_height));
  if (img.width == 0 || img.height == 0) return true;
  if (n == 0 || f.saliency.size() < n || f.ids.size() < n) {
    img.resize(img.width, img.height);  // no map (yet): black
    return true;
  }
  const auto mw = static_cast<double>(f.map_width), mh = static_cast<double>(f.map_height);
  if (map == "saliency") {
    const auto at = [&](int x, int y) {
      x = std::clamp(x, 0, f.map_width - 1);
      y = std::clamp(y, 0, f.map_height - 1);
      return f.saliency[static_cast<std::size_t>(y) * static_cast<std::size_t>(f.map_width) + static_cast<std::size_t>(x)];
    };
    for (std::uint32_t y = 0; y < img.height; ++y) {
      const double sy = (y + 0.5) * mh / img.height - 0.5;
      const int y0 = static_cast<int>(std::floor(sy));
      const auto fy = static_cast<float>(sy - y0);
      for (std::uint32_t x = 0; x < img.width; ++x) {
        const double sx = (x + 0.5) * mw / img.width - 0.5;
        const int x0 = static_cast<int>(std::floor(sx));
        const auto fx = static_cast<float>(sx - x0);
        const float top = at(x0, y0) + fx * (at(x0 + 1, y0) - at(x0, y0));
        const float bottom = at(x0, y0 + 1) + fx * (at(x0 + 1, y0 + 1) - at(x0, y0 + 1));
        img.set(x, y, heat(top + fy * (bottom - top)));
      }
    }
    return true;
  }
  double scale = 0.5;  // T_s and T_t lie in [0, 0.5]
  if (map == "attention") {
    scale = 0;
    for (const auto& o : f.objects) scale = std::max(scale, o.attention);
  }
  std::map<std::uint32_t, float> value;
  for (const auto& o : f.objects) {
    const double v = map == "spatial" ? o.spatial : map == "temporal" ? o.temporal : o.attention;
    value[o.id] = scale > 0 ? static_cast<float>(v / scale) : 0.0f;
  }
  for (std::uint32_t y = 0; y < img.height; ++y) {
    const auto my = std::min(static_cast<std::size_t>((y + 0.5) * mh / img.height), static_cast<std::size_t>(f.map_height - 1));
    for (std::uint32_t x = 0; x < img.width; ++x) {
      const auto mx = std::min(static_cast<std::size_t>((x + 0.5) * mw / img.width), static_cast<std::size_t>(f.map_width - 1));
      const auto it = value.find(f.ids[my * static_cast<std::size_t>(f.map_width) + mx]);
      // Listed objects at 0 show dark blue-grey, so they stand apart from the unlisted black.
      img.set(x, y, it == value.end() ? glm::vec3(0.0f) : glm::max(heat(it->second), glm::vec3(0.12f, 0.12f, 0.18f)));
    }
  }
  return true;
}

void draw_attention_mark(Image8& img, const attention::AttentionFrame& f) {
  if (f.most_attended == 0 || f.objects.empty() || img.width == 0 || img.height == 0) return;
  const attention::ObjectAttention& o = f.objects.front();
  if (!std::isfinite(o.screen_x) || !std::isfinite(o.screen_y)) return;
  const long cx = std::lround(std::clamp(o.screen_x, 0.0, 1.0) * img.width);
  const long cy = std::lround(std::clamp(o.screen_y, 0.0, 1.0) * img.height);
  const long half = std::max(3L, static_cast<long>(img.width) / 160);
  for (long y = cy - half - 1; y <= cy + half + 1; ++y) {
    for (long x = cx - half - 1; x <= cx + half + 1; ++x) {
      if (x < 0 || y < 0 || x >= static_cast<long>(img.width) || y >= static_cast<long>(img.height)) continue;
      const bool rim = std::labs(x - cx) == half + 1 || std::labs(y - cy) == half + 1;
      img.set(static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y), rim ? glm::vec3(0.0f) : glm::vec3(1.0f));
    }
  }
}

}  // namespace fovea::render
