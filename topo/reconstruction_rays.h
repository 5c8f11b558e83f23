#pragma once
// The rays of a null-screen reconstruction (topo/reconstruction.cc) on the surface it recovers: their intersections
// with it, the normals and slopes they give, and the figures computed from them (the expected slope noise, the
// residual's neighbour covariance, the consistency Delta and the zonal heights). Private to topo/reconstruction*.cc.
#include <vector>

#include <Eigen/Core>

#include "model/null_screen.h"
#include "topo/bspline_surface.h"
#include "topo/taylor_polynomial.h"

namespace topocal::topo::internal {

struct Ray {
  model::SpotId id;
  Eigen::Vector2d image_mm;  // on the detection plane
  Eigen::Vector3d incident;  // I, unit, from the pinhole towards the cornea
  Eigen::Vector3d target;    // P3
};

// Value and gradient of the recovered surface: Psi, plus the spline residual when there is one.
struct RecoveredSurface {
  const TaylorPolynomial& psi;
  const BSplineSurface& spline;
  void ValueAndGradient(double x, double y, double* z, double* zx, double* zy) const {
    psi.ValueAndGradient(x, y, z, zx, zy);
    if (spline.empty()) return;
    double s, sx, sy, sxx, sxy, syy;
    spline.Derivatives(x, y, &s, &sx, &sy, &sxx, &sxy, &syy);
    *z += s;
    *zx += sx;
    *zy += sy;
  }
  // At `count` points, each bit for bit as ValueAndGradient.
  void ValueAndGradientMany(int count, const double* x, const double* y, double* z, double* zx, double* zy) const {
    psi.ValueAndGradientMany(count, x, y, z, zx, zy);
    if (spline.empty()) return;
    for (int i = 0; i < count; ++i) {
      double s, sx, sy, sxx, sxy, syy;
      spline.Derivatives(x[i], y[i], &s, &sx, &sy, &sxx, &sxy, &syy);
      z[i] += s;
      zx[i] += sx;
      zy[i] += sy;
    }
  }
};

// Reused buffers of IntersectSurfaces and of the batched evaluations.
struct BatchScratch {
  std::vector<double> lambda, x, y, z, zx, zy, pz;
  std::vector<int> active;
};

// Intersections of the rays h + lambda dirs[i] with z = S(x, y), each by Newton on lambda from lambda0[i]; ok[i] = 0
// where Newton fails (flat derivative, non-finite step, no convergence). The rays step in lockstep, the surface
// evaluated at all rays still iterating in one ValueAndGradientMany call per step (the interleaved
// evaluation overlaps the rays' Horner chains); each ray takes the Newton steps it would take alone, bit for bit.
void IntersectSurfaces(const RecoveredSurface& psi, const Eigen::Vector3d& h, const std::vector<Eigen::Vector3d>& dirs,
                       const std::vector<double>& lambda0, std::vector<Eigen::Vector3d>* hits, std::vector<char>* ok,
                       BatchScratch* w);

// Value and gradient of the surface at the points' (x, y), each as RecoveredSurface::ValueAndGradient.
template <typename Point>
void EvaluateAt(const RecoveredSurface& psi, const std::vector<Point>& points, BatchScratch* w) {
  const int n = static_cast<int>(points.size());
  w->x.resize(n), w->y.resize(n), w->z.resize(n), w->zx.resize(n), w->zy.resize(n);
  for (int i = 0; i < n; ++i) w->x[i] = points[i].x(), w->y[i] = points[i].y();
  psi.ValueAndGradientMany(n, w->x.data(), w->y.data(), w->z.data(), w->zx.data(), w->zy.data());
}

inline Eigen::Vector3d NormalFromRays(const Eigen::Vector3d& incident, const Eigen::Vector3d& p2,
                                      const Eigen::Vector3d& p3) {
  const Eigen::Vector3d reflected = (p3 - p2).normalized();
  return (reflected - incident).normalized();  // Eq. 19
}

inline Eigen::Vector2d SlopesOf(const Eigen::Vector3d& n) { return {-n.x() / n.z(), -n.y() / n.z()}; }

// The rms slope residual a spot-centre uncertainty of sigma_mm produces: per spot, the 2x2 sensitivity of its slope
// residual (measured slope minus the surface's slope where the ray now lands) to its image position (finite
// differences of 1e-4 mm, i.e. ~0.1 px: linear, far above rounding), through the incident ray, its intersection
// with the surface and the reflected ray to the same target.
double ExpectedSlopeNoise(const std::vector<Ray>& rays, const std::vector<Eigen::Vector3d>& p2,
                          const std::vector<Eigen::Vector2d>& slopes, const RecoveredSurface& psi,
                          const model::Topographer& topo, double sigma_mm, int parameters, BatchScratch* w);

struct NeighbourCovariance {
  double covariance = 0, variance = 0;  // per slope component
};

// Reconstruction::residual_neighbour_correlation: pairs of the spot lattice — each spot with the next spot on its
// ring (the rays are grouped by ring, in index order; the last closes the ring) and with the nearest spot of the
// ring inside it.
NeighbourCovariance ResidualNeighbourCovariance(const std::vector<Ray>& rays, const std::vector<Eigen::Vector2d>& xy,
                                                const std::vector<Eigen::Vector2d>& residuals);

// Std of |U - n| (paper Sec. 4.1, Eq. 22 against Eq. 19), U = (Psi_x, Psi_y, -1)/norm.
double Consistency(const RecoveredSurface& psi, const std::vector<Eigen::Vector3d>& p2,
                   const std::vector<Eigen::Vector3d>& normals, BatchScratch* w);

// Trapezoidal integration of the slopes (Eq. 20) along straight paths: ring 1 from the vertex (0, 0, t) whose
// slope is taken as the mean slope of ring 1; every later spot from the nearest spot of the previous ring present.
std::vector<double> ZonalHeights(const std::vector<Ray>& rays, const std::vector<Eigen::Vector3d>& p2,
                                 const std::vector<Eigen::Vector2d>& slopes, double t_mm);

}  // namespace topocal::topo::internal
