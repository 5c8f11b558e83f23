#include "topo/analysis.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <fmt/format.h>

namespace topocal::topo {

PowerMapOptions PowerMapOptionsFrom(const model::ReconstructionSettings& s) {
  PowerMapOptions o;
  o.radius_mm = s.power_map_radius_mm;
  o.meridians = s.power_map_meridians;
  o.radial_samples = s.power_map_radial_samples;
  o.method = s.power_map_method == "polynomial" ? MeridianMethod::kPolynomialFit : MeridianMethod::kExact;
  return o;
}

std::optional<double> HeightDifferenceMm(const model::Surface& truth, double x_mm, double y_mm,
                                         double recovered_z_mm) noexcept {
  model::SurfaceDerivatives d;
  if (!model::EvaluateSurface(truth, x_mm, y_mm, &d)) return std::nullopt;
  return d.z - recovered_z_mm;
}

SurfaceErrors HeightErrors(const std::vector<ReconstructedPoint>& points, const model::Surface& truth) {
  SurfaceErrors e;
  if (points.empty()) return e;
  double lo = INFINITY, hi = -INFINITY, sum = 0, sum2 = 0;
  int n = 0;
  for (const auto& p : points) {
    const auto delta = HeightDifferenceMm(truth, p.point_mm.x(), p.point_mm.y(), p.point_mm.z());
    if (!delta) continue;
    const double ds = *delta;
    lo = std::min(lo, ds);
    hi = std::max(hi, ds);
    sum += ds;
    sum2 += ds * ds;
    ++n;
  }
  if (n == 0) return e;
  const double mean = sum / n;
  e.pv_um = (hi - lo) * 1e3;
  e.rms_um = std::sqrt(std::max(0.0, sum2 / n - mean * mean)) * 1e3;
  return e;
}

double SupportedRadiusMm(const std::vector<ReconstructedPoint>& points) {
  constexpr int kSectors = 36;
  std::array<double, kSectors> reach{};
  for (const auto& p : points) {
    const double angle = std::atan2(p.point_mm.y(), p.point_mm.x());
    const int sector = std::clamp(static_cast<int>(std::floor((angle + M_PI) / (2.0 * M_PI) * kSectors)), 0, kSectors - 1);
    reach[sector] = std::max(reach[sector], p.point_mm.head<2>().norm());
  }
  // A sector without any point (the innermost rings hold too few spots to put one in every 10 deg sector, a lid can
  // hide the outer ones, a lash's shadow takes a narrow wedge of spots out of the measurement) is covered as far as
  // the nearer of the two sectors with points on either side of its empty run reach, when that run is at most
  // kBridgedSectors wide (30 deg: a lash's wedge, the gaps of the inner rings); a wider empty wedge is not covered.
  // Sectors with points keep their own reach.
  constexpr int kBridgedSectors = 3;
  double supported = std::numeric_limits<double>::infinity();
  for (int s = 0; s < kSectors; ++s) {
    double own = reach[s];
    if (!(own > 0)) {
      int before = 1, after = 1;
      while (before < kSectors && !(reach[(s - before + kSectors) % kSectors] > 0)) ++before;
      while (after < kSectors && !(reach[(s + after) % kSectors] > 0)) ++after;
      const int run = before + after - 1;
      own = run <= kBridgedSectors && before < kSectors
                ? std::min(reach[(s - before + kSectors) % kSectors], reach[(s + after) % kSectors])
                : 0.0;
    }
    supported = std::min(supported, own);
  }
  return supported;
}

PowerMaps IdealPowerMaps(const model::BiconicParams& cornea, const model::ReconstructionSettings& settings) {
  const model::Biconic b{cornea};
  PowerMaps maps;
  std::string why;
  PowerMapOptions options = PowerMapOptionsFrom(settings);
  // Centred and untilted, the biconic's sag depends on the squares of the rotated coordinates only: z(-x, -y) =
  // z(x, y), so half the meridians give the maps (the paper's eye; a decentred or tilted one is not symmetric).
  options.point_symmetric = cornea.x0_mm == 0 && cornea.y0_mm == 0 && cornea.tilt_x_deg == 0 && cornea.tilt_y_deg == 0;
  if (!ComputePowerMaps([&](double x, double y, model::SurfaceDerivatives* d) { return b.Evaluate(x, y, d); }, options,
                        &maps, &why)) {
    throw std::runtime_error(fmt::format("ideal power maps: {}", why));
  }
  return maps;
}

namespace {

BiconicFitOptions SurfaceFitOptions(const model::Config& config, const AnalysisOptions& options) {
  BiconicFitOptions fit_options;
  fit_options.mode = BiconicFitModeFromName(config.reconstruction.biconic_fit);
  fit_options.stddev = options.stddev;
  if (options.start && options.start->surface_fit.ok && options.start->surface_fit.mode == fit_options.mode) {
    fit_options.start = &options.start->surface_fit.params;
  } else if (!options.start) {
    fit_options.start = options.fit_start;
  }
  return fit_options;
}

// The shape the maps describe: Psi without piston and tilts and the spline residual (surface_model "spline") with
// its own tangent plane at the origin removed, like Psi's.
struct MapShape {
  explicit MapShape(const Reconstruction& r) : shape(r.surface), spline(r.residual) {
    // Sec. 4.2: piston B_1 and tilts B_2, B_3 do not affect the shape and are zeroed before the maps.
    shape.coefficients().head(3).setZero();
    if (!spline.empty()) {
      double z, zxx, zxy, zyy;
      spline.Derivatives(0.0, 0.0, &z, &spline_tilt.x(), &spline_tilt.y(), &zxx, &zxy, &zyy);
    }
  }
  bool Derivatives(double x, double y, model::SurfaceDerivatives* d) const {
    shape.Derivatives(x, y, &d->z, &d->zx, &d->zy, &d->zxx, &d->zxy, &d->zyy);
    if (spline.empty()) return true;
    double s, sx, sy, sxx, sxy, syy;
    spline.Derivatives(x, y, &s, &sx, &sy, &sxx, &sxy, &syy);
    d->z += s - spline_tilt.dot(Eigen::Vector2d(x, y));
    d->zx += sx - spline_tilt.x();
    d->zy += sy - spline_tilt.y();
    d->zxx += sxx;
    d->zxy += sxy;
    d->zyy += syy;
    return true;
  }

