#include "pipeline/measurement_uncertainty.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <set>
#include <stdexcept>
#include <tuple>
#include <utility>

#include "pipeline/uncertainty.h"
#include "topo/clinical_indices.h"
#include "topo/power_map.h"
#include "util/parallel.h"
#include "util/io.h"

namespace topocal::pipeline {
namespace {

// The reading of an analysis a draw compares: its quantities and its polar axial map. nullopt: the analysis failed
// or did not give every quantity the measurement has.
struct Reading {
  std::vector<double> values;
  std::vector<double> axial_D;
};

std::optional<Reading> ReadingOf(const topo::Analysis& a, const std::vector<NamedQuantity>& reference) {
  const auto named = ReportedQuantities(a);
  if (named.size() != reference.size()) return std::nullopt;
  Reading r;
  for (size_t i = 0; i < named.size(); ++i) {
    if (named[i].name != reference[i].name || !std::isfinite(named[i].value)) return std::nullopt;
    r.values.push_back(named[i].value);
  }
  r.axial_D = a.power.axial_D;
  return r;
}

double Difference(double a, double b, bool axis) {
  double d = a - b;
  if (axis) d = std::remainder(d, 180.0);  // (-90, 90]
  return d;
}

// The spots the nominal analysis used, as measured.
std::vector<model::PlaneSpot> UsedSpots(const std::vector<model::PlaneSpot>& detected, const topo::Analysis& a) {
  std::set<model::SpotId> used;
  for (const auto& p : a.reconstruction.points) used.insert(p.id);
  std::vector<model::PlaneSpot> out;
  for (const auto& s : detected) {
    if (used.count(s.id)) out.push_back(s);
  }
  return out;
}

// The bias noise gives a reading that is not linear in the spots: a range or a maximum over a noisy map (pv, Kmax)
// rises with the noise, a smoothing spline's peak falls as its REML penalty grows with it. The draws, which add the
// measured noise again, shift the reading's mean by `sum / n`; when that shift stands out of the draws' own scatter
// (beyond 2 standard errors), the measurement itself carries a bias of the same sign: for a bias growing as the noise
// sigma it is shift / (sqrt(2) - 1) (the draws hold sqrt(2) sigma), the larger of the two laws (a bias growing as
// sigma^2 would be the shift itself). Left uncorrected and counted as a standard uncertainty (GUM F.2.4.5).
double NoiseBias(double sum, double sum_squares, int n) {
  if (n < 2) return 0.0;
  const double shift = sum / n;
  const double scatter2 = std::max(0.0, (sum_squares / n - shift * shift) * n / (n - 1));
  if (!(std::abs(shift) > 2.0 * std::sqrt(scatter2 / n))) return 0.0;
  return std::abs(shift) / (std::sqrt(2.0) - 1.0);
}

// A peak's location is determined only when the second peak (the highest value kPeakSeparationMm or farther away)
// lies below it by more than the U of that margin: otherwise noise or the calibration, within their uncertainty,
// could put the maximum elsewhere.
void MarkAmbiguousPeaks(MeasurementUncertainty* u) {
  const auto mark = [&](const std::string& margin, const std::vector<std::string>& location) {
    const QuantityUncertainty* m = u->Find(margin);
    if (!m || m->value > m->expanded) return;  // no margin: no second peak at all
    for (auto& q : u->quantities) {
      if (std::find(location.begin(), location.end(), q.name) == location.end()) continue;
      q.determined = false;
      q.expanded = std::numeric_limits<double>::quiet_NaN();
    }
  };
  mark("clinical.kmax.margin_D", {"clinical.kmax.x_mm", "clinical.kmax.y_mm"});
  mark("clinical.best_fit_sphere.elevation_peak_margin_um",
       {"clinical.best_fit_sphere.elevation_peak_x_mm", "clinical.best_fit_sphere.elevation_peak_y_mm"});
}

// `device` moved by `shift` (in the covariance's parameters and units).
model::Device ShiftedDevice(const model::Device& device, const std::vector<std::string>& names,
                            const Eigen::VectorXd& shift) {
  model::Device d = device;
  for (size_t k = 0; k < names.size(); ++k) {
    model::ShiftDeviceParameter(&d, names[k], shift(static_cast<Eigen::Index>(k)));
  }
  return d;
}

// The spots as `moved` sees them: each keeps its pixel on the sensor, the device moves under it.
std::vector<model::PlaneSpot> SpotsUnder(const model::Device& moved, const model::Device& device,
                                          std::vector<model::PlaneSpot> spots) {
  for (auto& s : spots) {
    s.position_mm = moved.camera.DetectionPlaneFromPixel(device.camera.PixelFromDetectionPlane(s.position_mm));
  }
  return spots;
}

// Spot draw `i`: the spots with normal noise of `sigma_um` per axis, seeded by (seed, i).
std::vector<model::PlaneSpot> NoisySpots(std::vector<model::PlaneSpot> spots, double sigma_um, std::uint32_t seed,
                                          std::uint32_t i) {
  std::seed_seq seq{seed, i};
  std::mt19937 rng(seq);
  std::normal_distribution<double> normal(0.0, sigma_um * 1e-3);
  for (auto& s : spots) {
    s.position_mm.x() += normal(rng);
    s.position_mm.y() += normal(rng);
  }
  return spots;
}

// Monte Carlo draws of the device: draw i = sum_j z_ij sqrt(l_j) v_j, z ~ N(0, 1) seeded by (seed, i).
std::vector<Eigen::VectorXd> DeviceDraws(const std::vector<Eigen::VectorXd>& scaled_directions,
                                         const UncertaintyOptions& options) {
  std::vector<Eigen::VectorXd> draws;
  if (scaled_directions.empty()) return draws;
  for (int i = 0; i < options.device_draws; ++i) {
    std::seed_seq seq{options.seed, 0x5eedu, static_cast<std::uint32_t>(i)};
    std::mt19937 rng(seq);
    std::normal_distribution<double> normal(0.0, 1.0);
    Eigen::VectorXd d = Eigen::VectorXd::Zero(scaled_directions.front().size());
    for (const auto& v : scaled_directions) d += normal(rng) * v;
    draws.push_back(d);
  }
  return draws;
}

// The sums of the readings' departures from the centre, per source: for each quantity and map sample the sum of
// squares, and (spot draws) the sum.
struct Departures {
  std::vector<double> var_device, var_spots, shift_spots, var_map_device, var_map_spots;
};

Departures Accumulate(const std::vector<std::optional<Reading>>& readings, size_t n_dir, const Reading& centre,
                      const std::vector<NamedQuantity>& reference, MeasurementUncertainty* u) {
  const size_t nq = reference.size(), n_map = centre.axial_D.size();
  Departures s{std::vector<double>(nq, 0.0), std::vector<double>(nq, 0.0), std::vector<double>(nq, 0.0),
               std::vector<double>(n_map, 0.0), std::vector<double>(n_map, 0.0)};
  for (size_t i = 0; i < readings.size(); ++i) {
    const auto& r = readings[i];
    if (!r || r->axial_D.size() != n_map) {
      ++u->failed_draws;
      continue;
    }
    const bool is_device = i < n_dir;
    if (is_device) ++u->device_analyses; else ++u->spot_draws;
    auto& var = is_device ? s.var_device : s.var_spots;
    auto& var_map = is_device ? s.var_map_device : s.var_map_spots;
    for (size_t q = 0; q < nq; ++q) {
      const double d = Difference(r->values[q], centre.values[q], reference[q].axis);
      var[q] += d * d;
      if (!is_device) s.shift_spots[q] += d;
    }
    for (size_t k = 0; k < n_map; ++k) {
      const double d = r->axial_D[k] - centre.axial_D[k];
      var_map[k] += d * d;
    }
  }
  return s;
}

// The standard uncertainties of each source, combined and expanded (k = 2); the map's U at each sample.
void Combine(const Departures& s, const std::vector<NamedQuantity>& reference, bool device_monte_carlo,
             MeasurementUncertainty* u) {
  const double spot_scale = 1.0 / u->spot_draws;  // the draws' mean is known (zero noise): n degrees of freedom
  // Linear: the sum over the directions is J S J'. Monte Carlo: the mean square over the draws (mean known).
  const double device_scale = device_monte_carlo && u->device_analyses > 0 ? 1.0 / u->device_analyses : 1.0;
  for (size_t q = 0; q < reference.size(); ++q) {
    QuantityUncertainty out;
    out.name = reference[q].name;
    out.unit = reference[q].unit;
    out.value = reference[q].value;
    out.u_device = std::sqrt(s.var_device[q] * device_scale);
    out.u_spots = std::sqrt(s.var_spots[q] * spot_scale);
    out.u_bias = NoiseBias(s.shift_spots[q], s.var_spots[q], u->spot_draws);
    out.u_resolution = reference[q].step / std::sqrt(12.0);
    out.expanded = 2.0 * std::sqrt(out.u_device * out.u_device + out.u_spots * out.u_spots +
                                   out.u_bias * out.u_bias + out.u_resolution * out.u_resolution);
    u->quantities.push_back(out);
  }
  u->axial_expanded_D.resize(s.var_map_device.size());
  for (size_t k = 0; k < s.var_map_device.size(); ++k) {
    u->axial_expanded_D[k] = 2.0 * std::sqrt(s.var_map_device[k] * device_scale + s.var_map_spots[k] * spot_scale);
  }
}

// The area-weighted rms and the largest value of a polar map (topo::PowerMaps layout) over the disc of `radius_mm`;
// non-finite samples (outside the data) are left out.
std::pair<double, double> DiscRmsAndMax(const std::vector<double>& map, const topo::PowerMaps& layout,
                                        double radius_mm) {
  double sum = 0, weight = 0, largest = 0;
  for (int j = 0; j < layout.meridians; ++j) {
    for (int k = 0; k < layout.radial_samples; ++k) {
      const double rho = layout.RhoMm(k);
      const double v = map[static_cast<size_t>(j) * layout.radial_samples + k];
      if (rho > radius_mm || !std::isfinite(v)) continue;
      sum += rho * v * v;
      weight += rho;
      largest = std::max(largest, v);
    }
  }
  return {weight > 0 ? std::sqrt(sum / weight) : 0.0, largest};
}

// The spline's smoothing bias of a map's peaks and ranges (QuantityUncertainty::lower_bound).
void MarkSmoothingBias(MeasurementUncertainty* u) {
  static const std::set<std::string> kPeaksAndRanges = {
      "power.pv_tangential_D", "power.pv_axial_D", "power.central_axial_D", "clinical.kmax.power_D",
      "clinical.kmax.margin_D", "clinical.inferior_superior_D"};
  for (auto& q : u->quantities) q.lower_bound = kPeaksAndRanges.count(q.name) > 0;
}

}  // namespace

const QuantityUncertainty* MeasurementUncertainty::Find(const std::string& name) const {
  for (const auto& q : quantities) {
    if (q.name == name) return &q;
  }
  return nullptr;
}

std::vector<NamedQuantity> ReportedQuantities(const topo::Analysis& a) {
  const auto& f = a.surface_fit;
  const auto& p = f.params;
  std::vector<NamedQuantity> q = {
      {"surface_fit.rx_mm", "mm", p.rx_mm, false},
      {"surface_fit.ry_mm", "mm", p.ry_mm, false},
      {"surface_fit.kx", "", p.kx, false},
      {"surface_fit.ky", "", p.ky, false},
      {"surface_fit.alpha_deg", "deg", p.alpha_deg, true},
      {"surface_fit.vertex_um", "um", p.z0_mm * 1e3, false}};
  if (f.mode != topo::BiconicFitMode::kPaper) {
    q.push_back({"surface_fit.apex_x_mm", "mm", f.apex_mm.x(), false});
    q.push_back({"surface_fit.apex_y_mm", "mm", f.apex_mm.y(), false});
    q.push_back({"surface_fit.decentration_mm", "mm", f.DecentrationMm(), false});
  }
  if (f.mode == topo::BiconicFitMode::kFreeApex) {
    q.push_back({"surface_fit.tilt_x_deg", "deg", p.tilt_x_deg, false});
    q.push_back({"surface_fit.tilt_y_deg", "deg", p.tilt_y_deg, false});
    q.push_back({"surface_fit.tilt_deg", "deg", f.TiltDeg(), false});
  }
  q.push_back({"power.pv_tangential_D", "D", a.power.pv_tangential_D});
  q.push_back({"power.pv_axial_D", "D", a.power.pv_axial_D});
  q.push_back({"power.central_axial_D", "D", topo::MeanAxialPowerD(a.power, kCentralPowerRadiusMm)});
  if (a.clinical_ok) {
    const auto& c = a.clinical;
    // The map's sample steps: an axis between meridians, a location between samples (radially, and along the
    // meridian's arc at the location's radius).
    const double axis_step_deg = a.power.meridians > 0 ? 360.0 / a.power.meridians : 0.0;
    const auto location_step_mm = [&](const Eigen::Vector2d& at) {
      const double radial = a.power.radial_samples > 0 ? a.power.radius_mm / a.power.radial_samples : 0.0;
      return std::max(radial, at.norm() * axis_step_deg * M_PI / 180.0);
    };
    const double kmax_step = location_step_mm(c.kmax_at_mm);
    q.push_back({"clinical.sim_k.steep_D", "D", c.steep_k_D});
    q.push_back({"clinical.sim_k.steep_axis_deg", "deg", c.steep_axis_deg, true, axis_step_deg});
    q.push_back({"clinical.sim_k.flat_D", "D", c.flat_k_D});
    q.push_back({"clinical.sim_k.flat_axis_deg", "deg", c.flat_axis_deg, true, axis_step_deg});
    q.push_back({"clinical.sim_k.cylinder_D", "D", c.CylinderD()});
    q.push_back({"clinical.kmax.power_D", "D", c.kmax_D});
    // How far the second peak lies below (its U says whether the data tell the two apart; MarkAmbiguousPeaks).
    if (std::isfinite(c.kmax_runner_up_D)) q.push_back({"clinical.kmax.margin_D", "D", c.kmax_D - c.kmax_runner_up_D});
    q.push_back({"clinical.kmax.x_mm", "mm", c.kmax_at_mm.x(), false, kmax_step});
    q.push_back({"clinical.kmax.y_mm", "mm", c.kmax_at_mm.y(), false, kmax_step});
    q.push_back({"clinical.best_fit_sphere.radius_mm", "mm", c.bfs_radius_mm});
    q.push_back({"clinical.best_fit_sphere.elevation_peak_um", "um", c.elevation_peak_um});
    if (std::isfinite(c.elevation_runner_up_um)) {
      q.push_back({"clinical.best_fit_sphere.elevation_peak_margin_um", "um", c.elevation_peak_um - c.elevation_runner_up_um});
    }
    q.push_back({"clinical.best_fit_sphere.elevation_peak_x_mm", "mm", c.elevation_peak_at_mm.x(), false,
                 topo::kElevationPeakStepMm});
    q.push_back({"clinical.best_fit_sphere.elevation_peak_y_mm", "mm", c.elevation_peak_at_mm.y(), false,
                 topo::kElevationPeakStepMm});
    if (c.is_available) q.push_back({"clinical.inferior_superior_D", "D", c.inferior_superior_D});
  }
  return q;
}

MeasurementUncertainty PropagateMeasurementUncertainty(const std::vector<model::PlaneSpot>& detected,
                                                       const model::Device& device,
                                                       const std::optional<model::DeviceCovariance>& covariance,
                                                       const model::Config& config, const topo::Analysis& nominal,
                                                       const UncertaintyOptions& options) {
  if (options.spot_draws < 2) throw util::InputError("uncertainty: at least 2 spot-noise draws are needed");
  MeasurementUncertainty u;
  const std::vector<NamedQuantity> reference = ReportedQuantities(nominal);
  const std::vector<model::PlaneSpot> used = UsedSpots(detected, nominal);
  // Every analysis below keeps the surface model the measurement chose ("auto" deciding again on a draw would
  // jump between models) and starts from the measurement's analysis.
  model::Config fixed = config;
  if (!nominal.reconstruction.surface_model.empty()) fixed.reconstruction.surface_model = nominal.reconstruction.surface_model;
  topo::AnalysisOptions draw_options;
  draw_options.stddev = draw_options.adequacy = false;
  draw_options.start = &nominal;
  // One analysis of `spots` (distorted, on `d`'s detection plane) through `d`.
  const auto analyze = [&](const model::Device& d,
                           const std::vector<model::PlaneSpot>& spots) -> std::optional<Reading> {
    try {
      const auto a = AnalyzeThroughDevice(UndistortSpots(spots, d.distortion), d, fixed, nullptr, draw_options);
      return ReadingOf(a, reference);
    } catch (const std::runtime_error&) {
      return std::nullopt;
    }
  };
  // The reference every draw is compared with: the same spots through the same warm start (the warm start agrees
  // with a cold analysis only to the refinement's convergence, so draws are differenced against it, not against
  // `nominal` itself).
  const auto centre = analyze(device, used);
  if (!centre) throw std::runtime_error("uncertainty: the measurement's own spots do not reconstruct again");

  // Device: one analysis per scaled eigen-direction (or Monte Carlo draw); each spot keeps its pixel, the device
  // moves under it.
  std::vector<Eigen::VectorXd> directions;
  if (covariance) {
    u.device_covariance = true;
    u.device_parameters = covariance->names;
    directions = ScaledEigenDirections(covariance->matrix);
    u.device_directions = static_cast<int>(directions.size());
    u.device_monte_carlo = options.device_draws > 0;
    if (options.device_draws > 0) directions = DeviceDraws(directions, options);
  }
  const size_t n_dir = directions.size();
  const size_t n_spot = static_cast<size_t>(options.spot_draws);
  u.configured_spot_sigma_um = config.reconstruction.spot_uncertainty_um;
  const double ratio = nominal.reconstruction.adequacy_ratio;
  u.spot_sigma_um = u.configured_spot_sigma_um * (ratio > 0 ? ratio : 1.0);
  std::vector<std::optional<Reading>> readings(n_dir + n_spot);
  util::ParallelFor(n_dir + n_spot, std::max(0, options.jobs), [&](size_t i) {
    if (i < n_dir) {
      const model::Device d = ShiftedDevice(device, covariance->names, directions[i]);
      readings[i] = analyze(d, SpotsUnder(d, device, used));
    } else {
      readings[i] = analyze(device, NoisySpots(used, u.spot_sigma_um, options.seed, static_cast<std::uint32_t>(i - n_dir)));
    }
  });

  const Departures sums = Accumulate(readings, n_dir, *centre, reference, &u);
  // A failed device direction is not dropped silently (that would shrink u_device): counted, and the measurement's
  // caller reports failed_draws.
  if (2 * u.failed_draws > static_cast<int>(readings.size()) || u.spot_draws < 2) {
    throw std::runtime_error(fmt::format("uncertainty: {} of {} analyses failed", u.failed_draws, readings.size()));
  }
  Combine(sums, reference, options.device_draws > 0, &u);
  std::tie(u.axial_rms_expanded_D, u.axial_max_expanded_D) =
      DiscRmsAndMax(u.axial_expanded_D, nominal.power, nominal.supported_radius_mm);
  MarkAmbiguousPeaks(&u);
  if (nominal.reconstruction.surface_model == "spline") MarkSmoothingBias(&u);
  return u;
}

std::optional<std::string> UncertaintyRefusal(const MeasurementUncertainty& u) {
  if (!(u.axial_max_expanded_D > kMaxAxialExpandedD)) return std::nullopt;
  return fmt::format("its axial map is too uncertain for a clinical reading: U (k = 2) up to {:.2f} D ({:.2f} D "
                     "rms) over the supported disc, above {:.2f} D (the spots' noise measured in this image is {:.2f} "
                     "x the configured; docs/uncertainty.md)",
                     u.axial_max_expanded_D, u.axial_rms_expanded_D, kMaxAxialExpandedD,
                     u.configured_spot_sigma_um > 0 ? u.spot_sigma_um / u.configured_spot_sigma_um : 0.0);
}

std::string FormatWithUncertainty(double value, double expanded, int fallback_decimals) {
  if (!(expanded > 0) || !std::isfinite(expanded)) return fmt::format("{:.{}f}", value, fallback_decimals);
  // Two significant digits of U: one decimal place past its leading digit's; when rounding carries U into a
  // third digit (0.0996 -> 0.100), one place fewer.
  int decimals = 1 - static_cast<int>(std::floor(std::log10(expanded)));
  if (std::llround(expanded * std::pow(10.0, decimals)) >= 100) --decimals;
  if (decimals >= 0) return fmt::format("{:.{}f} +- {:.{}f}", value, decimals, expanded, decimals);
  const double unit = std::pow(10.0, -decimals);  // U of 100 or more: both rounded to tens, hundreds, ...
  return fmt::format("{:.0f} +- {:.0f}", std::round(value / unit) * unit, std::round(expanded / unit) * unit);
}

}  // namespace topocal::pipeline
