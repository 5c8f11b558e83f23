// The spline fit's band Cholesky (topo/band_cholesky.h) against Eigen's dense LLT of the same matrix.
#include "topo/band_cholesky.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <cmath>
#include <random>
#include <vector>

namespace topocal::topo {
namespace {

// A random symmetric band matrix of half-width kd, diagonally dominant (positive definite) when `dominant`.
Eigen::SparseMatrix<double> RandomBand(int n, int kd, bool dominant, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Eigen::Triplet<double>> t;
  for (int j = 0; j < n; ++j) {
    t.emplace_back(j, j, dominant ? 2.0 * kd + 1.0 + u(rng) : u(rng));
    for (int i = j + 1; i <= std::min(n - 1, j + kd); ++i) {
      const double v = u(rng);
      t.emplace_back(i, j, v);
      t.emplace_back(j, i, v);
    }
  }
  Eigen::SparseMatrix<double> m(n, n);
  m.setFromTriplets(t.begin(), t.end());
  m.makeCompressed();
  return m;
}

TEST(BandCholesky, SolvesAndGivesTheLogDeterminantOfADenseFactorisation) {
  const int n = 300, kd = 40;
  const Eigen::SparseMatrix<double> m = RandomBand(n, kd, true, 3);
  BandCholesky band;
  ASSERT_TRUE(band.Factorize(m, kd));
  const Eigen::MatrixXd dense(m);
  const Eigen::LLT<Eigen::MatrixXd> llt(dense);
  ASSERT_EQ(llt.info(), Eigen::Success);
  std::mt19937 rng(4);
  std::normal_distribution<double> g;
  Eigen::MatrixXd b(n, 3);
  for (int i = 0; i < b.size(); ++i) b.data()[i] = g(rng);
  const Eigen::MatrixXd x = band.SolveColumns(b), reference = llt.solve(b);
  EXPECT_LT((x - reference).cwiseAbs().maxCoeff(), 1e-12);  // rounding; measured ~1e-16
  const Eigen::VectorXd x0 = band.Solve(Eigen::VectorXd(b.col(0)));
  EXPECT_LT((x0 - reference.col(0)).cwiseAbs().maxCoeff(), 1e-12);
  const double log_det = 2.0 * llt.matrixLLT().diagonal().array().log().sum();
  EXPECT_NEAR(band.LogDeterminant(), log_det, 1e-9 * std::abs(log_det));
}

TEST(BandCholesky, RefusesWhatItCannotFactorise) {
  BandCholesky band;
  // Indefinite: LAPACK stops at a non-positive pivot.
  EXPECT_FALSE(band.Factorize(RandomBand(50, 5, false, 7), 5));
  EXPECT_FALSE(band.ok());
  EXPECT_FALSE(band.Solve(Eigen::VectorXd::Ones(50)).allFinite());
  EXPECT_TRUE(std::isnan(band.LogDeterminant()));
  // An entry outside the stated band.
  EXPECT_FALSE(band.Factorize(RandomBand(50, 5, true, 8), 4));
  // The right-hand side of another size.
  ASSERT_TRUE(band.Factorize(RandomBand(50, 5, true, 9), 5));
  EXPECT_FALSE(band.Solve(Eigen::VectorXd::Ones(49)).allFinite());
}

}  // namespace
}  // namespace topocal::topo
