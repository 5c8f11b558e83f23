#pragma once
// Corneal surfaces as sag functions z = S(x, y) in the topographer frame (mm; vertex near the origin, sag towards
// +z, i.e. away from the camera). Each surface evaluates its sag and gradient in a template usable with Ceres jets
// (so Newton solvers get exact Jacobians), and its Hessian in double (the sphere's analytic; the others' from jets of
// the gradient).
//
//  * Sphere:  rho^2 - 2 r z + z^2 = 0, the root through the vertex: z = r - sqrt(r^2 - rho^2)   (paper Eq. 4),
//    with its vertex at (x0, y0, z0): a reference ball placed anywhere in front of the camera
//  * Biconic: paper Eq. 12 with the rotation convention of docs/paper-decisions.md (surface rotated by +alpha):
//        x_r = x cos(alpha) + y sin(alpha),   y_r = -x sin(alpha) + y cos(alpha)
//        X = x_r - x0, Y = y_r - y0
//        S = z0 + (cx X^2 + cy Y^2) / (1 + sqrt(1 - Qx cx^2 X^2 - Qy cy^2 Y^2)),  c = 1/r, Q = 1 + k
//    Defined where the square root's argument is positive; outside, Sag() returns false (never NaN).
//    Optionally tilted about its vertex (the eye's rotation): BiconicKernel below.
#include <cmath>
#include <type_traits>
#include <variant>
#include <vector>

#include <Eigen/Core>

#include "model/config.h"
#include "model/freeform_terms.h"

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
    const double vertex_mm[3] = {x0_mm, y0_mm, z0_mm};
    return CapSagAndGradient(radius_mm, vertex_mm, x, y, z, zx, zy);
  }
  // Eq. 4 once: the cap facing the camera, z = z0 + r - sqrt(r^2 - (x - x0)^2 - (y - y0)^2), with the vertex of any
  // type V (the device calibration moves a reference ball's vertex in jets: model::ProjectBallSpot).
  template <typename V, typename T>
  static bool CapSagAndGradient(double radius_mm, const V* vertex_mm, const T& x, const T& y, T* z, T* zx,
                                T* zy) noexcept {
    using std::sqrt;
    const T X = x - vertex_mm[0], Y = y - vertex_mm[1];
    const T arg = T(radius_mm * radius_mm) - X * X - Y * Y;
    if (!(arg > T(0))) return false;
    const T root = sqrt(arg);
    *z = T(vertex_mm[2]) + T(radius_mm) - root;
    *zx = X / root;
    *zy = Y / root;
    return true;
  }
  bool Evaluate(double x, double y, SurfaceDerivatives* d) const noexcept;
};

// The biconic of paper Eq. 12-13, once, on a parameter vector (so that the simulation with BiconicParams and the
// least-squares fit in topo/biconic_fit.cc with Ceres jets share one definition).
//
// Parameter order (kIndex): c_x = 1/r_x, c_y = 1/r_y (1/mm), k_x, k_y, alpha (rad), x0, y0 (mm, decentration in the
// rotated frame as in Eq. 12), z0 (mm, axial vertex position), tilt_x, tilt_y (rad).
//
// Untilted surface G (Eq. 12-13):   z = z0 + (c_x X^2 + c_y Y^2) / (1 + sqrt(1 - Q_x c_x^2 X^2 - Q_y c_y^2 Y^2))
// with X = x_r - x0, Y = y_r - y0, (x_r, y_r) = (x, y) rotated by alpha, Q = 1 + k.
//
// Tilted eye: G is rotated about its vertex A = (Rot(-alpha) (x0, y0), z0) by R = Ry(tilt_y) Rx(tilt_x):
// p lies on the surface iff u = A + R^T (p - A) lies on G, i.e.  F(x, y, z) = u_z - G(u_x, u_y) = 0.
// The sag z(x, y) is the root of F near G's own sag: Newton in double to ~1e-15 mm (F_z = cos(tilt) ~ 1 for small
// tilts, 3-4 steps), then ONE Newton step in the caller's type T, which makes z exact to first order in every jet
// variable (implicit function theorem); the gradient is z_x = -F_x / F_z, z_y = -F_y / F_z. Zero tilt takes the
// untilted formula directly (bit-identical to the paper's surface). Returns false where G is undefined (the
// square root's argument is not positive) or the Newton iteration does not converge; never NaN.
struct BiconicKernel {
  enum Index : int { kCx = 0, kCy, kKx, kKy, kAlpha, kX0, kY0, kZ0, kTiltX, kTiltY, kNumParams };

