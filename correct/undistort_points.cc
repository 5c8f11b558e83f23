#include "correct/undistort_points.h"

#include <cmath>

#include <fmt/format.h>

namespace topocal::correct {

UndistortedPoints UndistortPoints(const model::Distortion& distortion, const std::vector<Eigen::Vector2d>& distorted_mm,
                                  double residual_tolerance_mm) {
  UndistortedPoints out;
  out.points_mm = distorted_mm;
  out.ok.assign(distorted_mm.size(), false);
  for (size_t i = 0; i < distorted_mm.size(); ++i) {
    const Eigen::Vector2d& d = distorted_mm[i];
    if (!d.allFinite()) {
      out.failures.push_back({static_cast<int>(i), "not a finite point"});
      continue;
    }
    const auto u = model::Undistort(distortion, d);
    if (!u) {
      out.failures.push_back({static_cast<int>(i), fmt::format("({:.6g}, {:.6g}) mm: the inverse did not converge "
                                                               "(no preimage: beyond the fold of the distortion?)",
                                                               d.x(), d.y())});
      continue;
    }
    const double residual = (model::Distort(distortion, *u) - d).norm();
    if (!(residual <= residual_tolerance_mm)) {
      out.failures.push_back({static_cast<int>(i), fmt::format("({:.6g}, {:.6g}) mm: round-trip residual {:.3g} mm "
                                                               "exceeds {:.3g} mm",
                                                               d.x(), d.y(), residual, residual_tolerance_mm)});
      continue;
    }
    out.points_mm[i] = *u;
    out.ok[i] = true;
    out.max_residual_mm = std::max(out.max_residual_mm, residual);
  }
  return out;
}

std::vector<Eigen::Vector2d> DistortPoints(const model::Distortion& distortion,
                                           const std::vector<Eigen::Vector2d>& undistorted_mm) {
  std::vector<Eigen::Vector2d> out;
  out.reserve(undistorted_mm.size());
  for (const auto& p : undistorted_mm) out.push_back(model::Distort(distortion, p));
  return out;
}

}  // namespace topocal::correct
