#include "correct/undistort_coverage.h"

namespace topocal::correct {

UndistortCoverage CoverageOf(const UndistortMap& map, const model::TopographerCamera& camera) {
  UndistortCoverage c;
  c.beyond_fold_px = map.invalid_px;
  c.total_px = static_cast<int>(map.map_x.total());
  for (int r = 0; r < map.map_x.rows; ++r) {
    const float* x = map.map_x.ptr<float>(r);
    const float* y = map.map_y.ptr<float>(r);
    for (int col = 0; col < map.map_x.cols; ++col) {
      if (x[col] == -1.0f) continue;  // beyond the fold (UndistortMap marks it so), counted above
      if (!camera.OnSensor({x[col], y[col]})) ++c.outside_sensor_px;
    }
  }
  return c;
}

}  // namespace topocal::correct
