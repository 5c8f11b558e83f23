#include "model/surface.h"

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
  // Eq. 12-13 are written once, in BiconicKernel (templated); its gradient in jets carries the exact Hessian, tilted
  // or not (the tilted kernel's final Newton step makes z exact to first order). A second, hand-derived Hessian
  // formula here is not worth its upkeep: Evaluate serves the truth's power maps and height differences (a few
  // 10^4 points per analysis), not an inner loop.
  return EvaluateByJets(*this, x, y, d);
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
