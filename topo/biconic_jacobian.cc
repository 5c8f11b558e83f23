#include "topo/biconic_jacobian.h"

#include <cmath>

namespace topocal::topo {

BiconicSagJacobian::BiconicSagJacobian(const double* q, bool tilted) noexcept : tilted_(tilted) {
  for (int i = 0; i < K::kNumParams; ++i) q_[i] = q[i];
  frame_ = K::FrameOf(q_);
  tilt_ = K::TiltOf(frame_, q_);
  // dM/dtilt of the kernel's M = R^T, R = Ry(tilt_y) Rx(tilt_x).
  const double cx = std::cos(q_[K::kTiltX]), sx = std::sin(q_[K::kTiltX]);
  const double cy = std::cos(q_[K::kTiltY]), sy = std::sin(q_[K::kTiltY]);
  const double dtx[3][3] = {{0.0, 0.0, 0.0}, {cx * sy, -sx, cx * cy}, {-sx * sy, -cx, -sx * cy}};
  const double dty[3][3] = {{-sy, 0.0, -cy}, {sx * cy, 0.0, -sx * sy}, {cx * cy, 0.0, -cx * sy}};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      dm_tx_[i][j] = dtx[i][j];
      dm_ty_[i][j] = dty[i][j];
    }
  }
}

bool BiconicSagJacobian::Untilted(double u, double v, double* g, double* gu, double* gv, double* dg) const noexcept {
  if (!K::UntiltedSag(frame_, q_, u, v, g, gu, gv)) return false;
  if (!dg) return true;
  const double ca = frame_.ca, sa = frame_.sa;
  const double cx = q_[K::kCx], cy = q_[K::kCy];
  const double X = ca * u + sa * v - q_[K::kX0], Y = -sa * u + ca * v - q_[K::kY0];
  const double X2 = X * X, Y2 = Y * Y;
  const double s = std::sqrt(1.0 - frame_.qx * X2 - frame_.qy * Y2);  // > 0: UntiltedSag checked it
  const double den = 1.0 + s;
  const double zz = *g - q_[K::kZ0];
  // dzz/dQ_x = zz X^2 / (2 s den) with Q_x = (1 + k_x) c_x^2 (and the same in y).
  const double w = zz / (2.0 * s * den);
  const double gX = ca * *gu + sa * *gv, gY = -sa * *gu + ca * *gv;  // the gradient in the rotated frame
  dg[K::kCx] = X2 / den + w * X2 * 2.0 * (1.0 + q_[K::kKx]) * cx;
  dg[K::kCy] = Y2 / den + w * Y2 * 2.0 * (1.0 + q_[K::kKy]) * cy;
  dg[K::kKx] = w * X2 * cx * cx;
  dg[K::kKy] = w * Y2 * cy * cy;
  dg[K::kAlpha] = gX * (-sa * u + ca * v) + gY * (-ca * u - sa * v);
  dg[K::kX0] = -gX;
  dg[K::kY0] = -gY;
  dg[K::kZ0] = 1.0;
  return true;
}

bool BiconicSagJacobian::Sag(double x_mm, double y_mm, double* z_mm) const noexcept {
  if (!tilted_) {
    return K::UntiltedSag(frame_, q_, x_mm, y_mm, z_mm, static_cast<double*>(nullptr), static_cast<double*>(nullptr));
  }
  // The kernel's own tilted root (for T = P = double), on the trigonometry computed once.
  return K::TiltedSag(frame_, q_, tilt_, frame_, q_, tilt_, x_mm, y_mm, z_mm, static_cast<double*>(nullptr),
                      static_cast<double*>(nullptr));
}

bool BiconicSagJacobian::SagNear(double x_mm, double y_mm, double z_start_mm, double* z_mm) const noexcept {
  if (tilted_) {
    double z = z_start_mm;
    // The kernel's domain check at the point found (TiltedSag checks its final point the same way).
    if (K::TiltedRoot(frame_, q_, tilt_, x_mm, y_mm, kNearStepMm, &z) &&
        K::TiltedResidual(frame_, q_, tilt_, x_mm, y_mm, z, static_cast<double*>(nullptr),
                          static_cast<double*>(nullptr))) {
      *z_mm = z;
      return true;
    }
  }
  return Sag(x_mm, y_mm, z_mm);
}

bool BiconicSagJacobian::Derivatives(double x_mm, double y_mm, double z_mm, double* dz_dq) const noexcept {
  if (!tilted_) {
    double g, gu, gv;
    if (!Untilted(x_mm, y_mm, &g, &gu, &gv, dz_dq)) return false;
    dz_dq[K::kTiltX] = dz_dq[K::kTiltY] = 0.0;
    return true;
  }
  const double* apex = tilt_.apex;
  const auto& m = tilt_.m;
  const double d[3] = {x_mm - apex[0], y_mm - apex[1], z_mm - apex[2]};
  double u[3];
  K::ToUntilted(tilt_, x_mm, y_mm, z_mm, u);
  double g, gu, gv, dg[K::kNumParams];
  if (!Untilted(u[0], u[1], &g, &gu, &gv, dg)) return false;
  const double fz = m[2][2] - gu * m[0][2] - gv * m[1][2];
  if (!(std::abs(fz) > 1e-6)) return false;  // the kernel's own grazing limit
  // F_q for a change du of u and an explicit change dg_q of G.
  const auto f_q = [&](const double* du, double dg_q) { return du[2] - dg_q - gu * du[0] - gv * du[1]; };
  // du = (I - M) dA for a change dA of the apex.
  const auto from_apex = [&](double ax, double ay, double az, double* du) {
    const double da[3] = {ax, ay, az};
    for (int i = 0; i < 3; ++i) du[i] = da[i] - (m[i][0] * da[0] + m[i][1] * da[1] + m[i][2] * da[2]);
  };
  const auto from_tilt = [&](const double (*dm)[3], double* du) {
    for (int i = 0; i < 3; ++i) du[i] = dm[i][0] * d[0] + dm[i][1] * d[1] + dm[i][2] * d[2];
  };
  const double ca = frame_.ca, sa = frame_.sa;
  double du[3];
  for (int j : {K::kCx, K::kCy, K::kKx, K::kKy}) dz_dq[j] = dg[j] / fz;  // -F_q / F_z with F_q = -G_q
  from_apex(-apex[1], apex[0], 0.0, du);                                 // dA/dalpha
  dz_dq[K::kAlpha] = -f_q(du, dg[K::kAlpha]) / fz;
  from_apex(ca, sa, 0.0, du);  // dA/dx0
  dz_dq[K::kX0] = -f_q(du, dg[K::kX0]) / fz;
  from_apex(-sa, ca, 0.0, du);  // dA/dy0
  dz_dq[K::kY0] = -f_q(du, dg[K::kY0]) / fz;
  from_apex(0.0, 0.0, 1.0, du);  // dA/dz0
  dz_dq[K::kZ0] = -f_q(du, dg[K::kZ0]) / fz;
  from_tilt(dm_tx_, du);
  dz_dq[K::kTiltX] = -f_q(du, 0.0) / fz;
  from_tilt(dm_ty_, du);
  dz_dq[K::kTiltY] = -f_q(du, 0.0) / fz;
  return true;
}

}  // namespace topocal::topo
