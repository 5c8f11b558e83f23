#include "topo/band_cholesky.h"

#include <algorithm>
#include <cmath>
#include <cstddef>

// LAPACK (Fortran): the hidden trailing argument is the length of the character argument (gfortran's convention).
extern "C" {
void dpbtrf_(const char* uplo, const int* n, const int* kd, double* ab, const int* ldab, int* info, std::size_t);
void dpbtrs_(const char* uplo, const int* n, const int* kd, const int* nrhs, const double* ab, const int* ldab,
             double* b, const int* ldb, int* info, std::size_t);
}

namespace topocal::topo {

bool BandCholesky::Factorize(const Eigen::SparseMatrix<double>& m, int half_bandwidth) {
  ok_ = false;
  if (m.rows() != m.cols() || half_bandwidth < 0 || !m.isCompressed()) return false;
  n_ = static_cast<int>(m.rows());
  kd_ = std::min(half_bandwidth, std::max(0, n_ - 1));
  const int ld = kd_ + 1;
  band_.assign(static_cast<std::size_t>(ld) * n_, 0.0);
  for (int j = 0; j < n_; ++j) {
    for (Eigen::SparseMatrix<double>::InnerIterator it(m, j); it; ++it) {
      const int d = static_cast<int>(it.row()) - j;
      if (d < 0) continue;
      if (d > kd_) return false;
      band_[static_cast<std::size_t>(d) + static_cast<std::size_t>(j) * ld] = it.value();
    }
  }
  int info = 0;
  if (n_ > 0) dpbtrf_("L", &n_, &kd_, band_.data(), &ld, &info, 1);
  ok_ = info == 0;
  return ok_;
}

Eigen::MatrixXd BandCholesky::SolveColumns(const Eigen::MatrixXd& b) const {
  Eigen::MatrixXd x = b;
  if (!ok_ || b.rows() != n_) return Eigen::MatrixXd::Constant(b.rows(), b.cols(), NAN);
  if (b.cols() == 0 || n_ == 0) return x;
  const int ld = kd_ + 1, nrhs = static_cast<int>(b.cols());
  int info = 0;
  dpbtrs_("L", &n_, &kd_, &nrhs, band_.data(), &ld, x.data(), &n_, &info, 1);
  return x;
}

Eigen::VectorXd BandCholesky::Solve(const Eigen::VectorXd& b) const {
  Eigen::VectorXd x = b;
  if (!ok_ || b.rows() != n_) return Eigen::VectorXd::Constant(b.rows(), NAN);
  if (n_ == 0) return x;
  const int ld = kd_ + 1, nrhs = 1;
  int info = 0;
  dpbtrs_("L", &n_, &kd_, &nrhs, band_.data(), &ld, x.data(), &n_, &info, 1);
  return x;
}

double BandCholesky::LogDeterminant() const {
  if (!ok_) return NAN;
  double sum = 0;
  for (int j = 0; j < n_; ++j) sum += std::log(band_[static_cast<std::size_t>(j) * (kd_ + 1)]);
  return 2.0 * sum;
}

}  // namespace topocal::topo
