// The harness at a case count where its outputs must summarise (docs/scale-out.md): ~48,000 cases split into 100
// shard files and merged one at a time give the unsplit run's bytes, and the plots stay bounded. The case results
// are constructed (a function of each case's seed), not computed: the merge and the outputs depend only on them, and
// computing 48,000 cases would take ~90 s.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "harness/harness.h"
#include "harness/harness_answer.h"
#include "harness/harness_config.h"
#include "harness/harness_report.h"
#include "util/io.h"

namespace {

using namespace topocal;

const std::string kPaper = std::string(TOPOCAL_SOURCE_DIR) + "/data/paper.json";
constexpr int kShards = 100;
constexpr int kDraws = 8000;          // 2 distortions x 3 calibration errors x (1 + 8000 draws) = 48,006 cases
constexpr size_t kMaxPlotBytes = 300 << 10;  // 5,000 markers of ~45 bytes (~225 KB) and the frame

// A number in [0, 1) from the bits of a case's seed, `k` choosing which.
double Unit(std::uint64_t seed, int k) {
  const std::uint64_t x = (seed ^ (0x9E3779B97F4A7C15ull * static_cast<std::uint64_t>(k + 1))) * 0xBF58476D1CE4E5B9ull;
  return static_cast<double>(x >> 11) * 0x1.0p-53;
}

// A case result as a real one looks: errors growing with the residual, some noise, every 997th reconstruction failed.
harness::HarnessCaseResult ConstructedResult(const harness::HarnessCaseSpec& spec) {
  harness::HarnessCaseResult r;
  r.spec = spec;
  r.spots_used = 624;
  if (spec.index % 997 == 996) {
    r.failure = "constructed failure";
    return r;
  }
  r.ok = true;
  r.residual_max_um = std::abs(spec.calibration_error) * 40 * (0.5 + Unit(spec.seed, 0));
  r.residual_rms_um = 0.5 * r.residual_max_um;
  r.dk_x = 0.02 * r.residual_max_um * (Unit(spec.seed, 1) - 0.5) + 1e-4 * Unit(spec.seed, 2);
  r.dk_y = -0.8 * r.dk_x;
  r.dr_x_mm = 1e-3 * r.residual_max_um;
  r.dr_y_mm = -r.dr_x_mm;
  r.dP_axial_max_D = 0.15 * r.residual_max_um + 0.01 * Unit(spec.seed, 3);
  r.dP_tangential_max_D = 3 * r.dP_axial_max_D;
  r.dpv_axial_D = 0.9 * r.dP_axial_max_D;
  r.dpv_tangential_D = 0.9 * r.dP_tangential_max_D;
  r.compared_radius_mm = 5.3;
  return r;
}

harness::HarnessRun ConstructedRun(const harness::HarnessConfig& config, util::ShardSpec shard) {
  harness::HarnessRun run;
  run.config = config;
  run.config_sha256 = harness::HarnessConfigSha256(config);
  run.shard = shard;
  const auto all = harness::EnumerateHarnessCases(config);
  run.total_cases = static_cast<int>(all.size());
  harness::HarnessTruth truth;
  truth.cornea = "design";
  truth.fit.rx_mm = 7.8;
  truth.fit.ry_mm = 7.7;
  truth.covered_radius_mm = 5.3;
  run.truth = {truth};
  for (const auto& spec : all) {
    if (spec.index % shard.count == shard.index) run.cases.push_back(ConstructedResult(spec));
  }
  return run;
}

TEST(HarnessAtScale, HundredShardFilesMergeIntoTheUnsplitBytesAndThePlotsStayBounded) {
  const auto config = harness::ParseHarnessConfig(
      fmt::format(R"({{"design": "{}", "seed": 7,
        "distortion": {{"seidel_sigma_per_mm2": [6.3e-5], "brown_k2": [300]}},
        "noise_px": [0, 0.1], "noise_draws": {}, "calibration_errors": [-1, 0, 0.1],
        "limits": {{"dk": 0.05, "dP_D": 0.25}}}})",
                  kPaper, kDraws),
      "H.json", "");
  const auto single = ConstructedRun(config, {0, 1});
  ASSERT_EQ(single.total_cases, 6 * (1 + kDraws));
  const auto outputs = harness::RenderHarnessOutputs(single, harness::ComputeInverseAnswer(single));

  harness::HarnessShardMerger merger;
  for (int i = kShards - 1; i >= 0; --i) {  // any order
    const auto name = harness::HarnessShardFileName({i, kShards});
    merger.Add(harness::HarnessShardJson(ConstructedRun(config, {i, kShards})), name);
  }
  const auto merged = merger.Finish();
  EXPECT_EQ(harness::RenderHarnessOutputs(merged, harness::ComputeInverseAnswer(merged)), outputs);

  // Every case is in cases.csv; each plot draws at most 5,000 markers and says so.
  ASSERT_EQ(outputs[0].first, "cases.csv");
  EXPECT_EQ(static_cast<int>(std::count(outputs[0].second.begin(), outputs[0].second.end(), '\n')),
            single.total_cases + 1);
  for (const auto& [name, text] : outputs) {
    if (name.size() < 4 || name.compare(name.size() - 4, 4, ".svg") != 0) continue;
    EXPECT_LE(text.size(), kMaxPlotBytes) << name;
    size_t circles = 0;
    for (size_t at = text.find("<circle"); at != std::string::npos; at = text.find("<circle", at + 1)) ++circles;
    EXPECT_LE(circles, 5000u + 2u) << name;  // markers + the legend's
    EXPECT_NE(text.find("markers for"), std::string::npos) << name;
  }
}

TEST(HarnessAtScale, AShardOfAnotherConfigurationIsRefusedBeforeItsCasesAreRead) {
  const auto config = harness::ParseHarnessConfig(
      fmt::format(R"({{"design": "{}", "seed": 7, "distortion": {{"seidel_sigma_per_mm2": [6.3e-5]}},
        "noise_px": [0.1], "calibration_errors": [-1, 0], "limits": {{"dk": 0.05, "dP_D": 0.25}}}})",
                  kPaper),
      "H.json", "");
  auto other = config;
  other.seed = 8;
  harness::HarnessShardMerger merger;
  merger.Add(harness::HarnessShardJson(ConstructedRun(config, {0, 2})), "a.json");
  try {
    merger.Add(harness::HarnessShardJson(ConstructedRun(other, {1, 2})), "b.json");
    ADD_FAILURE() << "a shard of another configuration was merged";
  } catch (const util::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("b.json: config_sha256"), std::string::npos) << e.what();
  }
  try {
    (void)merger.Finish();
    ADD_FAILURE() << "a missing shard was not noticed";
  } catch (const util::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("shard 1/2 is missing"), std::string::npos) << e.what();
  }
}

}  // namespace
