#pragma once
// The biconic's sag (model::BiconicKernel: paper Eq. 12-13, optionally tilted about its vertex) and its derivatives
// with respect to the kernel's 10 parameters, in closed form, for the Jacobian of the biconic fit
// (topo/biconic_fit.cc).
//
// Written by hand rather than taken from Ceres' autodiff: with Jet<double, 10> every arithmetic operation carries
// ten derivatives. That includes the trigonometry of alpha and of the tilts at every point, and the jet's Newton
// step and second evaluation. Autodiff was the largest part of the free-apex fit, and that fit is ~24 % of
// `unit calibrate` (docs/performance.md).
// The derivatives (q = the parameter vector, p = (x, y, z) a point on the surface):
//  - untilted, z = G(x, y; q), where
//      G = z0 + (c_x X^2 + c_y Y^2) / (1 + s),  s = sqrt(1 - Q_x c_x^2 X^2 - Q_y c_y^2 Y^2),
//      X = ca x + sa y - x0,  Y = -sa x + ca y - y0.
//    With zz = G - z0 and den = 1 + s:
//      dG/dc_x = X^2 / den + zz X^2 (1 + k_x) c_x / (s den),   dG/dk_x = zz X^2 c_x^2 / (2 s den),
//      dG/dalpha = G_X dX/dalpha + G_Y dY/dalpha,   dG/dx0 = -G_X,   dG/dy0 = -G_Y,   dG/dz0 = 1.
//  - tilted, z is the root of F(p; q) = u_z - G(u_x, u_y; q), where u = A + M (p - A) and A is the apex. By the
//    implicit function theorem dz/dq = -F_q / F_z, with
//      F_z = M_22 - G_u M_02 - G_v M_12,
//      F_q = du_z/dq - G_q - G_u du_x/dq - G_v du_y/dq,
//      du/dq = (I - M) dA/dq   for alpha, x0, y0, z0,
//      du/dq = dM/dq (p - A)   for the tilts.
// tests/topo/biconic_jacobian_test.cc checks the result against Ceres' jets and finite differences.
#include "model/surface.h"

namespace topocal::topo {

class BiconicSagJacobian {
 public:
  using K = model::BiconicKernel;
  // The work that depends on the parameters alone: the trigonometry, the rotation and the apex.
  BiconicSagJacobian(const double* q, bool tilted) noexcept;

  // The sag z(x, y): bit for bit model::BiconicKernel::Sag (tested), the tilted root by the kernel's own
  // BiconicKernel::TiltedSag on the trigonometry computed once. Returns false where the kernel does (outside the
  // domain, or no convergence).
  bool Sag(double x_mm, double y_mm, double* z_mm) const noexcept;
  // The same root started from z_start_mm, the sag at nearly the same parameters (the fit's previous evaluation),
  // and stopped by the step that already gives the root to rounding: Newton converges quadratically, the error
  // after a step s being ~C s^2 with C = |F_zz / (2 F_z)| (~0.03 / mm at 30 deg of tilt, where F_zz is G's curvature
  // times sin^2 of the tilt), so after a step below kNearStepMm the error is below 1e-17 mm, under the rounding of
  // a sag. Within a few ulps of Sag's root (tested); not bit for bit, as the root's last bits depend on the start.
  // Near the fit's optimum one Newton step instead of Sag's 5 (3-4 from G's sag, the one that confirms it, and
  // the final one). Falls back to Sag where the warm root fails, so it rejects only what Sag rejects. Untilted: Sag.
  bool SagNear(double x_mm, double y_mm, double z_start_mm, double* z_mm) const noexcept;
  static constexpr double kNearStepMm = 1e-8;
  // dz/dq at the surface point (x, y, z) (z from Sag), in the kernel's parameter order. Without tilt the tilt
  // entries are 0: the surface does not depend on them.
  bool Derivatives(double x_mm, double y_mm, double z_mm, double* dz_dq) const noexcept;
  // Both; dz_dq may be null.
  bool Evaluate(double x_mm, double y_mm, double* z_mm, double* dz_dq) const noexcept {
    return Sag(x_mm, y_mm, z_mm) && (!dz_dq || Derivatives(x_mm, y_mm, *z_mm, dz_dq));
  }

 private:
  // G at (u, v) in the instrument frame: the value, the gradient (G_u, G_v) and the partials with respect to
  // c_x ... z0 (the first 8 parameters) at fixed (u, v).
  bool Untilted(double u, double v, double* g, double* gu, double* gv, double* dg) const noexcept;

  double q_[K::kNumParams];
  bool tilted_;
  K::Frame<double> frame_;
  K::Tilt<double> tilt_;              // u = A + M (p - A): the kernel's M = R^T and apex A
  double dm_tx_[3][3], dm_ty_[3][3];  // dM/dtilt_x, dM/dtilt_y
};

}  // namespace topocal::topo
