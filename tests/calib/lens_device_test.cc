// A lens calibration as a device (pipeline/lens_device.h): the device images every ray where the calibration does,
// carries the calibration's covariance to the device's parameters, round-trips as a device file, and refuses a
// calibration of another sensor.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "calib/calibrate.h"
#include "model/device.h"
#include "pipeline/lens_device.h"
#include "tests/calib/synthetic_views.h"
#include "util/io.h"

namespace topocal::pipeline {
namespace {

double StddevOf(const calib::CalibrationResult& calibration, const std::string& name) {
  for (const auto& p : calibration.parameters) {
    if (p.name == name) return p.stddev;
  }
  return -1.0;
}

calib::CalibrationResult UnitCalibration(const model::TopographerCamera& sensor) {
  model::CameraModel truth;
  truth.width_px = sensor.width_px;
  truth.height_px = sensor.height_px;
  truth.fx_px = 1.001 * sensor.FocalPx();
  truth.fy_px = truth.fx_px / 0.9998;
  truth.cx_px = sensor.principal_point_px.x() + 5.0;
  truth.cy_px = sensor.principal_point_px.y() - 3.0;
  truth.dist = {-0.05, 0.01, 2e-4, -1e-4, 0.0};
  const calib::testing::GridTarget grid;
  std::mt19937 rng(11);
  std::vector<calib::ViewObservations> views;
  for (const auto& pose : calib::testing::ReferencePoses(grid)) {
    views.push_back(calib::testing::ProjectGrid(truth, pose, grid, 0.1, rng));
  }
  return calib::CalibrateMultiView(views, {});
}

TEST(LensCalibratedDevice, ImagesAsTheCalibrationAndCarriesItsCovariance) {
  const model::Device nominal = model::LoadDevice(TOPOCAL_SOURCE_DIR "/data/device.json").device;
  const auto calibration = UnitCalibration(nominal.camera);
  ASSERT_TRUE(calibration.ok()) << calibration.message;
  const model::DeviceFile file = LensCalibratedDevice(calibration, nominal, "cal.yaml");
  const model::Device& device = file.device;
  const model::CameraModel& k = calibration.camera;
  EXPECT_NEAR(device.camera.a_mm, k.fx_px * nominal.camera.PitchMm(), 1e-12);
  EXPECT_NEAR(device.camera.pixel_aspect, k.fx_px / k.fy_px, 1e-12);
  // Every ray lands where the calibration puts it: the undistorted pixel (c + F x_n) as detection-plane mm, through
  // the device's distortion, against the calibration's projection of the same ray.
  double worst = 0;
  for (double x = -0.4; x <= 0.4; x += 0.05) {
    for (double y = -0.3; y <= 0.3; y += 0.05) {
      const Eigen::Vector2d undistorted_px(k.cx_px + k.fx_px * x, k.cy_px + k.fy_px * y);
      const Eigen::Vector2d px = device.PixelOf(device.camera.DetectionPlaneFromPixel(undistorted_px));
      worst = std::max(worst, (px - k.Project({x, y, 1.0})).norm());
    }
  }
  std::printf("device against its calibration: %.2e px\n", worst);
  EXPECT_LT(worst, 1e-6);   // acceptance: the same camera (an error here would misplace every spot)
  EXPECT_LT(worst, 1e-9);   // regression bound: measured 9.4e-13 px (2026-12-07)
  // A camera rolled by 90 or 180 deg: the tangential pair turns with it, its variances with it.
  for (const auto orientation : {model::ImageOrientation::kRotate180, model::ImageOrientation::kRotate90}) {
    model::Device rolled = nominal;
    rolled.camera.orientation = orientation;
    const model::DeviceFile turned = LensCalibratedDevice(calibration, rolled, "cal.yaml");
    double turned_worst = 0;
    for (double x = -0.4; x <= 0.4; x += 0.1) {
      for (double y = -0.3; y <= 0.3; y += 0.1) {
        const Eigen::Vector2d undistorted_px(k.cx_px + k.fx_px * x, k.cy_px + k.fy_px * y);
        const Eigen::Vector2d px =
            turned.device.PixelOf(turned.device.camera.DetectionPlaneFromPixel(undistorted_px));
        turned_worst = std::max(turned_worst, (px - k.Project({x, y, 1.0})).norm());
      }
    }
    EXPECT_LT(turned_worst, 1e-9) << model::OrientationName(orientation);
    const auto turned_covariance = model::DeviceCovarianceOf(turned.calibration, "device.json");
    ASSERT_TRUE(turned_covariance.has_value());
    // p1, p2 at rows 5, 6: for a quarter turn they swap (up to sign), for a half turn they keep their variances.
    const bool quarter = orientation == model::ImageOrientation::kRotate90;
    const double sd_p1 = std::sqrt(turned_covariance->matrix(5, 5)), sd_p2 = std::sqrt(turned_covariance->matrix(6, 6));
      EXPECT_NEAR(sd_p1, quarter ? StddevOf(calibration, "p2") : StddevOf(calibration, "p1"), 1e-9 * sd_p1);
    EXPECT_NEAR(sd_p2, quarter ? StddevOf(calibration, "p1") : StddevOf(calibration, "p2"), 1e-9 * sd_p2);
  }
  // The covariance, carried: a = fx pitch, the principal point and the radial terms as they are.
  const auto covariance = model::DeviceCovarianceOf(file.calibration, "device.json");
  ASSERT_TRUE(covariance.has_value());
  EXPECT_EQ(covariance->names, (std::vector<std::string>{"principal_point_u_px", "principal_point_v_px", "a_mm", "k1",
                                                         "k2", "p1", "p2", "k3"}));
  const auto sd = [&](const std::string& name) { return StddevOf(calibration, name); };
  const double pitch = nominal.camera.PitchMm();
  EXPECT_NEAR(std::sqrt(covariance->matrix(2, 2)), pitch * sd("fx"), 1e-9 * pitch * sd("fx"));
  EXPECT_NEAR(std::sqrt(covariance->matrix(0, 0)), sd("cx"), 1e-9 * sd("cx"));
  EXPECT_NEAR(std::sqrt(covariance->matrix(3, 3)), sd("k1"), 1e-9 * sd("k1"));
  EXPECT_GT(sd("k1"), 0.0);
  // The file round-trips, and `reconstruct --device` reads its covariance.
  const auto text = model::DeviceToJson(device, file.calibration);
  const auto read = model::ParseDevice(text, "device.json");
  EXPECT_EQ(model::DeviceToJson(read.device, read.calibration), text);
}

TEST(LensCalibratedDevice, RefusesAnotherSensorAndAFittedCentre) {
  const model::Device nominal = model::LoadDevice(TOPOCAL_SOURCE_DIR "/data/device.json").device;
  const auto calibration = UnitCalibration(nominal.camera);
  ASSERT_TRUE(calibration.ok()) << calibration.message;
  auto other = calibration;  // the same fit, said to come from a 2000 x 1500 sensor
  other.camera.width_px = 2000;
  other.camera.height_px = 1500;
  try {
    (void)LensCalibratedDevice(other, nominal, "cal.yaml");
    ADD_FAILURE() << "a 2000 x 1500 calibration made a 4000 x 3000 device";
  } catch (const util::InputError& e) {
    EXPECT_EQ(std::string(e.what()), "cal.yaml: calibrated at 2000 x 1500 px but the nominal device's sensor is "
                                     "4000 x 3000 px");
  }
  auto centred = calibration;
  for (auto& p : centred.parameters) {
    if (p.name == "ex") p.fixed = false;
  }
  EXPECT_THROW((void)LensCalibratedDevice(centred, nominal, "cal.yaml"), util::InputError);
}

}  // namespace
}  // namespace topocal::pipeline
