#pragma once
// Null-screen reconstruction (paper Sec. 4.1): from spot positions on the detection plane and the designed target
// points on the cone, recover the corneal surface as the Taylor polynomial Psi of Eq. 21.
//
// For every spot: the incident direction I from the image point through the pinhole (Eq. 3); an estimate P2' of the
// incidence point on a surface G; the reflected direction R' = (P3 - P2')/|P3 - P2'|; the normal n = (R' - I)/|R' - I|
// (Eq. 19) and the slopes S_x = -n_x/n_z, S_y = -n_y/n_z. The slopes are integrated zonally (trapezoidal rule along
// ring-to-ring paths, Eq. 20) and modally (least-squares fit of grad Psi, Eq. 21-22).
//
// Two ways to choose G (docs/reconstruction.md gives the evidence for the default):
//  * "paper": G is the design sphere placed at axial offsets t_k; the t_k whose Psi agrees best with its own
//    normals (smallest std of |U - n|, Eq. 22) wins, refining the t interval (Fig. 8) until Delta <= TOL or the
//    refinement budget ends. The normals are never updated, so Psi keeps the error of P2' ~ P2.
//  * "iterative" (default): start from the sphere, then intersect every ray with the current Psi, recompute the
//    normals from those points and refit, until no point moves by more than convergence_um. Delta(t) is monotone in
//    t here (the vertex height is not observable from one camera and one screen), so this method works at the
//    nominal vertex position vertex_t_um; the biconic fit's own vertex offset absorbs a small displacement.
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "model/config.h"
#include "model/null_screen.h"
#include "model/surface.h"
#include "topo/bspline_surface.h"
#include "topo/taylor_polynomial.h"

