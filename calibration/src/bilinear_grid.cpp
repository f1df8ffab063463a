// SPDX-License-Identifier: Apache-2.0
#include "fovea/calib/bilinear_grid.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>

namespace fovea::calib {

namespace {

// Groups values into clusters separated by gaps above `tol`; returns the cluster means (increasing)
// and each value's cluster.
std::vector<double> cluster(const std::vector<double>& v, double tol, std::vector<std::size_t>& which) {
  std::vector<std::size_t> order(v.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return v[a] < v[b]; });
  which.assign(v.size(), 0);
  std::vector<double> sums;
  std::vector<std::size_t> counts;
  for (std::size_t k = 0; k < order.size(); ++k) {
    if (k == 0 || v[order[k]] - v[order[k - 1]] > tol) {
      sums.push_back(0);
      counts.push_back(0);
    }
    sums.back() += v[order[k]];
    ++counts.back();
    which[order[k]] = sums.size() - 1;
  }
  std::vector<double> means(sums.size());
  for (std::size_t c = 0; c < sums.size(); ++c) means[c] = sums[c] / static_cast<double>(counts[c]);
  return means;
}

std::string list(const std::vector<double>& v) {
  std::string s;
  for (std::size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + detail::format_number(v[i]);
  return s;
}

// Where v falls on the grid g: the cell g[i] <= v <= g[i+1] and the normalised distance t (alpha or
// beta of eq. 4.1) in it, clamped to [0, 1]; `outside` when v is beyond the outermost grid value.
struct Located {
  std::size_t i = 0;
  double t = 0;
  bool outside = false;
  std::size_t edge = 0;  // the outermost grid index v is beyond, when outside
};

Located locate(const std::vector<double>& g, double v) {
  Located l;
  if (v < g.front()) return {0, 0, true, 0};
  if (v > g.back()) return {g.size() - 2, 1, true, g.size() - 1};
  const auto it = std::upper_bound(g.begin(), g.end(), v);
  l.i = std::min(static_cast<std::size_t>(it - g.begin()), g.size() - 1) - 1;
  l.t = (v - g[l.i]) / (g[l.i + 1] - g[l.i]);  // eq. 4.1
  return l;
}

Point mix(Point a, Point b, double t) { return {(1 - t) * a.x + t * b.x, (1 - t) * a.y + t * b.y}; }

}  // namespace

BilinearGrid BilinearGrid::fit(std::span<const Correspondence> pts, double tolerance) {
  const std::string who = "BilinearGrid::fit";
  if (pts.size() < 4) {
    throw std::invalid_argument(who + ": " + std::to_string(pts.size()) +
                                " correspondence(s); a calibration-vector grid needs targets on at least a 2x2 grid");
  }
  detail::check_finite(pts, who);

  std::vector<double> tx, ty;
  for (const auto& c : pts) {
    tx.push_back(c.target.x);
    ty.push_back(c.target.y);
  }
  auto tol_for = [&](const std::vector<double>& v) {
    if (tolerance > 0) return tolerance;
    const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
    return 1e-3 * (*hi - *lo);
  };
  std::vector<std::size_t> ix, iy;
  BilinearGrid grid;
  grid.xs = cluster(tx, tol_for(tx), ix);
  grid.ys = cluster(ty, tol_for(ty), iy);
  if (grid.xs.size() < 2 || grid.ys.size() < 2) {
    throw std::invalid_argument(who + ": the targets have " + std::to_string(grid.xs.size()) + " distinct x value(s) (" +
                                list(grid.xs) + ") and " + std::to_string(grid.ys.size()) + " distinct y value(s) (" +
                                list(grid.ys) + "); a calibration-vector grid needs at least 2 of each");
  }
  const std::size_t nx = grid.xs.size(), ny = grid.ys.size();
  std::vector<Point> sum(nx * ny);
  std::vector<std::size_t> count(nx * ny, 0);
  for (std::size_t k = 0; k < pts.size(); ++k) {
    const std::size_t cell = iy[k] * nx + ix[k];
    sum[cell].x += pts[k].target.x - pts[k].raw.x;  // v_ij: true target - measured point
    sum[cell].y += pts[k].target.y - pts[k].raw.y;
    ++count[cell];
  }
  std::size_t missing = 0;
  std::string first_missing;
  for (std::size_t j = 0; j < ny; ++j) {
    for (std::size_t i = 0; i < nx; ++i) {
      if (count[j * nx + i] == 0 && missing++ == 0) {
        first_missing = "(" + detail::format_number(grid.xs[i]) + ", " + detail::format_number(grid.ys[j]) + ")";
      }
    }
  }
  if (missing > 0) {
    throw std::invalid_argument(who + ": the targets do not form a full " + std::to_string(nx) + "x" +
                                std::to_string(ny) + " grid (x: " + list(grid.xs) + "; y: " + list(grid.ys) +
                                "): no samples for target " + first_missing +
                                (missing > 1 ? " and " + std::to_string(missing - 1) + " more" : std::string()));
  }
  grid.vectors.resize(nx * ny);
  for (std::size_t c = 0; c < nx * ny; ++c) {
    const double nd = static_cast<double>(count[c]);
    grid.vectors[c] = {sum[c].x / nd, sum[c].y / nd};
  }
  grid.stats.points = pts.size();
  grid.stats.condition = std::numeric_limits<double>::quiet_NaN();
  detail::fill_residuals(grid, pts, grid.stats);
  return grid;
}

Point BilinearGrid::correction(Point p) const {
  if (!std::isfinite(p.x) || !std::isfinite(p.y)) {
    return {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN()};
  }
  const Located lx = locate(xs, p.x), ly = locate(ys, p.y);
  if (lx.outside && ly.outside) return vector_at(lx.edge, ly.edge);  // corner region: the single adjacent vector
  if (ly.outside) {
    // Above or below the grid: only alpha, along the nearest grid row.
    return mix(vector_at(lx.i, ly.edge), vector_at(lx.i + 1, ly.edge), lx.t);
  }
  if (lx.outside) {
    // Left or right of the grid: only beta, along the nearest grid column.
    return mix(vector_at(lx.edge, ly.i), vector_at(lx.edge, ly.i + 1), ly.t);
  }
  // Eq. 4.2: v_p = (1 - alpha) (v_11 (1 - beta) + v_12 beta) + alpha (v_21 (1 - beta) + v_22 beta),
  // with Q_11 = (x_1, y_1), Q_12 = (x_1, y_2), Q_21 = (x_2, y_1), Q_22 = (x_2, y_2).
  const double alpha = lx.t, beta = ly.t;
  const Point v11 = vector_at(lx.i, ly.i), v12 = vector_at(lx.i, ly.i + 1);
  const Point v21 = vector_at(lx.i + 1, ly.i), v22 = vector_at(lx.i + 1, ly.i + 1);
  return {(1 - alpha) * (v11.x * (1 - beta) + v12.x * beta) + alpha * (v21.x * (1 - beta) + v22.x * beta),
          (1 - alpha) * (v11.y * (1 - beta) + v12.y * beta) + alpha * (v21.y * (1 - beta) + v22.y * beta)};
}

}  // namespace fovea::calib
