#pragma once
// From a pixel-space calibration (calib::CameraModel: OpenCV intrinsics + Brown distortion, optional distortion
// centre) to the distortion on the detection plane in mm that correction and reconstruction work with, through the
// topographer's camera (docs/camera-conventions.md). One place for the conversion, used by the closed loop and by
// the command line.
#include <optional>
#include <string>

#include "calib/camera.h"
#include "model/distortion.h"
#include "model/topographer_camera.h"

namespace topocal::pipeline {

// Largest |fx / fy - 1| accepted: the detection-plane model has one focal length. 2e-4 is ~10x the scatter of fx/fy
// in calibrations of square-pixel cameras (docs/calibration.md).
inline constexpr double kMaxAspectError = 2e-4;

// nullopt with *why when the calibration cannot be expressed on the detection plane (aspect ratio, model).
std::optional<model::Distortion> DistortionOnDetectionPlane(const calib::CameraModel& calibrated,
                                                            const model::TopographerCamera& camera, std::string* why);

}  // namespace topocal::pipeline