namespace topocal::topo {

struct ReconstructedPoint {
  model::SpotId id;
  Eigen::Vector3d point_mm;   // (x, y, Psi(x, y)): the incidence point on the recovered surface
  Eigen::Vector3d normal;     // n of Eq. 19 (points towards the camera, n_z < 0)
  double zonal_z_mm = 0;      // height from the trapezoidal zonal integration (Eq. 20)
};

struct Reconstruction {
  bool ok = false;
  std::string message;              // why it failed, or a one-line summary
  std::string method;
  TaylorPolynomial surface;         // Psi
  // surface_model "spline": a bicubic P-spline fitted to the slopes Psi leaves, with B(0, 0) = 0 (empty
  // otherwise). The recovered surface is Psi + residual: use Height() / Derivatives(), not Psi alone.
  BSplineSurface residual;
  // The surface model used: "polynomial" or "spline" (settings.surface_model, or what "auto" chose) and, for
  // "auto", why (the polynomial's two adequacy figures against their warning ratios).
  std::string surface_model;
  std::string surface_model_reason;
  double spline_lambda = 0;          // REML-chosen penalty weight
  double spline_effective_params = 0;
  double Height(double x_mm, double y_mm) const;
  void Derivatives(double x_mm, double y_mm, model::SurfaceDerivatives* d) const;
  std::vector<ReconstructedPoint> points;
  double vertex_t_mm = 0;           // axial position of G / of Psi(0, 0)
  double consistency = 0;           // Delta: std of |U - n| over the spots at the chosen t
  double rms_slope_residual = 0;    // rms of the gradient fit
  // Model adequacy: the rms slope residual a perfect surface model would leave if the spot centres
  // carried settings.spot_uncertainty_um of noise (each spot's slope sensitivity to its image position, by finite
  // differences through the rays and Psi, times the uncertainty, reduced by the fit's 1 - p / (2n) degrees of
  // freedom). adequacy_ratio = rms_slope_residual / expected_slope_noise: ~1 or below when the model holds, >> 1
  // when the surface model cannot represent the data.
  double expected_slope_noise = 0;
  double adequacy_ratio = 0;
  // The part of the slope residual that neighbouring spots share: the mean product of the residuals of
  // neighbouring spots on the spot lattice (each spot with the next on its ring and with the nearest of the ring
  // inside it), per slope component — the lag-1 autocovariance, ~0 for spot-centre noise (independent per spot),
  // the residual's variance for a model error smooth over the spot spacing. residual_neighbour_correlation = that
  // over the residual's variance; structured_residual_ratio = its square root over expected_slope_noise.
  double residual_neighbour_correlation = 0;
  double structured_residual_ratio = 0;
  int iterations = 0;               // normal-refinement iterations at the chosen t (iterative method)
  int vertex_evaluations = 0;       // t values tried
  int spots_used = 0;
  std::vector<model::SpotId> unmatched;  // spots whose identity is not in the design
  // The factor R (R^T R = A^T A) of the slope fit's last pass and the normalisation radius it belongs to: hand it to
  // ReconstructOptions::start to reconstruct slightly moved spots without a factorisation of their own.
  Eigen::MatrixXd slope_fit_factor;
  double slope_fit_norm_radius_mm = 0;
  int slope_fit_factorizations = 0;  // factorisations the slope fits needed at the chosen t (cold: one per pass)
};

// Above this ratio of slope residual to the expected noise the model, not the noise, leaves the residual: 3 x
// (a fit that holds leaves ~1 x; the paper biconic from exact spots leaves 1e-3 x, the keratoconus 10-100 x).
inline constexpr double kAdequacyWarningRatio = 3.0;
// Above this structured_residual_ratio (Reconstruction: the square root of the residual's neighbour covariance over
// the expected noise) the residual is a shape the model misses, whatever its size against the noise: spot-centre
// noise is independent per spot and leaves a covariance ~0 (measured <= 0 on every biconic and Zernike cornea of the
// test set with 0.04 px noise: 0.00), while the mildest cones that kAdequacyWarningRatio misses with the polynomial
// leave 0.54-1.96 (12 um cone 0.54-0.63, wide 40 um 0.81-0.87, 5 um 1.95; docs/reconstruction.md). 0.4: noise alone
// reaches it only with a neighbour correlation of +0.16, ~8 standard deviations of the estimate over ~1,200 pairs.
inline constexpr double kStructuredResidualWarningRatio = 0.4;
// The surface model represents the data: neither figure above its warning ratio.
bool ModelFitsData(const Reconstruction& r);

// Above this share of the slope observations (two per spot) in effective parameters (tr H) the spline residual
// interpolates the spots: too few residual degrees of freedom are left to judge the fit (the adequacy figures above
// fall to ~0 whatever the surface) or to hold the curvature between the spots. Measured on the freeform test set
// from exact spots (docs/reconstruction.md, "Knots finer than the spots"): every fit that held stayed at or below
// 0.77 (27 rings x 6 with knots every 0.15 mm); the fits at 1.00-1.06 (0.12 mm on 27 rings, 0.1 mm on the paper's
// screen) gave axial errors up to 15-18 D RMS with an adequacy ratio of 0.00.
inline constexpr double kMaxSplineParameterShare = 0.9;
// Empty when the spline residual (if any) is determined by the spots; otherwise why not, naming the setting.
std::optional<std::string> SplineUndetermined(const Reconstruction& r);

struct ReconstructOptions {
  // Model adequacy (expected_slope_noise, adequacy_ratio): finite differences through every ray, which a Monte
  // Carlo draw does not need (both are left 0 when false).
  bool adequacy = true;
  // A reconstruction of nearly the same spots (micrometres apart) whose slope-fit factor starts the fits here
  // (preconditioned CGLS instead of a new QR, topo/taylor_polynomial.h; ignored when the polynomial's degree or
  // normalisation radius differ) and, for the iterative method, whose recovered surface holds the first incidence
  // points (instead of the sphere G): the refinement converges to the same convergence_um from there in fewer
  // passes (results agree with a cold start to that tolerance, not bit for bit).
  const Reconstruction* start = nullptr;
};

// Reconstructs from any subset of spots (unordered, some missing). Fails (ok = false, message) with fewer spots
// than the polynomial needs, or when a ray misses the surface estimate.
Reconstruction Reconstruct(const std::vector<model::PlaneSpot>& spots, const std::vector<model::TargetPoint>& targets,
                           const model::TopographerParams& topographer, const model::ReconstructionSettings& settings,
                           const ReconstructOptions& options = {});

// One evaluation at a fixed vertex offset t (exposed for tests and the investigation in docs/reconstruction.md).
Reconstruction ReconstructAt(const std::vector<model::PlaneSpot>& spots, const std::vector<model::TargetPoint>& targets,
                             const model::TopographerParams& topographer,
                             const model::ReconstructionSettings& settings, double t_mm, bool iterate);

}  // namespace topocal::topo
