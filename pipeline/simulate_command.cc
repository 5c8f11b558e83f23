#include "pipeline/simulate_command.h"

#include <fmt/format.h>

#include <stdexcept>

#include "model/device.h"
#include "model/null_screen.h"
#include "model/spots_csv.h"
#include "topo/sweep.h"
#include "util/io.h"
#include "pipeline/simulation_surface.h"

namespace topocal::pipeline {

void RunSimulate(const SimulateRequest& a, std::ostream& out) {
  const bool at_sigma = !std::isnan(a.sigma_per_mm2);
  if (at_sigma == !a.device_path.empty()) throw util::InputError("simulate: give one of --sigma or --device");
  if (a.device_path.empty() && (a.sphere_radius_mm != 0 || !a.ball_at_mm.empty())) {
    throw util::InputError("--sphere-radius-mm and --ball-at go with --device");
  }
  if (at_sigma && !std::isfinite(a.sigma_per_mm2)) throw util::InputError("--sigma: must be a finite number");
  const auto cfg = model::LoadConfig(a.config_path);
  if (at_sigma) RequireFoldFreeSigma(a.sigma_per_mm2, cfg, a.config_path);
  const model::Surface surface = SurfaceToImage(cfg, a.sphere_radius_mm, a.ball_at_mm);
  model::SyntheticImage image;
  if (a.device_path.empty()) {
    image = topo::SimulateSpots(cfg, a.sigma_per_mm2);
  } else {
    const auto device = model::LoadDevice(a.device_path).device;
    const auto design = model::DesignNullScreen(cfg.ideal_image, cfg.topographer);
    image = model::SynthesizeImage(surface, device, cfg.topographer, design.targets);
    image.failures.insert(image.failures.begin(), design.failures.begin(), design.failures.end());
    for (auto& s : image.spots) s.position_mm = model::Distort(device.distortion, s.position_mm);
  }
  for (const auto& f : image.failures) {
    util::Log(a.log, fmt::format("spot ({}, {}): {}", f.id.ring, f.id.index, f.reason));
  }
  if (image.spots.empty()) throw std::runtime_error(fmt::format("{}: the surface images no spot", a.config_path));
  util::WriteFileAtomic(a.out_path, model::SpotsCsv(image.spots));
  out << fmt::format(
      "simulated {} spots ({} not imaged) {} -> {}\n", image.spots.size(), image.failures.size(),
      at_sigma ? fmt::format("at sigma = {} mm^-2", a.sigma_per_mm2) : "through the device " + a.device_path,
      a.out_path);
}

}  // namespace topocal::pipeline
