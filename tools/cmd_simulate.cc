#include <fmt/format.h>

#include "model/config.h"
#include "model/io.h"
#include "tools/commands.h"
#include "tools/csv.h"
#include "topo/sweep.h"

namespace topocal::tools {

void AddSimulateCommand(CLI::App& app) {
  auto* cmd = app.add_subcommand("simulate", "Synthesise the (distorted) spot image of the configured cornea");
  auto config = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto sigma = std::make_shared<double>(0.0);
  cmd->add_option("--config", *config, "Topographer configuration (JSON)")->required();
  cmd->add_option("--sigma", *sigma, "Seidel distortion coefficient sigma, mm^-2 (paper Eq. 18)")->required();
  cmd->add_option("--out", *out, "Spots CSV on the detection plane: ring,index,x_mm,y_mm")->required();
  cmd->callback([=] {
    if (!std::isfinite(*sigma)) throw model::InputError("--sigma: must be a finite number");
    const auto cfg = model::LoadConfig(*config);
    const auto image = topo::SimulateSpots(cfg, *sigma);
    for (const auto& f : image.failures) {
      fmt::print(stderr, "topocal simulate: spot ({}, {}): {}\n", f.id.ring, f.id.index, f.reason);
    }
    if (image.spots.empty()) throw std::runtime_error(fmt::format("{}: the cornea images no spot", *config));
    model::WriteFileAtomic(*out, SpotsCsv(image.spots));
    fmt::print("simulated {} spots ({} not imaged) at sigma = {} mm^-2 -> {}\n", image.spots.size(),
               image.failures.size(), *sigma, *out);
  });
}

}  // namespace topocal::tools
