// SPDX-License-Identifier: Apache-2.0
#include "backend/backend.h"

#include <stdexcept>
#include <string>

#include "backend/embree/embree_backend.h"
#include "backend/gl/gl_backend.h"

namespace fovea::render {

std::unique_ptr<Backend> make_backend(BackendKind kind) {
  switch (kind) {
    case BackendKind::Embree: return make_embree_backend();
    case BackendKind::OpenGL: return make_gl_backend();  // EGL: throws std::runtime_error without one
  }
  throw std::invalid_argument("make_backend: unknown backend kind " + std::to_string(static_cast<int>(kind)));
}

}  // namespace fovea::render