  static void FromParams(const BiconicParams& p, double* q) noexcept {
    q[kCx] = 1.0 / p.rx_mm;
    q[kCy] = 1.0 / p.ry_mm;
    q[kKx] = p.kx;
    q[kKy] = p.ky;
    q[kAlpha] = p.alpha_deg * M_PI / 180.0;
    q[kX0] = p.x0_mm;
    q[kY0] = p.y0_mm;
    q[kZ0] = p.z0_mm;
    q[kTiltX] = p.tilt_x_deg * M_PI / 180.0;
    q[kTiltY] = p.tilt_y_deg * M_PI / 180.0;
  }
  static BiconicParams ToParams(const double* q) noexcept {
    BiconicParams p;
    p.rx_mm = 1.0 / q[kCx];
    p.ry_mm = 1.0 / q[kCy];
    p.kx = q[kKx];
    p.ky = q[kKy];
    p.alpha_deg = q[kAlpha] * 180.0 / M_PI;
    p.x0_mm = q[kX0];
    p.y0_mm = q[kY0];
    p.z0_mm = q[kZ0];
    p.tilt_x_deg = q[kTiltX] * 180.0 / M_PI;
    p.tilt_y_deg = q[kTiltY] * 180.0 / M_PI;
    return p;
  }

  // What G needs from the parameters alone: computed once per evaluation of the (tilted) surface rather than once
  // per Newton step (the trigonometry of a jet is the costliest part of the fit's residual).
  template <typename P>
  struct Frame {
    P ca, sa;  // cos, sin alpha
    P qx, qy;  // Q_x c_x^2, Q_y c_y^2
  };
  template <typename P>
  static Frame<P> FrameOf(const P* q) noexcept {
    using std::cos;
    using std::sin;
    return {cos(q[kAlpha]), sin(q[kAlpha]), (1.0 + q[kKx]) * q[kCx] * q[kCx], (1.0 + q[kKy]) * q[kCy] * q[kCy]};
  }

  // The rotated, decentred coordinates (X, Y) of (x, y) and 1 - Q_x c_x^2 X^2 - Q_y c_y^2 Y^2, whose square root G
  // takes: G is defined where it is positive.
  template <typename T, typename P>
  static T SquareRootArgument(const Frame<P>& fr, const P* q, const T& x, const T& y, T* X, T* Y) noexcept {
    *X = fr.ca * x + fr.sa * y - q[kX0];
    *Y = -fr.sa * x + fr.ca * y - q[kY0];
    return 1.0 - fr.qx * *X * *X - fr.qy * *Y * *Y;
  }

