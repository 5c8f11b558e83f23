// The harness: configuration parsing and its refusals, the physics of one case against the paper's sweep and of
// assembly cases against an independent model's table, deterministic sharding (merged shards == single run, byte
// for byte) and the inverse answers (distortion, and per assembly axis).
#include "harness/harness.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "harness/harness_answer.h"
#include "harness/harness_config.h"
#include "harness/harness_report.h"
#include "plot/scatter_plot.h"
#include "topo/sweep.h"
#include "util/io.h"

namespace {

using namespace topocal;
using harness::AssemblyAxis;
using harness::DistortionFamily;

const std::string kPaper = std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json";

// Two identical spot sets reconstruct identically up to the solvers' own convergence: the iterative
// reconstruction stops when no point moves more than 1e-4 um, which moves k by ~1e-7; 1e-6 leaves a decade.
constexpr double kSameSpotsDk = 1e-6;
constexpr double kSameSpotsDP_D = 1e-4;  // the same convergence in power: ~1e-5 D
// The e = -1 (uncorrected) case is the sweep's row of the same sigma: the same spots through the same code.
constexpr double kSameComputation = 1e-12;
// ... except the biconic fit, which a harness case starts from its cornea's truth fit (the sweep from the quadratic
// guess): both stop within the fit's tolerances of the same optimum. Measured 5.8e-11 in k_x, 8.6e-12 in k_y
// (2026-12-02, docs/performance.md); the bound leaves a factor 3.
constexpr double kSameFitDk = 2e-10;

std::string SmallConfig(const std::string& extra = "") {
  return fmt::format(R"({{"design": "{}", "seed": 7,
    "distortion": {{"seidel_sigma_per_mm2": [6.3e-5], "brown_k2": [300]}},
    "noise_px": [0, 0.1], "noise_draws": 2, "calibration_errors": [-1, 0, 0.1],
    "limits": {{"dk": 0.05, "dP_D": 0.25}}{}}})",
                     kPaper, extra);
}

harness::HarnessConfig Parse(const std::string& text) { return harness::ParseHarnessConfig(text, "H.json", ""); }

// The message of the ConfigError that parsing `text` throws ("" if it does not throw).
std::string Refusal(const std::string& text) {
  try {
    Parse(text);
  } catch (const util::ConfigError& e) {
    return e.what();
  }
  return "";
}

std::string Replace(std::string s, const std::string& from, const std::string& to) {
  const auto at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) s.replace(at, from.size(), to);
  return s;
}

TEST(HarnessConfig, RangesExpandAndTheCanonicalFormRoundTrips) {
  const auto h = Parse(Replace(SmallConfig(), "[6.3e-5]",
                               R"({"from": 1e-6, "to": 1e-4, "count": 3, "spacing": "log", "both_signs": true})"));
  ASSERT_EQ(h.seidel_sigma_per_mm2.size(), 6u);
  EXPECT_DOUBLE_EQ(h.seidel_sigma_per_mm2[0], -1e-4);
  EXPECT_DOUBLE_EQ(h.seidel_sigma_per_mm2[1], -1e-5);
  EXPECT_DOUBLE_EQ(h.seidel_sigma_per_mm2[3], 1e-6);
  EXPECT_EQ(h.seidel_sigma_per_mm2[5], 1e-4);  // the stated end exactly
  ASSERT_EQ(h.corneas.size(), 1u);
  EXPECT_EQ(h.corneas[0].name, "design");
  // A list may mix numbers and ranges: concatenated in order.
  const auto mixed = Parse(Replace(SmallConfig(), "[6.3e-5]", R"([0, {"from": 1, "to": 3, "count": 3}, 7])"));
  EXPECT_EQ(mixed.seidel_sigma_per_mm2, (std::vector<double>{0, 1, 2, 3, 7}));
  EXPECT_NE(Refusal(Replace(SmallConfig(), "[6.3e-5]", R"([0, {"from": 1, "to": 3}])"))
                .find("H.json: distortion.seidel_sigma_per_mm2[1].count: missing"),
            std::string::npos);
  const std::string canonical = harness::CanonicalHarnessJson(h);
  const auto again = Parse(canonical);
  EXPECT_EQ(harness::CanonicalHarnessJson(again), canonical);
  EXPECT_EQ(harness::HarnessConfigSha256(again).size(), 64u);
}

