// An eye off the axis and tilted, exact spots from the forward model, reconstructed and fitted
// with the default (free-apex) biconic fit, against the truth.
#include <gtest/gtest.h>

#include "model/config.h"
#include "model/null_screen.h"
#include "topo/analysis.h"
#include "topo/biconic_fit.h"

namespace topocal::topo {
namespace {

// Targets (apex up to 0.5 mm off the axis, tilt up to 3 deg, exact spots).
constexpr double kRadiusTolMm = 0.002;
constexpr double kConicTol = 0.002;
constexpr double kApexTolMm = 0.005;
// Regression bounds near what the code achieves: measured on 2026-12-01 at most 2.1e-5 mm in r, 3.6e-5 in k,
// 8.6e-6 mm in the apex and 7e-5 deg in the tilt (the Taylor polynomial's nm-level model error, not the fit).
constexpr double kRadiusRegressionMm = 1e-4;
constexpr double kConicRegression = 2e-4;
constexpr double kApexRegressionMm = 5e-5;
// No tilt target is set; 0.001 deg is 15x the measured error and far below any clinical meaning.
constexpr double kTiltRegressionDeg = 1e-3;

// The eye placed as the instrument places it: the point on the axis at the working distance (model::FocusOnAxis).
model::BiconicParams Focused(model::BiconicParams p) {
  model::Biconic b{p};
  EXPECT_TRUE(model::FocusOnAxis(&b));
  return b.params;
}

Analysis AnalyzeEye(const model::BiconicParams& eye, const std::string& fit) {
  auto c = model::LoadConfig(std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json");
  c.cornea = eye;
  c.reconstruction.biconic_fit = fit;
  const auto design = model::DesignNullScreen(c.ideal_image, c.topographer);
  const auto image = model::SynthesizeImage(model::Biconic{eye}, model::Topographer{c.topographer}, design.targets);
  std::vector<model::PlaneSpot> spots;
  for (const auto& s : image.spots) spots.push_back({s.id, s.position_mm});
  return AnalyzeSpots(spots, design.targets, c, &c.cornea);
}

// The paper's cornea and an oblique one, 0.49 mm off the axis and tilted by ~3 deg.
const model::BiconicParams kPaperEye = Focused({8.35, 7.63, -0.43, -0.25, 17.0, 0.35, -0.34, 0.0, 2.0, -2.2});
const model::BiconicParams kObliqueEye = Focused({7.2, 7.9, 0.3, -0.6, 123.0, -0.45, 0.2, 0.0, -2.9, 0.6});

TEST(Apex, FreeApexFitRecoversAnEyeOffTheAxisAndTilted) {
  for (const auto& eye : {kPaperEye, kObliqueEye}) {
    const Analysis a = AnalyzeEye(eye, "free-apex");
    const auto t = CanonicalBiconic(eye);
    const auto& f = a.surface_fit;
    SCOPED_TRACE(f.message);
    for (auto [got, want] : {std::pair{f.params.rx_mm, t.rx_mm}, std::pair{f.params.ry_mm, t.ry_mm}}) {
      EXPECT_NEAR(got, want, kRadiusTolMm);
      EXPECT_NEAR(got, want, kRadiusRegressionMm);
    }
    for (auto [got, want] : {std::pair{f.params.kx, t.kx}, std::pair{f.params.ky, t.ky}}) {
      EXPECT_NEAR(got, want, kConicTol);
      EXPECT_NEAR(got, want, kConicRegression);
    }
    const Eigen::Vector3d apex = model::Biconic{eye}.ApexMm();
    const double apex_error_mm = (f.apex_mm.head<2>() - apex.head<2>()).norm();
    EXPECT_LT(apex_error_mm, kApexTolMm);
    EXPECT_LT(apex_error_mm, kApexRegressionMm);
    EXPECT_NEAR(f.params.tilt_x_deg, eye.tilt_x_deg, kTiltRegressionDeg);
    EXPECT_NEAR(f.params.tilt_y_deg, eye.tilt_y_deg, kTiltRegressionDeg);
    ASSERT_TRUE(f.stddev_ok);
    EXPECT_GT(f.stddev.apex_x_mm, 0.0);
  }
}

TEST(Apex, PaperFitTurnsTheDecentrationIntoShape) {
  // Why free-apex is the default (accuracy_tables apex, docs/reconstruction.md): the 6-parameter fit misreads this
  // eye's conic constants.
  const Analysis a = AnalyzeEye(kPaperEye, "paper");
  const auto t = CanonicalBiconic(kPaperEye);
  EXPECT_GT(std::max(std::abs(a.surface_fit.params.kx - t.kx), std::abs(a.surface_fit.params.ky - t.ky)), 0.1);
}

}  // namespace
}  // namespace topocal::topo