  // Eq. 12-13 without tilt: sag and gradient of G at (x, y).
  template <typename T, typename P>
  static bool UntiltedSag(const P* q, const T& x, const T& y, T* z, T* zx, T* zy) noexcept {
    return UntiltedSag(FrameOf(q), q, x, y, z, zx, zy);
  }
  // The same with the frame given; zx == nullptr: the sag alone.
  template <typename T, typename P>
  static bool UntiltedSag(const Frame<P>& fr, const P* q, const T& x, const T& y, T* z, T* zx, T* zy) noexcept {
    using std::sqrt;
    const P& ca = fr.ca;
    const P& sa = fr.sa;
    const P& qx = fr.qx;
    const P& qy = fr.qy;
    T X, Y;
    const T s2 = SquareRootArgument(fr, q, x, y, &X, &Y);
    if (!(ScalarPart(s2) > 0.0)) return false;
    const T s = sqrt(s2);
    const T den = 1.0 + s;
    const T zz = (q[kCx] * X * X + q[kCy] * Y * Y) / den;
    *z = q[kZ0] + zz;
    if (!zx) return true;
    // z * den = num  =>  z_X = (num_X - z s_X) / den, with s_X = -qx X / s
    const T zX = (2.0 * q[kCx] * X + zz * qx * X / s) / den;
    const T zY = (2.0 * q[kCy] * Y + zz * qy * Y / s) / den;
    *zx = ca * zX - sa * zY;
    *zy = sa * zX + ca * zY;
    return true;
  }

  // Sag and gradient of the (possibly tilted) surface in the instrument frame. T: type of (x, y) and of the
  // result; P: type of the parameters (double for simulation, a jet in the fit). Mixed double/jet arithmetic
  // resolves to the jet type.
  template <typename T, typename P>
  static bool SagAndGradient(const P* q, const T& x, const T& y, T* z, T* zx, T* zy, bool tilted) noexcept {
    return Evaluate(q, x, y, z, zx, zy, tilted);
  }
  // The sag alone (the fit's residual): the same z as SagAndGradient, bit for bit, without the gradient's work.
  template <typename T, typename P>
  static bool Sag(const P* q, const T& x, const T& y, T* z, bool tilted) noexcept {
    return Evaluate(q, x, y, z, static_cast<T*>(nullptr), static_cast<T*>(nullptr), tilted);
  }

  // The tilt of the eye about its apex A = (Rot(-alpha) (x0, y0), z0): a point p of the instrument frame is
  // u = A + M (p - A) in G's own frame, M = R^T with R = Ry(tilt_y) Rx(tilt_x).
  template <typename P>
  struct Tilt {
    P m[3][3];
    P apex[3];
  };
  template <typename P>
  static Tilt<P> TiltOf(const Frame<P>& fr, const P* q) noexcept {
    using std::cos;
    using std::sin;
    const P cx = cos(q[kTiltX]), sx = sin(q[kTiltX]), cy = cos(q[kTiltY]), sy = sin(q[kTiltY]);
    return {{{cy, P(0.0), -sy}, {sx * sy, cx, sx * cy}, {cx * sy, -sx, cx * cy}},
            {fr.ca * q[kX0] - fr.sa * q[kY0], fr.sa * q[kX0] + fr.ca * q[kY0], q[kZ0]}};
  }
  // u = A + M (p - A).
  template <typename V, typename P>
  static void ToUntilted(const Tilt<P>& t, const V& x, const V& y, const V& z, V* u) noexcept {
    const V dx = x - t.apex[0], dy = y - t.apex[1], dz = z - t.apex[2];
    for (int i = 0; i < 3; ++i) u[i] = t.apex[i] + t.m[i][0] * dx + t.m[i][1] * dy + t.m[i][2] * dz;
  }
  // F(p) = u_z - G(u_x, u_y), whose root in z is the tilted sag, and its partials fp = (F_x, F_y, F_z); fp == nullptr:
  // only whether G is defined at u (F is not computed either). False where G is undefined.
  template <typename V, typename P>
  static bool TiltedResidual(const Frame<P>& fr, const P* q, const Tilt<P>& t, const V& x, const V& y, const V& z, V* f,
                             V* fp) noexcept {
    V u[3];
    ToUntilted(t, x, y, z, u);
    V g, gx, gy;
    if (!fp) {
      // UntiltedSag's own test, without computing the sag (a square root and a division) only to discard it.
      V X, Y;
      return ScalarPart(SquareRootArgument(fr, q, u[0], u[1], &X, &Y)) > 0.0;
    }
    if (!UntiltedSag(fr, q, u[0], u[1], &g, &gx, &gy)) return false;
    *f = u[2] - g;
    for (int j = 0; j < 3; ++j) fp[j] = t.m[2][j] - gx * t.m[0][j] - gy * t.m[1][j];
    return true;
  }

