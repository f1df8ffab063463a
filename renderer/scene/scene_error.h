// SPDX-License-Identifier: Apache-2.0
#pragma once
// What loading a scene throws: the message names the file, the JSON path, the bad value and the
// allowed range, e.g. "scenes/room.json: $.objects[2].transform.translation[1] = nan: must be a
// finite number".
#include <stdexcept>

namespace fovea::render {

class SceneError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace fovea::render
