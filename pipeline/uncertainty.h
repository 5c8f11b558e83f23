#pragma once
// Calibration uncertainty carried to the clinical numbers (issue 7, item 2), by seeded Monte Carlo: draw the
// calibrated distortion parameters from their reported standard deviations, undistort the measured spots with each
// draw, reconstruct, fit, map — and report each clinical number as mean +- expanded uncertainty U = 2 s (k = 2).
//
// The draws are independent normals per free parameter (the calibration file stores standard deviations, not the
// covariance). That is exact for the topographer's single-view Seidel calibration, whose only free distortion
// parameter is k1, and conservative-or-not-known for correlated multi-parameter models (k1, k2, k3 anticorrelate):
// the result says which parameters were drawn.
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "calib/camera.h"
#include "model/config.h"
#include "model/null_screen.h"
#include "model/topographer_camera.h"
#include "pipeline/measure_spots.h"

namespace topocal::pipeline {

struct ClinicalUncertainty {
  struct Quantity {
    double mean = 0;
    double expanded_k2 = 0;  // 2 x standard deviation over the draws
  };
  int samples = 0;
  int failed_samples = 0;             // draws whose reconstruction failed (reported, not hidden)
  std::vector<std::string> drawn;     // parameter names drawn
  std::map<std::string, Quantity> quantities;  // rx_mm, ry_mm, kx, ky, alpha_deg, pv_tangential_D, pv_axial_D
};

// Throws std::invalid_argument for samples < 2 or no parameter with a positive standard deviation;
// std::runtime_error when more than half of the draws fail.
ClinicalUncertainty PropagateCalibrationUncertainty(const std::vector<MeasuredImageSpot>& spots,
                                                    const calib::CameraModel& calibrated,
                                                    const std::map<std::string, double>& stddev,
                                                    const model::TopographerCamera& camera,
                                                    const model::Config& config, int samples, std::uint32_t seed);

}  // namespace topocal::pipeline
