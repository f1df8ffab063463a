#include "passes/overlay.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace fovea::render {

double degrees_to_pixels(const protocol::DisplayGeometry& d, std::uint32_t image_width, double degrees) {
  // Size on the screen of the angle at the viewing distance (eq. 2.1 solved for h), then screen
  // millimetres to image pixels (the image fills the screen's width).
  const double size_m = 2.0 * d.viewing_distance_m * std::tan(degrees * std::numbers::pi / 360.0);
  return size_m / d.width_m * image_width;
}

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

}  // namespace fovea::render
