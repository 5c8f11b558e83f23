// Accuracy of the null-screen reconstruction against ground truth and against the paper's Tables VI and VII.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "model/config.h"
#include "model/null_screen.h"
#include "topo/analysis.h"
#include "topo/biconic_fit.h"
#include "topo/sweep.h"

namespace topocal::topo {
namespace {

// Acceptance, noise-free sigma = 0 ground truth: radii 0.002 mm, conic constants 0.002, alpha 0.01 deg, and pv of the
// height difference below 0.05 um (the paper reports 46 nm).
constexpr double kTruthRadiusTolMm = 0.002;
constexpr double kTruthConicTol = 0.002;
constexpr double kTruthAlphaTolDeg = 0.01;
constexpr double kTruthPvTolUm = 0.05;
// Regression bounds near what the iterative reconstruction achieves on exact spots (3-5x the value measured
// 2026-12-02), one set for the paper cornea and one for the two other biconics (whose alpha and asymmetry the
// polynomial represents less closely): the limits above stay as the acceptance.
struct TruthRegression {
  double radius_mm, conic, alpha_deg, pv_um;
};
// Paper cornea, all 624 spots / 90 % of them: measured |dr| 4.3e-6 / 4.6e-6 mm, |dk| 5.9e-6 / 6.3e-6, |dalpha|
// 0 / 5.3e-6 deg, pv 1.04e-3 / 1.11e-3 um.
constexpr TruthRegression kPaperCorneaRegression{2e-5, 2.5e-5, 2e-5, 4e-3};
// The two other biconics: measured |dr| 2.7e-5 mm, |dk| 4.2e-5, |dalpha| 2.1e-12 deg, pv 9.1e-3 um (worst of both).
constexpr TruthRegression kOtherBiconicRegression{1e-4, 1.5e-4, 2e-5, 0.03};
// Acceptance, paper Table VI for every sigma: r 0.01 mm, k 0.02, alpha 0.01 deg.
constexpr double kTableVIRadiusTolMm = 0.01;
constexpr double kTableVIConicTol = 0.02;
constexpr double kTableVIAlphaTolDeg = 0.01;
// Acceptance, paper Table VII: pv_m and pv_a within 0.1 D for |sigma| <= 1.41e-6.
constexpr double kTableVIIPowerTolD = 0.1;
// Regression bounds on the departure from the paper's printed (rounded) values, worst over the seven rows; measured
// 2026-12-02: |dr| 8.6e-3 mm, |dk| 8.6e-3, |dalpha| 1.0e-3 deg (the paper prints 16.999), Table VII |dpv| 0.082 D.
// Radius and power already sit near their acceptance limits, which therefore serve as both bounds.
constexpr double kTableVIConicRegression = 0.01;
constexpr double kTableVIAlphaRegressionDeg = 2e-3;

model::Config PaperConfig() { return model::LoadConfig(std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json"); }

std::vector<model::PlaneSpot> Spots(const model::SyntheticImage& image) {
  std::vector<model::PlaneSpot> out;
  for (const auto& s : image.spots) out.push_back({s.id, s.position_mm});
  return out;
}

Analysis AnalyzeCornea(const model::Config& base, const model::BiconicParams& cornea, double sigma,
                       std::vector<model::PlaneSpot>* spots_out = nullptr) {
  model::Config c = base;
  c.cornea = cornea;
  const auto design = model::DesignNullScreen(c.ideal_image, c.topographer);
  const auto spots = Spots(SimulateSpots(c, sigma));
  if (spots_out) *spots_out = spots;
  return AnalyzeSpots(spots, design.targets, c, &c.cornea);
}

void ExpectMatchesTruth(const model::BiconicParams& truth, const Analysis& a, const TruthRegression& regression) {
  const auto t = CanonicalBiconic(truth);
  const auto& f = a.surface_fit.params;
  EXPECT_NEAR(f.rx_mm, t.rx_mm, kTruthRadiusTolMm);
  EXPECT_NEAR(f.ry_mm, t.ry_mm, kTruthRadiusTolMm);
  EXPECT_NEAR(f.kx, t.kx, kTruthConicTol);
  EXPECT_NEAR(f.ky, t.ky, kTruthConicTol);
  EXPECT_NEAR(f.alpha_deg, t.alpha_deg, kTruthAlphaTolDeg);
  ASSERT_TRUE(a.errors.has_value());
  EXPECT_LT(a.errors->pv_um, kTruthPvTolUm);
  const double dr_mm = std::max(std::abs(f.rx_mm - t.rx_mm), std::abs(f.ry_mm - t.ry_mm));
  const double dk = std::max(std::abs(f.kx - t.kx), std::abs(f.ky - t.ky));
  const double dalpha_deg = std::abs(f.alpha_deg - t.alpha_deg);
  std::printf("truth recovery: |dr| %.2e mm, |dk| %.2e, |dalpha| %.2e deg, pv %.2e um\n", dr_mm, dk, dalpha_deg,
              a.errors->pv_um);
  EXPECT_LT(dr_mm, regression.radius_mm);
  EXPECT_LT(dk, regression.conic);
  EXPECT_LT(dalpha_deg, regression.alpha_deg);
  EXPECT_LT(a.errors->pv_um, regression.pv_um);
}

TEST(Reconstruction, PaperCorneaAtSigmaZeroMatchesTruth) {
  const auto c = PaperConfig();
  const auto a = AnalyzeCornea(c, c.cornea, 0.0);
  EXPECT_EQ(a.reconstruction.spots_used, 624);
  ExpectMatchesTruth(c.cornea, a, kPaperCorneaRegression);
}

TEST(Reconstruction, OtherBiconicsAtSigmaZeroMatchTruth) {
  const auto c = PaperConfig();
  // Steeper along x with a positive conic and alpha > 90 deg (canonicalised to 33 deg, r_x and r_y swapped).
  ExpectMatchesTruth({7.2, 7.9, 0.3, -0.6, 123.0, 0, 0, 0}, AnalyzeCornea(c, {7.2, 7.9, 0.3, -0.6, 123.0, 0, 0, 0}, 0),
                     kOtherBiconicRegression);
  // Canonical already, alpha = 95 deg reported as such.
  ExpectMatchesTruth({8.0, 7.4, -0.1, 0.2, 95.0, 0, 0, 0}, AnalyzeCornea(c, {8.0, 7.4, -0.1, 0.2, 95.0, 0, 0, 0}, 0),
                     kOtherBiconicRegression);
}

TEST(Reconstruction, PartialUnorderedSpotSetUsesWhatIsThere) {
  const auto c = PaperConfig();
  const auto design = model::DesignNullScreen(c.ideal_image, c.topographer);
  auto spots = Spots(SimulateSpots(c, 0.0));
  std::mt19937 rng(20261125);
  std::shuffle(spots.begin(), spots.end(), rng);
  spots.resize(spots.size() * 9 / 10);  // 10 % missing
  spots.push_back({model::SpotId{40, 1}, Eigen::Vector2d(0.1, 0.1)});  // an identity the design does not have
  const auto a = AnalyzeSpots(spots, design.targets, c, &c.cornea);
  EXPECT_EQ(a.reconstruction.spots_used, 561);
  ASSERT_EQ(a.reconstruction.unmatched.size(), 1u);
  EXPECT_EQ(a.reconstruction.unmatched[0], (model::SpotId{40, 1}));
  ExpectMatchesTruth(c.cornea, a, kPaperCorneaRegression);
}

TEST(Reconstruction, TooFewSpotsFailCleanly) {
  const auto c = PaperConfig();
  const auto design = model::DesignNullScreen(c.ideal_image, c.topographer);
  auto spots = Spots(SimulateSpots(c, 0.0));
  spots.resize(20);  // 40 slope equations for 54 unknown coefficients
  const auto r = Reconstruct(spots, design.targets, c.topographer, c.reconstruction);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.message.find("20 spots"), std::string::npos) << r.message;
  EXPECT_THROW(AnalyzeSpots(spots, design.targets, c, &c.cornea), std::runtime_error);
}

TEST(Reconstruction, IterativeMethodBeatsThePaperVertexSearch) {
  // docs/reconstruction.md: with the sphere alone the normals keep the error of P2' ~ P2 (tens of um), and
  // Delta(t) is monotone so the search ends at its window's edge. Both are measured here against the truth.
  auto c = PaperConfig();
  const auto iterative = AnalyzeCornea(c, c.cornea, 0.0);
  c.reconstruction.method = "paper";
  const auto paper = AnalyzeCornea(c, c.cornea, 0.0);
  ASSERT_TRUE(paper.errors && iterative.errors);
  EXPECT_GT(paper.errors->pv_um, 100 * iterative.errors->pv_um);
  // The search walks to the edge of its window and one grid step beyond per refinement (Fig. 8's t_k' +- Delta t).
  EXPECT_GE(std::abs(paper.reconstruction.vertex_t_mm * 1e3), c.reconstruction.vertex_search_halfwidth_um);
}

struct TableVIRow {
  double sigma, rx, ry, kx, ky, alpha;
};

TEST(Reconstruction, SweepReproducesTablesVIAndVII) {
  const auto c = PaperConfig();
  const auto sweep = RunSweep(c);
  // Paper Table VI.
  const std::vector<TableVIRow> table_vi = {
      {-2.0e-4, 8.350, 7.661, -1.106, -0.774, 16.999}, {-6.3e-5, 8.344, 7.636, -0.658, -0.425, 16.999},
      {-1.41e-6, 8.349, 7.629, -0.435, -0.254, 17.000}, {0.0, 8.349, 7.629, -0.429, -0.249, 17.000},
      {1.41e-6, 8.350, 7.629, -0.424, -0.245, 17.000},  {6.3e-5, 8.360, 7.627, -0.184, -0.062, 16.999},
      {2.0e-4, 8.415, 7.641, 0.435, 0.400, 16.999}};
  // Paper Table VII: pv_m, pv_a (D).
  const std::vector<std::pair<double, double>> table_vii = {{23.06, 15.64}, {16.37, 8.52}, {12.590, 6.97},
                                                            {12.49, 6.93},  {12.40, 6.89}, {7.917, 6.03},
                                                            {14.23, 11.29}};
  ASSERT_EQ(sweep.rows.size(), table_vi.size());
  double worst_r = 0, worst_k = 0, worst_alpha = 0, worst_pv = 0;
  for (size_t i = 0; i < table_vi.size(); ++i) {
    const auto& f = sweep.rows[i].analysis.surface_fit.params;
    const auto& p = table_vi[i];
    SCOPED_TRACE(::testing::Message() << "sigma " << p.sigma);
    EXPECT_NEAR(f.rx_mm, p.rx, kTableVIRadiusTolMm);
    EXPECT_NEAR(f.ry_mm, p.ry, kTableVIRadiusTolMm);
    EXPECT_NEAR(f.kx, p.kx, kTableVIConicTol);
    EXPECT_NEAR(f.ky, p.ky, kTableVIConicTol);
    EXPECT_NEAR(f.alpha_deg, p.alpha, kTableVIAlphaTolDeg);
    const auto& power = sweep.rows[i].analysis.power;
    worst_r = std::max({worst_r, std::abs(f.rx_mm - p.rx), std::abs(f.ry_mm - p.ry)});
    worst_k = std::max({worst_k, std::abs(f.kx - p.kx), std::abs(f.ky - p.ky)});
    worst_alpha = std::max(worst_alpha, std::abs(f.alpha_deg - p.alpha));
    if (std::abs(p.sigma) <= 1.41e-6) {
      EXPECT_NEAR(power.pv_tangential_D, table_vii[i].first, kTableVIIPowerTolD);
      EXPECT_NEAR(power.pv_axial_D, table_vii[i].second, kTableVIIPowerTolD);
      worst_pv = std::max({worst_pv, std::abs(power.pv_tangential_D - table_vii[i].first),
                           std::abs(power.pv_axial_D - table_vii[i].second)});
    }
  }
  std::printf("against the paper: |dr| %.2e mm, |dk| %.2e, |dalpha| %.2e deg, Table VII |dpv| %.2e D\n", worst_r,
              worst_k, worst_alpha, worst_pv);
  EXPECT_LT(worst_k, kTableVIConicRegression);
  EXPECT_LT(worst_alpha, kTableVIAlphaRegressionDeg);
  // The sign change of both conic constants at sigma = 2e-4 (the last row).
  EXPECT_GT(sweep.rows.back().analysis.surface_fit.params.kx, 0);
  EXPECT_GT(sweep.rows.back().analysis.surface_fit.params.ky, 0);
  // Beyond |sigma| = 1.41e-6 the maps depart from the ideal as the paper's do: larger and growing with |sigma| for
  // pincushion; smaller at 6.3e-5 and larger again at 2e-4 (where the bow tie turns) for barrel. Departures at
  // |sigma| >= 6.3e-5 are at least ten times that at 1.41e-6. (Paper: the same signs, Table VII against 12.507 D
  // and 6.938 D.)
  const auto pv = [&](size_t i, bool tangential) {
    const auto& pm = sweep.rows[i].analysis.power;
    return tangential ? pm.pv_tangential_D : pm.pv_axial_D;
  };
  for (bool tangential : {true, false}) {
    SCOPED_TRACE(tangential ? "tangential" : "axial");
    const double ideal = tangential ? sweep.ideal_power.pv_tangential_D : sweep.ideal_power.pv_axial_D;
    EXPECT_GT(pv(0, tangential), pv(1, tangential));
    EXPECT_GT(pv(1, tangential), pv(2, tangential));
    EXPECT_GT(pv(2, tangential), ideal);
    EXPECT_LT(pv(5, tangential), ideal);
    EXPECT_GT(pv(6, tangential), ideal);
    const double small = std::max(std::abs(pv(2, tangential) - ideal), std::abs(pv(4, tangential) - ideal));
    for (size_t i : {0u, 1u, 5u, 6u}) EXPECT_GT(std::abs(pv(i, tangential) - ideal), 10 * small) << "row " << i;
  }
}

}  // namespace
}  // namespace topocal::topo

namespace topocal::topo {
namespace {

// A Monte Carlo draw starts from the nominal analysis (its slope-fit factor, its surface, its fit) and skips what it
// does not read; what it does compute must be the cold analysis' result to the refinement's tolerance. The draw
// here: the paper cornea at sigma = 6.3e-5, every spot moved radially on the detection plane by `move_mm`.
struct WarmAndCold {
  Analysis warm, cold;
};
WarmAndCold WarmAndColdDraw(double move_mm) {
  const model::Config config = PaperConfig();
  const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
  const auto nominal_spots = Spots(SimulateSpots(config, 6.3e-5));
  std::vector<model::PlaneSpot> moved = nominal_spots;
  for (auto& s : moved) s.position_mm *= 1.0 + move_mm / std::max(1e-3, s.position_mm.norm());
  AnalysisOptions draw;
  draw.stddev = draw.adequacy = draw.clinical = false;
  const Analysis nominal = AnalyzeSpots(nominal_spots, design.targets, config, nullptr, draw);
  draw.start = &nominal;
  WarmAndCold out{AnalyzeSpots(moved, design.targets, config, nullptr, draw),
                  AnalyzeSpots(moved, design.targets, config, nullptr)};
  const Analysis& warm = out.warm;
  const Analysis& cold = out.cold;
  std::printf(
      "move %.1e mm: refinement passes warm %d / cold %d, fit iterations warm %d / cold %d; |dk| %.1e %.1e, "
      "|dr| %.1e %.1e mm, |dpv| %.1e (axial) %.1e D (tangential)\n",
      move_mm, warm.reconstruction.iterations, cold.reconstruction.iterations, warm.surface_fit.iterations,
      cold.surface_fit.iterations, std::abs(warm.surface_fit.params.kx - cold.surface_fit.params.kx),
      std::abs(warm.surface_fit.params.ky - cold.surface_fit.params.ky),
      std::abs(warm.surface_fit.params.rx_mm - cold.surface_fit.params.rx_mm),
      std::abs(warm.surface_fit.params.ry_mm - cold.surface_fit.params.ry_mm),
      std::abs(warm.power.pv_axial_D - cold.power.pv_axial_D),
      std::abs(warm.power.pv_tangential_D - cold.power.pv_tangential_D));
  // No factorisation of its own, and nothing computed that a draw does not read.
  EXPECT_EQ(warm.reconstruction.slope_fit_factorizations, 0);
  // A cold analysis factors the normal matrix of every refinement pass's own points (cheaper than CGLS
  // with the first pass' factor).
  EXPECT_EQ(cold.reconstruction.slope_fit_factorizations, cold.reconstruction.iterations);
  EXPECT_EQ(warm.reconstruction.expected_slope_noise, 0.0);
  EXPECT_FALSE(warm.surface_fit.stddev_ok);
  EXPECT_FALSE(warm.clinical_ok);
  EXPECT_TRUE(cold.surface_fit.stddev_ok);
  EXPECT_GT(cold.reconstruction.expected_slope_noise, 0.0);
  return out;
}

void ExpectAgreement(const Analysis& warm, const Analysis& cold, double conic_tol, double radius_tol_mm,
                     double power_tol_D) {
  EXPECT_NEAR(warm.surface_fit.params.kx, cold.surface_fit.params.kx, conic_tol);
  EXPECT_NEAR(warm.surface_fit.params.ky, cold.surface_fit.params.ky, conic_tol);
  EXPECT_NEAR(warm.surface_fit.params.rx_mm, cold.surface_fit.params.rx_mm, radius_tol_mm);
  EXPECT_NEAR(warm.surface_fit.params.ry_mm, cold.surface_fit.params.ry_mm, radius_tol_mm);
  EXPECT_NEAR(warm.power.pv_axial_D, cold.power.pv_axial_D, power_tol_D);
  EXPECT_NEAR(warm.power.pv_tangential_D, cold.power.pv_tangential_D, power_tol_D);
}

// The warm draw refines its incidence points from the nominal surface, the cold one from the design sphere: both
// stop when no point moves by more than convergence_um (1e-4 um), so they agree to what that tolerance leaves, not
// bit for bit. Acceptance: far below the clinical numbers' own Monte Carlo uncertainty on the demo unit (U(k) ~
// 1.9e-4, U(r_x) ~ 1.4e-5 mm, U(pv_t) ~ 3e-3 D): 1/100 of it.
constexpr double kConicLimit = 2e-6, kRadiusLimitMm = 1.4e-7, kPowerLimitD = 3e-5;

// Spots moved by 0.5 um (0.45 px), ~500 times what a calibration draw of the demo unit moves them (its first
// refinement pass moves the incidence points by 12 nm, median of the 400 draws; here by 6.9 um). The refinement
// contracts by ~0.05 per pass, so from 6.9 um it needs 5 passes, from the design sphere (260 um away) 6.
TEST(AnalysisStart, AWarmStartedDrawAgreesWithAColdAnalysis) {
  const auto [warm, cold] = WarmAndColdDraw(0.5e-3);
  // Regression bounds near what is measured (2026-12-02: |dk| 3.0e-8, |dr| 1.7e-8 mm, |dpv| 3.2e-7 (axial) /
  // 3.9e-6 D (tangential); with the sphere start for both, 2026-12-01, it was 9e-14, 4e-14 mm and 1.9e-11 D).
  ExpectAgreement(warm, cold, kConicLimit, kRadiusLimitMm, kPowerLimitD);
  ExpectAgreement(warm, cold, 1e-7, 5e-8, 1e-5);
  // What the start saves: refinement passes (from the nominal surface, not the sphere) and fit
  // iterations (Gauss-Newton from the nominal fit instead of the quadratic guess; measured 4 against 6: the warm
  // solver options stop at the first rounding-level step, where they took 20 while Ceres rejected that step and
  // shrank its trust region from 1e16).
  EXPECT_LT(warm.reconstruction.iterations, cold.reconstruction.iterations);
  EXPECT_LE(warm.surface_fit.iterations, 4);
  EXPECT_LT(warm.surface_fit.iterations, cold.surface_fit.iterations);
}

// A draw's size: spots moved by 1 nm on the detection plane (the first refinement pass then moves the incidence
// points by 14 nm, as in the demo unit's draws; the third by 1.01e-4 um, just above convergence_um, so 4 passes).
TEST(AnalysisStart, ADrawSizedMoveTakesFewerPassesAndIterations) {
  const auto [warm, cold] = WarmAndColdDraw(1e-6);
  // Regression bounds near what is measured (2026-12-02: see the printed line).
  ExpectAgreement(warm, cold, kConicLimit, kRadiusLimitMm, kPowerLimitD);
  ExpectAgreement(warm, cold, 1e-7, 5e-8, 1e-5);
  EXPECT_LE(warm.reconstruction.iterations, 4);
  EXPECT_LT(warm.reconstruction.iterations, cold.reconstruction.iterations);
  EXPECT_LE(warm.surface_fit.iterations, 3);
}

}  // namespace
}  // namespace topocal::topo