TEST(HarnessConfig, RefusesEveryInvalidRangeNamingTheKey) {
  const std::string ok = SmallConfig();
  ASSERT_EQ(Refusal(ok), "");
  const struct {
    std::string from, to, key;
  } cases[] = {
      {"[0, 0.1]", "[]", "noise_px"},
      {"[0, 0.1]", "[0, -0.1]", "noise_px[1]"},
      {"[0, 0.1]", "[0, \"x\"]", "noise_px[1]"},
      {"[-1, 0, 0.1]", "[-1.5]", "calibration_errors[0]"},
      {"[6.3e-5]", R"({"from": 2, "to": 1, "count": 3})", "distortion.seidel_sigma_per_mm2.from"},
      {"[6.3e-5]", R"({"from": 1, "to": 2, "count": 0})", "distortion.seidel_sigma_per_mm2.count"},
      {"[6.3e-5]", R"({"from": 0, "to": 2, "count": 3, "spacing": "log"})", "distortion.seidel_sigma_per_mm2.from"},
      {"[6.3e-5]", R"({"from": 1, "to": 2, "count": 3, "step": 1})", "distortion.seidel_sigma_per_mm2.step"},
      {"\"noise_draws\": 2", "\"noise_draws\": 0", "noise_draws"},
      {"\"dk\": 0.05", "\"dk\": -1", "limits.dk"},
      {"\"seed\": 7", "\"seed\": 7, \"sed\": 1", "sed"},
      {"\"brown_k2\": [300]", "\"brown_k3\": [300]", "distortion.brown_k3"},
  };
  for (const auto& c : cases) {
    const std::string why = Refusal(Replace(ok, c.from, c.to));
    EXPECT_NE(why.find("H.json: " + c.key + ":"), std::string::npos) << c.to << " -> " << why;
    EXPECT_EQ(why.find('\n'), std::string::npos) << why;
  }
  // A cornea the design's rays cannot image, and a duplicated name.
  EXPECT_NE(Refusal(SmallConfig(R"(, "corneas": [{"rx_mm": 7, "ry_mm": 7, "kx": 40, "ky": 40, "alpha_deg": 0}])"))
                .find("corneas[0]"),
            std::string::npos);
  EXPECT_NE(Refusal(SmallConfig(R"(, "corneas": ["design", "design"])")).find("corneas[1]"), std::string::npos);
  EXPECT_NE(Refusal(SmallConfig(R"(, "corneas": [])")).find("corneas"), std::string::npos);
  // JSON has no infinity: a number beyond double's range is refused, one line naming the file and the key.
  EXPECT_NE(Refusal(Replace(ok, "[0, 0.1]", "[0, 1e999]")).find("H.json: noise_px[]: a number beyond the range"),
            std::string::npos);
}

// An assembly-only sweep: no distortion, no calibration errors (assembly errors are measured uncorrected).
std::string AssemblyConfig(const std::string& assembly, const std::string& noise = "[0]") {
  return fmt::format(R"({{"design": "{}", "seed": 5, "assembly": {}, "noise_px": {},
    "limits": {{"dk": 0.05, "dP_D": 0.25, "dP_maps": "axial"}}}})",
                     kPaper, assembly, noise);
}

TEST(HarnessConfig, AssemblyAxesParseWithDefaultAzimuthsAndEnterTheIdentity) {
  const auto h = Parse(AssemblyConfig(
      R"({"screen_tilt_deg": [0, 1], "a_relative_error": {"from": 0.005, "to": 0.01, "count": 2, "both_signs": true}})"));
  EXPECT_FALSE(h.HasDistortion());
  EXPECT_TRUE(h.HasAssembly());
  EXPECT_EQ(h.Errors(AssemblyAxis::kScreenTilt), (std::vector<double>{0, 1}));
  EXPECT_EQ(h.Errors(AssemblyAxis::kARelative), (std::vector<double>{-0.01, -0.005, 0.005, 0.01}));
  ASSERT_EQ(h.assembly_azimuths_deg.size(), 8u);  // default: every 45 deg
  EXPECT_EQ(h.assembly_azimuths_deg[3], 135);
  const std::string canonical = harness::CanonicalHarnessJson(h);
  EXPECT_NE(canonical.find("\"assembly\""), std::string::npos);
  EXPECT_NE(canonical.find("\"azimuths_deg\""), std::string::npos);
  EXPECT_EQ(canonical.find("calibration_errors"), std::string::npos);
  EXPECT_EQ(harness::CanonicalHarnessJson(Parse(canonical)), canonical);
  // Every assembly value is part of the sweep's identity.
  const auto other = Parse(AssemblyConfig(R"({"screen_tilt_deg": [0, 1.5], "a_relative_error": [0.01]})"));
  const auto azimuths = Parse(AssemblyConfig(R"({"screen_tilt_deg": [0, 1], "azimuths_deg": [0, 90]})"));
  const auto base = Parse(AssemblyConfig(R"({"screen_tilt_deg": [0, 1]})"));
  EXPECT_NE(harness::HarnessConfigSha256(other), harness::HarnessConfigSha256(h));
  EXPECT_NE(harness::HarnessConfigSha256(azimuths), harness::HarnessConfigSha256(base));
  // A configuration without assembly axes keeps its canonical form (and so the identity of existing shards).
  EXPECT_EQ(harness::CanonicalHarnessJson(Parse(SmallConfig())).find("assembly"), std::string::npos);
  // Distortion and assembly together.
  const auto both = Parse(SmallConfig(R"(, "assembly": {"principal_point_offset_mm": [0.01]})"));
  EXPECT_TRUE(both.HasDistortion() && both.HasAssembly());
}

