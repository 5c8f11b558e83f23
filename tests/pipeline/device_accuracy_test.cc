// Ten seeded devices drawn within the assembly tolerances, three reference balls (6.5, 7.8,
// 9.0 mm) placed at random (+-0.3 mm), spot noise 0.04 px. The device fit must recover the tilt, the principal point
// and sigma, report honest uncertainties, and the paper cornea measured through each calibrated device must agree
// with the nominal device's result — while the lens-only workflow (sigma right, geometry nominal) does not.
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "model/config.h"
#include "model/device.h"
#include "pipeline/device_calibration.h"
#include "pipeline/measure_spots.h"
#include "pipeline/uncertainty.h"
#include "topo/biconic_fit.h"
#include "tests/pipeline/device_fixtures.h"
#include "topo/power_map.h"

namespace topocal::pipeline {
namespace {

using testing::DrawDevice;
using testing::NominalDevice;
using testing::PaperConfig;

constexpr int kDevices = 10;
constexpr double kSpotNoisePx = 0.04;
constexpr double kBallRadiiMm[] = {6.5, 7.8, 9.0};
constexpr double kBallPlacementMm = 0.3;

// Acceptance and regression bounds near the values measured on 2026-12-01 (in the comments).
constexpr double kTiltRmsAcceptDeg = 0.01, kTiltRmsRegressionDeg = 0.005;                    // measured 0.0028
constexpr double kPrincipalRmsAcceptMm = 1e-4;                                                // measured 7.4e-5
constexpr double kSigmaRmsAccept = 2e-7, kSigmaRmsRegression = 1e-7;                          // measured 5.2e-8
constexpr double kConicAccept = 0.001, kConicRegression = 6e-4;                               // measured 3.7e-4
constexpr double kRadiusAcceptMm = 0.001, kRadiusRegressionMm = 7e-4;                         // measured 3.9e-4
constexpr double kPowerPvAcceptD = 0.02, kPowerPvRegressionD = 0.015;                         // measured 0.0097
constexpr double kCentralPowerAcceptD = 0.005, kCentralPowerRegressionD = 0.0025;             // measured 0.0014
// Honest uncertainty (docs/device.md, "Is the uncertainty honest?"): the pulls (estimate - truth) / reported
// standard deviation of 80 parameters must look like standard normal draws: their RMS within [0.7, 1.3] (the
// sampling spread of an RMS of 80 unit normals is ~0.08) and none beyond 4 (P = 0.5 % for 80 draws). "Each within
// 3" would fail one run in five with perfect uncertainties. Measured: pull RMS 0.88, largest 2.39.
constexpr double kPullRmsLow = 0.7, kPullRmsHigh = 1.3, kMaxPull = 4.0;




// Exact spots of the paper cornea through a device, as the camera records them (pixels), with optional noise.
// The cornea's vertex sits at `vertex_z_mm`: the working position the datum ball defined.
std::vector<std::pair<model::SpotId, Eigen::Vector2d>> CorneaPixels(const model::Device& device,
                                                                     const model::Config& config,
                                                                     double vertex_z_mm = 0.0) {
  const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
  auto cornea = config.cornea;
  cornea.z0_mm = vertex_z_mm;
  const auto image = model::SynthesizeImage(model::Biconic{cornea}, device, config.topographer, design.targets);
  std::vector<std::pair<model::SpotId, Eigen::Vector2d>> out;
  for (const auto& s : image.spots) out.emplace_back(s.id, device.PixelOf(s.position_mm));
  return out;
}

struct Clinical {
  double rx, ry, kx, ky, pv_tangential, pv_axial, central_power;
};

// Measure recorded pixels through a device (its camera, its distortion undone, its screen and a).
Clinical MeasureThrough(const model::Device& device, const model::Config& config,
                        const std::vector<std::pair<model::SpotId, Eigen::Vector2d>>& pixels) {
  std::vector<model::PlaneSpot> spots;
  for (const auto& [id, px] : pixels) {
    const auto mm = device.UndistortedOf(px);
    if (mm) spots.push_back({id, *mm});
  }
  const auto a = AnalyzeThroughDevice(spots, device, config, nullptr);
  // The biconic fit frees the apex (position and tilt; topo/biconic_fit.h): a residual rotation of the calibrated
  // device about the pinhole — the direction the balls determine least (docs/device.md) — shows as an apparent
  // decentration of the eye, which the eye's own fixation gives anyway; the 6-parameter fit would turn it into shape.
  EXPECT_TRUE(a.surface_fit.ok) << a.surface_fit.message;
  const auto& p = a.surface_fit.params;
  return {p.rx_mm, p.ry_mm, p.kx, p.ky, a.power.pv_tangential_D, a.power.pv_axial_D,
          topo::MeanAxialPowerD(a.power, kCentralPowerRadiusMm)};
}

TEST(DeviceCalibration, TenSeededDevicesFromThreeBalls) {
  const auto config = PaperConfig();
  const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
  const auto nominal = NominalDevice();
  const Clinical reference = MeasureThrough(nominal, config, CorneaPixels(nominal, config));

  std::mt19937 rng(20261201);
  std::normal_distribution<double> noise(0.0, kSpotNoisePx);
  std::uniform_real_distribution<double> place(-kBallPlacementMm, kBallPlacementMm);
  double tilt2 = 0, pp2 = 0, sigma2 = 0, pp_var_reported = 0;
  double worst_pull = 0, pull2 = 0;
  int pulls = 0;
  double worst_k = 0, worst_r = 0, worst_pv = 0, worst_central = 0;
  double worst_lens_only_k = 0, worst_lens_only_pv = 0;
  for (int n = 0; n < kDevices; ++n) {
    SCOPED_TRACE(::testing::Message() << "device " << n);
    const auto truth = DrawDevice(rng);
    // Every ball placed by hand, the datum (the first) too: its unknown z offset is the axial gauge. The same
    // spots with the datum ball moved to z = 0 put the fitted device in the truth's own frame, where its
    // parameters can be compared with the truth's one by one (the honesty check below).
    std::vector<calib::BallView> views, views_in_truth_frame;
    double datum_z_mm = 0;
    for (const double radius : kBallRadiiMm) {
      const Eigen::Vector3d vertex(place(rng), place(rng), place(rng));
      const bool datum = views.empty();
      if (datum) datum_z_mm = vertex.z();
      for (const bool in_truth_frame : {false, true}) {
        const Eigen::Vector3d at = (datum && in_truth_frame) ? Eigen::Vector3d(vertex.x(), vertex.y(), 0.0) : vertex;
        const auto ball = SimulateBall(truth, config, radius, at);
        ASSERT_EQ(ball.spots_px.size(), 624u);
        calib::BallView v{"ball " + std::to_string(radius), radius, ball.spots_px};
        std::mt19937 spot_rng(static_cast<unsigned>(1000 * n + radius));  // the same noise in both frames
        for (auto& s : v.spots_px) s.second += Eigen::Vector2d(noise(spot_rng), noise(spot_rng));
        (in_truth_frame ? views_in_truth_frame : views).push_back(v);
      }
    }
    calib::DeviceFitOptions options;
    options.spot_sigma_px = kSpotNoisePx;
    const auto fit = calib::FitDevice(nominal, config.topographer, design.targets, views, options);
    ASSERT_TRUE(fit.ok) << fit.message;
    EXPECT_TRUE(fit.model_adequate) << fit.message;
    const auto& got = fit.device;
    const double pitch = truth.camera.PitchMm();
    tilt2 += std::pow(got.screen.rx_deg - truth.screen.rx_deg, 2) + std::pow(got.screen.ry_deg - truth.screen.ry_deg, 2);
    pp2 += (got.camera.principal_point_px - truth.camera.principal_point_px).squaredNorm() * pitch * pitch;
    const double sigma_true = std::get<model::SeidelParams>(truth.distortion).sigma_per_mm2;
    sigma2 += std::pow(std::get<model::SeidelParams>(got.distortion).sigma_per_mm2 - sigma_true, 2);
    // Honest uncertainty, in the truth's frame: every parameter against its truth in reported standard deviations.
    const auto framed = calib::FitDevice(nominal, config.topographer, design.targets, views_in_truth_frame, options);
    ASSERT_TRUE(framed.ok) << framed.message;
    const std::pair<const char*, double> truths[] = {
        {"rx_deg", truth.screen.rx_deg},
        {"ry_deg", truth.screen.ry_deg},
        {"rz_deg", truth.screen.rz_deg},
        {"tx_mm", truth.screen.tx_mm},
        {"ty_mm", truth.screen.ty_mm},
        {"tz_mm", truth.screen.tz_mm},
        {"principal_point_u_px", truth.camera.principal_point_px.x()},
        {"principal_point_v_px", truth.camera.principal_point_px.y()},
        {"a_mm", truth.camera.a_mm},
        {"sigma_per_mm2", sigma_true}};
    for (const auto& [name, value] : truths) {
      const auto p = framed.Parameter(name);
      ASSERT_TRUE(p) << name;
      ASSERT_GT(p->stddev, 0.0) << name;
      const double pull = std::abs(p->value - value) / p->stddev;
      worst_pull = std::max(worst_pull, pull);
      pull2 += pull * pull;
      ++pulls;
      EXPECT_LE(pull, kMaxPull) << name << " " << p->value << " +- " << p->stddev << " truth " << value;
    }
    for (const char* name : {"principal_point_u_px", "principal_point_v_px"}) {
      pp_var_reported += std::pow(framed.Parameter(name)->stddev * pitch, 2);
    }

    // The paper cornea, imaged exactly by the true device at the working position (the datum ball's vertex: the
    // device calibration's z = 0), measured through the calibrated device.
    const auto pixels = CorneaPixels(truth, config, datum_z_mm);
    const Clinical calibrated = MeasureThrough(got, config, pixels);
    worst_k = std::max({worst_k, std::abs(calibrated.kx - reference.kx), std::abs(calibrated.ky - reference.ky)});
    worst_r = std::max({worst_r, std::abs(calibrated.rx - reference.rx), std::abs(calibrated.ry - reference.ry)});
    worst_pv = std::max({worst_pv, std::abs(calibrated.pv_axial - reference.pv_axial),
                         std::abs(calibrated.pv_tangential - reference.pv_tangential)});
    worst_central = std::max(worst_central, std::abs(calibrated.central_power - reference.central_power));
    // The lens-only workflow: the true sigma, everything else nominal.
    model::Device lens_only = nominal;
    lens_only.distortion = truth.distortion;
    const Clinical lens = MeasureThrough(lens_only, config, pixels);
    worst_lens_only_k = std::max({worst_lens_only_k, std::abs(lens.kx - reference.kx), std::abs(lens.ky - reference.ky)});
    worst_lens_only_pv = std::max(worst_lens_only_pv, std::abs(lens.pv_axial - reference.pv_axial));
  }
  const double tilt_rms = std::sqrt(tilt2 / (2 * kDevices));
  const double pp_rms = std::sqrt(pp2 / (2 * kDevices));
  const double sigma_rms = std::sqrt(sigma2 / kDevices);
  const double pp_rms_expected = std::sqrt(pp_var_reported / (2 * kDevices));
  const double pull_rms = std::sqrt(pull2 / pulls);
  std::printf("device recovery over %d devices: tilt rms %.3g deg, principal point rms %.3g mm per axis (expected "
              "from the covariance %.3g), sigma rms %.3g; pulls rms %.2f, largest %.2f\n",
              kDevices, tilt_rms, pp_rms, pp_rms_expected, sigma_rms, pull_rms, worst_pull);
  std::printf("paper cornea through the calibrated devices vs nominal: |dk| %.3g, |dr| %.3g mm, pv %.3g D, central "
              "%.3g D; lens-only: |dk| %.3g, axial pv %.3g D\n",
              worst_k, worst_r, worst_pv, worst_central, worst_lens_only_k, worst_lens_only_pv);
  EXPECT_LE(tilt_rms, kTiltRmsAcceptDeg);
  EXPECT_LE(tilt_rms, kTiltRmsRegressionDeg);
  // The principal point is near the limit of what 0.04 px spots allow (a shift of it is a rotation of the camera to
  // first order; docs/device.md): both the observed error and the precision the covariance predicts (measured
  // 8.6e-5 mm) must meet the acceptance.
  EXPECT_LE(pp_rms, kPrincipalRmsAcceptMm);
  EXPECT_LE(pp_rms_expected, kPrincipalRmsAcceptMm);
  EXPECT_LE(sigma_rms, kSigmaRmsAccept);
  EXPECT_LE(sigma_rms, kSigmaRmsRegression);
  EXPECT_GE(pull_rms, kPullRmsLow);
  EXPECT_LE(pull_rms, kPullRmsHigh);
  EXPECT_LE(worst_k, kConicAccept);
  EXPECT_LE(worst_k, kConicRegression);
  EXPECT_LE(worst_r, kRadiusAcceptMm);
  EXPECT_LE(worst_r, kRadiusRegressionMm);
  EXPECT_LE(worst_pv, kPowerPvAcceptD);
  EXPECT_LE(worst_pv, kPowerPvRegressionD);
  EXPECT_LE(worst_central, kCentralPowerAcceptD);
  EXPECT_LE(worst_central, kCentralPowerRegressionD);
  // The lens-only workflow fails on the same devices (an earlier estimate: RMS dk ~0.15, pv up to 13 D; measured
  // here with the free-apex fit: |dk| up to 0.19, axial pv up to 2.7 D).
  EXPECT_GT(worst_lens_only_k, 10 * kConicAccept);
  EXPECT_GT(worst_lens_only_pv, 10 * kPowerPvAcceptD);
}

// The reported standard deviations against the scatter of repeated fits: one device, 40 seeded noise draws.
// The sampling error of a standard deviation from 40 draws is ~11 %; measured ratios 0.90-1.07 (60 draws).
constexpr int kNoiseDraws = 40;
constexpr double kScatterRatioLow = 0.7, kScatterRatioHigh = 1.3;

TEST(DeviceCalibration, ReportedStandardDeviationsMatchTheScatterOfRepeatedFits) {
  const auto config = PaperConfig();
  const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
  const auto nominal = NominalDevice();
  std::mt19937 rng(4);
  const auto truth = DrawDevice(rng);
  std::vector<calib::BallView> clean;
  const Eigen::Vector3d at[] = {{0.1, 0.05, 0.0}, {0.2, -0.1, 0.15}, {-0.2, 0.25, -0.1}};
  for (int i = 0; i < 3; ++i) {
    clean.push_back({"ball", kBallRadiiMm[i], SimulateBall(truth, config, kBallRadiiMm[i], at[i]).spots_px});
  }
  std::normal_distribution<double> noise(0.0, kSpotNoisePx);
  std::vector<Eigen::VectorXd> estimates;
  calib::DeviceFit first;
  for (int k = 0; k < kNoiseDraws; ++k) {
    auto views = clean;
    for (auto& v : views) {
      for (auto& s : v.spots_px) s.second += Eigen::Vector2d(noise(rng), noise(rng));
    }
    const auto fit = calib::FitDevice(nominal, config.topographer, design.targets, views);
    ASSERT_TRUE(fit.ok) << fit.message;
    Eigen::VectorXd v(fit.parameters.size());
    for (size_t j = 0; j < fit.parameters.size(); ++j) v[j] = fit.parameters[j].value;
    estimates.push_back(v);
    if (k == 0) first = fit;
  }
  for (size_t j = 0; j < first.parameters.size(); ++j) {
    double mean = 0, var = 0;
    for (const auto& e : estimates) mean += e[j];
    mean /= kNoiseDraws;
    for (const auto& e : estimates) var += (e[j] - mean) * (e[j] - mean);
    const double ratio = std::sqrt(var / (kNoiseDraws - 1)) / first.parameters[j].stddev;
    EXPECT_GE(ratio, kScatterRatioLow) << first.parameters[j].name;
    EXPECT_LE(ratio, kScatterRatioHigh) << first.parameters[j].name;
  }
}

}  // namespace
}  // namespace topocal::pipeline
