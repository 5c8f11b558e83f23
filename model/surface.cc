#include "model/surface.h"

#include <cmath>
#include <limits>

#include <ceres/jet.h>

namespace topocal::model {

bool Sphere::Evaluate(double x_mm, double y_mm, SurfaceDerivatives* d) const noexcept {
  const double x = x_mm - x0_mm, y = y_mm - y0_mm;
  const double arg = radius_mm * radius_mm - x * x - y * y;
  if (!(arg > 0)) return false;
  const double root = std::sqrt(arg);
  d->z = z0_mm + radius_mm - root;
  d->zx = x / root;
  d->zy = y / root;
  const double r3 = arg * root;
  d->zxx = (radius_mm * radius_mm - y * y) / r3;
  d->zxy = x * y / r3;
  d->zyy = (radius_mm * radius_mm - x * x) / r3;
  return true;
}

namespace {
// Sag, gradient and Hessian of any surface whose SagAndGradient is exact in jets: the jets of the gradient over
// (x, y) are the Hessian (symmetrised).
template <typename S>
bool EvaluateByJets(const S& surface, double x, double y, SurfaceDerivatives* d) noexcept {
  using Jet = ceres::Jet<double, 2>;
  Jet z, zx, zy;
  if (!surface.SagAndGradient(Jet(x, 0), Jet(y, 1), &z, &zx, &zy)) return false;
  d->z = z.a;
  d->zx = zx.a;
  d->zy = zy.a;
  d->zxx = zx.v[0];
  d->zxy = 0.5 * (zx.v[1] + zy.v[0]);
  d->zyy = zy.v[1];
  return true;
}
}  // namespace

bool Biconic::Evaluate(double x, double y, SurfaceDerivatives* d) const noexcept {
  // Eq. 12-13 are written once, in BiconicKernel (templated). The tilted surface takes its Hessian from jets of the
  // kernel's gradient (its final Newton step makes z exact to first order). The untilted one — every truth of the
  // paper sweep, whose ideal power maps sample it at 36,000 points — differentiates the kernel's gradient in closed
  // form below (the jets were 8 % of the one-thread sweep); tests/model/surface_test.cc checks it against
  // the jets and against central differences.
  if (Tilted()) return EvaluateByJets(*this, x, y, d);
  double q[BiconicKernel::kNumParams];
  BiconicKernel::FromParams(params, q);
  const BiconicKernel::Frame<double> fr = BiconicKernel::FrameOf(q);
  if (!BiconicKernel::UntiltedSag(fr, q, x, y, &d->z, &d->zx, &d->zy)) return false;
  // In the biconic's own frame (X, Y) = Rot(alpha) (x, y) - (x0, y0): zz = N / (1 + s), N = c_x X^2 + c_y Y^2,
  // s = sqrt(1 - qx X^2 - qy Y^2). From zz (1 + s) = N: zz_i = (N_i - zz s_i) / (1 + s) and
  // zz_ij = (N_ij - zz_i s_j - zz_j s_i - zz s_ij) / (1 + s), with s_X = -qx X / s, s_XX = -(qx + s_X^2) / s,
  // s_XY = -s_X s_Y / s (the kernel's expressions for zz and its gradient).
  const double cx = q[BiconicKernel::kCx], cy = q[BiconicKernel::kCy];
  const double X = fr.ca * x + fr.sa * y - q[BiconicKernel::kX0];
  const double Y = -fr.sa * x + fr.ca * y - q[BiconicKernel::kY0];
  const double s = std::sqrt(1.0 - fr.qx * X * X - fr.qy * Y * Y);
  const double den = 1.0 + s;
  const double zz = (cx * X * X + cy * Y * Y) / den;
  const double sX = -fr.qx * X / s, sY = -fr.qy * Y / s;
  const double zX = (2.0 * cx * X - zz * sX) / den, zY = (2.0 * cy * Y - zz * sY) / den;
  const double sXX = -(fr.qx + sX * sX) / s, sYY = -(fr.qy + sY * sY) / s, sXY = -sX * sY / s;
  const double zXX = (2.0 * cx - 2.0 * zX * sX - zz * sXX) / den;
  const double zYY = (2.0 * cy - 2.0 * zY * sY - zz * sYY) / den;
  const double zXY = (-zX * sY - zY * sX - zz * sXY) / den;
  // Back to (x, y): X_x = ca, X_y = sa, Y_x = -sa, Y_y = ca.
  const double ca = fr.ca, sa = fr.sa;
  d->zxx = ca * ca * zXX - 2.0 * ca * sa * zXY + sa * sa * zYY;
  d->zxy = ca * sa * (zXX - zYY) + (ca * ca - sa * sa) * zXY;
  d->zyy = sa * sa * zXX + 2.0 * ca * sa * zXY + ca * ca * zYY;
  return true;
}

double Biconic::DefinedRadiusMm() const noexcept {
  // 1 - qx X^2 - qy Y^2 > 0 on a disc of radius R about the biconic's own centre iff max(qx, qy, 0) R^2 < 1.
  const double qx = (1.0 + params.kx) / (params.rx_mm * params.rx_mm);
  const double qy = (1.0 + params.ky) / (params.ry_mm * params.ry_mm);
  const double q = std::max({qx, qy, 0.0});
  const double decentre = std::hypot(params.x0_mm, params.y0_mm);
  if (q <= 0) return std::numeric_limits<double>::infinity();
  return std::max(0.0, 1.0 / std::sqrt(q) - decentre);
}

}  // namespace topocal::model

namespace topocal::model {

Eigen::Vector3d Biconic::ApexMm() const noexcept {
  const double a = params.alpha_deg * M_PI / 180.0;
  return {std::cos(a) * params.x0_mm - std::sin(a) * params.y0_mm,
          std::sin(a) * params.x0_mm + std::cos(a) * params.y0_mm, params.z0_mm};
}

}  // namespace topocal::model

namespace topocal::model {

bool Freeform::Evaluate(double x, double y, SurfaceDerivatives* d) const noexcept {
  // Every term is analytic in its gradient; jets through the gradient give the exact Hessian.
  return EvaluateByJets(*this, x, y, d);
}

}  // namespace topocal::model

namespace topocal::model {

// The sag of every surface here moves rigidly with z0 (the tilt turns about the apex, which moves with it).
bool FocusOnAxis(Biconic* eye) noexcept {
  SurfaceDerivatives d;
  if (!eye->Evaluate(0.0, 0.0, &d)) return false;
  eye->params.z0_mm -= d.z;
  return true;
}

bool FocusOnAxis(Freeform* eye) noexcept {
  SurfaceDerivatives d;
  if (!eye->Evaluate(0.0, 0.0, &d)) return false;
  eye->base.params.z0_mm -= d.z;
  return true;
}

}  // namespace topocal::model
