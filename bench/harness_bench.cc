// The harness: one distortion case (distort, add noise, undistort, reconstruct, fit, maps, compare), one assembly
// case (image through the as-built device, measure through the nominal one), the
// per-process setup (screen design + one truth reconstruction per cornea), and the outputs of a merged run.
#include <benchmark/benchmark.h>

#include <cmath>
#include <string>

#include "harness/harness.h"
#include "harness/harness_answer.h"
#include "harness/harness_config.h"
#include "harness/harness_report.h"

namespace {

using namespace topocal;

harness::HarnessConfig BundledConfig() {
  return harness::LoadHarnessConfig(std::string(TOPOCAL_SOURCE_DIR) + "/data/harness.json");
}

void BM_HarnessSetup(benchmark::State& state) {
  const auto config = BundledConfig();
  for (auto _ : state) {
    const harness::HarnessCaseRunner runner(config);
    benchmark::DoNotOptimize(runner.truth().data());
  }
}
BENCHMARK(BM_HarnessSetup)->Unit(benchmark::kMillisecond);

// A case with residual distortion and noise on the paper's cornea (the typical case of data/harness.json).
void BM_HarnessCase(benchmark::State& state) {
  const auto config = BundledConfig();
  const harness::HarnessCaseRunner runner(config);
  const auto cases = harness::EnumerateHarnessCases(config);
  harness::HarnessCaseSpec spec = cases.front();
  for (const auto& s : cases) {
    if (s.cornea == 0 && s.calibration_error == 0.1 && s.coefficient == 2e-4) {
      spec = s;
      break;
    }
  }
  for (auto _ : state) benchmark::DoNotOptimize(runner.Run(spec).dk_x);
}
BENCHMARK(BM_HarnessCase)->Unit(benchmark::kMillisecond);

// An assembly case: the paper's cornea through a screen tilted by 1 deg, measured through the nominal device (the
// typical case of data/harness-assembly.json; its peer is BM_HarnessCase).
void BM_HarnessAssemblyCase(benchmark::State& state) {
  const auto config = harness::LoadHarnessConfig(std::string(TOPOCAL_SOURCE_DIR) + "/data/harness-assembly.json");
  const harness::HarnessCaseRunner runner(config);
  const auto cases = harness::EnumerateHarnessCases(config);
  harness::HarnessCaseSpec spec = cases.front();
  for (const auto& s : cases) {
    if (s.cornea == 0 && s.axis == harness::AssemblyAxis::kScreenTilt && s.error > 0.9 && s.error < 1.5) {
      spec = s;
      break;
    }
  }
  for (auto _ : state) benchmark::DoNotOptimize(runner.Run(spec).dk_x);
}
BENCHMARK(BM_HarnessAssemblyCase)->Unit(benchmark::kMillisecond);

// Inverse answer and every output file for the 1620 cases of data/harness.json (synthetic case values).
void BM_HarnessOutputs(benchmark::State& state) {
  harness::HarnessRun run;
  run.config = BundledConfig();
  run.config_sha256 = harness::HarnessConfigSha256(run.config);
  run.truth.resize(run.config.corneas.size());
  for (auto& t : run.truth) t.spot_field_radius_mm = 0.4;
  for (const auto& spec : harness::EnumerateHarnessCases(run.config)) {
    harness::HarnessCaseResult c;
    c.spec = spec;
    c.ok = true;
    c.residual_max_um = 1e5 * std::abs(spec.coefficient * spec.calibration_error) + 1e-3 * spec.draw;
    c.dk_x = 0.02 * c.residual_max_um;
    c.dP_axial_max_D = 0.15 * c.residual_max_um;
    run.cases.push_back(c);
  }
  run.total_cases = static_cast<int>(run.cases.size());
  for (auto _ : state) {
    const auto answer = harness::ComputeInverseAnswer(run);
    benchmark::DoNotOptimize(harness::RenderHarnessOutputs(run, answer).size());
  }
}
BENCHMARK(BM_HarnessOutputs)->Unit(benchmark::kMillisecond);

}  // namespace
