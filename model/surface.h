#pragma once
// Corneal surfaces as sag functions z = S(x, y) in the topographer frame (mm; vertex near the origin, sag towards
// +z, i.e. away from the camera). Each surface evaluates its sag and gradient in a template usable with Ceres jets
// (so Newton solvers get exact Jacobians), and its analytic Hessian in double.
//
//  * Sphere:  rho^2 - 2 r z + z^2 = 0, the root through the vertex: z = r - sqrt(r^2 - rho^2)   (paper Eq. 4),
//    with its vertex at (x0, y0, z0): a reference ball placed anywhere in front of the camera
//  * Biconic: paper Eq. 12 with the rotation convention of docs/paper-decisions.md (surface rotated by +alpha):
//        x_r = x cos(alpha) + y sin(alpha),   y_r = -x sin(alpha) + y cos(alpha)
//        X = x_r - x0, Y = y_r - y0
//        S = z0 + (cx X^2 + cy Y^2) / (1 + sqrt(1 - Qx cx^2 X^2 - Qy cy^2 Y^2)),  c = 1/r, Q = 1 + k
//    Defined where the square root's argument is positive; outside, Sag() returns false (never NaN).
#include <cmath>
#include <variant>

#include <Eigen/Core>

#include "model/config.h"

namespace topocal::model {

struct SurfaceDerivatives {
  double z = 0, zx = 0, zy = 0;        // sag and gradient
  double zxx = 0, zxy = 0, zyy = 0;    // Hessian
};

struct Sphere {
  double radius_mm = 7.8;
  double z0_mm = 0.0;  // axial position of the vertex
  double x0_mm = 0.0;  // lateral position of the vertex (and of the centre)
  double y0_mm = 0.0;

  template <typename T>
  bool SagAndGradient(const T& x, const T& y, T* z, T* zx, T* zy) const noexcept {
    using std::sqrt;
    const T X = x - x0_mm, Y = y - y0_mm;
    const T arg = T(radius_mm * radius_mm) - X * X - Y * Y;
    if (!(arg > T(0))) return false;
    const T root = sqrt(arg);
    *z = T(z0_mm) + T(radius_mm) - root;
    *zx = X / root;
    *zy = Y / root;
    return true;
  }
  bool Evaluate(double x, double y, SurfaceDerivatives* d) const noexcept;
};

struct Biconic {
  BiconicParams params;

  template <typename T>
  bool SagAndGradient(const T& x, const T& y, T* z, T* zx, T* zy) const noexcept {
    using std::sqrt;
    const double ca = std::cos(params.alpha_deg * M_PI / 180.0), sa = std::sin(params.alpha_deg * M_PI / 180.0);
    const double cx = 1.0 / params.rx_mm, cy = 1.0 / params.ry_mm;
    const double qx = (1.0 + params.kx) * cx * cx, qy = (1.0 + params.ky) * cy * cy;
    const T X = ca * x + sa * y - params.x0_mm;
    const T Y = -sa * x + ca * y - params.y0_mm;
    const T s2 = T(1) - qx * X * X - qy * Y * Y;
    if (!(s2 > T(0))) return false;
    const T s = sqrt(s2);
    const T den = T(1) + s;
    const T num = cx * X * X + cy * Y * Y;
    const T zz = num / den;
    // z * den = num  =>  z_X = (num_X - z s_X) / den, with s_X = -qx X / s
    const T zX = (2.0 * cx * X + zz * qx * X / s) / den;
    const T zY = (2.0 * cy * Y + zz * qy * Y / s) / den;
    *z = T(params.z0_mm) + zz;
    *zx = ca * zX - sa * zY;
    *zy = sa * zX + ca * zY;
    return true;
  }
  bool Evaluate(double x, double y, SurfaceDerivatives* d) const noexcept;
  // Radius of the largest disc about the z axis on which the biconic is defined (infinite for oblate-free cases).
  double DefinedRadiusMm() const noexcept;
};

using Surface = std::variant<Sphere, Biconic>;

inline bool EvaluateSurface(const Surface& s, double x, double y, SurfaceDerivatives* d) noexcept {
  return std::visit([&](const auto& surf) { return surf.Evaluate(x, y, d); }, s);
}

// Unit normal (-S_x, -S_y, 1)/norm of paper Eq. 14c.
inline Eigen::Vector3d SurfaceNormal(double zx, double zy) noexcept {
  return Eigen::Vector3d(-zx, -zy, 1.0).normalized();
}

}  // namespace topocal::model
