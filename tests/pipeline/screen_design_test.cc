// The null screen designed for a goal (pipeline/screen_design.h, docs/screen-design.md): the optimiser beats the
// paper's screen on its map-error goal within the spacing constraint, refuses goals nothing meets with the key to
// blame, reads its goal strictly, and its spot-image model holds against an exact trace of the spot outlines.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "model/config.h"
#include "model/null_screen.h"
#include "model/null_screen_layout.h"
#include "pipeline/screen_design.h"
#include "util/io.h"

namespace topocal::pipeline {
namespace {

ScreenDesignOptions Jobs(int jobs) {
  ScreenDesignOptions o;
  o.jobs = jobs;
  return o;
}

model::Config Paper() { return model::LoadConfig(std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json"); }

// A small goal: the worst ablation of the set (the paper's screen: 1.87 D tangential RMS, docs/reconstruction.md)
// and the steep cone, over a 2 x 3 grid, exact spots reconstructed with the configuration's knots.
ScreenDesignGoal SmallGoal() {
  ScreenDesignGoal g;
  g.corneas = {"lasik-hyperopic-6D", "kc-33um-0.85mm"};
  g.rings = {12, 16, 18};
  g.eta = {6, 8};
  g.spline_spacing_mm = {};
  g.spot_noise_px = 0.0;
  return g;
}

TEST(ScreenDesign, BeatsThePaperScreenOnTheGoalWithinTheSpacingConstraint) {
  const auto goal = SmallGoal();
  const auto r = OptimizeScreenDesign(Paper(), goal, Jobs(1));
  ASSERT_TRUE(r.chosen) << r.why;
  const auto& paper = r.candidates.front();
  ASSERT_TRUE(paper.base);
  EXPECT_EQ(paper.spots, 624);
  const auto& chosen = r.candidates[*r.chosen];
  // Acceptance: better than the paper's screen on the stated goal (the worst cornea's tangential RMS), with every
  // spot image resolvable at the steepest cornea of the range and the chosen spot no smaller than allowed.
  EXPECT_LT(chosen.worst_tangential_rms_D, paper.worst_tangential_rms_D);
  EXPECT_GE(chosen.min_gap_steep_px, goal.min_gap_px);
  EXPECT_GE(chosen.min_gap_flat_px, chosen.min_gap_steep_px);  // flatter corneas image the pattern larger
  EXPECT_GE(chosen.min_gap_corneas_px, goal.min_gap_px);       // and so do the goal's own corneas
  EXPECT_GE(chosen.ideal.spot_radius_um, goal.min_spot_radius_um);
  EXPECT_LE(chosen.steepest_resolved_mm, goal.steepest_radius_mm);
  EXPECT_TRUE(chosen.refused.empty());
  // The written configuration is the chosen design on the base topographer, measured with the goal's surface model.
  EXPECT_EQ(r.config.ideal_image.rings_N, chosen.ideal.rings_N);
  EXPECT_EQ(r.config.ideal_image.spot_radius_um, chosen.ideal.spot_radius_um);
  EXPECT_EQ(r.config.reconstruction.surface_model, "spline");
  // Regression (measured 2026-12-07): paper 1.87 D (lasik-hyperopic-6D); chosen 18 rings x 8, 1368 spots, spot radius
  // 4.68 um (4.51 px at 6.5 mm, 4.94 px on the corneas), worst 0.82 D (the same ablation), resolves from 6.49 mm;
  // 18 rings x 6 (0.82 D too) is refused: the pattern matcher finds no identity on the +6 D ablation's spots.
  EXPECT_NEAR(paper.worst_tangential_rms_D, 1.87, 0.05);
  EXPECT_EQ(chosen.ideal.rings_N + 1, 18);
  EXPECT_EQ(chosen.ideal.eta, 8);
  EXPECT_LT(chosen.worst_tangential_rms_D, 0.90);
  EXPECT_NEAR(chosen.ideal.spot_radius_um, 4.68, 0.02);
  EXPECT_NEAR(chosen.min_gap_steep_px, goal.min_gap_px, 0.05);
  EXPECT_GT(chosen.identified_share, 0.5);  // measured 0.532 (the +6 D ablation); the rest is left unidentified
}

// The knots are part of the design: a dense screen's ablation blend needs finer knots than the paper's 0.33 mm, and
// the chosen spacing is the written configuration's.
TEST(ScreenDesign, ADenseScreenTakesTheFinerKnotsItCarries) {
  auto goal = SmallGoal();
  goal.corneas = {"lasik-hyperopic-6D"};
  goal.rings = {26};
  goal.eta = {6};
  goal.spline_spacing_mm = {0.33, 0.15};
  const auto r = OptimizeScreenDesign(Paper(), goal, Jobs(2));
  ASSERT_TRUE(r.chosen) << r.why;
  ASSERT_EQ(r.candidates.size(), 3u);  // the paper's screen, then 26 rings x 6 with each spacing
  const auto& coarse = r.candidates[1];
  const auto& chosen = r.candidates[*r.chosen];
  EXPECT_EQ(coarse.spline_spacing_mm, 0.33);
  EXPECT_EQ(chosen.spline_spacing_mm, 0.15);
  EXPECT_EQ(r.config.reconstruction.spline_spacing_mm, 0.15);
  EXPECT_NE(r.why.find("knots every 0.15 mm"), std::string::npos) << r.why;
  // Acceptance: the issue's 0.25 D tangential RMS on the +6 D hyperopic ablation from exact spots. Regression
  // (measured 2026-12-07): 0.216 D with 0.15 mm knots, 0.69 D with 0.33 mm on the same 2,106 spots.
  EXPECT_LE(chosen.worst_tangential_rms_D, 0.25);
  EXPECT_NEAR(chosen.worst_tangential_rms_D, 0.216, 0.02);
  EXPECT_NEAR(coarse.worst_tangential_rms_D, 0.69, 0.05);
}

// An ablation's blend crowds the spots more than the steepest sphere of the range: on a dense screen it, not the
// sphere, sets the spot's size, so that the detector's centres are not pulled by their neighbours' light.
TEST(ScreenDesign, TheCorneaThatCrowdsTheSpotsMostSetsTheirSize) {
  auto goal = SmallGoal();
  goal.corneas = {"lasik-myopic-6D"};
  goal.rings = {26};
  goal.eta = {6};
  goal.spline_spacing_mm = {0.33};
  const auto r = OptimizeScreenDesign(Paper(), goal, Jobs(2));
  ASSERT_EQ(r.candidates.size(), 2u);
  const auto& dense = r.candidates[1];
  ASSERT_TRUE(dense.refused.empty()) << dense.refused;
  // Acceptance: every gap, on the sphere and on the ablation, at least min_gap_px; the ablation's the tighter.
  // Regression (measured 2026-12-07): 2.70 um spots, 4.51 px on the ablation, 5.42 px at 6.5 mm (the sphere alone
  // allowed 3.93 um spots at 3 px).
  EXPECT_GE(dense.min_gap_corneas_px, goal.min_gap_px);
  EXPECT_GT(dense.min_gap_steep_px, dense.min_gap_corneas_px + 0.5);
  EXPECT_NEAR(dense.min_gap_corneas_px, goal.min_gap_px, 0.05);
  EXPECT_NEAR(dense.ideal.spot_radius_um, 2.70, 0.02);
  // Spots the ablation cannot hold apart at min_gap_px are refused naming it.
  goal.min_spot_radius_um = 3.0;
  const auto refused = OptimizeScreenDesign(Paper(), goal, Jobs(2));
  EXPECT_EQ(refused.candidates[1].refused.rfind("min_spot_radius_um: spots of 2.7 um at most leave 4.5 px on "
                                                "lasik-myopic-6D", 0), 0u)
      << refused.candidates[1].refused;
}

// A design whose lattice the pattern matcher cannot read on an eye of the goal is refused, naming the eye: the
// matcher is given the eye's exact spots, as a capture's, and its identities are compared with the truth.
TEST(ScreenDesign, ADesignThePatternMatcherCannotReadIsRefused) {
  auto goal = SmallGoal();
  goal.corneas = {"lasik-hyperopic-6D"};
  goal.rings = {20};
  goal.eta = {6};
  goal.spline_spacing_mm = {0.33};
  const auto r = OptimizeScreenDesign(Paper(), goal, Jobs(2));
  ASSERT_EQ(r.candidates.size(), 2u);
  // The paper's screen: every identity given is right (87 % of the spots identified: measured 0.873).
  EXPECT_TRUE(r.candidates[0].refused.empty()) << r.candidates[0].refused;
  EXPECT_NEAR(r.candidates[0].identified_share, 0.873, 0.01);
  // 20 rings x 6: the lattice the matcher grows on the +6 D blend slips and its checks refuse it whole
  // (correct/spot_index_test.cc); the candidate is refused before any reconstruction.
  const auto& unread = r.candidates[1];
  EXPECT_EQ(unread.refused, "identification: the pattern matcher finds no identity on lasik-hyperopic-6D");
  EXPECT_EQ(unread.identified_share, 0.0);
  EXPECT_TRUE(std::isnan(unread.worst_tangential_rms_D));
}

// The noise a candidate is measured with is the goal's for spots of max_spot_radius_um, larger for smaller spots as
// 1 / radius, and it raises the map error.
TEST(ScreenDesign, SmallerSpotsAreMeasuredWithTheirLargerNoise) {
  auto goal = SmallGoal();
  goal.corneas = {"lasik-myopic-4D"};
  goal.rings = {22};
  goal.eta = {6};
  goal.spline_spacing_mm = {0.2};
  const auto exact = OptimizeScreenDesign(Paper(), goal, Jobs(2));
  goal.spot_noise_px = 0.04;
  const auto noisy = OptimizeScreenDesign(Paper(), goal, Jobs(2));
  ASSERT_EQ(noisy.candidates.size(), 2u);
  const auto& paper = noisy.candidates[0];
  const auto& dense = noisy.candidates[1];
  EXPECT_DOUBLE_EQ(paper.spot_noise_px, 0.04);  // the paper's spots are max_spot_radius_um
  EXPECT_DOUBLE_EQ(dense.spot_noise_px, 0.04 * goal.max_spot_radius_um / dense.ideal.spot_radius_um);
  EXPECT_EQ(exact.candidates[1].spot_noise_px, 0.0);
  // Regression (measured 2026-12-07): 22 rings x 6 with 0.2 mm knots, myopic -4 D, 0.20 D exact, 0.31 D at 0.058 px.
  EXPECT_GT(dense.worst_tangential_rms_D, exact.candidates[1].worst_tangential_rms_D);
  EXPECT_NEAR(exact.candidates[1].worst_tangential_rms_D, 0.20, 0.03);
  EXPECT_NEAR(dense.worst_tangential_rms_D, 0.31, 0.05);
}

TEST(ScreenDesign, TheResultDoesNotDependOnTheThreadCount) {
  auto goal = SmallGoal();
  goal.corneas = {"kc-33um-0.85mm"};
  goal.rings = {12, 14};
  const auto one = OptimizeScreenDesign(Paper(), goal, Jobs(1));
  const auto two = OptimizeScreenDesign(Paper(), goal, Jobs(2));
  EXPECT_EQ(ScreenDesignTable(one, goal), ScreenDesignTable(two, goal));
  ASSERT_EQ(one.candidates.size(), two.candidates.size());
  for (size_t i = 0; i < one.candidates.size(); ++i) {
    EXPECT_EQ(one.candidates[i].tangential_rms_D, two.candidates[i].tangential_rms_D) << i;
  }
}

TEST(ScreenDesign, AGoalNoDesignResolvesIsRefusedNamingTheKey) {
  auto goal = SmallGoal();
  // A 1180 x 885 sensor (3.8 um pixels: the paper's spots 6 px apart, docs/spot-noise.md) and spots no smaller
  // than the paper's: the sparsest candidate, 12 rings x 6, leaves 4.5 px on the 33 um cone with spots of 3.1 um
  // at most.
  goal.pixel_pitch_um = 3.8;
  goal.min_spot_radius_um = 8.0;
  const auto r = OptimizeScreenDesign(Paper(), goal, Jobs(1));
  EXPECT_FALSE(r.chosen);
  EXPECT_EQ(r.why.rfind("min_spot_radius_um: spots of 3.1 um at most leave 4.5 px on kc-33um-0.85mm", 0), 0u) << r.why;
  EXPECT_NE(r.why.find("no candidate of the grid resolves and prints"), std::string::npos) << r.why;
  for (const auto& c : r.candidates) {
    EXPECT_FALSE(c.refused.empty());
    EXPECT_TRUE(std::isnan(c.worst_tangential_rms_D));  // refused before any reconstruction
  }
}

TEST(ScreenDesign, AMapErrorNoDesignReachesIsRefusedNamingTheKey) {
  auto goal = SmallGoal();
  goal.corneas = {"lasik-hyperopic-6D"};
  goal.rings = {12};
  goal.max_tangential_rms_D = 0.25;  // the accuracy target: no screen of this grid holds the +6 D blend to it
  const auto r = OptimizeScreenDesign(Paper(), goal, Jobs(1));
  EXPECT_FALSE(r.chosen);
  EXPECT_EQ(r.why.rfind("max_tangential_rms_D: no candidate that resolves and prints meets 0.25 D", 0), 0u) << r.why;
}

TEST(ScreenDesign, ATargetTakesTheFewestSpotsThatMeetIt) {
  auto goal = SmallGoal();
  goal.corneas = {"kc-33um-0.85mm"};
  goal.max_tangential_rms_D = 0.14;  // 12 rings: 0.15 D; 16 and 18 rings: 0.10, 0.08 D (measured 2026-12-07)
  const auto r = OptimizeScreenDesign(Paper(), goal, Jobs(1));
  ASSERT_TRUE(r.chosen) << r.why;
  const auto& chosen = r.candidates[*r.chosen];
  EXPECT_LE(chosen.worst_tangential_rms_D, 0.14);
  for (const auto& c : r.candidates) {
    if (c.refused.empty() && c.worst_tangential_rms_D <= 0.14) {
      EXPECT_GE(c.spots, chosen.spots);
    }
  }
}

TEST(ScreenDesignGoal, ReadsEveryKeyAndRefusesBadOnesNamingThem) {
  const auto g = ParseScreenDesignGoal(
      R"({"corneas": ["lasik-myopic-2D"], "max_tangential_rms_D": 0.5, "surface_model": "auto",
          "steepest_radius_mm": 7.0, "flattest_radius_mm": 8.5, "pixel_pitch_um": 1.4, "min_gap_px": 2.5,
          "max_spot_radius_um": 7.0, "min_spot_radius_um": 3.0, "min_printed_feature_mm": 0.1,
          "max_page_mm": [420, 297], "rings": [12, 13], "eta": [7], "spline_spacing_mm": [0.3, 0.2],
          "spot_noise_px": 0.05})",
      "g.json");
  EXPECT_EQ(g.corneas, std::vector<std::string>{"lasik-myopic-2D"});
  EXPECT_EQ(g.max_tangential_rms_D, 0.5);
  EXPECT_EQ(g.surface_model, "auto");
  EXPECT_EQ(g.steepest_radius_mm, 7.0);
  EXPECT_EQ(g.flattest_radius_mm, 8.5);
  EXPECT_EQ(g.pixel_pitch_um, 1.4);
  EXPECT_EQ(g.min_gap_px, 2.5);
  EXPECT_EQ(g.max_spot_radius_um, 7.0);
  EXPECT_EQ(g.min_spot_radius_um, 3.0);
  EXPECT_EQ(g.min_printed_feature_mm, 0.1);
  EXPECT_EQ(g.max_page_mm, (std::vector<double>{420, 297}));
  EXPECT_EQ(g.rings, (std::vector<int>{12, 13}));
  EXPECT_EQ(g.eta, std::vector<int>{7});
  EXPECT_EQ(g.spline_spacing_mm, (std::vector<double>{0.3, 0.2}));
  EXPECT_EQ(g.spot_noise_px, 0.05);
  EXPECT_FALSE(ParseScreenDesignGoal("{}", "g.json").max_tangential_rms_D);  // defaults: the lowest error
  const auto refusal = [](const std::string& text) {
    try {
      ParseScreenDesignGoal(text, "g.json");
    } catch (const util::ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_EQ(refusal(R"({"corneas": ["kc-99um"]})").rfind("g.json: corneas[0]: no test cornea named \"kc-99um\"", 0), 0u);
  EXPECT_EQ(refusal(R"({"ring": [12]})"), "g.json: ring: unknown key");
  EXPECT_EQ(refusal(R"({"steepest_radius_mm": 9, "flattest_radius_mm": 8})").rfind("g.json: flattest_radius_mm:", 0), 0u);
  EXPECT_EQ(refusal(R"({"rings": [100], "eta": [64]})").rfind("g.json: rings:", 0), 0u);
  EXPECT_EQ(refusal(R"({"rings": [30], "eta": [20]})").rfind("g.json: rings, eta: the densest candidate", 0), 0u);
  EXPECT_EQ(refusal(R"({"max_page_mm": [210]})").rfind("g.json: max_page_mm:", 0), 0u);
  EXPECT_EQ(refusal(R"({"surface_model": "cubic"})").rfind("g.json: surface_model:", 0), 0u);
  EXPECT_EQ(refusal(R"({"spline_spacing_mm": [0.05]})").rfind("g.json: spline_spacing_mm: each must lie in", 0), 0u);
  EXPECT_EQ(refusal(R"({"spline_spacing_mm": []})").rfind("g.json: spline_spacing_mm: must hold at least one", 0), 0u);
  EXPECT_EQ(refusal(R"({"spline_spacing_mm": ["fine"]})").rfind("g.json: spline_spacing_mm[0]: must be a number", 0),
            0u);
  EXPECT_EQ(refusal(R"({"spot_noise_px": -0.1})").rfind("g.json: spot_noise_px: must lie in [0, 1]", 0), 0u);
  const std::string grid =
      "g.json: rings, eta, spline_spacing_mm: the grid must hold 1 to 60 candidates (got 8 x 2 x 4)";
  EXPECT_EQ(refusal(R"({"rings": [12, 14, 16, 18, 20, 22, 24, 26], "eta": [6, 8]})").rfind(grid, 0), 0u);
}

// data/screen-design-goal.json spells out the built-in defaults (docs/screen-design.md): the two stay equal.
TEST(ScreenDesignGoal, TheBundledGoalIsTheDefault) {
  const auto file = LoadScreenDesignGoal(std::string(TOPOCAL_SOURCE_DIR) + "/data/screen-design-goal.json");
  const ScreenDesignGoal d;
  EXPECT_EQ(file.corneas, d.corneas);
  EXPECT_EQ(file.max_tangential_rms_D, d.max_tangential_rms_D);
  EXPECT_EQ(file.surface_model, d.surface_model);
  EXPECT_EQ(file.steepest_radius_mm, d.steepest_radius_mm);
  EXPECT_EQ(file.flattest_radius_mm, d.flattest_radius_mm);
  EXPECT_EQ(file.pixel_pitch_um, d.pixel_pitch_um);
  EXPECT_EQ(file.min_gap_px, d.min_gap_px);
  EXPECT_EQ(file.max_spot_radius_um, d.max_spot_radius_um);
  EXPECT_EQ(file.min_spot_radius_um, d.min_spot_radius_um);
  EXPECT_EQ(file.min_printed_feature_mm, d.min_printed_feature_mm);
  EXPECT_EQ(file.max_page_mm, d.max_page_mm);
  EXPECT_EQ(file.rings, d.rings);
  EXPECT_EQ(file.eta, d.eta);
  EXPECT_EQ(file.spline_spacing_mm, d.spline_spacing_mm);
  EXPECT_EQ(file.spot_noise_px, d.spot_noise_px);
}

// The spot image taken as its ideal circle scaled by the pair's magnification (SpotSpacingAt) against the exact
// image: every outline point of every spot traced to the cone (model::LayoutNullScreen) and imaged back through a
// steep cornea (Eq. 15 solved per point), the smallest distance between neighbouring outlines.
TEST(ScreenDesign, TheSpotImageModelHoldsAgainstAnExactTraceOfTheOutlines) {
  constexpr double kSteepMm = 6.5, kPitchUm = 1.12;
  auto ideal = Paper().ideal_image;
  ideal.rings_N = 17;
  ideal.eta0 = ideal.eta = 6;
  ideal.spot_radius_um = 7.34;
  const auto topographer = Paper().topographer;
  const auto model_spacing = SpotSpacingAt(ideal, topographer, kSteepMm, kPitchUm, 3.0);
  ASSERT_TRUE(model_spacing);

  const model::Topographer topo{topographer};
  const model::Sphere steep{kSteepMm};
  model::NullScreenLayoutOptions layout_options;
  layout_options.outline_points = 32;
  const auto layout = model::LayoutNullScreen(ideal, topographer, layout_options);
  ASSERT_TRUE(layout.failures.empty());
  std::vector<Eigen::Vector2d> centre;
  std::vector<std::vector<Eigen::Vector2d>> outline;
  for (const auto& o : layout.outlines) {
    const auto p2 = model::SolveReflectionPoint(steep, topo, o.target_on_cone_mm, Eigen::Vector2d::Zero());
    ASSERT_TRUE(p2);
    centre.push_back(topo.ImageOf(*p2));
    outline.emplace_back();
    for (const auto& q : o.on_cone_mm) {
      const auto p = model::SolveReflectionPoint(steep, topo, q, p2->head<2>());
      ASSERT_TRUE(p);
      outline.back().push_back(topo.ImageOf(*p));
    }
  }
  double spacing_um = std::numeric_limits<double>::infinity(), gap_um = spacing_um;
  for (size_t a = 0; a < centre.size(); ++a) {
    for (size_t b = a + 1; b < centre.size(); ++b) {
      const double d = (centre[a] - centre[b]).norm() * 1e3;
      spacing_um = std::min(spacing_um, d);
      if (d > 3.0 * model_spacing->min_spacing_um) continue;  // not a neighbour
      for (const auto& p : outline[a]) {
        for (const auto& q : outline[b]) gap_um = std::min(gap_um, (p - q).norm() * 1e3);
      }
    }
  }
  // The centres are the same solve (nearest pair over all pairs against over the neighbour pairs): to rounding. The
  // gap: the model takes the spot image for a circle scaled by one magnification; acceptance 10 % of the 3 px the
  // detector needs. Regression (measured 2026-12-07): exact 3.010990 px, model 3.010973 px (the chain sphere -> cone
  // -> steeper sphere is locally a similarity to 2e-5 px over a spot).
  EXPECT_NEAR(model_spacing->min_spacing_um, spacing_um, 1e-9);
  EXPECT_NEAR(model_spacing->min_gap_px, gap_um / kPitchUm, 0.3);
  EXPECT_NEAR(model_spacing->min_gap_px, gap_um / kPitchUm, 1e-3);
}

}  // namespace
}  // namespace topocal::pipeline
