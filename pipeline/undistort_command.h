#pragma once
// `topocal undistort`: a spots CSV or an image corrected with a lens calibration file (calib/calibration_file.h) or
// a device file (model/device.h); and the Undistortion both give: one distortion on the detection plane, the camera
// whose pixels map onto it, and where that distortion is invertible.
#include <Eigen/Core>
#include <functional>
#include <ostream>
#include <string>

#include "model/distortion.h"
#include "model/topographer_camera.h"
#include "util/progress_display.h"

namespace topocal::pipeline {

// What corrects, from a calibration file (its valid region) or from a device file (its distortion's fold within the
// sensor). `source` names the file in every message.
struct Undistortion {
  model::Distortion distortion;
  model::TopographerCamera camera;
  std::string source;
  double valid_radius_px = 0;  // about `valid_centre_px`, on the distorted image
  Eigen::Vector2d valid_centre_px{0, 0};
  double farthest_px = 0;                                 // the sensor's farthest pixel from that centre
  std::function<bool(const Eigen::Vector2d& px)> inside;  // a distorted pixel within the invertible region
  bool has_pitch = true;  // false: a calibration that records no pixel pitch (its mm are 1 um pixels)
  const char* centre_name = "the principal point";
  const char* region_name = "valid_radius_px";
};

// The calibration on the detection plane. With `device_path`, that device's camera (checked against the
// calibration's image
// size); without, one derived from the calibration itself: principal point and focal length from its camera matrix,
// the pixel pitch the file's when it has one, else 1 um (it cancels out for images). util::InputError naming the
// file for a mismatch or a calibration the detection plane cannot express.
Undistortion UndistortionFromCalibration(const std::string& calibration_path, const std::string& device_path);

// A device's distortion, invertible within its fold: a distorted point closer to the centre than the fold's image
// has its one preimage inside the fold (the radial map rises monotonically up to it).
Undistortion UndistortionFromDevice(const std::string& device_path);

struct UndistortRequest {
  std::string calibration_path, device_path;  // exactly one: what corrects
  // With a calibration, device_path (optional) is the device whose camera maps pixels to mm (needed for spots
  // unless the calibration has a pitch); alone, the device's own distortion corrects.
  std::string spots_path, image_path;  // exactly one: what is corrected
  std::string out_path;                // spots CSV, or a .png for an image
  util::LogLine log;  // warnings beside the result: spots refused, black pixels and why
};

// Writes the corrected spots or image and says so on `out`; what could not be corrected (spots beyond the invertible
// region, black pixels) is said on `log`. util::InputError for bad input; std::runtime_error when no spot
// could be undistorted.
void RunUndistort(const UndistortRequest& request, std::ostream& out);

}  // namespace topocal::pipeline
