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
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

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

// The pinhole and the planes of the topographer.
struct Topographer {
  TopographerParams p;
  Eigen::Vector3d Pinhole() const { return {0.0, 0.0, -p.b_mm}; }
  // Direction of the ray from a detection-plane point through the pinhole (Eq. 3).
  Eigen::Vector3d IncidentDirection(const Eigen::Vector2d& image_mm) const {
    return Eigen::Vector3d(-image_mm.x(), -image_mm.y(), p.a_mm).normalized();
  }
  // Detection-plane point of a ray leaving the pinhole in direction d (Eq. 16).
  Eigen::Vector2d ImagePoint(const Eigen::Vector3d& d) const {
    return {-p.a_mm * d.x() / d.z(), -p.a_mm * d.y() / d.z()};
  }
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

// Reflection point of one target: the point P2 on the surface where the law of reflection sends the ray from
// target_mm through the pinhole. Newton on Eq. 15 from `initial_xy_mm`; nullopt if it fails or leaves the surface.
std::optional<Eigen::Vector3d> SolveReflectionPoint(const Surface& surface, const Topographer& topographer,
                                                    const Eigen::Vector3d& target_mm,
                                                    const Eigen::Vector2d& initial_xy_mm);

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
