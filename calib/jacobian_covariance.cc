#include "calib/jacobian_covariance.h"

#include <Eigen/Cholesky>
#include <ceres/crs_matrix.h>

namespace topocal::calib {

TangentCovarianceResult TangentCovariance(ceres::Problem& problem, const std::vector<double*>& blocks) {
  const auto fail = [](const char* reason) {
    TangentCovarianceResult failed;
    failed.message = reason;
    return failed;
  };
  TangentCovarianceResult result;
  int columns = 0;
  for (double* b : blocks) {
    if (problem.IsParameterBlockConstant(b)) return fail("internal: a constant parameter block has no covariance");
    result.offset.push_back(columns);
    result.tangent_size.push_back(problem.ParameterBlockTangentSize(b));
    columns += result.tangent_size.back();
  }
  ceres::Problem::EvaluateOptions eval;
  eval.parameter_blocks = blocks;
  eval.num_threads = 1;
  ceres::CRSMatrix jacobian;
  if (!problem.Evaluate(eval, nullptr, nullptr, nullptr, &jacobian)) return fail("the Jacobian could not be evaluated");
  if (jacobian.num_cols != columns) return fail("internal: the Jacobian's columns do not match the parameter blocks");

  Eigen::MatrixXd info = Eigen::MatrixXd::Zero(columns, columns);
  for (int r = 0; r < jacobian.num_rows; ++r) {
    for (int a = jacobian.rows[r]; a < jacobian.rows[r + 1]; ++a) {
      const double va = jacobian.values[a];
      const int ca = jacobian.cols[a];
      // Both triangles (a row's columns follow its residual block's parameter order, not necessarily ascending).
      for (int b = jacobian.rows[r]; b < jacobian.rows[r + 1]; ++b) info(ca, jacobian.cols[b]) += va * jacobian.values[b];
    }
  }
  const Eigen::VectorXd inv_norm = info.diagonal().cwiseMax(1e-300).cwiseSqrt().cwiseInverse();
  const Eigen::MatrixXd scaled = inv_norm.asDiagonal() * info * inv_norm.asDiagonal();
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(scaled);
  if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 1e-14 * ldlt.vectorD().maxCoeff())) {
    return fail("J^T J is singular: some free parameter is not determined by the data");
  }
  result.matrix = inv_norm.asDiagonal() * ldlt.solve(Eigen::MatrixXd::Identity(columns, columns)) * inv_norm.asDiagonal();
  if (!result.matrix.allFinite()) return fail("non-finite covariance");
  result.ok = true;
  return result;
}

}  // namespace topocal::calib
