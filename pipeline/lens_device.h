#pragma once
// A lens calibration (a target calibration: fx, fy, cx, cy and a lens model, calib/calibrate.h) as the device it
// makes of a nominal unit, so that every measuring verb takes it through --device:
//   the camera's principal point = (cx, cy): where the calibration puts the optical axis on the sensor;
//   a = fx pitch_u, the pixel aspect = fx / fy;
//   the lens model on the detection plane (pipeline::DetectionPlaneModelOf, its model error verified);
//   the screen pose, sensor size and orientation of the nominal device.
// The calibration's covariance is carried to the device's parameters (principal_point_u_px, principal_point_v_px,
// a_mm and the lens coefficients) by the Jacobian of that mapping, so that `reconstruct --device --uncertainty`
// propagates it. The pixel aspect's own uncertainty (fy against fx) is not a device parameter and is not carried;
// a fitted distortion centre is refused (its uncertainty has no device parameter to go to).
#include <optional>
#include <string>

#include "calib/calibrate.h"
#include "model/device.h"

namespace topocal::pipeline {

// The device and its calibration block (the covariance and where it came from). Throws util::InputError when the
// calibration's image size is not the nominal sensor's, when it fitted a distortion centre, or when it cannot be
// expressed on the detection plane (the reason and the model error).
model::DeviceFile LensCalibratedDevice(const calib::CalibrationResult& calibration, const model::Device& nominal,
                                       const std::string& calibration_name);

// The device a measuring verb (detect, reconstruct --image) images through: `--device D`, or with
// `--calibration C` the device D with C's lens on its camera, as above (what `calibrate --device D --device-out`
// would write). The covariance is the device file's, or the one C's covariance maps to; when there is none, why
// (a hand-written device; a calibration file without a covariance, or with a fitted distortion centre): the
// device's part of every uncertainty is then unknown and said so, never taken as zero.
struct MeasuringDevice {
  model::Device device;
  std::optional<model::DeviceCovariance> covariance;
  std::string no_covariance;  // why covariance is empty
  std::string name;           // for messages: "D" or "D with the lens of C"
};
// Throws util::InputError / util::ConfigError naming the file that is missing, malformed or does not fit, and for
// a calibration put on a device that is itself calibrated (its own lens and covariance would be silently replaced).
MeasuringDevice LoadMeasuringDevice(const std::string& device_path, const std::string& calibration_path);

}  // namespace topocal::pipeline
