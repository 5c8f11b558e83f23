// A calibration with fx != fy on the detection plane (pipeline/detection_plane.h): the camera takes fx / fy as its
// pixel aspect, the model error (computed, not assumed) stays at the undistortion's convergence, and an aspect no
// sensor has is refused with the number.
#include <gtest/gtest.h>

#include <cmath>

#include "model/opencv_view.h"
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

// The 13 opencv-doc photos calibrate to fx / fy = 0.999788: the camera carries it as its pixel aspect, and the
// detection-plane model is then the calibration's own, with any distortion.
TEST(DetectionPlane, AspectRatioBecomesThePixelAspectWithoutModelError) {
  const model::TopographerCamera sensor;
  for (const double fx_over_fy : {1.0, 0.999788, 0.995, 1.02}) {
    const double k1 = -0.05;  // ~36 px of displacement at the sensor corners
    const auto m = DetectionPlaneModelOf(UnitCamera(sensor, fx_over_fy, k1), sensor);
    SCOPED_TRACE(fx_over_fy);
    ASSERT_TRUE(m.ok) << m.message;
    EXPECT_NEAR(m.camera.pixel_aspect, fx_over_fy, 1e-12);
    // Acceptance: kMaxModelErrorPx (0.01 px). Measured ~1e-9 px (the undistortion's own convergence): the one
    // focal-length model this replaces made 0.004 px at 0.999788 and 0.09 px at 0.995.
    std::printf("fx/fy = %.6f, k1 = %.2f: model error %.2e px\n", fx_over_fy, k1, m.model_error_px);
    EXPECT_LT(m.model_error_px, kMaxModelErrorPx);
    EXPECT_LT(m.model_error_px, 1e-6);
    // The pixel <-> mm mapping follows the aspect: one pixel along v is pitch x aspect.
    const Eigen::Vector2d step = m.camera.DetectionPlaneFromPixel(sensor.principal_point_px + Eigen::Vector2d(0, 1)) -
                                 m.camera.DetectionPlaneFromPixel(sensor.principal_point_px);
    EXPECT_NEAR(step.norm(), sensor.PitchMm() * fx_over_fy, 1e-15);
  }
}

// Every lens model carries to the detection plane the same way: the rational model's calibration undistorts there as
// the calibration itself does, and the OpenCV view of the plane's model is the calibration again.
TEST(DetectionPlane, EveryLensModelCarriesWithoutModelError) {
  const model::TopographerCamera sensor;
  model::ForEachLensModel([&](auto lens) {
    model::CameraModel c = UnitCamera(sensor, 0.999788, -0.05);
    c.lens = lens;
    if (model::LensParameterCount(lens) > 5) c.dist[5] = 0.02, c.dist[6] = -0.004, c.dist[7] = 1e-3;
    const auto m = DetectionPlaneModelOf(c, sensor);
    SCOPED_TRACE(std::string(decltype(lens)::kName));
    ASSERT_TRUE(m.ok) << m.message;
    const auto& on_plane = std::get<model::LensParams>(m.distortion);
    EXPECT_EQ(on_plane.model.index(), c.lens.index());
    std::printf("%s: model error %.2e px\n", std::string(decltype(lens)::kName).c_str(), m.model_error_px);
    EXPECT_LT(m.model_error_px, kMaxModelErrorPx);  // acceptance
    // Regression: measured 8.4e-7 (rational8) and 1.0e-6 px (brown5), the 1e-6 px tolerance of the inverse.
    EXPECT_LT(m.model_error_px, 2e-6);
    const model::CameraModel back = model::OpenCvFromLens(on_plane, m.camera);
    EXPECT_EQ(back.lens.index(), c.lens.index());
    for (int i = 0; i < model::kMaxLensParams; ++i) EXPECT_NEAR(back.dist[i], c.dist[i], 1e-15) << i;
    EXPECT_NEAR(back.fx_px, c.fx_px, 1e-9 * c.fx_px);
    EXPECT_NEAR(back.cy_px, c.cy_px, 1e-9);
  });
}

TEST(DetectionPlane, AnAspectNoSensorHasIsRefusedWithTheNumber) {
  const model::TopographerCamera sensor;
  const auto refused = DetectionPlaneModelOf(UnitCamera(sensor, 3.0, -0.05), sensor);
  EXPECT_FALSE(refused.ok);
  EXPECT_NE(refused.message.find("fx / fy = 3.000000"), std::string::npos) << refused.message;
  EXPECT_NE(refused.message.find("pixel_aspect: must be in [0.5, 2]"), std::string::npos) << refused.message;
}

}  // namespace
}  // namespace topocal::pipeline
