#pragma once
// Calibration uncertainty carried to the clinical numbers, by seeded Monte Carlo: draw the
// calibrated distortion parameters from their reported standard deviations, undistort the measured spots with each
// draw, reconstruct, fit, map — and report each clinical number as mean +- expanded uncertainty U = 2 s (k = 2).
//
// The draws are joint normals with the calibration's parameter covariance (calibration files since topocal 0.1.0
// store it; for an older file calib::ParameterCovarianceOf gives the diagonal and `correlated` is false). Only the
// distortion parameters (k1..k3, p1, p2, ex, ey) are drawn; the intrinsics enter the detection-plane distortion
// only through its scale, which the topographer's camera description fixes. The result says what was drawn.
#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "calib/calibration_file.h"
#include "model/camera_model.h"
#include "model/config.h"
#include "model/null_screen.h"
#include "model/topographer_camera.h"
#include "pipeline/measure_spots.h"
#include "util/io.h"

namespace topocal::pipeline {

// The central zone of the power reading: 3 mm diameter, the zone keratometers and topographers' simulated-K
// readings use (the Javal–Schiøtz keratometer measures at about 3 mm).
inline constexpr double kCentralPowerRadiusMm = 1.5;

struct ClinicalUncertainty {
  struct Quantity {
    double mean = 0;
    double expanded_k2 = 0;  // 2 x standard deviation over the draws
  };
  int samples = 0;
  int failed_samples = 0;             // draws whose reconstruction failed (reported, not hidden)
  // Spots a draw could not undistort (the inverse distortion did not converge: a spot beyond the drawn distortion's
  // fold) and so left out of that draw's reconstruction, summed over the draws; and how many draws lost any.
  int undistort_failures = 0;
  int draws_with_undistort_failures = 0;
  std::vector<std::string> drawn;     // parameter names drawn
  bool correlated = false;            // drawn with the full covariance (false: independent, diagonal only)
  // rx_mm, ry_mm, kx, ky, alpha_deg, pv_tangential_D, pv_axial_D, radius_mm (mean of rx, ry),
  // central_axial_power_D (topo::MeanAxialPowerD over kCentralPowerRadiusMm)
  std::map<std::string, Quantity> quantities;
};

// The distortion parameters of `covariance` that have a spread to draw (positive, finite variance), in the
// covariance's order. Empty means nothing to propagate (every distortion parameter fixed or without a reported
// standard deviation): the one legitimate "no uncertainty" case, which callers test for before propagating.
// Throws util::InputError when the matrix does not match its names.
std::vector<std::string> DistortionParametersToDraw(const calib::ParameterCovariance& covariance);

// The draws run on `jobs` threads (<= 0: every core; model/parallel.h); draw i takes its normals from
// std::seed_seq{seed, i}, so the result is bit-identical whatever `jobs` is. Each draw starts from the nominal
// analysis (the calibration as it is: topo::AnalysisOptions::start — its slope-fit factor, its surface for the first
// incidence points, its biconic or sphere fit) and computes only what the quantities need.
// Throws util::InputError for samples < 2, a covariance whose size does not match its names, or no distortion
// parameter with a positive variance;
// std::runtime_error when more than half of the draws fail.
ClinicalUncertainty PropagateCalibrationUncertainty(const std::vector<model::PlaneSpot>& spots,
                                                    const model::CameraModel& calibrated,
                                                    const calib::ParameterCovariance& covariance,
                                                    const model::TopographerCamera& camera, const model::Config& config,
                                                    int samples, std::uint32_t seed, int jobs = 0);

}  // namespace topocal::pipeline
