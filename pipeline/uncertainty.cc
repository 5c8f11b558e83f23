#include "pipeline/uncertainty.h"

#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <optional>
#include <random>
#include <stdexcept>

#include "pipeline/detection_plane.h"
#include "topo/analysis.h"
#include "util/parallel.h"
#include "util/io.h"

namespace topocal::pipeline {
namespace {

// The distortion parameters of model::CameraModel (its lens model's and the centre) by the names the calibration
// file uses; nullptr for another name.
double* Parameter(model::CameraModel& c, const std::string& name) {
  const auto names = model::LensParameterNames(c.lens);
  if (const auto it = std::find(names.begin(), names.end(), name); it != names.end()) {
    return &c.dist[static_cast<size_t>(it - names.begin())];
  }
  if (name == "ex") return &c.distortion_centre.x();
  if (name == "ey") return &c.distortion_centre.y();
  return nullptr;
}

// Whether `name` is a distortion parameter of a camera of any lens model.
bool IsDistortionParameter(const std::string& name) {
  bool found = false;
  model::ForEachLensModel([&](auto lens) {
    model::CameraModel probe;
    probe.lens = lens;
    found = found || Parameter(probe, name) != nullptr;
  });
  return found;
}

// The quantities of ClinicalUncertainty, in the order a draw stores them.
constexpr std::array<const char*, 9> kQuantities = {"rx_mm", "ry_mm", "kx", "ky", "alpha_deg", "pv_tangential_D",
                                                     "pv_axial_D", "radius_mm", "central_axial_power_D"};

void RequireShape(const calib::ParameterCovariance& covariance) {
  const auto n_names = static_cast<Eigen::Index>(covariance.names.size());
  if (covariance.matrix.rows() != n_names || covariance.matrix.cols() != n_names) {
    throw util::InputError(fmt::format("uncertainty: the covariance matrix is {} x {} but has {} parameter names",
                                            covariance.matrix.rows(), covariance.matrix.cols(), n_names));
  }
}

// Indices into `covariance` of the distortion parameters with a spread.
std::vector<Eigen::Index> DrawnIndices(const calib::ParameterCovariance& covariance) {
  RequireShape(covariance);
  std::vector<Eigen::Index> drawn;
  for (Eigen::Index i = 0; i < covariance.matrix.rows(); ++i) {
    const double var = covariance.matrix(i, i);
    if (var > 0 && std::isfinite(var) && IsDistortionParameter(covariance.names[static_cast<size_t>(i)])) {
      drawn.push_back(i);
    }
  }
  return drawn;
}

// The drawn parameters' joint covariance.
Eigen::MatrixXd DrawnCovariance(const calib::ParameterCovariance& covariance,
                                const std::vector<Eigen::Index>& drawn_index) {
  const auto m = static_cast<Eigen::Index>(drawn_index.size());
  Eigen::MatrixXd drawn_covariance(m, m);
  for (Eigen::Index a = 0; a < m; ++a) {
    for (Eigen::Index b = 0; b < m; ++b) {
      drawn_covariance(a, b) =
          covariance.matrix(drawn_index[static_cast<size_t>(a)], drawn_index[static_cast<size_t>(b)]);
    }
  }
  return drawn_covariance;
}

// Its factor L (L L' = S): a draw is mean + L z, z ~ N(0, I).
// A symmetric eigendecomposition rather than a Cholesky factor, so that a covariance that is only positive
// semi-definite (rounding in a stored file) still factors; negative rounding-level eigenvalues are clamped to 0.
Eigen::MatrixXd DrawFactor(const calib::ParameterCovariance& covariance, const std::vector<Eigen::Index>& drawn_index) {
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(DrawnCovariance(covariance, drawn_index));
  if (eigen.info() != Eigen::Success) throw util::InputError("uncertainty: the covariance cannot be factored");
  return eigen.eigenvectors() * eigen.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal();
}

// The nominal analysis (the calibration as it is): every draw moves the spots by micrometres or less from it, so
// each draw starts from it: its slope-fit factor (no draw factorises the least-squares matrix anew), its surface
// (the incidence points' refinement begins there, not on the design sphere) and its fit (Gauss-Newton steps).
// Draws read only the biconic parameters and the power maps: no standard deviations, adequacy or clinical indices.
std::optional<topo::Analysis> NominalAnalysis(const std::vector<model::PlaneSpot>& spots,
                                              const DetectionPlaneModel& on_plane,
                                              const std::vector<model::TargetPoint>& targets,
                                              const model::Config& config) {
  std::optional<topo::Analysis> nominal;
  if (on_plane.ok) {
    topo::AnalysisOptions o;
    o.stddev = o.adequacy = o.clinical = false;
    try {
      nominal = topo::AnalyzeSpots(UndistortSpots(spots, on_plane.distortion), targets, config, nullptr, o);
    } catch (const std::runtime_error&) {
      // No start then: every draw starts cold (and fails or not on its own).
    }
  }
  return nominal;
}

using DrawnQuantities = std::array<double, kQuantities.size()>;

DrawnQuantities QuantitiesOf(const topo::Analysis& a) {
  const auto& p = a.surface_fit.params;
  return {p.rx_mm, p.ry_mm, p.kx, p.ky, p.alpha_deg, a.power.pv_tangential_D, a.power.pv_axial_D,
          0.5 * (p.rx_mm + p.ry_mm), topo::MeanAxialPowerD(a.power, kCentralPowerRadiusMm)};
}

// What every analysis of a moved calibration shares.
struct MovedAnalyses {
  const std::vector<model::PlaneSpot>& spots;
  const model::CameraModel& calibrated;
  const std::vector<std::string>& names;  // the moved parameters
  const model::TopographerCamera& camera;
  const model::Config& config;
  const std::vector<model::TargetPoint>& targets;
  topo::AnalysisOptions options;  // started from the nominal analysis
  bool nominal_verified = false;  // the nominal conversion was verified on the sensor grid: the moved ones are not

