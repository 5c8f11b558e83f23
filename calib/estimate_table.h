#pragma once
// What a fit reports it estimated: each parameter's name, the Ceres parameter block and component that hold it, and
// the covariance of those parameters from the tangent covariance of the blocks (calib/jacobian_covariance.h). One
// owner for the camera fit (calib/calibrate.h) and the device fit (calib/device_fit.h).
//
//   EstimateTable table;
//   table.AddBlock({"fx", "fy", "cx", "cy"}, intrinsics);
//   const auto tangent = TangentCovariance(problem, blocks);           // blocks: the non-constant ones
//   Eigen::MatrixXd cov = table.Covariance(problem, blocks, tangent, residual_variance);
//   std::vector<double> sd = EstimateTable::StandardDeviations(cov);
//
// cov = (P C P^T) s, C the tangent covariance, P each block's plus-Jacobian (identity without a manifold, the
// selection of a SubsetManifold, fx and fy moving together under a fixed aspect ratio), s the variance scale. A
// component a manifold holds, or a block that is not among `blocks` (held constant), has a zero row and column: its
// standard deviation is 0, never a number the data did not give.
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <ceres/problem.h>

#include "calib/jacobian_covariance.h"

namespace topocal::calib {

struct EstimateEntry {
  std::string name;
  const double* block = nullptr;  // the parameter block holding it
  int index = 0;                  // its component in the block
};

class EstimateTable {
 public:
  void Add(std::string name, const double* block, int index) { entries_.push_back({std::move(name), block, index}); }
  // Components 0, 1, ... of `block`, one per name.
  void AddBlock(const std::vector<std::string>& names, const double* block);

  const std::vector<EstimateEntry>& entries() const noexcept { return entries_; }
  int size() const noexcept { return static_cast<int>(entries_.size()); }
  std::vector<std::string> Names() const;
  // The current value of each entry (its block's component).
  std::vector<double> Values() const;

  // The entries' covariance, square in their order and units, scaled by `variance_scale` (the residual variance,
  // or 1 for whitened residuals). `blocks` and `tangent` as TangentCovariance was given and returned them. nullopt
  // with the reason when a block's plus-Jacobian cannot be evaluated or a variance is not finite.
  std::optional<Eigen::MatrixXd> Covariance(const ceres::Problem& problem, const std::vector<double*>& blocks,
                                            const TangentCovarianceResult& tangent, double variance_scale,
                                            std::string* why) const;

  // sqrt of the diagonal; 0 where the variance is not positive (a held parameter).
  static std::vector<double> StandardDeviations(const Eigen::MatrixXd& covariance);

 private:
  std::vector<EstimateEntry> entries_;
};

}  // namespace topocal::calib
