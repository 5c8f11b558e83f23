#pragma once
// The null screen: ideal image (paper Eq. 1-2), exact backward ray trace pinhole -> reference sphere -> cone
// (Eq. 3-11), and the synthetic image of any surface (Eq. 14-16).
//
//          detection plane        pinhole              cornea (vertex at O)
//   z:       -a-b                  -b                    0 --> +z (sag)
//             |                     .                   (
//   P1 -------|------ I ----------> h ---------------> P2  reflects to R ---> P3 on the cone
//
// The cone (semi-angle phi_c, vertex at z_c < -b) is x^2 + y^2 = tan^2(phi_c) (z - z_c)^2, z > z_c.
// A spot is identified by (ring i = 1..N+1, index j = 0..eta0+(i-1)eta-1); its ideal position is
//   rho_i = rho0 + (i-1)(rhoN - rho0)/N,  theta_ij = 2 pi j / (eta0 + (i-1) eta),
//   (x1, y1) = rho_i (cos theta_ij, sin theta_ij)      (Eq. 1 with the sin of the paper README, item 1)
#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <ceres/jet.h>

#include "model/config.h"
#include "model/surface.h"

namespace topocal::model {

struct SpotId {
  int ring = 0;   // 1..N+1
  int index = 0;  // 0..eta0+(ring-1)*eta-1
  friend bool operator==(const SpotId&, const SpotId&) = default;
  friend auto operator<=>(const SpotId&, const SpotId&) = default;
};

struct IdealSpot {
  SpotId id;
  Eigen::Vector2d position_mm;  // on the detection plane
};

std::vector<IdealSpot> IdealImage(const IdealImageParams& p);

// Eq. 2a: radius rho_i of ring i = 1..N+1 of the ideal image, mm.
inline double RingRadiusMm(const IdealImageParams& p, int ring) noexcept {
  return p.rho0_mm + (ring - 1) * (p.rhoN_mm - p.rho0_mm) / p.rings_N;
}
// Eq. 2a's step between neighbouring rings, (rhoN - rho0) / N, mm; with a single ring (N = 0, which the configuration
// reader refuses but the spot indexer tolerates) its radius rho0.
inline double RingStepMm(const IdealImageParams& p) noexcept {
  return p.rings_N > 0 ? (p.rhoN_mm - p.rho0_mm) / p.rings_N : p.rho0_mm;
}
// Eq. 2b: the number of spots on ring i, eta0 + (i - 1) eta.
inline int SpotsOnRing(const IdealImageParams& p, int ring) noexcept { return p.eta0 + (ring - 1) * p.eta; }

// Eq. 14a + 16: the point of the detection plane z = -a - b (undistorted, mm) at which the pinhole h = (0, 0, -b)
// images the point p: the incident direction I = (p - h) / |p - h| (Eq. 14a) continued through h meets the plane at
// -a (I_x, I_y) / I_z (Eq. 16). |p - h| cancels, so I is not normalised. Templated for the device fit's jets
// (model::ProjectBallSpot); the synthetic image (SynthesizeImage) and the spot truth (correct/spot_truth.cc) call it
// through Topographer::ImageOf.
template <typename T>
void ImageOfPoint(const T& a_mm, double b_mm, const T* point_mm, T* image_mm) noexcept {
  const T depth = point_mm[2] + b_mm;  // I_z |p - h|
  image_mm[0] = -a_mm * point_mm[0] / depth;
  image_mm[1] = -a_mm * point_mm[1] / depth;
}

// The pinhole and the planes of the topographer.
struct Topographer {
  TopographerParams p;
  Eigen::Vector3d Pinhole() const { return {0.0, 0.0, -p.b_mm}; }
  // Direction of the ray from a detection-plane point through the pinhole (Eq. 3).
  Eigen::Vector3d IncidentDirection(const Eigen::Vector2d& image_mm) const {
    return Eigen::Vector3d(-image_mm.x(), -image_mm.y(), p.a_mm).normalized();
  }
  // Detection-plane point at which the pinhole images the point p (Eq. 14a + 16: ImageOfPoint).
  Eigen::Vector2d ImageOf(const Eigen::Vector3d& point_mm) const;
  // Intersection of the ray from the pinhole in direction d with the reference sphere (nearest root).
  std::optional<Eigen::Vector3d> HitReferenceSphere(const Eigen::Vector3d& d, double offset_mm = 0.0) const;
  // First intersection of the ray origin + s dir (s > 0) with the cone, on its nappe z > z_c.
  std::optional<Eigen::Vector3d> HitCone(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir) const;
};

// A designed null-screen point: the target on the cone that images onto the ideal spot via the reference sphere.
struct TargetPoint {
  SpotId id;
  Eigen::Vector2d ideal_mm;       // P1 on the detection plane
  Eigen::Vector3d on_sphere_mm;   // P2 on the reference sphere
  Eigen::Vector3d on_cone_mm;     // P3 on the cone
};

struct SpotFailure {
  SpotId id;
  std::string reason;
};

struct NullScreenDesign {
  std::vector<TargetPoint> targets;
  std::vector<SpotFailure> failures;  // ideal spots whose backward ray missed the sphere or the cone
};

NullScreenDesign DesignNullScreen(const IdealImageParams& ideal, const TopographerParams& topographer);

// The backward trace of one ideal-image point (Eq. 3 through the pinhole, Eq. 5-7 onto the reference sphere, Eq. 8
// reflected, Eq. 9-11 onto the cone): the one implementation DesignNullScreen, the printable screen's outlines and
// the spot-shape ground truth all use. On failure *why (if given) says which step missed.
std::optional<TargetPoint> TraceIdealPoint(const Topographer& topographer, const Eigen::Vector2d& ideal_mm,
                                           std::string* why = nullptr);

// The law of reflection at a surface point (x, y, S(x, y)) for a ray from the pinhole h to the target p3 (paper
// Eq. 15): f = (R - I) + (R_z - I_z) grad S with I, R the unit incident and reflected directions; zero at the
// reflection point. `sag` is any callable sag(x, y, &z, &zx, &zy) -> bool; every argument may be a Ceres jet, so the
// same residual serves the Newton solve below and the device calibration's autodiff (calib/device_fit.h).
template <typename T, typename Sag>
bool ReflectionResidual(const Sag& sag, const T* h, const T* p3, const T& x, const T& y, T* f) {
  T z, zx, zy;
  if (!sag(x, y, &z, &zx, &zy)) return false;
  using std::sqrt;
  const T ix = x - h[0], iy = y - h[1], iz = z - h[2];
  const T in = sqrt(ix * ix + iy * iy + iz * iz);
  const T rx = p3[0] - x, ry = p3[1] - y, rz = p3[2] - z;
  const T rn = sqrt(rx * rx + ry * ry + rz * rz);
  const T dz = rz / rn - iz / in;
  f[0] = (rx / rn - ix / in) + dz * zx;
  f[1] = (ry / rn - iy / in) + dz * zy;
  return true;
}

// Reflection point of one target: the point P2 on the surface where the law of reflection sends the ray from
// target_mm through the pinhole. Newton on Eq. 15 from `initial_xy_mm`; nullopt if it fails or leaves the surface.
std::optional<Eigen::Vector3d> SolveReflectionPoint(const Surface& surface, const Topographer& topographer,
                                                    const Eigen::Vector3d& target_mm,
                                                    const Eigen::Vector2d& initial_xy_mm);
// The same Newton solve for any sag callable (see ReflectionResidual) and any pinhole position.
template <typename Sag>
std::optional<Eigen::Vector3d> SolveReflectionPointOn(const Sag& sag, const Eigen::Vector3d& pinhole_mm,
                                                      const Eigen::Vector3d& target_mm,
                                                      const Eigen::Vector2d& initial_xy_mm) {
  // Newton's method on the 2x2 system of Eq. 15 with a jet Jacobian. Written by hand rather than with a
  // ceres::Problem because it runs once per spot per image (624 x sweeps) and converges in ~5 steps from the
  // designed point; the solver set-up would dominate. Convergence: |step| below 1e-13 mm (double floor at ~5 mm).
  constexpr double kStepToleranceMm = 1e-13;
  constexpr int kMaxIterations = 60;
  using Jet = ceres::Jet<double, 2>;
  const Jet h[3] = {Jet(pinhole_mm.x()), Jet(pinhole_mm.y()), Jet(pinhole_mm.z())};
  const Jet p3[3] = {Jet(target_mm.x()), Jet(target_mm.y()), Jet(target_mm.z())};
  double x = initial_xy_mm.x(), y = initial_xy_mm.y();
  for (int it = 0; it < kMaxIterations; ++it) {
    Jet f[2];
    if (!ReflectionResidual(sag, h, p3, Jet(x, 0), Jet(y, 1), f)) return std::nullopt;
    const double det = f[0].v[0] * f[1].v[1] - f[0].v[1] * f[1].v[0];
    if (!(std::abs(det) > 0)) return std::nullopt;
    double dx = (f[1].v[1] * f[0].a - f[0].v[1] * f[1].a) / det;
    double dy = (-f[1].v[0] * f[0].a + f[0].v[0] * f[1].a) / det;
    // Damp steps larger than 1 mm: far from the solution the quadratic model is poor.
    const double step = std::hypot(dx, dy);
    if (step > 1.0) {
      dx /= step;
      dy /= step;
    }
    x -= dx;
    y -= dy;
    if (!std::isfinite(x) || !std::isfinite(y)) return std::nullopt;
    if (step < kStepToleranceMm) {
      double z, zx, zy;
      if (!sag(x, y, &z, &zx, &zy)) return std::nullopt;
      const Eigen::Vector3d p2(x, y, z);
      // The physical solution faces the camera: the incident ray travels towards +z and hits the front of the surface.
      if (!(p2.z() > pinhole_mm.z())) return std::nullopt;
      return p2;
    }
  }
  return std::nullopt;
}

// An identified spot on the detection plane: its identity and position (mm). The one record of a spot from detection
// (distorted, as the camera recorded it) through undistortion to reconstruction, and a spots CSV's row; whether the
// position is distorted is its container's to say.
struct PlaneSpot {
  SpotId id;
  Eigen::Vector2d position_mm = Eigen::Vector2d::Zero();
};

// The identities and positions of any spot records that carry them (a synthetic image's, a detection's).
template <typename Spots>
std::vector<PlaneSpot> PlaneSpotsOf(const Spots& spots) {
  std::vector<PlaneSpot> out;
  out.reserve(spots.size());
  for (const auto& s : spots) out.push_back({s.id, s.position_mm});
  return out;
}

struct ImageSpot {
  SpotId id;
  Eigen::Vector2d position_mm;    // on the detection plane (undistorted)
  Eigen::Vector3d on_surface_mm;  // incidence point P2
};

struct SyntheticImage {
  std::vector<ImageSpot> spots;
  std::vector<SpotFailure> failures;  // every target whose spot could not be formed, by identity
};

SyntheticImage SynthesizeImage(const Surface& surface, const Topographer& topographer,
                               const std::vector<TargetPoint>& targets);

}  // namespace topocal::model
