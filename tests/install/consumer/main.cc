// Measures the paper cornea through the bundled nominal device with the installed library and prints r_x, k_x.
#include <topocal/model/config.h>
#include <topocal/model/device.h>
#include <topocal/pipeline/measure_spots.h>
#include <topocal/util/version.h>

#include <cstdio>
#include <string>

int main() {
  using namespace topocal;
  const auto config = model::LoadConfig(std::string(TOPOCAL_DATA) + "/paper.json");
  const auto device = model::LoadDevice(std::string(TOPOCAL_DATA) + "/device.json").device;
  const auto design = model::DesignNullScreen(config.ideal_image, config.topographer);
  const auto image = model::SynthesizeImage(model::Biconic{config.cornea}, device, config.topographer, design.targets);
  std::vector<model::PlaneSpot> spots;
  for (const auto& s : image.spots) spots.push_back({s.id, s.position_mm});
  const auto a = pipeline::AnalyzeThroughDevice(spots, device, config, nullptr);
  std::printf("topocal %s: rx %.4f mm kx %.4f\n", kVersion, a.surface_fit.params.rx_mm, a.surface_fit.params.kx);
  return a.surface_fit.ok ? 0 : 1;
}
