#pragma once
// From a pixel-space calibration (model::CameraModel: OpenCV intrinsics + Brown distortion, optional distortion
// centre) to the distortion on the detection plane in mm that correction and reconstruction work with, through the
// topographer's camera (docs/camera-conventions.md). One place for the conversion, used by the closed loop and by
// the command line.
//
// fx != fy is the sensor's pixel aspect (model::TopographerCamera::pixel_aspect = fx / fy; real cameras calibrate to
// |fx / fy - 1| ~ 1e-4, the 13 opencv-doc photos to 0.999788): the camera returned carries it, and the distortion on
// the detection plane is then exactly the calibration's. That is verified, not assumed: the worst difference between
// the detection-plane undistortion and the calibration's own -- undistorted pixel (cx + fx x_n, cy + fy y_n) -- over
// a grid of sensor pixels (model_error_px, ~1e-9 px). A conversion beyond kMaxModelErrorPx is refused with that number.
#include <optional>
#include <string>

#include "calib/calibration_file.h"
#include "model/camera_model.h"
#include "model/distortion.h"
#include "model/topographer_camera.h"

namespace topocal::pipeline {

// Largest acceptable error of the detection-plane model over the sensor, px: a quarter of the 0.04 px RMS of a good
// unit calibration (README), so it never dominates the calibration's own uncertainty.
inline constexpr double kMaxModelErrorPx = 0.01;

struct DetectionPlaneModel {
  bool ok = false;
  std::string message;  // why the calibration cannot be expressed on the detection plane, when !ok
  model::Distortion distortion;
  // The topographer's camera with the calibration's pixel aspect (fx / fy): the camera every pixel <-> mm mapping of
  // this calibration's images must use.
  model::TopographerCamera camera;
  double model_error_px = 0;  // worst |undistorted pixel, detection-plane model - calibration| over the sensor
};

// !ok with the reason (model error, pixel aspect, focal length) when the calibration cannot be expressed on the
// detection plane. Whether that is bad input (a calibration file the user gave: the command line names the file,
// exit 2) or a computation that failed (a calibration the workflow computed: std::runtime_error, exit 1) is the
// caller's to say; an uncertainty draw counts it as a failed draw.
DetectionPlaneModel DetectionPlaneModelOf(const model::CameraModel& calibrated, const model::TopographerCamera& camera);

// The conversion without the model-error grid (model_error_px left 0): for the uncertainty draws of a calibration
// whose own conversion DetectionPlaneModelOf verified. The conversion is exact for any distortion parameters, which
// the draws change; the grid (two inversions at 17 x 17 sensor pixels) confirmed ~1e-9 px in every draw and cost a
// tenth of a unit's CPU. Still !ok for a pixel aspect or a distortion the detection plane cannot hold.
DetectionPlaneModel DetectionPlaneModelUnverified(const model::CameraModel& calibrated,
                                                  const model::TopographerCamera& camera);

// A lens calibration file given beside a device (`--device D --calibration cal.yaml`) on its camera's detection plane:
// DetectionPlaneModelOf, ok. Throws util::InputError naming the calibration file when it was made on a sensor of
// another size or cannot be expressed on the detection plane.
DetectionPlaneModel CalibrationOnDetectionPlane(const calib::CalibrationFile& calibration,
                                                const std::string& calibration_path,
                                                const model::TopographerCamera& camera, const std::string& camera_path);

}  // namespace topocal::pipeline
