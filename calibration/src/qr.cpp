// SPDX-License-Identifier: Apache-2.0
#include "fovea/calib/least_squares.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>

namespace fovea::calib {

namespace {

// ||A(from:, c)||_2 without overflow or underflow: scaled by the largest magnitude first.
double column_norm(const Matrix& a, std::size_t c, std::size_t from) {
  double big = 0;
  for (std::size_t i = from; i < a.rows(); ++i) big = std::max(big, std::abs(a(i, c)));
  if (big == 0) return 0;
  double sum = 0;
  for (std::size_t i = from; i < a.rows(); ++i) {
    const double s = a(i, c) / big;
    sum += s * s;
  }
  return big * std::sqrt(sum);
}

void swap_columns(Matrix& a, std::size_t p, std::size_t q) {
  if (p == q) return;
  for (std::size_t i = 0; i < a.rows(); ++i) std::swap(a(i, p), a(i, q));
}

// Applies H = I - 2 v v^T / (v^T v) to rows k.. of columns [c0, cols) of `m` (v[0] belongs to row k).
void reflect(const std::vector<double>& v, double v_norm2, std::size_t k, Matrix& m, std::size_t c0) {
  for (std::size_t c = c0; c < m.cols(); ++c) {
    double dot = 0;
    for (std::size_t i = k; i < m.rows(); ++i) dot += v[i - k] * m(i, c);
    const double f = 2.0 * dot / v_norm2;
    if (f == 0) continue;
    for (std::size_t i = k; i < m.rows(); ++i) m(i, c) -= f * v[i - k];
  }
}

}  // namespace

std::vector<double> singular_values(Matrix a) {
  if (a.rows() < a.cols()) throw std::invalid_argument("singular_values: needs rows >= cols");
  const std::size_t n = a.cols();
  constexpr double eps = std::numeric_limits<double>::epsilon();
  // One-sided Jacobi (Hestenes): rotate column pairs until all are mutually orthogonal; the column
  // norms are then the singular values.
  for (int sweep = 0; sweep < 80; ++sweep) {
    bool rotated = false;
    for (std::size_t p = 0; p + 1 < n; ++p) {
      for (std::size_t q = p + 1; q < n; ++q) {
        double alpha = 0, beta = 0, gamma = 0;
        for (std::size_t i = 0; i < a.rows(); ++i) {
          alpha += a(i, p) * a(i, p);
          beta += a(i, q) * a(i, q);
          gamma += a(i, p) * a(i, q);
        }
        if (gamma == 0 || std::abs(gamma) <= eps * std::sqrt(alpha * beta)) continue;
        rotated = true;
        const double zeta = (beta - alpha) / (2.0 * gamma);
        const double t = std::copysign(1.0, zeta) / (std::abs(zeta) + std::sqrt(1.0 + zeta * zeta));
        const double c = 1.0 / std::sqrt(1.0 + t * t);
        const double s = c * t;
        for (std::size_t i = 0; i < a.rows(); ++i) {
          const double ap = a(i, p), aq = a(i, q);
          a(i, p) = c * ap - s * aq;
          a(i, q) = s * ap + c * aq;
        }
      }
    }
    if (!rotated) break;
  }
  std::vector<double> sv(n);
  for (std::size_t c = 0; c < n; ++c) sv[c] = column_norm(a, c, 0);
  std::sort(sv.begin(), sv.end(), std::greater<>());
  return sv;
}

LeastSquaresSolution solve_least_squares(Matrix a, Matrix b, double rank_tolerance) {
  const std::size_t m = a.rows(), n = a.cols();
  if (n == 0 || m < n) {
    throw std::invalid_argument("solve_least_squares: A is " + std::to_string(m) + "x" + std::to_string(n) +
                                "; needs at least as many rows as columns, and a column");
  }
  if (b.rows() != m) {
    throw std::invalid_argument("solve_least_squares: B has " + std::to_string(b.rows()) + " rows, A has " +
                                std::to_string(m));
  }
  std::vector<std::size_t> perm(n);
  std::iota(perm.begin(), perm.end(), std::size_t{0});
  std::vector<double> r_diag(n, 0.0);
  std::vector<double> v(m);

  for (std::size_t k = 0; k < n; ++k) {
    // Pivot: the remaining column with the largest norm below row k (recomputed, not downdated:
    // the columns are few and recomputing avoids the cancellation of norm downdating).
    std::size_t p = k;
    double best = -1;
    for (std::size_t j = k; j < n; ++j) {
      const double nj = column_norm(a, j, k);
      if (nj > best) {
        best = nj;
        p = j;
      }
    }
    swap_columns(a, k, p);
    std::swap(perm[k], perm[p]);
    const double alpha = best;
    if (alpha == 0) break;  // the rest of A is zero: r_diag stays 0 from here
    // Householder vector v = x - beta e1 with beta = -sign(x0) ||x|| (no cancellation in v0).
    const double beta = a(k, k) >= 0 ? -alpha : alpha;
    double v_norm2 = 0;
    for (std::size_t i = k; i < m; ++i) {
      v[i - k] = a(i, k);
      if (i == k) v[0] -= beta;
      v_norm2 += v[i - k] * v[i - k];
    }
    if (v_norm2 > 0) {
      reflect(v, v_norm2, k, a, k + 1);
      reflect(v, v_norm2, k, b, 0);
    }
    a(k, k) = beta;
    for (std::size_t i = k + 1; i < m; ++i) a(i, k) = 0;
    r_diag[k] = beta;
  }

  LeastSquaresSolution out;
  const double r0 = std::abs(r_diag[0]);
  out.rank = 0;
  while (out.rank < n && r0 > 0 && std::abs(r_diag[out.rank]) > rank_tolerance * r0) ++out.rank;
  out.full_rank = out.rank == n;
  const double r_last = std::abs(r_diag[n - 1]);
  out.r_diagonal_ratio = r_last > 0 ? r0 / r_last : std::numeric_limits<double>::infinity();

  Matrix r(n, n);
  for (std::size_t c = 0; c < n; ++c)
    for (std::size_t i = 0; i <= c; ++i) r(i, c) = a(i, c);
  const std::vector<double> sv = singular_values(r);
  out.condition = sv.back() > 0 ? sv.front() / sv.back() : std::numeric_limits<double>::infinity();

  out.x = Matrix(n, b.cols());
  if (!out.full_rank) return out;
  // Back substitution R z = (Q^T B)(0:n), then undo the column permutation: x[perm[j]] = z[j].
  std::vector<double> z(n);
  for (std::size_t c = 0; c < b.cols(); ++c) {
    for (std::size_t jj = n; jj-- > 0;) {
      double s = b(jj, c);
      for (std::size_t l = jj + 1; l < n; ++l) s -= a(jj, l) * z[l];
      z[jj] = s / a(jj, jj);
    }
    for (std::size_t j = 0; j < n; ++j) out.x(perm[j], c) = z[j];
  }
  return out;
}

}  // namespace fovea::calib
