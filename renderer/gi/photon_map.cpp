// SPDX-License-Identifier: Apache-2.0
#include "gi/photon_map.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <numbers>

namespace fovea::render::gi {

namespace {

constexpr float kPi = std::numbers::pi_v<float>;

bool finite3(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// Size of the left subtree of a complete (left-balanced) binary tree of n nodes: the full levels'
// share, (m / 2 - 1), plus the left half of the last level, min(m / 2, n - (m - 1)), with m the
// largest power of two <= n.
std::size_t left_subtree_size(std::size_t n) {
  if (n <= 1) return 0;
  const std::size_t m = std::bit_floor(n);
  const std::size_t half = m / 2;
  return (half - 1) + std::min(half, n - (m - 1));
}

}  // namespace

void PhotonMap::clear() {
  photons_ = {};
  nodes_.clear();
}

void PhotonMap::build_all(std::span<const Photon> photons) { build(photons, {}); }

void PhotonMap::build(std::span<const Photon> photons, std::span<const std::uint32_t> subset) {
  photons_ = photons;
  std::vector<Node> items;
  const auto add = [&](std::uint32_t i) {
    if (i >= photons.size() || !finite3(photons[i].position)) return;
    items.push_back({photons[i].position, i, 3});
  };
  if (subset.empty()) {
    items.reserve(photons.size());
    for (std::size_t i = 0; i < photons.size(); ++i) add(static_cast<std::uint32_t>(i));
  } else {
    items.reserve(subset.size());
    for (std::uint32_t i : subset) add(i);
  }
  nodes_.assign(items.size(), Node{glm::vec3(0.0f), 0, 3});
  if (!items.empty()) build_subtree(items, 0, items.size(), 0);
}

// Jensen's balancing: the median along the box's longest axis becomes the node, the lower half
// the left subtree, the upper half the right one, sized so the array is a complete binary tree.
void PhotonMap::build_subtree(std::vector<Node>& items, std::size_t begin, std::size_t end, std::size_t slot) {
  const std::size_t n = end - begin;
  if (n == 1) {
    nodes_[slot] = items[begin];
    nodes_[slot].axis = 3;
    return;
  }
  glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
  for (std::size_t i = begin; i < end; ++i) {
    lo = glm::min(lo, items[i].position);
    hi = glm::max(hi, items[i].position);
  }
  const glm::vec3 extent = hi - lo;
  const std::uint8_t axis = extent.x >= extent.y && extent.x >= extent.z ? 0 : (extent.y >= extent.z ? 1 : 2);
  const std::size_t median = begin + left_subtree_size(n);
  const auto first = items.begin() + static_cast<std::ptrdiff_t>(begin);
  std::nth_element(first, items.begin() + static_cast<std::ptrdiff_t>(median), items.begin() + static_cast<std::ptrdiff_t>(end),
                   [axis](const Node& a, const Node& b) { return a.position[axis] < b.position[axis]; });
  nodes_[slot] = items[median];
  nodes_[slot].axis = axis;
  if (median > begin) build_subtree(items, begin, median, 2 * slot + 1);
  if (median + 1 < end) build_subtree(items, median + 1, end, 2 * slot + 2);
}

namespace {

// Jensen's locate_photons with a bounded max-heap of (distance^2, photon): r^2 shrinks to the k-th
// nearest distance once k photons are held.
template <class Node, class Accept>
void locate(const std::vector<Node>& nodes, std::span<const Photon> photons, const glm::vec3& x, std::uint32_t k,
            Accept&& accept, std::vector<std::pair<float, std::uint32_t>>& heap, float& r2) {
  // Explicit stack of (node, squared distance to the splitting plane that separated it): a tree of
  // n nodes is ceil(log2(n + 1)) deep, so 64 entries hold any search.
  struct Entry {
    std::size_t slot;
    float plane2;
  };
  Entry stack[64];
  int top = 0;
  stack[top++] = {0, 0.0f};
  const std::size_t n = nodes.size();
  while (top > 0) {
    const Entry e = stack[--top];
    if (e.plane2 >= r2) continue;  // r^2 shrank since this side was pushed: nothing there can be nearer
    const Node& node = nodes[e.slot];
    const std::size_t left = 2 * e.slot + 1, right = left + 1;
    if (node.axis < 3) {
      const float delta = x[node.axis] - node.position[node.axis];
      const std::size_t near = delta < 0 ? left : right, far = delta < 0 ? right : left;
      // Far side first on the stack so the near side is searched first (r^2 shrinks sooner).
      if (far < n && delta * delta < r2) stack[top++] = {far, std::max(e.plane2, delta * delta)};
      if (near < n) stack[top++] = {near, e.plane2};
    }
    const glm::vec3 d = node.position - x;
    const float dist2 = glm::dot(d, d);
    if (dist2 < r2 && accept(photons[node.photon])) {
      if (heap.size() < k) {
        heap.emplace_back(dist2, node.photon);
        std::push_heap(heap.begin(), heap.end());
        if (heap.size() == k) r2 = heap.front().first;
      } else {
        std::pop_heap(heap.begin(), heap.end());
        heap.back() = {dist2, node.photon};
        std::push_heap(heap.begin(), heap.end());
        r2 = heap.front().first;
      }
    }
  }
}

}  // namespace

void PhotonMap::nearest(const glm::vec3& x, std::uint32_t k, float max_radius, Neighbours& out,
                        const std::function<bool(const Photon&)>& accept) const {
  out.clear();
  if (k == 0 || !(max_radius > 0) || nodes_.empty() || !finite3(x)) return;
  float r2 = std::isfinite(max_radius) ? max_radius * max_radius : std::numeric_limits<float>::max();
  std::vector<std::pair<float, std::uint32_t>> heap;
  heap.reserve(std::min<std::size_t>(k, nodes_.size()));
  if (accept) {
    locate(nodes_, photons_, x, k, accept, heap, r2);
  } else {
    locate(nodes_, photons_, x, k, [](const Photon&) { return true; }, heap, r2);
  }
  std::sort_heap(heap.begin(), heap.end());
  out.radius2 = r2;
  for (const auto& [d2, i] : heap) {
    out.index.push_back(i);
    out.distance2.push_back(d2);
  }
}

std::vector<std::uint32_t> PhotonMap::indexed() const {
  std::vector<std::uint32_t> out;
  out.reserve(nodes_.size());
  for (const Node& node : nodes_) out.push_back(node.photon);
  return out;
}

void PhotonMap::within(const glm::vec3& x, float radius, std::vector<std::uint32_t>& out) const {
  out.clear();
  if (!(radius > 0) || nodes_.empty() || !finite3(x)) return;
  const float r2 = std::isfinite(radius) ? radius * radius : std::numeric_limits<float>::max();
  std::size_t stack[64];
  int top = 0;
  stack[top++] = 0;
  const std::size_t n = nodes_.size();
  while (top > 0) {
    const std::size_t slot = stack[--top];
    const Node& node = nodes_[slot];
    const std::size_t left = 2 * slot + 1, right = left + 1;
    if (node.axis < 3) {
      const float delta = x[node.axis] - node.position[node.axis];
      if (left < n && (delta < 0 || delta * delta < r2)) stack[top++] = left;
      if (right < n && (delta >= 0 || delta * delta < r2)) stack[top++] = right;
    }
    const glm::vec3 d = node.position - x;
    if (glm::dot(d, d) < r2) out.push_back(node.photon);
  }
}

glm::vec3 PhotonMap::flux_density(const glm::vec3& x, const glm::vec3& n, const EstimateSettings& s,
                                  Neighbours& scratch, const std::function<glm::vec3(const Photon&)>& weight,
                                  std::vector<std::uint32_t>* used) const {
  if (used) used->clear();
  scratch.clear();
  if ((s.nearest == 0 && !s.fixed_radius) || !(s.max_radius > 0) || nodes_.empty() || !finite3(x) || !finite3(n))
    return glm::vec3(0.0f);
  float r2 = std::isfinite(s.max_radius) ? s.max_radius * s.max_radius : std::numeric_limits<float>::max();
  std::vector<std::pair<float, std::uint32_t>> heap;
  // Only photons that arrived at the front side of this surface (Jensen 2001, §7.2).
  const auto front = [&n](const Photon& p) { return glm::dot(p.incoming, n) < 0.0f; };
  if (s.fixed_radius) {
    if (!std::isfinite(s.max_radius)) return glm::vec3(0.0f);  // every photon of the scene: no disc to divide by
    within(x, s.max_radius, scratch.index);
    for (std::uint32_t i : scratch.index) {
      const glm::vec3 d = photons_[i].position - x;
      if (front(photons_[i])) heap.emplace_back(glm::dot(d, d), i);
    }
    scratch.index.clear();
  } else {
    heap.reserve(std::min<std::size_t>(s.nearest, nodes_.size()));
    locate(nodes_, photons_, x, s.nearest, front, heap, r2);
  }
  if (heap.empty() || !(r2 > 0) || !std::isfinite(r2)) return glm::vec3(0.0f);
  const float r = std::sqrt(r2);
  const float k = std::max(1.0f, std::isfinite(s.cone_k) ? s.cone_k : 1.0f);
  const bool cone = s.filter == EstimateFilter::Cone;
  glm::vec3 sum(0.0f);
  for (const auto& [d2, i] : heap) {
    const Photon& p = photons_[i];
    glm::vec3 power = p.power;
    if (weight) power *= weight(p);
    const float w = cone ? std::max(0.0f, 1.0f - std::sqrt(d2) / (k * r)) : 1.0f;  // Jensen 2001, eq. 7.7
    sum += w * power;
    if (used) used->push_back(i);
  }
  scratch.radius2 = r2;
  const float norm = cone ? 1.0f - 2.0f / (3.0f * k) : 1.0f;  // the cone filter's integral over the disc
  const glm::vec3 e = sum / (norm * kPi * r2);                 // Jensen & Pedersen eq. 6.6: dPhi / (pi r^2)
  return finite3(e) ? glm::max(e, glm::vec3(0.0f)) : glm::vec3(0.0f);
}

}  // namespace fovea::render::gi
