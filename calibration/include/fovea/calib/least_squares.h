// SPDX-License-Identifier: Apache-2.0
#pragma once
// Dense linear least squares by Householder QR with column pivoting, hand-written for the small
// systems calibration fits (tens to thousands of rows, a handful of unknowns). Golub & Van Loan,
// Matrix Computations, 4th ed.: Householder vectors Alg. 5.1.1, QR with column pivoting Alg. 5.4.1,
// least squares via QR §5.3.3; condition from the singular values of R (one-sided Jacobi, §8.6.3).
#include <cstddef>
#include <vector>

namespace fovea::calib {

// Column-major rows x cols matrix of doubles.
class Matrix {
 public:
  Matrix() = default;
  Matrix(std::size_t rows, std::size_t cols) : rows_(rows), cols_(cols), data_(rows * cols, 0.0) {}
  std::size_t rows() const { return rows_; }
  std::size_t cols() const { return cols_; }
  double& operator()(std::size_t r, std::size_t c) { return data_[c * rows_ + r]; }
  double operator()(std::size_t r, std::size_t c) const { return data_[c * rows_ + r]; }

 private:
  std::size_t rows_ = 0, cols_ = 0;
  std::vector<double> data_;
};

struct LeastSquaresSolution {
  Matrix x;                  // cols(A) x cols(B): the minimiser of ||A x - B||_F, column by column
  std::size_t rank = 0;      // numerical rank of A (see solve_least_squares)
  bool full_rank = false;    // rank == cols(A); x is meaningful only then
  // 2-norm condition number of A, sigma_max / sigma_min, from the singular values of R (which
  // equal A's); +infinity when sigma_min is exactly 0.
  double condition = 0;
  // |R_00| / |R_{n-1,n-1}| of the pivoted QR: a cheap lower bound on `condition` (+infinity when
  // the last pivot is 0).
  double r_diagonal_ratio = 0;
};

// Minimises ||A x - B|| for each column of B. Requires rows(A) >= cols(A) >= 1 and rows(B) ==
// rows(A) (throws std::invalid_argument otherwise). A is rank deficient when a pivot |R_kk| falls
// to `rank_tolerance` * |R_00| or below; x is then zero and full_rank false (no exception: the
// caller says what the degeneracy means for its model). Entries must be finite.
LeastSquaresSolution solve_least_squares(Matrix a, Matrix b, double rank_tolerance = 1e-10);

// Singular values of a (rows >= cols), largest first, by one-sided Jacobi rotations.
std::vector<double> singular_values(Matrix a);

}  // namespace fovea::calib
