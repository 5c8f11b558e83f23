#pragma once
// Least-squares fit of a sphere — centre (x, y, z) and radius, 4 parameters — to a reconstructed point cloud: the
// fit of a reference sphere or reference ball (unit verification, the device's held-out ball), where the surface is
// known to be a sphere and only its size and place are unknown.
//
// Why not the biconic fit: a sphere has no axis, so the free-apex biconic's tilt and decentration describe the same
// surface and its conic constants and rotation are undetermined; that fit is degenerate on a sphere and runs to its
// iteration cap (~80 ms per analysis, 75 % of `unit calibrate`). The paper's 6-parameter fit (apex on the
// axis) is well posed but wrong for a ball that sits off the axis or is seen through a tilted screen. Four
// parameters with the centre free in 3-D are the sphere's own degrees of freedom: well conditioned, no degeneracy.
//
// Residual: the orthogonal distance |p_i - c| - r (mm), the maximum-likelihood residual for isotropic point noise,
// defined everywhere (a sag residual, as the biconic fit uses, is undefined beyond the sphere's equator). Start:
// the algebraic (Kasa) fit |p|^2 + D.p + E = 0, linear least squares, exact for exact data; then Ceres'
// Levenberg-Marquardt with the analytic Jacobian (the sag residual: Gauss-Newton steps on the 4 x 4 normal
// equations in Eigen, Ceres' overhead being most of that small fit's time). Standard deviations from (J'J)^-1
// scaled by SSR / (n - 4).
#include <string>
#include <vector>

#include <Eigen/Core>

#include "model/surface.h"

namespace topocal::topo {

// What the fit minimises.
enum class SphereResidual {
  kOrthogonal,  // |p_i - c| - r: a reference sphere or ball measured as a point cloud (above)
  kSag,         // z_i - sag of the cap facing the camera (z = c_z - sqrt(r^2 - (x - c_x)^2 - (y - c_y)^2)): the
                // clinical best-fit sphere (elevation maps, topo/clinical_indices.h), whose elevation is read
                // along the instrument axis; a point beyond the sphere's equator rejects the step
};

struct SphereFit;

struct SphereFitOptions {
  SphereResidual residual = SphereResidual::kOrthogonal;
  int max_iterations = 50;
  bool stddev = true;  // SphereFit::stddev_*; a Monte Carlo draw does not need it
  // The fit of nearly the same cloud (a Monte Carlo draw's nominal): start from it instead of the algebraic fit
  // (WarmStartSolverOptions: Gauss-Newton steps, 1e-12 relative step to stop).
  const SphereFit* start = nullptr;
};

struct SphereFit {
  bool ok = false;
  std::string message;
  Eigen::Vector3d centre_mm = Eigen::Vector3d::Zero();
  double radius_mm = 0;
  Eigen::Vector3d centre_stddev_mm = Eigen::Vector3d::Zero();
  double radius_stddev_mm = 0;
  double vertex_z_stddev_mm = 0;  // of the vertex's axial position centre_z - radius (correlated terms included)
  bool stddev_ok = false;
  double rms_residual_um = 0;  // rms residual (orthogonal distance or sag, as chosen)
  int iterations = 0;
  int points = 0;
  // The same sphere as model::Sphere: its vertex (the point nearest the camera, sag towards +z) at
  // (centre_x, centre_y, centre_z - radius).
  model::Sphere AsSurface() const;
};

// Needs at least 5 points not on one plane or circle. A failed fit returns ok = false with the reason; never throws.
SphereFit FitSphere(const std::vector<Eigen::Vector3d>& points_mm, const SphereFitOptions& options = {});

}  // namespace topocal::topo