  // The quantities of the spots analysed with the named parameters moved by `delta`; nullopt when the moved
  // calibration cannot be put on the detection plane or the analysis fails. Spots it cannot undistort are counted
  // into `undistort_failures`.
  std::optional<DrawnQuantities> Analyse(const Eigen::VectorXd& delta, int* undistort_failures) const {
    model::CameraModel moved = calibrated;
    for (Eigen::Index k = 0; k < delta.size(); ++k) *Parameter(moved, names[static_cast<size_t>(k)]) += delta(k);
    const auto on_plane = nominal_verified ? DetectionPlaneModelUnverified(moved, camera)
                                           : DetectionPlaneModelOf(moved, camera);
    if (!on_plane.ok) return std::nullopt;
    try {
      const auto undistorted = UndistortSpots(spots, on_plane.distortion, undistort_failures);
      return QuantitiesOf(topo::AnalyzeSpots(undistorted, targets, config, nullptr, options));
    } catch (const std::runtime_error&) {
      return std::nullopt;
    }
  }
};

// Linear propagation into u: central differences along each scaled eigen-direction of the moved parameters'
// covariance, two analyses per direction on `jobs` threads, summed in direction order (bit-identical whatever
// `jobs` is). Every analysis must succeed: a sum missing a direction would understate U.
void PropagateLinearly(const MovedAnalyses& analyses, const topo::Analysis& nominal, const Eigen::MatrixXd& covariance,
                       int jobs, ClinicalUncertainty* u) {
  const auto directions = ScaledEigenDirections(covariance);
  std::vector<std::optional<DrawnQuantities>> moved(2 * directions.size());
  std::vector<int> undistort_failures(moved.size(), 0);
  util::ParallelFor(moved.size(), std::max(0, jobs), [&](size_t i) {
    moved[i] = analyses.Analyse((i % 2 == 0 ? 1.0 : -1.0) * directions[i / 2], &undistort_failures[i]);
  });
  DrawnQuantities variance{};
  for (size_t j = 0; j < directions.size(); ++j) {
    if (!moved[2 * j] || !moved[2 * j + 1]) {
      throw std::runtime_error(fmt::format("uncertainty: the analysis with the calibration moved by one standard "
                                           "deviation along eigen-direction {} of {} failed",
                                           j + 1, directions.size()));
    }
    for (size_t q = 0; q < kQuantities.size(); ++q) {
      const double half_difference = 0.5 * ((*moved[2 * j])[q] - (*moved[2 * j + 1])[q]);
      variance[q] += half_difference * half_difference;
    }
  }
  for (const int f : undistort_failures) {
    u->undistort_failures += f;
    u->draws_with_undistort_failures += f > 0;
  }
  const DrawnQuantities centre = QuantitiesOf(nominal);
  u->linear = true;
  u->samples = static_cast<int>(directions.size());
  for (size_t q = 0; q < kQuantities.size(); ++q) {
    u->quantities[kQuantities[q]] = {centre[q], 2.0 * std::sqrt(variance[q])};
  }
}

// The draws' statistics into u: failures counted, then the mean and expanded uncertainty (k = 2) of each quantity
// over the draws that reconstructed, summed in draw order.
void Summarise(const std::vector<std::optional<DrawnQuantities>>& per_draw,
               const std::vector<int>& per_draw_undistort_failures, int samples, ClinicalUncertainty* u) {
  for (const int f : per_draw_undistort_failures) {
    u->undistort_failures += f;
    u->draws_with_undistort_failures += f > 0;
  }
  std::map<std::string, std::vector<double>> draws;
  for (const auto& v : per_draw) {
    if (!v) {
      ++u->failed_samples;
      continue;
    }
    for (size_t q = 0; q < kQuantities.size(); ++q) draws[kQuantities[q]].push_back((*v)[q]);
  }
  u->samples = samples - u->failed_samples;
  if (u->samples < 2 || 2 * u->failed_samples > samples) {
    throw std::runtime_error(
        fmt::format("uncertainty: {} of {} draws failed to reconstruct", u->failed_samples, samples));
  }
  for (const auto& [name, values] : draws) {
    double mean = 0;
    for (double v : values) mean += v;
    mean /= values.size();
    double var = 0;
    for (double v : values) var += (v - mean) * (v - mean);
    var /= values.size() - 1;
    u->quantities[name] = {mean, 2.0 * std::sqrt(var)};
  }
}

}  // namespace

UncertaintySetting UncertaintySetting::Parse(const std::string& text, const std::string& key) {
  if (text == "linear") return {};
  if (text == "none") return {Method::kNone, 0};
  int draws = -1;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), draws);
  if (error != std::errc() || end != text.data() + text.size() || draws == 1 || draws < 0 ||
      draws > kMaxUncertaintySamples) {
    throw util::InputError(fmt::format("{}: \"{}\" is not linear, none (or 0) or a number of Monte Carlo draws, "
                                       "2 to {}", key, text, kMaxUncertaintySamples));
  }
  if (draws == 0) return {Method::kNone, 0};
  return {Method::kMonteCarlo, draws};
}

