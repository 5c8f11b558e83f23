#include "topo/reconstruction.h"

#include <algorithm>
#include <cmath>
#include <map>

#include <fmt/format.h>

#include "topo/reconstruction_rays.h"

namespace topocal::topo {
namespace {

using internal::BatchScratch;
using internal::Consistency;
using internal::EvaluateAt;
using internal::ExpectedSlopeNoise;
using internal::IntersectSurfaces;
using internal::NeighbourCovariance;
using internal::NormalFromRays;
using internal::Ray;
using internal::RecoveredSurface;
using internal::ResidualNeighbourCovariance;
using internal::SlopesOf;
using internal::ZonalHeights;

struct Prepared {
  std::vector<Ray> rays;
  std::vector<model::SpotId> unmatched;
};

Prepared Prepare(const std::vector<model::PlaneSpot>& spots, const std::vector<model::TargetPoint>& targets,
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
    p.rays.push_back({s.id, s.position_mm, topo.IncidentDirection(s.position_mm), it->second->on_cone_mm});
  }
  // Ring order (then index) makes the zonal integration paths and all outputs deterministic.
  std::sort(p.rays.begin(), p.rays.end(), [](const Ray& a, const Ray& b) { return a.id < b.id; });
  return p;
}

// The first estimate P2' of every point: its ray's intersection with the reference sphere G at vertex offset t_mm;
// *radius: the largest distance of one from the axis. False (with r's message) when a ray misses G.
bool OnReferenceSphere(const Prepared& prep, const model::Topographer& topo, double t_mm,
                       std::vector<Eigen::Vector3d>* p2, double* radius, Reconstruction* r) {
  const int n = static_cast<int>(prep.rays.size());
  for (int i = 0; i < n; ++i) {
    const auto hit = topo.HitReferenceSphere(prep.rays[i].incident, t_mm);
    if (!hit) {
      r->message = fmt::format("spot ({}, {}): its ray misses the reference sphere", prep.rays[i].id.ring, prep.rays[i].id.index);
      return false;
    }
    (*p2)[i] = *hit;
    *radius = std::max(*radius, hit->head<2>().norm());
  }
  return true;
}

// One reconstruction at vertex offset t_mm, from the points on the reference sphere: the refinement passes (or the
// paper method's single fit), "auto"'s choice of model on the way, and the results written into r.
struct Solver {
  Solver(const Prepared& prepared, const model::Topographer& topographer,
         const model::ReconstructionSettings& reconstruction_settings, const ReconstructOptions& reconstruct_options,
         double t, bool iterative, std::vector<Eigen::Vector3d> on_sphere, double radius_mm, Reconstruction* out)
      : prep(prepared), topo(topographer), settings(reconstruction_settings), options(reconstruct_options), t_mm(t),
        iterate(iterative), r(*out), n(static_cast<int>(prepared.rays.size())), h(topographer.Pinhole()),
        p2(std::move(on_sphere)), normals(n), xy(n), slopes(n) {
    // Normalise the polynomial on the data radius (rounded up to 0.1 mm so that it does not change between
    // iterations, which keeps the basis identical while the points move by micrometres).
    norm_radius = std::ceil(radius_mm * 10.0 + 1.0) / 10.0;
    psi = TaylorPolynomial(settings.taylor_degree, norm_radius);
    tolerance_mm = settings.convergence_um * 1e-3;
    // surface_model "auto": the polynomial first; once it has converged (or after the paper method's single fit), the
    // spline joins only if the polynomial does not fit the data (ModelFitsData: either adequacy figure above its
    // warning ratio). A reconstruction started from another (a Monte Carlo draw of the same measurement) follows
    // that one's choice, so that every draw uses the same model.
    auto_mode = settings.surface_model == "auto";
    max_iterations = iterate ? settings.max_iterations : (auto_mode ? 2 : 1);
    if (const Reconstruction* start = options.start;
        start && start->slope_fit_norm_radius_mm == norm_radius && start->slope_fit_factor.rows() == psi.terms() - 1) {
      fitter.StartFrom(start->slope_fit_factor);
    }
    spline_mode = settings.surface_model == "spline" || auto_mode;
    if (auto_mode && options.start) {
      spline_mode = !options.start->residual.empty();
      auto_decided = true;
      r.surface_model_reason = "auto: as the reconstruction it started from";
    }
    incident.resize(n);
    for (int i = 0; i < n; ++i) incident[i] = prep.rays[i].incident;
    lambda0.resize(n);
    StartOnNominalSurface();
    if (spline_mode) spline = BSplineSurface(norm_radius, settings.spline_spacing_mm);
    // The spline joins once the polynomial alone has converged (or at once for the single-pass paper method): its
    // penalty is then chosen (REML) on the residual the polynomial really leaves — on the first pass the normals
    // still carry the error of the sphere estimate P2', smooth and large, and the choice (GCV, when measured) smoothed
    // the cone away — and kept for the remaining refinement.
    spline_active = spline_mode && !iterate && !(auto_mode && !auto_decided);
    residual_slopes.resize(n);
  }

  // A reconstruction of nearly the same spots starts on the surface that one recovered.
  void StartOnNominalSurface() {
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
  }

  // The model-adequacy figures of the surface as fitted now (Reconstruction: expected_slope_noise, adequacy_ratio,
  // residual_neighbour_correlation, structured_residual_ratio).
  void AssessAdequacy() {
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
  }

  // "auto" at the polynomial's convergence: true when the spline is to join.
  bool AutoWantsSpline() {
    auto_decided = true;
    AssessAdequacy();
    const bool fits = ModelFitsData(r);
    r.surface_model_reason = fmt::format(
        "auto: the polynomial's adequacy ratio {:.3g} (warning above {:g}) and structured residual ratio "
        "{:.3g} (warning above {:g}){}",
        r.adequacy_ratio, kAdequacyWarningRatio, r.structured_residual_ratio, kStructuredResidualWarningRatio,
        fits ? ": it fits" : ": the spline joins");
    return !fits;
  }

