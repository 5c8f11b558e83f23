// Forward model speed: design of the null screen plus the synthetic image of all spots for one sigma.
#include <benchmark/benchmark.h>

#include "model/config.h"
#include "model/distortion.h"
#include "model/null_screen.h"

namespace {

using namespace topocal::model;

void BM_DesignAndSynthesize(benchmark::State& state) {
  const Config config = LoadConfig(TOPOCAL_PAPER_CONFIG);
  const SeidelParams seidel{2e-4, config.distortion.magnification, 0, 0};
  for (auto _ : state) {
    const auto design = DesignNullScreen(config.ideal_image, config.topographer);
    auto image = SynthesizeImage(Biconic{config.cornea}, Topographer{config.topographer}, design.targets);
    for (auto& s : image.spots) s.position_mm = Distort(seidel, s.position_mm);
    benchmark::DoNotOptimize(image.spots.data());
  }
  state.SetItemsProcessed(state.iterations() * config.ideal_image.SpotCount());
}
BENCHMARK(BM_DesignAndSynthesize)->Unit(benchmark::kMicrosecond);

}  // namespace

