#pragma once
// The device calibration workflow: raw reference-ball images -> spots detected and identified through the nominal
// device's camera -> calib::FitDevice. Also the spots of one ball through any device (simulation).
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core/mat.hpp>

#include "calib/device_fit.h"
#include "model/config.h"
#include "model/device.h"
#include "util/io.h"

namespace topocal::pipeline {

struct BallImage {
  std::string name;      // file name, for messages
  cv::Mat image;
  double radius_mm = 0;  // certified radius
};

struct BallDetection {
  calib::BallView view;
  int unassigned = 0;    // detections without identity
  int missing = 0;       // designed spots not found
};

// Detects and identifies the spots of one ball image with the nominal device's camera. Throws std::runtime_error
// (one line naming the image) when the spots cannot be indexed; util::InputError for an unusable image type.
BallDetection DetectBall(const BallImage& ball, const model::Device& nominal, const model::IdealImageParams& ideal);

struct DeviceCalibration {
  std::vector<BallDetection> detections;
  std::vector<std::string> view_names;  // the target views fitted with the balls, if any
  calib::DeviceFit fit;
};

// Reference balls for a topographer: radii of human corneas and a little beyond.
inline constexpr double kMinBallRadiusMm = 3.0, kMaxBallRadiusMm = 20.0;

// Detects every ball and fits the device. Throws util::InputError when a radius is not a reference ball's
// (kMinBallRadiusMm to kMaxBallRadiusMm), when two balls are the same image (identical
// pixels: no new information, yet it would shrink the standard deviations), like DetectBall otherwise; a fit that
// fails comes back with fit.ok = false. `views`: target views through the same camera (calib::FitDevice).
DeviceCalibration CalibrateDevice(const std::vector<BallImage>& balls, const model::Device& nominal,
                                  const model::Config& config, const calib::DeviceFitOptions& options,
                                  const std::vector<calib::ViewObservations>& views = {});

// The calibration section of the device file (model::DeviceToJson): every fitted parameter with its standard
// deviation and nominal value, chi^2/dof, per-image residuals and detection counts, ball positions, the gauge and
// the notes (docs/device.md).
nlohmann::json DeviceCalibrationJson(const DeviceCalibration& calibration);

// The pixels at which a ball of radius_mm with its vertex at vertex_mm images the designed spots through a device
// (exact forward model, undistorted spots distorted and mapped by the camera); spots that do not form are listed.
struct BallSpots {
  std::vector<std::pair<model::SpotId, Eigen::Vector2d>> spots_px;
  std::vector<model::SpotFailure> failures;
};
BallSpots SimulateBall(const model::Device& device, const model::Config& config, double radius_mm,
                       const Eigen::Vector3d& vertex_mm);

}  // namespace topocal::pipeline
