#pragma once
// Undistortion of point sets on the detection plane with any model::Distortion (Seidel or Brown-Conrady).
//
// Each point is inverted by model::Undistort (Newton to convergence, never a fixed iteration count) and then
// checked independently: the undistorted point is distorted again and must land on the input within
// `residual_tolerance_mm`. A point that fails either step is reported by index with the reason; it is never
// silently replaced by a guess.
#include <string>
#include <vector>

#include <Eigen/Core>

#include "model/distortion.h"

namespace topocal::correct {

// Accepted |Distort(Undistort(p)) - p|: 1e-9 mm = 1e-6 px at a 1 um pitch, far below any centroid error (~0.01 px),
// far above the inverse's own floor (model::kInverseToleranceMm = 1e-12 mm).
inline constexpr double kPointResidualToleranceMm = 1e-9;

struct PointFailure {
  int index = 0;  // into the input
  std::string reason;
};

struct UndistortedPoints {
  std::vector<Eigen::Vector2d> points_mm;  // same order and size as the input; failed entries hold the input point
  std::vector<bool> ok;                    // ok[i] == false for every failure
  std::vector<PointFailure> failures;
  double max_residual_mm = 0;              // largest round-trip residual among the converged points
};

UndistortedPoints UndistortPoints(const model::Distortion& distortion, const std::vector<Eigen::Vector2d>& distorted_mm,
                                  double residual_tolerance_mm = kPointResidualToleranceMm);

// The forward direction, for simulation: every point distorted (the forward map always exists).
std::vector<Eigen::Vector2d> DistortPoints(const model::Distortion& distortion,
                                           const std::vector<Eigen::Vector2d>& undistorted_mm);

}  // namespace topocal::correct
