#pragma once
// Covariance of a solved least-squares problem's free parameters, (J^T J)^-1, from the Jacobian of every residual
// in the tangent space of the given parameter blocks.
//
//   auto cov = calib::TangentCovariance(problem, {intrinsics, distortion, pose0, pose1});
//   if (!cov.ok) return Fail(cov.message);            // a free direction the data do not determine
//   double var_fx = cov.matrix(cov.offset[0] + 0, cov.offset[0] + 0) * residual_variance;
//
// One owner for the camera fit (calib/calibrate.h) and the device fit (calib/device_fit.h). Computed here rather
// than with ceres::Covariance for two measured reasons:
//  - ceres::Covariance's DENSE_SVD builds the full m x m U of the Jacobian (15 MB for 13 views of 54 corners): it was
//    half of a 13-view calibration's solve time and most of its page faults;
//  - its SVD truncates weak directions: on the device fit it returned near-zero variances for the principal point.
// J^T J is accumulated from the sparse Jacobian (a row touches ~15 columns), its columns scaled to unit norm
// (sigma ~1e-5 mm^-2 next to pixels and degrees spans ten orders of magnitude), and inverted by LDLT; a pivot below
// 1e-14 of the largest (Ceres' own min_reciprocal_condition_number) means the parameters are not all determined.
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <ceres/problem.h>

namespace topocal::calib {

struct TangentCovarianceResult {
  bool ok = false;
  std::string message;  // why not, when !ok
  // Square, over the tangent coordinates of the blocks in the order given (a block with a SubsetManifold
  // contributes only its free components, in their order).
  Eigen::MatrixXd matrix;
  std::vector<int> offset;        // first row of each block
  std::vector<int> tangent_size;  // rows of each block
};

// `blocks` must be parameter blocks of `problem` that are not constant. Unscaled: multiply by the residual variance
// (or 1 when the residuals are already whitened). !ok with the reason in `message` when the Jacobian cannot be
// evaluated or J^T J is singular (a computation that failed; the fits report it in their own result).
TangentCovarianceResult TangentCovariance(ceres::Problem& problem, const std::vector<double*>& blocks);

}  // namespace topocal::calib
