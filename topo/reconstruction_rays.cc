#include "topo/reconstruction_rays.h"

#include <algorithm>
#include <cmath>

namespace topocal::topo::internal {

void IntersectSurfaces(const RecoveredSurface& psi, const Eigen::Vector3d& h, const std::vector<Eigen::Vector3d>& dirs,
                       const std::vector<double>& lambda0, std::vector<Eigen::Vector3d>* hits, std::vector<char>* ok,
                       BatchScratch* w) {
  // 1e-12 mm on lambda: far below the nm accuracy the reconstruction targets, above the double floor at ~70 mm.
  constexpr double kLambdaToleranceMm = 1e-12;
  constexpr int kMaxIterations = 30;
  const int n = static_cast<int>(dirs.size());
  hits->resize(n);
  ok->assign(n, 0);
  w->lambda = lambda0;
  w->active.resize(n);
  for (int i = 0; i < n; ++i) w->active[i] = i;
  for (int it = 0; it < kMaxIterations && !w->active.empty(); ++it) {
    const int m = static_cast<int>(w->active.size());
    w->x.resize(m), w->y.resize(m), w->pz.resize(m), w->z.resize(m), w->zx.resize(m), w->zy.resize(m);
    for (int j = 0; j < m; ++j) {
      const int i = w->active[j];
      const Eigen::Vector3d p = h + w->lambda[i] * dirs[i];
      w->x[j] = p.x(), w->y[j] = p.y(), w->pz[j] = p.z();
    }
    psi.ValueAndGradientMany(m, w->x.data(), w->y.data(), w->z.data(), w->zx.data(), w->zy.data());
    int kept = 0;
    for (int j = 0; j < m; ++j) {
      const int i = w->active[j];
      const Eigen::Vector3d& dir = dirs[i];
      const double f = w->pz[j] - w->z[j];
      const double df = dir.z() - w->zx[j] * dir.x() - w->zy[j] * dir.y();
      if (!(std::abs(df) > 1e-12)) continue;
      const double step = f / df;
      double& lambda = w->lambda[i];
      lambda -= step;
      if (!std::isfinite(lambda)) continue;
      if (std::abs(step) < kLambdaToleranceMm) {
        (*hits)[i] = h + lambda * dir;
        (*ok)[i] = 1;
        continue;
      }
      w->active[kept++] = i;
    }
    w->active.resize(kept);
  }
}

double ExpectedSlopeNoise(const std::vector<Ray>& rays, const std::vector<Eigen::Vector3d>& p2,
                          const std::vector<Eigen::Vector2d>& slopes, const RecoveredSurface& psi,
                          const model::Topographer& topo, double sigma_mm, int parameters, BatchScratch* w) {
  constexpr double kStepMm = 1e-4;
  const Eigen::Vector3d h = topo.Pinhole();
  const int count = static_cast<int>(rays.size());
  // What the fit sees: the measured slope against the surface's own slope at the (moved) incidence point.
  EvaluateAt(psi, p2, w);
  const std::vector<double> zx0 = w->zx, zy0 = w->zy;
  std::vector<Eigen::Matrix2d> J(count);
  std::vector<char> good(count, 1), ok;
  std::vector<Eigen::Vector3d> inc(count), hits;
  std::vector<double> lambda0(count);
  for (int i = 0; i < count; ++i) lambda0[i] = (p2[i] - h).norm();
  for (int c = 0; c < 2; ++c) {
    for (int i = 0; i < count; ++i) inc[i] = topo.IncidentDirection(rays[i].image_mm + kStepMm * Eigen::Vector2d::Unit(c));
    IntersectSurfaces(psi, h, inc, lambda0, &hits, &ok, w);
    EvaluateAt(psi, hits, w);
    for (int i = 0; i < count; ++i) {
      if (!ok[i]) {
        good[i] = 0;
        continue;
      }
      const Eigen::Vector2d moved = SlopesOf(NormalFromRays(inc[i], hits[i], rays[i].target)) - Eigen::Vector2d(w->zx[i], w->zy[i]);
      J[i].col(c) = (moved - (slopes[i] - Eigen::Vector2d(zx0[i], zy0[i]))) / kStepMm;
    }
  }
  double sum = 0;
  int n = 0;
  for (int i = 0; i < count; ++i) {
    if (!good[i]) continue;
    sum += sigma_mm * sigma_mm * J[i].squaredNorm() / 2.0;  // mean variance of the two slope components
    ++n;
  }
  if (n == 0) return 0;
  const double dof = std::max(0.0, 1.0 - static_cast<double>(parameters) / (2.0 * n));
  return std::sqrt(sum / n * dof);
}

NeighbourCovariance ResidualNeighbourCovariance(const std::vector<Ray>& rays, const std::vector<Eigen::Vector2d>& xy,
                                                const std::vector<Eigen::Vector2d>& residuals) {
  const int n = static_cast<int>(rays.size());
  NeighbourCovariance out;
  if (n < 2) return out;
  double sum = 0;
  int pairs = 0;
  int prev_begin = -1, prev_end = -1, begin = 0;
  while (begin < n) {
    int end = begin;
    while (end < n && rays[end].id.ring == rays[begin].id.ring) ++end;
    for (int i = begin; i < end; ++i) {
      const int next = i + 1 < end ? i + 1 : begin;
      if (next != i && end - begin > 2) sum += residuals[i].dot(residuals[next]), ++pairs;
      if (prev_begin >= 0) {
        int best = prev_begin;
        for (int j = prev_begin; j < prev_end; ++j) {
          if ((xy[j] - xy[i]).squaredNorm() < (xy[best] - xy[i]).squaredNorm()) best = j;
        }
        sum += residuals[i].dot(residuals[best]);
        ++pairs;
      }
    }
    prev_begin = begin;
    prev_end = end;
    begin = end;
  }
  double sum2 = 0;
  for (const auto& e : residuals) sum2 += e.squaredNorm();
  out.variance = sum2 / (2.0 * n);
  out.covariance = pairs ? sum / (2.0 * pairs) : 0.0;
  return out;
}

double Consistency(const RecoveredSurface& psi, const std::vector<Eigen::Vector3d>& p2,
                   const std::vector<Eigen::Vector3d>& normals, BatchScratch* w) {
  const int n = static_cast<int>(p2.size());
  double sum = 0, sum2 = 0;
  EvaluateAt(psi, p2, w);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d u = Eigen::Vector3d(w->zx[i], w->zy[i], -1.0).normalized();
    const double d = (u - normals[i]).norm();
    sum += d;
    sum2 += d * d;
  }
  const double mean = sum / n;
  return std::sqrt(std::max(0.0, sum2 / n - mean * mean));
}

