#pragma once
// `topocal render-target` as a library call: synthetic ground truth, a target seen through a pinhole camera with
// distortion, blur and noise (calib/render_target.h), written as an 8-bit PNG with the exact corner positions.
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "calib/calibrate.h"
#include "calib/render_target.h"
#include "util/parallel.h"
#include "util/progress_display.h"

namespace topocal::pipeline {

struct RenderTargetRequest {
  std::string target;  // target description (Kalibr YAML)
  std::string out;     // rendered image (PNG)
  std::string truth;   // also the corners' positions, CSV id,x_px,y_px, when not empty

  // The camera: an OpenCV calibration file, or pinhole intrinsics (unset: 640 x 480 px, fx 600 px, fy = fx,
  // the principal point at the image's centre), or fx = fy from focal_mm and pixel_pitch_um.
  std::string camera_file;
  std::optional<int> width_px, height_px;
  std::optional<double> fx_px, fy_px, cx_px, cy_px;
  std::optional<double> focal_mm, pixel_pitch_um;

  // The distortion: Brown-Conrady coefficients (unset = 0), or a Seidel sigma (needs focal_mm and pixel_pitch_um).
  std::optional<double> k1, k2, p1, p2, k3;
  std::optional<double> sigma_per_mm2;
  double magnification = model::kPaperMagnification;  // M_T of the Seidel sigma

  // The pose: the target facing the camera at distance_mm, turned and shifted; or an explicit cam_from_target.
  std::optional<double> distance_mm;
  double tilt_x_deg = 0, tilt_y_deg = 0, roll_deg = 0, shift_x_mm = 0, shift_y_mm = 0;
  std::vector<double> rvec_deg, tvec_mm;  // three numbers each, or both empty

  calib::RenderOptions render = [] {
    calib::RenderOptions options;
    options.jobs = util::AvailableCores();
    return options;
  }();
  util::ShowProgress progress;  // "rendering W x H" while the image is rendered
};

// Writes the image (and the truth) and prints one line saying what was rendered to `out`. InputError for options
// that do not go together, non-finite or out-of-range numbers, and a target that cannot be rendered.
void RunRenderTarget(const RenderTargetRequest& request, std::ostream& out);

}  // namespace topocal::pipeline
