// Every number measured through a calibrated device with its U: the device covariance's reader,
// the parameter vocabulary, GUM's rounding, linear propagation against Monte Carlo, and the coverage of U over
// seeded devices and eyes (small: the full table is bench/uncertainty_coverage).
#include <cmath>
#include <random>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "calib/device_fit.h"
#include "model/device.h"
#include "pipeline/device_calibration.h"
#include "pipeline/measurement_uncertainty.h"
#include "pipeline/uncertainty_coverage.h"
#include "tests/pipeline/device_fixtures.h"
#include "util/io.h"

namespace topocal::pipeline {
namespace {

using testing::NominalDevice;
using testing::PaperConfig;

nlohmann::json Calibration(const std::vector<std::string>& names, const nlohmann::json& matrix) {
  return {{"covariance", {{"parameters", names}, {"matrix", matrix}}}};
}

TEST(DeviceCovariance, ReadsTheCalibrationBlockAndRefusesAMalformedOne) {
  EXPECT_FALSE(model::DeviceCovarianceOf(nullptr, "d.json").has_value());  // a hand-written device: none
  const auto c = model::DeviceCovarianceOf(Calibration({"rx_deg", "a_mm"}, {{4e-6, 1e-7}, {1e-7, 1e-8}}), "d.json");
  ASSERT_TRUE(c.has_value());
  EXPECT_EQ(c->names, (std::vector<std::string>{"rx_deg", "a_mm"}));
  EXPECT_DOUBLE_EQ(c->matrix(0, 1), 1e-7);
  const auto refused = [](const nlohmann::json& calibration, const std::string& says) {
    try {
      model::DeviceCovarianceOf(calibration, "d.json");
      ADD_FAILURE() << "accepted: " << calibration.dump();
    } catch (const util::ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
      EXPECT_EQ(std::string(e.what()).rfind("d.json: calibration.covariance", 0), 0u) << e.what();
    }
  };
  refused(nlohmann::json::object(), "missing");
  refused(Calibration({"rx_deg", "lens_mm"}, {{1, 0}, {0, 1}}), "'lens_mm' is not a device parameter");
  refused(Calibration({"rx_deg", "rx_deg"}, {{1, 0}, {0, 1}}), "given twice");
  refused(Calibration({"rx_deg", "a_mm"}, {{1, 0}}), "must be 2 rows");
  refused(Calibration({"rx_deg", "a_mm"}, {{1, 0.5}, {0.4, 1}}), "not symmetric");
  refused(Calibration({"rx_deg", "a_mm"}, {{-1, 0}, {0, 1}}), "cannot be negative");
  refused(Calibration({"rx_deg", "a_mm"}, {{1, "x"}, {0, 1}}), "finite number");
}

TEST(DeviceCovariance, ParametersShiftByName) {
  model::Device d = NominalDevice();
  model::ShiftDeviceParameter(&d, "principal_point_u_px", 2.5);
  model::ShiftDeviceParameter(&d, "rz_deg", -0.25);
  model::ShiftDeviceParameter(&d, "sigma_per_mm2", 1e-5);
  EXPECT_DOUBLE_EQ(model::DeviceParameterOf(d, "principal_point_u_px"), NominalDevice().camera.principal_point_px.x() + 2.5);
  EXPECT_DOUBLE_EQ(d.screen.rz_deg, -0.25);
  EXPECT_DOUBLE_EQ(std::get<model::SeidelParams>(d.distortion).sigma_per_mm2, 1e-5);
  EXPECT_THROW(model::ShiftDeviceParameter(&d, "k1", 0.1), util::InputError);  // a Seidel device has no k1
  model::Device brown = NominalDevice();
  model::LensParams b;
  b.focal_mm = brown.camera.a_mm;
  brown.distortion = b;
  model::ShiftDeviceParameter(&brown, "a_mm", 0.01);  // one distance: Brown's normalisation moves with a
  EXPECT_DOUBLE_EQ(std::get<model::LensParams>(brown.distortion).focal_mm, brown.camera.a_mm);
  EXPECT_THROW(model::DeviceParameterOf(brown, "sigma_per_mm2"), util::InputError);
}

TEST(MeasurementUncertainty, PrintsAsGumAsks) {
  EXPECT_EQ(FormatWithUncertainty(8.350123, 0.001234), "8.3501 +- 0.0012");
  EXPECT_EQ(FormatWithUncertainty(44.13, 0.0996), "44.13 +- 0.10");  // U rounds up into a third digit: one fewer
  EXPECT_EQ(FormatWithUncertainty(107.0, 0.577), "107.00 +- 0.58");
  EXPECT_EQ(FormatWithUncertainty(62.2, 15.0), "62 +- 15");
  EXPECT_EQ(FormatWithUncertainty(1234.0, 156.0), "1230 +- 160");
  EXPECT_EQ(FormatWithUncertainty(8.35, 0.0, 3), "8.350");  // no U: the value alone, never "+- 0.000"
}

// One device calibrated from three noisy ball images and the paper cornea measured through it.
struct Measured {
  model::Device truth, device;
  model::DeviceCovariance covariance;
  std::vector<model::PlaneSpot> detected;
  topo::Analysis analysis;
  model::Config config = PaperConfig();
};

Measured MeasureThroughACalibratedDevice(std::uint32_t seed) {
  Measured m;
  std::mt19937 rng(seed);
  m.truth = DrawAssembledDevice(NominalDevice(), rng);
  std::normal_distribution<double> noise(0.0, 0.04);
  std::vector<calib::BallView> views;
  const double placed[3][3] = {{0.1, -0.2, 0.0}, {-0.2, 0.1, -0.15}, {0.2, 0.2, 0.1}};
  const double radii[3] = {6.5, 7.8, 9.0};
  for (int b = 0; b < 3; ++b) {
    const auto ball = SimulateBall(m.truth, m.config, radii[b], Eigen::Vector3d(placed[b][0], placed[b][1], placed[b][2]));
    calib::BallView v{"ball", radii[b], {}};
    for (const auto& [id, px] : ball.spots_px) v.spots_px.emplace_back(id, px + Eigen::Vector2d(noise(rng), noise(rng)));
    views.push_back(v);
  }
  const auto design = model::DesignNullScreen(m.config.ideal_image, m.config.topographer);
  const auto fit = calib::FitDevice(NominalDevice(), m.config.topographer, design.targets, views);
  EXPECT_TRUE(fit.ok) << fit.message;
  m.device = fit.device;
  m.covariance = fit.Covariance();
  const auto image = model::SynthesizeImage(model::Biconic{m.config.cornea}, m.truth, m.config.topographer, design.targets);
  for (const auto& s : image.spots) {
    const Eigen::Vector2d px = m.truth.PixelOf(s.position_mm) + Eigen::Vector2d(noise(rng), noise(rng));
    m.detected.push_back({s.id, m.device.camera.DetectionPlaneFromPixel(px)});
  }
  m.analysis = AnalyzeThroughDevice(UndistortSpots(m.detected, m.device.distortion), m.device, m.config, nullptr);
  return m;
}

TEST(MeasurementUncertainty, LinearPropagationAgreesWithMonteCarloAndEveryNumberHasAU) {
  const Measured m = MeasureThroughACalibratedDevice(7);
  UncertaintyOptions linear;
  linear.jobs = 2;
  const auto u = PropagateMeasurementUncertainty(m.detected, m.device, m.covariance, m.config, m.analysis, linear);
  EXPECT_TRUE(u.device_covariance);
  EXPECT_EQ(u.device_directions, 10);
  EXPECT_EQ(u.failed_draws, 0);
  // The noise is 0.04 px = 0.0448 um, the configured 0.045 um: measured from the residual within 10 %.
  EXPECT_NEAR(u.spot_sigma_um / 0.0448, 1.0, 0.10) << u.spot_sigma_um;
  for (const auto& q : u.quantities) {
    if (!q.determined) continue;
    EXPECT_GT(q.expanded, 0) << q.name;  // never "+- 0"
    EXPECT_TRUE(std::isfinite(q.expanded)) << q.name;
  }
  // The symmetric paper cornea's elevation peak has its twin across the apex: its location is not determined.
  ASSERT_NE(u.Find("clinical.best_fit_sphere.elevation_peak_x_mm"), nullptr);
  EXPECT_FALSE(u.Find("clinical.best_fit_sphere.elevation_peak_x_mm")->determined);
  EXPECT_TRUE(u.Find("clinical.best_fit_sphere.elevation_peak_um")->determined);
  // Monte Carlo of the device's covariance (200 draws: a standard deviation to ~5 %) agrees with the linear one.
  UncertaintyOptions mc = linear;
  mc.device_draws = 200;
  const auto v = PropagateMeasurementUncertainty(m.detected, m.device, m.covariance, m.config, m.analysis, mc);
  EXPECT_TRUE(v.device_monte_carlo);
  for (const char* name : {"surface_fit.rx_mm", "surface_fit.kx", "surface_fit.apex_x_mm", "surface_fit.tilt_y_deg",
                           "clinical.sim_k.steep_D", "power.central_axial_D"}) {
    const double a = u.Find(name)->u_device, b = v.Find(name)->u_device;
    // Acceptance: within 25 % (sampling 5 % x 2, plus the device fit's mild non-linearity); regression 10 %.
    // Measured 2026-12-03: Monte Carlo / linear 0.95-1.00 (worst: central axial power 0.954, sim-K 0.951).
    EXPECT_NEAR(b / a, 1.0, 0.25) << name;
    EXPECT_NEAR(b / a, 1.0, 0.10) << name;
  }
}

TEST(MeasurementUncertainty, CoversTheTruthOverSeededDevicesAndEyes) {
  CoverageOptions o;
  o.cases = 40;
  o.seed = 3;
  o.eye_kind = "biconic";  // the eyes the polynomial measures (the spline's smoothing bias: docs/uncertainty.md)
  o.jobs = 2;
  const auto r = RunUncertaintyCoverage(PaperConfig(), NominalDevice(), o);
  EXPECT_EQ(r.failed, 0);
  // The eyes the polynomial measures (biconics, mild irregularity): U (k = 2) covers ~95 % and the pulls have RMS ~1.
  // Acceptance: the 93-97 % and RMS 0.85-1.15, widened for 40 cases x 26 numbers correlated within a case
  // (coverage >= 88 %, RMS 0.75-1.3). Regression bounds near the values measured on 2026-12-03 (seed 3): coverage
  // 95.1 %, RMS 0.95; the device parameters' pulls RMS 0.96. (The 100-case table of docs/uncertainty.md: 94.3 %.)
  const auto* poly = r.Group("polynomial");
  ASSERT_NE(poly, nullptr);
  EXPECT_EQ(poly->cases, 40);
  EXPECT_GE(poly->overall.covered, 0.88);
  EXPECT_GE(poly->overall.pull_rms, 0.75);
  EXPECT_LE(poly->overall.pull_rms, 1.3);
  EXPECT_GE(poly->overall.covered, 0.93);  // regression (95.1 %)
  EXPECT_NEAR(poly->overall.pull_rms, 0.95, 0.1);  // regression
  double device2 = 0;
  int n = 0;
  for (const auto& row : r.device) {
    device2 += row.pull_rms * row.pull_rms * row.n;
    n += row.n;
  }
  const double device_rms = std::sqrt(device2 / n);
  EXPECT_GE(device_rms, 0.75);
  EXPECT_LE(device_rms, 1.3);
  EXPECT_NEAR(device_rms, 0.96, 0.1);  // regression
}

// Cones and ablations, measured with the spline: the U's of a map's peaks and ranges are marked lower bounds (the
// smoothing bias the draws do not reveal) and everything else is covered.
TEST(MeasurementUncertainty, MarksTheSplinesPeaksAndRangesAsLowerBounds) {
  CoverageOptions o;
  o.cases = 24;
  o.seed = 5;
  o.eye_kind = "keratoconus";
  o.jobs = 2;
  const auto r = RunUncertaintyCoverage(PaperConfig(), NominalDevice(), o);
  EXPECT_EQ(r.failed, 0);
  const auto* spline = r.Group("spline");
  ASSERT_NE(spline, nullptr);
  EXPECT_GE(spline->cases, 12);  // the paper cornea and the cones alternate; "auto" takes the spline for the cones
  EXPECT_GT(spline->lower_bounds.n, 0);
  // The acceptance (93-97 % within U, pull RMS 0.85-1.15) is NOT met by the spline's measurements yet, even
  // without the lower bounds (docs/uncertainty.md): this test holds today's figures so that they do not get worse
  // unnoticed. Measured 2026-12-05 (seed 5, 20 spline cases): 89.0 % within U, pull RMS 1.26; the lower bounds
  // 71.7 %, RMS 2.98.
  EXPECT_NEAR(spline->overall.covered, 0.89, 0.04);  // regression
  EXPECT_NEAR(spline->overall.pull_rms, 1.26, 0.15);  // regression
  EXPECT_NEAR(spline->lower_bounds.covered, 0.72, 0.08);  // regression
  // The lower bounds are what they say: short of the truth more often than the rest.
  EXPECT_LT(spline->lower_bounds.covered, spline->overall.covered);
}

}  // namespace
}  // namespace topocal::pipeline
