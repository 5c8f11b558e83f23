#pragma once
// Least-squares fit of the rotated biconic (paper Eq. 12-13, surface rotated by +alpha; the one definition is
// model::BiconicKernel in model/surface.h) to a reconstructed point cloud, with Ceres; each parameter's standard
// deviation from the covariance of the fit (scaled by the residual variance SSR / (n - p)).
//
// Parameters: curvatures c_x = 1/r_x, c_y = 1/r_y (better conditioned than radii), conic constants k_x, k_y, the
// rotation alpha, the vertex offset z0 along the axis, and — in the default "free-apex" mode — the lateral apex
// position (x0, y0) and the tilt of the eye about its apex (tilt_x, tilt_y: model/surface.h). A patient's fixation
// leaves the apex 0.1-0.5 mm off the instrument axis and the eye tilted by a few degrees; the paper's 6-parameter
// fit ("paper" mode: x0 = y0 = 0, no tilt) turns that into shape (0.42 mm off gives |dk| = 2.5).
// Residual: the sag difference z_i - S(x_i, y_i) at each point's (x, y).
// The result is canonical: r_x >= r_y and alpha in [0, 180) deg — (r_x, r_y, k_x, k_y, alpha) and
// (r_y, r_x, k_y, k_x, alpha + 90) are the same surface, so a fit cannot tell them apart.
#include <string>
#include <vector>

#include <Eigen/Core>

#include "model/config.h"
#include "util/io.h"

namespace topocal::topo {

enum class BiconicFitMode {
  kFreeApex,  // apex (x0, y0, z0) and tilt free: 10 parameters (default)
  kPaper,     // the paper's 6 parameters: apex on the axis (z0 free), no tilt
  // A known sphere (reference sphere, reference ball): topo::FitSphere's 4 parameters, centre and radius
  // (topo/sphere_fit.h). The result is written as a biconic with r_x = r_y = r and, by construction (not fitted),
  // k_x = k_y = 0, alpha = 0 and no tilt (a sphere's tilt about its vertex is a decentration); the apex is the
  // sphere's vertex (centre - r e_z); stddev of k, alpha and tilt are 0.
  kSphere,
};

struct BiconicFitOptions {
  BiconicFitMode mode = BiconicFitMode::kFreeApex;
  int max_iterations = 200;
  bool stddev = true;  // the covariance of the fit (BiconicFit::stddev); a Monte Carlo draw does not need it
  // The fit of nearly the same cloud, in the same mode (a Monte Carlo draw's nominal fit): the fit starts from its
  // parameters instead of the quadratic guess (kSphere: the algebraic fit) with WarmStartSolverOptions
  // (topo/surface_fit_solver.h). Agrees with a cold fit to ~1e-13.
  const model::BiconicParams* start = nullptr;
};

// "free-apex" / "paper" / "sphere" (the configuration key reconstruction.biconic_fit and the CLI's --biconic-fit).
BiconicFitMode BiconicFitModeFromName(const std::string& name);  // throws util::InputError
const char* BiconicFitModeName(BiconicFitMode mode);

struct BiconicStdDev {
  double rx_mm = 0, ry_mm = 0, kx = 0, ky = 0, alpha_deg = 0, z0_mm = 0, x0_mm = 0, y0_mm = 0;
  double tilt_x_deg = 0, tilt_y_deg = 0;
  double apex_x_mm = 0, apex_y_mm = 0;  // of the apex in the instrument frame
};

struct BiconicFit {
  bool ok = false;
  std::string message;
  BiconicFitMode mode = BiconicFitMode::kFreeApex;
  model::BiconicParams params;   // z0_mm is the fitted vertex offset; x0, y0 in the rotated frame (Eq. 12)
  Eigen::Vector3d apex_mm = Eigen::Vector3d::Zero();  // the apex in the instrument frame (decentration x, y; z0)
  BiconicStdDev stddev;
  bool stddev_ok = false;        // false when the covariance is rank-deficient (e.g. alpha of a near-sphere)
  double rms_residual_um = 0;     // of the sag residual (kSphere: of the orthogonal distance)
  int iterations = 0;
  int points = 0;
  double DecentrationMm() const { return apex_mm.head<2>().norm(); }
  // Total tilt of the eye's axis against the instrument axis.
  double TiltDeg() const;
};

BiconicFit FitBiconic(const std::vector<Eigen::Vector3d>& points_mm, const BiconicFitOptions& options = {});

// The canonical form (r_x >= r_y, alpha in [0, 180)) of a biconic, for comparing fits with a known truth.
model::BiconicParams CanonicalBiconic(const model::BiconicParams& p);

}  // namespace topocal::topo