TEST(HarnessConfig, RefusesBadAssemblyValuesNamingTheKey) {
  const struct {
    std::string assembly, key;
  } cases[] = {
      {R"({"screen_tilt_deg": [-1]})", "assembly.screen_tilt_deg[0]"},  // a magnitude: the azimuth is the direction
      {R"({"screen_tilt_deg": {"from": 0.5, "to": 1, "count": 2, "both_signs": true}})", "assembly.screen_tilt_deg[0]"},
      {R"({"screen_tilt_deg": [11]})", "assembly.screen_tilt_deg[0]"},
      {R"({"screen_roll_deg": [1, -10.5]})", "assembly.screen_roll_deg[1]"},
      {R"({"screen_decentration_mm": [0.2, -0.1]})", "assembly.screen_decentration_mm[1]"},
      {R"({"screen_axial_mm": [12]})", "assembly.screen_axial_mm[0]"},
      {R"({"principal_point_offset_mm": [1.5]})", "assembly.principal_point_offset_mm[0]"},
      {R"({"a_relative_error": [0.2]})", "assembly.a_relative_error[0]"},
      {R"({"a_relative_error": ["x"]})", "assembly.a_relative_error[0]"},
      {R"({"screen_tilt_deg": [1], "azimuths_deg": [0, 360]})", "assembly.azimuths_deg[1]"},
      {R"({"screen_tilt_deg": [1], "azimuths_deg": []})", "assembly.azimuths_deg"},
      {R"({"screen_roll_deg": [1], "azimuths_deg": [0]})", "assembly.azimuths_deg"},  // no directional axis
      {R"({"screen_tilt": [1]})", "assembly.screen_tilt"},                            // units in key names
      {R"({})", "assembly"},
      {R"([1])", "assembly"},
  };
  for (const auto& c : cases) {
    const std::string why = Refusal(AssemblyConfig(c.assembly));
    EXPECT_NE(why.find("H.json: " + c.key + ":"), std::string::npos) << c.assembly << " -> " << why;
    EXPECT_EQ(why.find('\n'), std::string::npos) << why;
  }
  // Calibration errors apply to distortion only; a sweep needs some axis.
  const std::string with_errors = Replace(AssemblyConfig(R"({"screen_roll_deg": [1]})"), "\"noise_px\"",
                                          "\"calibration_errors\": [0], \"noise_px\"");
  EXPECT_NE(Refusal(with_errors).find("H.json: calibration_errors:"), std::string::npos) << Refusal(with_errors);
  const std::string neither =
      Replace(AssemblyConfig(R"({"screen_roll_deg": [1]})"), R"("assembly": {"screen_roll_deg": [1]},)", "");
  EXPECT_NE(Refusal(neither).find("H.json: distortion:"), std::string::npos) << Refusal(neither);
}

TEST(HarnessShardSpec, ParsesOnlyIOfN) {
  EXPECT_EQ(util::ParseShardSpec("2/3").index, 2);
  EXPECT_EQ(util::ParseShardSpec("2/3").count, 3);
  for (const char* bad : {"3/3", "0/0", "1", "a/3", "-1/3", "1/", "/3", "1/3/4", " 1/3"}) {
    EXPECT_THROW(util::ParseShardSpec(bad), util::InputError) << bad;
  }
}