  // Newton in double for the root of F on the line along z through (x, y), from *z (the start) until a step is
  // below step_tolerance_mm; *z is then the point after that step. 20 steps at most: from G's own sag Newton
  // converges in 3-4 for tilts below 30 deg. False where G is undefined on the way, the line grazes the tilted
  // surface or the iteration does not converge (*z is then unspecified).
  static bool TiltedRoot(const Frame<double>& fr, const double* q, const Tilt<double>& tilt, double x, double y,
                         double step_tolerance_mm, double* z) noexcept {
    constexpr int kMaxNewton = 20;
    double zd = *z;
    for (int it = 0; it < kMaxNewton; ++it) {
      double f, fp[3];
      if (!TiltedResidual(fr, q, tilt, x, y, zd, &f, fp)) return false;
      if (!(std::abs(fp[2]) > 1e-6)) return false;  // the ray along z grazes the tilted surface
      const double step = f / fp[2];
      zd -= step;
      if (!std::isfinite(zd)) return false;
      if (std::abs(step) < step_tolerance_mm) {
        *z = zd;
        return true;
      }
    }
    return false;
  }

  // The tilted sag z(x, y): the root of F near G's own sag (see above), the one implementation of the kernel and of
  // the fit's closed-form Jacobian (topo/biconic_jacobian.cc). Newton in double on the scalar parts (fr_d, q_d,
  // tilt_d: the scalar parts of fr, q, tilt), then one Newton step in T; the gradient when zx != nullptr.
  template <typename T, typename P>
  static bool TiltedSag(const Frame<P>& fr, const P* q, const Tilt<P>& tilt, const Frame<double>& fr_d,
                        const double* q_d, const Tilt<double>& tilt_d, const T& x, const T& y, T* z, T* zx,
                        T* zy) noexcept {
    using R = decltype(T(0) * P(0));
    const double xd = ScalarPart(x), yd = ScalarPart(y);
    double zd;
    if (!UntiltedSag(fr_d, q_d, xd, yd, &zd, static_cast<double*>(nullptr), static_cast<double*>(nullptr))) {
      return false;
    }
    // 1e-14 mm: the double floor of a sag of ~1 mm.
    constexpr double kSagToleranceMm = 1e-14;
    if (!TiltedRoot(fr_d, q_d, tilt_d, xd, yd, kSagToleranceMm, &zd)) return false;
    // One Newton step in the full type: exact first derivatives in every jet variable.
    R zr = R(zd), f, fp[3];
    if (!TiltedResidual(fr, q, tilt, R(x), R(y), zr, &f, fp)) return false;
    zr = zr - f / fp[2];
    if (!zx) {
      // The sag alone: the second evaluation below only serves the gradient, apart from its check that G is defined
      // at the corrected point. That check reads scalar parts only, which a jet computes with the same double
      // operations: done in double, it accepts and rejects exactly as before.
      if (!TiltedResidual(fr_d, q_d, tilt_d, xd, yd, ScalarPart(zr), static_cast<double*>(nullptr),
                          static_cast<double*>(nullptr))) {
        return false;
      }
      *z = zr;
      return true;
    }
    if (!TiltedResidual(fr, q, tilt, R(x), R(y), zr, &f, fp)) return false;
    *z = zr;
    *zx = -fp[0] / fp[2];
    *zy = -fp[1] / fp[2];
    return true;
  }

