#pragma once
// Local departures added to a base cornea to make the freeform truth surfaces of topocal's test set (keratoconus cones,
// refractive ablations, irregular astigmatism). Each is a sag term dz(x, y) in mm in the instrument frame, with its
// gradient, templated so that Ceres jets (and therefore Newton solvers and exact Hessians) go through it.
// All three are smooth (C-infinity, or C2 for the ablation's blend) and analytic; none returns false.
#include <cmath>
#include <type_traits>
#include <vector>

#include "model/keratometry.h"

namespace topocal::model {

// Scalar part of a double or a Ceres jet (for branches and for Newton iterations in double).
template <typename T>
double ScalarPart(const T& v) noexcept {
  if constexpr (std::is_arithmetic_v<T>) {
    return static_cast<double>(v);
  } else {
    return v.a;
  }
}

// Keratoconus cone: a Gaussian protrusion towards the camera (the cornea bulges forward, i.e. towards -z):
//   dz = -height * exp(-|p - c|^2 / (2 sigma^2)).
struct GaussianCone {
  double height_um = 10.0;  // > 0: protrusion
  double sigma_mm = 1.0;
  double x_mm = 0.0, y_mm = 0.0;

  template <typename T>
  void Add(const T& x, const T& y, T* z, T* zx, T* zy) const noexcept {
    using std::exp;
    const T dx = x - x_mm, dy = y - y_mm;
    const double s2 = sigma_mm * sigma_mm;
    const T g = -height_um * 1e-3 * exp(-(dx * dx + dy * dy) / (2.0 * s2));
    *z += g;
    *zx += -g * dx / s2;
    *zy += -g * dy / s2;
  }
};

// Refractive ablation: a change of vertex curvature dc = power_change_D / ((n_k - 1) 1000) (keratometric index
// n_k = 1.3375) inside the optical zone, blended smoothly to nothing. Radially, with r = |p - c|, R = zone_mm / 2,
// w = blend_mm and the quintic smoothstep s(t) = 6t^5 - 15t^4 + 10t^3 (C2):
//   dz'(r) = dc r (1 - s((r - R) / w)),   dz(0) = 0,
// integrated in closed form: dz = dc r^2 / 2 inside R, dz = dc [r^2/2 - w (R S1(t) + w S2(t))] in the blend with
// S1 = t^6 - 3t^5 + 5t^4/2, S2 = 6t^7/7 - 5t^6/2 + 2t^5, constant beyond R + w. Myopic: power_change_D < 0 (flatter
// centre), hyperopic > 0.
struct Ablation {
  double power_change_D = -3.0;
  double zone_mm = 6.0;
  double blend_mm = 1.0;
  double x_mm = 0.0, y_mm = 0.0;

