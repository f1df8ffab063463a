// SPDX-License-Identifier: Apache-2.0
// Glints paired with the LED layout: the scale and translation that map the layout onto the most
// glints (with priors from earlier frames for ambiguous cases), and the reference point the
// pupil–glint vector is measured from (eye/EYE.md, step 9).
#include "eye/detector_stages.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <optional>
#include <vector>

namespace fovea::trackerd::eye::stages {

namespace {

// Pairs glints with the LED layout: the glints are a reduced, upright copy of the layout, so a
// scale and translation map LED positions to glint positions (rotation is not modelled).
// Two glints fit several LED pairs exactly (each at its own scale), so among hypotheses matching as
// many glints the one whose scale is nearest the scale seen in earlier frames wins: the glint
// pattern's size changes slowly (with the eye's distance), and without that prior the reference
// point can flip between LED assignments from frame to frame, moving the pupil–glint vector by a
// whole LED spacing.
struct Pairing {
  std::vector<int> led_of;  // per glint
  cv::Point2d reference;    // image of the layout's centroid
  bool valid = false;
  double scale = 0;
  int matches = 0;
};

// The search over placements (scale s, translation t) of the layout onto the glints; keeps the best so far.
struct LayoutSearch {
  const std::vector<Glint>& glints;
  const std::vector<cv::Point2d>& leds;
  cv::Point2d layout_centroid;
  double tolerance = 0;
  double last_scale = 0;
  Pairing best;
  int best_matches = 0;
  double best_cost = 1e300;