std::string UncertaintySetting::MethodName() const {
  switch (method) {
    case Method::kNone: return "none";
    case Method::kLinear: return "linear";
    case Method::kMonteCarlo: return "monte-carlo";
  }
  return "none";
}

std::optional<UncertaintySetting> UncertaintySetting::FromName(const std::string& method, int draws) {
  if (method == "monte-carlo" && draws >= 2 && draws <= kMaxUncertaintySamples) {
    return UncertaintySetting{Method::kMonteCarlo, draws};
  }
  if (method == "linear" && draws == 0) return UncertaintySetting{Method::kLinear, 0};
  if (method == "none" && draws == 0) return UncertaintySetting{Method::kNone, 0};
  return std::nullopt;
}

std::string UncertaintySetting::WhyNot(const std::string& method, int draws) {
  return fmt::format("\"{}\" with {} draws is not an uncertainty setting (linear or none with 0, monte-carlo with 2 "
                     "to {})", method, draws, kMaxUncertaintySamples);
}

std::vector<Eigen::VectorXd> ScaledEigenDirections(const Eigen::MatrixXd& covariance) {
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(covariance);
  if (eigen.info() != Eigen::Success) throw std::runtime_error("uncertainty: the covariance cannot be factored");
  std::vector<Eigen::VectorXd> out;
  const double largest = eigen.eigenvalues().cwiseAbs().maxCoeff();
  for (Eigen::Index j = 0; j < eigen.eigenvalues().size(); ++j) {
    const double l = eigen.eigenvalues()(j);
    if (l > 1e-14 * largest && l > 0) out.push_back(std::sqrt(l) * eigen.eigenvectors().col(j));
  }
  return out;
}

