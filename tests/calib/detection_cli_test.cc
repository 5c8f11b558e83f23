// `topocal target` and `topocal render-target` end to end: outputs, truth, exit codes, one-line messages and no
// partial files for bad input.
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "tests/cli_harness.h"
#include <opencv2/imgcodecs.hpp>

#include "calib/detect.h"
#include "calib/target.h"

namespace {

namespace fs = std::filesystem;

using topocal::testing_cli::Run;
using topocal::testing_cli::RunTopocal;

class DetectionCli : public topocal::testing_cli::TempDirTest {
 protected:
  void SetUp() override {
    TempDirTest::SetUp();
    Write("board.yaml",
          "target_type: checkerboard\ntargetCols: 9\ntargetRows: 6\nrowSpacingMeters: 0.02\ncolSpacingMeters: 0.02\n");
    Write("grid.yaml", "target_type: aprilgrid\ntagCols: 4\ntagRows: 3\ntagSize: 0.03\ntagSpacing: 0.3\n");
  }
};

TEST_F(DetectionCli, TargetWritesSvgAndPng) {
  auto r = RunTopocal("target --target " + Path("grid.yaml") + " --out " + Path("grid.svg"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(Path("grid.svg")));
  r = RunTopocal("target --target " + Path("board.yaml") + " --out " + Path("board.png") + " --dpi 100");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const cv::Mat png = cv::imread(Path("board.png"), cv::IMREAD_GRAYSCALE);
  // 12 x 9 squares of 20 mm (with the one-square border) at 100 dpi.
  EXPECT_EQ(png.cols, static_cast<int>(std::round(240.0 / 25.4 * 100)));
  EXPECT_EQ(png.rows, static_cast<int>(std::round(180.0 / 25.4 * 100)));
}

TEST_F(DetectionCli, RenderTargetWritesImageAndTruthThatDetectionMatches) {
  const auto r = RunTopocal("render-target --target " + Path("board.yaml") + " --out " + Path("v.png") + " --truth " +
                            Path("t.csv") + " --k1 -0.1 --distance-mm 420 --tilt-x-deg 20 --roll-deg 5 --noise 1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::ifstream in(Path("t.csv"));
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "id,x_px,y_px");
  std::vector<Eigen::Vector2d> truth;
  while (std::getline(in, line)) {
    std::istringstream row(line);
    std::string id, x, y;
    std::getline(row, id, ',');
    std::getline(row, x, ',');
    std::getline(row, y, ',');
    EXPECT_EQ(std::stoi(id), static_cast<int>(truth.size()));
    truth.emplace_back(std::stod(x), std::stod(y));
  }
  ASSERT_EQ(truth.size(), 54u);
  const auto target = topocal::calib::LoadTargetDescription(Path("board.yaml"));
  const auto view = topocal::calib::DetectTargetInFile(target, Path("v.png"));
  ASSERT_TRUE(view.has_value());
  // The corner bar (0.02 px RMS) holds per corner to within a few times; 0.1 px proves the files agree.
  constexpr double kAgreementPx = 0.1;
  for (const auto& c : view->corners) EXPECT_LT((c.image_px - truth[static_cast<size_t>(c.id)]).norm(), kAgreementPx);
}

TEST_F(DetectionCli, SeidelCameraAndExplicitPose) {
  const auto r = RunTopocal("render-target --target " + Path("grid.yaml") + " --out " + Path("s.png") +
                            " --width 320 --height 240 --supersampling 4 --focal-mm 5.2 --pixel-pitch-um 10 --sigma 2e-4" +
                            " --rvec-deg 10,0,0 --tvec-mm -80,-50,700");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(Path("s.png")));
}

TEST_F(DetectionCli, CameraFromAnOpenCvCalibrationFile) {
  Write("cal.yaml",
        "%YAML:1.0\n---\nimage_width: 320\nimage_height: 240\n"
        "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"
        "   data: [ 300., 0., 160., 0., 300., 120., 0., 0., 1. ]\n"
        "distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n"
        "   data: [ -0.1, 0.01, 0., 0., 0. ]\n");
  auto r = RunTopocal("render-target --target " + Path("grid.yaml") + " --camera " + Path("cal.yaml") + " --out " +
                      Path("c.png") + " --distance-mm 600 --supersampling 4");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const cv::Mat image = cv::imread(Path("c.png"), cv::IMREAD_GRAYSCALE);
  EXPECT_EQ(image.cols, 320);
  EXPECT_EQ(image.rows, 240);
  r = RunTopocal("render-target --target " + Path("grid.yaml") + " --camera " + Path("cal.yaml") + " --fx 3 --out " +
                 Path("d.png") + " --distance-mm 600");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.output, "topocal: --fx: not allowed with --camera\n");
}

TEST_F(DetectionCli, BadInputIsOneLineAndNoOutput) {
  Write("bad.yaml", "target_type: checkerboard\ntargetCols: 9\n");
  auto r = RunTopocal("target --target " + Path("bad.yaml") + " --out " + Path("x.svg"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.output, "topocal: " + Path("bad.yaml") + ": targetRows: missing\n");
  EXPECT_FALSE(fs::exists(Path("x.svg")));
  r = RunTopocal("target --target " + Path("board.yaml") + " --out " + Path("x.jpg"));
  EXPECT_EQ(r.exit_code, 2);
  r = RunTopocal("render-target --target " + Path("board.yaml") + " --out " + Path("x.png"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("--distance-mm"), std::string::npos) << r.output;
  r = RunTopocal("render-target --target " + Path("board.yaml") + " --out " + Path("x.png") +
                 " --distance-mm 400 --sigma 1e-4");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("--sigma"), std::string::npos) << r.output;
  r = RunTopocal("render-target --target " + Path("board.yaml") + " --out " + Path("x.png") +
                 " --distance-mm 400 --noise -1");
  EXPECT_EQ(r.exit_code, 2);
  r = RunTopocal("render-target --target " + Path("board.yaml") + " --out " + Path("x.png") +
                 " --distance-mm 400 --camera " + Path("missing.yaml"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_FALSE(fs::exists(Path("x.png")));
}

}  // namespace
