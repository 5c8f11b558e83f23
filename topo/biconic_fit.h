#pragma once
// Least-squares fit of the rotated biconic (paper Eq. 12, surface rotated by +alpha, model/surface.h) to a
// reconstructed point cloud, with Ceres; each parameter's standard deviation from the covariance of the fit
// (scaled by the residual variance SSR / (n - p)).
//
// Parameters: curvatures c_x = 1/r_x, c_y = 1/r_y (better conditioned than radii), conic constants k_x, k_y, the
// rotation alpha, the vertex offset z0 along the axis, and optionally the decentration (x0, y0).
// The result is canonical: r_x >= r_y and alpha in [0, 180) deg — (r_x, r_y, k_x, k_y, alpha) and
// (r_y, r_x, k_y, k_x, alpha + 90) are the same surface, so a fit cannot tell them apart.
#include <string>
#include <vector>

#include <Eigen/Core>

#include "model/config.h"

namespace topocal::topo {

struct BiconicFitOptions {
  bool fit_decentration = false;
  int max_iterations = 200;
};

struct BiconicStdDev {
  double rx_mm = 0, ry_mm = 0, kx = 0, ky = 0, alpha_deg = 0, z0_mm = 0, x0_mm = 0, y0_mm = 0;
};

struct BiconicFit {
  bool ok = false;
  std::string message;
  model::BiconicParams params;   // z0_mm is the fitted vertex offset
  BiconicStdDev stddev;
  bool stddev_ok = false;        // false when the covariance is rank-deficient (e.g. alpha of a near-sphere)
  double rms_residual_um = 0;
  int iterations = 0;
  int points = 0;
};

BiconicFit FitBiconic(const std::vector<Eigen::Vector3d>& points_mm, const BiconicFitOptions& options = {});

// The canonical form (r_x >= r_y, alpha in [0, 180)) of a biconic, for comparing fits with a known truth.
model::BiconicParams CanonicalBiconic(const model::BiconicParams& p);

}  // namespace topocal::topo
