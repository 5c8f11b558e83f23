// The device workflow on the command line: render reference balls through an as-built device, calibrate
// the device from them, measure a cornea through it; the refusals of bad input and the flag of a model that does not
// describe the images.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <regex>
#include <nlohmann/json.hpp>

#include "tests/cli_harness.h"

namespace {

namespace fs = std::filesystem;
using topocal::testing_cli::RunTopocal;

// A small sensor (1120 x 1120 px: the spots span about +-400 px) keeps the renders fast.
nlohmann::json UnitDevice(double radial_scale = 1.0) {
  auto d = nlohmann::json::parse(R"({
    "format": "topocal-device", "format_version": 1,
    "camera": {"pixel_pitch_um": 1.12, "width_px": 1120, "height_px": 1120, "principal_point_px": [567.9, 552.3],
               "a_mm": 5.23, "orientation": "identity"},
    "distortion": {"model": "seidel", "sigma_per_mm2": 6.3e-5},
    "screen_pose": {"rx_deg": 0.6, "ry_deg": -0.4, "rz_deg": 0.3, "tx_mm": 0.08, "ty_mm": -0.05, "tz_mm": 0.3}})");
  d["screen_pose"]["radial_scale"] = radial_scale;
  return d;
}

class DeviceCli : public topocal::testing_cli::TempDirTest {
 protected:
  void SetUp() override {
    TempDirTest::SetUp();
    nominal_ = Path("nominal.json");
    std::ofstream(nominal_) << nlohmann::json::parse(R"({
      "format": "topocal-device", "format_version": 1,
      "camera": {"pixel_pitch_um": 1.12, "width_px": 1120, "height_px": 1120, "principal_point_px": [559.5, 559.5],
                 "a_mm": 5.2}})").dump(2);
  }

  // Writes the device and renders three balls (6.5, 7.8, 9.0 mm) placed by hand through it. The first, the datum,
  // sits at the working position (vertex z = 0: where the eye will be), laterally off like the others.
  void RenderBalls(const nlohmann::json& device) {
    std::ofstream(Path("unit.json")) << device.dump(2);
    const char* balls[][4] = {{"6.5", "0.12", "-0.20", "0.00"}, {"7.8", "-0.25", "0.10", "-0.15"},
                              {"9.0", "0.20", "0.22", "0.10"}};
    for (const auto& b : balls) {
      const auto r = RunTopocal(fmt("render-spots --config {} --device {} --sphere-radius-mm {} --ball-at {} {} {} "
                                    "--seed 3 --out {}",
                                    paper_, Path("unit.json"), b[0], b[1], b[2], b[3], Path(std::string("b") + b[0] + ".png")));
      ASSERT_EQ(r.exit_code, 0) << r.output;
    }
  }
  std::string Balls() const {
    return "--balls " + Path("b6.5.png") + " " + Path("b7.8.png") + " " + Path("b9.0.png") + " --radii-mm 6.5 7.8 9.0";
  }
  template <typename... Args>
  static std::string fmt(const std::string& pattern, const Args&... args) {
    std::string out = pattern;
    for (const std::string& a : {std::string(args)...}) {
      const auto at = out.find("{}");
      out.replace(at, 2, a);
    }
    return out;
  }

  std::string nominal_;
};

// What the three balls recover of the demo unit (truth: rx 0.6, ry -0.4 deg, principal point (567.9, 552.3) px,
// sigma 6.3e-5). The renders' spots are detected to ~0.003 px, far better than the 0.04 px design noise, so the fit
// is far better than the issue's acceptance (tilt 0.01 deg, pp 1e-4 mm = 0.09 px, sigma 2e-7); the bounds are
// regression bounds near the errors measured on 2026-12-01: tilt 1.9e-4 deg, pp 0.001 px, sigma 1.1e-9.
constexpr double kTiltTolDeg = 0.002;
constexpr double kPrincipalTolPx = 0.01;
constexpr double kSigmaTol = 1e-8;
// The paper cornea measured through the calibrated device against the truth; acceptance |dk| 0.001,
// |dr| 0.001 mm; measured |dk| 2.1e-5, |dr| 3.0e-5 mm.
constexpr double kConicTol = 2e-4;
constexpr double kRadiusTolMm = 3e-4;

