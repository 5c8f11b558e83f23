// The command line for correct/: render-spots and undistort, end to end through their files; exit codes and
// one-line messages for bad input, and no output file when the input is bad.
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <tuple>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "tests/cli_harness.h"
#include "tests/device_file.h"
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "correct/detect_and_index.h"
#include "model/opencv_view.h"
#include "correct/undistort_map.h"
#include "model/device.h"
#include "model/spots_csv.h"
#include "synthetic.h"

namespace topocal::correct {
namespace {

namespace fs = std::filesystem;

// Spots written with fmt's shortest round-trip representation come back exactly; the undistortion's own
// convergence tolerance is 1e-12 mm.
constexpr double kCsvRoundTripMm = 1e-11;
// Matching a detection to its truth: far below the ~16 px spot spacing.
constexpr double kMatchPx = 1.0;

using topocal::testing_cli::Run;
using topocal::testing_cli::RunTopocal;

class CorrectCli : public topocal::testing_cli::TempDirTest {
 protected:
  void SetUp() override {
    TempDirTest::SetUp();
    // A 1000 x 1000 crop of the default camera: the whole pattern, a fraction of the rendering time.
    auto cam = testing::DefaultCamera();
    cam.width_px = 1000;
    cam.height_px = 1000;
    cam.principal_point_px = {499.5, 499.5};
    camera_ = cam;
    Write("cam.json", testing_cli::NominalDeviceText(cam));
  }
  // A plain OpenCV calibration file for the crop camera.
  void WriteCalibration(const std::string& name, const model::CameraModel& k, int width, int height) const {
    cv::FileStorage fs(Path(name), cv::FileStorage::WRITE);
    fs << "image_width" << width << "image_height" << height;
    fs << "camera_matrix" << cv::Mat(cv::Matx33d(k.fx_px, 0, k.cx_px, 0, k.fy_px, k.cy_px, 0, 0, 1));
    fs << "distortion_coefficients" << cv::Mat(cv::Mat(std::vector<double>(k.dist.begin(), k.dist.end())).t());
  }
  // An 11 x 11 grid of undistorted points 0.09 mm apart (the truth), written distorted by `distortion` as the spots
  // CSV `name` (ring 1, index = the point's place in the truth).
  std::vector<Eigen::Vector2d> WriteDistortedGrid(const std::string& name, const model::Distortion& distortion) const {
    std::vector<Eigen::Vector2d> truth;
    std::string csv = "ring,index,x_mm,y_mm\n";
    for (double x = -0.45; x <= 0.45; x += 0.09) {
      for (double y = -0.45; y <= 0.45; y += 0.09) {
        truth.emplace_back(x, y);
        const Eigen::Vector2d d = model::Distort(distortion, truth.back());
        csv += fmt::format("1,{},{},{}\n", truth.size() - 1, d.x(), d.y());
      }
    }
    Write(name, csv);
    return truth;
  }
  model::CameraModel Lens() const {
    const double f = camera_.FocalPx();
    return {.fx_px = f,
            .fy_px = f,
            .cx_px = camera_.principal_point_px.x() + 4.0,
            .cy_px = camera_.principal_point_px.y() - 3.0,
            .dist = {-0.15, 0.3, 6e-4, -4e-4, 0.0}};
  }
  model::TopographerCamera camera_;
};

TEST_F(CorrectCli, RenderSpotsWritesAnImageThatDetectsBackToItsTruth) {
  const auto r = RunTopocal("render-spots --config " + paper_ + " --device " + Path("cam.json") +
                            " --sigma 2e-4 --drop 0.1 --glints 4 --seed 5 --out " + Path("s.png") + " --truth " +
                            Path("t.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const cv::Mat img = cv::imread(Path("s.png"), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(img.type(), CV_16UC1);
  ASSERT_EQ(img.cols, 1000);
  std::ifstream in(Path("t.csv"));
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "ring,index,x_px,y_px,x_mm,y_mm");
  struct Row {
    model::SpotId id;
    Eigen::Vector2d px, mm;
  };
  std::vector<Row> rows;
  while (std::getline(in, line)) {
    std::replace(line.begin(), line.end(), ',', ' ');
    std::istringstream ls(line);
    Row row;
    ls >> row.id.ring >> row.id.index >> row.px.x() >> row.px.y() >> row.mm.x() >> row.mm.y();
    rows.push_back(row);
  }
  const int glints = static_cast<int>(std::count_if(rows.begin(), rows.end(), [](const Row& w) { return w.id.ring == 0; }));
  EXPECT_EQ(glints, 4);
  EXPECT_EQ(rows.size() - glints, 624u - 62u);  // 10 % of 624 dropped, rounded
  const auto cfg = testing::PaperConfig();
  const auto found = DetectAndIndexSpots(img, camera_, cfg.ideal_image);
  ASSERT_TRUE(found.ok) << found.message;
  EXPECT_EQ(found.spots.size(), rows.size() - glints);
  EXPECT_EQ(found.unassigned.size(), static_cast<size_t>(glints));
  for (const auto& s : found.spots) {
    const auto it = std::find_if(rows.begin(), rows.end(), [&](const Row& w) { return w.id == s.id; });
    ASSERT_NE(it, rows.end());
    EXPECT_LT((it->px - s.position_px).norm(), kMatchPx);
    EXPECT_LT((camera_.DetectionPlaneFromPixel(it->px) - it->mm).norm(), 1e-8);  // the two columns agree
  }
}

TEST_F(CorrectCli, RenderSpotsEightBit) {
  const auto r = RunTopocal("render-spots --config " + paper_ + " --device " + Path("cam.json") +
                            " --sigma 0 --bits 8 --spot psf --psf-px 1.5 --out " + Path("s.png"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(cv::imread(Path("s.png"), cv::IMREAD_UNCHANGED).type(), CV_8UC1);
}

TEST_F(CorrectCli, RenderSpotsBadInputIsOneLineExitTwoNoOutput) {
  const std::string base = "render-spots --config " + paper_ + " --sigma 0 --out " + Path("s.png");
  for (const auto& [args, needle] : std::vector<std::pair<std::string, std::string>>{
           {base + " --device " + Path("missing.json"), "missing.json"},
           {base + " --device " + Path("cam.json") + " --drop 1.5", "--drop: must be in [0, 1)"},
           {"render-spots --config " + paper_ + " --sigma 0 --device " + Path("cam.json") + " --out " + Path("s.jpg"),
            "must be a .png"},
           {base + " --device " + Path("bad.json"), "bad.json: a_mm: 4 differs from the configuration"}}) {
    SCOPED_TRACE(args);
    Write("bad.json", testing_cli::NominalDeviceText(R"({"pixel_pitch_um": 1.12, "width_px": 100, "height_px": 100,
                          "principal_point_px": [50, 50], "a_mm": 4})"));
    const auto r = RunTopocal(args);
    EXPECT_EQ(r.exit_code, 2) << r.output;
    EXPECT_NE(r.output.find(needle), std::string::npos) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_FALSE(fs::exists(Path("s.png")));
  }
}

TEST_F(CorrectCli, UndistortSpotsInvertsTheCalibratedLens) {
  const auto k = Lens();
  WriteCalibration("cal.yaml", k, camera_.width_px, camera_.height_px);
  const auto brown = LensFromOpenCv(k, camera_);
  ASSERT_TRUE(brown.ok) << brown.message;
  const auto truth = WriteDistortedGrid("in.csv", brown.lens);
  const auto r = RunTopocal("undistort --calibration " + Path("cal.yaml") + " --device " + Path("cam.json") +
                            " --spots " + Path("in.csv") + " --out " + Path("out.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::ifstream in(Path("out.csv"));
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "ring,index,x_mm,y_mm");
  size_t n = 0;
  while (std::getline(in, line)) {
    std::replace(line.begin(), line.end(), ',', ' ');
    std::istringstream ls(line);
    int ring = 0, index = 0;
    Eigen::Vector2d p;
    ls >> ring >> index >> p.x() >> p.y();
    ASSERT_LT(static_cast<size_t>(index), truth.size());
    EXPECT_LT((p - truth[index]).norm(), kCsvRoundTripMm);
    ++n;
  }
  EXPECT_EQ(n, truth.size());
}

TEST_F(CorrectCli, UndistortImageMatchesTheLibrary) {
  const auto k = Lens();
  WriteCalibration("cal.yaml", k, camera_.width_px, camera_.height_px);
  cv::Mat img(camera_.height_px, camera_.width_px, CV_8UC1);
  cv::randu(img, 0, 255);
  cv::imwrite(Path("in.png"), img);
  const auto r = RunTopocal("undistort --calibration " + Path("cal.yaml") + " --image " + Path("in.png") + " --out " +
                            Path("out.png") + " --device " + Path("cam.json"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const cv::Mat out = cv::imread(Path("out.png"), cv::IMREAD_UNCHANGED);
  const auto expected = UndistortImage(img, BuildUndistortMap(LensFromOpenCv(k, camera_).lens, camera_));
  ASSERT_EQ(out.size(), expected.size());
  EXPECT_EQ(cv::norm(out, expected, cv::NORM_INF), 0.0);
  // Without --device the calibration's own geometry is used: the same image in pixels.
  const auto r2 = RunTopocal("undistort --calibration " + Path("cal.yaml") + " --image " + Path("in.png") + " --out " +
                             Path("out2.png"));
  ASSERT_EQ(r2.exit_code, 0) << r2.output;
  EXPECT_LE(cv::norm(cv::imread(Path("out2.png"), cv::IMREAD_UNCHANGED), expected, cv::NORM_INF), 1.0);
}

// A device file corrects as a calibration does: its camera maps the pixels, its distortion (Seidel about an off-axis
// centre here) is inverted to the CSV's round trip, an image matches the library's remap, and a strong barrel's
// spots beyond its fold are refused by name.
TEST_F(CorrectCli, UndistortWithADeviceInvertsItsDistortion) {
  model::Device device = model::NominalDevice(camera_);
  device.distortion = model::SeidelParams{6.3e-5, -0.065, 0.01, -0.02};
  Write("device.json", model::DeviceToJson(device));
  const auto truth = WriteDistortedGrid("in.csv", device.distortion);
  auto r = RunTopocal("undistort --device " + Path("device.json") + " --spots " + Path("in.csv") + " --out " +
                      Path("out.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto rows = model::ReadSpotsCsv(Path("out.csv"));
  ASSERT_EQ(rows.size(), truth.size());
  for (const auto& row : rows) {
    EXPECT_LT((row.position_mm - truth[row.id.index]).norm(), kCsvRoundTripMm);
  }
  cv::Mat img(camera_.height_px, camera_.width_px, CV_8UC1);
  cv::randu(img, 0, 255);
  cv::imwrite(Path("in.png"), img);
  r = RunTopocal("undistort --device " + Path("device.json") + " --image " + Path("in.png") + " --out " + Path("out.png"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto expected = UndistortImage(img, BuildUndistortMap(device.distortion, camera_));
  EXPECT_EQ(cv::norm(cv::imread(Path("out.png"), cv::IMREAD_UNCHANGED), expected, cv::NORM_INF), 0.0);
  // sigma 3e-4 mm^-2 folds 0.55 mm from the centre (its image 0.37 mm): the outer spots have no unique preimage.
  device.distortion = model::SeidelParams{3e-4, -0.065, 0.0, 0.0};
  Write("barrel.json", model::DeviceToJson(device));
  r = RunTopocal("undistort --device " + Path("barrel.json") + " --spots " + Path("in.csv") + " --out " +
                 Path("barrel.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("beyond the fold"), std::string::npos) << r.output;
  const auto kept = model::ReadSpotsCsv(Path("barrel.csv"));
  EXPECT_LT(kept.size(), truth.size());
  EXPECT_GT(kept.size(), truth.size() / 4);
  // What is kept is the preimage inside the fold: distorted again, it lands on its input spot.
  const auto input = model::ReadSpotsCsv(Path("in.csv"));
  for (const auto& row : kept) {
    const Eigen::Vector2d back = model::Distort(device.distortion, row.position_mm);
    const auto& in_row = input[row.id.index];
    EXPECT_LT((back - in_row.position_mm).norm(), kCsvRoundTripMm);
    EXPECT_LT(row.position_mm.norm(), std::sqrt(-std::pow(-0.065, 3) / (3 * 3e-4)));
  }
}

TEST_F(CorrectCli, UndistortBadInputIsOneLineExitTwoNoOutput) {
  WriteCalibration("cal.yaml", Lens(), camera_.width_px, camera_.height_px);
  WriteCalibration("small.yaml", Lens(), 640, 480);
  Write("device.json", model::DeviceToJson(model::NominalDevice(camera_)));
  Write("in.csv", "ring,index,x_mm,y_mm\n1,0,0.1,0.1\n");
  const std::string cal = " --calibration " + Path("cal.yaml");
  for (const auto& [args, needle] : std::vector<std::pair<std::string, std::string>>{
           {"undistort" + cal + " --spots " + Path("in.csv") + " --image x.png --out " + Path("o.csv"),
            "exactly one of --spots or --image"},
           {"undistort --calibration " + Path("none.yaml") + " --spots " + Path("in.csv") + " --out " + Path("o.csv"),
            "none.yaml"},
           {"undistort" + cal + " --spots " + Path("in.csv") + " --out " + Path("o.csv"), "give --device"},
           {"undistort --calibration " + Path("small.yaml") + " --device " + Path("cam.json") + " --spots " +
                Path("in.csv") + " --out " + Path("o.csv"),
            "is for 640 x 480 px"},
           // A calibration (with a device for its camera) or a device.
           {"undistort --spots " + Path("in.csv") + " --out " + Path("o.csv"),
            "give --calibration (with --device for its camera) or --device"}}) {
    SCOPED_TRACE(args);
    const auto r = RunTopocal(args);
    EXPECT_EQ(r.exit_code, 2) << r.output;
    EXPECT_NE(r.output.find(needle), std::string::npos) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_FALSE(fs::exists(Path("o.csv")));
  }
}

// A capture with an upper and a lower lid (their skin drawn) is measured over what is visible, with its capture-
// quality line (2 glints, no blob from the skin); a lid
// that hides the sim-K zone above the centre is refused: exit 4, the reasons, the JSON marked invalid without a
// clinical number, no maps.
TEST_F(CorrectCli, ALidIsMeasuredOverWhatIsVisibleAndOneHidingTheSimKZoneIsRefused) {
  const std::string cfg = std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json";
  auto r = RunTopocal(fmt::format("render-spots --config {} --device {} --sigma 0 --upper-lid 0.25 --lower-lid 0.1 "
                                  "--lid-skin 8000 --glints 2 --out {}",
                                  cfg, Path("cam.json"), Path("lid.png")));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = RunTopocal(fmt::format("reconstruct --config {} --image {} --device {} --truth --json {}", cfg, Path("lid.png"),
                             Path("cam.json"), Path("lid.json")));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("at the image's top (upper lid?)"), std::string::npos) << r.output;
  auto j = nlohmann::json::parse(std::ifstream(Path("lid.json")));
  EXPECT_TRUE(j["valid"].get<bool>());
  const int identified = j["capture"]["identified"];
  EXPECT_GT(identified, 350) << r.output;  // ~60 % of 624 visible below and above the lids
  EXPECT_LT(identified, 500);
  EXPECT_LE(j["capture"]["unidentified_blobs"].get<int>(), 4);
  // The paper cornea (rx 8.35, kx -0.43) over what the lids leave: the issue's clean-image limits 0.005 mm and 0.005,
  // and regression bounds near today's errors (rx +0.00034, ry +0.00024 mm; kx +0.00010, ky -0.00086).
  const auto& fit = j["surface_fit"];
  for (const auto& [key, truth, limit, bound] : {std::tuple{"rx_mm", 8.35, 0.005, 0.001}, std::tuple{"ry_mm", 7.63, 0.005, 0.001},
                                                 std::tuple{"kx", -0.43, 0.005, 0.002}, std::tuple{"ky", -0.25, 0.005, 0.002}}) {
    EXPECT_NEAR(fit[key].get<double>(), truth, limit) << key;
    EXPECT_NEAR(fit[key].get<double>(), truth, bound) << key;
  }
  EXPECT_TRUE(j.contains("clinical"));

  r = RunTopocal(fmt::format("render-spots --config {} --device {} --sigma 0 --upper-lid 0.45 --out {}", cfg,
                             Path("cam.json"), Path("lid60.png")));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = RunTopocal(fmt::format("reconstruct --config {} --image {} --device {} --json {} --maps {}", cfg,
                             Path("lid60.png"), Path("cam.json"), Path("lid60.json"), Path("maps60")));
  EXPECT_EQ(r.exit_code, 4) << r.output;
  EXPECT_NE(r.output.find("measurement REFUSED"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("sim-K"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("clinical (data to"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(Path("maps60")));
  j = nlohmann::json::parse(std::ifstream(Path("lid60.json")));
  EXPECT_FALSE(j["valid"].get<bool>());
  EXPECT_FALSE(j["refused"].empty());
  EXPECT_FALSE(j.contains("clinical"));
  EXPECT_FALSE(j.contains("surface_fit"));

  // A lid over the pattern's centre: no identity can be anchored; refused at identification, the JSON says so.
  r = RunTopocal(fmt::format("render-spots --config {} --device {} --sigma 0 --upper-lid 0.7 --out {}", cfg,
                             Path("cam.json"), Path("lid70.png")));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = RunTopocal(fmt::format("reconstruct --config {} --image {} --device {} --json {}", cfg, Path("lid70.png"),
                             Path("cam.json"), Path("lid70.json")));
  EXPECT_EQ(r.exit_code, 4) << r.output;
  EXPECT_NE(r.output.find("measurement refused: spot identification"), std::string::npos) << r.output;
  j = nlohmann::json::parse(std::ifstream(Path("lid70.json")));
  EXPECT_FALSE(j["valid"].get<bool>());
  EXPECT_FALSE(j.contains("clinical"));
  r = RunTopocal(fmt::format("detect --image {} --device {} --config {} --out {}", Path("lid70.png"),
                             Path("cam.json"), cfg, Path("lid70.csv")));
  EXPECT_EQ(r.exit_code, 4) << r.output;
  EXPECT_FALSE(fs::exists(Path("lid70.csv")));
}


// Item 3 of the capture issue: a smaller sensor of the same size (the phone's 6 and 3 MP modes: 1.6 and 2.24 um
// pixels, spots 14 and 10 px apart, 3 px of background between the elliptical spot images at 3 MP; a binned video
// frame at 3.8 um with point-like spots, PSF 1.2 px, 6 px apart) measures every spot — neighbours share the gap between them rather than being left out — and the paper cornea comes back within
// the issue's clean-image limits (|dr| <= 0.005 mm, |dk| <= 0.005). Regression bounds near today's errors (2026-12-03, 2.24 um: rx +0.0001 mm, ry -0.0003 mm,
// kx +0.0001, ky -0.0003; 1.6 um: below 0.00004 everywhere; 3.8 um: rx -0.0001 mm, ry -0.0003 mm, kx -0.0001,
// ky -0.0002).
TEST_F(CorrectCli, SmallerPixelsMeasureEverySpot) {
  const std::string cfg = std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json";
  for (const double pitch_um : {1.6, 2.24, 3.8}) {
    SCOPED_TRACE(fmt::format("{} um", pitch_um));
    auto cam = testing::DefaultCamera();  // the same sensor area, larger pixels; a crop holding the pattern
    cam.pixel_pitch_um = pitch_um;
    cam.width_px = cam.height_px = static_cast<int>(std::ceil(1000 * 1.12 / pitch_um));
    cam.principal_point_px = Eigen::Vector2d::Constant(0.5 * (cam.width_px - 1));
    Write("small.json", testing_cli::NominalDeviceText(cam));
    const std::string spot = pitch_um > 3 ? "--spot psf --psf-px 1.2" : "";
    auto r = RunTopocal(fmt::format("render-spots --config {} --device {} --sigma 0 {} --out {}", cfg,
                                    Path("small.json"), spot, Path("small.png")));
    ASSERT_EQ(r.exit_code, 0) << r.output;
    r = RunTopocal(fmt::format("reconstruct --config {} --image {} --device {} --json {}", cfg, Path("small.png"),
                               Path("small.json"), Path("small-fit.json")));
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const auto j = nlohmann::json::parse(std::ifstream(Path("small-fit.json")));
    EXPECT_EQ(j["capture"]["usable"].get<int>(), 624) << r.output;
    const auto& fit = j["surface_fit"];
    for (const auto& [key, truth] : {std::pair{"rx_mm", 8.35}, std::pair{"ry_mm", 7.63}, std::pair{"kx", -0.43},
                                     std::pair{"ky", -0.25}}) {
      EXPECT_NEAR(fit[key].get<double>(), truth, 0.005) << key;
      EXPECT_NEAR(fit[key].get<double>(), truth, 0.001) << key;
    }
  }
}


// A clinical capture from the command line (capture issue, item 5): an upper lid with its skin, 4 lash shadows, an
// iris behind the pattern, defocus growing from 1.5 to 3 px, motion blur of 1.5 px, two dry patches of tear film and
// two glints. `reconstruct` measures it within twice the clean-image limits (0.01 mm, 0.01), with the spots the
// reconstructed surface rejected (centres a lash pulled) counted on the capture-quality line and in the JSON.
// Measured 2026-12-03: 513 of 518 visible spots identified, 16 rejected by the surface; rx +0.0008 mm, ry +0.0008 mm,
// kx +0.0007, ky +0.0009 (regression bound 0.002).
TEST_F(CorrectCli, AClinicalCaptureIsMeasuredWithWhatTheSurfaceRejectedCounted) {
  const std::string cfg = std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json";
  auto r = RunTopocal(fmt::format(
      "render-spots --config {} --device {} --sigma 0 --upper-lid 0.2 --lid-skin 8000 --lashes 4 --iris 2500 "
      "--psf-px 1.5 --defocus-rim-px 3 --motion-blur-px 1.5 --motion-blur-deg 30 --tear-film 2 --glints 2 --seed 5 "
      "--out {}",
      cfg, Path("cam.json"), Path("clinical.png")));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = RunTopocal(fmt::format("reconstruct --config {} --image {} --device {} --json {}", cfg, Path("clinical.png"),
                             Path("cam.json"), Path("clinical.json")));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("spots rejected by the reconstructed surface"), std::string::npos) << r.output;
  const auto j = nlohmann::json::parse(std::ifstream(Path("clinical.json")));
  EXPECT_GE(j["capture"]["identified"].get<int>(), 466);  // >= 90 % of the 518 visible
  EXPECT_GE(j["capture"]["surface_outliers"].get<int>(), 1);
  const auto& fit = j["surface_fit"];
  for (const auto& [key, truth] : {std::pair{"rx_mm", 8.35}, std::pair{"ry_mm", 7.63}, std::pair{"kx", -0.43},
                                   std::pair{"ky", -0.25}}) {
    EXPECT_NEAR(fit[key].get<double>(), truth, 0.01) << key;
    EXPECT_NEAR(fit[key].get<double>(), truth, 0.002) << key;
  }
}

}  // namespace
}  // namespace topocal::correct
