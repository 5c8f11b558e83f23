// `topocal calibrate` end to end on OpenCV's real chessboard photographs: outputs, skipped images, and failures
// that leave no output file.
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "tests/cli_harness.h"
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

namespace {

namespace fs = std::filesystem;

const std::string kDataDir = "/usr/share/doc/opencv-doc/examples/data/";

using topocal::testing_cli::Run;
using topocal::testing_cli::RunTopocal;

int CountLines(const std::string& s) { return static_cast<int>(std::count(s.begin(), s.end(), '\n')); }

class CalibrateCli : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!fs::exists(kDataDir + "left01.jpg")) GTEST_SKIP() << "opencv-doc's left*.jpg are not installed";
    dir_ = fs::temp_directory_path() / ("topocal_calcli_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
    // OpenCV's board: 9 x 6 inner corners; the square size is not known, 25 mm is as good as any.
    Write("board.yaml",
          "target_type: checkerboard\ntargetCols: 9\ntargetRows: 6\nrowSpacingMeters: 0.025\ncolSpacingMeters: "
          "0.025\n");
  }
  void TearDown() override {
    if (!dir_.empty()) fs::remove_all(dir_);
  }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  void Write(const std::string& name, const std::string& text) const { std::ofstream(Path(name)) << text; }
  void CopyImages(const std::vector<int>& numbers) const {
    for (int i : numbers) {
      const std::string name = (i < 10 ? "left0" : "left") + std::to_string(i) + ".jpg";
      fs::copy_file(kDataDir + name, Path(name));
    }
  }
  fs::path dir_;
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
  EXPECT_TRUE(j.contains("seidel"));
  EXPECT_TRUE(j["outliers"].is_array());
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
  // The same photograph three times: one target orientation, which cannot determine the intrinsics.
  for (const char* name : {"a.jpg", "b.jpg", "c.jpg"}) fs::copy_file(kDataDir + "left03.jpg", Path(name));
  const auto r = RunTopocal("calibrate --target " + Path("board.yaml") + " --images '" + Path("*.jpg") + "' --out " +
                            Path("cal.yaml") + " --json " + Path("report.json"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(CountLines(r.output), 1) << r.output;
  EXPECT_NE(r.output.find("degenerate"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(Path("cal.yaml")));
  EXPECT_FALSE(fs::exists(Path("report.json")));
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
  EXPECT_EQ(r.output, "topocal: --model: 'tps' is not seidel or brown5\n");
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
  EXPECT_TRUE(j.contains("target_distance_mm"));
}

}  // namespace