  template <typename T>
  void Add(const T& x, const T& y, T* z, T* zx, T* zy) const noexcept {
    using std::sqrt;
    const double dc = CurvatureFromPowerPerMm(power_change_D);  // Eq. 25 inverted
    const double R = 0.5 * zone_mm, w = blend_mm;
    const T dx = x - x_mm, dy = y - y_mm;
    const T r2 = dx * dx + dy * dy;
    const auto S1 = [](double t) { return t * t * t * t * (t * t - 3.0 * t + 2.5); };
    const auto S2 = [](double t) { return t * t * t * t * t * (6.0 / 7.0 * t * t - 2.5 * t + 2.0); };
    const double r_scalar = std::sqrt(ScalarPart(r2));
    if (r_scalar <= R) {
      *z += 0.5 * dc * r2;
      *zx += dc * dx;
      *zy += dc * dy;
      return;
    }
    if (r_scalar >= R + w) {
      *z += dc * (0.5 * (R + w) * (R + w) - w * (R * S1(1.0) + w * S2(1.0)));
      return;
    }
    const T r = sqrt(r2);  // r > R > 0 here: no singularity
    const T t = (r - R) / w;
    const T t3 = t * t * t;
    const T s = t3 * (6.0 * t * t - 15.0 * t + 10.0);
    const T t4 = t3 * t, t5 = t4 * t;
    const T s1 = t4 * (t * t - 3.0 * t + 2.5);
    const T s2 = t5 * (6.0 / 7.0 * t * t - 2.5 * t + 2.0);
    *z += dc * (0.5 * r2 - w * (R * s1 + w * s2));
    const T radial = dc * (1.0 - s);  // dz'(r) / r
    *zx += radial * dx;
    *zy += radial * dy;
  }

};

// One Zernike term (OSA/ANSI: n radial order, m azimuthal frequency, m >= 0 cosine, m < 0 sine; unnormalised,
// i.e. the coefficient is the term's value at rho = 1 along its peak meridian) on the disc of radius radius_mm
// about (x_mm, y_mm); used as a polynomial in (x, y) everywhere (no disc cut-off):
//   Z = R_n^|m|(rho) * {cos, sin}(|m| theta),  R_n^m = sum_s (-1)^s (n-s)! / (s! ((n+m)/2-s)! ((n-m)/2-s)!) rho^(n-2s)
// evaluated as Re/Im((u + i v)^|m|) (u^2 + v^2)^((n - 2s - |m|)/2) with (u, v) = (p - c) / radius: smooth at rho = 0.
struct ZernikeTerm {
  int n = 3, m = 1;
  double coefficient_um = 1.0;
  double radius_mm = 4.0;
  double x_mm = 0.0, y_mm = 0.0;

  template <typename T>
  void Add(const T& x, const T& y, T* z, T* zx, T* zy) const noexcept {
    const int am = m < 0 ? -m : m;
    const T u = (x - x_mm) / radius_mm, v = (y - y_mm) / radius_mm;
    // (u + i v)^am and its derivatives: d/du = am (u + i v)^(am - 1), d/dv = i am (u + i v)^(am - 1).
    T re = T(1.0), im = T(0.0), re1 = T(1.0), im1 = T(0.0);  // power am and am - 1
    for (int k = 0; k < am; ++k) {
      re1 = re;
      im1 = im;
      const T nre = re * u - im * v;
      im = re * v + im * u;
      re = nre;
    }
    const T ang = m < 0 ? im : re;
    // d(ang)/du, d(ang)/dv
    const T ang_u = am == 0 ? T(0.0) : (m < 0 ? double(am) * im1 : double(am) * re1);
    const T ang_v = am == 0 ? T(0.0) : (m < 0 ? double(am) * re1 : -double(am) * im1);
    const T r2 = u * u + v * v;
    T radial = T(0.0), radial_r2 = T(0.0);  // sum c_s r2^j and its derivative in r2
    for (int s = 0; s <= (n - am) / 2; ++s) {
      const int j = (n - 2 * s - am) / 2;
      const double c = (s % 2 ? -1.0 : 1.0) * Factorial(n - s) /
                       (Factorial(s) * Factorial((n + am) / 2 - s) * Factorial((n - am) / 2 - s));
      T p = T(1.0);
      for (int k = 0; k < j - 1; ++k) p = p * r2;  // r2^(j-1)
      if (j >= 1) {
        radial = radial + c * p * r2;
        radial_r2 = radial_r2 + c * double(j) * p;
      } else {
        radial = radial + c;
      }
    }
    const double a = coefficient_um * 1e-3;
    *z += a * radial * ang;
    // d/du [radial(r2) ang] = radial' 2u ang + radial ang_u; chain 1/radius for x.
    *zx += a * (radial_r2 * 2.0 * u * ang + radial * ang_u) / radius_mm;
    *zy += a * (radial_r2 * 2.0 * v * ang + radial * ang_v) / radius_mm;
  }

 private:
  static double Factorial(int k) noexcept {
    double f = 1;
    for (int i = 2; i <= k; ++i) f *= i;
    return f;
  }
};

}  // namespace topocal::model
