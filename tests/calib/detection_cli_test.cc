// `topocal target` and `topocal render-target` end to end: outputs, truth, exit codes, one-line messages and no
// partial files for bad input.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <utility>

#include "calib/detect.h"
#include "calib/target.h"
#include "tests/cli_harness.h"

namespace {

namespace fs = std::filesystem;

using topocal::testing_cli::Run;
using topocal::testing_cli::RunTopocal;

// The truth file's corners, in id order (the header checked; with every_id, that no id is missing: a whole board in
// the frame).
std::vector<Eigen::Vector2d> ReadTruth(const std::string& path, bool every_id = false) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "id,x_px,y_px");
  std::vector<Eigen::Vector2d> corners;
  while (std::getline(in, line)) {
    std::istringstream row(line);
    std::string id, x, y;
    std::getline(row, id, ',');
    std::getline(row, x, ',');
    std::getline(row, y, ',');
    if (every_id) {
      EXPECT_EQ(std::stoi(id), static_cast<int>(corners.size()));
    }
    corners.emplace_back(std::stod(x), std::stod(y));
  }
  return corners;
}

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
  const auto truth = ReadTruth(Path("t.csv"), /*every_id=*/true);
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
  // The size asked for, and the grid in view: ink and paper both present (default grey levels 30 and 220).
  const cv::Mat image = cv::imread(Path("s.png"), cv::IMREAD_GRAYSCALE);
  ASSERT_EQ(image.cols, 320);
  ASSERT_EQ(image.rows, 240);
  double lo = 0, hi = 0;
  cv::minMaxLoc(image, &lo, &hi);
  EXPECT_LT(lo, 60);
  EXPECT_GT(hi, 190);
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

// --- Every render-target option moves the truth or the image as it says (a test for every option). ---

class RenderTargetOptions : public DetectionCli {
 protected:
  // A fronto-parallel 9 x 6 board 400 mm in front of a 640 x 480 pinhole camera (fx 600 px unless `camera` says
  // otherwise): the truth of `extra`.
  std::vector<Eigen::Vector2d> Truth(const std::string& extra, const std::string& camera = "--fx 600") {
    const std::string name = "t" + std::to_string(runs_++);
    const auto r =
        RunTopocal("render-target --target " + Path("board.yaml") + " --out " + Path(name + ".png") + " --truth " +
                   Path(name + ".csv") + " --supersampling 1 --distance-mm 400 " + camera + " " + extra);
    EXPECT_EQ(r.exit_code, 0) << extra << ": " << r.output;
    auto corners = ReadTruth(Path(name + ".csv"));
    EXPECT_EQ(corners.size(), 54u) << extra;
    return corners;
  }
  int runs_ = 0;
};

// Corners are projected exactly (the renderer's truth is the model, not a detection); the truth file's 9 decimals
// round each coordinate by up to 5e-10 px, and a comparison combines up to ~2.5 such roundings: 3e-9 px.
constexpr double kExactPx = 3e-9;

TEST_F(RenderTargetOptions, FyCxCyAndShiftMoveTheCornersAsAPinholeDoes) {
  const auto base = Truth("");
  const Eigen::Vector2d centre(319.5, 239.5);  // the default principal point, (size - 1) / 2
  const auto fy = Truth("--fy 900");
  const auto pp = Truth("--cx 300 --cy 200");
  // A 10 mm / -5 mm shift across the view at 400 mm: 600 * 10 / 400 = 15 px and -7.5 px.
  const auto shifted = Truth("--shift-x-mm 10 --shift-y-mm -5");
  for (size_t i = 0; i < base.size(); ++i) {
    EXPECT_NEAR(fy[i].x(), base[i].x(), kExactPx);
    EXPECT_NEAR(fy[i].y() - centre.y(), 1.5 * (base[i].y() - centre.y()), kExactPx);
    EXPECT_NEAR(pp[i].x() - base[i].x(), 300 - centre.x(), kExactPx);
    EXPECT_NEAR(pp[i].y() - base[i].y(), 200 - centre.y(), kExactPx);
    EXPECT_NEAR(shifted[i].x() - base[i].x(), 15.0, kExactPx);
    EXPECT_NEAR(shifted[i].y() - base[i].y(), -7.5, kExactPx);
  }
}