 private:
  template <typename T, typename P>
  static bool Evaluate(const P* q, const T& x, const T& y, T* z, T* zx, T* zy, bool tilted) noexcept {
    const Frame<P> fr = FrameOf(q);
    if (!tilted) return UntiltedSag(fr, q, x, y, z, zx, zy);
    const Tilt<P> tilt = TiltOf(fr, q);
    if constexpr (std::is_same_v<P, double>) return TiltedSag(fr, q, tilt, fr, q, tilt, x, y, z, zx, zy);
    double q_d[kNumParams];
    for (int i = 0; i < kNumParams; ++i) q_d[i] = ScalarPart(q[i]);
    const Frame<double> fr_d = FrameOf(q_d);
    Tilt<double> tilt_d;
    for (int i = 0; i < 3; ++i) {
      tilt_d.apex[i] = ScalarPart(tilt.apex[i]);
      for (int j = 0; j < 3; ++j) tilt_d.m[i][j] = ScalarPart(tilt.m[i][j]);
    }
    return TiltedSag(fr, q, tilt, fr_d, q_d, tilt_d, x, y, z, zx, zy);
  }
};

struct Biconic {
  BiconicParams params;

  bool Tilted() const noexcept { return params.tilt_x_deg != 0.0 || params.tilt_y_deg != 0.0; }
  template <typename T>
  bool SagAndGradient(const T& x, const T& y, T* z, T* zx, T* zy) const noexcept {
    double q[BiconicKernel::kNumParams];
    BiconicKernel::FromParams(params, q);
    return BiconicKernel::SagAndGradient(q, x, y, z, zx, zy, Tilted());
  }
  bool Evaluate(double x, double y, SurfaceDerivatives* d) const noexcept;
  // Radius of the largest disc about the z axis on which the biconic is defined (infinite for oblate-free cases).
  double DefinedRadiusMm() const noexcept;
  // The apex (vertex) in the instrument frame: (Rot(-alpha) (x0, y0), z0).
  Eigen::Vector3d ApexMm() const noexcept;
};

// A freeform cornea (topocal's freeform test set): a biconic base (possibly off the axis and tilted) plus local
// departures added along z in the instrument frame — keratoconus cones, refractive ablations, Zernike irregularity
// (model/freeform_terms.h). Sag and gradient analytic (the base's Newton root when tilted); Hessian from jets.
struct Freeform {
  Biconic base;
  std::vector<GaussianCone> cones;
  std::vector<Ablation> ablations;
  std::vector<ZernikeTerm> zernike;

  template <typename T>
  bool SagAndGradient(const T& x, const T& y, T* z, T* zx, T* zy) const noexcept {
    if (!base.SagAndGradient(x, y, z, zx, zy)) return false;
    for (const auto& c : cones) c.Add(x, y, z, zx, zy);
    for (const auto& a : ablations) a.Add(x, y, z, zx, zy);
    for (const auto& t : zernike) t.Add(x, y, z, zx, zy);
    return true;
  }
  bool Evaluate(double x, double y, SurfaceDerivatives* d) const noexcept;
};

using Surface = std::variant<Sphere, Biconic, Freeform>;

// The eye as a topographer positions it: focused so that the corneal point ON THE INSTRUMENT AXIS sits at the
// working distance, z(0, 0) = 0 (what the reconstruction assumes, Psi(0, 0) = t: one camera and one screen do not
// observe the vertex height, docs/reconstruction.md). For an eye off the axis or tilted that point is not the apex:
// the surface is moved along z (z0 changed) until it passes through the origin. Returns false where the surface
// is undefined at the origin.
bool FocusOnAxis(Biconic* eye) noexcept;
bool FocusOnAxis(Freeform* eye) noexcept;

inline bool EvaluateSurface(const Surface& s, double x, double y, SurfaceDerivatives* d) noexcept {
  return std::visit([&](const auto& surf) { return surf.Evaluate(x, y, d); }, s);
}

// Unit normal (-S_x, -S_y, 1)/norm of paper Eq. 14c.
inline Eigen::Vector3d SurfaceNormal(double zx, double zy) noexcept {
  return Eigen::Vector3d(-zx, -zy, 1.0).normalized();
}

}  // namespace topocal::model
