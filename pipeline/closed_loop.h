#pragma once
// The closed loop that proves what calibration is worth: for a camera with distortion,
//   (i)   render a calibration target placed at the cornea position through it and calibrate (single view, Seidel);
//   (ii)  render the raw spot image of the cornea through the same camera;
//   (iii) detect and index the spots, undistort them with the calibration, reconstruct;
//   (iv)  the caller compares with the uncorrected reconstruction and with the truth.
// Everything is rendered in a square region of interest of the sensor around the optical axis (the spot pattern
// and the target cover ~+-0.5 mm of the detection plane, ~+-450 px at 1.12 um): the same geometry as the full
// sensor, at a fraction of the pixels.
//
// This module sits above calib, correct and topo (which must not depend on each other) and below tools.
#include <cstdint>
#include <string>

#include "model/config.h"
#include "model/distortion.h"
#include "model/topographer_camera.h"
#include "topo/analysis.h"

namespace topocal::pipeline {

struct ClosedLoopOptions {
  model::TopographerCamera camera;          // the full sensor; its pitch, principal point and a are used
  int roi_half_px = 560;                    // half side of the rendered region of interest
  // Calibration target at the cornea position: a checkerboard of cols x rows inner corners, square in mm.
  int target_cols = 13;
  int target_rows = 13;
  double target_square_mm = 0.9;
  double target_blur_px = 1.0;
  int target_supersampling = 8;             // renderer's N (~N^2 sub-samples near edges); 16 costs 4x for no
                                            // measurable change in the recovered sigma (docs/closed-loop.md)
  double target_noise_grey = 1.0;
  // Spot image: PSF blur and noise as correct::SpotRenderOptions defaults.
  double spot_psf_px = 1.2;
  double spot_read_noise_dn = 20.0;
  std::uint32_t seed = 1;
};

struct CalibrationOutcome {
  double sigma_estimated_per_mm2 = 0;
  double sigma_stddev_per_mm2 = 0;
  double residual_rms_px = 0;
  int corners = 0;
  model::Distortion distortion;  // the calibrated distortion on the detection plane (mm)
};

struct ClosedLoopResult {
  double sigma_per_mm2 = 0;
  CalibrationOutcome calibration;
  int spots_indexed = 0;
  int spots_unassigned = 0;
  int spots_missing = 0;
  int undistort_failures = 0;
  topo::Analysis corrected;  // reconstruction from the detected, indexed and undistorted spots
};

// Throws std::runtime_error with one line when a stage fails (no target found, calibration failed, no spots).
ClosedLoopResult RunClosedLoop(const model::Config& config, double sigma_per_mm2, const ClosedLoopOptions& options);

}  // namespace topocal::pipeline
