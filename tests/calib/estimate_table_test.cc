// The one estimate table of both fits: the covariance of named parameters from the tangent covariance, against the
// closed form of a linear least-squares problem.
#include "calib/estimate_table.h"

#include <gtest/gtest.h>

#include <cmath>
#include <optional>

#include <ceres/ceres.h>

namespace topocal::calib {
namespace {

// r = A x - y for a 3-vector x: J = A, cov(x) = (A^T A)^-1.
struct Linear {
  Eigen::Matrix3d a;
  Eigen::Vector3d y;
  template <typename T>
  bool operator()(const T* x, T* r) const {
    for (int i = 0; i < 3; ++i) r[i] = T(a(i, 0)) * x[0] + T(a(i, 1)) * x[1] + T(a(i, 2)) * x[2] - T(y[i]);
    return true;
  }
};

struct Fixture {
  Linear model{(Eigen::Matrix3d() << 2, 1, 0, 1, 3, 1, 0, 1, 4).finished(), Eigen::Vector3d(1, 2, 3)};
  double x[3] = {0.1, 0.2, 0.3};
  double held[1] = {5.0};  // a block the problem holds constant
  ceres::Problem problem;
  Fixture() {
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<Linear, 3, 3>(new Linear(model)), nullptr, x);
    problem.AddParameterBlock(held, 1);
    problem.SetParameterBlockConstant(held);
  }
  EstimateTable Table() const {
    EstimateTable t;
    t.AddBlock({"x0", "x1", "x2"}, x);
    t.Add("held", held, 0);
    return t;
  }
};

// The table's covariance of the fixture's problem as it stands (x the one non-constant block).
Eigen::MatrixXd CovarianceOf(Fixture& f, double variance_scale) {
  std::vector<double*> blocks = {f.x};
  const auto tangent = TangentCovariance(f.problem, blocks);
  EXPECT_TRUE(tangent.ok) << tangent.message;
  std::string why;
  const auto cov = f.Table().Covariance(f.problem, blocks, tangent, variance_scale, &why);
  EXPECT_TRUE(cov) << why;
  return cov.value_or(Eigen::MatrixXd::Constant(4, 4, NAN));
}

TEST(EstimateTable, IsTheInverseNormalMatrixScaledWithHeldParametersZero) {
  Fixture f;
  const auto cov = std::optional(CovarianceOf(f, 4.0));
  const Eigen::Matrix3d expected = 4.0 * (f.model.a.transpose() * f.model.a).inverse();
  EXPECT_LT((cov->topLeftCorner<3, 3>() - expected).norm(), 1e-12 * expected.norm());
  EXPECT_EQ(cov->row(3).norm(), 0.0);  // the constant block: held, not a number the data gave
  EXPECT_EQ(cov->col(3).norm(), 0.0);
  const auto sd = EstimateTable::StandardDeviations(*cov);
  EXPECT_NEAR(sd[1], std::sqrt(expected(1, 1)), 1e-12);
  EXPECT_EQ(sd[3], 0.0);
  EXPECT_EQ(f.Table().Names()[3], "held");
  EXPECT_EQ(f.Table().Values()[2], 0.3);
}

TEST(EstimateTable, AComponentAManifoldHoldsHasAZeroRowAndTheOthersTheReducedInverse) {
  Fixture f;
  f.problem.SetManifold(f.x, new ceres::SubsetManifold(3, {1}));
  const auto cov = std::optional(CovarianceOf(f, 1.0));
  // Columns 0 and 2 of A are what the data determine with x1 held.
  Eigen::Matrix<double, 3, 2> reduced;
  reduced << f.model.a.col(0), f.model.a.col(2);
  const Eigen::Matrix2d expected = (reduced.transpose() * reduced).inverse();
  EXPECT_NEAR((*cov)(0, 0), expected(0, 0), 1e-12);
  EXPECT_NEAR((*cov)(0, 2), expected(0, 1), 1e-12);
  EXPECT_NEAR((*cov)(2, 2), expected(1, 1), 1e-12);
  EXPECT_EQ(cov->row(1).norm(), 0.0);
  EXPECT_EQ(EstimateTable::StandardDeviations(*cov)[1], 0.0);
}

}  // namespace
}  // namespace topocal::calib
