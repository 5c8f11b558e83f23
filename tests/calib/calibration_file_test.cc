// The calibration file: OpenCV-loadable, usable by cv::undistort, round trip through LoadCalibrationFile, strict
// validation of bad files, and the JSON report.
#include "calib/calibration_file.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "calib/opencv_equivalent.h"
#include "tests/calib/synthetic_views.h"
#include "util/io.h"
#include "util/version.h"

namespace topocal::calib {
namespace {

namespace fs = std::filesystem;

class CalibrationFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("topocal_calfile_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  void Write(const std::string& name, const std::string& text) const { std::ofstream(Path(name)) << text; }
  static CalibrationResult Calibrated(const model::CameraModel& cam, const CalibrationOptions& o) {
    std::mt19937 rng(21);
    const testing::GridTarget grid;
    std::vector<ViewObservations> views;
    for (const auto& pose : testing::ReferencePoses(grid)) views.push_back(testing::ProjectGrid(cam, pose, grid, 0.05, rng));
    return CalibrateMultiView(views, o);
  }
  fs::path dir_;
};

// Values go through YAML as text with 16-17 significant digits.
constexpr double kYamlRoundTrip = 1e-12;

TEST_F(CalibrationFileTest, OpenCvReadsItAndUndistortUsesIt) {
  CalibrationOptions o;
  o.pixel_pitch_um = 3.0;  // known sensor: the file carries it for the correction (pixels -> mm)
  const auto r = Calibrated(testing::ReferenceCamera(), o);
  ASSERT_TRUE(r.ok()) << r.message;
  WriteCalibrationFile(Path("cal.yaml"), r, {"board.yaml", {}, "2026-11-25T00:00:00Z"});
  cv::FileStorage fs(Path("cal.yaml"), cv::FileStorage::READ);
  ASSERT_TRUE(fs.isOpened());
  cv::Mat k, d;
  fs["camera_matrix"] >> k;
  fs["distortion_coefficients"] >> d;
  EXPECT_EQ(static_cast<int>(fs["image_width"]), 640);
  EXPECT_EQ(static_cast<int>(fs["image_height"]), 480);
  ASSERT_EQ(k.rows, 3);
  ASSERT_EQ(d.rows, 1);
  ASSERT_EQ(d.cols, 5);
  EXPECT_NEAR(k.at<double>(0, 0), r.camera.fx_px, kYamlRoundTrip * r.camera.fx_px);
  EXPECT_NEAR(d.at<double>(0), r.camera.dist[0], kYamlRoundTrip);
  const cv::Mat image(480, 640, CV_8UC1, cv::Scalar(128));
  cv::Mat undistorted;
  cv::undistort(image, undistorted, k, d);
  EXPECT_EQ(undistorted.size(), image.size());
  EXPECT_EQ(static_cast<std::string>(fs["model"]), "brown5");
  EXPECT_EQ(static_cast<std::string>(fs["tool_version"]), topocal::kVersion);

  const auto loaded = LoadCalibrationFile(Path("cal.yaml"));
  EXPECT_TRUE(loaded.written_by_topocal);
  EXPECT_EQ(loaded.model, "brown5");
  EXPECT_NEAR(loaded.camera.cy_px, r.camera.cy_px, kYamlRoundTrip * r.camera.cy_px);
  EXPECT_NEAR(*loaded.rms_px, r.rms_px, kYamlRoundTrip);
  EXPECT_EQ(loaded.per_view_rms_px.size(), r.per_view_rms_px.size());
  EXPECT_NEAR(loaded.stddev.at("fx"), r.parameters[0].stddev, kYamlRoundTrip * r.parameters[0].stddev);
  EXPECT_EQ(loaded.target, "board.yaml");
  ASSERT_TRUE(loaded.pixel_pitch_um);
  EXPECT_EQ(*loaded.pixel_pitch_um, 3.0);
  ASSERT_TRUE(loaded.focal_mm);
  EXPECT_NEAR(*loaded.focal_mm, 0.5 * (r.camera.fx_px + r.camera.fy_px) * 3e-3, kYamlRoundTrip);
  EXPECT_FALSE(loaded.sigma_per_mm2);  // brown5: no Seidel sigma
}

TEST_F(CalibrationFileTest, SeidelWithCentreKeepsTheExactModelAndAnOpenCvEquivalent) {
  auto cam = testing::ReferenceCamera();
  cam.dist = {-0.3, 0, 0, 0, 0};
  cam.distortion_centre = {0.02, -0.015};
  CalibrationOptions o;
  o.model = DistortionModelKind::kSeidel;
  o.fit_distortion_centre = true;
  o.focal_mm = 4.0;
  const auto r = Calibrated(cam, o);
  ASSERT_TRUE(r.ok()) << r.message;
  WriteCalibrationFile(Path("cal.yaml"), r, {});
  const auto loaded = LoadCalibrationFile(Path("cal.yaml"));
  EXPECT_NEAR(loaded.camera.distortion_centre.x(), r.camera.distortion_centre.x(), kYamlRoundTrip);
  EXPECT_NEAR(loaded.camera.dist[0], r.camera.dist[0], kYamlRoundTrip);
  EXPECT_EQ(loaded.opencv_camera.distortion_centre, Eigen::Vector2d::Zero());
  ASSERT_TRUE(loaded.sigma_per_mm2);
  EXPECT_NEAR(*loaded.sigma_per_mm2, r.seidel->sigma_per_mm2, kYamlRoundTrip * std::abs(r.seidel->sigma_per_mm2));
}

TEST(OpenCvEquivalent, DecentringIsAbsorbedExceptForTheSkewAndTheReportSaysHowMuchIsLeft) {
  // A strong barrel (k1 = -0.3) decentred by ~5 px. OpenCV's model absorbs the decentring into p1, p2 and cx, cy;
  // what it cannot hold is the skew 2 k1 e_x e_y u (4.8e-5 x |u| <= 1 x 540 px = 0.026 px at the fold) and
  // higher orders: measured 0.051 px. Dropping the centre instead would cost ~k1 e |u|^2 f = 1.6 px.
  auto cam = testing::ReferenceCamera();
  cam.dist = {-0.3, 0, 0, 0, 0};
  cam.distortion_centre = {0.01, -0.008};
  const auto eq = ToOpenCvModel(cam);
  ASSERT_TRUE(eq);
  EXPECT_EQ(eq->camera.distortion_centre, Eigen::Vector2d::Zero());
  // The reported figure is what an independent check over the image finds, and it beats dropping the centre.
  double worst = 0, worst_dropped = 0;
  model::CameraModel dropped = cam;
  dropped.distortion_centre.setZero();
  for (double x = 0; x <= 639; x += 32) {
    for (double y = 0; y <= 479; y += 24) {
      const auto u = cam.PixelToNormalized({x, y});
      if (!u) continue;
      worst = std::max(worst, (eq->camera.Project({u->x(), u->y(), 1.0}) - Eigen::Vector2d(x, y)).norm());
      worst_dropped = std::max(worst_dropped, (dropped.Project({u->x(), u->y(), 1.0}) - Eigen::Vector2d(x, y)).norm());
    }
  }
  EXPECT_LE(worst, eq->max_error_px + 1e-9);
  constexpr double kMinImprovement = 10.0;  // an order of magnitude over ignoring the centre
  EXPECT_LT(kMinImprovement * eq->max_error_px, worst_dropped);
  RecordProperty("opencv_equivalent_max_error_px", std::to_string(eq->max_error_px));
  RecordProperty("dropped_centre_max_error_px", std::to_string(worst_dropped));
}

TEST_F(CalibrationFileTest, CovarianceRoundTripsAndOlderFilesFallBackToTheDiagonal) {
  const auto r = Calibrated(testing::ReferenceCamera(), {});
  ASSERT_TRUE(r.ok()) << r.message;
  WriteCalibrationFile(Path("cal.yaml"), r, {"board.yaml", {}, "2026-11-25T00:00:00Z"});
  const auto loaded = LoadCalibrationFile(Path("cal.yaml"));
  ASSERT_TRUE(loaded.covariance.has_value());
  ASSERT_EQ(loaded.parameter_names, CameraParameterNames(DistortionModelKind::kBrown5));
  ASSERT_EQ(loaded.parameter_names.size(), 11u);  // fx fy cx cy, k1 k2 p1 p2 k3, ex ey
  EXPECT_TRUE(loaded.covariance->isApprox(r.covariance, kYamlRoundTrip));
  const auto full = ParameterCovarianceOf(loaded);
  EXPECT_TRUE(full.full);
  EXPECT_NE(full.matrix(4, 5), 0.0);  // k1-k2 cross term kept

  // The same file without the covariance (as written before it was stored): the diagonal of the stddevs.
  std::string text = util::ReadFile(Path("cal.yaml"));
  const auto begin = text.find("parameter_covariance:");
  const auto end = text.find("rms_px:", begin);
  ASSERT_NE(begin, std::string::npos);
  ASSERT_NE(end, std::string::npos);
  text.erase(begin, end - begin);
  Write("old.yaml", text);
  const auto diagonal = ParameterCovarianceOf(LoadCalibrationFile(Path("old.yaml")));
  EXPECT_FALSE(diagonal.full);
  EXPECT_EQ(diagonal.matrix(4, 5), 0.0);
  EXPECT_NEAR(diagonal.matrix(4, 4), r.covariance(4, 4), kYamlRoundTrip * r.covariance(4, 4));

  // A corrupt covariance (one entry too many) is named.
  std::string asymmetric = util::ReadFile(Path("cal.yaml"));
  const auto data = asymmetric.find("data: [", asymmetric.find("parameter_covariance:"));
  asymmetric.insert(data + 7, "1., ");
  Write("bad.yaml", asymmetric);
  try {
    LoadCalibrationFile(Path("bad.yaml"));
    FAIL() << "accepted a corrupt covariance";
  } catch (const util::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("parameter_covariance"), std::string::npos) << e.what();
  }
}

TEST_F(CalibrationFileTest, PlainOpenCvFileIsAccepted) {
  Write("cv.yaml",
        "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n"
        "   dt: d\n   data: [ 500., 0., 320., 0., 500., 240., 0., 0., 1. ]\ndistortion_coefficients: !!opencv-matrix\n"
        "   rows: 5\n   cols: 1\n   dt: d\n   data: [ -0.1, 0.01, 0., 0., 0. ]\n");
  const auto loaded = LoadCalibrationFile(Path("cv.yaml"));
  EXPECT_FALSE(loaded.written_by_topocal);
  EXPECT_EQ(loaded.camera.fx_px, 500.0);
  EXPECT_EQ(loaded.camera.dist[0], -0.1);
}

TEST_F(CalibrationFileTest, BadFilesAreOneLineNamingFileAndKey) {
  const auto message = [&](const std::string& name) -> std::string {
    try {
      LoadCalibrationFile(Path(name));
    } catch (const util::InputError& e) {
      return e.what();
    }
    return "no error";
  };
  const std::string k = "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"
                        "   data: [ 500., 0., 320., 0., 500., 240., 0., 0., 1. ]\n";
  const std::string d4 = "distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 4\n   dt: d\n"
                         "   data: [ -0.1, 0.01, 0., 0. ]\n";
  Write("missing_width.yaml", "%YAML:1.0\n---\nimage_height: 480\n" + k + d4);
  EXPECT_EQ(message("missing_width.yaml"), Path("missing_width.yaml") + ": image_width: missing");
  // Four coefficients (OpenCV with CALIB_FIX_K3 in some tools) are k3 = 0; three are nothing OpenCV writes.
  Write("four.yaml", "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\n" + k + d4);
  EXPECT_EQ(message("four.yaml"), "no error");
  EXPECT_EQ(LoadCalibrationFile(Path("four.yaml")).camera.dist[4], 0.0);
  Write("three.yaml", "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\n" + k +
                          "distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 3\n   dt: d\n"
                          "   data: [ -0.1, 0.01, 0. ]\n");
  EXPECT_EQ(message("three.yaml"), Path("three.yaml") + ": distortion_coefficients: expected 4, 5, 8, 12 or 14 "
                                                        "coefficients in a row or column, found 1x3");
  // Eight coefficients: OpenCV's rational model, brown5 when k4..k6 are 0 and rational8 otherwise; twelve only with
  // the thin-prism terms 0.
  const std::string d8 = "distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 8\n   dt: d\n"
                         "   data: [ -0.1, 0.01, 0., 0., 0.002, ";
  Write("eight_zero.yaml", "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\n" + k + d8 + "0., 0., 0. ]\n");
  EXPECT_EQ(LoadCalibrationFile(Path("eight_zero.yaml")).camera.dist[4], 0.002);
  EXPECT_TRUE(std::holds_alternative<model::BrownConrady>(LoadCalibrationFile(Path("eight_zero.yaml")).camera.lens));
  Write("rational.yaml", "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\n" + k + d8 + "0.3, 0., 0. ]\n");
  const auto rational = LoadCalibrationFile(Path("rational.yaml")).camera;
  EXPECT_TRUE(std::holds_alternative<model::RationalPolynomial>(rational.lens));
  EXPECT_EQ(rational.dist[5], 0.3);
  Write("prism.yaml", "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\n" + k +
                          "distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 12\n   dt: d\n"
                          "   data: [ -0.1, 0.01, 0., 0., 0.002, 0., 0., 0., 0.001, 0., 0., 0. ]\n");
  EXPECT_EQ(message("prism.yaml"), Path("prism.yaml") + ": distortion_coefficients: coefficient 9 is 0.001 but "
                                                        "topocal's lens models end at k6 (OpenCV's thin-prism and "
                                                        "tilt terms must be 0)");
  Write("other.yaml", "%YAML:1.0\n---\nfoo: 1\n");
  EXPECT_EQ(message("other.yaml"),
            Path("other.yaml") + ": camera_matrix: missing: not a topocal or OpenCV calibration file");
  Write("garbage.yaml", "this is { not yaml");
  EXPECT_NE(message("garbage.yaml").find(Path("garbage.yaml") + ": "), std::string::npos);
  EXPECT_EQ(message("nope.yaml"), Path("nope.yaml") + ": cannot be opened");
}

TEST_F(CalibrationFileTest, JsonReportHasTheIssueKeys) {
  const auto r = Calibrated(testing::ReferenceCamera(), {});
  ASSERT_TRUE(r.ok());
  const auto j = nlohmann::json::parse(CalibrationReportJson(r, {}));
  for (const char* key : {"rms_px", "camera_matrix", "dist_coeffs", "stddev", "views_used", "per_view_rms_px",
                          "outliers"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  EXPECT_EQ(j["dist_coeffs"].size(), 5u);
  EXPECT_EQ(j["views_used"], 8);
  EXPECT_DOUBLE_EQ(j["rms_px"].get<double>(), r.rms_px);
}

}  // namespace
}  // namespace topocal::calib