std::vector<double> ZonalHeights(const std::vector<Ray>& rays, const std::vector<Eigen::Vector3d>& p2,
                                 const std::vector<Eigen::Vector2d>& slopes, double t_mm) {
  const int n = static_cast<int>(rays.size());
  std::vector<double> z(n, t_mm);
  Eigen::Vector2d vertex_slope = Eigen::Vector2d::Zero();
  int first_ring = n ? rays[0].id.ring : 0, count = 0;
  for (int i = 0; i < n && rays[i].id.ring == first_ring; ++i, ++count) vertex_slope += slopes[i];
  if (count) vertex_slope /= count;
  int prev_begin = -1, prev_end = -1, begin = 0;
  while (begin < n) {
    int end = begin;
    while (end < n && rays[end].id.ring == rays[begin].id.ring) ++end;
    for (int i = begin; i < end; ++i) {
      Eigen::Vector2d from_xy = Eigen::Vector2d::Zero(), from_slope = vertex_slope;
      double from_z = t_mm;
      if (prev_begin >= 0) {
        int best = prev_begin;
        for (int j = prev_begin; j < prev_end; ++j) {
          if ((p2[j].head<2>() - p2[i].head<2>()).squaredNorm() < (p2[best].head<2>() - p2[i].head<2>()).squaredNorm()) best = j;
        }
        from_xy = p2[best].head<2>();
        from_slope = slopes[best];
        from_z = z[best];
      }
      const Eigen::Vector2d step = p2[i].head<2>() - from_xy;
      z[i] = from_z + 0.5 * (from_slope + slopes[i]).dot(step);
    }
    prev_begin = begin;
    prev_end = end;
    begin = end;
  }
  return z;
}

}  // namespace topocal::topo::internal