TEST(HarnessCase, UncorrectedIsThePaperSweepAndExactCorrectionIsTheTruth) {
  const auto h = Parse(SmallConfig());
  const harness::HarnessCaseRunner runner(h);
  const auto all = harness::EnumerateHarnessCases(h);
  // 2 distortions x 3 calibration errors x (1 + 2 draws) noise cases.
  ASSERT_EQ(all.size(), 18u);
  auto find = [&](DistortionFamily f, double e, double noise) {
    for (const auto& s : all) {
      if (s.family == f && s.calibration_error == e && s.noise_px == noise && s.draw == 0) return s;
    }
    ADD_FAILURE() << "no such case";
    return all.front();
  };
  // e = -1: the spots keep the whole distortion, exactly as in the sweep's row of the same sigma.
  const auto uncorrected = runner.Run(find(DistortionFamily::kSeidelSigma, -1, 0));
  ASSERT_TRUE(uncorrected.ok) << uncorrected.failure;
  auto paper = model::LoadConfig(kPaper);
  paper.distortion.sigmas_per_mm2 = {0.0, 6.3e-5};
  const auto sweep = topo::RunSweep(paper);
  const auto& truth = sweep.rows[0].analysis;
  const auto& distorted = sweep.rows[1].analysis;
  EXPECT_NEAR(uncorrected.dk_x, distorted.surface_fit.params.kx - truth.surface_fit.params.kx, kSameFitDk);
  EXPECT_NEAR(uncorrected.dk_y, distorted.surface_fit.params.ky - truth.surface_fit.params.ky, kSameFitDk);
  EXPECT_NEAR(uncorrected.dpv_axial_D, distorted.power.pv_axial_D - truth.power.pv_axial_D, kSameComputation);
  // Its residual is the Seidel displacement at the edge of the spot field: |sigma / M_T^3| r^3.
  const double r = runner.truth()[0].spot_field_radius_mm;
  EXPECT_NEAR(uncorrected.residual_max_um, 6.3e-5 / std::pow(0.065, 3) * r * r * r * 1e3, 1e-9);
  // e = 0: no residual, and the reconstruction of the truth.
  const auto exact = runner.Run(find(DistortionFamily::kSeidelSigma, 0, 0));
  ASSERT_TRUE(exact.ok);
  EXPECT_LT(exact.residual_max_um, harness::kZeroResidualUm);
  EXPECT_LT(exact.MaxAbsDk(), kSameSpotsDk);
  EXPECT_LT(exact.MaxAbsDP_D(h.limits), kSameSpotsDP_D);
  // e = +0.1: the outermost spot, at r_d = r (1 + c r^2), is undistorted with 1.1 c to r_c (1 + 1.1 c r_c^2) = r_d:
  // about a tenth of the distortion remains, with the opposite sign (0.114 of it at this strength).
  const auto over = runner.Run(find(DistortionFamily::kSeidelSigma, 0.1, 0));
  const double c = 6.3e-5 / std::pow(-0.065, 3);  // M_T < 0: barrel
  const double r_d = r * (1 + c * r * r);
  double r_c = r;
  for (int i = 0; i < 50; ++i) r_c -= (r_c * (1 + 1.1 * c * r_c * r_c) - r_d) / (1 + 3.3 * c * r_c * r_c);
  EXPECT_NEAR(over.residual_max_um, std::abs(r - r_c) * 1e3, 1e-9);
  EXPECT_LT(over.dk_x * uncorrected.dk_x, 0);
  // Noise: the same case twice gives the same draw; another draw differs.
  const auto noisy = find(DistortionFamily::kSeidelSigma, 0, 0.1);
  const auto a = runner.Run(noisy), b = runner.Run(noisy);
  EXPECT_EQ(a.dk_x, b.dk_x);
  EXPECT_GT(a.MaxAbsDk(), 0);
  auto other = noisy;
  other.seed = harness::HarnessCaseSeed(h.seed, noisy.index + 1);
  EXPECT_NE(runner.Run(other).dk_x, a.dk_x);
}

