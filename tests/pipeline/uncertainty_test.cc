// Calibration uncertainty carried to the clinical numbers: linear propagation and seeded Monte Carlo.
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "model/config.h"
#include "pipeline/uncertainty.h"
#include "topo/sweep.h"
#include "util/io.h"

namespace topocal::pipeline {
namespace {

struct Fixture {
  model::Config config = model::LoadConfig(std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json");
  model::TopographerCamera camera;
  model::CameraModel calibrated;
  std::vector<model::PlaneSpot> spots;
  static constexpr double kSigma = 6.3e-5;
  Fixture() {
    camera.a_mm = config.topographer.a_mm;
    calibrated.width_px = camera.width_px;
    calibrated.height_px = camera.height_px;
    calibrated.fx_px = calibrated.fy_px = camera.FocalPx();
    calibrated.cx_px = camera.principal_point_px.x();
    calibrated.cy_px = camera.principal_point_px.y();
    calibrated.dist = {model::SeidelSigmaToBrownK1(kSigma, config.distortion.magnification, camera.a_mm), 0, 0, 0, 0};
    for (const auto& s : topo::SimulateSpots(config, kSigma).spots) spots.push_back({s.id, s.position_mm});
  }
};

// Independent draws with these standard deviations.
calib::ParameterCovariance Diagonal(const std::map<std::string, double>& stddev) {
  calib::ParameterCovariance c;
  c.matrix = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(stddev.size()), static_cast<Eigen::Index>(stddev.size()));
  Eigen::Index i = 0;
  for (const auto& [name, sd] : stddev) {
    c.names.push_back(name);
    c.matrix(i, i) = sd * sd;
    ++i;
  }
  return c;
}

// k1 and k2 with these standard deviations and correlation.
calib::ParameterCovariance K1K2(double sd1, double sd2, double correlation) {
  calib::ParameterCovariance c;
  c.names = {"k1", "k2"};
  c.matrix.resize(2, 2);
  c.matrix << sd1 * sd1, correlation * sd1 * sd2, correlation * sd1 * sd2, sd2 * sd2;
  c.full = true;
  return c;
}

TEST(Uncertainty, ScalesWithTheCalibrationsStandardDeviationAndIsCentredOnTheTruth) {
  const Fixture f;
  // k1 ~ -6.2; a standard deviation of 1e-3 is what the single-view calibration reports (topocal calibrate).
  const auto u1 = PropagateCalibrationUncertainty(f.spots, f.calibrated, Diagonal({{"k1", 1e-3}, {"fx", 0.0}}), f.camera,
                                                  f.config, 64, 7);
  const auto u2 = PropagateCalibrationUncertainty(f.spots, f.calibrated, Diagonal({{"k1", 2e-3}}), f.camera, f.config, 64, 7);
  ASSERT_EQ(u1.drawn, std::vector<std::string>{"k1"});  // fx has no spread, so it is not drawn
  EXPECT_EQ(u1.samples, 64);
  EXPECT_EQ(u1.failed_samples, 0);
  for (const char* q : {"kx", "ky", "rx_mm", "pv_tangential_D"}) {
    SCOPED_TRACE(q);
    EXPECT_GT(u1.quantities.at(q).expanded_k2, 0.0);
    // Same seed, so the same standard-normal draws: in the linear regime U doubles with the input spread.
    // 2 % allows for the curvature of k(sigma) over +-2 standard deviations.
    EXPECT_NEAR(u2.quantities.at(q).expanded_k2 / u1.quantities.at(q).expanded_k2, 2.0, 0.04);
  }
  // The draws are centred on the calibrated value, which is exact here: the means are the truth within U.
  EXPECT_NEAR(u1.quantities.at("kx").mean, f.config.cornea.kx, u1.quantities.at("kx").expanded_k2);
  EXPECT_NEAR(u1.quantities.at("rx_mm").mean, f.config.cornea.rx_mm, 1e-3);
}

TEST(Uncertainty, IsDeterministicForASeed) {
  const Fixture f;
  const auto a = PropagateCalibrationUncertainty(f.spots, f.calibrated, Diagonal({{"k1", 1e-3}}), f.camera, f.config, 8, 3);
  const auto b = PropagateCalibrationUncertainty(f.spots, f.calibrated, Diagonal({{"k1", 1e-3}}), f.camera, f.config, 8, 3);
  EXPECT_EQ(a.quantities.at("kx").mean, b.quantities.at("kx").mean);
  EXPECT_EQ(a.quantities.at("kx").expanded_k2, b.quantities.at("kx").expanded_k2);
}

TEST(Uncertainty, IsBitIdenticalWhateverTheThreadCount) {
  const Fixture f;
  // Draw i takes its normals from seed_seq{seed, i} and the statistics are summed in draw order: one thread and
  // three threads (more than this machine's cores, so the draws interleave) must agree to the last bit.
  const auto cov = K1K2(1e-3, 0.05, 0.5);
  const auto one = PropagateCalibrationUncertainty(f.spots, f.calibrated, cov, f.camera, f.config, 12, 11, 1);
  const auto three = PropagateCalibrationUncertainty(f.spots, f.calibrated, cov, f.camera, f.config, 12, 11, 3);
  EXPECT_EQ(one.samples, three.samples);
  EXPECT_EQ(one.failed_samples, three.failed_samples);
  ASSERT_EQ(one.quantities.size(), 9u);
  ASSERT_EQ(one.quantities.size(), three.quantities.size());
  for (const auto& [name, q] : one.quantities) {
    SCOPED_TRACE(name);
    EXPECT_EQ(q.mean, three.quantities.at(name).mean);
    EXPECT_EQ(q.expanded_k2, three.quantities.at(name).expanded_k2);
  }
}

TEST(Uncertainty, CorrelationsOfTheCalibrationChangeTheClinicalUncertainty) {
  const Fixture f;
  // Over the spot field (r ~ 0.1 in normalised units) k2 r^4 moves the spots the same way as k1 r^2, so both push
  // k_x the same way: correlated moves add up, anticorrelated ones cancel. Both methods: linear propagation (0) and
  // 64 Monte Carlo draws (same seed, so the same normal draws).
  constexpr double kSd1 = 1e-3, kSd2 = 0.1;  // k2's effect at r ~ 0.1 is then comparable to k1's
  for (const int samples : {0, 64}) {
    SCOPED_TRACE(samples);
    const auto propagate = [&](double correlation) {
      return PropagateCalibrationUncertainty(f.spots, f.calibrated, K1K2(kSd1, kSd2, correlation), f.camera,
                                             f.config, samples, 5);
    };
    const auto independent = propagate(0.0), together = propagate(0.95), opposed = propagate(-0.95);
    EXPECT_TRUE(together.correlated);
    EXPECT_EQ(together.drawn, (std::vector<std::string>{"k1", "k2"}));
    const double u0 = independent.quantities.at("kx").expanded_k2;
    EXPECT_GT(together.quantities.at("kx").expanded_k2, u0);
    EXPECT_LT(opposed.quantities.at("kx").expanded_k2, u0);
  }
}

TEST(Uncertainty, RefusesWhatItCannotPropagate) {
  const Fixture f;
  EXPECT_THROW(PropagateCalibrationUncertainty(f.spots, f.calibrated, Diagonal({{"k1", 0.0}}), f.camera, f.config, 8, 1),
               util::InputError);
  EXPECT_THROW(PropagateCalibrationUncertainty(f.spots, f.calibrated, Diagonal({{"k1", 1e-3}}), f.camera, f.config, 1, 1),
               util::InputError);
  auto mismatched = K1K2(1e-3, 1e-3, 0.0);
  mismatched.names.pop_back();
  EXPECT_THROW(PropagateCalibrationUncertainty(f.spots, f.calibrated, mismatched, f.camera, f.config, 8, 1),
               util::InputError);
}

TEST(Uncertainty, NothingToPropagateIsItsOwnConditionAndAMalformedCovarianceIsAnError) {
  // The legitimate "no uncertainty" case is detectable without trying (and without an exception)...
  EXPECT_TRUE(DistortionParametersToDraw(Diagonal({{"k1", 0.0}, {"fx", 1e-2}})).empty());
  EXPECT_TRUE(DistortionParametersToDraw(Diagonal({{"k1", std::nan("")}})).empty());
  EXPECT_EQ(DistortionParametersToDraw(K1K2(1e-3, 0.0, 0.0)), std::vector<std::string>{"k1"});
  EXPECT_EQ(DistortionParametersToDraw(Diagonal({{"fx", 1.0}, {"k1", 1e-3}, {"p2", 1e-4}})),
            (std::vector<std::string>{"k1", "p2"}));  // Diagonal's names are sorted
  // ...while a covariance that does not match its names is an error, not "nothing to propagate".
  auto mismatched = K1K2(1e-3, 1e-3, 0.0);
  mismatched.names.pop_back();
  EXPECT_THROW(DistortionParametersToDraw(mismatched), util::InputError);
}

TEST(Uncertainty, SpotsADrawCannotUndistortAreCountedNotDropped) {
  const Fixture f;
  // A k1 spread of 16 (the nominal k1 is -6.2): a draw far in the barrel tail folds the outermost spots, whose
  // inverse distortion then does not converge. Measured on 2026-12-01 with seed 1: 32 spots in 1 of 16 draws.
  const auto one = PropagateCalibrationUncertainty(f.spots, f.calibrated, Diagonal({{"k1", 16.0}}), f.camera,
                                                   f.config, 16, 1, 1);
  EXPECT_GT(one.undistort_failures, 0);
  EXPECT_GE(one.draws_with_undistort_failures, 1);
  EXPECT_LE(one.draws_with_undistort_failures, 16);
  EXPECT_GE(one.undistort_failures, one.draws_with_undistort_failures);
  // Counted per draw and summed in draw order: the same whatever the thread count.
  const auto two = PropagateCalibrationUncertainty(f.spots, f.calibrated, Diagonal({{"k1", 16.0}}), f.camera,
                                                   f.config, 16, 1, 2);
  EXPECT_EQ(one.undistort_failures, two.undistort_failures);
  EXPECT_EQ(one.draws_with_undistort_failures, two.draws_with_undistort_failures);
  // The calibration's own spread loses nothing.
  const auto calm = PropagateCalibrationUncertainty(f.spots, f.calibrated, Diagonal({{"k1", 1e-3}}), f.camera,
                                                    f.config, 8, 1);
  EXPECT_EQ(calm.undistort_failures, 0);
  EXPECT_EQ(calm.draws_with_undistort_failures, 0);
}

// Linear propagation (samples = 0) against Monte Carlo over the same covariance: k1 and k2 correlated, so that two
// eigen-directions carry the spread. The draws' own precision at n = 4000 is 1 / sqrt(2 n) = 1.1 % in U, so the two
// must agree to about 5 % (3 standard errors and a little curvature) where the clinical numbers are nearly linear
// over +-2 standard deviations.
TEST(Uncertainty, LinearPropagationAgreesWithMonteCarlo) {
  const Fixture f;
  const auto cov = K1K2(1e-3, 0.05, 0.5);
  const auto linear = PropagateCalibrationUncertainty(f.spots, f.calibrated, cov, f.camera, f.config, 0, 1);
  const auto drawn = PropagateCalibrationUncertainty(f.spots, f.calibrated, cov, f.camera, f.config, 4000, 1);
  EXPECT_TRUE(linear.linear);
  EXPECT_FALSE(drawn.linear);
  EXPECT_EQ(linear.samples, 2);  // the eigen-directions, two analyses each
  EXPECT_EQ(linear.failed_samples, 0);
  EXPECT_EQ(linear.drawn, drawn.drawn);
  // Measured on 2026-12-07: U ratio linear / Monte Carlo 1.017 (kx), 1.017 (central_axial_power_D); over four
  // seeds 0.985 to 1.018.
  for (const char* q : {"kx", "ky", "rx_mm", "radius_mm", "central_axial_power_D"}) {
    SCOPED_TRACE(q);
    const double ratio = linear.quantities.at(q).expanded_k2 / drawn.quantities.at(q).expanded_k2;
    EXPECT_NEAR(ratio, 1.0, 0.05);    // acceptance: the draws' precision
    EXPECT_NEAR(ratio, 1.017, 0.01);  // regression
    // The linear result is centred on the calibration's own value; the draws' mean is within their U of it.
    EXPECT_NEAR(drawn.quantities.at(q).mean, linear.quantities.at(q).mean, drawn.quantities.at(q).expanded_k2);
  }
}

TEST(Uncertainty, LinearPropagationScalesWithTheSpread) {
  const Fixture f;
  const auto u1 = PropagateCalibrationUncertainty(f.spots, f.calibrated, Diagonal({{"k1", 1e-3}}), f.camera,
                                                  f.config, 0, 1);
  const auto u2 = PropagateCalibrationUncertainty(f.spots, f.calibrated, Diagonal({{"k1", 2e-3}}), f.camera,
                                                  f.config, 0, 1);
  for (const char* q : {"kx", "ky", "rx_mm", "central_axial_power_D"}) {
    SCOPED_TRACE(q);
    EXPECT_GT(u1.quantities.at(q).expanded_k2, 0.0);
    // Central differences cancel the curvature: U doubles with the spread to well within 1 %.
    EXPECT_NEAR(u2.quantities.at(q).expanded_k2 / u1.quantities.at(q).expanded_k2, 2.0, 0.02);
    EXPECT_EQ(u1.quantities.at(q).mean, u2.quantities.at(q).mean);  // the calibration's own value, both times
  }
  EXPECT_NEAR(u1.quantities.at("kx").mean, f.config.cornea.kx, u1.quantities.at("kx").expanded_k2);
}

TEST(Uncertainty, LinearPropagationIsBitIdenticalWhateverTheThreadCount) {
  const Fixture f;
  const auto cov = K1K2(1e-3, 0.05, 0.5);
  const auto one = PropagateCalibrationUncertainty(f.spots, f.calibrated, cov, f.camera, f.config, 0, 1, 1);
  const auto three = PropagateCalibrationUncertainty(f.spots, f.calibrated, cov, f.camera, f.config, 0, 1, 3);
  ASSERT_EQ(one.quantities.size(), 9u);
  for (const auto& [name, q] : one.quantities) {
    SCOPED_TRACE(name);
    EXPECT_EQ(q.mean, three.quantities.at(name).mean);
    EXPECT_EQ(q.expanded_k2, three.quantities.at(name).expanded_k2);
  }
}

TEST(Uncertainty, TheSettingIsReadAsUsersWriteIt) {
  using Method = UncertaintySetting::Method;
  EXPECT_EQ(UncertaintySetting::Parse("linear", "--uncertainty").method, Method::kLinear);
  EXPECT_EQ(UncertaintySetting::Parse("none", "--uncertainty").method, Method::kNone);
  EXPECT_EQ(UncertaintySetting::Parse("0", "--uncertainty").method, Method::kNone);
  const auto mc = UncertaintySetting::Parse("200", "--uncertainty");
  EXPECT_EQ(mc.method, Method::kMonteCarlo);
  EXPECT_EQ(mc.draws, 200);
  EXPECT_EQ(mc.MethodName(), "monte-carlo");
  for (const char* bad : {"1", "-3", "100001", "lin", "20x", ""}) {
    SCOPED_TRACE(bad);
    try {
      (void)UncertaintySetting::Parse(bad, "--uncertainty");
      ADD_FAILURE() << "accepted";
    } catch (const util::InputError& e) {
      EXPECT_EQ(std::string(e.what()).rfind("--uncertainty: \"", 0), 0u) << e.what();
    }
  }
  ASSERT_TRUE(UncertaintySetting::FromName("linear", 0));
  EXPECT_EQ(UncertaintySetting::FromName("linear", 0)->method, Method::kLinear);
  EXPECT_EQ(UncertaintySetting::FromName("monte-carlo", 200)->draws, 200);
  EXPECT_FALSE(UncertaintySetting::FromName("linear", 5));
  EXPECT_FALSE(UncertaintySetting::FromName("monte-carlo", 1));
  EXPECT_FALSE(UncertaintySetting::FromName("bootstrap", 0));
}

}  // namespace
}  // namespace topocal::pipeline