  // The polynomial (and, once it has joined, the spline) fitted to the slopes at the current points.
  bool FitSurface() {
    for (int i = 0; i < n; ++i) {
      normals[i] = NormalFromRays(prep.rays[i].incident, p2[i], prep.rays[i].target);
      slopes[i] = SlopesOf(normals[i]);
      xy[i] = p2[i].head<2>();
    }
    const GradientFit fit = fitter.Fit(xy, slopes, t_mm, &psi);
    if (!fit.ok) {
      r.message = "the modal fit of the slopes is rank-deficient (too few or degenerate spots)";
      return false;
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
        return false;
      }
      if (lambda < 0) r.spline_effective_params = sf.effective_params;
      lambda = sf.lambda;
      r.spline_lambda = lambda;
      r.rms_slope_residual = sf.rms_slope_residual;
    }
    return true;
  }

  // The points onto the recovered surface along their rays; *moved: the largest move.
  bool MovePoints(double* moved) {
    for (int i = 0; i < n; ++i) lambda0[i] = (p2[i] - h).norm();
    IntersectSurfaces(recovered, h, incident, lambda0, &hits, &hit_ok, &scratch);
    for (int i = 0; i < n; ++i) {
      if (!hit_ok[i]) {
        r.message = fmt::format("spot ({}, {}): its ray misses the reconstructed surface", prep.rays[i].id.ring,
                                prep.rays[i].id.index);
        return false;
      }
      *moved = std::max(*moved, (hits[i] - p2[i]).norm());
      p2[i] = hits[i];
    }
    return true;
  }

  // The passes; false (with r's message) when a fit fails, a ray misses the surface or the refinement does not
  // converge.
  bool Iterate() {
    for (int it = 0; it < max_iterations; ++it) {
      if (!FitSurface()) return false;
      r.iterations = it + 1;
      if (!iterate) {
        if (auto_mode && !auto_decided) {
          if (AutoWantsSpline()) {
            spline_mode = spline_active = true;  // the same points, refitted with the spline
            continue;
          }
          spline = BSplineSurface();
        }
        break;
      }
      double moved = 0;
      if (!MovePoints(&moved)) return false;
      if (moved <= tolerance_mm) {
        if (auto_mode && !auto_decided && !AutoWantsSpline()) {
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
        return false;
      }
    }
    return true;
  }

  // Consistency, adequacy, the points and the surfaces into r.
  void Finish() {
    // Points on the recovered surface: for the paper's method the estimates P2' lie on G, not on Psi; report the
    // surface height Psi at their (x, y), as the paper's point cloud does.
    r.consistency = Consistency(recovered, p2, normals, &scratch);
    if (options.adequacy && !adequacy_current) AssessAdequacy();
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
  }

  const Prepared& prep;
  const model::Topographer& topo;
  const model::ReconstructionSettings& settings;
  const ReconstructOptions& options;
  const double t_mm;
  const bool iterate;
  Reconstruction& r;
  const int n;
  const Eigen::Vector3d h;
  std::vector<Eigen::Vector3d> p2, normals;
  std::vector<Eigen::Vector2d> xy, slopes;
  double norm_radius = 0;
  TaylorPolynomial psi;
  double tolerance_mm = 0;
  bool auto_mode = false;
  bool auto_decided = false;
  int max_iterations = 0;
  GradientFitter fitter;
  bool spline_mode = false;
  std::vector<Eigen::Vector3d> incident, hits;
  std::vector<double> lambda0;
  std::vector<char> hit_ok;
  BatchScratch scratch;
  BSplineSurface spline;
  const RecoveredSurface recovered{psi, spline};
  bool spline_active = false;
  double lambda = -1;
  std::vector<Eigen::Vector2d> residual_slopes;
  SplineSlopeFitter spline_fitter;  // keeps its pattern and analysis from one refinement to the next
  bool adequacy_current = false;    // r's figures belong to the final fit (no refit since they were computed)
};

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
  std::vector<Eigen::Vector3d> p2(n);
  double radius = 0;
  if (!OnReferenceSphere(prep, topo, t_mm, &p2, &radius, &r)) return r;
  Solver solver(prep, topo, settings, options, t_mm, iterate, std::move(p2), radius, &r);
  if (!solver.Iterate()) return r;
  solver.Finish();
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

std::optional<std::string> SplineUndetermined(const Reconstruction& r) {
  const double observations = 2.0 * r.spots_used;
  const bool determined = r.spline_effective_params <= kMaxSplineParameterShare * observations;
  if (r.residual.empty() || observations <= 0 || determined) return std::nullopt;
  return fmt::format("the spline's knots every {:.3g} mm are finer than the {} spots determine ({:.0f} effective "
                     "parameters for {:.0f} slopes, more than {:.0f} %): set reconstruction.spline_spacing_mm "
                     "coarser",
                     r.residual.spacing_mm(), r.spots_used, r.spline_effective_params, observations,
                     100 * kMaxSplineParameterShare);
}

Reconstruction ReconstructAt(const std::vector<model::PlaneSpot>& spots, const std::vector<model::TargetPoint>& targets,
                             const model::TopographerParams& topographer,
                             const model::ReconstructionSettings& settings, double t_mm, bool iterate) {
  const Prepared prep = Prepare(spots, targets, model::Topographer{topographer});
  return Solve(prep, topographer, settings, t_mm, iterate);
}

Reconstruction Reconstruct(const std::vector<model::PlaneSpot>& spots, const std::vector<model::TargetPoint>& targets,
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
