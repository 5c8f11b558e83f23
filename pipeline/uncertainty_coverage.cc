#include "pipeline/uncertainty_coverage.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <stdexcept>


#include "calib/device_fit.h"
#include "model/freeform_test_set.h"
#include "model/null_screen.h"
#include "pipeline/device_calibration.h"
#include "pipeline/measure_spots.h"
#include "pipeline/measurement_uncertainty.h"
#include "util/parallel.h"
#include "util/io.h"

namespace topocal::pipeline {
namespace {

constexpr double kBallRadiiMm[] = {6.5, 7.8, 9.0};
constexpr double kBallPlacementMm = 0.3;

struct Pull {
  std::string name;
  double pull = 0;
  bool lower_bound = false;  // QuantityUncertainty::lower_bound
};

struct CaseOutcome {
  std::optional<std::string> failure;
  std::string surface_model;  // the one the measurement used: "polynomial" or "spline"
  std::vector<Pull> measurement, device;
};

// The eyes of the study: the paper cornea, then topocal's freeform test set, in turn.
struct Eye {
  std::string name;
  model::Surface surface;
};
std::vector<Eye> StudyEyes(const model::Config& config, const std::string& kind) {
  std::vector<Eye> eyes = {{"paper cornea", model::Biconic{config.cornea}}};
  for (auto& t : model::FreeformTestSet()) {
    if (kind.empty() || t.kind == kind) eyes.push_back({t.name, t.surface});
  }
  return eyes;
}

std::vector<Eigen::Vector2d> Noisy(std::vector<Eigen::Vector2d> px, double sigma, std::mt19937& rng) {
  std::normal_distribution<double> noise(0.0, sigma);
  for (auto& p : px) p += Eigen::Vector2d(noise(rng), noise(rng));
  return px;
}

CaseOutcome RunCase(const model::Config& config, const model::Device& nominal,
                    const std::vector<model::TargetPoint>& targets, const std::vector<Eye>& eyes,
                    const CoverageOptions& o, int i) {
  CaseOutcome out;
  std::seed_seq seq{o.seed, static_cast<std::uint32_t>(i)};
  std::mt19937 rng(seq);
  const model::Device truth = DrawAssembledDevice(nominal, rng);
  // Three balls placed by hand within +-0.3 mm; the first, the datum, at the working position z = 0 (so that the
  // fitted device's frame is the truth's: its parameters compare one by one).
  std::uniform_real_distribution<double> place(-kBallPlacementMm, kBallPlacementMm);
  std::vector<calib::BallView> views;
  for (const double radius : kBallRadiiMm) {
    const double x = place(rng), y = place(rng), z = views.empty() ? 0.0 : place(rng);
    const auto ball = SimulateBall(truth, config, radius, Eigen::Vector3d(x, y, z));
    calib::BallView v{fmt::format("ball {}", radius), radius, {}};
    std::normal_distribution<double> noise(0.0, o.spot_noise_px);
    for (const auto& [id, px] : ball.spots_px) v.spots_px.emplace_back(id, px + Eigen::Vector2d(noise(rng), noise(rng)));
    views.push_back(std::move(v));
  }
  calib::DeviceFitOptions fit_options;
  fit_options.spot_sigma_px = o.spot_noise_px;
  const auto fit = calib::FitDevice(nominal, config.topographer, targets, views, fit_options);
  if (!fit.ok) {
    out.failure = fmt::format("case {}: device fit: {}", i, fit.message);
    return out;
  }
  const model::DeviceCovariance covariance = fit.Covariance();
  for (const auto& p : fit.parameters) {
    if (p.stddev > 0) out.device.push_back({p.name, (p.value - model::DeviceParameterOf(truth, p.name)) / p.stddev});
  }

  // The eye through the true device: exact pixels (the truth's reading) and noisy ones (the measurement's).
  const Eye& eye = eyes[static_cast<size_t>(i) % eyes.size()];
  const auto image = model::SynthesizeImage(eye.surface, truth, config.topographer, targets);
  std::vector<model::SpotId> ids;
  std::vector<Eigen::Vector2d> exact_px;
  for (const auto& s : image.spots) {
    ids.push_back(s.id);
    exact_px.push_back(truth.PixelOf(s.position_mm));
  }
  const auto noisy_px = Noisy(exact_px, o.spot_noise_px, rng);
  const auto through = [&](const model::Device& d, const std::vector<Eigen::Vector2d>& px) {
    std::vector<model::PlaneSpot> spots;
    for (size_t k = 0; k < px.size(); ++k) spots.push_back({ids[k], d.camera.DetectionPlaneFromPixel(px[k])});
    return spots;
  };
  model::Config measure_config = config;
  measure_config.reconstruction.surface_model = "auto";  // as reconstruct measures eyes
  try {
    const auto detected = through(fit.device, noisy_px);
    const auto analysis = AnalyzeThroughDevice(UndistortSpots(detected, fit.device.distortion), fit.device,
                                               measure_config, nullptr);
    UncertaintyOptions u_options;
    u_options.spot_draws = o.spot_draws;
    u_options.seed = o.seed + static_cast<std::uint32_t>(i);
    u_options.jobs = 1;
    const auto u = PropagateMeasurementUncertainty(detected, fit.device, covariance, measure_config, analysis, u_options);
    // The truth: the same method (the surface model the measurement chose) on the exact spots, through the truth.
    out.surface_model = analysis.reconstruction.surface_model;
    model::Config truth_config = measure_config;
    truth_config.reconstruction.surface_model = analysis.reconstruction.surface_model;
    const auto exact = through(truth, exact_px);
    const auto truth_analysis = AnalyzeThroughDevice(UndistortSpots(exact, truth.distortion), truth, truth_config, nullptr);
    std::map<std::string, NamedQuantity> truth_values;
    for (const auto& q : ReportedQuantities(truth_analysis)) truth_values[q.name] = q;
    for (const auto& q : u.quantities) {
      const auto t = truth_values.find(q.name);
      if (t == truth_values.end() || !(q.expanded > 0)) continue;
      double d = q.value - t->second.value;
      if (t->second.axis) d = std::remainder(d, 180.0);
      out.measurement.push_back({q.name, d / (0.5 * q.expanded), q.lower_bound});
    }
  } catch (const std::runtime_error& e) {
    out.failure = fmt::format("case {} ({}): {}", i, eye.name, e.what());
  }
  return out;
}

CoverageRow Summarise(const std::string& name, const std::vector<double>& pulls) {
  CoverageRow r;
  r.quantity = name;
  r.n = static_cast<int>(pulls.size());
  double sum2 = 0;
  int covered = 0;
  for (const double p : pulls) {
    sum2 += p * p;
    covered += std::abs(p) <= 2.0;
    r.max_abs_pull = std::max(r.max_abs_pull, std::abs(p));
  }
  if (r.n > 0) {
    r.pull_rms = std::sqrt(sum2 / r.n);
    r.covered = static_cast<double>(covered) / r.n;
  }
  return r;
}

// Rows per quantity, in the order met. `all` (optional) gathers the pulls of the overall row: every quantity but the
// peaks' locations (bimodal when a second peak competes: a pull of hundreds when the truth's peak is the twin; their
// coverage is in their rows, but they would swamp the RMS of everything else) and U's marked as lower bounds,
// which go to `lower_bounds`.
std::vector<CoverageRow> Rows(const std::vector<Pull>& pulls, std::vector<double>* all,
                              std::vector<double>* lower_bounds) {
  std::vector<std::string> order;
  std::map<std::string, std::vector<double>> by_name;
  const auto is_location = [](const std::string& name) {
    return name.rfind("clinical.kmax.", 0) == 0 ? name != "clinical.kmax.power_D" && name != "clinical.kmax.margin_D"
                                                : name.find("elevation_peak_x_mm") != std::string::npos ||
                                                      name.find("elevation_peak_y_mm") != std::string::npos;
  };
  for (const auto& p : pulls) {
    if (!by_name.count(p.name)) order.push_back(p.name);
    by_name[p.name].push_back(p.pull);
    if (!all || is_location(p.name)) continue;
    (p.lower_bound ? lower_bounds : all)->push_back(p.pull);
  }
  std::vector<CoverageRow> rows;
  for (const auto& name : order) rows.push_back(Summarise(name, by_name[name]));
  return rows;
}

}  // namespace

const CoverageGroup* CoverageResult::Group(const std::string& surface_model) const {
  for (const auto& g : measurement) {
    if (g.surface_model == surface_model) return &g;
  }
  return nullptr;
}

model::Device DrawAssembledDevice(const model::Device& nominal, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  model::Device d = nominal;
  d.screen.rx_deg = u(rng);
  d.screen.ry_deg = u(rng);
  d.screen.rz_deg = u(rng);
  d.screen.tx_mm = 0.2 * u(rng);
  d.screen.ty_mm = 0.2 * u(rng);
  d.screen.tz_mm = 0.5 * u(rng);
  d.camera.principal_point_px += Eigen::Vector2d(0.03 * u(rng), 0.03 * u(rng)) / d.camera.PitchMm();
  d.camera.a_mm *= 1.0 + 0.01 * u(rng);
  model::SeidelParams s;
  s.sigma_per_mm2 = u(rng) < 0 ? -6.3e-5 : 6.3e-5;
  d.distortion = s;
  return d;
}

CoverageResult RunUncertaintyCoverage(const model::Config& config, const model::Device& nominal,
                                      const CoverageOptions& o) {
  if (o.cases < 1) throw util::InputError("coverage: at least one case is needed");
  if (!(o.spot_noise_px > 0)) throw util::InputError("coverage: the spot noise must be > 0 px");
  const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
  if (!o.eye_kind.empty() && o.eye_kind != "biconic" && o.eye_kind != "keratoconus" && o.eye_kind != "ablation" &&
      o.eye_kind != "irregular") {
    throw util::InputError(fmt::format("coverage: no eyes of kind '{}'", o.eye_kind));
  }
  const auto eyes = StudyEyes(config, o.eye_kind);
  std::vector<CaseOutcome> outcomes(static_cast<size_t>(o.cases));
  util::ParallelFor(outcomes.size(), std::max(0, o.jobs), [&](size_t i) {
    outcomes[i] = RunCase(config, nominal, design.targets, eyes, o, static_cast<int>(i));
  });
  CoverageResult r;
  r.cases = o.cases;
  std::map<std::string, std::vector<Pull>> measurement;
  std::vector<Pull> device;
  for (const auto& c : outcomes) {
    if (c.failure) {
      ++r.failed;
      r.failures.push_back(*c.failure);
    }
    measurement[c.surface_model].insert(measurement[c.surface_model].end(), c.measurement.begin(), c.measurement.end());
    device.insert(device.end(), c.device.begin(), c.device.end());
  }
  for (const auto& [model, pulls] : measurement) {
    CoverageGroup g;
    g.surface_model = model;
    for (const auto& c : outcomes) g.cases += !c.failure && c.surface_model == model;
    std::vector<double> all, lower_bounds;
    g.rows = Rows(pulls, &all, &lower_bounds);
    g.overall = Summarise("all but the peaks' locations and the lower bounds", all);
    g.lower_bounds = Summarise("U marked a lower bound (spline: a map's peaks and ranges)", lower_bounds);
    r.measurement.push_back(std::move(g));
  }
  r.device = Rows(device, nullptr, nullptr);
  return r;
}

}  // namespace topocal::pipeline