  TaylorPolynomial shape;
  const BSplineSurface& spline;
  Eigen::Vector2d spline_tilt = Eigen::Vector2d::Zero();
};

// The analysis's warnings: maps beyond the disc the data support and (with options.adequacy) a surface model that
// does not represent the data.
void AddWarnings(const model::Config& config, const AnalysisOptions& options, Analysis* a) {
  if (a->maps_extrapolated) {
    a->warnings.push_back(fmt::format("the power maps reach {:.2f} mm but the data cover every direction only to "
                                      "{:.2f} mm: beyond, the maps are extrapolated (clinical indices use the "
                                      "supported disc only)", a->power.radius_mm, a->supported_radius_mm));
  }
  const auto& r = a->reconstruction;
  // What to try: the local model, when it was not used.
  const std::string hint = r.surface_model == "polynomial" ? "; try --surface-model auto (or spline)" : "";
  if (options.adequacy && r.adequacy_ratio > kAdequacyWarningRatio) {
    a->warnings.push_back(
        fmt::format("the surface model does not represent the data: slope residual {:.3g} is {:.1f} x "
                    "the {:.3g} expected from {:.3g} um spot-centre noise{}",
                    r.rms_slope_residual, r.adequacy_ratio, r.expected_slope_noise,
                    config.reconstruction.spot_uncertainty_um, hint));
  }
  if (options.adequacy && r.structured_residual_ratio > kStructuredResidualWarningRatio) {
    a->warnings.push_back(fmt::format(
        "the surface model misses a local shape: neighbouring spots share their slope "
        "residual (correlation {:.2f}; shared part {:.2f} x the expected noise, "
        "warning above {:.1f}){}",
        r.residual_neighbour_correlation, r.structured_residual_ratio, kStructuredResidualWarningRatio, hint));
  }
}

}  // namespace

Analysis AnalyzeSpots(const std::vector<model::PlaneSpot>& spots, const std::vector<model::TargetPoint>& targets,
                      const model::Config& config, const model::BiconicParams* truth,
                      const AnalysisOptions& options) {
  Analysis a;
  ReconstructOptions reconstruct_options;
  reconstruct_options.adequacy = options.adequacy;
  if (options.start) reconstruct_options.start = &options.start->reconstruction;
  a.reconstruction = Reconstruct(spots, targets, config.topographer, config.reconstruction, reconstruct_options);
  if (!a.reconstruction.ok) throw std::runtime_error(fmt::format("reconstruction failed: {}", a.reconstruction.message));
  std::vector<Eigen::Vector3d> cloud;
  cloud.reserve(a.reconstruction.points.size());
  for (const auto& p : a.reconstruction.points) cloud.push_back(p.point_mm);
  a.surface_fit = FitBiconic(cloud, SurfaceFitOptions(config, options));
  if (!a.surface_fit.ok) throw std::runtime_error(fmt::format("biconic fit failed: {}", a.surface_fit.message));
  // The maps use the configured radius for every input, as the paper's comparisons across sigma need; how far
  // the reconstructed points reach is reported beside it (beyond that radius Psi is extrapolated).
  const PowerMapOptions map_options = PowerMapOptionsFrom(config.reconstruction);
  a.covered_radius_mm = 0;
  for (const auto& p : a.reconstruction.points) {
    a.covered_radius_mm = std::max(a.covered_radius_mm, p.point_mm.head<2>().norm());
  }
  std::string why;
  const MapShape map_shape(a.reconstruction);
  const SurfaceEvaluator shape_eval = [&](double x, double y, model::SurfaceDerivatives* d) {
    return map_shape.Derivatives(x, y, d);
  };
  const bool maps_ok = map_shape.spline.empty() ? ComputePowerMaps(map_shape.shape, map_options, &a.power, &why)
                                                : ComputePowerMaps(shape_eval, map_options, &a.power, &why);
  if (!maps_ok) throw std::runtime_error(fmt::format("power maps failed: {}", why));
  if (truth) a.errors = HeightErrors(a.reconstruction.points, model::Biconic{*truth});
  a.supported_radius_mm = SupportedRadiusMm(a.reconstruction.points);
  a.maps_extrapolated = a.power.radius_mm > a.supported_radius_mm;
  AddWarnings(config, options, &a);
  if (options.clinical) {
    a.clinical_ok = ComputeClinicalIndices(a.power, shape_eval, a.supported_radius_mm, ClinicalOptions{}, &a.clinical,
                                           &a.clinical_message);
  } else {
    a.clinical_message = "not computed";
  }
  // A spline the spots do not determine gives maps with no evidence behind them: no clinical reading from it.
  if (const auto why = SplineUndetermined(a.reconstruction)) {
    a.warnings.push_back(*why);
    a.clinical_ok = false;
    a.clinical_message = *why;
  }
  return a;
}

}  // namespace topocal::topo
