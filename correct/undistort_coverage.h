#pragma once
// Why pixels of an undistorted image are empty: beyond the fold of the distortion model (no unique source: the
// model is not invertible there, calib/distortion_valid_region.h), or mapped from outside the sensor (barrel
// distortion squeezes a wider field onto the sensor than the undistorted frame of the same size can show, and the
// other way round for pincushion).
#include "correct/undistort_map.h"
#include "model/topographer_camera.h"

namespace topocal::correct {

struct UndistortCoverage {
  int beyond_fold_px = 0;     // no source: the distortion model folds (UndistortMap::invalid_px)
  int outside_sensor_px = 0;  // source off the sensor
  int total_px = 0;
};

UndistortCoverage CoverageOf(const UndistortMap& map, const model::TopographerCamera& camera);

}  // namespace topocal::correct
