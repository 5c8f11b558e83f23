// The topographer's camera: pixel <-> detection-plane mapping, its orientation, and strict loading.
#include "model/device.h"
#include "model/topographer_camera.h"

#include <gtest/gtest.h>

#include "util/io.h"

namespace topocal::model {
namespace {

// Round trip of two affine maps in double: a few ulps of a 4000 px coordinate.
constexpr double kRoundTripPx = 1e-9;

TEST(TopographerCamera, TheBundledDevicesCameraFitsThePaperPattern) {
  const auto c = model::LoadDevice(std::string(TOPOCAL_SOURCE_DIR) + "/data/device.json").device.camera;
  EXPECT_FALSE(c.Invalid().has_value());
  // The paper's spot image spans about +-0.45 mm (Table V semi-axes ~0.39 mm, plus the strongest pincushion):
  // all of it must land on the sensor.
  for (const double x : {-0.45, 0.45}) {
    for (const double y : {-0.45, 0.45}) EXPECT_TRUE(c.OnSensor(c.PixelFromDetectionPlane({x, y})));
  }
}

TEST(TopographerCamera, OrientationAndRoundTrip) {
  TopographerCamera c;
  // Default: detection-plane +x is pixel +u, +y is pixel +v (down); principal point at the optical axis.
  EXPECT_NEAR((c.PixelFromDetectionPlane({0, 0}) - c.principal_point_px).norm(), 0, kRoundTripPx);
  const Eigen::Vector2d px = c.PixelFromDetectionPlane({c.PitchMm(), 2 * c.PitchMm()});
  EXPECT_NEAR(px.x() - c.principal_point_px.x(), 1.0, kRoundTripPx);
  EXPECT_NEAR(px.y() - c.principal_point_px.y(), 2.0, kRoundTripPx);
  c.orientation = model::ImageOrientation::kRotate180;
  const Eigen::Vector2d rot = c.PixelFromDetectionPlane({c.PitchMm(), 2 * c.PitchMm()});
  EXPECT_NEAR(rot.x() - c.principal_point_px.x(), -1.0, kRoundTripPx);
  EXPECT_NEAR(rot.y() - c.principal_point_px.y(), -2.0, kRoundTripPx);
  for (const Eigen::Vector2d& p : {Eigen::Vector2d(0, 0), Eigen::Vector2d(3999, 2999), Eigen::Vector2d(12.25, 2000.75)}) {
    EXPECT_NEAR((c.PixelFromDetectionPlane(c.DetectionPlaneFromPixel(p)) - p).norm(), 0, kRoundTripPx);
  }
  // OpenCV's normalised coordinates are x_mm / a: fx = a / pitch.
  EXPECT_NEAR(c.FocalPx(), 5.2 / 1.12e-3, 1e-9);
}

std::string ErrorOf(const std::string& text) {
  try {
    ParseTopographerCamera(text, "cam.json");
  } catch (const util::InputError& e) {
    return e.what();
  }
  return "";
}

TEST(TopographerCamera, StrictLoadingNamesFileKeyAndProblem) {
  const std::string good = R"({"pixel_pitch_um": 1.12, "width_px": 4000, "height_px": 3000,
                               "principal_point_px": [1999.5, 1499.5], "a_mm": 5.2, "rotated_180": false})";
  EXPECT_EQ(ErrorOf(good), "");
  EXPECT_EQ(TopographerCameraToJson(ParseTopographerCamera(good, "x")),
            TopographerCameraToJson(ParseTopographerCamera(TopographerCameraToJson(ParseTopographerCamera(good, "x")), "y")));
  EXPECT_EQ(ErrorOf(R"({"pixel_pitch_um": 1.12})"), "cam.json: width_px: missing");
  EXPECT_EQ(ErrorOf(R"({"pixel_pitch_um": 1.12, "width_px": 4000, "height_px": 3000, "principal_point_px": [1, 1],
                       "a_mm": 5.2, "pitch": 1})"),
            "cam.json: pitch: unknown key");
  EXPECT_NE(ErrorOf(R"({"pixel_pitch_um": -1, "width_px": 4000, "height_px": 3000, "principal_point_px": [1, 1],
                       "a_mm": 5.2})").find("cam.json: pixel_pitch_um: must be > 0"),
            std::string::npos);
  EXPECT_NE(ErrorOf(R"({"pixel_pitch_um": 1, "width_px": 4000.5, "height_px": 3000, "principal_point_px": [1, 1],
                       "a_mm": 5.2})").find("cam.json: width_px: must be an integer"),
            std::string::npos);
  EXPECT_NE(ErrorOf(R"({"pixel_pitch_um": 1, "width_px": 40, "height_px": 30, "principal_point_px": [100, 1],
                       "a_mm": 5.2})").find("principal_point_px: (100, 1) lies outside"),
            std::string::npos);
  EXPECT_NE(ErrorOf(R"({"pixel_pitch_um": 1, "width_px": 40, "height_px": 30, "principal_point_px": [1],
                       "a_mm": 5.2})").find("principal_point_px: must be an array of 2 finite numbers"),
            std::string::npos);
  EXPECT_NE(ErrorOf(R"({"pixel_pitch_um": 1, "width_px": 40, "height_px": 30, "principal_point_px": [1, 1],
                       "a_mm": 5.2, "rotated_180": "yes"})").find("rotated_180: must be true or false"),
            std::string::npos);
  EXPECT_NE(ErrorOf("{nope").find("cam.json: not valid JSON"), std::string::npos);
}

// Non-square pixels (OpenCV's fx != fy): the pitch along v is pitch_u x pixel_aspect, in every orientation; the
// file carries the aspect only when it is not 1, and refuses one no sensor has.
TEST(TopographerCamera, PixelAspectScalesTheVAxisAndRoundTrips) {
  TopographerCamera c;
  c.pixel_aspect = 1.0002;
  for (const auto o : {ImageOrientation::kIdentity, ImageOrientation::kRotate90, ImageOrientation::kTranspose}) {
    c.orientation = o;
    const Eigen::Vector2d one_v = c.DetectionPlaneFromPixel(c.principal_point_px + Eigen::Vector2d(0, 1));
    EXPECT_NEAR(one_v.norm(), c.PitchMm() * 1.0002, 1e-15);
    const Eigen::Vector2d one_u = c.DetectionPlaneFromPixel(c.principal_point_px + Eigen::Vector2d(1, 0));
    EXPECT_NEAR(one_u.norm(), c.PitchMm(), 1e-15);
    const Eigen::Vector2d p(12.25, 2000.75);
    EXPECT_NEAR((c.PixelFromDetectionPlane(c.DetectionPlaneFromPixel(p)) - p).norm(), 0, kRoundTripPx);
  }
  const std::string square = R"({"pixel_pitch_um": 1.12, "width_px": 4000, "height_px": 3000,
                                 "principal_point_px": [1999.5, 1499.5], "a_mm": 5.2})";
  EXPECT_EQ(TopographerCameraToJson(ParseTopographerCamera(square, "x")).find("pixel_aspect"), std::string::npos);
  c = ParseTopographerCamera(TopographerCameraToJson(c), "x");
  EXPECT_EQ(c.pixel_aspect, 1.0002);
  EXPECT_NE(ErrorOf(R"({"pixel_pitch_um": 1, "width_px": 40, "height_px": 30, "principal_point_px": [1, 1],
                       "a_mm": 5.2, "pixel_aspect": 0})").find("cam.json: pixel_aspect: must be in [0.5, 2] (got 0)"),
            std::string::npos);
}

}  // namespace
}  // namespace topocal::model
