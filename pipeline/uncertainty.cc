#include "pipeline/uncertainty.h"

#include <cmath>
#include <random>
#include <stdexcept>

#include <Eigen/Eigenvalues>

#include <fmt/format.h>

#include "pipeline/detection_plane.h"
#include "topo/analysis.h"

namespace topocal::pipeline {
namespace {

// The distortion parameters of calib::CameraModel by the names the calibration file uses.
double* Parameter(calib::CameraModel& c, const std::string& name) {
  static const char* kDist[] = {"k1", "k2", "p1", "p2", "k3"};
  for (int i = 0; i < 5; ++i) {
    if (name == kDist[i]) return &c.dist[i];
  }
  if (name == "ex") return &c.distortion_centre.x();
  if (name == "ey") return &c.distortion_centre.y();
  return nullptr;
}

}  // namespace

ClinicalUncertainty PropagateCalibrationUncertainty(const std::vector<MeasuredImageSpot>& spots,
                                                    const calib::CameraModel& calibrated,
                                                    const calib::ParameterCovariance& covariance,
                                                    const model::TopographerCamera& camera,
                                                    const model::Config& config, int samples, std::uint32_t seed) {
  if (samples < 2) throw std::invalid_argument("uncertainty: at least 2 samples are needed");
  const auto n_names = static_cast<Eigen::Index>(covariance.names.size());
  if (covariance.matrix.rows() != n_names || covariance.matrix.cols() != n_names) {
    throw std::invalid_argument("uncertainty: the covariance matrix does not match its parameter names");
  }
  ClinicalUncertainty u;
  u.correlated = covariance.full;
  calib::CameraModel probe = calibrated;
  std::vector<Eigen::Index> drawn_index;
  for (Eigen::Index i = 0; i < n_names; ++i) {
    const double var = covariance.matrix(i, i);
    const auto& name = covariance.names[static_cast<size_t>(i)];
    if (var > 0 && std::isfinite(var) && Parameter(probe, name)) {
      u.drawn.push_back(name);
      drawn_index.push_back(i);
    }
  }
  if (u.drawn.empty()) {
    throw std::invalid_argument("uncertainty: the calibration reports no standard deviation for a distortion parameter");
  }
  // The drawn parameters' joint covariance and its factor L (L L' = S): a draw is mean + L z, z ~ N(0, I).
  // A symmetric eigendecomposition rather than a Cholesky factor, so that a covariance that is only positive
  // semi-definite (rounding in a stored file) still factors; negative rounding-level eigenvalues are clamped to 0.
  const auto m = static_cast<Eigen::Index>(drawn_index.size());
  Eigen::MatrixXd drawn_covariance(m, m);
  for (Eigen::Index a = 0; a < m; ++a) {
    for (Eigen::Index b = 0; b < m; ++b) drawn_covariance(a, b) = covariance.matrix(drawn_index[static_cast<size_t>(a)], drawn_index[static_cast<size_t>(b)]);
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(drawn_covariance);
  if (eigen.info() != Eigen::Success) throw std::invalid_argument("uncertainty: the covariance cannot be factored");
  const Eigen::MatrixXd factor = eigen.eigenvectors() * eigen.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal();

  const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);

  std::mt19937 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::map<std::string, std::vector<double>> draws;
  for (int i = 0; i < samples; ++i) {
    calib::CameraModel c = calibrated;
    Eigen::VectorXd z(m);
    for (Eigen::Index k = 0; k < m; ++k) z(k) = normal(rng);
    const Eigen::VectorXd delta = factor * z;
    for (Eigen::Index k = 0; k < m; ++k) *Parameter(c, u.drawn[static_cast<size_t>(k)]) += delta(k);
    std::string why;
    const auto distortion = DistortionOnDetectionPlane(c, camera, &why);
    if (!distortion) {
      ++u.failed_samples;
      continue;
    }
    const auto measured = UndistortSpots(spots, *distortion);
    try {
      const auto a = topo::AnalyzeSpots(measured, design.targets, config, nullptr);
      const auto& p = a.surface_fit.params;
      draws["rx_mm"].push_back(p.rx_mm);
      draws["ry_mm"].push_back(p.ry_mm);
      draws["kx"].push_back(p.kx);
      draws["ky"].push_back(p.ky);
      draws["alpha_deg"].push_back(p.alpha_deg);
      draws["pv_tangential_D"].push_back(a.power.pv_tangential_D);
      draws["pv_axial_D"].push_back(a.power.pv_axial_D);
      draws["radius_mm"].push_back(0.5 * (p.rx_mm + p.ry_mm));
      draws["central_axial_power_D"].push_back(topo::MeanAxialPowerD(a.power, kCentralPowerRadiusMm));
    } catch (const std::runtime_error&) {
      ++u.failed_samples;
    }
  }
  u.samples = samples - u.failed_samples;
  if (u.samples < 2 || 2 * u.failed_samples > samples) {
    throw std::runtime_error(fmt::format("uncertainty: {} of {} draws failed to reconstruct", u.failed_samples, samples));
  }
  for (const auto& [name, values] : draws) {
    double mean = 0;
    for (double v : values) mean += v;
    mean /= values.size();
    double var = 0;
    for (double v : values) var += (v - mean) * (v - mean);
    var /= values.size() - 1;
    u.quantities[name] = {mean, 2.0 * std::sqrt(var)};
  }
  return u;
}

}  // namespace topocal::pipeline