// Assembly cases: the cornea imaged through the as-built device and measured through the nominal one.
TEST(HarnessCase, AssemblyCasesImageThroughTheAsBuiltDeviceAndMeasureUncorrected) {
  const auto h = Parse(AssemblyConfig(R"({"screen_tilt_deg": [0, 1], "screen_axial_mm": [-0.5, 0.5],
      "principal_point_offset_mm": [0.03], "a_relative_error": [0.01], "azimuths_deg": [0, 90, 180]})"));
  const auto all = harness::EnumerateHarnessCases(h);
  // tilt: 0 once, 1 at three azimuths; axial 2; principal point 3 azimuths; a 1.
  ASSERT_EQ(all.size(), 1u + 3u + 2u + 3u + 1u);
  for (const auto& s : all) EXPECT_EQ(s.kind, harness::HarnessCaseKind::kAssembly);
  auto find = [&](AssemblyAxis axis, double value, double azimuth) {
    for (const auto& s : all) {
      if (s.axis == axis && s.error == value && s.azimuth_deg == azimuth) return s;
    }
    ADD_FAILURE() << "no such case";
    return all.front();
  };
  // The as-built devices.
  const auto nominal = harness::HarnessNominalDevice(h);
  EXPECT_EQ(nominal.camera.a_mm, h.design.topographer.a_mm);
  const auto tilted = harness::AssembledDevice(h, find(AssemblyAxis::kScreenTilt, 1, 90));
  EXPECT_NEAR(tilted.screen.rx_deg, 0, 1e-15);
  EXPECT_EQ(tilted.screen.ry_deg, 1);
  const auto offset = harness::AssembledDevice(h, find(AssemblyAxis::kPrincipalPoint, 0.03, 0));
  EXPECT_NEAR(offset.camera.principal_point_px.x() - nominal.camera.principal_point_px.x(), 0.03 / 1.12e-3, 1e-9);
  EXPECT_EQ(harness::AssembledDevice(h, find(AssemblyAxis::kARelative, 0.01, 0)).camera.a_mm,
            h.design.topographer.a_mm * 1.01);

  const harness::HarnessCaseRunner runner(h);
  // The nominal device reproduces the truth reconstruction.
  const auto zero = runner.Run(find(AssemblyAxis::kScreenTilt, 0, 0));
  ASSERT_TRUE(zero.ok) << zero.failure;
  EXPECT_LT(zero.residual_max_um, harness::kZeroResidualUm);
  EXPECT_LT(zero.MaxAbsDk(), kSameSpotsDk);
  EXPECT_LT(zero.MaxAbsDP_D(h.limits), kSameSpotsDP_D);
  EXPECT_EQ(zero.spots_used, runner.truth()[0].spots);
  // A principal-point offset shifts every spot by the offset: 30 um, max and rms.
  const auto pp = runner.Run(find(AssemblyAxis::kPrincipalPoint, 0.03, 0));
  ASSERT_TRUE(pp.ok) << pp.failure;
  EXPECT_NEAR(pp.residual_max_um, 30, 1e-9);
  EXPECT_NEAR(pp.residual_rms_um, 30, 1e-9);
  // The biconic (z(x, y) = z(-x, -y)) and the null screen are symmetric under a half turn about the axis, so an
  // error at azimuth phi + 180 deg gives the same surface as at phi (docs/harness.md: why the bundled sweep uses
  // four azimuths).
  const auto t0 = runner.Run(find(AssemblyAxis::kScreenTilt, 1, 0));
  const auto t180 = runner.Run(find(AssemblyAxis::kScreenTilt, 1, 180));
  ASSERT_TRUE(t0.ok && t180.ok);
  EXPECT_NEAR(t0.dk_x, t180.dk_x, kSameSpotsDk);
  EXPECT_NEAR(t0.dk_y, t180.dk_y, kSameSpotsDk);
  EXPECT_NEAR(t0.dP_axial_max_D, t180.dP_axial_max_D, kSameSpotsDP_D);
  // The issue's table (an independent model): a 1 deg tilt and a 0.03 mm principal point are outside the limits
  // uncorrected (its figures: |dk_y| 0.16-0.18 and 0.04-0.05, axial pv +5.5 and +1.4 D). The sizes depend on the
  // biconic fit (docs/harness.md), so only that is asserted here.
  EXPECT_GT(harness::LimitUtilisation(t0, h.limits), 1);
  EXPECT_GT(harness::LimitUtilisation(pp, h.limits), 1);
  // The rotationally symmetric errors against the issue's table: a 1 % too long a makes the cornea Delta r
  // +0.1 mm flatter; the cone 0.5 mm too near / far changes k_x by -/+0.03 and r by +/-0.2 mm. Acceptance: the
  // issue's figures to their one significant digit; regression: the values measured on 2026-12-01 (6-parameter
  // biconic fit) +-0.003.
  const auto a = runner.Run(find(AssemblyAxis::kARelative, 0.01, 0));
  const auto near = runner.Run(find(AssemblyAxis::kScreenAxial, 0.5, 0));  // tz > 0: towards the eye
  const auto far = runner.Run(find(AssemblyAxis::kScreenAxial, -0.5, 0));
  ASSERT_TRUE(a.ok && near.ok && far.ok);
  constexpr double kRegression = 0.003;
  EXPECT_NEAR(a.dr_x_mm, 0.1, 0.05);
  EXPECT_NEAR(a.dr_x_mm, 0.1075, kRegression);  // measured 0.1075
  EXPECT_NEAR(a.dr_y_mm, 0.1, 0.05);
  EXPECT_NEAR(a.dr_y_mm, 0.0947, kRegression);  // measured 0.0947
  EXPECT_NEAR(near.dk_x, -0.03, 0.01);
  EXPECT_NEAR(near.dk_x, -0.0307, kRegression);  // measured -0.0307
  EXPECT_NEAR(far.dk_x, 0.03, 0.01);
  EXPECT_NEAR(far.dk_x, 0.0322, kRegression);  // measured +0.0322
  EXPECT_NEAR(near.dr_x_mm, 0.2, 0.05);
  EXPECT_NEAR(near.dr_x_mm, 0.2253, kRegression);  // measured +0.2253
  EXPECT_NEAR(far.dr_x_mm, -0.2, 0.05);
  EXPECT_NEAR(far.dr_x_mm, -0.2138, kRegression);  // measured -0.2138
}

