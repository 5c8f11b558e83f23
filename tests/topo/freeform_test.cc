// topocal's own freeform test set (model/freeform_test_set.h): a handful of representative
// corneas, off the axis and tilted, exact spots, against the accuracy targets over the supported disc. The whole set
// is tabulated by build/bench/accuracy_tables freeform (docs/reconstruction.md).
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "model/config.h"
#include "model/freeform_test_set.h"
#include "model/null_screen.h"
#include "topo/bspline_surface.h"
#include "topo/reconstruction.h"
#include "topo/truth_comparison.h"

namespace topocal::topo {
namespace {

// Accuracy targets (exact spots).
constexpr double kAxialRmsD = 0.1, kAxialMaxD = 0.5, kTangentialRmsD = 0.25, kHeightRmsUm = 0.1;
constexpr double kKmaxD = 0.25, kKmaxLocationMm = 0.1, kConeHeightRelative = 0.10, kSimKD = 0.1;

model::Config SplineConfig() {
  auto c = model::LoadConfig(std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json");
  c.reconstruction.surface_model = "spline";
  return c;
}

TruthComparison Measure(const std::string& name, const model::Config& config, Analysis* analysis = nullptr) {
  const auto cornea = model::FreeformTestSubset({name}).front();
  auto m = MeasureSimulatedCornea(cornea.surface, config);
  if (analysis) *analysis = m.analysis;
  return m.comparison;
}

void ExpectAllTargets(const TruthComparison& e) {
  EXPECT_LT(e.axial_rms_D, kAxialRmsD);
  EXPECT_LT(e.axial_max_D, kAxialMaxD);
  EXPECT_LT(e.tangential_rms_D, kTangentialRmsD);
  EXPECT_LT(e.height_rms_um, kHeightRmsUm);
  EXPECT_LT(std::abs(e.kmax_error_D), kKmaxD);
  EXPECT_LT(e.kmax_location_error_mm, kKmaxLocationMm);
  EXPECT_LT(std::abs(e.steep_k_error_D), kSimKD);
  EXPECT_LT(std::abs(e.flat_k_error_D), kSimKD);
}

TEST(Freeform, SplineHoldsAKeratoconusCone) {
  // 33 um cone, sigma 0.85 mm, 1.1 mm below-left of the axis; the eye 0.36 mm off the axis, tilted 2.1 deg.
  const auto e = Measure("kc-33um-0.85mm", SplineConfig());
  ExpectAllTargets(e);
  EXPECT_NEAR(e.cone_height_recovered_um, e.cone_height_true_um, kConeHeightRelative * e.cone_height_true_um);
  // Regression (measured 2026-12-02, lambda by REML, unknowns near the data only): axial rms 0.015 / max 0.121 D,
  // tangential rms 0.154 D, height rms 0.077 um, Kmax -0.004 D at 0.059 mm, cone 19.99 -> 19.97 um (on the whole
  // grid, earlier the same day: tangential 0.145 D, height 0.071 um). (With GCV, 2026-12-01: tangential
  // 0.089 D, height 0.027 um; REML smooths this cone a little more and holds the ablations and noisy data better.)
  EXPECT_LT(e.axial_rms_D, 0.03);
  EXPECT_LT(e.axial_max_D, 0.25);
  EXPECT_LT(e.tangential_rms_D, 0.18);
  EXPECT_LT(e.height_rms_um, 0.09);
  EXPECT_NEAR(e.cone_height_recovered_um, e.cone_height_true_um, 0.1);
}

TEST(Freeform, SplineHoldsANippleCone) {
  const auto e = Measure("kc-14um-0.87mm-nipple", SplineConfig());
  ExpectAllTargets(e);
  EXPECT_NEAR(e.cone_height_recovered_um, e.cone_height_true_um, kConeHeightRelative * e.cone_height_true_um);
  // Regression (2026-12-02, REML, unknowns near the data): axial rms 0.008 / max 0.056 D, tangential rms 0.101 D
  // (0.099 on the whole grid), height 0.040 um
  // (GCV, 2026-12-01: tangential 0.039 D).
  EXPECT_LT(e.axial_rms_D, 0.015);
  EXPECT_LT(e.tangential_rms_D, 0.13);
}

TEST(Freeform, SplineOnAMyopicAblation) {
  // -5 D over 6 mm, decentred 0.5 mm. Axial map, Kmax and sim-K meet the targets; the tangential map and the
  // height do NOT yet (the C2 blend's curvature kink at r = 3-4 mm is narrower than the spot spacing:
  // tangential rms 0.86 D against 0.25 D, height rms 0.17 um against 0.1 um, measured 2026-12-02).
  const auto e = Measure("lasik-myopic-5D-decentred", SplineConfig());
  EXPECT_LT(e.axial_rms_D, kAxialRmsD);
  EXPECT_LT(e.axial_max_D, kAxialMaxD);
  EXPECT_LT(std::abs(e.kmax_error_D), kKmaxD);
  EXPECT_LT(std::abs(e.steep_k_error_D), kSimKD);
  EXPECT_LT(std::abs(e.flat_k_error_D), kSimKD);
  // Regression bounds (measured 2026-12-02, REML: 0.032 D axial rms, 0.86 D tangential rms, 0.17 um height rms;
  // with GCV, 2026-12-01: 0.053 D, 1.37 D, 0.42 um).
  EXPECT_LT(e.axial_rms_D, 0.05);
  EXPECT_LT(e.tangential_rms_D, 1.1);
  EXPECT_LT(e.height_rms_um, 0.22);
}

// Knots finer than the spots determine: the spline interpolates them, the adequacy figures fall to 0 and the curvature
// between the spots is the penalty's, not the data's. Such a fit gives no clinical reading, and says why; the same
// eye with the configuration's knots is measured.
TEST(Freeform, KnotsFinerThanTheSpotsDetermineGiveNoClinicalReading) {
  auto fine = SplineConfig();
  fine.reconstruction.spline_spacing_mm = 0.1;
  Analysis analysis;
  Measure("lasik-myopic-6D", fine, &analysis);
  const auto& r = analysis.reconstruction;
  // Measured 2026-12-07: 1,538 effective parameters for 1,456 slopes, adequacy ratio 0.00.
  EXPECT_GT(r.spline_effective_params, kMaxSplineParameterShare * 2 * r.spots_used);
  EXPECT_TRUE(ModelFitsData(r));  // the adequacy figures cannot see it
  // What the check guards against: on the +6 D hyperopic ablation the same knots make the tangential map worse than
  // the configuration's (measured 2026-12-07: 2.60 against 1.87 D rms), with nothing in the fit to show it.
  Analysis hyperopic_fine;
  const auto worse = Measure("lasik-hyperopic-6D", fine, &hyperopic_fine);
  const auto configured = Measure("lasik-hyperopic-6D", SplineConfig());
  EXPECT_TRUE(SplineUndetermined(hyperopic_fine.reconstruction));
  EXPECT_GT(worse.tangential_rms_D, configured.tangential_rms_D + 0.5);
  ASSERT_TRUE(SplineUndetermined(r));
  EXPECT_FALSE(analysis.clinical_ok);
  const std::string why =
      "the spline's knots every 0.1 mm are finer than the " + std::to_string(r.spots_used) + " spots determine";
  EXPECT_NE(analysis.clinical_message.find(why), std::string::npos) << analysis.clinical_message;
  EXPECT_NE(analysis.clinical_message.find("set reconstruction.spline_spacing_mm coarser"), std::string::npos);
  Analysis coarse;
  Measure("lasik-myopic-6D", SplineConfig(), &coarse);
  EXPECT_FALSE(SplineUndetermined(coarse.reconstruction));
  EXPECT_LT(coarse.reconstruction.spline_effective_params, 0.7 * 2 * coarse.reconstruction.spots_used);  // 0.58
  EXPECT_TRUE(coarse.clinical_ok) << coarse.clinical_message;
}

TEST(Freeform, BothModelsHoldAnObliqueToricBiconic) {
  // r 8.5 / 7.0 mm, k -0.6 / +0.4, 140 deg; off the axis and tilted. Measured 2026-12-01: spline axial rms 2e-4 D,
  // polynomial 1e-3 D within the supported disc.
  for (const char* model : {"spline", "polynomial"}) {
    auto config = SplineConfig();
    config.reconstruction.surface_model = model;
    SCOPED_TRACE(model);
    const auto e = Measure("biconic-toric-1.5mm-oblique", config);
    ExpectAllTargets(e);
    EXPECT_LT(e.axial_rms_D, 0.01);
  }
}

TEST(Freeform, ThePolynomialFlattensTheConeAndTheAdequacyFigureSaysSo) {
  // Today's polynomial (degree 10) on the 33 um cone: the cone is flattened and the slope residual is tens of
  // times the spot noise, which the analysis flags; the spline residual brings it back below the threshold.
  auto config = SplineConfig();
  config.reconstruction.surface_model = "polynomial";
  Analysis poly, spline;
  const auto ep = Measure("kc-33um-0.85mm", config, &poly);
  const auto es = Measure("kc-33um-0.85mm", SplineConfig(), &spline);
  EXPECT_GT(ep.axial_rms_D, 5 * es.axial_rms_D);
  EXPECT_GT(poly.reconstruction.adequacy_ratio, kAdequacyWarningRatio);
  bool warned = false;
  for (const auto& w : poly.warnings) warned |= w.find("does not represent the data") != std::string::npos;
  EXPECT_TRUE(warned);
  EXPECT_LT(spline.reconstruction.adequacy_ratio, kAdequacyWarningRatio);
}

// surface_model "auto": the spline joins exactly where the polynomial does not fit the data, and the result is then
// the spline model's bit for bit (the same passes, the decision computes only the adequacy figures); where the
// polynomial fits, the polynomial's bit for bit.
TEST(Freeform, AutoTakesTheSplineWhereThePolynomialDoesNotFit) {
  const auto with = [](const char* model) {
    auto c = SplineConfig();
    c.reconstruction.surface_model = model;
    return c;
  };
  // The mildest cone (flagged only by the structured residual), the 33 um cone, an ablation; and a biconic.
  for (const char* name : {"kc-5um-0.8mm", "kc-33um-0.85mm", "lasik-myopic-5D-decentred"}) {
    SCOPED_TRACE(name);
    Analysis a, s;
    const auto ea = Measure(name, with("auto"), &a);
    const auto es = Measure(name, with("spline"), &s);
    EXPECT_EQ(a.reconstruction.surface_model, "spline");
    EXPECT_NE(a.reconstruction.surface_model_reason.find("the spline joins"), std::string::npos)
        << a.reconstruction.surface_model_reason;
    EXPECT_EQ(ea.tangential_rms_D, es.tangential_rms_D);
    EXPECT_EQ(ea.height_rms_um, es.height_rms_um);
    EXPECT_EQ(a.surface_fit.params.rx_mm, s.surface_fit.params.rx_mm);
    EXPECT_EQ(a.reconstruction.iterations, s.reconstruction.iterations);
  }
  Analysis a, p;
  const auto ea = Measure("biconic-toric-1.5mm-oblique", with("auto"), &a);
  const auto ep = Measure("biconic-toric-1.5mm-oblique", with("polynomial"), &p);
  EXPECT_EQ(a.reconstruction.surface_model, "polynomial");
  EXPECT_TRUE(a.reconstruction.residual.empty());
  EXPECT_NE(a.reconstruction.surface_model_reason.find("it fits"), std::string::npos);
  EXPECT_EQ(ea.axial_rms_D, ep.axial_rms_D);
  EXPECT_EQ(a.reconstruction.adequacy_ratio, p.reconstruction.adequacy_ratio);
  EXPECT_EQ(a.reconstruction.structured_residual_ratio, p.reconstruction.structured_residual_ratio);
  EXPECT_EQ(a.surface_fit.params.kx, p.surface_fit.params.kx);
  EXPECT_EQ(p.reconstruction.surface_model, "polynomial");
  EXPECT_TRUE(p.reconstruction.surface_model_reason.empty());
  // Without the adequacy figures asked for, "auto" still decides (it computes them) but returns them as 0, so that
  // they never describe the polynomial when the spline joined.
  auto config = with("auto");
  const auto cornea = model::FreeformTestSubset({"kc-33um-0.85mm"}).front();
  const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
  std::vector<model::PlaneSpot> spots;
  for (const auto& s :
       model::SynthesizeImage(cornea.surface, model::Topographer{config.topographer}, design.targets).spots) {
    spots.push_back({s.id, s.position_mm});
  }
  ReconstructOptions no_adequacy;
  no_adequacy.adequacy = false;
  const Reconstruction r = Reconstruct(spots, design.targets, config.topographer, config.reconstruction, no_adequacy);
  ASSERT_TRUE(r.ok) << r.message;
  EXPECT_EQ(r.surface_model, "spline");
  EXPECT_EQ(r.adequacy_ratio, 0.0);
  EXPECT_EQ(r.structured_residual_ratio, 0.0);
}

// "auto" with the paper's single-pass method (the vertex search of Fig. 8): decided after the polynomial's one fit
// at each t, and the result is the reported model's bit for bit. On the paper method's points (the design sphere's,
// not refined) the adequacy figures do not separate the models (33 um cone, measured 2026-12-02: adequacy ratio
// 0.37 and structured ratio 0.33 with the polynomial, 0.33 / 0.30 with the spline; the sphere's error dominates
// both), so "auto" keeps the polynomial there; docs/reconstruction.md.
TEST(Freeform, AutoWithThePaperMethodIsTheModelItReports) {
  auto paper = SplineConfig();
  paper.reconstruction.method = "paper";
  auto automatic = paper;
  automatic.reconstruction.surface_model = "auto";
  Analysis a, m;
  const auto ea = Measure("kc-33um-0.85mm", automatic, &a);
  ASSERT_TRUE(a.reconstruction.surface_model == "polynomial" || a.reconstruction.surface_model == "spline");
  paper.reconstruction.surface_model = a.reconstruction.surface_model;
  const auto em = Measure("kc-33um-0.85mm", paper, &m);
  EXPECT_EQ(a.reconstruction.method, "paper");
  EXPECT_EQ(a.reconstruction.surface_model, "polynomial") << a.reconstruction.surface_model_reason;
  EXPECT_NE(a.reconstruction.surface_model_reason.find("auto: "), std::string::npos);
  EXPECT_EQ(a.reconstruction.vertex_t_mm, m.reconstruction.vertex_t_mm);
  EXPECT_EQ(ea.axial_rms_D, em.axial_rms_D);
  EXPECT_EQ(a.surface_fit.params.kx, m.surface_fit.params.kx);
  EXPECT_EQ(a.reconstruction.adequacy_ratio, m.reconstruction.adequacy_ratio);
}

// The mildest cones: the polynomial leaves a slope residual only 0.8-2.5 x the expected noise (below
// kAdequacyWarningRatio), but neighbouring spots share it — a shape, not noise — and the structured-residual figure
// flags it; on good fits with spot noise it stays at 0 (the noise is independent per spot). 0.04 px noise, seed 1.
TEST(Freeform, NeighbourCorrelatedResidualsFlagTheMildestConesButNotNoisyGoodFits) {
  auto config = SplineConfig();
  config.reconstruction.surface_model = "polynomial";
  const double noise_mm = 0.04 * 1.12e-3;  // 0.04 px of the 1.12 um pixel
  const auto structured = [&](const char* name, const model::Config& c) {
    const auto m = MeasureSimulatedCornea(model::FreeformTestSubset({name}).front().surface, c, noise_mm, 1);
    SCOPED_TRACE(name);
    EXPECT_EQ(ModelFitsData(m.analysis.reconstruction),
              m.analysis.reconstruction.structured_residual_ratio <= kStructuredResidualWarningRatio &&
                  m.analysis.reconstruction.adequacy_ratio <= kAdequacyWarningRatio);
    return m.analysis.reconstruction;
  };
  // Measured 2026-12-01 (structured / adequacy): 5 um 1.95 / 2.51, 12 um 0.54 / 1.23, wide 40 um 0.81 / 1.45.
  for (const auto& [name, measured] : {std::pair{"kc-5um-0.8mm", 1.95}, std::pair{"kc-12um-1.3mm", 0.54},
                                       std::pair{"kc-40um-1.5mm", 0.81}}) {
    const auto r = structured(name, config);
    EXPECT_LT(r.adequacy_ratio, kAdequacyWarningRatio) << name;  // what the first figure misses
    EXPECT_GT(r.structured_residual_ratio, kStructuredResidualWarningRatio) << name;  // acceptance: flagged
    EXPECT_GT(r.structured_residual_ratio, 0.85 * measured) << name;                   // regression
    EXPECT_FALSE(ModelFitsData(r)) << name;
  }
  // Good fits with noise: measured 0.00 (neighbour correlation -0.05 to -0.08) on 2026-12-01.
  for (const char* name : {"biconic-toric-1.5mm-oblique", "irregular-4th-6th"}) {
    const auto r = structured(name, config);
    EXPECT_LE(r.structured_residual_ratio, kStructuredResidualWarningRatio) << name;  // acceptance: not flagged
    EXPECT_LT(r.structured_residual_ratio, 0.1) << name;                             // regression
    EXPECT_LT(r.residual_neighbour_correlation, 0.05) << name;
    EXPECT_TRUE(ModelFitsData(r)) << name;
  }
  // The spline represents the 12 um cone: its residual is noise again (measured 0.00, correlation -0.05).
  const auto spline = structured("kc-12um-1.3mm", SplineConfig());
  EXPECT_LE(spline.structured_residual_ratio, kStructuredResidualWarningRatio);
  EXPECT_LT(spline.structured_residual_ratio, 0.1);
}

TEST(Freeform, TheModelFitsThePaperCorneaAndMapsBeyondTheDataAreFlagged) {
  const auto c = model::LoadConfig(std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json");
  const auto m = MeasureSimulatedCornea(model::Biconic{c.cornea}, c);
  // Measured 2026-12-01: 0.0097 (exact spots; a model that holds leaves <= 1).
  EXPECT_LT(m.analysis.reconstruction.adequacy_ratio, 0.05);
  EXPECT_GT(m.analysis.reconstruction.expected_slope_noise, 0.0);
  EXPECT_LE(m.analysis.supported_radius_mm, m.analysis.covered_radius_mm);
  EXPECT_EQ(m.analysis.maps_extrapolated, m.analysis.power.radius_mm > m.analysis.supported_radius_mm);
  EXPECT_TRUE(m.analysis.clinical_ok) << m.analysis.clinical_message;
  EXPECT_LE(m.analysis.clinical.supported_radius_mm, m.analysis.supported_radius_mm);
}

// A refit after the points moved by a micrometre keeps the pattern and its analysis (the unknowns stay), factorises
// its own M once, and equals a fresh fit of the moved points exactly (same operations); REML's walk from
// lambda_start takes 3 factorisations when the minimum is there. (Until 2026-12-02 refits ran conjugate gradients
// from the previous factorisation: 1.3e-9 relative from a fresh solve on the full grid, 3-7e-6 on these unknowns.)
TEST(SplineFit, RefitsKeepTheAnalysisAndEqualAFreshFit) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-4.0, 4.0);
  std::vector<Eigen::Vector2d> points, slopes;
  while (points.size() < 600) {
    const Eigen::Vector2d p(u(rng), u(rng));
    if (p.norm() > 4.0) continue;
    points.push_back(p);
    // Gradient of a 20 um Gaussian bump 1 mm wide at (1, -0.5) mm.
    const Eigen::Vector2d d = p - Eigen::Vector2d(1.0, -0.5);
    slopes.push_back(-0.020 * std::exp(-d.squaredNorm() / 2.0) * d);
  }
  BSplineSurface first(4.6, 0.33);
  SplineSlopeFitter fitter;
  const SplineFit chosen = fitter.Fit(points, slopes, -1.0, SplineFitOptions{}, &first);
  ASSERT_TRUE(chosen.ok);
  EXPECT_GE(fitter.factorisations(), 3);  // the start and both neighbours at least
  EXPECT_EQ(fitter.analyses(), 1);
  // Not the whole grid: the corners around the disc of points are not solved for (0, then the piston's shift).
  const Eigen::VectorXd& c = first.coefficients();
  EXPECT_EQ(c(0), c(c.size() - 1));
  EXPECT_NE(c(0), c(c.size() / 2));
  int factorisations = fitter.factorisations();
  for (int pass = 0; pass < 3; ++pass) {
    for (auto& p : points) p += Eigen::Vector2d(1e-3, -0.5e-3);
    BSplineSurface refit(4.6, 0.33), fresh(4.6, 0.33);
    ASSERT_TRUE(fitter.Fit(points, slopes, chosen.lambda, SplineFitOptions{}, &refit).ok);
    ASSERT_TRUE(FitSplineToSlopes(points, slopes, chosen.lambda, SplineFitOptions{}, &fresh).ok);
    EXPECT_EQ(fitter.factorisations(), ++factorisations);
    const double relative = (refit.coefficients() - fresh.coefficients()).norm() / fresh.coefficients().norm();
    EXPECT_LT(relative, 1e-15);  // measured 0 (the same operations in the same order)
  }
  // Points moved 3 um in all: the unknowns change only if a point at the rim enters a new knot cell (rare).
  EXPECT_LE(fitter.analyses(), 2);
}

// A null screen leaves a hole at the centre of the corneal image (inside its first ring) and a glint or a lash can
// take spots anywhere: knots finer than such a hole must still be solved for, shaped by the penalty between the data
// around them. Slopes of a 7.8 mm sphere on rings from 0.8 mm, knots every 0.12 mm (a hole 13 cells wide).
TEST(SplineFit, AHoleTheDataEncloseIsShapedByThePenalty) {
  constexpr double kRadiusMm = 7.8;
  std::vector<Eigen::Vector2d> points, slopes;
  for (int ring = 0; ring < 20; ++ring) {
    const double r = 0.8 + 0.16 * ring;
    for (int k = 0; k < 60; ++k) {
      const double t = 2.0 * M_PI * (k + 0.5 * ring) / 60.0;
      const Eigen::Vector2d p(r * std::cos(t), r * std::sin(t));
      points.push_back(p);
      slopes.push_back(p / std::sqrt(kRadiusMm * kRadiusMm - p.squaredNorm()));
    }
  }
  BSplineSurface spline(4.0, 0.12);
  ASSERT_TRUE(FitSplineToSlopes(points, slopes, -1.0, SplineFitOptions{}, &spline).ok);
  double worst_power_error_D = 0;
  for (double x = -0.4; x <= 0.41; x += 0.1) {
    for (double y = -0.4; y <= 0.41; y += 0.1) {
      double z, zx, zy, zxx, zxy, zyy;
      spline.Derivatives(x, y, &z, &zx, &zy, &zxx, &zxy, &zyy);
      // Curvature 1/R near the apex: (n - 1) / R with the keratometric index 1.3375.
      const double truth = 1.0 / std::sqrt(kRadiusMm * kRadiusMm - x * x - y * y);
      for (const double c : {zxx, zyy}) worst_power_error_D = std::max(worst_power_error_D, 337.5 * std::abs(c - truth));
    }
  }
  // Acceptance: 0.25 D (the tangential target); measured 2026-12-07: 0.143 D within 0.4 mm of the centre. With the
  // hole's coefficients set to 0 (as the outside of the data is), 12,756 D.
  EXPECT_LT(worst_power_error_D, 0.25);
  EXPECT_LT(worst_power_error_D, 0.17);
}

}  // namespace
}  // namespace topocal::topo
