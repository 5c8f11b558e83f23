#include "topo/device_analysis.h"

#include "model/null_screen.h"

namespace topocal::topo {

Analysis AnalyzeThroughDevice(const std::vector<model::PlaneSpot>& spots, const model::Device& device,
                              const model::Config& config, const model::BiconicParams* truth,
                              const AnalysisOptions& options) {
  const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
  model::Config as_built = config;
  as_built.topographer = device.AsBuilt(config.topographer);
  return AnalyzeSpots(spots, device.PlaceTargets(design.targets, config.topographer), as_built, truth, options);
}

}  // namespace topocal::topo
