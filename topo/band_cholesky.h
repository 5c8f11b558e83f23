#pragma once
// Cholesky factorisation of a symmetric positive definite band matrix, through LAPACK's band routines (dpbtrf /
// dpbtrs). The spline fit's normal matrix (topo/bspline_surface.h) couples coefficients at most 3 grid rows apart:
// in grid order it is a band of half-width ~3 rows. Eigen's SimplicialLDLT factorised it column by column as a
// general sparse matrix (65 % of a spline reconstruction, measured 2026-12-02); LAPACK's blocked band algorithm
// does the same arithmetic in dense blocks (docs/reconstruction.md, "The spline's cost").
#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <vector>

namespace topocal::topo {

class BandCholesky {
 public:
  // Factorises the lower triangle of `m` (entries with row - column > half_bandwidth must be 0; the upper triangle
  // is not read). False when `m` is not positive definite (LAPACK's info > 0) or the input is malformed.
  bool Factorize(const Eigen::SparseMatrix<double>& m, int half_bandwidth);
  // M^-1 B, column by column; NaN when not factorised or B does not have rows() rows.
  Eigen::MatrixXd SolveColumns(const Eigen::MatrixXd& b) const;
  Eigen::VectorXd Solve(const Eigen::VectorXd& b) const;
  // log det M = 2 sum log L_ii.
  double LogDeterminant() const;
  int rows() const { return n_; }
  bool ok() const { return ok_; }

 private:
  int n_ = 0, kd_ = 0;
  bool ok_ = false;
  std::vector<double> band_;  // LAPACK lower band storage: band_[(i - j) + j * (kd_ + 1)] = M(i, j), then L(i, j)
};

}  // namespace topocal::topo