// Shards 0/3, 1/3, 2/3 through their JSON files, merged, give byte-identical outputs to a single run, and so does
// a single run on two threads.
TEST(HarnessShards, MergedShardsEqualASingleRunByteForByte) {
  // Distortion and assembly cases together (the assembly cases follow the distortion cases of each cornea).
  const auto h = Parse(SmallConfig(R"(, "assembly": {"screen_tilt_deg": [0, 0.5], "a_relative_error": [0.01],
      "azimuths_deg": [0, 90]})"));
  ASSERT_EQ(harness::EnumerateHarnessCases(h).size(), 18u + 4u * 3u);
  auto outputs = [](const harness::HarnessRun& run) {
    return harness::RenderHarnessOutputs(run, harness::ComputeInverseAnswer(run));
  };
  const auto single = harness::RunHarness(h, {0, 1}, 1);
  std::vector<harness::HarnessRun> shards;
  std::vector<std::string> origins;
  for (int i = 0; i < 3; ++i) {
    const auto shard = harness::RunHarness(h, {i, 3}, 1);
    origins.push_back(harness::HarnessShardFileName({i, 3}));
    shards.push_back(harness::ParseHarnessShard(harness::HarnessShardJson(shard), origins.back()));
  }
  const auto merged =
      harness::MergeHarnessShards({shards[2], shards[0], shards[1]}, {origins[2], origins[0], origins[1]});
  EXPECT_EQ(outputs(merged), outputs(single));
  EXPECT_EQ(outputs(harness::RunHarness(h, {0, 1}, 2)), outputs(single));
  // The outputs hold the assembly answer and its plots.
  const auto files = outputs(single);
  ASSERT_EQ(files.size(), 5u + 2u);
  EXPECT_EQ(files[5].first, "assembly_screen_tilt_deg.svg");
  EXPECT_EQ(files[6].first, "assembly_a_relative_error.svg");
  EXPECT_NE(files[1].second.find("\"assembly_answer\""), std::string::npos);
  EXPECT_NE(files[2].second.find("## Assembly errors of the device (uncorrected)"), std::string::npos);

  // Refusals: a missing shard, a shard given twice, a shard of another configuration.
  EXPECT_THROW(harness::MergeHarnessShards({shards[0], shards[1]}, {origins[0], origins[1]}), util::InputError);
  EXPECT_THROW(harness::MergeHarnessShards({shards[0], shards[1], shards[1]}, {origins[0], origins[1], origins[1]}),
               util::InputError);
  auto other = Parse(Replace(SmallConfig(), "\"seed\": 7", "\"seed\": 8"));
  auto foreign = harness::RunHarness(other, {2, 3}, 1);
  EXPECT_THROW(harness::MergeHarnessShards({shards[0], shards[1], foreign}, {"a", "b", "c"}), util::InputError);
  // A shard file with a case removed is incomplete.
  auto cut = harness::RunHarness(h, {1, 3}, 1);
  cut.cases.pop_back();
  EXPECT_THROW(harness::ParseHarnessShard(harness::HarnessShardJson(cut), "cut.json"), util::InputError);
}

