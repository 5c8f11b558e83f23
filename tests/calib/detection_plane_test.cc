// A calibration with fx != fy on the detection plane (pipeline/detection_plane.h): accepted with its computed
// model error when that is negligible, refused with the number otherwise.
#include <gtest/gtest.h>

#include <cmath>

#include "pipeline/detection_plane.h"

namespace topocal::pipeline {
namespace {

model::CameraModel UnitCamera(const model::TopographerCamera& sensor, double fx_over_fy, double k1) {
  model::CameraModel c;
  c.width_px = sensor.width_px;
  c.height_px = sensor.height_px;
  const double f = sensor.FocalPx();
  c.fx_px = f * std::sqrt(fx_over_fy);
  c.fy_px = f / std::sqrt(fx_over_fy);
  c.cx_px = sensor.principal_point_px.x() + 3.2;
  c.cy_px = sensor.principal_point_px.y() - 1.7;
  c.dist = {k1, 0.01, 2e-4, -1e-4, 0.0};
  return c;
}

// The 13 opencv-doc photos calibrate to fx / fy = 0.999788, beyond the old 2e-4 limit.
TEST(DetectionPlane, RealAspectRatioIsCarriedWithItsModelError) {
  const model::TopographerCamera sensor;
  const double k1 = -0.05;  // ~36 px of displacement at the sensor corners
  const auto m = DetectionPlaneModelOf(UnitCamera(sensor, 0.999788, k1), sensor);
  ASSERT_TRUE(m.ok) << m.message;
  // |fx / fy - 1| / 2 times the largest displacement (correct/opencv_brown.h): 1.06e-4 x ~36 px ~ 0.004 px.
  std::printf("fx/fy = 0.999788, k1 = %.2f: model error %.4f px\n", k1, m.model_error_px);
  EXPECT_GT(m.model_error_px, 0.001);  // the error is computed, not assumed zero
  EXPECT_LT(m.model_error_px, kMaxModelErrorPx);
  // Square pixels: no model error at all.
  const auto square = DetectionPlaneModelOf(UnitCamera(sensor, 1.0, k1), sensor);
  ASSERT_TRUE(square.ok) << square.message;
  EXPECT_EQ(square.model_error_px, 0.0);
}

TEST(DetectionPlane, LargeAspectErrorIsRefusedWithTheNumber) {
  const model::TopographerCamera sensor;
  const auto refused = DetectionPlaneModelOf(UnitCamera(sensor, 0.995, -0.05), sensor);
  EXPECT_FALSE(refused.ok);
  EXPECT_NE(refused.message.find("fx / fy = 0.995000"), std::string::npos) << refused.message;
  EXPECT_NE(refused.message.find("px (> 0.01 px)"), std::string::npos) << refused.message;
  // The same aspect ratio without distortion moves no point: accepted.
  const auto accepted = DetectionPlaneModelOf(UnitCamera(sensor, 0.995, 0.0), sensor);
  EXPECT_TRUE(accepted.ok) << accepted.message;
}

}  // namespace
}  // namespace topocal::pipeline