TEST_F(DeviceCli, CalibratesTheDeviceFromBallsAndMeasuresThroughIt) {
  RenderBalls(UnitDevice());
  const auto r = RunTopocal("device calibrate --config " + paper_ + " --device " + nominal_ + " " + Balls() +
                            " --out " + Path("calibrated.json"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("gauge: axial gauge"), std::string::npos) << r.output;
  const auto device = nlohmann::json::parse(std::ifstream(Path("calibrated.json")));
  EXPECT_NEAR(device["screen_pose"]["rx_deg"].get<double>(), 0.6, kTiltTolDeg);
  EXPECT_NEAR(device["screen_pose"]["ry_deg"].get<double>(), -0.4, kTiltTolDeg);
  EXPECT_NEAR(device["camera"]["principal_point_px"][0].get<double>(), 567.9, kPrincipalTolPx);
  EXPECT_NEAR(device["camera"]["principal_point_px"][1].get<double>(), 552.3, kPrincipalTolPx);
  EXPECT_NEAR(device["distortion"]["sigma_per_mm2"].get<double>(), 6.3e-5, kSigmaTol);
  const auto& cal = device["calibration"];
  EXPECT_TRUE(cal["model_adequate"].get<bool>());
  EXPECT_GT(cal["parameters"]["rx_deg"]["stddev"].get<double>(), 0.0);
  EXPECT_EQ(cal["balls"].size(), 3u);
  EXPECT_EQ(cal["balls"][0]["sha256"].get<std::string>().size(), 64u);

  // A cornea through the unit, measured through the calibrated device.
  const auto cornea = RunTopocal("render-spots --config " + paper_ + " --device " + Path("unit.json") + " --out " +
                                 Path("cornea.png"));
  ASSERT_EQ(cornea.exit_code, 0) << cornea.output;
  const auto m = RunTopocal("reconstruct --config " + paper_ + " --image " + Path("cornea.png") + " --device " +
                            Path("calibrated.json") + " --json " + Path("cornea.json"));
  ASSERT_EQ(m.exit_code, 0) << m.output;
  const auto j = nlohmann::json::parse(std::ifstream(Path("cornea.json")));
  const auto& p = j["surface_fit"];
  EXPECT_NEAR(p["kx"].get<double>(), -0.43, kConicTol) << m.output;
  EXPECT_NEAR(p["ky"].get<double>(), -0.25, kConicTol) << m.output;
  EXPECT_NEAR(p["rx_mm"].get<double>(), 8.35, kRadiusTolMm) << m.output;
  EXPECT_NEAR(p["ry_mm"].get<double>(), 7.63, kRadiusTolMm) << m.output;
  EXPECT_EQ(j["image"]["indexed"].get<int>(), 624);

  // Every number carries its U (k = 2): the device's covariance, the image's spot noise. The truth lies
  // within it, the output never prints "+- 0.0000", and the axial map has its U map beside it.
  const auto& u = j["uncertainty"];
  EXPECT_EQ(u["coverage_factor"].get<int>(), 2);
  EXPECT_TRUE(u["device_covariance"].get<bool>());
  EXPECT_EQ(u["device_directions"].get<int>(), 10);
  EXPECT_EQ(u["method"].get<std::string>(), "device: linear; spots: Monte Carlo");
  const std::pair<const char*, double> truth[] = {
      {"surface_fit.rx_mm", 8.35}, {"surface_fit.ry_mm", 7.63}, {"surface_fit.kx", -0.43}, {"surface_fit.ky", -0.25}};
  for (const auto& [name, value] : truth) {
    const auto& q = u["quantities"][name];
    EXPECT_GT(q["expanded"].get<double>(), 0.0) << name;
    EXPECT_LE(std::abs(q["value"].get<double>() - value), q["expanded"].get<double>()) << name;
  }
  EXPECT_GT(u["quantities"]["clinical.kmax.power_D"]["expanded"].get<double>(), 0.0);
  EXPECT_NE(m.output.find("uncertainties below are U (k = 2) from: the device's covariance"), std::string::npos)
      << m.output;
  EXPECT_FALSE(std::regex_search(m.output, std::regex(R"(\+- 0\.?0*( |$))"))) << m.output;
  // A value the data do not determine (a peak's location with a twin within U) is null in the JSON, not a number
  // (the paper cornea's elevation above its best-fit sphere peaks alike on both ends of a meridian).
  int undetermined = 0;
  for (const auto& [name, q] : u["quantities"].items()) {
    if (q["determined"].get<bool>()) continue;
    ++undetermined;
    std::string pointer = "/" + name;
    std::replace(pointer.begin(), pointer.end(), '.', '/');
    EXPECT_TRUE(j.at(nlohmann::json::json_pointer(pointer)).is_null()) << name;
    EXPECT_TRUE(q["expanded"].is_null()) << name;
  }
  EXPECT_GT(undetermined, 0) << u.dump();
  // The device's part by Monte Carlo (a cross-check of the linear propagation) and the U map.
  const auto mc = RunTopocal("reconstruct --config " + paper_ + " --image " + Path("cornea.png") + " --device " +
                             Path("calibrated.json") + " --uncertainty 30 --seed 5 --json " + Path("mc.json") +
                             " --maps " + Path("maps"));
  ASSERT_EQ(mc.exit_code, 0) << mc.output;
  const auto jm = nlohmann::json::parse(std::ifstream(Path("mc.json")));
  EXPECT_EQ(jm["uncertainty"]["method"].get<std::string>(), "device: Monte Carlo; spots: Monte Carlo");
  EXPECT_EQ(jm["uncertainty"]["device_analyses"].get<int>(), 30);
  EXPECT_TRUE(fs::exists(Path("maps/axial_uncertainty.png")));
  EXPECT_TRUE(fs::exists(Path("maps/axial_uncertainty.csv")));
  // A hand-written device has no covariance: said so, not taken as zero.
  const auto plain = RunTopocal("reconstruct --config " + paper_ + " --image " + Path("cornea.png") + " --device " +
                                Path("unit.json"));
  ASSERT_EQ(plain.exit_code, 0) << plain.output;
  EXPECT_NE(plain.output.find("NOT the device (its file has no calibration covariance"), std::string::npos)
      << plain.output;
}

TEST_F(DeviceCli, SimulateThroughTheNominalDeviceIsThePapersImage) {
  const auto device = std::string(TOPOCAL_SOURCE_DIR) + "/data/device.json";
  ASSERT_EQ(RunTopocal("simulate --config " + paper_ + " --sigma 0 --out " + Path("paper.csv")).exit_code, 0);
  const auto r = RunTopocal("simulate --config " + paper_ + " --device " + device + " --out " + Path("device.csv"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto read = [](const std::string& path) { return std::string(std::istreambuf_iterator<char>(std::ifstream(path).rdbuf()), {}); };
  EXPECT_EQ(read(Path("device.csv")), read(Path("paper.csv")));
  // A ball placed off the axis images through the device; --ball-at alone, or with --sigma, is refused.
  const auto ball = RunTopocal("simulate --config " + paper_ + " --device " + device +
                               " --sphere-radius-mm 6.5 --ball-at 0.2 -0.1 0.3 --out " + Path("ball.csv"));
  ASSERT_EQ(ball.exit_code, 0) << ball.output;
  EXPECT_NE(read(Path("ball.csv")), read(Path("paper.csv")));
  EXPECT_EQ(RunTopocal("simulate --config " + paper_ + " --device " + device + " --ball-at 0 0 0 --out " + Path("x.csv")).exit_code, 2);
  EXPECT_EQ(RunTopocal("simulate --config " + paper_ + " --sigma 0 --sphere-radius-mm 7 --out " + Path("x.csv")).exit_code, 2);
  EXPECT_FALSE(fs::exists(Path("x.csv")));
}

TEST_F(DeviceCli, FlagsAScreenTheModelDoesNotDescribe) {
  // The cone's print 1 % too large: with the radial scale held, chi2/dof says the model does not fit (exit 3, the
  // file written and flagged); fitting the scale recovers it.
  RenderBalls(UnitDevice(1.01));
  const auto held = RunTopocal("device calibrate --config " + paper_ + " --device " + nominal_ + " " + Balls() +
                               " --out " + Path("held.json"));
  EXPECT_EQ(held.exit_code, 3) << held.output;
  EXPECT_NE(held.output.find("does not describe these images"), std::string::npos) << held.output;
  EXPECT_FALSE(nlohmann::json::parse(std::ifstream(Path("held.json")))["calibration"]["model_adequate"].get<bool>());
  const auto fitted = RunTopocal("device calibrate --config " + paper_ + " --device " + nominal_ + " " + Balls() +
                                 " --fit-radial-scale --out " + Path("fitted.json"));
  ASSERT_EQ(fitted.exit_code, 0) << fitted.output;
  const auto device = nlohmann::json::parse(std::ifstream(Path("fitted.json")));
  // measured 1.00999 +- 6e-5 (2026-12-01)
  EXPECT_NEAR(device["screen_pose"]["radial_scale"].get<double>(), 1.01, 3e-4);
}

// Target views join the fit (--target, --targets): two views of a 13 x 13 board of 0.9 mm squares at the cornea
// position, rendered through the same camera (the unit's a, principal point and sigma as render-target takes them).
// Their corners are fitted with the balls: each view's RMS is the corners' noise (measured 0.039 px), and the device
// comes back within the issue's bounds. A view without the target, or a description without views, is refused.
TEST_F(DeviceCli, TargetViewsJoinTheFit) {
  RenderBalls(UnitDevice());
  std::ofstream(Path("board.yaml")) << "target_type: checkerboard\ntargetCols: 13\ntargetRows: 13\n"
                                       "rowSpacingMeters: 0.0009\ncolSpacingMeters: 0.0009\n";
  for (const std::string tilt : {"0", "15"}) {
    const auto r = RunTopocal(fmt("render-target --target {} --width 1120 --height 1120 --focal-mm 5.23 "
                                  "--pixel-pitch-um 1.12 --cx 567.9 --cy 552.3 --sigma 6.3e-5 --distance-mm 70 "
                                  "--tilt-x-deg {} --supersampling 4 --noise 1 --out {}",
                                  Path("board.yaml"), tilt, Path("view-" + tilt + ".png")));
    ASSERT_EQ(r.exit_code, 0) << r.output;
  }
  const std::string base = "device calibrate --config " + paper_ + " --device " + nominal_ + " " + Balls();
  const auto r = RunTopocal(base + " --target " + Path("board.yaml") + " --targets '" + Path("view-*.png") +
                            "' --corner-sigma-px 0.05 --out " + Path("joint.json"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("2 target views"), std::string::npos) << r.output;
  const auto device = nlohmann::json::parse(std::ifstream(Path("joint.json")));
  const auto& views = device["calibration"]["target_views"];
  ASSERT_EQ(views.size(), 2u);
  for (const auto& v : views) {
    EXPECT_EQ(v["corners"].get<int>(), 169);
    EXPECT_LT(v["rms_px"].get<double>(), 0.1);
  }
  EXPECT_EQ(device["calibration"]["corner_sigma_px"].get<double>(), 0.05);
  // Acceptance: the issue's (tilt 0.01 deg, principal point 1e-4 mm = 0.09 px, sigma 2e-7); regression bounds near
  // the errors measured: tilt 4.5e-4 and 1.3e-3 deg, principal point 0.025 and 0.009 px, sigma 9.8e-9 (the corners'
  // 0.04 px noise now weighs in beside the spots' 0.003 px).
  for (const auto& [key, truth] : {std::pair{"rx_deg", 0.6}, std::pair{"ry_deg", -0.4}}) {
    EXPECT_NEAR(device["screen_pose"][key].get<double>(), truth, 0.01) << key;
    EXPECT_NEAR(device["screen_pose"][key].get<double>(), truth, 0.003) << key;
  }
  for (const auto& [i, truth] : {std::pair{size_t{0}, 567.9}, std::pair{size_t{1}, 552.3}}) {
    EXPECT_NEAR(device["camera"]["principal_point_px"][i].get<double>(), truth, 0.09) << i;
    EXPECT_NEAR(device["camera"]["principal_point_px"][i].get<double>(), truth, 0.05) << i;
  }
  EXPECT_NEAR(device["distortion"]["sigma_per_mm2"].get<double>(), 6.3e-5, 2e-7);
  EXPECT_NEAR(device["distortion"]["sigma_per_mm2"].get<double>(), 6.3e-5, 3e-8);

  auto bad = RunTopocal(base + " --target " + Path("board.yaml") + " --out " + Path("x.json"));
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_NE(bad.output.find("--target and --targets go together"), std::string::npos) << bad.output;
  bad = RunTopocal(base + " --target " + Path("board.yaml") + " --targets " + Path("b7.8.png") + " --out " +
                   Path("x.json"));
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_NE(bad.output.find("b7.8.png: no target found (target description"), std::string::npos) << bad.output;
  EXPECT_FALSE(fs::exists(Path("x.json")));
}

// Known stage steps as the axial gauge (--ball-steps-mm): the three balls sit 0.3 mm behind, 0.7 mm in front of and
// 1.3 mm behind the working position, 1 mm apart on the stage. The datum (ball 1 at z = 0) is then wrong by 0.3 mm,
// and a and tz follow it along the gauge (measured: a 5.2089 mm for 5.23, 64 of its standard deviations). The steps
// measure the distance instead: ball 1 at z = 0.3015 +- 0.025 mm, tz 0.3016 +- 0.025 mm, a 5.230094 +- 0.0018 mm
// (the datum on the same images: a 5.208926 +- 0.00033 mm).
TEST_F(DeviceCli, BallStepsAreTheAlternativeAxialGauge) {
  std::ofstream(Path("unit.json")) << UnitDevice().dump(2);
  const char* balls[][4] = {{"6.5", "0.12", "-0.20", "0.30"}, {"7.8", "-0.25", "0.10", "-0.70"},
                            {"9.0", "0.20", "0.22", "1.30"}};
  for (const auto& b : balls) {
    const auto r = RunTopocal(fmt("render-spots --config {} --device {} --sphere-radius-mm {} --ball-at {} {} {} "
                                  "--seed 3 --out {}",
                                  paper_, Path("unit.json"), b[0], b[1], b[2], b[3],
                                  Path(std::string("b") + b[0] + ".png")));
    ASSERT_EQ(r.exit_code, 0) << r.output;
  }
  const std::string base = "device calibrate --config " + paper_ + " --device " + nominal_ + " " + Balls();
  const auto steps = RunTopocal(base + " --ball-steps-mm 0 -1 1 --out " + Path("steps.json"));
  ASSERT_EQ(steps.exit_code, 0) << steps.output;
  EXPECT_NE(steps.output.find("fixed by the balls' known stage steps"), std::string::npos) << steps.output;
  const auto datum = RunTopocal(base + " --out " + Path("datum.json"));
  ASSERT_EQ(datum.exit_code, 0) << datum.output;
  const auto s = nlohmann::json::parse(std::ifstream(Path("steps.json")));
  const auto d = nlohmann::json::parse(std::ifstream(Path("datum.json")));
  const auto& sp = s["calibration"]["parameters"];
  // Within 3 standard deviations (acceptance), and regression bounds near the errors measured.
  EXPECT_LT(std::abs(sp["a_mm"]["value"].get<double>() - 5.23), 3 * sp["a_mm"]["stddev"].get<double>());
  EXPECT_LT(std::abs(sp["tz_mm"]["value"].get<double>() - 0.3), 3 * sp["tz_mm"]["stddev"].get<double>());
  EXPECT_NEAR(sp["a_mm"]["value"].get<double>(), 5.23, 2e-4);  // measured 9.4e-5
  EXPECT_NEAR(sp["tz_mm"]["value"].get<double>(), 0.3, 0.004);  // measured 1.6e-3
  const auto& first = s["calibration"]["balls"][0];
  EXPECT_NEAR(first["vertex_mm"][2].get<double>(), 0.3, 3 * first["vertex_stddev_mm"][2].get<double>());
  EXPECT_NEAR(s["calibration"]["balls"][1]["vertex_mm"][2].get<double>() - first["vertex_mm"][2].get<double>(), -1.0,
              1e-12);
  // The datum's a is off by many of its standard deviations.
  const auto& dp = d["calibration"]["parameters"];
  EXPECT_GT(std::abs(dp["a_mm"]["value"].get<double>() - 5.23), 10 * dp["a_mm"]["stddev"].get<double>());

  auto bad = RunTopocal(base + " --ball-steps-mm 0 1 --out " + Path("x.json"));
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_NE(bad.output.find("--ball-steps-mm: 2 steps for 3 ball images"), std::string::npos) << bad.output;
  bad = RunTopocal(base + " --ball-steps-mm 0 -1 1 --datum 2 --out " + Path("x.json"));
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_FALSE(fs::exists(Path("x.json")));
}

TEST_F(DeviceCli, RefusesBadInputWithOneLineAndNoOutput) {
  RenderBalls(UnitDevice());
  const auto out = Path("out.json");
  const auto run = [&](const std::string& args) { return RunTopocal("device calibrate --config " + paper_ + " " + args + " --out " + out); };
  auto r = run("--device " + nominal_ + " --balls " + Path("b6.5.png") + " " + Path("b7.8.png") + " --radii-mm 6.5");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("--radii-mm: 1 radii for 2 ball images"), std::string::npos) << r.output;
  r = run("--device " + nominal_ + " --balls " + Path("missing.png") + " --radii-mm 7.8");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("missing.png"), std::string::npos) << r.output;
  r = run("--device " + nominal_ + " " + Balls() + " --datum 4");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("--datum: must name one of the 3 balls"), std::string::npos) << r.output;
  r = run("--device " + nominal_ + " --balls " + Path("b6.5.png") + " --radii-mm 0.5");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("is not a reference-ball radius"), std::string::npos) << r.output;
  // The same capture twice (a copy under another name): no new information, yet it shrank the reported sd by sqrt 2.
  fs::copy_file(Path("b7.8.png"), Path("copy.png"));
  r = run("--device " + nominal_ + " --balls " + Path("b6.5.png") + " " + Path("b7.8.png") + " " +
          Path("copy.png") + " --radii-mm 6.5 7.8 7.8");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("copy.png: the same image as"), std::string::npos) << r.output;
  std::ofstream(Path("bad-device.json")) << R"({"format": "topocal-device", "format_version": 1, "camera": {"pixel_pitch_um": 1.12, "width_px": 1120, "height_px": 1120, "principal_point_px": [559.5, 559.5], "a_mm": 5.2}, "screen_pose": {"tilt_deg": 1}})";
  r = run("--device " + Path("bad-device.json") + " " + Balls());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("bad-device.json: screen_pose.tilt_deg: unknown key"), std::string::npos) << r.output;
  // An image without spots: nothing to index (a computation that cannot be done: exit 1).
  const auto blank = RunTopocal("render-spots --config " + paper_ + " --device " + Path("unit.json") +
                                " --drop 0.99 --seed 1 --out " + Path("blank.png"));
  ASSERT_EQ(blank.exit_code, 0) << blank.output;
  r = run("--device " + nominal_ + " --balls " + Path("blank.png") + " --radii-mm 7.8");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("blank.png"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out));
  // Every failure above was one line.
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
}