// The answer on constructed cases: one group whose utilisation grows linearly with the residual.
TEST(HarnessAnswer, InterpolatesTheFirstCrossingOfEachGroupAndTakesTheSmallest) {
  harness::HarnessRun run;
  run.config = Parse(SmallConfig());
  run.truth.push_back({});
  run.truth[0].spot_field_radius_mm = 0.4;
  auto add = [&](DistortionFamily f, double e, double residual_um, double dk, double dP) {
    harness::HarnessCaseResult c;
    c.spec.index = static_cast<int>(run.cases.size());
    c.spec.family = f;
    c.spec.coefficient = 1;
    c.spec.calibration_error = e;
    c.ok = true;
    c.residual_max_um = residual_um;
    c.dk_x = dk;
    c.dP_axial_max_D = dP;
    run.cases.push_back(c);
  };
  add(DistortionFamily::kSeidelSigma, 0, 0, 0.001, 0.01);   // anchor: u0 = 0.04
  add(DistortionFamily::kSeidelSigma, -0.1, 1, 0.02, 0.0);  // u = 0.4
  add(DistortionFamily::kSeidelSigma, -0.5, 5, 0.06, 0.0);  // u = 1.2: crossing at 1 + 0.6/0.8 * 4 = 4
  add(DistortionFamily::kSeidelSigma, -1, 10, 0.001, 0.0);  // after the first failure: not used
  add(DistortionFamily::kBrownK2, -1, 8, 0.0, 0.5);         // u = 2 from u0 = 0.04: crossing at 8 * 0.96 / 1.96
  run.total_cases = static_cast<int>(run.cases.size());
  const auto a = harness::ComputeInverseAnswer(run);
  ASSERT_TRUE(a.found);
  EXPECT_NEAR(a.residual_max_um, 8 * 0.96 / 1.96, 1e-12);
  EXPECT_EQ(a.limiting_case, 4);
  EXPECT_EQ(a.limited_by, "dP");
  EXPECT_EQ(a.grid_first_failure_um, 5);
  EXPECT_EQ(a.grid_all_pass_up_to_um, 1);
  ASSERT_EQ(a.families.size(), 2u);
  EXPECT_NEAR(a.families[0].residual_max_um, 4, 1e-12);
  EXPECT_NEAR(a.residual_max_px, a.residual_max_um / run.config.pixel_pitch_um, 1e-12);
  EXPECT_NEAR(a.sigma_equivalent_per_mm2, a.residual_max_um * 1e-3 * std::pow(0.065, 3) / std::pow(0.4, 3), 1e-15);
  EXPECT_EQ(a.cases_outside, 2);

  // One family within the limits throughout while another crosses: no crossing for it, and its answer is the
  // largest residual tested (8 um), finite. Before, the per-family lookup created a crossing at +infinity,
  // reported found = true and wrote residual_max_um null to summary.json ("inf" in table.md).
  run.cases[4].dP_axial_max_D = 0;
  const auto one = harness::ComputeInverseAnswer(run);
  ASSERT_EQ(one.families.size(), 2u);
  EXPECT_TRUE(one.families[0].found);
  EXPECT_FALSE(one.families[1].found);
  EXPECT_EQ(one.families[1].residual_max_um, 8);
  for (const auto& [name, text] : harness::RenderHarnessOutputs(run, one)) {
    EXPECT_EQ(text.find("null"), std::string::npos) << name;
    EXPECT_EQ(text.find("inf "), std::string::npos) << name;
  }
  run.cases[4].dP_axial_max_D = 0.5;

  // Noise alone outside the limits: the answer is 0.
  run.cases[0].dk_x = 0.1;
  const auto none = harness::ComputeInverseAnswer(run);
  EXPECT_TRUE(none.noise_alone_exceeds);
  EXPECT_EQ(none.residual_max_um, 0);
  EXPECT_EQ(none.limiting_case, 0);  // the noise-only case itself
  EXPECT_EQ(none.limited_by, "dk");
  // Nothing outside the limits: the largest residual tested is a lower bound.
  run.cases[0].dk_x = run.cases[2].dk_x = run.cases[4].dP_axial_max_D = 0;
  const auto bound = harness::ComputeInverseAnswer(run);
  EXPECT_FALSE(bound.found);
  EXPECT_EQ(bound.residual_max_um, 10);
}

