// `topocal calibrate` end to end on OpenCV's real chessboard photographs: outputs, skipped images, and failures
// that leave no output file.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "tests/cli_harness.h"

namespace {

namespace fs = std::filesystem;

const std::string kDataDir = "/usr/share/doc/opencv-doc/examples/data/";

using topocal::testing_cli::Run;
using topocal::testing_cli::RunTopocal;

int CountLines(const std::string& s) { return static_cast<int>(std::count(s.begin(), s.end(), '\n')); }

class CalibrateCli : public topocal::testing_cli::TempDirTest {
 protected:
  void SetUp() override {
    TempDirTest::SetUp();
    // The real photographs are part of the test set (scripts/setup.sh test installs opencv-doc): missing, they fail.
    if (!fs::exists(kDataDir + "left01.jpg"))
      FAIL() << "opencv-doc's left*.jpg are not installed (apt-get install opencv-doc)";
    // OpenCV's board: 9 x 6 inner corners; the square size is not known, 25 mm is as good as any.
    Write("board.yaml",
          "target_type: checkerboard\ntargetCols: 9\ntargetRows: 6\nrowSpacingMeters: 0.025\ncolSpacingMeters: "
          "0.025\n");
  }
  void CopyImages(const std::vector<int>& numbers) const {
    for (int i : numbers) {
      const std::string name = (i < 10 ? "left0" : "left") + std::to_string(i) + ".jpg";
      fs::copy_file(kDataDir + name, Path(name));
    }
  }
};

TEST_F(CalibrateCli, RealPhotographsWriteAnOpenCvFileAndAJsonReport) {
  const auto r = RunTopocal("calibrate --target " + Path("board.yaml") + " --images '" + kDataDir +
                            "left[0-9][0-9].jpg' --model brown5 --out " + Path("cal.yaml") + " --json " +
                            Path("report.json"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("[13/13]"), std::string::npos) << r.output;  // progress with many images
  cv::FileStorage file(Path("cal.yaml"), cv::FileStorage::READ);
  ASSERT_TRUE(file.isOpened());
  cv::Mat k, d;
  file["camera_matrix"] >> k;
  file["distortion_coefficients"] >> d;
  EXPECT_EQ(d.total(), 5u);
  // cv::calibrateCamera on these photographs: fx ~ 536 px (the library test pins the exact agreement).
  EXPECT_NEAR(k.at<double>(0, 0), 536.0, 5.0);
  std::ifstream in(Path("report.json"));
  const auto j = nlohmann::json::parse(in);
  EXPECT_EQ(j["views_used"], 13);
  EXPECT_EQ(j["per_view_rms_px"].size(), 13u);
  EXPECT_LT(j["rms_px"].get<double>(), 1.0);
  EXPECT_EQ(r.output.find("nan"), std::string::npos);
  // 13 views over the whole image determine every parameter (k3 = 0.21 +- 0.074 against a plausible +-5.6).
  EXPECT_EQ(j["undetermined"], nlohmann::json::array());
  EXPECT_EQ(r.output.find("undetermined"), std::string::npos) << r.output;
}

// A single view of a board in the middle of the image (about a fifth of its width) leaves k2 and k3 undetermined:
// k3 = -46 +- 211 where a lens could not go beyond +-5.6 (measured 2026-12-06). Reported with the advice; held fixed,
// the rest is determined.
TEST_F(CalibrateCli, ParametersTheViewsDoNotDetermineAreFlagged) {
  ASSERT_EQ(RunTopocal("render-target --target " + Path("board.yaml") + " --out " + Path("small.png") +
                       " --fx 533 --k1 -0.28 --k2 0.1 --distance-mm 1000 --tilt-x-deg 10")
                .exit_code,
            0);
  const auto calibrate = [&](const std::string& extra) {
    return RunTopocal("calibrate --target " + Path("board.yaml") + " --images " + Path("small.png") +
                      " --model brown5 --single-view --focal-mm 3.2 --pixel-pitch-um 6 --distance-mm 1000 --out " +
                      Path("cal.yaml") + " --json " + Path("report.json") + " " + extra);
  };
  auto r = calibrate("");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("warning: undetermined: k2 = "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("hold them fixed (--fix k2 k3) or add views"), std::string::npos) << r.output;
  auto j = nlohmann::json::parse(std::ifstream(Path("report.json")));
  ASSERT_EQ(j["undetermined"].size(), 2u) << j["undetermined"];
  EXPECT_EQ(j["undetermined"][1]["name"], "k3");
  EXPECT_GT(j["undetermined"][1]["stddev"].get<double>(), j["undetermined"][1]["plausible_half_range"].get<double>());
  r = calibrate("--fix k2 k3");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(r.output.find("undetermined"), std::string::npos) << r.output;
  j = nlohmann::json::parse(std::ifstream(Path("report.json")));
  EXPECT_EQ(j["undetermined"], nlohmann::json::array());
}

TEST_F(CalibrateCli, RobustSeidelReportsOutliersAndSigma) {
  CopyImages({1, 2, 3, 4, 5, 6});
  const auto r = RunTopocal("calibrate --target " + Path("board.yaml") + " --images '" + Path("left*.jpg") +
                            "' --model seidel --fit-centre --pixel-pitch-um 6 --robust --out " + Path("cal.yaml") +
                            " --json " + Path("report.json"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("Seidel sigma"), std::string::npos) << r.output;
  std::ifstream in(Path("report.json"));
  const auto j = nlohmann::json::parse(in);
  ASSERT_TRUE(j.contains("seidel"));
  ASSERT_TRUE(j["outliers"].is_array());
  // Every corner is either used or an outlier, and each outlier is named on the terminal (measured 2026-12-02: 3 of
  // 324, residuals 0.65-0.94 px).
  EXPECT_EQ(j["corners_used"].get<size_t>() + j["outliers"].size(), 6u * 54u);
  EXPECT_GE(j["outliers"].size(), 1u);
  for (const auto& o : j["outliers"]) {
    const std::string line =
        "outlier " + o["image"].get<std::string>() + " corner " + std::to_string(o["corner_id"].get<int>()) + ":";
    EXPECT_NE(r.output.find(line), std::string::npos) << line;
  }
  // sigma comes with the focal length it was converted with, f = (fx + fy) / 2 x pitch (6 um), and a meaningful
  // spread.
  const auto& seidel = j["seidel"];
  const double mean_focal_px = 0.5 * (j["camera_matrix"][0][0].get<double>() + j["camera_matrix"][1][1].get<double>());
  EXPECT_NEAR(seidel["focal_mm"].get<double>(), mean_focal_px * 6e-3, 1e-12);
  EXPECT_GT(seidel["sigma_per_mm2"].get<double>(), 0.0);
  EXPECT_LT(seidel["sigma_stddev_per_mm2"].get<double>(), 0.1 * seidel["sigma_per_mm2"].get<double>());
}

TEST_F(CalibrateCli, ImagesWithoutTargetAreListedAndSkipped) {
  CopyImages({1, 2, 3, 4});
  cv::imwrite(Path("left99.png"), cv::Mat(480, 640, CV_8UC1, cv::Scalar(128)));
  Write("left98.png", "not an image");
  const auto r = RunTopocal("calibrate --target " + Path("board.yaml") + " --images '" + Path("left*") +
                            "' --out " + Path("cal.yaml"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("skipping " + Path("left99.png") + ": no target found"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("skipping " + Path("left98.png") + ": cannot be read"), std::string::npos) << r.output;
  EXPECT_TRUE(fs::exists(Path("cal.yaml")));
}

// Bad input per view: another image size, a truncated JPEG, a photo without a board, a target file that
// contradicts the photos (8 x 5 for a 9 x 6 board): one line each naming the file, the good views are used.
TEST_F(CalibrateCli, BadViewsAreNamedAndTheRunGoesOnWithTheGoodOnes) {
  CopyImages({1, 2, 3, 4, 5});
  cv::Mat small = cv::imread(Path("left01.jpg"), cv::IMREAD_GRAYSCALE);
  cv::resize(small, small, cv::Size(320, 240));
  cv::imwrite(Path("left90.png"), small);
  std::ifstream original(Path("left02.jpg"), std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(original)), std::istreambuf_iterator<char>());
  Write("left91.jpg", bytes.substr(0, 100));  // truncated in its header: not an image
  cv::imwrite(Path("left92.png"), cv::Mat(480, 640, CV_8UC1, cv::Scalar(128)));
  const auto r = RunTopocal("calibrate --target " + Path("board.yaml") + " --images '" + Path("left*") +
                            "' --out " + Path("cal.yaml"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("skipping " + Path("left90.png") + ": 320 x 240 px, not the 640 x 480 px of the "),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("skipping " + Path("left91.jpg") + ": cannot be read"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("skipping " + Path("left92.png") + ": no target found"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("from 5 view(s)"), std::string::npos) << r.output;

  // 8 x 5 inner corners written for the 9 x 6 board: no view passes silently.
  Write("wrong.yaml",
        "target_type: checkerboard\ntargetCols: 8\ntargetRows: 5\nrowSpacingMeters: 0.025\ncolSpacingMeters: 0.025\n");
  const auto wrong = RunTopocal("calibrate --target " + Path("wrong.yaml") + " --images '" + Path("left0*.jpg") +
                                "' --out " + Path("wrong.yaml.cal"));
  EXPECT_EQ(wrong.exit_code, 1) << wrong.output;
  EXPECT_NE(wrong.output.find("no 8x5 checkerboard found"), std::string::npos) << wrong.output;
  EXPECT_FALSE(fs::exists(Path("wrong.yaml.cal")));
}

TEST_F(CalibrateCli, SquaresCountedInsteadOfInnerCornersGetAHint) {
  CopyImages({1, 2, 3});
  Write("squares.yaml",
        "target_type: checkerboard\ntargetCols: 10\ntargetRows: 7\nrowSpacingMeters: 0.025\ncolSpacingMeters: 0.025\n");
  const auto r = RunTopocal("calibrate --target " + Path("squares.yaml") + " --images '" + Path("left*.jpg") +
                            "' --out " + Path("cal.yaml"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("hint: the image shows a 9x6 board"), std::string::npos) << r.output;
}

// One column off on a phone-sized view (a 13 x 13 board described as 14 x 13): the run ends in seconds (it once ran
// 17 minutes inside OpenCV's full-resolution search), says what the image shows and names the description.
TEST_F(CalibrateCli, ABoardOneColumnOffIsNamedWithWhatTheImageShows) {
  Write("t13.yaml", "target_type: checkerboard\ntargetCols: 13\ntargetRows: 13\nrowSpacingMeters: 0.0009\n"
                    "colSpacingMeters: 0.0009\n");
  Write("t14.yaml", "target_type: checkerboard\ntargetCols: 14\ntargetRows: 13\nrowSpacingMeters: 0.0009\n"
                    "colSpacingMeters: 0.0009\n");
  ASSERT_EQ(RunTopocal("render-target --target " + Path("t13.yaml") + " --width 4000 --height 3000 --fx 4642.857 "
                       "--k1 -0.2 --distance-mm 40 --out " + Path("big.png"))
                .exit_code,
            0);
  const auto r = RunTopocal("calibrate --target " + Path("t14.yaml") + " --images " + Path("big.png") +
                            " --model seidel --single-view --focal-mm 5.2 --pixel-pitch-um 1.12 --distance-mm 40 --out " +
                            Path("cal.yaml"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("the image shows a 13x13 board of inner corners where the description says 14x13"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("(target description " + Path("t14.yaml") + ")"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(Path("cal.yaml")));
}

TEST_F(CalibrateCli, CrossValidationWritesItsMapAndBoardWarpIsReported) {
  const auto r = RunTopocal("calibrate --target " + Path("board.yaml") + " --images '" + kDataDir +
                            "left[0-9][0-9].jpg' --out " + Path("cal.yaml") + " --json " + Path("report.json") +
                            " --cross-validate " + Path("cv.svg") + " --board-warp");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::printf("%s", r.output.substr(r.output.find("brown5")).c_str());
  EXPECT_NE(r.output.find("cross-validation: halves of 7 and 6 views differ by RMS"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("board warp: sag_x ="), std::string::npos) << r.output;
  std::ifstream svg(Path("cv.svg"));
  const std::string text((std::istreambuf_iterator<char>(svg)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("<svg"), std::string::npos);
  EXPECT_NE(text.find("homography removed"), std::string::npos);
  std::ifstream in(Path("report.json"));
  const auto j = nlohmann::json::parse(in);
  EXPECT_TRUE(j.contains("board_warp"));
  // Single view: neither applies, bad input.
  const auto single = RunTopocal("calibrate --target " + Path("board.yaml") + " --images '" + kDataDir +
                                 "left01.jpg' --single-view --focal-mm 4 --pixel-pitch-um 6 --distance-mm 400 --out " +
                                 Path("s.yaml") + " --cross-validate " + Path("s.svg"));
  EXPECT_EQ(single.exit_code, 2) << single.output;
  EXPECT_FALSE(fs::exists(Path("s.yaml")));
}

TEST_F(CalibrateCli, TooFewViewsIsOneLineExitOneAndNoOutput) {
  CopyImages({1, 2});
  const auto r = RunTopocal("calibrate --target " + Path("board.yaml") + " --images '" + Path("*.jpg") + "' --out " +
                            Path("cal.yaml") + " --json " + Path("report.json"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(CountLines(r.output), 1) << r.output;
  EXPECT_NE(r.output.find("too few views"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(Path("cal.yaml")));
  EXPECT_FALSE(fs::exists(Path("report.json")));
}

TEST_F(CalibrateCli, DegenerateSetIsOneLineExitOneAndNoOutput) {
  // One photograph three times, each with other sensor noise (one grey level on a different pixel): one target
  // orientation, which cannot determine the intrinsics.
  const cv::Mat photo = cv::imread(kDataDir + "left03.jpg", cv::IMREAD_GRAYSCALE);
  ASSERT_FALSE(photo.empty());
  for (int k = 0; k < 3; ++k) {
    cv::Mat noisy = photo.clone();
    noisy.at<uint8_t>(k, 0) ^= 1;
    ASSERT_TRUE(cv::imwrite(Path(fmt::format("{}.png", k)), noisy));
  }
  const auto r = RunTopocal("calibrate --target " + Path("board.yaml") + " --images '" + Path("*.png") + "' --out " +
                            Path("cal.yaml") + " --json " + Path("report.json"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(CountLines(r.output), 1) << r.output;
  EXPECT_NE(r.output.find("degenerate"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(Path("cal.yaml")));
  EXPECT_FALSE(fs::exists(Path("report.json")));
}

// The same photograph under three names was once calibrated as three views, each copy shrinking the reported
// standard deviations by another sqrt(2) for no new information. Each repeat is skipped naming the first; what is
// left is one view.
TEST_F(CalibrateCli, ARepeatedPhotographIsOneView) {
  for (const char* name : {"a.jpg", "b.jpg", "c.jpg"}) fs::copy_file(kDataDir + "left03.jpg", Path(name));
  const cv::Mat png = cv::imread(kDataDir + "left04.jpg", cv::IMREAD_GRAYSCALE);
  ASSERT_TRUE(cv::imwrite(Path("d.png"), png));
  fs::copy_file(kDataDir + "left04.jpg", Path("e.jpg"));  // the same pixels in another file format
  const auto r = RunTopocal("calibrate --target " + Path("board.yaml") + " --images '" + Path("*.*g") + "' --out " +
                            Path("cal.yaml") + " --json " + Path("report.json"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("skipping " + Path("b.jpg") + ": the same image as " + Path("a.jpg") +
                          " (identical pixels): no new view"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("skipping " + Path("c.jpg") + ": the same image as " + Path("a.jpg")), std::string::npos);
  EXPECT_NE(r.output.find("skipping " + Path("e.jpg") + ": the same image as " + Path("d.png")), std::string::npos);
  EXPECT_NE(r.output.find("too few views"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(Path("cal.yaml")));
}

TEST_F(CalibrateCli, BadInputIsExitTwo) {
  auto r = RunTopocal("calibrate --target " + Path("nope.yaml") + " --images '" + kDataDir + "left0*.jpg' --out " +
                      Path("cal.yaml"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_EQ(CountLines(r.output), 1) << r.output;
  r = RunTopocal("calibrate --target " + Path("board.yaml") + " --images '" + Path("*.tif") + "' --out " +
                 Path("cal.yaml"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.output, "topocal: --images '" + Path("*.tif") + "': no file matches\n");
  r = RunTopocal("calibrate --target " + Path("board.yaml") + " --images '" + kDataDir + "left0*.jpg' --model tps --out " +
                 Path("cal.yaml"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.output, "topocal: --model: 'tps' is not one of seidel, brown5, rational8\n");
  r = RunTopocal("calibrate --target " + Path("board.yaml") + " --images '" + kDataDir + "left0*.jpg' --fix k9 --out " +
                 Path("cal.yaml"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("k9"), std::string::npos);
  r = RunTopocal("calibrate --target " + Path("board.yaml") + " --images '" + kDataDir +
                 "left01.jpg' --single-view --focal-mm 3.2 --out " + Path("cal.yaml"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("--distance-mm"), std::string::npos);
  EXPECT_FALSE(fs::exists(Path("cal.yaml")));
}

TEST_F(CalibrateCli, SingleViewRuns) {
  // left01.jpg as if it were the topographer's single view: f = 536 px x 6 um = 3.2 mm, board ~ 400 mm away.
  const auto r = RunTopocal("calibrate --target " + Path("board.yaml") + " --images '" + kDataDir +
                            "left01.jpg' --model seidel --single-view --focal-mm 3.216 --pixel-pitch-um 6 "
                            "--distance-mm 400 --out " + Path("cal.yaml") + " --json " + Path("report.json"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::ifstream in(Path("report.json"));
  const auto j = nlohmann::json::parse(in);
  EXPECT_EQ(j["single_view"], true);
  // The board is found where it was said to be (measured 2026-12-02: 402.0 mm) with a sub-pixel fit (0.18 px).
  EXPECT_NEAR(j["target_distance_mm"].get<double>(), 400.0, 10.0);
  EXPECT_LT(j["rms_px"].get<double>(), 0.5);
}

// --device-out: the lens calibration applied to a nominal device of the same sensor (640 x 480 px of 6 um here), with
// the calibration's k1 and its standard deviation; a device of another sensor is refused and nothing is written.
TEST_F(CalibrateCli, DeviceOutIsTheLensCalibrationAppliedToTheNominalDevice) {
  const std::string device =
      R"({"format": "topocal-device", "format_version": 1,
          "camera": {"pixel_pitch_um": 6.0, "width_px": 640, "height_px": 480, "principal_point_px": [319.5, 239.5],
                     "a_mm": 3.2, "orientation": "identity"},
          "distortion": {"model": "seidel", "sigma_per_mm2": 0.0, "magnification": -0.065, "centre_mm": [0.0, 0.0]},
          "screen_pose": {"rx_deg": 0.0, "ry_deg": 0.0, "rz_deg": 0.0, "tx_mm": 0.0, "ty_mm": 0.0, "tz_mm": 0.0,
                          "radial_scale": 1.0}})";
  std::ofstream(Path("nominal.json")) << device;
  const std::string single = "calibrate --target " + Path("board.yaml") + " --images '" + kDataDir +
                             "left01.jpg' --model seidel --single-view --focal-mm 3.216 --pixel-pitch-um 6 "
                             "--distance-mm 400 --out " + Path("cal.yaml") + " --json " + Path("report.json");
  auto r = RunTopocal(single + " --device " + Path("nominal.json") + " --device-out " + Path("device.json"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::ifstream in(Path("device.json"));
  const auto d = nlohmann::json::parse(in);
  std::ifstream report_in(Path("report.json"));
  const auto report = nlohmann::json::parse(report_in);
  // The single view holds f = 3.216 mm, so a is that; the lens is the calibration's k1 (Brown on x1 / a).
  EXPECT_NEAR(d["camera"]["a_mm"].get<double>(), 3.216, 1e-9);
  EXPECT_EQ(d["distortion"]["model"], "brown");
  EXPECT_DOUBLE_EQ(d["distortion"]["k"][0].get<double>(), report["dist_coeffs"][0].get<double>());
  EXPECT_EQ(d["calibration"]["covariance"]["parameters"], nlohmann::json::array({"k1"}));
  const double k1_sd = report["stddev"]["k1"].get<double>();
  EXPECT_NEAR(std::sqrt(d["calibration"]["covariance"]["matrix"][0][0].get<double>()), k1_sd, 1e-12 * k1_sd);
  // Another sensor: refused naming the calibration and both sizes; no calibration file, report or device either.
  fs::remove(Path("cal.yaml"));
  fs::remove(Path("report.json"));
  fs::remove(Path("device.json"));
  r = RunTopocal(single + " --device " + std::string(TOPOCAL_SOURCE_DIR) + "/data/device.json --device-out " +
                 Path("device.json"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_EQ(CountLines(r.output), 1) << r.output;
  EXPECT_NE(r.output.find("calibrated at 640 x 480 px but the nominal device's sensor is 4000 x 3000 px"),
            std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(Path("cal.yaml")));
  EXPECT_FALSE(fs::exists(Path("device.json")));
  r = RunTopocal(single + " --device-out " + Path("device.json"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--device and --device-out go together"), std::string::npos) << r.output;
}

// The calibration file's date honours SOURCE_DATE_EPOCH (the reproducible-builds convention), as the unit
// record's does; a malformed value is bad input naming the variable, and nothing is written.
TEST_F(CalibrateCli, SourceDateEpochSetsTheCalibrationDate) {
  const std::string args = "calibrate --target " + Path("board.yaml") + " --images '" + kDataDir +
                           "left01.jpg' --model seidel --single-view --focal-mm 3.216 --pixel-pitch-um 6 "
                           "--distance-mm 400 --out " +
                           Path("cal.yaml");
  ::setenv("SOURCE_DATE_EPOCH", "1764000000", 1);
  const auto r = RunTopocal(args);
  ::setenv("SOURCE_DATE_EPOCH", "17640000x0", 1);
  const auto bad = RunTopocal(args + ".bad");
  ::unsetenv("SOURCE_DATE_EPOCH");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::ifstream in(Path("cal.yaml"));
  const std::string yaml((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(yaml.find("calibration_date: \"2025-11-24T16:00:00Z\""), std::string::npos) << yaml.substr(0, 300);
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_NE(bad.output.find("SOURCE_DATE_EPOCH '17640000x0': not a non-negative integer"), std::string::npos)
      << bad.output;
  EXPECT_EQ(CountLines(bad.output), 1) << bad.output;
  EXPECT_FALSE(fs::exists(Path("cal.yaml.bad")));
}

// --- The robust fit's and the Seidel conversion's options (a test for every option). ---

TEST_F(CalibrateCli, LossScaleAndOutlierThresholdReachTheRobustFit) {
  CopyImages({1, 2, 3, 4, 5, 6});
  const auto fit = [&](const std::string& name, const std::string& extra) {
    const auto r = RunTopocal("calibrate --target " + Path("board.yaml") + " --images '" + Path("left*.jpg") +
                              "' --out " + Path(name + ".yaml") + " --json " + Path(name + ".json") + " " + extra);
    EXPECT_EQ(r.exit_code, 0) << extra << ": " << r.output;
    return nlohmann::json::parse(std::ifstream(Path(name + ".json")));
  };
  const auto fx = [](const nlohmann::json& j) { return j["camera_matrix"][0][0].get<double>(); };
  const auto plain = fit("plain", "");
  // A Huber scale of 1000 px is quadratic for every residual here and a 1000-sigma threshold rejects nothing: the
  // least-squares fit exactly.
  const auto wide = fit("wide", "--robust --loss huber --loss-scale-px 1000 --outlier-threshold 1000");
  EXPECT_EQ(wide["outliers"].size(), 0u);
  EXPECT_NEAR(fx(wide), fx(plain), 1e-9);
  // Measured 2026-12-02 on these six photographs: 1 outlier at the default 4 sigmas, 92 at 2 sigmas.
  const auto four = fit("four", "--robust");
  const auto two = fit("two", "--robust --outlier-threshold 2");
  EXPECT_GT(two["outliers"].size(), 10 * four["outliers"].size());
  EXPECT_LT(two["rms_px"].get<double>(), four["rms_px"].get<double>());
  // Cauchy and Huber at a 0.1 px scale weigh the residuals differently: fx 534.96 against 534.66 px (measured).
  const auto huber = fit("huber", "--robust --loss huber --loss-scale-px 0.1");
  const auto cauchy = fit("cauchy", "--robust --loss cauchy --loss-scale-px 0.1");
  EXPECT_GT(std::abs(fx(cauchy) - fx(huber)), 0.05);
  EXPECT_GT(std::abs(fx(huber) - fx(four)), 0.05);  // the scale itself matters: 0.1 px against 1 px
  const auto bad = RunTopocal("calibrate --target " + Path("board.yaml") + " --images '" + Path("left*.jpg") +
                              "' --robust --loss tukey --out " + Path("bad.yaml"));
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.output.find("--loss: 'tukey' is not huber or cauchy"), std::string::npos) << bad.output;
  EXPECT_FALSE(fs::exists(Path("bad.yaml")));
}

TEST_F(CalibrateCli, MagnificationScalesTheSeidelSigmaByItsCube) {
  // sigma = k1 M_T^3 / f^2 (paper Eq. 18): the same image and k1, M_T doubled, sigma eight times as large.
  const auto fit = [&](const std::string& name, const std::string& magnification) {
    const auto r = RunTopocal("calibrate --target " + Path("board.yaml") + " --images '" + kDataDir +
                              "left01.jpg' --model seidel --single-view --focal-mm 3.216 --pixel-pitch-um 6 "
                              "--distance-mm 400 --magnification " +
                              magnification + " --out " + Path(name + ".yaml") + " --json " + Path(name + ".json"));
    EXPECT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("M_T = " + magnification), std::string::npos) << r.output;
    return nlohmann::json::parse(std::ifstream(Path(name + ".json")))["seidel"];
  };
  const auto paper = fit("paper", "-0.065");
  const auto doubled = fit("doubled", "-0.13");
  EXPECT_EQ(doubled["magnification"].get<double>(), -0.13);
  EXPECT_NEAR(doubled["sigma_per_mm2"].get<double>() / paper["sigma_per_mm2"].get<double>(), 8.0, 1e-9);
  EXPECT_NEAR(doubled["sigma_stddev_per_mm2"].get<double>() / paper["sigma_stddev_per_mm2"].get<double>(), 8.0, 1e-6);
}

}  // namespace
