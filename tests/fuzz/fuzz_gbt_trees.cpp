// SPDX-License-Identifier: Apache-2.0
// libFuzzer entry point for the gbt classifier's tree format (trackerd/classify/trees.h), which
// `fovea-ctl classify --model FILE` reads from a user's file: whatever the bytes, parse must either
// return an ensemble or throw std::invalid_argument naming the line, without undefined behaviour.
// An ensemble it returns is walked on rows that reach every kind of split (ordinary numbers, the
// largest floats, infinities, NaN both ways): every walk must end inside the nodes (ASan checks each
// load), name one of the model's classes and leave finite scores for finite leaf values.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "classify/trees.h"

namespace {

void check(bool ok) {
  if (!ok) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using fovea::trackerd::classify::TreeEnsemble;
  static const std::vector<std::string> kFeatures{"speed", "spread", "gap"};
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const TreeEnsemble m = TreeEnsemble::parse(text, "fuzz.trees", kFeatures);
    const std::size_t classes = m.class_names().size();
    check(classes >= 1 && m.tree_count() >= 1 && m.node_count() >= m.tree_count());
    constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
    constexpr float kInf = std::numeric_limits<float>::infinity();
    constexpr float kMax = std::numeric_limits<float>::max();
    const float rows[][3] = {{0, 0, 0},          {1, -1, 0.5f},         {kMax, -kMax, kMax},
                             {kInf, -kInf, kInf}, {kNaN, kNaN, kNaN},    {-0.0f, 1e-45f, -1e-45f},
                             {1e30f, kNaN, -1e30f}};
    std::vector<double> scores(classes);
    for (const auto& row : rows) {
      const int best = m.predict(row, scores.data());
      check(best >= 0 && static_cast<std::size_t>(best) < classes);
      // Leaf values and the baseline are finite numbers (parse refuses others), but many added
      // together may overflow to infinity: never to NaN unless +inf and -inf meet.
      for (const double s : scores) check(!std::isnan(s) || m.tree_count() > 1);
    }
  } catch (const std::invalid_argument&) {
    // A damaged or hostile model: refused with its file and line, the correct outcome.
  }
  return 0;
}