std::vector<std::string> DistortionParametersToDraw(const calib::ParameterCovariance& covariance) {
  std::vector<std::string> names;
  for (const Eigen::Index i : DrawnIndices(covariance)) names.push_back(covariance.names[static_cast<size_t>(i)]);
  return names;
}

ClinicalUncertainty PropagateCalibrationUncertainty(const std::vector<model::PlaneSpot>& spots,
                                                    const model::CameraModel& calibrated,
                                                    const calib::ParameterCovariance& covariance,
                                                    const model::TopographerCamera& camera, const model::Config& config,
                                                    int samples, std::uint32_t seed, int jobs) {
  if (samples < 0 || samples == 1) {
    throw util::InputError("uncertainty: 0 samples (linear propagation) or at least 2 Monte Carlo draws are needed");
  }
  ClinicalUncertainty u;
  u.correlated = covariance.full;
  const std::vector<Eigen::Index> drawn_index = DrawnIndices(covariance);
  for (const Eigen::Index i : drawn_index) u.drawn.push_back(covariance.names[static_cast<size_t>(i)]);
  if (u.drawn.empty()) {
    throw util::InputError("uncertainty: the calibration reports no standard deviation for a distortion parameter");
  }
  {
    model::CameraModel probe = calibrated;
    for (const auto& name : u.drawn) {
      if (!Parameter(probe, name)) {
        throw util::InputError(fmt::format("uncertainty: the covariance names {}, not a parameter of the {} camera",
                                           name, model::LensModelName(calibrated.lens)));
      }
    }
  }
  const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
  // The nominal calibration's conversion, verified on the sensor grid; the draws then convert without the grid.
  const DetectionPlaneModel nominal_on_plane = DetectionPlaneModelOf(calibrated, camera);
  const bool nominal_verified = nominal_on_plane.ok;
  const std::optional<topo::Analysis> nominal = NominalAnalysis(spots, nominal_on_plane, design.targets, config);
  if (samples == 0 && !nominal) throw std::runtime_error("uncertainty: the calibration's own analysis failed");
  MovedAnalyses analyses{spots, calibrated, u.drawn, camera, config, design.targets, {}, nominal_verified};
  analyses.options.stddev = analyses.options.adequacy = analyses.options.clinical = false;
  analyses.options.start = nominal ? &*nominal : nullptr;
  if (samples == 0) {
    PropagateLinearly(analyses, *nominal, DrawnCovariance(covariance, drawn_index), jobs, &u);
    return u;
  }
  // Each draw's normals come from its own generator seeded by (seed, draw index) and each draw writes only its own
  // slot, so the draws are the same whatever the number of threads and the statistics (summed in draw order below)
  // are bit-identical.
  const auto m = static_cast<Eigen::Index>(drawn_index.size());
  const Eigen::MatrixXd factor = DrawFactor(covariance, drawn_index);
  std::vector<std::optional<DrawnQuantities>> per_draw(static_cast<size_t>(samples));
  std::vector<int> per_draw_undistort_failures(static_cast<size_t>(samples), 0);
  util::ParallelFor(static_cast<size_t>(samples), std::max(0, jobs), [&](size_t i) {
    std::seed_seq seq{seed, static_cast<std::uint32_t>(i)};
    std::mt19937 rng(seq);
    std::normal_distribution<double> normal(0.0, 1.0);
    Eigen::VectorXd z(m);
    for (Eigen::Index k = 0; k < m; ++k) z(k) = normal(rng);
    per_draw[i] = analyses.Analyse(factor * z, &per_draw_undistort_failures[i]);
  });
  Summarise(per_draw, per_draw_undistort_failures, samples, &u);
  return u;
}

}  // namespace topocal::pipeline
