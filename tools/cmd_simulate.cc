#include <fmt/format.h>

#include <cmath>

#include "model/config.h"
#include "model/device.h"
#include "model/spots_csv.h"
#include "tools/commands.h"
#include "tools/surface_option.h"
#include "topo/sweep.h"
#include "util/io.h"

namespace topocal::tools {
namespace {

struct SimulateArgs {
  std::string config, device, out;
  double sigma = NAN;
  double sphere_radius_mm = 0;
  std::vector<double> ball_at_mm;
};

void Run(const SimulateArgs& a) {
  if (std::isnan(a.sigma) == a.device.empty()) throw util::InputError("simulate: give one of --sigma or --device");
  if (a.device.empty() && (a.sphere_radius_mm != 0 || !a.ball_at_mm.empty())) {
    throw util::InputError("--sphere-radius-mm and --ball-at go with --device");
  }
  if (!std::isnan(a.sigma) && !std::isfinite(a.sigma)) throw util::InputError("--sigma: must be a finite number");
  const auto cfg = model::LoadConfig(a.config);
  if (!std::isnan(a.sigma)) RequireFoldFreeSigma(a.sigma, cfg, a.config);
  const model::Surface surface = SurfaceToImage(cfg, a.sphere_radius_mm, a.ball_at_mm);
  model::SyntheticImage image;
  if (a.device.empty()) {
    image = topo::SimulateSpots(cfg, a.sigma);
  } else {
    const auto device = model::LoadDevice(a.device).device;
    const auto design = model::DesignNullScreen(cfg.ideal_image, cfg.topographer);
    image = model::SynthesizeImage(surface, device, cfg.topographer, design.targets);
    image.failures.insert(image.failures.begin(), design.failures.begin(), design.failures.end());
    for (auto& s : image.spots) s.position_mm = model::Distort(device.distortion, s.position_mm);
  }
  for (const auto& f : image.failures) {
    fmt::print(stderr, "topocal simulate: spot ({}, {}): {}\n", f.id.ring, f.id.index, f.reason);
  }
  if (image.spots.empty()) throw std::runtime_error(fmt::format("{}: the surface images no spot", a.config));
  util::WriteFileAtomic(a.out, model::SpotsCsv(image.spots));
  fmt::print("simulated {} spots ({} not imaged) {} -> {}\n", image.spots.size(), image.failures.size(),
             a.device.empty() ? fmt::format("at sigma = {} mm^-2", a.sigma) : "through the device " + a.device, a.out);
}

}  // namespace

void AddSimulateCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("simulate", "Synthesise the (distorted) spot image of the configured cornea");
  auto a = std::make_shared<SimulateArgs>();
  cmd->add_option("--config", a->config, "Topographer configuration (JSON)")->required();
  auto* sigma = cmd->add_option("--sigma", a->sigma, "Seidel distortion coefficient sigma, mm^-2 (paper Eq. 18)");
  auto* device = cmd->add_option("--device", a->device,
                                 "As-built device (JSON, docs/device.md): its screen pose, a and distortion");
  sigma->excludes(device);
  cmd->add_option("--sphere-radius-mm", a->sphere_radius_mm,
                  "With --device: image a reference ball of this radius instead of the configured cornea, mm");
  cmd->add_option("--ball-at", a->ball_at_mm, "Vertex of the reference ball: x y z, mm (default 0 0 0)")->expected(3);
  cmd->add_option("--out", a->out, "Spots CSV on the detection plane (distorted): ring,index,x_mm,y_mm")->required();
  cmd->callback([a] { Run(*a); });
}

}  // namespace topocal::tools
