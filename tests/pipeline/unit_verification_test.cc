// The unit checks (pipeline/unit_verification.h) leave the uncertainty out only when there is nothing to propagate;
// every other failure of the propagation is an error that names the check.
#include "pipeline/unit_verification.h"

#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

#include "model/config.h"
#include "model/distortion.h"

namespace topocal::pipeline {
namespace {

struct Fixture {
  model::Config config = model::LoadConfig(std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json");
  model::TopographerCamera camera;
  UnitCalibration unit;
  CheckOptions options;
  Fixture() {
    camera.a_mm = config.topographer.a_mm;
    auto& c = unit.camera;
    c.width_px = camera.width_px;
    c.height_px = camera.height_px;
    c.fx_px = c.fy_px = camera.FocalPx();
    c.cx_px = camera.principal_point_px.x();
    c.cy_px = camera.principal_point_px.y();
    c.dist = {model::SeidelSigmaToBrownK1(6.3e-5, config.distortion.magnification, camera.a_mm), 0, 0, 0, 0};
    unit.covariance.names = {"fx", "k1"};
    unit.covariance.matrix = Eigen::Matrix2d::Zero();
    options.uncertainty = UncertaintySetting::Parse("4", "test");
  }
};

std::string ErrorOf(const Fixture& f) {
  try {
    SimulateThroughCalibratedCamera(f.unit, f.camera, f.config, f.options);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

TEST(UnitChecks, NoDistortionSpreadLeavesTheUncertaintyOut) {
  Fixture f;
  f.unit.covariance.matrix(0, 0) = 1.0;  // fx has a spread, but fx is not drawn (pipeline/uncertainty.h)
  const auto paper = SimulateThroughCalibratedCamera(f.unit, f.camera, f.config, f.options);
  EXPECT_FALSE(paper.uncertainty.has_value());
  f.unit.covariance.matrix(1, 1) = 1e-6;
  const auto drawn = SimulateThroughCalibratedCamera(f.unit, f.camera, f.config, f.options);
  ASSERT_TRUE(drawn.uncertainty.has_value());
  EXPECT_EQ(drawn.uncertainty->samples, 4);
  EXPECT_EQ(drawn.uncertainty->undistort_failures, 0);
}

TEST(UnitChecks, AMalformedCovarianceOrTooFewDrawsIsAnErrorNamingTheCheck) {
  Fixture f;
  f.unit.covariance.matrix(1, 1) = 1e-6;
  f.unit.covariance.names.pop_back();  // 2 x 2 matrix, 1 name: used to vanish as "no uncertainty"
  const std::string mismatch = ErrorOf(f);
  EXPECT_NE(mismatch.find("paper cornea"), std::string::npos) << mismatch;
  EXPECT_NE(mismatch.find("covariance matrix is 2 x 2 but has 1 parameter names"), std::string::npos) << mismatch;
  EXPECT_EQ(mismatch.find('\n'), std::string::npos) << "one line";

  Fixture g;
  g.unit.covariance.matrix(1, 1) = 1e-6;
  g.options.uncertainty = {UncertaintySetting::Method::kMonteCarlo, 1};  // a standard deviation needs 2
  const std::string few = ErrorOf(g);
  EXPECT_NE(few.find("at least 2 Monte Carlo draws"), std::string::npos) << few;
}

}  // namespace
}  // namespace topocal::pipeline
