#include "topo/reconstruction.h"

#include <algorithm>
#include <cmath>
#include <map>

#include <fmt/format.h>

namespace topocal::topo {
namespace {

struct Ray {
  model::SpotId id;
  Eigen::Vector2d image_mm;  // on the detection plane
  Eigen::Vector3d incident;  // I, unit, from the pinhole towards the cornea
  Eigen::Vector3d target;    // P3
};

struct Prepared {
  std::vector<Ray> rays;
  std::vector<model::SpotId> unmatched;
};

Prepared Prepare(const std::vector<MeasuredSpot>& spots, const std::vector<model::TargetPoint>& targets,
                 const model::Topographer& topo) {
  std::map<model::SpotId, const model::TargetPoint*> by_id;
  for (const auto& t : targets) by_id[t.id] = &t;
  Prepared p;
  p.rays.reserve(spots.size());
  for (const auto& s : spots) {
    const auto it = by_id.find(s.id);
    if (it == by_id.end()) {
      p.unmatched.push_back(s.id);
      continue;
    }
    p.rays.push_back({s.id, s.image_mm, topo.IncidentDirection(s.image_mm), it->second->on_cone_mm});
  }
  // Ring order (then index) makes the zonal integration paths and all outputs deterministic.
  std::sort(p.rays.begin(), p.rays.end(), [](const Ray& a, const Ray& b) { return a.id < b.id; });
  return p;
}

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

// Value and gradient of the surface at the points' (x, y), each as RecoveredSurface::ValueAndGradient.
template <typename Point>
void EvaluateAt(const RecoveredSurface& psi, const std::vector<Point>& points, BatchScratch* w) {
  const int n = static_cast<int>(points.size());
  w->x.resize(n), w->y.resize(n), w->z.resize(n), w->zx.resize(n), w->zy.resize(n);
  for (int i = 0; i < n; ++i) w->x[i] = points[i].x(), w->y[i] = points[i].y();
  psi.ValueAndGradientMany(n, w->x.data(), w->y.data(), w->z.data(), w->zx.data(), w->zy.data());
}

Eigen::Vector3d NormalFromRays(const Eigen::Vector3d& incident, const Eigen::Vector3d& p2, const Eigen::Vector3d& p3) {
  const Eigen::Vector3d reflected = (p3 - p2).normalized();
  return (reflected - incident).normalized();  // Eq. 19
}

Eigen::Vector2d SlopesOf(const Eigen::Vector3d& n) { return {-n.x() / n.z(), -n.y() / n.z()}; }

// The rms slope residual a spot-centre uncertainty of sigma_mm produces: per spot, the 2x2 sensitivity of its slope
// residual (measured slope minus the surface's slope where the ray now lands) to its image position (finite
// differences of 1e-4 mm, i.e. ~0.1 px: linear, far above rounding), through the incident ray, its intersection
// with the surface and the reflected ray to the same target.
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

struct NeighbourCovariance {
  double covariance = 0, variance = 0;  // per slope component
};

// Reconstruction::residual_neighbour_correlation: pairs of the spot lattice — each spot with the next spot on its
// ring (the rays are grouped by ring, in index order; the last closes the ring) and with the nearest spot of the
// ring inside it.
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

// Std of |U - n| (paper Sec. 4.1, Eq. 22 against Eq. 19), U = (Psi_x, Psi_y, -1)/norm.
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

// Trapezoidal integration of the slopes (Eq. 20) along straight paths: ring 1 from the vertex (0, 0, t) whose
// slope is taken as the mean slope of ring 1; every later spot from the nearest spot of the previous ring present.
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

Reconstruction Solve(const Prepared& prep, const model::TopographerParams& tp,
                     const model::ReconstructionSettings& settings, double t_mm, bool iterate,
                     const ReconstructOptions& options = {}) {
  Reconstruction r;
  r.method = iterate ? "iterative" : "paper";
  r.vertex_t_mm = t_mm;
  r.unmatched = prep.unmatched;
  const int n = static_cast<int>(prep.rays.size());
  r.spots_used = n;
  const int needed = TaylorPolynomial::TermCount(settings.taylor_degree);
  if (2 * n < needed - 1 + 1) {
    r.message = fmt::format("{} spots give {} slope equations; a degree-{} polynomial needs at least {}", n, 2 * n,
                            settings.taylor_degree, needed);
    return r;
  }
  const model::Topographer topo{tp};
  const Eigen::Vector3d h = topo.Pinhole();
  std::vector<Eigen::Vector3d> p2(n), normals(n);
  std::vector<Eigen::Vector2d> xy(n), slopes(n);
  double radius = 0;
  for (int i = 0; i < n; ++i) {
    const auto hit = topo.HitReferenceSphere(prep.rays[i].incident, t_mm);
    if (!hit) {
      r.message = fmt::format("spot ({}, {}): its ray misses the reference sphere", prep.rays[i].id.ring, prep.rays[i].id.index);
      return r;
    }
    p2[i] = *hit;
    radius = std::max(radius, hit->head<2>().norm());
  }
  // Normalise the polynomial on the data radius (rounded up to 0.1 mm so that it does not change between
  // iterations, which keeps the basis identical while the points move by micrometres).
  const double norm_radius = std::ceil(radius * 10.0 + 1.0) / 10.0;
  TaylorPolynomial psi(settings.taylor_degree, norm_radius);
  const double tolerance_mm = settings.convergence_um * 1e-3;
  // surface_model "auto": the polynomial first; once it has converged (or after the paper method's single fit), the
  // spline joins only if the polynomial does not fit the data (ModelFitsData: either adequacy figure above its
  // warning ratio). A reconstruction started from another (a Monte Carlo draw of the same measurement) follows
  // that one's choice, so that every draw uses the same model.
  const bool auto_mode = settings.surface_model == "auto";
  bool auto_decided = false;
  const int max_iterations = iterate ? settings.max_iterations : (auto_mode ? 2 : 1);
  GradientFitter fitter;
  if (const Reconstruction* start = options.start;
      start && start->slope_fit_norm_radius_mm == norm_radius && start->slope_fit_factor.rows() == psi.terms() - 1) {
    fitter.StartFrom(start->slope_fit_factor);
  }
  bool spline_mode = settings.surface_model == "spline" || auto_mode;
  if (auto_mode && options.start) {
    spline_mode = !options.start->residual.empty();
    auto_decided = true;
    r.surface_model_reason = "auto: as the reconstruction it started from";
  }
  std::vector<Eigen::Vector3d> incident(n), hits;
  for (int i = 0; i < n; ++i) incident[i] = prep.rays[i].incident;
  std::vector<double> lambda0(n);
  std::vector<char> hit_ok;
  BatchScratch scratch;
  // A reconstruction of nearly the same spots (a Monte Carlo draw: nanometres to micrometres away) starts on the
  // surface that one recovered instead of on the sphere G: the refinement then begins at the nominal solution's
  // error (~nm) rather than the sphere's (tens of um) and meets convergence_um in 1-2 passes instead of 3-6. It
  // converges to the same fixed point, to the same tolerance. A start with a spline residual, a spline
  // reconstruction (whose spline joins only once the polynomial has converged) or another vertex offset is not used
  // for the points; a ray that misses the start's surface leaves every ray on the sphere.
  if (const Reconstruction* start = options.start;
      start && iterate && !spline_mode && start->ok && start->residual.empty() && start->vertex_t_mm == t_mm) {
    const BSplineSurface none;
    const RecoveredSurface nominal{start->surface, none};
    for (int i = 0; i < n; ++i) lambda0[i] = (p2[i] - h).norm();
    IntersectSurfaces(nominal, h, incident, lambda0, &hits, &hit_ok, &scratch);
    if (std::all_of(hit_ok.begin(), hit_ok.end(), [](char ok) { return ok != 0; })) p2 = hits;
  }
  BSplineSurface spline;
  if (spline_mode) spline = BSplineSurface(norm_radius, settings.spline_spacing_mm);
  const RecoveredSurface recovered{psi, spline};
  // The spline joins once the polynomial alone has converged (or at once for the single-pass paper method): its
  // penalty is then chosen (REML) on the residual the polynomial really leaves — on the first pass the normals
  // still carry the error of the sphere estimate P2', smooth and large, and the choice (GCV, when measured) smoothed
  // the cone away — and kept for the remaining refinement.
  bool spline_active = spline_mode && !iterate && !(auto_mode && !auto_decided);
  double lambda = -1;
  std::vector<Eigen::Vector2d> residual_slopes(n);
  SplineSlopeFitter spline_fitter;  // keeps its pattern and analysis from one refinement to the next
  // The model-adequacy figures of the surface as fitted now (Reconstruction: expected_slope_noise, adequacy_ratio,
  // residual_neighbour_correlation, structured_residual_ratio).
  bool adequacy_current = false;  // r's figures belong to the final fit (no refit since they were computed)
  const auto assess_adequacy = [&] {
    const int parameters = psi.terms() - 1 + static_cast<int>(std::lround(r.spline_effective_params));
    r.expected_slope_noise = ExpectedSlopeNoise(prep.rays, p2, slopes, recovered, topo,
                                                settings.spot_uncertainty_um * 1e-3, parameters, &scratch);
    r.adequacy_ratio = r.expected_slope_noise > 0 ? r.rms_slope_residual / r.expected_slope_noise : 0.0;
    std::vector<Eigen::Vector2d> residuals(n);
    EvaluateAt(recovered, xy, &scratch);
    for (int i = 0; i < n; ++i) residuals[i] = slopes[i] - Eigen::Vector2d(scratch.zx[i], scratch.zy[i]);
    const NeighbourCovariance nc = ResidualNeighbourCovariance(prep.rays, xy, residuals);
    r.residual_neighbour_correlation = nc.variance > 0 ? nc.covariance / nc.variance : 0.0;
    r.structured_residual_ratio =
        r.expected_slope_noise > 0 ? std::sqrt(std::max(0.0, nc.covariance)) / r.expected_slope_noise : 0.0;
    adequacy_current = true;
  };
  // "auto" at the polynomial's convergence: true when the spline is to join.
  const auto auto_wants_spline = [&] {
    auto_decided = true;
    assess_adequacy();
    const bool fits = ModelFitsData(r);
    r.surface_model_reason = fmt::format(
        "auto: the polynomial's adequacy ratio {:.3g} (warning above {:g}) and structured residual ratio "
        "{:.3g} (warning above {:g}){}",
        r.adequacy_ratio, kAdequacyWarningRatio, r.structured_residual_ratio, kStructuredResidualWarningRatio,
        fits ? ": it fits" : ": the spline joins");
    return !fits;
  };
  for (int it = 0; it < max_iterations; ++it) {
    for (int i = 0; i < n; ++i) {
      normals[i] = NormalFromRays(prep.rays[i].incident, p2[i], prep.rays[i].target);
      slopes[i] = SlopesOf(normals[i]);
      xy[i] = p2[i].head<2>();
    }
    const GradientFit fit = fitter.Fit(xy, slopes, t_mm, &psi);
    if (!fit.ok) {
      r.message = "the modal fit of the slopes is rank-deficient (too few or degenerate spots)";
      return r;
    }
    r.rms_slope_residual = fit.rms_slope_residual;
    adequacy_current = false;
    if (spline_active) {
      for (int i = 0; i < n; ++i) {
        double z, zx, zy;
        psi.ValueAndGradient(xy[i].x(), xy[i].y(), &z, &zx, &zy);
        residual_slopes[i] = slopes[i] - Eigen::Vector2d(zx, zy);
      }
      const SplineFit sf = spline_fitter.Fit(xy, residual_slopes, lambda, SplineFitOptions{}, &spline);
      if (!sf.ok) {
        r.message = "the spline fit of the slope residual failed (singular system)";
        return r;
      }
      if (lambda < 0) r.spline_effective_params = sf.effective_params;
      lambda = sf.lambda;
      r.spline_lambda = lambda;
      r.rms_slope_residual = sf.rms_slope_residual;
    }
    r.iterations = it + 1;
    if (!iterate) {
      if (auto_mode && !auto_decided) {
        if (auto_wants_spline()) {
          spline_mode = spline_active = true;  // the same points, refitted with the spline
          continue;
        }
        spline = BSplineSurface();
      }
      break;
    }
    double moved = 0;
    for (int i = 0; i < n; ++i) lambda0[i] = (p2[i] - h).norm();
    IntersectSurfaces(recovered, h, incident, lambda0, &hits, &hit_ok, &scratch);
    for (int i = 0; i < n; ++i) {
      if (!hit_ok[i]) {
        r.message = fmt::format("spot ({}, {}): its ray misses the reconstructed surface", prep.rays[i].id.ring,
                                prep.rays[i].id.index);
        return r;
      }
      moved = std::max(moved, (hits[i] - p2[i]).norm());
      p2[i] = hits[i];
    }
    if (moved <= tolerance_mm) {
      if (auto_mode && !auto_decided && !auto_wants_spline()) {
        spline_mode = false;
        spline = BSplineSurface();  // the polynomial alone (an empty residual adds nothing and costs nothing)
      }
      if (spline_mode && !spline_active) {
        spline_active = true;  // one more pass at least, now with the spline
        continue;
      }
      break;
    }
    if (it + 1 == max_iterations) {
      r.message = fmt::format("normal refinement did not converge in {} iterations (last move {:.3g} um)",
                              max_iterations, moved * 1e3);
      return r;
    }
  }
  // Points on the recovered surface: for the paper's method the estimates P2' lie on G, not on Psi; report the
  // surface height Psi at their (x, y), as the paper's point cloud does.
  r.consistency = Consistency(recovered, p2, normals, &scratch);
  if (options.adequacy && !adequacy_current) assess_adequacy();
  if (!options.adequacy) {
    // Left 0 when not asked for (ReconstructOptions::adequacy), even when "auto" computed them for its decision:
    // after the spline joined they would describe the polynomial, not the surface returned.
    r.expected_slope_noise = r.adequacy_ratio = r.residual_neighbour_correlation = r.structured_residual_ratio = 0;
  }
  const std::vector<double> zonal = ZonalHeights(prep.rays, p2, slopes, t_mm);
  r.points.resize(n);
  EvaluateAt(recovered, p2, &scratch);
  for (int i = 0; i < n; ++i) {
    r.points[i].id = prep.rays[i].id;
    r.points[i].point_mm = Eigen::Vector3d(p2[i].x(), p2[i].y(), scratch.z[i]);
    r.points[i].normal = normals[i];
    r.points[i].zonal_z_mm = zonal[i];
  }
  r.slope_fit_factor = fitter.factor();
  r.slope_fit_factorizations = fitter.factorizations();
  r.slope_fit_norm_radius_mm = norm_radius;
  r.surface = std::move(psi);
  r.surface_model = spline_active ? "spline" : "polynomial";
  r.residual = std::move(spline);
  r.ok = true;
  return r;
}

}  // namespace

double Reconstruction::Height(double x, double y) const {
  return surface.Value(x, y) + (residual.empty() ? 0.0 : residual.Value(x, y));
}

void Reconstruction::Derivatives(double x, double y, model::SurfaceDerivatives* d) const {
  surface.Derivatives(x, y, &d->z, &d->zx, &d->zy, &d->zxx, &d->zxy, &d->zyy);
  if (residual.empty()) return;
  double s, sx, sy, sxx, sxy, syy;
  residual.Derivatives(x, y, &s, &sx, &sy, &sxx, &sxy, &syy);
  d->z += s;
  d->zx += sx;
  d->zy += sy;
  d->zxx += sxx;
  d->zxy += sxy;
  d->zyy += syy;
}

bool ModelFitsData(const Reconstruction& r) {
  return r.adequacy_ratio <= kAdequacyWarningRatio && r.structured_residual_ratio <= kStructuredResidualWarningRatio;
}

Reconstruction ReconstructAt(const std::vector<MeasuredSpot>& spots, const std::vector<model::TargetPoint>& targets,
                             const model::TopographerParams& topographer,
                             const model::ReconstructionSettings& settings, double t_mm, bool iterate) {
  const Prepared prep = Prepare(spots, targets, model::Topographer{topographer});
  return Solve(prep, topographer, settings, t_mm, iterate);
}

Reconstruction Reconstruct(const std::vector<MeasuredSpot>& spots, const std::vector<model::TargetPoint>& targets,
                           const model::TopographerParams& topographer, const model::ReconstructionSettings& settings,
                           const ReconstructOptions& options) {
  const Prepared prep = Prepare(spots, targets, model::Topographer{topographer});
  const bool iterate = settings.method == "iterative";
  if (iterate) {
    // The consistency Delta(t) is monotone in t for this geometry (docs/reconstruction.md): a single camera and
    // screen do not fix the vertex height, so the iterative method works at the nominal position.
    Reconstruction r = Solve(prep, topographer, settings, settings.vertex_t_um * 1e-3, true, options);
    r.vertex_evaluations = 1;
    if (r.ok) {
      r.message = fmt::format("iterative method: {} spots, t = {:.4f} um, {} iterations, slope rms {:.3g}",
                              r.spots_used, r.vertex_t_mm * 1e3, r.iterations, r.rms_slope_residual);
    }
    return r;
  }
  // Vertex search of Fig. 8: K points over [t - w, t + w]; take the best, shrink to +- one grid step around it and
  // repeat until Delta <= TOL, the budget ends, or the interval is below 1e-6 um (beyond double precision of t).
  double centre = settings.vertex_t_um * 1e-3, half = settings.vertex_search_halfwidth_um * 1e-3;
  Reconstruction best;
  int evaluations = 0;
  for (int round = 0; round < settings.vertex_search_max_refinements; ++round) {
    const int k = settings.vertex_search_steps;
    const double step = 2.0 * half / (k - 1);
    for (int i = 0; i < k; ++i) {
      const double t = centre - half + i * step;
      Reconstruction r = Solve(prep, topographer, settings, t, iterate, options);
      ++evaluations;
      if (!r.ok) continue;
      if (!best.ok || r.consistency < best.consistency) best = std::move(r);
    }
    if (!best.ok) break;
    if (best.consistency <= settings.vertex_search_tol || step < 1e-9) break;
    centre = best.vertex_t_mm;
    half = step;
  }
  if (!best.ok) {
    best = Solve(prep, topographer, settings, 0.0, iterate);  // for its failure message
    best.ok = false;
  }
  best.vertex_evaluations = evaluations;
  if (best.ok) {
    best.message = fmt::format("{} method: {} spots, t = {:.4f} um, Delta = {:.3g}, {} evaluations", best.method,
                               best.spots_used, best.vertex_t_mm * 1e3, best.consistency, evaluations);
  }
  return best;
}

}  // namespace topocal::topo
