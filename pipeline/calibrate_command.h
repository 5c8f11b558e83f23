#pragma once
// `topocal calibrate` as a library call: detect a planar target in a set of images, fit the camera
// (calib/calibrate.h) and write its calibration file, with a JSON report and a cross-validation map when asked.
#include <ostream>
#include <string>
#include <vector>

#include "calib/calibrate.h"
#include "util/parallel.h"
#include "util/progress_display.h"

namespace topocal::pipeline {

struct CalibrateRequest {
  std::string target;      // target description (Kalibr-style YAML)
  std::string images;      // glob(3) pattern of the images
  std::string model = "brown5";  // calib::DistortionModelNames
  std::string out;         // calibration file (OpenCV FileStorage YAML)
  std::string json;        // also a JSON report when not empty
  std::string cross_validate_svg;  // also fit two halves of the views and map their difference here
  std::string device;      // the unit's nominal device: with device_out, the lens calibration applied to it
  std::string device_out;  // also the device file of the lens calibration (pipeline/lens_device.h)
  bool single_view = false;  // one image at the cornea position; needs focal_mm, pixel_pitch_um, distance_mm
  bool robust = false;       // robust loss and iterative outlier rejection
  bool fit_centre = false;   // fit the radial distortion centre
  bool board_warp = false;   // fit the board's parabolic sag (multi-view)
  double focal_mm = 0, pixel_pitch_um = 0, distance_mm = 0;
  double magnification = model::kPaperMagnification;  // M_T of the Seidel sigma
  double fixed_aspect_ratio = 0;                      // fx / fy held in a multi-view fit; 0 = free
  std::vector<std::string> fixed;                     // parameters held fixed: fx fy cx cy k1 k2 p1 p2 k3 ex ey
  std::string loss = "huber";                         // with robust: huber or cauchy
  double loss_scale_px = 1.0;
  double outlier_threshold_sigmas = 4.0;  // corners beyond this many robust sigmas are rejected
  int jobs = util::AvailableCores();      // images detected at once; the result does not depend on it
  util::LogLine log;  // skipped images, outliers, per-image progress of a long set
};

// Writes the files (all or none) and prints the fit's summary to `out`. InputError for options that do not go
// together or a bad input; std::runtime_error when no target is found or the fit fails.
void RunCalibrate(const CalibrateRequest& request, std::ostream& out);

}  // namespace topocal::pipeline
