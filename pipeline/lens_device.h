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
#include <string>

#include "calib/calibrate.h"
#include "model/device.h"

namespace topocal::pipeline {

// The device and its calibration block (the covariance and where it came from). Throws util::InputError when the
// calibration's image size is not the nominal sensor's, when it fitted a distortion centre, or when it cannot be
// expressed on the detection plane (the reason and the model error).
model::DeviceFile LensCalibratedDevice(const calib::CalibrationResult& calibration, const model::Device& nominal,
                                       const std::string& calibration_name);

}  // namespace topocal::pipeline
