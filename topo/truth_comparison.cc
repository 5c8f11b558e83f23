#include "topo/truth_comparison.h"

#include <cmath>
#include <functional>
#include <random>
#include <stdexcept>

#include <fmt/format.h>

#include "model/null_screen.h"

namespace topocal::topo {

namespace {

// Peak of (biconic - surface) in um over a 0.05 mm grid within the disc of this radius.
double ElevationPeakUm(const model::BiconicParams& reference, const std::function<double(double, double)>& height,
                       double radius_mm, Eigen::Vector2d* at) {
  constexpr double kStepMm = 0.05;
  const model::Surface b = model::Biconic{reference};
  double peak = -INFINITY;
  const int half = static_cast<int>(std::floor(radius_mm / kStepMm));
  for (int iy = -half; iy <= half; ++iy) {
    for (int ix = -half; ix <= half; ++ix) {
      const double x = ix * kStepMm, y = iy * kStepMm;
      if (std::hypot(x, y) > radius_mm) continue;
      const auto delta = HeightDifferenceMm(b, x, y, height(x, y));  // Eq. 26
      if (!delta) continue;
      const double e = *delta * 1e3;
      if (e > peak) {
        peak = e;
        *at = Eigen::Vector2d(x, y);
      }
    }
  }
  return peak;
}

}  // namespace

TruthComparison CompareWithTruth(const Analysis& a, const model::Surface& truth,
                                 const model::ReconstructionSettings& settings) {
  TruthComparison c;
  model::SurfaceDerivatives o;
  if (!model::EvaluateSurface(truth, 0.0, 0.0, &o)) throw std::runtime_error("truth: undefined at the origin");
  const SurfaceEvaluator shape = [&](double x, double y, model::SurfaceDerivatives* d) {
    if (!model::EvaluateSurface(truth, x, y, d)) return false;
    d->z -= o.z + o.zx * x + o.zy * y;
    d->zx -= o.zx;
    d->zy -= o.zy;
    return true;
  };
  PowerMaps maps;
  std::string why;
  if (!ComputePowerMaps(shape, PowerMapOptionsFrom(settings), &maps, &why)) {
    throw std::runtime_error(fmt::format("truth power maps: {}", why));
  }
  const PowerMaps& got = a.power;
  if (got.meridians != maps.meridians || got.radial_samples != maps.radial_samples) {
    throw std::runtime_error("truth power maps: grid differs from the reconstruction's");
  }
  c.radius_mm = std::min(a.supported_radius_mm, maps.radius_mm);
  double sa = 0, st = 0;
  int n = 0;
  for (int j = 0; j < maps.meridians; ++j) {
    for (int k = 0; k < maps.radial_samples && maps.RhoMm(k) <= c.radius_mm; ++k) {
      const size_t i = static_cast<size_t>(j) * maps.radial_samples + k;
      const double ea = got.axial_D[i] - maps.axial_D[i], et = got.tangential_D[i] - maps.tangential_D[i];
      sa += ea * ea;
      st += et * et;
      c.axial_max_D = std::max(c.axial_max_D, std::abs(ea));
      c.tangential_max_D = std::max(c.tangential_max_D, std::abs(et));
      ++n;
    }
  }
  c.axial_rms_D = n ? std::sqrt(sa / n) : 0;
  c.tangential_rms_D = n ? std::sqrt(st / n) : 0;
  c.height_rms_um = HeightErrors(a.reconstruction.points, truth).rms_um;
  if (!ComputeClinicalIndices(maps, shape, a.supported_radius_mm, ClinicalOptions{}, &c.truth, &why)) {
    throw std::runtime_error(fmt::format("truth clinical indices: {}", why));
  }
  if (a.clinical_ok) {
    c.kmax_error_D = a.clinical.kmax_D - c.truth.kmax_D;
    c.kmax_location_error_mm = (a.clinical.kmax_at_mm - c.truth.kmax_at_mm).norm();
    c.steep_k_error_D = a.clinical.steep_k_D - c.truth.steep_k_D;
    c.flat_k_error_D = a.clinical.flat_k_D - c.truth.flat_k_D;
  }
  // Cone height against the best-fit biconic, the same way on both surfaces.
  std::vector<Eigen::Vector3d> truth_cloud;
  for (const auto& p : a.reconstruction.points) {
    model::SurfaceDerivatives d;
    if (model::EvaluateSurface(truth, p.point_mm.x(), p.point_mm.y(), &d)) truth_cloud.emplace_back(p.point_mm.x(), p.point_mm.y(), d.z);
  }
  const BiconicFit truth_fit = FitBiconic(truth_cloud);
  if (!truth_fit.ok) throw std::runtime_error(fmt::format("truth biconic fit: {}", truth_fit.message));
  c.cone_height_true_um = ElevationPeakUm(truth_fit.params, [&](double x, double y) {
    model::SurfaceDerivatives d;
    return model::EvaluateSurface(truth, x, y, &d) ? d.z : NAN;
  }, c.radius_mm, &c.cone_true_at_mm);
  c.cone_height_recovered_um = ElevationPeakUm(a.surface_fit.params, [&](double x, double y) {
    return a.reconstruction.Height(x, y);
  }, c.radius_mm, &c.cone_recovered_at_mm);
  return c;
}

SimulatedMeasurement MeasureSimulatedCornea(const model::Surface& truth, const model::Config& config,
                                            double spot_noise_mm, unsigned seed) {
  const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
  const auto image = model::SynthesizeImage(truth, model::Topographer{config.topographer}, design.targets);
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::vector<model::PlaneSpot> spots;
  spots.reserve(image.spots.size());
  for (const auto& s : image.spots) {
    Eigen::Vector2d p = s.position_mm;
    if (spot_noise_mm > 0) p += spot_noise_mm * Eigen::Vector2d(noise(rng), noise(rng));
    spots.push_back({s.id, p});
  }
  SimulatedMeasurement m;
  m.spots = static_cast<int>(spots.size());
  m.analysis = AnalyzeSpots(spots, design.targets, config, nullptr);
  m.comparison = CompareWithTruth(m.analysis, truth, config.reconstruction);
  return m;
}

}  // namespace topocal::topo