// The priors' tolerances, the spot noise and the chi2 limit (a test for every option). Measured 2026-12-02
// on these renders: with every tolerance at 1e-6 each parameter stays within 5e-5 of the nominal (rx 4.4e-5 deg,
// principal point 0.42 px, a 7.7e-4 mm: the nominal's 559.5 px and 5.2 mm) at chi2/dof 12857; by default they come
// to the truth (0.6 deg, 567.9 px, 5.23 mm) at chi2/dof 0.0017; a 10x larger spot noise gives 10x the standard
// deviations and ~1/100 of chi2/dof.
TEST_F(DeviceCli, PriorTolerancesSpotNoiseAndTheChi2LimitDoWhatTheySay) {
  RenderBalls(UnitDevice());
  const auto calibrate = [&](const std::string& name, const std::string& extra, int exit_code) {
    const auto r = RunTopocal("device calibrate --config " + paper_ + " --device " + nominal_ + " " + Balls() +
                              " --quiet --out " + Path(name) + " " + extra);
    EXPECT_EQ(r.exit_code, exit_code) << extra << ": " << r.output;
    return nlohmann::json::parse(std::ifstream(Path(name)))["calibration"];
  };
  const std::string tight =
      "--tol-tilt-deg 1e-6 --tol-roll-deg 1e-6 --tol-lateral-mm 1e-6 --tol-axial-mm 1e-6 "
      "--tol-principal-point-mm 1e-6 --tol-a-relative 1e-6";
  const auto free_fit = calibrate("free.json", "", 0);
  const auto held = calibrate("held.json", tight + " --max-chi2-per-dof 1e12", 0);
  const auto value = [](const nlohmann::json& c, const char* p) { return c["parameters"][p]["value"].get<double>(); };
  const auto stddev = [](const nlohmann::json& c, const char* p) { return c["parameters"][p]["stddev"].get<double>(); };
  // Each prior holds its parameters at the nominal device, where the free fit moves them to the truth.
  for (const char* p : {"rx_deg", "ry_deg"}) EXPECT_LT(std::abs(value(held, p)), 1e-3) << p;  // --tol-tilt-deg
  EXPECT_LT(std::abs(value(held, "rz_deg")), 1e-3);                                           // --tol-roll-deg
  for (const char* p : {"tx_mm", "ty_mm"}) EXPECT_LT(std::abs(value(held, p)), 1e-3) << p;    // --tol-lateral-mm
  EXPECT_LT(std::abs(value(held, "tz_mm")), 1e-3);                                            // --tol-axial-mm
  EXPECT_NEAR(value(held, "principal_point_u_px"), 559.5, 1.0);  // --tol-principal-point-mm
  EXPECT_NEAR(value(held, "a_mm"), 5.2, 0.002);                  // --tol-a-relative
  EXPECT_NEAR(value(free_fit, "rx_deg"), 0.6, 0.002);
  EXPECT_NEAR(value(free_fit, "rz_deg"), 0.3, 0.002);
  EXPECT_NEAR(value(free_fit, "tz_mm"), 0.3, 0.01);
  EXPECT_NEAR(value(free_fit, "principal_point_u_px"), 567.9, 0.01);
  EXPECT_NEAR(value(free_fit, "a_mm"), 5.23, 0.002);
  // --max-chi2-per-dof: the held model does not describe the images; 1e12 lets it pass, the default 4 flags it.
  EXPECT_GT(held["chi2_per_dof"].get<double>(), 1000.0);
  EXPECT_TRUE(held["model_adequate"].get<bool>());
  const auto flagged = calibrate("flagged.json", tight, 3);
  EXPECT_FALSE(flagged["model_adequate"].get<bool>());
  // --spot-sigma-px: the standard deviations scale with it, chi2/dof with its inverse square.
  const auto noisy = calibrate("noisy.json", "--spot-sigma-px 0.4", 0);
  EXPECT_NEAR(stddev(noisy, "rx_deg") / stddev(free_fit, "rx_deg"), 10.0, 0.5);
  EXPECT_NEAR(stddev(noisy, "a_mm") / stddev(free_fit, "a_mm"), 10.0, 0.5);
  EXPECT_NEAR(free_fit["chi2_per_dof"].get<double>() / noisy["chi2_per_dof"].get<double>(), 100.0, 10.0);
}

}  // namespace
