#pragma once
// `topocal device calibrate` as a library call: the whole device (screen pose, principal point, a, distortion) fitted
// to reference-ball images (pipeline/device_calibration.h) and written as a calibrated device file (docs/device.md).
#include <ostream>
#include <string>
#include <vector>

#include "calib/device_fit.h"

namespace topocal::pipeline {

struct DeviceCalibrateRequest {
  std::string config;          // topographer design (JSON)
  std::string nominal_device;  // nominal device file (JSON): the starting point and the priors' centre
  std::string out;             // calibrated device file (JSON)
  std::vector<std::string> balls;     // raw images of the reference balls
  std::vector<double> ball_radii_mm;  // certified radius of each ball, in the order of balls
  std::string target;                 // target description (YAML) of the target views; with targets
  std::string targets;                // target views through the same camera, a glob(3) pattern; empty: none
  int datum_ball_number = 1;          // the ball whose vertex defines z = 0, 1-based
  calib::DeviceFitOptions options;    // its datum_ball is set from datum_ball_number
  bool quiet = false;                 // print nothing to `out`
};

// Writes the device file and prints the fit to `out`. InputError for inputs that do not go together or a bad file;
// std::runtime_error when the fit fails; util::VerdictFailed, after the file is written, when the device model does
// not describe the images (chi2/dof above options.max_chi2_per_dof).
void RunDeviceCalibrate(const DeviceCalibrateRequest& request, std::ostream& out);

}  // namespace topocal::pipeline