TEST_F(RenderTargetOptions, BrownCoefficientsDistortAsOpenCvDefinesThem) {
  const auto base = Truth("");
  const double k1 = -0.1, k2 = 0.05, p1 = 0.001, p2 = -0.002, k3 = 0.01;
  const auto distorted = Truth("--k1 -0.1 --k2 0.05 --p1 0.001 --p2 -0.002 --k3 0.01");
  for (size_t i = 0; i < base.size(); ++i) {
    // OpenCV's model on the normalised undistorted point.
    const double x = (base[i].x() - 319.5) / 600, y = (base[i].y() - 239.5) / 600, r2 = x * x + y * y;
    const double radial = 1 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2;
    const double xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x);
    const double yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y;
    EXPECT_NEAR(distorted[i].x(), 319.5 + 600 * xd, kExactPx) << i;
    EXPECT_NEAR(distorted[i].y(), 239.5 + 600 * yd, kExactPx) << i;
  }
  // Each coefficient on its own moves the corners (none is silently dropped); k3 acts on r^6 (r^2 <= 0.07 here), so
  // it is given 1 to move them by more than 0.01 px.
  for (const char* one : {"--k2 0.05", "--p1 0.001", "--p2 -0.002", "--k3 1"}) {
    const auto moved = Truth(one);
    double largest = 0;
    for (size_t i = 0; i < base.size(); ++i) largest = std::max(largest, (moved[i] - base[i]).norm());
    EXPECT_GT(largest, 0.01) << one;
  }
}

TEST_F(RenderTargetOptions, MagnificationConvertsSigmaToK1) {
  // k1 = sigma f^2 / M_T^3 (paper Eq. 18): sigma 2e-5 mm^-2, f 5.2 mm, M_T -0.1 gives k1 = -0.5408. fx = 520 px.
  const std::string camera = "--focal-mm 5.2 --pixel-pitch-um 10";
  const auto by_sigma = Truth("--sigma 2e-5 --magnification -0.1", camera);
  const auto by_k1 = Truth("--k1 -0.5408", camera);
  const auto default_magnification = Truth("--sigma 2e-5", camera);
  double largest = 0;
  for (size_t i = 0; i < by_k1.size(); ++i) {
    EXPECT_NEAR(by_sigma[i].x(), by_k1[i].x(), 1e-6) << i;  // k1 printed to 4 digits is exact here
    EXPECT_NEAR(by_sigma[i].y(), by_k1[i].y(), 1e-6) << i;
    largest = std::max(largest, (default_magnification[i] - by_k1[i]).norm());
  }
  EXPECT_GT(largest, 1.0);  // M_T -0.065 gives k1 = -1.97: another image
}

TEST_F(RenderTargetOptions, GreyLevelsBlurAndSeedShapeTheImage) {
  // Far away (1500 mm) the board covers the middle of the image; the edges show the background.
  const auto render = [&](const std::string& name, const std::string& extra) {
    const auto r = RunTopocal("render-target --target " + Path("board.yaml") + " --out " + Path(name) +
                              " --fx 600 --distance-mm 1500 " + extra);
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return cv::imread(Path(name), cv::IMREAD_GRAYSCALE);
  };
  const cv::Mat levels = render("levels.png", "--blur-px 0 --black 10 --white 250 --background 77 --supersampling 2");
  ASSERT_FALSE(levels.empty());
  double lo = 0, hi = 0;
  cv::minMaxLoc(levels, &lo, &hi);
  EXPECT_EQ(lo, 10);
  EXPECT_EQ(hi, 250);
  EXPECT_EQ(levels.at<uchar>(0, 0), 77);
  EXPECT_EQ(levels.at<uchar>(levels.rows - 1, levels.cols - 1), 77);

  // Blur (sampled over the sub-samples: 64 of them here): sharp, the squares' insides are pure ink (2240 pixels
  // measured 2026-12-02) with no grey between ink and paper; a 3 px blur leaves no pure ink and greys ~8600 pixels.
  const auto ink_and_grey = [](const cv::Mat& image) {
    const int ink = cv::countNonZero(image == 30);
    const int grey = cv::countNonZero((image > 40) & (image < 210) & ((image < 108) | (image > 112)));
    return std::make_pair(ink, grey);
  };
  const auto [sharp_ink, sharp_grey] = ink_and_grey(render("sharp.png", "--blur-px 0 --supersampling 8"));
  const auto [blurred_ink, blurred_grey] = ink_and_grey(render("blurred.png", "--blur-px 3 --supersampling 8"));
  EXPECT_GT(sharp_ink, 1000);
  EXPECT_EQ(sharp_grey, 0);
  EXPECT_LT(blurred_ink, sharp_ink / 10);
  EXPECT_GT(blurred_grey, 4000);

  // Seed: the same seed gives the same noise, another seed other noise.
  const cv::Mat a = render("a.png", "--noise 5 --seed 3 --supersampling 2");
  const cv::Mat again = render("again.png", "--noise 5 --seed 3 --supersampling 2");
  const cv::Mat b = render("b.png", "--noise 5 --seed 4 --supersampling 2");
  EXPECT_EQ(cv::norm(a, again, cv::NORM_L1), 0.0);
  EXPECT_GT(cv::norm(a, b, cv::NORM_L1) / static_cast<double>(a.total()), 2.0);  // ~5 * 2 / sqrt(pi) per pixel
}

}  // namespace
