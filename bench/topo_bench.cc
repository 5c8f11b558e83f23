// The whole 7-sigma sweep of the paper: design, synthesis, distortion, reconstruction, biconic fit and power maps
// (no PNG writing), and its pieces for one sigma.
#include <benchmark/benchmark.h>

#include "model/config.h"
#include "model/null_screen.h"
#include "topo/analysis.h"
#include "topo/sweep.h"

namespace {

using namespace topocal;

void BM_PaperSweep(benchmark::State& state) {
  const auto config = model::LoadConfig(TOPOCAL_PAPER_CONFIG);
  for (auto _ : state) {
    auto result = topo::RunSweep(config);
    benchmark::DoNotOptimize(result.rows.data());
  }
}
BENCHMARK(BM_PaperSweep)->Unit(benchmark::kMillisecond);

struct OneSigma {
  model::Config config = model::LoadConfig(TOPOCAL_PAPER_CONFIG);
  model::NullScreenDesign design = model::DesignNullScreen(config.ideal_image, config.topographer);
  std::vector<topo::MeasuredSpot> spots;
  OneSigma() {
    for (const auto& s : topo::SimulateSpots(config, 6.3e-5).spots) spots.push_back({s.id, s.position_mm});
  }
};

void BM_Reconstruct(benchmark::State& state) {
  const OneSigma d;
  for (auto _ : state) {
    auto r = topo::Reconstruct(d.spots, d.design.targets, d.config.topographer, d.config.reconstruction);
    benchmark::DoNotOptimize(r.points.data());
  }
}
BENCHMARK(BM_Reconstruct)->Unit(benchmark::kMillisecond);

void BM_BiconicFit(benchmark::State& state) {
  const OneSigma d;
  const auto r = topo::Reconstruct(d.spots, d.design.targets, d.config.topographer, d.config.reconstruction);
  std::vector<Eigen::Vector3d> cloud;
  for (const auto& p : r.points) cloud.push_back(p.point_mm);
  for (auto _ : state) benchmark::DoNotOptimize(topo::FitBiconic(cloud).params.rx_mm);
}
BENCHMARK(BM_BiconicFit)->Unit(benchmark::kMillisecond);

void BM_PowerMaps(benchmark::State& state) {
  const OneSigma d;
  const auto r = topo::Reconstruct(d.spots, d.design.targets, d.config.topographer, d.config.reconstruction);
  const auto options = topo::PowerMapOptionsFrom(d.config.reconstruction);
  topo::PowerMaps maps;
  for (auto _ : state) {
    topo::ComputePowerMaps(r.surface, options, &maps);
    benchmark::DoNotOptimize(maps.pv_axial_D);
  }
}
BENCHMARK(BM_PowerMaps)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
