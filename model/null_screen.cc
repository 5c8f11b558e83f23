#include "model/null_screen.h"

#include <cmath>

#include <ceres/jet.h>
#include <fmt/format.h>

namespace topocal::model {

std::vector<IdealSpot> IdealImage(const IdealImageParams& p) {
  std::vector<IdealSpot> spots;
  spots.reserve(p.SpotCount());
  for (int i = 1; i <= p.rings_N + 1; ++i) {
    const double rho = p.rho0_mm + (i - 1) * (p.rhoN_mm - p.rho0_mm) / p.rings_N;
    const int n = p.eta0 + (i - 1) * p.eta;
    for (int j = 0; j < n; ++j) {
      const double theta = 2.0 * M_PI * j / n;
      spots.push_back({SpotId{i, j}, Eigen::Vector2d(rho * std::cos(theta), rho * std::sin(theta))});
    }
  }
  return spots;
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

NullScreenDesign DesignNullScreen(const IdealImageParams& ideal, const TopographerParams& topographer) {
  const Topographer topo{topographer};
  const Sphere sphere{topographer.re_mm, 0.0};
  NullScreenDesign design;
  const auto spots = IdealImage(ideal);
  design.targets.reserve(spots.size());
  for (const auto& s : spots) {
    const Eigen::Vector3d inc = topo.IncidentDirection(s.position_mm);
    const auto p2 = topo.HitReferenceSphere(inc);
    if (!p2) {
      design.failures.push_back({s.id, "backward ray misses the reference sphere"});
      continue;
    }
    double z = 0, zx = 0, zy = 0;
    sphere.SagAndGradient(p2->x(), p2->y(), &z, &zx, &zy);
    const Eigen::Vector3d n = SurfaceNormal(zx, zy);
    const Eigen::Vector3d refl = inc - 2.0 * inc.dot(n) * n;  // Eq. 8
    const auto p3 = topo.HitCone(*p2, refl);
    if (!p3) {
      design.failures.push_back({s.id, "reflected ray misses the cone"});
      continue;
    }
    design.targets.push_back({s.id, s.position_mm, *p2, *p3});
  }
  return design;
}

namespace {

// Residual of the reflection conditions (Eq. 15) at the surface point over (x, y), for target P3 and pinhole h.
template <typename T>
bool ReflectionResidual(const Surface& surface, const Eigen::Vector3d& h, const Eigen::Vector3d& p3, const T& x,
                        const T& y, T* f) {
  T z, zx, zy;
  const bool ok = std::visit([&](const auto& s) { return s.SagAndGradient(x, y, &z, &zx, &zy); }, surface);
  if (!ok) return false;
  using std::sqrt;
  const T ix = x - h.x(), iy = y - h.y(), iz = z - h.z();
  const T in = sqrt(ix * ix + iy * iy + iz * iz);
  const T rx = p3.x() - x, ry = p3.y() - y, rz = p3.z() - z;
  const T rn = sqrt(rx * rx + ry * ry + rz * rz);
  const T dz = rz / rn - iz / in;
  f[0] = (rx / rn - ix / in) + dz * zx;
  f[1] = (ry / rn - iy / in) + dz * zy;
  return true;
}

}  // namespace

std::optional<Eigen::Vector3d> SolveReflectionPoint(const Surface& surface, const Topographer& topographer,
                                                    const Eigen::Vector3d& target_mm,
                                                    const Eigen::Vector2d& initial_xy_mm) {
  // Newton's method on the 2x2 system of Eq. 15 with a jet Jacobian. Written by hand rather than with a
  // ceres::Problem because it runs once per spot per image (624 x sweeps) and converges in ~5 steps from the
  // designed point; the solver set-up would dominate. Convergence: |step| below 1e-13 mm (double floor at ~5 mm).
  constexpr double kStepToleranceMm = 1e-13;
  constexpr int kMaxIterations = 60;
  using Jet = ceres::Jet<double, 2>;
  const Eigen::Vector3d h = topographer.Pinhole();
  double x = initial_xy_mm.x(), y = initial_xy_mm.y();
  for (int it = 0; it < kMaxIterations; ++it) {
    Jet f[2];
    if (!ReflectionResidual(surface, h, target_mm, Jet(x, 0), Jet(y, 1), f)) return std::nullopt;
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
      const bool ok = std::visit([&](const auto& s) { return s.SagAndGradient(x, y, &z, &zx, &zy); }, surface);
      if (!ok) return std::nullopt;
      const Eigen::Vector3d p2(x, y, z);
      // The physical solution faces the camera: the incident ray travels towards +z and hits the front of the surface.
      if (!(p2.z() > h.z())) return std::nullopt;
      return p2;
    }
  }
  return std::nullopt;
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
    const Eigen::Vector3d inc = (*p2 - topographer.Pinhole()).normalized();  // Eq. 14a
    image.spots.push_back({t.id, topographer.ImagePoint(inc), *p2});
  }
  return image;
}

}  // namespace topocal::model
