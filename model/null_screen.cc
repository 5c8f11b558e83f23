#include "model/null_screen.h"

#include <cmath>

#include <ceres/jet.h>
#include <fmt/format.h>

namespace topocal::model {

std::vector<IdealSpot> IdealImage(const IdealImageParams& p) {
  std::vector<IdealSpot> spots;
  spots.reserve(p.SpotCount());
  for (int i = 1; i <= p.rings_N + 1; ++i) {
    const double rho = RingRadiusMm(p, i);
    const int n = SpotsOnRing(p, i);
    for (int j = 0; j < n; ++j) {
      const double theta = 2.0 * M_PI * j / n;
      spots.push_back({SpotId{i, j}, Eigen::Vector2d(rho * std::cos(theta), rho * std::sin(theta))});
    }
  }
  return spots;
}

Eigen::Vector2d Topographer::ImageOf(const Eigen::Vector3d& point_mm) const {
  Eigen::Vector2d image_mm;
  ImageOfPoint(p.a_mm, p.b_mm, point_mm.data(), image_mm.data());
  return image_mm;
}

std::optional<Eigen::Vector3d> Topographer::HitReferenceSphere(const Eigen::Vector3d& d, double offset_mm) const {
  // |h + xi d - c|^2 = r^2 with c = (0, 0, r + offset), h = (0, 0, -b):  xi^2 + 2 xi d.(h-c) + |h-c|^2 - r^2 = 0.
  const double r = p.re_mm;
  const double hc = -p.b_mm - (r + offset_mm);
  const double B = d.z() * hc;
  const double C = hc * hc - r * r;
  const double disc = B * B - C;
  if (!(disc >= 0)) return std::nullopt;
  const double xi = -B - std::sqrt(disc);  // the near side of the sphere, facing the camera
  if (!(xi > 0)) return std::nullopt;
  return Pinhole() + xi * d;
}

std::optional<Eigen::Vector3d> Topographer::HitCone(const Eigen::Vector3d& o, const Eigen::Vector3d& d) const {
  const double t2 = std::pow(std::tan(p.cone_semi_angle_deg * M_PI / 180.0), 2);
  const double w = o.z() - p.cone_vertex_z_mm;
  const double A = d.x() * d.x() + d.y() * d.y() - t2 * d.z() * d.z();
  const double B = o.x() * d.x() + o.y() * d.y() - t2 * w * d.z();
  const double C = o.x() * o.x() + o.y() * o.y() - t2 * w * w;
  double best = std::numeric_limits<double>::infinity();
  const auto consider = [&](double s) {
    if (s > 1e-9 && o.z() + s * d.z() > p.cone_vertex_z_mm && s < best) best = s;
  };
  if (std::abs(A) < 1e-15) {
    if (std::abs(B) > 0) consider(-C / (2.0 * B));
  } else {
    const double disc = B * B - A * C;
    if (disc < 0) return std::nullopt;
    const double sq = std::sqrt(disc);
    consider((-B - sq) / A);
    consider((-B + sq) / A);
  }
  if (!std::isfinite(best)) return std::nullopt;
  return o + best * d;
}

std::optional<TargetPoint> TraceIdealPoint(const Topographer& topo, const Eigen::Vector2d& ideal_mm,
                                           std::string* why) {
  const Sphere sphere{topo.p.re_mm, 0.0};
  const Eigen::Vector3d inc = topo.IncidentDirection(ideal_mm);  // Eq. 3
  const auto p2 = topo.HitReferenceSphere(inc);                  // Eq. 5-7
  if (!p2) {
    if (why) *why = "backward ray misses the reference sphere";
    return std::nullopt;
  }
  double z = 0, zx = 0, zy = 0;
  sphere.SagAndGradient(p2->x(), p2->y(), &z, &zx, &zy);
  const Eigen::Vector3d n = SurfaceNormal(zx, zy);
  const Eigen::Vector3d refl = inc - 2.0 * inc.dot(n) * n;  // Eq. 8
  const auto p3 = topo.HitCone(*p2, refl);                  // Eq. 9-11
  if (!p3) {
    if (why) *why = "reflected ray misses the cone";
    return std::nullopt;
  }
  return TargetPoint{{}, ideal_mm, *p2, *p3};
}

NullScreenDesign DesignNullScreen(const IdealImageParams& ideal, const TopographerParams& topographer) {
  const Topographer topo{topographer};
  NullScreenDesign design;
  const auto spots = IdealImage(ideal);
  design.targets.reserve(spots.size());
  for (const auto& s : spots) {
    std::string why;
    auto t = TraceIdealPoint(topo, s.position_mm, &why);
    if (!t) {
      design.failures.push_back({s.id, why});
      continue;
    }
    t->id = s.id;
    design.targets.push_back(*t);
  }
  return design;
}


std::optional<Eigen::Vector3d> SolveReflectionPoint(const Surface& surface, const Topographer& topographer,
                                                    const Eigen::Vector3d& target_mm,
                                                    const Eigen::Vector2d& initial_xy_mm) {
  return std::visit(
      [&](const auto& s) {
        const auto sag = [&s](const auto& x, const auto& y, auto* z, auto* zx, auto* zy) {
          return s.SagAndGradient(x, y, z, zx, zy);
        };
        return SolveReflectionPointOn(sag, topographer.Pinhole(), target_mm, initial_xy_mm);
      },
      surface);
}

SyntheticImage SynthesizeImage(const Surface& surface, const Topographer& topographer,
                               const std::vector<TargetPoint>& targets) {
  SyntheticImage image;
  image.spots.reserve(targets.size());
  for (const auto& t : targets) {
    const auto p2 = SolveReflectionPoint(surface, topographer, t.on_cone_mm, t.on_sphere_mm.head<2>());
    if (!p2) {
      image.failures.push_back({t.id, "no reflection point on the surface (solve failed or ray misses it)"});
      continue;
    }
    image.spots.push_back({t.id, topographer.ImageOf(*p2), *p2});
  }
  return image;
}

}  // namespace topocal::model