  // Each LED takes the nearest unused glint within the tolerance; more matches win, then the lower
  // cost (residual, `extra_cost`, and the scale's distance from the last one).
  void evaluate(double s, const cv::Point2d& t, double extra_cost) {
    const std::size_t m = leds.size(), g = glints.size();
    std::vector<int> led_of(g, -1);
    int matches = 0;
    double residual = 0;
    std::vector<char> used(g, 0);
    for (std::size_t l = 0; l < m; ++l) {
      const cv::Point2d predicted = s * leds[l] + t;
      double nearest = tolerance;
      int which = -1;
      for (std::size_t j = 0; j < g; ++j) {
        if (used[j]) continue;
        const double d = std::hypot(glints[j].centre.x - predicted.x, glints[j].centre.y - predicted.y);
        if (d < nearest) { nearest = d; which = static_cast<int>(j); }
      }
      if (which >= 0) {
        used[static_cast<std::size_t>(which)] = 1;
        led_of[static_cast<std::size_t>(which)] = static_cast<int>(l);
        ++matches;
        residual += nearest;
      }
    }
    // A scale 20 % off the last one costs as much as being 1.5 tolerances off per glint.
    const double cost =
        residual + extra_cost + (last_scale > 0 ? 8 * tolerance * std::abs(std::log(s / last_scale)) : 0.0);
    if (matches > best_matches || (matches == best_matches && cost < best_cost)) {
      best_matches = matches;
      best_cost = cost;
      best.led_of = led_of;
      best.scale = s;
      best.reference = s * layout_centroid + t;
    }
  }
};

// Every ordered glint pair taken as the image of every ordered LED pair fixes a scale and translation.
void place_by_glint_pairs(LayoutSearch& search) {
  const auto& leds = search.leds;
  const auto& glints = search.glints;
  const std::size_t m = leds.size(), g = glints.size();
  for (std::size_t a = 0; a < m; ++a)
    for (std::size_t b = 0; b < m; ++b) {
      if (a == b) continue;
      const cv::Point2d dl = leds[b] - leds[a];
      const double dl2 = dl.dot(dl);
      if (dl2 <= 0) continue;
      for (std::size_t i = 0; i < g; ++i)
        for (std::size_t j = 0; j < g; ++j) {
          if (i == j) continue;
          const cv::Point2d dg = glints[j].centre - glints[i].centre;
          const double s = dg.dot(dl) / dl2;
          if (!(s > 0)) continue;
          const double cross = std::abs(dg.x * dl.y - dg.y * dl.x) / std::sqrt(dl2);
          if (cross > 0.35 * std::hypot(dg.x, dg.y) + search.tolerance) continue;  // rotated by more than ~20 deg
          search.evaluate(s, glints[i].centre - s * leds[a], 0.0);
        }
    }
}

// One glint: place the layout by the scale seen in earlier frames, trying each LED for it; every
// choice fits that glint exactly, so the one keeping the reference nearest the last frame's wins.
void place_by_last_scale(LayoutSearch& search, const std::optional<cv::Point2d>& last_reference) {
  const double last_scale = search.last_scale;
  for (std::size_t a = 0; a < search.leds.size(); ++a)
    for (std::size_t i = 0; i < search.glints.size(); ++i) {
      const cv::Point2d t = search.glints[i].centre - last_scale * search.leds[a];
      const cv::Point2d reference = last_scale * search.layout_centroid + t;
      search.evaluate(last_scale, t,
                      last_reference ? std::hypot(reference.x - last_reference->x, reference.y - last_reference->y)
                                     : 0.0);
    }
}

Pairing pair_with_layout(const std::vector<Glint>& glints, const LedLayout& layout, double tolerance,
                         double last_scale, const std::optional<cv::Point2d>& last_reference) {
  LayoutSearch search{glints, layout.positions_mm, {}, tolerance, last_scale, {}};
  Pairing& best = search.best;
  best.led_of.assign(glints.size(), -1);
  const auto& leds = layout.positions_mm;
  const std::size_t m = leds.size(), g = glints.size();
  if (m == 0 || g == 0) return best;
  cv::Point2d layout_centroid;
  for (const auto& l : leds) layout_centroid += l;
  layout_centroid *= 1.0 / static_cast<double>(m);
  search.layout_centroid = layout_centroid;
  if (m >= 2) place_by_glint_pairs(search);
  if (search.best_matches < 2 && last_scale > 0) place_by_last_scale(search, last_reference);
  if (m == 1 && g >= 1) {
    best.led_of.assign(g, -1);
    best.led_of[0] = 0;  // the caller sorted glints nearest the pupil first
    best.reference = glints[0].centre - 0.0 * leds[0];
    best.valid = true;
    return best;
  }
  best.valid = search.best_matches >= 2 || (search.best_matches == 1 && last_scale > 0);
  best.matches = search.best_matches;
  return best;
}

}  // namespace

// With an LED layout: the image of the layout's centroid from the pairing (which also labels each
// glint with its LED and teaches the scale prior); without one: the glints' centroid.
GlintReference glint_reference(std::vector<Glint>& glints, const LedLayout& leds, double size, double& last_glint_scale,
                               std::optional<cv::Point2d>& last_reference) {
  GlintReference reference;
  if (!leds.positions_mm.empty() && !glints.empty()) {
    const double tolerance = std::max(1.5, 0.012 * size);
    const Pairing pairing = pair_with_layout(glints, leds, tolerance, last_glint_scale, last_reference);
    for (std::size_t i = 0; i < glints.size(); ++i) glints[i].led = pairing.led_of[i];
    if (pairing.valid) {
      reference.point = pairing.reference;
      reference.valid = true;
      last_reference = pairing.reference;
      // The scale prior learns from unambiguous pairings (three or more glints), or from two when
      // it has nothing yet or they agree with it.
      const bool learn = pairing.matches >= 3 ||
                         (pairing.matches == 2 && (last_glint_scale <= 0 ||
                                                   std::abs(std::log(pairing.scale / last_glint_scale)) < 0.2));
      if (pairing.scale > 0 && leds.positions_mm.size() >= 2 && learn) {
        last_glint_scale = last_glint_scale > 0 ? 0.8 * last_glint_scale + 0.2 * pairing.scale : pairing.scale;
      }
    }
  } else if (!glints.empty()) {
    for (const auto& g : glints) reference.point += g.centre;
    reference.point *= 1.0 / static_cast<double>(glints.size());
    reference.valid = true;
  }
  return reference;
}

}  // namespace fovea::trackerd::eye::stages
