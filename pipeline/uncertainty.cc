#include "pipeline/uncertainty.h"

#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
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

// The drawn parameters' joint covariance and its factor L (L L' = S): a draw is mean + L z, z ~ N(0, I).
// A symmetric eigendecomposition rather than a Cholesky factor, so that a covariance that is only positive
// semi-definite (rounding in a stored file) still factors; negative rounding-level eigenvalues are clamped to 0.
Eigen::MatrixXd DrawFactor(const calib::ParameterCovariance& covariance, const std::vector<Eigen::Index>& drawn_index) {
  const auto m = static_cast<Eigen::Index>(drawn_index.size());
  Eigen::MatrixXd drawn_covariance(m, m);
  for (Eigen::Index a = 0; a < m; ++a) {
    for (Eigen::Index b = 0; b < m; ++b) drawn_covariance(a, b) = covariance.matrix(drawn_index[static_cast<size_t>(a)], drawn_index[static_cast<size_t>(b)]);
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(drawn_covariance);
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
  if (samples < 2) throw util::InputError("uncertainty: at least 2 samples are needed");
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
  const auto m = static_cast<Eigen::Index>(drawn_index.size());
  const Eigen::MatrixXd factor = DrawFactor(covariance, drawn_index);

  const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
  // The nominal calibration's conversion, verified on the sensor grid; the draws then convert without the grid.
  const DetectionPlaneModel nominal_on_plane = DetectionPlaneModelOf(calibrated, camera);
  const bool nominal_verified = nominal_on_plane.ok;
  const std::optional<topo::Analysis> nominal = NominalAnalysis(spots, nominal_on_plane, design.targets, config);
  topo::AnalysisOptions draw_options;
  draw_options.stddev = draw_options.adequacy = draw_options.clinical = false;
  draw_options.start = nominal ? &*nominal : nullptr;

  // Each draw's normals come from its own generator seeded by (seed, draw index) and each draw writes only its own
  // slot, so the draws are the same whatever the number of threads and the statistics (summed in draw order below)
  // are bit-identical.
  std::vector<std::optional<DrawnQuantities>> per_draw(static_cast<size_t>(samples));
  std::vector<int> per_draw_undistort_failures(static_cast<size_t>(samples), 0);
  util::ParallelFor(static_cast<size_t>(samples), std::max(0, jobs), [&](size_t i) {
    std::seed_seq seq{seed, static_cast<std::uint32_t>(i)};
    std::mt19937 rng(seq);
    std::normal_distribution<double> normal(0.0, 1.0);
    model::CameraModel c = calibrated;
    Eigen::VectorXd z(m);
    for (Eigen::Index k = 0; k < m; ++k) z(k) = normal(rng);
    const Eigen::VectorXd delta = factor * z;
    for (Eigen::Index k = 0; k < m; ++k) *Parameter(c, u.drawn[static_cast<size_t>(k)]) += delta(k);
    const auto on_plane = nominal_verified ? DetectionPlaneModelUnverified(c, camera) : DetectionPlaneModelOf(c, camera);
    if (!on_plane.ok) return;  // counted as failed below
    const model::Distortion* distortion = &on_plane.distortion;
    try {
      const auto undistorted = UndistortSpots(spots, *distortion, &per_draw_undistort_failures[i]);
      const auto a = topo::AnalyzeSpots(undistorted, design.targets, config, nullptr, draw_options);
      const auto& p = a.surface_fit.params;
      per_draw[i] = DrawnQuantities{
          p.rx_mm, p.ry_mm, p.kx, p.ky, p.alpha_deg, a.power.pv_tangential_D, a.power.pv_axial_D,
          0.5 * (p.rx_mm + p.ry_mm), topo::MeanAxialPowerD(a.power, kCentralPowerRadiusMm)};
    } catch (const std::runtime_error&) {
      // counted as failed below
    }
  });
  Summarise(per_draw, per_draw_undistort_failures, samples, &u);
  return u;
}

}  // namespace topocal::pipeline
