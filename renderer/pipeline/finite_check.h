// SPDX-License-Identifier: Apache-2.0
#pragma once
// fovea's second promise at the module boundary: no NaN or Inf leaves a pass. In debug builds (and
// in any build with --set debug.finite_checks=true) the frame pipeline scans every pass's output
// and stops the frame with a NonFiniteError that names the pass, the buffer and the first bad
// element. Outgoing datagrams are checked by the protocol's encoder, which refuses non-finite fields.
#include <cstddef>
#include <cstdint>
#include <glm/glm.hpp>
#include <span>
#include <stdexcept>
#include <string>

namespace fovea::render {

class NonFiniteError : public std::runtime_error {
 public:
  NonFiniteError(std::string pass, std::string buffer, std::size_t index, std::uint32_t width, double value);
  const std::string& pass() const { return pass_; }
  const std::string& buffer() const { return buffer_; }
  std::size_t index() const { return index_; }

 private:
  std::string pass_, buffer_;
  std::size_t index_;
};

// width: the image's width, to name the pixel as (x, y); 0 for a plain list (named by index).
void require_finite(const char* pass, const char* buffer, std::span<const float> values, std::uint32_t width = 0);
void require_finite(const char* pass, const char* buffer, std::span<const glm::vec2> values, std::uint32_t width = 0);
void require_finite(const char* pass, const char* buffer, std::span<const glm::vec3> values, std::uint32_t width = 0);
void require_finite(const char* pass, const char* buffer, std::span<const double> values, std::uint32_t width = 0);

// Whether the checks run by default: on in debug builds (NDEBUG undefined), off in release ones.
constexpr bool kFiniteChecksByDefault =
#ifdef NDEBUG
    false;
#else
    true;
#endif

}  // namespace fovea::render
