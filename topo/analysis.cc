#include "topo/analysis.h"

#include <algorithm>
#include <cmath>
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

SurfaceErrors HeightErrors(const std::vector<ReconstructedPoint>& points, const model::Surface& truth) {
  SurfaceErrors e;
  if (points.empty()) return e;
  double lo = INFINITY, hi = -INFINITY, sum = 0, sum2 = 0;
  int n = 0;
  for (const auto& p : points) {
    model::SurfaceDerivatives d;
    if (!model::EvaluateSurface(truth, p.point_mm.x(), p.point_mm.y(), &d)) continue;
    const double ds = d.z - p.point_mm.z();  // Eq. 26: ideal - recovered
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

PowerMaps IdealPowerMaps(const model::BiconicParams& cornea, const model::ReconstructionSettings& settings) {
  const model::Biconic b{cornea};
  PowerMaps maps;
  std::string why;
  if (!ComputePowerMaps([&](double x, double y, model::SurfaceDerivatives* d) { return b.Evaluate(x, y, d); },
                        PowerMapOptionsFrom(settings), &maps, &why)) {
    throw std::runtime_error(fmt::format("ideal power maps: {}", why));
  }
  return maps;
}

Analysis AnalyzeSpots(const std::vector<MeasuredSpot>& spots, const std::vector<model::TargetPoint>& targets,
                      const model::Config& config, const model::BiconicParams* truth) {
  Analysis a;
  a.reconstruction = Reconstruct(spots, targets, config.topographer, config.reconstruction);
  if (!a.reconstruction.ok) throw std::runtime_error(fmt::format("reconstruction failed: {}", a.reconstruction.message));
  std::vector<Eigen::Vector3d> cloud;
  cloud.reserve(a.reconstruction.points.size());
  for (const auto& p : a.reconstruction.points) cloud.push_back(p.point_mm);
  a.surface_fit = FitBiconic(cloud);
  if (!a.surface_fit.ok) throw std::runtime_error(fmt::format("biconic fit failed: {}", a.surface_fit.message));
  // Sec. 4.2: piston B_1 and tilts B_2, B_3 do not affect the shape and are zeroed before the maps.
  TaylorPolynomial shape = a.reconstruction.surface;
  shape.coefficients().head(3).setZero();
  // The maps use the configured radius for every input, as the paper's comparisons across sigma need; how far
  // the reconstructed points reach is reported beside it (beyond that radius Psi is extrapolated).
  const PowerMapOptions map_options = PowerMapOptionsFrom(config.reconstruction);
  a.covered_radius_mm = 0;
  for (const auto& p : a.reconstruction.points) {
    a.covered_radius_mm = std::max(a.covered_radius_mm, p.point_mm.head<2>().norm());
  }
  std::string why;
  const bool maps_ok = ComputePowerMaps(shape, map_options, &a.power, &why);
  if (!maps_ok) throw std::runtime_error(fmt::format("power maps failed: {}", why));
  if (truth) a.errors = HeightErrors(a.reconstruction.points, model::Biconic{*truth});
  return a;
}

}  // namespace topocal::topo
