// The valid region of a distortion model (calib/distortion_valid_region.h): against the closed-form fold of a pure
// radial model, with a distortion centre, stored in and read from the calibration file (computed for files without
// it), and what `topocal undistort` says about pixels beyond it.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "calib/calibration_file.h"
#include "calib/camera_exchange.h"
#include "calib/distortion_valid_region.h"
#include "tests/cli_harness.h"
#include "tests/device_file.h"
#include "util/io.h"

namespace topocal::calib {
namespace {

namespace fs = std::filesystem;

// The search bisects to 1e-3 px; the closed form is exact.
constexpr double kRadiusTolerancePx = 2e-3;

model::CameraModel Radial(int width, int height, double k1) {
  model::CameraModel c;
  c.width_px = width;
  c.height_px = height;
  c.fx_px = c.fy_px = 1000;
  c.cx_px = (width - 1) / 2.0;
  c.cy_px = (height - 1) / 2.0;
  c.dist = {k1, 0, 0, 0, 0};
  return c;
}

// r_d = r (1 + k1 r^2) turns back where 1 + 3 k1 r^2 = 0: r^2 = -1 / (3 k1), r_d = (2/3) r.
double ClosedFormFoldPx(double k1, double f_px) { return f_px * (2.0 / 3.0) * std::sqrt(-1.0 / (3.0 * k1)); }

TEST(ValidRegion, NoDistortionCoversTheSensor) {
  const auto r = ValidRegionOf(Radial(1600, 1200, 0));
  EXPECT_TRUE(r.covers_sensor);
  EXPECT_GE(r.radius_px, FarthestSensorPixelPx(Radial(1600, 1200, 0)));
}

TEST(ValidRegion, PincushionNeverFolds) {
  EXPECT_TRUE(ValidRegionOf(Radial(1600, 1200, 0.3)).covers_sensor);
}

TEST(ValidRegion, BarrelFoldsWhereTheClosedFormSays) {
  const double expected = ClosedFormFoldPx(-0.5, 1000);  // 544.3 px
  const auto big = ValidRegionOf(Radial(1600, 1200, -0.5));
  EXPECT_NEAR(big.radius_px, expected, kRadiusTolerancePx);
  EXPECT_FALSE(big.covers_sensor);  // the corners are 999 px away
  const auto small = ValidRegionOf(Radial(640, 480, -0.5));
  EXPECT_NEAR(small.radius_px, expected, kRadiusTolerancePx);
  EXPECT_TRUE(small.covers_sensor);  // 399 px
}

TEST(ValidRegion, DistortionCentreMovesTheNearestFold) {
  // Radial about e = (0.05, 0): the fold circle of radius 544.3 px about e; the nearest point to (cx, cy) is 50 px
  // closer.
  auto c = Radial(1600, 1200, -0.5);
  c.distortion_centre = {0.05, 0};
  EXPECT_NEAR(ValidRegionOf(c).radius_px, ClosedFormFoldPx(-0.5, 1000) - 50.0, kRadiusTolerancePx);
}

class ValidRegionFile : public topocal::testing_cli::TempDirTest {};

TEST_F(ValidRegionFile, StoredOnWriteAndComputedForOlderFiles) {
  const auto camera = Radial(1600, 1200, -0.5);
  util::WriteFileAtomic(Path("cal.yaml"), OpenCvCalibrationText(camera, "test"));
  cv::FileStorage stored(Path("cal.yaml"), cv::FileStorage::READ);
  EXPECT_NEAR(static_cast<double>(stored["valid_radius_px"]), ClosedFormFoldPx(-0.5, 1000), kRadiusTolerancePx);
  EXPECT_EQ(static_cast<int>(stored["valid_region_covers_sensor"]), 0);
  const auto loaded = LoadCalibrationFile(Path("cal.yaml"));
  EXPECT_NEAR(loaded.valid_region.radius_px, ClosedFormFoldPx(-0.5, 1000), kRadiusTolerancePx);
  EXPECT_FALSE(loaded.valid_region.covers_sensor);

  // A file from before the keys existed (or another tool's): the region is computed when it is read.
  std::ofstream(Path("old.yaml")) << "%YAML:1.0\n---\nimage_width: 1600\nimage_height: 1200\n"
                                     "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"
                                     "   data: [ 1000., 0., 799.5, 0., 1000., 599.5, 0., 0., 1. ]\n"
                                     "distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n"
                                     "   data: [ -0.5, 0., 0., 0., 0. ]\n";
  const auto old = LoadCalibrationFile(Path("old.yaml"));
  EXPECT_NEAR(old.valid_region.radius_px, ClosedFormFoldPx(-0.5, 1000), kRadiusTolerancePx);
  EXPECT_FALSE(old.valid_region.covers_sensor);

  // A flag that contradicts the radius is a corrupt file.
  std::ofstream(Path("bad.yaml")) << util::ReadFile(Path("old.yaml"))
                                  << "valid_radius_px: 544.3\nvalid_region_covers_sensor: 1\n";
  try {
    LoadCalibrationFile(Path("bad.yaml"));
    FAIL() << "accepted a contradicting valid_region_covers_sensor";
  } catch (const util::InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              Path("bad.yaml") + ": valid_region_covers_sensor: contradicts valid_radius_px and the image size");
  }
}

TEST_F(ValidRegionFile, UndistortSaysWhyPixelsAreBlack) {
  util::WriteFileAtomic(Path("cal.yaml"), OpenCvCalibrationText(Radial(1600, 1200, -0.5), "test"));
  cv::imwrite(Path("in.png"), cv::Mat(1200, 1600, CV_8UC1, cv::Scalar(200)));
  const auto run = testing_cli::RunTopocal(fmt::format("undistort --calibration {} --image {} --out {}",
                                                       Path("cal.yaml"), Path("in.png"), Path("out.png")));
  EXPECT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("beyond the fold of " + Path("cal.yaml") + "'s distortion model"), std::string::npos)
      << run.output;
  EXPECT_NE(run.output.find("within 544 px of the principal point"), std::string::npos) << run.output;
  // The black pixels are exactly those the message counts as beyond the fold or off the sensor.
  const cv::Mat out = cv::imread(Path("out.png"), cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(out.empty());
  EXPECT_GT(out.total() - static_cast<size_t>(cv::countNonZero(out)), 0u);

  // Spots beyond the region are refused, named, with the reason; the others are corrected.
  // The same camera with a 1 um pitch: 1 mm on the detection plane is 1000 px.
  std::ofstream(Path("device.json")) << testing_cli::NominalDeviceText(R"({"pixel_pitch_um": 1.0, "width_px": 1600,
    "height_px": 1200, "principal_point_px": [799.5, 599.5], "a_mm": 1.0, "rotated_180": false})");
  std::ofstream(Path("spots.csv")) << "ring,index,x_mm,y_mm\n1,0,0.01,0.0\n2,0,0.9,0.6\n";
  const auto spots = testing_cli::RunTopocal(
      fmt::format("undistort --calibration {} --device {} --spots {} --out {}", Path("cal.yaml"), Path("device.json"),
                  Path("spots.csv"), Path("out.csv")));
  EXPECT_EQ(spots.exit_code, 0) << spots.output;
  EXPECT_NE(spots.output.find("spot (2, 0)"), std::string::npos) << spots.output;
  EXPECT_NE(spots.output.find("beyond the 544 px"), std::string::npos) << spots.output;
  EXPECT_EQ(spots.output.find("spot (1, 0)"), std::string::npos) << spots.output;
}

}  // namespace
}  // namespace topocal::calib
