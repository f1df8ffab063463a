// SPDX-License-Identifier: Apache-2.0
#include "eye/led_layout.h"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace fovea::trackerd::eye {

LedLayout LedLayout::preset(int count) {
  LedLayout layout;
  switch (count) {
    case 0: break;
    case 1: layout.positions_mm = {{0.0, 10.0}}; break;
    case 2: layout.positions_mm = {{-10.0, 0.0}, {10.0, 0.0}}; break;
    case 3: layout.positions_mm = {{-10.0, 6.0}, {10.0, 6.0}, {0.0, -10.0}}; break;
    case 4: layout.positions_mm = {{-9.0, -9.0}, {9.0, -9.0}, {9.0, 9.0}, {-9.0, 9.0}}; break;
    case 5: layout.positions_mm = {{-9.0, -9.0}, {9.0, -9.0}, {9.0, 9.0}, {-9.0, 9.0}, {0.0, 14.0}}; break;
    default: throw std::invalid_argument("LED preset " + std::to_string(count) + ": allowed 0..5");
  }
  return layout;
}

LedLayout LedLayout::parse(const std::string& text) {
  if (text.size() == 1 && text[0] >= '0' && text[0] <= '9') return preset(text[0] - '0');
  LedLayout layout;
  std::stringstream all(text);
  std::string part;
  while (std::getline(all, part, ';')) {
    if (part.empty()) continue;
    const auto comma = part.find(',');
    if (comma == std::string::npos)
      throw std::invalid_argument("LED layout \"" + text + "\": \"" + part + "\" is not x,y in millimetres");
    try {
      std::size_t used_x = 0, used_y = 0;
      const std::string xs = part.substr(0, comma), ys = part.substr(comma + 1);
      const double x = std::stod(xs, &used_x), y = std::stod(ys, &used_y);
      if (used_x != xs.size() || used_y != ys.size() || !std::isfinite(x) || !std::isfinite(y) || std::abs(x) > 1000 ||
          std::abs(y) > 1000)
        throw std::invalid_argument("bad");
      layout.positions_mm.emplace_back(x, y);
    } catch (const std::exception&) {
      throw std::invalid_argument("LED layout \"" + text + "\": \"" + part +
                                  "\" is not x,y in millimetres (finite, |value| <= 1000)");
    }
  }
  if (layout.positions_mm.size() > 8)
    throw std::invalid_argument("LED layout \"" + text + "\": at most 8 LEDs");
  return layout;
}

std::string LedLayout::to_string() const {
  std::ostringstream out;
  for (std::size_t i = 0; i < positions_mm.size(); ++i)
    out << (i ? ";" : "") << positions_mm[i].x << "," << positions_mm[i].y;
  return out.str();
}

}  // namespace fovea::trackerd::eye
