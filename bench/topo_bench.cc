// The whole 7-sigma sweep of the paper: design, synthesis, distortion, reconstruction, biconic fit and power maps
// (no PNG writing), and its pieces for one sigma.
#include <random>

#include <benchmark/benchmark.h>

#include "model/config.h"
#include "model/freeform_test_set.h"
#include "model/null_screen.h"
#include "topo/analysis.h"
#include "topo/sweep.h"

namespace {

using namespace topocal;

// The sigmas on every core (the default of RunSweep; wall-clock time), and on one thread (its peer: the same work
// serially, and what one core of a loaded machine gives).
void BM_PaperSweep(benchmark::State& state) {
  const auto config = model::LoadConfig(TOPOCAL_PAPER_CONFIG);
  for (auto _ : state) {
    auto result = topo::RunSweep(config);
    benchmark::DoNotOptimize(result.rows.data());
  }
}
BENCHMARK(BM_PaperSweep)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_PaperSweepOneThread(benchmark::State& state) {
  const auto config = model::LoadConfig(TOPOCAL_PAPER_CONFIG);
  for (auto _ : state) {
    auto result = topo::RunSweep(config, 1);
    benchmark::DoNotOptimize(result.rows.data());
  }
}
BENCHMARK(BM_PaperSweepOneThread)->Unit(benchmark::kMillisecond);

struct OneSigma {
  model::Config config = model::LoadConfig(TOPOCAL_PAPER_CONFIG);
  model::NullScreenDesign design = model::DesignNullScreen(config.ideal_image, config.topographer);
  std::vector<model::PlaneSpot> spots;
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

// One measurement of a keratoconic eye (off the axis, tilted; exact spots): the polynomial (paper) surface beside
// the spline residual, arg 0 = polynomial, 1 = spline.
struct Keratoconus {
  model::Config config = model::LoadConfig(TOPOCAL_PAPER_CONFIG);
  model::NullScreenDesign design = model::DesignNullScreen(config.ideal_image, config.topographer);
  std::vector<model::PlaneSpot> spots;
  Keratoconus() {
    const auto cornea = model::FreeformTestSubset({"kc-33um-0.85mm"}).front();
    const auto image = model::SynthesizeImage(cornea.surface, model::Topographer{config.topographer}, design.targets);
    for (const auto& s : image.spots) spots.push_back({s.id, s.position_mm});
  }
};

void BM_ReconstructKeratoconus(benchmark::State& state) {
  Keratoconus d;
  d.config.reconstruction.surface_model = state.range(0) ? "spline" : "polynomial";
  for (auto _ : state) {
    auto r = topo::Reconstruct(d.spots, d.design.targets, d.config.topographer, d.config.reconstruction);
    if (!r.ok) state.SkipWithError(r.message.c_str());
    benchmark::DoNotOptimize(r.points.data());
  }
}
BENCHMARK(BM_ReconstructKeratoconus)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// The paper cornea's measurement (sigma = 6.3e-5) with either surface model.
void BM_ReconstructSurfaceModel(benchmark::State& state) {
  OneSigma d;
  d.config.reconstruction.surface_model = state.range(0) ? "spline" : "polynomial";
  for (auto _ : state) {
    auto r = topo::Reconstruct(d.spots, d.design.targets, d.config.topographer, d.config.reconstruction);
    benchmark::DoNotOptimize(r.points.data());
  }
}
BENCHMARK(BM_ReconstructSurfaceModel)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// The whole analysis of one measurement (reconstruction, biconic fit, maps, clinical indices), arg = spline.
void BM_AnalyzeKeratoconus(benchmark::State& state) {
  Keratoconus d;
  d.config.reconstruction.surface_model = state.range(0) ? "spline" : "polynomial";
  for (auto _ : state) {
    auto a = topo::AnalyzeSpots(d.spots, d.design.targets, d.config, nullptr);
    benchmark::DoNotOptimize(a.clinical.kmax_D);
  }
}
BENCHMARK(BM_AnalyzeKeratoconus)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// The biconic fit: arg 0 = the paper's 6 parameters, 1 = free apex and tilt (10 parameters, the default).
void BM_BiconicFit(benchmark::State& state) {
  const OneSigma d;
  const auto r = topo::Reconstruct(d.spots, d.design.targets, d.config.topographer, d.config.reconstruction);
  std::vector<Eigen::Vector3d> cloud;
  for (const auto& p : r.points) cloud.push_back(p.point_mm);
  topo::BiconicFitOptions o;
  o.mode = state.range(0) ? topo::BiconicFitMode::kFreeApex : topo::BiconicFitMode::kPaper;
  for (auto _ : state) benchmark::DoNotOptimize(topo::FitBiconic(cloud, o).params.rx_mm);
}
BENCHMARK(BM_BiconicFit)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// The fit of a reference sphere (R 7.8 mm, the unit check's), reconstructed from spots with the configured
// spot-centre noise (seeded): arg 0 = the free-apex biconic it used to get (degenerate on a sphere: runs to its
// iteration cap), the peer; 1 = the 4-parameter sphere fit it gets now (topo/sphere_fit.h).
void BM_FitReferenceSphere(benchmark::State& state) {
  OneSigma d;
  d.config.cornea = model::BiconicParams{};
  d.config.cornea.rx_mm = d.config.cornea.ry_mm = 7.8;
  d.config.cornea.kx = d.config.cornea.ky = d.config.cornea.alpha_deg = 0.0;
  std::mt19937 rng(1);
  std::normal_distribution<double> noise_mm(0.0, d.config.reconstruction.spot_uncertainty_um * 1e-3);
  std::vector<model::PlaneSpot> spots;
  for (const auto& s : topo::SimulateSpots(d.config, 0.0).spots) {
    spots.push_back({s.id, s.position_mm + Eigen::Vector2d(noise_mm(rng), noise_mm(rng))});
  }
  const auto r = topo::Reconstruct(spots, d.design.targets, d.config.topographer, d.config.reconstruction);
  std::vector<Eigen::Vector3d> cloud;
  for (const auto& p : r.points) cloud.push_back(p.point_mm);
  topo::BiconicFitOptions o;
  o.mode = state.range(0) ? topo::BiconicFitMode::kSphere : topo::BiconicFitMode::kFreeApex;
  o.stddev = false;  // as a Monte Carlo draw fits
  int iterations = 0;
  for (auto _ : state) {
    const auto fit = topo::FitBiconic(cloud, o);
    iterations = fit.iterations;
    benchmark::DoNotOptimize(fit.params.rx_mm);
  }
  state.counters["iterations"] = iterations;
}
BENCHMARK(BM_FitReferenceSphere)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

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

