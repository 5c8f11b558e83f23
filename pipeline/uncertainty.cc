#include "pipeline/uncertainty.h"

#include <cmath>
#include <random>
#include <stdexcept>

#include <fmt/format.h>

#include "correct/undistort_points.h"
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
                                                    const std::map<std::string, double>& stddev,
                                                    const model::TopographerCamera& camera,
                                                    const model::Config& config, int samples, std::uint32_t seed) {
  if (samples < 2) throw std::invalid_argument("uncertainty: at least 2 samples are needed");
  ClinicalUncertainty u;
  calib::CameraModel probe = calibrated;
  for (const auto& [name, sd] : stddev) {
    if (sd > 0 && std::isfinite(sd) && Parameter(probe, name)) u.drawn.push_back(name);
  }
  if (u.drawn.empty()) {
    throw std::invalid_argument("uncertainty: the calibration reports no standard deviation for a distortion parameter");
  }
  const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
  std::vector<Eigen::Vector2d> distorted;
  distorted.reserve(spots.size());
  for (const auto& s : spots) distorted.push_back(s.distorted_mm);

  std::mt19937 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::map<std::string, std::vector<double>> draws;
  for (int i = 0; i < samples; ++i) {
    calib::CameraModel c = calibrated;
    for (const auto& name : u.drawn) *Parameter(c, name) += stddev.at(name) * normal(rng);
    std::string why;
    const auto distortion = DistortionOnDetectionPlane(c, camera, &why);
    if (!distortion) {
      ++u.failed_samples;
      continue;
    }
    const auto undistorted = correct::UndistortPoints(*distortion, distorted);
    std::vector<topo::MeasuredSpot> measured;
    for (size_t k = 0; k < spots.size(); ++k) {
      if (undistorted.ok[k]) measured.push_back({spots[k].id, undistorted.points_mm[k]});
    }
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
