// SPDX-License-Identifier: Apache-2.0
#include "scene/scene_overrides.h"

#include <algorithm>
#include <sstream>
#include <string>
#include <vector>

#include "scene/scene_schema.h"

namespace fovea::render {

using namespace json;
using namespace schema;

void apply_override(Json& doc, const SceneOverride& o, json::Reader& reader) {
  const std::string text = o.path + "=" + o.value;
  const auto bad = [&](const std::string& what) -> void {
    throw SceneError(reader.source() + ": override '" + text + "': " + what);
  };
  std::vector<std::string> segments;
  {
    std::string seg;
    std::istringstream in(o.path);
    while (std::getline(in, seg, '.')) segments.push_back(seg);
    if (!o.path.empty() && o.path.back() == '.') segments.emplace_back();
  }
  if (segments.empty()) bad("empty path; expected a dotted path such as camera.width or lights.0.power");
  for (const std::string& s : segments) {
    if (s.empty()) bad("empty path segment; expected a dotted path such as camera.width or lights.0.power");
  }

  Json value;
  try {
    value = Json::parse(o.value);
  } catch (const nlohmann::json::exception&) {
    value = Json(o.value);  // not JSON: taken as a string
  }

  Json* node = &doc;
  Kind kind = Kind::Scene;
  std::string path = "$";
  for (std::size_t i = 0; i < segments.size(); ++i) {
    const std::string& seg = segments[i];
    const bool last = i + 1 == segments.size();
    if (node->is_array()) {
      const bool numeric = std::all_of(seg.begin(), seg.end(), [](char c) { return c >= '0' && c <= '9'; });
      if (!numeric || seg.size() > 9) bad(path + " is an array; '" + seg + "' must be an element index");
      const auto index = static_cast<std::size_t>(std::stoul(seg));
      if (index >= node->size()) {
        bad(path + index_suffix(index) + ": index out of range (the array has " + std::to_string(node->size()) +
            " elements)");
      }
      node = &(*node)[index];
      path += index_suffix(index);
      kind = element_kind(kind);
    } else if (node->is_object()) {
      const Keys& known = keys_of(kind);
      if (!node->contains(seg)) {
        if (std::find(known.begin(), known.end(), seg) == known.end()) {
          std::string what = path + key_suffix(seg) + ": no such field in the scene";
          if (!known.empty()) what += "; " + unknown_field_message(seg, known);
          bad(what);
        }
        (*node)[seg] = last ? Json(nullptr) : Json::object();  // a known optional field: create it
      }
      node = &(*node)[seg];
      path += key_suffix(seg);
      kind = child_kind(kind, seg);
    } else {
      bad(path + " = " + describe(*node) + " is not an object or array; cannot set '" + seg + "' inside it");
    }
  }
  *node = std::move(value);
  reader.note_override(path, text);
}


}  // namespace fovea::render