// The assembly answer on constructed cases: per axis, groups by direction (sign, azimuth), anchored at the
// zero-error case; the distortion answer ignores assembly cases.
TEST(HarnessAnswer, AssemblyAxesAnswerTheirLargestErrorWithinTheLimits) {
  harness::HarnessRun run;
  run.config = Parse(SmallConfig(R"(, "assembly": {"screen_tilt_deg": [0.5, 1], "screen_axial_mm": [-0.2, 0, 0.2],
      "azimuths_deg": [0, 90]})"));
  run.truth.push_back({});
  run.truth[0].spot_field_radius_mm = 0.4;
  auto add = [&](AssemblyAxis axis, double error, double azimuth, double residual_um, double dk, double dP) {
    harness::HarnessCaseResult c;
    c.spec.index = static_cast<int>(run.cases.size());
    c.spec.kind = harness::HarnessCaseKind::kAssembly;
    c.spec.axis = axis;
    c.spec.error = error;
    c.spec.azimuth_deg = azimuth;
    c.ok = true;
    c.residual_max_um = residual_um;
    c.dk_y = dk;
    c.dP_axial_max_D = dP;
    run.cases.push_back(c);
  };
  add(AssemblyAxis::kScreenAxial, 0, 0, 0, 0.0025, 0);    // 0: anchor of every group, u0 = 0.05
  add(AssemblyAxis::kScreenAxial, 0.1, 0, 9, 0.025, 0);   // 1: u = 0.5
  add(AssemblyAxis::kScreenAxial, 0.2, 0, 18, 0.075, 0);  // 2: u = 1.5: crossing 0.1 + 0.5 / 1.0 * 0.1 = 0.15
  add(AssemblyAxis::kScreenAxial, -0.1, 0, 9, 0, 0.2);    // 3: u = 0.8
  add(AssemblyAxis::kScreenAxial, -0.2, 0, 18, 0, 0.35);  // 4: u = 1.4: crossing 0.1 + 0.2 / 0.6 * 0.1
  add(AssemblyAxis::kScreenTilt, 0.5, 0, 14, 0.025, 0);   // 5: u = 0.5
  add(AssemblyAxis::kScreenTilt, 1, 0, 28, 0.1, 0);       // 6: u = 2: crossing 0.5 + 0.5 / 1.5 * 0.5
  add(AssemblyAxis::kScreenTilt, 1, 90, 28, 0.045, 0);    // 7: u = 0.9, another direction: within
  harness::HarnessCaseResult d;                           // 8: a distortion case, u = 2 at 1 um
  d.spec.index = 8;
  d.spec.coefficient = 1;
  d.spec.calibration_error = -1;
  d.ok = true;
  d.residual_max_um = 1;
  d.dk_x = 0.1;
  run.cases.push_back(d);
  run.total_cases = static_cast<int>(run.cases.size());

  const auto a = harness::ComputeInverseAnswer(run);
  // The distortion answer sees the distortion case only (no anchor of its own: from u = 0 at no residual).
  ASSERT_TRUE(a.found);
  EXPECT_NEAR(a.residual_max_um, 0.5, 1e-12);
  EXPECT_EQ(a.max_tested_um, 1);
  EXPECT_EQ(a.limiting_case, 8);
  EXPECT_EQ(a.cases_outside, 4);
  // Per axis, in the order of the axes.
  ASSERT_EQ(a.assembly.size(), 2u);
  const auto& tilt = a.assembly[0];
  EXPECT_EQ(tilt.axis, AssemblyAxis::kScreenTilt);
  ASSERT_TRUE(tilt.found);
  EXPECT_NEAR(tilt.max_error, 0.5 + 0.5 / 1.5 * 0.5, 1e-12);
  EXPECT_EQ(tilt.limiting_case, 6);
  EXPECT_EQ(tilt.limited_by, "dk");
  EXPECT_EQ(tilt.grid_all_pass_up_to, 0.5);
  EXPECT_EQ(tilt.grid_first_failure, 1);
  const auto& axial = a.assembly[1];
  EXPECT_EQ(axial.axis, AssemblyAxis::kScreenAxial);
  ASSERT_TRUE(axial.found);
  EXPECT_NEAR(axial.max_error, 0.1 + 0.2 / 0.6 * 0.1, 1e-12);
  EXPECT_EQ(axial.limiting_case, 4);
  EXPECT_EQ(axial.limited_by, "dP");
  EXPECT_EQ(axial.grid_all_pass_up_to, 0.1);
  EXPECT_EQ(axial.grid_first_failure, 0.2);
  EXPECT_FALSE(axial.noise_alone_exceeds);

  // The nominal device already outside the limits: every axis answers 0, named by the zero-error case.
  run.cases[0].dk_y = 0.06;
  const auto none = harness::ComputeInverseAnswer(run);
  for (const auto& x : none.assembly) {
    EXPECT_EQ(x.max_error, 0) << harness::AssemblyAxisName(x.axis);
    EXPECT_TRUE(x.noise_alone_exceeds);
    EXPECT_EQ(x.limiting_case, 0);
  }
  EXPECT_EQ(none.residual_max_um, 0.5);  // the distortion answer does not use assembly cases
  // Nothing of an axis outside the limits: its largest error tested is a lower bound.
  run.cases[0].dk_y = run.cases[2].dk_y = run.cases[4].dP_axial_max_D = 0;
  const auto bound = harness::ComputeInverseAnswer(run);
  EXPECT_FALSE(bound.assembly[1].found);
  EXPECT_EQ(bound.assembly[1].max_error, 0.2);
  EXPECT_TRUE(bound.assembly[0].found);
  const std::string text = harness::HarnessAnswerText(run, bound);
  EXPECT_NE(text.find("screen_axial_mm: >= 0.2 mm"), std::string::npos) << text;
  EXPECT_NE(text.find("screen_tilt_deg: 0.6667 deg; limited by dk"), std::string::npos) << text;
}

TEST(SvgPlot, DrawsEveryPointAndClampsWhatALogAxisCannotShow) {
  plot::ScatterPlot p;
  p.title = "t < 1";
  p.series.push_back({"a", "#000", {{1e-2, 1e-3}, {10, 0.5}, {0, 1e-2}, {1, 0}}});
  p.horizontal.push_back({0.05, "limit", "#f00"});
  const std::string svg = plot::RenderScatterSvg(p);
  EXPECT_EQ(svg.rfind("<svg", 0), 0u);
  EXPECT_NE(svg.find("t &lt; 1"), std::string::npos);
  size_t circles = 0, hollow = 0;
  for (size_t at = svg.find("<circle"); at != std::string::npos; at = svg.find("<circle", at + 1)) ++circles;
  for (size_t at = svg.find("fill=\"none\"/>"); at != std::string::npos; at = svg.find("fill=\"none\"/>", at + 1))
    ++hollow;
  EXPECT_EQ(circles, 4u + 1u);  // 4 points + 1 legend marker
  EXPECT_EQ(hollow, 2u);
  EXPECT_EQ(svg.find("nan"), std::string::npos);
  EXPECT_EQ(svg.find("inf"), std::string::npos);
}

}  // namespace
